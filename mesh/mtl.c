/* mtl.c: reads Wavefront MTL material libraries into pf_material_t records of
 * a scene. It owns nothing beyond one call: each material is collected from
 * its statements, mapped once at the next `newmtl` (or the end of the file)
 * and, when the whole file has parsed, appended to the scene or put in place
 * of the scene material of the same name.
 * Called by obj.c for `mtllib` lines and by the scene loaders, on the one
 * thread that builds the scene. A file with an error adds nothing.
 *
 * Mapping from MTL to pf_material_t (also in docs/mtl-mapping.md):
 *
 *   illum            type     fields
 *   ---------------  -------  -----------------------------------------------
 *   absent, 0, 1, 2  DIFFUSE  kd = Kd. A Phong lobe ks = Ks, ns = Ns when Ks is
 *   (and 10)                  not black and illum is 2, or illum is absent and
 *                             Ns is given. If kd + ks exceeds 1 in a channel,
 *                             both are scaled by 1 / max_c(kd_c + ks_c) (warns)
 *                             so the surface cannot create energy.
 *                             `d` < 1 (or `Tr` > 0) is ignored: still opaque.
 *   3, 8             MIRROR   ks = Ks, or (1,1,1) when Ks is black or absent.
 *   5                MIRROR   as 3: the Fresnel-weighted reflection of illum 5
 *                             is approximated by a perfect mirror.
 *   4, 6, 7, 9       GLASS    ior = Ni (1.5 when absent or 0), ks = Ks or
 *                             (1,1,1) when black or absent, kt = Tf when given,
 *                             else (1,1,1). `d` does not change kt.
 *   other values     DIFFUSE  as illum 2, with a warning.
 *
 *   Pr / Pm (the PBR extension: roughness and metallic, each in [0, 1],
 *   clamped with a warning) on illum absent or 0-2, when either is given:
 *     Pm > 0.5       CONDUCTOR, reflectance Kd (pbrt's form: eta 1, k of Kd),
 *                    or map_Kd's texture per hit (refl_tex),
 *                    alpha = Pr^2 (Pr absent: 0, a smooth metal)
 *     Pm <= 0.5      COATED kd = Kd under a lossless coat of index Ni (1.5
 *                    when absent or below 1), alpha = Pr^2 (Pr absent: 1)
 *   alpha = roughness^2 as Disney's and glTF's roughness, which the
 *   extension copies; Ks and Ns are not used then.
 *   Ke gives le (emitted radiance, one-sided) for every type.
 *   Defaults when absent: Kd 0.8 (pf_material_default), Ks 0, Ke 0, Ns 1.
 *   map_Kd file: the diffuse albedo from that image (replacing Kd; path
 *   relative to the MTL's folder; options -s and -o scale and offset the uv,
 *   -clamp on clamps; the others are skipped). The image is read when the
 *   statement is, and a bad one is an error naming it and this file's line
 *   (a missing one is a warning: Kd stands in).
 *   bump / map_Bump file, norm file: a bump map (heights in the image's
 *   first channel, linear, times the -bm multiplier, in world units as
 *   pbrt's "displacement") and a tangent-space normal map (linear RGB) for
 *   any kind of material (accel/shading.h); the same options as map_Kd.
 *   map_d file (same options): an alpha cut-out of every triangle with this
 *   material (alpha_tex; the image's mean channel, linear: below a
 *   hash of the ray the hit is skipped, accel/alpha.c), any type.
 *   map_Ks file (same options, sRGB as map_Kd): the Phong lobe's ks (illum
 *   2) or a mirror's reflectance (illum 3, 5, 8) times the image per hit
 *   (refl_tex; Ks absent counts as 1), a Phong ks held to 1 - kd per
 *   channel at each hit; on other kinds a warning, not rendered.
 *   Other maps (map_Ns, map_Ka, disp, decal, refl, ...) are
 *   not rendered: one warning per kind at the end, with the count and
 *   the first line. Ignored without a word: Ka, sharpness.
 *   Other statements are skipped with one warning per keyword.
 *
 * Checks (errors name file:line): every number must parse and be finite.
 * Kd, Ks and Tf must be >= 0; a channel above 1 is clamped to 1 with a
 * warning. Ke >= 0 (unbounded). Ns >= 0. Ni >= 0, and Ni 0, which
 * exporters write for "unset", counts as absent. d and Tr >= 0, clamped to 1
 * with a warning; Tr means d = 1 - Tr. Colours may give one value (grey) or three; the `spectral` and
 * `xyz` forms are not supported. A material name longer than 63 bytes is
 * truncated with a warning (obj.c truncates `usemtl` names the same way). */
#include "mesh/mesh.h"

#include <errno.h>
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <strings.h>

#include "base/log.h"
#include "base/reserve.h"
#include "mesh/texload.h"
#include "mesh/text.h"

/* One material as written, before mapping. */
typedef struct s_mtl {
    char name[PF_NAME_MAX];
    int line; /* of its newmtl statement */
    pf_vec3 kd, ks, ke, tf;
    float ns, ni, d, pr, pm;
    int has_kd, has_ks, has_ke, has_tf, has_ns, has_ni, has_d, has_pr, has_pm;
    int illum; /* -1 when absent */
    uint32_t kd_tex; /* map_Kd's texture ref, or 0 */
    uint32_t d_tex;  /* map_d's texture ref, or 0 */
    uint32_t bump_tex, norm_tex; /* bump / map_Bump's and norm's texture refs, or 0 */
    uint32_t ks_tex; /* map_Ks's texture ref, or 0 */
} s_mtl_t;

#define S_MAX_WARNED 32

typedef struct s_ctx {
    pf_scene_t *scene;
    const char *path;
    int line;
    pf_error_t *err;
    pf_text_warned_t warned;
    s_mtl_t cur; /* the material being collected */
    int have;    /* cur holds one (a newmtl was read) */
    pf_material_t *done; /* mapped materials, committed when the whole file parsed */
    size_t ndone, cap_done;
    /* Maps not rendered, by kind: how many and the first line. */
    struct {
        char kw[16];
        unsigned count;
        int line;
    } maps[S_MAX_WARNED];
    int nmaps;
} s_ctx_t;

static int s_bad_number(s_ctx_t *c, const char *p)
{
    return pf_text_bad_number(c->err, c->path, c->line, p);
}

/* Rejects anything after the values except a comment. */
static int s_expect_end(s_ctx_t *c, const char *p, const char *kw)
{
    p = pf_text_skip_ws(p);
    if (pf_text_is_eol(*p))
        return PF_OK;
    return pf_error_set(c->err, PF_EPARSE, c->path, c->line, "unexpected '%.*s' after the values of %s",
                        pf_text_show(p), p, kw);
}

/* Reads one scalar statement value: finite, >= lo. */
static int s_scalar(s_ctx_t *c, const char *p, const char *kw, float lo, float *out)
{
    int rc = pf_text_float(&p, 0, out);
    if (rc == 1)
        return pf_error_set(c->err, PF_EPARSE, c->path, c->line, "%s needs a value", kw);
    if (rc < 0)
        return s_bad_number(c, p);
    if (!isfinite(*out))
        return pf_error_set(c->err, PF_EPARSE, c->path, c->line, "%s must be finite", kw);
    if (*out < lo)
        return pf_error_set(c->err, PF_EPARSE, c->path, c->line, "%s must be >= %g (got %g)", kw, lo, *out);
    return s_expect_end(c, p, kw);
}

/* Reads a scalar in [0, 1] (d, Tr, Pr, Pm): above 1 is clamped to 1, with a
 * warning. */
static int s_unit_scalar(s_ctx_t *c, const char *p, const char *kw, float *out)
{
    int rc = s_scalar(c, p, kw, 0.0f, out);
    if (rc == PF_OK && *out > 1.0f) {
        pf_warn("%s:%d: %s %g above 1 clamped to 1", c->path, c->line, kw, *out);
        *out = 1.0f;
    }
    return rc;
}

/* Reads "r [g b]": finite and >= 0; with clamp, channels above 1 become 1. */
static int s_color(s_ctx_t *c, const char *p, const char *kw, int clamp, pf_vec3 *out)
{
    const char *q = pf_text_skip_ws(p);
    if (strncasecmp(q, "spectral", 8) == 0 || strncasecmp(q, "xyz", 3) == 0)
        return pf_error_set(c->err, PF_EUNSUPPORTED, c->path, c->line,
                            "%s: only RGB colours are supported (not '%.*s')", kw, pf_text_show(q), q);
    float v[3];
    int n = 0;
    for (; n < 3; n++) {
        int rc = pf_text_float(&p, 0, &v[n]);
        if (rc == 1)
            break;
        if (rc < 0)
            return s_bad_number(c, p);
    }
    if (n == 0)
        return pf_error_set(c->err, PF_EPARSE, c->path, c->line, "%s needs a colour (r g b)", kw);
    if (n == 2)
        return pf_error_set(c->err, PF_EPARSE, c->path, c->line, "%s needs one value or three, not two", kw);
    if (n == 1)
        v[1] = v[2] = v[0];
    int rc = s_expect_end(c, p, kw);
    if (rc)
        return rc;
    int clamped = 0;
    for (int i = 0; i < 3; i++) {
        if (!isfinite(v[i]))
            return pf_error_set(c->err, PF_EPARSE, c->path, c->line, "%s must be finite", kw);
        if (v[i] < 0.0f)
            return pf_error_set(c->err, PF_EPARSE, c->path, c->line, "%s must not be negative (got %g)", kw, v[i]);
        if (clamp && v[i] > 1.0f) {
            v[i] = 1.0f;
            clamped = 1;
        }
    }
    if (clamped)
        pf_warn("%s:%d: %s above 1 clamped to 1 (a surface cannot reflect more than it receives)", c->path,
                c->line, kw);
    *out = pf_v3(v[0], v[1], v[2]);
    return PF_OK;
}

/* The PBR extension's mapping (Pr, Pm; the table above) of s onto *m. */
static void s_pbr(const s_mtl_t *s, pf_material_t *m)
{
    if (s->has_pm && s->pm > 0.5f) {
        float r = s->has_pr ? s->pr : 0.0f;
        m->type = PF_MAT_CONDUCTOR;
        m->ks = m->kd;
        m->eta = pf_v3s(1.0f);
        m->k = pf_v3(pf_conductor_k_of_reflectance(m->kd.x), pf_conductor_k_of_reflectance(m->kd.y),
                     pf_conductor_k_of_reflectance(m->kd.z));
        m->alpha = r * r;
        m->kd = pf_v3s(0.0f);
        return;
    }
    float r = s->has_pr ? s->pr : 1.0f;
    m->type = PF_MAT_COATED;
    m->ior = (s->has_ni && s->ni >= 1.0f) ? s->ni : 1.5f;
    m->alpha = r * r;
    m->thickness = 0.0f;
}

/* Maps a collected material (see the table above) and keeps it for the commit. */
static int s_finish(s_ctx_t *c, const s_mtl_t *s)
{
    pf_material_t m = pf_material_default(s->name);
    if (s->has_kd)
        m.kd = s->kd;
    m.le = s->has_ke ? s->ke : pf_v3s(0.0f);
    int illum = s->illum;
    pf_vec3 ones = pf_v3s(1.0f);
    if (illum == 3 || illum == 5 || illum == 8) {
        m.type = PF_MAT_MIRROR;
        m.ks = (s->has_ks && !pf_is_black(s->ks)) ? s->ks : ones;
        m.refl_tex = s->ks_tex; /* the reflectance times map_Ks per hit */
    } else if (illum == 4 || illum == 6 || illum == 7 || illum == 9) {
        m.type = PF_MAT_GLASS;
        m.ks = (s->has_ks && !pf_is_black(s->ks)) ? s->ks : ones;
        m.kt = s->has_tf ? s->tf : ones;
        m.ior = (s->has_ni && s->ni > 0.0f) ? s->ni : 1.5f;
    } else if ((s->has_pr || s->has_pm) && illum <= 2) {
        s_pbr(s, &m);
    } else {
        if (illum > 10) /* negative values were rejected while parsing */
            pf_warn("%s:%d: material '%s': unknown illum %d, treated as 2 (diffuse + Phong)", c->path, s->line,
                    s->name, illum);
        m.type = PF_MAT_DIFFUSE;
        int lobe = s->has_ks ? !pf_is_black(s->ks) : s->ks_tex != 0; /* map_Ks without Ks: Ks 1 */
        int phong = lobe && (illum == 2 || illum > 10 || (illum < 0 && s->has_ns));
        if (phong) {
            m.ks = s->has_ks ? s->ks : ones;
            m.ns = s->has_ns ? s->ns : 1.0f;
            m.refl_tex = s->ks_tex; /* ks times map_Ks per hit, at most 1 - kd (accel/surface.c) */
            float mx = pf_maxc(pf_add(m.kd, m.ks));
            if (mx > 1.0f && s->has_ks) {
                float k = 1.0f / mx;
                m.kd = pf_scale(m.kd, k);
                m.ks = pf_scale(m.ks, k);
                pf_warn("%s:%d: material '%s': Kd + Ks = %g exceeds 1; both scaled by %g to conserve energy",
                        c->path, s->line, s->name, mx, k);
            }
        }
        if (s->has_d && s->d < 1.0f)
            pf_warn("%s:%d: material '%s': transparency (d %g) is ignored for illum 0-2; the surface is opaque",
                    c->path, s->line, s->name, s->d);
    }
    if (s->ks_tex && !m.refl_tex)
        pf_warn("%s:%d: material '%s': map_Ks is not rendered for this kind of material (only for a Phong lobe, "
                "illum 2, and a mirror, illum 3, 5, 8)",
                c->path, s->line, s->name);
    if (s->kd_tex && (m.type == PF_MAT_DIFFUSE || m.type == PF_MAT_COATED))
        m.kd_tex = s->kd_tex;
    else if (s->kd_tex && m.type == PF_MAT_CONDUCTOR)
        m.refl_tex = s->kd_tex; /* the base colour textured: the reflectance form per hit */
    m.alpha_tex = s->d_tex;
    m.bump_tex = s->bump_tex; /* any kind: they bend the shading normal */
    m.normal_tex = s->norm_tex;
    if (pf_reserve((void **)&c->done, &c->cap_done, c->ndone + 1, sizeof *c->done))
        return pf_error_set(c->err, PF_ENOMEM, c->path, s->line, "out of memory");
    c->done[c->ndone++] = m;
    return PF_OK;
}

/* Adds the file's materials to the scene, each replacing one of its name. */
static int s_commit(s_ctx_t *c)
{
    for (size_t i = 0; i < c->ndone; i++) {
        int idx = pf_scene_find_material(c->scene, c->done[i].name);
        if (idx >= 0)
            c->scene->mats[idx] = c->done[i];
        else if (pf_scene_add_material(c->scene, &c->done[i]) < 0)
            return pf_error_set(c->err, PF_ENOMEM, c->path, 0, "out of memory");
    }
    return PF_OK;
}

/* newmtl: maps the material collected so far and starts the named one. */
static int s_newmtl(s_ctx_t *c, const char *p)
{
    s_mtl_t *cur = &c->cur;
    if (c->have) {
        int rc = s_finish(c, cur);
        if (rc)
            return rc;
    }
    size_t n;
    p = pf_text_rest(p, &n);
    if (n == 0)
        return pf_error_set(c->err, PF_EPARSE, c->path, c->line, "newmtl needs a name");
    if (n >= PF_NAME_MAX)
        pf_warn("%s:%d: material name '%.*s' truncated to %d bytes", c->path, c->line, (int)n, p, PF_NAME_MAX - 1);
    memset(cur, 0, sizeof *cur);
    snprintf(cur->name, sizeof cur->name, "%.*s", (int)n, p);
    cur->line = c->line;
    cur->illum = -1;
    c->have = 1;
    return PF_OK;
}

/* Counts a map statement that is not rendered, for the warnings at the end. */
static void s_map_unused(s_ctx_t *c, const char *kw, int kwlen)
{
    char k[16];
    snprintf(k, sizeof k, "%.*s", kwlen, kw);
    int i = 0;
    while (i < c->nmaps && strcasecmp(c->maps[i].kw, k) != 0)
        i++;
    if (i == c->nmaps) {
        if (c->nmaps == S_MAX_WARNED)
            i--; /* the table is full: counted with the last kind */
        else {
            c->nmaps++;
            memcpy(c->maps[i].kw, k, sizeof k);
            c->maps[i].line = c->line;
        }
    }
    c->maps[i].count++;
}

/* The options of a map statement this reader knows and how many values
 * each takes at most (-o, -s and -t take 1 to 3 numbers). */
static int s_map_option(const char *opt, size_t n)
{
    static const struct {
        const char *name;
        int nargs;
    } opts[] = { { "-blendu", 1 }, { "-blendv", 1 }, { "-bm", 1 },    { "-boost", 1 }, { "-cc", 1 },
                 { "-clamp", 1 },  { "-imfchan", 1 }, { "-mm", 2 },   { "-o", 3 },     { "-s", 3 },
                 { "-t", 3 },      { "-texres", 1 }, { "-type", 1 } };
    for (size_t i = 0; i < sizeof opts / sizeof *opts; i++)
        if (strlen(opts[i].name) == n && strncmp(opts[i].name, opt, n) == 0)
            return opts[i].nargs;
    return -1;
}

/* map_Kd, bump / map_Bump, norm, map_d or map_Ks [options] file (which 0,
 * 1, 2, 3, 4): reads the image into a scene texture (-bm, the bump
 * multiplier, its scale; a bump or normal map is linear: heights and
 * directions, not colours, and an alpha mask is a number; the two colour
 * maps are sRGB by default); a missing image is a warning. */
static int s_map_image(s_ctx_t *c, const char *p, int which)
{
    static const char *const kws[5] = { "map_Kd", "bump", "norm", "map_d", "map_Ks" };
    const char *kw = kws[which];
    pf_texture_t t = pf_texture_constant(c->cur.name, pf_v3s(0.0f));
    for (;;) {
        p = pf_text_skip_ws(p);
        if (*p != '-')
            break;
        const char *opt = p;
        while (!pf_text_is_delim(*p))
            p++;
        int nargs = s_map_option(opt, (size_t)(p - opt));
        if (nargs < 0)
            return pf_error_set(c->err, PF_EPARSE, c->path, c->line, "%s: unknown option '%.*s'", kw,
                                (int)(p - opt), opt);
        if ((size_t)(p - opt) == 6 && strncmp(opt, "-clamp", 6) == 0) {
            p = pf_text_skip_ws(p);
            if (!strncmp(p, "on", 2) && pf_text_is_delim(p[2]))
                t.wrap = PF_WRAP_CLAMP;
            while (!pf_text_is_delim(*p))
                p++;
            continue;
        }
        float v[3] = { 0, 0, 0 };
        int got = 0;
        for (; got < nargs; got++) {
            const char *q = pf_text_skip_ws(p);
            char *end;
            float x = strtof(q, &end);
            if (end == q || !pf_text_is_delim(*end))
                break;
            v[got] = x;
            p = end;
        }
        if ((size_t)(p - opt) >= 2 && opt[1] == 's' && pf_text_is_delim(opt[2]) && got >= 1) {
            t.su = v[0];
            t.sv = got >= 2 ? v[1] : 1.0f;
        } else if (which == 1 && (size_t)(p - opt) >= 3 && !strncmp(opt, "-bm", 3) && got >= 1) {
            t.scale = v[0];
        } else if (opt[1] == 'o' && pf_text_is_delim(opt[2]) && got >= 1) {
            t.du = v[0];
            t.dv = v[1];
        } else {
            /* -blendu, -bm, -mm, ...: not rendered, skipped (their words too). */
            while (got == 0 && nargs-- > 0) {
                p = pf_text_skip_ws(p);
                while (!pf_text_is_delim(*p))
                    p++;
            }
        }
    }
    size_t n;
    p = pf_text_rest(p, &n);
    if (n == 0)
        return pf_error_set(c->err, PF_EPARSE, c->path, c->line, "%s needs a file name", kw);
    char path[2048];
    const char *slash = strrchr(c->path, '/');
    int dirlen = slash && p[0] != '/' ? (int)(slash - c->path + 1) : 0;
    if (snprintf(path, sizeof path, "%.*s%.*s", dirlen, c->path, (int)n, p) >= (int)sizeof path)
        return pf_error_set(c->err, PF_EPARSE, c->path, c->line, "%s: path too long", kw);
    pf_error_t e = { { 0 } };
    int colour = which == 0 || which == 4;
    int ref = pf_texture_load_image(c->scene, path, &t, colour ? PF_TEXENC_DEFAULT : PF_TEXENC_LINEAR, c->path,
                                    c->line, &e);
    if (ref == PF_EIO) {
        /* A missing image, like a missing MTL file, is common in downloaded
         * models and not worth failing the scene over. */
        pf_warn("%s; %s", e.msg,
                which == 0   ? "Kd stands in"
                : which == 4 ? "Ks stands in"
                : which == 3 ? "the surface stays opaque"
                             : "the surface stays unbent");
        return PF_OK;
    }
    if (ref < 0) {
        if (c->err)
            *c->err = e;
        return ref;
    }
    uint32_t *out[5] = { &c->cur.kd_tex, &c->cur.bump_tex, &c->cur.norm_tex, &c->cur.d_tex, &c->cur.ks_tex };
    *out[which] = (uint32_t)ref;
    return PF_OK;
}

/* Handles one statement (keyword kw of length kwlen, values at p) for
 * pf_text_read_statements; arg is the s_ctx_t. */
static int s_statement(void *arg, const char *kw, int kwlen, const char *p)
{
    s_ctx_t *c = arg;
    s_mtl_t *cur = &c->cur;
#define S_KW(s) (kwlen == (int)sizeof(s) - 1 && strncasecmp(kw, s, sizeof(s) - 1) == 0)
    if (S_KW("newmtl"))
        return s_newmtl(c, p);
    if (S_KW("map_Kd") || S_KW("map_d") || S_KW("bump") || S_KW("map_Bump") || S_KW("norm") || S_KW("map_Ks")) {
        if (!c->have)
            return pf_error_set(c->err, PF_EPARSE, c->path, c->line, "%.*s before any newmtl", kwlen, kw);
        return s_map_image(c, p, S_KW("map_Kd") ? 0 : S_KW("norm") ? 2 : S_KW("map_d") ? 3 : S_KW("map_Ks") ? 4 : 1);
    }
    if ((kwlen > 4 && strncasecmp(kw, "map_", 4) == 0) || S_KW("bump") || S_KW("disp") || S_KW("decal") ||
        S_KW("refl") || S_KW("norm")) {
        s_map_unused(c, kw, kwlen);
        return PF_OK;
    }
    if (S_KW("Ka") || S_KW("sharpness"))
        return PF_OK;
    int known = S_KW("Kd") || S_KW("Ks") || S_KW("Ke") || S_KW("Tf") || S_KW("Ns") || S_KW("Ni") || S_KW("d") ||
                S_KW("Tr") || S_KW("illum") || S_KW("Pr") || S_KW("Pm");
    if (!known) {
        pf_text_warn_keyword(&c->warned, c->path, c->line, kw, kwlen);
        return PF_OK;
    }
    char name[8];
    snprintf(name, sizeof name, "%.*s", kwlen, kw);
    if (!c->have)
        return pf_error_set(c->err, PF_EPARSE, c->path, c->line, "%s before any newmtl", name);
    if (S_KW("Kd")) {
        cur->has_kd = 1;
        return s_color(c, p, name, 1, &cur->kd);
    }
    if (S_KW("Ks")) {
        cur->has_ks = 1;
        return s_color(c, p, name, 1, &cur->ks);
    }
    if (S_KW("Tf")) {
        cur->has_tf = 1;
        return s_color(c, p, name, 1, &cur->tf);
    }
    if (S_KW("Ke")) {
        cur->has_ke = 1;
        return s_color(c, p, name, 0, &cur->ke);
    }
    if (S_KW("Ns")) {
        cur->has_ns = 1;
        return s_scalar(c, p, name, 0.0f, &cur->ns);
    }
    if (S_KW("Ni")) {
        int rc = s_scalar(c, p, name, 0.0f, &cur->ni);
        cur->has_ni = cur->ni > 0.0f; /* Ni 0 means "unset" to many exporters */
        return rc;
    }
    if (S_KW("Pr") || S_KW("Pm")) {
        float v;
        int rc = s_unit_scalar(c, p, name, &v);
        if (rc)
            return rc;
        *(S_KW("Pr") ? &cur->pr : &cur->pm) = v;
        *(S_KW("Pr") ? &cur->has_pr : &cur->has_pm) = 1;
        return PF_OK;
    }
    if (S_KW("d") || S_KW("Tr")) {
        float v;
        int rc = s_unit_scalar(c, p, name, &v);
        if (rc)
            return rc;
        cur->has_d = 1;
        cur->d = S_KW("d") ? v : 1.0f - v;
        return PF_OK;
    }
    /* illum: a non-negative integer. */
    p = pf_text_skip_ws(p);
    char *end;
    long v = strtol(p, &end, 10);
    if (end == p || !pf_text_is_delim(*end) || v < 0 || v > 1000)
        return pf_error_set(c->err, PF_EPARSE, c->path, c->line, "illum needs an integer in 0..10, not '%.*s'",
                            pf_text_show(p), p);
    cur->illum = (int)v;
    return s_expect_end(c, end, "illum");
#undef S_KW
}

int pf_mtl_load(pf_scene_t *scene, const char *path, pf_error_t *err)
{
    PF_CHECK(scene && path);
    FILE *f = fopen(path, "rb");
    if (!f)
        return pf_error_set(err, PF_EIO, path, 0, "cannot open material library: %s", strerror(errno));
    s_ctx_t c = { .scene = scene, .path = path, .err = err, .warned = { .max = S_MAX_WARNED } };
    int rc = pf_text_read_statements(f, path, &c.line, err, s_statement, &c);
    if (rc == PF_OK && c.have)
        rc = s_finish(&c, &c.cur);
    if (rc == PF_OK)
        rc = s_commit(&c); /* nothing reaches the scene from a file with an error */
    for (int i = 0; rc == PF_OK && i < c.nmaps; i++)
        pf_warn("%s:%d: %s is not rendered (%u statement%s in this file; only map_Kd, map_Ks, map_d, bump and norm are)", path, c.maps[i].line,
                c.maps[i].kw, c.maps[i].count, c.maps[i].count == 1 ? "" : "s");
    free(c.done);
    fclose(f);
    return rc;
}
