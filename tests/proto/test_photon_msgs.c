/* test_photon_msgs.c: the photon pass's messages (PHOTON_REQ, PHOTONS):
 * round trips of a full part and of an empty batch, truncation at every
 * byte, counts that do not fit (n past total, indirect past total, an empty
 * part of a non-empty batch, too many photons a part, a batch or a range
 * past the limit, a byte count that is not n photons), photons with a
 * non-finite position or a negative or non-finite power, and the encoder
 * refusing to send what the decoder would refuse. */
#include <math.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "proto/messages.h"

#include "check.h"

static pf_msg_photon_t s_ph[4];

static pf_msg_t s_photons(void)
{
    for (int i = 0; i < 4; i++)
        s_ph[i] = (pf_msg_photon_t){ { 0.5f * i, 1.0f, -2.0f }, { 1e-3f, 0.0f, 2.5f }, 0x12345678u + i, 0x9abcdef0u };
    pf_msg_t m = { .type = PF_MSG_PHOTONS, .job = 42 };
    m.u.photons = (pf_msg_photons_t){ 3, 10, 4, 1, 6, 4, NULL, s_ph };
    return m;
}

static pf_msg_t s_req(void)
{
    pf_msg_t m = { .type = PF_MSG_PHOTON_REQ, .job = 42 };
    m.u.photon_req.settings = pf_settings_default();
    m.u.photon_req.settings.width = 64;
    m.u.photon_req.settings.height = 64;
    m.u.photon_req.scene_hash = 0xabcdef;
    m.u.photon_req.scene_size = 4096;
    m.u.photon_req.first = 7;
    m.u.photon_req.count = 2;
    return m;
}

/* Decodes an encoded message (why: 256 bytes). */
static int s_decode(const pf_buf_t *b, pf_msg_t *d, char *why)
{
    return pf_msg_decode(b->data, b->len, d, why, 256);
}

static void s_put32(uint8_t *p, uint32_t v)
{
    for (int i = 0; i < 4; i++)
        p[i] = (uint8_t)(v >> (8 * i));
}

static void s_put64(uint8_t *p, uint64_t v)
{
    for (int i = 0; i < 8; i++)
        p[i] = (uint8_t)(v >> (8 * i));
}

/* PHOTONS body offsets after the 16-byte header. */
enum { O_BATCH = 16, O_TOTAL = 20, O_FIRST = 28, O_REJ = 36, O_IND = 44, O_N = 52, O_DATA = 56 };

static void s_round_trips(void)
{
    pf_msg_t m = s_photons(), d;
    pf_buf_t b = { 0 };
    char why[256];
    CHECK(pf_msg_encode(&m, &b) == PF_OK && b.len == O_DATA + 4 * 32, "PHOTONS encodes (%zu bytes)", b.len);
    CHECK(s_decode(&b, &d, why) == PF_OK, "PHOTONS decodes: %s", why);
    int same = d.u.photons.batch == 3 && d.u.photons.total == 10 && d.u.photons.first == 4 &&
               d.u.photons.rejected == 1 && d.u.photons.indirect == 6 && d.u.photons.n == 4;
    for (uint32_t i = 0; same && i < 4; i++) {
        pf_msg_photon_t q;
        pf_msg_photon_get(&d.u.photons, i, &q);
        same = memcmp(&q, &s_ph[i], sizeof q) == 0;
    }
    CHECK(same, "PHOTONS round trip");
    /* An empty batch: total 0, n 0. */
    m.u.photons = (pf_msg_photons_t){ 9, 0, 0, 5, 0, 0, NULL, NULL };
    CHECK(pf_msg_encode(&m, &b) == PF_OK && s_decode(&b, &d, why) == PF_OK && d.u.photons.total == 0 &&
              d.u.photons.rejected == 5,
          "an empty batch round trips: %s", why);
    /* A full part fits a message. */
    pf_msg_photon_t *big = calloc(PF_PROTO_MAX_PART_PHOTONS, sizeof *big);
    m.u.photons = (pf_msg_photons_t){ 0, PF_PROTO_MAX_PART_PHOTONS * 2ull, PF_PROTO_MAX_PART_PHOTONS, 0, 0,
                                      PF_PROTO_MAX_PART_PHOTONS, NULL, big };
    CHECK(pf_msg_encode(&m, &b) == PF_OK && b.len <= PF_PROTO_MAX_MESSAGE && s_decode(&b, &d, why) == PF_OK,
          "a full part (%u photons, %zu bytes) fits the message limit: %s", (unsigned)PF_PROTO_MAX_PART_PHOTONS, b.len,
          why);
    m.u.photons.n = PF_PROTO_MAX_PART_PHOTONS + 1;
    CHECK(pf_msg_encode(&m, &b) == PF_EINVAL, "the encoder refuses a part over the limit");
    free(big);
    pf_msg_t r = s_req();
    CHECK(pf_msg_encode(&r, &b) == PF_OK && s_decode(&b, &d, why) == PF_OK && d.u.photon_req.first == 7 &&
              d.u.photon_req.count == 2 && d.u.photon_req.scene_hash == 0xabcdef &&
              d.u.photon_req.settings.seed == r.u.photon_req.settings.seed,
          "PHOTON_REQ round trip: %s", why);
    pf_buf_free(&b);
}

static void s_truncations(void)
{
    pf_msg_t ms[2] = { s_photons(), s_req() };
    for (int k = 0; k < 2; k++) {
        pf_buf_t b = { 0 };
        CHECK(pf_msg_encode(&ms[k], &b) == PF_OK, "encode");
        int bad = 0;
        for (size_t len = 0; len < b.len; len++) {
            uint8_t *c = malloc(len ? len : 1);
            memcpy(c, b.data, len);
            pf_msg_t d;
            char why[256] = "";
            bad += pf_msg_decode(c, len, &d, why, sizeof why) != PF_EPARSE || why[0] == 0;
            free(c);
        }
        CHECK(bad == 0, "%s: every truncation is refused with a reason (%d not)", pf_msg_type_name(ms[k].type), bad);
        pf_buf_free(&b);
    }
}

/* The PHOTONS sample with one field patched in its bytes: refused, with needle. */
static void s_patched(size_t off, int width, uint64_t v, const char *needle)
{
    pf_msg_t m = s_photons(), d;
    pf_buf_t b = { 0 };
    CHECK(pf_msg_encode(&m, &b) == PF_OK, "encode");
    if (width == 8)
        s_put64(b.data + off, v);
    else
        s_put32(b.data + off, (uint32_t)v);
    char why[256] = "";
    int rc = pf_msg_decode(b.data, b.len, &d, why, sizeof why);
    CHECK(rc == PF_EPARSE && strstr(why, needle), "patched at %zu to %llu: rc %d, '%s' (want '%s')", off,
          (unsigned long long)v, rc, why, needle);
    pf_buf_free(&b);
}

static void s_bad_counts(void)
{
    s_patched(O_TOTAL, 8, 7, "do not fit");                  /* first 4 + n 4 > total 7 */
    s_patched(O_FIRST, 8, 7, "do not fit");                  /* first 7 + n 4 > total 10 */
    s_patched(O_IND, 8, 11, "do not fit");                   /* indirect > total */
    s_patched(O_TOTAL, 8, UINT64_MAX, "do not fit");         /* absurd total */
    s_patched(O_BATCH, 4, PF_PROTO_MAX_BATCHES, "batch");    /* batch past the limit */
    s_patched(O_N, 4, 3, "bytes of photons");                /* 4 photons' bytes for n 3 */
    s_patched(O_N, 4, 5, "bytes of photons");                /* ... for n 5 */
    s_patched(O_N, 4, PF_PROTO_MAX_PART_PHOTONS + 1, "over"); /* n over the part limit */
    s_patched(O_N, 4, 0, "bytes of photons");                /* n 0 of a non-empty batch, with bytes */
    uint32_t nan = 0x7fc00000u, inf = 0x7f800000u, neg = 0xbf800000u; /* NaN, +Inf, -1 */
    s_patched(O_DATA + 4, 4, nan, "not finite");             /* photon 0's position y */
    s_patched(O_DATA + 32 + 12, 4, neg, "power < 0");         /* photon 1's power r */
    s_patched(O_DATA + 96 + 20, 4, inf, "not finite");        /* photon 3's power b */
    /* An empty part of a non-empty batch, with no bytes after it. */
    pf_msg_t m = s_photons(), d;
    m.u.photons.n = 0;
    pf_buf_t b = { 0 };
    CHECK(pf_msg_encode(&m, &b) == PF_EINVAL, "the encoder refuses an empty part of a non-empty batch");
    m = s_photons();
    CHECK(pf_msg_encode(&m, &b) == PF_OK, "encode");
    s_put32(b.data + O_N, 0);
    char why[256] = "";
    CHECK(pf_msg_decode(b.data, O_DATA, &d, why, sizeof why) == PF_EPARSE && strstr(why, "n 0"),
          "an empty part of a non-empty batch is refused: '%s'", why);
    /* The encoder refuses bad photons. */
    m = s_photons();
    s_ph[2].power[1] = -0.5f;
    CHECK(pf_msg_encode(&m, &b) == PF_EINVAL, "the encoder refuses a negative power");
    m = s_photons();
    s_ph[0].pos[2] = NAN;
    CHECK(pf_msg_encode(&m, &b) == PF_EINVAL, "the encoder refuses a NaN position");
    m = s_photons();
    m.u.photons.photons = NULL;
    CHECK(pf_msg_encode(&m, &b) == PF_EINVAL, "the encoder refuses missing photons");
    /* PHOTON_REQ ranges and settings. */
    pf_msg_t r = s_req();
    r.u.photon_req.count = 0;
    CHECK(pf_msg_encode(&r, &b) == PF_EINVAL, "PHOTON_REQ of no batch is refused");
    r.u.photon_req.count = PF_PROTO_MAX_REQ_BATCHES + 1;
    CHECK(pf_msg_encode(&r, &b) == PF_EINVAL, "PHOTON_REQ of too many batches is refused");
    r = s_req();
    CHECK(pf_msg_encode(&r, &b) == PF_OK, "encode");
    size_t end = b.len;
    s_put32(b.data + end - 8, PF_PROTO_MAX_BATCHES - 1); /* first: the range runs past the limit */
    CHECK(pf_msg_decode(b.data, b.len, &d, why, sizeof why) == PF_EPARSE && strstr(why, "first"),
          "PHOTON_REQ past the batch limit is refused: '%s'", why);
    s_put32(b.data + end - 8, 7);
    s_put32(b.data + end - 4, 1000);
    CHECK(pf_msg_decode(b.data, b.len, &d, why, sizeof why) == PF_EPARSE && strstr(why, "count"),
          "PHOTON_REQ count over the limit is refused: '%s'", why);
    r = s_req();
    r.u.photon_req.settings.global_k = 0;
    CHECK(pf_msg_encode(&r, &b) == PF_EINVAL, "PHOTON_REQ with settings out of range is refused");
    pf_buf_free(&b);
}

int main(void)
{
    s_round_trips();
    s_truncations();
    s_bad_counts();
    return pf_test_finish();
}
