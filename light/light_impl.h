/* light_impl.h: private to light/. The light table's layout (light.c
 * builds it and samples direct light from it, emit.c emits photons from it)
 * and the two helpers both use. */
#ifndef PF_LIGHT_LIGHT_IMPL_H
#define PF_LIGHT_LIGHT_IMPL_H

#include <stddef.h>
#include <stdint.h>

#include "base/vec.h"
#include "light/envlight.h"
#include "light/lightbvh.h"
#include "light/lighttab.h"
#include "scene/scene.h"

typedef enum {
    PF_ENTRY_AREA,
    PF_ENTRY_POINT,
    PF_ENTRY_DISTANT,
    PF_ENTRY_INFINITE,
    PF_ENTRY_ENVMAP,
    PF_ENTRY_SPHERE
} pf_light_kind;

typedef struct pf_light_entry {
    pf_light_kind kind;
    uint32_t mesh, tri; /* area */
    uint32_t light;     /* point, spot, distant or infinite; the index into env for PF_ENTRY_ENVMAP; the sphere's */
    float area;         /* area and sphere */
    /* A point light outside the scene's bounding sphere emits photons only
     * into the cone that holds the sphere (cos_max > -1; axis towards the
     * centre): the others would leave the scene unseen. */
    pf_vec3 axis;
    float cos_max;
} pf_light_entry_t;

/* The table (light.h's opaque pf_lights_t; not included here, so that
 * light.c may include both without a circle). */
struct pf_lights {
    pf_light_entry_t *entries;
    double *cdf; /* n + 1 entries, cdf[n] = 1: photon emission's choice, by power */
    /* Direct light's choice: the same entries by power, but the distant
     * lights (deltas, few) at zero, since every direct estimate takes each
     * of them with a shadow ray of its own (pf_lights_distant); dcdf is cdf
     * itself when there are none, and all zero when only distant lights
     * remain (nothing to choose). */
    double *dcdf;
    uint32_t *distant; /* the entries of the distant lights */
    size_t ndistant;
    size_t n;
    size_t narea; /* entries [0, narea) are the area lights, sorted by (mesh, tri) */
    uint32_t *sphere_entry; /* sphere index -> 1 + its entry, 0 none; NULL without spheres */
    double power;
    /* The scene's bounding sphere (radius 0 without geometry): distant
     * lights shine through the disc it casts. */
    pf_vec3 center;
    float radius;
    pf_vec3 sky;   /* the radiance of the infinite lights, summed: one entry, the last */
    float sky_pmf; /* that entry's probability (0: none) */
    pf_envlight_t *env; /* the image-based infinite lights */
    size_t nenv;
    /* Direct light's choice (s_pick_direct): NULL bvh: by power, the
     * table's cdf; else a defensive mixture: with probability S_DEFENSIVE (light.c) by
     * power, else the bounded emitters through the light BVH with
     * probability 1 - p_inf and the unbounded ones (distant lights, the sky
     * entries) by their power among themselves (unb, unb_cdf; their summed
     * share pu) with probability p_inf. */
    pf_lightbvh_t *bvh;
    float p_inf;
    double pu;
    uint32_t *unb;
    double *unb_cdf; /* nunb + 1 entries */
    size_t nunb;
    /* Lookup tables (lighttab.h): guides over cdf and dcdf (one when they
     * are one), the area entries' records, entries [0, narea). */
    pf_cdf_guide_t cdf_guide, dcdf_guide;
    pf_emit_tri_t *tris;
};

/* Picks entry i with cdf[i] <= u < cdf[i+1] (cdf: self->cdf or self->dcdf);
 * *pmf its probability. */
size_t pf_lights_pick(const struct pf_lights *self, const double *cdf, float u, double *pmf);

/* A uniform point on a triangle (its record) or sphere entry e, its unit
 * face normal and error bound, *two whether it emits on both sides;
 * returns its Le. Uses u[0..1]. */
pf_vec3 pf_lights_surface_point(const struct pf_lights *self, const pf_scene_t *scene, const pf_light_entry_t *e,
                                const float *u, pf_vec3 *p, pf_vec3 *n, pf_vec3 *perr, int *two);

#endif
