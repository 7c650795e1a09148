/* json_ctx.h: private to load/. What the JSON scene loader's two
 * files share:
 *
 *   scene_json_read.c  the file's text, the node-to-line table, error
 *                      reports at file:line, and typed access to values;
 *   scene_json.c       the scene's sections and pf_scene_json_load;
 *   scene_json_env.c   the image-based infinite light;
 *   scene_json_mat.c   the diffusetransmission and mix materials.
 *
 * Nothing outside them includes this header; the public interface is
 * pf_scene_json_load in load.h. The types and the S_FAIL_ macros keep the
 * names they had when both were one file. Every function that takes a
 * context reports its errors through it (c->err, file c->path) and returns
 * 0 or a negative status. */
#ifndef PF_SCENE_JSON_IMPL_H
#define PF_SCENE_JSON_IMPL_H

#include <cjson/cJSON.h>
#include <stddef.h>
#include <stdint.h>

#include "base/status.h"
#include "base/vec.h"
#include "scene/scene.h"

/* One node's lines; the table is sorted by node address. */
typedef struct s_line {
    const cJSON *node;
    int key_line; /* line of the member's key; the value's line for array elements and the root */
    int line;     /* line where the value starts */
} s_line_t;

/* One load's state. */
typedef struct s_ctx {
    pf_scene_t *scene;
    pf_error_t *err;
    const char *path;
    char dir[1024];  /* the JSON file's folder ("" for the working directory) */
    s_line_t *lines; /* sorted by node */
    size_t nlines;
    size_t mat_base; /* scene->nmats before this file's materials */
    size_t mat_end;  /* one past this file's materials */
} s_ctx_t;

/* ---- the file and its lines ---- */

/* Reads the whole file into *text_p (malloc'd, NUL-terminated; the caller
 * frees it), refusing files over 64 MiB. 0, or an error filled in err. */
int pf_json_read_file(const char *path, char **text_p, size_t *len_p, pf_error_t *err);
/* The 1-based line of byte pos of text. */
int pf_json_line_at(const char *text, size_t pos);
/* Reports a cJSON syntax error at at (cJSON's error position; NULL or out
 * of the text means the end) with the line and the text near it. */
int pf_json_syntax_error(const char *path, const char *text, size_t len, const char *at, pf_error_t *err);
/* Builds the node-to-line table of root, parsed from text (*tab_p malloc'd,
 * the caller frees it). Left empty when the scanner and cJSON disagree
 * (errors then name no line); PF_ENOMEM when out of memory. */
int pf_json_build_lines(const char *text, size_t len, const cJSON *root, s_line_t **tab_p, size_t *n_p);

/* ---- error reports ---- */

/* The line where node's value starts, and of its key; 0 when unknown. */
int pf_json_line_of(const s_ctx_t *c, const cJSON *node);
int pf_json_key_line_of(const s_ctx_t *c, const cJSON *node);
/* Reports status at c->path:line with a printf message; returns status. */
int pf_json_fail_line(s_ctx_t *c, int status, int line, const char *fmt, ...) __attribute__((format(printf, 4, 5)));
/* Reports at the line where the value `at` starts. */
#define S_FAIL_AT(c, at, ...) pf_json_fail_line((c), PF_EPARSE, pf_json_line_of((c), (at)), __VA_ARGS__)
/* Reports at the line of the member's key (for unknown and duplicate keys). */
#define S_FAIL_KEY(c, at, ...) pf_json_fail_line((c), PF_EPARSE, pf_json_key_line_of((c), (at)), __VA_ARGS__)
/* "a number", "a string", ...: v's type for messages. */
const char *pf_json_type_name(const cJSON *v);

/* ---- typed access ----
 * key and what name the value and its object in messages ("'fov' in
 * camera"); each checks the value and fills *out only when it is good. */

static inline const cJSON *pf_json_get(const cJSON *obj, const char *key)
{
    return cJSON_GetObjectItemCaseSensitive(obj, key);
}
/* node must be an object whose keys are all in allowed (NULL-ended;
 * "comment" is always allowed), each once. */
int pf_json_check_object(s_ctx_t *c, const cJSON *node, const char *what, const char *const *allowed);
/* A key that must be present. */
int pf_json_require(s_ctx_t *c, const cJSON *obj, const char *key, const char *what, const cJSON **out);
/* A finite number that fits a float. */
int pf_json_float(s_ctx_t *c, const cJSON *v, const char *key, const char *what, float *out);
/* An integer in [lo, hi]. */
int pf_json_int(s_ctx_t *c, const cJSON *v, const char *key, const char *what, int lo, int hi, int *out);
/* An integer in [0, 2^53] (exact in the double JSON gives). */
int pf_json_u64(s_ctx_t *c, const cJSON *v, const char *key, const char *what, uint64_t *out);
/* A non-empty string (owned by the tree). */
int pf_json_string(s_ctx_t *c, const cJSON *v, const char *key, const char *what, const char **out);
/* The path of a file named in the scene (at v): as written when absolute,
 * else beside the JSON file, into path (size bytes). 0, or an error at v
 * when it does not fit. */
int pf_json_file_path(s_ctx_t *c, const cJSON *v, const char *file, char *path, size_t size);
/* An array of exactly n numbers, each fitting a float. */
int pf_json_floats(s_ctx_t *c, const cJSON *v, const char *key, const char *what, int n, float *out);
int pf_json_vec3(s_ctx_t *c, const cJSON *v, const char *key, const char *what, pf_vec3 *out);
/* Whether every coordinate lies within +-1e18, the ray tracer's range. */
int pf_json_in_range(pf_vec3 v);
/* A vec3 within that range. */
int pf_json_position(s_ctx_t *c, const cJSON *v, const char *key, const char *what, pf_vec3 *out);
/* An RGB colour (3 numbers, or one for grey), each channel in [lo, hi]. */
int pf_json_rgb(s_ctx_t *c, const cJSON *v, const char *key, const char *what, float lo, float hi, pf_vec3 *out);

/* ---- scene_json_env.c ---- */

/* An infinite light with "image": reads the map into the scene and fills *l. */
int pf_json_envlight(s_ctx_t *c, const cJSON *o, pf_light_t *l);
/* ---- scene_json_maps.c ---- */
/* Whether key is one of a material's map keys (for every type). */
int pf_json_is_map_key(const char *key);
/* A material object's "normal_map", "bump" and "bump_scale" into mat's
 * normal_tex and bump_tex (images loaded here). 0 or a status, err filled. */
int pf_json_maps(s_ctx_t *c, const cJSON *m, pf_material_t *mat);

/* ---- scene_json_mat.c ---- */

/* When type is "diffusetransmission" or "mix": 1, with mat's type and
 * defaults set and *valid the kind's keys; 0 for any other type. */
int pf_json_material_kind(const char *type, pf_material_t *mat, const char *const **valid);
/* The kind's own keys (a mix's "materials" and "amount") and checks (kd +
 * kt <= 1), once the shared keys are read into mat; nothing for the other kinds. */
int pf_json_material_more(s_ctx_t *c, const cJSON *m, pf_material_t *mat);

#endif
