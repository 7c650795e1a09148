/* test_medium.c: absorbing media (scene.h sigma_in / sigma_out; pbrt-v4's
 * homogeneous media without scattering) through the whole renderer,
 * in-process. The media's glass has index 1, so its faces neither bend nor
 * reflect light and every answer is Beer-Lambert's alone.
 *
 *   camera   the camera looks through a slab 1 deep (a closed box of index
 *            1 whose inside absorbs sigma = 0.5, 1, 2) at an emitter of
 *            radiance 1: every pixel (emitted term only, deterministic)
 *            must be exp(-sigma / cos theta), theta the angle of the
 *            pixel's ray to the slab's normal, averaged over the pixel,
 *            within 0.05 % (64 stratified samples); the same with the
 *            box's faces turned inward and the medium on their outside
 *            (the medium is the side the ray reaches a face from). The
 *            clear slab must show exactly 1.
 *   photons  a sun straight down through a slab 0.5 deep onto a diffuse
 *            floor, the camera between them looking down: the floor's
 *            direct + caustic radiance (caustic photons only, the slab
 *            blocks the shadow rays) over that under a clear slab must be
 *            exp(-0.5 sigma) per channel within 1e-3 (the photons take the
 *            same paths, only their power differs), and the clear slab's
 *            floor kd / pi E within 3 % (the density estimate's noise).
 *   gather   a sun on a floor under an absorbing slab 0.3 deep, a white
 *            sheet above the slab facing the floor, seen by its indirect
 *            light alone: the global photons cross the slab down to the
 *            floor, the sheet's gather rays cross it (slanted, cosine-
 *            distributed) to the floor's precomputed irradiance, so the
 *            sheet's light falls by exp(-0.3 sigma) times the cosine-
 *            weighted mean of exp(-0.3 sigma / cos) from the clear slab to
 *            the absorbing one, within 1.5 % (the two renders' photons and
 *            rays take the same paths; 32,768 gather rays). */
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "base/log.h"
#include "coordinator/job.h"
#include "image/image.h"
#include "render/render.h"
#include "scene/camera.h"
#include "scene/scene.h"

#include "check.h"
#include "render_check.h"
#include "scenes_gen.h"

static const pf_vec3 s_sigma = { 0.5f, 1.0f, 2.0f };

/* An axis-aligned box [lo, hi] of material mat, its faces' normals
 * outward (inward when flip). */
static void s_box(pf_scene_t *scene, pf_vec3 lo, pf_vec3 hi, uint32_t mat, int flip)
{
    pf_vec3 d = pf_sub(hi, lo);
    pf_vec3 ex = pf_v3(d.x, 0, 0), ey = pf_v3(0, d.y, 0), ez = pf_v3(0, 0, d.z);
    pf_vec3 o[6] = { lo, pf_v3(hi.x, lo.y, lo.z), lo, pf_v3(lo.x, hi.y, lo.z), lo, pf_v3(lo.x, lo.y, hi.z) };
    pf_vec3 a[6] = { ez, ey, ex, ez, ey, ex }, b[6] = { ey, ez, ez, ex, ex, ey };
    for (int f = 0; f < 6; f++)
        pf_test_quad(scene, o[f], flip ? b[f] : a[f], flip ? a[f] : b[f], mat);
}

/* Glass of index 1 with the medium sigma on its inside (outside when flip). */
static uint32_t s_add_clear_glass(pf_scene_t *scene, pf_vec3 sigma, int flip)
{
    pf_material_t m = pf_material_default("slab");
    m.type = PF_MAT_GLASS;
    m.kd = pf_v3s(0.0f);
    m.ks = m.kt = pf_v3s(1.0f);
    m.ior = 1.0f;
    if (flip)
        m.sigma_out = sigma;
    else
        m.sigma_in = sigma;
    return (uint32_t)pf_scene_add_material(scene, &m);
}

static void s_test_camera(int flip, int clear)
{
    const int size = 16;
    pf_scene_t *scene = pf_scene_create();
    pf_material_t m = pf_material_default("lamp");
    m.kd = pf_v3s(0.0f);
    m.le = pf_v3s(1.0f);
    pf_test_quad(scene, pf_v3(-20, -20, -4), pf_v3(40, 0, 0), pf_v3(0, 40, 0), (uint32_t)pf_scene_add_material(scene, &m));
    pf_vec3 sigma = clear ? pf_v3s(0.0f) : s_sigma;
    s_box(scene, pf_v3(-10, -10, -2.5f), pf_v3(10, 10, -1.5f), s_add_clear_glass(scene, sigma, flip), flip);
    scene->camera = (pf_camera_desc_t){ .pos = { 0, 0, 0 }, .look_at = { 0.05f, 0.03f, -1 }, .up = { 0, 1, 0 },
                                        .vfov_deg = 30.0f };
    scene->has_camera = 1;
    pf_image_t img;
    if (pf_test_render(scene, size, 64, 1000, 1000, 0, PF_TERM_EMITTED, &img)) {
        pf_camera_t cam = pf_camera_make(&scene->camera, size, size);
        double worst = 0.0;
        for (int y = 0; y < size; y++)
            for (int x = 0; x < size; x++)
                for (int k = 0; k < 3; k++) {
                    double want = 0.0; /* the mean over the pixel's square (the box filter), 8 x 8 points */
                    for (int j = 0; j < 64; j++) {
                        pf_ray_t r = pf_camera_ray(&cam, (float)x + ((float)(j % 8) + 0.5f) / 8.0f,
                                                   (float)y + ((float)(j / 8) + 0.5f) / 8.0f);
                        double len = pf_len(r.d) / fabs((double)r.d.z); /* through a slab 1 deep */
                        want += exp(-(double)pf_vget(sigma, k) * len) / 64.0;
                    }
                    double got = img.rgb[3 * ((size_t)y * size + (size_t)x) + (size_t)k];
                    worst = fmax(worst, fabs(got / want - 1.0));
                }
        printf("camera through a slab (%s%s): worst pixel off by %.3g %%\n", clear ? "clear" : "absorbing",
               flip ? ", faces inward, medium outside" : "", 100.0 * worst);
        CHECK(worst < (clear ? 1e-6 : 5e-4), "the slab's pixels are off exp(-sigma d) by up to %.3g %%", 100.0 * worst);
        pf_image_free(&img);
    }
    pf_scene_destroy(&scene);
}

/* A floor under a sun, a slab 0.5 deep as wide as the floor between them
 * (all the light reaches the floor through it), the camera under the slab
 * looking down. */
static pf_scene_t *s_floor_scene(pf_vec3 sigma)
{
    pf_scene_t *scene = pf_scene_create();
    pf_material_t m = pf_material_default("floor");
    m.kd = pf_v3s(0.5f);
    pf_test_quad(scene, pf_v3(-6, 0, -6), pf_v3(0, 0, 12), pf_v3(12, 0, 0), (uint32_t)pf_scene_add_material(scene, &m));
    s_box(scene, pf_v3(-6, 1, -6), pf_v3(6, 1.5f, 6), s_add_clear_glass(scene, sigma, 0), 0);
    pf_light_t l = { .type = PF_LIGHT_DISTANT, .dir = pf_v3(0, -1, 0), .intensity = pf_v3s(1.0f) };
    PF_CHECK(pf_scene_add_light(scene, &l) == PF_OK);
    scene->camera = (pf_camera_desc_t){ .pos = { 0, 0.9f, 0.01f }, .look_at = { 0, 0, 0 }, .up = { 0, 0, 1 },
                                        .vfov_deg = 90.0f };
    scene->has_camera = 1;
    return scene;
}

static void s_mean(const pf_image_t *img, double out[3])
{
    size_t n = (size_t)img->width * (size_t)img->height;
    out[0] = out[1] = out[2] = 0.0;
    for (size_t i = 0; i < n; i++)
        for (int k = 0; k < 3; k++)
            out[k] += img->rgb[3 * i + (size_t)k] / (double)n;
}

static void s_test_photons(void)
{
    pf_image_t a, b;
    pf_scene_t *clear = s_floor_scene(pf_v3s(0.0f)), *tinted = s_floor_scene(s_sigma);
    unsigned terms = PF_TERM_DIRECT | PF_TERM_CAUSTIC;
    int ok = pf_test_render(clear, 24, 4, 1000, 1000000, 0, terms, &a);
    ok = pf_test_render(tinted, 24, 4, 1000, 1000000, 0, terms, &b) && ok;
    if (ok) {
        double ma[3], mb[3], want_clear = 0.5 / 3.14159265358979323846;
        s_mean(&a, ma);
        s_mean(&b, mb);
        printf("floor under a clear slab %.5f (kd / pi E %.5f, off by %+.2f %%)\n", ma[1], want_clear,
               100.0 * (ma[1] / want_clear - 1.0));
        CHECK(fabs(ma[1] / want_clear - 1.0) < 0.03, "the floor under a clear slab: %.5f, kd / pi E %.5f", ma[1],
              want_clear);
        for (int k = 0; k < 3; k++) {
            double want = exp(-0.5 * (double)pf_vget(s_sigma, k)), got = mb[k] / ma[k];
            printf("channel %d: absorbing / clear %.5f, exp(-0.5 sigma) %.5f\n", k, got, want);
            CHECK(fabs(got / want - 1.0) < 1e-3, "channel %d: the floor gets %.5f of the clear slab's light, not %.5f",
                  k, got, want);
        }
        pf_image_free(&a);
        pf_image_free(&b);
    }
    pf_scene_destroy(&clear);
    pf_scene_destroy(&tinted);
}

/* The gather scene: a sun on a floor, an absorbing slab 0.3 deep between
 * y = 0.3 and 0.6 (all light crosses it down to the floor and again up),
 * a white sheet above it facing down, the camera between them looking up. */
static pf_scene_t *s_gather_scene(pf_vec3 sigma)
{
    pf_scene_t *scene = pf_scene_create();
    pf_material_t m = pf_material_default("floor");
    m.kd = pf_v3s(0.5f);
    pf_test_quad(scene, pf_v3(-6, 0, -6), pf_v3(0, 0, 12), pf_v3(12, 0, 0), (uint32_t)pf_scene_add_material(scene, &m));
    s_box(scene, pf_v3(-6, 0.3f, -6), pf_v3(6, 0.6f, 6), s_add_clear_glass(scene, sigma, 0), 0);
    m = pf_material_default("sheet"); /* small: its shadow on the floor is a few thousandths of its view */
    m.kd = pf_v3s(0.9f);
    pf_test_quad(scene, pf_v3(-0.05f, 0.9f, -0.05f), pf_v3(0.1f, 0, 0), pf_v3(0, 0, 0.1f),
                 (uint32_t)pf_scene_add_material(scene, &m)); /* normal -y */
    pf_light_t l = { .type = PF_LIGHT_DISTANT, .dir = pf_v3(0, -1, 0), .intensity = pf_v3s(1.0f) };
    PF_CHECK(pf_scene_add_light(scene, &l) == PF_OK);
    scene->camera = (pf_camera_desc_t){ .pos = { 0, 0.75f, 0.001f }, .look_at = { 0, 2, 0 }, .up = { 0, 0, 1 },
                                        .vfov_deg = 30.0f };
    scene->has_camera = 1;
    return scene;
}

static void s_test_gather(void)
{
    pf_image_t a, b;
    pf_scene_t *clear = s_gather_scene(pf_v3s(0.0f)), *tinted = s_gather_scene(s_sigma);
    int ok = pf_test_render(clear, 16, 16, 200000, 1000, 8, PF_TERM_INDIRECT, &a);
    ok = pf_test_render(tinted, 16, 16, 200000, 1000, 8, PF_TERM_INDIRECT, &b) && ok;
    if (ok) {
        double ma[3], mb[3];
        s_mean(&a, ma);
        s_mean(&b, mb);
        for (int k = 0; k < 3; k++) {
            /* the photons' vertical crossing times the gather rays' crossings, cosine-weighted
             * over the floor's cone (its edge at atan(6 / 0.9)) */
            double sg = (double)pf_vget(s_sigma, k), tmax = atan(6.0 / 0.9), num = 0.0, den = 0.0;
            for (int i = 0; i < 20000; i++) {
                double t = tmax * (i + 0.5) / 20000.0, w = cos(t) * sin(t);
                num += w * exp(-0.3 * sg / cos(t));
                den += w;
            }
            double want = exp(-0.3 * sg) * num / den, got = mb[k] / ma[k];
            printf("the sheet's indirect light, channel %d: absorbing / clear %.5f, expected %.5f (%+.2f %%)\n", k,
                   got, want, 100.0 * (got / want - 1.0));
            CHECK(ma[k] > 0.0 && fabs(got / want - 1.0) < 0.015, "channel %d: the sheet's indirect light %.5f, not %.5f",
                  k, got, want);
        }
        pf_image_free(&a);
        pf_image_free(&b);
    }
    pf_scene_destroy(&clear);
    pf_scene_destroy(&tinted);
}

int main(void)
{
    pf_log_set_level(PF_LOG_ERROR);
    s_test_camera(0, 1);
    s_test_camera(0, 0);
    s_test_camera(1, 0);
    s_test_photons();
    s_test_gather();
    return pf_test_finish();
}
