/* transfer.c: framed blobs and per-worker transfer windows; see transfer.h.
 *
 * Owns the framed blobs, one range per blob and slot (chunks [next, hi)
 * asked and not yet handed to libzmq), and the accounts libzmq's callback
 * decrements. The callback runs in libzmq's I/O thread (or in the thread
 * that closes a socket or terminates the context); it touches the account's
 * atomics only, and frees an account whose last reference it drops. */
#include "coordinator/transfer.h"

#include <errno.h>
#include <inttypes.h>
#include <stdatomic.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <zmq.h>

#include "base/status.h"

typedef struct s_acct s_acct;

/* One blob's chunks of one account inside libzmq; the callback's hint. */
typedef struct s_part {
    atomic_int inflight;
    s_acct *acct;
} s_part;

/* A worker's account: referenced by its slot and by every chunk libzmq holds. */
struct s_acct {
    s_part part[2];
    atomic_int refs;
};

typedef struct s_slot {
    s_acct *acct;
    uint32_t next[2], hi[2];
} s_slot;

struct pf_xfer {
    pf_framed_blob_t blob[2]; /* scene, maps */
    /* Blobs of earlier progressive passes: libzmq may still hold their
     * chunks (see Lifetime), so they are freed with the server. */
    pf_framed_blob_t *retired;
    size_t nretired, cap_retired;
    s_slot *slots;
    int nslots, window;
    /* Payload bytes handed to libzmq per blob (scene, maps), and the sizes
     * of the distinct blobs served, summed over the passes (fan-out's
     * figure: sent / size is how many copies left this process). */
    uint64_t sent[2], sizes[2];
};

/* ---- framing ---- */

/* The bytes of chunk k's BLOB_CHUNK frame in front of its payload, from
 * the real encoder (so no field layout is written twice): the whole chunk is
 * encoded into scratch, whose first `head` bytes are the frame's header. */
static int s_chunk_head(pf_buf_t *scratch, uint64_t job, uint64_t hash, uint64_t size, uint64_t off, uint32_t len,
                        const uint8_t *payload, size_t *head)
{
    pf_msg_t m;
    memset(&m, 0, sizeof m);
    m.type = PF_MSG_BLOB_CHUNK;
    m.job = job;
    m.u.chunk = (pf_msg_blob_chunk_t){ hash, size, off, len, payload };
    int rc = pf_msg_encode(&m, scratch);
    if (rc != PF_OK)
        return rc;
    if (scratch->len < len || (*head && scratch->len - len != *head))
        return PF_EINVAL; /* every chunk's header has the same length */
    *head = scratch->len - len;
    return PF_OK;
}

int pf_framed_blob_make(pf_framed_blob_t *fb, uint64_t job, uint64_t hash, pf_buf_t *blob)
{
    memset(fb, 0, sizeof *fb);
    uint64_t size = blob->len;
    if (size == 0)
        return PF_EINVAL;
    uint64_t n = (size + PF_PROTO_CHUNK_SIZE - 1) / PF_PROTO_CHUNK_SIZE;
    pf_buf_t scratch = { 0 };
    size_t head = 0;
    int rc = s_chunk_head(&scratch, job, hash, size, 0, 0, blob->data, &head); /* an empty chunk: the header */
    uint8_t *data = rc == PF_OK ? realloc(blob->data, (size_t)n * (head + PF_PROTO_CHUNK_SIZE)) : NULL;
    if (!data) {
        pf_buf_free(&scratch);
        return rc != PF_OK ? rc : PF_ENOMEM;
    }
    /* The blob now owns the memory; spread the payloads out from the last
     * (each moves up, never over one not yet moved), then write the headers. */
    blob->data = NULL;
    blob->len = blob->cap = 0;
    size_t stride = head + PF_PROTO_CHUNK_SIZE;
    for (uint64_t k = n; k-- > 0 && rc == PF_OK;) {
        uint64_t off = k * PF_PROTO_CHUNK_SIZE;
        uint32_t len = (uint32_t)(size - off < PF_PROTO_CHUNK_SIZE ? size - off : PF_PROTO_CHUNK_SIZE);
        memmove(data + k * stride + head, data + off, len);
        rc = s_chunk_head(&scratch, job, hash, size, off, len, data + k * stride + head, &head);
        if (rc == PF_OK)
            memcpy(data + k * stride, scratch.data, head);
    }
    pf_buf_free(&scratch);
    *fb = (pf_framed_blob_t){ data, stride, head, hash, size, (uint32_t)n };
    if (rc != PF_OK)
        pf_framed_blob_free(fb);
    return rc;
}

void pf_framed_blob_free(pf_framed_blob_t *fb)
{
    free(fb->data);
    memset(fb, 0, sizeof *fb);
}

/* ---- accounts ---- */

static void s_acct_release(s_acct *a)
{
    if (a && atomic_fetch_sub(&a->refs, 1) == 1)
        free(a);
}

/* libzmq is done with a chunk frame. */
static void s_chunk_done(void *data, void *hint)
{
    (void)data;
    s_part *p = hint;
    s_acct *a = p->acct;
    atomic_fetch_sub(&p->inflight, 1);
    s_acct_release(a);
}

pf_xfer_t *pf_xfer_new(int nslots, int window)
{
    pf_xfer_t *x = calloc(1, sizeof *x);
    if (!x)
        return NULL;
    x->slots = calloc((size_t)(nslots > 0 ? nslots : 1), sizeof *x->slots);
    if (!x->slots) {
        free(x);
        return NULL;
    }
    x->nslots = nslots;
    x->window = window > 0 ? window : 1;
    return x;
}

void pf_xfer_destroy(pf_xfer_t **x_p)
{
    pf_xfer_t *x = *x_p;
    if (!x)
        return;
    for (int i = 0; i < x->nslots; i++)
        s_acct_release(x->slots[i].acct);
    pf_framed_blob_free(&x->blob[0]);
    pf_framed_blob_free(&x->blob[1]);
    for (size_t i = 0; i < x->nretired; i++)
        pf_framed_blob_free(&x->retired[i]);
    free(x->retired);
    free(x->slots);
    free(x);
    *x_p = NULL;
}

/* An earlier pass's blob, kept until the server goes (or freed now when
 * there is no room to keep it and no worker has chunks in flight). */
static void s_retire(pf_xfer_t *x, pf_framed_blob_t *fb)
{
    if (!fb->data)
        return;
    if (x->nretired == x->cap_retired) {
        size_t cap = x->cap_retired ? 2 * x->cap_retired : 8;
        pf_framed_blob_t *r = realloc(x->retired, cap * sizeof *r);
        if (r) {
            x->retired = r;
            x->cap_retired = cap;
        }
    }
    if (x->nretired < x->cap_retired)
        x->retired[x->nretired++] = *fb;
    else
        pf_framed_blob_free(fb); /* out of memory: the old behaviour, safe once transfers are over */
    memset(fb, 0, sizeof *fb);
}

void pf_xfer_set_blobs(pf_xfer_t *x, pf_framed_blob_t *scene, pf_framed_blob_t *maps)
{
    if (scene->data && scene->hash != x->blob[0].hash)
        x->sizes[0] += scene->size;
    if (maps->data && maps->hash != x->blob[1].hash)
        x->sizes[1] += maps->size;
    s_retire(x, &x->blob[0]);
    s_retire(x, &x->blob[1]);
    x->blob[0] = *scene;
    x->blob[1] = *maps;
    memset(scene, 0, sizeof *scene);
    memset(maps, 0, sizeof *maps);
}

void pf_xfer_set_maps(pf_xfer_t *x, pf_framed_blob_t *maps)
{
    if (maps->data && maps->hash != x->blob[1].hash)
        x->sizes[1] += maps->size;
    s_retire(x, &x->blob[1]);
    x->blob[1] = *maps;
    memset(maps, 0, sizeof *maps);
}

int pf_xfer_reset(pf_xfer_t *x, int slot)
{
    s_slot *s = &x->slots[slot];
    s_acct_release(s->acct);
    memset(s, 0, sizeof *s);
    s_acct *a = calloc(1, sizeof *a);
    if (!a)
        return PF_ENOMEM;
    for (int b = 0; b < 2; b++) {
        atomic_init(&a->part[b].inflight, 0);
        a->part[b].acct = a;
    }
    atomic_init(&a->refs, 1);
    s->acct = a;
    return PF_OK;
}

/* ---- requests and sending ---- */

int pf_xfer_request(pf_xfer_t *x, int slot, const pf_msg_blob_req_t *req, char *why, size_t why_len)
{
    int b = -1;
    for (int i = 0; i < 2 && b < 0; i++)
        if (x->blob[i].data && req->hash == x->blob[i].hash)
            b = i;
    if (b < 0) {
        snprintf(why, why_len, "BLOB_REQ for blob %016" PRIx64 ", which is not one of this job's", req->hash);
        return -1;
    }
    const pf_framed_blob_t *fb = &x->blob[b];
    uint64_t k0 = req->offset / PF_PROTO_CHUNK_SIZE;
    if (req->offset % PF_PROTO_CHUNK_SIZE || k0 >= fb->nchunks) {
        snprintf(why, why_len, "BLOB_REQ at offset %" PRIu64 " of blob %016" PRIx64 " (%" PRIu64 " bytes)",
                 req->offset, req->hash, fb->size);
        return -1;
    }
    s_slot *s = &x->slots[slot];
    if (!s->acct && pf_xfer_reset(x, slot) != PF_OK) {
        snprintf(why, why_len, "out of memory");
        return 1;
    }
    uint64_t credit = req->credit < (uint32_t)x->window ? req->credit : (uint32_t)x->window;
    uint64_t k1 = k0 + credit < fb->nchunks ? k0 + credit : fb->nchunks;
    int infl = atomic_load(&s->acct->part[b].inflight);
    if (k0 == s->hi[b]) { /* the continuation of what it asked before */
        uint64_t lim = (uint64_t)s->next[b] + (uint64_t)x->window;
        if (k1 > lim)
            k1 = lim;
        if (k1 > s->hi[b]) {
            s->hi[b] = (uint32_t)k1;
            return 0;
        }
        snprintf(why, why_len, "BLOB_REQ for chunk %" PRIu64 " of blob %016" PRIx64 " while %u chunks wait and %d are "
                 "in flight (window %d)", k0, req->hash, s->hi[b] - s->next[b], infl, x->window);
        return 1;
    }
    if (infl == 0 && s->next[b] == s->hi[b]) { /* a restart, with nothing of this blob on the way */
        s->next[b] = (uint32_t)k0;
        s->hi[b] = (uint32_t)k1;
        return 0;
    }
    snprintf(why, why_len, "BLOB_REQ for chunks %" PRIu64 " to %" PRIu64 " of blob %016" PRIx64 " overlaps or skips "
             "the chunks asked before (up to %u, %d of them in flight)", k0, k1 - 1, req->hash,
             s->hi[b] ? s->hi[b] - 1 : 0, infl);
    return 1;
}

int pf_xfer_pump(pf_xfer_t *x, int slot, void *sock, const uint8_t *id, size_t idlen, uint64_t *payload,
                 uint64_t *wire)
{
    s_slot *s = &x->slots[slot];
    if (!s->acct)
        return 0;
    int sent = 0;
    for (int b = 0; b < 2; b++) {
        const pf_framed_blob_t *fb = &x->blob[b];
        s_part *p = &s->acct->part[b];
        while (s->next[b] < s->hi[b]) {
            if (atomic_load(&s->acct->part[0].inflight) + atomic_load(&s->acct->part[1].inflight) >= x->window)
                return sent;
            uint64_t k = s->next[b], off = k * PF_PROTO_CHUNK_SIZE;
            size_t len = (size_t)(fb->size - off < PF_PROTO_CHUNK_SIZE ? fb->size - off : PF_PROTO_CHUNK_SIZE);
            zmq_msg_t m;
            atomic_fetch_add(&p->inflight, 1);
            atomic_fetch_add(&s->acct->refs, 1);
            if (zmq_msg_init_data(&m, fb->data + k * fb->stride, fb->head + len, s_chunk_done, p) != 0) {
                s_chunk_done(NULL, p);
                return sent;
            }
            if (zmq_send(sock, id, idlen, ZMQ_SNDMORE | ZMQ_DONTWAIT) < 0) {
                int gone = zmq_errno() == EHOSTUNREACH;
                zmq_msg_close(&m); /* calls s_chunk_done */
                return gone ? -1 : sent;
            }
            if (zmq_msg_send(&m, sock, ZMQ_DONTWAIT) < 0) {
                zmq_msg_close(&m);
                return sent;
            }
            s->next[b]++;
            sent++;
            *payload += len;
            *wire += fb->head + len;
            x->sent[b] += len;
        }
    }
    return sent;
}

uint32_t pf_xfer_waiting(const pf_xfer_t *x, int slot)
{
    const s_slot *s = &x->slots[slot];
    return (s->hi[0] - s->next[0]) + (s->hi[1] - s->next[1]);
}

int pf_xfer_in_flight(const pf_xfer_t *x, int slot)
{
    const s_slot *s = &x->slots[slot];
    return s->acct ? atomic_load(&s->acct->part[0].inflight) + atomic_load(&s->acct->part[1].inflight) : 0;
}

void pf_xfer_blob_bytes(const pf_xfer_t *x, int b, uint64_t *size, uint64_t *sent)
{
    *size = x->sizes[b];
    *sent = x->sent[b];
}

const pf_framed_blob_t *pf_xfer_blob(const pf_xfer_t *x, int b)
{
    return &x->blob[b];
}
