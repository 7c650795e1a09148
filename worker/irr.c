/* irr.c: the worker's share of the coordinator's irradiance precompute.
 *
 * An IRR_REQ names the scene blob, a map blob holding the pass's global
 * map (no caustic or irradiance photons), the pass's settings and a range
 * of chunks (messages.h: chunk c of the irradiance map is points [c * 4096,
 * ...), chunk C + c the same points of the deep map). The worker fetches
 * the blobs it does not hold (the scene blob it traced photons over is
 * usually there), then the compute thread reads the map blob once per hash
 * (validated field by field, pf_mapfile_read), builds the scene's accel
 * once per scene hash (shared with the photon batches, pf_w_scene_frame)
 * and computes each chunk's points with pf_irradiance_points and the
 * worker's threads. Each chunk goes back as one IRR_POINTS. The records
 * are those the coordinator's own precompute makes for the same indices
 * (each point's estimate is a pure function of the map, the scene and the
 * point), so who computed a chunk never shows in the maps.
 *
 * The chunks belong to the photon job (w->pjob): JOB, JOB_END, BYE or a
 * lost coordinator drop them with it. Handlers run in the main thread;
 * pf_w_compute_irr in the compute thread, which alone touches w->irr_maps. */
#include <inttypes.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "photon/mapfile.h"
#include "photon/trace.h"
#include "worker/worker_impl.h"

#define S_CHUNK PF_PROTO_IRR_CHUNK_POINTS

static void s_enqueue(s_worker *w, s_blob *sb, s_blob *mb, uint32_t first, uint32_t count)
{
    s_work *it = calloc(1, sizeof *it);
    if (!it) {
        pf_w_log(w, PF_LOG_ERROR, "out of memory for irradiance chunks %" PRIu32 "+%" PRIu32, first, count);
        return;
    }
    it->kind = S_WORK_IRR;
    it->job = w->pjob;
    w->pjob->refs++;
    it->scene_blob = sb;
    sb->pins++;
    it->maps_blob = mb;
    mb->pins++;
    it->ph_first = first;
    it->ph_count = count;
    pf_w_enqueue(w, it);
}

/* The range's blobs when both are here (and pins them via s_enqueue);
 * 1 when the range went to the compute thread, 0 when it waits, -1 when a
 * blob cannot be fetched. */
static int s_try(s_worker *w, const pf_msg_irr_req_t *q)
{
    s_blob *sb = pf_w_blob_get(w, q->scene_hash, q->scene_size, "scene");
    s_blob *mb = sb ? pf_w_blob_get(w, q->maps_hash, q->maps_size, "irradiance map") : NULL;
    if (!sb || !mb)
        return -1;
    if (!sb->complete || !mb->complete)
        return 0;
    s_enqueue(w, sb, mb, q->first, q->count);
    return 1;
}

void pf_w_on_irr_req(s_worker *w, const pf_msg_t *m)
{
    const pf_msg_irr_req_t *q = &m->u.irr_req;
    s_job *j = pf_w_photons_job(w, m->job, q->scene_hash, q->scene_size, &q->settings, "computing irradiance chunks");
    if (!j)
        return;
    if (j->desc.maps_hash != q->maps_hash || j->desc.maps_size != q->maps_size) {
        j->desc.maps_hash = q->maps_hash; /* the blob the cache must keep for this job (jobs.c) */
        j->desc.maps_size = q->maps_size;
        pf_w_log(w, PF_LOG_INFO, "job %" PRIu64 ": computing irradiance chunks (map blob %016" PRIx64 ")", j->id,
                 q->maps_hash);
    }
    int rc = s_try(w, q);
    if (rc < 0) {
        pf_w_photons_drop(w, "cannot fetch the blobs of the irradiance chunks");
        return;
    }
    if (rc > 0)
        return;
    if (w->nirr_wait < (int)(sizeof w->irr_wait / sizeof w->irr_wait[0]))
        w->irr_wait[w->nirr_wait++] = *q;
    else
        pf_w_log(w, PF_LOG_WARN, "irradiance chunks %" PRIu32 "+%" PRIu32 " asked while %d ranges wait; dropped",
                 q->first, q->count, w->nirr_wait);
}

void pf_w_irr_advance(s_worker *w)
{
    if (!w->pjob)
        return;
    int kept = 0;
    for (int i = 0; i < w->nirr_wait; i++) {
        int rc = s_try(w, &w->irr_wait[i]);
        if (rc == 0)
            w->irr_wait[kept++] = w->irr_wait[i];
    }
    w->nirr_wait = kept;
}

/* Compute thread: w->irr_maps read from the item's map blob (once per
 * hash). 0, or -1 with it->error set. */
static int s_maps(s_worker *w, s_work *it)
{
    const pf_msg_job_t *d = &it->job->desc;
    if (w->irr_maps_hash == it->maps_blob->hash && w->irr_maps.global)
        return 0;
    pf_photon_maps_free(&w->irr_maps);
    w->irr_maps_hash = 0;
    pf_error_t err = { { 0 } };
    if (pf_mapfile_read(it->maps_blob->data, (size_t)it->maps_blob->size, d->scene_hash,
                        pf_settings_hash(&d->settings), &w->irr_maps, &err) != PF_OK) {
        snprintf(it->error, sizeof it->error, "irradiance map blob %016" PRIx64 " rejected: %s", it->maps_blob->hash,
                 err.msg);
        return -1;
    }
    w->irr_maps_hash = it->maps_blob->hash;
    return 0;
}

void pf_w_compute_irr(s_worker *w, s_work *it)
{
    double t0 = pf_now();
    if (pf_w_scene_frame(w, it) != 0 || s_maps(w, it) != 0)
        return;
    pf_irr_plan_t plan;
    pf_photon_irr_plan(&w->irr_maps, &it->job->desc.settings, &plan);
    uint64_t per_map = (plan.points + S_CHUNK - 1) / S_CHUNK;
    uint64_t nc = per_map * (plan.has_deep ? 2u : 1u);
    if ((uint64_t)it->ph_first + it->ph_count > nc) {
        snprintf(it->error, sizeof it->error, "irradiance chunks %" PRIu32 "+%" PRIu32 " are not in this pass (%" PRIu64
                 " chunks)", it->ph_first, it->ph_count, nc);
        return;
    }
    it->irr_pts = malloc((size_t)it->ph_count * S_CHUNK * sizeof *it->irr_pts);
    it->irr_n = calloc(it->ph_count, sizeof *it->irr_n);
    int rc = it->irr_pts && it->irr_n ? PF_OK : PF_ENOMEM;
    for (uint32_t k = 0; k < it->ph_count && rc == PF_OK && !atomic_load(&it->job->cancelled); k++) {
        uint64_t c = (uint64_t)it->ph_first + k;
        int deep = c >= per_map;
        size_t first = (size_t)(c - (deep ? per_map : 0)) * S_CHUNK;
        size_t n = plan.points - first < S_CHUNK ? plan.points - first : S_CHUNK;
        rc = pf_irradiance_points(w->irr_maps.global, deep ? &plan.deep : &plan.main, w->ph_frame.accel, w->threads,
                                  first, n, it->irr_pts + (size_t)k * S_CHUNK);
        it->irr_n[k] = (uint32_t)n;
    }
    if (rc != PF_OK)
        snprintf(it->error, sizeof it->error, "irradiance chunks %" PRIu32 "+%" PRIu32 ": %s", it->ph_first,
                 it->ph_count, pf_strerror(rc));
    it->ph_s = pf_now() - t0;
}

void pf_w_irr_sent(s_worker *w, s_work *it)
{
    s_job *j = it->job;
    if (j != w->pjob || atomic_load(&j->cancelled) || w->conn != S_ONLINE)
        return;
    if (it->error[0] || !it->irr_n) {
        pf_w_log(w, PF_LOG_ERROR, "job %" PRIu64 ": %s", j->id, it->error[0] ? it->error : "irradiance chunks lost");
        return; /* the coordinator's lease runs out and someone else computes them */
    }
    pf_msg_photon_t *part = malloc(S_CHUNK * sizeof *part);
    if (!part) {
        pf_w_log(w, PF_LOG_ERROR, "out of memory sending irradiance chunks");
        return;
    }
    for (uint32_t k = 0; k < it->ph_count; k++) {
        const pf_photon_t *p = it->irr_pts + (size_t)k * S_CHUNK;
        for (uint32_t i = 0; i < it->irr_n[k]; i++) {
            memcpy(part[i].pos, p[i].pos, sizeof part[i].pos);
            memcpy(part[i].power, p[i].power, sizeof part[i].power);
            part[i].dir = p[i].dir;
            part[i].normal = p[i].normal;
        }
        pf_msg_t m;
        memset(&m, 0, sizeof m);
        m.type = PF_MSG_IRR_POINTS;
        m.job = j->id;
        m.u.photons = (pf_msg_photons_t){ it->ph_first + k, it->irr_n[k], 0, 0, 0, it->irr_n[k], NULL, part };
        pf_w_send(w, &m, 0);
    }
    free(part);
    pf_w_log(w, PF_LOG_DEBUG, "job %" PRIu64 ": irradiance chunks %" PRIu32 "+%" PRIu32 " computed in %.3f s", j->id,
             it->ph_first, it->ph_count, it->ph_s);
}
