/* difftrans.h: the diffuse transmission material (PF_MAT_DIFFUSE_TRANSMISSION,
 * pbrt-v4's DiffuseTransmissionBxDF): a thin sheet that reflects a
 * Lambertian share kd (R) back to the side the light comes from and
 * transmits a Lambertian share kt (T) to the other side, alike from both
 * sides:
 *   f(wo, wi) = R / pi   when wo and wi lie on the same side of the sheet,
 *               T / pi   when on opposite sides.
 * Sampling picks reflection with probability pr / (pr + pt), pr = max_c R,
 * pt = max_c T (pbrt's choice), then a cosine direction in that hemisphere,
 * so the weight f |cos| / pdf is R (pr + pt) / pr or T (pr + pt) / pt.
 * R + T <= 1 per channel conserves energy (finalize checks it); R + T = 1
 * passes the white furnace (tests/material/test_difftrans.c).
 *
 * Directions are unit vectors pointing away from the surface, n a unit
 * normal (either side: the sheet has no front); pure functions, any thread. */
#ifndef PF_DIFFTRANS_H
#define PF_DIFFTRANS_H

#include "base/vec.h"
#include "scene/scene.h"

static inline int pf_mat_difftrans(const pf_material_t *m) { return m->type == PF_MAT_DIFFUSE_TRANSMISSION; }

/* f(wo, wi) as above (the cosine not included); zero when either lies in the sheet's plane. */
pf_vec3 pf_difftrans_eval(const pf_material_t *m, pf_vec3 n, pf_vec3 wo, pf_vec3 wi);

/* The solid-angle pdf with which pf_difftrans_sample draws wi given wo. */
float pf_difftrans_pdf(const pf_material_t *m, pf_vec3 n, pf_vec3 wo, pf_vec3 wi);

/* Samples wi given wo from u0 (the side) and u1, u2 (the direction): 1 with
 * *wi, *weight = f |cos_i| / pdf and *pdf, or 0 when the sheet scatters
 * nothing (R = T = 0) or wo lies in its plane. */
int pf_difftrans_sample(const pf_material_t *m, pf_vec3 n, pf_vec3 wo, float u0, float u1, float u2, pf_vec3 *wi,
                        pf_vec3 *weight, float *pdf);

#endif
