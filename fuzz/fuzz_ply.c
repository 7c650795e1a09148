/* fuzz_ply.c: libFuzzer target for the PLY reader (mesh/ply.c: ascii and
 * binary of both byte orders). Each input is loaded as a scene by itself
 * (pf_scene_load: material, point light, finalize and the scene-blob round
 * trip), and again with a mirroring transform, which reverses the winding
 * and turns the normals.
 *
 * One thread; the regression driver and libFuzzer call it in a loop. */
#include <stddef.h>
#include <stdint.h>

#include "fuzz/fuzz_util.h"
#include "load/load.h"
#include "scene/scene.h"

int LLVMFuzzerTestOneInput(const uint8_t *data, size_t size);

int LLVMFuzzerTestOneInput(const uint8_t *data, size_t size)
{
    const char *path = s_fuzz_setup("ply", "input.ply", NULL, 0);
    s_fuzz_put(path, data, size);
    s_fuzz_load_checked(path, "a refused PLY has no error message");

    pf_scene_t *scene = pf_scene_create();
    PF_FUZZ_REQUIRE(scene != NULL, "out of memory");
    pf_material_t m = pf_material_default("default");
    PF_FUZZ_REQUIRE(pf_scene_add_material(scene, &m) == 0, "out of memory");
    pf_xform_t xf = pf_xform_identity();
    xf.m[1][1] = -1.0f;
    xf.m[0][3] = 1.0f;
    pf_error_t err;
    err.msg[0] = '\0';
    int rc = pf_ply_load(scene, path, &xf, 0, &err);
    PF_FUZZ_REQUIRE(rc <= 0, "pf_ply_load returned %d", rc);
    PF_FUZZ_REQUIRE(rc == 0 || err.msg[0] != '\0', "a refused PLY has no error message");
    PF_FUZZ_REQUIRE(rc != 0 || scene->nmeshes <= 1, "one PLY made %zu meshes", scene->nmeshes);
    for (size_t i = 0; rc == 0 && i < scene->nmeshes; i++) {
        const pf_mesh_t *mesh = &scene->meshes[i];
        for (size_t t = 0; t < 3 * mesh->ntris; t++)
            PF_FUZZ_REQUIRE(mesh->idx[t] < mesh->nverts, "index %u of %zu vertices", mesh->idx[t], mesh->nverts);
    }
    pf_scene_destroy(&scene);
    return 0;
}
