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
 * (clamped to [0, 1]: ks, eta 1 and k from it), a Phong lobe's or a
 * mirror's ks times refl_tex (MTL map_Ks; a Phong ks held to at most
 * 1 - kd); roughness rough_tex (alpha,
 * remapped by sqrt when rough_remap, clamped to [0, 1]). The material
 * itself when it has none. The normal and bump maps bend the hit's shading
 * normal instead (accel/shading.h). A MIX material is first resolved to one
 * of its two (mixes of mixes all the way down), chosen by pf_mix_choose; the
 * copy keeps the mix's own le, as the light table (light/) counts the hit
 * material's emission. */
pf_material_t pf_material_at(const pf_scene_t *scene, const pf_hit_t *hit);

/* The share of light that survives the medium a ray of unit direction d
 * crossed to reach the hit, exp(-sigma hit->t) per channel: sigma is the
 * hit material's sigma_in when the ray arrives from behind the surface
 * (d . ng > 0), its sigma_out from the front (scene.h: the media on a
 * surface's two sides). 1 for a clear medium. The medium of a segment is
 * the one its far end names, so a solid whose every face carries the
 * medium tints every ray inside it, however it bounces, without a ray
 * tracking where it is; a segment ending at a surface that names no
 * medium counts as clear. The hit's own material is read (hit->mat, not
 * what a mix resolves to): a mix's medium is the mix's. */
pf_vec3 pf_hit_transmittance(const pf_scene_t *scene, const pf_hit_t *hit, pf_vec3 d);

/* The index of the material MIX material `mix` stands for at the hit (one
 * level): mix[1] with probability amount (its texture's mean channel at the
 * hit's uv when textured; <= 0 always mix[0], >= 1 always mix[1]), drawn as
 * pbrt-v4's MixMaterial draws it, from a hash of the hit: its point and its
 * distance along the ray (so different rays to one point may choose
 * differently) and the mix's index. No random stream is consumed, so the
 * camera pass, the gather rays and the photons resolve a hit alike, on any
 * thread or worker. */
uint32_t pf_mix_choose(const pf_scene_t *scene, const pf_hit_t *hit, uint32_t mix);

#endif
