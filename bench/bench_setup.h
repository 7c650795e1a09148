/* bench_setup.h: what the bench programs share: a scene loaded with its
 * accelerator and lights, and its photon maps traced with given settings.
 * Failures end the program with a message (these are tools, not library). */
#ifndef PF_BENCH_SETUP_H
#define PF_BENCH_SETUP_H

#include <stdio.h>
#include <stdlib.h>

#include "base/log.h"
#include "load/load.h"
#include "photon/trace.h"
#include "render/frame.h"

/* Loads the scene at path into a frame (its settings are the scene
 * file's); exits with a message on failure. */
static inline pf_frame_t bench_load(const char *path)
{
    pf_log_set_level(PF_LOG_WARN);
    pf_error_t err;
    pf_scene_t *scene = pf_scene_load(path, &err);
    pf_frame_t f;
    if (!scene || pf_frame_open_owned(&f, &scene, &err) != PF_OK) {
        fprintf(stderr, "%s\n", err.msg);
        exit(1);
    }
    return f;
}

/* The photon pass into the frame's maps; exits on failure. */
static inline void bench_photon_pass(pf_frame_t *f, const pf_settings_t *s, pf_photon_stats_t *st)
{
    if (pf_photon_pass(f->scene, f->accel, f->lights, s, &f->maps, st) != PF_OK) {
        fprintf(stderr, "photon pass failed (out of memory)\n");
        exit(1);
    }
}

#endif
