/* stress_depth.c: the path-length limit (settings.path_max_depth, pbrt's
 * Integrator "maxdepth"; group "depth"). In the furnace (a closed sphere of
 * albedo a emitting Le everywhere, camera inside) a path with k scattering
 * events brings Le a^k, so with the limit D the radiance is
 * Le (1 + a + ... + a^D) everywhere: each D checks the photons' bounce counts
 * (the direct light covers k = 1, the final gather's precomputed irradiance
 * k = 2..D). Called from the test's main thread. */
#include <math.h>
#include <stdio.h>

#include "render/render.h"

#include "scenes_gen.h"
#include "stress.h"

/* The furnace (radius R) seen in a lossless mirror sphere (radius r, at the
 * centre) that fills the view. The mirror is one of the path's events, and
 * it hides the fraction f = (r / R)^2 of every wall point's cosine-weighted
 * hemisphere, whose light then takes an event more. The wall's radiance
 * W(n), n events left for it and what lies beyond, is the same everywhere:
 * W(0) = Le, W(n) = Le + a ((1 - f) W(n-1) + f W(n-2)) (W(-1) = 0: the
 * mirror's own reflection takes the event), and each pixel reads W(D - 1);
 * without a limit Le / (1 - a). Every estimate here is a step deeper than the
 * plain furnace's: the caustic map (photons off the mirror), the final
 * gather from the camera's second vertex (estimated from the global map
 * with the deeper limit, not read from the precomputed irradiance) and the
 * filtered first gather through the mirror. */
static void s_mirror(void)
{
    const float a = 0.7f, le = 1.0f;
    static const int depths[] = { 1, 2, 3, 5, 0 };
    pf_scene_t *scene = pf_scene_create();
    uint32_t wall = stress_material(scene, stress_diffuse("furnace", a, le));
    pf_material_t mirror = pf_material_default("mirror");
    mirror.type = PF_MAT_MIRROR;
    mirror.kd = pf_v3s(0.0f);
    mirror.ks = pf_v3s(1.0f);
    uint32_t mat = stress_material(scene, mirror);
    pf_test_inward_sphere(scene, 4, 1.0f, wall);
    stress_sphere(scene, pf_v3(0, 0, 0), 0.4f, mat);
    /* 0.7 from the centre the sphere spans 34.8 degrees each way: a 30
     * degree view sees nothing else */
    stress_camera(scene, pf_v3(0.7f, 0, 0), pf_v3(0, 0, 0), pf_v3(0, 1, 0), 30.0f);
    pf_error_t err = { { 0 } };
    CHECK(pf_scene_finalize(scene, &err) == PF_OK, "finalize: %s", err.msg);
    for (size_t i = 0; i < sizeof depths / sizeof *depths; i++) {
        int d = depths[i];
        pf_settings_t s = stress_settings(scene, 24, 4, 40000, 16);
        s.caustic_photons = 20000;
        s.irradiance_stride = 4;
        s.path_max_depth = d;
        const double f = 0.4 * 0.4;
        double w_prev = 0.0, w = le; /* W(-1), W(0) */
        for (int n = 1, last = d == 0 ? 1000 : d - 1; n <= last; n++) {
            double next = le + a * ((1.0 - f) * w + f * w_prev);
            w_prev = w;
            w = next;
        }
        double expect = w;
        char what[64];
        snprintf(what, sizeof what, "mirror in the furnace, path_max_depth %d", d);
        pf_image_t img;
        stress_job_t job;
        if (stress_job_begin(&job, what, scene, &s) != PF_OK)
            continue;
        stress_job_render(&job, what, PF_TERM_ALL, &img);
        double mean = stress_mean(&img);
        printf("%s: mean %.5f expected %.5f (ratio %.4f, bound 1 +- 0.02)\n", what, mean, expect, mean / expect);
        CHECK(fabs(mean / expect - 1.0) < 0.02, "%s: mean radiance %.5f, expected %.5f within 2%%", what, mean,
              expect);
        pf_image_free(&img);
        stress_job_end(&job);
    }
    pf_scene_destroy(&scene);
}

void stress_test_depth(void)
{
    const float a = 0.7f, le = 1.0f;
    /* 0: no limit; -1: emitted light only (pbrt's maxdepth 0) */
    static const int depths[] = { -1, 1, 2, 3, 5, 0 };
    pf_scene_t *scene = pf_scene_create();
    uint32_t mat = stress_material(scene, stress_diffuse("furnace", a, le));
    pf_test_inward_sphere(scene, 4, 1.0f, mat);
    stress_camera(scene, pf_v3(0.1f, 0.05f, 0), pf_v3(1, 0.3f, 0.2f), pf_v3(0, 1, 0), 90.0f);
    pf_error_t err = { { 0 } };
    CHECK(pf_scene_finalize(scene, &err) == PF_OK, "finalize: %s", err.msg);
    for (size_t i = 0; i < sizeof depths / sizeof *depths; i++) {
        int d = depths[i];
        pf_settings_t s = stress_settings(scene, 24, 1, 40000, 32);
        s.irradiance_stride = 4;
        s.path_max_depth = d;
        double expect = 0.0;
        for (int k = 0, n = d == 0 ? 1000 : d < 0 ? 0 : d; k <= n; k++)
            expect += le * pow(a, k);
        char what[64];
        snprintf(what, sizeof what, "furnace a=%.2f path_max_depth %d", a, d);
        pf_image_t img;
        stress_job_t job;
        if (stress_job_begin(&job, what, scene, &s) != PF_OK)
            continue;
        stress_job_render(&job, what, PF_TERM_ALL, &img);
        double mean = stress_mean(&img);
        printf("%s: mean %.5f expected %.5f (ratio %.4f, bound 1 +- 0.02)\n", what, mean, expect, mean / expect);
        CHECK(fabs(mean / expect - 1.0) < 0.02, "%s: mean radiance %.5f, expected %.5f within 2%%", what, mean,
              expect);
        pf_image_free(&img);
        stress_job_end(&job);
    }
    pf_scene_destroy(&scene);
    s_mirror();
}
