/* ph_batches.h: the photon pass spread over the workers: the table of a
 * pass's photon batches (photon/trace.h) that the coordinator's photon
 * thread and the farm's event loop share.
 *
 * The photon thread traces batches itself (pf_phq_run): the first free one,
 * or, when none is free, the oldest one leased to a worker and not yet back
 * (work stealing), so it never waits on a worker and a farm without workers
 * is as fast as the in-process pass. The event loop leases free batches to
 * idle workers (pf_phq_lease) and takes their PHOTONS in (pf_phq_on_photons).
 * The first complete result of a batch wins; a later or duplicate one is
 * dropped (and a local trace of a batch a worker has just returned stops at
 * its next block). A worker that dies or leaves gives its batches back
 * (pf_phq_release); a lease older than the timeout returns to the free list
 * (pf_phq_expire). When every batch is done, pf_phq_merge joins them in batch
 * order and builds the maps: the same bits whoever traced what.
 *
 * Spot checks (pf_phq_checks): the photon thread re-traces a sample of the
 * batches workers returned and compares them bit for bit before the merge:
 * each worker's batch with probability 1/one_in, drawn from a hash of a
 * per-run secret (the workers cannot tell which), the batch and the worker,
 * and, once every batch is in, one more of each worker that had none
 * checked. A mismatch bars the worker from the pass (its leases revoked,
 * every batch it returned discarded and traced again) and is queued for
 * the event loop (pf_phq_take_liar), which strikes it.
 *
 * Threads: every function takes the table's mutex; pf_phq_run traces
 * outside it. */
#ifndef PF_PH_BATCHES_H
#define PF_PH_BATCHES_H

#include <stdint.h>

#include "photon/trace.h"
#include "proto/messages.h"

typedef struct pf_phq pf_phq_t;

/* A table for the tracer's plan (the tracer must outlive it). NULL when
 * memory is short. */
pf_phq_t *pf_phq_new(const pf_photon_tracer_t *tracer, int max_depth);
void pf_phq_free(pf_phq_t **q_p); /* NULL-safe; nulls *q_p */
/* Turns spot checks on (before pf_phq_run): about one worker batch in
 * one_in (0: no checks; 1: all), drawn with `secret`. */
void pf_phq_checks(pf_phq_t *q, uint64_t secret, uint32_t one_in);
/* A worker caught returning a batch unlike the coordinator's trace: 1 with
 * its uid and a sentence (taken off the queue), 0 when there is none. */
int pf_phq_take_liar(pf_phq_t *q, uint32_t *uid, char *why, size_t why_len);
/* Batches done and batches in all (for the event loop's pacing). */
void pf_phq_progress(pf_phq_t *q, uint32_t *done, uint32_t *total);

/* The photon thread: traces batches (threads OpenMP threads) until every
 * batch is done, as above. 0, or PF_EINTERRUPTED (the process-wide cancel
 * flag), PF_ENOMEM. */
int pf_phq_run(pf_phq_t *q, int threads);

/* Leases up to `count` consecutive free batches to worker uid; *first gets
 * the first. Returns how many (0: none free, or uid is barred). */
uint32_t pf_phq_lease(pf_phq_t *q, uint32_t uid, uint32_t count, double now, uint32_t *first);
/* Batches leased to uid and not yet done. */
uint32_t pf_phq_held(pf_phq_t *q, uint32_t uid);
/* Returns uid's leased batches to the free list (how many); its partial
 * results go. */
uint32_t pf_phq_release(pf_phq_t *q, uint32_t uid);
/* Leases older than timeout_s return to the free list; how many did. */
uint32_t pf_phq_expire(pf_phq_t *q, double now, double timeout_s);

enum { PF_PHQ_PART = 0, PF_PHQ_DONE = 1, PF_PHQ_STALE = 2, PF_PHQ_BAD = -1 };
/* A PHOTONS from worker uid: PF_PHQ_PART (a part taken, more to come),
 * PF_PHQ_DONE (its batch is complete: the worker's), PF_PHQ_STALE (the batch
 * is done already, or no longer leased to uid: dropped), or PF_PHQ_BAD (it
 * contradicts the plan or the earlier parts: why says how; the partial batch
 * is dropped and the batch is free again). */
int pf_phq_on_photons(pf_phq_t *q, uint32_t uid, const pf_msg_photons_t *p, char *why, size_t why_len);

/* Joins the batches and builds the maps (pf_photon_merge_spread: spread
 * computes the irradiance points, NULL: here). Call after
 * pf_phq_run returned 0. */
int pf_phq_merge(pf_phq_t *q, const pf_scene_t *scene, const pf_accel_t *accel, const pf_settings_t *settings,
                 pf_photon_maps_t *maps, pf_photon_stats_t *stats, const pf_irr_spread_t *spread);

/* Who traced what: batches in all, by the coordinator, by workers (the
 * results kept); photons emitted in all; stale results dropped; leases
 * expired; workers' batches re-traced here to check them, mismatches, and
 * workers' batches discarded after a mismatch. */
typedef struct pf_phq_stats {
    uint32_t batches, local, remote;
    uint64_t emitted, stale, expired, stolen;
    uint64_t checked, mismatches, discarded;
} pf_phq_stats_t;
void pf_phq_stats(pf_phq_t *q, pf_phq_stats_t *out);

#endif
