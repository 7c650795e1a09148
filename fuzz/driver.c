/* driver.c: runs the fuzz targets without libFuzzer, for the regression
 * test fuzz_regress (tests/fuzz/CMakeLists.txt) in the ordinary gcc build and in the
 * sanitizer build. Every file under tests/data/fuzz/<target>/ (the seeds
 * and every crasher the fuzzers found) is fed to that target's
 * LLVMFuzzerTestOneInput, compiled here under the name pf_fuzz_<target>
 * (the build renames the entry point per target, so one program holds all).
 *
 * A crash, an abort from a target's oracle or a sanitizer report ends the
 * program, which fails the test; so does an input that takes longer than
 * S_SLOW_SECONDS (a hang that came back) or a target folder with no inputs.
 *
 *   test_fuzz_regress                  every target, every file
 *   test_fuzz_regress TARGET [FILE...] one target: its folder, or the files given
 *
 * Runs from the repository root (ctest's working directory). One thread. */
#include <dirent.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/stat.h>
#include <time.h>

#include "base/log.h"

/* The fuzzers run with -timeout=10 (seconds); sanitizers slow the same
 * input down about three times, which this limit allows for. */
#define S_SLOW_SECONDS 30.0

typedef int (*s_entry_fn)(const uint8_t *data, size_t size);

int pf_fuzz_json(const uint8_t *data, size_t size);
int pf_fuzz_obj(const uint8_t *data, size_t size);
int pf_fuzz_mtl(const uint8_t *data, size_t size);
int pf_fuzz_ply(const uint8_t *data, size_t size);
int pf_fuzz_pbrt(const uint8_t *data, size_t size);
int pf_fuzz_msg(const uint8_t *data, size_t size);
int pf_fuzz_sceneblob(const uint8_t *data, size_t size);
int pf_fuzz_mapfile(const uint8_t *data, size_t size);
int pf_fuzz_pfm(const uint8_t *data, size_t size);
int pf_fuzz_teximage(const uint8_t *data, size_t size);

static const struct {
    const char *name;
    s_entry_fn fn;
} s_targets[] = {
    { "json", pf_fuzz_json },       { "obj", pf_fuzz_obj },
    { "mtl", pf_fuzz_mtl },         { "ply", pf_fuzz_ply },
    { "pbrt", pf_fuzz_pbrt },
    { "msg", pf_fuzz_msg },         { "sceneblob", pf_fuzz_sceneblob },
    { "mapfile", pf_fuzz_mapfile }, { "pfm", pf_fuzz_pfm },
    { "teximage", pf_fuzz_teximage },
};
#define S_NTARGETS (sizeof s_targets / sizeof s_targets[0])

static int s_passed, s_failed;

static double s_now(void)
{
    struct timespec ts;
    clock_gettime(CLOCK_MONOTONIC, &ts);
    return (double)ts.tv_sec + 1e-9 * (double)ts.tv_nsec;
}

/* Feeds one file to a target. A crash does not return; a slow input or an
 * unreadable file counts as a failure. */
static void s_run_file(const char *target, s_entry_fn fn, const char *path)
{
    FILE *f = fopen(path, "rb");
    if (!f) {
        printf("FAIL %s: cannot open %s\n", target, path);
        s_failed++;
        return;
    }
    size_t cap = 4096, len = 0;
    uint8_t *data = malloc(cap);
    for (;;) {
        if (!data) {
            printf("FAIL %s: out of memory reading %s\n", target, path);
            fclose(f);
            s_failed++;
            return;
        }
        len += fread(data + len, 1, cap - len, f);
        if (len < cap)
            break;
        uint8_t *p = realloc(data, 2 * cap);
        if (!p)
            free(data);
        data = p;
        cap *= 2;
    }
    fclose(f);
    /* An exact-size copy, so that ASan catches a read one past the input. */
    uint8_t *exact = malloc(len ? len : 1);
    if (!exact) {
        free(data);
        printf("FAIL %s: out of memory for %s\n", target, path);
        s_failed++;
        return;
    }
    memcpy(exact, data, len);
    free(data);
    fprintf(stderr, "%s: %s (%zu bytes)\n", target, path, len);
    double t0 = s_now();
    fn(exact, len);
    double dt = s_now() - t0;
    free(exact);
    if (dt > S_SLOW_SECONDS) {
        printf("FAIL %s: %s took %.1f s (limit %.0f s): a hang is back\n", target, path, dt, S_SLOW_SECONDS);
        s_failed++;
        return;
    }
    s_passed++;
}

static int s_cmp(const void *a, const void *b) { return strcmp(*(char *const *)a, *(char *const *)b); }

/* Every regular file of tests/data/fuzz/<target>/, in name order. */
static void s_run_dir(const char *target, s_entry_fn fn)
{
    char dir[512];
    snprintf(dir, sizeof dir, "tests/data/fuzz/%s", target);
    DIR *d = opendir(dir);
    if (!d) {
        printf("FAIL %s: no folder %s (run from the repository root)\n", target, dir);
        s_failed++;
        return;
    }
    char **names = NULL;
    size_t n = 0, cap = 0;
    struct dirent *e;
    while ((e = readdir(d))) {
        if (e->d_name[0] == '.')
            continue;
        if (n == cap) {
            cap = cap ? 2 * cap : 64;
            char **p = realloc(names, cap * sizeof *p);
            if (!p)
                break;
            names = p;
        }
        names[n] = strdup(e->d_name);
        if (names[n])
            n++;
    }
    closedir(d);
    qsort(names, n, sizeof *names, s_cmp);
    size_t ran = 0;
    for (size_t i = 0; i < n; i++) {
        char path[1024];
        struct stat st;
        snprintf(path, sizeof path, "%s/%s", dir, names[i]);
        if (stat(path, &st) == 0 && S_ISREG(st.st_mode)) {
            s_run_file(target, fn, path);
            ran++;
        }
        free(names[i]);
    }
    free(names);
    if (ran == 0) {
        printf("FAIL %s: %s holds no inputs\n", target, dir);
        s_failed++;
    } else {
        printf("ok %s: %zu inputs\n", target, ran);
    }
}

int main(int argc, char **argv)
{
    /* Loaders warn about odd input; the inputs are odd on purpose. */
    if (!getenv("PF_FUZZ_VERBOSE"))
        pf_log_set_level(PF_LOG_QUIET);
    if (argc == 1) {
        for (size_t t = 0; t < S_NTARGETS; t++)
            s_run_dir(s_targets[t].name, s_targets[t].fn);
    } else {
        size_t t = 0;
        while (t < S_NTARGETS && strcmp(s_targets[t].name, argv[1]) != 0)
            t++;
        if (t == S_NTARGETS) {
            fprintf(stderr, "usage: %s [TARGET [FILE...]]; targets:", argv[0]);
            for (t = 0; t < S_NTARGETS; t++)
                fprintf(stderr, " %s", s_targets[t].name);
            fprintf(stderr, "\n");
            return 2;
        }
        if (argc == 2)
            s_run_dir(s_targets[t].name, s_targets[t].fn);
        for (int i = 2; i < argc; i++)
            s_run_file(s_targets[t].name, s_targets[t].fn, argv[i]);
    }
    printf("%d passed, %d failed\n", s_passed, s_failed);
    return s_failed ? 1 : 0;
}
