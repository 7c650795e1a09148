/* adapt.c: the sample allocation of adaptive progressive passes; see
 * adapt.h. The score is computed in double, pixel by pixel in row order,
 * in this process alone (the coordinator), so the counts are the same bits
 * whatever renders the tiles. */
#include "coordinator/adapt.h"

#include <math.h>
#include <stdio.h>
#include <stdlib.h>

#include "base/status.h"

/* The compare metric's offset: relMSE = var / (mean^2 + S_EPS). */
#define S_EPS 0.01

/* Pixel p's mean, channel c (0 where no pass reached it). */
static double s_mean(const pf_accum_t *a, size_t p, int c)
{
    return a->weight[p] ? a->sum[3 * p + c] / (double)a->weight[p] : 0.0;
}

/* Pixel (x, y)'s relative variance per camera sample (the score squared),
 * or -1 where no pass reached it. */
static double s_rel_var(const pf_accum_t *a, int x, int y)
{
    int W = a->width, H = a->height;
    size_t p = (size_t)y * (size_t)W + (size_t)x;
    if (!a->weight[p])
        return -1.0;
    double Wt = (double)a->weight[p], rel = 0.0;
    for (int c = 0; c < 3; c++) {
        double mean = s_mean(a, p, c), nb = 0.0, mu = 0.0;
        int n = 0, m = 0;
        for (int dy = -1; dy <= 1; dy++)
            for (int dx = -1; dx <= 1; dx++) {
                int qx = x + dx, qy = y + dy;
                if (qx < 0 || qy < 0 || qx >= W || qy >= H)
                    continue;
                size_t q = (size_t)qy * (size_t)W + (size_t)qx;
                if (!a->weight[q])
                    continue;
                mu += s_mean(a, q, c);
                m++;
                if (q != p) {
                    nb += s_mean(a, q, c);
                    n++;
                }
            }
        mu /= m;
        double var;
        if (a->passes[p] >= 2) {
            /* accum.c's estimate of one sample's variance */
            double ss = a->sum2[3 * p + c] - Wt * mean * mean;
            var = (ss > 0.0 ? ss : 0.0) / (double)(a->passes[p] - 1);
        } else {
            /* one pass: the difference from the neighbours stands for the
             * noise (it also sees edges and texture, which get more
             * samples than they need, never fewer) */
            double d = n ? mean - nb / n : 0.0;
            var = Wt * d * d;
        }
        rel += var / (mu * mu + S_EPS);
    }
    return rel / 3.0;
}

/* out = the maximum (max != 0) or the mean of in over the 2r + 1 pixels
 * along x (dx = 1) or y, clipped to the image. */
static void s_filter(const double *in, double *out, int W, int H, int r, int along_x, int max)
{
    for (int y = 0; y < H; y++)
        for (int x = 0; x < W; x++) {
            double acc = 0.0;
            int n = 0;
            for (int k = -r; k <= r; k++) {
                int qx = along_x ? x + k : x, qy = along_x ? y : y + k;
                if (qx < 0 || qy < 0 || qx >= W || qy >= H)
                    continue;
                double v = in[(size_t)qy * (size_t)W + (size_t)qx];
                acc = max ? (v > acc ? v : acc) : acc + v;
                n++;
            }
            out[(size_t)y * (size_t)W + (size_t)x] = max ? acc : acc / n;
        }
}

static void s_uniform(uint16_t *counts, size_t n, int spp)
{
    for (size_t p = 0; p < n; p++)
        counts[p] = (uint16_t)(spp > PF_ADAPT_MAX_SPP ? PF_ADAPT_MAX_SPP : spp);
}

void pf_adapt_note(const uint16_t *counts, size_t n, char *buf, size_t len)
{
    if (len)
        buf[0] = 0;
    if (!counts || !n)
        return;
    unsigned lo = counts[0], hi = counts[0];
    for (size_t p = 1; p < n; p++) {
        lo = counts[p] < lo ? counts[p] : lo;
        hi = counts[p] > hi ? counts[p] : hi;
    }
    if (lo < hi) /* a pass of 1 spp has nothing to share */
        snprintf(buf, len, " (adaptive, %u..%u per pixel)", lo, hi);
}

int pf_adapt_counts(const pf_accum_t *acc, int spp, uint16_t *counts)
{
    int W = acc->width, H = acc->height;
    size_t n = (size_t)W * (size_t)H;
    if (spp < 1)
        spp = 1;
    s_uniform(counts, n, spp);
    int floor_n = (spp + 1) / 2;
    if (n == 0 || floor_n >= spp)
        return PF_OK; /* nothing to share */
    double *a = malloc(n * sizeof *a), *b = malloc(n * sizeof *b);
    if (!a || !b) {
        free(a);
        free(b);
        return PF_ENOMEM;
    }
    /* the score: sqrt of the relative variance; unreached pixels get the mean */
    double total = 0.0;
    size_t reached = 0;
    for (int y = 0; y < H; y++)
        for (int x = 0; x < W; x++) {
            double v = s_rel_var(acc, x, y);
            size_t p = (size_t)y * (size_t)W + (size_t)x;
            a[p] = v >= 0.0 && isfinite(v) ? sqrt(v) : -1.0;
            if (a[p] >= 0.0) {
                total += a[p];
                reached++;
            }
        }
    double mean = reached ? total / (double)reached : 0.0;
    for (size_t p = 0; p < n; p++)
        if (a[p] < 0.0)
            a[p] = mean;
    s_filter(a, b, W, H, PF_ADAPT_MAX_R, 1, 1);
    s_filter(b, a, W, H, PF_ADAPT_MAX_R, 0, 1);
    s_filter(a, b, W, H, PF_ADAPT_BLUR_R, 1, 0);
    s_filter(b, a, W, H, PF_ADAPT_BLUR_R, 0, 0);
    total = 0.0;
    for (size_t p = 0; p < n; p++)
        total += a[p];
    double cap = PF_ADAPT_CAP * total / (double)n;
    total = 0.0;
    for (size_t p = 0; p < n; p++) {
        a[p] = a[p] < cap ? a[p] : cap;
        total += a[p];
    }
    if (!(total > 0.0) || !isfinite(total)) {
        free(a);
        free(b);
        return PF_OK;
    }
    /* the shares by cumulative rounding: pixel p takes the samples between
     * floor(R C(p-1) / total) and floor(R C(p) / total), C the running sum
     * of scores, so the counts add up to R exactly */
    double R = (double)n * (double)(spp - floor_n), run = 0.0;
    uint64_t given = 0;
    for (size_t p = 0; p < n; p++) {
        run += a[p];
        double upto = p + 1 == n ? R : floor(R * (run / total));
        uint64_t cum = upto > (double)given ? (uint64_t)upto : given;
        uint64_t c = (uint64_t)floor_n + (cum - given);
        given = cum;
        counts[p] = (uint16_t)(c > PF_ADAPT_MAX_SPP ? PF_ADAPT_MAX_SPP : c);
    }
    free(a);
    free(b);
    return PF_OK;
}
