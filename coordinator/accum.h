/* accum.h: the progressive render's image: the running mean of its passes,
 * pixel by pixel, each pass weighted by its camera samples per pixel. A
 * pass cut short (a deadline, Ctrl-C) adds the tiles it finished and no
 * others, so every pixel stays the mean of whole, independent pass
 * estimates of it: unbiased wherever a pass reached, whatever the order.
 * The spread between passes gives an estimate of the mean's error.
 *
 * Sums are kept in double and each pixel takes its passes in pass order,
 * so the image is the same bits however the tiles of a pass arrived.
 * Threads: pf_accum_add from several threads at once for disjoint
 * rectangles; the rest from one. */
#ifndef PF_ACCUM_H
#define PF_ACCUM_H

#include <stdint.h>

#include "image/image.h"

typedef struct pf_accum {
    int width, height;
    double *sum;      /* 3 per pixel: sum of w x over the passes */
    double *sum2;     /* 3 per pixel: sum of w x^2 */
    uint32_t *weight; /* per pixel: sum of w (camera samples) */
    uint32_t *passes; /* per pixel: passes added */
} pf_accum_t;

/* An empty accumulator for a width x height image. 0 or PF_ENOMEM. */
int pf_accum_init(pf_accum_t *a, int width, int height);
void pf_accum_free(pf_accum_t *a);

/* Adds one pass's w x h rectangle at (x0, y0): rgb holds its rows, top
 * first, stride floats apart (3 w for a packed tile), each pixel the mean
 * of `spp` camera samples. */
void pf_accum_add(pf_accum_t *a, int x0, int y0, int w, int h, const float *rgb, size_t stride, uint32_t spp);

/* pf_accum_add with each pixel's own camera samples: counts holds the
 * whole image's (width x height, row by row; adapt.h). */
void pf_accum_add_map(pf_accum_t *a, int x0, int y0, int w, int h, const float *rgb, size_t stride,
                      const uint16_t *counts);

/* The mean into img (allocated at the accumulator's size). Returns the
 * pixels no pass reached (left black). */
size_t pf_accum_resolve(const pf_accum_t *a, pf_image_t *img);

/* The mean's estimated relMSE (the compare command's metric: the variance
 * of the mean over mean^2 + 0.01, averaged over channels), from the spread
 * of the passes around it, over pixels with two passes or more; NaN when
 * none has. It sees noise only: bias does not show between passes. */
double pf_accum_error(const pf_accum_t *a);

#endif
