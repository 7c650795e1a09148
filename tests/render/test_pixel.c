/* test_pixel.c: where camera samples land in their pixel (the pixel filter)
 * and the emitters' edges (render/pixel.c), in-process.
 *
 *   parse     pf_pixel_filter_parse's accepted and refused specs.
 *   filter    each filter's marginal against its density: the positions of
 *             stratified u through pf_pixel_filter keep their order (the
 *             strata survive), their histogram matches the box-tent
 *             convolution bin by bin, and their mean and variance are the
 *             box's plus the tent's.
 *   edges     a tilted emitting quad (radiance 10) on black, seen straight
 *             on, emitted term only, 4 camera samples per pixel: every
 *             pixel must be within 0.08 Le of the brute-force value (2304
 *             stratified rays per pixel through the same filter, each tested
 *             against the quad in closed form). A pixel across the edge at
 *             4 samples is off by up to 0.5 Le without the edge samples (one
 *             sample is Le / 4); the image's sum must agree within 0.2 % (no
 *             bias). Run for the box, box+tent:0.5 and tent:1. */
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "base/log.h"
#include "coordinator/job.h"
#include "image/image.h"
#include "render/pixel_impl.h"
#include "render/render.h"
#include "scene/camera.h"
#include "scene/scene.h"

#include "check.h"
#include "scenes_gen.h"

static void s_parse(void)
{
    static const struct {
        const char *spec;
        float box, tent;
    } ok[] = {
        { "box", 1.0f, 0.0f },          { "tent", 0.0f, 1.0f },     { "tent:0.5", 0.0f, 0.5f },
        { "box+tent:0.5", 1.0f, 0.5f }, { "tent:1+box:2", 2.0f, 1.0f }, { "box:0+tent:1.5", 0.0f, 1.5f },
    };
    for (size_t i = 0; i < sizeof ok / sizeof *ok; i++) {
        float b = -1.0f, t = -1.0f;
        int rc = pf_pixel_filter_parse(ok[i].spec, &b, &t);
        CHECK(rc == PF_OK && b == ok[i].box && t == ok[i].tent, "parse '%s': rc %d, box %g tent %g", ok[i].spec, rc,
              (double)b, (double)t);
    }
    static const char *const bad[] = { "", "gauss", "tent:", "tent:5", "tent:-1", "box+box", "box:0",
                                       "tent:0+box:0", "box+tent+box", "tent:1x", "box+" };
    for (size_t i = 0; i < sizeof bad / sizeof *bad; i++) {
        float b = 7.0f, t = 7.0f;
        int rc = pf_pixel_filter_parse(bad[i], &b, &t);
        CHECK(rc != PF_OK && b == 7.0f && t == 7.0f, "parse '%s' refused, untouched (rc %d)", bad[i], rc);
    }
}

/* The box (width b) and tent (radius t) convolution's density at x. */
static double s_density(double x, double b, double t)
{
    if (t == 0.0)
        return fabs(x) < 0.5 * b ? 1.0 / b : 0.0;
    double n = 4000, sum = 0.0; /* the box's mean of the tent, numerically */
    if (b == 0.0)
        return fmax(0.0, 1.0 - fabs(x) / t) / t;
    for (int i = 0; i < n; i++) {
        double y = x - 0.5 * b + b * (i + 0.5) / n;
        sum += fmax(0.0, 1.0 - fabs(y) / t) / t;
    }
    return sum / n;
}

static void s_filter(void)
{
    static const float f[][2] = { { 1.0f, 0.5f }, { 0.0f, 1.0f }, { 2.0f, 0.0f }, { 1.0f, 1.0f }, { 0.5f, 1.5f } };
    enum { N = 200000, BINS = 40 };
    for (size_t k = 0; k < sizeof f / sizeof *f; k++) {
        pf_settings_t s = pf_settings_default();
        s.filter_box = f[k][0];
        s.filter_tent = f[k][1];
        double half = 0.5 * s.filter_box + s.filter_tent, mean = 0.0, var = 0.0;
        double hist[BINS] = { 0 };
        float prev = -INFINITY;
        int ordered = 1;
        for (int i = 0; i < N; i++) {
            float x = ((float)i + 0.5f) / (float)N, y = x;
            pf_pixel_filter(&s, &x, &y);
            ordered &= x >= prev && x == y;
            prev = x;
            double d = (double)x - 0.5;
            mean += d / N;
            var += d * d / N;
            int bin = (int)((d + half) / (2.0 * half) * BINS);
            hist[bin < 0 ? 0 : bin >= BINS ? BINS - 1 : bin] += 1.0 / N;
        }
        CHECK(ordered, "filter box %g tent %g: stratified u keep their order", (double)f[k][0], (double)f[k][1]);
        double want = (double)f[k][0] * f[k][0] / 12.0 + (double)f[k][1] * f[k][1] / 6.0;
        CHECK(fabs(mean) < 1e-4 && fabs(var - want) < 1e-3 * want + 1e-6,
              "filter box %g tent %g: mean %.2e (0), variance %.5f (%.5f)", (double)f[k][0], (double)f[k][1], mean,
              var, want);
        double worst = 0.0;
        for (int i = 0; i < BINS; i++) {
            double lo = -half + 2.0 * half * i / BINS, w = 2.0 * half / BINS, p = 0.0;
            for (int j = 0; j < 16; j++)
                p += s_density(lo + w * (j + 0.5) / 16, f[k][0], f[k][1]) * w / 16;
            worst = fmax(worst, fabs(hist[i] - p));
        }
        CHECK(worst < 2e-3, "filter box %g tent %g: histogram within 2e-3 of the density per bin (worst %.2e)",
              (double)f[k][0], (double)f[k][1], worst);
    }
}

/* The quad: centre (0, 0, 0) in the plane z = 0, facing +z, half-sides
 * 0.6 x 0.35, turned by 7 degrees about z. */
#define S_LE 10.0f
static const float s_angle = 7.0f * 3.14159265f / 180.0f;

static int s_in_quad(pf_ray_t r)
{
    if (!(r.d.z < 0.0f))
        return 0;
    float t = -r.o.z / r.d.z;
    float x = r.o.x + t * r.d.x, y = r.o.y + t * r.d.y;
    float u = cosf(s_angle) * x + sinf(s_angle) * y, v = -sinf(s_angle) * x + cosf(s_angle) * y;
    return fabsf(u) < 0.6f && fabsf(v) < 0.35f;
}

static void s_edges(const char *spec)
{
    enum { SIZE = 32 };
    pf_scene_t *scene = pf_scene_create();
    PF_CHECK(scene != NULL);
    pf_material_t m = pf_material_default("light");
    m.kd = pf_v3s(0.0f);
    m.le = pf_v3s(S_LE);
    uint32_t mat = (uint32_t)pf_scene_add_material(scene, &m);
    float c = cosf(s_angle), s = sinf(s_angle);
    pf_vec3 e1 = pf_v3(1.2f * c, 1.2f * s, 0.0f), e2 = pf_v3(-0.7f * s, 0.7f * c, 0.0f);
    pf_test_quad(scene, pf_sub(pf_v3s(0.0f), pf_scale(pf_add(e1, e2), 0.5f)), e1, e2, mat);
    scene->camera = (pf_camera_desc_t){ .pos = pf_v3(0.0f, 0.0f, 3.0f), .look_at = pf_v3s(0.0f),
                                        .up = pf_v3(0.0f, 1.0f, 0.0f), .vfov_deg = 30.0f };
    scene->has_camera = 1;
    pf_error_t err = { { 0 } };
    CHECK(pf_scene_finalize(scene, &err) == PF_OK, "finalize: %s", err.msg);
    pf_settings_t st = scene->settings;
    st.width = st.height = SIZE;
    st.spp = 4;
    st.photons = st.caustic_photons = 1000;
    st.threads = 0;
    CHECK(pf_pixel_filter_parse(spec, &st.filter_box, &st.filter_tent) == PF_OK, "filter %s", spec);
    pf_image_t image = { 0, 0, NULL }, *img = &image; /* allocated by the render */
    pf_job_summary_t sum;
    int rc = pf_job_render_local(scene, &st, PF_TERM_EMITTED, 0, img, &sum, &err);
    CHECK(rc == PF_OK, "render: %s", err.msg);
    pf_camera_t cam = pf_camera_make(&scene->camera, SIZE, SIZE);
    double worst = 0.0, total = 0.0, want_total = 0.0;
    int edge_px = 0;
    enum { K = 48 };
    for (int py = 0; py < SIZE && rc == PF_OK; py++)
        for (int px = 0; px < SIZE; px++) {
            int hits = 0;
            for (int j = 0; j < K; j++)
                for (int i = 0; i < K; i++) {
                    float jx = ((float)i + 0.5f) / K, jy = ((float)j + 0.5f) / K;
                    pf_pixel_filter(&st, &jx, &jy);
                    hits += s_in_quad(pf_camera_ray(&cam, (float)px + jx, (float)py + jy));
                }
            double want = S_LE * hits / (double)(K * K);
            double got = img->rgb[3 * ((size_t)py * SIZE + (size_t)px)];
            edge_px += hits > 0 && hits < K * K;
            worst = fmax(worst, fabs(got - want));
            total += got;
            want_total += want;
        }
    CHECK(edge_px > 60, "%s: %d pixels on the quad's edge", spec, edge_px);
    CHECK(worst < 0.08 * S_LE, "%s: every pixel within 0.08 Le of brute force (worst %.3f Le)", spec,
          worst / S_LE);
    printf("# %s: %d edge pixels, worst %.3f Le, sum %.5f of brute force's\n", spec, edge_px, worst / S_LE,
           total / want_total);
    CHECK(fabs(total / want_total - 1.0) < 2e-3, "%s: the image's sum within 0.2 %% (%.5f)", spec,
          total / want_total);
    pf_image_free(img);
    pf_scene_destroy(&scene);
}

int main(void)
{
    pf_log_set_level(PF_LOG_WARN);
    s_parse();
    s_filter();
    s_edges("box");
    s_edges("box+tent:0.5");
    s_edges("tent:1");
    return pf_test_finish();
}
