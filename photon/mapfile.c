/* mapfile.c: the photon maps (global, caustic, precomputed irradiance) as one
 * blob, the layout given in mapfile.h. The coordinator writes it once per
 * render; every worker reads it and must be able to trust the result, since
 * the kd-tree queries index arrays by what the blob says. So the reader checks
 * the header, sizes every array from the header's counts against the bytes
 * actually there before allocating, compares a content hash, checks every
 * photon and its split axis, and leaves the kd ordering to pf_kdtree_from_layout.
 *
 * The content hash covers the header fields before it as well as the body
 * (pf_hash_bytes over header bytes 0..179, continued over the body), so a
 * flipped emitted count or radius that is still in range is caught too.
 *
 * An empty map (count 0) is legal: a scene without mirror or glass has an
 * empty caustic tree. Its bounds, +inf..-inf in the tree, travel as zeros.
 *
 * Owns nothing past a call; the trees it returns belong to the caller's
 * pf_photon_maps_t. Reentrant. */
#include "photon/mapfile.h"

#include <inttypes.h>
#include <math.h>
#include <stdarg.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "base/hash.h"
#include "base/wire.h"

#define S_WHERE "photon-map blob"
#define S_MAPS 4                          /* global, caustic, irradiance, deep irradiance */
#define S_HASH_OFFSET 180                 /* the content hash's place in the header */
#define S_HEADER (S_HASH_OFFSET + 8)      /* 188 bytes */
#define S_RECORD 32                       /* a photon on the wire, its split axis included */
#define S_MAX_COUNT (((uint64_t)1 << 31) - 1) /* the kd-tree's limit */

static const char *const s_map_names[S_MAPS] = { "global", "caustic", "irradiance", "deep irradiance" };

/* ---- settings hash ---- */

static size_t s_put_u64(uint8_t *p, uint64_t v)
{
    for (int i = 0; i < 8; i++)
        p[i] = (uint8_t)(v >> (8 * i));
    return 8;
}

static size_t s_put_u32(uint8_t *p, uint32_t v)
{
    for (int i = 0; i < 4; i++)
        p[i] = (uint8_t)(v >> (8 * i));
    return 4;
}

static size_t s_put_f32(uint8_t *p, float f)
{
    f += 0.0f; /* -0 and +0 mean the same radius ("automatic") */
    uint32_t u;
    memcpy(&u, &f, sizeof u);
    return s_put_u32(p, u);
}

uint64_t pf_settings_hash(const pf_settings_t *s)
{
    /* Field by field in a fixed byte order, never the struct's bytes: its
     * padding is unspecified and the other settings do not change the maps. */
    uint8_t buf[64];
    size_t n = 0;
    n += s_put_u64(buf + n, s->photons);
    n += s_put_u64(buf + n, s->caustic_photons);
    n += s_put_u32(buf + n, (uint32_t)(int32_t)s->photon_max_depth);
    n += s_put_u32(buf + n, (uint32_t)(int32_t)s->global_k);
    n += s_put_u32(buf + n, (uint32_t)(int32_t)s->caustic_k);
    n += s_put_f32(buf + n, s->caustic_radius);
    n += s_put_f32(buf + n, s->global_radius);
    n += s_put_u32(buf + n, (uint32_t)(int32_t)s->irradiance_stride);
    n += s_put_u64(buf + n, s->seed);
    n += s_put_u32(buf + n, (uint32_t)(int32_t)s->pass);
    n += s_put_u32(buf + n, (uint32_t)(int32_t)s->path_max_depth); /* the precomputed irradiance's bounce limit */
    return pf_hash_bytes(PF_HASH_INIT, buf, n);
}

/* ---- writing ---- */

#define W(call)          \
    do {                 \
        if (rc == 0)     \
            rc = (call); \
    } while (0)

int pf_mapfile_write(const pf_photon_maps_t *maps, uint64_t scene_hash, uint64_t settings_hash, pf_buf_t *out)
{
    out->len = 0;
    const pf_kdtree_t *trees[S_MAPS] = { maps->global, maps->caustic, maps->irradiance, maps->irradiance_deep };
    size_t total = S_HEADER;
    for (int m = 0; m < S_MAPS; m++) {
        size_t n = trees[m] ? pf_kdtree_size(trees[m]) : 0;
        if (n > (SIZE_MAX - total) / S_RECORD)
            return PF_ENOMEM;
        total += n * S_RECORD;
    }
    int rc = pf_buf_reserve(out, total);
    W(pf_wr_u32(out, PF_MAPFILE_MAGIC));
    W(pf_wr_u16(out, PF_MAPFILE_VERSION));
    W(pf_wr_u16(out, S_RECORD));
    W(pf_wr_u64(out, scene_hash));
    W(pf_wr_u64(out, settings_hash));
    W(pf_wr_u64(out, maps->global_emitted));
    W(pf_wr_u64(out, maps->caustic_emitted));
    W(pf_wr_f32(out, maps->global_r2));
    W(pf_wr_f32(out, maps->caustic_r2));
    W(pf_wr_f32(out, maps->irradiance_r2));
    for (int m = 0; m < S_MAPS; m++) {
        /* A missing tree is written as an empty one. */
        size_t n = trees[m] ? pf_kdtree_size(trees[m]) : 0;
        pf_vec3 lo = pf_v3s(0.0f), hi = pf_v3s(0.0f);
        if (n > 0)
            pf_kdtree_bounds(trees[m], &lo, &hi);
        W(pf_wr_u64(out, n));
        W(pf_wr_f32(out, lo.x));
        W(pf_wr_f32(out, lo.y));
        W(pf_wr_f32(out, lo.z));
        W(pf_wr_f32(out, hi.x));
        W(pf_wr_f32(out, hi.y));
        W(pf_wr_f32(out, hi.z));
    }
    W(pf_wr_u64(out, 0)); /* the content hash, filled in below */
    /* The records, packed into space taken once per map (a call per field
     * made the 32 MB blob of a million photons take 0.3 s). */
    for (int m = 0; m < S_MAPS && rc == 0; m++) {
        size_t n = trees[m] ? pf_kdtree_size(trees[m]) : 0;
        const pf_photon_t *ph = n ? pf_kdtree_photons(trees[m]) : NULL;
        uint8_t *q = n ? (n <= SIZE_MAX / S_RECORD ? pf_wr_space(out, n * S_RECORD) : NULL) : out->data;
        if (!q) {
            rc = PF_ENOMEM;
            break;
        }
        for (size_t i = 0; i < n; i++) {
            uint8_t *r = q + i * S_RECORD;
            for (int k = 0; k < 3; k++) {
                uint32_t u;
                memcpy(&u, &ph[i].pos[k], sizeof u);
                s_put_u32(r + 4 * k, u);
                memcpy(&u, &ph[i].power[k], sizeof u);
                s_put_u32(r + 12 + 4 * k, u);
            }
            s_put_u32(r + 24, ph[i].dir);
            s_put_u32(r + 28, ph[i].normal);
        }
    }
    if (rc != 0) {
        out->len = 0;
        return rc;
    }
    uint64_t h = pf_hash_bytes(PF_HASH_INIT, out->data, S_HASH_OFFSET);
    h = pf_hash_bytes(h, out->data + S_HEADER, out->len - S_HEADER);
    s_put_u64(out->data + S_HASH_OFFSET, h);
    return PF_OK;
}

#undef W

/* ---- reading ---- */

static int s_fail(pf_error_t *err, int status, const char *fmt, ...) __attribute__((format(printf, 3, 4)));
static int s_fail(pf_error_t *err, int status, const char *fmt, ...)
{
    char text[sizeof err->msg];
    va_list ap;
    va_start(ap, fmt);
    vsnprintf(text, sizeof text, fmt, ap);
    va_end(ap);
    return pf_error_set(err, status, S_WHERE, 0, "%s", text);
}

static float s_f32_at(const uint8_t *p)
{
    uint32_t u = (uint32_t)p[0] | (uint32_t)p[1] << 8 | (uint32_t)p[2] << 16 | (uint32_t)p[3] << 24;
    float f;
    memcpy(&f, &u, sizeof f);
    return f;
}

static uint32_t s_u32_at(const uint8_t *p)
{
    return (uint32_t)p[0] | (uint32_t)p[1] << 8 | (uint32_t)p[2] << 16 | (uint32_t)p[3] << 24;
}

/* A header float without pf_rd_f32's finiteness latch, so that the check
 * that follows can say which field was not finite. */
static float s_rd_raw_f32(pf_rd_t *r)
{
    uint32_t u = pf_rd_u32(r);
    float f;
    memcpy(&f, &u, sizeof f);
    return f;
}

/* One map's header entry. */
typedef struct s_entry {
    uint64_t count;
    float lo[3], hi[3];
} s_entry_t;

/* Reads map m's photons from body (already checked to hold them),
 * validates each, and rebuilds the tree into *tree. */
static int s_read_map(int m, const s_entry_t *e, const uint8_t *body, pf_kdtree_t **tree, pf_error_t *err)
{
    const char *name = s_map_names[m];
    size_t n = (size_t)e->count;
    pf_photon_t *ph = malloc((n ? n : 1) * sizeof *ph);
    if (!ph)
        return s_fail(err, PF_ENOMEM, "out of memory for the %s map's %zu photons", name, n);
    int rc = PF_OK;
    for (size_t i = 0; i < n && rc == PF_OK; i++) {
        const uint8_t *p = body + i * S_RECORD;
        for (int k = 0; k < 3; k++) {
            ph[i].pos[k] = s_f32_at(p + 4 * k);
            ph[i].power[k] = s_f32_at(p + 12 + 4 * k);
        }
        ph[i].dir = s_u32_at(p + 24);
        ph[i].normal = s_u32_at(p + 28);
        for (int k = 0; k < 3 && rc == PF_OK; k++) {
            float x = ph[i].pos[k];
            if (!isfinite(x))
                rc = s_fail(err, PF_EPARSE, "%s photon %zu: position %c is not finite", name, i, "xyz"[k]);
            else if (!(x >= e->lo[k] && x <= e->hi[k]))
                rc = s_fail(err, PF_EPARSE, "%s photon %zu: position %c %g is outside the stated bounds [%g, %g]",
                            name, i, "xyz"[k], (double)x, (double)e->lo[k], (double)e->hi[k]);
            else if (!isfinite(ph[i].power[k]) || !(ph[i].power[k] >= 0.0f))
                rc = s_fail(err, PF_EPARSE, "%s photon %zu: power %c %g must be finite and >= 0", name, i, "rgb"[k],
                            (double)ph[i].power[k]);
        }
        if (rc == PF_OK && pf_photon_axis(&ph[i]) > 2)
            rc = s_fail(err, PF_EPARSE, "%s photon %zu: split axis %u is not 0, 1 or 2", name, i,
                        pf_photon_axis(&ph[i]));
    }
    if (rc != PF_OK) {
        free(ph);
        return rc;
    }
    /* Takes the array, also on failure. Positions and axes were checked
     * above, so a refusal here is the kd ordering itself (or, barely
     * possible, the tree's own few bytes of memory). */
    *tree = pf_kdtree_from_layout(&ph, n);
    if (!*tree)
        return s_fail(err, PF_EPARSE, "the %s map's photons are not in kd-tree order", name);
    return PF_OK;
}

int pf_mapfile_read(const uint8_t *data, size_t len, uint64_t expect_scene, uint64_t expect_settings,
                    pf_photon_maps_t *maps, pf_error_t *err)
{
    memset(maps, 0, sizeof *maps);
    if (!data || len < S_HEADER)
        return s_fail(err, PF_EPARSE, "%zu bytes, shorter than the %d-byte header", data ? len : 0, S_HEADER);
    pf_rd_t r = pf_rd_make(data, len);
    uint32_t magic = pf_rd_u32(&r);
    uint16_t version = pf_rd_u16(&r);
    uint16_t record = pf_rd_u16(&r);
    uint64_t scene_hash = pf_rd_u64(&r);
    uint64_t settings_hash = pf_rd_u64(&r);
    if (magic != PF_MAPFILE_MAGIC)
        return s_fail(err, PF_EPARSE, "bad magic 0x%08" PRIx32 " (expected 0x%08x, \"FMAP\"): not a photon-map blob",
                      magic, PF_MAPFILE_MAGIC);
    if (version != PF_MAPFILE_VERSION)
        return s_fail(err, PF_EMISMATCH, "format version %u, this build reads %u", (unsigned)version,
                      (unsigned)PF_MAPFILE_VERSION);
    if (record != S_RECORD)
        return s_fail(err, PF_EMISMATCH, "photon record size %u bytes, this build uses %u", (unsigned)record,
                      (unsigned)S_RECORD);
    if (expect_scene && scene_hash != expect_scene)
        return s_fail(err, PF_EMISMATCH, "scene hash %016" PRIx64 " is not the job's %016" PRIx64
                      ": the maps were traced for another scene", scene_hash, expect_scene);
    if (expect_settings && settings_hash != expect_settings)
        return s_fail(err, PF_EMISMATCH, "settings hash %016" PRIx64 " is not the job's %016" PRIx64
                      ": the maps were traced with other photon settings", settings_hash, expect_settings);

    uint64_t global_emitted = pf_rd_u64(&r);
    uint64_t caustic_emitted = pf_rd_u64(&r);
    const char *radius_names[3] = { "global_r2", "caustic_r2", "irradiance_r2" };
    float radii[3];
    for (int k = 0; k < 3; k++) {
        radii[k] = s_rd_raw_f32(&r);
        if (!isfinite(radii[k]) || !(radii[k] > 0.0f))
            return s_fail(err, PF_EPARSE, "%s %g must be finite and > 0", radius_names[k], (double)radii[k]);
    }
    s_entry_t e[S_MAPS];
    for (int m = 0; m < S_MAPS; m++) {
        const char *name = s_map_names[m];
        e[m].count = pf_rd_u64(&r);
        for (int k = 0; k < 3; k++)
            e[m].lo[k] = s_rd_raw_f32(&r);
        for (int k = 0; k < 3; k++)
            e[m].hi[k] = s_rd_raw_f32(&r);
        if (e[m].count > S_MAX_COUNT)
            return s_fail(err, PF_EPARSE, "%s count %" PRIu64 " is over the kd-tree limit of %" PRIu64, name,
                          e[m].count, S_MAX_COUNT);
        for (int k = 0; k < 3; k++) {
            if (!isfinite(e[m].lo[k]) || !isfinite(e[m].hi[k]))
                return s_fail(err, PF_EPARSE, "%s bounds on %c are not finite", name, "xyz"[k]);
            if (e[m].count > 0 && !(e[m].lo[k] <= e[m].hi[k]))
                return s_fail(err, PF_EPARSE, "%s bounds on %c are empty (%g > %g)", name, "xyz"[k],
                              (double)e[m].lo[k], (double)e[m].hi[k]);
        }
    }
    /* The counts must account for the body exactly; each is below 2^31, so
     * the sum cannot overflow. Checked before anything is allocated. */
    uint64_t need = (e[0].count + e[1].count + e[2].count + e[3].count) * S_RECORD;
    if (need != len - S_HEADER)
        return s_fail(err, PF_EPARSE,
                      "the counts (global %" PRIu64 ", caustic %" PRIu64 ", irradiance %" PRIu64
                      ", deep irradiance %" PRIu64 ") need %" PRIu64 " bytes after the header, but the blob has %zu",
                      e[0].count, e[1].count, e[2].count, e[3].count, need, len - S_HEADER);
    uint64_t stated = pf_rd_u64(&r);
    PF_CHECK(pf_rd_ok(&r) && r.left == len - S_HEADER);
    uint64_t h = pf_hash_bytes(PF_HASH_INIT, data, S_HASH_OFFSET);
    h = pf_hash_bytes(h, data + S_HEADER, len - S_HEADER);
    if (h != stated)
        return s_fail(err, PF_EPARSE, "content hash %016" PRIx64 " does not match the header and body (%016" PRIx64
                      "): the blob is corrupt", stated, h);

    pf_kdtree_t *trees[S_MAPS] = { NULL, NULL, NULL, NULL };
    const uint8_t *body = data + S_HEADER;
    int rc = PF_OK;
    for (int m = 0; m < S_MAPS && rc == PF_OK; m++) {
        rc = s_read_map(m, &e[m], body, &trees[m], err);
        body += (size_t)e[m].count * S_RECORD;
    }
    if (rc != PF_OK) {
        for (int m = 0; m < S_MAPS; m++)
            pf_kdtree_destroy(&trees[m]);
        return rc;
    }
    maps->global = trees[0];
    maps->caustic = trees[1];
    maps->irradiance = trees[2];
    /* The deep gathers' points: none (NULL) when the blob has none, as when
     * a frame's own photon pass derives none (no path limit of 3 or more). */
    if (e[3].count == 0)
        pf_kdtree_destroy(&trees[3]);
    maps->irradiance_deep = trees[3];
    maps->global_emitted = global_emitted;
    maps->caustic_emitted = caustic_emitted;
    maps->global_r2 = radii[0];
    maps->caustic_r2 = radii[1];
    maps->irradiance_r2 = radii[2];
    return PF_OK;
}
