/* fanout.h: who fetches the photon-map blob from whom (issue 21, fan-out).
 *
 * The coordinator's link would otherwise carry the maps once per worker.
 * Instead the workers that get the JOB form a tree as they get it: the
 * first fetches from the coordinator, each later one from the shallowest
 * worker already in the tree that serves peers (announced a peer port in
 * its HELLO) and has fewer than `degree` children. A worker relays each
 * chunk as soon as it holds and has checked it, so the tree streams: the
 * coordinator sends the maps about once, whatever the worker count. The
 * plan (BLOB_PLAN) carries the chunk hashes of the blob (proto/hashtree.h),
 * so a child checks every chunk it gets from a peer.
 *
 * When a worker dies or leaves, its children are re-planned onto the
 * coordinator (they also fall back by themselves when their source stalls
 * or sends a bad chunk). A new maps blob (the next progressive pass) starts
 * a new tree.
 *
 * Plain data for the event loop's thread; slots are the registry's. */
#ifndef PF_FANOUT_H
#define PF_FANOUT_H

#include <stdint.h>

#include "coordinator/transfer.h"
#include "proto/messages.h"

typedef struct pf_fanout pf_fanout_t;

/* A tree over nslots slots, at most degree children a serving worker
 * (0: no fan-out, every plan names the coordinator). NULL when memory is short. */
pf_fanout_t *pf_fanout_new(int nslots, int degree);
/* NULL-safe; sets *fo_p = NULL. */
void pf_fanout_free(pf_fanout_t **fo_p);

/* Slot now holds worker uid, reachable from other workers at addr (its
 * address as the coordinator sees it; NULL or "": loopback) on port (0:
 * it serves no peers). */
void pf_fanout_hello(pf_fanout_t *fo, int slot, uint32_t uid, const char *addr, uint16_t port);

/* The blob the tree distributes: its chunk hashes are computed from the
 * framed blob (whose payloads it reads), and the tree starts empty. 0 or
 * PF_ENOMEM (then pf_fanout_plan returns -1: no plan is sent, and the
 * workers fetch from the coordinator as before fan-out). */
int pf_fanout_set_blob(pf_fanout_t *fo, const pf_framed_blob_t *fb);

/* Puts slot into the tree (once per blob) and fills the plan for it: its
 * source (a serving worker with room, or the coordinator) and the chunk
 * hashes (pointing into fo: valid until the next pf_fanout_set_blob).
 * Returns the source's slot, -2 for the coordinator, -1 when there is no
 * blob or no hashes (send no plan). */
int pf_fanout_plan(pf_fanout_t *fo, int slot, pf_msg_blob_plan_t *plan);

/* Slot left the tree (dead, gone, evicted). Its children's slots go into
 * kids (at most max; their source is now the coordinator); returns their
 * number. */
int pf_fanout_gone(pf_fanout_t *fo, int slot, int *kids, int max);

/* The coordinator's plan for slot (its source died): the coordinator,
 * with the hashes. -1 when there is no blob. */
int pf_fanout_plan_coordinator(const pf_fanout_t *fo, pf_msg_blob_plan_t *plan);

#endif
