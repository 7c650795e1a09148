/* bench_photons.c: the photon maps' build and irradiance precomputation at a
 * large photon count, timed apart from the trace (the goal: 10M
 * photons built and precomputed in 5 s on 2 cores, 32 bytes per photon).
 *
 * Traces the scene's global photons once (default: cornell-box, 10M emitted,
 * no caustic photons, all threads), then repeats on the same photons: shuffle
 * a copy into a fixed pseudo-random order (the tracer's output order is by
 * photon, spatially random, unlike a built tree's), build the kd-tree, and
 * precompute irradiance as a render does (pf_irradiance_points_stride,
 * global_k nearest). Prints each repetition
 * and the best, and the bytes per photon the built tree holds. Not a test.
 *
 * usage: bench_photons [scene.json] [photons] [repetitions] */
#include <omp.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "base/rng.h"
#include "bench/bench_setup.h"
#include "photon/irradiance.h"

int main(int argc, char **argv)
{
    const char *path = argc > 1 ? argv[1] : "scenes/cornell-box/scene.json";
    unsigned long long photons = argc > 2 ? strtoull(argv[2], NULL, 10) : 10000000ull;
    int reps = argc > 3 ? atoi(argv[3]) : 3;
    pf_frame_t b = bench_load(path);
    pf_settings_t s = b.scene->settings;
    s.photons = photons;
    s.caustic_photons = 0;
    int threads = omp_get_num_procs();
    s.threads = threads;
    pf_photon_stats_t st;
    bench_photon_pass(&b, &s, &st);
    pf_photon_maps_t *maps = &b.maps;
    size_t n = pf_kdtree_size(maps->global);
    float r2 = maps->global_r2;
    size_t stride = pf_irradiance_points_stride(n, &s);
    printf("scene %s, %llu photons emitted, %zu stored, %llu irradiance points (stride %zu, k %d), %d threads\n",
           path, photons, n, (unsigned long long)st.irradiance_points, stride, s.global_k, threads);
    printf("photon pass as rendered: trace %.2f s, kd-trees %.2f s, irradiance %.2f s\n", st.trace_s, st.build_s,
           st.irradiance_s);
    pf_photon_t *shuffled = malloc(n * sizeof *shuffled);
    if (!shuffled)
        return 1;
    memcpy(shuffled, pf_kdtree_photons(maps->global), n * sizeof *shuffled);
    pf_rng_t rng = pf_rng_make(3, PF_STREAM_TEST, 0, 0);
    for (size_t i = n; i > 1; i--) {
        size_t j = (size_t)(pf_rng_float(&rng) * (float)i) % i;
        pf_photon_t t = shuffled[i - 1];
        shuffled[i - 1] = shuffled[j];
        shuffled[j] = t;
    }
    double best_b = 1e30, best_i = 1e30, best_sum = 1e30;
    for (int r = 0; r < reps; r++) {
        pf_photon_t *copy = malloc(n * sizeof *copy);
        if (!copy)
            return 1;
        memcpy(copy, shuffled, n * sizeof *copy);
        double t0 = pf_now();
        pf_kdtree_t *tree = pf_kdtree_build(&copy, n);
        double t1 = pf_now();
        pf_kdtree_t *irr = NULL;
        if (!tree || pf_irradiance_precompute(tree, (int)stride, s.global_k, r2, 1.0f, b.accel, threads, &irr) != PF_OK)
            return 1;
        double t2 = pf_now();
        printf("repetition %d: kd-tree %.2f s, irradiance %.2f s, sum %.2f s\n", r + 1, t1 - t0, t2 - t1, t2 - t0);
        best_b = t1 - t0 < best_b ? t1 - t0 : best_b;
        best_i = t2 - t1 < best_i ? t2 - t1 : best_i;
        best_sum = t2 - t0 < best_sum ? t2 - t0 : best_sum;
        pf_kdtree_destroy(&irr);
        pf_kdtree_destroy(&tree);
    }
    printf("best: kd-tree %.2f s, irradiance %.2f s, build + irradiance %.2f s (goal <= 5 s); the tree holds %zu "
           "bytes per photon\n",
           best_b, best_i, best_sum, sizeof(pf_photon_t));
    free(shuffled);
    pf_frame_close(&b);
    return 0;
}
