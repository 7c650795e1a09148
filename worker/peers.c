/* peers.c: fan-out on the worker's side (issue 21). A worker serves the
 * chunks it holds of its blobs to other workers, and fetches a blob from
 * another worker when the coordinator's BLOB_PLAN says so.
 *
 * Serving. A ROUTER bound at start (loopback when the coordinator is local,
 * every interface otherwise; the port announced in HELLO; none with CURVE,
 * --no-peers, or an ipc:// coordinator unless --peer-port is given). A child sends
 * BLOB_REQ(hash, offset, credit) exactly as it would to the coordinator;
 * the range is kept per child and blob and its chunks go out as this worker holds
 * them (a chunk is relayed as soon as it has arrived and passed its chunk
 * hash, so a tree streams). Bounded: at most S_MAX_CHILDREN children, a
 * few chunks queued per child (SNDHWM), requests of at most 64 chunks
 * (the decoder's credit limit), frames of at most S_MAX_REQ_FRAME bytes
 * (MAXMSGSIZE: libzmq drops a peer that sends more). Whatever is not a
 * well-formed BLOB_REQ is dropped, logged (the first few) and struck
 * against that peer's routing identity; at S_MAX_STRIKES the identity is
 * ignored. Nothing is trusted from a child but the range it asks for.
 *
 * Fetching. One DEALER to the current source. A blob fetched from a peer
 * carries the plan's chunk hashes; jobs.c checks each chunk (from the
 * coordinator as well) before it is stored. A bad chunk, a malformed frame
 * or a source silent for S_PEER_STALL_S (jobs.c) strikes the source: it is
 * not used again in this process, and the blob's rest comes from the
 * coordinator, from the first byte not yet held. The image cannot tell:
 * the blob's bytes are the same whoever sent them, and the whole-blob
 * content hash is still checked at the end.
 *
 * Main thread only. */
#include <errno.h>
#include <inttypes.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <zmq.h>

#include "proto/hashtree.h"
#include "worker/loop.h"
#include "worker/worker_impl.h"

#define S_MAX_REQ_FRAME 4096  /* a child sends BLOB_REQs only */
#define S_CHILD_HWM 4         /* chunks queued in libzmq per child */
#define S_MAX_STRIKES 3
#define S_CHILD_IDLE_S 60.0   /* a child with nothing asked for this long is forgotten */

/* ---- setup ---- */

/* Is the coordinator on this machine (so peers are too: loopback only)? */
static int s_local_endpoint(const char *ep)
{
    return strncmp(ep, "ipc://", 6) == 0 || strncmp(ep, "inproc://", 9) == 0 ||
           strncmp(ep, "tcp://127.", 10) == 0 || strncmp(ep, "tcp://localhost:", 16) == 0 ||
           strncmp(ep, "tcp://[::1]:", 12) == 0;
}

int pf_w_peers_open(s_worker *w)
{
    int port = w->opts->peer_port;
    /* No serving with CURVE (the peer socket would be plaintext), nor by
     * default for a coordinator on an ipc:// socket: its workers share one
     * machine (no link to spare) and that farm opens no TCP port at all. */
    if (port < 0 || w->curve || (port == 0 && strncmp(w->opts->endpoint, "ipc://", 6) == 0))
        return 0;
    w->psrv = zmq_socket(w->zctx, ZMQ_ROUTER);
    if (!w->psrv)
        return -1;
    int one = 1, zero = 0, hwm = S_CHILD_HWM, rhwm = 64;
    int64_t maxmsg = S_MAX_REQ_FRAME;
    zmq_setsockopt(w->psrv, ZMQ_ROUTER_MANDATORY, &one, sizeof one);
    zmq_setsockopt(w->psrv, ZMQ_LINGER, &zero, sizeof zero);
    zmq_setsockopt(w->psrv, ZMQ_MAXMSGSIZE, &maxmsg, sizeof maxmsg);
    zmq_setsockopt(w->psrv, ZMQ_SNDHWM, &hwm, sizeof hwm);
    zmq_setsockopt(w->psrv, ZMQ_RCVHWM, &rhwm, sizeof rhwm);
    char ep[64];
    const char *host = s_local_endpoint(w->opts->endpoint) ? "127.0.0.1" : "*";
    if (port > 0)
        snprintf(ep, sizeof ep, "tcp://%s:%d", host, port);
    else
        snprintf(ep, sizeof ep, "tcp://%s:*", host);
    char last[128] = "";
    size_t len = sizeof last;
    const char *colon = NULL;
    if (zmq_bind(w->psrv, ep) != 0 || zmq_getsockopt(w->psrv, ZMQ_LAST_ENDPOINT, last, &len) != 0 ||
        !(colon = strrchr(last, ':'))) {
        pf_w_log(w, PF_LOG_WARN, "cannot serve peers at %s (%s): every blob comes from the coordinator", ep,
                 zmq_strerror(zmq_errno()));
        zmq_close(w->psrv);
        w->psrv = NULL;
        return 0;
    }
    w->peer_port = (uint16_t)atoi(colon + 1);
    pf_w_log(w, PF_LOG_INFO, "serving blob chunks to other workers at %s", last);
    return 0;
}

static void s_fetch_close(s_worker *w)
{
    if (w->pfetch)
        zmq_close(w->pfetch);
    w->pfetch = NULL;
    w->pfetch_ep[0] = '\0';
}

void pf_w_peers_close(s_worker *w)
{
    s_fetch_close(w);
    if (w->psrv)
        zmq_close(w->psrv);
    w->psrv = NULL;
    for (int i = 0; i < 2; i++)
        free(w->plans[i].leaves);
    memset(w->plans, 0, sizeof w->plans);
    pf_buf_free(&w->penc);
}

/* ---- fetching ---- */

static int s_source_bad(const s_worker *w, const char *src)
{
    for (int i = 0; i < w->nbad_src; i++)
        if (strcmp(w->bad_src[i], src) == 0)
            return 1;
    return 0;
}

void pf_w_on_plan(s_worker *w, const pf_msg_t *m)
{
    const pf_msg_blob_plan_t *p = &m->u.plan;
    uint64_t *leaves = malloc((size_t)p->n * sizeof *leaves);
    if (!leaves) {
        pf_w_log(w, PF_LOG_WARN, "out of memory for a blob plan; fetching from the coordinator");
        return;
    }
    for (uint32_t k = 0; k < p->n; k++)
        leaves[k] = pf_msg_plan_leaf(p, k);
    /* The blob's own slot when it has one, else the older of the two. */
    int i = w->plans[0].leaves && w->plans[0].hash == p->hash ? 0
            : w->plans[1].leaves && w->plans[1].hash == p->hash ? 1
                                                                 : w->plan_next;
    if (i == w->plan_next)
        w->plan_next ^= 1;
    s_plan *pl = &w->plans[i];
    free(pl->leaves);
    pl->hash = p->hash;
    pl->size = p->size;
    pl->n = p->n;
    pl->leaves = leaves;
    snprintf(pl->source, sizeof pl->source, "%s", p->source);
    /* A blob already under way (the plan changed: its source is gone). */
    for (size_t i = 0; i < w->nblobs; i++) {
        s_blob *b = w->blobs[i];
        if (b->hash != p->hash || b->size != p->size || b->complete)
            continue;
        if (b->from_peer && !p->source[0])
            pf_w_blob_fallback(w, b, "the coordinator says its source is gone");
    }
}

/* The DEALER to src, (re)opened. 0, or -1. */
static int s_fetch_open(s_worker *w, const char *src)
{
    if (w->pfetch && strcmp(w->pfetch_ep, src) == 0)
        return 0;
    s_fetch_close(w);
    w->pfetch = zmq_socket(w->zctx, ZMQ_DEALER);
    if (!w->pfetch)
        return -1;
    int zero = 0, rhwm = 16;
    int64_t maxmsg = PF_PROTO_MAX_MESSAGE;
    zmq_setsockopt(w->pfetch, ZMQ_LINGER, &zero, sizeof zero);
    zmq_setsockopt(w->pfetch, ZMQ_MAXMSGSIZE, &maxmsg, sizeof maxmsg);
    zmq_setsockopt(w->pfetch, ZMQ_RCVHWM, &rhwm, sizeof rhwm);
    if (zmq_connect(w->pfetch, src) != 0) {
        pf_w_log(w, PF_LOG_WARN, "cannot connect to peer %s: %s", src, zmq_strerror(zmq_errno()));
        s_fetch_close(w);
        return -1;
    }
    snprintf(w->pfetch_ep, sizeof w->pfetch_ep, "%s", src);
    return 0;
}

void pf_w_peers_attach(s_worker *w, s_blob *b)
{
    const s_plan *pl = NULL;
    for (int i = 0; i < 2; i++)
        if (w->plans[i].leaves && w->plans[i].hash == b->hash && w->plans[i].size == b->size)
            pl = &w->plans[i];
    if (!pl)
        return;
    if (!b->leaves) {
        b->leaves = malloc((size_t)pl->n * sizeof *b->leaves);
        if (b->leaves) {
            memcpy(b->leaves, pl->leaves, (size_t)pl->n * sizeof *b->leaves);
            b->nleaves = pl->n;
        }
    }
    if (!b->leaves || !pl->source[0] || s_source_bad(w, pl->source) || s_fetch_open(w, pl->source) != 0)
        return;
    b->from_peer = 1;
    pf_w_log(w, PF_LOG_INFO, "fetching blob %016" PRIx64 " from peer %s", b->hash, pl->source);
}

void pf_w_peers_strike_source(s_worker *w, const char *why)
{
    pf_w_log(w, PF_LOG_WARN, "peer %s struck: %s", w->pfetch_ep[0] ? w->pfetch_ep : "(none)", why);
    if (w->pfetch_ep[0] && w->nbad_src < (int)(sizeof w->bad_src / sizeof w->bad_src[0]))
        snprintf(w->bad_src[w->nbad_src++], sizeof w->bad_src[0], "%s", w->pfetch_ep);
    s_fetch_close(w);
}

int pf_w_peer_send(s_worker *w, const pf_msg_t *m)
{
    if (!w->pfetch || pf_msg_encode(m, &w->penc) != 0)
        return -1;
    return zmq_send(w->pfetch, w->penc.data, w->penc.len, ZMQ_DONTWAIT) < 0 ? -1 : 0;
}

/* Frames from the source: BLOB_CHUNKs only. */
static void s_fetch_recv(s_worker *w)
{
    /* A few frames a wake-up, and never long: a source relaying a stream
     * would otherwise keep this loop here, and no heartbeat would go out. */
    double t0 = pf_now();
    for (int burst = 0; burst < 8 && w->pfetch && pf_now() - t0 < 0.05; burst++) {
        zmq_msg_t msg;
        zmq_msg_init(&msg);
        if (zmq_msg_recv(&msg, w->pfetch, ZMQ_DONTWAIT) < 0) {
            zmq_msg_close(&msg);
            return;
        }
        pf_msg_t m;
        char why[256] = "";
        int rc = pf_msg_decode(zmq_msg_data(&msg), zmq_msg_size(&msg), &m, why, sizeof why);
        if (rc != 0 || m.type != PF_MSG_BLOB_CHUNK || zmq_msg_more(&msg)) {
            char shown[300], text[340];
            snprintf(text, sizeof text, "%s", rc ? pf_log_printable(shown, sizeof shown, why)
                                                 : "a message that is not a BLOB_CHUNK");
            zmq_msg_close(&msg);
            pf_w_peers_strike_source(w, text);
            for (size_t i = 0; i < w->nblobs; i++)
                if (w->blobs[i]->from_peer && !w->blobs[i]->complete)
                    pf_w_blob_fallback(w, w->blobs[i], "its source sent garbage");
            return;
        }
        pf_w_on_chunk(w, &m.u.chunk, 1);
        zmq_msg_close(&msg);
    }
}

/* ---- serving ---- */

static s_strike *s_strike_find(s_worker *w, const uint8_t *id, size_t idlen, int add)
{
    for (int i = 0; i < w->nstrikes; i++)
        if (w->strikes[i].idlen == idlen && memcmp(w->strikes[i].id, id, idlen) == 0)
            return &w->strikes[i];
    if (!add)
        return NULL;
    int n = (int)(sizeof w->strikes / sizeof w->strikes[0]);
    int i = w->nstrikes < n ? w->nstrikes++ : (int)(w->tick % (uint64_t)n); /* full: one goes */
    memset(&w->strikes[i], 0, sizeof w->strikes[i]);
    memcpy(w->strikes[i].id, id, idlen);
    w->strikes[i].idlen = idlen;
    return &w->strikes[i];
}

static void s_child_strike(s_worker *w, const uint8_t *id, size_t idlen, const char *why)
{
    s_strike *s = s_strike_find(w, id, idlen, 1);
    s->n++;
    w->peer_malformed++;
    if (w->peer_malformed <= 20) {
        char shown[300];
        pf_w_log(w, PF_LOG_WARN, "dropped a message from a peer (strike %d of %d): %s", s->n, S_MAX_STRIKES,
                 pf_log_printable(shown, sizeof shown, why));
    }
}

/* The entry of a child's transfer of one blob (a child may fetch the scene
 * and the maps at once: an entry each). */
static s_child *s_child_get(s_worker *w, const uint8_t *id, size_t idlen, uint64_t hash)
{
    s_child *free_slot = NULL;
    for (int i = 0; i < S_MAX_CHILDREN; i++) {
        s_child *c = &w->children[i];
        if (c->used && c->hash == hash && c->idlen == idlen && memcmp(c->id, id, idlen) == 0)
            return c;
        if (!c->used && !free_slot)
            free_slot = c;
    }
    if (free_slot) {
        memset(free_slot, 0, sizeof *free_slot);
        free_slot->used = 1;
        memcpy(free_slot->id, id, idlen);
        free_slot->idlen = idlen;
        free_slot->hash = hash;
    }
    return free_slot;
}

static s_blob *s_blob_by_hash(s_worker *w, uint64_t hash)
{
    for (size_t i = 0; i < w->nblobs; i++)
        if (w->blobs[i]->hash == hash)
            return w->blobs[i];
    return NULL;
}

static void s_on_child_req(s_worker *w, const uint8_t *id, size_t idlen, uint64_t job, const pf_msg_blob_req_t *r)
{
    s_blob *b = s_blob_by_hash(w, r->hash);
    if (!b) {
        pf_w_log(w, PF_LOG_DEBUG, "a peer asked for blob %016" PRIx64 ", which this worker does not hold", r->hash);
        return;
    }
    uint64_t n = pf_chunk_count(b->size), k0 = r->offset / PF_PROTO_CHUNK_SIZE;
    if (k0 >= n) {
        s_child_strike(w, id, idlen, "BLOB_REQ past the blob's end");
        return;
    }
    s_child *c = s_child_get(w, id, idlen, r->hash);
    if (!c) {
        pf_w_log(w, PF_LOG_DEBUG, "a peer's BLOB_REQ ignored: %d transfers to children under way already",
                 S_MAX_CHILDREN);
        return;
    }
    if (k0 != c->hi) /* a restart: from k0 */
        c->next = (uint32_t)k0;
    c->hash = r->hash;
    c->size = b->size;
    c->job = job;
    uint64_t hi = k0 + r->credit;
    if (hi > n)
        hi = n;
    if (hi > (uint64_t)c->next + 16) /* at most 16 chunks asked ahead */
        hi = (uint64_t)c->next + 16;
    c->hi = (uint32_t)hi;
    c->last = pf_now();
}

static void s_serve_recv(s_worker *w)
{
    for (int burst = 0; burst < 64; burst++) {
        zmq_msg_t id, body;
        zmq_msg_init(&id);
        if (zmq_msg_recv(&id, w->psrv, ZMQ_DONTWAIT) < 0) {
            zmq_msg_close(&id);
            return;
        }
        zmq_msg_init(&body);
        int ok = zmq_msg_more(&id) && zmq_msg_recv(&body, w->psrv, ZMQ_DONTWAIT) >= 0;
        while (ok && zmq_msg_more(&body)) { /* one frame a message: drain the rest */
            ok = 0;
            zmq_msg_t extra;
            zmq_msg_init(&extra);
            zmq_msg_recv(&extra, w->psrv, 0);
            int more = zmq_msg_more(&extra);
            zmq_msg_close(&extra);
            if (!more)
                break;
        }
        const uint8_t *pid = zmq_msg_data(&id);
        size_t idlen = zmq_msg_size(&id);
        s_strike *st = idlen <= sizeof w->strikes[0].id ? s_strike_find(w, pid, idlen, 0) : NULL;
        if (idlen <= sizeof w->strikes[0].id && !(st && st->n >= S_MAX_STRIKES)) {
            pf_msg_t m;
            char why[256] = "";
            if (!ok)
                s_child_strike(w, pid, idlen, "an empty or multi-frame message");
            else if (pf_msg_decode(zmq_msg_data(&body), zmq_msg_size(&body), &m, why, sizeof why) != 0)
                s_child_strike(w, pid, idlen, why);
            else if (m.type != PF_MSG_BLOB_REQ)
                s_child_strike(w, pid, idlen, "a message other than BLOB_REQ");
            else
                s_on_child_req(w, pid, idlen, m.job, &m.u.blob_req);
        }
        zmq_msg_close(&body);
        zmq_msg_close(&id);
    }
}

/* Sends what each child asked and this worker holds, as far as libzmq takes it. */
static void s_serve_pump(s_worker *w)
{
    double now = pf_now();
    for (int i = 0; i < S_MAX_CHILDREN; i++) {
        s_child *c = &w->children[i];
        if (!c->used)
            continue;
        s_blob *b = s_blob_by_hash(w, c->hash);
        if (!b || b->size != c->size || (c->next >= c->hi && now - c->last > S_CHILD_IDLE_S)) {
            c->used = 0; /* evicted here, or gone quiet: the child falls back by itself */
            continue;
        }
        while (c->next < c->hi) {
            uint64_t off = (uint64_t)c->next * PF_PROTO_CHUNK_SIZE;
            uint64_t len = b->size - off < PF_PROTO_CHUNK_SIZE ? b->size - off : PF_PROTO_CHUNK_SIZE;
            if (b->received < off + len)
                break; /* not here yet: sent when it arrives */
            pf_msg_t m;
            memset(&m, 0, sizeof m);
            m.type = PF_MSG_BLOB_CHUNK;
            m.job = c->job;
            m.u.chunk = (pf_msg_blob_chunk_t){ b->hash, b->size, off, (uint32_t)len, b->data + off };
            if (pf_msg_encode(&m, &w->penc) != 0)
                break;
            if (zmq_send(w->psrv, c->id, c->idlen, ZMQ_SNDMORE | ZMQ_DONTWAIT) < 0) {
                if (zmq_errno() == EHOSTUNREACH)
                    c->used = 0;
                break;
            }
            if (zmq_send(w->psrv, w->penc.data, w->penc.len, ZMQ_DONTWAIT) < 0)
                break;
            c->next++;
            c->last = now;
            w->peer_bytes_served += len;
        }
    }
}

int pf_w_peers_busy(const s_worker *w)
{
    for (int i = 0; i < S_MAX_CHILDREN; i++)
        if (w->children[i].used && w->children[i].next < w->children[i].hi)
            return 1;
    return 0;
}

void pf_w_peers_pump(s_worker *w)
{
    if (w->psrv)
        s_serve_pump(w);
}

void pf_w_peers_on_poll(s_worker *w)
{
    if (w->psrv)
        s_serve_recv(w);
    if (w->pfetch)
        s_fetch_recv(w);
    pf_w_peers_pump(w);
}
