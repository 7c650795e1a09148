/* texfile.c: texture image files (texfile.h). stb_image reads the common
 * 8-bit formats and Radiance HDR; stbi_info reads only the header, so an
 * image that claims 100000 x 100000 pixels is refused before any memory is
 * asked for. PFM and OpenEXR go through image.c and exr.c, whose headers
 * are checked by those readers; the size limit is applied after. stb's
 * failure reason is a global: textures are read on the one thread that
 * loads the scene. */
#include "image/texfile.h"

#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <strings.h>

#include <stb_image.h>

#include "image/image.h"

static const char *s_ext(const char *path)
{
    const char *dot = strrchr(path, '.'), *slash = strrchr(path, '/');
    return dot && (!slash || dot > slash) ? dot + 1 : "";
}

static int s_check_size(const char *path, int w, int h, int max_side, uint64_t max_pixels, pf_error_t *err)
{
    if (w <= 0 || h <= 0 || w > max_side || h > max_side || (uint64_t)w * (uint64_t)h > max_pixels)
        return pf_error_set(err, PF_ERANGE, path, 0,
                            "image is %d x %d pixels; textures may have at most %d per side and %llu in all", w, h,
                            max_side, (unsigned long long)max_pixels);
    return PF_OK;
}

static int s_read_float(const char *path, int exr, int max_side, uint64_t max_pixels, pf_teximage_t *out,
                        pf_error_t *err)
{
    pf_image_t img = { 0, 0, NULL };
    int rc = exr ? pf_image_read_exr(&img, path, err) : pf_image_read_pfm(&img, path, err);
    if (rc == PF_OK)
        rc = s_check_size(path, img.width, img.height, max_side, max_pixels, err);
    if (rc) {
        pf_image_free(&img);
        return rc;
    }
    out->width = img.width;
    out->height = img.height;
    out->pxf = img.rgb;
    return PF_OK;
}

int pf_teximage_read(const char *path, int max_side, uint64_t max_pixels, pf_teximage_t *out, pf_error_t *err)
{
    memset(out, 0, sizeof *out);
    const char *ext = s_ext(path);
    if (!strcasecmp(ext, "exr") || !strcasecmp(ext, "pfm"))
        return s_read_float(path, !strcasecmp(ext, "exr"), max_side, max_pixels, out, err);
    FILE *f = fopen(path, "rb");
    if (!f)
        return pf_error_set(err, PF_EIO, path, 0, "cannot open texture image");
    int w, h, comp;
    int ok = stbi_info_from_file(f, &w, &h, &comp);
    if (!ok) {
        fclose(f);
        return pf_error_set(err, PF_EPARSE, path, 0, "not an image stb_image can read (%s)", stbi_failure_reason());
    }
    int rc = s_check_size(path, w, h, max_side, max_pixels, err);
    if (rc) {
        fclose(f);
        return rc;
    }
    int hdr = stbi_is_hdr_from_file(f), n;
    void *px = hdr ? (void *)stbi_loadf_from_file(f, &w, &h, &n, 3) : (void *)stbi_load_from_file(f, &w, &h, &n, 3);
    fclose(f);
    if (!px)
        return pf_error_set(err, PF_EPARSE, path, 0, "cannot decode image (%s)", stbi_failure_reason());
    if ((rc = s_check_size(path, w, h, max_side, max_pixels, err))) {
        stbi_image_free(px);
        return rc;
    }
    /* Copied into malloc'd memory so the scene frees it like any other
     * array, whatever allocator libstb was built with. */
    size_t n3 = (size_t)w * (size_t)h * 3, bytes = n3 * (hdr ? sizeof(float) : 1);
    void *mine = malloc(bytes);
    if (!mine) {
        stbi_image_free(px);
        return pf_error_set(err, PF_ENOMEM, path, 0, "out of memory for a %d x %d texture", w, h);
    }
    memcpy(mine, px, bytes);
    stbi_image_free(px);
    out->width = w;
    out->height = h;
    if (hdr)
        out->pxf = mine;
    else
        out->px8 = mine;
    return PF_OK;
}

void pf_teximage_free(pf_teximage_t *img)
{
    if (!img)
        return;
    free(img->px8);
    free(img->pxf);
    memset(img, 0, sizeof *img);
}
