/* pbrt_medium.c: pbrt-v4's participating media as far as photonfarm renders
 * them. MakeNamedMedium records a medium; MediumInterface names the media
 * on the two sides of the shapes that follow (inside: behind the surface's
 * normal, outside: in front of it); each shape's scene material carries
 * their absorption (sigma_in, sigma_out in scene/scene.h), which every ray
 * and photon segment inside the medium pays by Beer-Lambert
 * (accel/surface.h). So tea in a teapot, red glass and a tinted liquid are
 * rendered: absorbing media, the common case in interiors.
 *
 * Rendered: a "homogeneous" medium's sigma_a times its scale (pbrt-v4's
 * defaults: sigma_a 1, sigma_s 1, scale 1). Reported, one warning line per
 * kind: scattering (sigma_s > 0: the medium neither scatters nor dims by
 * it; only its absorption is rendered), emission (Le), a measured preset
 * and the other medium types (grids, clouds: rendered clear), and a camera
 * inside an absorbing medium (its rays are not tinted before their first
 * surface). Called on the loading thread. */
#include <stdio.h>
#include <string.h>

#include "base/reserve.h"
#include "load/pbrt/pbrt_impl.h"

/* The name id of a medium name, -1 for "" (no medium). */
static int s_medium_id(pf_pbrt_t *c, const char *name, int *id)
{
    *id = -1;
    if (!name[0])
        return PF_OK;
    int r = pf_pbrt_intern(c, name);
    if (r < 0)
        return PF_ENOMEM;
    *id = r;
    return PF_OK;
}

/* A homogeneous medium's parameters into m; warnings for what is not rendered. */
static int s_homogeneous(pf_pbrt_t *c, const char *name, pf_pbrt_params_t *ps, pf_pbrt_loc_t loc,
                         pf_pbrt_medium_t *m)
{
    char what[96];
    snprintf(what, sizeof what, "MakeNamedMedium \"%.60s\"", name);
    const char *preset;
    pf_vec3 sa, ss, le;
    double scale, lescale, g;
    int has_le = 0;
    int rc = pf_pbrt_get_string(c, ps, "preset", "", &preset);
    if (rc == PF_OK)
        rc = pf_pbrt_get_color(c, ps, "sigma_a", PF_PBRT_UNBOUNDED, pf_v3s(1.0f), what, &sa, NULL);
    if (rc == PF_OK)
        rc = pf_pbrt_get_color(c, ps, "sigma_s", PF_PBRT_UNBOUNDED, pf_v3s(1.0f), what, &ss, NULL);
    if (rc == PF_OK)
        rc = pf_pbrt_get_float(c, ps, "scale", 1.0, &scale);
    if (rc == PF_OK)
        rc = pf_pbrt_get_color(c, ps, "Le", PF_PBRT_ILLUMINANT, pf_v3s(0.0f), what, &le, &has_le);
    if (rc == PF_OK)
        rc = pf_pbrt_get_float(c, ps, "Lescale", 1.0, &lescale);
    if (rc == PF_OK)
        rc = pf_pbrt_get_float(c, ps, "g", 0.0, &g); /* the phase function: no scattering, no use */
    if (rc)
        return rc;
    if (!(scale >= 0.0))
        return pf_pbrt_error_line(c, PF_ERANGE, loc, "%s: scale %g must be >= 0", what, scale);
    if (preset[0])
        return pf_pbrt_warn(c, loc, "medium preset (not rendered)",
                            "%s: the measured preset \"%.60s\" is not rendered: the medium is clear", what, preset);
    m->sigma_a = pf_scale(sa, (float)scale);
    if (has_le && !pf_is_black(le) && lescale != 0.0 &&
        (rc = pf_pbrt_warn(c, loc, "medium emission (ignored)", "%s: the medium's emission Le is not rendered",
                           what)))
        return rc;
    if (pf_maxc(ss) > 0.0f && scale > 0.0)
        return pf_pbrt_warn(c, loc, "medium scattering (ignored)",
                            "%s scatters (sigma_s %g %g %g): only its absorption (sigma_a %g %g %g) is rendered",
                            what, (double)ss.x * scale, (double)ss.y * scale, (double)ss.z * scale,
                            (double)m->sigma_a.x, (double)m->sigma_a.y, (double)m->sigma_a.z);
    return PF_OK;
}

int pf_pbrt_medium(pf_pbrt_t *c, const char *name, pf_pbrt_params_t *ps, pf_pbrt_loc_t loc)
{
    int id;
    if (!name[0])
        return pf_pbrt_error_line(c, PF_EPARSE, loc, "MakeNamedMedium needs a name (\"\" means no medium)");
    if (s_medium_id(c, name, &id) ||
        pf_reserve((void **)&c->media, &c->cap_media, c->nmedia + 1, sizeof *c->media))
        return pf_pbrt_error(c, PF_ENOMEM, loc, "out of memory");
    pf_pbrt_medium_t m = { pf_v3s(0.0f), loc };
    const char *type;
    int rc = pf_pbrt_get_string(c, ps, "type", "", &type);
    if (rc)
        return rc;
    if (!type[0])
        return pf_pbrt_error_line(c, PF_EPARSE, loc, "MakeNamedMedium \"%.60s\" has no \"string type\"", name);
    if (!strcmp(type, "homogeneous")) {
        rc = s_homogeneous(c, name, ps, loc, &m);
        if (rc == PF_OK)
            rc = pf_pbrt_check_unused(c, ps, "MakeNamedMedium");
    } else {
        for (size_t k = 0; k < ps->n; k++)
            ps->p[k].used = 1;
        rc = pf_pbrt_warn(c, loc, "medium type (not rendered)",
                          "MakeNamedMedium \"%.60s\": a \"%.40s\" medium is not rendered (clear)", name, type);
    }
    if (rc)
        return rc;
    /* A later definition of the name replaces the earlier, as in pbrt. */
    c->named_medium[id] = (int32_t)c->nmedia;
    c->media[c->nmedia++] = m;
    return PF_OK;
}

int pf_pbrt_medium_interface(pf_pbrt_t *c, const char *inside, const char *outside, pf_pbrt_loc_t loc)
{
    if (s_medium_id(c, inside, &c->gs.medium_in) || s_medium_id(c, outside, &c->gs.medium_out))
        return pf_pbrt_error(c, PF_ENOMEM, loc, "out of memory");
    c->gs.medium_loc = loc;
    return PF_OK;
}

int pf_pbrt_medium_sigma(pf_pbrt_t *c, int id, pf_pbrt_loc_t loc, pf_vec3 *sigma)
{
    *sigma = pf_v3s(0.0f);
    if (id < 0)
        return PF_OK;
    if (c->named_medium[id] < 0)
        return pf_pbrt_error_line(c, PF_EPARSE, loc, "MediumInterface: medium \"%.60s\" is not defined",
                                  c->names.s[id]);
    *sigma = c->media[c->named_medium[id]].sigma_a;
    return PF_OK;
}

int pf_pbrt_camera_medium(pf_pbrt_t *c)
{
    pf_vec3 sigma;
    int rc = pf_pbrt_medium_sigma(c, c->camera_medium, c->camera_loc, &sigma);
    if (rc || pf_is_black(sigma))
        return rc;
    return pf_pbrt_warn(c, c->camera_loc, "camera inside a medium (not tinted)",
                        "the camera sits in medium \"%.60s\": its rays are not tinted before their first surface",
                        c->names.s[c->camera_medium]);
}
