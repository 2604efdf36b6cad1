/* The octree layout (sections OCTH and OCTN): the structs the builder
 * writes, the file stores and the CPU and GPU traversals read. */
#ifndef AS_OCTREE_LAYOUT_H
#define AS_OCTREE_LAYOUT_H

#include "as_kernel_common.h"

/* 16 bytes, one record; read by both. The root cell is the cube
 * [lo, lo + size] on every axis. The builder makes it slightly larger than
 * the scene's box so that no triangle lies on its faces. */
typedef struct as_octree_header {
    float lo[3];
    float size;
} as_octree_header_t;

/* 8 bytes, 4-byte aligned; read by both.
 *   count == AS_OCTREE_INNER: an inner node whose eight children are nodes
 *     first .. first + 7, child (x << 2) | (y << 1) | z holding the upper half
 *     on each axis whose bit is set (Revelles et al.'s numbering);
 *   otherwise a leaf of PRIM entries [first, first + count) (count 0: an
 *     empty leaf).
 * Node 0 is the root. */
typedef struct as_octree_node {
    uint32_t first;
    uint32_t count;
} as_octree_node_t;

#ifndef __CUDACC__
_Static_assert(sizeof(as_octree_header_t) == 16, "as_octree_header_t is 16 bytes");
_Static_assert(sizeof(as_octree_node_t) == 8, "as_octree_node_t is 8 bytes");
#else
static_assert(sizeof(as_octree_header_t) == 16, "as_octree_header_t is 16 bytes");
static_assert(sizeof(as_octree_node_t) == 8, "as_octree_node_t is 8 bytes");
#endif

#define AS_OCTREE_INNER 0xFFFFFFFFu
/* The deepest level the traversal stack holds (root = depth 0). */
#define AS_OCTREE_MAX_DEPTH 16
/* The depth limit when the build arguments give none (the study's octrees
 * are 12 deep). */
#define AS_OCTREE_DEFAULT_DEPTH 12
#define AS_OCTREE_LAYOUT_VERSION 1

#endif
