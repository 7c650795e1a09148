/* test_pbrt_media.c: the pbrt-v4 reader's media (load/pbrt/pbrt_medium.c),
 * diffuse transmission's textured slots and the coated conductor's
 * approximation, on small texts made at run time. Run from the repository
 * root (ctest does). */
#include "base/log.h"

#include "pbrt_text.h"

/* The scene material of mesh k's first triangle. */
static const pf_material_t *s_mesh_mat(const pf_scene_t *s, size_t k)
{
    CHECK(k < s->nmeshes, "mesh %zu of %zu", k, s->nmeshes);
    return k < s->nmeshes ? &s->mats[s->meshes[k].mat[0]] : &s->mats[0];
}

/* Participating media: MakeNamedMedium's absorption (sigma_a times scale)
 * lands on the sides MediumInterface names (inside: sigma_in, outside:
 * sigma_out; one name for both; "" none), kept through AttributeEnd, the
 * same material with other media a material of its own; what is not
 * rendered (scattering, other types, presets, a camera in a medium) is
 * warned once per kind; an undefined medium and a medium without a type
 * are errors naming the line. Also diffusetransmission's textured
 * reflectance and transmittance, each times "scale" through a scale
 * texture. */
static void test_media(void)
{
    pf_error_t err;
    pf_load_report_t rep;
    pf_scene_t *s = s_parse(
        "MakeNamedMedium \"fog\" \"string type\" \"homogeneous\" \"rgb sigma_a\" [0.5 0.5 0.5]\n"
        "MediumInterface \"\" \"fog\"\n" S_HEAD
        "MakeNamedMedium \"tea\" \"string type\" \"homogeneous\" \"rgb sigma_a\" [0.1 0.3 0.7]\n"
        "  \"rgb sigma_s\" [0 0 0] \"float scale\" 2\n"
        "MakeNamedMedium \"vdb\" \"string type\" \"nanovdb\" \"string filename\" \"x.nvdb\"\n"
        "MakeNamedMedium \"milk\" \"string type\" \"homogeneous\" \"string preset\" \"Wholemilk\"\n"
        "Material \"dielectric\"\n"
        "MediumInterface \"\"\n" S_TRI                                              /* 0: none */
        "AttributeBegin\nMediumInterface \"tea\" \"\"\n" S_TRI "AttributeEnd\n"     /* 1: tea inside */
        "AttributeBegin\nMediumInterface \"\" \"tea\"\n" S_TRI "AttributeEnd\n"     /* 2: tea outside */
        "AttributeBegin\nMediumInterface \"tea\"\n" S_TRI "AttributeEnd\n"           /* 3: both sides */
        S_TRI                                                                         /* 4: none again */
        "MediumInterface \"vdb\" \"milk\"\n" S_TRI                                   /* 5: clear, warned */
        "Texture \"ck\" \"spectrum\" \"checkerboard\" \"rgb tex1\" [1 1 1] \"rgb tex2\" [0.2 0.4 0.6]\n"
        "MediumInterface \"\"\n"
        "Material \"diffusetransmission\" \"texture reflectance\" \"ck\" \"texture transmittance\" \"ck\"\n"
        "  \"float scale\" 0.5\n" S_TRI                                               /* 6: leaf */
        "Material \"diffusetransmission\" \"texture transmittance\" \"ck\"\n" S_TRI, /* 7: kd 0.25, kt textured */
        0, &rep, &err);
    CHECK(s != NULL, "%s", err.msg);
    if (!s)
        return;
    pf_vec3 tea = pf_v3(0.2f, 0.6f, 1.4f);
    const pf_material_t *m0 = s_mesh_mat(s, 0), *m1 = s_mesh_mat(s, 1), *m2 = s_mesh_mat(s, 2);
    const pf_material_t *m3 = s_mesh_mat(s, 3), *m4 = s_mesh_mat(s, 4), *m5 = s_mesh_mat(s, 5);
    CHECK(pf_is_black(m0->sigma_in) && pf_is_black(m0->sigma_out), "no medium");
    CHECK(s_vnear(m1->sigma_in, tea.x, tea.y, tea.z) && pf_is_black(m1->sigma_out), "tea inside: %g %g %g",
          m1->sigma_in.x, m1->sigma_in.y, m1->sigma_in.z);
    CHECK(pf_is_black(m2->sigma_in) && s_vnear(m2->sigma_out, tea.x, tea.y, tea.z), "tea outside");
    CHECK(s_vnear(m3->sigma_in, tea.x, tea.y, tea.z) && s_vnear(m3->sigma_out, tea.x, tea.y, tea.z),
          "one name: both sides");
    CHECK(m4 == m0 && m1 != m0 && m2 != m1 && m3 != m2, "the media make distinct materials, AttributeEnd restores");
    CHECK(pf_is_black(m5->sigma_in) && pf_is_black(m5->sigma_out), "media not rendered are clear");
    CHECK(m1->type == PF_MAT_GLASS && m5->type == PF_MAT_GLASS);
    CHECK(s_warned(&rep, "camera inside a medium (not tinted)") == 1 && s_warned(&rep, "medium scattering (ignored)") == 1 &&
              s_warned(&rep, "medium type (not rendered)") == 1 && s_warned(&rep, "medium preset (not rendered)") == 1,
          "the media's warnings");
    const pf_material_t *leaf = s_mesh_mat(s, 6), *half = s_mesh_mat(s, 7);
    CHECK(leaf->type == PF_MAT_DIFFUSE_TRANSMISSION && leaf->kd_tex && leaf->kt_tex, "textured sheet");
    if (leaf->kd_tex && leaf->kt_tex) {
        const pf_texture_t *td = &s->texs[leaf->kd_tex - 1], *tt = &s->texs[leaf->kt_tex - 1];
        CHECK(td->type == PF_TEX_SCALE && td->op[0].ref && s->texs[td->op[0].ref - 1].type == PF_TEX_CHECKER &&
                  s_near(td->op[1].c.x, 0.5f) && tt->type == PF_TEX_SCALE && tt->op[0].ref == td->op[0].ref &&
                  s_near(tt->op[1].c.x, 0.5f),
              "both slots: the checker times the scale 0.5");
    }
    CHECK(half->kt_tex && !half->kd_tex && s_vnear(half->kd, 0.25f, 0.25f, 0.25f) &&
              s->texs[half->kt_tex - 1].type == PF_TEX_CHECKER,
          "a textured transmittance beside the default reflectance, no scale texture at scale 1");
    CHECK(s_warned(&rep, "texture") == 0, "nothing of the sheets is dropped");
    pf_scene_destroy(&s);

    s = s_parse(S_HEAD "MediumInterface \"nope\" \"\"\n" S_TRI, 0, NULL, &err);
    CHECK(!s && strstr(err.msg, "scene.pbrt:4: MediumInterface: medium \"nope\" is not defined"), "%s", err.msg);
    s = s_parse(S_HEAD "MakeNamedMedium \"m\" \"rgb sigma_a\" [1 1 1]\n", 0, NULL, &err);
    CHECK(!s && strstr(err.msg, "scene.pbrt:4: MakeNamedMedium \"m\" has no \"string type\""), "%s", err.msg);
    s = s_parse(S_HEAD "MakeNamedMedium \"m\" \"string type\" \"homogeneous\" \"rgb sigma_a\" [-1 1 1]\n", 0,
                NULL, &err);
    CHECK(!s && strstr(err.msg, "scene.pbrt:4:49: rgb parameter 'sigma_a' has a negative value"), "%s", err.msg);
    s = s_parse(S_HEAD "MakeNamedMedium \"m\" \"string type\" \"homogeneous\" \"rgb sigma_s\" [0 0 0]\n"
                       "MediumInterface \"m\" \"\"\n" S_TRI,
                1, &rep, &err);
    CHECK(s && rep.nwarnings == 0 && s_vnear(s_mesh_mat(s, 0)->sigma_in, 1, 1, 1),
          "an absorbing medium loads under --strict, sigma_a's default 1: %s", err.msg);
    pf_scene_destroy(&s);
}

/* coatedconductor: the metal under the coat, its constants over the
 * coat's index (as pbrt-v4 takes them), its own roughness; warned. */
static void test_coated_conductor(void)
{
    pf_error_t err;
    pf_load_report_t rep;
    pf_scene_t *s = s_parse(S_HEAD "Material \"coatedconductor\" \"rgb conductor.eta\" [0.3 0.9 1.2]\n"
                                   "  \"rgb conductor.k\" [3.9 2.4 2.1] \"float conductor.roughness\" 0.04\n"
                                   "  \"float interface.eta\" 1.5 \"float interface.roughness\" 0\n" S_TRI
                                   "Material \"coatedconductor\" \"rgb reflectance\" [0.9 0.8 0.7]\n" S_TRI,
                            0, &rep, &err);
    CHECK(s != NULL, "%s", err.msg);
    if (!s)
        return;
    const pf_material_t *a = s_mesh_mat(s, 0), *b = s_mesh_mat(s, 1);
    CHECK(a->type == PF_MAT_CONDUCTOR && s_vnear(a->eta, 0.2f, 0.6f, 0.8f) && s_vnear(a->k, 2.6f, 1.6f, 1.4f) &&
              s_near(a->alpha, 0.2f),
          "the metal under the coat: eta %g %g %g, k %g %g %g, alpha %g", a->eta.x, a->eta.y, a->eta.z, a->k.x, a->k.y,
          a->k.z, a->alpha);
    float k9 = pf_conductor_k_of_reflectance(0.9f) / 1.5f;
    CHECK(b->type == PF_MAT_CONDUCTOR && s_vnear(b->eta, 1.0f / 1.5f, 1.0f / 1.5f, 1.0f / 1.5f) && s_near(b->k.x, k9) &&
              b->alpha == 0.0f,
          "the reflectance form, over the default coat index 1.5: eta %g, k %g", b->eta.x, b->k.x);
    CHECK(s_warned(&rep, "coatedconductor (approximated)") == 2, "warned once per use");
    pf_scene_destroy(&s);
}

int main(void)
{
    pf_log_set_level(PF_LOG_ERROR);
    if (!pf_pbrt_text_dir())
        return 1;
    test_media();
    test_coated_conductor();
    pf_pbrt_text_dir_remove();
    return pf_test_finish();
}
