/* test_bsdf.c: statistical and analytic tests of the scattering code
 * (material/bsdf.h/.c), the local frame of base/vec.h and the octahedral
 * direction code of photon/photon.h.
 *
 * Sampling routines are checked against the pdfs their headers state: a
 * chi-square test over (cos theta, phi) bins of equal probability under the
 * stated pdf, moments with known values, and Monte Carlo integrals that use
 * pf_phong_pdf, so that a wrong pdf, a missing cosine or a stray factor of 2
 * or pi fails while sampling noise does not. Statistical bounds are 5 standard
 * errors (estimated from the samples) or, for chi-square, dof + 6 sqrt(2 dof),
 * which noise exceeds with probability well under 1e-6. All randomness comes
 * from pf_rng_make(seed, PF_STREAM_TEST, i, 0), so every run sees the same
 * numbers.
 *
 * Fresnel and Snell are checked against closed forms (normal incidence,
 * Brewster's angle, the critical angle) and a double-precision reference; the
 * Phong BRDF with a white-furnace integral and reciprocity. */
#include <math.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "base/rng.h"
#include "base/vec.h"
#include "material/bsdf.h"
#include "photon/photon.h"

#include "check.h"


/* CHECK(cond, fmt, ...): counts the check; on failure prints where, what was
 * tested and the message (expected and got). */

#define PI_D 3.14159265358979323846

/* ---- randomness and small helpers ---- */

/* Two uniforms for sample i of a test identified by seed. */
static void s_u2(uint64_t seed, uint64_t i, float *u1, float *u2)
{
    pf_rng_t r = pf_rng_make(seed, PF_STREAM_TEST, i, 0);
    *u1 = pf_rng_float(&r);
    *u2 = pf_rng_float(&r);
}

/* A uniformly random unit vector (independent of the code under test). */
static pf_vec3 s_rand_dir(pf_rng_t *r)
{
    for (;;) {
        float x = 2.0f * pf_rng_float(r) - 1.0f, y = 2.0f * pf_rng_float(r) - 1.0f, z = 2.0f * pf_rng_float(r) - 1.0f;
        float l2 = x * x + y * y + z * z;
        if (l2 > 1e-4f && l2 <= 1.0f)
            return pf_scale(pf_v3(x, y, z), 1.0f / sqrtf(l2));
    }
}

static double s_dot_d(pf_vec3 a, pf_vec3 b) { return (double)a.x * b.x + (double)a.y * b.y + (double)a.z * b.z; }
static double s_len_d(pf_vec3 a) { return sqrt(s_dot_d(a, a)); }

/* |a x b| in double: the sine of the angle between unit vectors. */
static double s_sin_d(pf_vec3 a, pf_vec3 b)
{
    double cx = (double)a.y * b.z - (double)a.z * b.y;
    double cy = (double)a.z * b.x - (double)a.x * b.z;
    double cz = (double)a.x * b.y - (double)a.y * b.x;
    return sqrt(cx * cx + cy * cy + cz * cz);
}

/* Angle between two vectors in double, accurate for tiny angles. */
static double s_angle(pf_vec3 a, pf_vec3 b)
{
    double cx = (double)a.y * b.z - (double)a.z * b.y;
    double cy = (double)a.z * b.x - (double)a.x * b.z;
    double cz = (double)a.x * b.y - (double)a.y * b.x;
    return atan2(sqrt(cx * cx + cy * cy + cz * cz), s_dot_d(a, b));
}

/* Running mean and variance (Welford), for standard errors. */
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

/* Standard error of the mean. */
static double s_stat_se(const s_stat *s) { return s->n > 1.0 ? sqrt(s->m2 / (s->n - 1.0) / s->n) : 0.0; }

/* Pearson's chi-square of counts against equal expected probabilities. */
static double s_chi2_equal(const long *count, int bins, long n)
{
    double e = (double)n / bins, x2 = 0.0;
    for (int i = 0; i < bins; i++)
        x2 += ((double)count[i] - e) * ((double)count[i] - e) / e;
    return x2;
}

/* An upper bound for a chi-square statistic with dof degrees of freedom that
 * noise exceeds with probability < 1e-6 (for dof >= 15). */
static double s_chi2_limit(int dof) { return dof + 6.0 * sqrt(2.0 * dof); }

/* ---- 1. sampling routines against their pdfs ---- */

enum { K_COSINE, K_SPHERE, K_CONE, K_PHONG };

static pf_vec3 s_sample(int kind, float u1, float u2, float param)
{
    switch (kind) {
    case K_COSINE: return pf_sample_cosine(u1, u2);
    case K_SPHERE: return pf_sample_sphere(u1, u2);
    case K_CONE: return pf_sample_cone(u1, u2, param);
    default: return pf_sample_phong(u1, u2, param);
    }
}

/* The CDF of cos theta under the header's pdf, derived independently:
 * cosine: pdf cos/pi -> P(cos <= c) = c^2; sphere: (c + 1) / 2;
 * cone: uniform in cos over [cos_max, 1]; Phong: (n+1) c^n dc -> c^(n+1). */
static double s_cos_cdf(int kind, double c, double param)
{
    switch (kind) {
    case K_COSINE: return c * c;
    case K_SPHERE: return 0.5 * (c + 1.0);
    case K_CONE: return (c - param) / (1.0 - param);
    default: return pow(c, param + 1.0);
    }
}

/* Lowest cos theta of the sampling domain. */
static double s_cos_min(int kind, double param)
{
    return kind == K_SPHERE ? -1.0 : kind == K_CONE ? param : 0.0;
}

/* Bins (cos theta, phi) into 16 x 16 cells of equal probability under the
 * stated pdf and checks the counts; checks every sample is unit length and
 * inside the domain; and checks E[cos] against its closed form. */
static void s_test_sampler(int kind, const char *name, float param, uint64_t seed)
{
    enum { NC = 16, NP = 16, N = 256000 };
    static long count[NC * NP];
    memset(count, 0, sizeof count);
    double cmin = s_cos_min(kind, param);
    long bad_len = 0, bad_dom = 0, bad_nan = 0;
    s_stat mc = { 0 };
    for (long i = 0; i < N; i++) {
        float u1, u2;
        s_u2(seed, (uint64_t)i, &u1, &u2);
        pf_vec3 v = s_sample(kind, u1, u2, param);
        if (!pf_is_finite3(v)) {
            bad_nan++;
            continue;
        }
        if (fabs(s_len_d(v) - 1.0) > 1e-5)
            bad_len++;
        if (v.z < cmin - 1e-6)
            bad_dom++;
        double F = s_cos_cdf(kind, fmin(fmax(v.z, cmin), 1.0), param);
        int ic = (int)(F * NC);
        ic = ic < 0 ? 0 : ic >= NC ? NC - 1 : ic;
        double phi = atan2(v.y, v.x);
        if (phi < 0.0)
            phi += 2.0 * PI_D;
        int ip = (int)(phi / (2.0 * PI_D) * NP);
        ip = ip < 0 ? 0 : ip >= NP ? NP - 1 : ip;
        count[ic * NP + ip]++;
        s_stat_add(&mc, v.z);
    }
    CHECK(bad_nan == 0, "%s(%g): %ld non-finite samples", name, param, bad_nan);
    CHECK(bad_len == 0, "%s(%g): %ld samples not unit length (|len-1| > 1e-5)", name, param, bad_len);
    CHECK(bad_dom == 0, "%s(%g): %ld samples with cos theta below the domain's %g", name, param, bad_dom, cmin);
    double x2 = s_chi2_equal(count, NC * NP, N - bad_nan);
    double lim = s_chi2_limit(NC * NP - 1);
    CHECK(x2 < lim, "%s(%g): chi-square over (cos theta, phi) bins = %.1f, expected < %.1f (dof %d)", name, param, x2,
          lim, NC * NP - 1);
    /* E[cos theta]: cosine 2/3, sphere 0, cone (1 + cos_max) / 2, Phong (n+1)/(n+2). */
    double expect = kind == K_COSINE ? 2.0 / 3.0
                    : kind == K_SPHERE ? 0.0
                    : kind == K_CONE   ? 0.5 * (1.0 + param)
                                       : (param + 1.0) / (param + 2.0);
    double se = s_stat_se(&mc);
    CHECK(fabs(mc.mean - expect) <= 5.0 * se + 1e-6, "%s(%g): E[cos theta] = %.6f, expected %.6f (5 se = %.2g)", name,
          param, mc.mean, expect, 5.0 * se);
}

/* Extreme uniforms must still give unit vectors inside the domain. */
static void s_test_sampler_edges(void)
{
    const float us[] = { 0.0f, 0x1p-24f, 0.25f, 0.5f, 1.0f - 0x1p-24f };
    const float cones[] = { -0.5f, 0.0f, 0.9f, 0.999999f };
    const float ns[] = { 0.0f, 1.0f, 100.0f, 10000.0f };
    for (int a = 0; a < 5; a++) {
        for (int b = 0; b < 5; b++) {
            float u1 = us[a], u2 = us[b];
            pf_vec3 v = pf_sample_cosine(u1, u2);
            CHECK(pf_is_finite3(v) && fabs(s_len_d(v) - 1.0) < 1e-5 && v.z >= 0.0f,
                  "cosine(%g, %g) = (%g, %g, %g): want a unit vector with z >= 0", u1, u2, v.x, v.y, v.z);
            v = pf_sample_sphere(u1, u2);
            CHECK(pf_is_finite3(v) && fabs(s_len_d(v) - 1.0) < 1e-5, "sphere(%g, %g) = (%g, %g, %g): want unit", u1, u2,
                  v.x, v.y, v.z);
            for (int c = 0; c < 4; c++) {
                v = pf_sample_cone(u1, u2, cones[c]);
                CHECK(pf_is_finite3(v) && fabs(s_len_d(v) - 1.0) < 1e-5 && v.z >= cones[c] - 1e-6f,
                      "cone(%g, %g, %g) = (%g, %g, %g): want unit with z >= cos_max", u1, u2, cones[c], v.x, v.y, v.z);
                v = pf_sample_phong(u1, u2, ns[c]);
                CHECK(pf_is_finite3(v) && fabs(s_len_d(v) - 1.0) < 1e-5 && v.z >= 0.0f,
                      "phong(%g, %g, n=%g) = (%g, %g, %g): want unit with z >= 0", u1, u2, ns[c], v.x, v.y, v.z);
            }
        }
    }
    /* u1 = 0 is the pole for cosine and Phong samplers, and the cone's axis. */
    CHECK(pf_sample_cosine(0.0f, 0.3f).z == 1.0f, "cosine(0, u2).z = %g, expected 1", pf_sample_cosine(0.0f, 0.3f).z);
    CHECK(pf_sample_phong(0.0f, 0.3f, 10.0f).z == 1.0f, "phong(0, u2).z = %g, expected 1",
          pf_sample_phong(0.0f, 0.3f, 10.0f).z);
    CHECK(pf_sample_sphere(0.0f, 0.3f).z == 1.0f, "sphere(0, u2).z = %g, expected 1", pf_sample_sphere(0.0f, 0.3f).z);
}

/* pf_phong_pdf integrates to 1 over the hemisphere (deterministic midpoint
 * rule in cos theta), is zero below it, and matches the sampler in a Monte
 * Carlo integral: E[cos^(n+1) / pdf] = int cos^(n+1) dw = 2 pi / (n+2). */
static void s_test_phong_pdf(void)
{
    const float ns[] = { 0.0f, 1.0f, 10.0f, 100.0f };
    for (int k = 0; k < 4; k++) {
        float n = ns[k];
        const int steps = 200000;
        double sum = 0.0;
        for (int i = 0; i < steps; i++)
            sum += pf_phong_pdf((float)((i + 0.5) / steps), n);
        double integral = 2.0 * PI_D * sum / steps;
        CHECK(fabs(integral - 1.0) < 1e-4, "phong pdf n=%g integrates to %.6f over the hemisphere, expected 1", n,
              integral);
        CHECK(pf_phong_pdf(-0.3f, n) == 0.0f && pf_phong_pdf(0.0f, n) == 0.0f,
              "phong pdf n=%g below the horizon: %g, %g, expected 0", n, pf_phong_pdf(-0.3f, n), pf_phong_pdf(0.0f, n));
        double expect_pole = (n + 1.0) / (2.0 * PI_D);
        CHECK(fabs(pf_phong_pdf(1.0f, n) - expect_pole) < 1e-6 * expect_pole, "phong pdf n=%g at the pole: %g, expected %g",
              n, pf_phong_pdf(1.0f, n), expect_pole);
        s_stat st = { 0 };
        for (long i = 0; i < 100000; i++) {
            float u1, u2;
            s_u2(700 + k, (uint64_t)i, &u1, &u2);
            pf_vec3 v = pf_sample_phong(u1, u2, n);
            double pdf = pf_phong_pdf(v.z, n);
            s_stat_add(&st, pdf > 0.0 ? pow(v.z, n + 1.0) / pdf : 0.0);
        }
        double expect = 2.0 * PI_D / (n + 2.0), se = s_stat_se(&st);
        CHECK(fabs(st.mean - expect) <= 5.0 * se + 1e-6,
              "phong n=%g: E[cos^(n+1)/pdf] = %.6f, expected 2 pi/(n+2) = %.6f (5 se = %.2g)", n, st.mean, expect,
              5.0 * se);
    }
}

/* Uniform triangle sampling: barycentrics in range, and equal counts in the
 * 64 congruent sub-triangles of the 8 x 8 subdivision. */
static void s_test_triangle(void)
{
    enum { M = 8, N = 256000 };
    /* up[i][j]: the upward sub-triangle of grid cell (i, j), i + j <= M - 1;
     * down[i][j]: the downward one, i + j <= M - 2. All M^2 have equal area. */
    static long up[M][M], down[M][M];
    memset(up, 0, sizeof up);
    memset(down, 0, sizeof down);
    long bad = 0;
    for (long i = 0; i < N; i++) {
        float u1, u2, b0, b1;
        s_u2(900, (uint64_t)i, &u1, &u2);
        pf_sample_triangle(u1, u2, &b0, &b1);
        float b2 = 1.0f - b0 - b1;
        if (!(b0 >= 0.0f && b1 >= 0.0f && b0 <= 1.0f && b1 <= 1.0f && b2 >= -1e-6f)) {
            if (bad++ < 3)
                fprintf(stderr, "  triangle(%g, %g) -> b = (%g, %g, %g)\n", u1, u2, b0, b1, b2);
            continue;
        }
        double x = (double)b0 * M, y = (double)b1 * M;
        int ci = (int)x, cj = (int)y;
        ci = ci > M - 1 ? M - 1 : ci;
        cj = cj > M - 1 - ci ? M - 1 - ci : cj;
        /* Fractional parts summing below 1: the upward half of the cell. On
         * the last diagonal only the upward half exists (b2 rounding). */
        if ((x - ci) + (y - cj) < 1.0 || ci + cj == M - 1)
            up[ci][cj]++;
        else
            down[ci][cj]++;
    }
    CHECK(bad == 0, "%ld triangle samples with barycentrics out of range", bad);
    long dense[M * M];
    int nd = 0;
    for (int ci = 0; ci < M; ci++) {
        for (int cj = 0; cj < M; cj++) {
            if (ci + cj <= M - 1)
                dense[nd++] = up[ci][cj];
            if (ci + cj <= M - 2)
                dense[nd++] = down[ci][cj];
        }
    }
    double x2 = s_chi2_equal(dense, nd, N - bad), lim = s_chi2_limit(nd - 1);
    CHECK(x2 < lim, "triangle: chi-square over %d equal sub-triangles = %.1f, expected < %.1f", nd, x2, lim);
}

/* ---- local frames ---- */

/* pf_basis gives a right-handed orthonormal frame for any unit n, including
 * the poles; pf_to_world keeps local +z hemisphere samples on n's side. */
static void s_test_basis(void)
{
    pf_rng_t r = pf_rng_make(11, PF_STREAM_TEST, 0, 0);
    long bad = 0;
    for (int i = 0; i < 20000; i++) {
        pf_vec3 n = i == 0 ? pf_v3(0, 0, 1) : i == 1 ? pf_v3(0, 0, -1) : i == 2 ? pf_v3(1, 0, 0)
                  : i == 3 ? pf_norm(pf_v3(1e-4f, 0, -1)) : s_rand_dir(&r);
        pf_vec3 t, b;
        pf_basis(n, &t, &b);
        pf_vec3 c = pf_cross(t, b);
        int ok = fabs(s_len_d(t) - 1.0) < 1e-5 && fabs(s_len_d(b) - 1.0) < 1e-5 && fabs(s_dot_d(t, b)) < 1e-5 &&
                 fabs(s_dot_d(t, n)) < 1e-5 && fabs(s_dot_d(b, n)) < 1e-5 && s_dot_d(c, n) > 1.0 - 1e-5;
        pf_vec3 w = pf_to_world(pf_sample_cosine(pf_rng_float(&r), pf_rng_float(&r)), n);
        ok = ok && s_dot_d(w, n) >= -1e-6 && fabs(s_len_d(w) - 1.0) < 1e-5;
        if (!ok && bad++ < 3)
            fprintf(stderr, "  basis for n = (%g, %g, %g): t = (%g, %g, %g), b = (%g, %g, %g)\n", n.x, n.y, n.z, t.x,
                    t.y, t.z, b.x, b.y, b.z);
    }
    CHECK(bad == 0, "%ld normals with a frame that is not right-handed orthonormal", bad);
}

/* ---- 2. Fresnel and Snell ---- */

/* Unpolarized dielectric Fresnel reflectance in double (Hecht's formulas). */
static double s_fresnel_ref(double cos_i, double ni, double nt)
{
    double sin_i = sqrt(fmax(0.0, 1.0 - cos_i * cos_i));
    double sin_t = ni / nt * sin_i;
    if (sin_t >= 1.0)
        return 1.0;
    double cos_t = sqrt(1.0 - sin_t * sin_t);
    double rs = (ni * cos_i - nt * cos_t) / (ni * cos_i + nt * cos_t);
    double rp = (nt * cos_i - ni * cos_t) / (nt * cos_i + ni * cos_t);
    return 0.5 * (rs * rs + rp * rp);
}

static void s_test_fresnel(void)
{
    /* Normal incidence: ((n1 - n2) / (n1 + n2))^2, either way round. */
    float f = pf_fresnel_dielectric(1.0f, 1.0f, 1.5f);
    CHECK(fabsf(f - 0.04f) < 1e-6f, "F(normal, 1 -> 1.5) = %.8f, expected 0.04", f);
    float g = pf_fresnel_dielectric(1.0f, 1.5f, 1.0f);
    CHECK(fabsf(g - 0.04f) < 1e-6f, "F(normal, 1.5 -> 1) = %.8f, expected 0.04", g);
    f = pf_fresnel_dielectric(1.0f, 1.0f, 2.4f);
    double d = (1.0 - 2.4) / 3.4;
    CHECK(fabs(f - d * d) < 1e-6, "F(normal, 1 -> 2.4) = %.8f, expected %.8f", f, d * d);
    f = pf_fresnel_dielectric(1.0f, 1.33f, 1.33f);
    CHECK(fabsf(f) < 1e-7f, "F(normal, matched indices) = %g, expected 0", f);

    /* Brewster's angle tan theta_B = n2 / n1: r_par vanishes, so
     * F = r_perp^2 / 2 with r_perp = cos(2 theta_B) there (theta_i + theta_t =
     * 90 degrees); cos 2 theta = (1 - tan^2) / (1 + tan^2). */
    const double pairs[][2] = { { 1.0, 1.5 }, { 1.5, 1.0 }, { 1.0, 2.4 }, { 1.33, 1.0 } };
    for (int k = 0; k < 4; k++) {
        double n1 = pairs[k][0], n2 = pairs[k][1];
        double tb = n2 / n1, theta_b = atan(tb);
        double r_perp = (1.0 - tb * tb) / (1.0 + tb * tb);
        double expect = 0.5 * r_perp * r_perp;
        f = pf_fresnel_dielectric((float)cos(theta_b), (float)n1, (float)n2);
        CHECK(fabs(f - expect) < 2e-6, "F(Brewster %.4f rad, %g -> %g) = %.8f, expected r_perp^2/2 = %.8f", theta_b,
              n1, n2, f, expect);
    }

    /* Grazing incidence reflects everything. */
    f = pf_fresnel_dielectric(0.0f, 1.0f, 1.5f);
    CHECK(f > 0.999999f && f <= 1.0f, "F(grazing, 1 -> 1.5) = %.8f, expected 1", f);
    f = pf_fresnel_dielectric(1e-3f, 1.0f, 1.5f);
    CHECK(f > 0.99f && f <= 1.0f, "F(cos 1e-3, 1 -> 1.5) = %.8f, expected about 0.995", f);

    /* Total internal reflection from the dense side beyond asin(n2/n1). */
    double crit = asin(1.0 / 1.5);
    f = pf_fresnel_dielectric((float)cos(crit + 1e-3), 1.5f, 1.0f);
    CHECK(f == 1.0f, "F(critical + 1e-3 rad, 1.5 -> 1) = %.9f, expected exactly 1 (TIR)", f);
    f = pf_fresnel_dielectric((float)cos(crit + 0.3), 1.5f, 1.0f);
    CHECK(f == 1.0f, "F(critical + 0.3 rad, 1.5 -> 1) = %.9f, expected exactly 1 (TIR)", f);
    f = pf_fresnel_dielectric(0.0f, 1.5f, 1.0f);
    CHECK(f == 1.0f, "F(grazing, 1.5 -> 1) = %.9f, expected exactly 1 (TIR)", f);
    f = pf_fresnel_dielectric((float)cos(crit - 1e-2), 1.5f, 1.0f);
    CHECK(f < 1.0f && f > 0.3f, "F(critical - 0.01 rad, 1.5 -> 1) = %.9f, expected < 1 (and large)", f);
    f = pf_fresnel_dielectric((float)cos(crit - 0.2), 1.5f, 1.0f);
    CHECK(fabs(f - s_fresnel_ref(cos(crit - 0.2), 1.5, 1.0)) < 1e-5, "F(critical - 0.2 rad, 1.5 -> 1) = %.7f, expected %.7f",
          f, s_fresnel_ref(cos(crit - 0.2), 1.5, 1.0));

    /* Against the double reference over all angles, away from the critical
     * angle where the float cosine's rounding is amplified without bound. */
    double worst = 0.0, worst_at = 0.0;
    int worst_pair = 0;
    for (int k = 0; k < 4; k++) {
        double n1 = pairs[k][0], n2 = pairs[k][1];
        double tir = n1 > n2 ? asin(n2 / n1) : 10.0;
        for (int i = 0; i <= 2000; i++) {
            double theta = 0.5 * PI_D * i / 2000.0;
            if (fabs(theta - tir) < 2e-3)
                continue;
            float c = (float)cos(theta);
            double e = fabs(pf_fresnel_dielectric(c, (float)n1, (float)n2) - s_fresnel_ref(c, n1, n2));
            if (e > worst) {
                worst = e;
                worst_at = theta;
                worst_pair = k;
            }
        }
    }
    CHECK(worst < 2e-5, "F differs from the double reference by %.3g at theta %.4f rad (%g -> %g)", worst, worst_at,
          pairs[worst_pair][0], pairs[worst_pair][1]);

    /* Reciprocity: the reflectance seen from either side along the same
     * light path is the same (Stokes relations). */
    double worst_r = 0.0;
    for (int i = 1; i < 200; i++) {
        double ti = 0.5 * PI_D * i / 200.0;
        double tt = asin(sin(ti) / 1.5);
        double a = pf_fresnel_dielectric((float)cos(ti), 1.0f, 1.5f);
        double b = pf_fresnel_dielectric((float)cos(tt), 1.5f, 1.0f);
        worst_r = fmax(worst_r, fabs(a - b));
    }
    CHECK(worst_r < 5e-5, "F(theta_i, 1 -> 1.5) and F(theta_t, 1.5 -> 1) differ by %.3g, expected equal", worst_r);
}

static void s_test_snell(void)
{
    const float etas[] = { 1.0f / 1.5f, 1.5f, 1.0f / 1.33f, 1.33f, 1.0f / 2.4f };
    pf_rng_t r = pf_rng_make(21, PF_STREAM_TEST, 0, 0);
    long bad_snell = 0, bad_unit = 0, bad_side = 0, bad_plane = 0, bad_back = 0, bad_tir = 0, bad_refl = 0;
    double worst_snell = 0.0, worst_back = 0.0;
    for (int i = 0; i < 50000; i++) {
        float eta = etas[i % 5];
        pf_vec3 n = s_rand_dir(&r);
        pf_vec3 wi = pf_to_world(pf_sample_sphere(pf_rng_float(&r), pf_rng_float(&r)), n);
        wi = pf_face_forward(wi, n);
        double cos_i = s_dot_d(wi, n);
        if (cos_i < 1e-3)
            continue;
        /* Sines as cross-product lengths: well conditioned at every angle. */
        double sin_i = s_sin_d(wi, n);
        pf_vec3 wt = pf_v3s(0.0f);
        int ok = pf_refract(wi, n, eta, &wt);
        double sin_t_exact = eta * sin_i;
        if (sin_t_exact > 1.0 + 1e-5) {
            if (ok)
                bad_tir++;
            continue;
        }
        if (sin_t_exact < 1.0 - 1e-5 && !ok) {
            bad_tir++;
            continue;
        }
        if (!ok)
            continue;
        double cos_t = -s_dot_d(wt, n);
        double sin_t = s_sin_d(wt, n);
        double e = fabs(eta * sin_i - sin_t);
        worst_snell = fmax(worst_snell, e);
        if (e > 1e-5)
            bad_snell++;
        if (fabs(s_len_d(wt) - 1.0) > 1e-5)
            bad_unit++;
        if (!(cos_t > 0.0))
            bad_side++;
        /* In the plane of incidence, tangential parts opposite: wt_tan = -eta wi_tan. */
        pf_vec3 ti = pf_sub(wi, pf_scale(n, (float)cos_i));
        pf_vec3 tt = pf_sub(wt, pf_scale(n, (float)-cos_t));
        if (s_len_d(pf_add(tt, pf_scale(ti, eta))) > 2e-5)
            bad_plane++;
        /* Refracting back with the inverse ratio recovers wi. */
        pf_vec3 back;
        if (!pf_refract(wt, pf_neg(n), 1.0f / eta, &back)) {
            bad_back++;
        } else {
            double a = s_angle(back, wi);
            worst_back = fmax(worst_back, a);
            if (a > 1e-4 + 1e-6 / fmax(cos_i, 1e-3))
                bad_back++;
        }
        /* Reflection keeps the angle to n, stays in the plane, is an involution. */
        pf_vec3 wr = pf_reflect(wi, n);
        if (fabs(s_dot_d(wr, n) - cos_i) > 1e-5 || fabs(s_len_d(wr) - 1.0) > 1e-5 ||
            s_len_d(pf_add(pf_sub(wr, pf_scale(n, (float)cos_i)), ti)) > 1e-5 || s_angle(pf_reflect(wr, n), wi) > 1e-5)
            bad_refl++;
    }
    CHECK(bad_snell == 0, "%ld refractions break n1 sin1 = n2 sin2 (worst |eta sin_i - sin_t| = %.3g)", bad_snell,
          worst_snell);
    CHECK(bad_unit == 0, "%ld refracted directions not unit length", bad_unit);
    CHECK(bad_side == 0, "%ld refracted directions not on the far side of the surface", bad_side);
    CHECK(bad_plane == 0, "%ld refracted directions out of the plane of incidence or with the wrong tangent", bad_plane);
    CHECK(bad_back == 0, "%ld refractions not undone by refracting back with 1/eta (worst %.3g rad)", bad_back,
          worst_back);
    CHECK(bad_tir == 0, "%ld refractions with the wrong total-internal-reflection verdict", bad_tir);
    CHECK(bad_refl == 0, "%ld reflections that change the angle, leave the plane or do not invert", bad_refl);

    /* The critical angle from glass: asin(1/1.5) = 41.81 degrees. */
    double crit = asin(1.0 / 1.5);
    pf_vec3 n = pf_v3(0, 0, 1), wt;
    pf_vec3 w_over = pf_v3((float)sin(crit + 1e-3), 0, (float)cos(crit + 1e-3));
    pf_vec3 w_under = pf_v3((float)sin(crit - 1e-3), 0, (float)cos(crit - 1e-3));
    CHECK(pf_refract(w_over, n, 1.5f, &wt) == 0, "refract at critical + 1e-3 rad from glass: want 0 (TIR)");
    CHECK(pf_refract(w_under, n, 1.5f, &wt) == 1 && wt.z < 0.0f && wt.z > -0.1f,
          "refract at critical - 1e-3 rad from glass: want 1 and a nearly grazing wt, got wt.z = %g", wt.z);
    /* Normal incidence passes straight through. */
    CHECK(pf_refract(n, n, 1.0f / 1.5f, &wt) == 1 && s_angle(wt, pf_v3(0, 0, -1)) < 1e-6,
          "refract at normal incidence: got (%g, %g, %g), expected (0, 0, -1)", wt.x, wt.y, wt.z);
    /* The refract TIR verdict agrees with Fresnel's. */
    long disagree = 0;
    for (int i = 0; i <= 1000; i++) {
        double theta = 0.5 * PI_D * i / 1000.0;
        if (fabs(theta - crit) < 1e-4)
            continue;
        pf_vec3 w = pf_v3((float)sin(theta), 0, (float)cos(theta));
        int tir_r = !pf_refract(w, n, 1.5f, &wt);
        int tir_f = pf_fresnel_dielectric(w.z, 1.5f, 1.0f) == 1.0f;
        disagree += tir_r != tir_f;
    }
    CHECK(disagree == 0, "pf_refract and pf_fresnel_dielectric disagree on TIR at %ld angles", disagree);
}

/* ---- 3. the Phong BRDF ---- */

static pf_material_t s_mat(float kd, float ks, float ns)
{
    pf_material_t m;
    memset(&m, 0, sizeof m);
    m.type = PF_MAT_DIFFUSE;
    m.kd = pf_v3s(kd);
    m.ks = pf_v3s(ks);
    m.ns = ns;
    return m;
}

/* Directional albedo int f cos dwo for incidence angle theta about a random
 * normal, estimated with a one-sample mixture of cosine and Phong-lobe
 * sampling (pdf 0.5 cos/pi + 0.5 phong_pdf), whose ratio f cos / pdf is
 * bounded, so the estimate is tight even for n = 1000. */
static void s_albedo(const pf_material_t *m, double theta, uint64_t seed, long nsamp, s_stat *st)
{
    pf_rng_t r = pf_rng_make(seed, PF_STREAM_TEST, 0, 0);
    pf_vec3 n = s_rand_dir(&r), t, b;
    pf_basis(n, &t, &b);
    pf_vec3 wi = pf_add(pf_scale(n, (float)cos(theta)), pf_scale(t, (float)sin(theta)));
    pf_vec3 refl = pf_reflect(wi, n);
    for (long i = 0; i < nsamp; i++) {
        pf_rng_t ri = pf_rng_make(seed, PF_STREAM_TEST, (uint64_t)i + 1, 0);
        float pick = pf_rng_float(&ri), u1 = pf_rng_float(&ri), u2 = pf_rng_float(&ri);
        pf_vec3 wo = pick < 0.5f ? pf_to_world(pf_sample_cosine(u1, u2), n)
                                 : pf_to_world(pf_sample_phong(u1, u2, m->ns), refl);
        double cos_o = s_dot_d(wo, n);
        if (cos_o <= 0.0) {
            s_stat_add(st, 0.0);
            continue;
        }
        double pdf = 0.5 * cos_o / PI_D + 0.5 * pf_phong_pdf(pf_dot(wo, refl), m->ns);
        pf_vec3 f = pf_brdf_eval(m, n, wi, wo);
        s_stat_add(st, pdf > 0.0 ? f.y * cos_o / pdf : 0.0);
    }
}

static void s_test_brdf(void)
{
    const float ns[] = { 1.0f, 10.0f, 100.0f, 1000.0f };
    const double thetas[] = { 0.0, 30.0, 60.0, 85.0 };
    const float mix[][2] = { { 1.0f, 0.0f }, { 0.6f, 0.0f }, { 0.0f, 1.0f }, { 0.5f, 0.5f }, { 0.2f, 0.7f } };
    int seed = 1000;
    for (int a = 0; a < 4; a++) {
        for (int b = 0; b < 4; b++) {
            for (int c = 0; c < 5; c++) {
                pf_material_t m = s_mat(mix[c][0], mix[c][1], ns[a]);
                double theta = thetas[b] * PI_D / 180.0;
                s_stat st = { 0 };
                s_albedo(&m, theta, (uint64_t)seed++, 60000, &st);
                double tol = 5.0 * s_stat_se(&st) + 1e-4;
                double kd = mix[c][0], ks = mix[c][1];
                /* Energy conservation: the albedo never exceeds kd + ks. */
                CHECK(st.mean <= kd + ks + tol,
                      "albedo(kd %g, ks %g, n %g, theta %g deg) = %.5f exceeds kd + ks = %g (5 se = %.2g)", kd, ks,
                      ns[a], thetas[b], st.mean, kd + ks, tol);
                /* Pure Lambert reflects exactly kd at every angle. */
                if (ks == 0.0)
                    CHECK(fabs(st.mean - kd) <= tol, "Lambert albedo(kd %g, theta %g deg) = %.5f, expected %g (5 se = %.2g)",
                          kd, thetas[b], st.mean, kd, tol);
                /* The normalized lobe reflects exactly ks at normal incidence
                 * (int cos^(n+1) dw = 2 pi / (n+2)). */
                if (thetas[b] == 0.0)
                    CHECK(fabs(st.mean - (kd + ks)) <= tol,
                          "albedo(kd %g, ks %g, n %g) at normal incidence = %.5f, expected kd + ks = %g (5 se = %.2g)",
                          kd, ks, ns[a], st.mean, kd + ks, tol);
            }
        }
    }
    /* Grazing incidence loses part of the lobe below the horizon: for n = 1
     * at 85 degrees the albedo must be well under ks. */
    pf_material_t m = s_mat(0.0f, 1.0f, 1.0f);
    s_stat st = { 0 };
    s_albedo(&m, 85.0 * PI_D / 180.0, 4242, 60000, &st);
    CHECK(st.mean < 0.6, "Phong n=1 albedo at 85 degrees = %.4f, expected well under 1", st.mean);

    /* Values: Lambert is kd / pi; the lobe peaks at ks (n+2)/(2 pi) along the
     * mirror direction; nothing below the surface. */
    pf_vec3 n = pf_v3(0, 0, 1), wi = pf_norm(pf_v3(0.3f, -0.2f, 0.8f));
    pf_material_t lam = s_mat(0.7f, 0.0f, 1.0f);
    pf_vec3 f = pf_brdf_eval(&lam, n, wi, pf_norm(pf_v3(-0.5f, 0.1f, 0.4f)));
    CHECK(fabs(f.x - 0.7 / PI_D) < 1e-7, "Lambert f = %.8f, expected kd/pi = %.8f", f.x, 0.7 / PI_D);
    pf_material_t ph = s_mat(0.0f, 0.5f, 20.0f);
    f = pf_brdf_eval(&ph, n, wi, pf_reflect(wi, n));
    double peak = 0.5 * 22.0 / (2.0 * PI_D);
    CHECK(fabs(f.x - peak) < 1e-5 * peak, "Phong f at the mirror direction = %.7f, expected ks (n+2)/(2 pi) = %.7f", f.x,
          peak);
    f = pf_brdf_eval(&lam, n, wi, pf_v3(0.6f, 0.0f, -0.8f));
    CHECK(pf_is_black(f), "f with wo below the surface = %g, expected 0", f.x);
    f = pf_brdf_eval(&lam, n, pf_v3(0.6f, 0.0f, -0.8f), wi);
    CHECK(pf_is_black(f), "f with wi below the surface = %g, expected 0", f.x);
    pf_material_t mir = s_mat(0.7f, 0.5f, 20.0f);
    mir.type = PF_MAT_MIRROR;
    f = pf_brdf_eval(&mir, n, wi, pf_reflect(wi, n));
    CHECK(pf_is_black(f), "f of a mirror material = %g, expected 0 (specular, not a BRDF value)", f.x);

    /* Reciprocity: f(wi, wo) = f(wo, wi). */
    pf_rng_t r = pf_rng_make(31, PF_STREAM_TEST, 0, 0);
    long bad = 0;
    double worst = 0.0;
    for (int i = 0; i < 20000; i++) {
        pf_material_t mm = s_mat(0.3f, 0.6f, ns[i % 4]);
        pf_vec3 nn = s_rand_dir(&r);
        pf_vec3 a = pf_face_forward(s_rand_dir(&r), nn);
        /* Half the pairs near the mirror direction, where the lobe is large. */
        pf_vec3 bdir = (i & 1) ? pf_face_forward(s_rand_dir(&r), nn)
                               : pf_to_world(pf_sample_phong(pf_rng_float(&r), pf_rng_float(&r), 50.0f), pf_reflect(a, nn));
        if (pf_dot(bdir, nn) <= 0.0f)
            continue;
        pf_vec3 f1 = pf_brdf_eval(&mm, nn, a, bdir), f2 = pf_brdf_eval(&mm, nn, bdir, a);
        double e = fabs(f1.y - f2.y) / fmax(fabs(f1.y), 1e-3);
        worst = fmax(worst, e);
        if (e > 1e-3)
            bad++;
    }
    CHECK(bad == 0, "%ld direction pairs with f(wi, wo) != f(wo, wi) (worst relative %.3g)", bad, worst);
}

/* ---- 4. octahedral encoding ---- */

static void s_test_oct(void)
{
    const pf_vec3 fixed[] = {
        { 1, 0, 0 }, { -1, 0, 0 }, { 0, 1, 0 }, { 0, -1, 0 }, { 0, 0, 1 }, { 0, 0, -1 },
        { 0.70710678f, 0.70710678f, 0 }, { 0.70710678f, -0.70710678f, 0 }, { 0.57735027f, 0.57735027f, -0.57735027f },
        { -0.57735027f, -0.57735027f, -0.57735027f }, { 0.6f, 0.8f, -1e-7f }, { 1e-7f, 0, -1 },
    };
    double worst = 0.0;
    pf_vec3 worst_v = pf_v3s(0.0f);
    long bad_unit = 0, bad_hemi = 0;
    pf_rng_t r = pf_rng_make(41, PF_STREAM_TEST, 0, 0);
    const int nfixed = (int)(sizeof fixed / sizeof fixed[0]);
    for (int i = 0; i < 300000 + nfixed; i++) {
        pf_vec3 v = i < nfixed ? pf_norm(fixed[i]) : s_rand_dir(&r);
        /* Every other random direction forced into z < 0. */
        if (i >= nfixed && (i & 1))
            v.z = -fabsf(v.z);
        pf_vec3 d = pf_oct_decode(pf_oct_encode(v));
        double a = s_angle(v, d);
        if (a > worst) {
            worst = a;
            worst_v = v;
        }
        if (fabs(s_len_d(d) - 1.0) > 1e-5)
            bad_unit++;
        if (fabsf(v.z) > 1e-3f && (v.z > 0.0f) != (d.z > 0.0f))
            bad_hemi++;
    }
    CHECK(worst < 1e-4, "octahedral round trip error %.3g rad at (%g, %g, %g), expected < 1e-4", worst, worst_v.x,
          worst_v.y, worst_v.z);
    CHECK(bad_unit == 0, "%ld decoded directions not unit length", bad_unit);
    CHECK(bad_hemi == 0, "%ld decoded directions in the wrong z hemisphere", bad_hemi);
}

int main(void)
{
    s_test_sampler(K_COSINE, "cosine", 0.0f, 101);
    s_test_sampler(K_SPHERE, "sphere", 0.0f, 102);
    const float cones[] = { -0.5f, 0.0f, 0.5f, 0.9f, 0.999f };
    for (int i = 0; i < 5; i++)
        s_test_sampler(K_CONE, "cone", cones[i], 110 + i);
    const float ns[] = { 1.0f, 10.0f, 100.0f };
    for (int i = 0; i < 3; i++)
        s_test_sampler(K_PHONG, "phong", ns[i], 120 + i);
    s_test_sampler_edges();
    s_test_phong_pdf();
    s_test_triangle();
    s_test_basis();
    s_test_fresnel();
    s_test_snell();
    s_test_brdf();
    s_test_oct();
    printf("%d passed, %d failed\n", s_passed, s_failed);
    return s_failed ? 1 : 0;
}
