/* camera.c: perspective camera rays, pinhole and thin lens; see camera.h.
 * Owns nothing; pure functions, any thread.
 *
 * The pinhole path (pf_camera_make without the new desc fields, and
 * pf_camera_ray) keeps its operations in their old order: every image
 * rendered before the lens existed stays the same to the bit. */
#include "scene/camera.h"

#include <string.h>

/* The screen window pbrt-v4's PerspectiveCamera gives a frame of aspect f
 * when none is given: the fov spans the shorter axis with fov_shorter (pbrt's
 * [-1, 1] x [-1/f, 1/f] for f < 1), else the vertical one. */
static void s_default_window(int fov_shorter, float f, float win[4])
{
    int portrait = fov_shorter && f < 1.0f;
    win[0] = portrait ? -1.0f : -f;
    win[1] = portrait ? 1.0f : f;
    win[2] = portrait ? -1.0f / f : -1.0f;
    win[3] = portrait ? 1.0f / f : 1.0f;
}

pf_camera_t pf_camera_make(const pf_camera_desc_t *desc, int width, int height)
{
    pf_camera_t c;
    c.pos = desc->pos;
    c.forward = pf_norm(pf_sub(desc->look_at, desc->pos));
    c.right = pf_norm(pf_cross(c.forward, desc->up));
    c.up = pf_cross(c.right, c.forward);
    /* Left-handed: right = up x forward = -(forward x up) for the same up,
     * so the image is mirrored left to right and nothing else moves. The
     * negation is exact: pixel x of one camera sees exactly what pixel
     * width - x of the other does, mirrored. */
    if (desc->left_handed)
        c.right = pf_neg(c.right);
    float tan_half = tanf(0.5f * desc->vfov_deg * PF_PI / 180.0f);
    c.tan_half_v = tan_half;
    c.aspect = (float)width / (float)height;
    /* The fov along the shorter axis: for a portrait image the horizontal
     * one, tan_half_h = tan_half_v * aspect; a landscape or square image's
     * shorter axis is the vertical one already. */
    if (desc->fov_shorter && width < height)
        c.tan_half_v = c.tan_half_v / c.aspect;
    c.win_cx = c.win_cy = 0.0f;
    /* A screen window (given, or the default of a frame aspect that is not
     * the image's): the image spans it, stretched if its shape is not the
     * image's. A window equal to the image's default one keeps the values
     * above, so it renders the same bits as none. */
    if (desc->has_window || desc->frame_aspect > 0.0f) {
        float img[4], win[4];
        s_default_window(desc->fov_shorter, c.aspect, img);
        if (desc->has_window)
            memcpy(win, desc->window, sizeof win);
        else
            s_default_window(desc->fov_shorter, desc->frame_aspect, win);
        if (win[0] != img[0] || win[1] != img[1] || win[2] != img[2] || win[3] != img[3]) {
            float hx = 0.5f * (win[1] - win[0]), hy = 0.5f * (win[3] - win[2]);
            c.tan_half_v = tan_half * hy;
            c.aspect = hx / hy;
            c.win_cx = (win[0] + win[1]) / (win[1] - win[0]);
            c.win_cy = (win[2] + win[3]) / (win[3] - win[2]);
        }
    }
    c.width = width;
    c.height = height;
    c.lens_radius = desc->lens_radius;
    c.focal_distance = desc->focal_distance;
    return c;
}

/* The unnormalized pinhole direction through (fx, fy): forward plus the film
 * offsets, so its component along forward is 1. The window's centre offsets
 * are 0 without a screen window, and 2 fx / width - 1 is never -0, so adding
 * them changes no bit of the plain camera's rays. */
static pf_vec3 s_film_dir(const pf_camera_t *cam, float fx, float fy)
{
    float sx = (2.0f * fx / (float)cam->width - 1.0f + cam->win_cx) * cam->tan_half_v * cam->aspect;
    float sy = (1.0f - 2.0f * fy / (float)cam->height + cam->win_cy) * cam->tan_half_v;
    return pf_add(cam->forward, pf_add(pf_scale(cam->right, sx), pf_scale(cam->up, sy)));
}

pf_ray_t pf_camera_ray(const pf_camera_t *cam, float fx, float fy)
{
    return (pf_ray_t){ cam->pos, pf_norm(s_film_dir(cam, fx, fy)) };
}

/* Shirley and Chiu's concentric map from [0, 1)^2 to the unit disc: area
 * preserving (uniform density 1/pi) and keeping strata compact. */
static void s_concentric_disc(float u1, float u2, float *x, float *y)
{
    float a = 2.0f * u1 - 1.0f, b = 2.0f * u2 - 1.0f;
    if (a == 0.0f && b == 0.0f) {
        *x = *y = 0.0f;
        return;
    }
    float r, phi;
    if (fabsf(a) > fabsf(b)) {
        r = a;
        phi = (PF_PI / 4.0f) * (b / a);
    } else {
        r = b;
        phi = PF_PI / 2.0f - (PF_PI / 4.0f) * (a / b);
    }
    *x = r * cosf(phi);
    *y = r * sinf(phi);
}

pf_ray_t pf_camera_ray_lens(const pf_camera_t *cam, float fx, float fy, float u1, float u2)
{
    if (!(cam->lens_radius > 0.0f))
        return pf_camera_ray(cam, fx, fy);
    /* The film direction has unit length along forward, so scaling it by
     * focal_distance reaches the plane in focus: pbrt's pFocus = ray(ft),
     * ft = focalDistance / d.z, without the division. */
    pf_vec3 focus = pf_madd(cam->pos, s_film_dir(cam, fx, fy), cam->focal_distance);
    float lx, ly;
    s_concentric_disc(u1, u2, &lx, &ly);
    pf_vec3 o = pf_madd(pf_madd(cam->pos, cam->right, cam->lens_radius * lx), cam->up, cam->lens_radius * ly);
    return (pf_ray_t){ o, pf_norm(pf_sub(focus, o)) };
}
