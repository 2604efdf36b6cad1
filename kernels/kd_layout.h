/* The KD-tree layouts: KD-standard (sections KDN8, PRIM, TRIS) and KD ropes
 * (the same three plus KDRP and KDLB). The structs the builders write, the
 * file stores, and the CPU and GPU traversals read, byte for byte. */
#ifndef AS_KD_LAYOUT_H
#define AS_KD_LAYOUT_H

#include "as_kernel_common.h"
#include "bvh2_layout.h" /* as_tri4_t: the TRIS section */

/* 8 bytes, 4-byte aligned; read by both CPU and GPU (one 8-byte load).
 * Inner node: word0 = split position (float bits),
 *             word1 = (above child index << 2) | axis (0, 1, 2);
 *             the below child is the next node (index + 1).
 * Leaf:       word0 = offset in PRIM of the leaf's list: PRIM[word0] is the
 *             triangle count n, PRIM[word0 + 1 .. word0 + n] the source
 *             triangle indices (ascending);
 *             word1 = (leaf index << 2) | 3. The leaf index (0 .. leaves-1,
 *             depth-first order) selects the leaf's ropes and box in the
 *             rope layout; keeping the count in PRIM leaves room for it, so
 *             both layouts share the node bytes.
 * Node 0 is the root; nodes are stored depth first, below subtree first. */
typedef struct __attribute__((aligned(8))) as_kd_node {
    uint32_t word0;
    uint32_t word1;
} as_kd_node_t;

/* 24 bytes, 4-byte aligned; read by the rope traversal (CPU and GPU). The six
 * ropes of a leaf, face 2 * axis + (1 for the max side): the deepest node
 * whose box covers the whole face from the other side, or -1 where the face
 * lies on the scene box. */
typedef struct as_kd_ropes {
    int32_t rope[6];
} as_kd_ropes_t;

/* 24 bytes, 4-byte aligned; read by the rope traversal (CPU and GPU): the
 * leaf's box, exactly the split positions (and scene box) that bound it.
 * The exit face is one of the three floats chosen by the ray's signs. */
typedef struct as_kd_leaf_box {
    float lo[3];
    float hi[3];
} as_kd_leaf_box_t;

#ifndef __CUDACC__
_Static_assert(sizeof(as_kd_node_t) == 8, "as_kd_node_t is 8 bytes");
_Static_assert(sizeof(as_kd_ropes_t) == 24, "as_kd_ropes_t is 24 bytes");
_Static_assert(sizeof(as_kd_leaf_box_t) == 24, "as_kd_leaf_box_t is 24 bytes");
#else
static_assert(sizeof(as_kd_node_t) == 8, "as_kd_node_t is 8 bytes");
static_assert(sizeof(as_kd_ropes_t) == 24, "as_kd_ropes_t is 24 bytes");
static_assert(sizeof(as_kd_leaf_box_t) == 24, "as_kd_leaf_box_t is 24 bytes");
#endif

#define AS_KD_LEAF_TAG 3u
/* The deepest tree the KD-standard stack holds (one entry per level);
 * builders cap the depth at this, validation rejects deeper trees. */
#define AS_KD_MAX_DEPTH 64
#define AS_KD_LAYOUT_VERSION 1

AS_HD int as_kd_is_leaf(uint32_t word1) { return (word1 & 3u) == AS_KD_LEAF_TAG; }

#endif
