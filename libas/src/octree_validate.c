/* Structural validation of the octree layout: everything the traversal
 * relies on. An octree that passes can send no traversal out of bounds, into
 * a loop or past its stack: nodes are numbered breadth first, so a child
 * index always exceeds its parent's, every node but the root is some inner
 * node's child exactly once, and depths stay within AS_OCTREE_MAX_DEPTH. */
#include "spatial_common.h"
#include "octree_layout.h"
#include "trace_gpu.h"

#include <math.h>
#include <string.h>
#include <stdlib.h>

as_error_t as_octree_validate(const as_structure_t *s, const char *name)
{
    const as_section_t *hs = as_structure_find(s, ASF_TAG_OCTH), *ns = as_structure_find(s, ASF_TAG_OCTN),
                       *ps = as_structure_find(s, ASF_TAG_PRIM), *ts = as_structure_find(s, ASF_TAG_TRIS);
    if (!hs || !ns || !ps || !ts)
        return as_set_error(AS_ERROR_INVALID_STRUCTURE, "%s: OCTH, OCTN, PRIM or TRIS section missing", name);
    as_error_t err = as_spatial_validate_tris(s, name, ts, ps);
    if (err != AS_OK) return err;
    if (hs->count != 1) return as_set_error(AS_ERROR_INVALID_STRUCTURE, "%s: OCTH holds %llu records, expected 1", name, (unsigned long long)hs->count);
    const as_octree_header_t *h = hs->data;
    if (!isfinite(h->lo[0]) || !isfinite(h->lo[1]) || !isfinite(h->lo[2]) || !isfinite(h->size) || !(h->size > 0.0f) ||
        !isfinite(h->lo[0] + h->size) || !isfinite(h->lo[1] + h->size) || !isfinite(h->lo[2] + h->size))
        return as_set_error(AS_ERROR_INVALID_STRUCTURE, "%s: OCTH root cube is not finite with a positive edge", name);
    const as_octree_node_t *nodes = ns->data;
    const uint32_t *prims = ps->data;
    const as_tri4_t *tris = ts->data;
    const uint64_t node_count = ns->count, prim_count = ps->count;
    if (node_count == 0) return as_set_error(AS_ERROR_INVALID_STRUCTURE, "%s: no root node", name);
    if (node_count >= AS_OCTREE_INNER)
        return as_set_error(AS_ERROR_INVALID_STRUCTURE, "%s: %llu nodes exceed the 32-bit index range", name, (unsigned long long)node_count);
    uint8_t *depth = calloc(node_count, 1), *seen = calloc(node_count, 1);
    uint8_t *prim_seen = calloc(prim_count ? prim_count : 1, 1);
    if (!depth || !seen || !prim_seen) {
        err = as_set_error(AS_ERROR_OUT_OF_MEMORY, "%s: out of memory validating", name);
        goto done;
    }
    seen[0] = 1;
    uint64_t inner = 0, leaves = 0, empty = 0, refs = 0;
    uint32_t max_depth = 0;
    for (uint64_t i = 0; i < node_count && err == AS_OK; ++i) {
        const as_octree_node_t *n = &nodes[i];
        if (!seen[i]) {
            err = as_set_error(AS_ERROR_INVALID_STRUCTURE, "%s: node %llu is no node's child (or comes before its parent)", name, (unsigned long long)i);
            break;
        }
        if (n->count == AS_OCTREE_INNER) {
            ++inner;
            if (depth[i] + 1 > AS_OCTREE_MAX_DEPTH) {
                err = as_set_error(AS_ERROR_INVALID_STRUCTURE, "%s: node %llu's children are deeper than the traversal stack (%d levels)",
                                   name, (unsigned long long)i, AS_OCTREE_MAX_DEPTH);
                break;
            }
            if (n->first <= i || (uint64_t)n->first + 8 > node_count) {
                err = as_set_error(AS_ERROR_INVALID_STRUCTURE, "%s: node %llu's children [%u, %llu) are not after it inside the %llu nodes",
                                   name, (unsigned long long)i, n->first, (unsigned long long)n->first + 8, (unsigned long long)node_count);
                break;
            }
            for (uint32_t c = n->first; c < n->first + 8; ++c) {
                if (seen[c]) {
                    err = as_set_error(AS_ERROR_INVALID_STRUCTURE, "%s: node %u is referenced twice (again by node %llu)", name, c, (unsigned long long)i);
                    break;
                }
                seen[c] = 1;
                depth[c] = (uint8_t)(depth[i] + 1);
            }
            continue;
        }
        const uint64_t first = n->first, count = n->count;
        if (first > prim_count || count > prim_count - first) {
            err = as_set_error(AS_ERROR_INVALID_STRUCTURE, "%s: leaf node %llu: PRIM [%llu, %llu) outside the %llu entries", name,
                               (unsigned long long)i, (unsigned long long)first, (unsigned long long)(first + count), (unsigned long long)prim_count);
            break;
        }
        if (count) ++leaves; else ++empty;
        refs += count;
        if (count && depth[i] > max_depth) max_depth = depth[i];
        for (uint64_t j = first; j < first + count; ++j) {
            if (prim_seen[j]) {
                err = as_set_error(AS_ERROR_INVALID_STRUCTURE, "%s: PRIM entry %llu is in two leaves (again in node %llu)", name,
                                   (unsigned long long)j, (unsigned long long)i);
                break;
            }
            prim_seen[j] = 1;
        }
    }
    /* Every referenced triangle inside the root cube (the traversal clips
     * rays to it). */
    for (uint64_t j = 0; j < prim_count && err == AS_OK; ++j) {
        const as_tri4_t *t = &tris[prims[j]];
        const float *v[3] = {&t->v0.x, &t->v1.x, &t->v2.x};
        for (int a = 0; a < 3 && err == AS_OK; ++a)
            for (int k = 0; k < 3; ++k)
                if (v[a][k] < h->lo[k] || v[a][k] > h->lo[k] + h->size) {
                    err = as_set_error(AS_ERROR_INVALID_STRUCTURE, "%s: triangle %u (PRIM entry %llu) lies outside the root cube", name,
                                       prims[j], (unsigned long long)j);
                    break;
                }
    }
    if (err == AS_OK && refs != prim_count)
        err = as_set_error(AS_ERROR_INVALID_STRUCTURE, "%s: the leaves hold %llu references but PRIM has %llu entries", name,
                           (unsigned long long)refs, (unsigned long long)prim_count);
    if (err == AS_OK) err = as_spatial_validate_counts(s, name, inner, leaves, empty, refs, max_depth);
done:
    free(depth);
    free(seen);
    free(prim_seen);
    return err;
}

#ifdef AS_HAVE_CUDA
as_error_t as_octree_validate_gpu(const as_structure_t *s, const char *name)
{
    return as_spatial_validate_gpu(s, name, ASF_TAG_OCTH, ASF_TAG_OCTN, as_gpu_validate_octree);
}
#endif
