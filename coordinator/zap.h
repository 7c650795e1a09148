/* zap.h: the ZAP handler (ZeroMQ RFC 27) that admits only listed CURVE
 * client keys. Without a ZAP handler libzmq admits any client that knows the
 * server's public key, so the coordinator always runs one with CURVE. */
#ifndef PF_ZAP_H
#define PF_ZAP_H

#include <stddef.h>

typedef struct pf_zap pf_zap_t;

/* Starts the handler thread on ctx (binds inproc://zeromq.zap.01; must run
 * before the server socket binds). keys: n Z85 public keys, copied. NULL on
 * failure. */
pf_zap_t *pf_zap_start(void *ctx, const char (*keys)[41], size_t n);
/* Stops the thread; NULL-safe. Returns how many clients it refused. */
int pf_zap_stop(pf_zap_t **self_p);

#endif
