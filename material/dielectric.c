/* dielectric.c: solid glass and the thin sheet as paths split on them; see
 * dielectric.h. */
#include "material/dielectric.h"

#include "material/bsdf.h"

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
