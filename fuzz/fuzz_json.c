/* fuzz_json.c: libFuzzer target for the JSON scene loader (common/scene_json.c
 * through pf_scene_load, so the finalize checks run too). The input is the
 * scene file; small OBJ, MTL and PLY models sit beside it under the names the
 * seed scenes use (fuzz_models.h), so obj and ply objects load for real.
 * A scene that loads must also survive the scene-blob round trip that sends
 * it to workers (s_fuzz_check_blob).
 *
 * One thread; the regression driver and libFuzzer call it in a loop. */
#include <stddef.h>
#include <stdint.h>

#include "common/scene.h"
#include "fuzz/fuzz_models.h"
#include "fuzz/fuzz_util.h"

int LLVMFuzzerTestOneInput(const uint8_t *data, size_t size);

int LLVMFuzzerTestOneInput(const uint8_t *data, size_t size)
{
    const char *path = s_fuzz_setup("json", "scene.json", s_fuzz_models, S_FUZZ_NMODELS);
    s_fuzz_put(path, data, size);
    pf_error_t err;
    err.msg[0] = '\0';
    pf_scene_t *scene = pf_scene_load(path, &err);
    if (scene)
        s_fuzz_check_blob(scene);
    else
        PF_FUZZ_REQUIRE(err.msg[0] != '\0', "a refused scene has no error message");
    pf_scene_destroy(&scene);
    return 0;
}
