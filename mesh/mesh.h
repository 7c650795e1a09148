/* mesh.h: the readers of mesh files, each appending to the scene model
 * through its builder verbs: OBJ with its MTL materials (obj.c, mtl.c,
 * sharing the statement reader of text.c) and PLY, ASCII or binary, gzip
 * compressed or not (ply.c). The scene formats of load/ (JSON, pbrt-v4) and
 * pf_scene_load's bare .obj and .ply use them. Errors name the file and line.
 * Single-threaded. */
#ifndef PF_MESH_H
#define PF_MESH_H

#include <stdint.h>

#include "base/status.h"
#include "base/vec.h"
#include "scene/scene.h"

/* Loaders, each appending to a scene. xf (may be NULL) moves the geometry to
 * world space; mat_override >= 0 replaces every material the file names.
 * Errors name the file and line. */
int pf_obj_load(pf_scene_t *scene, const char *path, const pf_xform_t *xf, int mat_override, pf_error_t *err);
/* Appends the materials of an MTL file (later ones with a known name replace it). */
int pf_mtl_load(pf_scene_t *scene, const char *path, pf_error_t *err);
/* Loads a PLY mesh (ascii, binary little/big endian; gzip-compressed when the
 * name ends in .gz); material index mat. */
int pf_ply_load(pf_scene_t *scene, const char *path, const pf_xform_t *xf, uint32_t mat, pf_error_t *err);
/* Reads a PLY mesh into *out (zeroed first; the caller owns its arrays, to
 * free with pf_mesh_free or hand to pf_scene_add_mesh), every triangle with
 * material index mat. A file without faces gives ntris = 0 and a warning. */
int pf_ply_read(const char *path, const pf_xform_t *xf, uint32_t mat, pf_mesh_t *out, pf_error_t *err);

#endif
