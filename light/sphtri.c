/* sphtri.c: spherical triangles (see sphtri.h). The sampler is Arvo's:
 * the sub-triangle (a, b, c') whose area is u0 times the whole fixes c' on
 * the arc from a to c, then the direction is uniform in solid angle along
 * the arc from b to c' (its cosine linear in u1). Computed in double: the
 * angles at the vertices come from the planes through pairs of vertex
 * directions, whose normals lose precision as the triangle shrinks. */
#include "light/sphtri.h"

#include <math.h>

typedef struct s_d3 {
    double x, y, z;
} s_d3;

static s_d3 s_dir(pf_vec3 p, pf_vec3 x)
{
    return (s_d3){ (double)p.x - (double)x.x, (double)p.y - (double)x.y, (double)p.z - (double)x.z };
}
static double s_dot(s_d3 a, s_d3 b) { return a.x * b.x + a.y * b.y + a.z * b.z; }
static s_d3 s_cross(s_d3 a, s_d3 b)
{
    return (s_d3){ a.y * b.z - a.z * b.y, a.z * b.x - a.x * b.z, a.x * b.y - a.y * b.x };
}
static s_d3 s_add(s_d3 a, s_d3 b) { return (s_d3){ a.x + b.x, a.y + b.y, a.z + b.z }; }
static s_d3 s_scale(s_d3 a, double s) { return (s_d3){ a.x * s, a.y * s, a.z * s }; }
static double s_len(s_d3 a) { return sqrt(s_dot(a, a)); }

/* a / |a|, or 0 (and *ok cleared) for a zero vector. */
static s_d3 s_unit(s_d3 a, int *ok)
{
    double l = s_len(a);
    if (!(l > 0.0) || !isfinite(l)) {
        *ok = 0;
        return a;
    }
    return s_scale(a, 1.0 / l);
}

/* The angle between unit vectors, accurate near 0 and pi (pbrt's AngleBetween). */
static double s_angle(s_d3 a, s_d3 b)
{
    if (s_dot(a, b) < 0.0)
        return M_PI - 2.0 * asin(fmin(1.0, s_len(s_add(a, b)) / 2.0));
    return 2.0 * asin(fmin(1.0, s_len(s_add(b, s_scale(a, -1.0))) / 2.0));
}

/* v less its component along unit w, made unit. */
static s_d3 s_ortho(s_d3 v, s_d3 w, int *ok) { return s_unit(s_add(v, s_scale(w, -s_dot(v, w))), ok); }

double pf_sphtri_solid_angle(pf_vec3 x, pf_vec3 p0, pf_vec3 p1, pf_vec3 p2)
{
    int ok = 1;
    s_d3 a = s_unit(s_dir(p0, x), &ok), b = s_unit(s_dir(p1, x), &ok), c = s_unit(s_dir(p2, x), &ok);
    if (!ok)
        return 0.0;
    double num = fabs(s_dot(a, s_cross(b, c))), den = 1.0 + s_dot(a, b) + s_dot(b, c) + s_dot(c, a);
    double omega = 2.0 * atan2(num, den);
    return isfinite(omega) && omega > 0.0 ? omega : 0.0;
}

int pf_sphtri_sample(pf_vec3 x, pf_vec3 p0, pf_vec3 p1, pf_vec3 p2, float u0, float u1, pf_vec3 *w)
{
    int ok = 1;
    s_d3 a = s_unit(s_dir(p0, x), &ok), b = s_unit(s_dir(p1, x), &ok), c = s_unit(s_dir(p2, x), &ok);
    s_d3 nab = s_unit(s_cross(a, b), &ok), nbc = s_unit(s_cross(b, c), &ok), nca = s_unit(s_cross(c, a), &ok);
    if (!ok)
        return 0;
    /* the triangle's angles at a, b, c; their sum less pi is its area */
    double alpha = s_angle(nab, s_scale(nca, -1.0)), beta = s_angle(nbc, s_scale(nab, -1.0));
    double gamma = s_angle(nca, s_scale(nbc, -1.0));
    double area_pi = alpha + beta + gamma;
    if (!(area_pi > M_PI))
        return 0;
    /* the sub-triangle (a, b, c') of area u0 times the whole, plus pi */
    double ap_pi = M_PI + (double)u0 * (area_pi - M_PI);
    double ca = cos(alpha), sa = sin(alpha);
    double sin_phi = sin(ap_pi) * ca - cos(ap_pi) * sa, cos_phi = cos(ap_pi) * ca + sin(ap_pi) * sa;
    double k1 = cos_phi + ca, k2 = sin_phi - sa * s_dot(a, b);
    double den = (k2 * sin_phi + k1 * cos_phi) * sa;
    double cos_bp = den != 0.0 ? (k2 + (k2 * cos_phi - k1 * sin_phi) * ca) / den : 1.0;
    cos_bp = fmin(1.0, fmax(-1.0, cos_bp));
    double sin_bp = sqrt(fmax(0.0, 1.0 - cos_bp * cos_bp));
    s_d3 cp = s_add(s_scale(a, cos_bp), s_scale(s_ortho(c, a, &ok), sin_bp));
    /* along the arc from b to c', uniform in solid angle */
    double cos_t = 1.0 - (double)u1 * (1.0 - s_dot(cp, b));
    double sin_t = sqrt(fmax(0.0, 1.0 - cos_t * cos_t));
    s_d3 d = s_add(s_scale(b, cos_t), s_scale(s_ortho(cp, b, &ok), sin_t));
    d = s_unit(d, &ok);
    if (!ok)
        return 0;
    *w = pf_v3((float)d.x, (float)d.y, (float)d.z);
    return 1;
}
