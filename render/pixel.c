/* pixel.c: where camera samples land in their pixel, and the edges of the
 * emitters the camera sees.
 *
 * The pixel filter is a box (settings.filter_box pixels wide) convolved
 * with a tent (radius settings.filter_tent): each sample is drawn from it
 * and counts with weight one for its own pixel (filter importance
 * sampling), so no pixel reads another's samples and tiles stay
 * independent. A tent of radius 1 is pbrt's "triangle" filter; box 1 with
 * tent 0.5 is a tent of radius 1 at twice the size box-downsampled by 2,
 * the reconstruction of the Cornell-box reference.
 *
 * Emitters' edges: a pixel that sees the edge of a bright emitter (the
 * Cornell box's light of radiance 17 beside a dark ceiling) takes its
 * covered fraction from its few camera samples: at 36 samples one sample
 * more or less is 0.47, and the edge rows carried nine tenths of the
 * cornell-box's error at long renders. Such a pixel takes PF_EDGE_SAMPLES
 * camera samples more, placed as a Latin hypercube (PF_EDGE_SAMPLES strata
 * along x and along y, so an edge along either axis is met at as many
 * heights), and averages all its samples. Only its samples' number changes,
 * never what a sample estimates: a pixel where the emitter meets glass
 * showing the same sky stays exact. Which pixels do is decided from probes
 * on the film's corners (a fixed grid, no random numbers), so the choice
 * does not depend on the tiling and biases nothing. An emitter smaller than
 * the probes' spacing may be missed: its pixels keep their camera samples
 * alone, as before. Edge pixels are a few in a thousand on the Cornell box
 * (0.5 % more samples in all). */
#include "render/pixel_impl.h"

#include <math.h>
#include <stdint.h>
#include <stdlib.h>

#include "accel/accel.h"
#include "base/rng.h"
#include "light/light.h"
#include "render/render.h"

/* The inverse CDF of the unit tent on [-1, 1]. */
static float s_tent(float u)
{
    return u < 0.5f ? sqrtf(2.0f * u) - 1.0f : 1.0f - sqrtf(2.0f - 2.0f * u);
}

/* The integral of the tent of radius t's CDF from -infinity to y. */
static double s_tent_cdf_integral(double y, double t)
{
    if (y <= -t)
        return 0.0;
    if (y < 0.0)
        return (y + t) * (y + t) * (y + t) / (6.0 * t * t);
    if (y < t)
        return t / 6.0 + y - (t * t * t - (t - y) * (t - y) * (t - y)) / (6.0 * t * t);
    return y;
}

/* The CDF of a box of width b convolved with a tent of radius t, at x. */
static double s_box_tent_cdf(double x, double b, double t)
{
    return (s_tent_cdf_integral(x + 0.5 * b, t) - s_tent_cdf_integral(x - 0.5 * b, t)) / b;
}

/* The filter's offset from the pixel's centre for u in [0, 1): its
 * marginal's inverse CDF, so stratified u stay stratified. */
static float s_filter_inverse(float u, float b, float t)
{
    if (t == 0.0f)
        return b * (u - 0.5f);
    if (b == 0.0f)
        return t * s_tent(u);
    double lo = -0.5 * b - t, hi = 0.5 * b + t;
    for (int i = 0; i < 40; i++) { /* bisection: 2^-40 of the support */
        double mid = 0.5 * (lo + hi);
        if (s_box_tent_cdf(mid, b, t) < u)
            lo = mid;
        else
            hi = mid;
    }
    return (float)(0.5 * (lo + hi));
}

void pf_pixel_filter(const pf_settings_t *s, float *jx, float *jy)
{
    float b = s->filter_box, t = s->filter_tent;
    if (b == 1.0f && t == 0.0f)
        return;
    *jx = 0.5f + s_filter_inverse(*jx, b, t);
    *jy = 0.5f + s_filter_inverse(*jy, b, t);
}

/* The emission a ray sees directly: an emitter's front or, when it
 * escapes, the sky. */
static pf_vec3 s_emission(const pf_render_ctx_t *c, pf_ray_t ray)
{
    pf_hit_t h;
    if (!pf_accel_intersect(c->accel, &ray, INFINITY, &h))
        return pf_lights_sky(c->lights, ray.d);
    const pf_material_t *m = &c->scene->mats[h.mat];
    return pf_dot(ray.d, h.ng) < 0.0f ? m->le : pf_v3s(0.0f);
}

static float s_lum(pf_vec3 v) { return 0.2126f * v.x + 0.7152f * v.y + 0.0722f * v.z; }

float *pf_edges_probe(const pf_render_ctx_t *c, int x0, int y0, int w, int h)
{
    int pw = w + 3, ph = h + 3;
    float *probe = malloc((size_t)pw * (size_t)ph * sizeof *probe);
    if (!probe)
        return NULL;
    for (int j = 0; j < ph; j++)
        for (int i = 0; i < pw; i++) {
            pf_ray_t ray = pf_camera_ray_lens(&c->camera, (float)(x0 - 1 + i), (float)(y0 - 1 + j), 0.5f, 0.5f);
            probe[(size_t)j * (size_t)pw + (size_t)i] = s_lum(s_emission(c, ray));
        }
    return probe;
}

int pf_edges_pixel(const float *probe, int x0, int y0, int w, int px, int py)
{
    if (!probe)
        return 0;
    int pw = w + 3;
    float lo = INFINITY, hi = 0.0f;
    for (int j = 0; j < 4; j++)
        for (int i = 0; i < 4; i++) {
            float v = probe[(size_t)(py - y0 + j) * (size_t)pw + (size_t)(px - x0 + i)];
            lo = fminf(lo, v);
            hi = fmaxf(hi, v);
        }
    return hi > 0.0f && hi > 2.0f * lo;
}

/* A random permutation of 0 .. n - 1 (Fisher-Yates) from rng. */
static void s_permute(uint8_t *p, int n, pf_rng_t *rng)
{
    for (int i = 0; i < n; i++)
        p[i] = (uint8_t)i;
    for (int i = n - 1; i > 0; i--) {
        int j = (int)(pf_rng_float(rng) * (float)(i + 1));
        j = j > i ? i : j;
        uint8_t t = p[i];
        p[i] = p[j];
        p[j] = t;
    }
}

void pf_edges_strata(const pf_render_ctx_t *c, int px, int py, uint8_t sx[PF_EDGE_SAMPLES],
                     uint8_t sy[PF_EDGE_SAMPLES])
{
    uint64_t pixel = (uint64_t)py * (uint64_t)c->camera.width + (uint64_t)px;
    pf_rng_t perm = pf_rng_make(c->settings.seed, PF_STREAM_EDGE, pixel, PF_EDGE_SAMPLES);
    s_permute(sx, PF_EDGE_SAMPLES, &perm);
    s_permute(sy, PF_EDGE_SAMPLES, &perm);
}
