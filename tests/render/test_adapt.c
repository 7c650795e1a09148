/* test_adapt.c: adaptive progressive passes (coordinator/adapt.c, the
 * per-pixel samples of render.c). The allocation keeps the pass's total and
 * its floor, puts more samples where the passes disagree more (or, after
 * one pass, where a pixel stands out from its neighbours), and is a
 * function of the data alone; a tile rendered with a map gives each pixel
 * exactly what a uniform render with its count gives it; an adaptive render
 * of the furnace (radiance Le / (1 - a) everywhere) stays on the answer, as
 * close as the uniform passes, and is the same bits for any thread count.
 * Runs from the source directory. */
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "base/log.h"
#include "coordinator/accum.h"
#include "coordinator/adapt.h"
#include "coordinator/job.h"
#include "render/frame.h"
#include "render/render.h"

#include "check.h"
#include "scenes_gen.h"

/* A deterministic value in [-1, 1) from an integer. */
static double s_hash(uint32_t x)
{
    x ^= x >> 16;
    x *= 0x7feb352du;
    x ^= x >> 15;
    x *= 0x846ca68bu;
    x ^= x >> 16;
    return (double)x / 2147483648.0 - 1.0;
}

/* Adds `passes` passes of a grey image of 1 +- noise, the noise 10 times
 * larger in the block [bx, bx + 8) x [by, by + 8). */
static void s_fill(pf_accum_t *a, int passes, int bx, int by, uint32_t spp)
{
    float *px = malloc(3 * sizeof *px * (size_t)a->width * (size_t)a->height);
    for (int k = 0; k < passes; k++) {
        for (int y = 0; y < a->height; y++)
            for (int x = 0; x < a->width; x++) {
                int hot = x >= bx && x < bx + 8 && y >= by && y < by + 8;
                double v = 1.0 + (hot ? 0.5 : 0.05) * s_hash((uint32_t)((k * 997 + y) * 4099 + x));
                for (int c = 0; c < 3; c++)
                    px[3 * ((size_t)y * (size_t)a->width + (size_t)x) + c] = (float)v;
            }
        pf_accum_add(a, 0, 0, a->width, a->height, px, 3 * (size_t)a->width, spp);
    }
    free(px);
}

/* Mean count inside and outside the block at (bx, by), 8 x 8. */
static void s_block_means(const uint16_t *n, int W, int H, int bx, int by, double *in, double *out)
{
    double si = 0, so = 0;
    int ni = 0, no = 0;
    for (int y = 0; y < H; y++)
        for (int x = 0; x < W; x++) {
            int hot = x >= bx && x < bx + 8 && y >= by && y < by + 8;
            if (hot)
                si += n[y * W + x], ni++;
            else
                so += n[y * W + x], no++;
        }
    *in = si / ni;
    *out = so / no;
}

static void s_allocation(void)
{
    enum { W = 64, H = 48, SPP = 8 };
    pf_accum_t a;
    CHECK(pf_accum_init(&a, W, H) == PF_OK);
    uint16_t n1[W * H], n2[W * H];
    /* no pass yet: uniform */
    CHECK(pf_adapt_counts(&a, SPP, n1) == PF_OK);
    int uniform = 1;
    for (int p = 0; p < W * H; p++)
        uniform &= n1[p] == SPP;
    CHECK(uniform, "no estimate: every pixel takes spp");
    for (int passes = 1; passes <= 3; passes += 2) {
        pf_accum_free(&a);
        CHECK(pf_accum_init(&a, W, H) == PF_OK);
        s_fill(&a, passes, 40, 16, SPP);
        CHECK(pf_adapt_counts(&a, SPP, n1) == PF_OK);
        CHECK(pf_adapt_counts(&a, SPP, n2) == PF_OK);
        CHECK(memcmp(n1, n2, sizeof n1) == 0, "%d passes: the same data, the same counts", passes);
        uint64_t total = 0;
        int lo = 1 << 20;
        for (int p = 0; p < W * H; p++) {
            total += n1[p];
            lo = n1[p] < lo ? n1[p] : lo;
        }
        double in, out;
        s_block_means(n1, W, H, 40, 16, &in, &out);
        printf("%d pass%s: total %llu (uniform %d), least %d (floor %d), mean count %.2f in the noisy block, "
               "%.2f elsewhere\n", passes, passes > 1 ? "es" : "", (unsigned long long)total, W * H * SPP, lo,
               (SPP + 1) / 2, in, out);
        CHECK(total == (uint64_t)W * H * SPP, "%d passes: the pass's total is kept (%llu)", passes,
              (unsigned long long)total);
        CHECK(lo >= (SPP + 1) / 2, "%d passes: the floor holds (least %d)", passes, lo);
        CHECK(in > 3.0 * out, "%d passes: the noisy block gets more (%.2f against %.2f)", passes, in, out);
    }
    /* one firefly after one pass: its neighbourhood gets the samples */
    pf_accum_free(&a);
    CHECK(pf_accum_init(&a, W, H) == PF_OK);
    float *px = calloc(3 * (size_t)W * H, sizeof *px);
    for (int p = 0; p < 3 * W * H; p++)
        px[p] = 0.5f;
    px[3 * (10 * W + 20)] = px[3 * (10 * W + 20) + 1] = px[3 * (10 * W + 20) + 2] = 50.0f;
    pf_accum_add(&a, 0, 0, W, H, px, 3 * (size_t)W, SPP);
    CHECK(pf_adapt_counts(&a, SPP, n1) == PF_OK);
    CHECK(n1[10 * W + 22] > 2 * SPP && n1[12 * W + 18] > 2 * SPP && n1[40 * W + 60] < SPP,
          "a firefly's neighbours get more (%d, %d), far away less (%d)", n1[10 * W + 22], n1[12 * W + 18],
          n1[40 * W + 60]);
    free(px);
    pf_accum_free(&a);
}

/* A furnace: radiance le / (1 - albedo) everywhere. */
static pf_scene_t *s_furnace(float albedo, float le)
{
    pf_scene_t *scene = pf_scene_create();
    pf_material_t m = pf_material_default("furnace");
    m.kd = pf_v3s(albedo);
    m.le = pf_v3s(le);
    int mat = pf_scene_add_material(scene, &m);
    PF_CHECK(mat >= 0);
    pf_test_inward_sphere(scene, 3, 1.0f, (uint32_t)mat);
    scene->camera = (pf_camera_desc_t){ .pos = pf_v3(0.1f, 0.05f, 0), .look_at = pf_v3(1, 0.3f, 0.2f),
                                        .up = pf_v3(0, 1, 0), .vfov_deg = 90.0f };
    scene->has_camera = 1;
    pf_error_t err = { { 0 } };
    CHECK(pf_scene_finalize(scene, &err) == PF_OK, "finalize: %s", err.msg);
    return scene;
}

/* Each pixel of a tile rendered with a map is the pixel of a uniform
 * render at its count, bit for bit (no first-gather filter, whose
 * neighbourhood would mix counts). */
static void s_map_reaches_tiles(const pf_scene_t *scene)
{
    enum { S = 16 };
    pf_settings_t s = scene->settings;
    s.width = s.height = S;
    s.photons = 5000;
    s.caustic_photons = 0;
    s.gather = 2;
    s.gather_filter = 0;
    s.threads = 1;
    pf_frame_t fr;
    pf_error_t err = { { 0 } };
    if (pf_frame_open(&fr, scene, &err) != PF_OK) {
        CHECK(0, "frame: %s", err.msg);
        return;
    }
    pf_photon_stats_t st;
    CHECK(pf_photon_pass(fr.scene, fr.accel, fr.lights, &s, &fr.maps, &st) == PF_OK);
    pf_frame_ready(&fr);
    uint16_t counts[S * S];
    for (int p = 0; p < S * S; p++)
        counts[p] = (uint16_t)((p * 7) % 3 == 0 ? 2 : (p % 5 == 0 ? 9 : 4));
    pf_spp_map_t map = { 0, 0, S, S, counts };
    float adapt[S * S * 3], uni[3][S * S * 3];
    pf_render_ctx_t ctx;
    pf_render_ctx_init(&ctx, &fr, &s);
    ctx.spp_map = &map;
    pf_render_tile(&ctx, 0, 0, S, S, adapt);
    const int spps[3] = { 2, 4, 9 };
    for (int k = 0; k < 3; k++) {
        pf_settings_t sk = s;
        sk.spp = spps[k];
        pf_render_ctx_init(&ctx, &fr, &sk);
        pf_render_tile(&ctx, 0, 0, S, S, uni[k]);
    }
    int same = 0;
    for (int p = 0; p < S * S; p++) {
        int k = counts[p] == 2 ? 0 : counts[p] == 4 ? 1 : 2;
        same += memcmp(&adapt[3 * p], &uni[k][3 * p], 3 * sizeof(float)) == 0;
    }
    CHECK(same == S * S, "each pixel is its count's uniform render (%d of %d)", same, S * S);
    pf_frame_close(&fr);
}

static double s_mean(const pf_image_t *img)
{
    double sum = 0.0;
    size_t n = (size_t)img->width * (size_t)img->height * 3;
    for (size_t k = 0; k < n; k++)
        sum += img->rgb[k];
    return sum / (double)n;
}

/* The furnace in adaptive passes: the mean stays on the answer. */
static void s_furnace_unbiased(const pf_scene_t *scene)
{
    const double expect = 1.0 / (1.0 - 0.5);
    pf_settings_t s = scene->settings;
    s.width = s.height = 32;
    s.spp = 4;
    s.photons = 20000;
    s.caustic_photons = 0;
    s.gather = 8;
    s.threads = 2;
    pf_job_summary_t sum;
    pf_error_t err = { { 0 } };
    pf_image_t ad, ad1, uni;
    pf_job_run_t run = { .passes = 6, .adaptive = 1 };
    CHECK(pf_job_render(scene, &s, PF_TERM_ALL, &run, &ad, &sum, &err) == PF_OK, "adaptive: %s", err.msg);
    double e_ad = sum.error_est;
    s.threads = 1;
    CHECK(pf_job_render(scene, &s, PF_TERM_ALL, &run, &ad1, &sum, &err) == PF_OK, "adaptive, 1 thread: %s", err.msg);
    run.adaptive = 0;
    CHECK(pf_job_render(scene, &s, PF_TERM_ALL, &run, &uni, &sum, &err) == PF_OK, "uniform: %s", err.msg);
    size_t bytes = (size_t)s.width * s.height * 3 * sizeof(float);
    CHECK(memcmp(ad.rgb, ad1.rgb, bytes) == 0, "adaptive passes: the same bits on 1 and 2 threads");
    CHECK(memcmp(ad.rgb, uni.rgb, bytes) != 0, "adaptive passes change the image");
    double m_ad = s_mean(&ad), m_uni = s_mean(&uni);
    printf("furnace, 6 passes: adaptive mean %.5f (est. relMSE %.3g), uniform %.5f (%.3g), expected %.5f\n", m_ad,
           e_ad, m_uni, sum.error_est, expect);
    CHECK(fabs(m_ad / expect - 1.0) < 0.01, "adaptive: mean %.5f, expected %.5f within 1 %%", m_ad, expect);
    CHECK(fabs(m_ad / m_uni - 1.0) < 0.002, "adaptive: mean %.5f, uniform passes' %.5f within 0.2 %%", m_ad, m_uni);
    pf_image_free(&ad);
    pf_image_free(&ad1);
    pf_image_free(&uni);
}

int main(void)
{
    pf_log_set_level(PF_LOG_WARN);
    s_allocation();
    pf_scene_t *scene = s_furnace(0.5f, 1.0f);
    s_map_reaches_tiles(scene);
    s_furnace_unbiased(scene);
    pf_scene_destroy(&scene);
    return pf_test_finish();
}
