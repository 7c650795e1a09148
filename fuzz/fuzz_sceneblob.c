/* fuzz_sceneblob.c: libFuzzer target for the scene-blob reader
 * (proto/sceneblob.c), which rebuilds on a worker the scene a coordinator
 * sent. A blob that reads must write back and read again into the same
 * bytes: the worker's scene then is a fixed point, and what it renders does
 * not depend on how many times the scene travelled.
 *
 * One thread; the regression driver and libFuzzer call it in a loop. */
#include <stddef.h>
#include <stdint.h>

#include "fuzz/fuzz_util.h"
#include "proto/sceneblob.h"

int LLVMFuzzerTestOneInput(const uint8_t *data, size_t size);

int LLVMFuzzerTestOneInput(const uint8_t *data, size_t size)
{
    static int quiet;
    if (!quiet && !getenv("PF_FUZZ_VERBOSE"))
        pf_log_set_level(PF_LOG_QUIET); /* finalize warns about degenerate triangles */
    quiet = 1;
    pf_error_t err;
    err.msg[0] = '\0';
    pf_scene_t *scene = pf_sceneblob_read(data, size, &err);
    if (!scene) {
        PF_FUZZ_REQUIRE(err.msg[0] != '\0', "a refused blob has no error message");
        return 0;
    }
    s_fuzz_check_blob(scene);
    pf_scene_destroy(&scene);
    return 0;
}
