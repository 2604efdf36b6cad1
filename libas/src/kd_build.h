/* What the two KD builders share (kd_build.c): the recursive driver with its
 * termination rules, perfect splits by clipping, deterministic threading,
 * progress and cancellation, and the writing of the KD-standard sections.
 * A builder only chooses the split of a node (kd_build_midcut.c,
 * kd_build_sah.c). */
#ifndef AS_KD_BUILD_H
#define AS_KD_BUILD_H

#include "structure.h"
#include "mesh.h"
#include "kd_layout.h"

/* A triangle's reference in a node: its source index and the box of the part
 * of it inside the node (clipped, rounded outwards, inside the node box). */
typedef struct kd_ref {
    float lo[3], hi[3];
    uint32_t id;
} kd_ref;

typedef struct kd_split {
    int axis;          /* 0..2 */
    float pos;         /* strictly inside the node box */
    int planar_left;   /* triangles lying in the plane go below (1) or above (0) */
} kd_split;

struct kd_ctx;
/* Chooses the split of a node with `n` references inside `box` (lo xyz, hi
 * xyz); returns 0 to make a leaf. May reorder refs. */
typedef int (*kd_choose_fn)(const struct kd_ctx *c, kd_ref *refs, uint32_t n, const float box[6], uint32_t depth,
                            kd_split *out);

typedef struct kd_ctx {
    const as_build_args_t *args;
    const as_mesh_t *mesh;
    kd_choose_fn choose;
    uint32_t max_depth;
    uint32_t builder;
} kd_ctx;

/* Builds the tree with `choose` and fills s (META and the KD-standard
 * sections, then the ropes when args->layout asks for them). */
as_error_t kd_build(const as_mesh_t *mesh, const as_build_args_t *args, uint32_t builder, kd_choose_fn choose,
                    as_structure_t *s);

#endif
