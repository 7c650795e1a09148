/* light.h: the scene's emitters in one power-weighted table: every emissive
 * triangle (an area light along its face normal, or on both sides when its
 * material is two-sided), every emissive
 * analytic sphere (emitting outward, sampled by its cone: spherelight.h), point, spot,
 * distant and infinite lights (a constant sky, or an image-based one:
 * envlight.h). Used for direct-light sampling (worker) and photon emission
 * (coordinator); with many emitters direct light chooses through a light
 * BVH instead (lightbvh.h), emission always by power. Built once, then
 * read-only from any thread. */
#ifndef PF_LIGHT_H
#define PF_LIGHT_H

#include <stddef.h>
#include <stdint.h>

#include "base/vec.h"
#include "scene/scene.h"

typedef struct pf_lights pf_lights_t;

/* Builds the table. NULL when out of memory; an empty table (no power) is
 * valid and samples nothing. */
pf_lights_t *pf_lights_build(const pf_scene_t *scene);
void pf_lights_destroy(pf_lights_t **self_p);

/* The radiance a ray leaving the scene along d sees: the infinite lights'
 * summed, maps looked up along d (zero without any). */
pf_vec3 pf_lights_sky(const pf_lights_t *self, pf_vec3 d);

/* The solid-angle pdf with which pf_lights_sample_direct_at, given the
 * normal n (zero: pf_lights_sample_direct), returns the sky direction d:
 * the sky's probability times its direction pdf; 0 without a sky. (All
 * infinite lights make one emitter: their radiances add; with maps, the
 * mixture of every sky entry's pmf times its pdf.) */
float pf_lights_sky_pdf(const pf_lights_t *self, pf_vec3 n, pf_vec3 d);
/* pf_lights_sky(d) and, in *pdf, pf_lights_sky_pdf(n, d), bit for bit,
 * each map read once for both. */
pf_vec3 pf_lights_sky_mis(const pf_lights_t *self, pf_vec3 n, pf_vec3 d, float *pdf);

/* Total emitted power (W, luminance-weighted) and the number of emitters. */
double pf_lights_power(const pf_lights_t *self);
size_t pf_lights_count(const pf_lights_t *self);

/* A sampled light connection from a receiving point. */
typedef struct pf_light_conn {
    pf_vec3 wi;      /* unit direction from the receiver to the light point */
    float dist;      /* distance to the light point; INFINITY for a distant or infinite light (a shadow
                      * ray unoccluded to infinity) */
    pf_vec3 weight;  /* Le cos_l / (d^2 pdf), i.e. incident radiance over pdf */
    float pdf;       /* the solid-angle pdf of wi (area and infinite lights), 0 for point, spot and distant
                      * lights (a delta) */
} pf_light_conn_t;

/* Samples one emitter and a point on it, as seen from x: by power, or with
 * many bounded emitters by their importance at x through a light BVH
 * (light.c, lightbvh.h); photon emission stays by power. The distant
 * lights are not among them: a direct estimate adds each of those apart
 * (pf_lights_distant), since a delta chosen by power would make a sunlit
 * point's light a coin toss. Returns 0 when the sample carries nothing (back
 * of a one-sided light, zero distance, no emitter but distant ones), else 1.
 * Uses u[0..2]. */
int pf_lights_sample_direct(const pf_lights_t *self, const pf_scene_t *scene, pf_vec3 x, const float u[3],
                            pf_light_conn_t *out);

/* The same at a receiver whose (shading) normal n is known: a constant
 * infinite light then draws its directions cosine-weighted about n rather than
 * uniformly over the sphere (what lies below n gets no sample; the caller
 * weighs by cos about n, so that is no loss). n zero: as
 * pf_lights_sample_direct. A map draws from its own distribution either
 * way. Every other light samples as there. */
int pf_lights_sample_direct_at(const pf_lights_t *self, const pf_scene_t *scene, pf_vec3 x, pf_vec3 n,
                               const float u[3], pf_light_conn_t *out);

/* The distant lights, for direct light: each makes a connection of its own
 * (weight E, the irradiance it brings at normal incidence; pdf 0, a delta;
 * dist INFINITY), i in [0, pf_lights_distant_count). Photon emission still
 * chooses among all emitters by power. */
size_t pf_lights_distant_count(const pf_lights_t *self);
void pf_lights_distant(const pf_lights_t *self, const pf_scene_t *scene, size_t i, pf_light_conn_t *out);

/* The solid-angle pdf with which pf_lights_sample_direct, called at x,
 * returns the point p on triangle prim of mesh geom (a hit's geom and
 * prim): the emitter's probability times its area pdf, converted to solid
 * angle; for geom == scene->nmeshes (the accelerator's sphere geometry),
 * sphere prim's probability times its cone's pdf. 0 when that triangle or
 * sphere is no light in the table, or x sees its back (inside a sphere). */
float pf_lights_pdf(const pf_lights_t *self, const pf_scene_t *scene, pf_vec3 x, uint32_t geom, uint32_t prim,
                    pf_vec3 p);

/* The same for pf_lights_sample_direct_at with the receiver's normal nx:
 * with many emitters the choice depends on where x is and which way it faces
 * (a light BVH, lightbvh.h), so MIS must ask with the same (x, nx). */
float pf_lights_pdf_at(const pf_lights_t *self, const pf_scene_t *scene, pf_vec3 x, pf_vec3 nx, uint32_t geom,
                       uint32_t prim, pf_vec3 p);

/* An emitted photon: origin, direction, and flux scaled by the number of
 * photons (divide by the emitted count). perr bounds the origin's error and
 * n is the surface normal at the origin (zero for point, spot, distant and
 * infinite lights; their photons start on a disc outside the scene's
 * bounding sphere, perpendicular to the light's direction, or for an
 * infinite light to a direction uniform over the sphere, or drawn from its
 * map's distribution for an image-based one). */
typedef struct pf_emission {
    pf_ray_t ray;
    pf_vec3 flux;
    pf_vec3 perr;
    pf_vec3 n;
} pf_emission_t;

/* Emits a photon: picks an emitter by power, a point and a direction. Uses
 * u[0..4]. Returns 0 if the table is empty. */
int pf_lights_emit(const pf_lights_t *self, const pf_scene_t *scene, const float u[5], pf_emission_t *out);

/* A bounding sphere of specular geometry that caustic photons are aimed at. */
typedef struct pf_target {
    pf_vec3 center;
    float radius;
} pf_target_t;

/* The cone from p that holds target t: unit axis, cos of the half-angle and
 * solid angle; a point inside the sphere sees the whole sphere of directions
 * (cos -1, solid 4 pi). For pf_lights_emit_targeted (targets.c). */
void pf_target_cone(pf_vec3 p, const pf_target_t *t, pf_vec3 *axis, float *cos_max, float *solid);

/* Bounding spheres of the scene's mirror, glass and conductor geometry: one
 * per mesh (over its specular triangles) and one per specular sphere. *out is
 * malloc'd (NULL when there are none). Returns the count, or PF_ENOMEM. */
int pf_specular_targets(const pf_scene_t *scene, pf_target_t **out);

/* Emits a photon aimed at the targets: an emitter by power, a point on it,
 * then a direction uniform in the cone of a target chosen uniformly. The
 * flux divides by the mixture pdf of all cones containing the direction, so
 * the estimate is unbiased for every path that reaches a target (and every
 * specular surface lies inside one). Returns 0 when the sample carries nothing
 * (direction behind a one-sided emitter). Uses u[0..5]. */
int pf_lights_emit_targeted(const pf_lights_t *self, const pf_scene_t *scene, const pf_target_t *targets,
                            size_t ntargets, const float u[6], pf_emission_t *out);

/* Smooth spot falloff: 1 inside cos_inner, 0 outside cos_outer. */
float pf_spot_falloff(const pf_light_t *l, float cos_theta);

#endif
