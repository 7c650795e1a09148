/* lightbvh.h: private to light/. A light BVH (pbrt-v4's BVHLightSampler):
 * a binary tree over bounded emitters, each node holding pbrt's LightBounds
 * (a box, the power phi, a cone of emission normals w / theta_o, the spread
 * theta_e about those normals, two-sidedness), traversed stochastically from
 * a receiving point x with normal n: at every node a child is chosen by its
 * importance seen from (x, n) (distance, orientation, power), so that among
 * hundreds of emitters the near ones that face x are chosen most often. The
 * probability of a given item at (x, n) is computed by the same walk
 * (pf_lightbvh_pmf). Built once, read-only after; deterministic. */
#ifndef PF_LIGHTBVH_H
#define PF_LIGHTBVH_H

#include <stddef.h>
#include <stdint.h>

#include "base/vec.h"

typedef struct pf_light_bounds {
    pf_vec3 lo, hi;    /* the emitter's box */
    float phi;         /* its power (any unit, the same for all) */
    pf_vec3 w;         /* axis of the cone of emission normals */
    float cos_theta_o; /* that cone's half angle */
    float cos_theta_e; /* how far about a normal light leaves (pi/2 for a diffuse area) */
    int two_sided;
} pf_light_bounds_t;

typedef struct pf_lightbvh pf_lightbvh_t;

/* Builds the tree over n items; item i has bounds b[i] and is reported as
 * id[i]. Items of zero power are left out. NULL when out of memory or no item
 * has power. */
pf_lightbvh_t *pf_lightbvh_build(const pf_light_bounds_t *b, const uint32_t *id, size_t n);
void pf_lightbvh_destroy(pf_lightbvh_t **self_p);

/* pbrt's LightBounds::Importance of b seen from x with normal n (n zero: any
 * orientation). Exposed for the tests. */
float pf_light_importance(const pf_light_bounds_t *b, pf_vec3 x, pf_vec3 n);

/* Chooses an item for the receiver (x, n) with u in [0, 1): its id and its
 * probability in *pmf. Returns 0 when every item has importance 0 there
 * (nothing chosen). */
int pf_lightbvh_sample(const pf_lightbvh_t *self, pf_vec3 x, pf_vec3 n, float u, uint32_t *id, float *pmf);

/* The probability with which pf_lightbvh_sample at (x, n) returns the item
 * whose id is id (0 if it is not in the tree or cannot be chosen there).
 * The product is formed in the same order as the sampler's, so both agree
 * to the bit. */
float pf_lightbvh_pmf(const pf_lightbvh_t *self, pf_vec3 x, pf_vec3 n, uint32_t id);

#endif
