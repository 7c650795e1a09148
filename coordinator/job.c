/* job.c: a whole render in one process (--workers 0): Embree build, photon
 * pass, tiles over OpenMP, in one pass or progressive passes; see job.h.
 * Called from the main thread. */
#include "coordinator/job.h"

#include <errno.h>
#include <math.h>
#include <omp.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <unistd.h>

#include "base/hash.h"
#include "base/log.h"
#include "coordinator/accum.h"
#include "coordinator/adapt.h"
#include "coordinator/checkpoint.h"
#include "coordinator/progress.h"

enum { S_TILE = 32 };

int pf_job_render_local(const pf_scene_t *scene, const pf_settings_t *settings, unsigned terms, int show_progress,
                        pf_image_t *img, pf_job_summary_t *summary, pf_error_t *err)
{
    pf_job_run_t run = { .show_progress = show_progress };
    return pf_job_render(scene, settings, terms, &run, img, summary, err);
}

static void s_texel_note(const pf_frame_t *frame)
{
    if (frame->texels) {
        size_t direct, filled = pf_irrtex_filled(frame->texels, &direct);
        pf_debug("irradiance texels: side %g, %zu filled of %zu (%zu send hits to the full lookup)",
                 (double)pf_irrtex_side(frame->texels), filled, pf_irrtex_count(frame->texels), direct);
    }
}

/* One pass: the tiles over OpenMP, all of them. */
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
    pf_render_image(&ctx, img, s->threads, S_TILE, pf_progress_tiles, &bar);
    pf_progress_end(&bar);
    summary->render_s = pf_now() - t2;
    s_texel_note(frame);
}

/* The photon pass of settings s into the frame's (emptied) maps. */
static int s_photons(pf_frame_t *frame, pf_settings_t *s, int show_progress, pf_job_summary_t *summary,
                     pf_error_t *err)
{
    pf_progress_t bar;
    pf_progress_begin(&bar, "photons", show_progress);
    double t0 = pf_now();
    pf_frame_drop_maps(frame);
    int rc = pf_photon_pass(frame->scene, frame->accel, frame->lights, s, &frame->maps, &summary->photons);
    pf_progress_end(&bar);
    summary->photon_s += pf_now() - t0;
    if (rc != PF_OK)
        return pf_error_set(err, rc, NULL, 0, "photon pass failed: %s", pf_strerror(rc));
    summary->photons_total += s->photons + frame->maps.caustic_emitted;
    pf_photon_skip_gather(&summary->photons, s);
    pf_frame_ready(frame);
    return PF_OK;
}

/* One progressive pass's tiles over OpenMP into the accumulator, until they
 * are done, *stop is set, or the next tile would end past deadline (each
 * thread judges by its own tiles' mean time). Returns the tiles done. */
static int s_render_pass(const pf_render_ctx_t *ctx, int threads, pf_accum_t *acc, double deadline,
                         volatile int *stop, pf_progress_t *bar)
{
    int W = acc->width, H = acc->height;
    int tx = (W + S_TILE - 1) / S_TILE, ty = (H + S_TILE - 1) / S_TILE, total = tx * ty;
    int done = 0, quit = 0;
    uint32_t spp = (uint32_t)ctx->settings.spp;
#pragma omp parallel num_threads(threads)
    {
        pf_accel_thread_init();
        float *buf = malloc((size_t)S_TILE * S_TILE * 3 * sizeof *buf);
        PF_CHECK(buf != NULL);
        double spent = 0.0;
        int mine = 0;
#pragma omp for schedule(dynamic, 1)
        for (int t = 0; t < total; t++) {
            int q;
#pragma omp atomic read
            q = quit;
            double t0 = pf_now();
            if (!q && ((stop && *stop) || t0 + (mine ? spent / mine : 0.0) > deadline)) {
#pragma omp atomic write
                quit = 1;
                q = 1;
            }
            if (q)
                continue;
            int x0 = (t % tx) * S_TILE, y0 = (t / tx) * S_TILE;
            int w = x0 + S_TILE <= W ? S_TILE : W - x0, h = y0 + S_TILE <= H ? S_TILE : H - y0;
            pf_render_tile(ctx, x0, y0, w, h, buf);
            if (ctx->spp_map)
                pf_accum_add_map(acc, x0, y0, w, h, buf, 3 * (size_t)w, ctx->spp_map->n);
            else
                pf_accum_add(acc, x0, y0, w, h, buf, 3 * (size_t)w, spp);
            spent += pf_now() - t0;
            mine++;
            int d;
#pragma omp atomic capture
            d = ++done;
            if (bar && omp_get_thread_num() == 0)
                pf_progress_update(bar, d, total);
        }
        free(buf);
    }
    return done;
}

/* The pass's line in the log: what it added and where the render stands. */
static void s_pass_log(const pf_job_summary_t *sum, const pf_settings_t *s, const pf_render_ctx_t *ctx, int done,
                       int total, double pass_s, const pf_budget_t *b)
{
    char left[48] = "";
    if (b)
        snprintf(left, sizeof left, ", %.1f s left", pf_budget_left(b));
    char err[48] = "", ad[64];
    if (isfinite(sum->error_est))
        snprintf(err, sizeof err, ", est. relMSE %.2g", sum->error_est);
    pf_adapt_note(ctx->spp_map ? ctx->spp_map->n : NULL, (size_t)s->width * (size_t)s->height, ad, sizeof ad);
    pf_info("pass %d: %d spp%s, %llu photons (%llu so far), radius x%.3f, %.2f s%s%s%s", s->pass + 1, s->spp, ad,
            (unsigned long long)(s->photons + s->caustic_photons), (unsigned long long)sum->photons_total,
            sqrt((double)ctx->shrink2), pass_s, done < total ? " (cut short)" : "", err, left);
    (void)total;
}

/* Resuming (run->resume): the checkpoint's passes into *acc. Returns the
 * first pass to render (0: none there), or a status with err filled (a
 * checkpoint of another render, or a malformed one). In process only
 * whole passes are kept. */
static int s_resume(const pf_job_run_t *run, uint64_t key, const pf_settings_t *base, pf_accum_t *acc,
                    pf_job_summary_t *sum, pf_error_t *err)
{
    if (!run->resume || !run->checkpoint)
        return 0;
    pf_ckpt_t c;
    pf_error_t e = { { 0 } };
    int rc = pf_ckpt_read(run->checkpoint, key, base->width, base->height, &c, &e);
    if (rc == PF_EIO) {
        pf_info("no checkpoint to resume from (%s): starting afresh", e.msg);
        return 0;
    }
    if (rc != PF_OK) {
        *err = e;
        return rc;
    }
    if (!c.has_acc || c.ntiles) {
        pf_ckpt_free(&c);
        return pf_error_set(err, PF_EMISMATCH, run->checkpoint, 0, "the checkpoint is of another render");
    }
    pf_accum_free(acc);
    *acc = c.acc;
    c.has_acc = 0;
    int first = c.passes_done;
    pf_ckpt_free(&c);
    sum->passes = sum->passes_whole = first;
    pf_info("resuming from %s: %d pass%s done", run->checkpoint, first, first == 1 ? "" : "es");
    return first;
}

/* The passes done (first `passes` of them, in acc) to the checkpoint. */
static void s_checkpoint(const pf_job_run_t *run, uint64_t key, const pf_settings_t *base, int passes,
                         const pf_accum_t *acc, const pf_image_t *img)
{
    if (!run->checkpoint)
        return;
    pf_settings_t next = *base;
    next.pass = passes;
    next.seed = pf_pass_seed(base->seed, passes);
    pf_error_t e = { { 0 } };
    if (pf_ckpt_write(run->checkpoint, key, passes, acc, &next, img, NULL, 0, &e) != PF_OK)
        pf_warn("checkpoint not written: %s", e.msg);
}

/* Progressive passes into img (allocated), as run says. */
static int s_progressive(pf_frame_t *frame, const pf_settings_t *base, unsigned terms, const pf_job_run_t *run,
                         pf_image_t *img, pf_job_summary_t *sum, pf_error_t *err)
{
    pf_accum_t acc;
    if (pf_accum_init(&acc, base->width, base->height) != PF_OK)
        return pf_error_set(err, PF_ENOMEM, NULL, 0, "cannot allocate the passes' %dx%d sums", base->width,
                            base->height);
    uint64_t key = pf_ckpt_key(frame->scene, base, terms, run->passes, run->budget != NULL, S_TILE);
    if (run->adaptive) /* another image: its checkpoint is another render's */
        key = pf_hash_u64(key, PF_ADAPT_KEY);
    int first = s_resume(run, key, base, &acc, sum, err);
    if (first < 0) {
        pf_accum_free(&acc);
        return first;
    }
    pf_budget_t *b = run->budget;
    pf_settings_t plan = *base;
    int rc = b ? pf_budget_plan_photons(b, frame, &plan) : PF_OK; /* calibration: the photon rate */
    if (rc != PF_OK)
        pf_error_set(err, rc, NULL, 0, "photon pass failed: %s", pf_strerror(rc));
    double deadline = b ? pf_budget_tiles_deadline(b) : INFINITY;
    int tiles = ((base->width + S_TILE - 1) / S_TILE) * ((base->height + S_TILE - 1) / S_TILE);
    uint16_t *counts = run->adaptive ? malloc((size_t)base->width * (size_t)base->height * sizeof *counts) : NULL;
    pf_spp_map_t map = { 0, 0, base->width, base->height, counts };
    sum->error_est = NAN;
    for (int pass = first; rc == PF_OK && pass < PF_MAX_PASSES; pass++) {
        if ((run->passes > 0 && pass >= run->passes) || (run->stop && *run->stop))
            break;
        pf_settings_t s = *base;
        s.pass = pass;
        s.seed = pf_pass_seed(base->seed, pass);
        double t0 = pf_now();
        if (b && pf_budget_plan_pass_photons(b, pass, &s) && pass > first)
            break; /* no pass fits in the time left */
        rc = s_photons(frame, &s, run->show_progress, sum, err);
        if (rc == PF_EINTERRUPTED && run->stop && *run->stop)
            rc = PF_OK; /* the passes done make the image */
        if (rc != PF_OK || (run->stop && *run->stop))
            break;
        if (b) {
            pf_budget_photons_done(b, pf_now() - t0, s.photons + frame->maps.caustic_emitted);
            pf_budget_plan_pass_spp(b, frame, terms, s.threads, pass, t0, &s);
            if (pass == 0)
                pf_budget_log(b, &s);
        }
        pf_render_ctx_t ctx;
        pf_render_ctx_init(&ctx, frame, &s);
        ctx.terms = terms;
        ctx.dropped = &sum->dropped_samples;
        /* adaptive: from the second pass on (the first has no estimate) */
        if (counts && pass > 0 && pf_adapt_counts(&acc, s.spp, counts) == PF_OK)
            ctx.spp_map = &map;
        pf_progress_t bar;
        pf_progress_begin(&bar, "render", run->show_progress);
        double t1 = pf_now();
        /* The first pass always finishes (the image needs every tile), unless stopped. */
        int done = s_render_pass(&ctx, s.threads, &acc, pass > first ? deadline : INFINITY, run->stop, &bar);
        pf_progress_end(&bar);
        double render_s = pf_now() - t1;
        sum->render_s += render_s;
        sum->passes++;
        sum->settings = s;
        if (done == tiles) {
            sum->passes_whole++;
            sum->spp_total += (uint64_t)s.spp;
            if (b)
                pf_budget_pass_done(b, s.spp, render_s);
            s_checkpoint(run, key, base, pass + 1, &acc, img);
        } else {
            sum->cut_tiles = done;
            sum->cut_total = tiles;
        }
        sum->error_est = pf_accum_error(&acc);
        s_pass_log(sum, &s, &ctx, done, tiles, pf_now() - t0, b);
        if (done < tiles)
            break;
    }
    s_texel_note(frame);
    free(counts);
    sum->interrupted = run->stop && *run->stop;
    if (rc == PF_OK && sum->passes == 0)
        rc = pf_error_set(err, sum->interrupted ? PF_EINTERRUPTED : PF_ETIMEOUT, NULL, 0,
                          sum->interrupted ? "interrupted before the first pass" : "no pass fits in the time limit");
    if (rc == PF_OK) {
        sum->unreached = pf_accum_resolve(&acc, img);
        if (sum->unreached == (size_t)base->width * (size_t)base->height)
            rc = pf_error_set(err, PF_EINTERRUPTED, NULL, 0, "interrupted before any tile was done");
    }
    if (rc == PF_OK && !sum->interrupted && run->checkpoint && remove(run->checkpoint) != 0 && errno != ENOENT)
        pf_warn("cannot remove the checkpoint %s: %s", run->checkpoint, strerror(errno));
    pf_accum_free(&acc);
    return rc;
}

int pf_job_render(const pf_scene_t *scene, const pf_settings_t *settings, unsigned terms, const pf_job_run_t *run,
                  pf_image_t *img, pf_job_summary_t *summary, pf_error_t *err)
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
    summary->accel_s = pf_now() - t0;
    summary->error_est = NAN;

    if (run->budget || run->passes > 1) {
        rc = s_progressive(&frame, &s, terms, run, img, summary, err);
    } else {
        rc = s_photons(&frame, &s, run->show_progress, summary, err);
        if (rc == PF_OK) {
            pf_info("photon pass: %llu global + %llu caustic photons stored, %llu irradiance points "
                    "(trace %.2f s, kd-trees %.2f s, irradiance %.2f s)",
                    (unsigned long long)summary->photons.global_stored,
                    (unsigned long long)summary->photons.caustic_stored,
                    (unsigned long long)summary->photons.irradiance_points, summary->photons.trace_s,
                    summary->photons.build_s, summary->photons.irradiance_s);
            s_render(&frame, &s, terms, run->show_progress, img, summary);
            summary->passes = summary->passes_whole = 1;
            summary->spp_total = (uint64_t)s.spp;
            summary->settings = s;
        }
    }
    if (rc == PF_OK) {
        size_t neg = 0;
        summary->bad_pixels = pf_image_count_bad(img, &neg) + neg;
    } else {
        pf_image_free(img);
    }
    pf_frame_close(&frame);
    summary->total_s = pf_now() - t0;
    return rc;
}
