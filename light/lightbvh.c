/* lightbvh.c: the light BVH; see lightbvh.h.
 *
 * As pbrt-v4's BVHLightSampler: one item per leaf; a node's bounds are the
 * union of its children's (boxes, powers, normal cones); the tree is split
 * top-down over 12 buckets of the items' centroids per axis, at the least
 * cost phi * M_omega * surface area * Kr (the power, the solid angle the
 * emission cone sweeps, the box's area, and a penalty for thin splits along
 * a short axis). Sampling walks from the root choosing a child with
 * probability proportional to its importance at (x, n), remapping u on the
 * way down; the pmf of an item is the product of the same ratios along its
 * path, found from the item's leaf through the parent links. Below depth
 * S_DEEP the split is by count, so every path fits S_MAX_DEPTH. */
#include "light/lightbvh.h"

#include <float.h>
#include <math.h>
#include <stdlib.h>
#include <string.h>

#include "base/sampling.h"

#define S_BUCKETS 12
#define S_DEEP 96
#define S_MAX_DEPTH 160
#define S_NONE UINT32_MAX

/* What importance needs of a node's bounds that does not depend on x:
 * computed once at build (the walk evaluates two nodes per level). */
typedef struct s_pre {
    pf_vec3 pc;   /* the box's centre */
    float r2;     /* its bounding sphere's squared radius */
    float clamp;  /* the floor on d^2: a quarter of the diagonal, squared */
    float sin_o;
} s_pre;

typedef struct s_node {
    pf_light_bounds_t b;
    s_pre q;
    uint32_t second; /* interior: the second child (the first is this + 1); leaf: the item's id */
    uint32_t parent; /* S_NONE at the root */
    int leaf;
} s_node;

struct pf_lightbvh {
    s_node *nodes;
    size_t nnodes;
    uint32_t *leaf_of; /* id -> its leaf (S_NONE: none), ids < nids */
    size_t nids;
};

static float s_safe_sqrt(float x) { return sqrtf(x > 0.0f ? x : 0.0f); }
static float s_safe_acos(float x) { return acosf(fminf(1.0f, fmaxf(-1.0f, x))); }

/* cos(max(0, a - b)) and sin(max(0, a - b)) from the sines and cosines. */
static float s_cos_sub_clamped(float sin_a, float cos_a, float sin_b, float cos_b)
{
    return cos_a > cos_b ? 1.0f : cos_a * cos_b + sin_a * sin_b;
}
static float s_sin_sub_clamped(float sin_a, float cos_a, float sin_b, float cos_b)
{
    return cos_a > cos_b ? 0.0f : sin_a * cos_b - cos_a * sin_b;
}

static float s_max(float a, float b) { return a > b ? a : b; }

static s_pre s_precompute(const pf_light_bounds_t *b)
{
    s_pre q;
    q.pc = pf_scale(pf_add(b->lo, b->hi), 0.5f);
    q.r2 = pf_len2(pf_sub(b->hi, q.pc));
    q.clamp = 0.0625f * pf_len2(pf_sub(b->hi, b->lo));
    q.sin_o = s_safe_sqrt(1.0f - b->cos_theta_o * b->cos_theta_o);
    return q;
}

static float s_importance(const pf_light_bounds_t *b, const s_pre *q, pf_vec3 x, pf_vec3 n)
{
    if (!(b->phi > 0.0f))
        return 0.0f;
    pf_vec3 dx = pf_sub(x, q->pc);
    float dc2 = pf_len2(dx);
    /* no closer than a quarter of the diagonal, so a receiver inside a large
     * node does not blow its importance up; a squared length, unlike pbrt-v4
     * (which floors d^2 by half the diagonal's length): the choice must not
     * change when the scene is scaled (stress_invariance). A quarter: half
     * flattened the upper levels (test_lightbvh's gain fell from 13x to 4x). */
    float d2 = s_max(dc2, q->clamp);
    if (!(d2 > 0.0f) || !(dc2 > 0.0f))
        return dc2 > 0.0f ? 0.0f : b->phi / s_max(d2, FLT_MIN); /* x at the centre: no direction to bound */
    pf_vec3 wi = pf_scale(dx, 1.0f / sqrtf(dc2));
    float cos_w = pf_dot(b->w, wi);
    if (b->two_sided)
        cos_w = fabsf(cos_w);
    float sin_w = s_safe_sqrt(1.0f - cos_w * cos_w);
    /* the cone the box subtends from x (the whole sphere from inside) */
    float cos_b = -1.0f;
    int inside = x.x >= b->lo.x && x.y >= b->lo.y && x.z >= b->lo.z && x.x <= b->hi.x && x.y <= b->hi.y &&
                 x.z <= b->hi.z;
    if (!inside && dc2 > q->r2)
        cos_b = s_safe_sqrt(1.0f - q->r2 / dc2);
    float sin_b = s_safe_sqrt(1.0f - cos_b * cos_b);
    float cos_x = s_cos_sub_clamped(sin_w, cos_w, q->sin_o, b->cos_theta_o);
    float sin_x = s_sin_sub_clamped(sin_w, cos_w, q->sin_o, b->cos_theta_o);
    float cos_p = s_cos_sub_clamped(sin_x, cos_x, sin_b, cos_b);
    if (cos_p <= b->cos_theta_e)
        return 0.0f;
    float imp = b->phi * cos_p / d2;
    if (!pf_is_black(n)) { /* the receiver's cosine, bounded over the box */
        float cos_i = fabsf(pf_dot(wi, n));
        float sin_i = s_safe_sqrt(1.0f - cos_i * cos_i);
        imp *= s_cos_sub_clamped(sin_i, cos_i, sin_b, cos_b);
    }
    return s_max(imp, 0.0f);
}

float pf_light_importance(const pf_light_bounds_t *b, pf_vec3 x, pf_vec3 n)
{
    s_pre q = s_precompute(b);
    return s_importance(b, &q, x, n);
}

/* pbrt's DirectionCone union: the smallest cone (w, cos) holding both. */
static void s_cone_union(pf_vec3 wa, float ca, pf_vec3 wb, float cb, pf_vec3 *w, float *c)
{
    float ta = s_safe_acos(ca), tb = s_safe_acos(cb);
    float td = s_safe_acos(pf_dot(wa, wb));
    if (fminf(td + tb, PF_PI) <= ta) {
        *w = wa, *c = ca;
        return;
    }
    if (fminf(td + ta, PF_PI) <= tb) {
        *w = wb, *c = cb;
        return;
    }
    float to = 0.5f * (ta + td + tb);
    pf_vec3 k = pf_cross(wa, wb);
    if (to >= PF_PI || !(pf_len2(k) > 0.0f)) {
        *w = wa, *c = -1.0f; /* the entire sphere */
        return;
    }
    /* wa rotated by to - ta about k (k is perpendicular to wa) */
    float tr = to - ta;
    k = pf_norm(k);
    *w = pf_norm(pf_add(pf_scale(wa, cosf(tr)), pf_scale(pf_cross(k, wa), sinf(tr))));
    *c = cosf(to);
}

static pf_light_bounds_t s_union(const pf_light_bounds_t *a, const pf_light_bounds_t *b)
{
    if (!(a->phi > 0.0f))
        return *b;
    if (!(b->phi > 0.0f))
        return *a;
    pf_light_bounds_t r;
    r.lo = pf_vmin(a->lo, b->lo);
    r.hi = pf_vmax(a->hi, b->hi);
    r.phi = a->phi + b->phi;
    s_cone_union(a->w, a->cos_theta_o, b->w, b->cos_theta_o, &r.w, &r.cos_theta_o);
    r.cos_theta_e = fminf(a->cos_theta_e, b->cos_theta_e);
    r.two_sided = a->two_sided || b->two_sided;
    return r;
}

/* pbrt's EvaluateCost for a split part b of a node whose box has extent ext. */
static float s_cost(const pf_light_bounds_t *b, pf_vec3 ext, int dim)
{
    if (!(b->phi > 0.0f))
        return 0.0f;
    float to = s_safe_acos(b->cos_theta_o), te = s_safe_acos(b->cos_theta_e);
    float tw = fminf(to + te, PF_PI), sin_o = s_safe_sqrt(1.0f - b->cos_theta_o * b->cos_theta_o);
    float m_omega = 2.0f * PF_PI * (1.0f - b->cos_theta_o) +
                    0.5f * PF_PI * (2.0f * tw * sin_o - cosf(to - 2.0f * tw) - 2.0f * to * sin_o + b->cos_theta_o);
    float e[3] = { ext.x, ext.y, ext.z };
    float kr = fmaxf(e[0], fmaxf(e[1], e[2])) / e[dim];
    pf_vec3 d = pf_sub(b->hi, b->lo);
    float area = 2.0f * (d.x * d.y + d.y * d.z + d.z * d.x);
    return b->phi * m_omega * kr * area;
}

static float s_axis(pf_vec3 v, int dim) { return dim == 0 ? v.x : dim == 1 ? v.y : v.z; }

static pf_vec3 s_centroid(const pf_light_bounds_t *b) { return pf_scale(pf_add(b->lo, b->hi), 0.5f); }

typedef struct s_build {
    const pf_light_bounds_t *b;
    const uint32_t *id;
    uint32_t *items; /* indices into b, permuted in place */
    s_node *nodes;
    size_t nnodes;
} s_build;

/* The split of items[lo, hi) (hi - lo >= 2): where the second part starts
 * after partitioning. */
static size_t s_split(s_build *bd, size_t lo, size_t hi, const pf_light_bounds_t *all, int depth)
{
    pf_vec3 clo = pf_v3s(FLT_MAX), chi = pf_v3s(-FLT_MAX);
    for (size_t i = lo; i < hi; i++) {
        pf_vec3 c = s_centroid(&bd->b[bd->items[i]]);
        clo = pf_vmin(clo, c);
        chi = pf_vmax(chi, c);
    }
    pf_vec3 ext = pf_sub(all->hi, all->lo), cext = pf_sub(chi, clo);
    float best = INFINITY;
    int best_dim = -1, best_bucket = 0;
    for (int dim = 0; depth < S_DEEP && dim < 3; dim++) {
        if (!(s_axis(cext, dim) > 0.0f) || !(s_axis(ext, dim) > 0.0f))
            continue;
        pf_light_bounds_t bucket[S_BUCKETS];
        memset(bucket, 0, sizeof bucket);
        for (size_t i = lo; i < hi; i++) {
            const pf_light_bounds_t *b = &bd->b[bd->items[i]];
            int k = (int)(S_BUCKETS * (s_axis(s_centroid(b), dim) - s_axis(clo, dim)) / s_axis(cext, dim));
            k = k < 0 ? 0 : k >= S_BUCKETS ? S_BUCKETS - 1 : k;
            bucket[k] = s_union(&bucket[k], b);
        }
        for (int s = 0; s < S_BUCKETS - 1; s++) {
            pf_light_bounds_t l = { 0 }, r = { 0 };
            for (int k = 0; k <= s; k++)
                l = s_union(&l, &bucket[k]);
            for (int k = s + 1; k < S_BUCKETS; k++)
                r = s_union(&r, &bucket[k]);
            float cost = s_cost(&l, ext, dim) + s_cost(&r, ext, dim);
            if (cost > 0.0f && cost < best) {
                best = cost;
                best_dim = dim;
                best_bucket = s;
            }
        }
    }
    if (best_dim >= 0) {
        size_t mid = lo;
        for (size_t i = lo; i < hi; i++) {
            const pf_light_bounds_t *b = &bd->b[bd->items[i]];
            int k = (int)(S_BUCKETS * (s_axis(s_centroid(b), best_dim) - s_axis(clo, best_dim)) /
                          s_axis(cext, best_dim));
            k = k < 0 ? 0 : k >= S_BUCKETS ? S_BUCKETS - 1 : k;
            if (k <= best_bucket) {
                uint32_t t = bd->items[i];
                bd->items[i] = bd->items[mid];
                bd->items[mid++] = t;
            }
        }
        if (mid > lo && mid < hi)
            return mid;
    }
    return lo + (hi - lo) / 2; /* by count (the items are in build order: deterministic) */
}

/* Builds the subtree of items[lo, hi) at node index bd->nnodes; returns it. */
static uint32_t s_build_node(s_build *bd, size_t lo, size_t hi, uint32_t parent, int depth)
{
    uint32_t at = (uint32_t)bd->nnodes++;
    s_node *nd = &bd->nodes[at];
    nd->parent = parent;
    if (hi - lo == 1) {
        nd->b = bd->b[bd->items[lo]];
        nd->second = bd->id[bd->items[lo]];
        nd->leaf = 1;
        return at;
    }
    pf_light_bounds_t all = { 0 };
    for (size_t i = lo; i < hi; i++)
        all = s_union(&all, &bd->b[bd->items[i]]);
    size_t mid = s_split(bd, lo, hi, &all, depth);
    s_build_node(bd, lo, mid, at, depth + 1);
    uint32_t second = s_build_node(bd, mid, hi, at, depth + 1);
    nd = &bd->nodes[at];
    nd->b = s_union(&bd->nodes[at + 1].b, &bd->nodes[second].b);
    nd->second = second;
    nd->leaf = 0;
    return at;
}

pf_lightbvh_t *pf_lightbvh_build(const pf_light_bounds_t *b, const uint32_t *id, size_t n)
{
    size_t k = 0, nids = 0;
    for (size_t i = 0; i < n; i++) {
        k += b[i].phi > 0.0f;
        if ((size_t)id[i] + 1 > nids)
            nids = (size_t)id[i] + 1;
    }
    if (k == 0)
        return NULL;
    pf_lightbvh_t *self = calloc(1, sizeof *self);
    s_build bd = { .b = b, .id = id, .items = malloc(k * sizeof(uint32_t)) };
    if (self) {
        self->nodes = calloc(2 * k - 1, sizeof *self->nodes);
        self->leaf_of = malloc(nids * sizeof *self->leaf_of);
    }
    if (!self || !bd.items || !self->nodes || !self->leaf_of) {
        free(bd.items);
        pf_lightbvh_destroy(&self);
        return NULL;
    }
    k = 0;
    for (size_t i = 0; i < n; i++)
        if (b[i].phi > 0.0f)
            bd.items[k++] = (uint32_t)i;
    bd.nodes = self->nodes;
    s_build_node(&bd, 0, k, S_NONE, 0);
    free(bd.items);
    self->nnodes = bd.nnodes;
    for (size_t i = 0; i < self->nnodes; i++)
        self->nodes[i].q = s_precompute(&self->nodes[i].b);
    self->nids = nids;
    for (size_t i = 0; i < nids; i++)
        self->leaf_of[i] = S_NONE;
    for (size_t i = 0; i < self->nnodes; i++)
        if (self->nodes[i].leaf)
            self->leaf_of[self->nodes[i].second] = (uint32_t)i;
    return self;
}

void pf_lightbvh_destroy(pf_lightbvh_t **self_p)
{
    if (!self_p || !*self_p)
        return;
    free((*self_p)->nodes);
    free((*self_p)->leaf_of);
    free(*self_p);
    *self_p = NULL;
}

/* The probability of the first child of interior node at (x, n): *p0, and
 * its complement's in *p1; 0 when neither child has importance. */
static int s_child_probs(const pf_lightbvh_t *self, uint32_t at, pf_vec3 x, pf_vec3 n, float *p0, float *p1)
{
    const s_node *nd = &self->nodes[at];
    const s_node *a = &self->nodes[at + 1], *b = &self->nodes[nd->second];
    float c0 = s_importance(&a->b, &a->q, x, n), c1 = s_importance(&b->b, &b->q, x, n);
    if (!(c0 + c1 > 0.0f))
        return 0;
    *p0 = c0 / (c0 + c1);
    *p1 = c1 / (c0 + c1);
    return 1;
}

int pf_lightbvh_sample(const pf_lightbvh_t *self, pf_vec3 x, pf_vec3 n, float u, uint32_t *id, float *pmf)
{
    if (!self)
        return 0;
    uint32_t at = 0;
    float p = 1.0f;
    if (self->nodes[0].leaf && !(s_importance(&self->nodes[0].b, &self->nodes[0].q, x, n) > 0.0f))
        return 0;
    while (!self->nodes[at].leaf) {
        float p0, p1;
        if (!s_child_probs(self, at, x, n, &p0, &p1))
            return 0;
        if (u < p0 && p0 > 0.0f) {
            u = fminf(u / p0, 0x1.fffffep-1f);
            p *= p0;
            at = at + 1;
        } else {
            if (!(p1 > 0.0f))
                return 0;
            u = fminf((u - p0) / p1, 0x1.fffffep-1f);
            p *= p1;
            at = self->nodes[at].second;
        }
    }
    *id = self->nodes[at].second;
    *pmf = p;
    return p > 0.0f;
}

float pf_lightbvh_pmf(const pf_lightbvh_t *self, pf_vec3 x, pf_vec3 n, uint32_t id)
{
    if (!self || id >= self->nids || self->leaf_of[id] == S_NONE)
        return 0.0f;
    uint32_t path[S_MAX_DEPTH + 1];
    int depth = 0;
    for (uint32_t at = self->leaf_of[id]; at != S_NONE && depth <= S_MAX_DEPTH; at = self->nodes[at].parent)
        path[depth++] = at;
    if (depth == 1) /* the root is the leaf */
        return s_importance(&self->nodes[0].b, &self->nodes[0].q, x, n) > 0.0f ? 1.0f : 0.0f;
    float p = 1.0f;
    for (int i = depth - 1; i > 0; i--) { /* root first, as the sampler multiplies */
        float p0, p1;
        if (!s_child_probs(self, path[i], x, n, &p0, &p1))
            return 0.0f;
        p *= path[i - 1] == path[i] + 1 ? p0 : p1;
    }
    return p;
}
