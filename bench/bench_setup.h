/* bench_setup.h: what the bench programs share: a scene loaded with its
 * accelerator and lights, and its photon maps traced with given settings.
 * Failures end the program with a message (these are tools, not library). */
#ifndef PF_BENCH_SETUP_H
#define PF_BENCH_SETUP_H

#include <stdio.h>
#include <stdlib.h>

#include "common/accel.h"
#include "common/light.h"
#include "common/log.h"
#include "coordinator/photon_trace.h"

typedef struct bench_scene {
    pf_scene_t *scene; /* its settings are the scene file's */
    pf_accel_t *accel;
    pf_lights_t *lights;
} bench_scene_t;

static inline bench_scene_t bench_load(const char *path)
{
    pf_log_set_level(PF_LOG_WARN);
    pf_error_t err;
    bench_scene_t b = { pf_scene_load(path, &err), NULL, NULL };
    if (!b.scene) {
        fprintf(stderr, "%s\n", err.msg);
        exit(1);
    }
    b.accel = pf_accel_create(b.scene, &err);
    b.lights = pf_lights_build(b.scene);
    if (!b.accel || !b.lights) {
        fprintf(stderr, "%s: %s\n", path, b.accel ? "out of memory for the lights" : err.msg);
        exit(1);
    }
    return b;
}

static inline void bench_photon_pass(const bench_scene_t *b, const pf_settings_t *s, pf_photon_maps_t *maps,
                                     pf_photon_stats_t *st)
{
    if (pf_photon_pass(b->scene, b->accel, b->lights, s, maps, st) != PF_OK) {
        fprintf(stderr, "photon pass failed (out of memory)\n");
        exit(1);
    }
}

static inline void bench_free(bench_scene_t *b)
{
    pf_lights_destroy(&b->lights);
    pf_accel_destroy(&b->accel);
    pf_scene_destroy(&b->scene);
}

#endif
