/* test_passes.c: progressive passes in one process (coordinator/job.c,
 * accum.c). The image of N passes is the spp-weighted mean of the N
 * one-pass renders with each pass's settings (its index and seed), bit for
 * bit; a pass cut short counts where it reached and nowhere else; the
 * error estimate sees the spread between passes; the planner's cost of a
 * sample from a short pass stays sane (budget.c). Runs from the source
 * directory (the scenes). */
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "base/log.h"
#include "coordinator/accum.h"
#include "coordinator/budget.h"
#include "coordinator/job.h"
#include "load/load.h"

#include "check.h"

static pf_settings_t s_settings(const pf_scene_t *scene)
{
    pf_settings_t s = scene->settings;
    s.width = 40;
    s.height = 32;
    s.spp = 3;
    s.photons = 8000;
    s.caustic_photons = 8000;
    s.threads = 2;
    return s;
}

/* --passes 3 is the mean of three one-pass renders of its passes. */
static void s_mean_of_passes(const pf_scene_t *scene)
{
    pf_settings_t s = s_settings(scene);
    pf_job_run_t run = { .passes = 3 };
    pf_image_t img3, one[3];
    pf_job_summary_t sum;
    pf_error_t err = { { 0 } };
    CHECK(pf_job_render(scene, &s, PF_TERM_ALL, &run, &img3, &sum, &err) == PF_OK, "three passes: %s", err.msg);
    CHECK(sum.passes == 3 && sum.passes_whole == 3 && sum.spp_total == 9, "summary: %d passes, %d whole, %llu spp",
          sum.passes, sum.passes_whole, (unsigned long long)sum.spp_total);
    CHECK(sum.settings.pass == 2 && sum.settings.seed == pf_pass_seed(s.seed, 2), "the summary has the last pass");
    CHECK(isfinite(sum.error_est) && sum.error_est > 0.0, "an error estimate from three passes (%g)", sum.error_est);
    for (int i = 0; i < 3; i++) {
        pf_settings_t si = s;
        si.pass = i;
        si.seed = pf_pass_seed(s.seed, i);
        CHECK(pf_job_render_local(scene, &si, PF_TERM_ALL, 0, &one[i], &sum, &err) == PF_OK, "pass %d: %s", i,
              err.msg);
    }
    size_t n = (size_t)3 * s.width * s.height, same = 0, differ01 = 0;
    for (size_t k = 0; k < n; k++) {
        double a = 3.0 * one[0].rgb[k], b = 3.0 * one[1].rgb[k], c = 3.0 * one[2].rgb[k];
        float mean = (float)((((0.0 + a) + b) + c) / 9.0);
        same += memcmp(&mean, &img3.rgb[k], sizeof mean) == 0;
        differ01 += one[0].rgb[k] != one[1].rgb[k];
    }
    CHECK(same == n, "the three-pass image is the mean of its passes, bit for bit (%zu of %zu channels)", same, n);
    CHECK(differ01 > n / 2, "the passes are independent renders (%zu of %zu channels differ)", differ01, n);
    pf_image_free(&img3);
    for (int i = 0; i < 3; i++)
        pf_image_free(&one[i]);
}

/* The accumulator alone: weights, a cut pass, the error estimate. */
static void s_accum(void)
{
    pf_accum_t a;
    CHECK(pf_accum_init(&a, 4, 2) == PF_OK, "init");
    float p1[24], p2[24];
    for (int k = 0; k < 24; k++) {
        p1[k] = 1.0f;
        p2[k] = 4.0f;
    }
    pf_accum_add(&a, 0, 0, 4, 2, p1, 12, 1);
    CHECK(isnan(pf_accum_error(&a)), "no error estimate from one pass");
    /* The second pass, with 3 samples per pixel, reached the left half only. */
    pf_accum_add(&a, 0, 0, 2, 2, p2, 12, 3);
    pf_image_t img;
    CHECK(pf_image_alloc(&img, 4, 2) == PF_OK, "alloc");
    CHECK(pf_accum_resolve(&a, &img) == 0, "every pixel reached");
    CHECK(img.rgb[0] == 3.25f && img.rgb[3 * 5] == 3.25f, "left: (1 x 1 + 3 x 4) / 4 = 3.25 (%g)", (double)img.rgb[0]);
    CHECK(img.rgb[3 * 2] == 1.0f && img.rgb[3 * 7 + 2] == 1.0f, "right: the first pass alone (%g)", (double)img.rgb[6]);
    double e = pf_accum_error(&a);
    /* Left pixels: weights 1 and 3 at 1 and 4, mean 3.25: sum w (x - m)^2 =
     * 5.0625 + 1.6875 = 6.75 over (2 - 1) and W = 4: 1.6875; over 3.25^2 + 0.01. */
    double want = 6.75 / 4.0 / (3.25 * 3.25 + 0.01);
    CHECK(fabs(e - want) < 1e-9, "error estimate %g, want %g (the two-pass pixels only)", e, want);
    pf_image_free(&img);
    pf_accum_free(&a);
    CHECK(pf_accum_init(&a, 3, 1) == PF_OK, "init");
    pf_accum_add(&a, 0, 0, 2, 1, p1, 6, 2);
    CHECK(pf_image_alloc(&img, 3, 1) == PF_OK, "alloc");
    CHECK(pf_accum_resolve(&a, &img) == 1 && img.rgb[6] == 0.0f, "a pixel no pass reached is black and counted");
    pf_image_free(&img);
    pf_accum_free(&a);
}

/* The cost of a sample measured from a pass: the time beyond the probe's
 * fixed part per sample, but never less than half the pass's time per
 * sample (a pass of 2 spp that took 0.45 s beside a fixed part of 0.42 s
 * would otherwise say 0.015 s a sample and plan the next pass 7 times too
 * long). */
static void s_pass_cost(void)
{
    pf_budget_t b;
    memset(&b, 0, sizeof b);
    b.pass_fixed_s = 0.42;
    pf_budget_pass_done(&b, 2, 0.45);
    CHECK(fabs(b.pass_spp_s - 0.1125) < 1e-12, "short pass: %g s a sample (0.1125)", b.pass_spp_s);
    pf_budget_pass_done(&b, 20, 4.42);
    CHECK(fabs(b.pass_spp_s - 0.2) < 1e-12, "long pass: %g s a sample (0.2)", b.pass_spp_s);
    pf_budget_pass_done(&b, 0, 1.0);
    CHECK(fabs(b.pass_spp_s - 0.2) < 1e-12, "no samples: unchanged (%g)", b.pass_spp_s);
}

int main(void)
{
    pf_log_set_level(PF_LOG_WARN);
    s_accum();
    s_pass_cost();
    pf_error_t err = { { 0 } };
    pf_scene_t *scene = pf_scene_load("scenes/cornell-spheres/scene.json", &err);
    CHECK(scene != NULL, "load: %s", err.msg);
    if (scene)
        s_mean_of_passes(scene);
    pf_scene_destroy(&scene);
    return pf_test_finish();
}
