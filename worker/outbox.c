/* outbox.c: the worker's log lines and its messages to the coordinator:
 * encoding, sending without blocking, and the outbox that holds what the
 * socket cannot take yet (sent in order by pf_w_flush). Main thread only,
 * but for pf_w_log, which any thread may call. The bottom of worker/: it
 * calls no other file of the worker. */
#include <errno.h>
#include <inttypes.h>
#include <stdarg.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <zmq.h>

#include "worker/worker_impl.h"

void pf_w_log(const s_worker *w, pf_log_level level, const char *fmt, ...)
{
    if (level < pf_log_get_level())
        return;
    char line[1800];
    va_list ap;
    va_start(ap, fmt);
    vsnprintf(line, sizeof line, fmt, ap);
    va_end(ap);
    pf_log(level, "worker %s: %s", w->name, line);
}

void pf_w_send(s_worker *w, const pf_msg_t *msg, int droppable)
{
    if (!w->sock)
        return;
    int rc = pf_msg_encode(msg, &w->enc);
    if (rc) {
        pf_w_log(w, PF_LOG_ERROR, "cannot encode %s for job %" PRIu64 ": %s", pf_msg_type_name(msg->type), msg->job,
                 pf_strerror(rc));
        return;
    }
    if (!w->out) {
        if (zmq_send(w->sock, w->enc.data, w->enc.len, ZMQ_DONTWAIT) >= 0)
            return;
        if (errno != EAGAIN) {
            pf_w_log(w, PF_LOG_WARN, "cannot send %s: %s", pf_msg_type_name(msg->type), zmq_strerror(errno));
            return;
        }
    }
    if (droppable)
        return;
    s_out *o = malloc(sizeof *o + w->enc.len);
    if (!o) {
        pf_w_log(w, PF_LOG_ERROR, "out of memory queueing %s", pf_msg_type_name(msg->type));
        return;
    }
    o->next = NULL;
    o->len = w->enc.len;
    memcpy(o->data, w->enc.data, w->enc.len);
    if (w->out_tail)
        w->out_tail->next = o;
    else
        w->out = o;
    w->out_tail = o;
}

void pf_w_flush(s_worker *w)
{
    while (w->out && w->sock) {
        if (zmq_send(w->sock, w->out->data, w->out->len, ZMQ_DONTWAIT) < 0) {
            if (errno == EAGAIN)
                return;
            pf_w_log(w, PF_LOG_WARN, "cannot send a queued message: %s", zmq_strerror(errno));
        }
        s_out *o = w->out;
        w->out = o->next;
        if (!w->out)
            w->out_tail = NULL;
        free(o);
    }
}

void pf_w_outbox_clear(s_worker *w)
{
    while (w->out) {
        s_out *o = w->out;
        w->out = o->next;
        free(o);
    }
    w->out_tail = NULL;
}
