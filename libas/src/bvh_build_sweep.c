/* BVH builder, full-sweep SAH (MacDonald & Booth 1990; Wald 2007 section 3):
 * at every node, the references are sorted by centroid on each axis and
 * every one of the count - 1 object partitions is evaluated exactly, which
 * costs O(N log N) per node. Written into the BVH2 child-bounds layout by
 * bvh_build_common.c.
 *
 * Determinism: the sort key (centroid, source index) is a total order and
 * ties between candidates go to the lower axis, then the earlier position. */
#include "bvh_build_common.h"

#include <math.h>
#include <stdlib.h>
#include <string.h>

typedef struct sort_key {
    float c;
    uint32_t id;
    uint32_t pos;    /* index in the node's range */
} sort_key;

static int key_cmp(const void *pa, const void *pb)
{
    const sort_key *a = pa, *b = pb;
    if (a->c < b->c) return -1;
    if (a->c > b->c) return 1;
    return (a->id > b->id) - (a->id < b->id);
}

static uint32_t sweep_partition(bvh_builder *b, uint32_t first, uint32_t count, const bvh_box *node_box)
{
    const float ci = b->args->cost_intersection, ct = b->args->cost_traversal;
    bvh_ref *refs = b->refs + first;
    sort_key *keys = malloc(sizeof(sort_key) * count * 3);
    double *right_area = malloc(sizeof(double) * count);
    bvh_ref *tmp = malloc(sizeof(bvh_ref) * count);
    if (!keys || !right_area || !tmp) {
        /* No memory for the sweep: split in half rather than fail. */
        free(keys); free(right_area); free(tmp);
        return count > b->args->max_leaf_size ? first + count / 2 : 0;
    }
    int best_axis = -1;
    uint32_t best_pos = 0;
    double best_cost = INFINITY;
    for (int axis = 0; axis < 3; ++axis) {
        sort_key *k = keys + (size_t)axis * count;
        for (uint32_t i = 0; i < count; ++i) k[i] = (sort_key){bvh_ref_centroid(&refs[i], axis), refs[i].id, i};
        qsort(k, count, sizeof *k, key_cmp);
        if (!(k[count - 1].c > k[0].c)) continue; /* every centroid on one plane */
        bvh_box acc = bvh_box_empty();
        for (uint32_t i = count; i-- > 1;) {
            bvh_box_grow(&acc, refs[k[i].pos].lo, refs[k[i].pos].hi);
            right_area[i] = bvh_box_half_area(&acc);
        }
        acc = bvh_box_empty();
        for (uint32_t i = 0; i + 1 < count; ++i) {
            bvh_box_grow(&acc, refs[k[i].pos].lo, refs[k[i].pos].hi);
            const double cost = bvh_box_half_area(&acc) * (double)(i + 1) + right_area[i + 1] * (double)(count - i - 1);
            if (cost < best_cost) {
                best_cost = cost;
                best_axis = axis;
                best_pos = i + 1;
            }
        }
    }
    const double area = bvh_box_half_area(node_box);
    const double leaf_cost = ci * (double)count;
    const double split_cost = area > 0 ? ct + ci * best_cost / area : ct + ci * (double)count;
    uint32_t mid = 0;
    if (best_axis >= 0 && (split_cost < leaf_cost || count > b->args->max_leaf_size)) {
        const sort_key *k = keys + (size_t)best_axis * count;
        for (uint32_t i = 0; i < count; ++i) tmp[i] = refs[k[i].pos];
        memcpy(refs, tmp, sizeof(bvh_ref) * count);
        mid = first + best_pos;
    } else if (count > b->args->max_leaf_size) {
        /* All centroids coincide (copies of one triangle): halve the list. */
        mid = first + count / 2;
    }
    free(keys);
    free(right_area);
    free(tmp);
    return mid;
}

static int sweep_split(bvh_builder *b, const bvh_range *node, unsigned threads, bvh_range *left, bvh_range *right)
{
    (void)threads;
    const uint32_t mid = sweep_partition(b, node->first, node->count, &node->box);
    if (mid <= node->first || mid >= node->first + node->count) return 0;
    left->first = node->first;
    left->count = mid - node->first;
    right->first = mid;
    right->count = node->first + node->count - mid;
    bvh_range_bound(b, left);
    bvh_range_bound(b, right);
    return 1;
}

as_error_t as_bvh_build_sweep(const as_mesh_t *mesh, const as_build_args_t *args, as_structure_t *s)
{
    const double t_start = as_now_ms();
    bvh_builder b;
    as_error_t err = bvh_builder_init(&b, mesh, args, 2);
    if (err != AS_OK) return err;
    const int32_t root = bvh_build_inplace(&b, sweep_split);
    err = bvh_builder_finish(&b, root, AS_BUILDER_BVH_SAH_SWEEP, s, t_start);
    bvh_builder_free(&b);
    return err;
}
