/* surface.c: a hit's uv and its material resolved there (surface.h). Kept
 * apart from accel.c's Embree code: it needs only the hit and the scene. */
#include "accel/surface.h"

#include <math.h>

#include "base/hash.h"
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

uint32_t pf_mix_choose(const pf_scene_t *scene, const pf_hit_t *hit, uint32_t mix)
{
    const pf_material_t *m = &scene->mats[mix];
    float a = m->amount;
    if (m->amount_tex) {
        float uv[2];
        pf_hit_uv(scene, hit, uv);
        pf_vec3 c = pf_texture_eval(scene, m->amount_tex, uv[0], uv[1]);
        a = (c.x + c.y + c.z) * (1.0f / 3.0f); /* a float lookup of an RGB texture: the mean, as pbrt-v4 */
    }
    if (!(a > 0.0f))
        return m->mix[0];
    if (a >= 1.0f)
        return m->mix[1];
    float f[4] = { hit->p.x, hit->p.y, hit->p.z, hit->t };
    uint64_t h = pf_hash_bytes(0x6d6978ull + mix, f, sizeof f);
    float u = (float)(h >> 40) * 0x1p-24f; /* [0, 1) */
    return u < a ? m->mix[1] : m->mix[0];
}

/* The textured slots beyond kd: a conductor's reflectance (pbrt-v4's
 * eta 1, k from it), a Phong lobe's or a mirror's ks (MTL map_Ks: times
 * the texture; the Phong ks at most 1 - kd, kd already resolved, so the
 * surface reflects no more than it receives) and the roughness of a
 * conductor or a coat. */
static void s_more_slots(const pf_scene_t *scene, pf_material_t *m, const float uv[2])
{
    if (m->refl_tex) {
        pf_vec3 r = pf_vmin(pf_vmax(pf_texture_eval(scene, m->refl_tex, uv[0], uv[1]), pf_v3s(0.0f)), pf_v3s(1.0f));
        if (m->type == PF_MAT_CONDUCTOR) {
            m->ks = r;
            m->eta = pf_v3s(1.0f);
            m->k = pf_v3(pf_conductor_k_of_reflectance(r.x), pf_conductor_k_of_reflectance(r.y),
                         pf_conductor_k_of_reflectance(r.z));
        } else if (m->type == PF_MAT_MIRROR) {
            m->ks = pf_mul(m->ks, r);
        } else if (m->type == PF_MAT_DIFFUSE) {
            m->ks = pf_vmin(pf_mul(m->ks, r), pf_vmax(pf_sub(pf_v3s(1.0f), m->kd), pf_v3s(0.0f)));
        }
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
    if (m.type == PF_MAT_MIX) {
        uint32_t i = hit->mat;
        /* finalize bounds the nesting (PF_MIX_MAX_DEPTH) and rules out cycles */
        for (int d = 0; d <= PF_MIX_MAX_DEPTH && scene->mats[i].type == PF_MAT_MIX; d++)
            i = pf_mix_choose(scene, hit, i);
        pf_vec3 le = m.le;
        uint32_t twosided = m.twosided;
        m = scene->mats[i];
        m.le = le;
        m.twosided = twosided;
        if (m.type == PF_MAT_MIX) { /* unreachable after finalize: a black surface */
            m.type = PF_MAT_DIFFUSE;
            m.kd = m.ks = pf_v3s(0.0f);
            m.kd_tex = 0;
        }
    }
    if (!(m.kd_tex | m.refl_tex | m.rough_tex | m.kt_tex))
        return m;
    float uv[2];
    pf_hit_uv(scene, hit, uv);
    /* Clamped to [0, 1] as pbrt-v4's diffuse material does: an albedo above
     * 1 would make light, and a scaled texture can ask for one. */
    if (m.kd_tex)
        m.kd = pf_vmin(pf_vmax(pf_texture_eval(scene, m.kd_tex, uv[0], uv[1]), pf_v3s(0.0f)), pf_v3s(1.0f));
    if (m.refl_tex | m.rough_tex)
        s_more_slots(scene, &m, uv);
    if (m.kt_tex)
        m.kt = pf_vmin(pf_vmax(pf_texture_eval(scene, m.kt_tex, uv[0], uv[1]), pf_v3s(0.0f)), pf_v3s(1.0f));
    if (m.type == PF_MAT_DIFFUSE_TRANSMISSION) /* a sheet passes on no more than its reflection leaves */
        m.kt = pf_vmin(m.kt, pf_vmax(pf_sub(pf_v3s(1.0f), m.kd), pf_v3s(0.0f)));
    return m;
}

pf_vec3 pf_hit_transmittance(const pf_scene_t *scene, const pf_hit_t *hit, pf_vec3 d)
{
    const pf_material_t *m = &scene->mats[hit->mat];
    pf_vec3 sigma = pf_dot(d, hit->ng) > 0.0f ? m->sigma_in : m->sigma_out;
    if (pf_is_black(sigma))
        return pf_v3s(1.0f);
    return pf_v3(expf(-sigma.x * hit->t), expf(-sigma.y * hit->t), expf(-sigma.z * hit->t));
}
