/* check.h: the one assertion macro of the C tests. CHECK(cond) or
 * CHECK(cond, "format", args...) counts a pass or prints a failure with file,
 * line, the condition and the message (the first 40 failures; the rest are
 * counted); pf_test_finish() prints the closing "N passed, M failed" line and
 * returns the exit status; pf_test_failures() is the count so far.
 *
 * A test program of one file includes it once, as it is. A program of
 * several files defines PF_CHECK_SHARED before including it in every file,
 * and PF_CHECK_MAIN as well in exactly one of them: that file holds the
 * counts, and the closing line counts the whole program. */
#ifndef PF_TEST_CHECK_H
#define PF_TEST_CHECK_H

#include <stdarg.h>
#include <stdio.h>

#if defined(PF_CHECK_SHARED) && !defined(PF_CHECK_MAIN)

void pf_check_(int ok, const char *cond, const char *file, int line, const char *fmt, ...)
    __attribute__((format(printf, 5, 6)));
int pf_test_finish(void);
int pf_test_failures(void);

#else

#ifdef PF_CHECK_SHARED
#define PF_CHECK_LINKAGE
void pf_check_(int ok, const char *cond, const char *file, int line, const char *fmt, ...)
    __attribute__((format(printf, 5, 6)));
int pf_test_finish(void);
int pf_test_failures(void);
#else
#define PF_CHECK_LINKAGE static
#endif

static int s_passed, s_failed;

PF_CHECK_LINKAGE void __attribute__((format(printf, 5, 6), unused))
pf_check_(int ok, const char *cond, const char *file, int line, const char *fmt, ...)
{
    if (ok) {
        s_passed++;
        return;
    }
    if (s_failed++ >= 40)
        return;
    printf("FAIL %s:%d: %s", file, line, cond);
    if (fmt[1]) { /* fmt is " " followed by the caller's format, if any */
        va_list ap;
        va_start(ap, fmt);
        printf(":");
        vprintf(fmt, ap);
        va_end(ap);
    }
    printf("\n");
    fflush(stdout);
}

PF_CHECK_LINKAGE int __attribute__((unused)) pf_test_finish(void)
{
    printf("%d passed, %d failed\n", s_passed, s_failed);
    return s_failed ? 1 : 0;
}

PF_CHECK_LINKAGE int __attribute__((unused)) pf_test_failures(void) { return s_failed; }

#endif

#define CHECK(cond, ...) pf_check_(!!(cond), #cond, __FILE__, __LINE__, " " __VA_ARGS__)

#endif
