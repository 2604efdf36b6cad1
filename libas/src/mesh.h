/* The mesh as libas holds it after import: every face of the file, in file
 * order, triangulated as fans. */
#ifndef AS_MESH_H
#define AS_MESH_H

#include "as/as.h"

#ifdef __cplusplus
extern "C" {
#endif

struct as_mesh {
    uint32_t vertex_count;
    uint32_t triangle_count;
    float *positions;         /* 3 per vertex */
    uint32_t *indices;        /* 3 per triangle */
    float *normals;           /* 3 per vertex, or NULL */
    float *uvs;               /* 2 per vertex, or NULL */
    uint32_t *material_ids;   /* 1 per triangle, or NULL */
    uint64_t faces_in_file;
    uint32_t polygon_faces;
    uint32_t degenerate_count;
    uint64_t *degenerate_bits; /* bit i: triangle i is degenerate (set by as_mesh_finish) */
    float bounds_lo[3], bounds_hi[3];
    uint64_t hash;
};

/* Checks a filled mesh (finite coordinates, indices in range, not empty),
 * counts zero-area triangles and computes bounds and hash. `name` names the
 * source in messages. Returns AS_ERROR_INVALID_MESH on failure. */
as_error_t as_mesh_finish(as_mesh_t *mesh, const char *name);

/* Whether triangle i has zero area (exactly, in float): such triangles are
 * kept but never hit. */
int as_mesh_triangle_is_degenerate(const as_mesh_t *mesh, uint32_t i);
/* How many of triangles [first, end) are degenerate. */
uint32_t as_mesh_degenerate_in_range(const as_mesh_t *mesh, uint32_t first, uint32_t end);

#ifdef __cplusplus
}
#endif

#endif
