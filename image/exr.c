/* exr.c: OpenEXR input and output through tinyexr (Debian's libtinyexr),
 * and the choice of an HDR codec by file extension. Output is RGB, 32-bit
 * float (exact for everything the renderer makes) or 16-bit half, ZIP
 * compressed, written to "PATH.tmp", fsynced, renamed over PATH and the
 * directory fsynced, like the other writers. Input takes the R, G and B channels of a single-part scanline or
 * tiled image (a missing channel is zero, a greyscale image is grey); the
 * header is read first and the size checked against the same limit as a
 * PFM's before any pixel is decoded. Every error names the file.
 *
 * No shared state: any thread may call any function on distinct images. */
#include "image/image.h"
#include "base/atomicfile.h"

#include <errno.h>
#include <fcntl.h>
#include <math.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <strings.h>
#include <tinyexr.h>
#include <unistd.h>

/* The largest image read: the PFM reader's limit (image.c). */
#define S_MAX_PIXELS ((size_t)1 << 28)

int pf_image_path_is_exr(const char *path)
{
    size_t n = path ? strlen(path) : 0;
    return n >= 4 && strcasecmp(path + n - 4, ".exr") == 0;
}

/* Scanlines a chunk holds, by compression (the ones tinyexr decodes). */
static int s_lines_per_chunk(int compression)
{
    switch (compression) {
    case TINYEXR_COMPRESSIONTYPE_ZIP: return 16;
    case TINYEXR_COMPRESSIONTYPE_PIZ: return 32;
    default: return 1; /* NONE, RLE, ZIPS */
    }
}

static uint64_t s_le64(const unsigned char *p)
{
    uint64_t v = 0;
    for (int i = 7; i >= 0; i--)
        v = (v << 8) | p[i];
    return v;
}

/* Every chunk the offset table names lies inside the file with its own
 * header. tinyexr leaks what it allocated when a chunk runs past the end of
 * the file (1.0.1), so a truncated or cut file is refused here first. Checked
 * for scanline and single-level tiled images; other tiled images go to
 * tinyexr unchecked. */
static int s_exr_chunks(const char *path, const EXRHeader *h, long long w, long long hgt, pf_error_t *err)
{
    long long nchunks;
    size_t chunk_head;
    if (!h->tiled) {
        int lines = s_lines_per_chunk(h->compression_type);
        nchunks = (hgt + lines - 1) / lines;
        chunk_head = 8; /* y, data size */
    } else if (h->tile_level_mode == TINYEXR_TILE_ONE_LEVEL && h->tile_size_x > 0 && h->tile_size_y > 0) {
        nchunks = ((w + h->tile_size_x - 1) / h->tile_size_x) * ((hgt + h->tile_size_y - 1) / h->tile_size_y);
        chunk_head = 20; /* tile x, y, level x, y, data size */
    } else {
        return PF_OK;
    }
    FILE *fp = fopen(path, "rb");
    if (!fp)
        return pf_error_set(err, PF_EIO, path, 0, "cannot open: %s", strerror(errno));
    int rc = PF_OK;
    long long table = 8 + (long long)h->header_len;
    long long size = (fseek(fp, 0, SEEK_END) == 0) ? (long long)ftell(fp) : -1;
    if (size < 0 || table + 8 * nchunks > size)
        rc = PF_EPARSE;
    for (long long i = 0; rc == PF_OK && i < nchunks; i++) {
        unsigned char b[8], c[4];
        if (fseek(fp, (long)(table + 8 * i), SEEK_SET) != 0 || fread(b, 1, 8, fp) != 8) {
            rc = PF_EPARSE;
            break;
        }
        uint64_t off = s_le64(b);
        if (off < (uint64_t)(table + 8 * nchunks) || off + chunk_head > (uint64_t)size ||
            fseek(fp, (long)(off + chunk_head - 4), SEEK_SET) != 0 || fread(c, 1, 4, fp) != 4) {
            rc = PF_EPARSE;
            break;
        }
        uint32_t len = (uint32_t)c[0] | (uint32_t)c[1] << 8 | (uint32_t)c[2] << 16 | (uint32_t)c[3] << 24;
        if (off + chunk_head + len > (uint64_t)size)
            rc = PF_EPARSE;
    }
    fclose(fp);
    if (rc != PF_OK)
        return pf_error_set(err, rc, path, 0, "truncated or corrupt OpenEXR file: a chunk lies outside the file");
    return PF_OK;
}

/* The image's header checked (its size against the limit, its chunks inside
 * the file) before anything is decoded. */
static int s_exr_check(const char *path, pf_error_t *err)
{
    EXRVersion version;
    int rc = ParseEXRVersionFromFile(&version, path);
    if (rc != TINYEXR_SUCCESS) {
        FILE *fp = fopen(path, "rb");
        if (!fp)
            return pf_error_set(err, PF_EIO, path, 0, "cannot open: %s", strerror(errno));
        fclose(fp);
        return pf_error_set(err, PF_EPARSE, path, 0, "not an OpenEXR file (tinyexr error %d)", rc);
    }
    if (version.multipart || version.non_image)
        return pf_error_set(err, PF_EUNSUPPORTED, path, 0, "multi-part and deep OpenEXR files are not read");
    EXRHeader header;
    InitEXRHeader(&header);
    const char *msg = NULL;
    rc = ParseEXRHeaderFromFile(&header, &version, path, &msg);
    if (rc != TINYEXR_SUCCESS) {
        pf_error_set(err, PF_EPARSE, path, 0, "bad OpenEXR header: %s", msg ? msg : "unknown error");
        FreeEXRErrorMessage(msg);
        FreeEXRHeader(&header); /* a header parsed half-way holds what it read */
        return PF_EPARSE;
    }
    long long w = (long long)header.data_window.max_x - header.data_window.min_x + 1;
    long long h = (long long)header.data_window.max_y - header.data_window.min_y + 1;
    if (w <= 0 || h <= 0 || (unsigned long long)w * (unsigned long long)h > S_MAX_PIXELS)
        rc = pf_error_set(err, PF_EPARSE, path, 0, "image size %lldx%lld is out of range (at most %zu pixels)", w, h,
                          S_MAX_PIXELS);
    else
        rc = s_exr_chunks(path, &header, w, h, err);
    FreeEXRHeader(&header);
    return rc;
}

int pf_image_read_exr(pf_image_t *img, const char *path, pf_error_t *err)
{
    PF_CHECK(img != NULL && path != NULL);
    memset(img, 0, sizeof *img);
    int rc = s_exr_check(path, err);
    if (rc != PF_OK)
        return rc;
    float *rgba = NULL;
    int w = 0, h = 0;
    const char *msg = NULL;
    rc = LoadEXR(&rgba, &w, &h, path, &msg);
    if (rc != TINYEXR_SUCCESS) {
        pf_error_set(err, PF_EPARSE, path, 0, "cannot decode the OpenEXR image: %s", msg ? msg : "unknown error");
        FreeEXRErrorMessage(msg);
        free(rgba);
        return PF_EPARSE;
    }
    rc = pf_image_alloc(img, w, h);
    if (rc != PF_OK) {
        free(rgba);
        return pf_error_set(err, rc, path, 0, "cannot allocate a %dx%d image", w, h);
    }
    size_t n = (size_t)w * (size_t)h;
    for (size_t i = 0; i < n; i++)
        for (int c = 0; c < 3; c++)
            img->rgb[3 * i + (size_t)c] = rgba[4 * i + (size_t)c];
    free(rgba);
    return PF_OK;
}

int pf_image_write_exr(const pf_image_t *img, const char *path, int half, pf_error_t *err)
{
    PF_CHECK(img != NULL && img->rgb != NULL && path != NULL);
    char tmp[4096];
    if (snprintf(tmp, sizeof tmp, "%s.tmp", path) >= (int)sizeof tmp)
        return pf_error_set(err, PF_EINVAL, path, 0, "path too long");
    const char *msg = NULL;
    int rc = SaveEXR(img->rgb, img->width, img->height, 3, half ? 1 : 0, tmp, &msg);
    if (rc != TINYEXR_SUCCESS) {
        pf_error_set(err, PF_EIO, path, 0, "cannot write the OpenEXR image: %s", msg ? msg : "unknown error");
        FreeEXRErrorMessage(msg);
        remove(tmp);
        return PF_EIO;
    }
    /* SaveEXR closed the file: reopen it to fsync it before the rename. */
    return pf_file_commit_closed(tmp, path, err);
}

int pf_image_read_hdr(pf_image_t *img, const char *path, pf_error_t *err)
{
    return pf_image_path_is_exr(path) ? pf_image_read_exr(img, path, err) : pf_image_read_pfm(img, path, err);
}

int pf_image_write_hdr(const pf_image_t *img, const char *path, int half, pf_error_t *err)
{
    return pf_image_path_is_exr(path) ? pf_image_write_exr(img, path, half, err) : pf_image_write_pfm(img, path, err);
}
