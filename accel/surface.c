/* surface.c: a hit's uv and its material resolved there (surface.h). Kept
 * apart from accel.c's Embree code: it needs only the hit and the scene. */
#include "accel/surface.h"

#include <math.h>

#include "scene/texture.h"

void pf_hit_uv(const pf_scene_t *scene, const pf_hit_t *hit, float uv[2])
{
    if (hit->geom < scene->nmeshes) {
        pf_mesh_uv(&scene->meshes[hit->geom], hit->prim, hit->u, hit->v, uv);
        return;
    }
    const pf_sphere_t *sp = &scene->spheres[hit->prim];
    pf_vec3 d = pf_sub(hit->p, sp->center);
    float phi = atan2f(d.y, d.x);
    phi += phi < 0.0f ? 2.0f * PF_PI : 0.0f;
    float z = d.z / sp->radius;
    z = z < -1.0f ? -1.0f : z > 1.0f ? 1.0f : z;
    uv[0] = phi / (2.0f * PF_PI);
    uv[1] = 1.0f - acosf(z) / PF_PI;
}

/* The textured slots beyond kd: a conductor's reflectance (pbrt-v4's
 * eta 1, k from it) and the roughness of a conductor or a coat. */
static void s_more_slots(const pf_scene_t *scene, pf_material_t *m, const float uv[2])
{
    if (m->refl_tex && m->type == PF_MAT_CONDUCTOR) {
        pf_vec3 r = pf_vmin(pf_vmax(pf_texture_eval(scene, m->refl_tex, uv[0], uv[1]), pf_v3s(0.0f)), pf_v3s(1.0f));
        m->ks = r;
        m->eta = pf_v3s(1.0f);
        m->k = pf_v3(pf_conductor_k_of_reflectance(r.x), pf_conductor_k_of_reflectance(r.y),
                     pf_conductor_k_of_reflectance(r.z));
    }
    if (m->rough_tex) {
        float r = fmaxf(pf_texture_eval(scene, m->rough_tex, uv[0], uv[1]).x, 0.0f);
        float a = m->rough_remap ? sqrtf(r) : r;
        m->alpha = a < 1.0f ? a : 1.0f; /* NaN falls to 1 too */
    }
}

pf_material_t pf_material_at(const pf_scene_t *scene, const pf_hit_t *hit)
{
    pf_material_t m = scene->mats[hit->mat];
    if (!(m.kd_tex | m.refl_tex | m.rough_tex))
        return m;
    float uv[2];
    pf_hit_uv(scene, hit, uv);
    /* Clamped to [0, 1] as pbrt-v4's diffuse material does: an albedo above
     * 1 would make light, and a scaled texture can ask for one. */
    if (m.kd_tex)
        m.kd = pf_vmin(pf_vmax(pf_texture_eval(scene, m.kd_tex, uv[0], uv[1]), pf_v3s(0.0f)), pf_v3s(1.0f));
    if (m.refl_tex | m.rough_tex)
        s_more_slots(scene, &m, uv);
    return m;
}
