/* photon_trace.c: the coordinator's photon pass (Jensen 2001, ch. 5-7).
 *
 * Global photons: emitted by power from all lights, traced with Russian
 * roulette by reflectance (the surviving photon's power is divided by the
 * survival probability, so expected power is conserved), stored at every hit
 * on a non-specular surface, the first included (the photon is stored before
 * roulette decides, so no power is lost at the first diffuse hit).
 * Conductors reflect photons by sampling their BSDF (a smooth one as a
 * mirror tinted by its Fresnel), with Russian roulette on the sampled weight
 * f cos / pdf; no photon is stored there, and for the caustic map they count
 * as specular (caustic paths are L (S|C)+ D, C a conductor, rough or not).
 * Coated surfaces store photons and scatter them by their BSDF; for the
 * caustic map the base is diffuse and the coat C (a caustic photon goes on
 * off the coat lobe alone); rough glass splits about a sampled microfacet
 * normal (specular for the caustic map, as rough conductors).
 * Caustic photons: a separate emission aimed at the bounding spheres of the
 * mirror, glass, conductor and coated geometry (pf_lights_emit_targeted: the flux divides by the
 * cone-mixture pdf, so the estimate stays unbiased while no photon is spent
 * on directions that cannot reach a specular surface); only paths L S+ D are
 * stored, at the first non-specular hit, after which the photon ends. With no
 * specular surface there is no caustic map. Power of every stored
 * photon is the emitted flux divided by the number emitted in its map.
 *
 * Determinism: photons are traced in blocks of PF_PHOTON_BLOCK consecutive
 * indices; photon i draws only from stream (seed, i); each block fills its own
 * buffer and the buffers are joined in block order, so the stored sequence is
 * the same for any thread count and schedule. Threads: OpenMP inside
 * pf_photon_pass; each thread sets FTZ/DAZ. */
#include "photon/trace.h"

#include <inttypes.h>
#include <omp.h>
#include <stdlib.h>
#include <string.h>

#include "accel/shading.h"
#include "accel/surface.h"
#include "base/log.h"
#include "base/reserve.h"
#include "base/rng.h"
#include "material/bsdf.h"
#include "material/coated.h"
#include "material/dielectric.h"
#include "material/difftrans.h"
#include "material/ggx.h"
#include "photon/irradiance.h"

static volatile int *s_cancel;

void pf_photon_set_cancel(volatile int *flag) { s_cancel = flag; }

static int s_cancelled(void) { return s_cancel && *s_cancel; }

typedef struct s_buf {
    pf_photon_t *p;
    size_t n, cap;
    uint64_t indirect; /* photons stored after a non-specular bounce */
    uint64_t rejected; /* photons dropped for bad power (batches only) */
} s_buf;

/* The first growth makes room for 1024 photons rather than pf_reserve's 16,
 * which saves six reallocations in every block that stores that many. */
static int s_push(s_buf *b, const pf_photon_t *ph)
{
    if (pf_reserve((void **)&b->p, &b->cap, b->cap ? b->n + 1 : 1024, sizeof *b->p))
        return PF_ENOMEM;
    b->p[b->n++] = *ph;
    return PF_OK;
}

typedef struct s_ctx {
    const pf_scene_t *scene;
    const pf_accel_t *accel;
    const pf_lights_t *lights;
    int max_depth;
    const pf_target_t *targets; /* specular bounding spheres caustic photons aim at */
    size_t ntargets;
} s_ctx;

/* A photon off a conductor: sampled (or mirrored, when smooth), then
 * Russian roulette on the weight f cos / pdf. 0 when it ends here. */
static int s_conductor(const pf_material_t *m, pf_vec3 nf, pf_vec3 ns, pf_vec3 wi, float u0, float u1, float u2,
                       pf_vec3 *wo, pf_vec3 *power)
{
    pf_vec3 w;
    if (!pf_conductor_scatter(m, ns, wi, u1, u2, wo, &w) || pf_dot(*wo, nf) <= 0.0f)
        return 0;
    float p = fminf(1.0f, pf_maxc(w));
    if (!(p > 0.0f) || u0 >= p)
        return 0;
    *power = pf_mul(*power, pf_scale(w, 1.0f / p));
    return 1;
}

/* A global photon off a coated surface (stored there as at a diffuse one):
 * its BSDF sampled (coat lobe or base, material/coated.h), then Russian
 * roulette on the weight f cos / pdf. 0 when the photon ends here. */
static int s_coated(const pf_material_t *m, pf_vec3 nf, pf_vec3 ns, pf_vec3 wi, float u0, float u1, float u2,
                    float u3, pf_vec3 *wo, pf_vec3 *power)
{
    pf_vec3 w;
    float pdf;
    int lobe;
    if (!pf_coated_sample(m, ns, wi, u0, u1, u2, wo, &w, &pdf, &lobe) || pf_dot(*wo, nf) <= 0.0f)
        return 0;
    float p = fminf(1.0f, pf_maxc(w));
    if (!(p > 0.0f) || u3 >= p)
        return 0;
    *power = pf_mul(*power, pf_scale(w, 1.0f / p));
    return 1;
}

/* A caustic photon off a coated surface's coat (C for the caustic map:
 * the camera's gather rays follow the coat as they follow a conductor,
 * render.c), the base's share left to the global map: the coat lobe
 * sampled alone, Russian roulette on its weight. 0 when the photon ends. */
static int s_coat_only(const pf_material_t *m, pf_vec3 nf, pf_vec3 ns, pf_vec3 wi, float u1, float u2, float u3,
                       pf_vec3 *wo, pf_vec3 *power)
{
    float w, pdf;
    if (!pf_coated_sample_coat(m, ns, wi, u1, u2, wo, &w, &pdf) || pf_dot(*wo, nf) <= 0.0f)
        return 0;
    float p = fminf(1.0f, w);
    if (!(p > 0.0f) || u3 >= p)
        return 0;
    *power = pf_scale(*power, w / p);
    return 1;
}

/* A photon off a diffuse transmitter (stored there as at a diffuse
 * surface, on the side it came from): reflected or transmitted as
 * material/difftrans.h samples it, then Russian roulette on the weight.
 * 0 when the photon ends here, or when the shading normal would send it
 * to the other side of the geometry than the side it chose. */
static int s_difftrans(const pf_material_t *m, pf_vec3 nf, pf_vec3 ns, pf_vec3 wi, float u0, float u1, float u2,
                       float u3, pf_vec3 *wo, pf_vec3 *power)
{
    pf_vec3 w;
    float pdf;
    if (!pf_difftrans_sample(m, ns, wi, u0, u1, u2, wo, &w, &pdf) ||
        (pf_dot(*wo, nf) > 0.0f) != (pf_dot(*wo, ns) > 0.0f))
        return 0;
    float p = fminf(1.0f, pf_maxc(w));
    if (!(p > 0.0f) || u3 >= p)
        return 0;
    *power = pf_mul(*power, pf_scale(w, 1.0f / p));
    return 1;
}

/* Traces photon `index` of the map (caustic or global) into buf. Returns the
 * number of photons rejected for bad power (0 or 1), or PF_ENOMEM. */
static int s_trace(const s_ctx *c, uint64_t seed, uint64_t index, uint64_t emitted, int caustic, s_buf *buf)
{
    pf_rng_t rng = pf_rng_make(seed, caustic ? PF_STREAM_CAUSTIC_PHOTON : PF_STREAM_GLOBAL_PHOTON, index, 0);
    float u[6];
    for (int i = 0; i < 6; i++)
        u[i] = pf_rng_float(&rng);
    pf_emission_t em;
    if (caustic ? !pf_lights_emit_targeted(c->lights, c->scene, c->targets, c->ntargets, u, &em)
                : !pf_lights_emit(c->lights, c->scene, u, &em))
        return 0;
    pf_vec3 power = pf_scale(em.flux, (float)(1.0 / (double)emitted));
    /* A light whose flux overflows a float would store infinite photons. */
    if (!pf_is_finite3(power) || power.x < 0.0f || power.y < 0.0f || power.z < 0.0f)
        return 1;
    pf_ray_t ray = em.ray;
    if (!pf_is_black(em.n))
        ray.o = pf_offset_origin(ray.o, pf_vmax(em.perr, pf_v3s(pf_accel_eps(c->accel))), em.n, ray.d);
    int specular_only = 1;
    for (int bounce = 0; bounce < c->max_depth; bounce++) {
        pf_hit_t hit;
        if (!pf_accel_intersect(c->accel, &ray, INFINITY, &hit))
            return 0;
        power = pf_mul(power, pf_hit_transmittance(c->scene, &hit, ray.d)); /* the medium it crossed */
        if (pf_is_black(power))
            return 0;
        pf_material_t mt = pf_material_at(c->scene, &hit);
        const pf_material_t *m = &mt;
        pf_shade_hit(c->scene, m, &hit, pf_neg(ray.d));
        pf_vec3 wi = pf_neg(ray.d); /* towards where the photon came from */
        pf_vec3 nf = pf_face_forward(hit.ng, wi);
        pf_vec3 ns = pf_dot(hit.ng, nf) > 0.0f ? hit.ns : pf_neg(hit.ns);
        pf_vec3 wo;
        float u0 = pf_rng_float(&rng), u1 = pf_rng_float(&rng), u2 = pf_rng_float(&rng);
        if (m->type == PF_MAT_DIFFUSE || m->type == PF_MAT_COATED || pf_mat_difftrans(m)) {
            if (!pf_mat_nonspecular(m))
                return 0;
            if (!caustic || (bounce > 0 && specular_only)) {
                pf_photon_t ph = { { hit.p.x, hit.p.y, hit.p.z }, { power.x, power.y, power.z },
                                   pf_photon_dir_code(ray.d, bounce), pf_oct_encode(nf) };
                if (s_push(buf, &ph))
                    return PF_ENOMEM;
                buf->indirect += !specular_only;
            }
            if (caustic && !(m->type == PF_MAT_COATED && s_coat_only(m, nf, ns, wi, u1, u2, u0, &wo, &power)))
                return 0;
            if (caustic) { /* off the coat: still L (S|C)+ */
                ray = pf_spawn_ray(&hit, wo);
                continue;
            }
            float pd = pf_maxc(m->kd), ps = pf_maxc(m->ks), sum = pd + ps;
            if (sum > 1.0f) {
                pd /= sum;
                ps /= sum;
            }
            if (pf_mat_difftrans(m)) {
                if (!s_difftrans(m, nf, ns, wi, u0, u1, u2, pf_rng_float(&rng), &wo, &power))
                    return 0;
            } else if (m->type == PF_MAT_COATED) {
                if (!s_coated(m, nf, ns, wi, u0, u1, u2, pf_rng_float(&rng), &wo, &power))
                    return 0;
            } else if (u0 < pd) {
                wo = pf_to_world(pf_sample_cosine(u1, u2), ns);
                power = pf_mul(power, pf_scale(m->kd, 1.0f / pd));
            } else if (u0 < pd + ps) {
                pf_vec3 r = pf_reflect(wi, ns);
                wo = pf_to_world(pf_sample_phong(u1, u2, m->ns), r);
                float cos_o = pf_dot(wo, ns);
                if (cos_o <= 0.0f)
                    return 0;
                /* f cos / pdf for the normalized Phong lobe sampled by its own shape. */
                power = pf_mul(power, pf_scale(m->ks, (m->ns + 2.0f) / (m->ns + 1.0f) * cos_o / ps));
            } else {
                return 0; /* absorbed */
            }
            if (pf_dot(wo, nf) <= 0.0f && !pf_mat_difftrans(m))
                return 0; /* the shading normal sent it below the surface */
            specular_only = 0;
        } else if (m->type == PF_MAT_MIRROR) {
            float p = pf_maxc(m->ks);
            if (!(p > 0.0f) || u0 >= p)
                return 0;
            power = pf_mul(power, pf_scale(m->ks, 1.0f / p));
            wo = pf_reflect(wi, ns);
        } else if (m->type == PF_MAT_CONDUCTOR) {
            if (!s_conductor(m, nf, ns, wi, u0, u1, u2, &wo, &power))
                return 0;
        } else {
            /* Glass, solid or thin: reflected with probability f (Fresnel R,
             * or a thin sheet's R'), else transmitted; power is conserved
             * across the interface, so kt is not scaled by the indices. */
            pf_dielectric_t g = pf_mat_rough_glass(m) ? pf_dielectric_rough_at(m, ray.d, hit.ng, wi, ns, u1, u2)
                                                      : pf_dielectric_at(m, ray.d, hit.ng, wi, ns);
            int reflect = u0 < g.f || !g.can_refract;
            wo = reflect ? g.wr : g.wt;
            power = pf_mul(power, reflect ? g.kr : pf_scale(m->kt, g.gt));
        }
        if (!pf_is_finite3(power) || power.x < 0.0f || power.y < 0.0f || power.z < 0.0f)
            return 1;
        if (pf_is_black(power))
            return 0;
        ray = pf_spawn_ray(&hit, wo);
    }
    return 0;
}

/* Traces photons [0, emitted) of one map in parallel blocks and joins them in
 * block order. *out receives a malloc'd array of *count photons. */
static int s_trace_map(const s_ctx *c, uint64_t seed, uint64_t emitted, int caustic, int threads,
                       pf_photon_t **out, size_t *count, uint64_t *rejected, uint64_t *indirect)
{
    *out = NULL;
    *count = 0;
    size_t nblocks = (size_t)((emitted + PF_PHOTON_BLOCK - 1) / PF_PHOTON_BLOCK);
    s_buf *bufs = calloc(nblocks ? nblocks : 1, sizeof *bufs);
    if (!bufs)
        return PF_ENOMEM;
    int failed = 0;
    uint64_t bad = 0;
#pragma omp parallel num_threads(threads) reduction(+ : bad)
    {
        pf_accel_thread_init();
#pragma omp for schedule(dynamic, 1)
        for (size_t b = 0; b < nblocks; b++) {
            if (s_cancelled()) {
#pragma omp atomic write
                failed = PF_EINTERRUPTED;
                continue;
            }
            uint64_t lo = (uint64_t)b * PF_PHOTON_BLOCK;
            uint64_t hi = lo + PF_PHOTON_BLOCK < emitted ? lo + PF_PHOTON_BLOCK : emitted;
            for (uint64_t i = lo; i < hi; i++) {
                int r = s_trace(c, seed, i, emitted, caustic, &bufs[b]);
                if (r < 0) {
#pragma omp atomic write
                    failed = PF_ENOMEM;
                    break;
                }
                bad += (uint64_t)r;
            }
        }
    }
    size_t total = 0;
    for (size_t b = 0; b < nblocks; b++) {
        total += bufs[b].n;
        *indirect += bufs[b].indirect;
    }
    pf_photon_t *all = failed ? NULL : malloc((total ? total : 1) * sizeof *all);
    if (all) {
        size_t k = 0;
        for (size_t b = 0; b < nblocks; b++) {
            if (bufs[b].n)
                memcpy(all + k, bufs[b].p, bufs[b].n * sizeof *all);
            k += bufs[b].n;
        }
    }
    for (size_t b = 0; b < nblocks; b++)
        free(bufs[b].p);
    free(bufs);
    if (!all)
        return failed ? failed : PF_ENOMEM;
    *out = all;
    *count = total;
    *rejected += bad;
    return PF_OK;
}

/* The caustic photons a scene gets (none without specular surfaces, where
 * the caustic map is skipped) and the specular targets they aim at. */
static int s_setup(const pf_scene_t *scene, const pf_settings_t *settings, pf_target_t **targets,
                   uint64_t *caustic_photons, int quiet)
{
    int nt = pf_specular_targets(scene, targets);
    if (nt < 0)
        return nt;
    *caustic_photons = nt > 0 ? settings->caustic_photons : 0;
    if (nt == 0 && settings->caustic_photons && !quiet)
        pf_info("caustic map skipped: no mirror, glass or conductor surfaces");
    return nt;
}

unsigned pf_deep_bounce_limit(const pf_settings_t *settings)
{
    int d = settings->path_max_depth;
    return d >= 3 ? pf_pm_bounce_limit(d, d - 3) : 0;
}

int pf_photon_deep_irradiance(pf_photon_maps_t *maps, const pf_accel_t *accel, const pf_settings_t *settings,
                              int threads)
{
    pf_kdtree_destroy(&maps->irradiance_deep);
    if (settings->path_max_depth < 3 || !maps->global || !maps->irradiance || pf_kdtree_size(maps->irradiance) == 0)
        return PF_OK;
    if (threads <= 0)
        threads = omp_get_num_procs();
    size_t stride = pf_irradiance_points_stride(pf_kdtree_size(maps->global), settings);
    unsigned limit = pf_deep_bounce_limit(settings);
    /* limit 0 here: D - 3 >= the bounce cap, every photon counts, as in irradiance */
    return pf_irradiance_precompute_limited(maps->global, (int)stride, settings->global_k, maps->global_r2,
                                            pf_pass_shrink2(settings->pass), limit, accel, threads,
                                            &maps->irradiance_deep);
}

void pf_photon_irr_plan(const pf_photon_maps_t *maps, const pf_settings_t *settings, pf_irr_plan_t *out)
{
    size_t gn = maps->global ? pf_kdtree_size(maps->global) : 0;
    int stride = (int)pf_irradiance_points_stride(gn, settings);
    float shrink2 = pf_pass_shrink2(settings->pass);
    out->main = (pf_irr_params_t){ stride, settings->global_k, maps->global_r2, shrink2,
                                   pf_gather_bounce_limit(settings) };
    out->deep = (pf_irr_params_t){ stride, settings->global_k, maps->global_r2, shrink2,
                                   pf_deep_bounce_limit(settings) };
    out->points = pf_irradiance_count(gn, stride);
    /* as pf_photon_deep_irradiance: under a limit of 3 or more, when there are points */
    out->has_deep = settings->path_max_depth >= 3 && out->points > 0;
}

/* The irradiance maps (and the deep one) from points that spread->points
 * computes: the same trees as pf_irradiance_precompute_limited's and
 * pf_photon_deep_irradiance's, since the points are the same records. */
static int s_irr_spread(pf_photon_maps_t *maps, const pf_settings_t *settings, const pf_irr_spread_t *spread)
{
    pf_irr_plan_t plan;
    pf_photon_irr_plan(maps, settings, &plan);
    size_t m = plan.points ? plan.points : 1;
    pf_photon_t *pts = malloc(m * sizeof *pts), *deep = plan.has_deep ? malloc(m * sizeof *deep) : NULL;
    int rc = pts && (deep || !plan.has_deep) ? spread->points(spread->ctx, maps, &plan, pts, deep) : PF_ENOMEM;
    if (rc == PF_OK) {
        maps->irradiance = pf_kdtree_build(&pts, plan.points);
        rc = maps->irradiance ? PF_OK : PF_ENOMEM;
    }
    if (rc == PF_OK && plan.has_deep) {
        maps->irradiance_deep = pf_kdtree_build(&deep, plan.points);
        rc = maps->irradiance_deep ? PF_OK : PF_ENOMEM;
    }
    free(pts);
    free(deep);
    return rc;
}

static int s_build(const pf_scene_t *scene, const pf_accel_t *accel, const pf_settings_t *settings,
                   uint64_t caustic_emitted, pf_photon_t **gp_p, size_t gn, pf_photon_t **cp_p, size_t cn,
                   pf_photon_maps_t *maps, pf_photon_stats_t *stats, const pf_irr_spread_t *spread)
{
    int threads = settings->threads > 0 ? settings->threads : omp_get_num_procs();
    pf_photon_t *gp = *gp_p, *cp = *cp_p;
    *gp_p = *cp_p = NULL;
    memset(maps, 0, sizeof *maps);
    pf_vec3 lo, hi;
    pf_scene_bounds(scene, &lo, &hi);
    float diag = pf_len(pf_sub(hi, lo));
    if (!(diag > 0.0f) || !isfinite(diag))
        diag = 1.0f;
    float gr = settings->global_radius > 0.0f ? settings->global_radius : 0.1f * diag;
    float cr = settings->caustic_radius > 0.0f ? settings->caustic_radius : 0.01f * diag;
    maps->global_r2 = gr * gr;
    maps->caustic_r2 = cr * cr;
    maps->irradiance_r2 = gr * gr;
    maps->global_emitted = settings->photons;
    maps->caustic_emitted = caustic_emitted;
    if (s_cancelled()) {
        free(gp);
        free(cp);
        return PF_EINTERRUPTED;
    }
    double t1 = pf_now();
    stats->global_stored = gn;
    stats->caustic_stored = cn;
    maps->global = pf_kdtree_build(&gp, gn);
    maps->caustic = pf_kdtree_build(&cp, cn);
    double t2 = pf_now();
    stats->build_s = t2 - t1;
    if (!maps->global || !maps->caustic) {
        pf_photon_maps_free(maps);
        return PF_ENOMEM;
    }
    /* No photon reached a non-specular surface after leaving another: no
     * diffuse point sees a lit one, the final gather would find nothing, and
     * the irradiance it reads need not be computed (pf_photon_skip_gather). */
    stats->gather_skipped = settings->photons > 0 && gn > 0 && stats->indirect_stored == 0;
    int rc;
    if (s_cancelled()) {
        rc = PF_EINTERRUPTED;
    } else if (stats->gather_skipped) {
        pf_photon_t *none = malloc(sizeof *none); /* an empty tree still owns an array */
        maps->irradiance = none ? pf_kdtree_build(&none, 0) : NULL;
        rc = maps->irradiance ? PF_OK : PF_ENOMEM;
    } else if (spread) {
        rc = s_irr_spread(maps, settings, spread);
    } else {
        size_t stride = pf_irradiance_points_stride(gn, settings);
        rc = pf_irradiance_precompute_limited(maps->global, (int)stride, settings->global_k, maps->global_r2,
                                              pf_pass_shrink2(settings->pass), pf_gather_bounce_limit(settings), accel,
                                              threads, &maps->irradiance);
        if (rc == PF_OK)
            rc = pf_photon_deep_irradiance(maps, accel, settings, threads);
    }
    stats->irradiance_s = pf_now() - t2;
    if (rc != PF_OK) {
        pf_photon_maps_free(maps);
        return rc;
    }
    stats->irradiance_points = pf_kdtree_size(maps->irradiance);
    return PF_OK;
}

int pf_photon_build(const pf_scene_t *scene, const pf_accel_t *accel, const pf_settings_t *settings,
                    uint64_t caustic_emitted, pf_photon_t **gp_p, size_t gn, pf_photon_t **cp_p, size_t cn,
                    pf_photon_maps_t *maps, pf_photon_stats_t *stats)
{
    return s_build(scene, accel, settings, caustic_emitted, gp_p, gn, cp_p, cn, maps, stats, NULL);
}

int pf_photon_pass(const pf_scene_t *scene, const pf_accel_t *accel, const pf_lights_t *lights,
                   const pf_settings_t *settings, pf_photon_maps_t *maps, pf_photon_stats_t *stats)
{
    memset(maps, 0, sizeof *maps);
    memset(stats, 0, sizeof *stats);
    int threads = settings->threads > 0 ? settings->threads : omp_get_num_procs();
    s_ctx c = { scene, accel, lights, pf_photon_depth(settings), NULL, 0 };
    pf_target_t *targets = NULL;
    uint64_t caustic_photons = 0;
    int nt = s_setup(scene, settings, &targets, &caustic_photons, 0);
    if (nt < 0)
        return nt;
    c.targets = targets;
    c.ntargets = (size_t)nt;

    double t0 = pf_now();
    pf_photon_t *gp = NULL, *cp = NULL;
    size_t gn = 0, cn = 0;
    int rc = PF_OK;
    uint64_t unused = 0;
    if (settings->photons)
        rc = s_trace_map(&c, settings->seed, settings->photons, 0, threads, &gp, &gn, &stats->rejected,
                         &stats->indirect_stored);
    if (rc == PF_OK && caustic_photons)
        rc = s_trace_map(&c, settings->seed, caustic_photons, 1, threads, &cp, &cn, &stats->rejected, &unused);
    free(targets);
    stats->trace_s = pf_now() - t0;
    if (rc != PF_OK) {
        free(gp);
        free(cp);
        return rc;
    }
    return pf_photon_build(scene, accel, settings, caustic_photons, &gp, gn, &cp, cn, maps, stats);
}

/* ---- batches: the photon pass spread over processes ---- */

struct pf_photon_tracer {
    s_ctx c;
    pf_target_t *targets;
    uint64_t seed;
    pf_photon_plan_t plan;
};

static uint32_t s_batches(uint64_t emitted)
{
    uint64_t blocks = (emitted + PF_PHOTON_BLOCK - 1) / PF_PHOTON_BLOCK;
    return (uint32_t)((blocks + PF_PHOTON_BATCH_BLOCKS - 1) / PF_PHOTON_BATCH_BLOCKS);
}

int pf_photon_tracer_new(const pf_scene_t *scene, const pf_accel_t *accel, const pf_lights_t *lights,
                         const pf_settings_t *settings, int quiet, pf_photon_tracer_t **out)
{
    *out = NULL;
    pf_photon_tracer_t *t = calloc(1, sizeof *t);
    if (!t)
        return PF_ENOMEM;
    uint64_t caustic = 0;
    int nt = s_setup(scene, settings, &t->targets, &caustic, quiet);
    if (nt < 0) {
        free(t);
        return nt;
    }
    t->c = (s_ctx){ scene, accel, lights, pf_photon_depth(settings), t->targets, (size_t)nt };
    t->seed = settings->seed;
    t->plan.global_emitted = settings->photons;
    t->plan.caustic_emitted = caustic;
    uint64_t gb = s_batches(settings->photons), cb = s_batches(caustic);
    if (gb + cb > PF_PHOTON_MAX_BATCHES) {
        free(t->targets);
        free(t);
        return PF_EINVAL;
    }
    t->plan.global_batches = (uint32_t)gb;
    t->plan.caustic_batches = (uint32_t)cb;
    *out = t;
    return PF_OK;
}

void pf_photon_tracer_free(pf_photon_tracer_t **t_p)
{
    if (!*t_p)
        return;
    free((*t_p)->targets);
    free(*t_p);
    *t_p = NULL;
}

const pf_photon_plan_t *pf_photon_tracer_plan(const pf_photon_tracer_t *t) { return &t->plan; }

/* Joins a batch's block buffers (freed) into out, in block order. */
static int s_join(s_buf *bufs, int n, int caustic, pf_photon_batch_t *out)
{
    memset(out, 0, sizeof *out);
    size_t total = 0;
    for (int k = 0; k < n; k++) {
        total += bufs[k].n;
        out->indirect += bufs[k].indirect;
        out->rejected += bufs[k].rejected;
    }
    pf_photon_t *all = malloc((total ? total : 1) * sizeof *all);
    if (all) {
        size_t at = 0;
        for (int k = 0; k < n; k++) {
            if (bufs[k].n)
                memcpy(all + at, bufs[k].p, bufs[k].n * sizeof *all);
            at += bufs[k].n;
        }
    }
    for (int k = 0; k < n; k++) {
        free(bufs[k].p);
        bufs[k].p = NULL;
    }
    if (!all) {
        memset(out, 0, sizeof *out);
        return PF_ENOMEM;
    }
    out->p = all;
    out->n = total;
    if (caustic)
        out->indirect = 0; /* only the global map's count matters (the gather skip) */
    return PF_OK;
}

int pf_photon_trace_batches(const pf_photon_tracer_t *t, uint32_t first, uint32_t count, int threads,
                            volatile int *abort, pf_photon_batch_t *out)
{
    memset(out, 0, count * sizeof *out);
    const pf_photon_plan_t *pl = &t->plan;
    uint32_t nb = pl->global_batches + pl->caustic_batches;
    if (count == 0 || count > PF_PHOTON_MAX_BATCHES || first >= nb || count > nb - first)
        return PF_EINVAL;
    /* One work item a block, over every block of the batches, so that the
     * threads stay busy across batch boundaries. */
    size_t nitems = (size_t)count * PF_PHOTON_BATCH_BLOCKS;
    s_buf *bufs = calloc(nitems, sizeof *bufs);
    if (!bufs)
        return PF_ENOMEM;
    int failed = 0;
#pragma omp parallel num_threads(threads)
    {
        pf_accel_thread_init();
#pragma omp for schedule(dynamic, 1)
        for (size_t w = 0; w < nitems; w++) {
            uint32_t batch = first + (uint32_t)(w / PF_PHOTON_BATCH_BLOCKS);
            int caustic = batch >= pl->global_batches;
            uint64_t emitted = caustic ? pl->caustic_emitted : pl->global_emitted;
            uint64_t block = (uint64_t)(caustic ? batch - pl->global_batches : batch) * PF_PHOTON_BATCH_BLOCKS +
                             w % PF_PHOTON_BATCH_BLOCKS;
            uint64_t lo = block * PF_PHOTON_BLOCK;
            if (lo >= emitted)
                continue; /* the map's last batch is short */
            if (s_cancelled() || (abort && *abort)) {
#pragma omp atomic write
                failed = PF_EINTERRUPTED;
                continue;
            }
            uint64_t hi = lo + PF_PHOTON_BLOCK < emitted ? lo + PF_PHOTON_BLOCK : emitted;
            for (uint64_t i = lo; i < hi; i++) {
                int r = s_trace(&t->c, t->seed, i, emitted, caustic, &bufs[w]);
                if (r < 0) {
#pragma omp atomic write
                    failed = PF_ENOMEM;
                    break;
                }
                bufs[w].rejected += (uint64_t)r;
            }
        }
    }
    int rc = failed;
    for (uint32_t k = 0; k < count; k++) {
        s_buf *b = bufs + (size_t)k * PF_PHOTON_BATCH_BLOCKS;
        if (rc == PF_OK)
            rc = s_join(b, PF_PHOTON_BATCH_BLOCKS, first + k >= pl->global_batches, &out[k]);
        for (int j = 0; j < PF_PHOTON_BATCH_BLOCKS; j++)
            free(b[j].p);
    }
    free(bufs);
    if (rc != PF_OK)
        for (uint32_t k = 0; k < count; k++) {
            free(out[k].p);
            memset(&out[k], 0, sizeof out[k]);
        }
    return rc;
}

int pf_photon_trace_batch(const pf_photon_tracer_t *t, uint32_t batch, int threads, volatile int *abort,
                          pf_photon_batch_t *out)
{
    return pf_photon_trace_batches(t, batch, 1, threads, abort, out);
}

int pf_photon_merge(const pf_scene_t *scene, const pf_accel_t *accel, const pf_settings_t *settings,
                    const pf_photon_plan_t *plan, pf_photon_batch_t *batches, pf_photon_maps_t *maps,
                    pf_photon_stats_t *stats)
{
    return pf_photon_merge_spread(scene, accel, settings, plan, batches, maps, stats, NULL);
}

int pf_photon_merge_spread(const pf_scene_t *scene, const pf_accel_t *accel, const pf_settings_t *settings,
                           const pf_photon_plan_t *plan, pf_photon_batch_t *batches, pf_photon_maps_t *maps,
                           pf_photon_stats_t *stats, const pf_irr_spread_t *spread)
{
    uint32_t nb = plan->global_batches + plan->caustic_batches;
    size_t gn = 0, cn = 0;
    for (uint32_t b = 0; b < nb; b++) {
        *(b < plan->global_batches ? &gn : &cn) += batches[b].n;
        stats->rejected += batches[b].rejected;
        if (b < plan->global_batches)
            stats->indirect_stored += batches[b].indirect;
    }
    pf_photon_t *gp = malloc((gn ? gn : 1) * sizeof *gp), *cp = malloc((cn ? cn : 1) * sizeof *cp);
    if (!gp || !cp) {
        free(gp);
        free(cp);
        return PF_ENOMEM;
    }
    size_t gi = 0, ci = 0;
    for (uint32_t b = 0; b < nb; b++) {
        int global = b < plan->global_batches;
        if (batches[b].n)
            memcpy(global ? gp + gi : cp + ci, batches[b].p, batches[b].n * sizeof *gp);
        *(global ? &gi : &ci) += batches[b].n;
        free(batches[b].p);
        batches[b].p = NULL;
        batches[b].n = 0;
    }
    return s_build(scene, accel, settings, plan->caustic_emitted, &gp, gn, &cp, cn, maps, stats, spread);
}

/* More than PF_IRRADIANCE_MAX_POINTS points add time and memory but no
 * visible detail: the lookup is piecewise constant over them, and each point's
 * estimate is already an average over its global_k photons. So large maps
 * take every stride-th photon with a wider stride. The widening stops at
 * global_k / 4, and the map gets more points than the cap instead: a lookup
 * reads the nearest point only when it lies within that point's support (the
 * disc of its k photons, pf_irradiance_lookup), and wider strides leave gaps
 * between the supports. Measured on the Cornell box (test_render's
 * s_test_point_stride): the mean irradiance lookups read is the same at
 * strides 4 and k / 4 (+0.15 %), 1 % low at k / 2.7 and 5 % low at k / 2. */
size_t pf_irradiance_points_stride(size_t stored, const pf_settings_t *settings)
{
    size_t stride = settings->irradiance_stride > 0 ? (size_t)settings->irradiance_stride : 1;
    if (stored / stride <= PF_IRRADIANCE_MAX_POINTS)
        return stride;
    size_t wide = (stored + PF_IRRADIANCE_MAX_POINTS - 1) / PF_IRRADIANCE_MAX_POINTS;
    size_t most = settings->global_k / 4 > 1 ? (size_t)(settings->global_k / 4) : 1;
    if (wide > most)
        wide = most;
    return wide > stride ? wide : stride;
}

void pf_photon_skip_gather(const pf_photon_stats_t *stats, pf_settings_t *s)
{
    if (!stats->gather_skipped || s->gather == 0)
        return;
    pf_info("final gather skipped: no light reaches a diffuse surface from another one (none of %" PRIu64
            " stored global photons had bounced off a non-specular surface)",
            stats->global_stored);
    s->gather = 0;
}
