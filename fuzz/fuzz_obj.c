/* fuzz_obj.c: libFuzzer target for the OBJ reader (mesh/obj.c), with the
 * MTL reader behind its mtllib statements (an MTL file of each name the
 * seeds use sits beside the input, fuzz_models.h). Each input is loaded
 * twice: as a scene by itself (pf_scene_load: default material, finalize,
 * and the scene-blob round trip), and into a scene with a mirroring,
 * non-uniform transform and a material override, which takes the paths that
 * reverse the winding and skip the MTL files.
 *
 * One thread; the regression driver and libFuzzer call it in a loop. */
#include <stddef.h>
#include <stdint.h>

#include "fuzz/fuzz_models.h"
#include "fuzz/fuzz_util.h"
#include "load/load.h"
#include "scene/scene.h"

int LLVMFuzzerTestOneInput(const uint8_t *data, size_t size);

int LLVMFuzzerTestOneInput(const uint8_t *data, size_t size)
{
    const char *path = s_fuzz_setup("obj", "input.obj", s_fuzz_models, S_FUZZ_NMODELS);
    s_fuzz_put(path, data, size);
    s_fuzz_load_checked(path, "a refused OBJ has no error message");

    pf_scene_t *scene = pf_scene_create();
    PF_FUZZ_REQUIRE(scene != NULL, "out of memory");
    pf_material_t m = pf_material_default("override");
    int mi = pf_scene_add_material(scene, &m);
    PF_FUZZ_REQUIRE(mi == 0, "out of memory");
    pf_xform_t xf = pf_xform_identity();
    xf.m[0][0] = -2.0f; /* mirror x and stretch it */
    xf.m[1][2] = 0.5f;  /* shear */
    xf.m[2][3] = 3.0f;  /* translate */
    pf_error_t err;
    err.msg[0] = '\0';
    int rc = pf_obj_load(scene, path, &xf, mi, &err);
    PF_FUZZ_REQUIRE(rc <= 0, "pf_obj_load returned %d", rc);
    PF_FUZZ_REQUIRE(rc == 0 || err.msg[0] != '\0', "a refused OBJ has no error message");
    for (size_t i = 0; rc == 0 && i < scene->nmeshes; i++) {
        const pf_mesh_t *mesh = &scene->meshes[i];
        for (size_t t = 0; t < 3 * mesh->ntris; t++)
            PF_FUZZ_REQUIRE(mesh->idx[t] < mesh->nverts, "mesh %zu: index %u of %zu vertices", i, mesh->idx[t],
                            mesh->nverts);
        for (size_t t = 0; t < mesh->ntris; t++)
            PF_FUZZ_REQUIRE(mesh->mat[t] == (uint32_t)mi, "the material override was not applied");
    }
    pf_scene_destroy(&scene);
    return 0;
}
