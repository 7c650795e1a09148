/* coated.c: the coated diffuse material; see coated.h for the model.
 *
 * The rough coat's interface is tabulated on a grid of 33 cosines x 17
 * alphas x 9 indices (eta 1 to 3; each index's slice built on first use):
 * its reflection albedo A and transmitted fraction from outside and its
 * reflection albedo from inside, each the mean visible-normal sampling
 * weight over a 12 x 12 stratified grid, read by trilinear interpolation. The
 * per-material constants B (the mean of (1 - A) T over cosine-weighted
 * directions) and r (the base's light turned back by the coat) are
 * quadratures over that table; they are kept in a small per-thread cache
 * keyed by (alpha, ior, thickness), so they are a pure function of the
 * material and every thread computes the same bits. */
#include "material/coated.h"

#include <sched.h>
#include <string.h>

#include "base/sampling.h"
#include "material/bsdf.h"
#include "material/ggx.h"

enum { S_NMU = 33, S_NAL = 17, S_NETA = 9, S_GRID = 12, S_QUAD = 64 };
#define S_ETA_LO 1.0f
#define S_ETA_HI 3.0f

/* The three tables, per index: the coat's reflection albedo A and the
 * fraction it lets in, T_in, both by the outside cosine; the underside's
 * reflection albedo R (total internal reflection included), by the inside
 * cosine. Each index's slice is built the first time it is read. */
enum { S_A = 0, S_TIN = 1, S_RINT = 2 };
static float s_table[S_NETA][3][S_NAL][S_NMU];
/* Per slice: 0 not built, 1 being built, 2 built (the builder's writes
 * published by the release store). */
static int s_state[S_NETA];

/* Single scattering off the rough interface from the side of wo's cosine
 * cos_o, eta the index beyond over the index here: the mean visible-normal
 * sampling weights G2 / G1 of the reflected (*refl, Fresnel-weighted) and
 * transmitted (*tran) branches; samples that leave on the wrong side of
 * the macrosurface are lost, as in pbrt's single-scattering interface. */
static void s_interface(float cos_o, float alpha, float eta, float *refl, float *tran)
{
    pf_vec3 wo = pf_v3(sqrtf(fmaxf(0.0f, 1.0f - cos_o * cos_o)), 0.0f, cos_o);
    double r = 0.0, t = 0.0;
    for (int i = 0; i < S_GRID; i++)
        for (int j = 0; j < S_GRID; j++) {
            float u1 = ((float)i + 0.5f) / S_GRID, u2 = ((float)j + 0.5f) / S_GRID;
            pf_vec3 wm = pf_ggx_sample_vn(wo, alpha, u1, u2);
            float c = pf_dot(wo, wm);
            if (c <= 0.0f)
                continue;
            float f = pf_fresnel_dielectric(c, 1.0f, eta), g1 = pf_ggx_g1(wo, alpha);
            pf_vec3 wi = pf_sub(pf_scale(wm, 2.0f * c), wo), wt;
            if (wi.z > 0.0f)
                r += f * pf_ggx_g2(wo, wi, alpha) / g1;
            if (f < 1.0f && pf_refract(wo, wm, 1.0f / eta, &wt) && wt.z < 0.0f)
                t += (1.0f - f) * pf_ggx_g2(wo, wt, alpha) / g1;
        }
    *refl = (float)(r / (S_GRID * S_GRID));
    *tran = (float)(t / (S_GRID * S_GRID));
}

static float s_node_eta(int e) { return S_ETA_LO + (S_ETA_HI - S_ETA_LO) * (float)e / (S_NETA - 1); }

static void s_build_slice(int e)
{
    float eta = s_node_eta(e);
    for (int a = 0; a < S_NAL; a++) {
        float alpha = fmaxf((float)a / (S_NAL - 1), PF_GGX_SMOOTH);
        for (int k = 0; k < S_NMU; k++) {
            float mu = fmaxf((float)k / (S_NMU - 1), 1e-4f), unused;
            s_interface(mu, alpha, eta, &s_table[e][S_A][a][k], &s_table[e][S_TIN][a][k]);
            s_interface(mu, alpha, 1.0f / eta, &s_table[e][S_RINT][a][k], &unused);
        }
    }
}

/* Builds slice e once: the first thread to claim it builds, the others
 * wait (a slice takes a few tens of milliseconds, once per process). */
static void s_slice_ready(int e)
{
    if (__atomic_load_n(&s_state[e], __ATOMIC_ACQUIRE) == 2)
        return;
    int expect = 0;
    if (__atomic_compare_exchange_n(&s_state[e], &expect, 1, 0, __ATOMIC_ACQ_REL, __ATOMIC_ACQUIRE)) {
        s_build_slice(e);
        __atomic_store_n(&s_state[e], 2, __ATOMIC_RELEASE);
        return;
    }
    while (__atomic_load_n(&s_state[e], __ATOMIC_ACQUIRE) != 2)
        sched_yield();
}

int pf_coated_smooth(const pf_material_t *m) { return m->alpha < PF_GGX_SMOOTH; }

static float s_eta(float ior) { return fminf(fmaxf(ior, S_ETA_LO), S_ETA_HI); }

/* Table `which` at cosine mu (outside, or inside for S_RINT), rough alpha,
 * index eta in [S_ETA_LO, S_ETA_HI]: trilinear, reading only the slices
 * with weight. */
static float s_lookup(int which, float mu, float alpha, float eta)
{
    float fe = (eta - S_ETA_LO) / (S_ETA_HI - S_ETA_LO) * (S_NETA - 1);
    float fa = fminf(alpha, 1.0f) * (S_NAL - 1), fm = fminf(fmaxf(mu, 0.0f), 1.0f) * (S_NMU - 1);
    int e0 = (int)fe, a0 = (int)fa, m0 = (int)fm;
    e0 = e0 < S_NETA - 2 ? e0 : S_NETA - 2;
    a0 = a0 < S_NAL - 2 ? a0 : S_NAL - 2;
    m0 = m0 < S_NMU - 2 ? m0 : S_NMU - 2;
    float te = fe - (float)e0, ta = fa - (float)a0, tm = fm - (float)m0;
    float v = 0.0f;
    for (int i = 0; i < 2; i++) {
        float we = i ? te : 1.0f - te;
        if (we == 0.0f)
            continue;
        s_slice_ready(e0 + i);
        for (int j = 0; j < 2; j++)
            for (int k = 0; k < 2; k++)
                v += we * (j ? ta : 1.0f - ta) * (k ? tm : 1.0f - tm) * s_table[e0 + i][which][a0 + j][m0 + k];
    }
    return v;
}

float pf_coat_albedo(float cos_o, float alpha, float eta)
{
    cos_o = fminf(fmaxf(cos_o, 0.0f), 1.0f);
    eta = s_eta(eta);
    if (alpha < PF_GGX_SMOOTH)
        return pf_fresnel_dielectric(cos_o, 1.0f, eta);
    return s_lookup(S_A, cos_o, alpha, eta);
}

/* The fraction of light from outside at cosine cos_o that enters the coat. */
static float s_coat_in(float cos_o, float alpha, float eta)
{
    if (alpha < PF_GGX_SMOOTH)
        return 1.0f - pf_fresnel_dielectric(fminf(fmaxf(cos_o, 0.0f), 1.0f), 1.0f, eta);
    return s_lookup(S_TIN, cos_o, alpha, eta);
}

/* The cosine inside the coat of a direction of outside cosine cos_o. */
static float s_cos_in(float cos_o, float eta) { return sqrtf(fmaxf(0.0f, 1.0f - (1.0f - cos_o * cos_o) / (eta * eta))); }

/* One crossing's attenuation at inside cosine c. */
static float s_tr(float thickness, float c) { return thickness > 0.0f ? expf(-thickness / fmaxf(c, 1e-6f)) : 1.0f; }

/* The per-material constants: B = int 2 mu (1 - A) T, r (see coated.h). */
typedef struct s_consts {
    float alpha, ior, thickness;
    float b, r, eta;
    int valid;
} s_consts;

static void s_compute(s_consts *k)
{
    float eta = s_eta(k->ior), t = k->thickness;
    float mu_c = sqrtf(fmaxf(0.0f, 1.0f - 1.0f / (eta * eta)));
    int smooth = k->alpha < PF_GGX_SMOOTH;
    double b = 0.0, r_tir = 0.0, r_fr = 0.0;
    for (int i = 0; i < S_QUAD; i++) {
        float mu = ((float)i + 0.5f) / S_QUAD; /* outside cosine */
        float tr = s_tr(t, s_cos_in(mu, eta));
        b += 2.0 * mu * s_coat_in(mu, k->alpha, eta) * tr;
        if (smooth) {
            /* The underside by the outside cosine (eta^2 mu_i dmu_i = mu dmu):
             * total internal reflection below mu_c, above it Fresnel, which
             * is the same from both sides; exact with thickness 0. */
            r_fr += 2.0 * mu * pf_fresnel_dielectric(mu, 1.0f, eta) * tr * tr;
            float mi = mu_c * mu;
            float ti = s_tr(t, mi);
            r_tir += 2.0 * mi * ti * ti * mu_c;
        } else { /* the rough underside's own table, by the inside cosine */
            float ti = s_tr(t, mu);
            r_tir += 2.0 * mu * s_lookup(S_RINT, mu, k->alpha, eta) * ti * ti;
        }
    }
    k->b = (float)(b / S_QUAD);
    k->r = (float)((r_tir + r_fr / (eta * eta)) / S_QUAD);
    k->eta = eta;
}

/* The constants of m, from this thread's cache. */
static const s_consts *s_get(const pf_material_t *m)
{
    static _Thread_local s_consts cache[64];
    uint32_t bits[3];
    memcpy(&bits[0], &m->alpha, 4);
    memcpy(&bits[1], &m->ior, 4);
    memcpy(&bits[2], &m->thickness, 4);
    uint32_t h = (bits[0] * 0x9e3779b1u) ^ (bits[1] * 0x85ebca77u) ^ (bits[2] * 0xc2b2ae3du);
    s_consts *k = &cache[h >> 26];
    if (!k->valid || k->alpha != m->alpha || k->ior != m->ior || k->thickness != m->thickness) {
        k->alpha = m->alpha;
        k->ior = m->ior;
        k->thickness = m->thickness;
        s_compute(k);
        k->valid = 1;
    }
    return k;
}

/* The base lobe's factor for one direction: T_in T (1 - A for a smooth coat). */
static float s_base_dir(const pf_material_t *m, const s_consts *k, float cos_w)
{
    return s_coat_in(cos_w, m->alpha, k->eta) * s_tr(m->thickness, s_cos_in(cos_w, k->eta));
}

/* kd / (pi eta^2 (1 - kd r)) per channel. */
static pf_vec3 s_base_scale(const pf_material_t *m, const s_consts *k)
{
    float s = PF_INV_PI / (k->eta * k->eta);
    return pf_v3(m->kd.x * s / (1.0f - m->kd.x * k->r), m->kd.y * s / (1.0f - m->kd.y * k->r),
                 m->kd.z * s / (1.0f - m->kd.z * k->r));
}

pf_vec3 pf_coated_base_albedo(const pf_material_t *m, float cos_o)
{
    const s_consts *k = s_get(m);
    if (cos_o <= 0.0f)
        return pf_v3s(0.0f);
    return pf_scale(s_base_scale(m, k), PF_PI * k->b * s_base_dir(m, k, cos_o));
}

pf_vec3 pf_coated_kd(const pf_material_t *m, float cos_o, int with_coat)
{
    pf_vec3 kd = pf_coated_base_albedo(m, cos_o);
    return with_coat ? pf_add(kd, pf_v3s(pf_coat_albedo(cos_o, m->alpha, m->ior))) : kd;
}

static pf_vec3 s_local(pf_vec3 w, pf_vec3 t, pf_vec3 b, pf_vec3 n)
{
    return pf_v3(pf_dot(w, t), pf_dot(w, b), pf_dot(w, n));
}

/* The rough coat's f and visible-normal pdf for local lo, li (z > 0). */
static void s_coat_local(const pf_material_t *m, float eta, pf_vec3 lo, pf_vec3 li, float *f, float *pdf)
{
    *f = *pdf = 0.0f;
    pf_vec3 h = pf_add(lo, li);
    float hl = pf_len(h);
    if (!(hl > 0.0f))
        return;
    pf_vec3 wm = pf_scale(h, 1.0f / hl);
    float c = pf_dot(lo, wm);
    if (c <= 0.0f)
        return;
    float d = pf_ggx_d(wm, m->alpha);
    *f = pf_fresnel_dielectric(c, 1.0f, eta) * d * pf_ggx_g2(lo, li, m->alpha) / (4.0f * lo.z * li.z);
    *pdf = pf_ggx_g1(lo, m->alpha) * d / (4.0f * lo.z);
}

pf_coated_f_t pf_coated_eval(const pf_material_t *m, pf_vec3 n, pf_vec3 wo, pf_vec3 wi)
{
    pf_coated_f_t r = { pf_v3s(0.0f), 0.0f, 0.0f };
    float co = pf_dot(wo, n), ci = pf_dot(wi, n);
    if (co <= 0.0f || ci <= 0.0f)
        return r;
    const s_consts *k = s_get(m);
    r.base = pf_scale(s_base_scale(m, k), s_base_dir(m, k, co) * s_base_dir(m, k, ci));
    if (!pf_coated_smooth(m)) {
        pf_vec3 t, b;
        pf_basis(n, &t, &b);
        s_coat_local(m, k->eta, s_local(wo, t, b, n), s_local(wi, t, b, n), &r.coat, &r.coat_pdf);
    }
    return r;
}

pf_vec3 pf_coated_f(const pf_material_t *m, pf_vec3 n, pf_vec3 wo, pf_vec3 wi)
{
    pf_coated_f_t f = pf_coated_eval(m, n, wo, wi);
    return pf_add(f.base, pf_v3s(f.coat));
}

float pf_coated_coat_prob(const pf_material_t *m, float cos_o)
{
    const s_consts *k = s_get(m);
    float a = pf_coat_albedo(cos_o, m->alpha, k->eta);
    pf_vec3 base = pf_coated_base_albedo(m, cos_o);
    float wb = (base.x + base.y + base.z) / 3.0f;
    return a + wb > 0.0f ? a / (a + wb) : 1.0f;
}

float pf_coated_pdf(const pf_material_t *m, pf_vec3 n, pf_vec3 wo, pf_vec3 wi)
{
    float co = pf_dot(wo, n), ci = pf_dot(wi, n);
    if (co <= 0.0f || ci <= 0.0f)
        return 0.0f;
    float pc = pf_coated_coat_prob(m, co);
    pf_coated_f_t f = pf_coated_eval(m, n, wo, wi);
    return pc * f.coat_pdf + (1.0f - pc) * ci * PF_INV_PI;
}

int pf_coated_sample_coat(const pf_material_t *m, pf_vec3 n, pf_vec3 wo, float u1, float u2, pf_vec3 *wi,
                          float *weight, float *pdf)
{
    float co = pf_dot(wo, n);
    if (co <= 0.0f)
        return 0;
    float eta = s_eta(m->ior);
    if (pf_coated_smooth(m)) {
        *wi = pf_reflect(wo, n);
        *weight = pf_fresnel_dielectric(co, 1.0f, eta);
        *pdf = 0.0f;
        return 1;
    }
    float c, g;
    if (!pf_ggx_sample_reflect(n, wo, m->alpha, u1, u2, wi, &c, &g, pdf))
        return 0;
    *weight = pf_fresnel_dielectric(c, 1.0f, eta) * g;
    return 1;
}

int pf_coated_sample(const pf_material_t *m, pf_vec3 n, pf_vec3 wo, float u0, float u1, float u2, pf_vec3 *wi,
                     pf_vec3 *weight, float *pdf, int *coat_lobe)
{
    float co = pf_dot(wo, n);
    if (co <= 0.0f)
        return 0;
    float pc = pf_coated_coat_prob(m, co);
    *coat_lobe = u0 < pc;
    if (*coat_lobe) {
        float w, p;
        if (!pf_coated_sample_coat(m, n, wo, u1, u2, wi, &w, &p))
            return 0;
        if (pf_coated_smooth(m)) { /* the mirror, a delta: its own weight over its choice */
            *weight = pf_v3s(w / pc);
            *pdf = 0.0f;
            return 1;
        }
    } else {
        *wi = pf_to_world(pf_sample_cosine(u1, u2), n);
    }
    float ci = pf_dot(*wi, n);
    *pdf = pf_coated_pdf(m, n, wo, *wi);
    if (ci <= 0.0f || !(*pdf > 0.0f))
        return 0;
    *weight = pf_scale(pf_coated_f(m, n, wo, *wi), ci / *pdf);
    return 1;
}
