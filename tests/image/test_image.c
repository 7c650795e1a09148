/* test_image.c: self-test of image I/O (image/image.c), error metrics
 * (image/metrics.c) and the `photonfarm compare` subcommand
 * (coordinator/compare.c). Temporary files live in a mkdtemp directory under
 * /tmp that is removed at the end. Runs from the repository root, where the
 * shared references are at ../shared/references/. */
#include <cjson/cJSON.h>
#include <dirent.h>
#include <errno.h>
#include <fcntl.h>
#include <float.h>
#include <limits.h>
#include <math.h>
#include <png.h>
#include <stdarg.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/stat.h>
#include <sys/wait.h>
#include <unistd.h>

#include "coordinator/compare.h"
#include "image/image.h"
#include "image/metrics.h"

#include "check.h"



#define CHECK_NEAR(a, b, tol)                                                                        \
    do {                                                                                             \
        double a_ = (a), b_ = (b);                                                                   \
        if (fabs(a_ - b_) <= (tol)) {                                                                \
            s_passed++;                                                                                \
        } else {                                                                                     \
            s_failed++;                                                                                \
            fprintf(stderr, "%s:%d: check failed: %s = %.17g, expected %s = %.17g (tol %g)\n", __FILE__, \
                    __LINE__, #a, a_, #b, b_, (double)(tol));                                        \
        }                                                                                            \
    } while (0)

static char s_dir[64];

/* A path inside the temporary directory (rotating static buffers). */
static const char *s_path(const char *name)
{
    static char bufs[8][256];
    static int next;
    char *b = bufs[next++ % 8];
    int len = snprintf(b, sizeof bufs[0], "%s/%s", s_dir, name);
    if (len < 0 || (size_t)len >= sizeof bufs[0]) {
        fprintf(stderr, "test path too long: %s/%s\n", s_dir, name);
        exit(2);
    }
    return b;
}

static void s_write_bytes(const char *path, const void *data, size_t n)
{
    FILE *fp = fopen(path, "wb");
    if (!fp || fwrite(data, 1, n, fp) != n || fclose(fp) != 0) {
        fprintf(stderr, "cannot write test file %s\n", path);
        exit(1);
    }
}

static unsigned char *s_read_all(const char *path, size_t *n)
{
    FILE *fp = fopen(path, "rb");
    *n = 0;
    if (!fp)
        return NULL;
    unsigned char *buf = NULL;
    size_t cap = 0;
    for (;;) {
        if (*n + 4096 + 1 > cap) {
            cap = (cap + 4096) * 2;
            buf = realloc(buf, cap);
        }
        size_t got = fread(buf + *n, 1, 4096, fp);
        *n += got;
        if (got < 4096)
            break;
    }
    fclose(fp);
    buf[*n] = '\0';
    return buf;
}

static int s_exists(const char *path)
{
    struct stat sb;
    return stat(path, &sb) == 0;
}

/* A byte buffer for building PFM files by hand. */
typedef struct {
    unsigned char b[4096];
    size_t n;
} s_buf_t;

static void s_buf_str(s_buf_t *b, const char *s)
{
    size_t n = strlen(s);
    memcpy(b->b + b->n, s, n);
    b->n += n;
}

static void s_buf_float(s_buf_t *b, float f, int little)
{
    uint32_t u;
    memcpy(&u, &f, 4);
    for (int i = 0; i < 4; i++)
        b->b[b->n++] = (unsigned char)(u >> (little ? 8 * i : 8 * (3 - i)));
}

static int s_bits_equal(float a, float b) { return memcmp(&a, &b, sizeof a) == 0; }

static float *s_px(pf_image_t *img, int x, int y) { return img->rgb + ((size_t)y * (size_t)img->width + (size_t)x) * 3; }

/* Reads a file that must fail; checks the image is left empty and the message names the file. */
static void s_expect_read_error(const char *name, const void *data, size_t n, const char *needle)
{
    const char *path = s_path(name);
    s_write_bytes(path, data, n);
    pf_image_t img = { 7, 7, NULL };
    pf_error_t err = { .msg = "" };
    int st = pf_image_read_pfm(&img, path, &err);
    CHECK(st < 0);
    CHECK(img.rgb == NULL && img.width == 0 && img.height == 0);
    CHECK(strstr(err.msg, path) == err.msg);
    if (needle && !strstr(err.msg, needle)) {
        s_failed++;
        fprintf(stderr, "%s: message \"%s\" lacks \"%s\"\n", name, err.msg, needle);
    } else {
        s_passed++;
    }
    pf_image_free(&img);
    unlink(path);
}

static void test_alloc(void)
{
    pf_image_t img;
    CHECK(pf_image_alloc(&img, 0, 5) == PF_EINVAL && img.rgb == NULL);
    CHECK(pf_image_alloc(&img, 5, -1) == PF_EINVAL && img.rgb == NULL);
    CHECK(pf_image_alloc(&img, INT_MAX, INT_MAX) == PF_EINVAL && img.rgb == NULL);
    CHECK(pf_image_alloc(&img, 1 << 15, 1 << 14) == PF_EINVAL); /* 2^29 pixels */
    CHECK(pf_image_alloc(&img, 3, 2) == PF_OK);
    CHECK(img.width == 3 && img.height == 2 && img.rgb != NULL);
    int zero = 1;
    for (int i = 0; i < 18; i++)
        zero &= img.rgb[i] == 0.0f;
    CHECK(zero);
    pf_image_free(&img);
    CHECK(img.rgb == NULL && img.width == 0);
    pf_image_free(&img); /* a second free is harmless */
    pf_image_free(NULL);
}

static void test_count_bad(void)
{
    pf_image_t img;
    CHECK(pf_image_alloc(&img, 2, 2) == PF_OK);
    img.rgb[0] = NAN;
    img.rgb[1] = INFINITY;
    img.rgb[2] = -INFINITY;
    img.rgb[3] = -1.0f;
    img.rgb[4] = -0.0f;
    img.rgb[5] = -1e-30f;
    img.rgb[6] = 2.0f;
    size_t neg = 99;
    CHECK(pf_image_count_bad(&img, &neg) == 3);
    CHECK(neg == 2);
    CHECK(pf_image_count_bad(&img, NULL) == 3);
    pf_image_free(&img);
}

static void test_pfm_roundtrip(void)
{
    const float special[] = { 0.0f, -0.0f, 1.0f, -1.5f, 1e-40f /* denormal */, FLT_MIN, FLT_MAX, -FLT_MAX,
                              3.14159265f, 1e-30f, 65504.0f, INFINITY, -INFINITY, NAN, 0.1f };
    const int nspecial = (int)(sizeof special / sizeof special[0]);
    pf_image_t img;
    CHECK(pf_image_alloc(&img, 5, 3) == PF_OK);
    for (int i = 0; i < 45; i++)
        img.rgb[i] = i < nspecial ? special[i] : (float)i * 0.37f - 4.0f;
    const char *path = s_path("round.pfm");
    pf_error_t err;
    CHECK(pf_image_write_pfm(&img, path, &err) == PF_OK);
    CHECK(!s_exists(s_path("round.pfm.tmp")));

    /* The exact bytes: header, then the bottom row first, little-endian. */
    size_t n;
    unsigned char *raw = s_read_all(path, &n);
    const char *head = "PF\n5 3\n-1.0\n";
    size_t hl = strlen(head);
    CHECK(raw && n == hl + 5 * 3 * 12);
    CHECK(raw && memcmp(raw, head, hl) == 0);
    if (raw && n == hl + 180) {
        /* First float in the file: red of the bottom-left pixel (row 2). */
        s_buf_t b = { .n = 0 };
        s_buf_float(&b, s_px(&img, 0, 2)[0], 1);
        CHECK(memcmp(raw + hl, b.b, 4) == 0);
        /* The last float: blue of the top-right pixel. */
        b.n = 0;
        s_buf_float(&b, s_px(&img, 4, 0)[2], 1);
        CHECK(memcmp(raw + n - 4, b.b, 4) == 0);
    }
    free(raw);

    pf_image_t back;
    CHECK(pf_image_read_pfm(&back, path, &err) == PF_OK);
    CHECK(back.width == 5 && back.height == 3);
    int same = back.rgb != NULL;
    for (int i = 0; same && i < 45; i++)
        same = s_bits_equal(img.rgb[i], back.rgb[i]);
    CHECK(same);
    pf_image_free(&back);

    /* Overwriting an existing file replaces it whole. */
    pf_image_t small;
    CHECK(pf_image_alloc(&small, 1, 1) == PF_OK);
    small.rgb[1] = 0.25f;
    CHECK(pf_image_write_pfm(&small, path, &err) == PF_OK);
    CHECK(pf_image_read_pfm(&back, path, &err) == PF_OK);
    CHECK(back.width == 1 && back.height == 1 && back.rgb[1] == 0.25f);
    pf_image_free(&back);
    pf_image_free(&small);

    /* Writing where no directory exists fails cleanly and names the file. */
    const char *bad = s_path("no/such/dir/x.pfm");
    CHECK(pf_image_write_pfm(&img, bad, &err) == PF_EIO);
    CHECK(strstr(err.msg, bad) != NULL);
    pf_image_free(&img);
    unlink(path);
}

static void test_pfm_big_endian(void)
{
    /* 2x2, scale +1.0: big-endian. File rows bottom first: (0,1) (1,1) then (0,0) (1,0). */
    s_buf_t b = { .n = 0 };
    s_buf_str(&b, "PF\n2 2\n1.0\n");
    const float bottom[6] = { 1.0f, 2.0f, 3.0f, -4.0f, 5e-20f, 6e20f };
    const float top[6] = { 0.5f, 0.25f, 0.125f, 7.0f, 8.0f, 9.0f };
    for (int i = 0; i < 6; i++)
        s_buf_float(&b, bottom[i], 0);
    for (int i = 0; i < 6; i++)
        s_buf_float(&b, top[i], 0);
    const char *path = s_path("be.pfm");
    s_write_bytes(path, b.b, b.n);
    pf_image_t img;
    pf_error_t err;
    CHECK(pf_image_read_pfm(&img, path, &err) == PF_OK);
    CHECK(img.width == 2 && img.height == 2);
    if (img.rgb) {
        int ok = 1;
        for (int i = 0; i < 6; i++) {
            ok &= s_bits_equal(img.rgb[i], top[i]);
            ok &= s_bits_equal(img.rgb[6 + i], bottom[i]);
        }
        CHECK(ok);
    }
    pf_image_free(&img);
    unlink(path);
}

static void test_pfm_greyscale_and_header_variants(void)
{
    /* Greyscale 3x2, little-endian: replicated to RGB, flipped to top first. */
    s_buf_t b = { .n = 0 };
    s_buf_str(&b, "Pf\n3 2\n-1.0\n");
    const float g[6] = { 1, 2, 3, 4, 5, 6 }; /* bottom row 1 2 3, top row 4 5 6 */
    for (int i = 0; i < 6; i++)
        s_buf_float(&b, g[i], 1);
    const char *path = s_path("grey.pfm");
    s_write_bytes(path, b.b, b.n);
    pf_image_t img;
    pf_error_t err;
    CHECK(pf_image_read_pfm(&img, path, &err) == PF_OK);
    CHECK(img.width == 3 && img.height == 2);
    if (img.rgb) {
        CHECK(s_px(&img, 0, 0)[0] == 4 && s_px(&img, 0, 0)[1] == 4 && s_px(&img, 0, 0)[2] == 4);
        CHECK(s_px(&img, 2, 0)[1] == 6);
        CHECK(s_px(&img, 1, 1)[0] == 2 && s_px(&img, 1, 1)[2] == 2);
    }
    pf_image_free(&img);

    /* Whitespace variations: spaces and tabs, blank lines, CRLF endings,
     * "-1" without a fraction, and a first data byte that is itself a
     * newline (0x0a) - which must not be eaten as header whitespace. */
    const char *heads[] = { "PF 1 1 -1\n", "PF\t1\t1\t-1.0\n", "PF\n\n1   1\n\n-1.000000\n", "PF\r\n1 1\r\n-1.0\r\n",
                            "PF\n1\n1\n-1e0\n" };
    for (size_t h = 0; h < sizeof heads / sizeof heads[0]; h++) {
        s_buf_t v = { .n = 0 };
        s_buf_str(&v, heads[h]);
        float vals[3];
        uint32_t u = 0x0a0a0a0au; /* a float whose every byte is '\n' */
        memcpy(&vals[0], &u, 4);
        vals[1] = 0.5f;
        vals[2] = -2.0f;
        for (int i = 0; i < 3; i++)
            s_buf_float(&v, vals[i], 1);
        s_write_bytes(path, v.b, v.n);
        int st = pf_image_read_pfm(&img, path, &err);
        CHECK(st == PF_OK);
        if (st != PF_OK)
            fprintf(stderr, "header variant %zu: %s\n", h, err.msg);
        CHECK(img.rgb && s_bits_equal(img.rgb[0], vals[0]) && img.rgb[1] == 0.5f && img.rgb[2] == -2.0f);
        pf_image_free(&img);
    }

    /* The scale's magnitude multiplies the values (as pbrt reads PFM). */
    s_buf_t sc = { .n = 0 };
    s_buf_str(&sc, "PF\n1 1\n-2.0\n");
    for (int i = 0; i < 3; i++)
        s_buf_float(&sc, 1.5f, 1);
    s_write_bytes(path, sc.b, sc.n);
    CHECK(pf_image_read_pfm(&img, path, &err) == PF_OK);
    CHECK(img.rgb && img.rgb[0] == 3.0f && img.rgb[2] == 3.0f);
    pf_image_free(&img);
    unlink(path);
}

static void test_pfm_malformed(void)
{
    /* A valid 2x2 file to cut and corrupt: 48 bytes of data. */
    s_buf_t good = { .n = 0 };
    s_buf_str(&good, "PF\n2 2\n-1.0\n");
    const size_t hl = good.n;
    for (int i = 0; i < 12; i++)
        s_buf_float(&good, (float)i, 1);

    s_buf_t b;
    b = good;
    b.b[1] = 'G';
    s_expect_read_error("magic1.pfm", b.b, b.n, "magic");
    s_expect_read_error("magic2.pfm", "P6\n2 2\n255\n", 11, "magic");
    s_expect_read_error("empty.pfm", "", 0, "magic");
    s_expect_read_error("trunc.pfm", good.b, good.n - 1, "expected 48 bytes of pixel data, found 47");
    s_expect_read_error("nodata.pfm", good.b, hl, "expected 48 bytes of pixel data, found 0");
    b = good;
    b.b[b.n++] = 'x';
    s_expect_read_error("trailing.pfm", b.b, b.n, "expected 48 bytes of pixel data, found 49");

    const char *bad_heads[][2] = {
        { "PF\n-2 2\n-1.0\n", "negative" },
        { "PF\n2 -2\n-1.0\n", "negative" },
        { "PF\n0 2\n-1.0\n", "zero" },
        { "PF\n100000 100000\n-1.0\n", "too large" },
        { "PF\n99999999999999999999999 1\n-1.0\n", "too large" },
        { "PF\n2.5 2\n-1.0\n", "width" },
        { "PF\nab 2\n-1.0\n", "width" },
        { "PF\n2 2\n0.0\n", "scale" },
        { "PF\n2 2\nnan\n", "scale" },
        { "PF\n2 2\n1e99\n", "scale" },
        { "PF\n2 2\n-1.0x\n", "scale" },
        { "PF2 2\n-1.0\n", "whitespace" },
        { "PF\n2", "truncated" },
        { "PF\n2 2\n-1.0", "truncated" },
    };
    for (size_t i = 0; i < sizeof bad_heads / sizeof bad_heads[0]; i++) {
        s_buf_t v = { .n = 0 };
        s_buf_str(&v, bad_heads[i][0]);
        for (int k = 0; k < 48; k++)
            v.b[v.n++] = 0;
        /* The header-truncation cases must end where their header ends. */
        size_t n = strstr(bad_heads[i][1], "truncated") ? strlen(bad_heads[i][0]) : v.n;
        s_expect_read_error("badhead.pfm", v.b, n, bad_heads[i][1]);
    }

    /* An overlong header (whitespace past the parser's window). */
    s_buf_t longh = { .n = 0 };
    s_buf_str(&longh, "PF");
    while (longh.n < 600)
        longh.b[longh.n++] = ' ';
    s_buf_str(&longh, "2 2 -1\n");
    s_expect_read_error("longhead.pfm", longh.b, longh.n, "header");

    /* Every truncation of a valid file fails cleanly. */
    int all = 1;
    for (size_t n = 0; n < good.n; n++) {
        const char *path = s_path("cut.pfm");
        s_write_bytes(path, good.b, n);
        pf_image_t img;
        pf_error_t err = { .msg = "" };
        all &= pf_image_read_pfm(&img, path, &err) < 0 && img.rgb == NULL && strstr(err.msg, path) == err.msg;
        unlink(path);
    }
    CHECK(all);

    /* A missing file names the file too. */
    pf_image_t img;
    pf_error_t err;
    const char *missing = s_path("missing.pfm");
    CHECK(pf_image_read_pfm(&img, missing, &err) == PF_EIO);
    CHECK(strstr(err.msg, missing) != NULL);
}

/* Serves bytes through a FIFO, so the reader cannot know the length up front. */
static int s_read_through_fifo(const void *data, size_t n, pf_image_t *img, pf_error_t *err)
{
    const char *fifo = s_path("fifo.pfm");
    unlink(fifo);
    if (mkfifo(fifo, 0600) != 0)
        return -1000;
    pid_t pid = fork();
    if (pid == 0) {
        int fd = open(fifo, O_WRONLY);
        const unsigned char *p = data;
        while (fd >= 0 && n > 0) {
            ssize_t w = write(fd, p, n);
            if (w <= 0)
                break;
            p += w;
            n -= (size_t)w;
        }
        _exit(0);
    }
    int st = pf_image_read_pfm(img, fifo, err);
    int status;
    waitpid(pid, &status, 0);
    unlink(fifo);
    return st;
}

static void test_pfm_fifo(void)
{
    s_buf_t good = { .n = 0 };
    s_buf_str(&good, "PF\n2 2\n-1.0\n");
    for (int i = 0; i < 12; i++)
        s_buf_float(&good, (float)i, 1);
    pf_image_t img;
    pf_error_t err;
    CHECK(s_read_through_fifo(good.b, good.n, &img, &err) == PF_OK);
    CHECK(img.rgb && s_px(&img, 0, 1)[0] == 0.0f && s_px(&img, 1, 0)[2] == 11.0f);
    pf_image_free(&img);

    CHECK(s_read_through_fifo(good.b, good.n - 5, &img, &err) == PF_EPARSE);
    CHECK(strstr(err.msg, "expected 48 bytes of pixel data, found 43") != NULL);
    s_buf_t longer = good;
    s_buf_str(&longer, "junk");
    CHECK(s_read_through_fifo(longer.b, longer.n, &img, &err) == PF_EPARSE);
    CHECK(strstr(err.msg, "expected 48 bytes of pixel data, found 52") != NULL);
    CHECK(img.rgb == NULL);
}

/* Reads an 8-bit RGB PNG with libpng's classic API; returns the pixel bytes. */
static unsigned char *s_read_png(const char *path, int *w, int *h, int *srgb)
{
    FILE *fp = fopen(path, "rb");
    if (!fp)
        return NULL;
    unsigned char sig[8];
    if (fread(sig, 1, 8, fp) != 8 || png_sig_cmp(sig, 0, 8) != 0) {
        fclose(fp);
        return NULL;
    }
    png_structp png = png_create_read_struct(PNG_LIBPNG_VER_STRING, NULL, NULL, NULL);
    png_infop info = png_create_info_struct(png);
    unsigned char *volatile pixels = NULL;
    if (setjmp(png_jmpbuf(png))) {
        png_destroy_read_struct(&png, &info, NULL);
        fclose(fp);
        free(pixels);
        return NULL;
    }
    png_init_io(png, fp);
    png_set_sig_bytes(png, 8);
    png_read_info(png, info);
    *w = (int)png_get_image_width(png, info);
    *h = (int)png_get_image_height(png, info);
    int intent;
    *srgb = png_get_sRGB(png, info, &intent) != 0;
    if (png_get_bit_depth(png, info) != 8 || png_get_color_type(png, info) != PNG_COLOR_TYPE_RGB) {
        png_destroy_read_struct(&png, &info, NULL);
        fclose(fp);
        return NULL;
    }
    pixels = malloc((size_t)*w * (size_t)*h * 3);
    for (int y = 0; y < *h; y++)
        png_read_row(png, pixels + (size_t)y * (size_t)*w * 3, NULL);
    png_read_end(png, NULL);
    png_destroy_read_struct(&png, &info, NULL);
    fclose(fp);
    return pixels;
}

static void test_png(void)
{
    pf_image_t img;
    CHECK(pf_image_alloc(&img, 4, 2) == PF_OK);
    const float top[12] = { 0.5f, 0.0f, 1.0f, 0.25f, 0.001f, 2.0f, NAN, -1.0f, INFINITY, 0.18f, 0.0031308f, 0.75f };
    const float bottom[12] = { 0.1f, 0.2f, 0.3f, 0.4f, 0.6f, 0.7f, 0.8f, 0.9f, 0.95f, 0.05f, 0.02f, 0.01f };
    memcpy(img.rgb, top, sizeof top);
    memcpy(img.rgb + 12, bottom, sizeof bottom);
    const char *path = s_path("out.png");
    pf_error_t err;
    CHECK(pf_image_write_png(&img, path, 0.0f, &err) == PF_OK);
    CHECK(!s_exists(s_path("out.png.tmp")));
    int w = 0, h = 0, srgb = 0;
    unsigned char *px = s_read_png(path, &w, &h, &srgb);
    CHECK(px != NULL && w == 4 && h == 2);
    CHECK(srgb);
    if (px && w == 4 && h == 2) {
        /* Hand-computed sRGB codes: 0.5 -> 187.52 -> 188; 0.25 -> 136.96 -> 137;
         * 0.001 -> 12.92 * 0.001 * 255 = 3.29 -> 3; 0.18 -> 117.6 -> 118;
         * NaN and negatives -> 0; above one -> 255. */
        const unsigned char want[12] = { 188, 0, 255, 137, 3, 255, 0, 0, 255, 118, 10, 225 };
        CHECK(memcmp(px, want, 12) == 0);
        /* The bottom row is stored second (PNG is top row first, like memory). */
        CHECK(px[12] == 89 && px[13] == 124);
        /* Monotone along the bottom row's increasing values. */
        int mono = 1;
        for (int i = 12; i < 20; i++) /* 0.1, 0.2, ..., 0.9, 0.95 */
            mono &= px[i + 1] > px[i];
        CHECK(mono);
    }
    free(px);

    /* Exposure +1 doubles: 0.25 -> 0.5 -> 188, 0.5 -> 1.0 -> 255. Exposure -1 halves 1.0 -> 188. */
    CHECK(pf_image_write_png(&img, path, 1.0f, &err) == PF_OK);
    px = s_read_png(path, &w, &h, &srgb);
    CHECK(px && px[3] == 188 && px[0] == 255 && px[1] == 0);
    free(px);
    CHECK(pf_image_write_png(&img, path, -1.0f, &err) == PF_OK);
    px = s_read_png(path, &w, &h, &srgb);
    CHECK(px && px[2] == 188 && px[0] == 137);
    free(px);

    CHECK(pf_image_write_png(&img, path, NAN, &err) == PF_EINVAL);
    const char *bad = s_path("no/such/dir/x.png");
    CHECK(pf_image_write_png(&img, bad, 0.0f, &err) == PF_EIO);
    CHECK(strstr(err.msg, bad) != NULL);
    pf_image_free(&img);

    /* libpng's own errors arrive through longjmp with the file named: a
     * width beyond libpng's default user limit (1,000,000) is refused when
     * the header is written. */
    CHECK(pf_image_alloc(&img, 1100000, 1) == PF_OK);
    int st = pf_image_write_png(&img, path, 0.0f, &err);
    CHECK(st == PF_EIO);
    CHECK(strstr(err.msg, path) == err.msg && strstr(err.msg, "libpng") != NULL);
    CHECK(!s_exists(s_path("out.png.tmp")));
    pf_image_free(&img);
    unlink(path);
}

static void test_downsample(void)
{
    /* 4x2, channel value = x + 10 y (+ 100 c), factor 2 -> 2x1. */
    pf_image_t src, dst;
    CHECK(pf_image_alloc(&src, 4, 2) == PF_OK);
    for (int y = 0; y < 2; y++)
        for (int x = 0; x < 4; x++)
            for (int c = 0; c < 3; c++)
                s_px(&src, x, y)[c] = (float)(x + 10 * y + 100 * c);
    CHECK(pf_image_downsample(&src, 2, &dst) == PF_OK);
    CHECK(dst.width == 2 && dst.height == 1);
    if (dst.rgb) {
        CHECK(dst.rgb[0] == 5.5f && dst.rgb[1] == 105.5f && dst.rgb[2] == 205.5f); /* (0+1+10+11)/4 */
        CHECK(dst.rgb[3] == 7.5f && dst.rgb[5] == 207.5f);                      /* (2+3+12+13)/4 */
    }
    pf_image_free(&dst);
    CHECK(pf_image_downsample(&src, 1, &dst) == PF_OK);
    CHECK(dst.width == 4 && dst.height == 2 && dst.rgb && memcmp(dst.rgb, src.rgb, 24 * sizeof(float)) == 0);
    pf_image_free(&dst);
    CHECK(pf_image_downsample(&src, 3, &dst) == PF_EINVAL && dst.rgb == NULL);
    CHECK(pf_image_downsample(&src, 0, &dst) == PF_EINVAL);
    CHECK(pf_image_downsample(&src, -2, &dst) == PF_EINVAL);
    pf_image_free(&src);

    /* Compensated sums: a block (v, 0.5; 0.5, -v) with v = 1e17 averages to
     * 0.25; a plain double sum loses both halves against v and gives 0. */
    CHECK(pf_image_alloc(&src, 2, 2) == PF_OK);
    const float v = 1e17f;
    for (int c = 0; c < 3; c++) {
        s_px(&src, 0, 0)[c] = v;
        s_px(&src, 1, 0)[c] = 0.5f;
        s_px(&src, 0, 1)[c] = 0.5f;
        s_px(&src, 1, 1)[c] = -v;
    }
    CHECK(pf_image_downsample(&src, 2, &dst) == PF_OK);
    CHECK(dst.rgb && dst.rgb[0] == 0.25f && dst.rgb[2] == 0.25f);
    pf_image_free(&dst);
    pf_image_free(&src);
}

static void s_fill(pf_image_t *img, float r, float g, float b)
{
    for (size_t i = 0; i < (size_t)img->width * (size_t)img->height; i++) {
        img->rgb[3 * i] = r;
        img->rgb[3 * i + 1] = g;
        img->rgb[3 * i + 2] = b;
    }
}

static void test_metrics(void)
{
    pf_image_t a, b;
    pf_metrics_t m;
    pf_error_t err;

    /* Identical images. */
    CHECK(pf_image_alloc(&a, 3, 2) == PF_OK && pf_image_alloc(&b, 3, 2) == PF_OK);
    for (int i = 0; i < 18; i++)
        a.rgb[i] = b.rgb[i] = 0.1f * (float)i;
    CHECK(pf_metrics_compare(&a, &b, &m, &err) == PF_OK);
    CHECK(m.relmse == 0.0 && m.rmse == 0.0 && m.lum_ratio == 1.0);
    CHECK(m.width == 3 && m.height == 2 && m.factor_a == 1 && m.factor_b == 1);

    /* A constant offset: b = 0.5, a = 0.75 everywhere. (a-b)^2 = 0.0625,
     * relMSE = 0.0625 / 0.26, RMSE = 0.25; luminance weights sum to one, so
     * the ratio is 1.5. */
    s_fill(&a, 0.75f, 0.75f, 0.75f);
    s_fill(&b, 0.5f, 0.5f, 0.5f);
    CHECK(pf_metrics_compare(&a, &b, &m, &err) == PF_OK);
    CHECK_NEAR(m.relmse, 0.0625 / 0.26, 1e-12);
    CHECK_NEAR(m.rmse, 0.25, 1e-12);
    CHECK_NEAR(m.lum_ratio, 1.5, 1e-12);
    /* The reference is the second argument: swapping changes relMSE. */
    CHECK(pf_metrics_compare(&b, &a, &m, &err) == PF_OK);
    CHECK_NEAR(m.relmse, 0.0625 / (0.5625 + 0.01), 1e-12);
    CHECK_NEAR(m.lum_ratio, 0.5 / 0.75, 1e-12);
    pf_image_free(&a);
    pf_image_free(&b);

    /* Per-channel terms: a = (1, 0, 0), b = (0, 0, 1) at one pixel. */
    CHECK(pf_image_alloc(&a, 1, 1) == PF_OK && pf_image_alloc(&b, 1, 1) == PF_OK);
    s_fill(&a, 1, 0, 0);
    s_fill(&b, 0, 0, 1);
    CHECK(pf_metrics_compare(&a, &b, &m, &err) == PF_OK);
    CHECK_NEAR(m.relmse, (1.0 / 0.01 + 1.0 / 1.01) / 3.0, 1e-9);
    CHECK_NEAR(m.rmse, sqrt(2.0 / 3.0), 1e-12);
    CHECK_NEAR(m.lum_ratio, 0.2126 / 0.0722, 1e-12);

    /* A black reference: the ratio is infinite, or undefined when both are black. */
    s_fill(&a, 0.5f, 0.5f, 0.5f);
    s_fill(&b, 0, 0, 0);
    CHECK(pf_metrics_compare(&a, &b, &m, &err) == PF_OK);
    CHECK(isinf(m.lum_ratio) && m.lum_ratio > 0);
    CHECK_NEAR(m.relmse, 0.25 / 0.01, 1e-9);
    s_fill(&a, 0, 0, 0);
    CHECK(pf_metrics_compare(&a, &b, &m, &err) == PF_OK);
    CHECK(isnan(m.lum_ratio) && m.relmse == 0.0);
    pf_image_free(&a);
    pf_image_free(&b);

    /* Size mismatches: not a multiple; different factors in x and y. */
    int sizes[][4] = { { 3, 3, 2, 2 }, { 4, 2, 2, 2 }, { 4, 4, 2, 1 }, { 2, 2, 4, 6 }, { 2, 3, 3, 2 } };
    for (size_t i = 0; i < sizeof sizes / sizeof sizes[0]; i++) {
        CHECK(pf_image_alloc(&a, sizes[i][0], sizes[i][1]) == PF_OK);
        CHECK(pf_image_alloc(&b, sizes[i][2], sizes[i][3]) == PF_OK);
        err.msg[0] = '\0';
        CHECK(pf_metrics_compare(&a, &b, &m, &err) == PF_ESIZE);
        char sa[32], sb[32];
        snprintf(sa, sizeof sa, "%dx%d", sizes[i][0], sizes[i][1]);
        snprintf(sb, sizeof sb, "%dx%d", sizes[i][2], sizes[i][3]);
        CHECK(strstr(err.msg, sa) && strstr(err.msg, sb));
        pf_image_free(&a);
        pf_image_free(&b);
    }

    /* Integer factors in both directions. The 4x4 image is a pattern whose
     * 2x2 block means are (1.5, 3.5; 5.5, 7.5); any other reduction (say,
     * taking one sample per block) differs from the 2x2 image. */
    pf_image_t big, small;
    CHECK(pf_image_alloc(&big, 4, 4) == PF_OK && pf_image_alloc(&small, 2, 2) == PF_OK);
    for (int y = 0; y < 4; y++)
        for (int x = 0; x < 4; x++)
            for (int c = 0; c < 3; c++)
                s_px(&big, x, y)[c] = (float)((y / 2) * 4 + (x / 2) * 2 + (x % 2) + (y % 2) + c);
    for (int y = 0; y < 2; y++)
        for (int x = 0; x < 2; x++)
            for (int c = 0; c < 3; c++)
                s_px(&small, x, y)[c] = (float)(y * 4 + x * 2 + 1 + c);
    CHECK(pf_metrics_compare(&big, &small, &m, &err) == PF_OK);
    CHECK(m.relmse == 0.0 && m.rmse == 0.0 && m.lum_ratio == 1.0);
    CHECK(m.factor_a == 2 && m.factor_b == 1 && m.width == 2 && m.height == 2);
    CHECK(pf_metrics_compare(&small, &big, &m, &err) == PF_OK);
    CHECK(m.relmse == 0.0 && m.rmse == 0.0);
    CHECK(m.factor_a == 1 && m.factor_b == 2 && m.width == 2 && m.height == 2);
    /* And a non-zero error after downsampling: small + 1 against big. */
    for (int i = 0; i < 12; i++)
        small.rgb[i] += 1.0f;
    CHECK(pf_metrics_compare(&small, &big, &m, &err) == PF_OK);
    CHECK_NEAR(m.rmse, 1.0, 1e-12);

    /* Non-finite values in the image make the error infinite, also when the
     * image is downsampled first. */
    big.rgb[7] = NAN;
    CHECK(pf_metrics_compare(&big, &small, &m, &err) == PF_OK);
    CHECK(isinf(m.relmse) && m.relmse > 0 && isinf(m.rmse) && !(m.relmse < 1e30));
    small.rgb[4] = INFINITY;
    pf_image_t copy;
    CHECK(pf_image_alloc(&copy, 2, 2) == PF_OK);
    CHECK(pf_metrics_compare(&small, &copy, &m, &err) == PF_OK);
    CHECK(isinf(m.relmse) && isinf(m.rmse));
    small.rgb[4] = -INFINITY;
    CHECK(pf_metrics_compare(&small, &copy, &m, &err) == PF_OK);
    CHECK(isinf(m.relmse) && m.relmse > 0);
    /* A non-finite reference is refused. */
    CHECK(pf_metrics_compare(&copy, &small, &m, &err) == PF_ERANGE);
    CHECK(strstr(err.msg, "non-finite") != NULL);
    pf_image_free(&copy);
    pf_image_free(&big);
    pf_image_free(&small);

    /* Compensated luminance sums: pixel 0 has luminance L = 1e17, the last
     * -L, the rest 0.5 (image) and 0.25 (reference). Plain double sums drop
     * every 0.5 against L and end at 0 / 0; the true ratio is 2. */
    CHECK(pf_image_alloc(&a, 64, 64) == PF_OK && pf_image_alloc(&b, 64, 64) == PF_OK);
    s_fill(&a, 0.5f, 0.5f, 0.5f);
    s_fill(&b, 0.25f, 0.25f, 0.25f);
    size_t last = 64 * 64 - 1;
    for (int c = 0; c < 3; c++) {
        a.rgb[c] = b.rgb[c] = 1e17f;
        a.rgb[3 * last + (size_t)c] = b.rgb[3 * last + (size_t)c] = -1e17f;
    }
    CHECK(pf_metrics_compare(&a, &b, &m, &err) == PF_OK);
    CHECK_NEAR(m.lum_ratio, 2.0, 1e-12);
    CHECK_NEAR(m.relmse, (0.0625 / 0.0725) * (double)(64 * 64 - 2) / (64.0 * 64.0), 1e-12);
    pf_image_free(&a);
    pf_image_free(&b);
}

/* The shared references: the 512 image downsampled by 4 against the 128 one.
 * Both come from one 1024 image box-downsampled (by 2 and by 8) and stored
 * as float, so they agree to float rounding. */
static void test_references(void)
{
    const char *dir = "../shared/references";
    char p512[256], p256[256], p128[256];
    snprintf(p512, sizeof p512, "%s/cornell-box-512.pfm", dir);
    snprintf(p256, sizeof p256, "%s/cornell-box-256.pfm", dir);
    snprintf(p128, sizeof p128, "%s/cornell-box-128.pfm", dir);
    if (!s_exists(p512) || !s_exists(p128) || !s_exists(p256)) {
        printf("note: %s not found; skipping the reference-image checks\n", dir);
        return;
    }
    pf_image_t i512, i256, i128;
    pf_error_t err;
    CHECK(pf_image_read_pfm(&i512, p512, &err) == PF_OK);
    CHECK(pf_image_read_pfm(&i256, p256, &err) == PF_OK);
    CHECK(pf_image_read_pfm(&i128, p128, &err) == PF_OK);
    if (i512.rgb && i256.rgb && i128.rgb) {
        size_t neg = 0;
        CHECK(pf_image_count_bad(&i512, &neg) == 0 && neg == 0);
        pf_metrics_t m;
        CHECK(pf_metrics_compare(&i512, &i128, &m, &err) == PF_OK);
        printf("cornell-box 512/4 vs 128: relMSE %.3g RMSE %.3g lum %.9f\n", m.relmse, m.rmse, m.lum_ratio);
        CHECK(m.factor_a == 4 && m.width == 128);
        /* Observed: relMSE 2.9e-19, RMSE 6.7e-11 (float rounding of the means). */
        CHECK(m.relmse < 1e-15);
        CHECK(fabs(m.lum_ratio - 1.0) < 1e-9);
        CHECK(pf_metrics_compare(&i128, &i256, &m, &err) == PF_OK);
        printf("cornell-box 128 vs 256/2: relMSE %.3g\n", m.relmse);
        CHECK(m.factor_b == 2 && m.relmse < 1e-15);
        /* A real difference is visible: the 128 image against the 512 one
         * shifted by one pixel is far off. */
        pf_image_t shifted;
        CHECK(pf_image_alloc(&shifted, 512, 512) == PF_OK);
        memcpy(shifted.rgb, i512.rgb + 3 * 4 * 512, (size_t)508 * 512 * 3 * sizeof(float));
        CHECK(pf_metrics_compare(&shifted, &i128, &m, &err) == PF_OK);
        CHECK(m.relmse > 1e-3);
        pf_image_free(&shifted);
    }
    pf_image_free(&i512);
    pf_image_free(&i256);
    pf_image_free(&i128);
}

/* Runs pf_cli_compare with stdout and stderr captured into files. */
static int s_run_compare(char **out, char **errs, int argc, ...)
{
    char *argv[16];
    va_list ap;
    va_start(ap, argc);
    for (int i = 0; i < argc && i < 15; i++)
        argv[i] = va_arg(ap, char *);
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
    *out = (char *)s_read_all(po, &n);
    *errs = (char *)s_read_all(pe, &n);
    unlink(po);
    unlink(pe);
    return code;
}

static void test_cli(void)
{
    pf_image_t a, b, c;
    pf_error_t err;
    CHECK(pf_image_alloc(&a, 4, 4) == PF_OK && pf_image_alloc(&b, 2, 2) == PF_OK && pf_image_alloc(&c, 3, 3) == PF_OK);
    s_fill(&a, 0.75f, 0.75f, 0.75f);
    s_fill(&b, 0.5f, 0.5f, 0.5f);
    char pa[256], pb[256], pc[256], pbad[256], pnan[256];
    snprintf(pa, sizeof pa, "%s", s_path("image.pfm"));
    snprintf(pb, sizeof pb, "%s", s_path("ref.pfm"));
    snprintf(pc, sizeof pc, "%s", s_path("odd.pfm"));
    snprintf(pbad, sizeof pbad, "%s", s_path("bad.pfm"));
    snprintf(pnan, sizeof pnan, "%s", s_path("nan.pfm"));
    CHECK(pf_image_write_pfm(&a, pa, &err) == PF_OK);
    CHECK(pf_image_write_pfm(&b, pb, &err) == PF_OK);
    CHECK(pf_image_write_pfm(&c, pc, &err) == PF_OK);
    s_write_bytes(pbad, "PF\n2 2\n-1.0\nshort", 17);
    a.rgb[5] = NAN;
    CHECK(pf_image_write_pfm(&a, pnan, &err) == PF_OK);

    char *out, *errs;
    int code = s_run_compare(&out, &errs, 3, "compare", pa, pb);
    CHECK(code == 0);
    CHECK(out && strstr(out, "downsampled x2 to 2x2") && strstr(out, "(4x4") && strstr(out, "reference "));
    CHECK(out && strstr(out, "relMSE     0.240385\n") && strstr(out, "RMSE       0.25\n"));
    CHECK(out && strstr(out, "luminance  1.5 (image / reference)"));
    free(out);
    free(errs);

    /* JSON, parsed back; the option may come first. */
    code = s_run_compare(&out, &errs, 4, "compare", "--json", pa, pb);
    CHECK(code == 0);
    cJSON *j = out ? cJSON_Parse(out) : NULL;
    CHECK(j != NULL);
    if (j) {
        CHECK(cJSON_IsNumber(cJSON_GetObjectItem(j, "relmse")));
        CHECK_NEAR(cJSON_GetNumberValue(cJSON_GetObjectItem(j, "relmse")), 0.0625 / 0.26, 1e-12);
        CHECK_NEAR(cJSON_GetNumberValue(cJSON_GetObjectItem(j, "rmse")), 0.25, 1e-12);
        CHECK_NEAR(cJSON_GetNumberValue(cJSON_GetObjectItem(j, "lum_ratio")), 1.5, 1e-12);
        CHECK(cJSON_GetNumberValue(cJSON_GetObjectItem(j, "width")) == 2);
        CHECK(cJSON_GetNumberValue(cJSON_GetObjectItem(j, "height")) == 2);
        CHECK(cJSON_GetNumberValue(cJSON_GetObjectItem(j, "nonfinite")) == 0);
        cJSON_Delete(j);
    }
    CHECK(out && strchr(out, '\n') == out + strlen(out) - 1); /* one line */
    free(out);
    free(errs);

    /* A NaN image: still a comparison (exit 0), but never a good one. */
    code = s_run_compare(&out, &errs, 4, "compare", pnan, pb, "--json");
    CHECK(code == 0);
    j = out ? cJSON_Parse(out) : NULL;
    CHECK(j && cJSON_IsNull(cJSON_GetObjectItem(j, "relmse")) && cJSON_IsNull(cJSON_GetObjectItem(j, "rmse")));
    CHECK(j && cJSON_GetNumberValue(cJSON_GetObjectItem(j, "nonfinite")) == 1);
    cJSON_Delete(j);
    CHECK(errs && strstr(errs, pnan) && strstr(errs, "non-finite"));
    free(out);
    free(errs);
    code = s_run_compare(&out, &errs, 3, "compare", pnan, pb);
    CHECK(code == 0 && out && strstr(out, "relMSE     inf"));
    free(out);
    free(errs);

    code = s_run_compare(&out, &errs, 2, "compare", "--help");
    CHECK(code == 0 && out && strstr(out, "usage: photonfarm compare"));
    free(out);
    free(errs);
    code = s_run_compare(&out, &errs, 3, "compare", pa, "-h");
    CHECK(code == 0 && out && strstr(out, "usage:"));
    free(out);
    free(errs);

    /* Usage errors: 2, with the usage on stderr and nothing on stdout. */
    code = s_run_compare(&out, &errs, 1, "compare");
    CHECK(code == 2 && errs && strstr(errs, "usage:") && out && out[0] == '\0');
    free(out);
    free(errs);
    code = s_run_compare(&out, &errs, 2, "compare", pa);
    CHECK(code == 2);
    free(out);
    free(errs);
    code = s_run_compare(&out, &errs, 4, "compare", pa, pb, pc);
    CHECK(code == 2);
    free(out);
    free(errs);
    code = s_run_compare(&out, &errs, 4, "compare", pa, pb, "--jsn");
    CHECK(code == 2 && errs && strstr(errs, "--jsn"));
    free(out);
    free(errs);

    /* Unreadable and malformed input: 3, naming the file. */
    const char *missing = s_path("missing.pfm");
    code = s_run_compare(&out, &errs, 3, "compare", missing, pb);
    CHECK(code == 3 && errs && strstr(errs, missing));
    free(out);
    free(errs);
    code = s_run_compare(&out, &errs, 3, "compare", pa, pbad);
    CHECK(code == 3 && errs && strstr(errs, pbad) && strstr(errs, "expected 48 bytes"));
    free(out);
    free(errs);
    /* A NaN reference is bad input, not a result. */
    code = s_run_compare(&out, &errs, 3, "compare", pb, pnan);
    CHECK(code == 3 && errs && strstr(errs, pnan));
    free(out);
    free(errs);

    /* Sizes that do not fit: 4, naming both files and sizes. */
    code = s_run_compare(&out, &errs, 3, "compare", pc, pb);
    CHECK(code == 4 && errs && strstr(errs, pc) && strstr(errs, pb) && strstr(errs, "3x3") && strstr(errs, "2x2"));
    free(out);
    free(errs);

    pf_image_free(&a);
    pf_image_free(&b);
    pf_image_free(&c);
    unlink(pa);
    unlink(pb);
    unlink(pc);
    unlink(pbad);
    unlink(pnan);
}

/* Removes the temporary directory and anything a failed test left in it. */
static void s_cleanup(void)
{
    DIR *d = opendir(s_dir);
    if (d) {
        struct dirent *e;
        while ((e = readdir(d)) != NULL) {
            if (strcmp(e->d_name, ".") != 0 && strcmp(e->d_name, "..") != 0)
                unlink(s_path(e->d_name));
        }
        closedir(d);
    }
    rmdir(s_dir);
}

int main(void)
{
    snprintf(s_dir, sizeof s_dir, "/tmp/pf_test_image_XXXXXX");
    if (!mkdtemp(s_dir)) {
        fprintf(stderr, "mkdtemp: %s\n", strerror(errno));
        return 1;
    }
    test_alloc();
    test_count_bad();
    test_pfm_roundtrip();
    test_pfm_big_endian();
    test_pfm_greyscale_and_header_variants();
    test_pfm_malformed();
    test_pfm_fifo();
    test_png();
    test_downsample();
    test_metrics();
    test_references();
    test_cli();
    s_cleanup();
    printf("%d passed, %d failed\n", s_passed, s_failed);
    return s_failed ? 1 : 0;
}
