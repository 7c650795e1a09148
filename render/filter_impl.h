/* filter_impl.h (private to render/): the first-gather filter's records
 * (see "Filtering the first gather" in filter.c). A pixel's record holds the
 * surfaces its camera samples' primary paths end on (clusters) and the sums
 * of the first gathers made there; a grid holds the records of a tile and
 * its border, recorded row by row (once each, by whichever thread asks
 * first), and gives each pixel the mean over its neighbourhood. render.c
 * traces the samples and makes the gathers; this file only groups them. */
#ifndef PF_RENDER_FILTER_IMPL_H
#define PF_RENDER_FILTER_IMPL_H

#include <omp.h>
#include <stdatomic.h>
#include <stddef.h>

#include "base/vec.h"

#define PF_FILTER_COS 0.95f  /* normals closer than this are one surface's */
#define PF_FILTER_REACH 3.0f /* in pixel widths (c->foot), within a pixel */
#define PF_FILTER_STEP 1.0f /* offsets from the tangent plane no turn of the normal explains, in c->base */
enum { PF_FILTER_MAX_CLUSTERS = 4 };

typedef struct pf_filter_cluster {
    pf_vec3 p, n; /* its first sample's hit point and (camera-facing) normal */
    pf_vec3 gsum; /* the sum of its samples' first gathers */
    float foot;   /* a pixel's width at p (along the surface, stretched at grazing angles) */
    float base;   /* a pixel's width at p across the line of sight: the primary path's length times its angle */
    int count;
} pf_filter_cluster_t;

typedef struct pf_filter_rec {
    int nc;
    pf_filter_cluster_t c[PF_FILTER_MAX_CLUSTERS];
} pf_filter_rec_t;

/* Whether q (normal m) lies on the surface of a cluster's point p (normal n)
 * within reach pixel widths. */
int pf_filter_same_surface(const pf_filter_cluster_t *c, pf_vec3 q, pf_vec3 m, float reach);

/* The first of rec's surfaces that q (normal m) lies on within
 * PF_FILTER_REACH pixel widths (the order they were found in), or rec->nc
 * when none does. */
int pf_filter_rec_find(const pf_filter_rec_t *rec, pf_vec3 q, pf_vec3 m);

/* The records of a tile (x0, y0, w, h) and its border of R pixels, clipped
 * to the image (W x H), kept by record row. */
typedef struct pf_filter_grid {
    int R;
    int rx0, ry0, rw, rh; /* the records' rectangle */
    pf_filter_rec_t *recs;
    atomic_int *done;  /* per record row: recorded */
    omp_lock_t *locks; /* per record row: held while it is recorded */
} pf_filter_grid_t;

/* Allocates g's records (aborts when out of memory). */
void pf_filter_grid_init(pf_filter_grid_t *g, int R, int x0, int y0, int w, int h, int W, int H);

/* Frees what pf_filter_grid_init allocated; safe on a zeroed grid. */
void pf_filter_grid_free(pf_filter_grid_t *g);

/* The record of image pixel (px, py), which must lie in g's rectangle. */
static inline pf_filter_rec_t *pf_filter_grid_at(const pf_filter_grid_t *g, int px, int py)
{
    return &g->recs[(size_t)(py - g->ry0) * (size_t)g->rw + (size_t)(px - g->rx0)];
}

/* Records row `row` of g (0 .. rh - 1) by calling record(user, row) unless
 * it is done already; thread-safe, each row recorded once. */
void pf_filter_grid_record_row(pf_filter_grid_t *g, int row, void (*record)(void *user, int row), void *user);

/* The filtered first gather of each of pixel (px, py)'s surfaces: the mean
 * over the neighbourhood's samples on it. The rows it reads must be
 * recorded. */
void pf_filter_gathers(const pf_filter_grid_t *g, int px, int py, pf_vec3 gf[PF_FILTER_MAX_CLUSTERS]);

#endif
