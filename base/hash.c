/* hash.c: XXH64 (Yann Collet's xxHash, 64-bit variant), written from its
 * specification: four 64-bit lanes over 32-byte stripes, then the tail; about
 * ten times faster than byte-wise FNV on the 100+ MB photon-map blobs that
 * workers hash on arrival. Pure function; any thread. */
#include "base/hash.h"

#include <string.h>

#define S_P1 0x9E3779B185EBCA87ULL
#define S_P2 0xC2B2AE3D27D4EB4FULL
#define S_P3 0x165667B19E3779F9ULL
#define S_P4 0x85EBCA77C2B2AE63ULL
#define S_P5 0x27D4EB2F165667C5ULL

static inline uint64_t s_rotl(uint64_t x, int r) { return (x << r) | (x >> (64 - r)); }

/* Little-endian loads, whatever the host (one load on little-endian ones). */
static inline uint64_t s_rd64(const unsigned char *p)
{
#if defined(__BYTE_ORDER__) && __BYTE_ORDER__ == __ORDER_LITTLE_ENDIAN__
    uint64_t v;
    memcpy(&v, p, sizeof v);
    return v;
#else
    uint64_t v = 0;
    for (int i = 7; i >= 0; i--)
        v = (v << 8) | p[i];
    return v;
#endif
}
static inline uint32_t s_rd32(const unsigned char *p)
{
    return (uint32_t)p[0] | (uint32_t)p[1] << 8 | (uint32_t)p[2] << 16 | (uint32_t)p[3] << 24;
}

static inline uint64_t s_round(uint64_t acc, uint64_t input)
{
    acc += input * S_P2;
    acc = s_rotl(acc, 31);
    return acc * S_P1;
}

static inline uint64_t s_merge(uint64_t acc, uint64_t val)
{
    acc ^= s_round(0, val);
    return acc * S_P1 + S_P4;
}

uint64_t pf_hash_bytes(uint64_t seed, const void *data, size_t len)
{
    const unsigned char *p = data, *end = p + len;
    uint64_t h;
    if (len >= 32) {
        uint64_t v1 = seed + S_P1 + S_P2, v2 = seed + S_P2, v3 = seed, v4 = seed - S_P1;
        const unsigned char *limit = end - 32;
        do {
            v1 = s_round(v1, s_rd64(p));
            v2 = s_round(v2, s_rd64(p + 8));
            v3 = s_round(v3, s_rd64(p + 16));
            v4 = s_round(v4, s_rd64(p + 24));
            p += 32;
        } while (p <= limit);
        h = s_rotl(v1, 1) + s_rotl(v2, 7) + s_rotl(v3, 12) + s_rotl(v4, 18);
        h = s_merge(h, v1);
        h = s_merge(h, v2);
        h = s_merge(h, v3);
        h = s_merge(h, v4);
    } else {
        h = seed + S_P5;
    }
    h += (uint64_t)len;
    while (p + 8 <= end) {
        h ^= s_round(0, s_rd64(p));
        h = s_rotl(h, 27) * S_P1 + S_P4;
        p += 8;
    }
    if (p + 4 <= end) {
        h ^= (uint64_t)s_rd32(p) * S_P1;
        h = s_rotl(h, 23) * S_P2 + S_P3;
        p += 4;
    }
    while (p < end) {
        h ^= (*p) * S_P5;
        h = s_rotl(h, 11) * S_P1;
        p++;
    }
    h ^= h >> 33;
    h *= S_P2;
    h ^= h >> 29;
    h *= S_P3;
    h ^= h >> 32;
    return h;
}
