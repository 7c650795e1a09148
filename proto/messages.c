/* messages.c: the message codecs of the photonfarm protocol (the layout of
 * every message is in messages.h), the shared settings field group, and the
 * build fingerprint of the handshake.
 *
 * Decoding is the boundary where bytes from the network enter, so it trusts
 * nothing: a decode context wraps the bounds-checked cursor of wire.c and, on
 * the first problem, writes one sentence into why naming the message type and
 * the field ("JOB: settings.spp 0 is out of range 1..2147483647", "TILE: the
 * frame ends inside h"), then every later read is a no-op. Range rules are
 * written once per type (s_check) and serve both sides: the encoder refuses
 * to send what the decoder would refuse to receive (PF_EINVAL), so a bug shows
 * up at the sender, where it can be found.
 *
 * Bodies on the wire, after the 16-byte header (str: u16 length + bytes):
 *   HELLO       u16 protocol, u16 photon_size, u16 float_size, u16 map_version,
 *               str git, u32 threads, str name, u16 peer_port
 *   WELCOME     u32 worker_id, u32 heartbeat_ms
 *   REFUSE      str reason
 *   HEARTBEAT   u64 progress, u32 tiles_held
 *   JOB         u64 scene_hash, scene_size, maps_hash, maps_size,
 *               settings (100 bytes, below), u32 terms, u32 tile_size
 *   BLOB_REQ    u64 hash, u64 offset, u32 credit
 *   BLOB_CHUNK  u64 hash, u64 total, u64 offset, u32 len, len bytes
 *   READY       u32 credit
 *   TILE        u32 tile, attempt, x0, y0, w, h
 *   RESULT      u32 tile, attempt, x0, y0, w, h, render_us, then w*h*3 f32
 *               (RGB by row) to the end of the frame
 *   JOB_END     (empty)
 *   BYE         str reason
 *   PHOTON_REQ  u64 scene_hash, scene_size, settings, u32 first, u32 count
 *   PHOTONS     u32 batch, u64 total, first, rejected, indirect, u32 n, then n
 *               photons of 32 bytes (f32 pos[3], f32 power[3], u32 dir,
 *               u32 normal) to the end of the frame
 *   BLOB_PLAN   u64 hash, u64 size, u32 source_uid, str source, u64 root,
 *               u32 n, then n u64 chunk hashes to the end of the frame
 *               (n = chunks of size; root = pf_chunk_root of them)
 *   IRR_REQ     u64 scene_hash, scene_size, maps_hash, maps_size, settings,
 *               u32 first, u32 count
 *   IRR_POINTS  as PHOTONS (batch: the chunk; first, rejected, indirect 0)
 *
 * Owns nothing: decoded chunk data and result pixels point into the frame.
 * Reentrant; any thread may encode or decode. */
#include "proto/messages.h"

#include <inttypes.h>
#include <math.h>
#include <stdarg.h>
#include <stdio.h>
#include <string.h>

#include "base/hash.h"
#include "base/status.h"
#include "base/wire.h"
#include "proto/hashtree.h"

_Static_assert(PF_HASHTREE_CHUNK == PF_PROTO_CHUNK_SIZE, "chunk hashes cover exactly one BLOB_CHUNK each");

/* Bounds of the range checks (see messages.h for what each field means). */
#define S_MAX_IMAGE_SIDE 65536
#define S_MAX_DEPTH 100000
#define S_MAX_K 1024
#define S_MAX_TILE_SIZE 256
#define S_MAX_TERMS 31
#define S_MAX_THREADS 4096
#define S_MAX_HEARTBEAT_MS 60000
#define S_MAX_READY_CREDIT 1024
#define S_MAX_BLOB_CREDIT 64

static const char *const s_type_names[] = {
    [PF_MSG_HELLO] = "HELLO",         [PF_MSG_WELCOME] = "WELCOME", [PF_MSG_REFUSE] = "REFUSE",
    [PF_MSG_HEARTBEAT] = "HEARTBEAT", [PF_MSG_JOB] = "JOB",         [PF_MSG_BLOB_REQ] = "BLOB_REQ",
    [PF_MSG_BLOB_CHUNK] = "BLOB_CHUNK", [PF_MSG_READY] = "READY",   [PF_MSG_TILE] = "TILE",
    [PF_MSG_RESULT] = "RESULT",       [PF_MSG_JOB_END] = "JOB_END", [PF_MSG_BYE] = "BYE",
    [PF_MSG_PHOTON_REQ] = "PHOTON_REQ", [PF_MSG_PHOTONS] = "PHOTONS", [PF_MSG_BLOB_PLAN] = "BLOB_PLAN",
    [PF_MSG_IRR_REQ] = "IRR_REQ", [PF_MSG_IRR_POINTS] = "IRR_POINTS",
};

const char *pf_msg_type_name(int type)
{
    if (type < 1 || type > PF_MSG_MAX_TYPE)
        return "UNKNOWN";
    return s_type_names[type];
}

/* Writes a sentence into why (which may be NULL). */
static void s_whyf(char *why, size_t why_len, const char *fmt, ...) __attribute__((format(printf, 3, 4)));
static void s_whyf(char *why, size_t why_len, const char *fmt, ...)
{
    if (!why || why_len == 0)
        return;
    va_list ap;
    va_start(ap, fmt);
    vsnprintf(why, why_len, fmt, ap);
    va_end(ap);
}

/* Encoders write field after field and stop at the first failure; W runs a
 * writer only while rc (in the caller's scope) is still 0. */
#define W(call)            \
    do {                   \
        if (rc == 0)       \
            rc = (call);   \
    } while (0)

/* ---- the settings field group ----
 *
 * On the wire, in this order (the declaration order of pf_settings_t), 100
 * bytes; int fields travel as two's-complement i32:
 *   i32 width, i32 height, i32 spp,
 *   u64 photons, u64 caustic_photons,
 *   i32 gather, i32 gather_filter, i32 light_samples, i32 max_depth, i32 photon_max_depth,
 *   i32 global_k, i32 caustic_k,
 *   f32 caustic_radius, f32 global_radius,
 *   i32 irradiance_stride, i32 threads,
 *   u64 seed, f32 exposure, i32 pass, f32 filter_box, f32 filter_tent, i32 path_max_depth
 */

static uint32_t s_u32_from_int(int v) { return (uint32_t)(int32_t)v; }

/* The inverse of s_u32_from_int, spelled out: converting an out-of-range
 * unsigned value to a signed type is implementation-defined in C. */
static int s_int_from_u32(uint32_t u)
{
    if (u <= (uint32_t)INT32_MAX)
        return (int)u;
    return -(int)(~u) - 1;
}

int pf_wr_settings(pf_buf_t *b, const pf_settings_t *s)
{
    int rc = 0;
    W(pf_wr_u32(b, s_u32_from_int(s->width)));
    W(pf_wr_u32(b, s_u32_from_int(s->height)));
    W(pf_wr_u32(b, s_u32_from_int(s->spp)));
    W(pf_wr_u64(b, s->photons));
    W(pf_wr_u64(b, s->caustic_photons));
    W(pf_wr_u32(b, s_u32_from_int(s->gather)));
    W(pf_wr_u32(b, s_u32_from_int(s->gather_filter)));
    W(pf_wr_u32(b, s_u32_from_int(s->light_samples)));
    W(pf_wr_u32(b, s_u32_from_int(s->max_depth)));
    W(pf_wr_u32(b, s_u32_from_int(s->photon_max_depth)));
    W(pf_wr_u32(b, s_u32_from_int(s->global_k)));
    W(pf_wr_u32(b, s_u32_from_int(s->caustic_k)));
    W(pf_wr_f32(b, s->caustic_radius));
    W(pf_wr_f32(b, s->global_radius));
    W(pf_wr_u32(b, s_u32_from_int(s->irradiance_stride)));
    W(pf_wr_u32(b, s_u32_from_int(s->threads)));
    W(pf_wr_u64(b, s->seed));
    W(pf_wr_f32(b, s->exposure));
    W(pf_wr_u32(b, s_u32_from_int(s->pass)));
    W(pf_wr_f32(b, s->filter_box));
    W(pf_wr_f32(b, s->filter_tent));
    W(pf_wr_u32(b, s_u32_from_int(s->path_max_depth)));
    return rc;
}

/* A decode: the cursor, the message type's name for the sentence, and where
 * the sentence goes. Only the first problem is reported. */
typedef struct s_dec {
    pf_rd_t r;
    const char *type;
    char *why;
    size_t why_len;
    int failed;
} s_dec_t;

static void s_fail(s_dec_t *d, const char *fmt, ...) __attribute__((format(printf, 2, 3)));
static void s_fail(s_dec_t *d, const char *fmt, ...)
{
    pf_rd_fail(&d->r);
    if (d->failed)
        return;
    d->failed = 1;
    if (!d->why || d->why_len == 0)
        return;
    int n = snprintf(d->why, d->why_len, "%s: ", d->type);
    if (n < 0 || (size_t)n >= d->why_len)
        return;
    va_list ap;
    va_start(ap, fmt);
    vsnprintf(d->why + n, d->why_len - (size_t)n, fmt, ap);
    va_end(ap);
}

/* Before each read: the field must be whole in what is left. */
static int s_need(s_dec_t *d, size_t n, const char *field)
{
    if (d->failed || d->r.err)
        return 0;
    if (d->r.left < n) {
        s_fail(d, "the frame ends inside %s (%zu of %zu bytes left)", field, d->r.left, n);
        return 0;
    }
    return 1;
}

static uint16_t s_u16(s_dec_t *d, const char *field) { return s_need(d, 2, field) ? pf_rd_u16(&d->r) : 0; }
static uint32_t s_u32(s_dec_t *d, const char *field) { return s_need(d, 4, field) ? pf_rd_u32(&d->r) : 0; }
static uint64_t s_u64(s_dec_t *d, const char *field) { return s_need(d, 8, field) ? pf_rd_u64(&d->r) : 0; }
static int s_i32(s_dec_t *d, const char *field) { return s_int_from_u32(s_u32(d, field)); }

/* A TILE's per-pixel samples: the rectangle, then its counts. */
static void s_tile_counts(s_dec_t *d, pf_msg_tile_t *t)
{
    t->cx0 = s_u32(d, "cx0");
    t->cy0 = s_u32(d, "cy0");
    t->cw = s_u32(d, "cw");
    t->ch = s_u32(d, "ch");
    uint64_t n = (uint64_t)t->cw * t->ch;
    if (d->failed || n == 0)
        return;
    if (n > PF_PROTO_MAX_TILE_COUNTS) {
        s_fail(d, "%" PRIu64 " per-pixel counts, over the limit of %u", n, (unsigned)PF_PROTO_MAX_TILE_COUNTS);
        return;
    }
    if (!s_need(d, 2 * (size_t)n, "counts"))
        return;
    t->counts_le = pf_rd_bytes(&d->r, 2 * (size_t)n); /* each >= 1: s_check */
}

static float s_f32(s_dec_t *d, const char *field)
{
    if (!s_need(d, 4, field))
        return 0.0f;
    float f = pf_rd_f32(&d->r);
    if (d->r.err)
        s_fail(d, "%s is not a finite number", field);
    return f;
}

static void s_str(s_dec_t *d, const char *field, char *dst, size_t cap)
{
    dst[0] = '\0';
    if (!s_need(d, 2, field))
        return;
    size_t n = (size_t)d->r.p[0] | (size_t)d->r.p[1] << 8;
    if (n > PF_PROTO_MAX_STRING) {
        s_fail(d, "%s is %zu bytes, over the limit of %u", field, n, (unsigned)PF_PROTO_MAX_STRING);
        return;
    }
    if (n >= cap) {
        s_fail(d, "%s is %zu bytes; at most %zu fit", field, n, cap - 1);
        return;
    }
    if (d->r.left - 2 < n) {
        s_fail(d, "the frame ends inside %s (%zu bytes of text, %zu left)", field, n, d->r.left - 2);
        return;
    }
    pf_rd_str(&d->r, dst, cap);
    if (d->r.err)
        s_fail(d, "%s contains a NUL byte", field);
}

static void s_dec_settings(s_dec_t *d, pf_settings_t *s)
{
    s->width = s_i32(d, "settings.width");
    s->height = s_i32(d, "settings.height");
    s->spp = s_i32(d, "settings.spp");
    s->photons = s_u64(d, "settings.photons");
    s->caustic_photons = s_u64(d, "settings.caustic_photons");
    s->gather = s_i32(d, "settings.gather");
    s->gather_filter = s_i32(d, "settings.gather_filter");
    s->light_samples = s_i32(d, "settings.light_samples");
    s->max_depth = s_i32(d, "settings.max_depth");
    s->photon_max_depth = s_i32(d, "settings.photon_max_depth");
    s->global_k = s_i32(d, "settings.global_k");
    s->caustic_k = s_i32(d, "settings.caustic_k");
    s->caustic_radius = s_f32(d, "settings.caustic_radius");
    s->global_radius = s_f32(d, "settings.global_radius");
    s->irradiance_stride = s_i32(d, "settings.irradiance_stride");
    s->threads = s_i32(d, "settings.threads");
    s->seed = s_u64(d, "settings.seed");
    s->exposure = s_f32(d, "settings.exposure");
    s->pass = s_i32(d, "settings.pass");
    s->filter_box = s_f32(d, "settings.filter_box");
    s->filter_tent = s_f32(d, "settings.filter_tent");
    s->path_max_depth = s_i32(d, "settings.path_max_depth");
}

void pf_rd_settings(pf_rd_t *r, pf_settings_t *s)
{
    s_dec_t d = { *r, "settings", NULL, 0, r->err };
    s_dec_settings(&d, s);
    *r = d.r;
}

/* Range checks write "field value is out of range lo..hi" into why and return
 * nonzero when the value is outside. */
static int s_out_of_range(char *why, size_t why_len, const char *field, int64_t v, int64_t lo, int64_t hi)
{
    if (v >= lo && v <= hi)
        return 0;
    s_whyf(why, why_len, "%s %" PRId64 " is out of range %" PRId64 "..%" PRId64, field, v, lo, hi);
    return 1;
}

static int s_bad_radius(char *why, size_t why_len, const char *field, float v)
{
    if (isfinite(v) && v >= 0.0f)
        return 0;
    s_whyf(why, why_len, "%s %g must be finite and >= 0", field, (double)v);
    return 1;
}

int pf_settings_check(const pf_settings_t *s, char *why, size_t why_len)
{
    if (s_out_of_range(why, why_len, "settings.width", s->width, 1, S_MAX_IMAGE_SIDE) ||
        s_out_of_range(why, why_len, "settings.height", s->height, 1, S_MAX_IMAGE_SIDE) ||
        s_out_of_range(why, why_len, "settings.spp", s->spp, 1, INT32_MAX) ||
        s_out_of_range(why, why_len, "settings.gather", s->gather, 0, INT32_MAX) ||
        s_out_of_range(why, why_len, "settings.gather_filter", s->gather_filter, 0, PF_MAX_GATHER_FILTER) ||
        s_out_of_range(why, why_len, "settings.light_samples", s->light_samples, 1, INT32_MAX) ||
        s_out_of_range(why, why_len, "settings.max_depth", s->max_depth, 0, S_MAX_DEPTH) ||
        s_out_of_range(why, why_len, "settings.photon_max_depth", s->photon_max_depth, 0, S_MAX_DEPTH) ||
        s_out_of_range(why, why_len, "settings.path_max_depth", s->path_max_depth, -1, S_MAX_DEPTH) ||
        s_out_of_range(why, why_len, "settings.global_k", s->global_k, 1, S_MAX_K) ||
        s_out_of_range(why, why_len, "settings.caustic_k", s->caustic_k, 1, S_MAX_K) ||
        s_bad_radius(why, why_len, "settings.caustic_radius", s->caustic_radius) ||
        s_bad_radius(why, why_len, "settings.global_radius", s->global_radius) ||
        s_out_of_range(why, why_len, "settings.irradiance_stride", s->irradiance_stride, 1, INT32_MAX) ||
        s_out_of_range(why, why_len, "settings.threads", s->threads, 0, INT32_MAX) ||
        s_out_of_range(why, why_len, "settings.pass", s->pass, 0, PF_MAX_PASSES - 1))
        return PF_EINVAL;
    if (!(s->filter_box >= 0.0f && s->filter_box <= PF_MAX_FILTER_WIDTH && s->filter_tent >= 0.0f &&
          s->filter_tent <= PF_MAX_FILTER_WIDTH && s->filter_box + s->filter_tent > 0.0f)) {
        s_whyf(why, why_len, "settings.filter_box %g and filter_tent %g must lie in 0..%g, not both 0",
               (double)s->filter_box, (double)s->filter_tent, (double)PF_MAX_FILTER_WIDTH);
        return PF_EINVAL;
    }
    if (!isfinite(s->exposure)) {
        s_whyf(why, why_len, "settings.exposure %g is not finite", (double)s->exposure);
        return PF_EINVAL;
    }
    return PF_OK;
}

/* ---- range rules, shared by encoder and decoder ---- */

/* A tile rectangle: non-empty, at most PF_PROTO_MAX_TILE_PIXELS, and its far
 * edges representable. */
/* Count i of a TILE to encode or decoded. */
static uint16_t s_tile_count(const pf_msg_tile_t *t, uint32_t i)
{
    return t->counts ? t->counts[i] : pf_msg_tile_count(t, i);
}

static int s_bad_rect(char *why, size_t why_len, uint32_t x0, uint32_t y0, uint32_t w, uint32_t h)
{
    if (s_out_of_range(why, why_len, "w", w, 1, PF_PROTO_MAX_TILE_PIXELS) ||
        s_out_of_range(why, why_len, "h", h, 1, PF_PROTO_MAX_TILE_PIXELS))
        return 1;
    if ((uint64_t)w * h > PF_PROTO_MAX_TILE_PIXELS) {
        s_whyf(why, why_len, "a %" PRIu32 "x%" PRIu32 " tile is over the limit of %u pixels", w, h,
               (unsigned)PF_PROTO_MAX_TILE_PIXELS);
        return 1;
    }
    if (x0 > UINT32_MAX - w || y0 > UINT32_MAX - h) {
        s_whyf(why, why_len, "the tile at (%" PRIu32 ", %" PRIu32 ") of %" PRIu32 "x%" PRIu32
               " runs past 2^32", x0, y0, w, h);
        return 1;
    }
    return 0;
}

/* A string field of the struct must end inside its array. */
static int s_bad_str(char *why, size_t why_len, const char *field, const char *s, size_t cap)
{
    if (memchr(s, 0, cap))
        return 0;
    s_whyf(why, why_len, "%s is not NUL-terminated within %zu bytes", field, cap);
    return 1;
}

/* Every rule of messages.h except the byte-level ones (RESULT's pixel bytes);
 * 0, or nonzero with why ("field value ...", without the type). */
static int s_check(const pf_msg_t *m, char *why, size_t why_len)
{
    switch (m->type) {
    case PF_MSG_HELLO:
        return s_bad_str(why, why_len, "fingerprint.git", m->u.hello.fp.git, sizeof m->u.hello.fp.git) ||
               s_bad_str(why, why_len, "name", m->u.hello.name, sizeof m->u.hello.name) ||
               s_out_of_range(why, why_len, "threads", m->u.hello.threads, 1, S_MAX_THREADS);
    case PF_MSG_WELCOME:
        return s_out_of_range(why, why_len, "heartbeat_ms", m->u.welcome.heartbeat_ms, 1, S_MAX_HEARTBEAT_MS);
    case PF_MSG_REFUSE:
        return s_bad_str(why, why_len, "reason", m->u.refuse.reason, sizeof m->u.refuse.reason);
    case PF_MSG_HEARTBEAT:
        return 0;
    case PF_MSG_JOB:
        return pf_settings_check(&m->u.job.settings, why, why_len) != PF_OK ||
               s_out_of_range(why, why_len, "terms", m->u.job.terms, 1, S_MAX_TERMS) ||
               s_out_of_range(why, why_len, "tile_size", m->u.job.tile_size, 1, S_MAX_TILE_SIZE);
    case PF_MSG_BLOB_REQ:
        if (s_out_of_range(why, why_len, "credit", m->u.blob_req.credit, 1, S_MAX_BLOB_CREDIT))
            return 1;
        if (m->u.blob_req.offset % PF_PROTO_CHUNK_SIZE) {
            s_whyf(why, why_len, "offset %" PRIu64 " is not a multiple of the chunk size %u", m->u.blob_req.offset,
                   (unsigned)PF_PROTO_CHUNK_SIZE);
            return 1;
        }
        return 0;
    case PF_MSG_BLOB_CHUNK: {
        const pf_msg_blob_chunk_t *c = &m->u.chunk;
        if (s_out_of_range(why, why_len, "len", c->len, 0, PF_PROTO_CHUNK_SIZE))
            return 1;
        if (c->offset > c->total || c->len > c->total - c->offset) {
            s_whyf(why, why_len, "offset %" PRIu64 " + len %" PRIu32 " runs past total %" PRIu64, c->offset, c->len,
                   c->total);
            return 1;
        }
        return 0;
    }
    case PF_MSG_READY:
        return s_out_of_range(why, why_len, "credit", m->u.ready.credit, 1, S_MAX_READY_CREDIT);
    case PF_MSG_TILE: {
        const pf_msg_tile_t *t = &m->u.tile;
        uint64_t n = (uint64_t)t->cw * t->ch;
        if (n > PF_PROTO_MAX_TILE_COUNTS || (n && !t->counts && !t->counts_le)) {
            s_whyf(why, why_len, "%" PRIu32 "x%" PRIu32 " per-pixel counts are over the limit or missing", t->cw,
                   t->ch);
            return 1;
        }
        for (uint32_t i = 0; i < n; i++)
            if (s_tile_count(t, i) == 0) {
                s_whyf(why, why_len, "count %" PRIu32 " is 0; a pixel takes at least one sample", i);
                return 1;
            }
        return s_bad_rect(why, why_len, t->x0, t->y0, t->w, t->h);
    }
    case PF_MSG_RESULT:
        return s_bad_rect(why, why_len, m->u.result.x0, m->u.result.y0, m->u.result.w, m->u.result.h);
    case PF_MSG_JOB_END:
        return 0;
    case PF_MSG_BYE:
        return s_bad_str(why, why_len, "reason", m->u.bye.reason, sizeof m->u.bye.reason);
    case PF_MSG_PHOTON_REQ: {
        const pf_msg_photon_req_t *q = &m->u.photon_req;
        return pf_settings_check(&q->settings, why, why_len) != PF_OK ||
               s_out_of_range(why, why_len, "count", q->count, 1, PF_PROTO_MAX_REQ_BATCHES) ||
               s_out_of_range(why, why_len, "first", q->first, 0, PF_PROTO_MAX_BATCHES - q->count);
    }
    case PF_MSG_IRR_REQ: {
        const pf_msg_irr_req_t *q = &m->u.irr_req;
        return pf_settings_check(&q->settings, why, why_len) != PF_OK ||
               s_out_of_range(why, why_len, "count", q->count, 1, PF_PROTO_MAX_REQ_IRR_CHUNKS) ||
               s_out_of_range(why, why_len, "first", q->first, 0, PF_PROTO_MAX_IRR_CHUNKS - q->count) ||
               s_out_of_range(why, why_len, "maps_size", q->maps_size ? 1 : 0, 1, 1);
    }
    case PF_MSG_IRR_POINTS: {
        const pf_msg_photons_t *p = &m->u.photons;
        if (s_out_of_range(why, why_len, "chunk", p->batch, 0, PF_PROTO_MAX_IRR_CHUNKS - 1) ||
            s_out_of_range(why, why_len, "n", p->n, 1, PF_PROTO_IRR_CHUNK_POINTS))
            return 1;
        if (p->total != p->n || p->first || p->rejected || p->indirect) {
            s_whyf(why, why_len, "a chunk is one message: total %" PRIu64 " must be n %" PRIu32 ", and first %" PRIu64
                   ", rejected %" PRIu64 ", indirect %" PRIu64 " 0", p->total, p->n, p->first, p->rejected, p->indirect);
            return 1;
        }
        return 0;
    }
    case PF_MSG_PHOTONS: {
        const pf_msg_photons_t *p = &m->u.photons;
        if (s_out_of_range(why, why_len, "batch", p->batch, 0, PF_PROTO_MAX_BATCHES - 1) ||
            s_out_of_range(why, why_len, "n", p->n, p->total ? 1 : 0, PF_PROTO_MAX_PART_PHOTONS))
            return 1;
        if (p->total > PF_PROTO_MAX_BATCH_PHOTONS || p->first > p->total || p->n > p->total - p->first ||
            p->indirect > p->total) {
            s_whyf(why, why_len, "photons first %" PRIu64 " + n %" PRIu32 ", indirect %" PRIu64 " do not fit total %"
                   PRIu64, p->first, p->n, p->indirect, p->total);
            return 1;
        }
        return 0;
    }
    case PF_MSG_BLOB_PLAN: {
        const pf_msg_blob_plan_t *p = &m->u.plan;
        if (s_bad_str(why, why_len, "source", p->source, sizeof p->source))
            return 1;
        if (p->source[0] && strncmp(p->source, "tcp://", 6) != 0) {
            s_whyf(why, why_len, "source does not begin with tcp://");
            return 1;
        }
        for (const char *c = p->source; *c; c++)
            if (*c <= ' ' || *c > '~') {
                s_whyf(why, why_len, "source holds a byte 0x%02x that is not printable", (unsigned)(uint8_t)*c);
                return 1;
            }
        if (p->size == 0 || p->size > (uint64_t)PF_PROTO_MAX_PLAN_CHUNKS * PF_PROTO_CHUNK_SIZE ||
            p->n != pf_chunk_count(p->size)) {
            s_whyf(why, why_len, "n %" PRIu32 " chunk hashes for a blob of %" PRIu64 " bytes", p->n, p->size);
            return 1;
        }
        return 0;
    }
    }
    s_whyf(why, why_len, "unknown message type %d", (int)m->type);
    return 1;
}

/* ---- encoding ---- */

/* BLOB_PLAN's body (its root checked by the caller). */
static int s_enc_plan(pf_buf_t *out, const pf_msg_blob_plan_t *pl)
{
    int rc = 0;
    W(pf_wr_u64(out, pl->hash));
    W(pf_wr_u64(out, pl->size));
    W(pf_wr_u32(out, pl->source_uid));
    W(pf_wr_str(out, pl->source));
    W(pf_wr_u64(out, pl->root));
    W(pf_wr_u32(out, pl->n));
    for (uint32_t k = 0; k < pl->n && rc == 0; k++)
        W(pf_wr_u64(out, pl->leaves[k]));
    return rc;
}

/* The payload rules s_check leaves out (pixels, photons, the plan's root):
 * 0, or PF_EINVAL. */
static int s_enc_payload_bad(const pf_msg_t *msg)
{
    const pf_msg_result_t *res = &msg->u.result;
    size_t npix = 0;
    if (msg->type == PF_MSG_RESULT) {
        npix = (size_t)res->w * res->h * 3;
        if (!res->rgb)
            return PF_EINVAL;
        for (size_t i = 0; i < npix; i++)
            if (!isfinite(res->rgb[i]) || !(res->rgb[i] >= 0.0f))
                return PF_EINVAL;
    }
    if (msg->type == PF_MSG_BLOB_CHUNK && msg->u.chunk.len > 0 && !msg->u.chunk.data)
        return PF_EINVAL;
    const pf_msg_photons_t *ph = &msg->u.photons;
    if (msg->type == PF_MSG_PHOTONS || msg->type == PF_MSG_IRR_POINTS) {
        if (ph->n > 0 && !ph->photons)
            return PF_EINVAL;
        for (uint32_t i = 0; i < ph->n; i++)
            for (int c = 0; c < 3; c++)
                if (!isfinite(ph->photons[i].pos[c]) || !isfinite(ph->photons[i].power[c]) ||
                    !(ph->photons[i].power[c] >= 0.0f))
                    return PF_EINVAL;
    }

    const pf_msg_blob_plan_t *pl = &msg->u.plan;
    if (msg->type == PF_MSG_BLOB_PLAN && (!pl->leaves || pf_chunk_root(pl->hash, pl->size, pl->leaves, pl->n) != pl->root))
        return PF_EINVAL;
    return 0;
}

int pf_msg_encode(const pf_msg_t *msg, pf_buf_t *out)
{
    out->len = 0;
    if (s_check(msg, NULL, 0) || s_enc_payload_bad(msg))
        return PF_EINVAL;
    const pf_msg_result_t *res = &msg->u.result;
    size_t npix = msg->type == PF_MSG_RESULT ? (size_t)res->w * res->h * 3 : 0;
    const pf_msg_photons_t *ph = &msg->u.photons;
    const pf_msg_blob_plan_t *pl = &msg->u.plan;
    int rc = 0;
    W(pf_wr_u32(out, PF_PROTO_MAGIC));
    W(pf_wr_u16(out, PF_PROTO_VERSION));
    W(pf_wr_u16(out, (uint16_t)msg->type));
    W(pf_wr_u64(out, msg->job));
    switch (msg->type) {
    case PF_MSG_HELLO: {
        const pf_msg_hello_t *h = &msg->u.hello;
        W(pf_wr_u16(out, h->fp.protocol));
        W(pf_wr_u16(out, h->fp.photon_size));
        W(pf_wr_u16(out, h->fp.float_size));
        W(pf_wr_u16(out, h->fp.map_version));
        W(pf_wr_str(out, h->fp.git));
        W(pf_wr_u32(out, h->threads));
        W(pf_wr_str(out, h->name));
        W(pf_wr_u16(out, h->peer_port));
        break;
    }
    case PF_MSG_WELCOME:
        W(pf_wr_u32(out, msg->u.welcome.worker_id));
        W(pf_wr_u32(out, msg->u.welcome.heartbeat_ms));
        break;
    case PF_MSG_REFUSE:
        W(pf_wr_str(out, msg->u.refuse.reason));
        break;
    case PF_MSG_HEARTBEAT:
        W(pf_wr_u64(out, msg->u.heartbeat.progress));
        W(pf_wr_u32(out, msg->u.heartbeat.tiles_held));
        break;
    case PF_MSG_JOB: {
        const pf_msg_job_t *j = &msg->u.job;
        W(pf_wr_u64(out, j->scene_hash));
        W(pf_wr_u64(out, j->scene_size));
        W(pf_wr_u64(out, j->maps_hash));
        W(pf_wr_u64(out, j->maps_size));
        W(pf_wr_settings(out, &j->settings));
        W(pf_wr_u32(out, j->terms));
        W(pf_wr_u32(out, j->tile_size));
        break;
    }
    case PF_MSG_BLOB_REQ:
        W(pf_wr_u64(out, msg->u.blob_req.hash));
        W(pf_wr_u64(out, msg->u.blob_req.offset));
        W(pf_wr_u32(out, msg->u.blob_req.credit));
        break;
    case PF_MSG_BLOB_CHUNK:
        W(pf_wr_u64(out, msg->u.chunk.hash));
        W(pf_wr_u64(out, msg->u.chunk.total));
        W(pf_wr_u64(out, msg->u.chunk.offset));
        W(pf_wr_u32(out, msg->u.chunk.len));
        W(pf_wr_bytes(out, msg->u.chunk.data, msg->u.chunk.len));
        break;
    case PF_MSG_READY:
        W(pf_wr_u32(out, msg->u.ready.credit));
        break;
    case PF_MSG_TILE:
        W(pf_wr_u32(out, msg->u.tile.tile));
        W(pf_wr_u32(out, msg->u.tile.attempt));
        W(pf_wr_u32(out, msg->u.tile.x0));
        W(pf_wr_u32(out, msg->u.tile.y0));
        W(pf_wr_u32(out, msg->u.tile.w));
        W(pf_wr_u32(out, msg->u.tile.h));
        W(pf_wr_u32(out, msg->u.tile.cx0));
        W(pf_wr_u32(out, msg->u.tile.cy0));
        W(pf_wr_u32(out, msg->u.tile.cw));
        W(pf_wr_u32(out, msg->u.tile.ch));
        for (uint32_t i = 0; i < msg->u.tile.cw * msg->u.tile.ch && rc == 0; i++)
            rc = pf_wr_u16(out, s_tile_count(&msg->u.tile, i));
        break;
    case PF_MSG_RESULT:
        W(pf_wr_u32(out, res->tile));
        W(pf_wr_u32(out, res->attempt));
        W(pf_wr_u32(out, res->x0));
        W(pf_wr_u32(out, res->y0));
        W(pf_wr_u32(out, res->w));
        W(pf_wr_u32(out, res->h));
        W(pf_wr_u32(out, res->render_us));
        /* The pixels are the rest of the frame, so their count is implied by
         * w and h and a decoder can check it against the frame's length. */
        for (size_t i = 0; i < npix && rc == 0; i++)
            rc = pf_wr_f32(out, res->rgb[i]);
        break;
    case PF_MSG_JOB_END:
        break;
    case PF_MSG_BYE:
        W(pf_wr_str(out, msg->u.bye.reason));
        break;
    case PF_MSG_PHOTON_REQ:
        W(pf_wr_u64(out, msg->u.photon_req.scene_hash));
        W(pf_wr_u64(out, msg->u.photon_req.scene_size));
        W(pf_wr_settings(out, &msg->u.photon_req.settings));
        W(pf_wr_u32(out, msg->u.photon_req.first));
        W(pf_wr_u32(out, msg->u.photon_req.count));
        break;
    case PF_MSG_IRR_REQ:
        W(pf_wr_u64(out, msg->u.irr_req.scene_hash));
        W(pf_wr_u64(out, msg->u.irr_req.scene_size));
        W(pf_wr_u64(out, msg->u.irr_req.maps_hash));
        W(pf_wr_u64(out, msg->u.irr_req.maps_size));
        W(pf_wr_settings(out, &msg->u.irr_req.settings));
        W(pf_wr_u32(out, msg->u.irr_req.first));
        W(pf_wr_u32(out, msg->u.irr_req.count));
        break;
    case PF_MSG_PHOTONS:
    case PF_MSG_IRR_POINTS:
        W(pf_wr_u32(out, ph->batch));
        W(pf_wr_u64(out, ph->total));
        W(pf_wr_u64(out, ph->first));
        W(pf_wr_u64(out, ph->rejected));
        W(pf_wr_u64(out, ph->indirect));
        W(pf_wr_u32(out, ph->n));
        for (uint32_t i = 0; i < ph->n && rc == 0; i++) {
            const pf_msg_photon_t *q = &ph->photons[i];
            for (int c = 0; c < 3; c++)
                W(pf_wr_f32(out, q->pos[c]));
            for (int c = 0; c < 3; c++)
                W(pf_wr_f32(out, q->power[c]));
            W(pf_wr_u32(out, q->dir));
            W(pf_wr_u32(out, q->normal));
        }
        break;
    case PF_MSG_BLOB_PLAN:
        W(s_enc_plan(out, pl));
        break;
    }
    if (rc != 0)
        out->len = 0;
    return rc;
}
#undef W

/* ---- decoding ---- */

/* PHOTONS: the counts, then exactly n photons to the end of the frame,
 * each position finite and each power finite and >= 0. */
static void s_dec_photons(s_dec_t *d, pf_msg_photons_t *p)
{
    p->batch = s_u32(d, "batch");
    p->total = s_u64(d, "total");
    p->first = s_u64(d, "first");
    p->rejected = s_u64(d, "rejected");
    p->indirect = s_u64(d, "indirect");
    p->n = s_u32(d, "n");
    if (d->failed)
        return;
    if (p->n > PF_PROTO_MAX_PART_PHOTONS) {
        s_fail(d, "n %" PRIu32 " is over %u photons a message", p->n, (unsigned)PF_PROTO_MAX_PART_PHOTONS);
        return;
    }
    size_t want = (size_t)p->n * PF_PROTO_PHOTON_BYTES;
    if (d->r.left != want) {
        s_fail(d, "%zu bytes of photons for n %" PRIu32 " (%zu expected)", d->r.left, p->n, want);
        return;
    }
    p->data = pf_rd_bytes(&d->r, want);
    for (uint32_t i = 0; i < p->n; i++) {
        pf_msg_photon_t q;
        pf_msg_photon_get(p, i, &q);
        for (int c = 0; c < 3; c++)
            if (!isfinite(q.pos[c]) || !isfinite(q.power[c]) || !(q.power[c] >= 0.0f)) {
                s_fail(d, "photon %" PRIu32 ": position or power not finite, or power < 0", i);
                return;
            }
    }
}

static uint64_t s_le64(const uint8_t *q)
{
    uint64_t v = 0;
    for (int i = 7; i >= 0; i--)
        v = v << 8 | q[i];
    return v;
}

uint64_t pf_msg_plan_leaf(const pf_msg_blob_plan_t *p, uint32_t k)
{
    return p->leaves ? p->leaves[k] : s_le64(p->leaves_le + 8 * (size_t)k);
}

/* BLOB_PLAN: the fields, then exactly n leaves to the end of the frame,
 * whose root must be the one sent (a plan damaged on the way is refused). */
static void s_dec_plan(s_dec_t *d, pf_msg_blob_plan_t *p)
{
    p->hash = s_u64(d, "hash");
    p->size = s_u64(d, "size");
    p->source_uid = s_u32(d, "source_uid");
    s_str(d, "source", p->source, sizeof p->source);
    p->root = s_u64(d, "root");
    p->n = s_u32(d, "n");
    if (d->failed)
        return;
    if (p->n > PF_PROTO_MAX_PLAN_CHUNKS) {
        s_fail(d, "n %" PRIu32 " is over %u chunk hashes a message", p->n, (unsigned)PF_PROTO_MAX_PLAN_CHUNKS);
        return;
    }
    size_t want = (size_t)p->n * 8;
    if (d->r.left != want) {
        s_fail(d, "%zu bytes of chunk hashes for n %" PRIu32 " (%zu expected)", d->r.left, p->n, want);
        return;
    }
    p->leaves_le = pf_rd_bytes(&d->r, want);
    uint64_t h = pf_chunk_root(p->hash, p->size, NULL, 0);
    for (uint32_t k = 0; k < p->n; k++)
        h = pf_hash_u64(h, s_le64(p->leaves_le + 8 * (size_t)k));
    if (h != p->root)
        s_fail(d, "the chunk hashes' root is %016" PRIx64 ", not the %016" PRIx64 " sent", h, p->root);
}

static void s_dec_body(s_dec_t *d, pf_msg_t *m)
{
    switch (m->type) {
    case PF_MSG_HELLO: {
        pf_msg_hello_t *h = &m->u.hello;
        h->fp.protocol = s_u16(d, "fingerprint.protocol");
        h->fp.photon_size = s_u16(d, "fingerprint.photon_size");
        h->fp.float_size = s_u16(d, "fingerprint.float_size");
        h->fp.map_version = s_u16(d, "fingerprint.map_version");
        s_str(d, "fingerprint.git", h->fp.git, sizeof h->fp.git);
        h->threads = s_u32(d, "threads");
        s_str(d, "name", h->name, sizeof h->name);
        h->peer_port = s_u16(d, "peer_port");
        break;
    }
    case PF_MSG_WELCOME:
        m->u.welcome.worker_id = s_u32(d, "worker_id");
        m->u.welcome.heartbeat_ms = s_u32(d, "heartbeat_ms");
        break;
    case PF_MSG_REFUSE:
        s_str(d, "reason", m->u.refuse.reason, sizeof m->u.refuse.reason);
        break;
    case PF_MSG_HEARTBEAT:
        m->u.heartbeat.progress = s_u64(d, "progress");
        m->u.heartbeat.tiles_held = s_u32(d, "tiles_held");
        break;
    case PF_MSG_JOB: {
        pf_msg_job_t *j = &m->u.job;
        j->scene_hash = s_u64(d, "scene_hash");
        j->scene_size = s_u64(d, "scene_size");
        j->maps_hash = s_u64(d, "maps_hash");
        j->maps_size = s_u64(d, "maps_size");
        s_dec_settings(d, &j->settings);
        j->terms = s_u32(d, "terms");
        j->tile_size = s_u32(d, "tile_size");
        break;
    }
    case PF_MSG_BLOB_REQ:
        m->u.blob_req.hash = s_u64(d, "hash");
        m->u.blob_req.offset = s_u64(d, "offset");
        m->u.blob_req.credit = s_u32(d, "credit");
        break;
    case PF_MSG_BLOB_CHUNK: {
        pf_msg_blob_chunk_t *c = &m->u.chunk;
        c->hash = s_u64(d, "hash");
        c->total = s_u64(d, "total");
        c->offset = s_u64(d, "offset");
        c->len = s_u32(d, "len");
        if (d->failed)
            break;
        if (c->len > PF_PROTO_CHUNK_SIZE) {
            s_fail(d, "len %" PRIu32 " is over the chunk size %u", c->len, (unsigned)PF_PROTO_CHUNK_SIZE);
            break;
        }
        if (d->r.left < c->len) {
            s_fail(d, "the frame ends inside data (len %" PRIu32 ", %zu bytes left)", c->len, d->r.left);
            break;
        }
        c->data = pf_rd_bytes(&d->r, c->len);
        break;
    }
    case PF_MSG_READY:
        m->u.ready.credit = s_u32(d, "credit");
        break;
    case PF_MSG_TILE:
        m->u.tile.tile = s_u32(d, "tile");
        m->u.tile.attempt = s_u32(d, "attempt");
        m->u.tile.x0 = s_u32(d, "x0");
        m->u.tile.y0 = s_u32(d, "y0");
        m->u.tile.w = s_u32(d, "w");
        m->u.tile.h = s_u32(d, "h");
        s_tile_counts(d, &m->u.tile);
        break;
    case PF_MSG_RESULT: {
        pf_msg_result_t *res = &m->u.result;
        res->tile = s_u32(d, "tile");
        res->attempt = s_u32(d, "attempt");
        res->x0 = s_u32(d, "x0");
        res->y0 = s_u32(d, "y0");
        res->w = s_u32(d, "w");
        res->h = s_u32(d, "h");
        res->render_us = s_u32(d, "render_us");
        if (d->failed)
            break;
        /* The rectangle decides how many pixel bytes must follow, so it is
         * checked here rather than after the body. */
        char why[160];
        if (s_bad_rect(why, sizeof why, res->x0, res->y0, res->w, res->h)) {
            s_fail(d, "%s", why);
            break;
        }
        size_t want = (size_t)res->w * res->h * 3 * 4;
        if (d->r.left != want) {
            s_fail(d, "%zu bytes of pixels for a %" PRIu32 "x%" PRIu32 " tile (%zu expected)", d->r.left, res->w,
                   res->h, want);
            break;
        }
        const uint8_t *px = pf_rd_bytes(&d->r, want);
        res->rgb_le = px;
        for (size_t i = 0; i < want / 4; i++) {
            const uint8_t *q = px + 4 * i;
            uint32_t u = (uint32_t)q[0] | (uint32_t)q[1] << 8 | (uint32_t)q[2] << 16 | (uint32_t)q[3] << 24;
            float f;
            memcpy(&f, &u, sizeof f);
            if (!isfinite(f) || !(f >= 0.0f)) {
                s_fail(d, "pixel %zu channel %zu is %g; pixels must be finite and >= 0", i / 3, i % 3, (double)f);
                break;
            }
        }
        break;
    }
    case PF_MSG_JOB_END:
        break;
    case PF_MSG_BYE:
        s_str(d, "reason", m->u.bye.reason, sizeof m->u.bye.reason);
        break;
    case PF_MSG_PHOTON_REQ:
        m->u.photon_req.scene_hash = s_u64(d, "scene_hash");
        m->u.photon_req.scene_size = s_u64(d, "scene_size");
        s_dec_settings(d, &m->u.photon_req.settings);
        m->u.photon_req.first = s_u32(d, "first");
        m->u.photon_req.count = s_u32(d, "count");
        break;
    case PF_MSG_IRR_REQ:
        m->u.irr_req.scene_hash = s_u64(d, "scene_hash");
        m->u.irr_req.scene_size = s_u64(d, "scene_size");
        m->u.irr_req.maps_hash = s_u64(d, "maps_hash");
        m->u.irr_req.maps_size = s_u64(d, "maps_size");
        s_dec_settings(d, &m->u.irr_req.settings);
        m->u.irr_req.first = s_u32(d, "first");
        m->u.irr_req.count = s_u32(d, "count");
        break;
    case PF_MSG_PHOTONS:
    case PF_MSG_IRR_POINTS:
        s_dec_photons(d, &m->u.photons);
        break;
    case PF_MSG_BLOB_PLAN:
        s_dec_plan(d, &m->u.plan);
        break;
    }
}

int pf_msg_decode(const uint8_t *frame, size_t len, pf_msg_t *msg, char *why, size_t why_len)
{
    memset(msg, 0, sizeof *msg);
    s_whyf(why, why_len, "%s", "");
    if (!frame || len < PF_PROTO_HEADER_SIZE) {
        s_whyf(why, why_len, "a frame of %zu bytes is shorter than the %d-byte message header", frame ? len : 0,
               PF_PROTO_HEADER_SIZE);
        return PF_EPARSE;
    }
    pf_rd_t r = pf_rd_make(frame, len);
    uint32_t magic = pf_rd_u32(&r);
    uint16_t version = pf_rd_u16(&r);
    uint16_t type = pf_rd_u16(&r);
    uint64_t job = pf_rd_u64(&r);
    if (magic != PF_PROTO_MAGIC) {
        s_whyf(why, why_len, "bad magic 0x%08" PRIx32 " (expected 0x%08x, \"PFRM\"): not a photonfarm message", magic,
               PF_PROTO_MAGIC);
        return PF_EPARSE;
    }
    if (version != PF_PROTO_VERSION) {
        s_whyf(why, why_len, "protocol version %u (peer) vs %u (this build)", (unsigned)version,
               (unsigned)PF_PROTO_VERSION);
        return PF_EMISMATCH;
    }
    if (type < 1 || type > PF_MSG_MAX_TYPE) {
        s_whyf(why, why_len, "unknown message type %u", (unsigned)type);
        return PF_EPARSE;
    }
    msg->type = (pf_msg_type)type;
    msg->job = job;

    s_dec_t d = { r, pf_msg_type_name(type), why, why_len, 0 };
    s_dec_body(&d, msg);
    if (!d.failed && d.r.left > 0)
        s_fail(&d, "%zu trailing bytes after the body", d.r.left);
    if (!d.failed) {
        char text[256];
        if (s_check(msg, text, sizeof text))
            s_fail(&d, "%s", text);
    }
    if (d.failed) {
        pf_msg_type t = msg->type;
        memset(msg, 0, sizeof *msg);
        msg->type = t;
        return PF_EPARSE;
    }
    return PF_OK;
}

uint16_t pf_msg_tile_count(const pf_msg_tile_t *t, uint32_t i)
{
    const uint8_t *q = t->counts_le + 2 * (size_t)i;
    return (uint16_t)(q[0] | q[1] << 8);
}

void pf_msg_result_pixels(const pf_msg_result_t *r, float *dst)
{
    size_t n = (size_t)r->w * r->h * 3;
    const uint8_t *p = r->rgb_le;
    for (size_t i = 0; i < n; i++, p += 4) {
        uint32_t u = (uint32_t)p[0] | (uint32_t)p[1] << 8 | (uint32_t)p[2] << 16 | (uint32_t)p[3] << 24;
        memcpy(&dst[i], &u, sizeof u);
    }
}

static uint32_t s_le32(const uint8_t *q)
{
    return (uint32_t)q[0] | (uint32_t)q[1] << 8 | (uint32_t)q[2] << 16 | (uint32_t)q[3] << 24;
}

void pf_msg_photon_get(const pf_msg_photons_t *p, uint32_t i, pf_msg_photon_t *out)
{
    const uint8_t *q = p->data + (size_t)i * PF_PROTO_PHOTON_BYTES;
    uint32_t u[8];
    for (int k = 0; k < 8; k++)
        u[k] = s_le32(q + 4 * k);
    memcpy(out->pos, u, sizeof out->pos);
    memcpy(out->power, u + 3, sizeof out->power);
    out->dir = u[6];
    out->normal = u[7];
}
