/* farm_irr.c: the irradiance precompute spread over the workers
 * (farm_impl.h; the table: irr_chunks.h).
 *
 * When the photon thread has merged the photon batches and built the
 * kd-trees, the merge asks for the irradiance points (pf_irr_spread_t). For
 * the first pass, when workers are there and the map is not tiny, the
 * thread serializes the maps without irradiance (the global map is what an
 * estimate reads; caustic and irradiance maps are left empty), frames that
 * blob and makes the chunk table; the event loop publishes the blob (the
 * blob server's maps slot: no JOB is out yet; its own fan-out tree, each
 * worker's BLOB_PLAN sent before its first IRR_REQ) and leases chunk
 * ranges to welcomed workers without a JOB (IRR_REQ), which fetch the
 * blob (from a peer or from here, as the plan says; and the
 * scene blob, if the photon pass did not give it them), compute the points
 * with pf_irradiance_points and send each chunk back (IRR_POINTS). The
 * thread computes chunks too and takes over leased ones when none is free,
 * so it never waits on a worker. The points land at their index and the
 * trees are built from them as in process: the maps blob is the same bits
 * for any number of workers. Later passes, whose workers hold a JOB, and
 * farms without a worker compute every point here, as before.
 *
 * Threads: pf_fm_irr_points in the photon thread; the rest in the event
 * loop's. */
#include <inttypes.h>
#include <omp.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "base/hash.h"
#include "base/log.h"
#include "coordinator/farm.h"
#include "coordinator/farm_impl.h"
#include "photon/mapfile.h"

/* Fewer points (both maps) than this are computed here: a few core-seconds
 * of estimates, which the global map's trip to the workers (and its chunks
 * queued ahead of their JOB, which delays the JOB's fan-out) would eat.
 * Measured in tests/integration/test_fanout.sh: 12 chunks spread over 6
 * workers behind an 80 Mbit/s link were all done here in 0.4 s while the
 * workers still fetched the map, and the JOB reached the fan-out tree's
 * root after its children had asked it for the maps. */
#define S_MIN_POINTS ((size_t)64 * PF_PROTO_IRR_CHUNK_POINTS)
#define S_LEASE_TIMEOUT_S 30.0

/* Every point here, as pf_photon_build computes them. */
static int s_all_here(const pf_kdtree_t *global, const pf_accel_t *accel, const pf_irr_plan_t *plan, int threads,
                      pf_photon_t *main, pf_photon_t *deep)
{
    int rc = pf_irradiance_points(global, &plan->main, accel, threads, 0, plan->points, main);
    if (rc == PF_OK && plan->has_deep)
        rc = pf_irradiance_points(global, &plan->deep, accel, threads, 0, plan->points, deep);
    return rc;
}

/* The map blob the workers estimate from: the global map (with the
 * radii and counts), no caustic or irradiance photons. */
static int s_frame_blob(pf_fm_photons_t *p, const pf_photon_maps_t *maps)
{
    pf_photon_maps_t view = *maps;
    view.caustic = view.irradiance = view.irradiance_deep = NULL;
    pf_buf_t b = { 0 };
    int rc = pf_mapfile_write(&view, p->early_hash, pf_settings_hash(&p->settings), &b);
    if (rc == PF_OK) {
        p->irr_hash = pf_hash_bytes(PF_HASH_INIT, b.data, b.len);
        p->irr_size = b.len;
        rc = pf_framed_blob_make(&p->irr_fb, p->job, p->irr_hash, &b);
    }
    pf_buf_free(&b);
    return rc;
}

int pf_fm_irr_points(void *ctx, const pf_photon_maps_t *maps, const pf_irr_plan_t *plan, pf_photon_t *main,
                     pf_photon_t *deep)
{
    pf_fm_photons_t *p = ctx;
    double t0 = pf_now();
    const pf_accel_t *accel = p->frame.accel;
    int threads = p->settings.threads > 0 ? p->settings.threads : omp_get_num_procs();
    p->irr_points = plan->points * (plan->has_deep ? 2u : 1u);
    int rc;
    if (!p->spread || p->early_from_job || p->irr_points < S_MIN_POINTS ||
        __atomic_load_n(&p->irr_workers, __ATOMIC_ACQUIRE) == 0 || s_frame_blob(p, maps) != PF_OK) {
        pf_framed_blob_free(&p->irr_fb);
        rc = s_all_here(maps->global, accel, plan, threads, main, deep);
    } else {
        p->irq = pf_irq_new(maps->global, accel, plan, main, deep);
        if (!p->irq) {
            rc = s_all_here(maps->global, accel, plan, threads, main, deep);
        } else {
            pf_irq_checks(p->irq, p->check_secret, p->check_one_in);
            __atomic_store_n(&p->irq_ready, 1, __ATOMIC_RELEASE);
            rc = pf_irq_run(p->irq, threads);
        }
    }
    p->irr_s = pf_now() - t0;
    return rc;
}

static pf_irq_t *s_irq(const pf_fm_t *f)
{
    return __atomic_load_n(&f->ph.irq_ready, __ATOMIC_ACQUIRE) ? f->ph.irq : NULL;
}

/* Leases a range of chunks to worker wi (about two a thread) and sends
 * the IRR_REQ. */
static void s_lease(pf_fm_t *f, int wi, pf_irq_t *q)
{
    pf_worker_t *w = &f->reg.w[wi];
    uint32_t want = 2 * (w->threads > 0 ? w->threads : 1), first = 0;
    if (want > PF_PROTO_MAX_REQ_IRR_CHUNKS)
        want = PF_PROTO_MAX_REQ_IRR_CHUNKS;
    uint32_t n = pf_irq_lease(q, w->uid, want, pf_now(), &first);
    if (n == 0)
        return;
    const pf_fm_photons_t *p = &f->ph;
    if (!w->irr_planned) {
        pf_fm_fanout_job(f, wi); /* where to fetch the map blob from: a peer, or here */
        w->irr_planned = 1;
    }
    pf_msg_t m = { .type = PF_MSG_IRR_REQ };
    m.job = p->job;
    m.u.irr_req = (pf_msg_irr_req_t){ p->early_hash, p->early_size, p->irr_hash, p->irr_size, p->settings, first, n };
    if (pf_fm_send(f, wi, &m) != 0) {
        pf_irq_release(q, w->uid);
        return;
    }
    w->ph_asked = 1; /* it may fetch the scene blob and the irradiance's map blob */
}

static void s_strike_liars(pf_fm_t *f, pf_irq_t *q)
{
    uint32_t uid;
    char why[160];
    while (pf_irq_take_liar(q, &uid, why, sizeof why)) {
        for (int i = 0; i < f->reg.nw; i++) {
            pf_worker_t *w = &f->reg.w[i];
            if (w->uid != uid || w->state == PF_W_FREE)
                continue;
            pf_warn("irradiance: worker %s returned a wrong chunk (spot check): its chunks are computed again",
                    w->name);
            w->ph_barred = 1;
            w->irr_pass = 0;
            pf_fm_strike(f, i, why);
        }
    }
}

void pf_fm_irr_tick(pf_fm_t *f)
{
    int idle = 0;
    for (int i = 0; i < f->reg.nw; i++) {
        const pf_worker_t *w = &f->reg.w[i];
        idle += w->state == PF_W_HELLO && !w->stuck && !w->ph_barred;
    }
    __atomic_store_n(&f->ph.irr_workers, idle, __ATOMIC_RELEASE);
    pf_irq_t *q = s_irq(f);
    if (!q)
        return;
    s_strike_liars(f, q);
    if (!f->irr_published) {
        /* its own fan-out tree (the JOB's maps blob starts another) */
        if (pf_fanout_set_blob(f->fan, &f->ph.irr_fb) != PF_OK)
            pf_warn("irradiance: out of memory for the map blob's fan-out plan; workers fetch it from here");
        uint64_t size0;
        pf_xfer_blob_bytes(f->xfer, 1, &size0, &f->irr_sent0);
        pf_xfer_set_maps(f->xfer, &f->ph.irr_fb);
        f->irr_published = 1;
        f->irr_served_hash = f->ph.irr_hash;
    }
    uint32_t n = pf_irq_expire(q, pf_now(), S_LEASE_TIMEOUT_S);
    if (n && pf_fm_may_log(&f->peer_log, 10.0))
        pf_warn("irradiance: %u chunk lease%s expired; computed by someone else", n, n == 1 ? "" : "s");
    if (f->job_ready)
        return;
    for (int i = 0; i < f->reg.nw; i++) {
        const pf_worker_t *w = &f->reg.w[i];
        if (w->state == PF_W_HELLO && !w->stuck && !w->ph_barred && pf_irq_held(q, w->uid) == 0)
            s_lease(f, i, q);
    }
}

void pf_fm_on_irr_points(pf_fm_t *f, int wi, const pf_msg_t *m)
{
    pf_irq_t *q = s_irq(f);
    pf_worker_t *w = &f->reg.w[wi];
    if (!w->ph_asked) {
        pf_fm_strike(f, wi, "IRR_POINTS without an IRR_REQ");
        return;
    }
    if (!q || m->job != f->ph.job) {
        pf_debug("dropped IRR_POINTS from %s: no irradiance of job %llu under way", w->name,
                 (unsigned long long)m->job);
        return;
    }
    char why[320] = "";
    int rc = pf_irq_on_points(q, w->uid, &m->u.photons, why, sizeof why);
    if (rc == PF_IRQ_BAD) {
        pf_fm_bad(f, w->name, why);
        pf_fm_strike(f, wi, why);
        return;
    }
    if (rc == PF_IRQ_DONE) {
        w->irr_pass++;
        if (!f->job_ready)
            w->result_at = pf_now();
        if (pf_irq_held(q, w->uid) == 0 && !f->job_ready && w->state == PF_W_HELLO)
            s_lease(f, wi, q); /* its next range, without waiting for the tick */
    }
}

int pf_fm_irr_release(pf_fm_t *f, int wi)
{
    pf_irq_t *q = s_irq(f);
    return q ? (int)pf_irq_release(q, f->reg.w[wi].uid) : 0;
}

void pf_fm_irr_end(pf_fm_t *f)
{
    pf_fm_photons_t *p = &f->ph;
    if (f->irr_published && f->xfer) {
        /* its bytes, apart from the maps blobs' (the summary's fan-out line) */
        uint64_t size, sent;
        pf_xfer_blob_bytes(f->xfer, 1, &size, &sent);
        f->sum->irr_blob_size += p->irr_size;
        f->sum->irr_blob_sent += sent - f->irr_sent0;
    }
    f->irr_published = 0;
    pf_framed_blob_free(&p->irr_fb); /* when the blob server did not take it */
    pf_farm_summary_t *sum = f->sum;
    if (!p->irr_points)
        return;
    sum->irr_points += p->irr_points;
    sum->irr_s += p->irr_s;
    if (!p->irq) {
        sum->irr_here += p->irr_points;
        pf_info("irradiance %d: %" PRIu64 " points computed on the coordinator (%.2f s)", p->pass + 1, p->irr_points,
                p->irr_s);
        p->irr_points = 0;
        return;
    }
    s_strike_liars(f, p->irq);
    pf_irq_stats_t st;
    pf_irq_stats(p->irq, &st);
    __atomic_store_n(&p->irq_ready, 0, __ATOMIC_RELEASE);
    pf_irq_free(&p->irq);
    sum->irr_chunks += st.chunks;
    sum->irr_local += st.local;
    sum->irr_remote += st.remote;
    sum->irr_checked += st.checked;
    sum->irr_mismatches += st.mismatches;
    char who[512];
    int n = 0;
    who[0] = 0;
    for (int i = 0; i < f->reg.nw; i++) {
        pf_worker_t *w = &f->reg.w[i];
        if (w->irr_pass && n < (int)sizeof who - 80)
            n += snprintf(who + n, sizeof who - (size_t)n, ", %s %llu", w->name, (unsigned long long)w->irr_pass);
        w->irr_pass = 0;
    }
    pf_info("irradiance %d: %" PRIu64 " points in %u chunks of %u, %u computed on the coordinator, %u on the "
            "workers%s; %llu worker chunk%s checked here, %llu mismatch%s, %llu late dropped (%.2f s)",
            p->pass + 1, p->irr_points, st.chunks, (unsigned)PF_PROTO_IRR_CHUNK_POINTS, st.local, st.remote, who,
            (unsigned long long)st.checked, st.checked == 1 ? "" : "s", (unsigned long long)st.mismatches,
            st.mismatches == 1 ? "" : "es", (unsigned long long)st.stale, p->irr_s);
    p->irr_points = 0;
}
