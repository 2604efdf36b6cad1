/* Whole-file I/O shared by the .asf container and the ray/hit files.
 *
 * Writers must never leave half a file where a reader expects a whole one, so
 * every output goes to PATH.tmp.XXXXXX in the same directory (rename is only
 * atomic within one file system), is fsync'd, then renamed over PATH. Readers
 * map files read-only instead of reading them, so that uncompressed sections
 * can be used in place. */
#ifndef AS_ATOMIC_FILE_H
#define AS_ATOMIC_FILE_H

#include "as/as.h"

#include <stddef.h>

/* One piece of the output; pieces are written back to back. Gathering
 * lets callers write a header and a caller-owned array without copying. */
typedef struct as_file_part {
    const void *data;
    size_t size;
} as_file_part_t;

/* Writes the parts to `path` atomically. On failure the temporary file is
 * removed, `path` is untouched, and the error is AS_ERROR_IO with a message
 * naming the path and the system error (or AS_ERROR_INVALID_ARGUMENT,
 * AS_ERROR_OUT_OF_MEMORY). A new file gets mode 0666 less the umask, like
 * fopen; an existing file keeps its mode. */
as_error_t as_atomic_write(const char *path, const as_file_part_t *parts, size_t part_count);

/* A read-only private mapping of a whole file. An empty file maps to
 * data == NULL, size == 0 (mmap refuses zero lengths). */
typedef struct as_file_map {
    const void *data;
    size_t size;
} as_file_map_t;

/* Errors: AS_ERROR_FILE_NOT_FOUND, AS_ERROR_IO (messages name the path). */
as_error_t as_file_map(const char *path, as_file_map_t *map);
/* Accepts a zeroed or already unmapped map. */
void as_file_unmap(as_file_map_t *map);

#endif
