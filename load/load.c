/* load.c: the loader dispatch by file extension; see load.h. */
#include "load/load.h"

#include <stdio.h>
#include <string.h>
#include <strings.h>

static const char *s_ext(const char *path)
{
    const char *dot = strrchr(path, '.');
    const char *slash = strrchr(path, '/');
    return (dot && (!slash || dot > slash)) ? dot + 1 : "";
}

pf_scene_t *pf_scene_load(const char *path, pf_error_t *err) { return pf_scene_load_opts(path, NULL, err); }

/* Whether path ends in ".ply.gz". */
static int s_is_ply_gz(const char *path)
{
    size_t n = strlen(path);
    return n > 7 && strcasecmp(path + n - 7, ".ply.gz") == 0;
}

pf_scene_t *pf_scene_load_opts(const char *path, const pf_load_opts_t *opts, pf_error_t *err)
{
    pf_scene_t *scene = pf_scene_create();
    if (!scene) {
        pf_error_set(err, PF_ENOMEM, path, 0, "out of memory");
        return NULL;
    }
    snprintf(scene->path, sizeof scene->path, "%s", path);
    const char *ext = s_ext(path);
    int rc;
    if (strcasecmp(ext, "json") == 0) {
        rc = pf_scene_json_load(scene, path, err);
    } else if (strcasecmp(ext, "obj") == 0) {
        rc = pf_obj_load(scene, path, NULL, -1, err);
    } else if (strcasecmp(ext, "pbrt") == 0) {
        rc = pf_pbrt_load(scene, path, opts, err);
    } else if (strcasecmp(ext, "ply") == 0 || s_is_ply_gz(path)) {
        pf_material_t m = pf_material_default("default");
        int mi = pf_scene_add_material(scene, &m);
        rc = mi < 0 ? mi : pf_ply_load(scene, path, NULL, (uint32_t)mi, err);
        if (rc == PF_OK && scene->nlights == 0) {
            /* A bare mesh has no light: add a point light at the default camera. */
            pf_vec3 lo, hi;
            pf_scene_bounds(scene, &lo, &hi);
            float r = pf_len(pf_sub(hi, lo));
            pf_light_t l = { .type = PF_LIGHT_POINT,
                             .pos = pf_add(pf_scale(pf_add(lo, hi), 0.5f), pf_v3(0.5f * r, r, 1.5f * r)),
                             .intensity = pf_v3s(r * r) };
            rc = pf_scene_add_light(scene, &l);
        }
    } else {
        rc = pf_error_set(err, PF_EUNSUPPORTED, path, 0, "unknown scene type '.%s' (expected .json, .obj, .ply, .ply.gz or .pbrt)", ext);
    }
    if (rc == PF_OK)
        rc = pf_scene_finalize(scene, err);
    if (rc != PF_OK) {
        pf_scene_destroy(&scene);
        return NULL;
    }
    return scene;
}
