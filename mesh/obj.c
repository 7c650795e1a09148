/* obj.c: reads Wavefront OBJ geometry into scene meshes. It owns the file's
 * parsing state for one call: the file-wide position and normal lists, the
 * mesh being read and the finished meshes, which go to the scene only when
 * the whole file has parsed (so a failed load adds no meshes; materials that
 * its `mtllib` files defined may stay). Called on the one thread that builds
 * the scene.
 *
 * Supported: v (x y z, a fourth w or trailing colour values are ignored), vt
 * (u and v; a w is ignored), vn, f with v, v/vt, v//vn and v/vt/vn corners and
 * positive or negative (relative) indices, polygons fan-triangulated as
 * (0, i, i+1), usemtl, mtllib (paths relative to the OBJ's folder, several
 * per line, no spaces inside a name), g and o (each starts a new mesh), s
 * (ignored), comments, blank lines, CRLF, tabs. Other statements (l, p, curv,
 * ...) are skipped with one warning per keyword.
 *
 * Vertices. OBJ indexes positions, uvs and normals separately; a mesh vertex
 * is one distinct (position, normal, uv) triple, found through per-position chains
 * when the mesh ends, so pos and nrm have one entry per vertex. In a mesh
 * where some faces have normals and others do not (the alternative, split
 * meshes, was not chosen), the corners without one get their face's
 * geometric normal (Newell's normal of the polygon, oriented by the winding
 * as stored, so it agrees with the triangle's face normal); those corners
 * are shared only within their face, which keeps flat faces flat. A mesh
 * without any normals gets nrm = NULL and shares vertices by position. Texture
 * coordinates likewise: a mesh with a vt on any corner gets uv, (0, 0) on the
 * corners without; one without gets uv = NULL.
 *
 * Materials. Each triangle carries the material of the last usemtl before
 * it. Names resolve when the file ends, so an mtllib after its usemtl still
 * works. Faces before any usemtl and faces naming an unknown material use
 * the scene material "default" (added once if absent; one warning per
 * unknown name). A missing or unreadable MTL file is a warning, not an error;
 * a malformed one is an error. mat_override >= 0 gives every triangle that
 * material and skips the MTL files.
 *
 * Transform. Positions go through xf as they are read, normals through its
 * inverse transpose. A mirroring xf (det < 0) reverses every triangle's
 * winding and negates the transformed normals, so face and shading normals
 * keep pointing out of the same side of the surface. */
#include "base/reserve.h"
#include "mesh/mesh.h"

#include <errno.h>
#include <math.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "base/log.h"
#include "mesh/text.h"

/* A corner's normal reference: an index into the file's vn list, or, with
 * S_FACE_NRM set, into the mesh's list of face normals. */
#define S_NO_NRM UINT32_MAX
#define S_FACE_NRM 0x80000000u
#define S_NONE UINT32_MAX /* end of a vertex chain */
#define S_NO_UV UINT32_MAX
#define S_MAX_WARNED 16

typedef struct s_slot {
    char name[PF_NAME_MAX]; /* "" for faces before any usemtl */
    int line;               /* of the first usemtl naming it */
    int used;               /* some triangle refers to it */
} s_slot_t;

typedef struct s_obj {
    pf_scene_t *scene;
    const char *path;
    int line;
    pf_error_t *err;
    const pf_xform_t *xf; /* NULL: identity */
    int flip;             /* det(xf) < 0 */
    int mat_override;
    char dir[1024];            /* the OBJ's folder, with its trailing slash, or "" */
    char base[PF_NAME_MAX];    /* file name without folder and extension */
    /* File-wide vertex data, already in world space. */
    pf_vec3 *pos;
    size_t npos, cap_pos;
    pf_vec3 *nrm;
    size_t nnrm, cap_nrm;
    float *tex; /* 2 per vt */
    size_t ntex, cap_tex;
    /* The mesh being read: 3 corners per triangle, each (normal ref << 32 | position). */
    char name[PF_NAME_MAX];
    uint64_t *corner;
    size_t ncorner, cap_corner;
    uint32_t *cuv; /* each corner's vt index, or S_NO_UV */
    size_t cap_cuv;
    int has_uv;
    uint32_t *tmat; /* material slot per triangle */
    size_t ntri, cap_tmat;
    pf_vec3 *fnrm; /* face normals for corners without vn */
    size_t nfnrm, cap_fnrm;
    int has_nrm;
    /* Scratch for one face. */
    uint32_t *fv, *fn, *ft;
    size_t cap_fv, cap_fn, cap_ft;
    /* usemtl names; slot 0 is "no usemtl". */
    s_slot_t *slots;
    size_t nslots, cap_slots;
    uint32_t cur_slot;
    /* Vertex sharing when a mesh ends: head[position] starts a chain of the
     * mesh's vertices at that position (S_NONE when none), linked by vnext;
     * vref is each vertex's normal reference. */
    uint32_t *head, *vnext, *vref, *vuv;
    size_t nhead, cap_head, cap_vnext, cap_vref, cap_vuv;
    /* Finished meshes; mat[] still holds slot numbers. */
    pf_mesh_t *meshes;
    size_t nmeshes, cap_meshes;
    pf_text_warned_t warned;
} s_obj_t;

#define S_RESERVE(o, arr, cap, need) pf_reserve((void **)&(arr), &(cap), (need), sizeof *(arr))

static int s_nomem(s_obj_t *o) { return pf_error_set(o->err, PF_ENOMEM, o->path, o->line, "out of memory"); }

/* Reads n >= 1 required floats of a statement; checks they are finite. */
static int s_floats(s_obj_t *o, const char **pp, int n, float *v, const char *kw)
{
    for (int i = 0; i < n; i++) {
        const char *tok = pf_text_skip_ws(*pp);
        int rc = pf_text_float(pp, 1, &v[i]);
        if (rc == 1)
            return pf_error_set(o->err, PF_EPARSE, o->path, o->line, "'%s' needs %d numbers, found %d", kw, n, i);
        if (rc < 0)
            return pf_text_bad_number(o->err, o->path, o->line, tok);
        if (!isfinite(v[i]))
            return pf_error_set(o->err, PF_EPARSE, o->path, o->line, "non-finite value '%.*s' in '%s'",
                                pf_text_show(tok), tok, kw);
    }
    return PF_OK;
}

/* The rest of the statement as a name: leading and trailing blanks dropped,
 * truncated (with a warning) to fit PF_NAME_MAX. */
static void s_rest_name(s_obj_t *o, const char *p, char *out)
{
    size_t n;
    p = pf_text_rest(p, &n);
    if (n >= PF_NAME_MAX)
        pf_warn("%s:%d: name '%.*s' truncated to %d bytes", o->path, o->line, (int)n, p, PF_NAME_MAX - 1);
    snprintf(out, PF_NAME_MAX, "%.*s", (int)n, p);
}

/* Parses one OBJ index at *pp and resolves it against count entries so far
 * (1-based, or negative = relative to the end). */
static int s_index(s_obj_t *o, const char **pp, size_t count, const char *what, const char *corner, uint32_t *out)
{
    const char *p = *pp;
    int neg = 0;
    if (*p == '-' || *p == '+')
        neg = *p++ == '-';
    if (*p < '0' || *p > '9')
        return pf_error_set(o->err, PF_EPARSE, o->path, o->line, "malformed face vertex '%.*s'",
                            pf_text_show(corner), corner);
    uint64_t v = 0;
    const char *digits = p;
    for (; *p >= '0' && *p <= '9'; p++)
        v = v > (1ull << 40) ? v : v * 10 + (uint64_t)(*p - '0'); /* saturates: out of range anyway */
    if (v == 0)
        return pf_error_set(o->err, PF_EPARSE, o->path, o->line,
                            "%s index 0 in '%.*s' is invalid (OBJ indices start at 1)", what, pf_text_show(corner),
                            corner);
    if (v > count)
        return pf_error_set(o->err, PF_EPARSE, o->path, o->line, "%s index %s%.*s out of range (%zu defined so far)",
                            what, neg ? "-" : "", (int)(p - digits), digits, count);
    *out = (uint32_t)(neg ? count - v : v - 1);
    *pp = p;
    return PF_OK;
}

/* Newell's normal of the face's polygon, unit length (or zero if degenerate). */
static pf_vec3 s_face_normal(const s_obj_t *o, size_t n)
{
    pf_vec3 s = pf_v3s(0.0f);
    for (size_t i = 0; i < n; i++) {
        pf_vec3 a = o->pos[o->fv[i]], b = o->pos[o->fv[(i + 1) % n]];
        s.x += (a.y - b.y) * (a.z + b.z);
        s.y += (a.z - b.z) * (a.x + b.x);
        s.z += (a.x - b.x) * (a.y + b.y);
    }
    return pf_norm(s);
}

static int s_face(s_obj_t *o, const char *p)
{
    size_t n = 0;
    int missing = 0;
    for (;;) {
        p = pf_text_skip_ws(p);
        if (pf_text_is_eol(*p))
            break;
        const char *corner = p;
        uint32_t vi, ti = S_NO_UV, ni = S_NO_NRM;
        int rc = s_index(o, &p, o->npos, "vertex", corner, &vi);
        if (!rc && *p == '/') {
            p++;
            if (*p != '/' && !pf_text_is_delim(*p))
                rc = s_index(o, &p, o->ntex, "texture coordinate", corner, &ti);
            if (!rc && *p == '/') {
                p++;
                if (!pf_text_is_delim(*p))
                    rc = s_index(o, &p, o->nnrm, "normal", corner, &ni);
            }
        }
        if (rc)
            return rc;
        if (!pf_text_is_delim(*p))
            return pf_error_set(o->err, PF_EPARSE, o->path, o->line, "malformed face vertex '%.*s'",
                                pf_text_show(corner), corner);
        if ((n >= o->cap_fv && S_RESERVE(o, o->fv, o->cap_fv, n + 1)) ||
            (n >= o->cap_fn && S_RESERVE(o, o->fn, o->cap_fn, n + 1)) ||
            (n >= o->cap_ft && S_RESERVE(o, o->ft, o->cap_ft, n + 1)))
            return s_nomem(o);
        o->fv[n] = vi;
        o->fn[n] = ni;
        o->ft[n] = ti;
        o->has_uv |= ti != S_NO_UV;
        missing |= ni == S_NO_NRM;
        o->has_nrm |= ni != S_NO_NRM;
        n++;
    }
    if (n < 3)
        return pf_error_set(o->err, PF_EPARSE, o->path, o->line, "face has %zu vertices; it needs at least 3", n);
    size_t nt = n - 2;
    if (o->ncorner + 3 * nt > UINT32_MAX || o->nfnrm >= S_FACE_NRM - 1)
        return pf_error_set(o->err, PF_EPARSE, o->path, o->line, "mesh '%s' is too large (over 2^32 corners)",
                            o->name);
    if (S_RESERVE(o, o->corner, o->cap_corner, o->ncorner + 3 * nt) ||
        S_RESERVE(o, o->cuv, o->cap_cuv, o->ncorner + 3 * nt) ||
        S_RESERVE(o, o->tmat, o->cap_tmat, o->ntri + nt))
        return s_nomem(o);
    if (missing) {
        /* Keep the face's own normal in case a later face of the mesh has vn. */
        if (S_RESERVE(o, o->fnrm, o->cap_fnrm, o->nfnrm + 1))
            return s_nomem(o);
        pf_vec3 fnrm = s_face_normal(o, n);
        o->fnrm[o->nfnrm] = o->flip ? pf_neg(fnrm) : fnrm;
        for (size_t i = 0; i < n; i++)
            if (o->fn[i] == S_NO_NRM)
                o->fn[i] = S_FACE_NRM | (uint32_t)o->nfnrm;
        o->nfnrm++;
    }
    for (size_t i = 1; i + 1 < n; i++) {
        size_t c[3] = { 0, i, i + 1 };
        if (o->flip) {
            c[1] = i + 1;
            c[2] = i;
        }
        for (int k = 0; k < 3; k++) {
            o->cuv[o->ncorner] = o->ft[c[k]];
            o->corner[o->ncorner++] = (uint64_t)o->fn[c[k]] << 32 | o->fv[c[k]];
        }
        o->tmat[o->ntri++] = o->cur_slot;
    }
    o->slots[o->cur_slot].used = 1;
    return PF_OK;
}

static void s_reset_mesh(s_obj_t *o)
{
    o->ncorner = o->ntri = o->nfnrm = 0;
    o->has_nrm = 0;
    o->has_uv = 0;
}

/* Turns the mesh being read into a pf_mesh_t with one vertex per distinct
 * corner, and starts an empty one. */
static int s_flush(s_obj_t *o)
{
    int rc = PF_OK;
    pf_mesh_t m;
    memset(&m, 0, sizeof m);
    if (o->ntri == 0) {
        s_reset_mesh(o);
        return PF_OK;
    }
    size_t nc = o->ncorner;
    snprintf(m.name, sizeof m.name, "%s", o->name);
    m.pos = malloc(nc * sizeof *m.pos);
    m.nrm = o->has_nrm ? malloc(nc * sizeof *m.nrm) : NULL;
    m.uv = o->has_uv ? malloc(2 * nc * sizeof *m.uv) : NULL;
    m.idx = malloc(nc * sizeof *m.idx);
    if (!m.pos || !m.idx || (o->has_nrm && !m.nrm) || (o->has_uv && !m.uv) ||
        S_RESERVE(o, o->meshes, o->cap_meshes, o->nmeshes + 1) || S_RESERVE(o, o->vnext, o->cap_vnext, nc) ||
        S_RESERVE(o, o->vref, o->cap_vref, nc) || S_RESERVE(o, o->vuv, o->cap_vuv, nc)) {
        rc = s_nomem(o);
        goto fail;
    }
    if (o->nhead < o->npos) {
        if (S_RESERVE(o, o->head, o->cap_head, o->npos)) {
            rc = s_nomem(o);
            goto fail;
        }
        memset(o->head + o->nhead, 0xff, (o->npos - o->nhead) * sizeof *o->head);
        o->nhead = o->npos;
    }
    /* Vertices with the same position form a chain from head[position];
     * chains are short (one per distinct normal at that position), and the
     * lookups follow the file's own locality. */
    uint32_t nv = 0;
    for (size_t c = 0; c < nc; c++) {
        uint32_t pi = (uint32_t)o->corner[c];
        uint32_t r = o->has_nrm ? (uint32_t)(o->corner[c] >> 32) : 0;
        uint32_t t = o->has_uv ? o->cuv[c] : S_NO_UV;
        uint32_t v = o->head[pi];
        while (v != S_NONE && (o->vref[v] != r || o->vuv[v] != t))
            v = o->vnext[v];
        if (v == S_NONE) {
            v = nv++;
            o->vref[v] = r;
            o->vuv[v] = t;
            if (m.uv) {
                m.uv[2 * v] = t == S_NO_UV ? 0.0f : o->tex[2 * (size_t)t];
                m.uv[2 * v + 1] = t == S_NO_UV ? 0.0f : o->tex[2 * (size_t)t + 1];
            }
            o->vnext[v] = o->head[pi];
            o->head[pi] = v;
            m.pos[v] = o->pos[pi];
            if (m.nrm)
                m.nrm[v] = (r & S_FACE_NRM) ? o->fnrm[r & ~S_FACE_NRM] : o->nrm[r];
        }
        m.idx[c] = v;
    }
    /* Clear the heads this mesh used, for the next mesh. */
    for (size_t c = 0; c < nc; c++)
        o->head[(uint32_t)o->corner[c]] = S_NONE;
    m.nverts = nv;
    m.ntris = o->ntri;
    /* Give back what the sharing saved; a failed shrink keeps the old block. */
    void *p = realloc(m.pos, nv * sizeof *m.pos);
    m.pos = p ? p : m.pos;
    if (m.nrm) {
        p = realloc(m.nrm, nv * sizeof *m.nrm);
        m.nrm = p ? p : m.nrm;
    }
    if (m.uv) {
        p = realloc(m.uv, 2 * (size_t)nv * sizeof *m.uv);
        m.uv = p ? p : m.uv;
    }
    p = realloc(o->tmat, o->ntri * sizeof *o->tmat);
    m.mat = p ? p : o->tmat;
    o->tmat = NULL;
    o->cap_tmat = 0;
    o->meshes[o->nmeshes++] = m;
    s_reset_mesh(o);
    return PF_OK;
fail:
    pf_mesh_free(&m);
    s_reset_mesh(o);
    return rc;
}

static int s_usemtl(s_obj_t *o, const char *p)
{
    char name[PF_NAME_MAX];
    s_rest_name(o, p, name);
    if (!name[0]) {
        o->cur_slot = 0;
        return PF_OK;
    }
    if (strcmp(o->slots[o->cur_slot].name, name) == 0)
        return PF_OK;
    for (size_t i = 1; i < o->nslots; i++) {
        if (strcmp(o->slots[i].name, name) == 0) {
            o->cur_slot = (uint32_t)i;
            return PF_OK;
        }
    }
    if (o->nslots >= UINT32_MAX || S_RESERVE(o, o->slots, o->cap_slots, o->nslots + 1))
        return s_nomem(o);
    s_slot_t *s = &o->slots[o->nslots];
    memset(s, 0, sizeof *s);
    memcpy(s->name, name, sizeof s->name);
    s->line = o->line;
    o->cur_slot = (uint32_t)o->nslots++;
    return PF_OK;
}

static int s_mtllib(s_obj_t *o, const char *p)
{
    for (;;) {
        p = pf_text_skip_ws(p);
        if (pf_text_is_eol(*p))
            return PF_OK;
        int n = pf_text_token_len(p);
        const char *name = p;
        p += n;
        if (o->mat_override >= 0)
            continue;
        char full[2048];
        if (name[0] == '/')
            snprintf(full, sizeof full, "%.*s", n, name);
        else
            snprintf(full, sizeof full, "%s%.*s", o->dir, n, name);
        pf_error_t e;
        e.msg[0] = '\0';
        int rc = pf_mtl_load(o->scene, full, &e);
        if (rc == PF_EIO) {
            pf_warn("%s:%d: skipping material library: %s; faces using its materials get 'default'", o->path,
                    o->line, e.msg);
        } else if (rc) {
            if (o->err)
                *o->err = e;
            return rc;
        }
    }
}

/* Handles one statement for pf_text_read_statements; arg is the s_obj_t. */
static int s_statement(void *arg, const char *kw, int kwlen, const char *p)
{
    s_obj_t *o = arg;
#define S_KW(s) (kwlen == (int)sizeof(s) - 1 && memcmp(kw, s, sizeof(s) - 1) == 0)
    float v[3];
    int rc;
    if (S_KW("v")) {
        if ((rc = s_floats(o, &p, 3, v, "v")))
            return rc;
        /* A fourth value (w) or vertex colours may follow; they are ignored. */
        if (o->npos >= UINT32_MAX - 1)
            return pf_error_set(o->err, PF_EPARSE, o->path, o->line, "too many vertices (over 2^32)");
        if (S_RESERVE(o, o->pos, o->cap_pos, o->npos + 1))
            return s_nomem(o);
        pf_vec3 x = pf_v3(v[0], v[1], v[2]);
        o->pos[o->npos++] = o->xf ? pf_xform_point(o->xf, x) : x;
        return PF_OK;
    }
    if (S_KW("f"))
        return s_face(o, p);
    if (S_KW("vn")) {
        if ((rc = s_floats(o, &p, 3, v, "vn")))
            return rc;
        if (o->nnrm >= S_FACE_NRM - 1)
            return pf_error_set(o->err, PF_EPARSE, o->path, o->line, "too many normals (over 2^31)");
        if (S_RESERVE(o, o->nrm, o->cap_nrm, o->nnrm + 1))
            return s_nomem(o);
        pf_vec3 n = pf_v3(v[0], v[1], v[2]);
        if (o->xf) {
            /* pf_xform_normal uses the cofactor matrix, which is det * the
             * inverse transpose: its sign flips with a mirroring xf. */
            n = pf_xform_normal(o->xf, n);
            n = o->flip ? pf_neg(n) : n;
        }
        o->nrm[o->nnrm++] = n;
        return PF_OK;
    }
    if (S_KW("vt")) {
        /* u [v [w]]: v defaults to 0, w is ignored. */
        if ((rc = s_floats(o, &p, 1, v, "vt")))
            return rc;
        const char *q = pf_text_skip_ws(p);
        v[1] = 0.0f;
        if (!pf_text_is_eol(*q) && (rc = s_floats(o, &p, 1, v + 1, "vt")))
            return rc;
        if (o->ntex >= S_NO_UV - 1)
            return pf_error_set(o->err, PF_EPARSE, o->path, o->line, "too many texture coordinates (over 2^32)");
        if (S_RESERVE(o, o->tex, o->cap_tex, 2 * o->ntex + 2))
            return s_nomem(o);
        o->tex[2 * o->ntex] = v[0];
        o->tex[2 * o->ntex + 1] = v[1];
        o->ntex++;
        return PF_OK;
    }
    if (S_KW("g") || S_KW("o")) {
        if ((rc = s_flush(o)))
            return rc;
        s_rest_name(o, p, o->name);
        if (!o->name[0])
            memcpy(o->name, o->base, sizeof o->name);
        return PF_OK;
    }
    if (S_KW("usemtl"))
        return s_usemtl(o, p);
    if (S_KW("mtllib"))
        return s_mtllib(o, p);
    if (S_KW("s"))
        return PF_OK;
    pf_text_warn_keyword(&o->warned, o->path, o->line, kw, kwlen);
    return PF_OK;
#undef S_KW
}

/* Maps material slots to scene materials and hands the meshes to the scene. */
static int s_commit(s_obj_t *o)
{
    uint32_t *map = malloc(o->nslots * sizeof *map);
    if (!map)
        return s_nomem(o);
    int def = -1, rc = PF_OK;
    for (size_t s = 0; s < o->nslots && rc == PF_OK; s++) {
        if (!o->slots[s].used)
            continue;
        if (o->mat_override >= 0) {
            map[s] = (uint32_t)o->mat_override;
            continue;
        }
        int idx = s ? pf_scene_find_material(o->scene, o->slots[s].name) : -1;
        if (idx < 0) {
            if (s)
                pf_warn("%s:%d: unknown material '%s'; its faces use 'default'", o->path, o->slots[s].line,
                        o->slots[s].name);
            if (def < 0) {
                def = pf_scene_find_material(o->scene, "default");
                if (def < 0) {
                    pf_material_t m = pf_material_default("default");
                    def = pf_scene_add_material(o->scene, &m);
                    if (def < 0)
                        rc = pf_error_set(o->err, PF_ENOMEM, o->path, 0, "out of memory");
                }
            }
            idx = def;
        }
        map[s] = (uint32_t)idx;
    }
    for (size_t i = 0; i < o->nmeshes && rc == PF_OK; i++) {
        pf_mesh_t *m = &o->meshes[i];
        for (size_t t = 0; t < m->ntris; t++)
            m->mat[t] = map[m->mat[t]];
        if (pf_scene_add_mesh(o->scene, m))
            rc = pf_error_set(o->err, PF_ENOMEM, o->path, 0, "out of memory");
    }
    free(map);
    return rc;
}

int pf_obj_load(pf_scene_t *scene, const char *path, const pf_xform_t *xf, int mat_override, pf_error_t *err)
{
    PF_CHECK(scene && path);
    if (mat_override >= 0 && (size_t)mat_override >= scene->nmats)
        return pf_error_set(err, PF_EINVAL, path, 0, "material override %d is not a scene material (%zu defined)",
                            mat_override, scene->nmats);
    FILE *f = fopen(path, "rb");
    if (!f)
        return pf_error_set(err, PF_EIO, path, 0, "cannot open: %s", strerror(errno));
    s_obj_t *o = calloc(1, sizeof *o);
    if (!o || S_RESERVE(o, o->slots, o->cap_slots, 1)) {
        if (o)
            free(o->slots);
        free(o);
        fclose(f);
        return pf_error_set(err, PF_ENOMEM, path, 0, "out of memory");
    }
    o->scene = scene;
    o->path = path;
    o->err = err;
    o->xf = xf;
    o->flip = xf && pf_xform_det(xf) < 0.0f;
    o->mat_override = mat_override;
    o->warned.max = S_MAX_WARNED;
    memset(&o->slots[0], 0, sizeof o->slots[0]);
    o->nslots = 1;
    const char *slash = strrchr(path, '/');
    const char *file = slash ? slash + 1 : path;
    if (slash)
        snprintf(o->dir, sizeof o->dir, "%.*s", (int)(file - path), path);
    const char *dot = strrchr(file, '.');
    snprintf(o->base, sizeof o->base, "%.*s", (int)(dot && dot != file ? dot - file : (ptrdiff_t)strlen(file)), file);
    memcpy(o->name, o->base, sizeof o->name);

    int rc = pf_text_read_statements(f, path, &o->line, err, s_statement, o);
    if (rc == PF_OK)
        rc = s_flush(o);
    if (rc == PF_OK)
        rc = s_commit(o);
    fclose(f);
    for (size_t i = 0; i < o->nmeshes; i++)
        pf_mesh_free(&o->meshes[i]); /* meshes handed to the scene were zeroed */
    free(o->meshes);
    free(o->pos);
    free(o->nrm);
    free(o->tex);
    free(o->cuv);
    free(o->ft);
    free(o->vuv);
    free(o->corner);
    free(o->tmat);
    free(o->fnrm);
    free(o->fv);
    free(o->fn);
    free(o->slots);
    free(o->head);
    free(o->vnext);
    free(o->vref);
    free(o);
    return rc;
}
