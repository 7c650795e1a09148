/* test_worker.c: the worker side of the farm, in two ctests chosen by argv[1]:
 *
 *   keyfile    base/keyfile: write/read round trips, 0600 on secret files,
 *              public-only files, allowed-key lists (bare and `public-key =`
 *              lines, comments, a key that starts with '#'), and malformed
 *              files whose errors must name file and line.
 *   protocol   a real photonfarm-worker process (argv[2]) against a scripted
 *              coordinator here (a ROUTER on tcp://127.0.0.1, ephemeral port):
 *              HELLO fields; a JOB whose scene arrives corrupted once (the
 *              worker must fetch it again) and whose map blob spans many
 *              chunks (credit window); every tile bit-identical to
 *              pf_render_tile in this process; garbage, truncated, foreign-
 *              version, multi-frame, wrong-job and out-of-image frames dropped
 *              while the worker keeps serving; the progress counter in its
 *              heartbeats; a second JOB with the same blobs transferring
 *              nothing; the same blobs under another seed rejected (the maps
 *              were made for other settings); BYE with --exit-on-bye
 *              (exit 0); BYE without it and a silent coordinator
 *              (re-registration), but not after the worker itself was
 *              stopped (SIGSTOP/SIGCONT); SIGTERM (BYE "signal",
 *              exit 0); REFUSE of a --fake-protocol worker (exit 3 with the
 *              reason); CURVE with a ZAP handler here that admits one key
 *              (the worker registers) and refuses another (exit 3); usage
 *              errors (exit 2, or 1 for unreadable key files).
 *
 * Every wait is bounded by zmq_poll timeouts and an overall alarm; the child
 * is killed and reaped on every path. */
#include <errno.h>
#include <fcntl.h>
#include <math.h>
#include <signal.h>
#include <stdarg.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/stat.h>
#include <sys/wait.h>
#include <time.h>
#include <unistd.h>
#include <zmq.h>

#include "accel/accel.h"
#include "base/hash.h"
#include "base/keyfile.h"
#include "light/light.h"
#include "base/log.h"
#include "photon/photonmap.h"
#include "scene/scene.h"
#include "photon/trace.h"
#include "photon/mapfile.h"
#include "proto/messages.h"
#include "proto/sceneblob.h"
#include "render/render.h"

#include "check.h"
#include "load/load.h"
#include "render/frame.h"


/* ------------------------------------------------------------------ keyfile */

static void s_write_text(const char *path, const char *text)
{
    FILE *f = fopen(path, "w");
    if (f) {
        fputs(text, f);
        fclose(f);
    }
}

/* The error names the file and this line ("path:line: ..."). */
static int s_names_line(const pf_error_t *err, const char *path, int line)
{
    char want[700];
    snprintf(want, sizeof want, "%.600s:%d: ", path, line);
    return strncmp(err->msg, want, strlen(want)) == 0;
}

static void s_test_keyfile(void)
{
    char dir[] = "/tmp/pf_keyfile_XXXXXX";
    if (!mkdtemp(dir)) {
        CHECK(0, "mkdtemp: %s", strerror(errno));
        return;
    }
    char pair[600], pub[600], bad[600], list[600];
    snprintf(pair, sizeof pair, "%s/worker.key", dir);
    snprintf(pub, sizeof pub, "%s/worker.pub", dir);
    snprintf(bad, sizeof bad, "%s/bad.key", dir);
    snprintf(list, sizeof list, "%s/allowed.txt", dir);
    const char *P = "Yne@$w-vo<fVvi]a<NY6T1ed:M$fCG*[IaLV{hID";
    const char *S = "D:)Q[IlAW!ahhC2ac:9*A}h:p?([4%wOTJ%JR%cs";
    const char *H = "#bcdefghij0123456789ABCDEFGHIJ.-:+=^!/*?"; /* a key starting with '#' */
    pf_error_t err;
    char p[41], s[41];

    CHECK(pf_z85_key_valid(P) && pf_z85_key_valid(S) && pf_z85_key_valid(H), "valid keys accepted");
    CHECK(!pf_z85_key_valid("short") && !pf_z85_key_valid("Yne@$w-vo<fVvi]a<NY6T1ed:M$fCG*[IaLV{hI~") &&
              !pf_z85_key_valid("Yne@$w-vo<fVvi]a<NY6T1ed:M$fCG*[IaLV{hIDx"),
          "short, foreign-alphabet and long keys rejected");

    /* Round trips. */
    CHECK(pf_keyfile_write(pair, P, S, &err) == 0, "write pair: %s", err.msg);
    struct stat st;
    CHECK(stat(pair, &st) == 0 && (st.st_mode & 0777) == 0600, "secret file mode %o", (unsigned)(st.st_mode & 0777));
    memset(p, 0, sizeof p), memset(s, 0, sizeof s);
    CHECK(pf_keyfile_read(pair, p, s, &err) == 0 && strcmp(p, P) == 0 && strcmp(s, S) == 0, "read pair: %s", err.msg);
    CHECK(pf_keyfile_read(pair, p, NULL, &err) == 0 && strcmp(p, P) == 0, "public from a pair file");
    CHECK(pf_keyfile_write(pub, P, NULL, &err) == 0, "write public: %s", err.msg);
    CHECK(pf_keyfile_read(pub, p, NULL, &err) == 0 && strcmp(p, P) == 0, "read public: %s", err.msg);
    CHECK(pf_keyfile_read(pub, p, s, &err) == PF_EPARSE && strstr(err.msg, "no secret-key") != NULL,
          "a secret requested from a public file: %s", err.msg);
    /* An existing world-readable file is narrowed to 0600 when it gets a secret. */
    chmod(pub, 0644);
    CHECK(pf_keyfile_write(pub, P, S, &err) == 0 && stat(pub, &st) == 0 && (st.st_mode & 0777) == 0600,
          "rewritten secret file mode %o", (unsigned)(st.st_mode & 0777));
    CHECK(pf_keyfile_write(pair, "not a key", S, &err) == PF_EINVAL, "writing an invalid key refused");
    CHECK(pf_keyfile_read("/nonexistent/pf.key", p, NULL, &err) == PF_EIO &&
              strstr(err.msg, "/nonexistent/pf.key") != NULL,
          "missing file: %s", err.msg);

    /* Comments, blanks, CRLF and spaces are fine. */
    char text[1024];
    snprintf(text, sizeof text, "# comment\r\n\n   public-key=%s  \r\n\tsecret-key =  %s\n", P, S);
    s_write_text(bad, text);
    CHECK(pf_keyfile_read(bad, p, s, &err) == 0 && strcmp(p, P) == 0 && strcmp(s, S) == 0, "lenient layout: %s",
          err.msg);

    /* Malformed key files: the error names file and line. */
    struct {
        const char *text;
        int line;
        const char *what;
    } cases[] = {
        { "# c\npublic-key = tooshort\n", 2, "Z85" },
        { "public-key = %P\nsecret-key = %P~\n", 2, "Z85" },
        { "\n\nprivate-key = %P\n", 3, "unknown entry" },
        { "public-key = %P\npublic-key = %P\n", 2, "second" },
        { "# c\n%P\n", 2, "expected" },
        { "public-key %P\n", 1, "expected" },
    };
    for (size_t i = 0; i < sizeof cases / sizeof cases[0]; i++) {
        /* %P stands for the valid public key. */
        char buf[1024] = "";
        for (const char *c = cases[i].text; *c; c++) {
            if (c[0] == '%' && c[1] == 'P') {
                strcat(buf, P);
                c++;
            } else {
                size_t n = strlen(buf);
                buf[n] = *c;
                buf[n + 1] = '\0';
            }
        }
        s_write_text(bad, buf);
        memset(&err, 0, sizeof err);
        int rc = pf_keyfile_read(bad, p, s, &err);
        CHECK(rc == PF_EPARSE && s_names_line(&err, bad, cases[i].line) && strstr(err.msg, cases[i].what),
              "malformed key file %zu: rc %d, '%s'", i, rc, err.msg);
    }
    s_write_text(bad, "# only a comment\n");
    CHECK(pf_keyfile_read(bad, p, NULL, &err) == PF_EPARSE && strstr(err.msg, "no public-key"), "empty key file: %s",
          err.msg);
    /* A NUL byte inside a line. */
    FILE *f = fopen(bad, "w");
    if (f) {
        fputs("public-key = ", f);
        fputc(0, f);
        fputs(P, f);
        fputc('\n', f);
        fclose(f);
    }
    CHECK(pf_keyfile_read(bad, p, NULL, &err) == PF_EPARSE && s_names_line(&err, bad, 1), "NUL byte: %s", err.msg);

    /* Allowed-key lists. */
    char(*keys)[41] = NULL;
    size_t n = 99;
    snprintf(text, sizeof text, "# allowed workers\n\n%s\npublic-key = %s\n  %s  \n# another comment with = sign\n",
             P, S, H);
    s_write_text(list, text);
    CHECK(pf_keyfile_read_list(list, &keys, &n, &err) == 0 && n == 3, "list: n %zu, %s", n, err.msg);
    if (keys && n == 3)
        CHECK(strcmp(keys[0], P) == 0 && strcmp(keys[1], S) == 0 && strcmp(keys[2], H) == 0, "list contents");
    free(keys);
    s_write_text(list, "# nobody\n\n");
    keys = (void *)1;
    CHECK(pf_keyfile_read_list(list, &keys, &n, &err) == 0 && n == 0 && keys == NULL, "empty list");
    snprintf(text, sizeof text, "%s\n\n%s\n", P, "Yne@$w-vo<fVvi]a<NY6T1ed:M$fCG*[IaLV{h");
    s_write_text(list, text);
    keys = NULL;
    CHECK(pf_keyfile_read_list(list, &keys, &n, &err) == PF_EPARSE && s_names_line(&err, list, 3) && keys == NULL,
          "short key in a list: %s", err.msg);
    snprintf(text, sizeof text, "%s\nsecret-key = %s\n", P, S);
    s_write_text(list, text);
    CHECK(pf_keyfile_read_list(list, &keys, &n, &err) == PF_EPARSE && s_names_line(&err, list, 2) &&
              strstr(err.msg, "secret"),
          "secret key in a list: %s", err.msg);
    /* Many keys (the list grows). */
    f = fopen(list, "w");
    for (int i = 0; f && i < 100; i++)
        fprintf(f, "%s\n", i % 2 ? P : S);
    if (f)
        fclose(f);
    CHECK(pf_keyfile_read_list(list, &keys, &n, &err) == 0 && n == 100 && strcmp(keys[99], P) == 0, "100 keys");
    free(keys);

    unlink(pair), unlink(pub), unlink(bad), unlink(list);
    rmdir(dir);
}

/* ------------------------------------------------------- worker processes */

static pid_t s_child;
static char s_log_path[64];

static void s_kill_child(void)
{
    if (s_child > 0) {
        kill(s_child, SIGKILL);
        waitpid(s_child, NULL, 0);
        s_child = 0;
    }
}

static void s_on_alarm(int sig)
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
static pid_t s_start_worker(const char *exe, const char *const *args)
{
    snprintf(s_log_path, sizeof s_log_path, "/tmp/pf_test_worker_XXXXXX");
    int fd = mkstemp(s_log_path);
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
static int s_wait_worker(double timeout_s)
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
            s_kill_child();
            return -1;
        }
        usleep(20000);
    }
    return -1;
}

static char *s_read_file(const char *path)
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
static void s_end_run(const char *run, int fails_before)
{
    s_kill_child();
    if (s_failed > fails_before) {
        char *log = s_read_file(s_log_path);
        printf("---- worker log of run '%s' ----\n%s---- end of log ----\n", run, log ? log : "(none)\n");
        free(log);
    }
    if (!getenv("PF_TEST_KEEP_LOGS"))
        unlink(s_log_path);
}

/* --------------------------------------------------- the scripted coordinator */

typedef struct s_blobsrc {
    const uint8_t *data;
    size_t len;
    uint64_t hash;
} s_blobsrc_t;

typedef struct s_coord {
    void *ctx, *router, *zap;
    char endpoint[256];
    char allowed[41];        /* the one CURVE client key the ZAP handler admits */
    uint8_t id[256];
    size_t id_len;
    int have_id;
    uint32_t hb_ms;
    int heartbeats_on;       /* send our heartbeats while waiting */
    double last_hb;
    uint8_t *frame;          /* the last message's bytes (decoded pointers point here) */
    size_t frame_cap;
    s_blobsrc_t blobs[2];
    int corrupt_scene_once;  /* flip a byte in the first scene chunk served, once */
    int blob_reqs, blob_reqs_scene_at0, max_credit;
    uint64_t chunks_served;
    int worker_heartbeats;
    uint64_t progress;       /* from the last worker HEARTBEAT */
    uint32_t tiles_held;
    int zap_requests, zap_denied;
} s_coord_t;

static int s_coord_open(s_coord_t *c, const char *server_secret)
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

static void s_coord_close(s_coord_t *c)
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

static int s_send_raw(s_coord_t *c, const void *data, size_t len)
{
    if (!c->have_id)
        return -1;
    if (zmq_send(c->router, c->id, c->id_len, ZMQ_SNDMORE) < 0)
        return -1;
    return zmq_send(c->router, data, len, 0) < 0 ? -1 : 0;
}

static int s_send_msg(s_coord_t *c, const pf_msg_t *m)
{
    pf_buf_t b = { 0 };
    int rc = pf_msg_encode(m, &b);
    if (rc == 0)
        rc = s_send_raw(c, b.data, b.len);
    pf_buf_free(&b);
    return rc;
}

static int s_send_simple(s_coord_t *c, pf_msg_type type, uint64_t job)
{
    pf_msg_t m;
    memset(&m, 0, sizeof m);
    m.type = type;
    m.job = job;
    return s_send_msg(c, &m);
}

static void s_send_heartbeat(s_coord_t *c)
{
    s_send_simple(c, PF_MSG_HEARTBEAT, 0);
    c->last_hb = pf_now();
}

static void s_serve_blob(s_coord_t *c, const pf_msg_t *req)
{
    const pf_msg_blob_req_t *r = &req->u.blob_req;
    c->blob_reqs++;
    if (r->credit > (uint32_t)c->max_credit)
        c->max_credit = (int)r->credit;
    const s_blobsrc_t *b = NULL;
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
        s_send_msg(c, &m);
        free(copy);
        c->chunks_served++;
    }
}

/* Answers one ZAP request: 200 for the allowed client key, else 400. */
static void s_zap_answer(s_coord_t *c)
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
static int s_next(s_coord_t *c, double timeout_s, pf_msg_t *m)
{
    double end = pf_now() + timeout_s;
    for (;;) {
        double now = pf_now();
        if (now >= end)
            return 0;
        if (c->heartbeats_on && c->have_id && now - c->last_hb >= c->hb_ms / 1000.0)
            s_send_heartbeat(c);
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
static int s_expect(s_coord_t *c, pf_msg_type type, double timeout_s, pf_msg_t *m, const char *what)
{
    int got = s_next(c, timeout_s, m);
    CHECK(got, "%s: no %s within %.0f s", what, pf_msg_type_name(type), timeout_s);
    if (!got)
        return 0;
    CHECK(m->type == type, "%s: expected %s, got %s", what, pf_msg_type_name(type), pf_msg_type_name(m->type));
    return m->type == type;
}

/* True when nothing but heartbeats and blob requests arrives for timeout_s. */
static int s_quiet(s_coord_t *c, double timeout_s, pf_msg_t *m)
{
    return !s_next(c, timeout_s, m);
}

static void s_send_welcome(s_coord_t *c, uint32_t id)
{
    pf_msg_t m;
    memset(&m, 0, sizeof m);
    m.type = PF_MSG_WELCOME;
    m.u.welcome.worker_id = id;
    m.u.welcome.heartbeat_ms = c->hb_ms;
    s_send_msg(c, &m);
    c->last_hb = pf_now();
}

static void s_send_bye(s_coord_t *c, const char *reason)
{
    pf_msg_t m;
    memset(&m, 0, sizeof m);
    m.type = PF_MSG_BYE;
    snprintf(m.u.bye.reason, sizeof m.u.bye.reason, "%s", reason);
    s_send_msg(c, &m);
}

/* ---------------------------------------------------------------- the job */

typedef struct s_fixture {
    pf_scene_t *scene;
    pf_frame_t fr; /* scene's accel, lights, maps and texels */
    pf_settings_t settings;
    unsigned terms;
    int tile;
    pf_buf_t scene_blob, maps_blob;
    uint64_t scene_hash, maps_hash;
    float *ref; /* the in-process image, W*H*3 */
} s_fixture_t;

static int s_fixture_make(s_fixture_t *fx)
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

static void s_fixture_free(s_fixture_t *fx)
{
    pf_buf_free(&fx->scene_blob);
    pf_buf_free(&fx->maps_blob);
    pf_frame_close(&fx->fr);
    pf_scene_destroy(&fx->scene);
    free(fx->ref);
}

static void s_coord_serve(s_coord_t *c, const s_fixture_t *fx)
{
    c->blobs[0] = (s_blobsrc_t){ fx->scene_blob.data, fx->scene_blob.len, fx->scene_hash };
    c->blobs[1] = (s_blobsrc_t){ fx->maps_blob.data, fx->maps_blob.len, fx->maps_hash };
}

static void s_send_job(s_coord_t *c, const s_fixture_t *fx, uint64_t job)
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
    s_send_msg(c, &m);
}

static pf_msg_t s_tile_msg(uint64_t job, uint32_t tile, uint32_t attempt, int x0, int y0, int w, int h)
{
    pf_msg_t m;
    memset(&m, 0, sizeof m);
    m.type = PF_MSG_TILE;
    m.job = job;
    m.u.tile = (pf_msg_tile_t){ tile, attempt, (uint32_t)x0, (uint32_t)y0, (uint32_t)w, (uint32_t)h };
    return m;
}

/* Does a RESULT carry exactly the reference pixels of its rectangle? */
static int s_result_matches(const s_fixture_t *fx, const pf_msg_result_t *r)
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
static int s_render_all(s_coord_t *c, const s_fixture_t *fx, uint64_t job, uint32_t credit, const char *what)
{
    int W = fx->settings.width, H = fx->settings.height, T = fx->tile;
    int tx = (W + T - 1) / T, ty = (H + T - 1) / T, total = tx * ty;
    int next = 0, done = 0, identical = 0, outstanding = 0;
    char *seen = calloc((size_t)total, 1);
    double end = pf_now() + 90;
    while (done < total && pf_now() < end) {
        while (next < total && outstanding < (int)credit) {
            int x0 = (next % tx) * T, y0 = (next / tx) * T;
            pf_msg_t m = s_tile_msg(job, (uint32_t)next, 1, x0, y0, x0 + T <= W ? T : W - x0, y0 + T <= H ? T : H - y0);
            s_send_msg(c, &m);
            next++, outstanding++;
        }
        pf_msg_t m;
        if (!s_next(c, end - pf_now(), &m))
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
        int same = s_result_matches(fx, r);
        CHECK(same, "%s: tile %d differs from the in-process render", what, t);
        identical += same;
        seen[t] = 1;
        done++, outstanding--;
    }
    CHECK(done == total, "%s: %d of %d tiles came back", what, done, total);
    free(seen);
    return identical;
}

/* Run A: the whole conversation with --exit-on-bye. */
static void s_run_render(const char *exe, const s_fixture_t *fx)
{
    int fails = s_failed;
    s_coord_t c;
    if (s_coord_open(&c, NULL)) {
        CHECK(0, "cannot bind the test coordinator");
        return;
    }
    s_coord_serve(&c, fx);
    const char *args[] = { "--connect", c.endpoint, "--threads", "2", "--name", "test-worker", "--exit-on-bye", "-v",
                           NULL };
    s_start_worker(exe, args);
    pf_msg_t m;
    if (!s_expect(&c, PF_MSG_HELLO, 15, &m, "render run"))
        goto out;
    pf_fingerprint_t fp = pf_frame_fingerprint();
    CHECK(m.u.hello.fp.protocol == PF_PROTO_VERSION && m.u.hello.fp.photon_size == fp.photon_size &&
              m.u.hello.fp.float_size == fp.float_size && m.u.hello.fp.map_version == fp.map_version &&
              strcmp(m.u.hello.fp.git, fp.git) == 0,
          "HELLO carries this build's fingerprint");
    CHECK(m.u.hello.threads == 2, "HELLO threads %u", m.u.hello.threads);
    CHECK(strcmp(m.u.hello.name, "test-worker") == 0, "HELLO name '%s'", m.u.hello.name);
    s_send_welcome(&c, 7);

    /* Job 1: the scene's first chunk arrives corrupted once. */
    c.corrupt_scene_once = 1;
    s_send_job(&c, fx, 1);
    if (!s_expect(&c, PF_MSG_READY, 60, &m, "job 1"))
        goto out;
    CHECK(m.job == 1 && m.u.ready.credit >= 2, "READY for job 1 with credit %u", m.u.ready.credit);
    uint32_t credit = m.u.ready.credit;
    CHECK(c.blob_reqs_scene_at0 == 2, "the corrupted scene was requested again (%d requests at offset 0)",
          c.blob_reqs_scene_at0);
    uint64_t chunks = (fx->scene_blob.len + PF_PROTO_CHUNK_SIZE - 1) / PF_PROTO_CHUNK_SIZE * 2 +
                      (fx->maps_blob.len + PF_PROTO_CHUNK_SIZE - 1) / PF_PROTO_CHUNK_SIZE;
    CHECK(c.chunks_served == chunks, "%llu chunks served, expected %llu (no chunk twice)",
          (unsigned long long)c.chunks_served, (unsigned long long)chunks);
    CHECK(c.max_credit >= 2 && c.max_credit <= 8, "credit window %d chunks", c.max_credit);
    CHECK(c.blob_reqs > 3, "the window was refilled (%d BLOB_REQs)", c.blob_reqs);
    int W = fx->settings.width, H = fx->settings.height, T = fx->tile;
    int total = ((W + T - 1) / T) * ((H + T - 1) / T);
    int same = s_render_all(&c, fx, 1, credit, "job 1");
    CHECK(same == total, "job 1: %d of %d tiles bit-identical", same, total);

    /* Garbage: each is dropped and the worker keeps serving. */
    uint8_t junk[64];
    srand(12345);
    for (size_t i = 0; i < sizeof junk; i++)
        junk[i] = (uint8_t)rand();
    s_send_raw(&c, junk, sizeof junk);
    s_send_raw(&c, "", 0);
    pf_msg_t tm = s_tile_msg(1, 0, 9, 0, 0, 16, 16);
    pf_buf_t b = { 0 };
    pf_msg_encode(&tm, &b);
    s_send_raw(&c, b.data, b.len - 3);                   /* truncated TILE */
    b.data[4] = 9;                                       /* another protocol version */
    s_send_raw(&c, b.data, b.len);
    b.data[4] = PF_PROTO_VERSION;
    zmq_send(c.router, c.id, c.id_len, ZMQ_SNDMORE);     /* two frames */
    zmq_send(c.router, b.data, b.len, ZMQ_SNDMORE);
    zmq_send(c.router, b.data, b.len, 0);
    pf_buf_free(&b);
    tm = s_tile_msg(99, 0, 9, 0, 0, 16, 16);             /* another job */
    s_send_msg(&c, &tm);
    tm = s_tile_msg(1, 5, 9, 32, 16, 16, 12);            /* runs past the right edge */
    s_send_msg(&c, &tm);
    tm = s_tile_msg(1, 5, 9, 0, 20, 8, 12);              /* runs past the bottom */
    s_send_msg(&c, &tm);
    CHECK(s_quiet(&c, 1.0, &m), "garbage answered with %s", pf_msg_type_name(m.type));
    tm = s_tile_msg(1, 3, 2, 0, 16, 16, 12);             /* a valid re-lease */
    s_send_msg(&c, &tm);
    if (s_expect(&c, PF_MSG_RESULT, 30, &m, "after garbage"))
        CHECK(m.job == 1 && m.u.result.tile == 3 && m.u.result.attempt == 2 && s_result_matches(fx, &m.u.result),
              "the worker still serves after garbage (tile %u attempt %u)", m.u.result.tile, m.u.result.attempt);
    /* The heartbeat's progress counts every pixel rendered. */
    uint64_t want = (uint64_t)W * (uint64_t)H + 16 * 12;
    double end = pf_now() + 3;
    while ((c.progress != want || c.tiles_held != 0) && pf_now() < end)
        s_next(&c, 0.1, &m);
    CHECK(c.progress == want && c.tiles_held == 0, "heartbeat progress %llu (want %llu), tiles held %u",
          (unsigned long long)c.progress, (unsigned long long)want, c.tiles_held);
    CHECK(c.worker_heartbeats >= 3, "%d worker heartbeats", c.worker_heartbeats);

    /* Job 2, same scene and maps: nothing transferred, nothing rebuilt. */
    s_send_simple(&c, PF_MSG_JOB_END, 1);
    tm = s_tile_msg(1, 0, 3, 0, 0, 16, 16);              /* job 1 is over */
    s_send_msg(&c, &tm);
    c.blob_reqs = 0;
    s_send_job(&c, fx, 2);
    double t0 = pf_now();
    if (s_expect(&c, PF_MSG_READY, 20, &m, "job 2")) {
        CHECK(m.job == 2, "READY for job %llu", (unsigned long long)m.job);
        CHECK(c.blob_reqs == 0, "job 2 with the same blobs sent %d BLOB_REQs", c.blob_reqs);
        CHECK(pf_now() - t0 < 2.0, "job 2 was ready in %.2f s (built structures reused)", pf_now() - t0);
        same = s_render_all(&c, fx, 2, credit, "job 2");
        CHECK(same == total, "job 2: %d of %d tiles bit-identical", same, total);
    }
    /* A tile and its job's end back to back: no RESULT is owed afterwards. */
    tm = s_tile_msg(2, 0, 4, 0, 0, 16, 16);
    s_send_msg(&c, &tm);
    s_send_simple(&c, PF_MSG_JOB_END, 2);
    while (s_next(&c, 1.0, &m))
        CHECK(m.type == PF_MSG_RESULT && m.job == 2, "after JOB_END: %s", pf_msg_type_name(m.type));

    /* Job 3 names the same blobs with another seed: the maps were made for
     * other settings, so the worker must reject them (no READY) rather than
     * reuse what it built for jobs 1 and 2. Job 4 is fine again. */
    c.blob_reqs = 0;
    s_fixture_t other = *fx;
    other.settings.seed += 1;
    s_send_job(&c, &other, 3);
    CHECK(s_quiet(&c, 2.0, &m), "job 3 with foreign maps answered with %s", pf_msg_type_name(m.type));
    tm = s_tile_msg(3, 0, 1, 0, 0, 16, 16);
    s_send_msg(&c, &tm);
    CHECK(s_quiet(&c, 0.5, &m), "a tile of the rejected job 3 answered with %s", pf_msg_type_name(m.type));
    s_send_simple(&c, PF_MSG_JOB_END, 3);
    s_send_job(&c, fx, 4);
    if (s_expect(&c, PF_MSG_READY, 20, &m, "job 4"))
        CHECK(m.job == 4, "READY for job %llu", (unsigned long long)m.job);
    CHECK(c.blob_reqs == 0, "jobs 3 and 4 sent %d BLOB_REQs", c.blob_reqs);
    tm = s_tile_msg(4, 1, 1, 16, 0, 16, 16);
    s_send_msg(&c, &tm);
    if (s_expect(&c, PF_MSG_RESULT, 30, &m, "job 4"))
        CHECK(m.job == 4 && m.u.result.tile == 1 && s_result_matches(fx, &m.u.result), "job 4 tile 1 identical");

    s_send_bye(&c, "test over");
    int code = s_wait_worker(10);
    CHECK(code == 0, "BYE with --exit-on-bye: exit code %d", code);
    char *log = s_read_file(s_log_path);
    CHECK(log && strstr(log, "job 3: photon-map blob") && strstr(log, "taking no tiles"),
          "the worker logs why it rejects job 3");
    free(log);
out:
    s_end_run("render", fails);
    s_coord_close(&c);
}

/* Run B: long-lived worker: BYE, a silent coordinator, SIGTERM. */
static void s_run_reconnect(const char *exe)
{
    int fails = s_failed;
    s_coord_t c;
    if (s_coord_open(&c, NULL)) {
        CHECK(0, "cannot bind the test coordinator");
        return;
    }
    const char *args[] = { "--connect", c.endpoint, "--threads", "1", "-v", NULL };
    pid_t pid = s_start_worker(exe, args);
    pf_msg_t m;
    if (!s_expect(&c, PF_MSG_HELLO, 15, &m, "reconnect run"))
        goto out;
    CHECK(strchr(m.u.hello.name, ':') != NULL, "default name host:pid, got '%s'", m.u.hello.name);
    s_send_welcome(&c, 1);
    CHECK(s_quiet(&c, 0.5, &m), "idle worker sent %s", pf_msg_type_name(m.type));
    s_send_bye(&c, "coordinator restarting");
    double t0 = pf_now();
    if (!s_expect(&c, PF_MSG_HELLO, 10, &m, "after BYE"))
        goto out;
    double dt = pf_now() - t0;
    CHECK(dt > 0.7 && dt < 4, "a new HELLO %.2f s after BYE (backoff 1 s)", dt);
    s_send_welcome(&c, 2);
    /* Go silent: after 5 heartbeat intervals (1 s) the worker gives up on us
     * and registers again after its backoff. */
    c.heartbeats_on = 0;
    t0 = pf_now();
    if (!s_expect(&c, PF_MSG_HELLO, 10, &m, "after silence"))
        goto out;
    dt = pf_now() - t0;
    CHECK(dt > 1.5 && dt < 5, "a new HELLO %.2f s after the coordinator went silent", dt);
    c.heartbeats_on = 1;
    s_send_welcome(&c, 3);
    CHECK(s_quiet(&c, 0.5, &m), "registered worker sent %s", pf_msg_type_name(m.type));
    /* A worker that was itself stopped does not blame the coordinator for
     * the silence: stopped for 2 s while we say nothing, it must carry on
     * once we speak again rather than register anew. */
    c.heartbeats_on = 0;
    kill(pid, SIGSTOP);
    CHECK(s_quiet(&c, 2.0, &m), "a stopped worker sent %s", pf_msg_type_name(m.type));
    kill(pid, SIGCONT);
    c.heartbeats_on = 1;
    s_send_heartbeat(&c);
    CHECK(s_quiet(&c, 1.5, &m), "after SIGCONT the worker sent %s (registering again?)", pf_msg_type_name(m.type));
    kill(pid, SIGTERM);
    if (s_expect(&c, PF_MSG_BYE, 5, &m, "SIGTERM"))
        CHECK(strcmp(m.u.bye.reason, "signal") == 0, "BYE reason '%s'", m.u.bye.reason);
    int code = s_wait_worker(10);
    CHECK(code == 0, "SIGTERM: exit code %d", code);
out:
    s_end_run("reconnect", fails);
    s_coord_close(&c);
}

/* Run B2: an --exit-on-bye worker whose coordinator goes away without a
 * goodbye (it was stopped or cut off when the BYE went out) tries to reach
 * it once more, then exits 0 instead of waiting forever; before any
 * coordinator has welcomed it, the same worker keeps trying. */
static void s_run_gone(const char *exe)
{
    int fails = s_failed;
    s_coord_t c;
    if (s_coord_open(&c, NULL)) {
        CHECK(0, "cannot bind the test coordinator");
        return;
    }
    const char *args[] = { "--connect", c.endpoint, "--threads", "1", "--exit-on-bye", "-v", NULL };
    s_start_worker(exe, args);
    pf_msg_t m;
    if (!s_expect(&c, PF_MSG_HELLO, 15, &m, "gone run"))
        goto out;
    /* Not welcomed: after the 5 s HELLO timeout it says HELLO again. */
    c.heartbeats_on = 0;
    if (!s_expect(&c, PF_MSG_HELLO, 10, &m, "a second HELLO before any WELCOME"))
        goto out;
    s_send_welcome(&c, 1);
    CHECK(s_quiet(&c, 0.5, &m), "idle worker sent %s", pf_msg_type_name(m.type));
    /* Now the coordinator is gone: silent, and deaf to the next HELLO. */
    double t0 = pf_now();
    if (!s_expect(&c, PF_MSG_HELLO, 10, &m, "a HELLO after the coordinator went silent"))
        goto out;
    int code = s_wait_worker(10);
    double dt = pf_now() - t0;
    CHECK(code == 0, "--exit-on-bye worker whose coordinator is gone: exit code %d after %.1f s", code, dt);
out:
    s_kill_child();
    s_end_run("gone", fails);
    s_coord_close(&c);
}

/* Run C: REFUSE ends the worker with exit code 3 and the reason. */
static void s_run_refuse(const char *exe)
{
    int fails = s_failed;
    s_coord_t c;
    if (s_coord_open(&c, NULL)) {
        CHECK(0, "cannot bind the test coordinator");
        return;
    }
    const char *args[] = { "--connect", c.endpoint, "--fake-protocol", "2", NULL };
    s_start_worker(exe, args);
    pf_msg_t m;
    if (s_expect(&c, PF_MSG_HELLO, 15, &m, "refuse run")) {
        CHECK(m.u.hello.fp.protocol == 2, "--fake-protocol 2 announces protocol %u", m.u.hello.fp.protocol);
        memset(&m, 0, sizeof m);
        m.type = PF_MSG_REFUSE;
        snprintf(m.u.refuse.reason, sizeof m.u.refuse.reason, "protocol version 2 (worker) vs 1 (coordinator)");
        s_send_msg(&c, &m);
        int code = s_wait_worker(10);
        CHECK(code == 3, "REFUSE: exit code %d", code);
        char *log = s_read_file(s_log_path);
        char want[512];
        snprintf(want, sizeof want, "photonfarm-worker: refused by %s: protocol version 2 (worker) vs 1 (coordinator)",
                 c.endpoint);
        CHECK(log && strstr(log, want), "the refusal is printed: want '%s'", want);
        free(log);
    }
    s_end_run("refuse", fails);
    s_coord_close(&c);
}

/* Runs D and E: CURVE with a ZAP handler that admits one client key. */
static void s_run_curve(const char *exe)
{
    if (!zmq_has("curve")) {
        printf("note: this libzmq has no CURVE; CURVE runs skipped\n");
        return;
    }
    char dir[] = "/tmp/pf_curve_XXXXXX";
    if (!mkdtemp(dir)) {
        CHECK(0, "mkdtemp");
        return;
    }
    char server_pub[41], server_sec[41], good_pub[41], good_sec[41], bad_pub[41], bad_sec[41];
    zmq_curve_keypair(server_pub, server_sec);
    zmq_curve_keypair(good_pub, good_sec);
    zmq_curve_keypair(bad_pub, bad_sec);
    char spath[600], gpath[600], bpath[600];
    snprintf(spath, sizeof spath, "%s/server.pub", dir);
    snprintf(gpath, sizeof gpath, "%s/good.key", dir);
    snprintf(bpath, sizeof bpath, "%s/bad.key", dir);
    pf_error_t err;
    CHECK(pf_keyfile_write(spath, server_pub, NULL, &err) == 0 && pf_keyfile_write(gpath, good_pub, good_sec, &err) == 0 &&
              pf_keyfile_write(bpath, bad_pub, bad_sec, &err) == 0,
          "key files: %s", err.msg);
    for (int run = 0; run < 2; run++) {
        int fails = s_failed;
        s_coord_t c;
        if (s_coord_open(&c, server_sec)) {
            CHECK(0, "cannot bind the CURVE test coordinator");
            break;
        }
        snprintf(c.allowed, sizeof c.allowed, "%s", good_pub);
        const char *args[] = { "--connect", c.endpoint, "--curve-key", run == 0 ? gpath : bpath,
                               "--curve-server-key", spath, "--exit-on-bye", "-v", NULL };
        s_start_worker(exe, args);
        pf_msg_t m;
        if (run == 0) {
            if (s_expect(&c, PF_MSG_HELLO, 15, &m, "CURVE, listed key")) {
                s_send_welcome(&c, 1);
                CHECK(s_quiet(&c, 0.3, &m), "CURVE worker sent %s", pf_msg_type_name(m.type));
                s_send_bye(&c, "done");
                int code = s_wait_worker(10);
                CHECK(code == 0, "CURVE, listed key: exit code %d", code);
            }
            CHECK(c.zap_requests >= 1 && c.zap_denied == 0, "ZAP: %d requests, %d denied", c.zap_requests,
                  c.zap_denied);
        } else {
            CHECK(!s_next(&c, 3, &m), "an unlisted key got a message through");
            int code = s_wait_worker(10);
            CHECK(code == 3, "CURVE, unlisted key: exit code %d", code);
            char *log = s_read_file(s_log_path);
            CHECK(log && strstr(log, "refused by") && strstr(log, "CURVE"), "the refusal names CURVE");
            free(log);
            CHECK(c.zap_denied >= 1, "ZAP denied %d", c.zap_denied);
        }
        s_end_run(run == 0 ? "curve-listed" : "curve-unlisted", fails);
        s_coord_close(&c);
    }
    unlink(spath), unlink(gpath), unlink(bpath);
    rmdir(dir);
}

/* Usage errors and --help, without a coordinator. */
static void s_run_usage(const char *exe)
{
    struct {
        const char *args[8];
        int code;
    } cases[] = {
        { { NULL }, 2 },
        { { "--help", NULL }, 0 },
        { { "--version", NULL }, 0 },
        { { "--connect", "tcp://127.0.0.1:1", "--threads", "many", NULL }, 2 },
        { { "--connect", "tcp://127.0.0.1:1", "--bogus", NULL }, 2 },
        { { "--connect", "tcp://127.0.0.1:1", "--curve-key", "/nonexistent", NULL }, 2 },
        { { "--connect", "nonsense", NULL }, 2 },
        { { "--connect", "tcp://127.0.0.1:1", "--curve-key", "/nonexistent", "--curve-server-key", "/nonexistent" },
          1 },
    };
    for (size_t i = 0; i < sizeof cases / sizeof cases[0]; i++) {
        int fails = s_failed;
        s_start_worker(exe, cases[i].args);
        int code = s_wait_worker(10);
        CHECK(code == cases[i].code, "usage case %zu (%s %s): exit code %d, want %d", i,
              cases[i].args[0] ? cases[i].args[0] : "", cases[i].args[0] && cases[i].args[1] ? cases[i].args[1] : "",
              code, cases[i].code);
        s_end_run("usage", fails);
    }
}

int main(int argc, char **argv)
{
    const char *mode = argc > 1 ? argv[1] : "keyfile";
    signal(SIGPIPE, SIG_IGN);
    if (strcmp(mode, "keyfile") == 0) {
        s_test_keyfile();
    } else if (strcmp(mode, "protocol") == 0) {
        if (argc < 3) {
            printf("usage: test_worker_protocol protocol PATH/photonfarm-worker\n0 passed, 1 failed\n");
            return 1;
        }
        const char *exe = argv[2];
        signal(SIGALRM, s_on_alarm);
        alarm(140);
        pf_log_set_level(PF_LOG_WARN);
        s_run_usage(exe);
        s_run_refuse(exe);
        s_run_curve(exe);
        s_run_reconnect(exe);
        s_run_gone(exe);
        s_fixture_t fx;
        if (s_fixture_make(&fx) == 0)
            s_run_render(exe, &fx);
        s_fixture_free(&fx);
        alarm(0);
    } else {
        printf("unknown mode '%s'\n0 passed, 1 failed\n", mode);
        return 1;
    }
    printf("%d passed, %d failed\n", s_passed, s_failed);
    return s_failed ? 1 : 0;
}
