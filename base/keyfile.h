/* keyfile.h: CURVE key files (no ZeroMQ dependency here: keys are handled as
 * the 40-character Z85 text that libzmq's socket options accept).
 *
 * A key file is text written by `photonfarm keygen`:
 *
 *   # photonfarm CURVE key pair
 *   public-key = <40 Z85 characters>
 *   secret-key = <40 Z85 characters>     (absent in a public-only file)
 *
 * Blank lines and lines starting with '#' are skipped; spaces around '=' and
 * at either end of a line are allowed. An allowed-workers list holds one
 * public key per line, either bare or as a `public-key = ...` line. */
#ifndef PF_KEYFILE_H
#define PF_KEYFILE_H

#include <stddef.h>

#include "base/status.h"

#define PF_Z85_KEY_LEN 40

/* 1 when s is exactly PF_Z85_KEY_LEN characters of the Z85 alphabet. */
int pf_z85_key_valid(const char *s);

/* Reads a key file. public_z85 receives the public key (NUL-terminated).
 * When secret_z85 is not NULL the secret key is required and copied there;
 * when NULL a secret in the file is ignored. When the secret is wanted, a
 * file others may read or write, or (owned by the reader) its group may, is
 * refused like ssh refuses such a key: PF_EIO, "FILE: this secret key file
 * is readable by others (mode 0644): chmod 600 FILE"; a file owned by
 * another user (root) and shared with a group (0640, 0440) is accepted.
 * Public-key files and lists may be readable by anyone. 0, or PF_EIO
 * (unreadable, or a secret others can read) /
 * PF_EPARSE (malformed: "file:line: what", or "file: no public-key line")
 * with err filled. */
int pf_keyfile_read(const char *path, char public_z85[41], char secret_z85[41], pf_error_t *err);

/* Writes a key file (secret_z85 may be NULL for a public-only file). A file
 * holding a secret is created with mode 0600 (an existing file is replaced
 * and re-moded, never left world-readable). Both keys are validated first
 * (PF_EINVAL). 0, PF_EINVAL or PF_EIO with err filled. */
int pf_keyfile_write(const char *path, const char *public_z85, const char *secret_z85, pf_error_t *err);

/* Reads an allowed-workers list into *keys (malloc'd array of n keys, each
 * NUL-terminated; the caller frees it with free()). An empty list is valid
 * (*keys NULL, *n 0). 0, PF_EIO, PF_EPARSE ("file:line: ...") or PF_ENOMEM. */
int pf_keyfile_read_list(const char *path, char (**keys)[41], size_t *n, pf_error_t *err);

#endif
