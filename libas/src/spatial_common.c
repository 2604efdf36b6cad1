/* Shared parts of the BIH, octree and grid builders and validators. */
#include "spatial_common.h"

#include <math.h>
#include <stdio.h>
#include <string.h>

typedef struct tris_job {
    const as_mesh_t *mesh;
    as_tri4_t *tris;
} tris_job;

/* Blocks of 8,192 triangles (384 KB of TRIS) taken in turn: with blocks of
 * 65,536 a scene such as bunny (69,451) made two blocks, one of them nearly
 * the whole scene, on one thread. */
#define TRIS_BLOCK 8192

static void tris_block(void *user, size_t block)
{
    const tris_job *j = user;
    const uint32_t n = j->mesh->triangle_count, first = (uint32_t)(block * TRIS_BLOCK);
    const uint32_t end = n - first < TRIS_BLOCK ? n : first + TRIS_BLOCK;
    for (uint32_t i = first; i < end; ++i) as_spatial_tri4(j->mesh, i, &j->tris[i]);
}

void as_spatial_add_tris(as_structure_t *s, as_tri4_t *tris, uint32_t n)
{
    as_structure_add_kept_section(s, ASF_TAG_TRIS, tris, n, sizeof(as_tri4_t), sizeof(as_tri4_t) * (size_t)(n ? n : 1));
}

as_tri4_t *as_spatial_tris(const as_mesh_t *mesh, unsigned threads)
{
    const uint32_t n = mesh->triangle_count;
    as_tri4_t *tris = as_aligned_alloc(sizeof(as_tri4_t) * (size_t)(n ? n : 1), "TRIS triangles");
    if (!tris) return NULL;
    tris_job j = {mesh, tris};
    as_parallel_for(threads, ((size_t)n + TRIS_BLOCK - 1) / TRIS_BLOCK, tris_block, &j);
    return tris;
}

double as_spatial_half_area(const float lo[3], const float hi[3])
{
    const double dx = (double)hi[0] - lo[0], dy = (double)hi[1] - lo[1], dz = (double)hi[2] - lo[2];
    if (!(dx >= 0 && dy >= 0 && dz >= 0)) return 0.0;
    return dx * dy + dy * dz + dz * dx;
}

/* Akenine-Moller's test: the 13 separating axes (3 box normals, the
 * triangle normal, 9 edge cross products), triangle moved to the box
 * centre. */
static int axis_separates(double p0, double p1, double p2, double r)
{
    double mn = p0, mx = p0;
    if (p1 < mn) mn = p1;
    if (p1 > mx) mx = p1;
    if (p2 < mn) mn = p2;
    if (p2 > mx) mx = p2;
    return mn > r || mx < -r;
}

int as_tri_box_overlap(const float *a, const float *b, const float *c, const float lo[3], const float hi[3],
                       double pad)
{
    double ctr[3], h[3], v[3][3];
    for (int k = 0; k < 3; ++k) {
        ctr[k] = 0.5 * ((double)lo[k] + (double)hi[k]);
        h[k] = 0.5 * ((double)hi[k] - (double)lo[k]) + pad;
        v[0][k] = (double)a[k] - ctr[k];
        v[1][k] = (double)b[k] - ctr[k];
        v[2][k] = (double)c[k] - ctr[k];
    }
    /* Box normals: the triangle's box against the box. */
    for (int k = 0; k < 3; ++k)
        if (axis_separates(v[0][k], v[1][k], v[2][k], h[k])) return 0;
    double e[3][3];
    for (int k = 0; k < 3; ++k) {
        e[0][k] = v[1][k] - v[0][k];
        e[1][k] = v[2][k] - v[1][k];
        e[2][k] = v[0][k] - v[2][k];
    }
    /* The triangle's plane, before the edge axes: cells that the box of a
     * large triangle reaches but its plane misses are the common case. */
    {
        const double nx = e[0][1] * e[1][2] - e[0][2] * e[1][1];
        const double ny = e[0][2] * e[1][0] - e[0][0] * e[1][2];
        const double nz = e[0][0] * e[1][1] - e[0][1] * e[1][0];
        const double d = nx * v[0][0] + ny * v[0][1] + nz * v[0][2];
        const double r = h[0] * fabs(nx) + h[1] * fabs(ny) + h[2] * fabs(nz);
        if (fabs(d) > r * (1.0 + 1e-12) + 1e-300) return 0;
    }
    /* Edge x box-axis cross products. With finite walls every term is
     * finite, and the generic loop's product with the axis's zero
     * component adds a zero, which changes no sum: the two other terms, in
     * the loop's order, give the same doubles at a third of the work. An
     * infinite wall (a scene wider than FLT_MAX) makes that product NaN,
     * which passes every test; the loop keeps that. */
    if (isfinite(ctr[0]) && isfinite(ctr[1]) && isfinite(ctr[2]) && isfinite(h[0]) && isfinite(h[1]) && isfinite(h[2])) {
        for (int i = 0; i < 3; ++i) {
            const double ex = e[i][0], ey = e[i][1], ez = e[i][2];
            const double grow = 1.0 + 1e-12;
            /* k = 0: axis (0, -ez, ey) */
            if (axis_separates(-ez * v[0][1] + ey * v[0][2], -ez * v[1][1] + ey * v[1][2], -ez * v[2][1] + ey * v[2][2],
                               (h[1] * fabs(-ez) + h[2] * fabs(ey)) * grow + 1e-300))
                return 0;
            /* k = 1: axis (ez, 0, -ex) */
            if (axis_separates(ez * v[0][0] + -ex * v[0][2], ez * v[1][0] + -ex * v[1][2], ez * v[2][0] + -ex * v[2][2],
                               (h[0] * fabs(ez) + h[2] * fabs(-ex)) * grow + 1e-300))
                return 0;
            /* k = 2: axis (-ey, ex, 0) */
            if (axis_separates(-ey * v[0][0] + ex * v[0][1], -ey * v[1][0] + ex * v[1][1], -ey * v[2][0] + ex * v[2][1],
                               (h[0] * fabs(-ey) + h[1] * fabs(ex)) * grow + 1e-300))
                return 0;
        }
        return 1;
    }
    for (int i = 0; i < 3; ++i) {
        for (int k = 0; k < 3; ++k) {
            /* axis = unit_k x e_i */
            double ax[3] = {0, 0, 0};
            const int k1 = (k + 1) % 3, k2 = (k + 2) % 3;
            ax[k1] = -e[i][k2];
            ax[k2] = e[i][k1];
            const double p0 = ax[0] * v[0][0] + ax[1] * v[0][1] + ax[2] * v[0][2];
            const double p1 = ax[0] * v[1][0] + ax[1] * v[1][1] + ax[2] * v[1][2];
            const double p2 = ax[0] * v[2][0] + ax[1] * v[2][1] + ax[2] * v[2][2];
            const double r = h[0] * fabs(ax[0]) + h[1] * fabs(ax[1]) + h[2] * fabs(ax[2]);
            /* Grown by a relative hair: the products above round. */
            if (axis_separates(p0, p1, p2, r * (1.0 + 1e-12) + 1e-300)) return 0;
        }
    }
    return 1;
}

void as_spatial_meta(as_structure_t *s, const as_mesh_t *mesh, const as_build_args_t *args, uint32_t kind,
                     uint32_t layout, uint32_t layout_version, uint32_t builder)
{
    memset(&s->meta, 0, sizeof s->meta);
    snprintf(s->meta.writer, sizeof s->meta.writer, "libas");
    s->meta.writer_version = AS_VERSION_NUMBER;
    s->meta.structure_kind = kind;
    s->meta.layout = layout;
    s->meta.layout_version = layout_version;
    s->meta.builder = builder;
    s->meta.max_leaf_size = args->max_leaf_size;
    s->meta.cost_traversal = args->cost_traversal;
    s->meta.cost_intersection = args->cost_intersection;
    s->meta.triangle_count = mesh->triangle_count;
    s->meta.source_hash = mesh->hash;
    memcpy(s->meta.bounds_lo, mesh->bounds_lo, sizeof s->meta.bounds_lo);
    memcpy(s->meta.bounds_hi, mesh->bounds_hi, sizeof s->meta.bounds_hi);
}

as_error_t as_spatial_validate_tris(const as_structure_t *s, const char *name, const as_section_t *ts,
                                    const as_section_t *ps)
{
    const as_tri4_t *tris = ts->data;
    if (ts->count != s->meta.triangle_count)
        return as_set_error(AS_ERROR_INVALID_STRUCTURE, "%s: TRIS holds %llu triangles but META says the mesh has %u",
                            name, (unsigned long long)ts->count, s->meta.triangle_count);
    for (uint64_t i = 0; i < ts->count; ++i) {
        const as_tri4_t *t = &tris[i];
        const float f[9] = {t->v0.x, t->v0.y, t->v0.z, t->v1.x, t->v1.y, t->v1.z, t->v2.x, t->v2.y, t->v2.z};
        for (int k = 0; k < 9; ++k)
            if (!isfinite(f[k]))
                return as_set_error(AS_ERROR_INVALID_STRUCTURE, "%s: TRIS triangle %llu has a non-finite vertex", name,
                                    (unsigned long long)i);
        if (as_float_as_uint(t->v0.w) != (uint32_t)i)
            return as_set_error(AS_ERROR_INVALID_STRUCTURE, "%s: TRIS triangle %llu says it is source triangle %u",
                                name, (unsigned long long)i, as_float_as_uint(t->v0.w));
    }
    const uint32_t *prims = ps->data;
    for (uint64_t i = 0; i < ps->count; ++i)
        if (prims[i] >= ts->count)
            return as_set_error(AS_ERROR_INVALID_STRUCTURE, "%s: PRIM entry %llu refers to triangle %u of %llu", name,
                                (unsigned long long)i, prims[i], (unsigned long long)ts->count);
    return AS_OK;
}

as_error_t as_spatial_validate_counts(const as_structure_t *s, const char *name, uint64_t inner, uint64_t leaves,
                                      uint64_t empty, uint64_t refs, uint32_t max_depth)
{
    if (s->meta.node_count == inner && s->meta.leaf_count == leaves && s->meta.empty_leaf_count == empty &&
        s->meta.reference_count == refs && s->meta.max_depth == max_depth)
        return AS_OK;
    return as_set_error(AS_ERROR_INVALID_STRUCTURE,
                        "%s: META says %llu inner nodes, %llu leaves, %llu empty, %llu references, depth %u; the tree has "
                        "%llu, %llu, %llu, %llu, %u", name, (unsigned long long)s->meta.node_count,
                        (unsigned long long)s->meta.leaf_count, (unsigned long long)s->meta.empty_leaf_count,
                        (unsigned long long)s->meta.reference_count, s->meta.max_depth, (unsigned long long)inner,
                        (unsigned long long)leaves, (unsigned long long)empty, (unsigned long long)refs, max_depth);
}

#ifdef AS_HAVE_CUDA
as_error_t as_spatial_validate_gpu(const as_structure_t *s, const char *name, uint32_t header_tag, uint32_t node_tag,
                                   as_error_t (*validate)(const as_gpu_resident_t *, const char *,
                                                          const as_gpu_spatial_expect_t *))
{
    const as_section_t *hs = header_tag ? as_structure_find(s, header_tag) : NULL;
    const as_section_t *ns = as_structure_find(s, node_tag), *ps = as_structure_find(s, ASF_TAG_PRIM),
                       *ts = as_structure_find(s, ASF_TAG_TRIS);
    if ((header_tag && !hs) || !ns || !ps || !ts || !s->gpu)
        return as_set_error(AS_ERROR_INVALID_STRUCTURE, "%s: a section of the %s layout is missing", name,
                            as_structure_ops(s)->layout_name);
    as_gpu_spatial_expect_t e = {
        .header_count = hs ? hs->count : 0,
        .node_count = ns->count,
        .prim_count = ps->count,
        .tri_count = ts->count,
    };
    as_gpu_meta_expect(s, &e.meta);
    return validate(s->gpu, name, &e);
}
#endif
