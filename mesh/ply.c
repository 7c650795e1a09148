/* ply.c: reads PLY meshes (ascii, binary little and big endian) into one
 * scene mesh. It owns the parsing state of one call. Called on the one thread
 * that builds the scene.
 *
 * The header is read line by line; the body element by element in header
 * order through a small buffered reader that checks the bytes it needs
 * before every read. What is used: the first element named "vertex" (scalar
 * x, y, z of any numeric type, nx, ny, nz when all three are present, and
 * texture coordinates u, v, also spelt s, t, texture_u, texture_v,
 * texture_s, texture_t, when both are present)
 * and the first element named "face" (a list named vertex_indices or
 * vertex_index; polygons are fan-triangulated as (0, i, i+1)). Every other
 * element and property is read past, lists included.
 *
 * Input is never trusted: before anything is allocated, the smallest body
 * the header's counts imply is compared with the file's size, so a header
 * claiming 2^31 vertices in a 100-byte file fails at once. Every index is
 * checked against the vertex count and every coordinate must be finite.
 * Errors name "file:line" in the header and in ascii bodies, and
 * "file: byte offset N" in binary bodies.
 *
 * A mirroring transform (det < 0) reverses the winding and negates the
 * transformed normals, as in obj.c.
 *
 * A file whose name ends in ".gz" is inflated through zlib into memory
 * first (at most S_GZ_MAX bytes) and read from there like any other: the
 * size check above then holds against the inflated size, and errors name
 * the .gz file with the line or byte offset of the inflated text. */
#include "base/fastfloat.h"
#include "base/reserve.h"
#include "mesh/mesh.h"

#include <errno.h>
#include <inttypes.h>
#include <strings.h>
#include <zlib.h>
#include <math.h>
#include <stdarg.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/stat.h>

#include "base/log.h"

enum { S_CHAR, S_UCHAR, S_SHORT, S_USHORT, S_INT, S_UINT, S_FLOAT, S_DOUBLE };
static const struct {
    const char *name;
    int type;
} s_types[] = {
    { "char", S_CHAR },     { "int8", S_CHAR },      { "uchar", S_UCHAR },   { "uint8", S_UCHAR },
    { "short", S_SHORT },   { "int16", S_SHORT },    { "ushort", S_USHORT }, { "uint16", S_USHORT },
    { "int", S_INT },       { "int32", S_INT },      { "uint", S_UINT },     { "uint32", S_UINT },
    { "float", S_FLOAT },   { "float32", S_FLOAT },  { "double", S_DOUBLE }, { "float64", S_DOUBLE },
};
static const unsigned s_size[] = { 1, 1, 2, 2, 4, 4, 4, 8 };
static const double s_lo[] = { -128, 0, -32768, 0, -2147483648.0, 0 };
static const double s_hi[] = { 127, 255, 32767, 65535, 2147483647.0, 4294967295.0 };

/* What a property means to the loader. */
enum { S_ROLE_NONE, S_X, S_Y, S_Z, S_NX, S_NY, S_NZ, S_U, S_V, S_INDICES };

typedef struct s_prop {
    int type;       /* scalar type, or a list's item type */
    int list;       /* 1 for a list property */
    int count_type; /* a list's length type */
    int role;
} s_prop_t;

typedef struct s_elem {
    char name[64];
    uint64_t count;
    int line;          /* of its header line */
    size_t first, n;   /* its properties in s_ply_t.props */
} s_elem_t;

#define S_BUF (1u << 16)
#define S_MAX_ELEMS 1024
#define S_MAX_PROPS 4096

enum { S_ASCII, S_LE, S_BE };

typedef struct s_ply {
    const char *path;
    pf_error_t *err;
    FILE *f;
    uint64_t fsize;
    /* Buffered reader: buf[pos..len) holds the file bytes from offset base + pos. */
    unsigned char *buf;
    size_t pos, len;
    uint64_t base;
    int line;          /* header and ascii body lines */
    int tok_line;      /* line of the last ascii token */
    uint64_t voff;     /* offset of the value being read (binary messages) */
    int format;
    s_elem_t *elems;
    size_t nelems, cap_elems;
    s_prop_t *props;
    size_t nprops, cap_props;
} s_ply_t;


static uint64_t s_offset(const s_ply_t *p) { return p->base + p->pos; }
/* Bytes of the file after the read position (0 if the file grew meanwhile). */
static uint64_t s_left(const s_ply_t *p) { return p->fsize > s_offset(p) ? p->fsize - s_offset(p) : 0; }

/* Makes at least need (<= S_BUF) bytes available; -1 if the file ends first. */
static int s_fill(s_ply_t *p, size_t need)
{
    size_t avail = p->len - p->pos;
    if (avail >= need)
        return 0;
    memmove(p->buf, p->buf + p->pos, avail);
    p->base += p->pos;
    p->pos = 0;
    p->len = avail;
    while (p->len < need) {
        size_t k = fread(p->buf + p->len, 1, S_BUF - p->len, p->f);
        if (k == 0)
            return -1;
        p->len += k;
    }
    return 0;
}

static int s_header_err(s_ply_t *p, const char *fmt, ...) __attribute__((format(printf, 2, 3)));
static int s_header_err(s_ply_t *p, const char *fmt, ...)
{
    char msg[512];
    va_list ap;
    va_start(ap, fmt);
    vsnprintf(msg, sizeof msg, fmt, ap);
    va_end(ap);
    return pf_error_set(p->err, PF_EPARSE, p->path, p->line, "%s", msg);
}

/* Body errors: "file:line: what" for ascii, "file: byte offset N: what" for binary. */
static int s_body_err(s_ply_t *p, const char *fmt, ...) __attribute__((format(printf, 2, 3)));
static int s_body_err(s_ply_t *p, const char *fmt, ...)
{
    char msg[512];
    va_list ap;
    va_start(ap, fmt);
    vsnprintf(msg, sizeof msg, fmt, ap);
    va_end(ap);
    if (ferror(p->f))
        return pf_error_set(p->err, PF_EIO, p->path, p->format == S_ASCII ? p->line : 0, "read error");
    if (p->format == S_ASCII)
        return pf_error_set(p->err, PF_EPARSE, p->path, p->line, "%s", msg);
    return pf_error_set(p->err, PF_EPARSE, p->path, 0, "byte offset %" PRIu64 ": %s", p->voff, msg);
}

/* Reads one header line without its end-of-line and trailing blanks.
 * Returns its length, -1 at the end of the file, -2 if longer than cap. */
static int s_header_line(s_ply_t *p, char *out, size_t cap)
{
    size_t n = 0;
    for (;;) {
        if (s_fill(p, 1))
            return -1;
        char c = (char)p->buf[p->pos++];
        if (c == '\n')
            break;
        if (n + 1 >= cap)
            return -2;
        out[n++] = c == '\0' ? ' ' : c;
    }
    while (n > 0 && (out[n - 1] == '\r' || out[n - 1] == ' ' || out[n - 1] == '\t'))
        n--;
    out[n] = '\0';
    return (int)n;
}

/* Splits a line into at most max blank-separated tokens; returns how many
 * (max + 1 when there are more). */
static int s_split(char *line, char **tok, int max)
{
    int n = 0;
    char *save = NULL;
    for (char *t = strtok_r(line, " \t\r", &save); t; t = strtok_r(NULL, " \t\r", &save)) {
        if (n == max)
            return max + 1;
        tok[n++] = t;
    }
    return n;
}

static int s_type(const char *name)
{
    for (size_t i = 0; i < sizeof s_types / sizeof s_types[0]; i++)
        if (strcmp(s_types[i].name, name) == 0)
            return s_types[i].type;
    return -1;
}

static int s_parse_header(s_ply_t *p)
{
    char line[1024];
    char *tok[8];
    int have_format = 0;
    for (;;) {
        p->line++;
        int n = s_header_line(p, line, sizeof line);
        if (n == -1)
            return s_header_err(p, "the file ends inside the header (no end_header)");
        if (n == -2 && p->line == 1)
            return s_header_err(p, "not a PLY file (it does not start with 'ply')");
        if (n == -2)
            return s_header_err(p, "header line longer than %zu bytes", sizeof line - 1);
        if (p->line == 1) {
            if (strcmp(line, "ply") != 0)
                return s_header_err(p, "not a PLY file (it does not start with 'ply')");
            continue;
        }
        int nt = s_split(line, tok, 6);
        if (nt == 0)
            continue;
        if (strcmp(tok[0], "comment") == 0 || strcmp(tok[0], "obj_info") == 0)
            continue;
        if (strcmp(tok[0], "end_header") == 0) {
            if (!have_format)
                return s_header_err(p, "end_header before any format line");
            return PF_OK;
        }
        if (strcmp(tok[0], "format") == 0) {
            if (nt != 3)
                return s_header_err(p, "expected 'format <ascii|binary_little_endian|binary_big_endian> 1.0'");
            if (strcmp(tok[1], "ascii") == 0)
                p->format = S_ASCII;
            else if (strcmp(tok[1], "binary_little_endian") == 0)
                p->format = S_LE;
            else if (strcmp(tok[1], "binary_big_endian") == 0)
                p->format = S_BE;
            else
                return s_header_err(p, "unknown format '%s'", tok[1]);
            if (strcmp(tok[2], "1.0") != 0 && strcmp(tok[2], "1") != 0)
                return pf_error_set(p->err, PF_EUNSUPPORTED, p->path, p->line, "unsupported PLY version '%s'",
                                    tok[2]);
            have_format = 1;
            continue;
        }
        if (strcmp(tok[0], "element") == 0) {
            if (nt != 3)
                return s_header_err(p, "expected 'element <name> <count>'");
            const char *c = tok[2];
            uint64_t count = 0;
            if (!*c)
                return s_header_err(p, "element count is empty");
            for (; *c; c++) {
                if (*c < '0' || *c > '9' || count > (UINT64_MAX - 9) / 10)
                    return s_header_err(p, "element count '%s' is not a non-negative integer", tok[2]);
                count = count * 10 + (uint64_t)(*c - '0');
            }
            if (p->nelems >= S_MAX_ELEMS)
                return s_header_err(p, "more than %d elements", S_MAX_ELEMS);
            if (pf_reserve((void **)&p->elems, &p->cap_elems, p->nelems + 1, sizeof *p->elems))
                return pf_error_set(p->err, PF_ENOMEM, p->path, p->line, "out of memory");
            s_elem_t *e = &p->elems[p->nelems++];
            memset(e, 0, sizeof *e);
            snprintf(e->name, sizeof e->name, "%s", tok[1]);
            e->count = count;
            e->line = p->line;
            e->first = p->nprops;
            continue;
        }
        if (strcmp(tok[0], "property") == 0) {
            if (p->nelems == 0)
                return s_header_err(p, "property before any element");
            s_prop_t q = { 0 };
            const char *name;
            if (nt >= 2 && strcmp(tok[1], "list") == 0) {
                if (nt != 5)
                    return s_header_err(p, "expected 'property list <count type> <item type> <name>'");
                q.list = 1;
                q.count_type = s_type(tok[2]);
                q.type = s_type(tok[3]);
                if (q.count_type < 0 || q.type < 0)
                    return s_header_err(p, "unknown type '%s'", q.count_type < 0 ? tok[2] : tok[3]);
                if (q.count_type >= S_FLOAT)
                    return s_header_err(p, "a list length must have an integer type, not '%s'", tok[2]);
                name = tok[4];
            } else {
                if (nt != 3)
                    return s_header_err(p, "expected 'property <type> <name>'");
                q.type = s_type(tok[1]);
                if (q.type < 0)
                    return s_header_err(p, "unknown type '%s'", tok[1]);
                name = tok[2];
            }
            s_elem_t *e = &p->elems[p->nelems - 1];
            static const char *coords[] = { "x", "y", "z", "nx", "ny", "nz" };
            static const char *uvs[] = { "u", "v", "s", "t", "texture_u", "texture_v", "texture_s", "texture_t" };
            if (strcmp(e->name, "vertex") == 0) {
                for (int i = 0; i < 6; i++)
                    if (strcmp(name, coords[i]) == 0)
                        q.role = S_X + i;
                for (int i = 0; i < 8; i++)
                    if (strcmp(name, uvs[i]) == 0)
                        q.role = S_U + (i & 1);
                if (q.role && q.list)
                    return s_header_err(p, "vertex property '%s' must not be a list", name);
            } else if (strcmp(e->name, "face") == 0 &&
                       (strcmp(name, "vertex_indices") == 0 || strcmp(name, "vertex_index") == 0)) {
                if (!q.list)
                    return s_header_err(p, "face property '%s' must be a list", name);
                if (q.type >= S_FLOAT)
                    return s_header_err(p, "vertex indices must have an integer type, not '%s'", tok[3]);
                q.role = S_INDICES;
            }
            /* The first property with a role keeps it. */
            for (size_t i = e->first; i < p->nprops && q.role; i++)
                if (p->props[i].role == q.role)
                    q.role = S_ROLE_NONE;
            if (p->nprops >= S_MAX_PROPS)
                return s_header_err(p, "more than %d properties", S_MAX_PROPS);
            if (pf_reserve((void **)&p->props, &p->cap_props, p->nprops + 1, sizeof *p->props))
                return pf_error_set(p->err, PF_ENOMEM, p->path, p->line, "out of memory");
            p->props[p->nprops++] = q;
            e->n++;
            continue;
        }
        return s_header_err(p, "unknown header line '%.40s'", tok[0]);
    }
}

/* Reads one whitespace-separated ascii token into tok (NUL-terminated).
 * Returns 0, -1 at the end of the file, -2 if too long. */
static int s_token(s_ply_t *p, char *tok, size_t cap)
{
    for (;;) {
        if (p->pos == p->len && s_fill(p, 1)) {
            p->line = p->tok_line ? p->tok_line : p->line; /* report the end at the last data line */
            return -1;
        }
        unsigned char c = p->buf[p->pos];
        if (c == '\n')
            p->line++;
        else if (c != ' ' && c != '\t' && c != '\r' && c != '\v' && c != '\f')
            break;
        p->pos++;
    }
    size_t n = 0;
    while (p->pos < p->len || s_fill(p, 1) == 0) {
        unsigned char c = p->buf[p->pos];
        if (c == ' ' || c == '\t' || c == '\r' || c == '\n' || c == '\v' || c == '\f')
            break;
        if (n + 1 >= cap)
            return -2;
        tok[n++] = c == '\0' ? '?' : (char)c;
        p->pos++;
    }
    tok[n] = '\0';
    p->tok_line = p->line;
    return 0;
}


/* Reads one value of a scalar type as a double (exact for every integer type). */
static int s_value(s_ply_t *p, int type, double *out)
{
    p->voff = s_offset(p);
    if (p->format == S_ASCII) {
        char tok[80];
        int rc = s_token(p, tok, sizeof tok);
        if (rc == -1)
            return s_body_err(p, "unexpected end of file (the header promises more data)");
        if (rc == -2)
            return s_body_err(p, "malformed number '%.40s...'", tok);
        char *end;
        if (type == S_FLOAT) {
            const char *fend;
            float f;
            if (pf_fast_float(tok, &fend, &f) && !*fend) {
                *out = f;
                return PF_OK;
            }
            f = strtof(tok, &end);
            if (end == tok || *end)
                return s_body_err(p, "malformed number '%s'", tok);
            *out = f;
            return PF_OK;
        }
        if (type == S_DOUBLE) {
            *out = strtod(tok, &end);
            if (end == tok || *end)
                return s_body_err(p, "malformed number '%s'", tok);
            return PF_OK;
        }
        /* Integers by hand: strtoll would accept "0x10" and be slower. */
        const char *c = tok;
        int neg = *c == '-';
        c += neg || *c == '+';
        if (!*c)
            return s_body_err(p, "malformed integer '%s'", tok);
        double v = 0;
        for (; *c; c++) {
            if (*c < '0' || *c > '9')
                return s_body_err(p, "malformed integer '%s'", tok);
            v = v * 10 + (*c - '0'); /* exact below 2^53; larger is out of range anyway */
        }
        v = neg ? -v : v;
        if (v < s_lo[type] || v > s_hi[type])
            return s_body_err(p, "integer '%s' out of range for its type", tok);
        *out = v;
        return PF_OK;
    }
    unsigned sz = s_size[type];
    if (s_fill(p, sz))
        return s_body_err(p, "unexpected end of file (the header promises more data)");
    const unsigned char *b = p->buf + p->pos;
    uint64_t u = 0;
    if (p->format == S_BE)
        for (unsigned i = 0; i < sz; i++)
            u = u << 8 | b[i];
    else
        for (unsigned i = sz; i-- > 0;)
            u = u << 8 | b[i];
    p->pos += sz;
    switch (type) {
    case S_CHAR: *out = (double)(int8_t)(uint8_t)u; break;
    case S_UCHAR: *out = (double)(uint8_t)u; break;
    case S_SHORT: *out = (double)(int16_t)(uint16_t)u; break;
    case S_USHORT: *out = (double)(uint16_t)u; break;
    case S_INT: *out = (double)(int32_t)(uint32_t)u; break;
    case S_UINT: *out = (double)(uint32_t)u; break;
    case S_FLOAT: {
        uint32_t w = (uint32_t)u;
        float f;
        memcpy(&f, &w, sizeof f);
        *out = f;
        break;
    }
    default: {
        double d;
        memcpy(&d, &u, sizeof d);
        *out = d;
        break;
    }
    }
    return PF_OK;
}

/* Reads past n binary items of size sz. */
static int s_skip_bytes(s_ply_t *p, uint64_t n, unsigned sz)
{
    p->voff = s_offset(p);
    if (n > s_left(p) / sz)
        return s_body_err(p, "a list of %" PRIu64 " items runs past the end of the file", n);
    uint64_t left = n * sz;
    while (left > 0) {
        if (s_fill(p, 1))
            return s_body_err(p, "unexpected end of file (the header promises more data)");
        size_t take = p->len - p->pos;
        if (take > left)
            take = (size_t)left;
        p->pos += take;
        left -= take;
    }
    return PF_OK;
}

/* The state of the mesh being built. */
typedef struct s_mesh_build {
    pf_vec3 *pos, *nrm;
    float *uv;
    uint32_t nverts;
    uint32_t *idx;
    size_t ntris, cap_idx;
    int flip;
} s_build_t;

static int s_read_face(s_ply_t *p, const s_prop_t *q, s_build_t *b, uint64_t face)
{
    double d;
    int rc = s_value(p, q->count_type, &d);
    if (rc)
        return rc;
    if (d < 3)
        return s_body_err(p, "face %" PRIu64 " has %.0f vertices; it needs at least 3", face, d);
    uint64_t n = (uint64_t)d;
    uint64_t left = s_left(p);
    if (p->format == S_ASCII ? n > left / 2 + 1 : n > left / s_size[q->type])
        return s_body_err(p, "face %" PRIu64 " with %" PRIu64 " vertices runs past the end of the file", face, n);
    if (pf_reserve((void **)&b->idx, &b->cap_idx, 3 * (b->ntris + n - 2), sizeof *b->idx))
        return pf_error_set(p->err, PF_ENOMEM, p->path, 0, "out of memory");
    uint32_t first = 0, prev = 0;
    for (uint64_t k = 0; k < n; k++) {
        if ((rc = s_value(p, q->type, &d)))
            return rc;
        if (!(d >= 0 && d < (double)b->nverts))
            return s_body_err(p, "face %" PRIu64 ": vertex index %.0f out of range (%u vertices)", face, d,
                              b->nverts);
        uint32_t v = (uint32_t)d;
        if (k >= 2) {
            uint32_t *t = &b->idx[3 * b->ntris++];
            t[0] = first;
            t[1] = b->flip ? v : prev;
            t[2] = b->flip ? prev : v;
        }
        if (k == 0)
            first = v;
        prev = v;
    }
    return PF_OK;
}

/* Reads every element in header order; only ve and fe are kept. */
static int s_read_body(s_ply_t *p, s_build_t *b, const s_elem_t *ve, const s_elem_t *fe)
{
    for (size_t ei = 0; ei < p->nelems; ei++) {
        const s_elem_t *e = &p->elems[ei];
        const s_prop_t *props = &p->props[e->first];
        int is_vertex = e == ve, is_face = e == fe;
        for (uint64_t i = 0; i < e->count; i++) {
            double c[S_INDICES] = { 0 };
            uint64_t start = s_offset(p);
            for (size_t k = 0; k < e->n; k++) {
                const s_prop_t *q = &props[k];
                int rc;
                if (!q->list) {
                    double d;
                    if ((rc = s_value(p, q->type, &d)))
                        return rc;
                    c[q->role < S_INDICES ? q->role : 0] = d;
                    continue;
                }
                if (q->role == S_INDICES && is_face) {
                    if ((rc = s_read_face(p, q, b, i)))
                        return rc;
                    continue;
                }
                double d;
                if ((rc = s_value(p, q->count_type, &d)))
                    return rc;
                if (d < 0)
                    return s_body_err(p, "negative list length %.0f", d);
                if (p->format != S_ASCII) {
                    if ((rc = s_skip_bytes(p, (uint64_t)d, s_size[q->type])))
                        return rc;
                    continue;
                }
                for (uint64_t j = 0; j < (uint64_t)d; j++) {
                    double skip;
                    if ((rc = s_value(p, q->type, &skip)))
                        return rc;
                }
            }
            if (!is_vertex)
                continue;
            pf_vec3 x = pf_v3((float)c[S_X], (float)c[S_Y], (float)c[S_Z]);
            p->voff = start; /* binary messages point at the vertex */
            if (!pf_is_finite3(x))
                return s_body_err(p, "vertex %" PRIu64 " has a non-finite coordinate", i);
            b->pos[i] = x;
            if (b->nrm) {
                pf_vec3 n = pf_v3((float)c[S_NX], (float)c[S_NY], (float)c[S_NZ]);
                if (!pf_is_finite3(n))
                    return s_body_err(p, "vertex %" PRIu64 " has a non-finite normal", i);
                b->nrm[i] = n;
            }
            if (b->uv) {
                b->uv[2 * i] = (float)c[S_U];
                b->uv[2 * i + 1] = (float)c[S_V];
                if (!isfinite(b->uv[2 * i]) || !isfinite(b->uv[2 * i + 1]))
                    return s_body_err(p, "vertex %" PRIu64 " has a non-finite texture coordinate", i);
            }
        }
    }
    return PF_OK;
}

/* Finds the vertex and face elements (*ve, *fe) and the roles their
 * properties play, and checks the counts of every element against the bytes
 * after the header. */
static int s_find_elements(s_ply_t *p, const s_elem_t **vep, const s_elem_t **fep, int roles[S_INDICES + 1])
{
    const s_elem_t *ve = NULL, *fe = NULL;
    uint64_t need = 0, body = s_left(p);
    for (size_t ei = 0; ei < p->nelems; ei++) {
        const s_elem_t *e = &p->elems[ei];
        if (!ve && strcmp(e->name, "vertex") == 0) {
            ve = e;
            for (size_t k = 0; k < e->n; k++)
                roles[p->props[e->first + k].role] = 1;
        }
        if (!fe && strcmp(e->name, "face") == 0) {
            fe = e;
            for (size_t k = 0; k < e->n; k++)
                roles[p->props[e->first + k].role] = 1;
        }
        if (e->count > 0 && e->n == 0) {
            p->line = e->line;
            return s_header_err(p, "element '%s' has no properties", e->name);
        }
        uint64_t per = 0;
        for (size_t k = 0; k < e->n; k++) {
            const s_prop_t *q = &p->props[e->first + k];
            per += p->format == S_ASCII ? 2 : s_size[q->list ? q->count_type : q->type];
        }
        uint64_t bytes;
        if (__builtin_mul_overflow(e->count, per, &bytes) || __builtin_add_overflow(need, bytes, &need) ||
            need > body + (p->format == S_ASCII)) {
            p->line = e->line;
            return s_header_err(p,
                                "the header promises %" PRIu64 " '%s' elements, more than the %" PRIu64
                                " bytes after the header can hold",
                                e->count, e->name, body);
        }
    }
    if (!ve || !roles[S_X] || !roles[S_Y] || !roles[S_Z])
        return pf_error_set(p->err, PF_EPARSE, p->path, ve ? ve->line : p->line,
                            "no vertex element with x, y and z properties");
    if (!fe || !roles[S_INDICES])
        return pf_error_set(p->err, PF_EUNSUPPORTED, p->path, fe ? fe->line : p->line,
                            "no face element with a vertex_indices list (point clouds are not supported)");
    if (ve->count > UINT32_MAX)
        return pf_error_set(p->err, PF_EUNSUPPORTED, p->path, ve->line, "more than 2^32 - 1 vertices");
    *vep = ve;
    *fep = fe;
    return PF_OK;
}

/* Whether path names a gzip-compressed file (".gz"). */
static int s_is_gz(const char *path)
{
    size_t n = strlen(path);
    return n > 3 && strcasecmp(path + n - 3, ".gz") == 0;
}

/* Inflates the gzip file at path into a new buffer: *out (owned by the
 * caller, at least one byte), *len bytes. At most S_GZ_MAX bytes, so that a
 * small file cannot expand into all of memory. */
#define S_GZ_MAX ((size_t)1 << 32)
static int s_inflate(const char *path, unsigned char **out, size_t *len, pf_error_t *err)
{
    gzFile gz = gzopen(path, "rb");
    if (!gz)
        return pf_error_set(err, errno == ENOMEM ? PF_ENOMEM : PF_EIO, path, 0, "cannot open: %s",
                            errno ? strerror(errno) : "out of memory");
    unsigned char *buf = NULL;
    size_t n = 0, cap = 0;
    int rc = PF_OK;
    for (;;) {
        if (n == cap) {
            if (cap >= S_GZ_MAX) {
                rc = pf_error_set(err, PF_ERANGE, path, 0, "inflates to more than %zu bytes", S_GZ_MAX);
                break;
            }
            size_t ncap = cap ? 2 * cap : (size_t)1 << 16;
            unsigned char *nb = realloc(buf, ncap);
            if (!nb) {
                rc = pf_error_set(err, PF_ENOMEM, path, 0, "out of memory");
                break;
            }
            buf = nb;
            cap = ncap;
        }
        size_t want = cap - n > (1u << 30) ? (1u << 30) : cap - n;
        int k = gzread(gz, buf + n, (unsigned)want);
        if (k < 0) {
            int zerr = 0;
            const char *msg = gzerror(gz, &zerr);
            rc = pf_error_set(err, zerr == Z_MEM_ERROR ? PF_ENOMEM : PF_EPARSE, path, 0, "not a valid gzip file: %s",
                              zerr == Z_ERRNO ? strerror(errno) : msg);
            break;
        }
        if (k == 0)
            break;
        n += (size_t)k;
    }
    gzclose(gz);
    if (rc) {
        free(buf);
        return rc;
    }
    *out = buf;
    *len = n;
    return PF_OK;
}

/* Opens the file for reading and fills p->f and p->fsize; a .gz file is
 * inflated into *inflated (freed by the caller after fclose) and read from
 * memory. */
static int s_open(s_ply_t *p, unsigned char **inflated)
{
    if (s_is_gz(p->path)) {
        size_t n = 0;
        int rc = s_inflate(p->path, inflated, &n, p->err);
        if (rc)
            return rc;
        if (n == 0)
            return pf_error_set(p->err, PF_EPARSE, p->path, 1, "not a PLY file (it inflates to nothing)");
        p->f = fmemopen(*inflated, n, "rb");
        if (!p->f)
            return pf_error_set(p->err, PF_ENOMEM, p->path, 0, "cannot read the inflated file: %s", strerror(errno));
        p->fsize = n;
        return PF_OK;
    }
    p->f = fopen(p->path, "rb");
    if (!p->f)
        return pf_error_set(p->err, PF_EIO, p->path, 0, "cannot open: %s", strerror(errno));
    struct stat st;
    if (fstat(fileno(p->f), &st) != 0 || st.st_size < 0) {
        int rc = pf_error_set(p->err, PF_EIO, p->path, 0, "cannot stat: %s", strerror(errno));
        fclose(p->f);
        p->f = NULL;
        return rc;
    }
    p->fsize = (uint64_t)st.st_size;
    return PF_OK;
}

int pf_ply_load(pf_scene_t *scene, const char *path, const pf_xform_t *xf, uint32_t mat, pf_error_t *err)
{
    PF_CHECK(scene && path);
    if (mat >= scene->nmats)
        return pf_error_set(err, PF_EINVAL, path, 0, "material %u is not a scene material (%zu defined)", mat,
                            scene->nmats);
    pf_mesh_t m = { 0 };
    int rc = pf_ply_read(path, xf, mat, &m, err);
    if (rc == PF_OK && m.ntris > 0 && pf_scene_add_mesh(scene, &m))
        rc = pf_error_set(err, PF_ENOMEM, path, 0, "out of memory");
    pf_mesh_free(&m);
    return rc;
}

int pf_ply_read(const char *path, const pf_xform_t *xf, uint32_t mat, pf_mesh_t *out, pf_error_t *err)
{
    PF_CHECK(path && out);
    memset(out, 0, sizeof *out);
    s_ply_t p = { .path = path, .err = err };
    s_build_t b = { 0 };
    pf_mesh_t m = { 0 };
    unsigned char *inflated = NULL;
    int rc = s_open(&p, &inflated);
    if (rc)
        return rc;
    p.buf = malloc(S_BUF);
    if (!p.buf) {
        rc = pf_error_set(err, PF_ENOMEM, path, 0, "out of memory");
        goto done;
    }
    if ((rc = s_parse_header(&p)))
        goto done;

    /* Find the vertex and face elements and check the counts against the size. */
    const s_elem_t *ve = NULL, *fe = NULL;
    int roles[S_INDICES + 1] = { 0 };
    if ((rc = s_find_elements(&p, &ve, &fe, roles)))
        goto done;
    int normals = roles[S_NX] && roles[S_NY] && roles[S_NZ];
    if (!normals && (roles[S_NX] || roles[S_NY] || roles[S_NZ]))
        pf_warn("%s:%d: only some of nx, ny, nz are given; normals ignored", path, ve->line);
    b.nverts = (uint32_t)ve->count;
    b.flip = xf && pf_xform_det(xf) < 0.0f;
    /* The counts fit the file, so these sizes are bounded by its size. */
    b.pos = malloc((b.nverts ? b.nverts : 1) * sizeof *b.pos);
    b.nrm = normals ? malloc((b.nverts ? b.nverts : 1) * sizeof *b.nrm) : NULL;
    int uvs = roles[S_U] && roles[S_V];
    b.uv = uvs ? malloc((b.nverts ? 2 * (size_t)b.nverts : 1) * sizeof *b.uv) : NULL;
    if (!b.pos || (normals && !b.nrm) || (uvs && !b.uv) ||
        pf_reserve((void **)&b.idx, &b.cap_idx, 3 * (fe->count ? fe->count : 1), sizeof *b.idx)) {
        rc = pf_error_set(err, PF_ENOMEM, path, 0, "out of memory");
        goto done;
    }
    p.line++; /* the body starts on the line after end_header */
    if ((rc = s_read_body(&p, &b, ve, fe)))
        goto done;
    if (b.ntris == 0) {
        pf_warn("%s: the mesh has no faces", path);
        goto done;
    }

    const char *slash = strrchr(path, '/');
    const char *file = slash ? slash + 1 : path;
    char stem[256];
    snprintf(stem, sizeof stem, "%.*s", (int)(strlen(file) - (s_is_gz(file) ? 3 : 0)), file);
    const char *dot = strrchr(stem, '.');
    snprintf(m.name, sizeof m.name, "%.*s", (int)(dot && dot != stem ? dot - stem : (ptrdiff_t)strlen(stem)), stem);
    m.nverts = b.nverts;
    m.ntris = b.ntris;
    m.pos = b.pos;
    m.nrm = b.nrm;
    m.uv = b.uv;
    m.idx = b.idx;
    b.pos = b.nrm = NULL;
    b.uv = NULL;
    b.idx = NULL;
    m.mat = malloc(m.ntris * sizeof *m.mat);
    if (!m.mat) {
        rc = pf_error_set(err, PF_ENOMEM, path, 0, "out of memory");
        goto done;
    }
    for (size_t t = 0; t < m.ntris; t++)
        m.mat[t] = mat;
    if (xf) {
        for (size_t v = 0; v < m.nverts; v++) {
            m.pos[v] = pf_xform_point(xf, m.pos[v]);
            /* The cofactor matrix is det * the inverse transpose: negate for det < 0. */
            if (m.nrm)
                m.nrm[v] = b.flip ? pf_neg(pf_xform_normal(xf, m.nrm[v])) : pf_xform_normal(xf, m.nrm[v]);
        }
    }
    *out = m;
    memset(&m, 0, sizeof m);
done:
    pf_mesh_free(&m);
    free(b.pos);
    free(b.nrm);
    free(b.uv);
    free(b.idx);
    free(p.elems);
    free(p.props);
    free(p.buf);
    fclose(p.f);
    free(inflated);
    return rc;
}
