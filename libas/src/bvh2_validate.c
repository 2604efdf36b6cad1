/* Structural validation of the BVH2 child-bounds layout: everything the
 * traversal relies on, checked before it reads a file. A tree that passes
 * can send no traversal out of bounds, into a loop, or past its stack. */
#include "structure.h"
#include "bvh2_layout.h"
#include "trace_gpu.h"

#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

static int finite6(float a, float b, float c, float d, float e, float f)
{
    return isfinite(a) && isfinite(b) && isfinite(c) && isfinite(d) && isfinite(e) && isfinite(f);
}

static int box_inside(const float in[6], const float out[6])
{
    return in[0] >= out[0] && in[1] <= out[1] && in[2] >= out[2] && in[3] <= out[3] && in[4] >= out[4] &&
           in[5] <= out[5];
}

static void child_box(const as_bvh2_node_t *n, int k, float b[6])
{
    if (k == 0) { b[0] = n->xy0.x; b[1] = n->xy0.y; b[2] = n->xy0.z; b[3] = n->xy0.w; b[4] = n->z01.x; b[5] = n->z01.y; }
    else        { b[0] = n->xy1.x; b[1] = n->xy1.y; b[2] = n->xy1.z; b[3] = n->xy1.w; b[4] = n->z01.z; b[5] = n->z01.w; }
}

as_error_t as_bvh2_validate_tris(const as_structure_t *s, const char *name, const as_tri4_t *tris, uint64_t tri_count)
{
    /* Triangles: finite vertices and source indices within the mesh. */
    for (uint64_t i = 0; i < tri_count; ++i) {
        const as_tri4_t *t = &tris[i];
        if (!finite6(t->v0.x, t->v0.y, t->v0.z, t->v1.x, t->v1.y, t->v1.z) || !isfinite(t->v2.x) ||
            !isfinite(t->v2.y) || !isfinite(t->v2.z))
            return as_set_error(AS_ERROR_INVALID_STRUCTURE, "%s: TRI4 triangle %llu has a non-finite vertex", name,
                                (unsigned long long)i);
        const uint32_t prim = as_float_as_uint(t->v0.w);
        if (prim >= s->meta.triangle_count)
            return as_set_error(AS_ERROR_INVALID_STRUCTURE,
                                "%s: TRI4 triangle %llu refers to source triangle %u but META says the mesh has %u",
                                name, (unsigned long long)i, prim, s->meta.triangle_count);
    }
    return AS_OK;
}

static const char *leaf_where(const as_leaf_where *w, char *buf, size_t size)
{
    if (w->slot_label) snprintf(buf, size, "%s %lld %s %d", w->node_label, w->node, w->slot_label, w->slot);
    else snprintf(buf, size, "%s %lld", w->node_label, w->node);
    return buf;
}

as_error_t as_bvh2_validate_leaf(const as_structure_t *s, const char *name, const as_tri4_t *tris, uint64_t tri_count,
                                 uint8_t *tri_seen, uint64_t first, uint64_t count, const float b[6],
                                 const as_leaf_where *place)
{
    char where[96];
    if (first > tri_count || count > tri_count - first)
        return as_set_error(AS_ERROR_INVALID_STRUCTURE, "%s: %s: leaf triangles [%llu, %llu) outside the %llu of TRI4",
                            name, leaf_where(place, where, sizeof where), (unsigned long long)first, (unsigned long long)(first + count),
                            (unsigned long long)tri_count);
    if (!finite6(b[0], b[1], b[2], b[3], b[4], b[5]) || !(b[0] <= b[1] && b[2] <= b[3] && b[4] <= b[5]))
        return as_set_error(AS_ERROR_INVALID_STRUCTURE, "%s: %s (a leaf) has a non-finite or inverted box", name,
                            leaf_where(place, where, sizeof where));
    /* An SBVH leaf box bounds only the part of a triangle it holds (the
     * reference was clipped): the triangle's box must overlap it. Any other
     * builder's leaf box holds its triangles whole. */
    const int clipped = s->meta.builder == AS_BUILDER_BVH_SBVH;
    for (uint64_t t = first; t < first + count; ++t) {
        if (tri_seen[t])
            return as_set_error(AS_ERROR_INVALID_STRUCTURE, "%s: TRI4 triangle %llu is in two leaves (again under %s)",
                                name, (unsigned long long)t, leaf_where(place, where, sizeof where));
        tri_seen[t] = 1;
        const as_f4_t *v[3] = {&tris[t].v0, &tris[t].v1, &tris[t].v2};
        float tb[6] = {v[0]->x, v[0]->x, v[0]->y, v[0]->y, v[0]->z, v[0]->z};
        for (int j = 0; j < 3; ++j) {
            const float c[3] = {v[j]->x, v[j]->y, v[j]->z};
            for (int a = 0; a < 3; ++a) {
                tb[2 * a] = fminf(tb[2 * a], c[a]);
                tb[2 * a + 1] = fmaxf(tb[2 * a + 1], c[a]);
            }
        }
        const int ok = clipped ? tb[0] <= b[1] && tb[1] >= b[0] && tb[2] <= b[3] && tb[3] >= b[2] && tb[4] <= b[5] &&
                                     tb[5] >= b[4]
                               : box_inside(tb, b);
        if (!ok)
            return as_set_error(AS_ERROR_INVALID_STRUCTURE, "%s: TRI4 triangle %llu lies outside the box of its leaf (%s)",
                                name, (unsigned long long)t, leaf_where(place, where, sizeof where));
    }
    return AS_OK;
}

as_error_t as_bvh2_validate_counts(const as_structure_t *s, const char *name, const char *section, uint64_t node_count,
                                   uint64_t tri_count, uint64_t leaves, uint64_t references, uint32_t max_leaf_depth)
{
    /* Every TRI4 entry is in exactly one leaf (an SBVH may hold one source
     * triangle several times, as several entries). */
    if (references != tri_count)
        return as_set_error(AS_ERROR_INVALID_STRUCTURE, "%s: TRI4 holds %llu triangles but the leaves reference %llu",
                            name, (unsigned long long)tri_count, (unsigned long long)references);
    /* META's counts describe the arrays; readers that size buffers from
     * them (statistics, the study) must be able to trust them. */
    if (s->meta.node_count != node_count)
        return as_set_error(AS_ERROR_INVALID_STRUCTURE, "%s: META says %llu nodes but %s holds %llu", name,
                            (unsigned long long)s->meta.node_count, section, (unsigned long long)node_count);
    if (s->meta.leaf_count != leaves)
        return as_set_error(AS_ERROR_INVALID_STRUCTURE, "%s: META leaf count is %llu but the tree has %llu leaves", name,
                            (unsigned long long)s->meta.leaf_count, (unsigned long long)leaves);
    if (s->meta.reference_count != references || s->meta.empty_leaf_count != 0)
        return as_set_error(AS_ERROR_INVALID_STRUCTURE,
                            "%s: META reference count %llu and empty leaf count %llu, but the leaves hold %llu references and none is empty",
                            name, (unsigned long long)s->meta.reference_count,
                            (unsigned long long)s->meta.empty_leaf_count, (unsigned long long)references);
    if (s->meta.max_depth != max_leaf_depth)
        return as_set_error(AS_ERROR_INVALID_STRUCTURE, "%s: META says max depth %u but the deepest leaf is at %u", name,
                            s->meta.max_depth, max_leaf_depth);
    return AS_OK;
}

as_error_t as_bvh2_validate(const as_structure_t *s, const char *name)
{
    const as_section_t *ns = as_structure_find(s, ASF_TAG_BVH2), *ts = as_structure_find(s, ASF_TAG_TRI4);
    if (!ns || !ts) return as_set_error(AS_ERROR_INVALID_STRUCTURE, "%s: BVH2 or TRI4 section missing", name);
    const as_bvh2_node_t *nodes = ns->data;
    const as_tri4_t *tris = ts->data;
    const uint64_t node_count = ns->count, tri_count = ts->count;
    if (node_count == 0) return as_set_error(AS_ERROR_INVALID_STRUCTURE, "%s: no root node", name);
    if (node_count > INT32_MAX || tri_count > INT32_MAX)
        return as_set_error(AS_ERROR_INVALID_STRUCTURE, "%s: %llu nodes / %llu triangles exceed the 31-bit index range",
                            name, (unsigned long long)node_count, (unsigned long long)tri_count);

    as_error_t err = as_bvh2_validate_tris(s, name, tris, tri_count);
    if (err != AS_OK) return err;

    uint8_t *node_seen = calloc(node_count, 1);
    uint8_t *tri_seen = calloc(tri_count ? tri_count : 1, 1);
    int32_t *stack = malloc(sizeof(int32_t) * (AS_BVH2_MAX_DEPTH + 1));
    uint32_t *depths = malloc(sizeof(uint32_t) * (AS_BVH2_MAX_DEPTH + 1));
    if (!node_seen || !tri_seen || !stack || !depths) {
        err = as_set_error(AS_ERROR_OUT_OF_MEMORY, "%s: out of memory validating", name);
        goto done;
    }
    int sp = 0;
    stack[sp] = 0; depths[sp] = 0; ++sp;
    node_seen[0] = 1;
    uint64_t reached = 1, leaves = 0, references = 0;
    uint32_t max_leaf_depth = 0;
    while (sp > 0 && err == AS_OK) {
        --sp;
        const int32_t ni = stack[sp];
        const uint32_t depth = depths[sp];
        const as_bvh2_node_t *n = &nodes[ni];
        for (int k = 0; k < 2 && err == AS_OK; ++k) {
            float b[6];
            child_box(n, k, b);
            const int32_t c = n->child[k];
            if (c >= 0) {
                if (n->count[k] != 0) {
                    err = as_set_error(AS_ERROR_INVALID_STRUCTURE, "%s: node %d child %d is an inner node with count %u (must be 0)", name, ni, k, n->count[k]);
                } else if ((uint64_t)c >= node_count || c == 0) {
                    err = as_set_error(AS_ERROR_INVALID_STRUCTURE, "%s: node %d child %d refers to node %d, outside [1, %llu)", name, ni, k, c, (unsigned long long)node_count);
                } else if (node_seen[c]) {
                    err = as_set_error(AS_ERROR_INVALID_STRUCTURE, "%s: node %d is referenced twice (again by node %d): a cycle or a shared subtree", name, c, ni);
                } else if (!finite6(b[0], b[1], b[2], b[3], b[4], b[5]) || !(b[0] <= b[1] && b[2] <= b[3] && b[4] <= b[5])) {
                    err = as_set_error(AS_ERROR_INVALID_STRUCTURE, "%s: node %d child %d has a non-finite or inverted box", name, ni, k);
                } else if (depth + 1 >= AS_BVH2_MAX_DEPTH) {
                    err = as_set_error(AS_ERROR_INVALID_STRUCTURE, "%s: node %d is deeper than the traversal stack (%d levels)", name, c, AS_BVH2_MAX_DEPTH);
                } else {
                    /* The grandchildren's boxes must lie inside this box. */
                    const as_bvh2_node_t *cn = &nodes[c];
                    for (int g = 0; g < 2 && err == AS_OK; ++g) {
                        float gb[6];
                        child_box(cn, g, gb);
                        const int empty = cn->child[g] < 0 && cn->count[g] == 0;
                        if (!empty && !box_inside(gb, b))
                            err = as_set_error(AS_ERROR_INVALID_STRUCTURE, "%s: node %d child %d's box is not inside the box its parent %d stores for it", name, c, g, ni);
                    }
                    node_seen[c] = 1;
                    ++reached;
                    stack[sp] = c; depths[sp] = depth + 1; ++sp;
                }
            } else {
                const uint64_t first = (uint64_t)(uint32_t)~c, count = n->count[k];
                if (count == 0) continue; /* an empty child: never entered */
                ++leaves;
                references += count;
                if (depth + 1 > max_leaf_depth) max_leaf_depth = depth + 1;
                const as_leaf_where where = {"node", ni, "child", k};
                err = as_bvh2_validate_leaf(s, name, tris, tri_count, tri_seen, first, count, b, &where);
            }
        }
    }
    if (err == AS_OK && reached != node_count)
        err = as_set_error(AS_ERROR_INVALID_STRUCTURE, "%s: %llu of %llu nodes are not reachable from the root", name,
                           (unsigned long long)(node_count - reached), (unsigned long long)node_count);
    if (err == AS_OK)
        err = as_bvh2_validate_counts(s, name, "BVH2", node_count, tri_count, leaves, references, max_leaf_depth);
done:
    free(node_seen);
    free(tri_seen);
    free(stack);
    free(depths);
    return err;
}

#ifdef AS_HAVE_CUDA
as_error_t as_bvh2_validate_gpu(const as_structure_t *s, const char *name)
{
    const as_section_t *ns = as_structure_find(s, ASF_TAG_BVH2), *ts = as_structure_find(s, ASF_TAG_TRI4);
    if (!ns || !ts || !s->gpu) return as_set_error(AS_ERROR_INVALID_STRUCTURE, "%s: BVH2 or TRI4 section missing", name);
    as_gpu_bvh2_expect_t e = {
        .node_count = ns->count,
        .tri_count = ts->count,
        .clipped_leaves = s->meta.builder == AS_BUILDER_BVH_SBVH,
    };
    as_gpu_meta_expect(s, &e.meta);
    return as_gpu_validate_bvh2(s->gpu, name, &e);
}
#endif
