/* spawn.h: local worker processes started by the coordinator (--workers N).
 * Each child gets PR_SET_PDEATHSIG so it dies with the coordinator even on
 * kill -9; pf_spawn_stop_all ends them on every exit path. */
#ifndef PF_SPAWN_H
#define PF_SPAWN_H

#include <sys/types.h>

/* The photonfarm-worker beside the running executable, into buf. */
int pf_spawn_default_worker_exe(char *buf, size_t len);

/* Starts exe with argv (NULL-terminated, argv[0] included). Returns the pid
 * or -1 with errno set. */
pid_t pf_spawn(const char *exe, char *const argv[]);

/* Waits up to grace_s for the pids to exit, then SIGTERM, then SIGKILL;
 * reaps them all. Entries are set to 0. */
void pf_spawn_stop_all(pid_t *pids, int n, double grace_s);

#endif
