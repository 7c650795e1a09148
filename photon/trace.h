/* photon_trace.h: the photon pass. Traces global and caustic photons from the
 * lights and builds the global, caustic and precomputed-irradiance maps. */
#ifndef PF_PHOTON_TRACE_H
#define PF_PHOTON_TRACE_H

#include "accel/accel.h"
#include "light/light.h"
#include "photon/irradiance.h"
#include "photon/photonmap.h"
#include "scene/scene.h"

/* The most irradiance points one map gets, unless that would space them
 * wider than their estimates reach (pf_irradiance_points_stride). */
#define PF_IRRADIANCE_MAX_POINTS ((size_t)500000)

/* Photons are traced in blocks of PF_PHOTON_BLOCK consecutive indices, each
 * into its own buffer, joined in block order (the determinism rule). */
#define PF_PHOTON_BLOCK 4096
/* A batch, the unit the photon pass is spread in over processes, is
 * PF_PHOTON_BATCH_BLOCKS blocks of one map: joining batches in batch order
 * joins their blocks in block order, so the maps do not depend on who traced
 * which batch. At most PF_PHOTON_MAX_BATCHES per pass (a table the coordinator
 * holds: 2^20 batches are 2^35 photons). */
#define PF_PHOTON_BATCH_BLOCKS 16
#define PF_PHOTON_MAX_BATCHES (1u << 20)

typedef struct pf_photon_stats {
    uint64_t global_stored, caustic_stored, irradiance_points;
    uint64_t rejected;          /* photons dropped for non-finite or negative power */
    uint64_t indirect_stored;   /* global photons stored after a non-specular bounce */
    int gather_skipped;         /* none were: no irradiance was precomputed (pf_photon_skip_gather) */
    double trace_s, build_s, irradiance_s;
} pf_photon_stats_t;

/* Every how many stored global photons (of `stored`) an irradiance point is
 * precomputed: settings->irradiance_stride, widened so that at most
 * PF_IRRADIANCE_MAX_POINTS points are made, but never past global_k / 4
 * by that widening (see photon_trace.c). At least 1. */
size_t pf_irradiance_points_stride(size_t stored, const pf_settings_t *settings);

/* The bounce limit (pf_pm_scratch_t) of maps->irradiance_deep: photons a
 * gather from the camera's second vertex may read (D - 3 bounces); 0 when
 * there is no limit or it leaves those gathers nothing (D < 3: none made). */
unsigned pf_deep_bounce_limit(const pf_settings_t *settings);

/* Derives maps->irradiance_deep (photonmap.h) from the global map, at the
 * same points as maps->irradiance, when settings->path_max_depth >= 3 and
 * there are points; deterministic for any thread count (0: all cores), so
 * the coordinator's and every worker's agree. 0 or PF_ENOMEM. */
int pf_photon_deep_irradiance(pf_photon_maps_t *maps, const pf_accel_t *accel, const pf_settings_t *settings,
                              int threads);

/* Runs the photon pass with settings->threads OpenMP threads. Photon i draws
 * from its own counter-based stream and photons are stored in index order,
 * so the maps are identical for any thread count. 0 or a status. */
int pf_photon_pass(const pf_scene_t *scene, const pf_accel_t *accel, const pf_lights_t *lights,
                   const pf_settings_t *settings, pf_photon_maps_t *maps, pf_photon_stats_t *stats);

/* The build half of the photon pass: the global and caustic photons (in
 * index order; *gp_p and *cp_p taken and nulled, also on failure) into the
 * kd-trees and the irradiance precompute (settings->threads threads), the
 * radii from the scene's bounds. stats: global_stored, caustic_stored,
 * irradiance_points, gather_skipped, build_s and irradiance_s are set;
 * indirect_stored must be set already (it decides the gather skip). */
int pf_photon_build(const pf_scene_t *scene, const pf_accel_t *accel, const pf_settings_t *settings,
                    uint64_t caustic_emitted, pf_photon_t **gp_p, size_t gn, pf_photon_t **cp_p, size_t cn,
                    pf_photon_maps_t *maps, pf_photon_stats_t *stats);

/* How a pass divides into batches: global batches [0, global_batches),
 * then caustic ones [global_batches, global_batches + caustic_batches). */
typedef struct pf_photon_plan {
    uint64_t global_emitted, caustic_emitted; /* caustic: 0 without specular surfaces */
    uint32_t global_batches, caustic_batches;
} pf_photon_plan_t;

/* What one batch stored: its photons in index order and its counters. */
typedef struct pf_photon_batch {
    pf_photon_t *p; /* malloc'd */
    size_t n;
    uint64_t rejected; /* photons dropped for non-finite or negative power */
    uint64_t indirect; /* global photons stored after a non-specular bounce (0 for a caustic batch) */
} pf_photon_batch_t;

/* Traces batches of one pass's photons over (scene, accel, lights) with
 * settings' seed, photon counts and depth; the scene and its accel and
 * lights must outlive it. quiet: no log line (a worker's). 0, PF_ENOMEM,
 * or PF_EINVAL when the pass has more than PF_PHOTON_MAX_BATCHES. */
typedef struct pf_photon_tracer pf_photon_tracer_t;
int pf_photon_tracer_new(const pf_scene_t *scene, const pf_accel_t *accel, const pf_lights_t *lights,
                         const pf_settings_t *settings, int quiet, pf_photon_tracer_t **out);
void pf_photon_tracer_free(pf_photon_tracer_t **t_p); /* NULL-safe; nulls *t_p */
const pf_photon_plan_t *pf_photon_tracer_plan(const pf_photon_tracer_t *t);

/* Traces batch `batch` with `threads` OpenMP threads into out (its photons
 * exactly those pf_photon_pass stores for that range of indices). Stops
 * early with PF_EINTERRUPTED when *abort (may be NULL) or the process-wide
 * cancel flag is set; PF_EINVAL for a batch out of the plan; PF_ENOMEM. */
int pf_photon_trace_batch(const pf_photon_tracer_t *t, uint32_t batch, int threads, volatile int *abort,
                          pf_photon_batch_t *out);
/* The same for batches [first, first + count) into out[0 .. count), the
 * threads sharing their blocks (no idle thread at each batch's end). On
 * failure every out[k] is empty. */
int pf_photon_trace_batches(const pf_photon_tracer_t *t, uint32_t first, uint32_t count, int threads,
                            volatile int *abort, pf_photon_batch_t *out);

/* Joins every batch of plan (batches[0 .. global + caustic), each's photons
 * freed and nulled) in batch order and builds the maps (pf_photon_build):
 * the same maps as pf_photon_pass for any split of the tracing. Adds the
 * batches' counters to stats (zero it first). 0 or a status. */
int pf_photon_merge(const pf_scene_t *scene, const pf_accel_t *accel, const pf_settings_t *settings,
                    const pf_photon_plan_t *plan, pf_photon_batch_t *batches, pf_photon_maps_t *maps,
                    pf_photon_stats_t *stats);

/* The irradiance precompute of a pass over maps->global (its radius in
 * maps->global_r2): the points' parameters for the irradiance map (main)
 * and, with has_deep, for maps->irradiance_deep, at the same `points`
 * points. Whoever computes a range of them (pf_irradiance_points) with
 * these parameters makes the records the in-process pass makes. */
typedef struct pf_irr_plan {
    pf_irr_params_t main, deep;
    int has_deep;
    size_t points;
} pf_irr_plan_t;
void pf_photon_irr_plan(const pf_photon_maps_t *maps, const pf_settings_t *settings, pf_irr_plan_t *out);

/* Someone else computes the irradiance points (the farm: its workers and
 * its own cores): points(ctx, maps, plan, main, deep) fills
 * main[0 .. plan->points) and, with plan->has_deep, deep[0 .. points) with
 * the records pf_irradiance_points makes; maps holds the global and
 * caustic trees by then. 0 or a status (the pass fails with it). */
typedef struct pf_irr_spread {
    int (*points)(void *ctx, const pf_photon_maps_t *maps, const pf_irr_plan_t *plan, pf_photon_t *main,
                  pf_photon_t *deep);
    void *ctx;
} pf_irr_spread_t;

/* pf_photon_merge with the irradiance points computed by spread (NULL:
 * here, as pf_photon_merge): the same maps, bit for bit, when spread's
 * points are right. */
int pf_photon_merge_spread(const pf_scene_t *scene, const pf_accel_t *accel, const pf_settings_t *settings,
                           const pf_photon_plan_t *plan, pf_photon_batch_t *batches, pf_photon_maps_t *maps,
                           pf_photon_stats_t *stats, const pf_irr_spread_t *spread);

/* A flag that, once non-zero (a signal handler sets it), stops a photon
 * pass under way: tracing stops within a block of photons per thread and the
 * pass returns PF_EINTERRUPTED before its next stage (kd-trees, irradiance).
 * Process-wide; NULL (the default): never. */
void pf_photon_set_cancel(volatile int *flag);

/* When the pass found no diffuse-to-diffuse transport (stats->gather_skipped),
 * sets s->gather to 0 and logs the skip; the final gather would add exactly
 * nothing. Call before the settings go to the renderer. */
void pf_photon_skip_gather(const pf_photon_stats_t *stats, pf_settings_t *s);

#endif
