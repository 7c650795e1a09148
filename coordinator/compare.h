/* compare.h: the `photonfarm compare` subcommand - error metrics of a
 * rendered PFM against a reference PFM, for people and for scripts. */
#ifndef PF_COMPARE_H
#define PF_COMPARE_H

/* Runs `photonfarm compare IMAGE REFERENCE [--json]`; argv[0] is "compare".
 * Reads both PFMs, box-downsamples the larger by an integer factor when the
 * sizes differ, and prints relMSE, RMSE and the mean-luminance ratio to
 * stdout (a table, or one JSON object with --json). --help / -h prints usage
 * to stdout. Errors go to stderr and name the file. Returns the process exit
 * code: 0 success, 2 usage error, 3 unreadable or malformed input file
 * (including a reference with NaN or infinities), 4 sizes do not fit, 1 out
 * of memory or stdout cannot be written. Blocks on file I/O only; not reentrant with respect to stdout. */
int pf_cli_compare(int argc, char **argv);

#endif
