/* irr_chunks.h: the irradiance precompute spread over the workers: the
 * table of a pass's irradiance chunks that the coordinator's photon thread
 * and the farm's event loop share.
 *
 * The points of the precompute (pf_photon_irr_plan: `points` of them for
 * the irradiance map, and as many again for the deep one when there is
 * one) are cut into chunks of PF_PROTO_IRR_CHUNK_POINTS by index: chunk c
 * < C holds points [c * 4096, ...) of the irradiance map, chunk C + c the
 * same points of the deep map. The photon thread computes chunks itself
 * (pf_irq_run: runs of free ones from the end of the table, workers being
 * leased from its start; else the oldest leased one not yet back, so it
 * never waits on a worker); the event loop leases free ranges to
 * idle workers (pf_irq_lease) and takes their IRR_POINTS in
 * (pf_irq_on_points). Each record lands at its index in the caller's
 * arrays, so the map built from them is the in-process one, bit for bit,
 * whoever computed which chunk.
 *
 * Worker results are hostile input: a chunk must come whole, from the
 * worker it was leased to, with exactly the chunk's point count; each
 * record's position and normal must be the global photon's it stands at
 * (the coordinator holds the global map), its irradiance finite and >= 0
 * (the decoder's check) and its support radius finite, >= 0 and within
 * the global search radius. Anything else is refused (the caller strikes
 * the sender) and the chunk is free again. Spot checks: each worker's
 * first chunk, and about one in one_in of the rest (drawn from a secret),
 * is computed again here and compared bit for bit; a mismatch bars the
 * worker, discards every chunk it returned and queues it for a strike.
 *
 * Threads: every function takes the table's mutex; pf_irq_run computes
 * outside it. */
#ifndef PF_IRR_CHUNKS_H
#define PF_IRR_CHUNKS_H

#include <stdint.h>

#include "photon/trace.h"
#include "proto/messages.h"

typedef struct pf_irq pf_irq_t;

/* A table for plan's points over global (with accel: the scene's), whose
 * records go to main[0 .. plan->points) and deep[...] (with has_deep).
 * global, accel and the arrays must outlive pf_irq_run; the table keeps
 * no pointer into them after pf_irq_run returned. NULL when memory is short. */
pf_irq_t *pf_irq_new(const pf_kdtree_t *global, const pf_accel_t *accel, const pf_irr_plan_t *plan,
                     pf_photon_t *main, pf_photon_t *deep);
void pf_irq_free(pf_irq_t **q_p); /* NULL-safe; nulls *q_p */
/* Spot checks: about one in one_in of a worker's chunks beyond its first
 * (0: only the first), drawn with secret. */
void pf_irq_checks(pf_irq_t *q, uint64_t secret, uint32_t one_in);
/* Chunks in all (both maps). */
uint32_t pf_irq_chunks(const pf_irq_t *q);

/* The photon thread: computes chunks (threads OpenMP threads) until every
 * chunk is done and checked. 0 or PF_ENOMEM. After it the table takes no
 * more results (all are stale). */
int pf_irq_run(pf_irq_t *q, int threads);

/* Leases up to count consecutive free chunks to worker uid; *first gets
 * the first; how many (0: none free, uid barred, or the table closed). */
uint32_t pf_irq_lease(pf_irq_t *q, uint32_t uid, uint32_t count, double now, uint32_t *first);
uint32_t pf_irq_held(pf_irq_t *q, uint32_t uid);
/* uid's leased chunks go back to the free list; how many. */
uint32_t pf_irq_release(pf_irq_t *q, uint32_t uid);
/* Leases older than timeout_s go back; how many. */
uint32_t pf_irq_expire(pf_irq_t *q, double now, double timeout_s);

enum { PF_IRQ_DONE = 1, PF_IRQ_STALE = 2, PF_IRQ_BAD = -1 };
/* An IRR_POINTS (decoded: PHOTONS' body) from worker uid: PF_IRQ_DONE (its
 * chunk is in), PF_IRQ_STALE (done already, or not leased to uid: dropped),
 * or PF_IRQ_BAD (why says how; the chunk is free again). */
int pf_irq_on_points(pf_irq_t *q, uint32_t uid, const pf_msg_photons_t *p, char *why, size_t why_len);

/* A worker the spot checks caught: 1 with its uid and a sentence, 0: none. */
int pf_irq_take_liar(pf_irq_t *q, uint32_t *uid, char *why, size_t why_len);

typedef struct pf_irq_stats {
    uint32_t chunks, local, remote;
    uint64_t stale, expired, stolen, checked, mismatches, discarded;
} pf_irq_stats_t;
void pf_irq_stats(pf_irq_t *q, pf_irq_stats_t *out);

#endif
