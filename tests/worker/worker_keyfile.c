/* worker_keyfile.c: base/keyfile, the worker's and coordinator's CURVE key
 * files (the keyfile ctest): write/read round trips, 0600 on secret files,
 * public-only files, allowed-key lists (bare and `public-key =` lines,
 * comments, a key that starts with '#'), and malformed files whose errors
 * must name file and line, and secret key files others can read, refused
 * with their mode and the chmod that fixes them. Files live in a fresh directory under /tmp. */
#include <errno.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/stat.h>
#include <unistd.h>

#include "base/keyfile.h"
#include "base/status.h"

#include "worker_test.h"

static void s_write_text(const char *path, const char *text)
{
    FILE *f = fopen(path, "w");
    if (f) {
        fputs(text, f);
        fclose(f);
    }
    chmod(path, 0600); /* some of these hold a secret: private, as keygen writes them */
}

/* The error names the file and this line ("path:line: ..."). */
static int s_names_line(const pf_error_t *err, const char *path, int line)
{
    char want[700];
    snprintf(want, sizeof want, "%.600s:%d: ", path, line);
    return strncmp(err->msg, want, strlen(want)) == 0;
}

/* Two valid keys (a pair), and a valid key that starts with '#'. */
static const char P[] = "Yne@$w-vo<fVvi]a<NY6T1ed:M$fCG*[IaLV{hID";
static const char S[] = "D:)Q[IlAW!ahhC2ac:9*A}h:p?([4%wOTJ%JR%cs";
static const char H[] = "#bcdefghij0123456789ABCDEFGHIJ.-:+=^!/*?";

/* Key validity, write/read round trips with the files' modes, and a
 * lenient layout (comments, blanks, CRLF, spaces). */
static void s_keyfile_round_trips(const char *pair, const char *pub, const char *bad)
{
    pf_error_t err;
    char p[41], s[41];

    CHECK(pf_z85_key_valid(P) && pf_z85_key_valid(S) && pf_z85_key_valid(H), "valid keys accepted");
    CHECK(!pf_z85_key_valid("short") && !pf_z85_key_valid("Yne@$w-vo<fVvi]a<NY6T1ed:M$fCG*[IaLV{hI~") &&
              !pf_z85_key_valid("Yne@$w-vo<fVvi]a<NY6T1ed:M$fCG*[IaLV{hIDx"),
          "short, foreign-alphabet and long keys rejected");

    /* Round trips. */
    CHECK(pf_keyfile_write(pair, P, S, &err) == 0, "write pair: %s", err.msg);
    struct stat st;
    CHECK(stat(pair, &st) == 0 && (st.st_mode & 0777) == 0600, "secret file mode %o", (unsigned)(st.st_mode & 0777));
    memset(p, 0, sizeof p), memset(s, 0, sizeof s);
    CHECK(pf_keyfile_read(pair, p, s, &err) == 0 && strcmp(p, P) == 0 && strcmp(s, S) == 0, "read pair: %s", err.msg);
    CHECK(pf_keyfile_read(pair, p, NULL, &err) == 0 && strcmp(p, P) == 0, "public from a pair file");
    CHECK(pf_keyfile_write(pub, P, NULL, &err) == 0, "write public: %s", err.msg);
    CHECK(pf_keyfile_read(pub, p, NULL, &err) == 0 && strcmp(p, P) == 0, "read public: %s", err.msg);
    CHECK(pf_keyfile_read(pub, p, s, &err) == PF_EPARSE && strstr(err.msg, "no secret-key") != NULL,
          "a secret requested from a public file: %s", err.msg);
    /* An existing world-readable file is narrowed to 0600 when it gets a secret. */
    chmod(pub, 0644);
    CHECK(pf_keyfile_write(pub, P, S, &err) == 0 && stat(pub, &st) == 0 && (st.st_mode & 0777) == 0600,
          "rewritten secret file mode %o", (unsigned)(st.st_mode & 0777));
    CHECK(pf_keyfile_write(pair, "not a key", S, &err) == PF_EINVAL, "writing an invalid key refused");
    CHECK(pf_keyfile_read("/nonexistent/pf.key", p, NULL, &err) == PF_EIO &&
              strstr(err.msg, "/nonexistent/pf.key") != NULL,
          "missing file: %s", err.msg);

    /* Comments, blanks, CRLF and spaces are fine. */
    char text[1024];
    snprintf(text, sizeof text, "# comment\r\n\n   public-key=%s  \r\n\tsecret-key =  %s\n", P, S);
    s_write_text(bad, text);
    CHECK(pf_keyfile_read(bad, p, s, &err) == 0 && strcmp(p, P) == 0 && strcmp(s, S) == 0, "lenient layout: %s",
          err.msg);
}

/* Secret key files with loose modes are refused (like ssh): the error names
 * the file, its mode and the fix; public keys may be readable by anyone. */
static void s_keyfile_modes(const char *pair, const char *pub)
{
    pf_error_t err;
    char p[41], s[41];
    CHECK(pf_keyfile_write(pair, P, S, &err) == 0, "write pair: %s", err.msg);
    static const unsigned bad_modes[] = { 0644, 0604, 0606, 0660, 0640, 0670, 0777 };
    for (size_t i = 0; i < sizeof bad_modes / sizeof bad_modes[0]; i++) {
        chmod(pair, bad_modes[i]);
        char mode[16], fix[700];
        snprintf(mode, sizeof mode, "(mode %04o)", bad_modes[i]);
        snprintf(fix, sizeof fix, "chmod 600 %.600s", pair);
        memset(s, 0, sizeof s);
        int rc = pf_keyfile_read(pair, p, s, &err);
        CHECK(rc == PF_EIO && strncmp(err.msg, pair, strlen(pair)) == 0 && strstr(err.msg, mode) &&
                  strstr(err.msg, fix) && s[0] == '\0',
              "mode %04o: rc %d, %s", bad_modes[i], rc, err.msg);
    }
    chmod(pair, 0644);
    CHECK(pf_keyfile_read(pair, p, s, &err) == PF_EIO && strstr(err.msg, "readable by others"),
          "0644 says readable by others: %s", err.msg);
    /* Only its public half wanted: a readable pair file is read. */
    CHECK(pf_keyfile_read(pair, p, NULL, &err) == 0 && strcmp(p, P) == 0, "public half of a 0644 pair: %s", err.msg);
    static const unsigned good_modes[] = { 0600, 0400, 0700 };
    for (size_t i = 0; i < sizeof good_modes / sizeof good_modes[0]; i++) {
        chmod(pair, good_modes[i]);
        CHECK(pf_keyfile_read(pair, p, s, &err) == 0 && strcmp(s, S) == 0, "mode %04o accepted: %s", good_modes[i],
              err.msg);
    }
    chmod(pair, 0600);
    /* A public key file and a list readable by all are fine. */
    CHECK(pf_keyfile_write(pub, P, NULL, &err) == 0 && chmod(pub, 0644) == 0, "write public: %s", err.msg);
    CHECK(pf_keyfile_read(pub, p, NULL, &err) == 0 && strcmp(p, P) == 0, "0644 public key: %s", err.msg);
    char(*keys)[41] = NULL;
    size_t n = 0;
    CHECK(pf_keyfile_read_list(pub, &keys, &n, &err) == 0 && n == 1, "0644 list: %s", err.msg);
    free(keys);
}

/* Malformed key files: the error names file and line. */
static void s_keyfile_malformed(const char *bad)
{
    pf_error_t err;
    char p[41], s[41];
    struct {
        const char *text;
        int line;
        const char *what;
    } cases[] = {
        { "# c\npublic-key = tooshort\n", 2, "Z85" },
        { "public-key = %P\nsecret-key = %P~\n", 2, "Z85" },
        { "\n\nprivate-key = %P\n", 3, "unknown entry" },
        { "public-key = %P\npublic-key = %P\n", 2, "second" },
        { "# c\n%P\n", 2, "expected" },
        { "public-key %P\n", 1, "expected" },
    };
    for (size_t i = 0; i < sizeof cases / sizeof cases[0]; i++) {
        /* %P stands for the valid public key. */
        char buf[1024] = "";
        for (const char *c = cases[i].text; *c; c++) {
            if (c[0] == '%' && c[1] == 'P') {
                strcat(buf, P);
                c++;
            } else {
                size_t n = strlen(buf);
                buf[n] = *c;
                buf[n + 1] = '\0';
            }
        }
        s_write_text(bad, buf);
        memset(&err, 0, sizeof err);
        int rc = pf_keyfile_read(bad, p, s, &err);
        CHECK(rc == PF_EPARSE && s_names_line(&err, bad, cases[i].line) && strstr(err.msg, cases[i].what),
              "malformed key file %zu: rc %d, '%s'", i, rc, err.msg);
    }
    s_write_text(bad, "# only a comment\n");
    CHECK(pf_keyfile_read(bad, p, NULL, &err) == PF_EPARSE && strstr(err.msg, "no public-key"), "empty key file: %s",
          err.msg);
    /* A NUL byte inside a line. */
    FILE *f = fopen(bad, "w");
    if (f) {
        fputs("public-key = ", f);
        fputc(0, f);
        fputs(P, f);
        fputc('\n', f);
        fclose(f);
    }
    CHECK(pf_keyfile_read(bad, p, NULL, &err) == PF_EPARSE && s_names_line(&err, bad, 1), "NUL byte: %s", err.msg);
}

/* Allowed-key lists: bare keys and `public-key =` lines, comments, a key
 * that starts with '#'; empty lists, bad keys naming their line, and a list
 * that grows. */
static void s_keyfile_lists(const char *list)
{
    pf_error_t err;
    char text[1024];
    char(*keys)[41] = NULL;
    size_t n = 99;
    snprintf(text, sizeof text, "# allowed workers\n\n%s\npublic-key = %s\n  %s  \n# another comment with = sign\n",
             P, S, H);
    s_write_text(list, text);
    CHECK(pf_keyfile_read_list(list, &keys, &n, &err) == 0 && n == 3, "list: n %zu, %s", n, err.msg);
    if (keys && n == 3)
        CHECK(strcmp(keys[0], P) == 0 && strcmp(keys[1], S) == 0 && strcmp(keys[2], H) == 0, "list contents");
    free(keys);
    s_write_text(list, "# nobody\n\n");
    keys = (void *)1;
    CHECK(pf_keyfile_read_list(list, &keys, &n, &err) == 0 && n == 0 && keys == NULL, "empty list");
    snprintf(text, sizeof text, "%s\n\n%s\n", P, "Yne@$w-vo<fVvi]a<NY6T1ed:M$fCG*[IaLV{h");
    s_write_text(list, text);
    keys = NULL;
    CHECK(pf_keyfile_read_list(list, &keys, &n, &err) == PF_EPARSE && s_names_line(&err, list, 3) && keys == NULL,
          "short key in a list: %s", err.msg);
    snprintf(text, sizeof text, "%s\nsecret-key = %s\n", P, S);
    s_write_text(list, text);
    CHECK(pf_keyfile_read_list(list, &keys, &n, &err) == PF_EPARSE && s_names_line(&err, list, 2) &&
              strstr(err.msg, "secret"),
          "secret key in a list: %s", err.msg);
    /* Many keys (the list grows). */
    FILE *f = fopen(list, "w");
    for (int i = 0; f && i < 100; i++)
        fprintf(f, "%s\n", i % 2 ? P : S);
    if (f)
        fclose(f);
    CHECK(pf_keyfile_read_list(list, &keys, &n, &err) == 0 && n == 100 && strcmp(keys[99], P) == 0, "100 keys");
    free(keys);
}

void wt_test_keyfile(void)
{
    char dir[] = "/tmp/pf_keyfile_XXXXXX";
    if (!mkdtemp(dir)) {
        CHECK(0, "mkdtemp: %s", strerror(errno));
        return;
    }
    char pair[600], pub[600], bad[600], list[600];
    snprintf(pair, sizeof pair, "%s/worker.key", dir);
    snprintf(pub, sizeof pub, "%s/worker.pub", dir);
    snprintf(bad, sizeof bad, "%s/bad.key", dir);
    snprintf(list, sizeof list, "%s/allowed.txt", dir);
    s_keyfile_round_trips(pair, pub, bad);
    s_keyfile_modes(pair, pub);
    s_keyfile_malformed(bad);
    s_keyfile_lists(list);

    unlink(pair), unlink(pub), unlink(bad), unlink(list);
    rmdir(dir);
}
