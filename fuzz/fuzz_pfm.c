/* fuzz_pfm.c: libFuzzer target for the PFM reader (image/image.c), which
 * `photonfarm compare` uses on images it did not write. An accepted image
 * has a positive size and a pixel array of that size (ASan checks the
 * reads below).
 *
 * One thread; the regression driver and libFuzzer call it in a loop. */
#include <stddef.h>
#include <stdint.h>

#include "fuzz/fuzz_util.h"
#include "image/image.h"

int LLVMFuzzerTestOneInput(const uint8_t *data, size_t size);

int LLVMFuzzerTestOneInput(const uint8_t *data, size_t size)
{
    const char *path = s_fuzz_setup("pfm", "input.pfm", NULL, 0);
    s_fuzz_put(path, data, size);
    pf_image_t img = { 0 };
    pf_error_t err;
    err.msg[0] = '\0';
    int rc = pf_image_read_pfm(&img, path, &err);
    if (rc != PF_OK) {
        PF_FUZZ_REQUIRE(rc < 0 && err.msg[0] != '\0', "a refused PFM: status %d, message '%s'", rc, err.msg);
        return 0;
    }
    PF_FUZZ_REQUIRE(img.width > 0 && img.height > 0 && img.rgb, "an accepted PFM of %dx%d", img.width, img.height);
    size_t negative = 0;
    (void)pf_image_count_bad(&img, &negative);
    pf_image_free(&img);
    return 0;
}
