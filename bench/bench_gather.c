/* bench_gather.c: the final gather's rays per second against Embree alone.
 *
 * Builds a scene's photon maps as a render does (default settings), then
 * makes the gather rays the integrator would trace: one camera ray through
 * each pixel centre of a W x W image, and at each diffuse hit `gather`
 * cosine-distributed rays from the offset hit point. It times, on one thread,
 * (a) Embree alone: pf_accel_intersect on every ray; (b) the gather as the
 * renderer does it: pf_render_gather_rays (intersection, mirror/glass
 * following, the irradiance lookup: the hit's irradiance texel, irrtex.h,
 * or the direct lookup with its support and visibility checks), the texel
 * reads put off while the next rays are traced as the first-gather records
 * do; and (b) again with each read made at once. Prints the rates and
 * ratios (the goal: (b) >= 50 % of (a)), the texels'
 * figures, and the direct lookup's steps timed one at a time: the
 * intersection, the nearest-point search, the leak-test visibility ray
 * (where the point is not flat; photonmap.h), with the share of lookups that
 * trace it; and the search alone, in ray order, with its data in cache and
 * shuffled. The renderer's loop runs three times and the best counts: its
 * texels are filled in the first (what a render's later samples find).
 *
 * usage: bench_gather [scene.json] [W] [gather] */
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "base/rng.h"
#include "bench/bench_setup.h"
#include "material/bsdf.h"
#include "photon/irrtex.h"
#include "render/render.h"

/* The figures this bench prints, filled in step by step. sink adds up what
 * the timed loops compute, so that none of it is optimized away; its total,
 * in the order the steps run, is printed as the checksum. */
typedef struct s_figures {
    size_t n;                      /* gather rays */
    double sink;
    double best_steps[3];          /* intersection; + irradiance lookup; + leak-test ray */
    size_t lookups, traced, flat;  /* lookups within a support, of them traced; flat points */
    size_t nl;                     /* diffuse hits of the gather rays */
    double best_l[3];              /* the lookup alone: ray order, in cache, shuffled */
    double best_a, best_b, best_c; /* Embree alone; the renderer's gather; each read at once */
} s_figures_t;

/* The gather rays: one camera ray through each pixel centre of a w x w
 * image, and at each diffuse hit `gather` cosine-distributed rays. Returns
 * the malloc'd rays and their count in *n_out. */
static pf_ray_t *s_gather_rays(const pf_render_ctx_t *ctx, const pf_scene_t *scene, const pf_accel_t *accel, int w,
                               int gather, size_t *n_out)
{
    size_t cap = (size_t)w * (size_t)w * (size_t)gather, n = 0;
    pf_ray_t *rays = malloc(cap * sizeof *rays);
    pf_rng_t rng = pf_rng_make(7, PF_STREAM_TEST, 0, 0);
    for (int y = 0; y < w; y++)
        for (int x = 0; x < w; x++) {
            pf_ray_t cam = pf_camera_ray(&ctx->camera, (float)x + 0.5f, (float)y + 0.5f);
            pf_hit_t h;
            if (!pf_accel_intersect(accel, &cam, INFINITY, &h) || scene->mats[h.mat].type != PF_MAT_DIFFUSE)
                continue;
            pf_vec3 wo = pf_neg(cam.d), nf = pf_face_forward(h.ng, wo);
            pf_vec3 ns = pf_dot(h.ng, nf) > 0.0f ? h.ns : pf_neg(h.ns);
            for (int g = 0; g < gather; g++) {
                pf_vec3 wi = pf_to_world(pf_sample_cosine(pf_rng_float(&rng), pf_rng_float(&rng)), ns);
                if (pf_dot(wi, nf) > 0.0f)
                    rays[n++] = pf_spawn_ray(&h, wi);
            }
        }
    *n_out = n;
    return rays;
}

static void s_time_steps(const pf_scene_t *scene, const pf_accel_t *accel, const pf_photon_maps_t *maps,
                         const pf_ray_t *rays, s_figures_t *f)
{
    size_t n = f->n;
    /* Where a gather ray's time goes, the renderer's steps one at a time on
     * the same rays: the intersection; + the irradiance lookup at a diffuse
     * hit (nearest point with an agreeing normal); + the leak test's
     * visibility ray (as s_irradiance makes it). The renderer's own gather
     * adds to these the mirror and glass paths it follows and the shading. */
    double sink = f->sink;
    double best_steps[3] = { 1e30, 1e30, 1e30 };
    size_t lookups = 0, traced = 0, flat = 0;
    for (size_t i = 0; i < pf_kdtree_size(maps->irradiance); i++)
        flat += pf_irradiance_flat(&pf_kdtree_photons(maps->irradiance)[i]);
    const pf_kdtree_t *irr = maps->irradiance;
    for (int rep = 0; rep < 3; rep++) {
        for (int step = 0; step < 3; step++) {
            double ta = pf_now();
            for (size_t i = 0; i < n; i++) {
                pf_hit_t h;
                if (!pf_accel_intersect(accel, &rays[i], INFINITY, &h))
                    continue;
                sink += h.t;
                if (step == 0 || scene->mats[h.mat].type != PF_MAT_DIFFUSE)
                    continue;
                pf_vec3 nf = pf_face_forward(h.ng, pf_neg(rays[i].d));
                pf_knn_t nn;
                if (!pf_kdtree_nearest_normal(irr, h.p, nf, PF_NORMAL_AGREE, maps->irradiance_r2, &nn))
                    continue;
                sink += nn.d2;
                if (step == 1)
                    continue;
                const pf_photon_t *q = &pf_kdtree_photons(irr)[nn.index];
                float d = sqrtf(nn.d2), len;
                pf_ray_t ray;
                if (rep == 0 && step == 2) {
                    lookups += nn.d2 <= pf_irradiance_radius(q) * pf_irradiance_radius(q);
                    traced += pf_irradiance_leak_test(q, d, pf_accel_eps(accel));
                }
                if (pf_irradiance_leak_test(q, d, pf_accel_eps(accel)) && pf_irradiance_leak_ray(h.p, nf, q, d, &ray, &len))
                    sink += pf_accel_occluded(accel, &ray, len);
            }
            double dt = pf_now() - ta;
            best_steps[step] = dt < best_steps[step] ? dt : best_steps[step];
        }
    }
    f->sink = sink;
    memcpy(f->best_steps, best_steps, sizeof best_steps);
    f->lookups = lookups;
    f->traced = traced;
    f->flat = flat;
}

/* The irradiance lookup alone, best of 3. */
static void s_time_lookup(const pf_scene_t *scene, const pf_accel_t *accel, const pf_photon_maps_t *maps,
                          const pf_ray_t *rays, s_figures_t *f)
{
    size_t n = f->n;
    const pf_kdtree_t *irr = maps->irradiance;
    double sink = f->sink;
    /* The lookup alone, at the diffuse hits of the same rays: in ray
     * order; with every query made 8 times in a row (its data in cache: what
     * the lookup costs without waiting on memory); and in shuffled order
     * (gather rays of different pixels, as the records pass makes them). */
    pf_vec3 *xs = malloc(n * sizeof *xs), *nfs = malloc(n * sizeof *nfs);
    size_t nl = 0;
    for (size_t i = 0; i < n; i++) {
        pf_hit_t h;
        if (pf_accel_intersect(accel, &rays[i], INFINITY, &h) && scene->mats[h.mat].type == PF_MAT_DIFFUSE) {
            xs[nl] = h.p;
            nfs[nl++] = pf_face_forward(h.ng, pf_neg(rays[i].d));
        }
    }
    double best_l[3] = { 1e30, 1e30, 1e30 };
    for (int rep = 0; rep < 3; rep++)
        for (int mode = 0; mode < 3; mode++) {
            pf_rng_t order = pf_rng_make(9, PF_STREAM_TEST, 1, 0);
            double ta = pf_now();
            for (size_t i = 0; i < nl; i++) {
                size_t j = mode == 1 ? i / 8 * 8 : mode == 2 ? pf_rng_u32(&order) % nl : i;
                pf_knn_t nn;
                if (pf_kdtree_nearest_normal(irr, xs[j], nfs[j], PF_NORMAL_AGREE, maps->irradiance_r2, &nn))
                    sink += nn.d2;
            }
            double dt = pf_now() - ta;
            best_l[mode] = dt < best_l[mode] ? dt : best_l[mode];
        }
    free(xs);
    free(nfs);
    f->sink = sink;
    memcpy(f->best_l, best_l, sizeof best_l);
    f->nl = nl;
}

/* Embree alone against the renderer's gather, and the gather with each
 * texel read at once; best of 3. */
static void s_time_gather(pf_render_ctx_t *ctx, const pf_accel_t *accel, const pf_ray_t *rays, s_figures_t *f)
{
    size_t n = f->n;
    double sink = f->sink;
    double best_a = 1e30, best_b = 1e30, best_c = 1e30;
    for (int rep = 0; rep < 3; rep++) {
        double t0 = pf_now();
        for (size_t i = 0; i < n; i++) {
            pf_hit_t h;
            sink += pf_accel_intersect(accel, &rays[i], INFINITY, &h) ? h.t : 0.0f;
        }
        double t1 = pf_now();
        sink += pf_render_gather_rays(ctx, rays, n, 0).x;
        double t2 = pf_now();
        ctx->reads_at_once = 1;
        sink += pf_render_gather_rays(ctx, rays, n, 0).x;
        ctx->reads_at_once = 0;
        double t3 = pf_now();
        best_a = t1 - t0 < best_a ? t1 - t0 : best_a;
        best_b = t2 - t1 < best_b ? t2 - t1 : best_b;
        best_c = t3 - t2 < best_c ? t3 - t2 : best_c;
    }
    f->sink = sink;
    f->best_a = best_a;
    f->best_b = best_b;
    f->best_c = best_c;
}

/* The figures, as the steps left them in f. */
static void s_print(const char *path, int w, int gather, const pf_photon_stats_t *st, const pf_frame_t *b,
                    const s_figures_t *f)
{
    const size_t n = f->n, nl = f->nl, lookups = f->lookups, traced = f->traced, flat = f->flat;
    const double *best_steps = f->best_steps, *best_l = f->best_l;
    const double best_a = f->best_a, best_b = f->best_b, best_c = f->best_c, sink = f->sink;
    const pf_photon_maps_t *maps = &b->maps;
    printf("scene %s, %zu gather rays (%dx%d pixel centres, %d per diffuse hit), %llu global photons, "
           "%llu irradiance points; one thread, best of 3\n",
           path, n, w, w, gather, (unsigned long long)st->global_stored, (unsigned long long)st->irradiance_points);
    printf("embree alone       %8.2f Mrays/s\n", (double)n / best_a / 1e6);
    printf("gather (renderer)  %8.2f Mrays/s\n", (double)n / best_b / 1e6);
    printf("ratio              %8.1f %%   (checksum %g)\n", 100.0 * best_a / best_b, sink);
    printf("gather, each texel read at once (not put off while the next rays are traced): %.2f Mrays/s, %.1f %%\n",
           (double)n / best_c / 1e6, 100.0 * best_a / best_c);
    printf("per gather ray: intersection %.0f ns, + irradiance lookup %.0f ns, + leak-test ray %.0f ns; "
           "the renderer's whole gather ray %.0f ns\n",
           best_steps[0] / (double)n * 1e9, (best_steps[1] - best_steps[0]) / (double)n * 1e9,
           (best_steps[2] - best_steps[1]) / (double)n * 1e9, best_b / (double)n * 1e9);
    printf("irradiance lookup alone (%zu diffuse hits): in ray order %.0f ns, each query 8 times (in cache) %.0f ns, "
           "shuffled %.0f ns\n",
           nl, best_l[0] / (double)nl * 1e9, best_l[1] / (double)nl * 1e9, best_l[2] / (double)nl * 1e9);
    printf("irradiance points flat (no leak-test ray): %.1f %%; lookups within a support %zu, of which %.1f %% "
           "traced the leak-test ray\n",
           100.0 * (double)flat / (double)pf_kdtree_size(maps->irradiance), lookups,
           lookups ? 100.0 * (double)traced / (double)lookups : 0.0);
    if (b->texels) {
        size_t direct, filled = pf_irrtex_filled(b->texels, &direct);
        printf("irradiance texels: side %.4g, %zu allocated, %zu filled (%.1f MB), of which %.1f %% look up "
               "directly\n",
               (double)pf_irrtex_side(b->texels), pf_irrtex_count(b->texels), filled, 8.0 * (double)filled / 1e6,
               filled ? 100.0 * (double)direct / (double)filled : 0.0);
    }
}

int main(int argc, char **argv)
{
    const char *path = argc > 1 ? argv[1] : "scenes/cornell-spheres/scene.json";
    int w = argc > 2 ? atoi(argv[2]) : 128, gather = argc > 3 ? atoi(argv[3]) : 16;
    pf_frame_t b = bench_load(path);
    const pf_scene_t *scene = b.scene;
    const pf_accel_t *accel = b.accel;
    pf_settings_t s = scene->settings;
    s.width = s.height = w;
    pf_photon_stats_t st;
    bench_photon_pass(&b, &s, &st);
    pf_frame_ready(&b);
    const pf_photon_maps_t *maps = &b.maps;
    pf_accel_thread_init();
    pf_render_ctx_t ctx;
    pf_render_ctx_init(&ctx, &b, &s);

    s_figures_t f = { 0 };
    pf_ray_t *rays = s_gather_rays(&ctx, scene, accel, w, gather, &f.n);
    s_time_steps(scene, accel, maps, rays, &f);
    s_time_lookup(scene, accel, maps, rays, &f);
    s_time_gather(&ctx, accel, rays, &f);
    s_print(path, w, gather, &st, &b, &f);
    free(rays);
    pf_frame_close(&b);
    return 0;
}
