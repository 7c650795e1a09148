/* sphtri.h: a triangle as the receiver sees it, a spherical triangle on
 * the unit sphere about the receiver: its solid angle, and directions
 * uniform within it (Arvo 1995, "Stratified sampling of spherical
 * triangles", as pbrt-v4's SampleSphericalTriangle). Direct light samples
 * a large or near triangle emitter this way: its pdf is 1 / solid angle
 * everywhere on it, where area sampling's is d^2 / (A cos_l), huge at the
 * light's near edge and at grazing angles, so the walls next to a ceiling
 * lamp are no longer noisy there. Pure functions, in double inside; any
 * thread. */
#ifndef PF_SPHTRI_H
#define PF_SPHTRI_H

#include "base/vec.h"

/* The range of solid angles (sr) spherical sampling serves (pbrt-v4's):
 * below, Arvo's formulas lose their precision and area sampling is as
 * good (the triangle is small and far); above, the triangle wraps much of
 * the hemisphere round the receiver. */
#define PF_SPHTRI_MIN 3e-4
#define PF_SPHTRI_MAX 6.22

/* The solid angle of triangle p0 p1 p2 seen from x (Van Oosterom and
 * Strackee); 0 when x lies in its plane or on a vertex. */
double pf_sphtri_solid_angle(pf_vec3 x, pf_vec3 p0, pf_vec3 p1, pf_vec3 p2);

/* A unit direction from x, uniform in the solid angle of triangle p0 p1 p2
 * (pdf 1 / pf_sphtri_solid_angle), from u0, u1 in [0, 1): 1 and *w, or 0
 * when the triangle seen from x is degenerate. */
int pf_sphtri_sample(pf_vec3 x, pf_vec3 p0, pf_vec3 p1, pf_vec3 p2, float u0, float u1, pf_vec3 *w);

#endif
