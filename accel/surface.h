/* surface.h: what a hit's surface is like there: its texture coordinates
 * and its material with the textured slots resolved. The camera pass, the
 * final gather and the photon pass read a hit's material through
 * pf_material_at, so a texture counts alike in all of them. */
#ifndef PF_SURFACE_H
#define PF_SURFACE_H

#include "accel/accel.h"
#include "scene/scene.h"

/* The hit's uv: interpolated from its mesh's uv, pbrt's default
 * parametrization on meshes without (scene/texture.h), and on spheres
 * pbrt's (phi / 2 pi, theta / pi with theta from the pole at -z), taken
 * about the sphere's world axes. */
void pf_hit_uv(const pf_scene_t *scene, const pf_hit_t *hit, float uv[2]);

/* A copy of the hit's material with its textured slots evaluated at the
 * hit's uv: kd (clamped to [0, 1]); a conductor's reflectance refl_tex
 * (clamped to [0, 1]: ks, eta 1 and k from it); roughness rough_tex (alpha,
 * remapped by sqrt when rough_remap, clamped to [0, 1]). The material
 * itself when it has none. The normal and bump maps bend the hit's shading
 * normal instead (accel/shading.h). */
pf_material_t pf_material_at(const pf_scene_t *scene, const pf_hit_t *hit);

#endif
