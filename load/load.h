/* load.h: the scene loaders, one file per format (scene_json.c, obj.c,
 * mtl.c, ply.c, pbrt*.c), and pf_scene_load, which picks one by the file's
 * extension. They fill the scene model (scene/scene.h) through its builder
 * verbs and report every error as file:line. A new scene format is a new
 * file here and a branch in pf_scene_load. Single-threaded. */
#ifndef PF_LOAD_H
#define PF_LOAD_H

#include <stddef.h>
#include <stdint.h>

#include "base/status.h"
#include "base/vec.h"
#include "scene/scene.h"

/* One kind of loader warning (pbrt-v4 files): something the file asks for
 * that the scene model cannot hold, approximated or ignored. */
typedef struct pf_load_warning {
    char kind[96];    /* e.g. "texture", "unused parameter \"float foo\"" */
    char first[384];  /* "file:line: what" of the first occurrence */
    unsigned count;   /* occurrences */
} pf_load_warning_t;

#define PF_LOAD_MAX_WARNINGS 64

/* The warnings of one load, one entry per kind in order of first occurrence. */
typedef struct pf_load_report {
    pf_load_warning_t warnings[PF_LOAD_MAX_WARNINGS];
    size_t nwarnings; /* kinds held */
    size_t more;      /* kinds beyond PF_LOAD_MAX_WARNINGS (counted only) */
} pf_load_report_t;

/* How to load. All-zero is the default (what pf_scene_load does). */
typedef struct pf_load_opts {
    int strict;               /* 1: anything approximated or ignored is an error (pbrt-v4 files) */
    pf_load_report_t *report; /* when not NULL, filled with the load's warnings (pbrt-v4 files) */
} pf_load_opts_t;

/* Loads a scene by extension: .json (scene format), .obj (model alone with its
 * .mtl), .ply or .ply.gz (mesh alone), .pbrt (pbrt-v4 scene, see docs/pbrt.md).
 * Finalized on success. NULL with err filled on failure. */
pf_scene_t *pf_scene_load(const char *path, pf_error_t *err);
/* The same with options (opts may be NULL). */
pf_scene_t *pf_scene_load_opts(const char *path, const pf_load_opts_t *opts, pf_error_t *err);

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
/* Parses a pbrt-v4 scene file (and what it includes) into scene, not
 * finalized; opts may be NULL. Prints one warning line per kind of thing it
 * approximated or ignored (see docs/pbrt.md). */
int pf_pbrt_load(pf_scene_t *scene, const char *path, const pf_load_opts_t *opts, pf_error_t *err);
/* Parses a JSON scene file into scene (not finalized). */
int pf_scene_json_load(pf_scene_t *scene, const char *path, pf_error_t *err);

#endif
