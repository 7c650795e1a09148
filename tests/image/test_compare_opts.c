/* test_compare_opts.c: the options `photonfarm compare` has for the
 * real-scene benchmarks (bench/realscenes.py): --downsample N, --mask-above Y
 * (pixels whose reference luminance exceeds Y are left out of every figure)
 * and --pair FILE.png (image and reference side by side). Checked on tiny
 * images whose figures are worked out by hand, through pf_metrics_compare_opts
 * and through pf_cli_compare with stdout captured. Temporary files live in a
 * mkdtemp directory under /tmp, removed at the end. */
#include <errno.h>
#include <fcntl.h>
#include <math.h>
#include <stdarg.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <unistd.h>

#include "coordinator/compare.h"
#include "image/image.h"
#include "image/metrics.h"

#include "check.h"

static char s_dir[64];

/* A path inside the temporary directory (rotating static buffers). */
static const char *s_path(const char *name)
{
    static char bufs[8][256];
    static int next;
    char *b = bufs[next++ % 8];
    snprintf(b, sizeof bufs[0], "%s/%s", s_dir, name);
    return b;
}

static char *s_read_all(const char *path, size_t *n)
{
    FILE *fp = fopen(path, "rb");
    *n = 0;
    if (!fp)
        return NULL;
    char *buf = malloc(1 << 16);
    *n = fread(buf, 1, (1 << 16) - 1, fp);
    buf[*n] = '\0';
    fclose(fp);
    return buf;
}

static void s_set(pf_image_t *img, int x, int y, float r, float g, float b)
{
    float *p = img->rgb + ((size_t)y * (size_t)img->width + (size_t)x) * 3;
    p[0] = r;
    p[1] = g;
    p[2] = b;
}

static void s_fill(pf_image_t *img, float v)
{
    for (size_t i = 0; i < (size_t)img->width * (size_t)img->height * 3; i++)
        img->rgb[i] = v;
}

/* Runs pf_cli_compare with argv (NULL-terminated), stdout captured into *out. */
static int s_run(char **out, ...)
{
    char *argv[16];
    int argc = 0;
    va_list ap;
    va_start(ap, out);
    for (char *a; argc < 15 && (a = va_arg(ap, char *)) != NULL;)
        argv[argc++] = a;
    va_end(ap);
    argv[argc] = NULL;
    const char *po = s_path("stdout.txt"), *pe = s_path("stderr.txt");
    fflush(stdout);
    fflush(stderr);
    int save_out = dup(1), save_err = dup(2);
    int fo = open(po, O_WRONLY | O_CREAT | O_TRUNC, 0600), fe = open(pe, O_WRONLY | O_CREAT | O_TRUNC, 0600);
    dup2(fo, 1);
    dup2(fe, 2);
    int code = pf_cli_compare(argc, argv);
    fflush(stdout);
    fflush(stderr);
    dup2(save_out, 1);
    dup2(save_err, 2);
    close(fo);
    close(fe);
    close(save_out);
    close(save_err);
    size_t n;
    *out = s_read_all(po, &n);
    unlink(po);
    unlink(pe);
    return code;
}

/* Masking: exactly the pixels whose reference luminance is above the
 * threshold are counted and left out; those just below stay in. */
static void test_mask(void)
{
    pf_image_t a, b;
    pf_error_t err;
    pf_metrics_t m;
    CHECK(pf_image_alloc(&a, 4, 4) == PF_OK && pf_image_alloc(&b, 4, 4) == PF_OK);
    s_fill(&a, 0.5f);
    s_fill(&b, 0.5f);
    s_set(&b, 1, 1, 100.0f, 100.0f, 100.0f); /* luminance 100: masked */
    s_set(&b, 3, 2, 0.0f, 60.0f, 0.0f);      /* 0.7152 * 60 = 42.9: kept */
    s_set(&b, 0, 3, 0.0f, 0.0f, 800.0f);     /* 0.0722 * 800 = 57.8: masked */
    s_set(&b, 2, 0, 49.9f, 49.9f, 49.9f);    /* just below 50: kept */
    /* The image matches the reference except at the two masked pixels. */
    s_set(&a, 3, 2, 0.0f, 60.0f, 0.0f);
    s_set(&a, 2, 0, 49.9f, 49.9f, 49.9f);

    pf_metrics_opts_t o = { 1, 50.0 };
    CHECK(pf_metrics_compare_opts(&a, &b, &o, &m, &err) == PF_OK);
    CHECK(m.masked == 2, "masked %zu, expected 2", m.masked);
    CHECK(m.relmse == 0.0 && m.rmse == 0.0, "relMSE %g RMSE %g with the differing pixels masked", m.relmse, m.rmse);
    CHECK(fabs(m.lum_ratio - 1.0) < 1e-12, "lum ratio %.17g", m.lum_ratio);

    /* Without the mask the two pixels count: the same call, NAN threshold. */
    o.mask_above = NAN;
    CHECK(pf_metrics_compare_opts(&a, &b, &o, &m, &err) == PF_OK);
    CHECK(m.masked == 0 && m.relmse > 1.0 && m.lum_ratio < 0.5, "unmasked: masked %zu relMSE %g lum %g", m.masked,
          m.relmse, m.lum_ratio);
    /* The plain entry point equals no options. */
    pf_metrics_t m0;
    CHECK(pf_metrics_compare(&a, &b, &m0, &err) == PF_OK && m0.relmse == m.relmse && m0.downsample == 1);

    /* Everything masked: no figure rather than a perfect one. */
    o.mask_above = 0.0;
    CHECK(pf_metrics_compare_opts(&a, &b, &o, &m, &err) == PF_OK);
    CHECK(m.masked == 16 && isnan(m.relmse) && isnan(m.lum_ratio), "all masked: %zu %g", m.masked, m.relmse);
    pf_image_free(&a);
    pf_image_free(&b);
}

/* Downsampling by 2 of a 4x2 image: blocks of mean 1 and 3 against a
 * reference of 1 give relMSE (0 + 4/1.01)/2, RMSE sqrt(2), luminance 2;
 * a masked source pixel masks its whole block. Bad factors give PF_ESIZE. */
static void test_downsample(void)
{
    pf_image_t a, b;
    pf_error_t err;
    pf_metrics_t m;
    CHECK(pf_image_alloc(&a, 4, 2) == PF_OK && pf_image_alloc(&b, 4, 2) == PF_OK);
    s_fill(&b, 1.0f);
    s_fill(&a, 3.0f);
    s_set(&a, 0, 0, 0.0f, 0.0f, 0.0f);
    s_set(&a, 1, 0, 0.0f, 0.0f, 0.0f);
    s_set(&a, 0, 1, 2.0f, 2.0f, 2.0f);
    s_set(&a, 1, 1, 2.0f, 2.0f, 2.0f);
    pf_metrics_opts_t o = { 2, NAN };
    CHECK(pf_metrics_compare_opts(&a, &b, &o, &m, &err) == PF_OK);
    CHECK(m.width == 2 && m.height == 1 && m.downsample == 2 && m.masked == 0);
    CHECK(fabs(m.relmse - 2.0 / 1.01) < 1e-12, "relMSE %.17g", m.relmse);
    CHECK(fabs(m.rmse - sqrt(2.0)) < 1e-12, "RMSE %.17g", m.rmse);
    CHECK(fabs(m.lum_ratio - 2.0) < 1e-12, "lum %.17g", m.lum_ratio);

    /* One bright reference pixel in the right block leaves that block out;
     * the reference's block mean changes too, but it is not compared. */
    s_set(&b, 3, 1, 200.0f, 200.0f, 200.0f);
    o.mask_above = 50.0;
    CHECK(pf_metrics_compare_opts(&a, &b, &o, &m, &err) == PF_OK);
    CHECK(m.masked == 1 && m.relmse == 0.0 && fabs(m.lum_ratio - 1.0) < 1e-12, "masked %zu relMSE %g lum %g",
          m.masked, m.relmse, m.lum_ratio);

    const int bad[] = { 3, 4, -2 };
    for (int i = 0; i < 3; i++) {
        o.downsample = bad[i];
        CHECK(pf_metrics_compare_opts(&a, &b, &o, &m, &err) == PF_ESIZE, "downsample %d", bad[i]);
    }
    /* After the size fitting: 4x2 against a 2x1 reference fits at 2x1, so 2 no longer divides. */
    pf_image_t small;
    CHECK(pf_image_alloc(&small, 2, 1) == PF_OK);
    s_fill(&small, 1.0f);
    o.downsample = 2;
    CHECK(pf_metrics_compare_opts(&a, &small, &o, &m, &err) == PF_ESIZE);
    o.downsample = 1;
    CHECK(pf_metrics_compare_opts(&a, &small, &o, &m, &err) == PF_OK && m.factor_a == 2 && m.width == 2);
    pf_image_free(&small);
    pf_image_free(&a);
    pf_image_free(&b);
}

/* The side-by-side picture: a, a white gap, b. */
static void test_side_by_side(void)
{
    pf_image_t a, b, p, c;
    CHECK(pf_image_alloc(&a, 3, 2) == PF_OK && pf_image_alloc(&b, 3, 2) == PF_OK && pf_image_alloc(&c, 2, 2) == PF_OK);
    s_fill(&a, 0.25f);
    s_fill(&b, 0.75f);
    CHECK(pf_image_side_by_side(&a, &b, 2, &p) == PF_OK);
    CHECK(p.width == 8 && p.height == 2);
    CHECK(p.rgb[0] == 0.25f && p.rgb[(1 * 8 + 2) * 3] == 0.25f);
    CHECK(p.rgb[3 * 3] > 1000.0f && p.rgb[(8 + 4) * 3 + 2] > 1000.0f, "the gap is white");
    CHECK(p.rgb[5 * 3] == 0.75f && p.rgb[(8 + 7) * 3 + 1] == 0.75f);
    pf_image_free(&p);
    CHECK(pf_image_side_by_side(&a, &c, 2, &p) == PF_EINVAL && p.rgb == NULL, "different sizes");
    pf_image_free(&a);
    pf_image_free(&b);
    pf_image_free(&c);
}

/* Big-endian 32-bit integer at p (PNG's IHDR). */
static unsigned s_be32(const unsigned char *p)
{
    return (unsigned)p[0] << 24 | (unsigned)p[1] << 16 | (unsigned)p[2] << 8 | p[3];
}

/* The command line: figures, the masked count in the table and the JSON,
 * exit 4 for bad factors, the pair PNG's size, unchanged default output. */
static void test_cli(void)
{
    pf_image_t a, b;
    pf_error_t err;
    CHECK(pf_image_alloc(&a, 4, 2) == PF_OK && pf_image_alloc(&b, 4, 2) == PF_OK);
    s_fill(&a, 1.0f);
    s_fill(&b, 1.0f);
    s_set(&a, 3, 1, 5.0f, 5.0f, 5.0f);
    s_set(&b, 3, 1, 80.0f, 80.0f, 80.0f);
    char pa[256], pb[256], pp[256];
    snprintf(pa, sizeof pa, "%s", s_path("a.pfm"));
    snprintf(pb, sizeof pb, "%s", s_path("b.pfm"));
    snprintf(pp, sizeof pp, "%s", s_path("pair.png"));
    CHECK(pf_image_write_pfm(&a, pa, &err) == PF_OK && pf_image_write_pfm(&b, pb, &err) == PF_OK);

    char *out = NULL;
    CHECK(s_run(&out, "compare", pa, pb, (char *)NULL) == 0);
    CHECK(out && !strstr(out, "masked") && !strstr(out, "compared") && strstr(out, "relMSE "),
          "default table unchanged: %s", out ? out : "");
    free(out);
    CHECK(s_run(&out, "compare", "--json", pa, pb, (char *)NULL) == 0);
    CHECK(out && !strstr(out, "masked") && strstr(out, "\"nonfinite\":0}\n"), "default JSON unchanged: %s",
          out ? out : "");
    free(out);

    CHECK(s_run(&out, "compare", pa, pb, "--downsample", "2", "--mask-above", "50", (char *)NULL) == 0);
    CHECK(out && strstr(out, "compared   2x1 (both downsampled x2)") && strstr(out, "masked     1 of 2 pixels")
          && strstr(out, "relMSE     0\n"), "table: %s", out ? out : "");
    free(out);
    CHECK(s_run(&out, "compare", "--json", pa, pb, "--downsample", "2", "--mask-above", "50", (char *)NULL) == 0);
    CHECK(out && strstr(out, "\"relmse\":0,") && strstr(out, "\"width\":2,\"height\":1")
          && strstr(out, "\"masked\":1}"), "json: %s", out ? out : "");
    free(out);

    const char *bad[] = { "3", "0", "-2", "1.5" };
    for (int i = 0; i < 4; i++) {
        CHECK(s_run(&out, "compare", pa, pb, "--downsample", bad[i], (char *)NULL) == 4, "--downsample %s", bad[i]);
        free(out);
    }
    CHECK(s_run(&out, "compare", pa, pb, "--downsample", "two", (char *)NULL) == 2);
    free(out);
    CHECK(s_run(&out, "compare", pa, pb, "--mask-above", (char *)NULL) == 2);
    free(out);

    CHECK(s_run(&out, "compare", pa, pb, "--pair", pp, "--exposure", "-1", (char *)NULL) == 0);
    free(out);
    size_t n;
    unsigned char *png = (unsigned char *)s_read_all(pp, &n);
    CHECK(png && n > 24 && memcmp(png + 12, "IHDR", 4) == 0, "pair PNG written");
    if (png && n > 24)
        CHECK(s_be32(png + 16) == 2 * 4 + 8 && s_be32(png + 20) == 2, "pair is %ux%u, expected 16x2", s_be32(png + 16),
              s_be32(png + 20));
    free(png);
    unlink(pp);
    pf_image_free(&a);
    pf_image_free(&b);
    unlink(pa);
    unlink(pb);
}

int main(void)
{
    snprintf(s_dir, sizeof s_dir, "/tmp/pf_test_compare_XXXXXX");
    if (!mkdtemp(s_dir)) {
        fprintf(stderr, "mkdtemp: %s\n", strerror(errno));
        return 1;
    }
    test_mask();
    test_downsample();
    test_side_by_side();
    test_cli();
    rmdir(s_dir);
    return pf_test_finish();
}
