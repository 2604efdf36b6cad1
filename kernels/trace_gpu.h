/* The CUDA back end's entry points, callable from C. */
#ifndef AS_TRACE_GPU_H
#define AS_TRACE_GPU_H

#include "as/as.h"

#ifdef __cplusplus
extern "C" {
#endif

/* Number of usable CUDA devices (0 when the driver or device is missing). */
int as_gpu_device_count(void);
/* Creates the CUDA context of the current device; 0 when it cannot. */
int as_gpu_create_context(void);

/* How to launch: filled from as_trace_args_t. */
typedef struct as_gpu_launch {
    int any_hit;
    unsigned timed_runs;         /* >= 1 */
    int persistent;              /* persistent threads, else one thread per ray */
    unsigned batch;              /* persistent: rays per atomic */
    int collect_stats;           /* run the counting kernel too (not timed) */
    int ray_flags;               /* as_ray_prepare flags (AS_RAY_PRECISE) */
    uint32_t *ray_steps;         /* with collect_stats: host array, each ray's steps, or NULL */
} as_gpu_launch_t;

/* A structure's sections on the device (or mapped for it in place). */
#define AS_GPU_MAX_SECTIONS 6
typedef struct as_gpu_resident {
    int section_count;
    void *device[AS_GPU_MAX_SECTIONS];   /* device pointers, in the layout's section order */
    uint64_t bytes[AS_GPU_MAX_SECTIONS];
    const void *registered;              /* the registered host range (zero-copy, registered) */
    as_upload_info_t info;
} as_gpu_resident_t;

/* Makes sections resident: copies them to device memory by `method`
 * (pageable, pinned pipeline, registered), or with zero_copy registers the
 * host range [map_base, map_base + map_size) that holds them and hands the
 * kernels device pointers into it. */
as_error_t as_gpu_upload(const void *const *sections, const uint64_t *bytes, int count, int zero_copy,
                         int method, unsigned pipe_threads, unsigned pipe_chunk_mib, const void *map_base,
                         uint64_t map_size, as_gpu_resident_t **out);
void as_gpu_release(as_gpu_resident_t *g);
/* Free device memory in bytes (0 when unknown). */
uint64_t as_gpu_free_memory(void);

/* What a BVH2 child-bounds structure's sections and META must agree on. */
/* What META says, for every GPU validator (as_gpu_meta_expect fills it). */
typedef struct as_gpu_meta_expect {
    uint32_t mesh_triangles;           /* source triangles */
    float bounds_lo[3], bounds_hi[3];  /* the scene's (root's) box */
    uint64_t node_count, leaf_count, reference_count, empty_leaf_count;
    uint32_t max_depth;
} as_gpu_meta_expect_t;

typedef struct as_gpu_bvh2_expect {
    uint64_t node_count, tri_count;    /* entries of the uploaded BVH2 and TRI4 */
    int clipped_leaves;                /* SBVH: leaf boxes hold clipped parts */
    as_gpu_meta_expect_t meta;
} as_gpu_bvh2_expect_t;

/* Validates uploaded BVH2 child-bounds sections (device[0] nodes, device[1]
 * triangles) on the GPU with the checks of as_bvh2_validate; sets the error
 * naming the node or triangle on failure. */
as_error_t as_gpu_validate_bvh2(const as_gpu_resident_t *g, const char *name, const as_gpu_bvh2_expect_t *expect);
/* The same for BVH2 own-bounds sections (device[0] BVHO, device[1] TRI4),
 * with the checks of as_bvh2_own_validate; node_count is BVHO's records,
 * META's node count the inner nodes among them. */
as_error_t as_gpu_validate_bvh2_own(const as_gpu_resident_t *g, const char *name, const as_gpu_bvh2_expect_t *expect);
/* The same for compressed wide BVH sections (device[0] CWBV, device[1]
 * TRI4), with the checks of as_cwbvh_validate; node_count is CWBV's. */
as_error_t as_gpu_validate_cwbvh(const as_gpu_resident_t *g, const char *name, const as_gpu_bvh2_expect_t *expect);

/* What a KD structure's sections and META must agree on (kd-standard:
 * device[0] KDN8, [1] PRIM, [2] TRIS; kd-ropes also [3] KDRP, [4] KDLB). */
typedef struct as_gpu_kd_expect {
    uint64_t node_count, prim_count, tri_count;
    int ropes;                         /* kd-ropes: check KDRP and KDLB too */
    uint64_t rope_count, leaf_box_count;
    as_gpu_meta_expect_t meta;
} as_gpu_kd_expect_t;

/* Validates uploaded KD sections on the GPU with the checks of
 * as_kd_validate (ropes: as_kd_ropes_validate). */
as_error_t as_gpu_validate_kd(const as_gpu_resident_t *g, const char *name, const as_gpu_kd_expect_t *expect);

/* What a BIH, octree or grid structure's sections and META must agree on. */
typedef struct as_gpu_spatial_expect {
    uint64_t header_count;             /* octree OCTH, grid GRDH records (1) */
    uint64_t node_count;               /* BIH BIHN, octree OCTN; grid: GRDC offsets */
    uint64_t prim_count, tri_count;
    as_gpu_meta_expect_t meta;
} as_gpu_spatial_expect_t;

/* Validate uploaded sections on the GPU with the checks of the CPU
 * validators: BIH (device[0] BIHN, [1] PRIM, [2] TRIS; as_bih_validate),
 * octree ([0] OCTH, [1] OCTN, [2] PRIM, [3] TRIS; as_octree_validate),
 * grid ([0] GRDH, [1] GRDC, [2] PRIM, [3] TRIS; as_grid_validate). */
as_error_t as_gpu_validate_bih(const as_gpu_resident_t *g, const char *name, const as_gpu_spatial_expect_t *expect);
as_error_t as_gpu_validate_octree(const as_gpu_resident_t *g, const char *name, const as_gpu_spatial_expect_t *expect);
as_error_t as_gpu_validate_grid(const as_gpu_resident_t *g, const char *name, const as_gpu_spatial_expect_t *expect);

/* Uploads the rays, runs one warm-up launch and `timed_runs` timed launches
 * of the layout's kernel over its resident sections (in the layout's section
 * order), and copies the hits back. timing->trace_ms is the median of the
 * timed launches (CUDA events around the kernel alone).
 * AS_ERROR_UNSUPPORTED for a layout without a kernel. */
as_error_t as_trace_gpu(uint32_t layout, const as_gpu_resident_t *g, const float bounds_lo[3],
                        const float bounds_hi[3], const as_ray_t *rays, size_t count, as_hit_t *hits,
                        const as_gpu_launch_t *launch, as_trace_timing_t *timing);

#ifdef __cplusplus
}
#endif

#endif
