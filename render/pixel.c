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

/* The box-tent convolution's inverse CDF at u = i / S_TABLE, i = 0 ..
 * S_TABLE, made once per thread for the filter in use; a sample then costs
 * a lookup and a linear interpolation, which keeps the order of u (the
 * strata), where a bisection per sample made cornell-box's render 3.7
 * times slower. Off by at most the outermost steps' width (0.07 pixel for
 * box 1, tent 0.5) in the outer 1/4096 of each tail. A pure function of
 * (b, t), so every thread's table is the same. */
enum { S_TABLE = 4096 };
typedef struct s_table {
    float b, t;
    double x[S_TABLE + 1];
} s_table;
static _Thread_local s_table s_tab = { -1.0f, -1.0f, { 0 } };

static void s_table_make(float b, float t)
{
    s_tab.x[0] = -0.5 * b - t;
    s_tab.x[S_TABLE] = 0.5 * b + t;
    for (int i = 1; i < S_TABLE; i++) {
        double u = (double)i / S_TABLE, lo = s_tab.x[i - 1], hi = s_tab.x[S_TABLE];
        for (int k = 0; k < 60; k++) { /* bisection to double precision */
            double mid = 0.5 * (lo + hi);
            if (s_box_tent_cdf(mid, b, t) < u)
                lo = mid;
            else
                hi = mid;
        }
        s_tab.x[i] = 0.5 * (lo + hi);
    }
    s_tab.b = b;
    s_tab.t = t;
}

/* The filter's offset from the pixel's centre for u in [0, 1): its
 * marginal's inverse CDF, so stratified u stay stratified. */
static float s_filter_inverse(float u, float b, float t)
{
    if (t == 0.0f)
        return b * (u - 0.5f);
    if (b == 0.0f)
        return t * s_tent(u);
    if (s_tab.b != b || s_tab.t != t)
        s_table_make(b, t);
    double f = (double)u * S_TABLE;
    int i = (int)f;
    i = i < 0 ? 0 : i >= S_TABLE ? S_TABLE - 1 : i;
    return (float)(s_tab.x[i] + (f - i) * (s_tab.x[i + 1] - s_tab.x[i]));
}

void pf_pixel_filter(const pf_settings_t *s, float *jx, float *jy)
{
    float b = s->filter_box, t = s->filter_tent;
    if (b == 1.0f && t == 0.0f)
        return;
    *jx = 0.5f + s_filter_inverse(*jx, b, t);
    *jy = 0.5f + s_filter_inverse(*jy, b, t);
}

/* The emission a ray sees directly: an emitter's front (a two-sided one's
 * either side) or, when it escapes, the sky. */
static pf_vec3 s_emission(const pf_render_ctx_t *c, pf_ray_t ray)
{
    pf_hit_t h;
    if (!pf_accel_intersect(c->accel, &ray, INFINITY, &h))
        return pf_lights_sky(c->lights, ray.d);
    const pf_material_t *m = &c->scene->mats[h.mat];
    return m->twosided || pf_dot(ray.d, h.ng) < 0.0f ? m->le : pf_v3s(0.0f);
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

void pf_edges_strata(const pf_render_ctx_t *c, int px, int py, pf_edge_strata_t *e)
{
    uint64_t pixel = (uint64_t)py * (uint64_t)c->camera.width + (uint64_t)px;
    pf_rng_t perm = pf_rng_make(c->settings.seed, PF_STREAM_EDGE, pixel, PF_EDGE_SAMPLES);
    s_permute(e->sx, PF_EDGE_SAMPLES, &perm);
    s_permute(e->sy, PF_EDGE_SAMPLES, &perm);
}

pf_pattern_t pf_pattern_make(int spp)
{
    pf_pattern_t pt = { spp > 0 ? spp : 1, 0, 0, 0 };
    int kx = (int)sqrt((double)pt.spp);
    while ((kx + 1) * (kx + 1) <= pt.spp)
        kx++;
    while (kx * kx > pt.spp)
        kx--;
    pt.kx = kx;
    pt.ky = pt.spp / kx;
    pt.strata = pt.kx * pt.ky;
    return pt;
}

/* The lens sample of a pixel's own sample takes the last two dimensions of
 * its stream (2^32 - 2 and 2^32 - 1), which its draws in order (dimensions
 * 1, 2, ...) never reach: a thin-lens render shares no number with anything
 * else of the sample, and a pinhole one draws exactly what it drew before
 * the lens existed. */
#define S_LENS_DIM 0xfffffffdu

pf_ray_t pf_pixel_sample(const pf_render_ctx_t *c, const pf_pattern_t *pt, int px, int py, int s,
                         const pf_edge_strata_t *e, pf_rng_t *rng, pf_film_t *film)
{
    uint64_t pixel = (uint64_t)py * (uint64_t)c->camera.width + (uint64_t)px;
    int lens = c->camera.lens_radius > 0.0f;
    float jx, jy;
    film->u1 = film->u2 = 0.0f;
    if (s < pt->spp) {
        *rng = pf_rng_make(c->settings.seed, PF_STREAM_PIXEL, pixel, (uint32_t)s);
        if (lens) {
            pf_rng_t l = *rng;
            l.dim = S_LENS_DIM;
            film->u1 = pf_rng_float(&l);
            film->u2 = pf_rng_float(&l);
        }
        jx = pf_rng_float(rng);
        jy = pf_rng_float(rng);
        if (s < pt->strata) {
            jx = ((float)(s % pt->kx) + jx) / (float)pt->kx;
            jy = ((float)(s / pt->kx) + jy) / (float)pt->ky;
        }
    } else {
        int j = s - pt->spp;
        *rng = pf_rng_make(c->settings.seed, PF_STREAM_EDGE, pixel, (uint32_t)j);
        jx = ((float)e->sx[j] + pf_rng_float(rng)) / (float)PF_EDGE_SAMPLES;
        jy = ((float)e->sy[j] + pf_rng_float(rng)) / (float)PF_EDGE_SAMPLES;
        if (lens) {
            film->u1 = pf_rng_float(rng);
            film->u2 = pf_rng_float(rng);
        }
    }
    pf_pixel_filter(&c->settings, &jx, &jy);
    film->fx = (float)px + jx;
    film->fy = (float)py + jy;
    return pf_camera_ray_lens(&c->camera, film->fx, film->fy, film->u1, film->u2);
}
