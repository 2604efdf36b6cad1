/* The readers behind as_mesh_import that are written in C++ (OpenMesh's
 * parsers, Draco's decoder), reached through a C interface. Each fills an
 * empty as_mesh_t from bytes in memory: the arrays are allocated with malloc
 * (as_mesh_release frees them), faces are kept in file order, a face of k > 3
 * corners becomes k - 2 fan triangles, nothing is dropped or renumbered. They
 * do not call as_mesh_finish. On failure they set the error (naming `name`),
 * free what they allocated and leave the mesh empty. Safe to call from several
 * threads (OpenMesh's readers are shared singletons, so its calls take a
 * lock). */
#ifndef AS_MESH_IMPORT_SHIMS_H
#define AS_MESH_IMPORT_SHIMS_H

#include "mesh.h"

#ifdef __cplusplus
extern "C" {
#endif

/* OBJ, PLY (ASCII or binary) or OFF; `format` is "obj", "ply" or "off".
 * `file_path` names a file holding exactly these bytes, or is NULL (data that
 * was decompressed); OpenMesh's OFF reader needs one to see the header, and
 * without it a temporary file is written. */
as_error_t as_mesh_read_openmesh(const void *data, size_t size, const char *format,
                                 const char *name, const char *file_path, as_mesh_t *mesh);

/* Checks a PLY file's header and body against the format before OpenMesh's
 * reader sees them: every count, every number, and no list property but a
 * face's vertex indices (the reader misreads any other). Sets the error with
 * the line (ASCII) or offset (binary) that is wrong. */
as_error_t as_mesh_check_ply(const void *data, size_t size, const char *name);

/* A Draco-compressed mesh (.drc). Draco's points become the vertices. */
as_error_t as_mesh_read_draco(const void *data, size_t size, const char *name,
                              as_mesh_t *mesh);

#ifdef __cplusplus
}
#endif

#endif
