/* pf_inject.c: a fault injector for the farm tests (tests/integration/test_farm.sh).
 *
 *   pf_inject ENDPOINT MODE [SEED]
 *
 * Connects one ZMQ_DEALER to a coordinator's ROUTER and sends crafted frames,
 * the way a broken or hostile peer would:
 *
 *   garbage     1000 random frames of 0..4096 bytes; every fourth one starts
 *               with a valid header (magic, version, a random type) so the
 *               body decoders are reached, not only the magic check;
 *   truncated   valid HELLO, RESULT, HEARTBEAT, READY, BLOB_REQ and BYE
 *               encodings cut at every length short of the whole (this peer
 *               never registers: no complete HELLO is sent);
 *   oversized   one 3 MiB frame, over the coordinator's ZMQ_MAXMSGSIZE
 *               (libzmq drops the connection; that is the expected outcome);
 *   replay      a valid HELLO, then, once the JOB names the job and its
 *               tiling, RESULT frames for the first tiles with a wrong size,
 *               a wrong attempt, a NaN pixel, a negative pixel, another job's
 *               id and a tile index past the end; then all of them again;
 *               then BYE. None of them may reach the image;
 *   multiframe  two-frame messages (valid + garbage, garbage + valid, and a
 *               HELLO split in two), which the one-frame protocol refuses;
 *   forge       a valid HELLO, then, once the JOB arrives, RESULT frames of
 *               the right size, attempt 0 and all-zero pixels for tiles this
 *               peer was never leased; then BYE. A coordinator that accepts
 *               results only for leases it issued to the sender drops them.
 *
 * Every wait is bounded (connection 5 s, JOB 30 s, each send 5 s, linger
 * 3 s), and the program exits 0 whatever the coordinator does, so a test
 * judges the coordinator by its log, its summary and its image, never by
 * this program. Exit 2 is a usage error, 1 an internal failure (no memory,
 * no ZeroMQ context). It prints one line per mode on stdout: what it sent. */
#include <errno.h>
#include <math.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <unistd.h>
#include <zmq.h>

#include "base/log.h"
#include "proto/messages.h"
#include "render/frame.h"

#define S_CONNECT_WAIT_MS 5000
#define S_JOB_WAIT_S 30.0
#define S_SEND_TIMEOUT_MS 5000
#define S_LINGER_MS 3000
#define S_REPLAY_TILES 64

typedef struct s_inj {
    void *ctx, *sock, *mon;
    uint64_t rng;
    unsigned long sent, failed;
} s_inj;

/* xorshift64*: reproducible noise from the seed argument. */
static uint64_t s_rand(s_inj *in)
{
    in->rng ^= in->rng >> 12;
    in->rng ^= in->rng << 25;
    in->rng ^= in->rng >> 27;
    return in->rng * 0x2545F4914F6CDD1Dull;
}

static void s_fill(s_inj *in, uint8_t *p, size_t n)
{
    for (size_t i = 0; i < n; i++)
        p[i] = (uint8_t)(s_rand(in) >> 56);
}

static void s_put_u16(uint8_t *p, uint16_t v)
{
    p[0] = (uint8_t)v;
    p[1] = (uint8_t)(v >> 8);
}

static void s_put_u32(uint8_t *p, uint32_t v)
{
    for (int i = 0; i < 4; i++)
        p[i] = (uint8_t)(v >> (8 * i));
}

/* Writes a valid 16-byte message header (used to get garbage past the magic
 * and version checks). */
static void s_header(uint8_t *p, uint16_t type, uint64_t job)
{
    s_put_u32(p, PF_PROTO_MAGIC);
    s_put_u16(p + 4, PF_PROTO_VERSION);
    s_put_u16(p + 6, type);
    for (int i = 0; i < 8; i++)
        p[8 + i] = (uint8_t)(job >> (8 * i));
}

/* Sends one frame (flags: 0 or ZMQ_SNDMORE). A send that cannot complete in
 * S_SEND_TIMEOUT_MS (the coordinator stopped reading, or the connection was
 * dropped) is counted as failed rather than waited for. */
static int s_send(s_inj *in, const void *data, size_t len, int flags)
{
    if (zmq_send(in->sock, data, len, flags) < 0) {
        in->failed++;
        return -1;
    }
    if (!(flags & ZMQ_SNDMORE))
        in->sent++;
    return 0;
}

static int s_send_msg(s_inj *in, const pf_msg_t *m, pf_buf_t *buf)
{
    if (pf_msg_encode(m, buf) != 0) {
        fprintf(stderr, "pf_inject: cannot encode a %s\n", pf_msg_type_name(m->type));
        return -1;
    }
    return s_send(in, buf->data, buf->len, 0);
}

/* Waits (bounded) until the connection's handshake is done, so the frames
 * are not merely queued towards an endpoint that is not there. Returns 1
 * when connected. */
static int s_wait_connected(s_inj *in)
{
    double end = pf_now() + S_CONNECT_WAIT_MS / 1000.0;
    while (pf_now() < end) {
        zmq_pollitem_t it = { in->mon, 0, ZMQ_POLLIN, 0 };
        if (zmq_poll(&it, 1, 100) <= 0)
            continue;
        zmq_msg_t ev;
        zmq_msg_init(&ev);
        if (zmq_msg_recv(&ev, in->mon, ZMQ_DONTWAIT) < 0) {
            zmq_msg_close(&ev);
            continue;
        }
        uint16_t event = 0;
        if (zmq_msg_size(&ev) >= 2) {
            const uint8_t *d = zmq_msg_data(&ev);
            event = (uint16_t)(d[0] | d[1] << 8);
        }
        int more = zmq_msg_more(&ev);
        zmq_msg_close(&ev);
        while (more) { /* the second frame names the endpoint */
            zmq_msg_t rest;
            zmq_msg_init(&rest);
            if (zmq_msg_recv(&rest, in->mon, 0) < 0)
                more = 0;
            else
                more = zmq_msg_more(&rest);
            zmq_msg_close(&rest);
        }
        if (event == ZMQ_EVENT_HANDSHAKE_SUCCEEDED)
            return 1;
    }
    return 0;
}

/* ---- modes -------------------------------------------------------------- */

static void s_garbage(s_inj *in)
{
    uint8_t *buf = malloc(4097);
    if (!buf)
        return;
    for (int i = 0; i < 1000; i++) {
        size_t n = (size_t)(s_rand(in) % 4097);
        s_fill(in, buf, n);
        if (i % 4 == 0 && n >= PF_PROTO_HEADER_SIZE)
            s_header(buf, (uint16_t)(1 + s_rand(in) % PF_MSG_MAX_TYPE), s_rand(in));
        s_send(in, buf, n, 0);
    }
    free(buf);
    printf("pf_inject garbage: %lu frames sent, %lu failed\n", in->sent, in->failed);
}

static pf_msg_t s_hello(const char *name)
{
    pf_msg_t m;
    memset(&m, 0, sizeof m);
    m.type = PF_MSG_HELLO;
    m.u.hello.fp = pf_frame_fingerprint();
    m.u.hello.threads = 1;
    snprintf(m.u.hello.name, sizeof m.u.hello.name, "%s", name);
    return m;
}

/* A RESULT for an 8x8 tile at (x0, y0) with valid pixels (encode needs them). */
static pf_msg_t s_result(uint64_t job, uint32_t tile, uint32_t attempt, uint32_t x0, uint32_t y0, uint32_t w, uint32_t h,
                         float *rgb)
{
    pf_msg_t m;
    memset(&m, 0, sizeof m);
    m.type = PF_MSG_RESULT;
    m.job = job;
    m.u.result = (pf_msg_result_t){ .tile = tile, .attempt = attempt, .x0 = x0, .y0 = y0, .w = w, .h = h, .rgb = rgb,
                                    .render_us = 1000 };
    return m;
}

static void s_truncated(s_inj *in)
{
    static float rgb[8 * 8 * 3];
    for (size_t i = 0; i < sizeof rgb / sizeof rgb[0]; i++)
        rgb[i] = 0.25f * (float)(i % 7);
    pf_msg_t msgs[6];
    msgs[0] = s_hello("inject-truncated");
    msgs[1] = s_result(1, 0, 0, 0, 0, 8, 8, rgb);
    memset(&msgs[2], 0, sizeof msgs[2]);
    msgs[2].type = PF_MSG_HEARTBEAT;
    msgs[2].u.heartbeat = (pf_msg_heartbeat_t){ 12345, 2 };
    memset(&msgs[3], 0, sizeof msgs[3]);
    msgs[3].type = PF_MSG_READY;
    msgs[3].u.ready.credit = 4;
    memset(&msgs[4], 0, sizeof msgs[4]);
    msgs[4].type = PF_MSG_BLOB_REQ;
    msgs[4].u.blob_req = (pf_msg_blob_req_t){ 0x1234, 0, 4 };
    memset(&msgs[5], 0, sizeof msgs[5]);
    msgs[5].type = PF_MSG_BYE;
    snprintf(msgs[5].u.bye.reason, sizeof msgs[5].u.bye.reason, "truncated");
    pf_buf_t buf = { 0 };
    for (size_t k = 0; k < sizeof msgs / sizeof msgs[0]; k++) {
        if (pf_msg_encode(&msgs[k], &buf) != 0) {
            fprintf(stderr, "pf_inject: cannot encode a %s\n", pf_msg_type_name(msgs[k].type));
            continue;
        }
        for (size_t len = 0; len < buf.len; len++)
            s_send(in, buf.data, len, 0);
    }
    pf_buf_free(&buf);
    printf("pf_inject truncated: %lu frames sent, %lu failed\n", in->sent, in->failed);
}

static void s_oversized(s_inj *in)
{
    size_t n = 3u << 20;
    uint8_t *buf = malloc(n);
    if (!buf)
        return;
    s_fill(in, buf, n);
    s_header(buf, PF_MSG_RESULT, 1);
    s_send(in, buf, n, 0);
    free(buf);
    printf("pf_inject oversized: %lu frames of %zu bytes sent, %lu failed\n", in->sent, n, in->failed);
}

static void s_multiframe(s_inj *in)
{
    pf_buf_t buf = { 0 };
    pf_msg_t hb;
    memset(&hb, 0, sizeof hb);
    hb.type = PF_MSG_HEARTBEAT;
    uint8_t junk[64];
    for (int i = 0; i < 100; i++) {
        s_fill(in, junk, sizeof junk);
        if (pf_msg_encode(&hb, &buf) != 0)
            break;
        if (i % 2 == 0) {
            if (s_send(in, buf.data, buf.len, ZMQ_SNDMORE) == 0)
                s_send(in, junk, sizeof junk, 0);
        } else {
            if (s_send(in, junk, sizeof junk, ZMQ_SNDMORE) == 0)
                s_send(in, buf.data, buf.len, 0);
        }
    }
    /* A HELLO split in two frames: neither half, nor the pair, may register. */
    pf_msg_t h = s_hello("inject-multiframe");
    if (pf_msg_encode(&h, &buf) == 0 && s_send(in, buf.data, buf.len / 2, ZMQ_SNDMORE) == 0)
        s_send(in, buf.data + buf.len / 2, buf.len - buf.len / 2, 0);
    /* And a whole HELLO followed by a second frame. */
    if (pf_msg_encode(&h, &buf) == 0 && s_send(in, buf.data, buf.len, ZMQ_SNDMORE) == 0)
        s_send(in, junk, sizeof junk, 0);
    pf_buf_free(&buf);
    printf("pf_inject multiframe: %lu two-frame messages sent, %lu failed\n", in->sent, in->failed);
}

/* Sends HELLO and waits (bounded) for the JOB; fills job. Returns 0 when a
 * JOB arrived, -1 when refused or timed out (printed). */
static int s_register(s_inj *in, const char *name, uint64_t *jobid, pf_msg_job_t *job)
{
    pf_buf_t buf = { 0 };
    pf_msg_t h = s_hello(name);
    int rc = s_send_msg(in, &h, &buf);
    pf_buf_free(&buf);
    if (rc != 0)
        return -1;
    int welcomed = 0;
    double end = pf_now() + S_JOB_WAIT_S;
    uint8_t *frame = malloc(PF_PROTO_MAX_MESSAGE);
    if (!frame)
        return -1;
    rc = -1;
    while (pf_now() < end) {
        int n = zmq_recv(in->sock, frame, PF_PROTO_MAX_MESSAGE, 0); /* RCVTIMEO bounds it */
        if (n < 0)
            continue;
        pf_msg_t m;
        char why[256];
        if ((size_t)n > PF_PROTO_MAX_MESSAGE || pf_msg_decode(frame, (size_t)n, &m, why, sizeof why) != 0)
            continue;
        if (m.type == PF_MSG_WELCOME)
            welcomed = 1;
        if (m.type == PF_MSG_REFUSE) {
            printf("pf_inject %s: refused: %s\n", name, m.u.refuse.reason);
            break;
        }
        if (m.type == PF_MSG_JOB) {
            *jobid = m.job;
            *job = m.u.job;
            rc = 0;
            break;
        }
    }
    free(frame);
    if (rc != 0 && pf_now() >= end)
        printf("pf_inject %s: no JOB within %.0f s (%s)\n", name, S_JOB_WAIT_S, welcomed ? "welcomed" : "not welcomed");
    return rc;
}

static void s_bye(s_inj *in, uint64_t jobid, const char *why)
{
    pf_buf_t buf = { 0 };
    pf_msg_t m;
    memset(&m, 0, sizeof m);
    m.type = PF_MSG_BYE;
    m.job = jobid;
    snprintf(m.u.bye.reason, sizeof m.u.bye.reason, "%s", why);
    s_send_msg(in, &m, &buf);
    pf_buf_free(&buf);
}

/* The tile rectangle the coordinator's tiling gives tile t (row-major
 * squares of tile_size, clipped at the image edge). */
static void s_tile_rect(const pf_msg_job_t *job, uint32_t t, uint32_t *x0, uint32_t *y0, uint32_t *w, uint32_t *h)
{
    uint32_t ts = job->tile_size, W = (uint32_t)job->settings.width, H = (uint32_t)job->settings.height;
    uint32_t tx = (W + ts - 1) / ts;
    *x0 = (t % tx) * ts;
    *y0 = (t / tx) * ts;
    *w = *x0 + ts <= W ? ts : W - *x0;
    *h = *y0 + ts <= H ? ts : H - *y0;
}

static uint32_t s_ntiles(const pf_msg_job_t *job)
{
    uint32_t ts = job->tile_size, W = (uint32_t)job->settings.width, H = (uint32_t)job->settings.height;
    return ((W + ts - 1) / ts) * ((H + ts - 1) / ts);
}

/* Overwrites pixel float k of an encoded RESULT (the pixels end the frame). */
static void s_patch_pixel(pf_buf_t *frame, uint32_t w, uint32_t h, size_t k, uint32_t bits)
{
    size_t npix = (size_t)w * h * 3;
    if (k < npix && frame->len >= npix * 4)
        s_put_u32(frame->data + frame->len - npix * 4 + 4 * k, bits);
}

/* Appends a copy of frame to the list. */
static int s_keep(pf_buf_t **list, size_t *n, const pf_buf_t *frame)
{
    pf_buf_t *l = realloc(*list, (*n + 1) * sizeof **list);
    if (!l)
        return -1;
    *list = l;
    l[*n].data = malloc(frame->len ? frame->len : 1);
    if (!l[*n].data)
        return -1;
    memcpy(l[*n].data, frame->data, frame->len);
    l[*n].len = l[*n].cap = frame->len;
    (*n)++;
    return 0;
}

static void s_replay(s_inj *in)
{
    uint64_t jobid = 0;
    pf_msg_job_t job;
    if (s_register(in, "inject-replay", &jobid, &job) != 0 || job.tile_size == 0)
        return;
    uint32_t nt = s_ntiles(&job);
    uint32_t n = nt < S_REPLAY_TILES ? nt : S_REPLAY_TILES;
    float *rgb = calloc((size_t)job.tile_size * job.tile_size * 3 + 3, sizeof *rgb);
    pf_buf_t *frames = NULL, buf = { 0 };
    size_t nframes = 0;
    if (!rgb)
        return;
    for (uint32_t t = 0; t < n; t++) {
        uint32_t x0, y0, w, h;
        s_tile_rect(&job, t, &x0, &y0, &w, &h);
        pf_msg_t m;
        /* A wrong size: one column more or less than the tile has. */
        uint32_t ww = w > 1 ? w - 1 : w + 1;
        m = s_result(jobid, t, 0, x0, y0, ww, h, rgb);
        if (pf_msg_encode(&m, &buf) == 0)
            s_keep(&frames, &nframes, &buf);
        /* A wrong attempt: far ahead of any lease the coordinator issued. */
        m = s_result(jobid, t, 1000 + t, x0, y0, w, h, rgb);
        if (pf_msg_encode(&m, &buf) == 0)
            s_keep(&frames, &nframes, &buf);
        /* The right tile and attempt, with a NaN, then a negative pixel. */
        m = s_result(jobid, t, 0, x0, y0, w, h, rgb);
        if (pf_msg_encode(&m, &buf) == 0) {
            s_patch_pixel(&buf, w, h, t % (w * h * 3), 0x7fc00000u);
            s_keep(&frames, &nframes, &buf);
        }
        if (pf_msg_encode(&m, &buf) == 0) {
            s_patch_pixel(&buf, w, h, (7 * t) % (w * h * 3), 0xbf800000u); /* -1.0f */
            s_keep(&frames, &nframes, &buf);
        }
        /* Another job's result for this tile. */
        m = s_result(jobid + 1, t, 0, x0, y0, w, h, rgb);
        if (pf_msg_encode(&m, &buf) == 0)
            s_keep(&frames, &nframes, &buf);
    }
    /* A tile past the end of the image's tiling. */
    pf_msg_t past = s_result(jobid, nt, 0, 0, 0, 1, 1, rgb);
    if (pf_msg_encode(&past, &buf) == 0)
        s_keep(&frames, &nframes, &buf);
    for (int round = 0; round < 2; round++)
        for (size_t i = 0; i < nframes; i++)
            s_send(in, frames[i].data, frames[i].len, 0);
    s_bye(in, jobid, "replay done");
    printf("pf_inject replay: job %llu, %u tiles, %zu crafted RESULT frames sent twice, %lu frames sent, %lu failed\n",
           (unsigned long long)jobid, nt, nframes, in->sent, in->failed);
    for (size_t i = 0; i < nframes; i++)
        free(frames[i].data);
    free(frames);
    pf_buf_free(&buf);
    free(rgb);
}

static void s_forge(s_inj *in)
{
    uint64_t jobid = 0;
    pf_msg_job_t job;
    if (s_register(in, "inject-forge", &jobid, &job) != 0 || job.tile_size == 0)
        return;
    uint32_t nt = s_ntiles(&job);
    float *rgb = calloc((size_t)job.tile_size * job.tile_size * 3, sizeof *rgb);
    pf_buf_t buf = { 0 };
    if (!rgb)
        return;
    for (uint32_t t = 0; t < nt; t++) {
        uint32_t x0, y0, w, h;
        s_tile_rect(&job, t, &x0, &y0, &w, &h);
        pf_msg_t m = s_result(jobid, t, 0, x0, y0, w, h, rgb);
        s_send_msg(in, &m, &buf);
    }
    s_bye(in, jobid, "forge done");
    printf("pf_inject forge: job %llu, %u forged RESULT frames sent, %lu frames sent, %lu failed\n",
           (unsigned long long)jobid, nt, in->sent, in->failed);
    pf_buf_free(&buf);
    free(rgb);
}

int main(int argc, char **argv)
{
    static const char *const modes[] = { "garbage", "truncated", "oversized", "replay", "multiframe", "forge" };
    static void (*const fns[])(s_inj *) = { s_garbage, s_truncated, s_oversized, s_replay, s_multiframe, s_forge };
    if (argc < 3 || argc > 4) {
        fprintf(stderr, "usage: pf_inject ENDPOINT garbage|truncated|oversized|replay|multiframe|forge [SEED]\n");
        return 2;
    }
    int mode = -1;
    for (int i = 0; i < (int)(sizeof modes / sizeof modes[0]); i++)
        if (!strcmp(argv[2], modes[i]))
            mode = i;
    if (mode < 0) {
        fprintf(stderr, "pf_inject: unknown mode '%s'\n", argv[2]);
        return 2;
    }
    s_inj in;
    memset(&in, 0, sizeof in);
    in.rng = argc == 4 ? strtoull(argv[3], NULL, 10) : 0;
    in.rng = in.rng * 0x9E3779B97F4A7C15ull + 0x853c49e6748fea9bull; /* never 0 */

    in.ctx = zmq_ctx_new();
    in.sock = in.ctx ? zmq_socket(in.ctx, ZMQ_DEALER) : NULL;
    if (!in.sock) {
        fprintf(stderr, "pf_inject: no ZeroMQ socket: %s\n", zmq_strerror(zmq_errno()));
        return 1;
    }
    int linger = S_LINGER_MS, sndto = S_SEND_TIMEOUT_MS, rcvto = 200, hwm = 100000;
    zmq_setsockopt(in.sock, ZMQ_LINGER, &linger, sizeof linger);
    zmq_setsockopt(in.sock, ZMQ_SNDTIMEO, &sndto, sizeof sndto);
    zmq_setsockopt(in.sock, ZMQ_RCVTIMEO, &rcvto, sizeof rcvto);
    zmq_setsockopt(in.sock, ZMQ_SNDHWM, &hwm, sizeof hwm);
    if (zmq_socket_monitor(in.sock, "inproc://pf_inject.monitor", ZMQ_EVENT_HANDSHAKE_SUCCEEDED) == 0) {
        in.mon = zmq_socket(in.ctx, ZMQ_PAIR);
        if (in.mon && zmq_connect(in.mon, "inproc://pf_inject.monitor") != 0) {
            zmq_close(in.mon);
            in.mon = NULL;
        }
    }
    if (zmq_connect(in.sock, argv[1]) != 0) {
        fprintf(stderr, "pf_inject: cannot connect to %s: %s\n", argv[1], zmq_strerror(zmq_errno()));
        return 2;
    }
    if (in.mon && !s_wait_connected(&in))
        printf("pf_inject %s: no connection to %s within %d ms; sending anyway\n", modes[mode], argv[1],
               S_CONNECT_WAIT_MS);
    fns[mode](&in);
    fflush(stdout);

    /* Linger (bounded) lets the queued frames leave before the context ends. */
    if (in.mon) {
        zmq_socket_monitor(in.sock, NULL, 0);
        zmq_close(in.mon);
    }
    zmq_close(in.sock);
    zmq_ctx_term(in.ctx);
    return 0;
}
