/* KD builder, spatial median ("mid-cut"): every node is halved across the
 * longest axis of its own box. The longest axis (rather than round-robin)
 * keeps the cells close to cubes whatever the scene's proportions, which is
 * what makes a spatial median useful on long, flat scenes (a staircase, a
 * street); round-robin would keep cutting a thin axis into slivers. Leaves
 * hold at most max_leaf_size references, unless the depth cap, the
 * no-progress rule or the split budget (kd_build.c) stop first. */
#include "kd_build.h"

static int midcut_choose(const kd_ctx *c, void *state, const kd_ref *refs, uint32_t n, const float box[6],
                         uint32_t depth, kd_split *out)
{
    (void)state;
    (void)refs;
    (void)depth;
    if (n <= c->args->max_leaf_size) return 0;
    int axis = 0;
    for (int a = 1; a < 3; ++a)
        if (box[a + 3] - box[a] > box[axis + 3] - box[axis]) axis = a;
    const float lo = box[axis], hi = box[axis + 3];
    const float pos = lo + 0.5f * (hi - lo);
    if (!(pos > lo && pos < hi)) return 0; /* the box is too thin to halve in float */
    out->axis = axis;
    out->pos = pos;
    out->planar_left = 1;
    out->counted = 0;
    return 1;
}

as_error_t as_kd_build_midcut(const as_mesh_t *mesh, const as_build_args_t *args, as_structure_t *s)
{
    static const kd_builder_ops ops = {AS_BUILDER_KD_MIDCUT, midcut_choose, NULL, NULL, NULL};
    return kd_build(mesh, args, &ops, s);
}
