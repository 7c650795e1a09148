/* camera.h: the perspective camera, pinhole or thin lens. Pixel (0,0) is the
 * top-left corner of the image; +x of the camera frame is image right, +y
 * image up, and forward looks from pos to look_at.
 *
 * The frame is right = forward x up (a right-handed camera space, the JSON
 * format's), or up x forward with left_handed (pbrt's camera space, whose
 * images are the mirror image left to right of the former). The field of
 * view spans the vertical axis, or with fov_shorter the shorter of the two
 * (pbrt's "fov"), decided by the image size given to pf_camera_make, so a
 * --size that turns a landscape image into a portrait one moves the fov to
 * the horizontal axis.
 *
 * A screen window (pbrt-v4's ProjectiveCamera "screenwindow") names the
 * part of the image plane at distance 1 that the image spans, in units of
 * tan(fov / 2): x from xmin (left edge) to xmax, y from ymin (bottom) to
 * ymax. Without one it is pbrt's default for the frame aspect f (pbrt's
 * "frameaspectratio", else width / height): [-f, f] x [-1, 1], or with
 * fov_shorter and f < 1 [-1, 1] x [-1/f, 1/f], which is the camera above;
 * an off-centre window crops a larger image, a window of another shape than
 * the image stretches it. */
#ifndef PF_CAMERA_H
#define PF_CAMERA_H

#include "base/vec.h"
#include "scene/scene.h"

typedef struct pf_camera {
    pf_vec3 pos;
    pf_vec3 right, up, forward; /* orthonormal frame; right is up x forward when left-handed */
    float tan_half_v;           /* tan of half the vertical field of view (half the window's height) */
    float aspect;               /* width / height; with a screen window its half width / half height */
    float win_cx, win_cy;       /* the window's centre over its half width, half height; 0 without one */
    int width, height;
    float lens_radius;          /* thin lens aperture radius, world units; 0: pinhole */
    float focal_distance;       /* distance from pos to the plane in focus, along forward */
} pf_camera_t;

/* Builds a camera for an image of width x height pixels. A desc with zero
 * fov_shorter, left_handed and lens_radius gives the pinhole camera, the same
 * bits as before those fields existed. */
pf_camera_t pf_camera_make(const pf_camera_desc_t *desc, int width, int height);

/* The pinhole ray through film position (fx, fy), in pixels from the
 * top-left corner (fx in [0, width), fy in [0, height)): from pos, unit
 * direction. Ignores the lens. */
pf_ray_t pf_camera_ray(const pf_camera_t *cam, float fx, float fy);

/* The camera ray through film position (fx, fy) for lens sample (u1, u2) in
 * [0, 1)^2. With lens_radius > 0 (pbrt-v4's PerspectiveCamera::GenerateRay):
 * the origin is the point of the aperture disc (radius lens_radius about pos,
 * in the plane of right and up) that the concentric map takes (u1, u2) to,
 * and the ray aims at where the pinhole ray meets the plane in focus, which
 * lies focal_distance along forward and perpendicular to it; every lens
 * sample of one film position meets there. With lens_radius == 0 it is
 * pf_camera_ray, bit for bit, and (u1, u2) are not used. */
pf_ray_t pf_camera_ray_lens(const pf_camera_t *cam, float fx, float fy, float u1, float u2);

#endif
