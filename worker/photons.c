/* photons.c: the worker's share of the coordinator's photon pass.
 *
 * A PHOTON_REQ names the scene blob, the pass's settings (seed, photon
 * counts, depth) and a range of batches (photon/trace.h: a batch is a run of
 * blocks of one map). The worker fetches the scene blob if it does not hold
 * it (the coordinator serves it before any map exists), then the compute
 * thread builds the scene's accel and lights once per scene hash and traces
 * the batches with the worker's OpenMP threads; each batch goes back as
 * PHOTONS messages of at most PF_PROTO_MAX_PART_PHOTONS photons, with the
 * batch's counters. The photons are exactly those the coordinator would have
 * stored for the same indices (photon i draws from stream (seed, i) alone),
 * so which process traced a batch never shows in the maps.
 *
 * The photon job lives beside the render job (w->pjob): it ends when the
 * render job's JOB arrives (the photon pass is over then), with JOB_END, BYE
 * or a lost coordinator (pf_w_job_drop calls pf_w_photons_drop). Handlers
 * run in the main thread; pf_w_compute_photons in the compute thread, which
 * alone touches w->ph_frame (pf_w_scene_frame): the same scene, accel and
 * lights serve the photon batches and, shared (pf_frame_share), every
 * render frame of that scene (compute.c), so a worker builds a scene once
 * however many passes and maps come. */
#include <inttypes.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "photon/mapfile.h"
#include "photon/trace.h"
#include "proto/sceneblob.h"
#include "worker/worker_impl.h"

_Static_assert(sizeof(pf_photon_t) == PF_PROTO_PHOTON_BYTES, "a photon is 32 bytes on the wire");

/* Queues batches [first, first + count) of the photon job for the compute thread. */
static void s_enqueue(s_worker *w, s_blob *sb, uint32_t first, uint32_t count)
{
    s_work *it = calloc(1, sizeof *it);
    if (!it) {
        pf_w_log(w, PF_LOG_ERROR, "out of memory for photon batches %" PRIu32 "..%" PRIu32, first, first + count);
        return;
    }
    it->kind = S_WORK_PHOTONS;
    it->job = w->pjob;
    w->pjob->refs++;
    it->scene_blob = sb;
    sb->pins++;
    it->ph_first = first;
    it->ph_count = count;
    pf_w_enqueue(w, it);
}

void pf_w_photons_drop(s_worker *w, const char *why)
{
    s_job *j = w->pjob;
    if (!j)
        return;
    pf_w_log(w, PF_LOG_DEBUG, "dropping photon job %" PRIu64 " (%s)", j->id, why);
    atomic_store(&j->cancelled, 1);
    w->pjob = NULL;
    w->nph_wait = 0;
    s_work *drop = pf_w_unqueue_job(w, j);
    while (drop) {
        s_work *next = drop->next;
        pf_w_work_free(drop);
        drop = next;
    }
    pf_w_job_release(j);
    pf_w_blobs_trim(w);
}

void pf_w_photons_advance(s_worker *w)
{
    s_job *j = w->pjob;
    if (!j || !w->nph_wait)
        return;
    s_blob *sb = pf_w_blob_get(w, j->desc.scene_hash, j->desc.scene_size, "scene");
    if (!sb || !sb->complete)
        return;
    for (int i = 0; i < w->nph_wait; i++)
        s_enqueue(w, sb, w->ph_wait[i].first, w->ph_wait[i].count);
    w->nph_wait = 0;
}

void pf_w_on_photon_req(s_worker *w, const pf_msg_t *m)
{
    const pf_msg_photon_req_t *q = &m->u.photon_req;
    s_job *j = w->pjob;
    if (!j || j->id != m->job || j->desc.scene_hash != q->scene_hash || j->desc.scene_size != q->scene_size ||
        pf_settings_hash(&j->desc.settings) != pf_settings_hash(&q->settings)) {
        pf_w_photons_drop(w, "a new photon pass");
        j = calloc(1, sizeof *j);
        if (!j) {
            pf_w_log(w, PF_LOG_ERROR, "job %" PRIu64 ": out of memory for the photon pass", m->job);
            return;
        }
        j->id = m->job;
        j->desc.scene_hash = q->scene_hash;
        j->desc.scene_size = q->scene_size;
        j->desc.settings = q->settings;
        j->refs = 1;
        atomic_init(&j->cancelled, 0);
        w->pjob = j;
        pf_w_log(w, PF_LOG_INFO, "job %" PRIu64 ": tracing photon batches (scene %016" PRIx64 ")", j->id,
                 q->scene_hash);
    }
    s_blob *sb = pf_w_blob_get(w, q->scene_hash, q->scene_size, "scene");
    if (!sb) {
        pf_w_photons_drop(w, "cannot fetch the scene blob");
        return;
    }
    if (sb->complete) {
        s_enqueue(w, sb, q->first, q->count);
        return;
    }
    /* The coordinator leases one range at a time; a few more are kept in
     * case it asks again while the scene is still coming. */
    if (w->nph_wait < (int)(sizeof w->ph_wait / sizeof w->ph_wait[0]))
        w->ph_wait[w->nph_wait++] = *q;
    else
        pf_w_log(w, PF_LOG_WARN, "photon batches %" PRIu32 "+%" PRIu32 " asked while %d ranges wait; dropped", q->first,
                 q->count, w->nph_wait);
}

int pf_w_scene_frame(s_worker *w, s_work *it)
{
    const pf_msg_job_t *d = &it->job->desc;
    if (w->ph_frame_ok && w->ph_frame_hash == d->scene_hash)
        return 0;
    pf_frame_close(&w->ph_frame);
    w->ph_frame_ok = 0;
    pf_error_t err = { { 0 } };
    pf_scene_t *scene = pf_sceneblob_read(it->scene_blob->data, (size_t)it->scene_blob->size, &err);
    if (!scene) {
        snprintf(it->error, sizeof it->error, "scene blob %016" PRIx64 " rejected: %s", d->scene_hash, err.msg);
        return -1;
    }
    if (pf_frame_open_owned(&w->ph_frame, &scene, &err) != PF_OK) {
        snprintf(it->error, sizeof it->error, "cannot build the ray-tracing structure: %s", err.msg);
        return -1;
    }
    w->ph_frame_ok = 1;
    w->ph_frame_hash = d->scene_hash;
    return 0;
}

void pf_w_compute_photons(s_worker *w, s_work *it)
{
    double t0 = pf_now();
    if (pf_w_scene_frame(w, it) != 0)
        return;
    pf_settings_t s = it->job->desc.settings;
    s.threads = w->threads;
    pf_photon_tracer_t *t = NULL;
    int rc = pf_photon_tracer_new(w->ph_frame.scene, w->ph_frame.accel, w->ph_frame.lights, &s, 1, &t);
    if (rc == PF_OK) {
        const pf_photon_plan_t *pl = pf_photon_tracer_plan(t);
        if ((uint64_t)it->ph_first + it->ph_count > (uint64_t)pl->global_batches + pl->caustic_batches)
            rc = PF_EINVAL;
    }
    it->ph_out = rc == PF_OK ? calloc(it->ph_count, sizeof *it->ph_out) : NULL;
    if (rc == PF_OK && !it->ph_out)
        rc = PF_ENOMEM;
    if (rc == PF_OK)
        rc = pf_photon_trace_batches(t, it->ph_first, it->ph_count, w->threads, NULL, it->ph_out);
    pf_photon_tracer_free(&t);
    if (rc != PF_OK)
        snprintf(it->error, sizeof it->error, "photon batches %" PRIu32 "+%" PRIu32 ": %s", it->ph_first, it->ph_count,
                 rc == PF_EINVAL ? "not in this pass" : pf_strerror(rc));
    it->ph_s = pf_now() - t0;
}

/* One batch as PHOTONS messages of at most PF_PROTO_MAX_PART_PHOTONS. */
static void s_send_batch(s_worker *w, uint64_t job, uint32_t batch, const pf_photon_batch_t *b)
{
    pf_msg_photon_t *part = malloc((b->n < PF_PROTO_MAX_PART_PHOTONS ? b->n + 1 : PF_PROTO_MAX_PART_PHOTONS) *
                                   sizeof *part);
    if (!part) {
        pf_w_log(w, PF_LOG_ERROR, "out of memory sending photon batch %" PRIu32, batch);
        return;
    }
    uint64_t first = 0;
    do {
        uint64_t n = b->n - first < PF_PROTO_MAX_PART_PHOTONS ? b->n - first : PF_PROTO_MAX_PART_PHOTONS;
        for (uint64_t i = 0; i < n; i++) {
            const pf_photon_t *p = &b->p[first + i];
            memcpy(part[i].pos, p->pos, sizeof part[i].pos);
            memcpy(part[i].power, p->power, sizeof part[i].power);
            part[i].dir = p->dir;
            part[i].normal = p->normal;
        }
        pf_msg_t m;
        memset(&m, 0, sizeof m);
        m.type = PF_MSG_PHOTONS;
        m.job = job;
        m.u.photons = (pf_msg_photons_t){ batch, b->n, first, b->rejected, b->indirect, (uint32_t)n, NULL, part };
        pf_w_send(w, &m, 0);
        first += n;
    } while (first < b->n);
    free(part);
}

void pf_w_photons_sent(s_worker *w, s_work *it)
{
    s_job *j = it->job;
    if (j != w->pjob || atomic_load(&j->cancelled) || w->conn != S_ONLINE)
        return;
    if (it->error[0]) {
        pf_w_log(w, PF_LOG_ERROR, "job %" PRIu64 ": %s", j->id, it->error);
        return; /* the coordinator's lease runs out and someone else traces them */
    }
    uint64_t n = 0;
    for (uint32_t k = 0; k < it->ph_count; k++) {
        s_send_batch(w, j->id, it->ph_first + k, &it->ph_out[k]);
        n += it->ph_out[k].n;
    }
    pf_w_log(w, PF_LOG_DEBUG, "job %" PRIu64 ": photon batches %" PRIu32 "+%" PRIu32 " traced in %.3f s, %" PRIu64
             " photons sent", j->id, it->ph_first, it->ph_count, it->ph_s, n);
}
