/* farm.c: the coordinator's side of the render farm; see farm.h.
 *
 * Threads: the caller's thread runs the event loop and owns the ROUTER
 * socket; a helper thread runs the photon pass (so workers that connect in
 * the meantime are welcomed and heartbeated) and frames the blobs; the ZAP
 * thread (zap.c) authenticates CURVE clients; libzmq's I/O thread calls
 * transfer.c back when it is done with a blob chunk.
 *
 * What lives where: the worker table, its ids, strikes and blocklist in
 * registry.c; tiles, the queue and leases in leases.c; the framed blobs and
 * the per-worker transfer windows in transfer.c; the conversation with the
 * workers (what a message is worth, leasing, strikes, eviction) in
 * farm_peers.c; spot checks of results on a second worker in verify.c.
 * This file is the photon thread, the event loop, the
 * housekeeping (when a worker is dead, stuck, or its lease expired) and the
 * job's steps.
 *
 * Tiles are leased as (job, tile, attempt) to a worker id that is never
 * reused. The first valid RESULT for a tile wins; later ones are counted as
 * duplicates and dropped. A lease returns its tile to the front of the queue
 * (attempt + 1) when its worker falls silent for dead_after heartbeats or is
 * disconnected, when it holds tiles and returns no RESULT for watchdog_s
 * (stuck in compute, or hoarding: the worker's own progress counter is not
 * trusted), after lease_timeout_s, or, once the queue is empty, when an idle
 * worker that never held the tile can take it over. Each worker holds at
 * most its tile credit (farm.h: credit_per_thread), so none idles waiting
 * and none takes the whole queue.
 *
 * Every frame from the network goes through pf_msg_decode; a bad one is
 * logged (rate-limited) and dropped, and when it comes from a registered
 * worker it is a strike, as is a message out of turn, an expired lease or a
 * stall; past max_strikes the worker is evicted: BYE, its tiles re-queued,
 * its slot freed, its routing identity, name and CURVE key blocked until the
 * job ends. A worker caught returning wrong pixels (verify.c) is evicted the
 * same way and every tile it delivered is rendered again.
 *
 * Without --bind the socket is ipc:// in a private 0700 directory (only the
 * local workers connect), removed at the end. */
#include "coordinator/farm.h"

#include <errno.h>
#include <omp.h>
#include <pthread.h>
#include <signal.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/random.h>
#include <sys/wait.h>
#include <time.h>
#include <unistd.h>
#include <zmq.h>

#include "base/hash.h"
#include "base/keyfile.h"
#include "base/log.h"
#include "coordinator/farm_impl.h"
#include "coordinator/spawn.h"
#include "photon/mapfile.h"
#include "proto/messages.h"
#include "proto/sceneblob.h"
#include "render/render.h"

#define S_STALL_TIMES 8.0 /* the stall deadline is at least this many typical tile times */

/* Serializes the scene and the maps, names them by content hash, and cuts
 * them into chunk frames (in place: the blobs are not held twice). */
static int s_photon_blobs(pf_fm_photons_t *p)
{
    pf_buf_t sb = { 0 }, mb = { 0 };
    int rc = pf_sceneblob_write(p->scene, &sb);
    if (rc == PF_OK) {
        p->scene_hash = pf_hash_bytes(PF_HASH_INIT, sb.data, sb.len);
        rc = pf_mapfile_write(p->into_next ? &p->next : &p->frame.maps, p->scene_hash,
                              pf_settings_hash(&p->settings), &mb);
        p->maps_hash = pf_hash_bytes(PF_HASH_INIT, mb.data, mb.len);
        if (rc)
            pf_error_set(&p->err, rc, NULL, 0, "cannot serialize the photon maps: %s", pf_strerror(rc));
    }
    p->scene_size = sb.len;
    p->maps_size = mb.len;
    if (rc == PF_OK)
        rc = pf_framed_blob_make(&p->scene_fb, p->job, p->scene_hash, &sb);
    if (rc == PF_OK)
        rc = pf_framed_blob_make(&p->maps_fb, p->job, p->maps_hash, &mb);
    pf_buf_free(&sb);
    pf_buf_free(&mb);
    if (rc != PF_OK && p->err.msg[0] == 0)
        pf_error_set(&p->err, rc, NULL, 0, "cannot prepare the scene and map blobs: %s", pf_strerror(rc));
    return rc;
}

/* A later pass's photon pass, its settings planned (pf_fm_pass_plan), into
 * p->next: the frame's maps are the pass being gathered. */
static void s_photon_pass_next(pf_fm_photons_t *p)
{
    pf_budget_t *b = p->budget;
    if (b && !(b->photon_s_per_photon > 0.0)) {
        /* A resumed render: the calibration the first pass would have made. */
        pf_settings_t cal = p->base;
        p->rc = pf_budget_plan_photons(b, &p->frame, &cal);
        if (p->rc == PF_OK && !p->given && pf_budget_plan_pass_photons(b, p->pass, &p->settings)) {
            p->no_pass = 1;
            return;
        }
    }
    p->into_next = 1;
    double t0 = pf_now();
    pf_photon_maps_free(&p->next);
    if (p->spread)
        p->rc = pf_fm_photons_spread(p, &p->next); /* the workers take batches between their tiles */
    else
        p->rc = pf_photon_pass(p->scene, p->frame.accel, p->frame.lights, &p->settings, &p->next, &p->stats);
    if (p->rc) {
        pf_error_set(&p->err, p->rc, NULL, 0, "photon pass failed: %s", pf_strerror(p->rc));
        return;
    }
    pf_photon_skip_gather(&p->stats, &p->settings);
    p->photon_s = pf_now() - t0;
}

/* The first pass's photon pass (the frame is opened for it): under a time
 * limit its photons are planned first and its spp after. */
static void s_photon_pass(pf_fm_photons_t *p)
{
    pf_frame_t *fr = &p->frame;
    pf_budget_t *b = p->budget;
    p->settings = p->base;
    p->settings.pass = p->pass;
    p->settings.seed = pf_pass_seed(p->base.seed, p->pass);
    if (b && p->pass == 0)
        p->rc = pf_budget_plan_photons(b, fr, &p->settings); /* the calibration: the photon rate */
    if (p->rc == PF_OK && b && p->progressive && pf_budget_plan_pass_photons(b, p->pass, &p->settings)) {
        p->no_pass = 1;
        return;
    }
    double t0 = pf_now();
    pf_frame_drop_maps(fr);
    if (p->rc == PF_OK && p->spread)
        p->rc = pf_fm_photons_spread(p, &fr->maps);
    else if (p->rc == PF_OK)
        p->rc = pf_photon_pass(p->scene, fr->accel, fr->lights, &p->settings, &fr->maps, &p->stats);
    if (p->rc) {
        pf_error_set(&p->err, p->rc, NULL, 0, "photon pass failed: %s", pf_strerror(p->rc));
        return;
    }
    if (b && p->progressive)
        pf_budget_photons_done(b, pf_now() - t0, p->settings.photons + fr->maps.caustic_emitted);
    pf_photon_skip_gather(&p->stats, &p->settings);
    if (b) {
        /* The probe renders here with the coordinator's cores, as the workers will. */
        pf_frame_ready(fr);
        if (p->progressive)
            pf_budget_plan_pass_spp(b, fr, p->terms, p->settings.threads, p->pass, t0, &p->settings);
        else
            pf_budget_plan_spp(b, fr, p->terms, p->settings.threads, &p->settings);
        if (p->pass == 0)
            pf_budget_log(b, &p->settings);
    }
}

static void *s_photon_thread(void *arg)
{
    pf_fm_photons_t *p = arg;
    p->rc = p->frame.accel ? PF_OK : pf_frame_open(&p->frame, p->scene, &p->err);
    if (p->rc == PF_OK)
        (p->pass || p->given ? s_photon_pass_next : s_photon_pass)(p);
    if (p->rc == PF_OK && !p->no_pass)
        p->rc = s_photon_blobs(p);
    __atomic_store_n(&p->done, 1, __ATOMIC_RELEASE);
    return NULL;
}

/* A log line that may come once per message of a flood: at most `rate`
 * lines a second (a burst of twice that); the lines held back are counted
 * and said with the next one that passes. */
/* --- housekeeping -------------------------------------------------------- */

/* How long a worker may hold tiles without a RESULT: watchdog_s, or
 * S_STALL_TIMES typical tile times when the job's tiles are that slow. */
static double s_stall_s(const pf_fm_t *f)
{
    double typical = S_STALL_TIMES * pf_leases_typical_s(&f->L);
    return typical > f->o->watchdog_s ? typical : f->o->watchdog_s;
}

static void s_tick_worker(pf_fm_t *f, int i, double now, double stall)
{
    pf_worker_t *w = &f->reg.w[i];
    double hb = f->o->heartbeat_ms / 1000.0;
    if (now - w->last_seen > f->o->dead_after * hb) {
        pf_fm_declare_dead(f, i, "is silent: declared dead");
        return;
    }
    if (w->held && !w->stuck && now - w->result_at > stall) {
        char why[160];
        snprintf(why, sizeof why, "held %u tile%s and returned no RESULT for %.0f s", w->held, w->held == 1 ? "" : "s",
                 now - w->result_at);
        w->stuck = 1;
        f->sum->stalls++;
        pf_fm_release_worker(f, i, "makes no progress (stuck in compute, or hoarding?)");
        pf_fm_strike(f, i, why);
        if (w->state == PF_W_FREE)
            return; /* evicted */
    }
    if (f->job_ready && w->state == PF_W_HELLO)
        pf_fm_send_job(f, i); /* its queue was full when the job went out */
    if (w->state != PF_W_DEAD && pf_xfer_waiting(f->xfer, i))
        pf_fm_pump(f, i);
    if (w->state != PF_W_DEAD && now - w->last_sent >= hb) {
        pf_msg_t m = { .type = PF_MSG_HEARTBEAT };
        pf_fm_send(f, i, &m);
    }
}

static void s_tick(pf_fm_t *f)
{
    double now = pf_now(), stall = s_stall_s(f);
    for (int i = 0; i < f->reg.nw; i++) {
        int st = f->reg.w[i].state;
        if (st == PF_W_HELLO || st == PF_W_JOB_SENT || st == PF_W_READY)
            s_tick_worker(f, i, now, stall);
    }
    for (int i = 0; i < f->L.nt; i++) {
        const pf_tile_t *t = &f->L.t[i];
        if (t->state != PF_T_LEASED || now - t->leased_at <= f->o->lease_timeout_s)
            continue;
        int owner = t->owner >= 0 && f->reg.w[t->owner].uid == t->owner_uid ? t->owner : -1;
        pf_warn("lease of tile %d (worker %s) expired after %.0f s", i, owner >= 0 ? f->reg.w[owner].name : "?",
                now - t->leased_at);
        f->sum->expired++;
        pf_leases_revoke(&f->L, &f->reg, i);
        if (owner >= 0)
            pf_fm_strike(f, owner, "a lease expired");
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
    o->max_workers = 1024;
    o->hello_rate = 100.0;
    o->max_strikes = 8;
    o->blob_window = 8;
    o->fanout = 2;
    o->send_hwm = 256;
    o->credit_per_thread = 2;
    o->takeover_factor = 4.0;
    o->takeover_min_s = 2.0;
    o->verify = 0.02;
    o->photon_check = 16;
}

/* The spot checks' per-run secret: from the kernel, else (no getrandom)
 * from the clock, the pid and an address, which a worker cannot see. */
static uint64_t s_check_secret(void)
{
    uint64_t v = 0;
    if (getrandom(&v, sizeof v, 0) == (ssize_t)sizeof v && v)
        return v;
    struct timespec ts;
    clock_gettime(CLOCK_REALTIME, &ts);
    v = pf_hash_u64(pf_hash_u64(PF_HASH_INIT, (uint64_t)ts.tv_nsec ^ ((uint64_t)ts.tv_sec << 30)), (uint64_t)getpid());
    return pf_hash_u64(v, (uint64_t)(uintptr_t)&v);
}

static int s_loopback(const char *ep)
{
    return strncmp(ep, "ipc://", 6) == 0 || strncmp(ep, "inproc://", 9) == 0 || strstr(ep, "://127.") ||
           strstr(ep, "://localhost") || strstr(ep, "://[::1]");
}

/* The tile table (all tiles queued in order), the worker registry and the
 * blob server. */
static int s_alloc_tables(pf_fm_t *f, const pf_settings_t *s, pf_error_t *err)
{
    const pf_farm_opts_t *o = f->o;
    f->ts = o->tile_size > 0 ? o->tile_size : 32;
    int maxw = o->max_workers > 0 ? o->max_workers : 1024;
    if (pf_leases_init(&f->L, s->width, s->height, f->ts) != PF_OK ||
        pf_registry_init(&f->reg, maxw, o->hello_rate) != PF_OK)
        return pf_error_set(err, PF_ENOMEM, NULL, 0, "out of memory");
    f->xfer = pf_xfer_new(maxw, o->blob_window);
    f->fan = pf_fanout_new(maxw, o->fanout);
    f->fan_scene = pf_fanout_new(maxw, o->fanout);
    f->pix = malloc((size_t)f->ts * (size_t)f->ts * 3 * sizeof *f->pix);
    if (!f->xfer || !f->fan || !f->fan_scene || !f->pix || pf_fm_verify_init(f) != PF_OK)
        return pf_error_set(err, PF_ENOMEM, NULL, 0, "out of memory");
    return PF_OK;
}
/* CURVE on the socket: the coordinator's key, and a ZAP handler that admits
 * only the allowed worker keys. */
static int s_setup_curve(pf_fm_t *f, pf_error_t *err)
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

/* Without --bind, only local workers connect: an ipc:// socket in a
 * private directory (mkdtemp: mode 0700) under $XDG_RUNTIME_DIR or /tmp,
 * which no other user can reach, removed at the end (s_free). Falls back to
 * tcp://127.0.0.1:* when no such directory can be made. */
static const char *s_private_ipc(pf_fm_t *f, char *ep, size_t cap)
{
    const char *bases[2] = { getenv("XDG_RUNTIME_DIR"), "/tmp" };
    for (int i = 0; i < 2; i++) {
        if (!bases[i] || bases[i][0] != '/')
            continue;
        /* The socket's path must fit in sun_path (108 bytes). */
        int n = snprintf(f->ipcdir, sizeof f->ipcdir, "%s/photonfarm-XXXXXX", bases[i]);
        if (n <= 0 || n + (int)sizeof "/farm" > 100 || !mkdtemp(f->ipcdir)) {
            f->ipcdir[0] = 0;
            continue;
        }
        snprintf(ep, cap, "ipc://%s/farm", f->ipcdir);
        return ep;
    }
    pf_warn("cannot make a private directory for the local workers' socket (%s): using loopback TCP",
            strerror(errno));
    return "tcp://127.0.0.1:*";
}

/* The ipc:// socket's file and private directory, when there is one. */
static void s_remove_ipc(pf_fm_t *f)
{
    if (!f->ipcdir[0])
        return;
    char path[192];
    snprintf(path, sizeof path, "%s/farm", f->ipcdir);
    if ((unlink(path) != 0 && errno != ENOENT) || rmdir(f->ipcdir) != 0)
        pf_warn("cannot remove %s: %s", f->ipcdir, strerror(errno));
    f->ipcdir[0] = 0;
}

/* The ROUTER socket, with CURVE and its ZAP handler when asked, bound; its
 * endpoint lands in f->endpoint. The queues are small (send_hwm messages a
 * peer; blob chunks are windowed apart, see transfer.h) and no frame from a
 * worker may be larger than a RESULT of one tile (libzmq drops the
 * connection of a peer that sends one). */
static int s_open_socket(pf_fm_t *f, pf_error_t *err)
{
    const pf_farm_opts_t *opts = f->o;
    f->ctx = zmq_ctx_new();
    f->sock = f->ctx ? zmq_socket(f->ctx, ZMQ_ROUTER) : NULL;
    if (!f->sock)
        return pf_error_set(err, PF_EIO, NULL, 0, "cannot create a ZeroMQ socket: %s", zmq_strerror(zmq_errno()));
    int one = 1, linger = 1000, hwm = opts->send_hwm > 0 ? opts->send_hwm : 256;
    int64_t maxmsg = (int64_t)12 * f->ts * f->ts + 4096; /* RESULT: 3 floats a pixel, and room for the rest */
    if (!opts->photons_here)
        maxmsg = PF_PROTO_MAX_MESSAGE; /* PHOTONS: up to a chunk's worth of photons */
    if (maxmsg > (int64_t)PF_PROTO_MAX_MESSAGE)
        maxmsg = PF_PROTO_MAX_MESSAGE;
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
    char ipc[256];
    const char *bind = opts->bind ? opts->bind : s_private_ipc(f, ipc, sizeof ipc);
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
static int s_start_local_workers(pf_fm_t *f, pf_error_t *err)
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
    int nloc = opts->local_workers < PF_FM_MAX_LOCAL ? opts->local_workers : PF_FM_MAX_LOCAL;
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

/* The photon pass runs beside the event loop: the first pass's with
 * scene, settings and terms given (pass 0); a later pass's with scene NULL,
 * pass and its settings s planned (pf_fm_pass_plan), while the workers
 * gather the pass before. */
static int s_start_photons(pf_fm_t *f, const pf_scene_t *scene, int pass, const pf_settings_t *s, unsigned terms,
                           pf_error_t *err)
{
    f->ph.given = 0;
    f->ph.into_next = 0;
    if (scene) {
        f->ph.scene = scene;
        f->ph.base = *s;
        f->ph.budget = f->o->budget;
        f->ph.terms = terms;
        f->ph.progressive = pf_fm_progressive(f);
        f->ph.spread = !f->o->photons_here;
        if (f->resumed_pass >= 0 && (f->resumed.ntiles > 0 || f->resumed_pass > 0)) {
            /* Resuming: the pass under way, with its settings as they were
             * planned when it has tiles done, else planned afresh. */
            pass = f->resumed_pass;
            f->ph.given = f->resumed.ntiles > 0;
            if (f->ph.given)
                f->ph.settings = f->resumed.pass;
            else if (pf_fm_pass_plan(f, pass, &f->ph.settings) && f->o->budget && f->o->budget->photon_s_per_photon > 0)
                return pf_error_set(err, PF_ETIMEOUT, NULL, 0, "no pass fits in the time limit");
        }
    } else {
        f->ph.settings = *s;
    }
    f->ph.pass = pass;
    /* A JOB went out before: its scene blob (the same every pass) is the
     * one the workers trace over, and the blob server has it. */
    f->ph.early_from_job = f->jobmsg.scene_size != 0;
    if (f->ph.early_from_job) {
        f->ph.early_hash = f->jobmsg.scene_hash;
        f->ph.early_size = f->jobmsg.scene_size;
    }
    f->ph.job = f->job0 + (uint64_t)pass;
    if (f->ph.job == 0)
        f->ph.job = 1;
    f->ph.rc = PF_OK;
    f->ph.no_pass = 0;
    memset(&f->ph.stats, 0, sizeof f->ph.stats);
    f->ph.done = 0;
    if (pthread_create(&f->phtid, NULL, s_photon_thread, &f->ph) != 0)
        return pf_error_set(err, PF_ENOMEM, NULL, 0, "cannot start the photon pass thread");
    f->ph_started = 1;
    return PF_OK;
}

/* The photon pass has finished: join it, and on success make the job
 * ready and send it to the workers waiting for it. */
static int s_on_photons_done(pf_fm_t *f, pf_error_t *err)
{
    pf_farm_summary_t *sum = f->sum;
    pthread_join(f->phtid, NULL);
    f->ph_started = 0;
    pf_fm_photons_end(f);
    if (f->ph.rc != PF_OK) {
        *err = f->ph.err;
        return f->ph.rc;
    }
    pf_progress_end(&f->bar);
    if (f->ph.no_pass)
        return PF_OK; /* the caller ends the render */
    if (f->ph.into_next) {
        /* The pass traced beside the last one begins: its maps become the
         * frame's (the verification renders read them), its spp is planned
         * for the time it now has (not a resumed pass's: its tiles done
         * have theirs). */
        pf_frame_drop_maps(&f->ph.frame);
        f->ph.frame.maps = f->ph.next;
        memset(&f->ph.next, 0, sizeof f->ph.next);
        f->frame_readied = 0;
        if (f->o->budget && !f->ph.given) {
            if (!(f->o->budget->pass_spp_s > 0.0)) { /* resumed: the probe needs the frame ready */
                pf_frame_ready(&f->ph.frame);
                f->frame_readied = 1;
            }
            pf_budget_photons_done(f->o->budget, f->ph.photon_s,
                                   f->ph.settings.photons + f->ph.frame.maps.caustic_emitted);
            pf_budget_plan_pass_spp(f->o->budget, &f->ph.frame, f->ph.terms, f->ph.settings.threads, f->ph.pass,
                                    pf_now(), &f->ph.settings);
        }
    }
    f->cur = f->ph.settings;
    f->cur_pass = f->ph.pass;
    pf_fm_pass_counts(f);
    f->job = f->ph.job;
    if (f->ph.pass == f->resumed_pass) {
        int rc = pf_fm_resume_tiles(f, err);
        if (rc != PF_OK)
            return rc;
    }
    sum->photons = f->ph.stats;
    sum->photons_total += f->ph.settings.photons + f->ph.frame.maps.caustic_emitted;
    if (f->ph.pass == 0)
        sum->photon_s = pf_now() - f->t0;
    sum->photon_total_s += f->ph.stats.trace_s + f->ph.stats.build_s + f->ph.stats.irradiance_s;
    sum->settings = f->ph.settings;
    pf_log(f->ph.pass ? PF_LOG_DEBUG : PF_LOG_INFO, "photon pass: %llu global + %llu caustic photons, %llu irradiance points; scene blob %llu bytes, "
            "map blob %llu bytes (%.1f bytes per photon)",
            (unsigned long long)f->ph.stats.global_stored, (unsigned long long)f->ph.stats.caustic_stored,
            (unsigned long long)f->ph.stats.irradiance_points, (unsigned long long)f->ph.scene_size,
            (unsigned long long)f->ph.maps_size, (double)f->ph.maps_size /
                (double)(f->ph.stats.global_stored + f->ph.stats.caustic_stored + f->ph.stats.irradiance_points + 1));
    pf_settings_t s = f->ph.settings; /* as a time limit planned them */
    f->jobmsg = (pf_msg_job_t){ f->ph.scene_hash, f->ph.scene_size, f->ph.maps_hash, f->ph.maps_size,
                                s, f->ph.terms, (uint32_t)f->ts };
    if (pf_fanout_set_blob(f->fan_scene, &f->ph.scene_fb) != PF_OK)
        pf_warn("out of memory for the scene blob's chunk hashes: every worker fetches the scene from here");
    f->fan_scene_on = 0; /* the early scene's tree is done: the JOB's plans carry the scene (pf_fm_fanout_job) */
    if (pf_fanout_set_blob(f->fan, &f->ph.maps_fb) != PF_OK)
        pf_warn("out of memory for the maps' chunk hashes: every worker fetches the maps from here");
    pf_xfer_set_blobs(f->xfer, &f->ph.scene_fb, &f->ph.maps_fb);
    f->job_ready = 1;
    f->pass_start = pf_now();
    if (f->render_start == 0.0) /* this process's first pass: pass 0, or the first after a --resume */
        f->render_start = f->pass_start;
    pf_progress_begin(&f->bar, "render", f->o->show_progress);
    for (int i = 0; i < f->reg.nw; i++)
        if (f->reg.w[i].state == PF_W_HELLO)
            pf_fm_send_job(f, i);
    /* The next pass's photons, traced while the workers gather this one. */
    pf_settings_t next;
    if (f->ph.progressive && pf_fm_pass_more(f, NULL) && !pf_fm_pass_plan(f, f->cur_pass + 1, &next))
        return s_start_photons(f, NULL, f->cur_pass + 1, &next, 0, err);
    return PF_OK;
}

/* Takes up to 256 queued messages off the socket without blocking, so the
 * housekeeping after each poll is never starved. */
static void s_recv_burst(pf_fm_t *f)
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
            pf_fm_bad(f, "a peer", "empty message");
        } else {
            if (zmq_msg_more(&body)) { /* our protocol is one frame; drain and drop the rest */
                pf_fm_bad(f, "a peer", "multi-frame message");
                while (zmq_msg_more(&body)) {
                    zmq_msg_close(&body);
                    zmq_msg_init(&body);
                    zmq_msg_recv(&body, f->sock, 0);
                }
            } else if (zmq_msg_size(&id) <= sizeof f->reg.w[0].id) {
                /* With CURVE, the ZAP handler made the client's public key its User-Id. */
                const char *key = zmq_msg_gets(&body, "User-Id");
                f->frame_addr = zmq_msg_gets(&body, "Peer-Address");
                pf_fm_on_frame(f, zmq_msg_data(&id), zmq_msg_size(&id), key, zmq_msg_data(&body), zmq_msg_size(&body));
            }
        }
        zmq_msg_close(&body);
        zmq_msg_close(&id);
    }
}

/* Workers that have registered and not left or died. */
static int s_count_alive(const pf_fm_t *f)
{
    int alive = 0;
    for (int i = 0; i < f->reg.nw; i++) {
        int st = f->reg.w[i].state;
        alive += st == PF_W_READY || st == PF_W_JOB_SENT || st == PF_W_HELLO;
    }
    return alive;
}

/* A local worker that exits on its own is reported, not waited for. */
static void s_reap_local_workers(pf_fm_t *f)
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
static void s_note_progress(pf_fm_t *f, int alive)
{
    char note[256];
    int nn = snprintf(note, sizeof note, "workers %d", alive);
    uint64_t blobs = f->jobmsg.scene_size + f->jobmsg.maps_size;
    for (int i = 0; i < f->reg.nw && nn < (int)sizeof note - 40; i++) {
        const pf_worker_t *w = &f->reg.w[i];
        if (w->state == PF_W_JOB_SENT && w->blob_sent > 0 && w->blob_sent < blobs)
            nn += snprintf(note + nn, sizeof note - (size_t)nn, "  maps->%.12s %d%%", w->name,
                           (int)(100.0 * (double)w->blob_sent / (double)blobs));
    }
    pf_progress_update_note(&f->bar, f->L.ndone, f->L.nt, note);
    if (!f->bar.enabled && pf_now() - f->last_log > 5.0) {
        f->last_log = pf_now();
        pf_info("render: %d/%d tiles, %d worker%s alive", f->L.ndone, f->L.nt, alive, alive == 1 ? "" : "s");
    }
}

/* The passes, at the top of each turn of the event loop: 1 when the render
 * is over (every tile in; for progressive passes, the last pass in, or a
 * stop, or the deadline: the pass under way is cut), 0 to go on (the next
 * pass's photon pass started when one was whole), or a status. */
static int s_pass_turn(pf_fm_t *f, volatile int *stop, pf_error_t *err)
{
    int stopped = stop && *stop;
    if (stopped && f->job_ready)
        pf_fm_checkpoint(f, 1); /* the tiles done, before a cut adds them to the sums */
    if (!pf_fm_progressive(f)) {
        if (stopped)
            return pf_error_set(err, PF_EINTERRUPTED, NULL, 0, "interrupted");
        return f->L.ndone == f->L.nt;
    }
    if (f->job_ready && f->L.ndone == f->L.nt) {
        pf_fm_pass_whole(f);
        pf_fm_checkpoint(f, 1);
        if (!pf_fm_pass_more(f, stop)) {
            f->sum->interrupted = stopped;
            return 1;
        }
        pf_progress_end(&f->bar);
        int rc = pf_fm_pass_reset(f, err);
        if (rc == PF_OK && !f->ph_started) {
            /* Its photons were not traced beside this pass (the time left
             * said no; a wrong guess, as the pass ended early): now. */
            pf_settings_t next;
            if (pf_fm_pass_plan(f, f->cur_pass + 1, &next))
                return 1;
            rc = s_start_photons(f, NULL, f->cur_pass + 1, &next, 0, err);
        }
        pf_progress_begin(&f->bar, "photons", f->o->show_progress);
        return rc;
    }
    const pf_budget_t *b = f->o->budget;
    int late = b && f->cur_pass > 0 && pf_now() > pf_budget_tiles_deadline(b);
    if (!stopped && !late)
        return 0;
    if (f->job_ready)
        pf_fm_pass_cut(f);
    f->sum->interrupted = stopped;
    if (f->sum->passes_whole == 0 && f->sum->cut_tiles == 0)
        return pf_error_set(err, PF_EINTERRUPTED, NULL, 0, "interrupted before any tile was done");
    return 1;
}

/* The event loop: runs until every tile is done (every pass's), *stop is
 * set, the photon pass fails, polling fails, or no worker has been alive
 * for max_wait_s. */
static int s_event_loop(pf_fm_t *f, volatile int *stop, pf_error_t *err)
{
    const pf_farm_opts_t *opts = f->o;
    int rc = PF_OK;
    pf_progress_begin(&f->bar, "photons", opts->show_progress);
    f->render_start = 0.0;
    f->last_log = pf_now();
    f->no_worker_since = pf_now();
    for (;;) {
        int over = s_pass_turn(f, stop, err);
        if (over != 0) {
            rc = over < 0 ? over : PF_OK;
            break;
        }
        if (!f->job_ready && __atomic_load_n(&f->ph.done, __ATOMIC_ACQUIRE)) {
            rc = s_on_photons_done(f, err);
            if (rc != PF_OK || f->ph.no_pass)
                break;
        }
        /* Chunks waiting for a transfer window to open: look again soon. */
        int waiting = 0;
        for (int i = 0; i < f->reg.nw && !waiting; i++)
            waiting = f->reg.w[i].state == PF_W_JOB_SENT && pf_xfer_waiting(f->xfer, i) > 0;
        zmq_pollitem_t it = { f->sock, 0, ZMQ_POLLIN, 0 };
        int pr = zmq_poll(&it, 1, waiting ? 10 : 50);
        if (pr < 0 && zmq_errno() != EINTR) {
            rc = pf_error_set(err, PF_EIO, NULL, 0, "poll failed: %s", zmq_strerror(zmq_errno()));
            break;
        }
        if (pr > 0)
            s_recv_burst(f);
        s_tick(f);
        pf_fm_photons_tick(f);
        pf_fm_verify_tick(f);
        pf_fm_evict_pending(f);
        if (f->job_ready) {
            pf_fm_lease_all(f);
            pf_fm_checkpoint(f, 0);
        }
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
    if (rc == PF_OK && pf_fm_progressive(f))
        pf_fm_pass_resolve(f);
    return rc;
}

/* Job over: tell everyone, then let local workers go. Workers declared
 * dead are told too: one that was only stopped (SIGSTOP) may be back. */
static void s_end_job(pf_fm_t *f, int rc)
{
    for (int i = 0; i < f->reg.nw; i++)
        if (f->reg.w[i].state != PF_W_FREE) {
            pf_msg_t m = { .type = PF_MSG_JOB_END };
            pf_fm_send(f, i, &m);
            pf_msg_t b = { .type = PF_MSG_BYE };
            snprintf(b.u.bye.reason, sizeof b.u.bye.reason, "%s",
                     rc == PF_OK ? "job complete" : "coordinator stopping");
            pf_fm_send(f, i, &b);
        }
}

/* Tiles per worker into the summary: one line per name, also for a worker
 * that registered twice; at most 64 names. And the counts the registry
 * and the leases kept. */
static void s_sum_up(pf_fm_t *f)
{
    pf_farm_summary_t *sum = f->sum;
    sum->reissued = f->L.reissued;
    sum->duplicates = f->L.duplicates;
    sum->hellos_dropped = f->reg.hellos_dropped;
    sum->slots_reused = f->reg.reused;
    if (f->xfer) {
        pf_xfer_blob_bytes(f->xfer, 0, &sum->scene_blob_size, &sum->scene_blob_sent);
        pf_xfer_blob_bytes(f->xfer, 1, &sum->maps_blob_size, &sum->maps_blob_sent);
        sum->maps_blob_size -= sum->irr_blob_size; /* the irradiance's map blob shared the slot */
        sum->maps_blob_sent -= sum->irr_blob_sent;
    }
    for (int i = 0; i < f->reg.nw; i++) {
        const pf_worker_t *w = &f->reg.w[i];
        if (!w->tiles && !w->ph_batches)
            continue;
        int k = 0;
        while (k < sum->nper_worker && strcmp(sum->per_worker[k].name, w->name) != 0)
            k++;
        if (k == sum->nper_worker) {
            if (k == 64)
                continue;
            snprintf(sum->per_worker[k].name, sizeof sum->per_worker[k].name, "%s", w->name);
            sum->per_worker[k].tiles = 0;
            sum->per_worker[k].photon_batches = 0;
            sum->nper_worker++;
        }
        sum->per_worker[k].tiles += w->tiles;
        sum->per_worker[k].photon_batches += w->ph_batches;
    }
}

/* Stops and frees whatever the steps started, on every path. The blob
 * server goes after the context: until zmq_ctx_term returns, libzmq may
 * still hold chunk frames that point into its blobs. */
static void s_free(pf_fm_t *f)
{
    if (f->npids)
        pf_spawn_stop_all(f->pids, f->npids, 3.0);
    if (f->ph_started) {
        /* A signal stops the photon pass within a block of photons
         * (pf_photon_set_cancel); otherwise it ends on its own. */
        if (!__atomic_load_n(&f->ph.done, __ATOMIC_ACQUIRE))
            pf_debug("stopping: waiting for the photon pass to end (%.0f s in so far)", pf_now() - f->t0);
        pthread_join(f->phtid, NULL);
    }
    pf_phq_free(&f->ph.phq);
    pf_irq_free(&f->ph.irq);
    pf_framed_blob_free(&f->ph.irr_fb);
    pf_photon_tracer_free(&f->ph.tracer);
    pf_framed_blob_free(&f->ph.early_fb);
    if (f->sock)
        zmq_close(f->sock);
    if (f->zap)
        f->sum->refused += (uint64_t)pf_zap_stop(&f->zap);
    if (f->ctx)
        zmq_ctx_term(f->ctx);
    s_remove_ipc(f);
    pf_xfer_destroy(&f->xfer);
    pf_fanout_free(&f->fan);
    pf_fanout_free(&f->fan_scene);
    pf_frame_close(&f->ph.frame);
    pf_photon_maps_free(&f->ph.next);
    pf_framed_blob_free(&f->ph.scene_fb);
    pf_framed_blob_free(&f->ph.maps_fb);
    pf_buf_free(&f->out);
    free(f->pix);
    pf_fm_verify_free(f);
    pf_leases_free(&f->L);
    pf_registry_free(&f->reg);
    pf_accum_free(&f->acc);
    free(f->counts_buf);
    pf_ckpt_free(&f->resumed);
}

int pf_farm_render(const pf_scene_t *scene, const pf_settings_t *settings, unsigned terms, const pf_farm_opts_t *opts,
                   volatile int *stop, pf_image_t *img, pf_farm_summary_t *sum, pf_error_t *err)
{
    memset(sum, 0, sizeof *sum);
    double t0 = pf_now();
    pf_fm_t f;
    memset(&f, 0, sizeof f);
    f.o = opts;
    f.sum = sum;
    f.img = img;
    f.t0 = t0;
    f.job = ((uint64_t)getpid() << 32) ^ (uint64_t)(t0 * 1000.0);
    if (f.job == 0)
        f.job = 1;
    f.job0 = f.job;
    f.ph.check_secret = s_check_secret();
    f.ph.check_one_in = opts->photon_check;

    pf_settings_t s = *settings;
    if (s.threads <= 0)
        s.threads = omp_get_num_procs();
    int rc = pf_image_alloc(img, s.width, s.height);
    if (rc)
        return pf_error_set(err, rc, NULL, 0, "cannot allocate a %dx%d image", s.width, s.height);
    rc = s_alloc_tables(&f, &s, err);
    if (rc == PF_OK && pf_fm_progressive(&f) && pf_accum_init(&f.acc, s.width, s.height) != PF_OK)
        rc = pf_error_set(err, PF_ENOMEM, NULL, 0, "cannot allocate the passes' %dx%d sums", s.width, s.height);
    if (rc == PF_OK)
        rc = pf_fm_resume_load(&f, scene, &s, terms, err);
    if (rc == PF_OK)
        rc = s_open_socket(&f, err);
    if (rc == PF_OK)
        rc = s_start_local_workers(&f, err);
    if (rc == PF_OK)
        rc = s_start_photons(&f, scene, 0, &s, terms, err);
    if (rc == PF_OK) {
        rc = s_event_loop(&f, stop, err);
        s_end_job(&f, rc);
        s_sum_up(&f);
    }
    s_free(&f);
    if (rc == PF_OK && !sum->interrupted && opts->checkpoint && remove(opts->checkpoint) != 0 && errno != ENOENT)
        pf_warn("cannot remove the checkpoint %s: %s", opts->checkpoint, strerror(errno));
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
    pf_info("summary: hostile peers: %llu strikes, %llu evicted, %llu frames from evicted peers dropped, "
            "%llu HELLOs dropped over the rate limit, %llu HELLOs blocked, %llu blob requests ignored, "
            "%llu results refused, %llu leases expired, %llu stalls, %llu leases taken over, %llu slots reused",
            (unsigned long long)s->strikes, (unsigned long long)s->evicted, (unsigned long long)s->evicted_frames,
            (unsigned long long)s->hellos_dropped, (unsigned long long)s->blocked, (unsigned long long)s->blob_ignored,
            (unsigned long long)s->results_refused, (unsigned long long)s->expired, (unsigned long long)s->stalls,
            (unsigned long long)s->takeovers, (unsigned long long)s->slots_reused);
    if (s->maps_blob_size)
        pf_info("summary: blobs from the coordinator: maps %llu bytes sent for %llu bytes of maps (%.2f x), scene "
                "%llu for %llu (%.2f x); fan-out: %llu worker%s fetched the maps from a peer, %llu sent back here, %llu "
                "scene plans named a peer",
                (unsigned long long)s->maps_blob_sent, (unsigned long long)s->maps_blob_size,
                (double)s->maps_blob_sent / (double)s->maps_blob_size, (unsigned long long)s->scene_blob_sent,
                (unsigned long long)s->scene_blob_size,
                s->scene_blob_size ? (double)s->scene_blob_sent / (double)s->scene_blob_size : 0.0,
                (unsigned long long)s->fanout_peer, s->fanout_peer == 1 ? "" : "s",
                (unsigned long long)s->fanout_fallback, (unsigned long long)s->fanout_scene_peer);
    if (s->verified || s->mismatches)
        pf_info("verify: %llu tile%s checked (%llu rendered here), %llu mismatch%s, %s%s%s, %llu tiles re-rendered",
                (unsigned long long)s->verified, s->verified == 1 ? "" : "s", (unsigned long long)s->verify_local,
                (unsigned long long)s->mismatches, s->mismatches == 1 ? "" : "es",
                s->liars ? (s->liars == 1 ? "worker " : "workers ") : "no worker evicted",
                s->liars ? s->liar_names : "", s->liars ? " evicted" : "", (unsigned long long)s->rerendered);
    if (s->ph_batches)
        pf_info("summary: photon pass spread: %llu batches, %llu traced on the coordinator (%llu of them also leased), "
                "%llu on the workers, %llu late or duplicate PHOTONS dropped, %llu leases expired; %.2f Mphotons/s",
                (unsigned long long)s->ph_batches, (unsigned long long)s->ph_local, (unsigned long long)s->ph_stolen,
                (unsigned long long)s->ph_remote, (unsigned long long)s->ph_stale, (unsigned long long)s->ph_expired,
                s->ph_trace_s > 0 ? (double)s->ph_emitted / s->ph_trace_s / 1e6 : 0.0);
    if (s->irr_blob_size)
        pf_info("summary: the irradiance's map blob (the global map): %llu bytes sent for %llu bytes (%.2f x)",
                (unsigned long long)s->irr_blob_sent, (unsigned long long)s->irr_blob_size,
                (double)s->irr_blob_sent / (double)s->irr_blob_size);
    if (s->irr_points)
        pf_info("summary: irradiance spread: %llu points, %llu of them computed on the coordinator alone; %llu chunks, "
                "%llu computed on the coordinator, %llu on the workers, %llu checked here, %llu mismatches; %.2f s",
                (unsigned long long)s->irr_points, (unsigned long long)s->irr_here, (unsigned long long)s->irr_chunks,
                (unsigned long long)s->irr_local, (unsigned long long)s->irr_remote,
                (unsigned long long)s->irr_checked, (unsigned long long)s->irr_mismatches, s->irr_s);
    if (s->ph_checked || s->ph_mismatches)
        pf_info("summary: photon spot checks: %llu worker batch%s traced again here, %llu mismatch%s (each a strike), "
                "%llu worker batches discarded and traced again",
                (unsigned long long)s->ph_checked, s->ph_checked == 1 ? "" : "es", (unsigned long long)s->ph_mismatches,
                s->ph_mismatches == 1 ? "" : "es", (unsigned long long)s->ph_discarded);
    for (int i = 0; i < s->nper_worker; i++)
        pf_info("summary: worker %s rendered %llu tiles, traced %llu photon batches", s->per_worker[i].name,
                (unsigned long long)s->per_worker[i].tiles, (unsigned long long)s->per_worker[i].photon_batches);
}

