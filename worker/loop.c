/* loop.c: the worker's side of the farm protocol (proto/messages.h); see
 * loop.h. This file is the protocol state machine and the socket: opening
 * and reopening it with backoff, HELLO / WELCOME / REFUSE, heartbeats,
 * message dispatch and the main loop. Jobs, blobs and results are jobs.c's;
 * the compute thread, its queue and the work items are compute.c's; logging
 * and sending are outbox.c's (worker_impl.h holds the state they share).
 * The files call downwards only: loop.c -> jobs.c -> compute.c -> outbox.c.
 *
 * Threads. The calling ("main") thread owns the ZeroMQ context, the DEALER
 * socket to the coordinator, its monitor socket and the outbox, and (through
 * jobs.c) the blobs, the built scenes and the current job; it only ever
 * waits in zmq_poll (100 ms at most, so a signal or a timer is noticed
 * promptly). One compute thread does everything slow (compute.c); a byte
 * written to a pipe that zmq_poll watches wakes the main thread to send the
 * RESULTs. Everything in this file runs on the main thread.
 *
 * Liveness. Any message from the coordinator counts as a heartbeat; silence
 * for 5 of its heartbeat intervals (or no WELCOME within 5 s of opening the
 * socket) means it is gone: the job is dropped, the socket closed, and a new
 * one opened after a backoff of 1 s doubling to 32 s (reset by a WELCOME).
 * A refusal (REFUSE, or the coordinator's ZAP handler rejecting this
 * worker's CURVE key with status 400) is treated the same way, with a
 * backoff that doubles up to 300 s: the coordinator may be upgraded, or the
 * key added to its list, and the worker then gets in without a restart.
 * Each distinct refusal is logged once. Only a --exit-on-bye worker (started
 * by a coordinator for one job) exits on a refusal. Strings from the peer
 * (reasons) are logged through pf_log_printable, so they cannot carry
 * terminal escapes or forge log lines.
 *
 * A gap in the worker's own loop (the process was stopped) is not counted
 * as the coordinator's silence. The worker's HEARTBEAT carries a pixel
 * counter that the compute threads advance, so the coordinator can tell a
 * busy worker from a stuck one (libzmq's I/O thread would keep answering
 * either way). */
#include "worker/loop.h"

#include <errno.h>
#include <inttypes.h>
#include <omp.h>
#include <stdarg.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <unistd.h>
#include <zmq.h>

#include "base/keyfile.h"
#include "worker/worker_impl.h"

#define S_POLL_MS 100             /* longest wait: signals and timers are noticed this quickly */
#define S_DEAD_AFTER 5            /* coordinator heartbeat intervals of silence before it is gone */
#define S_HELLO_TIMEOUT_S 5.0     /* opening the socket to WELCOME */
#define S_BACKOFF_MIN_S 1.0
#define S_BACKOFF_MAX_S 32.0
#define S_REFUSED_BACKOFF_MAX_S 300.0 /* after refusals: the coordinator's mind changes slowly */
#define S_LINGER_MS 1000          /* time to flush a BYE at exit */
#define S_MAX_RECV_PER_WAKE 256   /* messages handled before timers are looked at again */

static void s_send_hello(s_worker *w)
{
    pf_msg_t m;
    memset(&m, 0, sizeof m);
    m.type = PF_MSG_HELLO;
    m.u.hello.fp = pf_frame_fingerprint();
    if (w->opts->fake_protocol > 0)
        m.u.hello.fp.protocol = (uint16_t)w->opts->fake_protocol;
    m.u.hello.threads = (uint32_t)w->threads;
    m.u.hello.peer_port = w->peer_port;
    snprintf(m.u.hello.name, sizeof m.u.hello.name, "%s", w->name);
    if (pf_msg_encode(&m, &w->enc)) {
        pf_w_log(w, PF_LOG_ERROR, "cannot encode HELLO");
        return;
    }
    /* Queued until the connection is up; the loop sends it again when no
     * WELCOME comes within the HELLO timeout. */
    if (zmq_send(w->sock, w->enc.data, w->enc.len, ZMQ_DONTWAIT) >= 0) {
        w->hello_sent = 1;
        pf_w_log(w, PF_LOG_DEBUG, "HELLO sent to %s", w->opts->endpoint);
    }
}

static void s_send_heartbeat(s_worker *w)
{
    pf_msg_t m;
    memset(&m, 0, sizeof m);
    m.type = PF_MSG_HEARTBEAT;
    m.job = w->job ? w->job->id : 0;
    m.u.heartbeat.progress = atomic_load(&w->progress);
    m.u.heartbeat.tiles_held = w->tiles_held;
    pf_w_send(w, &m, 1);
}

/* ---- the connection ---- */

static void s_close_socket(s_worker *w, int linger_ms)
{
    if (w->monitor) {
        zmq_socket_monitor(w->sock, NULL, 0);
        zmq_close(w->monitor);
        w->monitor = NULL;
    }
    if (w->sock) {
        zmq_setsockopt(w->sock, ZMQ_LINGER, &linger_ms, sizeof linger_ms);
        zmq_close(w->sock);
        w->sock = NULL;
    }
    w->conn = S_OFFLINE;
    w->hello_sent = 0;
    pf_w_outbox_clear(w);
}

/* 1 when endpoint stays on this host: ipc://, inproc://, or tcp:// to a
 * loopback address (127.x.x.x, [::1], localhost). */
static int s_endpoint_local(const char *endpoint)
{
    if (strncmp(endpoint, "ipc://", 6) == 0 || strncmp(endpoint, "inproc://", 9) == 0)
        return 1;
    if (strncmp(endpoint, "tcp://", 6) != 0)
        return 0;
    const char *host = endpoint + 6;
    const char *semi = strchr(host, ';'); /* "source;destination": the destination counts */
    if (semi)
        host = semi + 1;
    return strncmp(host, "127.", 4) == 0 || strncmp(host, "[::1]:", 6) == 0 || strncmp(host, "localhost:", 10) == 0;
}

/* Opens the DEALER socket and starts the handshake. 0, or an exit code when
 * the endpoint or the keys cannot be used at all. */
static int s_open(s_worker *w)
{
    w->sock = zmq_socket(w->zctx, ZMQ_DEALER);
    if (!w->sock) {
        fprintf(stderr, "photonfarm-worker: cannot create a socket: %s\n", zmq_strerror(errno));
        return PF_WORKER_EXIT_FATAL;
    }
    int linger = S_LINGER_MS;
    int64_t maxmsg = PF_PROTO_MAX_MESSAGE;
    int rc = zmq_setsockopt(w->sock, ZMQ_LINGER, &linger, sizeof linger);
    rc |= zmq_setsockopt(w->sock, ZMQ_MAXMSGSIZE, &maxmsg, sizeof maxmsg);
    /* No ZMQ_IMMEDIATE: with it libzmq drops the unread messages of a
     * connection the peer closes, and the coordinator's last JOB_END/BYE were
     * lost half of the time (the farm test caught it). */
    if (w->curve) {
        /* Z85 keys are passed as 41 bytes, the terminating NUL included. */
        rc |= zmq_setsockopt(w->sock, ZMQ_CURVE_SERVERKEY, w->server_key, 41);
        rc |= zmq_setsockopt(w->sock, ZMQ_CURVE_PUBLICKEY, w->public_key, 41);
        rc |= zmq_setsockopt(w->sock, ZMQ_CURVE_SECRETKEY, w->secret_key, 41);
    }
    if (rc) {
        fprintf(stderr, "photonfarm-worker: cannot set socket options: %s\n", zmq_strerror(errno));
        s_close_socket(w, 0);
        return PF_WORKER_EXIT_FATAL;
    }
    /* The monitor reports handshake failures, above all a CURVE key the
     * coordinator's ZAP handler does not admit (no message would say so). */
    char addr[64];
    snprintf(addr, sizeof addr, "inproc://pf-worker-monitor-%u", ++w->monitor_seq);
    if (zmq_socket_monitor(w->sock, addr,
                           ZMQ_EVENT_CONNECTED | ZMQ_EVENT_DISCONNECTED | ZMQ_EVENT_HANDSHAKE_SUCCEEDED |
                               ZMQ_EVENT_HANDSHAKE_FAILED_AUTH | ZMQ_EVENT_HANDSHAKE_FAILED_PROTOCOL |
                               ZMQ_EVENT_HANDSHAKE_FAILED_NO_DETAIL) == 0) {
        w->monitor = zmq_socket(w->zctx, ZMQ_PAIR);
        if (w->monitor && zmq_connect(w->monitor, addr) != 0) {
            zmq_close(w->monitor);
            w->monitor = NULL;
        }
    }
    if (zmq_connect(w->sock, w->opts->endpoint) != 0) {
        int e = errno;
        fprintf(stderr, "photonfarm-worker: cannot connect to '%s': %s\n", w->opts->endpoint, zmq_strerror(e));
        s_close_socket(w, 0);
        return e == EINVAL || e == EPROTONOSUPPORT || e == ENOCOMPATPROTO ? PF_WORKER_EXIT_USAGE : PF_WORKER_EXIT_FATAL;
    }
    if (!w->curve && !w->plaintext_warned && !s_endpoint_local(w->opts->endpoint)) {
        w->plaintext_warned = 1;
        pf_w_log(w, PF_LOG_WARN, "connecting to %s without CURVE: the scene, the maps and the images cross the "
                 "network in the clear, and whoever can reach this worker's traffic can pose as the coordinator "
                 "(use --curve-key and --curve-server-key; see docs/cluster.md)", w->opts->endpoint);
    }
    w->conn = S_HELLO;
    w->hello_sent = 0;
    w->opened = w->last_recv = pf_now();
    pf_w_log(w, PF_LOG_DEBUG, "connecting to %s", w->opts->endpoint);
    s_send_hello(w);
    return 0;
}

/* The coordinator is gone (silent, or said BYE): forget its job and open a
 * new socket after the backoff. */
static void s_lost(s_worker *w, pf_log_level level, const char *why)
{
    pf_w_job_drop(w, why);
    s_close_socket(w, 0);
    w->reconnect_at = pf_now() + w->backoff_s;
    pf_w_log(w, level, "%s; contacting %s again in %.0f s", why, w->opts->endpoint, w->backoff_s);
    w->backoff_s = w->backoff_s * 2 > S_BACKOFF_MAX_S ? S_BACKOFF_MAX_S : w->backoff_s * 2;
}

/* The coordinator refused this worker (REFUSE, or CURVE authentication
 * refused). A --exit-on-bye worker was started for one job: it exits (3).
 * Any other closes the socket and tries again after the backoff, logging a
 * refusal only when its reason differs from the last one logged. */
static void s_refused(s_worker *w, const char *reason)
{
    char shown[sizeof w->refusal];
    pf_log_printable(shown, sizeof shown, reason);
    if (w->opts->exit_on_bye) {
        pf_w_log(w, PF_LOG_ERROR, "refused by %s: %s; --exit-on-bye: exiting", w->opts->endpoint, shown);
        pf_w_job_drop(w, "refused");
        w->finished = 1;
        w->exit_code = PF_WORKER_EXIT_REFUSED;
        return;
    }
    pf_w_job_drop(w, "refused");
    s_close_socket(w, 0);
    w->reconnect_at = pf_now() + w->backoff_s;
    if (strcmp(shown, w->refusal) != 0) {
        memcpy(w->refusal, shown, sizeof shown);
        pf_w_log(w, PF_LOG_ERROR, "refused by %s: %s; trying again in %.0f s, then with a backoff doubling to "
                 "%.0f s (the same refusal is not logged again)", w->opts->endpoint, shown, w->backoff_s,
                 S_REFUSED_BACKOFF_MAX_S);
    } else {
        pf_w_log(w, PF_LOG_DEBUG, "refused again by %s; trying again in %.0f s", w->opts->endpoint, w->backoff_s);
    }
    w->backoff_s = w->backoff_s * 2 > S_REFUSED_BACKOFF_MAX_S ? S_REFUSED_BACKOFF_MAX_S : w->backoff_s * 2;
}

static void s_on_monitor(s_worker *w)
{
    for (;;) {
        zmq_msg_t ev, ep;
        zmq_msg_init(&ev);
        if (zmq_msg_recv(&ev, w->monitor, ZMQ_DONTWAIT) < 0) {
            zmq_msg_close(&ev);
            return;
        }
        uint16_t event = 0;
        uint32_t value = 0;
        if (zmq_msg_size(&ev) >= 6) {
            const uint8_t *p = zmq_msg_data(&ev);
            memcpy(&event, p, 2); /* host byte order, from our own libzmq */
            memcpy(&value, p + 2, 4);
        }
        int more = zmq_msg_more(&ev);
        zmq_msg_close(&ev);
        zmq_msg_init(&ep);
        if (more)
            zmq_msg_recv(&ep, w->monitor, ZMQ_DONTWAIT);
        zmq_msg_close(&ep);
        switch (event) {
        case ZMQ_EVENT_CONNECTED: pf_w_log(w, PF_LOG_DEBUG, "TCP connection to %s up", w->opts->endpoint); break;
        case ZMQ_EVENT_DISCONNECTED: pf_w_log(w, PF_LOG_DEBUG, "connection to %s closed", w->opts->endpoint); break;
        case ZMQ_EVENT_HANDSHAKE_SUCCEEDED:
            pf_w_log(w, PF_LOG_DEBUG, "handshake with %s done", w->opts->endpoint);
            break;
        case ZMQ_EVENT_HANDSHAKE_FAILED_AUTH: {
            if (value != 400) { /* 300: try later, 500: the coordinator's ZAP handler failed */
                pf_w_log(w, PF_LOG_WARN, "CURVE authentication with %s failed with status %u; retrying",
                         w->opts->endpoint, (unsigned)value);
                break;
            }
            char why[160];
            snprintf(why, sizeof why, "CURVE authentication failed (status %u): this worker's public key is not on "
                     "the coordinator's list (yet)", (unsigned)value);
            s_refused(w, why);
            return;
        }
        case ZMQ_EVENT_HANDSHAKE_FAILED_PROTOCOL:
        case ZMQ_EVENT_HANDSHAKE_FAILED_NO_DETAIL:
            pf_w_log(w, PF_LOG_WARN, "handshake with %s failed (%s 0x%x): do both sides agree on CURVE and its keys?",
                     w->opts->endpoint, event == ZMQ_EVENT_HANDSHAKE_FAILED_PROTOCOL ? "protocol error" : "error",
                     (unsigned)value);
            break;
        default: break;
        }
    }
}

static void s_on_message(s_worker *w, const uint8_t *frame, size_t len)
{
    pf_msg_t m;
    char why[256] = "";
    int rc = pf_msg_decode(frame, len, &m, why, sizeof why);
    w->last_recv = pf_now(); /* even garbage shows the peer is there */
    if (rc) {
        w->malformed++;
        char shown[300];
        if (w->malformed <= 20 || w->malformed % 1000 == 0)
            pf_w_log(w, PF_LOG_WARN, "dropped %s message of %zu bytes from the coordinator (%u so far): %s",
                     rc == PF_EMISMATCH ? "a foreign-version" : "a malformed", len, w->malformed,
                     pf_log_printable(shown, sizeof shown, why));
        return;
    }
    if (w->conn == S_HELLO) {
        switch (m.type) {
        case PF_MSG_WELCOME:
            w->conn = S_ONLINE;
            w->served = 1;
            w->hb_ms = m.u.welcome.heartbeat_ms ? m.u.welcome.heartbeat_ms : 1000;
            w->backoff_s = S_BACKOFF_MIN_S;
            w->refusal[0] = '\0'; /* a later refusal is news again */
            w->last_hb = 0; /* a first heartbeat right away */
            pf_w_log(w, PF_LOG_INFO, "registered with %s as worker %" PRIu32 " (%d threads, heartbeat %" PRIu32 " ms)",
                     w->opts->endpoint, m.u.welcome.worker_id, w->threads, w->hb_ms);
            return;
        case PF_MSG_REFUSE: s_refused(w, m.u.refuse.reason); return;
        case PF_MSG_BYE: break;
        default:
            pf_w_log(w, PF_LOG_DEBUG, "%s before WELCOME; dropped", pf_msg_type_name(m.type));
            return;
        }
    }
    switch (m.type) {
    case PF_MSG_HEARTBEAT: break;
    case PF_MSG_WELCOME: pf_w_log(w, PF_LOG_DEBUG, "a second WELCOME; ignored"); break;
    case PF_MSG_REFUSE: s_refused(w, m.u.refuse.reason); break;
    case PF_MSG_JOB: pf_w_on_job(w, &m); break;
    case PF_MSG_BLOB_CHUNK: pf_w_on_chunk(w, &m.u.chunk, 0); break;
    case PF_MSG_BLOB_PLAN: pf_w_on_plan(w, &m); break;
    case PF_MSG_TILE: pf_w_on_tile(w, &m); break;
    case PF_MSG_PHOTON_REQ: pf_w_on_photon_req(w, &m); break;
    case PF_MSG_IRR_REQ: pf_w_on_irr_req(w, &m); break;
    case PF_MSG_JOB_END:
        if (w->pjob && w->pjob->id == m.job && (!w->job || w->job->id != m.job))
            pf_w_photons_drop(w, "JOB_END");
        if (w->job && w->job->id == m.job) {
            pf_w_log(w, PF_LOG_INFO, "job %" PRIu64 ": ended", m.job);
            pf_w_job_drop(w, "JOB_END");
        } else {
            pf_w_log(w, PF_LOG_DEBUG, "JOB_END for job %" PRIu64 ", which is not the current job", m.job);
        }
        break;
    case PF_MSG_BYE: {
        char shown[300];
        pf_w_log(w, PF_LOG_INFO, "the coordinator said goodbye (%s)",
                 pf_log_printable(shown, sizeof shown, m.u.bye.reason));
        if (w->opts->exit_on_bye) {
            pf_w_job_drop(w, "BYE");
            w->finished = 1;
            w->exit_code = PF_WORKER_EXIT_OK;
        } else {
            w->backoff_s = S_BACKOFF_MIN_S;
            s_lost(w, PF_LOG_INFO, "the coordinator left");
        }
        break;
    }
    default:
        pf_w_log(w, PF_LOG_WARN, "unexpected %s from the coordinator; dropped", pf_msg_type_name(m.type));
        break;
    }
}

/* Receives what the socket holds (bounded, so timers still run under a
 * flood). Multi-frame messages are not part of the protocol and are dropped. */
static void s_receive(s_worker *w)
{
    /* Never long (a stream of blob chunks must not keep the heartbeats back). */
    double t0 = pf_now();
    for (int i = 0; i < S_MAX_RECV_PER_WAKE && w->sock && !w->finished && pf_now() - t0 < 0.05; i++) {
        zmq_msg_t msg;
        zmq_msg_init(&msg);
        if (zmq_msg_recv(&msg, w->sock, ZMQ_DONTWAIT) < 0) {
            zmq_msg_close(&msg);
            return;
        }
        if (zmq_msg_more(&msg)) {
            size_t parts = 1;
            do {
                zmq_msg_close(&msg);
                zmq_msg_init(&msg);
                if (zmq_msg_recv(&msg, w->sock, ZMQ_DONTWAIT) < 0)
                    break;
                parts++;
            } while (zmq_msg_more(&msg));
            zmq_msg_close(&msg);
            w->malformed++;
            w->last_recv = pf_now();
            pf_w_log(w, PF_LOG_WARN, "dropped a message of %zu frames (the protocol uses one)", parts);
            continue;
        }
        s_on_message(w, zmq_msg_data(&msg), zmq_msg_size(&msg));
        zmq_msg_close(&msg);
    }
}

/* Heartbeats, the coordinator's liveness, HELLO retries, stalled transfers. */
static void s_timers(s_worker *w)
{
    double now = pf_now();
    /* A loop that did not run for a while (the process was stopped or
     * starved) says nothing about the coordinator: do not count that gap as
     * its silence. The late results then still go out (the coordinator
     * drops them as duplicates if it has re-issued the tiles), and a
     * coordinator that has written us off stays silent and is left after
     * the usual 5 intervals. */
    double gap = w->last_tick > 0 ? now - w->last_tick : 0;
    w->last_tick = now;
    if (gap > 1.0) {
        pf_w_log(w, PF_LOG_INFO, "this worker was stalled for %.1f s (stopped?); resuming", gap);
        w->last_recv += gap;
        w->opened += gap;
        pf_w_blobs_resume(w, gap);
    }
    if (w->conn == S_HELLO) {
        if (!w->hello_sent)
            s_send_hello(w);
        if (now - w->opened > S_HELLO_TIMEOUT_S && w->opts->exit_on_bye && w->served) {
            /* A one-job worker whose coordinator went away while it could
             * not hear the goodbye (stopped, cut off) would otherwise wait
             * for it forever. */
            pf_w_log(w, PF_LOG_INFO, "the coordinator this worker served is gone (no WELCOME within 5 s); "
                     "--exit-on-bye: exiting");
            pf_w_job_drop(w, "coordinator gone");
            w->finished = 1;
            w->exit_code = PF_WORKER_EXIT_OK;
        } else if (now - w->opened > S_HELLO_TIMEOUT_S)
            s_lost(w, PF_LOG_WARN, w->hello_sent ? "no WELCOME within 5 s"
                                    : (w->curve ? "no connection within 5 s (is the coordinator up, and the CURVE "
                                                  "server key right?)"
                                                : "no connection within 5 s (is the coordinator up?)"));
        return;
    }
    if (w->conn != S_ONLINE)
        return;
    double hb = w->hb_ms / 1000.0;
    if (now - w->last_recv > S_DEAD_AFTER * hb) {
        char why[96];
        snprintf(why, sizeof why, "no word from the coordinator for %.1f s", now - w->last_recv);
        s_lost(w, PF_LOG_WARN, why);
        return;
    }
    if (now - w->last_hb >= hb) {
        s_send_heartbeat(w);
        w->last_hb = now;
    }
    pf_w_blobs_check_stalls(w, now);
}

/* ---- set-up and the loop ---- */

static int s_setup(s_worker *w, const pf_worker_opts_t *opts)
{
    memset(w, 0, sizeof *w);
    w->opts = opts;
    w->q.wake[0] = w->q.wake[1] = -1;
    w->backoff_s = S_BACKOFF_MIN_S;
    w->hb_ms = 1000;
    atomic_init(&w->progress, 0);
    w->threads = opts->threads > 0 ? opts->threads : omp_get_num_procs();
    if (w->threads > 4096)
        w->threads = 4096;
    if (opts->name && opts->name[0]) {
        snprintf(w->name, sizeof w->name, "%s", opts->name);
    } else {
        char host[200] = "localhost";
        gethostname(host, sizeof host - 1);
        host[sizeof host - 1] = '\0';
        snprintf(w->name, sizeof w->name, "%s:%ld", host, (long)getpid());
    }
    if (!opts->endpoint || !opts->endpoint[0]) {
        fprintf(stderr, "photonfarm-worker: no coordinator endpoint\n");
        return PF_WORKER_EXIT_USAGE;
    }
    if (opts->curve_key || opts->curve_server_key) {
        pf_error_t err;
        if (!opts->curve_key || !opts->curve_server_key) {
            fprintf(stderr, "photonfarm-worker: CURVE needs both --curve-key and --curve-server-key\n");
            return PF_WORKER_EXIT_USAGE;
        }
        if (!zmq_has("curve")) {
            fprintf(stderr, "photonfarm-worker: this libzmq was built without CURVE\n");
            return PF_WORKER_EXIT_FATAL;
        }
        if (pf_keyfile_read(opts->curve_key, w->public_key, w->secret_key, &err) ||
            pf_keyfile_read(opts->curve_server_key, w->server_key, NULL, &err)) {
            fprintf(stderr, "photonfarm-worker: %s\n", err.msg);
            return PF_WORKER_EXIT_FATAL;
        }
        char derived[41];
        if (zmq_curve_public(derived, w->secret_key) != 0 || strcmp(derived, w->public_key) != 0) {
            fprintf(stderr, "photonfarm-worker: %s: the public key does not belong to the secret key\n",
                    opts->curve_key);
            return PF_WORKER_EXIT_FATAL;
        }
        w->curve = 1;
    }
    if (pf_w_queue_init(&w->q) != 0)
        return PF_WORKER_EXIT_FATAL;
    w->zctx = zmq_ctx_new();
    if (!w->zctx) {
        fprintf(stderr, "photonfarm-worker: cannot create a ZeroMQ context: %s\n", zmq_strerror(errno));
        return PF_WORKER_EXIT_FATAL;
    }
    if (pf_w_peers_open(w) != 0) {
        fprintf(stderr, "photonfarm-worker: cannot create the peer socket: %s\n", zmq_strerror(errno));
        return PF_WORKER_EXIT_FATAL;
    }
    return pf_w_compute_start(w) != 0 ? PF_WORKER_EXIT_FATAL : 0;
}

static void s_teardown(s_worker *w)
{
    pf_w_job_drop(w, "exit");
    pf_w_compute_stop(w);
    if (w->sock || w->monitor)
        s_close_socket(w, S_LINGER_MS);
    pf_w_outbox_clear(w);
    pf_w_peers_close(w);
    if (w->zctx)
        zmq_ctx_term(w->zctx);
    pf_w_cache_free(w);
    pf_buf_free(&w->enc);
    pf_w_queue_destroy(&w->q);
}

int pf_worker_run(const pf_worker_opts_t *opts)
{
    s_worker *w = calloc(1, sizeof *w);
    if (!w) {
        fprintf(stderr, "photonfarm-worker: out of memory\n");
        return PF_WORKER_EXIT_FATAL;
    }
    int code = s_setup(w, opts);
    if (code == 0)
        code = s_open(w);
    while (code == 0 && !w->finished) {
        if (opts->stop && *opts->stop) {
            if (w->sock && w->hello_sent) {
                pf_msg_t m;
                memset(&m, 0, sizeof m);
                m.type = PF_MSG_BYE;
                snprintf(m.u.bye.reason, sizeof m.u.bye.reason, "signal");
                pf_w_outbox_clear(w); /* results nobody will use; the BYE matters */
                pf_w_send(w, &m, 0);
            }
            pf_w_log(w, PF_LOG_INFO, "stopping on a signal");
            w->exit_code = PF_WORKER_EXIT_OK;
            break;
        }
        if (w->conn == S_OFFLINE && pf_now() >= w->reconnect_at) {
            code = s_open(w);
            if (code)
                break;
        }
        pf_w_flush(w);
        zmq_pollitem_t items[5];
        int n = 0, i_sock = -1, i_mon = -1;
        items[n++] = (zmq_pollitem_t){ NULL, w->q.wake[0], ZMQ_POLLIN, 0 };
        if (w->sock) {
            short ev = ZMQ_POLLIN;
            if (w->out || (w->conn == S_HELLO && !w->hello_sent))
                ev |= ZMQ_POLLOUT;
            i_sock = n;
            items[n++] = (zmq_pollitem_t){ w->sock, 0, ev, 0 };
        }
        if (w->monitor) {
            i_mon = n;
            items[n++] = (zmq_pollitem_t){ w->monitor, 0, ZMQ_POLLIN, 0 };
        }
        if (w->psrv) /* peers.c reads both peer sockets after every wake-up */
            items[n++] = (zmq_pollitem_t){ w->psrv, 0, ZMQ_POLLIN, 0 };
        if (w->pfetch)
            items[n++] = (zmq_pollitem_t){ w->pfetch, 0, ZMQ_POLLIN, 0 };
        /* A child waiting for chunks held back by libzmq's queue: look again soon. */
        int rc = zmq_poll(items, n, pf_w_peers_busy(w) ? 10 : S_POLL_MS);
        if (rc < 0) {
            if (errno == EINTR)
                continue;
            fprintf(stderr, "photonfarm-worker: zmq_poll: %s\n", zmq_strerror(errno));
            code = PF_WORKER_EXIT_FATAL;
            break;
        }
        if (items[0].revents & ZMQ_POLLIN)
            pf_w_drain_done(w);
        if (i_mon >= 0 && (items[i_mon].revents & ZMQ_POLLIN))
            s_on_monitor(w);
        if (!w->finished && i_sock >= 0 && w->sock && (items[i_sock].revents & ZMQ_POLLIN))
            s_receive(w);
        if (!w->finished)
            pf_w_peers_on_poll(w);
        if (!w->finished)
            s_timers(w);
    }
    if (code == 0)
        code = w->exit_code;
    s_teardown(w);
    free(w);
    return code;
}
