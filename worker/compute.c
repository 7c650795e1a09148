/* compute.c: the worker's compute thread and the queue that feeds it.
 *
 * The compute thread does everything slow: it rebuilds a job's scene,
 * Embree structure, lights and photon maps from the received blobs, and
 * renders leased tiles, each with an OpenMP team over rows. Work goes to it
 * through a mutex + condition variable queue; finished items come back on a
 * second list, and a byte written to a pipe (pollable by zmq_poll) wakes the
 * main thread to take them back (pf_w_drain_done in jobs.c).
 *
 * This file owns the thread, the queue's lock, condition variable and pipe.
 * The compute thread runs s_compute_main and what it calls; every pf_w_
 * function here is called by the main thread. A work item holds a reference
 * to its job (and a BUILD item pins its two blobs) from the moment it is
 * queued until the main thread takes it back, so the compute thread reads
 * them without further locks (the queue's mutex orders the hand-over). It
 * checks the job's atomic cancelled flag between rows. */
#include <errno.h>
#include <fcntl.h>
#include <inttypes.h>
#include <signal.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <unistd.h>

#include "accel/accel.h"
#include "photon/mapfile.h"
#include "photon/trace.h"
#include "worker/worker_impl.h"

/* ---- reference counting (main thread only) ---- */

void pf_w_built_release(s_built *b)
{
    if (!b || --b->refs > 0)
        return;
    pf_frame_close(&b->frame);
    free(b);
}

void pf_w_job_release(s_job *j)
{
    if (!j || --j->refs > 0)
        return;
    pf_w_built_release(j->built);
    free(j);
}

void pf_w_work_free(s_work *it)
{
    if (!it)
        return;
    if (it->kind != S_WORK_TILE) {
        if (it->scene_blob)
            it->scene_blob->pins--;
        if (it->maps_blob)
            it->maps_blob->pins--;
        pf_w_built_release(it->built);
    }
    if (it->ph_out) {
        for (uint32_t k = 0; k < it->ph_count; k++)
            free(it->ph_out[k].p);
        free(it->ph_out);
    }
    free(it->rgb);
    pf_w_job_release(it->job);
    free(it);
}

/* ---- the compute thread ---- */

/* Builds the job's frame: the scene, accel and lights shared with the
 * compute thread's frame of that scene (built from the scene blob only when
 * it is a new scene: pf_w_scene_frame), the maps, texels and deep points
 * from the maps blob. */
static void s_compute_build(s_worker *w, s_work *it)
{
    const pf_msg_job_t *d = &it->job->desc;
    pf_error_t err = { { 0 } };
    s_built *b = calloc(1, sizeof *b);
    if (!b) {
        snprintf(it->error, sizeof it->error, "out of memory");
        return;
    }
    b->scene_hash = d->scene_hash;
    b->maps_hash = d->maps_hash;
    b->settings_hash = pf_settings_hash(&d->settings);
    b->refs = 1;
    if (pf_w_scene_frame(w, it) != 0)
        goto fail;
    if (pf_frame_share(&b->frame, &w->ph_frame) != PF_OK) {
        snprintf(it->error, sizeof it->error, "out of memory");
        goto fail;
    }
    if (pf_frame_read_maps(&b->frame, it->maps_blob->data, it->maps_blob->size, d->scene_hash, d->maps_hash,
                           &d->settings, &err) != PF_OK) {
        snprintf(it->error, sizeof it->error, "%s", err.msg);
        goto fail;
    }
    it->built = b;
    return;
fail:
    pf_w_built_release(b);
}

/* Renders one tile: OpenMP over its rows, each recording the first-gather
 * records it needs that no other row has (pf_tile_plan_t), so progress moves
 * row by row for the watchdog; the pixels are those of any other split of
 * the image. */
static void s_compute_tile(s_worker *w, s_work *it)
{
    s_job *job = it->job;
    const pf_render_ctx_t *ctx = &job->ctx;
    int x0 = (int)it->tile.x0, y0 = (int)it->tile.y0, tw = (int)it->tile.w, th = (int)it->tile.h;
    float *out = it->rgb;
    double t0 = pf_now();
    pf_tile_plan_t *plan = pf_tile_plan_new(ctx, x0, y0, tw, th);
#pragma omp parallel num_threads(w->threads)
    {
        pf_accel_thread_init();
#pragma omp for schedule(dynamic, 1)
        for (int row = 0; row < th; row++) {
            if (atomic_load_explicit(&job->cancelled, memory_order_relaxed))
                continue;
            pf_tile_plan_render_row(plan, row, out + (size_t)row * (size_t)tw * 3);
            atomic_fetch_add_explicit(&w->progress, (uint_fast64_t)tw, memory_order_relaxed);
        }
    }
    pf_tile_plan_free(plan);
    double us = (pf_now() - t0) * 1e6;
    it->render_us = us >= 4294967295.0 ? UINT32_MAX : (uint32_t)us;
    uint64_t dropped = __atomic_load_n(&job->dropped, __ATOMIC_RELAXED);
    if (dropped)
        pf_w_log(w, PF_LOG_WARN, "job %" PRIu64 ": %" PRIu64 " camera samples so far were non-finite or negative and "
                 "left out of their pixels (last tile at %d,%d)", job->id, dropped, x0, y0);
    it->rendered = !atomic_load(&job->cancelled);
}

static void *s_compute_main(void *arg)
{
    s_worker *w = arg;
    s_queue *q = &w->q;
    pf_accel_thread_init();
    for (;;) {
        pthread_mutex_lock(&q->mu);
        while (!q->todo && !q->quit)
            pthread_cond_wait(&q->cv, &q->mu);
        if (q->quit) {
            pthread_mutex_unlock(&q->mu);
            return NULL;
        }
        s_work *it = q->todo;
        q->todo = it->next;
        if (!q->todo)
            q->todo_tail = NULL;
        it->next = NULL;
        pthread_mutex_unlock(&q->mu);

        if (!atomic_load(&it->job->cancelled)) {
            if (it->kind == S_WORK_BUILD)
                s_compute_build(w, it);
            else if (it->kind == S_WORK_PHOTONS)
                pf_w_compute_photons(w, it);
            else
                s_compute_tile(w, it);
        }

        pthread_mutex_lock(&q->mu);
        if (q->done_tail)
            q->done_tail->next = it;
        else
            q->done = it;
        q->done_tail = it;
        pthread_mutex_unlock(&q->mu);
        /* A full pipe already holds a wake-up; EAGAIN is fine. */
        ssize_t wr = write(q->wake[1], "w", 1);
        (void)wr;
    }
}

/* ---- the queue (main thread) ---- */

void pf_w_enqueue(s_worker *w, s_work *it)
{
    pthread_mutex_lock(&w->q.mu);
    if (w->q.todo_tail)
        w->q.todo_tail->next = it;
    else
        w->q.todo = it;
    w->q.todo_tail = it;
    pthread_cond_signal(&w->q.cv);
    pthread_mutex_unlock(&w->q.mu);
}

s_work *pf_w_unqueue_job(s_worker *w, const s_job *job)
{
    s_work *drop = NULL;
    pthread_mutex_lock(&w->q.mu);
    s_work **pp = &w->q.todo;
    w->q.todo_tail = NULL;
    while (*pp) {
        s_work *it = *pp;
        if (it->job == job) {
            *pp = it->next;
            it->next = drop;
            drop = it;
        } else {
            w->q.todo_tail = it;
            pp = &it->next;
        }
    }
    pthread_mutex_unlock(&w->q.mu);
    return drop;
}

s_work *pf_w_take_done(s_worker *w)
{
    char buf[64];
    while (read(w->q.wake[0], buf, sizeof buf) > 0) {
    }
    pthread_mutex_lock(&w->q.mu);
    s_work *list = w->q.done;
    w->q.done = w->q.done_tail = NULL;
    pthread_mutex_unlock(&w->q.mu);
    return list;
}

/* ---- starting and stopping ---- */

/* A non-blocking, close-on-exec pipe (the compute thread's wake-up). */
static int s_pipe(int fds[2])
{
    if (pipe(fds) != 0)
        return -1;
    for (int i = 0; i < 2; i++)
        if (fcntl(fds[i], F_SETFL, O_NONBLOCK) != 0 || fcntl(fds[i], F_SETFD, FD_CLOEXEC) != 0) {
            close(fds[0]);
            close(fds[1]);
            fds[0] = fds[1] = -1;
            return -1;
        }
    return 0;
}

int pf_w_queue_init(s_queue *q)
{
    if (pthread_mutex_init(&q->mu, NULL) || pthread_cond_init(&q->cv, NULL) ||
        s_pipe(q->wake) != 0) {
        fprintf(stderr, "photonfarm-worker: cannot set up the compute queue: %s\n", strerror(errno));
        return -1;
    }
    return 0;
}

int pf_w_compute_start(s_worker *w)
{
    /* The compute thread (and its OpenMP team) leaves SIGINT and SIGTERM to
     * the main thread, whose zmq_poll they interrupt. */
    sigset_t block, old;
    sigemptyset(&block);
    sigaddset(&block, SIGINT);
    sigaddset(&block, SIGTERM);
    pthread_sigmask(SIG_BLOCK, &block, &old);
    int rc = pthread_create(&w->compute, NULL, s_compute_main, w);
    pthread_sigmask(SIG_SETMASK, &old, NULL);
    if (rc != 0) {
        fprintf(stderr, "photonfarm-worker: cannot start the compute thread: %s\n", strerror(rc));
        return -1;
    }
    w->compute_started = 1;
    return 0;
}

void pf_w_compute_stop(s_worker *w)
{
    if (!w->compute_started)
        return;
    pthread_mutex_lock(&w->q.mu);
    w->q.quit = 1;
    pthread_cond_broadcast(&w->q.cv);
    pthread_mutex_unlock(&w->q.mu);
    pthread_join(w->compute, NULL);
    /* Whatever is left in either list belongs to the main thread now. */
    s_work *lists[2] = { w->q.todo, w->q.done };
    for (int i = 0; i < 2; i++)
        while (lists[i]) {
            s_work *next = lists[i]->next;
            pf_w_work_free(lists[i]);
            lists[i] = next;
        }
    w->q.todo = w->q.done = NULL;
    pf_frame_close(&w->ph_frame); /* the compute thread's; it is joined */
    w->ph_frame_ok = 0;
}

void pf_w_queue_destroy(s_queue *q)
{
    if (q->wake[0] >= 0) {
        close(q->wake[0]);
        close(q->wake[1]);
        pthread_mutex_destroy(&q->mu);
        pthread_cond_destroy(&q->cv);
    }
}
