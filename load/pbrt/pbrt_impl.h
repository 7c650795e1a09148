/* pbrt_impl.h: private to load/pbrt*.c, the pbrt-v4 scene reader.
 *
 *   pbrt_lex.c    files, the Include stack, tokens with file:line:column
 *   pbrt_param.c  parameter lists, typed look-ups, colours and spectra
 *   pbrt.c        the directives, the graphics state, transforms, camera,
 *                 and pf_pbrt_load
 *   pbrt_util.c   interned names, the warnings and their report, matrices
 *   pbrt_shape.c  shapes into meshes and spheres, object instances
 *   pbrt_mat.c    materials, textures, area and point/spot lights
 *   pbrt_tex.c    textures made scene textures (imagemap, checkerboard, ...)
 *
 * One pf_pbrt_t holds everything a load owns; every function takes it.
 * Single-threaded, like every loader. Nothing outside load/ includes this. */
#ifndef PF_LOAD_PBRT_IMPL_H
#define PF_LOAD_PBRT_IMPL_H

#include <stddef.h>
#include <stdint.h>

#include "base/status.h"
#include "base/vec.h"
#include "load/load.h"
#include "scene/scene.h"

/* Limits that keep hostile input from exhausting memory or the stack. */
#define PF_PBRT_MAX_INCLUDE 32          /* nested Include/Import */
#define PF_PBRT_MAX_NEST (1 << 16)      /* nested AttributeBegin/TransformBegin */
#define PF_PBRT_MAX_TRIS ((uint64_t)1 << 26) /* triangles in the scene, instances flattened (~2 GB) */
#define PF_PBRT_MAX_NUMBER 1e30         /* |value| of any number in the file */
#define PF_PBRT_MAX_PRINTED 100         /* warning lines printed; the rest are counted */

/* Where a token is: an index into pf_pbrt_t.files, line and column from 1. */
typedef struct pf_pbrt_loc {
    int file, line, col;
} pf_pbrt_loc_t;

typedef enum {
    PF_PBRT_EOF,
    PF_PBRT_WORD,   /* a bare word: a directive, true or false */
    PF_PBRT_NUMBER,
    PF_PBRT_STRING, /* text is between the quotes, escapes still in */
    PF_PBRT_LBRACK,
    PF_PBRT_RBRACK,
} pf_pbrt_tok_kind;

typedef struct pf_pbrt_tok {
    pf_pbrt_tok_kind kind;
    const char *text; /* into the file's buffer, which lives as long as the load */
    size_t len;
    pf_pbrt_loc_t loc;
} pf_pbrt_tok_t;

typedef struct pf_pbrt_file {
    char *path; /* as opened */
    char *dir;  /* its folder, with a trailing '/' or empty */
    char *data; /* the whole file, NUL-terminated */
    size_t size;
    uint64_t dev, ino; /* identity, for recursive includes */
} pf_pbrt_file_t;

/* An open file on the Include stack and the read position in it. */
typedef struct pf_pbrt_frame {
    int file;
    size_t pos;
    int line, col;
    pf_pbrt_loc_t from; /* the Include that opened it (file -1 for the main one) */
} pf_pbrt_frame_t;

typedef enum {
    PF_PBRT_P_FLOAT,
    PF_PBRT_P_INTEGER,
    PF_PBRT_P_BOOL,
    PF_PBRT_P_STRING,
    PF_PBRT_P_RGB,
    PF_PBRT_P_SPECTRUM,
    PF_PBRT_P_BLACKBODY,
    PF_PBRT_P_POINT2,
    PF_PBRT_P_VECTOR2,
    PF_PBRT_P_POINT3,
    PF_PBRT_P_VECTOR3,
    PF_PBRT_P_NORMAL3,
    PF_PBRT_P_TEXTURE,
} pf_pbrt_ptype;

/* One "type name" [ values ] of a parameter list. Numbers and strings are
 * kept apart (a spectrum may hold either). */
typedef struct pf_pbrt_param {
    pf_pbrt_ptype type;
    char *name;
    pf_pbrt_loc_t loc;
    double *num;
    size_t nnum, cap_num;
    char **str;
    size_t nstr, cap_str;
    int used;
} pf_pbrt_param_t;

typedef struct pf_pbrt_params {
    pf_pbrt_param_t *p;
    size_t n, cap;
} pf_pbrt_params_t;

typedef double pf_pbrt_m4[4][4];

/* What a shape takes from the graphics state for its material: the named
 * material (by name id), an anonymous Material (by record), or pbrt's default
 * (diffuse, reflectance 0.5). */
enum { PF_PBRT_MAT_DEFAULT, PF_PBRT_MAT_NAMED, PF_PBRT_MAT_ANON };

typedef struct pf_pbrt_gstate {
    pf_pbrt_m4 ctm;
    int reverse;   /* ReverseOrientation in effect */
    int mat_kind;  /* PF_PBRT_MAT_* */
    int mat;       /* name id or material record */
    pf_pbrt_loc_t mat_loc; /* the NamedMaterial/Material directive */
    int area;      /* area light record, or -1 */
    int medium_in, medium_out; /* MediumInterface's media (name ids; -1: none, pbrt's "") */
    pf_pbrt_loc_t medium_loc;  /* the MediumInterface in effect */
    char kind;     /* on the stack: 'A' AttributeBegin, 'T' TransformBegin, 'O' ObjectBegin */
    pf_pbrt_loc_t begin;
} pf_pbrt_gstate_t;

/* A Material or MakeNamedMaterial, converted on first use. */
typedef struct pf_pbrt_mat {
    int name;        /* name id, or -1 for Material */
    char *type;
    pf_pbrt_params_t params;
    pf_pbrt_loc_t loc;
    int converted;   /* 0 not yet, 1 done, -1 being converted (a mix cycle) */
    int no_surface;  /* interface: shapes with it are dropped */
    uint32_t part;   /* 1 + its scene material's index once added as a part of a mix; 0 */
    pf_material_t m;
} pf_pbrt_mat_t;

typedef struct pf_pbrt_tex {
    int name;        /* name id */
    int is_float;    /* "float" texture, else "spectrum" */
    char *cls;       /* imagemap, constant, ... */
    pf_pbrt_params_t params;
    pf_pbrt_loc_t loc;
    uint32_t ref;    /* the scene texture made of it (1 + index), 0 not yet (pbrt_tex.c) */
    int converting;  /* being made: a texture that names itself */
} pf_pbrt_tex_t;

/* An AreaLightSource, evaluated at once. */
typedef struct pf_pbrt_area {
    pf_vec3 le;      /* radiance, scale and spectrum normalization applied */
    double power;    /* > 0: the shape's power in W (pbrt's "power") */
    int twosided;
    pf_pbrt_loc_t loc;
} pf_pbrt_area_t;

/* A MakeNamedMedium: what photonfarm renders of it, its absorption
 * (pbrt_medium.c). */
typedef struct pf_pbrt_medium {
    pf_vec3 sigma_a; /* sigma_a times scale, per world unit; 0 for a medium not rendered */
    pf_pbrt_loc_t loc;
} pf_pbrt_medium_t;

/* A distinct (material, area light, emission, media) pair; one scene material each. */
typedef struct pf_pbrt_pair {
    int mat_kind, mat, area;
    int medium_in, medium_out; /* name ids, -1 none */
    pf_pbrt_loc_t medium_loc;
    pf_vec3 le;
    pf_pbrt_loc_t loc;     /* the first shape */
    pf_pbrt_loc_t mat_loc; /* the NamedMaterial or Material in effect */
    int out;           /* scene material index, -1 no surface */
} pf_pbrt_pair_t;

/* A mesh or sphere made by a shape: mesh.mat[] holds pair indices until the
 * end of the load. */
typedef struct pf_pbrt_meshes {
    pf_mesh_t *m;
    size_t n, cap;
    pf_sphere_t *s; /* spheres (mat: a pair index) */
    size_t ns, caps;
} pf_pbrt_meshes_t;

typedef struct pf_pbrt_object {
    int name;
    pf_pbrt_meshes_t shapes;
    pf_pbrt_loc_t loc;
    int emitters_dropped;
} pf_pbrt_object_t;

typedef struct pf_pbrt_coordsys {
    int name;
    pf_pbrt_m4 m;
} pf_pbrt_coordsys_t;

/* The interned strings (material, texture, object and coordinate system
 * names) and an open-addressing index over them. */
typedef struct pf_pbrt_names {
    char **s;
    size_t n, cap;
    int32_t *slot;
    size_t nslots;
} pf_pbrt_names_t;

/* One kind of warning, gathered; printed at the end of the load. */
typedef struct pf_pbrt_warning {
    char *kind;
    char *first; /* "file:line: what" */
    unsigned count;
} pf_pbrt_warning_t;

typedef struct pf_pbrt {
    pf_scene_t *scene;
    pf_error_t *err;
    int strict;
    pf_load_report_t *report;
    /* lexer */
    pf_pbrt_file_t *files;
    size_t nfiles, cap_files;
    pf_pbrt_frame_t stack[PF_PBRT_MAX_INCLUDE + 1];
    int depth; /* frames in stack */
    pf_pbrt_tok_t peek;
    int has_peek;
    char *main_dir;
    /* graphics state */
    pf_pbrt_gstate_t gs;
    pf_pbrt_gstate_t *gstack;
    size_t ngstack, cap_gstack;
    int in_world;
    int xform_end_only; /* ActiveTransform EndTime: transforms move the end transform alone */
    int have_camera;
    int have_filter; /* a PixelFilter was read (else pbrt-v4's default gaussian) */
    pf_pbrt_m4 camera_from_world;
    pf_pbrt_coordsys_t *coordsys;
    size_t ncoordsys, cap_coordsys;
    pf_pbrt_names_t names;
    int32_t *named_mat;  /* name id -> material record, -1 */
    int32_t *named_ftex, *named_stex; /* name id -> texture record, -1 */
    int32_t *named_obj;  /* name id -> object, -1 */
    int32_t *named_warn; /* name id (of a warning kind) -> warning, -1 */
    int32_t *named_pair; /* name id (of a pair's key) -> pair, -1 */
    int32_t *named_medium; /* name id -> medium record, -1 */
    size_t cap_named;    /* entries in each named_* array */
    pf_pbrt_mat_t *mats;
    size_t nmats, cap_mats;
    pf_pbrt_tex_t *texs;
    size_t ntexs, cap_texs;
    pf_pbrt_area_t *areas;
    size_t nareas, cap_areas;
    pf_pbrt_pair_t *pairs;
    size_t npairs, cap_pairs;
    pf_pbrt_medium_t *media;
    size_t nmedia, cap_media;
    int camera_medium;       /* the outside medium at Camera (pbrt's camera medium), name id or -1 */
    pf_pbrt_loc_t camera_loc;
    pf_pbrt_object_t *objects;
    size_t nobjects, cap_objects;
    int cur_object; /* the ObjectBegin being defined, or -1 */
    pf_pbrt_meshes_t shapes;
    uint64_t ntris; /* every triangle made so far, instances included */
    unsigned nshapes; /* for mesh names */
    uint32_t shape_alpha; /* the Shape being read: its alpha texture ref (pbrt_tex.c), 0 opaque */
    pf_pbrt_warning_t *warnings;
    size_t nwarnings, cap_warnings;
} pf_pbrt_t;

/* ---- pbrt_lex.c ---- */

/* Opens the file at path (resolved by the caller) on top of the Include
 * stack; from is the directive that asked (file -1 for the main file).
 * Errors: cannot open, a recursive include (the chain is named), too deep. */
int pf_pbrt_push_file(pf_pbrt_t *c, const char *path, pf_pbrt_loc_t from);
/* The next token (it may open no file: Include is the parser's). EOF at the
 * end of the main file; an included file's end pops it silently. */
int pf_pbrt_next(pf_pbrt_t *c, pf_pbrt_tok_t *t);
int pf_pbrt_peek(pf_pbrt_t *c, pf_pbrt_tok_t *t);
/* The token's number: finite, |x| <= PF_PBRT_MAX_NUMBER; an error naming
 * file:line:column otherwise. */
int pf_pbrt_tok_number(pf_pbrt_t *c, const pf_pbrt_tok_t *t, double *out);
/* The string token's text with escapes resolved, newly allocated. */
int pf_pbrt_tok_string(pf_pbrt_t *c, const pf_pbrt_tok_t *t, char **out);
/* Whether a word token is exactly w. */
int pf_pbrt_tok_is(const pf_pbrt_tok_t *t, const char *w);
/* "file:line:col: msg" into c->err; returns st. */
int pf_pbrt_error(pf_pbrt_t *c, int st, pf_pbrt_loc_t loc, const char *fmt, ...) __attribute__((format(printf, 4, 5)));
/* "file:line: msg" (no column: the whole directive or parameter). */
int pf_pbrt_error_line(pf_pbrt_t *c, int st, pf_pbrt_loc_t loc, const char *fmt, ...)
    __attribute__((format(printf, 4, 5)));
/* The file name of a location ("?" when none). */
const char *pf_pbrt_file_name(const pf_pbrt_t *c, pf_pbrt_loc_t loc);
/* Resolves a file name from the scene against the main file's folder, then
 * the folder of the file at loc (for Include the other way round); absolute
 * names as they are. Writes into out; 0, or an error when it is too long. */
int pf_pbrt_resolve(pf_pbrt_t *c, pf_pbrt_loc_t loc, const char *name, int include, char *out, size_t cap);
void pf_pbrt_lex_free(pf_pbrt_t *c);

/* ---- pbrt_param.c ---- */

/* Reads the parameter list that follows a directive's arguments. */
int pf_pbrt_read_params(pf_pbrt_t *c, pf_pbrt_params_t *out);
void pf_pbrt_params_free(pf_pbrt_params_t *ps);
/* Finds the parameter called name (any type) and marks it used; NULL if absent. */
pf_pbrt_param_t *pf_pbrt_param(pf_pbrt_params_t *ps, const char *name);
/* Typed single values with defaults: a wrong type or count is an error. */
int pf_pbrt_get_float(pf_pbrt_t *c, pf_pbrt_params_t *ps, const char *name, double def, double *out);
int pf_pbrt_get_int(pf_pbrt_t *c, pf_pbrt_params_t *ps, const char *name, int def, int *out);
int pf_pbrt_get_bool(pf_pbrt_t *c, pf_pbrt_params_t *ps, const char *name, int def, int *out);
/* *out is the parameter's string (owned by ps) or def. */
int pf_pbrt_get_string(pf_pbrt_t *c, pf_pbrt_params_t *ps, const char *name, const char *def, const char **out);
int pf_pbrt_get_point3(pf_pbrt_t *c, pf_pbrt_params_t *ps, const char *name, pf_vec3 def, double out[3]);
/* A 3-vector array (point3, normal, vector3) of exactly-3k numbers: *out
 * points into the parameter (NULL, n = 0 when absent). */
int pf_pbrt_get_vec3s(pf_pbrt_t *c, pf_pbrt_params_t *ps, const char *name, const double **out, size_t *n);
/* An integer array: values checked integral and within [0, hi]. */
int pf_pbrt_get_ints(pf_pbrt_t *c, pf_pbrt_params_t *ps, const char *name, int64_t hi, uint32_t **out, size_t *n);

/* How a colour parameter is used: pbrt converts spectra differently for each. */
typedef enum { PF_PBRT_ALBEDO, PF_PBRT_UNBOUNDED, PF_PBRT_ILLUMINANT } pf_pbrt_stype;
/* A colour parameter (rgb, spectrum, blackbody, float or texture) as linear
 * sRGB. Absent: def, *found 0. A texture: its constant value when it is a
 * constant texture, else def and a "texture" warning. what names the owner
 * for messages. */
int pf_pbrt_get_color(pf_pbrt_t *c, pf_pbrt_params_t *ps, const char *name, pf_pbrt_stype st, pf_vec3 def,
                      const char *what, pf_vec3 *out, int *found);
/* A float parameter that pbrt allows to be a texture (roughness, ...). */
int pf_pbrt_get_float_tex(pf_pbrt_t *c, pf_pbrt_params_t *ps, const char *name, double def, const char *what,
                          double *out, int *found);
/* The conductor constants of a named spectrum ("metal-Au-eta"), the index of
 * a named glass ("glass-BK7"): 1 and *out, or 0 when unknown. */
int pf_pbrt_named_metal(const char *name, pf_vec3 *out);
int pf_pbrt_named_glass(const char *name, double *ior);
/* A blackbody at kelvin as linear sRGB of luminance 1 (pbrt normalizes an
 * emitter's spectrum to 1 nit before its scale). */
pf_vec3 pf_pbrt_blackbody(double kelvin);
/* Warns "unused parameter" for every parameter not marked used. */
int pf_pbrt_check_unused(pf_pbrt_t *c, pf_pbrt_params_t *ps, const char *what);

/* ---- pbrt_util.c ---- */

/* Gathers one warning of kind (what the user should know happened, e.g.
 * "texture"); in strict mode an error naming file:line. Returns 0 or that
 * error. */
int pf_pbrt_warn(pf_pbrt_t *c, pf_pbrt_loc_t loc, const char *kind, const char *fmt, ...)
    __attribute__((format(printf, 4, 5)));
/* Interns a string: its id (>= 0) or PF_ENOMEM. */
int pf_pbrt_intern(pf_pbrt_t *c, const char *s);
/* The id of s when interned, else -1. */
int pf_pbrt_name_find(const pf_pbrt_t *c, const char *s);
/* 4x4 helpers (row-major; points are columns, as in pbrt). */
void pf_pbrt_m4_mul(const pf_pbrt_m4 a, const pf_pbrt_m4 b, pf_pbrt_m4 out);
int pf_pbrt_m4_inverse(const pf_pbrt_m4 m, pf_pbrt_m4 out);
double pf_pbrt_m4_det3(const pf_pbrt_m4 m);
void pf_pbrt_m4_identity(pf_pbrt_m4 m);
/* Prints one line per warning kind (pf_warn) and fills c->report. */
void pf_pbrt_report(pf_pbrt_t *c);

/* ---- pbrt_medium.c ---- */

/* MakeNamedMedium name (type and parameters in ps): records its absorption
 * and reports what of it is not rendered. */
int pf_pbrt_medium(pf_pbrt_t *c, const char *name, pf_pbrt_params_t *ps, pf_pbrt_loc_t loc);
/* MediumInterface inside outside ("" none): the media of the shapes that follow. */
int pf_pbrt_medium_interface(pf_pbrt_t *c, const char *inside, const char *outside, pf_pbrt_loc_t loc);
/* The absorption of medium name id (-1: none, 0) into *sigma; an undefined
 * name is an error at loc, the MediumInterface that named it. */
int pf_pbrt_medium_sigma(pf_pbrt_t *c, int id, pf_pbrt_loc_t loc, pf_vec3 *sigma);
/* After the parse: reports a camera inside an absorbing medium. */
int pf_pbrt_camera_medium(pf_pbrt_t *c);

/* ---- pbrt_shape.c ---- */

int pf_pbrt_shape(pf_pbrt_t *c, const char *type, pf_pbrt_params_t *ps, pf_pbrt_loc_t loc);
int pf_pbrt_object_instance(pf_pbrt_t *c, const char *name, pf_pbrt_loc_t loc);
void pf_pbrt_meshes_free(pf_pbrt_meshes_t *ms);
/* Moves every mesh and sphere into the scene with its pair's material,
 * dropping those of a material without a surface (interface). */
int pf_pbrt_emit_shapes(pf_pbrt_t *c);

/* ---- pbrt_mat.c ---- */

int pf_pbrt_texture(pf_pbrt_t *c, const char *name, const char *type, const char *cls, pf_pbrt_params_t *ps,
                    pf_pbrt_loc_t loc);
/* Checks a texture reference: the record of name (float or spectrum), or an
 * error at loc. */
int pf_pbrt_find_texture(pf_pbrt_t *c, const char *name, int is_float, pf_pbrt_loc_t loc, pf_pbrt_tex_t **out);
/* Material / MakeNamedMaterial: takes *ps. */
int pf_pbrt_material(pf_pbrt_t *c, const char *name, const char *type, pf_pbrt_params_t *ps, pf_pbrt_loc_t loc);

/* ---- pbrt_tex.c ---- */
/* The scene texture of a "texture" colour parameter p (a spectrum texture),
 * made on first use: *ref its ref, or 0 when pbrt's texture is a constant
 * (the caller reads the constant) or of a class not rendered (the caller
 * warns and uses its default). */
int pf_pbrt_color_texture(pf_pbrt_t *c, pf_pbrt_param_t *p, uint32_t *ref);
/* Texture ref times k: *out a new scale texture of it, or ref itself when k
 * is 1 or ref is 0 (none). */
int pf_pbrt_scaled_texture(pf_pbrt_t *c, uint32_t ref, double k, pf_pbrt_loc_t loc, uint32_t *out);
/* A float texture parameter p as a scene texture ref in *ref (constants
 * too); 0 when its class is not rendered. p is marked used when made. */
int pf_pbrt_float_texture(pf_pbrt_t *c, pf_pbrt_param_t *p, uint32_t *ref);
/* ---- pbrt_maps.c ---- */
/* A material's "normalmap" (an image file, read linear) and "displacement"
 * (a float texture) into m's normal_tex and bump_tex; their parameters are
 * marked used. Unrendered texture classes are warned. */
int pf_pbrt_mat_maps(pf_pbrt_t *c, pf_pbrt_params_t *ps, pf_material_t *m, const char *what);
/* The roughness of a conductor or coateddiffuse when "roughness",
 * "uroughness" or "vroughness" is a non-constant texture: m->rough_tex (the
 * mean of u and v when they differ) and m->rough_remap ("remaproughness"),
 * *done 1 and the parameters used; *done 0 and nothing touched otherwise. */
int pf_pbrt_rough_texture(pf_pbrt_t *c, pf_pbrt_params_t *ps, pf_material_t *m, int *done);
/* A shape's "alpha" (float or float texture) as a scene texture ref in *ref:
 * 0 when absent or 1 (opaque), or when its texture class is not rendered
 * (warned). */
int pf_pbrt_alpha_texture(pf_pbrt_t *c, pf_pbrt_params_t *ps, uint32_t *ref);
/* A float parameter that may be a texture: a texture the scene renders
 * gives its ref in *ref (and *value = def); otherwise *ref = 0 and *value is
 * the number, or what pf_pbrt_get_float_tex makes of a texture it cannot
 * render (a constant's value, or def with its warning). */
int pf_pbrt_float_param(pf_pbrt_t *c, pf_pbrt_params_t *ps, const char *name, double def, const char *what,
                        double *value, uint32_t *ref);
int pf_pbrt_area_light(pf_pbrt_t *c, const char *type, pf_pbrt_params_t *ps, pf_pbrt_loc_t loc);
int pf_pbrt_light(pf_pbrt_t *c, const char *type, pf_pbrt_params_t *ps, pf_pbrt_loc_t loc);
/* ---- pbrt_env.c ---- */

/* LightSource "infinite" with "filename" file (its other parameters in ps):
 * reads the map and adds an image-based infinite light. */
int pf_pbrt_image_infinite(pf_pbrt_t *c, pf_pbrt_params_t *ps, pf_pbrt_loc_t loc, const char *file);

/* The pair index for the current material and the area light area (-1)
 * emitting le. */
int pf_pbrt_pair(pf_pbrt_t *c, int area, pf_vec3 le, pf_pbrt_loc_t loc);
/* Makes the scene materials of every pair (pair.out) and converts the
 * materials no shape used, for their warnings. */
int pf_pbrt_emit_materials(pf_pbrt_t *c);

#endif
