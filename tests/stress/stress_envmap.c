/* stress_envmap.c: the image-based sky's furnace (group "envmap";
 * docs/stress.md). A map of one constant value L must render as the
 * constant sky of radiance L does, within noise, though its direct light
 * draws directions from the map's distribution (uniform over the sphere
 * here) rather than cosine-weighted, and its photons take directions from
 * it:
 *   - a diffuse sphere of albedo a alone: the background reads L exactly,
 *     the sphere a L (mean within 1.5 %), the stored flux 4 pi^2 r^2 L
 *     within 4 sigma, for the equal-area and the lat-long mapping;
 *   - the sphere over a diffuse ground (so that indirect light and shadows
 *     count): the direct and indirect terms' means within 2 % and 4 % of
 *     the constant sky's;
 *   - a skylight: a closed black room lit through a hole in its ceiling by a
 *     map 30 times brighter near the horizon (which the walls hide) than
 *     overhead. Light samples mostly go to the horizon and hit the walls;
 *     the gather rays, cosine-distributed, go through the hole far more
 *     often, and MIS between them must make the floor's light both right
 *     (its mean within 4 % of the exact value: the hole's form factor; the
 *     black walls add no indirect light) and at least twice less noisy per
 *     pixel than light sampling alone (the direct term rendered by itself). */
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "render/render.h"
#include "scenes_gen.h"
#include "stress.h"

#define S_L 0.8f

/* sky: 0 constant, else 1 + a pf_envmap_mapping; ground: a slab under the sphere. */
static pf_scene_t *s_scene(int sky, int ground)
{
    pf_scene_t *scene = pf_scene_create();
    stress_sphere(scene, pf_v3(0, 0, 0), 1.0f, stress_material(scene, stress_diffuse("sphere", 0.6f, 0.0f)));
    if (ground)
        stress_box(scene, pf_v3(-3, -1.3f, -3), pf_v3(3, -1.0f, 3),
                   stress_material(scene, stress_diffuse("ground", 0.5f, 0.0f)), 0);
    pf_light_t l = { .type = PF_LIGHT_INFINITE, .intensity = pf_v3s(S_L) };
    if (sky) {
        pf_envmap_t m;
        memset(&m, 0, sizeof m);
        snprintf(m.name, sizeof m.name, "constant");
        m.mapping = sky - 1;
        m.width = m.mapping == PF_ENVMAP_EQUALAREA ? 16 : 32;
        m.height = 16;
        m.rgb = malloc((size_t)m.width * m.height * 3 * sizeof *m.rgb);
        PF_CHECK(m.rgb != NULL);
        for (int k = 0; k < m.width * m.height * 3; k++)
            m.rgb[k] = 1.0f;
        /* turned, so that the frame is exercised: the map's z is the world's x */
        const double frame[9] = { 0, 0, 1, 1, 0, 0, 0, 1, 0 };
        PF_CHECK(pf_envmap_set_frame(&m, frame) == PF_OK);
        l.map = (uint32_t)pf_scene_add_envmap(scene, &m) + 1;
    }
    PF_CHECK(pf_scene_add_light(scene, &l) == PF_OK);
    stress_camera(scene, pf_v3(0.3f, 0.8f, 4.0f), pf_v3(0, -0.3f, 0), pf_v3(0, 1, 0), 50.0f);
    pf_error_t err = { { 0 } };
    CHECK(pf_scene_finalize(scene, &err) == PF_OK, "finalize: %s", err.msg);
    return scene;
}

/* Whether the camera's rays through a pixel's 5 x 5 points all hit the unit
 * sphere at the origin (1), all miss it (0), or differ (-1). */
static int s_sphere_class(const pf_camera_t *cam, int px, int py)
{
    int cls = -2;
    for (int j = 0; j < 5; j++)
        for (int i = 0; i < 5; i++) {
            pf_ray_t ray = pf_camera_ray(cam, (float)px + i / 4.0f, (float)py + j / 4.0f);
            float along = -pf_dot(ray.o, ray.d);
            int c = pf_len2(ray.o) - along * along < 0.999f;
            cls = cls == -2 || cls == c ? c : -1;
        }
    return cls;
}

/* The sphere alone: the background L, the sphere a L, the stored flux. */
static void s_test_alone(int sky)
{
    const char *name = sky == 1 + PF_ENVMAP_EQUALAREA ? "envmap furnace (equal-area)" : "envmap furnace (equirect)";
    pf_scene_t *scene = s_scene(sky, 0);
    pf_settings_t s = stress_settings(scene, 64, 16, 200000, 8);
    stress_job_t job;
    if (stress_job_begin(&job, name, scene, &s) != PF_OK) {
        pf_scene_destroy(&scene);
        return;
    }
    double want = 4.0 * PF_PI * PF_PI * S_L, flux = stress_map_power(job.fr.maps.global);
    double big = sqrt(3.0) * 1.01, p = 1.0 / (big * big), sigma = sqrt((1.0 - p) / ((double)s.photons * p));
    pf_image_t full;
    stress_job_render(&job, name, PF_TERM_ALL, &full);
    pf_camera_t cam = pf_camera_make(&scene->camera, full.width, full.height);
    size_t nsky = 0, bad_sky = 0, nsphere = 0;
    double sum = 0.0;
    for (int py = 0; py < full.height; py++)
        for (int px = 0; px < full.width; px++) {
            int cls = s_sphere_class(&cam, px, py);
            float v = full.rgb[3 * ((size_t)py * full.width + px) + 1];
            nsky += cls == 0;
            bad_sky += cls == 0 && v != S_L;
            nsphere += cls == 1;
            sum += cls == 1 ? v : 0.0;
        }
    double mean = sum / (double)nsphere / (0.6 * S_L);
    printf("%s: stored flux / 4 pi^2 r^2 L = %.4f (sigma %.4f, bound 4 sigma); %zu sky pixels L, %zu sphere pixels "
           "of mean / a L %.4f (bound 1 +- 0.015), %zu sky pixels not L\n",
           name, flux / want, sigma, nsky, nsphere, mean, bad_sky);
    CHECK(fabs(flux / want - 1.0) < 4.0 * sigma, "%s: stored flux %.5f, expected %.5f", name, flux, want);
    CHECK(nsky > 1000 && nsphere > 500 && bad_sky == 0 && fabs(mean - 1.0) <= 0.015,
          "%s: %zu sky, %zu sphere pixels (mean %.4f of a L), %zu sky pixels not L", name, nsky, nsphere, mean,
          bad_sky);
    pf_image_free(&full);
    stress_job_end(&job);
    pf_scene_destroy(&scene);
}

/* Over a ground: the map's terms against the constant sky's. */
static void s_test_ground(void)
{
    double means[2][2] = { { 0 } };
    for (int k = 0; k < 2; k++) {
        pf_scene_t *scene = s_scene(k ? 1 + PF_ENVMAP_EQUALAREA : 0, 1);
        pf_settings_t s = stress_settings(scene, 64, 16, 200000, 16);
        stress_job_t job;
        if (stress_job_begin(&job, k ? "envmap ground" : "sky ground", scene, &s) == PF_OK) {
            pf_image_t img;
            stress_job_render(&job, "ground direct", PF_TERM_DIRECT, &img);
            means[k][0] = stress_mean(&img);
            pf_image_free(&img);
            stress_job_render(&job, "ground indirect", PF_TERM_INDIRECT, &img);
            means[k][1] = stress_mean(&img);
            pf_image_free(&img);
            stress_job_end(&job);
        }
        pf_scene_destroy(&scene);
    }
    double rd = means[1][0] / means[0][0], ri = means[1][1] / means[0][1];
    printf("envmap ground: direct %.5f vs constant sky %.5f (ratio %.4f, bound 1 +- 0.02), indirect %.5f vs %.5f "
           "(ratio %.4f, bound 1 +- 0.04)\n",
           means[1][0], means[0][0], rd, means[1][1], means[0][1], ri);
    CHECK(fabs(rd - 1.0) <= 0.02 && fabs(ri - 1.0) <= 0.04, "envmap ground: direct ratio %.4f, indirect %.4f", rd, ri);
    CHECK(means[0][1] > 0.01 * means[0][0], "envmap ground: indirect light %.5f is too small to test", means[0][1]);
}


/* The skylight room (see the top): floor y = 0 (kd 0.5) over [-1, 1]^2,
 * black walls and ceiling at y = 1 with a hole of half side S_HOLE. */
#define S_HOLE 0.25f
static pf_scene_t *s_skylight_scene(void)
{
    pf_scene_t *scene = pf_scene_create();
    uint32_t floor_m = stress_material(scene, stress_diffuse("floor", 0.5f, 0.0f));
    uint32_t black = stress_material(scene, stress_diffuse("black", 0.0f, 0.0f));
    pf_test_quad(scene, pf_v3(-1, 0, -1), pf_v3(0, 0, 2), pf_v3(2, 0, 0), floor_m); /* normal +y */
    for (int k = 0; k < 4; k++) { /* walls, facing in */
        float sx = k == 0 ? -1.0f : k == 1 ? 1.0f : 0.0f, sz = k == 2 ? -1.0f : k == 3 ? 1.0f : 0.0f;
        pf_vec3 o = pf_v3(sx != 0 ? sx : -1, 0, sz != 0 ? sz : -1);
        pf_vec3 along = sx != 0 ? pf_v3(0, 0, 2) : pf_v3(2, 0, 0);
        pf_test_quad(scene, o, pf_v3(0, 1, 0), along, black);
        pf_test_quad(scene, o, along, pf_v3(0, 1, 0), black);
    }
    const float h = S_HOLE; /* the ceiling around the hole, both faces */
    const float r[4][4] = { { -1, -1, 2, 1 - h }, { -1, h, 2, 1 - h }, { -1, -h, 1 - h, 2 * h }, { h, -h, 1 - h, 2 * h } };
    for (int k = 0; k < 4; k++) {
        pf_vec3 o = pf_v3(r[k][0], 1, r[k][1]), ex = pf_v3(r[k][2], 0, 0), ez = pf_v3(0, 0, r[k][3]);
        pf_test_quad(scene, o, ex, ez, black);
        pf_test_quad(scene, o, ez, ex, black);
    }
    pf_envmap_t m;
    memset(&m, 0, sizeof m);
    snprintf(m.name, sizeof m.name, "horizon");
    m.mapping = PF_ENVMAP_EQUIRECT;
    m.width = 64;
    m.height = 32;
    m.rgb = malloc((size_t)m.width * m.height * 3 * sizeof *m.rgb);
    PF_CHECK(m.rgb != NULL);
    for (int y = 0; y < m.height; y++) { /* theta from the light's +z, the world's +y */
        float theta = PF_PI * ((float)y + 0.5f) / (float)m.height;
        float v = theta < PF_PI / 3.0f ? 1.0f : theta < 0.5f * PF_PI ? 30.0f : 0.0f;
        for (int k = 0; k < 3 * m.width; k++)
            m.rgb[3 * (size_t)y * (size_t)m.width + (size_t)k] = v;
    }
    const double frame[9] = { 1, 0, 0, 0, 0, 1, 0, 1, 0 };
    PF_CHECK(pf_envmap_set_frame(&m, frame) == PF_OK);
    pf_light_t l = { .type = PF_LIGHT_INFINITE, .intensity = pf_v3s(1.0f) };
    l.map = (uint32_t)pf_scene_add_envmap(scene, &m) + 1;
    PF_CHECK(pf_scene_add_light(scene, &l) == PF_OK);
    stress_camera(scene, pf_v3(0, 0.9f, 0.95f), pf_v3(0, 0, -0.1f), pf_v3(0, 1, 0), 60.0f);
    pf_error_t err = { { 0 } };
    CHECK(pf_scene_finalize(scene, &err) == PF_OK, "finalize: %s", err.msg);
    return scene;
}

/* The form factor from a floor point to the part of the ceiling plane
 * (height 1) over [0, a] x [0, b] from the point (a, b signed): the
 * point-to-parallel-rectangle formula, odd in a and in b. */
static double s_ff_corner(double a, double b)
{
    double A = sqrt(1.0 + a * a), B = sqrt(1.0 + b * b);
    return (a / A * atan(b / A) + b / B * atan(a / B)) / (2.0 * PF_PI);
}

/* The floor's radiance at (x, z): kd / pi times the irradiance pi F of the
 * hole, every direction through which sees the map's 1 (theta < 60 degrees
 * from anywhere in the room). */
static double s_skylight_want(double x, double z)
{
    double h = S_HOLE;
    double f = s_ff_corner(h - x, h - z) - s_ff_corner(-h - x, h - z) - s_ff_corner(h - x, -h - z) +
               s_ff_corner(-h - x, -h - z);
    return 0.5 * f;
}

/* Over the pixels whose centre sees the floor away from the walls: the mean
 * of img over the mean of the exact radiance, and the rms of each pixel's
 * relative error. */
static void s_skylight_stats(const pf_scene_t *scene, const pf_image_t *img, double *ratio, double *rms)
{
    pf_camera_t cam = pf_camera_make(&scene->camera, img->width, img->height);
    double s = 0.0, sw = 0.0, e2 = 0.0;
    size_t n = 0;
    for (int y = 0; y < img->height; y++)
        for (int x = 0; x < img->width; x++) {
            pf_ray_t r = pf_camera_ray(&cam, x + 0.5f, y + 0.5f);
            if (!(r.d.y < 0.0f))
                continue;
            pf_vec3 p = pf_madd(r.o, r.d, -r.o.y / r.d.y);
            if (fabsf(p.x) > 0.85f || fabsf(p.z) > 0.85f)
                continue;
            double v = img->rgb[3 * ((size_t)y * (size_t)img->width + (size_t)x) + 1], w = s_skylight_want(p.x, p.z);
            s += v, sw += w, e2 += (v / w - 1.0) * (v / w - 1.0), n++;
        }
    *ratio = n ? s / sw : 0.0;
    *rms = n ? sqrt(e2 / (double)n) : 0.0;
}

static void s_test_skylight(void)
{
    pf_scene_t *scene = s_skylight_scene();
    pf_settings_t s = stress_settings(scene, 48, 64, 20000, 1);
    s.gather_filter = 0; /* each sample's gather rays its own */
    stress_job_t job;
    if (stress_job_begin(&job, "skylight", scene, &s) == PF_OK) {
        pf_image_t full, direct;
        stress_job_render(&job, "skylight all", PF_TERM_ALL, &full);
        stress_job_render(&job, "skylight direct", PF_TERM_DIRECT, &direct);
        double rf, ef, rd, ed;
        s_skylight_stats(scene, &full, &rf, &ef);
        s_skylight_stats(scene, &direct, &rd, &ed);
        printf("skylight: floor mean / exact: %.4f with MIS (bound 1 +- 0.04), %.4f light samples alone; per-pixel "
               "rms relative error %.4f vs %.4f (%.2fx less, bound >= 2)\n",
               rf, rd, ef, ed, ed / ef);
        CHECK(fabs(rf - 1.0) <= 0.04, "skylight: floor mean %.4f of the exact value with MIS", rf);
        CHECK(ef > 0.0 && ed >= 2.0 * ef, "skylight: per-pixel rms error %.4f with MIS, %.4f without", ef, ed);
        pf_image_free(&full);
        pf_image_free(&direct);
        stress_job_end(&job);
    }
    pf_scene_destroy(&scene);
}

void stress_test_envmap(void)
{
    s_test_alone(1 + PF_ENVMAP_EQUALAREA);
    s_test_alone(1 + PF_ENVMAP_EQUIRECT);
    s_test_ground();
    s_test_skylight();
}
