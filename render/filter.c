/* filter.c: the first-gather filter's records (filter_impl.h): which
 * surfaces a pixel's camera samples end on, the sums of their first gathers,
 * and the mean over a pixel's neighbourhood that its samples take instead of
 * their own. The render pass (render.c) traces the samples, makes the
 * gathers and fills the records; any thread may record a row (once) or read
 * rows recorded.
 *
 * Filtering the first gather.
 *
 * The indirect term is smooth where the surface is, so the gathers of a
 * pixel's neighbours estimate it as well as its own: every camera sample
 * whose primary path (through mirrors, and glass refracting near the eye;
 * s_primary_hit) ends on a diffuse surface takes the mean of the gathers
 * there of all samples in the (2R+1) x (2R+1) pixels around its pixel that
 * lie on the same surface (normals within PF_FILTER_COS, within a pixel's
 * width of its tangent plane and PF_FILTER_REACH * (R + 1) pixel widths of
 * it; the width measured by tracing the paths one pixel over, s_footprint),
 * R = settings.gather_filter. A pixel's width along a surface seen at a
 * grazing angle or from far can exceed the steps of a staircase or the
 * spacing of shelves, whose treads get very different indirect light (each
 * from its own riser), so the offset from the tangent plane must also be
 * explained by the turn of the normal between the two points (curvature,
 * creases between facets), give or take PF_FILTER_STEP pixel widths across
 * the line of sight: parallel planes further apart than that never share
 * (tests/render/test_filter_steps.c). Samples of one pixel are grouped into at most
 * PF_FILTER_MAX_CLUSTERS such surfaces; a sample fitting none keeps its own
 * gather. Only this gather is shared: direct light, caustics and the other
 * branches stay per sample, and their gathers are not filtered.
 *
 * A first gather draws from its own stream (seed, gather, pixel, sample), so
 * a tile computes its neighbours' records exactly as their own tiles do: the
 * image still depends on the pixel alone, never on the tiling. The border of
 * R pixels costs one camera ray and one gather per sample (about 13 % more
 * gathers for 32-pixel tiles at R = 1). */
#include "render/filter_impl.h"

#include <math.h>
#include <stdlib.h>

#include "base/status.h"

int pf_filter_same_surface(const pf_filter_cluster_t *c, pf_vec3 q, pf_vec3 m, float reach)
{
    if (pf_dot(c->n, m) < PF_FILTER_COS)
        return 0;
    pf_vec3 d = pf_sub(q, c->p);
    float r = reach * c->foot, d2 = pf_dot(d, d), off = fabsf(pf_dot(d, c->n));
    if (off > c->foot || d2 > r * r)
        return 0;
    /* The step guard: q must lie off p's tangent plane by no more than the
     * turn of the normal from n to m explains (a curved or creased surface
     * leaves its tangent plane by at most |d| sin(angle(n, m))), give or
     * take PF_FILTER_STEP pixel widths across the line of sight (c->base,
     * not c->foot, which grazing angles stretch and which a neighbouring
     * path landing on the next step inflates). */
    return off <= PF_FILTER_STEP * c->base + pf_len(pf_cross(c->n, m)) * sqrtf(d2);
}

int pf_filter_rec_find(const pf_filter_rec_t *rec, pf_vec3 q, pf_vec3 m)
{
    int k = 0;
    while (k < rec->nc && !pf_filter_same_surface(&rec->c[k], q, m, PF_FILTER_REACH))
        k++;
    return k;
}

void pf_filter_grid_init(pf_filter_grid_t *g, int R, int x0, int y0, int w, int h, int W, int H)
{
    g->R = R;
    g->rx0 = x0 - R > 0 ? x0 - R : 0;
    g->ry0 = y0 - R > 0 ? y0 - R : 0;
    int rx1 = x0 + w + R < W ? x0 + w + R : W;
    int ry1 = y0 + h + R < H ? y0 + h + R : H;
    g->rw = rx1 - g->rx0;
    g->rh = ry1 - g->ry0;
    g->recs = malloc((size_t)g->rw * (size_t)g->rh * sizeof *g->recs);
    g->done = malloc((size_t)g->rh * sizeof *g->done);
    g->locks = malloc((size_t)g->rh * sizeof *g->locks);
    PF_CHECK(g->recs != NULL && g->done != NULL && g->locks != NULL);
    for (int r = 0; r < g->rh; r++) {
        atomic_init(&g->done[r], 0);
        omp_init_lock(&g->locks[r]);
    }
}

void pf_filter_grid_free(pf_filter_grid_t *g)
{
    if (g->locks)
        for (int r = 0; r < g->rh; r++)
            omp_destroy_lock(&g->locks[r]);
    free(g->locks);
    free((void *)g->done);
    free(g->recs);
    g->locks = NULL;
    g->done = NULL;
    g->recs = NULL;
}

void pf_filter_grid_record_row(pf_filter_grid_t *g, int row, void (*record)(void *user, int row), void *user)
{
    if (atomic_load_explicit(&g->done[row], memory_order_acquire))
        return;
    omp_set_lock(&g->locks[row]);
    if (!atomic_load_explicit(&g->done[row], memory_order_relaxed)) {
        record(user, row);
        atomic_store_explicit(&g->done[row], 1, memory_order_release);
    }
    omp_unset_lock(&g->locks[row]);
}

void pf_filter_gathers(const pf_filter_grid_t *g, int px, int py, pf_vec3 gf[PF_FILTER_MAX_CLUSTERS])
{
    int R = g->R;
    const pf_filter_rec_t *rec = pf_filter_grid_at(g, px, py);
    for (int k = 0; k < rec->nc; k++) {
        const pf_filter_cluster_t *own = &rec->c[k];
        pf_vec3 sum = pf_v3s(0.0f);
        int count = 0;
        for (int qy = py - R; qy <= py + R; qy++) {
            if (qy < g->ry0 || qy >= g->ry0 + g->rh)
                continue;
            for (int qx = px - R; qx <= px + R; qx++) {
                if (qx < g->rx0 || qx >= g->rx0 + g->rw)
                    continue;
                const pf_filter_rec_t *q = pf_filter_grid_at(g, qx, qy);
                for (int j = 0; j < q->nc; j++)
                    if (pf_filter_same_surface(own, q->c[j].p, q->c[j].n, PF_FILTER_REACH * (float)(R + 1))) {
                        sum = pf_add(sum, q->c[j].gsum);
                        count += q->c[j].count;
                    }
            }
        }
        gf[k] = pf_scale(sum, 1.0f / (float)count);
    }
}
