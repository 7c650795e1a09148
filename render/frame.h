/* frame.h: everything a tile render reads, built in one place: the scene,
 * its ray-tracing structure, the light table, the photon maps and the
 * irradiance texels. The in-process render, the coordinator (for its photon
 * pass and the time-limit probes) and the worker (from the job's blobs) all
 * build their frames through these verbs, so they render the same thing.
 *
 * Life of a frame:
 *   pf_frame_open (scene borrowed), pf_frame_open_owned or
 *   pf_frame_from_blobs (scene owned)
 *   -> the photon pass fills frame.maps (pf_photon_pass), or the blob does
 *   -> pf_frame_ready: the maps' lookup grid and the irradiance texels
 *   -> pf_render_ctx_init(ctx, frame, settings), pf_render_tile ...
 *   -> pf_frame_close.
 * A ready frame is read-only for rendering threads (the texels fill
 * themselves on first use, thread-safely). */
#ifndef PF_FRAME_H
#define PF_FRAME_H

#include <stddef.h>
#include <stdint.h>

#include "accel/accel.h"
#include "base/status.h"
#include "light/light.h"
#include "photon/irrtex.h"
#include "photon/photonmap.h"
#include "proto/messages.h"
#include "scene/scene.h"

/* A scene built once (the scene, its accel, its lights) that several frames
 * share (pf_frame_share): counted, freed by the last frame closed, from any
 * thread. */
typedef struct pf_frame_base pf_frame_base_t;

typedef struct pf_frame {
    const pf_scene_t *scene; /* the scene rendered (borrowed, or owned_scene) */
    pf_scene_t *owned_scene; /* set when the frame owns its scene (built from a blob) */
    pf_frame_base_t *base;   /* set when the scene, accel and lights are shared: base owns them */
    pf_accel_t *accel;
    pf_lights_t *lights;
    pf_photon_maps_t maps;   /* empty until filled by the photon pass or a blob */
    pf_irrtex_t *texels;     /* the irradiance lookups stored with the surface, or NULL */
} pf_frame_t;

/* Opens a frame on a finalized scene, which must outlive it: builds the
 * ray-tracing structure and the light table; the maps start empty. 0, or
 * PF_EEMBREE / PF_ENOMEM with err filled (the frame is then closed). */
int pf_frame_open(pf_frame_t *f, const pf_scene_t *scene, pf_error_t *err);

/* The same, taking the scene (*scene_p is nulled, also on failure, when
 * the scene is freed): the frame frees it on close. */
int pf_frame_open_owned(pf_frame_t *f, pf_scene_t **scene_p, pf_error_t *err);

/* Opens a frame from a job's blobs: the scene blob (pf_sceneblob_read) and
 * the photon-map blob (pf_mapfile_read, checked against scene_hash and the
 * hash of settings), then readies it (pf_frame_ready). 0, or a status with
 * err naming the blob and what was wrong with it (the frame is then closed). */
int pf_frame_from_blobs(pf_frame_t *f, const uint8_t *scene_blob, size_t scene_len, uint64_t scene_hash,
                        const uint8_t *maps_blob, size_t maps_len, uint64_t maps_hash, const pf_settings_t *settings,
                        pf_error_t *err);

/* Opens frame f on the scene, accel and lights of the open frame src
 * (one built from a blob, or opened owned), without building them again:
 * both frames share them from now on, and whichever closes last frees
 * them; f's maps start empty. 0, or PF_ENOMEM (f is then closed, src
 * unchanged). A borrowed scene (pf_frame_open) cannot be shared: PF_EINVAL. */
int pf_frame_share(pf_frame_t *f, pf_frame_t *src);

/* Reads the photon-map blob into an open frame without maps (checked
 * against scene_hash and the hash of settings), derives the deep gathers'
 * points and readies it (pf_frame_ready). 0, or a status with err naming
 * the blob; the frame keeps its scene either way. */
int pf_frame_read_maps(pf_frame_t *f, const uint8_t *maps_blob, size_t maps_len, uint64_t scene_hash,
                       uint64_t maps_hash, const pf_settings_t *settings, pf_error_t *err);

/* Readies the maps for rendering: the irradiance points' nearest-point grid
 * (pf_photon_maps_index) and the irradiance texels (pf_irrtex_create). Out
 * of memory for either leaves the frame usable, only slower, with a line in
 * the log. Call once, after the maps are in place. */
void pf_frame_ready(pf_frame_t *f);

/* Frees the maps and their texels, for the next progressive pass's photon
 * pass to fill (then pf_frame_ready again); the scene, accel and lights
 * stay. */
void pf_frame_drop_maps(pf_frame_t *f);

/* Frees what the frame owns (maps, texels, lights, accel, an owned scene);
 * NULL-safe; leaves it zeroed. */
void pf_frame_close(pf_frame_t *f);

/* This build's handshake fingerprint: the protocol's, with the photon
 * record and the photon-map blob format that frames are built from. */
pf_fingerprint_t pf_frame_fingerprint(void);

#endif
