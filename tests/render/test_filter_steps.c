/* test_filter_steps.c: the first-gather filter (settings.gather_filter)
 * must not share gathers across the steps of a staircase whose step height
 * is below a pixel's footprint (issue 18: stairs and shelves seen from far
 * or at grazing angles).
 *
 * The staircase rises along +x: treads S_DEPTH wide and S_LONG long (z),
 * each ending at its riser (S_RISE high, facing it); the risers alternate
 * white (0.9) and dark (0.1), lit by a spot light low on the -x side. A
 * tread's indirect light comes almost all from its own riser (it cannot see
 * the risers above it): a tread before a white riser gets 7-10 times the
 * indirect light of one before a dark riser. The camera, far away (40) and
 * 15 degrees up, looks along -z: the risers are edge-on, each tread is a
 * band about 10 pixels wide, and a pixel's footprint on a tread (0.1 across,
 * 0.39 along z) exceeds the step (0.3), so the filter's plane test (normals
 * agree, within a pixel width of the tangent plane) alone took neighbouring
 * treads for one surface.
 *
 * Checked: per tread (the pixels whose centre sees it), the mean indirect
 * term with gather_filter 2 against gather_filter 0 (no filter: unbiased),
 * same seed (the first gathers are the same rays), within 20 %. Without the
 * step guard (filter.c) the dark treads came out 1.74, 2.76 and 4.36 times
 * their unfiltered mean (the white treads' gathers leaked in), the white
 * ones 0.84-0.92; with it 0.87-1.03. What remains is the filter's blur of
 * the steep rise of each tread's light towards its riser (over about 3
 * pixels; the window is 5): tread 1 stays at 0.87-0.89 with other seeds and
 * with 64 samples per pixel, so it is no noise. Also checked: the filter
 * still shares on each tread (the noise between vertically adjacent pixels
 * of a tread drops to 0.16 of the unfiltered one; bound 0.3), and the scene
 * keeps its contrast. About 1 s on 2 cores. */
#include <math.h>
#include <stdio.h>
#include <stdlib.h>

#include "accel/accel.h"
#include "base/log.h"
#include "coordinator/job.h"
#include "render/render.h"
#include "scene/camera.h"
#include "scene/scene.h"

#include "check.h"
#include "scenes_gen.h"

enum { S_STEPS = 6, S_W = 48, S_H = 24 };
#define S_RISE 0.30f  /* step height: below a pixel's footprint on a tread (0.39) */
#define S_DEPTH 1.0f  /* tread width (x): 10 pixels */
#define S_LONG 20.0f  /* tread length (z) */
#define S_ELEV 0.2618f /* the camera's elevation: 15 degrees */

static pf_scene_t *s_stairs(void)
{
    pf_scene_t *scene = pf_scene_create();
    pf_material_t tread = pf_material_default("tread"), white = pf_material_default("white"),
                  dark = pf_material_default("dark");
    tread.kd = pf_v3s(0.7f);
    white.kd = pf_v3s(0.9f);
    dark.kd = pf_v3s(0.1f);
    uint32_t mt = (uint32_t)pf_scene_add_material(scene, &tread);
    uint32_t mw = (uint32_t)pf_scene_add_material(scene, &white);
    uint32_t md = (uint32_t)pf_scene_add_material(scene, &dark);
    for (int i = 0; i < S_STEPS; i++) {
        float x = (float)i * S_DEPTH, y = (float)i * S_RISE;
        /* tread i (normal +y), then its riser at its +x end, facing it (normal -x) */
        pf_test_quad(scene, pf_v3(x, y, S_LONG / 2), pf_v3(S_DEPTH, 0, 0), pf_v3(0, 0, -S_LONG), mt);
        pf_test_quad(scene, pf_v3(x + S_DEPTH, y, -S_LONG / 2), pf_v3(0, 0, S_LONG), pf_v3(0, S_RISE, 0),
                     i % 2 ? md : mw);
    }
    pf_vec3 c = pf_v3(S_STEPS * S_DEPTH / 2, S_STEPS * S_RISE / 2, 0);
    pf_light_t l = { 0 };
    l.type = PF_LIGHT_SPOT;
    l.pos = pf_add(c, pf_v3(-8.0f, 5.0f, 0.0f)); /* low on the -x side: the risers face it */
    l.dir = pf_norm(pf_sub(c, l.pos));
    l.cos_inner = cosf(0.70f); /* 40 degrees */
    l.cos_outer = cosf(0.79f); /* 45 degrees */
    l.intensity = pf_v3s(200.0f);
    PF_CHECK(pf_scene_add_light(scene, &l) == PF_OK);
    /* far away (40), narrow: a pixel is 0.1 wide, 0.1 / sin(15 deg) = 0.39 deep on a tread */
    float dist = 40.0f;
    pf_vec3 eye = pf_add(c, pf_v3(0, dist * sinf(S_ELEV), dist * cosf(S_ELEV)));
    float vfov = 2.0f * atanf(0.5f * S_H * 0.1f / dist) * 57.29578f;
    scene->camera = (pf_camera_desc_t){ .pos = eye, .look_at = c, .up = { 0, 1, 0 }, .vfov_deg = vfov };
    scene->has_camera = 1;
    pf_error_t err;
    PF_CHECK(pf_scene_finalize(scene, &err) == PF_OK);
    return scene;
}

/* The tread each pixel's centre sees (0 .. S_STEPS - 1), or -1. */
static void s_classify(const pf_scene_t *scene, int *tread)
{
    pf_error_t err;
    pf_accel_t *accel = pf_accel_create(scene, &err);
    PF_CHECK(accel != NULL);
    pf_camera_t cam = pf_camera_make(&scene->camera, S_W, S_H);
    for (int y = 0; y < S_H; y++)
        for (int x = 0; x < S_W; x++) {
            pf_ray_t r = pf_camera_ray(&cam, (float)x + 0.5f, (float)y + 0.5f);
            pf_hit_t h;
            int t = -1;
            if (pf_accel_intersect(accel, &r, INFINITY, &h) && fabsf(h.ng.y) > 0.99f)
                t = (int)lroundf(h.p.y / S_RISE);
            tread[y * S_W + x] = t;
        }
    pf_accel_destroy(&accel);
}

/* Per tread: the mean indirect term (over channels and its pixels). And in
 * *noise, the mean squared difference between vertically adjacent pixels of
 * one tread (the light changes little along a tread: mostly noise). */
static void s_tread_means(const pf_scene_t *scene, const pf_settings_t *s, const int *tread, double *mean,
                          double *noise)
{
    pf_image_t img;
    pf_job_summary_t sum;
    pf_error_t err = { { 0 } };
    int rc = pf_job_render_local(scene, s, PF_TERM_INDIRECT, 0, &img, &sum, &err);
    PF_CHECK(rc == PF_OK);
    int n[S_STEPS] = { 0 }, pairs = 0;
    for (int t = 0; t < S_STEPS; t++)
        mean[t] = 0.0;
    *noise = 0.0;
    for (int i = 0; i < S_W * S_H; i++)
        if (tread[i] >= 0 && tread[i] < S_STEPS) {
            const float *p = &img.rgb[3 * (size_t)i];
            mean[tread[i]] += ((double)p[0] + p[1] + p[2]) / 3.0;
            n[tread[i]]++;
            if (i + S_W < S_W * S_H && tread[i + S_W] == tread[i]) {
                double d = (double)p[0] - (double)p[3 * S_W];
                *noise += d * d;
                pairs++;
            }
        }
    for (int t = 0; t < S_STEPS; t++) {
        CHECK(n[t] >= 2 * S_H, "tread %d covers only %d pixels", t, n[t]);
        mean[t] /= n[t] > 0 ? n[t] : 1;
    }
    *noise /= pairs > 0 ? pairs : 1;
    pf_image_free(&img);
}

int main(void)
{
    pf_log_set_level(PF_LOG_WARN);
    pf_scene_t *scene = s_stairs();
    int *tread = malloc(S_W * S_H * sizeof *tread);
    PF_CHECK(tread != NULL);
    s_classify(scene, tread);
    pf_settings_t s = scene->settings;
    s.width = S_W;
    s.height = S_H;
    s.spp = 16;
    s.gather = 16;
    s.photons = 200000;
    s.caustic_photons = 0;
    s.threads = 2;
    double m0[S_STEPS], m2[S_STEPS], noise0, noise2;
    s.gather_filter = 0;
    s_tread_means(scene, &s, tread, m0, &noise0);
    s.gather_filter = 2;
    s_tread_means(scene, &s, tread, m2, &noise2);
    for (int t = 0; t < S_STEPS; t++) {
        double ratio = m0[t] > 0.0 ? m2[t] / m0[t] : INFINITY;
        printf("tread %d (%s riser): indirect %.5f unfiltered, %.5f filtered (ratio %.3f)\n", t,
               t % 2 ? "dark" : "white", m0[t], m2[t], ratio);
        CHECK(fabs(ratio - 1.0) < 0.2, "tread %d: the filter moved its indirect light by %+.3f (bound 0.2)", t,
              ratio - 1.0);
    }
    /* the guard must not stop the sharing on each tread: its noise drops */
    printf("noise (adjacent pixels on a tread): %.3g unfiltered, %.3g filtered (ratio %.3f)\n", noise0, noise2,
           noise2 / noise0);
    CHECK(noise2 < 0.3 * noise0, "the filter left %.3f of the noise on the treads (bound 0.3)", noise2 / noise0);
    /* the scene must keep the contrast that makes a leak show */
    CHECK(m0[0] > 4.0 * m0[1] && m0[2] > 4.0 * m0[3], "the treads' indirect light differs too little: %.5f %.5f",
          m0[0], m0[1]);
    free(tread);
    pf_scene_destroy(&scene);
    return pf_test_finish();
}
