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

/* The escaped form of byte c in esc (at least 5 bytes); its length. */
static size_t s_printable_byte(unsigned char c, char esc[8])
{
    if (c < 0x20 || c >= 0x7f)
        return (size_t)snprintf(esc, 8, "\\x%02x", (unsigned)c);
    if (c == '\\')
        return (size_t)snprintf(esc, 8, "\\\\");
    esc[0] = (char)c;
    esc[1] = '\0';
    return 1;
}

char *pf_log_printable(char *dst, unsigned long cap, const char *src)
{
    if (!dst || cap == 0)
        return dst;
    if (!src)
        src = "(null)";
    const unsigned char *p = (const unsigned char *)src;
    char esc[8];
    size_t total = 0;
    for (const unsigned char *q = p; *q; q++)
        total += s_printable_byte(*q, esc);
    /* When all of it does not fit, room is kept for "..." and escapes are
     * never cut in half (a cap under 5 leaves no room for the dots). */
    size_t room = total + 1 <= cap ? cap - 1 : (cap > 4 ? cap - 4 : cap - 1);
    size_t n = 0;
    for (; *p; p++) {
        size_t k = s_printable_byte(*p, esc);
        if (n + k > room)
            break;
        memcpy(dst + n, esc, k);
        n += k;
    }
    if (*p && cap > 4) {
        memcpy(dst + n, "...", 3);
        n += 3;
    }
    dst[n] = '\0';
    return dst;
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
