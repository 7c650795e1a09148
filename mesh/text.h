/* text.h: private to mesh/. The statement reading that the OBJ and MTL
 * readers share, as both formats define it: a statement is one line, a
 * keyword and its values separated by blanks, ended by the line's end or a
 * '#' comment. Here: the character classes, tokens and numbers (inline, as
 * the OBJ reader calls them for every byte of a model), the rest of a line
 * as a name, the one warning per unsupported keyword, and the read loop with
 * its read-error report (text.c).
 *
 * Nothing outside mesh/ includes this header. No state of its own: the
 * callers own their buffers and counters; single-threaded like the loaders. */
#ifndef PF_LOAD_TEXT_H
#define PF_LOAD_TEXT_H

#include <stddef.h>
#include <stdio.h>
#include <stdlib.h>

#include "base/fastfloat.h"
#include "base/status.h"

/* Blanks between tokens (a newline ends the statement instead). */
static inline int pf_text_is_ws(char c) { return c == ' ' || c == '\t' || c == '\r' || c == '\v' || c == '\f'; }
/* The end of a statement: the end of the text or the line, or a comment. */
static inline int pf_text_is_eol(char c) { return c == '\0' || c == '\n' || c == '#'; }
static inline int pf_text_is_delim(char c) { return pf_text_is_ws(c) || pf_text_is_eol(c); }
static inline const char *pf_text_skip_ws(const char *p)
{
    while (pf_text_is_ws(*p))
        p++;
    return p;
}
/* Length of the token at p. */
static inline int pf_text_token_len(const char *p)
{
    int n = 0;
    while (!pf_text_is_delim(p[n]))
        n++;
    return n;
}
/* How much of a token a message shows: at most 40 bytes. */
static inline int pf_text_show(const char *p)
{
    int n = pf_text_token_len(p);
    return n < 40 ? n : 40;
}

/* Parses one float at *pp (after blanks): 0, with *pp advanced past it; 1 at
 * the end of the statement; -1 when the token is not a number (*pp is then
 * at the token). The number must end at a blank or the statement's end.
 *
 * With fast, plain decimals take pf_fast_float's path (same value as strtof)
 * and the rest strtof's. The two syntaxes differ in one corner, kept as each
 * format always had it: a hexadecimal float ("0x1p3") is a number to strtof
 * alone (MTL, fast = 0) but malformed with fast (OBJ), whose fast path reads
 * the "0" and stops at the "x". */
static inline int pf_text_float(const char **pp, int fast, float *out)
{
    const char *p = pf_text_skip_ws(*pp);
    *pp = p;
    if (pf_text_is_eol(*p))
        return 1;
    const char *end;
    float v;
    if (!fast || !pf_fast_float(p, &end, &v)) {
        char *e;
        v = strtof(p, &e);
        end = e;
    }
    if (end == p || !pf_text_is_delim(*end))
        return -1;
    *out = v;
    *pp = end;
    return 0;
}

/* Reports "malformed number" for the token at p (after blanks) at path:line;
 * returns PF_EPARSE. */
int pf_text_bad_number(pf_error_t *err, const char *path, int line, const char *p);

/* The rest of the statement at p as a name: blanks skipped, then the text up
 * to the line's end or a '#', less trailing blanks. Returns where the name
 * starts and sets *n to its length (0 when there is none). */
const char *pf_text_rest(const char *p, size_t *n);

/* The unsupported keywords a file has been warned about. */
#define PF_TEXT_WARNED_MAX 32
typedef struct pf_text_warned {
    char kw[PF_TEXT_WARNED_MAX][32];
    int n;
    int max; /* how many to remember (<= PF_TEXT_WARNED_MAX); the caller sets it */
} pf_text_warned_t;

/* Warns "ignoring unsupported statement" at path:line once per keyword (its
 * first 31 bytes); once max keywords are remembered, a new one warns each
 * time it appears. */
void pf_text_warn_keyword(pf_text_warned_t *w, const char *path, int line, const char *kw, int len);

/* Called once per statement with its keyword (kwlen bytes at kw) and the
 * text after it; a nonzero return stops the reading. */
typedef int (*pf_text_statement_fn)(void *arg, const char *kw, int kwlen, const char *rest);

/* Reads f to its end, one line at a time: counts the lines in *line (the
 * number the callbacks' messages give), skips blank and comment lines and
 * hands every other one to fn. Returns fn's first nonzero return; or a read
 * error reported at path, the line after the last read (PF_ENOMEM for a line
 * too long for memory, else PF_EIO); or PF_OK at the end of the file. */
int pf_text_read_statements(FILE *f, const char *path, int *line, pf_error_t *err, pf_text_statement_fn fn,
                            void *arg);

#endif
