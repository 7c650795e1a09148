/* camera.c: pinhole camera rays; see camera.h. Pure functions, any thread. */
#include "scene/camera.h"

pf_camera_t pf_camera_make(const pf_camera_desc_t *desc, int width, int height)
{
    pf_camera_t c;
    c.pos = desc->pos;
    c.forward = pf_norm(pf_sub(desc->look_at, desc->pos));
    c.right = pf_norm(pf_cross(c.forward, desc->up));
    c.up = pf_cross(c.right, c.forward);
    c.tan_half_v = tanf(0.5f * desc->vfov_deg * PF_PI / 180.0f);
    c.aspect = (float)width / (float)height;
    c.width = width;
    c.height = height;
    return c;
}

pf_ray_t pf_camera_ray(const pf_camera_t *cam, float fx, float fy)
{
    float sx = (2.0f * fx / (float)cam->width - 1.0f) * cam->tan_half_v * cam->aspect;
    float sy = (1.0f - 2.0f * fy / (float)cam->height) * cam->tan_half_v;
    pf_vec3 d = pf_add(cam->forward, pf_add(pf_scale(cam->right, sx), pf_scale(cam->up, sy)));
    return (pf_ray_t){ cam->pos, pf_norm(d) };
}
