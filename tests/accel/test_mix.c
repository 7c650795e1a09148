/* test_mix.c: mix materials resolved at a hit (pf_material_at,
 * pf_mix_choose in accel/surface.c), and map_d-style per-material alpha
 * cut-outs (accel/alpha.c).
 *
 *   amount    a quad of mix(grey 0.2, diffuse transmitter R 0.9) at amount
 *             0.3, hit by 40000 rays from random origins: the share of hits
 *             resolved to the second material is 0.3 within 5 standard
 *             errors, and so the mean kd is 0.3 * 0.9 + 0.7 * 0.2 (the
 *             amount-weighted mean of both); the same ray resolves alike
 *             every time (the hash, no random stream); one point reached
 *             along 4000 rays of different lengths also splits 0.3 : 0.7;
 *             the mix's own le is kept, its parts' dropped.
 *   furnace   a mix of two lossless materials (diffuse kd 1, transmitter
 *             R + T = 1) resolves to a lossless one at every hit.
 *   texture   amount from a checker texture, 0 on the quad's left half and
 *             1 on its right: every hit resolves to the first material on
 *             the left and the second on the right.
 *   nested    mix(mix(a, b, 0.3), c, 0.5): a 0.35, b 0.15, c 0.5.
 *   checks    finalize rejects a mix of itself (a cycle) and an index out
 *             of range.
 *   alpha     a material's alpha texture (0: cut out) lets rays through a
 *             mesh without its own alpha.
 * Randomness: pf_rng_make(seed, PF_STREAM_TEST, i, 0). */
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "accel/accel.h"
#include "accel/surface.h"
#include "base/rng.h"
#include "scene/scene.h"
#include "scene/texture.h"

#include "check.h"

static pf_scene_t *s_scene(void)
{
    pf_scene_t *sc = pf_scene_create();
    if (!sc)
        exit(2);
    pf_light_t l;
    memset(&l, 0, sizeof l);
    l.type = PF_LIGHT_POINT;
    l.pos = pf_v3(0, 0, 100);
    l.intensity = pf_v3s(1.0f);
    pf_scene_add_light(sc, &l);
    return sc;
}

static uint32_t s_mat(pf_scene_t *sc, pf_mat_type type, float kd, float kt)
{
    pf_material_t m = pf_material_default("m");
    snprintf(m.name, sizeof m.name, "m%zu", sc->nmats);
    m.type = type;
    m.kd = pf_v3s(kd);
    m.kt = pf_v3s(kt);
    return (uint32_t)pf_scene_add_material(sc, &m);
}

static uint32_t s_mix(pf_scene_t *sc, uint32_t a, uint32_t b, float amount, uint32_t tex)
{
    pf_material_t m = pf_material_default("mix");
    snprintf(m.name, sizeof m.name, "mix%zu", sc->nmats);
    m.type = PF_MAT_MIX;
    m.mix[0] = a;
    m.mix[1] = b;
    m.amount = amount;
    m.amount_tex = tex;
    m.le = pf_v3s(3.0f);
    return (uint32_t)pf_scene_add_material(sc, &m);
}

/* The quad [-1, 1]^2 at z = 0 facing +z, uv (x + 1) / 2, (y + 1) / 2, of material mat. */
static void s_quad(pf_scene_t *sc, uint32_t mat, uint32_t alpha_tex)
{
    pf_mesh_t mesh;
    memset(&mesh, 0, sizeof mesh);
    snprintf(mesh.name, sizeof mesh.name, "quad");
    mesh.nverts = 4;
    mesh.ntris = 2;
    mesh.pos = malloc(4 * sizeof *mesh.pos);
    mesh.uv = malloc(8 * sizeof *mesh.uv);
    mesh.idx = malloc(6 * sizeof *mesh.idx);
    mesh.mat = malloc(2 * sizeof *mesh.mat);
    if (!mesh.pos || !mesh.uv || !mesh.idx || !mesh.mat)
        exit(2);
    const float xy[4][2] = { { -1, -1 }, { 1, -1 }, { 1, 1 }, { -1, 1 } };
    for (int i = 0; i < 4; i++) {
        mesh.pos[i] = pf_v3(xy[i][0], xy[i][1], 0.0f);
        mesh.uv[2 * i] = 0.5f * (xy[i][0] + 1.0f);
        mesh.uv[2 * i + 1] = 0.5f * (xy[i][1] + 1.0f);
    }
    const uint32_t idx[6] = { 0, 1, 2, 0, 2, 3 };
    memcpy(mesh.idx, idx, sizeof idx);
    mesh.mat[0] = mesh.mat[1] = mat;
    mesh.alpha_tex = alpha_tex;
    if (pf_scene_add_mesh(sc, &mesh) != PF_OK)
        exit(2);
}

static pf_accel_t *s_accel(pf_scene_t *sc)
{
    pf_error_t err;
    if (pf_scene_finalize(sc, &err) != PF_OK) {
        fprintf(stderr, "pf_scene_finalize: %s\n", err.msg);
        exit(2);
    }
    pf_accel_t *a = pf_accel_create(sc, &err);
    if (!a) {
        fprintf(stderr, "pf_accel_create: %s\n", err.msg);
        exit(2);
    }
    return a;
}

/* A ray from a random point above the quad to a random point on its inner 90 %. */
static pf_ray_t s_ray(uint64_t seed, uint64_t i, float *x)
{
    pf_rng_t r = pf_rng_make(seed, PF_STREAM_TEST, i, 0);
    pf_vec3 o = pf_v3(4.0f * pf_rng_float(&r) - 2.0f, 4.0f * pf_rng_float(&r) - 2.0f, 1.0f + 3.0f * pf_rng_float(&r));
    pf_vec3 t = pf_v3(1.8f * pf_rng_float(&r) - 0.9f, 1.8f * pf_rng_float(&r) - 0.9f, 0.0f);
    *x = t.x;
    return (pf_ray_t){ o, pf_norm(pf_sub(t, o)) };
}

static void s_test_amount(void)
{
    pf_scene_t *sc = s_scene();
    uint32_t a = s_mat(sc, PF_MAT_DIFFUSE, 0.2f, 0.0f), b = s_mat(sc, PF_MAT_DIFFUSE_TRANSMISSION, 0.9f, 0.1f);
    s_quad(sc, s_mix(sc, a, b, 0.3f, 0), 0);
    pf_accel_t *acc = s_accel(sc);
    const long N = 40000;
    long second = 0, hits = 0, unstable = 0, le = 0;
    double kd = 0.0;
    for (long i = 0; i < N; i++) {
        float x;
        pf_ray_t ray = s_ray(1, (uint64_t)i, &x);
        pf_hit_t h;
        if (!pf_accel_intersect(acc, &ray, INFINITY, &h))
            continue;
        hits++;
        pf_material_t m = pf_material_at(sc, &h), m2 = pf_material_at(sc, &h);
        second += m.type == PF_MAT_DIFFUSE_TRANSMISSION;
        kd += m.kd.x;
        unstable += m.type != m2.type;
        le += m.le.x == 3.0f;
    }
    double p = (double)second / (double)hits, se = sqrt(0.3 * 0.7 / (double)hits);
    CHECK(hits == N && fabs(p - 0.3) < 5.0 * se, "%ld hits, share of the second %.4f (want 0.3, se %.4f)", hits, p,
          se);
    CHECK(fabs(kd / hits - (0.3 * 0.9 + 0.7 * 0.2)) < 5.0 * se * 0.7 + 1e-6, "mean kd %.4f, want %.4f", kd / hits,
          0.3 * 0.9 + 0.7 * 0.2);
    CHECK(unstable == 0 && le == hits, "%ld hits resolved differently twice, %ld kept the mix's le", unstable, le);
    printf("mix amount 0.3: share %.4f of %ld hits (se %.4f)\n", p, hits, se);
    /* one point along rays of different lengths */
    long sec2 = 0, n2 = 0;
    for (long i = 0; i < 4000; i++) {
        pf_vec3 o = pf_v3(0.25f, 0.125f, 1.0f + 0.001f * (float)i);
        pf_ray_t ray = { o, pf_v3(0, 0, -1) };
        pf_hit_t h;
        if (!pf_accel_intersect(acc, &ray, INFINITY, &h))
            continue;
        n2++;
        sec2 += pf_material_at(sc, &h).type == PF_MAT_DIFFUSE_TRANSMISSION;
    }
    double p2 = (double)sec2 / (double)n2, se2 = sqrt(0.3 * 0.7 / (double)n2);
    CHECK(n2 == 4000 && fabs(p2 - 0.3) < 5.0 * se2, "one point, 4000 ray lengths: share %.4f", p2);
    pf_accel_destroy(&acc);
    pf_scene_destroy(&sc);
}

static void s_test_furnace_texture_nested(void)
{
    pf_scene_t *sc = s_scene();
    uint32_t a = s_mat(sc, PF_MAT_DIFFUSE, 1.0f, 0.0f), b = s_mat(sc, PF_MAT_DIFFUSE_TRANSMISSION, 0.4f, 0.6f);
    pf_texture_t t = pf_texture_constant("checker", pf_v3s(0.0f));
    t.type = PF_TEX_CHECKER;
    t.su = 2.0f;
    t.op[0].c = pf_v3s(0.0f);
    t.op[1].c = pf_v3s(1.0f);
    int tex = pf_scene_add_texture(sc, &t);
    CHECK(tex > 0);
    uint32_t lossless = s_mix(sc, a, b, 0.5f, 0), textured = s_mix(sc, a, b, 0.5f, (uint32_t)tex);
    uint32_t c = s_mat(sc, PF_MAT_DIFFUSE, 0.5f, 0.0f), inner = s_mix(sc, a, b, 0.3f, 0);
    uint32_t nested = s_mix(sc, inner, c, 0.5f, 0);
    s_quad(sc, lossless, 0);
    pf_accel_t *acc = s_accel(sc);
    long lossy = 0, wrong_side = 0, count[3] = { 0 }, hits = 0;
    for (long i = 0; i < 20000; i++) {
        float x;
        pf_ray_t ray = s_ray(2, (uint64_t)i, &x);
        pf_hit_t h;
        if (!pf_accel_intersect(acc, &ray, INFINITY, &h))
            continue;
        hits++;
        pf_material_t m = pf_material_at(sc, &h);
        lossy += fabsf(m.kd.x + (m.type == PF_MAT_DIFFUSE_TRANSMISSION ? m.kt.x : 0.0f) - 1.0f) > 1e-6f;
        h.mat = textured;
        m = pf_material_at(sc, &h);
        wrong_side += (m.type == PF_MAT_DIFFUSE_TRANSMISSION) != (h.p.x > 0.0f);
        h.mat = nested;
        m = pf_material_at(sc, &h);
        count[m.kd.x == 1.0f ? 0 : m.kd.x == 0.4f ? 1 : 2]++;
    }
    CHECK(hits == 20000 && lossy == 0, "furnace: %ld of %ld hits resolved to a lossy material", lossy, hits);
    CHECK(wrong_side == 0, "texture: %ld hits took the other half's material", wrong_side);
    double want[3] = { 0.35, 0.15, 0.5 };
    for (int k = 0; k < 3; k++) {
        double p = (double)count[k] / (double)hits, se = sqrt(want[k] * (1 - want[k]) / (double)hits);
        CHECK(fabs(p - want[k]) < 5.0 * se, "nested: part %d share %.4f, want %.2f", k, p, want[k]);
    }
    pf_accel_destroy(&acc);
    pf_scene_destroy(&sc);
}

static void s_test_checks_alpha(void)
{
    pf_error_t err;
    pf_scene_t *sc = s_scene();
    uint32_t a = s_mat(sc, PF_MAT_DIFFUSE, 0.5f, 0.0f);
    uint32_t self = s_mix(sc, a, a, 0.5f, 0);
    sc->mats[self].mix[1] = self;
    s_quad(sc, self, 0);
    CHECK(pf_scene_finalize(sc, &err) != PF_OK && strstr(err.msg, "cycle"), "a mix of itself: %s", err.msg);
    sc->mats[self].mix[1] = 99;
    CHECK(pf_scene_finalize(sc, &err) != PF_OK && strstr(err.msg, "out of range"), "index 99: %s", err.msg);
    pf_scene_destroy(&sc);

    /* a material's alpha texture: 0 on the left half, 1 on the right */
    sc = s_scene();
    pf_texture_t t = pf_texture_constant("mask", pf_v3s(0.0f));
    t.type = PF_TEX_CHECKER;
    t.su = 2.0f;
    t.op[0].c = pf_v3s(0.0f);
    t.op[1].c = pf_v3s(1.0f);
    int tex = pf_scene_add_texture(sc, &t);
    a = s_mat(sc, PF_MAT_DIFFUSE, 0.5f, 0.0f);
    sc->mats[a].alpha_tex = (uint32_t)tex;
    s_quad(sc, a, 0);
    pf_accel_t *acc = s_accel(sc);
    long wrong = 0;
    for (long i = 0; i < 2000; i++) {
        float x;
        pf_ray_t ray = s_ray(3, (uint64_t)i, &x);
        pf_hit_t h;
        int hit = pf_accel_intersect(acc, &ray, INFINITY, &h);
        wrong += hit != (x > 0.0f);
    }
    CHECK(wrong == 0, "alpha: %ld of 2000 rays hit where cut out or passed where opaque", wrong);
    pf_accel_destroy(&acc);
    pf_scene_destroy(&sc);
}

int main(void)
{
    s_test_amount();
    s_test_furnace_texture_nested();
    s_test_checks_alpha();
    return pf_test_finish();
}
