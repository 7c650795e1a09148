/* test_blobs.c: the scene blob and the photon-map blob (ctest `blobs`).
 *
 * Scene blob: a small scene built in code (materials of every kind, a mesh
 * with normals and one without, a sphere, a point, a spot, a distant and an infinite light, a
 * left-handed thin-lens camera whose fov spans the shorter axis, with a
 * screen window and a frame aspect)
 * and the shipped cornell-spheres scene round-trip into scenes equal in every
 * array, and re-serialize to the same bytes; every truncation (all lengths
 * for the small scene, a sample for cornell-spheres) fails cleanly; huge
 * counts are refused by the size check, not by a failed allocation; each kind
 * of bad field is refused with a message naming it.
 *
 * Photon-map blob: trees built from random photons round-trip into identical
 * photon arrays (split axes included), bounds and parameters; wrong scene or settings hashes
 * are PF_EMISMATCH; each header field, a split axis of 3, a NaN position, a
 * position outside the bounds, a negative power, a broken kd order, a content
 * hash mismatch and a count too large are refused naming the field (body
 * corruptions are re-hashed so that the check behind the hash is reached);
 * every truncation fails. And the settings hash covers exactly the photon
 * settings. */
#include <math.h>
#include <stddef.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "base/hash.h"
#include "base/log.h"
#include "base/wire.h"
#include "photon/mapfile.h"
#include "proto/sceneblob.h"

#include "check.h"
#include "load/load.h"



static uint64_t s_state = 0xb10b5;
static uint64_t s_next(void)
{
    uint64_t z = (s_state += 0x9e3779b97f4a7c15ULL);
    z = (z ^ (z >> 30)) * 0xbf58476d1ce4e5b9ULL;
    z = (z ^ (z >> 27)) * 0x94d049bb133111ebULL;
    return z ^ (z >> 31);
}
static float s_uniform(void) { return (float)(s_next() >> 40) * 0x1p-24f; }

static void s_put16(uint8_t *p, uint16_t v)
{
    p[0] = (uint8_t)v;
    p[1] = (uint8_t)(v >> 8);
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
static void s_putf(uint8_t *p, float f)
{
    uint32_t u;
    memcpy(&u, &f, sizeof u);
    s_put32(p, u);
}

/* ================= scene blob ================= */

static pf_scene_t *s_tiny_scene(void)
{
    pf_scene_t *s = pf_scene_create();
    snprintf(s->path, sizeof s->path, "tests/tiny/scene.json");
    s->settings.width = 320;
    s->settings.seed = 0x123456789abcdefULL;
    s->settings.exposure = 0.5f;
    s->settings.path_max_depth = 4;
    pf_material_t m = pf_material_default("emitter");
    m.le = pf_v3(5.0f, 4.0f, 3.0f);
    pf_scene_add_material(s, &m);
    m = pf_material_default("glass");
    m.type = PF_MAT_GLASS;
    m.ks = pf_v3s(1.0f);
    m.kt = pf_v3(0.9f, 0.95f, 1.0f);
    m.ior = 1.45f;
    m.sigma_in = pf_v3(0.5f, 1.0f, 2.0f); /* version 13: the media on its two sides */
    m.sigma_out = pf_v3(0.0f, 0.125f, 0.0f);
    pf_scene_add_material(s, &m);
    m = pf_material_default("phong");
    m.ks = pf_v3s(0.1f);
    m.ns = 40.0f;
    pf_scene_add_material(s, &m);
    m = pf_material_default("mirror");
    m.type = PF_MAT_MIRROR;
    m.ks = pf_v3s(0.95f);
    pf_scene_add_material(s, &m);
    m = pf_material_default("gold");
    m.type = PF_MAT_CONDUCTOR;
    m.eta = pf_v3(0.143f, 0.374f, 1.442f);
    m.k = pf_v3(3.983f, 2.385f, 1.603f);
    m.alpha = 0.125f;
    pf_scene_add_material(s, &m);
    m = pf_material_default("pane");
    m.type = PF_MAT_THIN_DIELECTRIC;
    m.kd = pf_v3s(0.0f);
    m.ks = pf_v3s(1.0f);
    m.kt = pf_v3(0.8f, 0.9f, 1.0f);
    m.ior = 1.52f;
    pf_scene_add_material(s, &m);
    m = pf_material_default("leaf"); /* version 9: diffuse transmission and mix */
    m.type = PF_MAT_DIFFUSE_TRANSMISSION;
    m.kd = pf_v3(0.2f, 0.5f, 0.1f);
    m.kt = pf_v3(0.6f, 0.4f, 0.3f);
    pf_scene_add_material(s, &m);
    m = pf_material_default("worn");
    m.type = PF_MAT_MIX;
    m.mix[0] = 4;
    m.mix[1] = 6;
    m.amount = 0.3f;
    pf_scene_add_material(s, &m);

    pf_mesh_t quad;
    memset(&quad, 0, sizeof quad);
    snprintf(quad.name, sizeof quad.name, "floor");
    quad.nverts = 4;
    quad.ntris = 2;
    quad.pos = malloc(4 * sizeof *quad.pos);
    quad.nrm = malloc(4 * sizeof *quad.nrm);
    quad.idx = malloc(6 * sizeof *quad.idx);
    quad.mat = malloc(2 * sizeof *quad.mat);
    const pf_vec3 qp[4] = { { -1, 0, -1 }, { 1, 0, -1 }, { 1, 0.1f, 1 }, { -1, 0, 1 } };
    const uint32_t qi[6] = { 0, 2, 1, 0, 3, 2 };
    for (int i = 0; i < 4; i++) {
        quad.pos[i] = qp[i];
        quad.nrm[i] = pf_norm(pf_v3(0.1f * (float)i, 1.0f, 0.3f));
    }
    memcpy(quad.idx, qi, sizeof qi);
    quad.mat[0] = 2;
    quad.mat[1] = 3;
    pf_scene_add_mesh(s, &quad);

    pf_mesh_t tri;
    memset(&tri, 0, sizeof tri);
    snprintf(tri.name, sizeof tri.name, "lamp");
    tri.nverts = 3;
    tri.ntris = 1;
    tri.pos = malloc(3 * sizeof *tri.pos);
    tri.idx = malloc(3 * sizeof *tri.idx);
    tri.mat = malloc(sizeof *tri.mat);
    tri.pos[0] = pf_v3(-0.2f, 2, -0.2f);
    tri.pos[1] = pf_v3(0.2f, 2, -0.2f);
    tri.pos[2] = pf_v3(0, 2, 0.2f);
    tri.idx[0] = 0;
    tri.idx[1] = 1;
    tri.idx[2] = 2;
    tri.mat[0] = 0;
    pf_scene_add_mesh(s, &tri);

    pf_sphere_t sp = { pf_v3(0.2f, 0.5f, -0.1f), 0.4f, 1 };
    pf_scene_add_sphere(s, &sp);
    pf_light_t l = { .type = PF_LIGHT_POINT, .pos = pf_v3(0, 1.9f, 0), .intensity = pf_v3(1, 2, 3) };
    pf_scene_add_light(s, &l);
    l = (pf_light_t){ .type = PF_LIGHT_SPOT, .pos = pf_v3(1, 1.5f, 1), .intensity = pf_v3s(10),
                      .dir = pf_norm(pf_v3(-1, -1, -1)), .cos_inner = 0.95f, .cos_outer = 0.9f };
    pf_scene_add_light(s, &l);
    l = (pf_light_t){ .type = PF_LIGHT_DISTANT, .intensity = pf_v3(3, 2, 1), .dir = pf_norm(pf_v3(0.3f, -1, 0.2f)) };
    pf_scene_add_light(s, &l);
    l = (pf_light_t){ .type = PF_LIGHT_INFINITE, .intensity = pf_v3(0.5f, 0.6f, 0.7f) };
    pf_scene_add_light(s, &l);
    s->camera = (pf_camera_desc_t){ .pos = pf_v3(0, 1, 4), .look_at = pf_v3(0, 0.5f, 0), .up = pf_v3(0, 1, 0),
                                    .vfov_deg = 45.0f, .fov_shorter = 1, .left_handed = 1, .lens_radius = 0.05f,
                                    .focal_distance = 4.25f, .has_window = 1,
                                    .window = { -0.5f, 1.5f, -0.25f, 0.5f }, .frame_aspect = 1.5f };
    s->has_camera = 1;
    pf_error_t err;
    if (pf_scene_finalize(s, &err) != 0) {
        fprintf(stderr, "tiny scene: %s\n", err.msg);
        exit(2);
    }
    return s;
}

static int s_settings_equal(const pf_settings_t *a, const pf_settings_t *b)
{
    return a->width == b->width && a->height == b->height && a->spp == b->spp && a->photons == b->photons &&
           a->caustic_photons == b->caustic_photons && a->gather == b->gather &&
           a->gather_filter == b->gather_filter &&
           a->light_samples == b->light_samples && a->max_depth == b->max_depth &&
           a->photon_max_depth == b->photon_max_depth && a->global_k == b->global_k && a->caustic_k == b->caustic_k &&
           memcmp(&a->caustic_radius, &b->caustic_radius, 4) == 0 &&
           memcmp(&a->global_radius, &b->global_radius, 4) == 0 && a->irradiance_stride == b->irradiance_stride &&
           a->threads == b->threads && a->seed == b->seed && memcmp(&a->exposure, &b->exposure, 4) == 0 &&
           a->path_max_depth == b->path_max_depth;
}

/* The first part in which two scenes differ, or NULL. Structs without
 * padding (vectors, spheres, lights, the material after its name) are
 * compared with memcmp, so the comparison is bit for bit. */
static const char *s_scene_diff(const pf_scene_t *a, const pf_scene_t *b)
{
    if (strcmp(a->path, b->path))
        return "path";
    if (!s_settings_equal(&a->settings, &b->settings))
        return "settings";
    if (a->has_camera != b->has_camera || memcmp(&a->camera, &b->camera, sizeof a->camera))
        return "camera";
    if (a->nmats != b->nmats)
        return "material count";
    const size_t mat_tail = offsetof(pf_material_t, type);
    for (size_t i = 0; i < a->nmats; i++) {
        if (strcmp(a->mats[i].name, b->mats[i].name))
            return "material name";
        if (memcmp((const char *)&a->mats[i] + mat_tail, (const char *)&b->mats[i] + mat_tail,
                   sizeof(pf_material_t) - mat_tail))
            return "material fields";
    }
    if (a->nmeshes != b->nmeshes)
        return "mesh count";
    for (size_t i = 0; i < a->nmeshes; i++) {
        const pf_mesh_t *x = &a->meshes[i], *y = &b->meshes[i];
        if (strcmp(x->name, y->name))
            return "mesh name";
        if (x->nverts != y->nverts || x->ntris != y->ntris)
            return "mesh sizes";
        if (memcmp(x->pos, y->pos, x->nverts * sizeof *x->pos))
            return "mesh positions";
        if (!x->nrm != !y->nrm || (x->nrm && memcmp(x->nrm, y->nrm, x->nverts * sizeof *x->nrm)))
            return "mesh normals";
        if (x->alpha_tex != y->alpha_tex)
            return "mesh alpha";
        if (!x->uv != !y->uv || (x->uv && memcmp(x->uv, y->uv, 2 * x->nverts * sizeof *x->uv)))
            return "mesh uvs";
        if (memcmp(x->idx, y->idx, 3 * x->ntris * sizeof *x->idx))
            return "mesh indices";
        if (memcmp(x->mat, y->mat, x->ntris * sizeof *x->mat))
            return "mesh materials";
    }
    if (a->nspheres != b->nspheres || (a->nspheres && memcmp(a->spheres, b->spheres, a->nspheres * sizeof *a->spheres)))
        return "spheres";
    if (a->nlights != b->nlights || (a->nlights && memcmp(a->lights, b->lights, a->nlights * sizeof *a->lights)))
        return "lights";
    if (a->ntexs != b->ntexs)
        return "texture count";
    for (size_t i = 0; i < a->ntexs; i++) {
        const pf_texture_t *x = &a->texs[i], *y = &b->texs[i];
        size_t n = (size_t)x->width * (size_t)x->height * 3;
        if (strcmp(x->name, y->name) || x->type != y->type || x->su != y->su || x->sv != y->sv || x->du != y->du ||
            x->dv != y->dv || memcmp(x->op, y->op, sizeof x->op) || x->wrap != y->wrap || x->srgb != y->srgb ||
            x->scale != y->scale || x->invert != y->invert || x->width != y->width || x->height != y->height)
            return "texture fields";
        if (!x->px8 != !y->px8 || !x->pxf != !y->pxf || (x->px8 && memcmp(x->px8, y->px8, n)) ||
            (x->pxf && memcmp(x->pxf, y->pxf, n * sizeof *x->pxf)))
            return "texture pixels";
    }
    return NULL;
}

static void s_scene_round_trip(const pf_scene_t *scene, const char *name)
{
    pf_buf_t b = { 0 }, b2 = { 0 };
    CHECK(pf_sceneblob_write(scene, &b) == 0, "%s: write", name);
    pf_error_t err = { "" };
    pf_scene_t *back = pf_sceneblob_read(b.data, b.len, &err);
    CHECK(back != NULL, "%s: read: %s", name, err.msg);
    if (back) {
        const char *diff = s_scene_diff(scene, back);
        CHECK(diff == NULL, "%s: round trip differs in %s", name, diff);
        CHECK(pf_sceneblob_write(back, &b2) == 0 && b2.len == b.len && memcmp(b.data, b2.data, b.len) == 0,
              "%s: re-serialized bytes differ (%zu vs %zu)", name, b2.len, b.len);
        pf_scene_destroy(&back);
    }
    pf_buf_free(&b);
    pf_buf_free(&b2);
}

/* Reads a truncated copy (exactly len bytes, so sanitizers see overreads). */
static int s_scene_truncation_fails(const uint8_t *data, size_t len)
{
    uint8_t *copy = malloc(len ? len : 1);
    memcpy(copy, data, len);
    pf_error_t err = { "" };
    pf_scene_t *s = pf_sceneblob_read(copy, len, &err);
    free(copy);
    if (s) {
        pf_scene_destroy(&s);
        return 0;
    }
    return strncmp(err.msg, "scene blob: ", 12) == 0;
}

/* Offsets of the tiny scene's fields, found by walking the documented layout
 * independently of the reader. */
typedef struct s_offsets {
    size_t reserved, has_camera, fov_shorter, left_handed, lens_radius, focal_distance, has_window, window, frame_aspect, nmats, mat1_type, mat0_name, nmeshes;
    size_t mat4_eta; /* the conductor's eta, k, alpha */
    size_t mat1_kd_tex, mat1_twosided;
    size_t mat7_mix0; /* the mix's first index */
    size_t mesh0_nverts, mesh0_ntris, mesh0_has_nrm, mesh0_has_uv, mesh0_pos, mesh0_idx, mesh0_mat;
    size_t nspheres, sphere0_radius, sphere0_mat, nlights, light0_type, ntexs, end;
} s_offsets_t;

static size_t s_str_len_at(const uint8_t *p) { return (size_t)p[0] | (size_t)p[1] << 8; }

static s_offsets_t s_walk(const uint8_t *d)
{
    s_offsets_t o;
    size_t at = 6;
    o.reserved = at;
    at += 2;
    at += 2 + s_str_len_at(d + at); /* path */
    at += 100;                      /* settings */
    o.has_camera = at;
    at += 1 + 40;
    o.fov_shorter = at;
    o.left_handed = at + 1;
    o.lens_radius = at + 2;
    o.focal_distance = at + 6;
    at += 2 + 8;
    o.has_window = at;
    o.window = at + 1;
    o.frame_aspect = at + 17;
    at += 1 + 16 + 4;
    o.nmats = at;
    uint32_t nm = d[at] | (uint32_t)d[at + 1] << 8;
    at += 4;
    o.mat0_name = at;
    for (uint32_t i = 0; i < nm; i++) {
        at += 2 + s_str_len_at(d + at);
        if (i == 1)
            o.mat1_type = at, o.mat1_twosided = at + 1 + 56,
            o.mat1_kd_tex = at + 1 + 56 + 1 + 28 + 4; /* after twosided, eta, k, alpha, thickness */
        if (i == 4)
            o.mat4_eta = at + 1 + 56 + 1;
        if (i == 7)
            o.mat7_mix0 = at + 1 + 56 + 1 + 28 + 4 + 4; /* after kd_tex */
        at += 1 + 56 + 1 + 36 + 20 + 20 + 4 + 24; /* version 12: twosided after le; version 9: mix0, mix1, amount,
                                                * amount_tex, alpha_tex, then refl_tex, rough_tex, rough_remap,
                                                * normal_tex, bump_tex; version 13: kt_tex, sigma_in, sigma_out */
    }
    o.nmeshes = at;
    uint32_t nmesh = d[at];
    at += 4;
    for (uint32_t i = 0; i < nmesh; i++) {
        at += 2 + s_str_len_at(d + at);
        uint64_t nv = d[at], nt = d[at + 8];
        if (i == 0)
            o.mesh0_nverts = at, o.mesh0_ntris = at + 8, o.mesh0_has_nrm = at + 16, o.mesh0_has_uv = at + 17;
        int has = d[at + 16], has_uv = d[at + 17];
        at += 22; /* and u32 alpha_tex */
        if (i == 0)
            o.mesh0_pos = at;
        at += nv * 12 * (has ? 2 : 1) + nv * 8 * (has_uv ? 1 : 0);
        if (i == 0)
            o.mesh0_idx = at;
        at += nt * 12;
        if (i == 0)
            o.mesh0_mat = at;
        at += nt * 4;
    }
    o.nspheres = at;
    o.sphere0_radius = at + 4 + 12;
    o.sphere0_mat = at + 4 + 16;
    at += 4 + 20 * d[at];
    o.nlights = at;
    o.light0_type = at + 4;
    at += 4 + 49 * d[at];
    o.ntexs = at; /* the tiny scene has none */
    at += 4;
    at += 4; /* no environment maps */
    o.end = at;
    return o;
}

typedef struct s_spatch {
    size_t off;
    int width; /* 1, 2, 4, 8; or -4 for a float */
    uint64_t value;
    float fvalue;
    const char *needle;
    const char *what;
} s_spatch_t;

static void s_scene_patch(const pf_buf_t *b, const s_spatch_t *p)
{
    uint8_t *c = malloc(b->len);
    memcpy(c, b->data, b->len);
    switch (p->width) {
    case 1: c[p->off] = (uint8_t)p->value; break;
    case 2: s_put16(c + p->off, (uint16_t)p->value); break;
    case 4: s_put32(c + p->off, (uint32_t)p->value); break;
    case 8: s_put64(c + p->off, p->value); break;
    default: s_putf(c + p->off, p->fvalue); break;
    }
    pf_error_t err = { "" };
    pf_scene_t *s = pf_sceneblob_read(c, b->len, &err);
    CHECK(s == NULL && strncmp(err.msg, "scene blob: ", 12) == 0 && strstr(err.msg, p->needle) != NULL,
          "%s: got '%s', want '%s'", p->what, err.msg, p->needle);
    /* Counts are refused by the size check, before any allocation. */
    CHECK(strstr(err.msg, "out of memory") == NULL, "%s: '%s'", p->what, err.msg);
    pf_scene_destroy(&s);
    free(c);
}

static void test_scene_blob(void)
{
    pf_scene_t *tiny = s_tiny_scene();
    s_scene_round_trip(tiny, "tiny scene");

    pf_buf_t b = { 0 };
    pf_sceneblob_write(tiny, &b);
    s_offsets_t o = s_walk(b.data);
    CHECK(o.end == b.len, "the layout walk ends at %zu of %zu bytes", o.end, b.len);

    int bad = 0;
    for (size_t len = 0; len < b.len; len++)
        bad += !s_scene_truncation_fails(b.data, len);
    CHECK(bad == 0, "tiny scene: %d of %zu truncations did not fail cleanly", bad, b.len);

    const s_spatch_t patches[] = {
        { 0, 1, 'X', 0, "bad magic", "magic" },
        { 4, 2, 14, 0, "format version 14", "version" },
        { 4, 2, 2, 0, "format version 2, this build reads 13", "version 2 (before the lens)" },
        { 4, 2, 3, 0, "format version 3, this build reads 13", "version 3 (before the conductor)" },
        { 4, 2, 4, 0, "format version 4, this build reads 13", "version 4 (before the thin dielectric)" },
        { 4, 2, 5, 0, "format version 5, this build reads 13", "version 5 (before the distant light)" },
        { 4, 2, 6, 0, "format version 6, this build reads 13", "version 6 (before the coat and the textures)" },
        { 4, 2, 7, 0, "format version 7, this build reads 13", "version 7 (before the environment maps)" },
        { 4, 2, 8, 0, "format version 8, this build reads 13", "version 8 (before mix, diffuse transmission, maps and the path-length limit)" },
        { 4, 2, 10, 0, "format version 10, this build reads 13", "version 10 (before the screen window)" },
        { 4, 2, 11, 0, "format version 11, this build reads 13", "version 11 (before two-sided emission)" },
        { 4, 2, 12, 0, "format version 12, this build reads 13", "version 12 (before kt_tex and the media)" },
        { o.reserved, 2, 1, 0, "reserved", "reserved field" },
        { o.has_camera, 1, 2, 0, "has_camera", "has_camera 2" },
        { o.has_camera + 1, -4, 0, NAN, "camera pos is not a finite number", "camera NaN" },
        { o.fov_shorter, 1, 2, 0, "camera fov_shorter is 2, not 0 or 1", "fov_shorter 2" },
        { o.left_handed, 1, 255, 0, "camera left_handed is 255, not 0 or 1", "left_handed 255" },
        { o.lens_radius, -4, 0, -0.5f, "camera lens_radius is -0.5, not >= 0", "negative lens radius" },
        { o.lens_radius, -4, 0, NAN, "camera lens_radius is not a finite number", "NaN lens radius" },
        { o.lens_radius, -4, 0, INFINITY, "camera lens_radius is not a finite number", "infinite lens radius" },
        { o.focal_distance, -4, 0, 0.0f, "camera focal_distance is 0, not > 0 with a lens", "focal distance 0" },
        { o.focal_distance, -4, 0, -2.0f, "camera focal_distance is -2, not > 0 with a lens", "negative focus" },
        { o.focal_distance, -4, 0, INFINITY, "camera focal_distance is not a finite number", "infinite focus" },
        { o.has_window, 1, 2, 0, "camera has_window is 2, not 0 or 1", "has_window 2" },
        { o.mat1_twosided, 1, 2, 0, "twosided must be 0 or 1", "material twosided 2 (finalize)" },
        { o.window + 4, -4, 0, NAN, "camera window is not a finite number", "NaN window" },
        { o.window + 4, -4, 0, -0.75f, "screen window [-0.5 -0.75 -0.25 0.5] (has_window 1) must lie", "xmax < xmin (finalize)" },
        { o.window + 12, -4, 0, 2e6f, "must lie within +-1e6", "window beyond 1e6 (finalize)" },
        { o.frame_aspect, -4, 0, -1.0f, "frame aspect -1 must be 0 or in [1e-6, 1e6]", "negative frame aspect (finalize)" },
        { o.lens_radius, -4, 0, 2e18f, "lens radius 2e+18 must be >= 0 and at most 1e18", "lens 2e18 (finalize)" },
        { o.nmats, 4, 0xffffffffu, 0, "materials need at least", "material count 2^32-1" },
        { o.nmats, 4, 7, 0, "", "material count one too many" },
        { o.mat0_name, 2, 64, 0, "name is 64 bytes", "material name too long" },
        { o.mat0_name + 2, 1, 0, 0, "NUL", "material name with a NUL" },
        { o.mat1_type, 1, 8, 0, "material 1 type 8", "material type" },
        { o.mat1_type, 1, 8, 0, "material 1 type 8 is not a material type (0..7)", "material type 8" },
        { o.mat1_type, 1, 6, 0, "diffuse transmission needs", "glass as diffuse transmission (kd + kt > 1)" },
        { o.mat7_mix0, 4, 99, 0, "mix of materials 99 and 6, out of range", "mix index (finalize)" },
        { o.mat1_type + 1, -4, 0, INFINITY, "material 1 kd is not a finite number", "material inf" },
        { o.mat4_eta, -4, 0, -1.0f, "material 4 conductor needs eta > 0", "conductor eta -1" },
        { o.mat4_eta + 12, -4, 0, -0.5f, "material 4 conductor needs eta > 0", "conductor k -0.5" },
        { o.mat4_eta + 24, -4, 0, 1.5f, "material 4 conductor needs eta > 0", "conductor alpha 1.5" },
        { o.mat4_eta + 24, -4, 0, NAN, "material 4 alpha is not a finite number", "conductor alpha NaN" },
        { o.nmeshes, 4, 0xffffffffu, 0, "meshes need at least", "mesh count" },
        { o.mesh0_nverts, 8, 1ull << 40, 0, "vertices need at least", "2^40 vertices" },
        { o.mesh0_nverts, 8, UINT64_MAX, 0, "vertices need at least", "2^64-1 vertices" },
        { o.mesh0_ntris, 8, 1ull << 40, 0, "triangles do not fit", "2^40 triangles" },
        { o.mesh0_ntris, 8, UINT64_MAX / 4, 0, "triangles do not fit", "2^62 triangles" },
        { o.mesh0_has_nrm, 1, 3, 0, "has_normals", "has_normals 3" },
        { o.mesh0_has_uv, 1, 2, 0, "has_uv 2", "has_uv 2" },
        { o.mat1_kd_tex, 4, 1, 0, "texture 1 out of range (0 textures)", "kd_tex without textures (finalize)" },
        { o.mat1_kd_tex + 16, 4, 1, 0, "texture 1 out of range (0 textures)", "normal_tex without textures (finalize)" },
        { o.mat1_kd_tex + 20, 4, 2, 0, "texture 2 out of range (0 textures)", "bump_tex without textures (finalize)" },
        { o.mat1_kd_tex + 44, 4, 3, 0, "texture 3 out of range (0 textures)", "kt_tex without textures (finalize)" },
        { o.mat1_kd_tex + 52, -4, 0, -0.5f, "a medium's absorption must be >= 0", "negative sigma_in (finalize)" },
        { o.mat1_kd_tex + 68, -4, 0, -1.0f, "a medium's absorption must be >= 0", "negative sigma_out (finalize)" },
        { o.mat1_kd_tex + 48, -4, 0, NAN, "material 1 sigma_in is not a finite number", "NaN sigma_in" },
        { o.ntexs, 4, 0x10000000u, 0, "textures need at least", "texture count" },
        { o.mesh0_pos + 4, -4, 0, NAN, "positions is not a finite", "NaN position" },
        { o.mesh0_idx + 4, 4, 4, 0, "vertex index 4 is out of range", "vertex index" },
        { o.mesh0_mat + 4, 4, 8, 0, "material index 8 is out of range", "triangle material" },
        { o.nspheres, 4, 0x7fffffffu, 0, "spheres need at least", "sphere count" },
        { o.sphere0_radius, -4, 0, 0.0f, "sphere 0: centre must be finite and radius > 0", "radius 0 (finalize)" },
        { o.sphere0_mat, 4, 9, 0, "sphere 0 material index 9", "sphere material" },
        { o.nlights, 4, 0x10000000u, 0, "lights need at least", "light count" },
        { o.light0_type, 1, 5, 0, "light 0 type 5 is not a light type (0..3)", "light type" },
        { o.light0_type + 45, 4, 1, 0, "environment map 1 does not exist (0 maps)", "light map index" },
        { o.end - 4, 4, 0x10000000u, 0, "envmaps need at least", "envmap count" },
    };
    for (size_t i = 0; i < sizeof patches / sizeof patches[0]; i++)
        s_scene_patch(&b, &patches[i]);

    /* One trailing byte. */
    uint8_t *c = malloc(b.len + 1);
    memcpy(c, b.data, b.len);
    c[b.len] = 0;
    pf_error_t err = { "" };
    pf_scene_t *s = pf_sceneblob_read(c, b.len + 1, &err);
    CHECK(s == NULL && strstr(err.msg, "1 trailing bytes"), "trailing byte: '%s'", err.msg);
    pf_scene_destroy(&s);
    free(c);
    CHECK(pf_sceneblob_read(NULL, 0, &err) == NULL, "NULL blob");
    CHECK(pf_sceneblob_read(b.data, b.len - 1, NULL) == NULL, "err may be NULL");
    pf_buf_free(&b);

    /* A scene without a camera of its own gets one framed by finalize; the
     * blob carries it, so the worker's camera is the coordinator's. */
    tiny->has_camera = 0;
    pf_sceneblob_write(tiny, &b);
    s = pf_sceneblob_read(b.data, b.len, &err);
    CHECK(s && s->has_camera == 1, "has_camera 0 is framed on read");
    CHECK(s && s->camera.lens_radius == 0.0f && s->camera.focal_distance == 0.0f && !s->camera.fov_shorter &&
              !s->camera.left_handed,
          "the framed camera is a pinhole (lens 0, focal distance 0 read back)");
    pf_scene_destroy(&s);
    pf_buf_free(&b);
    pf_scene_destroy(&tiny);

    /* The shipped demo scene: meshes from OBJ with normals, glass, mirror. */
    pf_scene_t *cs = pf_scene_load("scenes/cornell-spheres/scene.json", &err);
    CHECK(cs != NULL, "load cornell-spheres: %s", err.msg);
    if (!cs)
        return;
    s_scene_round_trip(cs, "cornell-spheres");
    pf_sceneblob_write(cs, &b);
    bad = 0;
    size_t tried = 0;
    for (size_t len = 0; len < b.len; len += (len < 400 ? 1 : 1 + b.len / 300), tried++)
        bad += !s_scene_truncation_fails(b.data, len);
    bad += !s_scene_truncation_fails(b.data, b.len - 1);
    CHECK(bad == 0, "cornell-spheres: %d of %zu truncations did not fail cleanly", bad, tried + 1);
    pf_buf_free(&b);
    pf_scene_destroy(&cs);
}

/* ================= photon-map blob ================= */

#define S_HDR 188
#define S_HASH_AT 180

static pf_kdtree_t *s_random_tree(size_t n)
{
    pf_photon_t *ph = malloc((n ? n : 1) * sizeof *ph);
    for (size_t i = 0; i < n; i++) {
        for (int k = 0; k < 3; k++) {
            ph[i].pos[k] = s_uniform() * 10.0f - 5.0f;
            ph[i].power[k] = s_uniform() * 1e-3f;
        }
        ph[i].dir = (uint32_t)s_next();
        ph[i].normal = (uint32_t)s_next();
    }
    return pf_kdtree_build(&ph, n);
}

static pf_photon_maps_t s_random_maps(size_t ng, size_t nc, size_t ni)
{
    pf_photon_maps_t m;
    memset(&m, 0, sizeof m);
    m.global = s_random_tree(ng);
    m.caustic = s_random_tree(nc);
    m.irradiance = s_random_tree(ni);
    m.global_emitted = 400000;
    m.caustic_emitted = 123457;
    m.global_r2 = 0.0324f;
    m.caustic_r2 = 0.000324f;
    m.irradiance_r2 = 0.0325f;
    return m;
}

static const char *s_maps_diff(const pf_photon_maps_t *a, const pf_photon_maps_t *b)
{
    if (a->global_emitted != b->global_emitted || a->caustic_emitted != b->caustic_emitted)
        return "emitted";
    if (memcmp(&a->global_r2, &b->global_r2, 4) || memcmp(&a->caustic_r2, &b->caustic_r2, 4) ||
        memcmp(&a->irradiance_r2, &b->irradiance_r2, 4))
        return "radii";
    const pf_kdtree_t *ta[3] = { a->global, a->caustic, a->irradiance };
    const pf_kdtree_t *tb[3] = { b->global, b->caustic, b->irradiance };
    if (!a->irradiance_deep != !b->irradiance_deep)
        return "deep irradiance present in one only";
    for (int m = 0; m < 3; m++) {
        if (!tb[m])
            return "missing tree";
        size_t n = pf_kdtree_size(ta[m]);
        if (pf_kdtree_size(tb[m]) != n)
            return "tree size";
        if (n && memcmp(pf_kdtree_photons(ta[m]), pf_kdtree_photons(tb[m]), n * sizeof(pf_photon_t)))
            return "photons";
        pf_vec3 l1, h1, l2, h2;
        pf_kdtree_bounds(ta[m], &l1, &h1);
        pf_kdtree_bounds(tb[m], &l2, &h2);
        if (n && (memcmp(&l1, &l2, sizeof l1) || memcmp(&h1, &h2, sizeof h1)))
            return "bounds";
    }
    return NULL;
}

static void s_rehash(uint8_t *d, size_t len)
{
    uint64_t h = pf_hash_bytes(PF_HASH_INIT, d, S_HASH_AT);
    h = pf_hash_bytes(h, d + S_HDR, len - S_HDR);
    s_put64(d + S_HASH_AT, h);
}

typedef struct s_mpatch {
    size_t off;
    int width; /* 1, 2, 4, 8, or -4 for a float */
    uint64_t value;
    float fvalue;
    int rehash;
    int rc;
    const char *needle;
    const char *what;
} s_mpatch_t;

static void s_map_patch(const pf_buf_t *b, const s_mpatch_t *p, uint64_t sh, uint64_t th)
{
    uint8_t *c = malloc(b->len);
    memcpy(c, b->data, b->len);
    switch (p->width) {
    case 1: c[p->off] = (uint8_t)p->value; break;
    case 2: s_put16(c + p->off, (uint16_t)p->value); break;
    case 4: s_put32(c + p->off, (uint32_t)p->value); break;
    case 8: s_put64(c + p->off, p->value); break;
    default: s_putf(c + p->off, p->fvalue); break;
    }
    if (p->rehash)
        s_rehash(c, b->len);
    pf_photon_maps_t m;
    pf_error_t err = { "" };
    int rc = pf_mapfile_read(c, b->len, sh, th, &m, &err);
    CHECK(rc == p->rc && strncmp(err.msg, "photon-map blob: ", 17) == 0 && strstr(err.msg, p->needle),
          "%s: rc %d (want %d), '%s' (want '%s')", p->what, rc, p->rc, err.msg, p->needle);
    CHECK(m.global == NULL && m.caustic == NULL && m.irradiance == NULL, "%s: maps left empty", p->what);
    free(c);
}

/* The round trip: equal photon arrays, bounds and parameters, the same bytes
 * written again, the same answers from the rebuilt tree; the hash checks. */
static void s_map_round_trip(const pf_photon_maps_t *maps, const pf_buf_t *b, uint64_t sh, uint64_t th)
{
    pf_photon_maps_t back;
    pf_error_t err = { "" };
    int rc = pf_mapfile_read(b->data, b->len, sh, th, &back, &err);
    CHECK(rc == 0, "read: %s", err.msg);
    if (rc == 0) {
        const char *diff = s_maps_diff(maps, &back);
        CHECK(diff == NULL, "round trip differs in %s", diff);
        pf_buf_t b2 = { 0 };
        CHECK(pf_mapfile_write(&back, sh, th, &b2) == 0 && b2.len == b->len &&
                  memcmp(b->data, b2.data, b->len) == 0,
              "re-written bytes differ");
        pf_buf_free(&b2);
        /* The rebuilt tree answers queries like the original. */
        pf_knn_t k1[8], k2[8];
        size_t n1 = pf_kdtree_knn(maps->global, pf_v3(0.5f, -1, 2), 8, INFINITY, k1);
        size_t n2 = pf_kdtree_knn(back.global, pf_v3(0.5f, -1, 2), 8, INFINITY, k2);
        CHECK(n1 == 8 && n2 == 8 && memcmp(k1, k2, sizeof k1) == 0, "knn on the rebuilt tree");
        pf_photon_maps_free(&back);
    }
    CHECK(pf_mapfile_read(b->data, b->len, 0, 0, &back, &err) == 0, "0 skips the hash checks: %s", err.msg);
    pf_photon_maps_free(&back);
    CHECK(pf_mapfile_read(b->data, b->len, sh + 1, th, &back, &err) == PF_EMISMATCH &&
              strstr(err.msg, "scene hash"),
          "wrong scene: '%s'", err.msg);
    CHECK(pf_mapfile_read(b->data, b->len, sh, th + 1, &back, &err) == PF_EMISMATCH &&
              strstr(err.msg, "settings hash"),
          "wrong settings: '%s'", err.msg);
}

/* Each header field and each photon check, by a patch to the blob b. */
static void s_map_patches(const pf_buf_t *b, uint64_t sh, uint64_t th)
{
    /* Header: magic 0, version 4, record 6, scene 8, settings 16, emitted 24
     * and 32, radii 40/44/48, maps at 52 (count, lo, hi; 32 bytes each:
     * global, caustic, irradiance, deep irradiance), content hash 180. */
    const size_t g = 52, c = 84, ir = 116, dp = 148;
    const s_mpatch_t patches[] = {
        { 0, 1, 'X', 0, 0, PF_EPARSE, "bad magic", "magic" },
        { 4, 2, 2, 0, 0, PF_EMISMATCH, "format version 2", "version 2 (before the bounce counts)" },
        { 4, 2, 3, 0, 0, PF_EMISMATCH, "format version 3", "version 3 (before the deep irradiance map)" },
        { 4, 2, 4, 0, 0, PF_EMISMATCH, "format version 4", "version 4 (before the points' direct share)" },
        { 4, 2, 6, 0, 0, PF_EMISMATCH, "format version 6", "version" },
        { 6, 2, 40, 0, 0, PF_EMISMATCH, "photon record size 40", "record size" },
        { 8, 1, 0, 0, 0, PF_EMISMATCH, "scene hash", "scene hash" },
        { 16, 1, 0, 0, 0, PF_EMISMATCH, "settings hash", "settings hash" },
        { 24, 1, 0x55, 0, 0, PF_EPARSE, "content hash", "global_emitted (caught by the hash)" },
        { 32, 1, 0x55, 0, 0, PF_EPARSE, "content hash", "caustic_emitted (caught by the hash)" },
        { 40, -4, 0, NAN, 0, PF_EPARSE, "global_r2 nan", "global_r2 NaN" },
        { 44, -4, 0, 0.0f, 0, PF_EPARSE, "caustic_r2 0 must be", "caustic_r2 0" },
        { 48, -4, 0, -1.0f, 0, PF_EPARSE, "irradiance_r2 -1", "irradiance_r2 < 0" },
        { 44, -4, 0, 0.001f, 0, PF_EPARSE, "content hash", "caustic_r2 changed in range" },
        { g, 8, 301, 0, 0, PF_EPARSE, "counts (global 301, caustic 0, irradiance 75, deep irradiance 0) need 12032 bytes", "global count + 1" },
        { g, 8, 299, 0, 0, PF_EPARSE, "need 11968 bytes after the header, but the blob has 12000", "global count - 1" },
        { g, 8, 1ull << 31, 0, 0, PF_EPARSE, "global count 2147483648 is over the kd-tree limit", "count 2^31" },
        { g, 8, UINT64_MAX, 0, 0, PF_EPARSE, "over the kd-tree limit", "count 2^64-1" },
        { c, 8, 1, 0, 0, PF_EPARSE, "caustic 1,", "caustic count 1" },
        { ir, 8, 1000000, 0, 0, PF_EPARSE, "irradiance 1000000,", "irradiance count" },
        { dp, 8, 2, 0, 0, PF_EPARSE, "deep irradiance 2)", "deep irradiance count" },
        { g + 8, -4, 0, INFINITY, 0, PF_EPARSE, "global bounds on x are not finite", "bounds inf" },
        { c + 8 + 12, -4, 0, NAN, 0, PF_EPARSE, "caustic bounds on x are not finite", "empty map's bounds NaN" },
        { ir + 8 + 4, -4, 0, 1e9f, 0, PF_EPARSE, "irradiance bounds on y are empty", "bounds lo > hi" },
        { ir + 8 + 4, -4, 0, 1e9f, 1, PF_EPARSE, "irradiance bounds on y are empty", "bounds lo > hi, rehashed" },
        { g + 8 + 12, -4, 0, 0.0f, 1, PF_EPARSE, "outside the stated bounds", "bounds too tight" },
        { S_HASH_AT, 1, 0, 0, 0, PF_EPARSE, "content hash", "hash flipped" },
        { S_HDR + 100, 1, 0xff, 0, 0, PF_EPARSE, "content hash", "body byte flipped" },
        /* Behind the hash (re-hashed): each photon check. */
        { S_HDR, -4, 0, NAN, 1, PF_EPARSE, "global photon 0: position x is not finite", "NaN position" },
        { S_HDR + 32 * 3 + 4, -4, 0, 1e6f, 1, PF_EPARSE, "global photon 3: position y 1e+06 is outside",
          "position outside the bounds" },
        { S_HDR + 300 * 32 + 32 * 2 + 16, -4, 0, -1.0f, 1, PF_EPARSE, "irradiance photon 2: power g -1",
          "negative power" },
        { S_HDR + 300 * 32 + 32 * 2 + 12, -4, 0, INFINITY, 1, PF_EPARSE, "irradiance photon 2: power r inf",
          "infinite power" },
        /* Photon 5's normal field (record offset 28): code 0 with both axis
         * bits (0 and 16) set. */
        { S_HDR + 32 * 5 + 28, 4, 0x00010001u, 0, 1, PF_EPARSE, "global photon 5: split axis 3", "axis 3" },
    };
    for (size_t i = 0; i < sizeof patches / sizeof patches[0]; i++)
        s_map_patch(b, &patches[i], sh, th);
}

/* Records out of kd order, and a trailing byte, both re-hashed. */
static void s_map_order_and_trailing(const pf_buf_t *b, uint64_t sh, uint64_t th)
{
    pf_error_t err = { "" };
    int rc;
    /* The kd order: swap the records of the root and the first photon. */
    {
        uint8_t *d = malloc(b->len);
        memcpy(d, b->data, b->len);
        uint8_t tmp[32];
        uint8_t *p0 = d + S_HDR, *pr = d + S_HDR + 150 * 32;
        memcpy(tmp, p0, 32);
        memcpy(p0, pr, 32);
        memcpy(pr, tmp, 32);
        s_rehash(d, b->len);
        pf_photon_maps_t m;
        rc = pf_mapfile_read(d, b->len, sh, th, &m, &err);
        CHECK(rc == PF_EPARSE && strstr(err.msg, "global map's photons are not in kd-tree order"), "kd order: '%s'",
              err.msg);
        free(d);
    }
    /* A trailing byte, even re-hashed: the counts do not account for it. */
    {
        uint8_t *d = malloc(b->len + 1);
        memcpy(d, b->data, b->len);
        d[b->len] = 0;
        s_rehash(d, b->len + 1);
        pf_photon_maps_t m;
        rc = pf_mapfile_read(d, b->len + 1, sh, th, &m, &err);
        CHECK(rc == PF_EPARSE && strstr(err.msg, "but the blob has 12001"), "trailing: '%s'", err.msg);
        free(d);
    }
}

/* Every truncation of a small blob. */
static void s_map_truncations(uint64_t sh, uint64_t th)
{
    pf_photon_maps_t maps = s_random_maps(40, 7, 10);
    pf_buf_t b = { 0 };
    pf_error_t err = { "" };
    pf_mapfile_write(&maps, sh, th, &b);
    int bad = 0;
    for (size_t len = 0; len < b.len; len++) {
        uint8_t *d = malloc(len ? len : 1);
        memcpy(d, b.data, len);
        pf_photon_maps_t m;
        err.msg[0] = '\0';
        int rc = pf_mapfile_read(d, len, sh, th, &m, &err);
        if (rc == 0 || strncmp(err.msg, "photon-map blob: ", 17) != 0 || m.global)
            bad++;
        pf_photon_maps_free(&m);
        free(d);
    }
    CHECK(bad == 0, "%d of %zu truncations did not fail cleanly", bad, b.len);
    pf_buf_free(&b);
    pf_photon_maps_free(&maps);
}

/* All maps empty; and a missing (NULL) tree travels as an empty one. */
static void s_map_empty(uint64_t sh, uint64_t th)
{
    pf_photon_maps_t maps = s_random_maps(0, 0, 0), back;
    pf_buf_t b = { 0 };
    pf_error_t err = { "" };
    pf_kdtree_destroy(&maps.caustic);
    CHECK(pf_mapfile_write(&maps, sh, th, &b) == 0 && b.len == S_HDR, "empty maps write");
    int rc = pf_mapfile_read(b.data, b.len, sh, th, &back, &err);
    CHECK(rc == 0 && back.global && back.caustic && back.irradiance && pf_kdtree_size(back.global) == 0 &&
              pf_kdtree_size(back.caustic) == 0 && pf_kdtree_size(back.irradiance) == 0,
          "empty maps read back: %s", err.msg);
    pf_photon_maps_free(&back);
    pf_buf_free(&b);
    pf_photon_maps_free(&maps);
}

/* The deep gathers' points (format 4) travel as a fourth map: they come
 * back bit for bit, and a blob without them reads as none (NULL). */
static void s_map_deep(uint64_t sh, uint64_t th)
{
    pf_photon_maps_t maps = s_random_maps(200, 10, 50), back;
    maps.irradiance_deep = s_random_tree(50);
    pf_buf_t b = { 0 };
    pf_error_t err = { "" };
    CHECK(pf_mapfile_write(&maps, sh, th, &b) == 0 && b.len == S_HDR + 310 * 32, "deep: size %zu", b.len);
    int rc = pf_mapfile_read(b.data, b.len, sh, th, &back, &err);
    CHECK(rc == 0 && s_maps_diff(&maps, &back) == NULL && back.irradiance_deep &&
              pf_kdtree_size(back.irradiance_deep) == 50 &&
              memcmp(pf_kdtree_photons(back.irradiance_deep), pf_kdtree_photons(maps.irradiance_deep),
                     50 * sizeof(pf_photon_t)) == 0,
          "deep round trip: %s", err.msg);
    pf_photon_maps_free(&back);
    /* A photon of the deep map out of its bounds is caught like any other. */
    const float far = 1e6f;
    memcpy(b.data + S_HDR + 260 * 32, &far, 4);
    s_rehash(b.data, b.len);
    CHECK(pf_mapfile_read(b.data, b.len, sh, th, &back, &err) == PF_EPARSE && strstr(err.msg, "deep irradiance photon"),
          "deep photon patched: '%s'", err.msg);
    pf_buf_free(&b);
    pf_kdtree_destroy(&maps.irradiance_deep);
    CHECK(pf_mapfile_write(&maps, sh, th, &b) == 0, "no deep: write");
    rc = pf_mapfile_read(b.data, b.len, sh, th, &back, &err);
    CHECK(rc == 0 && back.irradiance_deep == NULL, "no deep map reads as none: %s", err.msg);
    pf_photon_maps_free(&back);
    pf_buf_free(&b);
    pf_photon_maps_free(&maps);
}

/* A larger set, for the timing of the per-photon path. */
static void s_map_timing(uint64_t sh, uint64_t th)
{
    pf_photon_maps_t maps = s_random_maps(100000, 20000, 25000), back;
    pf_buf_t b = { 0 };
    pf_error_t err = { "" };
    double t0 = pf_now();
    pf_mapfile_write(&maps, sh, th, &b);
    int rc = pf_mapfile_read(b.data, b.len, sh, th, &back, &err);
    double dt = pf_now() - t0;
    CHECK(rc == 0 && s_maps_diff(&maps, &back) == NULL, "145k photons round trip: %s", err.msg);
    printf("145000 photons: write + read %.1f ms (%zu bytes)\n", dt * 1e3, b.len);
    pf_photon_maps_free(&back);
    pf_buf_free(&b);
    pf_photon_maps_free(&maps);
}

static void test_map_blob(void)
{
    const uint64_t sh = 0x5ce4e5ce4e5ce4e5ULL, th = 0x5e7715e7715e7715ULL;
    /* The caustic map is empty, as in a scene without mirror or glass. */
    pf_photon_maps_t maps = s_random_maps(300, 0, 75);
    pf_buf_t b = { 0 };
    CHECK(pf_mapfile_write(&maps, sh, th, &b) == 0, "write");
    CHECK(b.len == S_HDR + 375 * 32, "size %zu", b.len);
    s_map_round_trip(&maps, &b, sh, th);
    s_map_patches(&b, sh, th);
    s_map_deep(sh, th);
    s_map_order_and_trailing(&b, sh, th);
    pf_buf_free(&b);
    pf_photon_maps_free(&maps);
    s_map_truncations(sh, th);
    s_map_empty(sh, th);
    s_map_timing(sh, th);
}

static void test_settings_hash(void)
{
    const pf_settings_t base = pf_settings_default();
    uint64_t h0 = pf_settings_hash(&base);
    pf_settings_t s = base;
    CHECK(pf_settings_hash(&s) == h0, "deterministic");
    /* Every photon-relevant field changes the hash. */
    const char *names[10] = { "photons", "caustic_photons", "photon_max_depth", "global_k", "caustic_k",
                              "caustic_radius", "global_radius", "irradiance_stride", "seed", "path_max_depth" };
    for (int f = 0; f < 10; f++) {
        s = base;
        switch (f) {
        case 0: s.photons++; break;
        case 1: s.caustic_photons++; break;
        case 2: s.photon_max_depth++; break;
        case 3: s.global_k++; break;
        case 4: s.caustic_k++; break;
        case 5: s.caustic_radius = 0.01f; break;
        case 6: s.global_radius = 0.01f; break;
        case 7: s.irradiance_stride++; break;
        case 8: s.seed ^= 1ull << 63; break;
        case 9: s.path_max_depth = 3; break;
        }
        CHECK(pf_settings_hash(&s) != h0, "%s must change the settings hash", names[f]);
    }
    /* The others do not: the same maps serve any image size or sampling. */
    s = base;
    s.width = 17;
    s.height = 9;
    s.spp = 64;
    s.gather = 0;
    s.gather_filter = 5;
    s.light_samples = 4;
    s.max_depth = 3;
    s.threads = 7;
    s.exposure = 2.0f;
    CHECK(pf_settings_hash(&s) == h0, "render-only settings must not change the hash");
    s = base;
    s.caustic_radius = -0.0f;
    CHECK(pf_settings_hash(&s) == h0, "-0 and +0 radius are the same setting");
}

int main(void)
{
    pf_log_set_level(PF_LOG_ERROR);
    test_scene_blob();
    test_map_blob();
    test_settings_hash();
    printf("%d passed, %d failed\n", s_passed, s_failed);
    return s_failed ? 1 : 0;
}
