/* worker_harness.c: the test's side of a conversation with a real
 * photonfarm-worker: the child process (started with its output in a log
 * file, waited for with a deadline, killed on every path), a scripted
 * coordinator (a ROUTER on loopback that serves blobs under the worker's
 * credit window, answers ZAP requests for CURVE and keeps its heartbeats
 * going while it waits), and the job fixture: a scene, its blobs and the
 * reference tiles rendered in this process. Everything runs on the test's
 * one thread, except the renders inside pf_photon_pass. */
#include <signal.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/wait.h>
#include <unistd.h>
#include <zmq.h>

#include "accel/accel.h"
#include "base/hash.h"
#include "base/log.h"
#include "photon/mapfile.h"
#include "photon/trace.h"
#include "proto/sceneblob.h"
#include "render/render.h"

#include "load/load.h"
#include "worker_test.h"

/* ------------------------------------------------------- worker processes */

static pid_t s_child;
char wt_log_path[64];

void wt_kill_child(void)
{
    if (s_child > 0) {
        kill(s_child, SIGKILL);
        waitpid(s_child, NULL, 0);
        s_child = 0;
    }
}

void wt_on_alarm(int sig)
{
    (void)sig;
    static const char msg[] = "FAIL: overall deadline passed\n0 passed, 1 failed\n";
    if (s_child > 0) {
        kill(s_child, SIGKILL);
        waitpid(s_child, NULL, 0);
    }
    ssize_t w = write(STDOUT_FILENO, msg, sizeof msg - 1);
    (void)w;
    _exit(1);
}

/* Starts the worker with its output in a fresh log file. */
pid_t wt_start_worker(const char *exe, const char *const *args)
{
    snprintf(wt_log_path, sizeof wt_log_path, "/tmp/pf_test_worker_XXXXXX");
    int fd = mkstemp(wt_log_path);
    if (fd < 0)
        return -1;
    const char *argv[32];
    int n = 0;
    argv[n++] = exe;
    for (int i = 0; args[i] && n < 31; i++)
        argv[n++] = args[i];
    argv[n] = NULL;
    fflush(stdout);
    pid_t pid = fork();
    if (pid == 0) {
        dup2(fd, STDOUT_FILENO);
        dup2(fd, STDERR_FILENO);
        close(fd);
        execv(exe, (char *const *)argv);
        _exit(127);
    }
    close(fd);
    s_child = pid;
    return pid;
}

/* Waits for the child to exit: its exit code, or -1 (timeout; the child is
 * killed), or -2 (killed by a signal). */
int wt_wait_worker(double timeout_s)
{
    double end = pf_now() + timeout_s;
    while (s_child > 0) {
        int st;
        pid_t r = waitpid(s_child, &st, WNOHANG);
        if (r == s_child) {
            s_child = 0;
            return WIFEXITED(st) ? WEXITSTATUS(st) : -2;
        }
        if (pf_now() > end) {
            wt_kill_child();
            return -1;
        }
        usleep(20000);
    }
    return -1;
}

char *wt_read_file(const char *path)
{
    FILE *f = fopen(path, "rb");
    if (!f)
        return NULL;
    char *buf = NULL;
    size_t len = 0, cap = 0;
    char chunk[4096];
    size_t got;
    while ((got = fread(chunk, 1, sizeof chunk, f)) > 0) {
        if (len + got + 1 > cap) {
            cap = 2 * (len + got + 1);
            char *g = realloc(buf, cap);
            if (!g)
                break;
            buf = g;
        }
        memcpy(buf + len, chunk, got);
        len += got;
    }
    fclose(f);
    if (buf)
        buf[len] = '\0';
    return buf;
}

/* Ends a run: prints the worker's log when something failed, removes it. */
void wt_end_run(const char *run, int fails_before)
{
    wt_kill_child();
    if (pf_test_failures() > fails_before) {
        char *log = wt_read_file(wt_log_path);
        printf("---- worker log of run '%s' ----\n%s---- end of log ----\n", run, log ? log : "(none)\n");
        free(log);
    }
    if (!getenv("PF_TEST_KEEP_LOGS"))
        unlink(wt_log_path);
}

/* --------------------------------------------------- the scripted coordinator */

int wt_coord_open(wt_coord_t *c, const char *server_secret)
{
    memset(c, 0, sizeof *c);
    c->hb_ms = 200;
    c->heartbeats_on = 1;
    c->ctx = zmq_ctx_new();
    if (server_secret) {
        /* A ZAP handler (RFC 27) must be bound before the server socket. */
        c->zap = zmq_socket(c->ctx, ZMQ_REP);
        if (zmq_bind(c->zap, "inproc://zeromq.zap.01") != 0)
            return -1;
    }
    c->router = zmq_socket(c->ctx, ZMQ_ROUTER);
    int one = 1, linger = 0;
    zmq_setsockopt(c->router, ZMQ_ROUTER_MANDATORY, &one, sizeof one);
    zmq_setsockopt(c->router, ZMQ_LINGER, &linger, sizeof linger);
    if (server_secret) {
        zmq_setsockopt(c->router, ZMQ_CURVE_SERVER, &one, sizeof one);
        zmq_setsockopt(c->router, ZMQ_CURVE_SECRETKEY, server_secret, 41);
    }
    if (zmq_bind(c->router, "tcp://127.0.0.1:*") != 0)
        return -1;
    size_t len = sizeof c->endpoint;
    zmq_getsockopt(c->router, ZMQ_LAST_ENDPOINT, c->endpoint, &len);
    return 0;
}

void wt_coord_close(wt_coord_t *c)
{
    int linger = 0;
    if (c->zap) {
        zmq_setsockopt(c->zap, ZMQ_LINGER, &linger, sizeof linger);
        zmq_close(c->zap);
    }
    zmq_close(c->router);
    zmq_ctx_term(c->ctx);
    free(c->frame);
    memset(c, 0, sizeof *c);
}

int wt_send_raw(wt_coord_t *c, const void *data, size_t len)
{
    if (!c->have_id)
        return -1;
    if (zmq_send(c->router, c->id, c->id_len, ZMQ_SNDMORE) < 0)
        return -1;
    return zmq_send(c->router, data, len, 0) < 0 ? -1 : 0;
}

int wt_send_msg(wt_coord_t *c, const pf_msg_t *m)
{
    pf_buf_t b = { 0 };
    int rc = pf_msg_encode(m, &b);
    if (rc == 0)
        rc = wt_send_raw(c, b.data, b.len);
    pf_buf_free(&b);
    return rc;
}

int wt_send_simple(wt_coord_t *c, pf_msg_type type, uint64_t job)
{
    pf_msg_t m;
    memset(&m, 0, sizeof m);
    m.type = type;
    m.job = job;
    return wt_send_msg(c, &m);
}

void wt_send_heartbeat(wt_coord_t *c)
{
    wt_send_simple(c, PF_MSG_HEARTBEAT, 0);
    c->last_hb = pf_now();
}

static void s_serve_blob(wt_coord_t *c, const pf_msg_t *req)
{
    const pf_msg_blob_req_t *r = &req->u.blob_req;
    c->blob_reqs++;
    if (r->credit > (uint32_t)c->max_credit)
        c->max_credit = (int)r->credit;
    const wt_blobsrc_t *b = NULL;
    for (int i = 0; i < 2; i++)
        if (c->blobs[i].data && c->blobs[i].hash == r->hash)
            b = &c->blobs[i];
    CHECK(b != NULL, "BLOB_REQ for an unknown blob %016llx", (unsigned long long)r->hash);
    if (!b)
        return;
    if (b == &c->blobs[0] && r->offset == 0)
        c->blob_reqs_scene_at0++;
    for (uint32_t i = 0; i < r->credit; i++) {
        uint64_t off = r->offset + (uint64_t)i * PF_PROTO_CHUNK_SIZE;
        if (off >= b->len)
            break;
        size_t len = b->len - off < PF_PROTO_CHUNK_SIZE ? b->len - off : PF_PROTO_CHUNK_SIZE;
        uint8_t *copy = NULL;
        pf_msg_t m;
        memset(&m, 0, sizeof m);
        m.type = PF_MSG_BLOB_CHUNK;
        m.job = req->job;
        m.u.chunk.hash = b->hash;
        m.u.chunk.total = b->len;
        m.u.chunk.offset = off;
        m.u.chunk.len = (uint32_t)len;
        m.u.chunk.data = b->data + off;
        if (b == &c->blobs[0] && off == 0 && c->corrupt_scene_once) {
            c->corrupt_scene_once = 0;
            copy = malloc(len);
            memcpy(copy, b->data, len);
            copy[len / 2] ^= 0x5a;
            m.u.chunk.data = copy;
        }
        wt_send_msg(c, &m);
        free(copy);
        c->chunks_served++;
    }
}

/* Answers one ZAP request: 200 for the allowed client key, else 400. */
static void s_zap_answer(wt_coord_t *c)
{
    zmq_msg_t part[8];
    int n = 0, more = 1;
    while (more && n < 8) {
        zmq_msg_init(&part[n]);
        if (zmq_msg_recv(&part[n], c->zap, 0) < 0) {
            zmq_msg_close(&part[n]);
            break;
        }
        more = zmq_msg_more(&part[n]);
        n++;
    }
    c->zap_requests++;
    int ok = 0;
    if (n >= 7 && zmq_msg_size(&part[5]) == 5 && memcmp(zmq_msg_data(&part[5]), "CURVE", 5) == 0 &&
        zmq_msg_size(&part[6]) == 32) {
        char z85[41];
        zmq_z85_encode(z85, zmq_msg_data(&part[6]), 32);
        ok = strcmp(z85, c->allowed) == 0;
    }
    if (!ok)
        c->zap_denied++;
    zmq_send(c->zap, "1.0", 3, ZMQ_SNDMORE);
    zmq_send(c->zap, n > 1 ? zmq_msg_data(&part[1]) : "", n > 1 ? zmq_msg_size(&part[1]) : 0, ZMQ_SNDMORE);
    zmq_send(c->zap, ok ? "200" : "400", 3, ZMQ_SNDMORE);
    zmq_send(c->zap, ok ? "OK" : "not allowed", ok ? 2 : 11, ZMQ_SNDMORE);
    zmq_send(c->zap, "", 0, ZMQ_SNDMORE);
    zmq_send(c->zap, "", 0, 0);
    for (int i = 0; i < n; i++)
        zmq_msg_close(&part[i]);
}

/* The next message from the worker other than HEARTBEAT and BLOB_REQ (those
 * are recorded and served here), waiting at most timeout_s. 1 with *m, 0 on
 * timeout. Keeps sending our heartbeats while heartbeats_on. */
int wt_next(wt_coord_t *c, double timeout_s, pf_msg_t *m)
{
    double end = pf_now() + timeout_s;
    for (;;) {
        double now = pf_now();
        if (now >= end)
            return 0;
        if (c->heartbeats_on && c->have_id && now - c->last_hb >= c->hb_ms / 1000.0)
            wt_send_heartbeat(c);
        zmq_pollitem_t items[2] = { { c->router, 0, ZMQ_POLLIN, 0 }, { c->zap, 0, ZMQ_POLLIN, 0 } };
        long wait_ms = (long)((end - now) * 1000) + 1;
        if (wait_ms > 50)
            wait_ms = 50;
        if (zmq_poll(items, c->zap ? 2 : 1, wait_ms) < 0)
            continue;
        if (c->zap && (items[1].revents & ZMQ_POLLIN))
            s_zap_answer(c);
        if (!(items[0].revents & ZMQ_POLLIN))
            continue;
        zmq_msg_t id, body;
        zmq_msg_init(&id);
        zmq_msg_init(&body);
        zmq_msg_recv(&id, c->router, 0);
        int two = zmq_msg_more(&id) && zmq_msg_recv(&body, c->router, 0) >= 0 && !zmq_msg_more(&body);
        CHECK(two, "the worker sent a message of other than one frame");
        if (!two) {
            zmq_msg_close(&id);
            zmq_msg_close(&body);
            continue;
        }
        if (zmq_msg_size(&id) <= sizeof c->id) {
            c->id_len = zmq_msg_size(&id);
            memcpy(c->id, zmq_msg_data(&id), c->id_len);
            c->have_id = 1;
        }
        size_t len = zmq_msg_size(&body);
        if (len > c->frame_cap) {
            free(c->frame);
            c->frame = malloc(len);
            c->frame_cap = len;
        }
        memcpy(c->frame, zmq_msg_data(&body), len);
        zmq_msg_close(&id);
        zmq_msg_close(&body);
        char why[256] = "";
        int rc = pf_msg_decode(c->frame, len, m, why, sizeof why);
        CHECK(rc == 0, "the worker sent an undecodable message: %s", why);
        if (rc)
            continue;
        if (m->type == PF_MSG_HEARTBEAT) {
            c->worker_heartbeats++;
            c->progress = m->u.heartbeat.progress;
            c->tiles_held = m->u.heartbeat.tiles_held;
            continue;
        }
        if (m->type == PF_MSG_BLOB_REQ) {
            s_serve_blob(c, m);
            continue;
        }
        return 1;
    }
}

/* Waits for a message of one type (others fail the test). */
int wt_expect(wt_coord_t *c, pf_msg_type type, double timeout_s, pf_msg_t *m, const char *what)
{
    int got = wt_next(c, timeout_s, m);
    CHECK(got, "%s: no %s within %.0f s", what, pf_msg_type_name(type), timeout_s);
    if (!got)
        return 0;
    CHECK(m->type == type, "%s: expected %s, got %s", what, pf_msg_type_name(type), pf_msg_type_name(m->type));
    return m->type == type;
}

/* True when nothing but heartbeats and blob requests arrives for timeout_s. */
int wt_quiet(wt_coord_t *c, double timeout_s, pf_msg_t *m)
{
    return !wt_next(c, timeout_s, m);
}

void wt_send_welcome(wt_coord_t *c, uint32_t id)
{
    pf_msg_t m;
    memset(&m, 0, sizeof m);
    m.type = PF_MSG_WELCOME;
    m.u.welcome.worker_id = id;
    m.u.welcome.heartbeat_ms = c->hb_ms;
    wt_send_msg(c, &m);
    c->last_hb = pf_now();
}

void wt_send_bye(wt_coord_t *c, const char *reason)
{
    pf_msg_t m;
    memset(&m, 0, sizeof m);
    m.type = PF_MSG_BYE;
    snprintf(m.u.bye.reason, sizeof m.u.bye.reason, "%s", reason);
    wt_send_msg(c, &m);
}

/* ---------------------------------------------------------------- the job */

int wt_fixture_make(wt_fixture_t *fx)
{
    memset(fx, 0, sizeof *fx);
    pf_error_t err;
    fx->scene = pf_scene_load("scenes/cornell-spheres/scene.json", &err);
    CHECK(fx->scene != NULL, "load the scene: %s", err.msg);
    if (!fx->scene)
        return -1;
    pf_settings_t s = fx->scene->settings;
    s.width = 40; /* 3 x 2 tiles of 16, the right column and bottom row clipped */
    s.height = 28;
    s.spp = 4;
    s.gather = 4;
    s.photons = 250000; /* a map blob of about 19 MiB: more chunks than the window, so it refills */
    s.caustic_photons = 20000;
    s.threads = 2;
    s.seed = 7;
    fx->settings = s;
    fx->terms = PF_TERM_ALL;
    fx->tile = 16;
    int rc = pf_frame_open(&fx->fr, fx->scene, &err);
    CHECK(rc == PF_OK, "accel and lights: %s", err.msg);
    if (rc != PF_OK)
        return -1;
    pf_photon_stats_t stats;
    rc = pf_photon_pass(fx->scene, fx->fr.accel, fx->fr.lights, &s, &fx->fr.maps, &stats);
    CHECK(rc == 0, "photon pass: %s", pf_strerror(rc));
    if (rc)
        return -1;
    rc = pf_sceneblob_write(fx->scene, &fx->scene_blob);
    CHECK(rc == 0, "scene blob: %s", pf_strerror(rc));
    if (rc)
        return -1;
    fx->scene_hash = pf_hash_bytes(PF_HASH_INIT, fx->scene_blob.data, fx->scene_blob.len);
    rc = pf_mapfile_write(&fx->fr.maps, fx->scene_hash, pf_settings_hash(&s), &fx->maps_blob);
    CHECK(rc == 0, "map blob: %s", pf_strerror(rc));
    if (rc)
        return -1;
    fx->maps_hash = pf_hash_bytes(PF_HASH_INIT, fx->maps_blob.data, fx->maps_blob.len);
    CHECK(fx->maps_blob.len > 12 * PF_PROTO_CHUNK_SIZE, "the map blob (%zu bytes) spans more chunks than the window",
          fx->maps_blob.len);

    /* The reference: pf_render_tile in this process, tile by tile, with the
     * maps readied as a worker readies them (irradiance texels). */
    pf_frame_ready(&fx->fr);
    pf_render_ctx_t ctx;
    pf_render_ctx_init(&ctx, &fx->fr, &s);
    ctx.terms = fx->terms;
    size_t W = (size_t)s.width, H = (size_t)s.height;
    fx->ref = malloc(W * H * 3 * sizeof(float));
    float *buf = malloc((size_t)fx->tile * (size_t)fx->tile * 3 * sizeof(float));
    pf_accel_thread_init();
    for (int y0 = 0; y0 < s.height; y0 += fx->tile)
        for (int x0 = 0; x0 < s.width; x0 += fx->tile) {
            int w = x0 + fx->tile <= s.width ? fx->tile : s.width - x0;
            int h = y0 + fx->tile <= s.height ? fx->tile : s.height - y0;
            pf_render_tile(&ctx, x0, y0, w, h, buf);
            for (int y = 0; y < h; y++)
                memcpy(&fx->ref[3 * ((size_t)(y0 + y) * W + (size_t)x0)], &buf[3 * (size_t)y * (size_t)w],
                       (size_t)w * 3 * sizeof(float));
        }
    free(buf);
    return 0;
}

void wt_fixture_free(wt_fixture_t *fx)
{
    pf_buf_free(&fx->scene_blob);
    pf_buf_free(&fx->maps_blob);
    pf_frame_close(&fx->fr);
    pf_scene_destroy(&fx->scene);
    free(fx->ref);
}

void wt_coord_serve(wt_coord_t *c, const wt_fixture_t *fx)
{
    c->blobs[0] = (wt_blobsrc_t){ fx->scene_blob.data, fx->scene_blob.len, fx->scene_hash };
    c->blobs[1] = (wt_blobsrc_t){ fx->maps_blob.data, fx->maps_blob.len, fx->maps_hash };
}

void wt_send_job(wt_coord_t *c, const wt_fixture_t *fx, uint64_t job)
{
    pf_msg_t m;
    memset(&m, 0, sizeof m);
    m.type = PF_MSG_JOB;
    m.job = job;
    m.u.job.scene_hash = fx->scene_hash;
    m.u.job.scene_size = fx->scene_blob.len;
    m.u.job.maps_hash = fx->maps_hash;
    m.u.job.maps_size = fx->maps_blob.len;
    m.u.job.settings = fx->settings;
    m.u.job.terms = fx->terms;
    m.u.job.tile_size = (uint32_t)fx->tile;
    wt_send_msg(c, &m);
}

pf_msg_t wt_tile_msg(uint64_t job, uint32_t tile, uint32_t attempt, int x0, int y0, int w, int h)
{
    pf_msg_t m;
    memset(&m, 0, sizeof m);
    m.type = PF_MSG_TILE;
    m.job = job;
    m.u.tile = (pf_msg_tile_t){ .tile = tile, .attempt = attempt, .x0 = (uint32_t)x0, .y0 = (uint32_t)y0,
                                .w = (uint32_t)w, .h = (uint32_t)h };
    return m;
}

/* Does a RESULT carry exactly the reference pixels of its rectangle? */
int wt_result_matches(const wt_fixture_t *fx, const pf_msg_result_t *r)
{
    size_t W = (size_t)fx->settings.width;
    float *px = malloc((size_t)r->w * r->h * 3 * sizeof *px);
    pf_msg_result_pixels(r, px);
    int same = 1;
    for (uint32_t y = 0; y < r->h && same; y++)
        same = memcmp(&px[3 * (size_t)y * r->w], &fx->ref[3 * ((size_t)(r->y0 + y) * W + r->x0)],
                      (size_t)r->w * 3 * sizeof(float)) == 0;
    free(px);
    return same;
}

/* Leases every tile with `credit` in flight and checks every RESULT bit for
 * bit. Returns the number of tiles that came back identical. */
int wt_render_all(wt_coord_t *c, const wt_fixture_t *fx, uint64_t job, uint32_t credit, const char *what)
{
    int W = fx->settings.width, H = fx->settings.height, T = fx->tile;
    int tx = (W + T - 1) / T, ty = (H + T - 1) / T, total = tx * ty;
    int next = 0, done = 0, identical = 0, outstanding = 0;
    char *seen = calloc((size_t)total, 1);
    double end = pf_now() + 90;
    while (done < total && pf_now() < end) {
        while (next < total && outstanding < (int)credit) {
            int x0 = (next % tx) * T, y0 = (next / tx) * T;
            pf_msg_t m = wt_tile_msg(job, (uint32_t)next, 1, x0, y0, x0 + T <= W ? T : W - x0,
                                     y0 + T <= H ? T : H - y0);
            wt_send_msg(c, &m);
            next++, outstanding++;
        }
        pf_msg_t m;
        if (!wt_next(c, end - pf_now(), &m))
            break;
        CHECK(m.type == PF_MSG_RESULT, "%s: expected RESULT, got %s", what, pf_msg_type_name(m.type));
        if (m.type != PF_MSG_RESULT)
            continue;
        const pf_msg_result_t *r = &m.u.result;
        int t = (int)r->tile;
        int ok = m.job == job && t >= 0 && t < total && !seen[t] && r->attempt == 1;
        CHECK(ok, "%s: RESULT for job %llu tile %d attempt %u unexpected", what, (unsigned long long)m.job, t,
              r->attempt);
        if (!ok)
            continue;
        int x0 = (t % tx) * T, y0 = (t / tx) * T;
        CHECK(r->x0 == (uint32_t)x0 && r->y0 == (uint32_t)y0 && r->w == (uint32_t)(x0 + T <= W ? T : W - x0) &&
                  r->h == (uint32_t)(y0 + T <= H ? T : H - y0),
              "%s: tile %d rectangle", what, t);
        int same = wt_result_matches(fx, r);
        CHECK(same, "%s: tile %d differs from the in-process render", what, t);
        identical += same;
        seen[t] = 1;
        done++, outstanding--;
    }
    CHECK(done == total, "%s: %d of %d tiles came back", what, done, total);
    free(seen);
    return identical;
}
