/* direct.c: direct light at a camera path's non-specular point (see
 * direct_impl.h): light samples to emitters chosen by power, a shadow ray to
 * each distant light, and the MIS weights that share an emitter between
 * light sampling and the BSDF or gather rays that may hit it (power
 * heuristic). */
#include "render/direct_impl.h"

#include <math.h>

#include "accel/accel.h"
#include "base/sampling.h"
#include "light/light.h"
#include "material/bsdf.h"
#include "material/coated.h"
#include "material/difftrans.h"
#include "material/ggx.h"
#include "render/render.h"

float pf_mis_power(float na, float a, float nb, float b)
{
    float x = na * a, y = nb * b;
    return x * x / (x * x + y * y);
}

/* Shadow test between a hit and the light point at distance dist along wi.
 * The ray leaves from the offset origin aimed at the light point itself (the
 * offset moves the origin off the line from the hit point), and stops short
 * of it by more than that point's rounding, so the emitter never occludes
 * itself, at any scale or distance from the origin. A distant light's
 * dist is INFINITY: the ray must escape. */
static int s_visible(const pf_accel_t *accel, const pf_hit_t *h, pf_vec3 wi, float dist)
{
    if (isinf(dist)) { /* a distant light: nothing may lie ahead */
        pf_ray_t r = pf_spawn_ray(h, wi);
        return !pf_accel_occluded(accel, &r, INFINITY);
    }
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

/* One light connection's radiance towards wo at a non-specular hit: f cos
 * Le / pdf, zero when occluded. A rough conductor's, a rough coat's lobe
 * and a Phong lobe are weighted by MIS against its BSDF ray when `recurse`
 * says that ray is traced (nl light samples against one); the base (the
 * Lambertian part) is light sampling's alone, and so is a delta light (pdf 0). At a diffuse point whose ng > 0
 * cosine-distributed gather rays count the sky they see (pf_direct_sky_mis), a sky
 * sample is weighted by MIS against them. back: a diffuse transmitter's far
 * side receives the light (about -ns). */
static pf_vec3 s_connect(const pf_render_ctx_t *c, const pf_hit_t *h, const pf_material_t *m, pf_vec3 nf, pf_vec3 ns,
                         pf_vec3 wo, const pf_light_conn_t *lc, int nl, int recurse, int ng, int back)
{
    pf_vec3 sn = back ? pf_neg(ns) : ns, sf = back ? pf_neg(nf) : nf; /* the side the light falls on */
    float cos_x = pf_dot(lc->wi, sn);
    if (cos_x <= 0.0f || pf_dot(lc->wi, sf) <= 0.0f)
        return pf_v3s(0.0f);
    int mis = recurse && lc->pdf > 0.0f;
    pf_vec3 f;
    float w = 1.0f;
    if (m->type == PF_MAT_CONDUCTOR) {
        f = pf_conductor_eval(m, ns, wo, lc->wi);
        if (mis)
            w = pf_mis_power((float)nl, lc->pdf, 1.0f, pf_conductor_pdf(m, ns, wo, lc->wi));
    } else if (pf_mat_difftrans(m)) {
        f = pf_difftrans_eval(m, ns, wo, lc->wi);
    } else {
        f = pf_brdf_eval(m, ns, lc->wi, wo);
        if (ng > 0 && isinf(lc->dist) && lc->pdf > 0.0f) /* the sky, against ng gather rays */
            w = pf_mis_power((float)nl, lc->pdf, (float)ng, cos_x * PF_INV_PI);
        if (pf_mat_glossy(m) && mis && !pf_is_black(f)) {
            /* The Phong lobe against the lobe's own recursive ray (the gather
             * rays serve the Lambertian part only): each part its own weight. */
            pf_vec3 fp = pf_phong_eval(m, ns, lc->wi, wo);
            float wp = pf_mis_power((float)nl, lc->pdf, 1.0f, pf_phong_pdf_dir(m, ns, lc->wi, wo));
            f = pf_add(pf_scale(m->kd, PF_INV_PI * w), pf_scale(fp, wp));
            w = 1.0f;
        }
        if (pf_mat_coated(m)) {
            pf_coated_f_t cf = pf_coated_eval(m, ns, wo, lc->wi);
            float wc = mis ? pf_mis_power((float)nl, lc->pdf, 1.0f, cf.coat_pdf) : 1.0f;
            f = pf_add(cf.base, pf_v3s(cf.coat * wc));
        }
    }
    if (pf_is_black(f) || !s_visible(c->accel, h, lc->wi, lc->dist))
        return pf_v3s(0.0f);
    return pf_scale(pf_mul(f, lc->weight), cos_x * w);
}

/* Direct light at a non-specular hit: light_samples shadow rays to emitters
 * chosen by power, and one to each distant light (see s_connect for MIS and
 * ng). A diffuse transmitter takes as many on each side, each set counting
 * only the light its side's hemisphere receives (the sky sampled about that
 * side's normal), so a light behind the sheet shines through. */
pf_vec3 pf_direct_light(const pf_render_ctx_t *c, pf_rng_t *rng, const pf_hit_t *h, const pf_material_t *m, pf_vec3 nf,
                        pf_vec3 ns, pf_vec3 wo, int recurse, int ng)
{
    int n = c->settings.light_samples > 0 ? c->settings.light_samples : 1;
    pf_vec3 sum = pf_v3s(0.0f);
    for (int i = 0; i < (pf_mat_difftrans(m) ? 2 * n : n); i++) {
        float u[3] = { pf_rng_float(rng), pf_rng_float(rng), pf_rng_float(rng) };
        pf_light_conn_t lc;
        int back = i >= n;
        if (pf_lights_sample_direct_at(c->lights, c->scene, h->p, back ? pf_neg(ns) : ns, u, &lc))
            sum = pf_add(sum, s_connect(c, h, m, nf, ns, wo, &lc, n, recurse, ng, back));
    }
    sum = pf_scale(sum, 1.0f / (float)n);
    for (size_t i = 0; i < pf_lights_distant_count(c->lights); i++) {
        pf_light_conn_t lc;
        pf_lights_distant(c->lights, c->scene, i, &lc);
        for (int back = 0; back <= pf_mat_difftrans(m); back++)
            sum = pf_add(sum, s_connect(c, h, m, nf, ns, wo, &lc, n, recurse, 0, back));
    }
    return sum;
}

/* The radiance a near gather ray's end y (material m, reflectance kd as
 * the lookup would apply it) leaves towards wo: its direct light sampled
 * (as at a diffuse point of albedo kd) and the rest of its irradiance from
 * its point, E (1 - the point's direct share). A point's irradiance is its
 * photons' over the disc of its support, and from nearer than that the
 * blur shows: the sunlit stripe on a chair's shell, seen from its rim a
 * few centimetres away, read a tenth of its irradiance at 1M photons
 * (bench/pathref's one-bounce light there). */
pf_vec3 pf_direct_near_end(const pf_render_ctx_t *c, pf_rng_t *rng, const pf_hit_t *h, const pf_material_t *m,
                           pf_vec3 kd, pf_vec3 nf, pf_vec3 ns, pf_vec3 wo)
{
    pf_material_t md = *m;
    md.type = PF_MAT_DIFFUSE;
    md.kd = kd;
    md.ks = pf_v3s(0.0f);
    pf_vec3 l = pf_direct_light(c, rng, h, &md, nf, ns, wo, 0, 0);
    const pf_photon_maps_t *pm = c->maps;
    const pf_photon_t *q = pf_irradiance_lookup_point(pm->irradiance, pm->irradiance_r2, c->accel, h->p, nf);
    if (!q)
        return l;
    pf_vec3 e = pf_scale(pf_photon_power(q), 1.0f - pf_irradiance_direct_share(q));
    return pf_add(l, pf_scale(pf_mul(kd, e), PF_INV_PI));
}

/* The sky a gather ray sees straight from its diffuse point, weighted by MIS
 * against that point's light samples (s_connect's other half). */
pf_vec3 pf_direct_gather_sky(const pf_render_ctx_t *c, pf_vec3 ns, int ng, pf_vec3 d)
{
    float pl; /* its pdf from the same map lookup */
    pf_vec3 sky = pf_lights_sky_mis(c->lights, ns, d, &pl);
    float cos = pf_dot(d, ns);
    if (pf_is_black(sky) || !(cos > 0.0f))
        return pf_v3s(0.0f);
    int nl = c->settings.light_samples > 0 ? c->settings.light_samples : 1;
    return pf_scale(sky, pf_mis_power((float)ng, cos * PF_INV_PI, (float)nl, pl));
}

/* The gather rays at a diffuse point of material m that count the sky they
 * see directly (MIS against its light samples): its ng rays when the point
 * is plainly diffuse and both direct light and the gather are rendered,
 * else 0 (the sky is light sampling's alone). */
int pf_direct_sky_mis(const pf_render_ctx_t *c, const pf_material_t *m, int ng)
{
    unsigned both = PF_TERM_DIRECT | PF_TERM_INDIRECT;
    return m->type == PF_MAT_DIFFUSE && (c->terms & both) == both ? ng : 0;
}

