/* fuzz_util.h: what the fuzz targets share. The scene loaders read from a
 * path, so a target writes each input to a file in a per-process folder
 * under /dev/shm (memory, no disk wear), next to any helper files the input
 * may refer to (an OBJ's mtllib, a JSON scene's models); the folder is
 * removed at exit. Every function is static: each target (and the regression
 * driver, which links all of them into one program) gets its own copy.
 *
 * Oracles: a target aborts (PF_FUZZ_REQUIRE) when an accepted input breaks
 * a property the rest of the program relies on, e.g. a message that decodes
 * but does not encode back to the same bytes. libFuzzer and the regression
 * driver both report an abort as a crash. */
#ifndef PF_FUZZ_UTIL_H
#define PF_FUZZ_UTIL_H

#include <stddef.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/stat.h>
#include <unistd.h>

#include "base/log.h"
#include "load/load.h"
#include "proto/sceneblob.h"
#include "scene/scene.h"

/* Aborts with a message when an oracle fails: a finding, like a crash. */
#define PF_FUZZ_REQUIRE(cond, ...)                                                 \
    do {                                                                           \
        if (!(cond)) {                                                             \
            fprintf(stderr, "fuzz oracle failed at %s:%d: %s: ", __FILE__, __LINE__, #cond); \
            fprintf(stderr, __VA_ARGS__);                                          \
            fprintf(stderr, "\n");                                                 \
            abort();                                                               \
        }                                                                          \
    } while (0)

/* Not every target uses every helper. */
#define PF_FUZZ_UNUSED __attribute__((unused))

/* A file the target places beside its input (name in the work folder). */
typedef struct s_fuzz_file {
    const char *name;
    const char *text;
} s_fuzz_file_t;

#define S_FUZZ_MAX_FILES 16

static char s_fuzz_dir[256];
static char s_fuzz_names[S_FUZZ_MAX_FILES + 1][64];
static int s_fuzz_nnames;

PF_FUZZ_UNUSED static void s_fuzz_cleanup(void)
{
    char path[512];
    for (int i = 0; i < s_fuzz_nnames; i++) {
        snprintf(path, sizeof path, "%s/%.63s", s_fuzz_dir, s_fuzz_names[i]);
        unlink(path);
    }
    rmdir(s_fuzz_dir);
}

/* Writes size bytes to path; 0, or -1 (with a message) on failure. A
 * failure here is the harness's, not the code under test's, so the caller
 * aborts rather than count it as an input. */
PF_FUZZ_UNUSED static int s_fuzz_write(const char *path, const void *data, size_t size)
{
    FILE *f = fopen(path, "wb");
    if (!f) {
        perror(path);
        return -1;
    }
    int ok = fwrite(data, 1, size, f) == size;
    ok &= fclose(f) == 0;
    if (!ok)
        perror(path);
    return ok ? 0 : -1;
}

/* Creates the work folder for target (once), writes the helper files, keeps
 * the log quiet (warnings about unknown keywords would flood the fuzzer's
 * output and slow it down; PF_FUZZ_VERBOSE=1 keeps them), and returns the
 * path that inputs are written to: <folder>/<input_name>. */
PF_FUZZ_UNUSED static const char *s_fuzz_setup(const char *target, const char *input_name, const s_fuzz_file_t *files, int nfiles)
{
    static char input[512];
    if (s_fuzz_dir[0])
        return input;
    if (!getenv("PF_FUZZ_VERBOSE"))
        pf_log_set_level(PF_LOG_QUIET);
    const char *base = access("/dev/shm", W_OK) == 0 ? "/dev/shm" : (getenv("TMPDIR") ? getenv("TMPDIR") : "/tmp");
    snprintf(s_fuzz_dir, sizeof s_fuzz_dir, "%s/pf-fuzz-%s-%ld", base, target, (long)getpid());
    if (mkdir(s_fuzz_dir, 0700) != 0) {
        perror(s_fuzz_dir);
        abort();
    }
    atexit(s_fuzz_cleanup);
    PF_FUZZ_REQUIRE(nfiles <= S_FUZZ_MAX_FILES, "too many helper files");
    for (int i = 0; i < nfiles; i++) {
        char path[512];
        snprintf(path, sizeof path, "%s/%s", s_fuzz_dir, files[i].name);
        snprintf(s_fuzz_names[s_fuzz_nnames++], sizeof s_fuzz_names[0], "%s", files[i].name);
        if (s_fuzz_write(path, files[i].text, strlen(files[i].text)))
            abort();
    }
    snprintf(s_fuzz_names[s_fuzz_nnames++], sizeof s_fuzz_names[0], "%s", input_name);
    snprintf(input, sizeof input, "%s/%s", s_fuzz_dir, input_name);
    return input;
}

/* Writes one input to the path s_fuzz_setup returned. */
PF_FUZZ_UNUSED static void s_fuzz_put(const char *path, const uint8_t *data, size_t size)
{
    if (s_fuzz_write(path, data, size))
        abort();
}

/* A scene that loaded and finalized is what the coordinator sends to its
 * workers: it must serialize, and the blob must read back into a scene that
 * serializes to the same bytes. Otherwise a file the coordinator accepts
 * would be refused (or changed) by every worker. */
PF_FUZZ_UNUSED static void s_fuzz_check_blob(const pf_scene_t *scene)
{
    pf_buf_t a = { 0 }, b = { 0 };
    int rc = pf_sceneblob_write(scene, &a);
    PF_FUZZ_REQUIRE(rc == PF_OK, "a loaded scene does not serialize: %s", pf_strerror(rc));
    pf_error_t err;
    err.msg[0] = '\0';
    pf_scene_t *back = pf_sceneblob_read(a.data, a.len, &err);
    PF_FUZZ_REQUIRE(back != NULL, "the blob of a loaded scene does not read back: %s", err.msg);
    rc = pf_sceneblob_write(back, &b);
    PF_FUZZ_REQUIRE(rc == PF_OK, "a scene read from a blob does not serialize: %s", pf_strerror(rc));
    /* The first blob keeps the path the scene came from; the scene read
     * back carries the same path, so the bytes must agree exactly. */
    PF_FUZZ_REQUIRE(a.len == b.len && memcmp(a.data, b.data, a.len) == 0,
                    "a loaded scene's blob changes on a round trip (%zu vs %zu bytes)", a.len, b.len);
    pf_scene_destroy(&back);
    pf_buf_free(&a);
    pf_buf_free(&b);
}

/* Loads the scene file at path through pf_scene_load (what the renderer
 * does): a scene that loads must survive the blob round trip; one refused
 * must say why. what names the format in the oracle's message. */
PF_FUZZ_UNUSED static void s_fuzz_load_checked(const char *path, const char *what)
{
    pf_error_t err;
    err.msg[0] = '\0';
    pf_scene_t *scene = pf_scene_load(path, &err);
    if (scene)
        s_fuzz_check_blob(scene);
    else
        PF_FUZZ_REQUIRE(err.msg[0] != '\0', what);
    pf_scene_destroy(&scene);
}

#endif
