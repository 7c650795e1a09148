/* exr.c: OpenEXR input and output through tinyexr (Debian's libtinyexr),
 * and the choice of an HDR codec by file extension. Output is RGB, 32-bit
 * float (exact for everything the renderer makes) or 16-bit half, ZIP
 * compressed, written to "PATH.tmp" and renamed over PATH like the other
 * writers. Input takes the R, G and B channels of a single-part scanline or
 * tiled image (a missing channel is zero, a greyscale image is grey); the
 * header is read first and the size checked against the same limit as a
 * PFM's before any pixel is decoded. Every error names the file.
 *
 * No shared state: any thread may call any function on distinct images. */
#include "image/image.h"

#include <errno.h>
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <strings.h>
#include <tinyexr.h>

/* The largest image read: the PFM reader's limit (image.c). */
#define S_MAX_PIXELS ((size_t)1 << 28)

int pf_image_path_is_exr(const char *path)
{
    size_t n = path ? strlen(path) : 0;
    return n >= 4 && strcasecmp(path + n - 4, ".exr") == 0;
}

/* The image's size from its header, checked, before anything is decoded. */
static int s_exr_size(const char *path, pf_error_t *err)
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
        return PF_EPARSE;
    }
    long long w = (long long)header.data_window.max_x - header.data_window.min_x + 1;
    long long h = (long long)header.data_window.max_y - header.data_window.min_y + 1;
    FreeEXRHeader(&header);
    if (w <= 0 || h <= 0 || (unsigned long long)w * (unsigned long long)h > S_MAX_PIXELS)
        return pf_error_set(err, PF_EPARSE, path, 0, "image size %lldx%lld is out of range (at most %zu pixels)", w,
                            h, S_MAX_PIXELS);
    return PF_OK;
}

int pf_image_read_exr(pf_image_t *img, const char *path, pf_error_t *err)
{
    PF_CHECK(img != NULL && path != NULL);
    memset(img, 0, sizeof *img);
    int rc = s_exr_size(path, err);
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
    if (rename(tmp, path) != 0) {
        int e = errno;
        remove(tmp);
        return pf_error_set(err, PF_EIO, path, 0, "cannot rename %s into place: %s", tmp, strerror(e));
    }
    return PF_OK;
}

int pf_image_read_hdr(pf_image_t *img, const char *path, pf_error_t *err)
{
    return pf_image_path_is_exr(path) ? pf_image_read_exr(img, path, err) : pf_image_read_pfm(img, path, err);
}

int pf_image_write_hdr(const pf_image_t *img, const char *path, pf_error_t *err)
{
    return pf_image_path_is_exr(path) ? pf_image_write_exr(img, path, 0, err) : pf_image_write_pfm(img, path, err);
}
