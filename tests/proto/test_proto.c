/* test_proto.c: the wire cursor and the message codecs (ctest `proto`).
 *
 * For every message type: an encode -> decode round trip equal in every field
 * (and re-encoding the decoded message gives the same bytes); every
 * truncation of a valid frame fails cleanly with a reason; targeted
 * corruptions (magic, version, type, each range rule, non-finite floats,
 * trailing bytes) fail with a reason naming the field; the encoder refuses
 * what the decoder would refuse. Then 10 000 random and mutated frames, each
 * either rejected or decoded into a message that re-encodes to exactly the
 * same bytes (the encoding is canonical, so a "valid by chance" frame is
 * really valid). Plus the byte order of the writers, the cursor's latching,
 * and the handshake fingerprint check. */
#include <math.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "base/wire.h"
#include "photon/mapfile.h"
#include "photon/photon.h"
#include "proto/hashtree.h"
#include "proto/messages.h"

#include "check.h"
#include "render/frame.h"



/* SplitMix64: the test only needs repeatability. */
static uint64_t s_state = 0x5eed;
static uint64_t s_next(void)
{
    uint64_t z = (s_state += 0x9e3779b97f4a7c15ULL);
    z = (z ^ (z >> 30)) * 0xbf58476d1ce4e5b9ULL;
    z = (z ^ (z >> 27)) * 0x94d049bb133111ebULL;
    return z ^ (z >> 31);
}

static void s_put32(uint8_t *p, uint32_t v)
{
    for (int i = 0; i < 4; i++)
        p[i] = (uint8_t)(v >> (8 * i));
}

static void s_put64(uint8_t *p, uint64_t v)
{
    for (int i = 0; i < 8; i++)
        p[i] = (uint8_t)(v >> (8 * i));
}

static uint32_t s_fbits(float f)
{
    uint32_t u;
    memcpy(&u, &f, sizeof u);
    return u;
}

/* ---- sample messages ---- */

static float s_pixels[3 * 2 * 3];
static uint8_t s_chunk_data[100];

static pf_msg_photon_t s_photons[3];
#include "irr_sample.h"
static uint64_t s_leaves[3];

static void s_sample(int type, pf_msg_t *m)
{
    memset(m, 0, sizeof *m);
    m->type = (pf_msg_type)type;
    m->job = 0x1122334455667788ULL + (uint64_t)type;
    switch (type) {
    case PF_MSG_HELLO:
        m->u.hello.fp = pf_frame_fingerprint();
        m->u.hello.threads = 8;
        snprintf(m->u.hello.name, sizeof m->u.hello.name, "render-07:4242");
        m->u.hello.peer_port = 40123;
        break;
    case PF_MSG_WELCOME:
        m->u.welcome.worker_id = 7;
        m->u.welcome.heartbeat_ms = 1000;
        break;
    case PF_MSG_REFUSE:
        snprintf(m->u.refuse.reason, sizeof m->u.refuse.reason, "incompatible builds: protocol version 2 (worker) vs 1");
        break;
    case PF_MSG_HEARTBEAT:
        m->u.heartbeat.progress = 0x0123456789abcdefULL;
        m->u.heartbeat.tiles_held = 3;
        break;
    case PF_MSG_JOB: {
        pf_msg_job_t *j = &m->u.job;
        j->scene_hash = 0xa1a2a3a4a5a6a7a8ULL;
        j->scene_size = 123456789;
        j->maps_hash = 0xb1b2b3b4b5b6b7b8ULL;
        j->maps_size = 0x1234567890ULL;
        j->settings = pf_settings_default();
        j->settings.width = 640;
        j->settings.height = 480;
        j->settings.photons = 0x100000001ULL;
        j->settings.caustic_photons = 77;
        j->settings.gather = 0;
        j->settings.gather_filter = 8;
        j->settings.light_samples = 3;
        j->settings.max_depth = 0;
        j->settings.photon_max_depth = 100000;
        j->settings.global_k = 1024;
        j->settings.caustic_k = 1;
        j->settings.caustic_radius = 0.25f;
        j->settings.global_radius = 1e-7f;
        j->settings.irradiance_stride = 5;
        j->settings.threads = 12;
        j->settings.seed = 0xfeedface12345678ULL;
        j->settings.exposure = -1.5f;
        j->terms = 15;
        j->tile_size = 32;
        break;
    }
    case PF_MSG_BLOB_REQ:
        m->u.blob_req.hash = 0xc0ffee0000c0ffeeULL;
        m->u.blob_req.offset = 3ull * PF_PROTO_CHUNK_SIZE;
        m->u.blob_req.credit = 8;
        break;
    case PF_MSG_BLOB_CHUNK:
        for (size_t i = 0; i < sizeof s_chunk_data; i++)
            s_chunk_data[i] = (uint8_t)(i * 37 + 11);
        m->u.chunk.hash = 0xdeadbeefcafef00dULL;
        m->u.chunk.total = 5000;
        m->u.chunk.offset = 1000;
        m->u.chunk.len = sizeof s_chunk_data;
        m->u.chunk.data = s_chunk_data;
        break;
    case PF_MSG_READY:
        m->u.ready.credit = 4;
        break;
    case PF_MSG_TILE:
        m->u.tile = (pf_msg_tile_t){ .tile = 17, .attempt = 2, .x0 = 64, .y0 = 32, .w = 32, .h = 16 };
        break;
    case PF_MSG_RESULT: {
        const float v[18] = { 0.0f, -0.0f, 1.0f, 0.5f, 1e30f, 1e-40f, 3.25f, 0.125f, 7.0f,
                              2.0f, 0.0f, 1e-3f, 100.0f, 6.5f, 0.75f, 9.0f, 1e-20f, 42.0f };
        memcpy(s_pixels, v, sizeof v);
        pf_msg_result_t *r = &m->u.result;
        r->tile = 17;
        r->attempt = 2;
        r->x0 = 64;
        r->y0 = 32;
        r->w = 3;
        r->h = 2;
        r->rgb = s_pixels;
        r->render_us = 12345;
        break;
    }
    case PF_MSG_JOB_END:
        break;
    case PF_MSG_BYE:
        snprintf(m->u.bye.reason, sizeof m->u.bye.reason, "shutting down");
        break;
    case PF_MSG_PHOTON_REQ:
        s_sample(PF_MSG_JOB, m); /* its settings */
        m->type = PF_MSG_PHOTON_REQ;
        m->u.photon_req.settings = m->u.job.settings;
        m->u.photon_req.scene_hash = 0x0123456789abcdefULL;
        m->u.photon_req.scene_size = 123456;
        m->u.photon_req.first = 40;
        m->u.photon_req.count = 3;
        break;
    case PF_MSG_PHOTONS:
        for (int i = 0; i < 3; i++)
            s_photons[i] = (pf_msg_photon_t){ { 1.0f + i, -2.0f, 1e-30f }, { 0.0f, 0.5f * i, 7.0f }, 0x7fff7fffu + i,
                                              0xffffffffu - i };
        m->u.photons = (pf_msg_photons_t){ 5, 900, 30, 2, 800, 3, NULL, s_photons };
        break;
    case PF_MSG_BLOB_PLAN: {
        pf_msg_blob_plan_t *p = &m->u.plan;
        for (int i = 0; i < 3; i++)
            s_leaves[i] = 0x0f0e0d0c0b0a0908ULL * (uint64_t)(i + 1);
        p->hash = 0x5555aaaa5555aaaaULL;
        p->size = 2 * PF_PROTO_CHUNK_SIZE + 77; /* three chunks */
        p->source_uid = 4;
        snprintf(p->source, sizeof p->source, "tcp://10.0.0.7:40123");
        p->n = 3;
        p->leaves = s_leaves;
        p->root = pf_chunk_root(p->hash, p->size, s_leaves, 3);
        break;
    }
    default: s_irr_sample(type, m, s_photons); break; /* irr_sample.h */
    }
}

/* The first field in which a and b differ, or NULL. a is the message as
 * built, b as decoded (RESULT pixels compared through pf_msg_result_pixels). */
static const char *s_diff(const pf_msg_t *a, const pf_msg_t *b)
{
    if (a->type != b->type)
        return "type";
    if (a->job != b->job)
        return "job";
    switch (a->type) {
    case PF_MSG_HELLO: {
        const pf_msg_hello_t *x = &a->u.hello, *y = &b->u.hello;
        if (x->fp.protocol != y->fp.protocol || x->fp.photon_size != y->fp.photon_size ||
            x->fp.float_size != y->fp.float_size || x->fp.map_version != y->fp.map_version)
            return "fingerprint";
        if (strcmp(x->fp.git, y->fp.git))
            return "fingerprint.git";
        if (x->threads != y->threads)
            return "threads";
        if (strcmp(x->name, y->name))
            return "name";
        if (x->peer_port != y->peer_port)
            return "peer_port";
        return NULL;
    }
    case PF_MSG_WELCOME:
        return a->u.welcome.worker_id != b->u.welcome.worker_id         ? "worker_id"
               : a->u.welcome.heartbeat_ms != b->u.welcome.heartbeat_ms ? "heartbeat_ms"
                                                                        : NULL;
    case PF_MSG_REFUSE:
        return strcmp(a->u.refuse.reason, b->u.refuse.reason) ? "reason" : NULL;
    case PF_MSG_HEARTBEAT:
        return a->u.heartbeat.progress != b->u.heartbeat.progress       ? "progress"
               : a->u.heartbeat.tiles_held != b->u.heartbeat.tiles_held ? "tiles_held"
                                                                        : NULL;
    case PF_MSG_JOB: {
        const pf_msg_job_t *x = &a->u.job, *y = &b->u.job;
        const pf_settings_t *s = &x->settings, *t = &y->settings;
        if (x->scene_hash != y->scene_hash || x->scene_size != y->scene_size)
            return "scene";
        if (x->maps_hash != y->maps_hash || x->maps_size != y->maps_size)
            return "maps";
        if (s->width != t->width || s->height != t->height || s->spp != t->spp)
            return "settings.size/spp";
        if (s->photons != t->photons || s->caustic_photons != t->caustic_photons)
            return "settings.photons";
        if (s->gather != t->gather || s->gather_filter != t->gather_filter || s->light_samples != t->light_samples)
            return "settings.gather/light_samples";
        if (s->max_depth != t->max_depth || s->photon_max_depth != t->photon_max_depth)
            return "settings.depths";
        if (s->global_k != t->global_k || s->caustic_k != t->caustic_k)
            return "settings.k";
        if (s_fbits(s->caustic_radius) != s_fbits(t->caustic_radius) ||
            s_fbits(s->global_radius) != s_fbits(t->global_radius))
            return "settings.radii";
        if (s->irradiance_stride != t->irradiance_stride || s->threads != t->threads)
            return "settings.stride/threads";
        if (s->seed != t->seed)
            return "settings.seed";
        if (s_fbits(s->exposure) != s_fbits(t->exposure))
            return "settings.exposure";
        if (x->terms != y->terms)
            return "terms";
        if (x->tile_size != y->tile_size)
            return "tile_size";
        return NULL;
    }
    case PF_MSG_BLOB_REQ:
        return a->u.blob_req.hash != b->u.blob_req.hash         ? "hash"
               : a->u.blob_req.offset != b->u.blob_req.offset   ? "offset"
               : a->u.blob_req.credit != b->u.blob_req.credit   ? "credit"
                                                                : NULL;
    case PF_MSG_BLOB_CHUNK: {
        const pf_msg_blob_chunk_t *x = &a->u.chunk, *y = &b->u.chunk;
        if (x->hash != y->hash || x->total != y->total || x->offset != y->offset || x->len != y->len)
            return "chunk header";
        if (x->len && (!y->data || memcmp(x->data, y->data, x->len)))
            return "chunk data";
        return NULL;
    }
    case PF_MSG_READY:
        return a->u.ready.credit != b->u.ready.credit ? "credit" : NULL;
    case PF_MSG_TILE:
        return memcmp(&a->u.tile, &b->u.tile, sizeof a->u.tile) ? "tile" : NULL;
    case PF_MSG_RESULT: {
        const pf_msg_result_t *x = &a->u.result, *y = &b->u.result;
        if (x->tile != y->tile || x->attempt != y->attempt || x->x0 != y->x0 || x->y0 != y->y0 || x->w != y->w ||
            x->h != y->h || x->render_us != y->render_us)
            return "result header";
        size_t n = (size_t)x->w * x->h * 3;
        float *px = malloc(n * sizeof *px);
        pf_msg_result_pixels(y, px);
        int same = memcmp(px, x->rgb, n * sizeof *px) == 0;
        free(px);
        return same ? NULL : "pixels";
    }
    case PF_MSG_JOB_END:
        return NULL;
    case PF_MSG_BYE:
        return strcmp(a->u.bye.reason, b->u.bye.reason) ? "reason" : NULL;
    case PF_MSG_PHOTON_REQ: {
        const pf_msg_photon_req_t *x = &a->u.photon_req, *y = &b->u.photon_req;
        if (x->scene_hash != y->scene_hash || x->scene_size != y->scene_size || x->first != y->first ||
            x->count != y->count)
            return "photon_req";
        return pf_settings_hash(&x->settings) != pf_settings_hash(&y->settings) ? "settings" : NULL;
    }
    case PF_MSG_PHOTONS: {
        const pf_msg_photons_t *x = &a->u.photons, *y = &b->u.photons;
        if (x->batch != y->batch || x->total != y->total || x->first != y->first || x->rejected != y->rejected ||
            x->indirect != y->indirect || x->n != y->n)
            return "photons header";
        for (uint32_t i = 0; i < x->n; i++) {
            pf_msg_photon_t q;
            pf_msg_photon_get(y, i, &q);
            if (memcmp(&q, &x->photons[i], sizeof q))
                return "photon";
        }
        return NULL;
    }
    case PF_MSG_BLOB_PLAN: {
        const pf_msg_blob_plan_t *x = &a->u.plan, *y = &b->u.plan;
        if (x->hash != y->hash || x->size != y->size || x->source_uid != y->source_uid || x->root != y->root ||
            x->n != y->n || strcmp(x->source, y->source))
            return "plan header";
        for (uint32_t k = 0; k < x->n; k++)
            if (pf_msg_plan_leaf(y, k) != x->leaves[k])
                return "plan leaf";
        return NULL;
    }
    default: return s_irr_diff(a, b);
    }
}

/* Re-encodes a decoded message (RESULT pixels through pf_msg_result_pixels). */
static int s_reencode(const pf_msg_t *m, pf_buf_t *out)
{
    if (m->type == PF_MSG_BLOB_PLAN) {
        pf_msg_t c = *m;
        uint64_t *l = malloc((m->u.plan.n + 1) * sizeof *l);
        for (uint32_t k = 0; k < m->u.plan.n; k++)
            l[k] = pf_msg_plan_leaf(&m->u.plan, k);
        c.u.plan.leaves = l;
        int rc = pf_msg_encode(&c, out);
        free(l);
        return rc;
    }
    if (m->type == PF_MSG_PHOTONS || m->type == PF_MSG_IRR_POINTS) {
        pf_msg_t c = *m;
        pf_msg_photon_t *q = malloc((m->u.photons.n + 1) * sizeof *q);
        for (uint32_t i = 0; i < m->u.photons.n; i++)
            pf_msg_photon_get(&m->u.photons, i, &q[i]);
        c.u.photons.photons = q;
        int rc = pf_msg_encode(&c, out);
        free(q);
        return rc;
    }
    if (m->type != PF_MSG_RESULT)
        return pf_msg_encode(m, out);
    pf_msg_t c = *m;
    size_t n = (size_t)m->u.result.w * m->u.result.h * 3;
    float *px = malloc((n ? n : 1) * sizeof *px);
    pf_msg_result_pixels(&m->u.result, px);
    c.u.result.rgb = px;
    int rc = pf_msg_encode(&c, out);
    free(px);
    return rc;
}

/* ---- tests ---- */

static void test_wire(void)
{
    pf_buf_t b = { 0 };
    CHECK(pf_wr_u8(&b, 0xab) == 0 && pf_wr_u16(&b, 0x1234) == 0 && pf_wr_u32(&b, 0x89abcdefu) == 0 &&
              pf_wr_u64(&b, 0x0102030405060708ULL) == 0 && pf_wr_f32(&b, 1.0f) == 0 && pf_wr_str(&b, "hi") == 0,
          "writers");
    const uint8_t want[] = { 0xab, 0x34, 0x12, 0xef, 0xcd, 0xab, 0x89, 8, 7, 6, 5, 4, 3, 2, 1,
                             0x00, 0x00, 0x80, 0x3f, 2, 0, 'h', 'i' };
    CHECK(b.len == sizeof want && memcmp(b.data, want, sizeof want) == 0, "little-endian layout (len %zu)", b.len);

    pf_rd_t r = pf_rd_make(b.data, b.len);
    char s[8];
    CHECK(pf_rd_u8(&r) == 0xab && pf_rd_u16(&r) == 0x1234 && pf_rd_u32(&r) == 0x89abcdefu &&
              pf_rd_u64(&r) == 0x0102030405060708ULL && pf_rd_f32(&r) == 1.0f,
          "readers");
    pf_rd_str(&r, s, sizeof s);
    CHECK(pf_rd_ok(&r) && strcmp(s, "hi") == 0 && r.left == 0, "string read back");
    CHECK(pf_rd_u8(&r) == 0 && !pf_rd_ok(&r), "a read past the end latches");
    r.err = 0;
    CHECK(pf_rd_bytes(&r, 1) == NULL && !pf_rd_ok(&r), "pf_rd_bytes past the end");

    /* The latch holds: after a failure even available bytes read as 0. */
    r = pf_rd_make(b.data, 3);
    CHECK(pf_rd_u32(&r) == 0 && !pf_rd_ok(&r) && pf_rd_u8(&r) == 0, "latched error");

    r = pf_rd_make("\x02\x00hi", 4);
    pf_rd_str(&r, s, 2);
    CHECK(!pf_rd_ok(&r) && s[0] == '\0', "a string too long for its destination fails");
    r = pf_rd_make("\x02\x00h\0", 4);
    pf_rd_str(&r, s, sizeof s);
    CHECK(!pf_rd_ok(&r), "a string holding a NUL fails");
    uint8_t longlen[2] = { (PF_PROTO_MAX_STRING + 1) & 0xff, (PF_PROTO_MAX_STRING + 1) >> 8 };
    char big[4096];
    r = pf_rd_make(longlen, 2);
    pf_rd_str(&r, big, sizeof big);
    CHECK(!pf_rd_ok(&r), "a string over PF_PROTO_MAX_STRING fails");

    const uint32_t bad[] = { 0x7fc00000u, 0x7f800000u, 0xff800000u, 0xffffffffu };
    for (size_t i = 0; i < sizeof bad / sizeof bad[0]; i++) {
        uint8_t fb[4];
        s_put32(fb, bad[i]);
        r = pf_rd_make(fb, 4);
        (void)pf_rd_f32(&r);
        CHECK(!pf_rd_ok(&r), "pf_rd_f32 of 0x%08x must latch", bad[i]);
    }

    memset(big, 'x', sizeof big);
    big[PF_PROTO_MAX_STRING + 1] = '\0';
    size_t before = b.len;
    CHECK(pf_wr_str(&b, big) == PF_EINVAL && b.len == before, "pf_wr_str refuses an over-long string");
    big[PF_PROTO_MAX_STRING] = '\0';
    CHECK(pf_wr_str(&b, big) == 0 && b.len == before + 2 + PF_PROTO_MAX_STRING, "a string at the limit");

    /* Growth from empty to a megabyte keeps every byte. */
    pf_buf_free(&b);
    CHECK(b.data == NULL && b.len == 0 && b.cap == 0, "pf_buf_free zeroes");
    int ok = 1;
    for (uint32_t i = 0; i < 300000; i++)
        ok &= pf_wr_u32(&b, i * 2654435761u) == 0;
    for (uint32_t i = 0; i < 300000 && ok; i++) {
        const uint8_t *p = b.data + 4 * i;
        uint32_t v = (uint32_t)p[0] | (uint32_t)p[1] << 8 | (uint32_t)p[2] << 16 | (uint32_t)p[3] << 24;
        ok &= v == i * 2654435761u;
    }
    CHECK(ok && b.len == 1200000, "growth keeps the bytes");
    pf_buf_free(&b);
    pf_buf_free(&b); /* twice is harmless */

    CHECK(strcmp(pf_msg_type_name(PF_MSG_HELLO), "HELLO") == 0 && strcmp(pf_msg_type_name(PF_MSG_BYE), "BYE") == 0 &&
              strcmp(pf_msg_type_name(0), "UNKNOWN") == 0 && strcmp(pf_msg_type_name(PF_MSG_MAX_TYPE + 1), "UNKNOWN") == 0 &&
              strcmp(pf_msg_type_name(-1), "UNKNOWN") == 0,
          "type names");
}

static void test_settings_group(void)
{
    pf_settings_t s = pf_settings_default();
    s.seed = 0x8000000000000001ULL;
    s.threads = 3;
    s.path_max_depth = -1;
    pf_buf_t b = { 0 };
    CHECK(pf_wr_settings(&b, &s) == 0 && b.len == 100, "settings group is 100 bytes (got %zu)", b.len);
    pf_rd_t r = pf_rd_make(b.data, b.len);
    pf_settings_t t;
    memset(&t, 0xee, sizeof t);
    pf_rd_settings(&r, &t);
    CHECK(pf_rd_ok(&r) && r.left == 0, "settings read back");
    CHECK(t.width == s.width && t.photons == s.photons && t.seed == s.seed && t.threads == s.threads &&
              t.exposure == s.exposure && t.irradiance_stride == s.irradiance_stride &&
              t.path_max_depth == -1,
          "settings equal");
    r = pf_rd_make(b.data, 79);
    pf_rd_settings(&r, &t);
    CHECK(!pf_rd_ok(&r), "a truncated settings group latches");
    char why[256];
    CHECK(pf_settings_check(&s, why, sizeof why) == 0, "defaults are valid: %s", why);
    s.spp = 0;
    CHECK(pf_settings_check(&s, why, sizeof why) == PF_EINVAL && strstr(why, "settings.spp"), "spp 0: %s", why);
    pf_buf_free(&b);
}

static void test_round_trips(void)
{
    for (int t = 1; t <= PF_MSG_MAX_TYPE; t++) {
        pf_msg_t m, d;
        s_sample(t, &m);
        pf_buf_t b = { 0 }, b2 = { 0 };
        char why[512];
        int rc = pf_msg_encode(&m, &b);
        CHECK(rc == 0, "%s: encode returned %d", pf_msg_type_name(t), rc);
        if (rc)
            continue;
        CHECK(b.len >= PF_PROTO_HEADER_SIZE && b.len <= PF_PROTO_MAX_MESSAGE, "%s: size %zu", pf_msg_type_name(t),
              b.len);
        rc = pf_msg_decode(b.data, b.len, &d, why, sizeof why);
        CHECK(rc == 0, "%s: decode returned %d: %s", pf_msg_type_name(t), rc, why);
        if (rc)
            continue;
        const char *diff = s_diff(&m, &d);
        CHECK(diff == NULL, "%s: round trip differs in %s", pf_msg_type_name(t), diff);
        CHECK(s_reencode(&d, &b2) == 0 && b2.len == b.len && memcmp(b.data, b2.data, b.len) == 0,
              "%s: re-encoding the decoded message gives other bytes", pf_msg_type_name(t));
        /* Encoding resets the buffer, so a reused buffer holds one message. */
        CHECK(pf_msg_encode(&m, &b2) == 0 && b2.len == b.len, "%s: encode into a used buffer", pf_msg_type_name(t));
        pf_buf_free(&b);
        pf_buf_free(&b2);
    }

    /* A RESULT at the largest tile, and a full chunk, fit the message limit. */
    pf_msg_t m, d;
    s_sample(PF_MSG_RESULT, &m);
    m.u.result.w = 256;
    m.u.result.h = 256;
    float *px = calloc(256 * 256 * 3, sizeof *px);
    for (size_t i = 0; i < 256 * 256 * 3; i++)
        px[i] = (float)i * 0.5f;
    m.u.result.rgb = px;
    pf_buf_t b = { 0 };
    char why[512];
    CHECK(pf_msg_encode(&m, &b) == 0 && b.len <= PF_PROTO_MAX_MESSAGE, "largest RESULT encodes (%zu)", b.len);
    CHECK(pf_msg_decode(b.data, b.len, &d, why, sizeof why) == 0 && s_diff(&m, &d) == NULL, "largest RESULT: %s",
          why);
    free(px);
    uint8_t *chunk = malloc(PF_PROTO_CHUNK_SIZE);
    memset(chunk, 0x5a, PF_PROTO_CHUNK_SIZE);
    s_sample(PF_MSG_BLOB_CHUNK, &m);
    m.u.chunk.total = 3ull * PF_PROTO_CHUNK_SIZE;
    m.u.chunk.offset = 2ull * PF_PROTO_CHUNK_SIZE;
    m.u.chunk.len = PF_PROTO_CHUNK_SIZE;
    m.u.chunk.data = chunk;
    CHECK(pf_msg_encode(&m, &b) == 0 && b.len <= PF_PROTO_MAX_MESSAGE, "full chunk encodes (%zu)", b.len);
    CHECK(pf_msg_decode(b.data, b.len, &d, why, sizeof why) == 0 && s_diff(&m, &d) == NULL, "full chunk: %s", why);
    CHECK(d.u.chunk.data == b.data + b.len - PF_PROTO_CHUNK_SIZE, "chunk data points into the frame");
    free(chunk);
    pf_buf_free(&b);
}

static void test_truncations(void)
{
    for (int t = 1; t <= PF_MSG_MAX_TYPE; t++) {
        pf_msg_t m, d;
        s_sample(t, &m);
        pf_buf_t b = { 0 };
        if (pf_msg_encode(&m, &b)) {
            CHECK(0, "%s: encode", pf_msg_type_name(t));
            continue;
        }
        int bad = 0;
        for (size_t len = 0; len < b.len; len++) {
            /* A copy of exactly len bytes, so reading past it is caught by
             * sanitizers, not hidden by the rest of the buffer. */
            uint8_t *copy = malloc(len ? len : 1);
            memcpy(copy, b.data, len);
            char why[512] = "unset";
            int rc = pf_msg_decode(copy, len, &d, why, sizeof why);
            if (rc != PF_EPARSE || why[0] == '\0' || strcmp(why, "unset") == 0) {
                if (bad++ < 3)
                    CHECK(0, "%s truncated to %zu of %zu bytes: rc %d, why '%s'", pf_msg_type_name(t), len, b.len, rc,
                          why);
            }
            /* Past the header, the reason names the message type. */
            if (len >= PF_PROTO_HEADER_SIZE && strncmp(why, pf_msg_type_name(t), strlen(pf_msg_type_name(t)))) {
                if (bad++ < 3)
                    CHECK(0, "%s truncated to %zu: reason '%s' does not name the type", pf_msg_type_name(t), len, why);
            }
            free(copy);
        }
        CHECK(bad == 0, "%s: %d bad truncations", pf_msg_type_name(t), bad);
        pf_buf_free(&b);
    }
    pf_msg_t d;
    char why[256];
    CHECK(pf_msg_decode(NULL, 0, &d, why, sizeof why) == PF_EPARSE, "NULL frame");
    CHECK(pf_msg_decode((const uint8_t *)"x", 1, &d, NULL, 0) == PF_EPARSE, "why may be NULL");
}

/* Decodes frame (len bytes) and expects rc with a reason containing needle. */
static void s_expect(const uint8_t *frame, size_t len, int want_rc, const char *needle, const char *what)
{
    pf_msg_t d;
    char why[512] = "";
    int rc = pf_msg_decode(frame, len, &d, why, sizeof why);
    CHECK(rc == want_rc && strstr(why, needle) != NULL, "%s: rc %d (want %d), why '%s' (want '%s')", what, rc,
          want_rc, why, needle);
}

/* Encodes the sample of type t, lets patch change the bytes, and expects
 * a decode failure naming needle. */
typedef struct s_patch {
    size_t off;   /* byte offset in the frame */
    int width;    /* 4 or 8 (or 2) */
    uint64_t value;
    const char *needle;
    int rc;       /* expected status (0 means PF_EPARSE) */
} s_patch_t;

static void s_patch_test(int t, const s_patch_t *p, size_t n)
{
    pf_msg_t m;
    s_sample(t, &m);
    pf_buf_t b = { 0 };
    if (pf_msg_encode(&m, &b)) {
        CHECK(0, "%s: encode", pf_msg_type_name(t));
        return;
    }
    for (size_t i = 0; i < n; i++) {
        uint8_t *copy = malloc(b.len);
        memcpy(copy, b.data, b.len);
        if (p[i].width == 8)
            s_put64(copy + p[i].off, p[i].value);
        else if (p[i].width == 4)
            s_put32(copy + p[i].off, (uint32_t)p[i].value);
        else {
            copy[p[i].off] = (uint8_t)p[i].value;
            copy[p[i].off + 1] = (uint8_t)(p[i].value >> 8);
        }
        char what[96];
        snprintf(what, sizeof what, "%s patched at %zu to 0x%llx", pf_msg_type_name(t), p[i].off,
                 (unsigned long long)p[i].value);
        s_expect(copy, b.len, p[i].rc ? p[i].rc : PF_EPARSE, p[i].needle, what);
        free(copy);
    }
    pf_buf_free(&b);
}

#define NPATCH(a) (sizeof(a) / sizeof((a)[0]))

/* Header corruptions, for every type: magic, version, type, a trailing byte. */
static void s_corrupt_headers(void)
{
    for (int t = 1; t <= PF_MSG_MAX_TYPE; t++) {
        pf_msg_t m;
        s_sample(t, &m);
        pf_buf_t b = { 0 };
        if (pf_msg_encode(&m, &b))
            continue;
        uint8_t *c = malloc(b.len + 1);
        memcpy(c, b.data, b.len);
        c[0] ^= 0x20;
        s_expect(c, b.len, PF_EPARSE, "magic", "bad magic");
        memcpy(c, b.data, b.len);
        c[4] = 9;
        char want[64];
        snprintf(want, sizeof want, "protocol version 9 (peer) vs %d", PF_PROTO_VERSION);
        s_expect(c, b.len, PF_EMISMATCH, want, "other version");
        c[4] = 0;
        s_expect(c, b.len, PF_EMISMATCH, "version 0", "version 0");
        /* A foreign version is reported even when the rest is garbage. */
        s_expect(c, PF_PROTO_HEADER_SIZE, PF_EMISMATCH, "version", "other version, header only");
        memcpy(c, b.data, b.len);
        const uint16_t types[] = { 0, PF_MSG_MAX_TYPE + 1, 0xffff };
        for (int k = 0; k < 3; k++) {
            c[6] = (uint8_t)types[k];
            c[7] = (uint8_t)(types[k] >> 8);
            s_expect(c, b.len, PF_EPARSE, "unknown message type", "unknown type");
        }
        memcpy(c, b.data, b.len);
        c[b.len] = 0;
        /* RESULT's pixels are the rest of the frame: one more byte is a pixel
         * count that does not fit the tile. */
        s_expect(c, b.len + 1, PF_EPARSE,
                 t == PF_MSG_RESULT    ? "bytes of pixels"
                 : t == PF_MSG_PHOTONS || t == PF_MSG_IRR_POINTS ? "bytes of photons"
                 : t == PF_MSG_BLOB_PLAN ? "bytes of chunk hashes"
                                         : "trailing",
                 "trailing byte");
        free(c);
        pf_buf_free(&b);
    }
}

/* The handshake: HELLO, WELCOME, REFUSE. */
static void s_corrupt_handshake(void)
{
    /* HELLO: fingerprint 16..23, git string at 24, threads, name. */
    pf_fingerprint_t fp = pf_frame_fingerprint();
    size_t th = 24 + 2 + strlen(fp.git), nm = th + 4;
    const s_patch_t hello[] = {
        { th, 4, 0, "threads 0 is out of range 1..4096", 0 },
        { th, 4, 4097, "threads", 0 },
        { th, 4, 0xffffffffu, "threads", 0 },
        { 24, 2, 48, "fingerprint.git is 48 bytes; at most 47 fit", 0 },
        { 24, 2, 2000, "over the limit", 0 },
        { nm, 2, 256, "name is 256 bytes", 0 },
        { nm, 2, 255, "ends inside name", 0 },
        { nm + 2, 1, 0, "NUL", 0 },
    };
    s_patch_test(PF_MSG_HELLO, hello, NPATCH(hello));

    const s_patch_t welcome[] = {
        { 20, 4, 0, "heartbeat_ms 0", 0 },
        { 20, 4, 60001, "heartbeat_ms", 0 },
    };
    s_patch_test(PF_MSG_WELCOME, welcome, NPATCH(welcome));

    const s_patch_t refuse[] = {
        { 16, 2, 512, "reason is 512 bytes; at most 511 fit", 0 },
        { 16, 2, 1025, "over the limit", 0 },
        { 16, 2, 0xffff, "reason", 0 },
    };
    s_patch_test(PF_MSG_REFUSE, refuse, NPATCH(refuse));
}

/* JOB: the settings' ranges and non-finite floats, terms, the tile size. */
static void s_corrupt_job(void)
{
    /* JOB: four u64 then the settings at 48 (layout in messages.c), pass at
     * 132, the pixel filter at 136 and 140, path_max_depth at 144, terms at
     * 148, tile_size at 152. */
    const s_patch_t job[] = {
        { 48, 4, 0, "settings.width 0", 0 },
        { 48, 4, 65537, "settings.width", 0 },
        { 48, 4, 0xffffffffu, "settings.width -1", 0 },
        { 52, 4, 0, "settings.height", 0 },
        { 56, 4, 0, "settings.spp", 0 },
        { 76, 4, 0xffffffffu, "settings.gather -1", 0 },
        { 80, 4, 9, "settings.gather_filter 9 is out of range 0..8", 0 },
        { 84, 4, 0, "settings.light_samples", 0 },
        { 88, 4, 100001, "settings.max_depth", 0 },
        { 88, 4, 0x80000000u, "settings.max_depth", 0 },
        { 92, 4, 100001, "settings.photon_max_depth", 0 },
        { 96, 4, 0, "settings.global_k", 0 },
        { 96, 4, 1025, "settings.global_k", 0 },
        { 100, 4, 0, "settings.caustic_k", 0 },
        { 100, 4, 1025, "settings.caustic_k", 0 },
        { 136, 4, 0x40a00000u, "settings.filter_box 5 and filter_tent 0", 0 },
        { 140, 4, 0xbf800000u, "settings.filter_box 1 and filter_tent -1", 0 },
        { 136, 4, 0, "settings.filter_box 0 and filter_tent 0 must lie", 0 },
        { 104, 4, 0x7fc00000u, "settings.caustic_radius is not a finite number", 0 },
        { 104, 4, 0xbf800000u, "settings.caustic_radius -1 must be finite and >= 0", 0 },
        { 108, 4, 0x7f800000u, "settings.global_radius", 0 },
        { 108, 4, 0xbf800000u, "settings.global_radius", 0 },
        { 112, 4, 0, "settings.irradiance_stride", 0 },
        { 116, 4, 0xffffffffu, "settings.threads", 0 },
        { 128, 4, 0xff800000u, "settings.exposure", 0 },
        { 132, 4, 0xffffffffu, "settings.pass -1", 0 },
        { 132, 4, PF_MAX_PASSES, "settings.pass", 0 },
        { 144, 4, 0xfffffffeu, "settings.path_max_depth -2 is out of range", 0 },
        { 144, 4, 100001, "settings.path_max_depth", 0 },
        { 148, 4, 0, "terms 0", 0 },
        { 148, 4, 32, "terms 32", 0 },
        { 152, 4, 0, "tile_size 0", 0 },
        { 152, 4, 257, "tile_size", 0 },
    };
    s_patch_test(PF_MSG_JOB, job, NPATCH(job));
}

/* The blob transfer: BLOB_REQ, BLOB_CHUNK, READY. */
static void s_corrupt_transfer(void)
{
    const s_patch_t req[] = {
        { 24, 8, 5, "offset 5 is not a multiple", 0 },
        { 32, 4, 0, "credit 0", 0 },
        { 32, 4, 65, "credit 65", 0 },
    };
    s_patch_test(PF_MSG_BLOB_REQ, req, NPATCH(req));

    /* BLOB_CHUNK: hash 16, total 24, offset 32, len 40, data 44. */
    const s_patch_t chunk[] = {
        { 40, 4, PF_PROTO_CHUNK_SIZE + 1, "over the chunk size", 0 },
        { 40, 4, 101, "ends inside data", 0 },
        { 40, 4, 99, "trailing", 0 },
        { 24, 8, 1099, "runs past total", 0 },
        { 24, 8, 0, "runs past total", 0 },
        { 32, 8, UINT64_MAX - 10, "runs past total", 0 },
    };
    s_patch_test(PF_MSG_BLOB_CHUNK, chunk, NPATCH(chunk));
    {
        /* offset + len overflowing 64 bits must not wrap into range. */
        pf_msg_t m;
        s_sample(PF_MSG_BLOB_CHUNK, &m);
        pf_buf_t b = { 0 };
        pf_msg_encode(&m, &b);
        s_put64(b.data + 24, UINT64_MAX);
        s_put64(b.data + 32, UINT64_MAX - 50);
        s_expect(b.data, b.len, PF_EPARSE, "runs past total", "offset + len wraps");
        pf_buf_free(&b);
    }

    const s_patch_t ready[] = {
        { 16, 4, 0, "credit 0", 0 },
        { 16, 4, 1025, "credit 1025", 0 },
    };
    s_patch_test(PF_MSG_READY, ready, NPATCH(ready));
}

/* The tiles and the goodbye: TILE, RESULT, BYE. */
static void s_corrupt_tiles(void)
{
    /* TILE and RESULT: tile 16, attempt 20, x0 24, y0 28, w 32, h 36. */
    const s_patch_t tile[] = {
        { 32, 4, 0, "w 0", 0 },
        { 36, 4, 0, "h 0", 0 },
        { 32, 4, 65537, "w 65537", 0 },
        { 32, 4, 4097, "over the limit", 0 }, /* 4097 x 16 pixels */
        { 24, 4, 0xffffffe1u, "runs past", 0 },
        { 28, 4, 0xfffffff1u, "runs past", 0 },
    };
    s_patch_test(PF_MSG_TILE, tile, NPATCH(tile));

    const s_patch_t result[] = {
        { 32, 4, 0, "w 0", 0 },
        { 32, 4, 4, "bytes of pixels for a 4x2 tile", 0 },
        { 36, 4, 1, "72 bytes of pixels for a 3x1 tile", 0 },
        { 32, 4, 0x10000, "over the limit", 0 },
        { 24, 4, 0xfffffffeu, "runs past", 0 },
        { 44 + 4 * 5, 4, 0x7fc00000u, "pixel 1 channel 2", 0 },
        { 44 + 4 * 17, 4, 0x7f800000u, "pixel 5 channel 2", 0 },
        { 44, 4, 0xbf800000u, "finite and >= 0", 0 },
        { 44, 4, 0x80000001u, "finite and >= 0", 0 }, /* the smallest negative denormal */
    };
    s_patch_test(PF_MSG_RESULT, result, NPATCH(result));

    const s_patch_t bye[] = {
        { 16, 2, 256, "reason is 256 bytes", 0 },
        { 16, 2, 14, "ends inside reason", 0 },
        { 16, 2, 12, "trailing", 0 },
    };
    s_patch_test(PF_MSG_BYE, bye, NPATCH(bye));
}

/* Targeted corruptions: each fails with a reason naming the field. */
static void test_corruptions(void)
{
    s_corrupt_headers();
    s_corrupt_handshake();
    s_corrupt_job();
    s_corrupt_transfer();
    s_corrupt_tiles();
}

/* The encoder refuses what the decoder would refuse. */
static void test_encoder_refuses(void)
{
    pf_buf_t b = { 0 };
    pf_msg_t m;
    s_sample(PF_MSG_HELLO, &m);
    m.u.hello.threads = 0;
    CHECK(pf_msg_encode(&m, &b) == PF_EINVAL && b.len == 0, "HELLO threads 0");
    s_sample(PF_MSG_HELLO, &m);
    memset(m.u.hello.name, 'n', sizeof m.u.hello.name);
    CHECK(pf_msg_encode(&m, &b) == PF_EINVAL, "HELLO name without NUL");
    s_sample(PF_MSG_JOB, &m);
    m.u.job.settings.global_k = 0;
    CHECK(pf_msg_encode(&m, &b) == PF_EINVAL, "JOB global_k 0");
    s_sample(PF_MSG_JOB, &m);
    m.u.job.settings.exposure = NAN;
    CHECK(pf_msg_encode(&m, &b) == PF_EINVAL, "JOB exposure NaN");
    s_sample(PF_MSG_RESULT, &m);
    float px[18];
    memcpy(px, s_pixels, sizeof px);
    px[7] = NAN;
    m.u.result.rgb = px;
    CHECK(pf_msg_encode(&m, &b) == PF_EINVAL, "RESULT NaN pixel");
    px[7] = -1.0f;
    CHECK(pf_msg_encode(&m, &b) == PF_EINVAL, "RESULT negative pixel");
    m.u.result.rgb = NULL;
    CHECK(pf_msg_encode(&m, &b) == PF_EINVAL, "RESULT without pixels");
    s_sample(PF_MSG_BLOB_CHUNK, &m);
    m.u.chunk.offset = 4950;
    CHECK(pf_msg_encode(&m, &b) == PF_EINVAL, "BLOB_CHUNK past total");
    s_sample(PF_MSG_BLOB_REQ, &m);
    m.u.blob_req.offset = 1;
    CHECK(pf_msg_encode(&m, &b) == PF_EINVAL, "BLOB_REQ unaligned offset");
    s_sample(PF_MSG_TILE, &m);
    m.u.tile.w = 0;
    CHECK(pf_msg_encode(&m, &b) == PF_EINVAL, "TILE w 0");
    s_sample(PF_MSG_HELLO, &m);
    m.type = (pf_msg_type)99;
    CHECK(pf_msg_encode(&m, &b) == PF_EINVAL, "unknown type");
    pf_buf_free(&b);
}

/* Random frames and mutations of valid ones: no crash, and whatever decodes
 * must re-encode to exactly the frame (so it really was a valid message). */
static void test_fuzz(void)
{
    pf_buf_t valid[PF_MSG_MAX_TYPE + 1];
    memset(valid, 0, sizeof valid);
    for (int t = 1; t <= PF_MSG_MAX_TYPE; t++) {
        pf_msg_t m;
        s_sample(t, &m);
        pf_msg_encode(&m, &valid[t]);
    }
    int accepted = 0, noncanonical = 0, badrc = 0;
    pf_buf_t re = { 0 };
    for (int iter = 0; iter < 10000; iter++) {
        uint8_t frame[1024];
        size_t len;
        int kind = (int)(s_next() % 4);
        if (kind == 0) {
            /* Pure noise. */
            len = (size_t)(s_next() % 200);
            for (size_t i = 0; i < len; i++)
                frame[i] = (uint8_t)s_next();
        } else if (kind == 1) {
            /* A valid header of a random type, then noise. */
            len = PF_PROTO_HEADER_SIZE + (size_t)(s_next() % 160);
            for (size_t i = 0; i < len; i++)
                frame[i] = (uint8_t)s_next();
            s_put32(frame, PF_PROTO_MAGIC);
            frame[4] = PF_PROTO_VERSION;
            frame[5] = 0;
            frame[6] = (uint8_t)(1 + s_next() % PF_MSG_MAX_TYPE);
            frame[7] = 0;
        } else {
            /* A valid frame with a few bytes changed, and sometimes cut or
             * extended. */
            const pf_buf_t *v = &valid[1 + s_next() % PF_MSG_MAX_TYPE];
            len = v->len;
            memcpy(frame, v->data, len);
            int flips = 1 + (int)(s_next() % 4);
            for (int f = 0; f < flips; f++) {
                size_t at = PF_PROTO_HEADER_SIZE + (size_t)(s_next() % (len - PF_PROTO_HEADER_SIZE + 1));
                if (at < len)
                    frame[at] = kind == 2 ? (uint8_t)s_next() : (uint8_t)(frame[at] ^ (1u << (s_next() % 8)));
            }
            if (s_next() % 4 == 0) {
                size_t nl = (size_t)(s_next() % (len + 8));
                for (size_t i = len; i < nl; i++)
                    frame[i] = (uint8_t)s_next();
                len = nl;
            }
        }
        uint8_t *copy = malloc(len ? len : 1);
        memcpy(copy, frame, len);
        pf_msg_t d;
        char why[512];
        int rc = pf_msg_decode(copy, len, &d, why, sizeof why);
        if (rc == 0) {
            accepted++;
            if (s_reencode(&d, &re) != 0 || re.len != len || memcmp(re.data, copy, len) != 0)
                noncanonical++;
        } else if ((rc != PF_EPARSE && rc != PF_EMISMATCH) || why[0] == '\0') {
            badrc++;
        }
        free(copy);
    }
    CHECK(noncanonical == 0, "%d accepted frames do not re-encode to themselves", noncanonical);
    CHECK(badrc == 0, "%d rejections without PF_EPARSE/PF_EMISMATCH and a reason", badrc);
    /* Some mutations hit fields without rules (ids, hashes, pixel values),
     * so a share of frames is valid; the check above says they truly are. */
    CHECK(accepted > 100 && accepted < 6000, "accepted %d of 10000", accepted);
    printf("fuzz: %d of 10000 frames decoded (all canonical)\n", accepted);
    pf_buf_free(&re);
    for (int t = 1; t <= PF_MSG_MAX_TYPE; t++)
        pf_buf_free(&valid[t]);
}

static void test_fingerprint(void)
{
    pf_fingerprint_t self = pf_frame_fingerprint();
    CHECK(self.protocol == PF_PROTO_VERSION && self.photon_size == sizeof(pf_photon_t) &&
              self.float_size == sizeof(float) && self.map_version == PF_MAPFILE_VERSION,
          "self fingerprint %u/%u/%u/%u", self.protocol, self.photon_size, self.float_size, self.map_version);
    CHECK(strcmp(self.git, PF_GIT_HASH) == 0 && self.git[0], "git '%s'", self.git);

    char why[512] = "unset";
    CHECK(pf_fingerprint_check(&self, &self, why, sizeof why) == 0 && why[0] == '\0', "self vs self: '%s'", why);
    pf_fingerprint_t w = self;
    snprintf(w.git, sizeof w.git, "0123456789ab");
    snprintf(why, sizeof why, "unset");
    CHECK(pf_fingerprint_check(&w, &self, why, sizeof why) == 0 && why[0] == '\0', "git differs: '%s'", why);

    w = self;
    w.protocol = 9;
    char want[64];
    snprintf(want, sizeof want, "protocol version 9 (worker) vs %d (coordinator)", PF_PROTO_VERSION);
    CHECK(pf_fingerprint_check(&w, &self, why, sizeof why) == PF_EMISMATCH && strstr(why, want),
          "protocol: '%s'", why);
    w = self;
    w.photon_size = 40;
    CHECK(pf_fingerprint_check(&w, &self, why, sizeof why) == PF_EMISMATCH &&
              strstr(why, "photon record of 40 bytes (worker) vs 32 bytes (coordinator)"),
          "photon size: '%s'", why);
    w = self;
    w.float_size = 8;
    CHECK(pf_fingerprint_check(&w, &self, why, sizeof why) == PF_EMISMATCH &&
              strstr(why, "float of 8 bytes (worker) vs 4 bytes (coordinator)"),
          "float size: '%s'", why);
    w = self;
    w.map_version = 9;
    char vwant[96];
    snprintf(vwant, sizeof vwant, "photon-map format version 9 (worker) vs %u (coordinator)",
             (unsigned)PF_MAPFILE_VERSION);
    CHECK(pf_fingerprint_check(&w, &self, why, sizeof why) == PF_EMISMATCH && strstr(why, vwant),
          "map version: '%s'", why);
    /* Both directions: the coordinator's values are named as such. */
    snprintf(vwant, sizeof vwant, "version %u (worker) vs 9 (coordinator)", (unsigned)PF_MAPFILE_VERSION);
    CHECK(pf_fingerprint_check(&self, &w, why, sizeof why) == PF_EMISMATCH && strstr(why, vwant),
          "reversed: '%s'", why);
    w.protocol = PF_PROTO_VERSION + 1;
    w.photon_size = 16;
    CHECK(pf_fingerprint_check(&w, &self, why, sizeof why) == PF_EMISMATCH && strstr(why, "protocol") &&
              strstr(why, "photon record") && strstr(why, "photon-map"),
          "every difference is named: '%s'", why);
    CHECK(pf_fingerprint_check(&w, &self, NULL, 0) == PF_EMISMATCH, "why may be NULL");
    char tiny[8];
    CHECK(pf_fingerprint_check(&w, &self, tiny, sizeof tiny) == PF_EMISMATCH && strlen(tiny) < sizeof tiny,
          "a short why buffer is truncated safely");
}

int main(void)
{
    test_wire();
    test_settings_group();
    test_round_trips();
    test_truncations();
    test_corruptions();
    test_encoder_refuses();
    test_fuzz();
    test_fingerprint();
    printf("%d passed, %d failed\n", s_passed, s_failed);
    return s_failed ? 1 : 0;
}
