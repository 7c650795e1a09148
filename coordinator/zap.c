/* zap.c: ZAP handler thread; see zap.h. The thread owns one ZMQ_REP socket
 * on inproc://zeromq.zap.01 and answers every authentication request of the
 * context: mechanism CURVE and a client key on the list get "200", anything
 * else "400" and one log line naming the peer's address. */
#include "coordinator/zap.h"

#include <pthread.h>
#include <stdlib.h>
#include <string.h>
#include <zmq.h>

#include "base/log.h"

struct pf_zap {
    void *ctx;
    void *sock;
    pthread_t thread;
    char (*keys)[41];
    size_t n;
    volatile int stop;
    int refused;
};

/* Receives one frame into buf (NUL-terminated, truncated); returns its size or -1. */
static int s_recv(void *sock, char *buf, size_t cap, int *more)
{
    int n = zmq_recv(sock, buf, cap - 1, 0);
    if (n < 0)
        return -1;
    buf[(size_t)n < cap - 1 ? (size_t)n : cap - 1] = 0;
    int m = 0;
    size_t ml = sizeof m;
    zmq_getsockopt(sock, ZMQ_RCVMORE, &m, &ml);
    *more = m;
    return n;
}

static void *s_run(void *arg)
{
    pf_zap_t *z = arg;
    while (!z->stop) {
        zmq_pollitem_t it = { z->sock, 0, ZMQ_POLLIN, 0 };
        if (zmq_poll(&it, 1, 100) <= 0)
            continue;
        char version[16], reqid[256], domain[256], address[256], identity[256], mech[32], cred[64];
        int more = 0, n;
        char *frames[] = { version, reqid, domain, address, identity, mech };
        size_t caps[] = { sizeof version, sizeof reqid, sizeof domain, sizeof address, sizeof identity, sizeof mech };
        int reqid_len = 0, ok = 1;
        for (int i = 0; i < 6; i++) {
            n = s_recv(z->sock, frames[i], caps[i], &more);
            if (n < 0 || !more) {
                ok = 0;
                break;
            }
            if (i == 1)
                reqid_len = n < (int)sizeof reqid ? n : (int)sizeof reqid - 1;
        }
        int cred_len = 0;
        if (ok) {
            cred_len = zmq_recv(z->sock, cred, sizeof cred, 0);
            size_t ml = sizeof more;
            zmq_getsockopt(z->sock, ZMQ_RCVMORE, &more, &ml);
        }
        while (more) { /* drain anything unexpected */
            char junk[256];
            zmq_recv(z->sock, junk, sizeof junk, 0);
            size_t ml = sizeof more;
            zmq_getsockopt(z->sock, ZMQ_RCVMORE, &more, &ml);
        }
        int allow = 0;
        char z85[41] = "";
        if (ok && strcmp(mech, "CURVE") == 0 && cred_len == 32 && zmq_z85_encode(z85, (uint8_t *)cred, 32)) {
            for (size_t i = 0; i < z->n && !allow; i++)
                allow = strcmp(z->keys[i], z85) == 0;
        }
        if (!allow) {
            z->refused++;
            pf_warn("refused a worker at %s: %s", ok ? address : "?",
                    !ok ? "malformed authentication request"
                        : strcmp(mech, "CURVE") ? "not using CURVE" : "its public key is not in the allowed list");
        }
        const char *code = allow ? "200" : "400";
        const char *text = allow ? "OK" : "key not allowed";
        zmq_send(z->sock, "1.0", 3, ZMQ_SNDMORE);
        zmq_send(z->sock, reqid, (size_t)reqid_len, ZMQ_SNDMORE);
        zmq_send(z->sock, code, 3, ZMQ_SNDMORE);
        zmq_send(z->sock, text, strlen(text), ZMQ_SNDMORE);
        zmq_send(z->sock, allow ? z85 : "", allow ? 40 : 0, ZMQ_SNDMORE);
        zmq_send(z->sock, "", 0, 0);
    }
    return NULL;
}

pf_zap_t *pf_zap_start(void *ctx, const char (*keys)[41], size_t n)
{
    pf_zap_t *z = calloc(1, sizeof *z);
    if (!z)
        return NULL;
    z->ctx = ctx;
    z->keys = calloc(n ? n : 1, sizeof *z->keys);
    z->n = n;
    if (!z->keys) {
        free(z);
        return NULL;
    }
    memcpy(z->keys, keys, n * sizeof *z->keys);
    z->sock = zmq_socket(ctx, ZMQ_REP);
    int linger = 0;
    if (!z->sock || zmq_setsockopt(z->sock, ZMQ_LINGER, &linger, sizeof linger) ||
        zmq_bind(z->sock, "inproc://zeromq.zap.01") != 0) {
        pf_error("cannot start the ZAP handler: %s", zmq_strerror(zmq_errno()));
        if (z->sock)
            zmq_close(z->sock);
        free(z->keys);
        free(z);
        return NULL;
    }
    if (pthread_create(&z->thread, NULL, s_run, z) != 0) {
        zmq_close(z->sock);
        free(z->keys);
        free(z);
        return NULL;
    }
    return z;
}

int pf_zap_stop(pf_zap_t **self_p)
{
    if (!self_p || !*self_p)
        return 0;
    pf_zap_t *z = *self_p;
    z->stop = 1;
    pthread_join(z->thread, NULL);
    zmq_close(z->sock);
    int refused = z->refused;
    free(z->keys);
    free(z);
    *self_p = NULL;
    return refused;
}
