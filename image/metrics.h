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
} pf_metrics_t;

/* Compares a with reference b. When sizes differ by an integer factor (the
 * same in x and y), the larger is box-downsampled to the smaller first.
 * PF_ESIZE (err filled) when the sizes do not fit. Sums in double. */
int pf_metrics_compare(const pf_image_t *a, const pf_image_t *b, pf_metrics_t *out, pf_error_t *err);

/* Box-downsamples src by an integer factor into dst (allocated here). */
int pf_image_downsample(const pf_image_t *src, int factor, pf_image_t *dst);

#endif
