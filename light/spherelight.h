/* spherelight.h: private to light/. An emissive analytic sphere
 * (pf_sphere_t whose material has le) as an emitter: it emits its Le
 * outward only (pbrt's area light on an unreversed sphere), so its power is
 * pi 4 pi r^2 lum(Le), as a triangle's pi A lum(Le). Direct light samples it
 * uniformly in the cone it subtends from the receiver (pbrt-v4
 * Sphere::Sample(ctx, u)), which is exact for the solid angle it covers; a
 * receiver inside sees only the back of an outward emitter, so gets nothing.
 * Photons start uniformly on the surface. Pure functions of the sphere. */
#ifndef PF_SPHERELIGHT_H
#define PF_SPHERELIGHT_H

#include "base/vec.h"
#include "light/lightbvh.h"
#include "scene/scene.h"

/* The sphere's area 4 pi r^2 (float, as a triangle entry's area). */
float pf_sphere_light_area(const pf_sphere_t *s);

/* The solid-angle pdf of a direction drawn by pf_sphere_light_sample at x:
 * 1 / (2 pi (1 - cos theta_max)), the same for every direction that meets
 * the sphere; 0 when x is inside it or on it. */
float pf_sphere_light_pdf(const pf_sphere_t *s, pf_vec3 x);

/* Draws a point on the part of the sphere x sees, its direction uniform in
 * the cone the sphere subtends from x: *wi the unit direction to it, *dist
 * its distance, *pdf pf_sphere_light_pdf(s, x). Returns 0 (nothing set) when
 * x is inside or on the sphere, else 1. */
int pf_sphere_light_sample(const pf_sphere_t *s, pf_vec3 x, float u1, float u2, pf_vec3 *wi, float *dist,
                           float *pdf);

/* A point uniform over the sphere (pdf 1 / area): position, unit outward
 * normal and its error bound (as accel.c's sphere hits). */
void pf_sphere_light_point(const pf_sphere_t *s, float u1, float u2, pf_vec3 *p, pf_vec3 *n, pf_vec3 *perr);

/* The light BVH's bounds of the sphere emitting power phi: its box, normals
 * in every direction (cos_theta_o -1), each spreading over pi/2. */
pf_light_bounds_t pf_sphere_light_bounds(const pf_sphere_t *s, float phi);

#endif
