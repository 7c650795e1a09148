/* dielectric.h: the smooth dielectrics as the paths that follow them see
 * them: solid glass (PF_MAT_GLASS: Fresnel, Snell, total internal reflection
 * when leaving the denser side) and the thin sheet (PF_MAT_THIN_DIELECTRIC,
 * pbrt-v4's ThinDielectricBxDF: a pane whose two parallel faces are summed
 * over all inner bounces, so the light that crosses it goes on unbent and
 * both sides behave alike). Directions are unit vectors pointing away from the
 * surface unless named otherwise; pure functions, any thread. */
#ifndef PF_DIELECTRIC_H
#define PF_DIELECTRIC_H

#include "base/vec.h"
#include "scene/scene.h"

/* True for the materials pf_dielectric_at serves (both count as specular). */
static inline int pf_mat_dielectric(const pf_material_t *m)
{
    return m->type == PF_MAT_GLASS || m->type == PF_MAT_THIN_DIELECTRIC;
}

/* Reflectance R' of a thin sheet of index eta in vacuum at incident cosine
 * cos_i (its absolute value is taken, so both sides give the same): with R
 * the single interface's Fresnel reflectance and T = 1 - R, the inner
 * bounces sum to R' = R + T^2 R / (1 - R^2); the sheet transmits 1 - R'.
 * Returns 1 at grazing incidence (R = 1). Never total internal reflection. */
float pf_fresnel_thin(float cos_i, float eta);

/* How a dielectric hit splits a path into reflection and transmission. */
typedef struct pf_dielectric {
    float f;         /* probability of reflection: Fresnel R (glass) or R' (thin sheet) */
    int can_refract; /* 0 under total internal reflection (glass only) or when f = 1 */
    pf_vec3 wr;      /* the mirror direction */
    pf_vec3 wt;      /* the transmitted direction (refracted; for a thin sheet -wo, unbent) */
    pf_vec3 kt;      /* radiance tint of the transmitted branch: kt (eta_i / eta_t)^2 for glass,
                      * kt for a thin sheet (its two crossings cancel); photons carry power,
                      * so they take the material's kt unscaled (times gt) */
    pf_vec3 kr;      /* tint of the reflected branch: ks (rough glass: ks gr) */
    float gr, gt;    /* rough glass: the branches' sampling weights G2 / G1 (0: that branch leaves on
                      * the wrong side of the surface; kr and kt include them); 1 when smooth */
} pf_dielectric_t;

/* Glass rough enough for microfacets (GGX alpha >= 1e-3; pbrt-v4's rough
 * dielectric). */
static inline int pf_mat_rough_glass(const pf_material_t *m)
{
    return m->type == PF_MAT_GLASS && m->alpha >= 1e-3f;
}

/* The split of a dielectric material m (pf_mat_dielectric) hit by a ray of
 * direction d at geometric normal ng; wo = -d, ns the shading normal on wo's
 * side. Glass is entered when d runs against ng (the winding tells inside
 * from outside); a thin sheet has no inside. */
pf_dielectric_t pf_dielectric_at(const pf_material_t *m, pf_vec3 d, pf_vec3 ng, pf_vec3 wo, pf_vec3 ns);

/* The split of rough glass (pf_mat_rough_glass) as one sample of pbrt-v4's
 * rough DielectricBxDF: a microfacet normal wm drawn from the visible
 * normals of wo (u1, u2; ggx.h), then pf_dielectric_at about wm: f is the
 * Fresnel reflectance at wo.wm, wr and wt are mirrored and refracted about
 * wm, and the single-scattering weights G2 / G1 of each branch are in gr
 * and gt (and kr, kt). A path that takes the reflected branch with
 * probability f carries kr, the refracted one kt: f cos / pdf of the BSDF. */
pf_dielectric_t pf_dielectric_rough_at(const pf_material_t *m, pf_vec3 d, pf_vec3 ng, pf_vec3 wo, pf_vec3 ns, float u1,
                                       float u2);

#endif
