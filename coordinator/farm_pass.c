/* farm_pass.c: progressive passes on the farm (job.h has the scheme): each
 * pass is a job of its own (job id job0 + pass, its own maps blob; the
 * scene blob's content, and so its hash, is the same, so a worker fetches
 * it once) rendered into f->img, then added to the running mean (accum.h).
 * The next pass's photons are traced while this one's tiles are gathered
 * (farm.c's photon thread, into maps of their own); its JOB goes out once
 * this pass's tiles are all in and its maps are ready. A pass cut short by
 * the deadline or a signal adds the tiles it finished.
 * Results of an earlier pass carry its job id and are dropped as stale.
 * Called from the event loop's thread. */
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "base/hash.h"
#include "base/log.h"
#include "coordinator/adapt.h"
#include "coordinator/farm.h"
#include "coordinator/farm_impl.h"
#include "photon/photonmap.h"

int pf_fm_progressive(const pf_fm_t *f) { return f->o->budget != NULL || f->o->passes > 1; }

/* Adds the done tiles of the current pass from f->img. Returns how many. */
static int s_add_done(pf_fm_t *f)
{
    int n = 0;
    uint32_t spp = (uint32_t)f->cur.spp;
    for (int i = 0; i < f->L.nt; i++) {
        const pf_tile_t *t = &f->L.t[i];
        if (t->state != PF_T_DONE)
            continue;
        const float *px = &f->img->rgb[3 * ((size_t)t->y0 * (size_t)f->img->width + t->x0)];
        if (f->counts)
            pf_accum_add_map(&f->acc, (int)t->x0, (int)t->y0, (int)t->w, (int)t->h, px, 3 * (size_t)f->img->width,
                             f->counts);
        else
            pf_accum_add(&f->acc, (int)t->x0, (int)t->y0, (int)t->w, (int)t->h, px, 3 * (size_t)f->img->width, spp);
        n++;
    }
    return n;
}

static void s_pass_log(pf_fm_t *f, int done)
{
    pf_farm_summary_t *sum = f->sum;
    const pf_settings_t *s = &f->cur;
    char left[48] = "", err[48] = "", ad[64];
    pf_adapt_note(f->counts, (size_t)f->img->width * (size_t)f->img->height, ad, sizeof ad);
    if (f->o->budget)
        snprintf(left, sizeof left, ", %.1f s left", pf_budget_left(f->o->budget));
    if (isfinite(sum->error_est))
        snprintf(err, sizeof err, ", est. relMSE %.2g", sum->error_est);
    pf_info("pass %d: %d spp%s, %llu photons (%llu so far), radius x%.3f, tiles %.2f s%s%s%s", s->pass + 1, s->spp, ad,
            (unsigned long long)(s->photons + s->caustic_photons), (unsigned long long)sum->photons_total,
            sqrt((double)pf_pass_shrink2(s->pass)), pf_now() - f->pass_start,
            done < f->L.nt ? " (cut short)" : "", err, left);
}

void pf_fm_pass_whole(pf_fm_t *f)
{
    pf_farm_summary_t *sum = f->sum;
    s_add_done(f);
    sum->passes++;
    sum->passes_whole++;
    sum->spp_total += (uint64_t)f->cur.spp;
    sum->error_est = pf_accum_error(&f->acc);
    if (f->o->budget)
        pf_budget_pass_done(f->o->budget, f->cur.spp, pf_now() - f->pass_start);
    s_pass_log(f, f->L.nt);
}

void pf_fm_pass_cut(pf_fm_t *f)
{
    pf_farm_summary_t *sum = f->sum;
    int n = s_add_done(f);
    sum->passes++;
    sum->cut_tiles = n;
    sum->cut_total = f->L.nt;
    sum->error_est = pf_accum_error(&f->acc);
    s_pass_log(f, n);
}

int pf_fm_pass_more(const pf_fm_t *f, volatile int *stop)
{
    if (stop && *stop)
        return 0;
    int next = f->cur_pass + 1;
    if (f->o->passes > 0 && next >= f->o->passes)
        return 0;
    if (next >= PF_MAX_PASSES)
        return 0;
    return f->o->budget ? pf_now() < pf_budget_tiles_deadline(f->o->budget) : 1;
}

int pf_fm_pass_reset(pf_fm_t *f, pf_error_t *err)
{
    f->sum->reissued += f->L.reissued;
    f->sum->duplicates += f->L.duplicates;
    pf_leases_t old = f->L;
    pf_fm_verify_free(f);
    if (pf_leases_init(&f->L, f->img->width, f->img->height, f->ts) != PF_OK || pf_fm_verify_init(f) != PF_OK) {
        pf_leases_free(&old);
        return pf_error_set(err, PF_ENOMEM, NULL, 0, "out of memory");
    }
    /* The typical tile time carries over (the stall and takeover clocks). */
    memcpy(f->L.times, old.times, sizeof old.times);
    f->L.ntimes = old.ntimes;
    f->L.itime = old.itime;
    pf_leases_free(&old);
    double now = pf_now();
    for (int i = 0; i < f->reg.nw; i++) {
        pf_worker_t *w = &f->reg.w[i];
        if (w->state == PF_W_JOB_SENT || w->state == PF_W_READY)
            w->state = PF_W_HELLO; /* the next pass's JOB goes out once its maps are ready */
        w->held = 0;
        w->asked = 0;
        w->stuck = 0;
        w->blob_sent = 0;
        w->result_at = now;
        if (w->state == PF_W_HELLO && pf_xfer_reset(f->xfer, i) != PF_OK)
            return pf_error_set(err, PF_ENOMEM, NULL, 0, "out of memory");
    }
    f->job_ready = 0;
    f->job = f->job0 + (uint64_t)(f->cur_pass + 1);
    if (f->job == 0)
        f->job = 1;
    return PF_OK;
}

int pf_fm_pass_plan(pf_fm_t *f, int pass, pf_settings_t *s)
{
    *s = f->ph.base;
    s->pass = pass;
    s->seed = pf_pass_seed(f->ph.base.seed, pass);
    return f->o->budget ? pf_budget_plan_pass_photons(f->o->budget, pass, s) : 0;
}

void pf_fm_pass_counts(pf_fm_t *f)
{
    f->counts = NULL;
    if (!f->o->adaptive || !pf_fm_progressive(f) || f->cur_pass < 1)
        return;
    size_t n = (size_t)f->img->width * (size_t)f->img->height;
    if (!f->counts_buf && !(f->counts_buf = malloc(n * sizeof *f->counts_buf)))
        return; /* uniform, as job.c does */
    if (pf_adapt_counts(&f->acc, f->cur.spp, f->counts_buf) == PF_OK)
        f->counts = f->counts_buf;
}

void pf_fm_pass_resolve(pf_fm_t *f)
{
    f->sum->unreached = pf_accum_resolve(&f->acc, f->img);
}

void pf_fm_checkpoint(pf_fm_t *f, int force)
{
    const char *path = f->o->checkpoint;
    if (!path || (!force && (f->L.ndone == f->ckpt_done || pf_now() - f->ckpt_at < PF_FARM_CKPT_S)))
        return;
    uint32_t(*rects)[4] = malloc((size_t)(f->L.nt ? f->L.nt : 1) * sizeof *rects);
    if (!rects)
        return;
    int n = 0, passes_done = f->cur_pass;
    pf_settings_t pass = f->cur;
    if (force && f->job_ready && f->L.ndone == f->L.nt) {
        /* A whole pass: the next one is planned afresh on resuming. */
        passes_done = f->cur_pass + 1;
        pass = f->ph.base;
        pass.pass = passes_done;
        pass.seed = pf_pass_seed(f->ph.base.seed, passes_done);
    } else {
        for (int i = 0; i < f->L.nt; i++) {
            const pf_tile_t *t = &f->L.t[i];
            if (t->state == PF_T_DONE) {
                rects[n][0] = t->x0;
                rects[n][1] = t->y0;
                rects[n][2] = t->w;
                rects[n][3] = t->h;
                n++;
            }
        }
    }
    pf_error_t err = { { 0 } };
    int rc = pf_ckpt_write(path, f->ckpt_key, passes_done, pf_fm_progressive(f) ? &f->acc : NULL, &pass, f->img,
                           (const uint32_t(*)[4])rects, n, &err);
    free(rects);
    f->ckpt_at = pf_now();
    f->ckpt_done = f->L.ndone;
    if (rc != PF_OK && pf_fm_may_log(&f->bad_log, 0.1))
        pf_warn("checkpoint not written: %s", err.msg);
}

int pf_fm_resume_load(pf_fm_t *f, const pf_scene_t *scene, const pf_settings_t *s, unsigned terms, pf_error_t *err)
{
    f->resumed_pass = -1;
    f->ckpt_key = pf_ckpt_key(scene, s, terms, f->o->passes, f->o->budget != NULL, f->ts);
    if (f->o->adaptive && pf_fm_progressive(f))
        f->ckpt_key = pf_hash_u64(f->ckpt_key, PF_ADAPT_KEY);
    if (!f->o->resume || !f->o->checkpoint)
        return PF_OK;
    pf_error_t e = { { 0 } };
    int rc = pf_ckpt_read(f->o->checkpoint, f->ckpt_key, s->width, s->height, &f->resumed, &e);
    if (rc == PF_EIO) {
        pf_info("no checkpoint to resume from (%s): starting afresh", e.msg);
        return PF_OK;
    }
    if (rc != PF_OK) {
        *err = e;
        return rc;
    }
    if (f->resumed.has_acc != pf_fm_progressive(f) || (!f->resumed.has_acc && f->resumed.passes_done > 0)) {
        pf_ckpt_free(&f->resumed);
        return pf_error_set(err, PF_EMISMATCH, f->o->checkpoint, 0, "the checkpoint is of another render");
    }
    if (f->resumed.has_acc) {
        pf_accum_free(&f->acc);
        f->acc = f->resumed.acc;
        f->resumed.has_acc = 0;
        memset(&f->resumed.acc, 0, sizeof f->resumed.acc);
    }
    f->resumed_pass = f->resumed.passes_done;
    f->sum->passes = f->sum->passes_whole = f->resumed.passes_done;
    pf_info("resuming from %s: %d pass%s done, %d tile%s of pass %d", f->o->checkpoint, f->resumed.passes_done,
            f->resumed.passes_done == 1 ? "" : "es", f->resumed.ntiles, f->resumed.ntiles == 1 ? "" : "s",
            f->resumed.passes_done + 1);
    return PF_OK;
}

int pf_fm_resume_tiles(pf_fm_t *f, pf_error_t *err)
{
    for (int k = 0; k < f->resumed.ntiles; k++) {
        const pf_ckpt_tile_t *c = &f->resumed.tiles[k];
        int ti = -1;
        for (int i = 0; i < f->L.nt && ti < 0; i++)
            if (f->L.t[i].x0 == c->x0 && f->L.t[i].y0 == c->y0 && f->L.t[i].w == c->w && f->L.t[i].h == c->h)
                ti = i;
        if (ti < 0)
            return pf_error_set(err, PF_EMISMATCH, f->o->checkpoint, 0, "a tile of the checkpoint is not a tile of "
                                "this render");
        for (uint32_t y = 0; y < c->h; y++)
            memcpy(&f->img->rgb[3 * ((size_t)(c->y0 + y) * (size_t)f->img->width + c->x0)], &c->px[3 * (size_t)y * c->w],
                   3 * (size_t)c->w * sizeof(float));
        pf_leases_finish(&f->L, &f->reg, ti);
    }
    f->ckpt_done = f->L.ndone;
    pf_ckpt_free(&f->resumed);
    return PF_OK;
}
