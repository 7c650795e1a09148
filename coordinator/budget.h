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
 *   3. Passes. The render is progressive (photon/photonmap.h, PF_PASS_ALPHA):
 *      pass i is planned to take pf_budget_pass_seconds(i), short at first
 *      (an image exists early, for Ctrl-C and short limits) and doubling up
 *      to a third of the limit (a pass pays a fixed cost per pixel, the
 *      gather filter's records and the texels' fills, and its photons
 *      blur over a pass's own: few long passes beat many short ones at
 *      equal time); its photons get PF_BUDGET_PASS_PHOTON_SHARE of it
 *      at the measured rate, its spp the rest at the measured cost of a
 *      sample (the probe's for pass 0, the last pass's after). The last
 *      pass is planned to end by the deadline; if it runs late it is cut at
 *      tile granularity (the tiles it finished count: accum.h), so the
 *      image is written in time.
 * The choices depend on the machine's speed; the image of given pass
 * settings does not. */
#ifndef PF_BUDGET_H
#define PF_BUDGET_H

#include "render/frame.h"
#include "scene/scene.h"

#define PF_BUDGET_CAL_PHOTONS 20000
#define PF_BUDGET_PHOTON_SHARE 0.12
/* A progressive pass's share for its photons: larger than one pass's, as a
 * pass's photon estimates blur over the k nearest of its own photons only
 * (cornell-spheres, 512x512, 32 samples per pixel in all: 8 passes of 100k
 * photons per map gave relMSE 0.00100, one pass of 800k 0.00078, one of
 * 100k 0.00129). */
#define PF_BUDGET_PASS_PHOTON_SHARE 0.2
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
    /* Progressive passes: wall seconds of a pass's render, fixed + spp *
     * per_spp (the probe's, then measured); the photon rate in wall seconds
     * per photon emitted (calibration, then measured). */
    double pass_fixed_s, pass_spp_s, pass_photon_s;
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

/* Progressive passes under the limit (step 3 above). */

/* The wall seconds pass `pass` is planned to take: a geometric series from
 * limit / 40 (within [0.25, 2] s) by 2, to at most limit / 3. */
double pf_budget_pass_seconds(const pf_budget_t *b, int pass);

/* The deadline of the tiles: by then every tile of the last pass must be
 * done, leaving the reserve for writing the image. */
double pf_budget_tiles_deadline(const pf_budget_t *b);

/* Sets s->photons and s->caustic_photons (those not fixed on the command
 * line, and not 0) for pass `pass`: PF_BUDGET_PASS_PHOTON_SHARE of its
 * seconds (less when fewer are left) at the measured rate. Needs
 * pf_budget_plan_photons's calibration first. 0 when a pass (its photons
 * and a few tiles: the rest is cut at the deadline) still fits in the time
 * left, 1 when none does (the render should stop). */
int pf_budget_plan_pass_photons(pf_budget_t *b, int pass, pf_settings_t *s);

/* The photon pass of a pass took photon_s for `emitted` photons: the rate
 * for the next ones. */
void pf_budget_photons_done(pf_budget_t *b, double photon_s, uint64_t emitted);

/* Sets s->spp (unless fixed) for pass `pass`, its maps built, so the pass
 * ends on plan (its seconds, counted from pass_start, or the tiles'
 * deadline). Pass 0 probes the frame's cost first (as pf_budget_plan_spp);
 * later ones use the measured cost. At least 1. */
void pf_budget_plan_pass_spp(pf_budget_t *b, const pf_frame_t *frame, unsigned terms, int local_threads, int pass,
                             double pass_start, pf_settings_t *s);

/* A pass's tiles took render_s at spp samples per pixel, whole: the cost of
 * a sample for the next. */
void pf_budget_pass_done(pf_budget_t *b, int spp, double render_s);

/* Logs the plan: the settings chosen and the measurements behind them. */
void pf_budget_log(const pf_budget_t *b, const pf_settings_t *s);

#endif
