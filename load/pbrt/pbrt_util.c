/* pbrt_util.c: the pbrt-v4 reader's bookkeeping: interned names (material,
 * texture, object and coordinate-system names, warning kinds) with an
 * open-addressing index, the gathered warnings and their report, and the
 * 4x4 matrix helpers of the transforms. It owns nothing itself: the tables
 * live in the pf_pbrt_t of one load. Single-threaded. */
#include <math.h>
#include <stdarg.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "base/log.h"
#include "base/reserve.h"
#include "load/pbrt/pbrt_impl.h"

/* ---- names and warnings ---- */

static uint64_t s_hash(const char *s)
{
    uint64_t h = 1469598103934665603ull;
    for (; *s; s++)
        h = (h ^ (unsigned char)*s) * 1099511628211ull;
    return h;
}

int pf_pbrt_name_find(const pf_pbrt_t *c, const char *s)
{
    const pf_pbrt_names_t *nm = &c->names;
    if (!nm->nslots)
        return -1;
    for (size_t i = s_hash(s) & (nm->nslots - 1);; i = (i + 1) & (nm->nslots - 1)) {
        int32_t id = nm->slot[i];
        if (id < 0)
            return -1;
        if (strcmp(nm->s[id], s) == 0)
            return id;
    }
}

/* Grows the slot index to nslots and re-inserts every name. */
static int s_rehash(pf_pbrt_names_t *nm, size_t nslots)
{
    int32_t *slot = malloc(nslots * sizeof *slot);
    if (!slot)
        return PF_ENOMEM;
    for (size_t i = 0; i < nslots; i++)
        slot[i] = -1;
    for (size_t id = 0; id < nm->n; id++) {
        size_t i = s_hash(nm->s[id]) & (nslots - 1);
        while (slot[i] >= 0)
            i = (i + 1) & (nslots - 1);
        slot[i] = (int32_t)id;
    }
    free(nm->slot);
    nm->slot = slot;
    nm->nslots = nslots;
    return PF_OK;
}

/* Grows the name-indexed tables of c to hold id n - 1. */
static int s_named_grow(pf_pbrt_t *c, size_t n)
{
    if (n <= c->cap_named)
        return PF_OK;
    size_t cap = c->cap_named ? 2 * c->cap_named : 64;
    while (cap < n)
        cap *= 2;
    int32_t **tabs[] = { &c->named_mat, &c->named_ftex, &c->named_stex, &c->named_obj, &c->named_warn, &c->named_pair,
                         &c->named_medium };
    for (size_t t = 0; t < sizeof tabs / sizeof *tabs; t++) {
        int32_t *p = realloc(*tabs[t], cap * sizeof *p);
        if (!p)
            return PF_ENOMEM;
        for (size_t i = c->cap_named; i < cap; i++)
            p[i] = -1;
        *tabs[t] = p;
    }
    c->cap_named = cap;
    return PF_OK;
}

int pf_pbrt_intern(pf_pbrt_t *c, const char *s)
{
    int id = pf_pbrt_name_find(c, s);
    if (id >= 0)
        return id;
    pf_pbrt_names_t *nm = &c->names;
    if (nm->n >= INT32_MAX / 2)
        return PF_ENOMEM;
    if ((2 * (nm->n + 1) > nm->nslots && s_rehash(nm, nm->nslots ? 2 * nm->nslots : 256)) ||
        pf_reserve((void **)&nm->s, &nm->cap, nm->n + 1, sizeof *nm->s) || s_named_grow(c, nm->n + 1))
        return PF_ENOMEM;
    char *copy = strdup(s);
    if (!copy)
        return PF_ENOMEM;
    size_t i = s_hash(s) & (nm->nslots - 1);
    while (nm->slot[i] >= 0)
        i = (i + 1) & (nm->nslots - 1);
    nm->slot[i] = (int32_t)nm->n;
    nm->s[nm->n] = copy;
    return (int)nm->n++;
}

int pf_pbrt_warn(pf_pbrt_t *c, pf_pbrt_loc_t loc, const char *kind, const char *fmt, ...)
{
    char detail[512];
    va_list ap;
    va_start(ap, fmt);
    vsnprintf(detail, sizeof detail, fmt, ap);
    va_end(ap);
    if (c->strict)
        return pf_pbrt_error_line(c, PF_EUNSUPPORTED, loc, "%s: %s (an error with --strict)", kind, detail);
    int id = pf_pbrt_intern(c, kind);
    if (id < 0)
        return pf_pbrt_error(c, PF_ENOMEM, loc, "out of memory");
    int32_t *w = &c->named_warn[id];
    if (*w >= 0) {
        c->warnings[*w].count++;
        return PF_OK;
    }
    char first[768];
    snprintf(first, sizeof first, "%.200s:%d: %s: %s", pf_pbrt_file_name(c, loc), loc.line, kind, detail);
    if (pf_reserve((void **)&c->warnings, &c->cap_warnings, c->nwarnings + 1, sizeof *c->warnings))
        return pf_pbrt_error(c, PF_ENOMEM, loc, "out of memory");
    pf_pbrt_warning_t *pw = &c->warnings[c->nwarnings];
    pw->kind = strdup(kind);
    pw->first = strdup(first);
    pw->count = 1;
    if (!pw->kind || !pw->first) {
        free(pw->kind);
        free(pw->first);
        return pf_pbrt_error(c, PF_ENOMEM, loc, "out of memory");
    }
    *w = (int32_t)c->nwarnings++;
    return PF_OK;
}

/* Prints one line per warning kind and fills the caller's report. */
void pf_pbrt_report(pf_pbrt_t *c)
{
    for (size_t i = 0; i < c->nwarnings; i++) {
        const pf_pbrt_warning_t *w = &c->warnings[i];
        if (i < PF_PBRT_MAX_PRINTED) {
            if (w->count > 1)
                pf_warn("%s (%u times; this is the first)", w->first, w->count);
            else
                pf_warn("%s", w->first);
        }
        if (c->report && c->report->nwarnings < PF_LOAD_MAX_WARNINGS) {
            pf_load_warning_t *r = &c->report->warnings[c->report->nwarnings++];
            snprintf(r->kind, sizeof r->kind, "%s", w->kind);
            snprintf(r->first, sizeof r->first, "%s", w->first);
            r->count = w->count;
        } else if (c->report) {
            c->report->more++;
        }
    }
    if (c->nwarnings > PF_PBRT_MAX_PRINTED)
        pf_warn("%s: %zu more kinds of warnings not shown", c->scene->path, c->nwarnings - PF_PBRT_MAX_PRINTED);
}

/* ---- matrices ---- */

void pf_pbrt_m4_identity(pf_pbrt_m4 m)
{
    memset(m, 0, sizeof(pf_pbrt_m4));
    for (int i = 0; i < 4; i++)
        m[i][i] = 1.0;
}

void pf_pbrt_m4_mul(const pf_pbrt_m4 a, const pf_pbrt_m4 b, pf_pbrt_m4 out)
{
    pf_pbrt_m4 r;
    for (int i = 0; i < 4; i++)
        for (int j = 0; j < 4; j++)
            r[i][j] = a[i][0] * b[0][j] + a[i][1] * b[1][j] + a[i][2] * b[2][j] + a[i][3] * b[3][j];
    memcpy(out, r, sizeof r);
}

int pf_pbrt_m4_inverse(const pf_pbrt_m4 m, pf_pbrt_m4 out)
{
    double a[4][8];
    for (int i = 0; i < 4; i++)
        for (int j = 0; j < 8; j++)
            a[i][j] = j < 4 ? m[i][j] : (j - 4 == i);
    for (int col = 0; col < 4; col++) {
        int piv = col;
        for (int r = col + 1; r < 4; r++)
            if (fabs(a[r][col]) > fabs(a[piv][col]))
                piv = r;
        if (!(fabs(a[piv][col]) > 1e-300))
            return -1;
        for (int j = 0; j < 8; j++) {
            double t = a[col][j];
            a[col][j] = a[piv][j];
            a[piv][j] = t;
        }
        double inv = 1.0 / a[col][col];
        for (int j = 0; j < 8; j++)
            a[col][j] *= inv;
        for (int r = 0; r < 4; r++) {
            if (r == col || a[r][col] == 0.0)
                continue;
            double f = a[r][col];
            for (int j = 0; j < 8; j++)
                a[r][j] -= f * a[col][j];
        }
    }
    for (int i = 0; i < 4; i++)
        for (int j = 0; j < 4; j++)
            out[i][j] = a[i][j + 4];
    for (int i = 0; i < 4; i++)
        for (int j = 0; j < 4; j++)
            if (!isfinite(out[i][j]))
                return -1;
    return 0;
}

double pf_pbrt_m4_det3(const pf_pbrt_m4 m)
{
    return m[0][0] * (m[1][1] * m[2][2] - m[1][2] * m[2][1]) - m[0][1] * (m[1][0] * m[2][2] - m[1][2] * m[2][0]) +
           m[0][2] * (m[1][0] * m[2][1] - m[1][1] * m[2][0]);
}

/* A named texture of the kind asked for (float or spectrum), declared
 * earlier by a Texture directive. */
int pf_pbrt_find_texture(pf_pbrt_t *c, const char *name, int is_float, pf_pbrt_loc_t loc, pf_pbrt_tex_t **out)
{
    int id = pf_pbrt_name_find(c, name);
    int32_t t = id < 0 ? -1 : is_float ? c->named_ftex[id] : c->named_stex[id];
    if (t < 0)
        return pf_pbrt_error(c, PF_EPARSE, loc, "no %s texture named \"%s\"", is_float ? "float" : "spectrum", name);
    *out = &c->texs[t];
    return PF_OK;
}
