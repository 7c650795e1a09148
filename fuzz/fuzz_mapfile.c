/* fuzz_mapfile.c: libFuzzer target for the photon-map deserializer
 * (photon/mapfile.c) and the kd-tree layout check behind it
 * (pf_kdtree_from_layout).
 *
 * The blob carries a content hash over its header and body, which random
 * mutations almost never keep right; so each input is read twice: once as
 * it is (covering the header checks and the hash comparison), and once with
 * the hash recomputed over the mutated bytes and the job's expected scene and
 * settings hashes taken from the header, so that mutations reach the
 * per-photon checks and the kd ordering, the part a hostile peer with a
 * correct hash would attack.
 *
 * Oracles for accepted maps: k-nearest, radius and normal-filtered queries
 * (what the worker's estimates do) stay within the arrays and return at most
 * what was asked; the k nearest equal a brute-force scan's, so the layout
 * check lets through no tree that answers wrongly; and the maps write and
 * read back.
 *
 * One thread; the regression driver and libFuzzer call it in a loop. */
#include <math.h>
#include <stddef.h>
#include <stdint.h>
#include <stdlib.h>
#include <string.h>

#include "base/hash.h"
#include "fuzz/fuzz_util.h"
#include "photon/mapfile.h"
#include "photon/photonmap.h"

int LLVMFuzzerTestOneInput(const uint8_t *data, size_t size);

#define S_HASH_OFFSET 148
#define S_HEADER 156

static uint64_t s_u64_at(const uint8_t *p)
{
    uint64_t v = 0;
    for (int i = 7; i >= 0; i--)
        v = v << 8 | p[i];
    return v;
}

/* The kd-tree's squared distance (float differences, summed in double,
 * rounded once; see kdtree.c), so that the brute force agrees to the bit. */
static float s_dist2(const float q[3], const float p[3])
{
    double dx = q[0] - p[0], dy = q[1] - p[1], dz = q[2] - p[2];
    return (float)(dx * dx + dy * dy + dz * dz);
}

/* The k nearest photons to q by (d2, index), by looking at every one. */
static size_t s_brute_knn(const pf_photon_t *ph, size_t n, const float q[3], size_t k, pf_knn_t *out)
{
    size_t m = 0;
    for (size_t i = 0; i < n; i++) {
        pf_knn_t c = { (uint32_t)i, s_dist2(q, ph[i].pos) };
        size_t j = m < k ? m++ : k;
        if (j == k && !(c.d2 < out[k - 1].d2 || (c.d2 == out[k - 1].d2 && c.index < out[k - 1].index)))
            continue;
        if (j == k)
            j = k - 1;
        while (j > 0 && (c.d2 < out[j - 1].d2 || (c.d2 == out[j - 1].d2 && c.index < out[j - 1].index))) {
            out[j] = out[j - 1];
            j--;
        }
        out[j] = c;
    }
    return m;
}

/* Queries a tree the way the worker's estimates do, at its photons and at
 * points around them, and checks every answer against the tree's size. */
static void s_query(const pf_kdtree_t *t)
{
    if (!t)
        return;
    size_t n = pf_kdtree_size(t);
    const pf_photon_t *ph = pf_kdtree_photons(t);
    pf_knn_t out[16];
    size_t probes = n < 8 ? n : 8;
    for (size_t i = 0; i <= probes; i++) {
        pf_vec3 x = i < probes ? pf_photon_pos(&ph[i * n / probes]) : pf_v3(0.25f, -0.5f, 1.0f);
        size_t k = 1 + i % 16;
        size_t got = pf_kdtree_knn(t, x, k, INFINITY, out);
        PF_FUZZ_REQUIRE(got <= k && got <= n, "knn returned %zu of k=%zu, n=%zu", got, k, n);
        PF_FUZZ_REQUIRE(n == 0 || got == k || got == n, "knn without a radius returned %zu of k=%zu, n=%zu", got, k,
                        n);
        for (size_t j = 0; j < got; j++) {
            PF_FUZZ_REQUIRE(out[j].index < n, "knn index %u of %zu", out[j].index, n);
            PF_FUZZ_REQUIRE(j == 0 || out[j - 1].d2 <= out[j].d2, "knn results out of order");
        }
        pf_knn_t brute[16];
        float q[3] = { x.x, x.y, x.z };
        size_t want = s_brute_knn(ph, n, q, k, brute);
        PF_FUZZ_REQUIRE(got == want, "knn found %zu photons, a scan %zu", got, want);
        for (size_t j = 0; j < got; j++)
            PF_FUZZ_REQUIRE(out[j].index == brute[j].index && out[j].d2 == brute[j].d2,
                            "knn result %zu of %zu is photon %u at d2 %g, a scan says photon %u at d2 %g", j, k,
                            out[j].index, (double)out[j].d2, brute[j].index, (double)brute[j].d2);
        got = pf_kdtree_radius(t, x, 0.01f, out, 16);
        for (size_t j = 0; j < got && j < 16; j++)
            PF_FUZZ_REQUIRE(out[j].index < n, "radius index %u of %zu", out[j].index, n);
        pf_knn_t one;
        if (pf_kdtree_nearest_normal(t, x, pf_v3(0, 1, 0), 0.7f, INFINITY, &one))
            PF_FUZZ_REQUIRE(one.index < n, "nearest_normal index %u of %zu", one.index, n);
    }
}

static void s_read(const uint8_t *data, size_t size, uint64_t scene_hash, uint64_t settings_hash)
{
    pf_photon_maps_t maps;
    pf_error_t err;
    err.msg[0] = '\0';
    int rc = pf_mapfile_read(data, size, scene_hash, settings_hash, &maps, &err);
    if (rc != PF_OK) {
        PF_FUZZ_REQUIRE(rc < 0 && err.msg[0] != '\0', "a refused map blob: status %d, message '%s'", rc, err.msg);
        PF_FUZZ_REQUIRE(!maps.global && !maps.caustic && !maps.irradiance, "a refused map blob left trees");
        return;
    }
    PF_FUZZ_REQUIRE(maps.global && maps.caustic && maps.irradiance, "an accepted map blob lacks a tree");
    s_query(maps.global);
    s_query(maps.caustic);
    s_query(maps.irradiance);

    pf_buf_t b = { 0 };
    rc = pf_mapfile_write(&maps, scene_hash, settings_hash, &b);
    PF_FUZZ_REQUIRE(rc == PF_OK, "accepted maps do not write: %s", pf_strerror(rc));
    pf_photon_maps_t back;
    rc = pf_mapfile_read(b.data, b.len, scene_hash, settings_hash, &back, &err);
    PF_FUZZ_REQUIRE(rc == PF_OK, "accepted maps do not read back: %s", err.msg);
    PF_FUZZ_REQUIRE(pf_kdtree_size(back.global) == pf_kdtree_size(maps.global) &&
                        pf_kdtree_size(back.caustic) == pf_kdtree_size(maps.caustic) &&
                        pf_kdtree_size(back.irradiance) == pf_kdtree_size(maps.irradiance),
                    "the maps changed size on a round trip");
    pf_photon_maps_free(&back);
    pf_buf_free(&b);
    pf_photon_maps_free(&maps);
}

int LLVMFuzzerTestOneInput(const uint8_t *data, size_t size)
{
    s_read(data, size, 0, 0);
    if (size < S_HEADER)
        return 0;
    uint8_t *copy = malloc(size);
    PF_FUZZ_REQUIRE(copy != NULL, "out of memory");
    memcpy(copy, data, size);
    uint64_t h = pf_hash_bytes(PF_HASH_INIT, copy, S_HASH_OFFSET);
    h = pf_hash_bytes(h, copy + S_HEADER, size - S_HEADER);
    for (int i = 0; i < 8; i++)
        copy[S_HASH_OFFSET + i] = (uint8_t)(h >> (8 * i));
    s_read(copy, size, s_u64_at(copy + 8), s_u64_at(copy + 16));
    free(copy);
    return 0;
}
