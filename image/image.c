/* image.c: linear RGB float images and their file formats. This module owns
 * the pixel buffer of a pf_image_t (allocated by pf_image_alloc or
 * pf_image_read_pfm, released by pf_image_free) and the two codecs:
 *
 * - PNG output through libpng: 8 bits per channel, the sRGB transfer function
 *   applied after scaling by 2^exposure, with an sRGB chunk so viewers do not
 *   guess the colour space.
 * - PFM input and output: little-endian "PF" on output; on input "PF" and
 *   greyscale "Pf" in either byte order. The file stores the bottom row
 *   first; memory holds the top row first, and the codec flips.
 *
 * Both writers are atomic: they write "PATH.tmp", fsync it, rename it over
 * PATH and fsync the directory, so a reader never sees half an image, and
 * after a crash or a power cut PATH is the old file or the whole new one (a
 * crash leaves at most the .tmp file). The
 * PFM reader trusts nothing in the file: the header is parsed strictly, the
 * size is limited before anything is allocated, and the pixel data must be
 * exactly as long as the header says. Every error names the file.
 *
 * No shared state: any thread may call any function on distinct images. */
#include "image/image.h"
#include "base/atomicfile.h"

#include <errno.h>
#include <math.h>
#include <png.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <fcntl.h>
#include <sys/stat.h>
#include <unistd.h>

/* The largest image accepted anywhere: 2^28 pixels (3 GiB of floats). It is
 * far above any render this program makes, and low enough that a corrupt
 * header cannot ask for an allocation that overflows or exhausts memory. */
#define S_MAX_PIXELS ((size_t)1 << 28)

/* Longest PFM header we parse. Real headers are under 32 bytes; the slack is
 * for generous whitespace. */
#define S_PFM_HEAD_MAX 256

/* On success img holds a zeroed (black) width x height image. On failure it
 * is left empty ({0, 0, NULL}), so pf_image_free on it is always safe. */
int pf_image_alloc(pf_image_t *img, int width, int height)
{
    PF_CHECK(img != NULL);
    img->width = 0;
    img->height = 0;
    img->rgb = NULL;
    if (width <= 0 || height <= 0)
        return PF_EINVAL;
    size_t pixels = (size_t)width * (size_t)height; /* cannot overflow: both < 2^31 */
    if (pixels > S_MAX_PIXELS || pixels > SIZE_MAX / (3 * sizeof(float)))
        return PF_EINVAL;
    float *rgb = calloc(pixels * 3, sizeof(float));
    if (!rgb)
        return PF_ENOMEM;
    img->width = width;
    img->height = height;
    img->rgb = rgb;
    return PF_OK;
}

/* NULL-safe; leaves img empty so a second call does nothing. */
void pf_image_free(pf_image_t *img)
{
    if (!img)
        return;
    free(img->rgb);
    img->rgb = NULL;
    img->width = 0;
    img->height = 0;
}

/* Returns the number of NaN and infinite channel values. When negative is not
 * NULL it receives the number of finite values below zero (-0.0 does not
 * count); the two counts are disjoint, so -inf counts only as non-finite. */
size_t pf_image_count_bad(const pf_image_t *img, size_t *negative)
{
    PF_CHECK(img != NULL);
    size_t n = (size_t)img->width * (size_t)img->height * 3;
    size_t bad = 0, neg = 0;
    for (size_t i = 0; i < n; i++) {
        float v = img->rgb[i];
        if (!isfinite(v))
            bad++;
        else if (v < 0.0f)
            neg++;
    }
    if (negative)
        *negative = neg;
    return bad;
}

/* ---- atomic output -------------------------------------------------------- */

/* The writers go through base/atomicfile.h: PATH.tmp, fsync, rename, fsync
 * of the directory. */

/* ---- PNG ------------------------------------------------------------------ */

/* Scaled linear value to an 8-bit sRGB code: clamp to [0, 1] (NaN goes to 0,
 * so a bad pixel shows black rather than poisoning anything), apply the sRGB
 * transfer function (IEC 61966-2-1) and round to nearest. */
static unsigned char s_srgb_byte(double v)
{
    if (!(v > 0.0))
        return 0;
    if (v >= 1.0)
        return 255;
    double s = v <= 0.0031308 ? 12.92 * v : 1.055 * pow(v, 1.0 / 2.4) - 0.055;
    long q = lround(s * 255.0);
    return (unsigned char)(q < 0 ? 0 : q > 255 ? 255 : q);
}

typedef struct s_png_ctx {
    char msg[256];
} s_png_ctx_t;

/* libpng's error callback: keep the message for the caller's report, then
 * unwind to the setjmp in pf_image_write_png. It must not return. */
static void s_png_error(png_structp png, png_const_charp msg)
{
    s_png_ctx_t *ctx = png_get_error_ptr(png);
    if (ctx)
        snprintf(ctx->msg, sizeof ctx->msg, "%s", msg ? msg : "unknown error");
    png_longjmp(png, 1);
}

/* Warnings concern things this writer does not use (text chunks, ancillary
 * data); dropping them keeps stderr for real problems. */
static void s_png_warning(png_structp png, png_const_charp msg)
{
    (void)png;
    (void)msg;
}

/* Writes img to path as an 8-bit RGB PNG, each channel multiplied by
 * 2^exposure, clamped to [0, 1] and sRGB-encoded; atomic via PATH.tmp.
 * Returns 0, PF_EINVAL (non-finite exposure or empty image), PF_ENOMEM or
 * PF_EIO with err naming the file and libpng's or the system's message. */
int pf_image_write_png(const pf_image_t *img, const char *path, float exposure, pf_error_t *err)
{
    PF_CHECK(img != NULL && path != NULL);
    if (!img->rgb || img->width <= 0 || img->height <= 0)
        return pf_error_set(err, PF_EINVAL, path, 0, "cannot write an empty image");
    if (!isfinite(exposure))
        return pf_error_set(err, PF_EINVAL, path, 0, "exposure %g is not finite", (double)exposure);

    const double scale = exp2((double)exposure);
    const size_t w = (size_t)img->width;
    char *tmp = pf_file_tmp_path(path);
    unsigned char *row = malloc(w * 3);
    if (!tmp || !row) {
        free(tmp);
        free(row);
        return pf_error_set(err, PF_ENOMEM, path, 0, "out of memory");
    }
    FILE *fp = fopen(tmp, "wb");
    if (!fp) {
        int e = errno;
        int st = pf_error_set(err, PF_EIO, path, 0, "cannot create %s: %s", tmp, strerror(e));
        free(tmp);
        free(row);
        return st;
    }

    s_png_ctx_t ctx = { .msg = "" };
    png_structp png = png_create_write_struct(PNG_LIBPNG_VER_STRING, &ctx, s_png_error, s_png_warning);
    png_infop info = png ? png_create_info_struct(png) : NULL;
    if (!png || !info) {
        png_destroy_write_struct(&png, NULL);
        fclose(fp);
        remove(tmp);
        free(tmp);
        free(row);
        return pf_error_set(err, PF_ENOMEM, path, 0, "libpng: cannot create write structures");
    }
    /* Every object the error path releases (fp, tmp, row, png, info) was
     * created before setjmp and is not reassigned afterwards, so none needs
     * to be volatile to survive the longjmp. */
    if (setjmp(png_jmpbuf(png))) {
        png_destroy_write_struct(&png, &info);
        fclose(fp);
        remove(tmp);
        int st = pf_error_set(err, PF_EIO, path, 0, "libpng: %s", ctx.msg[0] ? ctx.msg : "unknown error");
        free(tmp);
        free(row);
        return st;
    }

    png_init_io(png, fp);
    png_set_IHDR(png, info, (png_uint_32)img->width, (png_uint_32)img->height, 8, PNG_COLOR_TYPE_RGB,
                 PNG_INTERLACE_NONE, PNG_COMPRESSION_TYPE_DEFAULT, PNG_FILTER_TYPE_DEFAULT);
    /* sRGB plus the matching gAMA and cHRM, for decoders that know only those. */
    png_set_sRGB_gAMA_and_cHRM(png, info, PNG_sRGB_INTENT_PERCEPTUAL);
    png_write_info(png, info);
    for (int y = 0; y < img->height; y++) {
        const float *src = img->rgb + (size_t)y * w * 3;
        for (size_t i = 0; i < w * 3; i++)
            row[i] = s_srgb_byte((double)src[i] * scale);
        png_write_row(png, row);
    }
    png_write_end(png, info);
    png_destroy_write_struct(&png, &info);
    free(row);

    int st = pf_file_commit(fp, tmp, path, err);
    free(tmp);
    return st;
}

/* ---- PFM output ----------------------------------------------------------- */

static void s_put_le32(unsigned char *p, float f)
{
    uint32_t u;
    memcpy(&u, &f, sizeof u);
    p[0] = (unsigned char)(u & 0xff);
    p[1] = (unsigned char)((u >> 8) & 0xff);
    p[2] = (unsigned char)((u >> 16) & 0xff);
    p[3] = (unsigned char)(u >> 24);
}

/* Writes img to path as a little-endian colour PFM (scale -1.0), bottom row
 * first as the format requires; atomic via PATH.tmp. The floats are written
 * bit for bit, NaN and infinities included: this is the lossless format.
 * Returns 0, PF_EINVAL, PF_ENOMEM or PF_EIO with err naming the file. */
int pf_image_write_pfm(const pf_image_t *img, const char *path, pf_error_t *err)
{
    PF_CHECK(img != NULL && path != NULL);
    if (!img->rgb || img->width <= 0 || img->height <= 0)
        return pf_error_set(err, PF_EINVAL, path, 0, "cannot write an empty image");

    const size_t w = (size_t)img->width;
    char *tmp = pf_file_tmp_path(path);
    unsigned char *row = malloc(w * 12);
    if (!tmp || !row) {
        free(tmp);
        free(row);
        return pf_error_set(err, PF_ENOMEM, path, 0, "out of memory");
    }
    FILE *fp = fopen(tmp, "wb");
    if (!fp) {
        int e = errno;
        int st = pf_error_set(err, PF_EIO, path, 0, "cannot create %s: %s", tmp, strerror(e));
        free(tmp);
        free(row);
        return st;
    }

    int ok = fprintf(fp, "PF\n%d %d\n-1.0\n", img->width, img->height) > 0;
    for (int y = img->height - 1; ok && y >= 0; y--) {
        const float *src = img->rgb + (size_t)y * w * 3;
        for (size_t i = 0; i < w * 3; i++)
            s_put_le32(row + 4 * i, src[i]);
        ok = fwrite(row, 1, w * 12, fp) == w * 12;
    }
    free(row);
    if (!ok) {
        int e = errno;
        fclose(fp);
        remove(tmp);
        int st = pf_error_set(err, PF_EIO, path, 0, "cannot write %s: %s", tmp, strerror(e));
        free(tmp);
        return st;
    }
    int st = pf_file_commit(fp, tmp, path, err);
    free(tmp);
    return st;
}

/* ---- PFM input ------------------------------------------------------------ */

static int s_is_space(unsigned char c)
{
    return c == ' ' || c == '\t' || c == '\n' || c == '\r' || c == '\v' || c == '\f';
}

/* A cursor over the header bytes read so far. `full` says the buffer was
 * filled to S_PFM_HEAD_MAX, so running off its end means "header too long"
 * rather than "file truncated". */
typedef struct s_head {
    const unsigned char *p;
    size_t n, pos;
    int full;
} s_head_t;

/* Reports running off the end of the header buffer. */
static int s_head_end(const s_head_t *h, const char *path, pf_error_t *err, const char *what)
{
    if (h->full)
        return pf_error_set(err, PF_EPARSE, path, 0, "PFM header too long while reading %s", what);
    return pf_error_set(err, PF_EPARSE, path, 0, "truncated PFM header (file ends before %s)", what);
}

/* Skips at least one whitespace byte. */
static int s_head_space(s_head_t *h, const char *path, pf_error_t *err, const char *before)
{
    if (h->pos >= h->n)
        return s_head_end(h, path, err, before);
    if (!s_is_space(h->p[h->pos]))
        return pf_error_set(err, PF_EPARSE, path, 0, "malformed PFM header: expected whitespace before %s",
                            before);
    while (h->pos < h->n && s_is_space(h->p[h->pos]))
        h->pos++;
    return PF_OK;
}

/* Parses a positive decimal dimension. Anything but digits (a sign, a
 * fraction, an exponent) is malformed; values above the pixel limit are
 * rejected here, before they can reach an allocation. */
static int s_head_dim(s_head_t *h, const char *path, pf_error_t *err, const char *name, int *out)
{
    if (h->pos >= h->n)
        return s_head_end(h, path, err, name);
    if (h->p[h->pos] == '-')
        return pf_error_set(err, PF_EPARSE, path, 0, "malformed PFM header: negative %s", name);
    uint64_t v = 0;
    size_t start = h->pos;
    while (h->pos < h->n && h->p[h->pos] >= '0' && h->p[h->pos] <= '9') {
        v = v * 10 + (uint64_t)(h->p[h->pos] - '0');
        if (v > S_MAX_PIXELS)
            return pf_error_set(err, PF_ERANGE, path, 0, "PFM %s is too large (limit %zu pixels in all)", name,
                                S_MAX_PIXELS);
        h->pos++;
    }
    if (h->pos >= h->n)
        return s_head_end(h, path, err, name);
    if (h->pos == start || !s_is_space(h->p[h->pos]))
        return pf_error_set(err, PF_EPARSE, path, 0, "malformed PFM header: %s is not a decimal number", name);
    if (v == 0)
        return pf_error_set(err, PF_EPARSE, path, 0, "malformed PFM header: %s is zero", name);
    *out = (int)v;
    return PF_OK;
}

static float s_get_float(const unsigned char *p, int little)
{
    uint32_t u = little ? (uint32_t)p[0] | (uint32_t)p[1] << 8 | (uint32_t)p[2] << 16 | (uint32_t)p[3] << 24
                        : (uint32_t)p[3] | (uint32_t)p[2] << 8 | (uint32_t)p[1] << 16 | (uint32_t)p[0] << 24;
    float f;
    memcpy(&f, &u, sizeof f);
    return f;
}

/* Reads pixel bytes: first what is left in the header buffer, then the file. */
typedef struct s_src {
    FILE *fp;
    const unsigned char *pending;
    size_t npending;
} s_src_t;

static size_t s_src_read(s_src_t *s, unsigned char *dst, size_t n)
{
    size_t got = 0;
    if (s->npending) {
        got = n < s->npending ? n : s->npending;
        memcpy(dst, s->pending, got);
        s->pending += got;
        s->npending -= got;
    }
    if (got < n)
        got += fread(dst + got, 1, n - got, s->fp);
    return got;
}

/* Counts the bytes left in the source, for the length error message. */
static uint64_t s_src_drain(s_src_t *s)
{
    uint64_t n = s->npending;
    s->npending = 0;
    unsigned char buf[4096];
    size_t got;
    while ((got = fread(buf, 1, sizeof buf, s->fp)) > 0)
        n += got;
    return n;
}

/* Parses the header in head[0..n) and fills the out parameters; *data_at is
 * the offset of the first pixel byte. file_size is the file's length, or -1
 * when unknown (a pipe); it only serves to recognise a CRLF line ending after
 * the scale. */
static int s_parse_header(s_head_t *h, long long file_size, const char *path, pf_error_t *err, int *width,
                          int *height, int *channels, int *little, float *scale, size_t *data_at)
{
    if (h->n < 2 || h->p[0] != 'P' || (h->p[1] != 'F' && h->p[1] != 'f'))
        return pf_error_set(err, PF_EPARSE, path, 0, "not a PFM file (bad magic; expected \"PF\" or \"Pf\")");
    *channels = h->p[1] == 'F' ? 3 : 1;
    h->pos = 2;
    int st;
    if ((st = s_head_space(h, path, err, "the width")) < 0 || (st = s_head_dim(h, path, err, "width", width)) < 0
        || (st = s_head_space(h, path, err, "the height")) < 0
        || (st = s_head_dim(h, path, err, "height", height)) < 0
        || (st = s_head_space(h, path, err, "the scale")) < 0)
        return st;
    if ((size_t)*width * (size_t)*height > S_MAX_PIXELS)
        return pf_error_set(err, PF_ERANGE, path, 0, "PFM image %dx%d is too large (limit %zu pixels)", *width,
                            *height, S_MAX_PIXELS);

    /* The scale: a decimal float whose sign gives the byte order (negative:
     * little-endian) and whose magnitude scales the pixel values. */
    char tok[64];
    size_t len = 0;
    while (h->pos < h->n && !s_is_space(h->p[h->pos])) {
        if (len + 1 >= sizeof tok)
            return pf_error_set(err, PF_EPARSE, path, 0, "malformed PFM header: scale is too long");
        tok[len++] = (char)h->p[h->pos++];
    }
    tok[len] = '\0';
    if (h->pos >= h->n)
        return s_head_end(h, path, err, "the end of the scale");
    char *end = NULL;
    errno = 0;
    double s = strtod(tok, &end);
    float fs = (float)fabs(s);
    if (len == 0 || end != tok + len || errno == ERANGE || !isfinite(fs) || fs == 0.0f)
        return pf_error_set(err, PF_EPARSE, path, 0,
                            "malformed PFM header: scale \"%s\" is not a finite non-zero number", tok);
    *little = s < 0.0;
    *scale = fs;

    /* Exactly one whitespace byte ends the header; the pixel data may start
     * with any byte, whitespace included. A writer that used CRLF line
     * endings leaves "\r\n"; that is taken as the terminator only when the
     * file length shows the extra byte belongs to the header. */
    size_t expected = (size_t)*width * (size_t)*height * (size_t)*channels * 4;
    h->pos++;
    if (h->p[h->pos - 1] == '\r' && h->pos < h->n && h->p[h->pos] == '\n' && file_size >= 0
        && (unsigned long long)file_size == (unsigned long long)h->pos + 1 + expected)
        h->pos++;
    *data_at = h->pos;
    return PF_OK;
}

/* Reads a PFM file into img (allocated here; top row first in memory).
 * Greyscale "Pf" is replicated into R, G and B. The magnitude of the header's
 * scale multiplies the values when it is not 1, as pbrt reads it; the sign
 * chooses the byte order. Returns 0, or PF_EIO (cannot open or read),
 * PF_EPARSE (bad magic, malformed header, data length not as declared),
 * PF_ERANGE (over the size limit) or PF_ENOMEM, with err naming the file; on
 * failure img is left empty. */
int pf_image_read_pfm(pf_image_t *img, const char *path, pf_error_t *err)
{
    PF_CHECK(img != NULL && path != NULL);
    img->width = 0;
    img->height = 0;
    img->rgb = NULL;

    FILE *fp = fopen(path, "rb");
    if (!fp) {
        int e = errno;
        return pf_error_set(err, PF_EIO, path, 0, "cannot open: %s", strerror(e));
    }
    long long file_size = -1;
    struct stat sb;
    if (fstat(fileno(fp), &sb) == 0 && S_ISREG(sb.st_mode))
        file_size = (long long)sb.st_size;

    unsigned char head[S_PFM_HEAD_MAX];
    size_t nhead = fread(head, 1, sizeof head, fp);
    if (ferror(fp)) {
        int e = errno;
        fclose(fp);
        return pf_error_set(err, PF_EIO, path, 0, "cannot read: %s", strerror(e));
    }
    s_head_t h = { .p = head, .n = nhead, .pos = 0, .full = nhead == sizeof head };
    int width = 0, height = 0, channels = 0, little = 0;
    float scale = 1.0f;
    size_t data_at = 0;
    int st = s_parse_header(&h, file_size, path, err, &width, &height, &channels, &little, &scale, &data_at);
    if (st < 0) {
        fclose(fp);
        return st;
    }

    const size_t row_bytes = (size_t)width * (size_t)channels * 4;
    const uint64_t expected = (uint64_t)row_bytes * (uint64_t)height;
    /* With a known length, reject a short or long file before allocating. */
    if (file_size >= 0 && (uint64_t)file_size - data_at != expected) {
        fclose(fp);
        return pf_error_set(err, PF_EPARSE, path, 0, "expected %llu bytes of pixel data, found %llu",
                            (unsigned long long)expected, (unsigned long long)((uint64_t)file_size - data_at));
    }

    unsigned char *row = malloc(row_bytes);
    if (!row || (st = pf_image_alloc(img, width, height)) < 0) {
        free(row);
        fclose(fp);
        return pf_error_set(err, PF_ENOMEM, path, 0, "out of memory for a %dx%d image", width, height);
    }

    s_src_t src = { .fp = fp, .pending = head + data_at, .npending = nhead - data_at };
    uint64_t found = 0;
    for (int r = 0; r < height; r++) {
        size_t got = s_src_read(&src, row, row_bytes);
        found += got;
        if (got < row_bytes)
            break;
        /* File row r counts from the bottom. */
        float *dst = img->rgb + (size_t)(height - 1 - r) * (size_t)width * 3;
        for (int x = 0; x < width; x++) {
            for (int c = 0; c < 3; c++) {
                const unsigned char *p = row + ((size_t)x * (size_t)channels + (size_t)(channels == 3 ? c : 0)) * 4;
                float v = s_get_float(p, little);
                dst[(size_t)x * 3 + (size_t)c] = scale == 1.0f ? v : v * scale;
            }
        }
    }
    free(row);
    if (ferror(fp)) {
        int e = errno;
        fclose(fp);
        pf_image_free(img);
        return pf_error_set(err, PF_EIO, path, 0, "cannot read: %s", strerror(e));
    }
    if (found == expected)
        found += s_src_drain(&src);
    fclose(fp);
    if (found != expected) {
        pf_image_free(img);
        return pf_error_set(err, PF_EPARSE, path, 0, "expected %llu bytes of pixel data, found %llu",
                            (unsigned long long)expected, (unsigned long long)found);
    }
    return PF_OK;
}
