/* render.h: the tile renderer, used by the worker and by the in-process
 * render alike. Given a frame (the scene, its Embree structure, the lights,
 * the photon maps and their texels; frame.h), renders any rectangle of the
 * image. Tiles are independent: a pixel's value depends on the scene, the
 * settings, the maps and the seed only, never on the tile it falls in or the
 * thread that renders it. */
#ifndef PF_RENDER_H
#define PF_RENDER_H

#include "accel/accel.h"
#include "image/image.h"
#include "light/light.h"
#include "photon/irrtex.h"
#include "photon/photonmap.h"
#include "render/frame.h"
#include "scene/camera.h"
#include "scene/scene.h"

/* Terms of the light-transport split, for rendering them separately. */
enum {
    PF_TERM_EMITTED = 1,  /* emitters seen directly or through mirror/glass */
    PF_TERM_DIRECT = 2,   /* light sampling at the visible non-specular point */
    PF_TERM_CAUSTIC = 4,  /* caustic map at the visible diffuse point */
    PF_TERM_INDIRECT = 8, /* final gather over the global map */
    PF_TERM_ALL = 15,
    PF_TERM_PHOTONMAP = 16, /* debugging: the global map's radiance at the visible point, no gather */
};

/* Camera samples per pixel over a rectangle of the image, for adaptive
 * progressive passes (coordinator/adapt.h): pixel (x, y) takes
 * n[(y - y0) * w + (x - x0)] >= 1 samples instead of settings.spp. A tile's
 * map must cover the tile and its first-gather filter border
 * (settings.gather_filter pixels, clipped to the image): the border
 * pixels' records are made from their own counts, as their own tiles make
 * them, so the pixels still do not depend on the tiling. */
typedef struct pf_spp_map {
    int x0, y0, w, h;
    const uint16_t *n;
} pf_spp_map_t;

typedef struct pf_render_ctx {
    const pf_scene_t *scene;
    const pf_accel_t *accel;
    const pf_lights_t *lights;
    const pf_photon_maps_t *maps;
    pf_irrtex_t *texels; /* the frame's irradiance texels (filled on first use), or NULL */
    pf_settings_t settings;
    pf_camera_t camera;
    unsigned terms; /* PF_TERM_* mask */
    /* Camera samples that came out non-finite or negative are left out of
     * their pixel (never reach the image) and counted here, atomically;
     * NULL: not counted. pf_render_ctx_init leaves it NULL. */
    uint64_t *dropped;
    /* Each gather ray's irradiance texel read made as the ray ends, not put
     * off while the next rays are traced (render.c, s_defer): the same
     * image (bit for bit with one gather ray per sample), slower. For tests
     * and benchmarks; pf_render_ctx_init leaves it 0. */
    int reads_at_once;
    /* The photon estimates' disc shrink of this progressive pass
     * (pf_pass_shrink2(settings.pass); 1 for pass 0). */
    float shrink2;
    /* Per-pixel camera samples of this pass (adaptive passes), covering
     * the whole image, or NULL: settings.spp everywhere (what
     * pf_render_ctx_init leaves). */
    const pf_spp_map_t *spp_map;
} pf_render_ctx_t;

/* The sum of final-gather rays' radiances, each exactly as the integrator
 * traces it (mirrors and glass followed, the global map's radiance at the
 * first non-specular hit), in one random stream (of the given sample index),
 * their texel reads put off a few rays as the first-gather records do
 * (unless ctx->reads_at_once). For benchmarks. */
pf_vec3 pf_render_gather_rays(const pf_render_ctx_t *ctx, const pf_ray_t *rays, size_t n, uint64_t sample);

/* Fills ctx for a full render of the frame's scene at settings' size. The
 * frame (render/frame.h) must outlive ctx and be ready (pf_frame_ready)
 * when it has maps. */
void pf_render_ctx_init(pf_render_ctx_t *ctx, const pf_frame_t *frame, const pf_settings_t *settings);

/* Renders pixels [x0, x0+w) x [y0, y0+h) into out (w*h*3 floats, top row
 * first), single-threaded (call it from as many threads as you like). */
void pf_render_tile(const pf_render_ctx_t *ctx, int x0, int y0, int w, int h, float *out);

/* A tile rendered row by row, for splitting one tile over threads: its rows
 * in any order, concurrently if you like, each written to its own w*3
 * floats. A row first makes sure the first-gather records it reads (rows
 * 0 .. pf_tile_plan_record_rows - 1 of the tile and its border) are done,
 * recording the missing ones itself; pf_tile_plan_record_row records one
 * ahead (once; thread-safe). The pixels are those pf_render_tile gives. */
typedef struct pf_tile_plan pf_tile_plan_t;
pf_tile_plan_t *pf_tile_plan_new(const pf_render_ctx_t *ctx, int x0, int y0, int w, int h);
/* The same with the per-pixel samples of map (covering the tile and its
 * border; NULL: ctx->spp_map) rather than ctx->spp_map: a worker's tiles
 * each bring their own. */
pf_tile_plan_t *pf_tile_plan_new_map(const pf_render_ctx_t *ctx, int x0, int y0, int w, int h,
                                     const pf_spp_map_t *map);
int pf_tile_plan_record_rows(const pf_tile_plan_t *p);
void pf_tile_plan_record_row(pf_tile_plan_t *p, int row);
void pf_tile_plan_render_row(pf_tile_plan_t *p, int row, float *out);
void pf_tile_plan_free(pf_tile_plan_t *p);

/* Where a tile's time went, for planning (--time-limit): the first-gather
 * records (the tile and its border of settings.gather_filter pixels) and the
 * rest. */
typedef struct pf_tile_cost {
    double record_s, render_s;          /* seconds */
    uint64_t record_samples, samples;   /* camera samples recorded / rendered */
} pf_tile_cost_t;

/* pf_render_tile, adding its costs to *cost. */
void pf_render_tile_cost(const pf_render_ctx_t *ctx, int x0, int y0, int w, int h, float *out, pf_tile_cost_t *cost);

/* Progress callback: tiles done so far and in all. */
typedef void (*pf_progress_fn)(void *user, int done, int total);

/* Renders the whole image in-process with `threads` OpenMP threads over
 * tiles of tile x tile pixels. img must be allocated at the camera's size. */
void pf_render_image(const pf_render_ctx_t *ctx, pf_image_t *img, int threads, int tile, pf_progress_fn progress,
                     void *user);

#endif
