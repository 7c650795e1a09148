/* stress.c: the stress suite's shared helpers (stress.h): building scenes in
 * code (materials, watertight boxes, spheres, lights, the camera), rendering
 * them with every image checked for NaN, Inf and negative channels, image and
 * photon-map statistics, and the analytic radiance of a plane under a point
 * light. The groups' files call these from the test's one thread; the
 * renders inside spread over OpenMP threads of their own. */
#include <math.h>
#include <omp.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "coordinator/job.h"
#include "light/light.h"
#include "render/render.h"

#include "stress.h"

/* ------------------------------------------------------------------------ */
/* Scene building                                                            */
/* ------------------------------------------------------------------------ */

uint32_t stress_material(pf_scene_t *scene, pf_material_t m)
{
    int i = pf_scene_add_material(scene, &m);
    PF_CHECK(i >= 0);
    return (uint32_t)i;
}

pf_material_t stress_diffuse(const char *name, float kd, float le)
{
    pf_material_t m = pf_material_default(name);
    m.kd = pf_v3s(kd);
    m.le = pf_v3s(le);
    return m;
}

pf_material_t stress_glass(const char *name, float ior)
{
    pf_material_t m = pf_material_default(name);
    m.type = PF_MAT_GLASS;
    m.kd = pf_v3s(0.0f);
    m.ks = pf_v3s(1.0f);
    m.kt = pf_v3s(1.0f);
    m.ior = ior;
    return m;
}


/* The total area of a scene's triangles with material mat, in double. */
double stress_area(const pf_scene_t *scene, uint32_t mat)
{
    double a = 0.0;
    for (size_t mi = 0; mi < scene->nmeshes; mi++) {
        const pf_mesh_t *m = &scene->meshes[mi];
        for (size_t t = 0; t < m->ntris; t++) {
            if (m->mat[t] != mat)
                continue;
            pf_vec3 p0 = m->pos[m->idx[3 * t]], p1 = m->pos[m->idx[3 * t + 1]], p2 = m->pos[m->idx[3 * t + 2]];
            double e1[3] = { (double)p1.x - p0.x, (double)p1.y - p0.y, (double)p1.z - p0.z };
            double e2[3] = { (double)p2.x - p0.x, (double)p2.y - p0.y, (double)p2.z - p0.z };
            double c[3] = { e1[1] * e2[2] - e1[2] * e2[1], e1[2] * e2[0] - e1[0] * e2[2], e1[0] * e2[1] - e1[1] * e2[0] };
            a += 0.5 * sqrt(c[0] * c[0] + c[1] * c[1] + c[2] * c[2]);
        }
    }
    return a;
}


/* An axis-aligned box lo..hi as one watertight mesh: 8 shared vertices and
 * 12 triangles, so no ray can slip between two faces. Face normals point out,
 * or in when inward is set (a room lit from inside). */
void stress_box(pf_scene_t *scene, pf_vec3 lo, pf_vec3 hi, uint32_t mat, int inward)
{
    pf_mesh_t m = { 0 };
    snprintf(m.name, sizeof m.name, "box");
    m.nverts = 8;
    m.ntris = 12;
    m.pos = malloc(8 * sizeof *m.pos);
    m.idx = malloc(36 * sizeof *m.idx);
    m.mat = malloc(12 * sizeof *m.mat);
    PF_CHECK(m.pos && m.idx && m.mat);
    for (int v = 0; v < 8; v++)
        m.pos[v] = pf_v3(v & 1 ? hi.x : lo.x, v & 2 ? hi.y : lo.y, v & 4 ? hi.z : lo.z);
    /* Counter-clockwise seen from outside: -x, +x, -y, +y, -z, +z. */
    static const uint32_t faces[6][4] = { { 0, 4, 6, 2 }, { 1, 3, 7, 5 }, { 0, 1, 5, 4 },
                                          { 2, 6, 7, 3 }, { 0, 2, 3, 1 }, { 4, 5, 7, 6 } };
    for (int f = 0; f < 6; f++) {
        const uint32_t *q = faces[f];
        uint32_t t[6] = { q[0], q[1], q[2], q[0], q[2], q[3] };
        if (inward) {
            t[1] = q[2], t[2] = q[1], t[4] = q[3], t[5] = q[2];
        }
        memcpy(&m.idx[6 * f], t, sizeof t);
        m.mat[2 * f] = m.mat[2 * f + 1] = mat;
    }
    PF_CHECK(pf_scene_add_mesh(scene, &m) == PF_OK);
}

void stress_sphere(pf_scene_t *scene, pf_vec3 c, float r, uint32_t mat)
{
    pf_sphere_t s = { c, r, mat };
    PF_CHECK(pf_scene_add_sphere(scene, &s) == PF_OK);
}

void stress_point_light(pf_scene_t *scene, pf_vec3 pos, float intensity)
{
    pf_light_t l = { .type = PF_LIGHT_POINT, .pos = pos, .intensity = pf_v3s(intensity) };
    PF_CHECK(pf_scene_add_light(scene, &l) == PF_OK);
}

void stress_camera(pf_scene_t *scene, pf_vec3 pos, pf_vec3 at, pf_vec3 up, float fov)
{
    scene->camera = (pf_camera_desc_t){ .pos = pos, .look_at = at, .up = up, .vfov_deg = fov };
    scene->has_camera = 1;
}

/* Settings for a small, fast render: no caustic map unless asked for. */
pf_settings_t stress_settings(const pf_scene_t *scene, int size, int spp, uint64_t photons, int gather)
{
    pf_settings_t s = scene->settings;
    s.width = s.height = size;
    s.spp = spp;
    s.photons = photons;
    s.caustic_photons = 0;
    s.gather = gather;
    return s;
}

/* ------------------------------------------------------------------------ */
/* Rendering and image checks                                                */
/* ------------------------------------------------------------------------ */

/* With PF_STRESS_DUMP=dir set, every checked image is also written there as
 * PNG and PFM, named after the case, to look at when a case fails. */
static void s_dump(const char *what, const pf_image_t *img)
{
    const char *dir = getenv("PF_STRESS_DUMP");
    if (!dir || !*dir)
        return;
    static int serial;
    char name[128], path[1024];
    size_t k = 0;
    for (const char *c = what; *c && k < sizeof name - 1; c++)
        name[k++] = (char)((*c >= 'a' && *c <= 'z') || (*c >= '0' && *c <= '9') || *c == '.' ? *c : '_');
    name[k] = '\0';
    pf_error_t err;
    double sum = 0.0;
    for (size_t i = 0; i < (size_t)img->width * (size_t)img->height * 3; i++)
        sum += isfinite(img->rgb[i]) ? img->rgb[i] : 0.0;
    double mean = sum / ((double)img->width * img->height * 3);
    snprintf(path, sizeof path, "%s/%03d-%s.png", dir, serial, name);
    /* Exposed so the mean maps to mid grey, whatever the scene's scale. */
    pf_image_write_png(img, path, mean > 0.0 ? (float)log2(0.18 / mean) : 0.0f, &err);
    snprintf(path, sizeof path, "%s/%03d-%s.pfm", dir, serial++, name);
    pf_image_write_pfm(img, path, &err);
}

/* Every render goes through here: no NaN, no Inf, no negative channel, by the
 * job's count (when given) and by a scan of our own. */
static void s_check_image(const char *what, const pf_image_t *img, size_t job_bad)
{
    s_dump(what, img);
    size_t n = (size_t)img->width * (size_t)img->height * 3, nonfinite = 0, negative = 0;
    for (size_t k = 0; k < n; k++) {
        nonfinite += !isfinite(img->rgb[k]);
        negative += img->rgb[k] < 0.0f;
    }
    CHECK(job_bad == 0, "%s: the job counted %zu bad channels", what, job_bad);
    CHECK(nonfinite == 0 && negative == 0, "%s: %zu non-finite and %zu negative channels", what, nonfinite,
          negative);
}

/* pf_job_render_local with the checks above. 0 on success. */
int stress_render(const char *what, const pf_scene_t *scene, const pf_settings_t *s, unsigned terms,
                  pf_image_t *img, double *seconds)
{
    pf_error_t err = { { 0 } };
    pf_job_summary_t sum;
    int rc = pf_job_render_local(scene, s, terms, 0, img, &sum, &err);
    CHECK(rc == PF_OK, "%s: render failed: %s", what, err.msg);
    if (rc != PF_OK)
        return rc;
    s_check_image(what, img, sum.bad_pixels);
    if (seconds)
        *seconds = sum.total_s;
    return PF_OK;
}

/* pf_job_render_local's steps, one at a time (stress_job_t in stress.h). */
int stress_job_begin(stress_job_t *job, const char *what, const pf_scene_t *scene, const pf_settings_t *s)
{
    memset(job, 0, sizeof *job);
    job->scene = scene;
    job->settings = *s;
    if (job->settings.threads <= 0)
        job->settings.threads = omp_get_num_procs();
    pf_error_t err = { { 0 } };
    int rc = pf_frame_open(&job->fr, scene, &err);
    CHECK(rc == PF_OK, "%s: accel: %s", what, err.msg);
    if (rc == PF_OK) {
        rc = pf_photon_pass(scene, job->fr.accel, job->fr.lights, &job->settings, &job->fr.maps, &job->stats);
        CHECK(rc == PF_OK, "%s: photon pass: %s", what, pf_strerror(rc));
        if (rc == PF_OK)
            pf_frame_ready(&job->fr);
        else
            pf_frame_close(&job->fr);
    }
    return rc;
}

/* Renders terms with the scene's current camera, and checks the image. */
void stress_job_render(const stress_job_t *job, const char *what, unsigned terms, pf_image_t *img)
{
    pf_render_ctx_t ctx;
    pf_render_ctx_init(&ctx, &job->fr, &job->settings);
    ctx.terms = terms;
    PF_CHECK(pf_image_alloc(img, job->settings.width, job->settings.height) == PF_OK);
    pf_render_image(&ctx, img, job->settings.threads, 16, NULL, NULL);
    size_t neg = 0, bad = pf_image_count_bad(img, &neg);
    s_check_image(what, img, bad + neg);
}

void stress_job_end(stress_job_t *job)
{
    pf_frame_close(&job->fr);
}

double stress_mean(const pf_image_t *img)
{
    size_t n = (size_t)img->width * (size_t)img->height * 3;
    double sum = 0.0;
    for (size_t k = 0; k < n; k++)
        sum += img->rgb[k];
    return n ? sum / (double)n : 0.0;
}

double stress_max(const pf_image_t *img)
{
    size_t n = (size_t)img->width * (size_t)img->height * 3;
    double m = 0.0;
    for (size_t k = 0; k < n; k++)
        m = fmax(m, img->rgb[k]);
    return m;
}

/* Fraction of channels within rel of expect. */
double stress_within(const pf_image_t *img, double expect, double rel)
{
    size_t n = (size_t)img->width * (size_t)img->height * 3, in = 0;
    for (size_t k = 0; k < n; k++)
        in += fabs(img->rgb[k] / expect - 1.0) <= rel;
    return (double)in / (double)n;
}

/* Sum of the stored power of a photon map (first channel), in double. */
double stress_map_power(const pf_kdtree_t *map)
{
    double sum = 0.0;
    const pf_photon_t *p = pf_kdtree_photons(map);
    for (size_t i = 0; i < pf_kdtree_size(map); i++)
        sum += p[i].power[0];
    return sum;
}

/* Photons (or irradiance points) whose power is non-finite or negative. */
size_t stress_bad_photons(const pf_kdtree_t *map)
{
    size_t bad = 0;
    const pf_photon_t *p = pf_kdtree_photons(map);
    for (size_t i = 0; map && i < pf_kdtree_size(map); i++)
        for (int k = 0; k < 3; k++)
            bad += !isfinite(p[i].power[k]) || p[i].power[k] < 0.0f;
    return bad;
}


/* ------------------------------------------------------------------------ */
/* the plane under a point light, analytically                              */
/* ------------------------------------------------------------------------ */

/* Radiance of the Lambertian plane y = 0 (|x|, |z| <= half) under a point
 * light, along the camera ray through film position (fx, fy); 0 where the ray
 * misses. L = kd / pi * I cos(theta) / d^2, in double. */
static double s_plane_radiance(const stress_plane_t *pl, const pf_camera_t *cam, double fx, double fy)
{
    pf_ray_t r = pf_camera_ray(cam, (float)fx, (float)fy);
    if (!(r.d.y < 0.0f))
        return 0.0;
    double t = -(double)r.o.y / (double)r.d.y;
    double p[3] = { r.o.x + t * r.d.x, 0.0, r.o.z + t * r.d.z };
    if (fabs(p[0]) > pl->half || fabs(p[2]) > pl->half)
        return 0.0;
    double v[3] = { pl->light.x - p[0], pl->light.y - p[1], pl->light.z - p[2] };
    double d2 = v[0] * v[0] + v[1] * v[1] + v[2] * v[2];
    return pl->kd / M_PI * pl->intensity * (v[1] / sqrt(d2)) / d2;
}

/* The analytic radiance's range over pixel (px, py), on a 9 x 9 grid that
 * includes the pixel's corners, and its mean by the midpoint rule on 8 x 8. */
void stress_plane_pixel(const stress_plane_t *pl, const pf_camera_t *cam, int px, int py, double *lo,
                        double *hi, double *mean)
{
    const int g = 9;
    *lo = INFINITY;
    *hi = 0.0;
    *mean = 0.0;
    for (int j = 0; j < g; j++)
        for (int i = 0; i < g; i++) {
            double v = s_plane_radiance(pl, cam, px + i / (g - 1.0), py + j / (g - 1.0));
            *lo = fmin(*lo, v);
            *hi = fmax(*hi, v);
            if (i < g - 1 && j < g - 1)
                *mean += s_plane_radiance(pl, cam, px + (i + 0.5) / (g - 1.0), py + (j + 0.5) / (g - 1.0));
        }
    *mean /= (g - 1) * (g - 1);
}

/* Compares a direct-light render of the plane with the analytic radiance:
 * every pixel inside its pixel's range (widened by tol), the image mean within
 * mean_tol. Direct light from a point light has no noise beyond the pixel
 * jitter, so a single shadow-acne pixel (a self-intersection at the offset
 * origin) falls outside. Returns the worst relative excursion. */
double stress_plane_compare(const char *what, const stress_plane_t *pl, const pf_scene_t *scene,
                            const pf_image_t *img, double tol, double mean_tol, size_t *lit_pixels)
{
    pf_camera_t cam = pf_camera_make(&scene->camera, img->width, img->height);
    size_t outside = 0, lit = 0;
    double worst = 0.0, sum_r = 0.0, sum_a = 0.0;
    for (int py = 0; py < img->height; py++)
        for (int px = 0; px < img->width; px++) {
            double lo, hi, mean;
            stress_plane_pixel(pl, &cam, px, py, &lo, &hi, &mean);
            double v = img->rgb[3 * ((size_t)py * (size_t)img->width + (size_t)px)];
            if (lo > 0.0) { /* the mean compares pixels wholly on the plane */
                lit++;
                sum_r += v;
                sum_a += mean;
            }
            double ex = 0.0;
            if (v < lo)
                ex = (lo - v) / lo;
            else if (v > hi)
                ex = hi > 0.0 ? (v - hi) / hi : INFINITY;
            worst = fmax(worst, ex);
            if (ex > tol) {
                if (outside++ < 5)
                    printf("  %s: pixel (%d, %d) = %.6g outside [%.6g, %.6g]\n", what, px, py, v, lo, hi);
            }
        }
    double ratio = sum_r / sum_a;
    printf("%s: %zu pixels, %zu wholly on the plane; worst excursion outside the pixel's analytic range %.2e "
           "(bound %.0e); mean ratio over those %.6f (bound 1 +- %.0e)\n",
           what, (size_t)img->width * (size_t)img->height, lit, worst, tol, ratio, mean_tol);
    CHECK(outside == 0, "%s: %zu pixels outside their analytic range", what, outside);
    CHECK(fabs(ratio - 1.0) <= mean_tol, "%s: mean ratio %.6f", what, ratio);
    if (lit_pixels)
        *lit_pixels = lit;
    return worst;
}

