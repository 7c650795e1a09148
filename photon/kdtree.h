/* kdtree.h: static, balanced, pointer-free kd-tree over photons, with
 * k-nearest and radius queries.
 *
 * Layout: the photons are reordered so that the node of the index range
 * [lo, hi) is its median m = lo + (hi - lo) / 2, split on axis[m]; the left
 * child is [lo, m), the right [m + 1, hi). No pointers and nothing beside the
 * photons: a node's split axis is kept in its photon record
 * (pf_photon_axis), so the tree holds 32 bytes per photon and a query reads
 * one record per node. The build is deterministic: the split axis is the widest extent
 * of the range, and equal coordinates are ordered by the photons' input index,
 * so the same input always gives the same layout, whatever the thread count.
 *
 * Queries are read-only and safe from any number of threads at once. */
#ifndef PF_KDTREE_H
#define PF_KDTREE_H

#include <stddef.h>
#include <stdint.h>

#include "base/vec.h"
#include "photon/photon.h"

typedef struct pf_kdtree pf_kdtree_t;

/* One query result: the photon's index in tree order and its squared distance. */
typedef struct pf_knn {
    uint32_t index;
    float d2;
} pf_knn_t;

/* Builds a tree over n photons, taking ownership of *photons_p (malloc'd;
 * *photons_p is set to NULL, also on failure). n may be 0. NULL when out of
 * memory or n >= 2^31. The photons keep every field but the normal's axis
 * bits (PF_PHOTON_AXIS_BITS), which the build sets. */
pf_kdtree_t *pf_kdtree_build(pf_photon_t **photons_p, size_t n);

/* Rebuilds a tree from an existing layout (photons already in tree order,
 * their split axes set), e.g. one received over the wire; takes ownership of
 * the array. Checks that every axis is 0..2, every position is finite and
 * that the layout satisfies the kd-tree ordering; NULL (array freed)
 * otherwise. */
pf_kdtree_t *pf_kdtree_from_layout(pf_photon_t **photons_p, size_t n);

/* NULL-safe; sets *self_p = NULL. */
void pf_kdtree_destroy(pf_kdtree_t **self_p);

size_t pf_kdtree_size(const pf_kdtree_t *self);
/* The photons in tree order, their split axes set. */
const pf_photon_t *pf_kdtree_photons(const pf_kdtree_t *self);
/* Bounds of all photon positions (lo > hi on an empty tree). */
void pf_kdtree_bounds(const pf_kdtree_t *self, pf_vec3 *lo, pf_vec3 *hi);

/* The k nearest photons to x within squared distance max_r2 (use INFINITY for
 * none). Writes at most k results to out sorted by (d2, index) ascending and
 * returns how many. Ties at equal distance go to the lower tree index, so the
 * result is a pure function of the tree and the query. */
size_t pf_kdtree_knn(const pf_kdtree_t *self, pf_vec3 x, size_t k, float max_r2, pf_knn_t *out);

/* The same k results unsorted: out[0] is the worst by (d2, index) (the
 * k-th nearest when k were found), the rest in no useful order. For
 * estimates that need only the set and its radius (no final sort). */
size_t pf_kdtree_knn_heap(const pf_kdtree_t *self, pf_vec3 x, size_t k, float max_r2, pf_knn_t *out);

/* pf_kdtree_knn_heap over the photons whose stored normal has a cosine >=
 * min_cos with unit n (pf_photon_normal_agrees) alone: the others are
 * neither kept nor counted, so the k found are the k nearest on the side of
 * a surface that n faces, however dense its other side. */
size_t pf_kdtree_knn_heap_normal(const pf_kdtree_t *self, pf_vec3 x, pf_vec3 n, float min_cos, size_t k, float max_r2,
                                 pf_knn_t *out);

/* The nearest photon to x within squared distance max_r2 whose stored normal
 * (pf_photon_normal) has a cosine >= min_cos with unit n; ties
 * go to the lower tree index. Returns 1 and fills *out, or 0 if none. The
 * irradiance lookup of every final-gather ray uses it. */
int pf_kdtree_nearest_normal(const pf_kdtree_t *self, pf_vec3 x, pf_vec3 n, float min_cos, float max_r2,
                             pf_knn_t *out);

/* Builds a grid beside the tree that answers pf_kdtree_nearest_normal
 * several times faster for the same result (the tree still decides the rare
 * queries the grid cannot settle). Costs 20 bytes per photon plus the cell
 * table; call once, before the tree is shared between threads. 0, or
 * PF_ENOMEM with the tree unchanged. */
int pf_kdtree_index_nearest(pf_kdtree_t *self);

/* All photons with squared distance <= r2 from x: writes up to cap of them to
 * out and returns how many there are in total (the slots of out past those
 * may be written too). Their order is fixed by the
 * tree and x alone (a walk of the tree, nearer child first, that a larger r2
 * only extends): the photons found within a smaller r2 come in the same
 * relative order, so sums over them do not depend on the radius searched. */
size_t pf_kdtree_radius(const pf_kdtree_t *self, pf_vec3 x, float r2, pf_knn_t *out, size_t cap);

/* The same, for a caller that needs the photons only when they all fit: the
 * search stops soon after more than cap are found, and then returns some
 * count above cap (not the total). */
size_t pf_kdtree_radius_upto(const pf_kdtree_t *self, pf_vec3 x, float r2, pf_knn_t *out, size_t cap);

#endif
