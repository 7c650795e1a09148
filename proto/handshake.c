/* handshake.c: the build fingerprint HELLO carries and the check that two
 * builds can share photon maps and messages (messages.h). Split from
 * messages.c, which holds the message codecs. */
#include <stdio.h>
#include <string.h>

#include "base/status.h"
#include "proto/messages.h"

#ifndef PF_GIT_HASH
#define PF_GIT_HASH "unknown"
#endif

pf_fingerprint_t pf_fingerprint_make(uint16_t photon_size, uint16_t map_version)
{
    pf_fingerprint_t fp;
    memset(&fp, 0, sizeof fp);
    fp.protocol = PF_PROTO_VERSION;
    fp.photon_size = photon_size;
    fp.float_size = (uint16_t)sizeof(float);
    fp.map_version = map_version;
    snprintf(fp.git, sizeof fp.git, "%s", PF_GIT_HASH);
    return fp;
}

int pf_fingerprint_check(const pf_fingerprint_t *worker, const pf_fingerprint_t *coord, char *why, size_t why_len)
{
    /* Each difference that makes the two builds unable to share photon maps
     * or messages, as one clause; all of them, so one refusal tells the whole
     * story. */
    char text[512];
    size_t n = 0;
    text[0] = '\0';
#define S_CLAUSE(...)                                                              \
    do {                                                                           \
        if (n < sizeof text) {                                                     \
            int w_ = snprintf(text + n, sizeof text - n, "%s", n ? "; " : "");     \
            n += w_ > 0 ? (size_t)w_ : 0;                                          \
        }                                                                          \
        if (n < sizeof text) {                                                     \
            int w_ = snprintf(text + n, sizeof text - n, __VA_ARGS__);             \
            n += w_ > 0 ? (size_t)w_ : 0;                                          \
        }                                                                          \
    } while (0)
    if (worker->protocol != coord->protocol)
        S_CLAUSE("protocol version %u (worker) vs %u (coordinator)", (unsigned)worker->protocol,
                 (unsigned)coord->protocol);
    if (worker->photon_size != coord->photon_size)
        S_CLAUSE("photon record of %u bytes (worker) vs %u bytes (coordinator)", (unsigned)worker->photon_size,
                 (unsigned)coord->photon_size);
    if (worker->float_size != coord->float_size)
        S_CLAUSE("float of %u bytes (worker) vs %u bytes (coordinator)", (unsigned)worker->float_size,
                 (unsigned)coord->float_size);
    if (worker->map_version != coord->map_version)
        S_CLAUSE("photon-map format version %u (worker) vs %u (coordinator)", (unsigned)worker->map_version,
                 (unsigned)coord->map_version);
#undef S_CLAUSE
    if (n == 0) {
        /* Builds from different commits with the same protocol and layouts
         * work together; the caller may log the git hashes itself. */
        if (why && why_len)
            why[0] = '\0';
        return PF_OK;
    }
    if (why && why_len)
        snprintf(why, why_len, "incompatible builds: %s (worker build %.47s, coordinator build %.47s)", text,
                 worker->git, coord->git);
    return PF_EMISMATCH;
}

