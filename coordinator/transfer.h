/* transfer.h: the coordinator's blob server: the scene and map blobs cut
 * into BLOB_CHUNK frames once, and a transfer window per worker.
 *
 * Framing. Each blob is stored as its BLOB_CHUNK frames, encoded once (the
 * job id, hash, total, offset and length in front of each 1 MiB payload), so
 * a chunk goes to libzmq without a copy: zmq_msg_init_data points into the
 * framed blob, and libzmq calls back when it is done with the frame (written
 * to the kernel, or dropped with its connection). Any number of workers
 * fetching the maps at once cost no memory beyond the framed blobs.
 *
 * Windows. A worker has at most `window` chunks inside libzmq (counted
 * exactly by that callback), whatever credit its BLOB_REQ asks for; what it
 * asked beyond that waits as a range (no bytes), sent as the window opens.
 * A request is served only as the continuation of what was asked before,
 * or, with nothing of that blob in flight, from any offset (a restart). A
 * request that overlaps or skips chunks still in flight, or that adds
 * nothing because the asked range is already full, is ignored: the caller
 * gets 1 and a sentence, and counts it against the worker.
 *
 * Lifetime. libzmq may hold chunk frames until the context is terminated,
 * so pf_xfer_destroy (which frees the framed blobs) must come after
 * zmq_ctx_term. The per-worker accounts the callbacks touch are reference
 * counted, so a slot can be given to a new worker while libzmq still holds
 * chunks queued for the old one.
 *
 * Threads: pf_framed_blob_make runs in any thread (the farm's photon
 * thread); everything else in the event loop's thread, except the libzmq
 * callback, which runs in libzmq's I/O thread and only touches atomics. */
#ifndef PF_TRANSFER_H
#define PF_TRANSFER_H

#include <stddef.h>
#include <stdint.h>

#include "proto/messages.h"

typedef struct pf_framed_blob {
    uint8_t *data;   /* nchunks frames; frame k starts at k * stride */
    size_t stride;   /* head + PF_PROTO_CHUNK_SIZE */
    size_t head;     /* encoded bytes in front of each payload */
    uint64_t hash, size;
    uint32_t nchunks;
} pf_framed_blob_t;

/* Frames the serialized blob (content hash `hash`) as the BLOB_CHUNK
 * messages of job `job`, in place: takes *blob's memory (grown by a header
 * a chunk; *blob is emptied), so the blob is never held twice. 0, PF_ENOMEM
 * (*blob is left as it was) or PF_EINVAL (an empty blob). */
int pf_framed_blob_make(pf_framed_blob_t *fb, uint64_t job, uint64_t hash, pf_buf_t *blob);
void pf_framed_blob_free(pf_framed_blob_t *fb);

typedef struct pf_xfer pf_xfer_t;

/* A server for slots 0..nslots-1, window chunks in flight per worker (at
 * least 1). NULL when memory is short. */
pf_xfer_t *pf_xfer_new(int nslots, int window);
/* Frees the framed blobs and what libzmq no longer holds. Call only after
 * zmq_ctx_term (see Lifetime). NULL-safe; sets *x_p = NULL. */
void pf_xfer_destroy(pf_xfer_t **x_p);

/* Takes the two blobs (*scene and *maps are zeroed). Blobs set before (an
 * earlier progressive pass's) are kept until pf_xfer_destroy, as libzmq may
 * still hold their chunks. */
void pf_xfer_set_blobs(pf_xfer_t *x, pf_framed_blob_t *scene, pf_framed_blob_t *maps);

/* Takes only the maps blob (*maps zeroed); the scene blob stays. The one
 * set before is kept until pf_xfer_destroy. */
void pf_xfer_set_maps(pf_xfer_t *x, pf_framed_blob_t *maps);

/* A new worker in this slot: what was asked for the old one is forgotten
 * (chunks libzmq still holds for it count against no one). 0 or PF_ENOMEM. */
int pf_xfer_reset(pf_xfer_t *x, int slot);

/* A BLOB_REQ from the worker in slot: 0 when it was taken (now or as a
 * range to send); 1 when ignored (why says why); -1 when it names no blob
 * of this job or an offset past its end (why says so). */
int pf_xfer_request(pf_xfer_t *x, int slot, const pf_msg_blob_req_t *req, char *why, size_t why_len);

/* Sends what the slot's window lets through to routing identity id on the
 * ROUTER sock. Returns the chunks sent (their payload bytes added to
 * *payload, their frames' bytes to *wire), or -1 when libzmq says the peer is gone (EHOSTUNREACH). */
int pf_xfer_pump(pf_xfer_t *x, int slot, void *sock, const uint8_t *id, size_t idlen, uint64_t *payload,
                 uint64_t *wire);

/* Chunks asked by the slot's worker and not yet handed to libzmq. */
uint32_t pf_xfer_waiting(const pf_xfer_t *x, int slot);
/* Chunks of the slot's worker inside libzmq now. */
int pf_xfer_in_flight(const pf_xfer_t *x, int slot);

/* Blob b (0: scene, 1: maps): the sizes of the distinct blobs it has been
 * over the passes, and the payload bytes of it handed to libzmq. */
void pf_xfer_blob_bytes(const pf_xfer_t *x, int b, uint64_t *size, uint64_t *sent);
/* The current blob b (0: scene, 1: maps); data NULL when there is none. */
const pf_framed_blob_t *pf_xfer_blob(const pf_xfer_t *x, int b);

#endif
