/* accum.c: the running mean of progressive passes; see accum.h. */
#include "coordinator/accum.h"

#include <math.h>
#include <stdlib.h>
#include <string.h>

#include "base/status.h"

int pf_accum_init(pf_accum_t *a, int width, int height)
{
    memset(a, 0, sizeof *a);
    size_t n = (size_t)width * (size_t)height;
    a->width = width;
    a->height = height;
    a->sum = calloc(3 * n, sizeof *a->sum);
    a->sum2 = calloc(3 * n, sizeof *a->sum2);
    a->weight = calloc(n, sizeof *a->weight);
    a->passes = calloc(n, sizeof *a->passes);
    if (!a->sum || !a->sum2 || !a->weight || !a->passes) {
        pf_accum_free(a);
        return PF_ENOMEM;
    }
    return PF_OK;
}

void pf_accum_free(pf_accum_t *a)
{
    free(a->sum);
    free(a->sum2);
    free(a->weight);
    free(a->passes);
    memset(a, 0, sizeof *a);
}

void pf_accum_add(pf_accum_t *a, int x0, int y0, int w, int h, const float *rgb, size_t stride, uint32_t spp)
{
    double wt = (double)spp;
    for (int y = 0; y < h; y++) {
        const float *row = rgb + (size_t)y * stride;
        size_t p = (size_t)(y0 + y) * (size_t)a->width + (size_t)x0;
        for (int x = 0; x < w; x++, p++) {
            for (int c = 0; c < 3; c++) {
                double v = (double)row[3 * x + c];
                a->sum[3 * p + c] += wt * v;
                a->sum2[3 * p + c] += wt * v * v;
            }
            a->weight[p] += spp;
            a->passes[p]++;
        }
    }
}

void pf_accum_add_map(pf_accum_t *a, int x0, int y0, int w, int h, const float *rgb, size_t stride,
                      const uint16_t *counts)
{
    for (int y = 0; y < h; y++)
        for (int x = 0; x < w; x++) {
            size_t p = (size_t)(y0 + y) * (size_t)a->width + (size_t)(x0 + x);
            pf_accum_add(a, x0 + x, y0 + y, 1, 1, rgb + (size_t)y * stride + 3 * (size_t)x, 3, counts[p]);
        }
}

size_t pf_accum_resolve(const pf_accum_t *a, pf_image_t *img)
{
    size_t n = (size_t)a->width * (size_t)a->height, empty = 0;
    for (size_t p = 0; p < n; p++) {
        if (!a->weight[p]) {
            img->rgb[3 * p] = img->rgb[3 * p + 1] = img->rgb[3 * p + 2] = 0.0f;
            empty++;
            continue;
        }
        double inv = (double)a->weight[p];
        for (int c = 0; c < 3; c++)
            img->rgb[3 * p + c] = (float)(a->sum[3 * p + c] / inv);
    }
    return empty;
}

double pf_accum_error(const pf_accum_t *a)
{
    size_t n = (size_t)a->width * (size_t)a->height, used = 0;
    double total = 0.0;
    for (size_t p = 0; p < n; p++) {
        uint32_t k = a->passes[p];
        if (k < 2)
            continue;
        double W = (double)a->weight[p];
        for (int c = 0; c < 3; c++) {
            double mean = a->sum[3 * p + c] / W;
            /* sum w (x - mean)^2 / (k - 1) estimates the variance of one
             * camera sample's worth (a pass of w samples has variance
             * sigma^2 / w); the mean's is that over W. */
            double ss = a->sum2[3 * p + c] - W * mean * mean;
            double var = (ss > 0.0 ? ss : 0.0) / ((double)(k - 1) * W);
            total += var / (mean * mean + 0.01);
        }
        used++;
    }
    return used ? total / (3.0 * (double)used) : NAN;
}
