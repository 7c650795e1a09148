/* lighttab.c: guide tables over cdfs and emissive triangle records; see
 * lighttab.h.
 *
 * The guide: with K = 2^bits buckets and a(v) the last i in [0, n) with
 * cdf[i] <= v, a is non-decreasing, so for j / K <= u < (j + 1) / K the
 * answer lies in [a(j / K), a((j + 1) / K)]; bisecting that range with the
 * same test keeps the invariant of the full bisection (cdf[lo] <= u, and
 * hi = n or cdf[hi] > u) and so ends on the same index. u * K is exact in
 * double (K a power of two), so the bucket is never off by one. On
 * veach-mis (11904 emissive triangles) a pick reads two guide entries and
 * one or two of the cdf's instead of 14 scattered ones.
 *
 * The records: the same float operations as light.c did on the mesh's
 * arrays at each sample, done once, so every result keeps its bits. */
#include "light/lighttab.h"

#include <stdlib.h>

/* Buckets per entry, rounded up to a power of two, at most 2^S_MAX_BITS. */
#define S_MAX_BITS 20

/* The full bisection over [lo, hi): light.c's original s_pick. */
static size_t s_bisect(const double *cdf, size_t lo, size_t hi, double u)
{
    while (hi - lo > 1) {
        size_t mid = (lo + hi) / 2;
        if (cdf[mid] <= u)
            lo = mid;
        else
            hi = mid;
    }
    return lo;
}

unsigned pf_guide_bits(size_t n, size_t per)
{
    unsigned bits = 1;
    while (bits < S_MAX_BITS && ((size_t)1 << bits) * per < n)
        bits++;
    return bits;
}

void pf_fcdf_guide_fill(uint32_t *at, unsigned bits, const float *c, int n)
{
    uint32_t k = (uint32_t)1 << bits;
    int i = 0;
    for (uint32_t j = 0; j <= k; j++) {
        float v = (float)j / (float)k;
        while (i + 1 < n && c[i + 1] <= v)
            i++;
        at[j] = (uint32_t)i;
    }
}

int pf_cdf_guide_build(pf_cdf_guide_t *g, const double *cdf, size_t n)
{
    g->at = NULL;
    g->bits = 0;
    if (n < 2)
        return 0; /* nothing to bisect */
    unsigned bits = pf_guide_bits(n, 1);
    size_t k = (size_t)1 << bits;
    uint32_t *at = malloc((k + 1) * sizeof *at);
    if (!at)
        return 1;
    size_t i = 0; /* a(v) for increasing v: a walk instead of k bisections */
    for (size_t j = 0; j <= k; j++) {
        double v = (double)j / (double)k;
        while (i + 1 < n && cdf[i + 1] <= v)
            i++;
        at[j] = (uint32_t)i;
    }
    g->at = at;
    g->bits = bits;
    return 0;
}

void pf_cdf_guide_free(pf_cdf_guide_t *g)
{
    free(g->at);
    g->at = NULL;
    g->bits = 0;
}

size_t pf_cdf_guide_pick(const pf_cdf_guide_t *g, const double *cdf, size_t n, float u)
{
    double ud = u;
    if (!g->at || !(ud >= 0.0))
        return s_bisect(cdf, 0, n, ud);
    size_t k = (size_t)1 << g->bits;
    double f = ud * (double)k;
    if (!(f < (double)k))
        return s_bisect(cdf, g->at[k - 1], n, ud); /* u >= 1: cdf[at[k - 1]] <= (k - 1) / k <= u */
    size_t j = (size_t)f;
    size_t hi = (size_t)g->at[j + 1] + 1;
    return s_bisect(cdf, g->at[j], hi < n ? hi : n, ud);
}

pf_emit_tri_t pf_emit_tri_make(const pf_scene_t *scene, uint32_t m, uint32_t t, float area)
{
    const pf_mesh_t *mesh = &scene->meshes[m];
    const uint32_t *v = &mesh->idx[3 * t];
    pf_emit_tri_t r;
    r.p0 = mesh->pos[v[0]], r.p1 = mesh->pos[v[1]], r.p2 = mesh->pos[v[2]];
    r.n = pf_norm(pf_cross(pf_sub(r.p1, r.p0), pf_sub(r.p2, r.p0)));
    if (mesh->nrm) /* as in accel.c: vertex normals orient the face */
        r.n = pf_face_forward(r.n, pf_add(pf_add(mesh->nrm[v[0]], mesh->nrm[v[1]]), mesh->nrm[v[2]]));
    r.le = scene->mats[mesh->mat[t]].le;
    r.area = area;
    r.twosided = scene->mats[mesh->mat[t]].twosided != 0;
    return r;
}
