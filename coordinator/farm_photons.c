/* farm_photons.c: every photon pass spread over the workers (farm_impl.h).
 *
 * The photon thread frames the scene blob first, so that welcomed workers
 * can fetch it and trace photon batches while the pass is under way, then
 * traces batches itself (ph_batches.h: it takes free ones, and steals leased
 * ones when none is free, so it never waits for a worker); the event loop
 * leases free batches to welcomed workers that have no JOB yet, one range at
 * a time (PHOTON_REQ), and takes their PHOTONS in. When every batch is done
 * the thread merges them in batch order and builds the trees and the
 * irradiance as the in-process pass does: the maps are the same bits for any
 * number of workers, and the coordinator still builds them once.
 *
 * A later progressive pass's photons are traced while the workers gather
 * the pass before: the photon thread traces free batches as it goes, and a
 * worker that has its JOB and is READY is leased batches (queued on it
 * behind its tiles) when it would otherwise idle (no tile left in the
 * queue) or when the photon pass lags the tiles (a smaller share of its
 * batches done than of the pass's tiles: the next JOB would wait for the
 * maps). Between passes (no JOB out) every welcomed worker takes batches,
 * as in the first pass. A later pass's scene blob is the JOB's (the same
 * content and hash every pass), which the workers already hold.
 *
 * Spot checks (ph_batches.h): the photon thread re-traces a secret-seeded
 * sample of each worker's batches and compares them bit for bit; a worker
 * caught is struck here, barred from photon batches for the rest of the
 * job, and every batch it returned this pass is traced again.
 *
 * Hostile peers: a PHOTONS that contradicts the plan or its earlier parts is
 * a strike (its batch goes back to the free list); a late or duplicate one
 * is dropped and counted, no strike (a slow worker is not a liar). A worker
 * fetches the scene blob before its JOB only after a PHOTON_REQ.
 *
 * Threads: pf_fm_photons_spread runs in the photon thread; the rest in the
 * event loop's. */
#include <inttypes.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "base/hash.h"
#include "base/log.h"
#include "coordinator/farm.h"
#include "coordinator/farm_impl.h"
#include "proto/sceneblob.h"

_Static_assert(PF_PHOTON_MAX_BATCHES == PF_PROTO_MAX_BATCHES, "a pass's batches fit PHOTON_REQ and PHOTONS");

#define S_LEASE_TIMEOUT_S 30.0 /* a batch leased this long goes to someone else (the first one waits for the scene) */

int pf_fm_photons_spread(pf_fm_photons_t *p, pf_photon_maps_t *maps)
{
    pf_frame_t *fr = &p->frame;
    const pf_settings_t *s = &p->settings;
    memset(maps, 0, sizeof *maps);
    memset(&p->stats, 0, sizeof p->stats);
    pf_buf_t sb = { 0 };
    int rc = PF_OK;
    if (!p->early_from_job) {
        rc = pf_sceneblob_write(p->scene, &sb);
        if (rc == PF_OK) {
            p->early_hash = pf_hash_bytes(PF_HASH_INIT, sb.data, sb.len);
            p->early_size = sb.len;
            rc = pf_framed_blob_make(&p->early_fb, p->job, p->early_hash, &sb);
        }
        pf_buf_free(&sb);
    }
    if (rc == PF_OK)
        rc = pf_photon_tracer_new(p->scene, fr->accel, fr->lights, s, 0, &p->tracer);
    if (rc == PF_OK) {
        p->phq = pf_phq_new(p->tracer, pf_photon_depth(s));
        rc = p->phq ? PF_OK : PF_ENOMEM;
        if (p->phq)
            pf_phq_checks(p->phq, p->check_secret, p->check_one_in);
    }
    if (rc != PF_OK)
        return rc;
    __atomic_store_n(&p->phq_ready, 1, __ATOMIC_RELEASE);
    double t0 = pf_now();
    rc = pf_phq_run(p->phq, s->threads > 0 ? s->threads : 1);
    p->stats.trace_s = pf_now() - t0;
    if (rc == PF_OK)
        rc = pf_phq_merge(p->phq, p->scene, fr->accel, s, maps, &p->stats);
    return rc;
}

static pf_phq_t *s_phq(const pf_fm_t *f)
{
    return __atomic_load_n(&f->ph.phq_ready, __ATOMIC_ACQUIRE) ? f->ph.phq : NULL;
}

/* Leases a range of batches to worker wi and sends the PHOTON_REQ: about
 * one batch per PF_PHOTON_BATCH_BLOCKS threads, at least one. */
static void s_lease(pf_fm_t *f, int wi, pf_phq_t *q)
{
    pf_worker_t *w = &f->reg.w[wi];
    uint32_t want = 1 + w->threads / PF_PHOTON_BATCH_BLOCKS, first = 0;
    if (want > PF_PROTO_MAX_REQ_BATCHES)
        want = PF_PROTO_MAX_REQ_BATCHES;
    uint32_t n = pf_phq_lease(q, w->uid, want, pf_now(), &first);
    if (n == 0)
        return;
    if (!w->ph_asked && !f->ph.early_from_job)
        pf_fm_fanout_scene(f, wi);
    pf_msg_t m = { .type = PF_MSG_PHOTON_REQ };
    m.job = f->ph.job;
    m.u.photon_req = (pf_msg_photon_req_t){ f->ph.early_hash, f->ph.early_size, f->ph.settings, first, n };
    if (pf_fm_send(f, wi, &m) != 0) {
        pf_phq_release(q, w->uid);
        return;
    }
    if (!w->ph_asked)
        pf_log(PF_LOG_DEBUG, "worker %s: photon batches %" PRIu32 "+%" PRIu32, w->name, first, n);
    w->ph_asked = 1;
}

/* Workers the spot checks caught: struck (farm_peers.c) and barred from
 * photon batches for the rest of the job. */
static void s_strike_liars(pf_fm_t *f, pf_phq_t *q)
{
    uint32_t uid;
    char why[160];
    while (pf_phq_take_liar(q, &uid, why, sizeof why)) {
        f->sum->ph_mismatches++;
        for (int i = 0; i < f->reg.nw; i++) {
            pf_worker_t *w = &f->reg.w[i];
            if (w->uid != uid || w->state == PF_W_FREE)
                continue;
            pf_warn("photon pass %d: worker %s returned a wrong photon batch (spot check): its batches of the pass "
                    "are traced again", f->ph.pass + 1, w->name);
            w->ph_barred = 1;
            w->ph_batches -= w->ph_pass;
            w->ph_pass = 0;
            pf_fm_strike(f, i, why);
        }
    }
}

/* While a pass's tiles are out (job_ready): may READY worker w take photon
 * batches of the next pass now? When no tile is queued (it would idle), or
 * when the photon pass lags the tiles. */
static int s_may_interleave(const pf_fm_t *f, pf_phq_t *q)
{
    if (f->L.qlen == 0)
        return 1;
    uint32_t done, total;
    pf_phq_progress(q, &done, &total);
    return total && (uint64_t)done * (uint64_t)f->L.nt < (uint64_t)f->L.ndone * total;
}

void pf_fm_photons_tick(pf_fm_t *f)
{
    pf_phq_t *q = s_phq(f);
    if (!q)
        return;
    s_strike_liars(f, q);
    if (__atomic_load_n(&f->ph.done, __ATOMIC_ACQUIRE))
        return;
    if (!f->ph_published) {
        if (!f->ph.early_from_job) {
            /* the scene fans out as the maps do (fanout.h; before the blob
             * server takes the blob); without its chunk hashes every
             * worker fetches it from here */
            f->fan_scene_on = pf_fanout_set_blob(f->fan_scene, &f->ph.early_fb) == PF_OK;
            pf_framed_blob_t none = { 0 };
            pf_xfer_set_blobs(f->xfer, &f->ph.early_fb, &none);
        }
        f->ph_published = 1;
    }
    uint32_t n = pf_phq_expire(q, pf_now(), S_LEASE_TIMEOUT_S);
    if (n && pf_fm_may_log(&f->peer_log, 10.0))
        pf_warn("photon pass: %u batch lease%s expired; traced by someone else", n, n == 1 ? "" : "s");
    int interleave = f->job_ready && s_may_interleave(f, q);
    for (int i = 0; i < f->reg.nw; i++) {
        const pf_worker_t *w = &f->reg.w[i];
        int fits = f->job_ready ? w->state == PF_W_READY && interleave : w->state == PF_W_HELLO;
        if (fits && !w->stuck && !w->ph_barred && pf_phq_held(q, w->uid) == 0)
            s_lease(f, i, q);
    }
}

void pf_fm_on_photons(pf_fm_t *f, int wi, const pf_msg_t *m)
{
    pf_phq_t *q = s_phq(f);
    pf_worker_t *w = &f->reg.w[wi];
    if (!w->ph_asked) {
        pf_fm_strike(f, wi, "PHOTONS without a PHOTON_REQ");
        return;
    }
    if (!q || m->job != f->ph.job) {
        f->sum->ph_stale++;
        pf_debug("dropped PHOTONS from %s: no photon pass of job %llu under way", w->name, (unsigned long long)m->job);
        return;
    }
    char why[320] = "";
    int rc = pf_phq_on_photons(q, w->uid, &m->u.photons, why, sizeof why);
    if (rc == PF_PHQ_BAD) {
        pf_fm_bad(f, w->name, why);
        pf_fm_strike(f, wi, why);
        return;
    }
    if (rc == PF_PHQ_DONE) {
        w->ph_batches++;
        w->ph_pass++;
        if (!f->job_ready)
            w->result_at = pf_now(); /* not while it holds tiles: the stall clock is theirs */
        if (pf_phq_held(q, w->uid) == 0 && !f->job_ready && w->state == PF_W_HELLO)
            s_lease(f, wi, q); /* its next range, without waiting for the tick */
    }
}

int pf_fm_photons_blob_ok(const pf_fm_t *f, int wi, uint64_t hash)
{
    return f->ph_published && !f->job_ready && f->reg.w[wi].ph_asked && hash == f->ph.early_hash;
}

int pf_fm_photons_release(pf_fm_t *f, int wi)
{
    pf_phq_t *q = s_phq(f);
    return q ? (int)pf_phq_release(q, f->reg.w[wi].uid) : 0;
}

void pf_fm_photons_end(pf_fm_t *f)
{
    pf_fm_photons_t *p = &f->ph;
    f->ph_published = 0; /* the blob server has the JOB's blobs from now on */
    if (!p->phq) {
        pf_photon_tracer_free(&p->tracer);
        pf_framed_blob_free(&p->early_fb);
        return;
    }
    s_strike_liars(f, p->phq);
    pf_phq_stats_t st;
    pf_phq_stats(p->phq, &st);
    __atomic_store_n(&p->phq_ready, 0, __ATOMIC_RELEASE);
    pf_phq_free(&p->phq);
    pf_photon_tracer_free(&p->tracer);
    pf_framed_blob_free(&p->early_fb); /* when the blob server did not take it */
    pf_farm_summary_t *sum = f->sum;
    sum->ph_batches += st.batches;
    sum->ph_local += st.local;
    sum->ph_remote += st.remote;
    sum->ph_stale += st.stale;
    sum->ph_expired += st.expired;
    sum->ph_stolen += st.stolen;
    sum->ph_emitted += st.emitted;
    sum->ph_trace_s += p->stats.trace_s;
    sum->ph_checked += st.checked;
    sum->ph_discarded += st.discarded;
    char who[512], chk[160] = "";
    int n = 0;
    who[0] = 0;
    for (int i = 0; i < f->reg.nw; i++) {
        pf_worker_t *w = &f->reg.w[i];
        if (w->ph_pass && n < (int)sizeof who - 80)
            n += snprintf(who + n, sizeof who - (size_t)n, ", %s %llu", w->name, (unsigned long long)w->ph_pass);
        w->ph_pass = 0;
    }
    if (st.checked || st.mismatches)
        snprintf(chk, sizeof chk, "; %llu worker batch%s checked here, %llu mismatch%s, %llu discarded",
                 (unsigned long long)st.checked, st.checked == 1 ? "" : "es", (unsigned long long)st.mismatches,
                 st.mismatches == 1 ? "" : "es", (unsigned long long)st.discarded);
    pf_info("photon pass %d: %u batches of %d photons, %u traced on the coordinator, %u on the workers%s%s; "
            "%.2f Mphotons/s (%.2f s tracing)",
            p->pass + 1, st.batches, PF_PHOTON_BATCH_BLOCKS * PF_PHOTON_BLOCK, st.local, st.remote, who, chk,
            p->stats.trace_s > 0 ? (double)st.emitted / p->stats.trace_s / 1e6 : 0.0, p->stats.trace_s);
}
