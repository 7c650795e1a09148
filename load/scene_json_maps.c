/* scene_json_maps.c: a JSON material's normal and bump maps (any type):
 *   "normal_map": "file.png"   tangent-space normals, linear RGB (2 c - 1)
 *   "bump": "file.png"         heights, the first channel read linear,
 *   "bump_scale": number       times this (default 1), in world units
 * Paths are relative to the JSON file's folder. The renderer bends the
 * shading normal by them (accel/shading.h). */
#include <math.h>
#include <stdio.h>
#include <string.h>

#include "load/json_ctx.h"
#include "mesh/texload.h"

int pf_json_is_map_key(const char *key)
{
    return !strcmp(key, "normal_map") || !strcmp(key, "bump") || !strcmp(key, "bump_scale");
}

/* Reads the image named by v (key) into a texture of that scale: its ref in *ref. */
static int s_image(s_ctx_t *c, const cJSON *v, const char *key, float scale, uint32_t *ref)
{
    const char *file;
    int rc = pf_json_string(c, v, key, "material", &file);
    if (rc)
        return rc;
    char path[2048];
    if ((rc = pf_json_file_path(c, v, file, path, sizeof path)))
        return rc;
    pf_texture_t t = pf_texture_constant(key, pf_v3s(0.0f));
    t.scale = scale;
    pf_error_t err = { { 0 } };
    int r = pf_texture_load_image(c->scene, path, &t, PF_TEXENC_LINEAR, c->path, pf_json_line_of(c, v), &err);
    if (r < 0)
        return pf_json_fail_line(c, r, pf_json_line_of(c, v), "%s", err.msg);
    *ref = (uint32_t)r;
    return PF_OK;
}

int pf_json_maps(s_ctx_t *c, const cJSON *m, pf_material_t *mat)
{
    const cJSON *v, *vs = pf_json_get(m, "bump_scale");
    float scale = 1.0f;
    int rc;
    if (vs && (rc = pf_json_float(c, vs, "bump_scale", "material", &scale)))
        return rc;
    if (vs && !pf_json_get(m, "bump"))
        return S_FAIL_AT(c, vs, "'bump_scale' in material needs 'bump'");
    if ((v = pf_json_get(m, "normal_map")) && (rc = s_image(c, v, "normal_map", 1.0f, &mat->normal_tex)))
        return rc;
    if ((v = pf_json_get(m, "bump")) && (rc = s_image(c, v, "bump", scale, &mat->bump_tex)))
        return rc;
    return PF_OK;
}
