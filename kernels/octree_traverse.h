/* Parametric octree traversal of Revelles, Urena & Lastra 2000 ("An
 * efficient parametric algorithm for octree traversal"), written once for
 * the CPU and the GPU, without recursion: an explicit stack holds, per
 * level, the node, its parametric entry and exit distances on the three
 * axes, its mid-plane distances and the child the state machine is at.
 *
 * Direction signs: as in the paper, the traversal runs in a space mirrored
 * so that every direction component is non-negative, and the mask `a` maps
 * the mirrored child numbers to stored ones (child ^ a). The mirroring is
 * only logical: on a negative axis the entry plane is the cell's upper face,
 * so no mirrored origin is ever computed and rounded.
 *
 * Zero direction components: as_ray_prepare turns -0 into +0 with inverse
 * +inf, so +0 and -0 run identically. A plane's distance (c - o) * inf is
 * +inf when the plane lies ahead of the origin, -inf behind it, and NaN when
 * the origin is on it; NaN becomes -inf (the origin counts as past the
 * plane, in the upper child, which holds every triangle touching the plane
 * since the builder's overlap test is inclusive). Mid planes are computed
 * from the cell's coordinates (lo + half), not as the mean of the entry and
 * exit distances, which would be inf - inf on such an axis.
 *
 * A triangle may be referenced by several leaves, so a hit is final only
 * when its t is within the current leaf's exit distance; leaves are visited
 * front to back, so the first leaf for which that holds ends the ray. */
#ifndef AS_OCTREE_TRAVERSE_H
#define AS_OCTREE_TRAVERSE_H

#include "octree_layout.h"
#include "indexed_leaf.h"

AS_HD float as_oct_plane_t(float c, float o, float inv)
{
    const float t = AS_MUL(AS_SUB(c, o), inv);
    return t == t ? t : -as_inf();
}

/* Revelles et al., table 1: the first child the ray enters, from the entry
 * distances t0 and the mid-plane distances tm (mirrored space). */
AS_HD int as_oct_first_node(const float t0[3], const float tm[3])
{
    int answer = 0;
    if (t0[0] > t0[1] && t0[0] > t0[2]) {        /* enters through a YZ face */
        if (tm[1] < t0[0]) answer |= 2;
        if (tm[2] < t0[0]) answer |= 1;
    } else if (t0[1] > t0[2]) {                  /* an XZ face */
        if (tm[0] < t0[1]) answer |= 4;
        if (tm[2] < t0[1]) answer |= 1;
    } else {                                     /* an XY face */
        if (tm[0] < t0[2]) answer |= 4;
        if (tm[1] < t0[2]) answer |= 2;
    }
    return answer;
}

/* Revelles et al., table 2: the next child after `child`, leaving it through
 * the axis whose exit distance is smallest; 8 when it leaves the parent. The
 * child's exit on an axis is the mid plane when its bit is clear (next:
 * the bit set) and the parent's exit when set (next: 8). */
AS_HD int as_oct_new_node(int child, const float tm[3], const float t1[3])
{
    const float ex = (child & 4) ? t1[0] : tm[0];
    const float ey = (child & 2) ? t1[1] : tm[1];
    const float ez = (child & 1) ? t1[2] : tm[2];
    if (ex < ey) {
        if (ex < ez) return (child & 4) ? 8 : child | 4;
    } else if (ey < ez) {
        return (child & 2) ? 8 : child | 2;
    }
    return (child & 1) ? 8 : child | 1;
}

/* The edge of a cell at `depth`: size * 2^-depth, exact (a power of two
 * times a float); the builder computes cell corners with the same float
 * operations (lo + this), so both agree on every plane. */
AS_HD float as_oct_cell_size(float size, int depth)
{
    return AS_MUL(size, as_uint_as_float((uint32_t)(127 - depth) << 23));
}

typedef struct as_oct_level {
    uint32_t node;
    int child;                 /* the state machine's current child (mirrored) */
    float t0[3], t1[3], tm[3]; /* mirrored space: t0 entry, t1 exit per axis */
    float lo[3];               /* the cell's lower corner (stored space) */
} as_oct_level_t;

/* Traces one prepared ray through the octree. */
AS_HD void as_octree_trace(const as_octree_header_t *AS_RESTRICT hdr, const as_octree_node_t *AS_RESTRICT nodes,
                           const uint32_t *AS_RESTRICT prims, const as_tri4_t *AS_RESTRICT tris,
                           const as_ray_pre_t *r, int any_hit, as_hit_rec_t *hit, as_trace_counters_t *ctr)
{
    as_hit_rec_miss(hit);
    const float org[3] = {r->ox, r->oy, r->oz}, inv[3] = {r->ix, r->iy, r->iz};
    const float size = hdr->size;
    int a = 0;
    as_oct_level_t st[AS_OCTREE_MAX_DEPTH + 1];
    for (int k = 0; k < 3; ++k) {
        const float lo = hdr->lo[k], hi = AS_ADD(hdr->lo[k], size);
        const int neg = inv[k] < 0.0f;
        if (neg) a |= 4 >> k;
        st[0].t0[k] = as_oct_plane_t(neg ? hi : lo, org[k], inv[k]);
        st[0].t1[k] = as_oct_plane_t(neg ? lo : hi, org[k], inv[k]);
        st[0].lo[k] = lo;
    }
    /* The ray must overlap the cube within [tmin, tmax]. On a zero axis the
     * entry is -inf and the exit +inf inside the slab, both -inf (or both
     * +inf) outside it. */
    {
        const float tn = AS_MAXF(AS_MAXF(st[0].t0[0], st[0].t0[1]), AS_MAXF(st[0].t0[2], r->tmin));
        const float tf = AS_MINF(AS_MINF(st[0].t1[0], st[0].t1[1]), AS_MINF(st[0].t1[2], r->tmax));
        if (!(tn <= tf * AS_BOX_FAR_SCALE)) return;
    }
    st[0].node = 0;
    st[0].child = -1;           /* not yet entered */
    int depth = 0;
    for (;;) {
        as_oct_level_t *L = &st[depth];
        const float entry = AS_MAXF(AS_MAXF(L->t0[0], L->t0[1]), L->t0[2]);
        const float exit = AS_MINF(AS_MINF(L->t1[0], L->t1[1]), L->t1[2]);
        if (L->child < 0) {
            /* First arrival at this cell. */
            const as_octree_node_t nd = nodes[L->node];
            if (ctr) ctr->node_visits++;
            const int skip = exit < r->tmin || entry > AS_MINF(hit->t, r->tmax) * AS_BOX_FAR_SCALE;
            if (nd.count != AS_OCTREE_INNER || skip) {
                if (!skip && nd.count) {
                    if (as_indexed_leaf(r, tris, prims, nd.first, nd.count, any_hit, hit, ctr)) return;
                    /* Leaves come front to back: a hit inside this one is the closest. */
                    if (hit->t <= exit) return;
                }
                if (depth == 0) return;
                --depth;
                continue;
            }
            const float half = as_oct_cell_size(size, depth + 1);
            for (int k = 0; k < 3; ++k) {
                const float mid = AS_ADD(L->lo[k], half);
                L->tm[k] = as_oct_plane_t(mid, org[k], inv[k]);
            }
            L->child = as_oct_first_node(L->t0, L->tm);
        } else {
            /* Back from child L->child: on to the next. */
            L->child = as_oct_new_node(L->child, L->tm, L->t1);
        }
        if (L->child >= 8) {
            if (depth == 0) return;
            --depth;
            continue;
        }
        /* Descend into child L->child (mirrored), stored child L->child ^ a. */
        const int c = L->child, sc = c ^ a;
        as_oct_level_t *C = &st[depth + 1];
        const uint32_t first = nodes[L->node].first;
        C->node = first + (uint32_t)sc;
        C->child = -1;
        const float half = as_oct_cell_size(size, depth + 1);
        for (int k = 0; k < 3; ++k) {
            const int bit = (c >> (2 - k)) & 1, sbit = (sc >> (2 - k)) & 1;
            C->t0[k] = bit ? L->tm[k] : L->t0[k];
            C->t1[k] = bit ? L->t1[k] : L->tm[k];
            C->lo[k] = sbit ? AS_ADD(L->lo[k], half) : L->lo[k];
        }
        ++depth;
    }
}

#endif
