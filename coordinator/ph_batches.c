/* ph_batches.c: the table of a photon pass's batches, shared by the photon
 * thread (which traces) and the event loop (which leases to workers and
 * takes their results in); see ph_batches.h.
 *
 * A batch is FREE, LEASED (to a worker uid, maybe also being traced here:
 * `local`) or DONE. A worker's result arrives in parts, in order, on one
 * connection; the parts must agree with each other and with the plan: a
 * batch of a map with E emitted photons in the batch stores at most
 * E * photon_max_depth global photons (one a bounce) or E caustic ones (one
 * a path), and rejects at most E. Whatever disagrees is refused (the caller
 * strikes the sender) and the batch is free again.
 *
 * Spot checks: a worker's complete batch is drawn for a check when it
 * arrives (S_CHK_WANT); the photon thread re-traces drawn batches when no
 * free batch is left (before it steals leased ones: a lie found early
 * re-issues less), and when every batch is in it draws one more batch of
 * each worker that had none checked, so the merge never takes a worker's
 * photons unchecked. A mismatch discards everything that worker returned
 * this pass (the batch checked keeps the coordinator's trace).
 *
 * Owns the table and the batches' photons until pf_phq_merge takes them.
 * Threads: all under q->mu; pf_phq_run traces with it unlocked. */
#include "coordinator/ph_batches.h"

#include <inttypes.h>
#include <pthread.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "base/hash.h"
#include "base/log.h"

enum { S_FREE = 0, S_LEASED, S_DONE };
enum { S_CHK_NONE = 0, S_CHK_WANT, S_CHK_OK }; /* a worker's done batch: its check */

#define S_MAX_BARRED 64 /* liars a pass remembers (more are refused by the farm's strikes anyway) */
#define S_MAX_LIARS 16  /* liars queued for the event loop */

#define S_LOCAL_RUN 4 /* free batches the photon thread takes at once */

typedef struct s_batch {
    int state;
    int local;              /* the photon thread is tracing it */
    volatile int abort;     /* set when a worker's result wins while it is traced here */
    uint32_t uid;           /* the lessee (S_LEASED), 0: none */
    double leased_at;
    pf_photon_batch_t res;  /* S_DONE: the result */
    uint32_t done_uid;      /* S_DONE: the worker whose result it is, 0: traced here */
    int check;              /* S_CHK_: a worker's result, drawn for a check */
    /* a worker's result coming in parts */
    pf_photon_t *recv;
    uint64_t total, got, cap, rejected, indirect;
    uint32_t recv_uid;
} s_batch;

struct pf_phq {
    pthread_mutex_t mu;
    const pf_photon_tracer_t *tracer;
    pf_photon_plan_t plan;
    uint32_t nb, ndone;
    s_batch *b;
    uint64_t max_global, max_caustic; /* stored photons a batch may hold */
    pf_phq_stats_t st;
    uint64_t secret;        /* the per-run secret the checks are drawn with */
    uint32_t one_in;        /* 0: no checks */
    uint32_t barred[S_MAX_BARRED], nbarred;
    uint32_t liar[S_MAX_LIARS], nliar;
    char liar_why[S_MAX_LIARS][160];
};

/* Photons emitted in batch i. */
static uint64_t s_emitted(const pf_phq_t *q, uint32_t i)
{
    int caustic = i >= q->plan.global_batches;
    uint64_t emitted = caustic ? q->plan.caustic_emitted : q->plan.global_emitted;
    uint64_t per = (uint64_t)PF_PHOTON_BATCH_BLOCKS * PF_PHOTON_BLOCK;
    uint64_t lo = (uint64_t)(caustic ? i - q->plan.global_batches : i) * per;
    return emitted - lo < per ? emitted - lo : per;
}

pf_phq_t *pf_phq_new(const pf_photon_tracer_t *tracer, int max_depth)
{
    pf_phq_t *q = calloc(1, sizeof *q);
    if (!q)
        return NULL;
    q->tracer = tracer;
    q->plan = *pf_photon_tracer_plan(tracer);
    q->nb = q->plan.global_batches + q->plan.caustic_batches;
    q->b = calloc(q->nb ? q->nb : 1, sizeof *q->b);
    if (!q->b || pthread_mutex_init(&q->mu, NULL) != 0) {
        free(q->b);
        free(q);
        return NULL;
    }
    uint64_t per = (uint64_t)PF_PHOTON_BATCH_BLOCKS * PF_PHOTON_BLOCK;
    q->max_global = per * (uint64_t)(max_depth > 0 ? max_depth : 1);
    q->max_caustic = per;
    q->st.batches = q->nb;
    q->st.emitted = q->plan.global_emitted + q->plan.caustic_emitted;
    return q;
}

void pf_phq_checks(pf_phq_t *q, uint64_t secret, uint32_t one_in)
{
    pthread_mutex_lock(&q->mu);
    q->secret = secret;
    q->one_in = one_in;
    pthread_mutex_unlock(&q->mu);
}

/* The draw for batch i returned by uid: a hash only the coordinator can
 * compute (the secret), different for the same batch from another worker. */
static uint64_t s_draw(const pf_phq_t *q, uint32_t i, uint32_t uid)
{
    return pf_hash_u64(pf_hash_u64(pf_hash_u64(PF_HASH_INIT, q->secret), i), uid);
}

static int s_barred(const pf_phq_t *q, uint32_t uid)
{
    for (uint32_t k = 0; k < q->nbarred; k++)
        if (q->barred[k] == uid)
            return 1;
    return 0;
}

static void s_drop_recv(s_batch *b)
{
    free(b->recv);
    b->recv = NULL;
    b->total = b->got = b->cap = b->rejected = b->indirect = 0;
    b->recv_uid = 0;
}

void pf_phq_free(pf_phq_t **q_p)
{
    pf_phq_t *q = *q_p;
    if (!q)
        return;
    for (uint32_t i = 0; i < q->nb; i++) {
        free(q->b[i].res.p);
        s_drop_recv(&q->b[i]);
    }
    free(q->b);
    pthread_mutex_destroy(&q->mu);
    free(q);
    *q_p = NULL;
}

/* Every batch is in: each worker with no batch checked gets one drawn
 * (the lowest draw of its batches). Returns how many were drawn (0 also
 * when memory is short: the sampled checks stand). */
typedef struct s_cand {
    uint32_t uid, idx;
    uint64_t draw;
    int check;
} s_cand;

static int s_cand_cmp(const void *a, const void *b)
{
    const s_cand *x = a, *y = b;
    if (x->uid != y->uid)
        return x->uid < y->uid ? -1 : 1;
    return x->draw < y->draw ? -1 : x->draw > y->draw;
}

static uint32_t s_draw_unchecked(pf_phq_t *q)
{
    s_cand *c = malloc((q->nb ? q->nb : 1) * sizeof *c);
    if (!c)
        return 0;
    uint32_t n = 0, drawn = 0;
    for (uint32_t i = 0; i < q->nb; i++)
        if (q->b[i].state == S_DONE && q->b[i].done_uid)
            c[n++] = (s_cand){ q->b[i].done_uid, i, s_draw(q, i, q->b[i].done_uid), q->b[i].check };
    qsort(c, n, sizeof *c, s_cand_cmp);
    for (uint32_t k = 0; k < n;) {
        uint32_t e = k;
        int any = 0;
        while (e < n && c[e].uid == c[k].uid)
            any |= c[e++].check != S_CHK_NONE;
        if (!any) {
            q->b[c[k].idx].check = S_CHK_WANT; /* its lowest draw */
            drawn++;
        }
        k = e;
    }
    free(c);
    return drawn;
}

/* The batches the photon thread traces next: up to S_LOCAL_RUN consecutive
 * free ones (the threads share their blocks), else a worker's batch to
 * check (*check = 1), else the oldest leased one it is not tracing
 * (*n = 1); UINT32_MAX: none left. */
static uint32_t s_pick(pf_phq_t *q, uint32_t *n, int *check)
{
    uint32_t oldest = UINT32_MAX, want = UINT32_MAX;
    *n = 1;
    *check = 0;
    for (uint32_t i = 0; i < q->nb; i++) {
        s_batch *b = &q->b[i];
        if (b->state == S_FREE) {
            while (*n < S_LOCAL_RUN && i + *n < q->nb && q->b[i + *n].state == S_FREE)
                (*n)++;
            return i;
        }
        if (b->state == S_DONE && b->check == S_CHK_WANT && want == UINT32_MAX)
            want = i;
        if (b->state == S_LEASED && !b->local && (oldest == UINT32_MAX || b->leased_at < q->b[oldest].leased_at))
            oldest = i;
    }
    if (want == UINT32_MAX && oldest == UINT32_MAX && q->one_in && s_draw_unchecked(q))
        return s_pick(q, n, check);
    *check = want != UINT32_MAX;
    return want != UINT32_MAX ? want : oldest;
}

/* Worker uid lied: barred from the pass, queued for the event loop, its
 * leases revoked and every batch it returned discarded (free again). */
static void s_liar(pf_phq_t *q, uint32_t uid, const char *why)
{
    if (q->nbarred < S_MAX_BARRED)
        q->barred[q->nbarred++] = uid;
    if (q->nliar < S_MAX_LIARS) {
        q->liar[q->nliar] = uid;
        snprintf(q->liar_why[q->nliar], sizeof q->liar_why[0], "%s", why);
        q->nliar++;
    }
    q->st.mismatches++;
    for (uint32_t j = 0; j < q->nb; j++) {
        s_batch *c = &q->b[j];
        if (c->state == S_LEASED && c->uid == uid) {
            c->uid = 0;
            s_drop_recv(c);
            if (!c->local)
                c->state = S_FREE;
        } else if (c->state == S_DONE && c->done_uid == uid) {
            free(c->res.p);
            memset(&c->res, 0, sizeof c->res);
            c->state = S_FREE;
            c->done_uid = 0;
            c->check = S_CHK_NONE;
            q->ndone--;
            q->st.remote--;
            q->st.discarded++;
        }
    }
}

/* Re-traces worker batch i here and compares it bit for bit. 0, or the
 * tracer's failure. */
static int s_check(pf_phq_t *q, uint32_t i, int threads)
{
    volatile int never = 0;
    pf_photon_batch_t mine;
    int rc = pf_photon_trace_batches(q->tracer, i, 1, threads, &never, &mine);
    if (rc != PF_OK)
        return rc;
    pthread_mutex_lock(&q->mu);
    s_batch *b = &q->b[i];
    q->st.checked++;
    const pf_photon_batch_t *r = &b->res;
    int same = r->n == mine.n && r->rejected == mine.rejected && r->indirect == mine.indirect &&
               (mine.n == 0 || memcmp(r->p, mine.p, (size_t)mine.n * sizeof *mine.p) == 0);
    if (same) {
        b->check = S_CHK_OK;
        free(mine.p);
    } else {
        char why[160];
        snprintf(why, sizeof why, "photon batch %" PRIu32 " differs from the coordinator's trace (%" PRIu64 " photons "
                 "returned, %" PRIu64 " traced here)", i, r->n, mine.n);
        s_liar(q, b->done_uid, why);
        /* This batch keeps the trace just made. */
        b->state = S_DONE;
        b->res = mine;
        q->ndone++;
        q->st.local++;
    }
    pthread_mutex_unlock(&q->mu);
    return PF_OK;
}

int pf_phq_run(pf_phq_t *q, int threads)
{
    pf_photon_batch_t res[S_LOCAL_RUN];
    for (;;) {
        uint32_t n;
        int check;
        pthread_mutex_lock(&q->mu);
        uint32_t i = s_pick(q, &n, &check);
        if (i == UINT32_MAX) {
            pthread_mutex_unlock(&q->mu);
            return PF_OK;
        }
        if (check) {
            pthread_mutex_unlock(&q->mu);
            int rc = s_check(q, i, threads); /* a DONE batch: nobody else changes it */
            if (rc != PF_OK)
                return rc;
            continue;
        }
        s_batch *b = &q->b[i];
        if (b->state == S_LEASED)
            q->st.stolen++; /* a worker's: whoever finishes first, the other's result is dropped */
        for (uint32_t k = 0; k < n; k++) {
            if (b[k].state == S_FREE)
                b[k].state = S_LEASED; /* uid 0: the coordinator's */
            b[k].local = 1;
            b[k].abort = 0;
        }
        pthread_mutex_unlock(&q->mu);

        /* Only a stolen batch (n == 1) can be won by a worker meanwhile. */
        int rc = pf_photon_trace_batches(q->tracer, i, n, threads, &b->abort, res);

        pthread_mutex_lock(&q->mu);
        int won = b->abort;
        for (uint32_t k = 0; k < n; k++) {
            b[k].local = 0;
            if (rc == PF_OK && b[k].state != S_DONE) {
                b[k].state = S_DONE;
                b[k].res = res[k];
                b[k].uid = 0;
                b[k].done_uid = 0;
                b[k].check = S_CHK_NONE;
                s_drop_recv(&b[k]);
                q->ndone++;
                q->st.local++;
            } else {
                free(res[k].p);
                if (rc != PF_OK && b[k].state == S_LEASED && b[k].uid == 0)
                    b[k].state = S_FREE;
            }
        }
        pthread_mutex_unlock(&q->mu);
        if (rc != PF_OK && !(rc == PF_EINTERRUPTED && won))
            return rc; /* out of memory, or the process is stopping */
    }
}

uint32_t pf_phq_lease(pf_phq_t *q, uint32_t uid, uint32_t count, double now, uint32_t *first)
{
    pthread_mutex_lock(&q->mu);
    uint32_t n = 0, i = 0;
    while (i < q->nb && q->b[i].state != S_FREE)
        i++;
    if (s_barred(q, uid))
        i = q->nb;
    *first = i;
    for (; i < q->nb && n < count && q->b[i].state == S_FREE; i++, n++) {
        q->b[i].state = S_LEASED;
        q->b[i].uid = uid;
        q->b[i].leased_at = now;
    }
    pthread_mutex_unlock(&q->mu);
    return n;
}

uint32_t pf_phq_held(pf_phq_t *q, uint32_t uid)
{
    pthread_mutex_lock(&q->mu);
    uint32_t n = 0;
    for (uint32_t i = 0; i < q->nb; i++)
        n += q->b[i].state == S_LEASED && q->b[i].uid == uid;
    pthread_mutex_unlock(&q->mu);
    return n;
}

/* Batch i leaves its lessee: free again (or still the photon thread's). */
static void s_unlease(s_batch *b)
{
    b->uid = 0;
    s_drop_recv(b);
    if (!b->local)
        b->state = S_FREE;
}

uint32_t pf_phq_release(pf_phq_t *q, uint32_t uid)
{
    pthread_mutex_lock(&q->mu);
    uint32_t n = 0;
    for (uint32_t i = 0; i < q->nb; i++)
        if (q->b[i].state == S_LEASED && q->b[i].uid == uid) {
            s_unlease(&q->b[i]);
            n++;
        }
    pthread_mutex_unlock(&q->mu);
    return n;
}

uint32_t pf_phq_expire(pf_phq_t *q, double now, double timeout_s)
{
    pthread_mutex_lock(&q->mu);
    uint32_t n = 0;
    for (uint32_t i = 0; i < q->nb; i++) {
        s_batch *b = &q->b[i];
        if (b->state == S_LEASED && b->uid && now - b->leased_at > timeout_s) {
            s_unlease(b);
            n++;
        }
    }
    q->st.expired += n;
    pthread_mutex_unlock(&q->mu);
    return n;
}

/* A part of batch b from uid, checked against the plan and the parts
 * before it; 0 or -1 with why. */
static int s_check_part(const pf_phq_t *q, const s_batch *b, uint32_t i, uint32_t uid, const pf_msg_photons_t *p,
                        char *why, size_t why_len)
{
    uint64_t emitted = s_emitted(q, i);
    uint64_t most = i < q->plan.global_batches ? q->max_global : q->max_caustic;
    if (p->first == 0) {
        if (p->total > most || p->rejected > emitted) {
            snprintf(why, why_len, "PHOTONS: batch %" PRIu32 " of %" PRIu64 " photons emitted cannot store %" PRIu64
                     " (at most %" PRIu64 ") or reject %" PRIu64, i, emitted, p->total, most, p->rejected);
            return -1;
        }
        if (i >= q->plan.global_batches && p->indirect) {
            snprintf(why, why_len, "PHOTONS: caustic batch %" PRIu32 " with indirect photons", i);
            return -1;
        }
        return 0;
    }
    if (b->recv_uid != uid || p->first != b->got || p->total != b->total || p->rejected != b->rejected ||
        p->indirect != b->indirect) {
        snprintf(why, why_len, "PHOTONS: batch %" PRIu32 " part at %" PRIu64 " of %" PRIu64 " does not follow the parts "
                 "before it (%" PRIu64 " of %" PRIu64 " received)", i, p->first, p->total, b->got, b->total);
        return -1;
    }
    return 0;
}

int pf_phq_on_photons(pf_phq_t *q, uint32_t uid, const pf_msg_photons_t *p, char *why, size_t why_len)
{
    pthread_mutex_lock(&q->mu);
    int rc = PF_PHQ_PART;
    uint32_t i = p->batch;
    s_batch *b = i < q->nb ? &q->b[i] : NULL;
    if (!b) {
        snprintf(why, why_len, "PHOTONS: batch %" PRIu32 " is not in this pass (%" PRIu32 " batches)", i, q->nb);
        rc = PF_PHQ_BAD;
    } else if (b->state != S_LEASED || b->uid != uid) {
        q->st.stale++;
        rc = PF_PHQ_STALE;
    } else if (s_check_part(q, b, i, uid, p, why, why_len) != 0) {
        s_unlease(b);
        rc = PF_PHQ_BAD;
    } else {
        if (p->first == 0) {
            s_drop_recv(b);
            b->total = p->total;
            b->rejected = p->rejected;
            b->indirect = p->indirect;
            b->recv_uid = uid;
        }
        /* The buffer grows as parts arrive (doubling, never past the total
         * announced), so a total that no photons follow costs nothing. */
        if (b->got + p->n > b->cap || !b->recv) {
            uint64_t cap = b->cap ? b->cap : 1;
            while (cap < b->got + p->n)
                cap *= 2;
            cap = cap < b->total ? cap : (b->total ? b->total : 1);
            pf_photon_t *grown = cap <= SIZE_MAX / sizeof *grown ? realloc(b->recv, (size_t)cap * sizeof *grown) : NULL;
            if (grown) {
                b->recv = grown;
                b->cap = cap;
            } else {
                free(b->recv);
                b->recv = NULL;
            }
        }
        if (!b->recv) {
            snprintf(why, why_len, "PHOTONS: out of memory for %" PRIu64 " photons", p->total);
            s_unlease(b);
            rc = PF_PHQ_STALE;
        } else {
            for (uint32_t k = 0; k < p->n; k++) {
                pf_msg_photon_t m;
                pf_msg_photon_get(p, k, &m);
                pf_photon_t *d = &b->recv[b->got + k];
                memcpy(d->pos, m.pos, sizeof d->pos);
                memcpy(d->power, m.power, sizeof d->power);
                d->dir = m.dir;
                d->normal = m.normal;
            }
            b->got += p->n;
            if (b->got == b->total) {
                b->res = (pf_photon_batch_t){ b->recv, b->total, b->rejected, b->indirect };
                b->recv = NULL;
                b->state = S_DONE;
                b->abort = 1; /* a local trace of it stops */
                b->done_uid = uid;
                b->check = q->one_in && s_draw(q, i, uid) % q->one_in == 0 ? S_CHK_WANT : S_CHK_NONE;
                q->ndone++;
                q->st.remote++;
                rc = PF_PHQ_DONE;
            }
        }
    }
    pthread_mutex_unlock(&q->mu);
    return rc;
}

int pf_phq_merge(pf_phq_t *q, const pf_scene_t *scene, const pf_accel_t *accel, const pf_settings_t *settings,
                 pf_photon_maps_t *maps, pf_photon_stats_t *stats, const pf_irr_spread_t *spread)
{
    pthread_mutex_lock(&q->mu);
    int complete = q->ndone == q->nb;
    pf_photon_batch_t *res = complete ? malloc((q->nb ? q->nb : 1) * sizeof *res) : NULL;
    if (res)
        for (uint32_t i = 0; i < q->nb; i++) {
            res[i] = q->b[i].res;
            memset(&q->b[i].res, 0, sizeof q->b[i].res);
        }
    pthread_mutex_unlock(&q->mu);
    if (!res)
        return complete ? PF_ENOMEM : PF_EINVAL;
    int rc = pf_photon_merge_spread(scene, accel, settings, &q->plan, res, maps, stats, spread);
    for (uint32_t i = 0; i < q->nb; i++)
        free(res[i].p);
    free(res);
    return rc;
}

int pf_phq_take_liar(pf_phq_t *q, uint32_t *uid, char *why, size_t why_len)
{
    pthread_mutex_lock(&q->mu);
    int got = q->nliar > 0;
    if (got) {
        *uid = q->liar[0];
        snprintf(why, why_len, "%s", q->liar_why[0]);
        q->nliar--;
        memmove(q->liar, q->liar + 1, q->nliar * sizeof q->liar[0]);
        memmove(q->liar_why, q->liar_why + 1, q->nliar * sizeof q->liar_why[0]);
    }
    pthread_mutex_unlock(&q->mu);
    return got;
}

void pf_phq_progress(pf_phq_t *q, uint32_t *done, uint32_t *total)
{
    pthread_mutex_lock(&q->mu);
    *done = q->ndone;
    *total = q->nb;
    pthread_mutex_unlock(&q->mu);
}

void pf_phq_stats(pf_phq_t *q, pf_phq_stats_t *out)
{
    pthread_mutex_lock(&q->mu);
    *out = q->st;
    pthread_mutex_unlock(&q->mu);
}
