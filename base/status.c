/* status.c: status-code text, error reports with file and line, and the
 * always-on programmer-error check. Thread-safe: no shared state. */
#include "base/status.h"

#include <stdarg.h>
#include <stdio.h>
#include <stdlib.h>

const char *pf_strerror(int status)
{
    switch (status) {
#define PF_STATUS_CASE(name, value, text) case value: return text;
        PF_STATUS_LIST(PF_STATUS_CASE)
#undef PF_STATUS_CASE
    default: return "unknown error";
    }
}

int pf_error_set(pf_error_t *err, int status, const char *file, int line, const char *fmt, ...)
{
    if (!err)
        return status;
    int n = 0;
    if (file && line > 0)
        n = snprintf(err->msg, sizeof err->msg, "%s:%d: ", file, line);
    else if (file)
        n = snprintf(err->msg, sizeof err->msg, "%s: ", file);
    if (n < 0 || (size_t)n >= sizeof err->msg)
        n = 0;
    va_list ap;
    va_start(ap, fmt);
    vsnprintf(err->msg + n, sizeof err->msg - (size_t)n, fmt, ap);
    va_end(ap);
    return status;
}

void pf_check_failed(const char *expr, const char *file, int line)
{
    fprintf(stderr, "photonfarm: internal check failed: %s (%s:%d)\n", expr, file, line);
    abort();
}
