/* spherelight.c: an emissive analytic sphere as an emitter; see
 * spherelight.h.
 *
 * Sampling follows pbrt-v4's Sphere::Sample(ctx, u): cos theta uniform in
 * [cos theta_max, 1] about the axis from the receiver x to the centre, then
 * the point of the near side that direction meets, found from the angle
 * alpha at the centre (cos alpha = sin^2 theta / sin theta_max + cos theta
 * sqrt(1 - sin^2 theta / sin^2 theta_max)). The cone's 1 - cos theta_max is
 * formed as sin^2 / (1 + cos) in double, and sin^2 theta as t (2 - t) with
 * t = 1 - cos theta, so a small far sphere (veach-mis's smallest subtends
 * under a degree) loses nothing to cancellation: pbrt's small-angle branch
 * is not needed. The point itself, the direction and the distance to it are
 * then made in float from the centre and the normal, so the shadow ray ends
 * on the surface the accelerator intersects. */
#include "light/spherelight.h"

#include <math.h>

#include "base/sampling.h"

float pf_sphere_light_area(const pf_sphere_t *s) { return 4.0f * PF_PI * s->radius * s->radius; }

/* 1 - cos theta_max of the cone the sphere subtends from x, with sin^2
 * theta_max and the unit axis from x to the centre; 0 when x is inside or on
 * the sphere. */
static double s_cone(const pf_sphere_t *s, pf_vec3 x, double *sin2max, pf_vec3 *axis)
{
    double dx = (double)s->center.x - x.x, dy = (double)s->center.y - x.y, dz = (double)s->center.z - x.z;
    double d2 = dx * dx + dy * dy + dz * dz, r = s->radius;
    if (!(d2 > r * r))
        return 0.0;
    double d = sqrt(d2);
    *axis = pf_v3((float)(dx / d), (float)(dy / d), (float)(dz / d));
    *sin2max = r * r / d2;
    return *sin2max / (1.0 + sqrt(1.0 - *sin2max));
}

/* The cone's pdf 1 / (2 pi (1 - cos theta_max)) as a float; 0 when it is
 * not finite (a sphere too small to see from x in float). */
static float s_cone_pdf(double one_minus_cos)
{
    float pdf = (float)(1.0 / (2.0 * PF_PI * one_minus_cos));
    return isfinite(pdf) ? pdf : 0.0f;
}

float pf_sphere_light_pdf(const pf_sphere_t *s, pf_vec3 x)
{
    double sin2max;
    pf_vec3 axis;
    double om = s_cone(s, x, &sin2max, &axis);
    return om > 0.0 ? s_cone_pdf(om) : 0.0f;
}

int pf_sphere_light_sample(const pf_sphere_t *s, pf_vec3 x, float u1, float u2, pf_vec3 *wi, float *dist,
                           float *pdf)
{
    double sin2max;
    pf_vec3 axis;
    double om = s_cone(s, x, &sin2max, &axis);
    float p_cone = om > 0.0 ? s_cone_pdf(om) : 0.0f;
    if (!(p_cone > 0.0f))
        return 0;
    double t = (double)u1 * om, sin2 = t * (2.0 - t), cos_t = 1.0 - t;
    double cos_a = sin2 / sqrt(sin2max) + cos_t * sqrt(fmax(0.0, 1.0 - sin2 / sin2max));
    double sin_a = sqrt(fmax(0.0, 1.0 - cos_a * cos_a)), phi = 2.0 * PF_PI * (double)u2;
    pf_vec3 local = pf_v3((float)(sin_a * cos(phi)), (float)(sin_a * sin(phi)), (float)cos_a);
    pf_vec3 n = pf_neg(pf_to_world(local, axis)); /* alpha from the centre's side facing x */
    pf_vec3 d = pf_sub(pf_madd(s->center, n, s->radius), x);
    float len = pf_len(d);
    if (!(len > 0.0f))
        return 0;
    *wi = pf_scale(d, 1.0f / len);
    *dist = len;
    *pdf = p_cone;
    return 1;
}

void pf_sphere_light_point(const pf_sphere_t *s, float u1, float u2, pf_vec3 *p, pf_vec3 *n, pf_vec3 *perr)
{
    const float eps = 0x1p-24f, gamma5 = 5.0f * eps / (1.0f - 5.0f * eps);
    *n = pf_norm(pf_sample_sphere(u1, u2));
    *p = pf_madd(s->center, *n, s->radius);
    *perr = pf_scale(pf_add(pf_vabs(s->center), pf_vabs(pf_scale(*n, s->radius))), gamma5);
}

pf_light_bounds_t pf_sphere_light_bounds(const pf_sphere_t *s, float phi)
{
    pf_vec3 r = pf_v3s(s->radius);
    return (pf_light_bounds_t){ .lo = pf_sub(s->center, r), .hi = pf_add(s->center, r), .phi = phi,
                                .w = pf_v3(0, 0, 1), .cos_theta_o = -1.0f, .cos_theta_e = 0.0f, .two_sided = 0 };
}
