/* scene_json_env.c: the JSON reader's image-based infinite light:
 *   { "type": "infinite", "image": "sky.pfm" (or .exr, .hdr, or an
 *     8-bit image taken as sRGB; relative to the scene file), "mapping": "equalarea" (the default, as pbrt-v4) or
 *     "equirect", "scale": a number or RGB (default 1), "up": the world
 *     direction of the map's +z, its zenith (default [0, 1, 0]) }
 * The map's +x goes to the world direction of +x made perpendicular to up
 * (for the default up, light (x, y, z) is world (x, -z, y): the JSON scenes
 * are y-up, the maps z-up). See scene/envmap.h for the mappings. */
#include <errno.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "load/envmap_load.h"
#include "base/log.h"
#include "load/json_ctx.h"

/* The frame whose z is up: row-major, columns x, y, z. */
static void s_frame(pf_vec3 up, double out[9])
{
    pf_vec3 z = pf_norm(up);
    pf_vec3 x = pf_v3(1, 0, 0);
    if (fabsf(z.x) > 0.9f)
        x = pf_v3(0, 0, 1);
    x = pf_norm(pf_sub(x, pf_scale(z, pf_dot(x, z))));
    pf_vec3 y = pf_cross(z, x);
    pf_vec3 col[3] = { x, y, z };
    for (int j = 0; j < 3; j++) {
        out[0 + j] = col[j].x;
        out[3 + j] = col[j].y;
        out[6 + j] = col[j].z;
    }
}

int pf_json_envlight(s_ctx_t *c, const cJSON *o, pf_light_t *l)
{
    static const char *const keys[] = { "type", "image", "mapping", "scale", "up", NULL };
    const char *what = "infinite light";
    const cJSON *vi = NULL, *v;
    const char *file, *mapping = "equalarea";
    pf_vec3 scale = pf_v3s(1.0f), up = pf_v3(0, 1, 0);
    int rc = pf_json_check_object(c, o, what, keys);
    if (!rc)
        rc = pf_json_require(c, o, "image", what, &vi);
    if (!rc)
        rc = pf_json_string(c, vi, "image", what, &file);
    if (!rc && (v = pf_json_get(o, "mapping")) && !(rc = pf_json_string(c, v, "mapping", what, &mapping)) &&
        strcmp(mapping, "equalarea") != 0 && strcmp(mapping, "equirect") != 0)
        rc = S_FAIL_AT(c, v, "'mapping' in infinite light must be \"equalarea\" or \"equirect\", not '%.64s'", mapping);
    if (!rc && (v = pf_json_get(o, "scale")))
        rc = pf_json_rgb(c, v, "scale", what, 0.0f, 1e30f, &scale);
    if (!rc && (v = pf_json_get(o, "up")) && !(rc = pf_json_vec3(c, v, "up", what, &up)) && !(pf_len2(up) > 0.0f))
        rc = S_FAIL_AT(c, v, "'up' in infinite light must not be zero");
    if (rc)
        return rc;
    char path[2048];
    if ((rc = pf_json_file_path(c, vi, file, path, sizeof path)))
        return rc;
    pf_envmap_t map;
    size_t clamped = 0;
    pf_error_t err = { { 0 } };
    rc = pf_envmap_load(path, strcmp(mapping, "equirect") == 0 ? PF_ENVMAP_EQUIRECT : PF_ENVMAP_EQUALAREA, &map,
                        &clamped, &err);
    if (rc)
        return pf_json_fail_line(c, rc, pf_json_line_of(c, vi), "%s", err.msg);
    if (clamped)
        pf_warn("%s:%d: %zu negative or non-finite values in %s read as 0", c->path, pf_json_line_of(c, vi), clamped,
                path);
    double frame[9];
    s_frame(up, frame);
    pf_envmap_set_frame(&map, frame); /* orthonormal: never singular */
    int idx = pf_scene_add_envmap(c->scene, &map);
    if (idx < 0) {
        free(map.rgb);
        return pf_error_set(c->err, PF_ENOMEM, c->path, 0, "out of memory");
    }
    *l = (pf_light_t){ .type = PF_LIGHT_INFINITE, .intensity = scale, .map = (uint32_t)idx + 1 };
    return PF_OK;
}
