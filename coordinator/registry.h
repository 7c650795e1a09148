/* registry.h: the coordinator's table of workers for one job: slots, the
 * monotonic worker ids, strikes, the blocklist of evicted peers and the
 * HELLO rate limit.
 *
 * A slot holds one registration. Its worker id (uid) is handed out once per
 * job and never again, so anything that must name "this worker and no other"
 * (a lease, a lessee allowed to return a tile) stores the uid, not the slot:
 * a slot freed by a dead worker is reused by the next HELLO (the one that
 * died first goes first), and the newcomer inherits none of its rights. (A
 * dead worker's late RESULTs, still queued on its old connection, count
 * until its slot is reused; after that they are unknown frames.)
 *
 * The blocklist holds hashes of the routing identities, names and CURVE
 * keys of evicted workers; a blocked peer's frames are dropped before they
 * are decoded and its HELLOs are refused, for the rest of the job. The HELLO
 * rate limit is one token bucket for all peers.
 *
 * Plain data: the farm's event loop (one thread) reads and writes the
 * fields; the functions below keep the invariants (uids, slot reuse). */
#ifndef PF_REGISTRY_H
#define PF_REGISTRY_H

#include <stddef.h>
#include <stdint.h>

enum { PF_W_FREE = 0, PF_W_HELLO, PF_W_JOB_SENT, PF_W_READY, PF_W_DEAD };

typedef struct pf_worker {
    int state;          /* PF_W_*; a FREE or DEAD slot may be reused */
    uint32_t uid;       /* this registration's id, unique in the job (1, 2, ...) */
    uint8_t id[256];    /* ZeroMQ routing identity */
    size_t idlen;
    char key[41];       /* the CURVE public key (Z85) it authenticated with; "" without CURVE */
    char name[64];      /* as it announced itself (not trusted: for logs and the summary) */
    uint32_t threads;   /* as announced (bounds its tile credit) */
    double last_seen, last_sent;
    double gone_at;     /* when it died, left or was evicted (slot reuse, oldest first) */
    double result_at;   /* its last RESULT, or when it began to hold tiles: the stall clock */
    int stuck;          /* held tiles without a RESULT too long: gets no tiles until one arrives */
    uint32_t asked;     /* the tile credit its READY asked for */
    uint32_t held;      /* tiles leased to it now (leases.c keeps this) */
    uint64_t tiles;     /* results of its that counted */
    uint64_t blob_sent; /* bytes of scene and maps sent to it */
    int strikes;
    int checked;        /* one of its results was picked for a check on another worker (verify.c) */
    int ph_asked;       /* it was sent a PHOTON_REQ: it may fetch the scene blob before its JOB */
    uint64_t ph_batches; /* photon batches of its that counted */
    uint64_t ph_pass;    /* of them, the current photon pass's (the pass's log line) */
    int ph_barred;       /* returned a photon batch unlike the coordinator's trace: no more batches this job */
    uint64_t irr_pass;   /* irradiance chunks of its that counted, this pass (irr_chunks.h) */
    int irr_planned;     /* it was sent the BLOB_PLAN of the irradiance's map blob (fan-out) */
} pf_worker_t;

typedef struct pf_registry {
    pf_worker_t *w;
    int nw;             /* slots in use so far (w[0..nw-1]); at most cap */
    int cap;
    uint32_t next_uid;
    double hello_rate;  /* HELLOs admitted per second, all peers together (<= 0: no limit) */
    double tokens, tokens_at;
    uint64_t *block;    /* open-addressing set of hashes (0 = empty) */
    size_t block_cap, nblock;
    uint64_t reused;    /* registrations that went into a reused slot */
    uint64_t hellos_dropped, block_full;
} pf_registry_t;

/* cap slots, hello_rate HELLOs per second (a burst of one second's worth).
 * 0 or PF_ENOMEM. */
int pf_registry_init(pf_registry_t *r, int cap, double hello_rate);
void pf_registry_free(pf_registry_t *r);

/* The slot registered under this routing identity (alive or dead), or -1. */
int pf_registry_find(const pf_registry_t *r, const uint8_t *id, size_t idlen);

/* The HELLO rate limit: 1 when this HELLO may be served now, 0 when it is
 * over the limit (counted in hellos_dropped). */
int pf_registry_hello_admit(pf_registry_t *r, double now);

/* A new registration for this routing identity: a fresh uid in a slot that
 * is free, or dead and holding no tile (the one gone longest first), or a new
 * slot. The slot is zeroed but for uid and id; *reused tells which. -1 when
 * every slot is taken by a live worker. */
int pf_registry_add(pf_registry_t *r, const uint8_t *id, size_t idlen, int *reused);

/* The worker leaves the table (state FREE or DEAD) at time now. */
void pf_registry_gone(pf_registry_t *r, int wi, int state, double now);

/* The blocklist. Blocking a worker blocks its routing identity, its name and
 * its CURVE key (if any). A full list (PF_REGISTRY_BLOCK_MAX entries) blocks
 * no more and counts block_full. */
#define PF_REGISTRY_BLOCK_MAX 4096
void pf_registry_block(pf_registry_t *r, const pf_worker_t *w);
int pf_registry_id_blocked(const pf_registry_t *r, const uint8_t *id, size_t idlen);
/* 1 when the name or (non-empty) key is blocked. */
int pf_registry_peer_blocked(const pf_registry_t *r, const char *name, const char *key);

#endif
