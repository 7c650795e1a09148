/* depth.h: the path-length limit (settings.path_max_depth, pbrt's
 * Integrator "maxdepth") as the camera side applies it. A light path
 * camera -> x_1 -> ... -> x_k -> light has k scattering events (specular
 * ones included); it counts when k <= D. A camera vertex x_j (j events on
 * the camera side, x_j's own included) that reads a photon which made b
 * bounces before landing there (b = 0: straight from the light) forms a path
 * of j + b events; light sampled at x_j one of j events; a final gather from
 * x_j reads photons at x_(j+1+s) (s specular bounces on the way). With no
 * limit (0) everything counts, and none of this changes a bit. */
#ifndef PF_RENDER_DEPTH_H
#define PF_RENDER_DEPTH_H

#include "photon/photonmap.h"
#include "scene/scene.h"

/* Whether a vertex that would make the path's events-th scattering event
 * may scatter: always without a limit. */
static inline int pf_depth_allows(const pf_settings_t *s, int events)
{
    return s->path_max_depth == 0 || events <= s->path_max_depth;
}

/* The photons' bounce_limit (pf_pm_scratch_t) for an estimate at a vertex
 * that is the path's events-th scattering event, which pf_depth_allows:
 * photons of at most D - events bounces. */
static inline unsigned pf_depth_photon_limit(const pf_settings_t *s, int events)
{
    return pf_pm_bounce_limit(s->path_max_depth, s->path_max_depth - events);
}

/* Whether the precomputed irradiance (pf_gather_bounce_limit: photons a
 * gather from x_1 may read, at x_2) holds the photons an estimate at the
 * events-th vertex may take; elsewhere (deeper, through mirrors) the
 * gather estimates from the global map itself. */
static inline int pf_depth_precomputed(const pf_settings_t *s, int events)
{
    return s->path_max_depth == 0 || events == 2 || pf_depth_photon_limit(s, events) == pf_gather_bounce_limit(s);
}

/* Whether the deep irradiance points (photonmap.h irradiance_deep) hold the
 * photons an estimate at the events-th vertex may take (a gather from the
 * camera's second vertex) where the first points do not. */
static inline int pf_depth_deep(const pf_settings_t *s, const pf_photon_maps_t *maps, int events)
{
    return s->path_max_depth >= 3 && maps->irradiance_deep && events == 3;
}

#endif
