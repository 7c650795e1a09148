/* farm_impl.h: what the farm's two files share (not a public interface):
 * farm.c (the photon thread, the event loop, housekeeping and the job's
 * steps) and farm_peers.c (the conversation with workers: sending, leasing,
 * receiving, strikes and eviction). One thread, the event loop's, calls
 * every pf_fm_ function. */
#ifndef PF_FARM_IMPL_H
#define PF_FARM_IMPL_H

#include <pthread.h>
#include <stdint.h>
#include <sys/types.h>

#include "coordinator/accum.h"
#include "coordinator/budget.h"
#include "coordinator/checkpoint.h"
#include "coordinator/fanout.h"
#include "coordinator/leases.h"
#include "coordinator/ph_batches.h"
#include "coordinator/progress.h"
#include "coordinator/registry.h"
#include "coordinator/transfer.h"
#include "coordinator/zap.h"
#include "image/image.h"
#include "photon/trace.h"
#include "proto/messages.h"
#include "render/frame.h"

#define PF_FM_MAX_LOCAL 256

/* The photon pass, run in its own thread. */
typedef struct pf_fm_photons {
    const pf_scene_t *scene;
    pf_settings_t base;     /* the render's settings */
    pf_settings_t settings; /* this pass's: its seed and index; a time limit plans them here, before the job
                               goes out */
    int pass;               /* the progressive pass traced (0: the first, or the only one) */
    int progressive;
    int no_pass;            /* set by the thread: no pass fits in the time left (nothing was traced) */
    /* Passes after the first are traced while the workers gather the one
     * before: into these maps, which replace the frame's when their pass
     * begins (pf_fm_pass_begin); photon_s is the trace's wall time. */
    pf_photon_maps_t next;
    double photon_s;
    int given;              /* the settings are given (a resumed pass): nothing is planned */
    int into_next;          /* the thread traced into next (every pass but a fresh first one) */
    pf_budget_t *budget;
    unsigned terms;
    uint64_t job;
    pf_frame_t frame; /* the scene's accel and lights, then the maps */
    pf_photon_stats_t stats;
    pf_framed_blob_t scene_fb, maps_fb; /* the blobs, cut into chunk frames */
    /* Every pass's photons spread over the workers (farm_photons.c):
     * spread says they may be; for the first pass the thread frames the
     * scene blob early (the workers trace over it; a later pass's is the
     * JOB's, with the blob server already: early_from_job), makes the batch
     * table and then sets phq_ready; the event loop publishes the blob,
     * leases batches, and frees the table once the thread is joined.
     * check_secret (drawn per run) and check_one_in drive the spot checks. */
    int spread;
    int early_from_job;
    pf_framed_blob_t early_fb;
    uint64_t early_hash, early_size;
    uint64_t check_secret;
    uint32_t check_one_in;
    pf_photon_tracer_t *tracer;
    pf_phq_t *phq;
    int phq_ready; /* atomic */
    uint64_t scene_hash, maps_hash, scene_size, maps_size;
    int rc;
    volatile int done;
    pf_error_t err;
} pf_fm_photons_t;

typedef struct pf_fm_limit {
    double tokens, at;
    unsigned long held;
} pf_fm_limit_t;

typedef struct pf_fm {
    const struct pf_farm_opts *o; /* farm.h (not included here: farm.c includes this file) */
    void *ctx, *sock;
    uint64_t job;
    pf_registry_t reg;
    pf_leases_t L;
    pf_xfer_t *xfer;
    pf_fanout_t *fan;       /* the maps blob's fan-out tree (fanout.c) */
    pf_fanout_t *fan_scene; /* the first photon pass's scene blob's (the early blob: workers trace over it) */
    int fan_scene_on;       /* fan_scene holds that blob; its plans go out before a worker's first PHOTON_REQ */
    const char *frame_addr; /* the address libzmq gives the frame being handled (Peer-Address), or NULL */
    pf_fm_photons_t ph;
    pf_msg_job_t jobmsg;
    int job_ready;
    pf_image_t *img;
    pf_buf_t out;
    float *pix; /* one tile's pixels, decoded from a RESULT */
    struct pf_farm_summary *sum;
    pf_fm_limit_t bad_log, strike_log, hello_log, peer_log; /* peer_log: joins, leaves, deaths */
    int leasing; /* tiles have been leased: --min-workers was met once */
    /* What pf_farm_render's steps share: the job's clock, what it started
     * (and must stop), and the event loop's clocks. */
    double t0;          /* when the job began */
    int ts;             /* tile side in pixels */
    char endpoint[256]; /* where the socket listens, for the local workers */
    char ipcdir[160];   /* the private directory of the ipc:// socket (local workers only), "" */
    pf_zap_t *zap;
    pid_t pids[PF_FM_MAX_LOCAL];
    int npids;
    pthread_t phtid;
    int ph_started; /* the photon thread runs and has not been joined */
    pf_progress_t bar;
    double render_start, last_log, no_worker_since;
    /* Verification (verify.c): per tile, its check's state and the uid whose
     * result is in the image (0: rendered here); a tile rendered here. */
    uint8_t *vstate;
    uint32_t *kept;
    double *vsince; /* when a check was asked */
    float *lpix;
    int frame_readied;
    /* Liars verify.c found and farm_peers.c evicts (pf_fm_evict_pending):
     * verify.c judges, farm_peers.c acts, so neither calls the other back. */
    uint32_t evict_uid[16];
    char evict_why[16][96];
    int nevict;
    /* Progressive passes (farm_pass.c): the running mean, the first job id
     * (pass i is job job0 + i), when this pass's tiles began, the pass being
     * gathered and its settings (the photon thread may be tracing the next
     * one meanwhile: f->ph.settings are its). */
    pf_accum_t acc;
    uint64_t job0;
    double pass_start;
    int cur_pass;
    pf_settings_t cur;
    /* Checkpoints (farm_pass.c): the render's key, when the last was
     * written and how many tiles it held; the checkpoint resumed from, its
     * tiles put in when its pass begins (resumed_pass: that pass, -1). */
    uint64_t ckpt_key;
    double ckpt_at;
    int ckpt_done;
    pf_ckpt_t resumed;
    int resumed_pass;
    int ph_published; /* the early scene blob is with the blob server */
} pf_fm_t;

/* farm_peers.c */

/* A log line that may come once per message of a flood: 1 when it may be
 * printed (at most rate lines a second, a burst of twice that). */
int pf_fm_may_log(pf_fm_limit_t *l, double rate);
/* A malformed message from peer (a phrase: "worker NAME"), counted and
 * logged (rate-limited). */
void pf_fm_bad(pf_fm_t *f, const char *peer, const char *why);
/* Sends m to worker wi (the job id filled in). 0, or -1: its queue is full,
 * or it is gone (then it is declared dead). */
int pf_fm_send(pf_fm_t *f, int wi, pf_msg_t *m);
/* Sends the JOB; the worker is JOB_SENT when it went out. */
void pf_fm_send_job(pf_fm_t *f, int wi);
/* Revokes a worker's leases, logged with why (NULL: only when it held any). */
void pf_fm_release_worker(pf_fm_t *f, int wi, const char *why);
/* The worker is dead (silent or disconnected): its leases are revoked. */
void pf_fm_declare_dead(pf_fm_t *f, int wi, const char *why);
/* A strike against a live worker, with why; past max_strikes it is evicted. */
void pf_fm_strike(pf_fm_t *f, int wi, const char *why);
/* Leases tiles to every worker with room (once min_workers were ready). */
void pf_fm_lease_all(pf_fm_t *f);
/* Hands libzmq what worker wi's blob transfer window lets through. */
void pf_fm_pump(pf_fm_t *f, int wi);
/* Evicts worker wi (why: a phrase): BYE, its tiles re-queued, its slot
 * freed, its identity, name and key blocked for the rest of the job. */
void pf_fm_evict(pf_fm_t *f, int wi, const char *why);
/* Evicts the live workers verify.c queued as liars (f->evict_uid). */
void pf_fm_evict_pending(pf_fm_t *f);
/* One frame from routing identity id (key: its CURVE key, or NULL). */
void pf_fm_on_frame(pf_fm_t *f, const uint8_t *id, size_t idlen, const char *key, const uint8_t *data, size_t len);

/* farm_pass.c */

/* Whether the render is progressive (more than one pass may be rendered). */
int pf_fm_progressive(const pf_fm_t *f);
/* Every tile of the current pass is done: adds the pass to the running
 * mean; logs it. */
void pf_fm_pass_whole(pf_fm_t *f);
/* The render stops inside a pass (deadline, signal): the tiles of the
 * current pass that are done go into the running mean. */
void pf_fm_pass_cut(pf_fm_t *f);
/* 1 when another pass should follow the one just added. */
int pf_fm_pass_more(const pf_fm_t *f, volatile int *stop);
/* Readies the tables for the next pass (leases, checks, the workers'
 * transfer state; the next job id, so the finished pass's late messages are
 * stale): its JOB goes out when its photon pass is done. 0 or PF_ENOMEM. */
int pf_fm_pass_reset(pf_fm_t *f, pf_error_t *err);
/* The settings of pass `pass` as the photon thread is to trace it (the
 * render's, its index and seed; under a time limit, its photons planned).
 * 1 when no pass fits in the time left. */
int pf_fm_pass_plan(pf_fm_t *f, int pass, pf_settings_t *s);
/* The running mean into f->img. */
void pf_fm_pass_resolve(pf_fm_t *f);
/* Writes the checkpoint (if the render keeps one): the passes done and the
 * tiles of the pass under way; `force`: now, else only when PF_FARM_CKPT_S
 * have passed and tiles came in. Logs (once) when it cannot. */
void pf_fm_checkpoint(pf_fm_t *f, int force);
/* The checkpoint to resume from (opts->resume): read and checked into
 * f->resumed, its passes' sums into f->acc; resumed_pass set. 0 (also when
 * there is none: a fresh start), or a status with err filled. */
int pf_fm_resume_load(pf_fm_t *f, const pf_scene_t *scene, const pf_settings_t *s, unsigned terms, pf_error_t *err);
/* Puts the resumed tiles into the image and marks them done, as the
 * resumed pass begins. */
int pf_fm_resume_tiles(pf_fm_t *f, pf_error_t *err);

/* farm_photons.c */

/* Photon thread: the pass's photons traced in batches, here and on the
 * workers, merged and built into maps (pf_phq_*). 0 or a status. */
int pf_fm_photons_spread(pf_fm_photons_t *p, pf_photon_maps_t *maps);
/* Event loop: publishes the scene blob, expires leases, leases batches to
 * idle welcomed workers. */
void pf_fm_photons_tick(pf_fm_t *f);
/* A PHOTONS from worker wi. */
void pf_fm_on_photons(pf_fm_t *f, int wi, const pf_msg_t *m);
/* 1 when worker wi (welcomed, no JOB yet) may fetch blob `hash`: the scene
 * blob of the photon pass it was asked to trace. */
int pf_fm_photons_blob_ok(const pf_fm_t *f, int wi, uint64_t hash);
/* Worker wi's photon batches go back to the free list; how many. */
int pf_fm_photons_release(pf_fm_t *f, int wi);
/* The photon thread is joined: the table's figures into the summary, the
 * table freed, a log line. */
void pf_fm_photons_end(pf_fm_t *f);

/* farm_peers.c: fan-out (the tree: fanout.c) */
/* The scene's BLOB_PLAN for worker wi before its first PHOTON_REQ of the
 * first photon pass (fan_scene_on), when the early scene blob is fanned out. */
void pf_fm_fanout_scene(pf_fm_t *f, int wi);

/* Before worker wi's JOB: its BLOB_PLAN (where to fetch the maps, and their
 * chunk hashes); nothing when there is no plan. */
void pf_fm_fanout_job(pf_fm_t *f, int wi);
/* Worker wi is dead, gone or evicted: its children still fetching are told
 * to fetch from the coordinator. */
void pf_fm_fanout_gone(pf_fm_t *f, int wi);

/* verify.c */

/* The per-tile tables (with the tile table). 0 or PF_ENOMEM. */
int pf_fm_verify_init(pf_fm_t *f);
void pf_fm_verify_free(pf_fm_t *f);
/* A RESULT (its pixels in f->pix) for a tile being checked: compared with
 * the kept one, and a mismatch decided. 1 when it was such a RESULT, 0 when
 * the caller stores it as the tile's result. */
int pf_fm_verify_result(pf_fm_t *f, int wi, const pf_msg_result_t *r);
/* Worker wi's result for tile ti was stored: maybe picked for a check. */
void pf_fm_verify_kept(pf_fm_t *f, int wi, int ti);
/* Checks no other worker can take are made here. */
void pf_fm_verify_tick(pf_fm_t *f);

#endif
