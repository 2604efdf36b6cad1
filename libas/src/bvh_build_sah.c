/* BVH builder, binned SAH (Wald 2007, "On fast construction of SAH-based
 * bounding volume hierarchies"), written into the BVH2 child-bounds layout by
 * bvh_build_common.c.
 *
 * Determinism: binning and the in-place partition are sequential per node,
 * ties broken by axis then bin (see bvh_build_common.c for the rest).
 *
 * Speed: subtrees of up to BVH_EXACT_MAX references are built by the exact
 * sweep (bvh_build_exact.c), which costs less than setting up bins; above,
 * one pass bins all three axes and notes each reference's bins, the SAH
 * sweep visits only occupied bins, and the partition reads the noted bins
 * (4 bytes a reference) instead of the references (32), so each level
 * costs one pass over its references; the children's boxes come from the
 * bins and their binning frames from the split (bvh_build_common.c,
 * split_frames); subtrees go to idle threads (task_pool.h). */
#include "bvh_build_common.h"

#include <math.h>
#include <string.h>

/* Nodes above this size bin into twice the requested bins (at most
 * BVH_MAX_BINS). Their binning costs per reference, hardly per bin, and a
 * greedy choice high in the tree decides much of the SAH cost: on
 * staircase2 one node of 1,859 references took the whole tree from 3.1% above
 * the full sweep's cost to 0.6% with 64 bins instead of 32, and the other
 * scenes' costs fell by 0.1-1.4%, at no build time measurable. */
#define BVH_DOUBLE_BINS_MIN 1024

static bvh_object_split find_split(bvh_builder *b, const bvh_range *node, uint32_t nb, unsigned threads)
{
    const bvh_ref *refs = b->refs + node->first;
    uint32_t *bins = b->ref_bins + node->first;
    return threads > 1 ? bvh_find_object_split_mt(refs, node->count, &node->cbox, nb, threads, bins)
                       : bvh_find_object_split(refs, node->count, &node->cbox, nb, bins);
}

static int binned_split(bvh_builder *b, const bvh_range *node, unsigned threads, bvh_range *left, bvh_range *right)
{
    const float ci = b->args->cost_intersection, ct = b->args->cost_traversal;
    const uint32_t count = node->count;
    uint32_t nb = b->args->bin_count;
    if (count > BVH_DOUBLE_BINS_MIN) nb = 2 * nb < BVH_MAX_BINS ? 2 * nb : BVH_MAX_BINS;
    bvh_object_split s = find_split(b, node, nb, threads);
    bvh_range exact;
    if (s.axis < 0) {
        /* A loose frame (split_frames) can hold every centroid in one bin
         * although they differ: before halving, bin once more in their own
         * box. Rare, and the plain case of copies of one triangle costs one
         * pass more. */
        exact = *node;
        exact.cbox = bvh_refs_centroid2_box(b->refs + node->first, count);
        if (memcmp(&exact.cbox, &node->cbox, sizeof exact.cbox) != 0) {
            node = &exact;
            s = find_split(b, node, nb, threads);
        }
    }
    const double area = bvh_box_half_area(&node->box);
    const double leaf_cost = ci * (double)count;
    const double split_cost = area > 0 ? ct + ci * s.cost / area : ct + ci * (double)count;
    if (s.axis >= 0 && (split_cost < leaf_cost || count > b->args->max_leaf_size)) {
        if (threads > 1) bvh_partition_object_mt(b, node, &s, left, right, threads);
        else bvh_partition_object(b, node, &s, left, right);
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
    b.exact_max = BVH_EXACT_MAX;
    b.ref_bins = as_block_take(sizeof(uint32_t) * (size_t)(b.ref_count ? b.ref_count : 1), 0, "BVH reference bins");
    if (!b.ref_bins) {
        err = as_get_error();
        bvh_builder_free(&b);
        return err;
    }
    const int32_t root = bvh_build_inplace(&b, binned_split);
    err = bvh_builder_finish(&b, root, AS_BUILDER_BVH_SAH_BINNED, s, t_start);
    bvh_builder_free(&b);
    return err;
}
