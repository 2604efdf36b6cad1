/* The BIH layout: its sections, statistics and SAH cost, and the CPU
 * traversal (kernels/bih_traverse.h; the GPU launcher comes later).
 *
 * SAH cost of a BIH: the expected cost of a ray through the scene box,
 * sum over inner nodes of C_t A(node) / A(root) plus over leaves of
 * C_i count A(leaf) / A(root), where a node's box is its parent's with the
 * split axis clipped to the node's plane (left: upper bound clip[0], right:
 * lower bound clip[1]) and the root's box is the scene box. */
#include "spatial_common.h"
#include "bih_traverse.h"

#include <string.h>

typedef struct bih_walk_entry {
    uint32_t node, depth;
    float lo[3], hi[3];
} bih_walk_entry;

double as_bih_sah_cost(const as_structure_t *s, as_structure_stats_t *st)
{
    const as_section_t *ns = as_structure_find(s, ASF_TAG_BIHN);
    const as_bih_node_t *nodes = ns->data;
    const double ci = s->meta.cost_intersection, ct = s->meta.cost_traversal;
    const double root_area = as_spatial_half_area(s->meta.bounds_lo, s->meta.bounds_hi);
    bih_walk_entry stack[AS_BIH_MAX_DEPTH + 2];
    int sp = 0;
    as_sah_sum sah = {0.0, 0.0, 0}; /* node by node in pre-order, as the builder adds them */
    uint64_t depth_sum = 0;
    stack[0].node = 0;
    stack[0].depth = 0;
    memcpy(stack[0].lo, s->meta.bounds_lo, sizeof stack[0].lo);
    memcpy(stack[0].hi, s->meta.bounds_hi, sizeof stack[0].hi);
    sp = 1;
    while (sp > 0) {
        const bih_walk_entry e = stack[--sp];
        const as_bih_node_t *n = &nodes[e.node];
        const double rel = root_area > 0 ? as_spatial_half_area(e.lo, e.hi) / root_area : 1.0;
        const uint32_t axis = n->info & 3u;
        if (axis == AS_BIH_LEAF) {
            const uint32_t count = as_float_as_uint(n->clip[0]);
            as_sah_sum_add(&sah, ci * count * rel);
            if (!st || count == 0) continue;
            st->leaf_count++;
            if (e.depth > st->max_depth) st->max_depth = e.depth;
            depth_sum += e.depth;
            st->depth_histogram[e.depth < AS_HISTOGRAM_BINS ? e.depth : AS_HISTOGRAM_BINS - 1]++;
            st->leaf_size_histogram[count < AS_HISTOGRAM_BINS ? count : AS_HISTOGRAM_BINS - 1]++;
            continue;
        }
        as_sah_sum_add(&sah, ct * rel);
        if (sp + 2 > AS_BIH_MAX_DEPTH + 2) continue; /* validated trees never get here */
        bih_walk_entry l = e, r = e;
        l.node = n->info >> 2;
        r.node = l.node + 1;
        l.depth = r.depth = e.depth + 1;
        if (n->clip[0] < l.hi[axis]) l.hi[axis] = n->clip[0];
        if (n->clip[1] > r.lo[axis]) r.lo[axis] = n->clip[1];
        stack[sp++] = r;
        stack[sp++] = l;
    }
    if (st) st->average_leaf_depth = st->leaf_count ? (double)depth_sum / (double)st->leaf_count : 0.0;
    return as_sah_sum_value(&sah);
}

static void bih_stats(const as_structure_t *s, as_structure_stats_t *st)
{
    st->node_count = s->meta.node_count;
    st->sah_cost = as_bih_sah_cost(s, st);
}

static void bih_trace_cpu(const as_structure_t *s, const as_ray_t *rays, as_hit_t *hits, size_t count, int any_hit,
                           int ray_flags, as_cpu_stats_t *stats)
{
    const as_section_t *ns = as_structure_find(s, ASF_TAG_BIHN), *ps = as_structure_find(s, ASF_TAG_PRIM),
                       *ts = as_structure_find(s, ASF_TAG_TRIS);
    AS_TRACE_CPU_LOOP(ns->count > 0,
                      as_bih_trace(ns->data, ps->data, ts->data, s->meta.bounds_lo, s->meta.bounds_hi, &pre, any_hit,
                                   &h, ctrp));
}

const as_layout_ops_t as_layout_bih = {
    .structure_kind = AS_STRUCT_BIH,
    .layout = AS_LAYOUT_BIH,
    .layout_version = AS_BIH_LAYOUT_VERSION,
    .kind_name = "bih",
    .layout_name = "bih",
    .section_count = 3,
    .sections = {
        {ASF_TAG_BIHN, sizeof(as_bih_node_t), "BIH nodes: two clip planes, axis and child or leaf range, read by the traversal"},
        {ASF_TAG_PRIM, sizeof(uint32_t), "leaf triangle lists (source indices into TRIS), read by the traversal"},
        {ASF_TAG_TRIS, sizeof(as_tri4_t), "triangle vertices in source order, read by the traversal"},
    },
    .validate = as_bih_validate,
    .stats = bih_stats,
    .trace_cpu = bih_trace_cpu,
#ifdef AS_HAVE_CUDA
    .trace_gpu = as_layout_trace_gpu,
    .validate_gpu = as_bih_validate_gpu,
#endif
};
