/* The compressed wide BVH layout: its sections, statistics, and the CPU
 * and GPU traversals (both run kernels/cwbvh_traverse.h). It is made from a BVH2 (build with
 * --layout cwbvh, or as_structure_convert), never converted back: the
 * quantized boxes are not the binary tree's. */
#include "structure.h"
#include "cwbvh_traverse.h"

#include <stdlib.h>
#include <string.h>

/* Slot s's box as the traversal decodes it. */
static void slot_box(const as_cwbvh_node_t *n, int s, float lo[3], float hi[3])
{
    for (int a = 0; a < 3; ++a) {
        const float scale = as_cwbvh_scale(n->e[a]);
        lo[a] = as_cwbvh_decode(n->p[a], scale, n->qlo[a][s]);
        hi[a] = as_cwbvh_decode(n->p[a], scale, n->qhi[a][s]);
    }
}

/* SAH cost and statistics over the boxes the traversal tests: the root
 * counts cost_traversal, every other inner node cost_traversal times its
 * decoded box's area, every leaf cost_intersection times its size times
 * its area, areas relative to the scene box of META. */
static double cwbvh_walk(const as_structure_t *s, as_structure_stats_t *st)
{
    const as_cwbvh_node_t *nodes = as_structure_find(s, ASF_TAG_CWBV)->data;
    const double ci = s->meta.cost_intersection, ct = s->meta.cost_traversal;
    const double root_area = as_half_area6(s->meta.bounds_lo[0], s->meta.bounds_hi[0], s->meta.bounds_lo[1],
                                           s->meta.bounds_hi[1], s->meta.bounds_lo[2], s->meta.bounds_hi[2]);
    struct { uint32_t node, depth; } stack[8 * (AS_CWBVH_MAX_DEPTH + 2)];
    int sp = 0;
    double inner_area = root_area, leaf_area_count = 0.0;
    uint64_t depth_sum = 0;
    stack[sp].node = 0; stack[sp].depth = 0; ++sp;
    while (sp > 0) {
        --sp;
        const as_cwbvh_node_t *n = &nodes[stack[sp].node];
        const uint32_t depth = stack[sp].depth;
        uint32_t inner = 0;
        for (int k = 0; k < 8; ++k) {
            const uint32_t meta = n->meta[k];
            if (meta == 0) continue;
            float lo[3], hi[3];
            slot_box(n, k, lo, hi);
            const double a = as_half_area6(lo[0], hi[0], lo[1], hi[1], lo[2], hi[2]);
            if (as_cwbvh_meta_is_inner(meta)) {
                inner_area += a;
                if (sp < (int)(sizeof stack / sizeof stack[0])) {
                    stack[sp].node = n->child_base + inner; stack[sp].depth = depth + 1; ++sp;
                }
                ++inner;
                continue;
            }
            const uint32_t count = as_cwbvh_meta_count(meta);
            leaf_area_count += a * count;
            if (!st) continue;
            st->leaf_count++;
            if (depth + 1 > st->max_depth) st->max_depth = depth + 1;
            depth_sum += depth + 1;
            st->depth_histogram[depth + 1 < AS_HISTOGRAM_BINS ? depth + 1 : AS_HISTOGRAM_BINS - 1]++;
            st->leaf_size_histogram[count]++;
        }
    }
    if (st) st->average_leaf_depth = st->leaf_count ? (double)depth_sum / (double)st->leaf_count : 0.0;
    if (!(root_area > 0))
        return ct * (double)as_structure_find(s, ASF_TAG_CWBV)->count + ci * (double)s->meta.reference_count;
    return (ct * inner_area + ci * leaf_area_count) / root_area;
}

double as_cwbvh_sah_cost(const as_structure_t *s) { return cwbvh_walk(s, NULL); }

static void cwbvh_stats(const as_structure_t *s, as_structure_stats_t *st)
{
    st->node_count = as_structure_find(s, ASF_TAG_CWBV)->count;
    st->sah_cost = cwbvh_walk(s, st);
}

static void cwbvh_trace_cpu(const as_structure_t *s, const as_ray_t *rays, as_hit_t *hits, size_t count, int any_hit,
                            int ray_flags, as_cpu_stats_t *stats)
{
    const as_section_t *ns = as_structure_find(s, ASF_TAG_CWBV), *ts = as_structure_find(s, ASF_TAG_TRI4);
    AS_TRACE_CPU_LOOP(ns->count > 0,
                      as_cwbvh_trace(ns->data, ts->data, &pre, any_hit, &h, ctrp));
}

static as_error_t cwbvh_convert(const as_structure_t *src, uint32_t target, as_structure_t *dst)
{
    if (target != AS_LAYOUT_BVH_CWBVH)
        return as_set_error(AS_ERROR_UNSUPPORTED, "a compressed wide BVH converts to no other layout (its boxes are "
                            "quantized): build the BVH2 again");
    const as_section_t *ns = as_structure_find(src, ASF_TAG_CWBV), *ts = as_structure_find(src, ASF_TAG_TRI4);
    void *n = as_aligned_alloc(ns->bytes ? ns->bytes : 1, "CWBV nodes");
    void *t = as_aligned_alloc(ts->bytes ? ts->bytes : 1, "TRI4 triangles");
    if (!n || !t) { free(n); free(t); return as_get_error(); }
    memcpy(n, ns->data, ns->bytes);
    if (ts->bytes) memcpy(t, ts->data, ts->bytes);
    dst->meta = src->meta;
    as_structure_add_section(dst, ASF_TAG_CWBV, n, ns->count, sizeof(as_cwbvh_node_t));
    as_structure_add_section(dst, ASF_TAG_TRI4, t, ts->count, sizeof(as_tri4_t));
    return AS_OK;
}

const as_layout_ops_t as_layout_cwbvh = {
    .structure_kind = AS_STRUCT_BVH,
    .layout = AS_LAYOUT_BVH_CWBVH,
    .layout_version = AS_CWBVH_LAYOUT_VERSION,
    .kind_name = "bvh",
    .layout_name = "cwbvh",
    .section_count = 2,
    .sections = {
        {ASF_TAG_CWBV, sizeof(as_cwbvh_node_t), "8-wide BVH nodes with quantized child boxes, read by the traversal"},
        {ASF_TAG_TRI4, sizeof(as_tri4_t), "triangle vertices in leaf order with source indices, read by the traversal"},
    },
    .validate = as_cwbvh_validate,
    .stats = cwbvh_stats,
    .trace_cpu = cwbvh_trace_cpu,
    .convert = cwbvh_convert,
#ifdef AS_HAVE_CUDA
    .trace_gpu = as_layout_trace_gpu,
    .validate_gpu = as_cwbvh_validate_gpu,
#endif
};
