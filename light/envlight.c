/* envlight.c: an image-based infinite light's sampling distribution; see
 * envlight.h.
 *
 * A row is drawn by the marginal cdf, a pixel in it by the row's cdf, and a
 * direction uniform in the pixel's solid angle (pf_envmap_pixel_dir). The
 * pdf of a direction is its pixel's probability over its solid angle, which
 * is mean(L(d)) / total for every mapping: the sin theta of a lat-long map
 * is in the pixel's solid angle. Nearest lookups make L constant over a
 * pixel, so the pdf is exactly proportional to L's mean channel: pixels
 * with light are never missed, black ones never drawn. */
#include "light/envlight.h"

#include <stdlib.h>

#include "base/status.h"
#include "light/lighttab.h"

static float s_mean(pf_vec3 v) { return (v.x + v.y + v.z) * (1.0f / 3.0f); }

/* The guide tables (see the struct); without memory, none (the same picks,
 * slower). */
static void s_guides(pf_envlight_t *e)
{
    int w = e->map->width, h = e->map->height;
    e->marg_bits = pf_guide_bits((size_t)h, 1);
    e->cond_bits = pf_guide_bits((size_t)w, 4);
    size_t kc = ((size_t)1 << e->cond_bits) + 1;
    e->marg_guide = malloc((((size_t)1 << e->marg_bits) + 1) * sizeof *e->marg_guide);
    e->cond_guide = malloc((size_t)h * kc * sizeof *e->cond_guide);
    if (!e->marg_guide || !e->cond_guide) {
        free(e->marg_guide);
        free(e->cond_guide);
        e->marg_guide = e->cond_guide = NULL;
        return;
    }
    pf_fcdf_guide_fill(e->marg_guide, e->marg_bits, e->marg, h);
    for (int y = 0; y < h; y++)
        pf_fcdf_guide_fill(&e->cond_guide[(size_t)y * kc], e->cond_bits, &e->cond[(size_t)y * ((size_t)w + 1)], w);
}

int pf_envlight_init(pf_envlight_t *e, const pf_envmap_t *map, pf_vec3 scale)
{
    int w = map->width, h = map->height;
    *e = (pf_envlight_t){ .map = map, .scale = scale };
    e->marg = malloc(((size_t)h + 1) * sizeof *e->marg);
    e->cond = malloc((size_t)h * ((size_t)w + 1) * sizeof *e->cond);
    double *rows = malloc((size_t)h * sizeof *rows);
    if (!e->marg || !e->cond || !rows) {
        free(rows);
        pf_envlight_free(e);
        return PF_ENOMEM;
    }
    double total = 0.0;
    for (int y = 0; y < h; y++) {
        float *c = &e->cond[(size_t)y * ((size_t)w + 1)];
        double acc = 0.0, omega = pf_envmap_pixel_solid_angle(map, y);
        for (int x = 0; x < w; x++) {
            const float *p = &map->rgb[3 * ((size_t)y * (size_t)w + (size_t)x)];
            c[x] = (float)acc;
            acc += s_mean(pf_v3(scale.x * p[0], scale.y * p[1], scale.z * p[2]));
        }
        for (int x = 0; x < w && acc > 0.0; x++)
            c[x] = (float)(c[x] / acc);
        c[w] = 1.0f;
        rows[y] = acc * omega;
        total += rows[y];
    }
    double acc = 0.0;
    for (int y = 0; y < h; y++) {
        e->marg[y] = total > 0.0 ? (float)(acc / total) : 0.0f;
        acc += rows[y];
    }
    e->marg[h] = 1.0f;
    free(rows);
    e->total = total;
    e->lum = pf_envmap_integral(map, scale, 0);
    s_guides(e);
    return PF_OK;
}

void pf_envlight_free(pf_envlight_t *e)
{
    free(e->marg);
    free(e->cond);
    free(e->marg_guide);
    free(e->cond_guide);
    e->marg = e->cond = NULL;
    e->marg_guide = e->cond_guide = NULL;
}

pf_vec3 pf_envlight_le(const pf_envlight_t *e, pf_vec3 d) { return pf_mul(e->scale, pf_envmap_lookup(e->map, d)); }

/* The i with c[i] <= u < c[i + 1] in a cdf of n + 1 entries; *f where u lies
 * in that interval, in [0, 1). The bisection starts from the guide's range
 * (at, bits: lighttab.h), which ends it on the same i. */
static int s_find(const float *c, int n, float u, float *f, const uint32_t *at, unsigned bits)
{
    int lo, hi;
    pf_fcdf_guide_range(at, bits, n, u, &lo, &hi);
    while (hi - lo > 1) {
        int mid = (lo + hi) / 2;
        if (c[mid] <= u)
            lo = mid;
        else
            hi = mid;
    }
    float span = c[lo + 1] - c[lo];
    float t = span > 0.0f ? (u - c[lo]) / span : 0.5f;
    *f = t < 0.0f ? 0.0f : t >= 1.0f ? 0x1.fffffep-1f : t;
    return lo;
}

pf_vec3 pf_envlight_sample(const pf_envlight_t *e, float u1, float u2)
{
    const pf_envmap_t *m = e->map;
    float fy, fx;
    int y = s_find(e->marg, m->height, u1, &fy, e->marg_guide, e->marg_bits);
    const uint32_t *row = e->cond_guide ? &e->cond_guide[(size_t)y * (((size_t)1 << e->cond_bits) + 1)] : NULL;
    int x = s_find(&e->cond[(size_t)y * ((size_t)m->width + 1)], m->width, u2, &fx, row, e->cond_bits);
    return pf_envmap_pixel_dir(m, x, y, fx, fy);
}

float pf_envlight_pdf(const pf_envlight_t *e, pf_vec3 d)
{
    if (!(e->total > 0.0))
        return 0.0f;
    return pf_envlight_pdf_le(e, pf_envlight_le(e, d));
}

float pf_envlight_pdf_le(const pf_envlight_t *e, pf_vec3 le)
{
    if (!(e->total > 0.0))
        return 0.0f;
    return (float)(s_mean(le) / e->total);
}
