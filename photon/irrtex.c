/* irrtex.c: irradiance texels on the scene's surfaces; see irrtex.h. Owns
 * the per-primitive table and the texels. Built by one thread
 * (pf_photon_maps_index); lookups and their fills come from every rendering
 * thread at once. A texel is one 64-bit atomic, written by whichever
 * thread first finds it empty, maybe several at once: each stores the same
 * bits (the value is a function of the texel), and a reader sees either
 * zero (empty: it fills the texel itself) or the whole value. */
#include "photon/irrtex.h"

#include <math.h>
#include <stdatomic.h>
#include <stdlib.h>
#include <string.h>

#include "base/log.h"
#include "photon/photonmap.h"

typedef struct {
    uint32_t off; /* first texel (the front side's; the back side's follow) */
    uint32_t res; /* texels along a side; 0: none, look up directly */
} s_prim;

/* A texel: 0 until filled; then bit 63 set, and either bit 62 (S_DIRECT:
 * hits in it are looked up directly) or the irradiance's three channels in
 * 20 bits each (s_pack). */
#define S_FILLED ((uint64_t)1 << 63)
#define S_DIRECT ((uint64_t)1 << 62)
typedef _Atomic uint64_t s_texel;

struct pf_irrtex {
    const pf_scene_t *scene;
    const pf_accel_t *accel;
    const pf_kdtree_t *irr;
    float irr_r2;
    float side;
    size_t *first;  /* first s_prim of each mesh */
    s_prim *prims;
    s_texel *texels;
    size_t ntexels;
    _Atomic size_t filled, direct; /* fills so far (two threads filling one texel at once count twice) */
};

/* Texels along a triangle's edges for its longest edge at the given texel
 * side; 0 when more than PF_IRRTEX_MAX_RES. */
static uint32_t s_res(float extent, float side)
{
    float r = ceilf(extent / side);
    if (!(r <= (float)PF_IRRTEX_MAX_RES))
        return 0;
    return r < 1.0f ? 1u : (uint32_t)r;
}

static float s_tri_extent(const pf_mesh_t *m, size_t t)
{
    const uint32_t *v = &m->idx[3 * t];
    pf_vec3 a = m->pos[v[0]], b = m->pos[v[1]], c = m->pos[v[2]];
    return sqrtf(fmaxf(fmaxf(pf_len2(pf_sub(b, a)), pf_len2(pf_sub(c, b))), pf_len2(pf_sub(a, c))));
}

/* Fills the primitive table for a texel side; the texel count, or more than
 * PF_IRRTEX_MAX_TEXELS when they would not fit. */
static size_t s_layout(pf_irrtex_t *t, float side)
{
    const pf_scene_t *sc = t->scene;
    size_t total = 0;
    for (size_t m = 0; m < sc->nmeshes; m++)
        for (size_t i = 0; i < sc->meshes[m].ntris; i++) {
            s_prim *p = &t->prims[t->first[m] + i];
            p->res = s_res(s_tri_extent(&sc->meshes[m], i), side);
            p->off = (uint32_t)total;
            total += 2 * (size_t)p->res * p->res;
            if (total > PF_IRRTEX_MAX_TEXELS)
                return total;
        }
    return total;
}

static int s_cmp_float(const void *a, const void *b)
{
    float x = *(const float *)a, y = *(const float *)b;
    return (x > y) - (x < y);
}

/* The median support radius over up to 4095 points spread evenly through
 * irr (a function of the tree alone); 0 when none is positive. */
static float s_median_radius(const pf_kdtree_t *irr)
{
    enum { SAMPLES = 4095 };
    static const size_t cap = SAMPLES;
    float r[SAMPLES];
    size_t n = pf_kdtree_size(irr), m = 0, want = n < cap ? n : cap;
    const pf_photon_t *ph = pf_kdtree_photons(irr);
    for (size_t i = 0; i < want; i++) {
        float ri = pf_irradiance_radius(&ph[i * n / want]);
        if (ri > 0.0f && isfinite(ri))
            r[m++] = ri;
    }
    if (!m)
        return 0.0f;
    qsort(r, m, sizeof *r, s_cmp_float);
    return r[m / 2];
}

pf_irrtex_t *pf_irrtex_create(const pf_scene_t *scene, const pf_accel_t *accel, const pf_kdtree_t *irr, float irr_r2)
{
    if (!scene || !accel || !irr || !pf_kdtree_size(irr))
        return NULL;
    float r = s_median_radius(irr);
    if (!(r > 0.0f))
        return NULL;
    pf_irrtex_t *t = calloc(1, sizeof *t);
    if (!t)
        return NULL;
    t->scene = scene;
    t->accel = accel;
    t->irr = irr;
    t->irr_r2 = irr_r2;
    t->first = malloc((scene->nmeshes ? scene->nmeshes : 1) * sizeof *t->first);
    size_t nprims = 0;
    for (size_t m = 0; t->first && m < scene->nmeshes; m++) {
        t->first[m] = nprims;
        nprims += scene->meshes[m].ntris;
    }
    t->prims = malloc((nprims ? nprims : 1) * sizeof *t->prims);
    if (!t->first || !t->prims) {
        pf_irrtex_destroy(&t);
        return NULL;
    }
    /* The side grows by 1.25 until the texels fit: primitives too large for
     * PF_IRRTEX_MAX_RES keep none (s_res), the rest share the budget. */
    float side = PF_IRRTEX_SIDE * r;
    size_t total = s_layout(t, side);
    for (int grow = 0; grow < 32 && total > PF_IRRTEX_MAX_TEXELS; grow++) {
        side *= 1.25f;
        total = s_layout(t, side);
    }
    if (total > PF_IRRTEX_MAX_TEXELS) {
        pf_irrtex_destroy(&t);
        return NULL;
    }
    t->side = side;
    t->ntexels = total;
    /* calloc: pages of texels no gather ray reaches are never touched. */
    t->texels = calloc(total ? total : 1, sizeof *t->texels);
    if (!t->texels) {
        pf_irrtex_destroy(&t);
        return NULL;
    }
    pf_debug("irradiance texels: side %g (median support radius %g), %zu texels", (double)side, (double)r, total);
    return t;
}

void pf_irrtex_destroy(pf_irrtex_t **self_p)
{
    if (!self_p || !*self_p)
        return;
    pf_irrtex_t *t = *self_p;
    free(t->first);
    free(t->prims);
    free(t->texels);
    free(t);
    *self_p = NULL;
}

/* The texel a hit falls in, and with c non-NULL its centre, side normal
 * and reach (the distance from the centre to its farthest corner).
 * PF_IRRTEX_NONE when the primitive has none (spheres never do). */
static size_t s_locate(const pf_irrtex_t *t, const pf_hit_t *h, pf_vec3 nf, pf_vec3 *c, pf_vec3 *n, float *reach)
{
    const pf_scene_t *sc = t->scene;
    if (h->geom >= sc->nmeshes)
        return PF_IRRTEX_NONE;
    const pf_mesh_t *m = &sc->meshes[h->geom];
    s_prim p = t->prims[t->first[h->geom] + h->prim];
    if (!p.res)
        return PF_IRRTEX_NONE;
    const uint32_t *v = &m->idx[3 * (size_t)h->prim];
    pf_vec3 p0 = m->pos[v[0]], e1 = pf_sub(m->pos[v[1]], p0), e2 = pf_sub(m->pos[v[2]], p0);
    pf_vec3 ng = pf_cross(e1, e2); /* the winding's side is the front */
    int back = pf_dot(nf, ng) < 0.0f;
    float c1, c2;
    uint32_t i = pf_irrtex_tri_texel(p.res, h->u, h->v, &c1, &c2);
    if (c) {
        *c = pf_add(p0, pf_add(pf_scale(e1, c1), pf_scale(e2, c2)));
        *n = pf_scale(pf_norm(ng), back ? -1.0f : 1.0f);
        /* The corners lie at (-1, -1), (2, -1), (-1, 2) / 3R from the
         * centroid in (b1, b2), or at their negatives (a texel pointing
         * down): the same distances. */
        float k = 1.0f / (3.0f * (float)p.res);
        pf_vec3 a = pf_scale(pf_add(e1, e2), -k), b = pf_scale(pf_sub(pf_scale(e1, 2.0f), e2), k),
                d = pf_scale(pf_sub(pf_scale(e2, 2.0f), e1), k);
        *reach = sqrtf(fmaxf(fmaxf(pf_len2(a), pf_len2(b)), pf_len2(d)));
    }
    return p.off + (size_t)back * p.res * p.res + i;
}

/* A channel (>= 0; anything else as 0) in 20 bits: a float's exponent and
 * its mantissa rounded to 12 bits, a relative error of at most 2^-13 (an
 * infinity stays one). */
static inline uint64_t s_pack1(float f)
{
    if (!(f > 0.0f))
        return 0;
    uint32_t u;
    memcpy(&u, &f, sizeof u);
    return (uint64_t)(u >= 0x7f800000u ? 0x7f800000u : u + (1u << 10)) >> 11;
}

static inline float s_unpack1(uint64_t b)
{
    uint32_t u = (uint32_t)(b & 0xfffffu) << 11;
    float f;
    memcpy(&f, &u, sizeof f);
    return f;
}

static inline uint64_t s_pack(pf_vec3 e)
{
    return S_FILLED | s_pack1(e.x) << 40 | s_pack1(e.y) << 20 | s_pack1(e.z);
}

static inline pf_vec3 s_unpack(uint64_t b)
{
    return pf_v3(s_unpack1(b >> 40), s_unpack1(b >> 20), s_unpack1(b));
}

/* Whether hits in the texel centred at c (side normal n, reach) must be
 * looked up directly: when any surface but the texel's own plane comes
 * within its reach, a wall may stand between the centre and a hit (a box on
 * the floor, a crate's side), or a surface may meet the texel's edge (a
 * corner, a curved mesh's next triangle), and the centre's answer might not
 * be the hit's. Corners touch their neighbours at exactly the reach, so the
 * query stops just short of it. */
static int s_direct(const pf_irrtex_t *t, pf_vec3 c, pf_vec3 n, float reach)
{
    return !pf_accel_only_plane(t->accel, c, n, 0.999f * reach);
}

pf_vec3 pf_irrtex_quantize(pf_vec3 e) { return s_unpack(s_pack(e)); }

int pf_irrtex_centre(const pf_irrtex_t *self, const pf_hit_t *h, pf_vec3 nf, pf_vec3 *c, pf_vec3 *n, int *direct)
{
    float reach;
    if (s_locate(self, h, nf, c, n, &reach) == PF_IRRTEX_NONE)
        return 0;
    *direct = s_direct(self, *c, *n, reach);
    return 1;
}

size_t pf_irrtex_find(const pf_irrtex_t *self, const pf_hit_t *h, pf_vec3 nf)
{
    size_t i = s_locate(self, h, nf, NULL, NULL, NULL);
    if (i != PF_IRRTEX_NONE)
        __builtin_prefetch((const void *)&self->texels[i]);
    return i;
}

int pf_irrtex_read(pf_irrtex_t *self, size_t texel, const pf_hit_t *h, pf_vec3 nf, pf_vec3 *e)
{
    if (texel == PF_IRRTEX_NONE)
        return 0;
    uint64_t b = atomic_load_explicit(&self->texels[texel], memory_order_relaxed);
    if (!b) {
        pf_vec3 c, n;
        float reach;
        s_locate(self, h, nf, &c, &n, &reach);
        int direct = s_direct(self, c, n, reach);
        b = direct ? S_FILLED | S_DIRECT : s_pack(pf_irradiance_lookup(self->irr, self->irr_r2, self->accel, c, n));
        atomic_store_explicit(&self->texels[texel], b, memory_order_relaxed);
        atomic_fetch_add_explicit(&self->filled, 1, memory_order_relaxed);
        if (direct)
            atomic_fetch_add_explicit(&self->direct, 1, memory_order_relaxed);
    }
    if (b & S_DIRECT)
        return 0;
    *e = s_unpack(b);
    return 1;
}

int pf_irrtex_lookup(pf_irrtex_t *self, const pf_hit_t *h, pf_vec3 nf, pf_vec3 *e)
{
    return pf_irrtex_read(self, s_locate(self, h, nf, NULL, NULL, NULL), h, nf, e);
}

float pf_irrtex_side(const pf_irrtex_t *self) { return self->side; }
size_t pf_irrtex_count(const pf_irrtex_t *self) { return self->ntexels; }

size_t pf_irrtex_filled(const pf_irrtex_t *self, size_t *direct)
{
    if (direct)
        *direct = atomic_load_explicit(&self->direct, memory_order_relaxed);
    return atomic_load_explicit(&self->filled, memory_order_relaxed);
}
