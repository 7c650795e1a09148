/* worker_test.h: what the worker test's files share (test_worker.c runs
 * them). worker_keyfile.c tests base/keyfile; worker_harness.c holds the
 * worker process, the scripted coordinator and the job fixture;
 * worker_runs.c the conversations (runs) built from them. The names carry
 * wt_ ("worker test").
 *
 * Every file checks through check.h shared (PF_CHECK_SHARED); the counts
 * live in test_worker.c, so the closing line counts the whole program. */
#ifndef PF_TEST_WORKER_TEST_H
#define PF_TEST_WORKER_TEST_H

#include <stddef.h>
#include <stdint.h>
#include <sys/types.h>

#include "proto/messages.h"
#include "render/frame.h"
#include "scene/scene.h"

#define PF_CHECK_SHARED
#include "check.h"

/* base/keyfile (the keyfile ctest). */
void wt_test_keyfile(void);

/* The worker process: one child at a time, its output in wt_log_path.
 * wt_wait_worker returns the exit code, -1 on timeout (the child is killed)
 * or -2 when a signal killed it; wt_end_run kills the child, prints its log
 * when the run failed a check, and removes the log; wt_on_alarm is the
 * overall deadline's SIGALRM handler. */
extern char wt_log_path[64];
pid_t wt_start_worker(const char *exe, const char *const *args);
int wt_wait_worker(double timeout_s);
void wt_kill_child(void);
void wt_end_run(const char *run, int fails_before);
void wt_on_alarm(int sig);
char *wt_read_file(const char *path); /* NUL-terminated, malloc'd; NULL when unreadable */

/* The scripted coordinator: a ROUTER on tcp://127.0.0.1 (ephemeral port),
 * with a ZAP handler when opened with a CURVE server secret. wt_next
 * returns the worker's next message other than HEARTBEAT and BLOB_REQ
 * (recorded and served here), 0 on timeout; wt_expect fails the test on
 * anything but the type asked for; wt_quiet is true when nothing else
 * arrives for timeout_s. */
typedef struct wt_blobsrc {
    const uint8_t *data;
    size_t len;
    uint64_t hash;
} wt_blobsrc_t;

typedef struct wt_coord {
    void *ctx, *router, *zap;
    char endpoint[256];
    char allowed[41];        /* the one CURVE client key the ZAP handler admits */
    uint8_t id[256];
    size_t id_len;
    int have_id;
    uint32_t hb_ms;
    int heartbeats_on;       /* send our heartbeats while waiting */
    double last_hb;
    uint8_t *frame;          /* the last message's bytes (decoded pointers point here) */
    size_t frame_cap;
    wt_blobsrc_t blobs[2];
    int corrupt_scene_once;  /* flip a byte in the first scene chunk served, once */
    int blob_reqs, blob_reqs_scene_at0, max_credit;
    uint64_t chunks_served;
    int worker_heartbeats;
    uint64_t progress;       /* from the last worker HEARTBEAT */
    uint32_t tiles_held;
    int zap_requests, zap_denied;
} wt_coord_t;

int wt_coord_open(wt_coord_t *c, const char *server_secret);
void wt_coord_close(wt_coord_t *c);
int wt_send_raw(wt_coord_t *c, const void *data, size_t len);
int wt_send_msg(wt_coord_t *c, const pf_msg_t *m);
int wt_send_simple(wt_coord_t *c, pf_msg_type type, uint64_t job);
void wt_send_heartbeat(wt_coord_t *c);
void wt_send_welcome(wt_coord_t *c, uint32_t id);
void wt_send_bye(wt_coord_t *c, const char *reason);
int wt_next(wt_coord_t *c, double timeout_s, pf_msg_t *m);
int wt_expect(wt_coord_t *c, pf_msg_type type, double timeout_s, pf_msg_t *m, const char *what);
int wt_quiet(wt_coord_t *c, double timeout_s, pf_msg_t *m);

/* The job: cornell-spheres at 40 x 28 in 16-pixel tiles, its scene and map
 * blobs, and the reference image rendered here tile by tile. */
typedef struct wt_fixture {
    pf_scene_t *scene;
    pf_frame_t fr; /* scene's accel, lights, maps and texels */
    pf_settings_t settings;
    unsigned terms;
    int tile;
    pf_buf_t scene_blob, maps_blob;
    uint64_t scene_hash, maps_hash;
    float *ref; /* the in-process image, W*H*3 */
} wt_fixture_t;

int wt_fixture_make(wt_fixture_t *fx);
void wt_fixture_free(wt_fixture_t *fx);
void wt_coord_serve(wt_coord_t *c, const wt_fixture_t *fx); /* serve fx's blobs */
void wt_send_job(wt_coord_t *c, const wt_fixture_t *fx, uint64_t job);
pf_msg_t wt_tile_msg(uint64_t job, uint32_t tile, uint32_t attempt, int x0, int y0, int w, int h);
int wt_result_matches(const wt_fixture_t *fx, const pf_msg_result_t *r);
int wt_render_all(wt_coord_t *c, const wt_fixture_t *fx, uint64_t job, uint32_t credit, const char *what);

/* The runs (the protocol ctest), in the order main makes them. */
void wt_run_usage(const char *exe);
void wt_run_refuse(const char *exe);
void wt_run_curve(const char *exe);
void wt_run_reconnect(const char *exe);
void wt_run_gone(const char *exe);
void wt_run_render(const char *exe, const wt_fixture_t *fx);

#endif
