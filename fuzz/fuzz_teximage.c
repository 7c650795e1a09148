/* fuzz_teximage.c: libFuzzer target for the texture image reader
 * (image/texfile.c: stb_image behind photonfarm's size checks), which reads
 * whatever image files a scene names. An accepted image has a positive size
 * within the limits asked for and one pixel array of that size (ASan checks
 * the reads below). The limit is small (512 per side, 2^16 pixels) so that
 * headers near it are cheap to reach.
 *
 * One thread; the regression driver and libFuzzer call it in a loop. */
#include <stddef.h>
#include <stdint.h>

#include "fuzz/fuzz_util.h"
#include "image/texfile.h"

int LLVMFuzzerTestOneInput(const uint8_t *data, size_t size);

int LLVMFuzzerTestOneInput(const uint8_t *data, size_t size)
{
    const char *path = s_fuzz_setup("teximage", "input.png", NULL, 0);
    s_fuzz_put(path, data, size);
    pf_teximage_t img;
    pf_error_t err;
    err.msg[0] = '\0';
    int rc = pf_teximage_read(path, 512, 1u << 16, &img, &err);
    if (rc != PF_OK) {
        PF_FUZZ_REQUIRE(rc < 0 && err.msg[0] != '\0' && !img.px8 && !img.pxf,
                        "a refused image: status %d, message '%s'", rc, err.msg);
        return 0;
    }
    PF_FUZZ_REQUIRE(img.width > 0 && img.height > 0 && img.width <= 512 && img.height <= 512 &&
                        (uint64_t)img.width * (uint64_t)img.height <= (1u << 16) && (!img.px8 != !img.pxf),
                    "an accepted image of %dx%d", img.width, img.height);
    size_t n = (size_t)img.width * (size_t)img.height * 3;
    unsigned sum = 0;
    for (size_t i = 0; i < n; i++)
        sum += img.px8 ? img.px8[i] : (img.pxf[i] > 0.5f);
    (void)sum;
    pf_teximage_free(&img);
    return 0;
}
