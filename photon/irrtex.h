/* irrtex.h: the final gather's irradiance lookups stored with the surface.
 *
 * Every triangle is cut into R x R congruent sub-triangles (texels), each
 * side of it apart, with edges no longer than a fraction of the irradiance
 * points' median support radius. A texel holds the answer the direct lookup
 * (pf_irradiance_lookup: the nearest point with an agreeing normal, within
 * its support, visible from the lookup) gives at the texel's centre, computed
 * the first time a gather ray lands in it. A gather hit then reads one texel
 * (8 bytes) instead of searching the irradiance points and tracing the leak
 * test's ray.
 *
 * The answer for a hit is its texel centre's: a displacement within the
 * texel (at most two thirds of its longest median). The centre is the
 * texel's centroid, so over the hits that land in a texel a linearly varying
 * irradiance averages to the same value. Where that could be wrong, the
 * texel sends its hits to the direct lookup: when any other surface comes
 * within the texel's reach (pf_accel_only_plane), a wall standing on it or a
 * corner, which could put the centre and a hit on different sides of
 * something. Spheres have no texels.
 *
 * Texels are filled on demand from any number of threads at once: a texel's
 * value depends on the texel alone (the maps, the scene, its centre), never
 * on which thread fills it or when, so images stay reproducible. Triangles
 * too large for their texels' count (more than PF_IRRTEX_MAX_RES along an
 * edge) have none and are looked up directly. */
#ifndef PF_IRRTEX_H
#define PF_IRRTEX_H

#include <stddef.h>
#include <stdint.h>

#include "accel/accel.h"
#include "photon/kdtree.h"
#include "scene/scene.h"

typedef struct pf_irrtex pf_irrtex_t;

/* Texel side as a fraction of the irradiance points' median support radius. */
#define PF_IRRTEX_SIDE 0.5f
/* Most texels along a triangle's edge. */
#define PF_IRRTEX_MAX_RES 1024
/* Most texels in all (8 bytes each, touched only when filled); the texel
 * side grows until the scene fits. */
#define PF_IRRTEX_MAX_TEXELS ((size_t)1 << 24)

/* Texels over the scene's surfaces for the irradiance points of irr (squared
 * lookup reach irr_r2), whose fills read irr and trace through accel. All
 * three must outlive the result. NULL when irr is empty, on out of memory, or
 * when the scene cannot fit PF_IRRTEX_MAX_TEXELS. */
pf_irrtex_t *pf_irrtex_create(const pf_scene_t *scene, const pf_accel_t *accel, const pf_kdtree_t *irr, float irr_r2);
void pf_irrtex_destroy(pf_irrtex_t **self_p); /* NULL-safe; sets *self_p = NULL */

/* The irradiance for a gather hit h seen from the side of its face normal nf
 * (pf_face_forward of h->ng towards the viewer): its texel's value, filled
 * now if it is not yet. 1 and *e filled; 0 when h's primitive has no texels
 * or its texel sends hits to the direct lookup (then look up directly).
 * Safe from any number of threads. */
int pf_irrtex_lookup(pf_irrtex_t *self, const pf_hit_t *h, pf_vec3 nf, pf_vec3 *e);

/* pf_irrtex_lookup in two steps, for hiding the texel's trip from memory
 * (gather rays land anywhere; their texels are seldom in cache): find names
 * the texel h falls in and asks for its cache line (PF_IRRTEX_NONE when h's
 * primitive has none); read, some work later, is pf_irrtex_lookup for that
 * texel, with the same h and nf. */
#define PF_IRRTEX_NONE SIZE_MAX
size_t pf_irrtex_find(const pf_irrtex_t *self, const pf_hit_t *h, pf_vec3 nf);
int pf_irrtex_read(pf_irrtex_t *self, size_t texel, const pf_hit_t *h, pf_vec3 nf, pf_vec3 *e);

/* The centre and side normal of the texel a hit falls in (what its value is
 * looked up at), and whether it sends its hits to the direct lookup; 0 when
 * h's primitive has no texels. */
int pf_irrtex_centre(const pf_irrtex_t *self, const pf_hit_t *h, pf_vec3 nf, pf_vec3 *c, pf_vec3 *n, int *direct);

/* What a texel keeps of an irradiance: each channel (negative or NaN as 0)
 * rounded to 12 mantissa bits, a relative error of at most 2^-13. */
pf_vec3 pf_irrtex_quantize(pf_vec3 e);

/* The texel side in world units, the texels allocated, and the fills so far
 * (of which *direct, unless NULL, sent their hits to the direct lookup); a
 * texel two threads filled at once counts twice. */
float pf_irrtex_side(const pf_irrtex_t *self);
size_t pf_irrtex_count(const pf_irrtex_t *self);
size_t pf_irrtex_filled(const pf_irrtex_t *self, size_t *direct);

/* A triangle's texel at barycentrics (b1, b2) (p = b0 p0 + b1 p1 + b2 p2)
 * for R texels along each edge: its index in [0, R^2) and its centroid's
 * barycentrics. Row i = floor(b1 R) holds R - i texels pointing up (i, j) and
 * R - i - 1 pointing down, interleaved; rows before it hold i (2R - i). */
static inline uint32_t pf_irrtex_tri_texel(uint32_t res, float b1, float b2, float *c1, float *c2)
{
    float fu = b1 * (float)res, fv = b2 * (float)res;
    int r = (int)res;
    int i = fu > 0.0f ? (int)fu : 0;
    i = i < r - 1 ? i : r - 1;
    int j = fv > 0.0f ? (int)fv : 0;
    j = j < r - 1 - i ? j : r - 1 - i;
    int down = i + j < r - 1 && (fu - (float)i) + (fv - (float)j) > 1.0f;
    float o = down ? 2.0f / 3.0f : 1.0f / 3.0f;
    *c1 = ((float)i + o) / (float)res;
    *c2 = ((float)j + o) / (float)res;
    return (uint32_t)(i * (2 * r - i) + 2 * j + down);
}

#endif
