/* worker_runs.c: the protocol ctest's conversations with a real
 * photonfarm-worker, each on a scripted coordinator of its own
 * (worker_harness.c): a render with corrupted and repeated blobs, garbage
 * frames and rejected maps; reconnection after BYE and silence, but not
 * after a SIGSTOP; a coordinator gone for good; REFUSE (retried, or the end
 * with --exit-on-bye); CURVE admission, also of a key added later; a key
 * file readable by others; usage errors. test_worker.c lists what each checks. Every wait is bounded;
 * a run that fails a check prints the worker's log. */
#include <signal.h>
#include <stdint.h>
#include <sys/stat.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <unistd.h>
#include <zmq.h>

#include "base/keyfile.h"
#include "base/log.h"

#include "worker_test.h"

/* Run A, step by step (wt_run_render below). HELLO carries this build's
 * fingerprint, the thread count and the name; 0 when no HELLO came. */
static int s_render_hello(wt_coord_t *c, pf_msg_t *m)
{
    if (!wt_expect(c, PF_MSG_HELLO, 15, m, "render run"))
        return 0;
    pf_fingerprint_t fp = pf_frame_fingerprint();
    CHECK(m->u.hello.fp.protocol == PF_PROTO_VERSION && m->u.hello.fp.photon_size == fp.photon_size &&
              m->u.hello.fp.float_size == fp.float_size && m->u.hello.fp.map_version == fp.map_version &&
              strcmp(m->u.hello.fp.git, fp.git) == 0,
          "HELLO carries this build's fingerprint");
    CHECK(m->u.hello.threads == 2, "HELLO threads %u", m->u.hello.threads);
    CHECK(strcmp(m->u.hello.name, "test-worker") == 0, "HELLO name '%s'", m->u.hello.name);
    wt_send_welcome(c, 7);
    return 1;
}

/* Job 1: the scene's first chunk arrives corrupted once, and the map blob
 * refills the credit window; every tile comes back bit-identical. 0 when
 * no READY came; the worker's tile credit in *credit. */
static int s_render_job1(wt_coord_t *c, const wt_fixture_t *fx, pf_msg_t *m, uint32_t *credit)
{
    c->corrupt_scene_once = 1;
    wt_send_job(c, fx, 1);
    if (!wt_expect(c, PF_MSG_READY, 60, m, "job 1"))
        return 0;
    CHECK(m->job == 1 && m->u.ready.credit >= 2, "READY for job 1 with credit %u", m->u.ready.credit);
    *credit = m->u.ready.credit;
    CHECK(c->blob_reqs_scene_at0 == 2, "the corrupted scene was requested again (%d requests at offset 0)",
          c->blob_reqs_scene_at0);
    uint64_t chunks = (fx->scene_blob.len + PF_PROTO_CHUNK_SIZE - 1) / PF_PROTO_CHUNK_SIZE * 2 +
                      (fx->maps_blob.len + PF_PROTO_CHUNK_SIZE - 1) / PF_PROTO_CHUNK_SIZE;
    CHECK(c->chunks_served == chunks, "%llu chunks served, expected %llu (no chunk twice)",
          (unsigned long long)c->chunks_served, (unsigned long long)chunks);
    CHECK(c->max_credit >= 2 && c->max_credit <= 8, "credit window %d chunks", c->max_credit);
    CHECK(c->blob_reqs > 3, "the window was refilled (%d BLOB_REQs)", c->blob_reqs);
    int W = fx->settings.width, H = fx->settings.height, T = fx->tile;
    int total = ((W + T - 1) / T) * ((H + T - 1) / T);
    int same = wt_render_all(c, fx, 1, *credit, "job 1");
    CHECK(same == total, "job 1: %d of %d tiles bit-identical", same, total);
    return 1;
}

/* Garbage: each is dropped and the worker keeps serving. */
static void s_render_garbage(wt_coord_t *c, const wt_fixture_t *fx, pf_msg_t *m)
{
    int W = fx->settings.width, H = fx->settings.height;
    uint8_t junk[64];
    srand(12345);
    for (size_t i = 0; i < sizeof junk; i++)
        junk[i] = (uint8_t)rand();
    wt_send_raw(c, junk, sizeof junk);
    wt_send_raw(c, "", 0);
    pf_msg_t tm = wt_tile_msg(1, 0, 9, 0, 0, 16, 16);
    pf_buf_t b = { 0 };
    pf_msg_encode(&tm, &b);
    wt_send_raw(c, b.data, b.len - 3);                  /* truncated TILE */
    b.data[4] = 9;                                      /* another protocol version */
    wt_send_raw(c, b.data, b.len);
    b.data[4] = PF_PROTO_VERSION;
    zmq_send(c->router, c->id, c->id_len, ZMQ_SNDMORE); /* two frames */
    zmq_send(c->router, b.data, b.len, ZMQ_SNDMORE);
    zmq_send(c->router, b.data, b.len, 0);
    pf_buf_free(&b);
    tm = wt_tile_msg(99, 0, 9, 0, 0, 16, 16);           /* another job */
    wt_send_msg(c, &tm);
    tm = wt_tile_msg(1, 5, 9, 32, 16, 16, 12);          /* runs past the right edge */
    wt_send_msg(c, &tm);
    tm = wt_tile_msg(1, 5, 9, 0, 20, 8, 12);            /* runs past the bottom */
    wt_send_msg(c, &tm);
    CHECK(wt_quiet(c, 1.0, m), "garbage answered with %s", pf_msg_type_name(m->type));
    tm = wt_tile_msg(1, 3, 2, 0, 16, 16, 12);           /* a valid re-lease */
    wt_send_msg(c, &tm);
    if (wt_expect(c, PF_MSG_RESULT, 30, m, "after garbage"))
        CHECK(m->job == 1 && m->u.result.tile == 3 && m->u.result.attempt == 2 && wt_result_matches(fx, &m->u.result),
              "the worker still serves after garbage (tile %u attempt %u)", m->u.result.tile, m->u.result.attempt);
    /* The heartbeat's progress counts every pixel rendered. */
    uint64_t want = (uint64_t)W * (uint64_t)H + 16 * 12;
    double end = pf_now() + 3;
    while ((c->progress != want || c->tiles_held != 0) && pf_now() < end)
        wt_next(c, 0.1, m);
    CHECK(c->progress == want && c->tiles_held == 0, "heartbeat progress %llu (want %llu), tiles held %u",
          (unsigned long long)c->progress, (unsigned long long)want, c->tiles_held);
    CHECK(c->worker_heartbeats >= 3, "%d worker heartbeats", c->worker_heartbeats);
}

/* Job 2, same scene and maps: nothing transferred, nothing rebuilt. */
static void s_render_job2(wt_coord_t *c, const wt_fixture_t *fx, pf_msg_t *m, uint32_t credit)
{
    int W = fx->settings.width, H = fx->settings.height, T = fx->tile;
    int total = ((W + T - 1) / T) * ((H + T - 1) / T);
    wt_send_simple(c, PF_MSG_JOB_END, 1);
    pf_msg_t tm = wt_tile_msg(1, 0, 3, 0, 0, 16, 16);   /* job 1 is over */
    wt_send_msg(c, &tm);
    c->blob_reqs = 0;
    wt_send_job(c, fx, 2);
    double t0 = pf_now();
    if (wt_expect(c, PF_MSG_READY, 20, m, "job 2")) {
        CHECK(m->job == 2, "READY for job %llu", (unsigned long long)m->job);
        CHECK(c->blob_reqs == 0, "job 2 with the same blobs sent %d BLOB_REQs", c->blob_reqs);
        CHECK(pf_now() - t0 < 2.0, "job 2 was ready in %.2f s (built structures reused)", pf_now() - t0);
        int same = wt_render_all(c, fx, 2, credit, "job 2");
        CHECK(same == total, "job 2: %d of %d tiles bit-identical", same, total);
    }
    /* A tile and its job's end back to back: no RESULT is owed afterwards. */
    tm = wt_tile_msg(2, 0, 4, 0, 0, 16, 16);
    wt_send_msg(c, &tm);
    wt_send_simple(c, PF_MSG_JOB_END, 2);
    while (wt_next(c, 1.0, m))
        CHECK(m->type == PF_MSG_RESULT && m->job == 2, "after JOB_END: %s", pf_msg_type_name(m->type));
}

/* Job 3 names the same blobs with another seed: the maps were made for
 * other settings, so the worker must reject them (no READY) rather than
 * reuse what it built for jobs 1 and 2. Job 4 is fine again. */
static void s_render_foreign_maps(wt_coord_t *c, const wt_fixture_t *fx, pf_msg_t *m)
{
    c->blob_reqs = 0;
    wt_fixture_t other = *fx;
    other.settings.seed += 1;
    wt_send_job(c, &other, 3);
    CHECK(wt_quiet(c, 2.0, m), "job 3 with foreign maps answered with %s", pf_msg_type_name(m->type));
    pf_msg_t tm = wt_tile_msg(3, 0, 1, 0, 0, 16, 16);
    wt_send_msg(c, &tm);
    CHECK(wt_quiet(c, 0.5, m), "a tile of the rejected job 3 answered with %s", pf_msg_type_name(m->type));
    wt_send_simple(c, PF_MSG_JOB_END, 3);
    wt_send_job(c, fx, 4);
    if (wt_expect(c, PF_MSG_READY, 20, m, "job 4"))
        CHECK(m->job == 4, "READY for job %llu", (unsigned long long)m->job);
    CHECK(c->blob_reqs == 0, "jobs 3 and 4 sent %d BLOB_REQs", c->blob_reqs);
    tm = wt_tile_msg(4, 1, 1, 16, 0, 16, 16);
    wt_send_msg(c, &tm);
    if (wt_expect(c, PF_MSG_RESULT, 30, m, "job 4"))
        CHECK(m->job == 4 && m->u.result.tile == 1 && wt_result_matches(fx, &m->u.result), "job 4 tile 1 identical");
}

/* The credit READY announced (3) is enforced: with the worker stopped, five
 * TILEs of job 4 queue up (tiles 0, 2, a copy of 2, 3 and 4); once it runs
 * again it renders the first three distinct ones and drops the copy and the
 * one beyond its credit. */
static void s_render_credit(wt_coord_t *c, const wt_fixture_t *fx, pf_msg_t *m, pid_t pid)
{
    if (pid <= 0)
        return;
    kill(pid, SIGSTOP);
    static const int tiles[5][5] = {
        { 0, 0, 0, 16, 16 }, { 2, 32, 0, 8, 16 }, { 2, 32, 0, 8, 16 }, { 3, 0, 16, 16, 12 }, { 4, 16, 16, 16, 12 },
    };
    for (int i = 0; i < 5; i++) {
        pf_msg_t tm = wt_tile_msg(4, (uint32_t)tiles[i][0], 2, tiles[i][1], tiles[i][2], tiles[i][3], tiles[i][4]);
        wt_send_msg(c, &tm);
    }
    usleep(300000);
    kill(pid, SIGCONT);
    int got[5] = { 0 }, results = 0, others = 0;
    while (wt_next(c, 3.0, m)) {
        if (m->type == PF_MSG_RESULT && m->job == 4 && m->u.result.tile < 5 && wt_result_matches(fx, &m->u.result)) {
            got[m->u.result.tile]++;
            results++;
        } else {
            others++;
        }
    }
    CHECK(results == 3 && got[0] == 1 && got[2] == 1 && got[3] == 1 && others == 0,
          "credit 3: %d RESULTs (tiles 0/2/3/4: %d %d %d %d), %d other messages; want tiles 0, 2 and 3 once", results,
          got[0], got[2], got[3], got[4], others);
}

/* The worker's virtual size in KiB (/proc/PID/status VmSize), or 0. */
static unsigned long long s_vm_kib(pid_t pid)
{
    char path[64];
    snprintf(path, sizeof path, "/proc/%d/status", (int)pid);
    char *st = wt_read_file(path);
    const char *v = st ? strstr(st, "VmSize:") : NULL;
    unsigned long long kib = v ? strtoull(v + 7, NULL, 10) : 0;
    free(st);
    return kib;
}

/* Job 5 announces a 60 GiB scene (the same hash, so the chunks served here,
 * of the real blob, do not fit it and are dropped): the worker must accept
 * the job and allocate nothing for the blob until data arrives (the buffer
 * grows with the chunks), not 60 GiB up front. */
static void s_render_lying_job(wt_coord_t *c, const wt_fixture_t *fx, pf_msg_t *m, pid_t pid)
{
    if (pid <= 0)
        return;
    pf_msg_t jm;
    memset(&jm, 0, sizeof jm);
    jm.type = PF_MSG_JOB;
    jm.job = 5;
    jm.u.job.scene_hash = fx->scene_hash;
    jm.u.job.scene_size = UINT64_C(60) << 30;
    jm.u.job.maps_hash = fx->maps_hash;
    jm.u.job.maps_size = fx->maps_blob.len;
    jm.u.job.settings = fx->settings;
    jm.u.job.terms = fx->terms;
    jm.u.job.tile_size = (uint32_t)fx->tile;
    /* The growth of the mapped size, not the size: a sanitizer build maps
     * terabytes of shadow memory from the start. */
    unsigned long long before = s_vm_kib(pid);
    wt_send_msg(c, &jm);
    CHECK(wt_quiet(c, 1.0, m), "job 5 (a 60 GiB scene) answered with %s", pf_msg_type_name(m->type));
    unsigned long long kib = s_vm_kib(pid);
    CHECK(before > 0 && kib > 0 && kib < before + (8ULL << 20),
          "after a JOB announcing 60 GiB the worker maps %llu KiB more (%llu KiB before)", kib - before, before);
    char *log = wt_read_file(wt_log_path);
    CHECK(log && strstr(log, "(64424.5 MB)") && !strstr(log, "cannot allocate"),
          "job 5 is fetched, nothing allocated up front");
    free(log);
    wt_send_simple(c, PF_MSG_JOB_END, 5);
}

/* BYE ends an --exit-on-bye worker with 0; its log says why it rejected job 3. */
static void s_render_bye(wt_coord_t *c)
{
    wt_send_bye(c, "test over");
    int code = wt_wait_worker(10);
    CHECK(code == 0, "BYE with --exit-on-bye: exit code %d", code);
    char *log = wt_read_file(wt_log_path);
    CHECK(log && strstr(log, "job 3: photon-map blob") && strstr(log, "taking no tiles"),
          "the worker logs why it rejects job 3");
    CHECK(log && strstr(log, "TILE 4 of job 4 is beyond the credit of 3 tiles") &&
              strstr(log, "TILE 2 (attempt 2) of job 4 sent again while this worker holds it"),
          "the worker logs the TILEs it dropped");
    free(log);
}

/* Run A: the whole conversation with --exit-on-bye. */
void wt_run_render(const char *exe, const wt_fixture_t *fx)
{
    int fails = pf_test_failures();
    wt_coord_t c;
    if (wt_coord_open(&c, NULL)) {
        CHECK(0, "cannot bind the test coordinator");
        return;
    }
    wt_coord_serve(&c, fx);
    const char *args[] = { "--connect", c.endpoint, "--threads", "2", "--name", "test-worker", "--exit-on-bye", "-v",
                           NULL };
    pid_t pid = wt_start_worker(exe, args);
    pf_msg_t m;
    uint32_t credit;
    if (s_render_hello(&c, &m) && s_render_job1(&c, fx, &m, &credit)) {
        s_render_garbage(&c, fx, &m);
        s_render_job2(&c, fx, &m, credit);
        s_render_foreign_maps(&c, fx, &m);
        s_render_credit(&c, fx, &m, pid);
        s_render_lying_job(&c, fx, &m, pid);
        s_render_bye(&c);
    }
    wt_end_run("render", fails);
    wt_coord_close(&c);
}

/* Run B: long-lived worker: BYE, a silent coordinator, SIGTERM. */
void wt_run_reconnect(const char *exe)
{
    int fails = pf_test_failures();
    wt_coord_t c;
    if (wt_coord_open(&c, NULL)) {
        CHECK(0, "cannot bind the test coordinator");
        return;
    }
    const char *args[] = { "--connect", c.endpoint, "--threads", "1", "-v", NULL };
    pid_t pid = wt_start_worker(exe, args);
    pf_msg_t m;
    if (!wt_expect(&c, PF_MSG_HELLO, 15, &m, "reconnect run"))
        goto out;
    CHECK(strchr(m.u.hello.name, ':') != NULL, "default name host:pid, got '%s'", m.u.hello.name);
    wt_send_welcome(&c, 1);
    CHECK(wt_quiet(&c, 0.5, &m), "idle worker sent %s", pf_msg_type_name(m.type));
    wt_send_bye(&c, "coordinator restarting");
    double t0 = pf_now();
    if (!wt_expect(&c, PF_MSG_HELLO, 10, &m, "after BYE"))
        goto out;
    double dt = pf_now() - t0;
    CHECK(dt > 0.7 && dt < 4, "a new HELLO %.2f s after BYE (backoff 1 s)", dt);
    wt_send_welcome(&c, 2);
    /* Go silent: after 5 heartbeat intervals (1 s) the worker gives up on us
     * and registers again after its backoff. */
    c.heartbeats_on = 0;
    t0 = pf_now();
    if (!wt_expect(&c, PF_MSG_HELLO, 10, &m, "after silence"))
        goto out;
    dt = pf_now() - t0;
    CHECK(dt > 1.5 && dt < 5, "a new HELLO %.2f s after the coordinator went silent", dt);
    c.heartbeats_on = 1;
    wt_send_welcome(&c, 3);
    CHECK(wt_quiet(&c, 0.5, &m), "registered worker sent %s", pf_msg_type_name(m.type));
    /* A worker that was itself stopped does not blame the coordinator for
     * the silence: stopped for 2 s while we say nothing, it must carry on
     * once we speak again rather than register anew. */
    c.heartbeats_on = 0;
    kill(pid, SIGSTOP);
    CHECK(wt_quiet(&c, 2.0, &m), "a stopped worker sent %s", pf_msg_type_name(m.type));
    kill(pid, SIGCONT);
    c.heartbeats_on = 1;
    wt_send_heartbeat(&c);
    CHECK(wt_quiet(&c, 1.5, &m), "after SIGCONT the worker sent %s (registering again?)", pf_msg_type_name(m.type));
    kill(pid, SIGTERM);
    if (wt_expect(&c, PF_MSG_BYE, 5, &m, "SIGTERM"))
        CHECK(strcmp(m.u.bye.reason, "signal") == 0, "BYE reason '%s'", m.u.bye.reason);
    int code = wt_wait_worker(10);
    CHECK(code == 0, "SIGTERM: exit code %d", code);
out:
    wt_end_run("reconnect", fails);
    wt_coord_close(&c);
}

/* Run B2: an --exit-on-bye worker whose coordinator goes away without a
 * goodbye (it was stopped or cut off when the BYE went out) tries to reach
 * it once more, then exits 0 instead of waiting forever; before any
 * coordinator has welcomed it, the same worker keeps trying. */
void wt_run_gone(const char *exe)
{
    int fails = pf_test_failures();
    wt_coord_t c;
    if (wt_coord_open(&c, NULL)) {
        CHECK(0, "cannot bind the test coordinator");
        return;
    }
    const char *args[] = { "--connect", c.endpoint, "--threads", "1", "--exit-on-bye", "-v", NULL };
    wt_start_worker(exe, args);
    pf_msg_t m;
    if (!wt_expect(&c, PF_MSG_HELLO, 15, &m, "gone run"))
        goto out;
    /* Not welcomed: after the 5 s HELLO timeout it says HELLO again. */
    c.heartbeats_on = 0;
    if (!wt_expect(&c, PF_MSG_HELLO, 10, &m, "a second HELLO before any WELCOME"))
        goto out;
    wt_send_welcome(&c, 1);
    CHECK(wt_quiet(&c, 0.5, &m), "idle worker sent %s", pf_msg_type_name(m.type));
    /* Now the coordinator is gone: silent, and deaf to the next HELLO. */
    double t0 = pf_now();
    if (!wt_expect(&c, PF_MSG_HELLO, 10, &m, "a HELLO after the coordinator went silent"))
        goto out;
    int code = wt_wait_worker(10);
    double dt = pf_now() - t0;
    CHECK(code == 0, "--exit-on-bye worker whose coordinator is gone: exit code %d after %.1f s", code, dt);
out:
    wt_kill_child();
    wt_end_run("gone", fails);
    wt_coord_close(&c);
}

/* How many times needle occurs in hay. */
static int s_count(const char *hay, const char *needle)
{
    int n = 0;
    for (const char *p = hay ? strstr(hay, needle) : NULL; p; p = strstr(p + 1, needle))
        n++;
    return n;
}

/* Sends a REFUSE whose reason carries a terminal escape and a forged line. */
static void s_send_refuse(wt_coord_t *c)
{
    pf_msg_t m;
    memset(&m, 0, sizeof m);
    m.type = PF_MSG_REFUSE;
    snprintf(m.u.refuse.reason, sizeof m.u.refuse.reason,
             "protocol version 2 (worker) vs 1 (coordinator)\x1b[31m\nerror: forged");
    wt_send_msg(c, &m);
}

/* Run C: a REFUSE does not end a long-lived worker: it tries again with
 * backoff (1 s, then 2 s), logs the refusal once with its control bytes
 * escaped, registers when the coordinator admits it, and leaves on SIGTERM.
 * With --exit-on-bye (a local one-job worker) a REFUSE still ends it (3). */
void wt_run_refuse(const char *exe)
{
    int fails = pf_test_failures();
    wt_coord_t c;
    if (wt_coord_open(&c, NULL)) {
        CHECK(0, "cannot bind the test coordinator");
        return;
    }
    const char *args[] = { "--connect", c.endpoint, "--fake-protocol", "2", NULL };
    pid_t pid = wt_start_worker(exe, args);
    pf_msg_t m;
    if (wt_expect(&c, PF_MSG_HELLO, 15, &m, "refuse run")) {
        CHECK(m.u.hello.fp.protocol == 2, "--fake-protocol 2 announces protocol %u", m.u.hello.fp.protocol);
        s_send_refuse(&c);
        double t0 = pf_now();
        int again = wt_expect(&c, PF_MSG_HELLO, 6, &m, "HELLO again after a REFUSE");
        double t1 = pf_now();
        CHECK(!again || t1 - t0 > 0.5, "the second HELLO came %.2f s after the REFUSE (backoff 1 s)", t1 - t0);
        if (again) {
            s_send_refuse(&c);
            again = wt_expect(&c, PF_MSG_HELLO, 8, &m, "HELLO a third time");
            CHECK(!again || pf_now() - t1 > 1.5, "the third HELLO came %.2f s after the second REFUSE (backoff 2 s)",
                  pf_now() - t1);
        }
        if (again) {
            wt_send_welcome(&c, 7);
            CHECK(wt_quiet(&c, 0.5, &m) || m.type == PF_MSG_BYE, "the admitted worker sent %s",
                  pf_msg_type_name(m.type));
        }
        if (pid > 0)
            kill(pid, SIGTERM);
        int code = wt_wait_worker(10);
        CHECK(code == 0, "a refused, then admitted worker stopped by SIGTERM: exit code %d", code);
        char *log = wt_read_file(wt_log_path);
        char want[512];
        snprintf(want, sizeof want, "refused by %s: protocol version 2 (worker) vs 1 (coordinator)\\x1b[31m\\x0aerror: "
                 "forged; trying again in 1 s", c.endpoint);
        CHECK(log && strstr(log, want), "the refusal is printed, escaped: want '%s'", want);
        CHECK(s_count(log, "refused by") == 1, "the same refusal logged %d times (want once)", s_count(log, "refused by"));
        CHECK(log && !strchr(log, '\x1b') && !strstr(log, "\nerror: forged"), "a raw escape or forged line in the log");
        CHECK(log && strstr(log, "registered with"), "the worker registered once admitted");
        CHECK(log && !strstr(log, "without CURVE"), "a loopback worker warned about plaintext");
        free(log);
    }
    wt_end_run("refuse", fails);
    wt_coord_close(&c);

    /* --exit-on-bye: a REFUSE ends the worker with exit code 3. */
    fails = pf_test_failures();
    if (wt_coord_open(&c, NULL)) {
        CHECK(0, "cannot bind the test coordinator");
        return;
    }
    const char *args1[] = { "--connect", c.endpoint, "--fake-protocol", "2", "--exit-on-bye", NULL };
    wt_start_worker(exe, args1);
    if (wt_expect(&c, PF_MSG_HELLO, 15, &m, "refuse run, --exit-on-bye")) {
        s_send_refuse(&c);
        int code = wt_wait_worker(10);
        CHECK(code == 3, "REFUSE with --exit-on-bye: exit code %d", code);
        char *log = wt_read_file(wt_log_path);
        CHECK(log && strstr(log, "refused by") && strstr(log, "--exit-on-bye: exiting"),
              "the refusal and the exit are printed");
        free(log);
    }
    wt_end_run("refuse-exit-on-bye", fails);
    wt_coord_close(&c);
}

/* Run F: a worker whose key the coordinator does not admit yet keeps
 * trying (each ZAP denial is a refusal, logged once) and registers once the
 * key is added; SIGTERM then ends it (0). */
static void s_run_curve_late(const char *exe, const char *server_sec, const char *key_pub, const char *kpath,
                             const char *spath)
{
    int fails = pf_test_failures();
    wt_coord_t c;
    if (wt_coord_open(&c, server_sec)) {
        CHECK(0, "cannot bind the CURVE test coordinator");
        return;
    }
    snprintf(c.allowed, sizeof c.allowed, "%s", "not-yet");
    const char *args[] = { "--connect", c.endpoint, "--curve-key", kpath, "--curve-server-key", spath, NULL };
    pid_t pid = wt_start_worker(exe, args);
    pf_msg_t m;
    CHECK(!wt_next(&c, 2.5, &m), "a key not yet admitted got a message through");
    CHECK(c.zap_denied >= 2, "ZAP denied %d times in 2.5 s (the worker retries)", c.zap_denied);
    snprintf(c.allowed, sizeof c.allowed, "%s", key_pub); /* the key is added to the list */
    if (wt_expect(&c, PF_MSG_HELLO, 10, &m, "CURVE, key added later")) {
        wt_send_welcome(&c, 3);
        CHECK(wt_quiet(&c, 0.3, &m), "CURVE worker sent %s", pf_msg_type_name(m.type));
    }
    if (pid > 0)
        kill(pid, SIGTERM);
    int code = wt_wait_worker(10);
    CHECK(code == 0, "CURVE, key added later, SIGTERM: exit code %d", code);
    char *log = wt_read_file(wt_log_path);
    CHECK(log && s_count(log, "refused by") == 1 && strstr(log, "CURVE"), "the CURVE refusal logged %d times (want once)",
          s_count(log, "refused by"));
    CHECK(log && strstr(log, "registered with"), "the worker registered once its key was admitted");
    free(log);
    wt_end_run("curve-late", fails);
    wt_coord_close(&c);
}

/* Run G: a key pair file readable by others is refused at start (exit 1,
 * naming the file, its mode and the fix). */
static void s_run_key_mode(const char *exe, const char *kpath, const char *spath)
{
    int fails = pf_test_failures();
    chmod(kpath, 0644);
    const char *args[] = { "--connect", "tcp://127.0.0.1:1", "--curve-key", kpath, "--curve-server-key", spath, NULL };
    wt_start_worker(exe, args);
    int code = wt_wait_worker(10);
    CHECK(code == 1, "a 0644 key pair file: exit code %d", code);
    char *log = wt_read_file(wt_log_path);
    char want[700];
    snprintf(want, sizeof want, "readable by others (mode 0644): chmod 600 %.600s", kpath);
    CHECK(log && strstr(log, want), "the error says: want '%s'", want);
    free(log);
    chmod(kpath, 0600);
    wt_end_run("key-mode", fails);
}

/* Runs D and E: CURVE with a ZAP handler that admits one client key. */
void wt_run_curve(const char *exe)
{
    if (!zmq_has("curve")) {
        printf("note: this libzmq has no CURVE; CURVE runs skipped\n");
        return;
    }
    char dir[] = "/tmp/pf_curve_XXXXXX";
    if (!mkdtemp(dir)) {
        CHECK(0, "mkdtemp");
        return;
    }
    char server_pub[41], server_sec[41], good_pub[41], good_sec[41], bad_pub[41], bad_sec[41];
    zmq_curve_keypair(server_pub, server_sec);
    zmq_curve_keypair(good_pub, good_sec);
    zmq_curve_keypair(bad_pub, bad_sec);
    char spath[600], gpath[600], bpath[600];
    snprintf(spath, sizeof spath, "%s/server.pub", dir);
    snprintf(gpath, sizeof gpath, "%s/good.key", dir);
    snprintf(bpath, sizeof bpath, "%s/bad.key", dir);
    pf_error_t err;
    CHECK(pf_keyfile_write(spath, server_pub, NULL, &err) == 0 &&
              pf_keyfile_write(gpath, good_pub, good_sec, &err) == 0 &&
              pf_keyfile_write(bpath, bad_pub, bad_sec, &err) == 0,
          "key files: %s", err.msg);
    for (int run = 0; run < 2; run++) {
        int fails = pf_test_failures();
        wt_coord_t c;
        if (wt_coord_open(&c, server_sec)) {
            CHECK(0, "cannot bind the CURVE test coordinator");
            break;
        }
        snprintf(c.allowed, sizeof c.allowed, "%s", good_pub);
        const char *args[] = { "--connect", c.endpoint, "--curve-key", run == 0 ? gpath : bpath,
                               "--curve-server-key", spath, "--exit-on-bye", "-v", NULL };
        wt_start_worker(exe, args);
        pf_msg_t m;
        if (run == 0) {
            if (wt_expect(&c, PF_MSG_HELLO, 15, &m, "CURVE, listed key")) {
                wt_send_welcome(&c, 1);
                CHECK(wt_quiet(&c, 0.3, &m), "CURVE worker sent %s", pf_msg_type_name(m.type));
                wt_send_bye(&c, "done");
                int code = wt_wait_worker(10);
                CHECK(code == 0, "CURVE, listed key: exit code %d", code);
            }
            CHECK(c.zap_requests >= 1 && c.zap_denied == 0, "ZAP: %d requests, %d denied", c.zap_requests,
                  c.zap_denied);
        } else {
            CHECK(!wt_next(&c, 3, &m), "an unlisted key got a message through");
            int code = wt_wait_worker(10);
            CHECK(code == 3, "CURVE, unlisted key: exit code %d", code);
            char *log = wt_read_file(wt_log_path);
            CHECK(log && strstr(log, "refused by") && strstr(log, "CURVE"), "the refusal names CURVE");
            free(log);
            CHECK(c.zap_denied >= 1, "ZAP denied %d", c.zap_denied);
        }
        wt_end_run(run == 0 ? "curve-listed" : "curve-unlisted", fails);
        wt_coord_close(&c);
    }
    s_run_curve_late(exe, server_sec, bad_pub, bpath, spath);
    s_run_key_mode(exe, bpath, spath);
    unlink(spath), unlink(gpath), unlink(bpath);
    rmdir(dir);
}

/* A worker without CURVE warns once when its endpoint is not on loopback
 * (192.0.2.1 is TEST-NET-1: never reached; it keeps trying until SIGTERM). */
static void s_run_plaintext(const char *exe)
{
    int fails = pf_test_failures();
    const char *args[] = { "--connect", "tcp://192.0.2.1:7878", NULL };
    pid_t pid = wt_start_worker(exe, args);
    usleep(700000);
    if (pid > 0)
        kill(pid, SIGTERM);
    int code = wt_wait_worker(10);
    CHECK(code == 0, "plaintext worker stopped by SIGTERM: exit code %d", code);
    char *log = wt_read_file(wt_log_path);
    CHECK(log && s_count(log, "without CURVE") == 1, "the plaintext warning given %d times (want once)",
          s_count(log, "without CURVE"));
    free(log);
    wt_end_run("plaintext", fails);
}

/* Usage errors and --help, without a coordinator; the plaintext warning. */
void wt_run_usage(const char *exe)
{
    struct {
        const char *args[8];
        int code;
    } cases[] = {
        { { NULL }, 2 },
        { { "--help", NULL }, 0 },
        { { "--version", NULL }, 0 },
        { { "--connect", "tcp://127.0.0.1:1", "--threads", "many", NULL }, 2 },
        { { "--connect", "tcp://127.0.0.1:1", "--bogus", NULL }, 2 },
        { { "--connect", "tcp://127.0.0.1:1", "--curve-key", "/nonexistent", NULL }, 2 },
        { { "--connect", "nonsense", NULL }, 2 },
        { { "--connect", "tcp://127.0.0.1:1", "--curve-key", "/nonexistent", "--curve-server-key", "/nonexistent" },
          1 },
    };
    for (size_t i = 0; i < sizeof cases / sizeof cases[0]; i++) {
        int fails = pf_test_failures();
        wt_start_worker(exe, cases[i].args);
        int code = wt_wait_worker(10);
        CHECK(code == cases[i].code, "usage case %zu (%s %s): exit code %d, want %d", i,
              cases[i].args[0] ? cases[i].args[0] : "", cases[i].args[0] && cases[i].args[1] ? cases[i].args[1] : "",
              code, cases[i].code);
        wt_end_run("usage", fails);
    }
    s_run_plaintext(exe);
}
