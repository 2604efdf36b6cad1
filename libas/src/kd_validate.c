/* Structural validation of the KD layouts: everything the KD-standard and
 * rope traversals rely on, checked before they read a file. A tree that
 * passes can send no traversal out of bounds, past its stack, or into a
 * loop: every index and count is in range, every node is reached once from
 * the root, splits lie strictly inside their node's box (so boxes nest and
 * ropes are well defined), depth is within AS_KD_MAX_DEPTH, and the ropes and
 * leaf boxes are exactly the ones the tree defines (recomputed and
 * compared). */
#include "structure.h"
#include "kd_layout.h"
#include "trace_gpu.h"

#include <math.h>
#include <stdlib.h>
#include <string.h>

void as_kd_compute_ropes(const as_kd_node_t *nodes, uint64_t node_count, uint64_t leaf_count, const float lo[3],
                         const float hi[3], as_kd_ropes_t *ropes, as_kd_leaf_box_t *boxes);

#define FAIL(...) do { err = as_set_error(AS_ERROR_INVALID_STRUCTURE, __VA_ARGS__); goto done; } while (0)

static as_error_t kd_validate_common(const as_structure_t *s, const char *name, uint64_t *leaf_total)
{
    const as_section_t *ns = as_structure_find(s, ASF_TAG_KDN8), *ps = as_structure_find(s, ASF_TAG_PRIM),
                       *ts = as_structure_find(s, ASF_TAG_TRIS);
    if (!ns || !ps || !ts) return as_set_error(AS_ERROR_INVALID_STRUCTURE, "%s: KDN8, PRIM or TRIS section missing", name);
    const as_kd_node_t *nodes = ns->data;
    const uint32_t *prim = ps->data;
    const as_tri4_t *tris = ts->data;
    const uint64_t node_count = ns->count, prim_count = ps->count, tri_count = ts->count;
    as_error_t err = AS_OK;
    uint8_t *seen = NULL, *leaf_seen = NULL;
    struct { uint32_t node, depth; float box[6]; } *stack = NULL;
    if (node_count == 0) return as_set_error(AS_ERROR_INVALID_STRUCTURE, "%s: KDN8 has no root node", name);
    if (node_count >= (1u << 30) || prim_count >= UINT32_MAX)
        return as_set_error(AS_ERROR_INVALID_STRUCTURE, "%s: %llu nodes / %llu PRIM entries exceed the index range",
                            name, (unsigned long long)node_count, (unsigned long long)prim_count);
    if (tri_count != s->meta.triangle_count)
        return as_set_error(AS_ERROR_INVALID_STRUCTURE, "%s: TRIS holds %llu triangles but META says the mesh has %u",
                            name, (unsigned long long)tri_count, s->meta.triangle_count);
    for (uint64_t i = 0; i < tri_count; ++i) {
        const as_tri4_t *t = &tris[i];
        const float v[9] = {t->v0.x, t->v0.y, t->v0.z, t->v1.x, t->v1.y, t->v1.z, t->v2.x, t->v2.y, t->v2.z};
        for (int k = 0; k < 9; ++k)
            if (!isfinite(v[k]))
                return as_set_error(AS_ERROR_INVALID_STRUCTURE, "%s: TRIS triangle %llu has a non-finite vertex", name,
                                    (unsigned long long)i);
        if (as_float_as_uint(t->v0.w) != i)
            return as_set_error(AS_ERROR_INVALID_STRUCTURE, "%s: TRIS triangle %llu carries source index %u (must be its own)",
                                name, (unsigned long long)i, as_float_as_uint(t->v0.w));
    }
    for (int k = 0; k < 3; ++k)
        if (!isfinite(s->meta.bounds_lo[k]) || !isfinite(s->meta.bounds_hi[k]) || !(s->meta.bounds_lo[k] <= s->meta.bounds_hi[k]))
            return as_set_error(AS_ERROR_INVALID_STRUCTURE, "%s: META scene box is not finite or inverted on axis %d", name, k);

    seen = calloc(node_count, 1);
    leaf_seen = calloc(node_count, 1);
    stack = malloc(sizeof *stack * (AS_KD_MAX_DEPTH + 2));
    if (!seen || !leaf_seen || !stack) {
        err = as_set_error(AS_ERROR_OUT_OF_MEMORY, "%s: out of memory validating", name);
        goto done;
    }
    uint64_t reached = 0, inner = 0, leaves = 0, empty = 0, refs = 0;
    uint32_t max_depth = 0;
    int sp = 0;
    stack[0].node = 0;
    stack[0].depth = 0;
    memcpy(stack[0].box, s->meta.bounds_lo, sizeof(float) * 3);
    memcpy(stack[0].box + 3, s->meta.bounds_hi, sizeof(float) * 3);
    seen[0] = 1;
    sp = 1;
    while (sp > 0) {
        --sp;
        const uint32_t ni = stack[sp].node, depth = stack[sp].depth;
        float box[6];
        memcpy(box, stack[sp].box, sizeof box);
        ++reached;
        const as_kd_node_t n = nodes[ni];
        if (depth > max_depth) max_depth = depth;
        if (as_kd_is_leaf(n.word1)) {
            const uint64_t li = n.word1 >> 2, off = n.word0;
            if (li >= node_count || leaf_seen[li]) FAIL("%s: leaf node %u has leaf index %llu, out of range or used twice", name, ni, (unsigned long long)li);
            leaf_seen[li] = 1;
            ++leaves;
            if (off >= prim_count) FAIL("%s: leaf node %u: PRIM offset %llu outside the %llu entries", name, ni, (unsigned long long)off, (unsigned long long)prim_count);
            const uint64_t cnt = prim[off];
            if (cnt > prim_count - off - 1) FAIL("%s: leaf node %u: %llu triangles from PRIM %llu run past the %llu entries", name, ni, (unsigned long long)cnt, (unsigned long long)off, (unsigned long long)prim_count);
            for (uint64_t i = 1; i <= cnt; ++i)
                if (prim[off + i] >= tri_count) FAIL("%s: leaf node %u refers to triangle %u, outside the %llu of TRIS", name, ni, prim[off + i], (unsigned long long)tri_count);
            refs += cnt;
            empty += cnt == 0;
            continue;
        }
        ++inner;
        const int axis = (int)(n.word1 & 3u);
        const float split = as_uint_as_float(n.word0);
        const uint64_t below = (uint64_t)ni + 1, above = n.word1 >> 2;
        if (!isfinite(split) || !(split > box[axis] && split < box[axis + 3]))
            FAIL("%s: node %u splits axis %d at %g, not strictly inside its box [%g, %g]", name, ni, axis, (double)split, (double)box[axis], (double)box[axis + 3]);
        if (depth + 1 > AS_KD_MAX_DEPTH) FAIL("%s: node %u is deeper than the traversal stack (%d levels)", name, ni, AS_KD_MAX_DEPTH);
        if (below >= node_count || above >= node_count || above <= below)
            FAIL("%s: node %u has children %llu and %llu, outside (%u, %llu) or out of order", name, ni, (unsigned long long)below, (unsigned long long)above, ni, (unsigned long long)node_count);
        if (seen[below] || seen[above]) FAIL("%s: node %u's child is referenced twice: a cycle or a shared subtree", name, ni);
        seen[below] = seen[above] = 1;
        stack[sp].node = (uint32_t)above;
        stack[sp].depth = depth + 1;
        memcpy(stack[sp].box, box, sizeof box);
        stack[sp].box[axis] = split;
        ++sp;
        stack[sp].node = (uint32_t)below;
        stack[sp].depth = depth + 1;
        memcpy(stack[sp].box, box, sizeof box);
        stack[sp].box[axis + 3] = split;
        ++sp;
    }
    if (reached != node_count) FAIL("%s: %llu of %llu nodes are not reachable from the root", name, (unsigned long long)(node_count - reached), (unsigned long long)node_count);
    for (uint64_t i = 0; i < leaves; ++i)
        if (!leaf_seen[i]) FAIL("%s: leaf indices are not 0..%llu (missing %llu)", name, (unsigned long long)leaves - 1, (unsigned long long)i);
    if (s->meta.node_count != inner) FAIL("%s: META says %llu inner nodes but the tree has %llu", name, (unsigned long long)s->meta.node_count, (unsigned long long)inner);
    if (s->meta.leaf_count != leaves - empty || s->meta.empty_leaf_count != empty)
        FAIL("%s: META says %llu leaves and %llu empty ones, the tree has %llu and %llu", name, (unsigned long long)s->meta.leaf_count, (unsigned long long)s->meta.empty_leaf_count, (unsigned long long)(leaves - empty), (unsigned long long)empty);
    if (s->meta.reference_count != refs) FAIL("%s: META says %llu references, the leaves hold %llu", name, (unsigned long long)s->meta.reference_count, (unsigned long long)refs);
    if (s->meta.max_depth != max_depth) FAIL("%s: META says max depth %u, the deepest leaf is at %u", name, s->meta.max_depth, max_depth);
    *leaf_total = leaves;
done:
    free(seen);
    free(leaf_seen);
    free(stack);
    return err;
}

as_error_t as_kd_validate(const as_structure_t *s, const char *name)
{
    uint64_t leaves = 0;
    return kd_validate_common(s, name, &leaves);
}

as_error_t as_kd_ropes_validate(const as_structure_t *s, const char *name)
{
    uint64_t leaves = 0;
    as_error_t err = kd_validate_common(s, name, &leaves);
    if (err != AS_OK) return err;
    const as_section_t *rs = as_structure_find(s, ASF_TAG_KDRP), *bs = as_structure_find(s, ASF_TAG_KDLB);
    if (!rs || !bs) return as_set_error(AS_ERROR_INVALID_STRUCTURE, "%s: KDRP or KDLB section missing", name);
    if (rs->count != leaves || bs->count != leaves)
        return as_set_error(AS_ERROR_INVALID_STRUCTURE, "%s: KDRP has %llu and KDLB %llu entries, the tree has %llu leaves",
                            name, (unsigned long long)rs->count, (unsigned long long)bs->count, (unsigned long long)leaves);
    as_kd_ropes_t *ropes = malloc(sizeof *ropes * (leaves ? leaves : 1));
    as_kd_leaf_box_t *boxes = malloc(sizeof *boxes * (leaves ? leaves : 1));
    if (!ropes || !boxes) {
        free(ropes);
        free(boxes);
        return as_set_error(AS_ERROR_OUT_OF_MEMORY, "%s: out of memory validating", name);
    }
    const as_section_t *ns = as_structure_find(s, ASF_TAG_KDN8);
    as_kd_compute_ropes(ns->data, ns->count, leaves, s->meta.bounds_lo, s->meta.bounds_hi, ropes, boxes);
    const as_kd_ropes_t *fr = rs->data;
    const as_kd_leaf_box_t *fb = bs->data;
    for (uint64_t i = 0; i < leaves && err == AS_OK; ++i) {
        if (memcmp(&fr[i], &ropes[i], sizeof ropes[i]) != 0)
            err = as_set_error(AS_ERROR_INVALID_STRUCTURE, "%s: KDRP leaf %llu: ropes differ from the ones the tree defines", name, (unsigned long long)i);
        else if (memcmp(&fb[i], &boxes[i], sizeof boxes[i]) != 0)
            err = as_set_error(AS_ERROR_INVALID_STRUCTURE, "%s: KDLB leaf %llu: box differs from the one the tree defines", name, (unsigned long long)i);
    }
    free(ropes);
    free(boxes);
    return err;
}

#ifdef AS_HAVE_CUDA
static as_error_t kd_validate_gpu(const as_structure_t *s, const char *name, int ropes)
{
    const as_section_t *ns = as_structure_find(s, ASF_TAG_KDN8), *ps = as_structure_find(s, ASF_TAG_PRIM),
                       *ts = as_structure_find(s, ASF_TAG_TRIS);
    if (!ns || !ps || !ts || !s->gpu)
        return as_set_error(AS_ERROR_INVALID_STRUCTURE, "%s: KDN8, PRIM or TRIS section missing", name);
    const as_section_t *rs = as_structure_find(s, ASF_TAG_KDRP), *bs = as_structure_find(s, ASF_TAG_KDLB);
    if (ropes && (!rs || !bs)) return as_set_error(AS_ERROR_INVALID_STRUCTURE, "%s: KDRP or KDLB section missing", name);
    as_gpu_kd_expect_t e = {
        .node_count = ns->count,
        .prim_count = ps->count,
        .tri_count = ts->count,
        .ropes = ropes,
        .rope_count = ropes ? rs->count : 0,
        .leaf_box_count = ropes ? bs->count : 0,
    };
    as_gpu_meta_expect(s, &e.meta);
    return as_gpu_validate_kd(s->gpu, name, &e);
}

as_error_t as_kd_validate_gpu(const as_structure_t *s, const char *name) { return kd_validate_gpu(s, name, 0); }

as_error_t as_kd_ropes_validate_gpu(const as_structure_t *s, const char *name) { return kd_validate_gpu(s, name, 1); }
#endif
