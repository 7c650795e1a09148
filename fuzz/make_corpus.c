/* make_corpus.c: writes the seed corpus of every fuzz target into
 * OUT/<target>/ (see docs/fuzzing.md):
 *   msg        one frame of every message type, made with proto's encoders
 *   sceneblob  the scene blobs of a shipped scene, of the test scene that uses
 *              every JSON key, and of a one-quad scene
 *   mapfile    the photon maps of a real scene traced with a few hundred
 *              photons (global, caustic and irradiance maps all non-empty),
 *              and empty maps
 *   json, obj, mtl, ply   copies of the scenes/ and tests/data/ files of each
 *              kind, plus a tiny binary PLY of each byte order
 *   pfm        tiny PFM images: colour little-endian, greyscale big-endian
 * Copies larger than --max-size bytes are left out (the bunny's full-size
 * PLYs; the committed regression seeds use a small limit).
 *
 *   pf_make_corpus [--root DIR] [--max-size BYTES] OUT
 *
 * DIR is the repository root (default "."). Exits non-zero if anything could
 * not be made. One thread, apart from the photon pass's OpenMP threads. */
#include <dirent.h>
#include <errno.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/stat.h>

#include "accel/accel.h"
#include "base/hash.h"
#include "base/log.h"
#include "light/light.h"
#include "load/load.h"
#include "photon/mapfile.h"
#include "photon/trace.h"
#include "proto/hashtree.h"
#include "proto/messages.h"
#include "proto/sceneblob.h"
#include "render/frame.h"
#include "scene/scene.h"

static const char *s_out = NULL;
static const char *s_root = ".";
static long s_max_size = -1;
static int s_errors;

static void s_mkdir(const char *path)
{
    if (mkdir(path, 0755) != 0 && errno != EEXIST) {
        fprintf(stderr, "make_corpus: cannot create %s: %s\n", path, strerror(errno));
        s_errors++;
    }
}

/* Writes OUT/<target>/<name>. */
static void s_put(const char *target, const char *name, const void *data, size_t len)
{
    char path[1024];
    snprintf(path, sizeof path, "%s/%s", s_out, target);
    s_mkdir(path);
    snprintf(path, sizeof path, "%s/%s/%s", s_out, target, name);
    FILE *f = fopen(path, "wb");
    if (!f || fwrite(data, 1, len, f) != len || fclose(f) != 0) {
        fprintf(stderr, "make_corpus: cannot write %s: %s\n", path, strerror(errno));
        s_errors++;
    }
}

/* ---- messages ---- */

static void s_put_msg(const char *name, const pf_msg_t *m)
{
    pf_buf_t b = { 0 };
    int rc = pf_msg_encode(m, &b);
    if (rc) {
        fprintf(stderr, "make_corpus: cannot encode %s: %s\n", name, pf_strerror(rc));
        s_errors++;
    } else {
        s_put("msg", name, b.data, b.len);
    }
    pf_buf_free(&b);
}

static void s_messages(void)
{
    pf_msg_t m;
    memset(&m, 0, sizeof m);
    m.type = PF_MSG_HELLO;
    m.u.hello.fp = pf_frame_fingerprint();
    m.u.hello.threads = 8;
    m.u.hello.peer_port = 40001;
    snprintf(m.u.hello.name, sizeof m.u.hello.name, "node7:4242");
    s_put_msg("seed-hello", &m);

    memset(&m, 0, sizeof m);
    m.type = PF_MSG_WELCOME;
    m.u.welcome.worker_id = 3;
    m.u.welcome.heartbeat_ms = 1000;
    s_put_msg("seed-welcome", &m);

    memset(&m, 0, sizeof m);
    m.type = PF_MSG_REFUSE;
    snprintf(m.u.refuse.reason, sizeof m.u.refuse.reason, "incompatible builds: protocol version 2 vs 1");
    s_put_msg("seed-refuse", &m);

    memset(&m, 0, sizeof m);
    m.type = PF_MSG_HEARTBEAT;
    m.job = 7;
    m.u.heartbeat.progress = 123456;
    m.u.heartbeat.tiles_held = 2;
    s_put_msg("seed-heartbeat", &m);

    memset(&m, 0, sizeof m);
    m.type = PF_MSG_JOB;
    m.job = 7;
    m.u.job.scene_hash = 0x0123456789abcdefull;
    m.u.job.scene_size = 4096;
    m.u.job.maps_hash = 0xfedcba9876543210ull;
    m.u.job.maps_size = 3u << 20;
    m.u.job.settings = pf_settings_default();
    m.u.job.settings.caustic_radius = 0.05f;
    m.u.job.settings.exposure = -1.5f;
    m.u.job.terms = 15;
    m.u.job.tile_size = 32;
    s_put_msg("seed-job", &m);

    memset(&m, 0, sizeof m);
    m.type = PF_MSG_BLOB_REQ;
    m.job = 7;
    m.u.blob_req.hash = 0x0123456789abcdefull;
    m.u.blob_req.offset = 2u << 20;
    m.u.blob_req.credit = 4;
    s_put_msg("seed-blob-req", &m);

    static const uint8_t chunk[] = "FSCN, part of a scene blob";
    memset(&m, 0, sizeof m);
    m.type = PF_MSG_BLOB_CHUNK;
    m.job = 7;
    m.u.chunk.hash = 0x0123456789abcdefull;
    m.u.chunk.total = 1000;
    m.u.chunk.offset = 100;
    m.u.chunk.len = sizeof chunk - 1;
    m.u.chunk.data = chunk;
    s_put_msg("seed-blob-chunk", &m);

    memset(&m, 0, sizeof m);
    m.type = PF_MSG_READY;
    m.job = 7;
    m.u.ready.credit = 4;
    s_put_msg("seed-ready", &m);

    memset(&m, 0, sizeof m);
    m.type = PF_MSG_TILE;
    m.job = 7;
    m.u.tile = (pf_msg_tile_t){ .tile = 5, .attempt = 1, .x0 = 64, .y0 = 32, .w = 32, .h = 32 };
    s_put_msg("seed-tile", &m);

    float rgb[2 * 3 * 3];
    for (size_t i = 0; i < sizeof rgb / sizeof rgb[0]; i++)
        rgb[i] = 0.125f * (float)i;
    memset(&m, 0, sizeof m);
    m.type = PF_MSG_RESULT;
    m.job = 7;
    m.u.result = (pf_msg_result_t){ .tile = 5, .attempt = 1, .x0 = 64, .y0 = 32, .w = 2, .h = 3, .rgb = rgb,
                                    .render_us = 1500 };
    s_put_msg("seed-result", &m);

    memset(&m, 0, sizeof m);
    m.type = PF_MSG_JOB_END;
    m.job = 7;
    s_put_msg("seed-job-end", &m);

    memset(&m, 0, sizeof m);
    m.type = PF_MSG_BYE;
    snprintf(m.u.bye.reason, sizeof m.u.bye.reason, "shutting down");
    s_put_msg("seed-bye", &m);

    memset(&m, 0, sizeof m);
    m.type = PF_MSG_PHOTON_REQ;
    m.job = 7;
    m.u.photon_req.scene_hash = 0x0123456789abcdefull;
    m.u.photon_req.scene_size = 4096;
    m.u.photon_req.settings = pf_settings_default();
    m.u.photon_req.first = 12;
    m.u.photon_req.count = 2;
    s_put_msg("seed-photon-req", &m);

    pf_msg_photon_t ph[3];
    for (int i = 0; i < 3; i++)
        ph[i] = (pf_msg_photon_t){ { 0.25f * (float)i, 1.0f, -0.5f }, { 0.01f, 0.02f * (float)i, 0.0f },
                                   0x7fff7fffu + (uint32_t)i, 0x00010002u * (uint32_t)(i + 1) };
    memset(&m, 0, sizeof m);
    m.type = PF_MSG_PHOTONS;
    m.job = 7;
    m.u.photons = (pf_msg_photons_t){ .batch = 12, .total = 40, .first = 37, .rejected = 1, .indirect = 20, .n = 3,
                                      .photons = ph };
    s_put_msg("seed-photons", &m);

    memset(&m, 0, sizeof m);
    m.type = PF_MSG_IRR_POINTS;
    m.job = 7;
    m.u.photons = (pf_msg_photons_t){ .batch = 30, .total = 3, .n = 3, .photons = ph };
    s_put_msg("seed-irr-points", &m);

    memset(&m, 0, sizeof m);
    m.type = PF_MSG_IRR_REQ;
    m.job = 7;
    m.u.irr_req = (pf_msg_irr_req_t){ .scene_hash = 0x0123456789abcdefull, .scene_size = 4096, .maps_hash = 0x55aa,
                                      .maps_size = 1 << 20, .first = 4, .count = 8 };
    m.u.irr_req.settings = pf_settings_default();
    s_put_msg("seed-irr-req", &m);

    uint64_t leaves[3] = { 0x1111, 0x2222, 0x3333 };
    memset(&m, 0, sizeof m);
    m.type = PF_MSG_BLOB_PLAN;
    m.job = 7;
    m.u.plan = (pf_msg_blob_plan_t){ .hash = 0xfeedbeef, .size = 2 * PF_PROTO_CHUNK_SIZE + 1, .source_uid = 2, .n = 3,
                                     .leaves = leaves };
    m.u.plan.root = pf_chunk_root(m.u.plan.hash, m.u.plan.size, leaves, 3);
    snprintf(m.u.plan.source, sizeof m.u.plan.source, "tcp://10.0.0.2:40001");
    s_put_msg("seed-blob-plan", &m);
}

/* ---- scene blobs and photon maps ---- */

static pf_scene_t *s_load(const char *rel)
{
    char path[1024];
    snprintf(path, sizeof path, "%s/%s", s_root, rel);
    pf_error_t err;
    pf_scene_t *scene = pf_scene_load(path, &err);
    if (!scene) {
        fprintf(stderr, "make_corpus: %s\n", err.msg);
        s_errors++;
    }
    return scene;
}

static void s_put_blob(const char *name, const pf_scene_t *scene)
{
    if (!scene)
        return;
    pf_buf_t b = { 0 };
    if (pf_sceneblob_write(scene, &b)) {
        fprintf(stderr, "make_corpus: cannot serialize %s\n", name);
        s_errors++;
    } else {
        s_put("sceneblob", name, b.data, b.len);
    }
    pf_buf_free(&b);
}

/* One quad lit by a point light, built with the scene verbs. */
static pf_scene_t *s_tiny_scene(void)
{
    pf_scene_t *s = pf_scene_create();
    if (!s)
        return NULL;
    snprintf(s->path, sizeof s->path, "tiny");
    pf_material_t m = pf_material_default("grey");
    pf_scene_add_material(s, &m);
    pf_mesh_t mesh = { 0 };
    snprintf(mesh.name, sizeof mesh.name, "quad");
    mesh.nverts = 4;
    mesh.ntris = 2;
    mesh.pos = malloc(4 * sizeof *mesh.pos);
    mesh.nrm = malloc(4 * sizeof *mesh.nrm);
    mesh.idx = malloc(6 * sizeof *mesh.idx);
    mesh.mat = calloc(2, sizeof *mesh.mat);
    if (!mesh.pos || !mesh.nrm || !mesh.idx || !mesh.mat) {
        pf_mesh_free(&mesh);
        pf_scene_destroy(&s);
        return NULL;
    }
    mesh.pos[0] = pf_v3(0, 0, 0);
    mesh.pos[1] = pf_v3(1, 0, 0);
    mesh.pos[2] = pf_v3(1, 1, 0);
    mesh.pos[3] = pf_v3(0, 1, 0);
    for (int i = 0; i < 4; i++)
        mesh.nrm[i] = pf_v3(0, 0, 1);
    static const uint32_t idx[6] = { 0, 1, 2, 0, 2, 3 };
    memcpy(mesh.idx, idx, sizeof idx);
    pf_scene_add_mesh(s, &mesh);
    pf_sphere_t sp = { .center = pf_v3(0.5f, 0.5f, 0.5f), .radius = 0.25f, .mat = 0 };
    pf_scene_add_sphere(s, &sp);
    pf_light_t l = { .type = PF_LIGHT_SPOT, .pos = pf_v3(0.5f, 0.5f, 2), .intensity = pf_v3s(3),
                     .dir = pf_v3(0, 0, -1), .cos_inner = 0.9f, .cos_outer = 0.8f };
    pf_scene_add_light(s, &l);
    l = (pf_light_t){ .type = PF_LIGHT_DISTANT, .intensity = pf_v3s(2), .dir = pf_norm(pf_v3(0.2f, 0.1f, -1)) };
    pf_scene_add_light(s, &l);
    l = (pf_light_t){ .type = PF_LIGHT_INFINITE, .intensity = pf_v3s(0.5f) };
    pf_scene_add_light(s, &l);
    pf_error_t err;
    if (pf_scene_finalize(s, &err)) {
        fprintf(stderr, "make_corpus: tiny scene: %s\n", err.msg);
        pf_scene_destroy(&s);
    }
    return s;
}

/* Traces a few hundred photons in scene and writes the maps. */
static void s_put_maps(const char *name, const pf_scene_t *scene, uint64_t photons, uint64_t caustic)
{
    if (!scene)
        return;
    pf_error_t err;
    pf_accel_t *accel = pf_accel_create(scene, &err);
    pf_lights_t *lights = pf_lights_build(scene);
    if (!accel || !lights) {
        fprintf(stderr, "make_corpus: cannot build the scene for %s\n", name);
        s_errors++;
        pf_accel_destroy(&accel);
        pf_lights_destroy(&lights);
        return;
    }
    pf_settings_t s = scene->settings;
    s.photons = photons;
    s.caustic_photons = caustic;
    s.threads = 1;
    s.irradiance_stride = 4;
    s.global_k = 8;
    pf_photon_maps_t maps;
    pf_photon_stats_t stats;
    int rc = pf_photon_pass(scene, accel, lights, &s, &maps, &stats);
    if (rc == PF_OK) {
        pf_buf_t blob = { 0 }, b = { 0 };
        pf_sceneblob_write(scene, &blob);
        uint64_t scene_hash = pf_hash_bytes(PF_HASH_INIT, blob.data, blob.len);
        if (pf_mapfile_write(&maps, scene_hash, pf_settings_hash(&s), &b) == PF_OK)
            s_put("mapfile", name, b.data, b.len);
        else
            s_errors++;
        printf("make_corpus: %s: %llu global, %llu caustic photons, %llu irradiance points, %zu bytes\n", name,
               (unsigned long long)stats.global_stored, (unsigned long long)stats.caustic_stored,
               (unsigned long long)stats.irradiance_points, b.len);
        pf_buf_free(&blob);
        pf_buf_free(&b);
    } else {
        fprintf(stderr, "make_corpus: photon pass for %s: %s\n", name, pf_strerror(rc));
        s_errors++;
    }
    pf_photon_maps_free(&maps);
    pf_lights_destroy(&lights);
    pf_accel_destroy(&accel);
}

static void s_blobs(void)
{
    pf_scene_t *box = s_load("scenes/cornell-box/scene.json");
    pf_scene_t *prims = s_load("tests/data/json/prims.json");
    pf_scene_t *tiny = s_tiny_scene();
    pf_scene_t *spheres = s_load("scenes/cornell-spheres/scene.json");
    s_put_blob("seed-cornell-box", box);
    s_put_blob("seed-prims", prims);
    s_put_blob("seed-tiny", tiny);
    /* The spheres' box keeps the photons in, and its mirror and glass
     * spheres make a caustic map; the tiny scene's caustic map is empty. */
    s_put_maps("seed-cornell-spheres-maps", spheres, 120, 120);
    s_put_maps("seed-tiny-maps", tiny, 60, 0);
    pf_photon_maps_t empty;
    memset(&empty, 0, sizeof empty);
    empty.global_r2 = empty.caustic_r2 = empty.irradiance_r2 = 0.01f;
    pf_buf_t b = { 0 };
    if (pf_mapfile_write(&empty, 1, 2, &b) == PF_OK)
        s_put("mapfile", "seed-empty-maps", b.data, b.len);
    pf_buf_free(&b);
    pf_scene_destroy(&box);
    pf_scene_destroy(&prims);
    pf_scene_destroy(&tiny);
    pf_scene_destroy(&spheres);
}

/* ---- copies and small files ---- */

static int s_has_ext(const char *name, const char *ext)
{
    size_t n = strlen(name), e = strlen(ext);
    return n > e && strcmp(name + n - e, ext) == 0;
}

/* Copies every DIR/<file>EXT of at most s_max_size bytes to OUT/target/,
 * named prefix-file. */
static void s_copy(const char *target, const char *dir, const char *ext, const char *prefix)
{
    char path[1024];
    snprintf(path, sizeof path, "%s/%s", s_root, dir);
    DIR *d = opendir(path);
    if (!d) {
        fprintf(stderr, "make_corpus: cannot open %s\n", path);
        s_errors++;
        return;
    }
    struct dirent *e;
    while ((e = readdir(d))) {
        if (!s_has_ext(e->d_name, ext))
            continue;
        char file[1280];
        snprintf(file, sizeof file, "%s/%s", path, e->d_name);
        FILE *f = fopen(file, "rb");
        if (!f)
            continue;
        struct stat st;
        if (fstat(fileno(f), &st) != 0 || !S_ISREG(st.st_mode) || (s_max_size >= 0 && st.st_size > s_max_size)) {
            fclose(f);
            continue;
        }
        char *buf = malloc((size_t)st.st_size + 1);
        size_t got = buf ? fread(buf, 1, (size_t)st.st_size, f) : 0;
        fclose(f);
        if (buf && got == (size_t)st.st_size) {
            char name[512];
            snprintf(name, sizeof name, "%s-%s", prefix, e->d_name);
            s_put(target, name, buf, got);
        } else {
            s_errors++;
        }
        free(buf);
    }
    closedir(d);
}

/* A two-triangle square as binary PLY (float positions and normals, an
 * extra uchar property to skip, uint indices), little or big endian. */
static void s_binary_ply(int big)
{
    char head[512];
    int hn = snprintf(head, sizeof head,
                      "ply\nformat binary_%s_endian 1.0\nelement vertex 4\nproperty float x\nproperty float y\n"
                      "property float z\nproperty float nx\nproperty float ny\nproperty float nz\n"
                      "property uchar flags\nelement face 2\nproperty list uchar uint vertex_indices\nend_header\n",
                      big ? "big" : "little");
    uint8_t body[4 * 25 + 2 * 13], *p = body;
    static const float v[4][3] = { { 0, 0, 0 }, { 1, 0, 0 }, { 1, 1, 0 }, { 0, 1, 0 } };
    for (int i = 0; i < 4; i++) {
        float vals[6] = { v[i][0], v[i][1], v[i][2], 0, 0, 1 };
        for (int k = 0; k < 6; k++) {
            uint32_t u;
            memcpy(&u, &vals[k], 4);
            for (int j = 0; j < 4; j++)
                *p++ = (uint8_t)(big ? u >> (24 - 8 * j) : u >> (8 * j));
        }
        *p++ = (uint8_t)i;
    }
    static const uint32_t f[2][3] = { { 0, 1, 2 }, { 0, 2, 3 } };
    for (int t = 0; t < 2; t++) {
        *p++ = 3;
        for (int k = 0; k < 3; k++)
            for (int j = 0; j < 4; j++)
                *p++ = (uint8_t)(big ? f[t][k] >> (24 - 8 * j) : f[t][k] >> (8 * j));
    }
    uint8_t all[sizeof head + sizeof body];
    memcpy(all, head, (size_t)hn);
    memcpy(all + hn, body, (size_t)(p - body));
    s_put("ply", big ? "seed-binary-be.ply" : "seed-binary-le.ply", all, (size_t)hn + (size_t)(p - body));
}

/* A 3x2 colour PFM (little-endian) and a 2x2 greyscale one (big-endian). */
static void s_pfms(void)
{
    uint8_t buf[256];
    int n = snprintf((char *)buf, sizeof buf, "PF\n3 2\n-1.0\n");
    for (int i = 0; i < 18; i++) {
        float x = 0.1f * (float)i;
        uint32_t u;
        memcpy(&u, &x, 4);
        for (int j = 0; j < 4; j++)
            buf[n++] = (uint8_t)(u >> (8 * j));
    }
    s_put("pfm", "seed-colour-le.pfm", buf, (size_t)n);
    n = snprintf((char *)buf, sizeof buf, "Pf\n2 2\n1.0\n");
    for (int i = 0; i < 4; i++) {
        float x = 0.25f * (float)i;
        uint32_t u;
        memcpy(&u, &x, 4);
        for (int j = 0; j < 4; j++)
            buf[n++] = (uint8_t)(u >> (24 - 8 * j));
    }
    s_put("pfm", "seed-grey-be.pfm", buf, (size_t)n);
}

static void s_copies(void)
{
    s_copy("json", "scenes/cornell-box", ".json", "cornell-box");
    s_copy("json", "scenes/cornell-spheres", ".json", "cornell-spheres");
    s_copy("json", "scenes/bunny", ".json", "bunny");
    s_copy("json", "tests/data/json", ".json", "json");
    s_copy("json", "tests/data/json/bad", ".json", "json-bad");
    s_copy("json", "tests/data/cli", ".json", "cli");
    s_copy("obj", "scenes/cornell-box", ".obj", "cornell-box");
    s_copy("obj", "scenes/cornell-spheres", ".obj", "cornell-spheres");
    s_copy("obj", "tests/data/json", ".obj", "json");
    s_copy("obj", "tests/data/loaders", ".obj", "loaders");
    s_copy("mtl", "scenes/cornell-box", ".mtl", "cornell-box");
    s_copy("mtl", "scenes/cornell-spheres", ".mtl", "cornell-spheres");
    s_copy("mtl", "tests/data/json", ".mtl", "json");
    s_copy("mtl", "tests/data/loaders", ".mtl", "loaders");
    s_copy("ply", "tests/data/json", ".ply", "json");
    s_copy("ply", "tests/data/loaders", ".ply", "loaders");
    /* Of the bunny only the smallest resolution: the others are 150 KB to 3 MB. */
    char path[1024];
    snprintf(path, sizeof path, "%s/scenes/bunny/bun_zipper_res4.ply", s_root);
    struct stat st;
    if (stat(path, &st) == 0 && (s_max_size < 0 || st.st_size <= s_max_size)) {
        FILE *f = fopen(path, "rb");
        char *buf = malloc((size_t)st.st_size);
        if (f && buf && fread(buf, 1, (size_t)st.st_size, f) == (size_t)st.st_size)
            s_put("ply", "bunny-bun_zipper_res4.ply", buf, (size_t)st.st_size);
        else
            s_errors++;
        free(buf);
        if (f)
            fclose(f);
    }
    s_binary_ply(0);
    s_binary_ply(1);
    s_pfms();
}

int main(int argc, char **argv)
{
    for (int i = 1; i < argc; i++) {
        if (strcmp(argv[i], "--root") == 0 && i + 1 < argc) {
            s_root = argv[++i];
        } else if (strcmp(argv[i], "--max-size") == 0 && i + 1 < argc) {
            s_max_size = strtol(argv[++i], NULL, 10);
        } else if (argv[i][0] != '-' && !s_out) {
            s_out = argv[i];
        } else {
            fprintf(stderr, "usage: %s [--root DIR] [--max-size BYTES] OUT\n", argv[0]);
            return 2;
        }
    }
    if (!s_out) {
        fprintf(stderr, "usage: %s [--root DIR] [--max-size BYTES] OUT\n", argv[0]);
        return 2;
    }
    pf_log_set_level(PF_LOG_WARN);
    s_mkdir(s_out);
    s_messages();
    s_blobs();
    s_copies();
    if (s_errors)
        fprintf(stderr, "make_corpus: %d errors\n", s_errors);
    return s_errors ? 1 : 0;
}
