/* stress_kdtree.c: the kd-tree at its extremes (the kdtree stress group):
 * 0, 1 and 2 photons, a million photons at one point, and 20 M random
 * photons (4 M under AddressSanitizer) against brute force, with the build
 * time, memory per photon and query rates printed. The large cases fill and
 * query the tree from OpenMP threads. */
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <sys/resource.h>
#include <unistd.h>

#include "base/log.h"
#include "base/rng.h"

#include "stress.h"

/* ------------------------------------------------------------------------ */
/* kd-tree extremes                                                          */
/* ------------------------------------------------------------------------ */

/* Squared distance as kdtree.c computes it (float differences, squares
 * summed in double, one rounding), so results compare bit for bit. */
static float s_d2(const pf_photon_t *p, pf_vec3 x)
{
    float dx = p->pos[0] - x.x, dy = p->pos[1] - x.y, dz = p->pos[2] - x.z;
    return (float)((double)dx * dx + (double)dy * dy + (double)dz * dz);
}

/* A photon array of n (at least one element, so the build always gets a
 * malloc'd pointer). */
static pf_photon_t *s_photons(size_t n)
{
    pf_photon_t *p = calloc(n ? n : 1, sizeof *p);
    PF_CHECK(p != NULL);
    return p;
}

static void s_set(pf_photon_t *p, float x, float y, float z, pf_vec3 n)
{
    p->pos[0] = x, p->pos[1] = y, p->pos[2] = z;
    p->power[0] = p->power[1] = p->power[2] = 1.0f;
    p->normal = pf_oct_encode(n);
}

/* Brute-force k nearest within max_r2 by (d2, tree index): checks the
 * tree's answer entry by entry. Returns 1 when equal. */
static int s_knn_matches(const pf_kdtree_t *t, pf_vec3 x, size_t k, float max_r2)
{
    size_t n = pf_kdtree_size(t);
    const pf_photon_t *ph = pf_kdtree_photons(t);
    pf_knn_t *got = malloc((k ? k : 1) * sizeof *got), *best = malloc((k + 1) * sizeof *best);
    PF_CHECK(got && best);
    size_t ng = pf_kdtree_knn(t, x, k, max_r2, got), nb = 0;
    /* Insertion into a sorted list of at most k; a scan in tree order means
     * a later index never displaces an equal distance. */
    for (size_t i = 0; i < n; i++) {
        float d2 = s_d2(&ph[i], x);
        if (!(d2 <= max_r2))
            continue;
        if (nb == k && !(d2 < best[k - 1].d2))
            continue;
        size_t j = nb < k ? nb++ : k - 1;
        while (j > 0 && best[j - 1].d2 > d2) {
            best[j] = best[j - 1];
            j--;
        }
        best[j] = (pf_knn_t){ (uint32_t)i, d2 };
    }
    int ok = ng == nb;
    for (size_t i = 0; ok && i < nb; i++)
        ok = got[i].index == best[i].index && got[i].d2 == best[i].d2;
    free(got);
    free(best);
    return ok;
}

/* Brute-force radius count. */
static size_t s_radius_count(const pf_kdtree_t *t, pf_vec3 x, float r2)
{
    size_t n = pf_kdtree_size(t), c = 0;
    const pf_photon_t *ph = pf_kdtree_photons(t);
    for (size_t i = 0; i < n; i++)
        c += s_d2(&ph[i], x) <= r2;
    return c;
}

/* Brute-force nearest with an agreeing normal; returns the index or -1. */
static long s_nearest_normal(const pf_kdtree_t *t, pf_vec3 x, pf_vec3 nrm, float min_cos, float max_r2)
{
    size_t n = pf_kdtree_size(t);
    const pf_photon_t *ph = pf_kdtree_photons(t);
    long best = -1;
    float bd = INFINITY;
    for (size_t i = 0; i < n; i++) {
        float d2 = s_d2(&ph[i], x);
        if (!(d2 <= max_r2) || pf_dot(pf_photon_normal(&ph[i]), nrm) < min_cos)
            continue;
        if (d2 < bd) {
            bd = d2;
            best = (long)i;
        }
    }
    return best;
}

static long s_rss_kb(void)
{
    long pages = 0, rss = 0;
    FILE *f = fopen("/proc/self/statm", "r");
    if (f) {
        if (fscanf(f, "%ld %ld", &pages, &rss) != 2)
            rss = 0;
        fclose(f);
    }
    return rss * (sysconf(_SC_PAGESIZE) / 1024);
}

static long s_peak_kb(void)
{
    struct rusage ru;
    getrusage(RUSAGE_SELF, &ru);
    return ru.ru_maxrss;
}

static void s_kdtree_tiny(void)
{
    const pf_vec3 up = pf_v3(0, 0, 1), down = pf_v3(0, 0, -1);
    pf_knn_t out[8];
    /* 0 photons: every query finds nothing, bounds are empty. */
    pf_photon_t *p = s_photons(0);
    pf_kdtree_t *t = pf_kdtree_build(&p, 0);
    CHECK(t != NULL && p == NULL, "empty tree");
    if (t) {
        pf_vec3 lo, hi;
        pf_kdtree_bounds(t, &lo, &hi);
        CHECK(pf_kdtree_size(t) == 0 && lo.x > hi.x, "empty tree: size and bounds");
        CHECK(pf_kdtree_knn(t, pf_v3(0, 0, 0), 4, INFINITY, out) == 0, "empty tree: knn");
        CHECK(pf_kdtree_radius(t, pf_v3(0, 0, 0), INFINITY, out, 8) == 0, "empty tree: radius");
        CHECK(pf_kdtree_nearest_normal(t, pf_v3(0, 0, 0), up, -1.0f, INFINITY, out) == 0, "empty tree: nearest");
    }
    pf_kdtree_destroy(&t);
    CHECK(t == NULL, "destroy nulls the pointer");

    /* 1 photon: found within the radius (inclusive), not beyond; the normal
     * filter applies. */
    p = s_photons(1);
    s_set(&p[0], 1, 2, 3, up);
    t = pf_kdtree_build(&p, 1);
    CHECK(t != NULL, "one-photon tree");
    if (t) {
        pf_vec3 x = pf_v3(1, 2, 5); /* d2 = 4 exactly */
        size_t k = pf_kdtree_knn(t, x, 4, INFINITY, out);
        CHECK(k == 1 && out[0].index == 0 && out[0].d2 == 4.0f, "one photon: knn %zu", k);
        CHECK(pf_kdtree_knn(t, x, 4, 4.0f, out) == 1, "one photon: knn at exactly the radius");
        CHECK(pf_kdtree_knn(t, x, 4, nextafterf(4.0f, 0.0f), out) == 0, "one photon: knn just inside the radius");
        CHECK(pf_kdtree_knn(t, x, 0, INFINITY, out) == 0, "one photon: k = 0");
        CHECK(pf_kdtree_radius(t, x, 4.0f, out, 8) == 1 && pf_kdtree_radius(t, x, 3.9f, out, 8) == 0,
              "one photon: radius");
        CHECK(pf_kdtree_radius(t, x, 4.0f, out, 0) == 1, "one photon: radius counts past cap 0");
        CHECK(pf_kdtree_nearest_normal(t, x, up, 0.7f, INFINITY, out) == 1 && out[0].d2 == 4.0f,
              "one photon: nearest with an agreeing normal");
        CHECK(pf_kdtree_nearest_normal(t, x, down, 0.7f, INFINITY, out) == 0,
              "one photon: nearest with an opposite normal");
        CHECK(pf_kdtree_knn(t, pf_v3(NAN, 0, 0), 4, INFINITY, out) == 0, "one photon: NaN query finds nothing");
    }
    pf_kdtree_destroy(&t);

    /* 2 photons: ordered by distance; at equal distance by tree index. */
    p = s_photons(2);
    s_set(&p[0], 0, 0, 0, up);
    s_set(&p[1], 2, 0, 0, down);
    t = pf_kdtree_build(&p, 2);
    CHECK(t != NULL, "two-photon tree");
    if (t) {
        const pf_photon_t *tp = pf_kdtree_photons(t);
        size_t k = pf_kdtree_knn(t, pf_v3(0.5f, 0, 0), 2, INFINITY, out);
        CHECK(k == 2 && out[0].d2 == 0.25f && out[1].d2 == 2.25f && tp[out[0].index].pos[0] == 0.0f,
              "two photons: knn order");
        k = pf_kdtree_knn(t, pf_v3(1, 0, 0), 2, INFINITY, out); /* equidistant */
        CHECK(k == 2 && out[0].d2 == 1.0f && out[1].d2 == 1.0f && out[0].index < out[1].index,
              "two photons: the tie goes to the lower tree index");
        CHECK(pf_kdtree_knn(t, pf_v3(1, 0, 0), 1, INFINITY, out) == 1 && out[0].index == 0,
              "two photons: k = 1 on a tie takes tree index 0");
        CHECK(pf_kdtree_nearest_normal(t, pf_v3(0.1f, 0, 0), down, 0.7f, INFINITY, out) == 1 &&
                  tp[out[0].index].pos[0] == 2.0f,
              "two photons: the normal filter skips the nearer photon");
        CHECK(pf_kdtree_radius(t, pf_v3(1, 0, 0), 1.0f, out, 8) == 2, "two photons: both on the radius");
    }
    pf_kdtree_destroy(&t);
}

/* n photons all at one point: the build must not degrade (ties are broken by
 * index, not by recursion that never splits), and queries see them all. */
static void s_kdtree_coincident(size_t n)
{
    pf_photon_t *p = s_photons(n);
    for (size_t i = 0; i < n; i++)
        s_set(&p[i], 0.25f, -0.5f, 0.75f, pf_v3(0, 1, 0));
    double t0 = pf_now();
    pf_kdtree_t *t = pf_kdtree_build(&p, n);
    double build = pf_now() - t0;
    CHECK(t != NULL, "coincident tree");
    if (!t)
        return;
    pf_knn_t *out = malloc(n * sizeof *out);
    PF_CHECK(out != NULL);
    pf_vec3 at = pf_v3(0.25f, -0.5f, 0.75f);
    t0 = pf_now();
    size_t k = pf_kdtree_knn(t, at, 100, INFINITY, out);
    int order = k == 100;
    for (size_t i = 0; order && i < k; i++)
        order = out[i].d2 == 0.0f && out[i].index == i;
    size_t r = pf_kdtree_radius(t, at, 0.0f, out, n);
    size_t r_off = pf_kdtree_radius(t, pf_v3(0.25f, -0.5f, 0.5f), 0.0625f, out, n);
    pf_knn_t nn;
    int found = pf_kdtree_nearest_normal(t, at, pf_v3(0, 1, 0), 0.7f, INFINITY, &nn);
    int none = pf_kdtree_nearest_normal(t, at, pf_v3(0, -1, 0), 0.7f, INFINITY, &nn);
    double query = pf_now() - t0;
    printf("kd-tree, %zu photons at one point: build %.3f s, knn/radius/nearest %.3f s\n", n, build, query);
    CHECK(order, "coincident: knn(100) must be tree indices 0..99 at d2 0 (got %zu)", k);
    CHECK(r == n && r_off == n, "coincident: radius found %zu and %zu of %zu", r, r_off, n);
    CHECK(found == 1 && !none, "coincident: nearest_normal");
    CHECK(s_knn_matches(t, pf_v3(0, 0, 0), 7, INFINITY), "coincident: knn against brute force");
    free(out);
    pf_kdtree_destroy(&t);
}

/* A large tree of random photons (normals random up or down): build time,
 * memory per photon, query rates, and queries against brute force. */
static void s_kdtree_large(size_t n)
{
    long rss0 = s_rss_kb();
    pf_photon_t *p = malloc(n * sizeof *p);
    CHECK(p != NULL, "cannot allocate %zu photons", n);
    if (!p)
        return;
    const pf_vec3 up = pf_v3(0, 0, 1), down = pf_v3(0, 0, -1);
#pragma omp parallel for schedule(static)
    for (size_t i = 0; i < n; i++) {
        pf_rng_t r = pf_rng_make(7, PF_STREAM_TEST, i, 0);
        float x = pf_rng_float(&r), y = pf_rng_float(&r), z = pf_rng_float(&r);
        s_set(&p[i], x, y, z, pf_rng_float(&r) < 0.5f ? up : down);
        p[i].dir = (uint32_t)i;
    }
    long rss_in = s_rss_kb();
    double t0 = pf_now();
    pf_kdtree_t *t = pf_kdtree_build(&p, n);
    double build = pf_now() - t0;
    long rss_tree = s_rss_kb(), peak = s_peak_kb();
    CHECK(t != NULL, "%zu-photon tree", n);
    if (!t)
        return;
    double held = (double)sizeof(pf_photon_t); /* the layout: the records, split axes inside */
    printf("kd-tree, %zu random photons: build %.2f s (%.1f M photons/s); the tree holds %.0f bytes per photon "
           "(%.0f MB); resident %.1f bytes per photon after the build, peak during it %.1f bytes per photon "
           "(input included)\n",
           n, build, n / build * 1e-6, held, held * (double)n / 1e6, (rss_tree - rss0) * 1024.0 / (double)n,
           (peak - rss0) * 1024.0 / (double)n);
    (void)rss_in;
    /* Queries against brute force (each scan reads the whole tree). */
    int knn_ok = 1, radius_ok = 1, nearest_ok = 1;
    for (int q = 0; q < 4; q++) {
        pf_rng_t r = pf_rng_make(9, PF_STREAM_TEST, (uint64_t)q, 0);
        pf_vec3 x = pf_v3(pf_rng_float(&r), pf_rng_float(&r), pf_rng_float(&r));
        if (q == 3)
            x = pf_v3(-0.01f, 0.5f, 1.0f); /* just outside the cloud */
        knn_ok &= s_knn_matches(t, x, 100, INFINITY);
        float r2 = 1e-4f;
        pf_knn_t tmp[1];
        radius_ok &= pf_kdtree_radius(t, x, r2, tmp, 0) == s_radius_count(t, x, r2);
        pf_knn_t nn;
        int got = pf_kdtree_nearest_normal(t, x, down, 0.7f, 1e-3f, &nn);
        long want = s_nearest_normal(t, x, down, 0.7f, 1e-3f);
        nearest_ok &= (want < 0 && !got) || (got && nn.index == (uint32_t)want);
    }
    CHECK(knn_ok, "%zu photons: knn differs from brute force", n);
    CHECK(radius_ok, "%zu photons: radius count differs from brute force", n);
    CHECK(nearest_ok, "%zu photons: nearest_normal differs from brute force", n);
    /* Query rate, as the irradiance precompute uses it (k = 100). */
    const int nq = 20000;
    t0 = pf_now();
    size_t found = 0;
#pragma omp parallel reduction(+ : found)
    {
        pf_knn_t out[100];
#pragma omp for schedule(static)
        for (int q = 0; q < nq; q++) {
            pf_rng_t r = pf_rng_make(11, PF_STREAM_TEST, (uint64_t)q, 0);
            pf_vec3 x = pf_v3(pf_rng_float(&r), pf_rng_float(&r), pf_rng_float(&r));
            found += pf_kdtree_knn(t, x, 100, INFINITY, out);
        }
    }
    double qs = pf_now() - t0;
    printf("kd-tree, %zu photons: %d knn(100) queries in %.2f s (%.0f k queries/s)\n", n, nq, qs, nq / qs * 1e-3);
    CHECK(found == (size_t)nq * 100, "knn(100) returned %zu results for %d queries", found, nq);
    pf_kdtree_destroy(&t);
}

void stress_test_kdtree(void)
{
    s_kdtree_tiny();
    s_kdtree_coincident(1000000);
#if defined(__SANITIZE_ADDRESS__)
    printf("AddressSanitizer build: the large kd-tree case uses 4 M photons instead of 20 M\n");
    s_kdtree_large(4000000);
#else
    s_kdtree_large(20000000);
#endif
}

