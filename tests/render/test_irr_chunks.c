/* test_irr_chunks.c: the irradiance precompute spread in chunks gives the
 * maps of the in-process pass, bit for bit (the irradiance map through the
 * serialized map blob, the deep map's records compared), whoever computed
 * which chunk: the coordinator's chunk table (coordinator/irr_chunks.c) fed
 * with a worker's chunks through the IRR_POINTS codec, a lease never
 * answered (taken over by the photon thread), and hostile results, each
 * refused and computed again: a point moved off its photon, a support
 * radius past the search radius, a chunk short of a point, a chunk not in
 * the pass, a chunk not leased to the sender, a late duplicate; a chunk
 * whose irradiance differs by one bit is caught by the spot check of the
 * worker's first chunk (the worker queued as a liar). Then the IRR_REQ and
 * IRR_POINTS rules the encoder and the decoder share: counts that do not
 * fit, a chunk past the limit, an empty map blob, a negative irradiance.
 * Cornell spheres with a path-length limit of 5: both maps. */
#include <math.h>
#include <stdlib.h>
#include <string.h>

#include "../check.h"
#include "base/log.h"
#include "coordinator/irr_chunks.h"
#include "load/load.h"
#include "photon/mapfile.h"
#include "render/frame.h"

enum { S_OK = 0, S_MOVED, S_WIDE, S_SHORT, S_BIT };

/* Chunk i computed as a worker would, spoiled as `how` says, sent through
 * the codec and fed to the table as uid. The verdict, or -100 on a codec
 * failure. */
static int s_feed(pf_irq_t *q, const pf_kdtree_t *global, const pf_accel_t *accel, const pf_irr_plan_t *plan,
                  uint32_t i, uint32_t uid, int how)
{
    uint32_t per_map = (uint32_t)((plan->points + PF_PROTO_IRR_CHUNK_POINTS - 1) / PF_PROTO_IRR_CHUNK_POINTS);
    int deep = i >= per_map;
    size_t first = (size_t)(i % per_map) * PF_PROTO_IRR_CHUNK_POINTS;
    size_t n = plan->points - first < PF_PROTO_IRR_CHUNK_POINTS ? plan->points - first : PF_PROTO_IRR_CHUNK_POINTS;
    if (i >= 2 * per_map)
        n = 1, first = 0, deep = 0;
    pf_photon_t *pts = malloc(n * sizeof *pts);
    pf_msg_photon_t *w = malloc(n * sizeof *w);
    int rc = pf_irradiance_points(global, deep ? &plan->deep : &plan->main, accel, 2, first, n, pts);
    for (size_t k = 0; k < n; k++) {
        memcpy(w[k].pos, pts[k].pos, sizeof w[k].pos);
        memcpy(w[k].power, pts[k].power, sizeof w[k].power);
        w[k].dir = pts[k].dir;
        w[k].normal = pts[k].normal;
    }
    if (how == S_MOVED)
        w[n / 2].pos[1] = nextafterf(w[n / 2].pos[1], INFINITY);
    if (how == S_WIDE) {
        float r = 2.0f * sqrtf(plan->main.max_r2);
        memcpy(&w[0].dir, &r, sizeof r);
    }
    if (how == S_BIT) {
        uint32_t b;
        memcpy(&b, &w[0].power[2], sizeof b);
        b ^= 1u;
        memcpy(&w[0].power[2], &b, sizeof b);
    }
    uint32_t sent = how == S_SHORT ? (uint32_t)n - 1 : (uint32_t)n;
    pf_msg_t m = { .type = PF_MSG_IRR_POINTS, .job = 1 };
    m.u.photons = (pf_msg_photons_t){ i, sent, 0, 0, 0, sent, NULL, w };
    pf_buf_t enc = { 0 };
    pf_msg_t d;
    char why[320];
    int verdict = -100;
    if (rc == PF_OK && pf_msg_encode(&m, &enc) == PF_OK && pf_msg_decode(enc.data, enc.len, &d, why, sizeof why) == PF_OK)
        verdict = pf_irq_on_points(q, uid, &d.u.photons, why, sizeof why);
    pf_buf_free(&enc);
    free(w);
    free(pts);
    return verdict;
}

typedef struct s_ctx {
    const pf_accel_t *accel;
    int checked;
} s_ctx;

/* The merge's hook: a worker's results, good and bad, then the photon
 * thread's run. */
static int s_points(void *ctx, const pf_photon_maps_t *maps, const pf_irr_plan_t *plan, pf_photon_t *main,
                    pf_photon_t *deep)
{
    s_ctx *c = ctx;
    const pf_kdtree_t *g = maps->global;
    CHECK(plan->has_deep && plan->points > 3 * PF_PROTO_IRR_CHUNK_POINTS, "plan: %zu points, deep %d", plan->points,
          plan->has_deep);
    pf_irq_t *q = pf_irq_new(g, c->accel, plan, main, deep);
    CHECK(q != NULL, "table");
    if (!q)
        return PF_ENOMEM;
    pf_irq_checks(q, 12345, 1u << 30); /* the sample passes nearly all: the first chunk's check catches the liar */
    uint32_t nc = pf_irq_chunks(q), first = 99;
    CHECK(pf_irq_lease(q, 5, 4, 0.0, &first) == 4 && first == 0, "lease 4 chunks to worker 5 (first %u)", first);
    CHECK(s_feed(q, g, c->accel, plan, 0, 5, S_OK) == PF_IRQ_DONE, "a good chunk");
    CHECK(s_feed(q, g, c->accel, plan, 0, 5, S_OK) == PF_IRQ_STALE, "the same chunk again: stale");
    CHECK(s_feed(q, g, c->accel, plan, 1, 5, S_MOVED) == PF_IRQ_BAD, "a point moved off its photon: refused");
    CHECK(s_feed(q, g, c->accel, plan, 2, 5, S_WIDE) == PF_IRQ_BAD, "a support radius past the search radius");
    CHECK(s_feed(q, g, c->accel, plan, 3, 5, S_SHORT) == PF_IRQ_BAD, "a chunk short of a point");
    CHECK(s_feed(q, g, c->accel, plan, nc + 3, 5, S_OK) == PF_IRQ_BAD, "a chunk not in the pass");
    CHECK(pf_irq_held(q, 5) == 0, "the refused chunks are free again");
    CHECK(s_feed(q, g, c->accel, plan, 1, 6, S_OK) == PF_IRQ_STALE, "a chunk not leased to the sender: dropped");
    CHECK(pf_irq_lease(q, 7, 1, 0.0, &first) == 1 && first == 1, "lease chunk 1 to worker 7 (%u)", first);
    CHECK(s_feed(q, g, c->accel, plan, 1, 7, S_BIT) == PF_IRQ_DONE, "a chunk one bit off is taken (for now)");
    CHECK(pf_irq_lease(q, 8, 2, 0.0, &first) == 2 && first == 2, "worker 8 takes chunks and never answers");
    int rc = pf_irq_run(q, 2);
    CHECK(rc == PF_OK, "run: %d", rc);
    uint32_t uid = 0;
    char why[160];
    CHECK(pf_irq_take_liar(q, &uid, why, sizeof why) == 1 && uid == 7, "worker 7 caught by the check (%u: %s)", uid,
          why);
    CHECK(s_feed(q, g, c->accel, plan, 2, 8, S_OK) == PF_IRQ_STALE, "a result after the run: stale");
    pf_irq_stats_t st;
    pf_irq_stats(q, &st);
    CHECK(st.chunks == nc && st.remote == 1 && st.local == nc - 1 && st.mismatches == 1 && st.stolen >= 1,
          "stats: %u chunks, %u local, %u remote, %llu mismatches, %llu stolen", st.chunks, st.local, st.remote,
          (unsigned long long)st.mismatches, (unsigned long long)st.stolen);
    c->checked = (int)st.checked;
    pf_irq_free(&q);
    return rc;
}

static int s_same_maps(const pf_photon_maps_t *a, const pf_photon_maps_t *b)
{
    pf_buf_t x = { 0 }, y = { 0 };
    int same = pf_mapfile_write(a, 1, 2, &x) == PF_OK && pf_mapfile_write(b, 1, 2, &y) == PF_OK && x.len == y.len &&
               memcmp(x.data, y.data, x.len) == 0;
    pf_buf_free(&x);
    pf_buf_free(&y);
    size_t n = a->irradiance_deep ? pf_kdtree_size(a->irradiance_deep) : 0;
    return same && b->irradiance_deep && n && n == pf_kdtree_size(b->irradiance_deep) &&
           memcmp(pf_kdtree_photons(a->irradiance_deep), pf_kdtree_photons(b->irradiance_deep), n * sizeof(pf_photon_t)) == 0;
}

static void s_test_spread(const pf_scene_t *scene)
{
    pf_frame_t fr;
    pf_error_t err = { { 0 } };
    CHECK(pf_frame_open(&fr, scene, &err) == PF_OK, "frame: %s", err.msg);
    pf_settings_t s = pf_settings_default();
    s.photons = 100000;
    s.caustic_photons = 20000;
    s.threads = 2;
    s.seed = 11;
    s.path_max_depth = 5;
    pf_photon_maps_t ref, mq;
    pf_photon_stats_t st_ref, st_q;
    memset(&st_q, 0, sizeof st_q);
    CHECK(pf_photon_pass(scene, fr.accel, fr.lights, &s, &ref, &st_ref) == PF_OK, "in-process pass");
    pf_photon_tracer_t *t = NULL;
    CHECK(pf_photon_tracer_new(scene, fr.accel, fr.lights, &s, 1, &t) == PF_OK, "tracer");
    const pf_photon_plan_t *pl = pf_photon_tracer_plan(t);
    uint32_t nb = pl->global_batches + pl->caustic_batches;
    pf_photon_batch_t *bs = calloc(nb, sizeof *bs);
    CHECK(pf_photon_trace_batches(t, 0, nb, 2, NULL, bs) == PF_OK, "batches");
    s_ctx c = { fr.accel, 0 };
    pf_irr_spread_t spread = { s_points, &c };
    CHECK(pf_photon_merge_spread(scene, fr.accel, &s, pl, bs, &mq, &st_q, &spread) == PF_OK, "merge, spread");
    CHECK(s_same_maps(&ref, &mq), "the maps (irradiance and deep) are the in-process ones, bit for bit");
    CHECK(c.checked >= 2, "worker chunks checked: %d", c.checked);
    free(bs);
    pf_photon_tracer_free(&t);
    pf_photon_maps_free(&ref);
    pf_photon_maps_free(&mq);
    pf_frame_close(&fr);
}

/* Encoder refuses (PF_EINVAL) and decoder rejects (a frame patched from a
 * valid one) what the IRR rules forbid. */
static void s_test_codec(void)
{
    pf_msg_photon_t p[2] = { { { 1, 2, 3 }, { 0.5f, 0, 1 }, 0x3f800000u, 7 }, { { 1, 2, 4 }, { 0, 0, 0 }, 0, 8 } };
    pf_msg_t m = { .type = PF_MSG_IRR_POINTS, .job = 3 };
    pf_buf_t b = { 0 };
    pf_msg_t d;
    char why[256];
    m.u.photons = (pf_msg_photons_t){ 9, 2, 0, 0, 0, 2, NULL, p };
    CHECK(pf_msg_encode(&m, &b) == PF_OK && pf_msg_decode(b.data, b.len, &d, why, sizeof why) == PF_OK &&
              d.type == PF_MSG_IRR_POINTS && d.u.photons.batch == 9 && d.u.photons.n == 2,
          "IRR_POINTS round trip: %s", why);
    for (size_t cut = 0; cut < b.len; cut++)
        CHECK(pf_msg_decode(b.data, cut, &d, why, sizeof why) == PF_EPARSE, "IRR_POINTS cut at %zu decodes", cut);
    /* total 3 for n 2 (bytes 20..27 after the header: batch u32 at 16, total u64 at 20) */
    b.data[20] = 3;
    CHECK(pf_msg_decode(b.data, b.len, &d, why, sizeof why) == PF_EPARSE && strstr(why, "one message"),
          "a chunk in parts is refused: %s", why);
    pf_msg_t bad = m;
    bad.u.photons.first = 1;
    CHECK(pf_msg_encode(&bad, &b) == PF_EINVAL, "first != 0");
    bad = m;
    bad.u.photons.batch = PF_PROTO_MAX_IRR_CHUNKS;
    CHECK(pf_msg_encode(&bad, &b) == PF_EINVAL, "a chunk past the limit");
    bad = m;
    bad.u.photons.n = bad.u.photons.total = 0;
    CHECK(pf_msg_encode(&bad, &b) == PF_EINVAL, "an empty chunk");
    bad = m;
    p[1].power[0] = -1.0f;
    CHECK(pf_msg_encode(&bad, &b) == PF_EINVAL, "a negative irradiance");
    p[1].power[0] = 0.0f;
    pf_msg_t r = { .type = PF_MSG_IRR_REQ, .job = 3 };
    r.u.irr_req = (pf_msg_irr_req_t){ 1, 100, 2, 200, pf_settings_default(), 0, 3 };
    r.u.irr_req.settings.width = r.u.irr_req.settings.height = 16;
    CHECK(pf_msg_encode(&r, &b) == PF_OK && pf_msg_decode(b.data, b.len, &d, why, sizeof why) == PF_OK &&
              d.u.irr_req.maps_hash == 2 && d.u.irr_req.count == 3,
          "IRR_REQ round trip: %s", why);
    for (size_t cut = 0; cut < b.len; cut++)
        CHECK(pf_msg_decode(b.data, cut, &d, why, sizeof why) == PF_EPARSE, "IRR_REQ cut at %zu decodes", cut);
    pf_msg_t br = r;
    br.u.irr_req.count = 0;
    CHECK(pf_msg_encode(&br, &b) == PF_EINVAL, "IRR_REQ count 0");
    br.u.irr_req.count = PF_PROTO_MAX_REQ_IRR_CHUNKS + 1;
    CHECK(pf_msg_encode(&br, &b) == PF_EINVAL, "IRR_REQ count past the limit");
    br = r;
    br.u.irr_req.first = PF_PROTO_MAX_IRR_CHUNKS - 1;
    CHECK(pf_msg_encode(&br, &b) == PF_EINVAL, "IRR_REQ range past the limit");
    br = r;
    br.u.irr_req.maps_size = 0;
    CHECK(pf_msg_encode(&br, &b) == PF_EINVAL, "IRR_REQ with an empty map blob");
    pf_buf_free(&b);
}

int main(void)
{
    pf_log_set_level(PF_LOG_WARN);
    s_test_codec();
    pf_error_t err = { { 0 } };
    pf_scene_t *scene = pf_scene_load("scenes/cornell-spheres/scene.json", &err);
    CHECK(scene != NULL, "load: %s", err.msg);
    if (scene)
        s_test_spread(scene);
    pf_scene_destroy(&scene);
    return pf_test_finish();
}
