/* render.c: the integrator: radiance along camera rays from direct light,
 * mirror and glass recursion, the caustic map and a final gather over the
 * precomputed irradiance (Jensen 2001, ch. 9; Christensen 1999), which the
 * gather reads through the surface's irradiance texels (photon/irrtex.h)
 * where the maps are indexed.
 *
 * Parameters (pf_settings_t; defaults in scene.c):
 *   spp            36   camera samples per pixel, stratified kx x ky, placed by the
 *                       pixel filter (filter_box, filter_tent; render/pixel.c)
 *   light_samples  2    shadow rays per camera sample at a non-specular point
 *   gather         1    final-gather rays per camera sample at a diffuse point, scaled by
 *                       the path's throughput (at least 1) below specular splits;
 *                       many camera samples with few gather rays each beat the
 *                       reverse at equal cost (the light's edges alias otherwise)
 *   gather_filter  2    the first gather of a camera path (through mirrors) is
 *                       shared over (2n+1)^2 pixels on the same surface (see
 *                       "Filtering the first gather" below)
 *   max_depth      16   mirror/glass recursion depth of camera paths
 *   caustic_k      80   photons per caustic estimate, cone filter, radius <= caustic_radius
 *   global_k       100  photons per irradiance estimate (precomputed at every
 *                       irradiance_stride-th global photon)
 *
 * Path classes (Heckbert notation, read from the light L to the eye E; S is
 * a mirror, glass (solid or thin) or smooth conductor bounce, C a rough conductor (GGX,
 * alpha >= 1e-3), D a diffuse or glossy one, x the first vertex seen from the
 * eye that is not S; behind x, towards the light, C counts as S: gather rays
 * follow it by sampling its BSDF, and photons leave it for L (S|C)+ D):
 *
 *   term        paths                  how
 *   emitted     L S* E                 Le added when a camera path (through
 *                                      S only) hits an emitter's front (or a
 *                                      two-sided one's either side); at an
 *                                      emitter's edge the emission seen
 *                                      directly has rays of its own (pixel.c)
 *   direct      L D S* E  (D = x)      light sampling at x; emitters are never
 *                                      counted when a camera path reaches them
 *                                      from x's own BSDF sampling
 *   caustic     L (S|C)+ D S* E        caustic map at x (diffuse part of x)
 *   indirect    L (S|C|D)* D (S|C)* D S* E
 *                                      final gather from x: each gather ray
 *                                      follows S and C to the first D, y, and
 *                                      takes the global map's radiance there
 *                                      (precomputed irradiance x kd/pi), which
 *                                      stands for every path that ends at y;
 *                                      emitters the gather ray reaches directly
 *                                      (L D E: direct) or through (S|C)+
 *                                      (L (S|C)+ D E: caustic) are not counted
 *   glossy      L ... S* G S* E        a glossy x samples its Phong lobe with one
 *                                      recursive ray; the emitter (or sky) that ray
 *                                      reaches directly counts with its MIS weight
 *                                      against x's light samples of the lobe, as the
 *                                      conductor row's, those it reaches through S+
 *                                      whole (the caustic map serves only x's
 *                                      diffuse part)
 *   conductor   L ... C S* E  (C = x)  a rough conductor x: L C S* E by MIS
 *                                      (power heuristic) of light_samples light
 *                                      samples and one BSDF sample, the latter
 *                                      also x's one recursive ray, which counts
 *                                      the emitter it hits directly with its MIS
 *                                      weight and the rest as a camera path
 *                                      from there (L S+ C E as emitted, paths
 *                                      with a vertex beyond by the next x)
 *
 * A coated x (material/coated.h) is D for its base (scaled by its
 * directional albedo) and adds its coat lobe as the conductor row does
 * (smooth: a mirror, as S). A gather ray follows a coat as C with the
 * coat's share of the choice (pf_coated_coat_prob), else ends at the base
 * as at D (the caustic map takes coats as C). A gather ray shorter than
 * the maps' near_r samples its end's direct light and reads only the rest
 * of the point's irradiance (pf_direct_near_end): the points' blur shows. Rough glass is
 * S taken as a random branch (a microfacet normal drawn per hit).
 *
 * Distant and infinite lights (the sun and a constant or image-based sky) fit the same
 * rows. The sun is a delta: only light sampling (direct) and photons reach
 * it, never a ray. The sky is an emitter every escaping ray reaches, as if
 * it were an area light's front at infinity: a camera path through S only
 * that escapes sees it (emitted, L S* E); x's light sampling draws
 * directions cosine-weighted about x's normal, or from an image sky's own
 * distribution (direct, L D S* E; light/light.c), and a
 * rough conductor's BSDF ray that escapes counts the sky with its MIS weight
 * (as it counts an emitter it hits); gather rays that escape count nothing (L D E is
 * direct, L (S|C)+ D E caustic: the caustic photons come from the sky too);
 * photons from a disc outside the scene, in every direction.
 *
 * Every path from a light to the eye falls in exactly one row: the classes are
 * split by the first vertex from the eye that is not S (none: emitted; x) and,
 * for a diffuse x, by what lies between x and the light (nothing: direct; only
 * S or C: caustic; a D: indirect); a glossy or conductor x hands what lies
 * beyond its recursive ray to the path that ray starts.
 *
 * Camera rays come from scene/camera.h: pinhole, or thin lens when the
 * camera's lens_radius > 0 (the lens sample's numbers: pf_pixel_sample in pixel.c).
 *
 * Threads: pf_render_tile is re-entrant; pf_render_image runs tiles over
 * OpenMP, each thread with FTZ/DAZ set. */
#include "render/render.h"

#include <omp.h>
#include <stdlib.h>
#include <string.h>

#include "accel/shading.h"
#include "accel/surface.h"
#include "base/log.h"
#include "base/rng.h"
#include "material/bsdf.h"
#include "material/coated.h"
#include "material/dielectric.h"
#include "material/difftrans.h"
#include "material/ggx.h"
#include "photon/irrtex.h"
#include "render/direct_impl.h"
#include "render/depth.h"
#include "render/filter_impl.h"
#include "render/pixel_impl.h"

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
    float caustic_hint; /* the last caustic estimate's squared radius, widened: bounds the next search */
    /* The filtered first gather (pf_render_tile): when filtering, the gather
     * at the end of a camera ray's primary path takes the filtered gather of
     * the first of the pixel's surfaces (rec) it lies on, else gathers with
     * the sample's own gather stream. */
    int filtering;
    const pf_filter_rec_t *rec;
    pf_vec3 gf[PF_FILTER_MAX_CLUSTERS];
    uint64_t pixel;
    uint32_t sample;
    /* The BSDF-sampled ray of a rough conductor (s_rough) in flight: where it
     * left, its pdf and the number of light samples taken there, for the
     * MIS weight of an emitter it hits (s_radiance with count_le 2). */
    pf_vec3 mis_x, mis_n; /* mis_n: x's shading normal, about which the sky was sampled */
    float mis_pdf;
    int mis_nl;
    /* The gather under way at a diffuse point weighs the sky its rays see
     * directly by MIS against that point's light samples (pf_direct_sky_mis):
     * sky_ng rays about sky_ns (0: the sky seen counts nothing). */
    int sky_ng;
    pf_vec3 sky_ns;
    unsigned caustic_limit; /* the bounce limit the reusable caustic estimate had */
    int events; /* the scattering events of the camera path at the vertex estimating now (render/depth.h) */
    pf_pm_scratch_t scratch;
} s_state;

/* Caustic irradiance at p (surface normal nf), reusing the pixel's last
 * estimate when it was made close enough. */
static pf_vec3 s_caustic(s_state *st, pf_vec3 p, pf_vec3 nf)
{
    const pf_render_ctx_t *c = st->ctx;
    unsigned limit = pf_depth_photon_limit(&c->settings, st->events);
    if (st->caustic_valid && pf_dot(nf, st->caustic_n) > 0.999f && st->caustic_limit == limit &&
        pf_dot(pf_sub(p, st->caustic_p), pf_sub(p, st->caustic_p)) < st->caustic_reach2)
        return st->caustic_e;
    st->scratch.bounce_limit = st->caustic_limit = limit;
    float r2 = 0.0f;
    pf_vec3 e = pf_pm_estimate(c->maps->caustic, p, nf, c->settings.caustic_k, c->maps->caustic_r2,
                               st->caustic_hint, c->shrink2, 1, &st->scratch, &r2);
    st->caustic_hint = r2 < c->maps->caustic_r2 ? fminf(2.25f * r2, c->maps->caustic_r2) : c->maps->caustic_r2;
    st->caustic_valid = 1;
    st->caustic_p = p;
    st->caustic_n = nf;
    st->caustic_e = e;
    st->caustic_reach2 = S_CAUSTIC_REUSE * S_CAUSTIC_REUSE * (c->shrink2 < 1.0f ? c->shrink2 * r2 : r2);
    return e;
}

static inline float s_u(s_state *st) { return pf_rng_float(&st->rng); }

/* Where a gather ray ends: its radiance, or, at a diffuse surface read
 * through the irradiance lookup, that lookup still to make (its texel's
 * cache line asked for where it has one; s_gather_end_value makes it): the
 * radiance is then thr * kd * E / pi, E the texel's irradiance (or the
 * direct lookup's, without a texel or where the texel sends its hits there). */
typedef struct s_gather_end {
    pf_vec3 value; /* unless lookup */
    int lookup;    /* the radiance is thr * kd * E / pi, E looked up at h */
    size_t texel;  /* h's texel, or PF_IRRTEX_NONE: the direct lookup */
    pf_hit_t h;
    pf_vec3 nf, thr, kd;
} s_gather_end;

/* A glass hit's split (material/dielectric.h): rough glass draws its
 * microfacet normal here, smooth glass draws nothing. */
static pf_dielectric_t s_glass(s_state *st, const pf_material_t *m, pf_vec3 d, pf_vec3 ng, pf_vec3 wo, pf_vec3 ns)
{
    if (!pf_mat_rough_glass(m))
        return pf_dielectric_at(m, d, ng, wo, ns);
    float u1 = s_u(st), u2 = s_u(st);
    return pf_dielectric_rough_at(m, d, ng, wo, ns, u1, u2);
}

/* Traces a final-gather ray to its end: mirrors and glass (solid or thin)
 * on the way are followed (one branch chosen by Fresnel); at the first
 * non-specular surface
 * the radiance it leaves towards the ray's origin, from the global map
 * (emission not counted); the sky seen straight from the point, as
 * pf_direct_gather_sky weighs it (when st->sky_ng says so). */
static void s_gather_trace(s_state *st, pf_ray_t ray, s_gather_end *end)
{
    const pf_render_ctx_t *c = st->ctx;
    end->value = pf_v3s(0.0f);
    end->lookup = 0;
    end->texel = PF_IRRTEX_NONE;
    pf_vec3 thr = pf_v3s(1.0f);
    for (int depth = 0; depth < c->settings.max_depth; depth++) {
        pf_hit_t h;
        if (!pf_accel_intersect(c->accel, &ray, INFINITY, &h)) {
            if (depth == 0 && st->sky_ng > 0)
                end->value = pf_direct_gather_sky(c, st->sky_ns, st->sky_ng, ray.d);
            return;
        }
        thr = pf_mul(thr, pf_hit_transmittance(c->scene, &h, ray.d));
        pf_material_t mt = pf_material_at(c->scene, &h);
        const pf_material_t *m = &mt;
        pf_shade_hit(c->scene, m, &h, pf_neg(ray.d));
        pf_vec3 wo = pf_neg(ray.d);
        pf_vec3 nf = pf_face_forward(h.ng, wo);
        pf_vec3 ns = pf_dot(h.ng, nf) > 0.0f ? h.ns : pf_neg(h.ns);
        /* A coat is C: the ray follows it with its albedo's share of the
         * choice (the caustic map holds L C D), else ends at the base. */
        float base_w = 1.0f;
        if (pf_mat_coated(m) && pf_mat_nonspecular(m) && pf_dot(wo, ns) > 0.0f) {
            float pc = pf_coated_coat_prob(m, pf_dot(wo, ns));
            if (s_u(st) < pc) {
                pf_vec3 wi;
                float w, pdf, u1 = s_u(st), u2 = s_u(st);
                if (!pf_coated_sample_coat(m, ns, wo, u1, u2, &wi, &w, &pdf) || pf_dot(wi, nf) <= 0.0f)
                    return;
                thr = pf_scale(thr, w / pc);
                ray = pf_spawn_ray(&h, wi);
                continue;
            }
            base_w = 1.0f / (1.0f - pc);
        }
        if (m->type == PF_MAT_DIFFUSE || pf_mat_coated(m) || pf_mat_difftrans(m)) {
            int events = st->events + 1 + depth; /* the gather ray's end's photons make the rest */
            if (!pf_mat_nonspecular(m) || !pf_depth_allows(&c->settings, events))
                return;
            st->scratch.bounce_limit = pf_depth_photon_limit(&c->settings, events);
            if (pf_mat_difftrans(m)) { /* both sides' irradiance, by the direct lookup */
                const pf_photon_maps_t *pm = c->maps;
                pf_vec3 ef = pf_irradiance_lookup(pm->irradiance, pm->irradiance_r2, c->accel, h.p, nf);
                pf_vec3 eb = pf_irradiance_lookup(pm->irradiance, pm->irradiance_r2, c->accel, h.p, pf_neg(nf));
                pf_vec3 l = pf_scale(pf_add(pf_mul(m->kd, ef), pf_mul(m->kt, eb)), PF_INV_PI);
                end->value = pf_mul(thr, l);
                return;
            }
            if (!pf_depth_precomputed(&c->settings, events)) { /* the deep points, else the map itself */
                pf_vec3 kd = pf_mat_coated(m) ? pf_scale(pf_coated_kd(m, pf_dot(wo, ns), 0), base_w) : m->kd;
                const pf_photon_maps_t *pm = c->maps;
                pf_vec3 e = pf_depth_deep(&c->settings, pm, events)
                                ? pf_irradiance_lookup(pm->irradiance_deep, pm->irradiance_r2, c->accel, h.p, nf)
                                : pf_pm_irradiance(pm->global, h.p, nf, c->settings.global_k, pm->global_r2,
                                                   &st->scratch, NULL);
                end->value = pf_mul(thr, pf_scale(pf_mul(kd, e), PF_INV_PI));
                return;
            }
            if (pf_mat_glossy(m)) {
                pf_vec3 l = pf_pm_radiance(c->maps->global, m, h.p, nf, wo, c->settings.global_k,
                                           c->maps->global_r2, c->shrink2, &st->scratch);
                end->value = pf_mul(thr, l);
                return;
            }
            pf_vec3 kd = pf_mat_coated(m) ? pf_scale(pf_coated_kd(m, pf_dot(wo, ns), 0), base_w) : m->kd;
            if (h.t < c->maps->near_r) {
                end->value = pf_mul(thr, pf_direct_near_end(c, &st->rng, &h, m, kd, nf, ns, wo));
                return;
            }
            end->texel = c->texels ? pf_irrtex_find(c->texels, &h, nf) : PF_IRRTEX_NONE;
            end->lookup = 1;
            end->h = h;
            end->nf = nf;
            end->thr = thr;
            end->kd = kd;
            return;
        }
        pf_vec3 wi;
        if (m->type == PF_MAT_MIRROR) {
            thr = pf_mul(thr, m->ks);
            wi = pf_reflect(wo, ns);
        } else if (m->type == PF_MAT_CONDUCTOR) {
            pf_vec3 w;
            float u1 = s_u(st), u2 = s_u(st);
            if (!pf_conductor_scatter(m, ns, wo, u1, u2, &wi, &w) || pf_dot(wi, nf) <= 0.0f)
                return;
            thr = pf_mul(thr, w);
        } else {
            pf_dielectric_t g = s_glass(st, m, ray.d, h.ng, wo, ns);
            int reflect = s_u(st) < g.f || !g.can_refract;
            wi = reflect ? g.wr : g.wt;
            thr = pf_mul(thr, reflect ? g.kr : g.kt);
        }
        if (pf_is_black(thr)) {
            end->value = thr;
            return;
        }
        ray = pf_spawn_ray(&h, wi);
    }
}

/* A gather ray's radiance, making its irradiance lookup if it waits on one
 * (the texel's answer, or the direct lookup without a texel or where the
 * texel sends it there). */
static pf_vec3 s_gather_end_value(const s_state *st, const s_gather_end *end)
{
    if (!end->lookup)
        return end->value;
    const pf_photon_maps_t *pm = st->ctx->maps;
    pf_vec3 e;
    if (end->texel == PF_IRRTEX_NONE || !pf_irrtex_read(st->ctx->texels, end->texel, &end->h, end->nf, &e))
        e = pf_irradiance_lookup(pm->irradiance, pm->irradiance_r2, st->ctx->accel, end->h.p, end->nf);
    return pf_mul(end->thr, pf_scale(pf_mul(end->kd, e), PF_INV_PI));
}

/* Gather reads put off (s_gather_sum): a few texel reads, each with the
 * sum it adds to, made together once the traces around them are done. */
enum { S_DEFER_MAX = 16 };
typedef struct s_defer {
    int n;
    s_gather_end end[S_DEFER_MAX];
    pf_vec3 *sum[S_DEFER_MAX];
} s_defer;

/* Adds a gather ray's radiance to *sum; with d, when the ray waits on a
 * texel read, the read is left in d (while there is room) to be added later
 * by s_defer_flush. */
static void s_gather_add(s_state *st, pf_ray_t ray, s_defer *d, pf_vec3 *sum)
{
    int defer = d && d->n < S_DEFER_MAX && !st->ctx->reads_at_once;
    s_gather_end now, *end = defer ? &d->end[d->n] : &now;
    s_gather_trace(st, ray, end);
    if (defer && end->texel != PF_IRRTEX_NONE)
        d->sum[d->n++] = sum;
    else
        *sum = pf_add(*sum, s_gather_end_value(st, end));
}

/* Makes the reads put off, each adding to its sum, in the order they came. */
static void s_defer_flush(const s_state *st, s_defer *d)
{
    for (int i = 0; i < d->n; i++)
        *d->sum[i] = pf_add(*d->sum[i], s_gather_end_value(st, &d->end[i]));
    d->n = 0;
}

/* The final gather at a diffuse hit: adds to *sum the radiances of n
 * cosine-distributed gather rays (their mean times kd is the reflected
 * radiance: f cos / pdf = kd), each as s_gather_add; sky: whether they count
 * the sky they see (pf_direct_sky_mis's answer, n or 0). */
static void s_gather_sum(s_state *st, const pf_hit_t *h, pf_vec3 nf, pf_vec3 ns, int n, int sky, s_defer *d,
                         pf_vec3 *sum)
{
    st->sky_ng = sky;
    st->sky_ns = ns;
    for (int i = 0; i < n; i++) {
        pf_vec3 wi = pf_to_world(pf_sample_cosine(s_u(st), s_u(st)), ns);
        if (pf_dot(wi, nf) > 0.0f)
            s_gather_add(st, pf_spawn_ray(h, wi), d, sum);
    }
}

static pf_vec3 s_gather_mean(s_state *st, const pf_hit_t *h, pf_vec3 nf, pf_vec3 ns, int n, int sky)
{
    pf_vec3 sum = pf_v3s(0.0f);
    s_gather_sum(st, h, nf, ns, n, sky, NULL, &sum);
    return pf_scale(sum, 1.0f / (float)n);
}

/* The first gather of a camera sample (depth 0), from its own random stream
 * so that any tile can compute it for any pixel (pf_render_tile's records):
 * its rays' radiances added to *sum, as s_gather_sum (d included). */
static void s_first_gather_sum(s_state *st, const pf_hit_t *h, pf_vec3 nf, pf_vec3 ns, int sky, s_defer *d,
                               pf_vec3 *sum)
{
    pf_rng_t pixel_rng = st->rng;
    st->rng = pf_rng_make(st->ctx->settings.seed, PF_STREAM_GATHER, st->pixel, st->sample);
    s_gather_sum(st, h, nf, ns, st->ctx->settings.gather, sky, d, sum);
    st->rng = pixel_rng;
}

/* The first gather of a camera sample as the render pass takes it: the
 * filtered gather of the pixel's surface it lies on, else its own. */
static pf_vec3 s_first_gather(s_state *st, const pf_hit_t *h, pf_vec3 nf, pf_vec3 ns, int sky)
{
    /* The surfaces are tried in the order they were found, as the records
     * assigned each sample to the first that took it (or to none of the
     * PF_FILTER_MAX_CLUSTERS), so this is the surface the sample's gather
     * went to. */
    int k = st->rec ? pf_filter_rec_find(st->rec, h->p, nf) : 0;
    if (st->rec && k < st->rec->nc)
        return st->gf[k];
    pf_vec3 sum = pf_v3s(0.0f);
    s_first_gather_sum(st, h, nf, ns, sky, NULL, &sum);
    return pf_scale(sum, 1.0f / (float)st->ctx->settings.gather);
}

/* Glass paths (solid or thin, material/dielectric.h) of the camera split
 * into both branches above this depth. */
#define S_GLASS_SPLIT_DEPTH 2

static pf_vec3 s_radiance(s_state *st, pf_ray_t ray, int depth, pf_vec3 thr, int count_le, int primary);


/* A rough conductor as x: direct light by multiple importance sampling of
 * light_samples light samples and one BSDF sample, which is also the path's
 * one recursive ray (the emitter it hits directly weighted by MIS: count_le
 * 2, st->mis_*). */
static pf_vec3 s_rough(s_state *st, const pf_hit_t *h, const pf_material_t *m, pf_vec3 nf, pf_vec3 ns, pf_vec3 wo,
                       int depth, pf_vec3 thr)
{
    const pf_render_ctx_t *c = st->ctx;
    int recurse = depth < c->settings.max_depth;
    int n = c->settings.light_samples > 0 ? c->settings.light_samples : 1;
    pf_vec3 L = (c->terms & PF_TERM_DIRECT) ? pf_direct_light(c, &st->rng, h, m, nf, ns, wo, recurse, 0) : pf_v3s(0.0f);
    pf_vec3 wi, wgt;
    float pdf, u1 = recurse ? s_u(st) : 0.0f, u2 = recurse ? s_u(st) : 0.0f;
    if (!recurse || !pf_conductor_sample(m, ns, wo, u1, u2, &wi, &wgt, &pdf) || pf_dot(wi, nf) <= 0.0f)
        return L;
    st->mis_x = h->p;
    st->mis_n = ns;
    st->mis_pdf = pdf;
    st->mis_nl = n;
    pf_vec3 li = s_radiance(st, pf_spawn_ray(h, wi), depth + 1, pf_mul(thr, wgt), 2, 0);
    return pf_add(L, pf_mul(wgt, li));
}

/* The coat lobe of a coated x: its one recursive ray. A rough coat's is
 * sampled from the visible normals, and the emitter it hits directly
 * counts with its MIS weight against pf_direct_light's light samples (count_le 2);
 * a smooth coat's is the mirror, which light sampling never sees, so what
 * it meets counts whole (count_le 1, as a mirror's). The base is x's
 * direct light, caustics and final gather (scaled by pf_coated_kd). */
static pf_vec3 s_coat(s_state *st, const pf_hit_t *h, const pf_material_t *m, pf_vec3 nf, pf_vec3 ns, pf_vec3 wo,
                      int depth, pf_vec3 thr)
{
    const pf_render_ctx_t *c = st->ctx;
    pf_vec3 wi;
    float w, pdf, u1 = s_u(st), u2 = s_u(st);
    if (depth >= c->settings.max_depth || !pf_coated_sample_coat(m, ns, wo, u1, u2, &wi, &w, &pdf) ||
        pf_dot(wi, nf) <= 0.0f || !(w > 0.0f))
        return pf_v3s(0.0f);
    int count_le = 1;
    if (pdf > 0.0f) {
        st->mis_x = h->p;
        st->mis_n = ns;
        st->mis_pdf = pdf;
        st->mis_nl = c->settings.light_samples > 0 ? c->settings.light_samples : 1;
        count_le = 2;
    }
    pf_vec3 wgt = pf_v3s(w);
    return pf_mul(wgt, s_radiance(st, pf_spawn_ray(h, wi), depth + 1, pf_mul(thr, wgt), count_le, 0));
}

/* The radiance an emitter hit at h along d sends back, as count_le (1 or 2)
 * counts it (see s_radiance). */
static pf_vec3 s_emitted(const s_state *st, const pf_hit_t *h, const pf_material_t *m, pf_vec3 d, int count_le)
{
    const pf_render_ctx_t *c = st->ctx;
    if (!(c->terms & (count_le == 2 ? PF_TERM_DIRECT : PF_TERM_EMITTED)) || pf_is_black(m->le) ||
        (!m->twosided && pf_dot(d, h->ng) >= 0.0f))
        return pf_v3s(0.0f);
    if (count_le == 1)
        return m->le;
    /* x's light sampling would have chosen this point with that pdf */
    float pl = pf_lights_pdf_at(c->lights, c->scene, st->mis_x, st->mis_n, h->geom, h->prim, h->p);
    return pf_scale(m->le, pf_mis_power(1.0f, st->mis_pdf, (float)st->mis_nl, pl));
}

/* The sky a camera path sees when it escapes along d, as count_le counts it
 * (see s_emitted). */
static pf_vec3 s_sky(const s_state *st, pf_vec3 d, int count_le)
{
    const pf_render_ctx_t *c = st->ctx;
    float pl = 0.0f; /* with count_le 2, its pdf from the same map lookup */
    pf_vec3 sky = count_le == 2 ? pf_lights_sky_mis(c->lights, st->mis_n, d, &pl) : pf_lights_sky(c->lights, d);
    if (!count_le || pf_is_black(sky) || !(c->terms & (count_le == 2 ? PF_TERM_DIRECT : PF_TERM_EMITTED)))
        return pf_v3s(0.0f);
    if (count_le == 1)
        return sky;
    return pf_scale(sky, pf_mis_power(1.0f, st->mis_pdf, (float)st->mis_nl, pl));
}

/* The light a diffuse transmitter x passes from its far side (-nf), as
 * the D rows take it on the near side: kt times the caustic irradiance and
 * the final gather there (its direct light is pf_direct_light's); with the
 * photon-map view, the global map's estimate there. Not filtered: the
 * first-gather records serve the near side. */
static pf_vec3 s_transmitted(s_state *st, const pf_hit_t *h, const pf_material_t *m, pf_vec3 nf, pf_vec3 ns,
                             pf_vec3 thr)
{
    const pf_render_ctx_t *c = st->ctx;
    pf_vec3 bf = pf_neg(nf), bs = pf_neg(ns), e = pf_v3s(0.0f);
    if (pf_is_black(m->kt))
        return e;
    if (c->terms & PF_TERM_PHOTONMAP)
        return pf_scale(pf_mul(m->kt, pf_pm_irradiance(c->maps->global, h->p, bf, c->settings.global_k,
                                                       c->maps->global_r2, &st->scratch, NULL)),
                        PF_INV_PI);
    if (c->terms & PF_TERM_CAUSTIC)
        e = pf_scale(s_caustic(st, h->p, bf), PF_INV_PI);
    /* The near side's first gather is shared over (2 g + 1)^2 pixels when
     * filtering; the far side's is not, so it takes 2 g + 1 times the rays
     * to keep its noise nearer the near side's. */
    int n = (int)ceilf((float)c->settings.gather * fminf(1.0f, pf_maxc(thr)));
    n *= st->filtering ? 2 * c->settings.gather_filter + 1 : 1;
    if ((c->terms & PF_TERM_INDIRECT) && n > 0)
        e = pf_add(e, s_gather_mean(st, h, bf, bs, n, 0));
    return pf_mul(m->kt, e);
}

/* Radiance along a camera path. thr is the path's throughput so far (to size
 * the final gather below dim specular branches); count_le says whether an
 * emitter hit here counts (see the table above): 0 no, 1 yes, 2 with the MIS
 * weight of a rough conductor's BSDF sample (st->mis_*); primary, whether
 * the path has met only mirrors so far (its first gather may be filtered). */
static pf_vec3 s_radiance_at(s_state *st, pf_ray_t ray, pf_hit_t h, int depth, pf_vec3 thr, int count_le,
                             int primary);

static pf_vec3 s_radiance(s_state *st, pf_ray_t ray, int depth, pf_vec3 thr, int count_le, int primary)
{
    pf_hit_t h;
    if (!pf_accel_intersect(st->ctx->accel, &ray, INFINITY, &h)) /* the sky, counted as an emitter's front */
        return s_sky(st, ray.d, count_le);
    pf_vec3 tr = pf_hit_transmittance(st->ctx->scene, &h, ray.d); /* the medium the ray crossed */
    if (tr.x == 1.0f && tr.y == 1.0f && tr.z == 1.0f)
        return s_radiance_at(st, ray, h, depth, thr, count_le, primary);
    return pf_mul(tr, s_radiance_at(st, ray, h, depth, pf_mul(thr, tr), count_le, primary));
}

/* s_radiance from the ray's hit h on. */
static pf_vec3 s_radiance_at(s_state *st, pf_ray_t ray, pf_hit_t h, int depth, pf_vec3 thr, int count_le,
                             int primary)
{
    const pf_render_ctx_t *c = st->ctx;
    pf_material_t mt = pf_material_at(c->scene, &h);
    const pf_material_t *m = &mt;
    pf_shade_hit(c->scene, m, &h, pf_neg(ray.d));
    pf_vec3 wo = pf_neg(ray.d);
    pf_vec3 nf = pf_face_forward(h.ng, wo);
    pf_vec3 ns = pf_dot(h.ng, nf) > 0.0f ? h.ns : pf_neg(h.ns);
    pf_vec3 L = count_le ? s_emitted(st, &h, m, ray.d, count_le) : pf_v3s(0.0f);
    if (!pf_depth_allows(&c->settings, depth + 1))
        return L; /* this vertex would scatter one event too many */
    st->events = depth + 1;
    if (pf_mat_rough(m))
        return pf_add(L, s_rough(st, &h, m, nf, ns, wo, depth, thr));

    if (m->type == PF_MAT_DIFFUSE || pf_mat_coated(m) || pf_mat_difftrans(m)) {
        if (!pf_mat_nonspecular(m))
            return L;
        pf_vec3 kd = pf_mat_coated(m) ? pf_coated_kd(m, pf_dot(wo, ns), 0) : m->kd;
        if (c->terms & PF_TERM_PHOTONMAP) {
            /* The global map's own estimate (the debugging view), not the
             * precomputed points, which a scene without indirect light lacks. */
            st->scratch.bounce_limit = pf_depth_photon_limit(&c->settings, depth + 1);
            pf_vec3 e = pf_pm_irradiance(c->maps->global, h.p, nf, c->settings.global_k, c->maps->global_r2,
                                         &st->scratch, NULL);
            if (pf_mat_difftrans(m))
                L = pf_add(L, s_transmitted(st, &h, m, nf, ns, thr));
            return pf_add(L, pf_scale(pf_mul(kd, e), PF_INV_PI));
        }
        /* the gather's rays: the filtered first gather's count, else fewer
         * below dim specular branches */
        int filtered = primary && st->filtering;
        int ng = (int)ceilf((float)c->settings.gather * fminf(1.0f, pf_maxc(thr)));
        ng = !(c->terms & PF_TERM_INDIRECT) || pf_is_black(kd) || !pf_depth_allows(&c->settings, depth + 2) ? 0
             : filtered ? c->settings.gather : ng;
        int sky = pf_direct_sky_mis(c, m, ng);
        if (c->terms & PF_TERM_DIRECT)
            L = pf_add(L, pf_direct_light(c, &st->rng, &h, m, nf, ns, wo, depth < c->settings.max_depth, sky));
        if (!pf_is_black(kd)) {
            if (c->terms & PF_TERM_CAUSTIC) {
                pf_vec3 e = s_caustic(st, h.p, nf);
                L = pf_add(L, pf_scale(pf_mul(kd, e), PF_INV_PI));
            }
            if (filtered && ng > 0)
                L = pf_add(L, pf_mul(kd, s_first_gather(st, &h, nf, ns, sky)));
            else if (ng > 0)
                L = pf_add(L, pf_mul(kd, s_gather_mean(st, &h, nf, ns, ng, sky)));
        }
        if (pf_mat_coated(m))
            L = pf_add(L, s_coat(st, &h, m, nf, ns, wo, depth, thr));
        if (pf_mat_difftrans(m) && !(c->terms & PF_TERM_PHOTONMAP))
            L = pf_add(L, s_transmitted(st, &h, m, nf, ns, thr));
        if (pf_mat_glossy(m) && depth < c->settings.max_depth) {
            pf_vec3 r = pf_reflect(wo, ns);
            pf_vec3 wi = pf_to_world(pf_sample_phong(s_u(st), s_u(st), m->ns), r);
            float cos_i = pf_dot(wi, ns);
            if (cos_i > 0.0f && pf_dot(wi, nf) > 0.0f) {
                pf_vec3 wgt = pf_scale(m->ks, (m->ns + 2.0f) / (m->ns + 1.0f) * cos_i);
                /* an emitter (or the sky) the lobe's ray meets counts with its
                 * MIS weight against pf_direct_light's samples of the lobe */
                st->mis_x = h.p;
                st->mis_n = ns;
                st->mis_pdf = pf_phong_pdf(pf_dot(wi, r), m->ns);
                st->mis_nl = c->settings.light_samples > 0 ? c->settings.light_samples : 1;
                pf_vec3 li = s_radiance(st, pf_spawn_ray(&h, wi), depth + 1, pf_mul(thr, wgt), 2, 0);
                L = pf_add(L, pf_mul(wgt, li));
            }
        }
        return L;
    }
    if (depth >= c->settings.max_depth)
        return L;
    if (m->type == PF_MAT_MIRROR || m->type == PF_MAT_CONDUCTOR) {
        /* a smooth conductor: a mirror tinted by its Fresnel at this angle */
        pf_vec3 wi = pf_reflect(wo, ns);
        pf_vec3 ks = m->type == PF_MAT_MIRROR ? m->ks : pf_fresnel_conductor(pf_dot(wo, ns), m->eta, m->k);
        return pf_add(L, pf_mul(ks, s_radiance(st, pf_spawn_ray(&h, wi), depth + 1, pf_mul(thr, ks), 1, primary)));
    }
    /* Glass: both branches near the eye, where their noise would show; one
     * chosen by Fresnel deeper down. The refracted branch near the eye (or
     * the reflection alone under total internal reflection) goes on as the
     * primary path; s_primary_hit follows the same choice. */
    pf_dielectric_t g = s_glass(st, m, ray.d, h.ng, wo, ns);
    float f = g.f;
    pf_vec3 wt = g.wt, wr = g.wr, kt = g.kt, ks = g.kr;
    if (!g.can_refract)
        return pf_add(L, pf_mul(ks, s_radiance(st, pf_spawn_ray(&h, wr), depth + 1, pf_mul(thr, ks), 1, primary)));
    if (depth < S_GLASS_SPLIT_DEPTH) {
        pf_vec3 kr = pf_scale(ks, f), ktt = pf_scale(kt, 1.0f - f);
        pf_vec3 lr = s_radiance(st, pf_spawn_ray(&h, wr), depth + 1, pf_mul(thr, kr), 1, 0);
        pf_vec3 lt = s_radiance(st, pf_spawn_ray(&h, wt), depth + 1, pf_mul(thr, ktt), 1, primary);
        return pf_add(L, pf_add(pf_mul(kr, lr), pf_mul(ktt, lt)));
    }
    if (s_u(st) < f)
        return pf_add(L, pf_mul(ks, s_radiance(st, pf_spawn_ray(&h, wr), depth + 1, pf_mul(thr, ks), 1, 0)));
    return pf_add(L, pf_mul(kt, s_radiance(st, pf_spawn_ray(&h, wt), depth + 1, pf_mul(thr, kt), 1, 0)));
}

pf_vec3 pf_render_gather_rays(const pf_render_ctx_t *ctx, const pf_ray_t *rays, size_t n, uint64_t sample)
{
    s_state st;
    st.ctx = ctx;
    st.rng = pf_rng_make(ctx->settings.seed, PF_STREAM_PIXEL, sample, 0);
    st.caustic_valid = 0;
    st.caustic_hint = INFINITY;
    st.filtering = 0;
    st.rec = NULL;
    st.sky_ng = 0;
    st.events = 1;
    st.scratch.bounce_limit = 0;
    s_defer d;
    d.n = 0;
    pf_vec3 sum = pf_v3s(0.0f);
    for (size_t i = 0; i < n; i++) {
        if (d.n == S_DEFER_MAX)
            s_defer_flush(&st, &d);
        s_gather_add(&st, rays[i], &d, &sum);
    }
    s_defer_flush(&st, &d);
    return sum;
}

void pf_render_ctx_init(pf_render_ctx_t *ctx, const pf_frame_t *frame, const pf_settings_t *settings)
{
    memset(ctx, 0, sizeof *ctx);
    ctx->scene = frame->scene;
    ctx->accel = frame->accel;
    ctx->lights = frame->lights;
    ctx->maps = &frame->maps;
    ctx->texels = frame->texels;
    ctx->settings = *settings;
    ctx->camera = pf_camera_make(&frame->scene->camera, settings->width, settings->height);
    ctx->terms = PF_TERM_ALL;
    ctx->shrink2 = pf_pass_shrink2(settings->pass);
}

/* Filtering the first gather: see render/filter.c. */

/* Camera sample s of pixel (px, py) (s < spp: one of its own; beyond, an
 * edge pixel's extra sample from its strata e): starts the sample's stream
 * in st and returns its ray through the film position *film receives. */
static pf_ray_t s_camera_sample(s_state *st, const pf_pattern_t *pt, int px, int py, int s,
                                const pf_edge_strata_t *e, pf_film_t *film)
{
    st->pixel = (uint64_t)py * (uint64_t)st->ctx->camera.width + (uint64_t)px;
    st->sample = (uint32_t)s;
    return pf_pixel_sample(st->ctx, pt, px, py, s, e, &st->rng, film);
}

/* The end of a camera ray's primary path as s_radiance follows it (mirrors,
 * glass refracting near the eye or reflecting totally) when that is a
 * diffuse surface the final gather serves: the material, with the hit in *h,
 * its camera-facing normals in *nf and *ns, the path's length in *length and
 * its scattering events there in *events (render/depth.h); NULL otherwise. */
static const pf_material_t *s_primary_hit(const pf_render_ctx_t *c, pf_ray_t ray, pf_hit_t *h, pf_vec3 *nf,
                                          pf_vec3 *ns, float *length, int *events)
{
    *length = 0.0f;
    for (int depth = 0; pf_accel_intersect(c->accel, &ray, INFINITY, h); depth++) {
        *events = depth + 1;
        pf_material_t mt = pf_material_at(c->scene, h);
        const pf_material_t *m = &mt;
        pf_shade_hit(c->scene, m, h, pf_neg(ray.d));
        *length += h->t;
        pf_vec3 wo = pf_neg(ray.d);
        *nf = pf_face_forward(h->ng, wo);
        *ns = pf_dot(h->ng, *nf) > 0.0f ? h->ns : pf_neg(h->ns);
        if (m->type == PF_MAT_DIFFUSE || pf_mat_coated(m) || pf_mat_difftrans(m))
            return pf_mat_nonspecular(m) && !pf_is_black(m->kd) ? &c->scene->mats[h->mat] : NULL;
        if (depth >= c->settings.max_depth)
            return NULL;
        if (pf_mat_rough(m) || pf_mat_rough_glass(m))
            return NULL; /* a random branch from here on */
        pf_vec3 wi = pf_reflect(wo, *ns);
        if (pf_mat_dielectric(m)) {
            pf_dielectric_t g = pf_dielectric_at(m, ray.d, h->ng, wo, *ns);
            if (g.can_refract && depth >= S_GLASS_SPLIT_DEPTH)
                return NULL; /* a random branch from here on */
            if (g.can_refract)
                wi = g.wt;
        }
        ray = pf_spawn_ray(h, wi);
    }
    return NULL;
}

/* A pixel's width at the end of a primary path through film position
 * (fx, fy) ending at p (normal nf), with *base_out the path's length times
 * the pixel's angle (its width across the line of sight): the distance to
 * where the paths one pixel to the right and one down end on the same
 * surface (mirrors and glass spread them far beyond the path's length times
 * the pixel's angle), at least that length times the angle and at most
 * S_FOOT_MAX times it. The neighbouring paths leave from the same lens
 * point as the sample's. */
#define S_FOOT_MAX 32.0f
static float s_footprint(const pf_render_ctx_t *c, const pf_film_t *film, pf_vec3 p, pf_vec3 nf, float length,
                         float *base_out)
{
    float base = length * 2.0f * c->camera.tan_half_v / (float)c->camera.height;
    float foot = base;
    *base_out = base;
    for (int k = 0; k < 2; k++) {
        pf_ray_t ray = pf_camera_ray_lens(&c->camera, film->fx + (k == 0 ? 1.0f : 0.0f),
                                          film->fy + (k == 1 ? 1.0f : 0.0f), film->u1, film->u2);
        pf_hit_t h;
        pf_vec3 n2, ns2;
        float len2;
        int events;
        if (!s_primary_hit(c, ray, &h, &n2, &ns2, &len2, &events) || pf_dot(n2, nf) < PF_FILTER_COS)
            continue;
        foot = fmaxf(foot, pf_len(pf_sub(h.p, p)));
    }
    return fminf(foot, S_FOOT_MAX * base);
}

/* Makes the texel reads d holds and adds the nb samples' gathers (sums) to
 * their surfaces' (owner) in rec. Returns 0, the samples left. */
static int s_record_flush(const s_state *st, s_defer *d, const pf_vec3 *sums, const int *owner, int nb,
                          pf_filter_rec_t *rec)
{
    s_defer_flush(st, d);
    for (int i = 0; i < nb; i++) {
        pf_filter_cluster_t *cl = &rec->c[owner[i]];
        cl->gsum = pf_add(cl->gsum, pf_scale(sums[i], 1.0f / (float)st->ctx->settings.gather));
        cl->count++;
    }
    return 0;
}

/* The first-gather records of pixel (px, py): its samples' surfaces and
 * the sums of their gathers. The gathers' texel reads wait while the next
 * samples are traced (s_defer; up to S_DEFER_MAX samples at a time), so
 * their trips from memory overlap the traces; each sample's gather still
 * reaches its surface's sum in sample order. */
static void s_record_pixel(s_state *st, const pf_pattern_t *pt, int px, int py, pf_filter_rec_t *rec)
{
    const pf_render_ctx_t *c = st->ctx;
    rec->nc = 0;
    s_defer d;
    d.n = 0;
    pf_vec3 sums[S_DEFER_MAX];
    int owner[S_DEFER_MAX], nb = 0;
    for (int s = 0; s < pt->spp; s++) {
        pf_film_t film;
        pf_ray_t ray = s_camera_sample(st, pt, px, py, s, NULL, &film);
        pf_hit_t h;
        pf_vec3 nf, ns;
        float length;
        const pf_material_t *m = s_primary_hit(c, ray, &h, &nf, &ns, &length, &st->events);
        if (!m)
            continue;
        int k = pf_filter_rec_find(rec, h.p, nf);
        if (k == PF_FILTER_MAX_CLUSTERS)
            continue; /* gathers for itself in the render pass */
        if (k == rec->nc) {
            pf_filter_cluster_t *cl = &rec->c[rec->nc++];
            *cl = (pf_filter_cluster_t){ .p = h.p, .n = nf, .gsum = pf_v3s(0.0f), .count = 0 };
            cl->foot = s_footprint(c, &film, h.p, nf, length, &cl->base);
        }
        sums[nb] = pf_v3s(0.0f);
        owner[nb] = k;
        int sky = (c->terms & PF_TERM_INDIRECT) ? pf_direct_sky_mis(c, m, c->settings.gather) : 0;
        s_first_gather_sum(st, &h, nf, ns, sky, &d, &sums[nb++]);
        if (nb == S_DEFER_MAX || c->reads_at_once)
            nb = s_record_flush(st, &d, sums, owner, nb, rec);
    }
    s_record_flush(st, &d, sums, owner, nb, rec);
}

/* A tile in the making: its first-gather records (none when not filtering). */
struct pf_tile_plan {
    const pf_render_ctx_t *ctx;
    pf_pattern_t pt;
    int x0, y0, w, h;
    int R, filter;
    pf_filter_grid_t grid; /* the tile and its border, clipped to the image */
    float *probe;          /* the emitters' edges (pixel_impl.h), or NULL */
    const pf_spp_map_t *map; /* per-pixel samples (adaptive passes), or NULL: pt everywhere */
};

/* Pixel (px, py)'s sampling pattern in plan p: its own count from the map
 * (which must cover it), else the settings' spp. */
static pf_pattern_t s_plan_pattern(const pf_tile_plan_t *p, int px, int py)
{
    const pf_spp_map_t *m = p->map;
    if (!m)
        return p->pt;
    PF_CHECK(px >= m->x0 && px < m->x0 + m->w && py >= m->y0 && py < m->y0 + m->h);
    return pf_pattern_make(m->n[(size_t)(py - m->y0) * (size_t)m->w + (size_t)(px - m->x0)]);
}

static s_state *s_state_new(const pf_render_ctx_t *ctx, int filtering)
{
    s_state *st = malloc(sizeof *st);
    PF_CHECK(st != NULL);
    st->ctx = ctx;
    st->filtering = filtering;
    st->rec = NULL;
    st->caustic_valid = 0;
    st->caustic_hint = INFINITY;
    st->events = 1;
    st->scratch.bounce_limit = 0;
    return st;
}

pf_tile_plan_t *pf_tile_plan_new(const pf_render_ctx_t *ctx, int x0, int y0, int w, int h)
{
    return pf_tile_plan_new_map(ctx, x0, y0, w, h, NULL);
}

pf_tile_plan_t *pf_tile_plan_new_map(const pf_render_ctx_t *ctx, int x0, int y0, int w, int h,
                                     const pf_spp_map_t *map)
{
    pf_tile_plan_t *p = calloc(1, sizeof *p);
    PF_CHECK(p != NULL);
    p->ctx = ctx;
    p->map = map ? map : ctx->spp_map;
    p->pt = pf_pattern_make(ctx->settings.spp);
    p->x0 = x0, p->y0 = y0, p->w = w, p->h = h;
    p->R = ctx->settings.gather_filter;
    p->filter = p->R > 0 && ctx->settings.gather > 0 && (ctx->terms & PF_TERM_INDIRECT) &&
                !(ctx->terms & PF_TERM_PHOTONMAP);
    if (p->filter)
        pf_filter_grid_init(&p->grid, p->R, x0, y0, w, h, ctx->camera.width, ctx->camera.height);
    p->probe = pf_edges_probe(ctx, x0, y0, w, h);
    return p;
}

int pf_tile_plan_record_rows(const pf_tile_plan_t *p) { return p->filter ? p->grid.rh : 0; }

/* Records row `row` of plan `user`'s grid (pf_filter_grid_record_row). */
static void s_record_row(void *user, int row)
{
    pf_tile_plan_t *p = user;
    s_state *st = s_state_new(p->ctx, 0);
    int py = p->grid.ry0 + row;
    for (int px = p->grid.rx0; px < p->grid.rx0 + p->grid.rw; px++) {
        pf_pattern_t pt = s_plan_pattern(p, px, py);
        s_record_pixel(st, &pt, px, py, pf_filter_grid_at(&p->grid, px, py));
    }
    free(st);
}

void pf_tile_plan_record_row(pf_tile_plan_t *p, int row) { pf_filter_grid_record_row(&p->grid, row, s_record_row, p); }

void pf_tile_plan_render_row(pf_tile_plan_t *p, int row, float *out)
{
    const pf_render_ctx_t *ctx = p->ctx;
    if (p->filter) {
        /* the record rows this row's filter reads: R above to R below */
        int first = p->y0 + row - p->R - p->grid.ry0, last = p->y0 + row + p->R - p->grid.ry0;
        for (int r = first > 0 ? first : 0; r <= last && r < p->grid.rh; r++)
            pf_tile_plan_record_row(p, r);
    }
    s_state *st = s_state_new(ctx, p->filter);
    int py = p->y0 + row;
    for (int x = 0; x < p->w; x++) {
        int px = p->x0 + x;
        if (p->filter) {
            st->rec = pf_filter_grid_at(&p->grid, px, py);
            pf_filter_gathers(&p->grid, px, py, st->gf);
        }
        double acc[3] = { 0, 0, 0 };
        st->caustic_valid = 0;
        /* on an emitter's edge, PF_EDGE_SAMPLES samples more (pixel_impl.h) */
        int edge = pf_edges_pixel(p->probe, p->x0, p->y0, p->w, px, py);
        pf_pattern_t pt = s_plan_pattern(p, px, py);
        int n = pt.spp + (edge ? PF_EDGE_SAMPLES : 0);
        pf_edge_strata_t strata;
        if (edge)
            pf_edges_strata(ctx, px, py, &strata);
        for (int s = 0; s < n; s++) {
            pf_film_t film;
            pf_ray_t ray = s_camera_sample(st, &pt, px, py, s, &strata, &film);
            pf_vec3 L = s_radiance(st, ray, 0, pf_v3s(1.0f), 1, 1);
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
        float *o = &out[3 * (size_t)x];
        for (int k = 0; k < 3; k++)
            o[k] = (float)(acc[k] / n);
    }
    free(st);
}

void pf_tile_plan_free(pf_tile_plan_t *p)
{
    if (!p)
        return;
    pf_filter_grid_free(&p->grid);
    free(p->probe);
    free(p);
}

void pf_render_tile(const pf_render_ctx_t *ctx, int x0, int y0, int w, int h, float *out)
{
    pf_render_tile_cost(ctx, x0, y0, w, h, out, NULL);
}

void pf_render_tile_cost(const pf_render_ctx_t *ctx, int x0, int y0, int w, int h, float *out, pf_tile_cost_t *cost)
{
    double t0 = cost ? pf_now() : 0.0;
    pf_tile_plan_t *p = pf_tile_plan_new(ctx, x0, y0, w, h);
    for (int row = 0; row < pf_tile_plan_record_rows(p); row++)
        pf_tile_plan_record_row(p, row);
    double t1 = cost ? pf_now() : 0.0;
    for (int row = 0; row < h; row++)
        pf_tile_plan_render_row(p, row, out + 3 * (size_t)row * (size_t)w);
    if (cost) {
        double t2 = pf_now();
        cost->record_s += t1 - t0;
        cost->render_s += t2 - t1;
        cost->record_samples += (uint64_t)p->grid.rw * (uint64_t)p->grid.rh * (uint64_t)p->pt.spp;
        cost->samples += (uint64_t)w * (uint64_t)h * (uint64_t)p->pt.spp;
    }
    pf_tile_plan_free(p);
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
