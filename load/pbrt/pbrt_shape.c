/* pbrt_shape.c: the pbrt-v4 reader's shapes: each Shape becomes one triangle
 * mesh in world space (or an analytic sphere), kept in the load until its
 * material is known; ObjectBegin/ObjectEnd keep their shapes aside and
 * ObjectInstance copies them through the instance's transform (instances
 * are flattened). It owns nothing: the lists live in the load's pf_pbrt_t.
 * Single-threaded.
 *
 * Every shape is first built in object space, then placed (s_place): points
 * through the current transform (in double), normals through its inverse
 * transpose. The scene model emits light one-sided (unless two-sided) along
 * the winding's normal cross(p1 - p0, p2 - p0), turned towards the vertex normals when a
 * mesh has them (light.c, accel.c); pbrt's area lights emit along the same
 * geometric normal, flipped by ReverseOrientation and by a transform that
 * swaps handedness, and likewise turned towards the vertex normals. So the
 * winding is reversed when exactly one of (ReverseOrientation, det < 0)
 * holds, and vertex normals are negated under ReverseOrientation: then the
 * emitting side, and the side pbrt's BSDFs see as outside, are pbrt's.
 *
 * Tessellated shapes (64 x 32 for spheres, 64 segments for disks and
 * cylinders) have the outward winding of pbrt's parametrization. A sphere
 * stays analytic (pf_sphere_t) when it is full, is not reversed and its
 * transform is a similarity (rotation, uniform scale, translation) outside
 * any object definition; an emissive one only when that transform also
 * keeps handedness: an analytic sphere emits outward (light/spherelight.h),
 * and pbrt's sphere flips its normal under ReverseOrientation and under a
 * mirroring transform, so both stay tessellated as before, and so does a
 * sphere under a two-sided area light (its inside emits too, which the
 * analytic sphere light does not). Its Le is the area light's, with "power"
 * over pi 4 pi r^2 as s_place does over a mesh's area (pbrt-v4's k_e: pi
 * times the area, times 2 when two-sided). */
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "base/reserve.h"
#include "load/pbrt/pbrt_impl.h"

#define S_PHI_STEPS 64
#define S_THETA_STEPS 32

void pf_pbrt_meshes_free(pf_pbrt_meshes_t *ms)
{
    for (size_t i = 0; i < ms->n; i++)
        pf_mesh_free(&ms->m[i]);
    free(ms->m);
    free(ms->s);
    memset(ms, 0, sizeof *ms);
}

/* Allocates a mesh of nv vertices (with normals when nrm) and nt triangles. */
static int s_mesh_alloc(pf_pbrt_t *c, pf_pbrt_loc_t loc, size_t nv, size_t nt, int nrm, pf_mesh_t *m)
{
    memset(m, 0, sizeof *m);
    if (nv > UINT32_MAX || nt > PF_PBRT_MAX_TRIS)
        return pf_pbrt_error_line(c, PF_ERANGE, loc, "a mesh of %zu vertices and %zu triangles is too large", nv, nt);
    m->nverts = nv;
    m->ntris = nt;
    m->pos = malloc((nv ? nv : 1) * sizeof *m->pos);
    m->nrm = nrm ? malloc((nv ? nv : 1) * sizeof *m->nrm) : NULL;
    m->idx = malloc((nt ? 3 * nt : 1) * sizeof *m->idx);
    m->mat = malloc((nt ? nt : 1) * sizeof *m->mat);
    if (!m->pos || (nrm && !m->nrm) || !m->idx || !m->mat) {
        pf_mesh_free(m);
        return pf_pbrt_error_line(c, PF_ENOMEM, loc, "out of memory");
    }
    return PF_OK;
}

static int s_append_mesh(pf_pbrt_t *c, pf_pbrt_meshes_t *ms, pf_mesh_t *m, pf_pbrt_loc_t loc)
{
    if (pf_reserve((void **)&ms->m, &ms->cap, ms->n + 1, sizeof *ms->m))
        return pf_pbrt_error_line(c, PF_ENOMEM, loc, "out of memory");
    ms->m[ms->n++] = *m;
    memset(m, 0, sizeof *m);
    return PF_OK;
}

/* The inverse transpose of m's linear part (normals), or 0 when singular. */
static int s_normal_matrix(const pf_pbrt_m4 m, double out[3][3])
{
    double det = pf_pbrt_m4_det3(m);
    if (!(fabs(det) > 1e-300) || !isfinite(det))
        return 0;
    for (int i = 0; i < 3; i++) {
        for (int j = 0; j < 3; j++) {
            int i1 = (i + 1) % 3, i2 = (i + 2) % 3, j1 = (j + 1) % 3, j2 = (j + 2) % 3;
            out[i][j] = (m[i1][j1] * m[i2][j2] - m[i1][j2] * m[i2][j1]) / det; /* cofactor / det */
        }
    }
    return 1;
}

/* Moves a mesh built in object space through m; flip reverses the winding,
 * negate the vertex normals. Positions that leave the finite range are an
 * error. */
static int s_transform(pf_pbrt_t *c, pf_mesh_t *mesh, const pf_pbrt_m4 m, int flip, int negate, pf_pbrt_loc_t loc)
{
    double nm[3][3];
    int has_nm = s_normal_matrix(m, nm);
    for (size_t v = 0; v < mesh->nverts; v++) {
        double p[3] = { mesh->pos[v].x, mesh->pos[v].y, mesh->pos[v].z }, r[4];
        for (int i = 0; i < 4; i++)
            r[i] = m[i][0] * p[0] + m[i][1] * p[1] + m[i][2] * p[2] + m[i][3];
        pf_vec3 w = pf_v3((float)(r[0] / r[3]), (float)(r[1] / r[3]), (float)(r[2] / r[3]));
        if (!pf_is_finite3(w))
            return pf_pbrt_error_line(c, PF_ERANGE, loc, "vertex %zu leaves the float range after the transform", v);
        mesh->pos[v] = w;
        if (!mesh->nrm)
            continue;
        double n[3] = { mesh->nrm[v].x, mesh->nrm[v].y, mesh->nrm[v].z }, o[3];
        for (int i = 0; i < 3; i++)
            o[i] = has_nm ? nm[i][0] * n[0] + nm[i][1] * n[1] + nm[i][2] * n[2] : n[i];
        double len = sqrt(o[0] * o[0] + o[1] * o[1] + o[2] * o[2]), s = len > 0.0 && isfinite(len) ? 1.0 / len : 0.0;
        s = negate ? -s : s;
        mesh->nrm[v] = pf_v3((float)(o[0] * s), (float)(o[1] * s), (float)(o[2] * s));
    }
    if (flip) {
        for (size_t t = 0; t < mesh->ntris; t++) {
            uint32_t k = mesh->idx[3 * t + 1];
            mesh->idx[3 * t + 1] = mesh->idx[3 * t + 2];
            mesh->idx[3 * t + 2] = k;
        }
    }
    return PF_OK;
}

/* The world-space area of a mesh. */
static double s_area(const pf_mesh_t *m)
{
    double a = 0.0;
    for (size_t t = 0; t < m->ntris; t++) {
        const uint32_t *v = &m->idx[3 * t];
        a += 0.5 * pf_len(pf_cross(pf_sub(m->pos[v[1]], m->pos[v[0]]), pf_sub(m->pos[v[2]], m->pos[v[0]])));
    }
    return a;
}

/* Checks the triangle budget for n more triangles. */
static int s_budget(pf_pbrt_t *c, uint64_t n, pf_pbrt_loc_t loc)
{
    if (n > PF_PBRT_MAX_TRIS - c->ntris)
        return pf_pbrt_error_line(c, PF_ERANGE, loc, "the scene would hold more than %llu triangles",
                                  (unsigned long long)PF_PBRT_MAX_TRIS);
    c->ntris += n;
    return PF_OK;
}

/* Places an object-space mesh: transform, orientation, material pair, and
 * into the world's or the current object's list. Takes *mesh. */
static int s_place(pf_pbrt_t *c, pf_mesh_t *mesh, int area, const char *name, pf_pbrt_loc_t loc)
{
    if (mesh->ntris == 0) {
        pf_mesh_free(mesh);
        return pf_pbrt_warn(c, loc, "empty shape (skipped)", "the shape has no area");
    }
    int rc = s_budget(c, mesh->ntris, loc);
    int swap = pf_pbrt_m4_det3(c->gs.ctm) < 0.0;
    if (rc == PF_OK)
        rc = s_transform(c, mesh, c->gs.ctm, swap != c->gs.reverse, c->gs.reverse, loc);
    pf_vec3 le = pf_v3s(0.0f);
    if (rc == PF_OK && area >= 0) {
        const pf_pbrt_area_t *a = &c->areas[area];
        le = a->le;
        double A = s_area(mesh);
        if (a->power > 0.0 && A > 0.0)
            le = pf_scale(le, (float)(a->power / (M_PI * A * (a->twosided ? 2.0 : 1.0))));
        if (!pf_is_finite3(le))
            rc = pf_pbrt_error_line(c, PF_ERANGE, loc, "the emitted radiance is not finite");
    }
    int pair = rc == PF_OK ? pf_pbrt_pair(c, area, le, loc) : -1;
    if (rc == PF_OK && pair < 0)
        rc = pair;
    if (rc == PF_OK) {
        mesh->alpha_tex = c->shape_alpha;
        for (size_t t = 0; t < mesh->ntris; t++)
            mesh->mat[t] = (uint32_t)pair;
        if (name)
            snprintf(mesh->name, sizeof mesh->name, "%s", name);
        rc = s_append_mesh(c, c->cur_object >= 0 ? &c->objects[c->cur_object].shapes : &c->shapes, mesh, loc);
    }
    pf_mesh_free(mesh);
    return rc;
}

/* The default mesh name: shape@file:line. */
static void s_name(const pf_pbrt_t *c, const char *type, pf_pbrt_loc_t loc, char *out, size_t cap)
{
    const char *f = pf_pbrt_file_name(c, loc), *slash = strrchr(f, '/');
    snprintf(out, cap, "%s@%.40s:%d", type, slash ? slash + 1 : f, loc.line);
}

/* Copies n object-space points (and normals) into mesh. */
static void s_fill(pf_mesh_t *m, const double *P, const double *N, size_t n)
{
    for (size_t v = 0; v < n; v++) {
        m->pos[v] = pf_v3((float)P[3 * v], (float)P[3 * v + 1], (float)P[3 * v + 2]);
        if (N)
            m->nrm[v] = pf_v3((float)N[3 * v], (float)N[3 * v + 1], (float)N[3 * v + 2]);
    }
}

/* Reads P and N of a mesh shape: P required (at least min points), N as
 * many as P when given; uv is marked used (s_uvs reads a trianglemesh's). */
static int s_points(pf_pbrt_t *c, pf_pbrt_params_t *ps, pf_pbrt_loc_t loc, const char *what, const double **P,
                    size_t *np, const double **N)
{
    size_t nn = 0;
    int rc = pf_pbrt_get_vec3s(c, ps, "P", P, np);
    if (rc == PF_OK && *np == 0)
        rc = pf_pbrt_error_line(c, PF_EPARSE, loc, "%s needs \"point3 P\"", what);
    if (rc == PF_OK)
        rc = pf_pbrt_get_vec3s(c, ps, "N", N, &nn);
    if (rc == PF_OK && nn && nn != *np)
        rc = pf_pbrt_error_line(c, PF_EPARSE, pf_pbrt_param(ps, "N")->loc, "%s: %zu normals for %zu points", what, nn,
                                *np);
    if (rc == PF_OK && *np > UINT32_MAX)
        rc = pf_pbrt_error_line(c, PF_ERANGE, loc, "%s: more than 2^32 - 1 points", what);
    pf_pbrt_param(ps, "uv");
    return rc;
}

/* A trianglemesh's "point2 uv" (or pbrt-v3's "float uv"): 2 per point,
 * into a new array in *out (NULL when absent). */
static int s_uvs(pf_pbrt_t *c, pf_pbrt_params_t *ps, size_t np, const char *what, float **out)
{
    *out = NULL;
    pf_pbrt_param_t *p = pf_pbrt_param(ps, "uv");
    if (!p)
        return PF_OK;
    if (p->nstr || p->nnum != 2 * np)
        return pf_pbrt_error_line(c, PF_EPARSE, p->loc, "%s: %zu uv values for %zu points (2 each)", what, p->nnum,
                                  np);
    if (!(*out = malloc((np ? 2 * np : 1) * sizeof **out)))
        return pf_pbrt_error_line(c, PF_ENOMEM, p->loc, "out of memory");
    for (size_t i = 0; i < 2 * np; i++)
        (*out)[i] = isfinite(p->num[i]) ? (float)p->num[i] : 0.0f;
    return PF_OK;
}

/* trianglemesh and loopsubdiv (its control mesh). */
static int s_trianglemesh(pf_pbrt_t *c, pf_pbrt_params_t *ps, int area, pf_pbrt_loc_t loc, const char *type)
{
    const double *P, *N;
    size_t np, ni;
    uint32_t *idx = NULL;
    int rc = s_points(c, ps, loc, type, &P, &np, &N);
    if (rc == PF_OK)
        rc = pf_pbrt_get_ints(c, ps, "indices", (int64_t)np - 1, &idx, &ni);
    if (rc == PF_OK && !idx && np != 3)
        rc = pf_pbrt_error_line(c, PF_EPARSE, loc, "%s needs \"integer indices\" (it has %zu points, not 3)", type, np);
    if (rc == PF_OK && idx && (ni == 0 || ni % 3))
        rc = pf_pbrt_error_line(c, PF_EPARSE, pf_pbrt_param(ps, "indices")->loc,
                                "%s: %zu indices are not a positive multiple of 3", type, ni);
    if (rc == PF_OK && type[0] == 'l') {
        pf_pbrt_param(ps, "levels");
        rc = pf_pbrt_warn(c, loc, "loopsubdiv (control mesh rendered)",
                          "loopsubdiv: the control mesh is rendered without subdivision");
    }
    pf_mesh_t m;
    float *uv = NULL;
    size_t nt = idx ? ni / 3 : 1;
    if (rc == PF_OK && type[0] == 't')
        rc = s_uvs(c, ps, np, type, &uv);
    if (rc == PF_OK)
        rc = s_mesh_alloc(c, loc, np, nt, N != NULL, &m);
    if (rc) {
        free(idx);
        free(uv);
        return rc;
    }
    s_fill(&m, P, N, np);
    m.uv = uv;
    for (size_t i = 0; i < 3 * nt; i++)
        m.idx[i] = idx ? idx[i] : (uint32_t)i;
    free(idx);
    char name[PF_NAME_MAX];
    s_name(c, type, loc, name, sizeof name);
    return s_place(c, &m, area, name, loc);
}

/* bilinearmesh: each patch (p00, p10, p01, p11) as (p00, p10, p11) and
 * (p00, p11, p01), which keeps pbrt's normal cross(dp/du, dp/dv). */
static int s_bilinearmesh(pf_pbrt_t *c, pf_pbrt_params_t *ps, int area, pf_pbrt_loc_t loc)
{
    const double *P, *N;
    size_t np, ni;
    uint32_t *idx = NULL;
    int rc = s_points(c, ps, loc, "bilinearmesh", &P, &np, &N);
    if (rc == PF_OK)
        rc = pf_pbrt_get_ints(c, ps, "indices", (int64_t)np - 1, &idx, &ni);
    if (rc == PF_OK && !idx && np != 4)
        rc = pf_pbrt_error_line(c, PF_EPARSE, loc, "bilinearmesh needs \"integer indices\" (it has %zu points, not 4)",
                                np);
    if (rc == PF_OK && idx && (ni == 0 || ni % 4))
        rc = pf_pbrt_error_line(c, PF_EPARSE, pf_pbrt_param(ps, "indices")->loc,
                                "bilinearmesh: %zu indices are not a positive multiple of 4", ni);
    size_t npatch = idx ? ni / 4 : 1;
    pf_mesh_t m;
    if (rc == PF_OK)
        rc = s_mesh_alloc(c, loc, np, 2 * npatch, N != NULL, &m);
    if (rc) {
        free(idx);
        return rc;
    }
    s_fill(&m, P, N, np);
    for (size_t q = 0; q < npatch; q++) {
        uint32_t v[4];
        for (int k = 0; k < 4; k++)
            v[k] = idx ? idx[4 * q + k] : (uint32_t)k;
        uint32_t *t = &m.idx[6 * q];
        t[0] = v[0], t[1] = v[1], t[2] = v[3];
        t[3] = v[0], t[4] = v[3], t[5] = v[2];
    }
    free(idx);
    char name[PF_NAME_MAX];
    s_name(c, "bilinearmesh", loc, name, sizeof name);
    return s_place(c, &m, area, name, loc);
}

static int s_plymesh(pf_pbrt_t *c, pf_pbrt_params_t *ps, int area, pf_pbrt_loc_t loc)
{
    const char *file;
    char path[4096];
    int rc = pf_pbrt_get_string(c, ps, "filename", NULL, &file);
    if (rc == PF_OK && !file)
        rc = pf_pbrt_error_line(c, PF_EPARSE, loc, "plymesh needs \"string filename\"");
    if (rc == PF_OK)
        rc = pf_pbrt_resolve(c, loc, file, 0, path, sizeof path);
    pf_pbrt_param_t *d = pf_pbrt_param(ps, "displacement");
    pf_pbrt_param(ps, "edgelength");
    if (rc == PF_OK && d)
        rc = pf_pbrt_warn(c, d->loc, "displacement (ignored)", "plymesh: \"displacement\" is not rendered yet");
    if (rc)
        return rc;
    pf_mesh_t m;
    pf_error_t err = { { 0 } };
    rc = pf_ply_read(path, NULL, 0, &m, &err);
    if (rc)
        return pf_pbrt_error_line(c, rc, loc, "plymesh: %s", err.msg);
    if (m.ntris == 0) {
        pf_mesh_free(&m);
        return pf_pbrt_warn(c, loc, "plymesh without faces (skipped)", "plymesh \"%s\" has no faces", file);
    }
    return s_place(c, &m, area, NULL, loc);
}

/* A tessellated surface of revolution about z: rows of points
 * (r_i cos phi, r_i sin phi, z_i), each row S_PHI_STEPS + 1 points from phi 0
 * to phimax, with normals n_i (rotated the same way) when nrm. Rows whose
 * radius is 0 (poles, a disk's centre) get one triangle per column. Each
 * triangle faces cross(row step, phi step): the callers order the rows so
 * that this is pbrt's normal (down a sphere or cylinder, out a disk). */
static int s_revolve(pf_pbrt_t *c, pf_pbrt_loc_t loc, const double *r, const double *z, const double (*n)[2],
                     size_t rows, double phimax, pf_mesh_t *m)
{
    size_t cols = S_PHI_STEPS, nv = rows * (cols + 1), nt = 0;
    for (size_t i = 0; i + 1 < rows; i++)
        nt += cols * ((r[i] > 0.0) + (r[i + 1] > 0.0));
    int rc = s_mesh_alloc(c, loc, nv, nt, n != NULL, m);
    if (rc)
        return rc;
    for (size_t i = 0; i < rows; i++) {
        for (size_t j = 0; j <= cols; j++) {
            double phi = phimax * (double)j / (double)cols, cp = cos(phi), sp = sin(phi);
            m->pos[i * (cols + 1) + j] = pf_v3((float)(r[i] * cp), (float)(r[i] * sp), (float)z[i]);
            if (n)
                m->nrm[i * (cols + 1) + j] = pf_v3((float)(n[i][0] * cp), (float)(n[i][0] * sp), (float)n[i][1]);
        }
    }
    size_t t = 0;
    for (size_t i = 0; i + 1 < rows; i++) {
        for (size_t j = 0; j < cols; j++) {
            uint32_t a = (uint32_t)(i * (cols + 1) + j), b = a + 1, d = a + (uint32_t)(cols + 1), e = d + 1;
            /* (a, d, b) and (d, e, b) face cross(row step, phi step). */
            if (r[i] > 0.0) {
                m->idx[3 * t] = a, m->idx[3 * t + 1] = d, m->idx[3 * t + 2] = b;
                t++;
            }
            if (r[i + 1] > 0.0) {
                m->idx[3 * t] = d, m->idx[3 * t + 1] = e, m->idx[3 * t + 2] = b;
                t++;
            }
        }
    }
    return PF_OK;
}

/* Whether the CTM is a similarity (rotation, uniform scale s, translation). */
static int s_similarity(const pf_pbrt_m4 m, double *s)
{
    if (m[3][0] != 0.0 || m[3][1] != 0.0 || m[3][2] != 0.0 || m[3][3] != 1.0)
        return 0;
    double g[3][3];
    for (int i = 0; i < 3; i++)
        for (int j = 0; j < 3; j++)
            g[i][j] = m[0][i] * m[0][j] + m[1][i] * m[1][j] + m[2][i] * m[2][j];
    double s2 = (g[0][0] + g[1][1] + g[2][2]) / 3.0;
    if (!(s2 > 0.0))
        return 0;
    for (int i = 0; i < 3; i++)
        for (int j = 0; j < 3; j++)
            if (fabs(g[i][j] - (i == j ? s2 : 0.0)) > 1e-6 * s2)
                return 0;
    *s = sqrt(s2);
    return 1;
}

static int s_sphere(pf_pbrt_t *c, pf_pbrt_params_t *ps, int area, pf_pbrt_loc_t loc)
{
    double rad, zmin, zmax, phimax, s;
    int rc = pf_pbrt_get_float(c, ps, "radius", 1.0, &rad);
    if (rc == PF_OK)
        rc = pf_pbrt_get_float(c, ps, "zmin", -rad, &zmin);
    if (rc == PF_OK)
        rc = pf_pbrt_get_float(c, ps, "zmax", rad, &zmax);
    if (rc == PF_OK)
        rc = pf_pbrt_get_float(c, ps, "phimax", 360.0, &phimax);
    if (rc == PF_OK && !(rad > 0.0))
        rc = pf_pbrt_error_line(c, PF_ERANGE, loc, "sphere: radius must be > 0");
    if (rc)
        return rc;
    zmin = fmax(fmin(zmin, rad), -rad);
    zmax = fmax(fmin(zmax, rad), -rad);
    phimax = fmax(fmin(phimax, 360.0), 0.0);
    int full = fmin(zmin, zmax) <= -rad && fmax(zmin, zmax) >= rad && phimax >= 360.0;
    if (!full && (rc = pf_pbrt_warn(c, loc, "partial sphere (tessellated)",
                                    "sphere: zmin %g, zmax %g, phimax %g: the part is tessellated (%d x %d)", zmin, zmax,
                                    phimax, S_PHI_STEPS, S_THETA_STEPS)))
        return rc;
    if (full && !c->gs.reverse && c->cur_object < 0 && s_similarity(c->gs.ctm, &s) &&
        (area < 0 || (pf_pbrt_m4_det3(c->gs.ctm) > 0.0 && !c->areas[area].twosided))) {
        if (c->shape_alpha &&
            (rc = pf_pbrt_warn(c, loc, "alpha on a sphere (opaque)", "sphere: \"alpha\" is not rendered on spheres")))
            return rc;
        pf_vec3 le = area < 0 ? pf_v3s(0.0f) : c->areas[area].le;
        if (area >= 0 && c->areas[area].power > 0.0) /* A = 4 pi r^2, one side (two-sided ones are meshes) */
            le = pf_scale(le, (float)(c->areas[area].power / (M_PI * 4.0 * M_PI * rad * s * rad * s)));
        if (!pf_is_finite3(le))
            return pf_pbrt_error_line(c, PF_ERANGE, loc, "the emitted radiance is not finite");
        int pair = pf_pbrt_pair(c, area, le, loc);
        if (pair < 0)
            return pair;
        pf_pbrt_meshes_t *ms = &c->shapes;
        if (pf_reserve((void **)&ms->s, &ms->caps, ms->ns + 1, sizeof *ms->s))
            return pf_pbrt_error_line(c, PF_ENOMEM, loc, "out of memory");
        const double(*m)[4] = (const double(*)[4])c->gs.ctm;
        ms->s[ms->ns++] = (pf_sphere_t){ .center = pf_v3((float)m[0][3], (float)m[1][3], (float)m[2][3]),
                                         .radius = (float)(rad * s), .mat = (uint32_t)pair };
        return PF_OK;
    }
    /* Rows from theta(zmax) to theta(zmin): down the sphere, outward winding. */
    double r[S_THETA_STEPS + 1], z[S_THETA_STEPS + 1], n[S_THETA_STEPS + 1][2];
    double t0 = acos(fmax(zmin, zmax) / rad), t1 = acos(fmin(zmin, zmax) / rad);
    for (int i = 0; i <= S_THETA_STEPS; i++) {
        double th = t0 + (t1 - t0) * i / S_THETA_STEPS;
        r[i] = (i == 0 && t0 == 0.0) || (i == S_THETA_STEPS && t1 >= M_PI) ? 0.0 : rad * sin(th);
        z[i] = rad * cos(th);
        n[i][0] = sin(th);
        n[i][1] = cos(th);
    }
    pf_mesh_t m;
    if ((rc = s_revolve(c, loc, r, z, (const double(*)[2])n, S_THETA_STEPS + 1, phimax * M_PI / 180.0, &m)))
        return rc;
    char name[PF_NAME_MAX];
    s_name(c, "sphere", loc, name, sizeof name);
    return s_place(c, &m, area, name, loc);
}

static int s_disk(pf_pbrt_t *c, pf_pbrt_params_t *ps, int area, pf_pbrt_loc_t loc)
{
    double h, rad, ri, phimax;
    int rc = pf_pbrt_get_float(c, ps, "height", 0.0, &h);
    if (rc == PF_OK)
        rc = pf_pbrt_get_float(c, ps, "radius", 1.0, &rad);
    if (rc == PF_OK)
        rc = pf_pbrt_get_float(c, ps, "innerradius", 0.0, &ri);
    if (rc == PF_OK)
        rc = pf_pbrt_get_float(c, ps, "phimax", 360.0, &phimax);
    if (rc == PF_OK && !(rad > 0.0 && ri >= 0.0 && ri < rad))
        rc = pf_pbrt_error_line(c, PF_ERANGE, loc, "disk: need 0 <= innerradius < radius");
    if (rc)
        return rc;
    /* Inner row first: cross(radial, tangential) is +z, pbrt's normal. */
    double r[2] = { ri, rad }, z[2] = { h, h };
    pf_mesh_t m;
    if ((rc = s_revolve(c, loc, r, z, NULL, 2, fmax(fmin(phimax, 360.0), 0.0) * M_PI / 180.0, &m)))
        return rc;
    char name[PF_NAME_MAX];
    s_name(c, "disk", loc, name, sizeof name);
    return s_place(c, &m, area, name, loc);
}

static int s_cylinder(pf_pbrt_t *c, pf_pbrt_params_t *ps, int area, pf_pbrt_loc_t loc)
{
    double rad, zmin, zmax, phimax;
    int rc = pf_pbrt_get_float(c, ps, "radius", 1.0, &rad);
    if (rc == PF_OK)
        rc = pf_pbrt_get_float(c, ps, "zmin", -1.0, &zmin);
    if (rc == PF_OK)
        rc = pf_pbrt_get_float(c, ps, "zmax", 1.0, &zmax);
    if (rc == PF_OK)
        rc = pf_pbrt_get_float(c, ps, "phimax", 360.0, &phimax);
    if (rc == PF_OK && !(rad > 0.0))
        rc = pf_pbrt_error_line(c, PF_ERANGE, loc, "cylinder: radius must be > 0");
    if (rc == PF_OK)
        rc = pf_pbrt_warn(c, loc, "cylinder (tessellated)", "cylinder: tessellated into %d segments", S_PHI_STEPS);
    if (rc)
        return rc;
    /* Top row first: the normal points outward, pbrt's. */
    double r[2] = { rad, rad }, z[2] = { fmax(zmin, zmax), fmin(zmin, zmax) }, n[2][2] = { { 1, 0 }, { 1, 0 } };
    pf_mesh_t m;
    if ((rc = s_revolve(c, loc, r, z, (const double(*)[2])n, 2, fmax(fmin(phimax, 360.0), 0.0) * M_PI / 180.0, &m)))
        return rc;
    char name[PF_NAME_MAX];
    s_name(c, "cylinder", loc, name, sizeof name);
    return s_place(c, &m, area, name, loc);
}

/* "alpha": the cut-out texture the shape's meshes get (s_place). */
static int s_alpha_param(pf_pbrt_t *c, pf_pbrt_params_t *ps, const char *type)
{
    (void)type;
    return pf_pbrt_alpha_texture(c, ps, &c->shape_alpha);
}

int pf_pbrt_shape(pf_pbrt_t *c, const char *type, pf_pbrt_params_t *ps, pf_pbrt_loc_t loc)
{
    int area = c->gs.area, rc = s_alpha_param(c, ps, type);
    if (rc == PF_OK && area >= 0 && c->cur_object >= 0) {
        area = -1;
        c->objects[c->cur_object].emitters_dropped = 1;
        rc = pf_pbrt_warn(c, loc, "area light in an object definition (not emitted)",
                          "Shape \"%s\" inside ObjectBegin does not emit (pbrt does not instance area lights)", type);
    }
    pf_pbrt_param(ps, "emissionfilename");
    if (rc)
        return rc;
    if (!strcmp(type, "trianglemesh") || !strcmp(type, "loopsubdiv"))
        rc = s_trianglemesh(c, ps, area, loc, type);
    else if (!strcmp(type, "bilinearmesh"))
        rc = s_bilinearmesh(c, ps, area, loc);
    else if (!strcmp(type, "plymesh"))
        rc = s_plymesh(c, ps, area, loc);
    else if (!strcmp(type, "sphere"))
        rc = s_sphere(c, ps, area, loc);
    else if (!strcmp(type, "disk"))
        rc = s_disk(c, ps, area, loc);
    else if (!strcmp(type, "cylinder"))
        rc = s_cylinder(c, ps, area, loc);
    else if (!strcmp(type, "curve") || !strcmp(type, "cone") || !strcmp(type, "paraboloid") ||
             !strcmp(type, "hyperboloid")) {
        for (size_t i = 0; i < ps->n; i++)
            ps->p[i].used = 1;
        char kind[64];
        snprintf(kind, sizeof kind, "shape %s (not rendered)", type);
        return pf_pbrt_warn(c, loc, kind, "Shape \"%s\" is not rendered", type);
    } else
        return pf_pbrt_error(c, PF_EPARSE, loc, "unknown Shape type \"%.60s\"", type);
    if (rc)
        return rc;
    char what[96];
    snprintf(what, sizeof what, "Shape \"%s\"", type);
    return pf_pbrt_check_unused(c, ps, what);
}

/* Copies mesh src (world space of the definition) through m into the world. */
static int s_instance_mesh(pf_pbrt_t *c, const pf_mesh_t *src, const char *obj, const pf_pbrt_m4 m, pf_pbrt_loc_t loc)
{
    pf_mesh_t d;
    int rc = s_budget(c, src->ntris, loc);
    if (rc == PF_OK)
        rc = s_mesh_alloc(c, loc, src->nverts, src->ntris, src->nrm != NULL, &d);
    if (rc)
        return rc;
    memcpy(d.pos, src->pos, src->nverts * sizeof *d.pos);
    if (src->nrm)
        memcpy(d.nrm, src->nrm, src->nverts * sizeof *d.nrm);
    d.alpha_tex = src->alpha_tex;
    if (src->uv) {
        if (!(d.uv = malloc((src->nverts ? 2 * src->nverts : 1) * sizeof *d.uv))) {
            pf_mesh_free(&d);
            return pf_pbrt_error_line(c, PF_ENOMEM, loc, "out of memory");
        }
        memcpy(d.uv, src->uv, 2 * src->nverts * sizeof *d.uv);
    }
    memcpy(d.idx, src->idx, 3 * src->ntris * sizeof *d.idx);
    memcpy(d.mat, src->mat, src->ntris * sizeof *d.mat);
    snprintf(d.name, sizeof d.name, "%.30s/%.30s", obj, src->name);
    /* pbrt transforms an instance's hits, normals included, by the instance
     * transform; ReverseOrientation at ObjectInstance changes nothing. */
    rc = s_transform(c, &d, m, pf_pbrt_m4_det3(m) < 0.0, 0, loc);
    if (rc == PF_OK)
        rc = s_append_mesh(c, &c->shapes, &d, loc);
    pf_mesh_free(&d);
    return rc;
}

int pf_pbrt_object_instance(pf_pbrt_t *c, const char *name, pf_pbrt_loc_t loc)
{
    int id = pf_pbrt_name_find(c, name);
    int32_t k = id < 0 ? -1 : c->named_obj[id];
    if (k < 0)
        return pf_pbrt_error(c, PF_EPARSE, loc, "ObjectInstance \"%s\": no such object", name);
    /* The objects' list may grow while instancing (it does not: no ObjectBegin
     * here), but the shapes list does; index afresh each time. */
    for (size_t i = 0; i < c->objects[k].shapes.n; i++) {
        int rc = s_instance_mesh(c, &c->objects[k].shapes.m[i], name, c->gs.ctm, loc);
        if (rc)
            return rc;
    }
    return PF_OK;
}

int pf_pbrt_emit_shapes(pf_pbrt_t *c)
{
    pf_pbrt_meshes_t *ms = &c->shapes;
    for (size_t i = 0; i < ms->n; i++) {
        pf_mesh_t *m = &ms->m[i];
        if (m->ntris == 0)
            continue;
        const pf_pbrt_pair_t *p = &c->pairs[m->mat[0]];
        if (p->out < 0) {
            int rc = pf_pbrt_warn(c, p->loc, "interface material (shape dropped)",
                                  "a shape with an interface material has no surface and is left out");
            if (rc)
                return rc;
            continue;
        }
        for (size_t t = 0; t < m->ntris; t++)
            m->mat[t] = (uint32_t)c->pairs[m->mat[t]].out;
        if (pf_scene_add_mesh(c->scene, m))
            return pf_pbrt_error_line(c, PF_ENOMEM, p->loc, "out of memory");
    }
    for (size_t i = 0; i < ms->ns; i++) {
        pf_sphere_t s = ms->s[i];
        const pf_pbrt_pair_t *p = &c->pairs[s.mat];
        if (p->out < 0) {
            int rc = pf_pbrt_warn(c, p->loc, "interface material (shape dropped)",
                                  "a shape with an interface material has no surface and is left out");
            if (rc)
                return rc;
            continue;
        }
        s.mat = (uint32_t)p->out;
        if (pf_scene_add_sphere(c->scene, &s))
            return pf_pbrt_error_line(c, PF_ENOMEM, p->loc, "out of memory");
    }
    return PF_OK;
}
