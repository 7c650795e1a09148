/* fuzz_mtl.c: libFuzzer target for the MTL reader (mesh/mtl.c). Every
 * material an accepted file adds must be one the renderer can use: finite
 * values, a known type, a positive index of refraction for glass, and a
 * NUL-terminated name (the scene blob and every message rely on that).
 *
 * One thread; the regression driver and libFuzzer call it in a loop. */
#include <math.h>
#include <stddef.h>
#include <stdint.h>
#include <string.h>

#include "fuzz/fuzz_util.h"
#include "load/load.h"
#include "scene/scene.h"

int LLVMFuzzerTestOneInput(const uint8_t *data, size_t size);

static int s_finite3(pf_vec3 v) { return isfinite(v.x) && isfinite(v.y) && isfinite(v.z); }

int LLVMFuzzerTestOneInput(const uint8_t *data, size_t size)
{
    const char *path = s_fuzz_setup("mtl", "input.mtl", NULL, 0);
    s_fuzz_put(path, data, size);
    pf_scene_t *scene = pf_scene_create();
    PF_FUZZ_REQUIRE(scene != NULL, "out of memory");
    /* A material the file may replace by name. */
    pf_material_t def = pf_material_default("default");
    PF_FUZZ_REQUIRE(pf_scene_add_material(scene, &def) == 0, "out of memory");
    pf_error_t err;
    err.msg[0] = '\0';
    int rc = pf_mtl_load(scene, path, &err);
    PF_FUZZ_REQUIRE(rc <= 0, "pf_mtl_load returned %d", rc);
    if (rc != 0) {
        PF_FUZZ_REQUIRE(err.msg[0] != '\0', "a refused MTL has no error message");
        PF_FUZZ_REQUIRE(scene->nmats == 1, "a refused MTL file added %zu materials", scene->nmats - 1);
    }
    for (size_t i = 0; i < scene->nmats; i++) {
        const pf_material_t *m = &scene->mats[i];
        PF_FUZZ_REQUIRE(memchr(m->name, 0, sizeof m->name) != NULL, "material %zu: name not terminated", i);
        PF_FUZZ_REQUIRE(m->type == PF_MAT_DIFFUSE || m->type == PF_MAT_MIRROR || m->type == PF_MAT_GLASS ||
                            m->type == PF_MAT_CONDUCTOR || m->type == PF_MAT_COATED,
                        "material %zu: type %d", i, (int)m->type);
        /* Pr / Pm: what finalize will ask of a conductor and a coat */
        PF_FUZZ_REQUIRE(m->type != PF_MAT_CONDUCTOR || (m->alpha >= 0.0f && m->alpha <= 1.0f && m->eta.x > 0.0f &&
                                                        m->k.x >= 0.0f && isfinite(m->k.x) && isfinite(m->k.y) &&
                                                        isfinite(m->k.z)),
                        "conductor '%s': alpha %g k %g", m->name, (double)m->alpha, (double)m->k.x);
        PF_FUZZ_REQUIRE(m->type != PF_MAT_COATED || (m->alpha >= 0.0f && m->alpha <= 1.0f && m->ior >= 1.0f),
                        "coated '%s': alpha %g ior %g", m->name, (double)m->alpha, (double)m->ior);
        PF_FUZZ_REQUIRE(m->alpha_tex <= scene->ntexs, "material '%s': alpha texture %u of %zu", m->name,
                        (unsigned)m->alpha_tex, scene->ntexs);
        PF_FUZZ_REQUIRE(s_finite3(m->kd) && s_finite3(m->ks) && s_finite3(m->kt) && s_finite3(m->le) &&
                            isfinite(m->ns) && isfinite(m->ior),
                        "material '%s' has a non-finite value", m->name);
        PF_FUZZ_REQUIRE(m->type != PF_MAT_GLASS || m->ior > 0.0f, "glass '%s' with ior %g", m->name,
                        (double)m->ior);
    }
    pf_scene_destroy(&scene);
    return 0;
}
