/* budget.h: `--time-limit`: the photon counts and the samples per pixel that
 * fit a wall-clock limit on this machine (or farm), chosen by measuring, not
 * guessing.
 *
 * How it decides (docs/benchmarks.md shows the curves behind the rules):
 *   1. Photons. A calibration pass of PF_BUDGET_CAL_PHOTONS photons per map
 *      (trace, kd-trees, irradiance; the faster of two runs) gives the
 *      seconds per photon; the photon
 *      pass then gets PF_BUDGET_PHOTON_SHARE of the time left, within
 *      [PF_BUDGET_MIN_PHOTONS, PF_BUDGET_MAX_PHOTONS] per map. The maps'
 *      error matters less than the pixels' (the renders at 512x512 say so:
 *      four times the photons lower relMSE by 9 %, four times the camera
 *      samples by 34 %), hence the small share.
 *   2. Samples. With the maps built, a probe renders PF_BUDGET_PROBE_PIXELS
 *      pixels in 8 x 8 blocks on a lattice over the image, twice: at 2 and
 *      at 8 samples per pixel, which gives a pixel's thread-seconds as
 *      p + spp c for this scene and view (p: the work done once per pixel,
 *      such as the gather filter's footprint and the caustic estimates its
 *      samples share; the filtered gathers of a block's border costed as the
 *      render's tiles will carry them); spp is the number of samples per
 *      pixel that fills the time left (less a reserve for writing the image
 *      and a safety margin) on all the threads that will render: this
 *      process's, or every worker's together.
 * The image is then rendered in one pass with that spp, so it is the same
 * image a render with those settings gives (deterministic given the choices;
 * the choices depend on the machine's speed). */
#ifndef PF_BUDGET_H
#define PF_BUDGET_H

#include "render/frame.h"
#include "scene/scene.h"

#define PF_BUDGET_CAL_PHOTONS 20000
#define PF_BUDGET_PHOTON_SHARE 0.12
#define PF_BUDGET_MIN_PHOTONS PF_BUDGET_CAL_PHOTONS
#define PF_BUDGET_MAX_PHOTONS 4000000
#define PF_BUDGET_PROBE_PIXELS 8192
/* Per camera sample under a time limit: one final-gather ray shared over the
 * 5 x 5 pixels around (settings.gather_filter 2) and two shadow rays. At
 * equal time (10 s, cornell-spheres 512x512) these gave relMSE 0.0014-0.0016,
 * against 0.0019 with 2 gather rays, 0.0018 with a 3 x 3 filter, 0.0015-0.0017
 * with one or three shadow rays, and 0.0055 for the 4 unfiltered gather
 * rays chosen before the filter existed. */
#define PF_BUDGET_GATHER 1
#define PF_BUDGET_LIGHT_SAMPLES 2
#define PF_BUDGET_GATHER_FILTER 2

typedef struct pf_budget {
    double deadline;    /* pf_now() by which the image must be written */
    double limit_s;     /* the limit as given */
    int render_threads; /* threads that will render the image, all workers together */
    int tile;           /* the render's tile size (its filtered-gather border scales with it) */
    int fix_photons, fix_caustic, fix_spp; /* given on the command line: kept as they are */
    /* Filled in as the plan is made, for the summary. */
    double photon_s_per_photon; /* calibration: seconds per photon */
    double pixel_s, sample_s;   /* thread-seconds a pixel costs: pixel_s + spp * sample_s */
    double planned_render_s;
} pf_budget_t;

/* A budget of limit_s seconds counted from start (pf_now() at program start). */
void pf_budget_init(pf_budget_t *b, double start, double limit_s, int render_threads, int tile);

/* Seconds left before the deadline (negative when past it). */
double pf_budget_left(const pf_budget_t *b);

/* Chooses s->photons and s->caustic_photons (and s->gather) for the time
 * left, running a small calibration photon pass with s->threads threads.
 * 0 or a status (out of memory, Embree). */
int pf_budget_plan_photons(pf_budget_t *b, const pf_frame_t *frame, pf_settings_t *s);

/* Chooses s->spp for the time left, with the frame's maps built: renders
 * the probe with local_threads threads. The frame must be ready
 * (pf_frame_ready) as the real render's will be. Always succeeds; spp is at least 1 (a warning
 * says when even that will not fit). */
void pf_budget_plan_spp(pf_budget_t *b, const pf_frame_t *frame, unsigned terms, int local_threads, pf_settings_t *s);

/* Logs the plan: the settings chosen and the measurements behind them. */
void pf_budget_log(const pf_budget_t *b, const pf_settings_t *s);

#endif
