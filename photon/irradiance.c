/* irradiance.c: precomputed irradiance at a subset of the global photons
 * (Christensen 1999); see irradiance.h. Runs on the coordinator once per
 * render, parallel over points with OpenMP; each point's estimate depends only
 * on the tree and the scene's surfaces, so the result is the same for any
 * thread count.
 *
 * An estimate sums only photons its point can see: under a thin wall the
 * floor on the far side lies in the same plane with the same normal, so the
 * normal test keeps its photons, and the final gather would read the far
 * side's light on this side (pf_pm_irradiance_seen). Most points lie
 * where no other surface comes near (pf_accel_only_plane, the check that
 * also sets their flat flag) and trace no ray. */
#include "photon/irradiance.h"

#include <omp.h>
#include <math.h>
#include <stdlib.h>
#include <string.h>

#include "accel/accel.h"
#include "photon/photonmap.h"

/* Photons one point's visibility search may sort (16 bytes each, per
 * thread): k seen ones need far more candidates only when the far side of a
 * wall is far denser; past this many the search stops widening. */
#define PF_IRRADIANCE_VISIBLE_CAP ((size_t)1 << 16)

int pf_irradiance_precompute(const pf_kdtree_t *global, int stride, int k, float max_r2, float shrink2,
                             const pf_accel_t *accel, int threads, pf_kdtree_t **out)
{
    return pf_irradiance_precompute_limited(global, stride, k, max_r2, shrink2, 0, accel, threads, out);
}

size_t pf_irradiance_count(size_t n, int stride)
{
    size_t st = stride < 1 ? 1 : (size_t)stride;
    return (n + st - 1) / st;
}

int pf_irradiance_precompute_limited(const pf_kdtree_t *global, int stride, int k, float max_r2, float shrink2,
                                     unsigned bounce_limit, const pf_accel_t *accel, int threads, pf_kdtree_t **out)
{
    pf_irr_params_t p = { stride < 1 ? 1 : stride, k, max_r2, shrink2, bounce_limit };
    size_t m = pf_irradiance_count(pf_kdtree_size(global), p.stride);
    pf_photon_t *pts = malloc((m ? m : 1) * sizeof *pts);
    if (!pts)
        return PF_ENOMEM;
    int rc = pf_irradiance_points(global, &p, accel, threads, 0, m, pts);
    if (rc != PF_OK) {
        free(pts);
        return rc;
    }
    *out = pf_kdtree_build(&pts, m);
    return *out ? PF_OK : PF_ENOMEM;
}

/* Sample points of the coverage test (below): 32 keep its quadrature
 * within 0.1 % of the exact share on the thin-wall stress case (16: 2 %;
 * asking a quarter of them first and the rest only when one missed left
 * slivers of discs uncounted: 1.6 %). */
#define S_COVER_N 32
/* No estimate is scaled up by more than this: a disc mostly off the
 * surface (the test's reading, in clutter, is least sure there) would
 * read its few photons far too bright; a straight edge through the point
 * leaves half. */
#define S_COVER_MIN 0.5f
/* The test's segments run this far above x's plane, over their length:
 * above a surface curving away (convex) or bent by its tessellation, below
 * a table top, a seat or a shelf over x (which a lift by the whole length,
 * as s_seen's, would take for walls). */
#define S_COVER_LIFT 0.25f

/* The share of the disc of radius r about x in x's tangent plane (unit
 * normal n) that x's surface covers, for a point near other surfaces (not
 * flat): the k-NN estimate divides the photons' flux by the whole disc, and
 * at a corner or an edge part of the disc lies behind a wall or past the
 * edge, where no photon of x's surface can be, so the estimate reads low by
 * that share (the boundary bias of density estimation: 0.5 % on the whole
 * Cornell box at 400k photons, against a path tracer, far more in its
 * corners). S_COVER_N points spread over the disc (stratified by area, a
 * golden-angle spiral turned by a hash of x) each count when (1) the
 * segment from x to it, both lifted along n by S_COVER_LIFT times the
 * point's distance rho, hits nothing (no wall between), and (2) a ray from
 * the lifted point down along -n meets, within the slab the estimate keeps
 * (PF_PM_SLAB rho below the plane), a surface parallel to x's within
 * PF_NORMAL_AGREE (either winding: its side facing the ray is the one
 * photons land on): the surface goes on there. At least S_COVER_MIN.
 * Against bench/pathref the Cornell box's mean went from -0.50 % to
 * -0.05 % (and -0.93 % to 0.00 % at 100k photons). */
static float s_coverage(const pf_accel_t *accel, pf_vec3 x, pf_vec3 n, float r)
{
    pf_vec3 t, b;
    pf_basis(n, &t, &b);
    uint32_t bits[3];
    memcpy(bits, &x, sizeof bits);
    float turn = (float)((bits[0] * 2654435761u ^ bits[1] * 2246822519u ^ bits[2] * 3266489917u) >> 8) * 0x1p-24f;
    int covered = 0;
    for (int i = 0; i < S_COVER_N; i++) {
        float rho = r * sqrtf(((float)i + 0.5f) / (float)S_COVER_N);
        float phi = 2.0f * PF_PI * (turn + 0.6180339887f * (float)i);
        pf_vec3 d = pf_add(pf_scale(t, cosf(phi)), pf_scale(b, sinf(phi)));
        float lift = S_COVER_LIFT * rho;
        pf_vec3 a = pf_madd(x, n, lift), e = pf_madd(pf_madd(x, d, rho), n, lift);
        pf_ray_t across = { a, d };
        if (pf_accel_occluded(accel, &across, rho))
            continue; /* a wall between */
        pf_ray_t down = { e, pf_neg(n) };
        pf_hit_t h;
        if (pf_accel_intersect(accel, &down, lift + PF_PM_SLAB * rho, &h) && fabsf(pf_dot(h.ng, n)) >= PF_NORMAL_AGREE)
            covered++;
    }
    float f = (float)covered / (float)S_COVER_N;
    return f > S_COVER_MIN ? f : S_COVER_MIN;
}

int pf_irradiance_points(const pf_kdtree_t *global, const pf_irr_params_t *par, const pf_accel_t *accel, int threads,
                         size_t first, size_t m, pf_photon_t *pts)
{
    int stride = par->stride < 1 ? 1 : par->stride;
    int k = par->k > PF_MAX_K ? PF_MAX_K : par->k;
    const float max_r2 = par->max_r2, shrink2 = par->shrink2;
    const unsigned bounce_limit = par->bounce_limit;
    if (threads < 1)
        threads = 1;
    const pf_photon_t *ph = pf_kdtree_photons(global);
    int failed = 0;
#pragma omp parallel num_threads(threads)
    {
        pf_accel_thread_init();
        pf_pm_scratch_t *scratch = malloc(sizeof *scratch);
        if (scratch)
            scratch->bounce_limit = bounce_limit;
        pf_pm_visible_scratch_t vis = { 0 };
        /* Points in tree order are near each other: the last estimate's
         * radius, widened by 1.5, bounds the next search (same results). */
        float hint = INFINITY;
        if (!scratch || (accel && pf_pm_visible_scratch_init(&vis, PF_IRRADIANCE_VISIBLE_CAP) != PF_OK)) {
#pragma omp atomic write
            failed = 1;
        }
#pragma omp for schedule(dynamic, 256)
        for (size_t i = 0; i < m; i++) {
            if (!scratch || (accel && !vis.found))
                continue;
            const pf_photon_t *p = &ph[(first + i) * (size_t)stride];
            pf_vec3 nrm = pf_photon_normal(p);
            float r2 = 0.0f;
            int flat = 0;
            pf_vec3 e = pf_pm_irradiance_seen(global, accel, pf_photon_pos(p), nrm, k, max_r2, hint, shrink2, scratch,
                                              &vis, &r2, &flat);
            hint = r2 < max_r2 ? fminf(1.44f * r2, max_r2) : max_r2;
            float r = sqrtf(r2);
            float rs = sqrtf(shrink2 < 1.0f ? r2 * shrink2 : r2);
            /* the disc's share off the surface, where another surface comes
             * within the disc itself (fewer than k found: none asked) */
            float lum = pf_luminance(e), share = lum > 0.0f ? pf_luminance(scratch->direct) / lum : 0.0f;
            if (accel && !flat && r2 < max_r2 && !pf_accel_only_plane(accel, pf_photon_pos(p), nrm, rs))
                e = pf_scale(e, 1.0f / s_coverage(accel, pf_photon_pos(p), nrm, rs));
            pts[i] = (pf_photon_t){ { p->pos[0], p->pos[1], p->pos[2] }, { e.x, e.y, e.z },
                                    pf_irradiance_pack(r, flat, share), p->normal };
        }
        free(scratch);
        pf_pm_visible_scratch_free(&vis);
    }
    return failed ? PF_ENOMEM : PF_OK;
}
