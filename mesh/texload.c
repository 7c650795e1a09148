/* texload.c: image textures from files (texload.h), shared by the MTL and
 * pbrt readers; the file formats themselves are image/texfile.c's. */
#include "mesh/texload.h"

#include <stdio.h>
#include <string.h>

#include "image/texfile.h"

int pf_texture_load_image(pf_scene_t *scene, const char *path, const pf_texture_t *tmpl, pf_texenc enc,
                          const char *from, int line, pf_error_t *err)
{
    pf_teximage_t img;
    pf_error_t ierr;
    memset(&ierr, 0, sizeof ierr);
    int rc = pf_teximage_read(path, PF_TEX_MAX_SIDE, PF_TEX_MAX_PIXELS, &img, &ierr);
    if (rc) {
        if (from)
            return pf_error_set(err, rc, from, line, "texture image %s", ierr.msg);
        return pf_error_set(err, rc, NULL, 0, "%s", ierr.msg);
    }
    pf_texture_t t = *tmpl;
    t.type = PF_TEX_IMAGE;
    t.width = img.width;
    t.height = img.height;
    t.px8 = img.px8;
    t.pxf = img.pxf;
    t.srgb = img.px8 && enc != PF_TEXENC_LINEAR;
    int ref = pf_scene_add_texture(scene, &t);
    if (ref < 0) {
        pf_teximage_free(&img);
        return pf_error_set(err, PF_ENOMEM, from ? from : path, line, "out of memory for texture %s", path);
    }
    return ref;
}
