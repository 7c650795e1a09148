/* pbrt_tex.c: pbrt-v4 textures made scene textures (scene/texture.h) when
 * a material first uses one. Rendered: imagemap (filename, encoding sRGB,
 * linear or gamma g (as sRGB, warned), scale, invert, wrap repeat, clamp or
 * black; filter and maxanisotropy read and ignored: lookups are bilinear),
 * checkerboard (2D: tex1, tex2), scale (tex, scale), mix (tex1, tex2,
 * amount) and constant (value) as operands; an image file that cannot be
 * opened is a warning (the material's constant stands in), one that is not
 * a readable image an error naming it and the Texture's file:line; every class with the "uv"
 * mapping and its uscale, vscale, udelta, vdelta. Operands are constants or
 * other textures, made the same way. The classes not rendered (bilerp,
 * dots, fbm, marble, ptex, windy, wrinkled, directionmix, 3D checkerboard,
 * other mappings) give ref 0, and the caller's "texture" warning. A shape's
 * "alpha" (a float or a float texture) becomes its meshes' cut-out texture
 * (accel/alpha.c). */
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "load/pbrt/pbrt_impl.h"
#include "mesh/texload.h"

static int s_make(pf_pbrt_t *c, pf_pbrt_tex_t *t, uint32_t *ref);

/* An operand: a texture parameter of the owner's kind (made here), or a
 * value (rgb / spectrum / float) or the default. */
static int s_operand(pf_pbrt_t *c, pf_pbrt_tex_t *t, const char *name, double def, pf_tex_operand_t *op, int *ok)
{
    op->ref = 0;
    op->c = pf_v3s((float)def);
    pf_pbrt_param_t *p = pf_pbrt_param(&t->params, name);
    if (!p)
        return PF_OK;
    if (p->type == PF_PBRT_P_TEXTURE) {
        if (p->nstr != 1)
            return pf_pbrt_error(c, PF_EPARSE, p->loc, "texture parameter '%s' takes one texture name", name);
        pf_pbrt_tex_t *o;
        int rc = pf_pbrt_find_texture(c, p->str[0], t->is_float, p->loc, &o);
        if (rc == PF_OK)
            rc = s_make(c, o, &op->ref);
        if (rc == PF_OK && !op->ref)
            *ok = 0;
        return rc;
    }
    if (t->is_float) {
        double v;
        int rc = pf_pbrt_get_float(c, &t->params, name, def, &v);
        op->c = pf_v3s((float)v);
        return rc;
    }
    char what[96];
    snprintf(what, sizeof what, "Texture \"%s\"", c->names.s[t->name]);
    return pf_pbrt_get_color(c, &t->params, name, PF_PBRT_UNBOUNDED, op->c, what, &op->c, NULL);
}

static int s_mapping(pf_pbrt_t *c, pf_pbrt_tex_t *t, pf_texture_t *x, int *ok)
{
    const char *mapping;
    double su, sv, du, dv;
    int rc = pf_pbrt_get_string(c, &t->params, "mapping", "uv", &mapping);
    if (rc == PF_OK)
        rc = pf_pbrt_get_float(c, &t->params, "uscale", 1.0, &su);
    if (rc == PF_OK)
        rc = pf_pbrt_get_float(c, &t->params, "vscale", 1.0, &sv);
    if (rc == PF_OK)
        rc = pf_pbrt_get_float(c, &t->params, "udelta", 0.0, &du);
    if (rc == PF_OK)
        rc = pf_pbrt_get_float(c, &t->params, "vdelta", 0.0, &dv);
    if (rc == PF_OK && strcmp(mapping, "uv") != 0)
        *ok = 0;
    x->su = (float)su;
    x->sv = (float)sv;
    x->du = (float)du;
    x->dv = (float)dv;
    return rc;
}

static int s_imagemap(pf_pbrt_t *c, pf_pbrt_tex_t *t, pf_texture_t *x, uint32_t *ref, int *ok)
{
    const char *file, *enc, *wrap, *filter;
    double scale, aniso;
    int invert;
    int rc = pf_pbrt_get_string(c, &t->params, "filename", NULL, &file);
    if (rc == PF_OK && !file)
        rc = pf_pbrt_error(c, PF_EPARSE, t->loc, "imagemap texture needs \"string filename\"");
    if (rc == PF_OK)
        rc = pf_pbrt_get_string(c, &t->params, "encoding", "sRGB", &enc);
    if (rc == PF_OK)
        rc = pf_pbrt_get_string(c, &t->params, "wrap", "repeat", &wrap);
    if (rc == PF_OK)
        rc = pf_pbrt_get_string(c, &t->params, "filter", "bilinear", &filter);
    if (rc == PF_OK)
        rc = pf_pbrt_get_float(c, &t->params, "maxanisotropy", 8.0, &aniso);
    if (rc == PF_OK)
        rc = pf_pbrt_get_float(c, &t->params, "scale", 1.0, &scale);
    if (rc == PF_OK)
        rc = pf_pbrt_get_bool(c, &t->params, "invert", 0, &invert);
    if (rc)
        return rc;
    x->scale = (float)scale;
    x->invert = invert;
    if (!strcmp(wrap, "clamp"))
        x->wrap = PF_WRAP_CLAMP;
    else if (!strcmp(wrap, "black"))
        x->wrap = PF_WRAP_BLACK;
    else if (strcmp(wrap, "repeat") != 0)
        return pf_pbrt_error(c, PF_EPARSE, t->loc, "imagemap: wrap \"%.60s\" is not repeat, clamp or black", wrap);
    pf_texenc e = PF_TEXENC_SRGB;
    if (!strcmp(enc, "linear"))
        e = PF_TEXENC_LINEAR;
    else if (!strncmp(enc, "gamma ", 6) &&
             (rc = pf_pbrt_warn(c, t->loc, "imagemap gamma encoding (as sRGB)",
                                "imagemap \"%s\": encoding \"%s\" decoded as sRGB", file, enc)))
        return rc;
    else if (strcmp(enc, "sRGB") != 0 && strncmp(enc, "gamma ", 6) != 0)
        return pf_pbrt_error(c, PF_EPARSE, t->loc, "imagemap: encoding \"%.60s\" is not sRGB, linear or gamma", enc);
    char path[4096];
    if ((rc = pf_pbrt_resolve(c, t->loc, file, 0, path, sizeof path)))
        return rc;
    pf_error_t ierr = { { 0 } };
    int r = pf_texture_load_image(c->scene, path, x, e, pf_pbrt_file_name(c, t->loc), t->loc.line, &ierr);
    if (r == PF_EIO) { /* missing: as in MTL, a warning, and the caller's constant */
        *ok = 0;
        return pf_pbrt_warn(c, t->loc, "missing texture image (constant stands in)", "%s", ierr.msg);
    }
    if (r < 0) {
        if (c->err)
            *c->err = ierr;
        return r;
    }
    *ref = (uint32_t)r;
    return PF_OK;
}

/* Makes the scene texture of t (once); *ref 0 when its class is not rendered. */
static int s_make(pf_pbrt_t *c, pf_pbrt_tex_t *t, uint32_t *ref)
{
    *ref = t->ref;
    if (t->ref)
        return PF_OK;
    if (t->converting)
        return pf_pbrt_error(c, PF_EPARSE, t->loc, "Texture \"%s\" refers to itself", c->names.s[t->name]);
    pf_texture_t x = pf_texture_constant(c->names.s[t->name], pf_v3s(1.0f));
    int ok = 1, rc;
    t->converting = 1;
    rc = s_mapping(c, t, &x, &ok);
    const char *cls = t->cls;
    if (rc == PF_OK && !strcmp(cls, "constant")) {
        rc = s_operand(c, t, "value", 1.0, &x.op[0], &ok);
        if (rc == PF_OK && x.op[0].ref) /* a constant naming a texture: that texture */
            x.op[0] = (pf_tex_operand_t){ pf_v3s(1.0f), x.op[0].ref }, x.type = PF_TEX_SCALE;
    } else if (rc == PF_OK && !strcmp(cls, "checkerboard")) {
        int dim;
        x.type = PF_TEX_CHECKER;
        rc = pf_pbrt_get_int(c, &t->params, "dimension", 2, &dim);
        const char *aa;
        if (rc == PF_OK)
            rc = pf_pbrt_get_string(c, &t->params, "aamode", "closedform", &aa);
        ok &= dim == 2;
        if (rc == PF_OK)
            rc = s_operand(c, t, "tex1", 1.0, &x.op[0], &ok);
        if (rc == PF_OK)
            rc = s_operand(c, t, "tex2", 0.0, &x.op[1], &ok);
    } else if (rc == PF_OK && !strcmp(cls, "scale")) {
        x.type = PF_TEX_SCALE;
        rc = s_operand(c, t, "tex", 1.0, &x.op[0], &ok);
        if (rc == PF_OK) {
            /* "scale" is a float (texture) whatever the kind of t. */
            int was = t->is_float;
            t->is_float = 1;
            rc = s_operand(c, t, "scale", 1.0, &x.op[1], &ok);
            t->is_float = was;
        }
    } else if (rc == PF_OK && !strcmp(cls, "mix")) {
        x.type = PF_TEX_MIX;
        rc = s_operand(c, t, "tex1", 0.0, &x.op[0], &ok);
        if (rc == PF_OK)
            rc = s_operand(c, t, "tex2", 1.0, &x.op[1], &ok);
        if (rc == PF_OK) {
            int was = t->is_float;
            t->is_float = 1;
            rc = s_operand(c, t, "amount", 0.5, &x.op[2], &ok);
            t->is_float = was;
        }
    } else if (rc == PF_OK && !strcmp(cls, "imagemap")) {
        if (ok)
            rc = s_imagemap(c, t, &x, ref, &ok);
    } else {
        ok = 0;
    }
    t->converting = 0;
    if (rc || !ok || *ref)
        return rc;
    int r = pf_scene_add_texture(c->scene, &x);
    if (r < 0)
        return pf_pbrt_error(c, PF_ENOMEM, t->loc, "out of memory");
    *ref = t->ref = (uint32_t)r;
    return PF_OK;
}

int pf_pbrt_color_texture(pf_pbrt_t *c, pf_pbrt_param_t *p, uint32_t *ref)
{
    *ref = 0;
    if (p->nstr != 1)
        return pf_pbrt_error(c, PF_EPARSE, p->loc, "texture parameter '%s' takes one texture name", p->name);
    pf_pbrt_tex_t *t;
    int rc = pf_pbrt_find_texture(c, p->str[0], 0, p->loc, &t);
    if (rc || !strcmp(t->cls, "constant"))
        return rc;
    if ((rc = s_make(c, t, ref)) == PF_OK && *ref)
        p->used = 1;
    return rc;
}

int pf_pbrt_float_param(pf_pbrt_t *c, pf_pbrt_params_t *ps, const char *name, double def, const char *what,
                        double *value, uint32_t *ref)
{
    *ref = 0;
    *value = def;
    pf_pbrt_param_t *p = pf_pbrt_param(ps, name);
    if (!p || p->type != PF_PBRT_P_TEXTURE)
        return pf_pbrt_get_float_tex(c, ps, name, def, what, value, NULL);
    int rc = pf_pbrt_float_texture(c, p, ref);
    if (rc == PF_OK && !*ref) /* a constant: its value */
        rc = pf_pbrt_get_float_tex(c, ps, name, def, what, value, NULL);
    return rc;
}

int pf_pbrt_alpha_texture(pf_pbrt_t *c, pf_pbrt_params_t *ps, uint32_t *ref)
{
    *ref = 0;
    pf_pbrt_param_t *p = pf_pbrt_param(ps, "alpha");
    if (!p)
        return PF_OK;
    if (p->type == PF_PBRT_P_TEXTURE) {
        if (p->nstr != 1)
            return pf_pbrt_error(c, PF_EPARSE, p->loc, "texture parameter 'alpha' takes one texture name");
        pf_pbrt_tex_t *t;
        int rc = pf_pbrt_find_texture(c, p->str[0], 1, p->loc, &t);
        if (rc == PF_OK)
            rc = s_make(c, t, ref);
        if (rc == PF_OK && !*ref)
            rc = pf_pbrt_warn(c, p->loc, "alpha texture (opaque)",
                              "\"alpha\" is the %s texture \"%s\", not rendered here: the shape is opaque", t->cls,
                              p->str[0]);
        return rc;
    }
    double a;
    int rc = pf_pbrt_get_float(c, ps, "alpha", 1.0, &a);
    if (rc || a >= 1.0)
        return rc;
    pf_texture_t x = pf_texture_constant("alpha", pf_v3s((float)a));
    int r = pf_scene_add_texture(c->scene, &x);
    if (r < 0)
        return pf_pbrt_error(c, PF_ENOMEM, p->loc, "out of memory");
    *ref = (uint32_t)r;
    return PF_OK;
}

int pf_pbrt_float_texture(pf_pbrt_t *c, pf_pbrt_param_t *p, uint32_t *ref)
{
    *ref = 0;
    if (p->nstr != 1)
        return pf_pbrt_error(c, PF_EPARSE, p->loc, "texture parameter '%s' takes one texture name", p->name);
    pf_pbrt_tex_t *t;
    int rc = pf_pbrt_find_texture(c, p->str[0], 1, p->loc, &t);
    if (rc == PF_OK)
        rc = s_make(c, t, ref);
    if (rc == PF_OK && *ref)
        p->used = 1;
    return rc;
}

int pf_pbrt_scaled_texture(pf_pbrt_t *c, uint32_t ref, double k, pf_pbrt_loc_t loc, uint32_t *out)
{
    *out = ref;
    if (!ref || k == 1.0)
        return PF_OK;
    pf_texture_t x = pf_texture_constant("scaled", pf_v3s(1.0f));
    x.type = PF_TEX_SCALE;
    x.op[0] = (pf_tex_operand_t){ pf_v3s(1.0f), ref };
    x.op[1] = (pf_tex_operand_t){ pf_v3s((float)k), 0 };
    int r = pf_scene_add_texture(c->scene, &x);
    if (r < 0)
        return pf_pbrt_error(c, PF_ENOMEM, loc, "out of memory");
    *out = (uint32_t)r;
    return PF_OK;
}
