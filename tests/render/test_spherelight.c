/* test_spherelight.c: an emissive analytic sphere (light/spherelight.h)
 * through the whole renderer, in-process.
 *
 *   floor     a diffuse floor (kd 0.5) under a sphere of radius 0.5 and
 *             radiance 4, its centre 2 above the floor, the camera under the
 *             sphere looking down: every pixel of the direct term must be
 *             kd / pi E, E = pi Le (r / d)^2 cos beta (the sphere's light
 *             outside it is a point source's of intensity pi r^2 Le), within
 *             2 %, and their mean within 0.2 % (64 spp of 2 light samples,
 *             the pixel centre alone; what remains is cos beta's spread over
 *             the cone). The same sphere tessellated (64 x 32, thousands of
 *             triangle lights sampled by area) misses by up to 60 % on a
 *             pixel at this count (printed).
 *   seen      the camera looking at the sphere sees Le at its centre
 *             (emitted term).
 *   glossy    a rough conductor floor (alpha 0.1) under the sphere: its
 *             direct term (light samples and the BSDF ray, by MIS with the
 *             pdf pf_lights_pdf_at gives a hit on the sphere) has the mean of
 *             the tessellated sphere's, within 1.5 % (the tessellation's own
 *             area is 0.3 % short); a wrong pdf for hits skews the MIS sum.
 *   blob      the scene through the scene blob (what workers get) renders
 *             the same image bit for bit.
 * Before this change pf_scene_finalize refused an emissive sphere. */
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "coordinator/job.h"
#include "image/image.h"
#include "proto/sceneblob.h"
#include "render/render.h"
#include "scene/camera.h"
#include "scene/scene.h"

#include "check.h"
#include "scenes_gen.h"

#define PI_D 3.14159265358979323846

static const pf_vec3 s_c = { 0.3f, 2.0f, 0.2f };
static const float s_r = 0.5f, s_le = 4.0f;

static uint32_t s_material(pf_scene_t *sc, pf_mat_type type, float kd, float le)
{
    pf_material_t m = pf_material_default("m");
    snprintf(m.name, sizeof m.name, "m%zu", sc->nmats);
    m.type = type;
    m.kd = pf_v3s(kd);
    m.le = pf_v3s(le);
    if (type == PF_MAT_CONDUCTOR) {
        m.eta = pf_v3(0.2f, 0.9f, 1.1f);
        m.k = pf_v3(3.9f, 2.4f, 2.1f);
        m.alpha = 0.1f;
    }
    int i = pf_scene_add_material(sc, &m);
    PF_CHECK(i >= 0);
    return (uint32_t)i;
}

/* The sphere tessellated as the pbrt loader does (64 x 32), every triangle wound outward. */
static void s_uv_sphere(pf_scene_t *sc, uint32_t mat)
{
    const int nphi = 64, nth = 32;
    pf_mesh_t m = { 0 };
    snprintf(m.name, sizeof m.name, "uvsphere");
    m.nverts = (size_t)(nth + 1) * (nphi + 1);
    m.pos = malloc(m.nverts * sizeof *m.pos);
    m.idx = malloc(3 * 2 * (size_t)nth * nphi * sizeof *m.idx);
    m.mat = malloc(2 * (size_t)nth * nphi * sizeof *m.mat);
    PF_CHECK(m.pos && m.idx && m.mat);
    for (int i = 0; i <= nth; i++)
        for (int j = 0; j <= nphi; j++) {
            double th = PI_D * i / nth, ph = 2.0 * PI_D * j / nphi;
            m.pos[i * (nphi + 1) + j] = pf_add(s_c, pf_v3((float)(s_r * sin(th) * cos(ph)), (float)(s_r * cos(th)),
                                                          (float)(s_r * sin(th) * sin(ph))));
        }
    for (int i = 0; i < nth; i++)
        for (int j = 0; j < nphi; j++) {
            uint32_t a = (uint32_t)(i * (nphi + 1) + j), b = a + 1, d = a + (uint32_t)(nphi + 1), e = d + 1;
            uint32_t tri[2][3] = { { a, d, b }, { d, e, b } };
            for (int k = 0; k < 2; k++) {
                pf_vec3 p0 = m.pos[tri[k][0]], p1 = m.pos[tri[k][1]], p2 = m.pos[tri[k][2]];
                pf_vec3 n = pf_cross(pf_sub(p1, p0), pf_sub(p2, p0));
                if (pf_len2(n) == 0.0f)
                    continue; /* at a pole */
                if (pf_dot(n, pf_sub(p0, s_c)) < 0.0f) { /* wind it outward */
                    uint32_t t = tri[k][1];
                    tri[k][1] = tri[k][2];
                    tri[k][2] = t;
                }
                memcpy(&m.idx[3 * m.ntris], tri[k], sizeof tri[k]);
                m.mat[m.ntris++] = mat;
            }
        }
    PF_CHECK(pf_scene_add_mesh(sc, &m) == PF_OK);
}

/* The floor (material type floor) under the sphere (analytic or not), the
 * camera at (0, 1, 0) looking down, or at the sphere when look_at_sphere. */
static pf_scene_t *s_scene(pf_mat_type floor, int tessellated, int look_at_sphere)
{
    pf_scene_t *sc = pf_scene_create();
    uint32_t lm = s_material(sc, PF_MAT_DIFFUSE, 0.0f, s_le);
    if (tessellated) {
        s_uv_sphere(sc, lm);
    } else {
        pf_sphere_t s = { .center = s_c, .radius = s_r, .mat = lm };
        PF_CHECK(pf_scene_add_sphere(sc, &s) == PF_OK);
    }
    pf_test_quad(sc, pf_v3(-6, 0, -6), pf_v3(0, 0, 12), pf_v3(12, 0, 0), s_material(sc, floor, 0.5f, 0.0f));
    sc->camera = look_at_sphere ? (pf_camera_desc_t){ .pos = { 0.3f, 0.5f, 3.0f }, .look_at = s_c, .up = { 0, 1, 0 },
                                                      .vfov_deg = 10.0f }
                                : (pf_camera_desc_t){ .pos = { 0, 1, 0 }, .look_at = { 0, 0, 0 }, .up = { 0, 0, 1 },
                                                      .vfov_deg = 60.0f };
    sc->has_camera = 1;
    sc->settings.filter_box = 0.02f; /* the pixel centre alone, nearly */
    sc->settings.filter_tent = 0.0f;
    pf_error_t err = { { 0 } };
    int rc = pf_scene_finalize(sc, &err);
    CHECK(rc == PF_OK, "finalize: %s", err.msg);
    if (rc != PF_OK)
        pf_scene_destroy(&sc);
    return sc;
}

static int s_render(const pf_scene_t *sc, int size, int spp, unsigned terms, pf_image_t *img)
{
    pf_settings_t s = sc->settings;
    s.width = s.height = size;
    s.spp = spp;
    s.photons = s.caustic_photons = 1000;
    s.threads = 0;
    pf_job_summary_t sum;
    pf_error_t err = { { 0 } };
    int rc = pf_job_render_local(sc, &s, terms, 0, img, &sum, &err);
    CHECK(rc == PF_OK, "render: %s", err.msg);
    return rc == PF_OK;
}

/* Pixels against kd / pi E on the floor: the worst and the mean ratio. */
static void s_floor_ratio(const pf_scene_t *sc, const pf_image_t *img, int size, double *worst, double *mean)
{
    pf_camera_t cam = pf_camera_make(&sc->camera, size, size);
    *worst = 0.0;
    *mean = 0.0;
    for (int y = 0; y < size; y++)
        for (int x = 0; x < size; x++) {
            pf_ray_t r = pf_camera_ray(&cam, (float)x + 0.5f, (float)y + 0.5f);
            pf_vec3 p = pf_madd(r.o, r.d, -r.o.y / r.d.y), d = pf_sub(s_c, p);
            double d2 = pf_dot(d, d), E = PI_D * s_le * s_r * s_r / d2 * d.y / sqrt(d2);
            double got = img->rgb[3 * ((size_t)y * size + (size_t)x) + 1], ratio = got / (0.5 / PI_D * E);
            *worst = fmax(*worst, fabs(ratio - 1.0));
            *mean += ratio / (size * size);
        }
}

static void s_test_floor(void)
{
    const int size = 24;
    pf_scene_t *sc = s_scene(PF_MAT_DIFFUSE, 0, 0), *tess = s_scene(PF_MAT_DIFFUSE, 1, 0);
    pf_image_t img, timg;
    if (sc && tess && s_render(sc, size, 64, PF_TERM_DIRECT, &img)) {
        double worst, mean, tworst = 0.0, tmean = 0.0;
        s_floor_ratio(sc, &img, size, &worst, &mean);
        if (s_render(tess, size, 64, PF_TERM_DIRECT, &timg)) {
            s_floor_ratio(tess, &timg, size, &tworst, &tmean);
            pf_image_free(&timg);
        }
        printf("floor: pixels / analytic: mean %.5f, worst off by %.3f %% (tessellated: mean %.5f, worst %.1f %%)\n",
               mean, 100.0 * worst, tmean, 100.0 * tworst);
        CHECK(worst < 0.02, "a floor pixel off by %.3f %% from kd / pi E", 100.0 * worst);
        CHECK(fabs(mean - 1.0) < 0.002, "the floor's pixels are %.5f of kd / pi E on average", mean);
        pf_image_free(&img);
    }
    pf_scene_destroy(&sc);
    pf_scene_destroy(&tess);
}

static void s_test_seen(void)
{
    const int size = 9;
    pf_scene_t *sc = s_scene(PF_MAT_DIFFUSE, 0, 1);
    pf_image_t img;
    if (sc && s_render(sc, size, 1, PF_TERM_EMITTED, &img)) {
        float got = img.rgb[3 * (4 * size + 4) + 1];
        CHECK(got == s_le, "the sphere's centre pixel shows %g, its Le is %g", got, s_le);
        pf_image_free(&img);
    }
    pf_scene_destroy(&sc);
}

static double s_mean(const pf_image_t *img)
{
    double m = 0.0;
    size_t n = (size_t)img->width * img->height;
    for (size_t i = 0; i < n; i++)
        m += img->rgb[3 * i + 1] / (double)n;
    return m;
}

static void s_test_glossy(void)
{
    const int size = 32;
    pf_scene_t *sc = s_scene(PF_MAT_CONDUCTOR, 0, 0), *tess = s_scene(PF_MAT_CONDUCTOR, 1, 0);
    pf_image_t img, timg;
    if (sc && tess && s_render(sc, size, 16, PF_TERM_DIRECT, &img)) {
        if (s_render(tess, size, 64, PF_TERM_DIRECT, &timg)) {
            double a = s_mean(&img), b = s_mean(&timg);
            printf("glossy floor: mean %.5f, tessellated sphere %.5f (ratio %.4f)\n", a, b, a / b);
            CHECK(fabs(a / b - 1.0) < 0.015, "the glossy floor's mean %.5f differs from the tessellated sphere's %.5f",
                  a, b);
            pf_image_free(&timg);
        }
        pf_image_free(&img);
    }
    pf_scene_destroy(&sc);
    pf_scene_destroy(&tess);
}

static void s_test_blob(void)
{
    const int size = 16;
    pf_scene_t *sc = s_scene(PF_MAT_CONDUCTOR, 0, 0);
    if (!sc)
        return;
    pf_buf_t b = { 0 };
    CHECK(pf_sceneblob_write(sc, &b) == PF_OK);
    pf_error_t err = { { 0 } };
    pf_scene_t *back = pf_sceneblob_read(b.data, b.len, &err);
    CHECK(back != NULL, "blob: %s", err.msg);
    pf_image_t a, c;
    if (back && s_render(sc, size, 4, PF_TERM_ALL, &a)) {
        if (s_render(back, size, 4, PF_TERM_ALL, &c)) {
            CHECK(memcmp(a.rgb, c.rgb, (size_t)size * size * 3 * sizeof *a.rgb) == 0,
                  "the scene read from its blob renders another image");
            pf_image_free(&c);
        }
        pf_image_free(&a);
    }
    pf_scene_destroy(&back);
    pf_buf_free(&b);
    pf_scene_destroy(&sc);
}

int main(void)
{
    s_test_floor();
    s_test_seen();
    s_test_glossy();
    s_test_blob();
    return pf_test_finish();
}
