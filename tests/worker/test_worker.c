/* test_worker.c: the worker side of the farm, in two ctests chosen by argv[1]:
 *
 *   keyfile    base/keyfile: write/read round trips, 0600 on secret files,
 *              secret files readable by others refused,
 *              public-only files, allowed-key lists (bare and `public-key =`
 *              lines, comments, a key that starts with '#'), and malformed
 *              files whose errors must name file and line.
 *   protocol   a real photonfarm-worker process (argv[2]) against a scripted
 *              coordinator here (a ROUTER on tcp://127.0.0.1, ephemeral port):
 *              HELLO fields; a JOB whose scene arrives corrupted once (the
 *              worker must fetch it again) and whose map blob spans many
 *              chunks (credit window); every tile bit-identical to
 *              pf_render_tile in this process; garbage, truncated, foreign-
 *              version, multi-frame, wrong-job and out-of-image frames dropped
 *              while the worker keeps serving; the progress counter in its
 *              heartbeats; a second JOB with the same blobs transferring
 *              nothing; the same blobs under another seed rejected (the maps
 *              were made for other settings); BYE with --exit-on-bye
 *              (exit 0); BYE without it and a silent coordinator
 *              (re-registration), but not after the worker itself was
 *              stopped (SIGSTOP/SIGCONT); SIGTERM (BYE "signal",
 *              exit 0); REFUSE of a --fake-protocol worker (it tries again
 *              with backoff, logs the reason once with its escapes
 *              escaped, registers when welcomed, exits 0 on SIGTERM; with
 *              --exit-on-bye it exits 3); CURVE with a ZAP handler here
 *              that admits one key (the worker registers) and refuses
 *              another (exit 3 with --exit-on-bye; without it the worker
 *              retries and registers once its key is admitted); a key pair
 *              file readable by others (exit 1, "chmod 600"); usage errors
 *              (exit 2, or 1 for unreadable key files); the warning of a
 *              worker without CURVE on a non-loopback endpoint (once).
 *
 * Every wait is bounded by zmq_poll timeouts and an overall alarm; the child
 * is killed and reaped on every path.
 *
 * This file holds main and the check counts; worker_test.h says where the
 * rest lives. */
#include <signal.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <unistd.h>

#include "base/log.h"

#define PF_CHECK_MAIN /* the counts live here */
#include "worker_test.h"

int main(int argc, char **argv)
{
    const char *mode = argc > 1 ? argv[1] : "keyfile";
    signal(SIGPIPE, SIG_IGN);
    if (strcmp(mode, "keyfile") == 0) {
        wt_test_keyfile();
    } else if (strcmp(mode, "protocol") == 0) {
        if (argc < 3) {
            printf("usage: test_worker_protocol protocol PATH/photonfarm-worker\n0 passed, 1 failed\n");
            return 1;
        }
        const char *exe = argv[2];
        signal(SIGALRM, wt_on_alarm);
        alarm(140);
        pf_log_set_level(PF_LOG_WARN);
        wt_run_usage(exe);
        wt_run_refuse(exe);
        wt_run_curve(exe);
        wt_run_reconnect(exe);
        wt_run_gone(exe);
        wt_fixture_t fx;
        if (wt_fixture_make(&fx) == 0)
            wt_run_render(exe, &fx);
        wt_fixture_free(&fx);
        alarm(0);
    } else {
        printf("unknown mode '%s'\n0 passed, 1 failed\n", mode);
        return 1;
    }
    printf("%d passed, %d failed\n", s_passed, s_failed);
    return s_failed ? 1 : 0;
}
