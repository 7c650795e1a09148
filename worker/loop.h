/* loop.h: the worker's network loop. One DEALER socket to the coordinator,
 * owned by the calling thread, which never blocks on compute; a compute
 * thread builds each job's scene, Embree structure and photon maps and
 * renders leased tiles with OpenMP. Blobs (scene, maps) are cached by content
 * hash, and the built structures by (scene, maps, settings hash), so a
 * second job with the same scene and maps transfers and rebuilds nothing. */
#ifndef PF_WORKER_LOOP_H
#define PF_WORKER_LOOP_H

#include <signal.h>

/* Exit codes of pf_worker_run (and of photonfarm-worker). */
enum {
    PF_WORKER_EXIT_OK = 0,      /* stopped by a signal, or BYE with exit_on_bye */
    PF_WORKER_EXIT_FATAL = 1,   /* could not start (bad key file, no ZeroMQ context, ...) */
    PF_WORKER_EXIT_USAGE = 2,   /* (main.c only) bad command line */
    PF_WORKER_EXIT_REFUSED = 3, /* refused by the coordinator with exit_on_bye (any other worker retries) */
};

typedef struct pf_worker_opts {
    const char *endpoint;          /* the coordinator, e.g. "tcp://host:7878" (required) */
    int threads;                   /* OpenMP threads per tile; 0: all cores */
    const char *name;              /* NULL: "hostname:pid" */
    const char *curve_key;         /* own key pair file (public + secret), or NULL: no CURVE */
    const char *curve_server_key;  /* the coordinator's public key file (required with curve_key) */
    int exit_on_bye;               /* a BYE from the coordinator ends the run, and so does a coordinator that
                                      served us and then cannot be reached again (else: reconnect, serve the next) */
    const volatile sig_atomic_t *stop; /* set non-zero (e.g. by a signal handler) to leave; may be NULL */
    int fake_protocol;             /* tests only: announce this protocol version in HELLO (0: the real one) */
    int peer_port;                 /* serve blob chunks to other workers on this TCP port (0: any free one,
                                      but none for an ipc:// coordinator; < 0: serve none); loopback only
                                      when the coordinator is local; never with CURVE */
} pf_worker_opts_t;

/* Serves coordinators until *opts->stop is set, or a BYE or a refusal
 * arrives with exit_on_bye. A coordinator that goes silent for 5 heartbeat
 * intervals is abandoned (current job dropped) and contacted again with
 * backoff 1 s doubling to 32 s; one that refuses this worker (REFUSE, or its
 * CURVE key not admitted) is contacted again with backoff 1 s doubling to
 * 300 s, each distinct refusal logged once. On stop the worker
 * says BYE("signal"). Blocks; frees everything it allocated before
 * returning. Returns a PF_WORKER_EXIT_* code. */
int pf_worker_run(const pf_worker_opts_t *opts);

#endif
