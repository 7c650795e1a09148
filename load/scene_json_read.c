/* scene_json_read.c: the reading half of the JSON scene loader (scene_json.c
 * is the other): the file's text, the line of every value, and typed access
 * to values whose errors name file:line.
 *
 * cJSON keeps no line numbers, so every error would otherwise lack the "where"
 * that a scene author needs. Two small pieces recover it: a syntax error's
 * line is counted from the parser's error position, and for everything else a
 * scanner walks the raw text (which cJSON has already accepted) in document
 * order, recording the line of every value and every object key; a walk over
 * the cJSON tree in the same order (cJSON keeps member order) pairs each node
 * with its lines. Errors then read "file:line: what" with the line of the
 * offending key or value.
 *
 * Owns nothing beyond a call (the text and the line table go to the caller,
 * who frees them). Called from one thread at a time per scene. */
#include "load/json_ctx.h"

#include <errno.h>
#include <float.h>
#include <math.h>
#include <stdarg.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "base/reserve.h"

/* Scene files are hand-written or generated descriptions; geometry lives in
 * OBJ/PLY files. 64 MiB is far beyond any sane scene and bounds the memory a
 * corrupt path can make us allocate. */
#define S_MAX_FILE_BYTES (64u << 20)

/* uint64 settings travel through a JSON number (a double): integers are exact
 * only up to 2^53, so larger values are refused rather than rounded. */
#define S_MAX_EXACT_INT 9007199254740992.0

/* ------------------------------------------------------------------------ */
/* Line table                                                               */

/* The scanner's state: the raw text and the lines it emits in document order
 * (for an object member: the key's line, then the value's lines). */
typedef struct s_scan {
    const char *text;
    size_t len, pos;
    int line;
    int *out;
    size_t n, cap;
    int ok;
    int nomem; /* ok was cleared by a failed allocation */
} s_scan_t;

static void s_scan_emit(s_scan_t *sc, int line)
{
    if (!sc->ok)
        return;
    if (pf_reserve((void **)&sc->out, &sc->cap, sc->n + 1, sizeof *sc->out)) {
        sc->ok = 0;
        sc->nomem = 1;
        return;
    }
    sc->out[sc->n++] = line;
}

/* cJSON treats every byte <= 32 as white space; so does the scanner. */
static void s_scan_ws(s_scan_t *sc)
{
    while (sc->pos < sc->len && (unsigned char)sc->text[sc->pos] <= 32) {
        if (sc->text[sc->pos] == '\n')
            sc->line++;
        sc->pos++;
    }
}

static void s_scan_string(s_scan_t *sc)
{
    if (sc->pos >= sc->len || sc->text[sc->pos] != '"') {
        sc->ok = 0;
        return;
    }
    sc->pos++;
    while (sc->pos < sc->len) {
        char ch = sc->text[sc->pos];
        if (ch == '"') {
            sc->pos++;
            return;
        }
        if (ch == '\n')
            sc->line++;
        sc->pos += (ch == '\\') ? 2 : 1;
    }
    sc->ok = 0;
}

static void s_scan_value(s_scan_t *sc, int depth)
{
    s_scan_ws(sc);
    if (!sc->ok || sc->pos >= sc->len || depth > CJSON_NESTING_LIMIT + 1) {
        sc->ok = 0;
        return;
    }
    s_scan_emit(sc, sc->line);
    char open = sc->text[sc->pos];
    if (open == '"') {
        s_scan_string(sc);
    } else if (open == '{' || open == '[') {
        char close = (open == '{') ? '}' : ']';
        sc->pos++;
        s_scan_ws(sc);
        if (sc->pos < sc->len && sc->text[sc->pos] == close) {
            sc->pos++;
            return;
        }
        while (sc->ok) {
            if (open == '{') {
                s_scan_ws(sc);
                s_scan_emit(sc, sc->line);
                s_scan_string(sc);
                s_scan_ws(sc);
                if (sc->pos >= sc->len || sc->text[sc->pos] != ':') {
                    sc->ok = 0;
                    return;
                }
                sc->pos++;
            }
            s_scan_value(sc, depth + 1);
            s_scan_ws(sc);
            if (sc->pos >= sc->len) {
                sc->ok = 0;
                return;
            }
            char ch = sc->text[sc->pos++];
            if (ch == close)
                return;
            if (ch != ',')
                sc->ok = 0;
        }
    } else {
        /* A number or a literal: it ends at a delimiter or white space. */
        while (sc->pos < sc->len) {
            char ch = sc->text[sc->pos];
            if ((unsigned char)ch <= 32 || ch == ',' || ch == ']' || ch == '}')
                break;
            sc->pos++;
        }
    }
}

typedef struct s_pairing {
    const int *lines;
    size_t nlines, next;
    s_line_t *tab;
    size_t ntab, cap;
    int ok;
    int nomem;
} s_pairing_t;

static int s_pair_take(s_pairing_t *p)
{
    if (p->next >= p->nlines) {
        p->ok = 0;
        return 0;
    }
    return p->lines[p->next++];
}

/* Walks the tree in document order, consuming the scanner's lines exactly as
 * the scanner produced them. */
static void s_pair(s_pairing_t *p, const cJSON *node, int key_line)
{
    int line = s_pair_take(p);
    if (!p->ok)
        return;
    if (pf_reserve((void **)&p->tab, &p->cap, p->ntab + 1, sizeof *p->tab)) {
        p->ok = 0;
        p->nomem = 1;
        return;
    }
    p->tab[p->ntab++] = (s_line_t){ .node = node, .key_line = key_line ? key_line : line, .line = line };
    if (cJSON_IsObject(node)) {
        for (const cJSON *ch = node->child; ch && p->ok; ch = ch->next) {
            int kl = s_pair_take(p);
            s_pair(p, ch, kl);
        }
    } else if (cJSON_IsArray(node)) {
        for (const cJSON *ch = node->child; ch && p->ok; ch = ch->next)
            s_pair(p, ch, 0);
    }
}

static int s_line_cmp(const void *a, const void *b)
{
    uintptr_t x = (uintptr_t)((const s_line_t *)a)->node, y = (uintptr_t)((const s_line_t *)b)->node;
    return (x > y) - (x < y);
}

/* Builds the node-to-line table sorted by node address. On any mismatch
 * (which would mean the scanner and cJSON disagree about the text) the table
 * is left empty: errors then name the file without a line rather than a wrong
 * line. Running out of memory is not degraded that way but returned
 * (PF_ENOMEM), since lines also name things (a quad's mesh name): a load
 * either fails or gives the same scene. */
int pf_json_build_lines(const char *text, size_t len, const cJSON *root, s_line_t **tab_p, size_t *n_p)
{
    *tab_p = NULL;
    *n_p = 0;
    s_scan_t sc = { .text = text, .len = len, .line = 1, .ok = 1 };
    if (len >= 3 && memcmp(text, "\xEF\xBB\xBF", 3) == 0)
        sc.pos = 3; /* cJSON skips a UTF-8 byte-order mark */
    s_scan_value(&sc, 0);
    s_pairing_t p = { .lines = sc.out, .nlines = sc.n, .ok = sc.ok };
    if (p.ok)
        s_pair(&p, root, 0);
    free(sc.out);
    if (!p.ok || p.next != p.nlines) {
        free(p.tab);
        return sc.nomem || p.nomem ? PF_ENOMEM : PF_OK;
    }
    qsort(p.tab, p.ntab, sizeof *p.tab, s_line_cmp);
    *tab_p = p.tab;
    *n_p = p.ntab;
    return PF_OK;
}

/* ------------------------------------------------------------------------ */
/* Context and error reports                                                */

static const s_line_t *s_find_line(const s_ctx_t *c, const cJSON *node)
{
    if (!node || !c->lines)
        return NULL;
    s_line_t key = { .node = node };
    return bsearch(&key, c->lines, c->nlines, sizeof key, s_line_cmp);
}

int pf_json_line_of(const s_ctx_t *c, const cJSON *node)
{
    const s_line_t *l = s_find_line(c, node);
    return l ? l->line : 0;
}

int pf_json_key_line_of(const s_ctx_t *c, const cJSON *node)
{
    const s_line_t *l = s_find_line(c, node);
    return l ? l->key_line : 0;
}

int pf_json_fail_line(s_ctx_t *c, int status, int line, const char *fmt, ...)
{
    char msg[768];
    va_list ap;
    va_start(ap, fmt);
    vsnprintf(msg, sizeof msg, fmt, ap);
    va_end(ap);
    return pf_error_set(c->err, status, c->path, line, "%s", msg);
}

const char *pf_json_type_name(const cJSON *v)
{
    if (cJSON_IsNumber(v))
        return "a number";
    if (cJSON_IsString(v))
        return "a string";
    if (cJSON_IsBool(v))
        return "a boolean";
    if (cJSON_IsNull(v))
        return "null";
    if (cJSON_IsArray(v))
        return "an array";
    if (cJSON_IsObject(v))
        return "an object";
    return "an invalid value";
}

/* ------------------------------------------------------------------------ */
/* Typed access                                                             */

/* Checks that node is an object whose keys are all in allowed (a NULL-ended
 * list; "comment" is always allowed) and each appears once. what names the
 * object in messages ("camera", "material", ...). */
int pf_json_check_object(s_ctx_t *c, const cJSON *node, const char *what, const char *const *allowed)
{
    if (!cJSON_IsObject(node))
        return S_FAIL_AT(c, node, "%s must be an object, not %s", what, pf_json_type_name(node));
    for (const cJSON *m = node->child; m; m = m->next) {
        int known = strcmp(m->string, "comment") == 0;
        for (const char *const *k = allowed; *k && !known; k++)
            known = strcmp(m->string, *k) == 0;
        if (!known)
            return S_FAIL_KEY(c, m, "unknown key '%.64s' in %s", m->string, what);
        if (strcmp(m->string, "comment") == 0 && !cJSON_IsString(m))
            return S_FAIL_AT(c, m, "'comment' in %s must be a string", what);
        for (const cJSON *o = node->child; o != m; o = o->next)
            if (strcmp(o->string, m->string) == 0)
                return S_FAIL_KEY(c, m, "duplicate key '%.64s' in %s", m->string, what);
    }
    return PF_OK;
}

/* Fetches a key that must be present; a missing key names the object's line. */
int pf_json_require(s_ctx_t *c, const cJSON *obj, const char *key, const char *what, const cJSON **out)
{
    *out = pf_json_get(obj, key);
    if (!*out)
        return S_FAIL_AT(c, obj, "%s is missing the required key '%s'", what, key);
    return PF_OK;
}

static int s_number(s_ctx_t *c, const cJSON *v, const char *key, const char *what, double *out)
{
    if (!cJSON_IsNumber(v))
        return S_FAIL_AT(c, v, "'%s' in %s must be a number, not %s", key, what, pf_json_type_name(v));
    if (!isfinite(v->valuedouble))
        return S_FAIL_AT(c, v, "'%s' in %s must be finite", key, what);
    *out = v->valuedouble;
    return PF_OK;
}

/* A number stored as float: it must also fit the float range. */
int pf_json_float(s_ctx_t *c, const cJSON *v, const char *key, const char *what, float *out)
{
    double d = 0.0; /* set by s_number when it succeeds; gcc -O3 cannot see that */
    int rc = s_number(c, v, key, what, &d);
    if (rc)
        return rc;
    if (fabs(d) > FLT_MAX)
        return S_FAIL_AT(c, v, "'%s' in %s is too large", key, what);
    *out = (float)d;
    return PF_OK;
}

int pf_json_int(s_ctx_t *c, const cJSON *v, const char *key, const char *what, int lo, int hi, int *out)
{
    double d = 0.0; /* set by s_number when it succeeds; gcc -O3 cannot see that */
    int rc = s_number(c, v, key, what, &d);
    if (rc)
        return rc;
    if (d != floor(d) || d < lo || d > hi)
        return S_FAIL_AT(c, v, "'%s' in %s must be an integer from %d to %d (got %g)", key, what, lo, hi, d);
    *out = (int)d;
    return PF_OK;
}

int pf_json_u64(s_ctx_t *c, const cJSON *v, const char *key, const char *what, uint64_t *out)
{
    double d = 0.0; /* set by s_number when it succeeds; gcc -O3 cannot see that */
    int rc = s_number(c, v, key, what, &d);
    if (rc)
        return rc;
    if (d != floor(d) || d < 0.0 || d > S_MAX_EXACT_INT)
        return S_FAIL_AT(c, v, "'%s' in %s must be an integer from 0 to 2^53 (got %g)", key, what, d);
    *out = (uint64_t)d;
    return PF_OK;
}

int pf_json_string(s_ctx_t *c, const cJSON *v, const char *key, const char *what, const char **out)
{
    if (!cJSON_IsString(v) || !v->valuestring)
        return S_FAIL_AT(c, v, "'%s' in %s must be a string, not %s", key, what, pf_json_type_name(v));
    if (v->valuestring[0] == '\0')
        return S_FAIL_AT(c, v, "'%s' in %s must not be empty", key, what);
    *out = v->valuestring;
    return PF_OK;
}

int pf_json_file_path(s_ctx_t *c, const cJSON *v, const char *file, char *path, size_t size)
{
    int n = (file[0] == '/' || c->dir[0] == '\0') ? snprintf(path, size, "%s", file)
                                                    : snprintf(path, size, "%s/%s", c->dir, file);
    if (n < 0 || (size_t)n >= size)
        return S_FAIL_AT(c, v, "the path '%.64s...' is too long", file);
    return PF_OK;
}

/* An array of exactly n numbers (each fitting a float). */
int pf_json_floats(s_ctx_t *c, const cJSON *v, const char *key, const char *what, int n, float *out)
{
    if (!cJSON_IsArray(v) || cJSON_GetArraySize(v) != n)
        return S_FAIL_AT(c, v, "'%s' in %s must be an array of %d numbers", key, what, n);
    int i = 0;
    for (const cJSON *e = v->child; e; e = e->next, i++) {
        if (!cJSON_IsNumber(e))
            return S_FAIL_AT(c, e, "'%s' in %s: element %d must be a number, not %s", key, what, i + 1,
                             pf_json_type_name(e));
        if (!isfinite(e->valuedouble) || fabs(e->valuedouble) > FLT_MAX)
            return S_FAIL_AT(c, e, "'%s' in %s: element %d must be finite", key, what, i + 1);
        out[i] = (float)e->valuedouble;
    }
    return PF_OK;
}

int pf_json_vec3(s_ctx_t *c, const cJSON *v, const char *key, const char *what, pf_vec3 *out)
{
    float f[3];
    int rc = pf_json_floats(c, v, key, what, 3, f);
    if (rc == PF_OK)
        *out = pf_v3(f[0], f[1], f[2]);
    return rc;
}

/* Positions must lie within +-1e18: each can become a ray origin, and Embree
 * refuses rays that start beyond 1.844e18 (see S_COORD_MAX in scene.c). */
int pf_json_in_range(pf_vec3 v)
{
    return fabsf(v.x) <= 1e18f && fabsf(v.y) <= 1e18f && fabsf(v.z) <= 1e18f;
}

int pf_json_position(s_ctx_t *c, const cJSON *v, const char *key, const char *what, pf_vec3 *out)
{
    int rc = pf_json_vec3(c, v, key, what, out);
    if (rc == PF_OK && !pf_json_in_range(*out))
        rc = S_FAIL_AT(c, v, "'%s' in %s must lie within +-1e18, the ray tracer's range", key, what);
    return rc;
}

/* An RGB colour: an array of 3 numbers, or one number meaning grey. Each
 * channel must lie in [lo, hi]. */
int pf_json_rgb(s_ctx_t *c, const cJSON *v, const char *key, const char *what, float lo, float hi, pf_vec3 *out)
{
    pf_vec3 rgb;
    if (cJSON_IsNumber(v)) {
        float g;
        int rc = pf_json_float(c, v, key, what, &g);
        if (rc)
            return rc;
        rgb = pf_v3s(g);
    } else if (cJSON_IsArray(v)) {
        int rc = pf_json_vec3(c, v, key, what, &rgb);
        if (rc)
            return rc;
    } else {
        return S_FAIL_AT(c, v, "'%s' in %s must be an RGB array of 3 numbers or one number, not %s", key, what,
                         pf_json_type_name(v));
    }
    for (int k = 0; k < 3; k++) {
        float x = pf_vget(rgb, k);
        if (x < lo || x > hi) {
            if (hi >= FLT_MAX)
                return S_FAIL_AT(c, v, "'%s' in %s must be >= %g in every channel (got %g)", key, what, lo, x);
            return S_FAIL_AT(c, v, "'%s' in %s must lie in [%g, %g] in every channel (got %g)", key, what, lo, hi, x);
        }
    }
    *out = rgb;
    return PF_OK;
}

/* ------------------------------------------------------------------------ */
/* The file                                                                 */

/* Reads the whole file, NUL-terminated. */
int pf_json_read_file(const char *path, char **text_p, size_t *len_p, pf_error_t *err)
{
    FILE *f = fopen(path, "rb");
    if (!f)
        return pf_error_set(err, PF_EIO, path, 0, "cannot open: %s", strerror(errno));
    char *buf = NULL;
    size_t len = 0, cap = 0;
    int rc = PF_OK;
    for (;;) {
        if (pf_reserve((void **)&buf, &cap, len + 4096 + 1, 1)) {
            rc = pf_error_set(err, PF_ENOMEM, path, 0, "out of memory");
            break;
        }
        size_t got = fread(buf + len, 1, cap - len - 1, f);
        len += got;
        if (len > S_MAX_FILE_BYTES) {
            rc = pf_error_set(err, PF_ERANGE, path, 0, "the scene file is larger than %u MiB",
                              S_MAX_FILE_BYTES >> 20);
            break;
        }
        if (got == 0) {
            if (ferror(f))
                rc = pf_error_set(err, PF_EIO, path, 0, "read error: %s", strerror(errno));
            break;
        }
    }
    fclose(f);
    if (rc) {
        free(buf);
        return rc;
    }
    buf[len] = '\0';
    *text_p = buf;
    *len_p = len;
    return PF_OK;
}

int pf_json_line_at(const char *text, size_t pos)
{
    int line = 1;
    for (size_t i = 0; i < pos; i++)
        line += text[i] == '\n';
    return line;
}

int pf_json_syntax_error(const char *path, const char *text, size_t len, const char *at, pf_error_t *err)
{
    size_t pos = (at && at >= text && at <= text + len) ? (size_t)(at - text) : len;
    int line = pf_json_line_at(text, pos);
    if (pos >= len)
        return pf_error_set(err, PF_EPARSE, path, line, "JSON syntax error near the end of the file");
    /* cJSON may point at the line end just after the culprit; show the
     * line's last token then rather than nothing. */
    size_t from = pos;
    while (from > 0 && (text[from] == '\n' || text[from] == '\r' || text[from] == ' ' || text[from] == '\t') &&
           text[from - 1] != '\n')
        from--;
    char near[32];
    size_t n = 0;
    for (size_t i = from; i < len && n < 24 && text[i] != '\n' && text[i] != '\r'; i++)
        near[n++] = (text[i] >= 32 && text[i] < 127) ? text[i] : '?';
    near[n] = '\0';
    return pf_error_set(err, PF_EPARSE, path, line, "JSON syntax error near '%s'", near);
}
