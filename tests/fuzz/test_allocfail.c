/* test_allocfail.c: allocation-failure injection into every decoder of
 * outside input: the scene loaders (JSON, OBJ, MTL, PLY, and
 * pf_scene_load's finalize), the scene blob, the photon-map blob and every
 * wire message.
 *
 * The test links with --wrap=malloc,calloc,realloc,free,strdup
 * (tests/fuzz/CMakeLists.txt), so every call to these from the project's objects
 * (the project libraries and this file) goes through the __wrap_ functions
 * below; cJSON, a shared library, is routed to the same functions through
 * cJSON_InitHooks. Allocations made inside libc itself (fopen's FILE,
 * getline's buffer) are not seen, and so are not failed.
 *
 * For each case, a reference run counts K allocations and records a digest
 * of the result (the scene or maps serialized, the message re-encoded).
 * Then for N = 1 .. K the N-th allocation fails, and the decoder must either
 * return a negative status with an error message, or recover completely
 * (same digest: e.g. a failed shrinking realloc keeps the larger block).
 * Either way every block allocated during the call must have been freed:
 * the wrappers keep the live blocks in a table, which must be empty after
 * the case has destroyed what it got. (The sanitizer build's LeakSanitizer
 * checks the same at exit, for the allocations the table cannot see.)
 *
 * Single-threaded: the decoders allocate on the calling thread only. */
#include <cjson/cJSON.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <unistd.h>

#include "base/hash.h"
#include "base/log.h"
#include "check.h"
#include "load/load.h"
#include "photon/kdtree.h"
#include "photon/mapfile.h"
#include "photon/photonmap.h"
#include "proto/hashtree.h"
#include "proto/messages.h"
#include "proto/sceneblob.h"
#include "render/frame.h"
#include "scene/scene.h"

/* ---- the failing allocator ---- */

void *__real_malloc(size_t n);
void *__real_calloc(size_t n, size_t size);
void *__real_realloc(void *p, size_t n);
void __real_free(void *p);
char *__real_strdup(const char *s);
void *__wrap_malloc(size_t n);
void *__wrap_calloc(size_t n, size_t size);
void *__wrap_realloc(void *p, size_t n);
void __wrap_free(void *p);
char *__wrap_strdup(const char *s);

static int s_armed;        /* count (and maybe fail) allocations */
static long s_calls;       /* allocations while armed */
static long s_fail_at;     /* the call to fail, 1-based; 0: none */
static int s_injected;     /* the failure happened */

/* Live blocks allocated while armed: open addressing on the pointer. */
#define S_SLOTS (1u << 18)
static void *s_live[S_SLOTS];
static size_t s_nlive;
static void *const s_tomb = (void *)1;

static size_t s_slot_of(const void *p) { return (size_t)(((uintptr_t)p >> 4) * 0x9E3779B97F4A7C15ull >> 46); }

static void s_track(void *p)
{
    if (!p)
        return;
    size_t i = s_slot_of(p);
    while (s_live[i] && s_live[i] != s_tomb)
        i = (i + 1) & (S_SLOTS - 1);
    s_live[i] = p;
    s_nlive++;
}

/* Forgets p; returns whether it was tracked. */
static int s_untrack(const void *p)
{
    if (!p || s_nlive == 0)
        return 0;
    for (size_t i = s_slot_of(p);; i = (i + 1) & (S_SLOTS - 1)) {
        if (!s_live[i])
            return 0;
        if (s_live[i] == p) {
            s_live[i] = s_tomb;
            s_nlive--;
            return 1;
        }
    }
}

static void s_reset_table(void)
{
    memset(s_live, 0, sizeof s_live);
    s_nlive = 0;
}

/* Whether this allocation is the one to fail. */
static int s_fail_now(void)
{
    if (!s_armed)
        return 0;
    s_calls++;
    if (s_calls == s_fail_at) {
        s_injected = 1;
        return 1;
    }
    return 0;
}

void *__wrap_malloc(size_t n)
{
    if (s_fail_now())
        return NULL;
    void *p = __real_malloc(n);
    if (s_armed)
        s_track(p);
    return p;
}

void *__wrap_calloc(size_t n, size_t size)
{
    if (s_fail_now())
        return NULL;
    void *p = __real_calloc(n, size);
    if (s_armed)
        s_track(p);
    return p;
}

void *__wrap_realloc(void *p, size_t n)
{
    if (s_fail_now())
        return NULL;
    int tracked = s_untrack(p);
    void *q = __real_realloc(p, n);
    if (!q && n > 0) {
        if (tracked)
            s_track(p); /* the old block lives on */
        return NULL;
    }
    if (tracked || (!p && s_armed))
        s_track(q);
    return q;
}

void __wrap_free(void *p)
{
    s_untrack(p);
    __real_free(p);
}

char *__wrap_strdup(const char *s)
{
    if (s_fail_now())
        return NULL;
    char *p = __real_strdup(s);
    if (s_armed)
        s_track(p);
    return p;
}

static void *s_cjson_malloc(size_t n) { return __wrap_malloc(n); }
static void s_cjson_free(void *p) { __wrap_free(p); }

/* ---- cases ---- */

/* A digest of what a decode produced, compared between runs. */
typedef struct s_digest {
    uint64_t hash;
    size_t len;
} s_digest_t;

/* One case: runs the decoder armed (s_arm/s_disarm around the decode only),
 * fills *d on success, frees everything, and returns the decoder's status. */
typedef int (*s_case_fn)(const void *arg, pf_error_t *err, s_digest_t *d);

static void s_arm(void) { s_armed = 1; }
static void s_disarm(void) { s_armed = 0; }

/* The canonical serialization of a scene, as a digest. */
static void s_scene_digest(const pf_scene_t *scene, s_digest_t *d)
{
    pf_buf_t b = { 0 };
    CHECK(pf_sceneblob_write(scene, &b) == 0, "serializing a decoded scene");
    d->hash = pf_hash_bytes(PF_HASH_INIT, b.data, b.len);
    d->len = b.len;
    pf_buf_free(&b);
}

typedef struct s_file_case {
    const char *path;
    int kind; /* 0 JSON, 1 OBJ, 2 MTL, 3 PLY, 4 pf_scene_load */
} s_file_case_t;

static int s_file(const void *arg, pf_error_t *err, s_digest_t *d)
{
    const s_file_case_t *c = arg;
    pf_scene_t *scene = NULL;
    int rc;
    if (c->kind == 4) {
        s_arm();
        scene = pf_scene_load(c->path, err);
        s_disarm();
        rc = scene ? PF_OK : PF_EINVAL; /* the status is in the message; any failure is negative */
        if (!scene && err->msg[0] == '\0')
            rc = 1; /* flagged below: a failure without a message */
    } else {
        scene = pf_scene_create();
        if (!scene)
            return PF_ENOMEM;
        pf_material_t m = pf_material_default("base");
        if (pf_scene_add_material(scene, &m) < 0) {
            pf_scene_destroy(&scene);
            return PF_ENOMEM;
        }
        s_arm();
        switch (c->kind) {
        case 0: rc = pf_scene_json_load(scene, c->path, err); break;
        case 1: rc = pf_obj_load(scene, c->path, NULL, -1, err); break;
        case 2: rc = pf_mtl_load(scene, c->path, err); break;
        default: rc = pf_ply_load(scene, c->path, NULL, 0, err); break;
        }
        s_disarm();
    }
    if (rc == PF_OK)
        s_scene_digest(scene, d);
    pf_scene_destroy(&scene);
    return rc;
}

typedef struct s_blob_case {
    const uint8_t *data;
    size_t len;
} s_blob_case_t;

static int s_sceneblob(const void *arg, pf_error_t *err, s_digest_t *d)
{
    const s_blob_case_t *c = arg;
    s_arm();
    pf_scene_t *scene = pf_sceneblob_read(c->data, c->len, err);
    s_disarm();
    if (!scene)
        return err->msg[0] ? PF_EINVAL : 1;
    s_scene_digest(scene, d);
    pf_scene_destroy(&scene);
    return PF_OK;
}

static int s_mapfile(const void *arg, pf_error_t *err, s_digest_t *d)
{
    const s_blob_case_t *c = arg;
    pf_photon_maps_t maps;
    s_arm();
    int rc = pf_mapfile_read(c->data, c->len, 0, 0, &maps, err);
    s_disarm();
    if (rc == PF_OK) {
        pf_buf_t b = { 0 };
        CHECK(pf_mapfile_write(&maps, 0, 0, &b) == 0, "writing decoded maps");
        d->hash = pf_hash_bytes(PF_HASH_INIT, b.data, b.len);
        d->len = b.len;
        pf_buf_free(&b);
    }
    pf_photon_maps_free(&maps);
    return rc;
}

static int s_message(const void *arg, pf_error_t *err, s_digest_t *d)
{
    const s_blob_case_t *c = arg;
    pf_msg_t m;
    s_arm();
    int rc = pf_msg_decode(c->data, c->len, &m, err->msg, sizeof err->msg);
    s_disarm();
    if (rc == PF_OK) {
        d->hash = pf_hash_bytes(PF_HASH_INIT, &m.type, sizeof m.type);
        d->hash = pf_hash_u64(d->hash, m.job);
        d->len = c->len;
    }
    return rc;
}

/* ---- the harness ---- */

static int s_total_failures, s_total_allocs;

/* Runs fn with no failure, then failing allocation N = 1 .. K. */
static void s_inject(const char *name, s_case_fn fn, const void *arg)
{
    pf_error_t err;
    s_digest_t ref = { 0, 0 };
    s_reset_table();
    s_fail_at = 0;
    s_calls = 0;
    s_injected = 0;
    err.msg[0] = '\0';
    int rc = fn(arg, &err, &ref);
    long k = s_calls;
    CHECK(rc == PF_OK, "%s: the reference decode failed: %s", name, err.msg);
    CHECK(s_nlive == 0, "%s: the reference decode leaked %zu blocks", name, s_nlive);
    if (rc != PF_OK)
        return;
    int clean = 0, recovered = 0, other = 0;
    for (long n = 1; n <= k; n++) {
        s_reset_table();
        s_fail_at = n;
        s_calls = 0;
        s_injected = 0;
        err.msg[0] = '\0';
        s_digest_t d = { 0, 0 };
        rc = fn(arg, &err, &d);
        s_fail_at = 0;
        CHECK(s_injected, "%s: allocation %ld of %ld never happened (the decoder is not deterministic)", name, n, k);
        if (rc == PF_OK) {
            recovered++;
            CHECK(d.hash == ref.hash && d.len == ref.len,
                  "%s: allocation %ld failed and the decode succeeded with a different result", name, n);
        } else {
            CHECK(rc < 0, "%s: allocation %ld failed: status %d is not a negative pf_status", name, n, rc);
            CHECK(err.msg[0] != '\0', "%s: allocation %ld failed: no error message", name, n);
            if (strstr(err.msg, "out of memory") || rc == PF_ENOMEM)
                clean++;
            else
                other++;
        }
        CHECK(s_nlive == 0, "%s: allocation %ld failed: %zu blocks leaked", name, n, s_nlive);
    }
    s_total_allocs += (int)k;
    s_total_failures += clean + other;
    printf("%-44s %4ld allocations: %4d failed with 'out of memory', %3d with another error, %3d recovered\n", name,
           k, clean, other, recovered);
    fflush(stdout);
}

static void s_write_file(const char *path, const void *data, size_t len)
{
    FILE *f = fopen(path, "wb");
    CHECK(f != NULL, "cannot write %s", path);
    if (!f)
        return;
    CHECK(fwrite(data, 1, len, f) == len && fclose(f) == 0, "cannot write %s", path);
}

/* A two-triangle binary PLY with normals, an extra property and a list to skip. */
static size_t s_binary_ply(int big, uint8_t *out, size_t cap)
{
    int hn = snprintf((char *)out, cap,
                      "ply\nformat binary_%s_endian 1.0\nelement vertex 4\nproperty float x\nproperty float y\n"
                      "property float z\nproperty float nx\nproperty float ny\nproperty float nz\n"
                      "element face 2\nproperty list uchar uint vertex_indices\n"
                      "element extra 1\nproperty list uchar short things\nend_header\n",
                      big ? "big" : "little");
    uint8_t *p = out + hn;
    static const float v[4][6] = { { 0, 0, 0, 0, 0, 1 }, { 1, 0, 0, 0, 0, 1 }, { 1, 1, 0, 0, 0, 1 },
                                   { 0, 1, 0, 0, 0, 1 } };
    for (int i = 0; i < 4; i++)
        for (int k = 0; k < 6; k++) {
            uint32_t u;
            memcpy(&u, &v[i][k], 4);
            for (int j = 0; j < 4; j++)
                *p++ = (uint8_t)(big ? u >> (24 - 8 * j) : u >> (8 * j));
        }
    static const uint32_t f[2][3] = { { 0, 1, 2 }, { 0, 2, 3 } };
    for (int t = 0; t < 2; t++) {
        *p++ = 3;
        for (int k = 0; k < 3; k++)
            for (int j = 0; j < 4; j++)
                *p++ = (uint8_t)(big ? f[t][k] >> (24 - 8 * j) : f[t][k] >> (8 * j));
    }
    *p++ = 2;
    for (int j = 0; j < 4; j++)
        *p++ = (uint8_t)j;
    return (size_t)(p - out);
}

static pf_kdtree_t *s_tree(size_t n, uint32_t seed)
{
    pf_photon_t *ph = malloc((n ? n : 1) * sizeof *ph);
    CHECK(ph != NULL, "out of memory");
    uint64_t x = seed * 0x9E3779B97F4A7C15ull + 1;
    for (size_t i = 0; i < n; i++) {
        for (int k = 0; k < 3; k++) {
            x = x * 6364136223846793005ull + 1442695040888963407ull;
            ph[i].pos[k] = (float)(x >> 40) / (float)(1u << 24) * 4.0f - 2.0f;
            ph[i].power[k] = (float)((x >> 20) & 0xff) * 1e-4f;
        }
        ph[i].dir = (uint32_t)(x >> 7);
        ph[i].normal = (uint32_t)(x >> 13);
    }
    return pf_kdtree_build(&ph, n);
}

int main(void)
{
    pf_log_set_level(PF_LOG_QUIET);
    cJSON_Hooks hooks = { s_cjson_malloc, s_cjson_free };
    cJSON_InitHooks(&hooks);

    /* The scene loaders, on the test data and the shipped Cornell box. */
    static const s_file_case_t files[] = {
        { "tests/data/json/models.json", 0 },      /* JSON with OBJ, MTL and PLY models */
        { "tests/data/json/prims.json", 0 },       /* every JSON key but the models */
        { "tests/data/json/prims.json", 4 },       /* the same through pf_scene_load and finalize */
        { "scenes/cornell-box/scene.json", 4 },    /* a shipped scene */
        { "tests/data/loaders/basic.obj", 1 },     /* every face form, groups, two MTL files */
        { "tests/data/loaders/mixed_normals.obj", 1 },
        { "scenes/cornell-box/cornell-box.obj", 1 },
        { "tests/data/loaders/materials.mtl", 2 },
        { "tests/data/json/tri.ply", 3 },
        { "scenes/bunny/bun_zipper_res4.ply", 3 }, /* 453 vertices, 948 faces */
    };
    const char *names[] = { "json models.json", "json prims.json", "scene_load prims.json",
                            "scene_load cornell-box/scene.json", "obj basic.obj", "obj mixed_normals.obj",
                            "obj cornell-box.obj", "mtl materials.mtl", "ply tri.ply", "ply bun_zipper_res4.ply" };
    for (size_t i = 0; i < sizeof files / sizeof files[0]; i++)
        s_inject(names[i], s_file, &files[i]);

    uint8_t ply[1024];
    char le_path[128], be_path[128];
    snprintf(le_path, sizeof le_path, "/tmp/pf-allocfail-%ld-le.ply", (long)getpid());
    snprintf(be_path, sizeof be_path, "/tmp/pf-allocfail-%ld-be.ply", (long)getpid());
    s_write_file(le_path, ply, s_binary_ply(0, ply, sizeof ply));
    s_write_file(be_path, ply, s_binary_ply(1, ply, sizeof ply));
    s_file_case_t le = { le_path, 3 }, be = { be_path, 3 };
    s_inject("ply binary little-endian", s_file, &le);
    s_inject("ply binary big-endian", s_file, &be);
    unlink(le_path);
    unlink(be_path);

    /* The scene blob of two loaded scenes. */
    const char *blob_scenes[] = { "scenes/cornell-box/scene.json", "tests/data/json/prims.json" };
    for (int i = 0; i < 2; i++) {
        pf_error_t err;
        pf_scene_t *scene = pf_scene_load(blob_scenes[i], &err);
        CHECK(scene != NULL, "%s: %s", blob_scenes[i], err.msg);
        if (!scene)
            continue;
        pf_buf_t b = { 0 };
        CHECK(pf_sceneblob_write(scene, &b) == 0, "serializing %s", blob_scenes[i]);
        s_blob_case_t c = { b.data, b.len };
        char name[96];
        snprintf(name, sizeof name, "sceneblob of %s", blob_scenes[i]);
        s_inject(name, s_sceneblob, &c);
        pf_buf_free(&b);
        pf_scene_destroy(&scene);
    }

    /* The photon-map blob: three non-empty maps, and three empty ones. */
    for (int empty = 0; empty < 2; empty++) {
        pf_photon_maps_t maps;
        memset(&maps, 0, sizeof maps);
        maps.global = s_tree(empty ? 0 : 300, 1);
        maps.caustic = s_tree(empty ? 0 : 40, 2);
        maps.irradiance = s_tree(empty ? 0 : 75, 3);
        maps.global_emitted = maps.caustic_emitted = 1000;
        maps.global_r2 = maps.caustic_r2 = maps.irradiance_r2 = 0.01f;
        pf_buf_t b = { 0 };
        CHECK(pf_mapfile_write(&maps, 0, 0, &b) == 0, "writing maps");
        s_blob_case_t c = { b.data, b.len };
        s_inject(empty ? "mapfile, empty maps" : "mapfile, 300 + 40 + 75 photons", s_mapfile, &c);
        pf_buf_free(&b);
        pf_photon_maps_free(&maps);
    }

    /* One message of every type. */
    float rgb[12] = { 0.5f, 1, 2, 3, 4, 5, 6, 7, 8, 9, 10, 11 };
    static const uint8_t chunk[5] = { 1, 2, 3, 4, 5 };
    static const pf_msg_photon_t photons[2] = { { { 1, 2, 3 }, { 0.5f, 0.5f, 0.5f }, 0x7fff7fffu, 0x7fff7fffu },
                                                { { -1, 0, 4 }, { 1, 0, 2 }, 0x12345678u, 0x7fff7fffu } };
    for (int t = 1; t <= PF_MSG_MAX_TYPE; t++) {
        pf_msg_t m;
        memset(&m, 0, sizeof m);
        m.type = (pf_msg_type)t;
        m.job = 9;
        switch (t) {
        case PF_MSG_HELLO:
            m.u.hello.fp = pf_frame_fingerprint();
            m.u.hello.threads = 2;
            snprintf(m.u.hello.name, sizeof m.u.hello.name, "host:1");
            break;
        case PF_MSG_WELCOME: m.u.welcome.heartbeat_ms = 1000; break;
        case PF_MSG_REFUSE: snprintf(m.u.refuse.reason, sizeof m.u.refuse.reason, "no"); break;
        case PF_MSG_JOB:
            m.u.job.settings = pf_settings_default();
            m.u.job.terms = 15;
            m.u.job.tile_size = 32;
            break;
        case PF_MSG_BLOB_REQ: m.u.blob_req.credit = 2; break;
        case PF_MSG_BLOB_CHUNK:
            m.u.chunk = (pf_msg_blob_chunk_t){ .hash = 1, .total = 10, .offset = 5, .len = 5, .data = chunk };
            break;
        case PF_MSG_READY: m.u.ready.credit = 3; break;
        case PF_MSG_TILE: m.u.tile = (pf_msg_tile_t){ .w = 4, .h = 4 }; break;
        case PF_MSG_RESULT: m.u.result = (pf_msg_result_t){ .w = 2, .h = 2, .rgb = rgb }; break;
        case PF_MSG_BYE: snprintf(m.u.bye.reason, sizeof m.u.bye.reason, "done"); break;
        case PF_MSG_PHOTON_REQ:
            m.u.photon_req = (pf_msg_photon_req_t){ .scene_hash = 7, .scene_size = 100, .first = 2, .count = 3 };
            m.u.photon_req.settings = pf_settings_default();
            break;
        case PF_MSG_PHOTONS:
        case PF_MSG_IRR_POINTS:
            m.u.photons = (pf_msg_photons_t){ .batch = 1, .total = 2, .first = 0, .n = 2, .photons = photons };
            break;
        case PF_MSG_IRR_REQ:
            m.u.irr_req = (pf_msg_irr_req_t){ .scene_hash = 7, .scene_size = 100, .maps_hash = 8, .maps_size = 200,
                                              .first = 2, .count = 3 };
            m.u.irr_req.settings = pf_settings_default();
            break;
        case PF_MSG_BLOB_PLAN: {
            static const uint64_t leaves[2] = { 11, 22 };
            m.u.plan = (pf_msg_blob_plan_t){ .hash = 5, .size = PF_PROTO_CHUNK_SIZE + 9, .n = 2, .leaves = leaves };
            m.u.plan.root = pf_chunk_root(5, m.u.plan.size, leaves, 2);
            snprintf(m.u.plan.source, sizeof m.u.plan.source, "tcp://127.0.0.1:4000");
            break;
        }
        default: break;
        }
        pf_buf_t b = { 0 };
        CHECK(pf_msg_encode(&m, &b) == 0, "encoding %s", pf_msg_type_name(t));
        s_blob_case_t c = { b.data, b.len };
        char name[64];
        snprintf(name, sizeof name, "message %s", pf_msg_type_name(t));
        s_inject(name, s_message, &c);
        pf_buf_free(&b);
    }

    printf("%d allocations failed one at a time, %d of them reported as errors\n", s_total_allocs,
           s_total_failures);
    CHECK(s_total_allocs > 1000, "too few allocations were failed (%d): is --wrap in effect?", s_total_allocs);
    return pf_test_finish();
}
