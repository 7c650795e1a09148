/* fanout.c: the fan-out tree of the maps blob (see fanout.h). The farm's
 * glue (the BLOB_PLAN sent before each JOB, the children of a worker that
 * is gone sent back to the coordinator) is in farm_peers.c.
 *
 * The tree is chosen greedily as workers get their JOB: the shallowest
 * serving worker with room, the earliest slot on a tie. With degree 2 and
 * workers that all serve, the coordinator has one child and the depth grows
 * as log2 of the workers; since every worker relays a chunk as soon as it
 * holds it, depth costs one chunk's time a level, not one blob's. */
#include "coordinator/fanout.h"

#include <inttypes.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "base/status.h"
#include "proto/hashtree.h"

typedef struct s_node {
    uint32_t uid;
    char source[PF_PROTO_MAX_SOURCE]; /* its peer socket, "" when it serves none */
    int in_tree, parent;              /* parent: a slot, or -2 (the coordinator) */
    int kids, depth;
} s_node;

struct pf_fanout {
    s_node *n;
    int nslots, degree;
    uint64_t hash, size, root;
    uint64_t *leaves;
    uint32_t nleaves;
};

pf_fanout_t *pf_fanout_new(int nslots, int degree)
{
    pf_fanout_t *fo = calloc(1, sizeof *fo);
    if (!fo)
        return NULL;
    fo->n = calloc((size_t)(nslots > 0 ? nslots : 1), sizeof *fo->n);
    if (!fo->n) {
        free(fo);
        return NULL;
    }
    fo->nslots = nslots;
    fo->degree = degree > 0 ? degree : 0;
    return fo;
}

void pf_fanout_free(pf_fanout_t **fo_p)
{
    pf_fanout_t *fo = *fo_p;
    if (!fo)
        return;
    free(fo->leaves);
    free(fo->n);
    free(fo);
    *fo_p = NULL;
}

void pf_fanout_hello(pf_fanout_t *fo, int slot, uint32_t uid, const char *addr, uint16_t port)
{
    if (!fo || slot < 0 || slot >= fo->nslots)
        return;
    s_node *n = &fo->n[slot];
    memset(n, 0, sizeof *n);
    n->uid = uid;
    n->parent = -2;
    if (port == 0 || fo->degree == 0)
        return;
    /* Only an address made of address characters is put into an endpoint
     * (it comes from libzmq, but the endpoint goes to other workers). */
    if (!addr || !addr[0] || strlen(addr) > 64 || strspn(addr, "0123456789abcdefABCDEF.:") != strlen(addr))
        addr = "127.0.0.1";
    if (strchr(addr, ':'))
        snprintf(n->source, sizeof n->source, "tcp://[%s]:%u", addr, (unsigned)port);
    else
        snprintf(n->source, sizeof n->source, "tcp://%s:%u", addr, (unsigned)port);
}

int pf_fanout_set_blob(pf_fanout_t *fo, const pf_framed_blob_t *fb)
{
    for (int i = 0; i < fo->nslots; i++) {
        fo->n[i].in_tree = fo->n[i].kids = fo->n[i].depth = 0;
        fo->n[i].parent = -2;
    }
    free(fo->leaves);
    fo->leaves = NULL;
    fo->nleaves = 0;
    fo->hash = fo->size = 0;
    if (!fb->data || fb->nchunks > PF_PROTO_MAX_PLAN_CHUNKS)
        return PF_OK;
    fo->leaves = malloc((size_t)fb->nchunks * sizeof *fo->leaves);
    if (!fo->leaves)
        return PF_ENOMEM;
    for (uint32_t k = 0; k < fb->nchunks; k++) {
        uint64_t off = (uint64_t)k * PF_PROTO_CHUNK_SIZE;
        size_t len = (size_t)(fb->size - off < PF_PROTO_CHUNK_SIZE ? fb->size - off : PF_PROTO_CHUNK_SIZE);
        fo->leaves[k] = pf_chunk_hash(fb->hash, k, fb->data + (size_t)k * fb->stride + fb->head, len);
    }
    fo->nleaves = fb->nchunks;
    fo->hash = fb->hash;
    fo->size = fb->size;
    fo->root = pf_chunk_root(fo->hash, fo->size, fo->leaves, fo->nleaves);
    return PF_OK;
}

int pf_fanout_plan_coordinator(const pf_fanout_t *fo, pf_msg_blob_plan_t *plan)
{
    memset(plan, 0, sizeof *plan);
    if (!fo || !fo->leaves)
        return -1;
    plan->hash = fo->hash;
    plan->size = fo->size;
    plan->root = fo->root;
    plan->n = fo->nleaves;
    plan->leaves = fo->leaves;
    return -2;
}

int pf_fanout_plan(pf_fanout_t *fo, int slot, pf_msg_blob_plan_t *plan)
{
    if (pf_fanout_plan_coordinator(fo, plan) == -1 || slot < 0 || slot >= fo->nslots)
        return -1;
    s_node *me = &fo->n[slot];
    if (me->in_tree) { /* the JOB again (its queue was full): the same source */
        if (me->parent >= 0) {
            snprintf(plan->source, sizeof plan->source, "%s", fo->n[me->parent].source);
            plan->source_uid = fo->n[me->parent].uid;
        }
        return me->parent;
    }
    int best = -2;
    for (int i = 0; i < fo->nslots; i++) {
        const s_node *c = &fo->n[i];
        if (i == slot || !c->in_tree || !c->source[0] || c->kids >= fo->degree)
            continue;
        if (best < 0 || c->depth < fo->n[best].depth)
            best = i;
    }
    me->in_tree = 1;
    me->parent = best;
    me->kids = 0;
    me->depth = best >= 0 ? fo->n[best].depth + 1 : 0;
    if (best >= 0) {
        fo->n[best].kids++;
        snprintf(plan->source, sizeof plan->source, "%s", fo->n[best].source);
        plan->source_uid = fo->n[best].uid;
    }
    return best;
}

int pf_fanout_gone(pf_fanout_t *fo, int slot, int *kids, int max)
{
    if (!fo || slot < 0 || slot >= fo->nslots || !fo->n[slot].in_tree)
        return 0;
    s_node *me = &fo->n[slot];
    if (me->parent >= 0)
        fo->n[me->parent].kids--;
    int k = 0;
    for (int i = 0; i < fo->nslots; i++)
        if (fo->n[i].in_tree && fo->n[i].parent == slot) {
            /* Straight to the coordinator (not re-parented onto a sibling:
             * a dead source's children are the ones in a hurry). */
            fo->n[i].parent = -2;
            fo->n[i].depth = 0;
            if (k < max)
                kids[k++] = i;
        }
    me->in_tree = 0;
    me->source[0] = '\0'; /* a dead worker serves no one, even if its slot's node is looked at again */
    return k;
}
