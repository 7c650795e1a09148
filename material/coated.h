/* coated.h: the coated diffuse material (PF_MAT_COATED, pbrt-v4's
 * coateddiffuse): a Lambertian base of albedo kd under a clear dielectric
 * coat of index ior, GGX roughness alpha (below PF_GGX_SMOOTH a smooth
 * interface) and thickness (pbrt's: every crossing of the layer attenuates
 * by exp(-thickness / |cos|), cos inside the coat).
 *
 * Model: the analytic layered approximation of Weidlich & Wilkie 2007 as
 * Mitsuba's plastic/roughplastic use it, made energy-consistent:
 *   f = f_coat + f_base
 *   f_coat(wo, wi) = F(wo.wm) D(wm) G2 / (4 cos_o cos_i)   (smooth: a mirror of weight F(cos_o))
 *   f_base(wo, wi) = kd (1 - A(wi)) T(wi) (1 - A(wo)) T(wo) / (pi eta^2 (1 - kd r))
 * with A(w) the coat's directional albedo (its reflection lobe's integral;
 * exactly the Fresnel reflectance when smooth; tabulated over (cos, alpha,
 * eta) for rough coats), T(w) = exp(-thickness / cos_t), cos_t the cosine of
 * w refracted into the coat, and r the hemispherical reflectance the base's
 * upgoing (Lambertian) light meets at the coat's underside, round trip
 * attenuation included: total internal reflection below the critical angle,
 * above it A by reciprocity (the coat's transmission is symmetric). With
 * thickness 0 this gives 1 - r = (1 - mean A) / eta^2 exactly, so kd = 1
 * reflects everything: A(wo) + base albedo(wo) = 1 (the white furnace).
 * tests/material/test_coated.c compares the directional albedo with a
 * Monte Carlo random walk through the layer (pbrt-v4's stochastic layered
 * BSDF, GGX interface included).
 *
 * Directions are unit vectors pointing away from the surface, n the unit
 * shading normal; pure functions, any thread (the albedo table's slice of an
 * index is built once, on first use). */
#ifndef PF_COATED_H
#define PF_COATED_H

#include "base/vec.h"
#include "scene/scene.h"

static inline int pf_mat_coated(const pf_material_t *m) { return m->type == PF_MAT_COATED; }
/* A coated material whose coat is a smooth mirror (a delta lobe). */
int pf_coated_smooth(const pf_material_t *m);

/* A(cos_o): the coat's directional albedo at incident cosine cos_o for GGX
 * roughness alpha and index eta (Fresnel reflectance when alpha < PF_GGX_SMOOTH). */
float pf_coat_albedo(float cos_o, float alpha, float eta);

/* The two lobes of the BSDF at (wo, wi): the base's and the coat's
 * (zero when smooth), and the pdf with which pf_coated_sample_coat returns
 * wi (zero when smooth). Zero when either direction is below the surface. */
typedef struct pf_coated_f {
    pf_vec3 base;
    float coat;
    float coat_pdf;
} pf_coated_f_t;
pf_coated_f_t pf_coated_eval(const pf_material_t *m, pf_vec3 n, pf_vec3 wo, pf_vec3 wi);

/* The whole BSDF f_base + f_coat (the smooth coat's delta excluded). */
pf_vec3 pf_coated_f(const pf_material_t *m, pf_vec3 n, pf_vec3 wo, pf_vec3 wi);

/* The base's directional albedo seen from wo: the integral of f_base cos_i
 * over wi. Radiance leaving towards wo under a uniform irradiance E is
 * pf_coated_base_albedo * E / pi (the final gather's and the irradiance
 * lookups' "kd"). */
pf_vec3 pf_coated_base_albedo(const pf_material_t *m, float cos_o);

/* The reflectance the renderer applies to irradiance at a coated surface
 * seen from cos_o (radiance = kd E / pi, as for a diffuse kd): the base's
 * directional albedo (exact for uniformly incident light; the falloff with
 * the incident angle is averaged), plus, with with_coat (where a gather
 * ray ends: it does not follow the coat), the coat's albedo A(cos_o), its
 * reflection estimated as that of a uniform incident field. */
pf_vec3 pf_coated_kd(const pf_material_t *m, float cos_o, int with_coat);

/* The probability with which pf_coated_sample takes the coat lobe at wo:
 * A(wo) against the base's mean albedo. */
float pf_coated_coat_prob(const pf_material_t *m, float cos_o);

/* The solid-angle pdf of pf_coated_sample's wi given wo for a rough coat
 * (the mixture of the coat's visible-normal pdf and the base's cosine); for
 * a smooth coat the base's part only (the mirror is a delta). */
float pf_coated_pdf(const pf_material_t *m, pf_vec3 n, pf_vec3 wo, pf_vec3 wi);

/* Samples the whole BSDF: the coat lobe with pf_coated_coat_prob, else the
 * base cosine-weighted (u0 chooses, u1 u2 sample). Returns 0 when the
 * sample carries nothing, else 1 with *wi, *weight = f cos / pdf (for a
 * smooth coat's mirror, F / prob), *pdf (0 for the mirror) and *coat_lobe. */
int pf_coated_sample(const pf_material_t *m, pf_vec3 n, pf_vec3 wo, float u0, float u1, float u2, pf_vec3 *wi,
                     pf_vec3 *weight, float *pdf, int *coat_lobe);

/* Samples the coat lobe alone (a camera path's one recursive ray; the base
 * is served by light sampling, caustics and the final gather): rough, from
 * the visible normals with *weight = f_coat cos / pdf and *pdf; smooth, the
 * mirror with *weight = F(cos_o) and *pdf = 0. Returns 0 when the sample
 * goes below the surface. */
int pf_coated_sample_coat(const pf_material_t *m, pf_vec3 n, pf_vec3 wo, float u1, float u2, pf_vec3 *wi,
                          float *weight, float *pdf);

#endif
