/* test_sphtri.c: spherical triangles (light/sphtri.h) and direct light's
 * use of them (light.c):
 *   - the solid angle against a count of uniform sphere directions that
 *     hit the triangle (a big near one, a thin one, one seen at grazing);
 *   - the sampler: every direction hits the triangle, and they fall on its
 *     16 sub-triangles (midpoint subdivision, twice) as their solid angles
 *     say (chi-square);
 *   - direct light: a large ceiling panel over a floor and a wall that
 *     touches it: the irradiance estimate at points of both against the
 *     closed form (the floor) and a quadrature (the wall) within 5 se and
 *     1 %, the pdf each sample reports equal to pf_lights_pdf_at at its
 *     point (MIS's), and on the wall 2 cm under the panel the variance per
 *     sample at least 10 times below area sampling's (measured: see the
 *     output). */
#include <math.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>

#include "base/rng.h"
#include "base/sampling.h"
#include "base/vec.h"
#include "light/light.h"
#include "light/sphtri.h"
#include "scene/scene.h"

#include "check.h"
#include "scenes_gen.h"

static double s_uniform(pf_rng_t *r) { return (double)pf_rng_float(r); }

/* Whether the ray from x along unit d hits triangle p0 p1 p2 (Moller-Trumbore, double). */
static int s_hits(pf_vec3 x, pf_vec3 d, pf_vec3 p0, pf_vec3 p1, pf_vec3 p2)
{
    double e1[3] = { p1.x - p0.x, p1.y - p0.y, p1.z - p0.z }, e2[3] = { p2.x - p0.x, p2.y - p0.y, p2.z - p0.z };
    double dd[3] = { d.x, d.y, d.z }, s[3] = { x.x - p0.x, x.y - p0.y, x.z - p0.z };
    double p[3] = { dd[1] * e2[2] - dd[2] * e2[1], dd[2] * e2[0] - dd[0] * e2[2], dd[0] * e2[1] - dd[1] * e2[0] };
    double det = e1[0] * p[0] + e1[1] * p[1] + e1[2] * p[2];
    if (fabs(det) < 1e-14)
        return 0;
    double u = (s[0] * p[0] + s[1] * p[1] + s[2] * p[2]) / det;
    double q[3] = { s[1] * e1[2] - s[2] * e1[1], s[2] * e1[0] - s[0] * e1[2], s[0] * e1[1] - s[1] * e1[0] };
    double v = (dd[0] * q[0] + dd[1] * q[1] + dd[2] * q[2]) / det;
    double t = (e2[0] * q[0] + e2[1] * q[1] + e2[2] * q[2]) / det;
    return u >= 0.0 && v >= 0.0 && u + v <= 1.0 && t > 0.0;
}

static pf_vec3 s_mid(pf_vec3 a, pf_vec3 b) { return pf_scale(pf_add(a, b), 0.5f); }

static void test_solid_angle(void)
{
    const pf_vec3 x = pf_v3(0, 0, 0);
    const pf_vec3 tris[][3] = {
        { { -1, 1, -1 }, { 2, 1, -1 }, { 0, 1, 2 } },         /* big and near: a large share of the sky */
        { { -0.1f, 2, 0 }, { 0.1f, 2, 0 }, { 0, 2.5f, 3 } },  /* thin */
        { { 1, 0.05f, 0 }, { 2, 0.05f, 1 }, { 1, 0.3f, 2 } }, /* near the horizon */
    };
    pf_rng_t r = pf_rng_make(11, PF_STREAM_TEST, 0, 0);
    for (int k = 0; k < 3; k++) {
        double omega = pf_sphtri_solid_angle(x, tris[k][0], tris[k][1], tris[k][2]);
        long hit = 0, n = 2000000;
        for (long i = 0; i < n; i++) {
            pf_vec3 d = pf_sample_sphere(pf_rng_float(&r), pf_rng_float(&r));
            hit += s_hits(x, d, tris[k][0], tris[k][1], tris[k][2]);
        }
        double p = (double)hit / (double)n, want = 4.0 * M_PI * p, se = 4.0 * M_PI * sqrt(p * (1.0 - p) / (double)n);
        printf("triangle %d: solid angle %.5f, by counting %.5f +- %.5f\n", k, omega, want, se);
        CHECK(fabs(omega - want) <= 5.0 * se, "triangle %d: solid angle %.6f against %.6f (5 se %.3g)", k, omega, want,
              5.0 * se);
    }
    CHECK(pf_sphtri_solid_angle(x, pf_v3(1, 0, 0), pf_v3(2, 0, 1), pf_v3(1, 0, 2)) == 0.0, "in x's plane: 0");
    CHECK(pf_sphtri_solid_angle(x, x, pf_v3(2, 1, 1), pf_v3(1, 1, 2)) == 0.0, "a vertex at x: 0");
}

/* The 16 sub-triangles of (a, b, c): midpoint subdivision twice. */
static void s_split16(pf_vec3 a, pf_vec3 b, pf_vec3 c, pf_vec3 out[16][3])
{
    pf_vec3 t4[4][3], ab = s_mid(a, b), bc = s_mid(b, c), ca = s_mid(c, a);
    pf_vec3 parts[4][3] = { { a, ab, ca }, { ab, b, bc }, { ca, bc, c }, { ab, bc, ca } };
    for (int i = 0; i < 4; i++)
        for (int j = 0; j < 3; j++)
            t4[i][j] = parts[i][j];
    for (int i = 0; i < 4; i++) {
        pf_vec3 p = t4[i][0], q = t4[i][1], s = t4[i][2];
        pf_vec3 pq = s_mid(p, q), qs = s_mid(q, s), sp = s_mid(s, p);
        pf_vec3 sub[4][3] = { { p, pq, sp }, { pq, q, qs }, { sp, qs, s }, { pq, qs, sp } };
        for (int j = 0; j < 4; j++)
            for (int v = 0; v < 3; v++)
                out[4 * i + j][v] = sub[j][v];
    }
}

static void test_sampler(void)
{
    const pf_vec3 x = pf_v3(0.2f, -0.1f, 0.3f);
    const pf_vec3 tris[][3] = {
        { { -1, 1, -1 }, { 2, 1, -1 }, { 0, 1, 2 } },
        { { 1, 0.05f, 0 }, { 2, 0.05f, 1 }, { 1, 0.3f, 2 } },
        { { -3, 0.2f, -3 }, { 3, 0.2f, -3 }, { 0, 0.2f, 4 } }, /* nearly a hemisphere (5 sr) */
    };
    pf_rng_t r = pf_rng_make(12, PF_STREAM_TEST, 0, 0);
    for (int k = 0; k < 3; k++) {
        pf_vec3 sub[16][3];
        s_split16(tris[k][0], tris[k][1], tris[k][2], sub);
        double omega = pf_sphtri_solid_angle(x, tris[k][0], tris[k][1], tris[k][2]), sum_sub = 0.0;
        double expect[16];
        for (int j = 0; j < 16; j++)
            sum_sub += expect[j] = pf_sphtri_solid_angle(x, sub[j][0], sub[j][1], sub[j][2]);
        CHECK(fabs(sum_sub - omega) < 1e-5 * omega, "triangle %d: the parts' solid angles add up (%.7f vs %.7f)", k,
              sum_sub, omega);
        long count[16] = { 0 }, off = 0, fail = 0, n = 400000;
        for (long i = 0; i < n; i++) {
            pf_vec3 w;
            if (!pf_sphtri_sample(x, tris[k][0], tris[k][1], tris[k][2], pf_rng_float(&r), pf_rng_float(&r), &w)) {
                fail++;
                continue;
            }
            off += !s_hits(x, w, tris[k][0], tris[k][1], tris[k][2]);
            for (int j = 0; j < 16; j++)
                if (s_hits(x, w, sub[j][0], sub[j][1], sub[j][2])) {
                    count[j]++;
                    break;
                }
        }
        double chi2 = 0.0;
        for (int j = 0; j < 16; j++) {
            double e = (double)n * expect[j] / omega;
            chi2 += ((double)count[j] - e) * ((double)count[j] - e) / e;
        }
        printf("triangle %d (%.4f sr): %ld samples failed, %ld off the triangle, chi-square over 16 parts %.1f\n", k,
               omega, fail, off, chi2);
        CHECK(fail == 0 && off <= n / 100000, "triangle %d: %ld failed, %ld samples off it", k, fail, off);
        CHECK(chi2 < 15.0 + 6.0 * sqrt(30.0), "triangle %d: chi-square %.1f over 15 dof", k, chi2);
    }
}

/* The irradiance at the origin (normal up) from a Lambertian rectangle
 * [x1, x2] x [z1, z2] at height h facing down, of radiance 1, by a fine
 * midpoint quadrature over the rectangle. */
static double s_rect_quad(pf_vec3 p, pf_vec3 n, double x1, double x2, double z1, double z2, double h)
{
    const int m = 800;
    double sum = 0.0, dx = (x2 - x1) / m, dz = (z2 - z1) / m;
    for (int i = 0; i < m; i++)
        for (int j = 0; j < m; j++) {
            double q[3] = { x1 + (i + 0.5) * dx - p.x, h - p.y, z1 + (j + 0.5) * dz - p.z };
            double d2 = q[0] * q[0] + q[1] * q[1] + q[2] * q[2], d = sqrt(d2);
            double cos_r = (q[0] * n.x + q[1] * n.y + q[2] * n.z) / d, cos_l = q[1] / d;
            if (cos_r > 0.0 && cos_l > 0.0)
                sum += cos_r * cos_l / d2 * dx * dz;
        }
    return sum;
}

static void test_direct(void)
{
    pf_scene_t *sc = pf_scene_create();
    pf_material_t m = pf_material_default("panel");
    m.kd = pf_v3s(0.0f);
    m.le = pf_v3s(1.0f);
    uint32_t lm = (uint32_t)pf_scene_add_material(sc, &m);
    /* a 2 x 1 panel at y = 1 facing down, one edge at x = 1 where a wall stands */
    pf_test_quad(sc, pf_v3(-1, 1, -0.5f), pf_v3(2, 0, 0), pf_v3(0, 0, 1), lm);
    pf_error_t err;
    PF_CHECK(pf_scene_finalize(sc, &err) == PF_OK);
    pf_lights_t *lt = pf_lights_build(sc);
    PF_CHECK(lt != NULL);
    struct {
        pf_vec3 x, n;
        const char *what;
    } pts[] = {
        { { 0.2f, 0.0f, 0.1f }, { 0, 1, 0 }, "floor under the panel" },
        { { 0.99f, 0.98f, 0.0f }, { -1, 0, 0 }, "wall 2 cm under its edge" },
        { { 0.99f, 0.5f, 0.3f }, { -1, 0, 0 }, "wall halfway down" },
    };
    pf_rng_t r = pf_rng_make(13, PF_STREAM_TEST, 0, 0);
    for (int k = 0; k < 3; k++) {
        const long n = 200000;
        double sum = 0.0, sum2 = 0.0, asum = 0.0, asum2 = 0.0, worst_pdf = 0.0;
        for (long i = 0; i < n; i++) {
            float u[3] = { pf_rng_float(&r), pf_rng_float(&r), pf_rng_float(&r) };
            pf_light_conn_t c;
            double v = 0.0;
            if (pf_lights_sample_direct_at(lt, sc, pts[k].x, pts[k].n, u, &c)) {
                v = c.weight.y * fmax(0.0, (double)pf_dot(c.wi, pts[k].n));
                pf_vec3 p = pf_madd(pts[k].x, c.wi, c.dist);
                /* the quad (o, o + e1, o + e1 + e2, o + e2) is triangles (0, 1, 2) and
                 * (0, 2, 3): the first holds the points with s >= t, p = o + s e1 + t e2 */
                uint32_t tri = (p.x + 1.0f) / 2.0f >= p.z + 0.5f ? 0u : 1u;
                float pa = pf_lights_pdf_at(lt, sc, pts[k].x, pts[k].n, 0, tri, p);
                worst_pdf = fmax(worst_pdf, fabs((double)pa / (double)c.pdf - 1.0));
            }
            sum += v;
            sum2 += v * v;
            /* area sampling of the same panel: a uniform point, f = cos_r cos_l / d^2 / (1 / A) */
            double px = -1.0 + 2.0 * s_uniform(&r), pz = -0.5 + s_uniform(&r);
            pf_vec3 q = pf_sub(pf_v3((float)px, 1.0f, (float)pz), pts[k].x);
            double d2 = pf_len2(q), d = sqrt(d2), cr = pf_dot(q, pts[k].n) / d, cl = q.y / d;
            double a = cr > 0.0 && cl > 0.0 ? cr * cl / d2 * 2.0 : 0.0;
            asum += a;
            asum2 += a * a;
        }
        double mean = sum / n, var = sum2 / n - mean * mean, se = sqrt(var / n);
        double amean = asum / n, avar = asum2 / n - amean * amean;
        double want = s_rect_quad(pts[k].x, pts[k].n, -1.0, 1.0, -0.5, 0.5, 1.0);
        printf("%s: irradiance %.5f against %.5f (5 se %.2g); variance per sample %.4g, by area %.4g (%.1fx); "
               "pdf against pf_lights_pdf_at within %.2g\n",
               pts[k].what, mean, want, 5.0 * se, var, avar, avar / var, worst_pdf);
        CHECK(fabs(mean - want) <= 5.0 * se && fabs(mean - want) <= 0.01 * want, "%s: irradiance %.5f, not %.5f",
              pts[k].what, mean, want);
        CHECK(worst_pdf < 1e-4, "%s: a sample's pdf differs from pf_lights_pdf_at's by %.3g", pts[k].what, worst_pdf);
        if (k == 1)
            CHECK(avar / var > 10.0, "%s: spherical sampling's variance only %.1fx below area sampling's", pts[k].what,
                  avar / var);
    }
    pf_lights_destroy(&lt);
    pf_scene_destroy(&sc);
}

int main(void)
{
    test_solid_angle();
    test_sampler();
    test_direct();
    return pf_test_finish();
}
