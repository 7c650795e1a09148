/* texture.h: the scene's textures (pf_texture_t in scene.h) made and
 * evaluated: a texture evaluates to linear RGB at uv coordinates; a float
 * texture is one with r = g = b. Evaluation only reads, so it is safe from
 * any thread. */
#ifndef PF_TEXTURE_H
#define PF_TEXTURE_H

#include <stddef.h>
#include <stdint.h>

#include "base/status.h"
#include "base/vec.h"
#include "scene/scene.h"

/* A texture with pbrt's defaults (identity mapping, repeat, scale 1): a
 * constant of value c. */
pf_texture_t pf_texture_constant(const char *name, pf_vec3 c);

/* Appends a texture, taking ownership of its pixels (and zeroing *tex):
 * returns its ref (1 + index) or PF_ENOMEM (negative). */
int pf_scene_add_texture(pf_scene_t *self, pf_texture_t *tex);

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

#endif
