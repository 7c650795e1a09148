/* test_difftrans.c: the diffuse transmission BSDF of material/difftrans.h.
 *
 * Sampling: a chi-square test of pf_difftrans_sample's directions against
 * pf_difftrans_pdf over (cos theta, phi) bins on the whole sphere (both
 * hemispheres: reflection and transmission), the expected counts integrated
 * from the pdf by a midpoint rule, bins expecting fewer than 20 pooled;
 * the bound dof + 6 sqrt(2 dof) is exceeded by noise with probability well
 * under 1e-6. With wo on either side, and for R, T unequal across channels.
 * Consistency: every sample's weight is f |cos| / pdf of its direction, and
 * its pdf is pf_difftrans_pdf's. Energy: the white furnace, R + T = 1 per
 * channel (R 0.3 0.5 0.9, T 0.7 0.5 0.1): the mean weight is 1 within 5
 * standard errors, and f |cos| integrated over the sphere is 1 (quadrature,
 * 0.5 %); the reflected and transmitted shares are R and T. Reciprocity:
 * f(wo, wi) = f(wi, wo) on random pairs. A black sheet samples nothing.
 * Randomness: pf_rng_make(seed, PF_STREAM_TEST, i, 0). */
#include <math.h>
#include <stdint.h>
#include <stdio.h>
#include <string.h>

#include "base/rng.h"
#include "base/sampling.h"
#include "base/vec.h"
#include "material/difftrans.h"

#include "check.h"

#define PI_D 3.14159265358979323846

static pf_material_t s_sheet(pf_vec3 r, pf_vec3 t)
{
    pf_material_t m = pf_material_default("sheet");
    m.type = PF_MAT_DIFFUSE_TRANSMISSION;
    m.kd = r;
    m.kt = t;
    return m;
}

static pf_vec3 s_dir(double cos_t, double phi)
{
    double s = sqrt(fmax(0.0, 1.0 - cos_t * cos_t));
    return pf_v3((float)(s * cos(phi)), (float)(s * sin(phi)), (float)cos_t);
}

enum { NC = 24, NP = 16, SUB = 8 };

/* Chi-square of sampled directions against the pdf over the sphere. */
static void s_test_chi2(const pf_material_t *m, pf_vec3 wo, uint64_t seed)
{
    const long N = 200000;
    pf_vec3 n = pf_v3(0, 0, 1);
    static long count[2 * NC * NP];
    static double expect[2 * NC * NP];
    memset(count, 0, sizeof count);
    for (int i = 0; i < 2 * NC; i++)
        for (int j = 0; j < NP; j++) {
            double e = 0.0;
            for (int a = 0; a < SUB; a++)
                for (int b = 0; b < SUB; b++) {
                    double th = PI_D * (i + (a + 0.5) / SUB) / (2 * NC);
                    double phi = 2.0 * PI_D * (j + (b + 0.5) / SUB) / NP;
                    double dw = sin(th) * (PI_D / (2 * NC * SUB)) * (2.0 * PI_D / (NP * SUB));
                    e += pf_difftrans_pdf(m, n, wo, s_dir(cos(th), phi)) * dw;
                }
            expect[i * NP + j] = e * N;
        }
    long bad = 0;
    for (long s = 0; s < N; s++) {
        pf_rng_t r = pf_rng_make(seed, PF_STREAM_TEST, (uint64_t)s, 0);
        float u0 = pf_rng_float(&r), u1 = pf_rng_float(&r), u2 = pf_rng_float(&r);
        pf_vec3 wi, w;
        float pdf;
        if (!pf_difftrans_sample(m, n, wo, u0, u1, u2, &wi, &w, &pdf)) {
            bad++;
            continue;
        }
        /* the weight and pdf the sampler reports are the eval's and the pdf's */
        float p2 = pf_difftrans_pdf(m, n, wo, wi);
        pf_vec3 f = pf_difftrans_eval(m, n, wo, wi), w2 = pf_scale(f, fabsf(wi.z) / p2);
        if (fabsf(pf_len(wi) - 1.0f) > 1e-4f || !(pdf > 0.0f) || fabsf(p2 - pdf) > 1e-4f * pdf ||
            pf_maxc(pf_vabs(pf_sub(w, w2))) > 1e-3f * pf_maxc(w))
            bad++;
        double th = acos(fmin(1.0, fmax(-1.0, (double)wi.z)));
        double ph = atan2(wi.y, wi.x);
        ph += ph < 0.0 ? 2.0 * PI_D : 0.0;
        int i = (int)(th / PI_D * 2 * NC), j = (int)(ph / (2.0 * PI_D) * NP);
        i = i < 2 * NC ? i : 2 * NC - 1;
        j = j < NP ? j : NP - 1;
        count[i * NP + j]++;
    }
    CHECK(bad == 0, "wo.z %g: %ld samples failed, not unit, or disagree with eval / pdf", wo.z, bad);
    double x2 = 0.0, pe = 0.0, pc = 0.0;
    int dof = -1;
    for (int b = 0; b < 2 * NC * NP; b++) {
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
    CHECK(dof >= 100 && x2 < limit, "wo.z %g R %g T %g: chi2 %.1f (dof %d, limit %.1f)", wo.z, m->kd.x, m->kt.x, x2,
          dof, limit);
    printf("chi2 wo.z %+.2f R %.2f T %.2f: %.1f (dof %d, limit %.1f)\n", wo.z, m->kd.x, m->kt.x, x2, dof, limit);
}

/* The white furnace: R + T = 1 reflects and transmits all it receives. */
static void s_test_furnace(pf_vec3 wo)
{
    pf_material_t m = s_sheet(pf_v3(0.3f, 0.5f, 0.9f), pf_v3(0.7f, 0.5f, 0.1f));
    pf_vec3 n = pf_v3(0, 0, 1);
    const long N = 200000;
    double sum[3] = { 0 }, sum2[3] = { 0 }, refl[3] = { 0 };
    for (long s = 0; s < N; s++) {
        pf_rng_t r = pf_rng_make(7, PF_STREAM_TEST, (uint64_t)s, 0);
        float u0 = pf_rng_float(&r), u1 = pf_rng_float(&r), u2 = pf_rng_float(&r);
        pf_vec3 wi, w;
        float pdf;
        if (!pf_difftrans_sample(&m, n, wo, u0, u1, u2, &wi, &w, &pdf))
            continue;
        float c[3] = { w.x, w.y, w.z };
        for (int k = 0; k < 3; k++) {
            sum[k] += c[k];
            sum2[k] += (double)c[k] * c[k];
            if ((wi.z > 0.0f) == (wo.z > 0.0f))
                refl[k] += c[k];
        }
    }
    float rr[3] = { 0.3f, 0.5f, 0.9f };
    for (int k = 0; k < 3; k++) {
        double mean = sum[k] / N, se = sqrt(fmax(sum2[k] / N - mean * mean, 0.0) / N);
        CHECK(fabs(mean - 1.0) < 5.0 * se + 1e-6, "channel %d: mean weight %.5f (se %.5f), not 1", k, mean, se);
        CHECK(fabs(refl[k] / N - rr[k]) < 5.0 * se + 1e-6, "channel %d: reflected %.5f, want R %.2f", k, refl[k] / N,
              rr[k]);
    }
    /* quadrature of f |cos| over the sphere */
    double q[3] = { 0 };
    const int M = 256;
    for (int i = 0; i < M; i++)
        for (int j = 0; j < 8; j++) {
            double th = PI_D * (i + 0.5) / M, phi = 2.0 * PI_D * (j + 0.5) / 8;
            pf_vec3 wi = s_dir(cos(th), phi);
            pf_vec3 f = pf_difftrans_eval(&m, n, wo, wi);
            double dw = sin(th) * (PI_D / M) * (2.0 * PI_D / 8), c = fabs(cos(th));
            q[0] += f.x * c * dw;
            q[1] += f.y * c * dw;
            q[2] += f.z * c * dw;
        }
    CHECK(fabs(q[0] - 1.0) < 0.005 && fabs(q[1] - 1.0) < 0.005 && fabs(q[2] - 1.0) < 0.005,
          "albedo by quadrature %.4f %.4f %.4f", q[0], q[1], q[2]);
}

static void s_test_reciprocity(void)
{
    pf_material_t m = s_sheet(pf_v3(0.2f, 0.4f, 0.6f), pf_v3(0.7f, 0.5f, 0.3f));
    pf_vec3 n = pf_norm(pf_v3(0.3f, -0.2f, 0.9f));
    int bad = 0;
    for (int s = 0; s < 1000; s++) {
        pf_rng_t r = pf_rng_make(11, PF_STREAM_TEST, (uint64_t)s, 0);
        pf_vec3 a = pf_sample_sphere(pf_rng_float(&r), pf_rng_float(&r));
        pf_vec3 b = pf_sample_sphere(pf_rng_float(&r), pf_rng_float(&r));
        pf_vec3 fab = pf_difftrans_eval(&m, n, a, b), fba = pf_difftrans_eval(&m, n, b, a);
        bad += fab.x != fba.x || fab.y != fba.y || fab.z != fba.z;
    }
    CHECK(bad == 0, "%d of 1000 pairs not reciprocal", bad);
    pf_material_t black = s_sheet(pf_v3s(0.0f), pf_v3s(0.0f));
    pf_vec3 wi, w;
    float pdf;
    CHECK(!pf_difftrans_sample(&black, pf_v3(0, 0, 1), pf_v3(0, 0, 1), 0.5f, 0.5f, 0.5f, &wi, &w, &pdf) &&
              pf_difftrans_pdf(&black, pf_v3(0, 0, 1), pf_v3(0, 0, 1), pf_v3(0, 0, -1)) == 0.0f,
          "a black sheet samples nothing");
}

int main(void)
{
    pf_vec3 up = pf_norm(pf_v3(0.4f, 0.1f, 0.9f)), down = pf_norm(pf_v3(-0.5f, 0.3f, -0.6f));
    pf_material_t a = s_sheet(pf_v3(0.3f, 0.5f, 0.9f), pf_v3(0.7f, 0.5f, 0.1f));
    pf_material_t b = s_sheet(pf_v3(0.1f, 0.1f, 0.1f), pf_v3(0.6f, 0.2f, 0.4f));
    pf_material_t c = s_sheet(pf_v3(0.5f, 0.5f, 0.5f), pf_v3(0.0f, 0.0f, 0.0f));
    s_test_chi2(&a, up, 1);
    s_test_chi2(&a, down, 2);
    s_test_chi2(&b, up, 3);
    s_test_chi2(&c, down, 4);
    s_test_furnace(up);
    s_test_furnace(down);
    s_test_reciprocity();
    return pf_test_finish();
}
