/* pixel_impl.h (private to render/): where a camera sample lands in its
 * pixel (the pixel filter), and the emitters' edges (pixel.c). render.c
 * traces the samples; this file places them and, at the edge of an emitter
 * the camera sees directly, estimates that emission apart. */
#ifndef PF_RENDER_PIXEL_IMPL_H
#define PF_RENDER_PIXEL_IMPL_H

#include <stdint.h>

#include "base/vec.h"
#include "scene/scene.h"

/* render.h's context (this header is read by render.c, and so may not
 * read render.h itself) */
typedef struct pf_render_ctx pf_render_ctx_t;

/* Moves a sample's stratified position (jx, jy) in [0, 1)^2 of its pixel to
 * where the pixel filter puts it (film offsets from the pixel's corner, may
 * leave [0, 1)), through the inverse CDF of the filter's marginal along
 * each axis, so stratified positions stay stratified. The default filter
 * (box 1, tent 0) leaves them as they are. */
void pf_pixel_filter(const pf_settings_t *s, float *jx, float *jy);

/* The emitters' edges of a tile: one emission probe per film corner from
 * (x0 - 1, y0 - 1) to (x0 + w + 1, y0 + h + 1), each the luminance of the
 * emitter or sky the ray through it sees directly, whatever terms the
 * render counts (so that renders of the terms apart add up to the whole);
 * NULL when out of memory (the tile then renders without edge samples: the
 * same estimate, noisier). Free with free(). */
float *pf_edges_probe(const pf_render_ctx_t *c, int x0, int y0, int w, int h);

/* Whether pixel (px, py) of the tile at (x0, y0), w wide, lies on an
 * emitter's edge: its 4 x 4 probes (corners px - 1 .. px + 2) see emission
 * that differs by more than a factor of 2. A function of the pixel alone,
 * never of the tiling. */
int pf_edges_pixel(const float *probe, int x0, int y0, int w, int px, int py);

/* The camera samples an edge pixel takes beyond its spp (at most 256). */
#define PF_EDGE_SAMPLES 64

/* The Latin hypercube of edge pixel (px, py)'s extra samples: sample j lies
 * in column sx[j] and row sy[j] of a PF_EDGE_SAMPLES-square grid of the
 * pixel (random permutations drawn from PF_STREAM_EDGE). */
void pf_edges_strata(const pf_render_ctx_t *c, int px, int py, uint8_t sx[PF_EDGE_SAMPLES],
                     uint8_t sy[PF_EDGE_SAMPLES]);

#endif
