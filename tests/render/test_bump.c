/* test_bump.c: normal maps, bump maps and textured roughness/reflectance
 * (accel/shading.h, accel/surface.h), end to end.
 * (a) a flat quad whose normal map encodes a constant 30-degree tilt,
 *     lit by a distant light alone (direct term), shades exactly as the
 *     same quad (same positions) whose vertex normals carry that tilt, and
 *     both as kd / pi * E * cos(tilted normal, light);
 * (b) a bump map of linear ramp h = s u gives the analytic normal of the
 *     height field (unit, at several points of both triangles, with and
 *     without vertex normals);
 * (c) a conductor whose roughness (and, separately, reflectance) is a
 *     constant texture renders bit for bit as the untextured one;
 * (d) a normal map of random grazing and below-horizon normals plus a steep
 *     bump map: no NaN or inf anywhere, no black pixels on the quad under a
 *     uniform sky, and the bent normals stay above the horizon;
 * plus an OBJ + MTL with bump -bm and norm read into bump_tex (scale = the
 * multiplier) and normal_tex, and the scene blob round trip of the slots. */
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <unistd.h>

#include <stb_image_write.h>

#include "accel/accel.h"
#include "accel/shading.h"
#include "accel/surface.h"
#include "base/log.h"
#include "base/wire.h"
#include "coordinator/job.h"
#include "image/image.h"
#include "load/load.h"
#include "mesh/mesh.h"
#include "proto/sceneblob.h"
#include "render/render.h"
#include "scene/scene.h"
#include "scene/texture.h"

#include "check.h"

static char s_dir[256];

/* The quad y = 0, x and z in [-1, 1], facing +y; uv (0,0) at (-1, 0, 1),
 * u along +x, v along -z (so dpdu = (2,0,0), dpdv = (0,0,-2)); vertex
 * normals nrm (all four alike) when nrm is not NULL. */
static void s_add_quad(pf_scene_t *sc, uint32_t mat, const pf_vec3 *nrm)
{
    pf_mesh_t me = { 0 };
    snprintf(me.name, sizeof me.name, "quad");
    me.nverts = 4;
    me.ntris = 2;
    me.pos = malloc(4 * sizeof *me.pos);
    me.uv = malloc(8 * sizeof *me.uv);
    me.idx = malloc(6 * sizeof *me.idx);
    me.mat = malloc(2 * sizeof *me.mat);
    pf_vec3 p[4] = { { -1, 0, 1 }, { 1, 0, 1 }, { 1, 0, -1 }, { -1, 0, -1 } };
    float uv[8] = { 0, 0, 1, 0, 1, 1, 0, 1 };
    uint32_t idx[6] = { 0, 1, 2, 0, 2, 3 };
    memcpy(me.pos, p, sizeof p);
    memcpy(me.uv, uv, sizeof uv);
    memcpy(me.idx, idx, sizeof idx);
    me.mat[0] = me.mat[1] = mat;
    if (nrm) {
        me.nrm = malloc(4 * sizeof *me.nrm);
        for (int i = 0; i < 4; i++)
            me.nrm[i] = *nrm;
    }
    CHECK(pf_scene_add_mesh(sc, &me) == PF_OK);
}

static void s_top_camera(pf_scene_t *sc)
{
    sc->camera = (pf_camera_desc_t){ .pos = { 0, 10, 0 }, .look_at = { 0, 0, 0 }, .up = { 0, 0, -1 },
                                     .vfov_deg = 10.0f };
    sc->has_camera = 1;
}

static int s_render(pf_scene_t *sc, int size, unsigned terms, pf_image_t *img)
{
    pf_error_t err = { { 0 } };
    if (pf_scene_finalize(sc, &err) != PF_OK) {
        CHECK(0, "finalize: %s", err.msg);
        return 0;
    }
    pf_settings_t s = sc->settings;
    s.width = s.height = size;
    s.spp = 2;
    s.photons = 4000;
    s.caustic_photons = 2000;
    s.gather = 8;
    s.threads = 0;
    pf_job_summary_t sum;
    int rc = pf_job_render_local(sc, &s, terms, 0, img, &sum, &err);
    CHECK(rc == PF_OK, "render: %s", err.msg);
    return rc == PF_OK;
}

/* Mean of the centre (size/2 square) of img. */
static pf_vec3 s_centre(const pf_image_t *img)
{
    int w = img->width, q = w / 4, n = 0;
    pf_vec3 s = pf_v3s(0);
    for (int y = q; y < w - q; y++)
        for (int x = q; x < w - q; x++, n++) {
            const float *p = &img->rgb[3 * (y * w + x)];
            s = pf_add(s, pf_v3(p[0], p[1], p[2]));
        }
    return pf_scale(s, 1.0f / (float)n);
}

/* ---- (a) ---- */

/* The quad under a distant light arriving from L (towards the light) at
 * irradiance E, kd 0.5, bent by a constant normal map (map 1) or by its
 * vertex normals (map 0) to n (or neither, n NULL); the centre's mean. */
static pf_vec3 s_tilt_render(int map, const pf_vec3 *n, pf_vec3 L, float E)
{
    pf_scene_t *sc = pf_scene_create();
    pf_material_t m = pf_material_default("m");
    m.kd = pf_v3s(0.5f);
    if (map) {
        /* local (t = dpdu = +x, b = n x t = -z, n = +y): l = (n.x, -n.z, n.y) */
        pf_vec3 l = pf_v3(n->x, -n->z, n->y);
        pf_texture_t t = pf_texture_constant("tilt", pf_scale(pf_add(l, pf_v3s(1.0f)), 0.5f));
        m.normal_tex = (uint32_t)pf_scene_add_texture(sc, &t);
    }
    uint32_t mi = (uint32_t)pf_scene_add_material(sc, &m);
    s_add_quad(sc, mi, map ? NULL : n);
    pf_light_t l = { .type = PF_LIGHT_DISTANT, .dir = pf_neg(L), .intensity = pf_v3s(E) };
    pf_scene_add_light(sc, &l);
    s_top_camera(sc);
    pf_image_t img = { 0 };
    pf_vec3 c = pf_v3s(-1.0f);
    if (s_render(sc, 32, PF_TERM_DIRECT, &img))
        c = s_centre(&img);
    pf_image_free(&img);
    pf_scene_destroy(&sc);
    return c;
}

static void s_test_normal_map_tilt(void)
{
    const float tilt = 30.0f * PF_PI / 180.0f, phi = 10.0f * PF_PI / 180.0f, E = 2.0f;
    pf_vec3 n = pf_v3(sinf(tilt), cosf(tilt), 0.0f);
    pf_vec3 L = pf_v3(-sinf(phi), cosf(phi), 0.0f); /* 40 degrees from n, 10 from the geometric normal */
    float want = 0.5f / PF_PI * E * pf_dot(n, L), flat = 0.5f / PF_PI * E * cosf(phi);
    pf_vec3 a = s_tilt_render(1, &n, L, E), b = s_tilt_render(0, &n, L, E);
    pf_vec3 f = s_tilt_render(0, NULL, L, E);
    printf("(a) normal map %.6f, vertex normals %.6f, analytic %.6f (untilted %.6f, rendered %.6f)\n", a.x, b.x,
           want, flat, f.x);
    CHECK(fabsf(a.x / want - 1.0f) < 1e-3f && fabsf(a.y / want - 1.0f) < 1e-3f, "normal map %g vs %g", a.x, want);
    CHECK(fabsf(a.x / b.x - 1.0f) < 1e-4f, "normal map %g vs tilted vertex normals %g", a.x, b.x);
    CHECK(fabsf(f.x / flat - 1.0f) < 1e-3f && fabsf(f.x - a.x) > 0.1f * flat, "untilted %g vs %g", f.x, flat);
}

/* ---- (b) ---- */

static void s_test_bump_ramp(void)
{
    const float slope[3] = { 0.5f, 2.0f, -1.0f };
    for (int k = 0; k < 3; k++)
        for (int with_nrm = 0; with_nrm < 2; with_nrm++) {
            pf_scene_t *sc = pf_scene_create();
            /* h = s u: a 2-pixel float image (0 and 1) clamped, its pixel
             * centres (s = 0.25, 0.75) mapped to u = 0 and 1, scale s */
            pf_texture_t t = pf_texture_constant("ramp", pf_v3s(0.0f));
            t.type = PF_TEX_IMAGE;
            t.width = 2;
            t.height = 1;
            t.wrap = PF_WRAP_CLAMP;
            t.su = 0.5f;
            t.du = 0.25f;
            t.scale = slope[k];
            t.pxf = calloc(6, sizeof(float));
            t.pxf[3] = t.pxf[4] = t.pxf[5] = 1.0f;
            pf_material_t m = pf_material_default("m");
            m.bump_tex = (uint32_t)pf_scene_add_texture(sc, &t);
            uint32_t mi = (uint32_t)pf_scene_add_material(sc, &m);
            pf_vec3 up = pf_v3(0, 1, 0);
            s_add_quad(sc, mi, with_nrm ? &up : NULL);
            /* height y = s u = s (x + 1) / 2: normal (-s / 2, 1, 0) */
            pf_vec3 want = pf_norm(pf_v3(-slope[k] / 2.0f, 1.0f, 0.0f));
            const float bary[4][3] = { { 0, 0.3f, 0.2f }, { 0, 0.1f, 0.6f }, { 1, 0.25f, 0.5f }, { 1, 0.7f, 0.1f } };
            float worst = 0.0f;
            for (int i = 0; i < 4; i++) {
                const pf_mesh_t *me = &sc->meshes[0];
                uint32_t prim = (uint32_t)bary[i][0];
                const uint32_t *v = &me->idx[3 * prim];
                float b1 = bary[i][1], b2 = bary[i][2];
                pf_vec3 p = pf_add(pf_add(pf_scale(me->pos[v[0]], 1 - b1 - b2), pf_scale(me->pos[v[1]], b1)),
                                   pf_scale(me->pos[v[2]], b2));
                pf_hit_t h = { .p = p, .ng = up, .ns = up, .mat = mi, .geom = 0, .prim = prim, .u = b1, .v = b2 };
                pf_shade_hit(sc, &sc->mats[mi], &h, want); /* seen along the normal: no reflection fix-up */
                worst = fmaxf(worst, pf_len(pf_sub(h.ns, want)));
            }
            printf("(b) slope %g%s: largest |n - analytic| %.2e\n", slope[k], with_nrm ? " (vertex normals)" : "",
                   worst);
            CHECK(worst < 2e-3f, "bump ramp slope %g: off by %g", slope[k], worst);
            pf_scene_destroy(&sc);
        }
}

/* ---- (c) ---- */

/* A conductor quad m over the sky, rendered with every term; tex, when
 * given, is the scene's first texture (ref 1). */
static int s_conductor_render(pf_material_t m, pf_texture_t *tex, pf_image_t *img)
{
    pf_scene_t *sc = pf_scene_create();
    if (tex)
        CHECK(pf_scene_add_texture(sc, tex) == 1);
    uint32_t mi = (uint32_t)pf_scene_add_material(sc, &m);
    s_add_quad(sc, mi, NULL);
    pf_material_t d = pf_material_default("ball");
    uint32_t di = (uint32_t)pf_scene_add_material(sc, &d);
    pf_sphere_t ball = { .center = { 0.3f, 0.5f, 0.2f }, .radius = 0.3f, .mat = di };
    pf_scene_add_sphere(sc, &ball);
    pf_light_t sky = { .type = PF_LIGHT_INFINITE, .intensity = { 1, 1, 1 } };
    pf_light_t sun = { .type = PF_LIGHT_DISTANT, .dir = pf_norm(pf_v3(0.3f, -1, 0.2f)), .intensity = { 3, 3, 3 } };
    pf_scene_add_light(sc, &sky);
    pf_scene_add_light(sc, &sun);
    sc->camera = (pf_camera_desc_t){ .pos = { 0, 4, 6 }, .look_at = { 0, 0, 0 }, .up = { 0, 1, 0 }, .vfov_deg = 30 };
    sc->has_camera = 1;
    int ok = s_render(sc, 48, PF_TERM_ALL, img);
    pf_scene_destroy(&sc);
    return ok;
}

static void s_test_textured_conductor(void)
{
    pf_material_t m = pf_material_default("metal");
    m.type = PF_MAT_CONDUCTOR;
    m.kd = pf_v3s(0.0f);
    m.eta = pf_v3(0.2f, 0.9f, 1.1f);
    m.k = pf_v3(3.9f, 2.4f, 2.2f);
    m.alpha = sqrtf(0.09f);
    pf_image_t a = { 0 }, b = { 0 }, c = { 0 }, d = { 0 };
    int ok = s_conductor_render(m, NULL, &a);
    /* roughness 0.09 remapped (pbrt's default): alpha 0.3, from the texture */
    pf_material_t mt = m;
    mt.alpha = 0.0f;
    mt.rough_tex = 1;
    mt.rough_remap = 1;
    pf_texture_t t = pf_texture_constant("r", pf_v3s(0.09f));
    ok = ok && s_conductor_render(mt, &t, &b);
    size_t n = (size_t)a.width * (size_t)a.height * 3;
    CHECK(ok && memcmp(a.rgb, b.rgb, n * sizeof(float)) == 0, "a constant roughness texture changes the image");
    /* reflectance: pbrt's form, eta 1 and k from r, against the texture */
    pf_material_t r = m;
    float rv[3] = { 0.9f, 0.6f, 0.3f };
    r.eta = pf_v3s(1.0f);
    r.ks = pf_v3(rv[0], rv[1], rv[2]);
    r.k = pf_v3(pf_conductor_k_of_reflectance(rv[0]), pf_conductor_k_of_reflectance(rv[1]),
                pf_conductor_k_of_reflectance(rv[2]));
    ok = ok && s_conductor_render(r, NULL, &c);
    pf_material_t rt = m;
    rt.refl_tex = 1;
    pf_texture_t t3 = pf_texture_constant("refl", pf_v3(rv[0], rv[1], rv[2]));
    ok = ok && s_conductor_render(rt, &t3, &d);
    CHECK(ok && memcmp(c.rgb, d.rgb, n * sizeof(float)) == 0, "a constant reflectance texture changes the image");
    CHECK(ok && memcmp(a.rgb, c.rgb, n * sizeof(float)) != 0, "the two conductors differ");
    printf("(c) textured roughness and reflectance: bit-identical to the constants (%dx%d)\n", a.width, a.height);
    pf_image_free(&a);
    pf_image_free(&b);
    pf_image_free(&c);
    pf_image_free(&d);
}

/* ---- (d) ---- */

static void s_test_grazing(void)
{
    pf_scene_t *sc = pf_scene_create();
    const int W = 16;
    pf_texture_t t = pf_texture_constant("wild", pf_v3s(0.0f));
    t.type = PF_TEX_IMAGE;
    t.width = t.height = W;
    t.pxf = malloc((size_t)W * W * 3 * sizeof(float));
    uint64_t x = 88172645463325252ull;
    for (int i = 0; i < W * W; i++) {
        /* grazing (z ~ 0), slightly below (z < 0), far below, and (0, 0, 0) */
        x ^= x << 13, x ^= x >> 7, x ^= x << 17;
        float a = (float)(x % 6283) / 1000.0f, zs[5] = { 0.0f, 0.01f, -0.05f, -0.9f, 0.3f };
        float z = zs[i % 5];
        float r = sqrtf(fmaxf(0.0f, 1 - z * z));
        pf_vec3 l = i % 17 == 0 ? pf_v3s(0.0f) : pf_v3(r * cosf(a), r * sinf(a), z);
        t.pxf[3 * i] = 0.5f * (l.x + 1), t.pxf[3 * i + 1] = 0.5f * (l.y + 1), t.pxf[3 * i + 2] = 0.5f * (l.z + 1);
    }
    pf_material_t m = pf_material_default("bent");
    m.normal_tex = (uint32_t)pf_scene_add_texture(sc, &t);
    pf_texture_t hb = pf_texture_constant("steep", pf_v3s(0.0f));
    hb.type = PF_TEX_CHECKER;
    hb.su = hb.sv = 40.0f;
    hb.op[1].c = pf_v3s(50.0f);
    pf_material_t mb = pf_material_default("bumped");
    mb.type = PF_MAT_CONDUCTOR;
    mb.kd = pf_v3s(0);
    mb.eta = pf_v3s(1.0f);
    mb.k = pf_v3s(3.0f);
    mb.alpha = 0.2f;
    mb.bump_tex = (uint32_t)pf_scene_add_texture(sc, &hb);
    uint32_t mi = (uint32_t)pf_scene_add_material(sc, &m);
    uint32_t bi = (uint32_t)pf_scene_add_material(sc, &mb);
    pf_vec3 up = pf_v3(0, 1, 0);
    s_add_quad(sc, mi, &up);
    pf_sphere_t ball = { .center = { 0, 0.4f, 0 }, .radius = 0.35f, .mat = bi };
    pf_scene_add_sphere(sc, &ball);
    pf_light_t sky = { .type = PF_LIGHT_INFINITE, .intensity = { 1, 1, 1 } };
    pf_scene_add_light(sc, &sky);
    s_top_camera(sc);
    sc->camera.pos = pf_v3(0, 6, 8); /* grazing views as well */
    sc->camera.vfov_deg = 16.0f;
    sc->camera.up = pf_v3(0, 1, 0);
    pf_image_t img = { 0 };
    if (s_render(sc, 64, PF_TERM_ALL, &img)) {
        size_t n = (size_t)img.width * (size_t)img.height, bad = 0, black = 0;
        for (size_t i = 0; i < 3 * n; i++)
            bad += !isfinite(img.rgb[i]);
        for (size_t i = 0; i < n; i++)
            if (img.rgb[3 * i] <= 0.0f && img.rgb[3 * i + 1] <= 0.0f && img.rgb[3 * i + 2] <= 0.0f && black++ < 8)
                printf("  black at %zu %zu\n", i % (size_t)img.width, i / (size_t)img.width);
        printf("(d) grazing normal map + steep bump: %zu non-finite values, %zu black pixels of %zu\n", bad, black, n);
        CHECK(bad == 0, "%zu non-finite values", bad);
        CHECK(black == 0, "%zu black pixels", black);
    }
    /* and each bent normal stays above the horizon, unit */
    float worst = 1.0f;
    for (int i = 0; i < 2000; i++) {
        float b1 = (float)(i % 37) / 37.0f * 0.98f, b2 = (1 - b1) * (float)(i % 23) / 23.0f;
        pf_hit_t h = { .ng = up, .ns = up, .mat = mi, .geom = 0, .prim = (uint32_t)(i & 1), .u = b1, .v = b2 };
        pf_shade_hit(sc, &sc->mats[mi], &h, up);
        float len = pf_len(h.ns);
        worst = fminf(worst, pf_is_finite3(h.ns) && fabsf(len - 1) < 1e-4f ? pf_dot(h.ns, up) : -1.0f);
    }
    CHECK(worst >= PF_SHADE_MIN_COS * 0.99f, "a bent normal at cos %g to ng", worst);
    pf_image_free(&img);
    pf_scene_destroy(&sc);
}

/* ---- loaders and the blob ---- */

static void s_test_mtl(void)
{
    char p[512];
    uint8_t px[4 * 4 * 3];
    for (int i = 0; i < 48; i++)
        px[i] = (uint8_t)(i * 5);
    snprintf(p, sizeof p, "%s/h.png", s_dir);
    CHECK(stbi_write_png(p, 4, 4, 3, px, 12));
    snprintf(p, sizeof p, "%s/n.png", s_dir);
    CHECK(stbi_write_png(p, 4, 4, 3, px, 12));
    snprintf(p, sizeof p, "%s/q.mtl", s_dir);
    FILE *f = fopen(p, "w");
    fputs("newmtl a\nKd 0.5 0.5 0.5\nbump -bm 0.25 h.png\n"
          "newmtl b\nKd 0.5 0.5 0.5\nnorm n.png\n"
          "newmtl c\nKd 0.5 0.5 0.5\nmap_Bump h.png\n",
          f);
    fclose(f);
    snprintf(p, sizeof p, "%s/q.obj", s_dir);
    f = fopen(p, "w");
    fputs("mtllib q.mtl\nv 0 0 0\nv 1 0 0\nv 1 0 -1\nv 0 0 -1\nvt 0 0\nvt 1 0\nvt 1 1\nvt 0 1\n"
          "usemtl a\nf 1/1 2/2 3/3\nusemtl b\nf 1/1 3/3 4/4\nusemtl c\nf 1/1 2/2 4/4\n",
          f);
    fclose(f);
    pf_scene_t *sc = pf_scene_create();
    pf_error_t err = { { 0 } };
    CHECK(pf_obj_load(sc, p, NULL, -1, &err) == PF_OK, "%s", err.msg);
    int a = pf_scene_find_material(sc, "a"), b = pf_scene_find_material(sc, "b"), c = pf_scene_find_material(sc, "c");
    CHECK(a >= 0 && b >= 0 && c >= 0);
    if (a >= 0 && b >= 0 && c >= 0) {
        const pf_material_t *ma = &sc->mats[a], *mb = &sc->mats[b], *mc = &sc->mats[c];
        CHECK(ma->bump_tex && !ma->normal_tex && sc->texs[ma->bump_tex - 1].scale == 0.25f &&
                  !sc->texs[ma->bump_tex - 1].srgb,
              "bump -bm 0.25: the texture's scale, linear");
        CHECK(mb->normal_tex && !mb->bump_tex && !sc->texs[mb->normal_tex - 1].srgb, "norm: a linear normal map");
        CHECK(mc->bump_tex && sc->texs[mc->bump_tex - 1].scale == 1.0f, "map_Bump");
        CHECK(fabsf(sc->texs[mb->normal_tex - 1].px8 ? sc->texs[mb->normal_tex - 1].px8[5] - 25.0f : 1.0f) < 0.5f,
              "the pixels as written");
    }
    /* the scene blob carries the slots */
    pf_light_t sky = { .type = PF_LIGHT_INFINITE, .intensity = { 1, 1, 1 } };
    pf_scene_add_light(sc, &sky);
    sc->mats[0].rough_tex = sc->mats[0].bump_tex;
    sc->mats[0].rough_remap = 1;
    sc->mats[0].refl_tex = sc->mats[0].bump_tex;
    CHECK(pf_scene_finalize(sc, &err) == PF_OK, "%s", err.msg);
    pf_buf_t blob = { 0 };
    CHECK(pf_sceneblob_write(sc, &blob) == PF_OK);
    pf_scene_t *back = pf_sceneblob_read(blob.data, blob.len, &err);
    CHECK(back != NULL, "%s", err.msg);
    for (size_t i = 0; back && i < sc->nmats; i++) {
        const pf_material_t *x = &sc->mats[i], *y = &back->mats[i];
        CHECK(x->normal_tex == y->normal_tex && x->bump_tex == y->bump_tex && x->rough_tex == y->rough_tex &&
                  x->rough_remap == y->rough_remap && x->refl_tex == y->refl_tex,
              "material %zu's slots through the blob", i);
    }
    pf_scene_destroy(&back);
    pf_buf_free(&blob);
    pf_scene_destroy(&sc);
}

/* pbrt-v4: "string normalmap", "texture displacement", roughness and
 * reflectance textures on conductor and coateddiffuse, read into the slots
 * without warnings. */
static void s_test_pbrt(void)
{
    char p[512];
    uint8_t px[2 * 2 * 3] = { 128, 128, 255, 128, 128, 255, 200, 128, 230, 128, 60, 230 };
    snprintf(p, sizeof p, "%s/nm.png", s_dir);
    CHECK(stbi_write_png(p, 2, 2, 3, px, 6));
    snprintf(p, sizeof p, "%s/m.pbrt", s_dir);
    FILE *f = fopen(p, "w");
    fputs("LookAt 0 10 0  0 0 0  0 0 -1\nCamera \"perspective\" \"float fov\" 10\nWorldBegin\n"
          "LightSource \"infinite\" \"rgb L\" [1 1 1]\n"
          "Texture \"h\" \"float\" \"imagemap\" \"string filename\" \"nm.png\"\n"
          "Texture \"r\" \"float\" \"checkerboard\" \"float tex1\" 0.04 \"float tex2\" 0.25\n"
          "Texture \"c\" \"spectrum\" \"checkerboard\" \"rgb tex1\" [0.9 0.5 0.2] \"rgb tex2\" [0.3 0.3 0.3]\n"
          "MakeNamedMaterial \"bumped\" \"string type\" \"diffuse\" \"texture displacement\" \"h\"\n"
          "MakeNamedMaterial \"mapped\" \"string type\" \"coateddiffuse\" \"string normalmap\" \"nm.png\"\n"
          "  \"texture reflectance\" \"c\" \"texture roughness\" \"r\"\n"
          "MakeNamedMaterial \"metal\" \"string type\" \"conductor\" \"texture reflectance\" \"c\"\n"
          "  \"texture uroughness\" \"r\" \"float vroughness\" 0.1 \"bool remaproughness\" false\n"
          "MakeNamedMaterial \"mapped2\" \"string type\" \"diffuse\" \"string normalmap\" \"nm.png\"\n"
          "NamedMaterial \"mapped2\"\n"
          "Shape \"trianglemesh\" \"point3 P\" [0 0 0 1 0 0 1 0 -1] \"integer indices\" [0 1 2]\n"
          "NamedMaterial \"bumped\"\n"
          "Shape \"trianglemesh\" \"point3 P\" [0 0 0 1 0 0 1 0 -1] \"integer indices\" [0 1 2]\n"
          "NamedMaterial \"mapped\"\n"
          "Shape \"trianglemesh\" \"point3 P\" [0 0 0 1 0 0 1 0 -1] \"integer indices\" [0 1 2]\n"
          "NamedMaterial \"metal\"\n"
          "Shape \"trianglemesh\" \"point3 P\" [0 0 0 1 0 0 1 0 -1] \"integer indices\" [0 1 2]\n",
          f);
    fclose(f);
    pf_error_t err = { { 0 } };
    pf_load_report_t rep;
    pf_scene_t *sc = pf_scene_load_opts(p, &(pf_load_opts_t){ .report = &rep }, &err);
    CHECK(sc != NULL, "%s", err.msg);
    if (!sc)
        return;
    CHECK(rep.nwarnings == 0, "%zu warning kinds: %s", rep.nwarnings, rep.nwarnings ? rep.warnings[0].first : "");
    int b = pf_scene_find_material(sc, "bumped"), m = pf_scene_find_material(sc, "mapped"),
        c = pf_scene_find_material(sc, "metal");
    CHECK(b >= 0 && m >= 0 && c >= 0);
    if (b >= 0 && m >= 0 && c >= 0) {
        const pf_material_t *mb = &sc->mats[b], *mm = &sc->mats[m], *mc = &sc->mats[c];
        CHECK(mb->bump_tex && !mb->normal_tex, "displacement: the bump slot");
        int m2 = pf_scene_find_material(sc, "mapped2");
        CHECK(m2 >= 0 && sc->mats[m2].normal_tex == mm->normal_tex, "one normal-map file is read once");
        CHECK(mm->type == PF_MAT_COATED && mm->normal_tex && mm->kd_tex && mm->rough_tex && mm->rough_remap == 1 &&
                  !sc->texs[mm->normal_tex - 1].srgb,
              "coateddiffuse: normal map (linear), reflectance and roughness textures");
        CHECK(mc->type == PF_MAT_CONDUCTOR && mc->refl_tex && mc->rough_tex && mc->rough_remap == 0 &&
                  sc->texs[mc->rough_tex - 1].type == PF_TEX_MIX,
              "conductor: reflectance texture, roughness the mean of u (texture) and v (0.1)");
        /* at uv (0.1, 0.1) the checkerboard's tex1: alpha (0.04 + 0.1) / 2 */
        float uv[2] = { 0.1f, 0.1f };
        float a = pf_texture_eval(sc, mc->rough_tex, uv[0], uv[1]).x;
        CHECK(fabsf(a - 0.07f) < 1e-6f, "roughness texture %g", a);
    }
    pf_scene_destroy(&sc);
}

/* JSON: "normal_map", "bump" and "bump_scale" on any material type; a
 * "bump_scale" without "bump" is an error naming the line. */
static void s_test_json(void)
{
    char p[512];
    uint8_t px[2 * 2 * 3] = { 128, 128, 255, 128, 128, 255, 200, 128, 230, 128, 60, 230 };
    snprintf(p, sizeof p, "%s/j.png", s_dir);
    CHECK(stbi_write_png(p, 2, 2, 3, px, 6));
    const char *good = "{ \"materials\": [\n"
                       "  { \"name\": \"a\", \"kd\": [0.5, 0.5, 0.5], \"normal_map\": \"j.png\" },\n"
                       "  { \"name\": \"b\", \"type\": \"conductor\", \"reflectance\": [0.9, 0.9, 0.9],\n"
                       "    \"bump\": \"j.png\", \"bump_scale\": 0.01 } ],\n"
                       "  \"objects\": [ { \"type\": \"sphere\", \"center\": [0, 0, 0], \"radius\": 1, "
                       "\"material\": \"a\" },\n"
                       "    { \"type\": \"sphere\", \"center\": [3, 0, 0], \"radius\": 1, \"material\": \"b\" },\n"
                       "    { \"type\": \"quad\", \"origin\": [0, -2, 0], \"edge1\": [2, 0, 0], \"edge2\": [0, 0, -2],\n"
                       "      \"material\": \"a\" } ],\n"
                       "  \"lights\": [ { \"type\": \"point\", \"position\": [0, 5, 0], \"intensity\": [1, 1, 1] } ] }\n";
    snprintf(p, sizeof p, "%s/j.json", s_dir);
    FILE *f = fopen(p, "w");
    fputs(good, f);
    fclose(f);
    pf_error_t err = { { 0 } };
    pf_scene_t *sc = pf_scene_load(p, &err);
    CHECK(sc != NULL, "%s", err.msg);
    int a = sc ? pf_scene_find_material(sc, "a") : -1, b = sc ? pf_scene_find_material(sc, "b") : -1;
    CHECK(a >= 0 && b >= 0);
    if (a >= 0 && b >= 0) {
        CHECK(sc->mats[a].normal_tex && !sc->mats[a].bump_tex && !sc->texs[sc->mats[a].normal_tex - 1].srgb);
        CHECK(sc->mats[b].bump_tex && sc->texs[sc->mats[b].bump_tex - 1].scale == 0.01f, "bump_scale");
        /* the mapped quad has uv along its edges: dpdu = edge1, dpdv = edge2 */
        const pf_mesh_t *q = sc->nmeshes == 1 ? &sc->meshes[0] : NULL;
        CHECK(q && q->uv && q->uv[2] == 1.0f && q->uv[3] == 0.0f && q->uv[7] == 1.0f, "quad uv");
        if (q && q->uv) {
            pf_hit_t h = { .ng = pf_v3(0, 1, 0), .geom = 0, .prim = 0, .u = 0.2f, .v = 0.1f };
            pf_vec3 du, dv;
            pf_hit_dpduv(sc, &h, &du, &dv);
            CHECK(pf_len(pf_sub(du, pf_v3(2, 0, 0))) < 1e-6f && pf_len(pf_sub(dv, pf_v3(0, 0, -2))) < 1e-6f,
                  "quad tangents (%g %g %g), (%g %g %g)", du.x, du.y, du.z, dv.x, dv.y, dv.z);
        }
    }
    pf_scene_destroy(&sc);
    f = fopen(p, "w");
    fputs("{ \"materials\": [\n  { \"name\": \"a\", \"bump_scale\": 2 } ],\n"
          "  \"objects\": [ { \"type\": \"sphere\", \"center\": [0, 0, 0], \"radius\": 1, \"material\": \"a\" } ],\n"
          "  \"lights\": [ { \"type\": \"point\", \"position\": [0, 5, 0], \"intensity\": [1, 1, 1] } ] }\n",
          f);
    fclose(f);
    sc = pf_scene_load(p, &err);
    CHECK(sc == NULL && strstr(err.msg, ":2") && strstr(err.msg, "needs 'bump'"), "%s", err.msg);
    pf_scene_destroy(&sc);
}

int main(int argc, char **argv)
{
    pf_log_set_level(PF_LOG_WARN);
    const char *mode = argc > 1 ? argv[1] : "unit";
    snprintf(s_dir, sizeof s_dir, "/tmp/pf_bump_XXXXXX");
    if (!mkdtemp(s_dir)) {
        perror("mkdtemp");
        return 1;
    }
    if (!strcmp(mode, "unit")) {
        s_test_bump_ramp();
        s_test_mtl();
        s_test_pbrt();
        s_test_json();
    } else {
        s_test_normal_map_tilt();
        s_test_textured_conductor();
        s_test_grazing();
    }
    char cmd[600];
    snprintf(cmd, sizeof cmd, "rm -rf '%s'", s_dir);
    if (system(cmd) != 0)
        fprintf(stderr, "could not remove %s\n", s_dir);
    return pf_test_finish();
}
