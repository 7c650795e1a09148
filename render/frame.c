/* frame.c: building and freeing the inputs of a tile render; see frame.h.
 * Called from one thread per frame (the main thread, the coordinator's
 * photon thread or the worker's compute thread). */
#include "render/frame.h"

#include <inttypes.h>
#include <stdatomic.h>
#include <stdlib.h>
#include <string.h>

#include "base/log.h"
#include "photon/mapfile.h"
#include "photon/trace.h"
#include "proto/sceneblob.h"

struct pf_frame_base {
    atomic_int refs;
    pf_scene_t *scene;
    pf_accel_t *accel;
    pf_lights_t *lights;
};

int pf_frame_share(pf_frame_t *f, pf_frame_t *src)
{
    memset(f, 0, sizeof *f);
    if (!src->base) {
        if (!src->owned_scene)
            return PF_EINVAL;
        pf_frame_base_t *b = malloc(sizeof *b);
        if (!b)
            return PF_ENOMEM;
        atomic_init(&b->refs, 1);
        b->scene = src->owned_scene;
        b->accel = src->accel;
        b->lights = src->lights;
        src->owned_scene = NULL;
        src->base = b;
    }
    atomic_fetch_add_explicit(&src->base->refs, 1, memory_order_relaxed);
    f->base = src->base;
    f->scene = src->scene;
    f->accel = src->accel;
    f->lights = src->lights;
    return PF_OK;
}

int pf_frame_open(pf_frame_t *f, const pf_scene_t *scene, pf_error_t *err)
{
    memset(f, 0, sizeof *f);
    f->scene = scene;
    f->accel = pf_accel_create(scene, err);
    if (!f->accel) {
        pf_frame_close(f);
        return PF_EEMBREE;
    }
    f->lights = pf_lights_build(scene);
    if (!f->lights) {
        pf_frame_close(f);
        return pf_error_set(err, PF_ENOMEM, NULL, 0, "cannot build the light table: out of memory");
    }
    return PF_OK;
}

int pf_frame_open_owned(pf_frame_t *f, pf_scene_t **scene_p, pf_error_t *err)
{
    pf_scene_t *scene = *scene_p;
    *scene_p = NULL;
    int rc = pf_frame_open(f, scene, err);
    if (rc != PF_OK) {
        pf_scene_destroy(&scene);
        return rc;
    }
    f->owned_scene = scene;
    return PF_OK;
}

int pf_frame_from_blobs(pf_frame_t *f, const uint8_t *scene_blob, size_t scene_len, uint64_t scene_hash,
                        const uint8_t *maps_blob, size_t maps_len, uint64_t maps_hash, const pf_settings_t *settings,
                        pf_error_t *err)
{
    memset(f, 0, sizeof *f);
    pf_error_t why = { { 0 } };
    pf_scene_t *scene = pf_sceneblob_read(scene_blob, scene_len, &why);
    if (!scene)
        return pf_error_set(err, PF_EPARSE, NULL, 0, "scene blob %016" PRIx64 " rejected: %s", scene_hash, why.msg);
    int rc = pf_frame_open_owned(f, &scene, &why);
    if (rc == PF_EEMBREE)
        return pf_error_set(err, rc, NULL, 0, "cannot build the ray-tracing structure: %s", why.msg);
    if (rc != PF_OK)
        return pf_error_set(err, rc, NULL, 0, "%s", why.msg);
    rc = pf_frame_read_maps(f, maps_blob, maps_len, scene_hash, maps_hash, settings, err);
    if (rc != PF_OK)
        pf_frame_close(f);
    return rc;
}

int pf_frame_read_maps(pf_frame_t *f, const uint8_t *maps_blob, size_t maps_len, uint64_t scene_hash,
                       uint64_t maps_hash, const pf_settings_t *settings, pf_error_t *err)
{
    pf_error_t why = { { 0 } };
    int rc = pf_mapfile_read(maps_blob, maps_len, scene_hash, pf_settings_hash(settings), &f->maps, &why);
    if (rc != PF_OK)
        return pf_error_set(err, rc, NULL, 0, "photon-map blob %016" PRIx64 " rejected: %s", maps_hash, why.msg);
    /* the deep gathers' points: from the blob, or derived here when it has
     * none (a blob of only the maps, as the irradiance's own) */
    if (!f->maps.irradiance_deep &&
        pf_photon_deep_irradiance(&f->maps, f->accel, settings, settings->threads) != PF_OK) {
        pf_frame_drop_maps(f);
        return pf_error_set(err, PF_ENOMEM, NULL, 0, "out of memory for the deep gathers' irradiance points");
    }
    pf_frame_ready(f);
    return PF_OK;
}

void pf_frame_ready(pf_frame_t *f)
{
    if (!f->maps.irradiance)
        return;
    if (pf_photon_maps_index(&f->maps) != PF_OK)
        pf_warn("out of memory for the irradiance lookup grid: rendering goes on, slower");
    pf_debug("gather rays shorter than %.4g (twice the irradiance points' median support) light their ends themselves",
             (double)f->maps.near_r);
    if (!f->texels) {
        f->texels = pf_irrtex_create(f->scene, f->accel, f->maps.irradiance, f->maps.irradiance_r2);
        if (!f->texels && pf_kdtree_size(f->maps.irradiance))
            pf_debug("irradiance texels: none (the scene does not fit them, or out of memory); direct lookups");
    }
}

void pf_frame_drop_maps(pf_frame_t *f)
{
    pf_irrtex_destroy(&f->texels);
    pf_photon_maps_free(&f->maps);
}

void pf_frame_close(pf_frame_t *f)
{
    if (!f)
        return;
    /* The texels, the accel and the lights point into the scene: free them first. */
    pf_irrtex_destroy(&f->texels);
    pf_photon_maps_free(&f->maps);
    if (f->base) {
        pf_frame_base_t *b = f->base;
        if (atomic_fetch_sub_explicit(&b->refs, 1, memory_order_acq_rel) == 1) {
            pf_lights_destroy(&b->lights);
            pf_accel_destroy(&b->accel);
            pf_scene_destroy(&b->scene);
            free(b);
        }
        memset(f, 0, sizeof *f);
        return;
    }
    pf_lights_destroy(&f->lights);
    pf_accel_destroy(&f->accel);
    pf_scene_destroy(&f->owned_scene);
    memset(f, 0, sizeof *f);
}

pf_fingerprint_t pf_frame_fingerprint(void)
{
    return pf_fingerprint_make((uint16_t)sizeof(pf_photon_t), PF_MAPFILE_VERSION);
}
