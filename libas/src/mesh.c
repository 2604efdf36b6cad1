/* Meshes: creation from caller arrays, validation, accessors. */
#include "mesh.h"

#include "as_internal.h"

#include <float.h>
#include <math.h>
#include <stdlib.h>
#include <string.h>

static int triangle_has_no_normal(const as_mesh_t *mesh, uint32_t i)
{
    const uint32_t *t = mesh->indices + (size_t)i * 3;
    if (t[0] == t[1] || t[1] == t[2] || t[0] == t[2]) return 1;
    const float *a = mesh->positions + (size_t)t[0] * 3;
    const float *b = mesh->positions + (size_t)t[1] * 3;
    const float *c = mesh->positions + (size_t)t[2] * 3;
    const float e1[3] = {b[0] - a[0], b[1] - a[1], b[2] - a[2]};
    const float e2[3] = {c[0] - a[0], c[1] - a[1], c[2] - a[2]};
    /* Exactly the float cross product the triangle test computes (no FMA:
     * the library is built with -ffp-contract=off), so "degenerate" here
     * means "has no normal there", not "small". */
    const float n[3] = {e1[1] * e2[2] - e1[2] * e2[1],
                        e1[2] * e2[0] - e1[0] * e2[2],
                        e1[0] * e2[1] - e1[1] * e2[0]};
    return n[0] == 0.0f && n[1] == 0.0f && n[2] == 0.0f;
}

int as_mesh_triangle_is_degenerate(const as_mesh_t *mesh, uint32_t i)
{
    if (mesh->degenerate_bits) return (int)(mesh->degenerate_bits[i >> 6] >> (i & 63)) & 1;
    return triangle_has_no_normal(mesh, i);
}

uint32_t as_mesh_degenerate_in_range(const as_mesh_t *mesh, uint32_t first, uint32_t end)
{
    if (first >= end) return 0;
    if (!mesh->degenerate_bits) {
        uint32_t n = 0;
        for (uint32_t i = first; i < end; ++i) n += (uint32_t)triangle_has_no_normal(mesh, i);
        return n;
    }
    if (!mesh->degenerate_count) return 0;
    const uint64_t *w = mesh->degenerate_bits;
    const uint32_t w0 = first >> 6, w1 = (end - 1) >> 6;
    const uint64_t head = ~(uint64_t)0 << (first & 63), tail = ~(uint64_t)0 >> (63 - ((end - 1) & 63));
    if (w0 == w1) return (uint32_t)as_popcount64(w[w0] & head & tail);
    uint32_t n = (uint32_t)as_popcount64(w[w0] & head) + (uint32_t)as_popcount64(w[w1] & tail);
    for (uint32_t k = w0 + 1; k < w1; ++k) n += (uint32_t)as_popcount64(w[k]);
    return n;
}

as_error_t as_mesh_finish(as_mesh_t *mesh, const char *name)
{
    if (mesh->triangle_count == 0)
        return as_set_error(AS_ERROR_INVALID_MESH, "%s: no triangles", name);

    const float *p = mesh->positions;
    for (uint32_t v = 0; v < mesh->vertex_count; ++v, p += 3) {
        if (!isfinite(p[0]) || !isfinite(p[1]) || !isfinite(p[2]))
            return as_set_error(AS_ERROR_INVALID_MESH,
                                "%s: vertex %u has a non-finite coordinate (%g, %g, %g)", name, v,
                                (double)p[0], (double)p[1], (double)p[2]);
    }

    const uint32_t *idx = mesh->indices;
    for (uint32_t t = 0; t < mesh->triangle_count; ++t) {
        for (int c = 0; c < 3; ++c) {
            const uint32_t v = idx[(size_t)t * 3 + c];
            if (v >= mesh->vertex_count)
                return as_set_error(AS_ERROR_INVALID_MESH,
                                    "%s: triangle %u refers to vertex %u but the mesh has %u "
                                    "vertices",
                                    name, t, v, mesh->vertex_count);
        }
    }

    /* Bounds of what the triangles use: an unreferenced stray vertex must not
     * move the default camera or the root box. */
    float lo[3] = {FLT_MAX, FLT_MAX, FLT_MAX}, hi[3] = {-FLT_MAX, -FLT_MAX, -FLT_MAX};
    uint32_t degenerate = 0;
    /* One bit per triangle, so that every build skips zero-area triangles
     * without reading their vertices again. */
    free(mesh->degenerate_bits);
    mesh->degenerate_bits = as_calloc(((size_t)mesh->triangle_count + 63) / 64, sizeof(uint64_t), "mesh degenerate bits");
    if (!mesh->degenerate_bits) return as_get_error();
    for (uint32_t t = 0; t < mesh->triangle_count; ++t) {
        for (int c = 0; c < 3; ++c) {
            const float *q = mesh->positions + (size_t)idx[(size_t)t * 3 + c] * 3;
            for (int k = 0; k < 3; ++k) {
                if (q[k] < lo[k]) lo[k] = q[k];
                if (q[k] > hi[k]) hi[k] = q[k];
            }
        }
        if (triangle_has_no_normal(mesh, t)) {
            mesh->degenerate_bits[t >> 6] |= (uint64_t)1 << (t & 63);
            degenerate++;
        }
    }
    memcpy(mesh->bounds_lo, lo, sizeof lo);
    memcpy(mesh->bounds_hi, hi, sizeof hi);
    mesh->degenerate_count = degenerate;

    uint64_t h = as_hash64_seeded(mesh->positions, (size_t)mesh->vertex_count * 3 * sizeof(float), 0);
    h = as_hash64_seeded(mesh->indices, (size_t)mesh->triangle_count * 3 * sizeof(uint32_t), h);
    mesh->hash = h;
    return AS_OK;
}

as_mesh_t *as_mesh_create(uint32_t vertex_count, const float *positions,
                          uint32_t triangle_count, const uint32_t *indices)
{
    if ((vertex_count && !positions) || (triangle_count && !indices)) {
        as_set_error(AS_ERROR_INVALID_ARGUMENT, "as_mesh_create: %s is NULL",
                     vertex_count && !positions ? "positions" : "indices");
        return NULL;
    }
    as_mesh_t *mesh = as_calloc(1, sizeof *mesh, "mesh");
    if (!mesh) return NULL;
    const size_t pos_bytes = (size_t)vertex_count * 3 * sizeof(float);
    const size_t idx_bytes = (size_t)triangle_count * 3 * sizeof(uint32_t);
    /* +1: an empty mesh still gets a distinct allocation, and is then
     * rejected by as_mesh_finish with the usual message. */
    mesh->positions = as_malloc(pos_bytes + 1, "mesh positions");
    mesh->indices = as_malloc(idx_bytes + 1, "mesh indices");
    if (!mesh->positions || !mesh->indices) {
        as_mesh_release(mesh);
        return NULL;
    }
    if (pos_bytes) memcpy(mesh->positions, positions, pos_bytes);
    if (idx_bytes) memcpy(mesh->indices, indices, idx_bytes);
    mesh->vertex_count = vertex_count;
    mesh->triangle_count = triangle_count;
    mesh->faces_in_file = triangle_count;
    if (as_mesh_finish(mesh, "as_mesh_create") != AS_OK) {
        as_mesh_release(mesh);
        return NULL;
    }
    return mesh;
}

void as_mesh_release(as_mesh_t *mesh)
{
    if (!mesh) return;
    free(mesh->positions);
    free(mesh->indices);
    free(mesh->normals);
    free(mesh->uvs);
    free(mesh->material_ids);
    free(mesh->degenerate_bits);
    free(mesh);
}

void as_mesh_get_info(const as_mesh_t *mesh, as_mesh_info_t *info)
{
    memset(info, 0, sizeof *info);
    if (!mesh) return;
    info->vertex_count = mesh->vertex_count;
    info->triangle_count = mesh->triangle_count;
    info->faces_in_file = mesh->faces_in_file;
    info->polygon_faces = mesh->polygon_faces;
    info->degenerate_count = mesh->degenerate_count;
    info->has_normals = mesh->normals != NULL;
    info->has_uvs = mesh->uvs != NULL;
    info->has_materials = mesh->material_ids != NULL;
    memcpy(info->bounds_lo, mesh->bounds_lo, sizeof info->bounds_lo);
    memcpy(info->bounds_hi, mesh->bounds_hi, sizeof info->bounds_hi);
    info->hash = mesh->hash;
}

const float *as_mesh_positions(const as_mesh_t *mesh) { return mesh ? mesh->positions : NULL; }
const uint32_t *as_mesh_indices(const as_mesh_t *mesh) { return mesh ? mesh->indices : NULL; }
const float *as_mesh_normals(const as_mesh_t *mesh) { return mesh ? mesh->normals : NULL; }
const float *as_mesh_uvs(const as_mesh_t *mesh) { return mesh ? mesh->uvs : NULL; }
const uint32_t *as_mesh_material_ids(const as_mesh_t *mesh)
{
    return mesh ? mesh->material_ids : NULL;
}
