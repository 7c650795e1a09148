/* envmap_load.c: reads an environment image for the scene readers; see
 * envmap_load.h. The pixels stay float RGB, the smallest form that keeps a
 * sky's range (a sun can be 1e5 times the sky around it). */
#include "load/envmap_load.h"

#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "base/log.h"
#include "image/image.h"

int pf_envmap_load(const char *path, int mapping, pf_envmap_t *out, size_t *clamped, pf_error_t *err)
{
    memset(out, 0, sizeof *out);
    *clamped = 0;
    pf_image_t img = { 0 };
    pf_error_t ierr = { { 0 } };
    int rc = pf_image_read_hdr(&img, path, &ierr);
    if (rc)
        return pf_error_set(err, rc, NULL, 0, "environment map: %s", ierr.msg);
    int w = img.width, h = img.height;
    if (w > PF_ENVMAP_MAX_SIDE || h > PF_ENVMAP_MAX_SIDE) {
        pf_image_free(&img);
        return pf_error_set(err, PF_ERANGE, NULL, 0, "environment map %s is %dx%d: larger than %d on a side", path, w,
                            h, PF_ENVMAP_MAX_SIDE);
    }
    if (mapping == PF_ENVMAP_EQUALAREA && w != h) {
        pf_image_free(&img);
        return pf_error_set(err, PF_EPARSE, NULL, 0,
                            "environment map %s is %dx%d: the equal-area mapping needs a square image", path, w, h);
    }
    size_t n = (size_t)img.width * (size_t)img.height * 3;
    for (size_t k = 0; k < n; k++) {
        if (!(img.rgb[k] >= 0.0f) || !isfinite(img.rgb[k])) {
            img.rgb[k] = 0.0f;
            (*clamped)++;
        }
    }
    size_t len = strlen(path);
    snprintf(out->name, sizeof out->name, "%s", len >= sizeof out->name ? path + len - (sizeof out->name - 1) : path);
    out->width = img.width;
    out->height = img.height;
    out->mapping = mapping;
    out->rgb = img.rgb; /* taken over from img */
    const double id[9] = { 1, 0, 0, 0, 1, 0, 0, 0, 1 };
    pf_envmap_set_frame(out, id);
    pf_info("environment map %s: %dx%d %s, float RGB, %.1f MB", path, out->width, out->height,
            mapping == PF_ENVMAP_EQUALAREA ? "equal-area" : "equirect", (double)pf_envmap_bytes(out) / 1048576.0);
    return PF_OK;
}
