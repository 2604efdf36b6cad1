/* The octree layout: its sections, statistics and SAH cost, and the CPU
 * traversal (kernels/octree_traverse.h; the GPU launcher comes later).
 *
 * SAH cost of an octree: sum over inner nodes of C_t A(cell) / A(root) plus
 * over leaves of C_i count A(cell) / A(root), cells being the cubes of the
 * subdivision (the root cube is the OCTH header's). */
#include "spatial_common.h"
#include "octree_traverse.h"

#include <stdlib.h>
#include <string.h>

double as_octree_sah_cost(const as_structure_t *s, as_structure_stats_t *st)
{
    const as_section_t *ns = as_structure_find(s, ASF_TAG_OCTN);
    const as_octree_node_t *nodes = ns->data;
    const double ci = s->meta.cost_intersection, ct = s->meta.cost_traversal;
    /* Breadth-first numbering: a node's depth is its parent's plus one, and
     * parents come first. */
    uint8_t *depth = calloc(ns->count ? ns->count : 1, 1);
    if (!depth) return 0.0;
    double sah = 0.0;
    uint64_t depth_sum = 0;
    for (uint64_t i = 0; i < ns->count; ++i) {
        const double rel = 1.0 / (double)(1ull << (2 * depth[i])); /* area ratio of a cube 2^-d as wide */
        if (nodes[i].count == AS_OCTREE_INNER) {
            sah += ct * rel;
            for (uint32_t c = 0; c < 8; ++c) depth[nodes[i].first + c] = (uint8_t)(depth[i] + 1);
            continue;
        }
        sah += ci * nodes[i].count * rel;
        if (!st || nodes[i].count == 0) continue;
        st->leaf_count++;
        if (depth[i] > st->max_depth) st->max_depth = depth[i];
        depth_sum += depth[i];
        st->depth_histogram[depth[i] < AS_HISTOGRAM_BINS ? depth[i] : AS_HISTOGRAM_BINS - 1]++;
        st->leaf_size_histogram[nodes[i].count < AS_HISTOGRAM_BINS ? nodes[i].count : AS_HISTOGRAM_BINS - 1]++;
    }
    free(depth);
    if (st) st->average_leaf_depth = st->leaf_count ? (double)depth_sum / (double)st->leaf_count : 0.0;
    return sah;
}

static void octree_stats(const as_structure_t *s, as_structure_stats_t *st)
{
    st->node_count = s->meta.node_count;
    st->sah_cost = as_octree_sah_cost(s, st);
}

static void octree_trace_cpu(const as_structure_t *s, const as_ray_t *rays, as_hit_t *hits, size_t count, int any_hit,
                           int ray_flags, as_cpu_stats_t *stats)
{
    const as_section_t *hs = as_structure_find(s, ASF_TAG_OCTH), *ns = as_structure_find(s, ASF_TAG_OCTN),
                       *ps = as_structure_find(s, ASF_TAG_PRIM), *ts = as_structure_find(s, ASF_TAG_TRIS);
    AS_TRACE_CPU_LOOP(hs->count == 1 && ns->count > 0,
                      as_octree_trace(hs->data, ns->data, ps->data, ts->data, &pre, any_hit, &h, ctrp));
}

const as_layout_ops_t as_layout_octree = {
    .structure_kind = AS_STRUCT_OCTREE,
    .layout = AS_LAYOUT_OCTREE,
    .layout_version = AS_OCTREE_LAYOUT_VERSION,
    .kind_name = "octree",
    .layout_name = "octree",
    .section_count = 4,
    .sections = {
        {ASF_TAG_OCTH, sizeof(as_octree_header_t), "the root cube, read by the traversal"},
        {ASF_TAG_OCTN, sizeof(as_octree_node_t), "octree nodes: first of 8 children or leaf range, read by the traversal"},
        {ASF_TAG_PRIM, sizeof(uint32_t), "leaf triangle lists (source indices into TRIS), read by the traversal"},
        {ASF_TAG_TRIS, sizeof(as_tri4_t), "triangle vertices in source order, read by the traversal"},
    },
    .validate = as_octree_validate,
    .stats = octree_stats,
    .trace_cpu = octree_trace_cpu,
#ifdef AS_HAVE_CUDA
    .trace_gpu = as_layout_trace_gpu,
    .validate_gpu = as_octree_validate_gpu,
#endif
};
