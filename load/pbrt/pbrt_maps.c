/* pbrt_maps.c: the texture slots of pbrt-v4 materials beyond the
 * reflectance: "string normalmap" (an image read with linear encoding, as
 * pbrt-v4's Image::Read(..., ColorEncoding::Linear) does), "texture
 * displacement" (a float texture: bump mapping) and roughness textures
 * ("roughness", "uroughness", "vroughness" naming non-constant float
 * textures). The renderer resolves them per hit (accel/surface.h,
 * accel/shading.h). */
#include <stdio.h>
#include <string.h>

#include "load/pbrt/pbrt_impl.h"
#include "mesh/texload.h"

/* The normal-map texture of a material converted earlier from the same
 * file (resolved path), or 0: a scene's materials often share one map. */
static uint32_t s_loaded(pf_pbrt_t *c, const char *path)
{
    char other[4096];
    for (size_t i = 0; i < c->nmats; i++) {
        const pf_pbrt_mat_t *o = &c->mats[i];
        if (o->converted <= 0 || !o->m.normal_tex)
            continue;
        for (size_t k = 0; k < o->params.n; k++) {
            const pf_pbrt_param_t *q = &o->params.p[k];
            if (q->type == PF_PBRT_P_STRING && q->nstr == 1 && !strcmp(q->name, "normalmap") &&
                pf_pbrt_resolve(c, q->loc, q->str[0], 0, other, sizeof other) == PF_OK && !strcmp(other, path))
                return o->m.normal_tex;
        }
    }
    return 0;
}

static int s_normal_map(pf_pbrt_t *c, pf_pbrt_param_t *p, pf_material_t *m, const char *what)
{
    if (p->type != PF_PBRT_P_STRING || p->nstr != 1)
        return pf_pbrt_error(c, PF_EPARSE, p->loc, "%s: \"normalmap\" takes one file name (string)", what);
    char path[4096];
    int rc = pf_pbrt_resolve(c, p->loc, p->str[0], 0, path, sizeof path);
    if (rc)
        return rc;
    if ((m->normal_tex = s_loaded(c, path)))
        return PF_OK;
    pf_texture_t tmpl = pf_texture_constant("normalmap", pf_v3s(0.5f));
    pf_error_t ierr = { { 0 } };
    int r = pf_texture_load_image(c->scene, path, &tmpl, PF_TEXENC_LINEAR, pf_pbrt_file_name(c, p->loc), p->loc.line,
                                  &ierr);
    if (r == PF_EIO)
        return pf_pbrt_warn(c, p->loc, "missing normal map (unbent)", "%s", ierr.msg);
    if (r < 0) {
        if (c->err)
            *c->err = ierr;
        return r;
    }
    m->normal_tex = (uint32_t)r;
    return PF_OK;
}

int pf_pbrt_mat_maps(pf_pbrt_t *c, pf_pbrt_params_t *ps, pf_material_t *m, const char *what)
{
    pf_pbrt_param_t *p = pf_pbrt_param(ps, "normalmap");
    int rc = p ? s_normal_map(c, p, m, what) : PF_OK;
    p = pf_pbrt_param(ps, "displacement");
    if (rc || !p)
        return rc;
    if (p->type == PF_PBRT_P_FLOAT)
        return PF_OK; /* a constant displacement bends nothing */
    if (p->type != PF_PBRT_P_TEXTURE)
        return pf_pbrt_error(c, PF_EPARSE, p->loc, "%s: \"displacement\" is a float texture", what);
    if ((rc = pf_pbrt_float_texture(c, p, &m->bump_tex)))
        return rc;
    if (!m->bump_tex)
        return pf_pbrt_warn(c, p->loc, "displacement texture (ignored)",
                            "%s: \"displacement\" names a texture class not rendered here", what);
    return PF_OK;
}

/* Whether parameter name of ps names a non-constant float texture. */
static int s_is_tex(pf_pbrt_t *c, pf_pbrt_params_t *ps, const char *name, pf_pbrt_param_t **out)
{
    *out = NULL;
    for (size_t i = 0; i < ps->n; i++)
        if (strcmp(ps->p[i].name, name) == 0 && ps->p[i].type == PF_PBRT_P_TEXTURE && ps->p[i].nstr == 1) {
            pf_pbrt_tex_t *t;
            if (pf_pbrt_find_texture(c, ps->p[i].str[0], 1, ps->p[i].loc, &t) != PF_OK)
                return 0; /* the ordinary reading reports it */
            *out = &ps->p[i];
            return strcmp(t->cls, "constant") != 0;
        }
    return 0;
}

/* One of u and v: its texture, or its float (default def). */
static int s_operand(pf_pbrt_t *c, pf_pbrt_params_t *ps, const char *name, pf_tex_operand_t def,
                     pf_tex_operand_t *op)
{
    pf_pbrt_param_t *p;
    *op = def;
    if (s_is_tex(c, ps, name, &p))
        return pf_pbrt_float_texture(c, p, &op->ref);
    double v;
    int rc = pf_pbrt_get_float_tex(c, ps, name, (double)def.c.x, name, &v, NULL);
    if (rc == PF_OK && pf_pbrt_param(ps, name))
        *op = (pf_tex_operand_t){ pf_v3s((float)v), 0 };
    return rc;
}

int pf_pbrt_rough_texture(pf_pbrt_t *c, pf_pbrt_params_t *ps, pf_material_t *m, int *done)
{
    pf_pbrt_param_t *p;
    *done = 0;
    if (!s_is_tex(c, ps, "roughness", &p) && !s_is_tex(c, ps, "uroughness", &p) && !s_is_tex(c, ps, "vroughness", &p))
        return PF_OK;
    pf_tex_operand_t r, u, v;
    int remap;
    int rc = s_operand(c, ps, "roughness", (pf_tex_operand_t){ pf_v3s(0.0f), 0 }, &r);
    if (rc == PF_OK)
        rc = s_operand(c, ps, "uroughness", r, &u);
    if (rc == PF_OK)
        rc = s_operand(c, ps, "vroughness", r, &v);
    if (rc == PF_OK)
        rc = pf_pbrt_get_bool(c, ps, "remaproughness", 1, &remap);
    if (rc)
        return rc;
    pf_texture_t x = pf_texture_constant("roughness", u.c);
    x.op[0] = u;
    if (u.ref != v.ref || u.c.x != v.c.x) { /* anisotropic: their mean, as the constant case */
        x.type = PF_TEX_MIX;
        x.op[1] = v;
        x.op[2] = (pf_tex_operand_t){ pf_v3s(0.5f), 0 };
    } else if (u.ref) {
        x.type = PF_TEX_SCALE;
        x.op[1] = (pf_tex_operand_t){ pf_v3s(1.0f), 0 };
    }
    int ref = x.type == PF_TEX_SCALE ? (int)u.ref : pf_scene_add_texture(c->scene, &x);
    if (ref < 0)
        return pf_pbrt_error(c, PF_ENOMEM, p->loc, "out of memory");
    m->rough_tex = (uint32_t)ref;
    m->rough_remap = (uint32_t)remap;
    *done = 1;
    return PF_OK;
}
