/* Stack traversal of the BIH (Wachter & Keller 2006, section 3), written once
 * for the CPU and the GPU. A node clips the ray's interval [tn, tf] with its
 * two planes: the near child (the left one for a non-negative direction)
 * gets [tn, min(tf, t(near plane))], the far child [max(tn, t(far plane)),
 * tf]. Both non-empty: visit near, push far with its interval; one: visit
 * it; none: pop. Children may overlap, so a leaf's hit never ends the
 * traversal by itself: popped intervals that start beyond the best hit are
 * skipped, as in the BVH. */
#ifndef AS_BIH_TRAVERSE_H
#define AS_BIH_TRAVERSE_H

#include "bih_layout.h"
#include "indexed_leaf.h"

typedef struct as_bih_stack_entry {
    uint32_t node;
    float tn, tf;
} as_bih_stack_entry_t;

/* Traces one prepared ray through the BIH whose scene box is [lo, hi]. */
AS_HD void as_bih_trace(const as_bih_node_t *AS_RESTRICT nodes, const uint32_t *AS_RESTRICT prims,
                        const as_tri4_t *AS_RESTRICT tris, const float lo[3], const float hi[3],
                        const as_ray_pre_t *r, int any_hit, as_hit_rec_t *hit, as_trace_counters_t *ctr)
{
    as_hit_rec_miss(hit);
    float tn;
    if (!as_ray_box(r, lo[0], hi[0], lo[1], hi[1], lo[2], hi[2], r->tmax, &tn)) return;
    /* The far end of the box: the slab test's, recomputed (as_ray_box gives
     * only the near one). NaN terms (origin on a face, zero direction) are
     * dropped by fminf, as there. */
    const float fx = r->ix >= 0.0f ? hi[0] : lo[0], fy = r->iy >= 0.0f ? hi[1] : lo[1];
    const float fz = r->iz >= 0.0f ? hi[2] : lo[2];
    float tf = AS_MINF(AS_MINF(AS_MUL(AS_SUB(fx, r->ox), r->ix), AS_MUL(AS_SUB(fy, r->oy), r->iy)),
                       AS_MINF(AS_MUL(AS_SUB(fz, r->oz), r->iz), r->tmax));
    as_bih_stack_entry_t stack[AS_BIH_MAX_DEPTH + 1];
    int sp = 0;
    uint32_t node = 0;
    const float org[3] = {r->ox, r->oy, r->oz}, inv[3] = {r->ix, r->iy, r->iz};
    for (;;) {
        const as_bih_node_t *n = nodes + node;
        const uint32_t info = as_load_u32(&n->info);
        if (ctr) ctr->node_visits++;
        int go = 0;
        if ((info & 3u) == AS_BIH_LEAF) {
            const uint32_t count = as_float_as_uint(n->clip[0]);
            if (as_indexed_leaf(r, tris, prims, info >> 2, count, any_hit, hit, ctr)) return;
        } else {
            const uint32_t axis = info & 3u, child = info >> 2;
            const float c0 = n->clip[0], c1 = n->clip[1];
            const float tl = AS_MUL(AS_SUB(c0, org[axis]), inv[axis]);
            const float tr = AS_MUL(AS_SUB(c1, org[axis]), inv[axis]);
            /* A zero direction component is +0 (as_ray_prepare), its inverse
             * +inf: the planes give +-inf, or NaN for an origin on the plane,
             * which fminf/fmaxf drop (the plane counts as inside). */
            float near_n, near_f, far_n, far_f;
            uint32_t near_c, far_c;
            if (inv[axis] >= 0.0f) {
                near_c = child; far_c = child + 1;
                near_n = tn; near_f = AS_MINF(tf, tl);
                far_n = AS_MAXF(tn, tr); far_f = tf;
            } else {
                near_c = child + 1; far_c = child;
                near_n = tn; near_f = AS_MINF(tf, tr);
                far_n = AS_MAXF(tn, tl); far_f = tf;
            }
            const float limit = AS_MINF(hit->t, r->tmax);
            const int hn = near_n <= AS_MINF(near_f, limit) * AS_BOX_FAR_SCALE;
            const int hf = far_n <= AS_MINF(far_f, limit) * AS_BOX_FAR_SCALE;
            if (hn && hf) {
                stack[sp].node = far_c; stack[sp].tn = far_n; stack[sp].tf = far_f; ++sp;
                node = near_c; tf = near_f;
                go = 1;
            } else if (hn) {
                node = near_c; tf = near_f; go = 1;
            } else if (hf) {
                node = far_c; tn = far_n; go = 1;
            }
        }
        while (!go) {
            if (sp == 0) return;
            --sp;
            const float limit = AS_MINF(hit->t, r->tmax);
            if (stack[sp].tn <= AS_MINF(stack[sp].tf, limit) * AS_BOX_FAR_SCALE) {
                node = stack[sp].node; tn = stack[sp].tn; tf = stack[sp].tf;
                go = 1;
            }
        }
    }
}

#endif
