/* job.c: a whole render in one process (--workers 0): Embree build, photon
 * pass, tiles over OpenMP; see job.h. Called from the main thread. */
#include "coordinator/job.h"

#include <omp.h>
#include <stdio.h>
#include <string.h>
#include <unistd.h>

#include "common/accel.h"
#include "common/irrtex.h"
#include "common/light.h"
#include "common/log.h"
#include "coordinator/progress.h"

int pf_job_render_local(const pf_scene_t *scene, const pf_settings_t *settings, unsigned terms, int show_progress,
                        pf_image_t *img, pf_job_summary_t *summary, pf_error_t *err)
{
    return pf_job_render(scene, settings, terms, show_progress, NULL, img, summary, err);
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
    pf_accel_t *accel = pf_accel_create(scene, err);
    pf_lights_t *lights = pf_lights_build(scene);
    if (!accel || !lights) {
        pf_accel_destroy(&accel);
        pf_lights_destroy(&lights);
        pf_image_free(img);
        return accel ? pf_error_set(err, PF_ENOMEM, NULL, 0, "out of memory") : PF_EEMBREE;
    }
    double t1 = pf_now();
    summary->accel_s = t1 - t0;

    pf_photon_maps_t maps;
    memset(&maps, 0, sizeof maps);
    pf_progress_t bar;
    pf_progress_begin(&bar, "photons", show_progress);
    rc = budget ? pf_budget_plan_photons(budget, scene, accel, lights, &s) : PF_OK;
    if (rc == PF_OK)
        rc = pf_photon_pass(scene, accel, lights, &s, &maps, &summary->photons);
    pf_progress_end(&bar);
    if (rc == PF_OK) {
        pf_info("photon pass: %llu global + %llu caustic photons stored, %llu irradiance points "
                "(trace %.2f s, kd-trees %.2f s, irradiance %.2f s)",
                (unsigned long long)summary->photons.global_stored,
                (unsigned long long)summary->photons.caustic_stored,
                (unsigned long long)summary->photons.irradiance_points, summary->photons.trace_s,
                summary->photons.build_s, summary->photons.irradiance_s);
        pf_photon_skip_gather(&summary->photons, &s);
        if (pf_photon_maps_index(&maps, scene, accel) != PF_OK)
            pf_warn("out of memory for the irradiance lookup grid: rendering goes on, slower");
        if (budget) {
            pf_budget_plan_spp(budget, scene, accel, lights, &maps, terms, threads, &s);
            pf_budget_log(budget, &s);
        }
        pf_render_ctx_t ctx;
        pf_render_ctx_init(&ctx, scene, accel, lights, &maps, &s);
        ctx.terms = terms;
        ctx.dropped = &summary->dropped_samples;
        double t2 = pf_now();
        pf_progress_begin(&bar, "render", show_progress);
        pf_render_image(&ctx, img, threads, 32, pf_progress_tiles, &bar);
        pf_progress_end(&bar);
        summary->render_s = pf_now() - t2;
        if (maps.texels) {
            size_t direct, filled = pf_irrtex_filled(maps.texels, &direct);
            pf_debug("irradiance texels: side %g, %zu filled of %zu (%zu send hits to the full lookup)",
                     (double)pf_irrtex_side(maps.texels), filled, pf_irrtex_count(maps.texels), direct);
        }
        size_t neg = 0;
        summary->bad_pixels = pf_image_count_bad(img, &neg) + neg;
    } else {
        pf_error_set(err, rc, NULL, 0, "photon pass failed: %s", pf_strerror(rc));
        pf_image_free(img);
    }
    pf_photon_maps_free(&maps);
    pf_lights_destroy(&lights);
    pf_accel_destroy(&accel);
    summary->total_s = pf_now() - t0;
    summary->settings = s;
    return rc;
}
