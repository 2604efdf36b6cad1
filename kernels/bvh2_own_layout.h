/* The classic BVH2 layout in which every node stores its own box (section
 * BVHO), the paper's first and slower BVH version; the leaf triangles are
 * the same TRI4 section as in the child-bounds layout (bvh2_layout.h). */
#ifndef AS_BVH2_OWN_LAYOUT_H
#define AS_BVH2_OWN_LAYOUT_H

#include "bvh2_layout.h"

/* 32 bytes, 16-byte aligned; read by both CPU and GPU (two 16-byte loads:
 * lo.xyz hi.x, then hi.yz child count).
 *   lo, hi: the node's own box. An empty leaf (the empty sibling of a
 *   one-leaf tree) has lo = +inf, hi = -inf, so no ray enters it.
 *   child >= 0: an inner node; its children are nodes child and child + 1,
 *   and count is 0.
 *   child < 0: a leaf whose triangles start at TRI4 index ~child and number
 *   count (0: the empty leaf).
 * Node 0 is the root and always an inner node; children come after their
 * parent. A node at depth d (root 0) holds at most d stack entries below it,
 * so AS_BVH2_MAX_DEPTH bounds the stack as in the child-bounds layout. */
typedef struct __attribute__((aligned(16))) as_bvh2o_node {
    float lo[3];
    float hi[3];
    int32_t child;
    uint32_t count;
} as_bvh2o_node_t;

#ifndef __CUDACC__
_Static_assert(sizeof(as_bvh2o_node_t) == 32, "as_bvh2o_node_t is 32 bytes");
#else
static_assert(sizeof(as_bvh2o_node_t) == 32, "as_bvh2o_node_t is 32 bytes");
#endif

#define AS_BVH2O_LAYOUT_VERSION 1

#endif
