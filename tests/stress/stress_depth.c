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
}
