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
#include "task_pool.h"

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
    /* The references each child gets, when the builder knows them (the SAH
     * sweep counts them): counted is 1 and count[] is what the driver's own
     * count would give; 0 leaves the counting to the driver. */
    int counted;
    uint32_t count[2];
} kd_split;

struct kd_ctx;
/* Chooses the split of a node with `n` references inside `box` (lo xyz, hi
 * xyz); returns 0 to make a leaf. `state` is what the builder keeps beside
 * the node's references (NULL for builders without one). */
typedef int (*kd_choose_fn)(const struct kd_ctx *c, void *state, const kd_ref *refs, uint32_t n, const float box[6],
                            uint32_t depth, kd_split *out);

/* How a parent's references reach its children, for builders that hand
 * data down (kd_builder_ops.child_states). A child's references keep the
 * parent's order, which is the order of their triangle indices.
 *
 * side[id], for each triangle id of the parent's references, says which of
 * the parent's events of the reference a child keeps: bit KD_KEEP_BIT(s, a,
 * hi) for child s, axis a, and the event at the box's low (START or PLANAR)
 * or high (END) bound. A reference that reaches a child unchanged keeps all
 * six there (KD_KEEP_SIDE); one the split clipped keeps the events at the
 * bounds that clipping left where they were (on the split axis, the bound
 * away from the plane, mostly). clipped[s][0 .. clipped_n[s]) are the
 * indices, in child s's array and in increasing order, of the references
 * whose box the split clipped: the builder makes the events they do not
 * keep.
 *
 * The arrays belong to the thread building the node (one set per thread, not
 * per node: side has two bytes per triangle of the mesh); `buf` is the
 * builder's own scratch, kd_scratch_reserve grows it. */
#define KD_KEEP_BIT(side, axis, hi) (1u << ((side) * 6 + (axis) * 2 + (hi)))
#define KD_KEEP_SIDE(side) (0x3fu << ((side) * 6))

typedef struct kd_scratch {
    uint16_t *side;
    uint32_t *clipped[2];
    uint32_t clipped_n[2];
    size_t clipped_cap;
    void *buf;
    size_t buf_size;
    struct kd_scratch *next_free;
    struct kd_arena_chunk *arena; /* the driver's: the tree's nodes and leaf lists */
    void *small_refs;             /* the driver's: free arrays for small nodes' references */
    /* The driver's count of the nodes this thread made, summed after the
     * build to size the tree's sections without another walk. */
    uint64_t inner, leaves, empty, refs;
    uint32_t max_depth;
    /* The share of the build this thread's leaves finished and has not yet
     * reported: reported in steps (kd_build.c), not leaf by leaf under the
     * run's lock. */
    double unreported;
    /* The driver's: the right children that the task using this scratch
     * has not started (task_pool.h). */
    as_pending_stack pending;
} kd_scratch;

/* buf with room for `bytes` (its contents are not kept); NULL when out of
 * memory. */
void *kd_scratch_reserve(kd_scratch *s, size_t bytes);

/* A builder: how it chooses splits, and, when it keeps per-node data (the
 * SAH builder's sorted event lists), how that data is made for the root and
 * handed down to the children. All state functions may be NULL. */
typedef struct kd_builder_ops {
    uint32_t builder;  /* AS_BUILDER_KD_* */
    kd_choose_fn choose;
    /* NULL means out of memory. */
    void *(*root_state)(const struct kd_ctx *c, const kd_ref *refs, uint32_t n);
    /* Fills out[0] (left) and out[1] (right) from the parent's data and
     * `how` (above); returns 0 when out of memory (then both are NULL). */
    int (*child_states)(const struct kd_ctx *c, const void *parent, kd_scratch *how, uint32_t parent_n,
                        const kd_ref *const child_refs[2], const uint32_t child_n[2], void *out[2]);
    void (*free_state)(void *state);
} kd_builder_ops;

typedef struct kd_ctx {
    const as_build_args_t *args;
    const as_mesh_t *mesh;
    const kd_builder_ops *ops;
    uint32_t max_depth;
    /* The triangles as the TRIS section holds them: clipping reads a
     * triangle's vertices from one 48-byte entry, not through the index
     * buffer from three places. */
    const as_tri4_t *tris;
    /* The form of the small nodes' chooser: KD_CHOOSE_SMALL (the fastest
     * the processor has), or KD_CHOOSE_SMALL_SSE2 or _PLAIN, which
     * kd_sah_choose_plane's tests hold to the same planes. */
    int small_form;
} kd_ctx;

/* The box of a reference after clipping (kd_build.c): `old`'s box within
 * `box`, narrowed to [dlo, dhi], the bounds of the clipped triangle, rounded
 * out to floats; dlo NULL when clipping left nothing. The SSE2 form is the
 * one that runs where the compiler targets SSE2 (every x86-64), the plain
 * one elsewhere; they give the same bits (test_kd holds them to it). */
void kd_clipped_ref_plain(const kd_ref *old, const float box[6], const double *dlo, const double *dhi, kd_ref *out);
#if defined(__SSE2__)
void kd_clipped_ref_sse2(const kd_ref *old, const float box[6], const double *dlo, const double *dhi, kd_ref *out);
#endif

/* A node's references as its partition makes them: triangle old->id of
 * `tris` clipped to `box` and intersected with old's box; and both
 * children's of a split of `node_box` at `pos` on `axis`, from one clip.
 * The boxes hold the exact clipped triangle: its bounds are computed in
 * double precision and rounded outwards. Where clipping leaves nothing (a
 * triangle touching the box, or missing it by rounding), the box is old's
 * within `box`: a reference is never dropped. */
void kd_clip_reference(const as_tri4_t *tris, const kd_ref *old, const float box[6], kd_ref *out);
void kd_clip_reference_split(const as_tri4_t *tris, const kd_ref *old, const float node_box[6], int axis, float pos,
                             kd_ref out[2]);
/* Both run in the fastest form this processor has (with AVX2 where it has
 * it); the portable forms (SSE2, or plain without it) give the same bits,
 * which test_kd holds them to. */
void kd_clip_reference_portable(const as_tri4_t *tris, const kd_ref *old, const float box[6], kd_ref *out);
void kd_clip_reference_split_portable(const as_tri4_t *tris, const kd_ref *old, const float node_box[6], int axis,
                                      float pos, kd_ref out[2]);

/* The SAH builder's plane for a node of n references (in increasing id
 * order) inside box: chosen by sweeping the node's sorted event lists
 * (KD_CHOOSE_SWEEP), or as a small node chooses it, from the references
 * themselves (n at most 64): in the form the build uses on this processor
 * (KD_CHOOSE_SMALL: AVX2 where it has it), in the SSE2 form
 * (KD_CHOOSE_SMALL_SSE2) or in the plain one (KD_CHOOSE_SMALL_PLAIN, the
 * form without vector units). Returns 1 with the plane, 0 when the node is
 * better a leaf, -1 when it cannot choose (out of memory, or too many
 * references for a small node). Every way gives the same plane. */
enum { KD_CHOOSE_SMALL = 0, KD_CHOOSE_SWEEP = 1, KD_CHOOSE_SMALL_SSE2 = 2, KD_CHOOSE_SMALL_PLAIN = 3 };
int kd_sah_choose_plane(const as_build_args_t *args, const kd_ref *refs, uint32_t n, const float box[6], int how,
                        kd_split *out);

/* Builds the tree with `ops` and fills s (META and the KD-standard
 * sections, then the ropes when args->layout asks for them). */
as_error_t kd_build(const as_mesh_t *mesh, const as_build_args_t *args, const kd_builder_ops *ops, as_structure_t *s);

#endif
