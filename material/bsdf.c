/* bsdf.c: scattering functions and the Phong lobe's sampling; see bsdf.h. */
#include "material/bsdf.h"

float pf_fresnel_dielectric(float cos_i, float eta_i, float eta_t)
{
    cos_i = fminf(fmaxf(cos_i, 0.0f), 1.0f);
    float sin_i = sqrtf(fmaxf(0.0f, 1.0f - cos_i * cos_i));
    float sin_t = eta_i / eta_t * sin_i;
    if (sin_t >= 1.0f)
        return 1.0f;
    float cos_t = sqrtf(fmaxf(0.0f, 1.0f - sin_t * sin_t));
    float r_par = (eta_t * cos_i - eta_i * cos_t) / (eta_t * cos_i + eta_i * cos_t);
    float r_perp = (eta_i * cos_i - eta_t * cos_t) / (eta_i * cos_i + eta_t * cos_t);
    return 0.5f * (r_par * r_par + r_perp * r_perp);
}

int pf_refract(pf_vec3 wi, pf_vec3 n, float eta, pf_vec3 *wt)
{
    float cos_i = pf_dot(n, wi);
    float sin2_i = fmaxf(0.0f, 1.0f - cos_i * cos_i);
    float sin2_t = eta * eta * sin2_i;
    if (sin2_t >= 1.0f)
        return 0;
    float cos_t = sqrtf(1.0f - sin2_t);
    *wt = pf_norm(pf_add(pf_scale(pf_neg(wi), eta), pf_scale(n, eta * cos_i - cos_t)));
    return 1;
}

pf_vec3 pf_sample_phong(float u1, float u2, float n)
{
    float z = powf(1.0f - u1, 1.0f / (n + 1.0f));
    float r = sqrtf(fmaxf(0.0f, 1.0f - z * z));
    float phi = 2.0f * PF_PI * u2;
    return pf_v3(r * cosf(phi), r * sinf(phi), z);
}

pf_vec3 pf_phong_eval(const pf_material_t *m, pf_vec3 n, pf_vec3 wi, pf_vec3 wo)
{
    if (m->type != PF_MAT_DIFFUSE || pf_is_black(m->ks) || pf_dot(n, wi) <= 0.0f || pf_dot(n, wo) <= 0.0f)
        return pf_v3s(0.0f);
    float c = pf_dot(pf_reflect(wi, n), wo);
    return c > 0.0f ? pf_scale(m->ks, (m->ns + 2.0f) * (0.5f * PF_INV_PI) * powf(c, m->ns)) : pf_v3s(0.0f);
}

pf_vec3 pf_brdf_eval(const pf_material_t *m, pf_vec3 n, pf_vec3 wi, pf_vec3 wo)
{
    if (m->type != PF_MAT_DIFFUSE || pf_dot(n, wi) <= 0.0f || pf_dot(n, wo) <= 0.0f)
        return pf_v3s(0.0f);
    return pf_add(pf_scale(m->kd, PF_INV_PI), pf_phong_eval(m, n, wi, wo));
}
