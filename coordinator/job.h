/* job.h: one render job in this process: load nothing, own nothing from the
 * caller; build the Embree structure, run the photon pass, render the tiles
 * and return the image with a summary. The farm (farm.h) splits the same
 * steps between coordinator and workers: the coordinator runs the photon
 * pass, the workers rebuild the frame from its blobs and render the tiles. */
#ifndef PF_JOB_H
#define PF_JOB_H

#include "coordinator/budget.h"
#include "image/image.h"
#include "photon/trace.h"
#include "render/render.h"
#include "scene/scene.h"

typedef struct pf_job_summary {
    pf_photon_stats_t photons;
    double accel_s, render_s, total_s;
    int threads;
    size_t bad_pixels; /* non-finite or negative channels in the result (must stay 0) */
    uint64_t dropped_samples; /* camera samples left out for being non-finite or negative (should be 0) */
    pf_settings_t settings; /* the settings rendered with (a time limit chooses some) */
} pf_job_summary_t;

/* Renders scene with settings (size, threads, photons, ...) and terms (a
 * PF_TERM_* mask) into *img (allocated here). show_progress draws a progress
 * bar on stderr. 0 or a status with err filled. */
int pf_job_render_local(const pf_scene_t *scene, const pf_settings_t *settings, unsigned terms, int show_progress,
                        pf_image_t *img, pf_job_summary_t *summary, pf_error_t *err);

/* The same under a time limit when budget is not NULL: the photon counts and
 * spp are chosen to finish by budget->deadline (budget.h); summary->settings
 * holds what was chosen. */
int pf_job_render(const pf_scene_t *scene, const pf_settings_t *settings, unsigned terms, int show_progress,
                  pf_budget_t *budget, pf_image_t *img, pf_job_summary_t *summary, pf_error_t *err);

#endif
