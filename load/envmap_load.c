/* envmap_load.c: reads an environment image for the scene readers; see
 * envmap_load.h. The pixels stay float RGB, the smallest form that keeps a
 * sky's range (a sun can be 1e5 times the sky around it). The file is read
 * as a texture image is (image/texfile.h), so a sky may be PFM, OpenEXR,
 * Radiance HDR or any 8-bit image stb_image reads; 8-bit values are
 * sRGB-decoded (pbrt-v4's default encoding for 8-bit images). */
#include "load/envmap_load.h"

#include <math.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "base/log.h"
#include "image/texfile.h"
#include "scene/texture.h"

int pf_envmap_load(const char *path, int mapping, pf_envmap_t *out, size_t *clamped, pf_error_t *err)
{
    memset(out, 0, sizeof *out);
    *clamped = 0;
    pf_teximage_t img = { 0 };
    pf_error_t ierr = { { 0 } };
    int rc = pf_teximage_read(path, PF_ENVMAP_MAX_SIDE, (uint64_t)PF_ENVMAP_MAX_SIDE * PF_ENVMAP_MAX_SIDE, &img, &ierr);
    if (rc)
        return pf_error_set(err, rc, NULL, 0, "environment map: %s", ierr.msg);
    int w = img.width, h = img.height;
    if (mapping == PF_ENVMAP_EQUALAREA && w != h) {
        pf_teximage_free(&img);
        return pf_error_set(err, PF_EPARSE, NULL, 0,
                            "environment map %s is %dx%d: the equal-area mapping needs a square image", path, w, h);
    }
    size_t n = (size_t)w * (size_t)h * 3;
    float *rgb = img.pxf;
    if (img.px8) {
        if (!(rgb = malloc(n * sizeof *rgb))) {
            pf_teximage_free(&img);
            return pf_error_set(err, PF_ENOMEM, NULL, 0, "environment map %s: out of memory for %dx%d pixels", path,
                                w, h);
        }
        for (size_t k = 0; k < n; k++)
            rgb[k] = pf_srgb8_to_linear(img.px8[k]);
        free(img.px8);
    }
    for (size_t k = 0; k < n; k++) {
        if (!(rgb[k] >= 0.0f) || !isfinite(rgb[k])) {
            rgb[k] = 0.0f;
            (*clamped)++;
        }
    }
    size_t len = strlen(path);
    snprintf(out->name, sizeof out->name, "%s", len >= sizeof out->name ? path + len - (sizeof out->name - 1) : path);
    out->width = w;
    out->height = h;
    out->mapping = mapping;
    out->rgb = rgb; /* taken over from img */
    const double id[9] = { 1, 0, 0, 0, 1, 0, 0, 0, 1 };
    pf_envmap_set_frame(out, id);
    pf_info("environment map %s: %dx%d %s, float RGB, %.1f MB", path, out->width, out->height,
            mapping == PF_ENVMAP_EQUALAREA ? "equal-area" : "equirect", (double)pf_envmap_bytes(out) / 1048576.0);
    return PF_OK;
}
