/* Traversal of the compressed wide BVH (cwbvh_layout.h), written once for
 * the CPU and the GPU, after Ylitie, Karras & Laine 2017: the stack holds
 * node groups (a node's inner children the ray entered, as a base index and
 * a mask), and the hit mask of a node's leaves is a triangle group tested
 * before the traversal goes down. The entered children are taken nearest
 * octant first from the mask, so the order costs no sorting. Boxes are
 * decoded to floats exactly as the validators decode them and tested with
 * the conservative slab test of bvh2_traverse.h (Ize's widening of the far
 * distance; -0 and +0 directions alike). Same hit semantics as
 * as_bvh2_trace: closest hit in [tmin, tmax], equal t to the lowest source
 * index. */
#ifndef AS_CWBVH_TRAVERSE_H
#define AS_CWBVH_TRAVERSE_H

#include "cwbvh_layout.h"
#include "bvh2_traverse.h"

AS_HD uint32_t as_popc32(uint32_t x)
{
#if defined(__CUDA_ARCH__)
    return (uint32_t)__popc(x);
#elif defined(__POPCNT__) || !(defined(__x86_64__) || defined(__i386__))
    return (uint32_t)__builtin_popcount(x);
#else
    /* x86 without POPCNT in the target: __builtin_popcount would call
     * libgcc's table loop once per node visited. */
    x = x - ((x >> 1) & 0x55555555u);
    x = (x & 0x33333333u) + ((x >> 2) & 0x33333333u);
    x = (x + (x >> 4)) & 0x0f0f0f0fu;
    return (x * 0x01010101u) >> 24;
#endif
}

/* Index of the highest set bit of a non-zero word. */
AS_HD uint32_t as_high_bit32(uint32_t x)
{
#ifdef __CUDA_ARCH__
    return 31u - (uint32_t)__clz(x);
#else
    return 31u - (uint32_t)__builtin_clz(x);
#endif
}

/* The 80 bytes of a node as twenty little-endian words. */
typedef struct as_cwbvh_words {
    uint32_t w[20];
} as_cwbvh_words_t;

AS_HD void as_cwbvh_load(const as_cwbvh_node_t *n, as_cwbvh_words_t *out)
{
    const as_f4_t *p = (const as_f4_t *)n;
    for (int k = 0; k < 5; ++k) {
        const as_f4_t v = as_load_f4(p + k);
        out->w[4 * k + 0] = as_float_as_uint(v.x);
        out->w[4 * k + 1] = as_float_as_uint(v.y);
        out->w[4 * k + 2] = as_float_as_uint(v.z);
        out->w[4 * k + 3] = as_float_as_uint(v.w);
    }
}

/* Byte `i` (0..7) of the eight-byte array at word `first`. */
AS_HD uint32_t as_cwbvh_byte(const as_cwbvh_words_t *n, int first, int i)
{
    return (n->w[first + (i >> 2)] >> (8 * (i & 3))) & 0xffu;
}

/* Word offsets of the node's fields (see as_cwbvh_node_t). */
#define AS_CWBVH_W_P 0
#define AS_CWBVH_W_E_IMASK 3
#define AS_CWBVH_W_CHILD 4
#define AS_CWBVH_W_TRI 5
#define AS_CWBVH_W_META 6
#define AS_CWBVH_W_QLO 8
#define AS_CWBVH_W_QHI 14

/* Traces one prepared ray; on return `hit` holds the closest hit in
 * [tmin, tmax] (any hit when any_hit is set) or a miss. `ctr` may be NULL:
 * node_visits counts node fetches and leaves entered, as the other
 * traversals count theirs. */
AS_HD void as_cwbvh_trace(const as_cwbvh_node_t *AS_RESTRICT nodes, const as_tri4_t *AS_RESTRICT tris,
                          const as_ray_pre_t *r, int any_hit, as_hit_rec_t *hit, as_trace_counters_t *ctr)
{
    /* A node group: base index of the inner children, and a mask whose bits
     * 24..31 are the entered children by visiting key (slot ^ oct_inv) and
     * bits 0..7 the parent's imask, which turns a slot into an index. */
    uint32_t stack_base[AS_CWBVH_MAX_DEPTH], stack_mask[AS_CWBVH_MAX_DEPTH];
    int sp = 0;
    /* Descending keys visit slot o first for a ray of octant o. */
    const uint32_t oct_inv = (r->dx < 0.0f ? 0u : 1u) | (r->dy < 0.0f ? 0u : 2u) | (r->dz < 0.0f ? 0u : 4u);
    /* The root as the only member of a group: slot 0, index 0. */
    uint32_t gbase = 0, gmask = (1u << (24 + oct_inv)) | 1u;
    as_hit_rec_miss(hit);
    float tmax = r->tmax;
    for (;;) {
        if ((gmask & 0xff000000u) == 0) {
            if (sp == 0) return;
            --sp;
            gbase = stack_base[sp];
            gmask = stack_mask[sp];
        }
        const uint32_t bit = as_high_bit32(gmask);
        gmask &= ~(1u << bit);
        const uint32_t slot = (bit - 24u) ^ oct_inv;
        const uint32_t index = gbase + as_popc32(gmask & 0xffu & ((1u << slot) - 1u));
        as_cwbvh_words_t n;
        as_cwbvh_load(nodes + index, &n);
        if (ctr) ctr->node_visits++;
        const float px = as_uint_as_float(n.w[AS_CWBVH_W_P]), py = as_uint_as_float(n.w[AS_CWBVH_W_P + 1]),
                    pz = as_uint_as_float(n.w[AS_CWBVH_W_P + 2]);
        const uint32_t ei = n.w[AS_CWBVH_W_E_IMASK];
        const float sx = as_cwbvh_scale(ei & 0xffu), sy = as_cwbvh_scale((ei >> 8) & 0xffu),
                    sz = as_cwbvh_scale((ei >> 16) & 0xffu);
        uint32_t inner_hits = 0, leaf_hits = 0;
#ifdef __CUDA_ARCH__
#pragma unroll
#endif
        for (int s = 0; s < 8; ++s) {
            const uint32_t meta = as_cwbvh_byte(&n, AS_CWBVH_W_META, s);
            if (meta == 0) continue;
            const float lox = as_cwbvh_decode(px, sx, as_cwbvh_byte(&n, AS_CWBVH_W_QLO, s));
            const float loy = as_cwbvh_decode(py, sy, as_cwbvh_byte(&n, AS_CWBVH_W_QLO + 2, s));
            const float loz = as_cwbvh_decode(pz, sz, as_cwbvh_byte(&n, AS_CWBVH_W_QLO + 4, s));
            const float hix = as_cwbvh_decode(px, sx, as_cwbvh_byte(&n, AS_CWBVH_W_QHI, s));
            const float hiy = as_cwbvh_decode(py, sy, as_cwbvh_byte(&n, AS_CWBVH_W_QHI + 2, s));
            const float hiz = as_cwbvh_decode(pz, sz, as_cwbvh_byte(&n, AS_CWBVH_W_QHI + 4, s));
            float t;
            if (!as_ray_box(r, lox, hix, loy, hiy, loz, hiz, tmax, &t)) continue;
            if (as_cwbvh_meta_is_inner(meta))
                inner_hits |= 1u << (24 + ((uint32_t)s ^ oct_inv));
            else
                leaf_hits |= 1u << ((uint32_t)s ^ oct_inv);
        }
        /* The triangle group, nearest leaf first: it shortens tmax before
         * the children below are fetched and tested. */
        const uint32_t tri_base = n.w[AS_CWBVH_W_TRI];
        /* The slot is known only at run time here: a shift of the meta
         * bytes as one word, not an index into the node's registers. */
        const uint64_t metas = (uint64_t)n.w[AS_CWBVH_W_META] | ((uint64_t)n.w[AS_CWBVH_W_META + 1] << 32);
        while (leaf_hits) {
            const uint32_t key = as_high_bit32(leaf_hits);
            leaf_hits &= ~(1u << key);
            const uint32_t meta = (uint32_t)(metas >> (8u * (key ^ oct_inv))) & 0xffu;
            if (as_bvh2_leaf(r, tris, tri_base + (meta & 31u), as_cwbvh_meta_count(meta), any_hit, hit, ctr)) return;
            tmax = AS_MINF(tmax, hit->t);
        }
        if (inner_hits) {
            /* The rest of the current group waits on the stack (one entry
             * per ancestor level at most); the new group becomes current. */
            if (gmask & 0xff000000u) {
                stack_base[sp] = gbase;
                stack_mask[sp] = gmask;
                ++sp;
            }
            gbase = n.w[AS_CWBVH_W_CHILD];
            gmask = inner_hits | ((ei >> 24) & 0xffu);
        }
    }
}

#endif
