/* envmap.c: the environment image's mappings and lookups; see envmap.h.
 *
 * The equal-area square follows Clarberg's construction as pbrt-v4 writes
 * it: the square's centre is +z; the distance r from the square's diagonal
 * ring (|u| + |v| = 1 in [-1, 1]^2) gives z = +-(1 - r^2), so equal areas of
 * the square hold equal solid angles, and the position along the ring gives
 * the azimuth. A point past the square's edge folds back into it by the
 * octahedron's symmetry (the wrap pbrt-v4 calls OctahedralSphere). */
#include "scene/envmap.h"

#include <math.h>
#include <string.h>

#include "base/status.h"

pf_vec3 pf_equal_area_square_to_sphere(float u, float v)
{
    float a = 2.0f * u - 1.0f, b = 2.0f * v - 1.0f;
    float ap = fabsf(a), bp = fabsf(b);
    float sd = 1.0f - (ap + bp); /* signed distance from the diagonal ring */
    float r = 1.0f - fabsf(sd);
    float phi = (r == 0.0f ? 1.0f : (bp - ap) / r + 1.0f) * (PF_PI / 4.0f);
    float z = copysignf(1.0f - r * r, sd);
    float cphi = copysignf(cosf(phi), a), sphi = copysignf(sinf(phi), b);
    float s = r * sqrtf(fmaxf(0.0f, 2.0f - r * r));
    return pf_v3(cphi * s, sphi * s, z);
}

void pf_equal_area_sphere_to_square(pf_vec3 d, float *u, float *v)
{
    float x = fabsf(d.x), y = fabsf(d.y), z = fabsf(d.z);
    float r = sqrtf(fmaxf(0.0f, 1.0f - z));
    float a = fmaxf(x, y), b = fminf(x, y);
    b = a == 0.0f ? 0.0f : b / a;
    float phi = atanf(b) * (2.0f / PF_PI);
    if (x < y)
        phi = 1.0f - phi;
    float vv = phi * r, uu = r - vv;
    if (d.z < 0.0f) { /* the lower hemisphere: the square's corners */
        float t = uu;
        uu = 1.0f - vv;
        vv = 1.0f - t;
    }
    uu = copysignf(uu, d.x);
    vv = copysignf(vv, d.y);
    *u = 0.5f * (uu + 1.0f);
    *v = 0.5f * (vv + 1.0f);
}

int pf_envmap_set_frame(pf_envmap_t *m, const double a[9])
{
    double inv[9];
    inv[0] = a[4] * a[8] - a[5] * a[7];
    inv[1] = a[2] * a[7] - a[1] * a[8];
    inv[2] = a[1] * a[5] - a[2] * a[4];
    inv[3] = a[5] * a[6] - a[3] * a[8];
    inv[4] = a[0] * a[8] - a[2] * a[6];
    inv[5] = a[2] * a[3] - a[0] * a[5];
    inv[6] = a[3] * a[7] - a[4] * a[6];
    inv[7] = a[1] * a[6] - a[0] * a[7];
    inv[8] = a[0] * a[4] - a[1] * a[3];
    double det = a[0] * inv[0] + a[1] * inv[3] + a[2] * inv[6];
    if (!(fabs(det) > 1e-30) || !isfinite(det))
        return PF_EINVAL;
    for (int i = 0; i < 9; i++) {
        m->to_world[i] = (float)a[i];
        m->to_light[i] = (float)(inv[i] / det);
        if (!isfinite(m->to_world[i]) || !isfinite(m->to_light[i]))
            return PF_EINVAL;
    }
    return PF_OK;
}

static pf_vec3 s_apply(const float *a, pf_vec3 v)
{
    return pf_v3(a[0] * v.x + a[1] * v.y + a[2] * v.z, a[3] * v.x + a[4] * v.y + a[5] * v.z,
                 a[6] * v.x + a[7] * v.y + a[8] * v.z);
}

/* pbrt-v4's octahedral wrap of a pixel index past the square's edge. */
static void s_wrap_octahedral(int w, int h, int *x, int *y)
{
    if (*x < 0) {
        *x = -*x;
        *y = h - 1 - *y;
    } else if (*x >= w) {
        *x = 2 * w - 1 - *x;
        *y = h - 1 - *y;
    }
    if (*y < 0) {
        *x = w - 1 - *x;
        *y = -*y;
    } else if (*y >= h) {
        *x = w - 1 - *x;
        *y = 2 * h - 1 - *y;
    }
    /* a clamp for what one fold cannot bring back (NaN input, 1-pixel maps) */
    *x = *x < 0 ? 0 : *x >= w ? w - 1 : *x;
    *y = *y < 0 ? 0 : *y >= h ? h - 1 : *y;
}

void pf_envmap_pixel(const pf_envmap_t *m, pf_vec3 d, int *x, int *y)
{
    pf_vec3 l = s_apply(m->to_light, d);
    float len = pf_len(l);
    l = len > 0.0f ? pf_scale(l, 1.0f / len) : pf_v3(0, 0, 1);
    if (m->mapping == PF_ENVMAP_EQUALAREA) {
        float u, v;
        pf_equal_area_sphere_to_square(l, &u, &v);
        float fx = floorf(u * (float)m->width), fy = floorf(v * (float)m->height);
        *x = isfinite(fx) ? (int)fx : 0;
        *y = isfinite(fy) ? (int)fy : 0;
        s_wrap_octahedral(m->width, m->height, x, y);
        return;
    }
    float phi = atan2f(l.y, l.x);
    if (phi < 0.0f)
        phi += 2.0f * PF_PI;
    float theta = acosf(fminf(1.0f, fmaxf(-1.0f, l.z)));
    float fx = floorf(phi * (1.0f / (2.0f * PF_PI)) * (float)m->width);
    float fy = floorf(theta * PF_INV_PI * (float)m->height);
    int xi = isfinite(fx) ? (int)fx : 0, yi = isfinite(fy) ? (int)fy : 0;
    *x = xi < 0 ? 0 : xi >= m->width ? xi % m->width : xi; /* phi = 2 pi wraps to column 0 */
    *y = yi < 0 ? 0 : yi >= m->height ? m->height - 1 : yi;
}

pf_vec3 pf_envmap_lookup(const pf_envmap_t *m, pf_vec3 d)
{
    int x, y;
    pf_envmap_pixel(m, d, &x, &y);
    const float *p = &m->rgb[3 * ((size_t)y * (size_t)m->width + (size_t)x)];
    return pf_v3(p[0], p[1], p[2]);
}

double pf_envmap_pixel_solid_angle(const pf_envmap_t *m, int y)
{
    if (m->mapping == PF_ENVMAP_EQUALAREA)
        return 4.0 * PF_PI / ((double)m->width * (double)m->height);
    double t0 = PF_PI * y / m->height, t1 = PF_PI * (y + 1) / m->height;
    return 2.0 * PF_PI / m->width * (cos(t0) - cos(t1));
}

pf_vec3 pf_envmap_pixel_dir(const pf_envmap_t *m, int x, int y, float fx, float fy)
{
    pf_vec3 l;
    if (m->mapping == PF_ENVMAP_EQUALAREA) {
        l = pf_equal_area_square_to_sphere(((float)x + fx) / (float)m->width, ((float)y + fy) / (float)m->height);
    } else { /* uniform in phi and in cos theta: uniform in solid angle */
        float phi = 2.0f * PF_PI * ((float)x + fx) / (float)m->width;
        float c0 = cosf(PF_PI * (float)y / (float)m->height), c1 = cosf(PF_PI * (float)(y + 1) / (float)m->height);
        float ct = c0 + (c1 - c0) * fy, st = sqrtf(fmaxf(0.0f, 1.0f - ct * ct));
        l = pf_v3(st * cosf(phi), st * sinf(phi), ct);
    }
    return pf_norm(s_apply(m->to_world, l));
}

double pf_envmap_integral(const pf_envmap_t *m, pf_vec3 w, int up)
{
    double sum = 0.0;
    for (int y = 0; y < m->height; y++) {
        double row = 0.0, omega = pf_envmap_pixel_solid_angle(m, y);
        for (int x = 0; x < m->width; x++) {
            double z = 1.0;
            if (up) {
                if (m->mapping == PF_ENVMAP_EQUALAREA)
                    z = pf_equal_area_square_to_sphere((x + 0.5f) / (float)m->width, (y + 0.5f) / (float)m->height).z;
                else
                    z = cos(PF_PI * (y + 0.5) / m->height);
                if (!(z > 0.0))
                    continue;
            }
            const float *p = &m->rgb[3 * ((size_t)y * (size_t)m->width + (size_t)x)];
            row += z * pf_luminance(pf_v3(w.x * p[0], w.y * p[1], w.z * p[2]));
        }
        sum += row * omega;
    }
    return sum;
}

size_t pf_envmap_bytes(const pf_envmap_t *m) { return (size_t)m->width * (size_t)m->height * 3 * sizeof(float); }
