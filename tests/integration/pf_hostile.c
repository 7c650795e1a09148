/* pf_hostile.c: a hostile worker for the farm tests (tests/integration/test_hostile.sh).
 *
 *   pf_hostile ENDPOINT MODE [N [SECONDS]]
 *
 * Speaks the real wire format (proto/messages.h) over one ZMQ_DEALER (or,
 * for churn and forge, several in turn), with a valid fingerprint: a peer
 * the coordinator admits, that then lies, floods or hoards:
 *
 *   blob-flood [N=5000 [HOLD=10]]  HELLO, waits for the JOB, then sends N
 *               BLOB_REQs for the map blob at offset 0 with the largest
 *               credit the protocol allows (64 chunks), and never reads
 *               again (small receive buffers, so the coordinator's queue to
 *               it fills); holds the connection HOLD seconds (it keeps
 *               heartbeating, still never reading), then exits.
 *   hoard [HOLD=60]   HELLO announcing 64 threads, READY with credit 1024
 *               at once (no blob fetched), then takes every TILE and answers
 *               none, while it heartbeats with a progress counter that
 *               climbs as if it rendered; until BYE, JOB_END or HOLD seconds.
 *   churn [N=1100]    N cycles of: a new connection, HELLO, up to 200 ms for
 *               the answer, close.
 *   forge [WAIT=2]    HELLO, READY with credit 1, waits for one TILE, then
 *               drops the connection without a word; WAIT seconds later a
 *               new connection says HELLO again (under the same name) and
 *               sends a RESULT (right size, black pixels) for the lease the
 *               first connection held, then BYE. A coordinator that knows a
 *               worker by an id it never reuses refuses it, whatever slot
 *               the second connection lands in.
 *   liar [HOLD=60]    HELLO, READY with credit 2 (no blob fetched), then
 *               answers every TILE at once with a RESULT of the right size
 *               whose pixels are made up (a constant 0.25, nothing
 *               rendered), heartbeating; until BYE, JOB_END or HOLD seconds.
 *               Only a coordinator that checks results catches it.
 *   photon-liar [HOLD=60]  HELLO, then answers every PHOTON_REQ at once
 *               with a PHOTONS per batch that claims the batch stored no
 *               photon and rejected none (well-formed, within the plan's
 *               bounds: only re-tracing the batch shows the lie); it never
 *               says READY (no tile); until BYE, JOB_END or HOLD seconds.
 *   evil-name         HELLO under a name with a newline and a terminal
 *               escape sequence ("evil\nname\x1b[31mred"), waits for the
 *               JOB, then BYE with a reason that has them too.
 *
 * While it waits for a JOB or a TILE it heartbeats, as a worker does.
 * Every wait is bounded. Exit 0 whatever the coordinator does (the tests
 * judge it by its log, summary, image and memory); 1 on an internal failure
 * (no memory, no context), 2 on a usage error, 3 when a mode could not get
 * as far as its attack (no JOB, no TILE). One line on stdout says what it
 * did. */
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <unistd.h>
#include <zmq.h>

#include "base/log.h"
#include "proto/messages.h"
#include "render/frame.h"

#define S_JOB_WAIT_S 60.0
#define S_TILE_WAIT_S 60.0
#define S_SEND_TIMEOUT_MS 5000

typedef struct s_peer {
    void *ctx, *sock;
    const char *endpoint;
    uint8_t *frame; /* receive buffer, PF_PROTO_MAX_MESSAGE bytes */
    pf_buf_t enc;
    uint32_t hb_ms, uid;
} s_peer;

/* A new DEALER connected to the endpoint. rcvbuf > 0 shrinks the kernel's
 * receive buffer (the flood's "never reading" fills up quickly). */
static int s_open(s_peer *p, int rcvbuf)
{
    p->sock = zmq_socket(p->ctx, ZMQ_DEALER);
    if (!p->sock)
        return -1;
    int linger = 0, sndto = S_SEND_TIMEOUT_MS, rcvto = 100, hwm = 100000;
    zmq_setsockopt(p->sock, ZMQ_LINGER, &linger, sizeof linger);
    zmq_setsockopt(p->sock, ZMQ_SNDTIMEO, &sndto, sizeof sndto);
    zmq_setsockopt(p->sock, ZMQ_RCVTIMEO, &rcvto, sizeof rcvto);
    zmq_setsockopt(p->sock, ZMQ_SNDHWM, &hwm, sizeof hwm);
    if (rcvbuf > 0) {
        int one = 1;
        zmq_setsockopt(p->sock, ZMQ_RCVBUF, &rcvbuf, sizeof rcvbuf);
        zmq_setsockopt(p->sock, ZMQ_RCVHWM, &one, sizeof one);
    }
    return zmq_connect(p->sock, p->endpoint);
}

static void s_close(s_peer *p)
{
    if (p->sock)
        zmq_close(p->sock);
    p->sock = NULL;
}

static int s_send(s_peer *p, pf_msg_t *m)
{
    if (pf_msg_encode(m, &p->enc) != 0) {
        fprintf(stderr, "pf_hostile: cannot encode a %s\n", pf_msg_type_name(m->type));
        return -1;
    }
    return zmq_send(p->sock, p->enc.data, p->enc.len, 0) < 0 ? -1 : 0;
}

/* Receives and decodes one message within timeout_ms. 0, or -1. */
static int s_recv(s_peer *p, pf_msg_t *m, int timeout_ms)
{
    zmq_pollitem_t it = { p->sock, 0, ZMQ_POLLIN, 0 };
    if (zmq_poll(&it, 1, timeout_ms) <= 0)
        return -1;
    int n = zmq_recv(p->sock, p->frame, PF_PROTO_MAX_MESSAGE, ZMQ_DONTWAIT);
    char why[256];
    if (n < 0 || (size_t)n > PF_PROTO_MAX_MESSAGE || pf_msg_decode(p->frame, (size_t)n, m, why, sizeof why) != 0)
        return -1;
    return 0;
}

static int s_hello(s_peer *p, const char *name, uint32_t threads)
{
    pf_msg_t m;
    memset(&m, 0, sizeof m);
    m.type = PF_MSG_HELLO;
    m.u.hello.fp = pf_frame_fingerprint();
    m.u.hello.threads = threads;
    snprintf(m.u.hello.name, sizeof m.u.hello.name, "%s", name);
    return s_send(p, &m);
}

/* A HEARTBEAT when one is due (every heartbeat interval the WELCOME gave),
 * so the coordinator does not take this peer for dead while it waits. */
static void s_heartbeat_due(s_peer *p, double *next, uint64_t progress)
{
    if (!p->hb_ms || pf_now() < *next)
        return;
    pf_msg_t h;
    memset(&h, 0, sizeof h);
    h.type = PF_MSG_HEARTBEAT;
    h.u.heartbeat.progress = progress;
    s_send(p, &h);
    *next = pf_now() + p->hb_ms / 1000.0;
}

/* Says HELLO and waits (bounded) for WELCOME and the JOB. 0 with the job,
 * -1 (printed) when refused or nothing came. */
static int s_register(s_peer *p, const char *name, uint32_t threads, uint64_t *jobid, pf_msg_job_t *job)
{
    if (s_hello(p, name, threads) != 0)
        return -1;
    double end = pf_now() + S_JOB_WAIT_S, next_hb = 0;
    while (pf_now() < end) {
        pf_msg_t m;
        s_heartbeat_due(p, &next_hb, 0);
        if (s_recv(p, &m, 50) != 0)
            continue;
        if (m.type == PF_MSG_WELCOME) {
            p->hb_ms = m.u.welcome.heartbeat_ms;
            p->uid = m.u.welcome.worker_id;
        } else if (m.type == PF_MSG_REFUSE) {
            printf("pf_hostile %s: refused: %s\n", name, m.u.refuse.reason);
            return -1;
        } else if (m.type == PF_MSG_JOB) {
            *jobid = m.job;
            *job = m.u.job;
            return 0;
        }
    }
    printf("pf_hostile %s: no JOB within %.0f s\n", name, S_JOB_WAIT_S);
    return -1;
}

static void s_simple(s_peer *p, int type, uint64_t job)
{
    pf_msg_t m;
    memset(&m, 0, sizeof m);
    m.type = type;
    m.job = job;
    if (type == PF_MSG_BYE)
        snprintf(m.u.bye.reason, sizeof m.u.bye.reason, "pf_hostile done");
    s_send(p, &m);
}

static void s_ready(s_peer *p, uint64_t job, uint32_t credit)
{
    pf_msg_t m;
    memset(&m, 0, sizeof m);
    m.type = PF_MSG_READY;
    m.job = job;
    m.u.ready.credit = credit;
    s_send(p, &m);
}

/* ---- modes ---- */

static int s_blob_flood(s_peer *p, long n, double hold)
{
    uint64_t jobid;
    pf_msg_job_t job;
    if (s_open(p, 4096) != 0 || s_register(p, "hostile-flood", 1, &jobid, &job) != 0)
        return 3;
    pf_msg_t m;
    memset(&m, 0, sizeof m);
    m.type = PF_MSG_BLOB_REQ;
    m.job = jobid;
    m.u.blob_req = (pf_msg_blob_req_t){ job.maps_hash, 0, 64 };
    long sent = 0, failed = 0;
    for (long i = 0; i < n; i++) {
        if (s_send(p, &m) == 0)
            sent++;
        else
            failed++;
    }
    printf("pf_hostile blob-flood: job %llu, map blob %016llx (%llu bytes): %ld BLOB_REQ (offset 0, credit 64) sent, "
           "%ld failed; holding the connection %.0f s without reading\n",
           (unsigned long long)jobid, (unsigned long long)job.maps_hash, (unsigned long long)job.maps_size, sent,
           failed, hold);
    fflush(stdout);
    double end = pf_now() + hold, next_hb = 0;
    while (pf_now() < end) { /* alive, and still not reading */
        s_heartbeat_due(p, &next_hb, 0);
        usleep(20000);
    }
    return 0;
}

static int s_hoard(s_peer *p, double hold)
{
    uint64_t jobid;
    pf_msg_job_t job;
    if (s_open(p, 0) != 0 || s_register(p, "hostile-hoard", 64, &jobid, &job) != 0)
        return 3;
    s_ready(p, jobid, 1024);
    double end = pf_now() + hold, next_hb = 0, hb = p->hb_ms ? p->hb_ms / 1000.0 : 1.0;
    uint64_t progress = 0, tiles = 0, heartbeats = 0;
    const char *ended = "its time";
    while (pf_now() < end) {
        if (pf_now() >= next_hb) {
            pf_msg_t h;
            memset(&h, 0, sizeof h);
            h.type = PF_MSG_HEARTBEAT;
            progress += 4096; /* "rendering": a counter a coordinator must not trust */
            h.u.heartbeat = (pf_msg_heartbeat_t){ progress, (uint32_t)tiles };
            s_send(p, &h);
            heartbeats++;
            next_hb = pf_now() + hb;
        }
        pf_msg_t m;
        if (s_recv(p, &m, 50) != 0)
            continue;
        if (m.type == PF_MSG_TILE)
            tiles++;
        if (m.type == PF_MSG_BYE || m.type == PF_MSG_JOB_END) {
            ended = m.type == PF_MSG_BYE ? "BYE" : "JOB_END";
            break;
        }
    }
    printf("pf_hostile hoard: job %llu, READY with credit 1024 (64 threads announced); %llu TILEs taken, none "
           "answered; %llu heartbeats with a rising progress counter; ended by %s\n",
           (unsigned long long)jobid, (unsigned long long)tiles, (unsigned long long)heartbeats, ended);
    return 0;
}

static int s_churn(s_peer *p, long n)
{
    long welcomed = 0, refused = 0, silent = 0;
    char last_refusal[128] = "";
    double t0 = pf_now();
    for (long i = 0; i < n; i++) {
        if (s_open(p, 0) != 0 || s_hello(p, "hostile-churn", 1) != 0) {
            s_close(p);
            silent++;
            continue;
        }
        double end = pf_now() + 0.2;
        int answered = 0;
        while (!answered && pf_now() < end) {
            pf_msg_t m;
            if (s_recv(p, &m, 20) != 0)
                continue;
            if (m.type == PF_MSG_WELCOME) {
                welcomed++;
                answered = 1;
            } else if (m.type == PF_MSG_REFUSE) {
                refused++;
                snprintf(last_refusal, sizeof last_refusal, "%.100s", m.u.refuse.reason);
                answered = 1;
            }
        }
        silent += !answered;
        s_close(p);
    }
    printf("pf_hostile churn: %ld connect-HELLO-close cycles in %.1f s: %ld welcomed, %ld refused%s%s%s, %ld "
           "unanswered\n",
           n, pf_now() - t0, welcomed, refused, refused ? " (\"" : "", last_refusal, refused ? "\")" : "", silent);
    return 0;
}

/* Waits (bounded) for the first TILE. 0 with it, -1. */
static int s_first_tile(s_peer *p, pf_msg_tile_t *tile, uint32_t *attempt)
{
    double end = pf_now() + S_TILE_WAIT_S, next_hb = 0;
    while (pf_now() < end) {
        pf_msg_t m;
        s_heartbeat_due(p, &next_hb, 0);
        if (s_recv(p, &m, 50) == 0 && m.type == PF_MSG_TILE) {
            *tile = m.u.tile;
            *attempt = m.u.tile.attempt;
            return 0;
        }
    }
    return -1;
}

static int s_forge(s_peer *p, double wait)
{
    uint64_t jobid;
    pf_msg_job_t job;
    pf_msg_tile_t tile;
    uint32_t attempt = 0;
    if (s_open(p, 0) != 0 || s_register(p, "hostile-forge", 1, &jobid, &job) != 0)
        return 3;
    uint32_t uid1 = p->uid;
    s_ready(p, jobid, 1);
    if (s_first_tile(p, &tile, &attempt) != 0) {
        printf("pf_hostile forge: no TILE within %.0f s\n", S_TILE_WAIT_S);
        return 3;
    }
    s_close(p); /* gone without a word: the lease stays behind */
    usleep((useconds_t)(wait * 1e6));
    pf_msg_job_t job2;
    uint64_t jobid2;
    if (s_open(p, 0) != 0 || s_register(p, "hostile-forge", 1, &jobid2, &job2) != 0)
        return 3;
    float *rgb = calloc((size_t)tile.w * tile.h * 3, sizeof *rgb);
    if (!rgb)
        return 1;
    pf_msg_t m;
    memset(&m, 0, sizeof m);
    m.type = PF_MSG_RESULT;
    m.job = jobid;
    m.u.result = (pf_msg_result_t){ .tile = tile.tile, .attempt = attempt, .x0 = tile.x0, .y0 = tile.y0,
                                    .w = tile.w, .h = tile.h, .rgb = rgb, .render_us = 1000 };
    int rc = s_send(p, &m);
    free(rgb);
    usleep(500000);
    s_simple(p, PF_MSG_BYE, jobid);
    usleep(200000);
    printf("pf_hostile forge: job %llu: worker id %u leased tile %u attempt %u and vanished; %.1f s later worker id %u "
           "sent a RESULT for that lease (%s)\n",
           (unsigned long long)jobid, uid1, tile.tile, attempt, wait, p->uid, rc == 0 ? "sent" : "send failed");
    return 0;
}

static int s_liar(s_peer *p, double hold)
{
    uint64_t jobid;
    pf_msg_job_t job;
    if (s_open(p, 0) != 0 || s_register(p, "hostile-liar", 1, &jobid, &job) != 0)
        return 3;
    s_ready(p, jobid, 2);
    size_t npx = (size_t)job.tile_size * job.tile_size * 3;
    float *rgb = malloc((npx ? npx : 1) * sizeof *rgb);
    if (!rgb)
        return 1;
    for (size_t i = 0; i < npx; i++)
        rgb[i] = 0.25f;
    double end = pf_now() + hold, next_hb = 0;
    uint64_t tiles = 0;
    const char *ended = "its time";
    while (pf_now() < end) {
        s_heartbeat_due(p, &next_hb, tiles);
        pf_msg_t m;
        if (s_recv(p, &m, 50) != 0)
            continue;
        if (m.type == PF_MSG_TILE && (size_t)m.u.tile.w * m.u.tile.h * 3 <= npx) {
            pf_msg_t r;
            memset(&r, 0, sizeof r);
            r.type = PF_MSG_RESULT;
            r.job = jobid;
            r.u.result = (pf_msg_result_t){ .tile = m.u.tile.tile, .attempt = m.u.tile.attempt, .x0 = m.u.tile.x0,
                                            .y0 = m.u.tile.y0, .w = m.u.tile.w, .h = m.u.tile.h, .rgb = rgb,
                                            .render_us = 1000 };
            if (s_send(p, &r) == 0)
                tiles++;
        }
        if (m.type == PF_MSG_BYE || m.type == PF_MSG_JOB_END) {
            ended = m.type == PF_MSG_BYE ? "BYE" : "JOB_END";
            break;
        }
    }
    free(rgb);
    printf("pf_hostile liar: job %llu: %llu made-up RESULTs sent; ended by %s\n", (unsigned long long)jobid,
           (unsigned long long)tiles, ended);
    return 0;
}

static int s_photon_liar(s_peer *p, double hold)
{
    if (s_open(p, 0) != 0 || s_hello(p, "hostile-photons", 1) != 0)
        return 3;
    double end = pf_now() + hold, next_hb = 0;
    uint64_t lies = 0, reqs = 0;
    const char *ended = "its time";
    pf_msg_photon_t none = { { 0, 0, 0 }, { 0, 0, 0 }, 0, 0 };
    while (pf_now() < end) {
        s_heartbeat_due(p, &next_hb, lies);
        pf_msg_t m;
        if (s_recv(p, &m, 20) != 0)
            continue;
        if (m.type == PF_MSG_WELCOME) {
            p->hb_ms = m.u.welcome.heartbeat_ms;
            p->uid = m.u.welcome.worker_id;
        } else if (m.type == PF_MSG_PHOTON_REQ) {
            reqs++;
            for (uint32_t k = 0; k < m.u.photon_req.count; k++) {
                pf_msg_t r;
                memset(&r, 0, sizeof r);
                r.type = PF_MSG_PHOTONS;
                r.job = m.job;
                r.u.photons = (pf_msg_photons_t){ m.u.photon_req.first + k, 0, 0, 0, 0, 0, NULL, &none };
                if (s_send(p, &r) == 0)
                    lies++;
            }
        } else if (m.type == PF_MSG_BYE || m.type == PF_MSG_JOB_END) {
            ended = m.type == PF_MSG_BYE ? "BYE" : "JOB_END";
            break;
        }
    }
    printf("pf_hostile photon-liar: %llu PHOTON_REQs, %llu empty batches sent; ended by %s\n",
           (unsigned long long)reqs, (unsigned long long)lies, ended);
    return 0;
}

static int s_evil_name(s_peer *p)
{
    uint64_t jobid;
    pf_msg_job_t job;
    if (s_open(p, 0) != 0 || s_register(p, "evil\nname\x1b[31mred", 1, &jobid, &job) != 0)
        return 3;
    pf_msg_t m;
    memset(&m, 0, sizeof m);
    m.type = PF_MSG_BYE;
    m.job = jobid;
    snprintf(m.u.bye.reason, sizeof m.u.bye.reason, "going\nnow\x1b[0m");
    s_send(p, &m);
    usleep(200000);
    printf("pf_hostile evil-name: job %llu: HELLO and BYE with a newline and an escape sequence sent\n",
           (unsigned long long)jobid);
    return 0;
}

int main(int argc, char **argv)
{
    if (argc < 3 || argc > 5) {
        fprintf(stderr, "usage: pf_hostile ENDPOINT blob-flood [N [HOLD_S]] | hoard [HOLD_S] | churn [N] | "
                        "forge [WAIT_S] | liar [HOLD_S] | photon-liar [HOLD_S] | evil-name\n");
        return 2;
    }
    const char *mode = argv[2];
    double a = argc > 3 ? atof(argv[3]) : -1, b = argc > 4 ? atof(argv[4]) : -1;
    s_peer p;
    memset(&p, 0, sizeof p);
    p.endpoint = argv[1];
    p.ctx = zmq_ctx_new();
    p.frame = malloc(PF_PROTO_MAX_MESSAGE);
    if (!p.ctx || !p.frame) {
        fprintf(stderr, "pf_hostile: no ZeroMQ context or no memory\n");
        return 1;
    }
    int rc;
    if (!strcmp(mode, "blob-flood"))
        rc = s_blob_flood(&p, a > 0 ? (long)a : 5000, b >= 0 ? b : 10.0);
    else if (!strcmp(mode, "hoard"))
        rc = s_hoard(&p, a > 0 ? a : 60.0);
    else if (!strcmp(mode, "churn"))
        rc = s_churn(&p, a > 0 ? (long)a : 1100);
    else if (!strcmp(mode, "forge"))
        rc = s_forge(&p, a >= 0 ? a : 2.0);
    else if (!strcmp(mode, "liar"))
        rc = s_liar(&p, a > 0 ? a : 60.0);
    else if (!strcmp(mode, "photon-liar"))
        rc = s_photon_liar(&p, a > 0 ? a : 60.0);
    else if (!strcmp(mode, "evil-name"))
        rc = s_evil_name(&p);
    else {
        fprintf(stderr, "pf_hostile: unknown mode '%s'\n", mode);
        rc = 2;
    }
    fflush(stdout);
    s_close(&p);
    zmq_ctx_term(p.ctx);
    pf_buf_free(&p.enc);
    free(p.frame);
    return rc;
}
