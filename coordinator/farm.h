/* farm.h: a render job served to worker processes over ZeroMQ. The
 * coordinator traces the photon maps once (in a thread, while the main loop
 * already answers workers), serializes the scene and the maps, and leases
 * image tiles to workers; results are validated and stitched. Workers may be
 * local processes this module starts (--workers N) or cluster workers that
 * connect to a bound endpoint. */
#ifndef PF_FARM_H
#define PF_FARM_H

#include <stdint.h>

#include "coordinator/budget.h"
#include "image/image.h"
#include "photon/trace.h"
#include "scene/scene.h"

typedef struct pf_farm_opts {
    const char *bind;         /* endpoint to bind; NULL: ipc:// in a private 0700 directory, for the local
                                 workers only (tcp://127.0.0.1:* when no directory can be made) */
    int local_workers;        /* worker processes to start on this machine */
    int worker_threads;       /* threads per local worker (0: cores / workers, at least 1) */
    int min_workers;          /* tiles are not leased before this many workers are ready */
    const char *worker_exe;   /* NULL: photonfarm-worker beside this executable */
    int tile_size;            /* pixels per tile side (default 32) */
    int heartbeat_ms;         /* default 1000 */
    int dead_after;           /* heartbeat intervals of silence before a worker is dead (default 4) */
    double lease_timeout_s;   /* a lease older than this returns its tile to the queue and strikes its holder
                                 (default 120) */
    double watchdog_s;        /* a worker holding tiles with no RESULT for this long (or 8 typical tile times if
                                 longer) is stuck: its tiles are re-issued, it gets none until a RESULT (default 30) */
    double max_wait_s;        /* give up when no worker has been ready for this long (0: wait forever) */
    const char *curve_secret; /* coordinator key file (public + secret), NULL: no CURVE */
    const char *curve_allow;  /* file of allowed worker public keys (required with curve_secret) */
    int show_progress;
    pf_budget_t *budget;      /* a time limit: progressive passes until its deadline, their photons and spp planned
                                 on the coordinator (NULL: none) */
    int passes;               /* progressive passes (job.h): each a job of its own maps, the image their running
                                 mean (0 or 1: one pass, unless a time limit) */
    const char *checkpoint;   /* where the render's progress is kept (checkpoint.h): after each pass and every
                                 PF_FARM_CKPT_S seconds while tiles come in; removed when the render ends well.
                                 NULL: none */
    int resume;               /* go on from the checkpoint (none there: start afresh; another render's: an
                                 error) */
    /* Budgets against hostile peers (docs/farm.md, "Hostile peers"). */
    int max_workers;          /* registry slots; dead ones are reused (default 1024) */
    double hello_rate;        /* HELLOs served per second, all peers together; the excess is dropped (default 100;
                                 0: no limit) */
    int max_strikes;          /* strikes (malformed or out-of-turn messages, expired leases, stalls) before a
                                 worker is evicted and blocked for the rest of the job (default 8; 0: never) */
    int blob_window;          /* blob chunks in flight per worker, whatever its BLOB_REQ asks (default 8) */
    int fanout;               /* a worker serves the maps to at most this many other workers (fanout.h; default
                                 2; 0: every worker fetches from the coordinator; off with CURVE, whose peer
                                 sockets would be plaintext) */
    int send_hwm;             /* ZMQ_SNDHWM and ZMQ_RCVHWM, in messages per peer (default 256) */
    int credit_per_thread;    /* tiles a worker may hold per thread it announced (default 2); also at most its fair
                                 share of the tiles left, and 2 + the results it has returned */
    double takeover_factor;   /* with the queue empty, a lease older than this many typical tile times (and
                                 takeover_min_s) goes to an idle worker that never held it (default 4; 0: never) */
    double takeover_min_s;    /* (default 2) */
    double verify;            /* fraction of tiles rendered again on a second worker and compared bit for bit,
                                 besides each worker's first result once another worker can check it (default
                                 0.02; 0: no checks) */
    int photons_here;         /* every photon pass is traced on the coordinator alone, not spread over the
                                 workers in batches (farm_photons.c) */
    uint32_t photon_check;    /* about one worker photon batch in this many is traced again here and compared
                                 bit for bit, and at least one of each worker's a pass (default 16; 0: none) */
} pf_farm_opts_t;

void pf_farm_opts_default(pf_farm_opts_t *o);

/* Seconds between checkpoints of a pass's tiles. */
#define PF_FARM_CKPT_S 5.0

typedef struct pf_farm_worker_stat {
    char name[64];
    uint64_t tiles;
    uint64_t photon_batches; /* photon batches it traced, all passes (ph_batches.h) */
} pf_farm_worker_stat_t;

typedef struct pf_farm_summary {
    pf_photon_stats_t photons;
    double photon_s, render_s, total_s;
    uint64_t bytes_sent, blob_bytes, results;
    /* Fan-out: the sizes of the scene and maps blobs over the passes, the
     * payload bytes of each the coordinator sent; workers told to fetch the
     * maps from a peer, and told to come back to the coordinator (their
     * source gone). */
    uint64_t scene_blob_size, scene_blob_sent, maps_blob_size, maps_blob_sent;
    uint64_t fanout_peer, fanout_fallback;
    uint64_t fanout_scene_peer; /* scene plans (BLOB_PLAN) that named a peer as the source */
    uint64_t reissued, duplicates, malformed, refused;
    int workers_seen, workers_lost;
    /* Hostile peers: what was refused, dropped, evicted. */
    uint64_t strikes, evicted, evicted_frames, hellos_dropped, blocked, blob_ignored, results_refused;
    uint64_t expired, stalls, takeovers, slots_reused;
    /* Verification (--verify): tiles checked on a second worker, mismatches, tiles rendered in the coordinator
     * to decide, liars evicted (their names) and their tiles rendered again. */
    uint64_t verified, mismatches, verify_local, liars, rerendered;
    char liar_names[256];
    pf_farm_worker_stat_t per_worker[64];
    int nper_worker;
    size_t bad_pixels;
    /* Progressive passes, as pf_job_summary_t has them. */
    int passes, passes_whole, cut_tiles, cut_total, interrupted;
    uint64_t spp_total, photons_total;
    double error_est, photon_total_s;
    size_t unreached;
    pf_settings_t settings; /* the last pass's */
    /* The photon passes, spread over the workers (ph_batches.h), all
     * passes together: their batches, those traced here and by workers,
     * worker results dropped as late or duplicate, leases expired, batches
     * traced here while leased; their photons emitted and the tracing's
     * wall time; worker batches checked here, mismatches (each a strike)
     * and worker batches discarded after one. */
    uint64_t ph_batches, ph_local, ph_remote, ph_stale, ph_expired, ph_stolen, ph_emitted;
    double ph_trace_s;
    uint64_t ph_checked, ph_mismatches, ph_discarded;
} pf_farm_summary_t;

/* Renders scene with settings through workers into *img (allocated here).
 * Blocks until the image is complete, an error, or *stop becomes non-zero
 * (PF_EINTERRUPTED; with progressive passes, the image of the passes done
 * and summary->interrupted, unless no tile was done). Local workers are
 * stopped on every path. */
int pf_farm_render(const pf_scene_t *scene, const pf_settings_t *settings, unsigned terms, const pf_farm_opts_t *opts,
                   volatile int *stop, pf_image_t *img, pf_farm_summary_t *summary, pf_error_t *err);

/* Prints the summary as log lines. */
void pf_farm_summary_log(const pf_farm_summary_t *s);

#endif
