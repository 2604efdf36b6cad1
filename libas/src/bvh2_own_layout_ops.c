/* The BVH2 own-bounds layout: its sections, statistics, CPU traversal
 * (kernels/bvh2_own_traverse.h) and the conversions between the two BVH2
 * layouts, which keep the tree, the leaves and TRI4 exactly. */
#include "structure.h"
#include "bvh2_own_traverse.h"
#include "cwbvh_layout.h"

#include <math.h>
#include <stdlib.h>
#include <string.h>

static double half_area(const float lo[3], const float hi[3])
{
    const double dx = (double)hi[0] - lo[0], dy = (double)hi[1] - lo[1], dz = (double)hi[2] - lo[2];
    if (!(dx >= 0 && dy >= 0 && dz >= 0)) return 0.0;
    return dx * dy + dy * dz + dz * dx;
}

/* SAH cost and statistics, as for the child-bounds layout (the same tree
 * gives the same cost): every inner node costs cost_traversal times its
 * area, every leaf cost_intersection times its size times its area, areas
 * relative to the scene box of META (the root counts 1). */
static double own_walk(const as_structure_t *s, as_structure_stats_t *st)
{
    const as_bvh2o_node_t *nodes = as_structure_find(s, ASF_TAG_BVHO)->data;
    const double ci = s->meta.cost_intersection, ct = s->meta.cost_traversal;
    const double root_area = half_area(s->meta.bounds_lo, s->meta.bounds_hi);
    struct { int32_t node; uint32_t depth; } stack[AS_BVH2_MAX_DEPTH + 2];
    int sp = 0;
    double sah = ct;
    uint64_t depth_sum = 0;
    stack[sp].node = 0; stack[sp].depth = 0; ++sp;
    while (sp > 0) {
        --sp;
        const as_bvh2o_node_t *n = &nodes[stack[sp].node];
        const uint32_t depth = stack[sp].depth;
        for (int k = 0; k < 2; ++k) {
            const as_bvh2o_node_t *c = &nodes[n->child + k];
            const double a = root_area > 0 ? half_area(c->lo, c->hi) / root_area : 1.0;
            if (c->child >= 0) {
                sah += ct * a;
                if (sp >= AS_BVH2_MAX_DEPTH + 2) continue;
                stack[sp].node = n->child + k; stack[sp].depth = depth + 1; ++sp;
                continue;
            }
            sah += ci * c->count * a;
            if (!st || c->count == 0) continue; /* the empty sibling of a one-leaf tree */
            st->leaf_count++;
            if (depth + 1 > st->max_depth) st->max_depth = depth + 1;
            depth_sum += depth + 1;
            st->depth_histogram[depth + 1 < AS_HISTOGRAM_BINS ? depth + 1 : AS_HISTOGRAM_BINS - 1]++;
            st->leaf_size_histogram[c->count < AS_HISTOGRAM_BINS ? c->count : AS_HISTOGRAM_BINS - 1]++;
        }
    }
    if (st) st->average_leaf_depth = st->leaf_count ? (double)depth_sum / (double)st->leaf_count : 0.0;
    return sah;
}

static void own_stats(const as_structure_t *s, as_structure_stats_t *st)
{
    /* Inner nodes, as for the child-bounds layout: a valid tree has 1 + 2 x
     * inner records. */
    st->node_count = (as_structure_find(s, ASF_TAG_BVHO)->count - 1) / 2;
    st->sah_cost = own_walk(s, st);
}

static void own_trace_cpu(const as_structure_t *s, const as_ray_t *rays, as_hit_t *hits, size_t count, int any_hit,
                          int ray_flags, as_cpu_stats_t *stats)
{
    const as_section_t *ns = as_structure_find(s, ASF_TAG_BVHO), *ts = as_structure_find(s, ASF_TAG_TRI4);
    AS_TRACE_CPU_LOOP(ns->count > 0,
                      as_bvh2o_trace(ns->data, ts->data, &pre, any_hit, &h, ctrp));
}

static void *copy_section(const as_section_t *sec, const char *what)
{
    void *p = as_aligned_alloc(sec->bytes ? sec->bytes : 1, what);
    if (p && sec->bytes) memcpy(p, sec->data, sec->bytes);
    return p;
}

/* ---- child-bounds -> own-bounds: nodes in depth-first order, each node's
 * two children adjacent, the root's box the union of its children's. */

typedef struct to_own_state {
    const as_bvh2_node_t *in;
    as_bvh2o_node_t *out;
    uint64_t next;
} to_own_state;

static void child_box(const as_bvh2_node_t *n, int k, float lo[3], float hi[3])
{
    if (k == 0) { lo[0] = n->xy0.x; hi[0] = n->xy0.y; lo[1] = n->xy0.z; hi[1] = n->xy0.w; lo[2] = n->z01.x; hi[2] = n->z01.y; }
    else        { lo[0] = n->xy1.x; hi[0] = n->xy1.y; lo[1] = n->xy1.z; hi[1] = n->xy1.w; lo[2] = n->z01.z; hi[2] = n->z01.w; }
}

static void to_own(to_own_state *st, int32_t in_index, uint64_t out_index)
{
    const as_bvh2_node_t *n = &st->in[in_index];
    const uint64_t first = st->next;
    st->next += 2;
    st->out[out_index].child = (int32_t)first;
    st->out[out_index].count = 0;
    for (int k = 0; k < 2; ++k) {
        as_bvh2o_node_t *o = &st->out[first + k];
        child_box(n, k, o->lo, o->hi);
        if (n->child[k] < 0) {
            o->child = n->child[k];
            o->count = n->count[k];
        }
    }
    for (int k = 0; k < 2; ++k)
        if (n->child[k] >= 0) to_own(st, n->child[k], first + k);
}

as_error_t as_bvh2_to_own_bounds(const as_structure_t *src, as_structure_t *dst)
{
    const as_section_t *ns = as_structure_find(src, ASF_TAG_BVH2), *ts = as_structure_find(src, ASF_TAG_TRI4);
    const uint64_t count = 1 + 2 * ns->count;
    as_bvh2o_node_t *out = as_aligned_alloc(sizeof(as_bvh2o_node_t) * count, "BVHO nodes");
    as_tri4_t *tris = copy_section(ts, "TRI4 triangles");
    if (!out || !tris) { free(out); free(tris); return as_get_error(); }
    memset(out, 0, sizeof(as_bvh2o_node_t) * count);
    to_own_state st = {ns->data, out, 1};
    to_own(&st, 0, 0);
    /* The root's own box: the union of its children's (an empty child's box
     * is inverted and changes nothing). */
    for (int a = 0; a < 3; ++a) {
        out[0].lo[a] = fminf(out[1].lo[a], out[2].lo[a]);
        out[0].hi[a] = fmaxf(out[1].hi[a], out[2].hi[a]);
    }
    dst->meta = src->meta;
    dst->meta.layout = AS_LAYOUT_BVH2_OWN_BOUNDS;
    dst->meta.layout_version = AS_BVH2O_LAYOUT_VERSION;
    as_structure_add_section(dst, ASF_TAG_BVHO, out, count, sizeof(as_bvh2o_node_t));
    as_structure_add_section(dst, ASF_TAG_TRI4, tris, ts->count, sizeof(as_tri4_t));
    dst->meta.sah_cost = own_walk(dst, NULL);
    return AS_OK;
}

/* ---- own-bounds -> child-bounds: the numbering rule of the builders'
 * flattening (bvh_build_common.c): at each node, slots for its inner
 * children in order, then child 0's subtree, then child 1's. */

typedef struct to_child_state {
    const as_bvh2o_node_t *in;
    as_bvh2_node_t *out;
    uint64_t next;
} to_child_state;

static void to_child(to_child_state *st, int32_t in_index, uint64_t out_index)
{
    const as_bvh2o_node_t *n = &st->in[in_index];
    int64_t slot[2] = {-1, -1};
    for (int k = 0; k < 2; ++k)
        if (st->in[n->child + k].child >= 0) slot[k] = (int64_t)st->next++;
    as_bvh2_node_t *o = &st->out[out_index];
    for (int k = 0; k < 2; ++k) {
        const as_bvh2o_node_t *c = &st->in[n->child + k];
        if (k == 0) {
            o->xy0 = (as_f4_t){c->lo[0], c->hi[0], c->lo[1], c->hi[1]};
            o->z01.x = c->lo[2]; o->z01.y = c->hi[2];
        } else {
            o->xy1 = (as_f4_t){c->lo[0], c->hi[0], c->lo[1], c->hi[1]};
            o->z01.z = c->lo[2]; o->z01.w = c->hi[2];
        }
        o->child[k] = slot[k] >= 0 ? (int32_t)slot[k] : c->child;
        o->count[k] = slot[k] >= 0 ? 0 : c->count;
    }
    for (int k = 0; k < 2; ++k)
        if (slot[k] >= 0) to_child(st, n->child + k, (uint64_t)slot[k]);
}

as_error_t as_bvh2_own_to_child_bounds(const as_structure_t *src, as_structure_t *dst)
{
    const as_section_t *ns = as_structure_find(src, ASF_TAG_BVHO), *ts = as_structure_find(src, ASF_TAG_TRI4);
    const as_bvh2o_node_t *in = ns->data;
    uint64_t inner = 0;
    for (uint64_t i = 0; i < ns->count; ++i) inner += in[i].child >= 0;
    as_bvh2_node_t *out = as_aligned_alloc(sizeof(as_bvh2_node_t) * (inner ? inner : 1), "BVH2 nodes");
    as_tri4_t *tris = copy_section(ts, "TRI4 triangles");
    if (!out || !tris) { free(out); free(tris); return as_get_error(); }
    memset(out, 0, sizeof(as_bvh2_node_t) * (inner ? inner : 1));
    to_child_state st = {in, out, 1};
    to_child(&st, 0, 0);
    dst->meta = src->meta;
    dst->meta.layout = AS_LAYOUT_BVH2_CHILD_BOUNDS;
    dst->meta.layout_version = AS_BVH2_LAYOUT_VERSION;
    dst->meta.node_count = st.next;
    as_structure_add_section(dst, ASF_TAG_BVH2, out, st.next, sizeof(as_bvh2_node_t));
    as_structure_add_section(dst, ASF_TAG_TRI4, tris, ts->count, sizeof(as_tri4_t));
    dst->meta.sah_cost = as_bvh2_sah_cost(dst);
    return AS_OK;
}

static as_error_t own_convert(const as_structure_t *src, uint32_t target, as_structure_t *dst)
{
    if (target == AS_LAYOUT_BVH2_CHILD_BOUNDS) return as_bvh2_own_to_child_bounds(src, dst);
    if (target == AS_LAYOUT_BVH_CWBVH) {
        /* Through the child-bounds tree, which the collapse reads. */
        as_structure_t cb;
        memset(&cb, 0, sizeof cb);
        as_error_t err = as_bvh2_own_to_child_bounds(src, &cb);
        if (err == AS_OK) err = as_bvh2_to_cwbvh(&cb, AS_CWBVH_MAX_LEAF, dst);
        for (uint32_t i = 0; i < cb.section_count; ++i) free(cb.sections[i].owned);
        return err;
    }
    if (target == AS_LAYOUT_BVH2_OWN_BOUNDS) {
        /* Same layout: a copy. */
        const as_section_t *ns = as_structure_find(src, ASF_TAG_BVHO), *ts = as_structure_find(src, ASF_TAG_TRI4);
        void *n = copy_section(ns, "BVHO nodes"), *t = copy_section(ts, "TRI4 triangles");
        if (!n || !t) { free(n); free(t); return as_get_error(); }
        dst->meta = src->meta;
        as_structure_add_section(dst, ASF_TAG_BVHO, n, ns->count, sizeof(as_bvh2o_node_t));
        as_structure_add_section(dst, ASF_TAG_TRI4, t, ts->count, sizeof(as_tri4_t));
        return AS_OK;
    }
    return as_set_error(AS_ERROR_UNSUPPORTED, "a BVH2 converts only to bvh2-child-bounds, bvh2-own-bounds or cwbvh");
}

const as_layout_ops_t as_layout_bvh2_own_bounds = {
    .structure_kind = AS_STRUCT_BVH,
    .layout = AS_LAYOUT_BVH2_OWN_BOUNDS,
    .layout_version = AS_BVH2O_LAYOUT_VERSION,
    .kind_name = "bvh",
    .layout_name = "bvh2-own-bounds",
    .section_count = 2,
    .sections = {
        {ASF_TAG_BVHO, sizeof(as_bvh2o_node_t), "BVH nodes, each with its own box, read by the traversal"},
        {ASF_TAG_TRI4, sizeof(as_tri4_t), "triangle vertices in leaf order with source indices, read by the traversal"},
    },
    .validate = as_bvh2_own_validate,
    .stats = own_stats,
    .trace_cpu = own_trace_cpu,
#ifdef AS_HAVE_CUDA
    .trace_gpu = as_layout_trace_gpu,
    .validate_gpu = as_bvh2_own_validate_gpu,
#endif
    .convert = own_convert,
};
