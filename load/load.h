/* load.h: the scene loaders, one file per format (scene_json.c, obj.c,
 * mtl.c, ply.c), and pf_scene_load, which picks one by the file's extension.
 * They fill the scene model (scene/scene.h) through its builder verbs and
 * report every error as file:line. A new scene format is a new file here and
 * a branch in pf_scene_load. Single-threaded. */
#ifndef PF_LOAD_H
#define PF_LOAD_H

#include <stdint.h>

#include "base/status.h"
#include "base/vec.h"
#include "scene/scene.h"

/* Loads a scene by extension: .json (scene format), .obj (model alone with its
 * .mtl), .ply (mesh alone). Finalized on success. NULL with err filled on failure. */
pf_scene_t *pf_scene_load(const char *path, pf_error_t *err);

/* Loaders, each appending to a scene. xf (may be NULL) moves the geometry to
 * world space; mat_override >= 0 replaces every material the file names.
 * Errors name the file and line. */
int pf_obj_load(pf_scene_t *scene, const char *path, const pf_xform_t *xf, int mat_override, pf_error_t *err);
/* Appends the materials of an MTL file (later ones with a known name replace it). */
int pf_mtl_load(pf_scene_t *scene, const char *path, pf_error_t *err);
/* Loads a PLY mesh (ascii, binary little/big endian); material index mat. */
int pf_ply_load(pf_scene_t *scene, const char *path, const pf_xform_t *xf, uint32_t mat, pf_error_t *err);
/* Parses a JSON scene file into scene (not finalized). */
int pf_scene_json_load(pf_scene_t *scene, const char *path, pf_error_t *err);

#endif
