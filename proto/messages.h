/* messages.h: the photonfarm wire protocol, version PF_PROTO_VERSION.
 *
 * Transport: the coordinator binds a ZMQ_ROUTER socket, each worker connects
 * a ZMQ_DEALER; every message is ONE frame (the ROUTER adds and strips the
 * routing identity). All integers are little-endian and written field by
 * field through the cursor in wire.h (never a struct memcpy); floats are IEEE
 * 754 binary32 little-endian and every float is checked finite on decode.
 *
 * Every message starts with the same 16-byte header:
 *   u32 magic  = PF_PROTO_MAGIC ("PFRM")
 *   u16 version = PF_PROTO_VERSION
 *   u16 type   (pf_msg_type)
 *   u64 job    (0 outside a job)
 * then the body of its type (below). Decoders reject a wrong magic, version or
 * type, any length that runs past the frame, trailing bytes, out-of-range
 * values and non-finite floats, returning PF_EPARSE (never asserting). Strings
 * are u16 length + bytes (no NUL, at most PF_PROTO_MAX_STRING).
 *
 * Conversation:
 *   worker  HELLO ──────────▶ coordinator   fingerprint, threads, name
 *           ◀────────── WELCOME | REFUSE     (REFUSE carries the reason)
 *           ◀────────── JOB                  blob names (content hashes) + settings + tiling
 *   worker  BLOB_REQ(hash, offset, credit)   for each blob it does not hold
 *           ◀────────── BLOB_CHUNK ×credit   ~1 MiB each, in order
 *   worker  READY(job, credit)               scene and maps built; may hold `credit` tiles
 *           ◀────────── TILE(job, tile, attempt, rect) ...
 *   worker  RESULT(job, tile, attempt, rect, floats) ...   (each RESULT frees one credit)
 *           ◀────────── JOB_END(job)         job finished or cancelled: drop its tiles
 *   Photon pass spread over the workers (before the JOB of that pass):
 *           ◀────────── PHOTON_REQ(job, scene blob, settings, batches first..+count)
 *   worker  BLOB_REQ for the scene blob, if it does not hold it
 *   worker  PHOTONS(job, batch, part) ...    each batch's stored photons, in parts
 *   Fan-out (6): the coordinator sends BLOB_PLAN(maps hash, chunk hashes,
 *   source) just before the JOB; with a worker as source, the worker sends
 *   its BLOB_REQs for that blob to the source's peer socket (a ROUTER whose
 *   port the source announced in its HELLO) and gets BLOB_CHUNKs from it,
 *   each checked against its chunk hash; a bad chunk, or a source silent
 *   for a few seconds, and it fetches the rest from the coordinator. A
 *   BLOB_PLAN with source "" (its source died) says the same.
 *   Irradiance spread over the workers (7; before the JOB of that pass):
 *           ◀────────── IRR_REQ(job, scene blob, map blob without irradiance,
 *                               settings, chunks first..+count)
 *   worker  BLOB_REQ for the blobs it does not hold
 *   worker  IRR_POINTS(job, chunk) ...       each chunk's irradiance point records
 *   both    HEARTBEAT about once a second (any message counts as alive)
 *   either  BYE                              leaving (worker) / shutting down (coordinator)
 */
#ifndef PF_MESSAGES_H
#define PF_MESSAGES_H

#include <stddef.h>
#include <stdint.h>

#include "base/wire.h"
#include "scene/scene.h"

#define PF_PROTO_MAGIC 0x4d524650u /* "PFRM" read as little-endian bytes 'P','F','R','M' */
#define PF_PROTO_VERSION 8 /* 3: settings carry the progressive pass; 4: and the pixel filter; 5: PHOTON_REQ, PHOTONS;
                              6: HELLO carries peer_port, BLOB_PLAN (fan-out),
                              settings.path_max_depth; 7: IRR_REQ, IRR_POINTS; 8: TILE carries per-pixel samples */
#define PF_PROTO_HEADER_SIZE 16
#define PF_PROTO_MAX_STRING PF_WIRE_MAX_STRING
#define PF_PROTO_CHUNK_SIZE (1u << 20)            /* blob chunk payload */
#define PF_PROTO_MAX_TILE_PIXELS (256u * 256u)    /* a RESULT carries at most this many pixels */
#define PF_PROTO_MAX_TILE_COUNTS (4u * PF_PROTO_MAX_TILE_PIXELS) /* per-pixel samples a TILE carries at most */
#define PF_PROTO_MAX_MESSAGE (PF_PROTO_CHUNK_SIZE + 4096u) /* ZMQ_MAXMSGSIZE on both sides */
#define PF_PROTO_MAX_BATCHES (1u << 20)          /* photon batches a pass has at most */
#define PF_PROTO_MAX_REQ_BATCHES 64u             /* batches one PHOTON_REQ asks for at most */
#define PF_PROTO_PHOTON_BYTES 32u                /* one photon on the wire */
#define PF_PROTO_MAX_PART_PHOTONS (PF_PROTO_CHUNK_SIZE / PF_PROTO_PHOTON_BYTES) /* photons a PHOTONS carries */
#define PF_PROTO_MAX_BATCH_PHOTONS (UINT64_C(1) << 32) /* photons one batch may store, at most */
#define PF_PROTO_MAX_PLAN_CHUNKS (PF_PROTO_CHUNK_SIZE / 8u) /* chunk hashes one BLOB_PLAN carries (a 128 GiB blob) */
#define PF_PROTO_MAX_SOURCE 128u                /* bytes of a BLOB_PLAN source endpoint, NUL included */
#define PF_PROTO_IRR_CHUNK_POINTS 4096u          /* irradiance points a chunk holds (the last of a map: fewer) */
#define PF_PROTO_MAX_IRR_CHUNKS (1u << 20)       /* irradiance chunks a pass has at most (both maps) */
#define PF_PROTO_MAX_REQ_IRR_CHUNKS 64u          /* chunks one IRR_REQ asks for at most */

typedef enum {
    PF_MSG_HELLO = 1,
    PF_MSG_WELCOME = 2,
    PF_MSG_REFUSE = 3,
    PF_MSG_HEARTBEAT = 4,
    PF_MSG_JOB = 5,
    PF_MSG_BLOB_REQ = 6,
    PF_MSG_BLOB_CHUNK = 7,
    PF_MSG_READY = 8,
    PF_MSG_TILE = 9,
    PF_MSG_RESULT = 10,
    PF_MSG_JOB_END = 11,
    PF_MSG_BYE = 12,
    PF_MSG_PHOTON_REQ = 13,
    PF_MSG_PHOTONS = 14,
    PF_MSG_BLOB_PLAN = 15,
    PF_MSG_IRR_REQ = 16,
    PF_MSG_IRR_POINTS = 17,
    PF_MSG_MAX_TYPE = 17
} pf_msg_type;

/* The build fingerprint a worker must share with the coordinator. */
typedef struct pf_fingerprint {
    uint16_t protocol;      /* PF_PROTO_VERSION */
    uint16_t photon_size;   /* sizeof(pf_photon_t) */
    uint16_t float_size;    /* sizeof(float) */
    uint16_t map_version;   /* PF_MAPFILE_VERSION */
    char git[48];           /* git hash of the build, NUL-terminated */
} pf_fingerprint_t;

/* This build's fingerprint, given what the layers above the protocol know:
 * the size of their photon record and the version of their photon-map blob
 * (render/frame.h's pf_frame_fingerprint passes them). */
pf_fingerprint_t pf_fingerprint_make(uint16_t photon_size, uint16_t map_version);
/* 0 when a and b may work together; else PF_EMISMATCH with a sentence in
 * why (e.g. "protocol version 2 (worker) vs 1 (coordinator)"). The git hash is
 * reported but only a protocol/layout difference refuses. */
int pf_fingerprint_check(const pf_fingerprint_t *worker, const pf_fingerprint_t *coord, char *why, size_t why_len);

typedef struct pf_msg_hello {
    pf_fingerprint_t fp;
    uint32_t threads;
    char name[256];          /* "host:pid" or a --name */
    uint16_t peer_port;      /* TCP port where it serves blob chunks to other workers; 0: it serves none */
} pf_msg_hello_t;

typedef struct pf_msg_welcome {
    uint32_t worker_id;
    uint32_t heartbeat_ms;   /* the interval both sides use */
} pf_msg_welcome_t;

typedef struct pf_msg_refuse {
    char reason[512];
} pf_msg_refuse_t;

typedef struct pf_msg_heartbeat {
    uint64_t progress;       /* worker: pixels rendered since start (the compute watchdog's counter) */
    uint32_t tiles_held;     /* worker: tiles leased and not yet returned */
} pf_msg_heartbeat_t;

typedef struct pf_msg_job {
    uint64_t scene_hash, scene_size;  /* the scene blob: pf_sceneblob */
    uint64_t maps_hash, maps_size;    /* the photon-map blob: pf_mapfile */
    pf_settings_t settings;           /* everything a tile render needs */
    uint32_t terms;                   /* PF_TERM_* mask */
    uint32_t tile_size;               /* tiles are tile_size squares, clipped at the image edge */
} pf_msg_job_t;

typedef struct pf_msg_blob_req {
    uint64_t hash;           /* which blob */
    uint64_t offset;         /* first byte wanted (a multiple of PF_PROTO_CHUNK_SIZE) */
    uint32_t credit;         /* how many chunks may be sent from offset on */
} pf_msg_blob_req_t;

typedef struct pf_msg_blob_chunk {
    uint64_t hash, total, offset;
    uint32_t len;            /* <= PF_PROTO_CHUNK_SIZE; offset + len <= total */
    const uint8_t *data;     /* decode: points into the frame (valid while it lives) */
} pf_msg_blob_chunk_t;

typedef struct pf_msg_ready {
    uint32_t credit;         /* tiles the worker wants in flight */
} pf_msg_ready_t;

typedef struct pf_msg_tile {
    uint32_t tile, attempt;
    uint32_t x0, y0, w, h;   /* w * h <= PF_PROTO_MAX_TILE_PIXELS */
    /* Adaptive progressive passes: the camera samples of each pixel of the
     * rectangle (cx0, cy0, cw, ch), which covers the tile and its
     * first-gather border (render.h's pf_spp_map_t), row by row, each >= 1;
     * cw * ch <= PF_PROTO_MAX_TILE_COUNTS. cw * ch == 0: settings.spp
     * everywhere. On the wire: 4 u32, then cw * ch u16. */
    uint32_t cx0, cy0, cw, ch;
    const uint8_t *counts_le; /* decode: inside the frame (pf_msg_tile_count) */
    const uint16_t *counts;   /* encode */
} pf_msg_tile_t;

typedef struct pf_msg_result {
    uint32_t tile, attempt;
    uint32_t x0, y0, w, h;
    const uint8_t *rgb_le;   /* decode: w*h*3 little-endian floats inside the frame, all checked finite and >= 0 */
    float *rgb;              /* encode: w*h*3 floats to send */
    uint32_t render_us;      /* time the tile took, microseconds (sent before the pixels) */
} pf_msg_result_t;

/* Trace photon batches [first, first + count) of the pass the settings
 * describe (seed, photon counts, depth), over the scene blob named. */
typedef struct pf_msg_photon_req {
    uint64_t scene_hash, scene_size;
    pf_settings_t settings;
    uint32_t first, count;   /* count 1..PF_PROTO_MAX_REQ_BATCHES; first + count <= PF_PROTO_MAX_BATCHES */
} pf_msg_photon_req_t;

/* One photon as it travels: the photon layer's record, field by field. */
typedef struct pf_msg_photon {
    float pos[3];
    float power[3];          /* finite, >= 0 */
    uint32_t dir, normal;
} pf_msg_photon_t;

/* Part of one batch's stored photons: photons [first, first + n) of the
 * total the batch stored, with the batch's counters (the same in every part). */
typedef struct pf_msg_photons {
    uint32_t batch;          /* < PF_PROTO_MAX_BATCHES */
    uint64_t total;          /* photons the batch stored; <= PF_PROTO_MAX_BATCH_PHOTONS */
    uint64_t first;          /* first + n <= total; n >= 1 unless total is 0 */
    uint64_t rejected;       /* photons dropped for bad power */
    uint64_t indirect;       /* global photons stored after a non-specular bounce; <= total */
    uint32_t n;              /* <= PF_PROTO_MAX_PART_PHOTONS */
    const uint8_t *data;     /* decode: n photons inside the frame, checked (pf_msg_photon_get) */
    const pf_msg_photon_t *photons; /* encode: the n photons to send */
} pf_msg_photons_t;

/* Where to fetch a blob from, and its chunk hashes (proto/hashtree.h):
 * sent by the coordinator before the JOB that names the blob, and again
 * when the source died. source "" is the coordinator itself; else a
 * worker's peer socket, "tcp://ADDR:PORT". */
typedef struct pf_msg_blob_plan {
    uint64_t hash, size;     /* the blob; size >= 1 */
    uint32_t source_uid;     /* the serving worker's id (0: the coordinator), for logs */
    char source[PF_PROTO_MAX_SOURCE]; /* "" or "tcp://..." (printable ASCII) */
    uint64_t root;           /* pf_chunk_root over the leaves; checked on decode */
    uint32_t n;              /* leaves: exactly pf_chunk_count(size), <= PF_PROTO_MAX_PLAN_CHUNKS */
    const uint8_t *leaves_le; /* decode: n little-endian u64 inside the frame (pf_msg_plan_leaf) */
    const uint64_t *leaves;  /* encode: the n leaves to send */
} pf_msg_blob_plan_t;

/* Compute irradiance chunks [first, first + count) of the pass the
 * settings describe over the scene blob and the map blob named (a map blob
 * whose irradiance map is empty: pf_photon_irr_plan gives the points).
 * Chunk c < C (C: chunks of one map, PF_PROTO_IRR_CHUNK_POINTS points each)
 * is points [c * 4096, ...) of the irradiance map; chunk C + c the same
 * points of the deep one (photonmap.h). The answer is IRR_POINTS, whose
 * body is PHOTONS' (pf_msg_photons_t): batch = the chunk, total = n = its
 * points (1..PF_PROTO_IRR_CHUNK_POINTS), first = rejected = indirect = 0;
 * each record a pf_photon_t as the precompute makes it. */
typedef struct pf_msg_irr_req {
    uint64_t scene_hash, scene_size;
    uint64_t maps_hash, maps_size;   /* maps_size >= 1 */
    pf_settings_t settings;
    uint32_t first, count;   /* count 1..PF_PROTO_MAX_REQ_IRR_CHUNKS; first + count <= PF_PROTO_MAX_IRR_CHUNKS */
} pf_msg_irr_req_t;

typedef struct pf_msg_bye {
    char reason[256];
} pf_msg_bye_t;

/* A decoded message. Pointers inside (chunk data, result pixels) point into
 * the frame that was decoded. */
typedef struct pf_msg {
    pf_msg_type type;
    uint64_t job;
    union {
        pf_msg_hello_t hello;
        pf_msg_welcome_t welcome;
        pf_msg_refuse_t refuse;
        pf_msg_heartbeat_t heartbeat;
        pf_msg_job_t job;
        pf_msg_blob_req_t blob_req;
        pf_msg_blob_chunk_t chunk;
        pf_msg_ready_t ready;
        pf_msg_tile_t tile;
        pf_msg_result_t result;
        pf_msg_bye_t bye;
        pf_msg_photon_req_t photon_req;
        pf_msg_photons_t photons; /* PHOTONS and IRR_POINTS */
        pf_msg_blob_plan_t plan;
        pf_msg_irr_req_t irr_req;
    } u;
} pf_msg_t;

/* Encodes msg (header from msg->type and msg->job) into out (reset first).
 * 0, PF_ENOMEM, or PF_EINVAL when a field is out of range. */
int pf_msg_encode(const pf_msg_t *msg, pf_buf_t *out);

/* Decodes one frame. 0, or PF_EPARSE with why filled ("RESULT: 12 bytes of
 * pixels for a 4x4 tile"), or PF_EMISMATCH for a foreign protocol version
 * (so the caller can say so rather than call it garbage). */
int pf_msg_decode(const uint8_t *frame, size_t len, pf_msg_t *msg, char *why, size_t why_len);

/* Copies a decoded RESULT's pixels into dst (w*h*3 floats). */
void pf_msg_result_pixels(const pf_msg_result_t *r, float *dst);

/* Count i (< cw * ch) of a decoded TILE. */
uint16_t pf_msg_tile_count(const pf_msg_tile_t *t, uint32_t i);

/* Photon i (< p->n) of a decoded PHOTONS. */
void pf_msg_photon_get(const pf_msg_photons_t *p, uint32_t i, pf_msg_photon_t *out);

/* Leaf k (< p->n) of a decoded BLOB_PLAN. */
uint64_t pf_msg_plan_leaf(const pf_msg_blob_plan_t *p, uint32_t k);

const char *pf_msg_type_name(int type);

/* The render settings as one field group, shared by the JOB message and the
 * scene blob so that both spell them the same way (the field order is
 * documented in messages.c). pf_wr_settings returns 0 or PF_ENOMEM;
 * pf_rd_settings latches the cursor on truncation or a non-finite float. */
int pf_wr_settings(pf_buf_t *b, const pf_settings_t *s);
void pf_rd_settings(pf_rd_t *r, pf_settings_t *s);
/* 0 when every field is in the range a tile render accepts (the JOB rules in
 * messages.c); else PF_EINVAL with why naming the field and its value, e.g.
 * "settings.spp 0 is out of range 1..2147483647". */
int pf_settings_check(const pf_settings_t *s, char *why, size_t why_len);

#endif
