/* leases.c: tiles, the queue and leases of one farm job; see leases.h.
 *
 * Owns the tile table and the queue (a ring of tile indices; a tile taken
 * from the middle shifts the ones before it). Called by the farm's event
 * loop only (one thread). */
#include "coordinator/leases.h"

#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "base/status.h"

/* Appends tile (x0, y0, w, h) clipped to the image, queued last. */
static void s_add(pf_leases_t *L, int width, int height, int x0, int y0, int side_w, int side_h)
{
    pf_tile_t *t = &L->t[L->nt];
    t->x0 = (uint32_t)x0;
    t->y0 = (uint32_t)y0;
    t->w = (uint32_t)(x0 + side_w <= width ? side_w : width - x0);
    t->h = (uint32_t)(y0 + side_h <= height ? side_h : height - y0);
    t->owner = -1;
    L->queue[L->nt] = L->nt;
    L->nt++;
}

int pf_leases_init(pf_leases_t *L, int width, int height, int ts)
{
    memset(L, 0, sizeof *L);
    int tx = (width + ts - 1) / ts, ty = (height + ts - 1) / ts, grid = tx * ty;
    /* The tail: the last quarter of the grid (in queue order) in quarters,
     * so the job's last round is of small tiles and no worker is left
     * with a whole tile while the others idle (a tile's pixels come out the
     * same bits whatever the tile). Not below 8 pixels a side. */
    int tail = ts >= 16 ? grid / 4 : 0, half = (ts + 1) / 2;
    L->t = calloc((size_t)(grid + 3 * tail), sizeof *L->t);
    L->queue = calloc((size_t)(grid + 3 * tail), sizeof *L->queue);
    if (!L->t || !L->queue) {
        pf_leases_free(L);
        return PF_ENOMEM;
    }
    for (int i = 0; i < grid; i++) {
        int x0 = (i % tx) * ts, y0 = (i / tx) * ts;
        if (i < grid - tail) {
            s_add(L, width, height, x0, y0, ts, ts);
            continue;
        }
        for (int q = 0; q < 4; q++) { /* the quadrants that exist: an edge tile may have fewer */
            int qx = x0 + (q & 1) * half, qy = y0 + (q >> 1) * half;
            if (qx < width && qy < height)
                s_add(L, width, height, qx, qy, q & 1 ? ts - half : half, q >> 1 ? ts - half : half);
        }
    }
    L->qlen = L->nt;
    return PF_OK;
}

void pf_leases_free(pf_leases_t *L)
{
    free(L->t);
    free(L->queue);
    L->t = NULL;
    L->queue = NULL;
}

/* ---- the queue ---- */

static int s_at(const pf_leases_t *L, int pos)
{
    return L->queue[(L->qhead + pos) % L->nt];
}

/* Takes the tile at queue position pos out of the queue. */
static int s_take(pf_leases_t *L, int pos)
{
    int ti = s_at(L, pos);
    for (int j = pos; j > 0; j--)
        L->queue[(L->qhead + j) % L->nt] = L->queue[(L->qhead + j - 1) % L->nt];
    L->qhead = (L->qhead + 1) % L->nt;
    L->qlen--;
    return ti;
}

static void s_push_front(pf_leases_t *L, int ti)
{
    L->qhead = (L->qhead + L->nt - 1) % L->nt;
    L->queue[L->qhead] = ti;
    L->qlen++;
}

/* The holder of t's current lease holds one tile less. */
static void s_drop_owner(pf_registry_t *r, pf_tile_t *t)
{
    if (t->owner >= 0 && t->owner < r->nw && r->w[t->owner].uid == t->owner_uid && r->w[t->owner].held > 0)
        r->w[t->owner].held--;
    t->owner = -1;
    t->owner_uid = 0;
}

/* ---- leasing ---- */

int pf_leases_was_lessee(const pf_tile_t *t, uint32_t uid)
{
    for (int k = 0; k < t->nlessees; k++)
        if (t->lessees[k].uid == uid)
            return 1;
    return 0;
}

/* Is there a ready worker other than wi, not stuck, that never held t? */
static int s_other_taker(const pf_registry_t *r, const pf_tile_t *t, int wi)
{
    for (int i = 0; i < r->nw; i++)
        if (i != wi && r->w[i].state == PF_W_READY && !r->w[i].stuck && !pf_leases_was_lessee(t, r->w[i].uid))
            return 1;
    return 0;
}

int pf_leases_pick(const pf_leases_t *L, const pf_registry_t *r, int wi)
{
    uint32_t uid = r->w[wi].uid;
    for (int k = 0; k < L->qlen; k++)
        if (L->t[s_at(L, k)].not_uid != uid && !pf_leases_was_lessee(&L->t[s_at(L, k)], uid))
            return k;
    for (int k = 0; k < L->qlen; k++)
        if (L->t[s_at(L, k)].not_uid != uid && !s_other_taker(r, &L->t[s_at(L, k)], wi))
            return k;
    return -1;
}

int pf_leases_grant(pf_leases_t *L, pf_registry_t *r, int pos, int wi, double now)
{
    int ti = s_take(L, pos);
    pf_tile_t *t = &L->t[ti];
    pf_worker_t *w = &r->w[wi];
    t->state = PF_T_LEASED;
    t->owner = wi;
    t->owner_uid = w->uid;
    t->leased_at = now;
    if (t->nlessees == PF_LEASES_LESSEES) {
        memmove(t->lessees, t->lessees + 1, (PF_LEASES_LESSEES - 1) * sizeof *t->lessees);
        t->nlessees--;
    }
    t->lessees[t->nlessees++] = (pf_lessee_t){ w->uid, t->attempt, now };
    if (w->held++ == 0)
        w->result_at = now; /* the stall clock runs while it holds tiles */
    return ti;
}

void pf_leases_ungrant(pf_leases_t *L, pf_registry_t *r, int ti)
{
    pf_tile_t *t = &L->t[ti];
    if (t->state != PF_T_LEASED)
        return;
    s_drop_owner(r, t);
    t->nlessees--; /* the lease just granted is the last one */
    t->state = PF_T_QUEUED;
    s_push_front(L, ti);
}

void pf_leases_revoke(pf_leases_t *L, pf_registry_t *r, int ti)
{
    pf_tile_t *t = &L->t[ti];
    if (t->state != PF_T_LEASED)
        return;
    s_drop_owner(r, t);
    t->state = PF_T_QUEUED;
    t->attempt++;
    s_push_front(L, ti);
    L->reissued++;
}

int pf_leases_release(pf_leases_t *L, pf_registry_t *r, int wi)
{
    int n = 0;
    uint32_t uid = r->w[wi].uid;
    for (int i = 0; i < L->nt; i++)
        if (L->t[i].state == PF_T_LEASED && L->t[i].owner == wi && L->t[i].owner_uid == uid) {
            pf_leases_revoke(L, r, i);
            n++;
        }
    r->w[wi].held = 0;
    return n;
}

/* ---- results ---- */

int pf_leases_check(pf_leases_t *L, const pf_registry_t *r, int wi, const pf_msg_result_t *res, char *why,
                    size_t why_len)
{
    if (res->tile >= (uint32_t)L->nt) {
        snprintf(why, why_len, "RESULT for tile %u, which does not exist (%d tiles)", res->tile, L->nt);
        return PF_RESULT_REFUSED;
    }
    const pf_tile_t *t = &L->t[res->tile];
    if (res->x0 != t->x0 || res->y0 != t->y0 || res->w != t->w || res->h != t->h) {
        snprintf(why, why_len, "RESULT for tile %u with the rectangle %ux%u at (%u, %u), not its own", res->tile,
                 res->w, res->h, res->x0, res->y0);
        return PF_RESULT_REFUSED;
    }
    uint32_t uid = r->w[wi].uid;
    for (int k = 0; k < t->nlessees; k++)
        if (t->lessees[k].uid == uid && t->lessees[k].attempt == res->attempt) {
            if (t->state != PF_T_DONE && uid != t->not_uid)
                return PF_RESULT_NEW;
            L->duplicates++;
            return PF_RESULT_DUPLICATE;
        }
    int n = snprintf(why, why_len, "RESULT for tile %u attempt %u, which was never leased to it (id %u); lessees:",
                     res->tile, res->attempt, uid);
    for (int k = 0; k < t->nlessees && n > 0 && (size_t)n < why_len; k++)
        n += snprintf(why + n, why_len - (size_t)n, " id %u attempt %u", t->lessees[k].uid, t->lessees[k].attempt);
    if (t->nlessees == 0 && n > 0 && (size_t)n < why_len)
        snprintf(why + n, why_len - (size_t)n, " none");
    return PF_RESULT_REFUSED;
}

void pf_leases_finish(pf_leases_t *L, pf_registry_t *r, int ti)
{
    pf_tile_t *t = &L->t[ti];
    if (t->state == PF_T_DONE)
        return;
    if (t->state == PF_T_LEASED) {
        s_drop_owner(r, t);
    } else { /* re-issued and waiting in the queue: this result makes it done, take it out */
        for (int k = 0; k < L->qlen; k++)
            if (s_at(L, k) == ti) {
                s_take(L, k);
                break;
            }
    }
    t->state = PF_T_DONE;
    L->ndone++;
}

int pf_leases_reopen(pf_leases_t *L, int ti, uint32_t not_uid)
{
    pf_tile_t *t = &L->t[ti];
    if (t->state != PF_T_DONE)
        return -1;
    t->state = PF_T_QUEUED;
    t->attempt++;
    t->not_uid = not_uid;
    L->ndone--;
    s_push_front(L, ti);
    return 0;
}

void pf_leases_complete(pf_leases_t *L, pf_registry_t *r, int wi, const pf_msg_result_t *res, double now)
{
    const pf_tile_t *t = &L->t[res->tile];
    if (t->state == PF_T_DONE)
        return;
    pf_leases_finish(L, r, (int)res->tile);
    uint32_t uid = r->w[wi].uid;
    for (int k = 0; k < t->nlessees; k++)
        if (t->lessees[k].uid == uid && t->lessees[k].attempt == res->attempt) {
            L->times[L->itime] = now - t->lessees[k].at;
            L->itime = (L->itime + 1) % PF_LEASES_TIMES;
            if (L->ntimes < PF_LEASES_TIMES)
                L->ntimes++;
            break;
        }
}

/* ---- the end of the job ---- */

int pf_leases_oldest(const pf_leases_t *L, double now, double min_age)
{
    int best = -1;
    for (int i = 0; i < L->nt; i++) {
        const pf_tile_t *t = &L->t[i];
        if (t->state != PF_T_LEASED || now - t->leased_at <= min_age)
            continue;
        if (best < 0 || t->leased_at < L->t[best].leased_at)
            best = i;
    }
    return best;
}

double pf_leases_typical_s(const pf_leases_t *L)
{
    double v[PF_LEASES_TIMES];
    int n = L->ntimes;
    if (n == 0)
        return 0.0;
    memcpy(v, L->times, (size_t)n * sizeof *v);
    for (int i = 1; i < n; i++) /* insertion sort: at most PF_LEASES_TIMES values */
        for (int j = i; j > 0 && v[j - 1] > v[j]; j--) {
            double x = v[j];
            v[j] = v[j - 1];
            v[j - 1] = x;
        }
    return v[n / 2];
}
