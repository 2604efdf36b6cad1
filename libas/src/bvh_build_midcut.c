/* BVH builder, mid-cut: the object median on the longest axis of the node's
 * centroid box (the paper's "Mid. Cut" BVH), written into the BVH2
 * child-bounds layout by bvh_build_common.c.
 *
 * The median is found with a quickselect on (centroid, source index), a
 * total order, so the partition depends only on the node's references: the
 * output is the same for any thread count. Leaves hold at most
 * max_leaf_size triangles (or whatever the depth cap leaves); there is no
 * cost-based termination. */
#include "bvh_build_common.h"

static int ref_less(const bvh_ref *a, const bvh_ref *b, int axis)
{
    const float ca = bvh_ref_centroid(a, axis), cb = bvh_ref_centroid(b, axis);
    if (ca != cb) return ca < cb;
    return a->id < b->id;
}

static void swap_refs(bvh_ref *a, bvh_ref *b)
{
    const bvh_ref t = *a;
    *a = *b;
    *b = t;
}

/* Reorders r[0, n) so that r[k] is the k-th smallest and nothing before it
 * is larger nor after it smaller. Median-of-three pivots; deterministic. */
static void select_kth(bvh_ref *r, uint32_t n, uint32_t k, int axis)
{
    uint32_t lo = 0, hi = n - 1;
    while (hi > lo) {
        const uint32_t mid = lo + (hi - lo) / 2;
        if (ref_less(&r[mid], &r[lo], axis)) swap_refs(&r[mid], &r[lo]);
        if (ref_less(&r[hi], &r[lo], axis)) swap_refs(&r[hi], &r[lo]);
        if (ref_less(&r[hi], &r[mid], axis)) swap_refs(&r[hi], &r[mid]);
        /* Pivot r[mid] to hi - 1 ... Lomuto partition around it at hi. */
        swap_refs(&r[mid], &r[hi]);
        const bvh_ref pivot = r[hi];
        uint32_t store = lo;
        for (uint32_t i = lo; i < hi; ++i)
            if (ref_less(&r[i], &pivot, axis)) swap_refs(&r[i], &r[store++]);
        swap_refs(&r[store], &r[hi]);
        if (store == k) return;
        if (k < store) hi = store - 1;
        else lo = store + 1;
    }
}

static int midcut_split(bvh_builder *b, const bvh_range *node, unsigned threads, bvh_range *left, bvh_range *right)
{
    (void)threads;
    const uint32_t first = node->first, count = node->count;
    if (count <= b->args->max_leaf_size) return 0;
    const bvh_box cb = node->cbox; /* doubled: only the longest axis matters */
    int axis = 0;
    float extent = cb.hi[0] - cb.lo[0];
    for (int k = 1; k < 3; ++k)
        if (cb.hi[k] - cb.lo[k] > extent) { axis = k; extent = cb.hi[k] - cb.lo[k]; }
    /* Coincident centroids still split by source index: the depth stays
     * logarithmic. */
    select_kth(b->refs + first, count, count / 2, axis);
    left->first = first;
    left->count = count / 2;
    right->first = first + count / 2;
    right->count = count - count / 2;
    bvh_range_bound(b, left);
    bvh_range_bound(b, right);
    return 1;
}

as_error_t as_bvh_build_midcut(const as_mesh_t *mesh, const as_build_args_t *args, as_structure_t *s)
{
    const double t_start = as_now_ms();
    bvh_builder b;
    as_error_t err = bvh_builder_init(&b, mesh, args, 2);
    if (err != AS_OK) return err;
    const int32_t root = bvh_build_inplace(&b, midcut_split);
    err = bvh_builder_finish(&b, root, AS_BUILDER_BVH_MIDCUT, s, t_start);
    bvh_builder_free(&b);
    return err;
}
