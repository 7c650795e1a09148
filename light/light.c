/* light.c: the power-weighted emitter table; see light.h.
 *
 * Emitters are sampled by their share of the total power (luminance of the
 * emitted flux): an area triangle emits pi A lum(Le) (twice that when its
 * material is two-sided: the same Le leaves its back), a point light
 * 4 pi lum(I), a spot 2 pi lum(I) times the integral of its falloff, a
 * distant light pi R^2 lum(E): the flux of its irradiance E through the
 * disc that the scene's bounding sphere (radius R) casts, which is all of
 * it the scene can receive, an infinite light (a constant sky of radiance
 * L) 4 pi^2 R^2 lum(L): pi L through that disc from each of 4 pi
 * directions. Photon emission chooses among all of them by power; direct
 * light chooses the same way among all but the distant lights, which every
 * direct estimate takes whole, a shadow ray each (a sun chosen by power
 * beside a sky would make each sunlit sample a coin toss).
 *
 * A distant light emits photons from that disc, placed on the light's side
 * of the sphere, perpendicular to its direction; caustic photons come from
 * the discs the specular targets cast on that plane. An infinite light does
 * the same for a direction drawn uniformly over the sphere; its direct light
 * samples directions cosine-weighted about the receiver's normal (uniformly
 * over the sphere without one), with that pdf for MIS at rough conductors
 * (pf_lights_sky_pdf). All constant infinite lights make one entry, the
 * last, of their summed radiance.
 *
 * An image-based infinite light (one with a map) is an entry of its own, of
 * power pi R^2 times the integral of its luminance over the sphere; its
 * directions come from its map's distribution (envlight.c), for direct light
 * and photons alike. The sky a ray sees is the sum of every infinite
 * light's, and direct light treats that sum as one emitter sampled by a
 * mixture: whichever sky entry is picked draws the direction, and the
 * sample weighs the whole sky's radiance by the mixture's pdf
 * (pf_lights_sky_pdf), which is also what a BSDF ray that escapes is
 * weighed against. Each map emits its own photons.
 *
 * Direct light (not emission) chooses otherwise when there are several
 * bounded emitters that are not one light (s_build_pick): through a light
 * BVH over the area triangles, point and spot lights (lightbvh.c), by their
 * importance at the receiver, mixed with a quarter by power; the distant
 * lights and the sky entries are chosen apart with probability p_inf.
 * pf_lights_pdf_at and pf_lights_sky_pdf give the same probabilities.
 *
 * An emissive analytic sphere is one entry (after the triangles), emitting
 * outward, of power pi 4 pi r^2 lum(Le) like a triangle's; direct light
 * draws it uniformly in the cone it subtends from the receiver (nothing from
 * inside), pf_lights_pdf_at gives that pdf for a hit on it, photons start
 * uniformly on it (spherelight.c); in the BVH it is bounded by its box and
 * emits in every direction.
 *
 * An emitting triangle whose solid angle from the receiver lies in
 * sphtri.h's range (large or near: the walls beside a ceiling panel) is
 * sampled uniformly in that solid angle (Arvo's spherical triangle, as
 * pbrt-v4), pdf pmf / omega; smaller ones uniformly by area, pdf
 * pmf d^2 / (A cos_l). pf_lights_pdf_at decides alike from the same solid
 * angle, so MIS sees the pdf the sample had.
 *
 * A two-sided triangle (its material's twosided) is seen from both sides:
 * a light sample that reaches its back carries Le with |cos_l|, and its
 * solid-angle pdf (pf_lights_pdf_at too) divides by |cos_l|, as pbrt-v4's
 * DiffuseAreaLight with twoSided. Photons leave it from emit.c. */
#include "light/light.h"

#include <stdlib.h>

#include "base/sampling.h"
#include "light/light_impl.h"
#include "light/spherelight.h"
#include "light/sphtri.h"

/* The entries the light BVH holds (a position and bounds): triangles,
 * spheres, point and spot lights. */
static int s_bounded(pf_light_kind k) { return k == PF_ENTRY_AREA || k == PF_ENTRY_SPHERE || k == PF_ENTRY_POINT; }

/* The share of direct light's samples drawn by power when the BVH is in use:
 * a defensive mixture. The BVH's importance is a bound and can be far off
 * for receivers among their emitters (inside an emissive sphere area
 * sampling is exact: cos_l / d^2 is constant there; the BVH, favouring the
 * triangles next to x by their distance, is not); a quarter by power caps
 * such losses at 4x the power table's variance. */
#define S_DEFENSIVE 0.25f

/* The BVH is used from this many separate bounded lights on (s_light_groups);
 * below, the power table. One light (a quad, an emissive sphere mesh) gains
 * nothing, and inside a concave one (the furnaces) area sampling is close to
 * ideal while the BVH's bounds mislead it. With a few lights the walk's cost
 * (two importances per level, again for MIS) outweighed its gain: veach-mis
 * (3 tessellated spheres, 11904 triangles) at 320x180, 16 spp went from
 * relMSE 0.406 / 0.666 (seeds 1 / 2) to 0.463 / 0.697 with the BVH, though
 * its direct term alone improved (0.069 -> 0.048 at 160x90). This keeps the
 * Cornell boxes, furnaces and veach-mis as they were (veach-mis's spheres,
 * now three analytic sphere lights, are three groups: the power table). */
#define S_MIN_GROUPS 8


float pf_spot_falloff(const pf_light_t *l, float cos_theta)
{
    if (cos_theta >= l->cos_inner)
        return 1.0f;
    if (cos_theta <= l->cos_outer)
        return 0.0f;
    float t = (cos_theta - l->cos_outer) / (l->cos_inner - l->cos_outer);
    return t * t * (3.0f - 2.0f * t);
}

static double s_light_power(const pf_light_t *l, float radius)
{
    double lum = pf_luminance(l->intensity);
    if (l->type == PF_LIGHT_DISTANT)
        return PF_PI * (double)radius * (double)radius * lum;
    if (l->type == PF_LIGHT_INFINITE)
        return 4.0 * PF_PI * PF_PI * (double)radius * (double)radius * lum;
    if (l->type == PF_LIGHT_POINT)
        return 4.0 * PF_PI * lum;
    /* Midpoint rule over cos theta in [cos_outer, 1]. */
    const int steps = 1024;
    double sum = 0.0, h = (1.0 - l->cos_outer) / steps;
    for (int i = 0; i < steps; i++)
        sum += pf_spot_falloff(l, (float)(l->cos_outer + (i + 0.5) * h)) * h;
    return 2.0 * PF_PI * lum * sum;
}

/* The scene's bounding sphere: centre and radius (0 without geometry). */
static void s_bounding_sphere(const pf_scene_t *scene, pf_vec3 *c, float *r)
{
    pf_vec3 lo, hi;
    pf_scene_geometry_bounds(scene, &lo, &hi);
    if (!(lo.x <= hi.x)) {
        *c = pf_v3s(0.0f);
        *r = 0.0f;
        return;
    }
    *c = pf_scale(pf_add(lo, hi), 0.5f);
    /* Widened for the rounding of the bounds and of the cone's sampling. */
    *r = 0.5f * pf_len(pf_sub(hi, lo)) * 1.01f + 1e-6f;
}

/* Points a point light's emission at the scene when it lies outside its
 * bounding sphere (see pf_light_entry_t). */
static void s_aim_at_scene(const pf_lights_t *self, const pf_scene_t *scene, pf_light_entry_t *e)
{
    const pf_light_t *l = &scene->lights[e->light];
    if (l->type != PF_LIGHT_POINT || !(self->radius > 0.0f))
        return; /* not a point light, or no geometry */
    pf_vec3 c = self->center, to = pf_sub(c, l->pos);
    float r = self->radius, d = pf_len(to);
    if (!(d > 1.5f * r) || !isfinite(d))
        return; /* inside or close: the cone would be most of the sphere anyway */
    e->axis = pf_scale(to, 1.0f / d);
    e->cos_max = sqrtf(1.0f - (r / d) * (r / d));
}

/* Adds the entry of an image-based infinite light li and its
 * power to *acc. A map without light, or a scene without geometry, adds
 * nothing. Nonzero when out of memory (self->env is then NULL with nenv
 * set, which pf_lights_build reports). */
static int s_add_envmap(pf_lights_t *self, const pf_scene_t *scene, const pf_light_t *li, double *acc)
{
    if (!self->env) {
        size_t k = 0;
        for (size_t i = 0; i < scene->nlights; i++)
            k += scene->lights[i].type == PF_LIGHT_INFINITE && scene->lights[i].map;
        self->env = calloc(k, sizeof *self->env);
        if (!self->env) {
            self->nenv = k;
            return 1;
        }
    }
    if (!(self->radius > 0.0f))
        return 0;
    pf_envlight_t *e = &self->env[self->nenv];
    if (pf_envlight_init(e, &scene->envmaps[li->map - 1], li->intensity)) {
        for (size_t i = 0; i < self->nenv; i++)
            pf_envlight_free(&self->env[i]);
        free(self->env);
        self->env = NULL;
        self->nenv = 1;
        return 1;
    }
    double p = PF_PI * (double)self->radius * (double)self->radius * e->lum;
    if (!(p > 0.0) || !(e->total > 0.0)) {
        pf_envlight_free(e);
        return 0;
    }
    self->entries[self->n] =
        (pf_light_entry_t){ .kind = PF_ENTRY_ENVMAP, .light = (uint32_t)self->nenv++, .cos_max = -1.0f };
    self->cdf[self->n++] = *acc;
    *acc += p;
    return 0;
}

/* Direct light's table (see dcdf): the distant lights apart, the rest by
 * their power as in cdf. Returns PF_ENOMEM or 0. */
static int s_direct_table(pf_lights_t *self)
{
    for (size_t i = 0; i < self->n; i++)
        self->ndistant += self->entries[i].kind == PF_ENTRY_DISTANT;
    if (self->ndistant == 0) {
        self->dcdf = self->cdf;
        return 0;
    }
    self->dcdf = calloc(self->n + 1, sizeof *self->dcdf);
    self->distant = calloc(self->ndistant, sizeof *self->distant);
    if (!self->dcdf || !self->distant)
        return PF_ENOMEM;
    double acc = 0.0;
    size_t k = 0, last = 0; /* last: one past the last entry with a share */
    for (size_t i = 0; i < self->n; i++) {
        double p = self->cdf[i + 1] - self->cdf[i];
        self->dcdf[i] = acc;
        if (self->entries[i].kind == PF_ENTRY_DISTANT) {
            self->distant[k++] = (uint32_t)i;
            continue;
        }
        acc += p;
        if (p > 0.0)
            last = i + 1;
    }
    for (size_t i = 0; i < self->n; i++)
        self->dcdf[i] = acc > 0.0 ? self->dcdf[i] / acc : 0.0;
    for (size_t i = last; i <= self->n; i++) /* the end exactly 1: u < 1 never picks past it */
        self->dcdf[i] = acc > 0.0 ? 1.0 : 0.0;
    return 0;
}

/* pbrt's LightBounds of a bounded entry (area, point, spot): an area
 * triangle along its normal, light leaving over pi/2 about it, on both
 * sides when two-sided (pbrt's twoSided: |cos| to the normal); a
 * point light in every direction; a spot in its inner cone, spreading to the
 * outer (power 4 pi I for both, as pbrt). Zero power for an unbounded one. */
static pf_light_bounds_t s_entry_bounds(const pf_lights_t *self, const pf_scene_t *scene, size_t i)
{
    const pf_light_entry_t *e = &self->entries[i];
    pf_light_bounds_t b = { .phi = 0.0f, .w = pf_v3(0, 0, 1), .cos_theta_o = -1.0f, .cos_theta_e = 0.0f };
    double p = self->power * (self->cdf[i + 1] - self->cdf[i]);
    if (e->kind == PF_ENTRY_AREA) {
        const pf_emit_tri_t *t = &self->tris[i]; /* built before (s_build_tables) */
        b.w = t->n;
        b.lo = pf_vmin(t->p0, pf_vmin(t->p1, t->p2));
        b.hi = pf_vmax(t->p0, pf_vmax(t->p1, t->p2));
        b.cos_theta_o = 1.0f;
        b.phi = (float)p;
        b.two_sided = (int)t->twosided;
        return b;
    }
    if (e->kind == PF_ENTRY_SPHERE)
        return pf_sphere_light_bounds(&scene->spheres[e->light], (float)p);
    if (e->kind != PF_ENTRY_POINT)
        return b;
    const pf_light_t *l = &scene->lights[e->light];
    b.lo = b.hi = l->pos;
    b.phi = (float)(4.0 * PF_PI * pf_luminance(l->intensity));
    if (l->type == PF_LIGHT_SPOT) {
        b.w = l->dir;
        b.cos_theta_o = l->cos_inner;
        b.cos_theta_e = cosf(acosf(fmaxf(-1.0f, l->cos_outer)) - acosf(fminf(1.0f, l->cos_inner)));
    }
    return b;
}

/* The number of separate bounded lights: point and spot lights, and runs
 * of area triangles of one mesh and one radiance (the area entries are in
 * mesh order). */
static size_t s_light_groups(const pf_lights_t *self, const pf_scene_t *scene)
{
    size_t groups = 0;
    for (size_t i = 0; i < self->n; i++) {
        const pf_light_entry_t *e = &self->entries[i], *p = i ? &self->entries[i - 1] : NULL;
        if (e->kind == PF_ENTRY_POINT || e->kind == PF_ENTRY_SPHERE) {
            groups++;
            continue;
        }
        if (e->kind != PF_ENTRY_AREA)
            continue;
        pf_vec3 le = scene->mats[scene->meshes[e->mesh].mat[e->tri]].le;
        if (!p || p->mesh != e->mesh) {
            groups++;
            continue;
        }
        pf_vec3 lp = scene->mats[scene->meshes[p->mesh].mat[p->tri]].le;
        groups += le.x != lp.x || le.y != lp.y || le.z != lp.z ||
                  self->tris[i].twosided != self->tris[i - 1].twosided;
    }
    return groups;
}

/* Direct light's probability of entry e when the BVH is in use (see the
 * struct), p_bvh the BVH's probability of e (bounded entries; ignored for the
 * others). One expression for the sampler and the pdfs, so they agree. */
static float s_mix_pmf(const pf_lights_t *self, size_t e, float p_bvh)
{
    pf_light_kind k = self->entries[e].kind;
    float power = (float)(self->dcdf[e + 1] - self->dcdf[e]);
    if (k == PF_ENTRY_DISTANT)
        return 0.0f; /* taken apart (pf_lights_distant) */
    float own = s_bounded(k) ? (1.0f - self->p_inf) * p_bvh
                             : self->p_inf * (float)((self->dcdf[e + 1] - self->dcdf[e]) / self->pu);
    return S_DEFENSIVE * power + (1.0f - S_DEFENSIVE) * own;
}

/* Sets up direct light's choice (see the struct): the BVH over the bounded
 * entries when they make at least S_MIN_GROUPS separate lights. The sky
 * entries (the distant lights are taken apart: pf_lights_distant) get p_inf,
 * half their power share and half pbrt's nInfinite / (nInfinite + 1) = 1/2
 * (the sky counting once): the power share alone lets a sky starve the lamps
 * of an interior, the count alone a dim sky take half the samples from
 * bright lamps.
 * Nonzero when out of memory. */
static int s_build_pick(pf_lights_t *self, const pf_scene_t *scene)
{
    size_t nb = 0, ninf = 0, nunb = 0;
    double pu = 0.0;
    for (size_t i = 0; i < self->n; i++) {
        pf_light_kind k = self->entries[i].kind;
        nb += s_bounded(k);
        if (k == PF_ENTRY_INFINITE || k == PF_ENTRY_ENVMAP) {
            nunb++;
            ninf = 1;
            pu += self->dcdf[i + 1] - self->dcdf[i];
        }
    }
    if (nb < 2 || s_light_groups(self, scene) < S_MIN_GROUPS)
        return 0;
    self->nunb = nunb;
    pf_light_bounds_t *b = malloc(nb * sizeof *b);
    uint32_t *id = malloc(nb * sizeof *id);
    self->unb = malloc((self->nunb ? self->nunb : 1) * sizeof *self->unb);
    self->unb_cdf = malloc((self->nunb + 1) * sizeof *self->unb_cdf);
    if (!b || !id || !self->unb || !self->unb_cdf) {
        free(b);
        free(id);
        return 1;
    }
    size_t k = 0, j = 0;
    double acc = 0.0;
    for (size_t i = 0; i < self->n; i++) {
        pf_light_kind kind = self->entries[i].kind;
        if (s_bounded(kind)) {
            b[k] = s_entry_bounds(self, scene, i);
            id[k++] = (uint32_t)i;
        } else if (kind != PF_ENTRY_DISTANT) {
            self->unb[j] = (uint32_t)i;
            self->unb_cdf[j++] = acc;
            acc += self->dcdf[i + 1] - self->dcdf[i];
        }
    }
    for (j = 0; j < self->nunb; j++)
        self->unb_cdf[j] /= acc;
    self->unb_cdf[self->nunb] = 1.0;
    self->bvh = pf_lightbvh_build(b, id, nb);
    free(b);
    free(id);
    if (!self->bvh)
        return 1;
    self->p_inf = self->nunb ? (float)(0.5 * pu + 0.5 * (double)ninf / (double)(ninf + 1)) : 0.0f;
    self->pu = pu;
    /* the sky entries' probabilities for direct light (pf_lights_sky_pdf) */
    for (j = 0; j < self->nunb; j++) {
        const pf_light_entry_t *e = &self->entries[self->unb[j]];
        float pmf = s_mix_pmf(self, self->unb[j], 0.0f);
        if (e->kind == PF_ENTRY_INFINITE)
            self->sky_pmf = pmf;
        else if (e->kind == PF_ENTRY_ENVMAP)
            self->env[e->light].pmf = pmf;
    }
    return 0;
}

/* The lookup tables (see the struct); nonzero when out of memory. */
static int s_build_tables(pf_lights_t *self, const pf_scene_t *scene)
{
    self->tris = malloc((self->narea ? self->narea : 1) * sizeof *self->tris);
    if (!self->tris || pf_cdf_guide_build(&self->cdf_guide, self->cdf, self->n))
        return 1;
    for (size_t i = 0; i < self->narea; i++)
        self->tris[i] = pf_emit_tri_make(scene, self->entries[i].mesh, self->entries[i].tri, self->entries[i].area);
    return self->dcdf != self->cdf && pf_cdf_guide_build(&self->dcdf_guide, self->dcdf, self->n);
}

pf_lights_t *pf_lights_build(const pf_scene_t *scene)
{
    pf_lights_t *self = calloc(1, sizeof *self);
    if (!self)
        return NULL;
    size_t cap = scene->nlights + scene->nspheres;
    for (size_t m = 0; m < scene->nmeshes; m++)
        for (size_t t = 0; t < scene->meshes[m].ntris; t++)
            cap += !pf_is_black(scene->mats[scene->meshes[m].mat[t]].le);
    self->entries = calloc(cap ? cap : 1, sizeof *self->entries);
    self->cdf = calloc(cap + 1, sizeof *self->cdf);
    self->sphere_entry = scene->nspheres ? calloc(scene->nspheres, sizeof *self->sphere_entry) : NULL;
    if (!self->entries || !self->cdf || (scene->nspheres && !self->sphere_entry)) {
        pf_lights_destroy(&self);
        return NULL;
    }
    s_bounding_sphere(scene, &self->center, &self->radius);
    double acc = 0.0;
    for (size_t m = 0; m < scene->nmeshes; m++) {
        const pf_mesh_t *mesh = &scene->meshes[m];
        for (size_t t = 0; t < mesh->ntris; t++) {
            pf_vec3 le = scene->mats[mesh->mat[t]].le;
            if (pf_is_black(le))
                continue;
            const uint32_t *v = &mesh->idx[3 * t];
            float area = 0.5f * pf_len(pf_cross(pf_sub(mesh->pos[v[1]], mesh->pos[v[0]]),
                                                pf_sub(mesh->pos[v[2]], mesh->pos[v[0]])));
            double p = PF_PI * (double)area * pf_luminance(le);
            if (scene->mats[mesh->mat[t]].twosided)
                p *= 2.0; /* both sides */
            if (!(p > 0.0))
                continue;
            self->entries[self->n] =
                (pf_light_entry_t){ .kind = PF_ENTRY_AREA, .mesh = (uint32_t)m, .tri = (uint32_t)t, .area = area };
            self->cdf[self->n++] = acc;
            acc += p;
        }
    }
    self->narea = self->n;
    for (size_t i = 0; i < scene->nspheres; i++) { /* after the triangles: pf_lights_pdf_at's search */
        const pf_sphere_t *sp = &scene->spheres[i];
        float area = pf_sphere_light_area(sp);
        double p = PF_PI * (double)area * pf_luminance(scene->mats[sp->mat].le);
        if (!(p > 0.0))
            continue;
        self->sphere_entry[i] = (uint32_t)self->n + 1;
        self->entries[self->n] = (pf_light_entry_t){ .kind = PF_ENTRY_SPHERE, .light = (uint32_t)i, .area = area };
        self->cdf[self->n++] = acc;
        acc += p;
    }
    for (size_t l = 0; l < scene->nlights; l++) {
        const pf_light_t *li = &scene->lights[l];
        double p = s_light_power(li, self->radius);
        if (!(p > 0.0))
            continue;
        if (li->type == PF_LIGHT_INFINITE && li->map) {
            if (s_add_envmap(self, scene, li, &acc))
                break;
            continue;
        }
        if (li->type == PF_LIGHT_INFINITE) { /* constant skies add up to one */
            self->sky = pf_add(self->sky, li->intensity);
            continue;
        }
        pf_light_kind kind = li->type == PF_LIGHT_DISTANT ? PF_ENTRY_DISTANT : PF_ENTRY_POINT;
        self->entries[self->n] =
            (pf_light_entry_t){ .kind = kind, .light = (uint32_t)l, .axis = li->dir, .cos_max = -1.0f };
        s_aim_at_scene(self, scene, &self->entries[self->n]);
        self->cdf[self->n++] = acc;
        acc += p;
    }
    pf_light_t sky = { .type = PF_LIGHT_INFINITE, .intensity = self->sky };
    double psky = s_light_power(&sky, self->radius);
    if (psky > 0.0) {
        self->entries[self->n] = (pf_light_entry_t){ .kind = PF_ENTRY_INFINITE, .cos_max = -1.0f };
        self->cdf[self->n++] = acc;
        acc += psky;
    } else {
        self->sky = pf_v3s(0.0f); /* no geometry to light: no sky either */
    }
    if (self->nenv && !self->env) { /* out of memory in s_add_envmap */
        pf_lights_destroy(&self);
        return NULL;
    }
    self->power = acc;
    for (size_t i = 0; i < self->n; i++)
        self->cdf[i] /= acc;
    self->cdf[self->n] = 1.0;
    if (s_direct_table(self) || s_build_tables(self, scene)) {
        pf_lights_destroy(&self);
        return NULL;
    }
    for (size_t i = 0; i < self->n; i++) {
        float pmf = (float)(self->dcdf[i + 1] - self->dcdf[i]);
        if (self->entries[i].kind == PF_ENTRY_ENVMAP)
            self->env[self->entries[i].light].pmf = pmf;
        else if (self->entries[i].kind == PF_ENTRY_INFINITE)
            self->sky_pmf = pmf;
    }
    if (s_build_pick(self, scene))
        pf_lights_destroy(&self);
    return self;
}

void pf_lights_destroy(pf_lights_t **self_p)
{
    if (!self_p || !*self_p)
        return;
    free((*self_p)->entries);
    free((*self_p)->sphere_entry);
    if ((*self_p)->dcdf != (*self_p)->cdf)
        free((*self_p)->dcdf);
    free((*self_p)->cdf);
    free((*self_p)->distant);
    for (size_t i = 0; (*self_p)->env && i < (*self_p)->nenv; i++)
        pf_envlight_free(&(*self_p)->env[i]);
    free((*self_p)->env);
    pf_lightbvh_destroy(&(*self_p)->bvh);
    free((*self_p)->unb);
    free((*self_p)->unb_cdf);
    free((*self_p)->tris);
    pf_cdf_guide_free(&(*self_p)->cdf_guide);
    pf_cdf_guide_free(&(*self_p)->dcdf_guide);
    free(*self_p);
    *self_p = NULL;
}

double pf_lights_power(const pf_lights_t *self) { return self->power; }
pf_vec3 pf_lights_sky(const pf_lights_t *self, pf_vec3 d)
{
    pf_vec3 L = self->sky;
    for (size_t i = 0; i < self->nenv; i++)
        L = pf_add(L, pf_envlight_le(&self->env[i], d));
    return L;
}

float pf_lights_sky_pdf(const pf_lights_t *self, pf_vec3 n, pf_vec3 d)
{
    float pdf;
    pf_lights_sky_mis(self, n, d, &pdf);
    return pdf;
}

pf_vec3 pf_lights_sky_mis(const pf_lights_t *self, pf_vec3 n, pf_vec3 d, float *pdf)
{
    pf_vec3 L = self->sky;
    float p = pf_is_black(n) ? self->sky_pmf / (4.0f * PF_PI) : self->sky_pmf * fmaxf(0.0f, pf_dot(n, d)) * PF_INV_PI;
    for (size_t i = 0; i < self->nenv; i++) { /* one map lookup for both */
        pf_vec3 le = pf_envlight_le(&self->env[i], d);
        L = pf_add(L, le);
        p += self->env[i].pmf * pf_envlight_pdf_le(&self->env[i], le);
    }
    *pdf = p;
    return L;
}

/* A sky direction drawn by the picked sky entry e (constant: uniform, or
 * cosine about n when n is not zero; a map: its distribution), weighed as a
 * sample of the mixture of every sky entry (see the top). 0 when it carries
 * nothing. */
static int s_sky_mixture(const pf_lights_t *self, const pf_light_entry_t *e, pf_vec3 n, const float u[3],
                         pf_light_conn_t *out)
{
    pf_vec3 wi;
    if (e->kind == PF_ENTRY_ENVMAP)
        wi = pf_envlight_sample(&self->env[e->light], u[1], u[2]);
    else if (pf_is_black(n))
        wi = pf_sample_sphere(u[1], u[2]);
    else
        wi = pf_to_world(pf_sample_cosine(u[1], u[2]), n);
    float pdf;
    pf_vec3 L = pf_lights_sky_mis(self, n, wi, &pdf);
    if (!(pdf > 0.0f) || pf_is_black(L))
        return 0;
    out->wi = wi;
    out->dist = INFINITY;
    out->weight = pf_scale(L, 1.0f / pdf);
    out->pdf = pdf;
    return 1;
}
size_t pf_lights_count(const pf_lights_t *self) { return self->n; }

size_t pf_lights_pick(const pf_lights_t *self, const double *cdf, float u, double *pmf)
{
    const pf_cdf_guide_t *g = cdf == self->cdf ? &self->cdf_guide : &self->dcdf_guide;
    size_t lo = pf_cdf_guide_pick(g, cdf, self->n, u);
    *pmf = cdf[lo + 1] - cdf[lo];
    return lo;
}

/* Direct light's choice of an entry at the receiver (x, n) with u: the
 * table's by power, or the BVH's and the unbounded entries' (see the
 * struct). SIZE_MAX when nothing is chosen. */
static size_t s_pick_direct(const pf_lights_t *self, pf_vec3 x, pf_vec3 n, float u, double *pmf)
{
    if (!self->bvh)
        return pf_lights_pick(self, self->dcdf, u, pmf);
    size_t e;
    double pp;
    if (u < S_DEFENSIVE) { /* by power */
        e = pf_lights_pick(self, self->dcdf, fminf(u / S_DEFENSIVE, 0x1.fffffep-1f), &pp);
        pf_light_kind k = self->entries[e].kind;
        float pb = s_bounded(k) ? pf_lightbvh_pmf(self->bvh, x, n, (uint32_t)e) : 0.0f;
        *pmf = (double)s_mix_pmf(self, e, pb);
        return e;
    }
    u = fminf((u - S_DEFENSIVE) / (1.0f - S_DEFENSIVE), 0x1.fffffep-1f);
    if (u < self->p_inf) {
        u = fminf(u / self->p_inf, 0x1.fffffep-1f);
        size_t lo = 0, hi = self->nunb;
        while (hi - lo > 1) {
            size_t mid = (lo + hi) / 2;
            if (self->unb_cdf[mid] <= u)
                lo = mid;
            else
                hi = mid;
        }
        *pmf = (double)s_mix_pmf(self, self->unb[lo], 0.0f);
        return self->unb[lo];
    }
    u = fminf((u - self->p_inf) / (1.0f - self->p_inf), 0x1.fffffep-1f);
    uint32_t id;
    float p;
    if (!pf_lightbvh_sample(self->bvh, x, n, u, &id, &p))
        return SIZE_MAX;
    *pmf = (double)s_mix_pmf(self, id, p);
    return id;
}


int pf_lights_sample_direct(const pf_lights_t *self, const pf_scene_t *scene, pf_vec3 x, const float u[3],
                            pf_light_conn_t *out)
{
    return pf_lights_sample_direct_at(self, scene, x, pf_v3s(0.0f), u, out);
}

/* A direct-light sample of emitting triangle t, omega its solid angle
 * from x (within sphtri.h's range), chosen with probability pmf: a
 * direction uniform in its solid angle (u[1], u[2]), pdf pmf / omega, and
 * the point where it meets the triangle's plane. 0 when x sees the back of
 * a one-sided emitter. */
static int s_tri_spherical(const pf_emit_tri_t *t, pf_vec3 x, double omega, double pmf, const float u[3],
                           pf_light_conn_t *out)
{
    pf_vec3 wi;
    if (!pf_sphtri_sample(x, t->p0, t->p1, t->p2, u[1], u[2], &wi))
        return 0;
    float cos_l = -pf_dot(wi, t->n);
    if (t->twosided)
        cos_l = fabsf(cos_l); /* x sees its back, which emits too */
    if (!(cos_l > 0.0f))
        return 0;
    float dist = pf_dot(pf_sub(t->p0, x), t->n) / pf_dot(wi, t->n);
    if (!(dist > 0.0f) || !isfinite(dist))
        return 0;
    float pdf = (float)(pmf / omega);
    out->wi = wi;
    out->dist = dist;
    out->weight = pf_scale(t->le, 1.0f / pdf);
    out->pdf = pdf;
    return 1;
}

int pf_lights_sample_direct_at(const pf_lights_t *self, const pf_scene_t *scene, pf_vec3 x, pf_vec3 n,
                               const float u[3], pf_light_conn_t *out)
{
    if (self->n == 0 || !(self->dcdf[self->n] > 0.0))
        return 0; /* no light, or only distant ones (pf_lights_distant) */
    double pmf;
    size_t pick = s_pick_direct(self, x, n, u[0], &pmf);
    if (pick == SIZE_MAX || !(pmf > 0.0))
        return 0;
    if (pick < self->narea) { /* an area entry: its record alone */
        const pf_emit_tri_t *t = &self->tris[pick];
        double omega = pf_sphtri_solid_angle(x, t->p0, t->p1, t->p2);
        if (omega >= PF_SPHTRI_MIN && omega <= PF_SPHTRI_MAX)
            return s_tri_spherical(t, x, omega, pmf, u, out);
        pf_vec3 p = pf_emit_tri_point(t, u[1], u[2], NULL), n = t->n;
        pf_vec3 d = pf_sub(p, x);
        float d2 = pf_len2(d);
        if (!(d2 > 0.0f))
            return 0;
        float dist = sqrtf(d2);
        pf_vec3 wi = pf_scale(d, 1.0f / dist);
        float cos_l = -pf_dot(wi, n);
        if (t->twosided)
            cos_l = fabsf(cos_l); /* x sees its back, which emits too */
        if (cos_l <= 0.0f)
            return 0; /* one-sided: x is behind the emitter */
        pf_vec3 le = t->le;
        float pdf_area = (float)pmf / t->area;
        out->wi = wi;
        out->dist = dist;
        out->weight = pf_scale(le, cos_l / (d2 * pdf_area));
        out->pdf = pdf_area * d2 / cos_l;
        return 1;
    }
    const pf_light_entry_t *e = &self->entries[pick];
    if (e->kind == PF_ENTRY_SPHERE) { /* uniform in its cone: Le / (pmf pdf) */
        const pf_sphere_t *sp = &scene->spheres[e->light];
        if (!pf_sphere_light_sample(sp, x, u[1], u[2], &out->wi, &out->dist, &out->pdf))
            return 0; /* x inside: it sees the back */
        out->pdf *= (float)pmf;
        out->weight = pf_scale(scene->mats[sp->mat].le, 1.0f / out->pdf);
        return 1;
    }
    if (e->kind == PF_ENTRY_ENVMAP || (e->kind == PF_ENTRY_INFINITE && self->nenv))
        return s_sky_mixture(self, e, n, u, out);
    if (e->kind == PF_ENTRY_INFINITE) {
        out->dist = INFINITY;
        if (pf_is_black(n)) { /* uniform over the sphere: L / (pdf pmf), pdf = 1 / (4 pi) */
            out->wi = pf_sample_sphere(u[1], u[2]);
            out->weight = pf_scale(self->sky, 4.0f * PF_PI / (float)pmf);
            out->pdf = (float)pmf / (4.0f * PF_PI);
            return 1;
        }
        /* cosine-weighted about n: L / (pdf pmf), pdf = cos / pi */
        pf_vec3 local = pf_sample_cosine(u[1], u[2]);
        if (!(local.z > 0.0f))
            return 0;
        out->wi = pf_to_world(local, n);
        out->weight = pf_scale(self->sky, PF_PI / (local.z * (float)pmf));
        out->pdf = (float)pmf * local.z * PF_INV_PI;
        return 1;
    }
    const pf_light_t *l = &scene->lights[e->light]; /* a point or spot: distant ones have no share here */
    pf_vec3 d = pf_sub(l->pos, x);
    float d2 = pf_len2(d);
    if (!(d2 > 0.0f))
        return 0;
    float dist = sqrtf(d2);
    pf_vec3 wi = pf_scale(d, 1.0f / dist);
    float falloff = l->type == PF_LIGHT_SPOT ? pf_spot_falloff(l, -pf_dot(wi, l->dir)) : 1.0f;
    if (falloff <= 0.0f)
        return 0;
    out->wi = wi;
    out->dist = dist;
    out->weight = pf_scale(l->intensity, falloff / (d2 * (float)pmf));
    out->pdf = 0.0f;
    return 1;
}

size_t pf_lights_distant_count(const pf_lights_t *self) { return self->ndistant; }

void pf_lights_distant(const pf_lights_t *self, const pf_scene_t *scene, size_t i, pf_light_conn_t *out)
{
    const pf_light_t *l = &scene->lights[self->entries[self->distant[i]].light];
    out->wi = pf_neg(l->dir);
    out->dist = INFINITY;
    out->weight = l->intensity;
    out->pdf = 0.0f;
}

float pf_lights_pdf(const pf_lights_t *self, const pf_scene_t *scene, pf_vec3 x, uint32_t geom, uint32_t prim,
                    pf_vec3 p)
{
    return pf_lights_pdf_at(self, scene, x, pf_v3s(0.0f), geom, prim, p);
}

/* Direct light's probability of choosing entry i at (x, nx). */
static float s_direct_pmf(const pf_lights_t *self, pf_vec3 x, pf_vec3 nx, size_t i)
{
    return self->bvh ? s_mix_pmf(self, i, pf_lightbvh_pmf(self->bvh, x, nx, (uint32_t)i))
                     : (float)(self->dcdf[i + 1] - self->dcdf[i]);
}

float pf_lights_pdf_at(const pf_lights_t *self, const pf_scene_t *scene, pf_vec3 x, pf_vec3 nx, uint32_t geom,
                       uint32_t prim, pf_vec3 p)
{
    if (geom == scene->nmeshes) { /* a sphere: accel.c's sphere_geom, prim its index */
        uint32_t i = self->sphere_entry && prim < scene->nspheres ? self->sphere_entry[prim] : 0;
        return i ? s_direct_pmf(self, x, nx, i - 1) * pf_sphere_light_pdf(&scene->spheres[prim], x) : 0.0f;
    }
    size_t lo = 0, hi = self->narea;
    while (lo < hi) { /* the first area entry >= (geom, prim) */
        size_t mid = (lo + hi) / 2;
        const pf_light_entry_t *e = &self->entries[mid];
        if (e->mesh < geom || (e->mesh == geom && e->tri < prim))
            lo = mid + 1;
        else
            hi = mid;
    }
    if (lo == self->narea || self->entries[lo].mesh != geom || self->entries[lo].tri != prim)
        return 0.0f;
    const pf_light_entry_t *e = &self->entries[lo];
    const pf_emit_tri_t *t = &self->tris[lo];
    pf_vec3 n = t->n; /* the normal exactly as pf_lights_surface_point gives it */
    pf_vec3 d = pf_sub(p, x);
    float d2 = pf_len2(d);
    if (!(d2 > 0.0f))
        return 0.0f;
    float cos_l = -pf_dot(d, n) / sqrtf(d2);
    if (t->twosided)
        cos_l = fabsf(cos_l); /* as pf_lights_sample_direct_at */
    if (cos_l <= 0.0f)
        return 0.0f;
    double omega = pf_sphtri_solid_angle(x, t->p0, t->p1, t->p2); /* sampled by solid angle, as there */
    if (omega >= PF_SPHTRI_MIN && omega <= PF_SPHTRI_MAX)
        return (float)((double)s_direct_pmf(self, x, nx, lo) / omega);
    return s_direct_pmf(self, x, nx, lo) / e->area * d2 / cos_l;
}
