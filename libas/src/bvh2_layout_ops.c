/* The BVH2 child-bounds layout: its sections, statistics, and the CPU and
 * GPU traversals (both run kernels/bvh2_traverse.h). */
#include "structure.h"
#include "bvh2_traverse.h"
#include "cwbvh_layout.h"
#include "trace_gpu.h"

#include <stdlib.h>
#include <string.h>

double as_bvh2_sah_from_sums(double ct, double ci, double root_area, double inner_area, double leaf_area_count,
                             uint64_t inner_count, uint64_t ref_count)
{
    if (!(root_area > 0)) return ct * (double)inner_count + ci * (double)ref_count;
    return (ct * inner_area + ci * leaf_area_count) / root_area;
}

/* One walk for the SAH cost and the statistics; the tree is valid (built or
 * validated), so the explicit stack never holds more than depth + 1. The
 * sums run in pre-order, left child first, in blocks (as_sah_sum), as the
 * builders' output walk (bvh_build_common.c) adds them, so both give the
 * same cost to the bit. */
static double bvh2_walk(const as_structure_t *s, as_structure_stats_t *st)
{
    const as_section_t *ns = as_structure_find(s, ASF_TAG_BVH2);
    const as_bvh2_node_t *nodes = ns->data;
    const double ci = s->meta.cost_intersection, ct = s->meta.cost_traversal;
    const double root_area = as_half_area6(s->meta.bounds_lo[0], s->meta.bounds_hi[0], s->meta.bounds_lo[1],
                                        s->meta.bounds_hi[1], s->meta.bounds_lo[2], s->meta.bounds_hi[2]);
    struct { int32_t node; uint32_t depth; double area; } stack[AS_BVH2_MAX_DEPTH + 2];
    int sp = 0;
    as_sah_sum inner_area = {0.0, 0.0, 0}, leaf_area_count = {0.0, 0.0, 0};
    uint64_t inner_count = 0, ref_count = 0;
    uint64_t depth_sum = 0;
    stack[sp].node = 0; stack[sp].depth = 0; stack[sp].area = root_area; ++sp;
    while (sp > 0) {
        --sp;
        const int32_t ni = stack[sp].node;
        const uint32_t depth = stack[sp].depth;
        const as_bvh2_node_t *n = &nodes[ni];
        as_sah_sum_add(&inner_area, stack[sp].area);
        inner_count++;
        const double ca[2] = {as_half_area6(n->xy0.x, n->xy0.y, n->xy0.z, n->xy0.w, n->z01.x, n->z01.y),
                              as_half_area6(n->xy1.x, n->xy1.y, n->xy1.z, n->xy1.w, n->z01.z, n->z01.w)};
        for (int k = 0; k < 2; ++k) {
            if (n->child[k] >= 0) continue;
            as_sah_sum_add(&leaf_area_count, ca[k] * n->count[k]);
            ref_count += n->count[k];
            if (!st || n->count[k] == 0) continue; /* the empty sibling of a one-leaf tree */
            st->leaf_count++;
            if (depth + 1 > st->max_depth) st->max_depth = depth + 1;
            depth_sum += depth + 1;
            st->depth_histogram[depth + 1 < AS_HISTOGRAM_BINS ? depth + 1 : AS_HISTOGRAM_BINS - 1]++;
            st->leaf_size_histogram[n->count[k] < AS_HISTOGRAM_BINS ? n->count[k] : AS_HISTOGRAM_BINS - 1]++;
        }
        /* Right child pushed first, so the left one is walked first. */
        for (int k = 1; k >= 0; --k) {
            if (n->child[k] < 0 || sp >= AS_BVH2_MAX_DEPTH + 2) continue;
            stack[sp].node = n->child[k]; stack[sp].depth = depth + 1; stack[sp].area = ca[k]; ++sp;
        }
    }
    if (st) st->average_leaf_depth = st->leaf_count ? (double)depth_sum / (double)st->leaf_count : 0.0;
    return as_bvh2_sah_from_sums(ct, ci, root_area, as_sah_sum_value(&inner_area), as_sah_sum_value(&leaf_area_count),
                                 inner_count, ref_count);
}

double as_bvh2_sah_cost(const as_structure_t *s) { return bvh2_walk(s, NULL); }

static void bvh2_stats(const as_structure_t *s, as_structure_stats_t *st)
{
    st->node_count = as_structure_find(s, ASF_TAG_BVH2)->count;
    st->sah_cost = bvh2_walk(s, st);
}

static void bvh2_trace_cpu(const as_structure_t *s, const as_ray_t *rays, as_hit_t *hits, size_t count, int any_hit,
                           int ray_flags, as_cpu_stats_t *stats)
{
    const as_section_t *ns = as_structure_find(s, ASF_TAG_BVH2), *ts = as_structure_find(s, ASF_TAG_TRI4);
    AS_TRACE_CPU_LOOP(ns->count > 0,
                      as_bvh2_trace(ns->data, ts->data, &pre, any_hit, &h, ctrp));
}

static as_error_t bvh2_convert(const as_structure_t *src, uint32_t target, as_structure_t *dst)
{
    if (target == AS_LAYOUT_BVH2_OWN_BOUNDS) return as_bvh2_to_own_bounds(src, dst);
    if (target == AS_LAYOUT_BVH_CWBVH) return as_bvh2_to_cwbvh(src, AS_CWBVH_MAX_LEAF, dst);
    if (target == AS_LAYOUT_BVH2_CHILD_BOUNDS) {
        /* Same layout: a copy. */
        const as_section_t *ns = as_structure_find(src, ASF_TAG_BVH2), *ts = as_structure_find(src, ASF_TAG_TRI4);
        void *n = as_aligned_alloc(ns->bytes ? ns->bytes : 1, "BVH2 nodes");
        void *t = as_aligned_alloc(ts->bytes ? ts->bytes : 1, "TRI4 triangles");
        if (!n || !t) { free(n); free(t); return as_get_error(); }
        memcpy(n, ns->data, ns->bytes);
        if (ts->bytes) memcpy(t, ts->data, ts->bytes);
        dst->meta = src->meta;
        as_structure_add_section(dst, ASF_TAG_BVH2, n, ns->count, sizeof(as_bvh2_node_t));
        as_structure_add_section(dst, ASF_TAG_TRI4, t, ts->count, sizeof(as_tri4_t));
        return AS_OK;
    }
    return as_set_error(AS_ERROR_UNSUPPORTED, "a BVH2 converts only to bvh2-child-bounds, bvh2-own-bounds or cwbvh");
}


const as_layout_ops_t as_layout_bvh2_child_bounds = {
    .structure_kind = AS_STRUCT_BVH,
    .layout = AS_LAYOUT_BVH2_CHILD_BOUNDS,
    .layout_version = AS_BVH2_LAYOUT_VERSION,
    .kind_name = "bvh",
    .layout_name = "bvh2-child-bounds",
    .section_count = 2,
    .sections = {
        {ASF_TAG_BVH2, sizeof(as_bvh2_node_t), "BVH nodes with both children's boxes, read by the traversal"},
        {ASF_TAG_TRI4, sizeof(as_tri4_t), "triangle vertices in leaf order with source indices, read by the traversal"},
    },
    .validate = as_bvh2_validate,
    .stats = bvh2_stats,
    .trace_cpu = bvh2_trace_cpu,
    .convert = bvh2_convert,
#ifdef AS_HAVE_CUDA
    .trace_gpu = as_layout_trace_gpu,
    .validate_gpu = as_bvh2_validate_gpu,
#endif
};
