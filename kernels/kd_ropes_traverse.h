/* Stackless KD traversal with ropes (Havran 1998; Popov et al. 2007; the
 * GPU form of Santos et al. 2012), written once for the CPU and the GPU.
 *
 * The ray starts at p = o + t0 d (three FMAs), t0 the entry into the scene
 * box or tmin when the origin is inside, and descends from the root to the
 * leaf holding p. After a leaf's triangles it leaves through the face of
 * smallest exit distance (one of three floats of the leaf box, chosen by the
 * ray's signs), follows that face's rope and descends from the rope's node to
 * the leaf holding the new entry point. On the exit axis the entry point is
 * the face's coordinate itself, not a rounded product, so the descent always
 * crosses the face. Points on a split plane go to the side the ray moves
 * towards (a ray lying in the plane: below), and when the entry point lies
 * exactly on split planes the leaves on their other sides are tested too
 * (as_kd_ropes_descend): a triangle may touch the point from a leaf the ray
 * does not enter.
 *
 * A ray lying exactly in a leaf face that is a split plane (direction
 * component 0, origin on the plane: axis-parallel rays from a vertex) can
 * hit triangles that touch the plane from either side, and a stackless walk
 * follows only one side. Such a ray is traced by the KD-standard traversal
 * instead (the rope layout holds every section it reads), which visits both;
 * every other ray never touches a stack.
 *
 * Hits are accepted as in kd_traverse.h: the closest so far is kept, and the
 * walk stops once the next leaf starts beyond it (widened). */
#ifndef AS_KD_ROPES_TRAVERSE_H
#define AS_KD_ROPES_TRAVERSE_H

#include "kd_traverse.h"

#ifdef __CUDA_ARCH__
#define AS_FMAF(a, b, c) __fmaf_rn((a), (b), (c))
#else
#define AS_FMAF(a, b, c) fmaf((a), (b), (c))
#endif

/* Descends from `node` to the leaf holding p. A point on a split plane goes
 * to the side the ray moves into, except on `exit_axis` (the face just
 * crossed, where p is exact) and when `combo` >= 0: then bit `axis` of combo
 * picks the side (1 above) and the axis is recorded in *ties. */
AS_HD int32_t as_kd_ropes_descend(const as_kd_node_t *AS_RESTRICT nodes, int32_t node, const float p[3],
                                  const float d[3], int exit_axis, int combo, uint32_t *ties,
                                  as_trace_counters_t *ctr)
{
    as_kd_node_t n = as_kd_load_node(nodes + node);
    while (!as_kd_is_leaf(n.word1)) {
        if (ctr) ctr->node_visits++;
        const int axis = (int)(n.word1 & 3u);
        const float split = as_uint_as_float(n.word0);
        int up = p[axis] > split;
        if (p[axis] == split) {
            if (axis != exit_axis) *ties |= 1u << axis;
            up = (combo >= 0 && axis != exit_axis) ? (combo >> axis) & 1 : d[axis] > 0.0f;
        }
        node = up ? (int32_t)(n.word1 >> 2) : node + 1;
        n = as_kd_load_node(nodes + node);
    }
    return node;
}

/* Traces one prepared ray through a KD tree with ropes. `box` is the root
 * (scene) box, lo xyz then hi xyz; `leaf_count` bounds the walk (a valid tree
 * never needs more steps; it only guards against a damaged one). */
AS_HD void as_kd_ropes_trace(const as_kd_node_t *AS_RESTRICT nodes, const uint32_t *AS_RESTRICT prim,
                             const as_tri4_t *AS_RESTRICT tris, const as_kd_ropes_t *AS_RESTRICT ropes,
                             const as_kd_leaf_box_t *AS_RESTRICT leaf_boxes, uint32_t leaf_count,
                             const float box[6], const as_ray_pre_t *r, int any_hit, as_hit_rec_t *hit,
                             as_trace_counters_t *ctr)
{
    as_hit_rec_miss(hit);
    float t, tend;
    if (!as_kd_clip_scene(r, box, &t, &tend)) return;
    const float o[3] = {r->ox, r->oy, r->oz}, d[3] = {r->dx, r->dy, r->dz}, inv[3] = {r->ix, r->iy, r->iz};
    float p[3] = {AS_FMAF(t, d[0], o[0]), AS_FMAF(t, d[1], o[1]), AS_FMAF(t, d[2], o[2])};
    int32_t node = 0, exit_axis = -1;
    uint64_t steps = 0;
    const uint64_t max_steps = 2 * (uint64_t)leaf_count + 8;
    for (;;) {
        uint32_t ties = 0;
        const int32_t leaf_node = as_kd_ropes_descend(nodes, node, p, d, exit_axis, -1, &ties, ctr);
        if (ties) {
            /* The entry point lies on split planes (other than the face just
             * crossed): test every leaf around it, on either side of each
             * such plane. A triangle lying in one of those planes may be on
             * the side the ray does not enter, and the ray can hit it exactly
             * at this point (an origin on a surface, a path through an edge).
             * Rare (exact ties only), at most eight leaves. */
            int32_t seen[8];
            int nseen = 0;
            for (int combo = 0; combo < 8; ++combo) {
                uint32_t unused = 0;
                const int32_t l = as_kd_ropes_descend(nodes, node, p, d, exit_axis, combo, &unused, ctr);
                int dup = l == leaf_node;
                for (int k = 0; k < nseen; ++k) dup |= seen[k] == l;
                if (dup) continue;
                seen[nseen++] = l;
                if (as_kd_leaf(r, prim, tris, as_kd_load_node(nodes + l).word0, any_hit, hit, ctr)) return;
            }
        }
        const as_kd_node_t n = as_kd_load_node(nodes + leaf_node);
        if (as_kd_leaf(r, prim, tris, n.word0, any_hit, hit, ctr)) return;
        const uint32_t leaf = n.word1 >> 2;
        const as_kd_leaf_box_t *lb = leaf_boxes + leaf;
        for (int a = 0; a < 3; ++a) {
            if (d[a] != 0.0f) continue;
            if ((o[a] == lb->lo[a] && ropes[leaf].rope[2 * a] >= 0) ||
                (o[a] == lb->hi[a] && ropes[leaf].rope[2 * a + 1] >= 0)) {
                as_kd_trace(nodes, prim, tris, box, r, any_hit, hit, ctr);
                return;
            }
        }
        /* Exit face: the far side on each axis; an axis the ray is parallel
         * to gives +inf or NaN, which never wins the comparison. */
        exit_axis = -1;
        float texit = as_inf(), face = 0.0f;
        for (int a = 0; a < 3; ++a) {
            const float f = d[a] >= 0.0f ? lb->hi[a] : lb->lo[a];
            const float ta = AS_MUL(AS_SUB(f, o[a]), inv[a]);
            if (ta < texit) { texit = ta; exit_axis = a; face = f; }
        }
        if (exit_axis < 0) return;
        if (texit > as_kd_widen(AS_MINF(hit->t, r->tmax))) return;
        const int32_t next = ropes[leaf].rope[2 * exit_axis + (d[exit_axis] > 0.0f ? 1 : 0)];
        if (next < 0 || ++steps > max_steps) return;
        t = AS_MAXF(t, texit);
        p[0] = AS_FMAF(t, d[0], o[0]);
        p[1] = AS_FMAF(t, d[1], o[1]);
        p[2] = AS_FMAF(t, d[2], o[2]);
        p[exit_axis] = face;
        node = next;
    }
}

#endif
