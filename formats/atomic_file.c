/* Atomic whole-file writes and read-only maps (atomic_file.h). */
#define _POSIX_C_SOURCE 200809L
#include "atomic_file.h"

#include "as_internal.h"

#include <errno.h>
#include <fcntl.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/mman.h>
#include <sys/stat.h>
#include <unistd.h>

/* The umask without changing it: umask(2) can only be read by setting it,
 * which races with other threads creating files. Linux reports it in
 * /proc/self/status since 4.7; elsewhere assume the common 022. */
static mode_t current_umask(void)
{
    mode_t mask = 022;
    FILE *f = fopen("/proc/self/status", "r");
    if (!f) return mask;
    char line[256];
    while (fgets(line, sizeof line, f)) {
        unsigned value;
        if (sscanf(line, "Umask: %o", &value) == 1) {
            mask = (mode_t)(value & 0777);
            break;
        }
    }
    fclose(f);
    return mask;
}

static as_atomic_fault_t injected_stage = AS_ATOMIC_FAULT_NONE;
static int injected_errno = 0;

void as_atomic_file_inject_fault(as_atomic_fault_t stage, int error_number)
{
    injected_stage = stage;
    injected_errno = error_number;
}

/* True, with errno set, when the test asked this stage to fail; the fault
 * fires once. */
static int fault_at(as_atomic_fault_t stage)
{
    if (injected_stage != stage) return 0;
    injected_stage = AS_ATOMIC_FAULT_NONE;
    errno = injected_errno;
    return 1;
}

static int write_all(int fd, const void *data, size_t size)
{
    const unsigned char *p = data;
    if (injected_stage == AS_ATOMIC_FAULT_WRITE && size > 0) {
        const ssize_t n = write(fd, p, size / 2);
        (void)n;
        return !fault_at(AS_ATOMIC_FAULT_WRITE);
    }
    while (size > 0) {
        /* Some kernels cap one write at about 2 GiB; ask for less. */
        const size_t chunk = size < ((size_t)1 << 30) ? size : ((size_t)1 << 30);
        const ssize_t n = write(fd, p, chunk);
        if (n < 0) {
            if (errno == EINTR) continue;
            return 0;
        }
        p += n;
        size -= (size_t)n;
    }
    return 1;
}

/* The directory entry made by rename is only durable once the directory
 * itself is synced. Best effort: some file systems refuse fsync on a
 * directory, and the data is already safe in the file. */
static void sync_parent_directory(const char *path)
{
    const char *slash = strrchr(path, '/');
    char *dir = NULL;
    if (!slash) {
        dir = strdup(".");
    } else if (slash == path) {
        dir = strdup("/");
    } else {
        dir = malloc((size_t)(slash - path) + 1);
        if (dir) {
            memcpy(dir, path, (size_t)(slash - path));
            dir[slash - path] = '\0';
        }
    }
    if (!dir) return;
    const int fd = open(dir, O_RDONLY | O_CLOEXEC);
    if (fd >= 0) {
        (void)fsync(fd);
        close(fd);
    }
    free(dir);
}

as_error_t as_atomic_write(const char *path, const as_file_part_t *parts, size_t part_count)
{
    if (!path || !*path)
        return as_set_error(AS_ERROR_INVALID_ARGUMENT, "as_atomic_write: empty path");
    if (part_count > 0 && !parts)
        return as_set_error(AS_ERROR_INVALID_ARGUMENT, "%s: no data to write", path);

    static const char suffix[] = ".tmp.XXXXXX";
    const size_t len = strlen(path);
    char *tmp = as_malloc(len + sizeof suffix, "a temporary file name");
    if (!tmp) return AS_ERROR_OUT_OF_MEMORY;
    memcpy(tmp, path, len);
    memcpy(tmp + len, suffix, sizeof suffix);

    const int fd = fault_at(AS_ATOMIC_FAULT_CREATE) ? -1 : mkstemp(tmp);
    if (fd < 0) {
        const int e = errno;
        as_set_error(AS_ERROR_IO, "%s: cannot create temporary file %s: %s", path, tmp, strerror(e));
        free(tmp);
        return AS_ERROR_IO;
    }

    /* mkstemp makes the file 0600; give it the mode a plain fopen would,
     * or the mode of the file it replaces. */
    struct stat st;
    const mode_t mode = stat(path, &st) == 0 ? (st.st_mode & 07777) : (0666 & ~current_umask());

    const char *what = NULL;
    int e = 0;
    if (fchmod(fd, mode) != 0) {
        what = "cannot set the mode of";
        e = errno;
    }
    for (size_t i = 0; !what && i < part_count; ++i) {
        if (parts[i].size > 0 && !parts[i].data) {
            close(fd);
            unlink(tmp);
            free(tmp);
            return as_set_error(AS_ERROR_INVALID_ARGUMENT, "%s: part %zu has no data", path, i);
        }
        if (!write_all(fd, parts[i].data, parts[i].size)) {
            what = "cannot write";
            e = errno;
        }
    }
    if (!what && (fault_at(AS_ATOMIC_FAULT_SYNC) || fsync(fd) != 0)) {
        what = "cannot sync";
        e = errno;
    }
    /* close can report a deferred write error (NFS, quotas). */
    if (close(fd) != 0 && !what) {
        what = "cannot close";
        e = errno;
    }
    if (!what && (fault_at(AS_ATOMIC_FAULT_RENAME) || rename(tmp, path) != 0)) {
        e = errno;
        unlink(tmp);
        as_set_error(AS_ERROR_IO, "%s: cannot rename %s over it: %s", path, tmp, strerror(e));
        free(tmp);
        return AS_ERROR_IO;
    }
    if (what) {
        unlink(tmp);
        as_set_error(AS_ERROR_IO, "%s: %s temporary file %s: %s", path, what, tmp, strerror(e));
        free(tmp);
        return AS_ERROR_IO;
    }
    free(tmp);
    sync_parent_directory(path);
    return AS_OK;
}

as_error_t as_file_map(const char *path, as_file_map_t *map)
{
    map->data = NULL;
    map->size = 0;
    if (!path || !*path) return as_set_error(AS_ERROR_INVALID_ARGUMENT, "as_file_map: empty path");

    const int fd = open(path, O_RDONLY | O_CLOEXEC);
    if (fd < 0) {
        const int e = errno;
        if (e == ENOENT) return as_set_error(AS_ERROR_FILE_NOT_FOUND, "%s: no such file", path);
        return as_set_error(AS_ERROR_IO, "%s: cannot open: %s", path, strerror(e));
    }
    struct stat st;
    if (fstat(fd, &st) != 0) {
        const int e = errno;
        close(fd);
        return as_set_error(AS_ERROR_IO, "%s: cannot stat: %s", path, strerror(e));
    }
    if (!S_ISREG(st.st_mode)) {
        close(fd);
        return as_set_error(AS_ERROR_IO, "%s: not a regular file", path);
    }
    if ((uint64_t)st.st_size > (uint64_t)SIZE_MAX) {
        close(fd);
        return as_set_error(AS_ERROR_IO, "%s: file of %lld bytes is too large to map", path,
                            (long long)st.st_size);
    }
    if (st.st_size == 0) {
        close(fd);
        return AS_OK;
    }
    void *p = mmap(NULL, (size_t)st.st_size, PROT_READ, MAP_PRIVATE, fd, 0);
    const int e = errno;
    close(fd); /* the mapping keeps the file open */
    if (p == MAP_FAILED) return as_set_error(AS_ERROR_IO, "%s: cannot map: %s", path, strerror(e));
    map->data = p;
    map->size = (size_t)st.st_size;
    return AS_OK;
}

void as_file_unmap(as_file_map_t *map)
{
    if (map && map->data) munmap((void *)map->data, map->size);
    if (map) {
        map->data = NULL;
        map->size = 0;
    }
}
