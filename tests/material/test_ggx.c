/* test_ggx.c: the GGX rough conductor of material/ggx.h.
 *
 * Sampling: a chi-square test of pf_conductor_sample's directions against
 * pf_conductor_pdf over (cos theta, phi) bins, the expected count of each bin
 * integrated from the pdf by a midpoint rule (bins expecting fewer than 20
 * samples are pooled; samples lost below the surface are their own bin with
 * the pdf's missing mass), at alpha 0.05, 0.2, 0.6 and several incident
 * angles; the bound dof + 6 sqrt(2 dof) is exceeded by noise with probability
 * well under 1e-6. Energy: the mean sampling weight f cos / pdf against the
 * directional albedo integrated numerically from pf_conductor_eval (within 5
 * standard errors plus the quadrature's 1 %), and with F = 1 (k huge) an
 * albedo <= 1, near 1 for small alpha. Reciprocity f(wo, wi) = f(wi, wo).
 * Fresnel: normal incidence ((n-1)^2 + k^2) / ((n+1)^2 + k^2), grazing 1,
 * the dielectric limit k = 0. Randomness: pf_rng_make(seed, PF_STREAM_TEST, i, 0). */
#include <math.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "base/rng.h"
#include "base/vec.h"
#include "material/bsdf.h"
#include "material/ggx.h"

#include "check.h"

#define PI_D 3.14159265358979323846

static pf_material_t s_metal(float alpha, pf_vec3 eta, pf_vec3 k)
{
    pf_material_t m = pf_material_default("metal");
    m.type = PF_MAT_CONDUCTOR;
    m.alpha = alpha;
    m.eta = eta;
    m.k = k;
    return m;
}

static pf_vec3 s_dir(double cos_t, double phi)
{
    double s = sqrt(fmax(0.0, 1.0 - cos_t * cos_t));
    return pf_v3((float)(s * cos(phi)), (float)(s * sin(phi)), (float)cos_t);
}

enum { NC = 24, NP = 24, SUB = 16 };

/* Chi-square of sampled directions against the pdf, for wo at theta_o. */
static void s_test_chi2(float alpha, float theta_o, uint64_t seed)
{
    const long N = 400000;
    pf_material_t m = s_metal(alpha, pf_v3s(0.2f), pf_v3s(3.0f));
    pf_vec3 n = pf_v3(0, 0, 1), wo = pf_v3(sinf(theta_o), 0.0f, cosf(theta_o));
    static long count[NC * NP + 1];
    static double expect[NC * NP + 1];
    memset(count, 0, sizeof count);
    /* Bins equal in theta and phi (d omega = sin theta d theta d phi). */
    /* Near the horizon a sharp lobe is narrow in phi: finer steps there. */
    int subp = alpha < 0.1f ? 4 * SUB : SUB;
    double mass = 0.0;
    for (int i = 0; i < NC; i++)
        for (int j = 0; j < NP; j++) {
            double e = 0.0;
            for (int a = 0; a < SUB; a++)
                for (int b = 0; b < subp; b++) {
                    double th = 0.5 * PI_D * (i + (a + 0.5) / SUB) / NC, ct = cos(th);
                    double phi = 2.0 * PI_D * (j + (b + 0.5) / subp) / NP;
                    double dw = sin(th) * (0.5 * PI_D / (NC * SUB)) * (2.0 * PI_D / (NP * subp));
                    e += pf_conductor_pdf(&m, n, wo, s_dir(ct, phi)) * dw;
                }
            expect[i * NP + j] = e * N;
            mass += e;
        }
    expect[NC * NP] = fmax(0.0, 1.0 - mass) * N;
    long bad = 0;
    for (long s = 0; s < N; s++) {
        pf_rng_t r = pf_rng_make(seed, PF_STREAM_TEST, (uint64_t)s, 0);
        float u1 = pf_rng_float(&r), u2 = pf_rng_float(&r);
        pf_vec3 wi, w;
        float pdf;
        if (!pf_conductor_sample(&m, n, wo, u1, u2, &wi, &w, &pdf)) {
            count[NC * NP]++;
            continue;
        }
        if (fabsf(pf_len(wi) - 1.0f) > 1e-4f || !(pdf > 0.0f))
            bad++;
        double th = acos(fmin(1.0, fmax(-1.0, (double)wi.z)));
        int i = (int)(th / (0.5 * PI_D) * NC), j = (int)((atan2(wi.y, wi.x) + (atan2(wi.y, wi.x) < 0 ? 2.0 * PI_D : 0.0)) /
                                           (2.0 * PI_D) * NP);
        i = i < NC ? i : NC - 1;
        j = j < NP ? j : NP - 1;
        count[i * NP + j]++;
    }
    CHECK(bad == 0, "alpha %g theta %g: %ld samples not unit or with pdf 0", alpha, theta_o, bad);
    /* Pool small bins. */
    double x2 = 0.0, pe = 0.0, pc = 0.0;
    int dof = -1;
    for (int b = 0; b <= NC * NP; b++) {
        pe += expect[b];
        pc += (double)count[b];
        if (pe >= 20.0) {
            x2 += (pc - pe) * (pc - pe) / pe;
            dof++;
            pe = pc = 0.0;
        }
    }
    if (pe > 0.0 || pc > 0.0) {
        double e = fmax(pe, 1.0);
        x2 += (pc - e) * (pc - e) / e;
    }
    double limit = dof + 6.0 * sqrt(2.0 * dof);
    CHECK(dof >= 15 && x2 < limit, "alpha %g theta %g: chi2 %.1f (dof %d, limit %.1f)", alpha, theta_o, x2, dof,
          limit);
}

/* Directional albedo by quadrature of f cos over the hemisphere (bins as above). */
static double s_albedo_quad(const pf_material_t *m, pf_vec3 wo)
{
    const int Q = 400, QP = m->alpha < 0.1f ? 4000 : 400;
    pf_vec3 n = pf_v3(0, 0, 1);
    double sum = 0.0;
    for (int i = 0; i < Q; i++)
        for (int j = 0; j < QP; j++) {
            double th = 0.5 * PI_D * (i + 0.5) / Q, phi = 2.0 * PI_D * (j + 0.5) / QP;
            pf_vec3 f = pf_conductor_eval(m, n, wo, s_dir(cos(th), phi));
            sum += f.y * cos(th) * sin(th) * (0.5 * PI_D / Q) * (2.0 * PI_D / QP);
        }
    return sum;
}

static void s_test_albedo(float alpha, float theta_o, pf_vec3 eta, pf_vec3 k, uint64_t seed, int furnace)
{
    pf_material_t m = s_metal(alpha, eta, k);
    pf_vec3 n = pf_v3(0, 0, 1), wo = pf_v3(sinf(theta_o), 0.0f, cosf(theta_o));
    const long N = 200000;
    double mean = 0.0, m2 = 0.0;
    for (long s = 0; s < N; s++) {
        pf_rng_t r = pf_rng_make(seed, PF_STREAM_TEST, (uint64_t)s, 0);
        float u1 = pf_rng_float(&r), u2 = pf_rng_float(&r);
        pf_vec3 wi, w;
        float pdf;
        double x = pf_conductor_sample(&m, n, wo, u1, u2, &wi, &w, &pdf) ? w.y : 0.0;
        double d = x - mean;
        mean += d / (double)(s + 1);
        m2 += d * (x - mean);
    }
    double se = sqrt(m2 / (N - 1) / N);
    double q = s_albedo_quad(&m, wo);
    /* The quadrature is coarse at the specular peak of small alpha. */
    double tol = 5.0 * se + 0.01 * q;
    CHECK(fabs(mean - q) <= tol, "alpha %g theta %g: sampled albedo %.5f vs quadrature %.5f (tol %.5f)", alpha,
          theta_o, mean, q, tol);
    if (furnace) {
        CHECK(mean <= 1.0 + 5.0 * se, "alpha %g theta %g: albedo %.5f > 1 with F = 1", alpha, theta_o, mean);
        if (alpha <= 0.05f && theta_o < 1.2f)
            CHECK(mean > 0.97, "alpha %g theta %g: albedo %.5f not near 1 with F = 1", alpha, theta_o, mean);
    }
}

static void s_test_reciprocity(void)
{
    pf_material_t m = s_metal(0.3f, pf_v3(0.2f, 0.9f, 1.1f), pf_v3(3.0f, 2.5f, 2.0f));
    pf_rng_t r = pf_rng_make(7, PF_STREAM_TEST, 0, 0);
    pf_vec3 n = pf_norm(pf_v3(0.2f, -0.1f, 0.9f));
    double worst = 0.0;
    for (int i = 0; i < 2000; i++) {
        pf_vec3 a = pf_to_world(pf_sample_cosine(pf_rng_float(&r), pf_rng_float(&r)), n);
        pf_vec3 b = pf_to_world(pf_sample_cosine(pf_rng_float(&r), pf_rng_float(&r)), n);
        pf_vec3 f1 = pf_conductor_eval(&m, n, a, b), f2 = pf_conductor_eval(&m, n, b, a);
        double d = fabs((double)f1.x - f2.x) / fmax(1e-6, fabs((double)f1.x));
        worst = fmax(worst, d);
    }
    CHECK(worst < 1e-4, "reciprocity: worst relative difference %g", worst);
    pf_vec3 below = pf_v3(0.3f, 0.0f, -0.95f);
    CHECK(pf_is_black(pf_conductor_eval(&m, pf_v3(0, 0, 1), pf_norm(below), pf_v3(0, 0, 1))),
          "f must vanish below the surface");
}

static void s_test_fresnel(void)
{
    const float ns[] = { 0.2f, 1.1f, 2.5f, 0.05f }, ks[] = { 3.0f, 0.0f, 1.5f, 4.0f };
    for (int i = 0; i < 4; i++) {
        double n = ns[i], k = ks[i];
        double want = ((n - 1) * (n - 1) + k * k) / ((n + 1) * (n + 1) + k * k);
        float got = pf_fresnel_complex(1.0f, ns[i], ks[i]);
        CHECK(fabs(got - want) < 1e-5, "normal incidence n %g k %g: %g, want %g", n, k, got, want);
        float g = pf_fresnel_complex(1e-4f, ns[i], ks[i]);
        CHECK(g > 0.99f && g <= 1.0001f, "grazing n %g k %g: %g, want -> 1", n, k, g);
    }
    for (float c = 0.05f; c < 1.0f; c += 0.1f) {
        float a = pf_fresnel_complex(c, 1.5f, 0.0f), b = pf_fresnel_dielectric(c, 1.0f, 1.5f);
        CHECK(fabsf(a - b) < 1e-5f, "k = 0 at cos %g: %g vs the dielectric's %g", c, a, b);
    }
    pf_vec3 fc = pf_fresnel_conductor(0.5f, pf_v3(0.2f, 1.0f, 1.5f), pf_v3(3.0f, 2.0f, 0.0f));
    CHECK(fc.x == pf_fresnel_complex(0.5f, 0.2f, 3.0f) && fc.z == pf_fresnel_complex(0.5f, 1.5f, 0.0f),
          "per-channel Fresnel");
}

int main(void)
{
    const float alphas[] = { 0.05f, 0.2f, 0.6f };
    const float thetas[] = { 0.0f, 0.6f, 1.2f, 1.45f };
    for (int a = 0; a < 3; a++)
        for (int t = 0; t < 4; t++) {
            s_test_chi2(alphas[a], thetas[t], 100 + 10 * a + t);
            s_test_albedo(alphas[a], thetas[t], pf_v3s(0.2f), pf_v3s(3.0f), 200 + 10 * a + t, 0);
            s_test_albedo(alphas[a], thetas[t], pf_v3s(1.0f), pf_v3s(1e4f), 300 + 10 * a + t, 1);
        }
    s_test_reciprocity();
    s_test_fresnel();
    return pf_test_finish();
}
