/* spawn.c: starting and stopping local worker processes; see spawn.h.
 * Called from the coordinator's main thread only. */
#include "coordinator/spawn.h"

#include <errno.h>
#include <limits.h>
#include <signal.h>
#include <stdio.h>
#include <string.h>
#include <sys/prctl.h>
#include <sys/wait.h>
#include <time.h>
#include <unistd.h>

#include "base/log.h"

int pf_spawn_default_worker_exe(char *buf, size_t len)
{
    char self[PATH_MAX];
    ssize_t n = readlink("/proc/self/exe", self, sizeof self - 1);
    if (n <= 0)
        return -1;
    self[n] = 0;
    char *slash = strrchr(self, '/');
    if (!slash)
        return -1;
    *slash = 0;
    int w = snprintf(buf, len, "%s/photonfarm-worker", self);
    return (w < 0 || (size_t)w >= len) ? -1 : 0;
}

pid_t pf_spawn(const char *exe, char *const argv[])
{
    pid_t parent = getpid();
    pid_t pid = fork();
    if (pid != 0)
        return pid;
    /* Child: die with the coordinator, whatever kills it. */
    prctl(PR_SET_PDEATHSIG, SIGKILL);
    if (getppid() != parent)
        _exit(1);
    execv(exe, argv);
    fprintf(stderr, "photonfarm: cannot start worker %s: %s\n", exe, strerror(errno));
    _exit(127);
}

static int s_reap(pid_t *pids, int n)
{
    int alive = 0;
    for (int i = 0; i < n; i++) {
        if (pids[i] <= 0)
            continue;
        int status;
        pid_t r = waitpid(pids[i], &status, WNOHANG);
        if (r == pids[i] || (r < 0 && errno == ECHILD))
            pids[i] = 0;
        else
            alive++;
    }
    return alive;
}

static void s_wait(pid_t *pids, int n, double seconds)
{
    double end = pf_now() + seconds;
    while (s_reap(pids, n) > 0 && pf_now() < end) {
        struct timespec ts = { 0, 20 * 1000 * 1000 };
        nanosleep(&ts, NULL);
    }
}

void pf_spawn_stop_all(pid_t *pids, int n, double grace_s)
{
    s_wait(pids, n, grace_s);
    for (int i = 0; i < n; i++)
        if (pids[i] > 0)
            kill(pids[i], SIGTERM);
    s_wait(pids, n, 2.0);
    for (int i = 0; i < n; i++)
        if (pids[i] > 0) {
            pf_warn("worker process %d did not stop; killing it", (int)pids[i]);
            kill(pids[i], SIGKILL);
        }
    s_wait(pids, n, 2.0);
}
