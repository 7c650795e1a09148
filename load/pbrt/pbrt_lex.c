/* pbrt_lex.c: the pbrt-v4 reader's tokenizer. It owns the files of one
 * load (each read whole into memory and kept until the load ends, so that
 * tokens can point into them) and the Include stack; it hands the parser one
 * token at a time, each with its file, line and column. Called on the one
 * thread that loads the scene.
 *
 * Tokens, as pbrt-v4 writes them: a '#' starts a comment to the end of the
 * line; "..." is a string (escapes \b \f \n \r \t \\ \' \", on one line);
 * '[' and ']'; anything else runs to the next blank, bracket, quote or '#',
 * and is a number when it starts with a digit, a sign or a dot, a bare word
 * (a directive, true, false) otherwise. Columns count bytes from 1.
 *
 * A file included while it is already open (directly or further up the
 * stack) is an error naming the chain; so is a stack deeper than
 * PF_PBRT_MAX_INCLUDE. A file included twice in a row is read once. */
#include <errno.h>
#include <limits.h>
#include <math.h>
#include <stdarg.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/stat.h>
#include <unistd.h>

#include "base/reserve.h"
#include "load/pbrt/pbrt_impl.h"

/* The largest file read: text scenes beyond this are not plausible. */
#define S_MAX_FILE ((size_t)1 << 32)

const char *pf_pbrt_file_name(const pf_pbrt_t *c, pf_pbrt_loc_t loc)
{
    return loc.file >= 0 && (size_t)loc.file < c->nfiles ? c->files[loc.file].path : "?";
}

int pf_pbrt_error(pf_pbrt_t *c, int st, pf_pbrt_loc_t loc, const char *fmt, ...)
{
    if (!c->err)
        return st;
    char msg[768];
    va_list ap;
    va_start(ap, fmt);
    vsnprintf(msg, sizeof msg, fmt, ap);
    va_end(ap);
    if (loc.file < 0)
        snprintf(c->err->msg, sizeof c->err->msg, "%s", msg);
    else
        snprintf(c->err->msg, sizeof c->err->msg, "%.200s:%d:%d: %s", pf_pbrt_file_name(c, loc), loc.line, loc.col,
                 msg);
    return st;
}

int pf_pbrt_error_line(pf_pbrt_t *c, int st, pf_pbrt_loc_t loc, const char *fmt, ...)
{
    if (!c->err)
        return st;
    char msg[768];
    va_list ap;
    va_start(ap, fmt);
    vsnprintf(msg, sizeof msg, fmt, ap);
    va_end(ap);
    if (loc.file < 0)
        snprintf(c->err->msg, sizeof c->err->msg, "%s", msg);
    else
        snprintf(c->err->msg, sizeof c->err->msg, "%.200s:%d: %s", pf_pbrt_file_name(c, loc), loc.line, msg);
    return st;
}

/* Reads the whole file into a NUL-terminated buffer. */
static int s_read_file(pf_pbrt_t *c, const char *path, pf_pbrt_loc_t from, pf_pbrt_file_t *f)
{
    FILE *fp = fopen(path, "rb");
    if (!fp)
        return pf_pbrt_error(c, PF_EIO, from, "cannot open '%s': %s", path, strerror(errno));
    struct stat st;
    int rc = PF_OK;
    if (fstat(fileno(fp), &st) != 0 || !S_ISREG(st.st_mode)) {
        rc = pf_pbrt_error(c, PF_EIO, from, "'%s' is not a regular file", path);
        goto done;
    }
    if ((uint64_t)st.st_size >= S_MAX_FILE) {
        rc = pf_pbrt_error(c, PF_ERANGE, from, "'%s' is larger than %zu bytes", path, S_MAX_FILE);
        goto done;
    }
    size_t size = (size_t)st.st_size;
    f->data = malloc(size + 1);
    f->path = strdup(path);
    const char *slash = strrchr(path, '/');
    size_t dlen = slash ? (size_t)(slash - path) + 1 : 0;
    f->dir = malloc(dlen + 1);
    if (!f->data || !f->path || !f->dir) {
        rc = pf_pbrt_error(c, PF_ENOMEM, from, "out of memory");
        goto done;
    }
    memcpy(f->dir, path, dlen);
    f->dir[dlen] = '\0';
    if (size && fread(f->data, 1, size, fp) != size) {
        rc = pf_pbrt_error(c, PF_EIO, from, "cannot read '%s'", path);
        goto done;
    }
    f->data[size] = '\0';
    f->size = size;
    f->dev = (uint64_t)st.st_dev;
    f->ino = (uint64_t)st.st_ino;
done:
    fclose(fp);
    if (rc) {
        free(f->data);
        free(f->path);
        free(f->dir);
        memset(f, 0, sizeof *f);
    }
    return rc;
}

/* The chain of open files and path, for the recursive-include error. */
static void s_chain(const pf_pbrt_t *c, const char *path, char *out, size_t cap)
{
    size_t n = 0;
    out[0] = '\0';
    for (int i = 0; i < c->depth && n < cap; i++) {
        int k = snprintf(out + n, cap - n, "%s -> ", c->files[c->stack[i].file].path);
        n += k > 0 ? (size_t)k : 0;
    }
    if (n < cap)
        snprintf(out + n, cap - n, "%s", path);
}

int pf_pbrt_push_file(pf_pbrt_t *c, const char *path, pf_pbrt_loc_t from)
{
    if (c->depth > PF_PBRT_MAX_INCLUDE)
        return pf_pbrt_error(c, PF_ERANGE, from, "includes nested deeper than %d", PF_PBRT_MAX_INCLUDE);
    struct stat st;
    if (stat(path, &st) != 0)
        return pf_pbrt_error(c, PF_EIO, from, "cannot open '%s': %s", path, strerror(errno));
    int idx = -1;
    for (size_t i = 0; i < c->nfiles; i++)
        if (c->files[i].dev == (uint64_t)st.st_dev && c->files[i].ino == (uint64_t)st.st_ino)
            idx = (int)i;
    for (int i = 0; i < c->depth && idx >= 0; i++) {
        if (c->stack[i].file == idx) {
            char chain[600];
            s_chain(c, path, chain, sizeof chain);
            return pf_pbrt_error(c, PF_EPARSE, from, "recursive Include: %s", chain);
        }
    }
    if (idx < 0) {
        if (c->nfiles >= INT_MAX ||
            pf_reserve((void **)&c->files, &c->cap_files, c->nfiles + 1, sizeof *c->files))
            return pf_pbrt_error(c, PF_ENOMEM, from, "out of memory");
        pf_pbrt_file_t *f = &c->files[c->nfiles];
        memset(f, 0, sizeof *f);
        int rc = s_read_file(c, path, from, f);
        if (rc)
            return rc;
        idx = (int)c->nfiles++;
    }
    c->stack[c->depth++] = (pf_pbrt_frame_t){ .file = idx, .pos = 0, .line = 1, .col = 1, .from = from };
    return PF_OK;
}

/* Moves the column on by n, the line on by one: both saturate (a 4 GiB
 * file may hold more lines or columns than an int counts). */
static void s_col(pf_pbrt_frame_t *fr, size_t n) { fr->col = n > (size_t)(INT_MAX - fr->col) ? INT_MAX : fr->col + (int)n; }
static void s_newline(pf_pbrt_frame_t *fr)
{
    fr->line += fr->line < INT_MAX;
    fr->col = 1;
}

static int s_is_blank(char ch) { return ch == ' ' || ch == '\t' || ch == '\r' || ch == '\n' || ch == '\v' || ch == '\f'; }
static int s_ends_word(char ch) { return s_is_blank(ch) || ch == '[' || ch == ']' || ch == '"' || ch == '#' || ch == '\0'; }

/* Skips blanks and comments in the top frame; returns its next byte. */
static char s_skip(pf_pbrt_t *c, pf_pbrt_frame_t *fr, const char *d)
{
    for (;;) {
        char ch = d[fr->pos];
        if (ch == '\n') {
            s_newline(fr);
            fr->pos++;
        } else if (s_is_blank(ch)) {
            s_col(fr, 1);
            fr->pos++;
        } else if (ch == '#') {
            while (d[fr->pos] != '\n' && fr->pos < c->files[fr->file].size)
                fr->pos++;
        } else {
            return ch;
        }
    }
}

/* Reads a string token starting at the quote. */
static int s_string(pf_pbrt_t *c, pf_pbrt_frame_t *fr, const char *d, pf_pbrt_tok_t *t)
{
    size_t start = fr->pos + 1, i = start, size = c->files[fr->file].size;
    for (;;) {
        if (i >= size || d[i] == '\n')
            return pf_pbrt_error(c, PF_EPARSE, t->loc, "unterminated string (a string must end on its line)");
        if (d[i] == '\\') {
            if (i + 1 >= size || d[i + 1] == '\n')
                return pf_pbrt_error(c, PF_EPARSE, t->loc, "unterminated string (a string must end on its line)");
            i += 2;
            continue;
        }
        if (d[i] == '"')
            break;
        if (d[i] == '\0')
            return pf_pbrt_error(c, PF_EPARSE, t->loc, "a NUL byte inside a string");
        i++;
    }
    t->kind = PF_PBRT_STRING;
    t->text = d + start;
    t->len = i - start;
    s_col(fr, i + 1 - fr->pos);
    fr->pos = i + 1;
    return PF_OK;
}

/* Lexes one token from the top frame, popping finished included files. */
static int s_lex(pf_pbrt_t *c, pf_pbrt_tok_t *t)
{
    for (;;) {
        pf_pbrt_frame_t *fr = &c->stack[c->depth - 1];
        const pf_pbrt_file_t *f = &c->files[fr->file];
        const char *d = f->data;
        char ch = s_skip(c, fr, d);
        t->loc = (pf_pbrt_loc_t){ fr->file, fr->line, fr->col };
        if (fr->pos >= f->size) {
            if (c->depth > 1) {
                c->depth--;
                continue;
            }
            t->kind = PF_PBRT_EOF;
            t->text = d + f->size;
            t->len = 0;
            return PF_OK;
        }
        if (ch == '"')
            return s_string(c, fr, d, t);
        if (ch == '[' || ch == ']') {
            t->kind = ch == '[' ? PF_PBRT_LBRACK : PF_PBRT_RBRACK;
            t->text = d + fr->pos;
            t->len = 1;
            fr->pos++;
            s_col(fr, 1);
            return PF_OK;
        }
        if ((unsigned char)ch < 0x20 || ch == 0x7f)
            return pf_pbrt_error(c, PF_EPARSE, t->loc, "unexpected byte 0x%02x", (unsigned char)ch);
        size_t start = fr->pos;
        while (!s_ends_word(d[fr->pos]))
            fr->pos++;
        if (fr->pos - start > 4096)
            return pf_pbrt_error(c, PF_EPARSE, t->loc, "a token longer than 4096 bytes");
        t->text = d + start;
        t->len = fr->pos - start;
        s_col(fr, t->len);
        t->kind = (ch >= '0' && ch <= '9') || ch == '-' || ch == '+' || ch == '.' ? PF_PBRT_NUMBER : PF_PBRT_WORD;
        return PF_OK;
    }
}

int pf_pbrt_peek(pf_pbrt_t *c, pf_pbrt_tok_t *t)
{
    if (!c->has_peek) {
        int rc = s_lex(c, &c->peek);
        if (rc)
            return rc;
        c->has_peek = 1;
    }
    *t = c->peek;
    return PF_OK;
}

int pf_pbrt_next(pf_pbrt_t *c, pf_pbrt_tok_t *t)
{
    int rc = pf_pbrt_peek(c, t);
    if (rc == PF_OK)
        c->has_peek = 0;
    return rc;
}

int pf_pbrt_tok_is(const pf_pbrt_tok_t *t, const char *w)
{
    size_t n = strlen(w);
    return t->kind == PF_PBRT_WORD && t->len == n && memcmp(t->text, w, n) == 0;
}

int pf_pbrt_tok_number(pf_pbrt_t *c, const pf_pbrt_tok_t *t, double *out)
{
    char buf[72];
    if (t->kind != PF_PBRT_NUMBER)
        return pf_pbrt_error(c, PF_EPARSE, t->loc, "expected a number, found '%.*s'", (int)(t->len > 40 ? 40 : t->len),
                             t->text);
    if (t->len >= sizeof buf)
        return pf_pbrt_error(c, PF_EPARSE, t->loc, "malformed number '%.40s...'", t->text);
    memcpy(buf, t->text, t->len);
    buf[t->len] = '\0';
    char *end;
    double v = strtod(buf, &end);
    if (end == buf || *end || strpbrk(buf, "xXnN"))
        return pf_pbrt_error(c, PF_EPARSE, t->loc, "malformed number '%s'", buf);
    if (!isfinite(v) || fabs(v) > PF_PBRT_MAX_NUMBER)
        return pf_pbrt_error(c, PF_ERANGE, t->loc, "number '%s' out of range (|x| <= %g)", buf, PF_PBRT_MAX_NUMBER);
    *out = v;
    return PF_OK;
}

int pf_pbrt_tok_string(pf_pbrt_t *c, const pf_pbrt_tok_t *t, char **out)
{
    if (t->kind != PF_PBRT_STRING)
        return pf_pbrt_error(c, PF_EPARSE, t->loc, "expected a quoted string, found '%.*s'",
                             (int)(t->len > 40 ? 40 : t->len), t->text);
    char *s = malloc(t->len + 1);
    if (!s)
        return pf_pbrt_error(c, PF_ENOMEM, t->loc, "out of memory");
    size_t n = 0;
    for (size_t i = 0; i < t->len; i++) {
        char ch = t->text[i];
        if (ch == '\\') {
            static const char from[] = "bfnrt\\'\"", to[] = "\b\f\n\r\t\\'\"";
            const char *k = strchr(from, t->text[++i]);
            if (!k || !*k) {
                pf_pbrt_loc_t at = t->loc;
                at.col = i > (size_t)(INT_MAX - at.col) ? INT_MAX : at.col + (int)i;
                free(s);
                return pf_pbrt_error(c, PF_EPARSE, at, "unknown escape '\\%c' in a string", t->text[i]);
            }
            ch = to[k - from];
        }
        s[n++] = ch;
    }
    s[n] = '\0';
    *out = s;
    return PF_OK;
}

/* Joins dir and name into out; 0 or -1 when it does not fit. */
static int s_join(const char *dir, const char *name, char *out, size_t cap)
{
    int k = snprintf(out, cap, "%s%s", dir, name);
    return k < 0 || (size_t)k >= cap ? -1 : 0;
}

int pf_pbrt_resolve(pf_pbrt_t *c, pf_pbrt_loc_t loc, const char *name, int include, char *out, size_t cap)
{
    const char *here = loc.file >= 0 && (size_t)loc.file < c->nfiles ? c->files[loc.file].dir : "";
    const char *first = include ? here : c->main_dir, *second = include ? c->main_dir : here;
    if (!name[0])
        return pf_pbrt_error_line(c, PF_EPARSE, loc, "empty file name");
    if (name[0] == '/')
        first = second = "";
    if (s_join(first, name, out, cap))
        return pf_pbrt_error_line(c, PF_ERANGE, loc, "file name too long");
    if (access(out, F_OK) == 0 || strcmp(first, second) == 0)
        return PF_OK;
    char alt[4096];
    if (s_join(second, name, alt, sizeof alt) == 0 && access(alt, F_OK) == 0 && strlen(alt) < cap)
        memcpy(out, alt, strlen(alt) + 1);
    return PF_OK;
}

void pf_pbrt_lex_free(pf_pbrt_t *c)
{
    for (size_t i = 0; i < c->nfiles; i++) {
        free(c->files[i].path);
        free(c->files[i].dir);
        free(c->files[i].data);
    }
    free(c->files);
    c->files = NULL;
    c->nfiles = 0;
}
