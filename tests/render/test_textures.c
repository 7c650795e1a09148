/* test_textures.c: textures end to end. "unit": uv interpolation on a hit
 * (mesh uv and pbrt's default), the sRGB decoding of a known 8-bit value,
 * the wrap modes, bad image files (text named .png, a truncated PNG, a PNG
 * header claiming 100000 x 100000) giving an error that names the file and
 * the MTL line, the scene blob round trip with a textured mesh, and MTL
 * map_Ks (Phong ks and mirror reflectance times the image, held to 1 - kd;
 * the checker's 0.716 blue against 1 - 0.6 makes the hold bite).
 * "render": a 64 x 64 checker PNG on a quad (OBJ vt + MTL map_Kd) under a
 * uniform sky renders each checker square at albedo x sky radiance, where
 * the uvs put it; the same from pbrt-v4 scenes (a PLY with u, v under a
 * "checkerboard" texture, a trianglemesh with "point2 uv" under an
 * "imagemap"), and a quad cut out by an alpha checkerboard showing the sky
 * through its holes. Files are written to a temporary folder. */
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <unistd.h>

#include <stb_image_write.h>

#include "accel/accel.h"
#include "accel/surface.h"
#include "base/log.h"
#include "base/wire.h"
#include "coordinator/job.h"
#include "image/image.h"
#include "image/texfile.h"
#include "load/load.h"
#include "mesh/mesh.h"
#include "proto/sceneblob.h"
#include "render/render.h"
#include "scene/scene.h"
#include "scene/texture.h"

#include "check.h"

static char s_dir[256];

static const uint8_t s_ca[3] = { 200, 50, 50 }, s_cb[3] = { 30, 120, 220 };

static void s_path(char *out, size_t cap, const char *name) { snprintf(out, cap, "%s/%s", s_dir, name); }

static void s_write(const char *name, const char *text)
{
    char p[512];
    s_path(p, sizeof p, name);
    FILE *f = fopen(p, "wb");
    fputs(text, f);
    fclose(f);
}

/* A 64 x 64 PNG, colour a in the top-left and bottom-right 32 x 32 squares, b elsewhere. */
static void s_checker_png(const char *name)
{
    uint8_t px[64 * 64 * 3];
    for (int y = 0; y < 64; y++)
        for (int x = 0; x < 64; x++)
            memcpy(&px[3 * (y * 64 + x)], ((x < 32) == (y < 32)) ? s_ca : s_cb, 3);
    char p[512];
    s_path(p, sizeof p, name);
    CHECK(stbi_write_png(p, 64, 64, 3, px, 64 * 3));
}

static pf_vec3 s_lin(const uint8_t c[3])
{
    return pf_v3(pf_srgb8_to_linear(c[0]), pf_srgb8_to_linear(c[1]), pf_srgb8_to_linear(c[2]));
}

/* ---- unit ---- */

static void s_test_uv_hit(void)
{
    pf_scene_t *sc = pf_scene_create();
    pf_material_t m = pf_material_default("m");
    m.le = pf_v3s(0.0f);
    uint32_t mi = (uint32_t)pf_scene_add_material(sc, &m);
    pf_light_t l = { .type = PF_LIGHT_POINT, .pos = { 0, 5, 0 }, .intensity = { 1, 1, 1 } };
    pf_scene_add_light(sc, &l);
    for (int k = 0; k < 2; k++) {
        /* triangle (0,0,0), (2,0,0), (0,0,-2) in y = k; mesh 0 with uvs, mesh 1 without */
        pf_mesh_t me = { 0 };
        me.nverts = 3;
        me.ntris = 1;
        me.pos = malloc(3 * sizeof *me.pos);
        me.idx = malloc(3 * sizeof *me.idx);
        me.mat = malloc(sizeof *me.mat);
        me.pos[0] = pf_v3(0, (float)-k, 0);
        me.pos[1] = pf_v3(2, (float)-k, 0);
        me.pos[2] = pf_v3(0, (float)-k, -2);
        for (int i = 0; i < 3; i++)
            me.idx[i] = (uint32_t)i;
        me.mat[0] = mi;
        if (k == 0) {
            me.uv = malloc(6 * sizeof *me.uv);
            const float uv[6] = { 0.1f, 0.2f, 0.9f, 0.2f, 0.1f, 0.7f };
            memcpy(me.uv, uv, sizeof uv);
        }
        pf_scene_add_mesh(sc, &me);
    }
    pf_error_t err = { { 0 } };
    CHECK(pf_scene_finalize(sc, &err) == PF_OK, "%s", err.msg);
    pf_accel_t *a = pf_accel_create(sc, &err);
    CHECK(a != NULL, "%s", err.msg);
    if (!a) {
        pf_scene_destroy(&sc);
        return;
    }
    /* At (0.5, ., -0.5): barycentrics b1 = 0.25 (towards p1), b2 = 0.25. */
    pf_ray_t r = { { 0.5f, 1, -0.5f }, { 0, -1, 0 } };
    pf_hit_t h;
    float uv[2];
    CHECK(pf_accel_intersect(a, &r, INFINITY, &h) && h.geom == 0);
    pf_hit_uv(sc, &h, uv);
    CHECK(fabsf(uv[0] - 0.3f) < 1e-5f && fabsf(uv[1] - 0.325f) < 1e-5f, "mesh uv %g %g, expected 0.3 0.325", uv[0],
          uv[1]);
    r.o.y = -0.5f;
    CHECK(pf_accel_intersect(a, &r, INFINITY, &h) && h.geom == 1);
    pf_hit_uv(sc, &h, uv);
    /* pbrt's default: corners (0,0), (1,0), (1,1): uv = (b1 + b2, b2). */
    CHECK(fabsf(uv[0] - 0.5f) < 1e-5f && fabsf(uv[1] - 0.25f) < 1e-5f, "default uv %g %g, expected 0.5 0.25", uv[0],
          uv[1]);
    pf_accel_destroy(&a);
    pf_scene_destroy(&sc);
}

static void s_test_srgb_wrap(void)
{
    CHECK(fabsf(pf_srgb8_to_linear(128) - 0.2158605f) < 1e-6f, "sRGB 128 -> %.7f", pf_srgb8_to_linear(128));
    CHECK(pf_srgb8_to_linear(0) == 0.0f && pf_srgb8_to_linear(255) == 1.0f);
    /* a 1x1 8-bit PNG of 128 read through the file path and a texture */
    uint8_t px[3] = { 128, 128, 128 };
    char p[512];
    s_path(p, sizeof p, "grey.png");
    stbi_write_png(p, 1, 1, 3, px, 3);
    pf_teximage_t img;
    pf_error_t err = { { 0 } };
    CHECK(pf_teximage_read(p, 16384, 1u << 28, &img, &err) == PF_OK && img.px8 && img.px8[0] == 128, "%s", err.msg);
    pf_teximage_free(&img);

    pf_scene_t *sc = pf_scene_create();
    pf_texture_t t = pf_texture_constant("w", pf_v3s(0));
    t.type = PF_TEX_IMAGE;
    t.width = 2;
    t.height = 1;
    t.pxf = malloc(6 * sizeof *t.pxf);
    const float v[6] = { 0.25f, 0.25f, 0.25f, 0.75f, 0.75f, 0.75f };
    memcpy(t.pxf, v, sizeof v);
    pf_texture_t c = t;
    c.pxf = malloc(sizeof v);
    memcpy(c.pxf, v, sizeof v);
    c.wrap = PF_WRAP_CLAMP;
    pf_texture_t b = c;
    b.pxf = malloc(sizeof v);
    memcpy(b.pxf, v, sizeof v);
    b.wrap = PF_WRAP_BLACK;
    uint32_t rr = (uint32_t)pf_scene_add_texture(sc, &t), rc = (uint32_t)pf_scene_add_texture(sc, &c),
             rb = (uint32_t)pf_scene_add_texture(sc, &b);
    /* x = s w - 1/2: s = 0.25 is pixel 0's centre, s = 1.25 is x = 2. */
    CHECK(fabsf(pf_texture_eval(sc, rr, 0.25f, 0.5f).x - 0.25f) < 1e-6f);
    CHECK(fabsf(pf_texture_eval(sc, rr, 0.5f, 0.5f).x - 0.5f) < 1e-6f, "bilinear midway");
    CHECK(fabsf(pf_texture_eval(sc, rr, 1.25f, 0.5f).x - 0.25f) < 1e-6f, "repeat");
    CHECK(fabsf(pf_texture_eval(sc, rr, -0.75f, 0.5f).x - 0.25f) < 1e-6f, "repeat below 0");
    CHECK(fabsf(pf_texture_eval(sc, rc, 1.25f, 0.5f).x - 0.75f) < 1e-6f, "clamp");
    CHECK(fabsf(pf_texture_eval(sc, rc, -3.0f, 0.5f).x - 0.25f) < 1e-6f, "clamp below 0");
    CHECK(pf_texture_eval(sc, rb, 1.75f, 0.5f).x == 0.0f, "black");
    CHECK(fabsf(pf_texture_eval(sc, rb, 0.75f, 0.5f).x - 0.75f) < 1e-6f, "black inside");
    /* checker of two constants, 2 x 2 per unit square */
    pf_texture_t k = pf_texture_constant("k", pf_v3s(0));
    k.type = PF_TEX_CHECKER;
    k.su = k.sv = 2.0f;
    k.op[0].c = pf_v3s(1.0f);
    k.op[1].c = pf_v3s(0.5f);
    uint32_t rk = (uint32_t)pf_scene_add_texture(sc, &k);
    CHECK(pf_texture_eval(sc, rk, 0.2f, 0.2f).x == 1.0f && pf_texture_eval(sc, rk, 0.7f, 0.2f).x == 0.5f &&
          pf_texture_eval(sc, rk, 0.7f, 0.7f).x == 1.0f && pf_texture_eval(sc, rk, -0.2f, 0.2f).x == 0.5f);
    pf_scene_destroy(&sc);
}

/* Loads an OBJ whose MTL's map_Kd names image: the error must name both. */
static void s_bad_image(const char *image, const char *what, const char *needle)
{
    char mtl[512], obj[512], mtlname[64];
    snprintf(mtlname, sizeof mtlname, "bad_%s.mtl", image);
    snprintf(mtl, sizeof mtl, "newmtl m\nKd 1 1 1\nmap_Kd %s\n", image);
    s_write(mtlname, mtl);
    snprintf(obj, sizeof obj, "mtllib %s\nv 0 0 0\nv 1 0 0\nv 1 0 -1\nvt 0 0\nvt 1 0\nvt 1 1\nusemtl m\nf 1/1 2/2 3/3\n",
             mtlname);
    s_write("bad.obj", obj);
    char p[512];
    s_path(p, sizeof p, "bad.obj");
    pf_scene_t *sc = pf_scene_create();
    pf_error_t err = { { 0 } };
    int rc = pf_obj_load(sc, p, NULL, -1, &err);
    if (!needle) { /* a missing image: a warning, and the material keeps Kd */
        CHECK(rc == PF_OK && sc->ntexs == 0, "%s: rc %d, '%s'", what, rc, err.msg);
        pf_scene_destroy(&sc);
        return;
    }
    CHECK(rc != PF_OK && strstr(err.msg, image) && strstr(err.msg, mtlname) && strstr(err.msg, ":3:") &&
              strstr(err.msg, needle),
          "%s: rc %d, '%s'", what, rc, err.msg);
    printf("%s: %s\n", what, err.msg);
    pf_scene_destroy(&sc);
}

static void s_test_bad_images(void)
{
    s_write("text.png", "this is not a PNG\n");
    s_bad_image("text.png", "text named .png", "not an image");
    char p[512];
    s_checker_png("whole.png");
    s_path(p, sizeof p, "whole.png");
    FILE *f = fopen(p, "rb");
    uint8_t buf[4096];
    size_t n = fread(buf, 1, sizeof buf, f);
    fclose(f);
    s_path(p, sizeof p, "cut.png");
    f = fopen(p, "wb");
    fwrite(buf, 1, n / 2, f);
    fclose(f);
    s_bad_image("cut.png", "truncated PNG", "cannot decode");
    /* a PNG signature and IHDR claiming 100000 x 100000 */
    const uint8_t big[] = { 0x89, 'P', 'N', 'G', 13, 10, 26, 10, 0, 0, 0, 13, 'I', 'H', 'D', 'R', 0, 1, 0x86, 0xa0,
                            0, 1, 0x86, 0xa0, 8, 2, 0, 0, 0, 0, 0, 0, 0 };
    s_path(p, sizeof p, "huge.png");
    f = fopen(p, "wb");
    fwrite(big, 1, sizeof big, f);
    fclose(f);
    /* stb_image's own header check refuses this one (over 2^24 bytes a row
     * times rows); the error still names the file. */
    s_bad_image("huge.png", "PNG claiming 100000 x 100000", "huge.png");
    /* 20000 x 8 passes stb's check: photonfarm's limit refuses it from the header. */
    uint8_t wide[sizeof big];
    memcpy(wide, big, sizeof big);
    const uint8_t wh[8] = { 0, 0, 0x4e, 0x20, 0, 0, 0, 8 };
    memcpy(wide + 16, wh, 8);
    s_path(p, sizeof p, "wide.png");
    f = fopen(p, "wb");
    fwrite(wide, 1, sizeof wide, f);
    fclose(f);
    s_bad_image("wide.png", "PNG claiming 20000 x 8", "at most 16384 per side");
    s_bad_image("missing.png", "missing file", NULL);
    /* pbrt: the error names the image and the Texture's file:line */
    s_write("badimg.pbrt", "LookAt 0 10 0  0 0 0  0 0 -1\nCamera \"perspective\" \"float fov\" 10\nWorldBegin\n"
                           "LightSource \"infinite\" \"rgb L\" [1 1 1]\n"
                           "Texture \"t\" \"spectrum\" \"imagemap\" \"string filename\" \"text.png\"\n"
                           "Material \"diffuse\" \"texture reflectance\" \"t\"\n"
                           "Shape \"trianglemesh\" \"point3 P\" [0 0 0 1 0 0 1 0 -1] \"integer indices\" [0 1 2]\n");
    s_path(p, sizeof p, "badimg.pbrt");
    pf_error_t err = { { 0 } };
    pf_scene_t *sc = pf_scene_load(p, &err);
    CHECK(sc == NULL && strstr(err.msg, "badimg.pbrt:5:") && strstr(err.msg, "text.png") &&
              strstr(err.msg, "not an image"),
          "pbrt bad image: '%s'", err.msg);
    printf("pbrt imagemap of a text file: %s\n", err.msg);
    pf_scene_destroy(&sc);
}

/* MTL map_Ks: a Phong lobe's ks and a mirror's reflectance are Ks times
 * the (sRGB) image at the hit, a Phong ks held to 1 - kd; without Ks the
 * map alone (Ks 1); on glass a warning and nothing textured. Four quads
 * side by side, each with uv over [0, 1]^2 (as s_obj_scene's). */
static void s_test_map_ks(void)
{
    s_checker_png("checker.png");
    s_write("ks.mtl", "newmtl phong\nKd 0.3 0.3 0.3\nKs 0.5 0.5 0.5\nNs 50\nillum 2\nmap_Ks checker.png\n"
                      "newmtl bright\nKd 0.6 0.6 0.6\nNs 20\nillum 2\nmap_Ks checker.png\n"
                      "newmtl mirror\nKs 0.9 0.9 0.9\nillum 3\nmap_Ks checker.png\n"
                      "newmtl glass\nillum 7\nmap_Ks checker.png\n");
    char obj[2048] = "mtllib ks.mtl\nvt 0 0\nvt 1 0\nvt 1 1\nvt 0 1\n";
    const char *names[4] = { "phong", "bright", "mirror", "glass" };
    for (int k = 0; k < 4; k++) {
        size_t n = strlen(obj);
        float x = 3.0f * (float)k;
        snprintf(obj + n, sizeof obj - n,
                 "v %g 0 1\nv %g 0 1\nv %g 0 -1\nv %g 0 -1\nusemtl %s\nf %d/1 %d/2 %d/3 %d/4\n", x - 1, x + 1,
                 x + 1, x - 1, names[k], 4 * k + 1, 4 * k + 2, 4 * k + 3, 4 * k + 4);
    }
    s_write("ks.obj", obj);
    char p[512];
    s_path(p, sizeof p, "ks.obj");
    pf_scene_t *sc = pf_scene_create();
    pf_light_t l = { .type = PF_LIGHT_POINT, .pos = { 0, 5, 0 }, .intensity = { 1, 1, 1 } };
    pf_scene_add_light(sc, &l);
    pf_error_t err = { { 0 } };
    int rc = pf_obj_load(sc, p, NULL, -1, &err);
    CHECK(rc == PF_OK, "%s", err.msg);
    if (rc == PF_OK)
        CHECK((rc = pf_scene_finalize(sc, &err)) == PF_OK, "finalize: %s", err.msg);
    pf_accel_t *a = rc == PF_OK ? pf_accel_create(sc, &err) : NULL;
    CHECK(a != NULL, "accel: %s", err.msg);
    if (!a) {
        pf_scene_destroy(&sc);
        return;
    }
    const pf_vec3 ca = s_lin(s_ca), cb = s_lin(s_cb);
    const float kslim[4] = { 0.5f, 1.0f, 0.9f, 0.0f }, kdv[4] = { 0.3f, 0.6f, 0.0f, 0.0f };
    for (int k = 0; k < 4; k++) {
        int seen[2] = { 0, 0 };
        for (int j = 0; j < 2; j++) {
            pf_ray_t r = { { 3.0f * (float)k - 0.5f, 1, j ? -0.5f : 0.5f }, { 0, -1, 0 } };
            pf_hit_t h;
            if (!pf_accel_intersect(a, &r, INFINITY, &h)) {
                CHECK(0, "%s: the ray missed its quad", names[k]);
                continue;
            }
            const pf_material_t *base = &sc->mats[h.mat];
            pf_material_t m = pf_material_at(sc, &h);
            CHECK(!strcmp(base->name, names[k]), "quad %d has material %s", k, base->name);
            if (k == 3) {
                CHECK(base->refl_tex == 0 && m.ks.x == base->ks.x && m.ks.z == base->ks.z,
                      "glass: map_Ks must not texture it (refl_tex %u)", base->refl_tex);
                continue;
            }
            CHECK(base->refl_tex != 0, "%s: map_Ks gives no texture", names[k]);
            /* which checker colour lies under this hit: the texel, then Ks times it, then the clamp */
            float uv[2];
            pf_hit_uv(sc, &h, uv);
            pf_vec3 t = pf_texture_eval(sc, base->refl_tex, uv[0], uv[1]);
            int is_a = fabsf(t.x - ca.x) < 1e-5f && fabsf(t.z - ca.z) < 1e-5f;
            int is_b = fabsf(t.x - cb.x) < 1e-5f && fabsf(t.z - cb.z) < 1e-5f;
            CHECK(is_a || is_b, "%s: texel (%g %g %g) is neither checker colour", names[k], t.x, t.y, t.z);
            seen[is_a ? 0 : 1] = 1;
            pf_vec3 c = is_a ? ca : cb;
            float lim = k == 2 ? INFINITY : 1.0f - kdv[k];
            pf_vec3 want = pf_v3(fminf(kslim[k] * c.x, lim), fminf(kslim[k] * c.y, lim), fminf(kslim[k] * c.z, lim));
            CHECK(fabsf(m.ks.x - want.x) < 1e-5f && fabsf(m.ks.y - want.y) < 1e-5f && fabsf(m.ks.z - want.z) < 1e-5f,
                  "%s: ks (%g %g %g), expected (%g %g %g)", names[k], m.ks.x, m.ks.y, m.ks.z, want.x, want.y,
                  want.z);
            CHECK(fabsf(m.kd.x - kdv[k]) < 1e-6f || k == 2, "%s: kd %g, expected %g (no energy scaling)", names[k],
                  m.kd.x, kdv[k]);
        }
        if (k < 3)
            CHECK(seen[0] && seen[1], "%s: the two hits should see both checker colours", names[k]);
    }
    pf_accel_destroy(&a);
    pf_scene_destroy(&sc);
}

/* The textured quad scene of the render test, from OBJ + MTL + PNG. */
static pf_scene_t *s_obj_scene(void)
{
    s_checker_png("checker.png");
    s_write("quad.mtl", "newmtl checker\nKd 0.5 0.5 0.5\nmap_Kd -s 1 1 checker.png\n");
    /* y = 0 facing +y, uv (0,0) at (-1, 1) (x left, z near), (0,1) at (-1, -1) */
    s_write("quad.obj", "mtllib quad.mtl\nv -1 0 1\nv 1 0 1\nv 1 0 -1\nv -1 0 -1\n"
                        "vt 0 0\nvt 1 0\nvt 1 1\nvt 0 1\nusemtl checker\nf 1/1 2/2 3/3 4/4\n");
    char p[512];
    s_path(p, sizeof p, "quad.obj");
    pf_scene_t *sc = pf_scene_create();
    pf_error_t err = { { 0 } };
    int rc = pf_obj_load(sc, p, NULL, -1, &err);
    CHECK(rc == PF_OK, "%s", err.msg);
    pf_light_t sky = { .type = PF_LIGHT_INFINITE, .intensity = { 1, 1, 1 } };
    pf_scene_add_light(sc, &sky);
    sc->camera = (pf_camera_desc_t){ .pos = { 0, 10, 0 }, .look_at = { 0, 0, 0 }, .up = { 0, 0, -1 },
                                     .vfov_deg = 10.0f };
    sc->has_camera = 1;
    if (rc == PF_OK && (rc = pf_scene_finalize(sc, &err)) != PF_OK)
        CHECK(0, "finalize: %s", err.msg);
    if (rc)
        pf_scene_destroy(&sc);
    return sc;
}

static void s_test_blob(void)
{
    pf_scene_t *sc = s_obj_scene();
    if (!sc)
        return;
    CHECK(sc->ntexs == 1 && sc->meshes[0].uv && sc->mats[sc->meshes[0].mat[0]].kd_tex == 1);
    pf_buf_t b = { 0 }, b2 = { 0 };
    CHECK(pf_sceneblob_write(sc, &b) == PF_OK);
    pf_error_t err = { { 0 } };
    pf_scene_t *back = pf_sceneblob_read(b.data, b.len, &err);
    CHECK(back != NULL, "%s", err.msg);
    if (back) {
        CHECK(back->ntexs == 1 && back->texs[0].width == 64 && back->texs[0].px8 && back->texs[0].srgb &&
              memcmp(back->texs[0].px8, sc->texs[0].px8, 64 * 64 * 3) == 0);
        CHECK(back->meshes[0].uv && memcmp(back->meshes[0].uv, sc->meshes[0].uv, 2 * sc->meshes[0].nverts * 4) == 0);
        CHECK(pf_sceneblob_write(back, &b2) == PF_OK && b2.len == b.len && memcmp(b.data, b2.data, b.len) == 0,
              "the blob of the read scene differs");
        /* a texture ref out of range is refused */
        pf_scene_destroy(&back);
    }
    pf_buf_free(&b);
    pf_buf_free(&b2);
    pf_scene_destroy(&sc);
}

/* ---- render ---- */

static int s_render(pf_scene_t *sc, int size, pf_image_t *img)
{
    pf_settings_t s = sc->settings;
    s.width = s.height = size;
    s.spp = 4;
    s.photons = 2000;
    s.caustic_photons = 0;
    s.threads = 0;
    pf_job_summary_t sum;
    pf_error_t err = { { 0 } };
    int rc = pf_job_render_local(sc, &s, PF_TERM_ALL, 0, img, &sum, &err);
    CHECK(rc == PF_OK, "render: %s", err.msg);
    return rc == PF_OK;
}

/* Mean of the quadrant (qx, qy) of img (0 left / top), leaving margin pixels
 * along the middle lines and the edges. */
static pf_vec3 s_quadrant(const pf_image_t *img, int qx, int qy, int margin)
{
    int h = img->width / 2;
    pf_vec3 s = pf_v3s(0);
    int n = 0;
    for (int y = qy * h + margin; y < (qy + 1) * h - margin; y++)
        for (int x = qx * h + margin; x < (qx + 1) * h - margin; x++, n++)
            s = pf_add(s, pf_v3(img->rgb[3 * (y * img->width + x)], img->rgb[3 * (y * img->width + x) + 1],
                                img->rgb[3 * (y * img->width + x) + 2]));
    return pf_scale(s, 1.0f / (float)n);
}

static float s_rel(pf_vec3 a, pf_vec3 b)
{
    return fmaxf(fabsf(a.x / b.x - 1), fmaxf(fabsf(a.y / b.y - 1), fabsf(a.z / b.z - 1)));
}

/* Each quadrant is one checker square: tl and br colour a, the others b
 * (exact == 1) or at least the diagonal ones alike (exact == 0: either way). */
static void s_check_checker(const pf_image_t *img, pf_vec3 a, pf_vec3 b, int exact, const char *what)
{
    pf_vec3 q[4] = { s_quadrant(img, 0, 0, 3), s_quadrant(img, 1, 0, 3), s_quadrant(img, 0, 1, 3),
                     s_quadrant(img, 1, 1, 3) };
    if (!exact && s_rel(q[0], a) > s_rel(q[0], b)) {
        pf_vec3 t = a;
        a = b;
        b = t;
    }
    float e[4] = { s_rel(q[0], a), s_rel(q[1], b), s_rel(q[2], b), s_rel(q[3], a) };
    printf("%s: quadrants (%.4f %.4f %.4f) (%.4f %.4f %.4f) / (%.4f %.4f %.4f) (%.4f %.4f %.4f); expected a (%.4f "
           "%.4f %.4f) b (%.4f %.4f %.4f); worst relative error %.4f\n",
           what, q[0].x, q[0].y, q[0].z, q[1].x, q[1].y, q[1].z, q[2].x, q[2].y, q[2].z, q[3].x, q[3].y, q[3].z, a.x,
           a.y, a.z, b.x, b.y, b.z, fmaxf(fmaxf(e[0], e[1]), fmaxf(e[2], e[3])));
    for (int i = 0; i < 4; i++)
        CHECK(e[i] < 0.03f, "%s: quadrant %d off by %.4f", what, i, e[i]);
    /* sharp: a pixel well inside a square matches its square's colour */
    int w = img->width;
    for (int y = 2; y < w / 2 - 2; y++) {
        const float *p = &img->rgb[3 * (y * w + 2)];
        if (s_rel(pf_v3(p[0], p[1], p[2]), a) > 0.15f) {
            CHECK(0, "%s: pixel (2, %d) %.3f %.3f %.3f is not colour a", what, y, p[0], p[1], p[2]);
            break;
        }
    }
}

static void s_test_render_obj(void)
{
    pf_scene_t *sc = s_obj_scene();
    pf_image_t img;
    if (sc && s_render(sc, 32, &img)) {
        s_check_checker(&img, s_lin(s_ca), s_lin(s_cb), 1, "OBJ + MTL map_Kd");
        pf_image_free(&img);
    }
    pf_scene_destroy(&sc);
}

static void s_test_render_pbrt(const char *name, const char *shape, pf_vec3 a, pf_vec3 b)
{
    char text[4096];
    snprintf(text, sizeof text,
             "LookAt 0 10 0  0 0 0  0 0 -1\nCamera \"perspective\" \"float fov\" 10\n"
             "Film \"rgb\" \"integer xresolution\" 32 \"integer yresolution\" 32\nWorldBegin\n"
             "LightSource \"infinite\" \"rgb L\" [1 1 1]\n"
             "Texture \"checks\" \"spectrum\" \"checkerboard\" \"float uscale\" 2 \"float vscale\" 2\n"
             "  \"rgb tex1\" [0.6 0.2 0.1] \"rgb tex2\" [0.1 0.3 0.7]\n"
             "Texture \"img\" \"spectrum\" \"imagemap\" \"string filename\" \"checker.png\"\n"
             "%s\n",
             shape);
    s_write(name, text);
    char p[512];
    s_path(p, sizeof p, name);
    pf_error_t err = { { 0 } };
    pf_scene_t *sc = pf_scene_load(p, &err);
    CHECK(sc != NULL, "%s: %s", name, err.msg);
    pf_image_t img;
    if (sc && s_render(sc, 32, &img)) {
        s_check_checker(&img, a, b, 0, name);
        pf_image_free(&img);
    }
    pf_scene_destroy(&sc);
}

/* A quad cut out by an alpha checkerboard (0 and 1) over the sky: the
 * camera sees the quad's albedo 0.5 in two squares and the sky (1) through
 * the holes. */
static void s_test_render_alpha(void)
{
    s_write("alpha.pbrt",
            "LookAt 0 10 0  0 0 0  0 0 -1\nCamera \"perspective\" \"float fov\" 10\nWorldBegin\n"
            "LightSource \"infinite\" \"rgb L\" [1 1 1]\n"
            "Texture \"holes\" \"float\" \"checkerboard\" \"float uscale\" 2 \"float vscale\" 2 \"float tex1\" 1 "
            "\"float tex2\" 0\n"
            "Material \"diffuse\" \"rgb reflectance\" [0.5 0.5 0.5]\n"
            "Shape \"trianglemesh\" \"point3 P\" [-1 0 1  1 0 1  1 0 -1  -1 0 -1] \"integer indices\" [0 1 2 0 2 3] "
            "\"point2 uv\" [0 0 1 0 1 1 0 1] \"texture alpha\" \"holes\"\n");
    char p[512];
    s_path(p, sizeof p, "alpha.pbrt");
    pf_error_t err = { { 0 } };
    pf_scene_t *sc = pf_scene_load(p, &err);
    CHECK(sc != NULL && sc->nmeshes == 1 && sc->meshes[0].alpha_tex > 0, "alpha: %s", err.msg);
    pf_image_t img;
    if (sc && s_render(sc, 32, &img)) {
        s_check_checker(&img, pf_v3s(0.5f), pf_v3s(1.0f), 0, "alpha cut-out");
        pf_image_free(&img);
    }
    pf_scene_destroy(&sc);
}

static void s_test_render(void)
{
    s_test_render_alpha();
    s_test_render_obj();
    s_checker_png("checker.png");
    s_write("quad.ply", "ply\nformat ascii 1.0\nelement vertex 4\nproperty float x\nproperty float y\n"
                        "property float z\nproperty float u\nproperty float v\nelement face 1\n"
                        "property list uchar int vertex_indices\nend_header\n"
                        "-1 0 1 0 0\n1 0 1 1 0\n1 0 -1 1 1\n-1 0 -1 0 1\n4 0 1 2 3\n");
    s_test_render_pbrt("ply.pbrt",
                       "Material \"diffuse\" \"texture reflectance\" \"checks\"\nShape \"plymesh\" \"string filename\" "
                       "\"quad.ply\"",
                       pf_v3(0.6f, 0.2f, 0.1f), pf_v3(0.1f, 0.3f, 0.7f));
    s_test_render_pbrt("tri.pbrt",
                       "Material \"diffuse\" \"texture reflectance\" \"img\"\nShape \"trianglemesh\" \"point3 P\" "
                       "[-1 0 1  1 0 1  1 0 -1  -1 0 -1] \"integer indices\" [0 1 2 0 2 3] "
                       "\"point2 uv\" [0 0 1 0 1 1 0 1]",
                       s_lin(s_ca), s_lin(s_cb));
}

int main(int argc, char **argv)
{
    pf_log_set_level(PF_LOG_WARN);
    const char *mode = argc > 1 ? argv[1] : "unit";
    snprintf(s_dir, sizeof s_dir, "/tmp/pf_textures_XXXXXX");
    if (!mkdtemp(s_dir)) {
        perror("mkdtemp");
        return 1;
    }
    if (!strcmp(mode, "unit")) {
        s_test_uv_hit();
        s_test_srgb_wrap();
        s_test_bad_images();
        s_test_blob();
        s_test_map_ks();
    } else {
        s_test_render();
    }
    char cmd[600];
    snprintf(cmd, sizeof cmd, "rm -rf '%s'", s_dir);
    if (system(cmd) != 0)
        fprintf(stderr, "could not remove %s\n", s_dir);
    return pf_test_finish();
}
