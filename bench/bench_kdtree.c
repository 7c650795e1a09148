/* bench_kdtree.c: build and query timings for the photon kd-tree, by hand,
 * not a test. For each size (default 1M and 10M random photons in a unit
 * cube) it prints the build time with one thread and with all threads,
 * whether the two layouts are identical, and k-nearest and radius query rates
 * on all threads, for random and for coherent query points.
 *
 * Usage: bench_kdtree [n ...] */
#include <omp.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "base/log.h"
#include "base/rng.h"
#include "photon/kdtree.h"

static pf_photon_t *s_random_photons(size_t n)
{
    pf_photon_t *ph = malloc(n * sizeof *ph);
    if (!ph)
        return NULL;
    for (size_t i = 0; i < n; i++) {
        pf_rng_t r = pf_rng_make(1, PF_STREAM_TEST, i, 0);
        memset(&ph[i], 0, sizeof ph[i]);
        for (int a = 0; a < 3; a++)
            ph[i].pos[a] = pf_rng_float(&r);
        ph[i].dir = (uint32_t)i;
    }
    return ph;
}

static pf_kdtree_t *s_timed_build(size_t n, int threads, double *seconds)
{
    pf_photon_t *ph = s_random_photons(n);
    if (!ph)
        return NULL;
    omp_set_num_threads(threads);
    double t0 = pf_now();
    pf_kdtree_t *t = pf_kdtree_build(&ph, n);
    *seconds = pf_now() - t0;
    return t;
}

static void s_bench(size_t n)
{
    int threads = omp_get_num_procs();
    double t1, tn;
    pf_kdtree_t *a = s_timed_build(n, 1, &t1);
    pf_kdtree_t *b = s_timed_build(n, threads, &tn);
    if (!a || !b) {
        fprintf(stderr, "out of memory at n = %zu\n", n);
        exit(1);
    }
    int same = memcmp(pf_kdtree_photons(a), pf_kdtree_photons(b), n * sizeof(pf_photon_t)) == 0;
    printf("n = %zu: build %.3f s on 1 thread, %.3f s on %d threads (layouts %s)\n", n, t1, tn, threads,
           same ? "identical" : "DIFFER");
    pf_kdtree_destroy(&a);

    /* Queries at random points, and coherent queries as a tile renderer
     * makes them (near photons taken in tree order, which is spatially
     * ordered), k = 50 and a radius that holds about 50 photons. */
    const int nq = 400000, k = 50;
    float r2 = powf(50.0f / (float)n * 3.0f / (4.0f * PF_PI), 2.0f / 3.0f);
    const pf_photon_t *tp = pf_kdtree_photons(b);
    for (int coherent = 0; coherent < 2; coherent++) {
        double found[2] = { 0, 0 }, seconds[2];
        for (int radius = 0; radius < 2; radius++) {
            double found_here = 0, q0 = pf_now();
#pragma omp parallel reduction(+ : found_here)
            {
                pf_knn_t out[256];
#pragma omp for schedule(static)
                for (int q = 0; q < nq; q++) {
                    pf_rng_t r = pf_rng_make(2, PF_STREAM_TEST, (uint64_t)q, 0);
                    pf_vec3 x = pf_v3(pf_rng_float(&r), pf_rng_float(&r), pf_rng_float(&r));
                    if (coherent) {
                        pf_vec3 jitter = pf_scale(pf_sub(x, pf_v3s(0.5f)), 0.01f);
                        x = pf_add(pf_photon_pos(&tp[(size_t)q * n / (size_t)nq]), jitter);
                    }
                    found_here += (double)(radius ? pf_kdtree_radius(b, x, r2, out, 256)
                                                  : pf_kdtree_knn(b, x, (size_t)k, INFINITY, out));
                }
            }
            seconds[radius] = pf_now() - q0;
            found[radius] = found_here / nq;
        }
        printf("  %s queries: knn k=%d %.3f M/s; radius (mean %.1f found) %.3f M/s\n",
               coherent ? "coherent" : "random", k, nq / seconds[0] * 1e-6, found[1], nq / seconds[1] * 1e-6);
    }
    pf_kdtree_destroy(&b);
}

int main(int argc, char **argv)
{
    if (argc > 1) {
        for (int i = 1; i < argc; i++)
            s_bench((size_t)strtoull(argv[i], NULL, 10));
    } else {
        s_bench(1000000);
        s_bench(10000000);
    }
    return 0;
}
