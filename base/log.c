/* log.c: leveled logging to stderr; see log.h. The level is process-wide and
 * set once at start-up; each message is formatted into one buffer and written
 * with one call so lines from threads do not interleave. */
#include "base/log.h"

#include <stdarg.h>
#include <stdio.h>
#include <string.h>
#include <time.h>
#include <unistd.h>

static pf_log_level s_level = PF_LOG_INFO;

void pf_log_set_level(pf_log_level level) { s_level = level; }
pf_log_level pf_log_get_level(void) { return s_level; }

double pf_now(void)
{
    struct timespec ts;
    clock_gettime(CLOCK_MONOTONIC, &ts);
    return (double)ts.tv_sec + 1e-9 * (double)ts.tv_nsec;
}

void pf_log(pf_log_level level, const char *fmt, ...)
{
    if (level < s_level)
        return;
    static const char *names[] = { "debug", "info", "warning", "error" };
    char line[2048];
    int n = 0;
    if (isatty(STDERR_FILENO)) {
        /* Clear a progress line that may be drawn; it redraws on its next update. */
        n = snprintf(line, sizeof line, "\r\033[K");
    } else {
        struct timespec ts;
        clock_gettime(CLOCK_REALTIME, &ts);
        struct tm tm;
        gmtime_r(&ts.tv_sec, &tm);
        n = snprintf(line, sizeof line, "%04d-%02d-%02dT%02d:%02d:%02d.%03ldZ ", tm.tm_year + 1900,
                     tm.tm_mon + 1, tm.tm_mday, tm.tm_hour, tm.tm_min, tm.tm_sec, ts.tv_nsec / 1000000);
    }
    if (level != PF_LOG_INFO)
        n += snprintf(line + n, sizeof line - (size_t)n, "%s: ", names[level]);
    va_list ap;
    va_start(ap, fmt);
    int m = vsnprintf(line + n, sizeof line - (size_t)n - 1, fmt, ap);
    va_end(ap);
    size_t len = (size_t)n + (m < 0 ? 0 : (size_t)m);
    if (len > sizeof line - 2)
        len = sizeof line - 2;
    line[len++] = '\n';
    fwrite(line, 1, len, stderr);
}
