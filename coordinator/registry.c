/* registry.c: the coordinator's worker table; see registry.h.
 *
 * Owns the slot array and the blocklist. Called by the farm's event loop
 * only (one thread); nothing here blocks or touches the network. */
#include "coordinator/registry.h"

#include <stdlib.h>
#include <string.h>

#include "base/hash.h"
#include "base/status.h"

/* Seeds that keep an identity, a name and a key with the same bytes apart. */
#define S_SEED_ID 0x6964656e74697479ull
#define S_SEED_NAME 0x6e616d656e616d65ull
#define S_SEED_KEY 0x6b65796b65796b65ull

int pf_registry_init(pf_registry_t *r, int cap, double hello_rate)
{
    memset(r, 0, sizeof *r);
    r->cap = cap > 0 ? cap : 1;
    r->w = calloc((size_t)r->cap, sizeof *r->w);
    r->block_cap = 2 * PF_REGISTRY_BLOCK_MAX * 3; /* three hashes per evicted worker, load at most 1/2 */
    r->block = calloc(r->block_cap, sizeof *r->block);
    if (!r->w || !r->block) {
        pf_registry_free(r);
        return PF_ENOMEM;
    }
    r->hello_rate = hello_rate;
    r->tokens = hello_rate > 1.0 ? hello_rate : 1.0;
    r->tokens_at = -1.0;
    return PF_OK;
}

void pf_registry_free(pf_registry_t *r)
{
    free(r->w);
    free(r->block);
    r->w = NULL;
    r->block = NULL;
}

int pf_registry_find(const pf_registry_t *r, const uint8_t *id, size_t idlen)
{
    for (int i = 0; i < r->nw; i++)
        if (r->w[i].state != PF_W_FREE && r->w[i].idlen == idlen && memcmp(r->w[i].id, id, idlen) == 0)
            return i;
    return -1;
}

int pf_registry_hello_admit(pf_registry_t *r, double now)
{
    if (r->hello_rate <= 0)
        return 1;
    double burst = r->hello_rate > 1.0 ? r->hello_rate : 1.0;
    if (r->tokens_at >= 0)
        r->tokens += (now - r->tokens_at) * r->hello_rate;
    if (r->tokens > burst)
        r->tokens = burst;
    r->tokens_at = now;
    if (r->tokens < 1.0) {
        r->hellos_dropped++;
        return 0;
    }
    r->tokens -= 1.0;
    return 1;
}

int pf_registry_add(pf_registry_t *r, const uint8_t *id, size_t idlen, int *reused)
{
    int wi = -1;
    for (int i = 0; i < r->nw; i++) {
        const pf_worker_t *w = &r->w[i];
        if ((w->state == PF_W_FREE || w->state == PF_W_DEAD) && w->held == 0 &&
            (wi < 0 || w->gone_at < r->w[wi].gone_at))
            wi = i;
    }
    *reused = wi >= 0 && r->w[wi].uid != 0;
    if (wi < 0) {
        if (r->nw == r->cap)
            return -1;
        wi = r->nw++;
    }
    if (*reused)
        r->reused++;
    pf_worker_t *w = &r->w[wi];
    memset(w, 0, sizeof *w);
    w->uid = ++r->next_uid;
    memcpy(w->id, id, idlen < sizeof w->id ? idlen : sizeof w->id);
    w->idlen = idlen < sizeof w->id ? idlen : sizeof w->id;
    return wi;
}

void pf_registry_gone(pf_registry_t *r, int wi, int state, double now)
{
    r->w[wi].state = state;
    r->w[wi].gone_at = now;
}

/* ---- the blocklist: an open-addressing set of 64-bit hashes ---- */

static uint64_t s_nonzero(uint64_t h)
{
    return h ? h : 1;
}

static int s_has(const pf_registry_t *r, uint64_t h)
{
    for (size_t i = h % r->block_cap;; i = (i + 1) % r->block_cap) {
        if (r->block[i] == h)
            return 1;
        if (r->block[i] == 0)
            return 0;
    }
}

static void s_put(pf_registry_t *r, uint64_t h)
{
    if (s_has(r, h))
        return;
    if (r->nblock >= r->block_cap / 2) {
        r->block_full++;
        return;
    }
    size_t i = h % r->block_cap;
    while (r->block[i])
        i = (i + 1) % r->block_cap;
    r->block[i] = h;
    r->nblock++;
}

void pf_registry_block(pf_registry_t *r, const pf_worker_t *w)
{
    s_put(r, s_nonzero(pf_hash_bytes(S_SEED_ID, w->id, w->idlen)));
    if (w->name[0])
        s_put(r, s_nonzero(pf_hash_bytes(S_SEED_NAME, w->name, strlen(w->name))));
    if (w->key[0])
        s_put(r, s_nonzero(pf_hash_bytes(S_SEED_KEY, w->key, strlen(w->key))));
}

int pf_registry_id_blocked(const pf_registry_t *r, const uint8_t *id, size_t idlen)
{
    return r->nblock && s_has(r, s_nonzero(pf_hash_bytes(S_SEED_ID, id, idlen)));
}

int pf_registry_peer_blocked(const pf_registry_t *r, const char *name, const char *key)
{
    if (!r->nblock)
        return 0;
    if (name[0] && s_has(r, s_nonzero(pf_hash_bytes(S_SEED_NAME, name, strlen(name)))))
        return 1;
    return key && key[0] && s_has(r, s_nonzero(pf_hash_bytes(S_SEED_KEY, key, strlen(key))));
}
