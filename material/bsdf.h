/* bsdf.h: the scattering functions: Lambertian, energy-conserving Phong
 * (Lafortune & Willems 1994: f = ks (n+2)/(2 pi) cos^n alpha), perfect mirror,
 * smooth dielectric (Fresnel, Snell, total internal reflection), and the
 * Phong lobe's sampling routine with its pdf (the general warps are in
 * base/sampling.h). Directions are unit vectors pointing away
 * from the surface unless named otherwise; pure functions, any thread. */
#ifndef PF_BSDF_H
#define PF_BSDF_H

#include "base/sampling.h"
#include "base/vec.h"
#include "scene/scene.h"

/* Mirror direction of v (pointing away from the surface) about unit n. */
static inline pf_vec3 pf_reflect(pf_vec3 v, pf_vec3 n) { return pf_sub(pf_scale(n, 2.0f * pf_dot(v, n)), v); }

/* Unpolarized Fresnel reflectance of a dielectric interface. cos_i is the
 * cosine of the incident angle (> 0, on the side of index eta_i). Returns 1 on
 * total internal reflection. */
float pf_fresnel_dielectric(float cos_i, float eta_i, float eta_t);

/* Refracts wi (pointing away from the surface, on n's side) through unit n
 * with eta = eta_i / eta_t. Returns 0 on total internal reflection, else 1
 * with *wt the transmitted direction (pointing away, on the other side). */
int pf_refract(pf_vec3 wi, pf_vec3 n, float eta, pf_vec3 *wt);

/* Direction about +z with pdf (n+1)/(2 pi) cos^n theta (the Phong lobe). */
pf_vec3 pf_sample_phong(float u1, float u2, float n);
static inline float pf_phong_pdf(float cos_alpha, float n)
{
    return cos_alpha > 0.0f ? (n + 1.0f) * (0.5f * PF_INV_PI) * powf(cos_alpha, n) : 0.0f;
}

/* BRDF of a DIFFUSE material (Lambert + Phong lobe) for unit wi, wo on the
 * side of unit n. Zero when either is below the surface. */
pf_vec3 pf_brdf_eval(const pf_material_t *m, pf_vec3 n, pf_vec3 wi, pf_vec3 wo);
/* Its Phong lobe alone, ks (ns + 2) / (2 pi) cos^ns alpha (alpha between wi
 * and wo's mirror direction about n); zero without a lobe or below. */
pf_vec3 pf_phong_eval(const pf_material_t *m, pf_vec3 n, pf_vec3 wi, pf_vec3 wo);
/* The solid-angle pdf with which the lobe's sampling (pf_sample_phong about
 * wo's mirror direction) returns wi; below the surface included, as the
 * sampler draws there too (those samples carry nothing). */
static inline float pf_phong_pdf_dir(const pf_material_t *m, pf_vec3 n, pf_vec3 wi, pf_vec3 wo)
{
    return pf_phong_pdf(pf_dot(pf_reflect(wo, n), wi), m->ns);
}

/* True when the material has a Phong lobe. */
static inline int pf_mat_glossy(const pf_material_t *m) { return m->type == PF_MAT_DIFFUSE && !pf_is_black(m->ks); }
/* True when the material scatters diffusely or glossily (photons are stored there; a coated
 * surface always; a diffuse transmitter that reflects or transmits). */
static inline int pf_mat_nonspecular(const pf_material_t *m)
{
    return (m->type == PF_MAT_DIFFUSE && !(pf_is_black(m->kd) && pf_is_black(m->ks))) || m->type == PF_MAT_COATED ||
           (m->type == PF_MAT_DIFFUSE_TRANSMISSION && !(pf_is_black(m->kd) && pf_is_black(m->kt)));
}

#endif
