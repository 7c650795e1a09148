/* test_camera.c: the camera's rays (scene/camera.c; ctest `camera`).
 *
 * - Pinhole: pf_camera_ray equals the formula the renderer has always used,
 *   bit for bit (every image rendered before the lens depends on it), and
 *   pf_camera_ray_lens with lens_radius 0 is that same ray whatever the lens
 *   sample and focal distance.
 * - fov_shorter: for a portrait image the fov spans the horizontal axis, for
 *   a landscape one the vertical; the edge and corner rays' angles to the
 *   view axis are the ones the fov and the aspect give.
 * - left_handed: pixel x of the left-handed camera sees exactly (bit for
 *   bit) what pixel width - x of the right-handed one sees, and its ray is
 *   the mirror image of the right-handed ray of the same pixel.
 * - Thin lens: every lens sample of one film position meets on the plane in
 *   focus (perpendicular to the view axis, focal_distance along it) at the
 *   point the pinhole ray reaches, within 1e-4 relative; origins lie on the
 *   lens plane within lens_radius of the eye and fill the disc uniformly.
 * - Screen window: a window equal to the default (landscape, portrait with
 *   fov_shorter, and a frame aspect equal to the image's) gives the plain
 *   camera's rays bit for bit; a quadrant window on W x H gives the rays of
 *   that quadrant of the default 2W x 2H camera (pixel x of the crop is
 *   pixel W + x of the big one) within 1e-6, with and without the lens and
 *   left-handed; an off-centre stretched window's rays cross the plane at
 *   distance 1 where xmin + (xmax - xmin) fx / W, ymax - (ymax - ymin) fy / H
 *   times tan(fov / 2) put them; a frame aspect f without a window is
 *   [-f, f] x [-1, 1] (or the portrait one with fov_shorter and f < 1).
 * - pf_scene_finalize refuses bad extras (flags not 0/1, a negative or
 *   non-finite lens radius, a focal distance not > 0 with a lens) naming the
 *   scene's file, and accepts the pinhole's.
 * One thread, no files. */
#include <math.h>
#include <stdint.h>
#include <stdio.h>
#include <string.h>

#include "base/rng.h"
#include "scene/camera.h"

#include "check.h"

static const pf_camera_desc_t s_general = { .pos = { 3, -2, 5 }, .look_at = { -1, 0.5f, 0.2f }, .up = { 0.1f, 1, 0.2f },
                                            .vfov_deg = 50 };

static int s_ray_same(pf_ray_t a, pf_ray_t b) { return memcmp(&a, &b, sizeof a) == 0; }

static double s_angle(pf_vec3 a, pf_vec3 b)
{
    double c = (double)pf_dot(a, b) / ((double)pf_len(a) * (double)pf_len(b));
    return acos(c > 1.0 ? 1.0 : c);
}

/* The pinhole formula, written out here as the renderer had it. */
static pf_ray_t s_formula(const pf_camera_desc_t *d, int w, int h, float fx, float fy)
{
    pf_vec3 f = pf_norm(pf_sub(d->look_at, d->pos));
    pf_vec3 r = pf_norm(pf_cross(f, d->up));
    pf_vec3 u = pf_cross(r, f);
    float t = tanf(0.5f * d->vfov_deg * PF_PI / 180.0f), a = (float)w / (float)h;
    float sx = (2.0f * fx / (float)w - 1.0f) * t * a;
    float sy = (1.0f - 2.0f * fy / (float)h) * t;
    return (pf_ray_t){ d->pos, pf_norm(pf_add(f, pf_add(pf_scale(r, sx), pf_scale(u, sy)))) };
}

static void test_pinhole(void)
{
    const int W = 300, H = 200;
    pf_camera_t cam = pf_camera_make(&s_general, W, H);
    pf_camera_desc_t focused = s_general;
    focused.focal_distance = 3.0f; /* no lens: ignored */
    pf_camera_t cam_f = pf_camera_make(&focused, W, H);
    pf_rng_t r = pf_rng_make(1, PF_STREAM_TEST, 0, 0);
    int same = 0, lens_same = 0, n = 0;
    for (int i = 0; i < 2000; i++, n++) {
        float fx = (float)W * pf_rng_float(&r), fy = (float)H * pf_rng_float(&r);
        pf_ray_t a = pf_camera_ray(&cam, fx, fy);
        same += s_ray_same(a, s_formula(&s_general, W, H, fx, fy));
        float u1 = pf_rng_float(&r), u2 = pf_rng_float(&r);
        lens_same += s_ray_same(a, pf_camera_ray_lens(&cam, fx, fy, u1, u2)) &&
                     s_ray_same(a, pf_camera_ray_lens(&cam_f, fx, fy, u1, u2));
    }
    CHECK(same == n, "pinhole rays equal the formula bit for bit: %d of %d", same, n);
    CHECK(lens_same == n, "lens_radius 0 gives the pinhole ray bit for bit: %d of %d", lens_same, n);
    /* The image centre looks along the view axis; (0, 0) is the top left. */
    pf_ray_t c = pf_camera_ray(&cam, 0.5f * W, 0.5f * H);
    CHECK(s_angle(c.d, cam.forward) < 1e-6, "centre ray along forward");
    pf_ray_t tl = pf_camera_ray(&cam, 0, 0);
    CHECK(pf_dot(tl.d, cam.right) < 0 && pf_dot(tl.d, cam.up) > 0, "pixel (0,0) is the top left");
}

/* Angles (degrees) between the view axis and the rays through the middle of
 * the left edge, the middle of the top edge, and the top-left corner. */
static void s_edge_angles(const pf_camera_desc_t *d, int w, int h, double *horiz, double *vert, double *corner)
{
    pf_camera_t cam = pf_camera_make(d, w, h);
    *horiz = s_angle(pf_camera_ray(&cam, 0, 0.5f * (float)h).d, cam.forward) * 180.0 / M_PI;
    *vert = s_angle(pf_camera_ray(&cam, 0.5f * (float)w, 0).d, cam.forward) * 180.0 / M_PI;
    *corner = s_angle(pf_camera_ray(&cam, 0, 0).d, cam.forward) * 180.0 / M_PI;
}

static double s_deg_atan(double x) { return atan(x) * 180.0 / M_PI; }

static void test_fov_shorter(void)
{
    pf_camera_desc_t d = s_general;
    d.vfov_deg = 60;
    d.fov_shorter = 1;
    const double t = tan(30.0 * M_PI / 180.0), tol = 1e-3;
    double hz, vt, co;
    /* Portrait 200 x 400: the fov spans the horizontal axis. */
    s_edge_angles(&d, 200, 400, &hz, &vt, &co);
    CHECK(fabs(hz - 30.0) < tol, "portrait: half horizontal fov %g, want 30", hz);
    CHECK(fabs(vt - s_deg_atan(2 * t)) < tol, "portrait: half vertical fov %g, want %g", vt, s_deg_atan(2 * t));
    CHECK(fabs(co - s_deg_atan(sqrt(5.0) * t)) < tol, "portrait: corner %g, want %g", co, s_deg_atan(sqrt(5.0) * t));
    /* Landscape 400 x 200: the vertical axis, as without fov_shorter. */
    s_edge_angles(&d, 400, 200, &hz, &vt, &co);
    CHECK(fabs(vt - 30.0) < tol, "landscape: half vertical fov %g, want 30", vt);
    CHECK(fabs(hz - s_deg_atan(2 * t)) < tol, "landscape: half horizontal fov %g, want %g", hz, s_deg_atan(2 * t));
    CHECK(fabs(co - s_deg_atan(sqrt(5.0) * t)) < tol, "landscape: corner %g, want %g", co, s_deg_atan(sqrt(5.0) * t));
    /* Landscape and square images are the vertical-fov camera bit for bit. */
    pf_camera_desc_t v = d;
    v.fov_shorter = 0;
    int same = 1;
    for (int k = 0; k < 2; k++) {
        int w = k ? 256 : 400, h = k ? 256 : 200;
        pf_camera_t a = pf_camera_make(&d, w, h), b = pf_camera_make(&v, w, h);
        for (int y = 0; y <= h; y += 50)
            for (int x = 0; x <= w; x += 50)
                same &= s_ray_same(pf_camera_ray(&a, (float)x, (float)y), pf_camera_ray(&b, (float)x, (float)y));
    }
    CHECK(same, "fov_shorter changes nothing for landscape and square images");
    /* Portrait without fov_shorter: the fov stays vertical. */
    s_edge_angles(&v, 200, 400, &hz, &vt, &co);
    CHECK(fabs(vt - 30.0) < tol && fabs(hz - s_deg_atan(0.5 * t)) < tol, "portrait, vertical fov: %g %g", vt, hz);
}

static void test_left_handed(void)
{
    const int W = 64, H = 48; /* a power-of-two width keeps 2x/W and 2(W-x)/W exact */
    pf_camera_desc_t l = s_general;
    l.left_handed = 1;
    pf_camera_t rc = pf_camera_make(&s_general, W, H), lc = pf_camera_make(&l, W, H);
    CHECK(memcmp(&lc.up, &rc.up, sizeof lc.up) == 0 && memcmp(&lc.forward, &rc.forward, sizeof lc.forward) == 0,
          "left-handed: same up and forward");
    CHECK(pf_dot(lc.right, pf_cross(lc.up, lc.forward)) > 0.999999f, "left-handed right = up x forward");
    int same = 0, mirrored = 0, n = 0;
    for (int y = 0; y < H; y += 5)
        for (int x = 0; x <= W; x++, n++) {
            float fx = (float)x + (x < W ? 0.5f : 0.0f), fy = (float)y + 0.5f;
            pf_ray_t a = pf_camera_ray(&lc, fx, fy);
            same += s_ray_same(a, pf_camera_ray(&rc, (float)W - fx, fy));
            /* The right-handed ray of the same pixel, reflected in the plane of forward and up. */
            pf_vec3 d = pf_camera_ray(&rc, fx, fy).d;
            pf_vec3 m = pf_sub(d, pf_scale(rc.right, 2.0f * pf_dot(d, rc.right)));
            mirrored += pf_len(pf_sub(m, a.d)) < 1e-6f;
        }
    CHECK(same == n, "left-handed pixel x = right-handed pixel W - x, bit for bit: %d of %d", same, n);
    CHECK(mirrored == n, "left-handed ray = mirrored right-handed ray: %d of %d", mirrored, n);
    pf_ray_t tl = pf_camera_ray(&lc, 0, 0);
    CHECK(pf_dot(tl.d, rc.right) > 0 && pf_dot(tl.d, rc.up) > 0, "left-handed pixel (0,0) looks right and up");
}

/* Where ray meets the plane dot(x - pos, forward) = dist. */
static pf_vec3 s_on_plane(const pf_camera_t *cam, pf_ray_t ray, float dist)
{
    double t = ((double)dist - (double)pf_dot(pf_sub(ray.o, cam->pos), cam->forward)) / (double)pf_dot(ray.d, cam->forward);
    return pf_madd(ray.o, ray.d, (float)t);
}

static void test_thin_lens(void)
{
    const int W = 320, H = 240;
    pf_camera_desc_t d = s_general;
    d.lens_radius = 0.25f;
    d.focal_distance = 7.5f;
    for (int hand = 0; hand < 2; hand++) {
        d.left_handed = hand;
        pf_camera_t cam = pf_camera_make(&d, W, H);
        const float px[][2] = { { 160.5f, 120.5f }, { 0.5f, 0.5f }, { 319.5f, 17.5f }, { 40.5f, 239.5f } };
        int meet = 0, radius = 0, plane = 0, unit = 0, n = 0;
        double worst = 0;
        for (size_t p = 0; p < sizeof px / sizeof px[0]; p++) {
            pf_ray_t pin = pf_camera_ray(&cam, px[p][0], px[p][1]);
            pf_vec3 want = s_on_plane(&cam, pin, d.focal_distance);
            double scale = (double)pf_len(pf_sub(want, cam.pos));
            for (int i = 0; i < 16; i++)
                for (int j = 0; j < 16; j++, n++) {
                    float u1 = ((float)i + 0.5f) / 16.0f, u2 = ((float)j + 0.5f) / 16.0f;
                    pf_ray_t r = pf_camera_ray_lens(&cam, px[p][0], px[p][1], u1, u2);
                    pf_vec3 off = pf_sub(r.o, cam.pos);
                    double e = (double)pf_len(pf_sub(s_on_plane(&cam, r, d.focal_distance), want)) / scale;
                    worst = e > worst ? e : worst;
                    meet += e <= 1e-4;
                    radius += pf_len(off) <= d.lens_radius * (1.0f + 1e-6f);
                    plane += fabsf(pf_dot(off, cam.forward)) <= 1e-6f;
                    unit += fabsf(pf_len(r.d) - 1.0f) <= 1e-6f;
                }
        }
        CHECK(meet == n, "%s: lens rays of one pixel meet on the focal plane: %d of %d (worst %.2g relative)",
              hand ? "left" : "right", meet, n, worst);
        CHECK(radius == n && plane == n, "%s: origins on the lens disc: %d, %d of %d", hand ? "left" : "right",
              radius, plane, n);
        CHECK(unit == n, "unit directions: %d of %d", unit, n);
    }
    /* The aperture is filled uniformly: a quarter of the samples of a
     * stratified grid land within half the radius, and their mean is the eye. */
    d.left_handed = 0;
    pf_camera_t cam = pf_camera_make(&d, W, H);
    int inner = 0, n = 0;
    double far = 0;
    pf_vec3 mean = pf_v3s(0.0f);
    for (int i = 0; i < 64; i++)
        for (int j = 0; j < 64; j++, n++) {
            pf_ray_t r = pf_camera_ray_lens(&cam, 100.5f, 50.5f, ((float)i + 0.5f) / 64.0f, ((float)j + 0.5f) / 64.0f);
            float dist = pf_len(pf_sub(r.o, cam.pos));
            inner += dist < 0.5f * d.lens_radius;
            far = dist > far ? dist : far;
            mean = pf_add(mean, pf_sub(r.o, cam.pos));
        }
    double frac = (double)inner / n;
    CHECK(fabs(frac - 0.25) < 0.01, "a quarter of the aperture within half its radius: %.4f", frac);
    CHECK(far > 0.97 * d.lens_radius, "the samples reach the aperture's rim: %g of %g", far, (double)d.lens_radius);
    CHECK(pf_len(pf_scale(mean, 1.0f / (float)n)) < 1e-3f * d.lens_radius, "the lens samples centre on the eye");
    /* A point on the focal plane is sharp, one off it is not: rays of two
     * lens samples through the same pixel part before and after the plane. */
    pf_ray_t a = pf_camera_ray_lens(&cam, 100.5f, 50.5f, 0.1f, 0.5f), b = pf_camera_ray_lens(&cam, 100.5f, 50.5f, 0.9f, 0.5f);
    CHECK(pf_len(pf_sub(s_on_plane(&cam, a, 3.0f), s_on_plane(&cam, b, 3.0f))) > 0.1f, "defocused off the focal plane");
}

/* The screen window, as the header says. */
static void s_window(pf_camera_desc_t *d, float x0, float x1, float y0, float y1)
{
    d->has_window = 1;
    d->window[0] = x0, d->window[1] = x1, d->window[2] = y0, d->window[3] = y1;
}

static int s_same_grid(const pf_camera_desc_t *a, const pf_camera_desc_t *b, int w, int h)
{
    pf_camera_t ca = pf_camera_make(a, w, h), cb = pf_camera_make(b, w, h);
    int same = 1;
    for (int y = 0; y <= h; y += 7)
        for (int x = 0; x <= w; x += 7)
            same &= s_ray_same(pf_camera_ray(&ca, (float)x + 0.25f, (float)y + 0.75f),
                               pf_camera_ray(&cb, (float)x + 0.25f, (float)y + 0.75f));
    return same;
}

/* Where the ray meets the camera's plane at distance 1 along forward, in
 * units of tan_half: (x right, y up). */
static void s_screen(const pf_camera_t *cam, pf_ray_t r, double tan_half, double *x, double *y)
{
    double z = pf_dot(r.d, cam->forward);
    *x = pf_dot(r.d, cam->right) / z / tan_half;
    *y = pf_dot(r.d, cam->up) / z / tan_half;
}

static void test_screen_window(void)
{
    pf_camera_desc_t d = s_general, w = s_general;
    d.fov_shorter = w.fov_shorter = 1;
    s_window(&w, -1.5f, 1.5f, -1.0f, 1.0f);
    CHECK(s_same_grid(&d, &w, 300, 200), "landscape: the default window gives the same rays");
    s_window(&w, -1.0f, 1.0f, -2.0f, 2.0f);
    CHECK(s_same_grid(&d, &w, 200, 400), "portrait, fov_shorter: the default window gives the same rays");
    d.fov_shorter = w.fov_shorter = 0;
    s_window(&w, -0.5f, 0.5f, -1.0f, 1.0f);
    CHECK(s_same_grid(&d, &w, 200, 400), "portrait, vertical fov: the default window gives the same rays");
    w = d;
    w.frame_aspect = 1.5f;
    CHECK(s_same_grid(&d, &w, 300, 200), "the image's frame aspect gives the same rays");
    w.frame_aspect = 2.0f;
    CHECK(!s_same_grid(&d, &w, 300, 200), "another frame aspect changes the rays");

    /* Quadrants of a 2W x 2H image, with the lens and either hand. */
    const int W = 96, H = 64;
    const double t = tan(25.0 * M_PI / 180.0);
    int close = 0, n = 0;
    double worst = 0;
    for (int k = 0; k < 8; k++) {
        pf_camera_desc_t big = s_general;
        big.fov_shorter = 1;
        big.left_handed = k & 1;
        big.lens_radius = (k & 2) ? 0.2f : 0.0f;
        big.focal_distance = 6.0f;
        pf_camera_desc_t small = big;
        int qx = (k >> 2) & 1, qy = k & 1; /* quadrant: left/right, top/bottom */
        float a = 1.5f;
        s_window(&small, qx ? 0.0f : -a, qx ? a : 0.0f, qy ? -1.0f : 0.0f, qy ? 0.0f : 1.0f);
        pf_camera_t cb = pf_camera_make(&big, 2 * W, 2 * H), cs = pf_camera_make(&small, W, H);
        for (int i = 0; i < 300; i++, n++) {
            float fx = (float)(i % 20) * (float)W / 19.0f, fy = (float)(i / 20) * (float)H / 14.0f;
            float u1 = (float)(i % 7) / 7.0f, u2 = (float)(i % 11) / 11.0f;
            pf_ray_t rb = pf_camera_ray_lens(&cb, fx + (float)(qx * W), fy + (float)(qy * H), u1, u2);
            pf_ray_t rs = pf_camera_ray_lens(&cs, fx, fy, u1, u2);
            double e = fmax((double)pf_len(pf_sub(rb.d, rs.d)), (double)pf_len(pf_sub(rb.o, rs.o)));
            worst = fmax(worst, e);
            close += e <= 1e-6;
        }
    }
    CHECK(close == n, "quadrant windows: the big camera's rays within 1e-6: %d of %d (worst %.2g)", close, n, worst);

    /* Off-centre and stretched: the rays cross the plane at distance 1 where the window puts them. */
    pf_camera_desc_t o = s_general;
    o.fov_shorter = 1;
    s_window(&o, -0.3f, 1.1f, -0.2f, 0.5f);
    pf_camera_t co = pf_camera_make(&o, 200, 100);
    int on = 0;
    n = 0;
    for (int y = 0; y <= 100; y += 10)
        for (int x = 0; x <= 200; x += 20, n++) {
            double sx, sy;
            s_screen(&co, pf_camera_ray(&co, (float)x, (float)y), t, &sx, &sy);
            double wx = -0.3 + 1.4 * x / 200.0, wy = 0.5 - 0.7 * y / 100.0;
            on += fabs(sx - wx) < 1e-5 && fabs(sy - wy) < 1e-5;
        }
    CHECK(on == n, "off-centre window: rays where the window puts them: %d of %d", on, n);
    /* A frame aspect without a window: [-f, f] x [-1, 1], or [-1, 1] x [-1/f, 1/f] in portrait. */
    for (int k = 0; k < 2; k++) {
        pf_camera_desc_t f = s_general;
        f.fov_shorter = 1;
        f.frame_aspect = k ? 0.5f : 3.0f;
        pf_camera_t cf = pf_camera_make(&f, 100, 100);
        double x0, y0, x1, y1;
        s_screen(&cf, pf_camera_ray(&cf, 0, 0), t, &x0, &y0);
        s_screen(&cf, pf_camera_ray(&cf, 100, 100), t, &x1, &y1);
        double wx = k ? 1.0 : 3.0, wy = k ? 2.0 : 1.0;
        CHECK(fabs(x0 + wx) < 1e-5 && fabs(y0 - wy) < 1e-5 && fabs(x1 - wx) < 1e-5 && fabs(y1 + wy) < 1e-5,
              "frame aspect %g: corners (%g, %g) (%g, %g), want (-%g, %g) (%g, -%g)", (double)f.frame_aspect, x0, y0,
              x1, y1, wx, wy, wx, wy);
    }
}

/* pf_scene_finalize checks a loaded scene's camera extras and names the file. */
static void test_finalize(void)
{
    struct {
        int shorter, left;
        float lens, focus;
        const char *want; /* NULL: accepted */
    } cases[] = {
        { 0, 0, 0.0f, 0.0f, NULL },
        { 1, 1, 0.1f, 2.0f, NULL },
        { 0, 0, 0.0f, -1.0f, NULL }, /* no lens: the focal distance is not used */
        { 2, 0, 0.0f, 0.0f, "fov_shorter (2) and left_handed (0) must be 0 or 1" },
        { 0, -1, 0.0f, 0.0f, "fov_shorter (0) and left_handed (-1) must be 0 or 1" },
        { 0, 0, -0.1f, 1.0f, "lens radius -0.1 must be >= 0" },
        { 0, 0, NAN, 1.0f, "lens radius nan must be >= 0" },
        { 0, 0, INFINITY, 1.0f, "lens radius inf must be >= 0" },
        { 0, 0, 0.1f, 0.0f, "focal distance 0 must be finite, and > 0 with a lens" },
        { 0, 0, 0.1f, -2.0f, "focal distance -2 must be finite, and > 0 with a lens" },
        { 0, 0, 0.0f, NAN, "focal distance nan must be finite" },
    };
    for (size_t i = 0; i < sizeof cases / sizeof cases[0]; i++) {
        pf_scene_t *sc = pf_scene_create();
        snprintf(sc->path, sizeof sc->path, "lens.json");
        pf_material_t m = pf_material_default("grey");
        pf_scene_add_material(sc, &m);
        pf_sphere_t sp = { .center = pf_v3(0, 0, 0), .radius = 1, .mat = 0 };
        pf_scene_add_sphere(sc, &sp);
        pf_light_t l = { .type = PF_LIGHT_POINT, .pos = pf_v3(0, 3, 0), .intensity = pf_v3s(1) };
        pf_scene_add_light(sc, &l);
        sc->camera = s_general;
        sc->camera.fov_shorter = cases[i].shorter;
        sc->camera.left_handed = cases[i].left;
        sc->camera.lens_radius = cases[i].lens;
        sc->camera.focal_distance = cases[i].focus;
        sc->has_camera = 1;
        pf_error_t err = { 0 };
        int rc = pf_scene_finalize(sc, &err);
        if (!cases[i].want)
            CHECK(rc == PF_OK, "case %zu accepted: %s", i, err.msg);
        else
            CHECK(rc != PF_OK && strncmp(err.msg, "lens.json", 9) == 0 && strstr(err.msg, cases[i].want),
                  "case %zu: got '%s', want 'lens.json...%s'", i, err.msg, cases[i].want);
        pf_scene_destroy(&sc);
    }
}

int main(void)
{
    test_finalize();
    test_pinhole();
    test_fov_shorter();
    test_left_handed();
    test_thin_lens();
    test_screen_window();
    return pf_test_finish();
}
