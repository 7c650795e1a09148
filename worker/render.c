/* render.c: the integrator: radiance along camera rays from direct light,
 * mirror and glass recursion, the caustic map and a final gather over the
 * precomputed irradiance (Jensen 2001, ch. 9; Christensen 1999).
 *
 * Parameters (pf_settings_t; defaults in scene.c):
 *   spp            16   camera samples per pixel, stratified kx x ky (box filter)
 *   light_samples  1    shadow rays per camera sample at a non-specular point
 *   gather         16   final-gather rays per camera sample at a diffuse point, scaled by
 *                       the path's throughput (at least 1) below specular splits;
 *                       many camera samples with few gather rays each beat the
 *                       reverse at equal cost (the light's edges alias otherwise)
 *   max_depth      16   mirror/glass recursion depth of camera paths
 *   caustic_k      80   photons per caustic estimate, cone filter, radius <= caustic_radius
 *   global_k       100  photons per irradiance estimate (precomputed at every
 *                       irradiance_stride-th global photon)
 *
 * Path classes (Heckbert notation, read from the light L to the eye E; S is
 * a mirror or glass bounce, D a diffuse or glossy one, x the first
 * non-specular vertex seen from the eye):
 *
 *   term        paths                  how
 *   emitted     L S* E                 Le added when a camera path (through
 *                                      mirrors/glass only) hits an emitter's front
 *   direct      L D S* E  (D = x)      light sampling at x; emitters are never
 *                                      counted when a camera path reaches them
 *                                      from x's own BSDF sampling
 *   caustic     L S+ D S* E            caustic map at x (diffuse part of x)
 *   indirect    L (S|D)* D S* D S* E   final gather from x: each gather ray
 *                                      follows mirrors/glass to the first
 *                                      non-specular y and takes the global
 *                                      map's radiance there (precomputed
 *                                      irradiance x kd/pi), which stands for
 *                                      every path that ends at y; emitters the
 *                                      gather ray reaches directly (L D E:
 *                                      direct) or through S+ (L S+ D E:
 *                                      caustic) are not counted
 *   glossy      L ... S* G S* E        a glossy x samples its Phong lobe with one
 *                                      recursive ray; emitters that ray reaches
 *                                      directly are left to direct light, those it
 *                                      reaches through S+ are counted (the caustic
 *                                      map serves only x's diffuse part)
 *
 * Every path from a light to the eye falls in exactly one row: the classes are
 * split by the first non-specular vertex from the eye (none: emitted; x) and
 * by what lies between x and the light (nothing: direct; only S: caustic;
 * a non-specular vertex: indirect).
 *
 * Threads: pf_render_tile is re-entrant; pf_render_image runs tiles over
 * OpenMP, each thread with FTZ/DAZ set. */
#include "worker/render.h"

#include <omp.h>
#include <stdlib.h>
#include <string.h>

#include "common/bsdf.h"
#include "common/rng.h"

/* The camera samples of one pixel reach nearly the same points, and the
 * caustic estimate is a blur of radius r (its k-th photon's distance), so an
 * estimate is reused for a point closer than S_CAUSTIC_REUSE * r to the one
 * it was made at, on a surface facing the same way. Kept per pixel (reset at
 * each), so the image stays a function of the pixel alone. */
#define S_CAUSTIC_REUSE 0.25f

/* Per-thread state for one pixel sample. */
typedef struct s_state {
    const pf_render_ctx_t *ctx;
    pf_rng_t rng;
    int caustic_valid;
    pf_vec3 caustic_p, caustic_n, caustic_e;
    float caustic_reach2;
    pf_knn_t scratch[PF_MAX_K];
} s_state;

/* Caustic irradiance at p (surface normal nf), reusing the pixel's last
 * estimate when it was made close enough. */
static pf_vec3 s_caustic(s_state *st, pf_vec3 p, pf_vec3 nf)
{
    if (st->caustic_valid && pf_dot(nf, st->caustic_n) > 0.999f &&
        pf_dot(pf_sub(p, st->caustic_p), pf_sub(p, st->caustic_p)) < st->caustic_reach2)
        return st->caustic_e;
    const pf_render_ctx_t *c = st->ctx;
    float r2 = 0.0f;
    pf_vec3 e = pf_pm_irradiance_cone(c->maps->caustic, p, nf, c->settings.caustic_k, c->maps->caustic_r2,
                                      st->scratch, &r2);
    st->caustic_valid = 1;
    st->caustic_p = p;
    st->caustic_n = nf;
    st->caustic_e = e;
    st->caustic_reach2 = S_CAUSTIC_REUSE * S_CAUSTIC_REUSE * r2;
    return e;
}

static inline float s_u(s_state *st) { return pf_rng_float(&st->rng); }

/* Shadow test between a hit and the light point at distance dist along wi.
 * The ray leaves from the offset origin aimed at the light point itself (the
 * offset moves the origin off the line from the hit point), and stops short
 * of it by more than that point's rounding, so the emitter never occludes
 * itself, at any scale or distance from the origin. */
static int s_visible(const pf_accel_t *accel, const pf_hit_t *h, pf_vec3 wi, float dist)
{
    pf_vec3 target = pf_madd(h->p, wi, dist);
    pf_ray_t r = pf_spawn_ray(h, wi);
    pf_vec3 d = pf_sub(target, r.o);
    float len = pf_len(d);
    if (!(len > 0.0f))
        return 1;
    r.d = pf_scale(d, 1.0f / len);
    float slack = 0x1p-18f * pf_maxc(pf_vabs(target)) + pf_accel_eps(accel) + 1e-4f * len;
    return len <= slack || !pf_accel_occluded(accel, &r, len - slack);
}

/* Direct light at a non-specular hit: light_samples shadow rays. */
static pf_vec3 s_direct(s_state *st, const pf_hit_t *h, const pf_material_t *m, pf_vec3 nf, pf_vec3 ns, pf_vec3 wo)
{
    const pf_render_ctx_t *c = st->ctx;
    int n = c->settings.light_samples > 0 ? c->settings.light_samples : 1;
    pf_vec3 sum = pf_v3s(0.0f);
    for (int i = 0; i < n; i++) {
        float u[3] = { s_u(st), s_u(st), s_u(st) };
        pf_light_conn_t lc;
        if (!pf_lights_sample_direct(c->lights, c->scene, h->p, u, &lc))
            continue;
        float cos_x = pf_dot(lc.wi, ns);
        if (cos_x <= 0.0f || pf_dot(lc.wi, nf) <= 0.0f)
            continue;
        pf_vec3 f = pf_brdf_eval(m, ns, lc.wi, wo);
        if (pf_is_black(f) || !s_visible(c->accel, h, lc.wi, lc.dist))
            continue;
        sum = pf_add(sum, pf_scale(pf_mul(f, lc.weight), cos_x));
    }
    return pf_scale(sum, 1.0f / (float)n);
}

/* Irradiance at a gather hit p: that of the nearest precomputed point q with
 * an agreeing normal, if p lies within q's support (the disc its estimate
 * averaged over) and q is visible from p; zero otherwise, since then no
 * photon landed near p on its side of any wall. The visibility ray runs
 * between p and q both lifted off the surface by their distance d, which
 * clears a convex surface (a chord's sagitta d^2 / 8R is below d) but not a
 * wall standing between them: without it the final gather reads light
 * through walls (the stress suite's thin wall and closed crate). */
static pf_vec3 s_irradiance(s_state *st, pf_vec3 p, pf_vec3 nf)
{
    const pf_render_ctx_t *c = st->ctx;
    const pf_photon_maps_t *pm = c->maps;
    pf_knn_t near;
    if (!pm->irradiance || !pf_kdtree_nearest_normal(pm->irradiance, p, nf, PF_NORMAL_AGREE, pm->irradiance_r2, &near))
        return pf_v3s(0.0f);
    const pf_photon_t *q = &pf_kdtree_photons(pm->irradiance)[near.index];
    float r = pf_irradiance_radius(q);
    if (!(near.d2 <= r * r))
        return pf_v3s(0.0f);
    float d = sqrtf(near.d2);
    if (d > pf_accel_eps(c->accel)) {
        pf_vec3 a = pf_madd(p, nf, d), b = pf_madd(pf_photon_pos(q), nf, d);
        pf_vec3 ab = pf_sub(b, a);
        float len = pf_len(ab);
        if (len > 0.0f) {
            pf_ray_t ray = { a, pf_scale(ab, 1.0f / len) };
            if (pf_accel_occluded(c->accel, &ray, len))
                return pf_v3s(0.0f);
        }
    }
    return pf_photon_power(q);
}

/* Radiance leaving the first non-specular surface a gather ray reaches,
 * towards the ray's origin, from the global map; mirrors and glass on the way
 * are followed (one branch chosen by Fresnel). Emission is not counted. */
static pf_vec3 s_gather_ray(s_state *st, pf_ray_t ray)
{
    const pf_render_ctx_t *c = st->ctx;
    pf_vec3 thr = pf_v3s(1.0f);
    for (int depth = 0; depth < c->settings.max_depth; depth++) {
        pf_hit_t h;
        if (!pf_accel_intersect(c->accel, &ray, INFINITY, &h))
            return pf_v3s(0.0f);
        const pf_material_t *m = &c->scene->mats[h.mat];
        pf_vec3 wo = pf_neg(ray.d);
        pf_vec3 nf = pf_face_forward(h.ng, wo);
        pf_vec3 ns = pf_dot(h.ng, nf) > 0.0f ? h.ns : pf_neg(h.ns);
        if (m->type == PF_MAT_DIFFUSE) {
            if (!pf_mat_nonspecular(m))
                return pf_v3s(0.0f);
            pf_vec3 l;
            if (pf_mat_glossy(m))
                l = pf_pm_radiance(c->maps->global, m, h.p, nf, wo, c->settings.global_k, c->maps->global_r2,
                                   st->scratch);
            else
                l = pf_scale(pf_mul(m->kd, s_irradiance(st, h.p, nf)), PF_INV_PI);
            return pf_mul(thr, l);
        }
        pf_vec3 wi;
        if (m->type == PF_MAT_MIRROR) {
            thr = pf_mul(thr, m->ks);
            wi = pf_reflect(wo, ns);
        } else {
            int entering = pf_dot(ray.d, h.ng) < 0.0f;
            float eta_i = entering ? 1.0f : m->ior, eta_t = entering ? m->ior : 1.0f;
            float f = pf_fresnel_dielectric(pf_dot(wo, ns), eta_i, eta_t);
            if (s_u(st) < f || !pf_refract(wo, ns, eta_i / eta_t, &wi)) {
                wi = pf_reflect(wo, ns);
                thr = pf_mul(thr, m->ks);
            } else {
                /* Radiance scales by (eta_i / eta_t)^2 across the interface, seen from the receiving side. */
                float s = eta_i / eta_t;
                thr = pf_mul(thr, pf_scale(m->kt, s * s));
            }
        }
        if (pf_is_black(thr))
            return thr;
        ray = pf_spawn_ray(&h, wi);
    }
    return pf_v3s(0.0f);
}

/* Indirect light at a diffuse hit: n cosine-distributed gather rays. Returns
 * the reflected radiance kd * mean(L_i) (f cos / pdf = kd). */
static pf_vec3 s_final_gather(s_state *st, const pf_hit_t *h, const pf_material_t *m, pf_vec3 nf, pf_vec3 ns, int n)
{
    pf_vec3 sum = pf_v3s(0.0f);
    for (int i = 0; i < n; i++) {
        pf_vec3 wi = pf_to_world(pf_sample_cosine(s_u(st), s_u(st)), ns);
        if (pf_dot(wi, nf) <= 0.0f)
            continue;
        sum = pf_add(sum, s_gather_ray(st, pf_spawn_ray(h, wi)));
    }
    return pf_mul(m->kd, pf_scale(sum, 1.0f / (float)n));
}

/* Radiance along a camera path. thr is the path's throughput so far (to size
 * the final gather below dim specular branches); count_le says whether an
 * emitter hit here counts (see the table above). */
static pf_vec3 s_radiance(s_state *st, pf_ray_t ray, int depth, pf_vec3 thr, int count_le)
{
    const pf_render_ctx_t *c = st->ctx;
    pf_hit_t h;
    if (!pf_accel_intersect(c->accel, &ray, INFINITY, &h))
        return pf_v3s(0.0f);
    const pf_material_t *m = &c->scene->mats[h.mat];
    pf_vec3 wo = pf_neg(ray.d);
    pf_vec3 nf = pf_face_forward(h.ng, wo);
    pf_vec3 ns = pf_dot(h.ng, nf) > 0.0f ? h.ns : pf_neg(h.ns);
    pf_vec3 L = pf_v3s(0.0f);
    if (count_le && (c->terms & PF_TERM_EMITTED) && !pf_is_black(m->le) && pf_dot(ray.d, h.ng) < 0.0f)
        L = m->le;

    if (m->type == PF_MAT_DIFFUSE) {
        if (!pf_mat_nonspecular(m))
            return L;
        if (c->terms & PF_TERM_PHOTONMAP) {
            /* The global map's own estimate (the debugging view), not the
             * precomputed points, which a scene without indirect light lacks. */
            pf_vec3 e = pf_pm_irradiance(c->maps->global, h.p, nf, c->settings.global_k, c->maps->global_r2,
                                         st->scratch, NULL);
            return pf_add(L, pf_scale(pf_mul(m->kd, e), PF_INV_PI));
        }
        if (c->terms & PF_TERM_DIRECT)
            L = pf_add(L, s_direct(st, &h, m, nf, ns, wo));
        if (!pf_is_black(m->kd)) {
            if (c->terms & PF_TERM_CAUSTIC) {
                pf_vec3 e = s_caustic(st, h.p, nf);
                L = pf_add(L, pf_scale(pf_mul(m->kd, e), PF_INV_PI));
            }
            if (c->terms & PF_TERM_INDIRECT) {
                float w = fminf(1.0f, pf_maxc(thr));
                int n = (int)ceilf((float)c->settings.gather * w);
                if (n > 0)
                    L = pf_add(L, s_final_gather(st, &h, m, nf, ns, n));
            }
        }
        if (pf_mat_glossy(m) && depth < c->settings.max_depth) {
            pf_vec3 r = pf_reflect(wo, ns);
            pf_vec3 wi = pf_to_world(pf_sample_phong(s_u(st), s_u(st), m->ns), r);
            float cos_i = pf_dot(wi, ns);
            if (cos_i > 0.0f && pf_dot(wi, nf) > 0.0f) {
                pf_vec3 wgt = pf_scale(m->ks, (m->ns + 2.0f) / (m->ns + 1.0f) * cos_i);
                pf_vec3 li = s_radiance(st, pf_spawn_ray(&h, wi), depth + 1, pf_mul(thr, wgt), 0);
                L = pf_add(L, pf_mul(wgt, li));
            }
        }
        return L;
    }
    if (depth >= c->settings.max_depth)
        return L;
    if (m->type == PF_MAT_MIRROR) {
        pf_vec3 wi = pf_reflect(wo, ns);
        return pf_add(L, pf_mul(m->ks, s_radiance(st, pf_spawn_ray(&h, wi), depth + 1, pf_mul(thr, m->ks), 1)));
    }
    /* Glass: both branches near the eye, where their noise would show; one
     * chosen by Fresnel deeper down. */
    int entering = pf_dot(ray.d, h.ng) < 0.0f;
    float eta_i = entering ? 1.0f : m->ior, eta_t = entering ? m->ior : 1.0f;
    float f = pf_fresnel_dielectric(pf_dot(wo, ns), eta_i, eta_t);
    pf_vec3 wt;
    int can_refract = f < 1.0f && pf_refract(wo, ns, eta_i / eta_t, &wt);
    float s = eta_i / eta_t;
    pf_vec3 kt = pf_scale(m->kt, s * s);
    pf_vec3 wr = pf_reflect(wo, ns);
    if (!can_refract)
        return pf_add(L, pf_mul(m->ks, s_radiance(st, pf_spawn_ray(&h, wr), depth + 1, pf_mul(thr, m->ks), 1)));
    if (depth < 2) {
        pf_vec3 kr = pf_scale(m->ks, f), ktt = pf_scale(kt, 1.0f - f);
        pf_vec3 lr = s_radiance(st, pf_spawn_ray(&h, wr), depth + 1, pf_mul(thr, kr), 1);
        pf_vec3 lt = s_radiance(st, pf_spawn_ray(&h, wt), depth + 1, pf_mul(thr, ktt), 1);
        return pf_add(L, pf_add(pf_mul(kr, lr), pf_mul(ktt, lt)));
    }
    if (s_u(st) < f)
        return pf_add(L, pf_mul(m->ks, s_radiance(st, pf_spawn_ray(&h, wr), depth + 1, pf_mul(thr, m->ks), 1)));
    return pf_add(L, pf_mul(kt, s_radiance(st, pf_spawn_ray(&h, wt), depth + 1, pf_mul(thr, kt), 1)));
}

pf_vec3 pf_render_gather_ray(const pf_render_ctx_t *ctx, pf_ray_t ray, uint64_t sample)
{
    s_state st;
    st.ctx = ctx;
    st.rng = pf_rng_make(ctx->settings.seed, PF_STREAM_PIXEL, sample, 0);
    st.caustic_valid = 0;
    return s_gather_ray(&st, ray);
}

void pf_render_ctx_init(pf_render_ctx_t *ctx, const pf_scene_t *scene, const pf_accel_t *accel,
                        const pf_lights_t *lights, const pf_photon_maps_t *maps, const pf_settings_t *settings)
{
    memset(ctx, 0, sizeof *ctx);
    ctx->scene = scene;
    ctx->accel = accel;
    ctx->lights = lights;
    ctx->maps = maps;
    ctx->settings = *settings;
    ctx->camera = pf_camera_make(&scene->camera, settings->width, settings->height);
    ctx->terms = PF_TERM_ALL;
}

void pf_render_tile(const pf_render_ctx_t *ctx, int x0, int y0, int w, int h, float *out)
{
    s_state *st = malloc(sizeof *st);
    PF_CHECK(st != NULL);
    st->ctx = ctx;
    int spp = ctx->settings.spp > 0 ? ctx->settings.spp : 1;
    /* Jitter is stratified on a kx x ky grid, kx = floor(sqrt(spp)) and
     * ky = floor(spp / kx) (edges against the bright light dominate the error
     * otherwise); the few samples beyond kx * ky are uniform. A square spp
     * fills a k x k grid. */
    int kx = (int)sqrt((double)spp);
    while ((kx + 1) * (kx + 1) <= spp)
        kx++;
    while (kx * kx > spp)
        kx--;
    int ky = spp / kx, strata = kx * ky;
    for (int y = 0; y < h; y++) {
        for (int x = 0; x < w; x++) {
            int px = x0 + x, py = y0 + y;
            uint64_t pixel = (uint64_t)py * (uint64_t)ctx->camera.width + (uint64_t)px;
            double acc[3] = { 0, 0, 0 };
            st->caustic_valid = 0;
            for (int s = 0; s < spp; s++) {
                st->rng = pf_rng_make(ctx->settings.seed, PF_STREAM_PIXEL, pixel, (uint32_t)s);
                float jx = s_u(st), jy = s_u(st);
                if (s < strata) {
                    jx = ((float)(s % kx) + jx) / (float)kx;
                    jy = ((float)(s / kx) + jy) / (float)ky;
                }
                pf_ray_t ray = pf_camera_ray(&ctx->camera, (float)px + jx, (float)py + jy);
                pf_vec3 L = s_radiance(st, ray, 0, pf_v3s(1.0f), 1);
                if (!pf_is_finite3(L) || L.x < 0.0f || L.y < 0.0f || L.z < 0.0f) {
                    /* never let a NaN or negative sample reach the image, but say so */
                    if (ctx->dropped)
                        __atomic_fetch_add(ctx->dropped, 1, __ATOMIC_RELAXED);
                    continue;
                }
                acc[0] += L.x;
                acc[1] += L.y;
                acc[2] += L.z;
            }
            float *o = &out[3 * ((size_t)y * (size_t)w + (size_t)x)];
            for (int k = 0; k < 3; k++)
                o[k] = (float)(acc[k] / spp);
        }
    }
    free(st);
}

void pf_render_image(const pf_render_ctx_t *ctx, pf_image_t *img, int threads, int tile, pf_progress_fn progress,
                     void *user)
{
    int W = img->width, H = img->height;
    int tx = (W + tile - 1) / tile, ty = (H + tile - 1) / tile, total = tx * ty;
    int done = 0;
#pragma omp parallel num_threads(threads)
    {
        pf_accel_thread_init();
        float *buf = malloc((size_t)tile * (size_t)tile * 3 * sizeof *buf);
        PF_CHECK(buf != NULL);
#pragma omp for schedule(dynamic, 1)
        for (int t = 0; t < total; t++) {
            int x0 = (t % tx) * tile, y0 = (t / tx) * tile;
            int w = x0 + tile <= W ? tile : W - x0, h = y0 + tile <= H ? tile : H - y0;
            pf_render_tile(ctx, x0, y0, w, h, buf);
            for (int y = 0; y < h; y++)
                memcpy(&img->rgb[3 * ((size_t)(y0 + y) * (size_t)W + (size_t)x0)], &buf[3 * (size_t)y * (size_t)w],
                       (size_t)w * 3 * sizeof(float));
            int d;
#pragma omp atomic capture
            d = ++done;
            if (progress && omp_get_thread_num() == 0)
                progress(user, d, total);
        }
        free(buf);
    }
    if (progress)
        progress(user, total, total);
}
