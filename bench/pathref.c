/* pathref.c: a brute-force path tracer over photonfarm's own scene model,
 * materials, lights and ray tracer, to check the photon mapper on scenes
 * that have no reference rendered elsewhere. It shares the BSDFs (each
 * tested against its pdf and in the furnace on its own) and the light
 * table, and nothing of the photon mapper: no photon maps, density
 * estimates, final gather, first-gather filter, caustic split or the
 * camera path's MIS bookkeeping. Where the photon mapper's image and this
 * one disagree by more than this one's noise, an estimator is wrong.
 * A tool, not a renderer for users: slow, no farm, no time limit.
 *
 *   build/bin/pathref SCENE -o ref.pfm|ref.exr [--size WxH] [--spp N] [--seed N] [--threads N] [--depth N]
 *                     [--pixel-filter F]
 *
 * --depth: pbrt's maxdepth (scattering events) instead of the scene's
 * (0: none, -1: emitted light only, as photonfarm's --path-depth);
 * --pixel-filter: instead of the scene's, as photonfarm's option.
 *
 * The integrator is pbrt-v4's PathIntegrator: at each vertex that is not a
 * delta one, a light sample (pf_lights_sample_direct_at, as the renderer
 * draws them) and a shadow ray to each distant light; a BSDF sample to go
 * on, whose hit on an emitter or escape to the sky counts with the power
 * heuristic's weight against the light sample; the scene's path_max_depth
 * as pbrt's maxdepth (0: none; Russian roulette from the fourth bounce);
 * absorbing media on every segment (pf_hit_transmittance). Delta vertices:
 * mirrors, smooth conductors, glass and thin sheets, a smooth coat's
 * mirror lobe; rough glass too (its sampler draws a microfacet normal per
 * hit with no pdf to weigh by: pure BSDF sampling, unbiased). Camera
 * samples are uniform in the pixel's square convolved with the scene's
 * pixel filter (box and tent, sampled as two independent offsets), through
 * the lens. The output is the mean; the summary line gives the relative
 * standard error of that mean (per pixel, averaged over the image), so one
 * knows how far it has converged. */
#include <math.h>
#include <omp.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "accel/shading.h"
#include "accel/surface.h"
#include "base/rng.h"
#include "base/sampling.h"
#include "bench_setup.h"
#include "image/image.h"
#include "light/light.h"
#include "material/bsdf.h"
#include "material/coated.h"
#include "material/dielectric.h"
#include "material/difftrans.h"
#include "material/ggx.h"
#include "scene/camera.h"

#define S_STREAM 0x70617468u /* "path": numbers of their own */

typedef struct s_ctx {
    const pf_scene_t *scene;
    const pf_accel_t *accel;
    const pf_lights_t *lights;
    int max_depth; /* scattering events; -1 none */
} s_ctx;

static float s_power(float a, float b) { return a * a / (a * a + b * b); }

/* A vertex: the hit, its material resolved, its normals on wo's side. */
typedef struct s_vtx {
    pf_hit_t h;
    pf_material_t m;
    pf_vec3 wo, nf, ns;
} s_vtx;

/* The diffuse part's and the Phong lobe's sampling shares (as photons choose). */
static void s_phong_split(const pf_material_t *m, float *pd, float *ps)
{
    *pd = pf_maxc(m->kd);
    *ps = pf_is_black(m->ks) ? 0.0f : pf_maxc(m->ks);
    float sum = *pd + *ps;
    if (sum > 0.0f) {
        *pd /= sum;
        *ps /= sum;
    }
}

/* Whether m has a part that light sampling can reach (not all delta). */
static int s_smooth_only(const pf_material_t *m)
{
    switch (m->type) {
    case PF_MAT_DIFFUSE:
    case PF_MAT_COATED:
    case PF_MAT_DIFFUSE_TRANSMISSION:
        return 0;
    case PF_MAT_CONDUCTOR:
        return !pf_mat_rough(m);
    default:
        return 1;
    }
}

/* f (no cosine) at v towards wi and the pdf with which s_sample draws wi;
 * zero where wi lies on the wrong side of the geometry. */
static pf_vec3 s_eval(const s_vtx *v, pf_vec3 wi, float *pdf)
{
    *pdf = 0.0f;
    const pf_material_t *m = &v->m;
    float gs = pf_dot(wi, v->nf), ss = pf_dot(wi, v->ns);
    if (m->type == PF_MAT_DIFFUSE_TRANSMISSION) {
        if ((gs > 0.0f) != (ss > 0.0f))
            return pf_v3s(0.0f);
        *pdf = pf_difftrans_pdf(m, v->ns, v->wo, wi);
        return pf_difftrans_eval(m, v->ns, v->wo, wi);
    }
    if (!(gs > 0.0f) || !(ss > 0.0f))
        return pf_v3s(0.0f);
    switch (m->type) {
    case PF_MAT_DIFFUSE: {
        float pd, ps;
        s_phong_split(m, &pd, &ps);
        *pdf = pd * ss * PF_INV_PI + (ps > 0.0f ? ps * pf_phong_pdf_dir(m, v->ns, wi, v->wo) : 0.0f);
        return pf_brdf_eval(m, v->ns, wi, v->wo);
    }
    case PF_MAT_CONDUCTOR:
        if (!pf_mat_rough(m))
            return pf_v3s(0.0f);
        *pdf = pf_conductor_pdf(m, v->ns, v->wo, wi);
        return pf_conductor_eval(m, v->ns, v->wo, wi);
    case PF_MAT_COATED:
        *pdf = pf_coated_pdf(m, v->ns, v->wo, wi);
        return pf_coated_f(m, v->ns, v->wo, wi);
    default:
        return pf_v3s(0.0f);
    }
}

/* A BSDF sample at v: 0 when the path ends, else 1 with *wi, *w = f cos /
 * pdf, *pdf (0: a delta sample, counted without MIS). */
static int s_sample(const s_vtx *v, pf_rng_t *rng, pf_vec3 *wi, pf_vec3 *w, float *pdf)
{
    const pf_material_t *m = &v->m;
    float u0 = pf_rng_float(rng), u1 = pf_rng_float(rng), u2 = pf_rng_float(rng);
    *pdf = 0.0f;
    int ok = 1;
    switch (m->type) {
    case PF_MAT_DIFFUSE: {
        float pd, ps;
        s_phong_split(m, &pd, &ps);
        if (pd + ps <= 0.0f)
            return 0;
        *wi = u0 < pd ? pf_to_world(pf_sample_cosine(u1, u2), v->ns)
                      : pf_to_world(pf_sample_phong(u1, u2, m->ns), pf_reflect(v->wo, v->ns));
        pf_vec3 f = s_eval(v, *wi, pdf);
        if (!(*pdf > 0.0f) || pf_is_black(f))
            return 0;
        *w = pf_scale(f, pf_dot(*wi, v->ns) / *pdf);
        return 1;
    }
    case PF_MAT_MIRROR:
        *wi = pf_reflect(v->wo, v->ns);
        *w = m->ks;
        break;
    case PF_MAT_CONDUCTOR:
        if (!pf_mat_rough(m)) {
            *wi = pf_reflect(v->wo, v->ns);
            *w = pf_fresnel_conductor(pf_dot(v->wo, v->ns), m->eta, m->k);
        } else {
            ok = pf_conductor_sample(m, v->ns, v->wo, u1, u2, wi, w, pdf);
        }
        break;
    case PF_MAT_COATED: {
        int coat;
        ok = pf_coated_sample(m, v->ns, v->wo, u0, u1, u2, wi, w, pdf, &coat);
        break;
    }
    case PF_MAT_DIFFUSE_TRANSMISSION:
        ok = pf_difftrans_sample(m, v->ns, v->wo, u0, u1, u2, wi, w, pdf) &&
             (pf_dot(*wi, v->nf) > 0.0f) == (pf_dot(*wi, v->ns) > 0.0f);
        return ok;
    default: { /* glass and thin sheets, smooth or rough: one branch by Fresnel */
        pf_vec3 d = pf_neg(v->wo);
        pf_dielectric_t g = pf_mat_rough_glass(m) ? pf_dielectric_rough_at(m, d, v->h.ng, v->wo, v->ns, u1, u2)
                                                  : pf_dielectric_at(m, d, v->h.ng, v->wo, v->ns);
        int reflect = pf_rng_float(rng) < g.f || !g.can_refract;
        *wi = reflect ? g.wr : g.wt;
        *w = reflect ? g.kr : g.kt;
        return !pf_is_black(*w);
    }
    }
    return ok && !pf_is_black(*w) && pf_dot(*wi, v->nf) > 0.0f;
}

/* Whether the segment from v along wi to distance dist (INFINITY: out of
 * the scene) is free; stops short of the light point by its rounding. */
static int s_visible(const s_ctx *c, const s_vtx *v, pf_vec3 wi, float dist)
{
    pf_ray_t r = pf_spawn_ray(&v->h, wi);
    if (isinf(dist))
        return !pf_accel_occluded(c->accel, &r, INFINITY);
    pf_vec3 target = pf_madd(v->h.p, wi, dist);
    pf_vec3 d = pf_sub(target, r.o);
    float len = pf_len(d);
    if (!(len > 0.0f))
        return 1;
    r.d = pf_scale(d, 1.0f / len);
    float slack = 0x1p-18f * pf_maxc(pf_vabs(target)) + pf_accel_eps(c->accel) + 1e-4f * len;
    return len <= slack || !pf_accel_occluded(c->accel, &r, len - slack);
}

/* The normal light sampling is told about at v (zero for a sheet that takes
 * light from both sides: directions over the whole sphere). */
static pf_vec3 s_light_normal(const s_vtx *v)
{
    return v->m.type == PF_MAT_DIFFUSE_TRANSMISSION ? pf_v3s(0.0f) : v->ns;
}

/* Direct light at v: one light sample (MIS against the BSDF) and every distant light. */
static pf_vec3 s_direct(const s_ctx *c, const s_vtx *v, pf_rng_t *rng)
{
    pf_vec3 sum = pf_v3s(0.0f);
    float u[3] = { pf_rng_float(rng), pf_rng_float(rng), pf_rng_float(rng) };
    pf_light_conn_t lc;
    if (pf_lights_sample_direct_at(c->lights, c->scene, v->h.p, s_light_normal(v), u, &lc)) {
        float pdf;
        pf_vec3 f = s_eval(v, lc.wi, &pdf);
        if (!pf_is_black(f) && s_visible(c, v, lc.wi, lc.dist)) {
            float w = lc.pdf > 0.0f ? s_power(lc.pdf, pdf) : 1.0f;
            sum = pf_add(sum, pf_scale(pf_mul(f, lc.weight), fabsf(pf_dot(lc.wi, v->ns)) * w));
        }
    }
    for (size_t i = 0; i < pf_lights_distant_count(c->lights); i++) {
        pf_lights_distant(c->lights, c->scene, i, &lc);
        float pdf;
        pf_vec3 f = s_eval(v, lc.wi, &pdf);
        if (!pf_is_black(f) && s_visible(c, v, lc.wi, lc.dist))
            sum = pf_add(sum, pf_scale(pf_mul(f, lc.weight), fabsf(pf_dot(lc.wi, v->ns))));
    }
    return sum;
}

/* The radiance along a camera ray. */
static pf_vec3 s_li(const s_ctx *c, pf_ray_t ray, pf_rng_t *rng)
{
    pf_vec3 L = pf_v3s(0.0f), beta = pf_v3s(1.0f);
    float prev_pdf = 0.0f; /* the last BSDF sample's pdf; 0: delta or the camera */
    s_vtx prev;
    memset(&prev, 0, sizeof prev);
    for (int bounces = 0;; bounces++) {
        s_vtx v;
        if (!pf_accel_intersect(c->accel, &ray, INFINITY, &v.h)) {
            float lp = prev_pdf > 0.0f ? pf_lights_sky_pdf(c->lights, s_light_normal(&prev), ray.d) : 0.0f;
            float w = prev_pdf > 0.0f && lp > 0.0f ? s_power(prev_pdf, lp) : 1.0f;
            return pf_add(L, pf_mul(beta, pf_scale(pf_lights_sky(c->lights, ray.d), w)));
        }
        beta = pf_mul(beta, pf_hit_transmittance(c->scene, &v.h, ray.d));
        const pf_material_t *own = &c->scene->mats[v.h.mat];
        if (!pf_is_black(own->le) && (own->twosided || pf_dot(ray.d, v.h.ng) < 0.0f)) {
            float w = 1.0f;
            if (prev_pdf > 0.0f) {
                float lp = pf_lights_pdf_at(c->lights, c->scene, prev.h.p, s_light_normal(&prev), v.h.geom, v.h.prim,
                                            v.h.p);
                w = lp > 0.0f ? s_power(prev_pdf, lp) : 1.0f;
            }
            L = pf_add(L, pf_mul(beta, pf_scale(own->le, w)));
        }
        if (c->max_depth >= 0 && bounces >= c->max_depth)
            return L;
        v.m = pf_material_at(c->scene, &v.h);
        v.wo = pf_neg(ray.d);
        pf_shade_hit(c->scene, &v.m, &v.h, v.wo);
        v.nf = pf_face_forward(v.h.ng, v.wo);
        v.ns = pf_dot(v.h.ng, v.nf) > 0.0f ? v.h.ns : pf_neg(v.h.ns);
        if (!s_smooth_only(&v.m))
            L = pf_add(L, pf_mul(beta, s_direct(c, &v, rng)));
        pf_vec3 wi, w;
        if (!s_sample(&v, rng, &wi, &w, &prev_pdf))
            return L;
        beta = pf_mul(beta, w);
        if (!pf_is_finite3(beta) || pf_is_black(beta))
            return L;
        if (bounces >= 3) { /* Russian roulette, as pbrt: survive with the throughput's largest channel */
            float q = fmaxf(0.0f, 1.0f - pf_maxc(beta));
            if (pf_rng_float(rng) < q)
                return L;
            beta = pf_scale(beta, 1.0f / (1.0f - q));
        }
        prev = v;
        ray = pf_spawn_ray(&v.h, wi);
    }
}

/* A sample of a tent of radius r (pdf (r - |x|) / r^2). */
static float s_tent(float u, float r)
{
    return u < 0.5f ? r * (sqrtf(2.0f * u) - 1.0f) : r * (1.0f - sqrtf(2.0f - 2.0f * u));
}

static void s_usage(void)
{
    fprintf(stderr, "usage: pathref SCENE -o OUT.pfm|OUT.exr [--size WxH] [--spp N] [--seed N] [--threads N] [--depth N]\n"
                    "       [--pixel-filter box|tent:R|box+tent:R]\n");
    exit(2);
}

int main(int argc, char **argv)
{
    const char *scene_path = NULL, *out = NULL;
    int w = 0, h = 0, spp = 256, threads = 0, depth = -2;
    const char *filter = NULL;
    unsigned long long seed = 1;
    for (int i = 1; i < argc; i++) {
        if (!strcmp(argv[i], "-o") && i + 1 < argc)
            out = argv[++i];
        else if (!strcmp(argv[i], "--size") && i + 1 < argc) {
            if (sscanf(argv[++i], "%dx%d", &w, &h) != 2 || w <= 0 || h <= 0)
                s_usage();
        } else if (!strcmp(argv[i], "--spp") && i + 1 < argc)
            spp = atoi(argv[++i]);
        else if (!strcmp(argv[i], "--seed") && i + 1 < argc)
            seed = strtoull(argv[++i], NULL, 10);
        else if (!strcmp(argv[i], "--threads") && i + 1 < argc)
            threads = atoi(argv[++i]);
        else if (!strcmp(argv[i], "--depth") && i + 1 < argc)
            depth = atoi(argv[++i]);
        else if (!strcmp(argv[i], "--pixel-filter") && i + 1 < argc)
            filter = argv[++i];
        else if (argv[i][0] != '-' && !scene_path)
            scene_path = argv[i];
        else
            s_usage();
    }
    if (!scene_path || !out || spp <= 0)
        s_usage();
    pf_frame_t f = bench_load(scene_path);
    const pf_settings_t *st = &f.scene->settings;
    if (!w) {
        w = st->width;
        h = st->height;
    }
    /* path_max_depth 0: no limit (-1 here: only the roulette ends a path); -1: emitted light only */
    int md = depth >= -1 ? depth : st->path_max_depth;
    s_ctx c = { f.scene, f.accel, f.lights, md == 0 ? -1 : md < 0 ? 0 : md };
    pf_camera_t cam = pf_camera_make(&f.scene->camera, w, h);
    pf_image_t img;
    double *m2 = calloc((size_t)w * (size_t)h, sizeof *m2);
    if (pf_image_alloc(&img, w, h) != PF_OK || !m2) {
        fprintf(stderr, "out of memory\n");
        return 1;
    }
    float box = st->filter_box, tent = st->filter_tent;
    if (filter && pf_pixel_filter_parse(filter, &box, &tent) != PF_OK) {
        fprintf(stderr, "pathref: bad --pixel-filter '%s' (box, tent:R or box+tent:R)\n", filter);
        return 2;
    }
    double t0 = omp_get_wtime();
#pragma omp parallel for schedule(dynamic, 1) num_threads(threads > 0 ? threads : omp_get_max_threads())
    for (int y = 0; y < h; y++) {
        pf_accel_thread_init();
        for (int x = 0; x < w; x++) {
            double sum[3] = { 0, 0, 0 }, sq = 0.0;
            size_t pix = (size_t)y * (size_t)w + (size_t)x;
            for (int s = 0; s < spp; s++) {
                pf_rng_t rng = pf_rng_make(seed, S_STREAM, pix, (uint32_t)s);
                float jx = 0.5f, jy = 0.5f;
                if (box > 0.0f) {
                    jx += box * (pf_rng_float(&rng) - 0.5f);
                    jy += box * (pf_rng_float(&rng) - 0.5f);
                }
                if (tent > 0.0f) {
                    jx += s_tent(pf_rng_float(&rng), tent);
                    jy += s_tent(pf_rng_float(&rng), tent);
                }
                float l1 = pf_rng_float(&rng), l2 = pf_rng_float(&rng);
                pf_vec3 L = s_li(&c, pf_camera_ray_lens(&cam, (float)x + jx, (float)y + jy, l1, l2), &rng);
                if (!pf_is_finite3(L))
                    continue; /* counted as black: a NaN would say nothing of the rest */
                sum[0] += L.x;
                sum[1] += L.y;
                sum[2] += L.z;
                double lum = pf_luminance(L);
                sq += lum * lum;
            }
            for (int k = 0; k < 3; k++)
                img.rgb[3 * pix + (size_t)k] = (float)(sum[k] / spp);
            m2[pix] = sq / spp;
        }
    }
    /* the mean's relative standard error per pixel, averaged (pixels brighter than 1e-4) */
    double rse = 0.0;
    size_t n = 0;
    for (size_t p = 0; p < (size_t)w * (size_t)h; p++) {
        double mean = pf_luminance(pf_v3(img.rgb[3 * p], img.rgb[3 * p + 1], img.rgb[3 * p + 2]));
        if (mean > 1e-4) {
            double var = fmax(0.0, m2[p] - mean * mean) / (spp > 1 ? spp - 1 : 1);
            rse += sqrt(var) / mean;
            n++;
        }
    }
    pf_error_t err;
    if (pf_image_write_hdr(&img, out, 0, &err) != PF_OK) {
        fprintf(stderr, "%s\n", err.msg);
        return 1;
    }
    printf("pathref: %s %dx%d, %d spp, max depth %d: %.1f s, mean relative standard error %.4f; wrote %s\n",
           scene_path, w, h, spp, md, omp_get_wtime() - t0, n ? rse / (double)n : 0.0, out);
    free(m2);
    pf_image_free(&img);
    pf_frame_close(&f);
    return 0;
}
