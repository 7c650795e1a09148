/* texfile.h: reading a texture's image file: PNG, JPEG, TGA, BMP, GIF,
 * PSD, PNM and Radiance HDR through stb_image (Debian's libstb), PFM and
 * OpenEXR through this layer's own readers. Size limits are checked on the
 * header before anything is decoded. */
#ifndef PF_TEXFILE_H
#define PF_TEXFILE_H

#include <stdint.h>

#include "base/status.h"

/* An image as read: RGB, top row first, in px8 (8-bit as stored in the
 * file, not decoded) or pxf (linear float: HDR, PFM, EXR); the other NULL. */
typedef struct pf_teximage {
    int width, height;
    uint8_t *px8;
    float *pxf;
} pf_teximage_t;

/* Reads path into *out. Images wider or taller than max_side or with more
 * than max_pixels pixels are refused from their header; a file that is not
 * an image, is truncated or is refused gives an error naming the file.
 * 0 or a status with err filled (*out zeroed). */
int pf_teximage_read(const char *path, int max_side, uint64_t max_pixels, pf_teximage_t *out, pf_error_t *err);
void pf_teximage_free(pf_teximage_t *img);

#endif
