/* Stack traversal of the BVH2 child-bounds layout, written once for the CPU
 * and the GPU (Aila & Laine 2009: one node fetch tests both children; the
 * nearer entered child is visited first, the other pushed). */
#ifndef AS_BVH2_TRAVERSE_H
#define AS_BVH2_TRAVERSE_H

#include "bvh2_layout.h"
#include "ray_triangle.h"

/* Per-ray counters for the statistics launch. */
typedef struct as_trace_counters {
    uint32_t node_visits;   /* traversal steps: nodes fetched, leaves included */
    uint32_t tri_tests;     /* ray/triangle tests */
} as_trace_counters_t;

/* Result of one ray, in the hit-file record's shape. */
typedef struct as_hit_rec {
    float t;
    uint32_t prim;
    float u, v;
} as_hit_rec_t;

AS_HD void as_hit_rec_miss(as_hit_rec_t *h)
{
    h->t = as_inf();
    h->prim = 0xFFFFFFFFu;
    h->u = 0.0f;
    h->v = 0.0f;
}

/* The children's indices and leaf sizes: one 16-byte load on the GPU. */
AS_HD void as_bvh2_load_links(const as_bvh2_node_t *n, int32_t c[2], uint32_t cnt[2])
{
#ifdef __CUDA_ARCH__
    const int4 v = __ldg((const int4 *)&n->child[0]);
    c[0] = v.x; c[1] = v.y; cnt[0] = (uint32_t)v.z; cnt[1] = (uint32_t)v.w;
#else
    c[0] = n->child[0]; c[1] = n->child[1]; cnt[0] = n->count[0]; cnt[1] = n->count[1];
#endif
}

/* Tests the triangles [first, first + count) and updates the hit; returns 1
 * when any_hit is set and something was hit (the caller stops). */
AS_HD int as_bvh2_leaf(const as_ray_pre_t *r, const as_tri4_t *AS_RESTRICT tris, uint32_t first,
                       uint32_t count, int any_hit, as_hit_rec_t *hit, as_trace_counters_t *ctr)
{
    if (ctr) ctr->node_visits++;
    for (uint32_t i = 0; i < count; ++i) {
        const as_tri4_t *tri = tris + first + i;
        const as_f4_t v0 = as_load_f4(&tri->v0), v1 = as_load_f4(&tri->v1), v2 = as_load_f4(&tri->v2);
        float t, u, v;
        if (ctr) ctr->tri_tests++;
        if (as_ray_triangle(r, &tri->v0, v0, v1, v2, AS_MINF(hit->t, r->tmax), &t, &u, &v)) {
            const uint32_t prim = as_float_as_uint(v0.w);
            /* Equal distances (a shared edge, coincident copies) go to the
             * lowest source index, so every traversal order reports the same
             * primitive. */
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

/* Traces one prepared ray; on return `hit` holds the closest hit in
 * [tmin, tmax] (any hit when any_hit is set) or a miss. `ctr` may be NULL. */
AS_HD void as_bvh2_trace(const as_bvh2_node_t *AS_RESTRICT nodes, const as_tri4_t *AS_RESTRICT tris,
                         const as_ray_pre_t *r, int any_hit, as_hit_rec_t *hit,
                         as_trace_counters_t *ctr)
{
    int32_t stack[AS_BVH2_MAX_DEPTH];
    int sp = 0;
    int32_t node = 0;
    as_hit_rec_miss(hit);
    float tmax = r->tmax;
    for (;;) {
        const as_bvh2_node_t *n = nodes + node;
        const as_f4_t xy0 = as_load_f4(&n->xy0), xy1 = as_load_f4(&n->xy1);
        const as_f4_t z01 = as_load_f4(&n->z01);
        if (ctr) ctr->node_visits++;
        float t0, t1;
        int hit0 = as_ray_box(r, xy0.x, xy0.y, xy0.z, xy0.w, z01.x, z01.y, tmax, &t0);
        int hit1 = as_ray_box(r, xy1.x, xy1.y, xy1.z, xy1.w, z01.z, z01.w, tmax, &t1);
        int32_t c[2];
        uint32_t cnt[2];
        as_bvh2_load_links(n, c, cnt);
        /* Leaves are tested at once: it shortens tmax before inner children
         * are ordered and pushed. */
        if (hit0 && c[0] < 0) {
            if (as_bvh2_leaf(r, tris, (uint32_t)~c[0], cnt[0], any_hit, hit, ctr)) return;
            tmax = AS_MINF(tmax, hit->t);
            hit0 = 0;
        }
        if (hit1 && c[1] < 0) {
            if (as_bvh2_leaf(r, tris, (uint32_t)~c[1], cnt[1], any_hit, hit, ctr)) return;
            tmax = AS_MINF(tmax, hit->t);
            hit1 = 0;
        }
        if (hit0 && hit1) {
            int32_t nearc = c[0], farc = c[1];
            if (t1 < t0) { nearc = c[1]; farc = c[0]; }
            stack[sp++] = farc;
            node = nearc;
            continue;
        }
        if (hit0) { node = c[0]; continue; }
        if (hit1) { node = c[1]; continue; }
        if (sp == 0) return;
        node = stack[--sp];
    }
}

#endif
