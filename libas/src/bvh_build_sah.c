/* BVH builder, binned SAH (Wald 2007, "On fast construction of SAH-based
 * bounding volume hierarchies"), written into the BVH2 child-bounds layout by
 * bvh_build_common.c.
 *
 * Determinism: binning and the in-place partition are sequential per node,
 * ties broken by axis then bin (see bvh_build_common.c for the rest). */
#include "bvh_build_common.h"

static uint32_t binned_split(bvh_builder *b, uint32_t first, uint32_t count, const bvh_box *node_box)
{
    const float ci = b->args->cost_intersection, ct = b->args->cost_traversal;
    const bvh_box cb = bvh_refs_centroid_box(b->refs + first, count);
    const bvh_object_split s = bvh_find_object_split(b->refs + first, count, &cb, b->args->bin_count);
    const double area = bvh_box_half_area(node_box);
    const double leaf_cost = ci * (double)count;
    const double split_cost = area > 0 ? ct + ci * s.cost / area : ct + ci * (double)count;
    uint32_t mid;
    if (s.axis >= 0 && (split_cost < leaf_cost || count > b->args->max_leaf_size)) {
        /* In-place partition, sequential, so the order is reproducible. */
        uint32_t i = first, j = first + count;
        while (i < j) {
            if (bvh_object_split_left(&b->refs[i], &s, b->args->bin_count)) { ++i; continue; }
            --j;
            const bvh_ref tmp = b->refs[i];
            b->refs[i] = b->refs[j];
            b->refs[j] = tmp;
        }
        mid = i;
    } else if (count > b->args->max_leaf_size) {
        /* All centroids coincide (copies of one triangle): split the list in
         * half, which keeps the depth logarithmic. */
        mid = first + count / 2;
    } else {
        return 0;
    }
    if (mid == first || mid == first + count) mid = first + count / 2;
    return mid;
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
