/* The BVH2 child-bounds layout (section BVH2) and the leaf triangles
 * (section TRI4): the structs the builder writes, the file stores, and the
 * CPU and GPU traversals read, byte for byte. */
#ifndef AS_BVH2_LAYOUT_H
#define AS_BVH2_LAYOUT_H

#include "as_kernel_common.h"

/* 64 bytes, 16-byte aligned; read by both CPU and GPU. A node stores the
 * boxes of both its children (Aila & Laine 2009), so one node fetch decides
 * which children a ray enters and in what order, without fetching them.
 *   xy0 = child 0: lo.x, hi.x, lo.y, hi.y
 *   xy1 = child 1: lo.x, hi.x, lo.y, hi.y
 *   z01 = child 0 lo.z, hi.z; child 1 lo.z, hi.z
 *   child[i] >= 0: index of an inner node; < 0: a leaf whose triangles start
 *   at TRI4 index ~child[i] and number count[i] (count 0: an empty child,
 *   whose box is inverted so that no ray enters it).
 * Node 0 is the root; an inner node's children come after it. */
typedef struct __attribute__((aligned(16))) as_bvh2_node {
    as_f4_t xy0;
    as_f4_t xy1;
    as_f4_t z01;
    int32_t child[2];
    uint32_t count[2];
} as_bvh2_node_t;

/* 48 bytes, 16-byte aligned; read by both. A triangle's vertices in the
 * order of the leaves; v0.w holds the triangle's index in the source mesh
 * (uint32 bits), v1.w and v2.w are zero. */
typedef struct __attribute__((aligned(16))) as_tri4 {
    as_f4_t v0, v1, v2;
} as_tri4_t;

#ifndef __CUDACC__
_Static_assert(sizeof(as_bvh2_node_t) == 64, "as_bvh2_node_t is 64 bytes");
_Static_assert(sizeof(as_tri4_t) == 48, "as_tri4_t is 48 bytes");
#else
static_assert(sizeof(as_bvh2_node_t) == 64, "as_bvh2_node_t is 64 bytes");
static_assert(sizeof(as_tri4_t) == 48, "as_tri4_t is 48 bytes");
#endif

/* The deepest tree the traversal stack holds: one entry per level. Builders
 * make a leaf at this depth whatever its size. */
#define AS_BVH2_MAX_DEPTH 64
#define AS_BVH2_LAYOUT_VERSION 1

#endif
