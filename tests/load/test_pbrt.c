/* test_pbrt.c: self-test of the pbrt-v4 reader (load/pbrt/). Small pbrt
 * texts written to a temporary folder: every transform directive against
 * hand-computed points, the emitting side of meshes, spheres, disks and
 * bilinear patches under ReverseOrientation and mirroring transforms,
 * the graphics-state stack, named and anonymous materials and their
 * mapping, object instances, Include paths and recursion, syntax errors
 * with their exact line and column, the warnings report and --strict, a
 * .ply.gz read equal to its .ply, the camera; then the two Bitterli scenes
 * in ../shared/scenes (skipped when absent). Run from the repository root
 * (ctest does). */
#include <math.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/stat.h>
#include <unistd.h>
#include <zlib.h>

#include "base/log.h"
#include "check.h"
#include "load/load.h"
#include "scene/scene.h"

#include "pbrt_text.h"

/* The side a triangle emits to, as light.c decides it. */
static pf_vec3 s_emit_normal(const pf_mesh_t *m, size_t t)
{
    const uint32_t *v = &m->idx[3 * t];
    pf_vec3 n = pf_norm(pf_cross(pf_sub(m->pos[v[1]], m->pos[v[0]]), pf_sub(m->pos[v[2]], m->pos[v[0]])));
    if (m->nrm)
        n = pf_face_forward(n, pf_add(pf_add(m->nrm[v[0]], m->nrm[v[1]]), m->nrm[v[2]]));
    return n;
}


/* One transform case: directives before the triangle, where (1,2,3) lands. */
static void s_xf(const char *directives, float x, float y, float z)
{
    char text[2048];
    snprintf(text, sizeof text, S_HEAD "%s\n" S_TRI, directives);
    pf_error_t err;
    pf_scene_t *s = s_parse(text, 0, NULL, &err);
    CHECK(s && s->nmeshes == 1, "%s: %s", directives, err.msg);
    if (s && s->nmeshes == 1)
        CHECK(s_vnear(s->meshes[0].pos[0], x, y, z), "%s: got (%g %g %g), want (%g %g %g)", directives,
              s->meshes[0].pos[0].x, s->meshes[0].pos[0].y, s->meshes[0].pos[0].z, x, y, z);
    pf_scene_destroy(&s);
}

static void test_transforms(void)
{
    s_xf("", 1, 2, 3);
    s_xf("Translate 1 2 3", 2, 4, 6);
    s_xf("Scale 2 3 4", 2, 6, 12);
    s_xf("Rotate 90 0 0 1", -2, 1, 3);
    s_xf("Rotate 90 1 0 0", 1, -3, 2);
    s_xf("Rotate 180 0 2 0", -1, 2, -3);
    s_xf("LookAt 1 2 3  1 2 4  0 1 0", 0, 0, 0);
    s_xf("LookAt 0 0 0  1 0 0  0 1 0", -3, 2, 1);
    s_xf("Transform [1 0 0 0  0 1 0 0  0 0 1 0  5 6 7 1]", 6, 8, 10);
    s_xf("Transform [0 1 0 0  -1 0 0 0  0 0 1 0  0 0 0 1]", -2, 1, 3); /* columns: x -> y, y -> -x */
    s_xf("Translate 1 0 0\nConcatTransform [2 0 0 0  0 2 0 0  0 0 2 0  0 0 0 1]", 3, 4, 6);
    s_xf("Translate 1 0 0\nScale 2 2 2", 3, 4, 6);
    s_xf("Scale 2 2 2\nTranslate 1 0 0", 4, 4, 6);
    s_xf("Translate 9 9 9\nIdentity", 1, 2, 3);
    s_xf("Translate 1 1 1\nCoordinateSystem \"a\"\nIdentity\nCoordSysTransform \"a\"", 2, 3, 4);
    /* camera space of LookAt 0 0 5 -> 0 0 0, up y: x is world -x, z world -z. */
    s_xf("CoordSysTransform \"camera\"", -1, 2, 2);
    s_xf("TransformBegin\nTranslate 5 5 5\nTransformEnd", 1, 2, 3);
    s_xf("AttributeBegin\nTranslate 5 5 5\nAttributeEnd", 1, 2, 3);
    s_xf("ActiveTransform EndTime\nTranslate 5 5 5\nActiveTransform All", 1, 2, 3);
}

/* The emitting side of a one-triangle light under the given directives. */
static void s_side(const char *directives, const char *extra, float nz)
{
    char text[2048];
    snprintf(text, sizeof text,
             S_HEAD "%s\nAreaLightSource \"diffuse\" \"rgb L\" [2 3 4]\n"
                    "Shape \"trianglemesh\" \"point3 P\" [0 0 0  1 0 0  0 1 0] %s\n",
             directives, extra);
    pf_error_t err;
    pf_scene_t *s = s_parse(text, 0, NULL, &err);
    CHECK(s && s->nmeshes == 1 && s->nmats == 1, "%s: %s", directives, err.msg);
    if (s && s->nmeshes == 1) {
        const pf_mesh_t *m = &s->meshes[0];
        pf_vec3 n = s_emit_normal(m, 0);
        CHECK(s_vnear(n, 0, 0, nz), "%s %s: emits along (%g %g %g), want z %g", directives, extra, n.x, n.y, n.z, nz);
        CHECK(s_vnear(s->mats[m->mat[0]].le, 2, 3, 4));
    }
    pf_scene_destroy(&s);
}

static void test_winding(void)
{
    s_side("", "", 1);
    s_side("ReverseOrientation", "", -1);
    s_side("Scale 1 1 -1", "", -1);
    s_side("Scale -1 1 1", "", 1); /* the normal goes by M^-T: z stays z */
    s_side("ReverseOrientation\nScale 1 1 -1", "", 1);
    s_side("", "\"integer indices\" [0 2 1]", -1);
    s_side("", "\"normal N\" [0 0 -1  0 0 -1  0 0 -1]", -1);
    s_side("ReverseOrientation", "\"normal N\" [0 0 -1  0 0 -1  0 0 -1]", 1);
    s_side("Rotate 180 1 0 0", "", -1);
}

/* Every triangle of mesh m faces away from c (sign 1) or towards it (-1). */
static int s_all_facing(const pf_mesh_t *m, pf_vec3 c, float sign)
{
    for (size_t t = 0; t < m->ntris; t++) {
        const uint32_t *v = &m->idx[3 * t];
        pf_vec3 mid = pf_scale(pf_add(pf_add(m->pos[v[0]], m->pos[v[1]]), m->pos[v[2]]), 1.0f / 3.0f);
        if (sign * pf_dot(s_emit_normal(m, t), pf_sub(mid, c)) <= 0.0f)
            return 0;
    }
    return 1;
}

static void test_shapes(void)
{
    pf_error_t err;
    pf_load_report_t rep;
    /* Analytic when it may be, emitting or not; tessellated when it is
     * reversed, mirrored and emitting, or not a similarity. */
    pf_scene_t *s = s_parse(S_HEAD "AttributeBegin\nTranslate 1 2 3\nRotate 30 1 1 0\nScale 2 2 2\n"
                                   "Shape \"sphere\" \"float radius\" 0.5\nAttributeEnd\n"
                                   "AttributeBegin\nTranslate 0 5 0\nAreaLightSource \"diffuse\"\n"
                                   "Shape \"sphere\"\nAttributeEnd\n"
                                   "AttributeBegin\nTranslate 0 -5 0\nReverseOrientation\n"
                                   "AreaLightSource \"diffuse\"\nShape \"sphere\"\nAttributeEnd\n"
                                   "AttributeBegin\nTranslate 0 9 0\nScale -1 1 1\n"
                                   "AreaLightSource \"diffuse\" \"float power\" 10\nShape \"sphere\"\nAttributeEnd\n"
                                   "AttributeBegin\nTranslate 0 -9 0\nScale 2 2 2\n"
                                   "AreaLightSource \"diffuse\" \"float power\" 10\nShape \"sphere\"\nAttributeEnd\n"
                                   "Scale 1 2 1\nShape \"sphere\"\n",
                            0, &rep, &err);
    CHECK(s && s->nspheres == 3 && s->nmeshes == 3, "%s", err.msg);
    if (s && s->nspheres == 3 && s->nmeshes == 3) {
        CHECK(s_vnear(s->spheres[0].center, 1, 2, 3) && s_near(s->spheres[0].radius, 1.0f));
        CHECK(pf_is_black(s->mats[s->spheres[0].mat].le));
        CHECK(s_vnear(s->spheres[1].center, 0, 5, 0) && s_near(s->spheres[1].radius, 1.0f) &&
              !pf_is_black(s->mats[s->spheres[1].mat].le), "an emitting sphere stays analytic");
        /* power 10 W over pi 4 pi r^2, r = 2 (pbrt's spectrum normalization aside: the same factor as a mesh's) */
        const pf_material_t *pm = &s->mats[s->spheres[2].mat];
        CHECK(s_vnear(s->spheres[2].center, 0, -9, 0) && s_near(s->spheres[2].radius, 2.0f) &&
              fabs(pf_luminance(pm->le) * M_PI * 4.0 * M_PI * 4.0 / 10.0 - 1.0) < 1e-4,
              "power 10 on a sphere of radius 2: lum(Le) %g", (double)pf_luminance(pm->le));
        CHECK(s->meshes[0].ntris == 3968 && s->meshes[0].nrm != NULL, "%zu triangles", s->meshes[0].ntris);
        CHECK(s_all_facing(&s->meshes[0], pf_v3(0, -5, 0), -1.0f), "a reversed one faces in");
        CHECK(s->meshes[1].ntris == 3968 && !pf_is_black(s->mats[s->meshes[1].mat[0]].le), "a mirrored one is a mesh");
        CHECK(s_all_facing(&s->meshes[2], pf_v3(0, 0, 0), 1.0f), "an ellipsoid faces out");
    }
    CHECK(rep.nwarnings == 0, "%s", rep.nwarnings ? rep.warnings[0].first : "");
    pf_scene_destroy(&s);
    /* Disk (+z), annulus, partial sphere, cylinder, bilinear patch. */
    s = s_parse(S_HEAD "AreaLightSource \"diffuse\"\nShape \"disk\" \"float height\" 1\n"
                       "Shape \"disk\" \"float radius\" 2 \"float innerradius\" 1\n"
                       "Shape \"sphere\" \"float zmin\" 0\n"
                       "Shape \"cylinder\"\n"
                       "Shape \"bilinearmesh\" \"point3 P\" [0 0 0  1 0 0  0 1 0  1 1 0]\n",
                0, &rep, &err);
    CHECK(s && s->nmeshes == 5, "%s", err.msg);
    if (s && s->nmeshes == 5) {
        CHECK(s->meshes[0].ntris == 64 && s_vnear(s_emit_normal(&s->meshes[0], 7), 0, 0, 1));
        CHECK(s_near(s->meshes[0].pos[0].z, 1.0f));
        CHECK(s->meshes[1].ntris == 128 && s_vnear(s_emit_normal(&s->meshes[1], 99), 0, 0, 1));
        CHECK(s_all_facing(&s->meshes[2], pf_v3(0, 0, 0), 1.0f));
        for (size_t i = 0; i < s->meshes[2].nverts; i++)
            CHECK(s->meshes[2].pos[i].z >= -1e-6f);
        const pf_mesh_t *cy = &s->meshes[3];
        int out = cy->ntris == 128;
        for (size_t t = 0; t < cy->ntris; t++) {
            pf_vec3 p = cy->pos[cy->idx[3 * t]], n = s_emit_normal(cy, t);
            out &= fabsf(n.z) < 1e-5f && n.x * p.x + n.y * p.y > 0.0f;
        }
        CHECK(out, "a cylinder faces away from its axis");
        CHECK(s->meshes[4].ntris == 2 && s_vnear(s_emit_normal(&s->meshes[4], 0), 0, 0, 1) &&
              s_vnear(s_emit_normal(&s->meshes[4], 1), 0, 0, 1));
    }
    CHECK(s_warned(&rep, "partial sphere") == 1 && s_warned(&rep, "cylinder") == 1);
    pf_scene_destroy(&s);
}

static void test_state_stack(void)
{
    pf_error_t err;
    pf_scene_t *s = s_parse(S_HEAD "AttributeBegin\nTranslate 5 0 0\nReverseOrientation\n"
                                   "AreaLightSource \"diffuse\"\nMaterial \"conductor\"\nAttributeEnd\n"
                                   "Shape \"trianglemesh\" \"point3 P\" [0 0 0  1 0 0  0 1 0]\n",
                            0, NULL, &err);
    CHECK(s && s->nmeshes == 1 && s->nmats == 1, "%s", err.msg);
    if (s && s->nmeshes == 1 && s->nmats == 1) {
        const pf_material_t *m = &s->mats[0];
        CHECK(s_vnear(s->meshes[0].pos[1], 1, 0, 0), "the transform is restored");
        CHECK(s_vnear(s_emit_normal(&s->meshes[0], 0), 0, 0, 1), "the orientation is restored");
        CHECK(pf_is_black(m->le) && m->type == PF_MAT_DIFFUSE && s_vnear(m->kd, 0.5f, 0.5f, 0.5f),
              "pbrt's default material, no emission");
    }
    pf_scene_destroy(&s);
    s = s_parse(S_HEAD "AttributeBegin\nTransformBegin\nAttributeEnd\n", 0, NULL, &err);
    CHECK(!s && strstr(err.msg, "scene.pbrt:6:1: AttributeEnd closes the TransformBegin of"), "%s", err.msg);
    s = s_parse(S_HEAD "  AttributeEnd\n", 0, NULL, &err);
    CHECK(!s && strstr(err.msg, "scene.pbrt:4:3: AttributeEnd without a matching AttributeBegin"), "%s", err.msg);
    pf_load_report_t rep;
    s = s_parse(S_HEAD "AttributeBegin\n" S_TRI, 0, &rep, &err);
    CHECK(s && s_warned(&rep, "unclosed AttributeBegin") == 1, "%s", err.msg);
    pf_scene_destroy(&s);
}

static const pf_material_t *s_mat(const pf_scene_t *s, const char *name)
{
    int i = pf_scene_find_material(s, name);
    CHECK(i >= 0, "no material '%s'", name);
    return i < 0 ? NULL : &s->mats[i];
}

/* Fresnel reflectance at normal incidence of a conductor. */
static float s_f0(float n, float k) { return ((n - 1) * (n - 1) + k * k) / ((n + 1) * (n + 1) + k * k); }

#define S_SHAPE(m) "NamedMaterial \"" m "\"\n" S_TRI

static void test_materials(void)
{
    pf_error_t err;
    pf_load_report_t rep;
    pf_scene_t *s = s_parse(
        S_HEAD S_SHAPE("later")
        "MakeNamedMaterial \"red\" \"string type\" \"diffuse\" \"rgb reflectance\" [0.8 0 0]\n"
        "MakeNamedMaterial \"cu\" \"string type\" \"conductor\" \"rgb eta\" [0.2 0.9 1.1] \"rgb k\" [3.9 2.4 2.1]\n"
        "MakeNamedMaterial \"au\" \"string type\" \"conductor\" \"spectrum eta\" \"metal-Au-eta\"\n"
        "  \"spectrum k\" \"metal-Au-k\" \"float roughness\" 0.5\n"
        "MakeNamedMaterial \"refl\" \"string type\" \"conductor\" \"rgb reflectance\" [0.9 0.8 0.7]\n"
        "MakeNamedMaterial \"aniso\" \"string type\" \"conductor\" \"float uroughness\" 0.04 \"float vroughness\" 0.16\n"
        "MakeNamedMaterial \"raw\" \"string type\" \"conductor\" \"float roughness\" 0.3 \"bool remaproughness\" false\n"
        "MakeNamedMaterial \"neg\" \"string type\" \"conductor\" \"rgb eta\" [0 0.5 0.5] \"rgb k\" [1 2 1]\n"
        "MakeNamedMaterial \"bk7\" \"string type\" \"dielectric\" \"spectrum eta\" \"glass-BK7\"\n"
        "MakeNamedMaterial \"water\" \"string type\" \"dielectric\" \"float eta\" 1.33\n"
        "MakeNamedMaterial \"pane\" \"string type\" \"thindielectric\" \"float eta\" 1.52\n"
        "MakeNamedMaterial \"coat\" \"string type\" \"coateddiffuse\" \"rgb reflectance\" [1 1 1] \"float roughness\" 0.04 "
        "\"float thickness\" 0.02\n"
        "Texture \"img\" \"spectrum\" \"imagemap\" \"string filename\" \"x.png\"\n"
        "Texture \"k\" \"spectrum\" \"constant\" \"rgb value\" [0.1 0.2 0.3]\n"
        "MakeNamedMaterial \"tex\" \"string type\" \"diffuse\" \"texture reflectance\" \"img\"\n"
        "MakeNamedMaterial \"const\" \"string type\" \"diffuse\" \"texture reflectance\" \"k\"\n"
        "MakeNamedMaterial \"mix\" \"string type\" \"mix\" \"string materials\" [\"red\" \"cu\"] \"float amount\" 0.3\n"
        "MakeNamedMaterial \"sheet\" \"string type\" \"diffusetransmission\" \"rgb reflectance\" [0.2 0.3 0.4] "
        "\"rgb transmittance\" [0.5 0.5 0.5] \"float scale\" 2\n"
        "MakeNamedMaterial \"dt0\" \"string type\" \"diffusetransmission\"\n"
        "MakeNamedMaterial \"later\" \"string type\" \"diffuse\" \"float foo\" 1\n"
        "MakeNamedMaterial \"air\" \"string type\" \"interface\"\n" S_SHAPE("red") S_SHAPE("cu") S_SHAPE("au")
            S_SHAPE("refl") S_SHAPE("bk7") S_SHAPE("water") S_SHAPE("coat") S_SHAPE("tex") S_SHAPE("const")
                S_SHAPE("mix") S_SHAPE("air") S_SHAPE("aniso") S_SHAPE("raw") S_SHAPE("neg") S_SHAPE("pane") S_SHAPE("sheet") S_SHAPE("dt0") "Material \"diffuse\" \"rgb reflectance\" [0.25 0.25 0.25]\n" S_TRI,
        0, &rep, &err);
    CHECK(s != NULL, "%s", err.msg);
    if (!s)
        return;
    const pf_material_t *m;
    CHECK(s->nmeshes == 18, "the interface shape is dropped: %zu meshes", s->nmeshes);
    if ((m = s_mat(s, "red")))
        CHECK(m->type == PF_MAT_DIFFUSE && s_vnear(m->kd, 0.8f, 0, 0));
    if ((m = s_mat(s, "cu")))
        CHECK(m->type == PF_MAT_CONDUCTOR && s_vnear(m->eta, 0.2f, 0.9f, 1.1f) && s_vnear(m->k, 3.9f, 2.4f, 2.1f) &&
              m->alpha == 0.0f && s_vnear(m->ks, s_f0(0.2f, 3.9f), s_f0(0.9f, 2.4f), s_f0(1.1f, 2.1f)));
    if ((m = s_mat(s, "au")))
        CHECK(m->type == PF_MAT_CONDUCTOR && s_vnear(m->eta, 0.143119f, 0.374957f, 1.442479f) &&
                  s_vnear(m->k, 3.98316f, 2.385721f, 1.603215f) && s_near(m->alpha, sqrtf(0.5f)),
              "remapped alpha sqrt(0.5): %g", m->alpha);
    /* reflectance r: eta 1, k = 2 sqrt(r) / sqrt(1 - r), so that F0 = k^2 / (4 + k^2) = r */
    if ((m = s_mat(s, "refl")))
        CHECK(m->type == PF_MAT_CONDUCTOR && s_vnear(m->eta, 1, 1, 1) &&
              s_vnear(m->k, 2.0f * sqrtf(0.9f) / sqrtf(0.1f), 2.0f * sqrtf(0.8f) / sqrtf(0.2f), 2.0f * sqrtf(0.7f) / sqrtf(0.3f)));
    if ((m = s_mat(s, "aniso")))
        CHECK(m->type == PF_MAT_CONDUCTOR && s_near(m->alpha, 0.5f * (0.2f + 0.4f)), "mean of alphas: %g", m->alpha);
    if ((m = s_mat(s, "raw")))
        CHECK(m->type == PF_MAT_CONDUCTOR && s_near(m->alpha, 0.3f), "remaproughness false: %g", m->alpha);
    if ((m = s_mat(s, "neg")))
        CHECK(m->type == PF_MAT_CONDUCTOR && s_vnear(m->eta, 1e-4f, 0.5f, 0.5f) && s_vnear(m->k, 1, 2, 1) &&
                  s_warned(&rep, "conductor eta <= 0 or k < 0 (clamped)") == 1,
              "an eta of 0 is clamped and warned (negative ones are parse errors)");
    if ((m = s_mat(s, "bk7")))
        CHECK(m->type == PF_MAT_GLASS && s_near(m->ior, 1.5168f));
    if ((m = s_mat(s, "water")))
        CHECK(m->type == PF_MAT_GLASS && s_near(m->ior, 1.33f) && s_vnear(m->kt, 1, 1, 1));
    if ((m = s_mat(s, "pane")))
        CHECK(m->type == PF_MAT_THIN_DIELECTRIC && s_near(m->ior, 1.52f) && s_vnear(m->ks, 1, 1, 1) &&
                  s_vnear(m->kt, 1, 1, 1) && s_warned(&rep, "thindielectric") == 0,
              "thindielectric: a thin sheet of index 1.52, not warned (type %d)", (int)m->type);
    if ((m = s_mat(s, "coat")))
        CHECK(m->type == PF_MAT_COATED && s_vnear(m->kd, 1, 1, 1) && s_near(m->alpha, 0.2f) && s_near(m->ior, 1.5f) &&
                  s_near(m->thickness, 0.02f),
              "coateddiffuse: kd %g alpha %g (remapped sqrt 0.04) ior %g thickness %g", m->kd.x, m->alpha, m->ior,
              m->thickness);
    if ((m = s_mat(s, "tex")))
        CHECK(s_vnear(m->kd, 0.5f, 0.5f, 0.5f));
    if ((m = s_mat(s, "const")))
        CHECK(s_vnear(m->kd, 0.1f, 0.2f, 0.3f));
    /* the mix: its parts added as materials of their own, amount 0.3 */
    if ((m = s_mat(s, "mix")))
        CHECK(m->type == PF_MAT_MIX && m->mix[0] < s->nmats && m->mix[1] < s->nmats &&
                  s->mats[m->mix[0]].type == PF_MAT_DIFFUSE && s_vnear(s->mats[m->mix[0]].kd, 0.8f, 0, 0) &&
                  s->mats[m->mix[1]].type == PF_MAT_CONDUCTOR && s_near(m->amount, 0.3f) && m->amount_tex == 0,
              "mix: type %d", (int)m->type);
    /* reflectance + transmittance 2 (0.4 + 1, 0.6 + 1, 0.8 + 1): scaled by 1 / 1.8, warned */
    if ((m = s_mat(s, "sheet")))
        CHECK(m->type == PF_MAT_DIFFUSE_TRANSMISSION && s_vnear(m->kd, 0.4f / 1.8f, 0.6f / 1.8f, 0.8f / 1.8f) &&
                  s_vnear(m->kt, 1.0f / 1.8f, 1.0f / 1.8f, 1.0f / 1.8f) &&
                  s_warned(&rep, "diffusetransmission above 1 (scaled)") == 1,
              "diffusetransmission: type %d kd %g kt %g", (int)m->type, m->kd.x, m->kt.x);
    if ((m = s_mat(s, "dt0")))
        CHECK(m->type == PF_MAT_DIFFUSE_TRANSMISSION && s_vnear(m->kd, 0.25f, 0.25f, 0.25f) &&
                  s_vnear(m->kt, 0.25f, 0.25f, 0.25f), "pbrt's defaults 0.25 and 0.25");
    if ((m = s_mat(s, "later")))
        CHECK(s_vnear(m->kd, 0.5f, 0.5f, 0.5f), "a forward NamedMaterial resolves");
    const pf_mesh_t *last = &s->meshes[s->nmeshes - 1];
    CHECK(s_vnear(s->mats[last->mat[0]].kd, 0.25f, 0.25f, 0.25f), "Material sets the current material");
    CHECK(s_warned(&rep, "rough conductor") == 0 && s_warned(&rep, "anisotropic roughness (isotropic mean used)") == 1 &&
          s_warned(&rep, "coateddiffuse") == 0 &&
          s_warned(&rep, "texture") == 1 && s_warned(&rep, "mix") == 0 && s_warned(&rep, "interface") == 1 &&
          s_warned(&rep, "unused parameter \"float foo\"") == 1);
    pf_scene_destroy(&s);

    s = s_parse(S_HEAD S_SHAPE("nope"), 0, NULL, &err);
    CHECK(!s && strstr(err.msg, "scene.pbrt:4: NamedMaterial \"nope\" is not defined"), "%s", err.msg);
    s = s_parse(S_HEAD "MakeNamedMaterial \"a\" \"string type\" \"diffuse\"\n"
                       "MakeNamedMaterial \"a\" \"string type\" \"diffuse\"\n", 0, NULL, &err);
    CHECK(!s && strstr(err.msg, "scene.pbrt:5:1: material \"a\" is defined twice (first at"), "%s", err.msg);
    s = s_parse(S_HEAD "Material \"plastic\"\n", 0, NULL, &err);
    CHECK(!s && strstr(err.msg, "scene.pbrt:4:1: unknown material type \"plastic\""), "%s", err.msg);
}

static void test_lights(void)
{
    pf_error_t err;
    pf_load_report_t rep;
    pf_scene_t *s = s_parse(S_HEAD "Translate 0 1 0\n"
                                   "LightSource \"point\" \"rgb I\" [1 2 3] \"float scale\" 2 \"point3 from\" [1 0 0]\n"
                                   "LightSource \"spot\" \"blackbody I\" 6500 \"point3 from\" [0 0 0] \"point3 to\" [0 0 -3]\n"
                                   "  \"float coneangle\" 40 \"float conedelta\" 10 \"float power\" 100\n"
                                   "LightSource \"distant\" \"rgb L\" [1 2 3] \"float illuminance\" 2 \"point3 from\" [0 0 0]\n"
                                   "  \"point3 to\" [1 0 0]\nRotate 90 0 0 1\nLightSource \"distant\" \"float scale\" 3\n"
                                   "LightSource \"infinite\" \"rgb L\" [1 2 3] \"float illuminance\" 6.2831853\n"
                                   "AreaLightSource \"diffuse\" \"blackbody L\" 3000 \"float power\" 10\n"
                                   "Shape \"trianglemesh\" \"point3 P\" [0 0 0  2 0 0  0 2 0]\n",
                            0, &rep, &err);
    CHECK(s && s->nlights == 5 && s->nmeshes == 1, "%s", err.msg);
    if (s && s->nlights == 5 && s->nmeshes == 1) {
        /* a constant sky: L times illuminance / pi (an upward patch gets pi L) */
        CHECK(s->lights[4].type == PF_LIGHT_INFINITE && s_vnear(s->lights[4].intensity, 2, 4, 6));
        const pf_light_t *p = &s->lights[0], *sp = &s->lights[1], *d1 = &s->lights[2], *d2 = &s->lights[3];
        /* distant: from -> to, turned by the CTM's linear part (not moved), L times illuminance (and scale) */
        CHECK(d1->type == PF_LIGHT_DISTANT && s_vnear(d1->dir, 1, 0, 0) && s_vnear(d1->intensity, 2, 4, 6));
        CHECK(d2->type == PF_LIGHT_DISTANT && s_vnear(d2->dir, 0, 0, 1) && s_vnear(d2->intensity, 3, 3, 3));
        CHECK(p->type == PF_LIGHT_POINT && s_vnear(p->pos, 1, 1, 0) && s_vnear(p->intensity, 2, 4, 6));
        CHECK(sp->type == PF_LIGHT_SPOT && s_vnear(sp->pos, 0, 1, 0) && s_vnear(sp->dir, 0, 0, -1));
        CHECK(s_near(sp->cos_outer, cosf(40 * PF_PI / 180)) && s_near(sp->cos_inner, cosf(30 * PF_PI / 180)));
        /* power 100 W over pbrt's cone integral; a blackbody is luminance 1. */
        double ke = 2 * PF_PI * ((1 - cos(30 * PF_PI / 180)) + (cos(30 * PF_PI / 180) - cos(40 * PF_PI / 180)) / 2);
        CHECK(fabs(pf_luminance(sp->intensity) - 100 / ke) < 1e-3 * 100 / ke, "lum %g", pf_luminance(sp->intensity));
        pf_vec3 le = s->mats[s->meshes[0].mat[0]].le;
        CHECK(fabs(pf_luminance(le) * PF_PI * 2.0 - 10.0) < 1e-3, "the triangle emits 10 W: lum %g", pf_luminance(le));
        CHECK(le.x > le.z, "3000 K is reddish");
        CHECK(fabsf(sp->intensity.x / sp->intensity.y - 1.0f) < 0.1f &&
                  fabsf(sp->intensity.z / sp->intensity.y - 1.0f) < 0.1f,
              "6500 K is near white: %g %g %g", sp->intensity.x, sp->intensity.y, sp->intensity.z);
    }
    CHECK(s_warned(&rep, "light type distant") == 0); /* image infinite lights: tests/light/test_envmap.c */
    pf_scene_destroy(&s);
    /* twosided: both sides emit, no warning; "power" is over both (pbrt-v4's
     * k_e = 2 pi A), so its Le is half the one-sided light's. */
    s = s_parse(S_HEAD "AttributeBegin\nAreaLightSource \"diffuse\" \"float power\" 10\n"
                       "Shape \"trianglemesh\" \"point3 P\" [0 0 0  2 0 0  0 2 0]\nAttributeEnd\n"
                       "AttributeBegin\nAreaLightSource \"diffuse\" \"float power\" 10 \"bool twosided\" true\n"
                       "Shape \"trianglemesh\" \"point3 P\" [0 0 1  2 0 1  0 2 1]\nAttributeEnd\n",
                0, &rep, &err);
    CHECK(s && s->nmeshes == 2, "twosided: %s", err.msg);
    if (s && s->nmeshes == 2) {
        const pf_material_t *one = &s->mats[s->meshes[0].mat[0]], *two = &s->mats[s->meshes[1].mat[0]];
        CHECK(one->twosided == 0 && two->twosided == 1, "twosided %u %u", one->twosided, two->twosided);
        CHECK(fabs(pf_luminance(two->le) * 2.0 - pf_luminance(one->le)) < 1e-5 * pf_luminance(one->le),
              "two-sided power over both sides: lum %g vs %g", pf_luminance(two->le), pf_luminance(one->le));
        CHECK(rep.nwarnings == 0, "twosided warned (%zu warnings)", rep.nwarnings);
    }
    pf_scene_destroy(&s);
}

static void test_instances(void)
{
    pf_error_t err;
    pf_load_report_t rep;
    pf_scene_t *s = s_parse(S_HEAD "ObjectBegin \"tri\"\nTranslate 1 0 0\nAreaLightSource \"diffuse\"\n"
                                   "Shape \"trianglemesh\" \"point3 P\" [0 0 0  1 0 0  0 1 0]\nObjectEnd\n"
                                   "Shape \"trianglemesh\" \"point3 P\" [0 0 9  1 0 9  0 1 9]\n"
                                   "AttributeBegin\nTranslate 0 10 0\nObjectInstance \"tri\"\nAttributeEnd\n"
                                   "ObjectInstance \"tri\"\nScale -1 1 1\nObjectInstance \"tri\"\n",
                            0, &rep, &err);
    CHECK(s && s->nmeshes == 4, "%s", err.msg);
    if (s && s->nmeshes == 4) {
        CHECK(s_vnear(s->meshes[0].pos[0], 0, 0, 9), "the shape outside the definition comes first");
        CHECK(s_vnear(s->meshes[1].pos[0], 1, 10, 0) && s_vnear(s->meshes[1].pos[1], 2, 10, 0));
        CHECK(s_vnear(s->meshes[2].pos[0], 1, 0, 0));
        CHECK(s_vnear(s->meshes[3].pos[0], -1, 0, 0) && s_vnear(s->meshes[3].pos[1], -2, 0, 0));
        for (int i = 1; i < 4; i++)
            CHECK(s_vnear(s_emit_normal(&s->meshes[i], 0), 0, 0, 1), "instance %d keeps the normal", i);
        for (size_t i = 0; i < s->nmats; i++)
            CHECK(pf_is_black(s->mats[i].le), "area lights are not instanced");
    }
    CHECK(s_warned(&rep, "area light in an object definition") == 1);
    pf_scene_destroy(&s);
    s = s_parse(S_HEAD "ObjectInstance \"none\"\n", 0, NULL, &err);
    CHECK(!s && strstr(err.msg, "scene.pbrt:4:1: ObjectInstance \"none\": no such object"), "%s", err.msg);
    s = s_parse(S_HEAD "ObjectBegin \"a\"\nObjectBegin \"b\"\n", 0, NULL, &err);
    CHECK(!s && strstr(err.msg, "scene.pbrt:5:1: ObjectBegin \"b\" inside the definition of \"a\""), "%s", err.msg);
}

static void test_include(void)
{
    char sub[300];
    snprintf(sub, sizeof sub, "%s/sub", s_dir);
    mkdir(sub, 0700);
    snprintf(sub, sizeof sub, "%s/models", s_dir);
    mkdir(sub, 0700);
    s_write("models/t.ply", "ply\nformat ascii 1.0\nelement vertex 3\nproperty float x\nproperty float y\n"
                            "property float z\nelement face 1\nproperty list uchar int vertex_indices\nend_header\n"
                            "0 0 0\n1 0 0\n0 1 0\n3 0 1 2\n");
    s_write("sub/a.pbrt", "Include \"b.pbrt\"\nShape \"plymesh\" \"string filename\" \"models/t.ply\"\n");
    s_write("sub/b.pbrt", "Translate 0 0 1\n" S_TRI);
    pf_error_t err;
    pf_scene_t *s = s_parse(S_HEAD "Include \"sub/a.pbrt\"\n" S_TRI, 0, NULL, &err);
    CHECK(s && s->nmeshes == 3, "%s", err.msg);
    if (s && s->nmeshes == 3) {
        CHECK(s_vnear(s->meshes[0].pos[0], 1, 2, 4) && s_vnear(s->meshes[1].pos[1], 1, 0, 1));
        CHECK(strcmp(s->meshes[1].name, "t") == 0, "the ply mesh keeps its name: %s", s->meshes[1].name);
        CHECK(s_vnear(s->meshes[2].pos[0], 1, 2, 4), "an Include shares the graphics state");
    }
    pf_scene_destroy(&s);
    s_write("sub/r1.pbrt", "# one\nInclude \"r2.pbrt\"\n");
    s_write("sub/r2.pbrt", "\n   Include \"r1.pbrt\"\n");
    s = s_parse(S_HEAD "Include \"sub/r1.pbrt\"\n", 0, NULL, &err);
    CHECK(!s && strstr(err.msg, "sub/r2.pbrt:2:4: recursive Include: ") && strstr(err.msg, "scene.pbrt -> ") &&
              strstr(err.msg, "r1.pbrt -> ") && strstr(err.msg, "r2.pbrt -> "),
          "%s", err.msg);
    s = s_parse(S_HEAD "Include \"scene.pbrt\"\n", 0, NULL, &err);
    CHECK(!s && strstr(err.msg, "scene.pbrt:4:1: recursive Include"), "%s", err.msg);
    s = s_parse(S_HEAD "Include \"missing.pbrt\"\n", 0, NULL, &err);
    CHECK(!s && strstr(err.msg, "scene.pbrt:4:1: cannot open"), "%s", err.msg);
}

/* text must fail with a message containing want. */
static void s_fails(const char *text, const char *want)
{
    pf_error_t err;
    pf_scene_t *s = s_parse(text, 0, NULL, &err);
    CHECK(!s && strstr(err.msg, want), "wanted '%s', got '%s'", want, err.msg);
    pf_scene_destroy(&s);
}

static void test_syntax(void)
{
    s_fails(S_HEAD "Shape \"sphere\" \"float radius\" [ 1 x ]\n", "scene.pbrt:4:35: expected a number, found 'x'");
    s_fails(S_HEAD "Shape \"sphere\n", "scene.pbrt:4:7: unterminated string");
    s_fails(S_HEAD "\n\t Frobnicate 1\n", "scene.pbrt:5:3: unknown directive 'Frobnicate'");
    s_fails(S_HEAD "Shape \"sphere\" \"floot radius\" 1\n", "scene.pbrt:4:16: unknown parameter type 'floot'");
    s_fails(S_HEAD "Translate 1 2\nShape \"sphere\"\n", "scene.pbrt:5:1: Translate expects 3 numbers");
    s_fails(S_HEAD "Shape \"sphere\" \"float radius\" 1e40\n", "scene.pbrt:4:31: number '1e40' out of range");
    s_fails(S_HEAD "Shape \"sphere\" \"float radius\" [ 1\n", "scene.pbrt:5:1: end of file inside the values");
    s_fails(S_HEAD "Shape \"sphere\" \"string radius\" \"a\"\n", "scene.pbrt:4:16: parameter 'radius' must be float");
    s_fails(S_HEAD "Shape \"trianglemesh\" \"point3 P\" [0 0 0 1 0 0 0 1 0] \"integer indices\" [0 1 3]\n",
            "scene.pbrt:4:53: parameter 'indices': value 2 (3) out of range [0, 2]");
    s_fails(S_HEAD "Shape \"sphere\" \"float radius\" 1 \"float radius\" 2\n",
            "scene.pbrt:4:33: parameter 'radius' given twice");
    s_fails("Shape \"sphere\"\n", "scene.pbrt:1:1: Shape is only allowed after WorldBegin");
    s_fails(S_HEAD "Camera \"perspective\"\n", "scene.pbrt:4:1: Camera is only allowed before WorldBegin");
    s_fails(S_HEAD "[ 1 ]\n", "scene.pbrt:4:1: expected a directive, found '['");
    s_fails(S_HEAD "Rotate 10 0 0 0\n", "scene.pbrt:4:1: Rotate: the axis must not be zero");
    s_fails(S_HEAD "Shape \"sphere\" \"bool x\" maybe\n", "scene.pbrt:4:25: bool parameter 'x' takes true or false");
    s_fails(S_HEAD "Shape \"sphere\" \"string s\" \"a\\qb\"\n", "scene.pbrt:4:29: unknown escape");
    s_fails(S_HEAD "Shape \"cube\"\n", "scene.pbrt:4:1: unknown Shape type \"cube\"");
    s_fails(S_HEAD "LightSource \"sun\"\n", "scene.pbrt:4:1: unknown LightSource type \"sun\"");
}

/* PixelFilter: box and triangle as they are, gaussian (and no PixelFilter:
 * pbrt-v4's default) as the tent of its variance, the rest as a box with a
 * warning; bad radii are errors. */
static void test_pixel_filter(void)
{
    static const struct {
        const char *text;
        float box, tent;
        const char *warning;
    } cases[] = {
        { "", 0.0f, 1.1733f, NULL },
        { "PixelFilter \"box\"\n", 1.0f, 0.0f, NULL },
        { "PixelFilter \"box\" \"float xradius\" 1 \"float yradius\" 1\n", 2.0f, 0.0f, NULL },
        { "PixelFilter \"triangle\" \"float xradius\" 1 \"float yradius\" 1\n", 0.0f, 1.0f, NULL },
        { "PixelFilter \"triangle\"\n", 0.0f, 2.0f, NULL },
        { "PixelFilter \"gaussian\" \"float sigma\" 0.25\n", 0.0f, 0.58665f, "PixelFilter gaussian (approximated)" },
        { "PixelFilter \"mitchell\"\n", 1.0f, 0.0f, "PixelFilter (rendered as a box)" },
    };
    for (size_t i = 0; i < sizeof cases / sizeof *cases; i++) {
        char text[512];
        snprintf(text, sizeof text, "%s" S_HEAD "LightSource \"point\"\n", cases[i].text);
        pf_error_t err;
        pf_load_report_t rep;
        pf_scene_t *s = s_parse(text, 0, &rep, &err);
        CHECK(s && fabsf(s->settings.filter_box - cases[i].box) < 1e-4f &&
                  fabsf(s->settings.filter_tent - cases[i].tent) < 1e-4f,
              "'%s': box %g tent %g", cases[i].text, s ? (double)s->settings.filter_box : -1.0,
              s ? (double)s->settings.filter_tent : -1.0);
        CHECK(cases[i].warning ? s_warned(&rep, cases[i].warning) == 1 : rep.nwarnings == 0, "'%s': %zu warnings",
              cases[i].text, rep.nwarnings);
        pf_scene_destroy(&s);
    }
    pf_error_t err;
    pf_scene_t *s = s_parse("PixelFilter \"triangle\" \"float xradius\" 3\n" S_HEAD, 0, NULL, &err);
    CHECK(!s && strstr(err.msg, "PixelFilter: radius 2.5 is out of range") && strstr(err.msg, ":1:"), "%s", err.msg);
    pf_scene_destroy(&s);
}

static void test_report(void)
{
    const char *text = "Sampler \"sobol\" \"integer pixelsamples\" 16\nPixelFilter \"gaussian\"\n"
                       "ColorSpace \"srgb\"\nOption \"bool wavefront\" true\n" S_HEAD
                       "Attribute \"shape\" \"float radius\" 2\nMakeNamedMedium \"fog\" \"string type\" \"homogeneous\"\n"
                       "MediumInterface \"\" \"fog\"\nLightSource \"point\"\n"
                       "Shape \"sphere\" \"float foo\" 1 \"float alpha\" 0.5\nShape \"sphere\" \"float foo\" 2\n"
                       "Texture \"d\" \"float\" \"wrinkled\"\n"
                       "Material \"diffuse\" \"texture displacement\" \"d\"\n";
    pf_error_t err;
    pf_load_report_t rep;
    pf_scene_t *s = s_parse(text, 0, &rep, &err);
    CHECK(s != NULL, "%s", err.msg);
    const char *kinds[] = { "Sampler (ignored)", "PixelFilter gaussian (approximated)", "ColorSpace (ignored)",
                            "Option (ignored)",
                            "Attribute (ignored)", "medium scattering (ignored)",
                            "alpha on a sphere (opaque)", "displacement texture (ignored)" };
    for (size_t i = 0; i < sizeof kinds / sizeof *kinds; i++)
        CHECK(s_warned(&rep, kinds[i]) == 1, "%s", kinds[i]);
    CHECK(s_warned(&rep, "unused parameter \"float foo\"") == 2, "one kind per name, counted");
    CHECK(rep.nwarnings == 9, "%zu kinds", rep.nwarnings);
    int first = -1;
    for (size_t i = 0; i < rep.nwarnings; i++)
        if (!strcmp(rep.warnings[i].kind, "unused parameter \"float foo\""))
            first = (int)i;
    CHECK(first >= 0 && strstr(rep.warnings[first].first, "scene.pbrt:12: unused parameter \"float foo\": "),
          "%s", first >= 0 ? rep.warnings[first].first : "");
    pf_scene_destroy(&s);
    /* --strict: the first of them is an error naming its line. */
    s = s_parse(text, 1, &rep, &err);
    CHECK(!s && strstr(err.msg, "scene.pbrt:1: Sampler (ignored): ") && strstr(err.msg, "--strict"), "%s", err.msg);
    s = s_parse(S_HEAD "Shape \"sphere\" \"float foo\" 1\n", 1, &rep, &err);
    CHECK(!s && strstr(err.msg, "scene.pbrt:4: unused parameter \"float foo\""), "%s", err.msg);
    s = s_parse(S_HEAD "LightSource \"point\"\n" S_TRI, 1, &rep, &err);
    CHECK(s && rep.nwarnings == 0, "a clean file loads in strict mode: %s", err.msg);
    pf_scene_destroy(&s);
    /* Through pf_scene_load_opts (finalized), as photonfarm render --strict. */
    const char *path = s_write("strict.pbrt", S_HEAD "LightSource \"point\"\nSampler \"halton\"\n" S_TRI);
    s = pf_scene_load_opts(path, &(pf_load_opts_t){ .strict = 1 }, &err);
    CHECK(!s && strstr(err.msg, "strict.pbrt:5:1: Sampler is only allowed before WorldBegin"), "%s", err.msg);
    path = s_write("strict.pbrt", "Sampler \"halton\"\n" S_HEAD "LightSource \"point\"\n" S_TRI);
    s = pf_scene_load_opts(path, &(pf_load_opts_t){ .strict = 1 }, &err);
    CHECK(!s && strstr(err.msg, "strict.pbrt:1: Sampler (ignored)"), "%s", err.msg);
    s = pf_scene_load_opts(path, NULL, &err);
    CHECK(s != NULL, "%s", err.msg);
    pf_scene_destroy(&s);
}

/* Writes text gzip-compressed to <s_dir>/name. */
static const char *s_write_gz(const char *name, const void *data, size_t len)
{
    static char p[512];
    snprintf(p, sizeof p, "%s/%s", s_dir, name);
    gzFile gz = gzopen(p, "wb");
    CHECK(gz != NULL);
    if (gz) {
        CHECK(gzwrite(gz, data, (unsigned)len) == (int)len);
        gzclose(gz);
    }
    return p;
}

static void test_ply_gz(void)
{
    /* A binary PLY with normals and uv, read plain and gzipped. */
    char hdr[] = "ply\nformat binary_little_endian 1.0\nelement vertex 4\nproperty float x\nproperty float y\n"
                 "property float z\nproperty float nx\nproperty float ny\nproperty float nz\nproperty float u\n"
                 "property float v\nelement face 1\nproperty list uchar int vertex_indices\nend_header\n";
    unsigned char buf[1024];
    size_t n = strlen(hdr);
    memcpy(buf, hdr, n);
    float v[4][8] = { { 0, 0, 0, 0, 0, 1, 0, 0 }, { 1, 0, 0, 0, 0, 1, 1, 0 }, { 1, 1, 0, 0, 0, 1, 1, 1 },
                      { 0, 1, 0.5f, 0, 0, 1, 0, 1 } };
    memcpy(buf + n, v, sizeof v); /* the test runs on little-endian hosts (x86-64) */
    n += sizeof v;
    unsigned char face[17] = { 4 };
    int32_t idx[4] = { 0, 1, 2, 3 };
    memcpy(face + 1, idx, sizeof idx);
    memcpy(buf + n, face, sizeof face);
    n += sizeof face;
    char plain[512];
    snprintf(plain, sizeof plain, "%s/q.ply", s_dir);
    FILE *f = fopen(plain, "wb");
    CHECK(f && fwrite(buf, 1, n, f) == n);
    if (f)
        fclose(f);
    const char *gz = s_write_gz("q.ply.gz", buf, n);
    pf_mesh_t a, b;
    pf_error_t err;
    pf_xform_t xf = pf_xform_identity();
    xf.m[0][0] = -2;
    CHECK(pf_ply_read(plain, &xf, 0, &a, &err) == PF_OK, "%s", err.msg);
    CHECK(pf_ply_read(gz, &xf, 0, &b, &err) == PF_OK, "%s", err.msg);
    CHECK(a.ntris == 2 && b.ntris == 2 && a.nverts == 4 && b.nverts == 4 && a.nrm && b.nrm);
    if (a.ntris == 2 && b.ntris == 2 && a.nrm && b.nrm)
        CHECK(!memcmp(a.pos, b.pos, 4 * sizeof *a.pos) && !memcmp(a.nrm, b.nrm, 4 * sizeof *a.nrm) &&
              !memcmp(a.idx, b.idx, 6 * sizeof *a.idx) && !strcmp(a.name, "q") && !strcmp(b.name, "q"));
    pf_mesh_free(&a);
    pf_mesh_free(&b);
    /* Through a scene, and broken: truncated compressed data, not gzip at all. */
    char text[512];
    snprintf(text, sizeof text, S_HEAD "LightSource \"point\"\nShape \"plymesh\" \"string filename\" \"q.ply.gz\"\n");
    pf_scene_t *s = s_parse(text, 0, NULL, &err);
    CHECK(s && s->nmeshes == 1 && s->meshes[0].ntris == 2, "%s", err.msg);
    pf_scene_destroy(&s);
    unsigned char z[4096];
    FILE *g = fopen(gz, "rb");
    size_t zn = g ? fread(z, 1, sizeof z, g) : 0;
    if (g)
        fclose(g);
    snprintf(plain, sizeof plain, "%s/t.ply.gz", s_dir);
    f = fopen(plain, "wb");
    if (f) {
        fwrite(z, 1, zn / 2, f);
        fclose(f);
    }
    CHECK(pf_ply_read(plain, NULL, 0, &a, &err) != PF_OK && strstr(err.msg, "t.ply.gz"), "%s", err.msg);
    s_write("u.ply.gz", "ply\nnot compressed\n");
    snprintf(plain, sizeof plain, "%s/u.ply.gz", s_dir);
    CHECK(pf_ply_read(plain, NULL, 0, &a, &err) != PF_OK && strstr(err.msg, "u.ply.gz"), "%s", err.msg);
}

static void test_camera(void)
{
    pf_error_t err;
    pf_load_report_t rep;
    pf_scene_t *s = s_parse("LookAt 1 2 3  1 2 4  0 1 0\nCamera \"perspective\" \"float fov\" 30 \"float lensradius\" 0.1\n"
                            "  \"float focaldistance\" 5 \"float screenwindow\" [-1 1 -1 1]\n"
                            "Film \"rgb\" \"integer xresolution\" 200 \"integer yresolution\" 100 \"string filename\" \"a.exr\"\n"
                            "Integrator \"path\" \"integer maxdepth\" 7\nWorldBegin\n",
                            0, &rep, &err);
    CHECK(s != NULL, "%s", err.msg);
    if (s) {
        const pf_camera_desc_t *c = &s->camera;
        CHECK(s->has_camera && s_vnear(c->pos, 1, 2, 3) && s_vnear(c->look_at, 1, 2, 4) && s_vnear(c->up, 0, 1, 0));
        CHECK(c->vfov_deg == 30.0f && c->fov_shorter == 1 && c->left_handed == 1);
        CHECK(s_near(c->lens_radius, 0.1f) && s_near(c->focal_distance, 5.0f));
        CHECK(s->settings.width == 200 && s->settings.height == 100 && s->settings.max_depth == 7 &&
              s->settings.photon_max_depth == 7 && s->settings.path_max_depth == 7,
              "maxdepth 7: max_depth %d photon_max_depth %d path_max_depth %d", s->settings.max_depth,
              s->settings.photon_max_depth, s->settings.path_max_depth);
        CHECK(c->has_window == 1 && c->window[0] == -1.0f && c->window[1] == 1.0f && c->window[2] == -1.0f &&
              c->window[3] == 1.0f && c->frame_aspect == 0.0f && rep.nwarnings == 0,
              "screenwindow read, no warning (%zu)", rep.nwarnings);
    }
    pf_scene_destroy(&s);
    /* A mirrored camera (Scale -1 1 1, as exporters write): right-handed. */
    s = s_parse("Scale -1 1 1\nLookAt 0 0 0  0 0 -1  0 1 0\nCamera \"perspective\"\nWorldBegin\n", 0, NULL, &err);
    CHECK(s && s->camera.left_handed == 0 && s_vnear(s->camera.look_at, 0, 0, -1) && s->camera.vfov_deg == 90.0f &&
              s->settings.width == 1280 && s->settings.height == 720 && s->settings.max_depth == 5 &&
              s->settings.path_max_depth == 5,
          "%s", err.msg);
    pf_scene_destroy(&s);
    /* pbrt's path-length limit: maxdepth 5 unless given (also without an
     * Integrator, above), 0 (emitted light only) as -1, since 0 is no limit. */
    s = s_parse("Integrator \"path\"\nWorldBegin\n", 0, NULL, &err);
    CHECK(s && s->settings.path_max_depth == 5, "Integrator without maxdepth: %s", err.msg);
    pf_scene_destroy(&s);
    s = s_parse("Integrator \"path\" \"integer maxdepth\" 0\nWorldBegin\n", 0, NULL, &err);
    CHECK(s && s->settings.path_max_depth == -1, "maxdepth 0: %s", err.msg);
    pf_scene_destroy(&s);
    s_fails("Scale 0 1 1\nCamera \"perspective\"\n", "scene.pbrt:2:1: Camera: the current transform cannot be inverted");
    s_fails("Camera \"perspective\" \"float fov\" 180\n", "scene.pbrt:1:22: Camera: fov must be in (0, 180)");
    s_fails("Film \"rgb\" \"integer xresolution\" 0\n", "scene.pbrt:1:1: Film: resolution 0x720 is out of range");
    s = s_parse("Camera \"perspective\" \"float frameaspectratio\" 2.5\nWorldBegin\n", 0, NULL, &err);
    CHECK(s && s->camera.frame_aspect == 2.5f && s->camera.has_window == 0, "frameaspectratio: %s", err.msg);
    pf_scene_destroy(&s);
    s_fails("Camera \"perspective\" \"float screenwindow\" [0 1 0]\n", "scene.pbrt:1:22: Camera: \"screenwindow\" takes four");
    s_fails("Camera \"perspective\" \"float screenwindow\" [1 0 0 1]\n", "scene.pbrt:1:22: Camera: screenwindow [1 0 0 1] must");
    s_fails("Camera \"perspective\" \"float frameaspectratio\" 0\n", "scene.pbrt:1:22: Camera: frameaspectratio 0 must");
}

/* The Bitterli scenes: counts, materials and the kinds of warnings. */
static void test_bitterli(void)
{
    const char *veach = "../shared/scenes/bitterli/veach-mis/scene-v4.pbrt";
    const char *dining = "../shared/scenes/bitterli/dining-room/scene-v4.pbrt";
    if (access(veach, R_OK) != 0 || access(dining, R_OK) != 0) {
        printf("SKIP the Bitterli scenes: ../shared/scenes/bitterli is absent\n");
        return;
    }
    pf_error_t err;
    pf_load_report_t rep;
    pf_scene_t *s = pf_scene_load_opts(veach, &(pf_load_opts_t){ .report = &rep }, &err);
    CHECK(s != NULL, "%s", err.msg);
    if (s) {
        size_t ntris = 0, emit = 0;
        for (size_t i = 0; i < s->nmeshes; i++) {
            ntris += s->meshes[i].ntris;
            emit += !pf_is_black(s->mats[s->meshes[i].mat[0]].le);
        }
        for (size_t i = 0; i < s->nspheres; i++)
            emit += !pf_is_black(s->mats[s->spheres[i].mat].le);
        /* 4 plates of 12, floor and wall of 2, three emitting analytic spheres. */
        CHECK(s->nmeshes == 6 && ntris == 4 * 12 + 2 + 2 && emit == 3 && s->nspheres == 3 && s->nlights == 0 &&
                  s->nmats == 8,
              "%zu meshes, %zu triangles, %zu emitting, %zu spheres, %zu materials", s->nmeshes, ntris, emit,
              s->nspheres, s->nmats);
        CHECK(s->settings.width == 1280 && s->settings.height == 720 && s->settings.max_depth == 3 &&
              s->settings.path_max_depth == 3);
        /* Its Transform mirrors (det -1, as exporters from right-handed
         * renderers write): camera +x is forward x up, a right-handed view. */
        CHECK(s->camera.left_handed == 0 && s_near(s->camera.vfov_deg, 20.114292f) && s->camera.fov_shorter == 1);
        CHECK(s_vnear(s->camera.pos, 28.2792f, 3.5f, 0.0f) && s_vnear(s->camera.up, 0, 1, 0), "pos %g %g %g",
              s->camera.pos.x, s->camera.pos.y, s->camera.pos.z);
        const pf_material_t *m = s_mat(s, "Diffuse");
        CHECK(m && m->type == PF_MAT_DIFFUSE && s_vnear(m->kd, 0.5f, 0.5f, 0.5f));
    }
    CHECK(rep.nwarnings == 1 && s_warned(&rep, "Sampler (ignored)") == 1 && s_warned(&rep, "rough conductor") == 0,
          "%zu kinds", rep.nwarnings);
    CHECK(s && s->settings.filter_box == 0.0f && s->settings.filter_tent == 1.0f, "veach-mis: PixelFilter triangle 1");
    if (s) {
        size_t rough = 0;
        for (size_t i = 0; i < s->nmats; i++)
            rough += s->mats[i].type == PF_MAT_CONDUCTOR && s->mats[i].alpha > 0.0f;
        CHECK(rough == 4, "veach-mis: 4 rough conductor plates, got %zu", rough);
    }
    pf_scene_destroy(&s);
    /* The dining room has the sun and sky alone: the sun is read (a distant
     * light), the sky an image-based infinite light (a 512 x 512 map). */
    s = pf_scene_create();
    CHECK(pf_pbrt_load(s, dining, &(pf_load_opts_t){ .report = &rep }, &err) == PF_OK, "%s", err.msg);
    size_t ntris = 0;
    for (size_t i = 0; i < s->nmeshes; i++)
        ntris += s->meshes[i].ntris;
    CHECK(s->nmeshes == 53 && ntris == 269538 && s->nlights == 2 && s->nenvmaps == 1 &&
              s->envmaps[0].width == 512 && s->lights[1].map == 1,
          "%zu meshes, %zu triangles, %zu lights", s->nmeshes, ntris, s->nlights);
    if (s->nlights == 2) {
        const pf_light_t *l = &s->lights[0];
        pf_vec3 to_sun = pf_norm(pf_v3(0.88698f, 0.288862f, 0.360313f));
        CHECK(l->type == PF_LIGHT_DISTANT && pf_dot(l->dir, to_sun) < -0.9999f && s_vnear(l->intensity, 10, 10, 10),
              "dir %g %g %g", l->dir.x, l->dir.y, l->dir.z);
    }
    /* the floor's, the picture's and the teacup's imagemaps (the last under
     * a coateddiffuse, its reflectance) are rendered; no displacement or
     * normal map in this scene */
    CHECK(rep.nwarnings == 1 && s_warned(&rep, "Sampler (ignored)") == 1 && s_warned(&rep, "texture") == 0 &&
              s_warned(&rep, "coateddiffuse") == 0 && s_warned(&rep, "rough conductor") == 0,
          "%zu kinds",
          rep.nwarnings);
    CHECK(s->ntexs == 3 && s_mat(s, "FloorTiles") && s_mat(s, "FloorTiles")->kd_tex > 0, "%zu textures", s->ntexs);
    size_t coated_tex = 0;
    for (size_t i = 0; i < s->nmats; i++)
        coated_tex += s->mats[i].type == PF_MAT_COATED && s->mats[i].kd_tex > 0;
    CHECK(coated_tex == 1, "the teacup: a textured coateddiffuse (%zu)", coated_tex);
    pf_scene_destroy(&s);
    s = pf_scene_load(dining, &err);
    CHECK(s && s->nlights == 2, "the sun and the sky light it: %s", s ? "" : err.msg);
    pf_scene_destroy(&s);
}

/* ---- allocation failures ----
 * The test links with --wrap for the malloc family (tests/load/CMakeLists.txt):
 * while armed, the N-th allocation from the project's code fails, and every
 * block allocated must be freed again by the end of the case. (zlib's and
 * libc's own allocations are not seen.) */

void *__real_malloc(size_t n);
void *__real_calloc(size_t n, size_t k);
void *__real_realloc(void *p, size_t n);
void __real_free(void *p);
char *__real_strdup(const char *s);
void *__wrap_malloc(size_t n);
void *__wrap_calloc(size_t n, size_t k);
void *__wrap_realloc(void *p, size_t n);
void __wrap_free(void *p);
char *__wrap_strdup(const char *s);

#define S_LIVE (1 << 16)
static int s_armed, s_injected;
static long s_calls, s_fail_at;
static void *s_live[S_LIVE];
static long s_nlive;

static int s_fail_now(void) { return s_armed && ++s_calls == s_fail_at && (s_injected = 1); }
static void s_track(void *p, int add)
{
    if (!p || !s_armed)
        return;
    size_t i = ((uintptr_t)p >> 4) * 0x9E3779B97F4A7C15ull >> 48;
    if (add) {
        while (s_live[i])
            i = (i + 1) % S_LIVE;
        s_live[i] = p;
        s_nlive++;
        return;
    }
    for (size_t k = 0; k < S_LIVE && s_live[i]; k++, i = (i + 1) % S_LIVE) {
        if (s_live[i] == p) {
            s_live[i] = (void *)1; /* a tombstone keeps the probe chain */
            s_nlive--;
            return;
        }
    }
}
void *__wrap_malloc(size_t n)
{
    void *p = s_fail_now() ? NULL : __real_malloc(n);
    s_track(p, 1);
    return p;
}
void *__wrap_calloc(size_t n, size_t k)
{
    void *p = s_fail_now() ? NULL : __real_calloc(n, k);
    s_track(p, 1);
    return p;
}
void *__wrap_realloc(void *p, size_t n)
{
    if (s_fail_now())
        return NULL;
    void *q = __real_realloc(p, n);
    if (q) {
        s_track(p, 0);
        s_track(q, 1);
    }
    return q;
}
void __wrap_free(void *p)
{
    s_track(p, 0);
    __real_free(p);
}
char *__wrap_strdup(const char *s)
{
    char *p = s_fail_now() ? NULL : __real_strdup(s);
    s_track(p, 1);
    return p;
}

/* Loads a scene that reaches most of the reader, failing each allocation in
 * turn: every failure is a clean error (or a full recovery), nothing leaks. */
static void test_alloc_failures(void)
{
    s_write("alloc-inc.pbrt", "Translate 0 1 0\n" S_TRI);
    const char *path = s_write("alloc.pbrt",
                               S_HEAD "Include \"alloc-inc.pbrt\"\nLightSource \"spot\" \"rgb I\" [1 1 1]\n"
                                      "Texture \"t\" \"spectrum\" \"imagemap\" \"string filename\" \"x.png\"\n"
                                      "MakeNamedMaterial \"a\" \"string type\" \"coateddiffuse\" \"texture reflectance\" \"t\"\n"
                                      "NamedMaterial \"a\"\nShape \"sphere\"\nObjectBegin \"o\"\nShape \"disk\"\nObjectEnd\n"
                                      "AttributeBegin\nAreaLightSource \"diffuse\" \"blackbody L\" 4000\nShape \"sphere\"\n"
                                      "AttributeEnd\nObjectInstance \"o\"\nShape \"plymesh\" \"string filename\" \"models/t.ply\"\n"
                                      "Shape \"bilinearmesh\" \"point3 P\" [0 0 0 1 0 0 0 1 0 1 1 0] \"float foo\" 1\n");
    pf_error_t err;
    pf_scene_t *s = pf_scene_load(path, &err);
    CHECK(s != NULL, "%s", err.msg);
    size_t nmeshes = s ? s->nmeshes : 0;
    pf_scene_destroy(&s);
    long total = 0, clean = 0, recovered = 0;
    for (long n = 1;; n++) {
        memset(s_live, 0, sizeof s_live);
        s_nlive = 0;
        s_calls = 0;
        s_fail_at = n;
        s_injected = 0;
        s_armed = 1;
        err.msg[0] = '\0';
        s = pf_scene_load(path, &err);
        int injected = s_injected;
        clean += !s && err.msg[0] != '\0';
        recovered += s && s->nmeshes == nmeshes;
        CHECK(s || err.msg[0] != '\0', "allocation %ld: refused without a message", n);
        CHECK(!s || s->nmeshes == nmeshes, "allocation %ld: a different scene", n);
        pf_scene_destroy(&s);
        s_armed = 0;
        CHECK(s_nlive == 0, "allocation %ld failed: %ld blocks leaked", n, s_nlive);
        total = n;
        if (!injected)
            break;
    }
    printf("allocation failures: %ld allocations, %ld clean errors, %ld recovered\n", total - 1, clean, recovered);
    CHECK(total > 100 && clean > 0);
}

int main(void)
{
    pf_log_set_level(PF_LOG_ERROR);
    if (!pf_pbrt_text_dir())
        return 1;
    test_transforms();
    test_winding();
    test_shapes();
    test_state_stack();
    test_materials();
    test_lights();
    test_instances();
    test_include();
    test_syntax();
    test_pixel_filter();
    test_report();
    test_ply_gz();
    test_camera();
    test_bitterli();
    test_alloc_failures();
    pf_pbrt_text_dir_remove();
    return pf_test_finish();
}
