/* irradiance.h: irradiance precomputed at a subset of the global photons
 * (Christensen, "Faster photon map global illumination", 1999). */
#ifndef PF_IRRADIANCE_H
#define PF_IRRADIANCE_H

#include "accel/accel.h"
#include "photon/kdtree.h"

/* For every stride-th photon of global (in tree order) estimates the
 * irradiance from its k nearest photons within max_r2 whose surface normal
 * agrees, over their disc shrunk by shrink2 (a progressive pass's,
 * pf_pass_shrink2; 1: none), leaving out those the point cannot see past
 * accel's surfaces (pf_pm_irradiance_seen: a thin wall's far side) and,
 * at a point near other surfaces, those off its own surface's slab, and
 * divides by the share of the disc its surface covers there (irradiance.c,
 * s_coverage: a corner, an edge, a table leg; the boundary bias of the
 * density estimate, 0.5 % of the whole Cornell box at 400k photons), and
 * builds *out: records with the photon's position and normal and the
 * irradiance (W/m^2) in power[], and the support radius (the unshrunk
 * disc's: where photons were found, which lookups must lie within) in dir
 * with each point's flat flag found against accel's surfaces (no flag and
 * no visibility test when accel is NULL; photonmap.h). Deterministic for
 * any thread count. 0 or PF_ENOMEM. */
int pf_irradiance_precompute(const pf_kdtree_t *global, int stride, int k, float max_r2, float shrink2,
                             const pf_accel_t *accel, int threads, pf_kdtree_t **out);

/* The same over only the photons bounce_limit counts (pf_pm_scratch_t's;
 * 0: all, as pf_irradiance_precompute): under a path-length limit the
 * final gather's points hold the irradiance of the photons a gather from
 * the camera's first vertex may take (pf_gather_bounce_limit). */
int pf_irradiance_precompute_limited(const pf_kdtree_t *global, int stride, int k, float max_r2, float shrink2,
                                     unsigned bounce_limit, const pf_accel_t *accel, int threads, pf_kdtree_t **out);

/* The parameters of one precompute (those of pf_irradiance_precompute_limited). */
typedef struct pf_irr_params {
    int stride, k;
    float max_r2, shrink2;
    unsigned bounce_limit;
} pf_irr_params_t;

/* How many points a precompute over n global photons makes: ceil(n / stride). */
size_t pf_irradiance_count(size_t n, int stride);

/* Points [first, first + count) of the precompute (point i at global photon
 * i * stride, in tree order) into out[0 .. count), before the tree is built:
 * the same records, bit for bit, as the whole precompute holds for those
 * indices, whatever the range and the thread count (each point's estimate
 * is a pure function of the map, accel and the point), so ranges computed
 * in different processes join into the same map. first + count must not
 * pass pf_irradiance_count. 0 or PF_ENOMEM. */
int pf_irradiance_points(const pf_kdtree_t *global, const pf_irr_params_t *p, const pf_accel_t *accel, int threads,
                         size_t first, size_t count, pf_photon_t *out);

#endif
