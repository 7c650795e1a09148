/* atomicfile.c: crash-safe file replacement; see atomicfile.h. */
#include "base/atomicfile.h"

#include <errno.h>
#include <fcntl.h>
#include <stdlib.h>
#include <string.h>
#include <unistd.h>

char *pf_file_tmp_path(const char *path)
{
    size_t n = strlen(path);
    char *tmp = malloc(n + sizeof ".tmp");
    if (tmp) {
        memcpy(tmp, path, n);
        memcpy(tmp + n, ".tmp", sizeof ".tmp");
    }
    return tmp;
}

int pf_file_sync_dir(const char *path)
{
    const char *slash = strrchr(path, '/');
    char dir[4096];
    if (!slash)
        snprintf(dir, sizeof dir, ".");
    else if (slash == path)
        snprintf(dir, sizeof dir, "/");
    else if ((size_t)(slash - path) < sizeof dir)
        snprintf(dir, sizeof dir, "%.*s", (int)(slash - path), path);
    else
        return ENAMETOOLONG;
    int fd = open(dir, O_RDONLY | O_DIRECTORY | O_CLOEXEC);
    if (fd < 0)
        return errno;
    int e = fsync(fd) == 0 || errno == EINVAL ? 0 : errno;
    close(fd);
    return e;
}

/* The rename and the directory's fsync, once tmp is on disk. */
static int s_rename(const char *tmp, const char *path, pf_error_t *err)
{
    if (rename(tmp, path) != 0) {
        int e = errno;
        remove(tmp);
        return pf_error_set(err, PF_EIO, path, 0, "cannot rename %s into place: %s", tmp, strerror(e));
    }
    int e = pf_file_sync_dir(path);
    if (e)
        return pf_error_set(err, PF_EIO, path, 0, "cannot sync the directory of %s: %s", path, strerror(e));
    return PF_OK;
}

int pf_file_commit(FILE *fp, const char *tmp, const char *path, pf_error_t *err)
{
    /* The data reaches the disk before the name does: fsync the file, rename
     * it, fsync the directory. */
    if (fflush(fp) != 0 || fsync(fileno(fp)) != 0) {
        int e = errno;
        fclose(fp);
        remove(tmp);
        return pf_error_set(err, PF_EIO, path, 0, "cannot write %s: %s", tmp, strerror(e));
    }
    if (fclose(fp) != 0) {
        int e = errno;
        remove(tmp);
        return pf_error_set(err, PF_EIO, path, 0, "cannot write %s: %s", tmp, strerror(e));
    }
    return s_rename(tmp, path, err);
}

int pf_file_commit_closed(const char *tmp, const char *path, pf_error_t *err)
{
    int fd = open(tmp, O_RDONLY | O_CLOEXEC);
    if (fd < 0 || fsync(fd) != 0) {
        int e = errno;
        if (fd >= 0)
            close(fd);
        remove(tmp);
        return pf_error_set(err, PF_EIO, path, 0, "cannot write %s: %s", tmp, strerror(e));
    }
    close(fd);
    return s_rename(tmp, path, err);
}

int pf_file_write_atomic(const char *path, const void *data, size_t len, pf_error_t *err)
{
    char *tmp = pf_file_tmp_path(path);
    if (!tmp)
        return pf_error_set(err, PF_ENOMEM, path, 0, "out of memory");
    FILE *fp = fopen(tmp, "wb");
    if (!fp) {
        int e = errno;
        free(tmp);
        return pf_error_set(err, PF_EIO, path, 0, "cannot create %s: %s", path, strerror(e));
    }
    int rc = PF_OK;
    if (len && fwrite(data, 1, len, fp) != len) {
        int e = errno;
        fclose(fp);
        remove(tmp);
        rc = pf_error_set(err, PF_EIO, path, 0, "cannot write %s: %s", tmp, strerror(e));
    } else {
        rc = pf_file_commit(fp, tmp, path, err);
    }
    free(tmp);
    return rc;
}
