/* keyfile.c: reading and writing CURVE key files and allowed-key lists; see
 * keyfile.h for the format. Keys stay Z85 text end to end (libzmq decodes
 * them), so this module only checks their length and alphabet.
 *
 * One subtlety: '#' belongs to the Z85 alphabet, so a line is a comment when
 * its first non-blank character is '#' AND it is not itself a bare 40-character
 * key; values after '=' are taken whole (no trailing comments). Stateless and
 * thread-safe. */
#include "base/keyfile.h"

#include <errno.h>
#include <fcntl.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/stat.h>
#include <unistd.h>

#include "base/reserve.h"

static const char s_z85_alphabet[] =
    "0123456789abcdefghijklmnopqrstuvwxyzABCDEFGHIJKLMNOPQRSTUVWXYZ.-:+=^!/*?&<>()[]{}@%$#";

int pf_z85_key_valid(const char *s)
{
    if (!s)
        return 0;
    size_t i = 0;
    for (; s[i]; i++) {
        if (i >= PF_Z85_KEY_LEN || !strchr(s_z85_alphabet, s[i]))
            return 0;
    }
    return i == PF_Z85_KEY_LEN;
}

/* Trims blanks (and a CR from CRLF files) at both ends, in place. */
static char *s_trim(char *s)
{
    while (*s == ' ' || *s == '\t')
        s++;
    size_t n = strlen(s);
    while (n > 0 && (s[n - 1] == ' ' || s[n - 1] == '\t' || s[n - 1] == '\r' || s[n - 1] == '\n'))
        s[--n] = '\0';
    return s;
}

/* A parsed line: blank/comment, a bare key, or "name = value". */
typedef enum { S_LINE_SKIP, S_LINE_BARE, S_LINE_PAIR } s_line_kind;

typedef struct s_reader {
    FILE *f;
    const char *path;
    int line;
    char *buf; /* getline's buffer */
    size_t cap;
} s_reader;

/* Reads the next line. 1 with *kind, *name and *value set (pointing into
 * r->buf), 0 at the end of the file, or a negative status with err filled. */
static int s_next_line(s_reader *r, s_line_kind *kind, char **name, char **value, pf_error_t *err)
{
    errno = 0;
    ssize_t len = getline(&r->buf, &r->cap, r->f);
    if (len < 0) {
        if (ferror(r->f))
            return pf_error_set(err, errno == ENOMEM ? PF_ENOMEM : PF_EIO, r->path, r->line + 1, "read error: %s",
                                strerror(errno));
        return 0;
    }
    r->line++;
    if (len > 4096)
        return pf_error_set(err, PF_EPARSE, r->path, r->line, "line too long (%zd characters)", len);
    if (strlen(r->buf) != (size_t)len)
        return pf_error_set(err, PF_EPARSE, r->path, r->line, "NUL byte in a text file");
    char *s = s_trim(r->buf);
    *name = *value = NULL;
    if (*s == '\0') {
        *kind = S_LINE_SKIP;
        return 1;
    }
    if (pf_z85_key_valid(s)) {
        *kind = S_LINE_BARE;
        *value = s;
        return 1;
    }
    if (*s == '#') {
        *kind = S_LINE_SKIP;
        return 1;
    }
    char *eq = strchr(s, '=');
    if (!eq) {
        *kind = S_LINE_BARE; /* not a valid key; the caller reports it */
        *value = s;
        return 1;
    }
    *eq = '\0';
    *name = s_trim(s);
    *value = s_trim(eq + 1);
    *kind = S_LINE_PAIR;
    return 1;
}

static int s_open(s_reader *r, const char *path, pf_error_t *err)
{
    memset(r, 0, sizeof *r);
    r->path = path;
    r->f = fopen(path, "r");
    if (!r->f)
        return pf_error_set(err, PF_EIO, path, 0, "cannot open: %s", strerror(errno));
    return 0;
}

/* A secret key file others can read (or write) is refused, like ssh does:
 * any access for others, and group access on a file the reader owns (a file
 * owned by root and shared with a service group, 0640 or 0440, is fine). */
static int s_check_private(s_reader *r, pf_error_t *err)
{
    struct stat st;
    if (fstat(fileno(r->f), &st) != 0)
        return pf_error_set(err, PF_EIO, r->path, 0, "cannot stat: %s", strerror(errno));
    unsigned mode = (unsigned)(st.st_mode & 07777);
    int others = (mode & 0007) != 0, group = (mode & 0070) != 0 && st.st_uid == geteuid();
    if (!S_ISREG(st.st_mode) || (!others && !group))
        return PF_OK;
    return pf_error_set(err, PF_EIO, r->path, 0,
                        "this secret key file is %s by %s (mode %04o): chmod 600 %s", (mode & 0022) ? "accessible"
                        : "readable", others ? "others" : "its group", mode, r->path);
}

int pf_keyfile_read(const char *path, char public_z85[41], char secret_z85[41], pf_error_t *err)
{
    s_reader r;
    int rc = s_open(&r, path, err);
    if (rc)
        return rc;
    int have_public = 0, have_secret = 0;
    s_line_kind kind;
    char *name, *value;
    while ((rc = s_next_line(&r, &kind, &name, &value, err)) == 1) {
        if (kind == S_LINE_SKIP)
            continue;
        if (kind == S_LINE_BARE) {
            rc = pf_error_set(err, PF_EPARSE, path, r.line, "expected 'public-key = KEY' or 'secret-key = KEY'");
            break;
        }
        int is_public = strcmp(name, "public-key") == 0, is_secret = strcmp(name, "secret-key") == 0;
        if (!is_public && !is_secret) {
            rc = pf_error_set(err, PF_EPARSE, path, r.line, "unknown entry '%.64s' (expected public-key or secret-key)",
                              name);
            break;
        }
        if (!pf_z85_key_valid(value)) {
            rc = pf_error_set(err, PF_EPARSE, path, r.line, "%s is not %d characters of the Z85 alphabet", name,
                              PF_Z85_KEY_LEN);
            break;
        }
        if ((is_public && have_public) || (is_secret && have_secret)) {
            rc = pf_error_set(err, PF_EPARSE, path, r.line, "a second %s line", name);
            break;
        }
        if (is_public) {
            memcpy(public_z85, value, PF_Z85_KEY_LEN + 1);
            have_public = 1;
        } else {
            if (secret_z85)
                memcpy(secret_z85, value, PF_Z85_KEY_LEN + 1);
            have_secret = 1;
        }
    }
    /* Checked once the file is known to hold a secret: a public key file
     * read where a pair is wanted is better told so. */
    if (rc >= 0 && secret_z85 && have_secret && (rc = s_check_private(&r, err)) != PF_OK)
        memset(secret_z85, 0, PF_Z85_KEY_LEN + 1);
    fclose(r.f);
    free(r.buf);
    if (rc < 0)
        return rc;
    if (!have_public)
        return pf_error_set(err, PF_EPARSE, path, 0, "no public-key line");
    if (secret_z85 && !have_secret)
        return pf_error_set(err, PF_EPARSE, path, 0,
                            "no secret-key line (this is a public key; the key pair file is needed here)");
    return PF_OK;
}

int pf_keyfile_write(const char *path, const char *public_z85, const char *secret_z85, pf_error_t *err)
{
    if (!pf_z85_key_valid(public_z85))
        return pf_error_set(err, PF_EINVAL, path, 0, "public key is not %d Z85 characters", PF_Z85_KEY_LEN);
    if (secret_z85 && !pf_z85_key_valid(secret_z85))
        return pf_error_set(err, PF_EINVAL, path, 0, "secret key is not %d Z85 characters", PF_Z85_KEY_LEN);
    mode_t mode = secret_z85 ? 0600 : 0644;
    int fd = open(path, O_WRONLY | O_CREAT | O_TRUNC | O_CLOEXEC, mode);
    if (fd < 0)
        return pf_error_set(err, PF_EIO, path, 0, "cannot create: %s", strerror(errno));
    /* open() keeps the mode of an existing file; a secret must not stay
     * readable by others because the file happened to exist. */
    if (secret_z85 && fchmod(fd, 0600) != 0) {
        int e = errno;
        close(fd);
        return pf_error_set(err, PF_EIO, path, 0, "cannot restrict permissions to 0600: %s", strerror(e));
    }
    FILE *f = fdopen(fd, "w");
    if (!f) {
        int e = errno;
        close(fd);
        return pf_error_set(err, PF_EIO, path, 0, "cannot write: %s", strerror(e));
    }
    fprintf(f, "# photonfarm CURVE %s (Z85)\n", secret_z85 ? "key pair: keep this file secret" : "public key");
    fprintf(f, "public-key = %s\n", public_z85);
    if (secret_z85)
        fprintf(f, "secret-key = %s\n", secret_z85);
    int bad = ferror(f);
    if (fclose(f) != 0 || bad)
        return pf_error_set(err, PF_EIO, path, 0, "write failed: %s", strerror(errno));
    return PF_OK;
}

int pf_keyfile_read_list(const char *path, char (**keys)[41], size_t *n, pf_error_t *err)
{
    *keys = NULL;
    *n = 0;
    s_reader r;
    int rc = s_open(&r, path, err);
    if (rc)
        return rc;
    char(*list)[41] = NULL;
    size_t count = 0, cap = 0;
    s_line_kind kind;
    char *name, *value;
    while ((rc = s_next_line(&r, &kind, &name, &value, err)) == 1) {
        if (kind == S_LINE_SKIP)
            continue;
        if (kind == S_LINE_PAIR && strcmp(name, "public-key") != 0) {
            rc = pf_error_set(err, PF_EPARSE, path, r.line,
                              strcmp(name, "secret-key") == 0
                                  ? "a secret key in a list of allowed public keys (never share secret keys)"
                                  : "expected a public key or 'public-key = KEY'");
            break;
        }
        if (!pf_z85_key_valid(value)) {
            rc = pf_error_set(err, PF_EPARSE, path, r.line, "not a public key (%d characters of the Z85 alphabet)",
                              PF_Z85_KEY_LEN);
            break;
        }
        if (pf_reserve((void **)&list, &cap, count + 1, sizeof *list)) {
            rc = pf_error_set(err, PF_ENOMEM, path, r.line, "out of memory");
            break;
        }
        memcpy(list[count++], value, PF_Z85_KEY_LEN + 1);
    }
    fclose(r.f);
    free(r.buf);
    if (rc < 0) {
        free(list);
        return rc;
    }
    *keys = list;
    *n = count;
    return PF_OK;
}
