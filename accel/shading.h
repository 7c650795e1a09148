/* shading.h: a hit's shading normal bent by its material's normal map or
 * bump map (pbrt-v4's NormalMap() and BumpMap()), on the hit's surface
 * tangents dpdu, dpdv (pbrt's, from the triangle's uvs or the sphere's
 * parametrization). The camera pass, the final gather and the photon pass
 * call pf_shade_hit after pf_material_at, so the bent normal counts alike
 * in all of them; the geometric normal (side tests, ray offsets) is kept. */
#ifndef PF_SHADING_H
#define PF_SHADING_H

#include "accel/accel.h"
#include "scene/scene.h"

/* The displacement step in u and v of a bump map: pbrt-v4's du when there
 * are no ray differentials. */
#define PF_BUMP_DELTA 0.0005f

/* The least cosine between a bent shading normal and the geometric normal:
 * a map that tilts the normal to or below the surface's horizon is clamped
 * to this far above it (so no NaN, and no sudden flip to the mirrored
 * normal as pbrt's FaceForward gives). */
#define PF_SHADE_MIN_COS 0.02f

/* pbrt's dpdu and dpdv at the hit (triangle: from the corner positions and
 * uvs, pbrt's default uvs on meshes without; sphere: of (phi / 2 pi, 1 -
 * theta / pi)); when the uv mapping is degenerate, any two tangents
 * perpendicular to ng. */
void pf_hit_dpduv(const pf_scene_t *scene, const pf_hit_t *hit, pf_vec3 *dpdu, pf_vec3 *dpdv);

/* Bends hit->ns by m's normal map (m->normal_tex) or, without one, its bump
 * map (m->bump_tex); the result is unit and at least PF_SHADE_MIN_COS
 * above ng's horizon (ns's side of it). Then, as Cycles'
 * ensure_valid_reflection, tilted back towards ng (by bisection) just
 * enough that the mirror direction of wo (unit, away from the surface:
 * towards the eye or where a photon came from) about it leaves the surface
 * on wo's side: otherwise a mirror, a conductor or a coat would send
 * everything into the surface and show black fringes. m is the hit's
 * material (as pf_material_at gives it). */
void pf_shade_bend(const pf_scene_t *scene, const pf_material_t *m, pf_hit_t *hit, pf_vec3 wo);

/* pf_shade_bend when m has a map; nothing (one test) otherwise. */
static inline void pf_shade_hit(const pf_scene_t *scene, const pf_material_t *m, pf_hit_t *hit, pf_vec3 wo)
{
    if (m->normal_tex | m->bump_tex)
        pf_shade_bend(scene, m, hit, wo);
}

#endif
