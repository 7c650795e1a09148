/* dielectric.c: solid glass and the thin sheet as paths split on them; see
 * dielectric.h. */
#include "material/dielectric.h"

#include "material/bsdf.h"
#include "material/ggx.h"

float pf_fresnel_thin(float cos_i, float eta)
{
    float r = pf_fresnel_dielectric(fabsf(cos_i), 1.0f, eta);
    if (r >= 1.0f)
        return 1.0f;
    float t = 1.0f - r;
    return r + t * t * r / (1.0f - r * r);
}

pf_dielectric_t pf_dielectric_at(const pf_material_t *m, pf_vec3 d, pf_vec3 ng, pf_vec3 wo, pf_vec3 ns)
{
    pf_dielectric_t g;
    g.wr = pf_reflect(wo, ns);
    g.kr = m->ks;
    g.gr = g.gt = 1.0f;
    if (m->type == PF_MAT_THIN_DIELECTRIC) {
        g.f = pf_fresnel_thin(pf_dot(wo, ns), m->ior);
        g.wt = d;
        g.can_refract = g.f < 1.0f;
        g.kt = m->kt;
        return g;
    }
    int entering = pf_dot(d, ng) < 0.0f;
    float eta_i = entering ? 1.0f : m->ior, eta_t = entering ? m->ior : 1.0f;
    g.f = pf_fresnel_dielectric(pf_dot(wo, ns), eta_i, eta_t);
    g.wt = pf_v3s(0.0f);
    g.can_refract = g.f < 1.0f && pf_refract(wo, ns, eta_i / eta_t, &g.wt);
    /* Radiance scales by (eta_i / eta_t)^2 across the interface, seen from the receiving side. */
    float s = eta_i / eta_t;
    g.kt = pf_scale(m->kt, s * s);
    return g;
}

pf_dielectric_t pf_dielectric_rough_at(const pf_material_t *m, pf_vec3 d, pf_vec3 ng, pf_vec3 wo, pf_vec3 ns, float u1,
                                       float u2)
{
    pf_vec3 t, b;
    pf_basis(ns, &t, &b);
    pf_vec3 lo = pf_v3(pf_dot(wo, t), pf_dot(wo, b), pf_dot(wo, ns));
    if (lo.z <= 1e-6f) /* grazing beyond the shading normal: as smooth glass */
        return pf_dielectric_at(m, d, ng, wo, ns);
    pf_vec3 lm = pf_ggx_sample_vn(lo, m->alpha, u1, u2);
    pf_vec3 wm = pf_norm(pf_add(pf_add(pf_scale(t, lm.x), pf_scale(b, lm.y)), pf_scale(ns, lm.z)));
    pf_dielectric_t g = pf_dielectric_at(m, d, ng, wo, wm);
    float g1 = pf_ggx_g1(lo, m->alpha);
    /* Each branch must leave on its side of the macrosurface: the
     * reflection above ns, the refraction below. */
    float cr = pf_dot(g.wr, ns), ct = pf_dot(g.wt, ns);
    pf_vec3 lr = pf_v3(0.0f, 0.0f, fabsf(cr)), lt = pf_v3(0.0f, 0.0f, fabsf(ct));
    lr.x = pf_dot(g.wr, t), lr.y = pf_dot(g.wr, b);
    lt.x = pf_dot(g.wt, t), lt.y = pf_dot(g.wt, b);
    g.gr = cr > 0.0f ? pf_ggx_g2(lo, lr, m->alpha) / g1 : 0.0f;
    g.gt = g.can_refract && ct < 0.0f ? pf_ggx_g2(lo, lt, m->alpha) / g1 : 0.0f;
    g.kr = pf_scale(g.kr, g.gr);
    g.kt = pf_scale(g.kt, g.gt);
    return g;
}
