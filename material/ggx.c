/* ggx.c: the GGX rough conductor and the conductor Fresnel; see ggx.h.
 * Local frames come from pf_basis about the shading normal; the BRDF is
 * isotropic, so the frame's twist does not matter. Pure, any thread. */
#include "material/ggx.h"

#include <complex.h>

#include "base/sampling.h"
#include "material/bsdf.h"

float pf_fresnel_complex(float cos_i, float eta, float k)
{
    double c = fmin(fmax((double)cos_i, 0.0), 1.0);
    double complex e = (double)eta + (double)k * I;
    double sin2_i = 1.0 - c * c;
    double complex sin2_t = sin2_i / (e * e);
    double complex cos_t = csqrt(1.0 - sin2_t);
    double complex r_parl = (e * c - cos_t) / (e * c + cos_t);
    double complex r_perp = (c - e * cos_t) / (c + e * cos_t);
    double n1 = creal(r_parl) * creal(r_parl) + cimag(r_parl) * cimag(r_parl);
    double n2 = creal(r_perp) * creal(r_perp) + cimag(r_perp) * cimag(r_perp);
    return (float)(0.5 * (n1 + n2));
}

pf_vec3 pf_fresnel_conductor(float cos_i, pf_vec3 eta, pf_vec3 k)
{
    return pf_v3(pf_fresnel_complex(cos_i, eta.x, k.x), pf_fresnel_complex(cos_i, eta.y, k.y),
                 pf_fresnel_complex(cos_i, eta.z, k.z));
}

float pf_ggx_d(pf_vec3 wm, float alpha)
{
    if (wm.z <= 0.0f)
        return 0.0f;
    float a2 = alpha * alpha;
    float t = (wm.x * wm.x + wm.y * wm.y) / a2 + wm.z * wm.z;
    return 1.0f / (PF_PI * a2 * t * t);
}

float pf_ggx_lambda(pf_vec3 w, float alpha)
{
    float z2 = w.z * w.z;
    if (!(z2 > 0.0f))
        return INFINITY;
    float tan2 = fmaxf(0.0f, 1.0f - z2) / z2;
    return 0.5f * (sqrtf(1.0f + alpha * alpha * tan2) - 1.0f);
}

float pf_ggx_g1(pf_vec3 w, float alpha) { return 1.0f / (1.0f + pf_ggx_lambda(w, alpha)); }

float pf_ggx_g2(pf_vec3 wo, pf_vec3 wi, float alpha)
{
    return 1.0f / (1.0f + pf_ggx_lambda(wo, alpha) + pf_ggx_lambda(wi, alpha));
}

pf_vec3 pf_ggx_sample_vn(pf_vec3 wo, float alpha, float u1, float u2)
{
    /* Stretch to the hemisphere configuration, sample the projected disc
     * (warped towards the visible half), lift, unstretch. */
    pf_vec3 vh = pf_norm(pf_v3(alpha * wo.x, alpha * wo.y, wo.z));
    float len2 = vh.x * vh.x + vh.y * vh.y;
    pf_vec3 t1 = len2 > 0.0f ? pf_scale(pf_v3(-vh.y, vh.x, 0.0f), 1.0f / sqrtf(len2)) : pf_v3(1.0f, 0.0f, 0.0f);
    pf_vec3 t2 = pf_cross(vh, t1);
    float r = sqrtf(u1), phi = 2.0f * PF_PI * u2;
    float p1 = r * cosf(phi), p2 = r * sinf(phi);
    float s = 0.5f * (1.0f + vh.z);
    p2 = (1.0f - s) * sqrtf(fmaxf(0.0f, 1.0f - p1 * p1)) + s * p2;
    float p3 = sqrtf(fmaxf(0.0f, 1.0f - p1 * p1 - p2 * p2));
    pf_vec3 nh = pf_add(pf_add(pf_scale(t1, p1), pf_scale(t2, p2)), pf_scale(vh, p3));
    return pf_norm(pf_v3(alpha * nh.x, alpha * nh.y, fmaxf(1e-6f, nh.z)));
}

/* World direction w in the local frame about n. */
static pf_vec3 s_local(pf_vec3 w, pf_vec3 n)
{
    pf_vec3 t, b;
    pf_basis(n, &t, &b);
    return pf_v3(pf_dot(w, t), pf_dot(w, b), pf_dot(w, n));
}

pf_vec3 pf_conductor_eval(const pf_material_t *m, pf_vec3 n, pf_vec3 wo, pf_vec3 wi)
{
    pf_vec3 lo = s_local(wo, n), li = s_local(wi, n);
    if (lo.z <= 0.0f || li.z <= 0.0f)
        return pf_v3s(0.0f);
    pf_vec3 h = pf_add(lo, li);
    float hl = pf_len(h);
    if (!(hl > 0.0f))
        return pf_v3s(0.0f);
    pf_vec3 wm = pf_scale(h, 1.0f / hl);
    float d = pf_ggx_d(wm, m->alpha), g = pf_ggx_g2(lo, li, m->alpha);
    pf_vec3 f = pf_fresnel_conductor(pf_dot(lo, wm), m->eta, m->k);
    return pf_scale(f, d * g / (4.0f * lo.z * li.z));
}

/* pdf of wi given wo, both local with z > 0, wm their half vector. */
static float s_pdf_local(pf_vec3 lo, pf_vec3 wm, float alpha)
{
    float c = pf_dot(lo, wm);
    if (c <= 0.0f)
        return 0.0f;
    /* D_wo(wm) / (4 wo.wm), D_wo = G1(wo) (wo.wm) D(wm) / wo.z */
    return pf_ggx_g1(lo, alpha) * pf_ggx_d(wm, alpha) / (4.0f * lo.z);
}

float pf_conductor_pdf(const pf_material_t *m, pf_vec3 n, pf_vec3 wo, pf_vec3 wi)
{
    pf_vec3 lo = s_local(wo, n), li = s_local(wi, n);
    if (lo.z <= 0.0f || li.z <= 0.0f)
        return 0.0f;
    pf_vec3 h = pf_add(lo, li);
    float hl = pf_len(h);
    if (!(hl > 0.0f))
        return 0.0f;
    return s_pdf_local(lo, pf_scale(h, 1.0f / hl), m->alpha);
}

int pf_ggx_sample_reflect(pf_vec3 n, pf_vec3 wo, float alpha, float u1, float u2, pf_vec3 *wi, float *cos_h,
                          float *g, float *pdf)
{
    pf_vec3 t, b;
    pf_basis(n, &t, &b);
    pf_vec3 lo = pf_v3(pf_dot(wo, t), pf_dot(wo, b), pf_dot(wo, n));
    if (lo.z <= 0.0f)
        return 0;
    pf_vec3 wm = pf_ggx_sample_vn(lo, alpha, u1, u2);
    float c = pf_dot(lo, wm);
    pf_vec3 li = pf_sub(pf_scale(wm, 2.0f * c), lo);
    if (li.z <= 0.0f || c <= 0.0f)
        return 0;
    *pdf = s_pdf_local(lo, wm, alpha);
    if (!(*pdf > 0.0f))
        return 0;
    *cos_h = c;
    *g = pf_ggx_g2(lo, li, alpha) / pf_ggx_g1(lo, alpha);
    *wi = pf_norm(pf_add(pf_add(pf_scale(t, li.x), pf_scale(b, li.y)), pf_scale(n, li.z)));
    return 1;
}

int pf_conductor_sample(const pf_material_t *m, pf_vec3 n, pf_vec3 wo, float u1, float u2, pf_vec3 *wi,
                        pf_vec3 *weight, float *pdf)
{
    float c, g;
    if (!pf_ggx_sample_reflect(n, wo, m->alpha, u1, u2, wi, &c, &g, pdf))
        return 0;
    *weight = pf_scale(pf_fresnel_conductor(c, m->eta, m->k), g);
    return 1;
}

int pf_conductor_scatter(const pf_material_t *m, pf_vec3 n, pf_vec3 wo, float u1, float u2, pf_vec3 *wi,
                         pf_vec3 *weight)
{
    if (pf_mat_rough(m)) {
        float pdf;
        return pf_conductor_sample(m, n, wo, u1, u2, wi, weight, &pdf);
    }
    *wi = pf_reflect(wo, n);
    *weight = pf_fresnel_conductor(pf_dot(wo, n), m->eta, m->k);
    return 1;
}
