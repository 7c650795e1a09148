/* lighttab.h: lookup tables that make light.c's hot paths cheaper without
 * changing a single result (private to light/).
 *
 * - A guide table over a cdf (pf_cdf_guide_*): the index that a bisection
 *   of the whole table finds, from a bisection of the few entries that one
 *   bucket of [0, 1) spans.
 * - The emissive triangles' records (pf_emit_tri): vertices, oriented face
 *   normal, radiance, area and sidedness in about one cache line, so that a
 *   light sample reads that instead of the mesh's index, position, normal
 *   and material arrays. */
#ifndef PF_LIGHT_LIGHTTAB_H
#define PF_LIGHT_LIGHTTAB_H

#include <stddef.h>
#include <stdint.h>

#include "base/sampling.h"
#include "base/vec.h"
#include "scene/scene.h"

/* A guide over cdf[0..n] (non-decreasing): 2^bits buckets, at[j] the index
 * that pf_cdf_guide_pick gives for u = j / 2^bits (at[2^bits] for u = 1). */
typedef struct pf_cdf_guide {
    uint32_t *at;
    unsigned bits;
} pf_cdf_guide_t;

/* Builds g over cdf[0..n] (n >= 1), which must stay alive and unchanged.
 * 0, or nonzero when out of memory (g is then empty: picks bisect all). */
int pf_cdf_guide_build(pf_cdf_guide_t *g, const double *cdf, size_t n);
void pf_cdf_guide_free(pf_cdf_guide_t *g);

/* The last i in [0, n) with cdf[i] <= u (0 when there is none): what
 * bisecting lo = 0, hi = n with that test gives, found from the bucket of u
 * when g has one; bit for bit the same index for every u. */
size_t pf_cdf_guide_pick(const pf_cdf_guide_t *g, const double *cdf, size_t n, float u);

/* The same over a float cdf c[0..n] (envlight.c's rows and columns):
 * at[0..2^bits] filled from c, which must stay unchanged. */
void pf_fcdf_guide_fill(uint32_t *at, unsigned bits, const float *c, int n);

/* The range [*lo, *hi) of [0, n) that holds the last i with c[i] <= u, for
 * a bisection that keeps its invariant (see lighttab.c): [0, n) when u is
 * outside [0, 1) or there is no guide (at NULL). */
static inline void pf_fcdf_guide_range(const uint32_t *at, unsigned bits, int n, float u, int *lo, int *hi)
{
    float f = u * (float)((uint32_t)1 << bits); /* exact: a power of two */
    if (!at || !(u >= 0.0f) || !(f < (float)((uint32_t)1 << bits))) {
        *lo = 0, *hi = n;
        return;
    }
    uint32_t j = (uint32_t)f;
    int h = (int)at[j + 1] + 1;
    *lo = (int)at[j], *hi = h < n ? h : n;
}

/* The guide's bits for a cdf of n entries: about one bucket per `per` entries. */
unsigned pf_guide_bits(size_t n, size_t per);

/* An emissive triangle as light.c samples it: p0, p1, p2 its vertices, n
 * its unit face normal oriented by the vertex normals (as accel.c does),
 * le the material's radiance, area as the light table computed it,
 * twosided the material's (le leaves the back too). */
typedef struct pf_emit_tri {
    pf_vec3 p0, p1, p2, n, le;
    float area;
    uint32_t twosided;
} pf_emit_tri_t;

/* The record of triangle t of mesh m with the given area. */
pf_emit_tri_t pf_emit_tri_make(const pf_scene_t *scene, uint32_t m, uint32_t t, float area);

/* The point at barycentrics from pf_sample_triangle(u1, u2) and, when
 * perr is not NULL, its rounding error bound (pf_tri_point_error). */
static inline pf_vec3 pf_emit_tri_point(const pf_emit_tri_t *t, float u1, float u2, pf_vec3 *perr)
{
    float b0, b1;
    pf_sample_triangle(u1, u2, &b0, &b1);
    float b2 = 1.0f - b0 - b1;
    if (perr)
        *perr = pf_tri_point_error(t->p0, t->p1, t->p2, b0, b1, b2);
    return pf_add(pf_add(pf_scale(t->p0, b0), pf_scale(t->p1, b1)), pf_scale(t->p2, b2));
}

#endif
