/* leases.h: the tiles of one farm job and their leases: the queue of tiles
 * waiting, who holds each lease, who may still return each tile, and how
 * long tiles take.
 *
 * A lease is (tile, attempt) granted to one worker, named by its registry
 * uid (never by its slot, which a later worker may reuse). A tile keeps its
 * last PF_LEASES_LESSEES leases: a RESULT counts only from one of them, with
 * the attempt it was leased, so a worker that lost a lease (dead, stuck,
 * taken over) may still deliver it, and nobody else can. Revoking a lease
 * puts the tile at the front of the queue with the next attempt number; the
 * next worker to lease it is, where possible, one that never held it.
 *
 * Plain data read by the farm; the functions keep the invariants: a tile is
 * in the queue iff it is QUEUED, and each worker's `held` counts the LEASED
 * tiles it owns. Called from the farm's event loop only. */
#ifndef PF_LEASES_H
#define PF_LEASES_H

#include <stdint.h>

#include "coordinator/registry.h"
#include "proto/messages.h"

enum { PF_T_QUEUED = 0, PF_T_LEASED, PF_T_DONE };

#define PF_LEASES_LESSEES 8
#define PF_LEASES_TIMES 32 /* tile times kept for the typical one */

typedef struct pf_lessee {
    uint32_t uid, attempt;
    double at; /* when the lease was granted */
} pf_lessee_t;

typedef struct pf_tile {
    int state;
    uint32_t attempt;   /* of the current lease, or of the next one while queued */
    int owner;          /* slot of the current lease's worker, -1 */
    uint32_t owner_uid; /* and its uid (the slot alone could be someone else's by now) */
    double leased_at;
    pf_lessee_t lessees[PF_LEASES_LESSEES]; /* oldest first */
    int nlessees;
    uint32_t x0, y0, w, h;
    uint32_t not_uid;   /* a worker that may not lease it again (verification: the one whose result was
                           kept, or a liar), 0: none; its RESULTs for the tile are duplicates */
} pf_tile_t;

typedef struct pf_leases {
    pf_tile_t *t;
    int nt, ndone;
    int *queue; /* tile indices, a ring of nt */
    int qhead, qlen;
    double times[PF_LEASES_TIMES]; /* seconds from lease to RESULT of recent tiles */
    int ntimes, itime;
    uint64_t reissued, duplicates;
} pf_leases_t;

/* Tiles of side ts over a width x height image, all queued in row order;
 * the last quarter of them (ts >= 16) split in four, in row order within
 * each, so the job ends on small tiles. 0 or PF_ENOMEM. */
int pf_leases_init(pf_leases_t *L, int width, int height, int ts);
void pf_leases_free(pf_leases_t *L);

/* The queue position of the tile to lease to worker wi next: the first one
 * it never held, or failing that the first one no other ready worker (not
 * stuck, never its holder) could take. -1 when none. */
int pf_leases_pick(const pf_leases_t *L, const pf_registry_t *r, int wi);

/* Leases the tile at queue position pos to worker wi; returns its index. */
int pf_leases_grant(pf_leases_t *L, pf_registry_t *r, int pos, int wi, double now);

/* The TILE for a lease just granted could not be sent: back to the front of
 * the queue as if never leased. */
void pf_leases_ungrant(pf_leases_t *L, pf_registry_t *r, int ti);

/* Revokes tile ti's current lease: the tile goes to the front of the queue
 * with the next attempt (counted as re-issued). Its holder stays a lessee. */
void pf_leases_revoke(pf_leases_t *L, pf_registry_t *r, int ti);

/* Revokes every lease worker wi holds; returns how many. */
int pf_leases_release(pf_leases_t *L, pf_registry_t *r, int wi);

/* What a RESULT from worker wi is worth. */
enum { PF_RESULT_NEW, PF_RESULT_DUPLICATE, PF_RESULT_REFUSED };
/* PF_RESULT_NEW: the first valid result for its tile (the caller stores the
 * pixels, then calls pf_leases_complete); DUPLICATE: from a lessee, for a
 * tile already done (counted in duplicates); REFUSED: not a lease of this worker's, with
 * why (a sentence). */
int pf_leases_check(pf_leases_t *L, const pf_registry_t *r, int wi, const pf_msg_result_t *res, char *why,
                    size_t why_len);
/* Marks the RESULT's tile done (the pixels are in the image). */
void pf_leases_complete(pf_leases_t *L, pf_registry_t *r, int wi, const pf_msg_result_t *res, double now);

/* Marks tile ti done without a RESULT (it was rendered in the
 * coordinator): its lease, if any, is dropped, or it leaves the queue. */
void pf_leases_finish(pf_leases_t *L, pf_registry_t *r, int ti);

/* Reopens done tile ti (verification, or a liar's tile to render again):
 * it goes to the front of the queue with the next attempt, and worker
 * not_uid (0: none) may not lease it. 0, or -1 when ti is not done. */
int pf_leases_reopen(pf_leases_t *L, int ti, uint32_t not_uid);

/* The tile of the oldest lease, granted more than min_age ago, or -1. */
int pf_leases_oldest(const pf_leases_t *L, double now, double min_age);

/* 1 when the worker with this uid held a lease of tile t (current or past,
 * among the last PF_LEASES_LESSEES). */
int pf_leases_was_lessee(const pf_tile_t *t, uint32_t uid);

/* The median of the recent lease-to-RESULT times (seconds), 0 before any. */
double pf_leases_typical_s(const pf_leases_t *L);

#endif
