/* irr_chunks.c: the table of a pass's irradiance chunks, shared by the
 * photon thread (which computes) and the event loop (which leases to
 * workers and takes their results in); see irr_chunks.h.
 *
 * A chunk is FREE, LEASED (to a worker uid, maybe also being computed here:
 * `local`) or DONE. Results are written straight into the caller's arrays
 * under the mutex, only into a chunk that is not DONE, so the first valid
 * result of a chunk wins and a late one is dropped. The photon thread
 * computes into its own buffer and copies under the mutex the same way.
 *
 * Owns the table only; the records live in the caller's arrays.
 * Threads: all under q->mu; pf_irq_run computes with it unlocked. */
#include "coordinator/irr_chunks.h"

#include <inttypes.h>
#include <math.h>
#include <pthread.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "base/hash.h"
#include "photon/irradiance.h"

enum { S_FREE = 0, S_LEASED, S_DONE };
enum { S_CHK_NONE = 0, S_CHK_WANT, S_CHK_OK };

#define S_LOCAL_RUN 8   /* free chunks the photon thread takes at once */
#define S_MAX_SEEN 256  /* workers whose first chunk the table remembers checking */
#define S_MAX_BARRED 64
#define S_MAX_LIARS 16
#define S_CHUNK PF_PROTO_IRR_CHUNK_POINTS

typedef struct s_chunk {
    int state, local, check;
    uint32_t uid, done_uid;
    double leased_at;
} s_chunk;

struct pf_irq {
    pthread_mutex_t mu;
    const pf_kdtree_t *global;
    const pf_accel_t *accel;
    pf_irr_plan_t plan;
    pf_photon_t *out[2];
    uint32_t per_map, nc, ndone;
    int closed;
    s_chunk *c;
    float max_r;
    pf_irq_stats_t st;
    uint64_t secret;
    uint32_t one_in;
    uint32_t seen[S_MAX_SEEN], nseen;
    uint32_t barred[S_MAX_BARRED], nbarred;
    uint32_t liar[S_MAX_LIARS], nliar;
    char liar_why[S_MAX_LIARS][160];
};

pf_irq_t *pf_irq_new(const pf_kdtree_t *global, const pf_accel_t *accel, const pf_irr_plan_t *plan,
                     pf_photon_t *main, pf_photon_t *deep)
{
    pf_irq_t *q = calloc(1, sizeof *q);
    if (!q)
        return NULL;
    q->global = global;
    q->accel = accel;
    q->plan = *plan;
    q->out[0] = main;
    q->out[1] = deep;
    q->per_map = (uint32_t)((plan->points + S_CHUNK - 1) / S_CHUNK);
    q->nc = q->per_map * (plan->has_deep ? 2u : 1u);
    q->c = calloc(q->nc ? q->nc : 1, sizeof *q->c);
    if (!q->c || pthread_mutex_init(&q->mu, NULL) != 0) {
        free(q->c);
        free(q);
        return NULL;
    }
    q->max_r = sqrtf(plan->main.max_r2);
    q->st.chunks = q->nc;
    return q;
}

void pf_irq_free(pf_irq_t **q_p)
{
    pf_irq_t *q = *q_p;
    if (!q)
        return;
    free(q->c);
    pthread_mutex_destroy(&q->mu);
    free(q);
    *q_p = NULL;
}

void pf_irq_checks(pf_irq_t *q, uint64_t secret, uint32_t one_in)
{
    pthread_mutex_lock(&q->mu);
    q->secret = secret;
    q->one_in = one_in;
    pthread_mutex_unlock(&q->mu);
}

uint32_t pf_irq_chunks(const pf_irq_t *q) { return q->nc; }

/* Chunk i's first point (in its map), its point count and its map (0: the
 * irradiance map, 1: the deep one). */
static uint32_t s_span(const pf_irq_t *q, uint32_t i, size_t *first, int *map)
{
    *map = i >= q->per_map;
    *first = (size_t)(i - (*map ? q->per_map : 0)) * S_CHUNK;
    size_t left = q->plan.points - *first;
    return (uint32_t)(left < S_CHUNK ? left : S_CHUNK);
}

static int s_barred(const pf_irq_t *q, uint32_t uid)
{
    for (uint32_t k = 0; k < q->nbarred; k++)
        if (q->barred[k] == uid)
            return 1;
    return 0;
}

/* Computes chunks [i, i + n) here (one map) into buf. 0 or PF_ENOMEM. */
static int s_compute(const pf_irq_t *q, uint32_t i, uint32_t n, int threads, pf_photon_t *buf, size_t *count)
{
    size_t first;
    int map;
    s_span(q, i, &first, &map);
    size_t last_first;
    int last_map;
    size_t last_n = s_span(q, i + n - 1, &last_first, &last_map);
    *count = last_first + last_n - first;
    return pf_irradiance_points(q->global, map ? &q->plan.deep : &q->plan.main, q->accel, threads, first, *count,
                                buf);
}

/* Worker uid lied: barred, queued for a strike, its leases revoked and
 * every chunk it returned free again. */
static void s_liar(pf_irq_t *q, uint32_t uid, const char *why)
{
    if (q->nbarred < S_MAX_BARRED)
        q->barred[q->nbarred++] = uid;
    if (q->nliar < S_MAX_LIARS) {
        q->liar[q->nliar] = uid;
        snprintf(q->liar_why[q->nliar], sizeof q->liar_why[0], "%s", why);
        q->nliar++;
    }
    q->st.mismatches++;
    for (uint32_t j = 0; j < q->nc; j++) {
        s_chunk *c = &q->c[j];
        if (c->state == S_LEASED && c->uid == uid) {
            c->uid = 0;
            if (!c->local)
                c->state = S_FREE;
        } else if (c->state == S_DONE && c->done_uid == uid) {
            c->state = S_FREE;
            c->done_uid = 0;
            c->check = S_CHK_NONE;
            q->ndone--;
            q->st.remote--;
            q->st.discarded++;
        }
    }
}

/* What the photon thread does next: up to S_LOCAL_RUN consecutive free
 * chunks of one map, taken from the end of the table (the workers are
 * leased from its start, so the two meet as late as they can), else a
 * worker's chunk to check (*check), else the oldest leased one (*n = 1);
 * UINT32_MAX: nothing left. */
static uint32_t s_pick(pf_irq_t *q, uint32_t *n, int *check)
{
    uint32_t oldest = UINT32_MAX, want = UINT32_MAX;
    *n = 1;
    *check = 0;
    for (uint32_t i = q->nc; i-- > 0;) {
        if (q->c[i].state != S_FREE)
            continue;
        while (*n < S_LOCAL_RUN && i > 0 && q->c[i - 1].state == S_FREE && (i - 1 < q->per_map) == (i < q->per_map)) {
            i--;
            (*n)++;
        }
        return i;
    }
    for (uint32_t i = 0; i < q->nc; i++) {
        s_chunk *c = &q->c[i];
        if (c->state == S_DONE && c->check == S_CHK_WANT && want == UINT32_MAX)
            want = i;
        if (c->state == S_LEASED && !c->local && (oldest == UINT32_MAX || c->leased_at < q->c[oldest].leased_at))
            oldest = i;
    }
    *check = want != UINT32_MAX;
    return want != UINT32_MAX ? want : oldest;
}

/* Re-computes worker chunk i here and compares it bit for bit. */
static int s_check(pf_irq_t *q, uint32_t i, int threads, pf_photon_t *buf)
{
    size_t count, first;
    int map;
    int rc = s_compute(q, i, 1, threads, buf, &count);
    if (rc != PF_OK)
        return rc;
    s_span(q, i, &first, &map);
    pthread_mutex_lock(&q->mu);
    s_chunk *c = &q->c[i];
    q->st.checked++;
    if (c->state == S_DONE && c->done_uid) {
        pf_photon_t *dst = q->out[map] + first;
        if (memcmp(dst, buf, count * sizeof *buf) == 0) {
            c->check = S_CHK_OK;
        } else {
            char why[160];
            snprintf(why, sizeof why, "irradiance chunk %" PRIu32 " differs from the coordinator's", i);
            s_liar(q, c->done_uid, why);
            memcpy(dst, buf, count * sizeof *buf); /* this chunk keeps the coordinator's */
            c->state = S_DONE;
            c->check = S_CHK_OK;
            q->ndone++;
            q->st.local++;
        }
    }
    pthread_mutex_unlock(&q->mu);
    return PF_OK;
}

int pf_irq_run(pf_irq_t *q, int threads)
{
    pf_photon_t *buf = malloc((size_t)S_LOCAL_RUN * S_CHUNK * sizeof *buf);
    if (!buf)
        return PF_ENOMEM;
    int rc = PF_OK;
    for (;;) {
        uint32_t n;
        int check;
        pthread_mutex_lock(&q->mu);
        uint32_t i = s_pick(q, &n, &check);
        if (i == UINT32_MAX) {
            q->closed = 1;
            pthread_mutex_unlock(&q->mu);
            break;
        }
        if (check) {
            pthread_mutex_unlock(&q->mu);
            rc = s_check(q, i, threads, buf);
            if (rc != PF_OK)
                break;
            continue;
        }
        s_chunk *c = &q->c[i];
        if (c->state == S_LEASED)
            q->st.stolen++;
        for (uint32_t k = 0; k < n; k++) {
            if (c[k].state == S_FREE)
                c[k].state = S_LEASED; /* uid 0: the coordinator's */
            c[k].local = 1;
        }
        pthread_mutex_unlock(&q->mu);

        size_t count;
        rc = s_compute(q, i, n, threads, buf, &count);

        pthread_mutex_lock(&q->mu);
        size_t off = 0;
        for (uint32_t k = 0; k < n; k++) {
            size_t first;
            int map;
            uint32_t len = s_span(q, i + k, &first, &map);
            c[k].local = 0;
            if (rc == PF_OK && c[k].state != S_DONE) {
                memcpy(q->out[map] + first, buf + off, (size_t)len * sizeof *buf);
                c[k].state = S_DONE;
                c[k].uid = c[k].done_uid = 0;
                c[k].check = S_CHK_NONE;
                q->ndone++;
                q->st.local++;
            } else if (rc != PF_OK && c[k].state == S_LEASED && c[k].uid == 0) {
                c[k].state = S_FREE;
            }
            off += len;
        }
        if (rc != PF_OK)
            q->closed = 1;
        pthread_mutex_unlock(&q->mu);
        if (rc != PF_OK)
            break;
    }
    free(buf);
    return rc;
}

uint32_t pf_irq_lease(pf_irq_t *q, uint32_t uid, uint32_t count, double now, uint32_t *first)
{
    pthread_mutex_lock(&q->mu);
    uint32_t n = 0, i = 0;
    while (i < q->nc && q->c[i].state != S_FREE)
        i++;
    if (q->closed || s_barred(q, uid))
        i = q->nc;
    *first = i;
    for (; i < q->nc && n < count && q->c[i].state == S_FREE; i++, n++) {
        q->c[i].state = S_LEASED;
        q->c[i].uid = uid;
        q->c[i].leased_at = now;
    }
    pthread_mutex_unlock(&q->mu);
    return n;
}

uint32_t pf_irq_held(pf_irq_t *q, uint32_t uid)
{
    pthread_mutex_lock(&q->mu);
    uint32_t n = 0;
    for (uint32_t i = 0; i < q->nc; i++)
        n += q->c[i].state == S_LEASED && q->c[i].uid == uid;
    pthread_mutex_unlock(&q->mu);
    return n;
}

static void s_unlease(s_chunk *c)
{
    c->uid = 0;
    if (!c->local)
        c->state = S_FREE;
}

uint32_t pf_irq_release(pf_irq_t *q, uint32_t uid)
{
    pthread_mutex_lock(&q->mu);
    uint32_t n = 0;
    for (uint32_t i = 0; i < q->nc; i++)
        if (q->c[i].state == S_LEASED && q->c[i].uid == uid) {
            s_unlease(&q->c[i]);
            n++;
        }
    pthread_mutex_unlock(&q->mu);
    return n;
}

uint32_t pf_irq_expire(pf_irq_t *q, double now, double timeout_s)
{
    pthread_mutex_lock(&q->mu);
    uint32_t n = 0;
    for (uint32_t i = 0; i < q->nc; i++) {
        s_chunk *c = &q->c[i];
        if (c->state == S_LEASED && c->uid && now - c->leased_at > timeout_s) {
            s_unlease(c);
            n++;
        }
    }
    q->st.expired += n;
    pthread_mutex_unlock(&q->mu);
    return n;
}

/* Whether chunk i's records (from the wire) can be what the precompute
 * makes: each at its global photon's position and normal, its support
 * radius finite and within the search radius (the irradiance is finite and
 * >= 0: the decoder's check). 0 or -1 with why. */
static int s_validate(const pf_irq_t *q, uint32_t i, const pf_msg_photons_t *p, uint32_t want, size_t first,
                      char *why, size_t why_len)
{
    if (p->n != want) {
        snprintf(why, why_len, "IRR_POINTS: chunk %" PRIu32 " has %" PRIu32 " points, not %" PRIu32, i, p->n, want);
        return -1;
    }
    const pf_photon_t *g = pf_kdtree_photons(q->global);
    size_t stride = (size_t)q->plan.main.stride;
    for (uint32_t k = 0; k < p->n; k++) {
        pf_msg_photon_t m;
        pf_msg_photon_get(p, k, &m);
        const pf_photon_t *at = &g[(first + k) * stride];
        const pf_photon_t support = { .dir = m.dir };
        float r = pf_irradiance_radius(&support);
        if (memcmp(m.pos, at->pos, sizeof m.pos) != 0 || m.normal != at->normal || !(r <= q->max_r)) {
            snprintf(why, why_len, "IRR_POINTS: chunk %" PRIu32 " point %" PRIu32 " is not at its photon, or its "
                     "support radius %g is out of range", i, k, (double)r);
            return -1;
        }
    }
    return 0;
}

/* Whether worker uid's result for chunk i is drawn for a check: its first
 * one always, the rest about one in one_in. */
static int s_draw_check(pf_irq_t *q, uint32_t i, uint32_t uid)
{
    for (uint32_t k = 0; k < q->nseen; k++)
        if (q->seen[k] == uid)
            return q->one_in && pf_hash_u64(pf_hash_u64(pf_hash_u64(PF_HASH_INIT, q->secret), i), uid) % q->one_in == 0;
    if (q->nseen < S_MAX_SEEN)
        q->seen[q->nseen++] = uid;
    return 1;
}

int pf_irq_on_points(pf_irq_t *q, uint32_t uid, const pf_msg_photons_t *p, char *why, size_t why_len)
{
    pthread_mutex_lock(&q->mu);
    int rc;
    uint32_t i = p->batch;
    s_chunk *c = i < q->nc ? &q->c[i] : NULL;
    size_t first = 0;
    int map = 0;
    uint32_t want = c ? s_span(q, i, &first, &map) : 0;
    if (!c) {
        snprintf(why, why_len, "IRR_POINTS: chunk %" PRIu32 " is not in this pass (%" PRIu32 " chunks)", i, q->nc);
        rc = PF_IRQ_BAD;
    } else if (q->closed || c->state != S_LEASED || c->uid != uid) {
        q->st.stale++;
        rc = PF_IRQ_STALE;
    } else if (s_validate(q, i, p, want, first, why, why_len) != 0) {
        s_unlease(c);
        rc = PF_IRQ_BAD;
    } else {
        pf_photon_t *dst = q->out[map] + first;
        for (uint32_t k = 0; k < p->n; k++) {
            pf_msg_photon_t m;
            pf_msg_photon_get(p, k, &m);
            memcpy(dst[k].pos, m.pos, sizeof dst[k].pos);
            memcpy(dst[k].power, m.power, sizeof dst[k].power);
            dst[k].dir = m.dir;
            dst[k].normal = m.normal;
        }
        c->state = S_DONE;
        c->done_uid = uid;
        c->uid = 0;
        c->check = s_draw_check(q, i, uid) ? S_CHK_WANT : S_CHK_NONE;
        q->ndone++;
        q->st.remote++;
        rc = PF_IRQ_DONE;
    }
    pthread_mutex_unlock(&q->mu);
    return rc;
}

int pf_irq_take_liar(pf_irq_t *q, uint32_t *uid, char *why, size_t why_len)
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

void pf_irq_stats(pf_irq_t *q, pf_irq_stats_t *out)
{
    pthread_mutex_lock(&q->mu);
    *out = q->st;
    pthread_mutex_unlock(&q->mu);
}
