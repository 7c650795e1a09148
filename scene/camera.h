/* camera.h: the pinhole camera. Pixel (0,0) is the top-left corner of the
 * image; +x of the camera frame is image right, +y image up. */
#ifndef PF_CAMERA_H
#define PF_CAMERA_H

#include "base/vec.h"
#include "scene/scene.h"

typedef struct pf_camera {
    pf_vec3 pos;
    pf_vec3 right, up, forward; /* orthonormal frame */
    float tan_half_v;           /* tan of half the vertical field of view */
    float aspect;               /* width / height */
    int width, height;
} pf_camera_t;

/* Builds a camera for an image of width x height pixels. */
pf_camera_t pf_camera_make(const pf_camera_desc_t *desc, int width, int height);

/* The primary ray through film position (fx, fy), in pixels from the top-left
 * corner (fx in [0, width), fy in [0, height)). */
pf_ray_t pf_camera_ray(const pf_camera_t *cam, float fx, float fy);

#endif
