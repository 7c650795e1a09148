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
            uint32_t support;
            memcpy(&support, &r, sizeof support);
            if (flat)
                support |= PF_IRRADIANCE_FLAT_BIT;
            pts[i] = (pf_photon_t){ { p->pos[0], p->pos[1], p->pos[2] }, { e.x, e.y, e.z }, support, p->normal };
        }
        free(scratch);
        pf_pm_visible_scratch_free(&vis);
    }
    return failed ? PF_ENOMEM : PF_OK;
}
