/* hashtree.c: per-chunk hashes and their root; see hashtree.h. The leaves
 * are hashed with the blob's content hash and the chunk index in the seed,
 * so equal chunks at two places or in two blobs get different leaves. */
#include "proto/hashtree.h"

#include "base/hash.h"

uint64_t pf_chunk_count(uint64_t size)
{
    return (size + PF_HASHTREE_CHUNK - 1) / PF_HASHTREE_CHUNK;
}

uint64_t pf_chunk_hash(uint64_t blob_hash, uint64_t k, const void *data, size_t len)
{
    return pf_hash_bytes(pf_hash_u64(blob_hash, k), data, len);
}

uint64_t pf_chunk_root(uint64_t blob_hash, uint64_t size, const uint64_t *leaves, uint32_t n)
{
    uint64_t h = pf_hash_u64(pf_hash_u64(PF_HASH_INIT, blob_hash), size);
    for (uint32_t k = 0; k < n; k++)
        h = pf_hash_u64(h, leaves[k]);
    return h;
}
