/* checkpoint.h: a farm render's progress on disk, so that `photonfarm
 * render ... --resume` goes on after the coordinator died (kill -9, a power
 * cut) and ends with the image an uninterrupted run gives, bit for bit.
 *
 * What it holds: the key of the render (scene, settings, terms, passes,
 * tile size: pf_ckpt_key), the passes done as the running mean's sums
 * (accum.h; none for a one-pass render), and the pass under way: its
 * settings (as planned: a time limit's choices are kept) and the tiles of
 * it that are done, with their pixels. The coordinator writes it after each
 * whole pass and every few seconds while tiles come in, atomically
 * (base/atomicfile.h); a render that ends well removes it.
 *
 * Format (little-endian, base/wire.h): "PFCK", u32 version, u64 key,
 * u32 width, u32 height, u32 passes done, u8 has sums, [sums: f64 x 3wh,
 * f64 x 3wh, u32 x wh, u32 x wh], the pass under way's settings (the
 * settings codec of proto/messages.h), u32 tiles, then per tile u32 x0, y0,
 * w, h and w h 3 f32. Every field is checked on reading; a file that does
 * not fit is refused with a sentence, never half used. */
#ifndef PF_CHECKPOINT_H
#define PF_CHECKPOINT_H

#include <stdint.h>

#include "coordinator/accum.h"
#include "image/image.h"
#include "scene/scene.h"

/* 2: the settings group gained path_max_depth. */
#define PF_CKPT_VERSION 2

typedef struct pf_ckpt_tile {
    uint32_t x0, y0, w, h;
    float *px; /* w h 3 floats */
} pf_ckpt_tile_t;

typedef struct pf_ckpt {
    uint64_t key;
    int width, height;
    int passes_done;       /* whole passes in acc */
    int has_acc;
    pf_accum_t acc;        /* their sums (has_acc) */
    pf_settings_t pass;    /* the pass under way (index passes_done) */
    int ntiles;
    pf_ckpt_tile_t *tiles; /* its tiles done */
} pf_ckpt_t;

/* The key: the scene's content, every setting that changes the image (not
 * threads), the terms, the passes asked for, a time limit or not, the tile
 * size. */
uint64_t pf_ckpt_key(const pf_scene_t *scene, const pf_settings_t *settings, unsigned terms, int passes,
                     int time_limited, int tile);

/* Writes a checkpoint: acc (NULL: none) with passes_done whole passes, the
 * pass under way's settings and its tiles done (n rectangles, their pixels
 * read from img). 0 or a status with err filled. */
int pf_ckpt_write(const char *path, uint64_t key, int passes_done, const pf_accum_t *acc, const pf_settings_t *pass,
                  const pf_image_t *img, const uint32_t (*rects)[4], int n, pf_error_t *err);

/* Reads path into *c (free with pf_ckpt_free), checking it holds a render
 * of this key and size. PF_ENOENT-like absence is reported as PF_EIO with
 * errno's text; a different render as PF_EMISMATCH; a malformed file as
 * PF_EPARSE; each with err naming the file and what was wrong. */
int pf_ckpt_read(const char *path, uint64_t key, int width, int height, pf_ckpt_t *c, pf_error_t *err);

void pf_ckpt_free(pf_ckpt_t *c);

#endif
