/* pbrt_mat.c: the pbrt-v4 reader's materials, textures and lights, mapped
 * onto the scene model (scene/scene.h). It owns nothing: the records live in
 * the load's pf_pbrt_t. Single-threaded.
 *
 * Materials (each distinct (material, area light) pair becomes one scene
 * material, named after the pbrt material):
 *   diffuse             DIFFUSE kd = reflectance
 *   coateddiffuse       COATED kd = reflectance, ior = eta (below 1: 1,
 *                       warned), alpha from the roughness (below; u != v:
 *                       their mean, warned), thickness (default 0.01); a
 *                       medium albedo is warned as ignored (material/coated.h
 *                       is the analytic model of pbrt's layered BSDF)
 *   conductor           CONDUCTOR eta, k per channel (pbrt's spectra at the
 *                       RGB primaries), or "reflectance" r: eta 1,
 *                       k = 2 sqrt(r) / sqrt(1 - r); alpha from the
 *                       roughness (below); anisotropic u != v: their mean,
 *                       warned
 *   coatedconductor     CONDUCTOR: the metal under the coat (conductor.eta,
 *                       conductor.k or reflectance over interface.eta, its
 *                       conductor.roughness); the coat's reflection left out,
 *                       warned
 *   dielectric          GLASS ior = eta (a named glass: its index), alpha
 *                       from the roughness (rough glass from 1e-3)
 *   thindielectric      THIN_DIELECTRIC ior = eta
 *   diffusetransmission DIFFUSE_TRANSMISSION kd = scale * reflectance (default
 *                       0.25; a texture: kd_tex), kt = scale * transmittance
 *                       (default 0.25); where kd + kt exceeds 1 both are
 *                       scaled down to sum to 1 (warned: pbrt would make light)
 *   mix                 MIX of its two materials (each added to the scene as
 *                       a material of its own, le 0) with amount (default
 *                       0.5; a float texture: amount_tex); a part that is an
 *                       interface: the other part alone, warned
 *   interface, none     no surface: its shapes are dropped, warned
 *   measured, hair, subsurface, conductors with textured eta or k:
 *                       DIFFUSE grey 0.5, warned as not renderable
 * Textured reflectances (diffuse, coateddiffuse, conductor) and roughness
 * textures (conductor, coateddiffuse) become the material's texture slots,
 * resolved per hit; "normalmap" and "displacement" on any material bend its
 * shading normal (pbrt_maps.c, accel/shading.h).
 * Alpha in pbrt-v4 is TrowbridgeReitz's: sqrt(roughness) when
 * remaproughness (the default), the roughness itself otherwise; pbrt renders
 * alpha < 1e-3 as perfectly smooth, and so warns nothing here.
 *
 * Lights: AreaLightSource "diffuse" gives the emission le = L * scale (or
 * the radiance that makes the shape emit "power" watts, from both sides
 * when two-sided) to the shapes after it, on their front or, with
 * "twosided", on both sides (the material's twosided); LightSource "point" and "spot" become point and spot
 * lights (pbrt's spot falloff is the same smoothstep as light.c's, between
 * cos(coneangle) and cos(coneangle - conedelta)); "distant" becomes a
 * distant light shining from "from" towards "to" (the CTM's linear part
 * turns that direction), irradiance L * scale, times "illuminance" when
 * given (pbrt-v4 normalizes L to one nit, which an RGB L already is here);
 * "infinite" without "filename" becomes a constant sky of radiance L *
 * scale (times illuminance / pi when given); with an image, an image-based
 * sky (pbrt_env.c); the other light types are warned as not rendered yet. */
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "base/reserve.h"
#include "load/pbrt/pbrt_impl.h"

int pf_pbrt_texture(pf_pbrt_t *c, const char *name, const char *type, const char *cls, pf_pbrt_params_t *ps,
                    pf_pbrt_loc_t loc)
{
    int is_float = strcmp(type, "float") == 0;
    if (!is_float && strcmp(type, "spectrum") != 0 && strcmp(type, "color") != 0)
        return pf_pbrt_error(c, PF_EPARSE, loc, "Texture \"%s\": type must be \"float\" or \"spectrum\", not \"%s\"",
                             name, type);
    int id = pf_pbrt_intern(c, name);
    if (id < 0 || pf_reserve((void **)&c->texs, &c->cap_texs, c->ntexs + 1, sizeof *c->texs))
        return pf_pbrt_error(c, PF_ENOMEM, loc, "out of memory");
    int32_t *slot = is_float ? &c->named_ftex[id] : &c->named_stex[id];
    if (*slot >= 0) {
        int rc = pf_pbrt_warn(c, loc, "texture redefined", "Texture \"%s\" is defined again; the later one is used",
                              name);
        if (rc)
            return rc;
    }
    pf_pbrt_tex_t *t = &c->texs[c->ntexs];
    memset(t, 0, sizeof *t);
    t->cls = strdup(cls);
    if (!t->cls)
        return pf_pbrt_error(c, PF_ENOMEM, loc, "out of memory");
    t->name = id;
    t->is_float = is_float;
    t->params = *ps;
    memset(ps, 0, sizeof *ps);
    t->loc = loc;
    *slot = (int32_t)c->ntexs++;
    return PF_OK;
}

static const char *s_mat_types[] = {
    "diffuse", "coateddiffuse", "conductor", "coatedconductor", "dielectric", "thindielectric", "diffusetransmission",
    "mix", "interface", "none", "", "measured", "hair", "subsurface",
};

int pf_pbrt_material(pf_pbrt_t *c, const char *name, const char *type, pf_pbrt_params_t *ps, pf_pbrt_loc_t loc)
{
    int id = -1, rc;
    if (name) {
        if ((rc = pf_pbrt_get_string(c, ps, "type", NULL, &type)))
            return rc;
        if (!type)
            return pf_pbrt_error(c, PF_EPARSE, loc, "MakeNamedMaterial \"%s\" has no \"string type\"", name);
        if ((id = pf_pbrt_intern(c, name)) < 0)
            return pf_pbrt_error(c, PF_ENOMEM, loc, "out of memory");
        if (c->named_mat[id] >= 0) {
            const pf_pbrt_mat_t *m = &c->mats[c->named_mat[id]];
            return pf_pbrt_error(c, PF_EPARSE, loc, "material \"%s\" is defined twice (first at %s:%d)", name,
                                 pf_pbrt_file_name(c, m->loc), m->loc.line);
        }
    }
    size_t k = 0;
    while (k < sizeof s_mat_types / sizeof *s_mat_types && strcmp(s_mat_types[k], type) != 0)
        k++;
    if (k == sizeof s_mat_types / sizeof *s_mat_types)
        return pf_pbrt_error(c, PF_EPARSE, loc, "unknown material type \"%.60s\"", type);
    if (pf_reserve((void **)&c->mats, &c->cap_mats, c->nmats + 1, sizeof *c->mats))
        return pf_pbrt_error(c, PF_ENOMEM, loc, "out of memory");
    pf_pbrt_mat_t *m = &c->mats[c->nmats];
    memset(m, 0, sizeof *m);
    m->type = strdup(type);
    if (!m->type)
        return pf_pbrt_error(c, PF_ENOMEM, loc, "out of memory");
    m->name = id;
    m->params = *ps;
    memset(ps, 0, sizeof *ps);
    m->loc = loc;
    if (id >= 0) {
        c->named_mat[id] = (int32_t)c->nmats;
    } else {
        c->gs.mat_kind = PF_PBRT_MAT_ANON;
        c->gs.mat = (int)c->nmats;
        c->gs.mat_loc = loc;
    }
    c->nmats++;
    return PF_OK;
}

/* ---- converting materials ---- */

/* The material's description for messages: Material "type" "name". */
static void s_what(const pf_pbrt_t *c, const pf_pbrt_mat_t *m, char *out, size_t cap)
{
    if (m->name >= 0)
        snprintf(out, cap, "material \"%.60s\" (%s)", c->names.s[m->name], m->type);
    else
        snprintf(out, cap, "Material \"%s\"", m->type);
}

/* The two alphas of "roughness" / "uroughness" / "vroughness" (remapped by
 * "remaproughness", default true: alpha = sqrt(roughness)). */
static int s_alpha_uv(pf_pbrt_t *c, pf_pbrt_params_t *ps, const char *prefix, const char *what, double *au,
                      double *av)
{
    char n[3][64];
    const char *base[3] = { "roughness", "uroughness", "vroughness" };
    for (int i = 0; i < 3; i++)
        snprintf(n[i], sizeof n[i], "%s%s", prefix, base[i]);
    double r, u, v;
    int remap;
    int rc = pf_pbrt_get_float_tex(c, ps, n[0], 0.0, what, &r, NULL);
    if (rc == PF_OK)
        rc = pf_pbrt_get_float_tex(c, ps, n[1], r, what, &u, NULL);
    if (rc == PF_OK)
        rc = pf_pbrt_get_float_tex(c, ps, n[2], r, what, &v, NULL);
    if (rc == PF_OK)
        rc = pf_pbrt_get_bool(c, ps, "remaproughness", 1, &remap);
    if (rc)
        return rc;
    u = fmax(u, 0.0);
    v = fmax(v, 0.0);
    *au = remap ? sqrt(u) : u;
    *av = remap ? sqrt(v) : v;
    return PF_OK;
}

/* Index of refraction from "eta" (float, spectrum or float texture). */
static int s_eta(pf_pbrt_t *c, pf_pbrt_params_t *ps, const char *name, const char *what, double *eta)
{
    pf_pbrt_param_t *p = pf_pbrt_param(ps, name);
    *eta = 1.5;
    if (!p)
        return PF_OK;
    if (p->type == PF_PBRT_P_SPECTRUM) {
        pf_vec3 v;
        int rc = pf_pbrt_get_color(c, ps, name, PF_PBRT_UNBOUNDED, pf_v3s(1.5f), what, &v, NULL);
        if (rc)
            return rc;
        *eta = v.y;
        if (v.x != v.y || v.y != v.z)
            return pf_pbrt_warn(c, p->loc, "dispersion (ignored)",
                                "%s: eta varies with wavelength; the index at 532 nm (%g) is used", what, v.y);
        return PF_OK;
    }
    int rc = pf_pbrt_get_float_tex(c, ps, name, 1.5, what, eta, NULL);
    if (rc == PF_OK && !(*eta > 0.0))
        rc = pf_pbrt_error(c, PF_ERANGE, p->loc, "%s: eta must be > 0", what);
    return rc;
}

/* Marks every parameter used: for materials approximated as a whole. */
static void s_use_all(pf_pbrt_params_t *ps)
{
    for (size_t i = 0; i < ps->n; i++)
        ps->p[i].used = 1;
}

/* Whether the colour parameter name is a texture. */
static int s_is_texture(pf_pbrt_params_t *ps, const char *name)
{
    for (size_t i = 0; i < ps->n; i++)
        if (strcmp(ps->p[i].name, name) == 0)
            return ps->p[i].type == PF_PBRT_P_TEXTURE;
    return 0;
}

static int s_not_renderable(pf_pbrt_t *c, pf_pbrt_mat_t *m, const char *what, const char *why)
{
    m->m.type = PF_MAT_DIFFUSE;
    m->m.kd = pf_v3s(0.5f);
    s_use_all(&m->params);
    return pf_pbrt_warn(c, m->loc, "material cannot be rendered (grey diffuse)", "%s %s: rendered as grey diffuse 0.5",
                        what, why);
}

static int s_diffuse(pf_pbrt_t *c, pf_pbrt_mat_t *m, const char *what)
{
    m->m.type = PF_MAT_DIFFUSE;
    pf_pbrt_param_t *p = pf_pbrt_param(&m->params, "reflectance");
    if (p && p->type == PF_PBRT_P_TEXTURE) {
        int rc = pf_pbrt_color_texture(c, p, &m->m.kd_tex);
        if (rc || m->m.kd_tex)
            return rc;
    }
    return pf_pbrt_get_color(c, &m->params, "reflectance", PF_PBRT_ALBEDO, pf_v3s(0.5f), what, &m->m.kd, NULL);
}

static int s_coated_diffuse(pf_pbrt_t *c, pf_pbrt_mat_t *m, const char *what)
{
    double au = 0.0, av = 0.0, eta, thickness;
    pf_vec3 albedo = pf_v3s(0.0f);
    int rc = PF_OK, rough_tex = 0;
    pf_pbrt_param_t *p = pf_pbrt_param(&m->params, "reflectance");
    if (p && p->type == PF_PBRT_P_TEXTURE)
        rc = pf_pbrt_color_texture(c, p, &m->m.kd_tex);
    if (rc == PF_OK && !m->m.kd_tex)
        rc = pf_pbrt_get_color(c, &m->params, "reflectance", PF_PBRT_ALBEDO, pf_v3s(0.5f), what, &m->m.kd, NULL);
    if (rc == PF_OK)
        rc = pf_pbrt_rough_texture(c, &m->params, &m->m, &rough_tex);
    if (rc == PF_OK && !rough_tex)
        rc = s_alpha_uv(c, &m->params, "", what, &au, &av);
    if (rc == PF_OK)
        rc = s_eta(c, &m->params, "eta", what, &eta);
    if (rc == PF_OK)
        rc = pf_pbrt_get_float_tex(c, &m->params, "thickness", 0.01, what, &thickness, NULL);
    if (rc == PF_OK && pf_pbrt_param(&m->params, "albedo"))
        rc = pf_pbrt_get_color(c, &m->params, "albedo", PF_PBRT_ALBEDO, pf_v3s(0.0f), what, &albedo, NULL);
    if (rc)
        return rc;
    m->m.type = PF_MAT_COATED;
    m->m.alpha = (float)fmin(0.5 * (au + av), 1.0);
    m->m.ior = (float)fmax(eta, 1.0);
    m->m.thickness = (float)fmax(thickness, 0.0);
    s_use_all(&m->params); /* g, maxdepth, nsamples: the analytic model needs none */
    if (au != av && (rc = pf_pbrt_warn(c, m->loc, "anisotropic roughness (isotropic mean used)",
                                       "%s: alphas %.3g and %.3g; rendered with their mean %.3g", what, au, av,
                                       0.5 * (au + av))))
        return rc;
    if (eta < 1.0 && (rc = pf_pbrt_warn(c, m->loc, "coat index below 1 (clamped)", "%s: eta %.3g rendered as 1",
                                        what, eta)))
        return rc;
    if (!pf_is_black(albedo))
        return pf_pbrt_warn(c, m->loc, "coateddiffuse medium albedo (ignored)",
                            "%s: the scattering medium between coat and base is left out", what);
    return PF_OK;
}

/* A conductor's normal-incidence reflectance from eta/k or reflectance. */
static int s_conductor_f0(pf_pbrt_t *c, pf_pbrt_mat_t *m, const char *prefix, const char *what, int *ok)
{
    char ne[64], nk[64];
    snprintf(ne, sizeof ne, "%seta", prefix);
    snprintf(nk, sizeof nk, "%sk", prefix);
    *ok = 0;
    if (s_is_texture(&m->params, ne) || s_is_texture(&m->params, nk))
        return PF_OK;
    *ok = 1;
    pf_pbrt_param_t *pr = pf_pbrt_param(&m->params, "reflectance");
    if (pr && pr->type == PF_PBRT_P_TEXTURE && !*prefix) { /* resolved per hit (accel/surface.h) */
        int rc = pf_pbrt_color_texture(c, pr, &m->m.refl_tex);
        if (rc || m->m.refl_tex) {
            m->m.eta = pf_v3s(1.0f);
            m->m.k = pf_v3s(pf_conductor_k_of_reflectance(0.5f));
            m->m.ks = pf_v3s(0.5f);
            return rc;
        }
    }
    if (s_is_texture(&m->params, "reflectance"))
        return *ok = 0, PF_OK;
    pf_vec3 eta, k, refl;
    int found = 0;
    int rc = pf_pbrt_get_color(c, &m->params, "reflectance", PF_PBRT_ALBEDO, pf_v3s(0.0f), what, &refl, &found);
    pf_vec3 cu_eta, cu_k;
    pf_pbrt_named_metal("metal-Cu-eta", &cu_eta);
    pf_pbrt_named_metal("metal-Cu-k", &cu_k);
    if (rc == PF_OK)
        rc = pf_pbrt_get_color(c, &m->params, ne, PF_PBRT_UNBOUNDED, cu_eta, what, &eta, NULL);
    if (rc == PF_OK)
        rc = pf_pbrt_get_color(c, &m->params, nk, PF_PBRT_UNBOUNDED, cu_k, what, &k, NULL);
    if (rc)
        return rc;
    if (found) {
        m->m.ks = refl;
        m->m.eta = pf_v3s(1.0f);
        m->m.k = pf_v3(pf_conductor_k_of_reflectance(refl.x), pf_conductor_k_of_reflectance(refl.y),
                       pf_conductor_k_of_reflectance(refl.z));
        return PF_OK;
    }
    m->m.eta = pf_v3(fmaxf(eta.x, 1e-4f), fmaxf(eta.y, 1e-4f), fmaxf(eta.z, 1e-4f));
    m->m.k = pf_vmax(k, pf_v3s(0.0f));
    float n3[3] = { eta.x, eta.y, eta.z }, k3[3] = { k.x, k.y, k.z }, f[3];
    for (int i = 0; i < 3; i++)
        f[i] = ((n3[i] - 1) * (n3[i] - 1) + k3[i] * k3[i]) / ((n3[i] + 1) * (n3[i] + 1) + k3[i] * k3[i]);
    m->m.ks = pf_v3(f[0], f[1], f[2]);
    if (!(eta.x > 0.0f && eta.y > 0.0f && eta.z > 0.0f && k.x >= 0.0f && k.y >= 0.0f && k.z >= 0.0f))
        return pf_pbrt_warn(c, m->loc, "conductor eta <= 0 or k < 0 (clamped)",
                            "%s: eta (%g %g %g), k (%g %g %g) clamped to eta >= 1e-4, k >= 0", what, eta.x, eta.y,
                            eta.z, k.x, k.y, k.z);
    return PF_OK;
}

static int s_conductor(pf_pbrt_t *c, pf_pbrt_mat_t *m, const char *what, int coated)
{
    int ok;
    double au, av;
    int rc = s_conductor_f0(c, m, coated ? "conductor." : "", what, &ok);
    if (rc)
        return rc;
    if (!ok)
        return s_not_renderable(c, m, what, "has textured optical constants");
    m->m.type = PF_MAT_CONDUCTOR;
    if (coated) {
        /* The metal under the coat: its optical constants relative to the
         * coat's index, its own roughness; the coat's reflection is left out
         * (a few per cent where the metal reflects most). */
        double ceta;
        if ((rc = s_eta(c, &m->params, "interface.eta", what, &ceta)) ||
            (rc = s_alpha_uv(c, &m->params, "conductor.", what, &au, &av)))
            return rc;
        if (!m->m.refl_tex) { /* pbrt-v4 divides both forms' constants by the coat's index */
            m->m.eta = pf_vmax(pf_scale(m->m.eta, (float)(1.0 / ceta)), pf_v3s(1e-4f));
            m->m.k = pf_scale(m->m.k, (float)(1.0 / ceta));
        }
        s_use_all(&m->params);
        m->m.alpha = (float)fmin(0.5 * (au + av), 1.0);
        return pf_pbrt_warn(c, m->loc, "coatedconductor (approximated)",
                            "%s: rendered as the metal under the coat (GGX alpha %.3g, its index relative to the "
                            "coat's %.3g); the coat's own reflection is left out",
                            what, (double)m->m.alpha, ceta);
    }
    int rough_tex = 0;
    if ((rc = pf_pbrt_rough_texture(c, &m->params, &m->m, &rough_tex)) || rough_tex)
        return rc;
    if ((rc = s_alpha_uv(c, &m->params, "", what, &au, &av)))
        return rc;
    m->m.alpha = (float)fmin(0.5 * (au + av), 1.0);
    if (au != av && (rc = pf_pbrt_warn(c, m->loc, "anisotropic roughness (isotropic mean used)",
                                       "%s: alphas %.3g and %.3g; rendered with their mean %.3g", what, au, av,
                                       0.5 * (au + av))))
        return rc;
    if (0.5 * (au + av) > 1.0)
        return pf_pbrt_warn(c, m->loc, "conductor roughness above 1 (clamped)",
                            "%s: alpha %.3g rendered as 1", what, 0.5 * (au + av));
    return PF_OK;
}

static int s_dielectric(pf_pbrt_t *c, pf_pbrt_mat_t *m, const char *what, int thin)
{
    double eta, au = 0.0, av = 0.0;
    int rc = s_eta(c, &m->params, "eta", what, &eta);
    if (rc == PF_OK && !thin)
        rc = s_alpha_uv(c, &m->params, "", what, &au, &av);
    if (rc)
        return rc;
    m->m.type = thin ? PF_MAT_THIN_DIELECTRIC : PF_MAT_GLASS;
    m->m.ks = m->m.kt = pf_v3s(1.0f);
    m->m.ior = (float)eta;
    m->m.alpha = (float)fmin(0.5 * (au + av), 1.0); /* rough glass from 1e-3 (material/dielectric.h) */
    if (au != av && (rc = pf_pbrt_warn(c, m->loc, "anisotropic roughness (isotropic mean used)",
                                       "%s: alphas %.3g and %.3g; rendered with their mean %.3g", what, au, av,
                                       0.5 * (au + av))))
        return rc;
    return PF_OK;
}

/* A diffusetransmission colour, "reflectance" or "transmittance": its
 * texture (times scale) into *tex, else its value (default 0.25) into *v. */
static int s_difftrans_slot(pf_pbrt_t *c, pf_pbrt_mat_t *m, const char *name, double scale, const char *what,
                            pf_vec3 *v, uint32_t *tex)
{
    pf_pbrt_param_t *p = pf_pbrt_param(&m->params, name);
    uint32_t ref = 0;
    int rc = PF_OK;
    if (p && p->type == PF_PBRT_P_TEXTURE)
        rc = pf_pbrt_color_texture(c, p, &ref);
    if (rc == PF_OK && ref) {
        *v = pf_v3s(0.0f); /* the texture stands for it */
        return pf_pbrt_scaled_texture(c, ref, scale, p->loc, tex);
    }
    if (rc == PF_OK)
        rc = pf_pbrt_get_color(c, &m->params, name, PF_PBRT_ALBEDO, pf_v3s(0.25f), what, v, NULL);
    *v = pf_scale(*v, (float)scale);
    return rc;
}

static int s_difftrans(pf_pbrt_t *c, pf_pbrt_mat_t *m, const char *what)
{
    double scale;
    int rc = pf_pbrt_get_float(c, &m->params, "scale", 1.0, &scale);
    scale = fmax(scale, 0.0);
    if (rc == PF_OK)
        rc = s_difftrans_slot(c, m, "reflectance", scale, what, &m->m.kd, &m->m.kd_tex);
    if (rc == PF_OK)
        rc = s_difftrans_slot(c, m, "transmittance", scale, what, &m->m.kt, &m->m.kt_tex);
    if (rc)
        return rc;
    m->m.type = PF_MAT_DIFFUSE_TRANSMISSION;
    /* With a texture, kt is held to at most 1 - kd at each hit
     * (accel/surface.c); constants are scaled here to sum to at most 1. */
    float sum = pf_maxc(pf_add(m->m.kd, m->m.kt));
    if (sum > 1.0f) {
        m->m.kd = pf_scale(m->m.kd, 1.0f / sum);
        m->m.kt = pf_scale(m->m.kt, 1.0f / sum);
    }
    if (sum > 1.0f)
        return pf_pbrt_warn(c, m->loc, "diffusetransmission above 1 (scaled)",
                            "%s: reflectance + transmittance reaches %.3g; both scaled by %.3g", what, sum, 1.0 / sum);
    return PF_OK;
}

static int s_convert(pf_pbrt_t *c, pf_pbrt_mat_t *m);

/* Part k of a mix: converted, and added to the scene once as a material of
 * its own (le 0: the mix's pair carries the emission), its index in *out;
 * *none when it is an interface (no surface). */
static int s_mix_part(pf_pbrt_t *c, pf_pbrt_param_t *p, int k, const char *what, uint32_t *out, int *none)
{
    int id = pf_pbrt_name_find(c, p->str[k]);
    int32_t r = id < 0 ? -1 : c->named_mat[id];
    if (r < 0)
        return pf_pbrt_error(c, PF_EPARSE, p->loc, "%s: no material named \"%s\"", what, p->str[k]);
    if (c->mats[r].converted < 0)
        return pf_pbrt_error(c, PF_EPARSE, p->loc, "%s: the mix refers to itself through \"%s\"", what, p->str[k]);
    int rc = s_convert(c, &c->mats[r]);
    if (rc)
        return rc;
    pf_pbrt_mat_t *f = &c->mats[r];
    *none = f->no_surface;
    if (!f->no_surface && !f->part) {
        pf_material_t x = f->m;
        x.le = pf_v3s(0.0f);
        int mi = pf_scene_add_material(c->scene, &x);
        if (mi < 0)
            return pf_pbrt_error(c, PF_ENOMEM, p->loc, "out of memory");
        f->part = (uint32_t)mi + 1;
    }
    *out = f->part ? f->part - 1 : 0;
    return PF_OK;
}

static int s_mix(pf_pbrt_t *c, pf_pbrt_mat_t *m, const char *what)
{
    pf_pbrt_param_t *p = pf_pbrt_param(&m->params, "materials");
    if (!p || p->type != PF_PBRT_P_STRING || p->nstr != 2)
        return pf_pbrt_error(c, PF_EPARSE, p ? p->loc : m->loc, "%s: needs \"string materials\" with two names", what);
    uint32_t idx[2];
    int none[2];
    double amount;
    int rc = s_mix_part(c, p, 0, what, &idx[0], &none[0]);
    if (rc == PF_OK)
        rc = s_mix_part(c, p, 1, what, &idx[1], &none[1]);
    if (rc == PF_OK)
        rc = pf_pbrt_float_param(c, &m->params, "amount", 0.5, what, &amount, &m->m.amount_tex);
    if (rc)
        return rc;
    if (none[0] || none[1]) {
        int k = none[0] ? 1 : 0; /* the part that has a surface, if any */
        m->no_surface = none[k];
        m->m.amount_tex = 0;
        if (!none[k])
            m->m = c->mats[c->named_mat[pf_pbrt_name_find(c, p->str[k])]].m;
        return pf_pbrt_warn(c, m->loc, "mix with an interface (its other part alone)",
                            "%s: \"%s\" has no surface; rendered as \"%s\" alone", what, p->str[none[0] ? 0 : 1],
                            p->str[k]);
    }
    m->m.type = PF_MAT_MIX;
    m->m.mix[0] = idx[0];
    m->m.mix[1] = idx[1];
    m->m.amount = (float)amount;
    return PF_OK;
}

/* Converts material record m into m->m (once). */
static int s_convert(pf_pbrt_t *c, pf_pbrt_mat_t *m)
{
    if (m->converted > 0)
        return PF_OK;
    char what[160];
    s_what(c, m, what, sizeof what);
    m->converted = -1;
    m->m = pf_material_default(NULL);
    m->m.kd = pf_v3s(0.5f);
    const char *t = m->type;
    int rc;
    if (!strcmp(t, "diffuse"))
        rc = s_diffuse(c, m, what);
    else if (!strcmp(t, "coateddiffuse"))
        rc = s_coated_diffuse(c, m, what);
    else if (!strcmp(t, "conductor") || !strcmp(t, "coatedconductor"))
        rc = s_conductor(c, m, what, t[0] == 'c' && t[1] == 'o' && t[2] == 'a');
    else if (!strcmp(t, "dielectric") || !strcmp(t, "thindielectric"))
        rc = s_dielectric(c, m, what, t[0] == 't');
    else if (!strcmp(t, "diffusetransmission"))
        rc = s_difftrans(c, m, what);
    else if (!strcmp(t, "mix"))
        rc = s_mix(c, m, what);
    else if (!strcmp(t, "interface") || !strcmp(t, "none") || !t[0]) {
        m->no_surface = 1;
        rc = PF_OK;
    } else
        rc = s_not_renderable(c, m, what, "is not supported");
    if (rc == PF_OK && !m->no_surface)
        rc = pf_pbrt_mat_maps(c, &m->params, &m->m, what);
    if (rc == PF_OK)
        rc = pf_pbrt_check_unused(c, &m->params, what);
    const char *f = pf_pbrt_file_name(c, m->loc), *slash = strrchr(f, '/');
    if (m->name >= 0)
        snprintf(m->m.name, sizeof m->m.name, "%s", c->names.s[m->name]);
    else
        snprintf(m->m.name, sizeof m->m.name, "%s@%.40s:%d", m->type, slash ? slash + 1 : f, m->loc.line);
    m->converted = rc == PF_OK ? 1 : 0;
    return rc;
}

/* ---- lights ---- */

int pf_pbrt_area_light(pf_pbrt_t *c, const char *type, pf_pbrt_params_t *ps, pf_pbrt_loc_t loc)
{
    if (strcmp(type, "diffuse") != 0)
        return pf_pbrt_error(c, PF_EPARSE, loc, "unknown AreaLightSource type \"%.60s\" (pbrt-v4 has \"diffuse\")",
                             type);
    pf_pbrt_area_t a = { .loc = loc };
    double scale, power;
    const char *image;
    int rc = pf_pbrt_get_color(c, ps, "L", PF_PBRT_ILLUMINANT, pf_v3s(1.0f), "AreaLightSource", &a.le, NULL);
    if (rc == PF_OK)
        rc = pf_pbrt_get_float(c, ps, "scale", 1.0, &scale);
    if (rc == PF_OK)
        rc = pf_pbrt_get_float(c, ps, "power", 0.0, &power);
    if (rc == PF_OK)
        rc = pf_pbrt_get_bool(c, ps, "twosided", 0, &a.twosided);
    if (rc == PF_OK)
        rc = pf_pbrt_get_string(c, ps, "filename", NULL, &image);
    if (rc == PF_OK && (scale < 0.0 || power < 0.0))
        rc = pf_pbrt_error(c, PF_ERANGE, loc, "AreaLightSource: scale and power must be >= 0");
    if (rc == PF_OK && image)
        rc = pf_pbrt_warn(c, loc, "emission image (not rendered yet)",
                          "AreaLightSource: the image \"%s\" is not read; L (%g %g %g) is emitted", image, a.le.x,
                          a.le.y, a.le.z);
    if (rc == PF_OK)
        rc = pf_pbrt_check_unused(c, ps, "AreaLightSource");
    if (rc)
        return rc;
    a.le = pf_scale(a.le, (float)scale);
    a.power = power;
    if (pf_reserve((void **)&c->areas, &c->cap_areas, c->nareas + 1, sizeof *c->areas))
        return pf_pbrt_error(c, PF_ENOMEM, loc, "out of memory");
    c->areas[c->nareas] = a;
    c->gs.area = (int)c->nareas++;
    return PF_OK;
}

/* A point of the light's space in world space. */
static pf_vec3 s_world_point(const pf_pbrt_t *c, const double p[3])
{
    const double(*m)[4] = (const double(*)[4])c->gs.ctm;
    double r[4];
    for (int i = 0; i < 4; i++)
        r[i] = m[i][0] * p[0] + m[i][1] * p[1] + m[i][2] * p[2] + m[i][3];
    return pf_v3((float)(r[0] / r[3]), (float)(r[1] / r[3]), (float)(r[2] / r[3]));
}

/* LightSource "point" and "spot". */
static int s_point_spot(pf_pbrt_t *c, int spot, pf_pbrt_params_t *ps, pf_pbrt_loc_t loc)
{
    const char *what = spot ? "LightSource \"spot\"" : "LightSource \"point\"";
    pf_vec3 I;
    double scale, power, from[3], to[3], cone = 30.0, delta = 5.0;
    int rc = pf_pbrt_get_color(c, ps, "I", PF_PBRT_ILLUMINANT, pf_v3s(1.0f), what, &I, NULL);
    if (rc == PF_OK)
        rc = pf_pbrt_get_float(c, ps, "scale", 1.0, &scale);
    if (rc == PF_OK)
        rc = pf_pbrt_get_float(c, ps, "power", 0.0, &power);
    if (rc == PF_OK)
        rc = pf_pbrt_get_point3(c, ps, "from", pf_v3(0, 0, 0), from);
    if (rc == PF_OK && spot)
        rc = pf_pbrt_get_point3(c, ps, "to", pf_v3(0, 0, 1), to);
    if (rc == PF_OK && spot)
        rc = pf_pbrt_get_float(c, ps, "coneangle", 30.0, &cone);
    if (rc == PF_OK && spot)
        rc = pf_pbrt_get_float(c, ps, "conedelta", 5.0, &delta);
    if (rc == PF_OK && (scale < 0.0 || power < 0.0))
        rc = pf_pbrt_error(c, PF_ERANGE, loc, "%s: scale and power must be >= 0", what);
    if (rc == PF_OK)
        rc = pf_pbrt_check_unused(c, ps, what);
    if (rc)
        return rc;
    pf_light_t l = { .type = spot ? PF_LIGHT_SPOT : PF_LIGHT_POINT, .pos = s_world_point(c, from) };
    double k_e = 4.0 * M_PI;
    if (spot) {
        pf_vec3 d = pf_sub(s_world_point(c, to), l.pos);
        if (!(pf_len2(d) > 0.0f) || !pf_is_finite3(d))
            return pf_pbrt_error(c, PF_EPARSE, loc, "%s: \"from\" and \"to\" must differ", what);
        l.dir = pf_norm(d);
        double cos_end = cos(cone * M_PI / 180.0), cos_start = cos((cone - delta) * M_PI / 180.0);
        l.cos_outer = (float)cos_end;
        l.cos_inner = (float)cos_start;
        k_e = 2.0 * M_PI * ((1.0 - cos_start) + (cos_start - cos_end) / 2.0);
    }
    if (power > 0.0 && k_e > 0.0)
        scale *= power / k_e;
    l.intensity = pf_scale(I, (float)scale);
    if (!pf_is_finite3(l.intensity) || !pf_is_finite3(l.pos))
        return pf_pbrt_error(c, PF_ERANGE, loc, "%s: position or intensity is not finite", what);
    if (c->cur_object >= 0)
        return pf_pbrt_warn(c, loc, "light inside an object definition (ignored)",
                            "%s inside ObjectBegin is not instanced (pbrt ignores it too)", what);
    if (pf_scene_add_light(c->scene, &l))
        return pf_pbrt_error(c, PF_ENOMEM, loc, "out of memory");
    return PF_OK;
}

/* A direction of the light's space in world space (the CTM's linear part). */
static pf_vec3 s_world_vector(const pf_pbrt_t *c, const double v[3])
{
    const double(*m)[4] = (const double(*)[4])c->gs.ctm;
    double r[3];
    for (int i = 0; i < 3; i++)
        r[i] = m[i][0] * v[0] + m[i][1] * v[1] + m[i][2] * v[2];
    return pf_v3((float)r[0], (float)r[1], (float)r[2]);
}

/* LightSource "distant". */
static int s_distant(pf_pbrt_t *c, pf_pbrt_params_t *ps, pf_pbrt_loc_t loc)
{
    const char *what = "LightSource \"distant\"";
    pf_vec3 L;
    double scale, illum, from[3], to[3];
    int rc = pf_pbrt_get_color(c, ps, "L", PF_PBRT_ILLUMINANT, pf_v3s(1.0f), what, &L, NULL);
    if (rc == PF_OK)
        rc = pf_pbrt_get_float(c, ps, "scale", 1.0, &scale);
    if (rc == PF_OK)
        rc = pf_pbrt_get_float(c, ps, "illuminance", -1.0, &illum);
    if (rc == PF_OK)
        rc = pf_pbrt_get_point3(c, ps, "from", pf_v3(0, 0, 0), from);
    if (rc == PF_OK)
        rc = pf_pbrt_get_point3(c, ps, "to", pf_v3(0, 0, 1), to);
    if (rc == PF_OK && scale < 0.0)
        rc = pf_pbrt_error(c, PF_ERANGE, loc, "%s: scale must be >= 0", what);
    if (rc == PF_OK)
        rc = pf_pbrt_check_unused(c, ps, what);
    if (rc)
        return rc;
    if (illum > 0.0) /* pbrt-v4: a negative or zero illuminance is unset */
        scale *= illum;
    double v[3] = { to[0] - from[0], to[1] - from[1], to[2] - from[2] };
    pf_vec3 d = s_world_vector(c, v);
    if (!(pf_len2(d) > 0.0f) || !pf_is_finite3(d))
        return pf_pbrt_error(c, PF_EPARSE, loc, "%s: \"from\" and \"to\" must differ", what);
    pf_light_t l = { .type = PF_LIGHT_DISTANT, .dir = pf_norm(d), .intensity = pf_scale(L, (float)scale) };
    if (!pf_is_finite3(l.intensity) || !pf_is_finite3(l.dir))
        return pf_pbrt_error(c, PF_ERANGE, loc, "%s: direction or irradiance is not finite", what);
    if (c->cur_object >= 0)
        return pf_pbrt_warn(c, loc, "light inside an object definition (ignored)",
                            "%s inside ObjectBegin is not instanced (pbrt ignores it too)", what);
    if (pf_scene_add_light(c->scene, &l))
        return pf_pbrt_error(c, PF_ENOMEM, loc, "out of memory");
    return PF_OK;
}

/* LightSource "infinite" without an image: a constant sky. 1 when it has an
 * image (the caller reads it: pbrt_env.c), else 0 or a status. */
static int s_infinite(pf_pbrt_t *c, pf_pbrt_params_t *ps, pf_pbrt_loc_t loc, int *image)
{
    const char *what = "LightSource \"infinite\"";
    const char *file;
    pf_vec3 L;
    double scale, illum;
    int rc = pf_pbrt_get_string(c, ps, "filename", "", &file);
    *image = rc == PF_OK && file[0] != '\0';
    if (rc || *image)
        return rc;
    rc = pf_pbrt_get_color(c, ps, "L", PF_PBRT_ILLUMINANT, pf_v3s(1.0f), what, &L, NULL);
    if (rc == PF_OK)
        rc = pf_pbrt_get_float(c, ps, "scale", 1.0, &scale);
    if (rc == PF_OK)
        rc = pf_pbrt_get_float(c, ps, "illuminance", -1.0, &illum);
    if (rc == PF_OK && scale < 0.0)
        rc = pf_pbrt_error(c, PF_ERANGE, loc, "%s: scale must be >= 0", what);
    if (rc == PF_OK)
        rc = pf_pbrt_check_unused(c, ps, what);
    if (rc)
        return rc;
    if (illum > 0.0) /* pbrt-v4: the illuminance of an upward patch, pi L for a constant sky */
        scale *= illum / M_PI;
    pf_light_t l = { .type = PF_LIGHT_INFINITE, .intensity = pf_scale(L, (float)scale) };
    if (!pf_is_finite3(l.intensity))
        return pf_pbrt_error(c, PF_ERANGE, loc, "%s: radiance is not finite", what);
    if (c->cur_object >= 0)
        return pf_pbrt_warn(c, loc, "light inside an object definition (ignored)",
                            "%s inside ObjectBegin is not instanced (pbrt ignores it too)", what);
    if (pf_scene_add_light(c->scene, &l))
        return pf_pbrt_error(c, PF_ENOMEM, loc, "out of memory");
    return PF_OK;
}

int pf_pbrt_light(pf_pbrt_t *c, const char *type, pf_pbrt_params_t *ps, pf_pbrt_loc_t loc)
{
    if (!strcmp(type, "infinite")) {
        int image = 0, rc = s_infinite(c, ps, loc, &image);
        if (rc || !image)
            return rc;
        const char *file = "";
        pf_pbrt_get_string(c, ps, "filename", "", &file);
        return pf_pbrt_image_infinite(c, ps, loc, file); /* pbrt_env.c */
    }
    if (!strcmp(type, "point") || !strcmp(type, "spot"))
        return s_point_spot(c, type[0] == 's', ps, loc);
    if (!strcmp(type, "distant"))
        return s_distant(c, ps, loc);
    static const char *later[] = { "goniometric", "projection" };
    for (size_t i = 0; i < sizeof later / sizeof *later; i++) {
        if (strcmp(type, later[i]) != 0)
            continue;
        char kind[64];
        snprintf(kind, sizeof kind, "light type %s (not rendered yet)", type);
        for (size_t k = 0; k < ps->n; k++)
            ps->p[k].used = 1;
        return pf_pbrt_warn(c, loc, kind, "LightSource \"%s\" is not rendered: it adds no light", type);
    }
    return pf_pbrt_error(c, PF_EPARSE, loc, "unknown LightSource type \"%.60s\"", type);
}

/* ---- pairs and the scene's materials ---- */

int pf_pbrt_pair(pf_pbrt_t *c, int area, pf_vec3 le, pf_pbrt_loc_t loc)
{
    char key[192];
    snprintf(key, sizeof key, "%d:%d:%d:%a:%a:%a:%d:%d", c->gs.mat_kind, c->gs.mat, area, (double)le.x,
             (double)le.y, (double)le.z, c->gs.medium_in, c->gs.medium_out);
    int id = pf_pbrt_intern(c, key);
    if (id < 0)
        return pf_pbrt_error(c, PF_ENOMEM, loc, "out of memory");
    int32_t *slot = &c->named_pair[id];
    if (*slot >= 0)
        return *slot;
    if (c->npairs >= INT32_MAX / 2 || pf_reserve((void **)&c->pairs, &c->cap_pairs, c->npairs + 1, sizeof *c->pairs))
        return pf_pbrt_error(c, PF_ENOMEM, loc, "out of memory");
    c->pairs[c->npairs] = (pf_pbrt_pair_t){ .mat_kind = c->gs.mat_kind, .mat = c->gs.mat, .area = area, .le = le,
                                            .medium_in = c->gs.medium_in, .medium_out = c->gs.medium_out,
                                            .medium_loc = c->gs.medium_loc, .loc = loc, .mat_loc = c->gs.mat_loc,
                                            .out = -1 };
    *slot = (int32_t)c->npairs;
    return (int)c->npairs++;
}

/* The scene material of pair p (p->out), made on first use. */
static int s_emit_pair(pf_pbrt_t *c, pf_pbrt_pair_t *p, size_t index)
{
    pf_material_t m = pf_material_default("default");
    m.kd = pf_v3s(0.5f); /* pbrt's default material: diffuse, reflectance 0.5 */
    int rc = PF_OK;
    if (p->mat_kind != PF_PBRT_MAT_DEFAULT) {
        int32_t r = p->mat;
        if (p->mat_kind == PF_PBRT_MAT_NAMED && (r = c->named_mat[p->mat]) < 0)
            return pf_pbrt_error_line(c, PF_EPARSE, p->mat_loc, "NamedMaterial \"%s\" is not defined",
                                      c->names.s[p->mat]);
        if ((rc = s_convert(c, &c->mats[r])))
            return rc;
        if (c->mats[r].no_surface) {
            p->out = -1;
            return PF_OK;
        }
        m = c->mats[r].m;
    }
    m.le = p->le;
    m.twosided = p->area >= 0 && !pf_is_black(p->le) && c->areas[p->area].twosided;
    if ((rc = pf_pbrt_medium_sigma(c, p->medium_in, p->medium_loc, &m.sigma_in)) ||
        (rc = pf_pbrt_medium_sigma(c, p->medium_out, p->medium_loc, &m.sigma_out)))
        return rc;
    if (!pf_is_black(p->le)) {
        char base[PF_NAME_MAX], suffix[32];
        snprintf(base, sizeof base, "%s", m.name);
        int k = snprintf(suffix, sizeof suffix, " (light %zu)", index);
        snprintf(m.name, sizeof m.name, "%.*s%s", (int)(sizeof m.name - 1 - (size_t)k), base, suffix);
    }
    int mi = pf_scene_add_material(c->scene, &m);
    if (mi < 0)
        return pf_pbrt_error_line(c, PF_ENOMEM, p->loc, "out of memory");
    p->out = mi;
    return PF_OK;
}

int pf_pbrt_emit_materials(pf_pbrt_t *c)
{
    for (size_t i = 0; i < c->npairs; i++) {
        int rc = s_emit_pair(c, &c->pairs[i], i);
        if (rc)
            return rc;
    }
    /* Materials no shape uses: converted for their warnings alone. */
    for (size_t i = 0; i < c->nmats; i++) {
        int rc = s_convert(c, &c->mats[i]);
        if (rc)
            return rc;
    }
    return PF_OK;
}
