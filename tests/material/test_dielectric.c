/* test_dielectric.c: the smooth dielectrics of material/dielectric.h as
 * paths split on them, above all the thin sheet (pbrt-v4's thindielectric).
 *
 * Thin sheet: its reflect probability f against R' = R + T^2 R / (1 - R^2)
 * with R the Fresnel reflectance written out here in double (s and p
 * polarizations) and T = 1 - R, at several angles and indices; its transmit
 * probability 1 - f against the inner bounces summed term by term,
 * T^2 (1 + R^2 + R^4 + ...), so the two add to 1 only if both are right; the
 * closed form at normal incidence 2 R0 / (1 + R0); the same f, an unbent
 * transmitted direction (-wo) and no total internal reflection when hit from
 * behind (at angles where solid glass reflects totally); kt untouched by the
 * indices; and the split's frequencies over many uniform draws (as photons
 * and gather rays choose) within 5 standard errors of f. Solid glass: the
 * entering tint kt / ior^2 and total internal reflection from inside, as
 * before the thin sheet existed. */
#include <math.h>
#include <stdio.h>

#include "base/rng.h"
#include "base/vec.h"
#include "material/bsdf.h"
#include "material/dielectric.h"

#include "check.h"

/* The unpolarized Fresnel reflectance from vacuum into index n at incident
 * cosine c, written out independently of bsdf.c. */
static double s_fresnel(double c, double n)
{
    double s = sqrt(1.0 - c * c) / n, ct = sqrt(1.0 - s * s);
    double rs = (c - n * ct) / (c + n * ct), rp = (n * c - ct) / (n * c + ct);
    return 0.5 * (rs * rs + rp * rp);
}

static pf_material_t s_pane(float ior)
{
    pf_material_t m = pf_material_default("pane");
    m.type = PF_MAT_THIN_DIELECTRIC;
    m.kd = pf_v3s(0.0f);
    m.ks = pf_v3s(1.0f);
    m.kt = pf_v3(0.9f, 0.8f, 0.7f);
    m.ior = ior;
    return m;
}

static int s_same_dir(pf_vec3 a, pf_vec3 b) { return pf_len(pf_sub(a, b)) < 1e-6f; }

/* The split at incident cosine c from both sides of a pane in the xz plane
 * (geometric and shading normal +y). */
static void s_test_thin_angle(float ior, double c)
{
    pf_material_t m = s_pane(ior);
    double r = s_fresnel(c, ior), t = 1.0 - r;
    double rp = r + t * t * r / (1.0 - r * r);
    double tp = 0.0, bounce = t * t;
    for (int k = 0; k < 200; k++, bounce *= r * r)
        tp += bounce;
    float sn = (float)sqrt(1.0 - c * c);
    pf_vec3 ng = pf_v3(0, 1, 0);
    for (int side = 0; side < 2; side++) {
        /* from above (against ng) or from below (along it) */
        pf_vec3 d = side == 0 ? pf_v3(sn, -(float)c, 0) : pf_v3(sn, (float)c, 0);
        pf_vec3 wo = pf_neg(d);
        pf_vec3 ns = side == 0 ? ng : pf_neg(ng);
        pf_dielectric_t g = pf_dielectric_at(&m, d, ng, wo, ns);
        CHECK(fabs(g.f - rp) < 2e-6, "ior %g cos %.3f side %d: reflect %.7f, R' %.7f", ior, c, side, g.f, rp);
        CHECK(fabs((1.0 - g.f) - tp) < 2e-6, "ior %g cos %.3f side %d: transmit %.7f, summed bounces %.7f", ior, c,
              side, 1.0 - g.f, tp);
        CHECK(fabs(rp + tp - 1.0) < 1e-12, "R' + T' = %.15f", rp + tp);
        CHECK(g.can_refract && s_same_dir(g.wt, d), "ior %g cos %.3f side %d: transmitted (%g %g %g), not straight on",
              ior, c, side, g.wt.x, g.wt.y, g.wt.z);
        CHECK(s_same_dir(g.wr, pf_v3(d.x, -d.y, d.z)), "side %d: mirror direction", side);
        CHECK(g.kt.x == m.kt.x && g.kt.y == m.kt.y && g.kt.z == m.kt.z, "thin kt scaled: %g %g %g", g.kt.x, g.kt.y,
              g.kt.z);
        CHECK(fabs(pf_fresnel_thin((float)(side ? -c : c), ior) - rp) < 2e-6, "pf_fresnel_thin at cos %+.3f",
              side ? -c : c);
    }
}

/* The split as photons and gather rays take it: reflect when u < f. */
static void s_test_frequencies(void)
{
    pf_material_t m = s_pane(1.5f);
    const double cs[] = { 1.0, 0.5, 0.15 };
    for (int i = 0; i < 3; i++) {
        float sn = (float)sqrt(1.0 - cs[i] * cs[i]);
        pf_vec3 d = pf_v3(sn, (float)cs[i], 0); /* from behind */
        pf_dielectric_t g = pf_dielectric_at(&m, d, pf_v3(0, 1, 0), pf_neg(d), pf_v3(0, -1, 0));
        pf_rng_t rng = pf_rng_make(7, PF_STREAM_TEST, (uint64_t)i, 0);
        const int n = 200000;
        int refl = 0;
        for (int k = 0; k < n; k++)
            refl += pf_rng_float(&rng) < g.f || !g.can_refract;
        double p = (double)refl / n, se = sqrt(g.f * (1.0 - g.f) / n);
        CHECK(fabs(p - g.f) < 5.0 * se + 1e-9, "cos %.2f: reflected %.5f of draws, R' %.5f", cs[i], p, g.f);
    }
}

static void s_test_thin(void)
{
    const float iors[] = { 1.33f, 1.5f, 2.4f };
    const double cs[] = { 1.0, 0.9, 0.7, 0.5, 0.3, 0.1, 0.02 };
    for (int i = 0; i < 3; i++)
        for (int k = 0; k < 7; k++)
            s_test_thin_angle(iors[i], cs[k]);
    double r0 = (0.5 / 2.5) * (0.5 / 2.5);
    CHECK(fabs(pf_fresnel_thin(1.0f, 1.5f) - 2.0 * r0 / (1.0 + r0)) < 1e-6, "normal incidence: %.7f, 2R0/(1+R0) %.7f",
          pf_fresnel_thin(1.0f, 1.5f), 2.0 * r0 / (1.0 + r0));
    CHECK(pf_fresnel_thin(0.0f, 1.5f) == 1.0f, "grazing: %g", pf_fresnel_thin(0.0f, 1.5f));
    s_test_frequencies();
}

/* Solid glass keeps its rules: refraction and kt / ior^2 entering, total
 * internal reflection leaving at cos 0.3 (sin 0.95 > 1 / 1.5). */
static void s_test_glass(void)
{
    pf_material_t m = s_pane(1.5f);
    m.type = PF_MAT_GLASS;
    pf_vec3 ng = pf_v3(0, 1, 0);
    pf_vec3 d = pf_norm(pf_v3(0.6f, -0.8f, 0));
    pf_dielectric_t in = pf_dielectric_at(&m, d, ng, pf_neg(d), ng);
    CHECK(in.can_refract && fabs(in.f - s_fresnel(0.8, 1.5)) < 2e-6, "glass entering: f %g", in.f);
    CHECK(fabsf(in.wt.x - 0.4f) < 1e-6f && in.wt.y < 0.0f, "glass bends: sin_t %g, expected 0.4", in.wt.x);
    CHECK(fabsf(in.kt.x - 0.9f / 2.25f) < 1e-6f, "glass kt entering %g", in.kt.x);
    pf_vec3 up = pf_norm(pf_v3(0.95f, 0.3122499f, 0));
    pf_dielectric_t out = pf_dielectric_at(&m, up, ng, pf_neg(up), pf_neg(ng));
    CHECK(!out.can_refract && out.f == 1.0f, "glass leaving at cos 0.31: f %g, refracts %d", out.f, out.can_refract);
}

/* Rough glass (pf_dielectric_rough_at): per incident angle and side, the
 * mean power a photon keeps (reflected with probability f carrying gr,
 * else refracted carrying gt) is at most 1 and, for alpha 0.05 away from
 * grazing (cos > 0.4), within 2 % of 1 (single scattering loses little at
 * low roughness; at cos 0.2 inside, 4 %: tilted facets send the totally
 * reflected light below the surface); the reflected share tends to the smooth Fresnel R as alpha -> 0;
 * every branch leaves on its own side. */
static void s_test_rough(void)
{
    const float alphas[3] = { 0.01f, 0.05f, 0.3f };
    pf_vec3 ng = pf_v3(0, 0, 1);
    for (int a = 0; a < 3; a++)
        for (int side = 0; side < 2; side++)
            for (float c = 0.2f; c < 1.0f; c += 0.25f) {
                pf_material_t m = pf_material_default("rough");
                m.type = PF_MAT_GLASS;
                m.ior = 1.5f;
                m.alpha = alphas[a];
                pf_vec3 wo = pf_v3(sqrtf(1.0f - c * c), 0.0f, side ? -c : c), ns = side ? pf_neg(ng) : ng;
                pf_vec3 d = pf_neg(wo);
                double keep = 0.0, refl = 0.0;
                int wrong = 0;
                const int N = 20000;
                for (int i = 0; i < N; i++) {
                    pf_rng_t r = pf_rng_make(5 + (uint64_t)a, PF_STREAM_TEST, (uint64_t)i, (uint32_t)side);
                    float u1 = pf_rng_float(&r), u2 = pf_rng_float(&r);
                    pf_dielectric_t g = pf_dielectric_rough_at(&m, d, ng, wo, ns, u1, u2);
                    float t = g.can_refract ? 1.0f - g.f : 0.0f;
                    keep += (1.0f - t) * g.gr + t * g.gt;
                    refl += (1.0f - t) * g.gr;
                    wrong += (g.gr > 0.0f && pf_dot(g.wr, ns) <= 0.0f) ||
                             (g.can_refract && g.gt > 0.0f && pf_dot(g.wt, ns) >= 0.0f);
                }
                keep /= N;
                refl /= N;
                float rs = pf_fresnel_dielectric(c, side ? 1.5f : 1.0f, side ? 1.0f : 1.5f);
                CHECK(keep <= 1.0 + 1e-6 && wrong == 0, "alpha %g side %d cos %g: keeps %.4f, %d on the wrong side",
                      alphas[a], side, c, keep, wrong);
                if (alphas[a] <= 0.05f && c > 0.4f)
                    CHECK(keep > 0.98, "alpha %g side %d cos %g: keeps only %.4f", alphas[a], side, c, keep);
                if (alphas[a] <= 0.01f)
                    CHECK(fabs(refl - rs) < 0.02, "alpha %g side %d cos %g: reflects %.4f, smooth R %.4f", alphas[a],
                          side, c, refl, rs);
                if (c > 0.9f)
                    printf("rough glass alpha %.2f %s, cos %.2f: keeps %.4f, reflects %.4f (smooth R %.4f)\n",
                           alphas[a], side ? "inside" : "outside", c, keep, refl, rs);
            }
}

int main(void)
{
    s_test_thin();
    s_test_glass();
    s_test_rough();
    return pf_test_finish();
}
