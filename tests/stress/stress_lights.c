/* stress_lights.c: the stress groups for lights beyond area, point and spot
 * ("distant" and "sky"; docs/stress.md lists the bounds and the values
 * measured).
 *
 * A diffuse plane y = 0 (kd 0.5, 6 x 6) under a distant light (the sun)
 * shining down at 25 degrees from the vertical with irradiance E: every
 * point of the plane has the radiance kd / pi * E cos, so direct light is
 * one number, with no noise at all (one shadow ray along -dir, a delta
 * light); the photon pass stores E cos * A on the plane (each photon hits it
 * or not: a binomial count); the photon map's estimate agrees on the mean.
 * Then a black square blocker at y = 1 casts a sharp shadow: in the full
 * render, every pixel wholly in the lit part reads kd / pi * E cos, every
 * pixel wholly in the shadow reads 0 (nothing else lights it; so the
 * shadow is sharp to the pixel), pixels across its edge lie between, and the
 * render equals
 * its direct term bit for bit. A grey blocker then sends light into the
 * shadow (plane, blocker's underside, plane: the final gather over photons
 * from the sun), which must be there and stay well below the lit plane.
 *
 * The sky's furnace: a diffuse sphere of albedo a alone under a constant sky
 * of radiance L is convex, so it sees nothing but the sky: its radiance is
 * a L exactly, with all terms, in every pixel (each cosine-weighted sky
 * sample escapes and gives a L; the gather rays, which also escape, take
 * their MIS share of the sky, and weights that did not sum to one, or a sky
 * counted twice, would miss a L), and so is the direct term rendered alone
 * (the light samples then take the whole sky); the background reads L; the photon pass
 * stores 4 pi^2 r^2 L on it (pi L on each point of its area); the photon
 * map agrees. A lossless glass sphere alone under the sky reads L in every
 * pixel (the sky seen through S, every path ending in it), but for the few
 * pixels at its rim where the depth limit cuts the inner reflections. A
 * rough conductor sphere (alpha 0.1) alone under the sky reads L times its
 * directional albedo (the mean of its sampled weights f cos / pdf), which
 * the MIS of light samples and BSDF rays that escape must give on the mean
 * (weights that do not sum to one miss it) and with little noise per pixel
 * (the cosine-weighted light samples alone find the narrow lobe rarely:
 * rms 1.41 per pixel without MIS, 0.142 with it); with one thread it
 * renders the same image bit for bit. */
#include <math.h>
#include <omp.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "base/rng.h"
#include "material/ggx.h"
#include "render/render.h"

#include "scenes_gen.h"
#include "stress.h"

#define S_HALF 3.0f      /* the plane's half side */
#define S_KD 0.5f        /* the plane's albedo */
#define S_E 2.0f         /* the sun's irradiance */
#define S_BLOCK_Y 1.0f   /* the blocker's height */
#define S_BLOCK_HALF 0.5f

/* The direction the sunlight travels: 25 degrees from straight down. */
static pf_vec3 s_sun_dir(void) { return pf_norm(pf_v3(0.35f, -1.0f, -0.25f)); }

/* sky: a constant sky's radiance beside the sun (0: none). */
static pf_scene_t *s_sun_scene(int blocker, float blocker_kd, float sky)
{
    pf_scene_t *scene = pf_scene_create();
    uint32_t mat = stress_material(scene, stress_diffuse("plane", S_KD, 0.0f));
    pf_test_quad(scene, pf_v3(-S_HALF, 0, -S_HALF), pf_v3(0, 0, 2 * S_HALF), pf_v3(2 * S_HALF, 0, 0),
                 mat); /* normal +y */
    if (blocker) {
        uint32_t bm = stress_material(scene, stress_diffuse("blocker", blocker_kd, 0.0f));
        float b = S_BLOCK_HALF;
        pf_test_quad(scene, pf_v3(-b, S_BLOCK_Y, -b), pf_v3(0, 0, 2 * b), pf_v3(2 * b, 0, 0), bm);
    }
    pf_light_t l = { .type = PF_LIGHT_DISTANT, .dir = s_sun_dir(), .intensity = pf_v3s(S_E) };
    PF_CHECK(pf_scene_add_light(scene, &l) == PF_OK);
    if (sky > 0.0f) {
        pf_light_t inf = { .type = PF_LIGHT_INFINITE, .intensity = pf_v3s(sky) };
        PF_CHECK(pf_scene_add_light(scene, &inf) == PF_OK);
    }
    /* on the shadow's side, so the blocker hides none of it */
    stress_camera(scene, pf_v3(2.5f, 5.0f, -2.5f), pf_v3(0.1f, 0, -0.1f), pf_v3(0, 1, 0), 60.0f);
    pf_error_t err = { { 0 } };
    CHECK(pf_scene_finalize(scene, &err) == PF_OK, "finalize: %s", err.msg);
    return scene;
}

/* What the camera sees through image point (x, y): 0 the lit plane, 1 the
 * plane in the blocker's shadow, 2 the blocker, 3 nothing. */
static int s_seen(const pf_camera_t *cam, float x, float y, int blocker)
{
    pf_ray_t r = pf_camera_ray(cam, x, y);
    if (!(r.d.y < 0.0f))
        return 3;
    float b = S_BLOCK_HALF;
    float tb = (S_BLOCK_Y - r.o.y) / r.d.y;
    pf_vec3 q = pf_madd(r.o, r.d, tb);
    if (blocker && tb > 0.0f && fabsf(q.x) <= b && fabsf(q.z) <= b)
        return 2;
    pf_vec3 p = pf_madd(r.o, r.d, -r.o.y / r.d.y);
    if (fabsf(p.x) > S_HALF || fabsf(p.z) > S_HALF)
        return 3;
    /* back along the sunlight to the blocker's height */
    pf_vec3 s = s_sun_dir();
    pf_vec3 up = pf_madd(p, s, -S_BLOCK_Y / -s.y);
    return blocker && fabsf(up.x) <= b && fabsf(up.z) <= b ? 1 : 0;
}

/* A pixel's class over a 5 x 5 grid of its points (edges included): the
 * class they all share, or -1 when they differ. */
static int s_pixel_class(const pf_camera_t *cam, int px, int py, int blocker)
{
    int cls = -2;
    for (int j = 0; j < 5; j++)
        for (int i = 0; i < 5; i++) {
            int c = s_seen(cam, (float)px + i / 4.0f, (float)py + j / 4.0f, blocker);
            cls = cls == -2 || cls == c ? c : -1;
        }
    return cls;
}

/* The lone plane: direct light per pixel, the stored flux, the photon map. */
static void s_test_sun_plane(void)
{
    pf_scene_t *scene = s_sun_scene(0, 0.0f, 0.0f);
    double cos_t = -s_sun_dir().y, lit = S_KD / PF_PI * S_E * cos_t;
    pf_settings_t s = stress_settings(scene, 48, 4, 200000, 8);
    stress_job_t job;
    if (stress_job_begin(&job, "sun plane", scene, &s) == PF_OK) {
        /* Photons hit the plane with probability p = A cos / (pi R^2), each
         * carrying E pi R^2 / N: the total is E cos A, relative sigma
         * sqrt((1 - p) / (N p)). */
        double area = 4.0 * S_HALF * S_HALF, want = S_E * cos_t * area;
        double flux = stress_map_power(job.fr.maps.global);
        double r = sqrt(2.0) * S_HALF * 1.01; /* the bounding sphere of the flat box, about */
        double p = area * cos_t / (PF_PI * r * r), sigma = sqrt((1.0 - p) / ((double)s.photons * p));
        printf("sun plane: stored flux %.5f, expected E cos A = %.5f (ratio %.4f, sigma %.4f, bound 4 sigma); "
               "%llu photons stored of %llu\n",
               flux, want, flux / want, sigma, (unsigned long long)job.stats.global_stored,
               (unsigned long long)s.photons);
        CHECK(fabs(flux / want - 1.0) < 4.0 * sigma, "sun plane: stored flux %.5f, expected %.5f", flux, want);

        pf_image_t direct, pm;
        stress_job_render(&job, "sun plane direct", PF_TERM_DIRECT, &direct);
        stress_job_render(&job, "sun plane photon map", PF_TERM_PHOTONMAP, &pm);
        pf_camera_t cam = pf_camera_make(&scene->camera, direct.width, direct.height);
        size_t n = 0, bad = 0;
        double worst = 0.0, sum_pm = 0.0;
        size_t n_pm = 0;
        for (int py = 0; py < direct.height; py++)
            for (int px = 0; px < direct.width; px++) {
                if (s_pixel_class(&cam, px, py, 0) != 0)
                    continue;
                size_t k = 3 * ((size_t)py * (size_t)direct.width + (size_t)px);
                double ex = fabs(direct.rgb[k] / lit - 1.0);
                worst = fmax(worst, ex);
                bad += ex > 1e-4;
                n++;
                /* the photon map away from the plane's edge (a disc cut by the edge reads low) */
                pf_ray_t ray = pf_camera_ray(&cam, px + 0.5f, py + 0.5f);
                pf_vec3 q = pf_madd(ray.o, ray.d, -ray.o.y / ray.d.y);
                if (fabsf(q.x) <= 0.6f * S_HALF && fabsf(q.z) <= 0.6f * S_HALF) {
                    sum_pm += pm.rgb[k];
                    n_pm++;
                }
            }
        double pm_ratio = sum_pm / (double)n_pm / lit;
        printf("sun plane direct: %zu pixels wholly on the plane, worst relative error against kd/pi E cos = %.6f: "
               "%.2e (bound 1e-4); photon-map estimate over the inner 60 %% (%zu pixels): ratio %.4f (bound 1 +- "
               "0.02)\n",
               n, lit, worst, n_pm, pm_ratio);
        CHECK(n > 1000 && bad == 0, "sun plane: %zu of %zu pixels off kd/pi E cos by more than 1e-4", bad, n);
        CHECK(n_pm > 200 && fabs(pm_ratio - 1.0) <= 0.02, "sun plane: photon-map radiance ratio %.4f", pm_ratio);
        pf_image_free(&direct);
        pf_image_free(&pm);
        stress_job_end(&job);
    }
    pf_scene_destroy(&scene);
}

/* The plane with a blocker: the sharp shadow, in the full render. */
static void s_test_sun_shadow(void)
{
    double lit = S_KD / PF_PI * S_E * -s_sun_dir().y;
    for (int grey = 0; grey < 2; grey++) {
        const char *what = grey ? "sun shadow, grey blocker" : "sun shadow, black blocker";
        pf_scene_t *scene = s_sun_scene(1, grey ? 0.5f : 0.0f, 0.0f);
        pf_settings_t s = stress_settings(scene, 96, 4, 200000, 16);
        pf_image_t full, direct;
        if (stress_render(what, scene, &s, PF_TERM_ALL, &full, NULL) != PF_OK) {
            pf_scene_destroy(&scene);
            continue;
        }
        int ok_direct = stress_render(what, scene, &s, PF_TERM_DIRECT, &direct, NULL) == PF_OK;
        pf_camera_t cam = pf_camera_make(&scene->camera, full.width, full.height);
        size_t count[4] = { 0, 0, 0, 0 }, edge = 0, bad_lit = 0, bad_dark = 0, bad_edge = 0;
        double shadow_sum = 0.0, maxdiff = 0.0;
        for (int py = 0; py < full.height; py++)
            for (int px = 0; px < full.width; px++) {
                int cls = s_pixel_class(&cam, px, py, 1);
                size_t k = 3 * ((size_t)py * (size_t)full.width + (size_t)px);
                double v = full.rgb[k], d = ok_direct ? direct.rgb[k] : 0.0;
                if (ok_direct)
                    maxdiff = fmax(maxdiff, fabs(v - d));
                if (cls < 0) {
                    edge++;
                    bad_edge += !(d >= 0.0 && d <= lit * (1.0 + 1e-4));
                    continue;
                }
                count[cls]++;
                if (cls == 0)
                    bad_lit += fabs(d / lit - 1.0) > 1e-4 || (!grey && fabs(v / lit - 1.0) > 1e-4);
                if (cls == 1) {
                    bad_dark += d != 0.0 || (!grey && v != 0.0);
                    shadow_sum += v;
                }
            }
        double shadow_mean = count[1] ? shadow_sum / (double)count[1] : 0.0;
        printf("%s: %zu lit, %zu shadowed, %zu blocker, %zu edge pixels; %zu lit off kd/pi E cos by > 1e-4, %zu "
               "shadowed with direct light, %zu edge pixels outside [0, lit]; shadow's mean (full render) %.5f = "
               "%.4f of the lit plane; full - direct up to %.3g\n",
               what, count[0], count[1], count[2], edge, bad_lit, bad_dark, bad_edge, shadow_mean, shadow_mean / lit,
               maxdiff);
        CHECK(count[0] > 3000 && count[1] > 100, "%s: %zu lit and %zu shadowed pixels", what, count[0], count[1]);
        CHECK(bad_lit == 0 && bad_dark == 0 && bad_edge == 0, "%s: %zu lit, %zu dark, %zu edge pixels wrong", what,
              bad_lit, bad_dark, bad_edge);
        if (!grey)
            CHECK(ok_direct && maxdiff == 0.0, "%s: the full render differs from direct light by %g", what, maxdiff);
        else
            CHECK(shadow_mean > 0.01 * lit && shadow_mean < 0.3 * lit,
                  "%s: the shadow gets %.4f of the lit plane's radiance from the blocker's underside", what,
                  shadow_mean / lit);
        pf_image_free(&full);
        if (ok_direct)
            pf_image_free(&direct);
        pf_scene_destroy(&scene);
    }
}

/* The lone plane under the sun and a constant sky together (an interior's
 * pair): the direct term is kd / pi (E cos + pi L) in every pixel wholly on
 * the plane, with no noise: the sun is taken whole by a shadow ray of its
 * own, and the sky's cosine-weighted samples all escape. A choice between
 * them by power would make each light sample the sun's or the sky's, and
 * pixels would scatter about that value. */
static void s_test_sun_and_sky(void)
{
    const float sky = 0.3f;
    pf_scene_t *scene = s_sun_scene(0, 0.0f, sky);
    double want = S_KD / PF_PI * (S_E * -s_sun_dir().y + PF_PI * sky);
    pf_settings_t s = stress_settings(scene, 48, 4, 20000, 8);
    pf_image_t direct;
    if (stress_render("sun and sky", scene, &s, PF_TERM_DIRECT, &direct, NULL) == PF_OK) {
        pf_camera_t cam = pf_camera_make(&scene->camera, direct.width, direct.height);
        size_t n = 0, bad = 0;
        double worst = 0.0;
        for (int py = 0; py < direct.height; py++)
            for (int px = 0; px < direct.width; px++) {
                if (s_pixel_class(&cam, px, py, 0) != 0)
                    continue;
                double ex = fabs(direct.rgb[3 * ((size_t)py * (size_t)direct.width + (size_t)px)] / want - 1.0);
                worst = fmax(worst, ex);
                bad += ex > 1e-4;
                n++;
            }
        printf("sun and sky: %zu pixels wholly on the plane, worst relative error against kd/pi (E cos + pi L) = "
               "%.6f: %.2e (bound 1e-4)\n",
               n, want, worst);
        CHECK(n > 1000 && bad == 0, "sun and sky: %zu of %zu pixels off kd/pi (E cos + pi L) by more than 1e-4 (worst %.3g)",
              bad, n, worst);
        pf_image_free(&direct);
    }
    pf_scene_destroy(&scene);
}

void stress_test_distant(void)
{
    s_test_sun_plane();
    s_test_sun_shadow();
    s_test_sun_and_sky();
}

#define S_SKY 0.8f /* the sky's radiance */

static pf_scene_t *s_sky_scene(pf_material_t m, float r)
{
    pf_scene_t *scene = pf_scene_create();
    stress_sphere(scene, pf_v3(0, 0, 0), r, stress_material(scene, m));
    pf_light_t l = { .type = PF_LIGHT_INFINITE, .intensity = pf_v3s(S_SKY) };
    PF_CHECK(pf_scene_add_light(scene, &l) == PF_OK);
    stress_camera(scene, pf_v3(0.3f, 0.8f, 4.0f), pf_v3(0, 0, 0), pf_v3(0, 1, 0), 40.0f);
    pf_error_t err = { { 0 } };
    CHECK(pf_scene_finalize(scene, &err) == PF_OK, "finalize: %s", err.msg);
    return scene;
}

/* Whether the camera's rays through a pixel's 5 x 5 points all hit the
 * sphere of radius r at the origin (1), all miss it (0), or differ (-1). */
static int s_sphere_class(const pf_camera_t *cam, int px, int py, float r)
{
    int cls = -2;
    for (int j = 0; j < 5; j++)
        for (int i = 0; i < 5; i++) {
            pf_ray_t ray = pf_camera_ray(cam, (float)px + i / 4.0f, (float)py + j / 4.0f);
            float along = -pf_dot(ray.o, ray.d);
            int c = pf_len2(ray.o) - along * along < r * r * 0.999f;
            cls = cls == -2 || cls == c ? c : -1;
        }
    return cls;
}

static void s_test_sky_furnace(void)
{
    const float a = 0.6f, r = 1.0f;
    pf_scene_t *scene = s_sky_scene(stress_diffuse("sphere", a, 0.0f), r);
    pf_settings_t s = stress_settings(scene, 64, 16, 200000, 8);
    stress_job_t job;
    if (stress_job_begin(&job, "sky furnace", scene, &s) == PF_OK) {
        /* a photon hits the sphere with probability p = r^2 / R^2 (R: the
         * bounding sphere of its box, sqrt(3) r widened by 1 %) */
        double want = 4.0 * PF_PI * PF_PI * r * r * S_SKY, flux = stress_map_power(job.fr.maps.global);
        double big = sqrt(3.0) * r * 1.01, p = (r * r) / (big * big), sigma = sqrt((1.0 - p) / ((double)s.photons * p));
        printf("sky furnace: stored flux %.5f, expected 4 pi^2 r^2 L = %.5f (ratio %.4f, sigma %.4f, bound 4 sigma)\n",
               flux, want, flux / want, sigma);
        CHECK(fabs(flux / want - 1.0) < 4.0 * sigma, "sky furnace: stored flux %.5f, expected %.5f", flux, want);
        pf_image_t full, direct, pm;
        stress_job_render(&job, "sky furnace all", PF_TERM_ALL, &full);
        stress_job_render(&job, "sky furnace direct", PF_TERM_DIRECT, &direct);
        stress_job_render(&job, "sky furnace photon map", PF_TERM_PHOTONMAP, &pm);
        pf_camera_t cam = pf_camera_make(&scene->camera, full.width, full.height);
        size_t n_sphere = 0, n_sky = 0, bad_sky = 0, not_direct = 0, off = 0;
        double sum = 0.0, sum_pm = 0.0;
        for (int py = 0; py < full.height; py++)
            for (int px = 0; px < full.width; px++) {
                int cls = s_sphere_class(&cam, px, py, r);
                size_t k = 3 * ((size_t)py * (size_t)full.width + (size_t)px);
                if (cls == 0) {
                    n_sky++;
                    bad_sky += full.rgb[k] != S_SKY || direct.rgb[k] != 0.0f;
                } else if (cls == 1) {
                    n_sphere++;
                    sum += full.rgb[k];
                    sum_pm += pm.rgb[k];
                    /* the direct term alone: light sampling takes the whole sky */
                    not_direct += fabs(direct.rgb[k] / (a * S_SKY) - 1.0) > 1e-4;
                    /* cosine-weighted sky samples all escape a convex object: each gives a L */
                    off += fabs(full.rgb[k] / (a * S_SKY) - 1.0) > 1e-4;
                }
            }
        double mean = sum / (double)n_sphere / (a * S_SKY), mean_pm = sum_pm / (double)n_sphere / (a * S_SKY);
        printf("sky furnace: %zu sky pixels, %zu not L; %zu sphere pixels, mean radiance / a L = %.4f (bound 1 +- "
               "0.02), %zu off a L by > 1e-4 (bound 0), photon map %.4f (bound 1 +- 0.03), %zu with the direct term "
               "alone off a L by > 1e-4 (bound 0)\n",
               n_sky, bad_sky, n_sphere, mean, off, mean_pm, not_direct);
        CHECK(n_sky > 1000 && bad_sky == 0, "sky furnace: %zu of %zu background pixels not L", bad_sky, n_sky);
        CHECK(n_sphere > 1000 && fabs(mean - 1.0) <= 0.02 && off == 0,
              "sky furnace: sphere radiance %.4f of a L, %zu pixels off", mean, off);
        CHECK(fabs(mean_pm - 1.0) <= 0.03, "sky furnace: photon-map radiance %.4f of a L", mean_pm);
        /* A convex object's gather rays all escape: they share the sky with
         * the light samples by MIS, and the full render must still be a L
         * (off, above: counting the sky twice would make it up to 2 a L),
         * as must direct light rendered alone. */
        CHECK(not_direct == 0, "sky furnace: %zu sphere pixels' direct term (rendered alone) off a L", not_direct);
        pf_image_free(&full);
        pf_image_free(&direct);
        pf_image_free(&pm);
        stress_job_end(&job);
    }
    pf_scene_destroy(&scene);

    /* lossless glass: L in every pixel */
    scene = s_sky_scene(stress_glass("glass", 1.5f), r);
    s = stress_settings(scene, 48, 4, 50000, 8);
    s.caustic_photons = 50000;
    pf_image_t img;
    if (stress_render("sky glass", scene, &s, PF_TERM_ALL, &img, NULL) == PF_OK) {
        size_t n = (size_t)img.width * (size_t)img.height * 3, off = 0, above = 0;
        double worst = 0.0, mean = 0.0;
        for (size_t k = 0; k < n; k++) {
            double ex = img.rgb[k] / S_SKY - 1.0;
            worst = fmax(worst, fabs(ex));
            off += fabs(ex) > 1e-3;
            above += ex > 1e-4;
            mean += img.rgb[k] / S_SKY / (double)n;
        }
        /* Paths grazing the rim bounce inside many times at a high Fresnel
         * reflectance: the depth limit (16) loses a few per cent there. */
        printf("sky glass: mean / L %.5f (bound 1 - 2e-3), %zu of %zu channels off L by > 1e-3 (bound 1 %%), %zu "
               "above L (bound 0), worst %.2e\n",
               mean, off, n, above, worst);
        CHECK(fabs(mean - 1.0) < 2e-3 && off <= n / 100 && above == 0,
              "sky glass: mean %.5f of L, %zu channels off L, %zu above it", mean, off, above);
        pf_image_free(&img);
    }
    pf_scene_destroy(&scene);
}

static void s_test_sky_conductor(void)
{
    const float r = 1.0f;
    pf_material_t m = pf_material_default("metal");
    m.type = PF_MAT_CONDUCTOR;
    m.kd = pf_v3s(0.0f);
    m.eta = pf_v3s(1.0f);
    m.k = pf_v3s(pf_conductor_k_of_reflectance(0.9f));
    m.alpha = 0.1f;
    pf_scene_t *scene = s_sky_scene(m, r);
    pf_settings_t s = stress_settings(scene, 48, 8, 20000, 8);
    pf_image_t img;
    if (stress_render("sky conductor", scene, &s, PF_TERM_ALL, &img, NULL) != PF_OK) {
        pf_scene_destroy(&scene);
        return;
    }
    pf_camera_t cam = pf_camera_make(&scene->camera, img.width, img.height);
    double sum = 0.0, sum_want = 0.0, sq = 0.0;
    size_t n = 0;
    pf_rng_t rng = pf_rng_make(17, PF_STREAM_TEST, 0, 0);
    for (int py = 0; py < img.height; py++)
        for (int px = 0; px < img.width; px++) {
            if (s_sphere_class(&cam, px, py, r) != 1)
                continue;
            /* L times the albedo, over 2 x 2 points of the pixel */
            double want = 0.0;
            for (int k = 0; k < 4; k++) {
                pf_ray_t ray = pf_camera_ray(&cam, px + 0.25f + 0.5f * (k & 1), py + 0.25f + 0.5f * (k >> 1));
                float along = -pf_dot(ray.o, ray.d);
                float t = along - sqrtf(r * r - (pf_len2(ray.o) - along * along));
                pf_vec3 nrm = pf_norm(pf_madd(ray.o, ray.d, t)), wo = pf_neg(ray.d);
                for (int i = 0; i < 64; i++) {
                    pf_vec3 wi, wgt;
                    float pdf, u1 = pf_rng_float(&rng), u2 = pf_rng_float(&rng);
                    if (pf_conductor_sample(&m, nrm, wo, u1, u2, &wi, &wgt, &pdf))
                        want += wgt.y * S_SKY / 256.0;
                }
            }
            double v = img.rgb[3 * ((size_t)py * (size_t)img.width + (size_t)px) + 1];
            sum += v;
            sum_want += want;
            sq += (v / want - 1.0) * (v / want - 1.0);
            n++;
        }
    double ratio = sum / sum_want, rms = sqrt(sq / (double)n);
    printf("sky conductor: %zu sphere pixels, mean / (L albedo) %.4f (bound 1 +- 0.02), per-pixel rms relative "
           "deviation %.4f (bound 0.3)\n",
           n, ratio, rms);
    CHECK(n > 500 && fabs(ratio - 1.0) <= 0.02, "sky conductor: mean %.4f of L albedo", ratio);
    CHECK(rms <= 0.3, "sky conductor: per-pixel rms deviation %.4f from L albedo", rms);
    /* one thread against all: the same image, bit for bit */
    pf_image_t one;
    s.threads = 1;
    if (stress_render("sky conductor, 1 thread", scene, &s, PF_TERM_ALL, &one, NULL) == PF_OK) {
        size_t nb = (size_t)img.width * (size_t)img.height * 3 * sizeof *img.rgb;
        CHECK(memcmp(one.rgb, img.rgb, nb) == 0, "sky conductor: 1 thread and %d differ", omp_get_num_procs());
        pf_image_free(&one);
    }
    pf_image_free(&img);
    pf_scene_destroy(&scene);
}

void stress_test_sky(void)
{
    s_test_sky_furnace();
    s_test_sky_conductor();
}
