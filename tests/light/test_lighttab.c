/* test_lighttab.c: light/lighttab.h's guide tables pick exactly what a
 * bisection of the whole cdf picks (light.c's s_pick, envlight.c's s_find
 * before the guides), for random u, for u on every bucket's edge and next to
 * it, and for cdfs with runs of zero-probability entries, a single spike and
 * float cdfs; and an emissive triangle's record gives the point and normal
 * that the mesh's arrays give. A guide whose range missed the answer by one
 * entry (an off-by-one bucket, a hi bound one short) fails here. */
#include <math.h>
#include <stdlib.h>
#include <string.h>

#include "base/rng.h"
#include "base/sampling.h"
#include "light/lighttab.h"

#include "check.h"

static size_t s_bisect(const double *cdf, size_t n, float u)
{
    size_t lo = 0, hi = n;
    while (hi - lo > 1) {
        size_t mid = (lo + hi) / 2;
        if (cdf[mid] <= u)
            lo = mid;
        else
            hi = mid;
    }
    return lo;
}

static int s_fbisect(const float *c, int lo, int hi, float u)
{
    while (hi - lo > 1) {
        int mid = (lo + hi) / 2;
        if (c[mid] <= u)
            lo = mid;
        else
            hi = mid;
    }
    return lo;
}

/* A cdf of n entries of the given shape: 0 uniform, 1 zero runs, 2 one spike. */
static void s_make_cdf(double *cdf, float *fc, size_t n, int shape, pf_rng_t *r)
{
    double acc = 0.0;
    for (size_t i = 0; i < n; i++) {
        cdf[i] = acc;
        double p = shape == 0   ? 1.0 + pf_rng_float(r)
                   : shape == 1 ? ((i / 7) % 3 == 0 ? 0.0 : pf_rng_float(r))
                                : (i == n / 3 ? 1e6 : 1e-3 * pf_rng_float(r));
        acc += p;
    }
    for (size_t i = 0; i < n; i++)
        cdf[i] /= acc;
    cdf[n] = 1.0;
    for (size_t i = 0; i <= n; i++)
        fc[i] = (float)cdf[i];
}

static void s_check_u(const pf_cdf_guide_t *g, const uint32_t *fat, unsigned fbits, const double *cdf,
                      const float *fc, size_t n, float u, int *bad)
{
    size_t want = s_bisect(cdf, n, u), got = pf_cdf_guide_pick(g, cdf, n, u);
    int lo, hi;
    pf_fcdf_guide_range(fat, fbits, (int)n, u, &lo, &hi);
    int fwant = s_fbisect(fc, 0, (int)n, u), fgot = s_fbisect(fc, lo, hi, u);
    if (want != got || fwant != fgot) {
        if (*bad < 5)
            CHECK(0, "u %a: double %zu vs %zu, float %d vs %d", (double)u, got, want, fgot, fwant);
        (*bad)++;
    }
}

static void s_guides(void)
{
    const size_t sizes[] = { 2, 3, 5, 64, 1000, 11904 };
    pf_rng_t r = pf_rng_make(7, 1, 0, 0);
    for (size_t si = 0; si < sizeof sizes / sizeof *sizes; si++)
        for (int shape = 0; shape < 3; shape++) {
            size_t n = sizes[si];
            double *cdf = malloc((n + 1) * sizeof *cdf);
            float *fc = malloc((n + 1) * sizeof *fc);
            s_make_cdf(cdf, fc, n, shape, &r);
            pf_cdf_guide_t g;
            CHECK(pf_cdf_guide_build(&g, cdf, n) == 0);
            unsigned fbits = pf_guide_bits(n, 4);
            uint32_t *fat = malloc((((size_t)1 << fbits) + 1) * sizeof *fat);
            pf_fcdf_guide_fill(fat, fbits, fc, (int)n);
            int bad = 0;
            for (int i = 0; i < 20000; i++)
                s_check_u(&g, fat, fbits, cdf, fc, n, pf_rng_float(&r), &bad);
            /* every bucket edge of both guides, and the floats either side */
            for (unsigned bits = 1; bits <= 12; bits++)
                for (uint32_t j = 0; j <= (1u << bits); j++) {
                    float e = (float)j / (float)(1u << bits);
                    s_check_u(&g, fat, fbits, cdf, fc, n, e, &bad);
                    s_check_u(&g, fat, fbits, cdf, fc, n, nextafterf(e, 0.0f), &bad);
                    s_check_u(&g, fat, fbits, cdf, fc, n, nextafterf(e, 2.0f), &bad);
                }
            /* every entry's own cdf value, and its neighbours */
            for (size_t i = 0; i <= n; i++) {
                s_check_u(&g, fat, fbits, cdf, fc, n, (float)cdf[i], &bad);
                s_check_u(&g, fat, fbits, cdf, fc, n, nextafterf((float)cdf[i], 0.0f), &bad);
                s_check_u(&g, fat, fbits, cdf, fc, n, nextafterf((float)cdf[i], 2.0f), &bad);
            }
            /* outside [0, 1) */
            s_check_u(&g, fat, fbits, cdf, fc, n, 1.0f, &bad);
            s_check_u(&g, fat, fbits, cdf, fc, n, 1.5f, &bad);
            s_check_u(&g, fat, fbits, cdf, fc, n, -0.25f, &bad);
            CHECK(bad == 0, "n %zu shape %d: %d picks differ", n, shape, bad);
            pf_cdf_guide_free(&g);
            free(fat);
            free(cdf);
            free(fc);
        }
}

/* The record's point and normal against the arrays' (as light.c had them). */
static void s_records(void)
{
    pf_vec3 pos[3] = { pf_v3(0.1f, 0.2f, 0.3f), pf_v3(1.7f, -0.4f, 0.25f), pf_v3(0.3f, 2.1f, -0.9f) };
    pf_vec3 nrm[3] = { pf_v3(0, 0, -1), pf_v3(0, 0, -1), pf_v3(0, 0, -1) };
    uint32_t idx[3] = { 0, 1, 2 }, mat[1] = { 0 };
    pf_material_t mats[1];
    memset(mats, 0, sizeof mats);
    mats[0].le = pf_v3(3, 2, 1);
    pf_mesh_t mesh;
    memset(&mesh, 0, sizeof mesh);
    mesh.pos = pos, mesh.nrm = nrm, mesh.idx = idx, mesh.mat = mat, mesh.nverts = 3, mesh.ntris = 1;
    pf_scene_t scene;
    memset(&scene, 0, sizeof scene);
    scene.meshes = &mesh, scene.nmeshes = 1, scene.mats = mats, scene.nmats = 1;
    pf_emit_tri_t t = pf_emit_tri_make(&scene, 0, 0, 0.75f);
    pf_vec3 n = pf_norm(pf_cross(pf_sub(pos[1], pos[0]), pf_sub(pos[2], pos[0])));
    n = pf_face_forward(n, pf_add(pf_add(nrm[0], nrm[1]), nrm[2]));
    CHECK(memcmp(&t.n, &n, sizeof n) == 0 && t.n.z < 0.0f, "normal oriented by the vertex normals");
    CHECK(t.le.x == 3.0f && t.area == 0.75f);
    pf_rng_t r = pf_rng_make(9, 2, 0, 0);
    int bad = 0;
    for (int i = 0; i < 1000; i++) {
        float u1 = pf_rng_float(&r), u2 = pf_rng_float(&r), b0, b1;
        pf_sample_triangle(u1, u2, &b0, &b1);
        float b2 = 1.0f - b0 - b1;
        pf_vec3 want = pf_add(pf_add(pf_scale(pos[0], b0), pf_scale(pos[1], b1)), pf_scale(pos[2], b2));
        pf_vec3 werr = pf_tri_point_error(pos[0], pos[1], pos[2], b0, b1, b2), err;
        pf_vec3 got = pf_emit_tri_point(&t, u1, u2, &err);
        bad += memcmp(&want, &got, sizeof got) != 0 || memcmp(&werr, &err, sizeof err) != 0;
    }
    CHECK(bad == 0, "%d of 1000 points differ", bad);
}

int main(void)
{
    s_guides();
    s_records();
    return pf_test_finish();
}
