/* scenes_gen.h: small scenes built in memory for the tests (a furnace
 * sphere, a parallelogram), shared by test_render.c and test_stress.c so the
 * geometry every furnace and plane test relies on is written once. */
#ifndef PF_TESTS_SCENES_GEN_H
#define PF_TESTS_SCENES_GEN_H

#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "base/status.h"
#include "scene/scene.h"

/* A geodesic sphere (subdivided octahedron) of 8 * 4^levels triangles, wound
 * so the face normals point inwards: emission and the lit side face the
 * centre. */
static inline void pf_test_inward_sphere(pf_scene_t *scene, int levels, float radius, uint32_t mat)
{
    size_t ntris = 8;
    for (int l = 0; l < levels; l++)
        ntris *= 4;
    pf_mesh_t m = { 0 };
    snprintf(m.name, sizeof m.name, "furnace");
    m.nverts = 3 * ntris;
    m.ntris = ntris;
    m.pos = malloc(m.nverts * sizeof *m.pos);
    m.idx = malloc(3 * ntris * sizeof *m.idx);
    m.mat = malloc(ntris * sizeof *m.mat);
    pf_vec3 *tri = malloc(3 * ntris * sizeof *tri), *next = malloc(3 * ntris * sizeof *next);
    PF_CHECK(m.pos && m.idx && m.mat && tri && next);
    const pf_vec3 ax[6] = { { 1, 0, 0 }, { -1, 0, 0 }, { 0, 1, 0 }, { 0, -1, 0 }, { 0, 0, 1 }, { 0, 0, -1 } };
    size_t n = 0;
    for (int sx = 0; sx < 2; sx++)
        for (int sy = 2; sy < 4; sy++)
            for (int sz = 4; sz < 6; sz++) {
                pf_vec3 a = ax[sx], b = ax[sy], c = ax[sz];
                if (pf_dot(pf_cross(pf_sub(b, a), pf_sub(c, a)), a) > 0) {
                    pf_vec3 t = b;
                    b = c;
                    c = t;
                }
                tri[n++] = a, tri[n++] = b, tri[n++] = c;
            }
    for (int l = 0; l < levels; l++) {
        size_t k = 0;
        for (size_t t = 0; t < n; t += 3) {
            pf_vec3 a = tri[t], b = tri[t + 1], c = tri[t + 2];
            pf_vec3 ab = pf_norm(pf_add(a, b)), bc = pf_norm(pf_add(b, c)), ca = pf_norm(pf_add(c, a));
            pf_vec3 out[12] = { a, ab, ca, ab, b, bc, ca, bc, c, ab, bc, ca };
            memcpy(&next[k], out, sizeof out);
            k += 12;
        }
        memcpy(tri, next, k * sizeof *tri);
        n = k;
    }
    for (size_t i = 0; i < n; i++) {
        m.pos[i] = pf_scale(tri[i], radius);
        m.idx[i] = (uint32_t)i;
    }
    for (size_t t = 0; t < ntris; t++)
        m.mat[t] = mat;
    free(tri);
    free(next);
    PF_CHECK(pf_scene_add_mesh(scene, &m) == PF_OK);
}

/* A parallelogram o, o+e1, o+e1+e2, o+e2 as two triangles; its face normal
 * is e1 x e2. */
static inline void pf_test_quad(pf_scene_t *scene, pf_vec3 o, pf_vec3 e1, pf_vec3 e2, uint32_t mat)
{
    pf_mesh_t m = { 0 };
    snprintf(m.name, sizeof m.name, "quad");
    m.nverts = 4;
    m.ntris = 2;
    m.pos = malloc(4 * sizeof *m.pos);
    m.idx = malloc(6 * sizeof *m.idx);
    m.mat = malloc(2 * sizeof *m.mat);
    PF_CHECK(m.pos && m.idx && m.mat);
    m.pos[0] = o;
    m.pos[1] = pf_add(o, e1);
    m.pos[2] = pf_add(pf_add(o, e1), e2);
    m.pos[3] = pf_add(o, e2);
    const uint32_t idx[6] = { 0, 1, 2, 0, 2, 3 };
    memcpy(m.idx, idx, sizeof idx);
    m.mat[0] = m.mat[1] = mat;
    PF_CHECK(pf_scene_add_mesh(scene, &m) == PF_OK);
}

#endif
