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

/* Test-only fault injection: the next as_atomic_write fails at `stage` as if
 * the system call there had failed with `error_number` (ENOSPC, EIO, EXDEV,
 * ...), then the fault clears itself. At AS_ATOMIC_FAULT_WRITE half of the
 * first part is written before the failure, as a disk that fills up mid-file
 * would. The tests run as root, where permission bits cannot make a write or
 * a rename fail, so this is how they prove that a failure at each stage leaves
 * the previous file intact. A function rather than an environment variable so
 * that no user of the tools can trigger it; it is declared only in this
 * internal header. Not thread-safe: for single-threaded tests. */
typedef enum as_atomic_fault {
    AS_ATOMIC_FAULT_NONE = 0,
    AS_ATOMIC_FAULT_CREATE,   /* mkstemp of the temporary file */
    AS_ATOMIC_FAULT_WRITE,    /* write(2), after half of the first part */
    AS_ATOMIC_FAULT_SYNC,     /* fsync(2) of the temporary file */
    AS_ATOMIC_FAULT_RENAME    /* rename(2) over the target */
} as_atomic_fault_t;
void as_atomic_file_inject_fault(as_atomic_fault_t stage, int error_number);

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
