/* direct_impl.h (private to render/): direct light at a camera path's
 * non-specular point (direct.c), and the MIS weights render.c gives the
 * emitters its BSDF and gather rays meet, so that every way of reaching an
 * emitter shares it exactly once. */
#ifndef PF_RENDER_DIRECT_IMPL_H
#define PF_RENDER_DIRECT_IMPL_H

#include "accel/accel.h"
#include "base/rng.h"
#include "base/vec.h"
#include "scene/scene.h"

/* render.h's context (this header is read by render.c, and so may not
 * read render.h itself) */
typedef struct pf_render_ctx pf_render_ctx_t;

/* The power heuristic's weight of a sample of pdf a (taken na times) against
 * the other strategy's pdf b (taken nb times). */
float pf_mis_power(float na, float a, float nb, float b);

/* Direct light leaving towards wo at hit h of material m (nf, ns: its
 * camera-facing geometric and shading normals): light_samples shadow rays
 * to emitters chosen by power (three numbers each from rng), and one to
 * each distant light. A rough conductor's, and a rough coat's lobe, weigh
 * their samples by MIS against the BSDF ray traced when `recurse` is set; a
 * plain diffuse point whose ng > 0 gather rays count the sky they see
 * (pf_direct_sky_mis) weighs its sky samples against them. A diffuse
 * transmitter takes as many samples on each side. */
pf_vec3 pf_direct_light(const pf_render_ctx_t *c, pf_rng_t *rng, const pf_hit_t *h, const pf_material_t *m, pf_vec3 nf,
                        pf_vec3 ns, pf_vec3 wo, int recurse, int ng);

/* The radiance a gather ray's end h, nearer than the irradiance points'
 * blur (maps->near_r), leaves towards wo, read as a diffuse surface of
 * reflectance kd: its direct light sampled, the rest of its irradiance
 * from the point the lookup reads (its direct share taken out). */
pf_vec3 pf_direct_near_end(const pf_render_ctx_t *c, pf_rng_t *rng, const pf_hit_t *h, const pf_material_t *m,
                           pf_vec3 kd, pf_vec3 nf, pf_vec3 ns, pf_vec3 wo);

/* How many of a diffuse point's ng gather rays count the sky they see
 * straight from it: ng when the point is plainly diffuse and both direct
 * light and the gather are rendered, else 0 (the sky is then light
 * sampling's alone). */
int pf_direct_sky_mis(const pf_render_ctx_t *c, const pf_material_t *m, int ng);

/* The sky a gather ray along d sees straight from a diffuse point of
 * shading normal ns, one of ng, weighted by MIS against that point's light
 * samples. */
pf_vec3 pf_direct_gather_sky(const pf_render_ctx_t *c, pf_vec3 ns, int ng, pf_vec3 d);

#endif
