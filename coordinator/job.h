/* job.h: one render job in this process: load nothing, own nothing from the
 * caller; build the Embree structure, run the photon pass, render the tiles
 * and return the image with a summary. The farm (farm.h) splits the same
 * steps between coordinator and workers: the coordinator runs the photon
 * pass, the workers rebuild the frame from its blobs and render the tiles.
 *
 * Progressive rendering (--passes, --time-limit): the job is a sequence of
 * independent passes, each with its own photons and camera samples (its
 * seed pf_pass_seed(seed, i)) and photon estimates shrunk by
 * pf_pass_shrink2(i) (photon/photonmap.h); the image is their running mean
 * (accum.h), valid after every pass. One pass is the render without passes,
 * bit for bit. */
#ifndef PF_JOB_H
#define PF_JOB_H

#include "coordinator/budget.h"
#include "image/image.h"
#include "photon/trace.h"
#include "render/render.h"
#include "scene/scene.h"

typedef struct pf_job_summary {
    pf_photon_stats_t photons; /* the last pass's */
    double accel_s, render_s, total_s;
    double photon_s;           /* all passes' photon passes */
    int threads;
    size_t bad_pixels; /* non-finite or negative channels in the result (must stay 0) */
    uint64_t dropped_samples; /* camera samples left out for being non-finite or negative (should be 0) */
    pf_settings_t settings; /* the settings rendered with (a time limit chooses some; the last pass's) */
    /* Progressive passes: passes begun (the last maybe cut short), whole
     * ones, camera samples per pixel and photons emitted over them all, the
     * estimated relMSE (pf_accum_error; NaN with one pass), the tiles of a
     * pass cut short that made it in, and pixels no pass reached. */
    int passes, passes_whole;
    uint64_t spp_total, photons_total;
    double error_est;
    int cut_tiles, cut_total;
    size_t unreached;
    int interrupted; /* stopped by run->stop */
} pf_job_summary_t;

/* How to run a job. */
typedef struct pf_job_run {
    int show_progress;      /* progress bars on stderr */
    pf_budget_t *budget;    /* a time limit: passes until its deadline (budget.h); NULL: none */
    int passes;             /* progressive passes (0: one, or as many as the time limit allows) */
    volatile int *stop;     /* when it becomes non-zero (a signal), the render stops at the next tile and the
                               passes done make the image; NULL: never */
    const char *checkpoint; /* progressive passes: the passes done are kept there (checkpoint.h) after each, and
                               the file removed when the render ends well; NULL: none */
    int resume;             /* go on from the checkpoint's passes (none there: start afresh) */
    int adaptive;           /* progressive passes: from the second on, samples where the error is (adapt.h) */
} pf_job_run_t;

/* Renders scene with settings (size, threads, photons, ...) and terms (a
 * PF_TERM_* mask) into *img (allocated here), in one pass. show_progress
 * draws a progress bar on stderr. 0 or a status with err filled. */
int pf_job_render_local(const pf_scene_t *scene, const pf_settings_t *settings, unsigned terms, int show_progress,
                        pf_image_t *img, pf_job_summary_t *summary, pf_error_t *err);

/* The same as run says: progressive passes, a time limit (photon counts
 * and spp chosen to end by budget->deadline), a stop flag. summary->settings
 * holds the last pass's settings. Stopped by run->stop, the image of the
 * passes done is returned (PF_OK, summary->interrupted set), or
 * PF_EINTERRUPTED when no tile was done. */
int pf_job_render(const pf_scene_t *scene, const pf_settings_t *settings, unsigned terms, const pf_job_run_t *run,
                  pf_image_t *img, pf_job_summary_t *summary, pf_error_t *err);

#endif
