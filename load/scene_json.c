/* scene_json.c: the JSON scene format (docs/scene-format.md). It parses the
 * file with cJSON, checks every key and value, and appends the camera, render
 * settings, materials, objects (OBJ and PLY models through their loaders,
 * analytic spheres, quads) and point/spot lights to a pf_scene_t. It does not
 * finalize the scene; pf_scene_load does that.
 *
 * cJSON keeps no line numbers, so every error would otherwise lack the "where"
 * that a scene author needs. Two small pieces recover it: a syntax error's
 * line is counted from the parser's error position, and for everything else a
 * scanner walks the raw text (which cJSON has already accepted) in document
 * order, recording the line of every value and every object key; a walk over
 * the cJSON tree in the same order (cJSON keeps member order) pairs each node
 * with its lines. Errors then read "file:line: what" with the line of the
 * offending key or value.
 *
 * Owns nothing beyond the call: the text, the tree and the line table are
 * freed before returning. Called from one thread at a time per scene. */
#include "load/load.h"

#include <cjson/cJSON.h>
#include <errno.h>
#include <float.h>
#include <math.h>
#include <stdarg.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

/* Scene files are hand-written or generated descriptions; geometry lives in
 * OBJ/PLY files. 64 MiB is far beyond any sane scene and bounds the memory a
 * corrupt path can make us allocate. */
#define S_MAX_FILE_BYTES (64u << 20)

/* uint64 settings travel through a JSON number (a double): integers are exact
 * only up to 2^53, so larger values are refused rather than rounded. */
#define S_MAX_EXACT_INT 9007199254740992.0

/* Entries in an obj object's "materials" map (MTL files with more distinct
 * materials than this are not plausible). */
#define S_MAX_REMAP 4096

/* ------------------------------------------------------------------------ */
/* Line table                                                               */

typedef struct s_line {
    const cJSON *node;
    int key_line; /* line of the member's key; the value's line for array elements and the root */
    int line;     /* line where the value starts */
} s_line_t;

/* The scanner's state: the raw text and the lines it emits in document order
 * (for an object member: the key's line, then the value's lines). */
typedef struct s_scan {
    const char *text;
    size_t len, pos;
    int line;
    int *out;
    size_t n, cap;
    int ok;
    int nomem; /* ok was cleared by a failed allocation */
} s_scan_t;

static void s_scan_emit(s_scan_t *sc, int line)
{
    if (!sc->ok)
        return;
    if (sc->n == sc->cap) {
        size_t ncap = sc->cap ? 2 * sc->cap : 256;
        int *p = realloc(sc->out, ncap * sizeof *p);
        if (!p) {
            sc->ok = 0;
            sc->nomem = 1;
            return;
        }
        sc->out = p;
        sc->cap = ncap;
    }
    sc->out[sc->n++] = line;
}

/* cJSON treats every byte <= 32 as white space; so does the scanner. */
static void s_scan_ws(s_scan_t *sc)
{
    while (sc->pos < sc->len && (unsigned char)sc->text[sc->pos] <= 32) {
        if (sc->text[sc->pos] == '\n')
            sc->line++;
        sc->pos++;
    }
}

static void s_scan_string(s_scan_t *sc)
{
    if (sc->pos >= sc->len || sc->text[sc->pos] != '"') {
        sc->ok = 0;
        return;
    }
    sc->pos++;
    while (sc->pos < sc->len) {
        char ch = sc->text[sc->pos];
        if (ch == '"') {
            sc->pos++;
            return;
        }
        if (ch == '\n')
            sc->line++;
        sc->pos += (ch == '\\') ? 2 : 1;
    }
    sc->ok = 0;
}

static void s_scan_value(s_scan_t *sc, int depth)
{
    s_scan_ws(sc);
    if (!sc->ok || sc->pos >= sc->len || depth > CJSON_NESTING_LIMIT + 1) {
        sc->ok = 0;
        return;
    }
    s_scan_emit(sc, sc->line);
    char open = sc->text[sc->pos];
    if (open == '"') {
        s_scan_string(sc);
    } else if (open == '{' || open == '[') {
        char close = (open == '{') ? '}' : ']';
        sc->pos++;
        s_scan_ws(sc);
        if (sc->pos < sc->len && sc->text[sc->pos] == close) {
            sc->pos++;
            return;
        }
        while (sc->ok) {
            if (open == '{') {
                s_scan_ws(sc);
                s_scan_emit(sc, sc->line);
                s_scan_string(sc);
                s_scan_ws(sc);
                if (sc->pos >= sc->len || sc->text[sc->pos] != ':') {
                    sc->ok = 0;
                    return;
                }
                sc->pos++;
            }
            s_scan_value(sc, depth + 1);
            s_scan_ws(sc);
            if (sc->pos >= sc->len) {
                sc->ok = 0;
                return;
            }
            char ch = sc->text[sc->pos++];
            if (ch == close)
                return;
            if (ch != ',')
                sc->ok = 0;
        }
    } else {
        /* A number or a literal: it ends at a delimiter or white space. */
        while (sc->pos < sc->len) {
            char ch = sc->text[sc->pos];
            if ((unsigned char)ch <= 32 || ch == ',' || ch == ']' || ch == '}')
                break;
            sc->pos++;
        }
    }
}

typedef struct s_pairing {
    const int *lines;
    size_t nlines, next;
    s_line_t *tab;
    size_t ntab, cap;
    int ok;
    int nomem;
} s_pairing_t;

static int s_pair_take(s_pairing_t *p)
{
    if (p->next >= p->nlines) {
        p->ok = 0;
        return 0;
    }
    return p->lines[p->next++];
}

/* Walks the tree in document order, consuming the scanner's lines exactly as
 * the scanner produced them. */
static void s_pair(s_pairing_t *p, const cJSON *node, int key_line)
{
    int line = s_pair_take(p);
    if (!p->ok)
        return;
    if (p->ntab == p->cap) {
        size_t ncap = p->cap ? 2 * p->cap : 256;
        s_line_t *t = realloc(p->tab, ncap * sizeof *t);
        if (!t) {
            p->ok = 0;
            p->nomem = 1;
            return;
        }
        p->tab = t;
        p->cap = ncap;
    }
    p->tab[p->ntab++] = (s_line_t){ .node = node, .key_line = key_line ? key_line : line, .line = line };
    if (cJSON_IsObject(node)) {
        for (const cJSON *ch = node->child; ch && p->ok; ch = ch->next) {
            int kl = s_pair_take(p);
            s_pair(p, ch, kl);
        }
    } else if (cJSON_IsArray(node)) {
        for (const cJSON *ch = node->child; ch && p->ok; ch = ch->next)
            s_pair(p, ch, 0);
    }
}

static int s_line_cmp(const void *a, const void *b)
{
    uintptr_t x = (uintptr_t)((const s_line_t *)a)->node, y = (uintptr_t)((const s_line_t *)b)->node;
    return (x > y) - (x < y);
}

/* Builds the node-to-line table sorted by node address. On any mismatch
 * (which would mean the scanner and cJSON disagree about the text) the table
 * is left empty: errors then name the file without a line rather than a wrong
 * line. Running out of memory is not degraded that way but returned
 * (PF_ENOMEM), since lines also name things (a quad's mesh name): a load
 * either fails or gives the same scene. */
static int s_build_lines(const char *text, size_t len, const cJSON *root, s_line_t **tab_p, size_t *n_p)
{
    *tab_p = NULL;
    *n_p = 0;
    s_scan_t sc = { .text = text, .len = len, .line = 1, .ok = 1 };
    if (len >= 3 && memcmp(text, "\xEF\xBB\xBF", 3) == 0)
        sc.pos = 3; /* cJSON skips a UTF-8 byte-order mark */
    s_scan_value(&sc, 0);
    s_pairing_t p = { .lines = sc.out, .nlines = sc.n, .ok = sc.ok };
    if (p.ok)
        s_pair(&p, root, 0);
    free(sc.out);
    if (!p.ok || p.next != p.nlines) {
        free(p.tab);
        return sc.nomem || p.nomem ? PF_ENOMEM : PF_OK;
    }
    qsort(p.tab, p.ntab, sizeof *p.tab, s_line_cmp);
    *tab_p = p.tab;
    *n_p = p.ntab;
    return PF_OK;
}

/* ------------------------------------------------------------------------ */
/* Context and error reports                                                */

typedef struct s_ctx {
    pf_scene_t *scene;
    pf_error_t *err;
    const char *path;
    char dir[1024];  /* the JSON file's folder ("" for the working directory) */
    s_line_t *lines; /* sorted by node */
    size_t nlines;
    size_t mat_base; /* scene->nmats before this file's materials */
    size_t mat_end;  /* one past this file's materials */
} s_ctx_t;

static const s_line_t *s_find_line(const s_ctx_t *c, const cJSON *node)
{
    if (!node || !c->lines)
        return NULL;
    s_line_t key = { .node = node };
    return bsearch(&key, c->lines, c->nlines, sizeof key, s_line_cmp);
}

static int s_line_of(const s_ctx_t *c, const cJSON *node)
{
    const s_line_t *l = s_find_line(c, node);
    return l ? l->line : 0;
}

static int s_key_line_of(const s_ctx_t *c, const cJSON *node)
{
    const s_line_t *l = s_find_line(c, node);
    return l ? l->key_line : 0;
}

static int s_fail_line(s_ctx_t *c, int status, int line, const char *fmt, ...) __attribute__((format(printf, 4, 5)));
static int s_fail_line(s_ctx_t *c, int status, int line, const char *fmt, ...)
{
    char msg[768];
    va_list ap;
    va_start(ap, fmt);
    vsnprintf(msg, sizeof msg, fmt, ap);
    va_end(ap);
    return pf_error_set(c->err, status, c->path, line, "%s", msg);
}

/* Reports at the line where the value `at` starts. */
#define S_FAIL_AT(c, at, ...) s_fail_line((c), PF_EPARSE, s_line_of((c), (at)), __VA_ARGS__)
/* Reports at the line of the member's key (for unknown and duplicate keys). */
#define S_FAIL_KEY(c, at, ...) s_fail_line((c), PF_EPARSE, s_key_line_of((c), (at)), __VA_ARGS__)

static const char *s_type_name(const cJSON *v)
{
    if (cJSON_IsNumber(v))
        return "a number";
    if (cJSON_IsString(v))
        return "a string";
    if (cJSON_IsBool(v))
        return "a boolean";
    if (cJSON_IsNull(v))
        return "null";
    if (cJSON_IsArray(v))
        return "an array";
    if (cJSON_IsObject(v))
        return "an object";
    return "an invalid value";
}

/* ------------------------------------------------------------------------ */
/* Typed access                                                             */

/* Checks that node is an object whose keys are all in allowed (a NULL-ended
 * list; "comment" is always allowed) and each appears once. what names the
 * object in messages ("camera", "material", ...). */
static int s_check_object(s_ctx_t *c, const cJSON *node, const char *what, const char *const *allowed)
{
    if (!cJSON_IsObject(node))
        return S_FAIL_AT(c, node, "%s must be an object, not %s", what, s_type_name(node));
    for (const cJSON *m = node->child; m; m = m->next) {
        int known = strcmp(m->string, "comment") == 0;
        for (const char *const *k = allowed; *k && !known; k++)
            known = strcmp(m->string, *k) == 0;
        if (!known)
            return S_FAIL_KEY(c, m, "unknown key '%.64s' in %s", m->string, what);
        if (strcmp(m->string, "comment") == 0 && !cJSON_IsString(m))
            return S_FAIL_AT(c, m, "'comment' in %s must be a string", what);
        for (const cJSON *o = node->child; o != m; o = o->next)
            if (strcmp(o->string, m->string) == 0)
                return S_FAIL_KEY(c, m, "duplicate key '%.64s' in %s", m->string, what);
    }
    return PF_OK;
}

static const cJSON *s_get(const cJSON *obj, const char *key)
{
    return cJSON_GetObjectItemCaseSensitive(obj, key);
}

/* Fetches a key that must be present; a missing key names the object's line. */
static int s_require(s_ctx_t *c, const cJSON *obj, const char *key, const char *what, const cJSON **out)
{
    *out = s_get(obj, key);
    if (!*out)
        return S_FAIL_AT(c, obj, "%s is missing the required key '%s'", what, key);
    return PF_OK;
}

static int s_number(s_ctx_t *c, const cJSON *v, const char *key, const char *what, double *out)
{
    if (!cJSON_IsNumber(v))
        return S_FAIL_AT(c, v, "'%s' in %s must be a number, not %s", key, what, s_type_name(v));
    if (!isfinite(v->valuedouble))
        return S_FAIL_AT(c, v, "'%s' in %s must be finite", key, what);
    *out = v->valuedouble;
    return PF_OK;
}

/* A number stored as float: it must also fit the float range. */
static int s_float(s_ctx_t *c, const cJSON *v, const char *key, const char *what, float *out)
{
    double d = 0.0; /* set by s_number when it succeeds; gcc -O3 cannot see that */
    int rc = s_number(c, v, key, what, &d);
    if (rc)
        return rc;
    if (fabs(d) > FLT_MAX)
        return S_FAIL_AT(c, v, "'%s' in %s is too large", key, what);
    *out = (float)d;
    return PF_OK;
}

static int s_int(s_ctx_t *c, const cJSON *v, const char *key, const char *what, int lo, int hi, int *out)
{
    double d = 0.0; /* set by s_number when it succeeds; gcc -O3 cannot see that */
    int rc = s_number(c, v, key, what, &d);
    if (rc)
        return rc;
    if (d != floor(d) || d < lo || d > hi)
        return S_FAIL_AT(c, v, "'%s' in %s must be an integer from %d to %d (got %g)", key, what, lo, hi, d);
    *out = (int)d;
    return PF_OK;
}

static int s_u64(s_ctx_t *c, const cJSON *v, const char *key, const char *what, uint64_t *out)
{
    double d = 0.0; /* set by s_number when it succeeds; gcc -O3 cannot see that */
    int rc = s_number(c, v, key, what, &d);
    if (rc)
        return rc;
    if (d != floor(d) || d < 0.0 || d > S_MAX_EXACT_INT)
        return S_FAIL_AT(c, v, "'%s' in %s must be an integer from 0 to 2^53 (got %g)", key, what, d);
    *out = (uint64_t)d;
    return PF_OK;
}

static int s_string(s_ctx_t *c, const cJSON *v, const char *key, const char *what, const char **out)
{
    if (!cJSON_IsString(v) || !v->valuestring)
        return S_FAIL_AT(c, v, "'%s' in %s must be a string, not %s", key, what, s_type_name(v));
    if (v->valuestring[0] == '\0')
        return S_FAIL_AT(c, v, "'%s' in %s must not be empty", key, what);
    *out = v->valuestring;
    return PF_OK;
}

/* An array of exactly n numbers (each fitting a float). */
static int s_floats(s_ctx_t *c, const cJSON *v, const char *key, const char *what, int n, float *out)
{
    if (!cJSON_IsArray(v) || cJSON_GetArraySize(v) != n)
        return S_FAIL_AT(c, v, "'%s' in %s must be an array of %d numbers", key, what, n);
    int i = 0;
    for (const cJSON *e = v->child; e; e = e->next, i++) {
        if (!cJSON_IsNumber(e))
            return S_FAIL_AT(c, e, "'%s' in %s: element %d must be a number, not %s", key, what, i + 1,
                             s_type_name(e));
        if (!isfinite(e->valuedouble) || fabs(e->valuedouble) > FLT_MAX)
            return S_FAIL_AT(c, e, "'%s' in %s: element %d must be finite", key, what, i + 1);
        out[i] = (float)e->valuedouble;
    }
    return PF_OK;
}

static int s_vec3(s_ctx_t *c, const cJSON *v, const char *key, const char *what, pf_vec3 *out)
{
    float f[3];
    int rc = s_floats(c, v, key, what, 3, f);
    if (rc == PF_OK)
        *out = pf_v3(f[0], f[1], f[2]);
    return rc;
}

/* Positions must lie within +-1e18: each can become a ray origin, and Embree
 * refuses rays that start beyond 1.844e18 (see S_COORD_MAX in scene.c). */
static int s_in_range(pf_vec3 v)
{
    return fabsf(v.x) <= 1e18f && fabsf(v.y) <= 1e18f && fabsf(v.z) <= 1e18f;
}

static int s_position(s_ctx_t *c, const cJSON *v, const char *key, const char *what, pf_vec3 *out)
{
    int rc = s_vec3(c, v, key, what, out);
    if (rc == PF_OK && !s_in_range(*out))
        rc = S_FAIL_AT(c, v, "'%s' in %s must lie within +-1e18, the ray tracer's range", key, what);
    return rc;
}

/* An RGB colour: an array of 3 numbers, or one number meaning grey. Each
 * channel must lie in [lo, hi]. */
static int s_rgb(s_ctx_t *c, const cJSON *v, const char *key, const char *what, float lo, float hi, pf_vec3 *out)
{
    pf_vec3 rgb;
    if (cJSON_IsNumber(v)) {
        float g;
        int rc = s_float(c, v, key, what, &g);
        if (rc)
            return rc;
        rgb = pf_v3s(g);
    } else if (cJSON_IsArray(v)) {
        int rc = s_vec3(c, v, key, what, &rgb);
        if (rc)
            return rc;
    } else {
        return S_FAIL_AT(c, v, "'%s' in %s must be an RGB array of 3 numbers or one number, not %s", key, what,
                         s_type_name(v));
    }
    for (int k = 0; k < 3; k++) {
        float x = pf_vget(rgb, k);
        if (x < lo || x > hi) {
            if (hi >= FLT_MAX)
                return S_FAIL_AT(c, v, "'%s' in %s must be >= %g in every channel (got %g)", key, what, lo, x);
            return S_FAIL_AT(c, v, "'%s' in %s must lie in [%g, %g] in every channel (got %g)", key, what, lo, hi, x);
        }
    }
    *out = rgb;
    return PF_OK;
}

/* Index of one of this file's materials by name, or -1. Models' own (MTL)
 * materials are deliberately not visible here, so a JSON name always means
 * the JSON material even when an MTL file reuses the name. */
static int s_find_json_material(const s_ctx_t *c, const char *name)
{
    for (size_t i = c->mat_base; i < c->mat_end; i++)
        if (strcmp(c->scene->mats[i].name, name) == 0)
            return (int)i;
    return -1;
}

static int s_material_ref(s_ctx_t *c, const cJSON *v, const char *key, const char *what, int *out)
{
    const char *name;
    int rc = s_string(c, v, key, what, &name);
    if (rc)
        return rc;
    int idx = s_find_json_material(c, name);
    if (idx < 0)
        return S_FAIL_AT(c, v, "unknown material '%.64s' in %s (not in \"materials\")", name, what);
    *out = idx;
    return PF_OK;
}

/* ------------------------------------------------------------------------ */
/* Sections                                                                 */

static int s_camera(s_ctx_t *c, const cJSON *cam)
{
    static const char *const keys[] = { "position", "look_at", "up", "fov", NULL };
    const char *what = "camera";
    int rc = s_check_object(c, cam, what, keys);
    const cJSON *pos = NULL, *at = NULL, *v;
    pf_camera_desc_t d = { .up = pf_v3(0, 1, 0), .vfov_deg = 40.0f };
    if (!rc)
        rc = s_require(c, cam, "position", what, &pos);
    if (!rc)
        rc = s_position(c, pos, "position", what, &d.pos);
    if (!rc)
        rc = s_require(c, cam, "look_at", what, &at);
    if (!rc)
        rc = s_vec3(c, at, "look_at", what, &d.look_at);
    if (!rc && (v = s_get(cam, "up")) && !(rc = s_vec3(c, v, "up", what, &d.up)) && !(pf_len2(d.up) > 0.0f))
        rc = S_FAIL_AT(c, v, "'up' in camera must not be zero");
    if (!rc && (v = s_get(cam, "fov")) && !(rc = s_float(c, v, "fov", what, &d.vfov_deg)) &&
        !(d.vfov_deg > 0.0f && d.vfov_deg < 180.0f))
        rc = S_FAIL_AT(c, v, "'fov' in camera must be in (0, 180) degrees (got %g)", d.vfov_deg);
    if (rc)
        return rc;
    pf_vec3 view = pf_sub(d.look_at, d.pos);
    if (!(pf_len2(view) > 0.0f))
        return S_FAIL_AT(c, at, "'look_at' in camera must differ from 'position'");
    if (!(pf_len2(pf_cross(pf_norm(view), pf_norm(d.up))) > 1e-12f))
        return S_FAIL_AT(c, cam, "camera 'up' must not be parallel to the view direction");
    c->scene->camera = d;
    c->scene->has_camera = 1;
    return PF_OK;
}

typedef struct s_int_setting {
    const char *key;
    size_t offset;
    int lo, hi;
} s_int_setting_t;

static int s_render(s_ctx_t *c, const cJSON *r)
{
    /* The bounds keep later allocations (k-NN buffers, the image) sane and
     * catch typos; they are far beyond useful values. */
    static const s_int_setting_t ints[] = {
        { "width", offsetof(pf_settings_t, width), 1, 65536 },
        { "height", offsetof(pf_settings_t, height), 1, 65536 },
        { "spp", offsetof(pf_settings_t, spp), 1, 1 << 20 },
        { "gather", offsetof(pf_settings_t, gather), 0, 1 << 16 },
        { "gather_filter", offsetof(pf_settings_t, gather_filter), 0, PF_MAX_GATHER_FILTER },
        { "light_samples", offsetof(pf_settings_t, light_samples), 1, 1 << 16 },
        { "max_depth", offsetof(pf_settings_t, max_depth), 0, 1024 },
        { "photon_max_depth", offsetof(pf_settings_t, photon_max_depth), 1, 100000 },
        { "global_k", offsetof(pf_settings_t, global_k), 1, 1 << 16 },
        { "caustic_k", offsetof(pf_settings_t, caustic_k), 1, 1 << 16 },
        { "irradiance_stride", offsetof(pf_settings_t, irradiance_stride), 1, 1 << 20 },
    };
    static const char *const keys[] = { "width", "height", "spp", "photons", "caustic_photons", "gather",
                                        "gather_filter", "light_samples", "max_depth", "photon_max_depth", "global_k",
                                        "caustic_k", "caustic_radius", "global_radius", "irradiance_stride",
                                        "seed", "exposure", NULL };
    const char *what = "render";
    int rc = s_check_object(c, r, what, keys);
    pf_settings_t *s = &c->scene->settings;
    for (size_t i = 0; !rc && i < sizeof ints / sizeof ints[0]; i++) {
        const cJSON *v = s_get(r, ints[i].key);
        if (v)
            rc = s_int(c, v, ints[i].key, what, ints[i].lo, ints[i].hi, (int *)((char *)s + ints[i].offset));
    }
    const cJSON *v;
    if (!rc && (v = s_get(r, "photons")))
        rc = s_u64(c, v, "photons", what, &s->photons);
    if (!rc && (v = s_get(r, "caustic_photons")))
        rc = s_u64(c, v, "caustic_photons", what, &s->caustic_photons);
    if (!rc && (v = s_get(r, "seed")))
        rc = s_u64(c, v, "seed", what, &s->seed);
    if (!rc && (v = s_get(r, "caustic_radius")) && !(rc = s_float(c, v, "caustic_radius", what, &s->caustic_radius)) &&
        s->caustic_radius < 0.0f)
        rc = S_FAIL_AT(c, v, "'caustic_radius' in render must be >= 0 (0: automatic)");
    if (!rc && (v = s_get(r, "global_radius")) && !(rc = s_float(c, v, "global_radius", what, &s->global_radius)) &&
        s->global_radius < 0.0f)
        rc = S_FAIL_AT(c, v, "'global_radius' in render must be >= 0 (0: automatic)");
    if (!rc && (v = s_get(r, "exposure")))
        rc = s_float(c, v, "exposure", what, &s->exposure);
    return rc;
}

static int s_material(s_ctx_t *c, const cJSON *m)
{
    static const char *const keys[] = { "name", "type", "kd", "ks", "ns", "kt", "ior", "emission", NULL };
    const char *what = "material";
    int rc = s_check_object(c, m, what, keys);
    const cJSON *vname = NULL, *v;
    const char *name = NULL, *type = "diffuse";
    if (!rc)
        rc = s_require(c, m, "name", what, &vname);
    if (!rc)
        rc = s_string(c, vname, "name", what, &name);
    if (!rc && strlen(name) >= PF_NAME_MAX)
        rc = S_FAIL_AT(c, vname, "material name '%.64s...' is longer than %d bytes", name, PF_NAME_MAX - 1);
    if (!rc && s_find_json_material(c, name) >= 0)
        rc = S_FAIL_AT(c, vname, "duplicate material name '%s'", name);
    const cJSON *vtype = s_get(m, "type");
    if (!rc && vtype)
        rc = s_string(c, vtype, "type", what, &type);
    if (rc)
        return rc;

    pf_material_t mat = pf_material_default(name);
    /* Keys that a kind ignores are errors: a glass "kd" or a diffuse "ior"
     * is a mistake the author wants to hear about, not silently dropped. */
    const char *const *valid;
    static const char *const diffuse_keys[] = { "kd", "ks", "ns", "emission", NULL };
    static const char *const mirror_keys[] = { "ks", "emission", NULL };
    static const char *const glass_keys[] = { "ks", "kt", "ior", "emission", NULL };
    if (strcmp(type, "diffuse") == 0) {
        mat.type = PF_MAT_DIFFUSE;
        valid = diffuse_keys;
    } else if (strcmp(type, "mirror") == 0) {
        /* A mirror or glass written without "ks" should reflect, so their
         * defaults differ from the grey Lambertian's. */
        mat.type = PF_MAT_MIRROR;
        mat.kd = pf_v3s(0.0f);
        mat.ks = pf_v3s(1.0f);
        valid = mirror_keys;
    } else if (strcmp(type, "glass") == 0) {
        mat.type = PF_MAT_GLASS;
        mat.kd = pf_v3s(0.0f);
        mat.ks = pf_v3s(1.0f);
        valid = glass_keys;
    } else {
        return S_FAIL_AT(c, vtype, "unknown material type '%.64s' (expected diffuse, mirror or glass)", type);
    }
    for (const cJSON *k = m->child; k; k = k->next) {
        if (strcmp(k->string, "name") == 0 || strcmp(k->string, "type") == 0 || strcmp(k->string, "comment") == 0)
            continue;
        int ok = 0;
        for (const char *const *p = valid; *p && !ok; p++)
            ok = strcmp(k->string, *p) == 0;
        if (!ok)
            return S_FAIL_KEY(c, k, "key '%s' does not apply to a %s material", k->string, type);
    }
    if ((v = s_get(m, "kd")) && (rc = s_rgb(c, v, "kd", what, 0.0f, 1.0f, &mat.kd)))
        return rc;
    if ((v = s_get(m, "ks")) && (rc = s_rgb(c, v, "ks", what, 0.0f, 1.0f, &mat.ks)))
        return rc;
    if ((v = s_get(m, "kt")) && (rc = s_rgb(c, v, "kt", what, 0.0f, 1.0f, &mat.kt)))
        return rc;
    if ((v = s_get(m, "emission")) && (rc = s_rgb(c, v, "emission", what, 0.0f, FLT_MAX, &mat.le)))
        return rc;
    if ((v = s_get(m, "ns"))) {
        if ((rc = s_float(c, v, "ns", what, &mat.ns)))
            return rc;
        if (mat.ns < 0.0f)
            return S_FAIL_AT(c, v, "'ns' in material must be >= 0 (got %g)", mat.ns);
    }
    if ((v = s_get(m, "ior"))) {
        if ((rc = s_float(c, v, "ior", what, &mat.ior)))
            return rc;
        if (!(mat.ior > 0.0f))
            return S_FAIL_AT(c, v, "'ior' in material must be > 0 (got %g)", mat.ior);
    }
    /* A diffuse surface reflects kd + ks in total; more than 1 would create
     * energy and break the photon tracer's Russian roulette. */
    if (mat.type == PF_MAT_DIFFUSE)
        for (int k = 0; k < 3; k++)
            if (pf_vget(mat.kd, k) + pf_vget(mat.ks, k) > 1.0f + 1e-6f)
                return S_FAIL_AT(c, m, "material '%s': kd + ks exceeds 1 in channel %d (it would create energy)",
                                 name, k);
    rc = pf_scene_add_material(c->scene, &mat);
    if (rc < 0)
        return pf_error_set(c->err, rc, c->path, 0, "out of memory");
    c->mat_end = c->scene->nmats;
    return PF_OK;
}

/* Rotation by deg degrees about axis (0 x, 1 y, 2 z), right-handed.
 * Multiples of 90 degrees are exact, so axis-aligned scenes stay exact. */
static pf_xform_t s_rotation(int axis, double deg)
{
    double s, co;
    double q = deg / 90.0;
    if (q == floor(q) && fabs(q) < 1e9) {
        static const double sn[4] = { 0, 1, 0, -1 }, cs[4] = { 1, 0, -1, 0 };
        long long i = ((long long)q % 4 + 4) % 4;
        s = sn[i];
        co = cs[i];
    } else {
        double r = deg * (3.14159265358979323846 / 180.0);
        s = sin(r);
        co = cos(r);
    }
    pf_xform_t x = pf_xform_identity();
    int a = (axis + 1) % 3, b = (axis + 2) % 3;
    x.m[a][a] = (float)co;
    x.m[a][b] = (float)-s;
    x.m[b][a] = (float)s;
    x.m[b][b] = (float)co;
    return x;
}

/* Parses a "transform" object. *lin_node gets the node that set the linear
 * part (scale or matrix), for messages about it. */
static int s_transform(s_ctx_t *c, const cJSON *t, pf_xform_t *out, const cJSON **lin_node)
{
    static const char *const keys[] = { "scale", "rotate", "translate", "matrix", NULL };
    const char *what = "transform";
    int rc = s_check_object(c, t, what, keys);
    if (rc)
        return rc;
    pf_xform_t x = pf_xform_identity();
    const cJSON *v;
    *lin_node = t;
    if ((v = s_get(t, "matrix"))) {
        for (const cJSON *m = t->child; m; m = m->next)
            if (strcmp(m->string, "matrix") && strcmp(m->string, "comment"))
                return S_FAIL_KEY(c, m, "'%s' cannot be combined with 'matrix' in a transform", m->string);
        int n = cJSON_IsArray(v) ? cJSON_GetArraySize(v) : 0;
        float f[16];
        if (n != 12 && n != 16)
            return S_FAIL_AT(c, v, "'matrix' in transform must be an array of 12 or 16 numbers (row-major)");
        if ((rc = s_floats(c, v, "matrix", what, n, f)))
            return rc;
        if (n == 16 && !(f[12] == 0.0f && f[13] == 0.0f && f[14] == 0.0f && f[15] == 1.0f))
            return S_FAIL_AT(c, v, "'matrix' in transform: the last row must be 0 0 0 1 (no projections)");
        for (int i = 0; i < 12; i++)
            x.m[i / 4][i % 4] = f[i];
        *lin_node = v;
    } else {
        if ((v = s_get(t, "scale"))) {
            pf_vec3 s;
            if (cJSON_IsNumber(v)) {
                float g;
                if ((rc = s_float(c, v, "scale", what, &g)))
                    return rc;
                s = pf_v3s(g);
            } else if (cJSON_IsArray(v)) {
                if ((rc = s_vec3(c, v, "scale", what, &s)))
                    return rc;
            } else {
                return S_FAIL_AT(c, v, "'scale' in transform must be a number or an array of 3 numbers, not %s",
                                 s_type_name(v));
            }
            if (s.x == 0.0f || s.y == 0.0f || s.z == 0.0f)
                return S_FAIL_AT(c, v, "'scale' in transform must not be zero (it would flatten the geometry)");
            x.m[0][0] = s.x;
            x.m[1][1] = s.y;
            x.m[2][2] = s.z;
            *lin_node = v;
        }
        if ((v = s_get(t, "rotate"))) {
            float r[3];
            if ((rc = s_floats(c, v, "rotate", what, 3, r)))
                return rc;
            for (int axis = 0; axis < 3; axis++) {
                pf_xform_t rx = s_rotation(axis, r[axis]);
                x = pf_xform_then(&x, &rx);
            }
        }
        if ((v = s_get(t, "translate"))) {
            pf_vec3 d;
            if ((rc = s_vec3(c, v, "translate", what, &d)))
                return rc;
            x.m[0][3] += d.x;
            x.m[1][3] += d.y;
            x.m[2][3] += d.z;
        }
    }
    float det = pf_xform_det(&x);
    if (!isfinite(det))
        return S_FAIL_AT(c, *lin_node, "the transform's scale is too large (its determinant overflows a float)");
    if (!(det != 0.0f))
        return S_FAIL_AT(c, *lin_node, "the transform is singular (it would flatten the geometry)");
    *out = x;
    return PF_OK;
}

/* Reads an object's optional "transform"; *has says whether there was one. */
static int s_object_transform(s_ctx_t *c, const cJSON *obj, pf_xform_t *xf, int *has, const cJSON **lin_node)
{
    const cJSON *t = s_get(obj, "transform");
    *has = t != NULL;
    *xf = pf_xform_identity();
    *lin_node = NULL;
    return t ? s_transform(c, t, xf, lin_node) : PF_OK;
}

/* Resolves a model path relative to the scene file's folder and checks that
 * it can be opened, so a missing file names the scene line that asked for it. */
static int s_model_path(s_ctx_t *c, const cJSON *obj, const char *what, char *out, size_t cap)
{
    const cJSON *v;
    const char *file;
    int rc = s_require(c, obj, "file", what, &v);
    if (!rc)
        rc = s_string(c, v, "file", what, &file);
    if (rc)
        return rc;
    int n = (file[0] == '/' || c->dir[0] == '\0') ? snprintf(out, cap, "%s", file)
                                                    : snprintf(out, cap, "%s/%s", c->dir, file);
    if (n < 0 || (size_t)n >= cap)
        return S_FAIL_AT(c, v, "the path '%.64s...' is too long", file);
    FILE *f = fopen(out, "rb");
    if (!f)
        return s_fail_line(c, PF_EIO, s_line_of(c, v), "cannot open %s '%s': %s", what, out, strerror(errno));
    fclose(f);
    return PF_OK;
}

/* Applies an OBJ object's "materials" map (MTL name -> scene material) to the
 * triangles of the meshes the OBJ loader appended, i.e. meshes from mesh0 on.
 * Each triangle is looked up by its original material only once, so a map
 * such as {"a": "b", "b": "c"} does not chain. */
static int s_remap(s_ctx_t *c, const cJSON *map, const int *target, size_t mesh0, const char *model)
{
    pf_scene_t *sc = c->scene;
    int n = cJSON_GetArraySize(map);
    int *used = calloc((size_t)n + 1, sizeof *used);
    int *remap = malloc((sc->nmats + 1) * sizeof *remap); /* -1: keep, else entry index */
    int rc = PF_OK, i;
    if (!used || !remap) {
        rc = pf_error_set(c->err, PF_ENOMEM, c->path, 0, "out of memory");
        goto done;
    }
    for (size_t m = 0; m < sc->nmats; m++) {
        remap[m] = -1;
        i = 0;
        for (const cJSON *e = map->child; e; e = e->next, i++)
            if (strcmp(sc->mats[m].name, e->string) == 0) {
                remap[m] = i;
                break;
            }
    }
    for (size_t mi = mesh0; mi < sc->nmeshes; mi++) {
        pf_mesh_t *mesh = &sc->meshes[mi];
        for (size_t t = 0; t < mesh->ntris; t++) {
            uint32_t m = mesh->mat[t];
            if (m < sc->nmats && remap[m] >= 0) {
                used[remap[m]] = 1;
                mesh->mat[t] = (uint32_t)target[remap[m]];
            }
        }
    }
    i = 0;
    for (const cJSON *e = map->child; e; e = e->next, i++)
        if (!used[i]) {
            rc = S_FAIL_KEY(c, e, "'%.64s' in 'materials': '%s' has no triangles with that material", e->string,
                            model);
            break;
        }
done:
    free(used);
    free(remap);
    return rc;
}

static int s_vec_equal(pf_vec3 a, pf_vec3 b)
{
    return a.x == b.x && a.y == b.y && a.z == b.z;
}

static int s_mat_equal(const pf_material_t *a, const pf_material_t *b)
{
    return strcmp(a->name, b->name) == 0 && a->type == b->type && s_vec_equal(a->kd, b->kd) &&
           s_vec_equal(a->ks, b->ks) && a->ns == b->ns && s_vec_equal(a->kt, b->kt) && a->ior == b->ior &&
           s_vec_equal(a->le, b->le);
}

/* The MTL loader replaces a scene material of the same name in place, which
 * would silently change the JSON material (or an earlier model's) of that
 * name for every object using it. Each model's materials are kept to that
 * model instead: a replaced material is restored, the model's version is
 * appended as a new material, and the model's new triangles point to it. */
static int s_isolate_materials(s_ctx_t *c, const pf_material_t *before, size_t nbefore, size_t mesh0)
{
    pf_scene_t *sc = c->scene;
    for (size_t i = 0; i < nbefore; i++) {
        if (s_mat_equal(&sc->mats[i], &before[i]))
            continue;
        pf_material_t model_mat = sc->mats[i];
        sc->mats[i] = before[i];
        int idx = pf_scene_add_material(sc, &model_mat);
        if (idx < 0)
            return pf_error_set(c->err, PF_ENOMEM, c->path, 0, "out of memory");
        for (size_t mi = mesh0; mi < sc->nmeshes; mi++)
            for (size_t t = 0; t < sc->meshes[mi].ntris; t++)
                if (sc->meshes[mi].mat[t] == (uint32_t)i)
                    sc->meshes[mi].mat[t] = (uint32_t)idx;
    }
    return PF_OK;
}

static int s_obj(s_ctx_t *c, const cJSON *o)
{
    static const char *const keys[] = { "type", "file", "transform", "material", "materials", NULL };
    const char *what = "obj object";
    int rc = s_check_object(c, o, what, keys);
    char path[2048];
    int mat = -1, has_xf;
    pf_xform_t xf;
    const cJSON *lin, *vmat = s_get(o, "material"), *vmap = s_get(o, "materials");
    if (!rc && vmat && vmap)
        rc = S_FAIL_KEY(c, vmap, "an obj object takes 'material' (one for all) or 'materials' (a map), not both");
    if (!rc && vmat)
        rc = s_material_ref(c, vmat, "material", what, &mat);
    if (!rc && vmap && !cJSON_IsObject(vmap))
        rc = S_FAIL_AT(c, vmap, "'materials' in obj object must be an object mapping MTL names to material names");
    /* The map is checked pairwise and against every material; a cap keeps a
     * hostile file from making that quadratic work unbounded. */
    if (!rc && vmap && cJSON_GetArraySize(vmap) > S_MAX_REMAP)
        rc = S_FAIL_AT(c, vmap, "'materials' in obj object has more than %d entries", S_MAX_REMAP);
    for (const cJSON *m = vmap ? vmap->child : NULL; m && !rc; m = m->next)
        for (const cJSON *e = vmap->child; e != m && !rc; e = e->next)
            if (strcmp(e->string, m->string) == 0)
                rc = S_FAIL_KEY(c, m, "duplicate key '%.64s' in 'materials'", m->string);
    /* The map's scene names are checked before the (possibly slow) load. */
    int *target = NULL;
    if (!rc && vmap && vmap->child) {
        target = calloc((size_t)cJSON_GetArraySize(vmap), sizeof *target);
        if (!target)
            rc = pf_error_set(c->err, PF_ENOMEM, c->path, 0, "out of memory");
        int i = 0;
        for (const cJSON *e = vmap->child; e && !rc; e = e->next, i++)
            rc = s_material_ref(c, e, e->string, "'materials' of an obj object", &target[i]);
    }
    if (!rc)
        rc = s_object_transform(c, o, &xf, &has_xf, &lin);
    if (!rc)
        rc = s_model_path(c, o, "obj", path, sizeof path);
    size_t mesh0 = c->scene->nmeshes, nmats0 = c->scene->nmats;
    pf_material_t *before = NULL;
    if (!rc && nmats0 && !(before = malloc(nmats0 * sizeof *before)))
        rc = pf_error_set(c->err, PF_ENOMEM, c->path, 0, "out of memory");
    if (before)
        memcpy(before, c->scene->mats, nmats0 * sizeof *before);
    if (!rc)
        rc = pf_obj_load(c->scene, path, has_xf ? &xf : NULL, mat, c->err);
    if (!rc && before)
        rc = s_isolate_materials(c, before, nmats0, mesh0);
    if (!rc && target)
        rc = s_remap(c, vmap, target, mesh0, path);
    free(before);
    free(target);
    return rc;
}

static int s_ply(s_ctx_t *c, const cJSON *o)
{
    static const char *const keys[] = { "type", "file", "transform", "material", NULL };
    const char *what = "ply object";
    int rc = s_check_object(c, o, what, keys);
    char path[2048];
    int mat = -1, has_xf;
    pf_xform_t xf;
    const cJSON *lin, *vmat = NULL;
    if (!rc)
        rc = s_require(c, o, "material", what, &vmat);
    if (!rc)
        rc = s_material_ref(c, vmat, "material", what, &mat);
    if (!rc)
        rc = s_object_transform(c, o, &xf, &has_xf, &lin);
    if (!rc)
        rc = s_model_path(c, o, "ply", path, sizeof path);
    if (rc)
        return rc;
    return pf_ply_load(c->scene, path, has_xf ? &xf : NULL, (uint32_t)mat, c->err);
}

static int s_sphere(s_ctx_t *c, const cJSON *o)
{
    static const char *const keys[] = { "type", "center", "radius", "material", "transform", NULL };
    const char *what = "sphere";
    int rc = s_check_object(c, o, what, keys);
    const cJSON *vc = NULL, *vr = NULL, *vmat = NULL, *lin;
    pf_sphere_t sp;
    int mat = -1, has_xf;
    pf_xform_t xf;
    if (!rc)
        rc = s_require(c, o, "center", what, &vc);
    if (!rc)
        rc = s_position(c, vc, "center", what, &sp.center);
    if (!rc)
        rc = s_require(c, o, "radius", what, &vr);
    if (!rc && !(rc = s_float(c, vr, "radius", what, &sp.radius)) && !(sp.radius > 0.0f))
        rc = S_FAIL_AT(c, vr, "'radius' in sphere must be > 0 (got %g)", sp.radius);
    if (!rc)
        rc = s_require(c, o, "material", what, &vmat);
    if (!rc)
        rc = s_material_ref(c, vmat, "material", what, &mat);
    if (!rc && !pf_is_black(c->scene->mats[mat].le))
        rc = s_fail_line(c, PF_EUNSUPPORTED, s_line_of(c, vmat),
                         "emissive spheres are not supported; use an emissive quad or mesh");
    if (!rc)
        rc = s_object_transform(c, o, &xf, &has_xf, &lin);
    if (rc)
        return rc;
    if (has_xf) {
        /* A sphere stays a sphere only under a similarity: the linear part's
         * columns must be orthogonal and of equal length s (the scale). */
        pf_vec3 col[3];
        for (int k = 0; k < 3; k++)
            col[k] = pf_v3(xf.m[0][k], xf.m[1][k], xf.m[2][k]);
        float s2 = pf_len2(col[0]), tol = 1e-5f * s2;
        if (fabsf(pf_len2(col[1]) - s2) > tol || fabsf(pf_len2(col[2]) - s2) > tol ||
            fabsf(pf_dot(col[0], col[1])) > tol || fabsf(pf_dot(col[0], col[2])) > tol ||
            fabsf(pf_dot(col[1], col[2])) > tol)
            return S_FAIL_AT(c, lin, "a sphere's transform must scale uniformly (non-uniform scale or shear)");
        sp.center = pf_xform_point(&xf, sp.center);
        sp.radius *= sqrtf(s2);
        if (!pf_is_finite3(sp.center) || !isfinite(sp.radius))
            return S_FAIL_AT(c, o, "the transformed sphere is not finite");
    }
    if (!s_in_range(pf_add(pf_vabs(sp.center), pf_v3s(sp.radius))))
        return S_FAIL_AT(c, o, "the sphere reaches beyond +-1e18, the ray tracer's range");
    sp.mat = (uint32_t)mat;
    if (pf_scene_add_sphere(c->scene, &sp))
        return pf_error_set(c->err, PF_ENOMEM, c->path, 0, "out of memory");
    return PF_OK;
}

static int s_quad(s_ctx_t *c, const cJSON *o)
{
    static const char *const keys[] = { "type", "origin", "edge1", "edge2", "material", "transform", NULL };
    const char *what = "quad";
    int rc = s_check_object(c, o, what, keys);
    const cJSON *vo = NULL, *v1 = NULL, *v2 = NULL, *vmat = NULL, *lin;
    pf_vec3 org, e1, e2;
    int mat = -1, has_xf;
    pf_xform_t xf;
    if (!rc)
        rc = s_require(c, o, "origin", what, &vo);
    if (!rc)
        rc = s_vec3(c, vo, "origin", what, &org);
    if (!rc)
        rc = s_require(c, o, "edge1", what, &v1);
    if (!rc)
        rc = s_vec3(c, v1, "edge1", what, &e1);
    if (!rc)
        rc = s_require(c, o, "edge2", what, &v2);
    if (!rc)
        rc = s_vec3(c, v2, "edge2", what, &e2);
    if (!rc && !(pf_len2(pf_cross(e1, e2)) > 0.0f))
        rc = S_FAIL_AT(c, o, "quad has no area: 'edge1' and 'edge2' must be non-zero and not parallel");
    if (!rc)
        rc = s_require(c, o, "material", what, &vmat);
    if (!rc)
        rc = s_material_ref(c, vmat, "material", what, &mat);
    if (!rc)
        rc = s_object_transform(c, o, &xf, &has_xf, &lin);
    if (rc)
        return rc;

    pf_mesh_t mesh;
    memset(&mesh, 0, sizeof mesh);
    snprintf(mesh.name, sizeof mesh.name, "quad (line %d)", s_line_of(c, o));
    mesh.nverts = 4;
    mesh.ntris = 2;
    mesh.pos = malloc(4 * sizeof *mesh.pos);
    mesh.idx = malloc(6 * sizeof *mesh.idx);
    mesh.mat = malloc(2 * sizeof *mesh.mat);
    if (!mesh.pos || !mesh.idx || !mesh.mat) {
        pf_mesh_free(&mesh);
        return pf_error_set(c->err, PF_ENOMEM, c->path, 0, "out of memory");
    }
    mesh.pos[0] = org;
    mesh.pos[1] = pf_add(org, e1);
    mesh.pos[2] = pf_add(pf_add(org, e1), e2);
    mesh.pos[3] = pf_add(org, e2);
    /* Counter-clockwise (0,1,2),(0,2,3): the face normal is edge1 x edge2,
     * the emitting side. A mirroring transform would turn it inside out, so
     * the winding is reversed to keep the normal on the transformed side. */
    static const uint32_t ccw[6] = { 0, 1, 2, 0, 2, 3 }, cw[6] = { 0, 2, 1, 0, 3, 2 };
    int flip = 0;
    if (has_xf) {
        for (int k = 0; k < 4; k++)
            mesh.pos[k] = pf_xform_point(&xf, mesh.pos[k]);
        flip = pf_xform_det(&xf) < 0.0f;
    }
    memcpy(mesh.idx, flip ? cw : ccw, sizeof ccw);
    mesh.mat[0] = mesh.mat[1] = (uint32_t)mat;
    if (pf_scene_add_mesh(c->scene, &mesh)) {
        pf_mesh_free(&mesh);
        return pf_error_set(c->err, PF_ENOMEM, c->path, 0, "out of memory");
    }
    return PF_OK;
}

static int s_object(s_ctx_t *c, const cJSON *o)
{
    if (!cJSON_IsObject(o))
        return S_FAIL_AT(c, o, "object must be an object, not %s", s_type_name(o));
    const cJSON *vt;
    const char *type;
    int rc = s_require(c, o, "type", "object", &vt);
    if (!rc)
        rc = s_string(c, vt, "type", "object", &type);
    if (rc)
        return rc;
    if (strcmp(type, "obj") == 0)
        return s_obj(c, o);
    if (strcmp(type, "ply") == 0)
        return s_ply(c, o);
    if (strcmp(type, "sphere") == 0)
        return s_sphere(c, o);
    if (strcmp(type, "quad") == 0)
        return s_quad(c, o);
    return S_FAIL_AT(c, vt, "unknown object type '%.64s' (expected obj, ply, sphere or quad)", type);
}

static int s_light(s_ctx_t *c, const cJSON *o)
{
    if (!cJSON_IsObject(o))
        return S_FAIL_AT(c, o, "light must be an object, not %s", s_type_name(o));
    const cJSON *vt, *vp = NULL, *vi = NULL, *vd = NULL, *va = NULL, *vf;
    const char *type;
    int rc = s_require(c, o, "type", "light", &vt);
    if (!rc)
        rc = s_string(c, vt, "type", "light", &type);
    if (rc)
        return rc;
    pf_light_t l;
    memset(&l, 0, sizeof l);
    if (strcmp(type, "point") == 0) {
        static const char *const keys[] = { "type", "position", "intensity", NULL };
        const char *what = "point light";
        l.type = PF_LIGHT_POINT;
        l.dir = pf_v3(0, -1, 0);
        l.cos_inner = l.cos_outer = -1.0f;
        rc = s_check_object(c, o, what, keys);
        if (!rc)
            rc = s_require(c, o, "position", what, &vp);
        if (!rc)
            rc = s_position(c, vp, "position", what, &l.pos);
        if (!rc)
            rc = s_require(c, o, "intensity", what, &vi);
        if (!rc)
            rc = s_rgb(c, vi, "intensity", what, 0.0f, FLT_MAX, &l.intensity);
    } else if (strcmp(type, "spot") == 0) {
        static const char *const keys[] = { "type", "position", "direction", "intensity", "angle", "falloff_start",
                                            NULL };
        const char *what = "spot light";
        float angle = 0.0f, inner;
        l.type = PF_LIGHT_SPOT;
        rc = s_check_object(c, o, what, keys);
        if (!rc)
            rc = s_require(c, o, "position", what, &vp);
        if (!rc)
            rc = s_position(c, vp, "position", what, &l.pos);
        if (!rc)
            rc = s_require(c, o, "direction", what, &vd);
        if (!rc && !(rc = s_vec3(c, vd, "direction", what, &l.dir)) && !(pf_len2(l.dir) > 0.0f))
            rc = S_FAIL_AT(c, vd, "'direction' in spot light must not be zero");
        if (!rc)
            rc = s_require(c, o, "intensity", what, &vi);
        if (!rc)
            rc = s_rgb(c, vi, "intensity", what, 0.0f, FLT_MAX, &l.intensity);
        if (!rc)
            rc = s_require(c, o, "angle", what, &va);
        if (!rc && !(rc = s_float(c, va, "angle", what, &angle)) && !(angle > 0.0f && angle <= 90.0f))
            rc = S_FAIL_AT(c, va, "'angle' in spot light must be in (0, 90] degrees (got %g)", angle);
        inner = angle;
        if (!rc && (vf = s_get(o, "falloff_start")) && !(rc = s_float(c, vf, "falloff_start", what, &inner)) &&
            !(inner >= 0.0f && inner <= angle))
            rc = S_FAIL_AT(c, vf, "'falloff_start' in spot light must be in [0, angle] degrees (got %g)", inner);
        if (rc)
            return rc;
        l.dir = pf_norm(l.dir);
        l.cos_outer = (float)cos(angle * (3.14159265358979323846 / 180.0));
        l.cos_inner = (float)cos(inner * (3.14159265358979323846 / 180.0));
    } else {
        return S_FAIL_AT(c, vt, "unknown light type '%.64s' (expected point or spot)", type);
    }
    if (rc)
        return rc;
    if (pf_scene_add_light(c->scene, &l))
        return pf_error_set(c->err, PF_ENOMEM, c->path, 0, "out of memory");
    return PF_OK;
}

/* Runs fn over every element of an array-valued top-level key. */
static int s_each(s_ctx_t *c, const cJSON *arr, const char *key, int (*fn)(s_ctx_t *, const cJSON *))
{
    if (!cJSON_IsArray(arr))
        return S_FAIL_AT(c, arr, "'%s' must be an array, not %s", key, s_type_name(arr));
    for (const cJSON *e = arr->child; e; e = e->next) {
        int rc = fn(c, e);
        if (rc)
            return rc;
    }
    return PF_OK;
}

/* ------------------------------------------------------------------------ */
/* Entry point                                                              */

/* Reads the whole file, NUL-terminated. */
static int s_read_file(const char *path, char **text_p, size_t *len_p, pf_error_t *err)
{
    FILE *f = fopen(path, "rb");
    if (!f)
        return pf_error_set(err, PF_EIO, path, 0, "cannot open: %s", strerror(errno));
    char *buf = NULL;
    size_t len = 0, cap = 0;
    int rc = PF_OK;
    for (;;) {
        if (len + 4096 + 1 > cap) {
            size_t ncap = cap ? 2 * cap : 65536;
            char *p = realloc(buf, ncap);
            if (!p) {
                rc = pf_error_set(err, PF_ENOMEM, path, 0, "out of memory");
                break;
            }
            buf = p;
            cap = ncap;
        }
        size_t got = fread(buf + len, 1, cap - len - 1, f);
        len += got;
        if (len > S_MAX_FILE_BYTES) {
            rc = pf_error_set(err, PF_ERANGE, path, 0, "the scene file is larger than %u MiB",
                              S_MAX_FILE_BYTES >> 20);
            break;
        }
        if (got == 0) {
            if (ferror(f))
                rc = pf_error_set(err, PF_EIO, path, 0, "read error: %s", strerror(errno));
            break;
        }
    }
    fclose(f);
    if (rc) {
        free(buf);
        return rc;
    }
    buf[len] = '\0';
    *text_p = buf;
    *len_p = len;
    return PF_OK;
}

static int s_line_at(const char *text, size_t pos)
{
    int line = 1;
    for (size_t i = 0; i < pos; i++)
        line += text[i] == '\n';
    return line;
}

static int s_syntax_error(const char *path, const char *text, size_t len, const char *at, pf_error_t *err)
{
    size_t pos = (at && at >= text && at <= text + len) ? (size_t)(at - text) : len;
    int line = s_line_at(text, pos);
    if (pos >= len)
        return pf_error_set(err, PF_EPARSE, path, line, "JSON syntax error near the end of the file");
    /* cJSON may point at the line end just after the culprit; show the
     * line's last token then rather than nothing. */
    size_t from = pos;
    while (from > 0 && (text[from] == '\n' || text[from] == '\r' || text[from] == ' ' || text[from] == '\t') &&
           text[from - 1] != '\n')
        from--;
    char near[32];
    size_t n = 0;
    for (size_t i = from; i < len && n < 24 && text[i] != '\n' && text[i] != '\r'; i++)
        near[n++] = (text[i] >= 32 && text[i] < 127) ? text[i] : '?';
    near[n] = '\0';
    return pf_error_set(err, PF_EPARSE, path, line, "JSON syntax error near '%s'", near);
}

int pf_scene_json_load(pf_scene_t *scene, const char *path, pf_error_t *err)
{
    PF_CHECK(scene && path);
    char *text = NULL;
    size_t len = 0;
    int rc = s_read_file(path, &text, &len, err);
    if (rc)
        return rc;
    if (!scene->path[0])
        snprintf(scene->path, sizeof scene->path, "%s", path);
    /* cJSON would stop at a NUL byte and accept the text before it. */
    const char *nul = memchr(text, '\0', len);
    if (nul) {
        rc = pf_error_set(err, PF_EPARSE, path, s_line_at(text, (size_t)(nul - text)), "NUL byte in the file");
        free(text);
        return rc;
    }
    const char *end = NULL;
    cJSON *root = cJSON_ParseWithOpts(text, &end, 1);
    if (!root) {
        rc = s_syntax_error(path, text, len, end, err);
        free(text);
        return rc;
    }

    s_ctx_t c = { .scene = scene, .err = err, .path = path, .mat_base = scene->nmats, .mat_end = scene->nmats };
    const char *slash = strrchr(path, '/');
    if (slash) {
        size_t n = (size_t)(slash - path);
        if (n == 0)
            n = 1; /* a file in "/": models become "//name", which is still "/name" */
        if (n >= sizeof c.dir) {
            rc = pf_error_set(err, PF_EINVAL, path, 0, "the scene file's path is too long");
            goto done;
        }
        memcpy(c.dir, path, n);
        c.dir[n] = '\0';
    }
    if (s_build_lines(text, len, root, &c.lines, &c.nlines) != PF_OK) {
        rc = pf_error_set(err, PF_ENOMEM, path, 0, "out of memory");
        goto done;
    }

    static const char *const top[] = { "camera", "render", "materials", "objects", "lights", NULL };
    rc = s_check_object(&c, root, "the scene (top level)", top);
    const cJSON *v;
    /* Fixed order, whatever the document's: objects refer to materials. */
    if (!rc && (v = s_get(root, "camera")))
        rc = s_camera(&c, v);
    if (!rc && (v = s_get(root, "render")))
        rc = s_render(&c, v);
    if (!rc && (v = s_get(root, "materials")))
        rc = s_each(&c, v, "materials", s_material);
    if (!rc && (v = s_get(root, "objects")))
        rc = s_each(&c, v, "objects", s_object);
    if (!rc && (v = s_get(root, "lights")))
        rc = s_each(&c, v, "lights", s_light);
done:
    free(c.lines);
    cJSON_Delete(root);
    free(text);
    return rc;
}
