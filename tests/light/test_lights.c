/* test_lights.c: the power-weighted emitter table (light/light.h/.c) on
 * small scenes built in code.
 *
 * (a) An emissive rectangle facing down: its power is pi A lum(Le); the direct
 *     light estimate (mean of weight cos) at points below it equals the
 *     closed-form irradiance of a Lambertian rectangle onto a parallel
 *     receiver (Howell's catalogue B-3, summed over corner rectangles), which
 *     the test also checks against a brute-force quadrature; nothing reaches a
 *     point behind it; photon emission carries pi A Le, starts uniformly on
 *     the rectangle and leaves cosine-distributed about its normal.
 * (b) A point light: weight I / d^2 exactly; emission 4 pi I, uniform on the
 *     sphere.
 * (c) A spot light: the falloff's shape, its power, the mean emitted flux and
 *     the emitted intensity per angle, and direct weights I falloff / d^2.
 * (d) Several lights: each is picked as often as its pmf says, and every
 *     estimate stays unbiased.
 * (e) A distant light: power pi R^2 lum(E) (R: the scene's bounding sphere,
 *     which the disc must cover), direct weight E along -dir to infinity;
 *     photons travel along dir from outside the sphere and carry E cos A onto
 *     a tilted quad; caustic photons aimed at a sphere carry E pi r^2 onto it
 *     (its cross-section).
 * (f) An infinite light (constant sky L): power 4 pi^2 R^2 lum(L); direct
 *     samples give the irradiance pi L on any surface (each one, when
 *     cosine-weighted about its normal); photons bring pi L A
 *     down onto a horizontal quad's top.
 * Statistical bounds are 5 standard errors estimated from the samples (plus
 * the 1 % the task asks of the irradiance), or dof + 6 sqrt(2 dof) for
 * chi-square; randomness is pf_rng_make(seed, PF_STREAM_TEST, i, 0). */
#include <math.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "base/rng.h"
#include "base/vec.h"
#include "light/light.h"
#include "scene/scene.h"

#include "check.h"
#define PI_D 3.14159265358979323846

/* ---- helpers ---- */

typedef struct {
    double n, mean, m2;
} s_stat;

static void s_stat_add(s_stat *s, double x)
{
    s->n += 1.0;
    double d = x - s->mean;
    s->mean += d / s->n;
    s->m2 += d * (x - s->mean);
}

static double s_stat_se(const s_stat *s) { return s->n > 1.0 ? sqrt(s->m2 / (s->n - 1.0) / s->n) : 0.0; }

static double s_chi2_equal(const long *count, int bins, long n)
{
    double e = (double)n / bins, x2 = 0.0;
    for (int i = 0; i < bins; i++)
        x2 += ((double)count[i] - e) * ((double)count[i] - e) / e;
    return x2;
}

static double s_chi2_limit(int dof) { return dof + 6.0 * sqrt(2.0 * dof); }

static double s_rel(double got, double want) { return fabs(got - want) / fmax(fabs(want), 1e-30); }

static void s_uniforms(uint64_t seed, uint64_t i, float *u, int n)
{
    pf_rng_t r = pf_rng_make(seed, PF_STREAM_TEST, i, 0);
    for (int k = 0; k < n; k++)
        u[k] = pf_rng_float(&r);
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

static int s_add_material(pf_scene_t *sc, pf_vec3 kd, pf_vec3 le)
{
    pf_material_t m = pf_material_default("m");
    snprintf(m.name, sizeof m.name, "m%zu", sc->nmats);
    m.kd = kd;
    m.le = le;
    int idx = pf_scene_add_material(sc, &m);
    if (idx < 0) {
        fprintf(stderr, "pf_scene_add_material failed\n");
        exit(2);
    }
    return idx;
}

/* A parallelogram corner, corner + u, corner + u + v, corner + v as two
 * triangles wound so the face normal is u x v. With vnrm non-NULL every vertex
 * gets that shading normal. */
static void s_add_quad(pf_scene_t *sc, pf_vec3 corner, pf_vec3 u, pf_vec3 v, int mat, const pf_vec3 *vnrm)
{
    pf_mesh_t mesh;
    memset(&mesh, 0, sizeof mesh);
    snprintf(mesh.name, sizeof mesh.name, "quad%zu", sc->nmeshes);
    mesh.nverts = 4;
    mesh.ntris = 2;
    mesh.pos = s_alloc(4 * sizeof *mesh.pos);
    mesh.idx = s_alloc(6 * sizeof *mesh.idx);
    mesh.mat = s_alloc(2 * sizeof *mesh.mat);
    mesh.pos[0] = corner;
    mesh.pos[1] = pf_add(corner, u);
    mesh.pos[2] = pf_add(pf_add(corner, u), v);
    mesh.pos[3] = pf_add(corner, v);
    const uint32_t idx[6] = { 0, 1, 2, 0, 2, 3 };
    memcpy(mesh.idx, idx, sizeof idx);
    mesh.mat[0] = mesh.mat[1] = (uint32_t)mat;
    if (vnrm) {
        mesh.nrm = s_alloc(4 * sizeof *mesh.nrm);
        for (int i = 0; i < 4; i++)
            mesh.nrm[i] = *vnrm;
    }
    if (pf_scene_add_mesh(sc, &mesh) != PF_OK) {
        fprintf(stderr, "pf_scene_add_mesh failed\n");
        exit(2);
    }
}

static void s_finalize(pf_scene_t *sc)
{
    pf_error_t err;
    int rc = pf_scene_finalize(sc, &err);
    if (rc != PF_OK) {
        fprintf(stderr, "pf_scene_finalize: %s\n", err.msg);
        exit(2);
    }
}

static pf_lights_t *s_build(const pf_scene_t *sc)
{
    pf_lights_t *l = pf_lights_build(sc);
    if (!l) {
        fprintf(stderr, "pf_lights_build returned NULL\n");
        exit(2);
    }
    return l;
}

/* ---- analytic irradiance of a rectangle ---- */

/* Irradiance per unit radiance at a point on a receiver parallel to a
 * Lambertian rectangle of sides a, b at distance c, the receiver's normal
 * through one corner: pi times the configuration factor of Howell's catalogue
 * B-3, E / Le = 1/2 [A' atan(b / sqrt(a^2 + c^2)) + B' atan(a / sqrt(b^2 +
 * c^2))] with A' = a / sqrt(a^2 + c^2), B' = b / sqrt(b^2 + c^2). It is odd in
 * a and in b, so signed sides give superposition for free. */
static double s_corner(double a, double b, double c)
{
    double sa = sqrt(a * a + c * c), sb = sqrt(b * b + c * c);
    return 0.5 * (a / sa * atan(b / sa) + b / sb * atan(a / sb));
}

/* E / Le at (x0, z0) on the plane y = 0 (normal +y) from the rectangle
 * [x1, x2] x [z1, z2] at height h facing down. */
static double s_rect_irradiance(double x0, double z0, double x1, double x2, double z1, double z2, double h)
{
    return s_corner(x2 - x0, z2 - z0, h) - s_corner(x1 - x0, z2 - z0, h) - s_corner(x2 - x0, z1 - z0, h) +
           s_corner(x1 - x0, z1 - z0, h);
}

/* The same integral, int Le cos_r cos_l / d^2 dA, by the midpoint rule. */
static double s_rect_irradiance_quad(double x0, double z0, double x1, double x2, double z1, double z2, double h)
{
    const int n = 800;
    double dx = (x2 - x1) / n, dz = (z2 - z1) / n, sum = 0.0;
    for (int i = 0; i < n; i++) {
        for (int j = 0; j < n; j++) {
            double x = x1 + (i + 0.5) * dx - x0, z = z1 + (j + 0.5) * dz - z0;
            double d2 = x * x + z * z + h * h;
            sum += h * h / (d2 * d2); /* cos_r cos_l / d^2 = (h/d)(h/d) / d^2 */
        }
    }
    return sum * dx * dz;
}

/* ---- (a) an emissive rectangle ---- */

static void s_test_area_light(void)
{
    const double a = 0.8, b = 0.5, h = 0.6;
    const pf_vec3 le = pf_v3(2.0f, 4.0f, 1.0f);
    pf_scene_t *sc = pf_scene_create();
    int lm = s_add_material(sc, pf_v3s(0.0f), le);
    int floor_m = s_add_material(sc, pf_v3s(0.5f), pf_v3s(0.0f));
    /* u x v = x x z = -y: the light faces down. */
    s_add_quad(sc, pf_v3((float)(-a / 2), (float)h, (float)(-b / 2)), pf_v3((float)a, 0, 0), pf_v3(0, 0, (float)b), lm,
               NULL);
    /* A non-emissive floor (faces up) must not enter the table. */
    s_add_quad(sc, pf_v3(-5, 0, 5), pf_v3(10, 0, 0), pf_v3(0, 0, -10), floor_m, NULL);
    s_finalize(sc);
    pf_lights_t *lt = s_build(sc);

    CHECK(pf_lights_count(lt) == 2, "emitters = %zu, expected 2 (the light's two triangles)", pf_lights_count(lt));
    double power = PI_D * a * b * pf_luminance(le);
    CHECK(s_rel(pf_lights_power(lt), power) < 1e-5, "quad light power = %.7g, expected pi A lum(Le) = %.7g",
          pf_lights_power(lt), power);

    /* The closed form agrees with brute-force quadrature (guards the formula
     * and the superposition the test relies on). */
    const double pts[][2] = { { 0.0, 0.0 }, { 0.25, -0.15 }, { 0.7, 0.4 } };
    for (int k = 0; k < 3; k++) {
        double e1 = s_rect_irradiance(pts[k][0], pts[k][1], -a / 2, a / 2, -b / 2, b / 2, h);
        double e2 = s_rect_irradiance_quad(pts[k][0], pts[k][1], -a / 2, a / 2, -b / 2, b / 2, h);
        CHECK(s_rel(e1, e2) < 1e-4, "closed-form irradiance %.8f vs quadrature %.8f at (%g, %g)", e1, e2, pts[k][0],
              pts[k][1]);
    }

    /* Direct-light estimate of the irradiance at points on the floor. */
    for (int k = 0; k < 3; k++) {
        pf_vec3 x = pf_v3((float)pts[k][0], 0.0f, (float)pts[k][1]);
        s_stat st[3] = { { 0 } };
        long bad_geom = 0;
        const long n = 400000;
        for (long i = 0; i < n; i++) {
            float u[3];
            s_uniforms(200 + k, (uint64_t)i, u, 3);
            pf_light_conn_t c;
            if (!pf_lights_sample_direct(lt, sc, x, u, &c)) {
                for (int ch = 0; ch < 3; ch++)
                    s_stat_add(&st[ch], 0.0);
                continue;
            }
            /* The sampled point lies on the light. */
            pf_vec3 p = pf_madd(x, c.wi, c.dist);
            if (fabsf(p.y - (float)h) > 1e-5f || fabsf(p.x) > a / 2 + 1e-5 || fabsf(p.z) > b / 2 + 1e-5 ||
                fabs(sqrt(pf_dot(c.wi, c.wi)) - 1.0) > 1e-5)
                bad_geom++;
            double cos_r = fmax(0.0, c.wi.y);
            s_stat_add(&st[0], c.weight.x * cos_r);
            s_stat_add(&st[1], c.weight.y * cos_r);
            s_stat_add(&st[2], c.weight.z * cos_r);
        }
        CHECK(bad_geom == 0, "%ld direct samples off the light (wi * dist from x not on the rectangle)", bad_geom);
        double g = s_rect_irradiance(pts[k][0], pts[k][1], -a / 2, a / 2, -b / 2, b / 2, h);
        const float lec[3] = { le.x, le.y, le.z };
        for (int ch = 0; ch < 3; ch++) {
            double want = lec[ch] * g, got = st[ch].mean, se = s_stat_se(&st[ch]);
            CHECK(fabs(got - want) <= 5.0 * se && fabs(got - want) <= 0.01 * want,
                  "irradiance at (%g, 0, %g) channel %d = %.6f, expected %.6f (5 se = %.3g, 1 %% = %.3g)", pts[k][0],
                  pts[k][1], ch, got, want, 5.0 * se, 0.01 * want);
        }
    }

    /* Behind the one-sided emitter nothing arrives. (Points level with it
     * are not tested: the sampled point's rounding decides their side.) */
    const pf_vec3 behind[] = { { 0.0f, 1.2f, 0.0f }, { 0.1f, (float)h + 0.01f, 0.1f }, { 2.0f, (float)h + 1e-3f, 0.0f } };
    for (int k = 0; k < 3; k++) {
        long got = 0;
        for (long i = 0; i < 20000; i++) {
            float u[3];
            s_uniforms(300 + k, (uint64_t)i, u, 3);
            pf_light_conn_t c;
            got += pf_lights_sample_direct(lt, sc, behind[k], u, &c);
        }
        CHECK(got == 0, "%ld of 20000 samples reach (%g, %g, %g), behind the light; expected 0", got,
              behind[k].x, behind[k].y, behind[k].z);
    }

    /* Photon emission. */
    enum { G = 8, NC = 16, NP = 16 };
    static long grid[G * G], dirs[NC * NP];
    memset(grid, 0, sizeof grid);
    memset(dirs, 0, sizeof dirs);
    const long n = 256000;
    long bad_flux = 0, bad_pos = 0, bad_n = 0, bad_dir = 0;
    s_stat cosm = { 0 };
    pf_vec3 want_flux = pf_scale(le, (float)(PI_D * a * b));
    for (long i = 0; i < n; i++) {
        float u[5];
        s_uniforms(400, (uint64_t)i, u, 5);
        pf_emission_t e;
        if (!pf_lights_emit(lt, sc, u, &e)) {
            bad_flux++;
            continue;
        }
        if (s_rel(e.flux.x, want_flux.x) > 1e-5 || s_rel(e.flux.y, want_flux.y) > 1e-5 ||
            s_rel(e.flux.z, want_flux.z) > 1e-5)
            bad_flux++;
        pf_vec3 o = e.ray.o;
        if (fabsf(o.y - (float)h) > e.perr.y + 1e-7f || fabsf(o.x) > a / 2 + 1e-6 || fabsf(o.z) > b / 2 + 1e-6)
            bad_pos++;
        if (fabsf(e.n.x) > 1e-6f || fabsf(e.n.y + 1.0f) > 1e-6f || fabsf(e.n.z) > 1e-6f)
            bad_n++;
        pf_vec3 d = e.ray.d;
        double cos_t = -d.y;
        if (fabs(sqrt(pf_dot(d, d)) - 1.0) > 1e-5 || cos_t < 0.0)
            bad_dir++;
        int gx = (int)((o.x / a + 0.5) * G), gz = (int)((o.z / b + 0.5) * G);
        gx = gx < 0 ? 0 : gx >= G ? G - 1 : gx;
        gz = gz < 0 ? 0 : gz >= G ? G - 1 : gz;
        grid[gx * G + gz]++;
        /* Cosine-distributed: cos^2 is uniform on [0, 1]; phi uniform. */
        double c2 = fmin(fmax(cos_t * cos_t, 0.0), 1.0);
        int ic = (int)(c2 * NC);
        ic = ic >= NC ? NC - 1 : ic;
        double phi = atan2(d.z, d.x) + PI_D;
        int ip = (int)(phi / (2.0 * PI_D) * NP);
        ip = ip < 0 ? 0 : ip >= NP ? NP - 1 : ip;
        dirs[ic * NP + ip]++;
        s_stat_add(&cosm, cos_t);
    }
    CHECK(bad_flux == 0, "%ld emitted photons with flux != pi A Le = (%g, %g, %g)", bad_flux, want_flux.x, want_flux.y,
          want_flux.z);
    CHECK(bad_pos == 0, "%ld emitted photons starting off the rectangle", bad_pos);
    CHECK(bad_n == 0, "%ld emitted photons with normal != (0, -1, 0)", bad_n);
    CHECK(bad_dir == 0, "%ld emitted directions not unit or not below the light", bad_dir);
    double x2 = s_chi2_equal(grid, G * G, n), lim = s_chi2_limit(G * G - 1);
    CHECK(x2 < lim, "emission origins over an 8x8 grid on the light: chi-square %.1f, expected < %.1f (uniform)", x2, lim);
    x2 = s_chi2_equal(dirs, NC * NP, n);
    lim = s_chi2_limit(NC * NP - 1);
    CHECK(x2 < lim, "emitted directions over (cos^2, phi) bins: chi-square %.1f, expected < %.1f (cosine about -y)", x2,
          lim);
    CHECK(fabs(cosm.mean - 2.0 / 3.0) <= 5.0 * s_stat_se(&cosm), "emitted E[cos] = %.5f, expected 2/3 (5 se = %.2g)",
          cosm.mean, 5.0 * s_stat_se(&cosm));
    pf_lights_destroy(&lt);
    CHECK(lt == NULL, "pf_lights_destroy must null the pointer");
    pf_scene_destroy(&sc);
}

/* Vertex normals against the winding turn the emitter around (light.h and
 * accel.c agree that vertex normals orient the face). */
static void s_test_area_light_vertex_normals(void)
{
    pf_scene_t *sc = pf_scene_create();
    int lm = s_add_material(sc, pf_v3s(0.0f), pf_v3s(1.0f));
    pf_vec3 down = pf_v3(0, -1, 0);
    /* Wound to face up (x cross -z = +y), vertex normals say down. */
    s_add_quad(sc, pf_v3(-0.5f, 1.0f, 0.5f), pf_v3(1, 0, 0), pf_v3(0, 0, -1), lm, &down);
    s_finalize(sc);
    pf_lights_t *lt = s_build(sc);
    long below = 0, above = 0;
    for (long i = 0; i < 2000; i++) {
        float u[5];
        s_uniforms(450, (uint64_t)i, u, 5);
        pf_light_conn_t c;
        below += pf_lights_sample_direct(lt, sc, pf_v3(0, 0, 0), u, &c);
        above += pf_lights_sample_direct(lt, sc, pf_v3(0, 2, 0), u, &c);
        pf_emission_t e;
        if (pf_lights_emit(lt, sc, u, &e) && i == 0)
            CHECK(e.n.y < -0.999f && e.ray.d.y < 0.0f, "emission from a light with downward vertex normals: n.y = %g, "
                  "d.y = %g, expected both negative", e.n.y, e.ray.d.y);
    }
    CHECK(below == 2000 && above == 0,
          "vertex normals facing down: %ld/2000 samples reach below, %ld/2000 above; expected all and none", below,
          above);
    pf_lights_destroy(&lt);
    pf_scene_destroy(&sc);
}

/* ---- (b) a point light ---- */

static void s_test_point_light(void)
{
    pf_scene_t *sc = pf_scene_create();
    int fm = s_add_material(sc, pf_v3s(0.5f), pf_v3s(0.0f));
    s_add_quad(sc, pf_v3(-5, 0, 5), pf_v3(10, 0, 0), pf_v3(0, 0, -10), fm, NULL);
    pf_light_t l;
    memset(&l, 0, sizeof l);
    l.type = PF_LIGHT_POINT;
    l.pos = pf_v3(0.3f, 2.0f, -0.1f);
    l.intensity = pf_v3(3.0f, 2.0f, 1.0f);
    pf_scene_add_light(sc, &l);
    s_finalize(sc);
    pf_lights_t *lt = s_build(sc);
    CHECK(pf_lights_count(lt) == 1, "emitters = %zu, expected 1", pf_lights_count(lt));
    double power = 4.0 * PI_D * pf_luminance(l.intensity);
    CHECK(s_rel(pf_lights_power(lt), power) < 1e-6, "point light power = %.7g, expected 4 pi lum(I) = %.7g",
          pf_lights_power(lt), power);

    /* Direct light: weight = I / d^2, exactly (one light, pmf 1). */
    pf_rng_t r = pf_rng_make(500, PF_STREAM_TEST, 0, 0);
    long bad = 0;
    for (int i = 0; i < 10000; i++) {
        pf_vec3 x = pf_v3(4.0f * pf_rng_float(&r) - 2.0f, 1.9f * pf_rng_float(&r), 4.0f * pf_rng_float(&r) - 2.0f);
        float u[3];
        s_uniforms(501, (uint64_t)i, u, 3);
        pf_light_conn_t c;
        if (!pf_lights_sample_direct(lt, sc, x, u, &c)) {
            bad++;
            continue;
        }
        double dx = (double)l.pos.x - x.x, dy = (double)l.pos.y - x.y, dz = (double)l.pos.z - x.z;
        double d2 = dx * dx + dy * dy + dz * dz, d = sqrt(d2);
        int ok = s_rel(c.weight.x, l.intensity.x / d2) < 1e-5 && s_rel(c.weight.y, l.intensity.y / d2) < 1e-5 &&
                 s_rel(c.weight.z, l.intensity.z / d2) < 1e-5 && s_rel(c.dist, d) < 1e-6 &&
                 fabs(c.wi.x - dx / d) < 1e-6 && fabs(c.wi.y - dy / d) < 1e-6 && fabs(c.wi.z - dz / d) < 1e-6;
        if (!ok && bad++ < 3)
            fprintf(stderr, "  point light from (%g, %g, %g): weight.x %g, expected I/d^2 = %g; dist %g, expected %g\n",
                    x.x, x.y, x.z, c.weight.x, l.intensity.x / d2, c.dist, d);
    }
    CHECK(bad == 0, "%ld point-light connections with weight != I / d^2 or a wrong direction", bad);

    /* Emission: flux 4 pi I per photon, from the light, uniform on the sphere. */
    enum { NC = 16, NP = 16 };
    static long bins[NC * NP];
    memset(bins, 0, sizeof bins);
    const long n = 256000;
    long bad_e = 0;
    s_stat mx = { 0 }, my = { 0 }, mz = { 0 };
    for (long i = 0; i < n; i++) {
        float u[5];
        s_uniforms(502, (uint64_t)i, u, 5);
        pf_emission_t e;
        if (!pf_lights_emit(lt, sc, u, &e)) {
            bad_e++;
            continue;
        }
        pf_vec3 d = e.ray.d;
        int ok = s_rel(e.flux.x, 4.0 * PI_D * 3.0) < 1e-6 && s_rel(e.flux.y, 4.0 * PI_D * 2.0) < 1e-6 &&
                 s_rel(e.flux.z, 4.0 * PI_D * 1.0) < 1e-6 && e.ray.o.x == l.pos.x && e.ray.o.y == l.pos.y &&
                 e.ray.o.z == l.pos.z && pf_is_black(e.n) && fabs(sqrt(pf_dot(d, d)) - 1.0) < 1e-5;
        if (!ok)
            bad_e++;
        int ic = (int)((d.z + 1.0) * 0.5 * NC), ip = (int)((atan2(d.y, d.x) + PI_D) / (2.0 * PI_D) * NP);
        ic = ic < 0 ? 0 : ic >= NC ? NC - 1 : ic;
        ip = ip < 0 ? 0 : ip >= NP ? NP - 1 : ip;
        bins[ic * NP + ip]++;
        s_stat_add(&mx, d.x);
        s_stat_add(&my, d.y);
        s_stat_add(&mz, d.z);
    }
    CHECK(bad_e == 0, "%ld point-light photons with flux != 4 pi I, origin != light, or a bad direction", bad_e);
    double x2 = s_chi2_equal(bins, NC * NP, n), lim = s_chi2_limit(NC * NP - 1);
    CHECK(x2 < lim, "point-light directions over (cos, phi) bins: chi-square %.1f, expected < %.1f (uniform)", x2, lim);
    CHECK(fabs(mx.mean) < 5 * s_stat_se(&mx) && fabs(my.mean) < 5 * s_stat_se(&my) && fabs(mz.mean) < 5 * s_stat_se(&mz),
          "mean point-light direction (%.4f, %.4f, %.4f), expected 0", mx.mean, my.mean, mz.mean);
    pf_lights_destroy(&lt);
    pf_scene_destroy(&sc);
}

/* A point light far outside a small scene emits only towards it: every
 * photon's ray passes the scene's bounding sphere, and the flux reaching the
 * quad equals the integral of I cos / d^2 over it (unbiased: the photons it
 * no longer sends would have missed). */
static void s_test_point_light_far(void)
{
    pf_scene_t *sc = pf_scene_create();
    int fm = s_add_material(sc, pf_v3s(0.5f), pf_v3s(0.0f));
    s_add_quad(sc, pf_v3(-0.5f, 0, 0.5f), pf_v3(1, 0, 0), pf_v3(0, 0, -1), fm, NULL);
    pf_light_t l;
    memset(&l, 0, sizeof l);
    l.type = PF_LIGHT_POINT;
    l.pos = pf_v3(3.0f, 20.0f, -2.0f);
    l.intensity = pf_v3s(5.0f);
    pf_scene_add_light(sc, &l);
    s_finalize(sc);
    pf_lights_t *lt = s_build(sc);
    /* The flux on the quad, by a fine midpoint rule. */
    double want = 0.0;
    const int g = 400;
    for (int i = 0; i < g; i++)
        for (int j = 0; j < g; j++) {
            double x = -0.5 + (i + 0.5) / g, z = -0.5 + (j + 0.5) / g;
            double dx = l.pos.x - x, dy = l.pos.y, dz = l.pos.z - z, d2 = dx * dx + dy * dy + dz * dz;
            want += 5.0 * (dy / sqrt(d2)) / d2 / ((double)g * g);
        }
    const long n = 200000;
    long off_scene = 0, hits = 0;
    s_stat flux = { 0 };
    for (long i = 0; i < n; i++) {
        float u[5];
        s_uniforms(503, (uint64_t)i, u, 5);
        pf_emission_t e;
        if (!pf_lights_emit(lt, sc, u, &e)) {
            off_scene++;
            continue;
        }
        /* Distance from the scene's centre (0, 0, 0) to the ray's line. */
        pf_vec3 to = pf_neg(e.ray.o);
        float along = pf_dot(to, e.ray.d);
        pf_vec3 closest = pf_sub(to, pf_scale(e.ray.d, along));
        if (!(along > 0.0f) || pf_len(closest) > 0.7072f * 1.02f)
            off_scene++;
        double got = 0.0;
        if (e.ray.d.y < 0.0f) {
            float t = -e.ray.o.y / e.ray.d.y;
            pf_vec3 p = pf_add(e.ray.o, pf_scale(e.ray.d, t));
            if (fabsf(p.x) <= 0.5f && fabsf(p.z) <= 0.5f) {
                got = e.flux.x;
                hits++;
            }
        }
        s_stat_add(&flux, got);
    }
    CHECK(off_scene == 0, "%ld of %ld far point-light photons miss the scene's bounding sphere", off_scene, n);
    CHECK(hits > n / 4, "only %ld of %ld far point-light photons hit the quad: emission is not aimed", hits, n);
    CHECK(fabs(flux.mean - want) < 5.0 * s_stat_se(&flux),
          "far point light: flux on the quad %.6g per photon, expected %.6g (se %.2g)", flux.mean, want,
          s_stat_se(&flux));
    pf_lights_destroy(&lt);
    pf_scene_destroy(&sc);
}

/* ---- (c) a spot light ---- */

static void s_test_spot_light(void)
{
    const double ci = cos(20.0 * PI_D / 180.0), co = cos(30.0 * PI_D / 180.0);
    pf_light_t l;
    memset(&l, 0, sizeof l);
    l.type = PF_LIGHT_SPOT;
    l.pos = pf_v3(0.0f, 2.0f, 0.0f);
    l.dir = pf_norm(pf_v3(0.3f, -1.0f, 0.2f));
    l.intensity = pf_v3(4.0f, 2.0f, 1.0f);
    l.cos_inner = (float)ci;
    l.cos_outer = (float)co;

    /* The falloff: 1 inside, 0 outside, smooth and monotonic between, 1/2
     * half way (smoothstep is symmetric). */
    CHECK(pf_spot_falloff(&l, 1.0f) == 1.0f && pf_spot_falloff(&l, l.cos_inner) == 1.0f &&
              pf_spot_falloff(&l, nextafterf(l.cos_inner, 2.0f)) == 1.0f,
          "falloff inside the inner cone: %g, %g, expected 1", pf_spot_falloff(&l, 1.0f),
          pf_spot_falloff(&l, l.cos_inner));
    CHECK(pf_spot_falloff(&l, l.cos_outer) == 0.0f && pf_spot_falloff(&l, 0.0f) == 0.0f &&
              pf_spot_falloff(&l, -1.0f) == 0.0f,
          "falloff outside the outer cone: %g, %g, %g, expected 0", pf_spot_falloff(&l, l.cos_outer),
          pf_spot_falloff(&l, 0.0f), pf_spot_falloff(&l, -1.0f));
    float mid = pf_spot_falloff(&l, 0.5f * (l.cos_inner + l.cos_outer));
    CHECK(fabsf(mid - 0.5f) < 1e-3f, "falloff half way between the cones = %g, expected 0.5", mid);
    float prev = 0.0f, max_step = 0.0f;
    int monotonic = 1, inside01 = 1;
    for (int i = 0; i <= 4000; i++) {
        float c = (float)(co - 0.01 + (ci - co + 0.02) * i / 4000.0);
        float f = pf_spot_falloff(&l, c);
        monotonic &= f >= prev;
        inside01 &= f >= 0.0f && f <= 1.0f;
        if (c > l.cos_outer && c < l.cos_inner)
            inside01 &= f > 0.0f && f < 1.0f;
        max_step = fmaxf(max_step, f - prev);
        prev = f;
    }
    CHECK(monotonic && inside01, "falloff not monotonic in cos or outside (0, 1) strictly between the cones");
    CHECK(max_step < 3e-3f, "falloff jumps by %g between neighbouring angles; expected smooth", max_step);
    /* Smooth at both edges too: the slope tends to 0 where the falloff meets
     * the constant 0 and 1 (a linear ramp would have slope 1 / width there). */
    double w = ci - co, eps = 0.01;
    float f_lo = pf_spot_falloff(&l, (float)(co + eps * w)), f_hi = pf_spot_falloff(&l, (float)(ci - eps * w));
    CHECK(f_lo < 0.1 * eps && 1.0f - f_hi < 0.1 * eps,
          "falloff 1 %% of the band inside the edges: %g and 1 - %g; expected both < %g (zero slope at the edges)", f_lo,
          f_hi, 0.1 * eps);

    pf_scene_t *sc = pf_scene_create();
    int fm = s_add_material(sc, pf_v3s(0.5f), pf_v3s(0.0f));
    s_add_quad(sc, pf_v3(-5, 0, 5), pf_v3(10, 0, 0), pf_v3(0, 0, -10), fm, NULL);
    pf_scene_add_light(sc, &l);
    s_finalize(sc);
    pf_lights_t *lt = s_build(sc);

    /* Power: 2 pi I int falloff dcos = 2 pi I [(1 - ci) + (ci - co) / 2]
     * (smoothstep averages 1/2 over the band). */
    double band = (1.0 - ci) + 0.5 * (ci - co);
    double power = 2.0 * PI_D * pf_luminance(l.intensity) * band;
    CHECK(s_rel(pf_lights_power(lt), power) < 1e-4, "spot power = %.7g, expected 2 pi lum(I) int falloff = %.7g",
          pf_lights_power(lt), power);

    /* Emission: mean flux = the spot's power per channel; directions in the
     * outer cone; emitted intensity per angle = I falloff. */
    enum { NB = 12 };
    s_stat flux[3] = { { 0 } }, inten[NB];
    memset(inten, 0, sizeof inten);
    const long n = 300000;
    long bad = 0;
    for (long i = 0; i < n; i++) {
        float u[5];
        s_uniforms(600, (uint64_t)i, u, 5);
        pf_emission_t e;
        if (!pf_lights_emit(lt, sc, u, &e)) {
            bad++;
            continue;
        }
        double c = pf_dot(e.ray.d, l.dir);
        if (c < co - 1e-5 || e.ray.o.x != l.pos.x || e.ray.o.y != l.pos.y || e.ray.o.z != l.pos.z ||
            !(e.flux.x >= 0.0f))
            bad++;
        s_stat_add(&flux[0], e.flux.x);
        s_stat_add(&flux[1], e.flux.y);
        s_stat_add(&flux[2], e.flux.z);
        /* Intensity in bin k of cos over [co, 1]: sum of flux / (n * solid angle). */
        int k = (int)((c - co) / (1.0 - co) * NB);
        k = k < 0 ? 0 : k >= NB ? NB - 1 : k;
        double omega = 2.0 * PI_D * (1.0 - co) / NB;
        for (int b = 0; b < NB; b++)
            s_stat_add(&inten[b], b == k ? e.flux.x / omega : 0.0);
    }
    CHECK(bad == 0, "%ld spot photons outside the outer cone, off the light or with negative flux", bad);
    const float ic[3] = { l.intensity.x, l.intensity.y, l.intensity.z };
    for (int ch = 0; ch < 3; ch++) {
        double want = 2.0 * PI_D * ic[ch] * band, se = s_stat_se(&flux[ch]);
        CHECK(fabs(flux[ch].mean - want) <= 5.0 * se, "spot mean flux channel %d = %.5f, expected %.5f (5 se = %.3g)",
              ch, flux[ch].mean, want, 5.0 * se);
    }
    for (int b = 0; b < NB; b++) {
        /* Expected: I times the bin's mean falloff (fine midpoint rule). */
        double lo = co + (1.0 - co) * b / NB, hi = co + (1.0 - co) * (b + 1) / NB, s = 0.0;
        for (int j = 0; j < 1000; j++)
            s += pf_spot_falloff(&l, (float)(lo + (hi - lo) * (j + 0.5) / 1000.0));
        double want = l.intensity.x * s / 1000.0, se = s_stat_se(&inten[b]);
        CHECK(fabs(inten[b].mean - want) <= 5.0 * se + 1e-9,
              "spot emitted intensity for cos in [%.4f, %.4f] = %.4f, expected I falloff = %.4f (5 se = %.3g)", lo, hi,
              inten[b].mean, want, 5.0 * se);
    }

    /* Direct light: I falloff(cos) / d^2 inside, nothing outside. */
    pf_rng_t r = pf_rng_make(601, PF_STREAM_TEST, 0, 0);
    long bad_in = 0, bad_out = 0, n_in = 0, n_out = 0;
    for (int i = 0; i < 20000; i++) {
        pf_vec3 x = pf_v3(4.0f * pf_rng_float(&r) - 2.0f, 1.5f * pf_rng_float(&r), 4.0f * pf_rng_float(&r) - 2.0f);
        double dx = (double)x.x - l.pos.x, dy = (double)x.y - l.pos.y, dz = (double)x.z - l.pos.z;
        double d2 = dx * dx + dy * dy + dz * dz, d = sqrt(d2);
        double c = (dx * l.dir.x + dy * l.dir.y + dz * l.dir.z) / d;
        if (fabs(c - co) < 1e-4 || fabs(c - ci) < 1e-4)
            continue; /* too close to a cone edge to judge in float */
        float u[3];
        s_uniforms(602, (uint64_t)i, u, 3);
        pf_light_conn_t cn;
        int got = pf_lights_sample_direct(lt, sc, x, u, &cn);
        if (c <= co) {
            n_out++;
            bad_out += got;
            continue;
        }
        n_in++;
        double f = c >= ci ? 1.0 : pf_spot_falloff(&l, (float)c);
        double want = l.intensity.y * f / d2;
        /* Between the cones the float cosine moves the smoothstep by up to
         * its slope (about 3 / (ci - co)) times a few ulps. */
        double tol = c >= ci ? 1e-5 : 1e-5 + 3.0 / (ci - co) * 4e-7 / f;
        if (!got || s_rel(cn.weight.y, want) > tol || s_rel(cn.dist, d) > 1e-6) {
            if (bad_in++ < 3)
                fprintf(stderr, "  spot from (%g, %g, %g), cos %.6f: got %d weight %g, expected %g\n", x.x, x.y, x.z, c,
                        got, got ? cn.weight.y : 0.0, want);
        }
    }
    CHECK(n_in > 1000 && n_out > 1000, "spot direct test saw %ld points inside and %ld outside; want both", n_in, n_out);
    CHECK(bad_in == 0, "%ld points inside the spot with weight != I falloff / d^2", bad_in);
    CHECK(bad_out == 0, "%ld points outside the spot's outer cone received light", bad_out);
    pf_lights_destroy(&lt);
    pf_scene_destroy(&sc);
}

/* ---- (d) several lights ---- */

static void s_test_light_choice(void)
{
    pf_scene_t *sc = pf_scene_create();
    int fm = s_add_material(sc, pf_v3s(0.5f), pf_v3s(0.0f));
    int lm = s_add_material(sc, pf_v3s(0.0f), pf_v3s(2.0f));
    s_add_quad(sc, pf_v3(-5, 0, 5), pf_v3(10, 0, 0), pf_v3(0, 0, -10), fm, NULL);
    /* A 1 x 1 light at y = 3 facing down: power pi * 1 * 2 = 2 pi. */
    s_add_quad(sc, pf_v3(-0.5f, 3.0f, -0.5f), pf_v3(1, 0, 0), pf_v3(0, 0, 1), lm, NULL);
    pf_light_t p1, p2;
    memset(&p1, 0, sizeof p1);
    p1.type = PF_LIGHT_POINT;
    p1.pos = pf_v3(-1.0f, 2.0f, 0.0f);
    p1.intensity = pf_v3s(1.0f); /* 4 pi */
    p2 = p1;
    p2.pos = pf_v3(1.0f, 2.0f, 0.5f);
    p2.intensity = pf_v3s(3.0f); /* 12 pi */
    pf_scene_add_light(sc, &p1);
    pf_scene_add_light(sc, &p2);
    pf_light_t dark = p1;
    dark.intensity = pf_v3s(0.0f); /* no power: must not enter the table */
    pf_scene_add_light(sc, &dark);
    s_finalize(sc);
    pf_lights_t *lt = s_build(sc);
    double lum1 = pf_luminance(pf_v3s(1.0f)); /* 1 up to the float sum of the weights */
    double pw_quad = 2.0 * PI_D * lum1, pw1 = 4.0 * PI_D * lum1, pw2 = 12.0 * PI_D * lum1;
    double total = pw_quad + pw1 + pw2;
    CHECK(pf_lights_count(lt) == 4, "emitters = %zu, expected 4 (2 triangles, 2 lights; the dark one skipped)",
          pf_lights_count(lt));
    CHECK(s_rel(pf_lights_power(lt), total) < 1e-5, "total power = %.7g, expected %.7g", pf_lights_power(lt), total);
    const double prob[3] = { pw_quad / total, pw1 / total, pw2 / total };
    const char *names[3] = { "quad", "point 1 (I = 1)", "point 2 (I = 3)" };

    /* Emission: counts per light; with grey lights picked by power every
     * photon carries the total power. */
    const long n = 90000;
    long cnt[3] = { 0, 0, 0 }, bad = 0;
    for (long i = 0; i < n; i++) {
        float u[5];
        s_uniforms(700, (uint64_t)i, u, 5);
        pf_emission_t e;
        if (!pf_lights_emit(lt, sc, u, &e)) {
            bad++;
            continue;
        }
        int k = (e.ray.o.x == p1.pos.x && e.ray.o.y == p1.pos.y && e.ray.o.z == p1.pos.z)   ? 1
                : (e.ray.o.x == p2.pos.x && e.ray.o.y == p2.pos.y && e.ray.o.z == p2.pos.z) ? 2
                                                                                            : 0;
        if (k == 0 && fabsf(e.ray.o.y - 3.0f) > 1e-5f)
            k = -1;
        if (k < 0) {
            bad++;
            continue;
        }
        cnt[k]++;
        if (s_rel(e.flux.y, total / lum1) > 1e-5)
            bad++;
    }
    CHECK(bad == 0, "%ld photons unclassifiable or with flux != total power %.5g", bad, total);
    for (int k = 0; k < 3; k++) {
        double want = n * prob[k], sd = sqrt(n * prob[k] * (1.0 - prob[k]));
        CHECK(fabs(cnt[k] - want) <= 5.0 * sd, "emission picked %s %ld times of %ld, expected %.0f (5 sd = %.0f)",
              names[k], cnt[k], n, want, 5.0 * sd);
    }

    /* Direct light from the origin: counts, irradiance; a point light's pmf, read off
     * its weight I / (d^2 pmf), is the same for all its samples and matches its count. */
    long dcnt[3] = { 0, 0, 0 }, bad_w = 0;
    double dpmf[3] = { 0, 0, 0 }; /* read off the weights */
    s_stat irr = { 0 };
    pf_vec3 x = pf_v3(0, 0, 0);
    const pf_light_t *pl[3] = { NULL, &p1, &p2 };
    for (long i = 0; i < n; i++) {
        float u[3];
        s_uniforms(701, (uint64_t)i, u, 3);
        pf_light_conn_t c;
        if (!pf_lights_sample_direct(lt, sc, x, u, &c)) {
            s_stat_add(&irr, 0.0);
            continue;
        }
        pf_vec3 p = pf_madd(x, c.wi, c.dist);
        int k = pf_len(pf_sub(p, p1.pos)) < 1e-5f ? 1 : pf_len(pf_sub(p, p2.pos)) < 1e-5f ? 2 : 0;
        dcnt[k]++;
        if (k) {
            double d2 = pf_len2(pl[k]->pos), pmf = pl[k]->intensity.y / (d2 * c.weight.y);
            if (dpmf[k] == 0.0)
                dpmf[k] = pmf;
            if (s_rel(pmf, dpmf[k]) > 1e-5 || !(pmf > 0.0 && pmf < 1.0))
                bad_w++;
        }
        s_stat_add(&irr, c.weight.y * fmax(0.0, c.wi.y));
    }
    CHECK(bad_w == 0, "%ld point-light connections whose weight I / (d^2 pmf) implies another pmf", bad_w);
    for (int k = 1; k < 3; k++) {
        double want = n * dpmf[k], sd = sqrt(n * dpmf[k] * (1.0 - dpmf[k]));
        CHECK(fabs(dcnt[k] - want) <= 5.0 * sd, "direct sampling picked %s %ld times of %ld, its pmf says %.0f (5 sd = %.0f)",
              names[k], dcnt[k], n, want, 5.0 * sd);
    }
    double want = 2.0 * s_rect_irradiance(0, 0, -0.5, 0.5, -0.5, 0.5, 3.0);
    for (int k = 1; k < 3; k++) {
        double d = pf_len(pl[k]->pos);
        want += pl[k]->intensity.y * (pl[k]->pos.y / d) / (d * d);
    }
    CHECK(fabs(irr.mean - want) <= 5.0 * s_stat_se(&irr), "irradiance from three lights = %.5f, expected %.5f (5 se = %.3g)",
          irr.mean, want, 5.0 * s_stat_se(&irr));
    pf_lights_destroy(&lt);
    pf_scene_destroy(&sc);
}

/* ---- (e) a distant light ---- */

/* The flux a photon brings onto the parallelogram corner + a u + b v (a, b
 * in [0, 1]), 0 when its ray misses it. */
static double s_quad_flux(const pf_emission_t *e, pf_vec3 corner, pf_vec3 u, pf_vec3 v, int channel)
{
    pf_vec3 n = pf_cross(u, v);
    float dn = pf_dot(e->ray.d, n);
    if (dn == 0.0f)
        return 0.0;
    float t = pf_dot(pf_sub(corner, e->ray.o), n) / dn;
    if (!(t > 0.0f))
        return 0.0;
    pf_vec3 q = pf_sub(pf_madd(e->ray.o, e->ray.d, t), corner);
    double a = pf_dot(q, u) / pf_len2(u), b = pf_dot(q, v) / pf_len2(v);
    if (a < 0.0 || a > 1.0 || b < 0.0 || b > 1.0)
        return 0.0;
    return channel == 0 ? e->flux.x : channel == 1 ? e->flux.y : e->flux.z;
}

static void s_test_distant_light(void)
{
    pf_scene_t *sc = pf_scene_create();
    int fm = s_add_material(sc, pf_v3s(0.5f), pf_v3s(0.0f));
    /* A 2 x 1 quad tilted 30 degrees about x, and a small one far off that
     * stretches the bounds. */
    pf_vec3 corner = pf_v3(-1, 0, 0), qu = pf_v3(2, 0, 0), qv = pf_v3(0, 0.5f, -0.8660254f);
    s_add_quad(sc, corner, qu, qv, fm, NULL);
    s_add_quad(sc, pf_v3(3, -1, -2), pf_v3(0.1f, 0, 0), pf_v3(0, 0, -0.1f), fm, NULL);
    pf_light_t l;
    memset(&l, 0, sizeof l);
    l.type = PF_LIGHT_DISTANT;
    l.dir = pf_norm(pf_v3(0.2f, -1.0f, -0.4f));
    l.intensity = pf_v3(2.0f, 3.0f, 4.0f);
    pf_scene_add_light(sc, &l);
    s_finalize(sc);
    pf_lights_t *lt = s_build(sc);
    pf_vec3 lo, hi;
    pf_scene_geometry_bounds(sc, &lo, &hi);
    pf_vec3 c = pf_scale(pf_add(lo, hi), 0.5f);
    double half_diag = 0.5 * pf_len(pf_sub(hi, lo));
    /* the disc's radius from the power, which must cover the bounds */
    double r = sqrt(pf_lights_power(lt) / (PI_D * pf_luminance(l.intensity)));
    CHECK(pf_lights_count(lt) == 1 && r >= half_diag && r <= 1.02 * half_diag,
          "distant light: %zu emitters, disc radius %.5g for a bounding sphere of %.5g (power %.6g)",
          pf_lights_count(lt), r, half_diag, pf_lights_power(lt));

    long bad = 0;
    for (int i = 0; i < 1000; i++) {
        float u[3];
        s_uniforms(601, (uint64_t)i, u, 3);
        pf_light_conn_t lc;
        /* not chosen by power: the direct estimate takes it apart, whole */
        bad += pf_lights_sample_direct(lt, sc, pf_v3(u[0] * 2 - 1, u[1], u[2] - 1), u, &lc) != 0;
    }
    CHECK(bad == 0, "%ld samples of a table whose only emitter is distant returned a connection", bad);
    pf_light_conn_t dc;
    pf_lights_distant(lt, sc, 0, &dc);
    CHECK(pf_lights_distant_count(lt) == 1 && isinf(dc.dist) && dc.pdf == 0.0f && pf_dot(dc.wi, l.dir) <= -0.99999f &&
              s_rel(dc.weight.x, 2.0) <= 1e-6 && s_rel(dc.weight.z, 4.0) <= 1e-6,
          "%zu distant lights listed (expected 1), or its connection not (wi = -dir, dist = inf, weight = E, pdf 0)",
          pf_lights_distant_count(lt));

    /* Photons: along dir, from outside the sphere, through the disc; the flux
     * they bring onto the tilted quad is E cos A (channel y: 3). */
    pf_vec3 n = pf_norm(pf_cross(qu, qv));
    double want = 3.0 * fabs(pf_dot(n, l.dir)) * pf_len(pf_cross(qu, qv));
    const long np = 200000;
    long bad_e = 0;
    s_stat flux = { 0 };
    for (long i = 0; i < np; i++) {
        float u[5];
        s_uniforms(602, (uint64_t)i, u, 5);
        pf_emission_t e;
        if (!pf_lights_emit(lt, sc, u, &e)) {
            bad_e++;
            continue;
        }
        pf_vec3 to = pf_sub(c, e.ray.o);
        float along = pf_dot(to, e.ray.d);
        double off = pf_len(pf_sub(to, pf_scale(e.ray.d, along)));
        if (pf_dot(e.ray.d, l.dir) < 0.99999f || along < half_diag || off > r * 1.0001 ||
            s_rel(e.flux.y, 3.0 * PI_D * r * r) > 1e-4 || !pf_is_black(e.n))
            bad_e++;
        s_stat_add(&flux, s_quad_flux(&e, corner, qu, qv, 1));
    }
    CHECK(bad_e == 0, "%ld distant-light photons not along dir, from inside the sphere, off the disc or with flux "
                      "!= E pi R^2", bad_e);
    CHECK(fabs(flux.mean - want) <= 5.0 * s_stat_se(&flux),
          "distant light: flux onto the tilted quad %.5f per photon, expected E cos A = %.5f (5 se = %.3g)", flux.mean,
          want, 5.0 * s_stat_se(&flux));

    /* Caustic photons aimed at a mirror sphere of radius 0.3 (the only
     * specular target), with a sky of radiance L added: the flux onto it is
     * E pi r^2 from the sun and pi L 4 pi r^2 from the sky (channel z: E 4,
     * L 0.1). */
    pf_material_t mir = pf_material_default("mirror");
    mir.type = PF_MAT_MIRROR;
    mir.ks = pf_v3s(1.0f);
    pf_sphere_t sp = { pf_v3(0.5f, 0.6f, -0.2f), 0.3f, (uint32_t)pf_scene_add_material(sc, &mir) };
    pf_scene_add_sphere(sc, &sp);
    pf_light_t sky = { .type = PF_LIGHT_INFINITE, .intensity = pf_v3s(0.1f) };
    pf_scene_add_light(sc, &sky);
    pf_lights_t *lt2 = s_build(sc);
    pf_target_t *targets = NULL;
    int nt = pf_specular_targets(sc, &targets);
    CHECK(nt == 1, "one specular target, got %d", nt);
    s_stat sflux = { 0 };
    long hits = 0;
    for (long i = 0; nt == 1 && i < np; i++) {
        float u[6];
        s_uniforms(603, (uint64_t)i, u, 6);
        pf_emission_t e;
        double got = 0.0;
        if (pf_lights_emit_targeted(lt2, sc, targets, 1, u, &e)) {
            pf_vec3 oc = pf_sub(sp.center, e.ray.o);
            float along = pf_dot(oc, e.ray.d);
            if (pf_len2(oc) - along * along <= sp.radius * sp.radius && along > 0.0f) {
                got = e.flux.z;
                hits++;
            }
        }
        s_stat_add(&sflux, got);
    }
    double swant = 4.0 * PI_D * sp.radius * sp.radius + PI_D * 0.1 * 4.0 * PI_D * sp.radius * sp.radius;
    CHECK(hits > np / 2, "only %ld of %ld aimed photons hit the sphere", hits, np);
    CHECK(fabs(sflux.mean - swant) <= 5.0 * s_stat_se(&sflux),
          "distant light and sky: aimed flux onto the sphere %.5f per photon, expected (E + 4 pi L) pi r^2 = %.5f "
          "(5 se = %.3g)",
          sflux.mean, swant, 5.0 * s_stat_se(&sflux));
    free(targets);
    pf_lights_destroy(&lt2);
    pf_lights_destroy(&lt);
    pf_scene_destroy(&sc);
}

/* ---- (f) an infinite light ---- */

static void s_test_infinite_light(void)
{
    pf_scene_t *sc = pf_scene_create();
    int fm = s_add_material(sc, pf_v3s(0.5f), pf_v3s(0.0f));
    pf_vec3 corner = pf_v3(-1, 0, 0.5f), qu = pf_v3(2, 0, 0), qv = pf_v3(0, 0, -1);
    s_add_quad(sc, corner, qu, qv, fm, NULL);
    s_add_quad(sc, pf_v3(0, 1, 0), pf_v3(0.1f, 0, 0), pf_v3(0, 0, -0.1f), fm, NULL);
    pf_light_t l;
    memset(&l, 0, sizeof l);
    l.type = PF_LIGHT_INFINITE;
    l.intensity = pf_v3(0.5f, 1.0f, 2.0f);
    pf_scene_add_light(sc, &l);
    s_finalize(sc);
    pf_lights_t *lt = s_build(sc);
    pf_vec3 lo, hi;
    pf_scene_geometry_bounds(sc, &lo, &hi);
    double half_diag = 0.5 * pf_len(pf_sub(hi, lo));
    double r = sqrt(pf_lights_power(lt) / (4.0 * PI_D * PI_D * pf_luminance(l.intensity)));
    CHECK(r >= half_diag && r <= 1.02 * half_diag, "infinite light: disc radius %.5g for a bounding sphere of %.5g", r,
          half_diag);
    /* irradiance on a tilted normal: pi L */
    pf_vec3 n = pf_norm(pf_v3(0.3f, 1.0f, -0.5f));
    s_stat irr = { 0 };
    long bad = 0;
    const long ns = 400000;
    for (long i = 0; i < ns; i++) {
        float u[3];
        s_uniforms(701, (uint64_t)i, u, 3);
        pf_light_conn_t lc;
        if (!pf_lights_sample_direct(lt, sc, pf_v3(0, 0, 0), u, &lc) || !isinf(lc.dist) ||
            s_rel(lc.pdf, 1.0 / (4.0 * PI_D)) > 1e-5 || lc.pdf != pf_lights_sky_pdf(lt, pf_v3s(0.0f), lc.wi) ||
            fabsf(pf_len(lc.wi) - 1.0f) > 1e-5f) {
            bad++;
            continue;
        }
        s_stat_add(&irr, lc.weight.z * fmax(0.0, pf_dot(lc.wi, n)));
        /* cosine-weighted about a known normal: every sample gives pi L */
        bad += !pf_lights_sample_direct_at(lt, sc, pf_v3(0, 0, 0), n, u, &lc) ||
               s_rel(lc.weight.z * pf_dot(lc.wi, n), PI_D * 2.0) > 1e-4 ||
               fabs(lc.pdf - pf_lights_sky_pdf(lt, n, lc.wi)) > 1e-5 * (1.0 / PI_D); /* rounding of cos */
    }
    CHECK(bad == 0, "%ld infinite-light connections not (unit wi, dist = inf, pdf 1 / (4 pi) = pf_lights_sky_pdf) "
                    "or, about n, not pi L with pdf cos / pi", bad);
    CHECK(fabs(irr.mean - PI_D * 2.0) <= 5.0 * s_stat_se(&irr),
          "infinite light: irradiance %.5f, expected pi L = %.5f (5 se = %.3g)", irr.mean, PI_D * 2.0,
          5.0 * s_stat_se(&irr));
    /* photons down onto the quad's top: pi L A (channel y: L = 1) */
    s_stat flux = { 0 };
    for (long i = 0; i < ns; i++) {
        float u[5];
        s_uniforms(702, (uint64_t)i, u, 5);
        pf_emission_t e;
        double got = 0.0;
        if (pf_lights_emit(lt, sc, u, &e) && e.ray.d.y < 0.0f)
            got = s_quad_flux(&e, corner, qu, qv, 1);
        s_stat_add(&flux, got);
    }
    double want = PI_D * 1.0 * 2.0;
    CHECK(fabs(flux.mean - want) <= 5.0 * s_stat_se(&flux),
          "infinite light: flux down onto the quad %.5f per photon, expected pi L A = %.5f (5 se = %.3g)", flux.mean,
          want, 5.0 * s_stat_se(&flux));
    pf_lights_destroy(&lt);
    pf_scene_destroy(&sc);
}

/* An empty table is valid and samples nothing. */
static void s_test_empty(void)
{
    pf_scene_t *sc = pf_scene_create();
    int fm = s_add_material(sc, pf_v3s(0.5f), pf_v3s(0.0f));
    s_add_quad(sc, pf_v3(-5, 0, 5), pf_v3(10, 0, 0), pf_v3(0, 0, -10), fm, NULL);
    pf_lights_t *lt = s_build(sc); /* not finalized: finalize refuses a scene without light */
    const float u[5] = { 0.1f, 0.2f, 0.3f, 0.4f, 0.5f };
    pf_light_conn_t c;
    pf_emission_t e;
    CHECK(pf_lights_count(lt) == 0 && pf_lights_power(lt) == 0.0, "empty table: count %zu, power %g, expected 0, 0",
          pf_lights_count(lt), pf_lights_power(lt));
    CHECK(pf_lights_sample_direct(lt, sc, pf_v3(0, 1, 0), u, &c) == 0, "empty table: sample_direct must return 0");
    CHECK(pf_lights_emit(lt, sc, u, &e) == 0, "empty table: emit must return 0");
    pf_lights_destroy(&lt);
    pf_lights_destroy(&lt); /* NULL-safe */
    pf_scene_destroy(&sc);
}

int main(void)
{
    s_test_area_light();
    s_test_area_light_vertex_normals();
    s_test_point_light();
    s_test_point_light_far();
    s_test_spot_light();
    s_test_light_choice();
    s_test_distant_light();
    s_test_infinite_light();
    s_test_empty();
    printf("%d passed, %d failed\n", s_passed, s_failed);
    return s_failed ? 1 : 0;
}
