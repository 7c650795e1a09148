/* ggx.h: the rough conductor: an isotropic GGX (Trowbridge-Reitz)
 * microfacet BRDF with height-correlated Smith masking-shadowing, the exact
 * unpolarized Fresnel reflectance of a conductor of complex index eta + i k
 * per RGB channel (pbrt-v4's FrComplex), and sampling of the visible normals
 * (Heitz 2018, "Sampling the GGX distribution of visible normals").
 * Directions are unit vectors pointing away from the surface; the verbs
 * (eval, sample, pdf) take the material and the unit shading normal n, as
 * bsdf.h does. Pure functions, any thread. */
#ifndef PF_GGX_H
#define PF_GGX_H

#include "base/vec.h"
#include "scene/scene.h"

/* Below this alpha a conductor is a smooth mirror tinted by its Fresnel. */
#define PF_GGX_SMOOTH 1e-3f

static inline int pf_mat_conductor(const pf_material_t *m) { return m->type == PF_MAT_CONDUCTOR; }
/* A conductor rough enough for the microfacet model (else a Fresnel mirror). */
static inline int pf_mat_rough(const pf_material_t *m)
{
    return m->type == PF_MAT_CONDUCTOR && m->alpha >= PF_GGX_SMOOTH;
}

/* Unpolarized Fresnel reflectance of a conductor of complex index eta + i k
 * (relative to the outside) at incident cosine cos_i (clamped to [0, 1]). */
float pf_fresnel_complex(float cos_i, float eta, float k);
/* Per channel, for the material's eta and k. */
pf_vec3 pf_fresnel_conductor(float cos_i, pf_vec3 eta, pf_vec3 k);

/* The GGX terms in the local frame (z along the normal): the distribution
 * of normals D(wm), Smith's Lambda(w), G1(w) = 1 / (1 + Lambda(w)) and the
 * height-correlated G2 = 1 / (1 + Lambda(wo) + Lambda(wi)). */
float pf_ggx_d(pf_vec3 wm, float alpha);
float pf_ggx_lambda(pf_vec3 w, float alpha);
float pf_ggx_g1(pf_vec3 w, float alpha);
float pf_ggx_g2(pf_vec3 wo, pf_vec3 wi, float alpha);
/* A visible normal for local wo (wo.z > 0), distributed with pdf
 * G1(wo) max(0, wo.wm) D(wm) / wo.z (Heitz 2018). */
pf_vec3 pf_ggx_sample_vn(pf_vec3 wo, float alpha, float u1, float u2);

/* A GGX reflection sampled from the visible normals about n (any unit
 * normal, its frame from pf_basis): 0 when wo is below the surface or the
 * reflection goes below it or has zero pdf; else 1 with the world *wi, the
 * cosine *cos_h = wo.wm that Fresnel takes, *g = G2 / G1(wo) and the
 * solid-angle *pdf of wi. Shared by the conductor and the coat. */
int pf_ggx_sample_reflect(pf_vec3 n, pf_vec3 wo, float alpha, float u1, float u2, pf_vec3 *wi, float *cos_h,
                          float *g, float *pdf);

/* The BRDF of a rough conductor: D G2 F / (4 cos_o cos_i), F at wo.wm.
 * Zero when either direction is below the surface. */
pf_vec3 pf_conductor_eval(const pf_material_t *m, pf_vec3 n, pf_vec3 wo, pf_vec3 wi);
/* The solid-angle pdf with which pf_conductor_sample returns wi given wo. */
float pf_conductor_pdf(const pf_material_t *m, pf_vec3 n, pf_vec3 wo, pf_vec3 wi);
/* Samples wi given wo from the visible normals: returns 0 when the sample
 * goes below the surface, else 1 with *wi, *weight = f cos_i / pdf
 * (= F G2 / G1(wo)) and *pdf. */
int pf_conductor_sample(const pf_material_t *m, pf_vec3 n, pf_vec3 wo, float u1, float u2, pf_vec3 *wi,
                        pf_vec3 *weight, float *pdf);

/* Reflection off any conductor for a path that follows it (gather rays,
 * photons, specular chains): a smooth one as a mirror tinted by its Fresnel
 * at wo, a rough one by pf_conductor_sample (u1, u2 unused when smooth).
 * Returns 0 when the sample carries nothing, else 1 with *wi and
 * *weight = f cos / pdf. */
int pf_conductor_scatter(const pf_material_t *m, pf_vec3 n, pf_vec3 wo, float u1, float u2, pf_vec3 *wi,
                         pf_vec3 *weight);

#endif
