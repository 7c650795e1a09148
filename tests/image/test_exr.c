/* test_exr.c: self-test of the OpenEXR codec (image/exr.c): float round
 * trips bit for bit, half round trips within half precision, the codec
 * chosen by extension, the shared pbrt-v4 references read, and malformed
 * input (not an EXR, truncated, a header announcing a huge image, a missing
 * file) refused with an error naming the file; and the durable writes of
 * every writer (PFM, PNG, EXR: fsync, rename, fsync of the directory) to a
 * path with no directory part. Temporary files live in a
 * mkdtemp directory that is removed at the end. Runs from the repository
 * root (the references are at ../shared/scenes/bitterli/). */
#include <math.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <unistd.h>

#include "base/status.h"
#include "image/image.h"

#include "check.h"

static char s_dir[64];

static const char *s_path(const char *name)
{
    static char bufs[4][256];
    static int next;
    char *b = bufs[next++ % 4];
    snprintf(b, sizeof bufs[0], "%s/%s", s_dir, name);
    return b;
}

/* A w x h image with values over many magnitudes, signs kept positive. */
static void s_pattern(pf_image_t *img, int w, int h)
{
    PF_CHECK(pf_image_alloc(img, w, h) == PF_OK);
    for (int i = 0; i < w * h * 3; i++)
        img->rgb[i] = (float)((i * 7919) % 1000) * powf(10.0f, (float)(i % 9) - 4.0f) / 997.0f;
}

static uint8_t *s_slurp(const char *path, size_t *n)
{
    FILE *fp = fopen(path, "rb");
    if (!fp)
        return NULL;
    fseek(fp, 0, SEEK_END);
    long len = ftell(fp);
    fseek(fp, 0, SEEK_SET);
    uint8_t *data = malloc(len > 0 ? (size_t)len : 1);
    *n = data ? fread(data, 1, (size_t)len, fp) : 0;
    fclose(fp);
    return data;
}

static void s_spill(const char *path, const uint8_t *data, size_t n)
{
    FILE *fp = fopen(path, "wb");
    PF_CHECK(fp != NULL);
    fwrite(data, 1, n, fp);
    fclose(fp);
}

static void test_round_trips(void)
{
    pf_image_t a, b = { 0 };
    pf_error_t err = { { 0 } };
    s_pattern(&a, 37, 23);
    CHECK(pf_image_write_exr(&a, s_path("f.exr"), 0, &err) == PF_OK, "write float: %s", err.msg);
    CHECK(pf_image_read_exr(&b, s_path("f.exr"), &err) == PF_OK, "read float: %s", err.msg);
    CHECK(b.width == 37 && b.height == 23 && memcmp(a.rgb, b.rgb, sizeof(float) * 37 * 23 * 3) == 0,
          "a float EXR does not round-trip bit for bit (%dx%d)", b.width, b.height);
    pf_image_free(&b);
    CHECK(access(s_path("f.exr.tmp"), F_OK) != 0, "the writer left its .tmp file");

    CHECK(pf_image_write_exr(&a, s_path("h.exr"), 1, &err) == PF_OK, "write half: %s", err.msg);
    CHECK(pf_image_read_exr(&b, s_path("h.exr"), &err) == PF_OK, "read half: %s", err.msg);
    double worst = 0.0;
    for (int i = 0; b.rgb && i < 37 * 23 * 3; i++)
        if (a.rgb[i] > 1e-4f) /* above half's subnormals */
            worst = fmax(worst, fabs((double)b.rgb[i] - a.rgb[i]) / a.rgb[i]);
    CHECK(b.rgb && worst <= 1.0 / 1024.0, "half round trip off by %.3g relative (bound 2^-10)", worst);
    pf_image_free(&b);

    /* By extension: .exr is OpenEXR (float), anything else PFM. */
    CHECK(pf_image_write_hdr(&a, s_path("x.EXR"), 0, &err) == PF_OK && pf_image_path_is_exr(s_path("x.EXR")),
          "write_hdr .EXR: %s", err.msg);
    size_t n = 0;
    uint8_t *bytes = s_slurp(s_path("x.EXR"), &n);
    CHECK(bytes && n > 4 && bytes[0] == 0x76 && bytes[1] == 0x2f && bytes[2] == 0x31 && bytes[3] == 0x01,
          "an .EXR path did not get the OpenEXR magic");
    free(bytes);
    CHECK(pf_image_write_hdr(&a, s_path("x.pfm"), 1, &err) == PF_OK, "write_hdr .pfm: %s", err.msg);
    bytes = s_slurp(s_path("x.pfm"), &n);
    CHECK(bytes && n > 2 && bytes[0] == 'P' && bytes[1] == 'F', "a .pfm path did not get a PFM");
    free(bytes);
    CHECK(pf_image_read_hdr(&b, s_path("x.EXR"), &err) == PF_OK && b.width == 37, "read_hdr .EXR: %s", err.msg);
    pf_image_free(&b);
    pf_image_free(&a);
}

/* The reference images of the shared pbrt-v4 scenes (skipped without them). */
static void test_references(void)
{
    const char *path = "../shared/scenes/bitterli/veach-mis/reference-pbrt-v4.exr";
    if (access(path, R_OK) != 0) {
        printf("SKIP %s not found\n", path);
        return;
    }
    pf_image_t img = { 0 };
    pf_error_t err = { { 0 } };
    CHECK(pf_image_read_exr(&img, path, &err) == PF_OK, "%s", err.msg);
    CHECK(img.width == 640 && img.height == 360, "reference is %dx%d, not 640x360", img.width, img.height);
    size_t neg = 0, bad = img.rgb ? pf_image_count_bad(&img, &neg) : 1;
    double sum = 0.0;
    for (int i = 0; img.rgb && i < img.width * img.height * 3; i++)
        sum += img.rgb[i];
    CHECK(bad == 0 && neg == 0 && sum > 0.0, "reference: %zu non-finite, %zu negative, sum %g", bad, neg, sum);
    pf_image_free(&img);
}

static void s_expect_error(const char *path, int status, const char *what)
{
    pf_image_t img = { 0 };
    pf_error_t err = { { 0 } };
    int rc = pf_image_read_exr(&img, path, &err);
    CHECK(rc == status && img.rgb == NULL && strstr(err.msg, path) != NULL,
          "%s: status %d (want %d), message '%s' should name %s", what, rc, status, err.msg, path);
    pf_image_free(&img);
}

static void test_malformed(void)
{
    s_expect_error(s_path("missing.exr"), PF_EIO, "a missing file");
    s_spill(s_path("text.exr"), (const uint8_t *)"PF\n2 2\n-1\n", 10);
    s_expect_error(s_path("text.exr"), PF_EPARSE, "a PFM named .exr");

    pf_image_t a;
    pf_error_t err = { { 0 } };
    s_pattern(&a, 16, 16);
    PF_CHECK(pf_image_write_exr(&a, s_path("good.exr"), 0, &err) == PF_OK);
    pf_image_free(&a);
    size_t n = 0;
    uint8_t *good = s_slurp(s_path("good.exr"), &n);
    PF_CHECK(good != NULL && n > 64);
    /* Every truncation: an error, never a crash (ASan watches). */
    int refused = 0, tried = 0;
    for (size_t cut = 0; cut < n; cut += cut < 400 ? 1 : 97) {
        s_spill(s_path("cut.exr"), good, cut);
        pf_image_t img = { 0 };
        tried++;
        refused += pf_image_read_exr(&img, s_path("cut.exr"), &err) != PF_OK;
        pf_image_free(&img);
    }
    CHECK(refused == tried, "%d of %d truncated files were read as images", tried - refused, tried);

    /* A header announcing 100000 x 100000 pixels is refused before decoding. */
    uint8_t *dw = NULL;
    for (size_t i = 0; i + 10 < n && !dw; i++)
        if (memcmp(good + i, "dataWindow", 10) == 0)
            dw = good + i;
    CHECK(dw != NULL, "no dataWindow attribute in the written file");
    if (dw) {
        uint8_t *box = dw + 11 + 6 + 4; /* name\0, "box2i\0", size; then min_x, min_y, max_x, max_y */
        int32_t big = 99999;
        memcpy(box + 8, &big, 4);
        memcpy(box + 12, &big, 4);
        s_spill(s_path("huge.exr"), good, n);
        pf_image_t img = { 0 };
        int rc = pf_image_read_exr(&img, s_path("huge.exr"), &err);
        CHECK(rc == PF_EPARSE && strstr(err.msg, "out of range") != NULL, "huge header: status %d, '%s'", rc,
              err.msg);
        pf_image_free(&img);
    }
    free(good);
}

/* The writers sync the file and then its directory (image.c s_commit,
 * exr.c): a path with no directory part (the directory is ".") is written
 * whole, under its name, with no .tmp left behind, by each writer. */
static void test_durable_write(void)
{
    pf_image_t img, back;
    s_pattern(&img, 7, 4);
    pf_error_t err;
    char cwd[4096];
    CHECK(getcwd(cwd, sizeof cwd) != NULL);
    CHECK(chdir(s_dir) == 0);
    CHECK(pf_image_write_pfm(&img, "rel.pfm", &err) == PF_OK);
    CHECK(pf_image_write_png(&img, "rel.png", 0.0f, &err) == PF_OK);
    CHECK(pf_image_write_exr(&img, "rel.exr", 0, &err) == PF_OK);
    CHECK(access("rel.pfm.tmp", F_OK) != 0 && access("rel.png.tmp", F_OK) != 0 && access("rel.exr.tmp", F_OK) != 0);
    CHECK(chdir(cwd) == 0);
    size_t n = 0;
    uint8_t *raw = s_slurp(s_path("rel.pfm"), &n);
    CHECK(raw && n == strlen("PF\n7 4\n-1.0\n") + 7 * 4 * 12);
    free(raw);
    raw = s_slurp(s_path("rel.png"), &n);
    CHECK(raw && n > 12 && memcmp(raw, "\x89PNG", 4) == 0 && memcmp(raw + n - 8, "IEND", 4) == 0);
    free(raw);
    const char *names[2] = { "rel.pfm", "rel.exr" };
    for (int k = 0; k < 2; k++) {
        CHECK(pf_image_read_hdr(&back, s_path(names[k]), &err) == PF_OK);
        CHECK(back.width == 7 && back.height == 4 && back.rgb && memcmp(back.rgb, img.rgb, 7 * 4 * 3 * 4) == 0);
        pf_image_free(&back);
    }
    pf_image_free(&img);
}

int main(void)
{
    snprintf(s_dir, sizeof s_dir, "/tmp/pf_exr_XXXXXX");
    PF_CHECK(mkdtemp(s_dir) != NULL);
    test_round_trips();
    test_references();
    test_malformed();
    test_durable_write();
    char cmd[128];
    snprintf(cmd, sizeof cmd, "rm -rf '%s'", s_dir);
    if (system(cmd) != 0)
        fprintf(stderr, "could not remove %s\n", s_dir);
    return pf_test_finish();
}
