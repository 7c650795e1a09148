/* test_twosided.c: two-sided area lights (a material's twosided, pbrt-v4's
 * DiffuseAreaLight "twosided") through the light table and the renderer,
 * in-process (ctest `render_twosided`).
 *
 *   power     a two-sided quad emits twice the power of the same quad
 *             one-sided (2 pi A lum(Le)): the table's total.
 *   floor     a diffuse floor under a 1 x 1 quad at height 1 whose front
 *             faces up, the camera between them looking down: one-sided,
 *             the floor's direct term is black (exactly); two-sided, it is
 *             the direct term of the same quad turned to face down, within
 *             1 % on the mean (light sampling sees |cos| on the back; the
 *             worst pixel's difference, the noise of 32 spp, is printed).
 *   box       a closed box lit by the two-sided quad in its middle, all
 *             terms (photons, gather, caustics, the light seen from
 *             below): the mean is that of two one-sided quads back to back
 *             (1e-3 apart, the physical equivalent) within 2 %, while the
 *             one-sided quad facing up (its front alone) gives far less. A photon flux that
 *             left the back unpaid (or paid twice) moves the mean by tens
 *             of per cent.
 *   blob      twosided survives the scene blob: the same image bit for bit.
 */
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "coordinator/job.h"
#include "image/image.h"
#include "light/light.h"
#include "proto/sceneblob.h"
#include "render/render.h"
#include "scene/scene.h"

#include "check.h"
#include "scenes_gen.h"

static const float s_le = 5.0f;

static uint32_t s_material(pf_scene_t *sc, float kd, float le, int twosided)
{
    pf_material_t m = pf_material_default("m");
    snprintf(m.name, sizeof m.name, "m%zu", sc->nmats);
    m.kd = pf_v3s(kd);
    m.le = pf_v3s(le);
    m.twosided = (uint32_t)twosided;
    int i = pf_scene_add_material(sc, &m);
    PF_CHECK(i >= 0);
    return (uint32_t)i;
}

/* The light quad's kinds. */
enum { S_DOWN, S_UP, S_UP_TWO, S_BACK_TO_BACK };

/* A unit quad at height y centred over (0, 0), facing down or up. */
static void s_light_quad(pf_scene_t *sc, float y, int up, uint32_t mat)
{
    if (up)
        pf_test_quad(sc, pf_v3(-0.5f, y, -0.5f), pf_v3(0, 0, 1), pf_v3(1, 0, 0), mat);
    else
        pf_test_quad(sc, pf_v3(-0.5f, y, -0.5f), pf_v3(1, 0, 0), pf_v3(0, 0, 1), mat);
}

static void s_light(pf_scene_t *sc, int kind, float y)
{
    switch (kind) {
    case S_DOWN: s_light_quad(sc, y, 0, s_material(sc, 0.5f, s_le, 0)); break;
    case S_UP: s_light_quad(sc, y, 1, s_material(sc, 0.5f, s_le, 0)); break;
    case S_UP_TWO: s_light_quad(sc, y, 1, s_material(sc, 0.5f, s_le, 1)); break;
    default: {
        uint32_t m = s_material(sc, 0.5f, s_le, 0);
        s_light_quad(sc, y - 0.0005f, 0, m);
        s_light_quad(sc, y + 0.0005f, 1, m);
    }
    }
}

static pf_scene_t *s_finish(pf_scene_t *sc)
{
    sc->has_camera = 1;
    pf_error_t err = { { 0 } };
    int rc = pf_scene_finalize(sc, &err);
    CHECK(rc == PF_OK, "finalize: %s", err.msg);
    if (rc != PF_OK)
        pf_scene_destroy(&sc);
    return sc;
}

/* The floor scene: an open floor, the light at height 1, the camera at 0.9 looking down. */
static pf_scene_t *s_floor_scene(int kind)
{
    pf_scene_t *sc = pf_scene_create();
    pf_test_quad(sc, pf_v3(-6, 0, -6), pf_v3(0, 0, 12), pf_v3(12, 0, 0), s_material(sc, 0.5f, 0.0f, 0));
    s_light(sc, kind, 1.0f);
    sc->camera = (pf_camera_desc_t){ .pos = { 0, 0.9f, 0 }, .look_at = { 0, 0, 0 }, .up = { 0, 0, 1 },
                                     .vfov_deg = 60.0f };
    return s_finish(sc);
}

/* The box: 4 x 3 x 4, kd 0.5 inside, the light at height 1.5; the camera
 * near a wall sees the far wall, the floor and the light from below. */
static pf_scene_t *s_box_scene(int kind)
{
    pf_scene_t *sc = pf_scene_create();
    uint32_t w = s_material(sc, 0.5f, 0.0f, 0);
    pf_test_quad(sc, pf_v3(-2, 0, -2), pf_v3(0, 0, 4), pf_v3(4, 0, 0), w);  /* floor, up */
    pf_test_quad(sc, pf_v3(-2, 3, -2), pf_v3(4, 0, 0), pf_v3(0, 0, 4), w);  /* ceiling, down */
    pf_test_quad(sc, pf_v3(-2, 0, -2), pf_v3(4, 0, 0), pf_v3(0, 3, 0), w);  /* z = -2, +z */
    pf_test_quad(sc, pf_v3(-2, 0, 2), pf_v3(0, 3, 0), pf_v3(4, 0, 0), w);   /* z = 2, -z */
    pf_test_quad(sc, pf_v3(-2, 0, -2), pf_v3(0, 3, 0), pf_v3(0, 0, 4), w);  /* x = -2, +x */
    pf_test_quad(sc, pf_v3(2, 0, -2), pf_v3(0, 0, 4), pf_v3(0, 3, 0), w);   /* x = 2, -x */
    s_light(sc, kind, 1.5f);
    sc->camera = (pf_camera_desc_t){ .pos = { 0.1f, 0.8f, 1.9f }, .look_at = { 0, 0.7f, -2 }, .up = { 0, 1, 0 },
                                     .vfov_deg = 70.0f };
    return s_finish(sc);
}

static int s_render(const pf_scene_t *sc, int size, int spp, int photons, unsigned terms, pf_image_t *img)
{
    pf_settings_t s = sc->settings;
    s.width = s.height = size;
    s.spp = spp;
    s.photons = photons;
    s.caustic_photons = 1000;
    s.threads = 0;
    pf_job_summary_t sum;
    pf_error_t err = { { 0 } };
    int rc = pf_job_render_local(sc, &s, terms, 0, img, &sum, &err);
    CHECK(rc == PF_OK, "render: %s", err.msg);
    return rc == PF_OK;
}

static double s_mean(const pf_image_t *img)
{
    double m = 0.0;
    size_t n = (size_t)img->width * img->height;
    for (size_t i = 0; i < n; i++)
        m += (img->rgb[3 * i] + img->rgb[3 * i + 1] + img->rgb[3 * i + 2]) / (3.0 * (double)n);
    return m;
}

static void s_test_power(void)
{
    pf_scene_t *one = s_floor_scene(S_UP), *two = s_floor_scene(S_UP_TWO);
    if (one && two) {
        pf_lights_t *a = pf_lights_build(one), *b = pf_lights_build(two);
        CHECK(a && b);
        if (a && b) {
            double pa = pf_lights_power(a), pb = pf_lights_power(b), want = PF_PI * 1.0 * s_le;
            printf("power: one-sided %.5f (pi A Le = %.5f), two-sided %.5f\n", pa, want, pb);
            CHECK(fabs(pa / want - 1.0) < 1e-5, "one-sided power %g, want %g", pa, want);
            CHECK(fabs(pb / (2.0 * want) - 1.0) < 1e-5, "two-sided power %g, want %g", pb, 2.0 * want);
        }
        pf_lights_destroy(&a);
        pf_lights_destroy(&b);
    }
    pf_scene_destroy(&one);
    pf_scene_destroy(&two);
}

static void s_test_floor(void)
{
    const int size = 32;
    pf_scene_t *down = s_floor_scene(S_DOWN), *up = s_floor_scene(S_UP), *two = s_floor_scene(S_UP_TWO);
    pf_image_t d, u, t;
    if (!down || !up || !two || !s_render(down, size, 32, 2000, PF_TERM_DIRECT, &d))
        goto out;
    if (s_render(up, size, 4, 2000, PF_TERM_DIRECT, &u)) {
        CHECK(s_mean(&u) == 0.0, "a one-sided light facing away lights the floor: mean %g", s_mean(&u));
        pf_image_free(&u);
    }
    if (s_render(two, size, 32, 2000, PF_TERM_DIRECT, &t)) {
        double a = s_mean(&d), b = s_mean(&t), worst = 0.0;
        for (size_t i = 0; i < (size_t)size * size * 3; i++) {
            double r = fabs(t.rgb[i] / d.rgb[i] - 1.0);
            worst = r > worst ? r : worst;
        }
        printf("floor: direct mean %.5f facing down, %.5f two-sided facing up (ratio %.4f), worst pixel %.3f\n", a, b,
               b / a, worst);
        CHECK(a > 0.01, "the floor is lit (%g)", a);
        CHECK(fabs(b / a - 1.0) < 0.01, "two-sided floor mean %g vs %g", b, a);
        pf_image_free(&t);
    }
    pf_image_free(&d);
out:
    pf_scene_destroy(&down);
    pf_scene_destroy(&up);
    pf_scene_destroy(&two);
}

static void s_test_box(void)
{
    const int size = 32;
    pf_scene_t *two = s_box_scene(S_UP_TWO), *pair = s_box_scene(S_BACK_TO_BACK), *one = s_box_scene(S_UP);
    pf_image_t t, p, o;
    if (!two || !pair || !one || !s_render(two, size, 16, 200000, PF_TERM_ALL, &t))
        goto out;
    if (s_render(pair, size, 16, 200000, PF_TERM_ALL, &p)) {
        if (s_render(one, size, 16, 200000, PF_TERM_ALL, &o)) {
            double a = s_mean(&t), b = s_mean(&p), c = s_mean(&o);
            printf("box: mean %.5f two-sided, %.5f back to back (ratio %.4f), %.5f one-sided up (ratio %.4f)\n", a, b,
                   a / b, c, c / b);
            CHECK(fabs(a / b - 1.0) < 0.02, "the two-sided box's mean %g differs from back to back's %g", a, b);
            CHECK(c / b < 0.8, "the front alone gives %g of back to back's light: the test cannot tell", c / b);
            pf_image_free(&o);
        }
        pf_image_free(&p);
    }
    pf_image_free(&t);
out:
    pf_scene_destroy(&two);
    pf_scene_destroy(&pair);
    pf_scene_destroy(&one);
}

static void s_test_blob(void)
{
    const int size = 16;
    pf_scene_t *sc = s_box_scene(S_UP_TWO);
    if (!sc)
        return;
    pf_buf_t b = { 0 };
    CHECK(pf_sceneblob_write(sc, &b) == PF_OK);
    pf_error_t err = { { 0 } };
    pf_scene_t *back = pf_sceneblob_read(b.data, b.len, &err);
    CHECK(back != NULL, "blob: %s", err.msg);
    CHECK(back && back->mats[back->meshes[6].mat[0]].twosided == 1, "twosided lost in the blob");
    pf_image_t a, c;
    if (back && s_render(sc, size, 4, 5000, PF_TERM_ALL, &a)) {
        if (s_render(back, size, 4, 5000, PF_TERM_ALL, &c)) {
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
    s_test_power();
    s_test_floor();
    s_test_box();
    s_test_blob();
    return pf_test_finish();
}
