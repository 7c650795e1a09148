/* photon_trace.h: the photon pass. Traces global and caustic photons from the
 * lights and builds the global, caustic and precomputed-irradiance maps. */
#ifndef PF_PHOTON_TRACE_H
#define PF_PHOTON_TRACE_H

#include "accel/accel.h"
#include "light/light.h"
#include "photon/photonmap.h"
#include "scene/scene.h"

/* The most irradiance points one map gets, unless that would space them
 * wider than their estimates reach (pf_irradiance_points_stride). */
#define PF_IRRADIANCE_MAX_POINTS ((size_t)500000)

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

/* Runs the photon pass with settings->threads OpenMP threads. Photon i draws
 * from its own counter-based stream and photons are stored in index order,
 * so the maps are identical for any thread count. 0 or a status. */
int pf_photon_pass(const pf_scene_t *scene, const pf_accel_t *accel, const pf_lights_t *lights,
                   const pf_settings_t *settings, pf_photon_maps_t *maps, pf_photon_stats_t *stats);

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
