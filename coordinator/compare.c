/* compare.c: the `photonfarm compare IMAGE REFERENCE [--json]` subcommand.
 * It reads two images (PFM, or OpenEXR by the .exr extension), measures the
 * image against the reference with pf_metrics_compare (downsampling the larger by an integer factor when the
 * sizes differ) and prints the result as a small table or, for scripts, as
 * one line of JSON. Options for the real-scene benchmarks (bench/realscenes.py):
 * --downsample N compares after a further N x N box downsample, --mask-above Y
 * leaves out the pixels whose reference luminance exceeds Y (the visible
 * lights, as the Bitterli references are judged), --pair FILE writes the two
 * images side by side as a PNG. Without them the output is unchanged, since
 * scripts parse it. The exit code tells scripts what went wrong without
 * parsing stderr. Runs on the main thread of a short-lived process; owns only
 * the images it reads and builds. */
#include "coordinator/compare.h"

#include <errno.h>
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "image/image.h"
#include "image/metrics.h"

enum {
    S_EXIT_OK = 0,
    S_EXIT_FAIL = 1,  /* out of memory, or stdout cannot be written */
    S_EXIT_USAGE = 2, /* bad command line */
    S_EXIT_INPUT = 3, /* unreadable or malformed input file */
    S_EXIT_SIZE = 4,  /* image sizes do not fit */
};

/* Columns of white between the two halves of a --pair picture. */
#define S_PAIR_GAP 8

/* The parsed command line. */
typedef struct s_args {
    const char *paths[2];
    int json;
    int downsample;    /* 1: none */
    double mask_above; /* NAN: no mask */
    const char *pair;  /* NULL: no picture */
    float exposure;
} s_args_t;

static void s_usage(FILE *out)
{
    fputs("usage: photonfarm compare IMAGE REFERENCE [--json] [--downsample N] [--mask-above Y]\n"
          "                          [--pair FILE.png [--exposure STOPS]]\n"
          "\n"
          "Measures IMAGE against REFERENCE (PFM, or OpenEXR for .exr). When the sizes differ by the\n"
          "same integer factor in x and y, the larger is box-downsampled first.\n"
          "\n"
          "  relMSE     mean over pixels and channels of (a-b)^2 / (b^2 + 0.01)\n"
          "  RMSE       square root of the mean of (a-b)^2\n"
          "  luminance  mean luminance of IMAGE / mean luminance of REFERENCE\n"
          "\n"
          "NaN or infinite values in IMAGE make relMSE and RMSE infinite.\n"
          "\n"
          "options:\n"
          "  --json     print one JSON object: relmse, rmse, lum_ratio, width, height,\n"
          "             nonfinite (non-finite numbers are printed as null); masked with\n"
          "             --mask-above\n"
          "  --downsample N\n"
          "             after the size fitting, box-downsample both images by N (N >= 1 must\n"
          "             divide both sizes, else exit 4)\n"
          "  --mask-above Y\n"
          "             leave out of every figure the pixels whose reference luminance\n"
          "             (0.2126 R + 0.7152 G + 0.0722 B, at the reference's own resolution)\n"
          "             exceeds Y, e.g. the visible lights; with --downsample a pixel is left\n"
          "             out when any of its source pixels is; prints how many were masked\n"
          "  --pair FILE.png\n"
          "             write IMAGE (left) and REFERENCE (right) side by side, at the fitted size,\n"
          "             same exposure, 8-bit sRGB, 8 white columns between\n"
          "  --exposure STOPS\n"
          "             exposure of the --pair picture (default 0)\n"
          "  -h, --help print this help\n"
          "\n"
          "exit codes: 0 success, 1 out of memory or output error, 2 usage error,\n"
          "3 unreadable or malformed input file, 4 image sizes do not fit\n",
          out);
}

/* A JSON number, or null for NaN and infinities, which JSON cannot carry. */
static void s_json_number(FILE *out, const char *key, double v, int last)
{
    if (isfinite(v))
        fprintf(out, "\"%s\":%.17g%s", key, v, last ? "" : ",");
    else
        fprintf(out, "\"%s\":null%s", key, last ? "" : ",");
}

/* One table line describing an input: its size, and the downsampling applied. */
static void s_describe(const char *label, const char *path, const pf_image_t *img, int factor,
                       const pf_metrics_t *m)
{
    if (factor > 1)
        printf("%-10s %s (%dx%d, downsampled x%d to %dx%d)\n", label, path, img->width, img->height, factor,
               m->width, m->height);
    else
        printf("%-10s %s (%dx%d)\n", label, path, img->width, img->height);
}

/* A number option's value: whole string, finite. Returns 0 or -1. */
static int s_number(const char *text, double *v)
{
    char *end;
    errno = 0;
    double d = strtod(text, &end);
    if (end == text || *end != '\0' || errno != 0 || !isfinite(d))
        return -1;
    *v = d;
    return 0;
}

/* Parses argv into a. Returns -1 to go on, else the exit code to return
 * (0 after --help, 2 after a usage error, reported here). */
static int s_parse(int argc, char **argv, s_args_t *a)
{
    *a = (s_args_t){ { NULL, NULL }, 0, 1, NAN, NULL, 0.0f };
    int npaths = 0, options_done = 0;
    for (int i = 1; i < argc; i++) {
        const char *arg = argv[i];
        if (!options_done && arg[0] == '-' && arg[1] != '\0') {
            const int valued = strcmp(arg, "--downsample") == 0 || strcmp(arg, "--mask-above") == 0
                               || strcmp(arg, "--pair") == 0 || strcmp(arg, "--exposure") == 0;
            double v = 0;
            if (strcmp(arg, "--help") == 0 || strcmp(arg, "-h") == 0) {
                s_usage(stdout);
                return S_EXIT_OK;
            } else if (strcmp(arg, "--json") == 0) {
                a->json = 1;
            } else if (strcmp(arg, "--") == 0) {
                options_done = 1;
            } else if (valued && i + 1 >= argc) {
                fprintf(stderr, "photonfarm compare: %s needs a value\n", arg);
                return S_EXIT_USAGE;
            } else if (strcmp(arg, "--pair") == 0) {
                a->pair = argv[++i];
            } else if (valued && s_number(argv[i + 1], &v) < 0) {
                fprintf(stderr, "photonfarm compare: %s: '%s' is not a finite number\n", arg, argv[i + 1]);
                return S_EXIT_USAGE;
            } else if (strcmp(arg, "--downsample") == 0) {
                i++;
                /* A bad factor is a size problem (exit 4), as a misfit image size is. */
                if (v != floor(v) || v < 1 || v > 1e9) {
                    fprintf(stderr, "photonfarm compare: --downsample: '%s' is not a whole number >= 1\n",
                            argv[i]);
                    return S_EXIT_SIZE;
                }
                a->downsample = (int)v;
            } else if (strcmp(arg, "--mask-above") == 0) {
                i++;
                a->mask_above = v;
            } else if (strcmp(arg, "--exposure") == 0) {
                i++;
                a->exposure = (float)v;
            } else {
                fprintf(stderr, "photonfarm compare: unknown option '%s'\n", arg);
                s_usage(stderr);
                return S_EXIT_USAGE;
            }
        } else if (npaths < 2) {
            a->paths[npaths++] = arg;
        } else {
            fprintf(stderr, "photonfarm compare: unexpected argument '%s' (takes IMAGE and REFERENCE)\n", arg);
            s_usage(stderr);
            return S_EXIT_USAGE;
        }
    }
    if (npaths != 2) {
        fprintf(stderr, "photonfarm compare: expected IMAGE and REFERENCE\n");
        s_usage(stderr);
        return S_EXIT_USAGE;
    }
    return -1;
}

/* Writes the --pair picture: both images at the fitted size (the larger
 * box-downsampled by m's factor), side by side. Returns an exit code. */
static int s_write_pair(const s_args_t *a, const pf_image_t *img, const pf_image_t *ref, const pf_metrics_t *m)
{
    pf_image_t da = { 0, 0, NULL }, db = { 0, 0, NULL }, pair = { 0, 0, NULL };
    const pf_image_t *ia = img, *ib = ref;
    pf_error_t err;
    int st = PF_OK;
    if (m->factor_a > 1 && (st = pf_image_downsample(img, m->factor_a, &da)) == PF_OK)
        ia = &da;
    if (st == PF_OK && m->factor_b > 1 && (st = pf_image_downsample(ref, m->factor_b, &db)) == PF_OK)
        ib = &db;
    if (st == PF_OK)
        st = pf_image_side_by_side(ia, ib, S_PAIR_GAP, &pair);
    int code = S_EXIT_OK;
    if (st < 0) {
        fprintf(stderr, "photonfarm compare: cannot build the pair picture: %s\n", pf_strerror(st));
        code = S_EXIT_FAIL;
    } else if (pf_image_write_png(&pair, a->pair, a->exposure, &err) < 0) {
        fprintf(stderr, "photonfarm compare: %s\n", err.msg);
        code = S_EXIT_FAIL;
    }
    pf_image_free(&da);
    pf_image_free(&db);
    pf_image_free(&pair);
    return code;
}

/* Prints the figures as the table or the JSON line. */
static void s_print(const s_args_t *a, const pf_image_t *img, const pf_image_t *ref, const pf_metrics_t *m,
                    size_t nonfinite)
{
    const int masking = !isnan(a->mask_above);
    if (a->json) {
        printf("{");
        s_json_number(stdout, "relmse", m->relmse, 0);
        s_json_number(stdout, "rmse", m->rmse, 0);
        s_json_number(stdout, "lum_ratio", m->lum_ratio, 0);
        printf("\"width\":%d,\"height\":%d,\"nonfinite\":%zu", m->width, m->height, nonfinite);
        if (masking)
            printf(",\"masked\":%zu", m->masked);
        printf("}\n");
        return;
    }
    /* The inputs' lines describe the size fitting only; --downsample gets its own line. */
    pf_metrics_t fit = *m;
    fit.width *= m->downsample;
    fit.height *= m->downsample;
    s_describe("image", a->paths[0], img, m->factor_a, &fit);
    s_describe("reference", a->paths[1], ref, m->factor_b, &fit);
    if (m->downsample > 1)
        printf("%-10s %dx%d (both downsampled x%d)\n", "compared", m->width, m->height, m->downsample);
    if (masking)
        printf("%-10s %zu of %zu pixels (reference luminance > %g)\n", "masked", m->masked,
               (size_t)m->width * (size_t)m->height, a->mask_above);
    printf("%-10s %.6g\n", "relMSE", m->relmse);
    printf("%-10s %.6g\n", "RMSE", m->rmse);
    printf("%-10s %.6g (image / reference)\n", "luminance", m->lum_ratio);
}

int pf_cli_compare(int argc, char **argv)
{
    s_args_t a;
    int code = s_parse(argc, argv, &a);
    if (code >= 0)
        return code;

    pf_image_t img = { 0, 0, NULL }, ref = { 0, 0, NULL };
    pf_error_t err;
    int st = pf_image_read_hdr(&img, a.paths[0], &err);
    if (st == PF_OK)
        st = pf_image_read_hdr(&ref, a.paths[1], &err);
    if (st < 0) {
        /* The reader's message already begins with the file name. */
        fprintf(stderr, "photonfarm compare: %s\n", err.msg);
        pf_image_free(&img);
        return st == PF_ENOMEM ? S_EXIT_FAIL : S_EXIT_INPUT;
    }

    size_t negative = 0;
    size_t nonfinite = pf_image_count_bad(&img, &negative);
    pf_metrics_t m;
    const pf_metrics_opts_t opts = { a.downsample, a.mask_above };
    st = pf_metrics_compare_opts(&img, &ref, &opts, &m, &err);
    code = S_EXIT_OK;
    if (st == PF_ESIZE) {
        fprintf(stderr, "photonfarm compare: %s and %s: %s\n", a.paths[0], a.paths[1], err.msg);
        code = S_EXIT_SIZE;
    } else if (st == PF_ERANGE) {
        fprintf(stderr, "photonfarm compare: %s: %s\n", a.paths[1], err.msg);
        code = S_EXIT_INPUT;
    } else if (st < 0) {
        fprintf(stderr, "photonfarm compare: %s\n", err.msg);
        code = st == PF_ENOMEM ? S_EXIT_FAIL : S_EXIT_INPUT;
    } else {
        if (nonfinite > 0)
            fprintf(stderr, "photonfarm compare: %s: %zu non-finite values (NaN or infinity); "
                    "relMSE and RMSE are infinite\n", a.paths[0], nonfinite);
        if (negative > 0)
            fprintf(stderr, "photonfarm compare: %s: note: %zu negative values\n", a.paths[0], negative);
        s_print(&a, &img, &ref, &m, nonfinite);
        if (fflush(stdout) != 0) {
            fprintf(stderr, "photonfarm compare: cannot write to standard output\n");
            code = S_EXIT_FAIL;
        }
        if (code == S_EXIT_OK && a.pair)
            code = s_write_pair(&a, &img, &ref, &m);
    }
    pf_image_free(&img);
    pf_image_free(&ref);
    return code;
}
