/* test_coated.c: a coated floor (PF_MAT_COATED) under a small area light,
 * through the whole renderer, in-process, against a brute-force estimate
 * made here.
 *
 * The camera looks down at the floor so that the light's reflection (the
 * coat's highlight) and the plain base both fill part of the image; the
 * light itself is out of view. The renderer's image with the direct term
 * (and, for the smooth coat, the emitted term: the light seen in its
 * mirror) is compared with a reference that integrates, for each of 8 x 8
 * points in every pixel, f(wo, wi) Le cos cos' / d^2 over the
 * light by a 16 x 16 grid (pf_coated_f, material/coated.h);
 * a smooth coat's mirror adds F(cos_o) Le where the mirror ray meets the
 * light. Checked: relMSE over the image, and the mean of the brightest
 * (highlight) pixels and of the rest (base) each within a few per cent of
 * the reference's (within 2 % and 1 %; measured +0.13 % and +0.04 % rough,
 * -0.05 % and +0.03 % smooth; relMSE below 0.002, measured 0.00026 and
 * 0.00014) (highlight: reference above 0.2 of its peak; base:
 * below 0.05). Rough alpha 0.1 (light samples and the coat's BSDF ray
 * by MIS) and smooth (the mirror ray). */
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "base/rng.h"
#include "coordinator/job.h"
#include "image/image.h"
#include "material/bsdf.h"
#include "material/coated.h"
#include "render/render.h"
#include "scene/camera.h"
#include "scene/scene.h"

#include "check.h"
#include "scenes_gen.h"

enum { SIZE = 24 };
#define LE 100.0f
#define LY 2.0f
#define LH 0.25f /* the light's half side */

static pf_scene_t *s_scene(float alpha, pf_material_t *coat)
{
    pf_scene_t *scene = pf_scene_create();
    pf_material_t m = pf_material_default("coat");
    m.type = PF_MAT_COATED;
    m.kd = pf_v3(0.6f, 0.3f, 0.1f);
    m.alpha = alpha;
    m.ior = 1.5f;
    m.thickness = 0.01f;
    *coat = m;
    uint32_t floor = (uint32_t)pf_scene_add_material(scene, &m);
    pf_test_quad(scene, pf_v3(-6, 0, -6), pf_v3(0, 0, 12), pf_v3(12, 0, 0), floor); /* normal +y */
    pf_material_t e = pf_material_default("light");
    e.kd = pf_v3s(0.0f);
    e.le = pf_v3s(LE);
    pf_test_quad(scene, pf_v3(-LH, LY, -LH), pf_v3(2 * LH, 0, 0), pf_v3(0, 0, 2 * LH),
                 (uint32_t)pf_scene_add_material(scene, &e)); /* normal -y */
    scene->camera = (pf_camera_desc_t){ .pos = { 0, 1, 2 }, .look_at = { 0, 0, 1.0f }, .up = { 0, 1, 0 },
                                        .vfov_deg = 50.0f };
    scene->has_camera = 1;
    return scene;
}

/* The reference radiance of the floor point p seen along -wo. */
static pf_vec3 s_reference_at(const pf_material_t *m, pf_vec3 p, pf_vec3 wo)
{
    const int G = 16;
    pf_vec3 n = pf_v3(0, 1, 0), sum = pf_v3s(0.0f);
    float area = 4.0f * LH * LH;
    for (int i = 0; i < G; i++)
        for (int j = 0; j < G; j++) {
            pf_vec3 q = pf_v3(-LH + 2 * LH * ((float)i + 0.5f) / G, LY, -LH + 2 * LH * ((float)j + 0.5f) / G);
            pf_vec3 d = pf_sub(q, p);
            float d2 = pf_dot(d, d);
            pf_vec3 wi = pf_scale(d, 1.0f / sqrtf(d2));
            float g = wi.y * wi.y / d2; /* cos at p times cos at the light (both wi.y) */
            sum = pf_add(sum, pf_scale(pf_coated_f(m, n, wo, wi), LE * g * area / (float)(G * G)));
        }
    if (pf_coated_smooth(m)) { /* the mirror: where does it meet the light's plane? */
        pf_vec3 r = pf_reflect(wo, n);
        float t = (LY - p.y) / r.y;
        pf_vec3 q = pf_madd(p, r, t);
        if (r.y > 0.0f && fabsf(q.x) < LH && fabsf(q.z) < LH)
            sum = pf_add(sum, pf_v3s(LE * pf_coat_albedo(wo.y, 0.0f, m->ior)));
    }
    return sum;
}

static void s_reference(const pf_scene_t *scene, const pf_material_t *m, float *ref)
{
    pf_camera_t cam = pf_camera_make(&scene->camera, SIZE, SIZE);
    for (int y = 0; y < SIZE; y++)
        for (int x = 0; x < SIZE; x++) {
            pf_vec3 acc = pf_v3s(0.0f);
            for (int s = 0; s < 64; s++) {
                pf_ray_t r = pf_camera_ray(&cam, (float)x + ((float)(s % 8) + 0.5f) / 8.0f,
                                           (float)y + ((float)(s / 8) + 0.5f) / 8.0f);
                float t = -r.o.y / r.d.y;
                acc = pf_add(acc, s_reference_at(m, pf_madd(r.o, r.d, t), pf_neg(r.d)));
            }
            float *o = &ref[3 * ((size_t)y * SIZE + (size_t)x)];
            o[0] = acc.x / 64.0f, o[1] = acc.y / 64.0f, o[2] = acc.z / 64.0f;
        }
}

static void s_test(float alpha)
{
    pf_material_t m;
    pf_scene_t *scene = s_scene(alpha, &m);
    pf_error_t err = { { 0 } };
    int rc = pf_scene_finalize(scene, &err);
    CHECK(rc == PF_OK, "finalize: %s", err.msg);
    pf_settings_t s = scene->settings;
    s.width = s.height = SIZE;
    s.spp = 64;
    s.photons = 1000;
    s.caustic_photons = 0;
    s.threads = 0;
    pf_image_t img;
    pf_job_summary_t sum;
    unsigned terms = PF_TERM_DIRECT | PF_TERM_EMITTED;
    rc = rc ? rc : pf_job_render_local(scene, &s, terms, 0, &img, &sum, &err);
    CHECK(rc == PF_OK, "render: %s", err.msg);
    if (rc == PF_OK) {
        static float ref[3 * SIZE * SIZE];
        s_reference(scene, &m, ref);
        /* the highlight: pixels whose reference is above 3x the median-ish base level */
        double rel = 0.0, hi[2] = { 0, 0 }, lo[2] = { 0, 0 }, peak = 0.0;
        for (int k = 0; k < 3 * SIZE * SIZE; k++)
            peak = fmax(peak, ref[k]);
        int nhi = 0, nlo = 0;
        for (int k = 0; k < 3 * SIZE * SIZE; k++) {
            double a = img.rgb[k], b = ref[k];
            rel += (a - b) * (a - b) / (b * b + 0.01);
            if (k % 3 != 2)
                continue; /* blue: the base is darkest there, so the coat shows most */
            if (b > 0.2 * peak) {
                nhi++;
                hi[0] += a, hi[1] += b;
            } else if (b < 0.05 * peak) {
                nlo++;
                lo[0] += a, lo[1] += b;
            }
        }
        rel /= 3.0 * SIZE * SIZE;
        printf("alpha %.2f: relMSE %.5f; highlight (%d px) %.4f vs %.4f (%+.2f %%), base (%d px) %.4f vs %.4f "
               "(%+.2f %%)\n",
               alpha, rel, nhi, hi[0] / nhi, hi[1] / nhi, 100.0 * (hi[0] / hi[1] - 1.0), nlo,
               lo[0] / nlo, lo[1] / nlo, 100.0 * (lo[0] / lo[1] - 1.0));
        CHECK(nhi >= 4 && nhi < SIZE * SIZE / 2, "alpha %g: %d highlight pixels", alpha, nhi);
        CHECK(fabs(hi[0] / hi[1] - 1.0) < 0.02, "alpha %g: highlight off by %+.2f %%", alpha,
              100.0 * (hi[0] / hi[1] - 1.0));
        CHECK(fabs(lo[0] / lo[1] - 1.0) < 0.01, "alpha %g: base off by %+.2f %%", alpha, 100.0 * (lo[0] / lo[1] - 1.0));
        CHECK(rel < 0.002, "alpha %g: relMSE %.5f", alpha, rel);
        pf_image_free(&img);
    }
    pf_scene_destroy(&scene);
}

/* Rough glass in a furnace (test_render.c's: a closed sphere of emission 1
 * and albedo a, radiance 1 / (1 - a) everywhere): a lossless rough glass
 * ball (alpha 0.03) filling most of the view must leave the radiance nearly
 * unchanged through every pass (camera paths, gather rays and photons cross
 * it as a random branch): the mean between -3 % and +1 %. Single
 * scattering off GGX loses energy where tilted facets send light below
 * the surface, so it may only darken: measured smooth +0.15 %, alpha 0.02
 * -1.3 %, alpha 0.1 -6.2 % (pbrt-v4's rough dielectric loses the same). */
static void s_test_rough_glass_furnace(void)
{
    const float a = 0.5f;
    pf_scene_t *scene = pf_scene_create();
    pf_material_t m = pf_material_default("furnace");
    m.kd = pf_v3s(a);
    m.le = pf_v3s(1.0f);
    pf_test_inward_sphere(scene, 4, 4.0f, (uint32_t)pf_scene_add_material(scene, &m));
    pf_material_t g = pf_material_default("rough glass");
    g.type = PF_MAT_GLASS;
    g.kd = pf_v3s(0.0f);
    g.ks = g.kt = pf_v3s(1.0f);
    g.ior = 1.5f;
    g.alpha = 0.03f;
    pf_sphere_t ball = { { 1.5f, 0, 0 }, 1.0f, (uint32_t)pf_scene_add_material(scene, &g) };
    pf_scene_add_sphere(scene, &ball);
    scene->camera = (pf_camera_desc_t){ .pos = { -1, 0, 0 }, .look_at = { 1.5f, 0, 0 }, .up = { 0, 1, 0 },
                                        .vfov_deg = 40.0f };
    scene->has_camera = 1;
    pf_error_t err = { { 0 } };
    int rc = pf_scene_finalize(scene, &err);
    pf_settings_t s = scene->settings;
    s.width = s.height = 16;
    s.spp = 16;
    s.photons = 40000;
    s.caustic_photons = 40000;
    s.gather = 8;
    s.threads = 0;
    pf_image_t img;
    pf_job_summary_t sum;
    rc = rc ? rc : pf_job_render_local(scene, &s, PF_TERM_ALL, 0, &img, &sum, &err);
    CHECK(rc == PF_OK, "render: %s", err.msg);
    if (rc == PF_OK) {
        double mean = 0.0, expect = 1.0 / (1.0 - a);
        for (int k = 0; k < 3 * 16 * 16; k++)
            mean += img.rgb[k];
        mean /= 3 * 16 * 16;
        printf("rough glass ball in the furnace: mean %.4f, expected %.4f (%+.2f %%)\n", mean, expect,
               100.0 * (mean / expect - 1.0));
        CHECK(mean / expect - 1.0 < 0.01 && mean / expect - 1.0 > -0.03, "rough glass furnace: mean %.4f, expected %.4f", mean, expect);
        pf_image_free(&img);
    }
    pf_scene_destroy(&scene);
}

int main(void)
{
    s_test(0.1f);
    s_test(0.0f);
    s_test_rough_glass_furnace();
    return pf_test_finish();
}
