/* stress_geometry.c: the stress groups that aim at hard geometry and bad
 * input (test_stress.c lists the cases and bounds): grazing rays, glass in a
 * furnace, a light inside glass, thin walls, cameras inside closed boxes,
 * and the degenerate files of tests/data/stress, each refused naming file
 * and line or loaded and rendered without a bad pixel. Called from the
 * test's main thread; the renders spread over OpenMP threads. */
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <unistd.h>

#include "accel/accel.h"
#include "base/log.h"
#include "base/rng.h"
#include "load/load.h"
#include "photon/irradiance.h"
#include "render/render.h"

#include "scenes_gen.h"
#include "stress.h"

/* ------------------------------------------------------------------------ */
/* geometry                                                                  */
/* ------------------------------------------------------------------------ */

/* Grazing rays on a plane 2e5 units wide: the camera 0.05 above it looking
 * at the horizon, the light 0.1 above it, so camera rays, shadow rays and the
 * plane meet at angles down to a few thousandths of a degree and hit points
 * lie up to 1e5 away. Direct light is compared pixel by pixel with the
 * analytic radiance, so any shadow acne shows. */
static void s_grazing(void)
{
    stress_plane_t pl = { .kd = 0.7, .intensity = 1.0, .half = 1e5, .light = { 0.3f, 0.1f, 3.0f } };
    pf_scene_t *scene = pf_scene_create();
    uint32_t mat = stress_material(scene, stress_diffuse("ground", (float)pl.kd, 0.0f));
    float h = (float)pl.half;
    pf_test_quad(scene, pf_v3(-h, 0, -h), pf_v3(0, 0, 2 * h), pf_v3(2 * h, 0, 0), mat);
    stress_point_light(scene, pl.light, (float)pl.intensity);
    stress_camera(scene, pf_v3(0, 0.05f, 0), pf_v3(0, 0.0f, 5.0f), pf_v3(0, 1, 0), 4.0f);
    pf_error_t err = { { 0 } };
    CHECK(pf_scene_finalize(scene, &err) == PF_OK, "finalize: %s", err.msg);
    pf_settings_t s = stress_settings(scene, 64, 16, 20000, 4);
    pf_image_t img;
    if (stress_render("grazing direct", scene, &s, PF_TERM_DIRECT, &img, NULL) == PF_OK) {
        size_t lit;
        stress_plane_compare("grazing direct", &pl, scene, &img, 1e-2, 1e-2, &lit);
        CHECK(lit > 1000, "grazing: only %zu lit pixels", lit);
        pf_image_free(&img);
    }
    if (stress_render("grazing full", scene, &s, PF_TERM_ALL, &img, NULL) == PF_OK)
        pf_image_free(&img);
    pf_scene_destroy(&scene);
}

/* The fraction of pixel centres whose camera ray first meets glass: shows a
 * glass case really looks at its glass. */
static double s_glass_fraction(const pf_scene_t *scene, int width, int height)
{
    pf_error_t err;
    pf_accel_t *accel = pf_accel_create(scene, &err);
    PF_CHECK(accel != NULL);
    pf_camera_t cam = pf_camera_make(&scene->camera, width, height);
    size_t glass = 0;
    for (int y = 0; y < height; y++)
        for (int x = 0; x < width; x++) {
            pf_ray_t r = pf_camera_ray(&cam, x + 0.5f, y + 0.5f);
            pf_hit_t h;
            glass += pf_accel_intersect(accel, &r, INFINITY, &h) && scene->mats[h.mat].type == PF_MAT_GLASS;
        }
    pf_accel_destroy(&accel);
    return (double)glass / ((double)width * height);
}

/* A furnace (a = 0.5, Le = 1) holding lossless glass: a sphere, a nested
 * pair (ior 1.33 around ior 1.8) and a cube, where rays that entered through
 * one face meet the side faces beyond the critical angle (total internal
 * reflection). Lossless glass in a uniform radiance field leaves it uniform,
 * so the image is still Le / (1 - a), through the glass as beside it. */
static void s_glass_furnace(void)
{
    const float a = 0.5f, le = 1.0f;
    pf_scene_t *scene = pf_scene_create();
    uint32_t wall = stress_material(scene, stress_diffuse("furnace", a, le));
    uint32_t g15 = stress_material(scene, stress_glass("glass", 1.5f));
    uint32_t g133 = stress_material(scene, stress_glass("water", 1.33f));
    uint32_t g18 = stress_material(scene, stress_glass("flint", 1.8f));
    pf_test_inward_sphere(scene, 4, 1.0f, wall);
    stress_sphere(scene, pf_v3(0.35f, -0.15f, -0.35f), 0.22f, g15);
    stress_sphere(scene, pf_v3(-0.3f, 0.15f, -0.4f), 0.25f, g133);
    stress_sphere(scene, pf_v3(-0.3f, 0.15f, -0.4f), 0.12f, g18);
    stress_box(scene, pf_v3(-0.05f, -0.45f, -0.55f), pf_v3(0.2f, -0.2f, -0.3f), g15, 0);
    stress_camera(scene, pf_v3(0, 0, 0.5f), pf_v3(0, -0.05f, -0.4f), pf_v3(0, 1, 0), 70.0f);
    pf_error_t err = { { 0 } };
    CHECK(pf_scene_finalize(scene, &err) == PF_OK, "finalize: %s", err.msg);
    pf_settings_t s = stress_settings(scene, 32, 4, 60000, 16);
    s.caustic_photons = 200000;
    pf_image_t img;
    double secs;
    if (stress_render("glass furnace", scene, &s, PF_TERM_ALL, &img, &secs) == PF_OK) {
        double expect = le / (1.0 - a), mean = stress_mean(&img), within;
        within = stress_within(&img, expect, 0.20);
        double seen = s_glass_fraction(scene, s.width, s.height);
        printf("glass furnace: mean %.5f expected %.5f (ratio %.4f, bound 1 +- 0.02); %.1f %% of channels within "
               "20 %% (bound 99 %%); glass in %.1f %% of the view; %.1f s\n",
               mean, expect, mean / expect, 100.0 * within, 100.0 * seen, secs);
        CHECK(seen >= 0.15, "glass furnace: glass covers only %.1f %% of the view", 100.0 * seen);
        CHECK(fabs(mean / expect - 1.0) <= 0.02, "glass furnace: mean %.5f, expected %.5f", mean, expect);
        CHECK(within >= 0.99, "glass furnace: %.1f %% within 20 %%", 100.0 * within);
        pf_image_free(&img);
    }
    /* The camera inside a glass sphere, at its centre: every ray leaves
     * along the normal (no refraction, no total internal reflection), and
     * radiance inside a medium of index n is n^2 times that outside. */
    pf_scene_t *inside = pf_scene_create();
    wall = stress_material(inside, stress_diffuse("furnace", a, le));
    g15 = stress_material(inside, stress_glass("glass", 1.5f));
    pf_test_inward_sphere(inside, 4, 1.0f, wall);
    stress_sphere(inside, pf_v3(0.1f, -0.05f, 0.05f), 0.4f, g15);
    stress_camera(inside, pf_v3(0.1f, -0.05f, 0.05f), pf_v3(0.1f, 0.2f, -1.0f), pf_v3(0, 1, 0), 80.0f);
    CHECK(pf_scene_finalize(inside, &err) == PF_OK, "finalize: %s", err.msg);
    s = stress_settings(inside, 24, 4, 60000, 16);
    s.caustic_photons = 100000;
    if (stress_render("camera inside glass", inside, &s, PF_TERM_ALL, &img, &secs) == PF_OK) {
        double expect = 1.5 * 1.5 * le / (1.0 - a), mean = stress_mean(&img);
        printf("camera at the centre of a glass sphere (ior 1.5) in the furnace: mean %.5f expected n^2 Le / (1 - a) "
               "= %.5f (ratio %.4f, bound 1 +- 0.02); %.1f s\n",
               mean, expect, mean / expect, secs);
        CHECK(fabs(mean / expect - 1.0) <= 0.02, "camera inside glass: mean %.5f, expected %.5f", mean, expect);
        pf_image_free(&img);
    }
    pf_scene_destroy(&inside);
    pf_scene_destroy(&scene);
}

/* A point light of intensity I inside a glass sphere (radius r) inside a
 * closed diffuse sphere (radius R, albedo a, no emission). Centred, every
 * photon leaves the glass (normal incidence); off centre by d, a photon whose
 * direction makes angle psi with the radial line meets the surface at
 * sin(theta) = d sin(psi) / r, and a sphere keeps that angle at every
 * reflection, so photons with sin(psi) > r / (n d) are trapped for good: a
 * fraction cos(psi0) of all directions. The flux that escapes, Phi_esc, is
 * stored on the walls Phi_esc (1 + a + a^2 ...) = Phi_esc / (1 - a) in all
 * (light from the walls crosses the glass and leaves it again). Centred, the
 * walls' radiance is a I / (pi R^2 (1 - a)) everywhere. */
static void s_light_in_glass(float offset, int check_image)
{
    const float a = 0.5f, I = 1.0f, R = 1.0f, r = 0.3f, n = 1.5f;
    pf_scene_t *scene = pf_scene_create();
    uint32_t wall = stress_material(scene, stress_diffuse("walls", a, 0.0f));
    uint32_t glass = stress_material(scene, stress_glass("glass", n));
    pf_test_inward_sphere(scene, 4, R, wall);
    stress_sphere(scene, pf_v3(0, 0, 0), r, glass);
    stress_point_light(scene, pf_v3(offset, 0, 0), I);
    stress_camera(scene, pf_v3(0.1f, 0.5f, 0.6f), pf_v3(-0.2f, -0.3f, -0.9f), pf_v3(0, 1, 0), 80.0f);
    pf_error_t err = { { 0 } };
    CHECK(pf_scene_finalize(scene, &err) == PF_OK, "finalize: %s", err.msg);
    /* Off centre, every trapped photon bounces photon_max_depth (1000)
     * times before it ends, so that case emits fewer. */
    pf_settings_t s = stress_settings(scene, 24, 4, check_image ? 40000 : 20000, 16);
    s.caustic_photons = check_image ? 200000 : 5000;
    char what[96];
    snprintf(what, sizeof what, "light in glass, offset %.2f r", offset / r);
    pf_image_t img;
    stress_job_t job;
    double t0 = pf_now();
    if (stress_job_begin(&job, what, scene, &s) == PF_OK) {
        stress_job_render(&job, what, PF_TERM_ALL, &img);
        double phi = 4.0 * M_PI * I, escape = 1.0;
        if (offset > r / n)
            escape = 1.0 - sqrt(1.0 - pow(r / (n * offset), 2.0));
        double flux = stress_map_power(job.fr.maps.global), expect = phi * escape / (1.0 - a);
        /* Binomial noise of the escaping fraction plus the wall bounces'
         * roulette: sigma_rel^2 = (1 - e) / (e N) + a / (e N). */
        double sigma = sqrt(((1.0 - escape) + a) / (escape * (double)s.photons));
        printf("%s: escaping fraction %.4f; stored flux %.4f expected %.4f (ratio %.4f, sigma %.4f, bound 4 "
               "sigma); %.1f s\n",
               what, escape, flux, expect, flux / expect, sigma, pf_now() - t0);
        CHECK(fabs(flux / expect - 1.0) <= 4.0 * sigma, "%s: stored flux %.4f, expected %.4f", what, flux, expect);
        if (check_image) {
            double L = a * I / (M_PI * R * R * (1.0 - a)), mean = stress_mean(&img);
            printf("%s: wall radiance mean %.5f expected a I / (pi R^2 (1 - a)) = %.5f (ratio %.4f, bound 1 +- "
                   "0.03)\n",
                   what, mean, L, mean / L);
            CHECK(fabs(mean / L - 1.0) <= 0.03, "%s: mean %.5f, expected %.5f", what, mean, L);
        }
        pf_image_free(&img);
        stress_job_end(&job);
    }
    pf_scene_destroy(&scene);
}

/* When a view that must be black is not, says which term carries the light
 * (for the report; the check itself is on the full render). */
static void s_leak_terms(const char *what, const stress_job_t *job)
{
    static const struct {
        unsigned term;
        const char *name;
    } terms[] = { { PF_TERM_EMITTED, "emitted" }, { PF_TERM_DIRECT, "direct" }, { PF_TERM_CAUSTIC, "caustic" },
                  { PF_TERM_INDIRECT, "indirect" } };
    for (size_t i = 0; i < sizeof terms / sizeof *terms; i++) {
        pf_image_t img;
        stress_job_render(job, what, terms[i].term, &img);
        size_t n = (size_t)img.width * (size_t)img.height * 3, lit = 0;
        for (size_t k = 0; k < n; k++)
            lit += img.rgb[k] > 0.0f;
        printf("  %s: %s term alone: brightest channel %.4g, mean %.4g, %zu of %zu channels non-zero\n", what,
               terms[i].name, stress_max(&img), stress_mean(&img), lit, n);
        pf_image_free(&img);
    }
}

/* Two closed rooms side by side, the wall between them `thickness` thick
 * (each room a watertight box; the wall is the gap between them). Room A has
 * an area light on its ceiling and a point light 1 cm from the wall; room B
 * has none. Every pixel of a view inside room B must be black and no photon
 * may be stored in it; a view of room A shows the lights work. */
static void s_thin_wall(float thickness)
{
    const float t = thickness;
    pf_scene_t *scene = pf_scene_create();
    uint32_t white = stress_material(scene, stress_diffuse("white", 0.8f, 0.0f));
    uint32_t light = stress_material(scene, stress_diffuse("light", 0.0f, 10.0f));
    stress_box(scene, pf_v3(-1, 0, 0), pf_v3(0, 1, 1), white, 1);
    stress_box(scene, pf_v3(t, 0, 0), pf_v3(1 + t, 1, 1), white, 1);
    pf_test_quad(scene, pf_v3(-0.7f, 0.99f, 0.3f), pf_v3(0.4f, 0, 0), pf_v3(0, 0, 0.4f), light); /* faces down */
    stress_point_light(scene, pf_v3(-0.01f, 0.5f, 0.5f), 2.0f);
    pf_error_t err = { { 0 } };
    stress_camera(scene, pf_v3(0.9f + t, 0.5f, 0.5f), pf_v3(0, 0.45f, 0.5f), pf_v3(0, 1, 0), 100.0f);
    CHECK(pf_scene_finalize(scene, &err) == PF_OK, "finalize: %s", err.msg);
    pf_settings_t s = stress_settings(scene, 32, 4, 40000, 16);
    char what[64];
    snprintf(what, sizeof what, "thin wall %.0e", (double)t);
    pf_image_t dark, lit;
    stress_job_t job;
    if (stress_job_begin(&job, what, scene, &s) == PF_OK) {
        stress_job_render(&job, what, PF_TERM_ALL, &dark);
        size_t leaked = 0;
        const pf_photon_t *p = pf_kdtree_photons(job.fr.maps.global);
        for (size_t i = 0; i < pf_kdtree_size(job.fr.maps.global); i++)
            leaked += p[i].pos[0] > 0.5f * t;
        double maxv = stress_max(&dark);
        if (maxv != 0.0)
            s_leak_terms(what, &job);
        /* The other room's view, for scale. */
        scene->camera = (pf_camera_desc_t){ .pos = pf_v3(-0.9f, 0.5f, 0.5f), .look_at = pf_v3(0, 0.45f, 0.5f),
                                            .up = pf_v3(0, 1, 0), .vfov_deg = 100.0f };
        stress_job_render(&job, what, PF_TERM_ALL, &lit);
        double lit_mean = stress_mean(&lit);
        pf_image_free(&lit);
        printf("%s: dark room's brightest channel %.3g (bound 0), lit room's mean %.4f; %zu of %zu photons stored "
               "in the dark room (bound 0)\n",
               what, maxv, lit_mean, leaked, pf_kdtree_size(job.fr.maps.global));
        CHECK(maxv == 0.0, "%s: light leaks into the dark room: a channel reads %g (lit room %g)", what, maxv,
              lit_mean);
        CHECK(leaked == 0, "%s: %zu photons stored in the dark room", what, leaked);
        CHECK(lit_mean > 0.05, "%s: the lit room is dark (%g): the test would prove nothing", what, lit_mean);
        pf_image_free(&dark);
        stress_job_end(&job);
    }
    pf_scene_destroy(&scene);
}

/* The irradiance (green channel) at irradiance point q as the precompute
 * means it, from the photons of q's own side of the wall only (x > side_x,
 * a plane inside the wall) whose normals agree with q's: those strictly
 * within q's disc (its support radius, shrunk by shrink2: a progressive
 * pass's) summed over that disc's share of the floor, the disc less the
 * segment the wall (its face at face_x) cuts off (irradiance.c's coverage,
 * here exact). The radius goes to *r_out. */
static double s_same_side_irradiance(const pf_kdtree_t *global, const pf_photon_t *q, float side_x, float face_x,
                                     float shrink2, double *r_out)
{
    const pf_photon_t *ph = pf_kdtree_photons(global);
    pf_vec3 x = pf_photon_pos(q), n = pf_photon_normal(q);
    double r2 = (double)pf_irradiance_radius(q) * (double)pf_irradiance_radius(q);
    double rs2 = shrink2 < 1.0f ? (double)(float)(r2 * shrink2) : r2, s = 0.0;
    *r_out = sqrt(r2);
    for (size_t i = 0; i < pf_kdtree_size(global); i++) {
        float d2 = pf_len2(pf_sub(pf_photon_pos(&ph[i]), x));
        if (ph[i].pos[0] > side_x && d2 < rs2 && pf_photon_normal_agrees(&ph[i], n, PF_NORMAL_AGREE))
            s += ph[i].power[1];
    }
    double rs = sqrt(rs2), w = (double)x.x - (double)face_x, cut = 0.0;
    if (w < rs)
        cut = rs2 * acos(w / rs) - w * sqrt(rs2 - w * w);
    return s / (M_PI * rs2 - cut);
}

/* s_thin_wall_gap's check of one irradiance map irr (estimates over discs
 * shrunk by shrink2): B's floor points (away from the side walls) whose
 * support reaches the wall against the brute-force estimate over B's
 * photons; A's floor points as near the wall give the scale. */
static void s_gap_compare(const char *what, const pf_kdtree_t *global, const pf_kdtree_t *irr, int k, float max_r2,
                          float shrink2, float wall_x, float t)
{
    double got = 0.0, want = 0.0, worst = 0.0, lit_a = 0.0;
    size_t near = 0, near_a = 0;
    const pf_photon_t *q = pf_kdtree_photons(irr);
    for (size_t i = 0; i < pf_kdtree_size(irr); i++) {
        float y = q[i].pos[1], z = q[i].pos[2], w = q[i].pos[0] - wall_x;
        if (!(y < 1e-3f && pf_photon_normal(&q[i]).y > 0.9f && z > 0.2f && z < 0.8f))
            continue;
        if (w < -t && w > -t - 0.05f) {
            lit_a += q[i].power[1];
            near_a++;
        }
        if (!(w > 0.0f && w < 0.05f))
            continue;
        double r, e = s_same_side_irradiance(global, &q[i], wall_x - 0.5f * t, wall_x, shrink2, &r);
        if (!(w < r))
            continue;
        got += q[i].power[1];
        want += e;
        worst = fmax(worst, e > 0.0 ? fabs(q[i].power[1] / e - 1.0) : q[i].power[1] > 0.0f);
        near++;
    }
    double ratio = got / want, scale = (lit_a / (double)(near_a ? near_a : 1)) / (want / (double)(near ? near : 1));
    printf("%s, disc shrunk by %.3f: %zu irradiance points on the dim floor within their support of the wall read "
           "%.4f times the estimate from their side's photons (bound 1 +- 0.01; worst point %+.1f %%); the lit "
           "floor as near the wall is %.0f times brighter\n",
           what, (double)shrink2, near, ratio, 100.0 * worst, scale);
    CHECK(near >= 20, "%s: only %zu irradiance points by the wall", what, near);
    CHECK(scale > 10.0, "%s: the lit side is only %.1f times brighter: the test would prove little", what, scale);
    CHECK(fabs(ratio - 1.0) <= 0.01, "%s, shrink %.3f: the dim side's irradiance by the wall is %.4f times its "
          "photons' estimate", what, (double)shrink2, ratio);
}

/* A room split by a thin wall (1e-3 of the room) that stands on the floor
 * and stops 0.3 short of the ceiling; a point light on side A, low and
 * 0.1 from the wall, so that A's floor by the wall is far brighter than
 * B's, which only light over the wall reaches. The irradiance points on B's
 * floor by the wall must read B's photons alone: their estimate must equal
 * the same estimate over B's photons (brute force), where summing A's
 * photons under the wall (which the normal test keeps: same plane, same
 * normal) reads A's brightness into B, and the final gather carries it onto
 * everything B's floor lights. (s_thin_wall's rooms are closed: no photon
 * reaches room B, so no irradiance point lies there to go wrong.) */
static void s_thin_wall_gap(void)
{
    const float t = 2e-3f, wall_x = 1.0f;
    pf_scene_t *scene = pf_scene_create();
    uint32_t white = stress_material(scene, stress_diffuse("white", 0.8f, 0.0f));
    stress_box(scene, pf_v3(0, 0, 0), pf_v3(2, 1, 1), white, 1);
    /* Through the floor and the side walls a little: no coplanar faces. */
    stress_box(scene, pf_v3(wall_x - t, -0.01f, -0.01f), pf_v3(wall_x, 0.7f, 1.01f), white, 0);
    stress_point_light(scene, pf_v3(wall_x - t - 0.1f, 0.15f, 0.5f), 1.0f);
    stress_camera(scene, pf_v3(1.9f, 0.5f, 0.5f), pf_v3(1.0f, 0.0f, 0.5f), pf_v3(0, 1, 0), 60.0f);
    pf_error_t err = { { 0 } };
    CHECK(pf_scene_finalize(scene, &err) == PF_OK, "finalize: %s", err.msg);
    pf_settings_t s = stress_settings(scene, 16, 1, 100000, 1);
    const char *what = "thin wall with a gap above";
    stress_job_t job;
    double t0 = pf_now();
    if (stress_job_begin(&job, what, scene, &s) != PF_OK) {
        pf_scene_destroy(&scene);
        return;
    }
    const pf_kdtree_t *global = job.fr.maps.global, *irr = job.fr.maps.irradiance;
    const float r2 = job.fr.maps.global_r2;
    s_gap_compare(what, global, irr, s.global_k, r2, pf_pass_shrink2(job.settings.pass), wall_x, t);
    /* The same points from one thread, bit for bit (the visibility search
     * depends on the point alone, not on the thread's previous point). */
    pf_kdtree_t *one = NULL;
    size_t stride = pf_irradiance_points_stride(pf_kdtree_size(global), &job.settings);
    int rc = pf_irradiance_precompute(global, (int)stride, s.global_k, r2, pf_pass_shrink2(job.settings.pass),
                                      job.fr.accel, 1, &one);
    CHECK(rc == PF_OK && pf_kdtree_size(one) == pf_kdtree_size(irr) &&
              memcmp(pf_kdtree_photons(one), pf_kdtree_photons(irr), pf_kdtree_size(irr) * sizeof(pf_photon_t)) == 0,
          "%s: the irradiance points differ between 1 and %d threads", what, job.settings.threads);
    pf_kdtree_destroy(&one);
    /* A later progressive pass's estimate (the disc shrunk) over the same
     * photons: the seen photons within the shrunk disc alone. */
    rc = pf_irradiance_precompute(global, (int)stride, s.global_k, r2, pf_pass_shrink2(3), job.fr.accel,
                                  job.settings.threads, &one);
    CHECK(rc == PF_OK, "%s: precompute at pass 3: %s", what, pf_strerror(rc));
    if (rc == PF_OK)
        s_gap_compare(what, global, one, s.global_k, r2, pf_pass_shrink2(3), wall_x, t);
    pf_kdtree_destroy(&one);
    printf("%s: %.1f s\n", what, pf_now() - t0);
    stress_job_end(&job);
    pf_scene_destroy(&scene);
}

/* A single sheet (one 2 x 2 quad, kd 0.5, both sides diffuse) lit on
 * both sides: a point light 0.5 above it of intensity 25, another 1 below
 * of intensity 1, so that the top holds about 100 times the photons the
 * underside does, at the same places. The underside's photons come
 * straight from the light below (nothing else is there to bounce them), so
 * its irradiance is I cos / r^2. Estimates on the underside
 * must count the underside's photons alone, in the number (the k nearest)
 * as in the sum: counting the top's in k shrank the disc to the top's
 * density, so the irradiance points' supports left gaps between the
 * underside's points (as far apart as that side's photons), and lookups
 * there read zero. Lookups at 2000 points of the underside's central half
 * must each read a point (none zero), and their mean the analytic mean
 * within 4 % (before: 1324 of them zero, the mean 0.50 of it; now 0 and
 * 0.9999). */
static void s_two_sided_sheet(void)
{
    pf_scene_t *scene = pf_scene_create();
    uint32_t white = stress_material(scene, stress_diffuse("white", 0.5f, 0.0f));
    pf_test_quad(scene, pf_v3(-1, 0, -1), pf_v3(0, 0, 2), pf_v3(2, 0, 0), white); /* normal +y */
    stress_point_light(scene, pf_v3(0, 0.5f, 0), 25.0f);
    stress_point_light(scene, pf_v3(0, -1, 0), 1.0f);
    stress_camera(scene, pf_v3(0, -0.5f, 0.01f), pf_v3(0, 0, 0), pf_v3(0, 0, 1), 60.0f);
    pf_error_t err = { { 0 } };
    CHECK(pf_scene_finalize(scene, &err) == PF_OK, "finalize: %s", err.msg);
    pf_settings_t s = stress_settings(scene, 16, 1, 4000000, 1);
    const char *what = "a sheet lit 100 times more on top";
    stress_job_t job;
    if (stress_job_begin(&job, what, scene, &s) != PF_OK) {
        pf_scene_destroy(&scene);
        return;
    }
    /* No photon bounces off a diffuse surface onto another here, so the
     * render skips the gather and makes no points: made here. */
    const pf_photon_maps_t *pm = &job.fr.maps;
    pf_kdtree_t *irr = NULL;
    size_t stride = pf_irradiance_points_stride(pf_kdtree_size(pm->global), &job.settings);
    int rc = pf_irradiance_precompute(pm->global, (int)stride, s.global_k, pm->global_r2, 1.0f, job.fr.accel,
                                      job.settings.threads, &irr);
    CHECK(rc == PF_OK, "%s: precompute: %s", what, pf_strerror(rc));
    pf_rng_t rng = pf_rng_make(7, PF_STREAM_TEST, 0, 0);
    double got = 0.0, want = 0.0;
    int zeros = 0, n = 2000;
    for (int i = 0; i < n; i++) {
        pf_vec3 p = pf_v3(pf_rng_float(&rng) - 0.5f, 0.0f, pf_rng_float(&rng) - 0.5f);
        pf_vec3 e = pf_irradiance_lookup(irr, pm->irradiance_r2, job.fr.accel, p, pf_v3(0, -1, 0));
        double r2 = 1.0 + (double)pf_len2(p);
        zeros += e.y == 0.0f;
        got += e.y;
        want += 1.0 / (r2 * sqrt(r2)); /* I cos / r^2 with cos = 1 / r */
    }
    printf("%s: %d of %d lookups on its underside read zero; their mean %.4f times the analytic\n", what, zeros, n,
           got / want);
    CHECK(zeros == 0, "%s: %d of %d underside lookups read zero (supports with gaps)", what, zeros, n);
    CHECK(fabs(got / want - 1.0) < 0.04, "%s: the underside reads %.4f times its irradiance", what, got / want);
    pf_kdtree_destroy(&irr);
    stress_job_end(&job);
    pf_scene_destroy(&scene);
}

/* An irradiance lookup whose nearest point stands behind a post (a thin
 * box 1 high between them) must read the next nearest that it sees, not
 * zero (where the points are sparse, under a table among chairs' legs,
 * zeros darkened whole regions); with the post around both points (none
 * seen) it reads zero. */
static void s_lookup_behind_post(void)
{
    pf_scene_t *scene = pf_scene_create();
    uint32_t white = stress_material(scene, stress_diffuse("white", 0.5f, 0.0f));
    pf_test_quad(scene, pf_v3(-2, 0, -2), pf_v3(0, 0, 4), pf_v3(4, 0, 0), white); /* the floor, normal +y */
    stress_box(scene, pf_v3(0.09f, 0, -0.3f), pf_v3(0.11f, 1, 0.3f), white, 0);  /* the post, across x = 0.1 */
    stress_point_light(scene, pf_v3(0, 3, 0), 1.0f);
    pf_error_t err = { { 0 } };
    CHECK(pf_scene_finalize(scene, &err) == PF_OK, "finalize: %s", err.msg);
    pf_accel_t *accel = pf_accel_create(scene, &err);
    CHECK(accel != NULL, "accel: %s", err.msg);
    if (!accel) {
        pf_scene_destroy(&scene);
        return;
    }
    const pf_vec3 at[3] = { { 0.2f, 0, 0 }, { -0.25f, 0, 0 }, { -0.6f, 0, 0 } }; /* behind, seen, seen but farther */
    pf_photon_t *pts = malloc(3 * sizeof *pts);
    PF_CHECK(pts != NULL);
    for (int i = 0; i < 3; i++) {
        float r = 0.8f, v = (float)(i + 1);
        uint32_t support;
        memcpy(&support, &r, sizeof support);
        pts[i] = (pf_photon_t){ { at[i].x, at[i].y, at[i].z }, { v, v, v }, support, pf_oct_encode(pf_v3(0, 1, 0)) };
    }
    pf_kdtree_t *irr = pf_kdtree_build(&pts, 3);
    PF_CHECK(irr != NULL);
    pf_vec3 e = pf_irradiance_lookup(irr, 4.0f, accel, pf_v3(0, 0, 0), pf_v3(0, 1, 0));
    CHECK(e.x == 2.0f, "behind a post: the lookup read %g, not the nearest point it sees (2)", (double)e.x);
    e = pf_irradiance_lookup(irr, 4.0f, accel, pf_v3(0.3f, 0, 0), pf_v3(0, 1, 0));
    CHECK(e.x == 1.0f, "in front of the post: the nearest point (1), read %g", (double)e.x);
    pf_kdtree_destroy(&irr);
    pf_accel_destroy(&accel);
    pf_scene_destroy(&scene);
}

/* The camera inside a closed, opaque box; the lights outside. */
static void s_camera_in_box(void)
{
    pf_scene_t *scene = pf_scene_create();
    uint32_t white = stress_material(scene, stress_diffuse("white", 0.8f, 0.0f));
    uint32_t light = stress_material(scene, stress_diffuse("light", 0.0f, 10.0f));
    stress_box(scene, pf_v3(-2, -1, -2), pf_v3(2, 3, 2), white, 1);   /* a room */
    stress_box(scene, pf_v3(-0.3f, 0, -0.3f), pf_v3(0.3f, 0.6f, 0.3f), white, 0); /* a closed crate in it */
    pf_test_quad(scene, pf_v3(-0.5f, 2.9f, -0.5f), pf_v3(1, 0, 0), pf_v3(0, 0, 1), light);
    stress_point_light(scene, pf_v3(0.31f, 0.3f, 0), 1.0f); /* 1 cm from the crate's side */
    stress_camera(scene, pf_v3(0.05f, 0.3f, 0.1f), pf_v3(0.3f, 0.2f, -0.2f), pf_v3(0, 1, 0), 120.0f);
    pf_error_t err = { { 0 } };
    CHECK(pf_scene_finalize(scene, &err) == PF_OK, "finalize: %s", err.msg);
    pf_settings_t s = stress_settings(scene, 32, 4, 40000, 16);
    pf_image_t img;
    stress_job_t job;
    if (stress_job_begin(&job, "camera in a closed box", scene, &s) == PF_OK) {
        stress_job_render(&job, "camera in a closed box", PF_TERM_ALL, &img);
        double maxv = stress_max(&img);
        printf("camera inside a closed crate, lights outside: brightest channel %.3g (bound 0)\n", maxv);
        if (maxv != 0.0)
            s_leak_terms("camera in a closed box", &job);
        CHECK(maxv == 0.0, "camera in a closed box sees light: %g", maxv);
        pf_image_free(&img);
        stress_job_end(&job);
    }
    pf_scene_destroy(&scene);
}

void stress_test_geometry(void)
{
    s_grazing();
    s_glass_furnace();
    s_light_in_glass(0.0f, 1);
    s_light_in_glass(0.24f, 0);
    s_thin_wall(2e-4f);
    s_thin_wall(2e-6f);
    s_thin_wall_gap();
    s_two_sided_sheet();
    s_lookup_behind_post();
    s_camera_in_box();
}

/* ------------------------------------------------------------------------ */
/* degenerate input                                                          */
/* ------------------------------------------------------------------------ */

/* pf_scene_load with stderr captured: returns the scene (or NULL with err)
 * and the warning lines the load printed. */
static pf_scene_t *s_load_captured(const char *path, pf_error_t *err, int *nwarn, char *first, size_t cap)
{
    fflush(stderr);
    char tmpl[] = "/tmp/pf_stress_log_XXXXXX";
    int fd = mkstemp(tmpl);
    PF_CHECK(fd >= 0);
    int saved = dup(STDERR_FILENO);
    PF_CHECK(saved >= 0 && dup2(fd, STDERR_FILENO) >= 0);
    pf_scene_t *scene = pf_scene_load(path, err);
    fflush(stderr);
    PF_CHECK(dup2(saved, STDERR_FILENO) >= 0);
    close(saved);
    close(fd);
    *nwarn = 0;
    first[0] = '\0';
    FILE *f = fopen(tmpl, "r");
    char line[2048];
    while (f && fgets(line, sizeof line, f)) {
        if (strstr(line, "warning: ")) {
            if ((*nwarn)++ == 0)
                snprintf(first, cap, "%s", strstr(line, "warning: "));
        }
        fputs(line, stdout); /* keep what the user would have seen in the test log */
    }
    if (f)
        fclose(f);
    remove(tmpl);
    size_t len = strlen(first);
    if (len && first[len - 1] == '\n')
        first[len - 1] = '\0';
    return scene;
}

typedef struct s_bad_case {
    const char *file;     /* under tests/data/stress/ */
    const char *expect;   /* error: the message's "file:line:" prefix; NULL: loads */
    int warnings;         /* warning lines expected when it loads */
    const char *warn_has; /* text the one warning must hold (when warnings == 1) */
    size_t min_photons;   /* global photons that must be stored (of 2000 emitted) */
    const char *same_as;  /* a case whose scene this one scales: same mean and photon count within 1 % */
} s_bad_case_t;

/* One case of the degenerate group: loads cases[i] and checks its error,
 * or its warnings and its render; the mean and photon count of a loaded
 * case go to means[i] and stored[i], for the cases that name it same_as. */
static void s_degenerate_case(const s_bad_case_t *cases, size_t i, double *means, size_t *stored)
{
    const s_bad_case_t *c = &cases[i];
    char path[256], first[2048];
    snprintf(path, sizeof path, "tests/data/stress/%s", c->file);
    pf_error_t err = { { 0 } };
    int nwarn;
    printf("-- %s\n", path);
    pf_scene_t *scene = s_load_captured(path, &err, &nwarn, first, sizeof first);
    if (c->expect) {
        printf("%s: %s\n", c->file, scene ? "loaded" : err.msg);
        CHECK(scene == NULL, "%s: accepted, expected an error", c->file);
        CHECK(strncmp(err.msg, c->expect, strlen(c->expect)) == 0, "%s: error '%s' does not start with '%s'",
              c->file, err.msg, c->expect);
        pf_scene_destroy(&scene);
        return;
    }
    CHECK(scene != NULL, "%s: refused: %s", c->file, err.msg);
    if (!scene)
        return;
    printf("%s: loaded with %d warning line%s%s%s\n", c->file, nwarn, nwarn == 1 ? "" : "s", nwarn ? ": " : "",
           first);
    CHECK(nwarn == c->warnings, "%s: %d warning lines, expected %d", c->file, nwarn, c->warnings);
    if (c->warn_has)
        CHECK(strstr(first, c->warn_has) != NULL, "%s: warning '%s' lacks '%s'", c->file, first, c->warn_has);
    pf_settings_t s = stress_settings(scene, 16, 1, 2000, 2);
    s.caustic_photons = 2000;
    pf_image_t img;
    stress_job_t job;
    if (stress_job_begin(&job, c->file, scene, &s) == PF_OK) {
        stress_job_render(&job, c->file, PF_TERM_ALL, &img);
        const pf_photon_maps_t maps = job.fr.maps;
        const pf_photon_stats_t st = job.stats;
        /* Non-finite power must be refused where it enters (the photon
         * tracer), not stored and left for the image's filter to hide. */
        size_t bad = stress_bad_photons(maps.global) + stress_bad_photons(maps.caustic) +
                     stress_bad_photons(maps.irradiance);
        printf("%s: rendered, mean %.4g; %zu photons stored, %llu rejected, %zu stored with non-finite or "
               "negative power (bound 0)\n",
               c->file, stress_mean(&img), pf_kdtree_size(maps.global) + pf_kdtree_size(maps.caustic),
               (unsigned long long)st.rejected, bad);
        CHECK(bad == 0, "%s: %zu photons or irradiance points with non-finite or negative power", c->file, bad);
        CHECK(pf_kdtree_size(maps.global) >= c->min_photons, "%s: %zu global photons stored, expected >= %zu",
              c->file, pf_kdtree_size(maps.global), c->min_photons);
        means[i] = stress_mean(&img);
        stored[i] = pf_kdtree_size(maps.global);
        for (size_t j = 0; c->same_as && j < i; j++) {
            if (strcmp(cases[j].file, c->same_as) != 0)
                continue;
            double mr = means[i] / means[j], pr = (double)stored[i] / (double)stored[j];
            printf("%s against %s: mean ratio %.4f, stored-photon ratio %.4f (bounds 1 +- 0.01)\n", c->file,
                   c->same_as, mr, pr);
            CHECK(fabs(mr - 1.0) <= 0.01 && fabs(pr - 1.0) <= 0.01,
                  "%s renders unlike %s: mean ratio %.4f, stored-photon ratio %.4f", c->file, c->same_as, mr, pr);
        }
        pf_image_free(&img);
        stress_job_end(&job);
    }
    pf_scene_destroy(&scene);
}

void stress_test_degenerate(void)
{
    /* The room cases (a 2 x 2 floor under a downward lamp) store about 1100
     * of 2000 global photons; the rest leave past the floor's edge. Under a
     * point light 2 above it, the floor holds about a tenth of all directions. */
    static const s_bad_case_t cases[] = {
        /* Skipped with one warning line; the rest renders. */
        { "zero-area.obj", NULL, 1, "zero-area.obj: skipped 4 degenerate triangles", 1000, NULL },
        { "huge.obj", NULL, 1, "huge.obj: skipped 1 degenerate triangle", 1000, "zero-area.obj" },
        { "far-triangle.obj", NULL, 1, "far-triangle.obj: skipped 1 degenerate triangle", 1000, "zero-area.obj" },
        { "huge.ply", NULL, 1, "huge.ply: skipped 1 degenerate triangle", 1, NULL },
        { "huge-quad.json", NULL, 1, "huge-quad.json: skipped 2 degenerate triangles", 1000, NULL },
        /* Large or small but legal: loads without a word and renders. The
         * tiny room is zero-area.obj's room scaled by 1e-6. */
        { "distant-sphere.json", NULL, 0, NULL, 100, NULL },
        { "bright-light.json", NULL, 0, NULL, 0, NULL },
        { "tiny.obj", NULL, 0, NULL, 1000, "zero-area.obj" },
        /* Rejected with an error naming the file and line. */
        { "nan-vertex.obj", "tests/data/stress/nan-vertex.obj:6:", 0, NULL, 0, NULL },
        { "inf-vertex.obj", "tests/data/stress/inf-vertex.obj:5:", 0, NULL, 0, NULL },
        { "overflow-vertex.obj", "tests/data/stress/overflow-vertex.obj:4:", 0, NULL, 0, NULL },
        { "inf-normal.obj", "tests/data/stress/inf-normal.obj:6:", 0, NULL, 0, NULL },
        { "nan.ply", "tests/data/stress/nan.ply:13:", 0, NULL, 0, NULL },
        { "inf.ply", "tests/data/stress/inf.ply:11:", 0, NULL, 0, NULL },
        { "overflow-sphere.json", "tests/data/stress/overflow-sphere.json:6:", 0, NULL, 0, NULL },
        { "overflow-light.json", "tests/data/stress/overflow-light.json:8:", 0, NULL, 0, NULL },
        { "huge-scale.json", "tests/data/stress/huge-scale.json:7:", 0, NULL, 0, NULL },
        { "far-light.json", "tests/data/stress/far-light.json:11:", 0, NULL, 0, NULL },
        { "far-sphere.json", "tests/data/stress/far-sphere.json:8:", 0, NULL, 0, NULL },
        { "far-camera.json", "tests/data/stress/far-camera.json:4:", 0, NULL, 0, NULL },
    };
    /* Results of the loaded cases, for same_as. */
    double means[sizeof cases / sizeof *cases] = { 0 };
    size_t stored[sizeof cases / sizeof *cases] = { 0 };
    for (size_t i = 0; i < sizeof cases / sizeof *cases; i++)
        s_degenerate_case(cases, i, means, stored);
}

