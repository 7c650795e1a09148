/* render_check.h: the render tests' way to render a scene built in memory:
 * finalized, then rendered in-process (pf_job_render_local) with the
 * scene's settings but for the size, samples, photons and gather rays
 * given, on every core; a failure or a bad pixel is a failed check. */
#ifndef PF_TEST_RENDER_CHECK_H
#define PF_TEST_RENDER_CHECK_H

#include "check.h"
#include "coordinator/job.h"
#include "image/image.h"
#include "render/render.h"
#include "scene/scene.h"

/* Renders scene (finalized here) at size x size with spp samples, these
 * photon counts, gather rays (0: the scene's) and terms into *img; 0 on
 * failure (checked), else 1 and *img the caller's to free. */
static inline int pf_test_render(pf_scene_t *scene, int size, int spp, uint64_t photons, uint64_t caustic, int gather,
                                 unsigned terms, pf_image_t *img)
{
    pf_error_t err = { { 0 } };
    int rc = pf_scene_finalize(scene, &err);
    CHECK(rc == PF_OK, "finalize: %s", err.msg);
    if (rc != PF_OK)
        return 0;
    pf_settings_t s = scene->settings;
    s.width = s.height = size;
    s.spp = spp;
    s.photons = photons;
    s.caustic_photons = caustic;
    if (gather > 0)
        s.gather = gather;
    s.threads = 0;
    pf_job_summary_t sum;
    rc = pf_job_render_local(scene, &s, terms, 0, img, &sum, &err);
    CHECK(rc == PF_OK, "render: %s", err.msg);
    CHECK(rc != PF_OK || sum.bad_pixels == 0, "%zu bad channels", sum.bad_pixels);
    return rc == PF_OK;
}

#endif
