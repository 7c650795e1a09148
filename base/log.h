/* log.h: leveled logging to stderr. On a terminal lines are plain; otherwise
 * each line carries a UTC timestamp. Thread-safe (one write per line). */
#ifndef PF_LOG_H
#define PF_LOG_H

typedef enum { PF_LOG_DEBUG, PF_LOG_INFO, PF_LOG_WARN, PF_LOG_ERROR, PF_LOG_QUIET } pf_log_level;

void pf_log_set_level(pf_log_level level);
pf_log_level pf_log_get_level(void);
void pf_log(pf_log_level level, const char *fmt, ...) __attribute__((format(printf, 2, 3)));

#define pf_debug(...) pf_log(PF_LOG_DEBUG, __VA_ARGS__)
#define pf_info(...)  pf_log(PF_LOG_INFO, __VA_ARGS__)
#define pf_warn(...)  pf_log(PF_LOG_WARN, __VA_ARGS__)
#define pf_error(...) pf_log(PF_LOG_ERROR, __VA_ARGS__)

/* Copies src into dst (at most cap bytes, NUL included; cap >= 1) with every
 * byte a terminal could act on escaped: control characters (below 0x20,
 * 0x7f) and bytes 0x80..0xff become \xHH, and a backslash becomes \\, so a
 * peer's name or reason logged with it cannot move the cursor, recolour the
 * terminal or forge a second log line. A result that does not fit is cut at
 * an escape boundary and ends in "..." when cap allows. src NULL is logged as
 * "(null)". Returns dst, for use as a printf argument. Thread-safe. */
char *pf_log_printable(char *dst, unsigned long cap, const char *src);

/* Seconds on a monotonic clock, for timing phases. */
double pf_now(void);

#endif
