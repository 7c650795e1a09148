/* test_phong.c: the Phong lobe's direct light by multiple importance
 * sampling (render/direct.c, the glossy row of render/render.c): light
 * samples of the lobe weighed against the lobe's own recursive ray, which
 * counts the emitter or sky it meets with the complementary weight.
 * In-process renders (ctest `render_phong`).
 *
 *   furnace   a plane (kd 0.3, ks 0.7, ns 50) under a constant sky of
 *             radiance 1, seen straight down: the normalized Phong lobe's
 *             albedo at normal incidence is exactly 1, so every pixel's
 *             expectation is 0.3 + 0.7 = 1. The mean must be 1 within
 *             0.5 % (about 10 standard errors), and the pixels' spread
 *             small: with light samples alone (no MIS) a lobe of ns 50
 *             under a cosine-sampled sky has a spread of 0.22 at 64 spp,
 *             with MIS 0.024.
 *   lamp      a sharp lobe (ns 3000) reflecting a 2 x 2 area light: two
 *             seeds agree on the mean within 2 %, and their pixel-wise
 *             difference (the noise) is small against the mean: light
 *             samples alone give a relative noise variance of 2.5 to 5.6
 *             (fireflies up to 6 in a mean of 0.18), MIS about 0.01.
 */
#include <math.h>
#include <stdio.h>

#include "coordinator/job.h"
#include "image/image.h"
#include "render/render.h"
#include "scene/scene.h"

#include "check.h"
#include "scenes_gen.h"

static uint32_t s_material(pf_scene_t *sc, float kd, float ks, float ns, float le)
{
    pf_material_t m = pf_material_default("m");
    snprintf(m.name, sizeof m.name, "m%zu", sc->nmats);
    m.kd = pf_v3s(kd);
    m.ks = pf_v3s(ks);
    m.ns = ns;
    m.le = pf_v3s(le);
    int i = pf_scene_add_material(sc, &m);
    PF_CHECK(i >= 0);
    return (uint32_t)i;
}

static pf_scene_t *s_finish(pf_scene_t *sc)
{
    sc->has_camera = 1;
    pf_error_t err = { { 0 } };
    int rc = pf_scene_finalize(sc, &err);
    CHECK(rc == PF_OK, "finalize: %s", err.msg);
    if (rc != PF_OK)
        pf_scene_destroy(&sc);
    return sc;
}

static int s_render(const pf_scene_t *sc, int size, int spp, unsigned terms, uint64_t seed, pf_image_t *img)
{
    pf_settings_t s = sc->settings;
    s.width = s.height = size;
    s.spp = spp;
    s.photons = 100000;
    s.caustic_photons = 1000;
    s.threads = 0;
    s.seed = seed;
    pf_job_summary_t sum;
    pf_error_t err = { { 0 } };
    int rc = pf_job_render_local(sc, &s, terms, 0, img, &sum, &err);
    CHECK(rc == PF_OK, "render: %s", err.msg);
    return rc == PF_OK;
}

/* The mean and standard deviation of the pixels' first channel. */
static void s_stats(const pf_image_t *img, double *mean, double *sd)
{
    size_t n = (size_t)img->width * img->height;
    double m = 0.0, v = 0.0;
    for (size_t i = 0; i < n; i++)
        m += img->rgb[3 * i] / (double)n;
    for (size_t i = 0; i < n; i++)
        v += (img->rgb[3 * i] - m) * (img->rgb[3 * i] - m) / (double)(n - 1);
    *mean = m;
    *sd = sqrt(v);
}

static void s_test_furnace(void)
{
    pf_scene_t *sc = pf_scene_create();
    pf_test_quad(sc, pf_v3(-50, 0, -50), pf_v3(0, 0, 100), pf_v3(100, 0, 0), s_material(sc, 0.3f, 0.7f, 50.0f, 0.0f));
    pf_light_t sky = { .type = PF_LIGHT_INFINITE, .intensity = { 1, 1, 1 } };
    pf_scene_add_light(sc, &sky);
    sc->camera = (pf_camera_desc_t){ .pos = { 0, 10, 0 }, .look_at = { 0, 0, 0 }, .up = { 0, 0, -1 },
                                     .vfov_deg = 2.0f };
    if (!(sc = s_finish(sc)))
        return;
    pf_image_t img;
    if (s_render(sc, 32, 64, PF_TERM_ALL, 1, &img)) {
        double m, sd;
        s_stats(&img, &m, &sd);
        printf("furnace: mean %.5f (expected 1), pixel spread %.4f (light samples alone: 0.22)\n", m, sd);
        CHECK(fabs(m - 1.0) < 0.005, "Phong under a constant sky: mean %.5f, expected 1", m);
        CHECK(sd < 0.06, "Phong under a constant sky: pixel spread %.4f, MIS gives about 0.024", sd);
        pf_image_free(&img);
    }
    pf_scene_destroy(&sc);
}

static void s_test_lamp(void)
{
    pf_scene_t *sc = pf_scene_create();
    pf_test_quad(sc, pf_v3(-3, 0, -3), pf_v3(0, 0, 6), pf_v3(6, 0, 0), s_material(sc, 0.2f, 0.6f, 3000.0f, 0.0f));
    /* facing down (edge1 x edge2 = -y) */
    pf_test_quad(sc, pf_v3(-1, 1.5f, -3), pf_v3(2, 0, 0), pf_v3(0, 0, 2), s_material(sc, 0.0f, 0.0f, 1.0f, 5.0f));
    sc->camera = (pf_camera_desc_t){ .pos = { 0, 2, 4 }, .look_at = { 0, 0, 0 }, .up = { 0, 1, 0 },
                                     .vfov_deg = 40.0f };
    if (!(sc = s_finish(sc)))
        return;
    pf_image_t a, b;
    if (s_render(sc, 48, 32, PF_TERM_DIRECT, 1, &a)) {
        if (s_render(sc, 48, 32, PF_TERM_DIRECT, 2, &b)) {
            double ma, mb, sd, var = 0.0, peak = 0.0;
            s_stats(&a, &ma, &sd);
            s_stats(&b, &mb, &sd);
            size_t n = (size_t)a.width * a.height;
            for (size_t i = 0; i < n; i++) {
                double d = a.rgb[3 * i] - b.rgb[3 * i];
                var += d * d / (2.0 * (double)n);
                peak = fmax(peak, fmax(a.rgb[3 * i], b.rgb[3 * i]));
            }
            double rel = var / (0.25 * (ma + mb) * (ma + mb));
            printf("lamp: means %.5f and %.5f, relative noise variance %.4f (light samples alone: 2.5 to 5.6), "
                   "brightest pixel %.3f\n",
                   ma, mb, rel, peak);
            CHECK(ma > 0.05 && fabs(ma / mb - 1.0) < 0.02, "lamp in a sharp lobe: means %.5f and %.5f", ma, mb);
            CHECK(rel < 0.05, "lamp in a sharp lobe: relative noise variance %.4f, MIS gives about 0.01", rel);
            pf_image_free(&b);
        }
        pf_image_free(&a);
    }
    pf_scene_destroy(&sc);
}

int main(void)
{
    s_test_furnace();
    s_test_lamp();
    return pf_test_finish();
}
