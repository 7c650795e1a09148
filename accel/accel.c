/* accel.c: the Embree 3 wrapper; see accel.h. Owns the Embree device and
 * scene. Embree's BVH build runs in pf_accel_create (its own threads); the
 * query functions are called by every rendering thread concurrently. */
#include "accel/accel.h"

#include "accel/alpha.h"

#include <embree3/rtcore.h>
#include <float.h>
#include <math.h>
#include <stdbool.h>
#include <pmmintrin.h>
#include <stdio.h>
#include <stdlib.h>
#include <xmmintrin.h>

#include "base/log.h"
#include "base/sampling.h"

struct pf_accel {
    RTCDevice device;
    RTCScene rtc;
    RTCScene sphere_bounds; /* the spheres as boxes, for pf_accel_only_plane: Embree's point
                             * query skips its own sphere geometry; NULL without spheres */
    const pf_scene_t *scene;
    uint32_t sphere_geom;
    float eps; /* pf_accel_eps */
};

static void s_embree_error(void *user, enum RTCError code, const char *str)
{
    (void)user;
    pf_error("Embree error %d: %s", (int)code, str ? str : "");
}

void pf_accel_thread_init(void)
{
    _MM_SET_FLUSH_ZERO_MODE(_MM_FLUSH_ZERO_ON);
    _MM_SET_DENORMALS_ZERO_MODE(_MM_DENORMALS_ZERO_ON);
}

static bool s_plane_query_prim(struct RTCPointQueryFunctionArguments *args);

static void s_sphere_box(const struct RTCBoundsFunctionArguments *args)
{
    const pf_sphere_t *sp = &((const pf_scene_t *)args->geometryUserPtr)->spheres[args->primID];
    args->bounds_o->lower_x = sp->center.x - sp->radius;
    args->bounds_o->lower_y = sp->center.y - sp->radius;
    args->bounds_o->lower_z = sp->center.z - sp->radius;
    args->bounds_o->upper_x = sp->center.x + sp->radius;
    args->bounds_o->upper_y = sp->center.y + sp->radius;
    args->bounds_o->upper_z = sp->center.z + sp->radius;
}

pf_accel_t *pf_accel_create(const pf_scene_t *scene, pf_error_t *err)
{
    pf_accel_t *self = calloc(1, sizeof *self);
    if (!self) {
        pf_error_set(err, PF_ENOMEM, NULL, 0, "out of memory building the ray-tracing structure");
        return NULL;
    }
    self->scene = scene;
    {
        pf_vec3 lo, hi;
        pf_scene_geometry_bounds(scene, &lo, &hi);
        float ext = fmaxf(fmaxf(hi.x - lo.x, hi.y - lo.y), hi.z - lo.z);
        self->eps = (ext > 0.0f && isfinite(ext) ? ext : 1.0f) * 0x1p-21f;
    }
    pf_accel_thread_init();
    self->device = rtcNewDevice("verbose=0");
    if (!self->device) {
        pf_error_set(err, PF_EEMBREE, NULL, 0, "cannot create the Embree device (error %d)", (int)rtcGetDeviceError(NULL));
        free(self);
        return NULL;
    }
    rtcSetDeviceErrorFunction(self->device, s_embree_error, NULL);
    self->rtc = rtcNewScene(self->device);
    rtcSetSceneFlags(self->rtc, RTC_SCENE_FLAG_ROBUST);
    rtcSetSceneBuildQuality(self->rtc, RTC_BUILD_QUALITY_HIGH);
    for (size_t m = 0; m < scene->nmeshes; m++) {
        const pf_mesh_t *mesh = &scene->meshes[m];
        RTCGeometry g = rtcNewGeometry(self->device, RTC_GEOMETRY_TYPE_TRIANGLE);
        float *vb = rtcSetNewGeometryBuffer(g, RTC_BUFFER_TYPE_VERTEX, 0, RTC_FORMAT_FLOAT3, 3 * sizeof(float),
                                            mesh->nverts ? mesh->nverts : 1);
        unsigned *ib = rtcSetNewGeometryBuffer(g, RTC_BUFFER_TYPE_INDEX, 0, RTC_FORMAT_UINT3, 3 * sizeof(unsigned),
                                               mesh->ntris);
        if (!vb || (!ib && mesh->ntris)) {
            rtcReleaseGeometry(g);
            pf_accel_destroy(&self);
            pf_error_set(err, PF_ENOMEM, NULL, 0, "out of memory for mesh '%s' in Embree", mesh->name);
            return NULL;
        }
        for (size_t i = 0; i < mesh->nverts; i++) {
            vb[3 * i + 0] = mesh->pos[i].x;
            vb[3 * i + 1] = mesh->pos[i].y;
            vb[3 * i + 2] = mesh->pos[i].z;
        }
        for (size_t i = 0; i < 3 * mesh->ntris; i++)
            ib[i] = mesh->idx[i];
        pf_alpha_attach(g, scene, m);
        rtcCommitGeometry(g);
        rtcAttachGeometryByID(self->rtc, g, (unsigned)m);
        rtcReleaseGeometry(g);
    }
    self->sphere_geom = (uint32_t)scene->nmeshes;
    if (scene->nspheres) {
        RTCGeometry g = rtcNewGeometry(self->device, RTC_GEOMETRY_TYPE_SPHERE_POINT);
        float *vb = rtcSetNewGeometryBuffer(g, RTC_BUFFER_TYPE_VERTEX, 0, RTC_FORMAT_FLOAT4, 4 * sizeof(float),
                                            scene->nspheres);
        if (!vb) {
            rtcReleaseGeometry(g);
            pf_accel_destroy(&self);
            pf_error_set(err, PF_ENOMEM, NULL, 0, "out of memory for spheres in Embree");
            return NULL;
        }
        for (size_t i = 0; i < scene->nspheres; i++) {
            vb[4 * i + 0] = scene->spheres[i].center.x;
            vb[4 * i + 1] = scene->spheres[i].center.y;
            vb[4 * i + 2] = scene->spheres[i].center.z;
            vb[4 * i + 3] = scene->spheres[i].radius;
        }
        rtcCommitGeometry(g);
        rtcAttachGeometryByID(self->rtc, g, self->sphere_geom);
        rtcReleaseGeometry(g);
        self->sphere_bounds = rtcNewScene(self->device);
        g = rtcNewGeometry(self->device, RTC_GEOMETRY_TYPE_USER);
        rtcSetGeometryUserPrimitiveCount(g, (unsigned)scene->nspheres);
        rtcSetGeometryUserData(g, (void *)scene);
        rtcSetGeometryBoundsFunction(g, s_sphere_box, NULL);
        rtcSetGeometryPointQueryFunction(g, s_plane_query_prim);
        rtcCommitGeometry(g);
        rtcAttachGeometryByID(self->sphere_bounds, g, self->sphere_geom);
        rtcReleaseGeometry(g);
        rtcCommitScene(self->sphere_bounds);
    }
    rtcCommitScene(self->rtc);
    enum RTCError e = rtcGetDeviceError(self->device);
    if (e != RTC_ERROR_NONE) {
        pf_accel_destroy(&self);
        pf_error_set(err, PF_EEMBREE, NULL, 0, "Embree failed to build the scene (error %d)", (int)e);
        return NULL;
    }
    return self;
}

void pf_accel_destroy(pf_accel_t **self_p)
{
    if (!self_p || !*self_p)
        return;
    pf_accel_t *self = *self_p;
    if (self->rtc)
        rtcReleaseScene(self->rtc);
    if (self->sphere_bounds)
        rtcReleaseScene(self->sphere_bounds);
    if (self->device)
        rtcReleaseDevice(self->device);
    free(self);
    *self_p = NULL;
}

static inline void s_fill_ray(struct RTCRay *r, const pf_ray_t *ray, float tmax)
{
    r->org_x = ray->o.x;
    r->org_y = ray->o.y;
    r->org_z = ray->o.z;
    r->dir_x = ray->d.x;
    r->dir_y = ray->d.y;
    r->dir_z = ray->d.z;
    r->tnear = 0.0f;
    r->tfar = tmax;
    r->time = 0.0f;
    r->mask = 0xffffffffu;
    r->id = 0;
    r->flags = 0;
}

static inline float s_gamma(int n)
{
    const float eps = 0x1p-24f;
    return (float)n * eps / (1.0f - (float)n * eps);
}

int pf_accel_intersect(const pf_accel_t *self, const pf_ray_t *ray, float tmax, pf_hit_t *hit)
{
    struct RTCIntersectContext ctx;
    rtcInitIntersectContext(&ctx);
    struct RTCRayHit rh;
    s_fill_ray(&rh.ray, ray, tmax);
    rh.hit.geomID = RTC_INVALID_GEOMETRY_ID;
    rh.hit.instID[0] = RTC_INVALID_GEOMETRY_ID;
    rtcIntersect1(self->rtc, &ctx, &rh);
    if (rh.hit.geomID == RTC_INVALID_GEOMETRY_ID)
        return 0;
    const pf_scene_t *scene = self->scene;
    hit->t = rh.ray.tfar;
    hit->geom = rh.hit.geomID;
    hit->prim = rh.hit.primID;
    if (rh.hit.geomID == self->sphere_geom) {
        const pf_sphere_t *s = &scene->spheres[rh.hit.primID];
        pf_vec3 p = pf_madd(ray->o, ray->d, rh.ray.tfar);
        pf_vec3 n = pf_norm(pf_sub(p, s->center));
        /* Reprojection onto the surface leaves an error of a few ulps of the
         * coordinates involved (pbrt-v3 3.9.4: gamma(5) |p|, here about the
         * world-space centre). */
        p = pf_madd(s->center, n, s->radius);
        hit->p = p;
        hit->perr = pf_vmax(pf_scale(pf_add(pf_vabs(s->center), pf_vabs(pf_scale(n, s->radius))), s_gamma(5)),
                            pf_v3s(self->eps));
        hit->ng = n;
        hit->ns = n;
        hit->mat = s->mat;
        hit->u = hit->v = 0.0f;
        return 1;
    }
    const pf_mesh_t *mesh = &scene->meshes[rh.hit.geomID];
    const uint32_t *v = &mesh->idx[3 * rh.hit.primID];
    pf_vec3 p0 = mesh->pos[v[0]], p1 = mesh->pos[v[1]], p2 = mesh->pos[v[2]];
    float b1 = rh.hit.u, b2 = rh.hit.v, b0 = 1.0f - b1 - b2;
    hit->p = pf_add(pf_add(pf_scale(p0, b0), pf_scale(p1, b1)), pf_scale(p2, b2));
    hit->perr = pf_vmax(pf_tri_point_error(p0, p1, p2, b0, b1, b2), pf_v3s(self->eps));
    pf_vec3 ng = pf_norm(pf_cross(pf_sub(p1, p0), pf_sub(p2, p0)));
    pf_vec3 ns = ng;
    if (mesh->nrm) {
        pf_vec3 n = pf_add(pf_add(pf_scale(mesh->nrm[v[0]], b0), pf_scale(mesh->nrm[v[1]], b1)),
                           pf_scale(mesh->nrm[v[2]], b2));
        if (pf_len2(n) > 0.0f) {
            ns = pf_norm(n);
            ng = pf_face_forward(ng, ns); /* as pbrt: vertex normals orient the surface */
        }
    }
    hit->ng = ng;
    hit->ns = ns;
    hit->mat = mesh->mat[rh.hit.primID];
    hit->u = b1;
    hit->v = b2;
    return 1;
}

int pf_accel_occluded(const pf_accel_t *self, const pf_ray_t *ray, float tmax)
{
    struct RTCIntersectContext ctx;
    rtcInitIntersectContext(&ctx);
    struct RTCRay r;
    s_fill_ray(&r, ray, tmax);
    rtcOccluded1(self->rtc, &ctx, &r);
    return r.tfar < 0.0f;
}

/* Moves f by n units in the last place towards +infinity (n > 0) or
 * -infinity (n < 0); on the bit pattern that is a step away from or towards
 * zero depending on f's sign. */
static inline float s_ulp_step(float f, int n)
{
    union { float f; int32_t i; } u = { f };
    u.i += (f < 0.0f) ? -n : n;
    return u.f;
}

pf_vec3 pf_offset_origin(pf_vec3 p, pf_vec3 perr, pf_vec3 ng, pf_vec3 w)
{
    /* 1. pbrt-v3: move past the hit point's own error bound along the normal
     *    on w's side, rounding away from the surface. */
    pf_vec3 n = pf_dot(w, ng) < 0.0f ? pf_neg(ng) : ng;
    float d = pf_dot(pf_vabs(n), perr);
    pf_vec3 po = pf_madd(p, n, d);
    /* 2. After Wächter & Binder (Ray Tracing Gems, ch. 6): the bound covers
     *    the hit point but not Embree's own rounding when it intersects a ray
     *    starting on a surface, so step a further 8 ulps along the normal.
     *    Where the bound is zero (a wall exactly at y = 0 has an exactly
     *    representable hit point, whose ulps are denormal), the floor the
     *    accelerator puts under every bound (pf_accel_eps: 2^-21 of the
     *    scene's extent) does it instead. Both are relative, to the
     *    coordinates and to the scene, so a scene scaled or moved far from
     *    the origin renders the same (the stress suite checks it); the
     *    original constants (256 ulps, 2^-16 absolute) were not: 256 ulps at
     *    1e4 is a quarter unit, and 2^-16 larger than a scene of size 1e-6. */
    const int int_scale = 8;
    float c[3] = { po.x, po.y, po.z }, nn[3] = { n.x, n.y, n.z };
    for (int i = 0; i < 3; i++)
        c[i] = s_ulp_step(c[i], (int)((float)int_scale * nn[i]));
    return pf_v3(c[0], c[1], c[2]);
}

float pf_accel_eps(const pf_accel_t *self) { return self->eps; }

/* pf_accel_only_plane's query state. */
typedef struct s_plane_query {
    const pf_accel_t *accel;
    double c[3], n[3]; /* the query point and the plane's unit normal */
    double reach2;
    int only_plane;
} s_plane_query;

static inline double s_dot3(const double a[3], const double b[3]) { return a[0] * b[0] + a[1] * b[1] + a[2] * b[2]; }

/* Squared distance from p to triangle abc (Ericson, Real-Time Collision
 * Detection, 5.1.5: the closest point by Voronoi region). */
static double s_tri_dist2(const double p[3], const double a[3], const double b[3], const double c[3])
{
    double ab[3], ac[3], ap[3], bp[3], cp[3], q[3];
    for (int i = 0; i < 3; i++) {
        ab[i] = b[i] - a[i], ac[i] = c[i] - a[i];
        ap[i] = p[i] - a[i], bp[i] = p[i] - b[i], cp[i] = p[i] - c[i];
    }
    double d1 = s_dot3(ab, ap), d2 = s_dot3(ac, ap), d3 = s_dot3(ab, bp), d4 = s_dot3(ac, bp);
    double d5 = s_dot3(ab, cp), d6 = s_dot3(ac, cp);
    double va = d3 * d6 - d5 * d4, vb = d5 * d2 - d1 * d6, vc = d1 * d4 - d3 * d2;
    double u, v; /* q = a + u ab + v ac */
    if (d1 <= 0.0 && d2 <= 0.0)
        u = 0.0, v = 0.0;
    else if (d3 >= 0.0 && d4 <= d3)
        u = 1.0, v = 0.0;
    else if (vc <= 0.0 && d1 >= 0.0 && d3 <= 0.0)
        u = d1 / (d1 - d3), v = 0.0;
    else if (d6 >= 0.0 && d5 <= d6)
        u = 0.0, v = 1.0;
    else if (vb <= 0.0 && d2 >= 0.0 && d6 <= 0.0)
        u = 0.0, v = d2 / (d2 - d6);
    else if (va <= 0.0 && (d4 - d3) >= 0.0 && (d5 - d6) >= 0.0) {
        double w = (d4 - d3) / ((d4 - d3) + (d5 - d6));
        u = 1.0 - w, v = w;
    } else {
        double den = 1.0 / (va + vb + vc);
        u = vb * den, v = vc * den;
    }
    double d2sum = 0.0;
    for (int i = 0; i < 3; i++) {
        q[i] = a[i] + u * ab[i] + v * ac[i] - p[i];
        d2sum += q[i] * q[i];
    }
    return d2sum;
}

/* Triangle prim of mesh geom when it comes within sqrt(reach2) of c and has
 * an area: 1 with its corners v and its unit normal nt (in doubles, for
 * the plane tests of the point queries below); else 0. */
static int s_near_triangle(const pf_scene_t *scene, unsigned geom, unsigned prim, const double c[3], double reach2,
                           double v[3][3], double nt[3])
{
    const pf_mesh_t *mesh = &scene->meshes[geom];
    const uint32_t *idx = &mesh->idx[3 * (size_t)prim];
    for (int k = 0; k < 3; k++) {
        pf_vec3 p = mesh->pos[idx[k]];
        v[k][0] = p.x, v[k][1] = p.y, v[k][2] = p.z;
    }
    if (s_tri_dist2(c, v[0], v[1], v[2]) > reach2)
        return 0; /* its bounds meet the sphere, the triangle does not */
    double e1[3], e2[3];
    for (int i = 0; i < 3; i++)
        e1[i] = v[1][i] - v[0][i], e2[i] = v[2][i] - v[0][i];
    nt[0] = e1[1] * e2[2] - e1[2] * e2[1];
    nt[1] = e1[2] * e2[0] - e1[0] * e2[2];
    nt[2] = e1[0] * e2[1] - e1[1] * e2[0];
    double len = sqrt(s_dot3(nt, nt));
    if (!(len > 0.0))
        return 0; /* no area: no ray hits it */
    for (int i = 0; i < 3; i++)
        nt[i] /= len;
    return 1;
}

/* Called by Embree for every primitive whose bounds meet the query sphere:
 * the triangles of rtc, the spheres of sphere_bounds. */
static bool s_plane_query_prim(struct RTCPointQueryFunctionArguments *args)
{
    s_plane_query *pq = args->userPtr;
    const pf_scene_t *scene = pq->accel->scene;
    int ok = 0;
    if (args->geomID < scene->nmeshes) {
        double v[3][3], nt[3], cv[3];
        if (!s_near_triangle(scene, args->geomID, args->primID, pq->c, pq->reach2, v, nt))
            return false;
        for (int i = 0; i < 3; i++)
            cv[i] = pq->c[i] - v[0][i];
        /* |nt x n| = sin of the angle between the planes */
        double cx = nt[1] * pq->n[2] - nt[2] * pq->n[1], cy = nt[2] * pq->n[0] - nt[0] * pq->n[2],
               cz = nt[0] * pq->n[1] - nt[1] * pq->n[0];
        ok = cx * cx + cy * cy + cz * cz <= (double)PF_ACCEL_PLANE_TILT * PF_ACCEL_PLANE_TILT &&
             fabs(s_dot3(cv, nt)) <= (double)pq->accel->eps;
    }
    else {
        const pf_sphere_t *sp = &scene->spheres[args->primID];
        double dc[3] = { pq->c[0] - sp->center.x, pq->c[1] - sp->center.y, pq->c[2] - sp->center.z };
        ok = fabs(sqrt(s_dot3(dc, dc)) - (double)sp->radius) > sqrt(pq->reach2);
    }
    if (ok)
        return false;
    /* Another surface: the answer is known, and a zero radius ends the
     * traversal. */
    pq->only_plane = 0;
    args->query->radius = 0.0f;
    return true;
}

int pf_accel_only_plane(const pf_accel_t *self, pf_vec3 c, pf_vec3 n, float reach)
{
    if (!(reach >= 0.0f) || !isfinite(reach) || !isfinite(c.x) || !isfinite(c.y) || !isfinite(c.z))
        return 0;
    double nl = sqrt((double)n.x * n.x + (double)n.y * n.y + (double)n.z * n.z);
    if (!(nl > 0.0))
        return 0;
    s_plane_query pq = { self, { c.x, c.y, c.z }, { n.x / nl, n.y / nl, n.z / nl }, (double)reach * reach, 1 };
    struct RTCPointQuery q = { c.x, c.y, c.z, 0.0f, reach };
    struct RTCPointQueryContext ctx;
    rtcInitPointQueryContext(&ctx);
    rtcPointQuery(self->rtc, &q, &ctx, s_plane_query_prim, &pq);
    if (pq.only_plane && self->sphere_bounds) {
        q.radius = reach;
        rtcInitPointQueryContext(&ctx);
        rtcPointQuery(self->sphere_bounds, &q, &ctx, s_plane_query_prim, &pq);
    }
    return pq.only_plane;
}


/* pf_accel_near_planes's query state. */
typedef struct s_planes_query {
    const pf_accel_t *accel;
    double c[3], reach2;
    pf_plane_t *planes;
    int n, max; /* n > max: too many */
} s_planes_query;

/* Called by Embree for every triangle whose bounds meet the query sphere. */
static bool s_planes_query_prim(struct RTCPointQueryFunctionArguments *args)
{
    s_planes_query *pq = args->userPtr;
    const pf_scene_t *scene = pq->accel->scene;
    if (args->geomID >= scene->nmeshes)
        return false; /* the spheres are asked apart */
    double v[3][3], nt[3];
    if (!s_near_triangle(scene, args->geomID, args->primID, pq->c, pq->reach2, v, nt))
        return false;
    if (pq->n >= pq->max) {
        pq->n = pq->max + 1;
        args->query->radius = 0.0f; /* the answer is known: stop */
        return true;
    }
    pf_plane_t *pl = &pq->planes[pq->n++];
    for (int i = 0; i < 3; i++)
        pl->n[i] = nt[i];
    pl->d = s_dot3(pl->n, v[0]);
    return false;
}

int pf_accel_near_planes(const pf_accel_t *self, pf_vec3 c, float reach, pf_plane_t *planes, int max)
{
    if (!(reach >= 0.0f) || !isfinite(reach) || !isfinite(c.x) || !isfinite(c.y) || !isfinite(c.z) || max < 0)
        return -1;
    if (self->sphere_bounds) {
        /* Any sphere's surface within reach (only_plane's test, whose
         * sphere branch ignores the normal). */
        s_plane_query sq = { self, { c.x, c.y, c.z }, { 0, 0, 1 }, (double)reach * reach, 1 };
        struct RTCPointQuery q = { c.x, c.y, c.z, 0.0f, reach };
        struct RTCPointQueryContext ctx;
        rtcInitPointQueryContext(&ctx);
        rtcPointQuery(self->sphere_bounds, &q, &ctx, s_plane_query_prim, &sq);
        if (!sq.only_plane)
            return -1;
    }
    s_planes_query pq = { self, { c.x, c.y, c.z }, (double)reach * reach, planes, 0, max };
    struct RTCPointQuery q = { c.x, c.y, c.z, 0.0f, reach };
    struct RTCPointQueryContext ctx;
    rtcInitPointQueryContext(&ctx);
    rtcPointQuery(self->rtc, &q, &ctx, s_planes_query_prim, &pq);
    return pq.n > max ? -1 : pq.n;
}
