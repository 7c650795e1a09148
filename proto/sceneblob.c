/* sceneblob.c: the scene as one self-contained blob, so that a worker can
 * rebuild exactly the coordinator's scene without any of its files.
 *
 * Layout (little-endian, field by field; f32 is IEEE 754 binary32, str is a
 * u16 length and that many bytes without a NUL, vec3 is three f32):
 *   u32 magic PF_SCENEBLOB_MAGIC, u16 version PF_SCENEBLOB_VERSION, u16 0
 *   str path                      (where the scene came from; for messages only)
 *   settings                      (the field group of messages.c, 100 bytes)
 *   u8 has_camera, vec3 pos, vec3 look_at, vec3 up, f32 vfov_deg,
 *     u8 fov_shorter, u8 left_handed, f32 lens_radius, f32 focal_distance,
 *     u8 has_window, 4 f32 window, f32 frame_aspect   (version 11: the screen window)
 *   u32 nmats,    nmats x   { str name, u8 type, vec3 kd, vec3 ks, f32 ns, vec3 kt, f32 ior, vec3 le,
 *                             u8 twosided, vec3 eta, vec3 k, f32 alpha, f32 thickness, u32 kd_tex, u32 mix0, u32 mix1,
 *                             f32 amount, u32 amount_tex, u32 alpha_tex, u32 refl_tex,
 *                             u32 rough_tex, u32 rough_remap, u32 normal_tex, u32 bump_tex, u32 kt_tex,
 *                             vec3 sigma_in, vec3 sigma_out }
 *                             (version 4: eta, k, alpha; version 5: type 4, the thin dielectric; version
 *                             7: type 5, the coated diffuse, thickness and kd_tex; version 9: types 6 and
 *                             7, diffuse transmission and mix, and after kd_tex: u32 mix0, u32 mix1, f32
 *                             amount, u32 amount_tex, u32 alpha_tex, then refl_tex to bump_tex; version 12:
 *                             twosided; version 13: kt_tex and the absorbing media, sigma_in and sigma_out)
 *   u32 nmeshes,  nmeshes x { str name, u64 nverts, u64 ntris, u8 has_normals, u8 has_uv, u32 alpha_tex,
 *                             nverts x vec3 pos, (has_normals) nverts x vec3 nrm,
 *                             (has_uv) nverts x 2 f32 uv, ntris x 3 u32 idx, ntris x u32 mat }
 *                             (version 7: has_uv, alpha_tex, uv)
 *   u32 nspheres, nspheres x { vec3 center, f32 radius, u32 mat }
 *   u32 nlights,  nlights x  { u8 type, vec3 pos, vec3 intensity, vec3 dir, f32 cos_inner, f32 cos_outer,
 *                             u32 map }  (version 6: types 2 and 3, the distant and infinite lights;
 *                             version 8: map, an infinite light's map, 1 + index; 0 none)
 *   u32 ntexs,    ntexs x    { str name, u8 type, f32 su, f32 sv, f32 du, f32 dv,
 *                              3 x { vec3 c, u32 ref }, u8 wrap, u8 srgb, f32 scale, u8 invert,
 *                              u8 pixels (0 none, 1 8-bit, 2 float), u32 width, u32 height,
 *                              width x height x 3 u8 or f32 }   (version 7: the textures)
 *   u32 nenvmaps, nenvmaps x { str name, u8 mapping, u32 width, u32 height, 9 f32 to_world,
 *                             9 f32 to_light, width x height x 3 f32 rgb }   (version 8)
 * and nothing after.
 *
 * The reader treats the blob as hostile: every count is checked against the
 * bytes that are left (at the smallest size its items can take) before any
 * allocation, so a blob cannot make it allocate much more than its own size;
 * every float must be finite, every index in range. The scene is rebuilt with
 * the scene builder verbs and finalized, like a loaded one.
 *
 * Owns nothing past a call. Reentrant. */
#include "proto/sceneblob.h"

#include <inttypes.h>
#include <math.h>
#include <stdarg.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "base/wire.h"
#include "scene/texture.h"

#define S_WHERE "scene blob"

/* The smallest encoded size of each repeated item, for the count checks. */
#define S_MIN_MATERIAL (2 + 1 + 23 * 4 + 4 + 5 * 4 + 1 + 4 + 6 * 4)
#define S_MIN_MESH (2 + 8 + 8 + 2 + 4)
#define S_MIN_TEXTURE (2 + 1 + 4 * 4 + 3 * 16 + 2 + 4 + 2 + 8)
#define S_VERTEX 12
#define S_TRIANGLE 16
#define S_SPHERE 20
#define S_LIGHT (1 + 11 * 4 + 4)
#define S_MIN_ENVMAP (2 + 1 + 4 + 4 + 18 * 4)
/* The settings field group (its layout is in messages.c). */
#define S_SETTINGS 100

/* Writers run while rc (in the caller's scope) is still 0. */
#define W(call)          \
    do {                 \
        if (rc == 0)     \
            rc = (call); \
    } while (0)

/* A name held in a fixed array: written up to its NUL or the array's end. */
static int s_wr_name(pf_buf_t *b, const char *name, size_t cap)
{
    size_t n = strnlen(name, cap - 1);
    int rc = pf_wr_u16(b, (uint16_t)n);
    W(pf_wr_bytes(b, name, n));
    return rc;
}

static int s_wr_vec3(pf_buf_t *b, pf_vec3 v)
{
    int rc = pf_wr_f32(b, v.x);
    W(pf_wr_f32(b, v.y));
    W(pf_wr_f32(b, v.z));
    return rc;
}

static int s_wr_textures(pf_buf_t *out, const pf_scene_t *scene)
{
    int rc = pf_wr_u32(out, (uint32_t)scene->ntexs);
    for (size_t i = 0; i < scene->ntexs && rc == 0; i++) {
        const pf_texture_t *t = &scene->texs[i];
        W(s_wr_name(out, t->name, sizeof t->name));
        W(pf_wr_u8(out, (uint8_t)t->type));
        W(pf_wr_f32(out, t->su));
        W(pf_wr_f32(out, t->sv));
        W(pf_wr_f32(out, t->du));
        W(pf_wr_f32(out, t->dv));
        for (int k = 0; k < 3; k++) {
            W(s_wr_vec3(out, t->op[k].c));
            W(pf_wr_u32(out, t->op[k].ref));
        }
        W(pf_wr_u8(out, (uint8_t)t->wrap));
        W(pf_wr_u8(out, t->srgb ? 1 : 0));
        W(pf_wr_f32(out, t->scale));
        W(pf_wr_u8(out, t->invert ? 1 : 0));
        W(pf_wr_u8(out, t->px8 ? 1 : t->pxf ? 2 : 0));
        int has = t->px8 || t->pxf;
        W(pf_wr_u32(out, has ? (uint32_t)t->width : 0));
        W(pf_wr_u32(out, has ? (uint32_t)t->height : 0));
        size_t n = has ? (size_t)t->width * (size_t)t->height * 3 : 0;
        if (t->px8)
            W(pf_wr_bytes(out, t->px8, n));
        for (size_t k = 0; t->pxf && k < n && rc == 0; k++)
            W(pf_wr_f32(out, t->pxf[k]));
    }
    return rc;
}

int pf_sceneblob_write(const pf_scene_t *scene, pf_buf_t *out)
{
    out->len = 0;
    int rc = 0;
    W(pf_wr_u32(out, PF_SCENEBLOB_MAGIC));
    W(pf_wr_u16(out, PF_SCENEBLOB_VERSION));
    W(pf_wr_u16(out, 0));
    W(s_wr_name(out, scene->path, sizeof scene->path));
    W(pf_wr_settings(out, &scene->settings));
    W(pf_wr_u8(out, scene->has_camera ? 1 : 0));
    W(s_wr_vec3(out, scene->camera.pos));
    W(s_wr_vec3(out, scene->camera.look_at));
    W(s_wr_vec3(out, scene->camera.up));
    W(pf_wr_f32(out, scene->camera.vfov_deg));
    W(pf_wr_u8(out, scene->camera.fov_shorter ? 1 : 0));
    W(pf_wr_u8(out, scene->camera.left_handed ? 1 : 0));
    W(pf_wr_f32(out, scene->camera.lens_radius));
    W(pf_wr_f32(out, scene->camera.focal_distance));
    W(pf_wr_u8(out, scene->camera.has_window ? 1 : 0));
    for (int i = 0; i < 4; i++)
        W(pf_wr_f32(out, scene->camera.window[i]));
    W(pf_wr_f32(out, scene->camera.frame_aspect));

    W(pf_wr_u32(out, (uint32_t)scene->nmats));
    for (size_t i = 0; i < scene->nmats && rc == 0; i++) {
        const pf_material_t *m = &scene->mats[i];
        W(s_wr_name(out, m->name, sizeof m->name));
        W(pf_wr_u8(out, (uint8_t)m->type));
        W(s_wr_vec3(out, m->kd));
        W(s_wr_vec3(out, m->ks));
        W(pf_wr_f32(out, m->ns));
        W(s_wr_vec3(out, m->kt));
        W(pf_wr_f32(out, m->ior));
        W(s_wr_vec3(out, m->le));
        W(pf_wr_u8(out, m->twosided ? 1 : 0));
        W(s_wr_vec3(out, m->eta));
        W(s_wr_vec3(out, m->k));
        W(pf_wr_f32(out, m->alpha));
        W(pf_wr_f32(out, m->thickness));
        W(pf_wr_u32(out, m->kd_tex));
        W(pf_wr_u32(out, m->mix[0]));
        W(pf_wr_u32(out, m->mix[1]));
        W(pf_wr_f32(out, m->amount));
        W(pf_wr_u32(out, m->amount_tex));
        W(pf_wr_u32(out, m->alpha_tex));
        W(pf_wr_u32(out, m->refl_tex));
        W(pf_wr_u32(out, m->rough_tex));
        W(pf_wr_u32(out, m->rough_remap));
        W(pf_wr_u32(out, m->normal_tex));
        W(pf_wr_u32(out, m->bump_tex));
        W(pf_wr_u32(out, m->kt_tex));
        W(s_wr_vec3(out, m->sigma_in));
        W(s_wr_vec3(out, m->sigma_out));
    }

    W(pf_wr_u32(out, (uint32_t)scene->nmeshes));
    for (size_t i = 0; i < scene->nmeshes && rc == 0; i++) {
        const pf_mesh_t *mesh = &scene->meshes[i];
        W(s_wr_name(out, mesh->name, sizeof mesh->name));
        W(pf_wr_u64(out, mesh->nverts));
        W(pf_wr_u64(out, mesh->ntris));
        W(pf_wr_u8(out, mesh->nrm ? 1 : 0));
        W(pf_wr_u8(out, mesh->uv ? 1 : 0));
        W(pf_wr_u32(out, mesh->alpha_tex));
        for (size_t v = 0; v < mesh->nverts && rc == 0; v++)
            W(s_wr_vec3(out, mesh->pos[v]));
        for (size_t v = 0; mesh->nrm && v < mesh->nverts && rc == 0; v++)
            W(s_wr_vec3(out, mesh->nrm[v]));
        for (size_t v = 0; mesh->uv && v < 2 * mesh->nverts && rc == 0; v++)
            W(pf_wr_f32(out, mesh->uv[v]));
        for (size_t t = 0; t < 3 * mesh->ntris && rc == 0; t++)
            W(pf_wr_u32(out, mesh->idx[t]));
        for (size_t t = 0; t < mesh->ntris && rc == 0; t++)
            W(pf_wr_u32(out, mesh->mat[t]));
    }

    W(pf_wr_u32(out, (uint32_t)scene->nspheres));
    for (size_t i = 0; i < scene->nspheres && rc == 0; i++) {
        W(s_wr_vec3(out, scene->spheres[i].center));
        W(pf_wr_f32(out, scene->spheres[i].radius));
        W(pf_wr_u32(out, scene->spheres[i].mat));
    }

    W(pf_wr_u32(out, (uint32_t)scene->nlights));
    for (size_t i = 0; i < scene->nlights && rc == 0; i++) {
        const pf_light_t *l = &scene->lights[i];
        W(pf_wr_u8(out, (uint8_t)l->type));
        W(s_wr_vec3(out, l->pos));
        W(s_wr_vec3(out, l->intensity));
        W(s_wr_vec3(out, l->dir));
        W(pf_wr_f32(out, l->cos_inner));
        W(pf_wr_f32(out, l->cos_outer));
        W(pf_wr_u32(out, l->map));
    }
    W(s_wr_textures(out, scene));
    W(pf_wr_u32(out, (uint32_t)scene->nenvmaps));
    for (size_t i = 0; i < scene->nenvmaps && rc == 0; i++) {
        const pf_envmap_t *m = &scene->envmaps[i];
        W(s_wr_name(out, m->name, sizeof m->name));
        W(pf_wr_u8(out, (uint8_t)m->mapping));
        W(pf_wr_u32(out, (uint32_t)m->width));
        W(pf_wr_u32(out, (uint32_t)m->height));
        for (int k = 0; k < 9; k++)
            W(pf_wr_f32(out, m->to_world[k]));
        for (int k = 0; k < 9; k++)
            W(pf_wr_f32(out, m->to_light[k]));
        size_t n = (size_t)m->width * (size_t)m->height * 3;
        for (size_t k = 0; k < n && rc == 0; k++)
            W(pf_wr_f32(out, m->rgb[k]));
    }
    if (rc != 0)
        out->len = 0;
    return rc;
}

/* ---- reading ---- */

/* The cursor plus the first error, reported as "scene blob: what". */
typedef struct s_in {
    pf_rd_t r;
    pf_error_t *err;
    int status; /* 0 until the first failure */
} s_in_t;

static void s_fail(s_in_t *in, int status, const char *fmt, ...) __attribute__((format(printf, 3, 4)));
static void s_fail(s_in_t *in, int status, const char *fmt, ...)
{
    pf_rd_fail(&in->r);
    if (in->status)
        return;
    in->status = status;
    char text[sizeof in->err->msg];
    va_list ap;
    va_start(ap, fmt);
    vsnprintf(text, sizeof text, fmt, ap);
    va_end(ap);
    pf_error_set(in->err, status, S_WHERE, 0, "%s", text);
}

/* Before each field: it must be whole in what is left. */
static int s_need(s_in_t *in, size_t n, const char *what, const char *field)
{
    if (in->status)
        return 0;
    if (in->r.left < n) {
        s_fail(in, PF_EPARSE, "the blob ends inside %s%s%s", what, *field ? " " : "", field);
        return 0;
    }
    return 1;
}

static uint8_t s_u8(s_in_t *in, const char *what, const char *field)
{
    return s_need(in, 1, what, field) ? pf_rd_u8(&in->r) : 0;
}

static uint16_t s_u16(s_in_t *in, const char *what, const char *field)
{
    return s_need(in, 2, what, field) ? pf_rd_u16(&in->r) : 0;
}

static uint32_t s_u32(s_in_t *in, const char *what, const char *field)
{
    return s_need(in, 4, what, field) ? pf_rd_u32(&in->r) : 0;
}

static uint64_t s_u64(s_in_t *in, const char *what, const char *field)
{
    return s_need(in, 8, what, field) ? pf_rd_u64(&in->r) : 0;
}

static float s_f32(s_in_t *in, const char *what, const char *field)
{
    if (!s_need(in, 4, what, field))
        return 0.0f;
    float f = pf_rd_f32(&in->r);
    if (in->r.err)
        s_fail(in, PF_EPARSE, "%s %s is not a finite number", what, field);
    return f;
}

static pf_vec3 s_vec3(s_in_t *in, const char *what, const char *field)
{
    pf_vec3 v;
    v.x = s_f32(in, what, field);
    v.y = s_f32(in, what, field);
    v.z = s_f32(in, what, field);
    return v;
}

static void s_str(s_in_t *in, const char *what, const char *field, char *dst, size_t cap)
{
    dst[0] = '\0';
    if (!s_need(in, 2, what, field))
        return;
    size_t n = (size_t)in->r.p[0] | (size_t)in->r.p[1] << 8;
    if (n >= cap) {
        s_fail(in, PF_EPARSE, "%s %s is %zu bytes; at most %zu fit", what, field, n, cap - 1);
        return;
    }
    if (in->r.left - 2 < n) {
        s_fail(in, PF_EPARSE, "the blob ends inside %s %s", what, field);
        return;
    }
    pf_rd_str(&in->r, dst, cap);
    if (in->r.err)
        s_fail(in, PF_EPARSE, "%s %s contains a NUL byte", what, field);
}

/* A count of items of at least item_size bytes each must fit in what is left. */
static int s_count_fits(s_in_t *in, uint64_t count, size_t item_size, const char *what)
{
    if (in->status)
        return 0;
    if (count > in->r.left / item_size) {
        s_fail(in, PF_EPARSE, "%" PRIu64 " %s need at least %" PRIu64 "%s bytes, but %zu are left", count, what,
               count <= UINT64_MAX / item_size ? count * item_size : UINT64_MAX,
               count <= UINT64_MAX / item_size ? "" : "+", in->r.left);
        return 0;
    }
    return 1;
}

static void s_read_camera(s_in_t *in, pf_scene_t *scene)
{
    uint8_t has = s_u8(in, "camera", "has_camera");
    if (!in->status && has > 1)
        s_fail(in, PF_EPARSE, "camera has_camera is %u, not 0 or 1", (unsigned)has);
    scene->has_camera = has;
    scene->camera.pos = s_vec3(in, "camera", "pos");
    scene->camera.look_at = s_vec3(in, "camera", "look_at");
    scene->camera.up = s_vec3(in, "camera", "up");
    scene->camera.vfov_deg = s_f32(in, "camera", "vfov_deg");
    uint8_t shorter = s_u8(in, "camera", "fov_shorter");
    if (!in->status && shorter > 1)
        s_fail(in, PF_EPARSE, "camera fov_shorter is %u, not 0 or 1", (unsigned)shorter);
    uint8_t left = s_u8(in, "camera", "left_handed");
    if (!in->status && left > 1)
        s_fail(in, PF_EPARSE, "camera left_handed is %u, not 0 or 1", (unsigned)left);
    scene->camera.fov_shorter = shorter;
    scene->camera.left_handed = left;
    float lens = s_f32(in, "camera", "lens_radius");
    float focus = s_f32(in, "camera", "focal_distance");
    if (!in->status && !(lens >= 0.0f))
        s_fail(in, PF_EPARSE, "camera lens_radius is %g, not >= 0", (double)lens);
    if (!in->status && lens > 0.0f && !(focus > 0.0f))
        s_fail(in, PF_EPARSE, "camera focal_distance is %g, not > 0 with a lens (lens_radius %g)", (double)focus,
               (double)lens);
    scene->camera.lens_radius = lens;
    scene->camera.focal_distance = focus;
    uint8_t win = s_u8(in, "camera", "has_window");
    if (!in->status && win > 1)
        s_fail(in, PF_EPARSE, "camera has_window is %u, not 0 or 1", (unsigned)win);
    scene->camera.has_window = win;
    for (int i = 0; i < 4; i++)
        scene->camera.window[i] = s_f32(in, "camera", "window");
    scene->camera.frame_aspect = s_f32(in, "camera", "frame_aspect"); /* the ranges: pf_scene_finalize */
}

static void s_read_materials(s_in_t *in, pf_scene_t *scene)
{
    uint32_t n = s_u32(in, "materials", "count");
    if (!s_count_fits(in, n, S_MIN_MATERIAL, "materials"))
        return;
    for (uint32_t i = 0; i < n && !in->status; i++) {
        char what[32];
        snprintf(what, sizeof what, "material %" PRIu32, i);
        pf_material_t m;
        memset(&m, 0, sizeof m);
        s_str(in, what, "name", m.name, sizeof m.name);
        uint8_t type = s_u8(in, what, "type");
        if (!in->status && type > PF_MAT_LAST)
            s_fail(in, PF_EPARSE, "%s type %u is not a material type (0..%d)", what, (unsigned)type, PF_MAT_LAST);
        m.type = (pf_mat_type)type;
        m.kd = s_vec3(in, what, "kd");
        m.ks = s_vec3(in, what, "ks");
        m.ns = s_f32(in, what, "ns");
        m.kt = s_vec3(in, what, "kt");
        m.ior = s_f32(in, what, "ior");
        m.le = s_vec3(in, what, "le");
        m.twosided = s_u8(in, what, "twosided"); /* 0 or 1: checked by finalize */
        m.eta = s_vec3(in, what, "eta");
        m.k = s_vec3(in, what, "k");
        m.alpha = s_f32(in, what, "alpha");
        m.thickness = s_f32(in, what, "thickness");
        m.kd_tex = s_u32(in, what, "kd_tex"); /* checked against the textures by finalize */
        m.mix[0] = s_u32(in, what, "mix0"); /* these four, too, by finalize */
        m.mix[1] = s_u32(in, what, "mix1");
        m.amount = s_f32(in, what, "amount");
        m.amount_tex = s_u32(in, what, "amount_tex");
        m.alpha_tex = s_u32(in, what, "alpha_tex");
        m.refl_tex = s_u32(in, what, "refl_tex"); /* the four: likewise */
        m.rough_tex = s_u32(in, what, "rough_tex");
        m.rough_remap = s_u32(in, what, "rough_remap") != 0;
        m.normal_tex = s_u32(in, what, "normal_tex");
        m.bump_tex = s_u32(in, what, "bump_tex");
        m.kt_tex = s_u32(in, what, "kt_tex"); /* by finalize, with the media's signs */
        m.sigma_in = s_vec3(in, what, "sigma_in");
        m.sigma_out = s_vec3(in, what, "sigma_out");
        if (!in->status && m.type == PF_MAT_CONDUCTOR &&
            !(m.eta.x > 0.0f && m.eta.y > 0.0f && m.eta.z > 0.0f && m.k.x >= 0.0f && m.k.y >= 0.0f &&
              m.k.z >= 0.0f && m.alpha >= 0.0f && m.alpha <= 1.0f))
            s_fail(in, PF_EPARSE, "%s conductor needs eta > 0, k >= 0 and alpha in [0, 1]", what);
        if (!in->status && pf_scene_add_material(scene, &m) < 0)
            s_fail(in, PF_ENOMEM, "out of memory for %s", what);
    }
}

/* Reads one mesh into *mesh (its arrays allocated here). *nrm_src is set to
 * the normals' bytes in the blob, so that they can be put back after
 * finalizing (see pf_sceneblob_read). */
static void s_read_mesh(s_in_t *in, uint32_t index, size_t nmats, pf_mesh_t *mesh, const uint8_t **nrm_src)
{
    char what[96];
    snprintf(what, sizeof what, "mesh %" PRIu32, index);
    s_str(in, what, "name", mesh->name, sizeof mesh->name);
    if (!in->status)
        snprintf(what, sizeof what, "mesh %" PRIu32 " ('%s')", index, mesh->name);
    uint64_t nverts = s_u64(in, what, "nverts");
    uint64_t ntris = s_u64(in, what, "ntris");
    uint8_t has_nrm = s_u8(in, what, "has_normals");
    uint8_t has_uv = s_u8(in, what, "has_uv");
    mesh->alpha_tex = s_u32(in, what, "alpha_tex"); /* checked against the textures by finalize */
    if (in->status)
        return;
    if (has_nrm > 1 || has_uv > 1) {
        s_fail(in, PF_EPARSE, "%s has_normals is %u and has_uv %u, not 0 or 1", what, (unsigned)has_nrm,
               (unsigned)has_uv);
        return;
    }
    /* Both counts against the bytes left, before allocating anything. */
    size_t vbytes = (has_nrm ? 2 * S_VERTEX : S_VERTEX) + (has_uv ? 8 : 0);
    if (!s_count_fits(in, nverts, vbytes, "vertices"))
        return;
    if (ntris > (in->r.left - nverts * vbytes) / S_TRIANGLE) {
        s_fail(in, PF_EPARSE, "%s: %" PRIu64 " triangles do not fit in the %zu bytes left after its vertices", what,
               ntris, in->r.left - (size_t)(nverts * vbytes));
        return;
    }
    mesh->nverts = (size_t)nverts;
    mesh->ntris = (size_t)ntris;
    mesh->pos = malloc((nverts ? nverts : 1) * sizeof *mesh->pos);
    mesh->nrm = has_nrm ? malloc((nverts ? nverts : 1) * sizeof *mesh->nrm) : NULL;
    mesh->uv = has_uv ? malloc((nverts ? 2 * nverts : 1) * sizeof *mesh->uv) : NULL;
    mesh->idx = malloc((ntris ? 3 * ntris : 1) * sizeof *mesh->idx);
    mesh->mat = malloc((ntris ? ntris : 1) * sizeof *mesh->mat);
    if (!mesh->pos || (has_nrm && !mesh->nrm) || (has_uv && !mesh->uv) || !mesh->idx || !mesh->mat) {
        s_fail(in, PF_ENOMEM, "out of memory for %s", what);
        return;
    }
    for (size_t v = 0; v < mesh->nverts && !in->status; v++)
        mesh->pos[v] = s_vec3(in, what, "positions");
    *nrm_src = has_nrm ? in->r.p : NULL;
    for (size_t v = 0; has_nrm && v < mesh->nverts && !in->status; v++)
        mesh->nrm[v] = s_vec3(in, what, "normals");
    for (size_t v = 0; has_uv && v < 2 * mesh->nverts && !in->status; v++)
        mesh->uv[v] = s_f32(in, what, "uv");
    for (size_t t = 0; t < 3 * mesh->ntris && !in->status; t++) {
        uint32_t k = s_u32(in, what, "indices");
        if (!in->status && k >= mesh->nverts)
            s_fail(in, PF_EPARSE, "%s triangle %zu: vertex index %" PRIu32 " is out of range (%zu vertices)", what,
                   t / 3, k, mesh->nverts);
        mesh->idx[t] = k;
    }
    for (size_t t = 0; t < mesh->ntris && !in->status; t++) {
        uint32_t k = s_u32(in, what, "materials");
        if (!in->status && k >= nmats)
            s_fail(in, PF_EPARSE, "%s triangle %zu: material index %" PRIu32 " is out of range (%zu materials)",
                   what, t, k, nmats);
        mesh->mat[t] = k;
    }
}

static void s_read_spheres(s_in_t *in, pf_scene_t *scene)
{
    uint32_t n = s_u32(in, "spheres", "count");
    if (!s_count_fits(in, n, S_SPHERE, "spheres"))
        return;
    for (uint32_t i = 0; i < n && !in->status; i++) {
        char what[32];
        snprintf(what, sizeof what, "sphere %" PRIu32, i);
        pf_sphere_t s;
        s.center = s_vec3(in, what, "center");
        s.radius = s_f32(in, what, "radius");
        s.mat = s_u32(in, what, "mat");
        if (!in->status && s.mat >= scene->nmats)
            s_fail(in, PF_EPARSE, "%s material index %" PRIu32 " is out of range (%zu materials)", what, s.mat,
                   scene->nmats);
        if (!in->status && pf_scene_add_sphere(scene, &s) != PF_OK)
            s_fail(in, PF_ENOMEM, "out of memory for %s", what);
    }
}

static void s_read_lights(s_in_t *in, pf_scene_t *scene)
{
    uint32_t n = s_u32(in, "lights", "count");
    if (!s_count_fits(in, n, S_LIGHT, "lights"))
        return;
    for (uint32_t i = 0; i < n && !in->status; i++) {
        char what[32];
        snprintf(what, sizeof what, "light %" PRIu32, i);
        pf_light_t l;
        memset(&l, 0, sizeof l);
        uint8_t type = s_u8(in, what, "type");
        if (!in->status && type > PF_LIGHT_LAST)
            s_fail(in, PF_EPARSE, "%s type %u is not a light type (0..%d)", what, (unsigned)type, PF_LIGHT_LAST);
        l.type = (pf_light_type)type;
        l.pos = s_vec3(in, what, "pos");
        l.intensity = s_vec3(in, what, "intensity");
        l.dir = s_vec3(in, what, "dir");
        l.cos_inner = s_f32(in, what, "cos_inner");
        l.cos_outer = s_f32(in, what, "cos_outer");
        l.map = s_u32(in, what, "map"); /* checked against the maps by finalize */
        if (!in->status && pf_scene_add_light(scene, &l) != PF_OK)
            s_fail(in, PF_ENOMEM, "out of memory for %s", what);
    }
}

/* One texture's pixels: their count checked against the bytes left first. */
static void s_read_pixels(s_in_t *in, const char *what, pf_texture_t *t, uint8_t kind)
{
    uint32_t w = s_u32(in, what, "width"), h = s_u32(in, what, "height");
    if (in->status || kind == 0)
        return;
    if (kind > 2 || w == 0 || h == 0 || w > PF_TEX_MAX_SIDE || h > PF_TEX_MAX_SIDE ||
        (uint64_t)w * h > PF_TEX_MAX_PIXELS) {
        s_fail(in, PF_EPARSE, "%s: pixel kind %u, %" PRIu32 " x %" PRIu32 " pixels is not a texture image", what,
               (unsigned)kind, w, h);
        return;
    }
    size_t n = (size_t)w * h * 3;
    if (!s_count_fits(in, n, kind == 1 ? 1 : 4, "texture channels"))
        return;
    t->width = (int)w;
    t->height = (int)h;
    if (kind == 1) {
        t->px8 = malloc(n);
        if (t->px8)
            memcpy(t->px8, pf_rd_bytes(&in->r, n), n);
    } else if ((t->pxf = malloc(n * sizeof *t->pxf)) != NULL) {
        for (size_t k = 0; k < n && !in->status; k++)
            t->pxf[k] = s_f32(in, what, "pixels");
    }
    if (!t->px8 && !t->pxf)
        s_fail(in, PF_ENOMEM, "out of memory for %s", what);
}

static void s_read_textures(s_in_t *in, pf_scene_t *scene)
{
    uint32_t n = s_u32(in, "textures", "count");
    if (!s_count_fits(in, n, S_MIN_TEXTURE, "textures"))
        return;
    for (uint32_t i = 0; i < n && !in->status; i++) {
        char what[32];
        snprintf(what, sizeof what, "texture %" PRIu32, i);
        pf_texture_t t = pf_texture_constant("", pf_v3s(0.0f));
        s_str(in, what, "name", t.name, sizeof t.name);
        t.type = (pf_tex_type)s_u8(in, what, "type");
        t.su = s_f32(in, what, "su");
        t.sv = s_f32(in, what, "sv");
        t.du = s_f32(in, what, "du");
        t.dv = s_f32(in, what, "dv");
        for (int k = 0; k < 3; k++) {
            t.op[k].c = s_vec3(in, what, "operand");
            t.op[k].ref = s_u32(in, what, "operand ref"); /* types, refs and wrap: checked by finalize */
        }
        t.wrap = (pf_tex_wrap)s_u8(in, what, "wrap");
        t.srgb = s_u8(in, what, "srgb") != 0;
        t.scale = s_f32(in, what, "scale");
        t.invert = s_u8(in, what, "invert") != 0;
        s_read_pixels(in, what, &t, s_u8(in, what, "pixels"));
        if (!in->status && pf_scene_add_texture(scene, &t) < 0)
            s_fail(in, PF_ENOMEM, "out of memory for %s", what);
        pf_texture_free(&t);
    }
}

/* The environment maps: sizes checked against the bytes left before the
 * pixels are allocated; the pixels' range and the mapping's square by
 * finalize. */
static void s_read_envmaps(s_in_t *in, pf_scene_t *scene)
{
    uint32_t n = s_u32(in, "envmaps", "count");
    if (!s_count_fits(in, n, S_MIN_ENVMAP, "envmaps"))
        return;
    for (uint32_t i = 0; i < n && !in->status; i++) {
        char what[32];
        snprintf(what, sizeof what, "envmap %" PRIu32, i);
        pf_envmap_t m;
        memset(&m, 0, sizeof m);
        s_str(in, what, "name", m.name, sizeof m.name);
        m.mapping = s_u8(in, what, "mapping");
        uint32_t w = s_u32(in, what, "width"), h = s_u32(in, what, "height");
        for (int k = 0; k < 9; k++)
            m.to_world[k] = s_f32(in, what, "to_world");
        for (int k = 0; k < 9; k++)
            m.to_light[k] = s_f32(in, what, "to_light");
        if (!in->status && (w == 0 || h == 0 || w > PF_ENVMAP_MAX_SIDE || h > PF_ENVMAP_MAX_SIDE))
            s_fail(in, PF_EPARSE, "%s size %" PRIu32 "x%" PRIu32 " is out of range", what, w, h);
        uint64_t nf = (uint64_t)w * h * 3;
        if (in->status || !s_count_fits(in, nf, 4, "envmap values"))
            return;
        m.width = (int)w;
        m.height = (int)h;
        m.rgb = malloc(nf * sizeof *m.rgb);
        if (!m.rgb) {
            s_fail(in, PF_ENOMEM, "out of memory for %s", what);
            return;
        }
        for (uint64_t k = 0; k < nf; k++)
            m.rgb[k] = pf_rd_f32(&in->r);
        if (in->r.err)
            s_fail(in, PF_EPARSE, "%s holds a non-finite value", what);
        if (pf_scene_add_envmap(scene, &m) < 0) {
            s_fail(in, PF_ENOMEM, "out of memory for %s", what);
            free(m.rgb);
        }
    }
}

/* A little-endian vec3 from 12 bytes the reader already validated. */
static pf_vec3 s_vec3_at(const uint8_t *p)
{
    float f[3];
    for (int k = 0; k < 3; k++) {
        uint32_t u = (uint32_t)p[4 * k] | (uint32_t)p[4 * k + 1] << 8 | (uint32_t)p[4 * k + 2] << 16 |
                     (uint32_t)p[4 * k + 3] << 24;
        memcpy(&f[k], &u, sizeof u);
    }
    return pf_v3(f[0], f[1], f[2]);
}

pf_scene_t *pf_sceneblob_read(const uint8_t *data, size_t len, pf_error_t *err)
{
    s_in_t in = { pf_rd_make(data, data ? len : 0), err, 0 };
    pf_scene_t *scene = NULL;
    const uint8_t **nrm_src = NULL;

    uint32_t magic = s_u32(&in, "header", "magic");
    if (!in.status && magic != PF_SCENEBLOB_MAGIC)
        s_fail(&in, PF_EPARSE, "bad magic 0x%08" PRIx32 " (expected 0x%08x, \"FSCN\"): not a scene blob", magic,
               PF_SCENEBLOB_MAGIC);
    uint16_t version = s_u16(&in, "header", "version");
    if (!in.status && version != PF_SCENEBLOB_VERSION)
        s_fail(&in, PF_EMISMATCH, "format version %u, this build reads %u", (unsigned)version,
               (unsigned)PF_SCENEBLOB_VERSION);
    uint16_t reserved = s_u16(&in, "header", "reserved");
    if (!in.status && reserved != 0)
        s_fail(&in, PF_EPARSE, "reserved header field is %u, not 0", (unsigned)reserved);
    if (in.status)
        return NULL;

    scene = pf_scene_create();
    if (!scene) {
        pf_error_set(err, PF_ENOMEM, S_WHERE, 0, "out of memory");
        return NULL;
    }
    char path[sizeof scene->path];
    s_str(&in, "header", "path", path, sizeof path);
    if (s_need(&in, S_SETTINGS, "settings", ""))
        pf_rd_settings(&in.r, &scene->settings);
    if (!in.status && in.r.err)
        s_fail(&in, PF_EPARSE, "settings hold a non-finite number");
    s_read_camera(&in, scene);
    s_read_materials(&in, scene);

    uint32_t nmeshes = s_u32(&in, "meshes", "count");
    if (s_count_fits(&in, nmeshes, S_MIN_MESH, "meshes")) {
        nrm_src = calloc(nmeshes ? nmeshes : 1, sizeof *nrm_src);
        if (!nrm_src)
            s_fail(&in, PF_ENOMEM, "out of memory for %" PRIu32 " meshes", nmeshes);
    }
    for (uint32_t i = 0; i < nmeshes && !in.status; i++) {
        pf_mesh_t mesh;
        memset(&mesh, 0, sizeof mesh);
        s_read_mesh(&in, i, scene->nmats, &mesh, &nrm_src[i]);
        if (!in.status && pf_scene_add_mesh(scene, &mesh) != PF_OK)
            s_fail(&in, PF_ENOMEM, "out of memory for mesh %" PRIu32, i);
        pf_mesh_free(&mesh); /* a no-op once the scene holds it */
    }
    s_read_spheres(&in, scene);
    s_read_lights(&in, scene);
    s_read_textures(&in, scene);
    s_read_envmaps(&in, scene);
    if (!in.status && in.r.left > 0)
        s_fail(&in, PF_EPARSE, "%zu trailing bytes after the environment maps", in.r.left);

    if (!in.status) {
        /* Finalize reports its errors under the scene's path; name the blob. */
        snprintf(scene->path, sizeof scene->path, "%s", S_WHERE);
        int rc = pf_scene_finalize(scene, err);
        if (rc != PF_OK)
            in.status = rc;
    }
    if (!in.status) {
        memcpy(scene->path, path, sizeof path);
        /* Finalizing renormalizes the shading normals, and normalizing an
         * already unit vector again may move its last bit. The blob carries
         * the coordinator's normals exactly, and the worker must shade with
         * those same bits for farm images to equal local ones; so unit
         * normals are put back as they were sent (others keep finalize's). */
        for (size_t i = 0; i < scene->nmeshes; i++) {
            pf_mesh_t *mesh = &scene->meshes[i];
            for (size_t v = 0; mesh->nrm && nrm_src[i] && v < mesh->nverts; v++) {
                pf_vec3 n = s_vec3_at(nrm_src[i] + 12 * v);
                if (fabsf(pf_len2(n) - 1.0f) <= 1e-5f)
                    mesh->nrm[v] = n;
            }
        }
    }
    free(nrm_src);
    if (in.status) {
        pf_scene_destroy(&scene);
        return NULL;
    }
    return scene;
}
