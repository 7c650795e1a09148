/* test_near.c: near gather ends (render.c, direct.c's pf_direct_near_end):
 * a gather ray shorter than the maps' near_r samples its end's direct
 * light and takes only the rest of the irradiance from the point it reads,
 * E (1 - the point's direct share). Ctest `render_near`.
 *
 *   share     on tests/data/near/stripe.json (a room lit by the sun through
 *             a slit in its ceiling: a bright stripe on the floor, a
 *             partition beside it in shadow) and on the Cornell box (an
 *             area light), every flat irradiance point (no coverage
 *             correction) holds pf_pm_irradiance_seen's irradiance at it
 *             bit for bit and, in its direction field, the share
 *             its first-hit photons carry (pf_pm_scratch_t.direct over the
 *             estimate, by luminance) to within the 8-bit quantum, and a
 *             support radius within 2^-15 below the estimate's. A share
 *             left at 0 would count a near end's direct light twice; one
 *             off by the quantum's rounding shows here.
 *   near_r    pf_photon_maps_index sets near_r to twice the points' median
 *             support (positive, below the scene's size), the same on
 *             every call (workers derive it from the same tree).
 */
#include <math.h>
#include <stdio.h>
#include <stdlib.h>

#include "base/log.h"
#include "coordinator/job.h"
#include "image/image.h"
#include "load/load.h"
#include "photon/photonmap.h"
#include "photon/trace.h"
#include "render/frame.h"
#include "scene/scene.h"

#include "check.h"

static void s_share(const char *path, uint64_t photons)
{
    pf_error_t err = { { 0 } };
    pf_scene_t *scene = pf_scene_load(path, &err);
    CHECK(scene != NULL, "load %s: %s", path, err.msg);
    if (!scene)
        return;
    pf_settings_t s = scene->settings;
    s.photons = photons;
    s.caustic_photons = 0;
    s.threads = 2;
    pf_frame_t fr;
    pf_photon_stats_t st;
    PF_CHECK(pf_frame_open(&fr, scene, &err) == PF_OK);
    PF_CHECK(pf_photon_pass(scene, fr.accel, fr.lights, &s, &fr.maps, &st) == PF_OK);
    const pf_photon_maps_t *pm = &fr.maps;
    const pf_kdtree_t *irr = pm->irradiance;
    const pf_photon_t *pts = pf_kdtree_photons(irr);
    pf_pm_scratch_t *scratch = calloc(1, sizeof *scratch);
    PF_CHECK(scratch != NULL);
    pf_pm_visible_scratch_t vis;
    PF_CHECK(pf_pm_visible_scratch_init(&vis, PF_PM_FOUND) == PF_OK);
    size_t n = pf_kdtree_size(irr), flat = 0, bad_e = 0, bad_share = 0, bad_r = 0, lit = 0, mixed = 0;
    for (size_t i = 0; i < n; i++) {
        const pf_photon_t *q = &pts[i];
        if (!pf_irradiance_flat(q))
            continue;
        flat++;
        float r2;
        int is_flat;
        pf_vec3 e = pf_pm_irradiance_seen(pm->global, fr.accel, pf_photon_pos(q), pf_photon_normal(q), s.global_k,
                                          pm->global_r2, INFINITY, 1.0f, scratch, &vis, &r2, &is_flat);
        bad_e += !is_flat;
        pf_vec3 qe = pf_photon_power(q);
        bad_e += e.x != qe.x || e.y != qe.y || e.z != qe.z;
        float lum = pf_luminance(e), want = lum > 0.0f ? pf_luminance(scratch->direct) / lum : 0.0f;
        float got = pf_irradiance_direct_share(q);
        bad_share += !(fabsf(got - want) <= 0.5f / 255.0f + 1e-6f);
        lit += want > 0.5f;
        mixed += want > 0.02f && want < 0.98f;
        float r = sqrtf(r2), qr = pf_irradiance_radius(q);
        bad_r += !(qr <= r && qr >= r * (1.0f - 0x1p-15f));
    }
    printf("%s, %llu photons: %zu of %zu points flat; shares: %zu above 0.5, %zu strictly between; "
           "%zu irradiances, %zu shares, %zu radii off\n",
           path, (unsigned long long)photons, flat, n, lit, mixed, bad_e, bad_share, bad_r);
    CHECK(flat > n / 10, "%s: only %zu of %zu points flat: the test would prove little", path, flat, n);
    CHECK(lit > 0 && mixed > 0, "%s: no point mostly lit directly (%zu) or partly (%zu)", path, lit, mixed);
    CHECK(bad_e == 0, "%s: %zu flat points' irradiance differs from the estimate at them", path, bad_e);
    CHECK(bad_share == 0, "%s: %zu points' direct share is off", path, bad_share);
    CHECK(bad_r == 0, "%s: %zu points' support radius is off", path, bad_r);

    PF_CHECK(pf_photon_maps_index(&fr.maps) == PF_OK);
    float near_r = fr.maps.near_r;
    PF_CHECK(pf_photon_maps_index(&fr.maps) == PF_OK);
    pf_vec3 lo, hi;
    pf_scene_geometry_bounds(scene, &lo, &hi);
    float size = pf_len(pf_sub(hi, lo));
    printf("%s: near_r %g (scene diagonal %g)\n", path, (double)near_r, (double)size);
    CHECK(near_r > 0.0f && near_r < size, "%s: near_r %g", path, (double)near_r);
    CHECK(fr.maps.near_r == near_r, "%s: near_r %g then %g", path, (double)near_r, (double)fr.maps.near_r);
    free(scratch);
    pf_pm_visible_scratch_free(&vis);
    pf_frame_close(&fr);
    pf_scene_destroy(&scene);
}

int main(void)
{
    pf_log_set_level(PF_LOG_WARN);
    s_share("tests/data/near/stripe.json", 100000);
    s_share("scenes/cornell-box/scene.json", 200000);
    printf("%d passed, %d failed\n", s_passed, s_failed);
    return s_failed ? 1 : 0;
}
