/* kdtree_query.c: the kd-tree's k-nearest and radius queries (kdtree.c
 * builds the tree and holds the nearest-normal search; its opening comment
 * gives the distance and NaN conventions these follow). Read-only: any
 * number of threads may run them on one tree at once, and they allocate
 * nothing. */
#include "photon/kdtree.h"

#include <math.h>
#include <stddef.h>
#include <stdlib.h>

#include "base/status.h"
#include "photon/kd_layout.h"

/* A radius search scans a subtree of at most this many photons in index
 * order instead of walking it: no plane tests or stack, and the photons are
 * contiguous (irradiance precomputation 2.9 -> 2.1 s at 10M photons). */
#define S_LEAF 8

/* The results heap is a max-heap on (d2, index): its root is the worst of the
 * k kept so far, the one a better candidate replaces. */
static inline int s_worse(const pf_knn_t *a, const pf_knn_t *b)
{
    return a->d2 > b->d2 || (a->d2 == b->d2 && a->index > b->index);
}

static void s_sift_down(pf_knn_t *h, size_t root, size_t n)
{
    pf_knn_t v = h[root];
    for (;;) {
        size_t child = 2 * root + 1;
        if (child >= n)
            break;
        if (child + 1 < n && s_worse(&h[child + 1], &h[child]))
            child++;
        if (!s_worse(&h[child], &v))
            break;
        h[root] = h[child];
        root = child;
    }
    h[root] = v;
}

static void s_sift_up(pf_knn_t *h, size_t i)
{
    pf_knn_t v = h[i];
    while (i > 0) {
        size_t parent = (i - 1) / 2;
        if (!s_worse(&v, &h[parent]))
            break;
        h[i] = h[parent];
        i = parent;
    }
    h[i] = v;
}

/* The heap lives in out itself, so k has no limit and nothing is allocated.
 * A subtree is skipped only when its plane is strictly farther than the
 * current bound (a photon exactly at the bound may still win on index), and
 * never when that distance is NaN. */
static size_t s_knn_heap(const pf_kdtree_t *self, pf_vec3 x, const pf_vec3 *n, float min_cos, size_t k, float max_r2,
                         pf_knn_t *out)
{
    if (!self || self->n == 0 || k == 0 || s_hopeless(x, max_r2))
        return 0;
    const pf_photon_t *ph = self->photons;
    const float q[3] = { x.x, x.y, x.z };
    size_t count = 0;
    float bound = max_r2; /* max_r2 until k are held, then the worst held d2 */
    s_entry_t stack[S_STACK];
    int sp = 0;
    uint32_t lo = 0, hi = (uint32_t)self->n;
    for (;;) {
        while (lo < hi) {
            uint32_t m = lo + (hi - lo) / 2;
            const float *p = ph[m].pos;
            float d2 = s_dist2(q, p);
            if (d2 <= bound && (!n || pf_photon_normal_agrees(&ph[m], *n, min_cos))) {
                pf_knn_t c = { m, d2 };
                if (count < k) {
                    out[count] = c;
                    s_sift_up(out, count);
                    if (++count == k)
                        bound = out[0].d2;
                } else if (s_worse(&out[0], &c)) {
                    out[0] = c;
                    s_sift_down(out, 0, k);
                    bound = out[0].d2;
                }
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
            if (flo < fhi && !(plane_d2 > bound)) {
                PF_DCHECK(sp < S_STACK);
                stack[sp++] = (s_entry_t){ flo, fhi, plane_d2 };
            }
        }
        /* Entries pushed before the bound shrank may now be out of reach. */
        do {
            if (sp == 0)
                return count;
            sp--;
        } while (stack[sp].d2 > bound);
        lo = stack[sp].lo;
        hi = stack[sp].hi;
    }
}

size_t pf_kdtree_knn_heap(const pf_kdtree_t *self, pf_vec3 x, size_t k, float max_r2, pf_knn_t *out)
{
    return s_knn_heap(self, x, NULL, 0.0f, k, max_r2, out);
}

size_t pf_kdtree_knn_heap_normal(const pf_kdtree_t *self, pf_vec3 x, pf_vec3 n, float min_cos, size_t k, float max_r2,
                                 pf_knn_t *out)
{
    return s_knn_heap(self, x, &n, min_cos, k, max_r2, out);
}

size_t pf_kdtree_knn(const pf_kdtree_t *self, pf_vec3 x, size_t k, float max_r2, pf_knn_t *out)
{
    size_t count = pf_kdtree_knn_heap(self, x, k, max_r2, out);
    /* Heapsort the max-heap in place: ascending by (d2, index). */
    for (size_t end = count; end-- > 1;) {
        pf_knn_t t = out[0];
        out[0] = out[end];
        out[end] = t;
        s_sift_down(out, 0, end);
    }
    return count;
}

/* pf_kdtree_radius, giving up once more than stop photons are found (the
 * count returned is then stop + 1 or a little more). */
static size_t s_radius(const pf_kdtree_t *self, pf_vec3 x, float r2, pf_knn_t *out, size_t cap, size_t stop)
{
    if (!self || self->n == 0 || s_hopeless(x, r2))
        return 0;
    const pf_photon_t *ph = self->photons;
    const float q[3] = { x.x, x.y, x.z };
    size_t count = 0;
    s_entry_t stack[S_STACK];
    int sp = 0;
    uint32_t lo = 0, hi = (uint32_t)self->n;
    /* Whether a photon is inside is a coin toss to the branch predictor, so
     * each one tested is written to the next free slot (or, once cap are
     * kept, to a slot of its own) and counted only if inside. */
    pf_knn_t spill;
    for (;;) {
        while (lo < hi) {
            if (hi - lo <= S_LEAF) {
                for (uint32_t m = lo; m < hi; m++) {
                    float d2 = s_dist2(q, ph[m].pos);
                    pf_knn_t *slot = count < cap ? &out[count] : &spill;
                    *slot = (pf_knn_t){ m, d2 };
                    count += d2 <= r2;
                }
                break;
            }
            uint32_t m = lo + (hi - lo) / 2;
            const float *p = ph[m].pos;
            float d2 = s_dist2(q, p);
            pf_knn_t *slot = count < cap ? &out[count] : &spill;
            *slot = (pf_knn_t){ m, d2 };
            count += d2 <= r2;
            unsigned a = pf_photon_axis(&ph[m]);
            float diff = q[a] - p[a];
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
            if (flo < fhi && !(diff * diff > r2)) {
                PF_DCHECK(sp < S_STACK);
                stack[sp++] = (s_entry_t){ flo, fhi, 0.0f };
            }
        }
        if (sp == 0 || count > stop)
            return count;
        sp--;
        lo = stack[sp].lo;
        hi = stack[sp].hi;
    }
}

size_t pf_kdtree_radius(const pf_kdtree_t *self, pf_vec3 x, float r2, pf_knn_t *out, size_t cap)
{
    return s_radius(self, x, r2, out, cap, SIZE_MAX);
}

size_t pf_kdtree_radius_upto(const pf_kdtree_t *self, pf_vec3 x, float r2, pf_knn_t *out, size_t cap)
{
    return s_radius(self, x, r2, out, cap, cap);
}

/* A high percentile (p in 0..1) of the distances from a sample of points to
 * their nearest neighbour. */
double pf_kdtree_spacing_percentile(const pf_kdtree_t *self, double p)
{
    enum { SAMPLES = 1024 };
    float d[SAMPLES];
    size_t m = 0;
    for (size_t s = 0; s < SAMPLES && s < self->n; s++) {
        size_t i = s * self->n / (self->n < SAMPLES ? self->n : SAMPLES);
        pf_knn_t nn[2];
        if (pf_kdtree_knn(self, pf_photon_pos(&self->photons[i]), 2, INFINITY, nn) == 2 && nn[1].d2 > 0.0f)
            d[m++] = nn[1].d2;
    }
    if (m == 0)
        return 0.0;
    /* a partial insertion sort would do; the sample is small */
    for (size_t i = 1; i < m; i++)
        for (size_t j = i; j > 0 && d[j - 1] > d[j]; j--) {
            float t = d[j];
            d[j] = d[j - 1];
            d[j - 1] = t;
        }
    return sqrt((double)d[(size_t)(p * (double)(m - 1))]);
}
