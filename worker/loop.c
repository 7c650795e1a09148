/* loop.c: the worker's side of the farm protocol (proto/messages.h); see
 * loop.h.
 *
 * Threads. The calling ("main") thread owns the ZeroMQ context, the DEALER
 * socket to the coordinator, its monitor socket, the blob cache, the built
 * scene cache and the current job; it only ever waits in zmq_poll (100 ms at
 * most, so a signal or a timer is noticed promptly). One compute thread does
 * everything slow: it rebuilds a job's scene, Embree structure, lights and
 * photon maps from the received blobs, and renders leased tiles, each with an
 * OpenMP team over rows. Work goes to it through a mutex + condition variable
 * queue; finished items come back on a second list, and a byte written to a
 * pipe (pollable by zmq_poll) wakes the main thread to send the RESULTs.
 *
 * Lifetimes. Jobs, built scenes and blobs are reference-counted by the main
 * thread alone: a work item holds a reference to its job (and a BUILD item
 * pins its two blobs) from the moment it is queued until the main thread
 * takes it back from the done list, so the compute thread can read them
 * without further locks (the queue's mutex orders the hand-over). Cancellation (JOB_END, a new job, a lost coordinator, a
 * signal) sets the job's atomic flag, which the compute thread checks between
 * rows; queued items of a cancelled job are taken out of the queue at once.
 *
 * Liveness. Any message from the coordinator counts as a heartbeat; silence
 * for 5 of its heartbeat intervals (or no WELCOME within 5 s of opening the
 * socket) means it is gone: the job is dropped, the socket closed, and a new
 * one opened after a backoff of 1 s doubling to 32 s (reset by a WELCOME).
 * A gap in the worker's own loop (the process was stopped) is not counted
 * as the coordinator's silence. The worker's HEARTBEAT carries a pixel
 * counter that the compute threads advance, so the coordinator can tell a
 * busy worker from a stuck one (libzmq's I/O thread would keep answering
 * either way). */
#include "worker/loop.h"

#include <errno.h>
#include <fcntl.h>
#include <inttypes.h>
#include <omp.h>
#include <pthread.h>
#include <stdarg.h>
#include <stdatomic.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <unistd.h>
#include <zmq.h>

#include "accel/accel.h"
#include "base/hash.h"
#include "base/keyfile.h"
#include "light/light.h"
#include "base/log.h"
#include "photon/photonmap.h"
#include "scene/scene.h"
#include "photon/mapfile.h"
#include "proto/messages.h"
#include "proto/sceneblob.h"
#include "render/render.h"

#define S_POLL_MS 100             /* longest wait: signals and timers are noticed this quickly */
#define S_DEAD_AFTER 5            /* coordinator heartbeat intervals of silence before it is gone */
#define S_HELLO_TIMEOUT_S 5.0     /* opening the socket to WELCOME */
#define S_BACKOFF_MIN_S 1.0
#define S_BACKOFF_MAX_S 32.0
#define S_LINGER_MS 1000          /* time to flush a BYE at exit */
#define S_CREDIT 3                /* tiles in flight: one rendering, two queued, so the worker never idles */
#define S_WINDOW 8                /* blob chunks requested ahead */
#define S_MAX_BLOBS 4             /* complete blobs kept (LRU) */
#define S_STALL_S 10.0            /* a transfer with no chunk for this long is requested again */
#define S_MAX_BLOB_SIZE (UINT64_C(1) << 36) /* 64 GiB: anything larger is not a scene or a map */
#define S_MAX_RECV_PER_WAKE 256   /* messages handled before timers are looked at again */

/* ---- the pieces of state ---- */

/* A blob (scene or maps) being received or held in the cache. */
typedef struct s_blob {
    uint64_t hash, size;
    uint8_t *data;
    uint64_t received;  /* bytes received, in order, from offset 0 */
    uint64_t requested; /* end of the range asked for so far */
    int complete;       /* received and hash-checked */
    int failures;       /* transfers that failed the hash check */
    int pins;           /* BUILD items reading data */
    uint64_t used;      /* LRU tick */
    double last_chunk;  /* pf_now() of the last chunk (or of the request) */
} s_blob;

/* What a job needs to render, built once per (scene hash, maps hash,
 * settings hash): the maps were validated against the settings hash, so a
 * job whose settings would change the maps must not reuse them. */
typedef struct s_built {
    uint64_t scene_hash, maps_hash, settings_hash;
    pf_frame_t frame;
    int refs; /* the cache's and each job's; main thread only */
} s_built;

typedef enum { S_JOB_FETCH, S_JOB_BUILD, S_JOB_READY, S_JOB_FAILED } s_job_state;

typedef struct s_job {
    uint64_t id;
    pf_msg_job_t desc;
    s_job_state state;
    s_built *built;      /* once built */
    pf_render_ctx_t ctx; /* once built; read-only for the compute thread */
    uint64_t dropped;    /* camera samples left out (ctx.dropped points here; atomic) */
    atomic_int cancelled;
    int refs;            /* the worker's current-job pointer and each work item; main thread only */
} s_job;

typedef enum { S_WORK_BUILD, S_WORK_TILE } s_work_kind;

typedef struct s_work {
    struct s_work *next;
    struct s_work *next_build; /* the main thread's list of BUILD items not yet taken back */
    s_work_kind kind;
    s_job *job;
    /* S_WORK_TILE */
    pf_msg_tile_t tile;
    float *rgb;
    uint32_t render_us;
    int rendered; /* every row done (not cancelled half-way) */
    /* S_WORK_BUILD */
    s_blob *scene_blob, *maps_blob; /* pinned while queued */
    s_built *built;                 /* the result, or NULL with error set */
    char error[1100];
} s_work;

/* The compute thread's in and out lists. */
typedef struct s_queue {
    pthread_mutex_t mu;
    pthread_cond_t cv;
    s_work *todo, *todo_tail;
    s_work *done, *done_tail;
    int quit;
    int wake[2]; /* pipe: the compute thread writes a byte when done gains an item */
} s_queue;

/* An encoded message waiting for the socket to accept it. */
typedef struct s_out {
    struct s_out *next;
    size_t len;
    uint8_t data[];
} s_out;

typedef enum { S_OFFLINE, S_HELLO, S_ONLINE } s_conn;

typedef struct s_worker {
    const pf_worker_opts_t *opts;
    char name[256];
    int threads;
    int curve;
    char public_key[41], secret_key[41], server_key[41];

    void *zctx;
    void *sock, *monitor;
    unsigned monitor_seq;
    s_conn conn;
    int hello_sent;
    double opened;       /* when the socket was opened */
    double last_recv;    /* any message from the coordinator */
    double last_hb;      /* our last HEARTBEAT */
    double last_tick;    /* the last pass of the main loop */
    uint32_t hb_ms;
    double backoff_s;
    int served; /* a coordinator has welcomed this worker at least once */
    double reconnect_at;
    s_out *out, *out_tail;
    pf_buf_t enc;
    unsigned malformed;

    s_blob **blobs;
    size_t nblobs, cap_blobs;
    uint64_t tick;
    s_built *built_cache;
    s_work *builds; /* BUILD items queued or running */
    s_job *job;

    s_queue q;
    pthread_t compute;
    int compute_started;
    atomic_uint_fast64_t progress; /* pixels rendered since start */
    uint32_t tiles_held;           /* TILEs received and not yet answered or dropped */

    int finished, exit_code;
} s_worker;

/* Logs with the worker's name, so lines from several local workers sharing
 * a terminal can be told apart. */
static void s_log(const s_worker *w, pf_log_level level, const char *fmt, ...) __attribute__((format(printf, 3, 4)));
static void s_log(const s_worker *w, pf_log_level level, const char *fmt, ...)
{
    if (level < pf_log_get_level())
        return;
    char line[1800];
    va_list ap;
    va_start(ap, fmt);
    vsnprintf(line, sizeof line, fmt, ap);
    va_end(ap);
    pf_log(level, "worker %s: %s", w->name, line);
}

/* ---- reference counting (main thread only) ---- */

static void s_built_release(s_built *b)
{
    if (!b || --b->refs > 0)
        return;
    pf_frame_close(&b->frame);
    free(b);
}

static void s_job_release(s_job *j)
{
    if (!j || --j->refs > 0)
        return;
    s_built_release(j->built);
    free(j);
}

static void s_work_free(s_work *it)
{
    if (!it)
        return;
    if (it->kind == S_WORK_BUILD) {
        if (it->scene_blob)
            it->scene_blob->pins--;
        if (it->maps_blob)
            it->maps_blob->pins--;
        s_built_release(it->built);
    }
    free(it->rgb);
    s_job_release(it->job);
    free(it);
}

/* ---- the compute thread ---- */

/* Rebuilds the frame (scene, accel, lights, maps, texels) from the job's blobs. */
static void s_compute_build(s_work *it)
{
    const pf_msg_job_t *d = &it->job->desc;
    pf_error_t err = { { 0 } };
    s_built *b = calloc(1, sizeof *b);
    if (!b) {
        snprintf(it->error, sizeof it->error, "out of memory");
        return;
    }
    b->scene_hash = d->scene_hash;
    b->maps_hash = d->maps_hash;
    b->settings_hash = pf_settings_hash(&d->settings);
    b->refs = 1;
    if (pf_frame_from_blobs(&b->frame, it->scene_blob->data, it->scene_blob->size, d->scene_hash, it->maps_blob->data,
                            it->maps_blob->size, d->maps_hash, &d->settings, &err) != PF_OK) {
        snprintf(it->error, sizeof it->error, "%s", err.msg);
        goto fail;
    }
    it->built = b;
    return;
fail:
    s_built_release(b);
}

/* Renders one tile: OpenMP over its rows, each recording the first-gather
 * records it needs that no other row has (pf_tile_plan_t), so progress moves
 * row by row for the watchdog; the pixels are those of any other split of
 * the image. */
static void s_compute_tile(s_worker *w, s_work *it)
{
    s_job *job = it->job;
    const pf_render_ctx_t *ctx = &job->ctx;
    int x0 = (int)it->tile.x0, y0 = (int)it->tile.y0, tw = (int)it->tile.w, th = (int)it->tile.h;
    float *out = it->rgb;
    double t0 = pf_now();
    pf_tile_plan_t *plan = pf_tile_plan_new(ctx, x0, y0, tw, th);
#pragma omp parallel num_threads(w->threads)
    {
        pf_accel_thread_init();
#pragma omp for schedule(dynamic, 1)
        for (int row = 0; row < th; row++) {
            if (atomic_load_explicit(&job->cancelled, memory_order_relaxed))
                continue;
            pf_tile_plan_render_row(plan, row, out + (size_t)row * (size_t)tw * 3);
            atomic_fetch_add_explicit(&w->progress, (uint_fast64_t)tw, memory_order_relaxed);
        }
    }
    pf_tile_plan_free(plan);
    double us = (pf_now() - t0) * 1e6;
    it->render_us = us >= 4294967295.0 ? UINT32_MAX : (uint32_t)us;
    uint64_t dropped = __atomic_load_n(&job->dropped, __ATOMIC_RELAXED);
    if (dropped)
        s_log(w, PF_LOG_WARN, "job %" PRIu64 ": %" PRIu64 " camera samples so far were non-finite or negative and "
              "left out of their pixels (last tile at %d,%d)", job->id, dropped, x0, y0);
    it->rendered = !atomic_load(&job->cancelled);
}

static void *s_compute_main(void *arg)
{
    s_worker *w = arg;
    s_queue *q = &w->q;
    pf_accel_thread_init();
    for (;;) {
        pthread_mutex_lock(&q->mu);
        while (!q->todo && !q->quit)
            pthread_cond_wait(&q->cv, &q->mu);
        if (q->quit) {
            pthread_mutex_unlock(&q->mu);
            return NULL;
        }
        s_work *it = q->todo;
        q->todo = it->next;
        if (!q->todo)
            q->todo_tail = NULL;
        it->next = NULL;
        pthread_mutex_unlock(&q->mu);

        if (!atomic_load(&it->job->cancelled)) {
            if (it->kind == S_WORK_BUILD)
                s_compute_build(it);
            else
                s_compute_tile(w, it);
        }

        pthread_mutex_lock(&q->mu);
        if (q->done_tail)
            q->done_tail->next = it;
        else
            q->done = it;
        q->done_tail = it;
        pthread_mutex_unlock(&q->mu);
        /* A full pipe already holds a wake-up; EAGAIN is fine. */
        ssize_t wr = write(q->wake[1], "w", 1);
        (void)wr;
    }
}

static void s_enqueue(s_worker *w, s_work *it)
{
    pthread_mutex_lock(&w->q.mu);
    if (w->q.todo_tail)
        w->q.todo_tail->next = it;
    else
        w->q.todo = it;
    w->q.todo_tail = it;
    pthread_cond_signal(&w->q.cv);
    pthread_mutex_unlock(&w->q.mu);
}

/* The main thread's record of BUILD items out with the compute thread, so a
 * job can wait for a build of its scene and maps already under way instead
 * of starting a second one. */
static void s_build_forget(s_worker *w, const s_work *it)
{
    for (s_work **pp = &w->builds; *pp; pp = &(*pp)->next_build)
        if (*pp == it) {
            *pp = it->next_build;
            return;
        }
}

/* Do two jobs need the same built scene and maps? */
static int s_same_build(const pf_msg_job_t *a, const pf_msg_job_t *b)
{
    return a->scene_hash == b->scene_hash && a->scene_size == b->scene_size && a->maps_hash == b->maps_hash &&
           a->maps_size == b->maps_size && pf_settings_hash(&a->settings) == pf_settings_hash(&b->settings);
}

static int s_built_fits(const s_built *c, const pf_msg_job_t *d)
{
    return c && c->scene_hash == d->scene_hash && c->maps_hash == d->maps_hash &&
           c->settings_hash == pf_settings_hash(&d->settings);
}

static int s_build_pending(const s_worker *w, const pf_msg_job_t *d)
{
    for (const s_work *b = w->builds; b; b = b->next_build)
        if (s_same_build(&b->job->desc, d))
            return 1;
    return 0;
}

/* Takes the queued (not yet started) items of job out of the queue. */
static void s_unqueue_job(s_worker *w, const s_job *job)
{
    s_work *drop = NULL;
    pthread_mutex_lock(&w->q.mu);
    s_work **pp = &w->q.todo;
    w->q.todo_tail = NULL;
    while (*pp) {
        s_work *it = *pp;
        if (it->job == job) {
            *pp = it->next;
            it->next = drop;
            drop = it;
        } else {
            w->q.todo_tail = it;
            pp = &it->next;
        }
    }
    pthread_mutex_unlock(&w->q.mu);
    while (drop) {
        s_work *next = drop->next;
        if (drop->kind == S_WORK_TILE)
            w->tiles_held--;
        else
            s_build_forget(w, drop);
        s_work_free(drop);
        drop = next;
    }
}

/* ---- sending ---- */

/* Encodes and sends msg without blocking. When the socket cannot take it
 * now (no connection yet, or the high-water mark), a droppable message
 * (HEARTBEAT) is dropped and any other waits in the outbox, in order. */
static void s_send(s_worker *w, const pf_msg_t *msg, int droppable)
{
    if (!w->sock)
        return;
    int rc = pf_msg_encode(msg, &w->enc);
    if (rc) {
        s_log(w, PF_LOG_ERROR, "cannot encode %s for job %" PRIu64 ": %s", pf_msg_type_name(msg->type), msg->job,
              pf_strerror(rc));
        return;
    }
    if (!w->out) {
        if (zmq_send(w->sock, w->enc.data, w->enc.len, ZMQ_DONTWAIT) >= 0)
            return;
        if (errno != EAGAIN) {
            s_log(w, PF_LOG_WARN, "cannot send %s: %s", pf_msg_type_name(msg->type), zmq_strerror(errno));
            return;
        }
    }
    if (droppable)
        return;
    s_out *o = malloc(sizeof *o + w->enc.len);
    if (!o) {
        s_log(w, PF_LOG_ERROR, "out of memory queueing %s", pf_msg_type_name(msg->type));
        return;
    }
    o->next = NULL;
    o->len = w->enc.len;
    memcpy(o->data, w->enc.data, w->enc.len);
    if (w->out_tail)
        w->out_tail->next = o;
    else
        w->out = o;
    w->out_tail = o;
}

static void s_flush(s_worker *w)
{
    while (w->out && w->sock) {
        if (zmq_send(w->sock, w->out->data, w->out->len, ZMQ_DONTWAIT) < 0) {
            if (errno == EAGAIN)
                return;
            s_log(w, PF_LOG_WARN, "cannot send a queued message: %s", zmq_strerror(errno));
        }
        s_out *o = w->out;
        w->out = o->next;
        if (!w->out)
            w->out_tail = NULL;
        free(o);
    }
}

static void s_outbox_clear(s_worker *w)
{
    while (w->out) {
        s_out *o = w->out;
        w->out = o->next;
        free(o);
    }
    w->out_tail = NULL;
}

static void s_send_hello(s_worker *w)
{
    pf_msg_t m;
    memset(&m, 0, sizeof m);
    m.type = PF_MSG_HELLO;
    m.u.hello.fp = pf_frame_fingerprint();
    if (w->opts->fake_protocol > 0)
        m.u.hello.fp.protocol = (uint16_t)w->opts->fake_protocol;
    m.u.hello.threads = (uint32_t)w->threads;
    snprintf(m.u.hello.name, sizeof m.u.hello.name, "%s", w->name);
    if (pf_msg_encode(&m, &w->enc)) {
        s_log(w, PF_LOG_ERROR, "cannot encode HELLO");
        return;
    }
    /* Queued until the connection is up; the loop sends it again when no
     * WELCOME comes within the HELLO timeout. */
    if (zmq_send(w->sock, w->enc.data, w->enc.len, ZMQ_DONTWAIT) >= 0) {
        w->hello_sent = 1;
        s_log(w, PF_LOG_DEBUG, "HELLO sent to %s", w->opts->endpoint);
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
    s_send(w, &m, 1);
}

/* ---- blobs ---- */

static s_blob *s_blob_find(s_worker *w, uint64_t hash, uint64_t size)
{
    for (size_t i = 0; i < w->nblobs; i++)
        if (w->blobs[i]->hash == hash && w->blobs[i]->size == size)
            return w->blobs[i];
    return NULL;
}

static void s_blob_remove(s_worker *w, size_t i)
{
    free(w->blobs[i]->data);
    free(w->blobs[i]);
    w->blobs[i] = w->blobs[--w->nblobs];
}

static int s_blob_needed(const s_worker *w, const s_blob *b)
{
    const s_job *j = w->job;
    if (!j || j->state == S_JOB_FAILED)
        return 0;
    return (b->hash == j->desc.scene_hash && b->size == j->desc.scene_size) ||
           (b->hash == j->desc.maps_hash && b->size == j->desc.maps_size);
}

/* Drops transfers no current job needs, then the least recently used
 * complete blobs beyond S_MAX_BLOBS (never one pinned by a build or needed
 * by the current job; the cache may run over while those are in use). */
static void s_blobs_trim(s_worker *w)
{
    for (size_t i = 0; i < w->nblobs;) {
        s_blob *b = w->blobs[i];
        if (!b->complete && !b->pins && !s_blob_needed(w, b)) {
            s_log(w, PF_LOG_DEBUG, "dropping the unfinished transfer of blob %016" PRIx64, b->hash);
            s_blob_remove(w, i);
        } else {
            i++;
        }
    }
    for (;;) {
        size_t complete = 0, victim = SIZE_MAX;
        for (size_t i = 0; i < w->nblobs; i++) {
            s_blob *b = w->blobs[i];
            if (!b->complete)
                continue;
            complete++;
            if (!b->pins && !s_blob_needed(w, b) && (victim == SIZE_MAX || b->used < w->blobs[victim]->used))
                victim = i;
        }
        if (complete <= S_MAX_BLOBS || victim == SIZE_MAX)
            return;
        s_log(w, PF_LOG_DEBUG, "evicting cached blob %016" PRIx64, w->blobs[victim]->hash);
        s_blob_remove(w, victim);
    }
}

/* Asks for more chunks so that about S_WINDOW are outstanding. */
static void s_blob_request(s_worker *w, s_blob *b)
{
    uint64_t chunk = PF_PROTO_CHUNK_SIZE;
    uint64_t outstanding = (b->requested - b->received + chunk - 1) / chunk;
    if (b->requested >= b->size || outstanding > S_WINDOW / 2)
        return;
    uint64_t left = (b->size - b->requested + chunk - 1) / chunk;
    uint64_t credit = S_WINDOW - outstanding;
    if (credit > left)
        credit = left;
    pf_msg_t m;
    memset(&m, 0, sizeof m);
    m.type = PF_MSG_BLOB_REQ;
    m.job = w->job ? w->job->id : 0;
    m.u.blob_req.hash = b->hash;
    m.u.blob_req.offset = b->requested;
    m.u.blob_req.credit = (uint32_t)credit;
    s_send(w, &m, 0);
    b->requested += credit * chunk;
    if (b->requested > b->size)
        b->requested = b->size;
}

/* Starts (or restarts from its last in-order byte) the transfer of b. */
static void s_blob_restart(s_worker *w, s_blob *b)
{
    b->requested = b->received;
    b->last_chunk = pf_now();
    s_blob_request(w, b);
}

/* The cached or in-transfer blob (hash, size), starting its transfer when
 * it is not there. NULL when the size is absurd or memory is short. */
static s_blob *s_blob_get(s_worker *w, uint64_t hash, uint64_t size, const char *what)
{
    s_blob *b = s_blob_find(w, hash, size);
    if (b) {
        b->used = ++w->tick;
        return b;
    }
    if (size == 0 || size > S_MAX_BLOB_SIZE) {
        s_log(w, PF_LOG_ERROR, "job %" PRIu64 ": the %s blob's size %" PRIu64 " is out of range", w->job->id, what,
              size);
        return NULL;
    }
    if (w->nblobs == w->cap_blobs) {
        size_t cap = w->cap_blobs ? 2 * w->cap_blobs : 8;
        s_blob **grown = realloc(w->blobs, cap * sizeof *grown);
        if (!grown)
            return NULL;
        w->blobs = grown;
        w->cap_blobs = cap;
    }
    b = calloc(1, sizeof *b);
    uint8_t *data = malloc((size_t)size);
    if (!b || !data) {
        free(b);
        free(data);
        s_log(w, PF_LOG_ERROR, "job %" PRIu64 ": cannot allocate %" PRIu64 " bytes for the %s blob", w->job->id, size,
              what);
        return NULL;
    }
    b->hash = hash;
    b->size = size;
    b->data = data;
    b->used = ++w->tick;
    w->blobs[w->nblobs++] = b;
    s_log(w, PF_LOG_INFO, "fetching the %s blob %016" PRIx64 " (%.1f MB)", what, hash, (double)size / 1e6);
    s_blob_restart(w, b);
    return b;
}

/* ---- jobs ---- */

/* Cancels the current job: its queued work leaves the queue, the tile being
 * rendered stops at the next row, and results still to come are discarded. */
static void s_job_drop(s_worker *w, const char *why)
{
    s_job *j = w->job;
    if (!j)
        return;
    s_log(w, PF_LOG_DEBUG, "dropping job %" PRIu64 " (%s)", j->id, why);
    atomic_store(&j->cancelled, 1);
    w->job = NULL;
    s_unqueue_job(w, j);
    s_job_release(j);
    s_blobs_trim(w);
}

static void s_job_fail(s_worker *w, s_job *j, const char *why)
{
    s_log(w, PF_LOG_ERROR, "job %" PRIu64 ": %s; taking no tiles for it", j->id, why);
    j->state = S_JOB_FAILED;
    s_blobs_trim(w);
}

/* The scene and maps are built: render context, then READY. */
static void s_job_ready(s_worker *w, s_job *j, s_built *b)
{
    b->refs++;
    j->built = b;
    pf_render_ctx_init(&j->ctx, &b->frame, &j->desc.settings);
    j->ctx.terms = j->desc.terms;
    j->ctx.dropped = &j->dropped;
    j->state = S_JOB_READY;
    s_log(w, PF_LOG_INFO, "job %" PRIu64 ": ready (%dx%d, %d spp)", j->id, j->desc.settings.width,
          j->desc.settings.height, j->desc.settings.spp);
    pf_msg_t m;
    memset(&m, 0, sizeof m);
    m.type = PF_MSG_READY;
    m.job = j->id;
    m.u.ready.credit = S_CREDIT;
    s_send(w, &m, 0);
}

/* Once both blobs are complete: reuse the built scene when it is the same,
 * else hand the build to the compute thread. */
static void s_job_advance(s_worker *w)
{
    s_job *j = w->job;
    if (!j || j->state != S_JOB_FETCH)
        return;
    const pf_msg_job_t *d = &j->desc;
    s_blob *sb = s_blob_find(w, d->scene_hash, d->scene_size), *mb = s_blob_find(w, d->maps_hash, d->maps_size);
    if (!sb || !mb || !sb->complete || !mb->complete)
        return;
    if (s_built_fits(w->built_cache, d)) {
        s_log(w, PF_LOG_DEBUG, "job %" PRIu64 ": reusing the built scene and maps", j->id);
        s_job_ready(w, j, w->built_cache);
        return;
    }
    if (s_build_pending(w, d)) {
        /* An earlier job's build of the same blobs is running; its result
         * will be cached and serve this job (s_drain_done). */
        s_log(w, PF_LOG_DEBUG, "job %" PRIu64 ": waiting for the build already under way", j->id);
        j->state = S_JOB_BUILD;
        return;
    }
    s_work *it = calloc(1, sizeof *it);
    if (!it) {
        s_job_fail(w, j, "out of memory");
        return;
    }
    it->kind = S_WORK_BUILD;
    it->job = j;
    j->refs++;
    it->scene_blob = sb;
    it->maps_blob = mb;
    sb->pins++;
    mb->pins++;
    j->state = S_JOB_BUILD;
    s_log(w, PF_LOG_INFO, "job %" PRIu64 ": building the scene and photon maps", j->id);
    it->next_build = w->builds;
    w->builds = it;
    s_enqueue(w, it);
}

static void s_on_job(s_worker *w, const pf_msg_t *m)
{
    const pf_msg_job_t *d = &m->u.job;
    if (w->job && w->job->id == m->job) {
        s_log(w, PF_LOG_DEBUG, "job %" PRIu64 " announced again; ignored", m->job);
        return;
    }
    s_job_drop(w, "a new job arrived");
    s_job *j = calloc(1, sizeof *j);
    if (!j) {
        s_log(w, PF_LOG_ERROR, "job %" PRIu64 ": out of memory", m->job);
        return;
    }
    j->id = m->job;
    j->desc = *d;
    j->refs = 1;
    atomic_init(&j->cancelled, 0);
    w->job = j;
    s_log(w, PF_LOG_INFO, "job %" PRIu64 ": scene %016" PRIx64 " (%" PRIu64 " bytes), maps %016" PRIx64
          " (%" PRIu64 " bytes)", j->id, d->scene_hash, d->scene_size, d->maps_hash, d->maps_size);
    /* The decoder checked the ranges; these guard the renderer's own limits
     * (estimate scratch, term mask) whatever the decoder lets through. */
    if (d->settings.global_k < 1 || d->settings.global_k > PF_MAX_K || d->settings.caustic_k < 1 ||
        d->settings.caustic_k > PF_MAX_K || d->settings.width < 1 || d->settings.height < 1 ||
        (d->terms & ~(unsigned)(PF_TERM_ALL | PF_TERM_PHOTONMAP)) != 0) {
        s_job_fail(w, j, "settings out of the renderer's range");
        return;
    }
    if (!s_blob_get(w, d->scene_hash, d->scene_size, "scene") || !s_blob_get(w, d->maps_hash, d->maps_size, "maps")) {
        s_job_fail(w, j, "cannot fetch its blobs");
        return;
    }
    s_blobs_trim(w);
    s_job_advance(w);
}

static void s_on_chunk(s_worker *w, const pf_msg_blob_chunk_t *c)
{
    s_blob *b = s_blob_find(w, c->hash, c->total);
    if (!b || b->complete) {
        s_log(w, PF_LOG_DEBUG, "chunk of blob %016" PRIx64 " not being fetched; dropped", c->hash);
        return;
    }
    uint64_t expect = b->size - b->received < PF_PROTO_CHUNK_SIZE ? b->size - b->received : PF_PROTO_CHUNK_SIZE;
    if (c->offset != b->received || c->len != expect) {
        /* A gap or a replay; the stall timer asks again from b->received. */
        s_log(w, PF_LOG_DEBUG, "chunk of blob %016" PRIx64 " at %" PRIu64 " (+%" PRIu32 ") out of order, expected %"
              PRIu64 "; dropped", c->hash, c->offset, c->len, b->received);
        return;
    }
    memcpy(b->data + b->received, c->data, c->len);
    b->received += c->len;
    b->last_chunk = pf_now();
    if (b->received < b->size) {
        s_blob_request(w, b);
        return;
    }
    uint64_t h = pf_hash_bytes(PF_HASH_INIT, b->data, (size_t)b->size);
    if (h != b->hash) {
        b->failures++;
        b->received = b->requested = 0;
        if (b->failures < 2) {
            s_log(w, PF_LOG_WARN, "blob %016" PRIx64 " arrived with content hash %016" PRIx64 "; fetching it again",
                  b->hash, h);
            s_blob_restart(w, b);
            return;
        }
        for (size_t i = 0; i < w->nblobs; i++)
            if (w->blobs[i] == b) {
                s_blob_remove(w, i);
                break;
            }
        if (w->job && w->job->state == S_JOB_FETCH) {
            char why[160];
            snprintf(why, sizeof why, "blob %016" PRIx64 " failed its content hash twice", c->hash);
            s_job_fail(w, w->job, why);
        }
        return;
    }
    b->complete = 1;
    b->used = ++w->tick;
    s_log(w, PF_LOG_DEBUG, "blob %016" PRIx64 " complete (%" PRIu64 " bytes)", b->hash, b->size);
    s_blobs_trim(w);
    s_job_advance(w);
}

static void s_on_tile(s_worker *w, const pf_msg_t *m)
{
    const pf_msg_tile_t *t = &m->u.tile;
    s_job *j = w->job;
    if (!j || j->id != m->job) {
        s_log(w, PF_LOG_DEBUG, "TILE %" PRIu32 " of job %" PRIu64 ", which is not the current job; dropped", t->tile,
              m->job);
        return;
    }
    if (j->state != S_JOB_READY) {
        if (j->state == S_JOB_FAILED)
            s_log(w, PF_LOG_DEBUG, "TILE %" PRIu32 " of job %" PRIu64 ", which this worker rejected; dropped", t->tile,
                  m->job);
        else
            s_log(w, PF_LOG_WARN, "TILE %" PRIu32 " of job %" PRIu64 " before READY; dropped", t->tile, m->job);
        return;
    }
    uint64_t W = (uint64_t)j->desc.settings.width, H = (uint64_t)j->desc.settings.height;
    if (t->w < 1 || t->h < 1 || (uint64_t)t->x0 + t->w > W || (uint64_t)t->y0 + t->h > H ||
        (uint64_t)t->w * t->h > PF_PROTO_MAX_TILE_PIXELS) {
        s_log(w, PF_LOG_WARN, "TILE %" PRIu32 " of job %" PRIu64 ": %" PRIu32 "x%" PRIu32 " at (%" PRIu32 ", %" PRIu32
              ") is not inside the %" PRIu64 "x%" PRIu64 " image; dropped", t->tile, m->job, t->w, t->h, t->x0, t->y0,
              W, H);
        return;
    }
    s_work *it = calloc(1, sizeof *it);
    float *rgb = malloc((size_t)t->w * t->h * 3 * sizeof *rgb);
    if (!it || !rgb) {
        free(it);
        free(rgb);
        s_log(w, PF_LOG_ERROR, "out of memory for TILE %" PRIu32, t->tile);
        return;
    }
    it->kind = S_WORK_TILE;
    it->job = j;
    j->refs++;
    it->tile = *t;
    it->rgb = rgb;
    w->tiles_held++;
    s_enqueue(w, it);
}

/* Takes finished items back from the compute thread. */
static void s_drain_done(s_worker *w)
{
    char buf[64];
    while (read(w->q.wake[0], buf, sizeof buf) > 0) {
    }
    pthread_mutex_lock(&w->q.mu);
    s_work *list = w->q.done;
    w->q.done = w->q.done_tail = NULL;
    pthread_mutex_unlock(&w->q.mu);
    while (list) {
        s_work *it = list;
        list = it->next;
        s_job *j = it->job;
        int current = j == w->job && !atomic_load(&j->cancelled);
        if (it->kind == S_WORK_BUILD) {
            s_build_forget(w, it);
            if (it->built) {
                /* Cache the build even if its job is gone: the next job
                 * with the same scene and maps will want it. */
                s_built_release(w->built_cache);
                w->built_cache = it->built;
                it->built = NULL;
            }
            /* The current job may be this item's or one waiting for it. */
            s_job *cj = w->job;
            if (cj && cj->state == S_JOB_BUILD && s_same_build(&cj->desc, &j->desc)) {
                if (s_built_fits(w->built_cache, &cj->desc)) {
                    s_job_ready(w, cj, w->built_cache);
                } else if (it->error[0]) {
                    s_job_fail(w, cj, it->error);
                } else if (!s_build_pending(w, &cj->desc)) {
                    /* The build was skipped (its job was cancelled before it
                     * started): build again for this one. */
                    cj->state = S_JOB_FETCH;
                    s_job_advance(w);
                }
            }
        } else {
            w->tiles_held--;
            if (current && it->rendered && w->conn == S_ONLINE) {
                pf_msg_t m;
                memset(&m, 0, sizeof m);
                m.type = PF_MSG_RESULT;
                m.job = j->id;
                pf_msg_result_t *r = &m.u.result;
                r->tile = it->tile.tile;
                r->attempt = it->tile.attempt;
                r->x0 = it->tile.x0;
                r->y0 = it->tile.y0;
                r->w = it->tile.w;
                r->h = it->tile.h;
                r->rgb = it->rgb;
                r->render_us = it->render_us;
                s_send(w, &m, 0);
            } else {
                s_log(w, PF_LOG_DEBUG, "tile %" PRIu32 " of job %" PRIu64 " discarded (job ended)", it->tile.tile,
                      j->id);
            }
        }
        int was_build = it->kind == S_WORK_BUILD;
        s_work_free(it);
        if (was_build)
            s_blobs_trim(w); /* its blobs are unpinned now */
    }
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
    s_outbox_clear(w);
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
    w->conn = S_HELLO;
    w->hello_sent = 0;
    w->opened = w->last_recv = pf_now();
    s_log(w, PF_LOG_DEBUG, "connecting to %s", w->opts->endpoint);
    s_send_hello(w);
    return 0;
}

/* The coordinator is gone (silent, or said BYE): forget its job and open a
 * new socket after the backoff. */
static void s_lost(s_worker *w, pf_log_level level, const char *why)
{
    s_job_drop(w, why);
    s_close_socket(w, 0);
    w->reconnect_at = pf_now() + w->backoff_s;
    s_log(w, level, "%s; contacting %s again in %.0f s", why, w->opts->endpoint, w->backoff_s);
    w->backoff_s = w->backoff_s * 2 > S_BACKOFF_MAX_S ? S_BACKOFF_MAX_S : w->backoff_s * 2;
}

static void s_refused(s_worker *w, const char *reason)
{
    fprintf(stderr, "photonfarm-worker: refused by %s: %s\n", w->opts->endpoint, reason);
    s_log(w, PF_LOG_DEBUG, "refused; exiting");
    w->finished = 1;
    w->exit_code = PF_WORKER_EXIT_REFUSED;
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
        case ZMQ_EVENT_CONNECTED: s_log(w, PF_LOG_DEBUG, "TCP connection to %s up", w->opts->endpoint); break;
        case ZMQ_EVENT_DISCONNECTED: s_log(w, PF_LOG_DEBUG, "connection to %s closed", w->opts->endpoint); break;
        case ZMQ_EVENT_HANDSHAKE_SUCCEEDED: s_log(w, PF_LOG_DEBUG, "handshake with %s done", w->opts->endpoint); break;
        case ZMQ_EVENT_HANDSHAKE_FAILED_AUTH: {
            if (value != 400) { /* 300: try later, 500: the coordinator's ZAP handler failed */
                s_log(w, PF_LOG_WARN, "CURVE authentication with %s failed with status %u; retrying",
                      w->opts->endpoint, (unsigned)value);
                break;
            }
            char why[128];
            snprintf(why, sizeof why, "CURVE authentication failed (status %u): this worker's public key is not on "
                     "the coordinator's list", (unsigned)value);
            s_refused(w, why);
            return;
        }
        case ZMQ_EVENT_HANDSHAKE_FAILED_PROTOCOL:
        case ZMQ_EVENT_HANDSHAKE_FAILED_NO_DETAIL:
            s_log(w, PF_LOG_WARN, "handshake with %s failed (%s 0x%x): do both sides agree on CURVE and its keys?",
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
        if (w->malformed <= 20 || w->malformed % 1000 == 0)
            s_log(w, PF_LOG_WARN, "dropped %s message of %zu bytes from the coordinator (%u so far): %s",
                  rc == PF_EMISMATCH ? "a foreign-version" : "a malformed", len, w->malformed, why);
        return;
    }
    if (w->conn == S_HELLO) {
        switch (m.type) {
        case PF_MSG_WELCOME:
            w->conn = S_ONLINE;
            w->served = 1;
            w->hb_ms = m.u.welcome.heartbeat_ms ? m.u.welcome.heartbeat_ms : 1000;
            w->backoff_s = S_BACKOFF_MIN_S;
            w->last_hb = 0; /* a first heartbeat right away */
            s_log(w, PF_LOG_INFO, "registered with %s as worker %" PRIu32 " (%d threads, heartbeat %" PRIu32 " ms)",
                  w->opts->endpoint, m.u.welcome.worker_id, w->threads, w->hb_ms);
            return;
        case PF_MSG_REFUSE: s_refused(w, m.u.refuse.reason); return;
        case PF_MSG_BYE: break;
        default:
            s_log(w, PF_LOG_DEBUG, "%s before WELCOME; dropped", pf_msg_type_name(m.type));
            return;
        }
    }
    switch (m.type) {
    case PF_MSG_HEARTBEAT: break;
    case PF_MSG_WELCOME: s_log(w, PF_LOG_DEBUG, "a second WELCOME; ignored"); break;
    case PF_MSG_REFUSE: s_refused(w, m.u.refuse.reason); break;
    case PF_MSG_JOB: s_on_job(w, &m); break;
    case PF_MSG_BLOB_CHUNK: s_on_chunk(w, &m.u.chunk); break;
    case PF_MSG_TILE: s_on_tile(w, &m); break;
    case PF_MSG_JOB_END:
        if (w->job && w->job->id == m.job) {
            s_log(w, PF_LOG_INFO, "job %" PRIu64 ": ended", m.job);
            s_job_drop(w, "JOB_END");
        } else {
            s_log(w, PF_LOG_DEBUG, "JOB_END for job %" PRIu64 ", which is not the current job", m.job);
        }
        break;
    case PF_MSG_BYE:
        s_log(w, PF_LOG_INFO, "the coordinator said goodbye (%s)", m.u.bye.reason);
        if (w->opts->exit_on_bye) {
            s_job_drop(w, "BYE");
            w->finished = 1;
            w->exit_code = PF_WORKER_EXIT_OK;
        } else {
            w->backoff_s = S_BACKOFF_MIN_S;
            s_lost(w, PF_LOG_INFO, "the coordinator left");
        }
        break;
    default:
        s_log(w, PF_LOG_WARN, "unexpected %s from the coordinator; dropped", pf_msg_type_name(m.type));
        break;
    }
}

/* Receives what the socket holds (bounded, so timers still run under a
 * flood). Multi-frame messages are not part of the protocol and are dropped. */
static void s_receive(s_worker *w)
{
    for (int i = 0; i < S_MAX_RECV_PER_WAKE && w->sock && !w->finished; i++) {
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
            s_log(w, PF_LOG_WARN, "dropped a message of %zu frames (the protocol uses one)", parts);
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
        s_log(w, PF_LOG_INFO, "this worker was stalled for %.1f s (stopped?); resuming", gap);
        w->last_recv += gap;
        w->opened += gap;
        for (size_t i = 0; i < w->nblobs; i++)
            w->blobs[i]->last_chunk += gap;
    }
    if (w->conn == S_HELLO) {
        if (!w->hello_sent)
            s_send_hello(w);
        if (now - w->opened > S_HELLO_TIMEOUT_S && w->opts->exit_on_bye && w->served) {
            /* A one-job worker whose coordinator went away while it could
             * not hear the goodbye (stopped, cut off) would otherwise wait
             * for it forever. */
            s_log(w, PF_LOG_INFO, "the coordinator this worker served is gone (no WELCOME within 5 s); "
                  "--exit-on-bye: exiting");
            s_job_drop(w, "coordinator gone");
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
    for (size_t i = 0; i < w->nblobs; i++) {
        s_blob *b = w->blobs[i];
        if (!b->complete && s_blob_needed(w, b) && now - b->last_chunk > S_STALL_S) {
            s_log(w, PF_LOG_WARN, "transfer of blob %016" PRIx64 " stalled at %" PRIu64 " of %" PRIu64
                  " bytes; asking again", b->hash, b->received, b->size);
            s_blob_restart(w, b);
        }
    }
}

/* ---- set-up and the loop ---- */

/* A non-blocking, close-on-exec pipe (the compute thread's wake-up). */
static int s_pipe(int fds[2])
{
    if (pipe(fds) != 0)
        return -1;
    for (int i = 0; i < 2; i++)
        if (fcntl(fds[i], F_SETFL, O_NONBLOCK) != 0 || fcntl(fds[i], F_SETFD, FD_CLOEXEC) != 0) {
            close(fds[0]);
            close(fds[1]);
            fds[0] = fds[1] = -1;
            return -1;
        }
    return 0;
}

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
    if (pthread_mutex_init(&w->q.mu, NULL) || pthread_cond_init(&w->q.cv, NULL) ||
        s_pipe(w->q.wake) != 0) {
        fprintf(stderr, "photonfarm-worker: cannot set up the compute queue: %s\n", strerror(errno));
        return PF_WORKER_EXIT_FATAL;
    }
    w->zctx = zmq_ctx_new();
    if (!w->zctx) {
        fprintf(stderr, "photonfarm-worker: cannot create a ZeroMQ context: %s\n", zmq_strerror(errno));
        return PF_WORKER_EXIT_FATAL;
    }
    /* The compute thread (and its OpenMP team) leaves SIGINT and SIGTERM to
     * the main thread, whose zmq_poll they interrupt. */
    sigset_t block, old;
    sigemptyset(&block);
    sigaddset(&block, SIGINT);
    sigaddset(&block, SIGTERM);
    pthread_sigmask(SIG_BLOCK, &block, &old);
    int rc = pthread_create(&w->compute, NULL, s_compute_main, w);
    pthread_sigmask(SIG_SETMASK, &old, NULL);
    if (rc != 0) {
        fprintf(stderr, "photonfarm-worker: cannot start the compute thread: %s\n", strerror(rc));
        return PF_WORKER_EXIT_FATAL;
    }
    w->compute_started = 1;
    return 0;
}

static void s_teardown(s_worker *w)
{
    s_job_drop(w, "exit");
    if (w->compute_started) {
        pthread_mutex_lock(&w->q.mu);
        w->q.quit = 1;
        pthread_cond_broadcast(&w->q.cv);
        pthread_mutex_unlock(&w->q.mu);
        pthread_join(w->compute, NULL);
        /* Whatever is left in either list belongs to the main thread now. */
        s_work *lists[2] = { w->q.todo, w->q.done };
        for (int i = 0; i < 2; i++)
            while (lists[i]) {
                s_work *next = lists[i]->next;
                s_work_free(lists[i]);
                lists[i] = next;
            }
        w->q.todo = w->q.done = NULL;
    }
    if (w->sock || w->monitor)
        s_close_socket(w, S_LINGER_MS);
    s_outbox_clear(w);
    if (w->zctx)
        zmq_ctx_term(w->zctx);
    s_built_release(w->built_cache);
    while (w->nblobs)
        s_blob_remove(w, 0);
    free(w->blobs);
    pf_buf_free(&w->enc);
    if (w->q.wake[0] >= 0) {
        close(w->q.wake[0]);
        close(w->q.wake[1]);
        pthread_mutex_destroy(&w->q.mu);
        pthread_cond_destroy(&w->q.cv);
    }
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
                s_outbox_clear(w); /* results nobody will use; the BYE matters */
                s_send(w, &m, 0);
            }
            s_log(w, PF_LOG_INFO, "stopping on a signal");
            w->exit_code = PF_WORKER_EXIT_OK;
            break;
        }
        if (w->conn == S_OFFLINE && pf_now() >= w->reconnect_at) {
            code = s_open(w);
            if (code)
                break;
        }
        s_flush(w);
        zmq_pollitem_t items[3];
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
        int rc = zmq_poll(items, n, S_POLL_MS);
        if (rc < 0) {
            if (errno == EINTR)
                continue;
            fprintf(stderr, "photonfarm-worker: zmq_poll: %s\n", zmq_strerror(errno));
            code = PF_WORKER_EXIT_FATAL;
            break;
        }
        if (items[0].revents & ZMQ_POLLIN)
            s_drain_done(w);
        if (i_mon >= 0 && (items[i_mon].revents & ZMQ_POLLIN))
            s_on_monitor(w);
        if (!w->finished && i_sock >= 0 && w->sock && (items[i_sock].revents & ZMQ_POLLIN))
            s_receive(w);
        if (!w->finished)
            s_timers(w);
    }
    if (code == 0)
        code = w->exit_code;
    s_teardown(w);
    free(w);
    return code;
}
