/* test_tile_msgs.c: the TILE message's per-pixel samples (adaptive
 * progressive passes, protocol 7): a round trip, re-encoding a decoded
 * TILE, and a count of 0 refused both ways. */
#include <stdio.h>
#include <string.h>

#include "proto/messages.h"

#include "check.h"

/* A TILE of an adaptive pass carries its per-pixel samples; a count of 0
 * is refused both ways; a decoded TILE re-encodes to the same frame. */
static void s_tile_counts(void)
{
    const uint16_t counts[6] = { 1, 2, 300, 65535, 7, 4 };
    pf_msg_t m, d;
    memset(&m, 0, sizeof m);
    m.type = PF_MSG_TILE;
    m.job = 42;
    m.u.tile = (pf_msg_tile_t){ .tile = 17, .attempt = 2, .x0 = 64, .y0 = 32, .w = 32, .h = 16 };
    m.u.tile.cx0 = 62, m.u.tile.cy0 = 30, m.u.tile.cw = 3, m.u.tile.ch = 2;
    m.u.tile.counts = counts;
    pf_buf_t b = { 0 }, b2 = { 0 };
    CHECK(pf_msg_encode(&m, &b) == PF_OK, "TILE with counts encodes");
    char why[256] = "";
    CHECK(pf_msg_decode(b.data, b.len, &d, why, sizeof why) == PF_OK, "TILE with counts decodes: %s", why);
    int same = d.u.tile.cx0 == 62 && d.u.tile.cy0 == 30 && d.u.tile.cw == 3 && d.u.tile.ch == 2;
    for (uint32_t i = 0; same && i < 6; i++)
        same = pf_msg_tile_count(&d.u.tile, i) == counts[i];
    CHECK(same, "the counts come back");
    CHECK(pf_msg_encode(&d, &b2) == PF_OK && b2.len == b.len && memcmp(b.data, b2.data, b.len) == 0,
          "a decoded TILE re-encodes to the same frame");
    const uint16_t zero[6] = { 1, 2, 0, 4, 5, 6 };
    m.u.tile.counts = zero;
    CHECK(pf_msg_encode(&m, &b2) == PF_EINVAL, "a count of 0 is refused");
    b.data[b.len - 7] = 0, b.data[b.len - 8] = 0; /* count 2 (300) on the wire */
    CHECK(pf_msg_decode(b.data, b.len, &d, why, sizeof why) == PF_EPARSE, "a count of 0 on the wire: %s", why);
    pf_buf_free(&b);
    pf_buf_free(&b2);
}

int main(void)
{
    s_tile_counts();
    return pf_test_finish();
}
