/* envmap_load.h: private to load/. Reads an environment image (by its
 * extension: PFM, OpenEXR, else Radiance HDR or an 8-bit image through
 * stb_image) into a scene map, for the JSON and pbrt readers. */
#ifndef PF_ENVMAP_LOAD_H
#define PF_ENVMAP_LOAD_H

#include "base/status.h"
#include "scene/envmap.h"

/* Reads path into *out with the given mapping and an identity frame: float
 * RGB, negative and non-finite values clamped to 0 (counted in *clamped). An
 * unreadable file, or a non-square image for the equal-area mapping, is an
 * error naming the file (err without file:line: the caller adds its own).
 * Logs one line with the map's size and memory. */
int pf_envmap_load(const char *path, int mapping, pf_envmap_t *out, size_t *clamped, pf_error_t *err);

#endif
