/* hash.h: 64-bit content hashes (XXH64), for naming blobs by content and
 * fingerprinting settings. Not cryptographic: a hostile peer can forge one,
 * which is why every blob is also validated field by field. */
#ifndef PF_HASH_H
#define PF_HASH_H

#include <stddef.h>
#include <stdint.h>

#define PF_HASH_INIT 0xcbf29ce484222325ULL

/* XXH64 of data with the given seed; chain calls by passing the previous
 * result as the seed. */
uint64_t pf_hash_bytes(uint64_t seed, const void *data, size_t len);
static inline uint64_t pf_hash_u64(uint64_t h, uint64_t v) { return pf_hash_bytes(h, &v, sizeof v); }

#endif
