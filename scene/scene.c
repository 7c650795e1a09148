/* scene.c: the scene model's builder verbs and validation (the loaders
 * that fill it are in load/). Single-threaded: scenes are built once, then
 * read by every rendering thread without locks. */
#include "scene/scene.h"

#include <float.h>
#include <math.h>
#include <stdlib.h>
#include <stdio.h>
#include <string.h>

#include "base/log.h"
#include "base/reserve.h"

uint64_t pf_pass_seed(uint64_t seed, int pass)
{
    if (pass <= 0)
        return seed;
    /* splitmix64's finalizer over seed and pass: a different stream per pass */
    uint64_t z = seed ^ (0x9e3779b97f4a7c15ULL * (uint64_t)(pass + 1));
    z = (z ^ (z >> 30)) * 0xbf58476d1ce4e5b9ULL;
    z = (z ^ (z >> 27)) * 0x94d049bb133111ebULL;
    return z ^ (z >> 31);
}

pf_settings_t pf_settings_default(void)
{
    return (pf_settings_t){
        .width = 512,
        .height = 512,
        .spp = 36,
        .photons = 400000,
        .caustic_photons = 400000,
        .gather = 1,
        .gather_filter = 2,
        .light_samples = 2,
        .max_depth = 16,
        .photon_max_depth = 1000,
        .global_k = 100,
        .caustic_k = 80,
        .caustic_radius = 0.0f,
        .global_radius = 0.0f,
        .irradiance_stride = 4,
        .threads = 0,
        .seed = 1,
        .exposure = 0.0f,
        .filter_box = 1.0f,
        .filter_tent = 0.0f,
        .path_max_depth = 0,
    };
}

/* One term of a pixel filter spec, name[:width], ending at end; *seen
 * gains its kind's bit (a kind given twice is an error). */
static int s_filter_term(const char *p, const char *end, float *box, float *tent, unsigned *seen)
{
    size_t n = (size_t)(end - p);
    const char *colon = memchr(p, ':', n);
    size_t name = colon ? (size_t)(colon - p) : n;
    float w = 1.0f;
    if (colon) {
        char num[32];
        size_t k = (size_t)(end - colon - 1);
        if (k == 0 || k >= sizeof num)
            return PF_EINVAL;
        memcpy(num, colon + 1, k);
        num[k] = '\0';
        char *stop;
        w = strtof(num, &stop);
        if (*stop || !(w >= 0.0f && w <= PF_MAX_FILTER_WIDTH))
            return PF_EINVAL;
    }
    unsigned bit = name == 3 && !memcmp(p, "box", 3) ? 1u : name == 4 && !memcmp(p, "tent", 4) ? 2u : 0u;
    if (!bit || (*seen & bit))
        return PF_EINVAL;
    *seen |= bit;
    *(bit == 1u ? box : tent) = w;
    return PF_OK;
}

int pf_pixel_filter_parse(const char *spec, float *box, float *tent)
{
    float b = 0.0f, t = 0.0f;
    unsigned seen = 0;
    const char *plus = strchr(spec, '+');
    const char *end = spec + strlen(spec);
    if (s_filter_term(spec, plus ? plus : end, &b, &t, &seen) != PF_OK ||
        (plus && s_filter_term(plus + 1, end, &b, &t, &seen) != PF_OK) || !(b + t > 0.0f))
        return PF_EINVAL;
    *box = b;
    *tent = t;
    return PF_OK;
}

pf_material_t pf_material_default(const char *name)
{
    pf_material_t m;
    memset(&m, 0, sizeof m);
    snprintf(m.name, sizeof m.name, "%s", name ? name : "default");
    m.type = PF_MAT_DIFFUSE;
    m.kd = pf_v3s(0.8f);
    m.ns = 1.0f;
    m.ior = 1.5f;
    m.kt = pf_v3s(1.0f);
    m.eta = pf_v3s(1.0f);
    return m;
}

pf_scene_t *pf_scene_create(void)
{
    pf_scene_t *self = calloc(1, sizeof *self);
    if (!self)
        return NULL;
    self->settings = pf_settings_default();
    return self;
}

void pf_mesh_free(pf_mesh_t *mesh)
{
    if (!mesh)
        return;
    free(mesh->pos);
    free(mesh->nrm);
    free(mesh->uv);
    free(mesh->idx);
    free(mesh->mat);
    memset(mesh, 0, sizeof *mesh);
}

void pf_scene_destroy(pf_scene_t **self_p)
{
    if (!self_p || !*self_p)
        return;
    pf_scene_t *self = *self_p;
    for (size_t i = 0; i < self->nmeshes; i++)
        pf_mesh_free(&self->meshes[i]);
    free(self->meshes);
    free(self->mats);
    free(self->spheres);
    free(self->lights);
    for (size_t i = 0; i < self->ntexs; i++)
        pf_texture_free(&self->texs[i]);
    free(self->texs);
    for (size_t i = 0; i < self->nenvmaps; i++)
        free(self->envmaps[i].rgb);
    free(self->envmaps);
    free(self);
    *self_p = NULL;
}

int pf_scene_add_material(pf_scene_t *self, const pf_material_t *mat)
{
    if (pf_reserve((void **)&self->mats, &self->cap_mats, self->nmats + 1, sizeof *mat))
        return PF_ENOMEM;
    self->mats[self->nmats] = *mat;
    return (int)self->nmats++;
}

int pf_scene_find_material(const pf_scene_t *self, const char *name)
{
    for (size_t i = self->nmats; i-- > 0;)
        if (strcmp(self->mats[i].name, name) == 0)
            return (int)i;
    return -1;
}

int pf_scene_add_mesh(pf_scene_t *self, pf_mesh_t *mesh)
{
    if (pf_reserve((void **)&self->meshes, &self->cap_meshes, self->nmeshes + 1, sizeof *mesh))
        return PF_ENOMEM;
    self->meshes[self->nmeshes++] = *mesh;
    memset(mesh, 0, sizeof *mesh);
    return PF_OK;
}

int pf_scene_add_sphere(pf_scene_t *self, const pf_sphere_t *sphere)
{
    if (pf_reserve((void **)&self->spheres, &self->cap_spheres, self->nspheres + 1, sizeof *sphere))
        return PF_ENOMEM;
    self->spheres[self->nspheres++] = *sphere;
    return PF_OK;
}

int pf_scene_add_light(pf_scene_t *self, const pf_light_t *light)
{
    if (pf_reserve((void **)&self->lights, &self->cap_lights, self->nlights + 1, sizeof *light))
        return PF_ENOMEM;
    self->lights[self->nlights++] = *light;
    return PF_OK;
}

int pf_scene_add_envmap(pf_scene_t *self, pf_envmap_t *map)
{
    if (pf_reserve((void **)&self->envmaps, &self->cap_envmaps, self->nenvmaps + 1, sizeof *map))
        return PF_ENOMEM;
    self->envmaps[self->nenvmaps] = *map;
    memset(map, 0, sizeof *map);
    return (int)self->nenvmaps++;
}

/* Checks an environment image: its size (square for the equal-area
 * mapping), frame and pixels (finite, >= 0). */
static int s_check_envmap(const pf_envmap_t *m, size_t i, const char *file, pf_error_t *err)
{
    if (!(m->width > 0 && m->height > 0 && m->width <= PF_ENVMAP_MAX_SIDE && m->height <= PF_ENVMAP_MAX_SIDE) ||
        !m->rgb || (unsigned)m->mapping > PF_ENVMAP_MAPPING_LAST)
        return pf_error_set(err, PF_EPARSE, file, 0, "environment map %zu (%s): bad size %dx%d or mapping %d", i,
                            m->name, m->width, m->height, m->mapping);
    if (m->mapping == PF_ENVMAP_EQUALAREA && m->width != m->height)
        return pf_error_set(err, PF_EPARSE, file, 0,
                            "environment map %zu (%s) is %dx%d: the equal-area mapping needs a square image", i,
                            m->name, m->width, m->height);
    for (int k = 0; k < 9; k++)
        if (!isfinite(m->to_world[k]) || !isfinite(m->to_light[k]))
            return pf_error_set(err, PF_EPARSE, file, 0, "environment map %zu (%s): its frame is not finite", i,
                                m->name);
    size_t n = (size_t)m->width * (size_t)m->height * 3;
    for (size_t k = 0; k < n; k++)
        if (!(m->rgb[k] >= 0.0f) || !isfinite(m->rgb[k]))
            return pf_error_set(err, PF_ERANGE, file, 0,
                                "environment map %zu (%s): pixel %zu holds %g (values must be finite and >= 0)", i,
                                m->name, k / 3, (double)m->rgb[k]);
    return PF_OK;
}

/* The largest coordinate a scene may use. Every position can become a ray
 * origin (hit points, lights, the camera), and Embree refuses rays whose
 * origin lies beyond its FLT_LARGE, 1.844e18 (Debian's build aborts on an
 * assertion). False for NaN too. */
#define S_COORD_MAX 1e18f

static int s_in_range(pf_vec3 v)
{
    return fabsf(v.x) <= S_COORD_MAX && fabsf(v.y) <= S_COORD_MAX && fabsf(v.z) <= S_COORD_MAX;
}

void pf_scene_bounds(const pf_scene_t *self, pf_vec3 *lo, pf_vec3 *hi)
{
    pf_vec3 a, b;
    pf_scene_geometry_bounds(self, &a, &b);
    for (size_t l = 0; l < self->nlights; l++) {
        if (self->lights[l].type == PF_LIGHT_DISTANT || self->lights[l].type == PF_LIGHT_INFINITE)
            continue;
        a = pf_vmin(a, self->lights[l].pos);
        b = pf_vmax(b, self->lights[l].pos);
    }
    *lo = a;
    *hi = b;
}

void pf_scene_geometry_bounds(const pf_scene_t *self, pf_vec3 *lo, pf_vec3 *hi)
{
    pf_vec3 a = pf_v3s(FLT_MAX), b = pf_v3s(-FLT_MAX);
    for (size_t m = 0; m < self->nmeshes; m++) {
        const pf_mesh_t *mesh = &self->meshes[m];
        for (size_t i = 0; i < mesh->nverts; i++) {
            /* Vertices finalize drops with their triangles (non-finite, out of
             * range) would make the bounds, and the framing camera and
             * search radii derived from them, infinite. */
            if (!s_in_range(mesh->pos[i]))
                continue;
            a = pf_vmin(a, mesh->pos[i]);
            b = pf_vmax(b, mesh->pos[i]);
        }
    }
    for (size_t s = 0; s < self->nspheres; s++) {
        const pf_sphere_t *sp = &self->spheres[s];
        a = pf_vmin(a, pf_sub(sp->center, pf_v3s(sp->radius)));
        b = pf_vmax(b, pf_add(sp->center, pf_v3s(sp->radius)));
    }
    *lo = a;
    *hi = b;
}

/* A shading normal made unit length, or zero when it has no direction (zero
 * or not finite). It must come out unit even when its squared length
 * underflows or overflows a float (components below ~1e-19 or above ~1e19):
 * (0, 1.5e-39, 4e-23) used to become (0, 4e-17, 1.057), which finalizing
 * again moves, so the scene blob of such a scene changed on every trip (the
 * blob reader keeps a normal's bits only when it is unit; sceneblob.c), and
 * (0, 6e32, 1) used to become zero. Such a normal is first divided by its
 * largest magnitude, which leaves a squared length in [1, 3]; the division,
 * not a multiplication by the reciprocal, because that overflows for a
 * subnormal magnitude. Every other normal takes the direct path, bit for bit
 * as before. */
static pf_vec3 s_unit_normal(pf_vec3 n)
{
    if (!pf_is_finite3(n))
        return pf_v3(0, 0, 0);
    float l2 = pf_len2(n);
    if (!(l2 >= FLT_MIN && l2 <= FLT_MAX)) {
        float m = pf_maxc(pf_vabs(n));
        if (!(m > 0.0f))
            return pf_v3(0, 0, 0);
        n = pf_v3(n.x / m, n.y / m, n.z / m);
        l2 = pf_len2(n);
    }
    return pf_scale(n, 1.0f / sqrtf(l2));
}

static int s_mat_finite(const pf_material_t *m)
{
    return pf_is_finite3(m->kd) && pf_is_finite3(m->ks) && pf_is_finite3(m->kt) && pf_is_finite3(m->le) &&
           isfinite(m->ns) && isfinite(m->ior) && pf_is_finite3(m->eta) && pf_is_finite3(m->k) && isfinite(m->alpha) &&
           isfinite(m->thickness) && isfinite(m->amount) && pf_is_finite3(m->sigma_in) && pf_is_finite3(m->sigma_out);
}

/* Checks a MIX material's two indices and that following mixes from it
 * ends, within PF_MIX_MAX_DEPTH, at materials that are not mixes (no cycle). */
static int s_check_mix(const pf_scene_t *self, size_t i, const char *file, pf_error_t *err)
{
    const pf_material_t *m = &self->mats[i];
    if (m->mix[0] >= self->nmats || m->mix[1] >= self->nmats)
        return pf_error_set(err, PF_EPARSE, file, 0, "material '%s': mix of materials %u and %u, out of range (%zu)",
                            m->name, (unsigned)m->mix[0], (unsigned)m->mix[1], self->nmats);
    /* Depth-first over the mix tree, at most 2^depth leaves; a cycle shows as depth running out. */
    uint32_t stack[2 * PF_MIX_MAX_DEPTH + 2];
    int depth[2 * PF_MIX_MAX_DEPTH + 2], n = 0;
    stack[n] = (uint32_t)i;
    depth[n++] = 0;
    while (n > 0) {
        n--;
        const pf_material_t *x = &self->mats[stack[n]];
        int d = depth[n];
        if (x->type != PF_MAT_MIX)
            continue;
        if (d >= PF_MIX_MAX_DEPTH || x->mix[0] >= self->nmats || x->mix[1] >= self->nmats)
            return pf_error_set(err, PF_EPARSE, file, 0,
                                "material '%s': mixes nest deeper than %d or form a cycle", m->name, PF_MIX_MAX_DEPTH);
        for (int k = 0; k < 2; k++) {
            stack[n] = x->mix[k];
            depth[n++] = d + 1;
        }
    }
    return PF_OK;
}

/* Removes triangles that cannot be rendered: zero area, an area whose square
 * overflows a float (edges beyond ~1e9; the light table and the hit normals
 * need it), vertices non-finite or beyond S_COORD_MAX. Returns how many. */
static size_t s_drop_degenerate(pf_mesh_t *mesh)
{
    size_t kept = 0;
    for (size_t t = 0; t < mesh->ntris; t++) {
        const uint32_t *v = &mesh->idx[3 * t];
        pf_vec3 p0 = mesh->pos[v[0]], p1 = mesh->pos[v[1]], p2 = mesh->pos[v[2]];
        pf_vec3 n = pf_cross(pf_sub(p1, p0), pf_sub(p2, p0));
        float a2 = pf_len2(n);
        if (!(a2 > 0.0f) || !isfinite(a2) || !s_in_range(p0) || !s_in_range(p1) || !s_in_range(p2))
            continue;
        if (kept != t) {
            memmove(&mesh->idx[3 * kept], v, 3 * sizeof *v);
            mesh->mat[kept] = mesh->mat[t];
        }
        kept++;
    }
    size_t dropped = mesh->ntris - kept;
    mesh->ntris = kept;
    return dropped;
}

void pf_texture_free(pf_texture_t *tex)
{
    if (!tex)
        return;
    free(tex->px8);
    free(tex->pxf);
    tex->px8 = NULL;
    tex->pxf = NULL;
}

static int s_check_one(const pf_texture_t *t, size_t i, const char *file, pf_error_t *err)
{
    if ((unsigned)t->type > PF_TEX_LAST || (unsigned)t->wrap > PF_WRAP_LAST)
        return pf_error_set(err, PF_EPARSE, file, 0, "texture '%s': unknown type %d or wrap mode %d", t->name,
                            (int)t->type, (int)t->wrap);
    if (!isfinite(t->su) || !isfinite(t->sv) || !isfinite(t->du) || !isfinite(t->dv) || !isfinite(t->scale))
        return pf_error_set(err, PF_EPARSE, file, 0, "texture '%s' has a non-finite mapping or scale", t->name);
    for (int k = 0; k < 3; k++) {
        if (!pf_is_finite3(t->op[k].c))
            return pf_error_set(err, PF_EPARSE, file, 0, "texture '%s' has a non-finite value", t->name);
        if (t->op[k].ref > i)
            return pf_error_set(err, PF_EPARSE, file, 0,
                                "texture '%s' refers to texture %u, not one defined before it", t->name,
                                (unsigned)t->op[k].ref);
    }
    if (t->type == PF_TEX_IMAGE) {
        if (t->width <= 0 || t->height <= 0 || t->width > PF_TEX_MAX_SIDE || t->height > PF_TEX_MAX_SIDE ||
            (uint64_t)t->width * (uint64_t)t->height > PF_TEX_MAX_PIXELS || (!t->px8 == !t->pxf))
            return pf_error_set(err, PF_EPARSE, file, 0, "texture '%s': bad image (%d x %d)", t->name, t->width,
                                t->height);
    }
    return PF_OK;
}

/* Checks the texture table and the refs into it (materials' kd_tex,
 * operands only to earlier textures, types, wrap modes, image sizes,
 * finite parameters); replaces non-finite pixels and mesh uvs by 0. */
static int s_check_textures(pf_scene_t *self, pf_error_t *err)
{
    const char *file = self->path[0] ? self->path : "scene";
    for (size_t i = 0; i < self->ntexs; i++) {
        pf_texture_t *t = &self->texs[i];
        int rc = s_check_one(t, i, file, err);
        if (rc)
            return rc;
        /* An HDR file's inf or nan would poison every pixel it is mixed into. */
        for (size_t k = 0; t->pxf && k < (size_t)t->width * (size_t)t->height * 3; k++)
            if (!isfinite(t->pxf[k]))
                t->pxf[k] = 0.0f;
    }
    for (size_t i = 0; i < self->nmats; i++) {
        const pf_material_t *m = &self->mats[i];
        uint32_t refs[8] = { m->kd_tex,     m->refl_tex,   m->rough_tex, m->normal_tex,
                             m->bump_tex,   m->amount_tex, m->alpha_tex, m->kt_tex };
        for (int k = 0; k < 8; k++)
            if (refs[k] > self->ntexs)
                return pf_error_set(err, PF_EPARSE, file, 0, "material '%s': texture %u out of range (%zu textures)",
                                    m->name, (unsigned)refs[k], self->ntexs);
    }
    for (size_t m = 0; m < self->nmeshes; m++) {
        pf_mesh_t *mesh = &self->meshes[m];
        if (mesh->alpha_tex > self->ntexs)
            return pf_error_set(err, PF_EPARSE, file, 0, "mesh '%s': alpha texture %u out of range (%zu textures)",
                                mesh->name, (unsigned)mesh->alpha_tex, self->ntexs);
        for (size_t k = 0; mesh->uv && k < 2 * mesh->nverts; k++)
            if (!isfinite(mesh->uv[k]))
                mesh->uv[k] = 0.0f;
    }
    return PF_OK;
}

/* Frames the geometry: looks at the bounds' centre from +z, far enough that
 * the bounding sphere fits the vertical field of view. */
static void s_frame_camera(pf_scene_t *self)
{
    pf_vec3 lo, hi;
    pf_scene_bounds(self, &lo, &hi);
    pf_vec3 c = pf_scale(pf_add(lo, hi), 0.5f);
    float r = 0.5f * pf_len(pf_sub(hi, lo));
    if (!(r > 0.0f) || !isfinite(r))
        r = 1.0f;
    float fov = 40.0f;
    float dist = r / sinf(0.5f * fov * PF_PI / 180.0f);
    self->camera = (pf_camera_desc_t){ .pos = pf_add(c, pf_v3(0, 0, dist)), .look_at = c, .up = pf_v3(0, 1, 0), .vfov_deg = fov };
    self->has_camera = 1;
}

/* The camera's frame and field of view, and its extras: flags 0 or 1, the
 * lens radius finite and >= 0, the focal distance finite and, with a lens,
 * > 0 (both within the ray tracer's range); the screen window's bounds
 * within +-1e6 and in order, the frame aspect 0 or within [1e-6, 1e6]. */
static int s_check_camera(const pf_camera_desc_t *c, const char *file, pf_error_t *err)
{
    if (!s_in_range(c->pos) || !pf_is_finite3(c->look_at) || !pf_is_finite3(c->up) || !(c->vfov_deg > 0.0f) ||
        !(c->vfov_deg < 180.0f) || !(pf_len2(pf_sub(c->look_at, c->pos)) > 0.0f) ||
        !(pf_len2(pf_cross(pf_sub(c->look_at, c->pos), c->up)) > 0.0f))
        return pf_error_set(err, PF_EPARSE, file, 0,
                            "bad camera: position must be within +-1e18 and differ from look-at, up must not be "
                            "parallel to the view, field of view in (0, 180)");
    if ((c->fov_shorter != 0 && c->fov_shorter != 1) || (c->left_handed != 0 && c->left_handed != 1))
        return pf_error_set(err, PF_EPARSE, file, 0, "bad camera: fov_shorter (%d) and left_handed (%d) must be 0 or 1",
                            c->fov_shorter, c->left_handed);
    if (!(c->lens_radius >= 0.0f && c->lens_radius <= S_COORD_MAX))
        return pf_error_set(err, PF_EPARSE, file, 0, "bad camera: lens radius %g must be >= 0 and at most 1e18",
                            (double)c->lens_radius);
    if (!(fabsf(c->focal_distance) <= S_COORD_MAX) || (c->lens_radius > 0.0f && !(c->focal_distance > 0.0f)))
        return pf_error_set(err, PF_EPARSE, file, 0,
                            "bad camera: focal distance %g must be finite, and > 0 with a lens (radius %g)",
                            (double)c->focal_distance, (double)c->lens_radius);
    int win_ok = 1;
    for (int i = 0; i < 4; i++)
        win_ok &= fabsf(c->window[i]) <= 1e6f;
    if ((c->has_window != 0 && c->has_window != 1) || !win_ok ||
        (c->has_window && !(c->window[0] < c->window[1] && c->window[2] < c->window[3])))
        return pf_error_set(err, PF_EPARSE, file, 0,
                            "bad camera: screen window [%g %g %g %g] (has_window %d) must lie within +-1e6 with "
                            "xmin < xmax and ymin < ymax",
                            (double)c->window[0], (double)c->window[1], (double)c->window[2], (double)c->window[3],
                            c->has_window);
    if (!(c->frame_aspect == 0.0f || (c->frame_aspect >= 1e-6f && c->frame_aspect <= 1e6f)))
        return pf_error_set(err, PF_EPARSE, file, 0, "bad camera: frame aspect %g must be 0 or in [1e-6, 1e6]",
                            (double)c->frame_aspect);
    return PF_OK;
}

int pf_scene_finalize(pf_scene_t *self, pf_error_t *err)
{
    const char *file = self->path[0] ? self->path : "scene";
    for (size_t i = 0; i < self->nmats; i++) {
        const pf_material_t *m = &self->mats[i];
        if (!s_mat_finite(m))
            return pf_error_set(err, PF_EPARSE, file, 0, "material '%s' has a non-finite value", m->name);
        if ((m->type == PF_MAT_GLASS || m->type == PF_MAT_THIN_DIELECTRIC) && !(m->ior > 0.0f))
            return pf_error_set(err, PF_EPARSE, file, 0, "material '%s': index of refraction must be > 0", m->name);
        if (m->type == PF_MAT_CONDUCTOR && !(m->eta.x > 0.0f && m->eta.y > 0.0f && m->eta.z > 0.0f))
            return pf_error_set(err, PF_EPARSE, file, 0, "material '%s': conductor eta must be > 0", m->name);
        if (m->type == PF_MAT_CONDUCTOR && !(m->k.x >= 0.0f && m->k.y >= 0.0f && m->k.z >= 0.0f))
            return pf_error_set(err, PF_EPARSE, file, 0, "material '%s': conductor k must be >= 0", m->name);
        if (m->type == PF_MAT_CONDUCTOR && !(m->alpha >= 0.0f && m->alpha <= 1.0f))
            return pf_error_set(err, PF_EPARSE, file, 0, "material '%s': conductor roughness must be in [0, 1]",
                                m->name);
        if (m->type == PF_MAT_GLASS && !(m->alpha >= 0.0f && m->alpha <= 1.0f))
            return pf_error_set(err, PF_EPARSE, file, 0, "material '%s': glass roughness must be in [0, 1]", m->name);
        if (m->type == PF_MAT_COATED &&
            !(m->ior >= 1.0f && m->alpha >= 0.0f && m->alpha <= 1.0f && m->thickness >= 0.0f &&
              m->kd.x >= 0.0f && m->kd.y >= 0.0f && m->kd.z >= 0.0f && pf_maxc(m->kd) <= 1.0f))
            return pf_error_set(err, PF_EPARSE, file, 0,
                                "material '%s': coated needs ior >= 1, roughness in [0, 1], thickness >= 0 and "
                                "reflectance in [0, 1]",
                                m->name);
        if (m->type == PF_MAT_DIFFUSE_TRANSMISSION &&
            !(m->kd.x >= 0.0f && m->kd.y >= 0.0f && m->kd.z >= 0.0f && m->kt.x >= 0.0f && m->kt.y >= 0.0f &&
              m->kt.z >= 0.0f && pf_maxc(pf_add(m->kd, m->kt)) <= 1.0f))
            return pf_error_set(err, PF_EPARSE, file, 0,
                                "material '%s': diffuse transmission needs reflectance, transmittance >= 0 and "
                                "their sum <= 1",
                                m->name);
        if (m->type == PF_MAT_MIX) {
            int mrc = s_check_mix(self, i, file, err);
            if (mrc)
                return mrc;
        }
        if (m->type > PF_MAT_LAST)
            return pf_error_set(err, PF_EPARSE, file, 0, "material '%s': unknown type %d", m->name, (int)m->type);
        if (m->twosided > 1)
            return pf_error_set(err, PF_EPARSE, file, 0, "material '%s': twosided must be 0 or 1", m->name);
        if (pf_minc(m->sigma_in) < 0.0f || pf_minc(m->sigma_out) < 0.0f)
            return pf_error_set(err, PF_EPARSE, file, 0, "material '%s': a medium's absorption must be >= 0",
                                m->name);
    }
    int trc = s_check_textures(self, err);
    if (trc)
        return trc;
    size_t dropped = 0, ntris = 0;
    for (size_t mi = 0; mi < self->nmeshes; mi++) {
        pf_mesh_t *mesh = &self->meshes[mi];
        for (size_t t = 0; t < mesh->ntris; t++) {
            for (int k = 0; k < 3; k++)
                if (mesh->idx[3 * t + k] >= mesh->nverts)
                    return pf_error_set(err, PF_EPARSE, file, 0, "mesh '%s': vertex index out of range", mesh->name);
            if (mesh->mat[t] >= self->nmats)
                return pf_error_set(err, PF_EPARSE, file, 0, "mesh '%s': material index out of range", mesh->name);
        }
        if (mesh->nrm) {
            for (size_t v = 0; v < mesh->nverts; v++) {
                mesh->nrm[v] = s_unit_normal(mesh->nrm[v]);
            }
        }
        dropped += s_drop_degenerate(mesh);
        ntris += mesh->ntris;
    }
    if (dropped)
        pf_warn("%s: skipped %zu degenerate triangle%s (zero area, area too large for a float, or vertices "
                "non-finite or beyond +-1e18)",
                file, dropped, dropped == 1 ? "" : "s");
    for (size_t s = 0; s < self->nspheres; s++) {
        const pf_sphere_t *sp = &self->spheres[s];
        if (!pf_is_finite3(sp->center) || !(sp->radius > 0.0f) || !isfinite(sp->radius))
            return pf_error_set(err, PF_EPARSE, file, 0, "sphere %zu: centre must be finite and radius > 0", s);
        if (!s_in_range(pf_add(pf_vabs(sp->center), pf_v3s(sp->radius))))
            return pf_error_set(err, PF_ERANGE, file, 0, "sphere %zu reaches beyond +-1e18, the ray tracer's range",
                                s);
        if (sp->mat >= self->nmats)
            return pf_error_set(err, PF_EPARSE, file, 0, "sphere %zu: material index out of range", s);
        if (self->mats[sp->mat].twosided && !pf_is_black(self->mats[sp->mat].le))
            return pf_error_set(err, PF_EPARSE, file, 0,
                                "sphere %zu: material '%s' emits on both sides (twosided), which an analytic sphere "
                                "does not: it emits outward (give a mesh that material instead)",
                                s, self->mats[sp->mat].name);
    }
    for (size_t l = 0; l < self->nlights; l++) {
        const pf_light_t *li = &self->lights[l];
        pf_vec3 I = li->intensity;
        if (!s_in_range(li->pos) || !pf_is_finite3(I) || I.x < 0.0f || I.y < 0.0f || I.z < 0.0f ||
            ((unsigned)li->type > PF_LIGHT_LAST) ||
            ((li->type == PF_LIGHT_SPOT || li->type == PF_LIGHT_DISTANT) &&
             (!pf_is_finite3(li->dir) || !(pf_len2(li->dir) > 0.0f))))
            return pf_error_set(err, PF_ERANGE, file, 0,
                                "light %zu: position must be finite and within +-1e18, intensity finite and >= 0, "
                                "direction (spot, distant) finite and not zero", l);
        if (li->map && (li->type != PF_LIGHT_INFINITE || li->map > self->nenvmaps))
            return pf_error_set(err, PF_EPARSE, file, 0, "light %zu: environment map %u does not exist (%zu maps)",
                                l, (unsigned)li->map, self->nenvmaps);
    }
    for (size_t i = 0; i < self->nenvmaps; i++) {
        int rc = s_check_envmap(&self->envmaps[i], i, file, err);
        if (rc)
            return rc;
    }
    int emitters = (int)self->nlights;
    for (size_t s = 0; s < self->nspheres && !emitters; s++) /* a sphere emits outward (light/spherelight.h) */
        emitters = !pf_is_black(self->mats[self->spheres[s].mat].le);
    for (size_t mi = 0; mi < self->nmeshes && !emitters; mi++)
        for (size_t t = 0; t < self->meshes[mi].ntris && !emitters; t++)
            emitters = !pf_is_black(self->mats[self->meshes[mi].mat[t]].le);
    if (ntris == 0 && self->nspheres == 0)
        return pf_error_set(err, PF_EPARSE, file, 0, "the scene has no geometry");
    if (!emitters)
        return pf_error_set(err, PF_EPARSE, file, 0,
                            "the scene has no light: give a material an emission (Ke) or add a point, spot, distant or infinite light");
    if (!self->has_camera)
        s_frame_camera(self);
    return s_check_camera(&self->camera, file, err);
}
