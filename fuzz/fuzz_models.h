/* fuzz_models.h: small model files the loader targets place beside their
 * input, under the names that the seed scenes and OBJ files refer to, so
 * that a seed loads all the way (a JSON scene's obj and ply objects, an
 * OBJ's mtllib) and mutations explore the loaders behind it rather than
 * stopping at "cannot open". */
#ifndef PF_FUZZ_MODELS_H
#define PF_FUZZ_MODELS_H

#include "fuzz/fuzz_util.h"

#define S_FUZZ_MTL                                                                          \
    "newmtl mtlA\nKd 0.5 0.5 0.5\n\nnewmtl mtlB\nKd 0.2 0.2 0.2\n"                          \
    "newmtl Light\nKd 0 0 0\nKe 17 12 4\nnewmtl Floor\nKd 0.725 0.71 0.68\n"                 \
    "newmtl Mirror\nillum 3\nKs 0.9 0.9 0.9\nnewmtl Glass\nillum 7\nNi 1.5\n"

#define S_FUZZ_OBJ(mtl)                                                                     \
    "mtllib " mtl "\nv 0 0 0\nv 1 0 0\nv 1 1 0\nv 0 1 0\nvn 0 0 1\n"                         \
    "g partA\nusemtl mtlA\nf 1 2 3\ng partB\nusemtl mtlB\nf 1//1 3//1 4//1\n"                 \
    "g light\nusemtl Light\nf 4 3 1\n"

#define S_FUZZ_PLY                                                                          \
    "ply\nformat ascii 1.0\nelement vertex 3\nproperty float x\nproperty float y\n"          \
    "property float z\nelement face 1\nproperty list uchar int vertex_indices\nend_header\n" \
    "0 0 0\n1 0 0\n0 1 0\n3 0 1 2\n"

static const s_fuzz_file_t s_fuzz_models[] = {
    { "model.mtl", S_FUZZ_MTL },
    { "cornell-box.mtl", S_FUZZ_MTL },
    { "CornellBox-Sphere-Jensen.mtl", S_FUZZ_MTL },
    { "materials.mtl", S_FUZZ_MTL },
    { "extra.mtl", S_FUZZ_MTL },
    { "model.obj", S_FUZZ_OBJ("model.mtl") },
    { "cornell-box.obj", S_FUZZ_OBJ("cornell-box.mtl") },
    { "CornellBox-Sphere-Jensen.obj", S_FUZZ_OBJ("CornellBox-Sphere-Jensen.mtl") },
    { "tri.ply", S_FUZZ_PLY },
    { "bun_zipper.ply", S_FUZZ_PLY },
};
#define S_FUZZ_NMODELS ((int)(sizeof s_fuzz_models / sizeof s_fuzz_models[0]))

#endif
