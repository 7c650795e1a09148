/* hash.h: 64-bit content hashes (FNV-1a folded through a 64-bit mixer), for
 * naming blobs by content and fingerprinting settings. Not cryptographic. */
#ifndef PF_HASH_H
#define PF_HASH_H

#include <stddef.h>
#include <stdint.h>

#define PF_HASH_INIT 0xcbf29ce484222325ULL

uint64_t pf_hash_bytes(uint64_t h, const void *data, size_t len);
static inline uint64_t pf_hash_u64(uint64_t h, uint64_t v) { return pf_hash_bytes(h, &v, sizeof v); }

#endif
