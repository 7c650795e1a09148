/* kd_layout.h: private to photon/. What the kd-tree's two files share:
 *
 *   kdtree.c        the build, the layout check, the tree's lifetime, and
 *                   the nearest-normal search with its grid;
 *   kdtree_query.c  the k-nearest and radius queries.
 *
 * Nothing else includes this header (tests/photon/test_kdtree.c does, through
 * its copy of kdtree.c); the public interface is kdtree.h. The names keep
 * the s_ and S_ forms they had when both were one file; the inline helpers
 * here are the ones both files' queries use. It does not include kdtree.h
 * (its includers do, first), so that the two headers form no circle. */
#ifndef PF_KDTREE_IMPL_H
#define PF_KDTREE_IMPL_H

#include <math.h>
#include <stddef.h>
#include <stdint.h>

#include "base/vec.h"
#include "photon/photon.h"

/* n < 2^31 keeps every index in a uint32_t with bit 31 free, and the tree at
 * most 31 levels deep, so traversal stacks of this size cannot overflow. */
#define S_MAX_N ((size_t)1 << 31)
#define S_STACK 64

/* pf_kdtree_index_nearest's grid (kdtree.c). */
typedef struct s_grid s_grid;

struct pf_kdtree {
    pf_photon_t *photons;
    size_t n;
    pf_vec3 lo, hi;
    s_grid *grid; /* pf_kdtree_index_nearest's grid, or NULL */
};

/* Squared distance, contraction-proof; see kdtree.c's opening comment. */
static inline float s_dist2(const float q[3], const float p[3])
{
    double dx = q[0] - p[0], dy = q[1] - p[1], dz = q[2] - p[2];
    return (float)(dx * dx + dy * dy + dz * dz);
}

typedef struct s_entry {
    uint32_t lo, hi;
    float d2; /* squared distance from the query to the range's split plane */
} s_entry_t;

/* A query nothing can satisfy: a NaN point, or a NaN or negative radius.
 * Caught up front because NaN comparisons would otherwise prune nothing. */
static inline int s_hopeless(pf_vec3 x, float r2)
{
    return isnan(x.x) || isnan(x.y) || isnan(x.z) || !(r2 >= 0.0f);
}

/* A high percentile (p in 0..1) of the distances from a sample of the
 * tree's photons to their nearest neighbours (kdtree_query.c); the grid's
 * cell size follows it. */
double pf_kdtree_spacing_percentile(const struct pf_kdtree *self, double p);

#endif
