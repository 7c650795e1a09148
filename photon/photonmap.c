/* photonmap.c: density estimates over photon maps; see photonmap.h. Pure
 * functions of the maps and the query, safe from any thread. Sums run in
 * double in an order fixed by the map and the query point alone (s_gather),
 * so results are reproducible bit for bit. */
#include "photon/photonmap.h"

#include <math.h>
#include <stddef.h>
#include <stdlib.h>
#include <string.h>

#include "base/status.h"
#include "scene/scene.h"
#include "material/bsdf.h"
#include "photon/photon.h"

void pf_photon_maps_free(pf_photon_maps_t *maps)
{
    if (!maps)
        return;
    pf_kdtree_destroy(&maps->global);
    pf_kdtree_destroy(&maps->caustic);
    pf_kdtree_destroy(&maps->irradiance);
    pf_kdtree_destroy(&maps->irradiance_deep);
    memset(maps, 0, sizeof *maps);
}

static int s_cmp_float(const void *a, const void *b)
{
    float x = *(const float *)a, y = *(const float *)b;
    return (x > y) - (x < y);
}

/* The median support of up to S_NEAR_SAMPLES of the irradiance points,
 * evenly spaced in tree order (a pure function of the tree). */
#define S_NEAR_SAMPLES 4096
static float s_median_support(const pf_kdtree_t *irr)
{
    size_t n = irr ? pf_kdtree_size(irr) : 0;
    if (n == 0)
        return 0.0f;
    size_t m = n < S_NEAR_SAMPLES ? n : S_NEAR_SAMPLES;
    float r[S_NEAR_SAMPLES];
    const pf_photon_t *pts = pf_kdtree_photons(irr);
    for (size_t i = 0; i < m; i++)
        r[i] = pf_irradiance_radius(&pts[i * n / m]);
    qsort(r, m, sizeof *r, s_cmp_float);
    return r[m / 2];
}

/* near_r over the median support: a disc of radius r seen from 2 r spans
 * 53 degrees. At equal work (4 passes x 8 spp, 1M photons) the dining
 * room's 4x relMSE against pbrt-v4 went 0.00223 -> 0.00177 (1) -> 0.00155
 * (2) -> 0.00148 (4), its render time +0 %, +8 %, +16 %; cornell-spheres'
 * time +0.7 % (1), +2.2 % (2), its relMSE within noise. */
#define S_NEAR_SUPPORTS 2.0f

int pf_photon_maps_index(pf_photon_maps_t *maps)
{
    maps->near_r = S_NEAR_SUPPORTS * s_median_support(maps->irradiance);
    int rc = maps->irradiance ? pf_kdtree_index_nearest(maps->irradiance) : PF_OK;
    if (rc == PF_OK && maps->irradiance_deep)
        rc = pf_kdtree_index_nearest(maps->irradiance_deep);
    return rc;
}

/* An entry as one integer in (d2, index) order, the order of the k nearest: a squared distance is >= 0
 * (or NaN, never returned by a search), so its bits order as it does. */
static inline uint64_t s_knn_key(const pf_knn_t *e)
{
    uint32_t b;
    memcpy(&b, &e->d2, sizeof b);
    return (uint64_t)b << 32 | e->index;
}

/* The entry of a key (the inverse of s_knn_key). */
static inline pf_knn_t s_knn_of_key(uint64_t key)
{
    uint32_t b = (uint32_t)(key >> 32);
    pf_knn_t e = { (uint32_t)key, 0.0f };
    memcpy(&e.d2, &b, sizeof b);
    return e;
}

/* Whether irradiance point q at squared distance d2 answers a lookup at p
 * (face normal nf): p within q's support, and nothing between them. */
static int s_answers(const pf_photon_t *q, float d2, const pf_accel_t *accel, pf_vec3 p, pf_vec3 nf)
{
    float r = pf_irradiance_radius(q);
    if (!(d2 <= r * r))
        return 0;
    float d = sqrtf(d2);
    pf_ray_t ray;
    float len;
    return !(pf_irradiance_leak_test(q, d, pf_accel_eps(accel)) && pf_irradiance_leak_ray(p, nf, q, d, &ray, &len) &&
             pf_accel_occluded(accel, &ray, len));
}

/* Where the nearest point does not answer, the next nearest up to this
 * many are asked, nearest first. */
#define S_LOOKUP_TRIES 8

pf_vec3 pf_irradiance_lookup(const pf_kdtree_t *irr, float irr_r2, const pf_accel_t *accel, pf_vec3 p, pf_vec3 nf)
{
    const pf_photon_t *q = pf_irradiance_lookup_point(irr, irr_r2, accel, p, nf);
    return q ? pf_photon_power(q) : pf_v3s(0.0f);
}

const pf_photon_t *pf_irradiance_lookup_point(const pf_kdtree_t *irr, float irr_r2, const pf_accel_t *accel, pf_vec3 p,
                                              pf_vec3 nf)
{
    pf_knn_t near;
    if (!irr || !pf_kdtree_nearest_normal(irr, p, nf, PF_NORMAL_AGREE, irr_r2, &near))
        return NULL;
    const pf_photon_t *pts = pf_kdtree_photons(irr);
    if (s_answers(&pts[near.index], near.d2, accel, p, nf))
        return &pts[near.index];
    /* The nearest lies behind something (a chair's leg between the floor
     * points under a table, where the points are sparse) or its support
     * stops short: a zero here darkened whole regions of cluttered rooms
     * by 5 to 25 % at 400k photons. The next nearest that answers, in
     * (distance, index) order: a pure function of the lookup. */
    pf_knn_t cand[S_LOOKUP_TRIES];
    size_t n = pf_kdtree_knn_heap_normal(irr, p, nf, PF_NORMAL_AGREE, S_LOOKUP_TRIES, irr_r2, cand);
    for (size_t i = 0; i < n; i++) /* sort the few by (d2, index) */
        for (size_t j = i + 1; j < n; j++)
            if (s_knn_key(&cand[j]) < s_knn_key(&cand[i])) {
                pf_knn_t t = cand[i];
                cand[i] = cand[j];
                cand[j] = t;
            }
    for (size_t i = 0; i < n; i++)
        if (cand[i].index != near.index && s_answers(&pts[cand[i].index], cand[i].d2, accel, p, nf))
            return &pts[cand[i].index];
    return NULL;
}


/* The key of rank r (0-based) of keys[0, n), r < n; reorders keys.
 * Quickselect with a branch-free Lomuto partition (the comparisons' outcomes
 * are random, so branching on them would mispredict half the time). */
static uint64_t s_rank(uint64_t *keys, size_t n, size_t r)
{
    size_t lo = 0, hi = n; /* the rank lies in [lo, hi) */
    while (hi - lo > 1) {
        size_t mid = lo + (hi - lo) / 2;
        uint64_t t = keys[mid];
        keys[mid] = keys[hi - 1];
        keys[hi - 1] = t;
        size_t store = lo;
        for (size_t i = lo; i < hi - 1; i++) {
            uint64_t v = keys[i];
            int less = v < t;
            keys[i] = keys[store];
            keys[store] = v;
            store += (size_t)less;
        }
        keys[hi - 1] = keys[store];
        keys[store] = t;
        if (r == store)
            return t;
        if (r < store)
            hi = store;
        else
            lo = store + 1;
    }
    return keys[lo];
}

/* Sorts keys[0, n) ascending: quicksort (middle pivot, the smaller side
 * recursed), insertion sort below 16. */
static void s_sort_keys(uint64_t *a, size_t n)
{
    while (n > 16) {
        uint64_t piv = a[n / 2];
        size_t i = 0, j = n - 1;
        for (;;) {
            while (a[i] < piv)
                i++;
            while (a[j] > piv)
                j--;
            if (i >= j)
                break;
            uint64_t t = a[i];
            a[i] = a[j];
            a[j] = t;
            i++;
            j--;
        }
        /* a[0, j] <= piv <= a[j + 1, n) (keys are unique) */
        size_t left = j + 1;
        if (left < n - left) {
            s_sort_keys(a, left);
            a += left;
            n -= left;
        } else {
            s_sort_keys(a + left, n - left);
            n = left;
        }
    }
    for (size_t i = 1; i < n; i++) {
        uint64_t v = a[i];
        size_t j = i;
        for (; j > 0 && a[j - 1] > v; j--)
            a[j] = a[j - 1];
        a[j] = v;
    }
}

/* Puts found[0, n) in tree-index order (indices are unique). */
static void s_sort_by_index(pf_knn_t *found, size_t n, uint64_t *keys)
{
    for (size_t i = 0; i < n; i++) {
        uint32_t bits;
        memcpy(&bits, &found[i].d2, sizeof bits);
        keys[i] = (uint64_t)found[i].index << 32 | bits;
    }
    s_sort_keys(keys, n);
    for (size_t i = 0; i < n; i++) {
        uint32_t bits = (uint32_t)keys[i];
        found[i].index = (uint32_t)(keys[i] >> 32);
        memcpy(&found[i].d2, &bits, sizeof bits);
    }
}

/* Keeps, in place and in order, the entries of a[0, n) with keys below
 * kth's. */
static size_t s_keep_before(pf_knn_t *a, size_t n, uint64_t kth)
{
    size_t m = 0;
    for (size_t i = 0; i < n; i++) {
        pf_knn_t e = a[i];
        a[m] = e;
        m += (size_t)(s_knn_key(&e) < kth);
    }
    return m;
}

/* Keeps, in place and in order, the photons of found[0, c) on n's side
 * (their stored normals agree with n); c itself when c > cap (they were not
 * all written: the caller's overflow case). */
static size_t s_keep_side(const pf_kdtree_t *map, pf_knn_t *found, size_t c, size_t cap, pf_vec3 n)
{
    if (c > cap)
        return c;
    const pf_photon_t *ph = pf_kdtree_photons(map);
    size_t m = 0;
    for (size_t i = 0; i < c; i++) {
        pf_knn_t e = found[i];
        found[m] = e;
        m += (size_t)pf_photon_normal_agrees(&ph[e.index], n, PF_NORMAL_AGREE);
    }
    return m;
}

/* The k nearest photons to x of any side, as s_gather's first step: the
 * k - 1 nearest (the k-th only marks the radius, *r2: for photons of
 * density lambda, E[(k - 1) / (pi r_k^2)] = lambda, while counting all k
 * overestimates by k / (k - 1), 1 % at k = 100, which the furnace shows),
 * or all within max_r2 (*r2 = max_r2, *full 0) when fewer than k lie there,
 * or for k = 1 the nearest over max_r2; returns how many, in
 * scratch->found.
 *
 * They come in the radius search's order (a pre-order walk of the tree,
 * nearer child first), which does not depend on the radius searched: a larger
 * one only adds subtrees; or, when fewer than k lie within max_r2 (which no
 * hint can change), in tree order. So the sums over them, and the estimates,
 * are the same bits whatever the hint (or a thread's previous query) was.
 *
 * With a hint (a guess at the k-th photon's squared distance, from a nearby
 * estimate) the photons within it are collected and the k-th picked by
 * selection, cheaper than keeping a heap; when the hint holds fewer than k
 * (or too many to keep) the k-th is found by a heap search without it, and
 * the photons before it collected within its distance. */
static size_t s_gather_any(const pf_kdtree_t *map, pf_vec3 x, int k, float max_r2, float hint_r2,
                           pf_pm_scratch_t *scratch, float *r2, int *full)
{
    *r2 = max_r2;
    *full = 0;
    if (!map || pf_kdtree_size(map) == 0 || k <= 0)
        return 0;
    if (k > PF_MAX_K)
        k = PF_MAX_K;
    const size_t cap = PF_PM_FOUND, kk = (size_t)k;
    pf_knn_t *found = scratch->found;
    uint64_t kth;
    size_t c = 0;
    /* A hint of max_r2 itself says the last estimate found fewer than k:
     * one radius search then finds them all, cheaper than a heap search. */
    int whole = hint_r2 == max_r2 && isfinite(max_r2);
    if (hint_r2 < max_r2 || whole)
        c = pf_kdtree_radius_upto(map, x, hint_r2, found, cap);
    if (whole && c < kk) {
        s_sort_by_index(found, c, scratch->keys); /* as the heap path below returns them */
        return c;
    }
    *full = 1;
    if (c >= kk && c <= cap) {
        for (size_t i = 0; i < c; i++)
            scratch->keys[i] = s_knn_key(&found[i]);
        kth = s_rank(scratch->keys, c, kk - 1);
        if (kk == 1) {
            /* k = 1: the nearest photon, over the max_r2 disc (a radius
             * marked by the only photon would leave none to sum). */
            found[0] = s_knn_of_key(kth);
            return 1;
        }
    } else {
        size_t n = pf_kdtree_knn_heap(map, x, kk, max_r2, found);
        if (n < kk) {
            /* All of them (none within a hint can have found k): in tree
             * order, which is canonical too and cheaper than a walk. */
            *full = 0;
            s_sort_by_index(found, n, scratch->keys);
            return n;
        }
        if (kk == 1)
            return 1; /* the nearest, in found[0]; over max_r2 as above */
        kth = s_knn_key(&found[0]); /* the heap's root: the k-th */
        float kth_d2 = found[0].d2;
        c = pf_kdtree_radius_upto(map, x, kth_d2, found, cap);
        if (c > cap) {
            /* More than cap photons at the k-th's very distance (coincident
             * photons): the heap's own k - 1, in its order. */
            pf_kdtree_knn_heap(map, x, kk, max_r2, found);
            found[0] = found[kk - 1];
            *r2 = kth_d2;
            return kk - 1;
        }
    }
    *r2 = s_knn_of_key(kth).d2;
    size_t m = s_keep_before(found, c, kth);
    PF_DCHECK(m == kk - 1);
    return m;
}

/* How much farther, in area, the k nearest photons of x's own side may
 * reach than the k nearest of any side: it bounds the search past a sheet
 * whose other side is far denser (S_SIDE_AREA k photons at most). */
#define S_SIDE_AREA 32.0f

/* The k - 1 nearest photons of n's side within lim2 and the k-th's
 * squared distance in *r2, or all of them over lim2 when fewer than k lie
 * there; in the orders s_gather_any gives (a radius walk, or tree order). */
static size_t s_gather_side(const pf_kdtree_t *map, pf_vec3 x, pf_vec3 n, size_t kk, float lim2,
                            pf_pm_scratch_t *scratch, float *r2)
{
    const size_t cap = PF_PM_FOUND;
    pf_knn_t *found = scratch->found;
    *r2 = lim2;
    size_t got = pf_kdtree_knn_heap_normal(map, x, n, PF_NORMAL_AGREE, kk, lim2, found);
    if (got < kk) {
        s_sort_by_index(found, got, scratch->keys);
        return got;
    }
    uint64_t kth = s_knn_key(&found[0]);
    float kth_d2 = found[0].d2;
    *r2 = kth_d2;
    size_t c = s_keep_side(map, found, pf_kdtree_radius_upto(map, x, kth_d2, found, cap), cap, n);
    if (c > cap) { /* the other side's photons, too many to keep: the heap's own k - 1 */
        pf_kdtree_knn_heap_normal(map, x, n, PF_NORMAL_AGREE, kk, lim2, found);
        found[0] = found[kk - 1];
        return kk - 1;
    }
    size_t m = s_keep_before(found, c, kth);
    PF_DCHECK(m == kk - 1);
    return m;
}

/* The photons of the precompute's estimate at x, surface normal n (the
 * camera pass's estimates take s_gather_any's alone): the k - 1 nearest
 * (s_gather_any), those whose stored normals disagree with n left for
 * s_estimate to skip, as long as at least an eighth of them agree (on a
 * thin curved part or in a corner many do not: the disc of all of them is
 * the estimate's, as it always was). When fewer do, x lies on the sparse
 * side of a sheet lit far more on its other side: the k nearest then would shrink
 * the disc to the other side's density, leaving a few of x's photons over
 * a tiny disc (noise) and a support (pf_irradiance_radius) with gaps
 * between the irradiance points, where lookups read zero. So the k - 1
 * nearest of x's side are taken instead, over the k-th's disc, within
 * S_SIDE_AREA times the first disc's area (beyond it, all of x's side
 * within that area over it). Every step depends on x, n and the map alone:
 * the same bits whatever the hint. */
static size_t s_gather(const pf_kdtree_t *map, pf_vec3 x, pf_vec3 n, int k, float max_r2, float hint_r2,
                       pf_pm_scratch_t *scratch, float *r2)
{
    int full;
    size_t cnt = s_gather_any(map, x, k, max_r2, hint_r2, scratch, r2, &full);
    if (!full || k <= 1)
        return cnt;
    const pf_photon_t *ph = pf_kdtree_photons(map);
    size_t agree = 0;
    for (size_t i = 0; i < cnt; i++)
        agree += (size_t)pf_photon_normal_agrees(&ph[scratch->found[i].index], n, PF_NORMAL_AGREE);
    if (8 * agree >= cnt)
        return cnt;
    size_t kk = (size_t)(k > PF_MAX_K ? PF_MAX_K : k);
    return s_gather_side(map, x, n, kk, fminf(max_r2, S_SIDE_AREA * *r2), scratch, r2);
}

pf_vec3 pf_pm_irradiance(const pf_kdtree_t *map, pf_vec3 x, pf_vec3 n, int k, float max_r2, pf_pm_scratch_t *scratch,
                         float *r2_out)
{
    return pf_pm_irradiance_hint(map, x, n, k, max_r2, INFINITY, scratch, r2_out);
}

/* The estimate over the photons s_gather found (cnt of them, the k-th at
 * squared distance r2): over the disc of squared radius shrink2 r2, with a
 * constant kernel or, with cone, Jensen's cone filter. shrink2 = 1 keeps
 * every photon found (no distance test), so the sums are the unshrunk
 * estimate's, bit for bit. */

/* Whether photon p (squared distance d2 from x) lies within x's slab. */
static inline int s_in_slab(const pf_photon_t *p, pf_vec3 x, pf_vec3 n, float d2)
{
    float h = pf_dot(pf_sub(pf_photon_pos(p), x), n);
    return h * h <= PF_PM_SLAB * PF_PM_SLAB * d2;
}

static pf_vec3 s_estimate_slab(const pf_kdtree_t *map, pf_pm_scratch_t *scratch, size_t cnt, const pf_vec3 *slab_x,
                               pf_vec3 n, float r2, float shrink2, int cone)
{
    scratch->direct = pf_v3s(0.0f);
    if (cnt == 0 || !(r2 > 0.0f))
        return pf_v3s(0.0f);
    float rs2 = shrink2 < 1.0f ? r2 * shrink2 : r2;
    if (!(rs2 > 0.0f))
        return pf_v3s(0.0f);
    const pf_photon_t *ph = pf_kdtree_photons(map);
    double r = sqrt((double)rs2);
    double s[3] = { 0, 0, 0 }, sd[3] = { 0, 0, 0 };
    for (size_t i = 0; i < cnt; i++) {
        const pf_photon_t *p = &ph[scratch->found[i].index];
        float d2 = scratch->found[i].d2;
        if (!pf_photon_normal_agrees(p, n, PF_NORMAL_AGREE) || !pf_photon_counts(p, scratch->bounce_limit) ||
            (slab_x && !s_in_slab(p, *slab_x, n, d2)))
            continue;
        double w = 1.0;
        if (cone) {
            w = 1.0 - sqrt((double)d2) / r;
            if (w <= 0.0)
                continue;
        } else if (shrink2 < 1.0f && !(d2 < rs2)) {
            continue;
        }
        double *to = pf_photon_bounce(p) == 0 ? sd : s;
        to[0] += w * p->power[0];
        to[1] += w * p->power[1];
        to[2] += w * p->power[2];
    }
    /* The cone of height 1 over the disc holds pi r^2 / 3; normalize to the disc. */
    double inv = (cone ? 3.0 : 1.0) / (PF_PI * (double)rs2);
    scratch->direct = pf_v3((float)(sd[0] * inv), (float)(sd[1] * inv), (float)(sd[2] * inv));
    return pf_v3((float)((s[0] + sd[0]) * inv), (float)((s[1] + sd[1]) * inv), (float)((s[2] + sd[2]) * inv));
}

static pf_vec3 s_estimate(const pf_kdtree_t *map, pf_pm_scratch_t *scratch, size_t cnt, pf_vec3 n, float r2,
                          float shrink2, int cone)
{
    return s_estimate_slab(map, scratch, cnt, NULL, n, r2, shrink2, cone);
}

pf_vec3 pf_pm_irradiance_hint(const pf_kdtree_t *map, pf_vec3 x, pf_vec3 n, int k, float max_r2, float hint_r2,
                              pf_pm_scratch_t *scratch, float *r2_out)
{
    return pf_pm_estimate(map, x, n, k, max_r2, hint_r2, 1.0f, 0, scratch, r2_out);
}

pf_vec3 pf_pm_irradiance_cone(const pf_kdtree_t *map, pf_vec3 x, pf_vec3 n, int k, float max_r2, float hint_r2,
                              pf_pm_scratch_t *scratch, float *r2_out)
{
    return pf_pm_estimate(map, x, n, k, max_r2, hint_r2, 1.0f, 1, scratch, r2_out);
}

pf_vec3 pf_pm_estimate(const pf_kdtree_t *map, pf_vec3 x, pf_vec3 n, int k, float max_r2, float hint_r2,
                       float shrink2, int cone, pf_pm_scratch_t *scratch, float *r2_out)
{
    float r2 = max_r2;
    int full;
    size_t cnt = s_gather_any(map, x, k, max_r2, hint_r2, scratch, &r2, &full);
    if (r2_out)
        *r2_out = r2;
    return s_estimate(map, scratch, cnt, n, r2, shrink2, cone);
}

float pf_pass_shrink2(int pass)
{
    double s = 1.0;
    for (int i = 1; i <= pass && i < PF_MAX_PASSES; i++)
        s *= ((double)i + PF_PASS_ALPHA) / ((double)i + 1.0);
    return (float)s;
}

pf_vec3 pf_pm_radiance(const pf_kdtree_t *map, const struct pf_material *m, pf_vec3 x, pf_vec3 n, pf_vec3 wo, int k,
                       float max_r2, float shrink2, pf_pm_scratch_t *scratch)
{
    float r2 = 0.0f;
    int full;
    size_t cnt = s_gather_any(map, x, k, max_r2, INFINITY, scratch, &r2, &full);
    if (cnt == 0 || !(r2 > 0.0f))
        return pf_v3s(0.0f);
    if (shrink2 < 1.0f)
        r2 *= shrink2;
    const pf_photon_t *ph = pf_kdtree_photons(map);
    double s[3] = { 0, 0, 0 };
    for (size_t i = 0; i < cnt; i++) {
        const pf_photon_t *p = &ph[scratch->found[i].index];
        if (!pf_photon_normal_agrees(p, n, PF_NORMAL_AGREE) || (shrink2 < 1.0f && !(scratch->found[i].d2 < r2)) ||
            !pf_photon_counts(p, scratch->bounce_limit))
            continue;
        pf_vec3 wi = pf_neg(pf_photon_dir(p));
        pf_vec3 f = pf_brdf_eval(m, n, wi, wo);
        s[0] += f.x * p->power[0];
        s[1] += f.y * p->power[1];
        s[2] += f.z * p->power[2];
    }
    double inv = 1.0 / (PF_PI * (double)r2);
    return pf_v3((float)(s[0] * inv), (float)(s[1] * inv), (float)(s[2] * inv));
}

int pf_pm_visible_scratch_init(pf_pm_visible_scratch_t *vs, size_t cap)
{
    memset(vs, 0, sizeof *vs);
    if (cap < PF_PM_FOUND)
        cap = PF_PM_FOUND;
    vs->found = malloc(cap * sizeof *vs->found);
    vs->keys = malloc(cap * sizeof *vs->keys);
    vs->visible = malloc(PF_MAX_K * sizeof *vs->visible);
    if (!vs->found || !vs->keys || !vs->visible) {
        pf_pm_visible_scratch_free(vs);
        return PF_ENOMEM;
    }
    vs->cap = cap;
    return PF_OK;
}

void pf_pm_visible_scratch_free(pf_pm_visible_scratch_t *vs)
{
    if (!vs)
        return;
    free(vs->found);
    free(vs->keys);
    free(vs->visible);
    memset(vs, 0, sizeof *vs);
}

/* The surfaces near one query point, to spare its visibility rays. */
typedef struct s_near {
    const pf_plane_t *planes;
    int n;        /* -1: unknown (trace every ray) */
    float reach;  /* the planes are those of every triangle within reach */
    double margin;
} s_near;

/* Whether every near plane has both a and b on one side of it (by more
 * than the margin): then the segment meets no triangle within reach. */
static int s_separated(const s_near *near, pf_vec3 a, pf_vec3 b)
{
    for (int i = 0; i < near->n; i++) {
        const pf_plane_t *pl = &near->planes[i];
        double sa = pl->n[0] * a.x + pl->n[1] * a.y + pl->n[2] * a.z - pl->d;
        double sb = pl->n[0] * b.x + pl->n[1] * b.y + pl->n[2] * b.z - pl->d;
        if (!((sa > near->margin && sb > near->margin) || (sa < -near->margin && sb < -near->margin)))
            return 0;
    }
    return 1;
}

/* Whether x (unit normal n) sees photon p at distance d: the segment from x
 * lifted by d along n to p lifted by d along its own normal (the side it
 * was stored on) hits nothing. For a photon of x's plane that is the leak
 * test's ray; lifting each end along its own normal also keeps a photon on
 * a wall that meets x's plane (a corner) in view, its end moved off the wall
 * into the room, while one on the wall's far face moves further behind it.
 * Lifting by d keeps the segment clear of x's own surface where it curves
 * (it sags d^2 / 2R below the tangent plane) or is tessellated. Within eps
 * no wall fits between. The segment lies within 2 d of x, so where no near
 * plane separates its ends no ray is needed: at a corner, and on a thin
 * wall's near side, no plane does. */
static int s_seen(const pf_accel_t *accel, const s_near *near, pf_vec3 x, pf_vec3 n, const pf_photon_t *p, float d,
                  float eps)
{
    if (!(d > eps))
        return 1;
    pf_vec3 a = pf_madd(x, n, d), b = pf_madd(pf_photon_pos(p), pf_photon_normal(p), d);
    if (near->n >= 0 && 2.0f * d <= near->reach && s_separated(near, a, b))
        return 1;
    pf_vec3 ab = pf_sub(b, a);
    float len = pf_len(ab);
    if (!(len > 0.0f))
        return 1;
    pf_ray_t ray = { a, pf_scale(ab, 1.0f / len) };
    return !pf_accel_occluded(accel, &ray, len);
}

/* Normalization when photons are hidden: the k - 1 nearest SEEN photons
 * over the disc of the k-th seen one, not the k nearest with the hidden
 * ones dropped from the sum. Both divide by the whole disc, part of which
 * (behind the wall) is not x's surface, so both read low by the share of
 * the disc the wall cuts off, as the estimate already does at any corner
 * (a wall's photons there count towards k but not the sum). But when the
 * far side is much brighter its photons crowd the k nearest: dropping them
 * would leave few photons (noise) over a tiny disc, and that disc is also
 * the point's support (pf_irradiance_radius), outside of which lookups read
 * zero, so a dark band would line the wall. The k nearest seen photons keep
 * the noise and the support at x's own side's density. Dividing by the seen
 * part of the disc instead would remove the corner bias too, but needs that
 * area, which no query gives, and would make the corner and the thin wall
 * disagree.
 *
 * The estimate over the seen photons at x (those bounce_limit counts, as
 * pf_pm_scratch_t's) into *e (its first hits' part into *direct) and *r2 (which hold the
 * plain estimate's squared radius on entry); returns how many photons were
 * found hidden, 0 leaving *e and *r2 as they were. */
static size_t s_seen_estimate(const pf_kdtree_t *map, const pf_accel_t *accel, s_near near, pf_vec3 x, pf_vec3 n,
                              size_t kk, float max_r2, float shrink2, unsigned bounce_limit, pf_vec3 *e, pf_vec3 *direct,
                              float *r2, pf_pm_visible_scratch_t *vs)
{
    const pf_photon_t *ph = pf_kdtree_photons(map);
    const float eps = pf_accel_eps(accel);
    /* Search radii grow; the photons within a smaller one are a prefix (in
     * (d2, index) order) of those within a larger one, so each is tested
     * once and the seen ones kept in order in vs->visible. */
    float search = fminf(*r2, max_r2), done = 0.0f;
    size_t tested = 0, seen = 0, hidden = 0;
    int complete = 0;
    for (;;) {
        size_t c = pf_kdtree_radius(map, x, search, vs->found, vs->cap);
        if (c > vs->cap)
            break; /* too many to sort: the seen ones within `done` serve */
        /* keys[0, tested) hold, sorted, the photons within done (all of
         * them, tested); the new ones lie beyond it: sort only those. */
        size_t m = tested;
        for (size_t i = 0; i < c; i++)
            if (vs->found[i].d2 > done || tested == 0)
                vs->keys[m++] = s_knn_key(&vs->found[i]);
        PF_DCHECK(m == c);
        s_sort_keys(vs->keys + tested, m - tested);
        c = m;
        for (; tested < c && seen < kk; tested++) {
            pf_knn_t f = s_knn_of_key(vs->keys[tested]);
            if (!pf_photon_normal_agrees(&ph[f.index], n, PF_NORMAL_AGREE))
                continue; /* the other side's: neither seen nor hidden (s_gather) */
            if (s_seen(accel, &near, x, n, &ph[f.index], sqrtf(f.d2), eps))
                vs->visible[seen++] = vs->keys[tested];
            else
                hidden++;
        }
        if (seen >= kk || !(search < max_r2)) {
            complete = 1;
            break;
        }
        /* Fewer than k seen within search, all tested: widen to where the
         * seen photons' density would hold k, by 1.5 to 16 times the area. */
        done = search;
        float grow = 1.25f * (float)kk / (float)(seen ? seen : 1);
        grow = fminf(fmaxf(grow, 1.5f), 16.0f);
        search = search > 0.0f ? fminf(search * grow, max_r2) : max_r2;
        /* The planes near the wider photons' segments too (else each of
         * them would trace its ray). */
        near.reach = 2.0f * sqrtf(search) * 1.001f;
        near.n = pf_accel_near_planes(accel, x, near.reach + 4.0f * eps, vs->planes, PF_PM_VISIBLE_PLANES);
    }
    if (hidden == 0)
        return 0; /* nothing tested (the first search overflowed): the estimate stands */
    float rr = done;
    size_t sum_n = seen;
    if (complete && seen >= kk) {
        rr = s_knn_of_key(vs->visible[kk - 1]).d2;
        sum_n = kk == 1 ? 1 : kk - 1; /* k = 1: the nearest over max_r2, as s_gather */
        if (kk == 1)
            rr = max_r2;
    } else if (complete) {
        rr = max_r2; /* fewer than k seen within max_r2: all of them over it */
    }
    *r2 = rr; /* the support: the unshrunk disc, as s_estimate's callers keep it */
    float rs2 = shrink2 < 1.0f ? rr * shrink2 : rr;
    if (!(rs2 > 0.0f)) {
        *e = *direct = pf_v3s(0.0f);
        return hidden;
    }
    /* As s_estimate with a constant kernel: the disc shrunk by shrink2
     * keeps the seen photons within it. */
    double s[3] = { 0, 0, 0 }, sd[3] = { 0, 0, 0 };
    for (size_t i = 0; i < sum_n; i++) {
        pf_knn_t f = s_knn_of_key(vs->visible[i]);
        const pf_photon_t *p = &ph[f.index];
        if (!pf_photon_normal_agrees(p, n, PF_NORMAL_AGREE) || (shrink2 < 1.0f && !(f.d2 < rs2)) ||
            !pf_photon_counts(p, bounce_limit) || !s_in_slab(p, x, n, f.d2))
            continue;
        double *to = pf_photon_bounce(p) == 0 ? sd : s;
        to[0] += p->power[0];
        to[1] += p->power[1];
        to[2] += p->power[2];
    }
    double inv = 1.0 / (PF_PI * (double)rs2);
    *direct = pf_v3((float)(sd[0] * inv), (float)(sd[1] * inv), (float)(sd[2] * inv));
    *e = pf_v3((float)((s[0] + sd[0]) * inv), (float)((s[1] + sd[1]) * inv), (float)((s[2] + sd[2]) * inv));
    return hidden;
}

pf_vec3 pf_pm_irradiance_seen(const pf_kdtree_t *map, const pf_accel_t *accel, pf_vec3 x, pf_vec3 n, int k,
                              float max_r2, float hint_r2, float shrink2, pf_pm_scratch_t *scratch,
                              pf_pm_visible_scratch_t *vs, float *r2_out, int *flat_out)
{
    float r2 = max_r2;
    size_t cnt = s_gather(map, x, n, k, max_r2, hint_r2, scratch, &r2);
    const pf_photon_t *ph = pf_kdtree_photons(map);
    pf_vec3 e = s_estimate(map, scratch, cnt, n, r2, shrink2, 0);
    *r2_out = r2;
    *flat_out = 0;
    if (!accel)
        return e;
    *flat_out = pf_accel_only_plane(accel, x, n, PF_IRRADIANCE_FLAT_REACH * sqrtf(r2));
    if (*flat_out || cnt == 0)
        return e;
    e = s_estimate_slab(map, scratch, cnt, &x, n, r2, shrink2, 0); /* other surfaces near: x's own slab */
    if (k > PF_MAX_K)
        k = PF_MAX_K;
    /* The triangles within reach of the nearest photons' segments (2 d,
     * with a margin for the rounding of their ends). */
    const float eps = pf_accel_eps(accel);
    s_near near = { vs->planes, -1, 2.0f * sqrtf(fminf(r2, max_r2)) * 1.001f, 4.0 * (double)eps };
    near.n = pf_accel_near_planes(accel, x, near.reach + 4.0f * eps, vs->planes, PF_PM_VISIBLE_PLANES);
    /* The photons summed, all seen: the estimate stands (the k-th only
     * marks the radius). Else the search over seen photons. */
    size_t i = 0;
    while (i < cnt && s_seen(accel, &near, x, n, &ph[scratch->found[i].index], sqrtf(scratch->found[i].d2), eps))
        i++;
    if (i == cnt)
        return e;
    s_seen_estimate(map, accel, near, x, n, (size_t)k, max_r2, shrink2, scratch->bounce_limit, &e, &scratch->direct,
                    r2_out, vs);
    return e;
}
