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
 * xyz); returns 0 to make a leaf. `state` is what the builder keeps beside
 * the node's references (NULL for builders without one). */
typedef int (*kd_choose_fn)(const struct kd_ctx *c, void *state, const kd_ref *refs, uint32_t n, const float box[6],
                            uint32_t depth, kd_split *out);

/* How a parent's references reach its children: two entries per parent
 * reference, map[2 i] for the left child and map[2 i + 1] for the right:
 * KD_REF_ABSENT, or the index in that child's array, with KD_REF_CHANGED
 * when the reference was clipped (its box in the child differs). A child's
 * references keep the parent's order. */
#define KD_REF_ABSENT 0xffffffffu
#define KD_REF_CHANGED 0x80000000u

/* A builder: how it chooses splits, and, when it keeps per-node data (the
 * SAH builder's sorted event lists), how that data is made for the root and
 * handed down to the children. All state functions may be NULL. */
typedef struct kd_builder_ops {
    uint32_t builder;  /* AS_BUILDER_KD_* */
    kd_choose_fn choose;
    /* NULL means out of memory. */
    void *(*root_state)(const struct kd_ctx *c, const kd_ref *refs, uint32_t n);
    /* Fills out[0] (left) and out[1] (right); returns 0 when out of memory
     * (then both are NULL). */
    int (*child_states)(const struct kd_ctx *c, const void *parent, const uint32_t *map, uint32_t parent_n,
                        const kd_ref *const child_refs[2], const uint32_t child_n[2], void *out[2]);
    void (*free_state)(void *state);
} kd_builder_ops;

typedef struct kd_ctx {
    const as_build_args_t *args;
    const as_mesh_t *mesh;
    const kd_builder_ops *ops;
    uint32_t max_depth;
} kd_ctx;

/* Builds the tree with `ops` and fills s (META and the KD-standard
 * sections, then the ropes when args->layout asks for them). */
as_error_t kd_build(const as_mesh_t *mesh, const as_build_args_t *args, const kd_builder_ops *ops, as_structure_t *s);

#endif
