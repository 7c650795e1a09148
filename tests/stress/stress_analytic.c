/* stress_analytic.c: the stress groups with an answer known in closed form
 * (test_stress.c lists their bounds; docs/stress.md says why they hold):
 * the furnace, a diffuse plane under a point light, and the Cornell scenes
 * moved, scaled and rotated, which must render as they do in place. Called
 * from the test's main thread; the renders spread over OpenMP threads. */
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "base/log.h"
#include "image/metrics.h"
#include "load/load.h"
#include "render/render.h"

#include "scenes_gen.h"
#include "stress.h"

/* ------------------------------------------------------------------------ */
/* furnace                                                                   */
/* ------------------------------------------------------------------------ */

/* A closed sphere with emission Le and albedo a, camera inside: radiance is
 * Le / (1 - a) everywhere (the "furnace"). The mean over the image must be
 * within 1 %; the photons stored must carry Phi / (1 - a) in all, Phi = pi A Le
 * the emitted flux, within 4 sigma of the photon pass's own noise. */
void stress_test_furnace(void)
{
    /* High albedos store ~1 / (1 - a) photons per emitted one (300 per
     * photon at 0.99 would cost minutes at the low albedos' count), so they
     * emit fewer and precompute irradiance at fewer of them: the gather reads
     * the nearest point, whose spacing stays far below the sphere's size. */
    static const struct {
        float a;
        uint64_t photons;
        int stride;
    } cases[] = { { 0.2f, 60000, 4 }, { 0.5f, 60000, 4 }, { 0.9f, 40000, 8 }, { 0.99f, 30000, 16 } };
    for (size_t i = 0; i < sizeof cases / sizeof *cases; i++) {
        float a = cases[i].a, le = 1.0f;
        pf_scene_t *scene = pf_scene_create();
        uint32_t mat = stress_material(scene, stress_diffuse("furnace", a, le));
        pf_test_inward_sphere(scene, 4, 1.0f, mat);
        stress_camera(scene, pf_v3(0.1f, 0.05f, 0), pf_v3(1, 0.3f, 0.2f), pf_v3(0, 1, 0), 90.0f);
        pf_error_t err = { { 0 } };
        CHECK(pf_scene_finalize(scene, &err) == PF_OK, "finalize: %s", err.msg);
        pf_settings_t s = stress_settings(scene, 24, 1, cases[i].photons, 32);
        s.irradiance_stride = cases[i].stride;
        char what[64];
        snprintf(what, sizeof what, "furnace a=%.2f", a);
        pf_image_t img;
        stress_job_t job;
        double t0 = pf_now();
        if (stress_job_begin(&job, what, scene, &s) == PF_OK) {
            stress_job_render(&job, what, PF_TERM_ALL, &img);
            const pf_photon_stats_t st = job.stats;
            double secs = pf_now() - t0;
            double expect = le / (1.0 - a), mean = stress_mean(&img);
            double within = stress_within(&img, expect, 0.10);
            double phi = PF_PI * stress_area(scene, mat) * le, flux = stress_map_power(job.fr.maps.global);
            double flux_expect = phi / (1.0 - a);
            /* Each emitted photon is stored a geometric number of times (mean
             * 1 / (1 - a), relative standard deviation sqrt(a)) with constant
             * power, so the total's relative sigma is sqrt(a / N). */
            double sigma = sqrt(a / (double)s.photons);
            printf("%s: mean %.5f expected %.5f (ratio %.4f, bound 1 +- 0.01); %.1f %% of channels within 10 %%; "
                   "stored flux %.5f expected %.5f (ratio %.4f, sigma %.4f, bound 4 sigma); %llu photons stored; "
                   "%.2f s (trace %.2f, kd-tree %.2f, irradiance %.2f)\n",
                   what, mean, expect, mean / expect, 100.0 * within, flux, flux_expect, flux / flux_expect, sigma,
                   (unsigned long long)st.global_stored, secs, st.trace_s, st.build_s, st.irradiance_s);
            /* The photons' own noise moves the image with them: emission plus
             * direct light (Le (1 + a)) come from light sampling, the rest from
             * the photons. Scaled by the stored flux's ratio, the expectation
             * isolates the density estimate and the gather from photon noise. */
            double fr = flux / flux_expect, direct = le * (1.0 + a);
            double corrected = direct + (expect - direct) * fr;
            printf("%s: mean against the expectation scaled by the stored flux: ratio %.4f (bound 1 +- 0.005)\n",
                   what, mean / corrected);
            CHECK(fabs(mean / expect - 1.0) < 0.01, "%s: mean radiance %.5f, expected %.5f within 1%%", what, mean,
                  expect);
            CHECK(fabs(mean / corrected - 1.0) < 0.005, "%s: mean radiance %.5f, flux-scaled expectation %.5f", what,
                  mean, corrected);
            CHECK(within >= 0.98, "%s: only %.1f %% of channels within 10 %% of %.4f", what, 100.0 * within, expect);
            CHECK(fabs(flux / flux_expect - 1.0) < 4.0 * sigma, "%s: stored flux %.5f, expected %.5f", what, flux,
                  flux_expect);
            CHECK(st.rejected == 0, "%s: %llu photons rejected for bad power", what, (unsigned long long)st.rejected);
            pf_image_free(&img);
            stress_job_end(&job);
        }
        pf_scene_destroy(&scene);
    }
}

void stress_test_plane(void)
{
    stress_plane_t pl = { .kd = 0.5, .intensity = 3.0, .half = 3.0, .light = { 0.3f, 1.0f, -0.2f } };
    pf_scene_t *scene = pf_scene_create();
    uint32_t mat = stress_material(scene, stress_diffuse("plane", (float)pl.kd, 0.0f));
    float h = (float)pl.half;
    pf_test_quad(scene, pf_v3(-h, 0, -h), pf_v3(0, 0, 2 * h), pf_v3(2 * h, 0, 0), mat); /* normal +y */
    stress_point_light(scene, pl.light, (float)pl.intensity);
    stress_camera(scene, pf_v3(0, 2.5f, 3.5f), pf_v3(0, 0, 0), pf_v3(0, 1, 0), 60.0f);
    pf_error_t err = { { 0 } };
    CHECK(pf_scene_finalize(scene, &err) == PF_OK, "finalize: %s", err.msg);
    pf_settings_t s = stress_settings(scene, 48, 16, 200000, 8);
    pf_image_t direct, full, pm;
    int ok = stress_render("plane direct", scene, &s, PF_TERM_DIRECT, &direct, NULL) == PF_OK;
    if (ok) {
        size_t lit;
        stress_plane_compare("plane direct", &pl, scene, &direct, 1e-3, 1e-3, &lit);
        CHECK(lit > 1000, "plane: the view holds only %zu lit pixels", lit);
    }
    /* The full render adds nothing: gather rays from a lone plane leave into
     * the void, and there is no caustic map. So it is the direct image, bit
     * for bit (the gather draws its random numbers after direct light). */
    if (ok && stress_render("plane full", scene, &s, PF_TERM_ALL, &full, NULL) == PF_OK) {
        size_t n = (size_t)full.width * (size_t)full.height * 3;
        double maxdiff = 0.0;
        for (size_t k = 0; k < n; k++)
            maxdiff = fmax(maxdiff, fabs((double)full.rgb[k] - direct.rgb[k]));
        printf("plane full render: largest difference from the direct term %.3g (bound 0)\n", maxdiff);
        CHECK(maxdiff == 0.0, "plane: the full render differs from direct light by up to %g", maxdiff);
        pf_image_free(&full);
    }
    /* The photon map's own estimate (global map, no gather): kd / pi times
     * the k-nearest irradiance. Compared on the mean over pixels whose plane
     * point lies well inside the plane (a disc cut by the plane's edge reads
     * low); the k-NN estimate's noise averages out there, its bias (the
     * irradiance's curvature across the disc) is below 2 %. */
    if (ok && stress_render("plane photon map", scene, &s, PF_TERM_PHOTONMAP, &pm, NULL) == PF_OK) {
        pf_camera_t cam = pf_camera_make(&scene->camera, pm.width, pm.height);
        double sum_r = 0.0, sum_a = 0.0;
        for (int py = 0; py < pm.height; py++)
            for (int px = 0; px < pm.width; px++) {
                pf_ray_t r = pf_camera_ray(&cam, px + 0.5f, py + 0.5f);
                if (!(r.d.y < 0.0f))
                    continue;
                float t = -r.o.y / r.d.y;
                if (fabsf(r.o.x + t * r.d.x) > 0.6f * h || fabsf(r.o.z + t * r.d.z) > 0.6f * h)
                    continue;
                double lo, hi, mean;
                stress_plane_pixel(&pl, &cam, px, py, &lo, &hi, &mean);
                sum_r += pm.rgb[3 * ((size_t)py * (size_t)pm.width + (size_t)px)];
                sum_a += mean;
            }
        double ratio = sum_r / sum_a;
        printf("plane photon-map estimate: mean ratio to analytic %.4f over the plane's inner 60 %% (bound 1 +- "
               "0.02)\n",
               ratio);
        CHECK(fabs(ratio - 1.0) <= 0.02, "plane: photon-map radiance ratio %.4f", ratio);
        pf_image_free(&pm);
    }
    if (ok)
        pf_image_free(&direct);
    pf_scene_destroy(&scene);
}

/* ------------------------------------------------------------------------ */
/* invariance                                                                */
/* ------------------------------------------------------------------------ */

/* Moves every position, normal, radius, light and the camera by xf (a
 * similarity with uniform scale `scale`). Point-light intensity scales by
 * scale^2 so irradiance I / d^2 stays the same; area lights keep their
 * radiance (their power grows with their area by itself). */
static void s_transform_scene(pf_scene_t *scene, const pf_xform_t *xf, float scale)
{
    for (size_t mi = 0; mi < scene->nmeshes; mi++) {
        pf_mesh_t *m = &scene->meshes[mi];
        for (size_t v = 0; v < m->nverts; v++) {
            m->pos[v] = pf_xform_point(xf, m->pos[v]);
            if (m->nrm)
                m->nrm[v] = pf_xform_normal(xf, m->nrm[v]);
        }
    }
    for (size_t i = 0; i < scene->nspheres; i++) {
        scene->spheres[i].center = pf_xform_point(xf, scene->spheres[i].center);
        scene->spheres[i].radius *= scale;
    }
    for (size_t i = 0; i < scene->nlights; i++) {
        pf_light_t *l = &scene->lights[i];
        l->pos = pf_xform_point(xf, l->pos);
        l->dir = pf_norm(pf_xform_vector(xf, l->dir));
        l->intensity = pf_scale(l->intensity, scale * scale);
    }
    pf_camera_desc_t *c = &scene->camera;
    c->pos = pf_xform_point(xf, c->pos);
    c->look_at = pf_xform_point(xf, c->look_at);
    c->up = pf_norm(pf_xform_vector(xf, c->up));
}

/* A rotation by deg degrees about the unit axis (Rodrigues), computed in double. */
static pf_xform_t s_rotation(pf_vec3 axis, double deg)
{
    double a = deg * M_PI / 180.0, c = cos(a), s = sin(a), t = 1.0 - c;
    double x = axis.x, y = axis.y, z = axis.z;
    double r[3][3] = { { t * x * x + c, t * x * y - s * z, t * x * z + s * y },
                       { t * x * y + s * z, t * y * y + c, t * y * z - s * x },
                       { t * x * z - s * y, t * y * z + s * x, t * z * z + c } };
    pf_xform_t xf = pf_xform_identity();
    for (int i = 0; i < 3; i++)
        for (int j = 0; j < 3; j++)
            xf.m[i][j] = (float)r[i][j];
    return xf;
}

typedef struct s_variant {
    const char *name;
    pf_xform_t xf;
    float scale;
} s_variant_t;

/* Loads a scene for the invariance test; with_point adds a point light
 * (so that the s^2 intensity rule is exercised as well as area lights). */
static pf_scene_t *s_load_variant(const char *path, int with_point, const s_variant_t *v)
{
    pf_error_t err = { { 0 } };
    pf_scene_t *scene = pf_scene_load(path, &err);
    CHECK(scene != NULL, "load %s: %s", path, err.msg);
    if (!scene)
        return NULL;
    if (with_point)
        stress_point_light(scene, pf_v3(0.4f, 1.6f, 0.3f), 1.5f);
    if (v)
        s_transform_scene(scene, &v->xf, v->scale);
    /* Finalize again: the moved scene must pass validation too. */
    CHECK(pf_scene_finalize(scene, &err) == PF_OK, "finalize moved %s: %s", path, err.msg);
    return scene;
}

static void s_invariance_scene(const char *path, int with_point, double max_relmse, double max_lum)
{
    pf_scene_t *base = s_load_variant(path, with_point, NULL);
    if (!base)
        return;
    pf_vec3 lo, hi;
    pf_scene_bounds(base, &lo, &hi);
    float diag = pf_len(pf_sub(hi, lo));
    pf_settings_t s = stress_settings(base, 48, 4, 60000, 12);
    s.caustic_photons = 60000;
    /* The automatic search radii follow the axis-aligned bounds, which a
     * rotation changes; fix them (as the defaults, 10 % and 1 % of the
     * diagonal) and scale them with the scene. */
    float gr = 0.1f * diag, cr = 0.01f * diag;
    s.global_radius = gr;
    s.caustic_radius = cr;
    pf_image_t ref, other;
    char what[160];
    snprintf(what, sizeof what, "%s%s", path, with_point ? " + point light" : "");
    if (stress_render(what, base, &s, PF_TERM_ALL, &ref, NULL) != PF_OK) {
        pf_scene_destroy(&base);
        return;
    }
    CHECK(stress_mean(&ref) > 0.01, "%s: the reference render is black", what);
    /* The noise floor: the same scene with another seed. The transformed
     * renders share the seed, so they must sit far below it. */
    pf_settings_t s2 = s;
    s2.seed = 2;
    pf_image_t ref_small;
    PF_CHECK(pf_image_downsample(&ref, 4, &ref_small) == PF_OK);
    if (stress_render(what, base, &s2, PF_TERM_ALL, &other, NULL) == PF_OK) {
        pf_metrics_t m, mb;
        pf_error_t err;
        pf_image_t small;
        PF_CHECK(pf_metrics_compare(&other, &ref, &m, &err) == PF_OK);
        PF_CHECK(pf_image_downsample(&other, 4, &small) == PF_OK);
        PF_CHECK(pf_metrics_compare(&small, &ref_small, &mb, &err) == PF_OK);
        printf("%s: seed 2 against seed 1 (noise floor): relMSE %.2e, %.2e downsampled, luminance ratio %.5f\n",
               what, m.relmse, mb.relmse, m.lum_ratio);
        pf_image_free(&small);
        pf_image_free(&other);
    }
    pf_scene_destroy(&base);

    pf_vec3 axis = pf_norm(pf_v3(1, 2, 3));
    s_variant_t variants[] = {
        { "scale 1e-3", { { { 1e-3f, 0, 0, 0 }, { 0, 1e-3f, 0, 0 }, { 0, 0, 1e-3f, 0 } } }, 1e-3f },
        { "scale 1e3", { { { 1e3f, 0, 0, 0 }, { 0, 1e3f, 0, 0 }, { 0, 0, 1e3f, 0 } } }, 1e3f },
        { "translate x 1e4", { { { 1, 0, 0, 1e4f }, { 0, 1, 0, 0 }, { 0, 0, 1, 0 } } }, 1.0f },
        { "translate y 1e4", { { { 1, 0, 0, 0 }, { 0, 1, 0, 1e4f }, { 0, 0, 1, 0 } } }, 1.0f },
        { "translate z 1e4", { { { 1, 0, 0, 0 }, { 0, 1, 0, 0 }, { 0, 0, 1, 1e4f } } }, 1.0f },
        { "rotate 37 deg about (1,2,3)", s_rotation(axis, 37.0), 1.0f },
    };
    for (size_t i = 0; i < sizeof variants / sizeof *variants; i++) {
        const s_variant_t *v = &variants[i];
        pf_scene_t *scene = s_load_variant(path, with_point, v);
        if (!scene)
            continue;
        pf_settings_t sv = s;
        sv.global_radius = gr * v->scale;
        sv.caustic_radius = cr * v->scale;
        char vw[224];
        snprintf(vw, sizeof vw, "%s, %s", what, v->name);
        double secs;
        if (stress_render(vw, scene, &sv, PF_TERM_ALL, &other, &secs) == PF_OK) {
            pf_metrics_t m, mb;
            pf_error_t err = { { 0 } };
            pf_image_t small;
            CHECK(pf_metrics_compare(&other, &ref, &m, &err) == PF_OK, "compare: %s", err.msg);
            PF_CHECK(pf_image_downsample(&other, 4, &small) == PF_OK);
            CHECK(pf_metrics_compare(&small, &ref_small, &mb, &err) == PF_OK, "compare: %s", err.msg);
            printf("%s: relMSE %.2e at %dx%d, %.2e at %dx%d (bound %.1e), luminance ratio %.5f (bound 1 +- %.3f), "
                   "%.1f s\n",
                   vw, m.relmse, ref.width, ref.height, mb.relmse, small.width, small.height, max_relmse, m.lum_ratio,
                   max_lum, secs);
            CHECK(mb.relmse <= max_relmse, "%s: relMSE %.3g above %.3g", vw, mb.relmse, max_relmse);
            CHECK(fabs(m.lum_ratio - 1.0) <= max_lum, "%s: luminance ratio %.5f", vw, m.lum_ratio);
            pf_image_free(&small);
            pf_image_free(&other);
        }
        pf_scene_destroy(&scene);
    }
    pf_image_free(&ref_small);
    pf_image_free(&ref);
}

void stress_test_invariance(void)
{
    s_invariance_scene("scenes/cornell-box/scene.json", 1, 1.5e-3, 0.02);
    s_invariance_scene("scenes/cornell-spheres/scene.json", 0, 1.5e-3, 0.02);
}

