/* accel.c: the Embree 3 wrapper; see accel.h. Owns the Embree device and
 * scene. Embree's BVH build runs in pf_accel_create (its own threads); the
 * query functions are called by every rendering thread concurrently. */
#include "common/accel.h"

#include <embree3/rtcore.h>
#include <float.h>
#include <pmmintrin.h>
#include <stdio.h>
#include <stdlib.h>
#include <xmmintrin.h>

#include "common/light.h"
#include "common/log.h"

struct pf_accel {
    RTCDevice device;
    RTCScene rtc;
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
