/* BVH builder, binned SAH (Wald 2007, "On fast construction of SAH-based
 * bounding volume hierarchies"), written into the BVH2 child-bounds layout by
 * bvh_build_common.c.
 *
 * Determinism: binning and the in-place partition are sequential per node,
 * ties broken by axis then bin (see bvh_build_common.c for the rest).
 *
 * Speed: one pass bins all three axes, the SAH sweep visits only occupied
 * bins, and the partition computes both children's boxes and centroid boxes
 * as it goes, so each level costs two passes over its references; subtrees
 * go to idle threads (task_pool.h). */
#include "bvh_build_common.h"

#include <math.h>
#include <string.h>

/* Two or three references: every object partition along each axis,
 * exactly, which costs a few comparisons where binning would set up bins.
 * The order of the candidates is fixed (axis, then the sorted position, ties
 * by source index), so the result depends only on the references. */
static double tiny_cost(const bvh_ref *refs, const uint8_t *side, uint32_t count)
{
    bvh_box l = bvh_box_empty(), r = bvh_box_empty();
    uint32_t nl = 0;
    for (uint32_t i = 0; i < count; ++i) {
        if (side[i]) bvh_box_grow(&r, refs[i].lo, refs[i].hi);
        else { bvh_box_grow(&l, refs[i].lo, refs[i].hi); ++nl; }
    }
    return bvh_box_half_area(&l) * nl + bvh_box_half_area(&r) * (count - nl);
}

static uint32_t tiny_split(bvh_ref *refs, uint32_t count, double *best_cost)
{
    /* With two references there is one partition; with three, per axis,
     * the first one alone or the last one alone in centroid order. */
    *best_cost = INFINITY;
    uint8_t best_side[3] = {0, 1, 1};
    if (count == 2) {
        const uint8_t side[2] = {0, 1};
        *best_cost = tiny_cost(refs, side, 2);
        return 1;
    }
    for (int axis = 0; axis < 3; ++axis) {
        uint32_t o[3] = {0, 1, 2};
        for (int pass = 0; pass < 2; ++pass)
            for (int j = 0; j < 2; ++j) {
                const bvh_ref *a = &refs[o[j]], *c = &refs[o[j + 1]];
                const float ka = a->lo[axis] + a->hi[axis], kc = c->lo[axis] + c->hi[axis];
                if (ka > kc || (ka == kc && a->id > c->id)) { const uint32_t t = o[j]; o[j] = o[j + 1]; o[j + 1] = t; }
            }
        for (uint32_t first_right = 1; first_right <= 2; ++first_right) {
            uint8_t side[3];
            for (uint32_t j = 0; j < 3; ++j) side[o[j]] = j >= first_right;
            const double c = tiny_cost(refs, side, 3);
            if (c < *best_cost) {
                *best_cost = c;
                memcpy(best_side, side, 3);
            }
        }
    }
    /* Left references first, in their original order. */
    bvh_ref tmp[3];
    uint32_t n = 0;
    for (uint32_t i = 0; i < 3; ++i) if (!best_side[i]) tmp[n++] = refs[i];
    const uint32_t nl = n;
    for (uint32_t i = 0; i < 3; ++i) if (best_side[i]) tmp[n++] = refs[i];
    memcpy(refs, tmp, sizeof tmp);
    return nl;
}

static int binned_split(bvh_builder *b, const bvh_range *node, bvh_range *left, bvh_range *right)
{
    const float ci = b->args->cost_intersection, ct = b->args->cost_traversal;
    const uint32_t count = node->count;
    if (count <= 3) {
        double cost;
        const uint32_t nl = tiny_split(b->refs + node->first, count, &cost);
        const double area = bvh_box_half_area(&node->box);
        const double split_cost = area > 0 ? ct + ci * cost / area : ct + ci * (double)count;
        if (!(split_cost < ci * (double)count) && count <= b->args->max_leaf_size) return 0;
        left->first = node->first;
        left->count = nl;
        right->first = node->first + nl;
        right->count = count - nl;
        bvh_range_bound(b, left);
        bvh_range_bound(b, right);
        return 1;
    }
    const bvh_object_split s = bvh_find_object_split(b->refs + node->first, count, &node->cbox, b->args->bin_count);
    const double area = bvh_box_half_area(&node->box);
    const double leaf_cost = ci * (double)count;
    const double split_cost = area > 0 ? ct + ci * s.cost / area : ct + ci * (double)count;
    if (s.axis >= 0 && (split_cost < leaf_cost || count > b->args->max_leaf_size)) {
        bvh_partition_object(b, node, &s, left, right);
        if (left->count && right->count) return 1;
    } else if (count <= b->args->max_leaf_size) {
        return 0;
    }
    /* All centroids coincide (copies of one triangle): split the list in
     * half, which keeps the depth logarithmic. */
    left->first = node->first;
    left->count = count / 2;
    right->first = node->first + count / 2;
    right->count = count - count / 2;
    bvh_range_bound(b, left);
    bvh_range_bound(b, right);
    return 1;
}

as_error_t as_bvh_build_sah(const as_mesh_t *mesh, const as_build_args_t *args, as_structure_t *s)
{
    const double t_start = as_now_ms();
    bvh_builder b;
    as_error_t err = bvh_builder_init(&b, mesh, args, 2);
    if (err != AS_OK) return err;
    const int32_t root = bvh_build_inplace(&b, binned_split);
    err = bvh_builder_finish(&b, root, AS_BUILDER_BVH_SAH_BINNED, s, t_start);
    bvh_builder_free(&b);
    return err;
}
