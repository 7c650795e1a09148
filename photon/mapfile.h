/* mapfile.h: the photon maps as one blob (the coordinator serializes them
 * once; workers validate them field by field before use).
 *
 * Layout (little-endian):
 *   header: u32 magic PF_MAPFILE_MAGIC, u16 version, u16 photon record size,
 *           u64 scene hash, u64 settings hash,
 *           u64 global_emitted, u64 caustic_emitted,
 *           f32 global_r2, caustic_r2, irradiance_r2,
 *           4 x { u64 count, f32 lo[3], f32 hi[3] }   (global, caustic, irradiance,
 *                                                      deep irradiance (photonmap.h
 *                                                      irradiance_deep; count 0 when
 *                                                      there is none); an empty map's
 *                                                      bounds are zeros)
 *           u64 content hash: pf_hash_bytes over the header bytes before it,
 *               continued over everything after the header
 *   body:   for each map: count photons (pos 3 f32, power 3 f32, dir u32,
 *           normal u32, whose bits 0 and 16 hold the node's split axis).
 * A reader checks magic, version, record size, that the scene and settings
 * hashes are the ones the job names, radii finite and > 0, counts against the
 * bytes left, the content hash, every position and power finite and power
 * >= 0, positions inside the stated bounds, axes in 0..2, and the kd ordering
 * (pf_kdtree_from_layout). */
#ifndef PF_MAPFILE_H
#define PF_MAPFILE_H

#include <stdint.h>

#include "base/status.h"
#include "base/wire.h"
#include "photon/photonmap.h"
#include "scene/scene.h"

#define PF_MAPFILE_MAGIC 0x50414d46u /* "FMAP" */
/* 2: the split axes moved from a byte array after the photons into the
 * photons' normal field. 3: a photon's dir holds 12+12 direction bits and
 * its bounce count (photon.h). 4: the deep gathers' irradiance points
 * travel as a fourth map (workers derived them, each a whole precompute).
 * 5: an irradiance point's support field carries its direct share in its
 * 8 lowest bits (photonmap.h). */
#define PF_MAPFILE_VERSION 5

/* Serializes maps into out (reset first). 0 or PF_ENOMEM. */
int pf_mapfile_write(const pf_photon_maps_t *maps, uint64_t scene_hash, uint64_t settings_hash, pf_buf_t *out);

/* Validates and rebuilds maps (all four trees; the deep irradiance NULL when empty) from a blob. expect_scene and
 * expect_settings are the hashes the job names (0 skips that check). 0, or
 * PF_EPARSE / PF_EMISMATCH / PF_ENOMEM with err naming the field. */
int pf_mapfile_read(const uint8_t *data, size_t len, uint64_t expect_scene, uint64_t expect_settings,
                    pf_photon_maps_t *maps, pf_error_t *err);

/* The hash of the settings fields that change the photon maps. */
uint64_t pf_settings_hash(const pf_settings_t *s);

#endif
