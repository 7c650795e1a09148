/* fuzz_pbrt.c: libFuzzer target for the pbrt-v4 reader (load/pbrt/
 * through pf_scene_load_opts, so the finalize checks run too). The input is
 * the scene file scene.pbrt; beside it lie a PLY mesh (tri.ply, the name of
 * fuzz_models.h), a file to Include (inc.pbrt) and a spectrum file
 * (flat.spd), so the seeds' plymesh, Include and spectrum-file paths load
 * for real; Include "scene.pbrt" is the recursion seed.
 *
 * Oracles: a scene that loads survives the scene-blob round trip; a refused
 * one says why; and --strict agrees with the report: the strict load
 * succeeds exactly when the plain one succeeded without a warning.
 *
 * One thread; the regression driver and libFuzzer call it in a loop. */
#include <stddef.h>
#include <stdint.h>

#include "fuzz/fuzz_models.h"
#include "fuzz/fuzz_util.h"
#include "load/load.h"
#include "scene/scene.h"

int LLVMFuzzerTestOneInput(const uint8_t *data, size_t size);

static const s_fuzz_file_t s_files[] = {
    { "tri.ply", S_FUZZ_PLY },
    { "inc.pbrt", "AttributeBegin\nMaterial \"conductor\"\nTranslate 0 1 0\n"
                  "Shape \"sphere\" \"float radius\" 0.5\nAttributeEnd\n" },
    { "flat.spd", "# wavelength value\n400 0.5\n550 0.5\n700 0.5\n" },
};

int LLVMFuzzerTestOneInput(const uint8_t *data, size_t size)
{
    const char *path = s_fuzz_setup("pbrt", "scene.pbrt", s_files, (int)(sizeof s_files / sizeof *s_files));
    s_fuzz_put(path, data, size);
    pf_load_report_t report;
    pf_error_t err;
    err.msg[0] = '\0';
    pf_scene_t *plain = pf_scene_load_opts(path, &(pf_load_opts_t){ .report = &report }, &err);
    if (plain)
        s_fuzz_check_blob(plain);
    else
        PF_FUZZ_REQUIRE(err.msg[0] != '\0', "a refused pbrt scene has no error message");
    int clean = plain && report.nwarnings == 0 && report.more == 0;
    err.msg[0] = '\0';
    pf_scene_t *strict = pf_scene_load_opts(path, &(pf_load_opts_t){ .strict = 1 }, &err);
    PF_FUZZ_REQUIRE((strict != NULL) == clean, "strict mode %s a scene that loads with %zu warning kinds",
                    strict ? "accepts" : "refuses", plain ? report.nwarnings : 0);
    PF_FUZZ_REQUIRE(strict || err.msg[0] != '\0', "a scene refused in strict mode has no error message");
    pf_scene_destroy(&plain);
    pf_scene_destroy(&strict);
    return 0;
}
