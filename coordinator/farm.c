/* farm.c: the coordinator's side of the render farm; see farm.h.
 *
 * Threads: the caller's thread runs the event loop and owns the ROUTER
 * socket; a helper thread runs the photon pass (so workers that connect in
 * the meantime are welcomed and heartbeated); the ZAP thread (zap.c)
 * authenticates CURVE clients.
 *
 * Tiles are leased as (job, tile, attempt). The first valid RESULT for a
 * tile wins; later ones are counted as duplicates and dropped. A lease
 * returns its tile to the front of the queue (attempt + 1) when its worker
 * falls silent for dead_after heartbeats, when its progress counter stalls
 * for watchdog_s while it holds tiles (stuck in compute: libzmq's own
 * heartbeat would still be answered by its I/O thread), or after
 * lease_timeout_s. Each worker holds up to the credit it announced, so it
 * never idles waiting for the next tile. Every frame from the network goes
 * through pf_msg_decode; a bad one is logged (rate-limited) and dropped. */
#include "coordinator/farm.h"

#include <errno.h>
#include <omp.h>
#include <pthread.h>
#include <signal.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/wait.h>
#include <unistd.h>
#include <zmq.h>

#include "base/hash.h"
#include "base/keyfile.h"
#include "base/log.h"
#include "coordinator/progress.h"
#include "coordinator/spawn.h"
#include "coordinator/zap.h"
#include "photon/mapfile.h"
#include "proto/messages.h"
#include "proto/sceneblob.h"
#include "render/render.h"

#define S_MAX_WORKERS 1024
#define S_MAX_LOCAL 256

enum { W_FREE = 0, W_HELLO, W_JOB_SENT, W_READY, W_DEAD };
enum { T_QUEUED = 0, T_LEASED, T_DONE };

typedef struct s_worker {
    int state;
    uint8_t id[256];
    size_t idlen;
    uint32_t wid;
    char name[64];
    uint32_t threads;
    double last_seen, last_sent;
    uint64_t progress;
    double progress_at; /* when progress last changed */
    int stuck;
    uint32_t credit, held;
    uint64_t tiles;
    uint64_t blob_sent; /* bytes of scene and maps sent in this job (for the transfer display) */
} s_worker;

#define S_LESSEES 4

typedef struct s_tile {
    int state;
    uint32_t attempt;
    int owner; /* worker slot of the current lease, or -1 */
    int lessees[S_LESSEES]; /* the last workers this tile was leased to: only they may return it */
    int nlessees;
    double leased_at;
    uint32_t x0, y0, w, h;
} s_tile;

/* The photon pass, run in its own thread. */
typedef struct s_photons {
    const pf_scene_t *scene;
    pf_settings_t settings; /* a time limit changes them here, before the job goes out */
    pf_budget_t *budget;
    unsigned terms;
    pf_frame_t frame; /* the scene's accel and lights, then the maps */
    pf_photon_stats_t stats;
    pf_buf_t scene_blob, maps_blob;
    uint64_t scene_hash, maps_hash;
    int rc;
    volatile int done;
    pf_error_t err;
} s_photons;

static void *s_photon_thread(void *arg)
{
    s_photons *p = arg;
    pf_frame_t *fr = &p->frame;
    p->rc = pf_frame_open(fr, p->scene, &p->err);
    if (p->rc == PF_OK) {
        if (p->budget)
            p->rc = pf_budget_plan_photons(p->budget, fr, &p->settings);
        if (p->rc == PF_OK)
            p->rc = pf_photon_pass(p->scene, fr->accel, fr->lights, &p->settings, &fr->maps, &p->stats);
        if (p->rc)
            pf_error_set(&p->err, p->rc, NULL, 0, "photon pass failed: %s", pf_strerror(p->rc));
    }
    if (p->rc == PF_OK)
        pf_photon_skip_gather(&p->stats, &p->settings);
    if (p->rc == PF_OK && p->budget) {
        /* The probe renders here with the coordinator's cores, as the workers will. */
        pf_frame_ready(fr);
        pf_budget_plan_spp(p->budget, fr, p->terms, p->settings.threads, &p->settings);
        pf_budget_log(p->budget, &p->settings);
    }
    if (p->rc == PF_OK)
        p->rc = pf_sceneblob_write(p->scene, &p->scene_blob);
    if (p->rc == PF_OK) {
        p->scene_hash = pf_hash_bytes(PF_HASH_INIT, p->scene_blob.data, p->scene_blob.len);
        p->rc = pf_mapfile_write(&fr->maps, p->scene_hash, pf_settings_hash(&p->settings), &p->maps_blob);
        p->maps_hash = pf_hash_bytes(PF_HASH_INIT, p->maps_blob.data, p->maps_blob.len);
        if (p->rc)
            pf_error_set(&p->err, p->rc, NULL, 0, "cannot serialize the photon maps: %s", pf_strerror(p->rc));
    }
    __atomic_store_n(&p->done, 1, __ATOMIC_RELEASE);
    return NULL;
}

typedef struct s_farm {
    const pf_farm_opts_t *o;
    void *ctx, *sock;
    uint64_t job;
    s_worker *w;
    int nw;
    s_tile *t;
    int nt, ndone;
    int *queue; /* tile indices, a ring */
    int qhead, qlen;
    s_photons ph;
    pf_msg_job_t jobmsg;
    int job_ready;
    pf_image_t *img;
    pf_buf_t out;
    pf_farm_summary_t *sum;
    uint32_t next_wid;
    double last_bad_log;
    int bad_since_log;
    int leasing; /* tiles have been leased: --min-workers was met once */
    /* What pf_farm_render's steps share: the job's clock, what it started
     * (and must stop), and the event loop's clocks. */
    double t0;          /* when the job began */
    int ts;             /* tile side in pixels */
    char endpoint[256]; /* where the socket listens, for the local workers */
    pf_zap_t *zap;
    pid_t pids[S_MAX_LOCAL];
    int npids;
    pthread_t phtid;
    int ph_started; /* the photon thread runs and has not been joined */
    pf_progress_t bar;
    double render_start, last_log, no_worker_since;
} s_farm;

/* --- sending ------------------------------------------------------------ */

static int s_send(s_farm *f, int wi, pf_msg_t *m)
{
    s_worker *w = &f->w[wi];
    m->job = m->job ? m->job : f->job;
    if (pf_msg_encode(m, &f->out) != PF_OK)
        return -1;
    if (zmq_send(f->sock, w->id, w->idlen, ZMQ_SNDMORE | ZMQ_DONTWAIT) < 0 ||
        zmq_send(f->sock, f->out.data, f->out.len, ZMQ_DONTWAIT) < 0) {
        /* ROUTER_MANDATORY: an unroutable peer is gone; a full queue waits. */
        if (zmq_errno() == EHOSTUNREACH && w->state != W_DEAD)
            pf_debug("worker %s is unreachable", w->name);
        return -1;
    }
    w->last_sent = pf_now();
    f->sum->bytes_sent += f->out.len;
    return 0;
}

static void s_requeue(s_farm *f, int ti, int front)
{
    s_tile *t = &f->t[ti];
    if (t->state == T_DONE)
        return;
    if (t->state == T_LEASED && t->owner >= 0 && f->w[t->owner].held > 0)
        f->w[t->owner].held--;
    t->state = T_QUEUED;
    t->owner = -1;
    t->attempt++;
    if (front) {
        f->qhead = (f->qhead + f->nt - 1) % f->nt;
        f->queue[f->qhead] = ti;
    } else {
        f->queue[(f->qhead + f->qlen) % f->nt] = ti;
    }
    f->qlen++;
    f->sum->reissued++;
}

/* Returns a worker's leased tiles to the front of the queue. */
static void s_release_worker(s_farm *f, int wi, const char *why)
{
    int n = 0;
    for (int i = 0; i < f->nt; i++)
        if (f->t[i].state == T_LEASED && f->t[i].owner == wi) {
            s_requeue(f, i, 1);
            n++;
        }
    f->w[wi].held = 0;
    if (n || why)
        pf_warn("worker %s %s: %d tile%s re-issued", f->w[wi].name, why ? why : "released", n, n == 1 ? "" : "s");
}

static void s_lease(s_farm *f, int wi)
{
    s_worker *w = &f->w[wi];
    if (w->state != W_READY || w->stuck)
        return;
    if (!f->leasing) { /* --min-workers holds back the start only, never a running job */
        int ready = 0;
        for (int i = 0; i < f->nw; i++)
            ready += f->w[i].state == W_READY;
        if (ready < f->o->min_workers)
            return;
        f->leasing = 1;
    }
    if (w->held == 0 && f->qlen > 0)
        w->progress_at = pf_now(); /* the stall clock runs only while it holds tiles */
    while (w->held < w->credit && f->qlen > 0) {
        int ti = f->queue[f->qhead];
        f->qhead = (f->qhead + 1) % f->nt;
        f->qlen--;
        s_tile *t = &f->t[ti];
        pf_msg_t m = { .type = PF_MSG_TILE };
        m.u.tile = (pf_msg_tile_t){ (uint32_t)ti, t->attempt, t->x0, t->y0, t->w, t->h };
        t->state = T_LEASED;
        t->owner = wi;
        t->leased_at = pf_now();
        if (t->nlessees == S_LESSEES) {
            memmove(t->lessees, t->lessees + 1, (S_LESSEES - 1) * sizeof *t->lessees);
            t->nlessees--;
        }
        t->lessees[t->nlessees++] = wi;
        w->held++;
        if (s_send(f, wi, &m) != 0) {
            s_requeue(f, ti, 1);
            f->sum->reissued--; /* never left: not a re-issue */
            f->t[ti].attempt--;
            break;
        }
    }
}

static void s_lease_all(s_farm *f)
{
    for (int i = 0; i < f->nw; i++)
        s_lease(f, i);
}

static void s_send_job(s_farm *f, int wi)
{
    pf_msg_t m = { .type = PF_MSG_JOB };
    m.u.job = f->jobmsg;
    if (s_send(f, wi, &m) == 0)
        f->w[wi].state = W_JOB_SENT;
}

/* --- receiving ---------------------------------------------------------- */

static int s_find(s_farm *f, const uint8_t *id, size_t len)
{
    for (int i = 0; i < f->nw; i++)
        if (f->w[i].state != W_FREE && f->w[i].idlen == len && memcmp(f->w[i].id, id, len) == 0)
            return i;
    return -1;
}

static void s_bad(s_farm *f, const char *peer, const char *why)
{
    f->sum->malformed++;
    double now = pf_now();
    if (now - f->last_bad_log > 2.0) {
        if (f->bad_since_log)
            pf_warn("dropped %d more malformed messages", f->bad_since_log);
        pf_warn("dropped a malformed message from %s: %s", peer, why);
        f->last_bad_log = now;
        f->bad_since_log = 0;
    } else {
        f->bad_since_log++;
    }
}

static void s_on_hello(s_farm *f, const uint8_t *id, size_t idlen, const pf_msg_hello_t *h)
{
    char why[256] = "";
    pf_fingerprint_t self = pf_frame_fingerprint();
    int wi = s_find(f, id, idlen);
    if (wi < 0) {
        for (wi = 0; wi < f->nw && f->w[wi].state != W_FREE; wi++)
            ;
        if (wi == f->nw) {
            if (f->nw == S_MAX_WORKERS) {
                pf_warn("too many workers; ignoring %s", h->name);
                return;
            }
            f->nw++;
        }
        memset(&f->w[wi], 0, sizeof f->w[wi]);
        memcpy(f->w[wi].id, id, idlen);
        f->w[wi].idlen = idlen;
    } else if (f->w[wi].held) {
        s_release_worker(f, wi, "registered again");
    }
    s_worker *w = &f->w[wi];
    snprintf(w->name, sizeof w->name, "%.63s", h->name);
    w->threads = h->threads;
    w->last_seen = w->progress_at = pf_now();
    if (pf_fingerprint_check(&h->fp, &self, why, sizeof why) != PF_OK) {
        pf_msg_t m = { .type = PF_MSG_REFUSE };
        snprintf(m.u.refuse.reason, sizeof m.u.refuse.reason, "%s", why);
        w->state = W_HELLO;
        s_send(f, wi, &m);
        pf_warn("refused worker %s: %s", w->name, why);
        f->sum->refused++;
        w->state = W_FREE;
        return;
    }
    if (strcmp(h->fp.git, self.git) != 0)
        pf_info("worker %s was built from %s (this coordinator: %s)", w->name, h->fp.git, self.git);
    w->state = W_HELLO;
    w->wid = ++f->next_wid;
    f->sum->workers_seen++;
    pf_msg_t m = { .type = PF_MSG_WELCOME };
    m.u.welcome = (pf_msg_welcome_t){ w->wid, (uint32_t)f->o->heartbeat_ms };
    s_send(f, wi, &m);
    pf_info("worker %s joined (%u thread%s)", w->name, w->threads, w->threads == 1 ? "" : "s");
    if (f->job_ready)
        s_send_job(f, wi);
}

static void s_on_blob_req(s_farm *f, int wi, const pf_msg_blob_req_t *r)
{
    const pf_buf_t *blob = r->hash == f->ph.scene_hash ? &f->ph.scene_blob
                         : r->hash == f->ph.maps_hash  ? &f->ph.maps_blob
                                                       : NULL;
    if (!f->job_ready || !blob) {
        pf_warn("worker %s asked for an unknown blob %016llx", f->w[wi].name, (unsigned long long)r->hash);
        return;
    }
    uint64_t off = r->offset;
    for (uint32_t c = 0; c < r->credit && off < blob->len; c++) {
        uint64_t len = blob->len - off < PF_PROTO_CHUNK_SIZE ? blob->len - off : PF_PROTO_CHUNK_SIZE;
        pf_msg_t m = { .type = PF_MSG_BLOB_CHUNK };
        m.u.chunk = (pf_msg_blob_chunk_t){ r->hash, blob->len, off, (uint32_t)len, blob->data + off };
        if (s_send(f, wi, &m) != 0)
            break;
        f->sum->blob_bytes += len;
        f->w[wi].blob_sent += len;
        off += len;
    }
}

static void s_on_result(s_farm *f, int wi, const pf_msg_result_t *r)
{
    if (r->tile >= (uint32_t)f->nt) {
        s_bad(f, f->w[wi].name, "RESULT for a tile that does not exist");
        return;
    }
    s_tile *t = &f->t[r->tile];
    if (r->x0 != t->x0 || r->y0 != t->y0 || r->w != t->w || r->h != t->h || r->attempt > t->attempt) {
        s_bad(f, f->w[wi].name, "RESULT does not match its tile's lease");
        return;
    }
    int leased = 0;
    for (int k = 0; k < t->nlessees; k++)
        leased |= t->lessees[k] == wi;
    if (!leased) {
        s_bad(f, f->w[wi].name, "RESULT for a tile that was not leased to it");
        return;
    }
    /* Invariant: a worker's held = tiles in state LEASED whose owner it is. */
    if (t->state == T_DONE) {
        f->sum->duplicates++;
        return;
    }
    if (t->state == T_LEASED) {
        if (t->owner >= 0 && f->w[t->owner].held > 0)
            f->w[t->owner].held--;
    } else { /* re-issued and waiting in the queue: this result makes it done, take it out */
        for (int k = 0; k < f->qlen; k++) {
            if (f->queue[(f->qhead + k) % f->nt] != (int)r->tile)
                continue;
            for (int j = k; j > 0; j--)
                f->queue[(f->qhead + j) % f->nt] = f->queue[(f->qhead + j - 1) % f->nt];
            f->qhead = (f->qhead + 1) % f->nt;
            f->qlen--;
            break;
        }
    }
    float *row = malloc((size_t)r->w * 3 * sizeof *row * r->h);
    if (!row)
        return;
    pf_msg_result_pixels(r, row);
    for (uint32_t y = 0; y < r->h; y++)
        memcpy(&f->img->rgb[3 * ((size_t)(r->y0 + y) * (size_t)f->img->width + r->x0)], &row[3 * (size_t)y * r->w],
               (size_t)r->w * 3 * sizeof(float));
    free(row);
    t->state = T_DONE;
    t->owner = -1;
    f->ndone++;
    f->sum->results++;
    f->w[wi].tiles++;
}

static void s_on_frame(s_farm *f, const uint8_t *id, size_t idlen, const uint8_t *data, size_t len)
{
    pf_msg_t m;
    char why[256] = "";
    int wi = s_find(f, id, idlen);
    char peer[80];
    if (wi >= 0)
        snprintf(peer, sizeof peer, "worker %s", f->w[wi].name);
    else
        snprintf(peer, sizeof peer, "an unregistered peer");
    int rc = pf_msg_decode(data, len, &m, why, sizeof why);
    if (rc != PF_OK) {
        s_bad(f, peer, why);
        return;
    }
    if (m.type == PF_MSG_HELLO) {
        s_on_hello(f, id, idlen, &m.u.hello);
        return;
    }
    if (wi < 0) {
        s_bad(f, peer, "message before HELLO");
        return;
    }
    s_worker *w = &f->w[wi];
    if (w->state == W_DEAD) {
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
    if (m.type != PF_MSG_BYE && m.job != f->job && m.type != PF_MSG_HEARTBEAT) {
        pf_debug("dropped %s for job %llu from %s", pf_msg_type_name(m.type), (unsigned long long)m.job, peer);
        return;
    }
    switch (m.type) {
    case PF_MSG_HEARTBEAT:
        if (m.u.heartbeat.progress != w->progress) {
            w->progress = m.u.heartbeat.progress;
            w->progress_at = w->last_seen;
            if (w->stuck) {
                pf_info("worker %s makes progress again", w->name);
                w->stuck = 0;
            }
        }
        break;
    case PF_MSG_BLOB_REQ: s_on_blob_req(f, wi, &m.u.blob_req); break;
    case PF_MSG_READY:
        if (w->state != W_READY)
            pf_info("worker %s ready: scene and maps built", w->name);
        w->state = W_READY;
        w->credit = m.u.ready.credit;
        w->progress_at = w->last_seen;
        break;
    case PF_MSG_RESULT: s_on_result(f, wi, &m.u.result); break;
    case PF_MSG_BYE:
        pf_info("worker %s left: %s", w->name, m.u.bye.reason);
        s_release_worker(f, wi, NULL);
        w->state = W_FREE;
        break;
    default: s_bad(f, peer, "unexpected message type for a coordinator"); break;
    }
}

/* --- housekeeping -------------------------------------------------------- */

static void s_tick(s_farm *f)
{
    double now = pf_now();
    double hb = f->o->heartbeat_ms / 1000.0;
    for (int i = 0; i < f->nw; i++) {
        s_worker *w = &f->w[i];
        if (w->state == W_FREE || w->state == W_DEAD)
            continue;
        if (now - w->last_seen > f->o->dead_after * hb) {
            w->state = W_DEAD;
            f->sum->workers_lost++;
            s_release_worker(f, i, "is silent: declared dead");
            continue;
        }
        if (w->held && !w->stuck && now - w->progress_at > f->o->watchdog_s) {
            w->stuck = 1;
            s_release_worker(f, i, "makes no progress (stuck in compute?)");
        }
        if (now - w->last_sent >= hb) {
            pf_msg_t m = { .type = PF_MSG_HEARTBEAT };
            s_send(f, i, &m);
        }
    }
    for (int i = 0; i < f->nt; i++)
        if (f->t[i].state == T_LEASED && now - f->t[i].leased_at > f->o->lease_timeout_s) {
            pf_warn("lease of tile %d expired", i);
            s_requeue(f, i, 1);
        }
}

/* --- the job's steps ------------------------------------------------------ */

void pf_farm_opts_default(pf_farm_opts_t *o)
{
    memset(o, 0, sizeof *o);
    o->tile_size = 32;
    o->heartbeat_ms = 1000;
    o->dead_after = 4;
    o->lease_timeout_s = 120.0;
    o->watchdog_s = 30.0;
    o->min_workers = 1;
}

static int s_loopback(const char *ep)
{
    return strncmp(ep, "ipc://", 6) == 0 || strncmp(ep, "inproc://", 9) == 0 || strstr(ep, "://127.") ||
           strstr(ep, "://localhost") || strstr(ep, "://[::1]");
}

/* The tile table, all tiles queued in order, and the worker table. */
static int s_alloc_tables(s_farm *f, const pf_settings_t *s, pf_error_t *err)
{
    int ts = f->o->tile_size > 0 ? f->o->tile_size : 32;
    int tx = (s->width + ts - 1) / ts, ty = (s->height + ts - 1) / ts;
    f->ts = ts;
    f->nt = tx * ty;
    f->t = calloc((size_t)f->nt, sizeof *f->t);
    f->queue = calloc((size_t)f->nt, sizeof *f->queue);
    f->w = calloc(S_MAX_WORKERS, sizeof *f->w);
    if (!f->t || !f->queue || !f->w)
        return pf_error_set(err, PF_ENOMEM, NULL, 0, "out of memory");
    for (int i = 0; i < f->nt; i++) {
        s_tile *t = &f->t[i];
        t->x0 = (uint32_t)((i % tx) * ts);
        t->y0 = (uint32_t)((i / tx) * ts);
        t->w = (uint32_t)(t->x0 + (uint32_t)ts <= (uint32_t)s->width ? ts : s->width - (int)t->x0);
        t->h = (uint32_t)(t->y0 + (uint32_t)ts <= (uint32_t)s->height ? ts : s->height - (int)t->y0);
        t->owner = -1;
        f->queue[i] = i;
    }
    f->qlen = f->nt;
    return PF_OK;
}

/* CURVE on the socket: the coordinator's key, and a ZAP handler that admits
 * only the allowed worker keys. */
static int s_setup_curve(s_farm *f, pf_error_t *err)
{
    const pf_farm_opts_t *opts = f->o;
    int one = 1;
    char pub[41], sec[41];
    char (*keys)[41] = NULL;
    size_t nkeys = 0;
    if (pf_keyfile_read(opts->curve_secret, pub, sec, err) != PF_OK)
        return PF_EINVAL;
    if (!opts->curve_allow)
        return pf_error_set(err, PF_EINVAL, NULL, 0, "CURVE needs a list of allowed worker keys (--curve-allow)");
    if (pf_keyfile_read_list(opts->curve_allow, &keys, &nkeys, err) != PF_OK)
        return PF_EINVAL;
    f->zap = pf_zap_start(f->ctx, (const char(*)[41])keys, nkeys);
    free(keys);
    if (!f->zap)
        return pf_error_set(err, PF_EIO, NULL, 0, "cannot start the CURVE authentication handler");
    zmq_setsockopt(f->sock, ZMQ_ZAP_DOMAIN, "photonfarm", 10);
    zmq_setsockopt(f->sock, ZMQ_CURVE_SERVER, &one, sizeof one);
    zmq_setsockopt(f->sock, ZMQ_CURVE_SECRETKEY, sec, 40);
    pf_info("CURVE on: %zu worker key%s allowed", nkeys, nkeys == 1 ? "" : "s");
    return PF_OK;
}

/* The ROUTER socket, with CURVE and its ZAP handler when asked, bound; its
 * endpoint lands in f->endpoint. */
static int s_open_socket(s_farm *f, pf_error_t *err)
{
    const pf_farm_opts_t *opts = f->o;
    f->ctx = zmq_ctx_new();
    f->sock = f->ctx ? zmq_socket(f->ctx, ZMQ_ROUTER) : NULL;
    if (!f->sock)
        return pf_error_set(err, PF_EIO, NULL, 0, "cannot create a ZeroMQ socket: %s", zmq_strerror(zmq_errno()));
    int one = 1, linger = 1000, hwm = 100000;
    int64_t maxmsg = PF_PROTO_MAX_MESSAGE;
    zmq_setsockopt(f->sock, ZMQ_ROUTER_MANDATORY, &one, sizeof one);
    zmq_setsockopt(f->sock, ZMQ_LINGER, &linger, sizeof linger);
    zmq_setsockopt(f->sock, ZMQ_MAXMSGSIZE, &maxmsg, sizeof maxmsg);
    zmq_setsockopt(f->sock, ZMQ_SNDHWM, &hwm, sizeof hwm);
    zmq_setsockopt(f->sock, ZMQ_RCVHWM, &hwm, sizeof hwm);
    if (opts->curve_secret) {
        int rc = s_setup_curve(f, err);
        if (rc != PF_OK)
            return rc;
    }
    const char *bind = opts->bind ? opts->bind : "tcp://127.0.0.1:*";
    if (zmq_bind(f->sock, bind) != 0)
        return pf_error_set(err, PF_EIO, NULL, 0, "cannot bind %s: %s", bind, zmq_strerror(zmq_errno()));
    size_t eplen = sizeof f->endpoint;
    zmq_getsockopt(f->sock, ZMQ_LAST_ENDPOINT, f->endpoint, &eplen);
    if (!s_loopback(f->endpoint) && !opts->curve_secret)
        pf_warn("listening on %s without CURVE: anyone who can reach it can join and read the scene "
                "(see 'photonfarm keygen')", f->endpoint);
    pf_info("listening on %s", f->endpoint);
    return PF_OK;
}

/* Local workers, started now so they connect during the photon pass. Their
 * pids go to f->pids, which are stopped on every path. */
static int s_start_local_workers(s_farm *f, pf_error_t *err)
{
    const pf_farm_opts_t *opts = f->o;
    if (opts->local_workers <= 0)
        return PF_OK;
    char exe[4096];
    if (opts->worker_exe)
        snprintf(exe, sizeof exe, "%s", opts->worker_exe);
    else if (pf_spawn_default_worker_exe(exe, sizeof exe) != 0)
        return pf_error_set(err, PF_EIO, NULL, 0, "cannot find photonfarm-worker beside this program");
    if (access(exe, X_OK) != 0)
        return pf_error_set(err, PF_EIO, exe, 0, "cannot run the worker program: %s", strerror(errno));
    int wt = opts->worker_threads > 0 ? opts->worker_threads
                                      : (omp_get_num_procs() / opts->local_workers > 0
                                             ? omp_get_num_procs() / opts->local_workers
                                             : 1);
    char threads[16], name[64];
    snprintf(threads, sizeof threads, "%d", wt);
    int nloc = opts->local_workers < S_MAX_LOCAL ? opts->local_workers : S_MAX_LOCAL;
    for (int i = 0; i < nloc; i++) {
        snprintf(name, sizeof name, "local-%d", i + 1);
        /* Local workers report through the coordinator (joins, losses,
         * the summary); their own lines only for warnings, or all with -v. */
        char *argv[] = { exe, "--connect", f->endpoint, "--threads", threads, "--name", name, "--exit-on-bye",
                         pf_log_get_level() <= PF_LOG_DEBUG ? "-v" : "-q", NULL };
        pid_t pid = pf_spawn(exe, argv);
        if (pid < 0)
            return pf_error_set(err, PF_EIO, exe, 0, "cannot start a worker: %s", strerror(errno));
        f->pids[f->npids++] = pid;
    }
    pf_info("started %d local worker%s with %d thread%s each", f->npids, f->npids == 1 ? "" : "s", wt,
            wt == 1 ? "" : "s");
    return PF_OK;
}

/* The photon pass runs beside the event loop. */
static int s_start_photons(s_farm *f, const pf_scene_t *scene, const pf_settings_t *s, unsigned terms,
                           pf_error_t *err)
{
    f->ph.scene = scene;
    f->ph.settings = *s;
    f->ph.budget = f->o->budget;
    f->ph.terms = terms;
    if (pthread_create(&f->phtid, NULL, s_photon_thread, &f->ph) != 0)
        return pf_error_set(err, PF_ENOMEM, NULL, 0, "cannot start the photon pass thread");
    f->ph_started = 1;
    return PF_OK;
}

/* The photon pass has finished: join it, and on success make the job
 * ready and send it to the workers waiting for it. */
static int s_on_photons_done(s_farm *f, pf_error_t *err)
{
    pf_farm_summary_t *sum = f->sum;
    pthread_join(f->phtid, NULL);
    f->ph_started = 0;
    if (f->ph.rc != PF_OK) {
        *err = f->ph.err;
        return f->ph.rc;
    }
    sum->photons = f->ph.stats;
    sum->photon_s = pf_now() - f->t0;
    pf_progress_end(&f->bar);
    pf_info("photon pass: %llu global + %llu caustic photons, %llu irradiance points; scene blob %zu bytes, "
            "map blob %zu bytes (%.1f bytes per photon)",
            (unsigned long long)f->ph.stats.global_stored, (unsigned long long)f->ph.stats.caustic_stored,
            (unsigned long long)f->ph.stats.irradiance_points, f->ph.scene_blob.len, f->ph.maps_blob.len,
            (double)f->ph.maps_blob.len /
                (double)(f->ph.stats.global_stored + f->ph.stats.caustic_stored + f->ph.stats.irradiance_points + 1));
    pf_settings_t s = f->ph.settings; /* as a time limit planned them */
    f->jobmsg = (pf_msg_job_t){ f->ph.scene_hash, f->ph.scene_blob.len, f->ph.maps_hash, f->ph.maps_blob.len,
                                s, f->ph.terms, (uint32_t)f->ts };
    f->job_ready = 1;
    f->render_start = pf_now();
    pf_progress_begin(&f->bar, "render", f->o->show_progress);
    for (int i = 0; i < f->nw; i++)
        if (f->w[i].state == W_HELLO)
            s_send_job(f, i);
    return PF_OK;
}

/* Takes up to 256 queued messages off the socket without blocking, so the
 * housekeeping after each poll is never starved. */
static void s_recv_burst(s_farm *f)
{
    for (int burst = 0; burst < 256; burst++) {
        zmq_msg_t id, body;
        zmq_msg_init(&id);
        if (zmq_msg_recv(&id, f->sock, ZMQ_DONTWAIT) < 0) {
            zmq_msg_close(&id);
            break;
        }
        zmq_msg_init(&body);
        int more = zmq_msg_more(&id);
        if (!more || zmq_msg_recv(&body, f->sock, ZMQ_DONTWAIT) < 0) {
            s_bad(f, "a peer", "empty message");
        } else {
            if (zmq_msg_more(&body)) { /* our protocol is one frame; drain and drop the rest */
                s_bad(f, "a peer", "multi-frame message");
                while (zmq_msg_more(&body)) {
                    zmq_msg_close(&body);
                    zmq_msg_init(&body);
                    zmq_msg_recv(&body, f->sock, 0);
                }
            } else if (zmq_msg_size(&id) <= sizeof f->w[0].id) {
                s_on_frame(f, zmq_msg_data(&id), zmq_msg_size(&id), zmq_msg_data(&body), zmq_msg_size(&body));
            }
        }
        zmq_msg_close(&body);
        zmq_msg_close(&id);
    }
}

/* Workers that have registered and not left or died. */
static int s_count_alive(const s_farm *f)
{
    int alive = 0;
    for (int i = 0; i < f->nw; i++)
        alive += f->w[i].state == W_READY || f->w[i].state == W_JOB_SENT || f->w[i].state == W_HELLO;
    return alive;
}

/* A local worker that exits on its own is reported, not waited for. */
static void s_reap_local_workers(s_farm *f)
{
    for (int i = 0; i < f->npids; i++) {
        int status;
        if (f->pids[i] > 0 && waitpid(f->pids[i], &status, WNOHANG) == f->pids[i]) {
            pf_warn("local worker process %d exited (%s %d)", (int)f->pids[i],
                    WIFSIGNALED(status) ? "signal" : "status",
                    WIFSIGNALED(status) ? WTERMSIG(status) : WEXITSTATUS(status));
            f->pids[i] = 0;
        }
    }
}

/* The progress bar's note: workers alive, and the map transfers still under
 * way; without a bar, a log line every 5 s. */
static void s_note_progress(s_farm *f, int alive)
{
    char note[256];
    int nn = snprintf(note, sizeof note, "workers %d", alive);
    uint64_t blobs = f->ph.scene_blob.len + f->ph.maps_blob.len;
    for (int i = 0; i < f->nw && nn < (int)sizeof note - 40; i++)
        if (f->w[i].state == W_JOB_SENT && f->w[i].blob_sent > 0 && f->w[i].blob_sent < blobs)
            nn += snprintf(note + nn, sizeof note - (size_t)nn, "  maps->%.12s %d%%", f->w[i].name,
                           (int)(100.0 * (double)f->w[i].blob_sent / (double)blobs));
    pf_progress_update_note(&f->bar, f->ndone, f->nt, note);
    if (!f->bar.enabled && pf_now() - f->last_log > 5.0) {
        f->last_log = pf_now();
        pf_info("render: %d/%d tiles, %d worker%s alive", f->ndone, f->nt, alive, alive == 1 ? "" : "s");
    }
}

/* The event loop: runs until every tile is done, *stop is set, the photon
 * pass fails, polling fails, or no worker has been alive for max_wait_s. */
static int s_event_loop(s_farm *f, volatile int *stop, pf_error_t *err)
{
    const pf_farm_opts_t *opts = f->o;
    int rc = PF_OK;
    pf_progress_begin(&f->bar, "photons", opts->show_progress);
    f->render_start = 0.0;
    f->last_log = pf_now();
    f->no_worker_since = pf_now();
    while (f->ndone < f->nt) {
        if (stop && *stop) {
            rc = pf_error_set(err, PF_EINTERRUPTED, NULL, 0, "interrupted");
            break;
        }
        if (!f->job_ready && __atomic_load_n(&f->ph.done, __ATOMIC_ACQUIRE)) {
            rc = s_on_photons_done(f, err);
            if (rc != PF_OK)
                break;
        }
        zmq_pollitem_t it = { f->sock, 0, ZMQ_POLLIN, 0 };
        int pr = zmq_poll(&it, 1, 50);
        if (pr < 0 && zmq_errno() != EINTR) {
            rc = pf_error_set(err, PF_EIO, NULL, 0, "poll failed: %s", zmq_strerror(zmq_errno()));
            break;
        }
        if (pr > 0)
            s_recv_burst(f);
        s_tick(f);
        if (f->job_ready)
            s_lease_all(f);
        int alive = s_count_alive(f);
        if (alive)
            f->no_worker_since = pf_now();
        else if (opts->max_wait_s > 0 && pf_now() - f->no_worker_since > opts->max_wait_s) {
            rc = pf_error_set(err, PF_ETIMEOUT, NULL, 0, "no worker for %.0f s: giving up", opts->max_wait_s);
            break;
        }
        if (f->npids)
            s_reap_local_workers(f);
        if (f->job_ready)
            s_note_progress(f, alive);
    }
    pf_progress_end(&f->bar);
    if (rc == PF_OK)
        f->sum->render_s = pf_now() - f->render_start;
    return rc;
}

/* Job over: tell everyone, then let local workers go. Workers declared
 * dead are told too: one that was only stopped (SIGSTOP) may be back. */
static void s_end_job(s_farm *f, int rc)
{
    for (int i = 0; i < f->nw; i++)
        if (f->w[i].state != W_FREE) {
            pf_msg_t m = { .type = PF_MSG_JOB_END };
            s_send(f, i, &m);
            pf_msg_t b = { .type = PF_MSG_BYE };
            snprintf(b.u.bye.reason, sizeof b.u.bye.reason, "%s", rc == PF_OK ? "job complete" : "coordinator stopping");
            s_send(f, i, &b);
        }
}

/* Tiles per worker into the summary: one line per name, also for a worker
 * that registered twice; at most 64 names. */
static void s_sum_per_worker(s_farm *f)
{
    pf_farm_summary_t *sum = f->sum;
    for (int i = 0; i < f->nw; i++) {
        if (!f->w[i].tiles)
            continue;
        int k = 0;
        while (k < sum->nper_worker && strcmp(sum->per_worker[k].name, f->w[i].name) != 0)
            k++;
        if (k == sum->nper_worker) {
            if (k == 64)
                continue;
            snprintf(sum->per_worker[k].name, sizeof sum->per_worker[k].name, "%s", f->w[i].name);
            sum->per_worker[k].tiles = 0;
            sum->nper_worker++;
        }
        sum->per_worker[k].tiles += f->w[i].tiles;
    }
}

/* Stops and frees whatever the steps started, on every path. */
static void s_free(s_farm *f)
{
    if (f->ph_started) {
        pthread_join(f->phtid, NULL); /* the photon pass cannot be cancelled midway; it ends on its own */
    }
    if (f->npids)
        pf_spawn_stop_all(f->pids, f->npids, 3.0);
    if (f->sock)
        zmq_close(f->sock);
    if (f->zap)
        f->sum->refused += (uint64_t)pf_zap_stop(&f->zap);
    if (f->ctx)
        zmq_ctx_term(f->ctx);
    pf_frame_close(&f->ph.frame);
    pf_buf_free(&f->ph.scene_blob);
    pf_buf_free(&f->ph.maps_blob);
    pf_buf_free(&f->out);
    free(f->t);
    free(f->queue);
    free(f->w);
}

int pf_farm_render(const pf_scene_t *scene, const pf_settings_t *settings, unsigned terms, const pf_farm_opts_t *opts,
                   volatile int *stop, pf_image_t *img, pf_farm_summary_t *sum, pf_error_t *err)
{
    memset(sum, 0, sizeof *sum);
    double t0 = pf_now();
    s_farm f;
    memset(&f, 0, sizeof f);
    f.o = opts;
    f.sum = sum;
    f.img = img;
    f.t0 = t0;
    f.job = ((uint64_t)getpid() << 32) ^ (uint64_t)(t0 * 1000.0);
    if (f.job == 0)
        f.job = 1;

    pf_settings_t s = *settings;
    if (s.threads <= 0)
        s.threads = omp_get_num_procs();
    int rc = pf_image_alloc(img, s.width, s.height);
    if (rc)
        return pf_error_set(err, rc, NULL, 0, "cannot allocate a %dx%d image", s.width, s.height);
    rc = s_alloc_tables(&f, &s, err);
    if (rc == PF_OK)
        rc = s_open_socket(&f, err);
    if (rc == PF_OK)
        rc = s_start_local_workers(&f, err);
    if (rc == PF_OK)
        rc = s_start_photons(&f, scene, &s, terms, err);
    if (rc == PF_OK) {
        rc = s_event_loop(&f, stop, err);
        s_end_job(&f, rc);
        s_sum_per_worker(&f);
    }
    s_free(&f);
    if (rc != PF_OK) {
        pf_image_free(img);
    } else {
        size_t neg = 0;
        sum->bad_pixels = pf_image_count_bad(img, &neg) + neg;
    }
    sum->total_s = pf_now() - t0;
    return rc;
}

void pf_farm_summary_log(const pf_farm_summary_t *s)
{
    pf_info("summary: photon pass %.2f s, render %.2f s, total %.2f s", s->photon_s, s->render_s, s->total_s);
    pf_info("summary: %llu tiles, %.1f MB sent (%.1f MB of scene and maps), %llu re-issued, %llu duplicates dropped, "
            "%llu malformed messages dropped, %d worker%s seen, %d lost, %llu refused",
            (unsigned long long)s->results, s->bytes_sent / 1e6, s->blob_bytes / 1e6, (unsigned long long)s->reissued,
            (unsigned long long)s->duplicates, (unsigned long long)s->malformed, s->workers_seen,
            s->workers_seen == 1 ? "" : "s", s->workers_lost, (unsigned long long)s->refused);
    for (int i = 0; i < s->nper_worker; i++)
        pf_info("summary: worker %s rendered %llu tiles", s->per_worker[i].name,
                (unsigned long long)s->per_worker[i].tiles);
}
