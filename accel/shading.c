/* shading.c: normal and bump mapping (shading.h). The tangents are pbrt's
 * (Triangle::InteractionFromIntersection, Sphere): computed per hit from
 * the triangle's corners, which costs a few dozen flops and only on
 * materials with a map, instead of storing a tangent per vertex. The
 * shading frame follows pbrt-v4: with vertex normals, dpdu is made
 * perpendicular to the shading normal n and dpdv = n x dpdu; without, both
 * are the geometric ones. pbrt's displace * dndu term of BumpMap is left
 * out (it is zero on flat triangles and small beside the texture's slope
 * elsewhere). */
#include "accel/shading.h"

#include <math.h>

#include "accel/surface.h"
#include "scene/texture.h"

/* Two tangents perpendicular to unit n. */
static void s_any_tangents(pf_vec3 n, pf_vec3 *dpdu, pf_vec3 *dpdv) { pf_basis(n, dpdu, dpdv); }

static void s_tri_dpduv(const pf_mesh_t *m, const pf_hit_t *h, pf_vec3 *dpdu, pf_vec3 *dpdv)
{
    const uint32_t *v = &m->idx[3 * (size_t)h->prim];
    pf_vec3 p0 = m->pos[v[0]], p1 = m->pos[v[1]], p2 = m->pos[v[2]];
    float uv[3][2] = { { 0, 0 }, { 1, 0 }, { 1, 1 } }; /* pbrt's default */
    if (m->uv)
        for (int k = 0; k < 3; k++)
            uv[k][0] = m->uv[2 * v[k]], uv[k][1] = m->uv[2 * v[k] + 1];
    float du02 = uv[0][0] - uv[2][0], dv02 = uv[0][1] - uv[2][1];
    float du12 = uv[1][0] - uv[2][0], dv12 = uv[1][1] - uv[2][1];
    pf_vec3 dp02 = pf_sub(p0, p2), dp12 = pf_sub(p1, p2);
    float det = du02 * dv12 - dv02 * du12;
    if (fabsf(det) < 1e-9f) {
        s_any_tangents(h->ng, dpdu, dpdv);
        return;
    }
    float inv = 1.0f / det;
    *dpdu = pf_scale(pf_sub(pf_scale(dp02, dv12), pf_scale(dp12, dv02)), inv);
    *dpdv = pf_scale(pf_sub(pf_scale(dp12, du02), pf_scale(dp02, du12)), inv);
    pf_vec3 c = pf_cross(*dpdu, *dpdv);
    if (!(pf_len2(c) > 0.0f) || !pf_is_finite3(c))
        s_any_tangents(h->ng, dpdu, dpdv);
}

void pf_hit_dpduv(const pf_scene_t *scene, const pf_hit_t *hit, pf_vec3 *dpdu, pf_vec3 *dpdv)
{
    if (hit->geom < scene->nmeshes) {
        s_tri_dpduv(&scene->meshes[hit->geom], hit, dpdu, dpdv);
        return;
    }
    /* pbrt's sphere: phi_max 2 pi, theta from pi (z = -r) to 0 (z = r). */
    const pf_sphere_t *sp = &scene->spheres[hit->prim];
    pf_vec3 d = pf_sub(hit->p, sp->center);
    float rxy = sqrtf(d.x * d.x + d.y * d.y);
    if (!(rxy > 1e-6f * sp->radius)) {
        s_any_tangents(hit->ng, dpdu, dpdv);
        return;
    }
    float cphi = d.x / rxy, sphi = d.y / rxy;
    *dpdu = pf_v3(-2.0f * PF_PI * d.y, 2.0f * PF_PI * d.x, 0.0f);
    *dpdv = pf_scale(pf_v3(d.z * cphi, d.z * sphi, -rxy), -PF_PI);
}

/* pbrt-v4's shading dpdu, dpdv about the shading normal n. */
static void s_shading_frame(const pf_scene_t *scene, const pf_hit_t *h, pf_vec3 n, pf_vec3 *dpdu, pf_vec3 *dpdv)
{
    if (h->geom >= scene->nmeshes || !scene->meshes[h->geom].nrm)
        return; /* no vertex normals: the geometric tangents */
    pf_vec3 ts = pf_cross(n, *dpdu);
    if (!(pf_len2(ts) > 0.0f)) {
        s_any_tangents(n, dpdu, dpdv);
        return;
    }
    *dpdu = pf_cross(ts, n);
    *dpdv = ts;
}

/* The normal map's normal in the (dpdu, n x dpdu, n) frame. */
static pf_vec3 s_normal_map(const pf_scene_t *scene, const pf_material_t *m, const float uv[2], pf_vec3 n,
                            pf_vec3 dpdu)
{
    pf_vec3 c = pf_texture_eval(scene, m->normal_tex, uv[0], uv[1]);
    pf_vec3 l = pf_sub(pf_scale(c, 2.0f), pf_v3s(1.0f));
    if (!(pf_len2(l) > 1e-12f) || !pf_is_finite3(l))
        return n;
    l = pf_norm(l);
    pf_vec3 t = pf_sub(dpdu, pf_scale(n, pf_dot(n, dpdu)));
    if (!(pf_len2(t) > 0.0f)) {
        pf_vec3 b;
        pf_basis(n, &t, &b);
    }
    t = pf_norm(t);
    pf_vec3 b = pf_cross(n, t);
    return pf_add(pf_add(pf_scale(t, l.x), pf_scale(b, l.y)), pf_scale(n, l.z));
}

/* pbrt-v4's BumpMap: the displaced surface's normal from finite differences
 * of the displacement in u and v (the first channel). */
static pf_vec3 s_bump_map(const pf_scene_t *scene, const pf_material_t *m, const float uv[2], pf_vec3 n,
                          pf_vec3 dpdu, pf_vec3 dpdv)
{
    const float du = PF_BUMP_DELTA, dv = PF_BUMP_DELTA;
    float h = pf_texture_eval(scene, m->bump_tex, uv[0], uv[1]).x;
    float hu = pf_texture_eval(scene, m->bump_tex, uv[0] + du, uv[1]).x;
    float hv = pf_texture_eval(scene, m->bump_tex, uv[0], uv[1] + dv).x;
    pf_vec3 pu = pf_add(dpdu, pf_scale(n, (hu - h) / du));
    pf_vec3 pv = pf_add(dpdv, pf_scale(n, (hv - h) / dv));
    pf_vec3 c = pf_cross(pu, pv);
    if (!(pf_len2(c) > 0.0f) || !pf_is_finite3(c))
        return n;
    c = pf_norm(c);
    return pf_dot(c, n) < 0.0f ? pf_neg(c) : c; /* pbrt's FaceForward onto the unbent normal */
}

/* v mirrored about unit n (material/bsdf.h's pf_reflect; a sibling layer). */
static pf_vec3 s_reflect(pf_vec3 v, pf_vec3 n) { return pf_sub(pf_scale(n, 2.0f * pf_dot(v, n)), v); }

/* ns (unit, on nf's side) tilted towards nf until wo's mirror direction
 * about it is at least min(0.9 cos(wo, nf), 0.01) above the surface (nf
 * itself always is): 20 steps of bisection on the blend, only when needed. */
static pf_vec3 s_valid_reflection(pf_vec3 ns, pf_vec3 nf, pf_vec3 wo)
{
    float iz = pf_dot(wo, nf), th = fminf(0.9f * iz, 0.01f);
    if (!(iz > 0.0f) || pf_dot(s_reflect(wo, ns), nf) >= th)
        return ns;
    float lo = 0.0f, hi = 1.0f;
    for (int i = 0; i < 20; i++) {
        float t = 0.5f * (lo + hi);
        pf_vec3 n = pf_norm(pf_add(pf_scale(ns, 1.0f - t), pf_scale(nf, t)));
        if (pf_dot(s_reflect(wo, n), nf) >= th)
            hi = t;
        else
            lo = t;
    }
    return pf_norm(pf_add(pf_scale(ns, 1.0f - hi), pf_scale(nf, hi)));
}

void pf_shade_bend(const pf_scene_t *scene, const pf_material_t *m, pf_hit_t *hit, pf_vec3 wo)
{
    float uv[2];
    pf_vec3 dpdu, dpdv, n = hit->ns;
    pf_hit_uv(scene, hit, uv);
    pf_hit_dpduv(scene, hit, &dpdu, &dpdv);
    s_shading_frame(scene, hit, n, &dpdu, &dpdv);
    pf_vec3 b = m->normal_tex ? s_normal_map(scene, m, uv, n, dpdu) : s_bump_map(scene, m, uv, n, dpdu, dpdv);
    /* Keep it on ns's side of the geometric horizon (ns is in ng's
     * hemisphere): lift a normal tilted to or below it to PF_SHADE_MIN_COS. */
    float c = pf_dot(b, hit->ng);
    if (!(c >= PF_SHADE_MIN_COS)) {
        pf_vec3 t = pf_sub(b, pf_scale(hit->ng, c));
        float tl = pf_len(t);
        if (!(tl > 1e-6f) || !pf_is_finite3(t))
            return; /* straight down or broken: keep the unbent normal */
        const float s = sqrtf(1.0f - PF_SHADE_MIN_COS * PF_SHADE_MIN_COS);
        b = pf_add(pf_scale(t, s / tl), pf_scale(hit->ng, PF_SHADE_MIN_COS));
    }
    if (!pf_is_finite3(b))
        return;
    b = pf_norm(b);
    /* ns and ng on one side; the renderer flips both for a back view. */
    float side = pf_dot(wo, hit->ng) < 0.0f ? -1.0f : 1.0f;
    b = pf_scale(s_valid_reflection(pf_scale(b, side), pf_scale(hit->ng, side), wo), side);
    hit->ns = b;
}
