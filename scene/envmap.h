/* envmap.h: an environment image, the radiance of an image-based infinite
 * light (a sky) by direction: its pixels (linear float RGB, top row first,
 * every value finite and >= 0), the mapping from the unit sphere to the image
 * square, and the light's frame (pbrt's renderFromLight). The scene owns its
 * maps (pf_scene_t.envmaps); an infinite light with map = k + 1 multiplies
 * its intensity (the scale) by map k's pixel in the direction it is seen.
 *
 * Mappings, in the light's frame:
 *   PF_ENVMAP_EQUALAREA  Clarberg's equal-area octahedral square (pbrt-v4's
 *                        EqualAreaSquareToSphere): +z is the square's
 *                        centre, -z its corners; every pixel covers the
 *                        same solid angle 4 pi / (w h). Square images only.
 *   PF_ENVMAP_EQUIRECT   latitude-longitude: the row v (0 at the top) is the
 *                        polar angle theta = pi v from +z, the column u the
 *                        azimuth phi = 2 pi u from +x towards +y.
 * Lookups take the nearest pixel, as pbrt-v4's ImageInfiniteLight does (its
 * octahedral wrap for pixels past the square's edge). */
#ifndef PF_ENVMAP_H
#define PF_ENVMAP_H

#include <stddef.h>

#include "base/vec.h"

typedef enum { PF_ENVMAP_EQUALAREA = 0, PF_ENVMAP_EQUIRECT = 1 } pf_envmap_mapping;
#define PF_ENVMAP_MAPPING_LAST PF_ENVMAP_EQUIRECT

/* The largest side a map may have (a 16k x 16k map is 3 GB of floats). */
#define PF_ENVMAP_MAX_SIDE 16384

typedef struct pf_envmap {
    char name[64];      /* the file it came from (its last 63 bytes), for messages */
    int width, height;
    int mapping;        /* pf_envmap_mapping */
    float *rgb;         /* width * height * 3, top row first */
    float to_world[9];  /* light frame -> world, row-major; directions are normalized after */
    float to_light[9];  /* its inverse */
} pf_envmap_t;

/* pbrt-v4's EqualAreaSquareToSphere: the unit direction of (u, v) in [0, 1]^2. */
pf_vec3 pf_equal_area_square_to_sphere(float u, float v);
/* Its inverse for a unit d: (u, v) in [0, 1]^2. */
void pf_equal_area_sphere_to_square(pf_vec3 d, float *u, float *v);

/* Sets to_world (row-major 3x3) and its inverse. PF_EINVAL when singular or
 * not finite. */
int pf_envmap_set_frame(pf_envmap_t *m, const double to_world[9]);
/* The pixel a world direction d (any length > 0) falls in. */
void pf_envmap_pixel(const pf_envmap_t *m, pf_vec3 d, int *x, int *y);
/* The map's value (before the light's scale) in world direction d. */
pf_vec3 pf_envmap_lookup(const pf_envmap_t *m, pf_vec3 d);
/* The solid angle pixel row y covers, per pixel (sr). */
double pf_envmap_pixel_solid_angle(const pf_envmap_t *m, int y);
/* The world direction at (fx, fy) in [0, 1)^2 inside pixel (x, y): uniform
 * (fx, fy) give directions uniform in the pixel's solid angle. */
pf_vec3 pf_envmap_pixel_dir(const pf_envmap_t *m, int x, int y, float fx, float fy);
/* The integral of a channel-wise weight w over the sphere, as luminance:
 * sum over pixels of lum(w * pixel) * solid angle; up: only directions with
 * light-frame z > 0, each times that z (the illuminance of an upward patch). */
double pf_envmap_integral(const pf_envmap_t *m, pf_vec3 w, int up);
/* Bytes the map's pixels take. */
size_t pf_envmap_bytes(const pf_envmap_t *m);

#endif
