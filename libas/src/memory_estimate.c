/* Memory of a build before it runs: an upper bound of the structure's bytes
 * and an estimate of the builder's working memory, from the mesh's counts
 * and the build arguments alone, for the BVH family.
 *
 * The bounds follow the builders' code (bvh_build_common.c and the four
 * builders): zero-area triangles are left out, so N = triangles minus
 * degenerate ones; every builder but the SBVH holds each triangle once
 * (TRI4 = N entries), the SBVH at most split_budget x N (its reference
 * budget); a binary tree whose leaves hold at least one reference has at
 * most references - 1 inner nodes, and a one-leaf tree still has its root
 * (the empty sibling); the own-bounds layout stores 1 + 2 x inner nodes. */
#include "structure.h"
#include "bvh_build_common.h"
#include "bvh2_own_layout.h"

#include <math.h>
#include <string.h>

/* Nodes of a binary tree over `refs` references, at most. */
static uint64_t inner_nodes_max(uint64_t refs) { return refs > 2 ? refs - 1 : 1; }

as_error_t as_structure_estimate(const as_mesh_t *mesh, const as_build_args_t *user_args,
                                 as_memory_estimate_t *out)
{
    if (!mesh || !out) return as_set_error(AS_ERROR_INVALID_ARGUMENT, "as_structure_estimate: NULL argument");
    memset(out, 0, sizeof *out);
    as_build_args_t args;
    as_build_args_default(&args);
    if (user_args) memcpy(&args, user_args, user_args->size < sizeof args ? user_args->size : sizeof args);
    args.size = sizeof args;
    if (args.structure != AS_STRUCT_BVH)
        return as_set_error(AS_ERROR_UNSUPPORTED, "as_structure_estimate: memory bounds are derived for the BVH family "
                            "only; %s has none in this version",
                            as_structure_kind_name(args.structure) ? as_structure_kind_name(args.structure) : "this kind");
    const as_builder_t builder = args.builder == AS_BUILDER_DEFAULT ? AS_BUILDER_BVH_SAH_BINNED : args.builder;
    const as_layout_t layout = args.layout == AS_LAYOUT_DEFAULT ? AS_LAYOUT_BVH2_CHILD_BOUNDS : args.layout;
    if (layout != AS_LAYOUT_BVH2_CHILD_BOUNDS && layout != AS_LAYOUT_BVH2_OWN_BOUNDS)
        return as_set_error(AS_ERROR_UNSUPPORTED, "layout 0x%04x is not a BVH layout", (unsigned)layout);
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
    const uint64_t node_bytes = layout == AS_LAYOUT_BVH2_CHILD_BOUNDS ? sizeof(as_bvh2_node_t) * inner_max
                                                                      : sizeof(as_bvh2o_node_t) * (1 + 2 * inner_max);
    out->structure_bytes_max = sizeof(as_meta_t) + node_bytes + sizeof(as_tri4_t) * refs_max;

    /* Typical: leaves half full on average, a quarter more references for
     * an SBVH at the default budget (what the bunny and the study's scenes
     * show); an estimate, not a bound. */
    const uint64_t refs_typ = sbvh ? (uint64_t)fmin((double)refs_max, 1.25 * (double)n) : n;
    const double leaf_fill = args.max_leaf_size > 1 ? 0.5 * (args.max_leaf_size + 1) : 1.0;
    const uint64_t leaves_typ = (uint64_t)ceil((double)refs_typ / leaf_fill);
    const uint64_t inner_typ = inner_nodes_max(leaves_typ + 1);
    out->structure_bytes_typical =
        sizeof(as_meta_t) + sizeof(as_tri4_t) * refs_typ +
        (layout == AS_LAYOUT_BVH2_CHILD_BOUNDS ? sizeof(as_bvh2_node_t) * inner_typ
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
    out->build_peak_bytes = peak;
    return AS_OK;
}
