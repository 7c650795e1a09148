/* accel.h: ray intersection through Embree 3: one triangle geometry per mesh
 * and one analytic-sphere geometry for all spheres. Hit points are
 * reconstructed from barycentrics (triangles) or reprojected onto the surface
 * (spheres) and carry a bound on their floating-point error, so that spawned
 * rays are offset by that bound instead of a fixed epsilon (pbrt-v3, 3.9).
 * Built once; intersection queries are safe from any number of threads. */
#ifndef PF_ACCEL_H
#define PF_ACCEL_H

#include <stdint.h>

#include "base/status.h"
#include "base/vec.h"
#include "scene/scene.h"

typedef struct pf_accel pf_accel_t;

typedef struct pf_hit {
    float t;
    pf_vec3 p;     /* hit point */
    pf_vec3 perr;  /* per-axis bound on |p - exact point| */
    pf_vec3 ng;    /* unit geometric normal: the winding's, or the vertex normals' side, or outward (spheres) */
    pf_vec3 ns;    /* unit shading normal, in ng's hemisphere */
    uint32_t mat;  /* material index */
    uint32_t geom; /* mesh index, or nmeshes for spheres */
    uint32_t prim; /* triangle or sphere index */
    float u, v;    /* barycentrics of p1 and p2 on a triangle (p = (1 - u - v) p0 + u p1 + v p2); 0 on spheres */
} pf_hit_t;

/* Builds the acceleration structure for a finalized scene. NULL with err
 * filled on failure. The scene must outlive the accel. */
pf_accel_t *pf_accel_create(const pf_scene_t *scene, pf_error_t *err);
void pf_accel_destroy(pf_accel_t **self_p);

/* Closest hit along ray within (0, tmax). 1 and *hit filled, or 0. */
int pf_accel_intersect(const pf_accel_t *self, const pf_ray_t *ray, float tmax, pf_hit_t *hit);
/* 1 when anything lies along ray within (0, tmax). */
int pf_accel_occluded(const pf_accel_t *self, const pf_ray_t *ray, float tmax);

/* Offsets p to the side of ng that w points to: by the projection of the
 * error bound on ng (pbrt-v3's OffsetRayOrigin), then by Wächter & Binder's
 * 256-ulp step along ng (an absolute 2^-16 near zero), which covers Embree's
 * rounding for rays that start on a surface. */
pf_vec3 pf_offset_origin(pf_vec3 p, pf_vec3 perr, pf_vec3 ng, pf_vec3 w);

/* The least position error the accelerator assumes for any point on its
 * scene: 2^-21 of the scene's extent. Hits already include it in perr; points
 * made elsewhere (emission) take the max with it before pf_offset_origin. */
float pf_accel_eps(const pf_accel_t *self);
/* Whether every surface within reach of c lies in the plane through c with
 * unit normal n: 1 when each triangle that comes that close has its plane
 * within pf_accel_eps of c and tilted from n (either side) by at most
 * PF_ACCEL_PLANE_TILT radians; 0 when any other triangle or any sphere does.
 * Then no surface but that plane meets the ball, and a ray inside the ball
 * running above the plane (by more than the tilt and eps allow) hits
 * nothing. Safe from any thread. */
#define PF_ACCEL_PLANE_TILT 5e-4f
int pf_accel_only_plane(const pf_accel_t *self, pf_vec3 c, pf_vec3 n, float reach);

/* A triangle's plane: the points y with n . y = d, n unit (in double, so
 * that which side of it a point lies on is known to far below eps). */
typedef struct pf_plane {
    double n[3], d;
} pf_plane_t;

/* The planes of the triangles that come within reach of c, into
 * planes[0, max): returns how many (0 when none), or -1 when more than max
 * do or a sphere's surface does. A segment that lies within reach of c and
 * whose two ends lie on one side of every plane returned, each by more than
 * 4 pf_accel_eps, hits nothing: pf_accel_occluded need not be asked. Safe
 * from any thread. */
int pf_accel_near_planes(const pf_accel_t *self, pf_vec3 c, float reach, pf_plane_t *planes, int max);

/* A ray leaving the hit point in direction w. */
static inline pf_ray_t pf_spawn_ray(const pf_hit_t *h, pf_vec3 w)
{
    return (pf_ray_t){ pf_offset_origin(h->p, h->perr, h->ng, w), w };
}

/* Sets flush-to-zero and denormals-are-zero for the calling thread (Embree
 * asks for it in every thread that traces rays). */
void pf_accel_thread_init(void);

#endif
