/* alpha.c: alpha cut-outs as Embree filter functions (alpha.h). As in
 * pbrt-v4's Triangle: a is the mesh's alpha texture at the hit's uv; a >= 1
 * keeps the hit, a <= 0 skips it, and in between the hit is skipped when a
 * hash of the ray (the bits of its origin and direction) maps above a, so a
 * half-transparent leaf lets half the rays through, the same ones every
 * time. The texture is the mesh's, or, on a mesh without one, that of the
 * hit triangle's material (an MTL map_d). The filters run inside Embree's traversal on whatever thread
 * traces; they only read the scene (Embree's user pointer), and the mesh is
 * the hit's geometry ID (meshes are attached by their index). */
#include "accel/alpha.h"

#include <string.h>

#include "base/hash.h"
#include "scene/texture.h"

/* Embree's RTCRayN / RTCHitN accessors are C++ only: their SOA layout
 * (rtcore_ray.h), field k of ray i of N at float k N + i. */
static inline float s_rayf(const struct RTCRayN *ray, unsigned n, unsigned k, unsigned i)
{
    return ((const float *)ray)[k * n + i];
}

static float s_ray_hash(const struct RTCRayN *ray, unsigned n, unsigned i)
{
    /* org x y z are fields 0-2, dir x y z 4-6 */
    float f[6] = { s_rayf(ray, n, 0, i), s_rayf(ray, n, 1, i), s_rayf(ray, n, 2, i),
                   s_rayf(ray, n, 4, i), s_rayf(ray, n, 5, i), s_rayf(ray, n, 6, i) };
    uint64_t h = pf_hash_bytes(0x616c706861ull, f, sizeof f);
    return (float)(h >> 40) * 0x1p-24f; /* [0, 1) */
}

static void s_filter(const struct RTCFilterFunctionNArguments *args)
{
    const pf_scene_t *scene = args->geometryUserPtr;
    for (unsigned i = 0; i < args->N; i++) {
        if (args->valid[i] != -1)
            continue;
        /* hit fields: u 3, v 4, primID 5, geomID 6 */
        const float *hf = (const float *)args->hit;
        const unsigned *hu = (const unsigned *)args->hit;
        unsigned n = args->N, prim = hu[5 * n + i], geom = hu[6 * n + i];
        const pf_mesh_t *mesh = &scene->meshes[geom];
        uint32_t tex = mesh->alpha_tex ? mesh->alpha_tex : scene->mats[mesh->mat[prim]].alpha_tex;
        if (!tex)
            continue;
        float uv[2];
        pf_mesh_uv(mesh, prim, hf[3 * n + i], hf[4 * n + i], uv);
        pf_vec3 c = pf_texture_eval(scene, tex, uv[0], uv[1]);
        float a = (c.x + c.y + c.z) * (1.0f / 3.0f); /* a float lookup of an RGB image: the mean, as pbrt-v4 */
        if (a >= 1.0f)
            continue;
        float u = a <= 0.0f ? 1.0f : s_ray_hash(args->ray, args->N, i);
        if (u > a)
            args->valid[i] = 0;
    }
}

void pf_alpha_attach(RTCGeometry g, const pf_scene_t *scene, size_t m)
{
    const pf_mesh_t *mesh = &scene->meshes[m];
    int any = mesh->alpha_tex != 0;
    for (size_t t = 0; !any && t < mesh->ntris; t++)
        any = scene->mats[mesh->mat[t]].alpha_tex != 0;
    if (!any)
        return;
    rtcSetGeometryUserData(g, (void *)scene);
    rtcSetGeometryIntersectFilterFunction(g, s_filter);
    rtcSetGeometryOccludedFilterFunction(g, s_filter);
}
