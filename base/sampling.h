/* sampling.h: warps from uniform numbers to directions and points (pdfs
 * stated beside each), and the floating-point error bound of a point
 * interpolated on a triangle. Pure functions, any thread; used by the
 * lights, the materials and the ray accelerator alike. */
#ifndef PF_SAMPLING_H
#define PF_SAMPLING_H

#include "base/vec.h"

/* Cosine-weighted direction about +z from two uniforms; pdf = cos / pi. */
pf_vec3 pf_sample_cosine(float u1, float u2);
/* Uniform direction on the sphere; pdf = 1 / (4 pi). */
pf_vec3 pf_sample_sphere(float u1, float u2);
/* Uniform direction in the cone about +z with cos theta >= cos_max; pdf = 1 / (2 pi (1 - cos_max)). */
pf_vec3 pf_sample_cone(float u1, float u2, float cos_max);
/* Uniform barycentrics on a triangle (b0, b1; b2 = 1 - b0 - b1). */
void pf_sample_triangle(float u1, float u2, float *b0, float *b1);

/* Error bound of a point interpolated from triangle vertices with barycentrics
 * (pbrt-v3, 3.9.2): gamma(7) (|b0 p0| + |b1 p1| + |b2 p2|). */
pf_vec3 pf_tri_point_error(pf_vec3 p0, pf_vec3 p1, pf_vec3 p2, float b0, float b1, float b2);

#endif
