/* test_scene_json.c: the JSON scene format (load/scene_json.c).
 *
 * - prims.json uses every key except the model objects; the values must land
 *   in pf_scene_t exactly (camera, settings, materials, sphere transform,
 *   quad corners and winding, transform order, matrices, lights).
 * - models.json loads OBJ and PLY models through their loaders with a
 *   material override, an MTL-name remap and a transform.
 * - The three shipped scenes load through pf_scene_load with sane geometry
 *   and a light whose emitting side faces down.
 * - The camera's thin-lens keys land, default as documented, and bad values
 *   fail with their line.
 * - Malformed files each fail with the exact "file:line:" of the offending
 *   key or value; files under tests/data/json/bad/ plus inline variants
 *   written to a temporary folder.
 * Run from the repository root (ctest does). */
#include <float.h>
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <unistd.h>

#include "base/log.h"
#include "scene/scene.h"

#include "check.h"
#include "load/load.h"



static int near(float a, float b, float tol) { return fabsf(a - b) <= tol; }
static int near3(pf_vec3 a, pf_vec3 b, float tol) { return near(a.x, b.x, tol) && near(a.y, b.y, tol) && near(a.z, b.z, tol); }
#define V3F "(%g, %g, %g)"
#define V3A(v) (double)(v).x, (double)(v).y, (double)(v).z

static pf_vec3 s_tri_normal(const pf_mesh_t *m, size_t t)
{
    const uint32_t *i = &m->idx[3 * t];
    return pf_norm(pf_cross(pf_sub(m->pos[i[1]], m->pos[i[0]]), pf_sub(m->pos[i[2]], m->pos[i[0]])));
}

/* Loads a JSON file without finalizing; NULL (and prints err) on failure. */
static pf_scene_t *s_json(const char *path, pf_error_t *err)
{
    pf_scene_t *sc = pf_scene_create();
    if (!sc)
        return NULL;
    if (pf_scene_json_load(sc, path, err) != PF_OK) {
        pf_scene_destroy(&sc);
        return NULL;
    }
    return sc;
}

static void test_prims(void)
{
    pf_error_t err = { { 0 } };
    pf_scene_t *sc = s_json("tests/data/json/prims.json", &err);
    CHECK(sc != NULL, "prims.json: %s", err.msg);
    if (!sc)
        return;

    CHECK(sc->has_camera, "camera given");
    CHECK(near3(sc->camera.pos, pf_v3(1, 2, 10), 0) && near3(sc->camera.look_at, pf_v3(0, 1, 0), 0) &&
              near3(sc->camera.up, pf_v3(0, 1, 0), 0) && sc->camera.vfov_deg == 35.0f,
          "camera " V3F " fov %g", V3A(sc->camera.pos), (double)sc->camera.vfov_deg);

    const pf_settings_t *s = &sc->settings;
    CHECK(s->width == 320 && s->height == 200 && s->spp == 3, "size %dx%d spp %d", s->width, s->height, s->spp);
    CHECK(s->photons == 9007199254740992ull, "photons 2^53 accepted exactly: %llu", (unsigned long long)s->photons);
    CHECK(s->caustic_photons == 12345 && s->seed == 42, "caustic_photons %llu seed %llu",
          (unsigned long long)s->caustic_photons, (unsigned long long)s->seed);
    CHECK(s->gather == 7 && s->gather_filter == 3 && s->light_samples == 3 && s->max_depth == 5 &&
              s->photon_max_depth == 9 && s->path_max_depth == 4,
          "gather %d filter %d light_samples %d depths %d %d %d", s->gather, s->gather_filter, s->light_samples,
          s->max_depth, s->photon_max_depth, s->path_max_depth);
    CHECK(s->global_k == 50 && s->caustic_k == 40 && s->irradiance_stride == 2, "k %d %d stride %d", s->global_k,
          s->caustic_k, s->irradiance_stride);
    CHECK(s->caustic_radius == 0.25f && s->global_radius == 0.5f && s->exposure == -1.5f, "radii %g %g exposure %g",
          (double)s->caustic_radius, (double)s->global_radius, (double)s->exposure);
    CHECK(s->threads == pf_settings_default().threads, "threads untouched");

    CHECK(sc->nmats == 5, "5 materials, got %zu", sc->nmats);
    int shiny = pf_scene_find_material(sc, "shiny"), mirror = pf_scene_find_material(sc, "mirror");
    int glass = pf_scene_find_material(sc, "glass"), light = pf_scene_find_material(sc, "light");
    int plain = pf_scene_find_material(sc, "plain");
    CHECK(shiny >= 0 && mirror >= 0 && glass >= 0 && light >= 0 && plain >= 0, "all materials found");
    if (shiny < 0 || mirror < 0 || glass < 0 || light < 0 || plain < 0) {
        pf_scene_destroy(&sc);
        return;
    }
    const pf_material_t *m = &sc->mats[shiny];
    CHECK(m->type == PF_MAT_DIFFUSE && near3(m->kd, pf_v3(0.4f, 0.3f, 0.2f), 0) && near3(m->ks, pf_v3s(0.5f), 0) &&
              m->ns == 50.0f && pf_is_black(m->le),
          "shiny kd " V3F " ks " V3F " ns %g", V3A(m->kd), V3A(m->ks), (double)m->ns);
    m = &sc->mats[mirror];
    CHECK(m->type == PF_MAT_MIRROR && near3(m->ks, pf_v3s(0.9f), 0), "mirror ks " V3F, V3A(m->ks));
    m = &sc->mats[glass];
    CHECK(m->type == PF_MAT_GLASS && m->ior == 1.33f && near3(m->ks, pf_v3(1, 0.9f, 0.8f), 0) &&
              near3(m->kt, pf_v3(0.7f, 0.8f, 0.9f), 0),
          "glass ior %g ks " V3F " kt " V3F, (double)m->ior, V3A(m->ks), V3A(m->kt));
    m = &sc->mats[light];
    CHECK(m->type == PF_MAT_DIFFUSE && pf_is_black(m->kd) && near3(m->le, pf_v3(17, 12, 4), 0),
          "light kd " V3F " le " V3F, V3A(m->kd), V3A(m->le));
    pf_material_t def = pf_material_default("plain");
    m = &sc->mats[plain];
    CHECK(memcmp(m, &def, sizeof def) == 0, "a material with only a name is pf_material_default");

    /* Sphere: (1,0,0) scaled 2 -> (2,0,0), rotated 90 about z -> (0,2,0), translated -> (1,4,3). */
    CHECK(sc->nspheres == 1, "one sphere, got %zu", sc->nspheres);
    if (sc->nspheres == 1) {
        const pf_sphere_t *sp = &sc->spheres[0];
        CHECK(near3(sp->center, pf_v3(1, 4, 3), 1e-6f) && near(sp->radius, 1.0f, 1e-6f) && sp->mat == (uint32_t)glass,
              "sphere centre " V3F " radius %g", V3A(sp->center), (double)sp->radius);
    }

    CHECK(sc->nmeshes == 4, "four quads, got %zu", sc->nmeshes);
    if (sc->nmeshes == 4) {
        /* Mirrored quad: corners mirrored in order, normal still +z. */
        const pf_mesh_t *q = &sc->meshes[0];
        CHECK(q->nverts == 4 && q->ntris == 2 && q->mat[0] == (uint32_t)shiny && q->mat[1] == (uint32_t)shiny,
              "quad shape");
        CHECK(near3(q->pos[0], pf_v3(0, 0, 0), 0) && near3(q->pos[1], pf_v3(-1, 0, 0), 0) &&
                  near3(q->pos[2], pf_v3(-1, 1, 0), 0) && near3(q->pos[3], pf_v3(0, 1, 0), 0),
              "mirrored corners " V3F V3F V3F V3F, V3A(q->pos[0]), V3A(q->pos[1]), V3A(q->pos[2]), V3A(q->pos[3]));
        for (size_t t = 0; t < 2; t++)
            CHECK(near3(s_tri_normal(q, t), pf_v3(0, 0, 1), 1e-6f), "mirrored quad tri %zu normal " V3F, t,
                  V3A(s_tri_normal(q, t)));

        /* Rotate [90, 90, 0] then translate: X first maps (x,y,z) to (x,-z,y),
         * then Y maps that to (y, -z, -x). Corner (0,1,0) -> (1,0,0) -> +5y. */
        q = &sc->meshes[1];
        CHECK(near3(q->pos[0], pf_v3(1, 5, 0), 1e-6f) && near3(q->pos[1], pf_v3(1, 5, -2), 1e-6f) &&
                  near3(q->pos[2], pf_v3(1, 2, -2), 1e-6f) && near3(q->pos[3], pf_v3(1, 2, 0), 1e-6f),
              "rotated corners " V3F V3F V3F V3F, V3A(q->pos[0]), V3A(q->pos[1]), V3A(q->pos[2]), V3A(q->pos[3]));
        /* Untransformed normal edge1 x edge2 = (2,0,0) x (0,0,3) = -y, rotated like a vector: -x. */
        CHECK(near3(s_tri_normal(q, 0), pf_v3(-1, 0, 0), 1e-6f) && near3(s_tri_normal(q, 1), pf_v3(-1, 0, 0), 1e-6f),
              "rotated quad normal " V3F, V3A(s_tri_normal(q, 0)));
        CHECK(q->idx[0] == 0 && q->idx[1] == 1 && q->idx[2] == 2 && q->idx[3] == 0 && q->idx[4] == 2 && q->idx[5] == 3,
              "unmirrored quad keeps (0,1,2),(0,2,3)");

        /* 16-number matrix: a translation by (7,8,9). */
        q = &sc->meshes[2];
        CHECK(near3(q->pos[0], pf_v3(7, 8, 9), 0) && near3(q->pos[2], pf_v3(8, 8, 8), 0), "matrix16 corners " V3F V3F,
              V3A(q->pos[0]), V3A(q->pos[2]));
        CHECK(near3(s_tri_normal(q, 0), pf_v3(0, 1, 0), 1e-6f), "edge1 x edge2 = (1,0,0)x(0,0,-1) = +y: " V3F,
              V3A(s_tri_normal(q, 0)));
        /* 12-number matrix: 90 degrees about z, then z - 4. */
        q = &sc->meshes[3];
        CHECK(near3(q->pos[1], pf_v3(0, 1, -4), 0) && near3(q->pos[2], pf_v3(-1, 1, -4), 0), "matrix12 corners " V3F V3F,
              V3A(q->pos[1]), V3A(q->pos[2]));
    }

    CHECK(sc->nlights == 4, "four lights, got %zu", sc->nlights);
    if (sc->nlights == 4)
        CHECK(sc->lights[3].type == PF_LIGHT_INFINITE && near3(sc->lights[3].intensity, pf_v3(0.25f, 0.5f, 1), 0),
              "infinite light radiance " V3F, V3A(sc->lights[3].intensity));
    if (sc->nlights >= 3) {
        const pf_light_t *d = &sc->lights[2];
        CHECK(d->type == PF_LIGHT_DISTANT && near3(d->dir, pf_v3(0, -0.6f, 0.8f), 1e-6f) &&
                  near3(d->intensity, pf_v3(1, 2, 3), 0),
              "distant light dir " V3F " irradiance " V3F, V3A(d->dir), V3A(d->intensity));
    }
    if (sc->nlights >= 2) {
        const pf_light_t *l = &sc->lights[0];
        CHECK(l->type == PF_LIGHT_POINT && near3(l->pos, pf_v3(0, 1.9f, 0), 0) && near3(l->intensity, pf_v3(5, 6, 7), 0),
              "point light");
        l = &sc->lights[1];
        CHECK(l->type == PF_LIGHT_SPOT && near3(l->pos, pf_v3(0, 3, 0), 0) && near3(l->dir, pf_v3(0, -1, 0), 0) &&
                  near3(l->intensity, pf_v3s(20), 0),
              "spot light dir " V3F, V3A(l->dir));
        CHECK(near(l->cos_outer, 0.5f, 1e-6f) && near(l->cos_inner, sqrtf(0.5f), 1e-6f), "spot cosines %g %g",
              (double)l->cos_outer, (double)l->cos_inner);
    }
    pf_scene_destroy(&sc);

    /* The same file finalizes through the dispatcher. */
    sc = pf_scene_load("tests/data/json/prims.json", &err);
    CHECK(sc != NULL, "pf_scene_load(prims.json): %s", err.msg);
    if (sc)
        CHECK(strcmp(sc->path, "tests/data/json/prims.json") == 0, "path kept: %s", sc->path);
    pf_scene_destroy(&sc);
}

static void test_models(void)
{
    pf_error_t err = { { 0 } };
    pf_scene_t *sc = s_json("tests/data/json/models.json", &err);
    CHECK(sc != NULL, "models.json (needs the OBJ and PLY loaders): %s", err.msg);
    if (!sc)
        return;
    int white = pf_scene_find_material(sc, "white"), red = pf_scene_find_material(sc, "red");
    int light = pf_scene_find_material(sc, "light");
    CHECK(white == 0 && red == 1 && light == 2, "JSON materials first: %d %d %d", white, red, light);
    CHECK(sc->nmats >= 4 && strcmp(sc->mats[3].name, "mtlB") == 0 && near3(sc->mats[3].kd, pf_v3s(0.9f), 0),
          "the JSON material mtlB survives model.mtl's mtlB");

    /* Count, per model, the triangles and what they use. Meshes appear in
     * object order; the first OBJ's triangles all have x >= 10. */
    size_t first_obj = 0, first_white = 0, second_obj = 0, second_red = 0, second_a = 0, ply = 0;
    size_t third_obj = 0, third_own = 0, quad = 0, quad_json = 0;
    for (size_t mi = 0; mi < sc->nmeshes; mi++) {
        const pf_mesh_t *mesh = &sc->meshes[mi];
        for (size_t t = 0; t < mesh->ntris; t++) {
            const uint32_t *v = &mesh->idx[3 * t];
            pf_vec3 p0 = mesh->pos[v[0]], p1 = mesh->pos[v[1]], p2 = mesh->pos[v[2]];
            uint32_t mat = mesh->mat[t];
            if (mat == (uint32_t)light) {
                ply++;
                /* (0,0,0),(1,0,0),(0,1,0) scaled 2, rotated 90 about x ((x,y,z) -> (x,-z,y)), +5y. */
                CHECK(near3(p0, pf_v3(0, 5, 0), 1e-6f) && near3(p1, pf_v3(2, 5, 0), 1e-6f) &&
                          near3(p2, pf_v3(0, 5, 2), 1e-6f),
                      "ply triangle " V3F V3F V3F, V3A(p0), V3A(p1), V3A(p2));
            } else if (p0.z > 99.0f) {
                quad++;
                quad_json += mat == 3;
            } else if (p0.x >= 19.5f && p1.x >= 19.5f && p2.x >= 19.5f) {
                /* Its own MTL materials: mtlA 0.5 and mtlB 0.2, not the JSON mtlB. */
                third_obj++;
                float kd = mat < sc->nmats ? sc->mats[mat].kd.x : -1.0f;
                third_own += mat != 3 && (kd == 0.5f || kd == 0.2f);
            } else if (p0.x >= 9.5f && p1.x >= 9.5f && p2.x >= 9.5f) {
                first_obj++;
                first_white += mat == (uint32_t)white;
            } else {
                second_obj++;
                second_red += mat == (uint32_t)red;
                second_a += mat < sc->nmats && strcmp(sc->mats[mat].name, "mtlA") == 0;
            }
        }
    }
    CHECK(first_obj == 2 && first_white == 2, "override: %zu triangles, %zu white", first_obj, first_white);
    CHECK(second_obj == 2 && second_red == 1 && second_a == 1, "remap: %zu triangles, %zu red, %zu mtlA", second_obj,
          second_red, second_a);
    CHECK(ply == 1, "one ply triangle, got %zu", ply);
    CHECK(third_obj == 2 && third_own == 2, "MTL materials: %zu triangles, %zu with their own", third_obj, third_own);
    CHECK(quad == 2 && quad_json == 2, "the quad keeps the JSON mtlB: %zu of %zu", quad_json, quad);
    pf_scene_destroy(&sc);
}

/* Checks the emitting triangles of a loaded scene: radiance le, face normal -y. */
static void s_check_light(const pf_scene_t *sc, const char *name, pf_vec3 le, size_t want_tris)
{
    size_t n = 0, down = 0;
    for (size_t mi = 0; mi < sc->nmeshes; mi++) {
        const pf_mesh_t *mesh = &sc->meshes[mi];
        for (size_t t = 0; t < mesh->ntris; t++) {
            const pf_material_t *m = &sc->mats[mesh->mat[t]];
            if (pf_is_black(m->le))
                continue;
            n++;
            CHECK(near3(m->le, le, 1e-6f), "%s: emission " V3F, name, V3A(m->le));
            down += near3(s_tri_normal(mesh, t), pf_v3(0, -1, 0), 1e-5f);
        }
    }
    CHECK(n == want_tris && down == n, "%s: %zu emitting triangles, %zu facing down (want %zu)", name, n, down,
          want_tris);
}

static size_t s_ntris(const pf_scene_t *sc)
{
    size_t n = 0;
    for (size_t mi = 0; mi < sc->nmeshes; mi++)
        n += sc->meshes[mi].ntris;
    return n;
}

static void test_shipped(void)
{
    pf_error_t err = { { 0 } };
    pf_vec3 lo, hi;

    pf_scene_t *sc = pf_scene_load("scenes/cornell-box/scene.json", &err);
    CHECK(sc != NULL, "cornell-box: %s", err.msg);
    if (sc) {
        CHECK(sc->has_camera && near3(sc->camera.pos, pf_v3(0, 1, 6.8f), 0) && sc->camera.vfov_deg == 19.5f,
              "cornell-box camera");
        CHECK(sc->settings.width == 512 && sc->settings.height == 512, "cornell-box size");
        CHECK(s_ntris(sc) == 36, "cornell-box: 36 triangles, got %zu", s_ntris(sc));
        pf_scene_bounds(sc, &lo, &hi);
        CHECK(near3(lo, pf_v3(-1, 0, -1), 1e-5f) && near3(hi, pf_v3(1, 2, 1), 1e-5f), "cornell-box bounds " V3F V3F,
              V3A(lo), V3A(hi));
        s_check_light(sc, "cornell-box", pf_v3(17, 12, 4), 2);
        int lw = pf_scene_find_material(sc, "LeftWall"), rw = pf_scene_find_material(sc, "RightWall");
        CHECK(lw >= 0 && near3(sc->mats[lw].kd, pf_v3(0.63f, 0.065f, 0.05f), 1e-6f), "LeftWall kd");
        CHECK(rw >= 0 && near3(sc->mats[rw].kd, pf_v3(0.14f, 0.45f, 0.091f), 1e-6f), "RightWall kd");
        int li = pf_scene_find_material(sc, "Light");
        CHECK(li >= 0 && pf_is_black(sc->mats[li].kd), "the light does not reflect");
    }
    pf_scene_destroy(&sc);

    sc = pf_scene_load("scenes/cornell-spheres/scene.json", &err);
    CHECK(sc != NULL, "cornell-spheres: %s", err.msg);
    if (sc) {
        CHECK(sc->has_camera && near3(sc->camera.pos, pf_v3(0, 0.8f, 3.2f), 0) && sc->camera.vfov_deg == 40.0f,
              "cornell-spheres camera");
        CHECK(s_ntris(sc) >= 2 * 1088 + 10, "cornell-spheres: %zu triangles", s_ntris(sc));
        pf_scene_bounds(sc, &lo, &hi);
        CHECK(lo.y > -0.01f && near(hi.y, 1.59f, 0.01f) && lo.x > -1.1f && hi.x < 1.1f, "cornell-spheres bounds " V3F V3F,
              V3A(lo), V3A(hi));
        s_check_light(sc, "cornell-spheres", pf_v3s(10), 2);
        int g = pf_scene_find_material(sc, "rightSphere"), mi = pf_scene_find_material(sc, "leftSphere");
        CHECK(g >= 0 && sc->mats[g].type == PF_MAT_GLASS && sc->mats[g].ior == 1.5f, "glass sphere material");
        CHECK(mi >= 0 && sc->mats[mi].type == PF_MAT_MIRROR, "mirror sphere material");
    }
    pf_scene_destroy(&sc);

    sc = pf_scene_load("scenes/bunny/scene.json", &err);
    CHECK(sc != NULL, "bunny: %s", err.msg);
    if (sc) {
        size_t n = s_ntris(sc);
        CHECK(n > 69000 && n <= 69451 + 12, "bunny: %zu triangles", n);
        pf_scene_bounds(sc, &lo, &hi);
        CHECK(near3(lo, pf_v3(-1, 0, -1), 1e-5f) && near3(hi, pf_v3(1, 2, 1), 1e-5f), "bunny box bounds " V3F V3F,
              V3A(lo), V3A(hi));
        /* The bunny itself: the glass triangles stand on the floor, inside the box. */
        int glass = pf_scene_find_material(sc, "glass");
        pf_vec3 blo = pf_v3s(FLT_MAX), bhi = pf_v3s(-FLT_MAX);
        for (size_t mi = 0; mi < sc->nmeshes; mi++)
            for (size_t t = 0; t < sc->meshes[mi].ntris; t++)
                if (sc->meshes[mi].mat[t] == (uint32_t)glass)
                    for (int k = 0; k < 3; k++) {
                        pf_vec3 p = sc->meshes[mi].pos[sc->meshes[mi].idx[3 * t + k]];
                        blo = pf_vmin(blo, p);
                        bhi = pf_vmax(bhi, p);
                    }
        CHECK(glass >= 0 && blo.y >= 0.0f && blo.y < 0.01f && bhi.y > 0.85f && bhi.y < 1.0f && blo.x > -0.95f &&
                  bhi.x < 0.95f && blo.z > -0.95f && bhi.z < 0.95f,
              "bunny bounds " V3F V3F, V3A(blo), V3A(bhi));
        CHECK(sc->nspheres == 1 && sc->spheres[0].center.x - sc->spheres[0].radius > bhi.x - 0.01f,
              "the mirror sphere stands beside the bunny");
        s_check_light(sc, "bunny", pf_v3(17, 12, 4), 2);
    }
    pf_scene_destroy(&sc);
}

typedef struct bad_case {
    const char *file; /* under tests/data/json/bad/ */
    int line;
    const char *what; /* a fragment of the message after "file:line: " */
} bad_case_t;

static void s_expect_error(const char *path, int line, const char *what)
{
    pf_error_t err = { { 0 } };
    pf_scene_t *sc = pf_scene_create();
    int rc = pf_scene_json_load(sc, path, &err);
    char prefix[600];
    snprintf(prefix, sizeof prefix, "%s:%d: ", path, line);
    CHECK(rc < 0, "%s must fail", path);
    CHECK(strncmp(err.msg, prefix, strlen(prefix)) == 0 && strstr(err.msg + strlen(prefix), what),
          "want \"%s...%s\", got \"%s\"", prefix, what, err.msg);
    pf_scene_destroy(&sc);
}

static void test_bad_files(void)
{
    static const bad_case_t cases[] = {
        { "syntax.json", 5, "JSON syntax error near '\"fov\": 40'" },
        { "unknown-key.json", 5, "unknown key 'kdd' in material" },
        { "wrong-type.json", 3, "'fov' in camera must be a number, not a string" },
        { "negative-albedo.json", 5, "'kd' in material must lie in [0, 1]" },
        { "fov-zero.json", 5, "'fov' in camera must be in (0, 180)" },
        { "ior-zero.json", 5, "'ior' in material must be > 0" },
        { "unknown-material.json", 6, "unknown material 'whte' in quad" },
        { "missing-obj.json", 4, "cannot open obj 'tests/data/json/bad/no-such-model.obj'" },
        { "duplicate-material.json", 5, "duplicate material name 'white'" },
        { "sphere-nonuniform.json", 7, "must scale uniformly" },
        { "array-element.json", 6, "'position' in point light: element 2 must be a number, not a string" },
        { "u64-overflow.json", 4, "'caustic_photons' in render must be an integer from 0 to 2^53" },
    };
    for (size_t i = 0; i < sizeof cases / sizeof cases[0]; i++) {
        char path[256];
        snprintf(path, sizeof path, "tests/data/json/bad/%s", cases[i].file);
        s_expect_error(path, cases[i].line, cases[i].what);
    }
}

typedef struct inline_case {
    int line;
    const char *what;
    const char *text;
} inline_case_t;

/* Variants written to a temporary folder: each text's error line is given. */
static void test_bad_inline(void)
{
    static const inline_case_t cases[] = {
        { 1, "the scene (top level) must be an object, not an array", "[1, 2]\n" },
        { 3, "JSON syntax error near the end of the file", "{\n  \"camera\": {\n" },
        { 1, "JSON syntax error near ','", "{ \"render\": { \"spp\": 4, },\n  \"x\": 1 }\n" },
        { 1, "JSON syntax error near 'garbage'", "{} garbage\n" },
        { 2, "unknown key 'objets' in the scene (top level)", "{\n \"objets\": []\n}\n" },
        { 3, "duplicate key 'spp' in render", "{ \"render\": {\n  \"spp\": 1,\n  \"spp\": 2 } }\n" },
        { 2, "'photons' in render must be an integer from 0 to 2^53 (got -1)", "{ \"render\":\n { \"photons\": -1 } }\n" },
        { 1, "'seed' in render must be an integer from 0 to 2^53 (got 1.5)", "{ \"render\": { \"seed\": 1.5 } }\n" },
        { 1, "'photons' in render must be an integer from 0 to 2^53 (got 1e+20)", "{ \"render\": { \"photons\": 1e20 } }\n" },
        { 1, "'spp' in render must be an integer from 1 to", "{ \"render\": { \"spp\": 0 } }\n" },
        /* cJSON accepts a raw line break inside a string; the line count must too. */
        { 3, "'spp' in render must be an integer from 1 to", "{ \"render\": { \"comment\": \"two\nlines\",\n \"spp\": 0 } }\n" },
        { 1, "'width' in render must be an integer", "{ \"render\": { \"width\": 2.5 } }\n" },
        { 1, "'exposure' in render must be finite", "{ \"render\": { \"exposure\": 1e999 } }\n" },
        { 1, "'caustic_radius' in render must be >= 0", "{ \"render\": { \"caustic_radius\": -1 } }\n" },
        { 2, "camera is missing the required key 'look_at'", "{\n \"camera\": {\n  \"position\": [0, 0, 1] } }\n" },
        { 1, "'look_at' in camera must differ from 'position'",
          "{ \"camera\": { \"position\": [0, 0, 1], \"look_at\": [0, 0, 1] } }\n" },
        { 1, "'up' must not be parallel", "{ \"camera\": { \"position\": [0, 0, 1], \"look_at\": [0, 0, 0], \"up\": [0, 0, 2] } }\n" },
        { 1, "'position' in camera must be an array of 3 numbers", "{ \"camera\": { \"position\": [0, 1], \"look_at\": [0, 0, 0] } }\n" },
        { 1, "camera must be an object, not a number", "{ \"camera\": 3 }\n" },
        { 2, "'materials' must be an array, not an object", "{\n \"materials\": {} }\n" },
        { 2, "material is missing the required key 'name'", "{ \"materials\": [\n { \"kd\": 0.5 } ] }\n" },
        { 2, "unknown material type 'metal'", "{ \"materials\": [ { \"name\": \"a\",\n \"type\": \"metal\" } ] }\n" },
        { 2, "key 'ior' does not apply to a diffuse material", "{ \"materials\": [ { \"name\": \"a\",\n \"ior\": 1.5 } ] }\n" },
        { 2, "key 'kd' does not apply to a mirror material",
          "{ \"materials\": [ { \"name\": \"a\", \"type\": \"mirror\",\n \"kd\": 0.5 } ] }\n" },
        { 1, "'ns' in material must be >= 0", "{ \"materials\": [ { \"name\": \"a\", \"ns\": -1 } ] }\n" },
        { 1, "'emission' in material must be >= 0", "{ \"materials\": [ { \"name\": \"a\", \"emission\": [1, -1, 1] } ] }\n" },
        { 1, "'ks' in material must lie in [0, 1]", "{ \"materials\": [ { \"name\": \"a\", \"type\": \"mirror\", \"ks\": 1.5 } ] }\n" },
        { 1, "'kt' in material must be an RGB array", "{ \"materials\": [ { \"name\": \"a\", \"type\": \"glass\", \"kt\": \"clear\" } ] }\n" },
        { 1, "kd + ks exceeds 1", "{ \"materials\": [ { \"name\": \"a\", \"kd\": 0.6, \"ks\": 0.6 } ] }\n" },
        { 1, "'name' in material must not be empty", "{ \"materials\": [ { \"name\": \"\" } ] }\n" },
        { 2, "object is missing the required key 'type'", "{ \"objects\": [\n { \"file\": \"x.obj\" } ] }\n" },
        { 1, "unknown object type 'cube'", "{ \"objects\": [ { \"type\": \"cube\" } ] }\n" },
        { 3, "sphere is missing the required key 'radius'",
          "{ \"materials\": [ { \"name\": \"m\" } ],\n \"objects\": [\n { \"type\": \"sphere\",\n \"center\": [0, 0, 0], \"material\": \"m\" } ] }\n" },
        { 2, "'radius' in sphere must be > 0",
          "{ \"materials\": [ { \"name\": \"m\" } ], \"objects\": [ { \"type\": \"sphere\", \"center\": [0, 0, 0],\n \"radius\": 0, \"material\": \"m\" } ] }\n" },
        { 2, "must scale uniformly",
          "{ \"materials\": [ { \"name\": \"m\" } ], \"objects\": [ { \"type\": \"sphere\", \"center\": [0, 0, 0], \"radius\": 1, \"material\": \"m\", \"transform\":\n { \"matrix\": [1, 0.5, 0, 0, 0, 1, 0, 0, 0, 0, 1, 0] } } ] }\n" },
        { 2, "quad has no area",
          "{ \"materials\": [ { \"name\": \"m\" } ], \"objects\": [\n { \"type\": \"quad\", \"origin\": [0, 0, 0], \"edge1\": [1, 0, 0], \"edge2\": [2, 0, 0], \"material\": \"m\" } ] }\n" },
        { 2, "unknown key 'rotation' in transform",
          "{ \"materials\": [ { \"name\": \"m\" } ], \"objects\": [ { \"type\": \"quad\", \"origin\": [0, 0, 0], \"edge1\": [1, 0, 0], \"edge2\": [0, 1, 0], \"material\": \"m\", \"transform\": {\n \"rotation\": [0, 90, 0] } } ] }\n" },
        { 2, "'scale' cannot be combined with 'matrix'",
          "{ \"materials\": [ { \"name\": \"m\" } ], \"objects\": [ { \"type\": \"quad\", \"origin\": [0, 0, 0], \"edge1\": [1, 0, 0], \"edge2\": [0, 1, 0], \"material\": \"m\", \"transform\": { \"matrix\": [1, 0, 0, 0, 0, 1, 0, 0, 0, 0, 1, 0],\n \"scale\": 2 } } ] }\n" },
        { 2, "the last row must be 0 0 0 1",
          "{ \"materials\": [ { \"name\": \"m\" } ], \"objects\": [ { \"type\": \"quad\", \"origin\": [0, 0, 0], \"edge1\": [1, 0, 0], \"edge2\": [0, 1, 0], \"material\": \"m\", \"transform\": {\n \"matrix\": [1, 0, 0, 0, 0, 1, 0, 0, 0, 0, 1, 0, 0, 0, 1, 1] } } ] }\n" },
        { 2, "12 or 16 numbers",
          "{ \"materials\": [ { \"name\": \"m\" } ], \"objects\": [ { \"type\": \"quad\", \"origin\": [0, 0, 0], \"edge1\": [1, 0, 0], \"edge2\": [0, 1, 0], \"material\": \"m\", \"transform\": {\n \"matrix\": [1, 0, 0] } } ] }\n" },
        { 2, "'scale' in transform must not be zero",
          "{ \"materials\": [ { \"name\": \"m\" } ], \"objects\": [ { \"type\": \"quad\", \"origin\": [0, 0, 0], \"edge1\": [1, 0, 0], \"edge2\": [0, 1, 0], \"material\": \"m\", \"transform\": {\n \"scale\": [1, 0, 1] } } ] }\n" },
        { 2, "the transform is singular",
          "{ \"materials\": [ { \"name\": \"m\" } ], \"objects\": [ { \"type\": \"quad\", \"origin\": [0, 0, 0], \"edge1\": [1, 0, 0], \"edge2\": [0, 1, 0], \"material\": \"m\", \"transform\": {\n \"matrix\": [1, 0, 0, 0, 1, 0, 0, 0, 0, 0, 1, 0] } } ] }\n" },
        { 2, "ply object is missing the required key 'material'", "{ \"objects\": [\n { \"type\": \"ply\", \"file\": \"x.ply\" } ] }\n" },
        { 2, "'material' (one for all) or 'materials' (a map), not both",
          "{ \"materials\": [ { \"name\": \"m\" } ], \"objects\": [ { \"type\": \"obj\", \"file\": \"x.obj\", \"material\": \"m\",\n \"materials\": { \"a\": \"m\" } } ] }\n" },
        { 3, "duplicate key 'a' in 'materials'",
          "{ \"materials\": [ { \"name\": \"m\" } ], \"objects\": [ { \"type\": \"obj\", \"file\": \"x.obj\",\n \"materials\": { \"a\": \"m\",\n \"a\": \"m\" } } ] }\n" },
        { 2, "light is missing the required key 'type'", "{ \"lights\": [\n { \"position\": [0, 0, 0] } ] }\n" },
        { 1, "unknown light type 'area'", "{ \"lights\": [ { \"type\": \"area\" } ] }\n" },
        { 2, "unknown key 'direction' in point light",
          "{ \"lights\": [ { \"type\": \"point\", \"position\": [0, 0, 0], \"intensity\": 1,\n \"direction\": [0, -1, 0] } ] }\n" },
        { 2, "'angle' in spot light must be in (0, 90]",
          "{ \"lights\": [ { \"type\": \"spot\", \"position\": [0, 0, 0], \"direction\": [0, -1, 0], \"intensity\": 1,\n \"angle\": 120 } ] }\n" },
        { 2, "'falloff_start' in spot light must be in [0, angle]",
          "{ \"lights\": [ { \"type\": \"spot\", \"position\": [0, 0, 0], \"direction\": [0, -1, 0], \"intensity\": 1, \"angle\": 30,\n \"falloff_start\": 40 } ] }\n" },
        { 2, "'direction' in distant light must not be zero",
          "{ \"lights\": [ { \"type\": \"distant\",\n \"direction\": [0, 0, 0], \"irradiance\": 1 } ] }\n" },
        { 2, "distant light is missing the required key 'irradiance'",
          "{ \"lights\": [\n { \"type\": \"distant\", \"direction\": [0, -1, 0] } ] }\n" },
        { 2, "unknown key 'direction' in infinite light",
          "{ \"lights\": [ { \"type\": \"infinite\", \"radiance\": 1,\n \"direction\": [0, -1, 0] } ] }\n" },
        { 2, "unknown key 'position' in distant light",
          "{ \"lights\": [ { \"type\": \"distant\", \"direction\": [0, -1, 0], \"irradiance\": 1,\n \"position\": [0, 0, 0] } ] }\n" },
        { 2, "'direction' in spot light must not be zero",
          "{ \"lights\": [ { \"type\": \"spot\", \"position\": [0, 0, 0],\n \"direction\": [0, 0, 0], \"intensity\": 1, \"angle\": 30 } ] }\n" },
        { 3, "'intensity' in point light must be >= 0",
          "{ \"lights\": [ { \"type\": \"point\", \"position\": [0, 0, 0],\n \"comment\": \"a string with \\\"escapes\\\" and \\n and ] } {\",\n \"intensity\": -1 } ] }\n" },
        { 2, "'comment' in camera must be a string", "{ \"camera\": { \"position\": [0, 0, 1], \"look_at\": [0, 0, 0],\n \"comment\": 5 } }\n" },
        { 3, "'lens_radius' in camera must be >= 0 and at most 1e18 (got -0.5)",
          "{ \"camera\": { \"position\": [0, 0, 1],\n \"look_at\": [0, 0, 0],\n \"lens_radius\": -0.5 } }\n" },
        { 2, "'lens_radius' in camera must be >= 0 and at most 1e18 (got 1e+30)",
          "{ \"camera\": { \"position\": [0, 0, 1], \"look_at\": [0, 0, 0],\n \"lens_radius\": 1e30 } }\n" },
        { 2, "'lens_radius' in camera must be a number, not a string",
          "{ \"camera\": { \"position\": [0, 0, 1], \"look_at\": [0, 0, 0],\n \"lens_radius\": \"wide\" } }\n" },
        { 3, "'focal_distance' in camera must be > 0 and at most 1e18 (got 0)",
          "{ \"camera\": { \"position\": [0, 0, 1], \"look_at\": [0, 0, 0],\n \"lens_radius\": 0.1,\n \"focal_distance\": 0 } }\n" },
        { 2, "'focal_distance' in camera must be > 0 and at most 1e18 (got -3)",
          "{ \"camera\": { \"position\": [0, 0, 1], \"look_at\": [0, 0, 0], \"lens_radius\": 0.1,\n \"focal_distance\": -3 } }\n" },
        { 2, "'focal_distance' in camera must be finite",
          "{ \"camera\": { \"position\": [0, 0, 1], \"look_at\": [0, 0, 0], \"lens_radius\": 0.1,\n \"focal_distance\": 1e999 } }\n" },
        { 2, "unknown key 'aperture' in camera",
          "{ \"camera\": { \"position\": [0, 0, 1], \"look_at\": [0, 0, 0],\n \"aperture\": 2 } }\n" },
    };
    char dir[] = "/tmp/pf_scene_json_XXXXXX";
    if (!mkdtemp(dir)) {
        CHECK(0, "mkdtemp failed");
        return;
    }
    char path[128];
    snprintf(path, sizeof path, "%s/case.json", dir);
    for (size_t i = 0; i < sizeof cases / sizeof cases[0]; i++) {
        FILE *f = fopen(path, "wb");
        if (!f) {
            CHECK(0, "cannot write %s", path);
            break;
        }
        fputs(cases[i].text, f);
        fclose(f);
        s_expect_error(path, cases[i].line, cases[i].what);
    }
    remove(path);
    rmdir(dir);
}

/* Loads text as a JSON scene file (in a temporary folder, not finalized);
 * NULL with err filled on failure. */
static pf_scene_t *s_json_text(const char *text, pf_error_t *err)
{
    char dir[] = "/tmp/pf_scene_json_XXXXXX";
    if (!mkdtemp(dir)) {
        snprintf(err->msg, sizeof err->msg, "mkdtemp failed");
        return NULL;
    }
    char path[128];
    snprintf(path, sizeof path, "%s/lens.json", dir);
    FILE *f = fopen(path, "wb");
    pf_scene_t *sc = NULL;
    if (f) {
        fputs(text, f);
        fclose(f);
        sc = s_json(path, err);
    }
    remove(path);
    rmdir(dir);
    return sc;
}

/* The camera's thin-lens keys land in pf_camera_desc_t; without them the
 * camera's extras stay all zero (the pinhole every older scene renders with);
 * a lens without "focal_distance" focuses at the look-at point. */
static void test_camera_lens(void)
{
    pf_error_t err = { { 0 } };
    pf_scene_t *sc = s_json_text("{ \"camera\": { \"position\": [0, 1, 6.8], \"look_at\": [0, 1, 0], \"fov\": 19.5,\n"
                                 "  \"lens_radius\": 0.05, \"focal_distance\": 6.25 } }\n",
                                 &err);
    CHECK(sc && sc->camera.lens_radius == 0.05f && sc->camera.focal_distance == 6.25f && sc->camera.vfov_deg == 19.5f,
          "lens_radius and focal_distance land: %s", sc ? "" : err.msg);
    pf_scene_destroy(&sc);
    sc = s_json_text("{ \"camera\": { \"position\": [3, 0, 4], \"look_at\": [0, 0, 0], \"lens_radius\": 0.1 } }\n", &err);
    CHECK(sc && sc->camera.lens_radius == 0.1f && sc->camera.focal_distance == 5.0f,
          "a lens without focal_distance focuses at look_at (5): got %g", sc ? (double)sc->camera.focal_distance : -1.0);
    pf_scene_destroy(&sc);
    sc = s_json_text("{ \"camera\": { \"position\": [3, 0, 4], \"look_at\": [0, 0, 0] } }\n", &err);
    CHECK(sc && sc->camera.lens_radius == 0.0f && sc->camera.focal_distance == 0.0f && sc->camera.fov_shorter == 0 &&
              sc->camera.left_handed == 0,
          "no lens keys: a pinhole with all-zero extras");
    pf_scene_destroy(&sc);
    sc = s_json_text("{ \"camera\": { \"position\": [3, 0, 4], \"look_at\": [0, 0, 0], \"lens_radius\": 0,"
                     " \"focal_distance\": 2 } }\n",
                     &err);
    CHECK(sc && sc->camera.lens_radius == 0.0f && sc->camera.focal_distance == 2.0f,
          "lens_radius 0 with a focal distance: kept, a pinhole");
    pf_scene_destroy(&sc);
}

/* A thin dielectric: glass's keys and defaults (ks 1), its own type;
 * keys of other kinds are errors. */
static void test_thin_dielectric(void)
{
    pf_error_t err = { { 0 } };
    pf_scene_t *sc = s_json_text("{ \"materials\": [ { \"name\": \"window\", \"type\": \"thindielectric\",\n"
                                 "  \"ior\": 1.52, \"kt\": [0.9, 0.95, 1] } ] }\n",
                                 &err);
    CHECK(sc && sc->nmats == 1, "a thin dielectric loads: %s", sc ? "" : err.msg);
    if (sc && sc->nmats == 1) {
        const pf_material_t *m = &sc->mats[0];
        CHECK(m->type == PF_MAT_THIN_DIELECTRIC && m->ior == 1.52f && near3(m->ks, pf_v3s(1.0f), 0) &&
                  near3(m->kt, pf_v3(0.9f, 0.95f, 1.0f), 0) && pf_is_black(m->kd),
              "window type %d ior %g ks " V3F " kt " V3F, (int)m->type, (double)m->ior, V3A(m->ks), V3A(m->kt));
    }
    pf_scene_destroy(&sc);
    sc = s_json_text("{ \"materials\": [ { \"name\": \"w\", \"type\": \"thindielectric\", \"kd\": 0.5 } ] }\n", &err);
    CHECK(!sc && strstr(err.msg, "key 'kd' does not apply to a thindielectric material"), "kd on a pane: %s", err.msg);
    pf_scene_destroy(&sc);
    /* a glass solid's absorbing inside: "absorption" per unit length, on glass only */
    sc = s_json_text("{ \"materials\": [ { \"name\": \"tea\", \"type\": \"glass\", \"ior\": 1.33,\n"
                     "  \"absorption\": [0.1, 0.3, 0.7] } ] }\n",
                     &err);
    CHECK(sc && sc->nmats == 1 && near3(sc->mats[0].sigma_in, pf_v3(0.1f, 0.3f, 0.7f), 0) &&
              pf_is_black(sc->mats[0].sigma_out),
          "absorption: %s", sc ? "" : err.msg);
    pf_scene_destroy(&sc);
    sc = s_json_text("{ \"materials\": [ { \"name\": \"w\", \"type\": \"thindielectric\", \"absorption\": 1 } ] }\n",
                     &err);
    CHECK(!sc && strstr(err.msg, "key 'absorption' does not apply to a thindielectric material"), "%s", err.msg);
    sc = s_json_text("{ \"materials\": [ { \"name\": \"g\", \"type\": \"glass\", \"absorption\": [1, -1, 1] } ] }\n",
                     &err);
    CHECK(!sc && strstr(err.msg, "absorption"), "a negative absorption: %s", err.msg);
}

/* The coated diffuse: kd, ior, roughness, thickness (default 0: lossless);
 * keys of other kinds and bad ranges are errors. */
static void test_coated(void)
{
    pf_error_t err = { { 0 } };
    pf_scene_t *sc = s_json_text("{ \"materials\": [ { \"name\": \"lacquer\", \"type\": \"coated\",\n"
                                 "  \"kd\": [0.5, 0.2, 0.1], \"ior\": 1.6, \"roughness\": 0.1, \"thickness\": 0.01 },\n"
                                 "  { \"name\": \"plain\", \"type\": \"coated\" } ] }\n",
                                 &err);
    CHECK(sc && sc->nmats == 2, "coated loads: %s", sc ? "" : err.msg);
    if (sc && sc->nmats == 2) {
        const pf_material_t *m = &sc->mats[0], *p = &sc->mats[1];
        CHECK(m->type == PF_MAT_COATED && m->ior == 1.6f && m->alpha == 0.1f && m->thickness == 0.01f &&
                  near3(m->kd, pf_v3(0.5f, 0.2f, 0.1f), 0),
              "lacquer type %d ior %g alpha %g thickness %g", (int)m->type, (double)m->ior, (double)m->alpha,
              (double)m->thickness);
        CHECK(p->type == PF_MAT_COATED && p->ior == 1.5f && p->alpha == 0.0f && p->thickness == 0.0f,
              "defaults: ior %g alpha %g thickness %g", (double)p->ior, (double)p->alpha, (double)p->thickness);
    }
    pf_scene_destroy(&sc);
    sc = s_json_text("{ \"materials\": [ { \"name\": \"c\", \"type\": \"coated\", \"ks\": 0.5 } ] }\n", &err);
    CHECK(!sc && strstr(err.msg, "key 'ks' does not apply to a coated material"), "ks on coated: %s", err.msg);
    pf_scene_destroy(&sc);
    sc = s_json_text("{ \"materials\": [ { \"name\": \"c\", \"type\": \"coated\", \"thickness\": -1 } ] }\n", &err);
    CHECK(!sc && strstr(err.msg, "'thickness' in material must be >= 0"), "negative thickness: %s", err.msg);
    pf_scene_destroy(&sc);
    sc = s_json_text("{ \"materials\": [ { \"name\": \"c\", \"type\": \"coated\", \"ior\": 0.8 } ] }\n", &err);
    CHECK(!sc && strstr(err.msg, "'ior' must be >= 1"), "ior below 1: %s", err.msg);
    pf_scene_destroy(&sc);
}

/* diffusetransmission (kd, kt, pbrt's 0.25 defaults, kd + kt <= 1), mix
 * (two earlier materials and an amount) and "dielectric" as glass. */
static void test_mix_difftrans(void)
{
    pf_error_t err = { { 0 } };
    pf_scene_t *sc = s_json_text(
        "{ \"materials\": [ { \"name\": \"leaf\", \"type\": \"diffusetransmission\", \"kd\": [0.2, 0.3, 0.4],\n"
        "  \"kt\": [0.7, 0.6, 0.5] }, { \"name\": \"paper\", \"type\": \"diffusetransmission\" },\n"
        "  { \"name\": \"g\", \"type\": \"dielectric\", \"ior\": 1.4 },\n"
        "  { \"name\": \"m\", \"type\": \"mix\", \"materials\": [\"g\", \"leaf\"], \"amount\": 0.25 },\n"
        "  { \"name\": \"half\", \"type\": \"mix\", \"materials\": [\"m\", \"paper\"] } ] }\n",
        &err);
    CHECK(sc && sc->nmats == 5, "mix and diffusetransmission load: %s", sc ? "" : err.msg);
    if (sc && sc->nmats == 5) {
        const pf_material_t *l = &sc->mats[0], *p = &sc->mats[1], *g = &sc->mats[2], *m = &sc->mats[3],
                            *h = &sc->mats[4];
        CHECK(l->type == PF_MAT_DIFFUSE_TRANSMISSION && near3(l->kd, pf_v3(0.2f, 0.3f, 0.4f), 0) &&
                  near3(l->kt, pf_v3(0.7f, 0.6f, 0.5f), 0),
              "leaf: type %d", (int)l->type);
        CHECK(p->type == PF_MAT_DIFFUSE_TRANSMISSION && near3(p->kd, pf_v3s(0.25f), 0) &&
                  near3(p->kt, pf_v3s(0.25f), 0),
              "defaults 0.25, 0.25");
        CHECK(g->type == PF_MAT_GLASS && g->ior == 1.4f, "dielectric is glass");
        CHECK(m->type == PF_MAT_MIX && m->mix[0] == 2 && m->mix[1] == 0 && m->amount == 0.25f, "mix %u %u %g",
              (unsigned)m->mix[0], (unsigned)m->mix[1], (double)m->amount);
        CHECK(h->type == PF_MAT_MIX && h->mix[0] == 3 && h->mix[1] == 1 && h->amount == 0.5f, "a mix of a mix");
    }
    pf_scene_destroy(&sc);
    const char *bad[][2] = {
        { "{ \"materials\": [ { \"name\": \"a\", \"type\": \"diffusetransmission\", \"kd\": 0.6, \"kt\": 0.5 } ] }\n",
          "kd + kt exceeds 1" },
        { "{ \"materials\": [ { \"name\": \"a\", \"type\": \"diffusetransmission\", \"ior\": 1.5 } ] }\n",
          "key 'ior' does not apply" },
        { "{ \"materials\": [ { \"name\": \"a\", \"type\": \"mix\", \"materials\": [\"a\", \"a\"] } ] }\n",
          "no material named 'a' before it" },
        { "{ \"materials\": [ { \"name\": \"b\" }, { \"name\": \"a\", \"type\": \"mix\", \"materials\": [\"b\"] } ] }\n",
          "an array of two material names" },
        { "{ \"materials\": [ { \"name\": \"b\" }, { \"name\": \"a\", \"type\": \"mix\" } ] }\n", "materials" },
        { "{ \"materials\": [ { \"name\": \"b\" }, { \"name\": \"a\", \"type\": \"mix\", \"materials\": [\"b\", \"b\"],"
          " \"amount\": 1.5 } ] }\n",
          "'amount' in material must lie in [0, 1]" },
    };
    for (size_t i = 0; i < sizeof bad / sizeof *bad; i++) {
        sc = s_json_text(bad[i][0], &err);
        CHECK(!sc && strstr(err.msg, bad[i][1]), "case %zu: %s", i, sc ? "loaded" : err.msg);
        pf_scene_destroy(&sc);
    }
}

/* The conductor's keys: "eta" + "k" land as given, "reflectance" becomes
 * eta 1 and the k of that normal-incidence reflectance, "roughness" is the
 * GGX alpha (default 0); errors for both forms, neither, or bad ranges. */
static void test_conductor(void)
{
    pf_error_t err = { { 0 } };
    pf_scene_t *sc = s_json_text("{ \"materials\": [ { \"name\": \"gold\", \"type\": \"conductor\",\n"
                                 "  \"eta\": [0.14, 0.37, 1.44], \"k\": [3.98, 2.38, 1.60], \"roughness\": 0.2 },\n"
                                 "  { \"name\": \"chrome\", \"type\": \"conductor\", \"reflectance\": [0.5, 0.25, 0] } ] }\n",
                                 &err);
    CHECK(sc && sc->nmats == 2, "two conductors load: %s", sc ? "" : err.msg);
    if (sc && sc->nmats == 2) {
        const pf_material_t *g = &sc->mats[0], *c = &sc->mats[1];
        CHECK(g->type == PF_MAT_CONDUCTOR && g->alpha == 0.2f && g->eta.y == 0.37f && g->k.z == 1.60f,
              "eta, k, roughness land (type %d alpha %g)", (int)g->type, g->alpha);
        /* r = ((eta-1)^2 + k^2) / ((eta+1)^2 + k^2) with eta 1: k^2 / (4 + k^2) */
        float k = c->k.x, r = k * k / (4.0f + k * k);
        CHECK(c->type == PF_MAT_CONDUCTOR && c->alpha == 0.0f && c->eta.x == 1.0f && fabsf(r - 0.5f) < 1e-5f &&
                  c->k.z == 0.0f && fabsf(c->k.y * c->k.y / (4.0f + c->k.y * c->k.y) - 0.25f) < 1e-5f,
              "reflectance 0.5 -> eta 1, k %g (r %g)", k, r);
    }
    pf_scene_destroy(&sc);
    static const struct {
        const char *text, *want;
    } bad[] = {
        { "{ \"materials\": [ { \"name\": \"a\", \"type\": \"conductor\" } ] }\n", "needs 'eta' and 'k', or 'reflectance'" },
        { "{ \"materials\": [ { \"name\": \"a\", \"type\": \"conductor\", \"eta\": 1 } ] }\n", "needs 'eta' and 'k'" },
        { "{ \"materials\": [ { \"name\": \"a\", \"type\": \"conductor\", \"eta\": 1, \"k\": 1, \"reflectance\": 0.5 } ] }\n",
          "not both" },
        { "{ \"materials\": [ { \"name\": \"a\", \"type\": \"conductor\", \"eta\": 0, \"k\": 1 } ] }\n",
          "'eta' in material must be > 0" },
        { "{ \"materials\": [ { \"name\": \"a\", \"type\": \"conductor\", \"eta\": 1, \"k\": -1 } ] }\n",
          "'k' in material must be >= 0" },
        { "{ \"materials\": [ { \"name\": \"a\", \"type\": \"conductor\", \"reflectance\": 1.5 } ] }\n",
          "'reflectance' in material must lie in [0, 1]" },
        { "{ \"materials\": [ { \"name\": \"a\", \"type\": \"conductor\", \"reflectance\": 0.5, \"roughness\": 2 } ] }\n",
          "'roughness' in material must lie in [0, 1]" },
        { "{ \"materials\": [ { \"name\": \"a\", \"type\": \"conductor\", \"reflectance\": 0.5, \"kd\": 0.5 } ] }\n",
          "key 'kd' does not apply to a conductor material" },
        { "{ \"materials\": [ { \"name\": \"a\", \"roughness\": 0.5 } ] }\n", "key 'roughness' does not apply to a diffuse" },
    };
    for (size_t i = 0; i < sizeof bad / sizeof bad[0]; i++) {
        sc = s_json_text(bad[i].text, &err);
        CHECK(!sc && strstr(err.msg, bad[i].want), "case %zu: want '%s', got '%s'", i, bad[i].want, sc ? "" : err.msg);
        pf_scene_destroy(&sc);
    }
}

/* The "materials" map must name MTL materials the model uses; both models.json
 * loaders are needed, so this is separate from the inline cases above. */
static void test_remap_errors(void)
{
    char dir[] = "/tmp/pf_scene_json_XXXXXX";
    if (!mkdtemp(dir)) {
        CHECK(0, "mkdtemp failed");
        return;
    }
    char path[128], model[256];
    snprintf(path, sizeof path, "%s/case.json", dir);
    char *cwd = getcwd(NULL, 0);
    snprintf(model, sizeof model, "%s/tests/data/json/model.obj", cwd ? cwd : ".");
    free(cwd);
    FILE *f = fopen(path, "wb");
    if (f) {
        fprintf(f,
                "{ \"materials\": [ { \"name\": \"m\" } ],\n"
                "  \"objects\": [ { \"type\": \"obj\", \"file\": \"%s\", \"materials\": {\n"
                "    \"mtlA\": \"m\",\n"
                "    \"mtlX\": \"m\" } } ] }\n",
                model);
        fclose(f);
        s_expect_error(path, 4, "'mtlX' in 'materials'");
        f = fopen(path, "wb");
    }
    if (f) {
        fprintf(f,
                "{ \"materials\": [ { \"name\": \"m\" } ],\n"
                "  \"objects\": [ { \"type\": \"obj\", \"file\": \"%s\", \"materials\": {\n"
                "    \"mtlA\": \"nope\" } } ] }\n",
                model);
        fclose(f);
        s_expect_error(path, 3, "unknown material 'nope'");
    }
    remove(path);
    rmdir(dir);
}

/* Every truncation of prims.json, and copies with bytes overwritten, must
 * fail (or load) cleanly: an error names the file, nothing crashes (run under
 * PF_SANITIZE to catch memory errors). */
static void test_corruptions(void)
{
    FILE *f = fopen("tests/data/json/prims.json", "rb");
    CHECK(f != NULL, "open prims.json");
    if (!f)
        return;
    static char text[16384];
    size_t len = fread(text, 1, sizeof text, f);
    fclose(f);
    size_t end = len; /* the closing brace: cutting after it leaves valid JSON */
    while (end > 0 && text[end - 1] != '}')
        end--;
    char dir[] = "/tmp/pf_scene_json_XXXXXX";
    if (!mkdtemp(dir)) {
        CHECK(0, "mkdtemp failed");
        return;
    }
    char path[128];
    snprintf(path, sizeof path, "%s/case.json", dir);
    int trunc_ok = 1, mut_ok = 1;
    uint32_t rng = 12345;
    static const char junk[] = "{}[],:\"\\-0e.9 \nxtfn\x01\xff";
    for (size_t i = 0; i < end + 300; i++) {
        static char buf[16384];
        size_t n = len;
        memcpy(buf, text, len);
        if (i < end) {
            n = i; /* a truncation */
        } else {
            for (int k = 0; k < 3; k++) { /* three overwritten bytes */
                rng = rng * 1664525u + 1013904223u;
                size_t at = (rng >> 8) % len;
                rng = rng * 1664525u + 1013904223u;
                buf[at] = junk[(rng >> 8) % (sizeof junk - 1)];
            }
        }
        f = fopen(path, "wb");
        if (!f)
            break;
        fwrite(buf, 1, n, f);
        fclose(f);
        pf_error_t err = { { 0 } };
        pf_scene_t *sc = pf_scene_create();
        int rc = pf_scene_json_load(sc, path, &err);
        int named = strncmp(err.msg, path, strlen(path)) == 0;
        if (i < end && (rc >= 0 || !named)) {
            if (trunc_ok)
                printf("truncation at %zu: rc %d, \"%s\"\n", i, rc, err.msg);
            trunc_ok = 0;
        }
        if (i >= end && rc < 0 && !named)
            mut_ok = 0;
        pf_scene_destroy(&sc);
    }
    CHECK(trunc_ok, "every truncation fails with an error naming the file");
    CHECK(mut_ok, "every corrupted copy that fails names the file");
    remove(path);
    rmdir(dir);
}

int main(void)
{
    double t0 = pf_now();
    pf_log_set_level(PF_LOG_ERROR);
    test_prims();
    test_bad_files();
    test_bad_inline();
    test_camera_lens();
    test_conductor();
    test_thin_dielectric();
    test_coated();
    test_mix_difftrans();
    test_models();
    test_remap_errors();
    test_corruptions();
    test_shipped();
    /* Not a check: wall time depends on the machine's load. Normally ~0.1 s. */
    printf("scene_json: %.2f s\n", pf_now() - t0);
    printf("%d passed, %d failed\n", s_passed, s_failed);
    return s_failed ? 1 : 0;
}
