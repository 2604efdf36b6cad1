/* What the BIH, octree and grid builders share: the TRIS section (one
 * as_tri4_t per source triangle, in source order), the exact triangle/box
 * overlap test, and META's common fields. */
#ifndef AS_SPATIAL_COMMON_H
#define AS_SPATIAL_COMMON_H

#include "structure.h"
#include "mesh.h"
#include "bvh2_layout.h"

#include <math.h>

/* TRIS: entry i is source triangle i with v0.w = i (uint32 bits); zero-area
 * triangles are present but no structure refers to them. Filled on up to
 * `threads` threads. NULL (error set) when out of memory. */
as_tri4_t *as_spatial_tris(const as_mesh_t *mesh, unsigned threads);
/* Triangle `id` of the mesh as a TRIS/TRI4 entry: its vertices, v0.w = id. */
static inline void as_spatial_tri4(const as_mesh_t *mesh, uint32_t id, as_tri4_t *out)
{
    const uint32_t *ix = mesh->indices + 3 * (size_t)id;
    const float *a = mesh->positions + 3 * (size_t)ix[0], *b = mesh->positions + 3 * (size_t)ix[1],
                *c = mesh->positions + 3 * (size_t)ix[2];
    out->v0 = (as_f4_t){a[0], a[1], a[2], as_uint_as_float(id)};
    out->v1 = (as_f4_t){b[0], b[1], b[2], 0.0f};
    out->v2 = (as_f4_t){c[0], c[1], c[2], 0.0f};
}
/* Adds TRIS (from as_spatial_tris) to s; the array goes back to the build
 * memory kept for the next build (as_block_give) when s is released. */
void as_spatial_add_tris(as_structure_t *s, as_tri4_t *tris, uint32_t n);

/* Whether triangle (a, b, c) overlaps the closed box [lo, hi] grown by
 * `pad` on every side: the separating-axis test of Akenine-Moller 2001
 * ("Fast 3D triangle-box overlap testing"), in double. The pad keeps the
 * test conservative against the float rounding of the traversals' cell
 * walls and entry points; it adds references only for triangles that pass
 * within `pad` of a cell. */
int as_tri_box_overlap(const float *a, const float *b, const float *c, const float lo[3], const float hi[3],
                       double pad);

/* The pad the octree and grid use around a cell with these corners: a few
 * float ulps of the largest coordinate involved. */
static inline double as_spatial_pad(const float lo[3], const float hi[3])
{
    double m = 0.0;
    for (int k = 0; k < 3; ++k) {
        if (fabs((double)lo[k]) > m) m = fabs((double)lo[k]);
        if (fabs((double)hi[k]) > m) m = fabs((double)hi[k]);
    }
    /* 2^-20: eight ulps of the largest coordinate. */
    return m * 0x1p-20 + 1e-30;
}

/* Fills META's writer, kind, layout, builder, parameters, source and bounds. */
void as_spatial_meta(as_structure_t *s, const as_mesh_t *mesh, const as_build_args_t *args, uint32_t kind,
                     uint32_t layout, uint32_t layout_version, uint32_t builder);

/* Half the surface area of a box, in double (SAH ratios). */
double as_spatial_half_area(const float lo[3], const float hi[3]);

/* Checks shared by the validators: TRIS holds META.triangle_count finite
 * entries with v0.w = their index, and every PRIM entry is inside TRIS. (A
 * reference to a zero-area triangle would be harmless: it is never hit.) */
as_error_t as_spatial_validate_tris(const as_structure_t *s, const char *name, const as_section_t *tris,
                                    const as_section_t *prims);

/* That META's node, leaf, empty-leaf and reference counts and depth are the
 * tree's, as a validator counted them. */
#ifdef AS_HAVE_CUDA
#include "trace_gpu.h"
/* A BIH, octree or grid's GPU validation: finds its sections (header_tag 0:
 * none), fills what they and META say, and runs `validate` over s->gpu. */
as_error_t as_spatial_validate_gpu(const as_structure_t *s, const char *name, uint32_t header_tag, uint32_t node_tag,
                                   as_error_t (*validate)(const as_gpu_resident_t *, const char *,
                                                          const as_gpu_spatial_expect_t *));
#endif
as_error_t as_spatial_validate_counts(const as_structure_t *s, const char *name, uint64_t inner, uint64_t leaves,
                                      uint64_t empty, uint64_t refs, uint32_t max_depth);

#endif
