/* verify.c: the farm's spot checks (farm_impl.h; --verify). The farm's
 * images are bit-identical for any worker count, so a tile rendered twice
 * must come back the same, bit for bit. A tile picked for a check (each
 * worker's first result, once another worker is there to check it, and a fraction
 * of the tiles chosen by a hash of the job id and the tile) is reopened and
 * leased to a worker other than the one whose result was kept; the two
 * results are compared. On a mismatch the coordinator renders the tile
 * itself (its photon thread's frame, pf_render_tile) to decide who lied;
 * the liar is evicted and every tile it delivered is rendered again
 * elsewhere. A check no other worker can take (the only one left is the
 * tile's own), or that none took within a few tile times, is made here.
 * The decider is always this process (a third worker is not asked).
 *
 * Owns the per-tile tables (vstate, kept) and the buffer for a tile
 * rendered here. Threads: the event loop's only; a tile rendered here
 * blocks the loop for that time (the photon thread has ended by then). */
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "base/hash.h"
#include "base/log.h"
#include "coordinator/farm.h"
#include "coordinator/farm_impl.h"
#include "render/render.h"

enum { S_V_NONE = 0, S_V_PENDING, S_V_CHECKED };

/* A check waiting in the queue this long (typical tile times, at least
 * S_WAIT_MIN_S seconds) with no worker taking it is made here. */
#define S_WAIT_TIMES 4.0
#define S_WAIT_MIN_S 2.0

int pf_fm_verify_init(pf_fm_t *f)
{
    f->vstate = calloc((size_t)f->L.nt, 1);
    f->kept = calloc((size_t)f->L.nt, sizeof *f->kept);
    f->vsince = calloc((size_t)f->L.nt, sizeof *f->vsince);
    f->lpix = malloc((size_t)f->ts * (size_t)f->ts * 3 * sizeof *f->lpix);
    return f->vstate && f->kept && f->vsince && f->lpix ? PF_OK : PF_ENOMEM;
}

void pf_fm_verify_free(pf_fm_t *f)
{
    free(f->vstate);
    free(f->kept);
    free(f->vsince);
    free(f->lpix);
    f->vsince = NULL;
    f->vstate = NULL;
    f->kept = NULL;
    f->lpix = NULL;
}

/* 1 when px (the tile's w*h*3 floats) equals the tile in the image, bit
 * for bit. */
static int s_same_as_image(const pf_fm_t *f, const pf_tile_t *t, const float *px)
{
    for (uint32_t y = 0; y < t->h; y++)
        if (memcmp(&f->img->rgb[3 * ((size_t)(t->y0 + y) * (size_t)f->img->width + t->x0)], &px[3 * (size_t)y * t->w],
                   (size_t)t->w * 3 * sizeof(float)) != 0)
            return 0;
    return 1;
}

static void s_store(pf_fm_t *f, const pf_tile_t *t, const float *px)
{
    for (uint32_t y = 0; y < t->h; y++)
        memcpy(&f->img->rgb[3 * ((size_t)(t->y0 + y) * (size_t)f->img->width + t->x0)], &px[3 * (size_t)y * t->w],
               (size_t)t->w * 3 * sizeof(float));
}

/* Renders tile ti here, into f->lpix. */
static void s_render_here(pf_fm_t *f, int ti)
{
    const pf_tile_t *t = &f->L.t[ti];
    if (!f->frame_readied) {
        if (!f->ph.budget) /* a time limit readied it in the photon thread */
            pf_frame_ready(&f->ph.frame);
        f->frame_readied = 1;
    }
    pf_render_ctx_t ctx;
    pf_render_ctx_init(&ctx, &f->ph.frame, &f->cur);
    ctx.terms = f->ph.terms;
    pf_spp_map_t map = { 0, 0, f->img->width, f->img->height, f->counts };
    if (f->counts)
        ctx.spp_map = &map;
    double t0 = pf_now();
    pf_render_tile(&ctx, (int)t->x0, (int)t->y0, (int)t->w, (int)t->h, f->lpix);
    f->sum->verify_local++;
    pf_info("verify: tile %d rendered here in %.2f s", ti, pf_now() - t0);
}

/* The slot of the registration with this uid (any state but FREE), -1. */
static int s_slot_of(const pf_fm_t *f, uint32_t uid)
{
    for (int i = 0; i < f->reg.nw; i++)
        if (f->reg.w[i].uid == uid && f->reg.w[i].state != PF_W_FREE)
            return i;
    return -1;
}

/* The worker with this uid returned wrong pixels for tile ti: evicted (or,
 * already dead, blocked), and every tile whose kept result is its goes back
 * to the queue, for anyone but it. */
static void s_liar(pf_fm_t *f, uint32_t uid, int ti)
{
    pf_farm_summary_t *sum = f->sum;
    int wi = s_slot_of(f, uid);
    char why[96];
    snprintf(why, sizeof why, "returned wrong pixels for tile %d (a check on another worker)", ti);
    const char *name = wi >= 0 ? f->reg.w[wi].name : "?";
    size_t nl = strlen(sum->liar_names);
    if (nl + strlen(name) + 3 < sizeof sum->liar_names)
        snprintf(sum->liar_names + nl, sizeof sum->liar_names - nl, "%s%s", nl ? ", " : "", name);
    sum->liars++;
    int n = 0;
    for (int i = 0; i < f->L.nt; i++) {
        if (f->kept[i] != uid)
            continue;
        /* A tile being checked: the check becomes its result. Else it is
         * done, and goes back to the queue. Either way it is rendered again. */
        f->vstate[i] = S_V_NONE;
        pf_leases_reopen(&f->L, i, uid);
        f->kept[i] = 0;
        n++;
    }
    sum->rerendered += (uint64_t)n;
    sum->results -= (uint64_t)n < sum->results ? (uint64_t)n : sum->results;
    if (wi >= 0) {
        pf_worker_t *w = &f->reg.w[wi];
        w->tiles -= (uint64_t)n < w->tiles ? (uint64_t)n : w->tiles;
        if (w->state == PF_W_DEAD) {
            pf_warn("evicted worker %s (id %u, dead): %s", w->name, w->uid, why);
            pf_registry_block(&f->reg, w);
            pf_registry_gone(&f->reg, wi, PF_W_FREE, pf_now());
            sum->evicted++;
        } else if (f->nevict < (int)(sizeof f->evict_uid / sizeof f->evict_uid[0])) {
            /* Evicted by farm_peers.c once this check is done (pf_fm_evict_pending). */
            f->evict_uid[f->nevict] = uid;
            snprintf(f->evict_why[f->nevict], sizeof f->evict_why[0], "%s", why);
            f->nevict++;
        }
    }
    pf_warn("verify: %d tile%s of the liar's rendered again elsewhere", n, n == 1 ? "" : "s");
}

/* The two results for tile ti differ: the one kept (in the image, from
 * uid a) and px (from uid b, 0 when none: the check is made here). A
 * render here decides. */
static void s_decide(pf_fm_t *f, int ti, uint32_t a, uint32_t b, const float *px)
{
    const pf_tile_t *t = &f->L.t[ti];
    size_t n = (size_t)t->w * t->h * 3;
    f->sum->mismatches++;
    int ai = s_slot_of(f, a), bi = b ? s_slot_of(f, b) : -1;
    pf_warn("verify: tile %d: %s and %s returned different pixels; rendering it here to decide", ti,
            ai >= 0 ? f->reg.w[ai].name : "?", b ? (bi >= 0 ? f->reg.w[bi].name : "?") : "this coordinator");
    if (b)
        s_render_here(f, ti);
    int a_ok = s_same_as_image(f, t, f->lpix);
    int b_ok = b && memcmp(px, f->lpix, n * sizeof(float)) == 0;
    if (b && !a_ok && !b_ok) {
        /* Neither agrees with this process: more likely builds that render
         * differently than two liars. The tile keeps this render; nobody is
         * evicted on this evidence. */
        pf_warn("verify: tile %d: neither result matches this coordinator's render (different builds?); "
                "keeping this one, evicting nobody",
                ti);
        s_store(f, t, f->lpix);
        f->kept[ti] = 0;
        return;
    }
    if (!a_ok) {
        s_store(f, t, f->lpix);
        f->kept[ti] = 0;
        s_liar(f, a, ti);
    }
    if (b && !b_ok)
        s_liar(f, b, ti);
}

int pf_fm_verify_result(pf_fm_t *f, int wi, const pf_msg_result_t *r)
{
    int ti = (int)r->tile;
    if (!f->vstate || f->vstate[ti] != S_V_PENDING)
        return 0;
    pf_leases_complete(&f->L, &f->reg, wi, r, pf_now());
    f->vstate[ti] = S_V_CHECKED;
    f->sum->verified++;
    uint32_t a = f->kept[ti], b = f->reg.w[wi].uid;
    if (s_same_as_image(f, &f->L.t[ti], f->pix))
        pf_debug("verify: tile %d: %s agrees", ti, f->reg.w[wi].name);
    else
        s_decide(f, ti, a, b, f->pix);
    return 1;
}

/* A fraction of the tiles, picked by a hash of the job id and the tile. */
static int s_hash_pick(const pf_fm_t *f, int ti)
{
    uint64_t h = pf_hash_u64(pf_hash_u64(PF_HASH_INIT, f->job), (uint64_t)ti);
    return (double)(h >> 11) * (1.0 / 9007199254740992.0) < f->o->verify;
}

void pf_fm_verify_kept(pf_fm_t *f, int wi, int ti)
{
    pf_worker_t *w = &f->reg.w[wi];
    if (!f->vstate)
        return;
    f->kept[ti] = w->uid;
    if (f->o->verify <= 0 || f->vstate[ti] != S_V_NONE)
        return;
    int others = 0; /* other live workers: ready, or on their way */
    for (int i = 0; i < f->reg.nw; i++) {
        int st = f->reg.w[i].state;
        others += i != wi && (st == PF_W_READY || st == PF_W_JOB_SENT || st == PF_W_HELLO) && !f->reg.w[i].stuck;
    }
    if (others == 0 || (w->checked && !s_hash_pick(f, ti)))
        return;
    w->checked = 1;
    if (pf_leases_reopen(&f->L, ti, w->uid) == 0) {
        f->vstate[ti] = S_V_PENDING;
        f->vsince[ti] = pf_now();
        pf_debug("verify: tile %d of %s goes to another worker for a check", ti, w->name);
    }
}

void pf_fm_verify_tick(pf_fm_t *f)
{
    if (!f->vstate || !f->job_ready)
        return;
    double now = pf_now(), typical = pf_leases_typical_s(&f->L);
    double patience = S_WAIT_TIMES * typical > S_WAIT_MIN_S ? S_WAIT_TIMES * typical : S_WAIT_MIN_S;
    for (int ti = 0; ti < f->L.nt; ti++) {
        const pf_tile_t *t = &f->L.t[ti];
        if (f->vstate[ti] != S_V_PENDING || t->state != PF_T_QUEUED)
            continue;
        int taker = 0; /* another live worker: ready, or on its way */
        for (int i = 0; i < f->reg.nw && !taker; i++) {
            int st = f->reg.w[i].state;
            taker = (st == PF_W_READY || st == PF_W_JOB_SENT || st == PF_W_HELLO) && !f->reg.w[i].stuck &&
                    f->reg.w[i].uid != t->not_uid;
        }
        if (taker && now - f->vsince[ti] < patience)
            continue;
        /* Nobody else to ask, or nobody took it in time: the check is made here. */
        s_render_here(f, ti);
        pf_leases_finish(&f->L, &f->reg, ti);
        f->vstate[ti] = S_V_CHECKED;
        f->sum->verified++;
        if (!s_same_as_image(f, t, f->lpix))
            s_decide(f, ti, f->kept[ti], 0, NULL);
    }
}
