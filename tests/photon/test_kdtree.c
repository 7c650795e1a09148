/* test_kdtree.c: the photon kd-tree against brute force.
 *
 * Each photon carries its input index in `dir`, so after the build reorders
 * them the test can tell which photon went where. For every set the test
 * checks (1) the layout against the rules of kdtree.h, recomputed naively:
 * the tree is a permutation of the input, each node's axis is the widest
 * extent of its range (lowest axis on ties), and the node is the median of its
 * range by (coordinate, input index); (2) k-nearest results equal the first k
 * of a linear scan sorted by (d2, tree index), bit for bit, for many queries,
 * k and radii; (3) radius counts and members equal the linear scan.
 * Squared distances are computed with the formula kdtree.c documents (float
 * differences, squares summed in double, one rounding), so they must match
 * exactly. Plus: determinism across runs and thread counts; the selection's
 * heapsort fallback; photons with non-finite positions; tiny distances with
 * flush-to-zero on, as in rendering threads; and pf_kdtree_from_layout's
 * acceptance and rejection of layouts. */
#include <math.h>
#include <omp.h>
#ifdef __SSE2__
#include <pmmintrin.h>
#include <xmmintrin.h>
#endif
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "photon/kdtree.h"
#include "photon/photonmap.h"

#include "check.h"



/* ---- random numbers (SplitMix64; the test only needs repeatability) ---- */

static uint64_t s_state = 12345;

static uint64_t s_next(void)
{
    uint64_t z = (s_state += 0x9e3779b97f4a7c15ULL);
    z = (z ^ (z >> 30)) * 0xbf58476d1ce4e5b9ULL;
    z = (z ^ (z >> 27)) * 0x94d049bb133111ebULL;
    return z ^ (z >> 31);
}

static float s_uniform(void) { return (float)(s_next() >> 40) * 0x1p-24f; }

static float s_gauss(void)
{
    float u = s_uniform() + 0x1p-25f, v = s_uniform();
    return sqrtf(-2.0f * logf(u)) * cosf(6.2831853f * v);
}

/* ---- photon sets ---- */

enum { SET_UNIFORM, SET_CLUSTERED, SET_COINCIDENT, SET_HALF_COINCIDENT, SET_TINY, SET_GRID, SET_LINE };
static const char *s_set_names[] = { "uniform", "clustered", "coincident", "half-coincident", "tiny", "grid", "line" };

static pf_photon_t *s_make_set(int kind, size_t n)
{
    pf_photon_t *ph = malloc((n ? n : 1) * sizeof *ph);
    if (!ph) {
        fprintf(stderr, "out of memory\n");
        exit(2);
    }
    float centers[5][3];
    for (int c = 0; c < 5; c++)
        for (int a = 0; a < 3; a++)
            centers[c][a] = s_uniform() * 20.0f - 10.0f;
    for (size_t i = 0; i < n; i++) {
        float p[3];
        for (int a = 0; a < 3; a++) {
            switch (kind) {
            case SET_UNIFORM: p[a] = s_uniform() * 2.0f - 1.0f; break;
            case SET_CLUSTERED: p[a] = centers[i % 5][a] + 0.05f * s_gauss(); break;
            case SET_COINCIDENT: p[a] = 0.25f * (float)(a + 1); break;
            case SET_HALF_COINCIDENT: p[a] = (i % 2) ? 0.5f : s_uniform(); break;
            case SET_TINY: p[a] = 1e-20f * s_uniform(); break;
            case SET_GRID: {
                /* Integers -3..3 with zero stored as -0 or +0 at random: many
                 * equal coordinates, many equal distances. */
                int v = (int)(s_next() % 7) - 3;
                p[a] = v == 0 ? ((s_next() & 1) ? -0.0f : 0.0f) : (float)v;
                break;
            }
            case SET_LINE: p[a] = a == 0 ? (float)i : 0.0f; break;
            }
        }
        memset(&ph[i], 0, sizeof ph[i]);
        memcpy(ph[i].pos, p, sizeof p);
        ph[i].power[0] = (float)i;
        ph[i].dir = (uint32_t)i;
        ph[i].normal = (uint32_t)(i * 2654435761u);
    }
    return ph;
}

static pf_photon_t *s_copy(const void *src, size_t bytes)
{
    void *dst = malloc(bytes ? bytes : 1);
    if (!dst) {
        fprintf(stderr, "out of memory\n");
        exit(2);
    }
    if (bytes)
        memcpy(dst, src, bytes);
    return dst;
}

/* ---- reference rules ---- */

/* The same photon record, the split-axis bits of the normal aside. */
static int s_same_record(const pf_photon_t *a, const pf_photon_t *b)
{
    pf_photon_t x = *a, y = *b;
    x.normal &= ~PF_PHOTON_AXIS_BITS;
    y.normal &= ~PF_PHOTON_AXIS_BITS;
    return memcmp(&x, &y, sizeof x) == 0;
}

/* The documented distance: float differences, squares summed in double. */
static float s_ref_d2(pf_vec3 x, const pf_photon_t *p)
{
    double dx = x.x - p->pos[0], dy = x.y - p->pos[1], dz = x.z - p->pos[2];
    return (float)(dx * dx + dy * dy + dz * dz);
}

/* Build order: coordinate on the axis, then input index (kept in dir). */
static int s_key_less(const pf_photon_t *a, const pf_photon_t *b, int axis)
{
    if (a->pos[axis] != b->pos[axis])
        return a->pos[axis] < b->pos[axis];
    return a->dir < b->dir;
}

/* Checks axis choice and median rule for the subtree of [lo, hi). */
static void s_check_subtree(const pf_photon_t *ph, size_t lo, size_t hi, int *bad)
{
    if (lo >= hi || *bad)
        return;
    size_t m = lo + (hi - lo) / 2;
    float mn[3] = { INFINITY, INFINITY, INFINITY }, mx[3] = { -INFINITY, -INFINITY, -INFINITY };
    for (size_t i = lo; i < hi; i++)
        for (int a = 0; a < 3; a++) {
            mn[a] = fminf(mn[a], ph[i].pos[a]);
            mx[a] = fmaxf(mx[a], ph[i].pos[a]);
        }
    int want = 0;
    for (int a = 1; a < 3; a++)
        if (mx[a] - mn[a] > mx[want] - mn[want])
            want = a;
    int axis = (int)pf_photon_axis(&ph[m]);
    if (axis != want) {
        CHECK(axis == want, "range [%zu,%zu): axis %d, widest is %d", lo, hi, axis, want);
        *bad = 1;
        return;
    }
    for (size_t i = lo; i < hi; i++) {
        if (i == m)
            continue;
        int ok = i < m ? s_key_less(&ph[i], &ph[m], want) : s_key_less(&ph[m], &ph[i], want);
        if (!ok) {
            CHECK(ok, "range [%zu,%zu): photon %zu on the wrong side of median %zu", lo, hi, i, m);
            *bad = 1;
            return;
        }
    }
    s_check_subtree(ph, lo, m, bad);
    s_check_subtree(ph, m + 1, hi, bad);
}

static void s_check_layout(const pf_kdtree_t *t, const pf_photon_t *input, size_t n, const char *what)
{
    CHECK(pf_kdtree_size(t) == n, "%s: size", what);
    const pf_photon_t *ph = pf_kdtree_photons(t);
    /* A permutation of the input, records intact but for the axis bits. */
    unsigned char *seen = calloc(n ? n : 1, 1);
    int perm_ok = 1;
    for (size_t i = 0; i < n && perm_ok; i++) {
        uint32_t id = ph[i].dir;
        if (id >= n || seen[id] || !s_same_record(&ph[i], &input[id]))
            perm_ok = 0;
        else
            seen[id] = 1;
    }
    free(seen);
    CHECK(perm_ok, "%s: tree photons are not a permutation of the input", what);
    if (!perm_ok)
        return;
    int bad = 0;
    s_check_subtree(ph, 0, n, &bad);
    CHECK(!bad, "%s: layout rules", what);
    /* Bounds. */
    pf_vec3 lo, hi;
    pf_kdtree_bounds(t, &lo, &hi);
    if (n == 0) {
        CHECK(lo.x > hi.x && lo.y > hi.y && lo.z > hi.z, "%s: empty bounds", what);
    } else {
        float mn[3] = { INFINITY, INFINITY, INFINITY }, mx[3] = { -INFINITY, -INFINITY, -INFINITY };
        for (size_t i = 0; i < n; i++)
            for (int a = 0; a < 3; a++) {
                mn[a] = fminf(mn[a], ph[i].pos[a]);
                mx[a] = fmaxf(mx[a], ph[i].pos[a]);
            }
        CHECK(lo.x == mn[0] && lo.y == mn[1] && lo.z == mn[2], "%s: bounds lo", what);
        CHECK(hi.x == mx[0] && hi.y == mx[1] && hi.z == mx[2], "%s: bounds hi", what);
    }
}

/* ---- queries against brute force ---- */

/* By (d2, index), NaN distances (photons with a NaN coordinate) last. */
static int s_cmp_knn(const void *pa, const void *pb)
{
    const pf_knn_t *a = pa, *b = pb;
    if (isnan(a->d2) != isnan(b->d2))
        return isnan(a->d2) ? 1 : -1;
    if (a->d2 != b->d2 && !isnan(a->d2))
        return a->d2 < b->d2 ? -1 : 1;
    return (a->index > b->index) - (a->index < b->index);
}

/* All photons with their d2 from x, sorted by (d2, tree index); NaN distances
 * come last and no radius takes them. */
static void s_brute(const pf_kdtree_t *t, pf_vec3 x, pf_knn_t *all)
{
    size_t n = pf_kdtree_size(t);
    const pf_photon_t *ph = pf_kdtree_photons(t);
    for (size_t i = 0; i < n; i++)
        all[i] = (pf_knn_t){ (uint32_t)i, s_ref_d2(x, &ph[i]) };
    qsort(all, n, sizeof *all, s_cmp_knn);
}

static void s_check_knn(const pf_kdtree_t *t, pf_vec3 x, const pf_knn_t *all, size_t k, float max_r2,
                        pf_knn_t *out, const char *what)
{
    size_t n = pf_kdtree_size(t);
    size_t want = 0;
    while (want < n && want < k && all[want].d2 <= max_r2)
        want++;
    size_t got = pf_kdtree_knn(t, x, k, max_r2, out);
    int ok = got == want;
    for (size_t i = 0; ok && i < got; i++)
        ok = out[i].index == all[i].index && memcmp(&out[i].d2, &all[i].d2, sizeof(float)) == 0;
    CHECK(ok, "%s: knn(x=(%g,%g,%g), k=%zu, max_r2=%g): got %zu, want %zu", what, x.x, x.y, x.z, k,
          max_r2, got, want);
}

static void s_check_radius(const pf_kdtree_t *t, pf_vec3 x, const pf_knn_t *all, float r2, pf_knn_t *out,
                           const char *what)
{
    size_t n = pf_kdtree_size(t);
    size_t want = 0;
    while (want < n && all[want].d2 <= r2)
        want++;
    /* Enough room: the members, in any order, are exactly the scan's. */
    size_t got = pf_kdtree_radius(t, x, r2, out, n);
    int ok = got == want;
    if (ok) {
        /* member[i]: 1 + the position of tree photon i in the scan, if in. */
        uint32_t *member = calloc(n ? n : 1, sizeof *member);
        for (size_t i = 0; i < want; i++)
            member[all[i].index] = (uint32_t)i + 1;
        for (size_t i = 0; ok && i < got; i++) {
            uint32_t at = out[i].index < n ? member[out[i].index] : 0;
            ok = at != 0 && memcmp(&out[i].d2, &all[at - 1].d2, sizeof(float)) == 0;
            if (ok)
                member[out[i].index] = 0; /* a second report fails */
        }
        free(member);
    }
    CHECK(ok, "%s: radius(x=(%g,%g,%g), r2=%g): got %zu, want %zu", what, x.x, x.y, x.z, r2, got, want);
    /* Too little room: the full count, and the cap written with true members. */
    if (want >= 2) {
        size_t cap = want / 2;
        for (size_t i = 0; i < n; i++)
            out[i] = (pf_knn_t){ UINT32_MAX, -1.0f };
        got = pf_kdtree_radius(t, x, r2, out, cap);
        const pf_photon_t *ph = pf_kdtree_photons(t);
        unsigned char *seen = calloc(n, 1);
        ok = got == want && out[cap].index == UINT32_MAX;
        for (size_t i = 0; ok && i < cap; i++) {
            ok = out[i].index < n && !seen[out[i].index] && out[i].d2 == s_ref_d2(x, &ph[out[i].index]) &&
                 out[i].d2 <= r2;
            if (ok)
                seen[out[i].index] = 1;
        }
        free(seen);
        CHECK(ok, "%s: radius with cap %zu of %zu", what, cap, want);
        /* radius_upto: beyond its cap only "more than cap", the same photons
         * written; within its cap, what radius gives. */
        pf_knn_t *first = malloc(cap * sizeof *first);
        memcpy(first, out, cap * sizeof *first);
        size_t upto = pf_kdtree_radius_upto(t, x, r2, out, cap);
        CHECK(upto > cap && upto <= want && memcmp(first, out, cap * sizeof *out) == 0,
              "%s: radius_upto with cap %zu of %zu returned %zu", what, cap, want, upto);
        free(first);
    }
    if (want <= n) {
        pf_knn_t *a = malloc((want ? want : 1) * sizeof *a), *b = malloc((want ? want : 1) * sizeof *b);
        size_t na = pf_kdtree_radius(t, x, r2, a, want), nb = pf_kdtree_radius_upto(t, x, r2, b, want);
        CHECK(na == nb && memcmp(a, b, na * sizeof *a) == 0, "%s: radius_upto with room for all differs", what);
        free(a);
        free(b);
    }
}

/* The radius search's order does not depend on the radius: the photons
 * found within r2 come in the same relative order within a larger r2_big
 * (the estimates' sums rely on it to be the same bits for any search hint). */
static void s_check_radius_order(const pf_kdtree_t *t, pf_vec3 x, float r2, float r2_big, const char *what)
{
    size_t n = pf_kdtree_size(t);
    pf_knn_t *small = malloc((n + 1) * sizeof *small), *big = malloc((n + 1) * sizeof *big);
    uint32_t *pos = malloc((n + 1) * sizeof *pos);
    size_t ns = pf_kdtree_radius(t, x, r2, small, n), nb = pf_kdtree_radius(t, x, r2_big, big, n);
    int ok = ns <= nb;
    for (size_t i = 0; i < n; i++)
        pos[i] = UINT32_MAX;
    for (size_t i = 0; ok && i < nb; i++)
        pos[big[i].index] = (uint32_t)i;
    for (size_t i = 0; ok && i < ns; i++)
        ok = pos[small[i].index] != UINT32_MAX && (i == 0 || pos[small[i].index] > pos[small[i - 1].index]);
    CHECK(ok, "%s: radius(x=(%g,%g,%g)) order: r2 %g's %zu photons are not in r2 %g's order", what, x.x, x.y, x.z,
          r2, ns, r2_big);
    free(small);
    free(big);
    free(pos);
}

/* Queries: random points around the set, every (or every few) photon's own
 * position, and midpoints of photon pairs, which make distance ties. */
static void s_check_queries(const pf_kdtree_t *t, int nrandom, const char *what)
{
    size_t n = pf_kdtree_size(t);
    const pf_photon_t *ph = pf_kdtree_photons(t);
    /* Query region: around the finite photons. */
    pf_vec3 lo = pf_v3s(INFINITY), hi = pf_v3s(-INFINITY);
    for (size_t i = 0; i < n; i++) {
        if (pf_is_finite3(pf_photon_pos(&ph[i]))) {
            lo = pf_vmin(lo, pf_photon_pos(&ph[i]));
            hi = pf_vmax(hi, pf_photon_pos(&ph[i]));
        }
    }
    if (lo.x > hi.x)
        lo = hi = pf_v3s(0.0f);
    pf_vec3 ext = pf_sub(hi, lo);
    pf_knn_t *all = malloc((n + 1) * sizeof *all);
    pf_knn_t *out = malloc((n + 6) * sizeof *out);
    size_t step = n > 200 ? n / 60 : 1;
    size_t nq = (size_t)nrandom + (n + step - 1) / step + 20;
    for (size_t q = 0; q < nq; q++) {
        pf_vec3 x;
        if (q < (size_t)nrandom || n == 0) {
            x = pf_v3(lo.x + ext.x * (s_uniform() * 1.4f - 0.2f), lo.y + ext.y * (s_uniform() * 1.4f - 0.2f),
                      lo.z + ext.z * (s_uniform() * 1.4f - 0.2f));
        } else if (q < nq - 20) {
            x = pf_photon_pos(&ph[((q - (size_t)nrandom) * step) % n]);
        } else {
            pf_vec3 a = pf_photon_pos(&ph[s_next() % n]), b = pf_photon_pos(&ph[s_next() % n]);
            x = pf_scale(pf_add(a, b), 0.5f);
        }
        s_brute(t, x, all);
        /* Radii: none, zero, exactly some neighbour's d2 (inclusive edge),
         * and a random fraction of the extent. */
        float radii[5] = { INFINITY, 0.0f, INFINITY, INFINITY, 0.01f * pf_len2(ext) * s_uniform() };
        if (n > 0) {
            radii[2] = all[s_next() % n].d2;
            radii[3] = all[(n - 1) / 3].d2;
        }
        /* k = n and beyond costs O(n log n) a query; on large sets a few
         * queries are enough for it. */
        size_t ks[7] = { 1, 2, 7, 32, 64, n, n + 5 };
        int nk = n <= 64 || q % 16 == 0 ? 7 : 5;
        for (int r = 0; r < 5; r++) {
            for (int ki = 0; ki < nk; ki++)
                s_check_knn(t, x, all, ks[ki], radii[r], out, what);
            s_check_radius(t, x, all, radii[r], out, what);
        }
        if (q % 4 == 0) {
            s_check_radius_order(t, x, fminf(radii[4], radii[3]), fmaxf(radii[4], radii[3]), what);
            s_check_radius_order(t, x, radii[4], INFINITY, what);
            s_check_radius_order(t, x, 0.25f * radii[4], radii[4], what);
        }
    }
    free(all);
    free(out);
}

static pf_kdtree_t *s_build_copy(const pf_photon_t *input, size_t n)
{
    pf_photon_t *ph = s_copy(input, n * sizeof *input);
    pf_kdtree_t *t = pf_kdtree_build(&ph, n);
    CHECK(ph == NULL, "build must take the photons");
    return t;
}

/* Builds a set, checks layout and queries, then that a rebuild is identical
 * and that the layout survives pf_kdtree_from_layout. */
static void s_test_set(int kind, size_t n, int nrandom)
{
    char what[64];
    snprintf(what, sizeof what, "%s n=%zu", s_set_names[kind], n);
    pf_photon_t *input = s_make_set(kind, n);
    pf_kdtree_t *t = s_build_copy(input, n);
    CHECK(t != NULL, "%s: build", what);
    if (!t) {
        free(input);
        return;
    }
    s_check_layout(t, input, n, what);
    s_check_queries(t, nrandom, what);

    /* Input indices break every tie, so a set whose order is the order of
     * its coordinates (all at one point, or along a line) stays in place. */
    if (kind == SET_COINCIDENT || kind == SET_LINE) {
        int ok = 1;
        for (size_t i = 0; i < n; i++)
            ok &= pf_kdtree_photons(t)[i].dir == i && pf_photon_axis(&pf_kdtree_photons(t)[i]) == 0;
        CHECK(ok, "%s: presorted input must keep its order, all axes 0", what);
    }

    pf_kdtree_t *t2 = s_build_copy(input, n);
    CHECK(t2 && memcmp(pf_kdtree_photons(t), pf_kdtree_photons(t2), n * sizeof(pf_photon_t)) == 0,
          "%s: rebuild differs", what);
    pf_kdtree_destroy(&t2);

    pf_photon_t *lph = s_copy(pf_kdtree_photons(t), n * sizeof(pf_photon_t));
    pf_kdtree_t *t3 = pf_kdtree_from_layout(&lph, n);
    CHECK(lph == NULL, "%s: from_layout must take the array", what);
    CHECK(t3 != NULL, "%s: from_layout rejects a built layout", what);
    if (t3) {
        CHECK(memcmp(pf_kdtree_photons(t), pf_kdtree_photons(t3), n * sizeof(pf_photon_t)) == 0,
              "%s: from_layout changed the layout", what);
        pf_vec3 a, b, c, d;
        pf_kdtree_bounds(t, &a, &b);
        pf_kdtree_bounds(t3, &c, &d);
        CHECK(memcmp(&a, &c, sizeof a) == 0 && memcmp(&b, &d, sizeof b) == 0, "%s: from_layout bounds", what);
        /* Same answers as the built tree. */
        pf_knn_t *o1 = malloc((n + 8) * sizeof *o1), *o2 = malloc((n + 8) * sizeof *o2);
        int ok = 1;
        for (int q = 0; q < 10; q++) {
            pf_vec3 x = pf_v3(s_uniform() * 2 - 1, s_uniform() * 2 - 1, s_uniform() * 2 - 1);
            size_t k = 1 + s_next() % (n + 8);
            size_t g1 = pf_kdtree_knn(t, x, k, INFINITY, o1), g2 = pf_kdtree_knn(t3, x, k, INFINITY, o2);
            ok &= g1 == g2 && memcmp(o1, o2, g1 * sizeof *o1) == 0;
        }
        CHECK(ok, "%s: from_layout tree answers differently", what);
        free(o1);
        free(o2);
        pf_kdtree_destroy(&t3);
    }
    pf_kdtree_destroy(&t);
    CHECK(t == NULL, "destroy must clear the pointer");
    free(input);
}

/* Bad positions the build cannot refuse: every 7th photon has a NaN and every
 * 11th an infinite coordinate. The NaN ones must never be found nor hide any
 * other photon (a NaN split plane must not prune); the infinite ones are at
 * infinite distance, found only with an infinite radius. */
static void s_test_nonfinite(size_t n)
{
    char what[64];
    snprintf(what, sizeof what, "non-finite n=%zu", n);
    pf_photon_t *input = s_make_set(SET_UNIFORM, n);
    for (size_t i = 0; i < n; i++) {
        if (i % 7 == 3)
            input[i].pos[i % 3] = NAN;
        else if (i % 11 == 5)
            input[i].pos[(i + 1) % 3] = (i & 1) ? INFINITY : -INFINITY;
    }
    pf_kdtree_t *t = s_build_copy(input, n);
    CHECK(t != NULL, "%s: build", what);
    if (!t) {
        free(input);
        return;
    }
    s_check_queries(t, 30, what);
    pf_kdtree_t *t2 = s_build_copy(input, n);
    CHECK(t2 && memcmp(pf_kdtree_photons(t), pf_kdtree_photons(t2), n * sizeof(pf_photon_t)) == 0,
          "%s: rebuild differs", what);
    pf_kdtree_destroy(&t2);
    /* Such a layout cannot come back over the wire. */
    if (n > 3) {
        pf_photon_t *lph = s_copy(pf_kdtree_photons(t), n * sizeof(pf_photon_t));
        pf_kdtree_t *t3 = pf_kdtree_from_layout(&lph, n);
        CHECK(t3 == NULL, "%s: from_layout must reject non-finite positions", what);
        pf_kdtree_destroy(&t3);
    }
    pf_kdtree_destroy(&t);
    free(input);
}

/* ---- pf_kdtree_from_layout ---- */

/* Tries a layout (copied) and reports whether it was accepted. */
static int s_accepts(const pf_photon_t *ph, size_t n)
{
    pf_photon_t *p = s_copy(ph, n * sizeof *ph);
    pf_kdtree_t *t = pf_kdtree_from_layout(&p, n);
    CHECK(p == NULL, "from_layout must take the array, also when it fails");
    int ok = t != NULL;
    pf_kdtree_destroy(&t);
    return ok;
}

/* The nodes of all ranges of exactly 3 photons in the subtree of [lo, hi). */
static size_t s_ranges_of_3(size_t lo, size_t hi, size_t *m_out, size_t count)
{
    if (hi - lo < 3 || count >= 512)
        return count;
    size_t m = lo + (hi - lo) / 2;
    if (hi - lo == 3) {
        m_out[count++] = m;
        return count;
    }
    count = s_ranges_of_3(lo, m, m_out, count);
    return s_ranges_of_3(m + 1, hi, m_out, count);
}

static void s_test_from_layout(void)
{
    size_t n = 1000;
    pf_photon_t *input = s_make_set(SET_UNIFORM, n);
    pf_kdtree_t *t = s_build_copy(input, n);
    const pf_photon_t *tp = pf_kdtree_photons(t);
    pf_photon_t *ph = s_copy(tp, n * sizeof *ph);
    CHECK(s_accepts(ph, n), "own layout");

    pf_photon_set_axis(&ph[417], 3);
    CHECK(pf_photon_axis(&ph[417]) == 3 && !s_accepts(ph, n), "axis 3");
    ph[417] = tp[417];
    /* The axis bits leave the normal's code alone, and the normal leaves
     * the axis alone. */
    pf_photon_t q = tp[417];
    pf_photon_set_axis(&q, 2);
    CHECK(pf_photon_axis(&q) == 2 && (q.normal & ~PF_PHOTON_AXIS_BITS) == (tp[417].normal & ~PF_PHOTON_AXIS_BITS),
          "axis bits");

    ph[123].pos[1] = NAN;
    CHECK(!s_accepts(ph, n), "NaN position");
    ph[123].pos[1] = INFINITY;
    CHECK(!s_accepts(ph, n), "infinite position");
    ph[123].pos[1] = -INFINITY;
    CHECK(!s_accepts(ph, n), "-infinite position");
    ph[123] = tp[123];

    /* Swap the root with the first photon, which lies strictly on the low side
     * of it on the root's axis (random coordinates are distinct). */
    size_t root = n / 2;
    unsigned ra = pf_photon_axis(&tp[root]);
    CHECK(tp[0].pos[ra] < tp[root].pos[ra], "test premise");
    memcpy(ph[0].pos, tp[root].pos, sizeof ph[0].pos);
    memcpy(ph[root].pos, tp[0].pos, sizeof ph[root].pos);
    CHECK(!s_accepts(ph, n), "swapped root and first photon");
    memcpy(ph, tp, n * sizeof *ph);

    /* Swap two siblings: the leaves either side of each node of a 3-photon
     * range. */
    size_t bottom[512];
    size_t nbottom = s_ranges_of_3(0, n, bottom, 0);
    CHECK(nbottom > 100, "test premise: %zu ranges of 3", nbottom);
    int rejected_all = 1;
    for (size_t b = 0; b < nbottom; b++) {
        size_t m = bottom[b], l = m - 1, r = m + 1;
        unsigned ma = pf_photon_axis(&tp[m]);
        if (tp[l].pos[ma] == tp[r].pos[ma])
            continue;
        /* Positions swapped, each record keeping its own (leaf) axis. */
        memcpy(ph[l].pos, tp[r].pos, sizeof ph[l].pos);
        memcpy(ph[r].pos, tp[l].pos, sizeof ph[r].pos);
        rejected_all &= !s_accepts(ph, n);
        ph[l] = tp[l];
        ph[r] = tp[r];
    }
    CHECK(rejected_all, "swapped sibling leaves");
    CHECK(s_accepts(ph, n), "restored layout");

    /* A leaf's axis does not matter: any value 0..2 is a valid layout. */
    pf_photon_set_axis(&ph[0], (pf_photon_axis(&tp[0]) + 1) % 3);
    CHECK(s_accepts(ph, n), "leaf with another axis");
    ph[0] = tp[0];

    /* Sizes the tree cannot index are refused before the arrays are read
     * (these are far shorter than the size claimed). */
    {
        pf_photon_t *bp = s_copy(ph, 4 * sizeof *bp);
        pf_kdtree_t *bt = pf_kdtree_from_layout(&bp, (size_t)1 << 31);
        CHECK(bt == NULL && bp == NULL, "n = 2^31");
        pf_kdtree_destroy(&bt);
    }

    free(ph);
    pf_kdtree_destroy(&t);
    free(input);

    /* Hand-made 7-photon layout: root 3 splits x at 0, node 1 splits y at 0
     * (leaves 0 and 2), node 5 splits y at 0 (leaves 4 and 6). Leaf 2 obeys
     * its parent but, at x = +1, not the root two levels up. */
    pf_photon_t h[7];
    uint8_t hax[7] = { 0, 1, 0, 0, 0, 1, 0 };
    float pos[7][3] = { { -1, -1, 0 }, { -2, 0, 0 }, { -1, 1, 0 }, { 0, 0, 0 }, { 1, -1, 0 }, { 2, 0, 0 }, { 1, 1, 0 } };
    memset(h, 0, sizeof h);
    for (int i = 0; i < 7; i++) {
        memcpy(h[i].pos, pos[i], sizeof pos[i]);
        pf_photon_set_axis(&h[i], hax[i]);
    }
    CHECK(s_accepts(h, 7), "hand layout");
    h[2].pos[0] = 1.0f;
    CHECK(!s_accepts(h, 7), "hand layout violating the grandparent");
    h[2].pos[0] = 0.0f; /* equal to the root's coordinate is allowed */
    CHECK(s_accepts(h, 7), "hand layout with a coordinate equal to the root's");
    h[4].pos[0] = 0.0f;
    CHECK(s_accepts(h, 7), "equal coordinates on both sides");
    h[4].pos[0] = -0.5f;
    CHECK(!s_accepts(h, 7), "right subtree below the root");

    /* Empty layouts, with or without arrays. */
    pf_photon_t *np = NULL;
    pf_kdtree_t *e = pf_kdtree_from_layout(&np, 0);
    CHECK(e && pf_kdtree_size(e) == 0 && pf_kdtree_knn(e, pf_v3s(0), 3, INFINITY, NULL) == 0,
          "empty layout");
    pf_kdtree_destroy(&e);
}

/* ---- the selection's heapsort fallback ----
 *
 * The build's selection falls back to heapsort when quickselect-style
 * partitioning overspends its work budget, which ordinary input never makes
 * it do. To run that path, a second copy of kdtree.c is compiled into this
 * test with a budget of one pass (so every large range is partly partitioned,
 * then heapsorted) and its public functions renamed. Since the layout is a
 * function of the input alone, its trees must be byte-identical to the
 * library's.
 *
 * The same copy runs the build's ways for short memory: its malloc fails the
 * calls numbered in s_malloc_fail (bit i: the i-th call since s_malloc_calls
 * was reset; the build's are items, permutation, axes, the photons' new
 * array, the tree), and those trees must be byte-identical too. */
static unsigned s_malloc_calls, s_malloc_fail;
static void *s_fallback_malloc(size_t size)
{
    unsigned call = s_malloc_calls++;
    return call < 32 && (s_malloc_fail >> call & 1u) ? NULL : malloc(size);
}
#define malloc s_fallback_malloc
#define PF_KDTREE_SELECT_BUDGET 1
#define pf_kdtree_build s_fallback_build
#define pf_kdtree_from_layout s_fallback_from_layout
#define pf_kdtree_destroy s_fallback_destroy
#define pf_kdtree_size s_fallback_size
#define pf_kdtree_photons s_fallback_photons
#define pf_kdtree_bounds s_fallback_bounds
#define pf_kdtree_knn s_fallback_knn
#define pf_kdtree_knn_heap s_fallback_knn_heap
#define pf_kdtree_radius s_fallback_radius
#define pf_kdtree_radius_upto s_fallback_radius_upto
#define pf_kdtree_nearest_normal s_fallback_nearest_normal
#define pf_kdtree_index_nearest s_fallback_index_nearest
#include "photon/kdtree.c"
#undef pf_kdtree_build
#undef pf_kdtree_from_layout
#undef pf_kdtree_destroy
#undef pf_kdtree_size
#undef pf_kdtree_photons
#undef pf_kdtree_bounds
#undef pf_kdtree_knn
#undef pf_kdtree_knn_heap
#undef pf_kdtree_radius
#undef pf_kdtree_radius_upto
#undef malloc

static void s_test_fallback(int kind, size_t n)
{
    pf_photon_t *input = s_make_set(kind, n);
    pf_kdtree_t *t = s_build_copy(input, n);
    /* Nothing failed; then no array for the permutation, or none for the
     * axes (it is packed into the items' memory), no new array for the
     * photons (they move in place), and both. */
    static const unsigned fail[] = { 0, 1u << 1, 1u << 2, 1u << 3, 1u << 1 | 1u << 3 };
    for (size_t i = 0; i < sizeof fail / sizeof fail[0]; i++) {
        pf_photon_t *ph = s_copy(input, n * sizeof *input);
        s_malloc_calls = 0;
        s_malloc_fail = fail[i];
        pf_kdtree_t *f = s_fallback_build(&ph, n);
        s_malloc_fail = 0;
        CHECK(t && f && memcmp(pf_kdtree_photons(t), s_fallback_photons(f), n * sizeof(pf_photon_t)) == 0,
              "%s n=%zu, malloc calls failed 0x%x: heapsort fallback builds another layout", s_set_names[kind], n,
              fail[i]);
        s_fallback_destroy(&f);
    }
    pf_kdtree_destroy(&t);
    free(input);
}

/* ---- edge cases ---- */

static void s_test_edges(void)
{
    /* Empty trees from build, with and without an array. */
    pf_photon_t *ph = NULL;
    pf_kdtree_t *t = pf_kdtree_build(&ph, 0);
    CHECK(t && pf_kdtree_size(t) == 0, "empty build from NULL");
    pf_knn_t out[4];
    CHECK(pf_kdtree_knn(t, pf_v3s(0), 4, INFINITY, out) == 0, "empty knn");
    CHECK(pf_kdtree_radius(t, pf_v3s(0), INFINITY, out, 4) == 0, "empty radius");
    pf_kdtree_destroy(&t);
    pf_kdtree_destroy(&t); /* NULL-safe */
    pf_kdtree_destroy(NULL);

    pf_photon_t *input = s_make_set(SET_UNIFORM, 100);
    t = s_build_copy(input, 100);
    /* k = 0, a NaN query and a NaN or negative radius find nothing. */
    CHECK(pf_kdtree_knn(t, pf_v3s(0), 0, INFINITY, NULL) == 0, "k = 0");
    CHECK(pf_kdtree_knn(t, pf_v3(NAN, 0, 0), 4, INFINITY, out) == 0, "NaN query");
    CHECK(pf_kdtree_knn(t, pf_v3s(0), 4, NAN, out) == 0, "NaN radius");
    CHECK(pf_kdtree_knn(t, pf_v3s(0), 4, -1.0f, out) == 0, "negative radius");
    CHECK(pf_kdtree_radius(t, pf_v3(0, NAN, 0), 1.0f, out, 4) == 0, "NaN radius query");
    CHECK(pf_kdtree_radius(t, pf_v3s(0), INFINITY, NULL, 0) == 100, "radius count without output");
    pf_kdtree_destroy(&t);
    free(input);
}

/* The build's top levels run as OpenMP tasks; the layout must not depend on
 * the thread count. Large enough to take the parallel path. */
static void s_test_threads(void)
{
    size_t n = 300000;
    pf_photon_t *input = s_make_set(SET_CLUSTERED, n);
    int saved = omp_get_max_threads();
    omp_set_num_threads(1);
    pf_kdtree_t *t1 = s_build_copy(input, n);
    omp_set_num_threads(4);
    pf_kdtree_t *t4 = s_build_copy(input, n);
    omp_set_num_threads(saved);
    CHECK(t1 && t4, "large builds");
    if (t1 && t4) {
        CHECK(memcmp(pf_kdtree_photons(t1), pf_kdtree_photons(t4), n * sizeof(pf_photon_t)) == 0,
              "1 and 4 threads build different layouts");
        s_check_layout(t4, input, n, "clustered n=300000");
        /* A few queries against brute force at this size. */
        pf_knn_t *all = malloc(n * sizeof *all), *out = malloc(64 * sizeof *out);
        for (int q = 0; q < 6; q++) {
            pf_vec3 x = pf_photon_pos(&input[s_next() % n]);
            x = pf_add(x, pf_v3(0.01f * s_gauss(), 0.01f * s_gauss(), 0.01f * s_gauss()));
            s_brute(t4, x, all);
            s_check_knn(t4, x, all, 50, INFINITY, out, "clustered n=300000");
            s_check_knn(t4, x, all, 64, all[20].d2, out, "clustered n=300000");
        }
        free(all);
        free(out);
    }
    pf_kdtree_destroy(&t1);
    pf_kdtree_destroy(&t4);
    free(input);

    /* Many coincident photons: selection must not go quadratic, and the
     * input order is kept. */
    n = 200000;
    input = s_make_set(SET_COINCIDENT, n);
    t1 = s_build_copy(input, n);
    int ok = t1 != NULL;
    for (size_t i = 0; ok && i < n; i++)
        ok = pf_kdtree_photons(t1)[i].dir == i;
    CHECK(ok, "200000 coincident photons keep their order");
    pf_kdtree_destroy(&t1);
    free(input);
}

/* pf_kdtree_nearest_normal against a scan: photons get normals among the
 * six axes (and a few random ones); the answer must be the (d2, index)
 * minimum over photons within max_r2 whose normal agrees. With indexed, the
 * tree first gets its nearest-point grid (pf_kdtree_index_nearest), which
 * answers most queries near the photons itself and must agree exactly. */
static void s_test_nearest_normal(int kind, size_t n, int nq, int indexed)
{
    static const pf_vec3 axes6[6] = { { 1, 0, 0 }, { -1, 0, 0 }, { 0, 1, 0 }, { 0, -1, 0 }, { 0, 0, 1 }, { 0, 0, -1 } };
    pf_photon_t *input = s_make_set(kind, n);
    for (size_t i = 0; i < n; i++)
        input[i].normal = pf_oct_encode(i % 7 == 6 ? pf_norm(pf_v3(s_uniform() - 0.5f, s_uniform() - 0.5f, 0.3f))
                                                   : axes6[s_next() % 6]);
    pf_kdtree_t *t = s_build_copy(input, n);
    if (indexed)
        CHECK(pf_kdtree_index_nearest(t) == PF_OK, "index_nearest failed");
    const pf_photon_t *ph = pf_kdtree_photons(t);
    int ok = 1;
    for (int q = 0; q < nq; q++) {
        pf_vec3 x = pf_v3(s_uniform() * 2.4f - 1.2f, s_uniform() * 2.4f - 1.2f, s_uniform() * 2.4f - 1.2f);
        if (n && q % 3 == 0)
            x = pf_photon_pos(&ph[s_next() % n]);
        if (n && q % 3 == 1) /* near a photon: where the grid answers */
            x = pf_add(pf_photon_pos(&ph[s_next() % n]),
                       pf_scale(pf_v3(s_uniform() - 0.5f, s_uniform() - 0.5f, s_uniform() - 0.5f), 0.02f));
        pf_vec3 nn = axes6[s_next() % 6];
        float min_cos = q % 2 ? 0.7f : 0.99f;
        float r2 = q % 5 == 0 ? INFINITY : 0.3f * s_uniform();
        pf_knn_t best = { UINT32_MAX, INFINITY };
        int want = 0;
        for (size_t i = 0; i < n; i++) {
            double dx = x.x - ph[i].pos[0], dy = x.y - ph[i].pos[1], dz = x.z - ph[i].pos[2];
            float d2 = (float)(dx * dx + dy * dy + dz * dz);
            if (d2 > r2 || pf_dot(pf_photon_normal(&ph[i]), nn) < min_cos)
                continue;
            if (!want || d2 < best.d2 || (d2 == best.d2 && i < best.index)) {
                best = (pf_knn_t){ (uint32_t)i, d2 };
                want = 1;
            }
        }
        pf_knn_t got = { 0, 0 };
        int found = pf_kdtree_nearest_normal(t, x, nn, min_cos, r2, &got);
        if (found != want || (want && (got.index != best.index || got.d2 != best.d2))) {
            ok = 0;
            printf("nearest_normal %s n=%zu query %d: got %d (%u, %g), want %d (%u, %g)\n", s_set_names[kind], n, q,
                   found, got.index, got.d2, want, best.index, best.d2);
            break;
        }
    }
    CHECK(ok, "%s n=%zu%s: nearest with normal filter differs from a scan", s_set_names[kind], n,
          indexed ? " (indexed)" : "");
    pf_kdtree_destroy(&t);
    free(input);
}

/* pf_pm_irradiance_hint gives exactly pf_pm_irradiance's estimate and radius
 * (and pf_pm_irradiance_cone with a hint exactly its own without) whatever
 * the hint: too small (a second search), the k-th photon's own
 * distance (the inclusive edge), larger, max_r2 itself (fewer than k
 * expected), none. */
static void s_test_irradiance_hint(int kind, size_t n, int nq)
{
    pf_photon_t *input = s_make_set(kind, n);
    for (size_t i = 0; i < n; i++) {
        input[i].normal = pf_oct_encode(i % 5 == 4 ? pf_v3(0, 0, -1) : pf_v3(0, 0, 1));
        input[i].power[0] = s_uniform();
        input[i].power[1] = s_uniform();
        input[i].power[2] = 1.0f;
    }
    pf_kdtree_t *t = s_build_copy(input, n);
    const pf_photon_t *ph = pf_kdtree_photons(t);
    static pf_pm_scratch_t scratch_mem;
    pf_pm_scratch_t *scratch = &scratch_mem;
    int bad = 0;
    const int ks[4] = { 1, 2, 8, 100 };
    for (int q = 0; q < nq; q++) {
        pf_vec3 x = n && q % 2 ? pf_photon_pos(&ph[s_next() % n])
                               : pf_v3(s_uniform() * 2.4f - 1.2f, s_uniform() * 2.4f - 1.2f, s_uniform() * 2.4f - 1.2f);
        for (int ki = 0; ki < 4; ki++) {
            for (int mi = 0; mi < 2; mi++) {
                float max_r2 = mi ? 0.05f : INFINITY, r2 = 0.0f;
                pf_vec3 e = pf_pm_irradiance(t, x, pf_v3(0, 0, 1), ks[ki], max_r2, scratch, &r2);
                float hints[8] = { 0.0f, 1e-12f, 0.5f * r2, r2, nextafterf(r2, INFINITY), 4.0f * r2, INFINITY, max_r2 };
                for (int h = 0; h < 8; h++) {
                    float r2h = -1.0f;
                    pf_vec3 eh = pf_pm_irradiance_hint(t, x, pf_v3(0, 0, 1), ks[ki], max_r2, hints[h], scratch, &r2h);
                    bad += memcmp(&e, &eh, sizeof e) != 0 || memcmp(&r2, &r2h, sizeof r2) != 0;
                    float r2c = -1.0f, r2ch = -1.0f;
                    pf_vec3 ec = pf_pm_irradiance_cone(t, x, pf_v3(0, 0, 1), ks[ki], max_r2, max_r2, scratch, &r2c);
                    pf_vec3 ech = pf_pm_irradiance_cone(t, x, pf_v3(0, 0, 1), ks[ki], max_r2, hints[h], scratch, &r2ch);
                    bad += memcmp(&ec, &ech, sizeof ec) != 0 || memcmp(&r2c, &r2ch, sizeof r2c) != 0;
                }
            }
        }
    }
    CHECK(bad == 0, "irradiance with a hint: %d of %d estimates differ from the search without one (set %d, n %zu)",
          bad, nq * 4 * 2 * 8 * 2, kind, n);
    pf_kdtree_destroy(&t);
    free(input);
}

int main(void)
{
    for (size_t n = 0; n <= 64; n++)
        s_test_set(SET_UNIFORM, n, 20);
    s_test_set(SET_UNIFORM, 1000, 60);
    s_test_set(SET_UNIFORM, 4000, 40);
    size_t small[] = { 1, 2, 3, 5, 17, 64 };
    for (int kind = SET_CLUSTERED; kind <= SET_LINE; kind++)
        for (size_t i = 0; i < sizeof small / sizeof small[0]; i++)
            s_test_set(kind, small[i], 10);
    s_test_set(SET_CLUSTERED, 3000, 40);
    s_test_set(SET_COINCIDENT, 2000, 10);
    s_test_set(SET_HALF_COINCIDENT, 2000, 40);
    s_test_set(SET_TINY, 1500, 40);
#ifdef __SSE2__
    /* Rendering threads flush denormals to zero; then the tiny set's squared
     * distances (about 1e-40) mostly become 0 and tie, and the index decides. */
    unsigned int csr = _mm_getcsr();
    _MM_SET_FLUSH_ZERO_MODE(_MM_FLUSH_ZERO_ON);
    _MM_SET_DENORMALS_ZERO_MODE(_MM_DENORMALS_ZERO_ON);
    s_test_set(SET_TINY, 64, 20);
    s_test_set(SET_TINY, 1500, 40);
    _mm_setcsr(csr);
#endif
    s_test_set(SET_GRID, 2500, 40);
    s_test_set(SET_LINE, 1000, 20);
    size_t nonfinite[] = { 2, 4, 5, 12, 13, 40, 64, 1000 };
    for (size_t i = 0; i < sizeof nonfinite / sizeof nonfinite[0]; i++)
        s_test_nonfinite(nonfinite[i]);
    s_test_fallback(SET_UNIFORM, 5000);
    s_test_fallback(SET_CLUSTERED, 3000);
    s_test_fallback(SET_GRID, 3000);
    s_test_fallback(SET_COINCIDENT, 1000);
    for (int indexed = 0; indexed <= 1; indexed++) {
        for (size_t n = 0; n <= 70; n += 7)
            s_test_nearest_normal(SET_UNIFORM, n, 200, indexed);
        s_test_nearest_normal(SET_UNIFORM, 3000, 400, indexed);
        s_test_nearest_normal(SET_UNIFORM, 20000, 2000, indexed);
        s_test_nearest_normal(SET_CLUSTERED, 2000, 400, indexed);
        s_test_nearest_normal(SET_COINCIDENT, 500, 100, indexed);
        s_test_nearest_normal(SET_HALF_COINCIDENT, 2000, 400, indexed);
        s_test_nearest_normal(SET_TINY, 1500, 300, indexed);
        s_test_nearest_normal(SET_GRID, 2500, 300, indexed);
        s_test_nearest_normal(SET_LINE, 1000, 300, indexed);
    }
    s_test_irradiance_hint(SET_UNIFORM, 5000, 300);
    s_test_irradiance_hint(SET_CLUSTERED, 3000, 300);
    s_test_irradiance_hint(SET_COINCIDENT, 500, 100);
    s_test_irradiance_hint(SET_GRID, 2500, 200);
    s_test_edges();
    s_test_from_layout();
    s_test_threads();
    printf("%d passed, %d failed\n", s_passed, s_failed);
    return s_failed ? 1 : 0;
}
