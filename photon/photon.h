/* photon.h: the compact photon record stored in photon maps and sent to
 * workers, with octahedral unit-vector encoding (Cigolle et al. 2014).
 * The same record holds a precomputed-irradiance point: power then carries
 * irradiance (W/m^2) and dir the support radius (see photonmap.h).
 * 32 bytes, no padding: the kd-tree's split axis rides in the normal's two
 * lowest code bits (bit 0 of each 16-bit half), which leaves the normal 15+15
 * bits, ample for the agreement tests it serves (worst-case angular error
 * about 1e-4 rad). The direction is coded in 12+12 bits (worst-case error
 * about 5e-4 rad; only the glossy estimate reads it) and its top 8 bits
 * hold the photon's bounce count, so that a render with a path-length limit
 * (pbrt's maxdepth) can leave out photons whose path is too long. */
#ifndef PF_PHOTON_H
#define PF_PHOTON_H

#include <math.h>
#include <stdint.h>

#include "base/vec.h"

typedef struct pf_photon {
    float pos[3];
    float power[3];   /* flux, W per channel (or irradiance, see above) */
    uint32_t dir;     /* direction the photon travelled, octahedral 12+12 bits (pf_photon_dir),
                       * and its bounce count in bits 24..31 (pf_photon_bounce) */
    uint32_t normal;  /* surface normal on the side the photon arrived from (octahedral,
                       * bits 0 and 16 excluded) and the kd-tree split axis (bits 0 | 16 << 1) */
} pf_photon_t;

/* The normal's code bits that carry the split axis instead. */
#define PF_PHOTON_AXIS_BITS 0x00010001u

_Static_assert(sizeof(pf_photon_t) == 32, "pf_photon_t must stay 32 bytes");

static inline pf_vec3 pf_photon_pos(const pf_photon_t *p) { return pf_v3(p->pos[0], p->pos[1], p->pos[2]); }
static inline pf_vec3 pf_photon_power(const pf_photon_t *p) { return pf_v3(p->power[0], p->power[1], p->power[2]); }

static inline float pf_oct_sign(float v) { return v >= 0.0f ? 1.0f : -1.0f; }

/* Unit vector to 16+16 bit octahedral code. Worst-case angular error ~3e-5 rad. */
static inline uint32_t pf_oct_encode(pf_vec3 v)
{
    float l1 = fabsf(v.x) + fabsf(v.y) + fabsf(v.z);
    if (!(l1 > 0.0f))
        return 0x7fff7fffu;
    float x = v.x / l1, y = v.y / l1;
    if (v.z < 0.0f) {
        float tx = (1.0f - fabsf(y)) * pf_oct_sign(x);
        float ty = (1.0f - fabsf(x)) * pf_oct_sign(y);
        x = tx;
        y = ty;
    }
    uint32_t ux = (uint32_t)lrintf((fminf(fmaxf(x, -1.0f), 1.0f) * 0.5f + 0.5f) * 65535.0f);
    uint32_t uy = (uint32_t)lrintf((fminf(fmaxf(y, -1.0f), 1.0f) * 0.5f + 0.5f) * 65535.0f);
    return ux | (uy << 16);
}

/* The octahedral code's point on the unit octahedron (|x| + |y| + |z| = 1):
 * the direction, not yet of unit length. */
static inline pf_vec3 pf_oct_decode_raw(uint32_t code)
{
    float x = (float)(code & 0xffffu) / 65535.0f * 2.0f - 1.0f;
    float y = (float)(code >> 16) / 65535.0f * 2.0f - 1.0f;
    float z = 1.0f - fabsf(x) - fabsf(y);
    if (z < 0.0f) {
        float tx = (1.0f - fabsf(y)) * pf_oct_sign(x);
        float ty = (1.0f - fabsf(x)) * pf_oct_sign(y);
        x = tx;
        y = ty;
    }
    return pf_v3(x, y, z);
}

static inline pf_vec3 pf_oct_decode(uint32_t code) { return pf_norm(pf_oct_decode_raw(code)); }

/* The most bounces a photon's count holds: it saturates there. */
#define PF_PHOTON_BOUNCE_MAX 255u

/* A photon's dir field: unit vector v (the direction it travelled) as a
 * 12+12 bit octahedral code, and bounce, the scattering events (specular
 * ones included) the photon made before it landed here (0: straight from
 * the light), saturated at PF_PHOTON_BOUNCE_MAX. */
static inline uint32_t pf_photon_dir_code(pf_vec3 v, int bounce)
{
    uint32_t c = pf_oct_encode(v);
    /* 16 to 12 bits by rounding: 65535 / 4095 = 16.0037. */
    uint32_t ux = ((c & 0xffffu) * 4095u + 32767u) / 65535u, uy = ((c >> 16) * 4095u + 32767u) / 65535u;
    uint32_t b = bounce < 0 ? 0u : (uint32_t)bounce > PF_PHOTON_BOUNCE_MAX ? PF_PHOTON_BOUNCE_MAX : (uint32_t)bounce;
    return ux | (uy << 12) | (b << 24);
}

/* The direction the photon travelled (unit). */
static inline pf_vec3 pf_photon_dir(const pf_photon_t *p)
{
    uint32_t ux = p->dir & 0xfffu, uy = (p->dir >> 12) & 0xfffu;
    float x = (float)ux / 4095.0f * 2.0f - 1.0f, y = (float)uy / 4095.0f * 2.0f - 1.0f;
    float z = 1.0f - fabsf(x) - fabsf(y);
    if (z < 0.0f) {
        float tx = (1.0f - fabsf(y)) * pf_oct_sign(x);
        float ty = (1.0f - fabsf(x)) * pf_oct_sign(y);
        x = tx;
        y = ty;
    }
    return pf_norm(pf_v3(x, y, z));
}

/* The photon's bounce count (see pf_photon_dir_code). */
static inline unsigned pf_photon_bounce(const pf_photon_t *p) { return p->dir >> 24; }

/* The photon's surface normal (unit). */
static inline pf_vec3 pf_photon_normal(const pf_photon_t *p)
{
    return pf_oct_decode(p->normal & ~PF_PHOTON_AXIS_BITS);
}

/* Whether the photon's normal has a cosine of at least min_cos (> 0) with
 * unit n, without normalizing it: dot >= min_cos |v| as dot^2 >= min_cos^2
 * |v|^2 (the estimates test every photon they sum). */
static inline int pf_photon_normal_agrees(const pf_photon_t *p, pf_vec3 n, float min_cos)
{
    pf_vec3 v = pf_oct_decode_raw(p->normal & ~PF_PHOTON_AXIS_BITS);
    float d = pf_dot(v, n);
    return d > 0.0f && d * d >= min_cos * min_cos * pf_dot(v, v);
}

/* The kd-tree split axis kept with the photon: 0, 1 or 2 in a tree (3 is
 * never written; a layout that holds it is refused). */
static inline unsigned pf_photon_axis(const pf_photon_t *p)
{
    return (p->normal & 1u) | ((p->normal >> 15) & 2u);
}

static inline void pf_photon_set_axis(pf_photon_t *p, unsigned axis)
{
    p->normal = (p->normal & ~PF_PHOTON_AXIS_BITS) | (axis & 1u) | ((axis & 2u) << 15);
}

#endif
