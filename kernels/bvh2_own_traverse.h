/* Stack traversal of the own-bounds BVH2 layout, written once for the CPU
 * and the GPU: fetch a node, test its own box, then either its triangles or
 * its two children (the classic scheme, one box test per node fetch; the
 * child-bounds layout of bvh2_traverse.h tests both children per fetch and
 * visits the nearer first). Children are visited left first: the node holds
 * no information to order them by. Same hit semantics as as_bvh2_trace:
 * closest hit in [tmin, tmax], equal t to the lowest source index. */
#ifndef AS_BVH2_OWN_TRAVERSE_H
#define AS_BVH2_OWN_TRAVERSE_H

#include "bvh2_own_layout.h"
#include "bvh2_traverse.h"

/* Traces one prepared ray; on return `hit` holds the closest hit in
 * [tmin, tmax] (any hit when any_hit is set) or a miss. `ctr` may be NULL. */
AS_HD void as_bvh2o_trace(const as_bvh2o_node_t *AS_RESTRICT nodes, const as_tri4_t *AS_RESTRICT tris,
                          const as_ray_pre_t *r, int any_hit, as_hit_rec_t *hit, as_trace_counters_t *ctr)
{
    int32_t stack[AS_BVH2_MAX_DEPTH];
    int sp = 0;
    int32_t node = 0;
    as_hit_rec_miss(hit);
    float tmax = r->tmax;
    for (;;) {
        const as_f4_t *p = (const as_f4_t *)(nodes + node);
        const as_f4_t a = as_load_f4(p), b = as_load_f4(p + 1);
        if (ctr) ctr->node_visits++;
        float t;
        if (as_ray_box(r, a.x, a.w, a.y, b.x, a.z, b.y, tmax, &t)) {
            const int32_t child = (int32_t)as_float_as_uint(b.z);
            if (child >= 0) {
                stack[sp++] = child + 1;
                node = child;
                continue;
            }
            if (as_bvh2_leaf(r, tris, (uint32_t)~child, as_float_as_uint(b.w), any_hit, hit, ctr)) return;
            tmax = AS_MINF(tmax, hit->t);
        }
        if (sp == 0) return;
        node = stack[--sp];
    }
}

#endif
