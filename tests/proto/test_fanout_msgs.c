/* test_fanout_msgs.c: the fan-out's protocol pieces (issue 21): BLOB_PLAN
 * round trips (with a source and with the coordinator), truncation at every
 * byte, a damaged leaf or root refused (the root check), a source that is
 * not tcp:// or not printable, a leaf count that does not fit the size; the
 * chunk hashes (a chunk moved or changed changes its leaf); and the
 * coordinator's tree (coordinator/fanout.h): six serving workers at degree 2
 * give the coordinator one child and no worker more than two; a dead
 * source's children go back to the coordinator; degree 0 or no peer port:
 * everyone fetches from the coordinator. */
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "base/status.h"
#include "coordinator/fanout.h"
#include "proto/hashtree.h"
#include "proto/messages.h"

#include "check.h"

static uint64_t s_leaves[5];

static pf_msg_t s_plan(const char *source)
{
    pf_msg_t m = { .type = PF_MSG_BLOB_PLAN, .job = 9 };
    pf_msg_blob_plan_t *p = &m.u.plan;
    p->hash = 0x1234;
    p->size = 4 * (uint64_t)PF_PROTO_CHUNK_SIZE + 1; /* five chunks */
    p->n = 5;
    for (int k = 0; k < 5; k++)
        s_leaves[k] = 0x9e3779b97f4a7c15ULL * (uint64_t)(k + 3);
    p->leaves = s_leaves;
    p->root = pf_chunk_root(p->hash, p->size, s_leaves, 5);
    p->source_uid = source[0] ? 3 : 0;
    snprintf(p->source, sizeof p->source, "%s", source);
    return m;
}

static void s_round_trips(void)
{
    const char *sources[] = { "", "tcp://10.78.0.4:41000", "tcp://[::1]:5" };
    for (int i = 0; i < 3; i++) {
        pf_msg_t m = s_plan(sources[i]), d;
        pf_buf_t b = { 0 };
        char why[256];
        CHECK(pf_msg_encode(&m, &b) == PF_OK, "encode plan %d", i);
        CHECK(pf_msg_decode(b.data, b.len, &d, why, sizeof why) == PF_OK, "decode plan %d: %s", i, why);
        CHECK(d.type == PF_MSG_BLOB_PLAN && d.job == 9 && d.u.plan.hash == 0x1234 && d.u.plan.n == 5 &&
                  d.u.plan.size == m.u.plan.size && d.u.plan.root == m.u.plan.root &&
                  strcmp(d.u.plan.source, sources[i]) == 0 && d.u.plan.source_uid == m.u.plan.source_uid,
              "plan %d fields", i);
        for (uint32_t k = 0; k < 5; k++)
            CHECK(pf_msg_plan_leaf(&d.u.plan, k) == s_leaves[k], "plan %d leaf %u", i, k);
        /* Every truncation is refused, naming the type. */
        int bad = 0;
        for (size_t len = 0; len < b.len; len++)
            if (pf_msg_decode(b.data, len, &d, why, sizeof why) != PF_EPARSE)
                bad++;
        CHECK(bad == 0, "plan %d: %d truncations decoded", i, bad);
        /* A flipped bit in any leaf or the root breaks the root check. */
        size_t leaves_at = b.len - 5 * 8;
        for (int f = -1; f < 5; f++) {
            size_t at = f < 0 ? leaves_at - 12 : leaves_at + 8 * (size_t)f + 3; /* the root, or leaf f */
            b.data[at] ^= 0x10;
            int rc = pf_msg_decode(b.data, b.len, &d, why, sizeof why);
            CHECK(rc == PF_EPARSE && strstr(why, "root"), "plan %d: a flipped byte at %zu: rc %d (%s)", i, at, rc,
                  why);
            b.data[at] ^= 0x10;
        }
        pf_buf_free(&b);
    }
}

static void s_refusals(void)
{
    pf_buf_t b = { 0 };
    pf_msg_t m = s_plan("udp://10.0.0.1:5");
    CHECK(pf_msg_encode(&m, &b) == PF_EINVAL, "a source that is not tcp:// is not sent");
    m = s_plan("tcp://10.0.0.1:5\n");
    CHECK(pf_msg_encode(&m, &b) == PF_EINVAL, "a source with a newline is not sent");
    m = s_plan("");
    m.u.plan.size = 3 * (uint64_t)PF_PROTO_CHUNK_SIZE;
    m.u.plan.root = pf_chunk_root(m.u.plan.hash, m.u.plan.size, s_leaves, 5);
    CHECK(pf_msg_encode(&m, &b) == PF_EINVAL, "five leaves for three chunks are not sent");
    m = s_plan("");
    m.u.plan.root ^= 1;
    CHECK(pf_msg_encode(&m, &b) == PF_EINVAL, "a wrong root is not sent");
    m = s_plan("");
    m.u.plan.size = 0;
    m.u.plan.n = 0;
    m.u.plan.root = pf_chunk_root(m.u.plan.hash, 0, s_leaves, 0);
    CHECK(pf_msg_encode(&m, &b) == PF_EINVAL, "a plan for an empty blob is not sent");
    /* The decoder refuses the same, written by hand: a plan with n = 4 for five chunks. */
    m = s_plan("");
    CHECK(pf_msg_encode(&m, &b) == PF_OK, "encode");
    pf_msg_t d;
    char why[256];
    b.len -= 8;                      /* one leaf fewer */
    size_t n_at = b.len - 4 * 8 - 4; /* the u32 n */
    b.data[n_at] = 4;
    uint64_t root4 = pf_chunk_root(0x1234, m.u.plan.size, s_leaves, 4);
    for (int i = 0; i < 8; i++)
        b.data[n_at - 8 + (size_t)i] = (uint8_t)(root4 >> (8 * i));
    CHECK(pf_msg_decode(b.data, b.len, &d, why, sizeof why) == PF_EPARSE && strstr(why, "chunk hashes for a blob"),
          "four leaves for five chunks refused: %s", why);
    pf_buf_free(&b);
}

static void s_chunk_hashes(void)
{
    uint8_t a[64], c[64];
    memset(a, 7, sizeof a);
    memcpy(c, a, sizeof c);
    uint64_t h0 = pf_chunk_hash(1, 0, a, sizeof a);
    CHECK(h0 == pf_chunk_hash(1, 0, c, sizeof c), "same bytes, same leaf");
    CHECK(h0 != pf_chunk_hash(1, 1, a, sizeof a), "the same bytes as another chunk: another leaf");
    CHECK(h0 != pf_chunk_hash(2, 0, a, sizeof a), "the same bytes in another blob: another leaf");
    c[63] ^= 1;
    CHECK(h0 != pf_chunk_hash(1, 0, c, sizeof c), "a changed byte changes the leaf");
    CHECK(pf_chunk_count(0) == 0 && pf_chunk_count(1) == 1 && pf_chunk_count(PF_PROTO_CHUNK_SIZE) == 1 &&
              pf_chunk_count(PF_PROTO_CHUNK_SIZE + 1) == 2,
          "chunk counts");
}

/* A framed blob of size bytes for the tree (payload bytes only matter). */
static pf_framed_blob_t s_fb(uint64_t size)
{
    pf_buf_t blob = { 0 };
    for (uint64_t i = 0; i < size; i++)
        pf_wr_u8(&blob, (uint8_t)(i * 131));
    pf_framed_blob_t fb;
    CHECK(pf_framed_blob_make(&fb, 1, 0xabc, &blob) == PF_OK, "framed blob");
    pf_buf_free(&blob);
    return fb;
}

static void s_tree(void)
{
    pf_fanout_t *fo = pf_fanout_new(8, 2);
    pf_framed_blob_t fb = s_fb(2 * PF_PROTO_CHUNK_SIZE + 5);
    pf_msg_blob_plan_t p;
    CHECK(pf_fanout_plan(fo, 0, &p) == -1, "no blob: no plan");
    for (int i = 0; i < 6; i++)
        pf_fanout_hello(fo, i, (uint32_t)i + 1, i == 3 ? "::1" : "10.1.0.9", (uint16_t)(40000 + i));
    CHECK(pf_fanout_set_blob(fo, &fb) == PF_OK, "set blob");
    int kids[8] = { 0 }, coord = 0;
    for (int i = 0; i < 6; i++) {
        int src = pf_fanout_plan(fo, i, &p);
        CHECK(p.n == 3 && p.hash == 0xabc && p.root == pf_chunk_root(0xabc, fb.size, p.leaves, 3), "plan %d", i);
        if (src == -2) {
            coord++;
            CHECK(p.source[0] == 0 && p.source_uid == 0, "coordinator plan %d has no source", i);
        } else {
            CHECK(src >= 0 && src < i, "plan %d: source %d", i, src);
            kids[src]++;
            char want[64];
            snprintf(want, sizeof want, src == 3 ? "tcp://[::1]:%d" : "tcp://10.1.0.9:%d", 40000 + src);
            CHECK(strcmp(p.source, want) == 0 && p.source_uid == (uint32_t)src + 1, "plan %d: source '%s'", i,
                  p.source);
        }
    }
    CHECK(coord == 1, "the coordinator serves %d workers (1 expected)", coord);
    for (int i = 0; i < 6; i++)
        CHECK(kids[i] <= 2, "worker %d serves %d", i, kids[i]);
    /* Each leaf is the chunk's: chunk 1 of the framed blob. */
    CHECK(p.leaves[1] == pf_chunk_hash(0xabc, 1, fb.data + fb.stride + fb.head, PF_PROTO_CHUNK_SIZE), "leaf 1");
    /* Worker 0 (the root) dies: its children go to the coordinator. */
    int gone[8];
    int ng = pf_fanout_gone(fo, 0, gone, 8);
    CHECK(ng == kids[0] && ng >= 1, "the root's %d children re-planned (%d)", kids[0], ng);
    /* A newcomer in slot 6 fetches from a live serving worker, never from slot 0. */
    pf_fanout_hello(fo, 6, 7, "10.1.0.9", 40006);
    int src = pf_fanout_plan(fo, 6, &p);
    CHECK(src != 0, "no plan names a dead worker (got %d)", src);
    /* Degree 0: the coordinator for everyone. */
    pf_fanout_t *off = pf_fanout_new(4, 0);
    for (int i = 0; i < 4; i++)
        pf_fanout_hello(off, i, (uint32_t)i + 1, "10.1.0.9", 40000);
    pf_fanout_set_blob(off, &fb);
    int all = 1;
    for (int i = 0; i < 4; i++)
        all &= pf_fanout_plan(off, i, &p) == -2;
    CHECK(all, "degree 0: every plan names the coordinator");
    /* No peer port: not a source. */
    pf_fanout_t *np = pf_fanout_new(4, 2);
    for (int i = 0; i < 4; i++)
        pf_fanout_hello(np, i, (uint32_t)i + 1, "10.1.0.9", 0);
    pf_fanout_set_blob(np, &fb);
    all = 1;
    for (int i = 0; i < 4; i++)
        all &= pf_fanout_plan(np, i, &p) == -2;
    CHECK(all, "workers without a peer port serve no one");
    pf_fanout_free(&fo);
    pf_fanout_free(&off);
    pf_fanout_free(&np);
    pf_framed_blob_free(&fb);
}

int main(void)
{
    s_round_trips();
    s_refusals();
    s_chunk_hashes();
    s_tree();
    return pf_test_finish();
}
