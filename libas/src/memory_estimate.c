/* Memory of a build before it runs: an upper bound of the structure's bytes
 * and an estimate of the builder's working memory, from the mesh's counts
 * and the build arguments alone (and, for the grid, the scene box, which
 * fixes its resolution), for every kind.
 *
 * For the BVH, the bounds follow the builders' code (bvh_build_common.c and the four
 * builders): zero-area triangles are left out, so N = triangles minus
 * degenerate ones; every builder but the SBVH holds each triangle once
 * (TRI4 = N entries), the SBVH at most split_budget x N (its reference
 * budget); a binary tree whose leaves hold at least one reference has at
 * most references - 1 inner nodes, and a one-leaf tree still has its root
 * (the empty sibling); the own-bounds layout stores 1 + 2 x inner nodes.
 * The compressed wide BVH (cwbvh_build.c) collapses a binary tree built
 * with one triangle per leaf: TRI4 as that tree's, and at most one wide
 * node per reference (every wide node but a lone root has two children or
 * more, every leaf a triangle or more). */
#include "structure.h"
#include "mesh.h"
#include "bvh_build_common.h"
#include "bvh2_own_layout.h"
#include "cwbvh_layout.h"
#include "kd_layout.h"
#include "bih_layout.h"
#include "octree_layout.h"
#include "grid_layout.h"

#include <float.h>

#include <math.h>
#include <string.h>

/* Nodes of a binary tree over `refs` references, at most. */
static uint64_t inner_nodes_max(uint64_t refs) { return refs > 2 ? refs - 1 : 1; }

static as_error_t estimate_bvh(const as_mesh_t *mesh, as_build_args_t args, as_memory_estimate_t *out)
{
    const as_builder_t builder = args.builder == AS_BUILDER_DEFAULT ? AS_BUILDER_BVH_SAH_BINNED : args.builder;
    const as_layout_t layout = args.layout == AS_LAYOUT_DEFAULT ? AS_LAYOUT_BVH2_CHILD_BOUNDS : args.layout;
    if (layout != AS_LAYOUT_BVH2_CHILD_BOUNDS && layout != AS_LAYOUT_BVH2_OWN_BOUNDS && layout != AS_LAYOUT_BVH_CWBVH)
        return as_set_error(AS_ERROR_UNSUPPORTED, "layout 0x%04x is not a BVH layout", (unsigned)layout);
    const int wide = layout == AS_LAYOUT_BVH_CWBVH;
    if (wide) args.max_leaf_size = 1;
    if (builder != AS_BUILDER_BVH_SAH_BINNED && builder != AS_BUILDER_BVH_SAH_SWEEP &&
        builder != AS_BUILDER_BVH_MIDCUT && builder != AS_BUILDER_BVH_SBVH)
        return as_set_error(AS_ERROR_UNSUPPORTED, "builder 0x%04x is not a BVH builder", (unsigned)builder);
    const int sbvh = builder == AS_BUILDER_BVH_SBVH;
    if (sbvh && (!(args.split_budget >= 0.0f) || !isfinite(args.split_budget)))
        return as_set_error(AS_ERROR_INVALID_ARGUMENT, "split budget must be finite and >= 0 (got %g)",
                            (double)args.split_budget);

    as_mesh_info_t info;
    as_mesh_get_info(mesh, &info);
    const uint64_t n = (uint64_t)info.triangle_count - info.degenerate_count;
    /* The SBVH adds at most floor((split_budget - 1) x N) references, the
     * factor capped at 15 (bvh_build_sbvh.c). */
    double factor = sbvh && args.split_budget > 1.0f ? (double)args.split_budget - 1.0 : 0.0;
    if (factor > 15.0) factor = 15.0;
    const uint64_t refs_max = n + (uint64_t)floor(factor * (double)n);
    const uint64_t inner_max = inner_nodes_max(refs_max);
    const uint64_t bin_node_bytes = sizeof(as_bvh2_node_t) * inner_max;
    const uint64_t node_bytes = wide ? sizeof(as_cwbvh_node_t) * (refs_max ? refs_max : 1)
                                : layout == AS_LAYOUT_BVH2_CHILD_BOUNDS ? bin_node_bytes
                                                                        : sizeof(as_bvh2o_node_t) * (1 + 2 * inner_max);
    out->structure_bytes_max = sizeof(as_meta_t) + node_bytes + sizeof(as_tri4_t) * refs_max;

    /* Typical: leaves half full on average, a quarter more references for
     * an SBVH at the default budget (what the bunny and the study's scenes
     * show); an estimate, not a bound. */
    const uint64_t refs_typ = sbvh ? (uint64_t)fmin((double)refs_max, 1.25 * (double)n) : n;
    const double leaf_fill = args.max_leaf_size > 1 ? 0.5 * (args.max_leaf_size + 1) : 1.0;
    const uint64_t leaves_typ = (uint64_t)ceil((double)refs_typ / leaf_fill);
    const uint64_t inner_typ = inner_nodes_max(leaves_typ + 1);
    /* Wide: about one node per eight references (0.12 on the staircase,
     * leaves of 1.35 triangles and 6.3 leaves per node). */
    out->structure_bytes_typical =
        sizeof(as_meta_t) + sizeof(as_tri4_t) * refs_typ +
        (wide ? sizeof(as_cwbvh_node_t) * (uint64_t)fmax(1.0, ceil(0.12 * (double)refs_typ))
              : layout == AS_LAYOUT_BVH2_CHILD_BOUNDS ? sizeof(as_bvh2_node_t) * inner_typ
                                                      : sizeof(as_bvh2o_node_t) * (1 + 2 * inner_typ));

    /* Working memory, from the allocations of bvh_builder_init and the
     * builders: the references (one bvh_ref each) and the temporary tree
     * (two nodes per reference), the flattened output, and per builder its
     * own: the sweep's sorted keys, areas and copy at the root (three
     * 12-byte keys per axis entry, one double and one reference per
     * reference), the SBVH's root copy of its references and the left and
     * right lists of a split, which live down one path of the tree (their
     * sum halves at each level, so twice the root's). The mesh is the
     * caller's and not counted. */
    uint64_t peak = sizeof(bvh_ref) * (n ? n : 1) + sizeof(bvh_tmp_node) * (2 * refs_max + 3) + out->structure_bytes_max;
    if (builder == AS_BUILDER_BVH_SAH_SWEEP) peak += (3 * 12 + 8 + sizeof(bvh_ref)) * n;
    if (sbvh) peak += sizeof(bvh_ref) * refs_max * 3;
    /* The collapse: the binary tree it reads (kept until it is done), its
     * own copy with costs and choices (81 bytes a node, up to two per
     * binary node and two per reference), and its output. */
    if (wide) peak += bin_node_bytes + sizeof(as_tri4_t) * refs_max + 81 * (2 * inner_max + 2 * refs_max + 2);
    out->build_peak_bytes = peak;
    return AS_OK;
}

/* References a budget allows: the builders compare the running total, an
 * integer, with split_budget x N, so the floor. None without triangles. */
static uint64_t budget_refs(double budget, uint64_t n)
{
    if (n == 0) return 0;
    const double r = floor(budget * (double)n);
    return r < 18446744073709551615.0 ? (uint64_t)r : UINT64_MAX;
}

/* Inner nodes of a tree of fan-out `fanout` whose inner nodes lie at depths
 * 0 .. levels - 1, the root inner only when `root_inner`, and at most
 * `per_level` inner nodes on one level: every level holds at most fan-out
 * times the inner nodes of the one above, and per_level bounds it where the
 * nodes of a level share a reference total (each inner node holds at least
 * a minimum of references). */
static uint64_t inner_by_level(uint32_t levels, uint64_t fanout, uint64_t per_level, int root_inner)
{
    uint64_t total = 0, level = root_inner ? 1 : 0;
    for (uint32_t d = 0; d < levels && level; ++d) {
        if (level > per_level) level = per_level;
        total += level;
        level = level > UINT64_MAX / fanout ? UINT64_MAX : level * fanout;
    }
    return total;
}

static as_error_t check_budget(const as_build_args_t *args)
{
    if (!(args->split_budget >= 1.0f) || !isfinite(args->split_budget))
        return as_set_error(AS_ERROR_INVALID_ARGUMENT, "split budget must be finite and at least 1 (got %g)",
                            (double)args->split_budget);
    return AS_OK;
}

/* KD (kd_build.c): a node's subtree holds at most its share of split_budget
 * x N references (shares split in proportion to the children's counts, and a
 * split whose children would exceed the share is refused), so the references
 * of the leaves, and of the nodes of any one level, sum to at most that. A
 * node is inner only above the depth cap (8 + 1.3 log2 N unless max_depth
 * says, never beyond AS_KD_MAX_DEPTH) and with at least max_leaf_size + 1
 * references (mid-cut) or one (SAH; two when traversal costs no less than an
 * intersection). Nothing else limits the nodes: a split may leave one side
 * empty, so empty leaves are bounded only by the depth cap. */
static as_error_t estimate_kd(const as_mesh_t *mesh, const as_build_args_t *args, as_memory_estimate_t *out)
{
    const as_builder_t builder = args->builder == AS_BUILDER_DEFAULT ? AS_BUILDER_KD_SAH : args->builder;
    const as_layout_t layout = args->layout == AS_LAYOUT_DEFAULT ? AS_LAYOUT_KD_STANDARD : args->layout;
    if (builder != AS_BUILDER_KD_SAH && builder != AS_BUILDER_KD_MIDCUT)
        return as_set_error(AS_ERROR_UNSUPPORTED, "builder 0x%04x is not a KD builder", (unsigned)builder);
    if (layout != AS_LAYOUT_KD_STANDARD && layout != AS_LAYOUT_KD_ROPES)
        return as_set_error(AS_ERROR_UNSUPPORTED, "layout 0x%04x is not a KD layout", (unsigned)layout);
    if (args->max_leaf_size < 1) return as_set_error(AS_ERROR_INVALID_ARGUMENT, "max leaf size must be at least 1");
    const as_error_t e = check_budget(args);
    if (e != AS_OK) return e;
    as_mesh_info_t info;
    as_mesh_get_info(mesh, &info);
    const uint64_t n = (uint64_t)info.triangle_count - info.degenerate_count;
    uint32_t cap = (uint32_t)(8.0 + 1.3 * log2((double)(n > 1 ? n : 1)));
    if (args->max_depth) cap = args->max_depth;
    if (cap > AS_KD_MAX_DEPTH) cap = AS_KD_MAX_DEPTH;
    const uint64_t min_split = builder == AS_BUILDER_KD_MIDCUT ? (uint64_t)args->max_leaf_size + 1
                               : args->cost_traversal >= args->cost_intersection ? 2 : 1;
    const uint64_t refs_max = budget_refs(args->split_budget, n);
    uint64_t inner = inner_by_level(cap, 2, refs_max / min_split, n >= min_split);
    /* The builder refuses 2^30 nodes or more. */
    if (inner > ((1u << 30) - 2) / 2) inner = ((1u << 30) - 2) / 2;
    const uint64_t leaves = inner + 1;
    const uint64_t per_leaf = layout == AS_LAYOUT_KD_ROPES ? sizeof(as_kd_ropes_t) + sizeof(as_kd_leaf_box_t) : 0;
    const uint64_t fixed = sizeof(as_meta_t) + sizeof(as_tri4_t) * (uint64_t)info.triangle_count;
    /* KDN8, PRIM (a count per leaf and its references), the ropes' two
     * sections per leaf. */
    out->structure_bytes_max =
        fixed + sizeof(as_kd_node_t) * (2 * inner + 1) + sizeof(uint32_t) * (leaves + refs_max) + per_leaf * leaves;

    /* Typical, from the test scenes (bunny, soups): about 1.6 N references
     * and 0.7 N leaves for the SAH (a third of them empty), 2.5 N and 0.6 N
     * for the mid-cut at the default leaf size; an estimate, not a bound. */
    const int sah = builder == AS_BUILDER_KD_SAH;
    const uint64_t refs_typ = (uint64_t)fmin((double)refs_max, (sah ? 1.6 : 2.5) * (double)n);
    const uint64_t leaves_typ = (uint64_t)fmin((double)leaves, ceil((sah ? 0.7 : 0.6) * (double)n) + 1);
    out->structure_bytes_typical = fixed + sizeof(as_kd_node_t) * (2 * leaves_typ - 1) +
                                   sizeof(uint32_t) * (leaves_typ + refs_typ) + per_leaf * leaves_typ;

    /* Working memory: the root's references and the children's copies down
     * one path (twice the root's), the temporary tree (about 48 bytes a
     * node, counted at the typical size: the bound is loose) with its
     * leaves' lists, and for the SAH its event lists (two 8-byte events per
     * reference and axis, at the root and down one path). */
    uint64_t peak = 2 * (uint64_t)(4 * 7) * (refs_max ? refs_max : 1) + 48 * (2 * leaves_typ) +
                    sizeof(uint32_t) * refs_max + out->structure_bytes_max;
    if (sah) peak += 2 * 48 * refs_max;
    out->build_peak_bytes = peak;
    return AS_OK;
}

/* BIH (bih_build.c): each triangle once, in one leaf; a node splits only
 * above the depth limit (max_depth, else AS_BIH_MAX_DEPTH) with more than
 * max_leaf_size objects, and both children non-empty (the global heuristic
 * splits where centres lie on both sides, the fallback halves the list), so
 * at most N - 1 inner nodes, and on one level at most N / (max_leaf_size +
 * 1). */
static as_error_t estimate_bih(const as_mesh_t *mesh, const as_build_args_t *args, as_memory_estimate_t *out)
{
    if ((args->builder != AS_BUILDER_DEFAULT && args->builder != AS_BUILDER_BIH) ||
        (args->layout != AS_LAYOUT_DEFAULT && args->layout != AS_LAYOUT_BIH))
        return as_set_error(AS_ERROR_UNSUPPORTED, "the BIH has one builder and one layout");
    if (args->max_leaf_size < 1) return as_set_error(AS_ERROR_INVALID_ARGUMENT, "max leaf size must be at least 1");
    as_mesh_info_t info;
    as_mesh_get_info(mesh, &info);
    const uint64_t n = (uint64_t)info.triangle_count - info.degenerate_count;
    const uint32_t levels = args->max_depth && args->max_depth < AS_BIH_MAX_DEPTH ? args->max_depth : AS_BIH_MAX_DEPTH;
    const uint64_t m = (uint64_t)args->max_leaf_size + 1;
    uint64_t inner = inner_by_level(levels, 2, n / m, n >= m);
    if (n && inner > n - 1) inner = n - 1;
    const uint64_t fixed = sizeof(as_meta_t) + sizeof(as_tri4_t) * (uint64_t)info.triangle_count + sizeof(uint32_t) * n;
    out->structure_bytes_max = fixed + sizeof(as_bih_node_t) * (2 * inner + 1);
    /* Typical: leaves about half full (what the test scenes show); an
     * estimate. */
    const uint64_t leaves_typ = (uint64_t)fmin((double)(inner + 1), ceil((double)n / (0.5 * (double)m)) + 1);
    out->structure_bytes_typical = fixed + sizeof(as_bih_node_t) * (2 * leaves_typ - 1);
    /* The references (32 bytes each) and the temporary nodes (2 N + 1 of 24
     * bytes, allocated up front). */
    out->build_peak_bytes = 32 * (n ? n : 1) + 24 * (2 * n + 1) + out->structure_bytes_max;
    return AS_OK;
}

/* Octree (octree_build.c): at most split_budget x N references (a cell is
 * split only while the total stays within it); a cell is inner only above
 * the depth limit (max_depth, else AS_OCTREE_DEFAULT_DEPTH, never beyond
 * AS_OCTREE_MAX_DEPTH) with more than max_leaf_size triangles, and the
 * cells of one level hold at most the total, so one level has at most
 * budget x N / (max_leaf_size + 1) inner cells; each inner cell adds eight
 * nodes, empty ones included. */
static as_error_t estimate_octree(const as_mesh_t *mesh, const as_build_args_t *args, as_memory_estimate_t *out)
{
    if ((args->builder != AS_BUILDER_DEFAULT && args->builder != AS_BUILDER_OCTREE) ||
        (args->layout != AS_LAYOUT_DEFAULT && args->layout != AS_LAYOUT_OCTREE))
        return as_set_error(AS_ERROR_UNSUPPORTED, "the octree has one builder and one layout");
    if (args->max_leaf_size < 1) return as_set_error(AS_ERROR_INVALID_ARGUMENT, "max leaf size must be at least 1");
    const as_error_t e = check_budget(args);
    if (e != AS_OK) return e;
    as_mesh_info_t info;
    as_mesh_get_info(mesh, &info);
    const uint64_t n = (uint64_t)info.triangle_count - info.degenerate_count;
    const uint32_t levels = args->max_depth == 0 ? AS_OCTREE_DEFAULT_DEPTH
                            : args->max_depth < AS_OCTREE_MAX_DEPTH ? args->max_depth : AS_OCTREE_MAX_DEPTH;
    const uint64_t m = (uint64_t)args->max_leaf_size + 1;
    const uint64_t refs_max = budget_refs(args->split_budget, n);
    const uint64_t inner = inner_by_level(levels, 8, refs_max / m, n >= m);
    const uint64_t fixed = sizeof(as_meta_t) + sizeof(as_octree_header_t) +
                           sizeof(as_tri4_t) * (uint64_t)info.triangle_count;
    out->structure_bytes_max = fixed + sizeof(as_octree_node_t) * (1 + 8 * inner) + sizeof(uint32_t) * refs_max;
    /* Typical, from the test scenes: about 2 N references and N / 3 inner
     * cells at the defaults; an estimate. */
    const uint64_t refs_typ = (uint64_t)fmin((double)refs_max, 2.0 * (double)n);
    const uint64_t inner_typ = (uint64_t)fmin((double)inner, ceil((double)n / 3.0));
    out->structure_bytes_typical = fixed + sizeof(as_octree_node_t) * (1 + 8 * inner_typ) + sizeof(uint32_t) * refs_typ;
    /* The cells (32 bytes a node, counted at the typical size: the bound is
     * loose), their lists, and a level's child lists (eight entries per
     * reference of a split cell). */
    out->build_peak_bytes = 32 * (1 + 8 * inner_typ) + 4 * (refs_max + n) + 32 * (refs_max ? refs_max : 1) +
                            out->structure_bytes_max;
    return AS_OK;
}

/* Grid (grid_build.c): the resolution is the builder's formula on the box
 * of the non-degenerate triangles, capped at AS_GRID_MAX_CELLS; the build
 * only lowers it (while references exceed split_budget x N), so the cells
 * computed here bound GRDC, and the budget bounds PRIM. */
static as_error_t estimate_grid(const as_mesh_t *mesh, const as_build_args_t *args, as_memory_estimate_t *out)
{
    if ((args->builder != AS_BUILDER_DEFAULT && args->builder != AS_BUILDER_GRID) ||
        (args->layout != AS_LAYOUT_DEFAULT && args->layout != AS_LAYOUT_GRID))
        return as_set_error(AS_ERROR_UNSUPPORTED, "the grid has one builder and one layout");
    if (!(args->grid_lambda > 0.0f) || !isfinite(args->grid_lambda))
        return as_set_error(AS_ERROR_INVALID_ARGUMENT, "grid lambda must be positive and finite");
    const as_error_t e = check_budget(args);
    if (e != AS_OK) return e;
    const uint32_t nt = mesh->triangle_count;
    uint64_t n = 0;
    float blo[3] = {FLT_MAX, FLT_MAX, FLT_MAX}, bhi[3] = {-FLT_MAX, -FLT_MAX, -FLT_MAX};
    for (uint32_t i = 0; i < nt; ++i) {
        if (as_mesh_triangle_is_degenerate(mesh, i)) continue;
        ++n;
        for (int v = 0; v < 3; ++v) {
            const float *q = mesh->positions + 3 * (size_t)mesh->indices[3 * (size_t)i + v];
            for (int k = 0; k < 3; ++k) {
                if (q[k] < blo[k]) blo[k] = q[k];
                if (q[k] > bhi[k]) bhi[k] = q[k];
            }
        }
    }
    if (n == 0) for (int k = 0; k < 3; ++k) { blo[k] = 0.0f; bhi[k] = 0.0f; }
    /* The builder's first resolution, the same expressions. */
    double ext[3], maxext = 0.0, measure = 1.0;
    int active[3], nactive = 0;
    for (int k = 0; k < 3; ++k) {
        ext[k] = (double)bhi[k] - blo[k];
        if (ext[k] > maxext) maxext = ext[k];
    }
    for (int k = 0; k < 3; ++k) {
        active[k] = maxext > 0 && ext[k] > 1e-6 * maxext;
        if (active[k]) { ++nactive; measure *= ext[k]; }
    }
    double scale = nactive ? pow((double)args->grid_lambda * (double)(n ? n : 1) / measure, 1.0 / nactive) : 0.0;
    uint64_t cells;
    for (;;) {
        uint64_t dims[3];
        for (int k = 0; k < 3; ++k) {
            double d = active[k] ? floor(ext[k] * scale + 0.5) : 1.0;
            if (d < 1) d = 1;
            if (d > AS_GRID_MAX_CELLS) d = AS_GRID_MAX_CELLS;
            dims[k] = (uint64_t)d;
        }
        cells = dims[0] * dims[1] * dims[2];
        if (cells <= AS_GRID_MAX_CELLS) break;
        scale *= pow((double)AS_GRID_MAX_CELLS / (double)cells, 1.0 / (nactive ? nactive : 1)) * 0.999;
    }
    uint64_t refs_max = budget_refs(args->split_budget, n);
    if (refs_max > 0xFFFFFFF0u) refs_max = 0xFFFFFFF0u;
    const uint64_t fixed = sizeof(as_meta_t) + sizeof(as_grid_header_t) + sizeof(uint32_t) * (cells + 1) +
                           sizeof(as_tri4_t) * (uint64_t)nt;
    out->structure_bytes_max = fixed + sizeof(uint32_t) * refs_max;
    /* Typical: about 2.5 references per triangle at the default lambda (the
     * test scenes); an estimate. */
    out->structure_bytes_typical = fixed + sizeof(uint32_t) * (uint64_t)fmin((double)refs_max, 2.5 * (double)n);
    /* The per-cell counters, the (cell, triangle) pairs of pass 1 (8 bytes a
     * reference, lists grown by doubling), the skip flags. */
    out->build_peak_bytes = 4 * cells + 16 * refs_max + nt + out->structure_bytes_max;
    return AS_OK;
}

as_error_t as_structure_estimate(const as_mesh_t *mesh, const as_build_args_t *user_args,
                                 as_memory_estimate_t *out)
{
    if (!mesh || !out) return as_set_error(AS_ERROR_INVALID_ARGUMENT, "as_structure_estimate: NULL argument");
    memset(out, 0, sizeof *out);
    as_build_args_t args;
    as_build_args_default(&args);
    if (user_args) memcpy(&args, user_args, user_args->size < sizeof args ? user_args->size : sizeof args);
    args.size = sizeof args;
    switch (args.structure) {
    case AS_STRUCT_BVH: return estimate_bvh(mesh, args, out);
    case AS_STRUCT_KD: return estimate_kd(mesh, &args, out);
    case AS_STRUCT_BIH: return estimate_bih(mesh, &args, out);
    case AS_STRUCT_OCTREE: return estimate_octree(mesh, &args, out);
    case AS_STRUCT_GRID: return estimate_grid(mesh, &args, out);
    }
    return as_set_error(AS_ERROR_UNSUPPORTED, "as_structure_estimate: no structure kind 0x%04x in this version",
                        (unsigned)args.structure);
}
