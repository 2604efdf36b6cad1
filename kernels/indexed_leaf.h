/* The leaf test shared by the BIH, octree and grid traversals: a list of
 * uint32 source indices (section PRIM) into one triangle per source triangle
 * in source order (section TRIS, as_tri4_t, v0.w = the index's bits). */
#ifndef AS_INDEXED_LEAF_H
#define AS_INDEXED_LEAF_H

#include "bvh2_traverse.h" /* as_hit_rec_t, as_trace_counters_t, as_tri4_t */

AS_HD uint32_t as_load_u32(const uint32_t *p)
{
#ifdef __CUDA_ARCH__
    return __ldg(p);
#else
    return *p;
#endif
}

/* Tests triangles TRIS[PRIM[first + i]] for i in [0, count) over the whole ray
 * interval [tmin, min(hit t, tmax)], not only the part inside the leaf:
 * whatever it finds is a true hit, and the caller decides when a hit is final
 * (BIH: never before the stack is empty; octree and grid: once its t is
 * within the current cell). Equal t goes to the lowest source index, as in
 * as_bvh2_leaf. Returns 1 when any_hit is set and something was hit. */
AS_HD int as_indexed_leaf(const as_ray_pre_t *r, const as_tri4_t *AS_RESTRICT tris,
                          const uint32_t *AS_RESTRICT prims, uint32_t first, uint32_t count,
                          int any_hit, as_hit_rec_t *hit, as_trace_counters_t *ctr)
{
    for (uint32_t i = 0; i < count; ++i) {
        const uint32_t prim = as_load_u32(prims + first + i);
        const as_tri4_t *tri = tris + prim;
        const as_f4_t v0 = as_load_f4(&tri->v0), v1 = as_load_f4(&tri->v1), v2 = as_load_f4(&tri->v2);
        float t, u, v;
        if (ctr) ctr->tri_tests++;
        if (as_ray_triangle(r, &tri->v0, v0, v1, v2, AS_MINF(hit->t, r->tmax), &t, &u, &v)) {
            if (t < hit->t || prim < hit->prim) {
                hit->t = t;
                hit->prim = prim;
                hit->u = u;
                hit->v = v;
            }
            if (any_hit) return 1;
        }
    }
    return 0;
}

#endif
