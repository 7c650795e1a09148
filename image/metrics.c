/* metrics.c: error of a rendered image against a reference - relMSE, RMSE and
 * the ratio of mean luminances - and the box downsampling that brings a
 * larger image to the other's size first. It owns nothing beyond the
 * temporary downsampled copies and mask inside pf_metrics_compare_opts.
 *
 * The mask (--mask-above in `photonfarm compare`) is taken from the
 * reference at its own resolution, before any downsampling: the visible
 * lights are a few pixels far above everything else, and a block averaged
 * over them would hide them below the threshold while still dominating the
 * block's error. So a compared pixel is left out when any reference pixel
 * that fed it is above the threshold.
 *
 * Numerics: every sum is taken in double with Neumaier's compensation, so the
 * error of a sum over n terms stays near one rounding of the result instead
 * of growing with n (n is 3 * 2^28 at the size limit). Non-finite values in
 * the image make relMSE and RMSE infinite on purpose: a NaN must never make a
 * render look good, and IEEE arithmetic alone would yield NaN, which compares
 * false against every bound. A non-finite reference is rejected as bad input.
 *
 * No shared state: any thread may call these functions. */
#include "image/metrics.h"

#include <limits.h>
#include <math.h>
#include <stddef.h>
#include <stdlib.h>
#include <string.h>

/* Neumaier's variant of Kahan summation: it also stays exact when a term is
 * larger in magnitude than the running sum. */
typedef struct s_acc {
    double sum, comp;
} s_acc_t;

static inline void s_acc_add(s_acc_t *acc, double x)
{
    double t = acc->sum + x;
    if (fabs(acc->sum) >= fabs(x))
        acc->comp += (acc->sum - t) + x;
    else
        acc->comp += (x - t) + acc->sum;
    acc->sum = t;
}

static inline double s_acc_total(const s_acc_t *acc) { return acc->sum + acc->comp; }

/* Rec. 709 / sRGB primaries, the colour space of the references. */
double pf_rgb_luminance(const float *rgb)
{
    return 0.2126 * (double)rgb[0] + 0.7152 * (double)rgb[1] + 0.0722 * (double)rgb[2];
}

/* Box-downsamples src by factor (>= 1; both dimensions must be multiples of
 * it) into dst, which is allocated here and must be freed by the caller; each
 * output channel is the mean of factor x factor input values, summed in
 * double. NaN and infinities propagate into the block they fall in. Returns
 * 0, PF_EINVAL (bad factor or empty source) or PF_ENOMEM; on failure dst is
 * left empty. */
int pf_image_downsample(const pf_image_t *src, int factor, pf_image_t *dst)
{
    PF_CHECK(src != NULL && dst != NULL);
    dst->width = 0;
    dst->height = 0;
    dst->rgb = NULL;
    if (!src->rgb || src->width <= 0 || src->height <= 0 || factor < 1 || src->width % factor != 0
        || src->height % factor != 0)
        return PF_EINVAL;
    int st = pf_image_alloc(dst, src->width / factor, src->height / factor);
    if (st < 0)
        return st;

    const size_t sw = (size_t)src->width, f = (size_t)factor;
    const double inv = 1.0 / ((double)f * (double)f);
    for (size_t y = 0; y < (size_t)dst->height; y++) {
        for (size_t x = 0; x < (size_t)dst->width; x++) {
            s_acc_t acc[3] = { { 0, 0 }, { 0, 0 }, { 0, 0 } };
            for (size_t j = 0; j < f; j++) {
                const float *p = src->rgb + ((y * f + j) * sw + x * f) * 3;
                for (size_t i = 0; i < f * 3; i += 3) {
                    s_acc_add(&acc[0], (double)p[i]);
                    s_acc_add(&acc[1], (double)p[i + 1]);
                    s_acc_add(&acc[2], (double)p[i + 2]);
                }
            }
            float *q = dst->rgb + (y * (size_t)dst->width + x) * 3;
            for (int c = 0; c < 3; c++)
                q[c] = (float)(s_acc_total(&acc[c]) * inv);
        }
    }
    return PF_OK;
}

/* The factor by which big is an integer multiple of small in both
 * dimensions (the same factor in x and y), or 0 when it is not. */
static int s_factor(const pf_image_t *big, const pf_image_t *small)
{
    if (big->width % small->width != 0 || big->height % small->height != 0)
        return 0;
    int f = big->width / small->width;
    return f >= 1 && big->height / small->height == f ? f : 0;
}

/* Compares image a with reference b and fills out (no options). */
int pf_metrics_compare(const pf_image_t *a, const pf_image_t *b, pf_metrics_t *out, pf_error_t *err)
{
    return pf_metrics_compare_opts(a, b, NULL, out, err);
}

/* The mask on the compared grid (w x h, a divisor of ref's size by the same
 * factor f in x and y): a pixel is set when one of the f x f reference
 * pixels it covers has luminance above limit. *mask is allocated here (NULL
 * and 0 masked when limit masks nothing). Returns 0 or PF_ENOMEM. */
static int s_mask(const pf_image_t *ref, int w, int h, double limit, unsigned char **mask, size_t *count)
{
    *mask = NULL;
    *count = 0;
    if (isnan(limit) || limit == INFINITY)
        return PF_OK;
    unsigned char *m = calloc((size_t)w * (size_t)h, 1);
    if (!m)
        return PF_ENOMEM;
    const size_t f = (size_t)(ref->width / w), rw = (size_t)ref->width;
    for (size_t y = 0; y < (size_t)ref->height; y++) {
        for (size_t x = 0; x < rw; x++) {
            if (pf_rgb_luminance(ref->rgb + (y * rw + x) * 3) > limit)
                m[(y / f) * (size_t)w + x / f] = 1;
        }
    }
    for (size_t i = 0; i < (size_t)w * (size_t)h; i++)
        *count += m[i];
    *mask = m;
    return PF_OK;
}

/* The figures over the pixels of ia against ib (out->width x out->height)
 * that mask (may be NULL) leaves in. */
static void s_figures(const pf_image_t *ia, const pf_image_t *ib, const unsigned char *mask, pf_metrics_t *out)
{
    s_acc_t rel = { 0, 0 }, sq = { 0, 0 }, lum_a = { 0, 0 }, lum_b = { 0, 0 };
    const size_t pixels = (size_t)out->width * (size_t)out->height;
    size_t kept = 0;
    for (size_t i = 0; i < pixels; i++) {
        if (mask && mask[i])
            continue;
        const float *pa = ia->rgb + i * 3, *pb = ib->rgb + i * 3;
        for (int c = 0; c < 3; c++) {
            double va = (double)pa[c], vb = (double)pb[c];
            double d2 = (va - vb) * (va - vb);
            s_acc_add(&rel, d2 / (vb * vb + 0.01));
            s_acc_add(&sq, d2);
        }
        s_acc_add(&lum_a, pf_rgb_luminance(pa));
        s_acc_add(&lum_b, pf_rgb_luminance(pb));
        kept++;
    }
    /* With every pixel masked, 0 / 0 gives NAN: no figure, not a perfect one. */
    const double n = 3.0 * (double)kept;
    out->relmse = s_acc_total(&rel) / n;
    out->rmse = sqrt(s_acc_total(&sq) / n);
    /* The pixel count cancels in the ratio of means; 0 / 0 gives NAN. */
    out->lum_ratio = s_acc_total(&lum_a) / s_acc_total(&lum_b);
}

/* Compares image a with reference b and fills out. Equal sizes compare
 * directly; otherwise the larger image is box-downsampled by the integer
 * factor that maps it onto the smaller (out->factor_a / factor_b record
 * which), then both by opts->downsample. relMSE divides by b^2 + 0.01, so b
 * must be the reference.
 *
 * Non-finite values in a set relmse and rmse to INFINITY and lum_ratio to NAN
 * (callers count them with pf_image_count_bad to say how many); out->masked
 * is filled all the same. A reference with zero mean luminance gives
 * lum_ratio +-INFINITY, or NAN when a's is zero too. Returns 0; PF_ESIZE when
 * the sizes do not fit or the downsampling factor does not divide them;
 * PF_ERANGE when the reference holds NaN or infinities; PF_EINVAL for an
 * empty image; PF_ENOMEM. err, when given, receives a message naming the
 * sizes or the problem. */
int pf_metrics_compare_opts(const pf_image_t *a, const pf_image_t *b, const pf_metrics_opts_t *opts,
                            pf_metrics_t *out, pf_error_t *err)
{
    PF_CHECK(a != NULL && b != NULL && out != NULL);
    if (!a->rgb || a->width <= 0 || a->height <= 0 || !b->rgb || b->width <= 0 || b->height <= 0)
        return pf_error_set(err, PF_EINVAL, NULL, 0, "cannot compare an empty image");

    int fa = 1, fb = 1;
    if (a->width != b->width || a->height != b->height) {
        if ((fa = s_factor(a, b)) > 0)
            fb = 1;
        else if ((fb = s_factor(b, a)) > 0)
            fa = 1;
        else
            return pf_error_set(err, PF_ESIZE, NULL, 0,
                                "image is %dx%d and reference %dx%d: sizes must be equal or differ by the "
                                "same integer factor in both dimensions",
                                a->width, a->height, b->width, b->height);
    }
    const int fw = a->width / fa, fh = a->height / fa;
    const int ds = opts && opts->downsample != 0 ? opts->downsample : 1;
    if (ds < 1 || fw % ds != 0 || fh % ds != 0)
        return pf_error_set(err, PF_ESIZE, NULL, 0,
                            "cannot downsample %dx%d by %d: the factor must be at least 1 and divide both sizes",
                            fw, fh, ds);

    size_t ref_bad = pf_image_count_bad(b, NULL);
    if (ref_bad > 0)
        return pf_error_set(err, PF_ERANGE, NULL, 0, "reference has %zu non-finite values (NaN or infinity)",
                            ref_bad);

    out->factor_a = fa;
    out->factor_b = fb;
    out->downsample = ds;
    out->width = fw / ds;
    out->height = fh / ds;
    unsigned char *mask = NULL;
    int st = s_mask(b, out->width, out->height, opts ? opts->mask_above : NAN, &mask, &out->masked);
    if (st < 0)
        return pf_error_set(err, st, NULL, 0, "cannot build the mask: %s", pf_strerror(st));
    if (pf_image_count_bad(a, NULL) > 0) {
        free(mask);
        out->relmse = INFINITY;
        out->rmse = INFINITY;
        out->lum_ratio = NAN;
        return PF_OK;
    }

    /* One box of fa * ds (fb * ds) equals the two in turn, with one rounding. */
    pf_image_t da = { 0, 0, NULL }, db = { 0, 0, NULL };
    const pf_image_t *ia = a, *ib = b;
    if (fa * ds > 1 && (st = pf_image_downsample(a, fa * ds, &da)) == PF_OK)
        ia = &da;
    if (st == PF_OK && fb * ds > 1 && (st = pf_image_downsample(b, fb * ds, &db)) == PF_OK)
        ib = &db;
    if (st < 0) {
        free(mask);
        pf_image_free(&da);
        pf_image_free(&db);
        return pf_error_set(err, st, NULL, 0, "cannot downsample for comparison: %s", pf_strerror(st));
    }
    s_figures(ia, ib, mask, out);
    free(mask);
    pf_image_free(&da);
    pf_image_free(&db);
    return PF_OK;
}

/* Places a and b side by side with a white gap (see metrics.h). */
int pf_image_side_by_side(const pf_image_t *a, const pf_image_t *b, int gap, pf_image_t *dst)
{
    PF_CHECK(a != NULL && b != NULL && dst != NULL);
    dst->width = 0;
    dst->height = 0;
    dst->rgb = NULL;
    if (!a->rgb || !b->rgb || a->width <= 0 || a->height <= 0 || a->width != b->width || a->height != b->height
        || gap < 0 || a->width > (INT_MAX - gap) / 2)
        return PF_EINVAL;
    int st = pf_image_alloc(dst, 2 * a->width + gap, a->height);
    if (st < 0)
        return st;
    const size_t w = (size_t)a->width, dw = (size_t)dst->width;
    for (size_t y = 0; y < (size_t)a->height; y++) {
        float *row = dst->rgb + y * dw * 3;
        memcpy(row, a->rgb + y * w * 3, w * 3 * sizeof(float));
        for (size_t i = w * 3; i < (w + (size_t)gap) * 3; i++)
            row[i] = 1e6f;
        memcpy(row + (w + (size_t)gap) * 3, b->rgb + y * w * 3, w * 3 * sizeof(float));
    }
    return PF_OK;
}
