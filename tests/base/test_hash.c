/* test_hash.c: pf_hash_bytes is XXH64: the reference implementation's
 * published values, every tail length, and sensitivity to every byte. */
#include <stdio.h>
#include <string.h>

#include "base/hash.h"

#include "check.h"


int main(void)
{
    /* Reference values of XXH64 (xxhash's own test suite and documentation). */
    CHECK(pf_hash_bytes(0, "", 0) == 0xEF46DB3751D8E999ULL, "XXH64('', 0) = %016llx",
          (unsigned long long)pf_hash_bytes(0, "", 0));
    CHECK(pf_hash_bytes(0, "a", 1) == 0xD24EC4F1A98C6E5BULL, "XXH64('a', 0) = %016llx",
          (unsigned long long)pf_hash_bytes(0, "a", 1));
    CHECK(pf_hash_bytes(0, "abc", 3) == 0x44BC2CF5AD770999ULL, "XXH64('abc', 0) = %016llx",
          (unsigned long long)pf_hash_bytes(0, "abc", 3));
    const char *fox = "The quick brown fox jumps over the lazy dog";
    CHECK(pf_hash_bytes(0, fox, strlen(fox)) == 0x0B242D361FDA71BCULL, "XXH64(fox, 0) = %016llx",
          (unsigned long long)pf_hash_bytes(0, fox, strlen(fox)));
    /* Every length 0..200 differs from its neighbours, and flipping any byte changes the hash. */
    unsigned char buf[200];
    for (int i = 0; i < 200; i++)
        buf[i] = (unsigned char)(i * 37 + 11);
    int distinct = 1, flips = 1;
    for (size_t n = 1; n <= sizeof buf; n++) {
        uint64_t h = pf_hash_bytes(PF_HASH_INIT, buf, n);
        distinct &= h != pf_hash_bytes(PF_HASH_INIT, buf, n - 1);
        for (size_t k = 0; k < n; k += 7) {
            buf[k] ^= 1;
            flips &= pf_hash_bytes(PF_HASH_INIT, buf, n) != h;
            buf[k] ^= 1;
        }
    }
    CHECK(distinct, "prefixes collide");
    CHECK(flips, "a flipped byte went unnoticed");
    CHECK(pf_hash_bytes(1, "abc", 3) != pf_hash_bytes(2, "abc", 3), "the seed is ignored");
    printf("%d passed, %d failed\n", s_passed, s_failed);
    return s_failed ? 1 : 0;
}
