/* compare.h: the `photonfarm compare` subcommand - error metrics of a
 * rendered PFM against a reference PFM, for people and for scripts. */
#ifndef PF_COMPARE_H
#define PF_COMPARE_H

/* Runs `photonfarm compare IMAGE REFERENCE [--json] [--downsample N]
 * [--mask-above Y] [--pair FILE.png [--exposure STOPS]]`; argv[0] is
 * "compare". Reads both images, box-downsamples the larger by an integer
 * factor when the sizes differ (then both by N), leaves out the pixels whose
 * reference luminance exceeds Y, and prints relMSE, RMSE and the
 * mean-luminance ratio to stdout (a table, or one JSON object with --json;
 * the masked count only with --mask-above); --pair also writes both images
 * side by side as a PNG. --help / -h prints usage
 * to stdout. Errors go to stderr and name the file. Returns the process exit
 * code: 0 success, 2 usage error, 3 unreadable or malformed input file
 * (including a reference with NaN or infinities), 4 sizes do not fit (or N
 * does not divide them, or N < 1), 1 out
 * of memory or stdout cannot be written. Blocks on file I/O only; not reentrant with respect to stdout. */
int pf_cli_compare(int argc, char **argv);

#endif
