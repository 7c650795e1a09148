/* pbrt_param.c: the pbrt-v4 reader's parameter lists ("type name" [ values ]
 * or one value without brackets), their typed look-ups, and the conversion
 * of pbrt's colours and spectra to the linear sRGB the scene model holds.
 * It owns the lists it reads (pf_pbrt_params_free). Single-threaded.
 *
 * A look-up marks its parameter used; pf_pbrt_check_unused warns about the
 * rest, once per parameter name. A parameter of the right name but another
 * type than asked is an error (pbrt-v4 stops on such an unused parameter).
 *
 * Spectra to RGB (pbrt renders spectrally; these are the RGB equivalents):
 *   - emitters (PF_PBRT_ILLUMINANT): pbrt divides an emitter's spectrum by
 *     its luminance before the light's scale, so a blackbody or a sampled
 *     spectrum becomes the sRGB colour of luminance 1; rgb values are taken
 *     as they are (pbrt normalizes only the colour space's illuminant);
 *   - reflectances (PF_PBRT_ALBEDO): the colour of the spectrum under a
 *     6504 K blackbody (close to D65), divided by that white's colour, so a
 *     constant spectrum gives the same grey;
 *   - eta and k (PF_PBRT_UNBOUNDED): the spectrum at 630, 532 and 465 nm.
 * XYZ comes from the analytic colour-matching functions of Wyman, Sloan and
 * Shirley (JCGT 2013), integrated 360..830 nm in 1 nm steps; their error
 * against the CIE tables (about 1 %) is far below what these conversions
 * need. The named metals are the RGB eta/k constants renderers commonly fit
 * from the same measured data (see docs/pbrt.md). */
#include <errno.h>
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "base/reserve.h"
#include "load/pbrt/pbrt_impl.h"

static const struct {
    const char *name;
    pf_pbrt_ptype type;
} s_types[] = {
    { "float", PF_PBRT_P_FLOAT },     { "integer", PF_PBRT_P_INTEGER },   { "bool", PF_PBRT_P_BOOL },
    { "string", PF_PBRT_P_STRING },   { "rgb", PF_PBRT_P_RGB },           { "color", PF_PBRT_P_RGB },
    { "spectrum", PF_PBRT_P_SPECTRUM }, { "blackbody", PF_PBRT_P_BLACKBODY }, { "point2", PF_PBRT_P_POINT2 },
    { "vector2", PF_PBRT_P_VECTOR2 }, { "point3", PF_PBRT_P_POINT3 },     { "point", PF_PBRT_P_POINT3 },
    { "vector3", PF_PBRT_P_VECTOR3 }, { "vector", PF_PBRT_P_VECTOR3 },    { "normal3", PF_PBRT_P_NORMAL3 },
    { "normal", PF_PBRT_P_NORMAL3 },  { "texture", PF_PBRT_P_TEXTURE },
};

static const char *s_type_name(pf_pbrt_ptype t)
{
    for (size_t i = 0; i < sizeof s_types / sizeof *s_types; i++)
        if (s_types[i].type == t)
            return s_types[i].name;
    return "?";
}

void pf_pbrt_params_free(pf_pbrt_params_t *ps)
{
    for (size_t i = 0; i < ps->n; i++) {
        pf_pbrt_param_t *p = &ps->p[i];
        free(p->name);
        free(p->num);
        for (size_t k = 0; k < p->nstr; k++)
            free(p->str[k]);
        free(p->str);
    }
    free(ps->p);
    memset(ps, 0, sizeof *ps);
}

/* Splits the declaration "type name" into p's type and name. */
static int s_decl(pf_pbrt_t *c, const pf_pbrt_tok_t *t, pf_pbrt_param_t *p)
{
    char *d = NULL;
    int rc = pf_pbrt_tok_string(c, t, &d);
    if (rc)
        return rc;
    char *save = NULL, *type = strtok_r(d, " \t", &save), *name = type ? strtok_r(NULL, " \t", &save) : NULL;
    if (!type || !name || strtok_r(NULL, " \t", &save)) {
        free(d);
        return pf_pbrt_error(c, PF_EPARSE, t->loc, "expected a parameter declaration \"type name\", found \"%.60s\"",
                             t->text);
    }
    size_t i = 0;
    while (i < sizeof s_types / sizeof *s_types && strcmp(s_types[i].name, type) != 0)
        i++;
    if (i == sizeof s_types / sizeof *s_types) {
        rc = pf_pbrt_error(c, PF_EPARSE, t->loc, "unknown parameter type '%.40s'", type);
        free(d);
        return rc;
    }
    p->type = s_types[i].type;
    p->name = strdup(name);
    free(d);
    return p->name ? PF_OK : pf_pbrt_error(c, PF_ENOMEM, t->loc, "out of memory");
}

/* Appends one value token to p, checked against its type. */
static int s_value(pf_pbrt_t *c, const pf_pbrt_tok_t *t, pf_pbrt_param_t *p)
{
    pf_pbrt_ptype ty = p->type;
    int want_str = ty == PF_PBRT_P_STRING || ty == PF_PBRT_P_TEXTURE || (ty == PF_PBRT_P_SPECTRUM && t->kind == PF_PBRT_STRING);
    if (ty == PF_PBRT_P_BOOL) {
        int v = -1;
        if (t->kind == PF_PBRT_WORD || t->kind == PF_PBRT_STRING) {
            if (t->len == 4 && memcmp(t->text, "true", 4) == 0)
                v = 1;
            else if (t->len == 5 && memcmp(t->text, "false", 5) == 0)
                v = 0;
        }
        if (v < 0)
            return pf_pbrt_error(c, PF_EPARSE, t->loc, "bool parameter '%s' takes true or false", p->name);
        if (pf_reserve((void **)&p->num, &p->cap_num, p->nnum + 1, sizeof *p->num))
            return pf_pbrt_error(c, PF_ENOMEM, t->loc, "out of memory");
        p->num[p->nnum++] = v;
        return PF_OK;
    }
    if (want_str) {
        if (t->kind != PF_PBRT_STRING)
            return pf_pbrt_error(c, PF_EPARSE, t->loc, "%s parameter '%s' takes quoted strings", s_type_name(ty), p->name);
        if (p->nnum)
            return pf_pbrt_error(c, PF_EPARSE, t->loc, "spectrum '%s' mixes numbers and a name", p->name);
        char *s = NULL;
        int rc = pf_pbrt_tok_string(c, t, &s);
        if (rc)
            return rc;
        if (pf_reserve((void **)&p->str, &p->cap_str, p->nstr + 1, sizeof *p->str)) {
            free(s);
            return pf_pbrt_error(c, PF_ENOMEM, t->loc, "out of memory");
        }
        p->str[p->nstr++] = s;
        return PF_OK;
    }
    if (p->nstr)
        return pf_pbrt_error(c, PF_EPARSE, t->loc, "spectrum '%s' mixes numbers and a name", p->name);
    double v;
    int rc = pf_pbrt_tok_number(c, t, &v);
    if (rc)
        return rc;
    if (ty == PF_PBRT_P_INTEGER && (v != floor(v) || fabs(v) > 2147483647.0))
        return pf_pbrt_error(c, PF_ERANGE, t->loc, "integer parameter '%s': %.40s is not a 32-bit integer", p->name,
                             t->text);
    if (pf_reserve((void **)&p->num, &p->cap_num, p->nnum + 1, sizeof *p->num))
        return pf_pbrt_error(c, PF_ENOMEM, t->loc, "out of memory");
    p->num[p->nnum++] = v;
    return PF_OK;
}

/* Reads the value(s) of p: [ v ... ] or one value. */
static int s_values(pf_pbrt_t *c, pf_pbrt_param_t *p)
{
    pf_pbrt_tok_t t;
    int rc = pf_pbrt_next(c, &t);
    if (rc)
        return rc;
    if (t.kind != PF_PBRT_LBRACK) {
        if (t.kind == PF_PBRT_EOF || t.kind == PF_PBRT_RBRACK)
            return pf_pbrt_error(c, PF_EPARSE, t.loc, "parameter '%s' has no value", p->name);
        return s_value(c, &t, p);
    }
    for (;;) {
        if ((rc = pf_pbrt_next(c, &t)))
            return rc;
        if (t.kind == PF_PBRT_RBRACK)
            return PF_OK;
        if (t.kind == PF_PBRT_EOF || t.kind == PF_PBRT_LBRACK)
            return pf_pbrt_error(c, PF_EPARSE, t.loc, "%s inside the values of '%s' (a ']' is missing)",
                                 t.kind == PF_PBRT_EOF ? "end of file" : "'['", p->name);
        if ((rc = s_value(c, &t, p)))
            return rc;
    }
}

int pf_pbrt_read_params(pf_pbrt_t *c, pf_pbrt_params_t *out)
{
    memset(out, 0, sizeof *out);
    for (;;) {
        pf_pbrt_tok_t t;
        int rc = pf_pbrt_peek(c, &t);
        if (rc)
            return rc;
        if (t.kind != PF_PBRT_STRING)
            return PF_OK;
        pf_pbrt_next(c, &t);
        if (pf_reserve((void **)&out->p, &out->cap, out->n + 1, sizeof *out->p))
            return pf_pbrt_error(c, PF_ENOMEM, t.loc, "out of memory");
        pf_pbrt_param_t *p = &out->p[out->n++];
        memset(p, 0, sizeof *p);
        p->loc = t.loc;
        if ((rc = s_decl(c, &t, p)))
            return rc;
        for (size_t i = 0; i + 1 < out->n; i++)
            if (strcmp(out->p[i].name, p->name) == 0)
                return pf_pbrt_error(c, PF_EPARSE, t.loc, "parameter '%s' given twice", p->name);
        if ((rc = s_values(c, p)))
            return rc;
    }
}

pf_pbrt_param_t *pf_pbrt_param(pf_pbrt_params_t *ps, const char *name)
{
    for (size_t i = 0; i < ps->n; i++) {
        if (strcmp(ps->p[i].name, name) == 0) {
            ps->p[i].used = 1;
            return &ps->p[i];
        }
    }
    return NULL;
}

/* The parameter name of one of the types in mask (bits of pf_pbrt_ptype),
 * or NULL; a parameter of that name but another type is an error. */
static int s_find(pf_pbrt_t *c, pf_pbrt_params_t *ps, const char *name, unsigned mask, const char *want,
                  pf_pbrt_param_t **out)
{
    pf_pbrt_param_t *p = pf_pbrt_param(ps, name);
    *out = NULL;
    if (!p)
        return PF_OK;
    if (!(mask & (1u << p->type)))
        return pf_pbrt_error(c, PF_EPARSE, p->loc, "parameter '%s' must be %s, not %s", name, want,
                             s_type_name(p->type));
    *out = p;
    return PF_OK;
}

#define S_BIT(t) (1u << (t))

/* One number of a parameter of the types in mask: def when absent. */
static int s_one(pf_pbrt_t *c, pf_pbrt_params_t *ps, const char *name, unsigned mask, const char *want, double def,
                 double *out)
{
    pf_pbrt_param_t *p;
    int rc = s_find(c, ps, name, mask, want, &p);
    if (rc)
        return rc;
    *out = def;
    if (!p)
        return PF_OK;
    if (p->nnum != 1)
        return pf_pbrt_error(c, PF_EPARSE, p->loc, "parameter '%s' takes one value, not %zu", name, p->nnum);
    *out = p->num[0];
    return PF_OK;
}

int pf_pbrt_get_float(pf_pbrt_t *c, pf_pbrt_params_t *ps, const char *name, double def, double *out)
{
    return s_one(c, ps, name, S_BIT(PF_PBRT_P_FLOAT) | S_BIT(PF_PBRT_P_INTEGER), "float", def, out);
}

int pf_pbrt_get_int(pf_pbrt_t *c, pf_pbrt_params_t *ps, const char *name, int def, int *out)
{
    double v = def;
    int rc = s_one(c, ps, name, S_BIT(PF_PBRT_P_INTEGER), "integer", def, &v);
    *out = (int)v; /* integral and within int32: checked when read */
    return rc;
}

int pf_pbrt_get_bool(pf_pbrt_t *c, pf_pbrt_params_t *ps, const char *name, int def, int *out)
{
    double v = def;
    int rc = s_one(c, ps, name, S_BIT(PF_PBRT_P_BOOL), "bool", def, &v);
    *out = v != 0.0;
    return rc;
}

int pf_pbrt_get_string(pf_pbrt_t *c, pf_pbrt_params_t *ps, const char *name, const char *def, const char **out)
{
    pf_pbrt_param_t *p;
    int rc = s_find(c, ps, name, S_BIT(PF_PBRT_P_STRING), "string", &p);
    *out = def;
    if (rc || !p)
        return rc;
    if (p->nstr != 1)
        return pf_pbrt_error(c, PF_EPARSE, p->loc, "parameter '%s' takes one string, not %zu", name, p->nstr);
    *out = p->str[0];
    return PF_OK;
}

#define S_VEC3_TYPES (S_BIT(PF_PBRT_P_POINT3) | S_BIT(PF_PBRT_P_VECTOR3) | S_BIT(PF_PBRT_P_NORMAL3))

int pf_pbrt_get_point3(pf_pbrt_t *c, pf_pbrt_params_t *ps, const char *name, pf_vec3 def, double out[3])
{
    pf_pbrt_param_t *p;
    int rc = s_find(c, ps, name, S_VEC3_TYPES, "point3", &p);
    out[0] = def.x;
    out[1] = def.y;
    out[2] = def.z;
    if (rc || !p)
        return rc;
    if (p->nnum != 3)
        return pf_pbrt_error(c, PF_EPARSE, p->loc, "parameter '%s' takes 3 values, not %zu", name, p->nnum);
    memcpy(out, p->num, 3 * sizeof *out);
    return PF_OK;
}

int pf_pbrt_get_vec3s(pf_pbrt_t *c, pf_pbrt_params_t *ps, const char *name, const double **out, size_t *n)
{
    pf_pbrt_param_t *p;
    int rc = s_find(c, ps, name, S_VEC3_TYPES, "point3 or normal", &p);
    *out = NULL;
    *n = 0;
    if (rc || !p)
        return rc;
    if (p->nnum % 3)
        return pf_pbrt_error(c, PF_EPARSE, p->loc, "parameter '%s' has %zu values, not a multiple of 3", name, p->nnum);
    *out = p->num;
    *n = p->nnum / 3;
    return PF_OK;
}

int pf_pbrt_get_ints(pf_pbrt_t *c, pf_pbrt_params_t *ps, const char *name, int64_t hi, uint32_t **out, size_t *n)
{
    pf_pbrt_param_t *p;
    int rc = s_find(c, ps, name, S_BIT(PF_PBRT_P_INTEGER), "integer", &p);
    *out = NULL;
    *n = 0;
    if (rc || !p)
        return rc;
    uint32_t *v = malloc((p->nnum ? p->nnum : 1) * sizeof *v);
    if (!v)
        return pf_pbrt_error(c, PF_ENOMEM, p->loc, "out of memory");
    for (size_t i = 0; i < p->nnum; i++) {
        if (p->num[i] < 0 || p->num[i] > (double)hi) {
            free(v);
            return pf_pbrt_error(c, PF_ERANGE, p->loc, "parameter '%s': value %zu (%.0f) out of range [0, %lld]", name,
                                 i, p->num[i], (long long)hi);
        }
        v[i] = (uint32_t)p->num[i];
    }
    *out = v;
    *n = p->nnum;
    return PF_OK;
}

int pf_pbrt_check_unused(pf_pbrt_t *c, pf_pbrt_params_t *ps, const char *what)
{
    for (size_t i = 0; i < ps->n; i++) {
        pf_pbrt_param_t *p = &ps->p[i];
        if (p->used)
            continue;
        p->used = 1;
        char kind[96];
        snprintf(kind, sizeof kind, "unused parameter \"%s %.60s\"", s_type_name(p->type), p->name);
        int rc = pf_pbrt_warn(c, p->loc, kind, "%s: parameter \"%s %s\" is not used (ignored)", what,
                              s_type_name(p->type), p->name);
        if (rc)
            return rc;
    }
    return PF_OK;
}

/* ---- colour ---- */

static double s_g(double x, double mu, double s1, double s2)
{
    double t = (x - mu) / (x < mu ? s1 : s2);
    return exp(-0.5 * t * t);
}

/* XYZ of a spectrum given as a function of wavelength in nm. */
static void s_xyz(double (*f)(double, const void *), const void *arg, double xyz[3])
{
    xyz[0] = xyz[1] = xyz[2] = 0.0;
    for (int l = 360; l <= 830; l++) {
        double v = f(l, arg);
        xyz[0] += v * (1.056 * s_g(l, 599.8, 37.9, 31.0) + 0.362 * s_g(l, 442.0, 16.0, 26.7) -
                       0.065 * s_g(l, 501.1, 20.4, 26.2));
        xyz[1] += v * (0.821 * s_g(l, 568.8, 46.9, 40.5) + 0.286 * s_g(l, 530.9, 16.3, 31.1));
        xyz[2] += v * (1.217 * s_g(l, 437.0, 11.8, 36.0) + 0.681 * s_g(l, 459.0, 26.0, 13.8));
    }
}

/* Linear sRGB (D65) of XYZ, not clamped. */
static void s_rgb(const double xyz[3], double rgb[3])
{
    rgb[0] = 3.2404542 * xyz[0] - 1.5371385 * xyz[1] - 0.4985314 * xyz[2];
    rgb[1] = -0.9692660 * xyz[0] + 1.8760108 * xyz[1] + 0.0415560 * xyz[2];
    rgb[2] = 0.0556434 * xyz[0] - 0.2040259 * xyz[1] + 1.0572252 * xyz[2];
}

static double s_planck(double nm, const void *arg)
{
    double T = *(const double *)arg, l = nm * 1e-9;
    /* Relative spectral radiance; the constant 2hc^2 cancels in every use. */
    return 1.0 / (l * l * l * l * l * (exp(1.4387769e-2 / (l * T)) - 1.0)) * 1e-30;
}

pf_vec3 pf_pbrt_blackbody(double kelvin)
{
    double xyz[3], rgb[3];
    if (!(kelvin > 0.0))
        return pf_v3s(0.0f);
    s_xyz(s_planck, &kelvin, xyz);
    double y = xyz[1];
    if (!(y > 0.0) || !isfinite(y))
        return pf_v3s(0.0f);
    for (int i = 0; i < 3; i++)
        xyz[i] /= y;
    s_rgb(xyz, rgb);
    return pf_v3((float)fmax(rgb[0], 0.0), (float)fmax(rgb[1], 0.0), (float)fmax(rgb[2], 0.0));
}

/* A piecewise-linear spectrum: n (wavelength, value) pairs, wavelengths increasing. */
typedef struct s_spd {
    const double *v;
    size_t n;
    double white_T; /* > 0: multiplied by this blackbody (reflectances) */
} s_spd_t;

static double s_spd_at(const s_spd_t *s, double nm)
{
    const double *v = s->v;
    if (nm <= v[0])
        return v[1];
    if (nm >= v[2 * (s->n - 1)])
        return v[2 * s->n - 1];
    size_t lo = 0, hi = s->n - 1;
    while (hi - lo > 1) {
        size_t mid = (lo + hi) / 2;
        if (v[2 * mid] <= nm)
            lo = mid;
        else
            hi = mid;
    }
    double t = (nm - v[2 * lo]) / (v[2 * hi] - v[2 * lo]);
    return v[2 * lo + 1] + t * (v[2 * hi + 1] - v[2 * lo + 1]);
}

static double s_spd_fn(double nm, const void *arg)
{
    const s_spd_t *s = arg;
    double v = s_spd_at(s, nm);
    return s->white_T > 0.0 ? v * s_planck(nm, &s->white_T) : v;
}

/* The RGB of a sampled spectrum used as st. */
static pf_vec3 s_spd_rgb(const s_spd_t *spd, pf_pbrt_stype st)
{
    if (st == PF_PBRT_UNBOUNDED)
        return pf_v3((float)s_spd_at(spd, 630), (float)s_spd_at(spd, 532), (float)s_spd_at(spd, 465));
    double xyz[3], rgb[3];
    s_spd_t s = *spd;
    s.white_T = st == PF_PBRT_ALBEDO ? 6504.0 : 0.0;
    s_xyz(s_spd_fn, &s, xyz);
    if (st == PF_PBRT_ILLUMINANT) {
        double y = xyz[1];
        if (!(y > 0.0) || !isfinite(y))
            return pf_v3s(0.0f);
        for (int i = 0; i < 3; i++)
            xyz[i] /= y;
        s_rgb(xyz, rgb);
    } else {
        double wxyz[3], wrgb[3];
        s_xyz(s_planck, &s.white_T, wxyz);
        s_rgb(xyz, rgb);
        s_rgb(wxyz, wrgb);
        for (int i = 0; i < 3; i++)
            rgb[i] /= wrgb[i];
    }
    return pf_v3((float)fmax(rgb[0], 0.0), (float)fmax(rgb[1], 0.0), (float)fmax(rgb[2], 0.0));
}

static const struct {
    const char *name;
    float eta[3], k[3];
} s_metals[] = {
    { "Ag", { 0.155265f, 0.116723f, 0.138342f }, { 4.828181f, 3.122249f, 2.146961f } },
    { "Al", { 1.657460f, 0.880369f, 0.521229f }, { 9.223869f, 6.269523f, 4.837001f } },
    { "Au", { 0.143119f, 0.374957f, 1.442479f }, { 3.983160f, 2.385721f, 1.603215f } },
    { "Cu", { 0.200438f, 0.924033f, 1.102212f }, { 3.912949f, 2.452848f, 2.142188f } },
    { "CuZn", { 0.444f, 0.527f, 1.094f }, { 3.695f, 2.765f, 1.829f } },
    { "MgO", { 1.7298f, 1.7357f, 1.7462f }, { 0.0f, 0.0f, 0.0f } },
    { "TiO2", { 2.5870f, 2.6650f, 2.8400f }, { 0.0f, 0.0f, 0.0f } },
};

int pf_pbrt_named_metal(const char *name, pf_vec3 *out)
{
    if (strncmp(name, "metal-", 6) != 0)
        return 0;
    for (size_t i = 0; i < sizeof s_metals / sizeof *s_metals; i++) {
        size_t n = strlen(s_metals[i].name);
        const char *rest = name + 6 + n;
        if (strncmp(name + 6, s_metals[i].name, n) != 0 || (strcmp(rest, "-eta") != 0 && strcmp(rest, "-k") != 0))
            continue;
        const float *v = rest[1] == 'e' ? s_metals[i].eta : s_metals[i].k;
        *out = pf_v3(v[0], v[1], v[2]);
        return 1;
    }
    return 0;
}

int pf_pbrt_named_glass(const char *name, double *ior)
{
    static const struct {
        const char *name;
        double ior;
    } glass[] = {
        { "glass-BK7", 1.5168 },  { "glass-BAF10", 1.6700 }, { "glass-FK51A", 1.4866 }, { "glass-LASF9", 1.8503 },
        { "glass-F5", 1.6727 },   { "glass-F10", 1.7283 },   { "glass-F11", 1.7847 },   { "glass-SF5", 1.6727 },
        { "glass-SF10", 1.7283 }, { "glass-SF11", 1.7847 },
    };
    for (size_t i = 0; i < sizeof glass / sizeof *glass; i++) {
        if (strcmp(name, glass[i].name) == 0) {
            *ior = glass[i].ior;
            return 1;
        }
    }
    return 0;
}

/* Checks sampled-spectrum values: (wavelength, value) pairs, wavelengths
 * increasing; fills spd. */
static int s_spd_check(pf_pbrt_t *c, pf_pbrt_loc_t loc, const char *name, const double *v, size_t nnum, s_spd_t *spd)
{
    if (nnum < 2 || nnum % 2)
        return pf_pbrt_error(c, PF_EPARSE, loc, "spectrum '%s' needs (wavelength, value) pairs, not %zu numbers", name,
                             nnum);
    for (size_t i = 0; i < nnum / 2; i++)
        if (!(v[2 * i] > 0.0) || (i > 0 && !(v[2 * i] > v[2 * i - 2])))
            return pf_pbrt_error(c, PF_EPARSE, loc, "spectrum '%s': wavelengths must be positive and increasing", name);
    *spd = (s_spd_t){ .v = v, .n = nnum / 2 };
    return PF_OK;
}

/* Reads a spectrum file (pairs of numbers, '#' comments) into *out. */
#define S_SPD_FILE_MAX (1 << 20)
static int s_spd_file(pf_pbrt_t *c, pf_pbrt_loc_t loc, const char *name, double **out, size_t *n)
{
    char path[4096];
    int rc = pf_pbrt_resolve(c, loc, name, 0, path, sizeof path);
    if (rc)
        return rc;
    FILE *f = fopen(path, "rb");
    if (!f)
        return pf_pbrt_error(c, PF_EIO, loc, "spectrum '%s' is not a known name, and the file '%s' cannot be read: %s",
                             name, path, strerror(errno));
    char *text = malloc(S_SPD_FILE_MAX + 2);
    double *v = NULL;
    size_t len = text ? fread(text, 1, S_SPD_FILE_MAX + 1, f) : 0, nv = 0, cap = 0;
    fclose(f);
    if (!text)
        return pf_pbrt_error(c, PF_ENOMEM, loc, "out of memory");
    if (len > S_SPD_FILE_MAX) {
        free(text);
        return pf_pbrt_error(c, PF_ERANGE, loc, "spectrum file '%s' is larger than %d bytes", path, S_SPD_FILE_MAX);
    }
    text[len] = '\0';
    for (char *p = text; *p;) {
        if (*p == '#') {
            while (*p && *p != '\n')
                p++;
            continue;
        }
        if (strchr(" \t\r\n,", *p)) {
            p++;
            continue;
        }
        char *end;
        double x = strtod(p, &end);
        if (end == p || !isfinite(x) || fabs(x) > PF_PBRT_MAX_NUMBER) {
            rc = pf_pbrt_error(c, PF_EPARSE, loc, "spectrum file '%s': malformed number '%.20s'", path, p);
            break;
        }
        if (pf_reserve((void **)&v, &cap, nv + 1, sizeof *v)) {
            rc = pf_pbrt_error(c, PF_ENOMEM, loc, "out of memory");
            break;
        }
        v[nv++] = x;
        p = end;
    }
    free(text);
    if (rc) {
        free(v);
        return rc;
    }
    *out = v;
    *n = nv;
    return PF_OK;
}

/* A spectrum given by name (named spectrum or file). */
static int s_named_color(pf_pbrt_t *c, pf_pbrt_param_t *p, pf_pbrt_stype st, pf_vec3 def, const char *what,
                         pf_vec3 *out)
{
    const char *name = p->str[0];
    double ior;
    pf_vec3 v;
    if (st == PF_PBRT_UNBOUNDED && pf_pbrt_named_metal(name, &v)) {
        *out = v;
        return PF_OK;
    }
    if (st == PF_PBRT_UNBOUNDED && pf_pbrt_named_glass(name, &ior)) {
        *out = pf_v3s((float)ior);
        return PF_OK;
    }
    if (st != PF_PBRT_UNBOUNDED && strcmp(name, "stdillum-D65") == 0) {
        *out = pf_v3s(1.0f);
        return PF_OK;
    }
    if (st != PF_PBRT_UNBOUNDED && strcmp(name, "stdillum-A") == 0) {
        *out = pf_pbrt_blackbody(2856.0); /* illuminant A is Planckian */
        return PF_OK;
    }
    if (!strncmp(name, "stdillum-", 9) || !strncmp(name, "illum-", 6) || !strncmp(name, "metal-", 6) ||
        !strncmp(name, "glass-", 6) || !strncmp(name, "canon_", 6) || !strncmp(name, "nikon_", 6) ||
        !strncmp(name, "sony_", 5)) {
        *out = st == PF_PBRT_ILLUMINANT ? pf_v3s(1.0f) : def;
        return pf_pbrt_warn(c, p->loc, "named spectrum (approximated)",
                            "%s: spectrum \"%s\" for '%s' is not in photonfarm's table: %g %g %g stands in", what, name,
                            p->name, out->x, out->y, out->z);
    }
    double *vals = NULL;
    size_t n = 0;
    s_spd_t spd;
    int rc = s_spd_file(c, p->loc, name, &vals, &n);
    if (rc == PF_OK && (rc = s_spd_check(c, p->loc, name, vals, n, &spd)) == PF_OK)
        *out = s_spd_rgb(&spd, st);
    free(vals);
    return rc;
}

static int s_color(pf_pbrt_t *c, pf_pbrt_params_t *ps, const char *name, pf_pbrt_stype st, pf_vec3 def,
                   const char *what, int allow_tex, pf_vec3 *out, int *found);

/* A colour parameter that names a texture. */
static int s_tex_color(pf_pbrt_t *c, pf_pbrt_param_t *p, pf_pbrt_stype st, pf_vec3 def, const char *what,
                       pf_vec3 *out)
{
    if (p->nstr != 1)
        return pf_pbrt_error(c, PF_EPARSE, p->loc, "texture parameter '%s' takes one texture name", p->name);
    pf_pbrt_tex_t *t;
    int rc = pf_pbrt_find_texture(c, p->str[0], 0, p->loc, &t);
    if (rc)
        return rc;
    if (strcmp(t->cls, "constant") == 0) {
        int found;
        return s_color(c, &t->params, "value", st, pf_v3s(1.0f), what, 0, out, &found);
    }
    *out = def;
    return pf_pbrt_warn(c, p->loc, "texture",
                        "%s: '%s' is the %s texture \"%s\", not rendered here (photonfarm renders image, checkerboard, "
                        "scale and mix textures as a diffuse reflectance): the constant (%g %g %g) stands in",
                        what, p->name, t->cls, p->str[0], def.x, def.y, def.z);
}

static int s_color(pf_pbrt_t *c, pf_pbrt_params_t *ps, const char *name, pf_pbrt_stype st, pf_vec3 def,
                   const char *what, int allow_tex, pf_vec3 *out, int *found)
{
    pf_pbrt_param_t *p;
    unsigned mask = S_BIT(PF_PBRT_P_RGB) | S_BIT(PF_PBRT_P_SPECTRUM) | S_BIT(PF_PBRT_P_BLACKBODY) |
                    (allow_tex ? S_BIT(PF_PBRT_P_TEXTURE) : 0);
    int rc = s_find(c, ps, name, mask, allow_tex ? "rgb, spectrum, blackbody or texture" : "rgb, spectrum or blackbody",
                    &p);
    *out = def;
    *found = p != NULL;
    if (rc || !p)
        return rc;
    s_spd_t spd;
    switch (p->type) {
    case PF_PBRT_P_RGB:
        if (p->nnum != 3)
            return pf_pbrt_error(c, PF_EPARSE, p->loc, "rgb parameter '%s' takes 3 values, not %zu", name, p->nnum);
        if (p->num[0] < 0 || p->num[1] < 0 || p->num[2] < 0)
            return pf_pbrt_error(c, PF_ERANGE, p->loc, "rgb parameter '%s' has a negative value", name);
        *out = pf_v3((float)p->num[0], (float)p->num[1], (float)p->num[2]);
        break;
    case PF_PBRT_P_BLACKBODY:
        if (p->nnum != 1 || !(p->num[0] > 0))
            return pf_pbrt_error(c, PF_EPARSE, p->loc, "blackbody '%s' takes one temperature in kelvin (> 0)", name);
        *out = pf_pbrt_blackbody(p->num[0]);
        break;
    case PF_PBRT_P_TEXTURE:
        return s_tex_color(c, p, st, def, what, out);
    default:
        if (p->nstr == 1)
            return s_named_color(c, p, st, def, what, out);
        if (p->nstr > 1)
            return pf_pbrt_error(c, PF_EPARSE, p->loc, "spectrum '%s' takes one name", name);
        if ((rc = s_spd_check(c, p->loc, name, p->num, p->nnum, &spd)))
            return rc;
        *out = s_spd_rgb(&spd, st);
        break;
    }
    if (st == PF_PBRT_ALBEDO && pf_maxc(*out) > 1.0f) {
        pf_vec3 was = *out;
        *out = pf_vmin(*out, pf_v3s(1.0f));
        return pf_pbrt_warn(c, p->loc, "reflectance above 1 (clamped)", "%s: '%s' (%g %g %g) clamped to 1", what, name,
                            was.x, was.y, was.z);
    }
    return PF_OK;
}

int pf_pbrt_get_color(pf_pbrt_t *c, pf_pbrt_params_t *ps, const char *name, pf_pbrt_stype st, pf_vec3 def,
                      const char *what, pf_vec3 *out, int *found)
{
    int dummy;
    return s_color(c, ps, name, st, def, what, 1, out, found ? found : &dummy);
}

int pf_pbrt_get_float_tex(pf_pbrt_t *c, pf_pbrt_params_t *ps, const char *name, double def, const char *what,
                          double *out, int *found)
{
    pf_pbrt_param_t *p;
    int rc = s_find(c, ps, name, S_BIT(PF_PBRT_P_FLOAT) | S_BIT(PF_PBRT_P_TEXTURE), "float or texture", &p);
    int dummy;
    found = found ? found : &dummy;
    *out = def;
    *found = p != NULL;
    if (rc || !p)
        return rc;
    if (p->type == PF_PBRT_P_FLOAT) {
        if (p->nnum != 1)
            return pf_pbrt_error(c, PF_EPARSE, p->loc, "parameter '%s' takes one value, not %zu", name, p->nnum);
        *out = p->num[0];
        return PF_OK;
    }
    if (p->nstr != 1)
        return pf_pbrt_error(c, PF_EPARSE, p->loc, "texture parameter '%s' takes one texture name", name);
    pf_pbrt_tex_t *t;
    if ((rc = pf_pbrt_find_texture(c, p->str[0], 1, p->loc, &t)))
        return rc;
    if (strcmp(t->cls, "constant") == 0)
        return pf_pbrt_get_float(c, &t->params, "value", 1.0, out);
    return pf_pbrt_warn(c, p->loc, "texture",
                        "%s: '%s' is the %s texture \"%s\"; textures are not rendered yet: the constant %g stands in",
                        what, name, t->cls, p->str[0], def);
}
