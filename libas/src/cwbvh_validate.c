/* Structural validation of the compressed wide BVH layout: everything its
 * traversal relies on. A tree that passes can send no traversal out of
 * bounds, into a loop, or past its stack, and every triangle lies in (for an
 * SBVH: overlaps) the decoded box of its leaf and of every inner node above
 * it, the boxes the traversal tests on the way down. */
#include "structure.h"
#include "cwbvh_layout.h"
#include "trace_gpu.h"

#include <math.h>
#include <stdlib.h>

typedef struct cw_entry {
    uint32_t node, depth;
    float clip[6];                /* the ancestors' decoded boxes intersected: lo.x hi.x lo.y hi.y lo.z hi.z */
} cw_entry;

/* Checks one node's own fields; fills the decoded box of every used slot. */
static as_error_t check_node(const as_cwbvh_node_t *n, uint64_t ni, const char *name, float box[8][6])
{
    for (int a = 0; a < 3; ++a) {
        if (!isfinite(n->p[a]))
            return as_set_error(AS_ERROR_INVALID_STRUCTURE, "%s: CWBV node %llu has a non-finite origin", name,
                                (unsigned long long)ni);
        if (n->e[a] < 1 || n->e[a] > 254)
            return as_set_error(AS_ERROR_INVALID_STRUCTURE, "%s: CWBV node %llu's exponent %u on axis %d is outside "
                                "[1, 254]", name, (unsigned long long)ni, n->e[a], a);
    }
    for (int s = 0; s < 8; ++s) {
        const uint32_t meta = n->meta[s];
        const int inner_bit = (n->imask >> s) & 1;
        if (meta == 0) {
            int q = 0;
            for (int a = 0; a < 3; ++a) q |= n->qlo[a][s] | n->qhi[a][s];
            if (inner_bit || q)
                return as_set_error(AS_ERROR_INVALID_STRUCTURE, "%s: CWBV node %llu's empty slot %d has its imask bit "
                                    "or box bytes set", name, (unsigned long long)ni, s);
            continue;
        }
        if (as_cwbvh_meta_is_inner(meta)) {
            if (meta != AS_CWBVH_META_INNER(s) || !inner_bit)
                return as_set_error(AS_ERROR_INVALID_STRUCTURE, "%s: CWBV node %llu's slot %d: meta 0x%02x and imask "
                                    "disagree (an inner slot's meta is 0x%02x and its imask bit is set)", name,
                                    (unsigned long long)ni, s, meta, AS_CWBVH_META_INNER(s));
        } else {
            const uint32_t unary = meta >> 5, count = as_cwbvh_meta_count(meta);
            if (inner_bit || (unary != 1 && unary != 3 && unary != 7) || (meta & 31u) + count > 24)
                return as_set_error(AS_ERROR_INVALID_STRUCTURE, "%s: CWBV node %llu's slot %d: leaf meta 0x%02x is not "
                                    "a unary count of 1 to 3 at an offset within 24, or its imask bit is set", name,
                                    (unsigned long long)ni, s, meta);
        }
        for (int a = 0; a < 3; ++a) {
            const float scale = as_cwbvh_scale(n->e[a]);
            const float lo = as_cwbvh_decode(n->p[a], scale, n->qlo[a][s]);
            const float hi = as_cwbvh_decode(n->p[a], scale, n->qhi[a][s]);
            if (!isfinite(lo) || !isfinite(hi) || n->qlo[a][s] > n->qhi[a][s])
                return as_set_error(AS_ERROR_INVALID_STRUCTURE, "%s: CWBV node %llu's slot %d has a non-finite or "
                                    "inverted box on axis %d", name, (unsigned long long)ni, s, a);
            box[s][2 * a] = lo;
            box[s][2 * a + 1] = hi;
        }
    }
    return AS_OK;
}

as_error_t as_cwbvh_validate(const as_structure_t *s, const char *name)
{
    const as_section_t *ns = as_structure_find(s, ASF_TAG_CWBV), *ts = as_structure_find(s, ASF_TAG_TRI4);
    if (!ns || !ts) return as_set_error(AS_ERROR_INVALID_STRUCTURE, "%s: CWBV or TRI4 section missing", name);
    const as_cwbvh_node_t *nodes = ns->data;
    const as_tri4_t *tris = ts->data;
    const uint64_t node_count = ns->count, tri_count = ts->count;
    if (node_count == 0) return as_set_error(AS_ERROR_INVALID_STRUCTURE, "%s: CWBV has no root node", name);
    if (node_count > INT32_MAX || tri_count > INT32_MAX)
        return as_set_error(AS_ERROR_INVALID_STRUCTURE, "%s: %llu nodes / %llu triangles exceed the 31-bit index range",
                            name, (unsigned long long)node_count, (unsigned long long)tri_count);
    as_error_t err = as_bvh2_validate_tris(s, name, tris, tri_count);
    if (err != AS_OK) return err;

    uint8_t *node_seen = calloc(node_count, 1);
    uint8_t *tri_seen = calloc(tri_count ? tri_count : 1, 1);
    /* Depth first, eight entries at most per level. */
    const size_t cap = 8 * (AS_CWBVH_MAX_DEPTH + 2);
    cw_entry *stack = malloc(sizeof *stack * cap);
    if (!node_seen || !tri_seen || !stack) {
        err = as_set_error(AS_ERROR_OUT_OF_MEMORY, "%s: out of memory validating", name);
        goto done;
    }
    size_t sp = 0;
    stack[sp].node = 0;
    stack[sp].depth = 0;
    for (int a = 0; a < 3; ++a) { stack[sp].clip[2 * a] = -INFINITY; stack[sp].clip[2 * a + 1] = INFINITY; }
    ++sp;
    node_seen[0] = 1;
    uint64_t reached = 1, leaves = 0, references = 0;
    uint32_t max_leaf_depth = 0;
    while (sp > 0 && err == AS_OK) {
        const cw_entry e = stack[--sp];
        const as_cwbvh_node_t *n = &nodes[e.node];
        if (e.depth > AS_CWBVH_MAX_DEPTH) {
            err = as_set_error(AS_ERROR_INVALID_STRUCTURE, "%s: CWBV node %u is deeper than the traversal stack (%d "
                               "levels)", name, e.node, AS_CWBVH_MAX_DEPTH);
            break;
        }
        float box[8][6];
        err = check_node(n, e.node, name, box);
        if (err != AS_OK) break;
        uint32_t rank = 0;
        for (int k = 0; k < 8 && err == AS_OK; ++k) {
            const uint32_t meta = n->meta[k];
            if (meta == 0) continue;
            float clip[6];
            int apart = 0;
            for (int a = 0; a < 3; ++a) {
                clip[2 * a] = fmaxf(e.clip[2 * a], box[k][2 * a]);
                clip[2 * a + 1] = fminf(e.clip[2 * a + 1], box[k][2 * a + 1]);
                apart |= !(clip[2 * a] <= clip[2 * a + 1]);
            }
            /* Every slot holds a triangle or more, none of which a ray
             * could reach there. */
            if (apart) {
                err = as_set_error(AS_ERROR_INVALID_STRUCTURE, "%s: CWBV node %u slot %d's box lies outside the boxes "
                                   "of the nodes above it", name, e.node, k);
                break;
            }
            if (as_cwbvh_meta_is_inner(meta)) {
                const uint64_t ci = (uint64_t)n->child_base + rank++;
                if (ci <= e.node || ci >= node_count) {
                    err = as_set_error(AS_ERROR_INVALID_STRUCTURE, "%s: CWBV node %u's child in slot %d is node %llu, "
                                       "outside (%u, %llu)", name, e.node, k, (unsigned long long)ci, e.node,
                                       (unsigned long long)node_count);
                    break;
                }
                if (node_seen[ci]) {
                    err = as_set_error(AS_ERROR_INVALID_STRUCTURE, "%s: CWBV node %llu is referenced twice (again by "
                                       "node %u): a cycle or a shared subtree", name, (unsigned long long)ci, e.node);
                    break;
                }
                node_seen[ci] = 1;
                ++reached;
                if (sp >= cap) {
                    err = as_set_error(AS_ERROR_INVALID_STRUCTURE, "%s: CWBV node %u is deeper than the traversal "
                                       "stack (%d levels)", name, e.node, AS_CWBVH_MAX_DEPTH);
                    break;
                }
                stack[sp].node = (uint32_t)ci;
                stack[sp].depth = e.depth + 1;
                for (int a = 0; a < 6; ++a) stack[sp].clip[a] = clip[a];
                ++sp;
                continue;
            }
            const uint32_t count = as_cwbvh_meta_count(meta);
            ++leaves;
            references += count;
            if (e.depth + 1 > max_leaf_depth) max_leaf_depth = e.depth + 1;
            const as_leaf_where where = {"CWBV node", e.node, "slot", k};
            err = as_bvh2_validate_leaf(s, name, tris, tri_count, tri_seen, (uint64_t)n->tri_base + (meta & 31u),
                                        count, clip, &where);
        }
    }
    if (err == AS_OK && reached != node_count)
        err = as_set_error(AS_ERROR_INVALID_STRUCTURE, "%s: %llu of %llu CWBV nodes are not reachable from the root", name,
                           (unsigned long long)(node_count - reached), (unsigned long long)node_count);
    if (err == AS_OK)
        err = as_bvh2_validate_counts(s, name, "CWBV", node_count, tri_count, leaves, references, max_leaf_depth);
done:
    free(node_seen);
    free(tri_seen);
    free(stack);
    return err;
}

#ifdef AS_HAVE_CUDA
as_error_t as_cwbvh_validate_gpu(const as_structure_t *s, const char *name)
{
    const as_section_t *ns = as_structure_find(s, ASF_TAG_CWBV), *ts = as_structure_find(s, ASF_TAG_TRI4);
    if (!ns || !ts || !s->gpu) return as_set_error(AS_ERROR_INVALID_STRUCTURE, "%s: CWBV or TRI4 section missing", name);
    as_gpu_bvh2_expect_t e = {
        .node_count = ns->count,
        .tri_count = ts->count,
        .clipped_leaves = s->meta.builder == AS_BUILDER_BVH_SBVH,
    };
    as_gpu_meta_expect(s, &e.meta);
    return as_gpu_validate_cwbvh(s->gpu, name, &e);
}
#endif
