/* hashtree.h: per-chunk hashes of a blob, bound to its content hash, so a
 * worker fetching a blob from another worker checks every chunk as it
 * arrives (a bad chunk is caught at that chunk, and its sender struck),
 * not only the whole blob at the end.
 *
 * The tree has two levels: leaf k is the XXH64 of chunk k's bytes seeded by
 * (blob content hash, k), so a chunk cannot stand in for another one or for
 * a chunk of another blob; the root is the XXH64 chain over the leaves
 * seeded by the blob's content hash and size. The coordinator (trusted)
 * sends the leaves and the root in BLOB_PLAN; the decoder recomputes the
 * root, so a plan damaged on the way is refused. XXH64 is not
 * cryptographic (base/hash.h): it catches a broken or careless peer, and a
 * forged chunk still has to pass the whole-blob hash and the mapfile's field
 * checks. Chunks are PF_HASHTREE_CHUNK bytes (= PF_PROTO_CHUNK_SIZE, which
 * messages.c asserts), the last one shorter. */
#ifndef PF_HASHTREE_H
#define PF_HASHTREE_H

#include <stddef.h>
#include <stdint.h>

#define PF_HASHTREE_CHUNK (1u << 20)

/* Chunks of a blob of size bytes (0 for an empty blob). */
uint64_t pf_chunk_count(uint64_t size);
/* Leaf k of blob `blob_hash`: the hash of that chunk's len bytes. */
uint64_t pf_chunk_hash(uint64_t blob_hash, uint64_t k, const void *data, size_t len);
/* The root over n leaves of the blob (blob_hash, size). */
uint64_t pf_chunk_root(uint64_t blob_hash, uint64_t size, const uint64_t *leaves, uint32_t n);

#endif
