/* fuzz_json.c: libFuzzer target for the JSON scene loader (load/scene_json.c
 * through pf_scene_load, so the finalize checks run too). The input is the
 * scene file; small OBJ, MTL and PLY models sit beside it under the names the
 * seed scenes use (fuzz_models.h), so obj and ply objects load for real.
 * A scene that loads must also survive the scene-blob round trip that sends
 * it to workers (s_fuzz_check_blob).
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
    const char *path = s_fuzz_setup("json", "scene.json", s_fuzz_models, S_FUZZ_NMODELS);
    s_fuzz_put(path, data, size);
    s_fuzz_load_checked(path, "a refused scene has no error message");
    return 0;
}
