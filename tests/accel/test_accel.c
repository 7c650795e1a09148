/* test_accel.c: ray intersection through the Embree wrapper (accel/accel.h)
 * and the pinhole camera (scene/camera.h).
 *
 * Hits are compared with intersections solved in double: distance (1e-5
 * relative), point, normals (outward on spheres, by winding on triangles),
 * and from inside a sphere. Self-intersection: rays spawned with
 * pf_spawn_ray from hit points on spheres and triangles at unit, large (1e4)
 * and tiny (1e-3) scale must start on the side they leave to, must escape
 * when they leave outward, and when spawned into a sphere must reach its far
 * side (the distance solved in double from the spawned origin), never the near
 * side. pf_accel_occluded must agree with pf_accel_intersect, and concurrent
 * queries must return what serial ones do. The camera: the centre ray looks
 * at look_at, the edge rays subtend the field of view, and image right is +x
 * for the Cornell cameras. Randomness is pf_rng_make(seed, PF_STREAM_TEST, i, 0). */
#include <math.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "accel/accel.h"
#include "base/log.h"
#include "base/rng.h"
#include "base/vec.h"
#include "material/bsdf.h"
#include "scene/camera.h"
#include "scene/scene.h"

#include "check.h"



#define PI_D 3.14159265358979323846

/* ---- helpers ---- */

typedef struct {
    double x, y, z;
} s_d3;

static s_d3 s_d(pf_vec3 v) { return (s_d3){ v.x, v.y, v.z }; }
static s_d3 s_dsub(s_d3 a, s_d3 b) { return (s_d3){ a.x - b.x, a.y - b.y, a.z - b.z }; }
static double s_ddot(s_d3 a, s_d3 b) { return a.x * b.x + a.y * b.y + a.z * b.z; }
static double s_dlen(s_d3 a) { return sqrt(s_ddot(a, a)); }
static s_d3 s_dcross(s_d3 a, s_d3 b)
{
    return (s_d3){ a.y * b.z - a.z * b.y, a.z * b.x - a.x * b.z, a.x * b.y - a.y * b.x };
}

static double s_angle(pf_vec3 a, pf_vec3 b)
{
    return atan2(s_dlen(s_dcross(s_d(a), s_d(b))), s_ddot(s_d(a), s_d(b)));
}

static pf_vec3 s_rand_dir(pf_rng_t *r)
{
    for (;;) {
        float x = 2.0f * pf_rng_float(r) - 1.0f, y = 2.0f * pf_rng_float(r) - 1.0f, z = 2.0f * pf_rng_float(r) - 1.0f;
        float l2 = x * x + y * y + z * z;
        if (l2 > 1e-4f && l2 <= 1.0f)
            return pf_scale(pf_v3(x, y, z), 1.0f / sqrtf(l2));
    }
}

/* A direction in the hemisphere about n: uniform in cos theta, except that
 * every fourth has cos theta < 1e-3 (nearly grazing, where offsets matter). */
static pf_vec3 s_hemi_dir(pf_rng_t *r, pf_vec3 n, int i)
{
    float z = pf_rng_float(r);
    if (i % 4 == 0)
        z *= 1e-3f;
    z = fmaxf(z, 1e-6f);
    float s = sqrtf(fmaxf(0.0f, 1.0f - z * z)), phi = 2.0f * PF_PI * pf_rng_float(r);
    return pf_norm(pf_to_world(pf_v3(s * cosf(phi), s * sinf(phi), z), n));
}

static void *s_alloc(size_t n)
{
    void *p = calloc(1, n);
    if (!p) {
        fprintf(stderr, "out of memory\n");
        exit(2);
    }
    return p;
}

/* A scene with one grey material (index 0) and a far point light, so that
 * pf_scene_finalize accepts it. */
static pf_scene_t *s_scene(void)
{
    pf_scene_t *sc = pf_scene_create();
    if (!sc)
        exit(2);
    pf_material_t m = pf_material_default("grey");
    pf_scene_add_material(sc, &m);
    pf_light_t l;
    memset(&l, 0, sizeof l);
    l.type = PF_LIGHT_POINT;
    l.pos = pf_v3(0, 1e6f, 0);
    l.intensity = pf_v3s(1.0f);
    pf_scene_add_light(sc, &l);
    return sc;
}

static void s_add_tris(pf_scene_t *sc, const pf_vec3 *pos, size_t nverts, const uint32_t *idx, size_t ntris,
                       const pf_vec3 *nrm)
{
    pf_mesh_t mesh;
    memset(&mesh, 0, sizeof mesh);
    snprintf(mesh.name, sizeof mesh.name, "mesh%zu", sc->nmeshes);
    mesh.nverts = nverts;
    mesh.ntris = ntris;
    mesh.pos = s_alloc(nverts * sizeof *mesh.pos);
    mesh.idx = s_alloc(3 * ntris * sizeof *mesh.idx);
    mesh.mat = s_alloc(ntris * sizeof *mesh.mat);
    memcpy(mesh.pos, pos, nverts * sizeof *pos);
    memcpy(mesh.idx, idx, 3 * ntris * sizeof *idx);
    if (nrm) {
        mesh.nrm = s_alloc(nverts * sizeof *mesh.nrm);
        memcpy(mesh.nrm, nrm, nverts * sizeof *nrm);
    }
    if (pf_scene_add_mesh(sc, &mesh) != PF_OK)
        exit(2);
}

static pf_accel_t *s_accel(pf_scene_t *sc)
{
    pf_error_t err;
    if (pf_scene_finalize(sc, &err) != PF_OK) {
        fprintf(stderr, "pf_scene_finalize: %s\n", err.msg);
        exit(2);
    }
    pf_accel_t *a = pf_accel_create(sc, &err);
    if (!a) {
        fprintf(stderr, "pf_accel_create: %s\n", err.msg);
        exit(2);
    }
    return a;
}

/* Ray-sphere roots in double: *t0 <= *t1; 0 when the ray misses. */
static int s_sphere_roots(s_d3 o, s_d3 d, s_d3 c, double r, double *t0, double *t1)
{
    s_d3 oc = s_dsub(o, c);
    double a = s_ddot(d, d), b = s_ddot(oc, d), cc = s_ddot(oc, oc) - r * r;
    double disc = b * b - a * cc;
    if (disc < 0.0)
        return 0;
    double q = sqrt(disc);
    *t0 = (-b - q) / a;
    *t1 = (-b + q) / a;
    return 1;
}

/* ---- hit distances and normals ---- */

static void s_test_sphere_hits(void)
{
    pf_scene_t *sc = s_scene();
    pf_sphere_t sp = { .center = pf_v3(0.25f, -0.5f, 1.0f), .radius = 1.0f, .mat = 0 };
    pf_scene_add_sphere(sc, &sp);
    pf_accel_t *acc = s_accel(sc);
    pf_rng_t r = pf_rng_make(1, PF_STREAM_TEST, 0, 0);
    s_d3 c = s_d(sp.center);
    long bad_t = 0, bad_n = 0, bad_rec = 0, miss = 0, bad_in = 0;
    double worst_t = 0.0;
    for (int i = 0; i < 20000; i++) {
        /* From outside, aimed well inside the silhouette. */
        pf_vec3 o = pf_madd(sp.center, s_rand_dir(&r), 3.0f);
        pf_vec3 target = pf_madd(sp.center, s_rand_dir(&r), 0.8f * pf_rng_float(&r));
        pf_ray_t ray = { o, pf_norm(pf_sub(target, o)) };
        double t0, t1;
        if (!s_sphere_roots(s_d(ray.o), s_d(ray.d), c, sp.radius, &t0, &t1))
            continue;
        pf_hit_t h;
        if (!pf_accel_intersect(acc, &ray, INFINITY, &h)) {
            miss++;
            continue;
        }
        double e = fabs(h.t - t0) / t0;
        worst_t = fmax(worst_t, e);
        if (e > 1e-5)
            bad_t++;
        s_d3 np = s_dsub(s_d(h.p), c);
        double lp = s_dlen(np);
        if (fabs(lp - sp.radius) > 1e-5 || s_angle(h.ng, pf_v3((float)np.x, (float)np.y, (float)np.z)) > 1e-5 ||
            pf_dot(h.ng, ray.d) >= 0.0f || fabs(pf_len(h.ng) - 1.0f) > 1e-5f)
            bad_n++;
        if (h.geom != sc->nmeshes || h.prim != 0 || h.mat != 0 || h.ns.x != h.ng.x || h.ns.y != h.ng.y ||
            h.ns.z != h.ng.z)
            bad_rec++;
        /* From inside: the far root, normal still outward (so along the ray). */
        pf_vec3 oi = pf_madd(sp.center, s_rand_dir(&r), 0.9f * pf_rng_float(&r));
        pf_ray_t ri = { oi, s_rand_dir(&r) };
        s_sphere_roots(s_d(ri.o), s_d(ri.d), c, sp.radius, &t0, &t1);
        if (!pf_accel_intersect(acc, &ri, INFINITY, &h) || fabs(h.t - t1) > 1e-5 * t1 || pf_dot(h.ng, ri.d) <= 0.0f)
            bad_in++;
    }
    CHECK(miss == 0, "%ld rays aimed inside the sphere missed it", miss);
    CHECK(bad_t == 0, "%ld sphere hits with t off the double-precision root by > 1e-5 relative (worst %.3g)", bad_t,
          worst_t);
    CHECK(bad_n == 0, "%ld sphere hits off the surface or with a normal that is not outward and unit", bad_n);
    CHECK(bad_rec == 0, "%ld sphere hits with wrong geom/prim/mat or ns != ng", bad_rec);
    CHECK(bad_in == 0, "%ld rays from inside the sphere did not hit its inside at the far root", bad_in);
    /* A ray pointing away misses; tmax short of the sphere misses. */
    pf_hit_t h;
    pf_ray_t away = { pf_v3(0.25f, -0.5f, 3.0f), pf_v3(0, 0, 1) };
    CHECK(!pf_accel_intersect(acc, &away, INFINITY, &h), "a ray pointing away from the sphere hit it at t = %g", h.t);
    pf_ray_t to = { pf_v3(0.25f, -0.5f, 5.0f), pf_v3(0, 0, -1) };
    CHECK(!pf_accel_intersect(acc, &to, 2.9f, &h), "tmax 2.9 short of the sphere at t = 3 still hit (t = %g)", h.t);
    CHECK(pf_accel_intersect(acc, &to, INFINITY, &h) && fabsf(h.t - 3.0f) < 3e-6f,
          "axis ray: t = %g, expected 3", h.t);
    pf_accel_destroy(&acc);
    CHECK(acc == NULL, "pf_accel_destroy must null the pointer");
    pf_scene_destroy(&sc);
}

static void s_test_triangle_hits(void)
{
    pf_scene_t *sc = s_scene();
    const pf_vec3 pos[3] = { { -1.0f, 0.2f, -0.5f }, { 1.5f, -0.3f, 0.1f }, { 0.2f, 0.4f, 1.7f } };
    const uint32_t idx[3] = { 0, 1, 2 };
    s_add_tris(sc, pos, 3, idx, 1, NULL);
    /* A second mesh with vertex normals against its winding. */
    const pf_vec3 pos2[3] = { { 5, 0, 0 }, { 6, 0, 0 }, { 5, 1, 0 } }; /* winding normal +z */
    const pf_vec3 nrm2[3] = { { 0, 0, -1 }, { 0, 0, -1 }, { 0, 0, -1 } };
    s_add_tris(sc, pos2, 3, idx, 1, nrm2);
    pf_accel_t *acc = s_accel(sc);
    s_d3 p0 = s_d(pos[0]), p1 = s_d(pos[1]), p2 = s_d(pos[2]);
    s_d3 nw = s_dcross(s_dsub(p1, p0), s_dsub(p2, p0));
    double lnw = s_dlen(nw);
    nw = (s_d3){ nw.x / lnw, nw.y / lnw, nw.z / lnw };
    pf_rng_t r = pf_rng_make(2, PF_STREAM_TEST, 0, 0);
    long bad_t = 0, bad_n = 0, bad_rec = 0, miss = 0, bad_plane = 0;
    double worst_t = 0.0;
    for (int i = 0; i < 20000; i++) {
        float b0, b1;
        pf_sample_triangle(0.02f + 0.96f * pf_rng_float(&r), 0.02f + 0.96f * pf_rng_float(&r), &b0, &b1);
        pf_vec3 target = pf_add(pf_add(pf_scale(pos[0], b0), pf_scale(pos[1], b1)), pf_scale(pos[2], 1.0f - b0 - b1));
        pf_vec3 o = pf_madd(target, s_rand_dir(&r), 1.0f + 4.0f * pf_rng_float(&r));
        pf_ray_t ray = { o, pf_norm(pf_sub(target, o)) };
        s_d3 od = s_d(ray.o), dd = s_d(ray.d);
        double denom = s_ddot(dd, nw);
        if (fabs(denom) < 0.05)
            continue; /* near-parallel: t is ill-conditioned */
        double t = s_ddot(s_dsub(p0, od), nw) / denom;
        pf_hit_t h;
        if (!pf_accel_intersect(acc, &ray, INFINITY, &h)) {
            miss++;
            continue;
        }
        double e = fabs(h.t - t) / t;
        worst_t = fmax(worst_t, e);
        if (e > 1e-5)
            bad_t++;
        /* The normal follows the winding whichever side the ray came from. */
        if (s_angle(h.ng, pf_v3((float)nw.x, (float)nw.y, (float)nw.z)) > 1e-5)
            bad_n++;
        if (h.geom != 0 || h.prim != 0 || h.mat != 0 || s_angle(h.ns, h.ng) > 0.0)
            bad_rec++;
        /* The hit point is within its error bound of the plane. */
        double dist = fabs(s_ddot(s_dsub(s_d(h.p), p0), nw));
        double bound = fabs(nw.x) * h.perr.x + fabs(nw.y) * h.perr.y + fabs(nw.z) * h.perr.z;
        if (dist > bound)
            bad_plane++;
    }
    CHECK(miss == 0, "%ld rays aimed inside the triangle missed it", miss);
    CHECK(bad_t == 0, "%ld triangle hits with t off the double-precision value by > 1e-5 relative (worst %.3g)", bad_t,
          worst_t);
    CHECK(bad_n == 0, "%ld triangle hits whose ng is not the winding normal", bad_n);
    CHECK(bad_rec == 0, "%ld triangle hits with wrong geom/prim/mat or ns != ng without vertex normals", bad_rec);
    CHECK(bad_plane == 0, "%ld triangle hit points farther from the plane than their error bound", bad_plane);
    /* Vertex normals orient ng (accel.h). */
    pf_hit_t h;
    pf_ray_t down = { pf_v3(5.2f, 0.2f, 1.0f), pf_v3(0, 0, -1) };
    CHECK(pf_accel_intersect(acc, &down, INFINITY, &h) && h.geom == 1 && h.ng.z < -0.999f && h.ns.z < -0.999f,
          "triangle with vertex normals -z: ng.z = %g, ns.z = %g, expected -1 (vertex normals orient the face)", h.ng.z,
          h.ns.z);
    pf_accel_destroy(&acc);
    pf_scene_destroy(&sc);
}

/* ---- self-intersection ---- */

/* Hits a lone sphere from outside, then spawns rays from each hit point:
 * outward ones must start outside and escape, inward ones must start inside
 * and reach the far side at the distance solved in double. */
static void s_test_sphere_spawn(const char *name, pf_vec3 center, float radius, uint64_t seed)
{
    pf_scene_t *sc = s_scene();
    pf_sphere_t sp = { .center = center, .radius = radius, .mat = 0 };
    pf_scene_add_sphere(sc, &sp);
    pf_accel_t *acc = s_accel(sc);
    s_d3 c = s_d(center);
    double R = radius;
    long miss = 0, out_inside = 0, out_rehit = 0, in_outside = 0, in_miss = 0, in_bad_t = 0, in_normal = 0;
    double min_rehit = INFINITY, worst_in = 0.0;
    const int n = 100000;
    for (int i = 0; i < n; i++) {
        pf_rng_t r = pf_rng_make(seed, PF_STREAM_TEST, (uint64_t)i, 0);
        pf_vec3 o = pf_madd(center, s_rand_dir(&r), 3.0f * radius);
        pf_vec3 target = pf_madd(center, s_rand_dir(&r), 0.95f * radius * pf_rng_float(&r));
        pf_ray_t ray = { o, pf_norm(pf_sub(target, o)) };
        pf_hit_t h;
        if (!pf_accel_intersect(acc, &ray, INFINITY, &h)) {
            miss++;
            continue;
        }
        /* Outward. */
        pf_vec3 w = s_hemi_dir(&r, h.ng, i);
        pf_ray_t s = pf_spawn_ray(&h, w);
        if (s_dlen(s_dsub(s_d(s.o), c)) <= R)
            out_inside++;
        pf_hit_t h2;
        if (pf_accel_intersect(acc, &s, INFINITY, &h2)) {
            out_rehit++;
            min_rehit = fmin(min_rehit, h2.t);
        }
        /* Inward. */
        w = s_hemi_dir(&r, pf_neg(h.ng), i);
        s = pf_spawn_ray(&h, w);
        if (s_dlen(s_dsub(s_d(s.o), c)) >= R) {
            in_outside++;
            continue;
        }
        double t0, t1;
        if (!s_sphere_roots(s_d(s.o), s_d(s.d), c, R, &t0, &t1) || !pf_accel_intersect(acc, &s, INFINITY, &h2)) {
            in_miss++;
            continue;
        }
        /* Float error of Embree's root: a few ulps of R, amplified by
         * 1/chord for grazing chords (the discriminant cancels). */
        double tol = 1e-5 * R + 1e-6 * R * R / t1;
        double e = fabs(h2.t - t1);
        if (e > tol) {
            if (in_bad_t++ < 3)
                fprintf(stderr, "  %s: inward ray from a hit reached t = %.9g, expected the far side at %.9g\n", name,
                        h2.t, t1);
        }
        worst_in = fmax(worst_in, e / R);
        if (pf_dot(h2.ng, w) <= 0.0f)
            in_normal++;
    }
    CHECK(miss == 0, "%s: %ld rays aimed inside the sphere missed it", name, miss);
    CHECK(out_inside == 0, "%s: %ld outward spawned rays start inside the sphere", name, out_inside);
    CHECK(out_rehit == 0, "%s: %ld of %d outward spawned rays re-hit the sphere (smallest t %.3g, radius %g)", name,
          out_rehit, n, min_rehit, R);
    CHECK(in_outside == 0, "%s: %ld inward spawned rays start outside the sphere", name, in_outside);
    CHECK(in_miss == 0, "%s: %ld inward spawned rays hit nothing", name, in_miss);
    CHECK(in_bad_t == 0, "%s: %ld inward spawned rays hit off the far side (worst |t - chord| / R = %.3g)", name,
          in_bad_t, worst_in);
    CHECK(in_normal == 0, "%s: %ld inward spawned rays hit with ng against the ray (not the inside)", name, in_normal);
    pf_accel_destroy(&acc);
    pf_scene_destroy(&sc);
}

/* The same for a lone triangle: spawned rays to either side start on that
 * side of its plane and never hit it again. */
static void s_test_triangle_spawn(const char *name, const pf_vec3 pos[3], uint64_t seed)
{
    pf_scene_t *sc = s_scene();
    const uint32_t idx[3] = { 0, 1, 2 };
    s_add_tris(sc, pos, 3, idx, 1, NULL);
    pf_accel_t *acc = s_accel(sc);
    s_d3 p0 = s_d(pos[0]), p1 = s_d(pos[1]), p2 = s_d(pos[2]);
    s_d3 nw = s_dcross(s_dsub(p1, p0), s_dsub(p2, p0));
    double lnw = s_dlen(nw);
    nw = (s_d3){ nw.x / lnw, nw.y / lnw, nw.z / lnw };
    double scale = fmax(s_dlen(s_dsub(p1, p0)), s_dlen(s_dsub(p2, p0)));
    long miss = 0, wrong_side = 0, rehit = 0;
    double min_rehit = INFINITY;
    const int n = 100000;
    for (int i = 0; i < n; i++) {
        pf_rng_t r = pf_rng_make(seed, PF_STREAM_TEST, (uint64_t)i, 0);
        float b0, b1;
        pf_sample_triangle(0.01f + 0.98f * pf_rng_float(&r), 0.01f + 0.98f * pf_rng_float(&r), &b0, &b1);
        pf_vec3 target = pf_add(pf_add(pf_scale(pos[0], b0), pf_scale(pos[1], b1)), pf_scale(pos[2], 1.0f - b0 - b1));
        pf_vec3 dir = s_rand_dir(&r);
        if (fabs(s_ddot(s_d(dir), nw)) < 0.1)
            dir = pf_v3((float)nw.x, (float)nw.y, (float)nw.z);
        pf_vec3 o = pf_madd(target, dir, 0.5f * (float)scale);
        pf_ray_t ray = { o, pf_norm(pf_sub(target, o)) };
        pf_hit_t h;
        if (!pf_accel_intersect(acc, &ray, INFINITY, &h)) {
            miss++;
            continue;
        }
        for (int side = 0; side < 2; side++) {
            pf_vec3 w = s_hemi_dir(&r, side ? pf_neg(h.ng) : h.ng, i + side);
            pf_ray_t s = pf_spawn_ray(&h, w);
            /* Which side of the exact plane of the float vertices. */
            double sd = s_ddot(s_dsub(s_d(s.o), p0), nw), sw = s_ddot(s_d(w), nw);
            if (!(sd * sw > 0.0))
                wrong_side++;
            pf_hit_t h2;
            if (pf_accel_intersect(acc, &s, INFINITY, &h2)) {
                rehit++;
                min_rehit = fmin(min_rehit, h2.t);
            }
        }
    }
    CHECK(miss == 0, "%s: %ld rays aimed inside the triangle missed it", name, miss);
    CHECK(wrong_side == 0, "%s: %ld spawned rays start on the wrong side of (or on) the plane", name, wrong_side);
    CHECK(rehit == 0, "%s: %ld of %d spawned rays re-hit the triangle (smallest t %.3g, size %g)", name, rehit, 2 * n,
          min_rehit, scale);
    pf_accel_destroy(&acc);
    pf_scene_destroy(&sc);
}

/* ---- occluded agrees with intersect; threads agree with serial ---- */

static void s_test_occluded(void)
{
    pf_scene_t *sc = s_scene();
    pf_sphere_t sp = { .center = pf_v3(0, 0, 0), .radius = 1.0f, .mat = 0 };
    pf_scene_add_sphere(sc, &sp);
    pf_sphere_t sp2 = { .center = pf_v3(2.0f, 1.0f, -1.0f), .radius = 0.5f, .mat = 0 };
    pf_scene_add_sphere(sc, &sp2);
    const pf_vec3 pos[4] = { { -3, -1.5f, -3 }, { 3, -1.5f, -3 }, { 3, -1.5f, 3 }, { -3, -1.5f, 3 } };
    const uint32_t idx[6] = { 0, 2, 1, 0, 3, 2 };
    s_add_tris(sc, pos, 4, idx, 2, NULL);
    const pf_vec3 pos2[3] = { { -2, 0, 2 }, { -1, 2, 2 }, { -2.5f, 1.5f, 1 } };
    s_add_tris(sc, pos2, 3, idx, 1, NULL);
    pf_accel_t *acc = s_accel(sc);
    pf_rng_t r = pf_rng_make(3, PF_STREAM_TEST, 0, 0);
    long disagree = 0, hits = 0, bad_bracket = 0;
    enum { N = 20000 };
    static pf_ray_t rays[N];
    static pf_hit_t serial[N];
    static int serial_ok[N];
    for (int i = 0; i < N; i++) {
        pf_vec3 o = pf_v3(6.0f * pf_rng_float(&r) - 3.0f, 6.0f * pf_rng_float(&r) - 3.0f, 6.0f * pf_rng_float(&r) - 3.0f);
        pf_ray_t ray = { o, s_rand_dir(&r) };
        rays[i] = ray;
        float tmax = (i & 1) ? INFINITY : 6.0f * pf_rng_float(&r);
        pf_hit_t h;
        int hit = pf_accel_intersect(acc, &ray, tmax, &h);
        int occ = pf_accel_occluded(acc, &ray, tmax);
        disagree += hit != occ;
        serial_ok[i] = pf_accel_intersect(acc, &ray, INFINITY, &serial[i]);
        if (serial_ok[i]) {
            hits++;
            /* Nothing before the closest hit, something just past it. */
            if (pf_accel_occluded(acc, &ray, serial[i].t * 0.999f) || !pf_accel_occluded(acc, &ray, serial[i].t * 1.001f))
                bad_bracket++;
        }
    }
    CHECK(hits > N / 4, "only %ld of %d random rays hit; the scene is not exercising anything", hits, N);
    CHECK(disagree == 0, "pf_accel_occluded and pf_accel_intersect disagree on %ld of %d rays", disagree, N);
    CHECK(bad_bracket == 0, "%ld rays where occluded(0.999 t) or !occluded(1.001 t) around the closest hit t", bad_bracket);

    /* Queries from many threads return what serial ones do. */
    long differ = 0;
#pragma omp parallel reduction(+ : differ)
    {
        pf_accel_thread_init();
#pragma omp for schedule(dynamic, 64)
        for (int i = 0; i < N; i++) {
            pf_hit_t h;
            int ok = pf_accel_intersect(acc, &rays[i], INFINITY, &h);
            if (ok != serial_ok[i] || (ok && (h.t != serial[i].t || h.geom != serial[i].geom || h.prim != serial[i].prim)))
                differ++;
        }
    }
    CHECK(differ == 0, "%ld of %d rays hit differently from several threads than serially", differ, N);
    pf_accel_destroy(&acc);
    pf_scene_destroy(&sc);
}

/* pf_accel_only_plane: a floor made of two triangles, a second floor
 * triangle split off in the same plane, a wall standing on it at x = 1, a
 * parallel sheet 1e-3 under the floor's far half (a thin wall's other face)
 * and a sphere above. */
static void s_test_only_plane(void)
{
    pf_scene_t *sc = s_scene();
    const pf_vec3 floor[4] = { { -2, 0, -2 }, { 2, 0, -2 }, { 2, 0, 2 }, { -2, 0, 2 } };
    const uint32_t quad[6] = { 0, 2, 1, 0, 3, 2 };
    s_add_tris(sc, floor, 4, quad, 2, NULL);
    const pf_vec3 wall[4] = { { 1, 0, -2 }, { 1, 2, -2 }, { 1, 2, 2 }, { 1, 0, 2 } };
    s_add_tris(sc, wall, 4, quad, 2, NULL);
    const pf_vec3 sheet[4] = { { -2, -1e-3f, 1 }, { 0.5f, -1e-3f, 1 }, { 0.5f, -1e-3f, 2 }, { -2, -1e-3f, 2 } };
    s_add_tris(sc, sheet, 4, quad, 2, NULL);
    pf_sphere_t sp = { .center = pf_v3(-1.0f, 0.5f, -1.0f), .radius = 0.25f, .mat = 0 };
    pf_scene_add_sphere(sc, &sp);
    pf_accel_t *acc = s_accel(sc);
    const pf_vec3 up = pf_v3(0, 1, 0);
    float eps = pf_accel_eps(acc);
    /* Open floor, across the diagonal where its two triangles meet. */
    CHECK(pf_accel_only_plane(acc, pf_v3(0.0f, 0.0f, 0.0f), up, 0.4f), "open floor: not only its plane");
    CHECK(pf_accel_only_plane(acc, pf_v3(0.0f, 0.0f, 0.0f), pf_neg(up), 0.4f), "open floor, normal -y: not only its plane");
    /* A normal tilted by 1e-3 rad, or a point off the plane by 4 eps. */
    CHECK(!pf_accel_only_plane(acc, pf_v3(0.0f, 0.0f, 0.0f), pf_norm(pf_v3(1e-3f, 1.0f, 0.0f)), 0.4f),
          "a plane tilted by 1e-3 rad passed as the floor's");
    CHECK(!pf_accel_only_plane(acc, pf_v3(0.0f, 4.0f * eps, 0.0f), up, 0.4f), "a point 4 eps above the floor passed");
    /* The wall 0.5 away: outside a reach of 0.45, inside one of 0.55. */
    CHECK(pf_accel_only_plane(acc, pf_v3(0.5f, 0.0f, -0.5f), up, 0.45f), "the wall counted from 0.5 at reach 0.45");
    CHECK(!pf_accel_only_plane(acc, pf_v3(0.5f, 0.0f, -0.5f), up, 0.55f), "the wall missed from 0.5 at reach 0.55");
    /* The parallel sheet 1e-3 below: a thin wall's other face. */
    CHECK(!pf_accel_only_plane(acc, pf_v3(-1.0f, 0.0f, 1.5f), up, 0.1f), "a parallel face 1e-3 below passed");
    CHECK(pf_accel_only_plane(acc, pf_v3(-1.0f, 0.0f, 0.5f), up, 0.4f), "the sheet counted from 0.5 at reach 0.4");
    /* The sphere's bottom 0.25 above the floor. */
    CHECK(!pf_accel_only_plane(acc, pf_v3(-1.0f, 0.0f, -1.0f), up, 0.3f), "the sphere above missed");
    /* Degenerate queries. */
    CHECK(!pf_accel_only_plane(acc, pf_v3(0.0f, 0.0f, 0.0f), pf_v3s(0.0f), 0.4f), "a zero normal passed");
    CHECK(!pf_accel_only_plane(acc, pf_v3(NAN, 0.0f, 0.0f), up, 0.4f), "a NaN point passed");
    CHECK(!pf_accel_only_plane(acc, pf_v3(0.0f, 0.0f, 0.0f), up, NAN), "a NaN reach passed");
    pf_accel_destroy(&acc);
    pf_scene_destroy(&sc);
}

/* pf_accel_near_planes on the same floor, wall, sheet and sphere: which
 * triangles it finds, that a segment its planes separate from nothing
 * indeed hits nothing, and its refusals (too many, a sphere). */
static void s_test_near_planes(void)
{
    pf_scene_t *sc = s_scene();
    const pf_vec3 floor[4] = { { -2, 0, -2 }, { 2, 0, -2 }, { 2, 0, 2 }, { -2, 0, 2 } };
    const uint32_t quad[6] = { 0, 2, 1, 0, 3, 2 };
    s_add_tris(sc, floor, 4, quad, 2, NULL);
    const pf_vec3 wall[4] = { { 1, 0, -2 }, { 1, 2, -2 }, { 1, 2, 2 }, { 1, 0, 2 } };
    s_add_tris(sc, wall, 4, quad, 2, NULL);
    pf_sphere_t sp = { .center = pf_v3(-1.0f, 0.5f, -1.0f), .radius = 0.25f, .mat = 0 };
    pf_scene_add_sphere(sc, &sp);
    pf_accel_t *acc = s_accel(sc);
    pf_plane_t pl[8];
    /* The floor's two triangles (split along x = z) from its middle; from
     * (0.5, 0, -0.5), 0.71 from that diagonal, one of them, and the wall's
     * lower triangle beyond 0.5. */
    int n = pf_accel_near_planes(acc, pf_v3(0.0f, 0.0f, 0.0f), 0.4f, pl, 8);
    CHECK(n == 2, "open floor: %d planes, expected its 2 triangles", n);
    for (int i = 0; i < n; i++)
        CHECK(fabs(fabs(pl[i].n[1]) - 1.0) < 1e-12 && fabs(pl[i].d) < 1e-12, "floor plane %d: n (%g %g %g) d %g", i,
              pl[i].n[0], pl[i].n[1], pl[i].n[2], pl[i].d);
    n = pf_accel_near_planes(acc, pf_v3(0.5f, 0.0f, -0.5f), 0.45f, pl, 8);
    CHECK(n == 1, "the wall or the far floor triangle counted from 0.5 at reach 0.45 (%d planes)", n);
    n = pf_accel_near_planes(acc, pf_v3(0.5f, 0.0f, -0.5f), 0.55f, pl, 8);
    int walls = 0;
    for (int i = 0; i < n; i++)
        walls += fabs(fabs(pl[i].n[0]) - 1.0) < 1e-12 && fabs(fabs(pl[i].d) - 1.0) < 1e-12;
    CHECK(n == 2 && walls == 1, "the wall missed from 0.5 at reach 0.55 (%d planes, %d of the wall)", n, walls);
    /* Too many for the room given, or a sphere within reach: -1. */
    CHECK(pf_accel_near_planes(acc, pf_v3(0.5f, 0.0f, -0.5f), 0.55f, pl, 1) == -1, "2 planes fit in 1");
    CHECK(pf_accel_near_planes(acc, pf_v3(-1.0f, 0.0f, -1.0f), 0.3f, pl, 8) == -1, "the sphere above missed");
    CHECK(pf_accel_near_planes(acc, pf_v3(NAN, 0.0f, 0.0f), 0.3f, pl, 8) == -1, "a NaN point passed");
    /* Segments near the wall: the planes separate them from nothing (both
     * ends on one side of every plane) exactly when no ray hits, here. */
    const pf_vec3 c = pf_v3(0.8f, 0.0f, 0.0f);
    n = pf_accel_near_planes(acc, c, 0.5f, pl, 8);
    CHECK(n == 2, "floor and wall from 0.2: %d planes", n);
    const pf_vec3 ends[][2] = { { { 0.7f, 0.1f, 0.0f }, { 0.95f, 0.1f, 0.2f } },   /* room side */
                                { { 0.7f, 0.1f, 0.0f }, { 1.05f, 0.1f, 0.1f } } }; /* through the wall */
    for (int s = 0; s < 2; s++) {
        int apart = 1;
        for (int i = 0; i < n; i++) {
            double sa = pl[i].n[0] * ends[s][0].x + pl[i].n[1] * ends[s][0].y + pl[i].n[2] * ends[s][0].z - pl[i].d;
            double sb = pl[i].n[0] * ends[s][1].x + pl[i].n[1] * ends[s][1].y + pl[i].n[2] * ends[s][1].z - pl[i].d;
            apart &= (sa > 0) == (sb > 0);
        }
        pf_vec3 ab = pf_sub(ends[s][1], ends[s][0]);
        pf_ray_t r = { ends[s][0], pf_norm(ab) };
        int hit = pf_accel_occluded(acc, &r, pf_len(ab));
        CHECK(apart == (s == 0) && hit == (s == 1), "segment %d: one-sided %d, occluded %d", s, apart, hit);
    }
    pf_accel_destroy(&acc);
    pf_scene_destroy(&sc);
}

/* ---- camera ---- */

static void s_test_camera(void)
{
    const pf_camera_desc_t cornell = { .pos = { 0, 1, 6.8f }, .look_at = { 0, 1, 0 }, .up = { 0, 1, 0 }, .vfov_deg = 19.5f };
    const int sizes[][2] = { { 512, 512 }, { 640, 360 } };
    for (int k = 0; k < 2; k++) {
        int W = sizes[k][0], H = sizes[k][1];
        pf_camera_t cam = pf_camera_make(&cornell, W, H);
        double vfov = 19.5 * PI_D / 180.0, aspect = (double)W / H;
        pf_ray_t c = pf_camera_ray(&cam, 0.5f * W, 0.5f * H);
        CHECK(c.o.x == 0.0f && c.o.y == 1.0f && c.o.z == 6.8f, "camera ray origin (%g, %g, %g), expected the position",
              c.o.x, c.o.y, c.o.z);
        CHECK(s_angle(c.d, pf_v3(0, 0, -1)) < 1e-6, "%dx%d centre ray (%g, %g, %g), expected towards look_at (0, 0, -1)",
              W, H, c.d.x, c.d.y, c.d.z);
        pf_ray_t top = pf_camera_ray(&cam, 0.5f * W, 0.0f), bottom = pf_camera_ray(&cam, 0.5f * W, (float)H);
        CHECK(fabs(s_angle(top.d, bottom.d) - vfov) < 1e-5, "%dx%d top and bottom edge rays subtend %.6f rad, expected "
              "the vertical fov %.6f", W, H, s_angle(top.d, bottom.d), vfov);
        CHECK(top.d.y > 0.0f && bottom.d.y < 0.0f, "%dx%d top edge ray d.y = %g (want > 0), bottom %g (want < 0)", W, H,
              top.d.y, bottom.d.y);
        pf_ray_t left = pf_camera_ray(&cam, 0.0f, 0.5f * H), right = pf_camera_ray(&cam, (float)W, 0.5f * H);
        CHECK(left.d.x < 0.0f && right.d.x > 0.0f, "%dx%d left edge ray d.x = %g (want < 0: image right is +x), right %g",
              W, H, left.d.x, right.d.x);
        double hfov = 2.0 * atan(aspect * tan(0.5 * vfov));
        CHECK(fabs(s_angle(left.d, right.d) - hfov) < 1e-5, "%dx%d left and right edge rays subtend %.6f rad, expected "
              "2 atan(aspect tan(vfov/2)) = %.6f", W, H, s_angle(left.d, right.d), hfov);
        pf_ray_t tl = pf_camera_ray(&cam, 0.0f, 0.0f);
        CHECK(tl.d.x < 0.0f && tl.d.y > 0.0f && fabs(pf_len(tl.d) - 1.0f) < 1e-6f,
              "%dx%d pixel (0, 0) ray (%g, %g, %g): expected top-left (x < 0, y > 0), unit", W, H, tl.d.x, tl.d.y, tl.d.z);
    }

    /* A general camera: the frame is orthonormal, and projecting a point to
     * the film and tracing the ray through that film position passes through
     * the point. */
    const pf_camera_desc_t gen = { .pos = { 3, -2, 5 }, .look_at = { -1, 0.5f, 0.2f }, .up = { 0.1f, 1, 0.2f }, .vfov_deg = 50 };
    pf_camera_t cam = pf_camera_make(&gen, 300, 200);
    CHECK(fabs(pf_len(cam.right) - 1) < 1e-6 && fabs(pf_len(cam.up) - 1) < 1e-6 && fabs(pf_len(cam.forward) - 1) < 1e-6 &&
              fabsf(pf_dot(cam.right, cam.up)) < 1e-6f && fabsf(pf_dot(cam.right, cam.forward)) < 1e-6f &&
              fabsf(pf_dot(cam.up, cam.forward)) < 1e-6f && pf_dot(cam.up, gen.up) > 0.0f,
          "camera frame not orthonormal or up flipped");
    pf_rng_t r = pf_rng_make(4, PF_STREAM_TEST, 0, 0);
    long bad = 0;
    for (int i = 0; i < 2000; i++) {
        pf_vec3 p = pf_v3(4 * pf_rng_float(&r) - 3, 3 * pf_rng_float(&r) - 1, 4 * pf_rng_float(&r) - 2);
        pf_vec3 v = pf_sub(p, gen.pos);
        float z = pf_dot(v, cam.forward);
        float sx = pf_dot(v, cam.right) / z, sy = pf_dot(v, cam.up) / z;
        float fx = (sx / (cam.tan_half_v * cam.aspect) + 1.0f) * 0.5f * 300.0f;
        float fy = (1.0f - sy / cam.tan_half_v) * 0.5f * 200.0f;
        if (z <= 0.0f || fx < 0 || fx >= 300 || fy < 0 || fy >= 200)
            continue;
        pf_ray_t ray = pf_camera_ray(&cam, fx, fy);
        /* Distance from p to the ray, relative to its distance from the camera. */
        s_d3 vp = s_dsub(s_d(p), s_d(ray.o));
        double miss = s_dlen(s_dcross(vp, s_d(ray.d))) / s_dlen(vp);
        if (miss > 1e-5)
            bad++;
    }
    CHECK(bad == 0, "%ld points not on the ray through their projected film position", bad);
}

int main(void)
{
    pf_log_set_level(PF_LOG_WARN);
    s_test_sphere_hits();
    s_test_triangle_hits();
    s_test_sphere_spawn("unit sphere", pf_v3(0, 0, 0), 1.0f, 10);
    s_test_sphere_spawn("sphere r=1 at (1e4, 0, 0)", pf_v3(1e4f, 0, 0), 1.0f, 11);
    s_test_sphere_spawn("sphere r=1e-3 at the origin", pf_v3(0, 0, 0), 1e-3f, 12);
    s_test_sphere_spawn("sphere r=1e-3 at (1, 2, 3)", pf_v3(1, 2, 3), 1e-3f, 13);
    s_test_sphere_spawn("sphere r=100 at (-300, 50, 20)", pf_v3(-300, 50, 20), 100.0f, 14);
    const pf_vec3 big[3] = { { 1000, 2000, -3000 }, { 11000, 4000, 0 }, { 3000, 9000, 5000 } };
    s_test_triangle_spawn("triangle 1e4 across", big, 20);
    const pf_vec3 unit[3] = { { -0.3f, 0.1f, 0.2f }, { 0.8f, -0.2f, 0.4f }, { 0.1f, 0.9f, -0.3f } };
    s_test_triangle_spawn("unit triangle", unit, 21);
    const pf_vec3 tiny[3] = { { -3e-4f, 1e-4f, 2e-4f }, { 8e-4f, -2e-4f, 4e-4f }, { 1e-4f, 9e-4f, -3e-4f } };
    s_test_triangle_spawn("triangle 1e-3 across at the origin", tiny, 22);
    const pf_vec3 tiny_off[3] = { { 0.9997f, 2.0001f, 3.0002f }, { 1.0008f, 1.9998f, 3.0004f }, { 1.0001f, 2.0009f, 2.9997f } };
    s_test_triangle_spawn("triangle 1e-3 across at (1, 2, 3)", tiny_off, 23);
    /* Axis-aligned walls: hit points are exact in the normal's coordinate,
     * so the error bound along the normal is zero or tiny (Cornell walls). */
    const pf_vec3 floor0[3] = { { -1, 0, -1 }, { 1, 0, 1 }, { 1, 0, -1 } };
    s_test_triangle_spawn("floor triangle in the plane y = 0", floor0, 24);
    const pf_vec3 wall[3] = { { -1, 0, -1 }, { -1, 2, -1 }, { -1, 0, 1 } };
    s_test_triangle_spawn("wall triangle in the plane x = -1", wall, 25);
    const pf_vec3 ceil[3] = { { -0.24f, 1.98f, -0.22f }, { 0.23f, 1.98f, -0.22f }, { 0.23f, 1.98f, 0.16f } };
    s_test_triangle_spawn("ceiling-light triangle in the plane y = 1.98", ceil, 26);
    s_test_occluded();
    s_test_only_plane();
    s_test_near_planes();
    s_test_camera();
    printf("%d passed, %d failed\n", s_passed, s_failed);
    return s_failed ? 1 : 0;
}
