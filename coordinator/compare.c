/* compare.c: the `photonfarm compare IMAGE REFERENCE [--json]` subcommand.
 * It reads two images (PFM, or OpenEXR by the .exr extension), measures the
 * image against the reference with pf_metrics_compare (downsampling the larger by an integer factor when the
 * sizes differ) and prints the result as a small table or, for scripts, as
 * one line of JSON. The exit code tells scripts what went wrong without
 * parsing stderr. Runs on the main thread of a short-lived process; owns only
 * the two images it reads. */
#include "coordinator/compare.h"

#include <math.h>
#include <stdio.h>
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

static void s_usage(FILE *out)
{
    fputs("usage: photonfarm compare IMAGE REFERENCE [--json]\n"
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
          "             nonfinite (non-finite numbers are printed as null)\n"
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

int pf_cli_compare(int argc, char **argv)
{
    const char *paths[2] = { NULL, NULL };
    int npaths = 0, json = 0, options_done = 0;
    for (int i = 1; i < argc; i++) {
        const char *arg = argv[i];
        if (!options_done && arg[0] == '-' && arg[1] != '\0') {
            if (strcmp(arg, "--help") == 0 || strcmp(arg, "-h") == 0) {
                s_usage(stdout);
                return S_EXIT_OK;
            } else if (strcmp(arg, "--json") == 0) {
                json = 1;
            } else if (strcmp(arg, "--") == 0) {
                options_done = 1;
            } else {
                fprintf(stderr, "photonfarm compare: unknown option '%s'\n", arg);
                s_usage(stderr);
                return S_EXIT_USAGE;
            }
        } else if (npaths < 2) {
            paths[npaths++] = arg;
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

    pf_image_t img = { 0, 0, NULL }, ref = { 0, 0, NULL };
    pf_error_t err;
    int st = pf_image_read_hdr(&img, paths[0], &err);
    if (st == PF_OK)
        st = pf_image_read_hdr(&ref, paths[1], &err);
    if (st < 0) {
        /* The reader's message already begins with the file name. */
        fprintf(stderr, "photonfarm compare: %s\n", err.msg);
        pf_image_free(&img);
        return st == PF_ENOMEM ? S_EXIT_FAIL : S_EXIT_INPUT;
    }

    size_t negative = 0;
    size_t nonfinite = pf_image_count_bad(&img, &negative);
    pf_metrics_t m;
    st = pf_metrics_compare(&img, &ref, &m, &err);
    int code = S_EXIT_OK;
    if (st == PF_ESIZE) {
        fprintf(stderr, "photonfarm compare: %s and %s: %s\n", paths[0], paths[1], err.msg);
        code = S_EXIT_SIZE;
    } else if (st == PF_ERANGE) {
        fprintf(stderr, "photonfarm compare: %s: %s\n", paths[1], err.msg);
        code = S_EXIT_INPUT;
    } else if (st < 0) {
        fprintf(stderr, "photonfarm compare: %s\n", err.msg);
        code = st == PF_ENOMEM ? S_EXIT_FAIL : S_EXIT_INPUT;
    } else {
        if (nonfinite > 0)
            fprintf(stderr, "photonfarm compare: %s: %zu non-finite values (NaN or infinity); "
                    "relMSE and RMSE are infinite\n", paths[0], nonfinite);
        if (negative > 0)
            fprintf(stderr, "photonfarm compare: %s: note: %zu negative values\n", paths[0], negative);
        if (json) {
            printf("{");
            s_json_number(stdout, "relmse", m.relmse, 0);
            s_json_number(stdout, "rmse", m.rmse, 0);
            s_json_number(stdout, "lum_ratio", m.lum_ratio, 0);
            printf("\"width\":%d,\"height\":%d,\"nonfinite\":%zu}\n", m.width, m.height, nonfinite);
        } else {
            s_describe("image", paths[0], &img, m.factor_a, &m);
            s_describe("reference", paths[1], &ref, m.factor_b, &m);
            printf("%-10s %.6g\n", "relMSE", m.relmse);
            printf("%-10s %.6g\n", "RMSE", m.rmse);
            printf("%-10s %.6g (image / reference)\n", "luminance", m.lum_ratio);
        }
        if (fflush(stdout) != 0) {
            fprintf(stderr, "photonfarm compare: cannot write to standard output\n");
            code = S_EXIT_FAIL;
        }
    }
    pf_image_free(&img);
    pf_image_free(&ref);
    return code;
}
