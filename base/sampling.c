/* sampling.c: direction and point warps, triangle point error; see sampling.h. */
#include "base/sampling.h"

#include <math.h>

pf_vec3 pf_sample_cosine(float u1, float u2)
{
    float r = sqrtf(u1);
    float phi = 2.0f * PF_PI * u2;
    return pf_v3(r * cosf(phi), r * sinf(phi), sqrtf(fmaxf(0.0f, 1.0f - u1)));
}

pf_vec3 pf_sample_sphere(float u1, float u2)
{
    float z = 1.0f - 2.0f * u1;
    float r = sqrtf(fmaxf(0.0f, 1.0f - z * z));
    float phi = 2.0f * PF_PI * u2;
    return pf_v3(r * cosf(phi), r * sinf(phi), z);
}

pf_vec3 pf_sample_cone(float u1, float u2, float cos_max)
{
    float z = 1.0f - u1 * (1.0f - cos_max);
    float r = sqrtf(fmaxf(0.0f, 1.0f - z * z));
    float phi = 2.0f * PF_PI * u2;
    return pf_v3(r * cosf(phi), r * sinf(phi), z);
}

void pf_sample_triangle(float u1, float u2, float *b0, float *b1)
{
    float s = sqrtf(u1);
    *b0 = 1.0f - s;
    *b1 = u2 * s;
}

static inline float s_gamma(int n)
{
    const float eps = 0x1p-24f;
    return (float)n * eps / (1.0f - (float)n * eps);
}

pf_vec3 pf_tri_point_error(pf_vec3 p0, pf_vec3 p1, pf_vec3 p2, float b0, float b1, float b2)
{
    pf_vec3 s = pf_add(pf_add(pf_vabs(pf_scale(p0, b0)), pf_vabs(pf_scale(p1, b1))), pf_vabs(pf_scale(p2, b2)));
    return pf_scale(s, s_gamma(7));
}
