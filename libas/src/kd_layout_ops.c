/* The KD layouts, kd-standard and kd-ropes: sections, statistics, SAH cost,
 * conversion between the two, and the CPU traversals
 * (kernels/kd_traverse.h, kernels/kd_ropes_traverse.h).
 *
 * SAH cost of a stored KD tree: with A the surface area of a node's box
 * (boxes follow from the scene box in META and the split planes),
 * sum over inner nodes of C_t A / A_root plus sum over leaves of
 * C_i n A / A_root, n the leaf's references (a triangle in several leaves
 * counts in each). When the root box has no area the ratios are 1. */
#include "structure.h"
#include "kd_ropes_traverse.h"

#include <stdlib.h>
#include <string.h>

void as_kd_compute_ropes(const as_kd_node_t *nodes, uint64_t node_count, uint64_t leaf_count, const float lo[3],
                         const float hi[3], as_kd_ropes_t *ropes, as_kd_leaf_box_t *boxes);

static double half_area(const float b[6])
{
    const double dx = (double)b[3] - b[0], dy = (double)b[4] - b[1], dz = (double)b[5] - b[2];
    return dx * dy + dy * dz + dz * dx;
}

/* One walk for the SAH cost and the statistics; the tree is valid (built or
 * validated), so depth stays within AS_KD_MAX_DEPTH. */
static double kd_walk(const as_structure_t *s, as_structure_stats_t *st)
{
    const as_kd_node_t *nodes = as_structure_find(s, ASF_TAG_KDN8)->data;
    const uint32_t *prim = as_structure_find(s, ASF_TAG_PRIM)->data;
    const double ci = s->meta.cost_intersection, ct = s->meta.cost_traversal;
    struct { uint32_t node, depth; float box[6]; } stack[AS_KD_MAX_DEPTH + 2];
    int sp = 1;
    stack[0].node = 0;
    stack[0].depth = 0;
    memcpy(stack[0].box, s->meta.bounds_lo, sizeof(float) * 3);
    memcpy(stack[0].box + 3, s->meta.bounds_hi, sizeof(float) * 3);
    const double root_area = half_area(stack[0].box);
    as_sah_sum sah = {0.0, 0.0, 0}; /* node by node in pre-order, as the builder adds them */
    uint64_t depth_sum = 0, leaves = 0;
    while (sp > 0) {
        --sp;
        const uint32_t ni = stack[sp].node, depth = stack[sp].depth;
        float box[6];
        memcpy(box, stack[sp].box, sizeof box);
        const double ratio = root_area > 0 ? half_area(box) / root_area : 1.0;
        const as_kd_node_t n = nodes[ni];
        if (as_kd_is_leaf(n.word1)) {
            const uint32_t cnt = prim[n.word0];
            as_sah_sum_add(&sah, ci * cnt * ratio);
            if (!st) continue;
            if (depth > st->max_depth) st->max_depth = depth;
            if (cnt == 0) continue;
            ++leaves;
            depth_sum += depth;
            st->depth_histogram[depth < AS_HISTOGRAM_BINS ? depth : AS_HISTOGRAM_BINS - 1]++;
            st->leaf_size_histogram[cnt < AS_HISTOGRAM_BINS ? cnt : AS_HISTOGRAM_BINS - 1]++;
            continue;
        }
        as_sah_sum_add(&sah, ct * ratio);
        const int axis = (int)(n.word1 & 3u);
        const float split = as_uint_as_float(n.word0);
        if (sp + 2 > AS_KD_MAX_DEPTH + 2) continue;
        stack[sp].node = n.word1 >> 2;
        stack[sp].depth = depth + 1;
        memcpy(stack[sp].box, box, sizeof box);
        stack[sp].box[axis] = split;
        ++sp;
        stack[sp].node = ni + 1;
        stack[sp].depth = depth + 1;
        memcpy(stack[sp].box, box, sizeof box);
        stack[sp].box[axis + 3] = split;
        ++sp;
    }
    if (st) {
        st->leaf_count = leaves;
        st->average_leaf_depth = leaves ? (double)depth_sum / (double)leaves : 0.0;
    }
    return as_sah_sum_value(&sah);
}

double as_kd_sah_cost(const as_structure_t *s) { return kd_walk(s, NULL); }

static void kd_stats(const as_structure_t *s, as_structure_stats_t *st)
{
    st->node_count = s->meta.node_count;
    st->sah_cost = kd_walk(s, st);
}

static void scene_box(const as_structure_t *s, float box[6])
{
    memcpy(box, s->meta.bounds_lo, sizeof(float) * 3);
    memcpy(box + 3, s->meta.bounds_hi, sizeof(float) * 3);
}

static void kd_trace_cpu(const as_structure_t *s, const as_ray_t *rays, as_hit_t *hits, size_t count, int any_hit,
                         int ray_flags, as_cpu_stats_t *stats)
{
    const as_section_t *ns = as_structure_find(s, ASF_TAG_KDN8), *ps = as_structure_find(s, ASF_TAG_PRIM),
                       *ts = as_structure_find(s, ASF_TAG_TRIS);
    float box[6];
    scene_box(s, box);
    AS_TRACE_CPU_LOOP(ns->count > 0,
                      as_kd_trace(ns->data, ps->data, ts->data, box, &pre, any_hit, &h, ctrp));
}

static void kd_ropes_trace_cpu(const as_structure_t *s, const as_ray_t *rays, as_hit_t *hits, size_t count,
                               int any_hit, int ray_flags, as_cpu_stats_t *stats)
{
    const as_section_t *ns = as_structure_find(s, ASF_TAG_KDN8), *ps = as_structure_find(s, ASF_TAG_PRIM),
                       *ts = as_structure_find(s, ASF_TAG_TRIS), *rs = as_structure_find(s, ASF_TAG_KDRP),
                       *bs = as_structure_find(s, ASF_TAG_KDLB);
    float box[6];
    scene_box(s, box);
    AS_TRACE_CPU_LOOP(ns->count > 0,
                      as_kd_ropes_trace(ns->data, ps->data, ts->data, rs->data, bs->data, (uint32_t)rs->count, box,
                                        &pre, any_hit, &h, ctrp));
}

/* Copies the shared sections (KDN8, PRIM, TRIS) and META: the tree bytes are
 * the same in both layouts. */
static as_error_t copy_tree(const as_structure_t *src, as_structure_t *dst)
{
    const uint32_t tags[3] = {ASF_TAG_KDN8, ASF_TAG_PRIM, ASF_TAG_TRIS};
    dst->meta = src->meta;
    for (int k = 0; k < 3; ++k) {
        const as_section_t *sec = as_structure_find(src, tags[k]);
        void *data = as_aligned_alloc(sec->bytes, "KD section copy");
        if (!data) return as_get_error();
        memcpy(data, sec->data, sec->bytes);
        as_structure_add_section(dst, tags[k], data, sec->count, sec->stride);
    }
    return AS_OK;
}

static as_error_t kd_convert(const as_structure_t *src, uint32_t target, as_structure_t *dst)
{
    if (target != AS_LAYOUT_KD_STANDARD && target != AS_LAYOUT_KD_ROPES)
        return as_set_error(AS_ERROR_UNSUPPORTED, "a KD tree converts only to kd-standard or kd-ropes");
    as_error_t err = copy_tree(src, dst);
    if (err != AS_OK) return err;
    dst->meta.layout = AS_LAYOUT_KD_STANDARD;
    if (target == AS_LAYOUT_KD_ROPES) err = as_kd_add_ropes(dst);
    return err;
}

const as_layout_ops_t as_layout_kd_standard = {
    .structure_kind = AS_STRUCT_KD,
    .layout = AS_LAYOUT_KD_STANDARD,
    .layout_version = AS_KD_LAYOUT_VERSION,
    .kind_name = "kd",
    .layout_name = "kd-standard",
    .section_count = 3,
    .sections = {
        {ASF_TAG_KDN8, sizeof(as_kd_node_t), "KD nodes, 8 bytes: split or leaf list, read by the traversal"},
        {ASF_TAG_PRIM, sizeof(uint32_t), "leaf lists: count then source triangle indices, read by the traversal"},
        {ASF_TAG_TRIS, sizeof(as_tri4_t), "triangles in source order, read by the traversal"},
    },
    .validate = as_kd_validate,
    .stats = kd_stats,
    .trace_cpu = kd_trace_cpu,
#ifdef AS_HAVE_CUDA
    .trace_gpu = as_layout_trace_gpu,
    .validate_gpu = as_kd_validate_gpu,
#endif
    .convert = kd_convert,
};

const as_layout_ops_t as_layout_kd_ropes = {
    .structure_kind = AS_STRUCT_KD,
    .layout = AS_LAYOUT_KD_ROPES,
    .layout_version = AS_KD_LAYOUT_VERSION,
    .kind_name = "kd",
    .layout_name = "kd-ropes",
    .section_count = 5,
    .sections = {
        {ASF_TAG_KDN8, sizeof(as_kd_node_t), "KD nodes, 8 bytes: split or leaf list, read by the traversal"},
        {ASF_TAG_PRIM, sizeof(uint32_t), "leaf lists: count then source triangle indices, read by the traversal"},
        {ASF_TAG_TRIS, sizeof(as_tri4_t), "triangles in source order, read by the traversal"},
        {ASF_TAG_KDRP, sizeof(as_kd_ropes_t), "six ropes per leaf, read by the stackless traversal"},
        {ASF_TAG_KDLB, sizeof(as_kd_leaf_box_t), "leaf boxes (exit faces), read by the stackless traversal"},
    },
    .validate = as_kd_ropes_validate,
    .stats = kd_stats,
    .trace_cpu = kd_ropes_trace_cpu,
#ifdef AS_HAVE_CUDA
    .trace_gpu = as_layout_trace_gpu,
    .validate_gpu = as_kd_ropes_validate_gpu,
#endif
    .convert = kd_convert,
};
