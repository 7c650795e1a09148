/* worker_impl.h: private to worker/. The state the worker's files share,
 * and the pf_w_ functions they call across the file boundary, each file
 * calling only those below it:
 *
 *   loop.c     the protocol state machine and the socket (main thread);
 *   jobs.c     jobs, the blob cache and transfers, the built scene cache,
 *              TILE and RESULT handling (main thread);
 *   compute.c  the compute thread, its work queue and the reference-counted
 *              work items, jobs and built frames;
 *   photons.c  the photon job: batches of the coordinator's photon pass
 *              traced on request (PHOTON_REQ) and sent back (PHOTONS); its
 *              handlers run in the main thread, its tracing in the compute
 *              thread; jobs.c calls it when a blob completes and when a job
 *              is dropped, it calls jobs.c for the scene blob;
 *   outbox.c   log lines and messages to the coordinator, the outbox.
 *
 * Nothing outside worker/ includes this header; the public interface is
 * loop.h. Everything here is owned and reference-counted by the main thread
 * unless a field says otherwise (see jobs.c for the lifetimes, compute.c for
 * the hand-over to the compute thread). */
#ifndef PF_WORKER_IMPL_H
#define PF_WORKER_IMPL_H

#include <pthread.h>
#include <stdatomic.h>
#include <stddef.h>
#include <stdint.h>

#include "base/log.h"
#include "base/wire.h"
#include "proto/messages.h"
#include "photon/photonmap.h"
#include "render/render.h"

/* ---- the pieces of state ----
 *
 * The types keep the s_ names they had when all of this was one file;
 * they are private to worker/ all the same. */

/* A blob (scene or maps) being received or held in the cache. */
typedef struct s_blob {
    uint64_t hash, size;
    uint8_t *data;      /* a mapping grown as chunks arrive (never the announced size up front) */
    uint64_t alloc;     /* bytes mapped at data (0: none; munmap, never free) */
    uint64_t received;  /* bytes received, in order, from offset 0 */
    uint64_t requested; /* end of the range asked for so far */
    int complete;       /* received and hash-checked */
    int failures;       /* transfers that failed the hash check */
    int pins;           /* BUILD items reading data */
    uint64_t used;      /* LRU tick */
    double last_chunk;  /* pf_now() of the last chunk (or of the request) */
    uint64_t *leaves;   /* chunk hashes from the coordinator's BLOB_PLAN (each chunk is checked), or NULL */
    uint32_t nleaves;
    int from_peer;      /* its chunks come from the peer source (peers.c), not the coordinator */
} s_blob;

/* peers.c: a worker this one serves blob chunks to (a routing identity on
 * the peer ROUTER) and the range it asked: chunks [next, hi) of blob hash. */
#define S_MAX_CHILDREN 16 /* transfers to children: (child, blob) pairs */
typedef struct s_child {
    int used;
    uint8_t id[256];
    size_t idlen;
    uint64_t hash, size, job;
    uint32_t next, hi;
    double last;
} s_child;

/* peers.c: strikes against a peer's routing identity (bounded table). */
typedef struct s_strike {
    uint8_t id[256];
    size_t idlen;
    int n;
} s_strike;

/* peers.c: a BLOB_PLAN of the coordinator's (one per blob: the JOB's scene
 * and maps come with a plan each, from the same source). */
typedef struct s_plan {
    uint64_t hash, size;
    uint32_t n;
    uint64_t *leaves;
    char source[PF_PROTO_MAX_SOURCE];
} s_plan;

/* What a job needs to render, built once per (scene hash, maps hash,
 * settings hash): the maps were validated against the settings hash, so a
 * job whose settings would change the maps must not reuse them. */
typedef struct s_built {
    uint64_t scene_hash, maps_hash, settings_hash;
    pf_frame_t frame;
    int refs; /* the cache's and each job's; main thread only */
} s_built;

typedef enum { S_JOB_FETCH, S_JOB_BUILD, S_JOB_READY, S_JOB_FAILED } s_job_state;

/* Tiles a worker asks for in READY (one rendering, two queued, so it never
 * idles); a TILE beyond them is dropped without allocating its buffer. */
#define PF_W_CREDIT 3

typedef struct s_job {
    uint64_t id;
    pf_msg_job_t desc;
    s_job_state state;
    s_built *built;      /* once built */
    pf_render_ctx_t ctx; /* once built; read-only for the compute thread */
    uint64_t dropped;    /* camera samples left out (ctx.dropped points here; atomic) */
    atomic_int cancelled;
    uint32_t held;       /* TILEs of this job held (queued or rendering), at most PF_W_CREDIT */
    struct {
        uint32_t tile, attempt;
    } held_tiles[PF_W_CREDIT];
    int refs;            /* the worker's current-job pointer and each work item; main thread only */
} s_job;

typedef enum { S_WORK_BUILD, S_WORK_TILE, S_WORK_PHOTONS, S_WORK_IRR } s_work_kind;

typedef struct s_work {
    struct s_work *next;
    struct s_work *next_build; /* the main thread's list of BUILD items not yet taken back */
    s_work_kind kind;
    s_job *job;
    /* S_WORK_TILE */
    pf_msg_tile_t tile;   /* its counts pointers cleared: the frame is gone */
    uint16_t *counts;     /* an adaptive pass's samples over tile.cx0.. (render.h's pf_spp_map_t), or NULL */
    float *rgb;
    uint32_t render_us;
    int rendered; /* every row done (not cancelled half-way) */
    /* S_WORK_BUILD */
    s_blob *scene_blob, *maps_blob; /* pinned while queued */
    s_built *built;                 /* the result, or NULL with error set */
    char error[1100];
    /* S_WORK_PHOTONS (scene_blob pinned too): batches [ph_first, ph_first +
     * ph_count) of the photon job, traced into ph_out (calloc'd, ph_count) */
    uint32_t ph_first, ph_count;
    struct pf_photon_batch *ph_out;
    double ph_s; /* the trace's wall time */
    /* S_WORK_IRR (scene_blob and maps_blob pinned): irradiance chunks
     * [ph_first, ph_first + ph_count) into irr_pts (chunk k at k *
     * PF_PROTO_IRR_CHUNK_POINTS, irr_n[k] points) */
    pf_photon_t *irr_pts;
    uint32_t *irr_n;
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
    const struct pf_worker_opts *opts; /* loop.h */
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
    char refusal[300]; /* the last refusal logged (printable), so a repeated one is not logged again */
    int plaintext_warned; /* the warning about a plaintext non-loopback endpoint was given */
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
    /* photons.c: the photon job (desc: the scene blob and the pass's
     * settings; maps unused), the batch ranges waiting for its scene blob;
     * the compute thread's own frame of that scene (accel and lights: built
     * once per scene hash, touched only by the compute thread; render frames
     * share it, compute.c). */
    s_job *pjob;
    pf_msg_photon_req_t ph_wait[4];
    int nph_wait;
    pf_frame_t ph_frame;
    uint64_t ph_frame_hash;
    int ph_frame_ok;
    /* irr.c: the chunk ranges waiting for their blobs; the compute
     * thread's maps (the global map of the irradiance's map blob, read
     * once per hash, touched only by the compute thread). */
    pf_msg_irr_req_t irr_wait[4];
    int nirr_wait;
    pf_photon_maps_t irr_maps;
    uint64_t irr_maps_hash;

    s_queue q;
    pthread_t compute;
    int compute_started;
    atomic_uint_fast64_t progress; /* pixels rendered since start */
    uint32_t tiles_held;           /* TILEs received and not yet answered or dropped */

    /* peers.c: fan-out. The ROUTER serving other workers and its port (0:
     * none), the children served, strikes; the DEALER to the current
     * source, sources struck; the latest plans (two blobs). */
    void *psrv;
    uint16_t peer_port;
    s_child children[S_MAX_CHILDREN];
    s_strike strikes[16];
    int nstrikes;
    unsigned peer_malformed;
    uint64_t peer_bytes_served;
    void *pfetch;
    char pfetch_ep[PF_PROTO_MAX_SOURCE];
    char bad_src[4][PF_PROTO_MAX_SOURCE];
    int nbad_src;
    s_plan plans[2];
    int plan_next; /* the slot the next plan of a new blob takes */
    pf_buf_t penc;

    int finished, exit_code;
} s_worker;

/* ---- jobs.c: jobs, blobs, results (main thread) ---- */

/* Message handlers for JOB, BLOB_CHUNK and TILE. */
void pf_w_on_job(s_worker *w, const pf_msg_t *m);
void pf_w_on_chunk(s_worker *w, const pf_msg_blob_chunk_t *c, int from_peer);
/* The rest of blob b comes from the coordinator (its peer source failed:
 * why says how), from its first byte not yet held. */
void pf_w_blob_fallback(s_worker *w, s_blob *b, const char *why);
void pf_w_on_tile(s_worker *w, const pf_msg_t *m);
/* Cancels the current job (if any); why goes to the debug log. */
void pf_w_job_drop(s_worker *w, const char *why);
/* Takes finished items back from the compute thread and sends the RESULTs. */
void pf_w_drain_done(s_worker *w);
/* Moves the transfers' stall clocks on by gap seconds (the loop was stopped). */
void pf_w_blobs_resume(s_worker *w, double gap);
/* Asks again for the needed transfers that have had no chunk for too long. */
void pf_w_blobs_check_stalls(s_worker *w, double now);
/* Frees the built scene cache and every blob (at exit, the compute thread joined). */
void pf_w_cache_free(s_worker *w);
/* The cached or in-transfer blob (hash, size), its transfer started when it
 * is not there; NULL when the size is absurd or memory is short. */
s_blob *pf_w_blob_get(s_worker *w, uint64_t hash, uint64_t size, const char *what);
/* Drops transfers no job needs and the least recently used blobs. */
void pf_w_blobs_trim(s_worker *w);

/* ---- peers.c: fan-out (main thread) ---- */

/* Binds the peer ROUTER (unless opts->peer_port < 0 or CURVE is on); the
 * port lands in w->peer_port. 0, or -1 when no socket can be made. */
int pf_w_peers_open(s_worker *w);
/* Closes both peer sockets and frees the plan (before zmq_ctx_term). */
void pf_w_peers_close(s_worker *w);
/* A BLOB_PLAN from the coordinator. */
void pf_w_on_plan(s_worker *w, const pf_msg_t *m);
/* A new blob transfer: the plan's chunk hashes and, when the plan names a
 * usable peer, the peer as its source (b->from_peer). */
void pf_w_peers_attach(s_worker *w, s_blob *b);
/* The current source misbehaved (why): never used again; its socket closed. */
void pf_w_peers_strike_source(s_worker *w, const char *why);
/* Sends m (a BLOB_REQ) to the current source. 0, or -1 (then ask the coordinator). */
int pf_w_peer_send(s_worker *w, const pf_msg_t *m);
/* Receives from both peer sockets without blocking, and pumps. */
void pf_w_peers_on_poll(s_worker *w);
/* Sends the children what they asked and this worker holds. */
void pf_w_peers_pump(s_worker *w);
/* 1 when some child waits for chunks (the loop polls briefly then). */
int pf_w_peers_busy(const s_worker *w);

/* ---- photons.c: the photon job ---- */

/* A PHOTON_REQ: its batches traced once the scene blob is here. */
void pf_w_on_photon_req(s_worker *w, const pf_msg_t *m);
/* A blob completed: batches waiting for it go to the compute thread. */
void pf_w_photons_advance(s_worker *w);
/* Cancels the photon job (if any): queued batches are dropped, a batch
 * being traced is not sent. */
void pf_w_photons_drop(s_worker *w, const char *why);
/* A PHOTONS item came back from the compute thread: its batches are sent. */
void pf_w_photons_sent(s_worker *w, s_work *it);
/* Compute thread: traces a PHOTONS item's batches. */
void pf_w_compute_photons(s_worker *w, s_work *it);
/* Compute thread: w->ph_frame made the frame of it's job's scene (accel,
 * lights; no maps) from it->scene_blob, built only when the scene differs
 * from the last one built. 0, or -1 with it->error set. */
int pf_w_scene_frame(s_worker *w, s_work *it);
/* The photon job for (job, scene blob, settings): the current one when
 * they match, else a new one (the old one dropped; `what` it is for goes
 * to the log); NULL when memory is short. */
s_job *pf_w_photons_job(s_worker *w, uint64_t job, uint64_t scene_hash, uint64_t scene_size,
                        const pf_settings_t *settings, const char *what);

/* ---- irr.c: the irradiance chunks of the photon job ---- */

/* An IRR_REQ: its chunks computed once the scene and map blobs are here. */
void pf_w_on_irr_req(s_worker *w, const pf_msg_t *m);
/* A blob completed: chunks waiting for it go to the compute thread. */
void pf_w_irr_advance(s_worker *w);
/* Compute thread: an IRR item's chunks. */
void pf_w_compute_irr(s_worker *w, s_work *it);
/* An IRR item came back: its chunks are sent (IRR_POINTS). */
void pf_w_irr_sent(s_worker *w, s_work *it);

/* ---- compute.c: the compute thread, its queue and the work items ---- */

/* Drop one reference; the last one frees. NULL-safe. A fresh s_built may
 * also be released by the compute thread that made it (no one else holds it). */
void pf_w_built_release(s_built *b);
/* Drops one reference to a job; the last one frees it (and releases its build). NULL-safe. */
void pf_w_job_release(s_job *j);
/* Frees a work item, unpinning its blobs and releasing its job and build. NULL-safe. */
void pf_w_work_free(s_work *it);


/* Sets up the queue's mutex, condition variable and wake-up pipe. 0, or
 * -1 after a message on stderr. */
int pf_w_queue_init(s_queue *q);
/* Starts the compute thread (SIGINT and SIGTERM blocked in it). 0, or
 * -1 after a message on stderr. */
int pf_w_compute_start(s_worker *w);
/* Stops and joins the compute thread, if started, and frees what is left in
 * its lists. */
void pf_w_compute_stop(s_worker *w);
/* Closes the wake-up pipe and destroys the mutex and condition variable, if
 * pf_w_queue_init got that far. */
void pf_w_queue_destroy(s_queue *q);
/* Hands it to the compute thread (appends to the todo list). */
void pf_w_enqueue(s_worker *w, s_work *it);
/* Takes the queued (not yet started) items of job out of the queue and
 * returns them, linked by next, for the caller to free. */
s_work *pf_w_unqueue_job(s_worker *w, const s_job *job);
/* Empties the wake-up pipe and takes the whole done list (linked by next). */
s_work *pf_w_take_done(s_worker *w);

/* ---- outbox.c: logging and sending (main thread; pf_w_log any thread) ---- */

/* Logs with the worker's name, so lines from several local workers sharing
 * a terminal can be told apart. */
void pf_w_log(const s_worker *w, pf_log_level level, const char *fmt, ...) __attribute__((format(printf, 3, 4)));

/* Encodes and sends msg without blocking. When the socket cannot take it
 * now (no connection yet, or the high-water mark), a droppable message
 * (HEARTBEAT) is dropped and any other waits in the outbox, in order. */
void pf_w_send(s_worker *w, const pf_msg_t *msg, int droppable);
/* Sends what waits in the outbox, in order, as far as the socket takes it. */
void pf_w_flush(s_worker *w);
/* Drops what waits in the outbox (the socket is closing). */
void pf_w_outbox_clear(s_worker *w);

#endif
