/* scene_json.c: the JSON scene format (docs/scene-format.md). It parses the
 * file with cJSON, checks every key and value, and appends the camera, render
 * settings, materials, objects (OBJ and PLY models through their loaders,
 * analytic spheres, quads) and point, spot, distant and infinite lights to a pf_scene_t. It does not
 * finalize the scene; pf_scene_load does that.
 *
 * This file holds the scene's sections and the entry point; reading the file,
 * the line of every value (for "file:line: what" errors) and typed access to
 * values are in scene_json_read.c, shared through json_ctx.h.
 *
 * Owns nothing beyond the call: the text, the tree and the line table are
 * freed before returning. Called from one thread at a time per scene. */
#include "load/load.h"

#include <cjson/cJSON.h>
#include <errno.h>
#include <float.h>
#include <math.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "load/json_ctx.h"

/* Entries in an obj object's "materials" map (MTL files with more distinct
 * materials than this are not plausible). */
#define S_MAX_REMAP 4096

/* ------------------------------------------------------------------------ */
/* Materials by name                                                        */

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
    int rc = pf_json_string(c, v, key, what, &name);
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

/* The thin lens: "lens_radius" (>= 0; 0, the default, is the pinhole) and
 * "focal_distance" (> 0; by default the distance from position to look_at,
 * so that the look-at point is in focus). */
static int s_camera_lens(s_ctx_t *c, const cJSON *cam, pf_camera_desc_t *d)
{
    const char *what = "camera";
    const cJSON *v;
    int rc = PF_OK;
    if ((v = pf_json_get(cam, "lens_radius")) && !(rc = pf_json_float(c, v, "lens_radius", what, &d->lens_radius)) &&
        !(d->lens_radius >= 0.0f && d->lens_radius <= 1e18f))
        rc = S_FAIL_AT(c, v, "'lens_radius' in camera must be >= 0 and at most 1e18 (got %g)", (double)d->lens_radius);
    if (rc)
        return rc;
    if ((v = pf_json_get(cam, "focal_distance"))) {
        if (!(rc = pf_json_float(c, v, "focal_distance", what, &d->focal_distance)) &&
            !(d->focal_distance > 0.0f && d->focal_distance <= 1e18f))
            rc = S_FAIL_AT(c, v, "'focal_distance' in camera must be > 0 and at most 1e18 (got %g)",
                           (double)d->focal_distance);
    } else if (d->lens_radius > 0.0f) {
        d->focal_distance = pf_len(pf_sub(d->look_at, d->pos));
        if (!(d->focal_distance <= 1e18f))
            rc = S_FAIL_AT(c, cam, "camera: 'look_at' is %g from 'position', too far to be the focal distance; "
                           "give 'focal_distance'", (double)d->focal_distance);
    }
    return rc;
}

static int s_camera(s_ctx_t *c, const cJSON *cam)
{
    static const char *const keys[] = { "position", "look_at", "up", "fov", "lens_radius", "focal_distance", NULL };
    const char *what = "camera";
    int rc = pf_json_check_object(c, cam, what, keys);
    const cJSON *pos = NULL, *at = NULL, *v;
    pf_camera_desc_t d = { .up = pf_v3(0, 1, 0), .vfov_deg = 40.0f };
    if (!rc)
        rc = pf_json_require(c, cam, "position", what, &pos);
    if (!rc)
        rc = pf_json_position(c, pos, "position", what, &d.pos);
    if (!rc)
        rc = pf_json_require(c, cam, "look_at", what, &at);
    if (!rc)
        rc = pf_json_vec3(c, at, "look_at", what, &d.look_at);
    if (!rc && (v = pf_json_get(cam, "up")) && !(rc = pf_json_vec3(c, v, "up", what, &d.up)) && !(pf_len2(d.up) > 0.0f))
        rc = S_FAIL_AT(c, v, "'up' in camera must not be zero");
    if (!rc && (v = pf_json_get(cam, "fov")) && !(rc = pf_json_float(c, v, "fov", what, &d.vfov_deg)) &&
        !(d.vfov_deg > 0.0f && d.vfov_deg < 180.0f))
        rc = S_FAIL_AT(c, v, "'fov' in camera must be in (0, 180) degrees (got %g)", d.vfov_deg);
    if (rc)
        return rc;
    pf_vec3 view = pf_sub(d.look_at, d.pos);
    if (!(pf_len2(view) > 0.0f))
        return S_FAIL_AT(c, at, "'look_at' in camera must differ from 'position'");
    if (!(pf_len2(pf_cross(pf_norm(view), pf_norm(d.up))) > 1e-12f))
        return S_FAIL_AT(c, cam, "camera 'up' must not be parallel to the view direction");
    if ((rc = s_camera_lens(c, cam, &d)))
        return rc;
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
        { "path_max_depth", offsetof(pf_settings_t, path_max_depth), -1, 100000 },
        { "global_k", offsetof(pf_settings_t, global_k), 1, 1 << 16 },
        { "caustic_k", offsetof(pf_settings_t, caustic_k), 1, 1 << 16 },
        { "irradiance_stride", offsetof(pf_settings_t, irradiance_stride), 1, 1 << 20 },
    };
    static const char *const keys[] = { "width", "height", "spp", "photons", "caustic_photons", "gather",
                                        "gather_filter", "light_samples", "max_depth", "photon_max_depth", "path_max_depth", "global_k",
                                        "caustic_k", "caustic_radius", "global_radius", "irradiance_stride",
                                        "seed", "exposure", "pixel_filter", NULL };
    const char *what = "render";
    int rc = pf_json_check_object(c, r, what, keys);
    pf_settings_t *s = &c->scene->settings;
    for (size_t i = 0; !rc && i < sizeof ints / sizeof ints[0]; i++) {
        const cJSON *v = pf_json_get(r, ints[i].key);
        if (v)
            rc = pf_json_int(c, v, ints[i].key, what, ints[i].lo, ints[i].hi, (int *)((char *)s + ints[i].offset));
    }
    const cJSON *v;
    if (!rc && (v = pf_json_get(r, "photons")))
        rc = pf_json_u64(c, v, "photons", what, &s->photons);
    if (!rc && (v = pf_json_get(r, "caustic_photons")))
        rc = pf_json_u64(c, v, "caustic_photons", what, &s->caustic_photons);
    if (!rc && (v = pf_json_get(r, "seed")))
        rc = pf_json_u64(c, v, "seed", what, &s->seed);
    if (!rc && (v = pf_json_get(r, "caustic_radius")) &&
        !(rc = pf_json_float(c, v, "caustic_radius", what, &s->caustic_radius)) && s->caustic_radius < 0.0f)
        rc = S_FAIL_AT(c, v, "'caustic_radius' in render must be >= 0 (0: automatic)");
    if (!rc && (v = pf_json_get(r, "global_radius")) &&
        !(rc = pf_json_float(c, v, "global_radius", what, &s->global_radius)) && s->global_radius < 0.0f)
        rc = S_FAIL_AT(c, v, "'global_radius' in render must be >= 0 (0: automatic)");
    if (!rc && (v = pf_json_get(r, "exposure")))
        rc = pf_json_float(c, v, "exposure", what, &s->exposure);
    if (!rc && (v = pf_json_get(r, "pixel_filter")) &&
        (!cJSON_IsString(v) || pf_pixel_filter_parse(v->valuestring, &s->filter_box, &s->filter_tent) != PF_OK))
        rc = S_FAIL_AT(c, v, "'pixel_filter' in render must be \"box\", \"box:W\", \"tent:R\" or \"box+tent:R\" "
                             "with widths in 0..4 pixels");
    return rc;
}

/* A conductor's keys: "eta" and "k" (RGB, the complex index), or
 * "reflectance" (RGB normal-incidence reflectance: eta 1, k from it, as
 * pbrt-v4), and "roughness" (GGX alpha in [0, 1]; 0, the default: smooth). */
static int s_conductor(s_ctx_t *c, const cJSON *m, pf_material_t *mat)
{
    const char *what = "material";
    const cJSON *veta = pf_json_get(m, "eta"), *vk = pf_json_get(m, "k"), *vr = pf_json_get(m, "reflectance"), *v;
    int rc;
    if (vr && (veta || vk))
        return S_FAIL_AT(c, vr, "material '%s': give a conductor 'reflectance' or 'eta' and 'k', not both", mat->name);
    if (!vr && !(veta && vk))
        return S_FAIL_AT(c, m, "material '%s': a conductor needs 'eta' and 'k', or 'reflectance'", mat->name);
    if (vr) {
        pf_vec3 r;
        if ((rc = pf_json_rgb(c, vr, "reflectance", what, 0.0f, 1.0f, &r)))
            return rc;
        mat->eta = pf_v3s(1.0f);
        mat->k = pf_v3(pf_conductor_k_of_reflectance(r.x), pf_conductor_k_of_reflectance(r.y),
                       pf_conductor_k_of_reflectance(r.z));
    } else {
        if ((rc = pf_json_rgb(c, veta, "eta", what, 0.0f, FLT_MAX, &mat->eta)))
            return rc;
        if (!(mat->eta.x > 0.0f && mat->eta.y > 0.0f && mat->eta.z > 0.0f))
            return S_FAIL_AT(c, veta, "'eta' in material must be > 0 in every channel");
        if ((rc = pf_json_rgb(c, vk, "k", what, 0.0f, FLT_MAX, &mat->k)))
            return rc;
    }
    if ((v = pf_json_get(m, "roughness"))) {
        if ((rc = pf_json_float(c, v, "roughness", what, &mat->alpha)))
            return rc;
        if (!(mat->alpha >= 0.0f && mat->alpha <= 1.0f))
            return S_FAIL_AT(c, v, "'roughness' in material must lie in [0, 1] (got %g)", mat->alpha);
    }
    return PF_OK;
}

/* A coated material's "roughness" (GGX alpha in [0, 1]) and "thickness"
 * (>= 0; 0, the default: a lossless coat); its "kd" and "ior" are read with
 * the other kinds'. Glass's "roughness" too (rough glass from 1e-3). */
static int s_coated(s_ctx_t *c, const cJSON *m, pf_material_t *mat)
{
    const char *what = "material";
    const cJSON *v;
    int rc;
    if ((v = pf_json_get(m, "roughness")) && (rc = pf_json_float(c, v, "roughness", what, &mat->alpha)))
        return rc;
    if (v && !(mat->alpha >= 0.0f && mat->alpha <= 1.0f))
        return S_FAIL_AT(c, v, "'roughness' in material must lie in [0, 1] (got %g)", mat->alpha);
    if ((v = pf_json_get(m, "thickness")) && (rc = pf_json_float(c, v, "thickness", what, &mat->thickness)))
        return rc;
    if (v && !(mat->thickness >= 0.0f))
        return S_FAIL_AT(c, v, "'thickness' in material must be >= 0 (got %g)", mat->thickness);
    if (mat->type == PF_MAT_COATED && !(mat->ior >= 1.0f))
        return S_FAIL_AT(c, m, "a coated material's 'ior' must be >= 1 (got %g)", mat->ior);
    return PF_OK;
}

static int s_material(s_ctx_t *c, const cJSON *m)
{
    static const char *const keys[] = { "name", "type", "kd", "ks", "ns", "kt", "ior", "emission", "twosided",
                                        "eta", "k", "reflectance", "roughness", "thickness", "materials", "amount",
                                        "normal_map", "bump", "bump_scale", "absorption", NULL };
    const char *what = "material";
    int rc = pf_json_check_object(c, m, what, keys);
    const cJSON *vname = NULL, *v;
    const char *name = NULL, *type = "diffuse";
    if (!rc)
        rc = pf_json_require(c, m, "name", what, &vname);
    if (!rc)
        rc = pf_json_string(c, vname, "name", what, &name);
    if (!rc && strlen(name) >= PF_NAME_MAX)
        rc = S_FAIL_AT(c, vname, "material name '%.64s...' is longer than %d bytes", name, PF_NAME_MAX - 1);
    if (!rc && s_find_json_material(c, name) >= 0)
        rc = S_FAIL_AT(c, vname, "duplicate material name '%s'", name);
    const cJSON *vtype = pf_json_get(m, "type");
    if (!rc && vtype)
        rc = pf_json_string(c, vtype, "type", what, &type);
    if (rc)
        return rc;

    pf_material_t mat = pf_material_default(name);
    /* Keys that a kind ignores are errors: a glass "kd" or a diffuse "ior"
     * is a mistake the author wants to hear about, not silently dropped. */
    const char *const *valid;
    static const char *const diffuse_keys[] = { "kd", "ks", "ns", "emission", NULL };
    static const char *const mirror_keys[] = { "ks", "emission", NULL };
    static const char *const glass_keys[] = { "ks", "kt", "ior", "roughness", "absorption", "emission", NULL };
    static const char *const thin_keys[] = { "ks", "kt", "ior", "emission", NULL };
    static const char *const conductor_keys[] = { "eta", "k", "reflectance", "roughness", "emission", NULL };
    static const char *const coated_keys[] = { "kd", "ior", "roughness", "thickness", "emission", NULL };
    if (strcmp(type, "diffuse") == 0) {
        mat.type = PF_MAT_DIFFUSE;
        valid = diffuse_keys;
    } else if (strcmp(type, "mirror") == 0) {
        /* A mirror or glass (solid or thin) written without "ks" should reflect, so their
         * defaults differ from the grey Lambertian's. */
        mat.type = PF_MAT_MIRROR;
        mat.kd = pf_v3s(0.0f);
        mat.ks = pf_v3s(1.0f);
        valid = mirror_keys;
    } else if (strcmp(type, "glass") == 0 || strcmp(type, "dielectric") == 0) {
        mat.type = PF_MAT_GLASS;
        mat.kd = pf_v3s(0.0f);
        mat.ks = pf_v3s(1.0f);
        valid = glass_keys;
    } else if (strcmp(type, "thindielectric") == 0) {
        mat.type = PF_MAT_THIN_DIELECTRIC;
        mat.kd = pf_v3s(0.0f);
        mat.ks = pf_v3s(1.0f);
        valid = thin_keys;
    } else if (strcmp(type, "conductor") == 0) {
        mat.type = PF_MAT_CONDUCTOR;
        mat.kd = pf_v3s(0.0f);
        valid = conductor_keys;
    } else if (strcmp(type, "coated") == 0) {
        mat.type = PF_MAT_COATED;
        valid = coated_keys;
    } else if (!pf_json_material_kind(type, &mat, &valid)) {
        return S_FAIL_AT(c, vtype,
                         "unknown material type '%.64s' (expected diffuse, mirror, glass or dielectric, "
                         "thindielectric, conductor, coated, diffusetransmission or mix)",
                         type);
    }
    for (const cJSON *k = m->child; k; k = k->next) {
        if (strcmp(k->string, "name") == 0 || strcmp(k->string, "type") == 0 || strcmp(k->string, "comment") == 0 ||
            strcmp(k->string, "twosided") == 0 || pf_json_is_map_key(k->string))
            continue; /* twosided: with emission, on every type (scene_json_mat.c) */
        int ok = 0;
        for (const char *const *p = valid; *p && !ok; p++)
            ok = strcmp(k->string, *p) == 0;
        if (!ok)
            return S_FAIL_KEY(c, k, "key '%s' does not apply to a %s material", k->string, type);
    }
    if ((v = pf_json_get(m, "kd")) && (rc = pf_json_rgb(c, v, "kd", what, 0.0f, 1.0f, &mat.kd)))
        return rc;
    if ((v = pf_json_get(m, "ks")) && (rc = pf_json_rgb(c, v, "ks", what, 0.0f, 1.0f, &mat.ks)))
        return rc;
    if ((v = pf_json_get(m, "kt")) && (rc = pf_json_rgb(c, v, "kt", what, 0.0f, 1.0f, &mat.kt)))
        return rc;
    if ((v = pf_json_get(m, "emission")) && (rc = pf_json_rgb(c, v, "emission", what, 0.0f, FLT_MAX, &mat.le)))
        return rc;
    /* glass: the solid's inside absorbs (per unit length; its faces'
     * winding says which side is inside) */
    if ((v = pf_json_get(m, "absorption")) &&
        (rc = pf_json_rgb(c, v, "absorption", what, 0.0f, FLT_MAX, &mat.sigma_in)))
        return rc;
    if ((v = pf_json_get(m, "ns"))) {
        if ((rc = pf_json_float(c, v, "ns", what, &mat.ns)))
            return rc;
        if (mat.ns < 0.0f)
            return S_FAIL_AT(c, v, "'ns' in material must be >= 0 (got %g)", mat.ns);
    }
    if ((v = pf_json_get(m, "ior"))) {
        if ((rc = pf_json_float(c, v, "ior", what, &mat.ior)))
            return rc;
        if (!(mat.ior > 0.0f))
            return S_FAIL_AT(c, v, "'ior' in material must be > 0 (got %g)", mat.ior);
    }
    if (mat.type == PF_MAT_CONDUCTOR && (rc = s_conductor(c, m, &mat)))
        return rc;
    if ((mat.type == PF_MAT_COATED || mat.type == PF_MAT_GLASS) && (rc = s_coated(c, m, &mat)))
        return rc;
    if ((rc = pf_json_material_more(c, m, &mat)) || (rc = pf_json_maps(c, m, &mat)))
        return rc;
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
    int rc = pf_json_check_object(c, t, what, keys);
    if (rc)
        return rc;
    pf_xform_t x = pf_xform_identity();
    const cJSON *v;
    *lin_node = t;
    if ((v = pf_json_get(t, "matrix"))) {
        for (const cJSON *m = t->child; m; m = m->next)
            if (strcmp(m->string, "matrix") && strcmp(m->string, "comment"))
                return S_FAIL_KEY(c, m, "'%s' cannot be combined with 'matrix' in a transform", m->string);
        int n = cJSON_IsArray(v) ? cJSON_GetArraySize(v) : 0;
        float f[16];
        if (n != 12 && n != 16)
            return S_FAIL_AT(c, v, "'matrix' in transform must be an array of 12 or 16 numbers (row-major)");
        if ((rc = pf_json_floats(c, v, "matrix", what, n, f)))
            return rc;
        if (n == 16 && !(f[12] == 0.0f && f[13] == 0.0f && f[14] == 0.0f && f[15] == 1.0f))
            return S_FAIL_AT(c, v, "'matrix' in transform: the last row must be 0 0 0 1 (no projections)");
        for (int i = 0; i < 12; i++)
            x.m[i / 4][i % 4] = f[i];
        *lin_node = v;
    } else {
        if ((v = pf_json_get(t, "scale"))) {
            pf_vec3 s;
            if (cJSON_IsNumber(v)) {
                float g;
                if ((rc = pf_json_float(c, v, "scale", what, &g)))
                    return rc;
                s = pf_v3s(g);
            } else if (cJSON_IsArray(v)) {
                if ((rc = pf_json_vec3(c, v, "scale", what, &s)))
                    return rc;
            } else {
                return S_FAIL_AT(c, v, "'scale' in transform must be a number or an array of 3 numbers, not %s",
                                 pf_json_type_name(v));
            }
            if (s.x == 0.0f || s.y == 0.0f || s.z == 0.0f)
                return S_FAIL_AT(c, v, "'scale' in transform must not be zero (it would flatten the geometry)");
            x.m[0][0] = s.x;
            x.m[1][1] = s.y;
            x.m[2][2] = s.z;
            *lin_node = v;
        }
        if ((v = pf_json_get(t, "rotate"))) {
            float r[3];
            if ((rc = pf_json_floats(c, v, "rotate", what, 3, r)))
                return rc;
            for (int axis = 0; axis < 3; axis++) {
                pf_xform_t rx = s_rotation(axis, r[axis]);
                x = pf_xform_then(&x, &rx);
            }
        }
        if ((v = pf_json_get(t, "translate"))) {
            pf_vec3 d;
            if ((rc = pf_json_vec3(c, v, "translate", what, &d)))
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
    const cJSON *t = pf_json_get(obj, "transform");
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
    int rc = pf_json_require(c, obj, "file", what, &v);
    if (!rc)
        rc = pf_json_string(c, v, "file", what, &file);
    if (rc)
        return rc;
    int n = (file[0] == '/' || c->dir[0] == '\0') ? snprintf(out, cap, "%s", file)
                                                    : snprintf(out, cap, "%s/%s", c->dir, file);
    if (n < 0 || (size_t)n >= cap)
        return S_FAIL_AT(c, v, "the path '%.64s...' is too long", file);
    FILE *f = fopen(out, "rb");
    if (!f)
        return pf_json_fail_line(c, PF_EIO, pf_json_line_of(c, v), "cannot open %s '%s': %s", what, out,
                                 strerror(errno));
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
           s_vec_equal(a->le, b->le) && a->twosided == b->twosided && s_vec_equal(a->eta, b->eta) && s_vec_equal(a->k, b->k) && a->alpha == b->alpha;
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
    int rc = pf_json_check_object(c, o, what, keys);
    char path[2048];
    int mat = -1, has_xf;
    pf_xform_t xf;
    const cJSON *lin, *vmat = pf_json_get(o, "material"), *vmap = pf_json_get(o, "materials");
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
    int rc = pf_json_check_object(c, o, what, keys);
    char path[2048];
    int mat = -1, has_xf;
    pf_xform_t xf;
    const cJSON *lin, *vmat = NULL;
    if (!rc)
        rc = pf_json_require(c, o, "material", what, &vmat);
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
    int rc = pf_json_check_object(c, o, what, keys);
    const cJSON *vc = NULL, *vr = NULL, *vmat = NULL, *lin;
    pf_sphere_t sp;
    int mat = -1, has_xf;
    pf_xform_t xf;
    if (!rc)
        rc = pf_json_require(c, o, "center", what, &vc);
    if (!rc)
        rc = pf_json_position(c, vc, "center", what, &sp.center);
    if (!rc)
        rc = pf_json_require(c, o, "radius", what, &vr);
    if (!rc && !(rc = pf_json_float(c, vr, "radius", what, &sp.radius)) && !(sp.radius > 0.0f))
        rc = S_FAIL_AT(c, vr, "'radius' in sphere must be > 0 (got %g)", sp.radius);
    if (!rc)
        rc = pf_json_require(c, o, "material", what, &vmat);
    if (!rc)
        rc = s_material_ref(c, vmat, "material", what, &mat);
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
    if (!pf_json_in_range(pf_add(pf_vabs(sp.center), pf_v3s(sp.radius))))
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
    int rc = pf_json_check_object(c, o, what, keys);
    const cJSON *vo = NULL, *v1 = NULL, *v2 = NULL, *vmat = NULL, *lin;
    pf_vec3 org, e1, e2;
    int mat = -1, has_xf;
    pf_xform_t xf;
    if (!rc)
        rc = pf_json_require(c, o, "origin", what, &vo);
    if (!rc)
        rc = pf_json_vec3(c, vo, "origin", what, &org);
    if (!rc)
        rc = pf_json_require(c, o, "edge1", what, &v1);
    if (!rc)
        rc = pf_json_vec3(c, v1, "edge1", what, &e1);
    if (!rc)
        rc = pf_json_require(c, o, "edge2", what, &v2);
    if (!rc)
        rc = pf_json_vec3(c, v2, "edge2", what, &e2);
    if (!rc && !(pf_len2(pf_cross(e1, e2)) > 0.0f))
        rc = S_FAIL_AT(c, o, "quad has no area: 'edge1' and 'edge2' must be non-zero and not parallel");
    if (!rc)
        rc = pf_json_require(c, o, "material", what, &vmat);
    if (!rc)
        rc = s_material_ref(c, vmat, "material", what, &mat);
    if (!rc)
        rc = s_object_transform(c, o, &xf, &has_xf, &lin);
    if (rc)
        return rc;

    pf_mesh_t mesh;
    memset(&mesh, 0, sizeof mesh);
    snprintf(mesh.name, sizeof mesh.name, "quad (line %d)", pf_json_line_of(c, o));
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
    /* uv along the edges (0 to 1) for a normal or bump map's tangents */
    const pf_material_t *mm = &c->scene->mats[mat];
    static const float uv[8] = { 0, 0, 1, 0, 1, 1, 0, 1 };
    if ((mm->normal_tex | mm->bump_tex) && !(mesh.uv = malloc(sizeof uv))) {
        pf_mesh_free(&mesh);
        return pf_error_set(c->err, PF_ENOMEM, c->path, 0, "out of memory");
    }
    if (mesh.uv)
        memcpy(mesh.uv, uv, sizeof uv);
    if (pf_scene_add_mesh(c->scene, &mesh)) {
        pf_mesh_free(&mesh);
        return pf_error_set(c->err, PF_ENOMEM, c->path, 0, "out of memory");
    }
    return PF_OK;
}

static int s_object(s_ctx_t *c, const cJSON *o)
{
    if (!cJSON_IsObject(o))
        return S_FAIL_AT(c, o, "object must be an object, not %s", pf_json_type_name(o));
    const cJSON *vt;
    const char *type;
    int rc = pf_json_require(c, o, "type", "object", &vt);
    if (!rc)
        rc = pf_json_string(c, vt, "type", "object", &type);
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
        return S_FAIL_AT(c, o, "light must be an object, not %s", pf_json_type_name(o));
    const cJSON *vt, *vp = NULL, *vi = NULL, *vd = NULL, *va = NULL, *vf;
    const char *type;
    int rc = pf_json_require(c, o, "type", "light", &vt);
    if (!rc)
        rc = pf_json_string(c, vt, "type", "light", &type);
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
        rc = pf_json_check_object(c, o, what, keys);
        if (!rc)
            rc = pf_json_require(c, o, "position", what, &vp);
        if (!rc)
            rc = pf_json_position(c, vp, "position", what, &l.pos);
        if (!rc)
            rc = pf_json_require(c, o, "intensity", what, &vi);
        if (!rc)
            rc = pf_json_rgb(c, vi, "intensity", what, 0.0f, FLT_MAX, &l.intensity);
    } else if (strcmp(type, "spot") == 0) {
        static const char *const keys[] = { "type", "position", "direction", "intensity", "angle", "falloff_start",
                                            NULL };
        const char *what = "spot light";
        float angle = 0.0f, inner;
        l.type = PF_LIGHT_SPOT;
        rc = pf_json_check_object(c, o, what, keys);
        if (!rc)
            rc = pf_json_require(c, o, "position", what, &vp);
        if (!rc)
            rc = pf_json_position(c, vp, "position", what, &l.pos);
        if (!rc)
            rc = pf_json_require(c, o, "direction", what, &vd);
        if (!rc && !(rc = pf_json_vec3(c, vd, "direction", what, &l.dir)) && !(pf_len2(l.dir) > 0.0f))
            rc = S_FAIL_AT(c, vd, "'direction' in spot light must not be zero");
        if (!rc)
            rc = pf_json_require(c, o, "intensity", what, &vi);
        if (!rc)
            rc = pf_json_rgb(c, vi, "intensity", what, 0.0f, FLT_MAX, &l.intensity);
        if (!rc)
            rc = pf_json_require(c, o, "angle", what, &va);
        if (!rc && !(rc = pf_json_float(c, va, "angle", what, &angle)) && !(angle > 0.0f && angle <= 90.0f))
            rc = S_FAIL_AT(c, va, "'angle' in spot light must be in (0, 90] degrees (got %g)", angle);
        inner = angle;
        if (!rc && (vf = pf_json_get(o, "falloff_start")) &&
            !(rc = pf_json_float(c, vf, "falloff_start", what, &inner)) && !(inner >= 0.0f && inner <= angle))
            rc = S_FAIL_AT(c, vf, "'falloff_start' in spot light must be in [0, angle] degrees (got %g)", inner);
        if (rc)
            return rc;
        l.dir = pf_norm(l.dir);
        l.cos_outer = (float)cos(angle * (3.14159265358979323846 / 180.0));
        l.cos_inner = (float)cos(inner * (3.14159265358979323846 / 180.0));
    } else if (strcmp(type, "distant") == 0) {
        static const char *const keys[] = { "type", "direction", "irradiance", NULL };
        const char *what = "distant light";
        l.type = PF_LIGHT_DISTANT;
        rc = pf_json_check_object(c, o, what, keys);
        if (!rc)
            rc = pf_json_require(c, o, "direction", what, &vd);
        if (!rc && !(rc = pf_json_vec3(c, vd, "direction", what, &l.dir)) && !(pf_len2(l.dir) > 0.0f))
            rc = S_FAIL_AT(c, vd, "'direction' in distant light must not be zero");
        if (!rc)
            rc = pf_json_require(c, o, "irradiance", what, &vi);
        if (!rc)
            rc = pf_json_rgb(c, vi, "irradiance", what, 0.0f, FLT_MAX, &l.intensity);
        if (!rc)
            l.dir = pf_norm(l.dir);
    } else if (strcmp(type, "infinite") == 0 && pf_json_get(o, "image")) {
        rc = pf_json_envlight(c, o, &l); /* scene_json_env.c */
    } else if (strcmp(type, "infinite") == 0) {
        static const char *const keys[] = { "type", "radiance", NULL };
        const char *what = "infinite light";
        l.type = PF_LIGHT_INFINITE;
        rc = pf_json_check_object(c, o, what, keys);
        if (!rc)
            rc = pf_json_require(c, o, "radiance", what, &vi);
        if (!rc)
            rc = pf_json_rgb(c, vi, "radiance", what, 0.0f, FLT_MAX, &l.intensity);
    } else {
        return S_FAIL_AT(c, vt, "unknown light type '%.64s' (expected point, spot, distant or infinite)", type);
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
        return S_FAIL_AT(c, arr, "'%s' must be an array, not %s", key, pf_json_type_name(arr));
    for (const cJSON *e = arr->child; e; e = e->next) {
        int rc = fn(c, e);
        if (rc)
            return rc;
    }
    return PF_OK;
}

/* ------------------------------------------------------------------------ */
/* Entry point                                                              */

int pf_scene_json_load(pf_scene_t *scene, const char *path, pf_error_t *err)
{
    PF_CHECK(scene && path);
    char *text = NULL;
    size_t len = 0;
    int rc = pf_json_read_file(path, &text, &len, err);
    if (rc)
        return rc;
    if (!scene->path[0])
        snprintf(scene->path, sizeof scene->path, "%s", path);
    /* cJSON would stop at a NUL byte and accept the text before it. */
    const char *nul = memchr(text, '\0', len);
    if (nul) {
        rc = pf_error_set(err, PF_EPARSE, path, pf_json_line_at(text, (size_t)(nul - text)), "NUL byte in the file");
        free(text);
        return rc;
    }
    const char *end = NULL;
    cJSON *root = cJSON_ParseWithOpts(text, &end, 1);
    if (!root) {
        rc = pf_json_syntax_error(path, text, len, end, err);
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
    if (pf_json_build_lines(text, len, root, &c.lines, &c.nlines) != PF_OK) {
        rc = pf_error_set(err, PF_ENOMEM, path, 0, "out of memory");
        goto done;
    }

    static const char *const top[] = { "camera", "render", "materials", "objects", "lights", NULL };
    rc = pf_json_check_object(&c, root, "the scene (top level)", top);
    const cJSON *v;
    /* Fixed order, whatever the document's: objects refer to materials. */
    if (!rc && (v = pf_json_get(root, "camera")))
        rc = s_camera(&c, v);
    if (!rc && (v = pf_json_get(root, "render")))
        rc = s_render(&c, v);
    if (!rc && (v = pf_json_get(root, "materials")))
        rc = s_each(&c, v, "materials", s_material);
    if (!rc && (v = pf_json_get(root, "objects")))
        rc = s_each(&c, v, "objects", s_object);
    if (!rc && (v = pf_json_get(root, "lights")))
        rc = s_each(&c, v, "lights", s_light);
done:
    free(c.lines);
    cJSON_Delete(root);
    free(text);
    return rc;
}
