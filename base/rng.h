/* rng.h: counter-based random numbers. A value is a pure function of
 * (seed, stream, sample, dimension): a pixel's samples hash (seed, pixel
 * index, sample index, dimension), a photon's (seed, photon index, 0,
 * dimension). Nothing depends on thread count, tile order or timing. */
#ifndef PF_RNG_H
#define PF_RNG_H

#include <stdint.h>

/* SplitMix64's finalizer (Stafford's mix13): a bijection on 64 bits. */
static inline uint64_t pf_mix64(uint64_t z)
{
    z = (z ^ (z >> 30)) * 0xbf58476d1ce4e5b9ULL;
    z = (z ^ (z >> 27)) * 0x94d049bb133111ebULL;
    return z ^ (z >> 31);
}

/* One stream's state: its key and the next dimension. */
typedef struct pf_rng {
    uint64_t key;
    uint32_t dim;
} pf_rng_t;

/* Streams for the purposes the renderer draws numbers for, so that a photon
 * and a pixel with the same index never share numbers. */
enum { PF_STREAM_PIXEL = 1, PF_STREAM_GLOBAL_PHOTON = 2, PF_STREAM_CAUSTIC_PHOTON = 3, PF_STREAM_TEST = 4,
       PF_STREAM_GATHER = 5, PF_STREAM_EDGE = 6 };

static inline pf_rng_t pf_rng_make(uint64_t seed, uint32_t purpose, uint64_t index, uint32_t sample)
{
    uint64_t k = pf_mix64(seed + 0x9e3779b97f4a7c15ULL * (uint64_t)purpose);
    k = pf_mix64(k ^ index);
    k = pf_mix64(k + 0x632be59bd9b4e019ULL * ((uint64_t)sample + 1));
    return (pf_rng_t){ k, 0 };
}

static inline uint32_t pf_rng_u32(pf_rng_t *r)
{
    return (uint32_t)(pf_mix64(r->key + 0x9e3779b97f4a7c15ULL * (uint64_t)(++r->dim)) >> 32);
}

/* Uniform in [0, 1): 24 random bits, so the result is never 1.0f. */
static inline float pf_rng_float(pf_rng_t *r)
{
    return (float)(pf_rng_u32(r) >> 8) * 0x1p-24f;
}

#endif
