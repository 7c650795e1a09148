/* stress.h: what the numerical stress suite's files share (test_stress.c
 * runs the groups). The scene builders and the checked renders live in
 * stress.c; each group of cases lives in a file of its own:
 * stress_analytic.c (furnace, plane, invariance), stress_geometry.c
 * (geometry, degenerate input), stress_kdtree.c (kd-tree extremes) and
 * stress_lights.c (distant and infinite lights).
 *
 * Every file checks through check.h shared (PF_CHECK_SHARED); the counts
 * live in test_stress.c, so the closing line counts the whole program. */
#ifndef PF_TEST_STRESS_H
#define PF_TEST_STRESS_H

#include <stddef.h>
#include <stdint.h>

#include "image/image.h"
#include "photon/kdtree.h"
#include "photon/trace.h"
#include "render/frame.h"
#include "scene/camera.h"
#include "scene/scene.h"

#define PF_CHECK_SHARED
#include "check.h"

/* The groups, one ctest each (argv[1] names them). */
void stress_test_furnace(void);
void stress_test_plane(void);
void stress_test_invariance(void);
void stress_test_geometry(void);
void stress_test_degenerate(void);
void stress_test_kdtree(void);
void stress_test_distant(void); /* stress_lights.c */
void stress_test_sky(void);     /* stress_lights.c */
void stress_test_envmap(void);  /* stress_envmap.c */
void stress_test_depth(void);   /* stress_depth.c */

/* Scene building: materials, watertight boxes, spheres, point lights, the
 * camera, and settings for a small, fast render. */
uint32_t stress_material(pf_scene_t *scene, pf_material_t m);
pf_material_t stress_diffuse(const char *name, float kd, float le);
pf_material_t stress_glass(const char *name, float ior);
double stress_area(const pf_scene_t *scene, uint32_t mat);
void stress_box(pf_scene_t *scene, pf_vec3 lo, pf_vec3 hi, uint32_t mat, int inward);
void stress_sphere(pf_scene_t *scene, pf_vec3 c, float r, uint32_t mat);
void stress_point_light(pf_scene_t *scene, pf_vec3 pos, float intensity);
void stress_camera(pf_scene_t *scene, pf_vec3 pos, pf_vec3 at, pf_vec3 up, float fov);
pf_settings_t stress_settings(const pf_scene_t *scene, int size, int spp, uint64_t photons, int gather);

/* pf_job_render_local, every image checked for NaN, Inf and negative
 * channels (and dumped under PF_STRESS_DUMP). 0 on success. */
int stress_render(const char *what, const pf_scene_t *scene, const pf_settings_t *s, unsigned terms,
                  pf_image_t *img, double *seconds);

/* The same steps as pf_job_render_local, split so that one photon pass can
 * serve several renders (terms, cameras) and its maps can be inspected. */
typedef struct stress_job {
    const pf_scene_t *scene;
    pf_settings_t settings;
    pf_frame_t fr; /* accel, lights, maps, texels */
    pf_photon_stats_t stats;
} stress_job_t;

int stress_job_begin(stress_job_t *job, const char *what, const pf_scene_t *scene, const pf_settings_t *s);
void stress_job_render(const stress_job_t *job, const char *what, unsigned terms, pf_image_t *img);
void stress_job_end(stress_job_t *job);

/* Image and photon-map statistics, in double. */
double stress_mean(const pf_image_t *img);
double stress_max(const pf_image_t *img);
double stress_within(const pf_image_t *img, double expect, double rel);
double stress_map_power(const pf_kdtree_t *map);
size_t stress_bad_photons(const pf_kdtree_t *map);

/* A Lambertian plane y = 0 under a point light, and its analytic radiance
 * (the plane group, and the grazing case of the geometry group). */
typedef struct stress_plane {
    double kd, intensity, half; /* albedo, point-light intensity, half the plane's side */
    pf_vec3 light;
} stress_plane_t;

void stress_plane_pixel(const stress_plane_t *pl, const pf_camera_t *cam, int px, int py, double *lo,
                        double *hi, double *mean);
double stress_plane_compare(const char *what, const stress_plane_t *pl, const pf_scene_t *scene,
                            const pf_image_t *img, double tol, double mean_tol, size_t *lit_pixels);

#endif
