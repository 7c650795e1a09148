/* test_camwin.c: pbrt-v4's screen window ("screenwindow", "frameaspectratio")
 * through the loader and the renderer (ctest `render_screenwindow`).
 *
 * The scene: the camera looks straight down at emitting squares (radiance 3)
 * on an emitting ground (radiance 1), rendered with the emitted term only,
 * so a camera sample's value is a function of its ray alone, through a box
 * pixel filter of the pixel's size (its samples stay in the pixel).
 *
 * - A screenwindow equal to the default one ([-2, 2] x [-1, 1] for a 2:1
 *   film), and a frameaspectratio equal to the film's, render the same bits
 *   as none, with every term.
 * - Crops: a film of a part of the big image's size whose screenwindow is
 *   that part of the default window (the top-right quadrant, and an
 *   off-centre 16 x 16 square) renders that part of the big image. Samples
 *   are placed by pixel index, so the renders' samples differ; but a pixel
 *   that lies wholly in one square (or on the ground) sees one radiance
 *   whatever its samples. The squares' corners are projected into the big
 *   image's pixels (the pinhole formula, written out here), and every pixel
 *   of the big image and of each crop whose area lies wholly (by 1e-3
 *   pixel) on one side of every edge must be that radiance exactly; the
 *   pixels that straddle an edge are left out.
 * - A frameaspectratio of 1 on the 2:1 film squeezes the default window to
 *   [-1, 1] x [-1, 1]: the image is the big image's middle half (pixels
 *   16 to 47) stretched twice across, judged the same way.
 * Files are written to a temporary folder. */
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <unistd.h>

#include "base/log.h"
#include "coordinator/job.h"
#include "image/image.h"
#include "load/load.h"
#include "render/render.h"
#include "scene/scene.h"

#include "check.h"

static char s_dir[256];

/* The squares' corners (x0, z0, x1, z1), placed off the pixel grid; the
 * last four have every edge 0.05 pixel inside a pixel boundary of the big
 * image (pixels 40.05 to 44.95 and 4.05 to 8.95, and their mirror images
 * 19.05 to 23.95 and 23.05 to 27.95, at 16 / (9.99 tan 20 deg) pixels a
 * unit), so a window misplaced by more than 0.05 pixel either way makes a
 * whole pixel straddle an edge in the quadrant and off-centre crops. */
static const float s_squares[][4] = {
    { -2.9f, -1.1f, -1.3f, 0.2f },
    { 0.37f, 0.21f, 1.63f, 1.18f },
    { 2.05f, -1.45f, 3.3f, -0.33f },
    { -0.6f, 0.9f, 0.15f, 1.6f },
    { 0.9f, -1.3f, 1.4f, -0.6f },
    { 1.82939f, -2.71568f, 2.94294f, -1.60214f },
    { 1.82939f, 1.60214f, 2.94294f, 2.71568f },
    { -2.94294f, -2.71568f, -1.82939f, -1.60214f },
    { -2.94294f, 1.60214f, -1.82939f, 2.71568f },
};

/* Renders the scene with the camera parameters extra on a film of w x h. */
static int s_render(const char *extra, int w, int h, unsigned terms, pf_image_t *img)
{
    char text[8192], *p = text;
    size_t cap = sizeof text;
    int n = snprintf(p, cap,
                     "LookAt 0 10 0  0 0 0  0 0 -1\nCamera \"perspective\" \"float fov\" 40 %s\n"
                     "Film \"rgb\" \"integer xresolution\" %d \"integer yresolution\" %d\n"
                     "PixelFilter \"box\" \"float xradius\" 0.5 \"float yradius\" 0.5\nWorldBegin\n"
                     "AttributeBegin\nAreaLightSource \"diffuse\" \"rgb L\" [1 1 1]\n"
                     "Shape \"trianglemesh\" \"point3 P\" [-20 0 -20  20 0 -20  20 0 20  -20 0 20] "
                     "\"integer indices\" [0 2 1 0 3 2]\nAttributeEnd\n",
                     extra, w, h);
    for (size_t i = 0; i < sizeof s_squares / sizeof s_squares[0]; i++) {
        const float *q = s_squares[i];
        n += snprintf(text + n, cap - (size_t)n,
                      "AttributeBegin\nAreaLightSource \"diffuse\" \"rgb L\" [3 3 3]\n"
                      "Shape \"trianglemesh\" \"point3 P\" [%g 0.01 %g  %g 0.01 %g  %g 0.01 %g  %g 0.01 %g] "
                      "\"integer indices\" [0 2 1 0 3 2]\nAttributeEnd\n",
                      (double)q[0], (double)q[1], (double)q[2], (double)q[1], (double)q[2], (double)q[3],
                      (double)q[0], (double)q[3]);
    }
    char path[512];
    snprintf(path, sizeof path, "%s/win.pbrt", s_dir);
    FILE *f = fopen(path, "wb");
    fputs(text, f);
    fclose(f);
    pf_error_t err = { { 0 } };
    pf_scene_t *sc = pf_scene_load(path, &err);
    CHECK(sc != NULL, "load (%s): %s", extra, err.msg);
    if (!sc)
        return 0;
    pf_settings_t s = sc->settings;
    s.spp = 4;
    s.photons = 2000;
    s.caustic_photons = 1000;
    s.threads = 0;
    pf_job_summary_t sum;
    int rc = pf_job_render_local(sc, &s, terms, 0, img, &sum, &err);
    CHECK(rc == PF_OK, "render (%s): %s", extra, err.msg);
    pf_scene_destroy(&sc);
    return rc == PF_OK;
}

static const float *s_px(const pf_image_t *img, int x, int y) { return &img->rgb[3 * ((size_t)y * img->width + x)]; }


static void s_test_default(void)
{
    pf_image_t none, win, frame;
    if (!s_render("", 64, 32, PF_TERM_ALL, &none))
        return;
    if (s_render("\"float screenwindow\" [-2 2 -1 1]", 64, 32, PF_TERM_ALL, &win)) {
        CHECK(memcmp(none.rgb, win.rgb, 3 * sizeof(float) * 64 * 32) == 0,
              "the default screenwindow renders the same bits as none");
        pf_image_free(&win);
    }
    if (s_render("\"float frameaspectratio\" 2", 64, 32, PF_TERM_ALL, &frame)) {
        CHECK(memcmp(none.rgb, frame.rgb, 3 * sizeof(float) * 64 * 32) == 0,
              "the film's frameaspectratio renders the same bits as none");
        pf_image_free(&frame);
    }
    pf_image_free(&none);
}

/* The big image's pixel coordinates of the squares' corners, and of a
 * point on the ground, through the big camera's frame (its pinhole
 * projection, written out here: straight down onto a plane, so each square
 * is an axis-aligned rectangle of pixel space). */
typedef struct s_rect {
    double x0, x1, y0, y1;
} s_rect_t;

static s_rect_t s_rects[sizeof s_squares / sizeof s_squares[0]];

static void s_project(const pf_camera_t *cam, double wx, double wy, double wz, double *fx, double *fy)
{
    pf_vec3 d = pf_sub(pf_v3((float)wx, (float)wy, (float)wz), cam->pos);
    double x = pf_dot(d, cam->right), y = pf_dot(d, cam->up), z = pf_dot(d, cam->forward);
    double t = tan(20.0 * M_PI / 180.0);
    *fx = (x / z / (t * cam->width / cam->height) + 1.0) * 0.5 * cam->width;
    *fy = (1.0 - y / z / t) * 0.5 * cam->height;
}

static void s_make_rects(void)
{
    pf_camera_desc_t d = { .pos = { 0, 10, 0 }, .look_at = { 0, 0, 0 }, .up = { 0, 0, -1 }, .vfov_deg = 40,
                           .fov_shorter = 1, .left_handed = 1 };
    pf_camera_t cam = pf_camera_make(&d, 64, 32);
    for (size_t i = 0; i < sizeof s_squares / sizeof s_squares[0]; i++) {
        double ax, ay, bx, by;
        s_project(&cam, s_squares[i][0], 0.01, s_squares[i][1], &ax, &ay);
        s_project(&cam, s_squares[i][2], 0.01, s_squares[i][3], &bx, &by);
        s_rects[i] = (s_rect_t){ fmin(ax, bx), fmax(ax, bx), fmin(ay, by), fmax(ay, by) };
    }
}

/* What the big image's pixel rectangle r sees: 3 wholly inside a square, 1
 * wholly on the ground, 0 within S_MARGIN pixels of an edge (not judged). */
#define S_MARGIN 1e-3
static float s_expect(s_rect_t r)
{
    for (size_t i = 0; i < sizeof s_rects / sizeof s_rects[0]; i++) {
        const s_rect_t *q = &s_rects[i];
        if (r.x0 >= q->x0 + S_MARGIN && r.x1 <= q->x1 - S_MARGIN && r.y0 >= q->y0 + S_MARGIN &&
            r.y1 <= q->y1 - S_MARGIN)
            return 3.0f;
        if (r.x1 > q->x0 - S_MARGIN && r.x0 < q->x1 + S_MARGIN && r.y1 > q->y0 - S_MARGIN && r.y0 < q->y1 + S_MARGIN)
            return 0.0f;
    }
    return 1.0f;
}

/* img's pixel (x, y) covers the big image's [x0 + kx x, x0 + kx (x + 1)] x
 * [y0 + y, y0 + y + 1]: every pixel of it that the analysis calls whole must
 * be that radiance exactly (and the straddling ones are left out). A window
 * off by a pixel puts the pixels next to an edge on its other side (fails
 * each crop); off by a tenth of one, the samples of some (fails the
 * squeezed image, which has most edges). */
static void s_check_crop(const pf_image_t *img, double x0, double kx, double y0, const char *what)
{
    int whole = 0, right = 0, bright = 0;
    for (int y = 0; y < img->height; y++)
        for (int x = 0; x < img->width; x++) {
            float want = s_expect((s_rect_t){ x0 + kx * x, x0 + kx * (x + 1), y0 + y, y0 + y + 1 });
            if (want == 0.0f)
                continue;
            const float *p = s_px(img, x, y);
            whole++;
            bright += want == 3.0f;
            right += p[0] == want && p[1] == want && p[2] == want;
        }
    printf("%s: %d pixels, %d whole (%d in a square), %d of them the radiance they see\n", what,
           img->width * img->height, whole, bright, right);
    CHECK(right == whole, "%s: whole pixels of the radiance they see: %d of %d", what, right, whole);
    CHECK(bright > 10 && whole > img->width * img->height / 2, "%s: the crop sees squares and the ground", what);
}

static void s_test_crops(void)
{
    pf_image_t big, quad, square, squeezed;
    s_make_rects();
    if (!s_render("", 64, 32, PF_TERM_EMITTED, &big))
        return;
    s_check_crop(&big, 0, 1, 0, "the whole image");
    pf_image_free(&big);
    /* The top-right quadrant: x in [0, 2], y in [0, 1]. */
    if (s_render("\"float screenwindow\" [0 2 0 1]", 32, 16, PF_TERM_EMITTED, &quad)) {
        s_check_crop(&quad, 32, 1, 0, "quadrant");
        pf_image_free(&quad);
    }
    /* Pixels 40..55 x 8..23: x = -2 + 4 * 40 / 64 = 0.5 to 1.5, y = 1 - 2 * 8 / 32 = 0.5 to -0.5. */
    if (s_render("\"float screenwindow\" [0.5 1.5 -0.5 0.5]", 16, 16, PF_TERM_EMITTED, &square)) {
        s_check_crop(&square, 40, 1, 8, "off-centre square");
        pf_image_free(&square);
    }
    /* frameaspectratio 1: [-1, 1] x [-1, 1] over 64 x 32, the big image's
     * middle half (pixels 16..47) stretched twice across. */
    if (s_render("\"float frameaspectratio\" 1", 64, 32, PF_TERM_EMITTED, &squeezed)) {
        s_check_crop(&squeezed, 16, 0.5, 0, "frameaspectratio 1");
        pf_image_free(&squeezed);
    }
}

int main(void)
{
    pf_log_set_level(PF_LOG_WARN);
    snprintf(s_dir, sizeof s_dir, "/tmp/pf_camwin_XXXXXX");
    if (!mkdtemp(s_dir)) {
        perror("mkdtemp");
        return 1;
    }
    s_test_default();
    s_test_crops();
    char cmd[600];
    snprintf(cmd, sizeof cmd, "rm -rf '%s'", s_dir);
    if (system(cmd) != 0)
        fprintf(stderr, "could not remove %s\n", s_dir);
    return pf_test_finish();
}
