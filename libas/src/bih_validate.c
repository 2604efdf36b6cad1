/* Structural validation of the BIH layout: everything the traversal relies
 * on. A BIH that passes can send no traversal out of bounds, into a loop or
 * past its stack, and every referenced triangle lies inside the scene box
 * that the traversal clips rays to. */
#include "spatial_common.h"
#include "bih_layout.h"
#include "trace_gpu.h"

#include <math.h>
#include <string.h>
#include <stdlib.h>

as_error_t as_bih_validate(const as_structure_t *s, const char *name)
{
    const as_section_t *ns = as_structure_find(s, ASF_TAG_BIHN), *ps = as_structure_find(s, ASF_TAG_PRIM),
                       *ts = as_structure_find(s, ASF_TAG_TRIS);
    if (!ns || !ps || !ts) return as_set_error(AS_ERROR_INVALID_STRUCTURE, "%s: BIHN, PRIM or TRIS section missing", name);
    as_error_t err = as_spatial_validate_tris(s, name, ts, ps);
    if (err != AS_OK) return err;
    const as_bih_node_t *nodes = ns->data;
    const uint32_t *prims = ps->data;
    const as_tri4_t *tris = ts->data;
    const uint64_t node_count = ns->count, prim_count = ps->count;
    if (node_count == 0) return as_set_error(AS_ERROR_INVALID_STRUCTURE, "%s: no root node", name);
    if (node_count > AS_BIH_MAX_INDEX || prim_count > AS_BIH_MAX_INDEX)
        return as_set_error(AS_ERROR_INVALID_STRUCTURE, "%s: %llu nodes / %llu PRIM entries exceed the 30-bit index range",
                            name, (unsigned long long)node_count, (unsigned long long)prim_count);
    const float *lo = s->meta.bounds_lo, *hi = s->meta.bounds_hi;
    for (int k = 0; k < 3; ++k)
        if (!isfinite(lo[k]) || !isfinite(hi[k]) || !(lo[k] <= hi[k]))
            return as_set_error(AS_ERROR_INVALID_STRUCTURE, "%s: META scene box is not finite and ordered", name);
    uint8_t *seen = calloc(node_count, 1);
    uint8_t *prim_seen = calloc(prim_count ? prim_count : 1, 1);
    struct { uint32_t node, depth; } *stack = malloc(sizeof *stack * (AS_BIH_MAX_DEPTH + 2));
    if (!seen || !prim_seen || !stack) {
        err = as_set_error(AS_ERROR_OUT_OF_MEMORY, "%s: out of memory validating", name);
        goto done;
    }
    int sp = 0;
    stack[sp].node = 0; stack[sp].depth = 0; ++sp;
    seen[0] = 1;
    uint64_t reached = 1, inner = 0, leaves = 0, empty = 0, refs = 0;
    uint32_t max_depth = 0;
    while (sp > 0 && err == AS_OK) {
        --sp;
        const uint32_t ni = stack[sp].node, depth = stack[sp].depth;
        const as_bih_node_t *n = &nodes[ni];
        const uint32_t axis = n->info & 3u, idx = n->info >> 2;
        if (axis == AS_BIH_LEAF) {
            const uint64_t count = as_float_as_uint(n->clip[0]);
            if (as_float_as_uint(n->clip[1]) != 0) {
                err = as_set_error(AS_ERROR_INVALID_STRUCTURE, "%s: leaf node %u has a non-zero second word", name, ni);
                break;
            }
            if (idx > prim_count || count > prim_count - idx) {
                err = as_set_error(AS_ERROR_INVALID_STRUCTURE, "%s: leaf node %u: PRIM [%u, %llu) outside the %llu entries",
                                   name, ni, idx, (unsigned long long)(idx + count), (unsigned long long)prim_count);
                break;
            }
            if (count) ++leaves; else ++empty;
            refs += count;
            if (depth > max_depth) max_depth = depth;
            for (uint64_t i = idx; i < idx + count && err == AS_OK; ++i) {
                if (prim_seen[i]) {
                    err = as_set_error(AS_ERROR_INVALID_STRUCTURE, "%s: PRIM entry %llu is in two leaves (again in node %u)",
                                       name, (unsigned long long)i, ni);
                    break;
                }
                prim_seen[i] = 1;
                const as_tri4_t *t = &tris[prims[i]];
                const float *v[3] = {&t->v0.x, &t->v1.x, &t->v2.x};
                for (int j = 0; j < 3; ++j)
                    for (int k = 0; k < 3; ++k)
                        if (v[j][k] < lo[k] || v[j][k] > hi[k]) {
                            err = as_set_error(AS_ERROR_INVALID_STRUCTURE,
                                               "%s: triangle %u (leaf node %u) lies outside the META scene box", name,
                                               prims[i], ni);
                            j = 3;
                            break;
                        }
            }
            continue;
        }
        ++inner;
        if (!isfinite(n->clip[0]) || !isfinite(n->clip[1])) {
            err = as_set_error(AS_ERROR_INVALID_STRUCTURE, "%s: node %u has a non-finite clip plane", name, ni);
            break;
        }
        if (depth + 1 > AS_BIH_MAX_DEPTH) {
            err = as_set_error(AS_ERROR_INVALID_STRUCTURE, "%s: node %u's children are deeper than the traversal stack (%d levels)",
                               name, ni, AS_BIH_MAX_DEPTH);
            break;
        }
        if (idx == 0 || (uint64_t)idx + 1 >= node_count) {
            err = as_set_error(AS_ERROR_INVALID_STRUCTURE, "%s: node %u's children %u and %u are outside [1, %llu)", name, ni,
                               idx, idx + 1, (unsigned long long)node_count);
            break;
        }
        for (uint32_t c = idx; c <= idx + 1; ++c) {
            if (seen[c]) {
                err = as_set_error(AS_ERROR_INVALID_STRUCTURE, "%s: node %u is referenced twice (again by node %u): a cycle or a shared subtree",
                                   name, c, ni);
                break;
            }
            seen[c] = 1;
            ++reached;
            stack[sp].node = c; stack[sp].depth = depth + 1; ++sp;
        }
    }
    if (err == AS_OK && reached != node_count)
        err = as_set_error(AS_ERROR_INVALID_STRUCTURE, "%s: %llu of %llu nodes are not reachable from the root", name,
                           (unsigned long long)(node_count - reached), (unsigned long long)node_count);
    if (err == AS_OK && refs != prim_count)
        err = as_set_error(AS_ERROR_INVALID_STRUCTURE, "%s: the leaves hold %llu references but PRIM has %llu entries", name,
                           (unsigned long long)refs, (unsigned long long)prim_count);
    if (err == AS_OK) err = as_spatial_validate_counts(s, name, inner, leaves, empty, refs, max_depth);
done:
    free(seen);
    free(prim_seen);
    free(stack);
    return err;
}

#ifdef AS_HAVE_CUDA
as_error_t as_bih_validate_gpu(const as_structure_t *s, const char *name)
{
    return as_spatial_validate_gpu(s, name, 0, ASF_TAG_BIHN, as_gpu_validate_bih);
}
#endif
