/* emit.c: photon emission from the light table (light.h's pf_lights_emit
 * and pf_lights_emit_targeted; the table itself: light.c). Read-only on the
 * table: safe from any thread.
 *
 * Area triangles and spheres emit from a uniform point on their surface,
 * cosine-distributed about its normal; a two-sided triangle (pbrt-v4's
 * twoSided DiffuseAreaLight::SampleLe) about either normal, the side chosen
 * by the first direction number, so each side takes half the photons and
 * the flux is Le A 2 pi / pmf: their total is the 2 pi A lum(Le) the table
 * gives it. Distant and infinite lights emit from the disc their
 * directions cast on the scene's bounding sphere (light.c's header). */
#include "light/light.h"
#include "light/light_impl.h"

#include <math.h>

#include "base/sampling.h"
#include "light/spherelight.h"

pf_vec3 pf_lights_surface_point(const pf_lights_t *self, const pf_scene_t *scene, const pf_light_entry_t *e,
                                const float *u, pf_vec3 *p, pf_vec3 *n, pf_vec3 *perr, int *two)
{
    *two = 0;
    if (e->kind == PF_ENTRY_AREA) {
        const pf_emit_tri_t *t = &self->tris[e - self->entries];
        *p = pf_emit_tri_point(t, u[0], u[1], perr);
        *n = t->n;
        *two = (int)t->twosided;
        return t->le;
    }
    pf_sphere_light_point(&scene->spheres[e->light], u[0], u[1], p, n, perr);
    return scene->mats[scene->spheres[e->light].mat].le;
}

/* The plane a distant light's photons start on: perpendicular to its
 * direction dir, touching the scene's bounding sphere on the light's side. */
static pf_vec3 s_plane_origin(const pf_lights_t *self, pf_vec3 dir)
{
    return pf_madd(self->center, dir, -self->radius);
}

/* A uniform point on the disc of radius r on that plane whose centre is c's
 * projection onto it. */
static pf_vec3 s_disc_point(const pf_lights_t *self, pf_vec3 dir, pf_vec3 c, float r, float u1, float u2)
{
    pf_vec3 o = s_plane_origin(self, dir), t, b;
    pf_vec3 cp = pf_madd(c, dir, -pf_dot(pf_sub(c, o), dir));
    pf_basis(dir, &t, &b);
    float rho = r * sqrtf(u1), phi = 2.0f * PF_PI * u2;
    return pf_add(cp, pf_add(pf_scale(t, rho * cosf(phi)), pf_scale(b, rho * sinf(phi))));
}

int pf_lights_emit(const pf_lights_t *self, const pf_scene_t *scene, const float u[5], pf_emission_t *out)
{
    if (self->n == 0)
        return 0;
    double pmf;
    const pf_light_entry_t *e = &self->entries[pf_lights_pick(self, self->cdf, u[0], &pmf)];
    if (e->kind == PF_ENTRY_AREA || e->kind == PF_ENTRY_SPHERE) {
        int two;
        pf_vec3 p, n, perr, le = pf_lights_surface_point(self, scene, e, &u[1], &p, &n, &perr, &two);
        float u3 = u[3], sides = 1.0f;
        if (two) { /* as pbrt-v4: u picks the side, each half the photons, cosine about its normal */
            sides = 2.0f;
            n = u3 < 0.5f ? n : pf_neg(n);
            u3 = fminf(u3 < 0.5f ? 2.0f * u3 : 2.0f * (u3 - 0.5f), 0x1.fffffep-1f);
        }
        pf_vec3 local = pf_sample_cosine(u3, u[4]);
        /* Le cos / (pdf_area pdf_dir) = Le cos / ((pmf / A) (cos / pi)) = Le A pi / pmf; two-sided,
         * pdf_dir = cos / (2 pi): Le A 2 pi / pmf. */
        out->ray = (pf_ray_t){ p, pf_to_world(local, n) };
        out->flux = pf_scale(le, sides * PF_PI * e->area / (float)pmf);
        out->perr = perr;
        out->n = n;
        return 1;
    }
    out->perr = pf_v3s(0.0f);
    out->n = pf_v3s(0.0f);
    if (e->kind == PF_ENTRY_ENVMAP) {
        /* a direction towards the sky from the map's distribution, the photon
         * travelling against it: L pi R^2 / (pdf_dir pmf) */
        const pf_envlight_t *env = &self->env[e->light];
        pf_vec3 d = pf_envlight_sample(env, u[1], u[2]);
        float pdf = pf_envlight_pdf(env, d);
        if (!(pdf > 0.0f))
            return 0;
        pf_vec3 dir = pf_neg(d);
        out->ray = (pf_ray_t){ s_disc_point(self, dir, self->center, self->radius, u[3], u[4]), dir };
        out->flux = pf_scale(pf_envlight_le(env, d), PF_PI * self->radius * self->radius / (pdf * (float)pmf));
        return 1;
    }
    const pf_light_t *l = e->kind == PF_ENTRY_INFINITE ? NULL : &scene->lights[e->light]; /* the sky: self->sky */
    if (e->kind == PF_ENTRY_DISTANT) {
        /* E / (pdf_area pmf), pdf_area = 1 / (pi R^2) over the disc. */
        out->ray = (pf_ray_t){ s_disc_point(self, l->dir, self->center, self->radius, u[3], u[4]), l->dir };
        out->flux = pf_scale(l->intensity, PF_PI * self->radius * self->radius / (float)pmf);
        return 1;
    }
    if (e->kind == PF_ENTRY_INFINITE) {
        /* a direction uniform over the sphere, then as a distant light along it:
         * L pi R^2 / (pdf_dir pmf), pdf_dir = 1 / (4 pi) */
        pf_vec3 d = pf_sample_sphere(u[1], u[2]);
        out->ray = (pf_ray_t){ s_disc_point(self, d, self->center, self->radius, u[3], u[4]), d };
        out->flux = pf_scale(self->sky, 4.0f * PF_PI * PF_PI * self->radius * self->radius / (float)pmf);
        return 1;
    }
    if (l->type == PF_LIGHT_POINT && e->cos_max > -1.0f) {
        /* I / (pdf_dir pmf), pdf_dir = 1 / solid angle of the cone. */
        out->ray = (pf_ray_t){ l->pos, pf_to_world(pf_sample_cone(u[3], u[4], e->cos_max), e->axis) };
        out->flux = pf_scale(l->intensity, 2.0f * PF_PI * (1.0f - e->cos_max) / (float)pmf);
        return 1;
    }
    if (l->type == PF_LIGHT_POINT) {
        out->ray = (pf_ray_t){ l->pos, pf_sample_sphere(u[3], u[4]) };
        out->flux = pf_scale(l->intensity, 4.0f * PF_PI / (float)pmf);
        return 1;
    }
    pf_vec3 local = pf_sample_cone(u[3], u[4], l->cos_outer);
    pf_vec3 w = pf_to_world(local, l->dir);
    float pdf = 1.0f / (2.0f * PF_PI * (1.0f - l->cos_outer));
    out->ray = (pf_ray_t){ l->pos, w };
    out->flux = pf_scale(l->intensity, pf_spot_falloff(l, local.z) / (pdf * (float)pmf));
    return 1;
}

/* A caustic photon of a distant light: a point uniform in the disc that a
 * target chosen uniformly casts on the emission plane (every ray along dir
 * that meets a target crosses its disc), the flux divided by the mixture pdf
 * of all discs holding the point. */
static int s_distant_targeted(const pf_lights_t *self, pf_vec3 dir, pf_vec3 irradiance, double pmf,
                              const pf_target_t *targets, size_t ntargets, const float u[6], pf_emission_t *out)
{
    size_t ti = (size_t)(u[3] * (float)ntargets);
    if (ti >= ntargets)
        ti = ntargets - 1;
    pf_vec3 p = s_disc_point(self, dir, targets[ti].center, targets[ti].radius, u[4], u[5]);
    double pdf = 0.0;
    for (size_t k = 0; k < ntargets; k++) {
        pf_vec3 d = pf_sub(p, targets[k].center);
        float r = targets[k].radius;
        /* the squared distance to the target's centre line, by the disc's own test */
        float dperp2 = pf_len2(pf_madd(d, dir, -pf_dot(d, dir)));
        if (k == ti || dperp2 <= r * r)
            pdf += 1.0 / (PF_PI * (double)r * (double)r);
    }
    pdf /= (double)ntargets;
    if (!(pdf > 0.0) || !isfinite(pdf))
        return 0;
    out->ray = (pf_ray_t){ p, dir };
    out->flux = pf_scale(irradiance, (float)(1.0 / (pdf * pmf)));
    out->perr = pf_v3s(0.0f);
    out->n = pf_v3s(0.0f);
    return 1;
}

int pf_lights_emit_targeted(const pf_lights_t *self, const pf_scene_t *scene, const pf_target_t *targets,
                            size_t ntargets, const float u[6], pf_emission_t *out)
{
    if (self->n == 0 || ntargets == 0)
        return 0;
    double pmf;
    const pf_light_entry_t *e = &self->entries[pf_lights_pick(self, self->cdf, u[0], &pmf)];
    if (e->kind == PF_ENTRY_DISTANT) {
        const pf_light_t *ld = &scene->lights[e->light];
        return s_distant_targeted(self, ld->dir, ld->intensity, pmf, targets, ntargets, u, out);
    }
    if (e->kind == PF_ENTRY_ENVMAP) { /* a direction from the map's distribution: irradiance L / pdf along it */
        const pf_envlight_t *env = &self->env[e->light];
        pf_vec3 d = pf_envlight_sample(env, u[1], u[2]);
        float pdf = pf_envlight_pdf(env, d);
        if (!(pdf > 0.0f))
            return 0;
        return s_distant_targeted(self, pf_neg(d), pf_scale(pf_envlight_le(env, d), 1.0f / pdf), pmf, targets,
                                  ntargets, u, out);
    }
    if (e->kind == PF_ENTRY_INFINITE) /* a direction uniform over the sphere, pdf 1 / (4 pi) */
        return s_distant_targeted(self, pf_sample_sphere(u[1], u[2]), pf_scale(self->sky, 4.0f * PF_PI), pmf,
                                  targets, ntargets, u, out);
    pf_vec3 p, n = pf_v3s(0.0f), perr = pf_v3s(0.0f), le = pf_v3s(0.0f);
    const pf_light_t *l = NULL;
    int surface = e->kind == PF_ENTRY_AREA || e->kind == PF_ENTRY_SPHERE, two = 0;
    if (surface) {
        le = pf_lights_surface_point(self, scene, e, &u[1], &p, &n, &perr, &two);
    } else {
        l = &scene->lights[e->light];
        p = l->pos;
    }
    size_t ti = (size_t)(u[3] * (float)ntargets);
    if (ti >= ntargets)
        ti = ntargets - 1;
    pf_vec3 axis;
    float cos_max, solid;
    pf_target_cone(p, &targets[ti], &axis, &cos_max, &solid);
    pf_vec3 w = cos_max <= -1.0f ? pf_sample_sphere(u[4], u[5])
                                 : pf_to_world(pf_sample_cone(u[4], u[5], cos_max), axis);
    /* Mixture pdf over every target whose cone holds w. */
    double pdf = 0.0;
    for (size_t k = 0; k < ntargets; k++) {
        pf_vec3 ak;
        float ck, sk;
        pf_target_cone(p, &targets[k], &ak, &ck, &sk);
        if (ck <= -1.0f || pf_dot(w, ak) >= ck)
            pdf += 1.0 / (double)sk;
    }
    pdf /= (double)ntargets;
    if (!(pdf > 0.0))
        return 0;
    pf_vec3 radiant; /* emitted radiance x cos (area) or intensity (point, spot) towards w */
    if (surface) {
        float cos_l = pf_dot(w, n);
        if (two && cos_l < 0.0f) { /* leaving the back: the photon starts on that side */
            cos_l = -cos_l;
            n = pf_neg(n);
        }
        if (cos_l <= 0.0f)
            return 0;
        radiant = pf_scale(le, cos_l * e->area); /* divided by pdf_area = 1 / area */
    } else {
        float f = l->type == PF_LIGHT_SPOT ? pf_spot_falloff(l, pf_dot(w, l->dir)) : 1.0f;
        if (f <= 0.0f)
            return 0;
        radiant = pf_scale(l->intensity, f);
    }
    out->ray = (pf_ray_t){ p, w };
    out->flux = pf_scale(radiant, (float)(1.0 / (pdf * pmf)));
    out->perr = perr;
    out->n = n;
    return 1;
}
