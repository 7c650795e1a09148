/* texload.h: an image file made a scene texture, for the formats that name
 * texture images (MTL's map_Kd here, pbrt's imagemap in load/). */
#ifndef PF_TEXLOAD_H
#define PF_TEXLOAD_H

#include "base/status.h"
#include "scene/scene.h"
#include "scene/texture.h"

/* How the image's 8-bit values are encoded: sRGB unless told linear (pbrt
 * and MTL both default to sRGB for 8-bit files); float files are linear. */
typedef enum { PF_TEXENC_DEFAULT = 0, PF_TEXENC_SRGB = 1, PF_TEXENC_LINEAR = 2 } pf_texenc;

/* Reads the image at path and appends it to the scene as a texture: tmpl
 * gives its name, mapping, wrap, scale and invert (type and pixels are set
 * here). Returns its ref (1 + index, > 0), or a negative status with err
 * naming the image file and where it was named (from:line, when from is
 * not NULL). */
int pf_texture_load_image(pf_scene_t *scene, const char *path, const pf_texture_t *tmpl, pf_texenc enc,
                          const char *from, int line, pf_error_t *err);

#endif
