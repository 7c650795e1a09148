/* test_leases.c: the farm's tile table (coordinator/leases.h). Every pixel
 * of the image lies in exactly one tile, whatever the size and the tile
 * side; the queue holds every tile once; the job ends on small tiles (the
 * last quarter of the grid split in four), so the last round leaves no
 * worker with a whole tile while the others idle; a tile side under 16 is
 * not split. */
#include <stdlib.h>
#include <string.h>

#include "check.h"
#include "coordinator/leases.h"

/* Checks the table for width x height at side ts; returns the tile count. */
static int s_check(int width, int height, int ts)
{
    pf_leases_t L;
    CHECK(pf_leases_init(&L, width, height, ts) == 0);
    unsigned char *cover = calloc((size_t)width * (size_t)height, 1);
    unsigned char *queued = calloc((size_t)L.nt, 1);
    int overlaps = 0, outside = 0, bad_queue = 0;
    for (int i = 0; i < L.nt; i++) {
        const pf_tile_t *t = &L.t[i];
        if (t->w == 0 || t->h == 0 || t->x0 + t->w > (uint32_t)width || t->y0 + t->h > (uint32_t)height ||
            t->w > (uint32_t)ts || t->h > (uint32_t)ts) {
            outside++;
            continue;
        }
        for (uint32_t y = t->y0; y < t->y0 + t->h; y++)
            for (uint32_t x = t->x0; x < t->x0 + t->w; x++)
                overlaps += cover[(size_t)y * (size_t)width + x]++ != 0;
        int q = L.queue[i];
        if (q < 0 || q >= L.nt || queued[q]++)
            bad_queue++;
    }
    size_t holes = 0;
    for (size_t p = 0; p < (size_t)width * (size_t)height; p++)
        holes += cover[p] == 0;
    CHECK(outside == 0 && overlaps == 0 && holes == 0, "%dx%d tile %d: %d tiles outside, %d pixels twice, %zu in none",
          width, height, ts, outside, overlaps, holes);
    CHECK(bad_queue == 0 && L.qlen == L.nt && L.ndone == 0, "%dx%d tile %d: queue", width, height, ts);
    int tx = (width + ts - 1) / ts, ty = (height + ts - 1) / ts, grid = tx * ty;
    if (ts >= 16) {
        /* The first three quarters are whole tiles in row order; the tail
         * is of tiles of side at most ceil(ts / 2). */
        int whole = grid - grid / 4, ok = 1;
        for (int i = 0; i < whole; i++)
            ok &= L.t[L.queue[i]].x0 == (uint32_t)((i % tx) * ts) && L.t[L.queue[i]].y0 == (uint32_t)((i / tx) * ts);
        CHECK(ok, "%dx%d tile %d: the head is the grid in row order", width, height, ts);
        int small = 1;
        for (int i = whole; i < L.nt; i++)
            small &= L.t[L.queue[i]].w <= (uint32_t)(ts + 1) / 2 && L.t[L.queue[i]].h <= (uint32_t)(ts + 1) / 2;
        CHECK(small, "%dx%d tile %d: the tail is of split tiles", width, height, ts);
        CHECK(L.nt >= grid + 3 * (grid / 4 - tx), "%dx%d tile %d: %d tiles for a grid of %d", width, height, ts, L.nt, grid);
    } else {
        CHECK(L.nt == grid, "%dx%d tile %d: %d tiles, grid %d (no split under 16)", width, height, ts, L.nt, grid);
    }
    int n = L.nt;
    free(cover);
    free(queued);
    pf_leases_free(&L);
    return n;
}

int main(void)
{
    static const int sizes[][2] = { { 1280, 720 }, { 512, 512 }, { 128, 128 }, { 33, 17 }, { 1, 1 },
                                    { 640, 360 }, { 97, 203 }, { 16, 16 } };
    static const int sides[] = { 8, 15, 16, 17, 31, 32, 64, 256 };
    for (size_t i = 0; i < sizeof sizes / sizeof *sizes; i++)
        for (size_t j = 0; j < sizeof sides / sizeof *sides; j++)
            s_check(sizes[i][0], sizes[i][1], sides[j]);
    /* 1280x720 at 32: a grid of 40 x 23 = 920; its last 230 in quarters
     * (the last row's tiles are 16 high: two quadrants each). */
    int n = s_check(1280, 720, 32);
    CHECK(n == 690 + 4 * 190 + 2 * 40, "1280x720 at 32: %d tiles", n);
    return pf_test_finish();
}
