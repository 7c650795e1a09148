/* test_envmap.c: the image-based infinite light (scene/envmap.c,
 * light/envlight.c and its entries in light/light.c, the readers in load/,
 * the scene blob):
 *   (a) the equal-area square: round trips both ways, unit directions, and
 *       a constant Jacobian 4 pi (equal areas hold equal solid angles);
 *   (b) the sampling pdf integrates to 1 over the sphere (both mappings);
 *       a chi-square test of sampled directions against it, binned by map
 *       pixel; each sample's weight is L / pdf with pdf = pf_lights_sky_pdf;
 *   (c) a map black but for one pixel lights an upward receiver with the
 *       analytic irradiance L dphi (sin^2 t1 - sin^2 t0) / 2, and with a
 *       constant sky L' beside it (the two sampled as one mixture) that plus
 *       pi L';
 *   (d) the photons' flux: the mean emitted flux is pi R^2 times the map's
 *       integral, and the flux onto an upward quad its irradiance times its
 *       area; caustic photons aimed at a sphere bring it pi r^2 int L;
 *   (e) the scene blob carries the map bit for bit;
 *   (f) the readers: pbrt-v4 "infinite" with a filename (the CTM turns the
 *       map, scale and illuminance apply), JSON equirect; a non-square map
 *       and a missing file are errors naming the file (and file:line);
 *       skies in Radiance HDR and 8-bit PNG (sRGB-decoded), a broken .hdr
 *       an error naming it. */
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include <stb_image_write.h>

#include "base/log.h"
#include "base/rng.h"
#include "check.h"
#include "image/image.h"
#include "light/light.h"
#include "load/load.h"
#include "proto/sceneblob.h"

#define PI_D 3.14159265358979323846

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

static void s_uniforms(uint64_t seed, uint64_t i, float *u, int n)
{
    pf_rng_t r = pf_rng_make(seed, PF_STREAM_TEST, i, 0);
    for (int k = 0; k < n; k++)
        u[k] = pf_rng_float(&r);
}

/* ---- (a) the equal-area square ---- */

static void s_test_equal_area(void)
{
    long bad_rt = 0, bad_len = 0, bad_jac = 0, n = 0;
    double worst_jac = 0.0;
    for (long i = 0; i < 20000; i++) {
        float u[2];
        s_uniforms(11, (uint64_t)i, u, 2);
        u[0] = 0.002f + 0.996f * u[0];
        u[1] = 0.002f + 0.996f * u[1];
        pf_vec3 d = pf_equal_area_square_to_sphere(u[0], u[1]);
        bad_len += fabsf(pf_len(d) - 1.0f) > 1e-5f;
        float a, b;
        pf_equal_area_sphere_to_square(d, &a, &b);
        bad_rt += fabsf(a - u[0]) > 2e-4f || fabsf(b - u[1]) > 2e-4f;
        /* sphere -> square -> sphere */
        pf_vec3 w = pf_norm(pf_v3(2.0f * u[0] - 1.0f, 2.0f * u[1] - 1.0f, 1.7f * u[0] - 0.9f));
        pf_equal_area_sphere_to_square(w, &a, &b);
        bad_rt += !(a >= 0.0f && a <= 1.0f && b >= 0.0f && b <= 1.0f) ||
                  pf_len(pf_sub(pf_equal_area_square_to_sphere(a, b), w)) > 1e-3f;
        /* the Jacobian by central differences, away from the folds (the
         * axes and the diagonal ring), where the map is smooth */
        double x = 2.0 * u[0] - 1.0, y = 2.0 * u[1] - 1.0, h = 1e-3;
        if (fabs(x) < 4 * h || fabs(y) < 4 * h || fabs(fabs(x) + fabs(y) - 1.0) < 4 * h)
            continue;
        pf_vec3 du = pf_sub(pf_equal_area_square_to_sphere(u[0] + (float)h, u[1]),
                            pf_equal_area_square_to_sphere(u[0] - (float)h, u[1]));
        pf_vec3 dv = pf_sub(pf_equal_area_square_to_sphere(u[0], u[1] + (float)h),
                            pf_equal_area_square_to_sphere(u[0], u[1] - (float)h));
        double jac = pf_len(pf_cross(du, dv)) / (4.0 * h * h);
        double rel = fabs(jac / (4.0 * PI_D) - 1.0);
        worst_jac = fmax(worst_jac, rel);
        bad_jac += rel > 0.01;
        n++;
    }
    printf("equal-area: %ld round trips off, %ld not unit, Jacobian / 4 pi off by at most %.2e over %ld points\n",
           bad_rt, bad_len, worst_jac, n);
    CHECK(bad_rt == 0 && bad_len == 0, "equal-area: %ld round trips off, %ld not unit", bad_rt, bad_len);
    CHECK(n > 15000 && bad_jac == 0, "equal-area: Jacobian off 4 pi by %.3g (%ld points over 1 %%)", worst_jac,
          bad_jac);
    /* the centre is +z, the corners -z, the edge midpoints the equator */
    pf_vec3 c = pf_equal_area_square_to_sphere(0.5f, 0.5f), k = pf_equal_area_square_to_sphere(0.0f, 0.0f);
    pf_vec3 e = pf_equal_area_square_to_sphere(1.0f, 0.5f);
    CHECK(c.z > 0.9999f && k.z < -0.9999f && fabsf(e.z) < 1e-6f && e.x > 0.9999f,
          "equal-area: centre (%g %g %g), corner (%g %g %g), edge (%g %g %g)", c.x, c.y, c.z, k.x, k.y, k.z, e.x, e.y,
          e.z);
}

/* ---- scenes with a map ---- */

/* A map of w x h with pixel values from fn; identity frame. */
static pf_envmap_t s_map(int w, int h, int mapping, pf_vec3 (*fn)(int x, int y, int w, int h))
{
    pf_envmap_t m;
    memset(&m, 0, sizeof m);
    snprintf(m.name, sizeof m.name, "test");
    m.width = w;
    m.height = h;
    m.mapping = mapping;
    m.rgb = malloc((size_t)w * h * 3 * sizeof *m.rgb);
    PF_CHECK(m.rgb != NULL);
    for (int y = 0; y < h; y++)
        for (int x = 0; x < w; x++) {
            pf_vec3 v = fn(x, y, w, h);
            float *p = &m.rgb[3 * ((size_t)y * w + x)];
            p[0] = v.x, p[1] = v.y, p[2] = v.z;
        }
    const double id[9] = { 1, 0, 0, 0, 1, 0, 0, 0, 1 };
    pf_envmap_set_frame(&m, id);
    return m;
}

static pf_vec3 s_varied(int x, int y, int w, int h)
{
    float a = 0.2f + (float)((x * 7 + y * 13) % 11) / 5.0f;
    if (x == w / 3 && y == h / 4)
        a = 40.0f; /* a sun */
    return pf_v3(a, 0.5f * a + 0.1f, (x + y) % 3 == 0 ? 0.0f : a);
}

/* A unit quad facing +z at z = 0 (the geometry the lights need) and a light
 * of map m, scale s. */
static pf_scene_t *s_scene(pf_envmap_t *m, pf_vec3 s)
{
    pf_scene_t *sc = pf_scene_create();
    pf_material_t mat = pf_material_default("grey");
    uint32_t mi = (uint32_t)pf_scene_add_material(sc, &mat);
    pf_mesh_t mesh;
    memset(&mesh, 0, sizeof mesh);
    snprintf(mesh.name, sizeof mesh.name, "quad");
    mesh.nverts = 4;
    mesh.ntris = 2;
    mesh.pos = malloc(4 * sizeof *mesh.pos);
    mesh.idx = malloc(6 * sizeof *mesh.idx);
    mesh.mat = malloc(2 * sizeof *mesh.mat);
    PF_CHECK(mesh.pos && mesh.idx && mesh.mat);
    mesh.pos[0] = pf_v3(-0.5f, -0.5f, 0);
    mesh.pos[1] = pf_v3(0.5f, -0.5f, 0);
    mesh.pos[2] = pf_v3(0.5f, 0.5f, 0);
    mesh.pos[3] = pf_v3(-0.5f, 0.5f, 0);
    const uint32_t idx[6] = { 0, 1, 2, 0, 2, 3 };
    memcpy(mesh.idx, idx, sizeof idx);
    mesh.mat[0] = mesh.mat[1] = mi;
    pf_scene_add_mesh(sc, &mesh);
    int k = pf_scene_add_envmap(sc, m);
    pf_light_t l = { .type = PF_LIGHT_INFINITE, .intensity = s, .map = (uint32_t)k + 1 };
    pf_scene_add_light(sc, &l);
    pf_error_t err = { { 0 } };
    CHECK(pf_scene_finalize(sc, &err) == PF_OK, "finalize: %s", err.msg);
    return sc;
}

/* ---- (b) pdf and samples ---- */

static void s_test_pdf(int mapping)
{
    const char *name = mapping == PF_ENVMAP_EQUALAREA ? "equal-area" : "equirect";
    int w = mapping == PF_ENVMAP_EQUALAREA ? 8 : 16, h = 8;
    pf_envmap_t m = s_map(w, h, mapping, s_varied);
    pf_scene_t *sc = s_scene(&m, pf_v3(1.0f, 2.0f, 0.5f));
    const pf_envmap_t *map = &sc->envmaps[0];
    pf_lights_t *lt = pf_lights_build(sc);
    PF_CHECK(lt != NULL);
    /* the pdf's integral over the sphere on a fine grid of the map's own
     * square (equal-area cells) or of (theta, phi) with sin theta */
    double integral = 0.0;
    const int g = 512;
    for (int j = 0; j < g; j++)
        for (int i = 0; i < g; i++) {
            float u = (i + 0.5f) / g, v = (j + 0.5f) / g;
            if (mapping == PF_ENVMAP_EQUALAREA) {
                integral += pf_lights_sky_pdf(lt, pf_v3s(0.0f), pf_equal_area_square_to_sphere(u, v)) * 4.0 * PI_D /
                            ((double)g * g);
            } else {
                double th = PI_D * v, ph = 2.0 * PI_D * u;
                pf_vec3 d = pf_v3((float)(sin(th) * cos(ph)), (float)(sin(th) * sin(ph)), (float)cos(th));
                integral += pf_lights_sky_pdf(lt, pf_v3s(0.0f), d) * sin(th) * (PI_D / g) * (2.0 * PI_D / g);
            }
        }
    printf("%s: the pdf integrates to %.6f\n", name, integral);
    CHECK(fabs(integral - 1.0) < 2e-3, "%s: the pdf integrates to %.6f, not 1", name, integral);
    /* chi-square of samples binned by pixel against pdf x pixel solid angle */
    const long ns = 200000;
    long *count = calloc((size_t)w * h, sizeof *count);
    long bad = 0;
    for (long i = 0; i < ns; i++) {
        float u[3];
        s_uniforms(21, (uint64_t)i, u, 3);
        pf_light_conn_t lc;
        if (!pf_lights_sample_direct(lt, sc, pf_v3(0, 0, 0), u, &lc)) {
            bad++;
            continue;
        }
        pf_vec3 L = pf_lights_sky(lt, lc.wi);
        float pdf = pf_lights_sky_pdf(lt, pf_v3s(0.0f), lc.wi);
        bad += !isinf(lc.dist) || lc.pdf != pdf || fabsf(lc.weight.y - L.y / pdf) > 1e-5f * L.y / pdf ||
               fabsf(pf_len(lc.wi) - 1.0f) > 1e-5f;
        int x, y;
        pf_envmap_pixel(map, lc.wi, &x, &y);
        count[y * w + x]++;
    }
    double x2 = 0.0;
    int bins = 0;
    long zero_hits = 0;
    for (int y = 0; y < h; y++)
        for (int x = 0; x < w; x++) {
            pf_vec3 c = pf_envmap_pixel_dir(map, x, y, 0.5f, 0.5f);
            double e = ns * pf_lights_sky_pdf(lt, pf_v3s(0.0f), c) * pf_envmap_pixel_solid_angle(map, y);
            if (e <= 0.0) {
                zero_hits += count[y * w + x];
                continue;
            }
            x2 += (count[y * w + x] - e) * (count[y * w + x] - e) / e;
            bins++;
        }
    double bound = (bins - 1) + 5.0 * sqrt(2.0 * (bins - 1));
    printf("%s: chi-square %.1f over %d pixels (bound %.1f), %ld samples bad, %ld in pixels of pdf 0\n", name, x2, bins,
           bound, bad, zero_hits);
    CHECK(bad == 0 && zero_hits == 0, "%s: %ld samples not (L / pdf, pdf = sky pdf), %ld where the pdf is 0", name, bad,
          zero_hits);
    CHECK(x2 < bound, "%s: chi-square %.1f over %d pixels, bound %.1f", name, x2, bins, bound);
    free(count);
    pf_lights_destroy(&lt);
    pf_scene_destroy(&sc);
}

/* ---- (c) one bright pixel over an upward receiver ---- */

static int s_px = 5, s_py = 3; /* the bright pixel of a 32 x 16 equirect map */
static pf_vec3 s_patch(int x, int y, int w, int h)
{
    (void)w, (void)h;
    return x == s_px && y == s_py ? pf_v3(100.0f, 50.0f, 25.0f) : pf_v3s(0.0f);
}

static void s_test_patch(void)
{
    pf_envmap_t m = s_map(32, 16, PF_ENVMAP_EQUIRECT, s_patch);
    pf_scene_t *sc = s_scene(&m, pf_v3s(2.0f));
    pf_lights_t *lt = pf_lights_build(sc);
    /* E = L dphi (sin^2 t1 - sin^2 t0) / 2 about +z */
    double t0 = PI_D * s_py / 16.0, t1 = PI_D * (s_py + 1) / 16.0;
    double want = 2.0 * 50.0 * (2.0 * PI_D / 32.0) * (sin(t1) * sin(t1) - sin(t0) * sin(t0)) / 2.0;
    s_stat irr = { 0 }, irr_n = { 0 };
    pf_vec3 n = pf_v3(0, 0, 1);
    for (long i = 0; i < 100000; i++) {
        float u[3];
        s_uniforms(31, (uint64_t)i, u, 3);
        pf_light_conn_t lc;
        double v = 0.0, vn = 0.0;
        if (pf_lights_sample_direct(lt, sc, pf_v3(0, 0, 0), u, &lc))
            v = lc.weight.y * fmax(0.0, pf_dot(lc.wi, n));
        if (pf_lights_sample_direct_at(lt, sc, pf_v3(0, 0, 0), n, u, &lc))
            vn = lc.weight.y * fmax(0.0, pf_dot(lc.wi, n));
        s_stat_add(&irr, v);
        s_stat_add(&irr_n, vn);
    }
    printf("bright pixel: irradiance %.5f and %.5f (at a normal), expected %.5f (5 se = %.2g)\n", irr.mean, irr_n.mean,
           want, 5.0 * s_stat_se(&irr));
    CHECK(fabs(irr.mean - want) <= 5.0 * s_stat_se(&irr) + 1e-4 * want &&
              fabs(irr_n.mean - want) <= 5.0 * s_stat_se(&irr_n) + 1e-4 * want,
          "bright pixel: irradiance %.5f / %.5f, expected %.5f", irr.mean, irr_n.mean, want);
    pf_lights_destroy(&lt);
    /* with a constant sky beside it: one emitter of both radiances, sampled
     * by the mixture; the irradiance adds pi Lc */
    pf_light_t c = { .type = PF_LIGHT_INFINITE, .intensity = pf_v3s(0.3f) };
    pf_scene_add_light(sc, &c);
    lt = pf_lights_build(sc);
    double want2 = want + PI_D * 0.3;
    s_stat mix = { 0 };
    long bad = 0;
    for (long i = 0; i < 100000; i++) {
        float u[3];
        s_uniforms(32, (uint64_t)i, u, 3);
        pf_light_conn_t lc;
        double v = 0.0;
        if (pf_lights_sample_direct_at(lt, sc, pf_v3(0, 0, 0), n, u, &lc)) {
            v = lc.weight.y * fmax(0.0, pf_dot(lc.wi, n));
            bad += lc.pdf != pf_lights_sky_pdf(lt, n, lc.wi);
        }
        s_stat_add(&mix, v);
    }
    printf("bright pixel and a constant sky: irradiance %.5f, expected %.5f (5 se = %.2g)\n", mix.mean, want2,
           5.0 * s_stat_se(&mix));
    CHECK(bad == 0 && fabs(mix.mean - want2) <= 5.0 * s_stat_se(&mix),
          "map and constant sky: irradiance %.5f, expected %.5f; %ld pdfs not the mixture's", mix.mean, want2, bad);
    pf_lights_destroy(&lt);
    pf_scene_destroy(&sc);
}

/* ---- (d) photons ---- */

static void s_test_photons(void)
{
    pf_envmap_t m = s_map(16, 16, PF_ENVMAP_EQUALAREA, s_varied);
    pf_scene_t *sc = s_scene(&m, pf_v3(1.0f, 1.0f, 0.5f));
    pf_lights_t *lt = pf_lights_build(sc);
    const pf_envmap_t *map = &sc->envmaps[0];
    /* the disc: the unit quad's bounding sphere, widened as light.c does */
    double R = 0.5 * sqrt(2.0) * 1.01 + 1e-6;
    double lum = pf_envmap_integral(map, pf_v3(1.0f, 1.0f, 0.5f), 0);
    double up = pf_envmap_integral(map, pf_v3(1.0f, 1.0f, 0.5f), 1);
    CHECK(fabs(pf_lights_power(lt) / (PI_D * R * R * lum) - 1.0) < 1e-4, "map power %.6g, expected pi R^2 %.6g",
          pf_lights_power(lt), PI_D * R * R * lum);
    s_stat all = { 0 }, onto = { 0 };
    long bad = 0;
    for (long i = 0; i < 400000; i++) {
        float u[5];
        s_uniforms(41, (uint64_t)i, u, 5);
        pf_emission_t e;
        double f = 0.0, g = 0.0;
        if (pf_lights_emit(lt, sc, u, &e)) {
            f = pf_luminance(e.flux);
            bad += !pf_is_finite3(e.flux) || fabsf(pf_len(e.ray.d) - 1.0f) > 1e-5f;
            /* does it cross the quad (z = 0) from above? */
            if (e.ray.d.z < 0.0f && e.ray.o.z > 0.0f) {
                float t = -e.ray.o.z / e.ray.d.z;
                pf_vec3 p = pf_madd(e.ray.o, e.ray.d, t);
                if (fabsf(p.x) <= 0.5f && fabsf(p.y) <= 0.5f)
                    g = f;
            }
        }
        s_stat_add(&all, f);
        s_stat_add(&onto, g);
    }
    /* the map's +z is the world's +z: what reaches the quad's top is its
     * upward irradiance times its area, 1 */
    printf("photons: mean flux %.5f, expected pi R^2 int L = %.5f; onto the quad %.5f, expected E A = %.5f "
           "(5 se = %.2g)\n",
           all.mean, PI_D * R * R * lum, onto.mean, up, 5.0 * s_stat_se(&onto));
    CHECK(bad == 0, "%ld photons not finite or not unit", bad);
    CHECK(fabs(all.mean - PI_D * R * R * lum) <= 1e-3 * PI_D * R * R * lum, "photons: mean flux %.5f, expected %.5f",
          all.mean, PI_D * R * R * lum);
    CHECK(fabs(onto.mean - up) <= 5.0 * s_stat_se(&onto), "photons onto the quad: %.5f, expected %.5f", onto.mean, up);
    /* caustic photons aimed at a sphere: the flux that reaches it is
     * pi r^2 int L (every direction's radiance through its cross-section) */
    pf_target_t t = { pf_v3(0.1f, -0.1f, 0.2f), 0.25f };
    s_stat aimed = { 0 };
    long hits = 0;
    for (long i = 0; i < 400000; i++) {
        float u[6];
        s_uniforms(42, (uint64_t)i, u, 6);
        pf_emission_t e;
        double f = 0.0;
        if (pf_lights_emit_targeted(lt, sc, &t, 1, u, &e)) {
            pf_vec3 oc = pf_sub(t.center, e.ray.o);
            float along = pf_dot(oc, e.ray.d);
            if (along > 0.0f && pf_len2(oc) - along * along <= t.radius * t.radius) {
                f = pf_luminance(e.flux);
                hits++;
            }
        }
        s_stat_add(&aimed, f);
    }
    double want = PI_D * t.radius * t.radius * lum;
    printf("caustic photons: flux onto the target %.5f, expected pi r^2 int L = %.5f (5 se = %.2g), %ld of 400000 "
           "hit\n",
           aimed.mean, want, 5.0 * s_stat_se(&aimed), hits);
    CHECK(hits > 300000 && fabs(aimed.mean - want) <= 5.0 * s_stat_se(&aimed), "caustic photons: %.5f, expected %.5f",
          aimed.mean, want);
    pf_lights_destroy(&lt);
    pf_scene_destroy(&sc);
}

/* ---- (e) the scene blob ---- */

static void s_test_blob(void)
{
    pf_envmap_t m = s_map(24, 12, PF_ENVMAP_EQUIRECT, s_varied);
    const double rot[9] = { 0, -1, 0, 1, 0, 0, 0, 0, 1 };
    pf_envmap_set_frame(&m, rot);
    pf_scene_t *sc = s_scene(&m, pf_v3(0.5f, 1.0f, 2.0f));
    pf_buf_t buf = { 0 };
    CHECK(pf_sceneblob_write(sc, &buf) == PF_OK, "blob write");
    pf_error_t err = { { 0 } };
    pf_scene_t *back = pf_sceneblob_read(buf.data, buf.len, &err);
    CHECK(back != NULL, "blob read: %s", err.msg);
    if (back) {
        const pf_envmap_t *a = &sc->envmaps[0], *b = &back->envmaps[0];
        CHECK(back->nenvmaps == 1 && back->nlights == 1 && back->lights[0].map == 1 && a->width == b->width &&
                  a->height == b->height && a->mapping == b->mapping && !strcmp(a->name, b->name) &&
                  !memcmp(a->to_world, b->to_world, sizeof a->to_world) &&
                  !memcmp(a->to_light, b->to_light, sizeof a->to_light) &&
                  !memcmp(a->rgb, b->rgb, pf_envmap_bytes(a)),
              "blob: the map did not come back bit for bit");
        /* a truncated blob is an error, not a crash */
        pf_scene_t *cut = pf_sceneblob_read(buf.data, buf.len - 7, &err);
        CHECK(cut == NULL, "a truncated blob with a map was read");
        pf_scene_destroy(&cut);
    }
    printf("blob: %zu bytes with a 24x12 map\n", buf.len);
    pf_buf_free(&buf);
    pf_scene_destroy(&back);
    pf_scene_destroy(&sc);
}

/* ---- (f) the readers ---- */

static void s_write_map(const char *path, int w, int h, float v)
{
    pf_image_t img;
    PF_CHECK(pf_image_alloc(&img, w, h) == PF_OK);
    for (size_t k = 0; k < (size_t)w * h * 3; k++)
        img.rgb[k] = v;
    for (int k = 0; k < 4; k++) /* the corner pixels: the square's corners are -z */
        img.rgb[3 * ((k & 1 ? w - 1 : 0) + (k & 2 ? (size_t)(h - 1) * w : 0))] = 10.0f * v;
    pf_error_t err;
    PF_CHECK(pf_image_write_pfm(&img, path, &err) == PF_OK);
    pf_image_free(&img);
}

static void s_write(const char *path, const char *text)
{
    FILE *f = fopen(path, "w");
    PF_CHECK(f != NULL);
    fputs(text, f);
    fclose(f);
}

static const char *s_pbrt_body = "Shape \"trianglemesh\" \"point3 P\" [ -1 -1 0 1 -1 0 1 1 0 -1 1 0 ] "
                                 "\"integer indices\" [ 0 1 2 0 2 3 ]\n";

/* Skies in Radiance HDR and 8-bit PNG (read as textures are): the HDR's
 * values as written (RGBE keeps 8 bits of mantissa), the PNG's sRGB-decoded. */
static void s_test_ldr_skies(const char *dir, const char *scene)
{
    enum { W = 32, H = 16 };
    static float hdr[W * H * 3];
    static unsigned char png[W * H * 3];
    for (int k = 0; k < W * H * 3; k++) {
        hdr[k] = 1.5f;
        png[k] = 128;
    }
    hdr[0] = 15.0f; /* the top-left pixel: the zenith's first columns */
    png[0] = 255;
    char path[300], text[1024];
    snprintf(path, sizeof path, "%s/sky.hdr", dir);
    PF_CHECK(stbi_write_hdr(path, W, H, 3, hdr));
    snprintf(path, sizeof path, "%s/sky.png", dir);
    PF_CHECK(stbi_write_png(path, W, H, 3, png, W * 3));
    snprintf(path, sizeof path, "%s/bad.hdr", dir);
    s_write(path, "#?RADIANCE\nthis is not a picture\n");
    const char *names[3] = { "sky.hdr", "sky.png", "bad.hdr" };
    const float want_up[2] = { 15.0f, 1.0f }, want_side[2] = { 1.5f, 0.21586050f };
    for (int i = 0; i < 3; i++) {
        snprintf(text, sizeof text,
                 "{ \"objects\": [ { \"type\": \"quad\", \"origin\": [-1, 0, -1], \"edge1\": [2, 0, 0], "
                 "\"edge2\": [0, 0, 2], \"material\": \"m\" } ],\n  \"materials\": [ { \"name\": \"m\", "
                 "\"kd\": 0.5 } ],\n  \"lights\": [ { \"type\": \"infinite\", \"image\": \"%s\", "
                 "\"mapping\": \"equirect\" } ] }\n",
                 names[i]);
        s_write(scene, text);
        pf_error_t err = { { 0 } };
        pf_scene_t *sc = pf_scene_load(scene, &err);
        if (i == 2) {
            CHECK(sc == NULL && strstr(err.msg, "bad.hdr"), "a broken .hdr sky: %s", err.msg);
            pf_scene_destroy(&sc);
            continue;
        }
        CHECK(sc != NULL, "JSON with %s: %s", names[i], err.msg);
        if (!sc)
            continue;
        pf_lights_t *lt = pf_lights_build(sc);
        /* world (x, y, z) is light (x, -z, y): this is near the zenith at an azimuth just above 0, column 0 */
        pf_vec3 up = pf_lights_sky(lt, pf_norm(pf_v3(1.0f, 1000.0f, -0.001f)));
        pf_vec3 side = pf_lights_sky(lt, pf_v3(1, 0, 0));
        CHECK(fabsf(up.x - want_up[i]) < 1e-5f * want_up[i] && fabsf(side.x - want_side[i]) < 1e-5f &&
                  fabsf(side.y - want_side[i]) < 1e-5f,
              "%s: zenith %g (want %g), side %g %g (want %g)", names[i], up.x, want_up[i], side.x, side.y,
              want_side[i]);
        pf_lights_destroy(&lt);
        pf_scene_destroy(&sc);
    }
}

static void s_test_readers(void)
{
    char dir[] = "/tmp/pf_envmap_XXXXXX";
    PF_CHECK(mkdtemp(dir) != NULL);
    char map[256], rect[256], scene[256], text[2048];
    snprintf(map, sizeof map, "%s/sky.pfm", dir);
    snprintf(rect, sizeof rect, "%s/rect.pfm", dir);
    s_write_map(map, 16, 16, 0.25f);
    s_write_map(rect, 32, 16, 0.5f);
    /* pbrt: the CTM turns the map: Rotate 90 about x sends the map's +z
     * (its centre) to world -y, and its -z (the corner, 10x) to +y */
    snprintf(scene, sizeof scene, "%s/a.pbrt", dir);
    snprintf(text, sizeof text,
             "WorldBegin\nAttributeBegin\nRotate 90 1 0 0\nLightSource \"infinite\" \"string filename\" \"sky.pfm\" "
             "\"float scale\" 2\nAttributeEnd\n%s",
             s_pbrt_body);
    s_write(scene, text);
    pf_error_t err = { { 0 } };
    pf_scene_t *sc = pf_scene_load(scene, &err);
    CHECK(sc != NULL, "pbrt with a map: %s", err.msg);
    if (sc) {
        pf_lights_t *lt = pf_lights_build(sc);
        pf_vec3 down = pf_lights_sky(lt, pf_v3(0, -1, 0));
        pf_vec3 top = pf_lights_sky(lt, pf_norm(pf_v3(0.02f, 1.0f, 0.03f))); /* near, not at, the corner */
        CHECK(sc->nenvmaps == 1 && sc->envmaps[0].width == 16 && fabsf(down.x - 0.5f) < 1e-6f &&
                  fabsf(top.x - 5.0f) < 1e-6f,
              "pbrt map: %zu maps, world -y sees %g (want 0.5), +y %g (want 5)", sc->nenvmaps, down.x, top.x);
        pf_lights_destroy(&lt);
        pf_scene_destroy(&sc);
    }
    /* illuminance E: pbrt-v4 weighs the pixels by 2 pi / (w h), half their
     * solid angle, so the upward irradiance becomes 2 E */
    snprintf(text, sizeof text,
             "WorldBegin\nLightSource \"infinite\" \"string filename\" \"sky.pfm\" \"float illuminance\" 7\n%s",
             s_pbrt_body);
    s_write(scene, text);
    sc = pf_scene_load(scene, &err);
    CHECK(sc != NULL, "pbrt with illuminance: %s", err.msg);
    if (sc) {
        double e = pf_envmap_integral(&sc->envmaps[0], sc->lights[0].intensity, 1);
        CHECK(fabs(e / 14.0 - 1.0) < 1e-4, "illuminance 7 gives an upward irradiance of %g (pbrt-v4: 14)", e);
        pf_scene_destroy(&sc);
    }
    /* a non-square equal-area map: an error naming the map and file:line */
    snprintf(text, sizeof text, "WorldBegin\n\nLightSource \"infinite\" \"string filename\" \"rect.pfm\"\n%s",
             s_pbrt_body);
    s_write(scene, text);
    sc = pf_scene_load(scene, &err);
    char where[300];
    snprintf(where, sizeof where, "%s:3", scene);
    CHECK(sc == NULL && strstr(err.msg, "rect.pfm") && strstr(err.msg, "32x16") && strstr(err.msg, where),
          "non-square map: %s", err.msg);
    pf_scene_destroy(&sc);
    /* a missing map */
    snprintf(text, sizeof text, "WorldBegin\nLightSource \"infinite\" \"string filename\" \"nope.pfm\"\n%s",
             s_pbrt_body);
    s_write(scene, text);
    sc = pf_scene_load(scene, &err);
    snprintf(where, sizeof where, "%s:2", scene);
    CHECK(sc == NULL && strstr(err.msg, "nope.pfm") && strstr(err.msg, where), "missing map: %s", err.msg);
    pf_scene_destroy(&sc);
    /* JSON, equirect with the default up (+y): the top row is world +y */
    snprintf(scene, sizeof scene, "%s/a.json", dir);
    s_write(scene, "{ \"objects\": [ { \"type\": \"quad\", \"origin\": [-1, 0, -1], \"edge1\": [2, 0, 0], "
                   "\"edge2\": [0, 0, 2], \"material\": \"m\" } ],\n  \"materials\": [ { \"name\": \"m\", \"kd\": 0.5 } ],\n"
                   "  \"lights\": [ { \"type\": \"infinite\", \"image\": \"rect.pfm\", \"mapping\": \"equirect\", "
                   "\"scale\": 3 } ] }\n");
    sc = pf_scene_load(scene, &err);
    CHECK(sc != NULL, "JSON with a map: %s", err.msg);
    if (sc) {
        pf_lights_t *lt = pf_lights_build(sc);
        /* the top-left pixel (10x) holds the zenith's first columns */
        pf_vec3 up = pf_lights_sky(lt, pf_norm(pf_v3(1.0f, 1000.0f, 0.001f)));
        pf_vec3 side = pf_lights_sky(lt, pf_v3(1, 0, 0));
        CHECK(sc->envmaps[0].mapping == PF_ENVMAP_EQUIRECT && fabsf(up.x - 15.0f) < 1e-5f &&
                  fabsf(side.x - 1.5f) < 1e-6f,
              "JSON equirect: zenith %g (want 15), side %g (want 1.5)", up.x, side.x);
        pf_lights_destroy(&lt);
        pf_scene_destroy(&sc);
    }
    s_write(scene, "{ \"objects\": [ { \"type\": \"quad\", \"origin\": [-1, 0, -1], \"edge1\": [2, 0, 0], "
                   "\"edge2\": [0, 0, 2], \"material\": \"m\" } ],\n  \"materials\": [ { \"name\": \"m\", \"kd\": 0.5 } ],\n"
                   "  \"lights\": [ { \"type\": \"infinite\", \"image\": \"rect.pfm\" } ] }\n");
    sc = pf_scene_load(scene, &err);
    CHECK(sc == NULL && strstr(err.msg, "rect.pfm") && strstr(err.msg, "square"), "JSON non-square: %s", err.msg);
    pf_scene_destroy(&sc);
    s_test_ldr_skies(dir, scene);
    char cmd[300];
    snprintf(cmd, sizeof cmd, "rm -rf %s", dir);
    if (system(cmd) != 0)
        printf("could not remove %s\n", dir);
}

int main(void)
{
    pf_log_set_level(PF_LOG_WARN);
    s_test_equal_area();
    s_test_pdf(PF_ENVMAP_EQUALAREA);
    s_test_pdf(PF_ENVMAP_EQUIRECT);
    s_test_patch();
    s_test_photons();
    s_test_blob();
    s_test_readers();
    return pf_test_finish();
}
