/* vec.h: 3-vectors of float and the small amount of linear algebra the
 * renderer needs. Plain data, passed by value; everything is static inline. */
#ifndef PF_VEC_H
#define PF_VEC_H

#include <math.h>

typedef struct pf_vec3 {
    float x, y, z;
} pf_vec3;

#define PF_PI 3.14159265358979323846f
#define PF_INV_PI 0.31830988618379067154f

static inline pf_vec3 pf_v3(float x, float y, float z) { return (pf_vec3){ x, y, z }; }
static inline pf_vec3 pf_v3s(float s) { return (pf_vec3){ s, s, s }; }
static inline pf_vec3 pf_add(pf_vec3 a, pf_vec3 b) { return pf_v3(a.x + b.x, a.y + b.y, a.z + b.z); }
static inline pf_vec3 pf_sub(pf_vec3 a, pf_vec3 b) { return pf_v3(a.x - b.x, a.y - b.y, a.z - b.z); }
static inline pf_vec3 pf_mul(pf_vec3 a, pf_vec3 b) { return pf_v3(a.x * b.x, a.y * b.y, a.z * b.z); }
static inline pf_vec3 pf_scale(pf_vec3 a, float s) { return pf_v3(a.x * s, a.y * s, a.z * s); }
static inline pf_vec3 pf_madd(pf_vec3 a, pf_vec3 b, float s) { return pf_v3(a.x + b.x * s, a.y + b.y * s, a.z + b.z * s); }
static inline pf_vec3 pf_neg(pf_vec3 a) { return pf_v3(-a.x, -a.y, -a.z); }
static inline float pf_dot(pf_vec3 a, pf_vec3 b) { return a.x * b.x + a.y * b.y + a.z * b.z; }
static inline pf_vec3 pf_cross(pf_vec3 a, pf_vec3 b)
{
    return pf_v3(a.y * b.z - a.z * b.y, a.z * b.x - a.x * b.z, a.x * b.y - a.y * b.x);
}
static inline float pf_len2(pf_vec3 a) { return pf_dot(a, a); }
static inline float pf_len(pf_vec3 a) { return sqrtf(pf_dot(a, a)); }
static inline pf_vec3 pf_norm(pf_vec3 a)
{
    float l = pf_len(a);
    return l > 0.0f ? pf_scale(a, 1.0f / l) : a;
}
static inline pf_vec3 pf_vabs(pf_vec3 a) { return pf_v3(fabsf(a.x), fabsf(a.y), fabsf(a.z)); }
static inline pf_vec3 pf_vmin(pf_vec3 a, pf_vec3 b) { return pf_v3(fminf(a.x, b.x), fminf(a.y, b.y), fminf(a.z, b.z)); }
static inline pf_vec3 pf_vmax(pf_vec3 a, pf_vec3 b) { return pf_v3(fmaxf(a.x, b.x), fmaxf(a.y, b.y), fmaxf(a.z, b.z)); }
static inline float pf_vget(pf_vec3 a, int axis) { return axis == 0 ? a.x : axis == 1 ? a.y : a.z; }
static inline float pf_maxc(pf_vec3 a) { return fmaxf(a.x, fmaxf(a.y, a.z)); }
static inline float pf_minc(pf_vec3 a) { return fminf(a.x, fminf(a.y, a.z)); }
static inline float pf_avgc(pf_vec3 a) { return (a.x + a.y + a.z) * (1.0f / 3.0f); }
static inline float pf_luminance(pf_vec3 a) { return 0.2126f * a.x + 0.7152f * a.y + 0.0722f * a.z; }
static inline int pf_is_black(pf_vec3 a) { return a.x == 0.0f && a.y == 0.0f && a.z == 0.0f; }
static inline int pf_is_finite3(pf_vec3 a) { return isfinite(a.x) && isfinite(a.y) && isfinite(a.z); }
/* Flips v to the hemisphere of ref. */
static inline pf_vec3 pf_face_forward(pf_vec3 v, pf_vec3 ref) { return pf_dot(v, ref) < 0.0f ? pf_neg(v) : v; }

/* An orthonormal basis around unit n (Duff et al. 2017, branchless). */
static inline void pf_basis(pf_vec3 n, pf_vec3 *t, pf_vec3 *b)
{
    float sign = copysignf(1.0f, n.z);
    float a = -1.0f / (sign + n.z);
    float c = n.x * n.y * a;
    *t = pf_v3(1.0f + sign * n.x * n.x * a, sign * c, -sign * n.x);
    *b = pf_v3(c, sign + n.y * n.y * a, -n.y);
}
/* Local (x,y,z with z along n) to world. */
static inline pf_vec3 pf_to_world(pf_vec3 local, pf_vec3 n)
{
    pf_vec3 t, b;
    pf_basis(n, &t, &b);
    return pf_add(pf_add(pf_scale(t, local.x), pf_scale(b, local.y)), pf_scale(n, local.z));
}

/* A ray: origin, unit direction. */
typedef struct pf_ray {
    pf_vec3 o, d;
} pf_ray_t;

/* An affine transform, row-major 3x4 (the last row is 0 0 0 1). */
typedef struct pf_xform {
    float m[3][4];
} pf_xform_t;

static inline pf_xform_t pf_xform_identity(void)
{
    return (pf_xform_t){ { { 1, 0, 0, 0 }, { 0, 1, 0, 0 }, { 0, 0, 1, 0 } } };
}
static inline pf_vec3 pf_xform_point(const pf_xform_t *x, pf_vec3 p)
{
    return pf_v3(x->m[0][0] * p.x + x->m[0][1] * p.y + x->m[0][2] * p.z + x->m[0][3],
                 x->m[1][0] * p.x + x->m[1][1] * p.y + x->m[1][2] * p.z + x->m[1][3],
                 x->m[2][0] * p.x + x->m[2][1] * p.y + x->m[2][2] * p.z + x->m[2][3]);
}
static inline pf_vec3 pf_xform_vector(const pf_xform_t *x, pf_vec3 v)
{
    return pf_v3(x->m[0][0] * v.x + x->m[0][1] * v.y + x->m[0][2] * v.z,
                 x->m[1][0] * v.x + x->m[1][1] * v.y + x->m[1][2] * v.z,
                 x->m[2][0] * v.x + x->m[2][1] * v.y + x->m[2][2] * v.z);
}
/* a then b: returns b * a. */
static inline pf_xform_t pf_xform_then(const pf_xform_t *a, const pf_xform_t *b)
{
    pf_xform_t r;
    for (int i = 0; i < 3; i++) {
        for (int j = 0; j < 4; j++) {
            float s = (j == 3) ? b->m[i][3] : 0.0f;
            for (int k = 0; k < 3; k++)
                s += b->m[i][k] * a->m[k][j];
            r.m[i][j] = s;
        }
    }
    return r;
}
/* Normals transform by the inverse transpose of the linear part; the cofactor
 * matrix is that up to a positive scale (for det > 0) and is renormalized. */
static inline pf_vec3 pf_xform_normal(const pf_xform_t *x, pf_vec3 n)
{
    const float(*m)[4] = x->m;
    pf_vec3 c0 = pf_cross(pf_v3(m[0][1], m[1][1], m[2][1]), pf_v3(m[0][2], m[1][2], m[2][2]));
    pf_vec3 c1 = pf_cross(pf_v3(m[0][2], m[1][2], m[2][2]), pf_v3(m[0][0], m[1][0], m[2][0]));
    pf_vec3 c2 = pf_cross(pf_v3(m[0][0], m[1][0], m[2][0]), pf_v3(m[0][1], m[1][1], m[2][1]));
    return pf_norm(pf_add(pf_add(pf_scale(c0, n.x), pf_scale(c1, n.y)), pf_scale(c2, n.z)));
}
static inline float pf_xform_det(const pf_xform_t *x)
{
    const float(*m)[4] = x->m;
    return pf_dot(pf_v3(m[0][0], m[1][0], m[2][0]),
                  pf_cross(pf_v3(m[0][1], m[1][1], m[2][1]), pf_v3(m[0][2], m[1][2], m[2][2])));
}

#endif
