/* pbrt_env.c: the pbrt-v4 reader's image-based infinite light,
 * LightSource "infinite" with "filename" (pbrt-v4's ImageInfiniteLight):
 * the image (PFM, EXR, HDR or 8-bit sRGB; load/envmap_load.c) read with
 * the equal-area octahedral mapping, which pbrt-v4 uses for every image
 * infinite light; the CTM at the LightSource is the light's frame (renderFromLight: a world direction d looks up the
 * map at CTM^-1 d); radiance = scale * pixel, and with "illuminance" E the
 * scale is multiplied by E / k with pbrt-v4's k: the sum over the pixels of
 * the upper hemisphere (light frame +z) of lum * cos, times 2 pi / (w h).
 * An equal-area pixel spans 4 pi / (w h), so k is half the upward
 * irradiance and the scaled map gives an upward patch 2 E; that is what
 * pbrt-v4 renders, and its references are what the scenes are compared to. "L" with a filename is
 * an error in pbrt-v4 and here; "portal" is warned and ignored. */
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "load/envmap_load.h"
#include "load/pbrt/pbrt_impl.h"

/* The light's frame: the CTM's linear part, row-major. */
static void s_frame(const pf_pbrt_t *c, double out[9])
{
    const double(*m)[4] = (const double(*)[4])c->gs.ctm;
    for (int i = 0; i < 3; i++)
        for (int j = 0; j < 3; j++)
            out[3 * i + j] = m[i][j];
}

int pf_pbrt_image_infinite(pf_pbrt_t *c, pf_pbrt_params_t *ps, pf_pbrt_loc_t loc, const char *file)
{
    const char *what = "LightSource \"infinite\"";
    double scale, illum;
    char path[4096];
    int rc = pf_pbrt_get_float(c, ps, "scale", 1.0, &scale);
    if (rc == PF_OK)
        rc = pf_pbrt_get_float(c, ps, "illuminance", -1.0, &illum);
    if (rc == PF_OK && scale < 0.0)
        rc = pf_pbrt_error_line(c, PF_ERANGE, loc, "%s: scale must be >= 0", what);
    if (rc == PF_OK && pf_pbrt_param(ps, "L"))
        rc = pf_pbrt_error_line(c, PF_EPARSE, loc, "%s: give either \"L\" or \"filename\", not both", what);
    pf_pbrt_param_t *portal = rc == PF_OK ? pf_pbrt_param(ps, "portal") : NULL;
    if (portal)
        rc = pf_pbrt_warn(c, portal->loc, "infinite light portal (ignored)",
                          "%s: \"portal\" is not supported; the whole map is sampled", what);
    if (rc == PF_OK)
        rc = pf_pbrt_check_unused(c, ps, what);
    if (rc == PF_OK)
        rc = pf_pbrt_resolve(c, loc, file, 0, path, sizeof path);
    if (rc)
        return rc;
    if (c->cur_object >= 0)
        return pf_pbrt_warn(c, loc, "light inside an object definition (ignored)",
                            "%s inside ObjectBegin is not instanced (pbrt ignores it too)", what);
    pf_envmap_t map;
    size_t clamped = 0;
    pf_error_t err = { { 0 } };
    rc = pf_envmap_load(path, PF_ENVMAP_EQUALAREA, &map, &clamped, &err);
    if (rc)
        return pf_pbrt_error_line(c, rc, loc, "%s: %s", what, err.msg);
    double frame[9];
    s_frame(c, frame);
    if (pf_envmap_set_frame(&map, frame)) {
        pf_envmap_t tmp = map;
        pf_scene_add_envmap(c->scene, &tmp); /* the scene frees it */
        return pf_pbrt_error_line(c, PF_EPARSE, loc, "%s: the transformation is singular", what);
    }
    if (clamped)
        rc = pf_pbrt_warn(c, loc, "environment map values clamped",
                          "%s: %zu negative or non-finite values in %s read as 0", what, clamped, path);
    if (rc == PF_OK && illum > 0.0) { /* pbrt-v4: a negative or zero illuminance is unset */
        double k = 0.5 * pf_envmap_integral(&map, pf_v3s(1.0f), 1); /* pbrt-v4's 2 pi, not 4 pi */
        if (k > 0.0)
            scale *= illum / k;
    }
    int idx = pf_scene_add_envmap(c->scene, &map);
    if (idx < 0) {
        free(map.rgb);
        return pf_pbrt_error(c, PF_ENOMEM, loc, "out of memory");
    }
    if (rc)
        return rc;
    pf_light_t l = { .type = PF_LIGHT_INFINITE, .intensity = pf_v3s((float)scale), .map = (uint32_t)idx + 1 };
    if (!pf_is_finite3(l.intensity))
        return pf_pbrt_error_line(c, PF_ERANGE, loc, "%s: scale is not finite", what);
    if (pf_scene_add_light(c->scene, &l))
        return pf_pbrt_error(c, PF_ENOMEM, loc, "out of memory");
    return PF_OK;
}
