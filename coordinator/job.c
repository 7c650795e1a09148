/* job.c: a whole render in one process (--workers 0): Embree build, photon
 * pass, tiles over OpenMP; see job.h. Called from the main thread. */
#include "coordinator/job.h"

#include <omp.h>
#include <stdio.h>
#include <string.h>
#include <unistd.h>

#include "base/log.h"
#include "coordinator/progress.h"

int pf_job_render_local(const pf_scene_t *scene, const pf_settings_t *settings, unsigned terms, int show_progress,
                        pf_image_t *img, pf_job_summary_t *summary, pf_error_t *err)
{
    return pf_job_render(scene, settings, terms, show_progress, NULL, img, summary, err);
}

/* The tiles over OpenMP, once the frame is ready. */
static void s_render(pf_frame_t *frame, const pf_settings_t *s, unsigned terms, int show_progress, pf_image_t *img,
                     pf_job_summary_t *summary)
{
    pf_render_ctx_t ctx;
    pf_render_ctx_init(&ctx, frame, s);
    ctx.terms = terms;
    ctx.dropped = &summary->dropped_samples;
    double t2 = pf_now();
    pf_progress_t bar;
    pf_progress_begin(&bar, "render", show_progress);
    pf_render_image(&ctx, img, s->threads, 32, pf_progress_tiles, &bar);
    pf_progress_end(&bar);
    summary->render_s = pf_now() - t2;
    if (frame->texels) {
        size_t direct, filled = pf_irrtex_filled(frame->texels, &direct);
        pf_debug("irradiance texels: side %g, %zu filled of %zu (%zu send hits to the full lookup)",
                 (double)pf_irrtex_side(frame->texels), filled, pf_irrtex_count(frame->texels), direct);
    }
    size_t neg = 0;
    summary->bad_pixels = pf_image_count_bad(img, &neg) + neg;
}

int pf_job_render(const pf_scene_t *scene, const pf_settings_t *settings, unsigned terms, int show_progress,
                  pf_budget_t *budget, pf_image_t *img, pf_job_summary_t *summary, pf_error_t *err)
{
    memset(summary, 0, sizeof *summary);
    double t0 = pf_now();
    int threads = settings->threads > 0 ? settings->threads : omp_get_num_procs();
    summary->threads = threads;
    pf_settings_t s = *settings;
    s.threads = threads;

    int rc = pf_image_alloc(img, s.width, s.height);
    if (rc)
        return pf_error_set(err, rc, NULL, 0, "cannot allocate a %dx%d image", s.width, s.height);
    pf_frame_t frame;
    rc = pf_frame_open(&frame, scene, err);
    if (rc != PF_OK) {
        pf_image_free(img);
        return rc;
    }
    double t1 = pf_now();
    summary->accel_s = t1 - t0;

    pf_progress_t bar;
    pf_progress_begin(&bar, "photons", show_progress);
    rc = budget ? pf_budget_plan_photons(budget, &frame, &s) : PF_OK;
    if (rc == PF_OK)
        rc = pf_photon_pass(scene, frame.accel, frame.lights, &s, &frame.maps, &summary->photons);
    pf_progress_end(&bar);
    if (rc == PF_OK) {
        pf_info("photon pass: %llu global + %llu caustic photons stored, %llu irradiance points "
                "(trace %.2f s, kd-trees %.2f s, irradiance %.2f s)",
                (unsigned long long)summary->photons.global_stored,
                (unsigned long long)summary->photons.caustic_stored,
                (unsigned long long)summary->photons.irradiance_points, summary->photons.trace_s,
                summary->photons.build_s, summary->photons.irradiance_s);
        pf_photon_skip_gather(&summary->photons, &s);
        pf_frame_ready(&frame);
        if (budget) {
            pf_budget_plan_spp(budget, &frame, terms, threads, &s);
            pf_budget_log(budget, &s);
        }
        s_render(&frame, &s, terms, show_progress, img, summary);
    } else {
        pf_error_set(err, rc, NULL, 0, "photon pass failed: %s", pf_strerror(rc));
        pf_image_free(img);
    }
    pf_frame_close(&frame);
    summary->total_s = pf_now() - t0;
    summary->settings = s;
    return rc;
}
