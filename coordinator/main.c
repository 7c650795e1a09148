/* main.c: the photonfarm command line: `render` (in this process, or through
 * a farm of worker processes with --workers or --bind; see farm.h),
 * `compare` and `keygen`. Exit codes: 0 success, 1 render failure, 2 usage
 * error, 3 unreadable or malformed input, 4 image sizes do not fit
 * (compare), 130 a farm render interrupted by SIGINT or SIGTERM. */
#include <errno.h>
#include <omp.h>
#include <getopt.h>
#include <inttypes.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <unistd.h>

#include "base/keyfile.h"
#include "base/log.h"
#include "coordinator/compare.h"
#include "coordinator/farm.h"
#include "coordinator/job.h"
#include "image/image.h"
#include "load/load.h"
#include "scene/scene.h"
#include "scene/texture.h"

#include <signal.h>
#include <zmq.h>

enum { EXIT_RENDER = 1, EXIT_USAGE = 2, EXIT_INPUT = 3 };

static void s_usage(FILE *f)
{
    fprintf(f,
            "photonfarm %s (%s): a distributed photon-mapping renderer\n"
            "\n"
            "usage:\n"
            "  photonfarm render SCENE [-o out.png] [--hdr out.pfm|out.exr] [options]\n"
            "  photonfarm compare IMAGE.pfm REFERENCE.pfm [--json]\n"
            "  photonfarm keygen NAME        (writes NAME.key, secret, and NAME.pub for CURVE)\n"
            "  photonfarm --help | --version\n"
            "\n"
            "SCENE is a JSON scene (docs/scene-format.md), an .obj model (materials from its\n"
            ".mtl, lights from Ke, a camera that frames it), a .ply or .ply.gz mesh, or a\n"
            "pbrt-v4 scene (.pbrt; what is read and how: docs/pbrt.md).\n"
            "\n"
            "render options (defaults from the scene's \"render\" block, else shown here):\n"
            "  -o, --output FILE        PNG output, 8-bit sRGB (default: <scene name>.png)\n"
            "      --hdr FILE           also write linear float: OpenEXR if FILE ends in .exr, else PFM\n"
            "      --hdr-half           an .exr --hdr file in 16-bit half floats (default 32-bit float)\n"
            "      --size WxH           image size (512x512)\n"
            "      --spp N              camera samples per pixel, stratified when a square (36)\n"
            "      --photons N          global photons emitted (400000)\n"
            "      --caustic-photons N  caustic photons emitted (400000)\n"
            "      --gather N           final-gather rays per camera sample at a diffuse point (1)\n"
            "      --gather-filter R    share first gathers over (2R+1)^2 pixels on the same surface,\n"
            "                           0..8 (2; 0: every sample gathers for itself)\n"
            "      --light-samples N    shadow rays per camera sample at a diffuse point (2)\n"
            "      --global-k N         photons per irradiance estimate (100)\n"
            "      --caustic-k N        photons per caustic estimate (80)\n"
            "      --caustic-radius R   max caustic search radius in world units (0: 1%% of the scene)\n"
            "      --max-depth N        mirror/glass recursion depth (16)\n"
            "      --path-depth N       most scattering events of a light path, pbrt's maxdepth\n"
            "                           (0: no limit, the default; -1: emitted light only)\n"
            "      --threads N          rendering threads (0: all cores)\n"
            "      --seed N             random seed (1); the image depends on nothing else\n"
            "      --exposure STOPS     PNG exposure in stops (0)\n"
            "      --pixel-filter F     box (each pixel its own square), tent:R (pbrt's triangle\n"
            "                           filter of radius R pixels) or box+tent:R (box)\n"
            "      --quality PRESET     draft, default or high: spp and photons from the\n"
            "                           benchmark curves (docs/benchmarks.md); other options override\n"
            "      --passes N           progressive: N independent passes, each with --spp samples per\n"
            "                           pixel and --photons photons of its own, photon radii shrinking\n"
            "                           from pass to pass; the image is their mean (1)\n"
            "      --time-limit SECONDS progressive passes until SECONDS of wall clock (everything\n"
            "                           included): each pass's photons and spp chosen by measuring this\n"
            "                           machine (or farm); given --spp/--photons are kept per pass.\n"
            "                           Ctrl-C writes the image of the passes done\n"
            "      --no-adaptive        progressive passes all uniform; by default passes after the\n"
            "                           first put their samples where the passes so far see noise\n"
            "      --terms LIST         render only these terms: emitted,direct,caustic,indirect (all);\n"
            "                           photonmap shows the global map's radiance (debugging)\n"
            "      --strict             a .pbrt scene that asks for anything approximated or ignored\n"
            "                           is an error (exit 3) instead of a warning\n"
            "\n"
            "render farm (docs/cluster.md):\n"
            "      --workers N          start N local worker processes (0: render in this process)\n"
            "      --threads T          with --workers: threads per worker (default: cores / N)\n"
            "      --bind ENDPOINT      listen for workers there, e.g. tcp://*:7878 (default: loopback only)\n"
            "      --min-workers K      lease no tile before K workers are ready (1)\n"
            "      --curve-secret FILE  encrypt with CURVE: this coordinator's key file (photonfarm keygen)\n"
            "      --curve-allow FILE   the public keys of the workers admitted, one per line\n"
            "      --tile N             tile size in pixels (32)\n"
            "      --heartbeat-ms MS    heartbeat interval (1000); a worker silent for 4 is dead\n"
            "      --watchdog S         a worker holding tiles that returns no RESULT for S seconds is stuck (30)\n"
            "      --lease-timeout S    a tile not returned S seconds after its lease goes to another worker (120)\n"
            "      --max-strikes N      evict a worker after N offences: malformed, out-of-turn or refused\n"
            "                           messages, expired leases, stalls (8; 0: never)\n"
            "      --fanout N           workers relay the photon maps to each other, each to at most N\n"
            "                           (2; 0: every worker fetches them from the coordinator)\n"
            "      --verify FRACTION    render this fraction of the tiles again on a second worker and compare\n"
            "                           bit for bit, besides each worker's first tile; a worker caught\n"
            "                           returning wrong pixels is evicted and its tiles rendered again\n"
            "                           (0.02; 0: no checks)\n"
            "      --max-wait S         give up when no worker is connected for S seconds (0: never)\n"
            "      --checkpoint FILE    keep the render's progress there (farm: after each pass and every\n"
            "                           5 s of tiles; in process: after each progressive pass), removed\n"
            "                           when it ends well (OUTPUT.ckpt; none: no file)\n"
            "      --resume             go on from the checkpoint after a crash: the same image, bit for\n"
            "                           bit, as an uninterrupted render (none there: start afresh)\n"
            "      --worker-exe PATH    the worker program for --workers (default: beside photonfarm)\n"
            "\n"
            "  -q, --quiet              only errors\n"
            "  -v, --verbose            debug logging\n"
            "\n"
            "exit codes: 0 done, 1 render failure, 2 usage error, 3 unreadable or malformed input,\n"
            "4 image sizes do not fit (compare), 130 interrupted (SIGINT), 143 stopped (SIGTERM)\n",
            PF_VERSION, PF_GIT_HASH);
}

static int s_parse_u64(const char *s, uint64_t *out)
{
    char *end;
    errno = 0;
    if (s[0] < '0' || s[0] > '9')
        return -1; /* strtoull would skip spaces and wrap "-1" around */
    unsigned long long v = strtoull(s, &end, 10);
    if (errno || end == s || *end)
        return -1;
    *out = v;
    return 0;
}

static int s_parse_int(const char *s, int lo, int hi, int *out)
{
    char *end;
    errno = 0;
    long v = strtol(s, &end, 10);
    if (errno || end == s || *end || v < lo || v > hi)
        return -1;
    *out = (int)v;
    return 0;
}

static int s_parse_float(const char *s, float *out)
{
    char *end;
    errno = 0;
    float v = strtof(s, &end);
    if (errno || end == s || *end || !isfinite(v))
        return -1;
    *out = v;
    return 0;
}

/* --quality presets, from the time-against-error measurements of the
 * shipped scenes at 512x512 on 2 cores (docs/benchmarks.md): draft is about
 * what --time-limit 10 chooses there, default is the renderer's defaults,
 * high four times the camera samples and 2.5 times the photons. All take one
 * filtered gather ray and two shadow rays per camera sample, which beat more
 * gather rays per sample at equal time. Options given beside a preset
 * override its values. */
typedef struct pf_quality {
    const char *name;
    int spp, gather, light_samples, gather_filter;
    uint64_t photons, caustic_photons;
} pf_quality_t;

static const pf_quality_t s_qualities[] = {
    { "draft", 12, 1, 2, 2, 200000, 200000 },
    { "default", 36, 1, 2, 2, 400000, 400000 },
    { "high", 144, 1, 2, 2, 1000000, 1000000 },
};

static const pf_quality_t *s_find_quality(const char *name)
{
    for (size_t i = 0; i < sizeof s_qualities / sizeof *s_qualities; i++)
        if (!strcmp(name, s_qualities[i].name))
            return &s_qualities[i];
    return NULL;
}

static int s_parse_terms(const char *s, unsigned *out)
{
    unsigned t = 0;
    char buf[256];
    snprintf(buf, sizeof buf, "%s", s);
    for (char *save, *tok = strtok_r(buf, ",", &save); tok; tok = strtok_r(NULL, ",", &save)) {
        if (!strcmp(tok, "emitted"))
            t |= PF_TERM_EMITTED;
        else if (!strcmp(tok, "direct"))
            t |= PF_TERM_DIRECT;
        else if (!strcmp(tok, "caustic"))
            t |= PF_TERM_CAUSTIC;
        else if (!strcmp(tok, "indirect"))
            t |= PF_TERM_INDIRECT;
        else if (!strcmp(tok, "photonmap"))
            t |= PF_TERM_PHOTONMAP;
        else if (!strcmp(tok, "all"))
            t |= PF_TERM_ALL;
        else
            return -1;
    }
    *out = t;
    return t ? 0 : -1;
}

/* Default output name: the scene file's stem, or its folder's name for scene.json. */
static void s_default_output(const char *scene, char *out, size_t n)
{
    char tmp[1024];
    snprintf(tmp, sizeof tmp, "%s", scene);
    char *slash = strrchr(tmp, '/');
    char *base = slash ? slash + 1 : tmp;
    char *dot = strrchr(base, '.');
    if (dot)
        *dot = 0;
    if (!strcmp(base, "scene") && slash) {
        *slash = 0;
        char *p = strrchr(tmp, '/');
        base = p ? p + 1 : tmp;
    }
    snprintf(out, n, "%.1000s.png", base[0] ? base : "render");
}

enum {
    OPT_HDR = 256, OPT_SIZE, OPT_SPP, OPT_PHOTONS, OPT_CPHOTONS, OPT_GATHER, OPT_GFILTER, OPT_LSAMPLES, OPT_GK, OPT_CK, OPT_CR,
    OPT_DEPTH, OPT_PDEPTH, OPT_THREADS, OPT_SEED, OPT_EXPOSURE, OPT_PFILTER, OPT_TERMS, OPT_WORKERS, OPT_BIND, OPT_MINW, OPT_CSECRET,
    OPT_CALLOW, OPT_TILE, OPT_HB, OPT_WATCHDOG, OPT_MAXWAIT, OPT_WEXE, OPT_TLIMIT, OPT_QUALITY, OPT_STRICT,
    OPT_LEASE, OPT_STRIKES, OPT_FANOUT, OPT_VERIFY, OPT_PASSES, OPT_CKPT, OPT_RESUME, OPT_NOADAPT, OPT_HDRHALF,
};

/* SIGINT and SIGTERM. The farm's event loop and the progressive passes poll
 * s_interrupted (the signal's number) and stop: progressive passes write
 * the image of the passes done. The command then exits 128 + that number,
 * as a shell reports a process a signal killed (130, 143). A one-pass
 * render in this process has nothing whole to write before its end: there
 * the handler says so on stderr and exits at once with that code (the
 * image files are written to a temporary name and renamed, so a
 * half-written output never takes the real name). */
static volatile int s_interrupted; /* int: pf_farm_render's stop flag (written whole by the handler) */
static void s_on_signal(int sig)
{
    s_interrupted = sig;
}

static void s_on_signal_exit(int sig)
{
    static const char msg[] = "photonfarm: interrupted\n";
    ssize_t w = write(2, msg, sizeof msg - 1);
    (void)w;
    _exit(128 + sig);
}

static void s_catch_signals(void (*handler)(int))
{
    /* With a handler that only sets the flag, a photon pass under way
     * stops too (within a block of photons). */
    pf_photon_set_cancel(handler == s_on_signal ? &s_interrupted : NULL);
    struct sigaction sa;
    memset(&sa, 0, sizeof sa);
    sa.sa_handler = handler;
    sigaction(SIGINT, &sa, NULL);
    sigaction(SIGTERM, &sa, NULL);
}

static const struct option s_render_opts[] = {
    { "output", required_argument, 0, 'o' },        { "hdr", required_argument, 0, OPT_HDR },
    { "size", required_argument, 0, OPT_SIZE },      { "spp", required_argument, 0, OPT_SPP },
    { "photons", required_argument, 0, OPT_PHOTONS }, { "caustic-photons", required_argument, 0, OPT_CPHOTONS },
    { "gather", required_argument, 0, OPT_GATHER },  { "light-samples", required_argument, 0, OPT_LSAMPLES },
    { "gather-filter", required_argument, 0, OPT_GFILTER },
    { "global-k", required_argument, 0, OPT_GK },    { "caustic-k", required_argument, 0, OPT_CK },
    { "caustic-radius", required_argument, 0, OPT_CR }, { "max-depth", required_argument, 0, OPT_DEPTH },
    { "path-depth", required_argument, 0, OPT_PDEPTH },
    { "threads", required_argument, 0, OPT_THREADS }, { "seed", required_argument, 0, OPT_SEED },
    { "exposure", required_argument, 0, OPT_EXPOSURE }, { "terms", required_argument, 0, OPT_TERMS },
    { "pixel-filter", required_argument, 0, OPT_PFILTER },
    { "quiet", no_argument, 0, 'q' },                { "verbose", no_argument, 0, 'v' },
    { "help", no_argument, 0, 'h' },                 { "workers", required_argument, 0, OPT_WORKERS },
    { "bind", required_argument, 0, OPT_BIND },      { "min-workers", required_argument, 0, OPT_MINW },
    { "curve-secret", required_argument, 0, OPT_CSECRET }, { "curve-allow", required_argument, 0, OPT_CALLOW },
    { "tile", required_argument, 0, OPT_TILE },      { "heartbeat-ms", required_argument, 0, OPT_HB },
    { "watchdog", required_argument, 0, OPT_WATCHDOG }, { "max-wait", required_argument, 0, OPT_MAXWAIT },
    { "worker-exe", required_argument, 0, OPT_WEXE }, { "time-limit", required_argument, 0, OPT_TLIMIT },
    { "quality", required_argument, 0, OPT_QUALITY }, { "strict", no_argument, 0, OPT_STRICT },
    { "lease-timeout", required_argument, 0, OPT_LEASE }, { "max-strikes", required_argument, 0, OPT_STRIKES },
    { "fanout", required_argument, 0, OPT_FANOUT },
    { "verify", required_argument, 0, OPT_VERIFY }, { "passes", required_argument, 0, OPT_PASSES },
    { "checkpoint", required_argument, 0, OPT_CKPT }, { "resume", no_argument, 0, OPT_RESUME },
    { "no-adaptive", no_argument, 0, OPT_NOADAPT }, { "hdr-half", no_argument, 0, OPT_HDRHALF },
    { 0, 0, 0, 0 },
};

/* Command-line settings are applied over the scene's after it loads; has_x
 * says x was given. */
typedef struct s_cli_settings {
    int w, h, spp, gather, gfilter, ls, gk, ck, depth, pdepth, threads;
    uint64_t photons, cphotons, seed;
    float cr, exposure, fbox, ftent;
    int has_filter, has_pdepth;
    int has_w, has_spp, has_gather, has_gfilter, has_ls, has_gk, has_ck, has_depth, has_threads, has_photons, has_cphotons,
        has_seed, has_cr, has_exposure;
} s_cli_settings;

/* Everything `photonfarm render` was told. */
typedef struct s_render_args {
    s_cli_settings o;
    const char *path, *out, *hdr;
    int hdr_half; /* --hdr-half: an .exr --hdr file in 16-bit half floats */
    char outbuf[1024]; /* the default output name, when -o is not given */
    unsigned terms;
    pf_farm_opts_t farm;
    int workers;
    float time_limit;
    int passes; /* --passes: progressive passes (0: one, or as many as a time limit allows) */
    const char *checkpoint; /* --checkpoint (farm renders; NULL: OUTPUT.ckpt; "none": none) */
    char ckptbuf[1100];
    const pf_quality_t *quality;
    int strict; /* --strict: loader warnings are errors */
    int no_adaptive; /* --no-adaptive: every progressive pass uniform */
} s_render_args;

/* The long name of the render option whose getopt value is c, for an error
 * message. */
static const char *s_render_opt_name(int c)
{
    const char *name = "?";
    for (const struct option *op = s_render_opts; op->name; op++)
        if (op->val == c)
            name = op->name;
    return name;
}

/* Parses the render command's options and its SCENE argument into *a.
 * Returns -1 to go on with the render, else the exit code (0 for --help). */
static int s_parse_render_args(int argc, char **argv, s_render_args *a)
{
    memset(a, 0, sizeof *a);
    s_cli_settings *o = &a->o;
    pf_farm_opts_t *farm = &a->farm;
    a->terms = PF_TERM_ALL;
    pf_farm_opts_default(farm);
    float fval = 0;
    int c;
    optind = 1;
    opterr = 0;
    while ((c = getopt_long(argc, argv, ":o:qvh", s_render_opts, NULL)) != -1) {
        int bad = 0;
        switch (c) {
        case 'o': a->out = optarg; break;
        case OPT_HDR: a->hdr = optarg; break;
        case OPT_SIZE:
            {
                char tail = 0;
                bad = sscanf(optarg, "%dx%d%c", &o->w, &o->h, &tail) != 2 || o->w <= 0 || o->h <= 0 || o->w > 65536 ||
                      o->h > 65536;
            }
            o->has_w = 1;
            break;
        case OPT_SPP: bad = s_parse_int(optarg, 1, 1 << 20, &o->spp); o->has_spp = 1; break;
        case OPT_PHOTONS: bad = s_parse_u64(optarg, &o->photons) || o->photons > (1ull << 31); o->has_photons = 1; break;
        case OPT_CPHOTONS: bad = s_parse_u64(optarg, &o->cphotons) || o->cphotons > (1ull << 31); o->has_cphotons = 1; break;
        case OPT_GATHER: bad = s_parse_int(optarg, 0, 1 << 16, &o->gather); o->has_gather = 1; break;
        case OPT_GFILTER:
            bad = s_parse_int(optarg, 0, PF_MAX_GATHER_FILTER, &o->gfilter);
            o->has_gfilter = 1;
            break;
        case OPT_LSAMPLES: bad = s_parse_int(optarg, 1, 1 << 10, &o->ls); o->has_ls = 1; break;
        case OPT_GK: bad = s_parse_int(optarg, 1, 1024, &o->gk); o->has_gk = 1; break;
        case OPT_CK: bad = s_parse_int(optarg, 1, 1024, &o->ck); o->has_ck = 1; break;
        case OPT_CR: bad = s_parse_float(optarg, &o->cr) || o->cr < 0; o->has_cr = 1; break;
        case OPT_DEPTH: bad = s_parse_int(optarg, 0, 1000, &o->depth); o->has_depth = 1; break;
        case OPT_PDEPTH: bad = s_parse_int(optarg, -1, 1000, &o->pdepth); o->has_pdepth = 1; break;
        case OPT_THREADS: bad = s_parse_int(optarg, 0, 4096, &o->threads); o->has_threads = 1; break;
        case OPT_SEED: bad = s_parse_u64(optarg, &o->seed); o->has_seed = 1; break;
        case OPT_EXPOSURE: bad = s_parse_float(optarg, &o->exposure); o->has_exposure = 1; break;
        case OPT_PFILTER: bad = pf_pixel_filter_parse(optarg, &o->fbox, &o->ftent) != 0; o->has_filter = 1; break;
        case OPT_TERMS: bad = s_parse_terms(optarg, &a->terms); break;
        case OPT_WORKERS: bad = s_parse_int(optarg, 0, 256, &a->workers); break;
        case OPT_BIND: farm->bind = optarg; break;
        case OPT_MINW: bad = s_parse_int(optarg, 1, 1024, &farm->min_workers); break;
        case OPT_CSECRET: farm->curve_secret = optarg; break;
        case OPT_CALLOW: farm->curve_allow = optarg; break;
        case OPT_TILE: bad = s_parse_int(optarg, 1, 256, &farm->tile_size); break;
        case OPT_HB: bad = s_parse_int(optarg, 10, 60000, &farm->heartbeat_ms); break;
        case OPT_WATCHDOG: bad = s_parse_float(optarg, &fval) || fval <= 0; farm->watchdog_s = fval; break;
        case OPT_MAXWAIT: bad = s_parse_float(optarg, &fval) || fval < 0; farm->max_wait_s = fval; break;
        case OPT_LEASE: bad = s_parse_float(optarg, &fval) || fval <= 0 || fval > 1e6; farm->lease_timeout_s = fval; break;
        case OPT_STRIKES: bad = s_parse_int(optarg, 0, 1000000, &farm->max_strikes); break;
        case OPT_FANOUT: bad = s_parse_int(optarg, 0, 64, &farm->fanout); break;
        case OPT_VERIFY: bad = s_parse_float(optarg, &fval) || fval < 0 || fval > 1; farm->verify = fval; break;
        case OPT_WEXE: farm->worker_exe = optarg; break;
        case OPT_TLIMIT: bad = s_parse_float(optarg, &a->time_limit) || a->time_limit <= 0 || a->time_limit > 1e7; break;
        case OPT_PASSES: bad = s_parse_int(optarg, 1, PF_MAX_PASSES, &a->passes); break;
        case OPT_CKPT: a->checkpoint = optarg; break;
        case OPT_RESUME: farm->resume = 1; break;
        case OPT_NOADAPT: a->no_adaptive = 1; break;
        case OPT_HDRHALF: a->hdr_half = 1; break;
        case OPT_QUALITY: bad = (a->quality = s_find_quality(optarg)) == NULL; break;
        case OPT_STRICT: a->strict = 1; break;
        case 'q': pf_log_set_level(PF_LOG_ERROR); break;
        case 'v': pf_log_set_level(PF_LOG_DEBUG); break;
        case 'h': s_usage(stdout); return 0;
        case ':':
            fprintf(stderr, "photonfarm render: option '%s' needs a value (see 'photonfarm --help')\n", argv[optind - 1]);
            return EXIT_USAGE;
        default:
            fprintf(stderr, "photonfarm render: unknown option '%s' (see 'photonfarm --help')\n", argv[optind - 1]);
            return EXIT_USAGE;
        }
        if (bad) {
            fprintf(stderr, "photonfarm render: bad value '%s' for --%s (see 'photonfarm --help')\n", optarg,
                    s_render_opt_name(c));
            return EXIT_USAGE;
        }
    }
    if (optind != argc - 1) {
        fprintf(stderr, "photonfarm render: expected one SCENE argument (see 'photonfarm --help')\n");
        return EXIT_USAGE;
    }
    a->path = argv[optind];
    if (farm->resume && a->workers == 0 && !farm->bind && a->passes <= 1 && !(a->time_limit > 0)) {
        fprintf(stderr, "photonfarm render: --resume continues a farm render (--workers N or --bind) or progressive "
                        "passes (--passes, --time-limit); a one-pass render in this process keeps no checkpoint\n");
        return EXIT_USAGE;
    }
    if (!a->out) {
        s_default_output(a->path, a->outbuf, sizeof a->outbuf);
        a->out = a->outbuf;
    }
    return -1;
}

/* The settings to render with: the scene's, then a --quality preset, then
 * the budget's sampling choices under a time limit, then each option given. */
static pf_settings_t s_render_settings(const pf_scene_t *scene, const s_render_args *a)
{
    const s_cli_settings *o = &a->o;
    const pf_quality_t *quality = a->quality;
    pf_settings_t s = scene->settings;
    if (quality) {
        s.spp = quality->spp;
        s.gather = quality->gather;
        s.light_samples = quality->light_samples;
        s.gather_filter = quality->gather_filter;
        s.photons = quality->photons;
        s.caustic_photons = quality->caustic_photons;
    }
    if (a->time_limit > 0) {
        if (!o->has_gather) s.gather = PF_BUDGET_GATHER;
        if (!o->has_ls) s.light_samples = PF_BUDGET_LIGHT_SAMPLES;
        if (!o->has_gfilter) s.gather_filter = PF_BUDGET_GATHER_FILTER;
    }
    if (o->has_w) { s.width = o->w; s.height = o->h; }
    if (o->has_spp) s.spp = o->spp;
    if (o->has_photons) s.photons = o->photons;
    if (o->has_cphotons) s.caustic_photons = o->cphotons;
    if (o->has_gather) s.gather = o->gather;
    if (o->has_ls) s.light_samples = o->ls;
    if (o->has_gfilter) s.gather_filter = o->gfilter;
    if (o->has_gk) s.global_k = o->gk;
    if (o->has_ck) s.caustic_k = o->ck;
    if (o->has_cr) s.caustic_radius = o->cr;
    if (o->has_depth) s.max_depth = o->depth;
    if (o->has_pdepth) s.path_max_depth = o->pdepth;
    if (o->has_threads) s.threads = o->threads;
    if (o->has_seed) s.seed = o->seed;
    if (o->has_exposure) s.exposure = o->exposure;
    if (o->has_filter) s.filter_box = o->fbox, s.filter_tent = o->ftent;
    return s;
}

/* Logs the scene and the settings; under a time limit, sets up *budget for
 * the threads that will render (all workers together) first. */
static void s_plan(const pf_scene_t *scene, const s_render_args *a, const pf_settings_t *s, double t0,
                   pf_budget_t *budget)
{
    const s_cli_settings *o = &a->o;
    int workers = a->workers;
    float time_limit = a->time_limit;
    size_t ntris = 0;
    for (size_t i = 0; i < scene->nmeshes; i++)
        ntris += scene->meshes[i].ntris;
    pf_info("scene %s: %zu triangles, %zu spheres, %zu materials, %zu point, spot, sun or sky lights, %zu textures "
            "(%.1f MB of pixels) (%.2f s to load)",
            a->path, ntris, scene->nspheres, scene->nmats, scene->nlights, scene->ntexs,
            (double)pf_textures_bytes(scene) / (1024.0 * 1024.0), pf_now() - t0);
    if (time_limit > 0) {
        int render_threads;
        if (workers > 0)
            render_threads = workers * (o->has_threads && o->threads > 0 ? o->threads
                                        : omp_get_num_procs() / workers > 0 ? omp_get_num_procs() / workers : 1);
        else if (a->farm.bind)
            render_threads = a->farm.min_workers * omp_get_num_procs(); /* assumed: remote workers like this machine */
        else
            render_threads = o->has_threads && o->threads > 0 ? o->threads : omp_get_num_procs();
        pf_budget_init(budget, t0, time_limit, render_threads, workers > 0 || a->farm.bind ? a->farm.tile_size : 32);
        budget->fix_photons = o->has_photons;
        budget->fix_caustic = o->has_cphotons;
        budget->fix_spp = o->has_spp;
        pf_info("settings: %dx%d, time limit %.3g s (passes until then, photons and spp chosen below), %d gather rays (filter %d), "
                "%d light samples, seed %" PRIu64,
                s->width, s->height, time_limit, s->gather, s->gather_filter, s->light_samples, s->seed);
    } else {
        pf_info("settings: %dx%d, %d spp, %" PRIu64 " global + %" PRIu64
                " caustic photons, %d gather rays (filter %d), %d light samples, seed %" PRIu64 "%s%s",
                s->width, s->height, s->spp, s->photons, s->caustic_photons, s->gather, s->gather_filter, s->light_samples,
                s->seed, a->quality ? ", quality " : "", a->quality ? a->quality->name : "");
    }
}

/* The exit code of a render a signal stopped: 128 + its number, as a
 * shell reports it (130, 143). */
static int s_signal_code(void) { return 128 + (s_interrupted ? (int)s_interrupted : SIGINT); }

/* The exit code of a failed render: a signal's, 3 for a checkpoint of
 * another render or a malformed one, else 1. */
static int s_failure_code(int rc)
{
    if (rc == PF_EINTERRUPTED)
        return s_signal_code();
    return rc == PF_EMISMATCH || rc == PF_EPARSE ? EXIT_INPUT : EXIT_RENDER;
}

/* Where the render keeps its checkpoint: --checkpoint, or OUTPUT.ckpt; NULL
 * for --checkpoint none. */
static const char *s_checkpoint_path(s_render_args *a)
{
    if (!a->checkpoint) {
        snprintf(a->ckptbuf, sizeof a->ckptbuf, "%s.ckpt", a->out);
        return a->ckptbuf;
    }
    return strcmp(a->checkpoint, "none") ? a->checkpoint : NULL;
}

/* The farm: --threads is per local worker; the photon pass uses every core
 * here. Takes *scene_p. Returns 0, or the exit code of a failed render. */
static int s_render_farm(pf_scene_t **scene_p, s_render_args *a, pf_budget_t *budget, pf_settings_t *s,
                         pf_image_t *img, pf_job_summary_t *sum, pf_error_t *err)
{
    pf_farm_opts_t *farm = &a->farm;
    farm->local_workers = a->workers;
    farm->worker_threads = a->o.has_threads ? a->o.threads : 0;
    farm->show_progress = 1;
    farm->budget = a->time_limit > 0 ? budget : NULL;
    farm->passes = a->passes;
    farm->adaptive = !a->no_adaptive;
    farm->checkpoint = s_checkpoint_path(a);
    s->threads = 0;
    s_catch_signals(s_on_signal);
    signal(SIGPIPE, SIG_IGN);
    pf_farm_summary_t fs;
    int rc = pf_farm_render(*scene_p, s, a->terms, farm, &s_interrupted, img, &fs, err);
    pf_scene_destroy(scene_p);
    if (rc != PF_OK) {
        pf_error("render failed: %s", err->msg);
        return s_failure_code(rc);
    }
    pf_farm_summary_log(&fs);
    sum->bad_pixels = fs.bad_pixels;
    sum->threads = s->threads;
    sum->accel_s = 0;
    sum->photons = fs.photons;
    sum->render_s = fs.render_s;
    sum->photon_s = fs.photon_total_s;
    sum->passes = fs.passes;
    sum->passes_whole = fs.passes_whole;
    sum->cut_tiles = fs.cut_tiles;
    sum->cut_total = fs.cut_total;
    sum->spp_total = fs.spp_total;
    sum->photons_total = fs.photons_total;
    sum->error_est = fs.error_est;
    sum->interrupted = fs.interrupted;
    sum->unreached = fs.unreached;
    return 0;
}

/* The render in this process. Takes *scene_p. Returns 0, or the exit code
 * of a failed render. */
static int s_render_here(pf_scene_t **scene_p, s_render_args *a, pf_budget_t *budget, const pf_settings_t *s,
                         pf_image_t *img, pf_job_summary_t *sum, pf_error_t *err)
{
    /* Progressive passes stop at the next tile and write what they have;
     * one pass has nothing whole to write before its end. */
    int progressive = a->time_limit > 0 || a->passes > 1;
    s_catch_signals(progressive ? s_on_signal : s_on_signal_exit);
    pf_job_run_t run = { .show_progress = 1, .budget = a->time_limit > 0 ? budget : NULL, .passes = a->passes,
                         .stop = &s_interrupted, .checkpoint = progressive ? s_checkpoint_path(a) : NULL,
                         .resume = a->farm.resume, .adaptive = !a->no_adaptive };
    int rc = pf_job_render(*scene_p, s, a->terms, &run, img, sum, err);
    pf_scene_destroy(scene_p);
    if (rc != PF_OK) {
        pf_error("render failed: %s", err->msg);
        return s_failure_code(rc);
    }
    return 0;
}

/* Warns about bad samples, writes the PNG (and the PFM or EXR with --hdr), frees
 * *img and logs the times. Returns the command's exit code. */
static int s_write_output(const s_render_args *a, const pf_settings_t *s, pf_image_t *img,
                          const pf_job_summary_t *sum, double t0, pf_error_t *err)
{
    const char *out = a->out, *hdr = a->hdr;
    float time_limit = a->time_limit;
    if (sum->bad_pixels)
        pf_warn("%zu image channels were non-finite or negative", sum->bad_pixels);
    if (sum->dropped_samples)
        pf_warn("%" PRIu64 " camera samples were non-finite or negative and left out of their pixels",
                sum->dropped_samples);
    int rc = pf_image_write_png(img, out, s->exposure, err);
    if (rc == PF_OK && hdr)
        rc = pf_image_write_hdr(img, hdr, a->hdr_half, err);
    pf_image_free(img);
    if (rc != PF_OK) {
        pf_error("%s", err->msg);
        return EXIT_RENDER;
    }
    double total = pf_now() - t0;
    if (sum->passes > 1 || a->passes > 1 || time_limit > 0) {
        char cut[96] = "";
        if (sum->cut_total)
            snprintf(cut, sizeof cut, " + %d of %d tiles of pass %d", sum->cut_tiles, sum->cut_total, sum->passes);
        pf_info("passes: %d whole%s, %" PRIu64 " samples per pixel and %" PRIu64 " photons in all, est. relMSE %.2g%s",
                sum->passes_whole, cut, sum->spp_total, sum->photons_total, sum->error_est,
                sum->interrupted ? " (interrupted)" : "");
    }
    pf_info("done in %.2f s: photons %.2f s, render %.2f s -> %s%s%s", total,
            sum->photon_s > 0 ? sum->photon_s
                              : sum->photons.trace_s + sum->photons.build_s + sum->photons.irradiance_s,
            sum->render_s, out, hdr ? ", " : "", hdr ? hdr : "");
    if (time_limit > 0 && total > time_limit)
        pf_warn("the time limit of %.3g s was overrun by %.2f s", time_limit, total - time_limit);
    return 0;
}

static int s_cmd_render(int argc, char **argv)
{
    s_render_args a;
    int code = s_parse_render_args(argc, argv, &a);
    if (code >= 0)
        return code;

    double t0 = pf_now();
    pf_error_t err = { { 0 } };
    pf_scene_t *scene = pf_scene_load_opts(a.path, &(pf_load_opts_t){ .strict = a.strict }, &err);
    if (!scene) {
        pf_error("%s", err.msg);
        return EXIT_INPUT;
    }
    pf_settings_t s = s_render_settings(scene, &a);
    pf_budget_t budget;
    s_plan(scene, &a, &s, t0, &budget);

    pf_image_t img = { 0 };
    pf_job_summary_t sum;
    memset(&sum, 0, sizeof sum);
    if (a.workers > 0 || a.farm.bind)
        code = s_render_farm(&scene, &a, &budget, &s, &img, &sum, &err);
    else
        code = s_render_here(&scene, &a, &budget, &s, &img, &sum, &err);
    if (code != 0)
        return code;
    code = s_write_output(&a, &s, &img, &sum, t0, &err);
    if (code == 0 && sum.interrupted)
        code = s_signal_code();
    return code;
}

/* photonfarm keygen NAME: a CURVE key pair in NAME.key (secret, mode 0600)
 * and the public half in NAME.pub. */
static int s_cmd_keygen(int argc, char **argv)
{
    if (argc != 2 || argv[1][0] == '-') {
        fprintf(argc == 2 ? stdout : stderr, "usage: photonfarm keygen NAME   (writes NAME.key and NAME.pub)\n");
        return argc == 2 && (!strcmp(argv[1], "--help") || !strcmp(argv[1], "-h")) ? 0 : EXIT_USAGE;
    }
    char pub[41], sec[41], path[4096];
    if (zmq_curve_keypair(pub, sec) != 0) {
        fprintf(stderr, "photonfarm keygen: this libzmq has no CURVE support: %s\n", zmq_strerror(zmq_errno()));
        return EXIT_RENDER;
    }
    pf_error_t err = { { 0 } };
    snprintf(path, sizeof path, "%s.key", argv[1]);
    if (pf_keyfile_write(path, pub, sec, &err) != PF_OK) {
        fprintf(stderr, "photonfarm keygen: %s\n", err.msg);
        return EXIT_RENDER;
    }
    printf("wrote %s (keep it secret)\n", path);
    snprintf(path, sizeof path, "%s.pub", argv[1]);
    if (pf_keyfile_write(path, pub, NULL, &err) != PF_OK) {
        fprintf(stderr, "photonfarm keygen: %s\n", err.msg);
        return EXIT_RENDER;
    }
    printf("wrote %s\npublic key: %s\n", path, pub);
    return 0;
}

int main(int argc, char **argv)
{
    if (argc < 2) {
        s_usage(stderr);
        return EXIT_USAGE;
    }
    const char *cmd = argv[1];
    if (!strcmp(cmd, "--help") || !strcmp(cmd, "-h") || !strcmp(cmd, "help")) {
        s_usage(stdout);
        return 0;
    }
    if (!strcmp(cmd, "--version")) {
        printf("photonfarm %s (%s)\n", PF_VERSION, PF_GIT_HASH);
        return 0;
    }
    if (!strcmp(cmd, "render"))
        return s_cmd_render(argc - 1, argv + 1);
    if (!strcmp(cmd, "compare"))
        return pf_cli_compare(argc - 1, argv + 1);
    if (!strcmp(cmd, "keygen"))
        return s_cmd_keygen(argc - 1, argv + 1);
    fprintf(stderr, "photonfarm: unknown command '%s' (see 'photonfarm --help')\n", cmd);
    return EXIT_USAGE;
}
