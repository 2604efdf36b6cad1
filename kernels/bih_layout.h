/* The BIH layout (section BIHN) of Wachter & Keller 2006, "Instant ray
 * tracing: the bounding interval hierarchy": the struct the builder writes,
 * the file stores, and the CPU and GPU traversals read. */
#ifndef AS_BIH_LAYOUT_H
#define AS_BIH_LAYOUT_H

#include "as_kernel_common.h"

/* 12 bytes, 4-byte aligned; read by both CPU and GPU.
 *   info & 3 = axis 0..2: an inner node. clip[0] is the left child's upper
 *     bound and clip[1] the right child's lower bound on that axis; the
 *     children are nodes (info >> 2) (left) and (info >> 2) + 1 (right).
 *   info & 3 = 3: a leaf of PRIM entries [info >> 2, (info >> 2) + count),
 *     count being clip[0]'s bits as a uint32; clip[1] is zero.
 * Node 0 is the root (a leaf when the scene is that small). The root's box
 * is the scene box, META bounds_lo/bounds_hi. 12 bytes instead of 16: the
 * paper's point for the BIH is its small memory, and a node is read with
 * three 4-byte loads either way. */
typedef struct as_bih_node {
    float clip[2];
    uint32_t info;
} as_bih_node_t;

#ifndef __CUDACC__
_Static_assert(sizeof(as_bih_node_t) == 12, "as_bih_node_t is 12 bytes");
#else
static_assert(sizeof(as_bih_node_t) == 12, "as_bih_node_t is 12 bytes");
#endif

#define AS_BIH_LEAF 3u
/* Node and PRIM indices have 30 bits. */
#define AS_BIH_MAX_INDEX 0x3FFFFFFFu
/* The deepest node the traversal stack holds (root = depth 0). */
#define AS_BIH_MAX_DEPTH 64
#define AS_BIH_LAYOUT_VERSION 1

#endif
