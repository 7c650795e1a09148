/* kdtree.c: the photon maps' static kd-tree (see kdtree.h for the layout):
 * its build, the check of a received layout and the tree's lifetime, and
 * the nearest-photon search with an agreeing normal, with the grid that
 * speeds it up. The k-nearest and radius queries are in kdtree_query.c.
 *
 * Why these together: tests/photon/test_kdtree.c compiles a second copy of
 * this file (a selection budget of one pass, a failing malloc, the public
 * names renamed) and calls that copy's build, destroy, photons,
 * nearest-normal search and grid index. Those must stay here, with all they
 * call by a public name; anything else this file defines externally would
 * be defined twice in that test.
 *
 * The tree owns one array, the photons reordered into the implicit median
 * layout, each carrying its node's split axis in its normal's spare bits
 * (photon.h); plus the bounds of all positions, and the grid once
 * pf_kdtree_index_nearest has built it.
 * It is built once, by one caller thread (the top levels of the build run as
 * OpenMP tasks), and then only read: any number of threads may query it at
 * once, and queries allocate nothing.
 *
 * Determinism. The build orders photons by the key (coordinate on the split
 * axis, input index), a total order in which no two photons are equal, so the
 * median of a range, the sets that go left and right, and therefore the whole
 * layout are a function of the input alone: not of the selection algorithm's
 * internal order, nor of which thread built which subtree. Coordinates enter
 * the key through an order-preserving map of their bits in which -0 and +0 are
 * equal (so they tie on the index, as equal coordinates should) and NaN has a
 * fixed place, so even bad input cannot make the comparison inconsistent.
 *
 * Distances. A squared distance is computed as the float differences squared
 * and summed in double, then rounded once to float (s_dist2, kd_layout.h).
 * The products are exact in double, so the value does not depend on whether
 * the compiler contracts multiply-adds into FMA, and tests can reproduce it
 * bit for bit. The rounding is monotone, so the squared distance to a split
 * plane is a true lower bound of the distance of every photon beyond it,
 * which is what pruning needs.
 *
 * Positions are expected to be finite (pf_kdtree_from_layout enforces it; the
 * photon tracer rejects NaN before storing), but the build cannot refuse them
 * (its contract has no such failure), so bad ones are contained: a photon with
 * a NaN coordinate has a NaN distance and is never found, and queries never
 * prune on a NaN split plane, so it hides no other photon. A query point or
 * radius that is NaN finds nothing. */
#include "photon/kdtree.h"

#include <math.h>
#include <stddef.h>
#include <stdlib.h>
#include <string.h>

#include "base/status.h"
#include "photon/kd_layout.h"

/* Ranges at least this large are split by a separate OpenMP task; below it a
 * task costs more than it saves. The result does not depend on it. */
#define S_TASK_MIN ((size_t)1 << 15)
/* Builds this small run on the calling thread alone. */
#define S_PARALLEL_MIN ((size_t)1 << 17)
/* The work one selection may spend, in multiples of its range's size, before
 * it falls back to heapsort (typical use is under 3). The test lowers it to
 * exercise the fallback. */
#ifndef PF_KDTREE_SELECT_BUDGET
#define PF_KDTREE_SELECT_BUDGET 8
#endif

static void s_grid_free(s_grid *g);

/* ------------------------------------------------------------------------ */
/* The build and the tree's lifetime                                        */

/* A photon as the build sees it: its coordinates already mapped to ordered
 * integer keys (s_fkey) and its input index, 16 bytes, so that the many
 * selection passes move half as much memory as whole photons and compare
 * integers. */
typedef struct s_item {
    uint32_t k[3];
    uint32_t idx;
} s_item_t;

/* Maps a float to an unsigned integer with the same order (IEEE total order on
 * the bits), after turning -0 into +0 so that the two compare equal. */
static inline uint32_t s_fkey(float f)
{
    f += 0.0f; /* -0 + +0 is +0 in round-to-nearest; not folded without -ffast-math */
    uint32_t u;
    memcpy(&u, &f, sizeof u);
    uint32_t mask = (uint32_t)((int32_t)u >> 31) | 0x80000000u;
    return u ^ mask;
}

/* The inverse of s_fkey (up to the sign of zero). */
static inline float s_fkey_inv(uint32_t u)
{
    u ^= (u & 0x80000000u) ? 0x80000000u : 0xffffffffu;
    float f;
    memcpy(&f, &u, sizeof f);
    return f;
}

/* The build order: coordinate key on the axis, then input index. */
static inline uint64_t s_key(const s_item_t *it, int axis)
{
    return ((uint64_t)it->k[axis] << 32) | it->idx;
}

static inline void s_swap(s_item_t *a, s_item_t *b)
{
    s_item_t t = *a;
    *a = *b;
    *b = t;
}

static void s_insertion_sort(s_item_t *a, size_t lo, size_t hi, int axis)
{
    for (size_t i = lo + 1; i < hi; i++) {
        s_item_t v = a[i];
        uint64_t kv = s_key(&v, axis);
        size_t j = i;
        while (j > lo && s_key(&a[j - 1], axis) > kv) {
            a[j] = a[j - 1];
            j--;
        }
        a[j] = v;
    }
}

static void s_sift_items(s_item_t *a, size_t root, size_t n, int axis)
{
    for (;;) {
        size_t child = 2 * root + 1;
        if (child >= n)
            return;
        if (child + 1 < n && s_key(&a[child + 1], axis) > s_key(&a[child], axis))
            child++;
        if (s_key(&a[root], axis) >= s_key(&a[child], axis))
            return;
        s_swap(&a[root], &a[child]);
        root = child;
    }
}

/* Heapsort of a[0, n): the fallback that bounds quickselect's worst case. */
static void s_heapsort_items(s_item_t *a, size_t n, int axis)
{
    for (size_t i = n / 2; i-- > 0;)
        s_sift_items(a, i, n, axis);
    for (size_t end = n; end-- > 1;) {
        s_swap(&a[0], &a[end]);
        s_sift_items(a, 0, end, axis);
    }
}

/* Partitions a[left, right] (inclusive) around the key of a[p]: returns the
 * pivot's final place j, with smaller keys before it and larger after (keys
 * are unique). Block partitioning (Edelkamp and Weiss, "BlockQuicksort",
 * ESA 2016): a block of S_BLOCK items at each end is scanned without
 * branches, noting the offsets of the items on the wrong side, and then as
 * many pairs as both blocks hold are swapped; so the comparisons, whose
 * outcomes are random, never steer a branch (a branchy partition mispredicts
 * about once per two items, which made it most of the build's time). The
 * remainder, under two blocks, is partitioned item by item, also without
 * branching on the comparison. */
#define S_BLOCK 64
static ptrdiff_t s_partition(s_item_t *a, ptrdiff_t left, ptrdiff_t right, ptrdiff_t p, int axis)
{
    s_swap(&a[left], &a[p]);
    const uint64_t t = s_key(&a[left], axis);
    /* a[left + 1, i) are smaller than t, a(j, right] larger; [i, j] unknown. */
    ptrdiff_t i = left + 1, j = right;
    uint8_t off_l[S_BLOCK], off_r[S_BLOCK];
    int num_l = 0, num_r = 0, start_l = 0, start_r = 0;
    while (j - i + 1 >= 2 * S_BLOCK) {
        if (num_l == 0) {
            start_l = 0;
            for (int k = 0; k < S_BLOCK; k++) {
                off_l[num_l] = (uint8_t)k;
                num_l += s_key(&a[i + k], axis) > t;
            }
        }
        if (num_r == 0) {
            start_r = 0;
            for (int k = 0; k < S_BLOCK; k++) {
                off_r[num_r] = (uint8_t)k;
                num_r += s_key(&a[j - k], axis) < t;
            }
        }
        int num = num_l < num_r ? num_l : num_r;
        for (int k = 0; k < num; k++)
            s_swap(&a[i + off_l[start_l + k]], &a[j - off_r[start_r + k]]);
        num_l -= num;
        num_r -= num;
        start_l += num;
        start_r += num;
        /* A block is done when it holds no misplaced item; one with some
         * left stays in [i, j] for the next round or the remainder. */
        if (num_l == 0)
            i += S_BLOCK;
        if (num_r == 0)
            j -= S_BLOCK;
    }
    /* The remainder (all of a small range): Lomuto's partition with an
     * unconditional swap, branch-free too. */
    ptrdiff_t store = i;
    for (ptrdiff_t k = i; k <= j; k++) {
        s_item_t v = a[k];
        ptrdiff_t less = s_key(&v, axis) < t;
        a[k] = a[store];
        a[store] = v;
        store += less;
    }
    s_swap(&a[left], &a[store - 1]);
    return store - 1;
}

/* Rearranges a[left, right] (inclusive) so that a[nth] holds the item of rank
 * nth - left by key, with smaller keys before it and larger after. This is
 * Floyd and Rivest's SELECT (CACM 1975, Algorithm 489): on large ranges it
 * first selects within a sample around nth, which leaves a pivot very close to
 * the wanted rank, so one partition discards most of the range; about 1.5 n
 * comparisons for a median where median-of-3 quickselect needs about 2.75 n.
 * The pivots change only the speed, never the result, as keys are unique. A
 * work budget bounds the worst case: past it the range is heapsorted. */
static void s_select(s_item_t *a, ptrdiff_t left, ptrdiff_t right, ptrdiff_t nth, int axis)
{
    size_t budget = PF_KDTREE_SELECT_BUDGET * (size_t)(right - left + 1);
    while (right - left > 16) {
        size_t size = (size_t)(right - left + 1);
        if (size > budget) {
            s_heapsort_items(a + left, size, axis);
            return;
        }
        budget -= size;
        if (size > 600) {
            double n = (double)size, i = (double)(nth - left + 1);
            double z = log(n), s = 0.5 * exp(2.0 * z / 3.0);
            double sd = 0.5 * sqrt(z * s * (n - s) / n) * (i < n / 2 ? -1.0 : 1.0);
            ptrdiff_t sl = (ptrdiff_t)((double)nth - i * s / n + sd);
            ptrdiff_t sr = (ptrdiff_t)((double)nth + (n - i) * s / n + sd);
            s_select(a, sl > left ? sl : left, sr < right ? sr : right, nth, axis);
        }
        ptrdiff_t j = s_partition(a, left, right, nth, axis);
        /* Now a[j] holds t, smaller keys are before it and larger after. */
        if (j <= nth)
            left = j + 1;
        if (nth <= j)
            right = j - 1;
    }
    if (right > left)
        s_insertion_sort(a, (size_t)left, (size_t)right + 1, axis);
}

/* The split axis of a range: the widest extent of its positions' bounding box,
 * the lowest axis on a tie. The box is found on the keys, whose order is the
 * coordinates' order, and converted back to floats for the extents. */
static int s_widest_axis(const s_item_t *a, size_t lo, size_t hi)
{
    uint32_t mn0 = UINT32_MAX, mn1 = UINT32_MAX, mn2 = UINT32_MAX;
    uint32_t mx0 = 0, mx1 = 0, mx2 = 0;
    for (size_t i = lo; i < hi; i++) {
        mn0 = a[i].k[0] < mn0 ? a[i].k[0] : mn0;
        mn1 = a[i].k[1] < mn1 ? a[i].k[1] : mn1;
        mn2 = a[i].k[2] < mn2 ? a[i].k[2] : mn2;
        mx0 = a[i].k[0] > mx0 ? a[i].k[0] : mx0;
        mx1 = a[i].k[1] > mx1 ? a[i].k[1] : mx1;
        mx2 = a[i].k[2] > mx2 ? a[i].k[2] : mx2;
    }
    float e[3] = { s_fkey_inv(mx0) - s_fkey_inv(mn0), s_fkey_inv(mx1) - s_fkey_inv(mn1),
                   s_fkey_inv(mx2) - s_fkey_inv(mn2) };
    int axis = 0;
    for (int k = 1; k < 3; k++) {
        if (e[k] > e[axis])
            axis = k;
    }
    return axis;
}

/* Lays out the subtree of a[lo, hi): the median by key goes to the middle,
 * then both halves recursively. Large left halves become tasks. A placed
 * median's keys are never read again, so its first key holds its split axis
 * from then on (no array of axes beside the items). */
static void s_build(s_item_t *a, size_t lo, size_t hi)
{
    while (hi > lo) {
        size_t m = lo + (hi - lo) / 2;
        int axis = s_widest_axis(a, lo, hi);
        if (hi - lo > 1)
            s_select(a, (ptrdiff_t)lo, (ptrdiff_t)hi - 1, (ptrdiff_t)m, axis);
        a[m].k[0] = (uint32_t)axis;
        if (m - lo >= S_TASK_MIN) {
            size_t llo = lo, lhi = m;
#pragma omp task default(none) firstprivate(a, llo, lhi)
            s_build(a, llo, lhi);
        } else {
            s_build(a, lo, m);
        }
        lo = m + 1;
    }
}

/* Moves photon perm[i] to slot i for all i, giving it split axis axes[i]
 * (when axes is not NULL; else the photons carry theirs already). A gather
 * into a new array issues independent loads (on all threads when parallel)
 * and writes each photon once, in order, an order of magnitude faster than
 * following the permutation's cycles in place, whose loads depend on each
 * other; the in-place way is the fallback when memory for the copy is short.
 * Returns the array now holding the photons (ph itself, or the copy with ph
 * freed). */
static pf_photon_t *s_permute(pf_photon_t *ph, uint32_t *perm, const uint8_t *axes, size_t n, int parallel)
{
    pf_photon_t *out = malloc((n ? n : 1) * sizeof *out);
    if (out) {
#pragma omp parallel for if (parallel) schedule(static) default(none) shared(out, ph, perm, axes, n)
        for (size_t i = 0; i < n; i++) {
            out[i] = ph[perm[i]];
            if (axes)
                pf_photon_set_axis(&out[i], axes[i]);
        }
        free(ph);
        return out;
    }
    if (axes) {
        for (size_t i = 0; i < n; i++)
            pf_photon_set_axis(&ph[perm[i]], axes[i]);
    }
    /* Bit 31 of perm[j] (free, as n < 2^31) marks slot j as done. */
    const uint32_t done = 0x80000000u;
    for (size_t i = 0; i < n; i++) {
        if (perm[i] & done)
            continue;
        pf_photon_t first = ph[i];
        size_t j = i;
        for (;;) {
            size_t from = perm[j];
            perm[j] |= done;
            if (from == i) {
                ph[j] = first;
                break;
            }
            ph[j] = ph[from];
            j = from;
        }
    }
    return ph;
}

/* The bounds of ph[lo, hi): per axis the first least and first greatest
 * coordinate (so -0 and +0 resolve by order, not by chance). */
static void s_bounds_range(const pf_photon_t *ph, size_t lo, size_t hi, float mn[3], float mx[3])
{
    for (int k = 0; k < 3; k++) {
        mn[k] = INFINITY;
        mx[k] = -INFINITY;
    }
    for (size_t i = lo; i < hi; i++) {
        for (int k = 0; k < 3; k++) {
            float v = ph[i].pos[k];
            mn[k] = v < mn[k] ? v : mn[k];
            mx[k] = v > mx[k] ? v : mx[k];
        }
    }
}

/* In S_BOUNDS_PARTS fixed parts (in parallel when large), combined in order
 * by the same rule, so the result is the one-pass result bit for bit. */
#define S_BOUNDS_PARTS 64
static void s_bounds(const pf_photon_t *ph, size_t n, pf_vec3 *lo, pf_vec3 *hi)
{
    float pmn[S_BOUNDS_PARTS][3], pmx[S_BOUNDS_PARTS][3];
#pragma omp parallel for if (n >= S_PARALLEL_MIN) schedule(static) default(none) shared(ph, n, pmn, pmx)
    for (int p = 0; p < S_BOUNDS_PARTS; p++)
        s_bounds_range(ph, n * (size_t)p / S_BOUNDS_PARTS, n * (size_t)(p + 1) / S_BOUNDS_PARTS, pmn[p], pmx[p]);
    float mn[3] = { INFINITY, INFINITY, INFINITY };
    float mx[3] = { -INFINITY, -INFINITY, -INFINITY };
    for (int p = 0; p < S_BOUNDS_PARTS; p++) {
        for (int k = 0; k < 3; k++) {
            mn[k] = pmn[p][k] < mn[k] ? pmn[p][k] : mn[k];
            mx[k] = pmx[p][k] > mx[k] ? pmx[p][k] : mx[k];
        }
    }
    *lo = pf_v3(mn[0], mn[1], mn[2]);
    *hi = pf_v3(mx[0], mx[1], mx[2]);
}

static pf_kdtree_t *s_make(pf_photon_t *ph, size_t n)
{
    pf_kdtree_t *self = malloc(sizeof *self);
    if (!self)
        return NULL;
    self->photons = ph;
    self->n = n;
    self->grid = NULL;
    s_bounds(ph, n, &self->lo, &self->hi);
    return self;
}

pf_kdtree_t *pf_kdtree_build(pf_photon_t **photons_p, size_t n)
{
    PF_CHECK(photons_p);
    pf_photon_t *ph = *photons_p;
    *photons_p = NULL;
    PF_CHECK(n == 0 || ph);
    s_item_t *items = NULL;
    if (n >= S_MAX_N)
        goto fail;
    items = malloc((n ? n : 1) * sizeof *items);
    if (!items)
        goto fail;
    const int parallel = n >= S_PARALLEL_MIN;
#pragma omp parallel for if (parallel) schedule(static) default(none) shared(items, ph, n)
    for (size_t i = 0; i < n; i++) {
        for (int a = 0; a < 3; a++)
            items[i].k[a] = s_fkey(ph[i].pos[a]);
        items[i].idx = (uint32_t)i;
    }
    if (parallel) {
#pragma omp parallel default(none) shared(items, n)
#pragma omp single
        s_build(items, 0, n);
        /* The implicit barrier at the end of the region waits for all tasks. */
    } else {
        s_build(items, 0, n);
    }
    /* Only the permutation and the split axes (5 of the 16 bytes per
     * photon) are kept, so that less is held during the permutation, and the
     * photons take their axes as they move: in arrays of their own, or when
     * that memory is short the permutation packed at the front of the items'
     * memory, one thread (slot i is written after items[i] was read), the
     * photons taking their axes where they are. */
    uint32_t *perm = malloc((n ? n : 1) * sizeof *perm);
    uint8_t *axes = malloc(n ? n : 1);
    if (perm && axes) {
#pragma omp parallel for if (parallel) schedule(static) default(none) shared(items, perm, axes, n)
        for (size_t i = 0; i < n; i++) {
            perm[i] = items[i].idx;
            axes[i] = (uint8_t)items[i].k[0];
        }
        free(items);
    } else {
        free(perm);
        free(axes);
        axes = NULL;
        perm = (uint32_t *)items;
        for (size_t i = 0; i < n; i++) {
            uint32_t idx = items[i].idx;
            pf_photon_set_axis(&ph[idx], items[i].k[0]);
            perm[i] = idx;
        }
        uint32_t *smaller = realloc(perm, (n ? n : 1) * sizeof *perm);
        perm = smaller ? smaller : perm;
    }
    items = NULL;
    ph = s_permute(ph, perm, axes, n, parallel);
    free(perm);
    free(axes);
    pf_kdtree_t *self = s_make(ph, n);
    if (!self)
        goto fail;
    return self;
fail:
    free(items);
    free(ph);
    return NULL;
}

/* Checks the kd ordering in O(n): every photon must lie inside the box that
 * its ancestors' split planes leave for it (left of a node: coordinate <= the
 * node's on its axis; right: >=). That is the same set of constraints as
 * checking every node against its whole subtree. */
static int s_layout_ok(const pf_photon_t *ph, size_t n)
{
    struct {
        uint32_t lo, hi;
        float bmin[3], bmax[3];
    } stack[S_STACK];
    int sp = 0;
    uint32_t lo = 0, hi = (uint32_t)n;
    float bmin[3] = { -INFINITY, -INFINITY, -INFINITY };
    float bmax[3] = { INFINITY, INFINITY, INFINITY };
    for (;;) {
        while (lo < hi) {
            uint32_t m = lo + (hi - lo) / 2;
            const float *p = ph[m].pos;
            for (int k = 0; k < 3; k++) {
                if (!(p[k] >= bmin[k] && p[k] <= bmax[k]))
                    return 0;
            }
            unsigned a = pf_photon_axis(&ph[m]);
            if (m + 1 < hi) {
                PF_CHECK(sp < S_STACK);
                stack[sp].lo = m + 1;
                stack[sp].hi = hi;
                memcpy(stack[sp].bmin, bmin, sizeof bmin);
                memcpy(stack[sp].bmax, bmax, sizeof bmax);
                stack[sp].bmin[a] = p[a];
                sp++;
            }
            bmax[a] = p[a];
            hi = m;
        }
        if (sp == 0)
            return 1;
        sp--;
        lo = stack[sp].lo;
        hi = stack[sp].hi;
        memcpy(bmin, stack[sp].bmin, sizeof bmin);
        memcpy(bmax, stack[sp].bmax, sizeof bmax);
    }
}

pf_kdtree_t *pf_kdtree_from_layout(pf_photon_t **photons_p, size_t n)
{
    PF_CHECK(photons_p);
    pf_photon_t *ph = *photons_p;
    *photons_p = NULL;
    if (n >= S_MAX_N || (n > 0 && !ph))
        goto fail;
    for (size_t i = 0; i < n; i++) {
        if (pf_photon_axis(&ph[i]) > 2)
            goto fail;
        if (!isfinite(ph[i].pos[0]) || !isfinite(ph[i].pos[1]) || !isfinite(ph[i].pos[2]))
            goto fail;
    }
    if (!s_layout_ok(ph, n))
        goto fail;
    pf_kdtree_t *self = s_make(ph, n);
    if (!self)
        goto fail;
    return self;
fail:
    free(ph);
    return NULL;
}

void pf_kdtree_destroy(pf_kdtree_t **self_p)
{
    if (!self_p || !*self_p)
        return;
    pf_kdtree_t *self = *self_p;
    s_grid_free(self->grid);
    free(self->photons);
    free(self);
    *self_p = NULL;
}

size_t pf_kdtree_size(const pf_kdtree_t *self) { return self->n; }
const pf_photon_t *pf_kdtree_photons(const pf_kdtree_t *self) { return self->photons; }

void pf_kdtree_bounds(const pf_kdtree_t *self, pf_vec3 *lo, pf_vec3 *hi)
{
    *lo = self->lo;
    *hi = self->hi;
}

/* ------------------------------------------------------------------------ */
/* The nearest photon with an agreeing normal, and its grid                 */

/* The k = 1 search without a heap, with the normal test applied to each
 * candidate that would beat the current best (the oct-normal decode is paid
 * only for those). Ties go to the lower tree index, as in pf_kdtree_knn. */
static int s_nearest_tree(const pf_kdtree_t *self, pf_vec3 x, pf_vec3 n, float min_cos, float max_r2,
                          pf_knn_t *out)
{
    const pf_photon_t *ph = self->photons;
    const float q[3] = { x.x, x.y, x.z };
    pf_knn_t best = { UINT32_MAX, max_r2 };
    int found = 0;
    s_entry_t stack[S_STACK];
    int sp = 0;
    uint32_t lo = 0, hi = (uint32_t)self->n;
    for (;;) {
        while (lo < hi) {
            uint32_t m = lo + (hi - lo) / 2;
            const float *p = ph[m].pos;
            float d2 = s_dist2(q, p);
            if ((d2 < best.d2 || (d2 == best.d2 && m < best.index)) &&
                pf_dot(pf_photon_normal(&ph[m]), n) >= min_cos) {
                best = (pf_knn_t){ m, d2 };
                found = 1;
            }
            unsigned a = pf_photon_axis(&ph[m]);
            float diff = q[a] - p[a];
            float plane_d2 = diff * diff;
            uint32_t flo, fhi;
            if (diff < 0.0f) {
                flo = m + 1;
                fhi = hi;
                hi = m;
            } else {
                flo = lo;
                fhi = m;
                lo = m + 1;
            }
            if (flo < fhi && !(plane_d2 > best.d2)) {
                PF_DCHECK(sp < S_STACK);
                stack[sp++] = (s_entry_t){ flo, fhi, plane_d2 };
            }
        }
        do {
            if (sp == 0)
                goto end;
            sp--;
        } while (stack[sp].d2 > best.d2);
        lo = stack[sp].lo;
        hi = stack[sp].hi;
    }
end:
    if (found)
        *out = best;
    return found;
}

/* The nearest-point grid (pf_kdtree_index_nearest). A uniform grid of cubic
 * cells of side h, hashed (open addressing, linear probing) from the cell's
 * packed coordinates to its run of points; the points are copied in cell
 * order, each with its normal's code and its tree index, 20 bytes (the
 * normal is decoded only for a point closer than the best so far). A query
 * scans the 2 x 2 x 2 cells around it, nearest first, which hold every point
 * closer than h / 2; only when the best agreeing point found there is not
 * that close does it fall back to the tree, so the answer is always the
 * tree's answer. */
#define S_GRID_BITS 21
#define S_GRID_MAX ((int64_t)1 << S_GRID_BITS)
#define S_GRID_EMPTY UINT64_MAX

typedef struct s_gpoint {
    float pos[3];
    uint32_t normal; /* the photon's normal code, axis bits cleared: decoded only for a closer point */
    uint32_t index;
} s_gpoint;

typedef struct s_gcell {
    uint64_t key;
    uint32_t start, count;
} s_gcell;

struct s_grid {
    double origin[3];
    double inv_h;
    float exact_d2; /* a best point closer than this is the exact answer */
    double cell_d2; /* h^2, less a margin as for exact_d2: squared distances in cells to world units */
    s_gcell *cells;
    uint64_t mask;  /* table size - 1 */
    size_t ncells;
    s_gpoint *pts;
};

static void s_grid_free(s_grid *g)
{
    if (!g)
        return;
    free(g->cells);
    free(g->pts);
    free(g);
}

static inline uint64_t s_grid_key(int64_t x, int64_t y, int64_t z)
{
    return ((uint64_t)x << (2 * S_GRID_BITS)) | ((uint64_t)y << S_GRID_BITS) | (uint64_t)z;
}

/* Every key bit must reach the low bits the mask keeps (a bare multiply
 * would leave the x coordinate, in the top bits, out): MurmurHash3's
 * finalizer. */
static inline uint64_t s_grid_slot(uint64_t key, uint64_t mask)
{
    key ^= key >> 33;
    key *= 0xff51afd7ed558ccdull;
    key ^= key >> 33;
    key *= 0xc4ceb9fe1a85ec53ull;
    key ^= key >> 33;
    return key & mask;
}

/* The cell coordinate of c on one axis, computed in double so that the
 * rounding is far below the margin exact_d2 leaves. */
static inline int64_t s_grid_coord(const s_grid *g, int axis, double c)
{
    return (int64_t)floor((c - g->origin[axis]) * g->inv_h);
}

/* Finds key's cell, or the empty slot where it belongs. */
static s_gcell *s_grid_find(s_gcell *cells, uint64_t mask, uint64_t key)
{
    uint64_t i = s_grid_slot(key, mask);
    while (cells[i].key != key && cells[i].key != S_GRID_EMPTY)
        i = (i + 1) & mask;
    return &cells[i];
}

static int s_grid_grow(s_grid *g)
{
    uint64_t size = 2 * (g->mask + 1), mask = size - 1;
    s_gcell *cells = malloc(size * sizeof *cells);
    if (!cells)
        return PF_ENOMEM;
    for (uint64_t i = 0; i < size; i++)
        cells[i].key = S_GRID_EMPTY;
    for (uint64_t i = 0; i <= g->mask; i++)
        if (g->cells[i].key != S_GRID_EMPTY)
            *s_grid_find(cells, mask, g->cells[i].key) = g->cells[i];
    free(g->cells);
    g->cells = cells;
    g->mask = mask;
    return PF_OK;
}

int pf_kdtree_index_nearest(pf_kdtree_t *self)
{
    if (!self || self->grid || self->n < 64)
        return PF_OK; /* a small tree is fast enough */
    /* The spacing of the sparse regions (photon density follows the light),
     * so that queries there are settled by the grid too. */
    double spacing = pf_kdtree_spacing_percentile(self, 0.9);
    double ext = fmax(fmax(self->hi.x - self->lo.x, self->hi.y - self->lo.y), self->hi.z - self->lo.z);
    if (!(spacing > 0.0) || !isfinite(ext))
        return PF_OK; /* coincident points: the tree is as good */
    /* Cells of three such spacings leave the nearest point within h / 2 for
     * all but a few queries (0.5 % on cornell-spheres; the tree answers those,
     * bounded by the best point the grid saw). */
    double h = fmax(3.0 * spacing, ext / (double)(S_GRID_MAX - 8));
    s_grid *g = calloc(1, sizeof *g);
    if (!g)
        return PF_ENOMEM;
    /* Two cells of margin below the points, so that queries on the bounding
     * box's faces (the walls of a room) still land inside the grid. */
    g->origin[0] = self->lo.x - 2.0 * h, g->origin[1] = self->lo.y - 2.0 * h, g->origin[2] = self->lo.z - 2.0 * h;
    g->inv_h = 1.0 / h;
    double half = 0.5 * h * (1.0 - 1e-3);
    g->exact_d2 = (float)(half * half);
    g->cell_d2 = h * h * (1.0 - 1e-3) * (1.0 - 1e-3);
    g->mask = 1023;
    g->cells = malloc((g->mask + 1) * sizeof *g->cells);
    g->pts = malloc(self->n * sizeof *g->pts);
    if (!g->cells || !g->pts)
        goto fail;
    for (uint64_t i = 0; i <= g->mask; i++)
        g->cells[i].key = S_GRID_EMPTY;
    /* Count the points per cell. */
    for (size_t i = 0; i < self->n; i++) {
        const float *p = self->photons[i].pos;
        if (!isfinite(p[0]) || !isfinite(p[1]) || !isfinite(p[2]))
            continue; /* never found by the tree either */
        uint64_t key = s_grid_key(s_grid_coord(g, 0, p[0]), s_grid_coord(g, 1, p[1]),
                                  s_grid_coord(g, 2, p[2]));
        s_gcell *c = s_grid_find(g->cells, g->mask, key);
        if (c->key == S_GRID_EMPTY) {
            if (2 * (g->ncells + 1) > g->mask + 1) {
                if (s_grid_grow(g) != PF_OK)
                    goto fail;
                c = s_grid_find(g->cells, g->mask, key);
            }
            *c = (s_gcell){ key, 0, 0 };
            g->ncells++;
        }
        c->count++;
    }
    /* Runs in table order; points in tree order within a run. */
    uint32_t start = 0;
    for (uint64_t i = 0; i <= g->mask; i++) {
        if (g->cells[i].key == S_GRID_EMPTY)
            continue;
        g->cells[i].start = start;
        start += g->cells[i].count;
        g->cells[i].count = 0;
    }
    for (size_t i = 0; i < self->n; i++) {
        const pf_photon_t *ph = &self->photons[i];
        if (!isfinite(ph->pos[0]) || !isfinite(ph->pos[1]) || !isfinite(ph->pos[2]))
            continue;
        uint64_t key = s_grid_key(s_grid_coord(g, 0, ph->pos[0]), s_grid_coord(g, 1, ph->pos[1]),
                                  s_grid_coord(g, 2, ph->pos[2]));
        s_gcell *c = s_grid_find(g->cells, g->mask, key);
        g->pts[c->start + c->count++] = (s_gpoint){ { ph->pos[0], ph->pos[1], ph->pos[2] },
                                                    ph->normal & ~PF_PHOTON_AXIS_BITS,
                                                    (uint32_t)i };
    }
    self->grid = g;
    return PF_OK;
fail:
    s_grid_free(g);
    return PF_ENOMEM;
}

/* Scans the cell of key for agreeing points better than *best (by d2, then
 * index); 1 if one was found. */
static inline int s_grid_scan(const s_grid *g, uint64_t key, const float q[3], pf_vec3 n, float min_cos,
                              pf_knn_t *best)
{
    uint64_t i = s_grid_slot(key, g->mask);
    while (g->cells[i].key != key && g->cells[i].key != S_GRID_EMPTY)
        i = (i + 1) & g->mask;
    if (g->cells[i].key == S_GRID_EMPTY)
        return 0;
    const s_gpoint *p = &g->pts[g->cells[i].start], *end = p + g->cells[i].count;
    /* The cell's nearest point (the first of equals: a run is in tree
     * order) is the answer when its normal agrees, and none when it is no
     * better than *best; only otherwise is the cell searched point by point. */
    const s_gpoint *arg = NULL;
    float m = INFINITY;
    for (const s_gpoint *r = p; r < end; r++) {
        float d2 = s_dist2(q, r->pos);
        if (d2 < m)
            m = d2, arg = r;
    }
    if (!arg || !(m < best->d2 || (m == best->d2 && arg->index < best->index)))
        return 0;
    if (pf_dot(pf_oct_decode(arg->normal), n) >= min_cos) {
        *best = (pf_knn_t){ arg->index, m };
        return 1;
    }
    int got = 0;
    for (; p < end; p++) {
        float d2 = s_dist2(q, p->pos);
        if ((d2 < best->d2 || (d2 == best->d2 && p->index < best->index)) &&
            pf_dot(pf_oct_decode(p->normal), n) >= min_cos) {
            *best = (pf_knn_t){ p->index, d2 };
            got = 1;
        }
    }
    return got;
}

/* The grid's part of pf_kdtree_nearest_normal: 1 with the exact answer in
 * *out (or none, *found = 0), 0 when the tree must decide; then *max_r2 is
 * lowered to the best squared distance seen, which bounds the tree's search. */
static int s_nearest_grid(const s_grid *g, pf_vec3 x, pf_vec3 n, float min_cos, float *max_r2, pf_knn_t *out,
                          int *found)
{
    const double c[3] = { x.x, x.y, x.z };
    int64_t b[3];
    for (int a = 0; a < 3; a++) {
        double f = (c[a] - g->origin[a]) * g->inv_h - 0.5;
        if (!(f >= 0.0 && f < (double)(S_GRID_MAX - 2)))
            return 0;
        b[a] = (int64_t)f;
    }
    const float q[3] = { x.x, x.y, x.z };
    pf_knn_t best = { UINT32_MAX, *max_r2 };
    int got = 0;
    /* The block's cells are read nearest first (the query's own cell, at 0,
     * then across the nearest face, ...): once the best agreeing point found
     * is closer than the next cell, no point there or in the cells after it
     * can match it (margin as for exact_d2) and they are not read. Per axis:
     * the query's side of the block (its own cell) and its squared distance
     * to the block's middle face, in cells; a cell's distance sums those of
     * the axes it lies across. */
    int own = 0;
    double da2[3];
    for (int a = 0; a < 3; a++) {
        double fr = (c[a] - g->origin[a]) * g->inv_h - (double)b[a]; /* in [0.5, 1.5) */
        own |= (fr >= 1.0) << a;
        da2[a] = (fr - 1.0) * (fr - 1.0);
    }
    /* The axes by that distance, s0 <= s1 <= s2: the cells across none,
     * one, two or all three of them come nearest first in the order 0, s0,
     * s1, then s2 and s0 + s1 (whichever is smaller first), s0 + s2,
     * s1 + s2, s0 + s1 + s2. */
    int ax[3] = { 0, 1, 2 };
    if (da2[ax[1]] < da2[ax[0]])
        ax[0] = 1, ax[1] = 0;
    if (da2[ax[2]] < da2[ax[1]]) {
        int t = ax[1];
        ax[1] = ax[2], ax[2] = t;
        if (da2[ax[1]] < da2[ax[0]])
            t = ax[0], ax[0] = ax[1], ax[1] = t;
    }
    const int m0 = 1 << ax[0], m1 = 1 << ax[1], m2 = 1 << ax[2];
    const double s0 = da2[ax[0]], s1 = da2[ax[1]], s2 = da2[ax[2]];
    const int two_first = s0 + s1 < s2;
    const int across[8] = { 0, m0, m1, two_first ? m0 | m1 : m2, two_first ? m2 : m0 | m1, m0 | m2, m1 | m2, 7 };
    const double dist[8] = { 0.0, s0, s1, two_first ? s0 + s1 : s2, two_first ? s2 : s0 + s1, s0 + s2, s1 + s2,
                             s0 + s1 + s2 };
    for (int j = 0; j < 8; j++) {
        if (got && best.d2 < (float)(dist[j] * g->cell_d2))
            break;
        int d = own ^ across[j];
        uint64_t key = s_grid_key(b[0] + (d & 1), b[1] + ((d >> 1) & 1), b[2] + (d >> 2));
        got |= s_grid_scan(g, key, q, n, min_cos, &best);
    }
    if (got ? best.d2 < g->exact_d2 : *max_r2 < g->exact_d2) {
        *found = got;
        if (got)
            *out = best;
        return 1;
    }
    /* The tree accepts a point at exactly *max_r2 with any index, so the best
     * seen here (or a tie with a lower index) is still found. */
    *max_r2 = best.d2;
    return 0;
}

int pf_kdtree_nearest_normal(const pf_kdtree_t *self, pf_vec3 x, pf_vec3 n, float min_cos, float max_r2,
                             pf_knn_t *out)
{
    if (!self || self->n == 0 || s_hopeless(x, max_r2))
        return 0;
    int found;
    if (self->grid && s_nearest_grid(self->grid, x, n, min_cos, &max_r2, out, &found))
        return found;
    return s_nearest_tree(self, x, n, min_cos, max_r2, out);
}
