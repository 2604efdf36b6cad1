/* Structural validation of the BVH2 own-bounds layout: everything its
 * traversal relies on. A tree that passes can send no traversal out of
 * bounds, into a loop, or past its stack. */
#include "structure.h"
#include "bvh2_own_layout.h"
#include "trace_gpu.h"

#include <math.h>
#include <stdlib.h>

static int box_finite_ordered(const as_bvh2o_node_t *n)
{
    for (int a = 0; a < 3; ++a)
        if (!isfinite(n->lo[a]) || !isfinite(n->hi[a]) || !(n->lo[a] <= n->hi[a])) return 0;
    return 1;
}

/* The box of an empty leaf: lo = +inf, hi = -inf on every axis. */
static int box_inverted(const as_bvh2o_node_t *n)
{
    for (int a = 0; a < 3; ++a)
        if (!(n->lo[a] == INFINITY && n->hi[a] == -INFINITY)) return 0;
    return 1;
}

static int box_inside(const as_bvh2o_node_t *in, const as_bvh2o_node_t *out)
{
    for (int a = 0; a < 3; ++a)
        if (!(in->lo[a] >= out->lo[a] && in->hi[a] <= out->hi[a])) return 0;
    return 1;
}

as_error_t as_bvh2_own_validate(const as_structure_t *s, const char *name)
{
    const as_section_t *ns = as_structure_find(s, ASF_TAG_BVHO), *ts = as_structure_find(s, ASF_TAG_TRI4);
    if (!ns || !ts) return as_set_error(AS_ERROR_INVALID_STRUCTURE, "%s: BVHO or TRI4 section missing", name);
    const as_bvh2o_node_t *nodes = ns->data;
    const as_tri4_t *tris = ts->data;
    const uint64_t node_count = ns->count, tri_count = ts->count;
    if (node_count < 3) return as_set_error(AS_ERROR_INVALID_STRUCTURE, "%s: BVHO has %llu nodes; a root and its two children are the least",
                                            name, (unsigned long long)node_count);
    if (node_count > INT32_MAX || tri_count > INT32_MAX)
        return as_set_error(AS_ERROR_INVALID_STRUCTURE, "%s: %llu nodes / %llu triangles exceed the 31-bit index range",
                            name, (unsigned long long)node_count, (unsigned long long)tri_count);
    if (nodes[0].child < 0)
        return as_set_error(AS_ERROR_INVALID_STRUCTURE, "%s: BVHO node 0 (the root) is a leaf; the root is always an inner node", name);
    as_error_t err = as_bvh2_validate_tris(s, name, tris, tri_count);
    if (err != AS_OK) return err;
    if (!box_finite_ordered(&nodes[0]) && !box_inverted(&nodes[0]))
        return as_set_error(AS_ERROR_INVALID_STRUCTURE, "%s: BVHO node 0 has a non-finite or inverted box", name);

    uint8_t *node_seen = calloc(node_count, 1);
    uint8_t *tri_seen = calloc(tri_count ? tri_count : 1, 1);
    int32_t *stack = malloc(sizeof(int32_t) * (AS_BVH2_MAX_DEPTH + 2));
    uint32_t *depths = malloc(sizeof(uint32_t) * (AS_BVH2_MAX_DEPTH + 2));
    if (!node_seen || !tri_seen || !stack || !depths) {
        err = as_set_error(AS_ERROR_OUT_OF_MEMORY, "%s: out of memory validating", name);
        goto done;
    }
    int sp = 0;
    stack[sp] = 0; depths[sp] = 0; ++sp;
    node_seen[0] = 1;
    uint64_t reached = 1, inner = 1, leaves = 0, references = 0;
    uint32_t max_leaf_depth = 0;
    while (sp > 0 && err == AS_OK) {
        --sp;
        const int32_t ni = stack[sp];
        const uint32_t depth = depths[sp];
        const as_bvh2o_node_t *n = &nodes[ni];
        /* An inner node at depth d holds d + 1 stack entries after its push. */
        if (depth + 1 > AS_BVH2_MAX_DEPTH) {
            err = as_set_error(AS_ERROR_INVALID_STRUCTURE, "%s: BVHO node %d is deeper than the traversal stack (%d levels)", name, ni, AS_BVH2_MAX_DEPTH);
            break;
        }
        if (n->count != 0) {
            err = as_set_error(AS_ERROR_INVALID_STRUCTURE, "%s: BVHO node %d is an inner node with count %u (must be 0)", name, ni, n->count);
            break;
        }
        const int64_t c0 = n->child;
        if (c0 <= ni || (uint64_t)c0 + 1 >= node_count) {
            err = as_set_error(AS_ERROR_INVALID_STRUCTURE, "%s: BVHO node %d's children %lld and %lld are outside (%d, %llu)", name, ni,
                               (long long)c0, (long long)c0 + 1, ni, (unsigned long long)node_count);
            break;
        }
        for (int k = 0; k < 2 && err == AS_OK; ++k) {
            const int32_t ci = (int32_t)(c0 + k);
            const as_bvh2o_node_t *c = &nodes[ci];
            if (node_seen[ci]) {
                err = as_set_error(AS_ERROR_INVALID_STRUCTURE, "%s: BVHO node %d is referenced twice (again by node %d): a cycle or a shared subtree", name, ci, ni);
                break;
            }
            node_seen[ci] = 1;
            ++reached;
            if (c->child < 0 && c->count == 0) {
                /* The empty leaf: never entered, its box must say so. */
                if (!box_inverted(c))
                    err = as_set_error(AS_ERROR_INVALID_STRUCTURE, "%s: BVHO node %d is an empty leaf without the inverted box", name, ci);
                continue;
            }
            if (!box_finite_ordered(c) || !box_inside(c, n)) {
                err = as_set_error(AS_ERROR_INVALID_STRUCTURE, "%s: BVHO node %d's box is non-finite, inverted or not inside its parent %d's box", name, ci, ni);
                break;
            }
            if (c->child >= 0) {
                ++inner;
                stack[sp] = ci; depths[sp] = depth + 1; ++sp;
                continue;
            }
            ++leaves;
            references += c->count;
            if (depth + 1 > max_leaf_depth) max_leaf_depth = depth + 1;
            const float b[6] = {c->lo[0], c->hi[0], c->lo[1], c->hi[1], c->lo[2], c->hi[2]};
            const as_leaf_where where = {"BVHO node", ci, NULL, 0};
            err = as_bvh2_validate_leaf(s, name, tris, tri_count, tri_seen, (uint32_t)~c->child, c->count, b, &where);
        }
    }
    if (err == AS_OK && reached != node_count)
        err = as_set_error(AS_ERROR_INVALID_STRUCTURE, "%s: %llu of %llu BVHO nodes are not reachable from the root", name,
                           (unsigned long long)(node_count - reached), (unsigned long long)node_count);
    if (err == AS_OK)
        err = as_bvh2_validate_counts(s, name, "BVHO (inner nodes)", inner, tri_count, leaves, references, max_leaf_depth);
done:
    free(node_seen);
    free(tri_seen);
    free(stack);
    free(depths);
    return err;
}

#ifdef AS_HAVE_CUDA
as_error_t as_bvh2_own_validate_gpu(const as_structure_t *s, const char *name)
{
    const as_section_t *ns = as_structure_find(s, ASF_TAG_BVHO), *ts = as_structure_find(s, ASF_TAG_TRI4);
    if (!ns || !ts || !s->gpu) return as_set_error(AS_ERROR_INVALID_STRUCTURE, "%s: BVHO or TRI4 section missing", name);
    as_gpu_bvh2_expect_t e = {
        .node_count = ns->count,
        .tri_count = ts->count,
        .clipped_leaves = s->meta.builder == AS_BUILDER_BVH_SBVH,
    };
    as_gpu_meta_expect(s, &e.meta);
    return as_gpu_validate_bvh2_own(s->gpu, name, &e);
}
#endif
