/* Ropes for a KD tree (Havran 1998), with Popov et al.'s 2007 optimisation:
 * each of a leaf's six ropes points at the deepest node whose box covers the
 * whole face from the other side, or -1 where the face lies on the scene
 * box. Ropes are passed down the tree: a child inherits its parent's ropes,
 * its face on the split plane gets the sibling, and every rope is pushed
 * down while one child of the rope's node still covers the face. One
 * depth-first walk, O(nodes x depth) at most. */
#include "structure.h"
#include "kd_layout.h"

#include <stdlib.h>
#include <string.h>

typedef struct rope_walk {
    const as_kd_node_t *nodes;
    uint64_t node_count;
    as_kd_ropes_t *ropes;
    as_kd_leaf_box_t *boxes;
    uint64_t leaf_count;
} rope_walk;

/* Pushes the rope of face `face` of `box` down to the deepest covering node. */
static int32_t optimise(const rope_walk *w, int32_t r, int face, const float box[6])
{
    const int fa = face >> 1, positive = face & 1;
    while (r >= 0) {
        const as_kd_node_t n = w->nodes[r];
        if (as_kd_is_leaf(n.word1)) break;
        const int axis = (int)(n.word1 & 3u);
        const float s = as_uint_as_float(n.word0);
        const int32_t below = r + 1, above = (int32_t)(n.word1 >> 2);
        if (axis == fa) r = positive ? below : above;  /* the child next to the face */
        else if (box[axis + 3] <= s) r = below;
        else if (box[axis] >= s) r = above;
        else break;
    }
    return r;
}

static void walk(const rope_walk *w, uint32_t node, const float box[6], const int32_t in[6])
{
    const as_kd_node_t n = w->nodes[node];
    if (as_kd_is_leaf(n.word1)) {
        const uint32_t leaf = n.word1 >> 2;
        for (int f = 0; f < 6; ++f) w->ropes[leaf].rope[f] = optimise(w, in[f], f, box);
        memcpy(w->boxes[leaf].lo, box, sizeof(float) * 3);
        memcpy(w->boxes[leaf].hi, box + 3, sizeof(float) * 3);
        return;
    }
    const int axis = (int)(n.word1 & 3u);
    const float s = as_uint_as_float(n.word0);
    const uint32_t below = node + 1, above = n.word1 >> 2;
    float lbox[6], rbox[6];
    int32_t lr[6], rr[6];
    memcpy(lbox, box, sizeof lbox);
    memcpy(rbox, box, sizeof rbox);
    lbox[axis + 3] = s;
    rbox[axis] = s;
    for (int f = 0; f < 6; ++f) {
        lr[f] = optimise(w, in[f], f, lbox);
        rr[f] = optimise(w, in[f], f, rbox);
    }
    lr[2 * axis + 1] = (int32_t)above;
    rr[2 * axis] = (int32_t)below;
    walk(w, below, lbox, lr);
    walk(w, above, rbox, rr);
}

/* Computes the ropes and boxes of a tree that passed the KD-standard checks
 * (kd_validate.c); `leaf_count` is the number of leaves (empty ones too). */
void as_kd_compute_ropes(const as_kd_node_t *nodes, uint64_t node_count, uint64_t leaf_count, const float lo[3],
                         const float hi[3], as_kd_ropes_t *ropes, as_kd_leaf_box_t *boxes)
{
    const rope_walk w = {nodes, node_count, ropes, boxes, leaf_count};
    const float box[6] = {lo[0], lo[1], lo[2], hi[0], hi[1], hi[2]};
    const int32_t none[6] = {-1, -1, -1, -1, -1, -1};
    walk(&w, 0, box, none);
}

as_error_t as_kd_add_ropes(as_structure_t *s)
{
    const as_section_t *ns = as_structure_find(s, ASF_TAG_KDN8);
    const uint64_t leaves = s->meta.leaf_count + s->meta.empty_leaf_count;
    as_kd_ropes_t *ropes = as_aligned_alloc(sizeof(as_kd_ropes_t) * (leaves ? leaves : 1), "KD ropes");
    as_kd_leaf_box_t *boxes = as_aligned_alloc(sizeof(as_kd_leaf_box_t) * (leaves ? leaves : 1), "KD leaf boxes");
    if (!ropes || !boxes) {
        free(ropes);
        free(boxes);
        return as_get_error();
    }
    as_kd_compute_ropes(ns->data, ns->count, leaves, s->meta.bounds_lo, s->meta.bounds_hi, ropes, boxes);
    as_structure_add_section(s, ASF_TAG_KDRP, ropes, leaves, sizeof(as_kd_ropes_t));
    as_structure_add_section(s, ASF_TAG_KDLB, boxes, leaves, sizeof(as_kd_leaf_box_t));
    s->meta.layout = AS_LAYOUT_KD_ROPES;
    return AS_OK;
}
