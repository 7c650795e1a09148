/* atomicfile.h: files that survive a crash whole or not at all: written to
 * "PATH.tmp", fsynced, renamed over PATH, and the directory fsynced, so a
 * reader never sees half a file and a crash leaves at most the .tmp file.
 * Used by the image writers (image/) and the render's checkpoints. */
#ifndef PF_ATOMICFILE_H
#define PF_ATOMICFILE_H

#include <stddef.h>
#include <stdio.h>

#include "base/status.h"

/* "PATH.tmp" in a fresh allocation (free it), or NULL when out of memory. */
char *pf_file_tmp_path(const char *path);

/* fsyncs the directory that holds path, so a rename into it survives a
 * crash. 0, or an errno; EINVAL (a file system that cannot sync a
 * directory) counts as done. */
int pf_file_sync_dir(const char *path);

/* Flushes, fsyncs and closes fp (open on tmp), renames tmp over path and
 * fsyncs the directory. On any failure tmp is removed, err is filled and a
 * negative status returned. fclose is checked: a buffered write first
 * reports a full disk there. */
int pf_file_commit(FILE *fp, const char *tmp, const char *path, pf_error_t *err);

/* fsyncs the closed file tmp, renames it over path and fsyncs the
 * directory (for writers that close their own file). As pf_file_commit. */
int pf_file_commit_closed(const char *tmp, const char *path, pf_error_t *err);

/* Writes len bytes to path atomically (the steps above). 0 or a status
 * with err filled. */
int pf_file_write_atomic(const char *path, const void *data, size_t len, pf_error_t *err);

#endif
