/* budget.c: the time-limit planner; see budget.h for how it decides. Called
 * from the thread that runs the photon pass (the main thread in-process, the
 * farm's photon thread); the probe renders with OpenMP. */
#include "coordinator/budget.h"

#include <inttypes.h>
#include <math.h>
#include <omp.h>
#include <string.h>

#include "base/log.h"
#include "photon/trace.h"
#include "render/render.h"

/* Writing the image and the farm's last results take a moment after the
 * last tile; the render may overrun its estimate by this fraction. */
#define S_RESERVE_S 0.25
#define S_RESERVE_SHARE 0.03
#define S_SAFETY 0.85
#define S_LAST_SAFETY 0.97
#define S_MIN_TILES_S 0.3 /* the least time worth starting a last pass for */

void pf_budget_init(pf_budget_t *b, double start, double limit_s, int render_threads, int tile)
{
    memset(b, 0, sizeof *b);
    b->tile = tile;
    b->limit_s = limit_s;
    b->deadline = start + limit_s;
    b->render_threads = render_threads > 0 ? render_threads : 1;
}

double pf_budget_left(const pf_budget_t *b) { return b->deadline - pf_now(); }

static uint64_t s_clamp_photons(double n)
{
    if (!(n > PF_BUDGET_MIN_PHOTONS))
        return PF_BUDGET_MIN_PHOTONS;
    if (n > PF_BUDGET_MAX_PHOTONS)
        return PF_BUDGET_MAX_PHOTONS;
    return (uint64_t)n;
}

int pf_budget_plan_photons(pf_budget_t *b, const pf_frame_t *frame, pf_settings_t *s)
{
    if (b->fix_photons && b->fix_caustic)
        return PF_OK;
    pf_settings_t cal = *s;
    cal.photons = s->photons ? PF_BUDGET_CAL_PHOTONS : 0;
    cal.caustic_photons = s->caustic_photons ? PF_BUDGET_CAL_PHOTONS : 0;
    /* The faster of two passes: one pass takes a few tens of milliseconds,
     * so a first touch of memory, the thread pool's start or a moment of the
     * machine's other load could make it look several times slower (seen
     * here: 10x fewer photons chosen in one run of four). */
    double dt = INFINITY;
    int has_caustic = 0;
    for (int pass = 0; pass < 2; pass++) {
        pf_photon_maps_t maps;
        pf_photon_stats_t st;
        double t0 = pf_now();
        int rc = pf_photon_pass(frame->scene, frame->accel, frame->lights, &cal, &maps, &st);
        double t = pf_now() - t0;
        if (rc != PF_OK)
            return rc;
        dt = t < dt ? t : dt;
        has_caustic = maps.caustic_emitted > 0;
        pf_photon_maps_free(&maps);
    }
    uint64_t emitted = cal.photons + (has_caustic ? cal.caustic_photons : 0);
    if (!has_caustic)
        s->caustic_photons = 0; /* no specular surface: the pass would skip it anyway */
    if (emitted == 0)
        return PF_OK;
    b->photon_s_per_photon = dt / (double)emitted;
    double n = PF_BUDGET_PHOTON_SHARE * pf_budget_left(b) / b->photon_s_per_photon;
    int maps_n = (s->photons ? 1 : 0) + (s->caustic_photons ? 1 : 0);
    if (maps_n == 0)
        return PF_OK;
    uint64_t each = s_clamp_photons(n / maps_n);
    if (s->photons && !b->fix_photons)
        s->photons = each;
    if (s->caustic_photons && !b->fix_caustic)
        s->caustic_photons = each;
    return PF_OK;
}

/* Blocks of S_PROBE_BLOCK^2 pixels, as the real render meets them
 * (neighbouring pixels share caches, a pixel's samples share its caustic
 * estimate); single scattered samples cost half again as much per sample and
 * made the plan leave a third of the time unused. */
enum { S_PROBE_BLOCK = 8 };

/* Renders the probe's blocks at spp samples per pixel (the settings in base
 * otherwise) and returns the thread-seconds per camera sample, the filtered
 * gathers of a block's border costed as the render's tiles will carry them. */
static double s_probe(pf_budget_t *b, const pf_frame_t *frame, unsigned terms, int local_threads,
                      const pf_settings_t *base, int spp)
{
    pf_settings_t probe = *base;
    probe.spp = spp;
    pf_render_ctx_t ctx;
    pf_render_ctx_init(&ctx, frame, &probe);
    ctx.terms = terms;
    int bx = (base->width + S_PROBE_BLOCK - 1) / S_PROBE_BLOCK, by = (base->height + S_PROBE_BLOCK - 1) / S_PROBE_BLOCK;
    /* A gx x gy lattice of blocks, evenly spaced in both directions, so the
     * probe sees each part of the view in proportion (spacing them in scan
     * order put every block in one or two columns of the image: the left
     * wall alone, and a plan 25 % short of the render's cost). */
    int want = PF_BUDGET_PROBE_PIXELS / (S_PROBE_BLOCK * S_PROBE_BLOCK);
    int gx = (int)lround(sqrt((double)want * (double)bx / (double)by));
    gx = gx < 1 ? 1 : gx > bx ? bx : gx;
    int gy = want / gx;
    gy = gy < 1 ? 1 : gy > by ? by : gy;
    int n = gx * gy;
    if (local_threads < 1)
        local_threads = 1;
    pf_tile_cost_t cost = { 0 };
    double wall0 = pf_now();
#pragma omp parallel num_threads(local_threads)
    {
        pf_accel_thread_init();
        float px[3 * S_PROBE_BLOCK * S_PROBE_BLOCK];
        pf_tile_cost_t mine = { 0 };
#pragma omp for schedule(dynamic, 1)
        for (int i = 0; i < n; i++) {
            int x0 = (int)(((2 * (int64_t)(i % gx) + 1) * bx) / (2 * gx)) * S_PROBE_BLOCK;
            int y0 = (int)(((2 * (int64_t)(i / gx) + 1) * by) / (2 * gy)) * S_PROBE_BLOCK;
            int w = x0 + S_PROBE_BLOCK <= base->width ? S_PROBE_BLOCK : base->width - x0;
            int h = y0 + S_PROBE_BLOCK <= base->height ? S_PROBE_BLOCK : base->height - y0;
            pf_render_tile_cost(&ctx, x0, y0, w, h, px, &mine);
        }
#pragma omp critical
        {
            cost.record_s += mine.record_s;
            cost.render_s += mine.render_s;
            cost.record_samples += mine.record_samples;
            cost.samples += mine.samples;
        }
    }
    /* A probe block's border of filtered gathers is far larger for its size
     * than a tile's: the recording is costed per sample recorded and scaled
     * to the border the render's tiles carry. */
    double r = (double)base->gather_filter, t = (double)(b->tile > 0 ? b->tile : 32);
    double border = cost.record_samples ? (t + 2.0 * r) * (t + 2.0 * r) / (t * t) : 0.0;
    double sample_s = cost.samples ? cost.render_s / (double)cost.samples : 0.0;
    if (cost.record_samples)
        sample_s += border * cost.record_s / (double)cost.record_samples;
    pf_debug("time limit probe at spp %d: %d blocks, %.3f s wall on %d threads; recording %.3f s for %" PRIu64
             " samples, rendering %.3f s for %" PRIu64 " samples: %.2f us per sample",
             spp, n, pf_now() - wall0, local_threads, cost.record_s, cost.record_samples, cost.render_s, cost.samples,
             sample_s * 1e6);
    return sample_s;
}

void pf_budget_plan_spp(pf_budget_t *b, const pf_frame_t *frame, unsigned terms, int local_threads, pf_settings_t *s)
{
    if (b->fix_spp)
        return;
    /* A pixel's cost is p + spp c: some work is done once per pixel whatever
     * its samples (the filter's footprint, caustic estimates its samples
     * share), so the cost per sample falls as spp grows. Probed at 8 samples
     * alone, the plan for spp 23 overestimated the render by 30 % (21.2 s
     * planned, 16.2 s taken, cornell-spheres at 30 s). Two probes, at
     * S_PROBE_LO and S_PROBE_HI, give p and c. */
    enum { S_PROBE_LO = 2, S_PROBE_HI = 8 };
    double e_lo = s_probe(b, frame, terms, local_threads, s, S_PROBE_LO);
    double e_hi = s_probe(b, frame, terms, local_threads, s, S_PROBE_HI);
    double c = (S_PROBE_HI * e_hi - S_PROBE_LO * e_lo) / (S_PROBE_HI - S_PROBE_LO);
    double p = S_PROBE_LO * (e_lo - c);
    if (!(c > 0.0) || !(p >= 0.0)) {
        /* Noise outweighed the difference: the cost per sample at the higher
         * spp, which overestimates any larger one. */
        c = e_hi;
        p = 0.0;
    }
    b->sample_s = c;
    b->pixel_s = p;
    uint64_t npx = (uint64_t)s->width * (uint64_t)s->height;
    double left = pf_budget_left(b) - S_RESERVE_S - S_RESERVE_SHARE * b->limit_s;
    double per_spp = (double)npx * c / (double)b->render_threads;
    double fixed = (double)npx * p / (double)b->render_threads;
    double spp = per_spp > 0.0 ? floor((S_SAFETY * left - fixed) / per_spp) : 1.0;
    if (!(spp >= 1.0)) {
        pf_warn("time limit: even one sample per pixel needs about %.1f s more than the %.1f s left; "
                "rendering with 1",
                fixed + per_spp - left, left > 0.0 ? left : 0.0);
        spp = 1.0;
    }
    if (spp > (double)(1 << 16))
        spp = (double)(1 << 16);
    s->spp = (int)spp;
    b->planned_render_s = fixed + per_spp * spp;
}

double pf_budget_pass_seconds(const pf_budget_t *b, int pass)
{
    double t0 = b->limit_s / 40.0, tmax = b->limit_s / 3.0;
    t0 = t0 < 0.25 ? 0.25 : t0 > 2.0 ? 2.0 : t0;
    tmax = tmax > t0 ? tmax : t0;
    double t = t0;
    for (int i = 0; i < pass && t < tmax; i++)
        t *= 2.0;
    return t < tmax ? t : tmax;
}

double pf_budget_tiles_deadline(const pf_budget_t *b)
{
    return b->deadline - S_RESERVE_S - S_RESERVE_SHARE * b->limit_s;
}

int pf_budget_plan_pass_photons(pf_budget_t *b, int pass, pf_settings_t *s)
{
    double left = pf_budget_tiles_deadline(b) - pf_now();
    double want = pf_budget_pass_seconds(b, pass);
    if (want > left)
        want = left;
    double rate = b->pass_photon_s > 0.0 ? b->pass_photon_s : b->photon_s_per_photon;
    int maps_n = (s->photons ? 1 : 0) + (s->caustic_photons ? 1 : 0);
    uint64_t each = maps_n && rate > 0.0 ? s_clamp_photons(PF_BUDGET_PASS_PHOTON_SHARE * want / rate / maps_n) : 0;
    if (s->photons && !b->fix_photons)
        s->photons = each;
    if (s->caustic_photons && !b->fix_caustic)
        s->caustic_photons = each;
    /* A pass needs its photons and time for some tiles: what does not fit
     * is cut at the deadline, and the tiles done still count (unbiased), so
     * a pass too short to finish beats leaving the time unused. */
    double need = rate * (double)(s->photons + s->caustic_photons) + S_MIN_TILES_S;
    return pass > 0 && need > left;
}

void pf_budget_photons_done(pf_budget_t *b, double photon_s, uint64_t emitted)
{
    if (emitted > 0 && photon_s > 0.0)
        b->pass_photon_s = photon_s / (double)emitted;
}

void pf_budget_plan_pass_spp(pf_budget_t *b, const pf_frame_t *frame, unsigned terms, int local_threads, int pass,
                             double pass_start, pf_settings_t *s)
{
    if (pass == 0 || !(b->pass_spp_s > 0.0)) {
        int fix = b->fix_spp;
        b->fix_spp = 0;
        pf_settings_t probe = *s;
        pf_budget_plan_spp(b, frame, terms, local_threads, &probe);
        b->fix_spp = fix;
        double npx = (double)s->width * (double)s->height;
        b->pass_fixed_s = npx * b->pixel_s / (double)b->render_threads;
        b->pass_spp_s = npx * b->sample_s / (double)b->render_threads;
    }
    if (b->fix_spp)
        return;
    double end = pass_start + pf_budget_pass_seconds(b, pass), hard = pf_budget_tiles_deadline(b);
    /* Within 1.5 passes of the deadline, this pass is the last: it takes
     * what is left, rather than leave a sliver for a pass too short to pay
     * for its photons. */
    int last = end > hard || hard - end < 0.5 * pf_budget_pass_seconds(b, pass + 1);
    if (last)
        end = hard;
    /* The last pass is cut at the deadline if it runs late (only its
     * unfinished tiles are lost), so it may plan closer to it. */
    double safety = last && pass > 0 ? S_LAST_SAFETY : S_SAFETY;
    double spp = b->pass_spp_s > 0.0 ? floor(safety * (end - pf_now() - b->pass_fixed_s) / b->pass_spp_s) : 1.0;
    if (!(spp >= 1.0))
        spp = 1.0;
    if (spp > (double)(1 << 16))
        spp = (double)(1 << 16);
    s->spp = (int)spp;
    b->planned_render_s = b->pass_fixed_s + b->pass_spp_s * spp;
}

void pf_budget_pass_done(pf_budget_t *b, int spp, double render_s)
{
    if (!(spp > 0 && render_s > 0.0))
        return;
    /* The fixed part comes from the probe, and a pass of a few samples is
     * mostly fixed cost (records, texels, the edge pixels' samples): what
     * is left over can be a small difference of two noisy times, and a
     * cost per sample taken from it planned a cornell-box pass of 219 spp
     * after one of 2 (27.5 s of a 30 s limit in one pass). At least half
     * of a pass's time is taken to grow with its samples. */
    double per = (render_s - b->pass_fixed_s) / (double)spp, floor_per = 0.5 * render_s / (double)spp;
    b->pass_spp_s = per > floor_per ? per : floor_per;
}

void pf_budget_log(const pf_budget_t *b, const pf_settings_t *s)
{
    pf_info("time limit %.3g s: %" PRIu64 " global + %" PRIu64 " caustic photons, %d spp x %d gather rays "
            "(%.2f us per photon; per thread %.1f us per pixel + %.1f us per camera sample; render planned at "
            "%.1f s on %d threads, %.1f s left)",
            b->limit_s, s->photons, s->caustic_photons, s->spp, s->gather, b->photon_s_per_photon * 1e6,
            b->pixel_s * 1e6, b->sample_s * 1e6, b->planned_render_s, b->render_threads, pf_budget_left(b));
}
