// Structural validation of a compressed wide BVH on the GPU, after its
// upload and before any traversal kernel reads it: the checks of
// as_cwbvh_validate (libas/src/cwbvh_validate.c) with one thread per node
// and per triangle (validate_gpu_common.cuh says how the walk's checks
// become order-free). Children come after their parent, so claims cannot
// close a cycle; pointer jumping gives the depths. The walk's running
// intersection of the boxes above a node becomes a walk up the claimed
// parents, at most AS_CWBVH_MAX_DEPTH steps once the depths are checked.
#include "cwbvh_layout.h"
#include "validate_gpu_common.cuh"

namespace {

enum check : unsigned {
    NODE_ORIGIN = GV_LAYOUT_CHECKS,
    NODE_EXPONENT,
    EMPTY_SLOT,
    INNER_META,
    LEAF_META,
    SLOT_BOX,
    CHILD_RANGE,
    NODE_TWICE,
    LEAF_RANGE,
    NODE_UNREACHABLE,
    NODE_TOO_DEEP,
    SLOT_APART,
};

// gv_scratch counts.
enum { LEAVES, REFERENCES };

// Slot s's decoded box, {lox, hix, loy, hiy, loz, hiz}.
__device__ inline void slot_box(const as_cwbvh_node_t &n, int s, float b[6])
{
    for (int a = 0; a < 3; ++a) {
        const float scale = as_cwbvh_scale(n.e[a]);
        b[2 * a] = as_cwbvh_decode(n.p[a], scale, n.qlo[a][s]);
        b[2 * a + 1] = as_cwbvh_decode(n.p[a], scale, n.qhi[a][s]);
    }
}

// One thread per node: its own fields (as check_node on the CPU), claims of
// its inner children (with the slot that names each) and of its leaves'
// triangles.
__global__ void check_nodes(const as_cwbvh_node_t *nodes, unsigned long long node_count, unsigned long long tri_count,
                            int *parent, unsigned char *parent_slot, unsigned *owner, gv_scratch *s)
{
    const unsigned long long i = gv_thread_index();
    if (i >= node_count) return;
    const as_cwbvh_node_t n = nodes[i];
    unsigned long long leaves = 0, references = 0;
    for (int a = 0; a < 3; ++a) {
        if (!gv_finite(n.p[a])) { gv_fail(s, NODE_ORIGIN, i); return; }
        if (n.e[a] < 1 || n.e[a] > 254) { gv_fail(s, NODE_EXPONENT, i); return; }
    }
    unsigned rank = 0;
    for (int k = 0; k < 8; ++k) {
        const unsigned meta = n.meta[k];
        const bool inner_bit = (n.imask >> k) & 1;
        if (meta == 0) {
            unsigned q = 0;
            for (int a = 0; a < 3; ++a) q |= n.qlo[a][k] | n.qhi[a][k];
            if (inner_bit || q) gv_fail(s, EMPTY_SLOT, i);
            continue;
        }
        const bool inner = as_cwbvh_meta_is_inner(meta);
        if (inner && (meta != AS_CWBVH_META_INNER(k) || !inner_bit)) { gv_fail(s, INNER_META, i); continue; }
        const unsigned unary = meta >> 5, count = as_cwbvh_meta_count(meta);
        if (!inner && (inner_bit || (unary != 1 && unary != 3 && unary != 7) || (meta & 31u) + count > 24)) {
            gv_fail(s, LEAF_META, i);
            continue;
        }
        float b[6];
        slot_box(n, k, b);
        bool box_ok = true;
        for (int a = 0; a < 3; ++a) box_ok = box_ok && n.qlo[a][k] <= n.qhi[a][k];
        if (!box_ok || !gv_box_ok(b)) { gv_fail(s, SLOT_BOX, i); continue; }
        if (inner) {
            const unsigned long long ci = (unsigned long long)n.child_base + rank++;
            if (ci <= i || ci >= node_count) { gv_fail(s, CHILD_RANGE, i); continue; }
            if (atomicCAS(&parent[ci], -1, (int)i) != -1) { gv_fail(s, NODE_TWICE, ci); continue; }
            parent_slot[ci] = (unsigned char)k;
            continue;
        }
        const unsigned long long first = (unsigned long long)n.tri_base + (meta & 31u);
        if (first > tri_count || count > tri_count - first) { gv_fail(s, LEAF_RANGE, i); continue; }
        ++leaves;
        references += count;
        for (unsigned long long t = first; t < first + count; ++t)
            if (atomicExch(&owner[t], 0u) != 0xffffffffu) gv_fail(s, GV_TRI4_TWICE, t);
    }
    gv_count(s, LEAVES, leaves);
    gv_count(s, REFERENCES, references);
}

// Every node within the stack's depth, and the deepest leaf for META.
__global__ void check_depths(const as_cwbvh_node_t *nodes, const int *anc, const unsigned *depth,
                             unsigned long long node_count, gv_scratch *s)
{
    const unsigned long long i = gv_thread_index();
    if (i >= node_count) return;
    if (anc[i] != 0 || depth[i] > AS_CWBVH_MAX_DEPTH) { gv_fail(s, NODE_TOO_DEEP, i); return; }
    const as_cwbvh_node_t n = nodes[i];
    bool has_leaf = false;
    for (int k = 0; k < 8; ++k) has_leaf = has_leaf || (n.meta[k] && !as_cwbvh_meta_is_inner(n.meta[k]));
    if (has_leaf) atomicMax(&s->max_depth, depth[i] + 1);
}

// The boxes above each node intersected, then each slot's box within them
// and each leaf's triangles inside (SBVH: overlapping) what remains.
__global__ void check_boxes(const as_cwbvh_node_t *nodes, unsigned long long node_count, const as_tri4_t *tris,
                            const int *parent, const unsigned char *parent_slot, int clipped, gv_scratch *s)
{
    const unsigned long long i = gv_thread_index();
    if (i >= node_count) return;
    float clip[6] = {-INFINITY, INFINITY, -INFINITY, INFINITY, -INFINITY, INFINITY};
    for (unsigned long long c = i; c != 0;) {
        const int p = parent[c];
        float b[6];
        slot_box(nodes[p], parent_slot[c], b);
        for (int a = 0; a < 3; ++a) {
            clip[2 * a] = fmaxf(clip[2 * a], b[2 * a]);
            clip[2 * a + 1] = fminf(clip[2 * a + 1], b[2 * a + 1]);
        }
        c = (unsigned long long)p;
    }
    const as_cwbvh_node_t n = nodes[i];
    for (int k = 0; k < 8; ++k) {
        const unsigned meta = n.meta[k];
        if (meta == 0) continue;
        float b[6];
        slot_box(n, k, b);
        bool apart = false;
        for (int a = 0; a < 3; ++a) {
            b[2 * a] = fmaxf(b[2 * a], clip[2 * a]);
            b[2 * a + 1] = fminf(b[2 * a + 1], clip[2 * a + 1]);
            apart = apart || !(b[2 * a] <= b[2 * a + 1]);
        }
        if (apart) { gv_fail(s, SLOT_APART, i); continue; }
        if (as_cwbvh_meta_is_inner(meta)) continue;
        const unsigned long long first = (unsigned long long)n.tri_base + (meta & 31u);
        const unsigned count = as_cwbvh_meta_count(meta);
        for (unsigned long long t = first; t < first + count; ++t) {
            float tb[6];
            gv_tri_box(tris[t], tb);
            const bool ok = clipped ? tb[0] <= b[1] && tb[1] >= b[0] && tb[2] <= b[3] && tb[3] >= b[2] &&
                                          tb[4] <= b[5] && tb[5] >= b[4]
                                    : gv_box_inside(tb, b);
            if (!ok) gv_fail(s, GV_TRI4_OUTSIDE_LEAF, t);
        }
    }
}

as_error_t report(const char *name, unsigned long long key, const as_gpu_bvh2_expect_t *e)
{
    const unsigned long long index = key >> 8;
    switch ((unsigned)(key & 0xff)) {
    case NODE_ORIGIN:
        return as_set_error(AS_ERROR_INVALID_STRUCTURE, "%s: CWBV node %llu has a non-finite origin", name, index);
    case NODE_EXPONENT:
        return as_set_error(AS_ERROR_INVALID_STRUCTURE, "%s: CWBV node %llu has an exponent outside [1, 254]", name,
                            index);
    case EMPTY_SLOT:
        return as_set_error(AS_ERROR_INVALID_STRUCTURE,
                            "%s: CWBV node %llu has an empty slot with its imask bit or box bytes set", name, index);
    case INNER_META:
        return as_set_error(AS_ERROR_INVALID_STRUCTURE, "%s: CWBV node %llu has an inner slot whose meta and imask "
                            "disagree", name, index);
    case LEAF_META:
        return as_set_error(AS_ERROR_INVALID_STRUCTURE, "%s: CWBV node %llu has a leaf meta that is not a unary count "
                            "of 1 to 3 at an offset within 24, or its imask bit set", name, index);
    case SLOT_BOX:
        return as_set_error(AS_ERROR_INVALID_STRUCTURE, "%s: CWBV node %llu has a slot with a non-finite or inverted "
                            "box", name, index);
    case CHILD_RANGE:
        return as_set_error(AS_ERROR_INVALID_STRUCTURE, "%s: CWBV node %llu has a child outside (%llu, %llu)", name,
                            index, index, (unsigned long long)e->node_count);
    case NODE_TWICE:
        return as_set_error(AS_ERROR_INVALID_STRUCTURE,
                            "%s: CWBV node %llu is referenced twice: a cycle or a shared subtree", name, index);
    case LEAF_RANGE:
        return as_set_error(AS_ERROR_INVALID_STRUCTURE, "%s: CWBV node %llu: leaf triangles outside the %llu of TRI4",
                            name, index, (unsigned long long)e->tri_count);
    case NODE_UNREACHABLE:
        return as_set_error(AS_ERROR_INVALID_STRUCTURE, "%s: CWBV node %llu is not reachable from the root", name, index);
    case NODE_TOO_DEEP:
        return as_set_error(AS_ERROR_INVALID_STRUCTURE, "%s: CWBV node %llu is deeper than the traversal stack (%d "
                            "levels)", name, index, AS_CWBVH_MAX_DEPTH);
    case SLOT_APART:
        return as_set_error(AS_ERROR_INVALID_STRUCTURE, "%s: CWBV node %llu has a slot whose box lies outside the boxes "
                            "of the nodes above it", name, index);
    default:
        return gv_report_shared(name, key, e->tri_count, e->meta.mesh_triangles);
    }
}

} // namespace

extern "C" as_error_t as_gpu_validate_cwbvh(const as_gpu_resident_t *g, const char *name, const as_gpu_bvh2_expect_t *e)
{
    const unsigned long long nn = e->node_count, nt = e->tri_count;
    if (nn == 0) return as_set_error(AS_ERROR_INVALID_STRUCTURE, "%s: CWBV has no root node", name);
    if (nn > INT32_MAX || nt > INT32_MAX)
        return as_set_error(AS_ERROR_INVALID_STRUCTURE, "%s: %llu nodes / %llu triangles exceed the 31-bit index range",
                            name, nn, nt);
    const as_cwbvh_node_t *nodes = static_cast<const as_cwbvh_node_t *>(g->device[0]);
    const as_tri4_t *tris = static_cast<const as_tri4_t *>(g->device[1]);
    gv_memory mem;
    int *parent = mem.get<int>(nn, 0xff);
    unsigned char *parent_slot = mem.get<unsigned char>(nn, 0);
    int *anc[2] = {mem.get<int>(nn), mem.get<int>(nn)};
    unsigned *depth[2] = {mem.get<unsigned>(nn), mem.get<unsigned>(nn)};
    unsigned *owner = mem.get<unsigned>(nt, 0xff);
    gv_scratch *d_s = gv_new_scratch(mem);
    gv_scratch h_s;
    if (!d_s) return gv_no_memory(name, mem.error());
    if (nt) gv_check_tri4<<<gv_blocks(nt), 256>>>(tris, nt, e->meta.mesh_triangles, d_s);
    check_nodes<<<gv_blocks(nn), 256>>>(nodes, nn, nt, parent, parent_slot, owner, d_s);
    cudaError_t ce = gv_read(d_s, &h_s);
    if (ce == cudaSuccess && h_s.first_failure == GV_NO_FAILURE) {
        // Depths up to AS_CWBVH_MAX_DEPTH, and one level more to tell a node
        // just past it from an unreachable one.
        const int cur = gv_depths(parent, nn, AS_CWBVH_MAX_DEPTH + 1, NODE_UNREACHABLE, anc, depth, d_s);
        check_depths<<<gv_blocks(nn), 256>>>(nodes, anc[cur], depth[cur], nn, d_s);
        if (nt) gv_check_tri4_owned<<<gv_blocks(nt), 256>>>(owner, nt, d_s);
        ce = gv_read(d_s, &h_s);
    }
    if (ce == cudaSuccess && h_s.first_failure == GV_NO_FAILURE) {
        check_boxes<<<gv_blocks(nn), 256>>>(nodes, nn, tris, parent, parent_slot, e->clipped_leaves, d_s);
        ce = gv_read(d_s, &h_s);
    }
    if (ce != cudaSuccess) return gv_cuda_failed(name, ce);
    if (h_s.first_failure != GV_NO_FAILURE) return report(name, h_s.first_failure, e);
    return gv_bvh2_counts(name, "CWBV", nn, h_s.count[LEAVES], h_s.count[REFERENCES], h_s.max_depth, e);
}
