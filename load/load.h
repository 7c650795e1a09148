/* load.h: the scene formats (JSON: scene_json.c; pbrt-v4: pbrt/), and
 * pf_scene_load, which picks a loader by the file's extension (a bare .obj
 * or .ply goes to the mesh readers of mesh/mesh.h, included here). They fill
 * the scene model (scene/scene.h) through its builder verbs and report every
 * error as file:line. A new scene format is a new file here and a branch in
 * pf_scene_load. Single-threaded. */
#ifndef PF_LOAD_H
#define PF_LOAD_H

#include <stddef.h>
#include <stdint.h>

#include "base/status.h"
#include "base/vec.h"
#include "mesh/mesh.h"
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

/* Parses a pbrt-v4 scene file (and what it includes) into scene, not
 * finalized; opts may be NULL. Prints one warning line per kind of thing it
 * approximated or ignored (see docs/pbrt.md). */
int pf_pbrt_load(pf_scene_t *scene, const char *path, const pf_load_opts_t *opts, pf_error_t *err);
/* Parses a JSON scene file into scene (not finalized). */
int pf_scene_json_load(pf_scene_t *scene, const char *path, pf_error_t *err);

#endif
