/* image.h: linear RGB float images, PNG output (8-bit sRGB with exposure),
 * PFM and OpenEXR input and output (linear float; exr.c). Rows are stored top row first in
 * memory; the PFM codec converts to and from the format's bottom-up order. */
#ifndef PF_IMAGE_H
#define PF_IMAGE_H

#include <stddef.h>

#include "base/status.h"

typedef struct pf_image {
    int width, height;
    float *rgb; /* width * height * 3, top row first */
} pf_image_t;

/* Allocates a black image; 0 or PF_ENOMEM / PF_EINVAL (non-positive size or too large). */
int pf_image_alloc(pf_image_t *img, int width, int height);
void pf_image_free(pf_image_t *img);

/* Writes 8-bit sRGB PNG: each channel times 2^exposure, clamped, sRGB-encoded. */
int pf_image_write_png(const pf_image_t *img, const char *path, float exposure, pf_error_t *err);
/* Writes little-endian PFM ("PF", scale -1). */
int pf_image_write_pfm(const pf_image_t *img, const char *path, pf_error_t *err);
/* Reads a PFM (colour "PF" or greyscale "Pf", either byte order). Errors name the file. */
int pf_image_read_pfm(pf_image_t *img, const char *path, pf_error_t *err);

/* Reads an OpenEXR image's R, G and B (tinyexr); errors name the file. */
int pf_image_read_exr(pf_image_t *img, const char *path, pf_error_t *err);
/* Writes RGB OpenEXR, 16-bit half when half is set, else 32-bit float. */
int pf_image_write_exr(const pf_image_t *img, const char *path, int half, pf_error_t *err);
/* Whether path ends in ".exr" (any case). */
int pf_image_path_is_exr(const char *path);
/* An HDR image by the path's extension: OpenEXR for ".exr" (written as
 * 32-bit float, or 16-bit half when half is set), PFM otherwise (always
 * float; half is then ignored). */
int pf_image_read_hdr(pf_image_t *img, const char *path, pf_error_t *err);
int pf_image_write_hdr(const pf_image_t *img, const char *path, int half, pf_error_t *err);

/* Counts non-finite and negative channel values. */
size_t pf_image_count_bad(const pf_image_t *img, size_t *negative);

#endif
