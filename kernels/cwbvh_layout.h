/* The compressed wide BVH of Ylitie, Karras & Laine 2017 (section CWBV):
 * 8-wide nodes of 80 bytes whose child boxes are quantized to 8 bits per
 * plane against a per-node origin and power-of-two scales. The leaves'
 * triangles are the TRI4 section of the binary layouts (bvh2_layout.h), in
 * the order the leaves reference them. */
#ifndef AS_CWBVH_LAYOUT_H
#define AS_CWBVH_LAYOUT_H

#include "bvh2_layout.h"

/* 80 bytes, 16-byte aligned: five 16-byte loads on the GPU.
 *   p: the origin of the quantization grid (the node's box minimum).
 *   e[a]: the grid step on axis a is 2^(e[a] - 127), i.e. the float whose
 *   exponent bits are e[a] and whose mantissa is zero; 1 <= e[a] <= 254.
 *   imask: bit s set when slot s holds an inner node.
 *   child_base: index in CWBV of the node in the first inner slot; the inner
 *   children follow each other in slot order, so the node in slot s is
 *   child_base + (inner slots below s).
 *   tri_base: index in TRI4 of the first triangle of the node's leaves.
 *   meta[s]: 0 for an empty slot; an inner node: 0x38 | s (top bits 001,
 *   low five bits 24 + s); a leaf of n = 1..3 triangles at TRI4 index
 *   tri_base + o (o + n <= 24): the top three bits the unary count (001,
 *   011, 111), the low five bits o.
 *   qlo[a][s], qhi[a][s]: slot s's box on axis a is
 *   [p[a] + 2^(e[a]-127) qlo[a][s], p[a] + 2^(e[a]-127) qhi[a][s]], each
 *   value one float multiplication (exact) and one float addition rounded
 *   to nearest, as the traversal computes it; it contains the child's box.
 *   Empty slots have all their q bytes zero.
 * A ray whose direction has the signs of octant o (bit a set when its
 * component a is negative) visits the children it enters in descending
 * order of s ^ (7 ^ o), so slot o first; the builder puts in slot s the
 * child lying farthest towards the corner that is high on axis a when bit
 * a of s is set, which that ray meets first.
 * Node 0 is the root; children come after their parent. */
typedef struct __attribute__((aligned(16))) as_cwbvh_node {
    float p[3];
    uint8_t e[3];
    uint8_t imask;
    uint32_t child_base;
    uint32_t tri_base;
    uint8_t meta[8];
    uint8_t qlo[3][8];
    uint8_t qhi[3][8];
} as_cwbvh_node_t;

#ifndef __CUDACC__
_Static_assert(sizeof(as_cwbvh_node_t) == 80, "as_cwbvh_node_t is 80 bytes");
#else
static_assert(sizeof(as_cwbvh_node_t) == 80, "as_cwbvh_node_t is 80 bytes");
#endif

/* The deepest inner node the traversal's stack holds (root: depth 0): the
 * stack keeps at most one group per ancestor of the node being fetched. */
#define AS_CWBVH_MAX_DEPTH 64
/* The most triangles one leaf slot encodes (the unary count's three bits). */
#define AS_CWBVH_MAX_LEAF 3
#define AS_CWBVH_LAYOUT_VERSION 1

#define AS_CWBVH_META_INNER(slot) ((uint8_t)(0x38u | (uint32_t)(slot)))

/* Whether a non-zero meta byte names an inner node (its low five bits are
 * 24..31, which no leaf offset reaches). */
AS_HD int as_cwbvh_meta_is_inner(uint32_t meta) { return (meta & 0x18u) == 0x18u; }

/* Triangles of a leaf meta byte: the unary count in its top three bits. */
AS_HD uint32_t as_cwbvh_meta_count(uint32_t meta)
{
    const uint32_t u = meta >> 5;
    return (u & 1u) + ((u >> 1) & 1u) + ((u >> 2) & 1u);
}

/* 2^(e - 127) for 1 <= e <= 254: exact. */
AS_HD float as_cwbvh_scale(uint32_t e) { return as_uint_as_float(e << 23); }

/* A quantized plane as the traversal and the validators compute it. */
AS_HD float as_cwbvh_decode(float p, float scale, uint32_t q)
{
    return AS_ADD(p, AS_MUL(scale, (float)q));
}

#endif
