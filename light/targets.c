/* targets.c: the specular targets caustic photons are aimed at (light.h's
 * pf_specular_targets) and the cone a target subtends from a point
 * (light.h), apart from light.c to keep that file within bounds. */
#include "light/light.h"

#include <float.h>
#include <stdlib.h>

int pf_specular_targets(const pf_scene_t *scene, pf_target_t **out)
{
    *out = NULL;
    size_t cap = scene->nmeshes + scene->nspheres, n = 0;
    if (cap == 0)
        return 0;
    pf_target_t *t = malloc(cap * sizeof *t);
    if (!t)
        return PF_ENOMEM;
    for (size_t m = 0; m < scene->nmeshes; m++) {
        const pf_mesh_t *mesh = &scene->meshes[m];
        pf_vec3 lo = pf_v3s(FLT_MAX), hi = pf_v3s(-FLT_MAX);
        for (size_t i = 0; i < mesh->ntris; i++) {
            pf_mat_type ty = scene->mats[mesh->mat[i]].type;
            if (ty == PF_MAT_DIFFUSE || ty == PF_MAT_DIFFUSE_TRANSMISSION)
                continue; /* diffuse transmission is diffuse for the caustic map; a coat is C (photon/trace.c) */
            for (int k = 0; k < 3; k++) {
                lo = pf_vmin(lo, mesh->pos[mesh->idx[3 * i + k]]);
                hi = pf_vmax(hi, mesh->pos[mesh->idx[3 * i + k]]);
            }
        }
        if (lo.x > hi.x)
            continue;
        pf_vec3 c = pf_scale(pf_add(lo, hi), 0.5f);
        /* Half the box diagonal, widened a little for the rounding above. */
        t[n++] = (pf_target_t){ c, 0.5f * pf_len(pf_sub(hi, lo)) * 1.001f + 1e-6f };
    }
    for (size_t i = 0; i < scene->nspheres; i++) {
        const pf_sphere_t *sp = &scene->spheres[i];
        pf_mat_type ty = scene->mats[sp->mat].type;
        if (ty != PF_MAT_DIFFUSE && ty != PF_MAT_DIFFUSE_TRANSMISSION)
            t[n++] = (pf_target_t){ sp->center, sp->radius * 1.001f };
    }
    if (n == 0) {
        free(t);
        return 0;
    }
    *out = t;
    return (int)n;
}

/* The cone from p that holds target t: axis and cos of the half-angle; a
 * point inside the sphere sees the whole sphere of directions (cos = -1). */
void pf_target_cone(pf_vec3 p, const pf_target_t *t, pf_vec3 *axis, float *cos_max, float *solid)
{
    pf_vec3 d = pf_sub(t->center, p);
    float dist2 = pf_len2(d);
    float r2 = t->radius * t->radius;
    if (dist2 <= r2) {
        *axis = pf_v3(0, 0, 1);
        *cos_max = -1.0f;
        *solid = 4.0f * PF_PI;
        return;
    }
    float dist = sqrtf(dist2);
    *axis = pf_scale(d, 1.0f / dist);
    float sin2 = r2 / dist2;
    float c = sqrtf(fmaxf(0.0f, 1.0f - sin2));
    *cos_max = c;
    /* 1 - cos without cancellation for small cones. */
    *solid = 2.0f * PF_PI * (sin2 / (1.0f + c));
}

