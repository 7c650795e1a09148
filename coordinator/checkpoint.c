/* checkpoint.c: a farm render's progress on disk; see checkpoint.h. Called
 * from the event loop's thread. */
#include "coordinator/checkpoint.h"

#include <errno.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "base/atomicfile.h"
#include "base/hash.h"
#include "base/wire.h"
#include "proto/messages.h"
#include "proto/sceneblob.h"

#define S_MAGIC 0x4b434650u /* "PFCK" */

uint64_t pf_ckpt_key(const pf_scene_t *scene, const pf_settings_t *settings, unsigned terms, int passes,
                     int time_limited, int tile)
{
    pf_buf_t b = { 0 };
    uint64_t h = PF_HASH_INIT;
    if (pf_sceneblob_write(scene, &b) == PF_OK)
        h = pf_hash_bytes(h, b.data, b.len);
    pf_buf_free(&b);
    pf_settings_t s = *settings;
    s.threads = 0; /* threads never change the image */
    if (time_limited) {
        s.spp = 0; /* planned per pass: kept in the checkpoint */
        s.photons = s.caustic_photons = 0;
    }
    if (pf_wr_settings(&b, &s) == PF_OK)
        h = pf_hash_bytes(h, b.data, b.len);
    pf_buf_free(&b);
    h = pf_hash_u64(h, terms);
    h = pf_hash_u64(h, (uint64_t)passes);
    h = pf_hash_u64(h, (uint64_t)time_limited);
    return pf_hash_u64(h, (uint64_t)tile);
}

/* v's n low bytes, little-endian (as pf_wr_u32 and pf_wr_u64 write them). */
static void s_le(uint8_t *p, uint64_t v, int n)
{
    for (int i = 0; i < n; i++)
        p[i] = (uint8_t)(v >> 8 * i);
}

/* The sums (sum, sum2 as f64 per channel) and then the weights (weight,
 * passes as u32 per pixel): the bytes a pf_wr_u64 / pf_wr_u32 per number
 * wrote, staged a chunk at a time, since at 640x360 that was 5.5 million
 * calls after every pass of a time-limited render (2 % of its time). */
static int s_wr_acc(pf_buf_t *b, const pf_accum_t *acc, size_t np)
{
    uint8_t chunk[4096]; /* a multiple of 16 and of 8 */
    size_t k = 0;
    int rc = 0;
    for (size_t i = 0; rc == 0 && i < 3 * np; i++) {
        uint64_t u[2];
        memcpy(&u[0], &acc->sum[i], sizeof u[0]);
        memcpy(&u[1], &acc->sum2[i], sizeof u[1]);
        s_le(chunk + k, u[0], 8);
        s_le(chunk + k + 8, u[1], 8);
        if ((k += 16) == sizeof chunk)
            rc = pf_wr_bytes(b, chunk, k), k = 0;
    }
    for (size_t i = 0; rc == 0 && i < np; i++) {
        s_le(chunk + k, acc->weight[i], 4);
        s_le(chunk + k + 4, acc->passes[i], 4);
        if ((k += 8) == sizeof chunk)
            rc = pf_wr_bytes(b, chunk, k), k = 0;
    }
    return rc != 0 ? rc : pf_wr_bytes(b, chunk, k);
}

static double s_rd_f64(pf_rd_t *r)
{
    uint64_t u = pf_rd_u64(r);
    double v;
    memcpy(&v, &u, sizeof v);
    return v;
}

int pf_ckpt_write(const char *path, uint64_t key, int passes_done, const pf_accum_t *acc, const pf_settings_t *pass,
                  const pf_image_t *img, const uint32_t (*rects)[4], int n, pf_error_t *err)
{
    pf_buf_t b = { 0 };
    int rc = pf_wr_u32(&b, S_MAGIC) | pf_wr_u32(&b, PF_CKPT_VERSION) | pf_wr_u64(&b, key) |
             pf_wr_u32(&b, (uint32_t)img->width) | pf_wr_u32(&b, (uint32_t)img->height) |
             pf_wr_u32(&b, (uint32_t)passes_done) | pf_wr_u8(&b, acc ? 1 : 0);
    size_t np = (size_t)img->width * (size_t)img->height;
    if (acc && rc == 0)
        rc = s_wr_acc(&b, acc, np);
    rc |= pf_wr_settings(&b, pass) | pf_wr_u32(&b, (uint32_t)n);
    for (int t = 0; rc == 0 && t < n; t++) {
        const uint32_t *q = rects[t];
        rc = pf_wr_u32(&b, q[0]) | pf_wr_u32(&b, q[1]) | pf_wr_u32(&b, q[2]) | pf_wr_u32(&b, q[3]);
        for (uint32_t y = 0; rc == 0 && y < q[3]; y++)
            rc = pf_wr_bytes(&b, &img->rgb[3 * ((size_t)(q[1] + y) * (size_t)img->width + q[0])],
                             3 * (size_t)q[2] * sizeof(float));
    }
    if (rc != 0) {
        pf_buf_free(&b);
        return pf_error_set(err, PF_ENOMEM, path, 0, "out of memory for the checkpoint");
    }
    rc = pf_file_write_atomic(path, b.data, b.len, err);
    pf_buf_free(&b);
    return rc;
}

void pf_ckpt_free(pf_ckpt_t *c)
{
    if (c->has_acc)
        pf_accum_free(&c->acc);
    for (int t = 0; t < c->ntiles; t++)
        free(c->tiles[t].px);
    free(c->tiles);
    memset(c, 0, sizeof *c);
}

static int s_bad(pf_ckpt_t *c, pf_error_t *err, const char *path, const char *what)
{
    pf_ckpt_free(c);
    return pf_error_set(err, PF_EPARSE, path, 0, "not a usable checkpoint: %s", what);
}

/* The tiles of the pass under way, checked against the image. */
static int s_read_tiles(pf_rd_t *r, pf_ckpt_t *c, const char *path, pf_error_t *err)
{
    uint32_t n = pf_rd_u32(r);
    uint64_t np = (uint64_t)c->width * (uint64_t)c->height;
    if (!pf_rd_ok(r) || n > np)
        return s_bad(c, err, path, "bad tile count");
    c->tiles = calloc(n ? n : 1, sizeof *c->tiles);
    if (!c->tiles)
        return s_bad(c, err, path, "out of memory");
    for (uint32_t t = 0; t < n; t++) {
        pf_ckpt_tile_t *k = &c->tiles[t];
        k->x0 = pf_rd_u32(r);
        k->y0 = pf_rd_u32(r);
        k->w = pf_rd_u32(r);
        k->h = pf_rd_u32(r);
        if (!pf_rd_ok(r) || k->w == 0 || k->h == 0 || k->x0 >= (uint32_t)c->width || k->y0 >= (uint32_t)c->height ||
            k->w > (uint32_t)c->width - k->x0 || k->h > (uint32_t)c->height - k->y0)
            return s_bad(c, err, path, "a tile outside the image");
        size_t nf = 3 * (size_t)k->w * k->h;
        const uint8_t *px = pf_rd_bytes(r, nf * sizeof(float));
        k->px = px ? malloc(nf * sizeof(float)) : NULL;
        if (!k->px)
            return s_bad(c, err, path, px ? "out of memory" : "truncated");
        memcpy(k->px, px, nf * sizeof(float));
        c->ntiles++;
    }
    return PF_OK;
}

int pf_ckpt_read(const char *path, uint64_t key, int width, int height, pf_ckpt_t *c, pf_error_t *err)
{
    memset(c, 0, sizeof *c);
    FILE *fp = fopen(path, "rb");
    if (!fp)
        return pf_error_set(err, PF_EIO, path, 0, "cannot open the checkpoint: %s", strerror(errno));
    pf_buf_t b = { 0 };
    uint8_t chunk[65536];
    size_t got;
    int rc = 0;
    while (rc == 0 && (got = fread(chunk, 1, sizeof chunk, fp)) > 0)
        rc = pf_wr_bytes(&b, chunk, got);
    fclose(fp);
    if (rc != 0) {
        pf_buf_free(&b);
        return pf_error_set(err, PF_ENOMEM, path, 0, "out of memory");
    }
    pf_rd_t r = pf_rd_make(b.data, b.len);
    uint32_t magic = pf_rd_u32(&r), version = pf_rd_u32(&r);
    c->key = pf_rd_u64(&r);
    c->width = (int)pf_rd_u32(&r);
    c->height = (int)pf_rd_u32(&r);
    c->passes_done = (int)pf_rd_u32(&r);
    int has = pf_rd_u8(&r);
    if (!pf_rd_ok(&r) || magic != S_MAGIC || version != PF_CKPT_VERSION) {
        pf_buf_free(&b);
        return s_bad(c, err, path, "not a photonfarm checkpoint of this version");
    }
    if (c->key != key || c->width != width || c->height != height) {
        pf_buf_free(&b);
        pf_ckpt_free(c);
        return pf_error_set(err, PF_EMISMATCH, path, 0,
                            "the checkpoint is of another render (scene, settings, terms, passes or tile size "
                            "differ): not resumed");
    }
    if (c->passes_done < 0 || c->passes_done >= PF_MAX_PASSES || has > 1) {
        pf_buf_free(&b);
        return s_bad(c, err, path, "bad pass count");
    }
    if (has && (rc = pf_accum_init(&c->acc, width, height)) == PF_OK) {
        c->has_acc = 1;
        size_t np = (size_t)width * (size_t)height;
        for (size_t i = 0; i < 3 * np; i++) {
            c->acc.sum[i] = s_rd_f64(&r);
            c->acc.sum2[i] = s_rd_f64(&r);
        }
        for (size_t i = 0; i < np; i++) {
            c->acc.weight[i] = pf_rd_u32(&r);
            c->acc.passes[i] = pf_rd_u32(&r);
        }
    }
    char why[256] = "";
    pf_rd_settings(&r, &c->pass);
    if (rc == PF_OK && (!pf_rd_ok(&r) || pf_settings_check(&c->pass, why, sizeof why) != PF_OK ||
                        c->pass.pass != c->passes_done))
        rc = s_bad(c, err, path, why[0] ? why : "bad settings of the pass under way");
    else if (rc == PF_OK)
        rc = s_read_tiles(&r, c, path, err);
    else
        rc = s_bad(c, err, path, "out of memory");
    if (rc == PF_OK && r.left != 0)
        rc = s_bad(c, err, path, "trailing bytes");
    pf_buf_free(&b);
    return rc;
}
