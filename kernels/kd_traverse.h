/* KD-standard traversal (Wald's thesis, Havran's TA_B): a stack of (node,
 * tnear, tfar) entries, 8-byte nodes, written once for the CPU and the GPU.
 * The entry keeps its own tnear (rather than the previous tfar) because a
 * ray lying in a split plane visits both children over the same interval.
 *
 * Hit acceptance. A triangle that crosses a split plane is referenced by
 * leaves on both sides, so a leaf may report a hit that lies beyond the leaf.
 * Every hit found is a true hit in [tmin, tmax]; the traversal keeps the
 * closest (ties to the lowest source index, as the BVH does) and stops only
 * when the next leaf starts beyond it. "Beyond" is widened by a relative
 * margin that covers the rounding of the split distances, so a leaf that the
 * exact ray enters before the hit is never skipped, and a hit at exactly the
 * distance where the next leaf starts still meets the equal-t hits there. */
#ifndef AS_KD_TRAVERSE_H
#define AS_KD_TRAVERSE_H

#include "kd_layout.h"
#include "bvh2_traverse.h" /* as_hit_rec_t, as_trace_counters_t, as_hit_rec_miss */

/* t plus a margin of about 80 float ulps of t: far above the few ulps a split
 * distance or a hit distance can be off, far below any real gap. */
AS_HD float as_kd_widen(float t) { return t + fabsf(t) * 1e-5f + 1e-30f; }

/* Clips [tmin, tmax] to the scene box; 0 when the ray misses it. The same
 * robust slab test as as_ray_box, returning both ends. */
AS_HD int as_kd_clip_scene(const as_ray_pre_t *r, const float box[6], float *t0, float *t1)
{
    const float nx = r->ix >= 0.0f ? box[0] : box[3], fx = r->ix >= 0.0f ? box[3] : box[0];
    const float ny = r->iy >= 0.0f ? box[1] : box[4], fy = r->iy >= 0.0f ? box[4] : box[1];
    const float nz = r->iz >= 0.0f ? box[2] : box[5], fz = r->iz >= 0.0f ? box[5] : box[2];
    const float t0x = AS_MUL(AS_SUB(nx, r->ox), r->ix), t1x = AS_MUL(AS_SUB(fx, r->ox), r->ix);
    const float t0y = AS_MUL(AS_SUB(ny, r->oy), r->iy), t1y = AS_MUL(AS_SUB(fy, r->oy), r->iy);
    const float t0z = AS_MUL(AS_SUB(nz, r->oz), r->iz), t1z = AS_MUL(AS_SUB(fz, r->oz), r->iz);
    const float tn = AS_MAXF(AS_MAXF(t0x, t0y), AS_MAXF(t0z, r->tmin));
    const float tf = AS_MINF(AS_MINF(t1x, t1y), AS_MINF(t1z, r->tmax)) * AS_BOX_FAR_SCALE;
    *t0 = tn;
    *t1 = AS_MINF(tf, r->tmax);
    return tn <= tf;
}

/* Tests a leaf's list (PRIM[offset] = n, then n source indices into TRIS) and
 * updates the hit; returns 1 when any_hit is set and something was hit. */
AS_HD int as_kd_leaf(const as_ray_pre_t *r, const uint32_t *AS_RESTRICT prim, const as_tri4_t *AS_RESTRICT tris,
                     uint32_t offset, int any_hit, as_hit_rec_t *hit, as_trace_counters_t *ctr)
{
    const uint32_t n = prim[offset];
    for (uint32_t i = 1; i <= n; ++i) {
        const as_tri4_t *tri = tris + prim[offset + i];
        const as_f4_t v0 = as_load_f4(&tri->v0), v1 = as_load_f4(&tri->v1), v2 = as_load_f4(&tri->v2);
        float t, u, v;
        if (ctr) ctr->tri_tests++;
        if (as_ray_triangle(r, &tri->v0, v0, v1, v2, AS_MINF(hit->t, r->tmax), &t, &u, &v)) {
            const uint32_t id = as_float_as_uint(v0.w);
            if (t < hit->t || id < hit->prim) {
                hit->t = t;
                hit->prim = id;
                hit->u = u;
                hit->v = v;
            }
            if (any_hit) return 1;
        }
    }
    return 0;
}

AS_HD as_kd_node_t as_kd_load_node(const as_kd_node_t *n)
{
#ifdef __CUDA_ARCH__
    const uint2 v = __ldg((const uint2 *)n);
    as_kd_node_t r = {v.x, v.y};
    return r;
#else
    return *n;
#endif
}

/* Traces one prepared ray through a KD-standard tree whose root box is
 * `box` (lo xyz, hi xyz); `hit` gets the closest hit in [tmin, tmax] (any hit
 * when any_hit is set) or a miss. `ctr` may be NULL. The tree must have passed
 * validation: depth at most AS_KD_MAX_DEPTH, so the stack cannot overflow. */
AS_HD void as_kd_trace(const as_kd_node_t *AS_RESTRICT nodes, const uint32_t *AS_RESTRICT prim,
                       const as_tri4_t *AS_RESTRICT tris, const float box[6], const as_ray_pre_t *r, int any_hit,
                       as_hit_rec_t *hit, as_trace_counters_t *ctr)
{
    as_hit_rec_miss(hit);
    float tnear, tfar;
    if (!as_kd_clip_scene(r, box, &tnear, &tfar)) return;
    struct { uint32_t node; float tnear, tfar; } stack[AS_KD_MAX_DEPTH + 1];
    int sp = 0;
    uint32_t node = 0;
    const float o[3] = {r->ox, r->oy, r->oz}, d[3] = {r->dx, r->dy, r->dz}, inv[3] = {r->ix, r->iy, r->iz};
    for (;;) {
        /* A node that starts beyond the closest hit (or tmax) holds nothing
         * nearer. The stack is not quite in increasing tnear (a ray lying in
         * a split plane pushes a child with the current tnear), so the
         * others are still looked at: popping is cheap. */
        if (tnear > as_kd_widen(AS_MINF(hit->t, r->tmax))) {
            if (sp == 0) return;
            --sp;
            node = stack[sp].node;
            tnear = stack[sp].tnear;
            tfar = stack[sp].tfar;
            continue;
        }
        as_kd_node_t n = as_kd_load_node(nodes + node);
        while (!as_kd_is_leaf(n.word1)) {
            if (ctr) ctr->node_visits++;
            const int axis = (int)(n.word1 & 3u);
            const float split = as_uint_as_float(n.word0);
            const uint32_t below = node + 1, above = n.word1 >> 2;
            if (d[axis] == 0.0f) {
                /* Parallel to the plane: the side of the origin, or both when
                 * the ray lies in the plane (as_ray_prepare made -0 +0). */
                if (o[axis] == split) {
                    stack[sp].node = above;
                    stack[sp].tnear = tnear;
                    stack[sp].tfar = tfar;
                    ++sp;
                    node = below;
                } else {
                    node = o[axis] < split ? below : above;
                }
            } else {
                /* The child the ray is in before it crosses the plane. */
                const uint32_t first = d[axis] > 0.0f ? below : above, second = first == below ? above : below;
                const float tsplit = AS_MUL(AS_SUB(split, o[axis]), inv[axis]);
                const float m = (fabsf(tnear) + fabsf(tfar)) * 1e-5f;
                if (tsplit > tfar + m) {
                    node = first;
                } else if (tsplit < tnear - m) {
                    node = second;
                } else {
                    const float ts = AS_MINF(AS_MAXF(tsplit, tnear), tfar);
                    stack[sp].node = second;
                    stack[sp].tnear = ts;
                    stack[sp].tfar = tfar;
                    ++sp;
                    tfar = ts;
                    node = first;
                }
            }
            n = as_kd_load_node(nodes + node);
        }
        if (as_kd_leaf(r, prim, tris, n.word0, any_hit, hit, ctr)) return;
        if (sp == 0) return;
        --sp;
        node = stack[sp].node;
        tnear = stack[sp].tnear;
        tfar = stack[sp].tfar;
    }
}

#endif
