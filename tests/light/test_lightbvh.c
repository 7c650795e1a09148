/* test_lightbvh.c: direct light's choice among many emitters (the light BVH,
 * light/lightbvh.h, behind pf_lights_sample_direct_at / pf_lights_pdf_at).
 *
 * (a) Many lights: 100 small quads of radiances 1..100 spread over a 20 x 20
 *     ceiling 2 above a floor. At 16 floor points the one-sample irradiance
 *     estimator's relative variance (var / E^2, E exact by Lambert's polygon
 *     formula) must be at least 3x lower than that of the same estimator with
 *     the emitter picked by power (the old table's choice, emulated here with
 *     the same uniforms), and its mean must be E within 5 standard errors.
 * (b) The pmf: at a few receivers (normal up, tilted, none) the BVH's
 *     sampler picks each item as often as pf_lightbvh_pmf says (chi-square),
 *     the pmfs sum to 1 (or to 1 - P(nothing chosen) above the emitters, where
 *     pbrt's walk may end in a dark pair of children), the sampler reports the very pmf pf_lightbvh_pmf
 *     computes, and pf_lights_pdf_at gives back each connection's pdf.
 * (c) The same quads with a constant sky and a sun: the estimate is still the
 *     exact irradiance (the sun apart, pf_lights_distant) and sky connections
 *     carry pf_lights_sky_pdf's pdf.
 * Randomness is pf_rng_make(seed, PF_STREAM_TEST, i, 0). */
#include <math.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "base/rng.h"
#include "base/sampling.h"
#include "base/vec.h"
#include "light/light.h"
#include "light/lightbvh.h"
#include "scene/scene.h"

#include "check.h"

#define NQ 100
#define SIDE 0.1f
#define HEIGHT 2.0f

static void *s_alloc(size_t n)
{
    void *p = calloc(1, n);
    if (!p) {
        fprintf(stderr, "out of memory\n");
        exit(2);
    }
    return p;
}

static float s_radiance(int k) { return 1.0f + 99.0f * (float)((k * 37) % NQ) / (NQ - 1); }

/* The corner of quad k: a 10 x 10 grid of pitch 2 over [-10, 10]^2, jittered. */
static pf_vec3 s_corner(int k)
{
    pf_rng_t r = pf_rng_make(77, PF_STREAM_TEST, (uint64_t)k, 0);
    float jx = pf_rng_float(&r), jz = pf_rng_float(&r);
    return pf_v3(-10.0f + 2.0f * (float)(k % 10) + 1.8f * jx, HEIGHT, -10.0f + 2.0f * (float)(k / 10) + 1.8f * jz);
}

/* The scene: NQ emissive quads facing down (x then z: normal -y), one mesh
 * each, plus a floor so that the scene has a size. */
static pf_scene_t *s_scene(int with_sky)
{
    pf_scene_t *sc = pf_scene_create();
    if (!sc)
        exit(2);
    if (with_sky) { /* a constant sky L = 0.05 and a sun E = 0.2 along (0.3, -1, 0.2) */
        pf_light_t sky = { .type = PF_LIGHT_INFINITE, .intensity = pf_v3s(0.05f) };
        pf_light_t sun = { .type = PF_LIGHT_DISTANT, .intensity = pf_v3s(0.2f), .dir = pf_norm(pf_v3(0.3f, -1, 0.2f)) };
        if (pf_scene_add_light(sc, &sky) < 0 || pf_scene_add_light(sc, &sun) < 0)
            exit(2);
    }
    pf_material_t floor = pf_material_default("floor");
    int fm = pf_scene_add_material(sc, &floor);
    for (int k = 0; k <= NQ; k++) {
        int mat = fm;
        if (k < NQ) {
            pf_material_t m = pf_material_default("m");
            snprintf(m.name, sizeof m.name, "e%d", k);
            m.kd = pf_v3s(0.0f);
            m.le = pf_v3s(s_radiance(k));
            mat = pf_scene_add_material(sc, &m);
        }
        pf_mesh_t mesh;
        memset(&mesh, 0, sizeof mesh);
        snprintf(mesh.name, sizeof mesh.name, "q%d", k);
        mesh.nverts = 4;
        mesh.ntris = 2;
        mesh.pos = s_alloc(4 * sizeof *mesh.pos);
        mesh.idx = s_alloc(6 * sizeof *mesh.idx);
        mesh.mat = s_alloc(2 * sizeof *mesh.mat);
        pf_vec3 c = k < NQ ? s_corner(k) : pf_v3(-11, 0, -11);
        float s = k < NQ ? SIDE : 22.0f;
        pf_vec3 u = pf_v3(s, 0, 0), v = pf_v3(0, 0, s);
        if (k == NQ) { /* the floor faces up */
            u = pf_v3(0, 0, s);
            v = pf_v3(s, 0, 0);
        }
        mesh.pos[0] = c;
        mesh.pos[1] = pf_add(c, u);
        mesh.pos[2] = pf_add(pf_add(c, u), v);
        mesh.pos[3] = pf_add(c, v);
        const uint32_t idx[6] = { 0, 1, 2, 0, 2, 3 };
        memcpy(mesh.idx, idx, sizeof idx);
        mesh.mat[0] = mesh.mat[1] = (uint32_t)mat;
        if (pf_scene_add_mesh(sc, &mesh) != PF_OK || mat < 0)
            exit(2);
    }
    pf_error_t err;
    if (pf_scene_finalize(sc, &err) != PF_OK)
        exit(2);
    return sc;
}

/* Irradiance at x (normal n) from quad k: Lambert's polygon formula, in
 * double with the edge angles by atan2 (acos of a float dot loses the small
 * angles of far quads). */
static double s_quad_irradiance(int k, pf_vec3 x, pf_vec3 n)
{
    pf_vec3 c = s_corner(k);
    double q[4][3] = { { c.x, c.y, c.z }, { c.x + SIDE, c.y, c.z }, { c.x + SIDE, c.y, c.z + SIDE },
                       { c.x, c.y, c.z + SIDE } };
    double sum = 0.0;
    for (int i = 0; i < 4; i++) {
        const double *p0 = q[i], *p1 = q[(i + 1) % 4];
        double a[3] = { p0[0] - x.x, p0[1] - x.y, p0[2] - x.z }, b[3] = { p1[0] - x.x, p1[1] - x.y, p1[2] - x.z };
        double cr[3] = { a[1] * b[2] - a[2] * b[1], a[2] * b[0] - a[0] * b[2], a[0] * b[1] - a[1] * b[0] };
        double lc = sqrt(cr[0] * cr[0] + cr[1] * cr[1] + cr[2] * cr[2]);
        double th = atan2(lc, a[0] * b[0] + a[1] * b[1] + a[2] * b[2]);
        sum += th * (n.x * cr[0] + n.y * cr[1] + n.z * cr[2]) / lc;
    }
    return 0.5 * s_radiance(k) * fabs(sum);
}

static pf_vec3 s_receiver(int i)
{
    pf_rng_t r = pf_rng_make(78, PF_STREAM_TEST, (uint64_t)i, 0);
    float a = pf_rng_float(&r), b = pf_rng_float(&r);
    return pf_v3(-9.0f + 18.0f * a, 0.0f, -9.0f + 18.0f * b);
}

/* One-sample estimate with the emitter picked by power (the old table): a
 * quad k with probability Le_k / sum Le, a point uniform on it. */
static double s_power_sample(pf_vec3 x, pf_vec3 n, const float u[3], double total)
{
    double acc = 0.0, t = u[0] * total;
    int k = 0;
    for (; k < NQ - 1; k++) {
        acc += s_radiance(k);
        if (t < acc)
            break;
    }
    double pk = s_radiance(k) / total;
    pf_vec3 p = pf_add(s_corner(k), pf_v3(SIDE * u[1], 0, SIDE * u[2]));
    pf_vec3 d = pf_sub(p, x);
    double d2 = pf_len2(d), dist = sqrt(d2);
    double cos_l = d.y / dist, cos_r = pf_dot(d, n) / dist; /* the quads face down */
    if (cos_l <= 0.0 || cos_r <= 0.0)
        return 0.0;
    return s_radiance(k) * cos_l * cos_r * (double)(SIDE * SIDE) / (d2 * pk);
}

static void s_test_many(const pf_scene_t *sc, const pf_lights_t *lt)
{
    const int npts = 16, ns = 4096;
    double total = 0.0;
    for (int k = 0; k < NQ; k++)
        total += s_radiance(k);
    pf_vec3 n = pf_v3(0, 1, 0);
    double rv_bvh = 0.0, rv_pow = 0.0;
    int biased = 0;
    for (int i = 0; i < npts; i++) {
        pf_vec3 x = s_receiver(i);
        double e = 0.0;
        for (int k = 0; k < NQ; k++)
            e += s_quad_irradiance(k, x, n);
        double s1 = 0, s2 = 0, t1 = 0, t2 = 0;
        for (int j = 0; j < ns; j++) {
            pf_rng_t r = pf_rng_make(79, PF_STREAM_TEST, (uint64_t)(i * ns + j), 0);
            float u[3] = { pf_rng_float(&r), pf_rng_float(&r), pf_rng_float(&r) };
            pf_light_conn_t c;
            double v = 0.0;
            if (pf_lights_sample_direct_at(lt, sc, x, n, u, &c))
                v = c.weight.y * fmax(0.0, c.wi.y);
            s1 += v, s2 += v * v;
            double w = s_power_sample(x, n, u, total);
            t1 += w, t2 += w * w;
        }
        double m = s1 / ns, var = s2 / ns - m * m, mp = t1 / ns, varp = t2 / ns - mp * mp;
        if (fabs(m - e) > 5.0 * sqrt(var / ns) + 1e-6 * e) {
            biased++;
            fprintf(stderr, "  point %d: BVH mean %.5g, exact %.5g (5 se %.3g)\n", i, m, e, 5.0 * sqrt(var / ns));
        }
        rv_bvh += var / (e * e) / npts;
        rv_pow += varp / (e * e) / npts;
    }
    printf("relative variance per sample: BVH %.4g, power %.4g (%.1fx)\n", rv_bvh, rv_pow, rv_pow / rv_bvh);
    CHECK(biased == 0, "%d of %d points: the BVH estimate is not the exact irradiance", biased, npts);
    CHECK(rv_pow >= 3.0 * rv_bvh, "relative variance with the BVH %.4g, by power %.4g: not 3x lower", rv_bvh, rv_pow);
}

/* Item bounds for the pmf test: the quads' triangles as light.c makes them,
 * plus point lights and a spot. */
static size_t s_items(pf_light_bounds_t *b, uint32_t *id)
{
    size_t n = 0;
    for (int k = 0; k < NQ; k++) {
        pf_vec3 c = s_corner(k);
        for (int t = 0; t < 2; t++) {
            b[n] = (pf_light_bounds_t){ .lo = c, .hi = pf_add(c, pf_v3(SIDE, 0, SIDE)), .phi = s_radiance(k),
                                        .w = pf_v3(0, -1, 0), .cos_theta_o = 1.0f, .cos_theta_e = 0.0f };
            id[n] = (uint32_t)(3 * n + 1); /* ids need not be dense */
            n++;
        }
    }
    for (int k = 0; k < 6; k++) {
        pf_vec3 p = pf_v3(-8.0f + 3.0f * k, 1.0f + 0.2f * k, 4.0f - k);
        b[n] = (pf_light_bounds_t){ .lo = p, .hi = p, .phi = 50.0f * (k + 1), .w = pf_v3(0, 0, 1),
                                    .cos_theta_o = k == 5 ? 0.9f : -1.0f, .cos_theta_e = k == 5 ? 0.95f : 0.0f };
        if (k == 5)
            b[n].w = pf_v3(0, -1, 0);
        id[n] = (uint32_t)(3 * n + 1);
        n++;
    }
    return n;
}

static void s_test_pmf(void)
{
    pf_light_bounds_t b[2 * NQ + 6];
    uint32_t id[2 * NQ + 6];
    size_t n = s_items(b, id);
    pf_lightbvh_t *bvh = pf_lightbvh_build(b, id, n);
    CHECK(bvh != NULL, "light BVH build failed");
    if (!bvh)
        return;
    const pf_vec3 xs[4] = { pf_v3(0, 0, 0), pf_v3(7, 0.5f, -3), pf_v3(-9, 0, 9), pf_v3(2, 3, 1) };
    const pf_vec3 ns[4] = { pf_v3(0, 1, 0), pf_norm(pf_v3(1, 1, 0)), pf_v3(0, 0, 0), pf_v3(0, -1, 0) };
    const long nsamp = 400000;
    long *cnt = s_alloc(3 * (2 * NQ + 6) * sizeof *cnt);
    for (int q = 0; q < 4; q++) {
        memset(cnt, 0, 3 * (2 * NQ + 6) * sizeof *cnt);
        long none = 0, mismatch = 0;
        for (long i = 0; i < nsamp; i++) {
            pf_rng_t r = pf_rng_make(80 + (uint64_t)q, PF_STREAM_TEST, (uint64_t)i, 0);
            uint32_t got;
            float pmf;
            if (!pf_lightbvh_sample(bvh, xs[q], ns[q], pf_rng_float(&r), &got, &pmf)) {
                none++;
                continue;
            }
            cnt[got]++;
            mismatch += pmf != pf_lightbvh_pmf(bvh, xs[q], ns[q], got);
        }
        double sum = 0.0, x2 = 0.0;
        int dof = 0;
        long zero_picked = 0;
        for (size_t i = 0; i < n; i++) {
            double p = pf_lightbvh_pmf(bvh, xs[q], ns[q], id[i]);
            sum += p;
            if (p == 0.0) {
                zero_picked += cnt[id[i]];
                continue;
            }
            double e = p * (double)nsamp;
            x2 += (cnt[id[i]] - e) * (cnt[id[i]] - e) / e;
            dof++;
        }
        dof--;
        CHECK(mismatch == 0, "receiver %d: %ld samples whose pmf is not pf_lightbvh_pmf's", q, mismatch);
        /* pbrt's walk gives up where both children are dark (bounds looser
         * than their parent's): the pmfs then sum to 1 - P(nothing) */
        double pn = (double)none / nsamp, sd = sqrt(fmax(pn * (1.0 - pn), 1e-12) / nsamp);
        CHECK(sum <= 1.0 + 1e-5 && fabs(sum + pn - 1.0) <= 5.0 * sd + 1e-5, "receiver %d: pmfs sum to %.7f, P(none) %.5f",
              q, sum, pn);
        if (q < 3)
            CHECK(fabs(sum - 1.0) < 1e-5 && none == 0, "receiver %d below lit emitters: pmfs sum to %.7f", q, sum);
        CHECK(zero_picked == 0, "receiver %d: %ld picks of items of pmf 0", q, zero_picked);
        CHECK(x2 <= dof + 6.0 * sqrt(2.0 * dof), "receiver %d: chi-square %.1f for %d dof", q, x2, dof);
        printf("receiver %d: pmf sum %.7f, chi-square %.1f / %d dof, %ld none\n", q, sum, x2, dof, none);
    }
    CHECK(pf_lightbvh_pmf(bvh, xs[0], ns[0], 0) == 0.0f, "an id not in the tree has pmf 0");
    free(cnt);
    pf_lightbvh_destroy(&bvh);
}

/* pf_lights_pdf_at gives back the pdf of each connection (quad k is mesh k + 1:
 * the floor's material comes first but meshes are in order; triangle 0 holds
 * the points with local a >= b). */
static void s_test_pdf(const pf_scene_t *sc, const pf_lights_t *lt)
{
    long bad = 0, checked = 0;
    pf_vec3 n = pf_v3(0, 1, 0);
    for (int i = 0; i < 4000; i++) {
        pf_vec3 x = s_receiver(i % 16);
        pf_rng_t r = pf_rng_make(81, PF_STREAM_TEST, (uint64_t)i, 0);
        float u[3] = { pf_rng_float(&r), pf_rng_float(&r), pf_rng_float(&r) };
        pf_light_conn_t c;
        if (!pf_lights_sample_direct_at(lt, sc, x, n, u, &c))
            continue;
        pf_vec3 p = pf_madd(x, c.wi, c.dist);
        int k = -1;
        for (int j = 0; j < NQ && k < 0; j++) {
            pf_vec3 d = pf_sub(p, s_corner(j));
            if (d.x >= -1e-4f && d.z >= -1e-4f && d.x <= SIDE + 1e-4f && d.z <= SIDE + 1e-4f)
                k = j;
        }
        if (k < 0) {
            bad++;
            continue;
        }
        pf_vec3 d = pf_sub(p, s_corner(k));
        float a = d.x / SIDE, bb = d.z / SIDE;
        if (fabsf(a - bb) < 1e-3f)
            continue; /* on the diagonal: either triangle */
        float pdf = pf_lights_pdf_at(lt, sc, x, n, (uint32_t)k, a >= bb ? 0u : 1u, p);
        checked++;
        if (!(fabs(pdf / c.pdf - 1.0) < 1e-3))
            bad++;
    }
    CHECK(checked > 3000 && bad == 0, "%ld of %ld connections whose pf_lights_pdf_at differs from their pdf", bad,
          checked);
}

/* With a sky and a sun beside the quads (p_inf, the sky's pdf mixed in):
 * the estimate stays the exact irradiance (quads + pi L + E cos, nothing
 * occludes here), and every sky connection's pdf is pf_lights_sky_pdf's. */
static void s_test_sky(void)
{
    pf_scene_t *sc = s_scene(1);
    pf_lights_t *lt = pf_lights_build(sc);
    CHECK(lt != NULL, "pf_lights_build failed (sky)");
    if (!lt) {
        pf_scene_destroy(&sc);
        return;
    }
    pf_vec3 n = pf_v3(0, 1, 0);
    long badpdf = 0, nsky = 0, nsun = 0;
    int biased = 0;
    const int ns = 20000;
    for (int i = 0; i < 4; i++) {
        pf_vec3 x = s_receiver(i);
        double e = PF_PI * 0.05, s1 = 0.0, s2 = 0.0; /* the sun apart: pf_lights_distant */
        for (int k = 0; k < NQ; k++)
            e += s_quad_irradiance(k, x, n);
        for (int j = 0; j < ns; j++) {
            pf_rng_t r = pf_rng_make(82, PF_STREAM_TEST, (uint64_t)(i * ns + j), 0);
            float u[3] = { pf_rng_float(&r), pf_rng_float(&r), pf_rng_float(&r) };
            pf_light_conn_t c;
            double v = 0.0;
            if (pf_lights_sample_direct_at(lt, sc, x, n, u, &c)) {
                v = c.weight.y * fmax(0.0, c.wi.y);
                if (isinf(c.dist) && c.pdf > 0.0f) {
                    nsky++;
                    badpdf += fabsf(c.pdf - pf_lights_sky_pdf(lt, n, c.wi)) > 1e-6f * c.pdf;
                } else if (isinf(c.dist)) {
                    nsun++;
                }
            }
            s1 += v, s2 += v * v;
        }
        double m = s1 / ns, se = sqrt((s2 / ns - m * m) / ns);
        if (fabs(m - e) > 5.0 * se + 1e-5 * e) {
            biased++;
            fprintf(stderr, "  sky point %d: mean %.5g, exact %.5g (5 se %.3g)\n", i, m, e, 5.0 * se);
        }
    }
    printf("sky + sun + quads: %ld sky and %ld sun connections of %d\n", nsky, nsun, 4 * ns);
    CHECK(biased == 0, "%d of 4 points: with a sky and a sun the estimate is not the exact irradiance", biased);
    CHECK(nsun == 0 && pf_lights_distant_count(lt) == 1, "the sun is taken apart");
    CHECK(nsky > 0 && badpdf == 0, "%ld of %ld sky connections with a pdf other than pf_lights_sky_pdf's",
          badpdf, nsky);
    pf_lights_destroy(&lt);
    pf_scene_destroy(&sc);
}

int main(void)
{
    pf_scene_t *sc = s_scene(0);
    pf_lights_t *lt = pf_lights_build(sc);
    CHECK(lt != NULL, "pf_lights_build failed");
    if (lt) {
        s_test_many(sc, lt);
        s_test_pdf(sc, lt);
    }
    s_test_pmf();
    s_test_sky();
    pf_lights_destroy(&lt);
    pf_scene_destroy(&sc);
    return pf_test_finish();
}
