/* texture.h: the scene's textures (pbrt-v4's 2D textures on uv
 * coordinates): images (8-bit, sRGB-encoded or linear, or float linear
 * RGB) with bilinear lookup and a wrap mode, and the procedurals constant,
 * checkerboard, scale and mix, whose operands are constants or other
 * textures. A texture evaluates to linear RGB; a float texture is one with
 * r = g = b. Textures live in pf_scene_t.texs; the scene owns their
 * pixels. Evaluation only reads, so it is safe from any thread. */
#ifndef PF_TEXTURE_H
#define PF_TEXTURE_H

#include <stddef.h>
#include <stdint.h>

#include "base/status.h"
#include "base/vec.h"
#include "scene/scene.h"

typedef enum {
    PF_TEX_CONSTANT = 0, /* op[0] */
    PF_TEX_IMAGE = 1,    /* pixels, times scale, inverted (1 - v, clamped at 0) when invert */
    PF_TEX_CHECKER = 2,  /* op[0] where floor(s) + floor(t) is even, else op[1] (pbrt-v4 checkerboard, 2D) */
    PF_TEX_SCALE = 3,    /* op[0] * op[1] */
    PF_TEX_MIX = 4,      /* (1 - a) op[0] + a op[1], a = op[2]'s first channel */
} pf_tex_type;
#define PF_TEX_LAST PF_TEX_MIX

typedef enum { PF_WRAP_REPEAT = 0, PF_WRAP_CLAMP = 1, PF_WRAP_BLACK = 2 } pf_tex_wrap;
#define PF_WRAP_LAST PF_WRAP_BLACK

/* The largest image a texture may hold: each side and the pixel count. */
#define PF_TEX_MAX_SIDE 16384
#define PF_TEX_MAX_PIXELS (1u << 28)

/* An operand of a procedural: the texture ref (1 + index, earlier in the
 * table) when nonzero, else the constant c. */
typedef struct pf_tex_operand {
    pf_vec3 c;
    uint32_t ref;
} pf_tex_operand_t;

typedef struct pf_texture {
    char name[PF_NAME_MAX];
    pf_tex_type type;
    /* pbrt's uv mapping: s = su u + du, t = sv v + dv. */
    float su, sv, du, dv;
    pf_tex_operand_t op[3];
    /* IMAGE: width x height RGB pixels, top row first, in px8 (8 bits,
     * sRGB-encoded when srgb, else linear v / 255) or pxf (linear float);
     * t = 0 is the bottom row, as in pbrt. */
    int width, height;
    pf_tex_wrap wrap;
    int srgb;
    float scale;
    int invert;
    uint8_t *px8;
    float *pxf;
} pf_texture_t;

/* A texture with pbrt's defaults (identity mapping, repeat, scale 1): a
 * constant of value c. */
pf_texture_t pf_texture_constant(const char *name, pf_vec3 c);

/* Appends a texture, taking ownership of its pixels (and zeroing *tex):
 * returns its ref (1 + index) or PF_ENOMEM (negative). */
int pf_scene_add_texture(pf_scene_t *self, pf_texture_t *tex);
/* Frees a texture's pixels (for textures not handed to a scene). */
void pf_texture_free(pf_texture_t *tex);

/* The texture ref's value at texture coordinates (u, v). ref must be valid
 * (pf_textures_check). */
pf_vec3 pf_texture_eval(const pf_scene_t *scene, uint32_t ref, float u, float v);

/* The uv of a point with barycentrics (b1, b2) on triangle tri of mesh m:
 * interpolated from m->uv, or pbrt's default for meshes without uv, which
 * gives the corners (0,0), (1,0) and (1,1). */
void pf_mesh_uv(const pf_mesh_t *m, size_t tri, float b1, float b2, float uv[2]);

/* The sRGB decoding of 8-bit value i (the exact curve, in float). */
float pf_srgb8_to_linear(uint8_t i);

/* Bytes the textures' pixels take. */
size_t pf_textures_bytes(const pf_scene_t *self);

/* Checks the texture table and the refs into it (materials' kd_tex,
 * operands only to earlier textures, types, wrap modes, image sizes,
 * finite parameters); replaces non-finite mesh uvs by 0. For
 * pf_scene_finalize; 0 or PF_EPARSE with err filled. */
int pf_textures_check(pf_scene_t *self, pf_error_t *err);

#endif
