/* test_progressive.c: the progressive passes' photon estimate converges
 * (photon/photonmap.h, PF_PASS_ALPHA). A plane lit on one half only
 * (irradiance 1 for x < 0, 0 beyond: a shadow's edge), a row of query
 * points 0.3 k-nearest radii to either side of the edge; each pass traces
 * its own photons. The mean of the passes' estimates with the radius
 * shrinking (pf_pass_shrink2) must close in on the true 1 and 0 as passes
 * are added, where the unshrunk k-nearest estimate, however many passes
 * are averaged, keeps the blur across the edge (its bias). Also the shrink
 * schedule itself, and that pass 0 is the unshrunk estimate bit for bit. */
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "photon/kdtree.h"
#include "photon/photon.h"
#include "photon/photonmap.h"
#include "scene/scene.h"

#include "check.h"

static uint64_t s_state;

static uint64_t s_next(void)
{
    uint64_t z = (s_state += 0x9e3779b97f4a7c15ULL);
    z = (z ^ (z >> 30)) * 0xbf58476d1ce4e5b9ULL;
    z = (z ^ (z >> 27)) * 0x94d049bb133111ebULL;
    return z ^ (z >> 31);
}

static float s_uniform(void) { return (float)(s_next() >> 40) * 0x1p-24f; }

enum { S_PHOTONS = 20000, S_K = 50, S_QUERIES = 64 };

/* One pass's map: S_PHOTONS photons uniform over [-1, 0] x [-1, 1] on the
 * plane z = 0 (normal +z), power 2 / S_PHOTONS each: irradiance 1 there. */
static pf_kdtree_t *s_pass_map(int pass)
{
    s_state = pf_pass_seed(7, pass);
    pf_photon_t *ph = malloc(S_PHOTONS * sizeof *ph);
    PF_CHECK(ph != NULL);
    uint32_t up = pf_oct_encode(pf_v3(0, 0, 1)) & ~PF_PHOTON_AXIS_BITS;
    for (int i = 0; i < S_PHOTONS; i++) {
        memset(&ph[i], 0, sizeof ph[i]);
        ph[i].pos[0] = -s_uniform();
        ph[i].pos[1] = 2.0f * s_uniform() - 1.0f;
        ph[i].power[0] = ph[i].power[1] = ph[i].power[2] = 2.0f / S_PHOTONS;
        ph[i].dir = pf_oct_encode(pf_v3(0, 0, -1));
        ph[i].normal = up;
    }
    pf_kdtree_t *t = pf_kdtree_build(&ph, S_PHOTONS);
    PF_CHECK(t != NULL);
    return t;
}

/* The mean over the query row at x of one map's estimate (shrunk by
 * shrink2; cone filter or not). */
static double s_row(const pf_kdtree_t *t, float x, float shrink2, int cone, pf_pm_scratch_t *scratch)
{
    double sum = 0.0;
    for (int q = 0; q < S_QUERIES; q++) {
        float y = -0.8f + 1.6f * (float)q / (S_QUERIES - 1);
        pf_vec3 e = pf_pm_estimate(t, pf_v3(x, y, 0), pf_v3(0, 0, 1), S_K, 1.0f, INFINITY, shrink2, cone, scratch, NULL);
        sum += e.x;
    }
    return sum / S_QUERIES;
}

static void s_schedule(void)
{
    CHECK(pf_pass_shrink2(0) == 1.0f, "pass 0 is unshrunk (%g)", (double)pf_pass_shrink2(0));
    double s = 1.0;
    int monotone = 1;
    for (int i = 1; i <= 1000; i++) {
        s *= ((double)i + PF_PASS_ALPHA) / ((double)i + 1.0);
        float got = pf_pass_shrink2(i);
        if (fabs(got - s) > 1e-6 * s)
            CHECK(0, "shrink2(%d) = %g, the product says %g", i, (double)got, s);
        monotone &= got < pf_pass_shrink2(i - 1);
    }
    CHECK(monotone, "the radius shrinks with every pass");
    /* r_i^2 ~ i^(alpha - 1): a thousand passes shrink the area ~10x. */
    double ratio = pf_pass_shrink2(999) / pow(1000.0, PF_PASS_ALPHA - 1.0);
    CHECK(ratio > 0.5 && ratio < 2.0, "shrink2(999) %g against 1000^(alpha-1) (ratio %g)", (double)pf_pass_shrink2(999),
          ratio);
}

/* Pass 0 through pf_pm_estimate is the old estimate, bit for bit. */
static void s_pass0_same(pf_pm_scratch_t *scratch)
{
    pf_kdtree_t *t = s_pass_map(0);
    int same = 1;
    for (int q = 0; q < 200; q++) {
        pf_vec3 x = pf_v3(-1.2f + 1.4f * (float)q / 199.0f, 0.3f, 0.0f), n = pf_v3(0, 0, 1);
        float r2a, r2b;
        pf_vec3 a = pf_pm_irradiance_cone(t, x, n, S_K, 0.01f, INFINITY, scratch, &r2a);
        pf_vec3 b = pf_pm_estimate(t, x, n, S_K, 0.01f, INFINITY, pf_pass_shrink2(0), 1, scratch, &r2b);
        pf_vec3 c = pf_pm_irradiance(t, x, n, S_K, 0.01f, scratch, &r2a);
        pf_vec3 d = pf_pm_estimate(t, x, n, S_K, 0.01f, INFINITY, 1.0f, 0, scratch, &r2b);
        same &= memcmp(&a, &b, sizeof a) == 0 && memcmp(&c, &d, sizeof c) == 0 && r2a == r2b;
    }
    CHECK(same, "pass 0's estimate is the unshrunk one, bit for bit");
    pf_kdtree_destroy(&t);
}

static void s_converges(pf_pm_scratch_t *scratch, int cone)
{
    /* The k-nearest radius in the lit half: k = pi r^2 density. */
    double r = sqrt(S_K / (M_PI * S_PHOTONS / 2.0));
    float xin = (float)(-0.3 * r), xout = (float)(0.3 * r);
    enum { S_MARKS = 3 };
    const int marks[S_MARKS] = { 8, 32, 128 };
    double err_shrunk[S_MARKS], err_fixed[S_MARKS];
    double in_s = 0, out_s = 0, in_f = 0, out_f = 0;
    int m = 0;
    for (int pass = 0; pass < marks[S_MARKS - 1]; pass++) {
        pf_kdtree_t *t = s_pass_map(pass);
        float s2 = pf_pass_shrink2(pass);
        in_s += s_row(t, xin, s2, cone, scratch);
        out_s += s_row(t, xout, s2, cone, scratch);
        in_f += s_row(t, xin, 1.0f, cone, scratch);
        out_f += s_row(t, xout, 1.0f, cone, scratch);
        pf_kdtree_destroy(&t);
        if (pass + 1 == marks[m]) {
            double n = pass + 1;
            /* Error against the truth: 1 inside, 0 outside. */
            err_shrunk[m] = fabs(in_s / n - 1.0) + fabs(out_s / n);
            err_fixed[m] = fabs(in_f / n - 1.0) + fabs(out_f / n);
            printf("%s, %3d passes: inside %.4f / %.4f, outside %.4f / %.4f (shrunk / fixed radius); error %.4f / "
                   "%.4f\n",
                   cone ? "cone" : "box", pass + 1, in_s / n, in_f / n, out_s / n, out_f / n, err_shrunk[m],
                   err_fixed[m]);
            m++;
        }
    }
    CHECK(err_fixed[S_MARKS - 1] > 0.1, "%s: the fixed k-nearest estimate blurs the edge (error %.4f): the test sees "
          "the bias", cone ? "cone" : "box", err_fixed[S_MARKS - 1]);
    /* The blur across an edge goes as the radius, and pass i's radius as
     * i^((alpha - 1) / 2) = i^(-1/6): four times the passes take the
     * newest passes' blur down by 4^(-1/6) = 0.79, the mean over all passes
     * (the early, wide ones included) by less; measured 0.77-0.90. The
     * unshrunk estimate's error stays where it is. */
    for (int i = 1; i < S_MARKS; i++) {
        CHECK(err_shrunk[i] < 0.95 * err_shrunk[i - 1], "%s: the error falls from %d to %d passes (%.4f -> %.4f)",
              cone ? "cone" : "box", marks[i - 1], marks[i], err_shrunk[i - 1], err_shrunk[i]);
        CHECK(fabs(err_fixed[i] / err_fixed[0] - 1.0) < 0.05, "%s: the fixed radius's error stays (%.4f -> %.4f)",
              cone ? "cone" : "box", err_fixed[0], err_fixed[i]);
    }
    CHECK(err_shrunk[S_MARKS - 1] < 0.8 * err_fixed[S_MARKS - 1],
          "%s: after %d passes the shrinking radius is well below the fixed one's error (%.4f vs %.4f)",
          cone ? "cone" : "box", marks[S_MARKS - 1], err_shrunk[S_MARKS - 1], err_fixed[S_MARKS - 1]);
}

int main(void)
{
    pf_pm_scratch_t *scratch = calloc(1, sizeof *scratch);
    PF_CHECK(scratch != NULL);
    s_schedule();
    s_pass0_same(scratch);
    s_converges(scratch, 0);
    s_converges(scratch, 1);
    free(scratch);
    return pf_test_finish();
}
