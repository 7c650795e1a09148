/* pbrt_text.h: the pbrt reader's tests' helpers: small pbrt texts written
 * to a temporary folder and loaded (tests/load/test_pbrt*.c). */
#ifndef PF_TEST_PBRT_TEXT_H
#define PF_TEST_PBRT_TEXT_H

#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <unistd.h>

#include "check.h"
#include "load/load.h"
#include "scene/scene.h"

static char s_dir[256];

/* Writes text to <s_dir>/name; returns the path (static buffer per slot). */
static const char *s_write(const char *name, const char *text)
{
    static char paths[8][512];
    static int slot;
    char *p = paths[slot++ % 8];
    snprintf(p, 512, "%s/%s", s_dir, name);
    FILE *f = fopen(p, "wb");
    CHECK(f != NULL, "cannot write %s", p);
    if (f) {
        fputs(text, f);
        fclose(f);
    }
    return p;
}

/* The scene of text (parsed, not finalized); NULL with err filled. */
static pf_scene_t *s_parse(const char *text, int strict, pf_load_report_t *rep, pf_error_t *err)
{
    const char *path = s_write("scene.pbrt", text);
    pf_scene_t *s = pf_scene_create();
    pf_load_opts_t o = { .strict = strict, .report = rep };
    err->msg[0] = '\0';
    if (pf_pbrt_load(s, path, &o, err) != PF_OK)
        pf_scene_destroy(&s);
    return s;
}

/* Occurrences of warnings whose kind starts with prefix. */
static unsigned s_warned(const pf_load_report_t *r, const char *prefix)
{
    unsigned n = 0;
    for (size_t i = 0; i < r->nwarnings; i++)
        if (strncmp(r->warnings[i].kind, prefix, strlen(prefix)) == 0)
            n += r->warnings[i].count;
    return n;
}

static int s_near(float a, float b) { return fabsf(a - b) <= 1e-5f * (1.0f + fabsf(b)); }
static int s_vnear(pf_vec3 a, float x, float y, float z) { return s_near(a.x, x) && s_near(a.y, y) && s_near(a.z, z); }

#define S_HEAD "LookAt 0 0 5  0 0 0  0 1 0\nCamera \"perspective\" \"float fov\" 45\nWorldBegin\n"
#define S_TRI "Shape \"trianglemesh\" \"point3 P\" [1 2 3  0 0 0  1 0 0] \"integer indices\" [0 1 2]\n"

/* Makes the temporary folder the texts go to; 0 on failure (said). */
static inline int pf_pbrt_text_dir(void)
{
    snprintf(s_dir, sizeof s_dir, "/tmp/pf-test-pbrt-XXXXXX");
    if (!mkdtemp(s_dir)) {
        perror("mkdtemp");
        return 0;
    }
    return 1;
}

static inline void pf_pbrt_text_dir_remove(void)
{
    char cmd[512];
    snprintf(cmd, sizeof cmd, "rm -rf '%s'", s_dir);
    if (system(cmd) != 0)
        fprintf(stderr, "could not remove %s\n", s_dir);
}

#endif
