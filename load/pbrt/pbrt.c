/* pbrt.c: the pbrt-v4 scene reader (pf_pbrt_load): the directives, the
 * graphics state (current transform, material, area light, orientation) and
 * its stack, named coordinate systems, the camera, film and integrator, and
 * the report of everything the scene model cannot hold. It owns one
 * pf_pbrt_t per load; shapes, materials and lights are in pbrt_shape.c and
 * pbrt_mat.c, tokens in pbrt_lex.c, parameters in pbrt_param.c. Called on
 * the one thread that loads the scene.
 *
 * pbrt's conventions, kept: the current transform (CTM) maps object space to
 * world space and every transform directive post-multiplies it (CTM = CTM *
 * T); Transform and ConcatTransform give the matrix column by column; the
 * CTM at Camera is camera-from-world, and the camera's space is left-handed
 * (x right, y up, z forward). World space is the scene model's space.
 *
 * Reporting: anything approximated or ignored is a warning of a kind
 * ("texture", "unused parameter \"float foo\"", "Sampler (ignored)", ...);
 * the load prints one line per kind at its end (the first occurrence's
 * file:line and how many there were), and fills opts->report. With
 * opts->strict the first such warning is an error naming its file:line. */
#include <math.h>
#include <stdarg.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "base/reserve.h"
#include "load/pbrt/pbrt_impl.h"

/* ---- reading directive arguments ---- */

/* n numbers, optionally inside one pair of brackets (brackets required when
 * bracketed is 1). */
static int s_numbers(pf_pbrt_t *c, const char *what, int n, int bracketed, double *out)
{
    pf_pbrt_tok_t t;
    int rc = pf_pbrt_peek(c, &t);
    if (rc)
        return rc;
    int open = t.kind == PF_PBRT_LBRACK;
    if (bracketed && !open)
        return pf_pbrt_error(c, PF_EPARSE, t.loc, "%s expects '[' and %d numbers", what, n);
    if (open)
        pf_pbrt_next(c, &t);
    for (int i = 0; i < n; i++) {
        if ((rc = pf_pbrt_next(c, &t)))
            return rc;
        if (t.kind != PF_PBRT_NUMBER)
            return pf_pbrt_error(c, PF_EPARSE, t.loc, "%s expects %d numbers; found %s", what, n,
                                 t.kind == PF_PBRT_EOF ? "the end of the file" : "something else");
        if ((rc = pf_pbrt_tok_number(c, &t, &out[i])))
            return rc;
    }
    if (open) {
        if ((rc = pf_pbrt_next(c, &t)))
            return rc;
        if (t.kind != PF_PBRT_RBRACK)
            return pf_pbrt_error(c, PF_EPARSE, t.loc, "%s expects ']' after %d numbers", what, n);
    }
    return PF_OK;
}

/* One quoted string argument, newly allocated. */
static int s_string_arg(pf_pbrt_t *c, const char *what, char **out)
{
    pf_pbrt_tok_t t;
    int rc = pf_pbrt_next(c, &t);
    if (rc)
        return rc;
    if (t.kind != PF_PBRT_STRING)
        return pf_pbrt_error(c, PF_EPARSE, t.loc, "%s expects a quoted string", what);
    return pf_pbrt_tok_string(c, &t, out);
}

/* ---- transforms ---- */

/* CTM = CTM * m (s_directive keeps the CTM after ActiveTransform EndTime). */
static void s_apply(pf_pbrt_t *c, const pf_pbrt_m4 m) { pf_pbrt_m4_mul(c->gs.ctm, m, c->gs.ctm); }

static int s_translate(pf_pbrt_t *c, pf_pbrt_loc_t loc)
{
    double v[3];
    int rc = s_numbers(c, "Translate", 3, 0, v);
    if (rc)
        return rc;
    pf_pbrt_m4 m;
    pf_pbrt_m4_identity(m);
    for (int i = 0; i < 3; i++)
        m[i][3] = v[i];
    s_apply(c, m);
    return PF_OK;
}

static int s_scale(pf_pbrt_t *c, pf_pbrt_loc_t loc)
{
    double v[3];
    int rc = s_numbers(c, "Scale", 3, 0, v);
    if (rc)
        return rc;
    pf_pbrt_m4 m;
    pf_pbrt_m4_identity(m);
    for (int i = 0; i < 3; i++)
        m[i][i] = v[i];
    s_apply(c, m);
    return PF_OK;
}

static int s_rotate(pf_pbrt_t *c, pf_pbrt_loc_t loc)
{
    double v[4];
    int rc = s_numbers(c, "Rotate", 4, 0, v);
    if (rc)
        return rc;
    double len = sqrt(v[1] * v[1] + v[2] * v[2] + v[3] * v[3]);
    if (!(len > 0.0) || !isfinite(len))
        return pf_pbrt_error(c, PF_EPARSE, loc, "Rotate: the axis must not be zero");
    double x = v[1] / len, y = v[2] / len, z = v[3] / len, th = v[0] * (M_PI / 180.0);
    double s = sin(th), co = cos(th);
    pf_pbrt_m4 m = {
        { x * x + (1 - x * x) * co, x * y * (1 - co) - z * s, x * z * (1 - co) + y * s, 0 },
        { x * y * (1 - co) + z * s, y * y + (1 - y * y) * co, y * z * (1 - co) - x * s, 0 },
        { x * z * (1 - co) - y * s, y * z * (1 - co) + x * s, z * z + (1 - z * z) * co, 0 },
        { 0, 0, 0, 1 },
    };
    s_apply(c, m);
    return PF_OK;
}

static int s_lookat(pf_pbrt_t *c, pf_pbrt_loc_t loc)
{
    double v[9];
    int rc = s_numbers(c, "LookAt", 9, 0, v);
    if (rc)
        return rc;
    double dir[3] = { v[3] - v[0], v[4] - v[1], v[5] - v[2] }, *up = v + 6;
    double dl = sqrt(dir[0] * dir[0] + dir[1] * dir[1] + dir[2] * dir[2]);
    double ul = sqrt(up[0] * up[0] + up[1] * up[1] + up[2] * up[2]);
    if (!(dl > 0.0) || !(ul > 0.0) || !isfinite(dl) || !isfinite(ul))
        return pf_pbrt_error(c, PF_EPARSE, loc, "LookAt: the eye equals the look-at point, or up is zero");
    for (int i = 0; i < 3; i++)
        dir[i] /= dl;
    double u[3] = { up[0] / ul, up[1] / ul, up[2] / ul };
    double right[3] = { u[1] * dir[2] - u[2] * dir[1], u[2] * dir[0] - u[0] * dir[2], u[0] * dir[1] - u[1] * dir[0] };
    double rl = sqrt(right[0] * right[0] + right[1] * right[1] + right[2] * right[2]);
    if (!(rl > 1e-12))
        return pf_pbrt_error(c, PF_EPARSE, loc, "LookAt: the up vector is parallel to the viewing direction");
    for (int i = 0; i < 3; i++)
        right[i] /= rl;
    double nup[3] = { dir[1] * right[2] - dir[2] * right[1], dir[2] * right[0] - dir[0] * right[2],
                      dir[0] * right[1] - dir[1] * right[0] };
    pf_pbrt_m4 world_from_camera = {
        { right[0], nup[0], dir[0], v[0] },
        { right[1], nup[1], dir[1], v[1] },
        { right[2], nup[2], dir[2], v[2] },
        { 0, 0, 0, 1 },
    }, m;
    if (pf_pbrt_m4_inverse(world_from_camera, m))
        return pf_pbrt_error(c, PF_EPARSE, loc, "LookAt: the view cannot be inverted");
    s_apply(c, m);
    return PF_OK;
}

/* Transform (set) and ConcatTransform (post-multiply): 16 numbers, column by column. */
static int s_matrix(pf_pbrt_t *c, pf_pbrt_loc_t loc, int concat)
{
    double v[16];
    int rc = s_numbers(c, concat ? "ConcatTransform" : "Transform", 16, 1, v);
    if (rc)
        return rc;
    pf_pbrt_m4 m;
    for (int i = 0; i < 4; i++)
        for (int j = 0; j < 4; j++)
            m[i][j] = v[4 * j + i];
    if (concat)
        s_apply(c, m);
    else
        memcpy(c->gs.ctm, m, sizeof m);
    return PF_OK;
}

static int s_transform(pf_pbrt_t *c, pf_pbrt_loc_t loc) { return s_matrix(c, loc, 0); }
static int s_concat(pf_pbrt_t *c, pf_pbrt_loc_t loc) { return s_matrix(c, loc, 1); }
static int s_identity(pf_pbrt_t *c, pf_pbrt_loc_t loc)
{
    pf_pbrt_m4_identity(c->gs.ctm);
    return PF_OK;
}

static int s_name_coordsys(pf_pbrt_t *c, pf_pbrt_loc_t loc, const char *name, const pf_pbrt_m4 m);

static int s_coordsys(pf_pbrt_t *c, pf_pbrt_loc_t loc)
{
    char *name = NULL;
    int rc = s_string_arg(c, "CoordinateSystem", &name);
    if (rc == PF_OK)
        rc = s_name_coordsys(c, loc, name, c->gs.ctm);
    free(name);
    return rc;
}

static int s_coordsys_transform(pf_pbrt_t *c, pf_pbrt_loc_t loc)
{
    char *name = NULL;
    int rc = s_string_arg(c, "CoordSysTransform", &name);
    if (rc)
        return rc;
    int id = pf_pbrt_name_find(c, name);
    for (size_t i = 0; i < c->ncoordsys && id >= 0; i++) {
        if (c->coordsys[i].name == id) {
            memcpy(c->gs.ctm, c->coordsys[i].m, sizeof(pf_pbrt_m4));
            free(name);
            return PF_OK;
        }
    }
    rc = pf_pbrt_warn(c, loc, "unknown coordinate system", "CoordSysTransform \"%s\": no such coordinate system "
                      "(the transform is left as it was)", name);
    free(name);
    return rc;
}

static int s_reverse(pf_pbrt_t *c, pf_pbrt_loc_t loc)
{
    c->gs.reverse = !c->gs.reverse;
    return PF_OK;
}

/* ---- the graphics state stack ---- */

static int s_push(pf_pbrt_t *c, pf_pbrt_loc_t loc, char kind)
{
    if (c->ngstack >= PF_PBRT_MAX_NEST)
        return pf_pbrt_error(c, PF_ERANGE, loc, "attributes nested deeper than %d", PF_PBRT_MAX_NEST);
    if (pf_reserve((void **)&c->gstack, &c->cap_gstack, c->ngstack + 1, sizeof *c->gstack))
        return pf_pbrt_error(c, PF_ENOMEM, loc, "out of memory");
    c->gs.kind = kind;
    c->gs.begin = loc;
    c->gstack[c->ngstack++] = c->gs;
    return PF_OK;
}

static int s_pop(pf_pbrt_t *c, pf_pbrt_loc_t loc, char kind, const char *what)
{
    static const char *names[] = { "AttributeBegin", "TransformBegin", "ObjectBegin" };
    if (c->ngstack == 0 || c->gstack[c->ngstack - 1].kind != kind) {
        if (c->ngstack == 0)
            return pf_pbrt_error(c, PF_EPARSE, loc, "%s without a matching %s", what,
                                 names[kind == 'A' ? 0 : kind == 'T' ? 1 : 2]);
        const pf_pbrt_gstate_t *top = &c->gstack[c->ngstack - 1];
        const char *open = names[top->kind == 'A' ? 0 : top->kind == 'T' ? 1 : 2];
        return pf_pbrt_error(c, PF_EPARSE, loc, "%s closes the %s of %s:%d", what, open,
                             pf_pbrt_file_name(c, top->begin), top->begin.line);
    }
    pf_pbrt_gstate_t top = c->gstack[--c->ngstack];
    if (kind == 'T')
        memcpy(c->gs.ctm, top.ctm, sizeof top.ctm); /* TransformEnd restores the transform alone */
    else
        c->gs = top;
    return PF_OK;
}

static int s_attr_begin(pf_pbrt_t *c, pf_pbrt_loc_t loc) { return s_push(c, loc, 'A'); }
static int s_attr_end(pf_pbrt_t *c, pf_pbrt_loc_t loc) { return s_pop(c, loc, 'A', "AttributeEnd"); }
static int s_xform_begin(pf_pbrt_t *c, pf_pbrt_loc_t loc) { return s_push(c, loc, 'T'); }
static int s_xform_end(pf_pbrt_t *c, pf_pbrt_loc_t loc) { return s_pop(c, loc, 'T', "TransformEnd"); }

static int s_object_begin(pf_pbrt_t *c, pf_pbrt_loc_t loc)
{
    char *name = NULL;
    int rc = s_string_arg(c, "ObjectBegin", &name);
    if (rc)
        return rc;
    if (c->cur_object >= 0) {
        const pf_pbrt_object_t *o = &c->objects[c->cur_object];
        rc = pf_pbrt_error(c, PF_EPARSE, loc, "ObjectBegin \"%s\" inside the definition of \"%s\" (%s:%d)", name,
                           c->names.s[o->name], pf_pbrt_file_name(c, o->loc), o->loc.line);
        free(name);
        return rc;
    }
    int id = pf_pbrt_intern(c, name);
    free(name);
    if (id < 0 || pf_reserve((void **)&c->objects, &c->cap_objects, c->nobjects + 1, sizeof *c->objects))
        return pf_pbrt_error(c, PF_ENOMEM, loc, "out of memory");
    if (c->named_obj[id] >= 0) {
        const pf_pbrt_object_t *o = &c->objects[c->named_obj[id]];
        return pf_pbrt_error(c, PF_EPARSE, loc, "object \"%s\" is defined twice (first at %s:%d)", c->names.s[id],
                             pf_pbrt_file_name(c, o->loc), o->loc.line);
    }
    if ((rc = s_push(c, loc, 'O')))
        return rc;
    pf_pbrt_object_t *o = &c->objects[c->nobjects];
    memset(o, 0, sizeof *o);
    o->name = id;
    o->loc = loc;
    c->named_obj[id] = (int32_t)c->nobjects;
    c->cur_object = (int)c->nobjects++;
    return PF_OK;
}

static int s_object_end(pf_pbrt_t *c, pf_pbrt_loc_t loc)
{
    if (c->cur_object < 0)
        return pf_pbrt_error(c, PF_EPARSE, loc, "ObjectEnd without ObjectBegin");
    c->cur_object = -1;
    return s_pop(c, loc, 'O', "ObjectEnd");
}

static int s_object_instance(pf_pbrt_t *c, pf_pbrt_loc_t loc)
{
    char *name = NULL;
    int rc = s_string_arg(c, "ObjectInstance", &name);
    if (rc)
        return rc;
    if (c->cur_object >= 0)
        rc = pf_pbrt_error(c, PF_EPARSE, loc, "ObjectInstance inside an object definition");
    else
        rc = pf_pbrt_object_instance(c, name, loc);
    free(name);
    return rc;
}

/* ---- rendering options ---- */

/* Reads "type" and the parameter list of a directive. */
static int s_type_params(pf_pbrt_t *c, const char *what, char **type, pf_pbrt_params_t *ps)
{
    memset(ps, 0, sizeof *ps);
    int rc = s_string_arg(c, what, type);
    if (rc == PF_OK)
        rc = pf_pbrt_read_params(c, ps);
    return rc;
}

/* Stores the named coordinate system name with matrix m (a later one of
 * the same name replaces it). */
static int s_name_coordsys(pf_pbrt_t *c, pf_pbrt_loc_t loc, const char *name, const pf_pbrt_m4 m)
{
    int id = pf_pbrt_intern(c, name);
    if (id < 0)
        return pf_pbrt_error(c, PF_ENOMEM, loc, "out of memory");
    for (size_t i = 0; i < c->ncoordsys; i++) {
        if (c->coordsys[i].name == id) {
            memcpy(c->coordsys[i].m, m, sizeof(pf_pbrt_m4));
            return PF_OK;
        }
    }
    if (pf_reserve((void **)&c->coordsys, &c->cap_coordsys, c->ncoordsys + 1, sizeof *c->coordsys))
        return pf_pbrt_error(c, PF_ENOMEM, loc, "out of memory");
    c->coordsys[c->ncoordsys].name = id;
    memcpy(c->coordsys[c->ncoordsys++].m, m, sizeof(pf_pbrt_m4));
    return PF_OK;
}

/* "frameaspectratio" and "screenwindow" (pbrt-v4's ProjectiveCamera; the
 * window's bounds in units of tan(fov / 2), scene/camera.h). The limits keep
 * the rays' directions finite; pbrt's mirrored windows (xmin > xmax) are
 * refused. */
#define S_WINDOW_MAX 1e6
static int s_screen_window(pf_pbrt_t *c, pf_pbrt_params_t *ps)
{
    pf_camera_desc_t *cam = &c->scene->camera;
    pf_pbrt_param_t *fp = pf_pbrt_param(ps, "frameaspectratio");
    double frame;
    int rc = pf_pbrt_get_float(c, ps, "frameaspectratio", 0.0, &frame);
    if (rc == PF_OK && fp && !(frame >= 1.0 / S_WINDOW_MAX && frame <= S_WINDOW_MAX))
        rc = pf_pbrt_error(c, PF_ERANGE, fp->loc, "Camera: frameaspectratio %g must be in [1e-6, 1e6]", frame);
    if (rc)
        return rc;
    cam->frame_aspect = (float)frame;
    pf_pbrt_param_t *p = pf_pbrt_param(ps, "screenwindow");
    cam->has_window = 0;
    if (!p)
        return PF_OK;
    if ((p->type != PF_PBRT_P_FLOAT && p->type != PF_PBRT_P_INTEGER) || p->nnum != 4)
        return pf_pbrt_error(c, PF_EPARSE, p->loc, "Camera: \"screenwindow\" takes four floats (xmin xmax ymin ymax)");
    for (int i = 0; i < 4; i++)
        if (!(fabs(p->num[i]) <= S_WINDOW_MAX))
            return pf_pbrt_error(c, PF_ERANGE, p->loc, "Camera: screenwindow bound %g is beyond +-1e6", p->num[i]);
    if (!(p->num[1] - p->num[0] >= 1.0 / S_WINDOW_MAX && p->num[3] - p->num[2] >= 1.0 / S_WINDOW_MAX))
        return pf_pbrt_error(c, PF_ERANGE, p->loc,
                             "Camera: screenwindow [%g %g %g %g] must have xmin < xmax and ymin < ymax (by 1e-6)",
                             p->num[0], p->num[1], p->num[2], p->num[3]);
    cam->has_window = 1;
    for (int i = 0; i < 4; i++)
        cam->window[i] = (float)p->num[i];
    return PF_OK;
}

static int s_camera_params(pf_pbrt_t *c, const char *type, pf_pbrt_params_t *ps, pf_pbrt_loc_t loc)
{
    double fov, lens, focal;
    pf_pbrt_param_t *fp = pf_pbrt_param(ps, "fov");
    int rc = pf_pbrt_get_float(c, ps, "fov", 90.0, &fov);
    if (rc == PF_OK && !(fov > 0.0 && fov < 180.0))
        rc = pf_pbrt_error(c, PF_ERANGE, fp ? fp->loc : loc, "Camera: fov must be in (0, 180) degrees");
    if (rc == PF_OK)
        rc = pf_pbrt_get_float(c, ps, "lensradius", 0.0, &lens);
    if (rc == PF_OK)
        rc = pf_pbrt_get_float(c, ps, "focaldistance", 1e6, &focal);
    if (rc == PF_OK && (lens < 0.0 || !(focal > 0.0)))
        rc = pf_pbrt_error(c, PF_ERANGE, loc, "Camera: lensradius must be >= 0 and focaldistance > 0");
    if (rc)
        return rc;
    c->scene->camera.vfov_deg = (float)fov;
    c->scene->camera.fov_shorter = 1;
    c->scene->camera.lens_radius = (float)lens;
    c->scene->camera.focal_distance = (float)focal;
    if (rc == PF_OK)
        rc = s_screen_window(c, ps);
    if (rc == PF_OK && strcmp(type, "perspective") != 0)
        rc = pf_pbrt_warn(c, loc, "camera type (rendered as perspective)",
                          "Camera \"%s\" is rendered as a perspective camera", type);
    return rc ? rc : pf_pbrt_check_unused(c, ps, "Camera");
}

static int s_camera(pf_pbrt_t *c, pf_pbrt_loc_t loc)
{
    char *type = NULL;
    pf_pbrt_params_t ps;
    int rc = s_type_params(c, "Camera", &type, &ps);
    pf_pbrt_m4 inv;
    if (rc == PF_OK && pf_pbrt_m4_inverse(c->gs.ctm, inv))
        rc = pf_pbrt_error(c, PF_EPARSE, loc, "Camera: the current transform cannot be inverted");
    if (rc == PF_OK) {
        memcpy(c->camera_from_world, c->gs.ctm, sizeof inv);
        c->have_camera = 1;
        c->camera_medium = c->gs.medium_out; /* pbrt's camera medium */
        c->camera_loc = loc;
        rc = s_name_coordsys(c, loc, "camera", inv);
    }
    if (rc == PF_OK)
        rc = s_camera_params(c, type, &ps, loc);
    free(type);
    pf_pbrt_params_free(&ps);
    return rc;
}

static int s_film(pf_pbrt_t *c, pf_pbrt_loc_t loc)
{
    char *type = NULL;
    pf_pbrt_params_t ps;
    int rc = s_type_params(c, "Film", &type, &ps);
    int w = 1280, h = 720;
    const char *fname;
    if (rc == PF_OK)
        rc = pf_pbrt_get_int(c, &ps, "xresolution", 1280, &w);
    if (rc == PF_OK)
        rc = pf_pbrt_get_int(c, &ps, "yresolution", 720, &h);
    if (rc == PF_OK && (w < 1 || h < 1 || w > 65536 || h > 65536))
        rc = pf_pbrt_error(c, PF_ERANGE, loc, "Film: resolution %dx%d is out of range (1..65536)", w, h);
    if (rc == PF_OK)
        rc = pf_pbrt_get_string(c, &ps, "filename", "", &fname); /* the output is -o's */
    if (rc == PF_OK) {
        c->scene->settings.width = w;
        c->scene->settings.height = h;
        rc = pf_pbrt_check_unused(c, &ps, "Film");
    }
    free(type);
    pf_pbrt_params_free(&ps);
    return rc;
}

/* Integrator: only maxdepth is read. pbrt's maxdepth bounds the scattering
 * events of a whole light path (path_max_depth; 0 there means no limit, so
 * pbrt's 0, emitted light only, becomes -1); it also bounds the camera
 * side's specular recursion (max_depth) and a photon's bounces
 * (photon_max_depth), which no longer path could use. */
static int s_integrator(pf_pbrt_t *c, pf_pbrt_loc_t loc)
{
    char *type = NULL;
    pf_pbrt_params_t ps;
    int rc = s_type_params(c, "Integrator", &type, &ps);
    int depth = 5;
    if (rc == PF_OK)
        rc = pf_pbrt_get_int(c, &ps, "maxdepth", 5, &depth);
    if (rc == PF_OK && (depth < 0 || depth > 1000))
        rc = pf_pbrt_error(c, PF_ERANGE, loc, "Integrator: maxdepth %d is out of range (0..1000)", depth);
    if (rc == PF_OK) {
        c->scene->settings.max_depth = depth;
        c->scene->settings.photon_max_depth = depth;
        c->scene->settings.path_max_depth = depth > 0 ? depth : -1;
        rc = pf_pbrt_check_unused(c, &ps, "Integrator");
    }
    free(type);
    pf_pbrt_params_free(&ps);
    return rc;
}

/* PixelFilter: box and triangle as they are (a box of width 2 xradius, a
 * tent of radius xradius; x and y radii averaged); gaussian (pbrt-v4's
 * default, also without a PixelFilter: radius 1.5, sigma 0.5) as the tent
 * of the same variance; mitchell, lanczos and sinc, whose lobes go
 * negative, as a box, with a warning. */
#define S_GAUSSIAN_TENT 1.1733f /* sqrt(6 var) of pbrt-v4's default gaussian, var 0.2295 */

static int s_pixel_filter(pf_pbrt_t *c, pf_pbrt_loc_t loc)
{
    char *type = NULL;
    pf_pbrt_params_t ps;
    int rc = s_type_params(c, "PixelFilter", &type, &ps);
    int box = type && !strcmp(type, "box"), tri = type && !strcmp(type, "triangle");
    int gauss = type && !strcmp(type, "gaussian");
    double def = box ? 0.5 : tri ? 2.0 : gauss ? 1.5 : 2.0, xr = def, yr = def, sigma = 0.5;
    if (rc == PF_OK)
        rc = pf_pbrt_get_float(c, &ps, "xradius", def, &xr);
    if (rc == PF_OK)
        rc = pf_pbrt_get_float(c, &ps, "yradius", def, &yr);
    if (rc == PF_OK && gauss)
        rc = pf_pbrt_get_float(c, &ps, "sigma", 0.5, &sigma);
    double r = 0.5 * (xr + yr);
    if (rc == PF_OK && !(r > 0.0 && r <= 0.5 * PF_MAX_FILTER_WIDTH))
        rc = pf_pbrt_error(c, PF_ERANGE, loc, "PixelFilter: radius %g is out of range (0..%g]", r,
                           0.5 * PF_MAX_FILTER_WIDTH);
    pf_settings_t *s = &c->scene->settings;
    if (rc == PF_OK) {
        s->filter_box = box ? (float)(2.0 * r) : 0.0f;
        s->filter_tent = box ? 0.0f : tri ? (float)r : 0.0f;
        if (gauss) {
            s->filter_tent = (float)fmin(S_GAUSSIAN_TENT * (sigma / 0.5), 0.5 * PF_MAX_FILTER_WIDTH);
            rc = pf_pbrt_warn(c, loc, "PixelFilter gaussian (approximated)",
                              "PixelFilter \"gaussian\" is rendered as a tent of the same variance (radius %.3g)",
                              (double)s->filter_tent);
        } else if (!box && !tri) {
            s->filter_box = 1.0f;
            rc = pf_pbrt_warn(c, loc, "PixelFilter (rendered as a box)",
                              "PixelFilter \"%s\" is rendered as a one-pixel box", type ? type : "");
        }
    }
    if (rc == PF_OK)
        c->have_filter = 1;
    free(type);
    if (rc == PF_OK && (box || tri || gauss))
        rc = pf_pbrt_check_unused(c, &ps, "PixelFilter");
    pf_pbrt_params_free(&ps);
    return rc;
}

/* Directives read and reported as ignored, with why. args: leading strings
 * (-1: one or more), then a parameter list when params. */
static const struct {
    const char *name;
    int args, params, options; /* options: only before WorldBegin */
    const char *why;
} s_ignored_list[] = {
    { "Sampler", 1, 1, 1, "photonfarm's own sampler and --spp decide the samples" },
    { "ColorSpace", 1, 0, 0, "colours are read as linear sRGB" },
    { "Option", 0, 1, 0, "pbrt's options do not apply" },
    { "Attribute", 1, 1, 0, "default parameters of shapes, lights and materials are not applied" },
    { "Accelerator", 1, 1, 1, "Embree builds its own" },
    { "TransformTimes", 0, 0, 1, "motion blur is not rendered" },
    { "ActiveTransform", 0, 0, 0, "motion blur is not rendered (the start time's transform is used)" },
    { "WorldEnd", 0, 0, 0, "pbrt-v3's WorldEnd: nothing to do" },
};

static int s_ignored(pf_pbrt_t *c, pf_pbrt_loc_t loc, size_t which)
{
    int rc = PF_OK;
    pf_pbrt_tok_t t;
    for (int i = 0; i < s_ignored_list[which].args || s_ignored_list[which].args < 0; i++) {
        if ((rc = pf_pbrt_peek(c, &t)))
            return rc;
        if (t.kind != PF_PBRT_STRING && (i > 0 || s_ignored_list[which].args < 0))
            break;
        char *s = NULL;
        if ((rc = s_string_arg(c, s_ignored_list[which].name, &s)))
            return rc;
        free(s);
    }
    if (s_ignored_list[which].params) {
        pf_pbrt_params_t ps;
        rc = pf_pbrt_read_params(c, &ps);
        pf_pbrt_params_free(&ps);
    } else if (!strcmp(s_ignored_list[which].name, "TransformTimes")) {
        double v[2];
        rc = s_numbers(c, "TransformTimes", 2, 0, v);
    } else if (!strcmp(s_ignored_list[which].name, "ActiveTransform")) {
        rc = pf_pbrt_next(c, &t);
        if (rc == PF_OK && !pf_pbrt_tok_is(&t, "StartTime") && !pf_pbrt_tok_is(&t, "EndTime") && !pf_pbrt_tok_is(&t, "All"))
            rc = pf_pbrt_error(c, PF_EPARSE, t.loc, "ActiveTransform expects StartTime, EndTime or All");
        if (rc == PF_OK)
            c->xform_end_only = pf_pbrt_tok_is(&t, "EndTime");
    }
    if (rc)
        return rc;
    char kind[64];
    snprintf(kind, sizeof kind, "%s (ignored)", s_ignored_list[which].name);
    return pf_pbrt_warn(c, loc, kind, "%s is not read: %s", s_ignored_list[which].name, s_ignored_list[which].why);
}

/* ---- the world ---- */

static int s_world_begin(pf_pbrt_t *c, pf_pbrt_loc_t loc)
{
    if (c->in_world)
        return pf_pbrt_error(c, PF_EPARSE, loc, "a second WorldBegin");
    c->in_world = 1;
    pf_pbrt_m4_identity(c->gs.ctm);
    return s_name_coordsys(c, loc, "world", c->gs.ctm);
}

static int s_make_named_material(pf_pbrt_t *c, pf_pbrt_loc_t loc)
{
    char *name = NULL;
    pf_pbrt_params_t ps;
    int rc = s_type_params(c, "MakeNamedMaterial", &name, &ps);
    if (rc == PF_OK)
        rc = pf_pbrt_material(c, name, NULL, &ps, loc);
    free(name);
    pf_pbrt_params_free(&ps);
    return rc;
}

static int s_material(pf_pbrt_t *c, pf_pbrt_loc_t loc)
{
    char *type = NULL;
    pf_pbrt_params_t ps;
    int rc = s_type_params(c, "Material", &type, &ps);
    if (rc == PF_OK)
        rc = pf_pbrt_material(c, NULL, type, &ps, loc);
    free(type);
    pf_pbrt_params_free(&ps);
    return rc;
}

static int s_make_named_medium(pf_pbrt_t *c, pf_pbrt_loc_t loc)
{
    char *name = NULL;
    pf_pbrt_params_t ps;
    int rc = s_type_params(c, "MakeNamedMedium", &name, &ps);
    if (rc == PF_OK)
        rc = pf_pbrt_medium(c, name, &ps, loc);
    free(name);
    pf_pbrt_params_free(&ps);
    return rc;
}

/* MediumInterface "inside" ["outside"]: one name stands for both sides. */
static int s_medium_interface(pf_pbrt_t *c, pf_pbrt_loc_t loc)
{
    char *in = NULL, *out = NULL;
    pf_pbrt_tok_t t;
    int rc = s_string_arg(c, "MediumInterface", &in);
    if (rc == PF_OK)
        rc = pf_pbrt_peek(c, &t);
    if (rc == PF_OK && t.kind == PF_PBRT_STRING)
        rc = s_string_arg(c, "MediumInterface", &out);
    if (rc == PF_OK)
        rc = pf_pbrt_medium_interface(c, in, out ? out : in, loc);
    free(in);
    free(out);
    return rc;
}

static int s_named_material(pf_pbrt_t *c, pf_pbrt_loc_t loc)
{
    char *name = NULL;
    int rc = s_string_arg(c, "NamedMaterial", &name);
    if (rc)
        return rc;
    int id = pf_pbrt_intern(c, name);
    free(name);
    if (id < 0)
        return pf_pbrt_error(c, PF_ENOMEM, loc, "out of memory");
    c->gs.mat_kind = PF_PBRT_MAT_NAMED;
    c->gs.mat = id;
    c->gs.mat_loc = loc;
    return PF_OK;
}

static int s_texture(pf_pbrt_t *c, pf_pbrt_loc_t loc)
{
    char *s[3] = { NULL, NULL, NULL };
    pf_pbrt_params_t ps = { 0 };
    int rc = PF_OK;
    for (int i = 0; i < 3 && rc == PF_OK; i++)
        rc = s_string_arg(c, "Texture (name, type, class)", &s[i]);
    if (rc == PF_OK)
        rc = pf_pbrt_read_params(c, &ps);
    if (rc == PF_OK)
        rc = pf_pbrt_texture(c, s[0], s[1], s[2], &ps, loc);
    for (int i = 0; i < 3; i++)
        free(s[i]);
    pf_pbrt_params_free(&ps);
    return rc;
}

/* LightSource, AreaLightSource and Shape: "type" and parameters. */
static int s_typed(pf_pbrt_t *c, pf_pbrt_loc_t loc, const char *what,
                   int (*fn)(pf_pbrt_t *, const char *, pf_pbrt_params_t *, pf_pbrt_loc_t))
{
    char *type = NULL;
    pf_pbrt_params_t ps;
    int rc = s_type_params(c, what, &type, &ps);
    if (rc == PF_OK)
        rc = fn(c, type, &ps, loc);
    free(type);
    pf_pbrt_params_free(&ps);
    return rc;
}

static int s_light(pf_pbrt_t *c, pf_pbrt_loc_t loc) { return s_typed(c, loc, "LightSource", pf_pbrt_light); }
static int s_area(pf_pbrt_t *c, pf_pbrt_loc_t loc) { return s_typed(c, loc, "AreaLightSource", pf_pbrt_area_light); }
static int s_shape(pf_pbrt_t *c, pf_pbrt_loc_t loc) { return s_typed(c, loc, "Shape", pf_pbrt_shape); }

static int s_include(pf_pbrt_t *c, pf_pbrt_loc_t loc)
{
    char *name = NULL;
    char path[4096];
    int rc = s_string_arg(c, "Include", &name);
    if (rc)
        return rc;
    rc = pf_pbrt_resolve(c, loc, name, 1, path, sizeof path);
    free(name);
    if (rc == PF_OK && c->has_peek)
        rc = pf_pbrt_error(c, PF_EPARSE, loc, "internal: Include after a peeked token");
    return rc ? rc : pf_pbrt_push_file(c, path, loc);
}

/* Where a directive may stand: before WorldBegin, after it, or anywhere. */
enum { S_ANY, S_OPTIONS, S_WORLD, S_XFORM };

static const struct {
    const char *name;
    int (*fn)(pf_pbrt_t *, pf_pbrt_loc_t);
    int where;
} s_directives[] = {
    { "AttributeBegin", s_attr_begin, S_ANY },   { "AttributeEnd", s_attr_end, S_ANY },
    { "TransformBegin", s_xform_begin, S_ANY },  { "TransformEnd", s_xform_end, S_ANY },
    { "ObjectBegin", s_object_begin, S_WORLD },  { "ObjectEnd", s_object_end, S_WORLD },
    { "ObjectInstance", s_object_instance, S_WORLD },
    { "Identity", s_identity, S_XFORM },         { "Translate", s_translate, S_XFORM },
    { "Scale", s_scale, S_XFORM },               { "Rotate", s_rotate, S_XFORM },
    { "LookAt", s_lookat, S_XFORM },             { "Transform", s_transform, S_XFORM },
    { "ConcatTransform", s_concat, S_XFORM },    { "CoordinateSystem", s_coordsys, S_ANY },
    { "CoordSysTransform", s_coordsys_transform, S_XFORM },
    { "ReverseOrientation", s_reverse, S_ANY },  { "WorldBegin", s_world_begin, S_OPTIONS },
    { "Camera", s_camera, S_OPTIONS },           { "Film", s_film, S_OPTIONS },
    { "Integrator", s_integrator, S_OPTIONS },   { "PixelFilter", s_pixel_filter, S_OPTIONS },   { "MakeNamedMaterial", s_make_named_material, S_WORLD },
    { "Material", s_material, S_WORLD },         { "NamedMaterial", s_named_material, S_WORLD },
    { "Texture", s_texture, S_WORLD },           { "LightSource", s_light, S_WORLD },
    { "AreaLightSource", s_area, S_WORLD },      { "Shape", s_shape, S_WORLD },
    { "Include", s_include, S_ANY },             { "Import", s_include, S_ANY },
    { "MakeNamedMedium", s_make_named_medium, S_ANY },
    { "MediumInterface", s_medium_interface, S_ANY },
};

/* Runs the directive of word token t. */
static int s_directive(pf_pbrt_t *c, const pf_pbrt_tok_t *t)
{
    for (size_t i = 0; i < sizeof s_directives / sizeof *s_directives; i++) {
        if (!pf_pbrt_tok_is(t, s_directives[i].name))
            continue;
        int where = s_directives[i].where;
        if (where == S_OPTIONS && c->in_world)
            return pf_pbrt_error(c, PF_EPARSE, t->loc, "%s is only allowed before WorldBegin", s_directives[i].name);
        if (where == S_WORLD && !c->in_world)
            return pf_pbrt_error(c, PF_EPARSE, t->loc, "%s is only allowed after WorldBegin", s_directives[i].name);
        if (where != S_XFORM || !c->xform_end_only)
            return s_directives[i].fn(c, t->loc);
        /* ActiveTransform EndTime: the directive moves the end transform alone. */
        pf_pbrt_m4 keep;
        memcpy(keep, c->gs.ctm, sizeof keep);
        int rc = s_directives[i].fn(c, t->loc);
        memcpy(c->gs.ctm, keep, sizeof keep);
        return rc;
    }
    for (size_t i = 0; i < sizeof s_ignored_list / sizeof *s_ignored_list; i++) {
        if (!pf_pbrt_tok_is(t, s_ignored_list[i].name))
            continue;
        if (s_ignored_list[i].options && c->in_world)
            return pf_pbrt_error(c, PF_EPARSE, t->loc, "%s is only allowed before WorldBegin", s_ignored_list[i].name);
        return s_ignored(c, t->loc, i);
    }
    if (t->kind == PF_PBRT_WORD)
        return pf_pbrt_error(c, PF_EPARSE, t->loc, "unknown directive '%.*s'", (int)(t->len > 60 ? 60 : t->len), t->text);
    static const char *what[] = { "the end of the file", "", "a number", "a string", "'['", "']'" };
    return pf_pbrt_error(c, PF_EPARSE, t->loc, "expected a directive, found %s", what[t->kind]);
}

/* ---- the load ---- */

/* Fills the scene's camera from the CTM at Camera (or pbrt's default). */
static void s_finish_camera(pf_pbrt_t *c)
{
    pf_pbrt_m4 w;
    if (!c->have_camera || pf_pbrt_m4_inverse(c->camera_from_world, w))
        pf_pbrt_m4_identity(w);
    pf_camera_desc_t *cam = &c->scene->camera;
    if (!c->have_camera) {
        cam->vfov_deg = 90.0f; /* pbrt's default camera: at the origin, looking down +z */
        cam->fov_shorter = 1;
        cam->focal_distance = 1e6f;
    }
    /* pos = c2w (0,0,0), look_at = c2w (0,0,1), up and right: c2w's y and x axes. */
    double o[3], f[3], up[3], right[3];
    for (int i = 0; i < 3; i++) {
        o[i] = w[i][3] / w[3][3];
        f[i] = (w[i][2] + w[i][3]) / (w[3][2] + w[3][3]);
        up[i] = w[i][1];
        right[i] = w[i][0];
    }
    cam->pos = pf_v3((float)o[0], (float)o[1], (float)o[2]);
    cam->look_at = pf_v3((float)f[0], (float)f[1], (float)f[2]);
    cam->up = pf_v3((float)up[0], (float)up[1], (float)up[2]);
    /* The image's right is c2w's +x: left-handed when that is up x forward. */
    double fw[3] = { f[0] - o[0], f[1] - o[1], f[2] - o[2] };
    double uxf[3] = { up[1] * fw[2] - up[2] * fw[1], up[2] * fw[0] - up[0] * fw[2], up[0] * fw[1] - up[1] * fw[0] };
    cam->left_handed = uxf[0] * right[0] + uxf[1] * right[1] + uxf[2] * right[2] >= 0.0;
    c->scene->has_camera = 1;
}

static int s_parse(pf_pbrt_t *c)
{
    for (;;) {
        pf_pbrt_tok_t t;
        int rc = pf_pbrt_next(c, &t);
        if (rc)
            return rc;
        if (t.kind == PF_PBRT_EOF)
            break;
        if ((rc = s_directive(c, &t)))
            return rc;
    }
    if (c->cur_object >= 0) {
        const pf_pbrt_object_t *o = &c->objects[c->cur_object];
        return pf_pbrt_error(c, PF_EPARSE, o->loc, "ObjectBegin \"%s\" has no ObjectEnd", c->names.s[o->name]);
    }
    if (c->ngstack > 0) {
        const pf_pbrt_gstate_t *g = &c->gstack[c->ngstack - 1];
        return pf_pbrt_warn(c, g->begin, "unclosed AttributeBegin", "%zu AttributeBegin/TransformBegin without an end",
                            c->ngstack);
    }
    return PF_OK;
}

static void s_free(pf_pbrt_t *c)
{
    pf_pbrt_lex_free(c);
    free(c->main_dir);
    free(c->gstack);
    free(c->coordsys);
    for (size_t i = 0; i < c->names.n; i++)
        free(c->names.s[i]);
    free(c->names.s);
    free(c->names.slot);
    free(c->named_mat);
    free(c->named_ftex);
    free(c->named_stex);
    free(c->named_obj);
    free(c->named_warn);
    free(c->named_pair);
    free(c->named_medium);
    free(c->media);
    for (size_t i = 0; i < c->nmats; i++) {
        free(c->mats[i].type);
        pf_pbrt_params_free(&c->mats[i].params);
    }
    free(c->mats);
    for (size_t i = 0; i < c->ntexs; i++) {
        free(c->texs[i].cls);
        pf_pbrt_params_free(&c->texs[i].params);
    }
    free(c->texs);
    free(c->areas);
    free(c->pairs);
    for (size_t i = 0; i < c->nobjects; i++)
        pf_pbrt_meshes_free(&c->objects[i].shapes);
    free(c->objects);
    pf_pbrt_meshes_free(&c->shapes);
    for (size_t i = 0; i < c->nwarnings; i++) {
        free(c->warnings[i].kind);
        free(c->warnings[i].first);
    }
    free(c->warnings);
}

int pf_pbrt_load(pf_scene_t *scene, const char *path, const pf_load_opts_t *opts, pf_error_t *err)
{
    PF_CHECK(scene && path);
    pf_pbrt_t c;
    memset(&c, 0, sizeof c);
    c.scene = scene;
    c.err = err;
    c.strict = opts && opts->strict;
    c.report = opts ? opts->report : NULL;
    if (c.report)
        memset(c.report, 0, sizeof *c.report);
    c.cur_object = -1;
    c.gs.area = -1;
    c.gs.medium_in = c.gs.medium_out = c.camera_medium = -1;
    pf_pbrt_m4_identity(c.gs.ctm);
    /* pbrt's defaults where the file says nothing. */
    scene->settings.width = 1280;
    scene->settings.height = 720;
    scene->settings.max_depth = scene->settings.photon_max_depth = scene->settings.path_max_depth = 5;
    const char *slash = strrchr(path, '/');
    size_t dlen = slash ? (size_t)(slash - path) + 1 : 0;
    int rc = PF_OK;
    c.main_dir = malloc(dlen + 1);
    if (!c.main_dir)
        rc = pf_error_set(err, PF_ENOMEM, path, 0, "out of memory");
    else {
        memcpy(c.main_dir, path, dlen);
        c.main_dir[dlen] = '\0';
        rc = pf_pbrt_push_file(&c, path, (pf_pbrt_loc_t){ -1, 0, 0 });
    }
    if (rc == PF_OK)
        rc = s_parse(&c);
    if (rc == PF_OK)
        rc = pf_pbrt_camera_medium(&c);
    if (rc == PF_OK)
        rc = pf_pbrt_emit_materials(&c);
    if (rc == PF_OK)
        rc = pf_pbrt_emit_shapes(&c);
    if (rc == PF_OK)
        s_finish_camera(&c);
    if (rc == PF_OK && !c.have_filter) { /* pbrt-v4's default filter, the gaussian */
        scene->settings.filter_box = 0.0f;
        scene->settings.filter_tent = S_GAUSSIAN_TENT;
    }
    pf_pbrt_report(&c);
    s_free(&c);
    return rc;
}
