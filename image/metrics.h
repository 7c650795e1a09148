/* metrics.h: image error metrics against a reference. */
#ifndef PF_METRICS_H
#define PF_METRICS_H

#include "image/image.h"

typedef struct pf_metrics {
    double relmse;          /* mean over pixels and channels of (a-b)^2/(b^2+0.01) */
    double rmse;            /* sqrt of mean (a-b)^2 */
    double lum_ratio;       /* mean luminance of a / mean luminance of b */
    int width, height;      /* the size compared at */
    int factor_a, factor_b; /* box-downsampling factors applied to a and b */
    int downsample;         /* the extra factor applied to both after fitting (1: none) */
    size_t masked;          /* pixels of the compared grid left out (0 without a mask) */
} pf_metrics_t;

/* Options of pf_metrics_compare_opts. downsample: after the size fitting,
 * box-downsample both images by this factor (>= 1; 0 counts as 1).
 * mask_above: leave out every compared pixel one of whose reference pixels
 * (at the reference's own resolution) has luminance above it; NAN or
 * INFINITY masks nothing. */
typedef struct pf_metrics_opts {
    int downsample;
    double mask_above;
} pf_metrics_opts_t;

/* Rec. 709 luminance of one linear RGB pixel (the weights the mask uses). */
double pf_rgb_luminance(const float *rgb);

/* Compares a with reference b. When sizes differ by an integer factor (the
 * same in x and y), the larger is box-downsampled to the smaller first.
 * PF_ESIZE (err filled) when the sizes do not fit. Sums in double. */
int pf_metrics_compare(const pf_image_t *a, const pf_image_t *b, pf_metrics_t *out, pf_error_t *err);

/* pf_metrics_compare with options (opts NULL: none). After the size fitting,
 * both images are box-downsampled by opts->downsample; PF_ESIZE when it does
 * not divide both fitted sizes (or is negative). Masked pixels are left out of
 * every figure: relMSE and RMSE average over the pixels kept, the luminance
 * ratio sums over them; with every pixel masked the figures are NAN. */
int pf_metrics_compare_opts(const pf_image_t *a, const pf_image_t *b, const pf_metrics_opts_t *opts,
                            pf_metrics_t *out, pf_error_t *err);

/* Places a and b (the same size) side by side into dst (allocated here):
 * a on the left, then gap columns of white (a value far above 1, so it
 * clips to white at any reasonable exposure), then b. Returns 0, PF_EINVAL
 * (empty images, different sizes or gap < 0) or PF_ENOMEM. */
int pf_image_side_by_side(const pf_image_t *a, const pf_image_t *b, int gap, pf_image_t *dst);

/* Box-downsamples src by an integer factor into dst (allocated here). */
int pf_image_downsample(const pf_image_t *src, int factor, pf_image_t *dst);

#endif
