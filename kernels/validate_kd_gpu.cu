// Structural validation of the KD layouts on the GPU, after the upload and
// before any traversal kernel reads them: the checks of as_kd_validate and
// as_kd_ropes_validate (libas/src/kd_validate.c, kd_ropes.c), with one
// thread per node, leaf and triangle (validate_gpu_common.cuh says how the
// walk's claims and depths become order-free).
//
// The CPU walk carries each node's box down from the scene box, replacing
// one face at each split, and checks every split strictly inside its box.
// Here the box is an intersection along the path to the root, found by the
// same pointer jumping as the depth: each node starts with the half-space
// its parent's split gives it, and each doubling intersects it with its
// known ancestor's. Below a node whose split is strictly inside its box the
// replaced face and the intersection are the same float, so the shallowest
// bad split sees the box the CPU sees, and a tree passes here exactly when
// it passes there. Each face also keeps the node whose split made it (the
// deepest one, since nested faces strictly tighten): that split's other
// child is the rope before optimisation, and pushing it down once with the
// leaf's box gives the rope the CPU's walk computes level by level (each
// level's descent is a prefix of the leaf's, boxes only shrinking).
#include "kd_layout.h"
#include "validate_gpu_common.cuh"

#include <cmath>

namespace {

enum check : unsigned {
    LEAF_INDEX = GV_LAYOUT_CHECKS,
    LEAF_INDEX_TWICE,
    LEAF_PRIM_OFFSET,
    LEAF_PRIM_COUNT,
    LEAF_TRI_RANGE,
    CHILD_RANGE,
    NODE_TWICE,
    NODE_UNREACHABLE,
    SPLIT,
    NODE_TOO_DEEP,
    LEAF_MISSING,
    ROPE,
    LEAF_BOX,
};

// gv_scratch counts.
enum { INNER, LEAVES, EMPTY, REFERENCES };

// A node's box so far and, for each face, the node whose split made it and
// the rope's start: the split's other child (-1: the scene box).
struct kd_box {
    float lo[3], hi[3];
    int src_lo[3], src_hi[3];
};

__device__ inline kd_box kd_open_box()
{
    kd_box b;
    for (int a = 0; a < 3; ++a) {
        b.lo[a] = -INFINITY;
        b.hi[a] = INFINITY;
        b.src_lo[a] = b.src_hi[a] = -1;
    }
    return b;
}

// One thread per node. Inner nodes claim their children and hand each the
// half-space of its side; leaves claim their leaf index and check their
// PRIM list.
__global__ void check_nodes(const as_kd_node_t *nodes, unsigned long long node_count, const unsigned *prim,
                            unsigned long long prim_count, unsigned long long tri_count, kd_box root, int *parent,
                            int *leaf_owner, kd_box *box, gv_scratch *s)
{
    const unsigned long long i = gv_thread_index();
    if (i >= node_count) return;
    const as_kd_node_t n = nodes[i];
    unsigned long long inner = 0, leaves = 0, empty = 0, references = 0;
    if (i == 0) box[0] = root;
    if (as_kd_is_leaf(n.word1)) {
        const unsigned long long li = n.word1 >> 2, off = n.word0;
        leaves = 1;
        if (li >= node_count) gv_fail(s, LEAF_INDEX, i);
        else if (atomicCAS(&leaf_owner[li], -1, (int)i) != -1) gv_fail(s, LEAF_INDEX_TWICE, li);
        if (off >= prim_count) {
            gv_fail(s, LEAF_PRIM_OFFSET, i);
        } else {
            const unsigned long long cnt = prim[off];
            if (cnt > prim_count - off - 1) {
                gv_fail(s, LEAF_PRIM_COUNT, i);
            } else {
                for (unsigned long long k = 1; k <= cnt; ++k)
                    if (prim[off + k] >= tri_count) { gv_fail(s, LEAF_TRI_RANGE, i); break; }
                references = cnt;
                empty = cnt == 0;
            }
        }
    } else {
        inner = 1;
        const int axis = (int)(n.word1 & 3u);
        const float split = __uint_as_float(n.word0);
        const unsigned long long below = i + 1, above = n.word1 >> 2;
        if (!gv_finite(split)) {
            gv_fail(s, SPLIT, i);
        } else if (below >= node_count || above >= node_count || above <= below) {
            gv_fail(s, CHILD_RANGE, i);
        } else {
            if (atomicCAS(&parent[below], -1, (int)i) != -1) {
                gv_fail(s, NODE_TWICE, below);
            } else {
                kd_box b = kd_open_box();
                b.hi[axis] = split;
                b.src_hi[axis] = (int)above;
                box[below] = b;
            }
            if (atomicCAS(&parent[above], -1, (int)i) != -1) {
                gv_fail(s, NODE_TWICE, above);
            } else {
                kd_box b = kd_open_box();
                b.lo[axis] = split;
                b.src_lo[axis] = (int)below;
                box[above] = b;
            }
        }
    }
    gv_count(s, INNER, inner);
    gv_count(s, LEAVES, leaves);
    gv_count(s, EMPTY, empty);
    gv_count(s, REFERENCES, references);
}

// One doubling of depth, ancestor and box (the root's box intersected with
// itself stays the same, so it can be its own ancestor).
__global__ void jump_round(const int *anc, const unsigned *depth, const kd_box *box, unsigned long long node_count,
                           int *anc_out, unsigned *depth_out, kd_box *box_out)
{
    const unsigned long long i = gv_thread_index();
    if (i >= node_count) return;
    const int a = anc[i];
    anc_out[i] = anc[a];
    depth_out[i] = depth[i] + depth[a];
    kd_box b = box[i];
    const kd_box o = box[a];
    for (int k = 0; k < 3; ++k) {
        if (o.lo[k] > b.lo[k]) { b.lo[k] = o.lo[k]; b.src_lo[k] = o.src_lo[k]; }
        if (o.hi[k] < b.hi[k]) { b.hi[k] = o.hi[k]; b.src_hi[k] = o.src_hi[k]; }
    }
    box_out[i] = b;
}

// Every node reached within AS_KD_MAX_DEPTH levels, inner nodes above that
// depth (one stack entry per level), splits strictly inside their box; the
// deepest node for META.
__global__ void check_depths(const as_kd_node_t *nodes, const int *anc, const unsigned *depth, const kd_box *box,
                             unsigned long long node_count, gv_scratch *s)
{
    const unsigned long long i = gv_thread_index();
    if (i >= node_count) return;
    if (anc[i] != 0) { gv_fail(s, NODE_TOO_DEEP, i); return; }
    atomicMax(&s->max_depth, depth[i]);
    const as_kd_node_t n = nodes[i];
    if (as_kd_is_leaf(n.word1)) return;
    const int axis = (int)(n.word1 & 3u);
    const float split = __uint_as_float(n.word0);
    const kd_box b = box[i];
    if (!(split > b.lo[axis] && split < b.hi[axis])) gv_fail(s, SPLIT, i);
    else if (depth[i] + 1 > AS_KD_MAX_DEPTH) gv_fail(s, NODE_TOO_DEEP, i);
}

// Leaf indices 0 .. leaves - 1 each used (they are distinct and in range).
__global__ void check_leaf_ids(const int *leaf_owner, unsigned long long leaves, gv_scratch *s)
{
    const unsigned long long i = gv_thread_index();
    if (i < leaves && leaf_owner[i] < 0) gv_fail(s, LEAF_MISSING, i);
}

// kd_ropes.c's optimise: pushes the rope of face `face` of `box` ({lo, hi})
// down to the deepest node covering it. The tree is valid by now, so the
// descent ends at a leaf within AS_KD_MAX_DEPTH steps.
__device__ int optimise(const as_kd_node_t *nodes, int r, int face, const float box[6])
{
    const int fa = face >> 1, positive = face & 1;
    for (int step = 0; r >= 0 && step <= AS_KD_MAX_DEPTH; ++step) {
        const as_kd_node_t n = nodes[r];
        if (as_kd_is_leaf(n.word1)) break;
        const int axis = (int)(n.word1 & 3u);
        const float sp = __uint_as_float(n.word0);
        const int below = r + 1, above = (int)(n.word1 >> 2);
        if (axis == fa) r = positive ? below : above;
        else if (box[axis + 3] <= sp) r = below;
        else if (box[axis] >= sp) r = above;
        else break;
    }
    return r;
}

// One thread per leaf node: its stored box and ropes must be, bit for bit,
// the ones the tree defines.
__global__ void check_ropes(const as_kd_node_t *nodes, unsigned long long node_count, const kd_box *box,
                            const as_kd_ropes_t *ropes, const as_kd_leaf_box_t *leaf_boxes, gv_scratch *s)
{
    const unsigned long long i = gv_thread_index();
    if (i >= node_count) return;
    const as_kd_node_t n = nodes[i];
    if (!as_kd_is_leaf(n.word1)) return;
    const unsigned long long li = n.word1 >> 2;
    const kd_box b = box[i];
    const float b6[6] = {b.lo[0], b.lo[1], b.lo[2], b.hi[0], b.hi[1], b.hi[2]};
    const as_kd_ropes_t stored = ropes[li];
    for (int f = 0; f < 6; ++f) {
        const int start = (f & 1) ? b.src_hi[f >> 1] : b.src_lo[f >> 1];
        if (stored.rope[f] != optimise(nodes, start, f, b6)) { gv_fail(s, ROPE, li); return; }
    }
    const as_kd_leaf_box_t lb = leaf_boxes[li];
    for (int a = 0; a < 3; ++a)
        if (__float_as_uint(lb.lo[a]) != __float_as_uint(b.lo[a]) || __float_as_uint(lb.hi[a]) != __float_as_uint(b.hi[a])) {
            gv_fail(s, LEAF_BOX, li);
            return;
        }
}

as_error_t report(const char *name, unsigned long long key, const as_gpu_kd_expect_t *e)
{
    const unsigned long long index = key >> 8;
    switch ((unsigned)(key & 0xff)) {
    case LEAF_INDEX:
        return as_set_error(AS_ERROR_INVALID_STRUCTURE, "%s: leaf node %llu has a leaf index outside the %llu nodes", name,
                            index, (unsigned long long)e->node_count);
    case LEAF_INDEX_TWICE:
        return as_set_error(AS_ERROR_INVALID_STRUCTURE, "%s: leaf index %llu is used by two leaf nodes", name, index);
    case LEAF_PRIM_OFFSET:
        return as_set_error(AS_ERROR_INVALID_STRUCTURE, "%s: leaf node %llu: PRIM offset outside the %llu entries", name,
                            index, (unsigned long long)e->prim_count);
    case LEAF_PRIM_COUNT:
        return as_set_error(AS_ERROR_INVALID_STRUCTURE, "%s: leaf node %llu: its triangles run past the %llu PRIM entries",
                            name, index, (unsigned long long)e->prim_count);
    case LEAF_TRI_RANGE:
        return as_set_error(AS_ERROR_INVALID_STRUCTURE, "%s: leaf node %llu refers to a triangle outside the %llu of TRIS",
                            name, index, (unsigned long long)e->tri_count);
    case CHILD_RANGE:
        return as_set_error(AS_ERROR_INVALID_STRUCTURE, "%s: node %llu has children outside (%llu, %llu) or out of order",
                            name, index, index, (unsigned long long)e->node_count);
    case NODE_TWICE:
        return as_set_error(AS_ERROR_INVALID_STRUCTURE, "%s: node %llu is referenced twice: a cycle or a shared subtree",
                            name, index);
    case NODE_UNREACHABLE:
        return as_set_error(AS_ERROR_INVALID_STRUCTURE, "%s: node %llu is not reachable from the root", name, index);
    case SPLIT:
        return as_set_error(AS_ERROR_INVALID_STRUCTURE, "%s: node %llu's split is not finite and strictly inside its box",
                            name, index);
    case NODE_TOO_DEEP:
        return as_set_error(AS_ERROR_INVALID_STRUCTURE, "%s: node %llu is deeper than the traversal stack (%d levels)",
                            name, index, AS_KD_MAX_DEPTH);
    case LEAF_MISSING:
        return as_set_error(AS_ERROR_INVALID_STRUCTURE, "%s: leaf indices are not 0..leaves-1 (missing %llu)", name, index);
    case ROPE:
        return as_set_error(AS_ERROR_INVALID_STRUCTURE, "%s: KDRP leaf %llu: ropes differ from the ones the tree defines",
                            name, index);
    case LEAF_BOX:
        return as_set_error(AS_ERROR_INVALID_STRUCTURE, "%s: KDLB leaf %llu: box differs from the one the tree defines",
                            name, index);
    default:
        return gv_report_shared(name, key, e->tri_count, e->meta.mesh_triangles);
    }
}

} // namespace

extern "C" as_error_t as_gpu_validate_kd(const as_gpu_resident_t *g, const char *name, const as_gpu_kd_expect_t *e)
{
    const unsigned long long nn = e->node_count, np = e->prim_count, nt = e->tri_count;
    if (nn == 0) return as_set_error(AS_ERROR_INVALID_STRUCTURE, "%s: KDN8 has no root node", name);
    if (nn >= (1u << 30) || np >= UINT32_MAX)
        return as_set_error(AS_ERROR_INVALID_STRUCTURE, "%s: %llu nodes / %llu PRIM entries exceed the index range", name,
                            nn, np);
    if (nt != e->meta.mesh_triangles)
        return as_set_error(AS_ERROR_INVALID_STRUCTURE, "%s: TRIS holds %llu triangles but META says the mesh has %u",
                            name, nt, e->meta.mesh_triangles);
    for (int k = 0; k < 3; ++k)
        if (!std::isfinite(e->meta.bounds_lo[k]) || !std::isfinite(e->meta.bounds_hi[k]) || !(e->meta.bounds_lo[k] <= e->meta.bounds_hi[k]))
            return as_set_error(AS_ERROR_INVALID_STRUCTURE, "%s: META scene box is not finite or inverted on axis %d",
                                name, k);
    const as_kd_node_t *nodes = static_cast<const as_kd_node_t *>(g->device[0]);
    const unsigned *prim = static_cast<const unsigned *>(g->device[1]);
    const as_tri4_t *tris = static_cast<const as_tri4_t *>(g->device[2]);
    kd_box root;
    for (int a = 0; a < 3; ++a) {
        root.lo[a] = e->meta.bounds_lo[a];
        root.hi[a] = e->meta.bounds_hi[a];
        root.src_lo[a] = root.src_hi[a] = -1;
    }
    gv_memory mem;
    int *parent = mem.get<int>(nn, 0xff);
    int *leaf_owner = mem.get<int>(nn, 0xff);
    int *anc[2] = {mem.get<int>(nn), mem.get<int>(nn)};
    unsigned *depth[2] = {mem.get<unsigned>(nn), mem.get<unsigned>(nn)};
    // Zeroed: a node no parent claims fails as unreachable, but its box is
    // still read, and must not depend on what the memory held.
    kd_box *box[2] = {mem.get<kd_box>(nn, 0), mem.get<kd_box>(nn, 0)};
    gv_scratch *d_s = gv_new_scratch(mem);
    gv_scratch h_s;
    if (!d_s) return gv_no_memory(name, mem.error());
    if (nt) gv_check_tris<<<gv_blocks(nt), 256>>>(tris, nt, d_s);
    check_nodes<<<gv_blocks(nn), 256>>>(nodes, nn, prim, np, nt, root, parent, leaf_owner, box[0], d_s);
    cudaError_t ce = gv_read(d_s, &h_s);
    int cur = 0;
    if (ce == cudaSuccess && h_s.first_failure == GV_NO_FAILURE) {
        gv_jump_start<<<gv_blocks(nn), 256>>>(parent, nn, anc[0], depth[0], NODE_UNREACHABLE, d_s);
        for (int round = 0; round < gv_rounds(AS_KD_MAX_DEPTH); ++round, cur ^= 1)
            jump_round<<<gv_blocks(nn), 256>>>(anc[cur], depth[cur], box[cur], nn, anc[cur ^ 1], depth[cur ^ 1],
                                               box[cur ^ 1]);
        check_depths<<<gv_blocks(nn), 256>>>(nodes, anc[cur], depth[cur], box[cur], nn, d_s);
        if (h_s.count[LEAVES])
            check_leaf_ids<<<gv_blocks(h_s.count[LEAVES]), 256>>>(leaf_owner, h_s.count[LEAVES], d_s);
        ce = gv_read(d_s, &h_s);
    }
    if (ce != cudaSuccess) return gv_cuda_failed(name, ce);
    if (h_s.first_failure != GV_NO_FAILURE) return report(name, h_s.first_failure, e);
    const unsigned long long leaves = h_s.count[LEAVES], empty = h_s.count[EMPTY], refs = h_s.count[REFERENCES];
    if (e->meta.node_count != h_s.count[INNER])
        return as_set_error(AS_ERROR_INVALID_STRUCTURE, "%s: META says %llu inner nodes but the tree has %llu", name,
                            (unsigned long long)e->meta.node_count, h_s.count[INNER]);
    if (e->meta.leaf_count != leaves - empty || e->meta.empty_leaf_count != empty)
        return as_set_error(AS_ERROR_INVALID_STRUCTURE, "%s: META says %llu leaves and %llu empty ones, the tree has %llu and %llu",
                            name, (unsigned long long)e->meta.leaf_count, (unsigned long long)e->meta.empty_leaf_count,
                            leaves - empty, empty);
    if (e->meta.reference_count != refs)
        return as_set_error(AS_ERROR_INVALID_STRUCTURE, "%s: META says %llu references, the leaves hold %llu", name,
                            (unsigned long long)e->meta.reference_count, refs);
    if (e->meta.max_depth != h_s.max_depth)
        return as_set_error(AS_ERROR_INVALID_STRUCTURE, "%s: META says max depth %u, the deepest leaf is at %u", name,
                            e->meta.max_depth, h_s.max_depth);
    if (!e->ropes) return AS_OK;
    if (e->rope_count != leaves || e->leaf_box_count != leaves)
        return as_set_error(AS_ERROR_INVALID_STRUCTURE, "%s: KDRP has %llu and KDLB %llu entries, the tree has %llu leaves",
                            name, (unsigned long long)e->rope_count, (unsigned long long)e->leaf_box_count, leaves);
    check_ropes<<<gv_blocks(nn), 256>>>(nodes, nn, box[cur], static_cast<const as_kd_ropes_t *>(g->device[3]),
                                        static_cast<const as_kd_leaf_box_t *>(g->device[4]), d_s);
    ce = gv_read(d_s, &h_s);
    if (ce != cudaSuccess) return gv_cuda_failed(name, ce);
    if (h_s.first_failure != GV_NO_FAILURE) return report(name, h_s.first_failure, e);
    return AS_OK;
}
