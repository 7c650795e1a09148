/* jobs.c: the worker's jobs and what they need: the blob cache and blob
 * transfers (BLOB_REQ / BLOB_CHUNK), the built scene cache, the job's
 * states (fetch, build, ready, failed), TILE handling and RESULTs.
 *
 * Lifetimes. Jobs, built scenes and blobs are reference-counted by the main
 * thread alone: a work item holds a reference to its job (and a BUILD item
 * pins its two blobs) from the moment it is queued until the main thread
 * takes it back from the done list, so the compute thread can read them
 * without further locks (compute.c). Cancellation (JOB_END, a new job, a
 * lost coordinator, a signal) sets the job's atomic flag, which the compute
 * thread checks between rows; queued items of a cancelled job are taken out
 * of the queue at once.
 *
 * Trust. The coordinator is not believed blindly: a blob's buffer grows as
 * its chunks arrive (an anonymous mapping doubling in place, capped at the size the JOB announced and at
 * S_MAX_BLOB_SIZE), so a JOB announcing 64 GiB allocates nothing until that
 * much data comes; a TILE beyond the credit READY announced, or a copy of a
 * lease already held, is dropped with a warning before its buffer is
 * allocated.
 *
 * This file owns the worker's blobs, built scene cache, BUILD list and
 * current job (fields of s_worker). Only the main thread calls it; the
 * compute thread reads a job and its blobs only through the work items. */
#define _GNU_SOURCE /* mremap */
#include <inttypes.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/mman.h>

#include "base/hash.h"
#include "base/reserve.h"
#include "photon/mapfile.h"
#include "proto/hashtree.h"
#include "worker/worker_impl.h"

#define S_WINDOW 8                /* blob chunks requested ahead */
#define S_MAX_BLOBS 4             /* complete blobs kept (LRU) */
#define S_STALL_S 10.0            /* a transfer with no chunk for this long is requested again */
#define S_PEER_STALL_S 4.0        /* a peer source silent for this long: the rest comes from the coordinator */
#define S_MAX_BLOB_SIZE (UINT64_C(1) << 36) /* 64 GiB: anything larger is not a scene or a map */
#define S_BLOB_FIRST_ALLOC (UINT64_C(4) << 20) /* a blob's first buffer; it doubles as chunks arrive */

/* ---- builds under way ---- */

/* The main thread's record of BUILD items out with the compute thread, so a
 * job can wait for a build of its scene and maps already under way instead
 * of starting a second one. */
static void s_build_forget(s_worker *w, const s_work *it)
{
    for (s_work **pp = &w->builds; *pp; pp = &(*pp)->next_build)
        if (*pp == it) {
            *pp = it->next_build;
            return;
        }
}

/* Do two jobs need the same built scene and maps? */
static int s_same_build(const pf_msg_job_t *a, const pf_msg_job_t *b)
{
    return a->scene_hash == b->scene_hash && a->scene_size == b->scene_size && a->maps_hash == b->maps_hash &&
           a->maps_size == b->maps_size && pf_settings_hash(&a->settings) == pf_settings_hash(&b->settings);
}

static int s_built_fits(const s_built *c, const pf_msg_job_t *d)
{
    return c && c->scene_hash == d->scene_hash && c->maps_hash == d->maps_hash &&
           c->settings_hash == pf_settings_hash(&d->settings);
}

static int s_build_pending(const s_worker *w, const pf_msg_job_t *d)
{
    for (const s_work *b = w->builds; b; b = b->next_build)
        if (s_same_build(&b->job->desc, d))
            return 1;
    return 0;
}

/* ---- blobs ---- */

static s_blob *s_blob_find(s_worker *w, uint64_t hash, uint64_t size)
{
    for (size_t i = 0; i < w->nblobs; i++)
        if (w->blobs[i]->hash == hash && w->blobs[i]->size == size)
            return w->blobs[i];
    return NULL;
}

static void s_blob_remove(s_worker *w, size_t i)
{
    if (w->blobs[i]->alloc)
        munmap(w->blobs[i]->data, (size_t)w->blobs[i]->alloc);
    free(w->blobs[i]->leaves);
    free(w->blobs[i]);
    w->blobs[i] = w->blobs[--w->nblobs];
}

static int s_blob_needed(const s_worker *w, const s_blob *b)
{
    const s_job *pj = w->pjob;
    if (pj && ((b->hash == pj->desc.scene_hash && b->size == pj->desc.scene_size) ||
               (b->hash == pj->desc.maps_hash && b->size == pj->desc.maps_size)))
        return 1;
    const s_job *j = w->job;
    if (!j || j->state == S_JOB_FAILED)
        return 0;
    return (b->hash == j->desc.scene_hash && b->size == j->desc.scene_size) ||
           (b->hash == j->desc.maps_hash && b->size == j->desc.maps_size);
}

/* Drops transfers no current job needs, then the least recently used
 * complete blobs beyond S_MAX_BLOBS (never one pinned by a build or needed
 * by the current job; the cache may run over while those are in use). */
void pf_w_blobs_trim(s_worker *w)
{
    for (size_t i = 0; i < w->nblobs;) {
        s_blob *b = w->blobs[i];
        if (!b->complete && !b->pins && !s_blob_needed(w, b)) {
            pf_w_log(w, PF_LOG_DEBUG, "dropping the unfinished transfer of blob %016" PRIx64, b->hash);
            s_blob_remove(w, i);
        } else {
            i++;
        }
    }
    for (;;) {
        size_t complete = 0, victim = SIZE_MAX;
        for (size_t i = 0; i < w->nblobs; i++) {
            s_blob *b = w->blobs[i];
            if (!b->complete)
                continue;
            complete++;
            if (!b->pins && !s_blob_needed(w, b) && (victim == SIZE_MAX || b->used < w->blobs[victim]->used))
                victim = i;
        }
        if (complete <= S_MAX_BLOBS || victim == SIZE_MAX)
            return;
        pf_w_log(w, PF_LOG_DEBUG, "evicting cached blob %016" PRIx64, w->blobs[victim]->hash);
        s_blob_remove(w, victim);
    }
}

/* Makes room at b->data for need bytes (need <= b->size <= S_MAX_BLOB_SIZE):
 * the buffer doubles from S_BLOB_FIRST_ALLOC, never past the blob's size.
 * It is an anonymous mapping that mremap grows in place or by moving its
 * pages, never by copying them: a realloc'd buffer was copied at every
 * doubling, and for a 100 MB map blob under the sanitizers one such copy
 * held the main loop for up to a second, long enough for the coordinator
 * to declare the worker silent. 0, or -1 when memory is short (b unchanged). */
static int s_blob_grow(s_blob *b, uint64_t need)
{
    if (need <= b->alloc)
        return 0;
    uint64_t cap = b->alloc ? b->alloc : S_BLOB_FIRST_ALLOC;
    while (cap < need)
        cap *= 2;
    if (cap > b->size)
        cap = b->size;
    if (cap > SIZE_MAX)
        return -1;
    void *data = b->alloc ? mremap(b->data, (size_t)b->alloc, (size_t)cap, MREMAP_MAYMOVE)
                          : mmap(NULL, (size_t)cap, PROT_READ | PROT_WRITE, MAP_PRIVATE | MAP_ANONYMOUS, -1, 0);
    if (data == MAP_FAILED)
        return -1;
    b->data = data;
    b->alloc = cap;
    return 0;
}

/* Asks for more chunks so that about S_WINDOW are outstanding. */
static void s_blob_request(s_worker *w, s_blob *b)
{
    uint64_t chunk = PF_PROTO_CHUNK_SIZE;
    uint64_t outstanding = (b->requested - b->received + chunk - 1) / chunk;
    if (b->requested >= b->size || outstanding > S_WINDOW / 2)
        return;
    uint64_t left = (b->size - b->requested + chunk - 1) / chunk;
    uint64_t credit = S_WINDOW - outstanding;
    if (credit > left)
        credit = left;
    pf_msg_t m;
    memset(&m, 0, sizeof m);
    m.type = PF_MSG_BLOB_REQ;
    /* The job that needs it: the render job, else the photon job. */
    const s_job *j = w->job;
    int for_job = j && ((b->hash == j->desc.scene_hash && b->size == j->desc.scene_size) ||
                        (b->hash == j->desc.maps_hash && b->size == j->desc.maps_size));
    m.job = for_job ? j->id : w->pjob ? w->pjob->id : j ? j->id : 0;
    m.u.blob_req.hash = b->hash;
    m.u.blob_req.offset = b->requested;
    m.u.blob_req.credit = (uint32_t)credit;
    if (b->from_peer && pf_w_peer_send(w, &m) != 0) {
        pf_w_peers_strike_source(w, "cannot send it a BLOB_REQ");
        b->from_peer = 0;
    }
    if (!b->from_peer)
        pf_w_send(w, &m, 0);
    b->requested += credit * chunk;
    if (b->requested > b->size)
        b->requested = b->size;
}

/* Starts (or restarts from its last in-order byte) the transfer of b. */
static void s_blob_restart(s_worker *w, s_blob *b)
{
    b->requested = b->received;
    b->last_chunk = pf_now();
    s_blob_request(w, b);
}

/* The cached or in-transfer blob (hash, size), starting its transfer when
 * it is not there. NULL when the size is absurd or memory is short. */
s_blob *pf_w_blob_get(s_worker *w, uint64_t hash, uint64_t size, const char *what)
{
    uint64_t job = w->job ? w->job->id : w->pjob ? w->pjob->id : 0;
    s_blob *b = s_blob_find(w, hash, size);
    if (b) {
        b->used = ++w->tick;
        return b;
    }
    if (size == 0 || size > S_MAX_BLOB_SIZE) {
        pf_w_log(w, PF_LOG_ERROR, "job %" PRIu64 ": the %s blob's size %" PRIu64 " is out of range", job, what,
                 size);
        return NULL;
    }
    if (pf_reserve((void **)&w->blobs, &w->cap_blobs, w->nblobs + 1, sizeof *w->blobs))
        return NULL;
    /* Nothing is allocated for the data yet: the buffer grows as chunks
     * arrive (s_blob_grow), so a JOB announcing a huge size costs nothing
     * until the coordinator actually sends that much. */
    b = calloc(1, sizeof *b);
    if (!b) {
        pf_w_log(w, PF_LOG_ERROR, "job %" PRIu64 ": out of memory for the %s blob", job, what);
        return NULL;
    }
    b->hash = hash;
    b->size = size;
    b->used = ++w->tick;
    w->blobs[w->nblobs++] = b;
    pf_w_log(w, PF_LOG_INFO, "fetching the %s blob %016" PRIx64 " (%.1f MB)", what, hash, (double)size / 1e6);
    pf_w_peers_attach(w, b);
    s_blob_restart(w, b);
    return b;
}

/* ---- jobs ---- */

/* The TILEs a job holds (queued or rendering), against the credit READY
 * announced: the index of (tile, attempt) in j->held_tiles, or -1. */
static int s_tile_held(const s_job *j, uint32_t tile, uint32_t attempt)
{
    for (uint32_t i = 0; i < j->held; i++)
        if (j->held_tiles[i].tile == tile && j->held_tiles[i].attempt == attempt)
            return (int)i;
    return -1;
}

/* The job no longer holds (tile, attempt): answered, discarded or cancelled. */
static void s_tile_unhold(s_job *j, uint32_t tile, uint32_t attempt)
{
    int i = s_tile_held(j, tile, attempt);
    if (i >= 0)
        j->held_tiles[i] = j->held_tiles[--j->held];
}

/* Cancels the current job: its queued work leaves the queue, the tile being
 * rendered stops at the next row, and results still to come are discarded. */
void pf_w_job_drop(s_worker *w, const char *why)
{
    pf_w_photons_drop(w, why);
    s_job *j = w->job;
    if (!j)
        return;
    pf_w_log(w, PF_LOG_DEBUG, "dropping job %" PRIu64 " (%s)", j->id, why);
    atomic_store(&j->cancelled, 1);
    w->job = NULL;
    s_work *drop = pf_w_unqueue_job(w, j);
    while (drop) {
        s_work *next = drop->next;
        if (drop->kind == S_WORK_TILE) {
            w->tiles_held--;
            s_tile_unhold(j, drop->tile.tile, drop->tile.attempt);
        } else
            s_build_forget(w, drop);
        pf_w_work_free(drop);
        drop = next;
    }
    pf_w_job_release(j);
    pf_w_blobs_trim(w);
}

static void s_job_fail(s_worker *w, s_job *j, const char *why)
{
    pf_w_log(w, PF_LOG_ERROR, "job %" PRIu64 ": %s; taking no tiles for it", j->id, why);
    j->state = S_JOB_FAILED;
    pf_w_blobs_trim(w);
}

/* The scene and maps are built: render context, then READY. */
static void s_job_ready(s_worker *w, s_job *j, s_built *b)
{
    b->refs++;
    j->built = b;
    pf_render_ctx_init(&j->ctx, &b->frame, &j->desc.settings);
    j->ctx.terms = j->desc.terms;
    j->ctx.dropped = &j->dropped;
    j->state = S_JOB_READY;
    pf_w_log(w, PF_LOG_INFO, "job %" PRIu64 ": ready (%dx%d, %d spp)", j->id, j->desc.settings.width,
             j->desc.settings.height, j->desc.settings.spp);
    pf_msg_t m;
    memset(&m, 0, sizeof m);
    m.type = PF_MSG_READY;
    m.job = j->id;
    m.u.ready.credit = PF_W_CREDIT;
    pf_w_send(w, &m, 0);
}

/* Once both blobs are complete: reuse the built scene when it is the same,
 * else hand the build to the compute thread. */
static void s_job_advance(s_worker *w)
{
    s_job *j = w->job;
    if (!j || j->state != S_JOB_FETCH)
        return;
    const pf_msg_job_t *d = &j->desc;
    s_blob *sb = s_blob_find(w, d->scene_hash, d->scene_size), *mb = s_blob_find(w, d->maps_hash, d->maps_size);
    if (!sb || !mb || !sb->complete || !mb->complete)
        return;
    if (s_built_fits(w->built_cache, d)) {
        pf_w_log(w, PF_LOG_DEBUG, "job %" PRIu64 ": reusing the built scene and maps", j->id);
        s_job_ready(w, j, w->built_cache);
        return;
    }
    if (s_build_pending(w, d)) {
        /* An earlier job's build of the same blobs is running; its result
         * will be cached and serve this job (pf_w_drain_done). */
        pf_w_log(w, PF_LOG_DEBUG, "job %" PRIu64 ": waiting for the build already under way", j->id);
        j->state = S_JOB_BUILD;
        return;
    }
    s_work *it = calloc(1, sizeof *it);
    if (!it) {
        s_job_fail(w, j, "out of memory");
        return;
    }
    it->kind = S_WORK_BUILD;
    it->job = j;
    j->refs++;
    it->scene_blob = sb;
    it->maps_blob = mb;
    sb->pins++;
    mb->pins++;
    j->state = S_JOB_BUILD;
    pf_w_log(w, PF_LOG_INFO, "job %" PRIu64 ": building the scene and photon maps", j->id);
    it->next_build = w->builds;
    w->builds = it;
    pf_w_enqueue(w, it);
}

void pf_w_on_job(s_worker *w, const pf_msg_t *m)
{
    const pf_msg_job_t *d = &m->u.job;
    if (w->job && w->job->id == m->job) {
        pf_w_log(w, PF_LOG_DEBUG, "job %" PRIu64 " announced again; ignored", m->job);
        return;
    }
    pf_w_job_drop(w, "a new job arrived");
    s_job *j = calloc(1, sizeof *j);
    if (!j) {
        pf_w_log(w, PF_LOG_ERROR, "job %" PRIu64 ": out of memory", m->job);
        return;
    }
    j->id = m->job;
    j->desc = *d;
    j->refs = 1;
    atomic_init(&j->cancelled, 0);
    w->job = j;
    pf_w_log(w, PF_LOG_INFO, "job %" PRIu64 ": scene %016" PRIx64 " (%" PRIu64 " bytes), maps %016" PRIx64
             " (%" PRIu64 " bytes)", j->id, d->scene_hash, d->scene_size, d->maps_hash, d->maps_size);
    /* The decoder checked the ranges; these guard the renderer's own limits
     * (estimate scratch, term mask) whatever the decoder lets through. */
    if (d->settings.global_k < 1 || d->settings.global_k > PF_MAX_K || d->settings.caustic_k < 1 ||
        d->settings.caustic_k > PF_MAX_K || d->settings.width < 1 || d->settings.height < 1 ||
        (d->terms & ~(unsigned)(PF_TERM_ALL | PF_TERM_PHOTONMAP)) != 0) {
        s_job_fail(w, j, "settings out of the renderer's range");
        return;
    }
    if (!pf_w_blob_get(w, d->scene_hash, d->scene_size, "scene") || !pf_w_blob_get(w, d->maps_hash, d->maps_size, "maps")) {
        s_job_fail(w, j, "cannot fetch its blobs");
        return;
    }
    pf_w_blobs_trim(w);
    s_job_advance(w);
}

void pf_w_blob_fallback(s_worker *w, s_blob *b, const char *why)
{
    pf_w_log(w, PF_LOG_WARN, "blob %016" PRIx64 ": fetching the rest (from byte %" PRIu64 ") from the coordinator: %s",
             b->hash, b->received, why);
    b->from_peer = 0;
    s_blob_restart(w, b);
}

/* Chunk k of b against its chunk hash (a blob without a plan: nothing to
 * check before the whole-blob hash). 1 when it may be stored. */
static int s_chunk_ok(s_worker *w, s_blob *b, const pf_msg_blob_chunk_t *c, int from_peer)
{
    uint64_t k = c->offset / PF_PROTO_CHUNK_SIZE;
    if (!b->leaves || k >= b->nleaves || pf_chunk_hash(b->hash, k, c->data, c->len) == b->leaves[k])
        return 1;
    char why[200];
    snprintf(why, sizeof why, "chunk %" PRIu64 " of blob %016" PRIx64 " does not match its chunk hash", k, b->hash);
    if (from_peer) {
        pf_w_peers_strike_source(w, why);
        pf_w_blob_fallback(w, b, why);
    } else {
        pf_w_log(w, PF_LOG_WARN, "%s (from the coordinator); asking again", why);
        s_blob_restart(w, b);
    }
    return 0;
}

void pf_w_on_chunk(s_worker *w, const pf_msg_blob_chunk_t *c, int from_peer)
{
    s_blob *b = s_blob_find(w, c->hash, c->total);
    if (!b || b->complete || b->from_peer != from_peer) {
        pf_w_log(w, PF_LOG_DEBUG, "chunk of blob %016" PRIx64 " not being fetched (from there); dropped", c->hash);
        return;
    }
    uint64_t expect = b->size - b->received < PF_PROTO_CHUNK_SIZE ? b->size - b->received : PF_PROTO_CHUNK_SIZE;
    if (c->offset != b->received || c->len != expect) {
        /* A gap or a replay; the stall timer asks again from b->received. */
        pf_w_log(w, PF_LOG_DEBUG, "chunk of blob %016" PRIx64 " at %" PRIu64 " (+%" PRIu32 ") out of order, expected %"
                 PRIu64 "; dropped", c->hash, c->offset, c->len, b->received);
        return;
    }
    if (s_blob_grow(b, b->received + c->len) != 0) {
        char why[200];
        snprintf(why, sizeof why, "cannot allocate %" PRIu64 " bytes for blob %016" PRIx64 " (%" PRIu64 " announced)",
                 b->received + c->len, b->hash, b->size);
        for (size_t i = 0; i < w->nblobs; i++)
            if (w->blobs[i] == b && !b->pins) {
                s_blob_remove(w, i);
                break;
            }
        if (w->job && w->job->state == S_JOB_FETCH)
            s_job_fail(w, w->job, why);
        else
            pf_w_log(w, PF_LOG_ERROR, "%s", why);
        return;
    }
    if (!s_chunk_ok(w, b, c, from_peer))
        return;
    memcpy(b->data + b->received, c->data, c->len);
    b->received += c->len;
    b->last_chunk = pf_now();
    pf_w_peers_pump(w); /* relayed at once to the workers fetching from this one */
    if (b->received < b->size) {
        s_blob_request(w, b);
        return;
    }
    uint64_t h = pf_hash_bytes(PF_HASH_INIT, b->data, (size_t)b->size);
    if (h != b->hash) {
        b->failures++;
        b->received = b->requested = 0;
        b->from_peer = 0;
        if (b->failures < 2) {
            pf_w_log(w, PF_LOG_WARN, "blob %016" PRIx64 " arrived with content hash %016" PRIx64 "; fetching it again",
                     b->hash, h);
            s_blob_restart(w, b);
            return;
        }
        for (size_t i = 0; i < w->nblobs; i++)
            if (w->blobs[i] == b) {
                s_blob_remove(w, i);
                break;
            }
        if (w->job && w->job->state == S_JOB_FETCH) {
            char why[160];
            snprintf(why, sizeof why, "blob %016" PRIx64 " failed its content hash twice", c->hash);
            s_job_fail(w, w->job, why);
        }
        return;
    }
    b->complete = 1;
    b->used = ++w->tick;
    pf_w_log(w, PF_LOG_DEBUG, "blob %016" PRIx64 " complete (%" PRIu64 " bytes)", b->hash, b->size);
    pf_w_blobs_trim(w);
    s_job_advance(w);
    pf_w_photons_advance(w);
}

/* A TILE the coordinator may send: one of the current job's, beyond none of
 * the credit announced in READY, not a copy of a lease already held. Else 0,
 * after a warning (the coordinator is broken or hostile; nothing allocated). */
static int s_tile_admissible(s_worker *w, const s_job *j, const pf_msg_tile_t *t)
{
    if (s_tile_held(j, t->tile, t->attempt) >= 0) {
        pf_w_log(w, PF_LOG_WARN, "TILE %" PRIu32 " (attempt %" PRIu32 ") of job %" PRIu64 " sent again while this "
                 "worker holds it; dropped", t->tile, t->attempt, j->id);
        return 0;
    }
    if (j->held >= PF_W_CREDIT) {
        pf_w_log(w, PF_LOG_WARN, "TILE %" PRIu32 " of job %" PRIu64 " is beyond the credit of %d tiles this worker "
                 "announced (it holds %" PRIu32 "); dropped", t->tile, j->id, PF_W_CREDIT, j->held);
        return 0;
    }
    return 1;
}

/* An adaptive pass's counts (if any) must cover the tile and its
 * first-gather border within the image, as the render reads them. Else 0,
 * after a warning. */
static int s_tile_counts_cover(s_worker *w, const s_job *j, uint64_t job, const pf_msg_tile_t *t)
{
    if ((uint64_t)t->cw * t->ch == 0)
        return 1;
    int64_t R = j->desc.settings.gather_filter > 0 ? j->desc.settings.gather_filter : 0;
    int64_t W = j->desc.settings.width, H = j->desc.settings.height;
    int64_t x0 = (int64_t)t->x0 - R, y0 = (int64_t)t->y0 - R;
    int64_t x1 = (int64_t)t->x0 + t->w + R, y1 = (int64_t)t->y0 + t->h + R;
    x0 = x0 < 0 ? 0 : x0, y0 = y0 < 0 ? 0 : y0, x1 = x1 > W ? W : x1, y1 = y1 > H ? H : y1;
    if ((int64_t)t->cx0 <= x0 && (int64_t)t->cy0 <= y0 && (int64_t)t->cx0 + t->cw >= x1 &&
        (int64_t)t->cy0 + t->ch >= y1)
        return 1;
    pf_w_log(w, PF_LOG_WARN, "TILE %" PRIu32 " of job %" PRIu64 ": its per-pixel counts do not cover the tile and "
             "its border; dropped", t->tile, job);
    return 0;
}

void pf_w_on_tile(s_worker *w, const pf_msg_t *m)
{
    const pf_msg_tile_t *t = &m->u.tile;
    s_job *j = w->job;
    if (!j || j->id != m->job) {
        pf_w_log(w, PF_LOG_DEBUG, "TILE %" PRIu32 " of job %" PRIu64 ", which is not the current job; dropped", t->tile,
                 m->job);
        return;
    }
    if (j->state != S_JOB_READY) {
        if (j->state == S_JOB_FAILED)
            pf_w_log(w, PF_LOG_DEBUG, "TILE %" PRIu32 " of job %" PRIu64 ", which this worker rejected; dropped",
                     t->tile, m->job);
        else
            pf_w_log(w, PF_LOG_WARN, "TILE %" PRIu32 " of job %" PRIu64 " before READY; dropped", t->tile, m->job);
        return;
    }
    uint64_t W = (uint64_t)j->desc.settings.width, H = (uint64_t)j->desc.settings.height;
    if (t->w < 1 || t->h < 1 || (uint64_t)t->x0 + t->w > W || (uint64_t)t->y0 + t->h > H ||
        (uint64_t)t->w * t->h > PF_PROTO_MAX_TILE_PIXELS) {
        pf_w_log(w, PF_LOG_WARN, "TILE %" PRIu32 " of job %" PRIu64 ": %" PRIu32 "x%" PRIu32 " at (%" PRIu32
                 ", %" PRIu32 ") is not inside the %" PRIu64 "x%" PRIu64 " image; dropped", t->tile, m->job, t->w, t->h,
                 t->x0, t->y0, W, H);
        return;
    }
    if (!s_tile_admissible(w, j, t) || !s_tile_counts_cover(w, j, m->job, t))
        return;
    s_work *it = calloc(1, sizeof *it);
    float *rgb = malloc((size_t)t->w * t->h * 3 * sizeof *rgb);
    size_t nc = (size_t)t->cw * t->ch;
    uint16_t *counts = nc ? malloc(nc * sizeof *counts) : NULL;
    if (!it || !rgb || (nc && !counts)) {
        free(it);
        free(rgb);
        free(counts);
        pf_w_log(w, PF_LOG_ERROR, "out of memory for TILE %" PRIu32, t->tile);
        return;
    }
    it->kind = S_WORK_TILE;
    it->job = j;
    j->refs++;
    it->tile = *t;
    it->tile.counts_le = NULL;
    it->tile.counts = NULL;
    for (size_t i = 0; i < nc; i++)
        counts[i] = pf_msg_tile_count(t, (uint32_t)i);
    it->counts = counts;
    it->rgb = rgb;
    w->tiles_held++;
    j->held_tiles[j->held].tile = t->tile;
    j->held_tiles[j->held].attempt = t->attempt;
    j->held++;
    pf_w_enqueue(w, it);
}

/* Takes finished items back from the compute thread. */
void pf_w_drain_done(s_worker *w)
{
    s_work *list = pf_w_take_done(w);
    while (list) {
        s_work *it = list;
        list = it->next;
        s_job *j = it->job;
        int current = j == w->job && !atomic_load(&j->cancelled);
        if (it->kind == S_WORK_IRR) {
            pf_w_irr_sent(w, it);
        } else if (it->kind == S_WORK_PHOTONS) {
            pf_w_photons_sent(w, it);
        } else if (it->kind == S_WORK_BUILD) {
            s_build_forget(w, it);
            if (it->built) {
                /* Cache the build even if its job is gone: the next job
                 * with the same scene and maps will want it. */
                pf_w_built_release(w->built_cache);
                w->built_cache = it->built;
                it->built = NULL;
            }
            /* The current job may be this item's or one waiting for it. */
            s_job *cj = w->job;
            if (cj && cj->state == S_JOB_BUILD && s_same_build(&cj->desc, &j->desc)) {
                if (s_built_fits(w->built_cache, &cj->desc)) {
                    s_job_ready(w, cj, w->built_cache);
                } else if (it->error[0]) {
                    s_job_fail(w, cj, it->error);
                } else if (!s_build_pending(w, &cj->desc)) {
                    /* The build was skipped (its job was cancelled before it
                     * started): build again for this one. */
                    cj->state = S_JOB_FETCH;
                    s_job_advance(w);
                }
            }
        } else {
            w->tiles_held--;
            s_tile_unhold(j, it->tile.tile, it->tile.attempt);
            if (current && it->rendered && w->conn == S_ONLINE) {
                pf_msg_t m;
                memset(&m, 0, sizeof m);
                m.type = PF_MSG_RESULT;
                m.job = j->id;
                pf_msg_result_t *r = &m.u.result;
                r->tile = it->tile.tile;
                r->attempt = it->tile.attempt;
                r->x0 = it->tile.x0;
                r->y0 = it->tile.y0;
                r->w = it->tile.w;
                r->h = it->tile.h;
                r->rgb = it->rgb;
                r->render_us = it->render_us;
                pf_w_send(w, &m, 0);
            } else {
                pf_w_log(w, PF_LOG_DEBUG, "tile %" PRIu32 " of job %" PRIu64 " discarded (job ended)", it->tile.tile,
                         j->id);
            }
        }
        int was_build = it->kind != S_WORK_TILE;
        pf_w_work_free(it);
        if (was_build)
            pf_w_blobs_trim(w); /* its blobs are unpinned now */
    }
}

/* ---- timers and exit ---- */

void pf_w_blobs_resume(s_worker *w, double gap)
{
    for (size_t i = 0; i < w->nblobs; i++)
        w->blobs[i]->last_chunk += gap;
}

void pf_w_blobs_check_stalls(s_worker *w, double now)
{
    for (size_t i = 0; i < w->nblobs; i++) {
        s_blob *b = w->blobs[i];
        if (!b->complete && b->from_peer && now - b->last_chunk > S_PEER_STALL_S) {
            char why[80];
            snprintf(why, sizeof why, "its source sent nothing for %.0f s", S_PEER_STALL_S);
            pf_w_peers_strike_source(w, why);
            pf_w_blob_fallback(w, b, why);
        } else if (!b->complete && s_blob_needed(w, b) && now - b->last_chunk > S_STALL_S) {
            pf_w_log(w, PF_LOG_WARN, "transfer of blob %016" PRIx64 " stalled at %" PRIu64 " of %" PRIu64
                     " bytes; asking again", b->hash, b->received, b->size);
            s_blob_restart(w, b);
        }
    }
}

void pf_w_cache_free(s_worker *w)
{
    pf_w_built_release(w->built_cache);
    while (w->nblobs)
        s_blob_remove(w, 0);
    free(w->blobs);
}
