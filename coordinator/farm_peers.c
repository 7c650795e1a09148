/* farm_peers.c: the farm's conversation with its workers (farm_impl.h):
 * sending, leasing tiles, receiving and judging messages, strikes and
 * eviction. The policy against hostile peers is here: a worker fetches
 * blobs only between its JOB and its READY (or the scene blob after a
 * PHOTON_REQ, farm_photons.c), through a window (transfer.h);
 * holds at most its tile credit; may return only the tiles leased to its
 * worker id; and every malformed or out-of-turn message is a strike.
 *
 * Threads: the event loop's only (farm.c). */
#include <errno.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <zmq.h>

#include "base/log.h"
#include "coordinator/farm.h"
#include "coordinator/farm_impl.h"

int pf_fm_may_log(pf_fm_limit_t *l, double rate)
{
    double now = pf_now();
    l->tokens = l->at > 0 ? l->tokens + (now - l->at) * rate : 2 * rate;
    if (l->tokens > 2 * rate)
        l->tokens = 2 * rate;
    l->at = now;
    if (l->tokens < 1.0) {
        l->held++;
        return 0;
    }
    l->tokens -= 1.0;
    if (l->held)
        pf_warn("(%lu similar lines held back)", l->held);
    l->held = 0;
    return 1;
}

/* --- sending ------------------------------------------------------------ */

/* Sends m to a routing identity (registered or not). 0, or -1 with errno
 * from libzmq (EHOSTUNREACH: the peer is gone; EAGAIN: its queue is full). */
static int s_send_to(pf_fm_t *f, const uint8_t *id, size_t idlen, pf_msg_t *m)
{
    m->job = m->job ? m->job : f->job;
    if (pf_msg_encode(m, &f->out) != PF_OK)
        return -1;
    if (zmq_send(f->sock, id, idlen, ZMQ_SNDMORE | ZMQ_DONTWAIT) < 0 ||
        zmq_send(f->sock, f->out.data, f->out.len, ZMQ_DONTWAIT) < 0)
        return -1;
    f->sum->bytes_sent += f->out.len;
    return 0;
}

/* Sends m to worker wi. A worker libzmq no longer knows (ROUTER_MANDATORY
 * says EHOSTUNREACH: its connection is gone, and a routing identity never
 * comes back) is declared dead at once; a full queue just fails. */
int pf_fm_send(pf_fm_t *f, int wi, pf_msg_t *m)
{
    pf_worker_t *w = &f->reg.w[wi];
    if (s_send_to(f, w->id, w->idlen, m) != 0) {
        if (zmq_errno() == EHOSTUNREACH && w->state != PF_W_DEAD && w->state != PF_W_FREE)
            pf_fm_declare_dead(f, wi, "is gone (disconnected): declared dead");
        return -1;
    }
    w->last_sent = pf_now();
    return 0;
}

static void s_refuse(pf_fm_t *f, const uint8_t *id, size_t idlen, const char *why)
{
    pf_msg_t m = { .type = PF_MSG_REFUSE };
    snprintf(m.u.refuse.reason, sizeof m.u.refuse.reason, "%s", why);
    s_send_to(f, id, idlen, &m);
}

/* Returns a worker's leased tiles to the front of the queue. */
void pf_fm_release_worker(pf_fm_t *f, int wi, const char *why)
{
    int nb = pf_fm_photons_release(f, wi);
    int n = pf_leases_release(&f->L, &f->reg, wi);
    if ((n || nb || why) && pf_fm_may_log(&f->peer_log, 10.0))
        pf_warn("worker %s %s: %d tile%s re-issued%s", f->reg.w[wi].name, why ? why : "released", n, n == 1 ? "" : "s",
                nb ? " (and its photon batches)" : "");
}

void pf_fm_declare_dead(pf_fm_t *f, int wi, const char *why)
{
    f->sum->workers_lost++;
    pf_registry_gone(&f->reg, wi, PF_W_DEAD, pf_now());
    pf_fm_release_worker(f, wi, why);
    pf_fm_fanout_gone(f, wi);
}

void pf_fm_send_job(pf_fm_t *f, int wi)
{
    pf_fm_fanout_job(f, wi);
    pf_msg_t m = { .type = PF_MSG_JOB };
    m.u.job = f->jobmsg;
    if (pf_fm_send(f, wi, &m) == 0)
        f->reg.w[wi].state = PF_W_JOB_SENT;
}

/* --- strikes ------------------------------------------------------------- */

/* Evicts worker wi: BYE, its tiles back to the queue, its slot freed, and
 * its routing identity, name and key blocked for the rest of the job. */
void pf_fm_evict(pf_fm_t *f, int wi, const char *why)
{
    pf_worker_t *w = &f->reg.w[wi];
    pf_warn("evicted worker %s (id %u): %s", w->name, w->uid, why);
    pf_msg_t b = { .type = PF_MSG_BYE };
    snprintf(b.u.bye.reason, sizeof b.u.bye.reason, "evicted: %.240s", why);
    pf_fm_send(f, wi, &b);
    pf_fm_release_worker(f, wi, "was evicted");
    pf_registry_block(&f->reg, w);
    pf_registry_gone(&f->reg, wi, PF_W_FREE, pf_now());
    pf_fm_fanout_gone(f, wi);
    f->sum->evicted++;
}

void pf_fm_evict_pending(pf_fm_t *f)
{
    for (int k = 0; k < f->nevict; k++)
        for (int i = 0; i < f->reg.nw; i++)
            if (f->reg.w[i].uid == f->evict_uid[k] && f->reg.w[i].state != PF_W_FREE &&
                f->reg.w[i].state != PF_W_DEAD) {
                pf_fm_evict(f, i, f->evict_why[k]);
                break;
            }
    f->nevict = 0;
}

/* Counts a strike against a live worker; evicts it past max_strikes. */
void pf_fm_strike(pf_fm_t *f, int wi, const char *why)
{
    pf_worker_t *w = &f->reg.w[wi];
    if (w->state == PF_W_FREE || w->state == PF_W_DEAD)
        return;
    w->strikes++;
    f->sum->strikes++;
    if (pf_fm_may_log(&f->strike_log, 10.0))
        pf_warn("worker %s (id %u): strike %d of %d: %s", w->name, w->uid, w->strikes, f->o->max_strikes, why);
    if (f->o->max_strikes > 0 && w->strikes >= f->o->max_strikes) {
        char ev[400];
        snprintf(ev, sizeof ev, "after %d strikes; the last: %.300s", w->strikes, why);
        pf_fm_evict(f, wi, ev);
    }
}

void pf_fm_bad(pf_fm_t *f, const char *peer, const char *why)
{
    f->sum->malformed++;
    char pwhy[512];
    if (pf_fm_may_log(&f->bad_log, 1.0))
        pf_warn("dropped a malformed message from %s: %s", peer, pf_log_printable(pwhy, sizeof pwhy, why));
}

/* --- leasing ------------------------------------------------------------- */

/* Ready workers that may take tiles now (not stuck). */
static int s_count_takers(const pf_fm_t *f)
{
    int n = 0;
    for (int i = 0; i < f->reg.nw; i++)
        n += f->reg.w[i].state == PF_W_READY && !f->reg.w[i].stuck;
    return n;
}

/* How many tiles worker w may hold: what it asked for, at most
 * credit_per_thread per thread it announced, at most 2 + the results it has
 * returned (a worker proves itself before it holds more), at most its fair
 * share of the tiles left among the takers; at least 1. */
static uint32_t s_credit(const pf_fm_t *f, const pf_worker_t *w, int takers)
{
    uint64_t cap = w->asked;
    uint64_t per = (uint64_t)(f->o->credit_per_thread > 0 ? f->o->credit_per_thread : 1);
    per *= w->threads ? w->threads : 1;
    uint64_t proven = 2 + w->tiles;
    uint64_t left = (uint64_t)(f->L.nt - f->L.ndone);
    uint64_t fair = takers > 0 ? (left + (uint64_t)takers - 1) / (uint64_t)takers : left;
    cap = cap < per ? cap : per;
    cap = cap < proven ? cap : proven;
    cap = cap < fair ? cap : fair;
    return cap >= 1 ? (uint32_t)cap : 1;
}

static void s_lease(pf_fm_t *f, int wi, int takers)
{
    pf_worker_t *w = &f->reg.w[wi];
    if (w->state != PF_W_READY || w->stuck)
        return;
    uint32_t cap = s_credit(f, w, takers);
    double now = pf_now();
    while (w->state == PF_W_READY && w->held < cap) {
        int pos = pf_leases_pick(&f->L, &f->reg, wi);
        if (pos < 0)
            break;
        int ti = pf_leases_grant(&f->L, &f->reg, pos, wi, now);
        const pf_tile_t *t = &f->L.t[ti];
        pf_msg_t m = { .type = PF_MSG_TILE };
        m.u.tile = (pf_msg_tile_t){ (uint32_t)ti, t->attempt, t->x0, t->y0, t->w, t->h };
        if (pf_fm_send(f, wi, &m) != 0) {
            pf_leases_ungrant(&f->L, &f->reg, ti); /* unless the failure already declared it dead */
            break;
        }
    }
}

/* The job's tail: with the queue empty, the oldest lease (older than
 * takeover_factor typical tile times and takeover_min_s) returns to the
 * queue when a worker with room that never held its tile is there to take
 * it, so the job does not wait on a slow or hoarding worker. The holder may
 * still deliver; the first RESULT wins. At most one a round of the loop. */
static void s_takeover(pf_fm_t *f, int takers)
{
    const pf_farm_opts_t *o = f->o;
    if (f->L.qlen > 0 || o->takeover_factor <= 0 || takers < 1)
        return;
    double typical = pf_leases_typical_s(&f->L);
    if (typical <= 0)
        return;
    double now = pf_now(), min_age = o->takeover_factor * typical;
    min_age = min_age > o->takeover_min_s ? min_age : o->takeover_min_s;
    int ti = pf_leases_oldest(&f->L, now, min_age);
    if (ti < 0)
        return;
    const pf_tile_t *t = &f->L.t[ti];
    for (int i = 0; i < f->reg.nw; i++) {
        const pf_worker_t *w = &f->reg.w[i];
        if (w->state != PF_W_READY || w->stuck || pf_leases_was_lessee(t, w->uid) || w->held >= s_credit(f, w, takers))
            continue;
        pf_info("tile %d: leased to %s for %.1f s (typical tile %.2f s); %s may take it over", ti,
                t->owner >= 0 ? f->reg.w[t->owner].name : "?", now - t->leased_at, typical, w->name);
        f->sum->takeovers++;
        pf_leases_revoke(&f->L, &f->reg, ti);
        return;
    }
}

void pf_fm_lease_all(pf_fm_t *f)
{
    int takers = s_count_takers(f);
    if (!f->leasing) { /* --min-workers holds back the start only, never a running job */
        if (takers < f->o->min_workers)
            return;
        f->leasing = 1;
    }
    s_takeover(f, takers);
    for (int i = 0; i < f->reg.nw; i++)
        s_lease(f, i, takers);
}

/* --- receiving ---------------------------------------------------------- */

static void s_on_hello(pf_fm_t *f, const uint8_t *id, size_t idlen, const char *key, const pf_msg_hello_t *h)
{
    double now = pf_now();
    int wi = pf_registry_find(&f->reg, id, idlen);
    if (wi >= 0 && f->reg.w[wi].state != PF_W_DEAD) {
        pf_fm_strike(f, wi, "HELLO again on a registered connection");
        return;
    }
    char name[64], why[256] = "";
    /* The name is the peer's: kept escaped (base/log.h), so no log line or
     * summary prints a newline or a terminal escape it sent. */
    pf_log_printable(name, sizeof name, h->name);
    if (!pf_registry_hello_admit(&f->reg, now)) {
        if (pf_fm_may_log(&f->hello_log, 1.0))
            pf_warn("dropped a HELLO from %s: more than %.0f a second", name, f->o->hello_rate);
        return;
    }
    if (pf_registry_peer_blocked(&f->reg, name, key)) {
        f->sum->blocked++;
        if (pf_fm_may_log(&f->hello_log, 1.0))
            pf_warn("refused %s: evicted from this job", name);
        s_refuse(f, id, idlen, "evicted from this job");
        return;
    }
    pf_fingerprint_t self = pf_frame_fingerprint();
    if (pf_fingerprint_check(&h->fp, &self, why, sizeof why) != PF_OK) {
        char pwhy[512];
        s_refuse(f, id, idlen, why);
        pf_warn("refused worker %s: %s", name, pf_log_printable(pwhy, sizeof pwhy, why));
        f->sum->refused++;
        return;
    }
    int reused = 0;
    wi = pf_registry_add(&f->reg, id, idlen, &reused);
    if (wi < 0 || pf_xfer_reset(f->xfer, wi) != PF_OK) {
        if (wi >= 0)
            pf_registry_gone(&f->reg, wi, PF_W_FREE, now);
        f->sum->refused++;
        if (pf_fm_may_log(&f->hello_log, 1.0))
            pf_warn("refused worker %s: %s", name, wi < 0 ? "too many workers" : "out of memory");
        s_refuse(f, id, idlen, wi < 0 ? "too many workers" : "out of memory");
        return;
    }
    pf_worker_t *w = &f->reg.w[wi];
    snprintf(w->name, sizeof w->name, "%s", name);
    snprintf(w->key, sizeof w->key, "%s", key ? key : "");
    w->threads = h->threads;
    w->last_seen = now;
    w->state = PF_W_HELLO;
    /* Peer sockets are plaintext: no fan-out where CURVE guards the farm. */
    pf_fanout_hello(f->fan, wi, w->uid, f->frame_addr, f->o->curve_secret ? 0 : h->peer_port);
    pf_fanout_hello(f->fan_scene, wi, w->uid, f->frame_addr, f->o->curve_secret ? 0 : h->peer_port);
    if (strcmp(h->fp.git, self.git) != 0) {
        char git[128];
        pf_info("worker %s was built from %s (this coordinator: %s)", w->name,
                pf_log_printable(git, sizeof git, h->fp.git), self.git);
    }
    f->sum->workers_seen++;
    pf_msg_t m = { .type = PF_MSG_WELCOME };
    m.u.welcome = (pf_msg_welcome_t){ w->uid, (uint32_t)f->o->heartbeat_ms };
    if (pf_fm_send(f, wi, &m) != 0)
        return;
    if (pf_fm_may_log(&f->peer_log, 10.0))
        pf_info("worker %s joined (%u thread%s; id %u, slot %d%s)", w->name, w->threads, w->threads == 1 ? "" : "s",
                w->uid, wi, reused ? ", reused" : "");
    if (f->job_ready)
        pf_fm_send_job(f, wi);
}

/* Hands libzmq what worker wi's transfer window lets through. */
void pf_fm_pump(pf_fm_t *f, int wi)
{
    pf_worker_t *w = &f->reg.w[wi];
    uint64_t payload = 0, wire = 0;
    int n = pf_xfer_pump(f->xfer, wi, f->sock, w->id, w->idlen, &payload, &wire);
    f->sum->blob_bytes += payload;
    f->sum->bytes_sent += wire;
    w->blob_sent += payload;
    if (n > 0)
        w->last_sent = pf_now();
    if (n < 0 && w->state != PF_W_DEAD)
        pf_fm_declare_dead(f, wi, "is gone (disconnected): declared dead");
}

/* Only a worker that has its JOB and is not READY yet fetches blobs. */
static void s_on_blob_req(pf_fm_t *f, int wi, const pf_msg_blob_req_t *r)
{
    pf_worker_t *w = &f->reg.w[wi];
    char why[320];
    int rc = 1;
    if (w->state != PF_W_JOB_SENT && !(w->state == PF_W_HELLO && pf_fm_photons_blob_ok(f, wi, r->hash)))
        snprintf(why, sizeof why, "BLOB_REQ %s", w->state == PF_W_HELLO ? "before its JOB" : "after READY");
    else
        rc = pf_xfer_request(f->xfer, wi, r, why, sizeof why);
    if (rc != 0) {
        f->sum->blob_ignored++;
        pf_fm_strike(f, wi, why);
        return;
    }
    pf_fm_pump(f, wi);
}

static void s_on_ready(pf_fm_t *f, int wi, const pf_msg_ready_t *r)
{
    pf_worker_t *w = &f->reg.w[wi];
    if (w->state != PF_W_JOB_SENT) {
        pf_fm_strike(f, wi, w->state == PF_W_READY ? "READY again" : "READY before its JOB");
        return;
    }
    pf_log(f->cur_pass ? PF_LOG_DEBUG : PF_LOG_INFO, "worker %s ready: scene and maps built", w->name);
    w->state = PF_W_READY;
    w->asked = r->credit;
}

static void s_on_result(pf_fm_t *f, int wi, const pf_msg_result_t *r)
{
    pf_worker_t *w = &f->reg.w[wi];
    char why[400];
    int v = pf_leases_check(&f->L, &f->reg, wi, r, why, sizeof why);
    if (v == PF_RESULT_REFUSED) {
        f->sum->results_refused++;
        if (w->state == PF_W_DEAD && pf_fm_may_log(&f->bad_log, 1.0))
            pf_warn("refused a RESULT from dead worker %s: %s", w->name, why);
        pf_fm_strike(f, wi, why);
        return;
    }
    double now = pf_now();
    w->result_at = now;
    if (w->stuck && w->state == PF_W_READY) {
        pf_info("worker %s returns results again", w->name);
        w->stuck = 0;
    }
    if (v == PF_RESULT_DUPLICATE)
        return;
    pf_msg_result_pixels(r, f->pix);
    if (pf_fm_verify_result(f, wi, r)) {
        pf_fm_evict_pending(f);
        return;
    }
    for (uint32_t y = 0; y < r->h; y++)
        memcpy(&f->img->rgb[3 * ((size_t)(r->y0 + y) * (size_t)f->img->width + r->x0)], &f->pix[3 * (size_t)y * r->w],
               (size_t)r->w * 3 * sizeof(float));
    pf_leases_complete(&f->L, &f->reg, wi, r, now);
    f->sum->results++;
    w->tiles++;
    pf_fm_verify_kept(f, wi, (int)r->tile);
    pf_fm_evict_pending(f);
}

/* A message from a registered worker, past the checks of s_on_frame. */
static void s_dispatch(pf_fm_t *f, int wi, const pf_msg_t *m)
{
    pf_worker_t *w = &f->reg.w[wi];
    char why[96];
    switch (m->type) {
    case PF_MSG_HEARTBEAT: break; /* alive; its progress counter is not trusted */
    case PF_MSG_BLOB_REQ: s_on_blob_req(f, wi, &m->u.blob_req); break;
    case PF_MSG_READY: s_on_ready(f, wi, &m->u.ready); break;
    case PF_MSG_RESULT: s_on_result(f, wi, &m->u.result); break;
    case PF_MSG_PHOTONS: pf_fm_on_photons(f, wi, m); break;
    case PF_MSG_BYE:
        if (pf_fm_may_log(&f->peer_log, 10.0)) {
            char reason[1024];
            pf_info("worker %s left: %s", w->name, pf_log_printable(reason, sizeof reason, m->u.bye.reason));
        }
        pf_fm_release_worker(f, wi, NULL);
        pf_registry_gone(&f->reg, wi, PF_W_FREE, pf_now());
        pf_fm_fanout_gone(f, wi);
        break;
    default:
        snprintf(why, sizeof why, "%s is not a message for a coordinator", pf_msg_type_name(m->type));
        pf_fm_bad(f, w->name, why);
        pf_fm_strike(f, wi, why);
        break;
    }
}

void pf_fm_on_frame(pf_fm_t *f, const uint8_t *id, size_t idlen, const char *key, const uint8_t *data, size_t len)
{
    if (pf_registry_id_blocked(&f->reg, id, idlen)) {
        f->sum->evicted_frames++;
        return;
    }
    pf_msg_t m;
    char why[256] = "", peer[96];
    int wi = pf_registry_find(&f->reg, id, idlen);
    if (wi >= 0 && strcmp(f->reg.w[wi].key, key ? key : "") != 0) {
        pf_fm_bad(f, "a peer", "a routing identity registered under another key");
        return;
    }
    if (wi >= 0)
        snprintf(peer, sizeof peer, "worker %s", f->reg.w[wi].name);
    else
        snprintf(peer, sizeof peer, "an unregistered peer");
    if (pf_msg_decode(data, len, &m, why, sizeof why) != PF_OK) {
        pf_fm_bad(f, peer, why);
        if (wi >= 0)
            pf_fm_strike(f, wi, why);
        return;
    }
    if (m.type == PF_MSG_HELLO) {
        s_on_hello(f, id, idlen, key, &m.u.hello);
        return;
    }
    if (wi < 0) {
        pf_fm_bad(f, peer, "message before HELLO");
        return;
    }
    pf_worker_t *w = &f->reg.w[wi];
    if (w->state == PF_W_DEAD) {
        /* Messages still queued on a dead worker's old connection do not
         * bring it back (a worker that really is back registers again with a
         * HELLO); its results still count, as first results or duplicates. */
        if (m.type == PF_MSG_RESULT && m.job == f->job)
            s_on_result(f, wi, &m.u.result);
        else
            pf_debug("ignored %s from dead worker %s", pf_msg_type_name(m.type), w->name);
        return;
    }
    w->last_seen = pf_now();
    if (m.type != PF_MSG_BYE && m.job != f->job && m.type != PF_MSG_HEARTBEAT &&
        !(m.type == PF_MSG_PHOTONS && m.job == f->ph.job)) {
        pf_debug("dropped %s for job %llu from %s", pf_msg_type_name(m.type), (unsigned long long)m.job, peer);
        return;
    }
    s_dispatch(f, wi, &m);
}

/* --- fan-out (fanout.h: the tree) -------------------------------------- */

void pf_fm_fanout_job(pf_fm_t *f, int wi)
{
    pf_msg_t m = { .type = PF_MSG_BLOB_PLAN };
    int src = pf_fanout_plan(f->fan, wi, &m.u.plan);
    if (src == -1)
        return;
    if (pf_fm_send(f, wi, &m) != 0)
        return;
    /* The scene (fetched with the maps when the worker has not traced over
     * it) from the same source: the worker's one peer socket serves both. */
    pf_msg_t sm = { .type = PF_MSG_BLOB_PLAN };
    if (pf_fanout_plan_coordinator(f->fan_scene, &sm.u.plan) != -1) {
        snprintf(sm.u.plan.source, sizeof sm.u.plan.source, "%s", m.u.plan.source);
        sm.u.plan.source_uid = m.u.plan.source_uid;
        if (pf_fm_send(f, wi, &sm) == 0 && src >= 0)
            f->sum->fanout_scene_peer++;
    }
    if (src >= 0) {
        f->sum->fanout_peer++;
        pf_debug("worker %s fetches the maps from worker %s (%s)", f->reg.w[wi].name, f->reg.w[src].name,
                 m.u.plan.source);
    }
}

void pf_fm_fanout_scene(pf_fm_t *f, int wi)
{
    if (!f->fan_scene_on)
        return;
    pf_msg_t m = { .type = PF_MSG_BLOB_PLAN };
    int src = pf_fanout_plan(f->fan_scene, wi, &m.u.plan);
    if (src == -1 || pf_fm_send(f, wi, &m) != 0)
        return;
    if (src >= 0) {
        f->sum->fanout_scene_peer++;
        pf_debug("worker %s fetches the scene from worker %s (%s)", f->reg.w[wi].name, f->reg.w[src].name,
                 m.u.plan.source);
    }
}

void pf_fm_fanout_gone(pf_fm_t *f, int wi)
{
    int kids[64];
    /* The scene's tree while the first photon pass runs: a child still
     * fetching takes the rest from the coordinator (one that holds the
     * scene already ignores the plan). */
    int ns = pf_fanout_gone(f->fan_scene, wi, kids, 64);
    for (int k = 0; k < ns && f->fan_scene_on && !f->job_ready; k++) {
        int ci = kids[k];
        if (f->reg.w[ci].state != PF_W_HELLO)
            continue;
        pf_msg_t m = { .type = PF_MSG_BLOB_PLAN };
        if (pf_fanout_plan_coordinator(f->fan_scene, &m.u.plan) == -1 || pf_fm_send(f, ci, &m) != 0)
            continue;
        f->sum->fanout_fallback++;
        pf_info("worker %s fetches the scene from the coordinator now: its source, worker %s, is gone",
                f->reg.w[ci].name, f->reg.w[wi].name);
    }
    int n = pf_fanout_gone(f->fan, wi, kids, 64);
    for (int k = 0; k < n; k++) {
        int ci = kids[k];
        if (f->reg.w[ci].state != PF_W_JOB_SENT)
            continue; /* it has the maps already, or is gone itself */
        pf_msg_t m = { .type = PF_MSG_BLOB_PLAN }, sm = { .type = PF_MSG_BLOB_PLAN };
        if (pf_fanout_plan_coordinator(f->fan, &m.u.plan) == -1 || pf_fm_send(f, ci, &m) != 0)
            continue;
        if (pf_fanout_plan_coordinator(f->fan_scene, &sm.u.plan) != -1) /* the scene came from there too */
            pf_fm_send(f, ci, &sm);
        f->sum->fanout_fallback++;
        pf_info("worker %s fetches the maps from the coordinator now: its source, worker %s, is gone",
                f->reg.w[ci].name, f->reg.w[wi].name);
    }
}
