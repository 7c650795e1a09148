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

static float s_mean(pf_vec3 v) { return (v.x + v.y + v.z) * (1.0f / 3.0f); }

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
    return PF_OK;
}

void pf_envlight_free(pf_envlight_t *e)
{
    free(e->marg);
    free(e->cond);
    e->marg = e->cond = NULL;
}

pf_vec3 pf_envlight_le(const pf_envlight_t *e, pf_vec3 d) { return pf_mul(e->scale, pf_envmap_lookup(e->map, d)); }

/* The i with c[i] <= u < c[i + 1] in a cdf of n + 1 entries; *f where u lies
 * in that interval, in [0, 1). */
static int s_find(const float *c, int n, float u, float *f)
{
    int lo = 0, hi = n;
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
    int y = s_find(e->marg, m->height, u1, &fy);
    int x = s_find(&e->cond[(size_t)y * ((size_t)m->width + 1)], m->width, u2, &fx);
    return pf_envmap_pixel_dir(m, x, y, fx, fy);
}

float pf_envlight_pdf(const pf_envlight_t *e, pf_vec3 d)
{
    if (!(e->total > 0.0))
        return 0.0f;
    return (float)(s_mean(pf_envlight_le(e, d)) / e->total);
}
