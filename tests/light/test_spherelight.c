/* test_spherelight.c: emissive analytic spheres as lights (light.h through
 * light/spherelight.c), on small scenes built in code.
 *
 * (a) Direct light's estimate of the irradiance at points below a sphere of
 *     radius r and radiance Le, fully above their horizon: the sphere's
 *     light field outside it is a point source's of intensity pi r^2 Le at
 *     its centre, so E = pi Le (r / d)^2 cos beta (d the distance to the
 *     centre, beta the angle of the centre off the normal), within 5
 *     standard errors and 0.2 %. Every sample lies on the part of the sphere
 *     the point sees. The estimate's variance is far below that of the same
 *     sphere tessellated (64 x 32, area sampling: half the samples land on
 *     its back), at least 100 x: measured 1.34e-5 against 0.484 (36000 x)
 *     under it, 2.6e-4 against 0.196 (740 x) off to the side, 4.1e-5
 *     against 0.83 on a tilted receiver.
 *     A point inside the sphere gets nothing (it emits outward).
 * (b) The pdf: for every sample on the sphere, pf_lights_pdf_at at its point
 *     equals the sample's pdf; the directions are uniform in the cone
 *     (chi-square on 1 - cos over 1 - cos theta_max, and on phi); and the
 *     pdf integrated over the directions that meet the sphere (a Monte Carlo
 *     sum over a wider cone) is the probability with which direct light picks
 *     it, counted. Both with the power table (sphere and a quad) and through
 *     the light BVH (four spheres and four quads of different radiance).
 * (d) Photons: their mean flux is the power per channel (pi 4 pi r^2 Le plus
 *     the quad's pi A Le); a sphere's photons start on it, uniformly (z
 *     uniform), their normal outward and their direction cosine-distributed
 *     about it (cos^2 uniform); the flux they bring onto a mirror quad facing
 *     the sphere is the point source's I Omega, both emitted plainly and aimed
 *     at the specular targets (pf_lights_emit_targeted).
 * Before this change a sphere whose material emits was refused by
 * pf_scene_finalize ("emissive spheres are not supported"): every part
 * fails. Randomness: pf_rng_make(seed, PF_STREAM_TEST, i, 0). */
#include <math.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "base/rng.h"
#include "base/sampling.h"
#include "base/vec.h"
#include "light/light.h"
#include "scene/scene.h"

#include "check.h"
#include "scenes_gen.h"

#define PI_D 3.14159265358979323846

typedef struct {
    double n, mean, m2;
} s_stat;

static void s_stat_add(s_stat *s, double x)
{
    s->n += 1.0;
    double d = x - s->mean;
    s->mean += d / s->n;
    s->m2 += d * (x - s->mean);
}

static double s_var(const s_stat *s) { return s->n > 1.0 ? s->m2 / (s->n - 1.0) : 0.0; }
static double s_se(const s_stat *s) { return s->n > 1.0 ? sqrt(s_var(s) / s->n) : 0.0; }

static double s_chi2(const long *count, int bins, long n)
{
    double e = (double)n / bins, x2 = 0.0;
    for (int i = 0; i < bins; i++)
        x2 += ((double)count[i] - e) * ((double)count[i] - e) / e;
    return x2;
}

static double s_chi2_limit(int dof) { return dof + 6.0 * sqrt(2.0 * dof); }

static void s_uniforms(uint64_t seed, uint64_t i, float *u, int n)
{
    pf_rng_t r = pf_rng_make(seed, PF_STREAM_TEST, i, 0);
    for (int k = 0; k < n; k++)
        u[k] = pf_rng_float(&r);
}

static uint32_t s_material(pf_scene_t *sc, pf_mat_type type, pf_vec3 kd, pf_vec3 le)
{
    pf_material_t m = pf_material_default("m");
    snprintf(m.name, sizeof m.name, "m%zu", sc->nmats);
    m.type = type;
    m.kd = kd;
    m.ks = pf_v3s(0.9f);
    m.le = le;
    int i = pf_scene_add_material(sc, &m);
    PF_CHECK(i >= 0);
    return (uint32_t)i;
}

/* A grey floor, 10 x 10 at y = 0, facing up. */
static void s_floor(pf_scene_t *sc)
{
    uint32_t m = s_material(sc, PF_MAT_DIFFUSE, pf_v3s(0.5f), pf_v3s(0.0f));
    pf_test_quad(sc, pf_v3(-5, 0, 5), pf_v3(10, 0, 0), pf_v3(0, 0, -10), m);
}

static void s_sphere(pf_scene_t *sc, pf_vec3 c, float r, uint32_t mat)
{
    pf_sphere_t s = { .center = c, .radius = r, .mat = mat };
    PF_CHECK(pf_scene_add_sphere(sc, &s) == PF_OK);
}

/* The sphere tessellated as pbrt_shape.c does (64 x 32 rows of latitude),
 * every triangle wound outward. */
static void s_uv_sphere(pf_scene_t *sc, pf_vec3 c, float r, uint32_t mat)
{
    const int nphi = 64, nth = 32;
    pf_mesh_t m = { 0 };
    snprintf(m.name, sizeof m.name, "uvsphere");
    m.nverts = (size_t)(nth + 1) * (nphi + 1);
    m.ntris = (size_t)2 * nth * nphi;
    m.pos = malloc(m.nverts * sizeof *m.pos);
    m.idx = malloc(3 * m.ntris * sizeof *m.idx);
    m.mat = malloc(m.ntris * sizeof *m.mat);
    PF_CHECK(m.pos && m.idx && m.mat);
    for (int i = 0; i <= nth; i++)
        for (int j = 0; j <= nphi; j++) {
            double th = PI_D * i / nth, ph = 2.0 * PI_D * j / nphi;
            m.pos[i * (nphi + 1) + j] = pf_add(c, pf_v3((float)(r * sin(th) * cos(ph)), (float)(r * cos(th)),
                                                        (float)(r * sin(th) * sin(ph))));
        }
    size_t t = 0;
    for (int i = 0; i < nth; i++)
        for (int j = 0; j < nphi; j++) {
            uint32_t a = (uint32_t)(i * (nphi + 1) + j), b = a + 1, d = a + (uint32_t)(nphi + 1), e = d + 1;
            uint32_t tri[2][3] = { { a, d, b }, { d, e, b } };
            for (int k = 0; k < 2; k++) {
                pf_vec3 p0 = m.pos[tri[k][0]], p1 = m.pos[tri[k][1]], p2 = m.pos[tri[k][2]];
                pf_vec3 n = pf_cross(pf_sub(p1, p0), pf_sub(p2, p0));
                if (pf_len2(n) == 0.0f)
                    continue; /* at a pole */
                if (pf_dot(n, pf_sub(pf_scale(pf_add(pf_add(p0, p1), p2), 1.0f / 3.0f), c)) < 0.0f) {
                    uint32_t s = tri[k][1];
                    tri[k][1] = tri[k][2];
                    tri[k][2] = s;
                }
                memcpy(&m.idx[3 * t], tri[k], sizeof tri[k]);
                m.mat[t++] = mat;
            }
        }
    m.ntris = t;
    PF_CHECK(pf_scene_add_mesh(sc, &m) == PF_OK);
}

static void s_finalize(pf_scene_t *sc)
{
    pf_error_t err;
    int rc = pf_scene_finalize(sc, &err);
    CHECK(rc == PF_OK, "pf_scene_finalize: %s", err.msg);
    if (rc != PF_OK)
        exit(pf_test_finish());
}

/* The irradiance on (x, n) from a sphere (c, r) of radiance le (channel y)
 * fully above the horizon: pi Le (r / d)^2 cos beta. */
static double s_sphere_irradiance(pf_vec3 c, float r, double le, pf_vec3 x, pf_vec3 n)
{
    pf_vec3 d = pf_sub(c, x);
    double d2 = pf_dot(d, d);
    return PI_D * le * r * r / d2 * pf_dot(d, n) / sqrt(d2);
}

/* Direct light's irradiance estimate at (x, n): mean and variance (channel y). */
static s_stat s_estimate(const pf_lights_t *lt, const pf_scene_t *sc, pf_vec3 x, pf_vec3 n, long count, uint64_t seed,
                         pf_vec3 c, float r, long *off)
{
    s_stat st = { 0 };
    for (long i = 0; i < count; i++) {
        float u[3];
        s_uniforms(seed, (uint64_t)i, u, 3);
        pf_light_conn_t lc;
        if (!pf_lights_sample_direct_at(lt, sc, x, n, u, &lc)) {
            s_stat_add(&st, 0.0);
            continue;
        }
        pf_vec3 p = pf_madd(x, lc.wi, lc.dist), pn = pf_scale(pf_sub(p, c), 1.0f / r);
        if (off && (fabsf(pf_len(pn) - 1.0f) > 1e-4f || pf_dot(pn, lc.wi) > 1e-4f))
            (*off)++; /* not on the sphere, or on the part x cannot see */
        s_stat_add(&st, lc.weight.y * fmax(0.0, pf_dot(lc.wi, n)));
    }
    return st;
}

/* ---- (a) irradiance ---- */

static void s_test_irradiance(void)
{
    const pf_vec3 c = pf_v3(0.0f, 2.0f, 0.0f), le = pf_v3(1.0f, 2.0f, 3.0f);
    const float r = 0.5f;
    pf_scene_t *sc = pf_scene_create(), *tess = pf_scene_create();
    s_sphere(sc, c, r, s_material(sc, PF_MAT_DIFFUSE, pf_v3s(0.0f), le));
    s_uv_sphere(tess, c, r, s_material(tess, PF_MAT_DIFFUSE, pf_v3s(0.0f), le));
    s_floor(sc);
    s_finalize(sc);
    s_finalize(tess);
    pf_lights_t *lt = pf_lights_build(sc), *lt_tess = pf_lights_build(tess);
    PF_CHECK(lt && lt_tess);
    double power = PI_D * 4.0 * PI_D * r * r * pf_luminance(le);
    CHECK(pf_lights_count(lt) == 1 && fabs(pf_lights_power(lt) / power - 1.0) < 1e-5,
          "%zu emitters of power %.6g, expected one of pi 4 pi r^2 lum(Le) = %.6g", pf_lights_count(lt),
          pf_lights_power(lt), power);
    const pf_vec3 xs[3] = { { 0, 0, 0 }, { 1.0f, 0, 0.5f }, { -0.5f, 0.3f, 0.2f } };
    const pf_vec3 ns[3] = { { 0, 1, 0 }, { 0, 1, 0 }, { 0.3f, 0.9f, -0.1f } };
    const long count = 200000;
    for (int k = 0; k < 3; k++) {
        pf_vec3 n = pf_norm(ns[k]);
        long off = 0;
        s_stat st = s_estimate(lt, sc, xs[k], n, count, 100 + (uint64_t)k, c, r, &off);
        s_stat tt = s_estimate(lt_tess, tess, xs[k], n, count, 100 + (uint64_t)k, c, r, NULL);
        double want = s_sphere_irradiance(c, r, le.y, xs[k], n);
        printf("irradiance at point %d: %.6f (se %.2g), tessellated %.6f (se %.2g), analytic %.6f; variance "
               "%.3g vs %.3g tessellated\n", k, st.mean, s_se(&st), tt.mean, s_se(&tt), want, s_var(&st), s_var(&tt));
        CHECK(off == 0, "point %d: %ld samples off the sphere's visible part", k, off);
        CHECK(fabs(st.mean - want) <= 5.0 * s_se(&st) && fabs(st.mean / want - 1.0) < 0.002,
              "point %d: irradiance %.6f, expected pi Le (r/d)^2 cos = %.6f (5 se %.2g)", k, st.mean, want,
              5.0 * s_se(&st));
        CHECK(s_var(&st) * 100.0 < s_var(&tt), "point %d: variance %.3g, not far below the tessellated sphere's %.3g",
              k, s_var(&st), s_var(&tt));
    }
    /* inside: the back of an outward emitter */
    long got = 0;
    for (long i = 0; i < 1000; i++) {
        float u[3];
        s_uniforms(7, (uint64_t)i, u, 3);
        pf_light_conn_t lc;
        got += pf_lights_sample_direct(lt, sc, pf_add(c, pf_v3(0.2f, -0.1f, 0.3f)), u, &lc);
    }
    CHECK(got == 0, "%ld samples reach a point inside the sphere", got);
    pf_vec3 inside = pf_add(c, pf_v3(0.2f, 0.0f, 0.0f)), on = pf_madd(c, pf_v3(1, 0, 0), r);
    CHECK(pf_lights_pdf(lt, sc, inside, (uint32_t)sc->nmeshes, 0, on) == 0.0f, "a pdf for a point inside the sphere");
    pf_lights_destroy(&lt);
    pf_lights_destroy(&lt_tess);
    pf_scene_destroy(&sc);
    pf_scene_destroy(&tess);
}

/* ---- (b) the pdf ---- */

/* Samples direct light at (x, n): every sample on sphere s must have the pdf
 * pf_lights_pdf_at gives its point; directions uniform in the cone; the pdf
 * integrated over the cone equals the sphere's pick frequency. */
static void s_check_pdf(const pf_scene_t *sc, const pf_lights_t *lt, uint32_t s, pf_vec3 x, pf_vec3 n, const char *what)
{
    const pf_sphere_t *sp = &sc->spheres[s];
    pf_vec3 axis = pf_norm(pf_sub(sp->center, x));
    double d = pf_len(pf_sub(sp->center, x)), sin2 = (double)sp->radius * sp->radius / (d * d);
    double om = sin2 / (1.0 + sqrt(1.0 - sin2)); /* 1 - cos theta_max */
    const long count = 400000;
    const int bins = 20;
    long hits = 0, bad = 0, hc[20] = { 0 }, hp[20] = { 0 };
    for (long i = 0; i < count; i++) {
        float u[3];
        s_uniforms(300 + s, (uint64_t)i, u, 3);
        pf_light_conn_t lc;
        if (!pf_lights_sample_direct_at(lt, sc, x, n, u, &lc))
            continue;
        pf_vec3 p = pf_madd(x, lc.wi, lc.dist);
        if (fabsf(pf_len(pf_sub(p, sp->center)) / sp->radius - 1.0f) > 1e-4f)
            continue; /* another light */
        hits++;
        float pdf = pf_lights_pdf_at(lt, sc, x, n, (uint32_t)sc->nmeshes, s, p);
        if (!(fabsf(pdf / lc.pdf - 1.0f) < 1e-5f))
            bad++;
        double t = (1.0 - pf_dot(lc.wi, axis)) / om;
        pf_vec3 tb, bb;
        pf_basis(axis, &tb, &bb);
        double phi = atan2(pf_dot(lc.wi, bb), pf_dot(lc.wi, tb)) / (2.0 * PI_D) + 0.5;
        hc[t < 0.0 ? 0 : t >= 1.0 ? bins - 1 : (int)(t * bins)]++;
        hp[phi < 0.0 ? 0 : phi >= 1.0 ? bins - 1 : (int)(phi * bins)]++;
    }
    CHECK(hits > 1000 && bad == 0, "%s: %ld of %ld samples on the sphere whose pf_lights_pdf_at differs", what, bad,
          hits);
    CHECK(s_chi2(hc, bins, hits) < s_chi2_limit(bins - 1), "%s: 1 - cos not uniform in the cone (chi2 %.1f)", what,
          s_chi2(hc, bins, hits));
    CHECK(s_chi2(hp, bins, hits) < s_chi2_limit(bins - 1), "%s: phi not uniform (chi2 %.1f)", what,
          s_chi2(hp, bins, hits));
    /* the pdf over the directions of a cone twice as wide (uniform in it):
     * sum pdf Omega / N over those that meet the sphere = the pick probability */
    double cos_w = 1.0 - 4.0 * om, omega = 2.0 * PI_D * (1.0 - cos_w);
    s_stat in = { 0 };
    for (long i = 0; i < count; i++) {
        float u[2];
        s_uniforms(400 + s, (uint64_t)i, u, 2);
        pf_vec3 w = pf_to_world(pf_sample_cone(u[0], u[1], (float)cos_w), axis);
        double b = pf_dot(w, pf_sub(sp->center, x)), disc = b * b - (d * d - (double)sp->radius * sp->radius);
        double v = 0.0;
        if (disc >= 0.0) { /* the near hit */
            pf_vec3 p = pf_madd(x, w, (float)(b - sqrt(disc)));
            v = pf_lights_pdf_at(lt, sc, x, n, (uint32_t)sc->nmeshes, s, p) * omega;
        }
        s_stat_add(&in, v);
    }
    double freq = (double)hits / count, se = sqrt(freq * (1.0 - freq) / count);
    printf("%s: %ld samples on the sphere, pick frequency %.5f, integrated pdf %.5f (se %.2g)\n", what, hits, freq,
           in.mean, s_se(&in));
    CHECK(fabs(in.mean - freq) <= 5.0 * sqrt(se * se + s_se(&in) * s_se(&in)),
          "%s: the pdf integrates to %.5f over the sphere, but it is picked with frequency %.5f", what, in.mean, freq);
}

static void s_test_pdf(void)
{
    /* the power table: the sphere and a quad above it */
    pf_scene_t *sc = pf_scene_create();
    s_sphere(sc, pf_v3(0.3f, 2.0f, -0.2f), 0.4f, s_material(sc, PF_MAT_DIFFUSE, pf_v3s(0.0f), pf_v3(3, 2, 1)));
    uint32_t qm = s_material(sc, PF_MAT_DIFFUSE, pf_v3s(0.0f), pf_v3s(1.0f));
    pf_test_quad(sc, pf_v3(-1, 3, -1), pf_v3(2, 0, 0), pf_v3(0, 0, 2), qm);
    s_floor(sc);
    s_finalize(sc);
    pf_lights_t *lt = pf_lights_build(sc);
    PF_CHECK(lt);
    s_check_pdf(sc, lt, 0, pf_v3(-0.4f, 0.0f, 0.3f), pf_v3(0, 1, 0), "power table");
    pf_lights_destroy(&lt);
    pf_scene_destroy(&sc);

    /* the light BVH: four spheres and four quads, each of its own radiance */
    sc = pf_scene_create();
    for (int i = 0; i < 4; i++) {
        float f = (float)(i + 1);
        s_sphere(sc, pf_v3(-3.0f + 2.0f * (float)i, 1.5f + 0.3f * (float)i, 0.5f), 0.2f + 0.1f * (float)i,
                 s_material(sc, PF_MAT_DIFFUSE, pf_v3s(0.0f), pf_v3s(f)));
        pf_test_quad(sc, pf_v3(-3.0f + 2.0f * (float)i, 4.0f, -2.0f), pf_v3(0.5f, 0, 0), pf_v3(0, 0, 0.5f),
                     s_material(sc, PF_MAT_DIFFUSE, pf_v3s(0.0f), pf_v3s(2.0f * f)));
    }
    s_floor(sc);
    s_finalize(sc);
    lt = pf_lights_build(sc);
    PF_CHECK(lt);
    s_check_pdf(sc, lt, 1, pf_v3(-0.5f, 0.0f, 0.2f), pf_norm(pf_v3(0.2f, 1.0f, 0.1f)), "light BVH, sphere 1");
    s_check_pdf(sc, lt, 3, pf_v3(-0.5f, 0.0f, 0.2f), pf_norm(pf_v3(0.2f, 1.0f, 0.1f)), "light BVH, sphere 3");
    pf_lights_destroy(&lt);
    pf_scene_destroy(&sc);
}

/* ---- (d) photons ---- */

/* The flux (channel y) a photon brings onto the square of side a centred
 * at (0, h, 0) in the plane y = h, 0 when it misses. */
static double s_square_flux(const pf_emission_t *e, float a, float h)
{
    if (!(e->ray.d.y > 0.0f))
        return 0.0;
    float t = (h - e->ray.o.y) / e->ray.d.y;
    pf_vec3 q = pf_madd(e->ray.o, e->ray.d, t);
    return t > 0.0f && fabsf(q.x) <= 0.5f * a && fabsf(q.z) <= 0.5f * a ? e->flux.y : 0.0;
}

static void s_test_photons(void)
{
    const float r = 0.3f, a = 1.0f, h = 2.0f;
    const pf_vec3 le = pf_v3(1.0f, 2.0f, 3.0f), c = pf_v3s(0.0f);
    pf_scene_t *sc = pf_scene_create();
    s_sphere(sc, c, r, s_material(sc, PF_MAT_DIFFUSE, pf_v3s(0.0f), le));
    /* a quad light far to the side, facing away from the mirror */
    uint32_t qm = s_material(sc, PF_MAT_DIFFUSE, pf_v3s(0.0f), pf_v3s(0.5f));
    pf_test_quad(sc, pf_v3(4, 1, 0), pf_v3(1, 0, 0), pf_v3(0, 0, 1), qm);
    /* the mirror square at y = h facing down */
    uint32_t mm = s_material(sc, PF_MAT_MIRROR, pf_v3s(0.0f), pf_v3s(0.0f));
    pf_test_quad(sc, pf_v3(-0.5f * a, h, -0.5f * a), pf_v3(a, 0, 0), pf_v3(0, 0, a), mm);
    s_finalize(sc);
    pf_lights_t *lt = pf_lights_build(sc);
    PF_CHECK(lt);
    double area = 4.0 * PI_D * r * r;
    const double lec[3] = { le.x, le.y, le.z };
    const long count = 400000;
    s_stat flux[3] = { { 0 } }, onto = { 0 }, onto_t = { 0 };
    long bins_z[20] = { 0 }, bins_c[20] = { 0 }, nsph = 0, bad = 0;
    for (long i = 0; i < count; i++) {
        float u[6];
        s_uniforms(500, (uint64_t)i, u, 6);
        pf_emission_t e;
        PF_CHECK(pf_lights_emit(lt, sc, u, &e));
        s_stat_add(&flux[0], e.flux.x);
        s_stat_add(&flux[1], e.flux.y);
        s_stat_add(&flux[2], e.flux.z);
        pf_vec3 q = pf_scale(pf_sub(e.ray.o, c), 1.0f / r);
        int on = fabsf(pf_len(q) - 1.0f) < 1e-4f;
        s_stat_add(&onto, on ? s_square_flux(&e, a, h) : 0.0);
        if (!on)
            continue;
        nsph++;
        float cos = pf_dot(e.ray.d, e.n);
        if (pf_dot(e.n, q) < 0.9999f || !(cos > 0.0f))
            bad++;
        int bz = (int)((q.y + 1.0f) * 10.0f), bc = (int)(cos * cos * 20.0f);
        bins_z[bz < 0 ? 0 : bz > 19 ? 19 : bz]++;
        bins_c[bc < 0 ? 0 : bc > 19 ? 19 : bc]++;
    }
    for (int ch = 0; ch < 3; ch++) {
        double want = PI_D * area * lec[ch] + PI_D * 1.0 * 0.5;
        CHECK(fabs(flux[ch].mean - want) <= 5.0 * s_se(&flux[ch]) + 1e-6 * want,
              "channel %d: photons carry %.5f on average, the power is %.5f", ch, flux[ch].mean, want);
    }
    CHECK(nsph > 1000 && bad == 0, "%ld of %ld sphere photons with a normal not outward or a direction behind it", bad,
          nsph);
    CHECK(s_chi2(bins_z, 20, nsph) < s_chi2_limit(19), "sphere photons' origins not uniform (chi2 on z %.1f)",
          s_chi2(bins_z, 20, nsph));
    CHECK(s_chi2(bins_c, 20, nsph) < s_chi2_limit(19), "sphere photons' directions not cosine-weighted (chi2 %.1f)",
          s_chi2(bins_c, 20, nsph));

    /* onto the mirror: I Omega, I = pi r^2 Le, Omega the square's from the centre */
    pf_target_t *tg = NULL;
    int nt = pf_specular_targets(sc, &tg);
    CHECK(nt == 1, "%d specular targets, expected the mirror", nt);
    for (long i = 0; nt == 1 && i < count; i++) {
        float u[6];
        s_uniforms(600, (uint64_t)i, u, 6);
        pf_emission_t e;
        int on = pf_lights_emit_targeted(lt, sc, tg, 1, u, &e) && fabsf(pf_len(pf_sub(e.ray.o, c)) / r - 1.0f) < 1e-4f;
        s_stat_add(&onto_t, on ? s_square_flux(&e, a, h) : 0.0);
    }
    free(tg);
    double omega = 4.0 * asin(a * a / ((a * a + 4.0 * h * h))), want = PI_D * r * r * le.y * omega;
    printf("photons onto the mirror: %.5f (se %.2g), aimed %.5f (se %.2g), analytic %.5f\n", onto.mean, s_se(&onto),
           onto_t.mean, s_se(&onto_t), want);
    CHECK(fabs(onto.mean - want) <= 5.0 * s_se(&onto), "photons bring %.5f onto the mirror, expected %.5f", onto.mean,
          want);
    CHECK(fabs(onto_t.mean - want) <= 5.0 * s_se(&onto_t) && fabs(onto_t.mean / want - 1.0) < 0.01,
          "aimed photons bring %.5f onto the mirror, expected %.5f", onto_t.mean, want);
    pf_lights_destroy(&lt);
    pf_scene_destroy(&sc);
}

int main(void)
{
    s_test_irradiance();
    s_test_pdf();
    s_test_photons();
    return pf_test_finish();
}
