/* test_photon_batches.c: the photon pass in batches gives the maps of the
 * in-process pass, bit for bit (serialized map blobs compared), whatever the
 * order the batches are traced in, the threads, and who traced them: the
 * coordinator's batch table (coordinator/ph_batches.c) fed with a worker's
 * results in parts (through the PHOTONS codec), a lease never answered
 * (stolen by the photon thread), a stale result, a duplicate and parts that
 * contradict each other. Cornell spheres: global and caustic batches.
 * Spot checks: a worker whose batch differs by one bit from the
 * coordinator's trace is caught even when the sample (1 in 2^30) would
 * pass it by (each worker gets one batch checked a pass), barred, its
 * batches traced again, and the maps are still the in-process ones. */
#include <stdlib.h>
#include <string.h>

#include "../check.h"
#include "base/log.h"
#include "coordinator/ph_batches.h"
#include "load/load.h"
#include "photon/mapfile.h"
#include "render/frame.h"

static int s_same_maps(const pf_photon_maps_t *a, const pf_photon_maps_t *b)
{
    pf_buf_t x = { 0 }, y = { 0 };
    int same = pf_mapfile_write(a, 1, 2, &x) == PF_OK && pf_mapfile_write(b, 1, 2, &y) == PF_OK && x.len == y.len &&
               memcmp(x.data, y.data, x.len) == 0;
    pf_buf_free(&x);
    pf_buf_free(&y);
    return same;
}

static int s_corrupt; /* s_feed flips a bit of the batch's first photon's power */

/* Batch `batch` as a worker sends it: PHOTONS parts of `part` photons,
 * encoded and decoded, fed to the table as worker uid. Returns the last
 * verdict; first_at: the part offset to forge (or UINT64_MAX). */
static int s_feed(pf_phq_t *q, const pf_photon_tracer_t *t, uint32_t batch, uint32_t uid, uint32_t part,
                  uint64_t forge_at)
{
    pf_photon_batch_t b;
    if (pf_photon_trace_batch(t, batch, 1, NULL, &b) != PF_OK)
        return -100;
    pf_msg_photon_t *ph = malloc((b.n + 1) * sizeof *ph);
    for (size_t i = 0; i < b.n; i++) {
        memcpy(ph[i].pos, b.p[i].pos, sizeof ph[i].pos);
        memcpy(ph[i].power, b.p[i].power, sizeof ph[i].power);
        ph[i].dir = b.p[i].dir;
        ph[i].normal = b.p[i].normal;
    }
    if (s_corrupt && b.n) {
        uint32_t bits;
        memcpy(&bits, &ph[0].power[0], sizeof bits);
        bits ^= 1u; /* the last bit of the mantissa: still finite, still >= 0 */
        memcpy(&ph[0].power[0], &bits, sizeof bits);
    }
    int verdict = PF_PHQ_PART;
    pf_buf_t enc = { 0 };
    for (uint64_t first = 0; first < b.n || (b.n == 0 && first == 0); first += part) {
        uint32_t n = (uint32_t)(b.n - first < part ? b.n - first : part);
        pf_msg_t m = { .type = PF_MSG_PHOTONS, .job = 1 };
        m.u.photons = (pf_msg_photons_t){ batch, b.n, first == forge_at ? first + 1 : first, b.rejected, b.indirect, n,
                                          NULL, ph + first };
        pf_msg_t d;
        char why[256];
        if (pf_msg_encode(&m, &enc) != PF_OK || pf_msg_decode(enc.data, enc.len, &d, why, sizeof why) != PF_OK) {
            verdict = -200;
            break;
        }
        verdict = pf_phq_on_photons(q, uid, &d.u.photons, why, sizeof why);
        if (verdict == PF_PHQ_BAD || verdict == PF_PHQ_STALE || b.n == 0)
            break;
    }
    pf_buf_free(&enc);
    free(ph);
    free(b.p);
    return verdict;
}

static void s_test(const pf_scene_t *scene)
{
    pf_frame_t fr;
    pf_error_t err = { { 0 } };
    CHECK(pf_frame_open(&fr, scene, &err) == PF_OK, "frame: %s", err.msg);
    pf_settings_t s = pf_settings_default();
    s.photons = 150000;
    s.caustic_photons = 80000;
    s.threads = 2;
    s.seed = 7;
    pf_photon_maps_t ref, mb, mq;
    pf_photon_stats_t st_ref, st_b, st_q;
    CHECK(pf_photon_pass(scene, fr.accel, fr.lights, &s, &ref, &st_ref) == PF_OK, "in-process pass");

    /* Every batch, in reverse order, one thread each, then merged. */
    pf_photon_tracer_t *t = NULL;
    CHECK(pf_photon_tracer_new(scene, fr.accel, fr.lights, &s, 1, &t) == PF_OK, "tracer");
    const pf_photon_plan_t *pl = pf_photon_tracer_plan(t);
    uint32_t nb = pl->global_batches + pl->caustic_batches;
    CHECK(pl->global_batches == 3 && pl->caustic_batches == 2, "plan: %u global + %u caustic batches",
          pl->global_batches, pl->caustic_batches);
    pf_photon_batch_t *bs = calloc(nb, sizeof *bs);
    for (uint32_t i = nb; i-- > 0;)
        CHECK(pf_photon_trace_batch(t, i, 1, NULL, &bs[i]) == PF_OK, "batch %u", i);
    pf_photon_batch_t extra;
    CHECK(pf_photon_trace_batch(t, nb, 1, NULL, &extra) == PF_EINVAL, "a batch past the plan is refused");
    memset(&st_b, 0, sizeof st_b);
    CHECK(pf_photon_merge(scene, fr.accel, &s, pl, bs, &mb, &st_b) == PF_OK, "merge");
    CHECK(s_same_maps(&ref, &mb), "batches merged give the in-process maps, bit for bit");
    CHECK(st_b.global_stored == st_ref.global_stored && st_b.caustic_stored == st_ref.caustic_stored &&
              st_b.indirect_stored == st_ref.indirect_stored && st_b.rejected == st_ref.rejected,
          "the counters agree (%llu/%llu global, %llu/%llu indirect)", (unsigned long long)st_b.global_stored,
          (unsigned long long)st_ref.global_stored, (unsigned long long)st_b.indirect_stored,
          (unsigned long long)st_ref.indirect_stored);
    free(bs);

    /* The coordinator's table: worker 7 returns batch 0 in parts and the
     * caustic batch 5; worker 9 holds batch 1 and never answers (stolen). */
    pf_phq_t *q = pf_phq_new(t, s.photon_max_depth);
    uint32_t first = 99;
    CHECK(pf_phq_lease(q, 7, 1, 0.0, &first) == 1 && first == 0, "lease batch 0 to 7");
    CHECK(pf_phq_lease(q, 9, 1, 0.0, &first) == 1 && first == 1, "lease batch 1 to 9");
    CHECK(s_feed(q, t, 0, 8, 5000, UINT64_MAX) == PF_PHQ_STALE, "a result from a worker that does not hold it is stale");
    CHECK(s_feed(q, t, 0, 7, 5000, 10000) == PF_PHQ_BAD, "a part out of order is refused");
    CHECK(pf_phq_held(q, 7) == 0, "... and its batch is no longer leased");
    CHECK(pf_phq_lease(q, 7, 1, 0.0, &first) == 1 && first == 0, "lease batch 0 to 7 again");
    CHECK(s_feed(q, t, 0, 7, 5000, UINT64_MAX) == PF_PHQ_DONE, "batch 0 in parts is done");
    CHECK(s_feed(q, t, 0, 7, 5000, UINT64_MAX) == PF_PHQ_STALE, "a duplicate is stale");
    uint32_t n = pf_phq_lease(q, 7, 64, 0.0, &first);
    CHECK(n == nb - 2 && first == 2, "the rest leased to 7 (%u from %u)", n, first);
    pf_phq_release(q, 7);
    CHECK(pf_phq_held(q, 7) == 0 && pf_phq_held(q, 9) == 1, "released");
    CHECK(pf_phq_lease(q, 7, 1, 0.0, &first) == 1 && first == 2, "lease batch 2 to 7");
    CHECK(pf_phq_expire(q, 100.0, 30.0) == 2, "both leases expire");
    CHECK(pf_phq_lease(q, 7, 1, 0.0, &first) == 1 && first == 1, "batch 1 leased to 7 (9's expired)");
    CHECK(pf_phq_lease(q, 7, 1, 0.0, &first) == 1 && first == 2, "batch 2 leased to 7");
    CHECK(s_feed(q, t, 2, 7, PF_PROTO_MAX_PART_PHOTONS, UINT64_MAX) == PF_PHQ_DONE, "batch 2 in one part");
    CHECK(pf_phq_run(q, 2) == PF_OK, "the photon thread traces the rest (and steals batch 1)");
    pf_phq_stats_t st;
    pf_phq_stats(q, &st);
    CHECK(st.remote == 2 && st.local == nb - 2 && st.stolen == 1 && st.expired == 2,
          "stats: %u remote, %u local, %llu stolen, %llu expired", st.remote, st.local,
          (unsigned long long)st.stolen, (unsigned long long)st.expired);
    CHECK(s_feed(q, t, 1, 7, 5000, UINT64_MAX) == PF_PHQ_STALE, "a result after the photon thread traced it is stale");
    memset(&st_q, 0, sizeof st_q);
    CHECK(pf_phq_merge(q, scene, fr.accel, &s, &mq, &st_q, NULL) == PF_OK, "table merge");
    CHECK(s_same_maps(&ref, &mq), "the table's maps are the in-process ones, bit for bit");
    pf_phq_free(&q);

    /* Spot checks: worker 7 returns batches 0 and 1 honestly, worker 8
     * batch 2 with one bit flipped. A sample of 1 in 2^30 draws neither,
     * but each worker gets one batch checked once all are in. */
    pf_photon_maps_t mc;
    q = pf_phq_new(t, s.photon_max_depth);
    pf_phq_checks(q, 0x5eed5eedULL, 1u << 30);
    CHECK(pf_phq_lease(q, 7, 2, 0.0, &first) == 2 && first == 0, "lease batches 0, 1 to 7");
    CHECK(pf_phq_lease(q, 8, 1, 0.0, &first) == 1 && first == 2, "lease batch 2 to 8");
    CHECK(s_feed(q, t, 0, 7, 5000, UINT64_MAX) == PF_PHQ_DONE && s_feed(q, t, 1, 7, 5000, UINT64_MAX) == PF_PHQ_DONE,
          "7's batches are in");
    s_corrupt = 1;
    CHECK(s_feed(q, t, 2, 8, 5000, UINT64_MAX) == PF_PHQ_DONE, "8's forged batch passes the structural checks");
    s_corrupt = 0;
    CHECK(pf_phq_run(q, 2) == PF_OK, "the photon thread traces the rest and checks");
    pf_phq_stats(q, &st);
    uint32_t liar = 0;
    char why[160] = "";
    CHECK(pf_phq_take_liar(q, &liar, why, sizeof why) == 1 && liar == 8, "worker 8 is named (%u: %s)", liar, why);
    CHECK(pf_phq_take_liar(q, &liar, why, sizeof why) == 0, "and only worker 8");
    CHECK(strstr(why, "photon batch 2 differs") != NULL, "why names the batch: %s", why);
    CHECK(st.checked == 2 && st.mismatches == 1 && st.discarded == 1 && st.remote == 2 && st.local == nb - 2,
          "stats: %llu checked, %llu mismatches, %llu discarded, %u remote, %u local", (unsigned long long)st.checked,
          (unsigned long long)st.mismatches, (unsigned long long)st.discarded, st.remote, st.local);
    CHECK(pf_phq_lease(q, 8, 1, 0.0, &first) == 0, "the liar is barred");
    memset(&st_q, 0, sizeof st_q);
    CHECK(pf_phq_merge(q, scene, fr.accel, &s, &mc, &st_q, NULL) == PF_OK, "checked table merge");
    CHECK(s_same_maps(&ref, &mc), "after the lie the maps are the in-process ones, bit for bit");
    pf_photon_maps_free(&mc);
    pf_phq_free(&q);

    /* Every batch checked (1 in 1): the liar's two batches both discarded. */
    q = pf_phq_new(t, s.photon_max_depth);
    pf_phq_checks(q, 1, 1);
    CHECK(pf_phq_lease(q, 8, 2, 0.0, &first) == 2 && first == 0, "lease batches 0, 1 to 8");
    s_corrupt = 1;
    CHECK(s_feed(q, t, 0, 8, 5000, UINT64_MAX) == PF_PHQ_DONE, "8's forged batch 0");
    s_corrupt = 0;
    CHECK(s_feed(q, t, 1, 8, 5000, UINT64_MAX) == PF_PHQ_DONE, "8's honest batch 1");
    CHECK(pf_phq_run(q, 2) == PF_OK, "the photon thread traces and checks");
    pf_phq_stats(q, &st);
    CHECK(st.mismatches == 1 && st.discarded == 2 && st.remote == 0 && st.local == nb,
          "stats: %llu mismatches, %llu discarded, %u remote", (unsigned long long)st.mismatches,
          (unsigned long long)st.discarded, st.remote);
    CHECK(pf_phq_merge(q, scene, fr.accel, &s, &mc, &st_q, NULL) == PF_OK && s_same_maps(&ref, &mc),
          "the maps are the in-process ones");
    pf_photon_maps_free(&mc);
    pf_phq_free(&q);
    pf_photon_tracer_free(&t);
    pf_photon_maps_free(&ref);
    pf_photon_maps_free(&mb);
    pf_photon_maps_free(&mq);
    pf_frame_close(&fr);
}

int main(void)
{
    pf_log_set_level(PF_LOG_WARN);
    pf_error_t err = { { 0 } };
    pf_scene_t *scene = pf_scene_load("scenes/cornell-spheres/scene.json", &err);
    CHECK(scene != NULL, "load: %s", err.msg);
    if (scene)
        s_test(scene);
    pf_scene_destroy(&scene);
    return pf_test_finish();
}
