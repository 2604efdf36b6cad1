/*
 * libas: acceleration structures for ray tracing.
 *
 * The whole public C API. Conventions, as in Embree's rtcore.h and zstd.h:
 *  - opaque handles; functions that create one return NULL on failure and set
 *    the per-thread last error; release functions accept NULL;
 *  - argument structs start with a `size` field and have a function that
 *    fills in the defaults, so they can grow without breaking callers; NULL
 *    for an argument struct means "defaults";
 *  - every function that can fail either returns an as_error_t or returns
 *    NULL/0 and sets the last error, which as_get_error() and
 *    as_get_error_message() read on the same thread.
 * All functions are thread-safe unless their comment says otherwise; a
 * handle may be read from several threads at once but not released while in
 * use.
 * Builds and CPU work run on threads the library keeps from one call to the
 * next (at most twice the cores, 32 at least, wait between calls); they
 * block every signal, and they leave when the library is unloaded. A child
 * of fork() starts threads of its own, and the build memory it inherits is
 * consistent even when another thread was building at the fork.
 */
#ifndef AS_AS_H
#define AS_AS_H

#include <stdbool.h>
#include <stddef.h>
#include <stdint.h>

#include "as/as_version.h"

#ifdef __cplusplus
extern "C" {
#endif

/* ------------------------------------------------------------------------ */
/* Version                                                                  */

/* The version of the library that is running, as
 * MAJOR * 10000 + MINOR * 100 + PATCH (compare with AS_VERSION_NUMBER, the
 * version the caller was compiled against). */
unsigned as_version_number(void);
/* The same as "MAJOR.MINOR.PATCH"; a static string. */
const char *as_version_string(void);

/* ------------------------------------------------------------------------ */
/* Errors                                                                   */

/* Error codes. Values below AS_ERROR_MAX_STABLE are pinned: they never change
 * meaning between versions. */
typedef enum as_error {
    AS_OK = 0,
    AS_ERROR_UNKNOWN = 1,
    AS_ERROR_INVALID_ARGUMENT = 2, /* a caller passed a bad argument */
    AS_ERROR_OUT_OF_MEMORY = 3,
    AS_ERROR_CANCELLED = 4,        /* a progress callback returned false */
    AS_ERROR_IO = 10,              /* open, read, write, map or rename failed */
    AS_ERROR_FILE_NOT_FOUND = 11,
    AS_ERROR_PARSE = 20,           /* the input file cannot be parsed */
    AS_ERROR_INVALID_MESH = 21,    /* NaN/Inf coordinates, bad indices, empty */
    AS_ERROR_CORRUPT = 22,         /* a container or record file is damaged */
    AS_ERROR_CHECKSUM = 23,        /* a section's checksum does not match */
    AS_ERROR_INVALID_STRUCTURE = 24, /* structure validation failed */
    AS_ERROR_VERSION = 30,         /* a newer major version than this build reads */
    AS_ERROR_UNSUPPORTED = 31,     /* unknown required section, kind or layout */
    AS_ERROR_NO_DEVICE = 40,       /* a GPU was asked for and none is usable */
    AS_ERROR_DEVICE = 41,          /* the CUDA runtime reported an error */
    AS_ERROR_MAX_STABLE = 100
} as_error_t;

/* The enumerator's name without its prefix ("CORRUPT"); "UNKNOWN_CODE" for a
 * value that is not a code. Static string. */
const char *as_error_name(as_error_t code);

/* The last error set on this thread by a libas function, and its message
 * (the context: file, section, offset, line, primitive). The message is
 * "" when the code is AS_OK. It stays valid until the next libas call on this
 * thread. Errors are sticky: successful calls do not clear them. */
as_error_t as_get_error(void);
const char *as_get_error_message(void);
void as_clear_error(void);

/* The exit code the libas tools use for an error (0 ok, 1 usage, 2 I/O,
 * 3 invalid input file, 4 runtime or library error, 5 unsupported). */
int as_error_exit_code(as_error_t code);

/* ------------------------------------------------------------------------ */
/* Meshes                                                                   */

typedef struct as_mesh as_mesh_t;

/* Reads a triangle mesh: OBJ, PLY, OFF, STL (through OpenMesh's parsers) or
 * Draco .drc, chosen by the extension; NAME.EXT.zst is decompressed first.
 * Every face of the file is kept in file order: a face with k > 3 corners
 * becomes k - 2 consecutive triangles (a fan), zero-area triangles are kept
 * (they are never hit) and counted. Normals, UVs and material ids are kept
 * only when the file has them. Fails with FILE_NOT_FOUND, IO, PARSE or
 * INVALID_MESH and a message naming the file. */
as_mesh_t *as_mesh_import(const char *path);

/* Makes a mesh from caller arrays (copied): positions are 3 floats per vertex,
 * indices 3 per triangle. Validated like an imported mesh. */
as_mesh_t *as_mesh_create(uint32_t vertex_count, const float *positions,
                          uint32_t triangle_count, const uint32_t *indices);

void as_mesh_release(as_mesh_t *mesh);

typedef struct as_mesh_info {
    uint32_t vertex_count;
    uint32_t triangle_count;
    uint64_t faces_in_file;      /* faces the file lists (before fans) */
    uint32_t polygon_faces;      /* faces with more than 3 corners */
    uint32_t degenerate_count;   /* zero-area triangles kept, never hit */
    bool has_normals, has_uvs, has_materials;
    float bounds_lo[3], bounds_hi[3];
    uint64_t hash;               /* XXH3-64 of positions then indices */
} as_mesh_info_t;

/* Fills `info` with the mesh's counts, bounds and hash; a NULL mesh gives
 * all zeros. */
void as_mesh_get_info(const as_mesh_t *mesh, as_mesh_info_t *info);
/* Arrays owned by the mesh; NULL where the file had none. */
const float *as_mesh_positions(const as_mesh_t *mesh);    /* 3 per vertex */
const uint32_t *as_mesh_indices(const as_mesh_t *mesh);   /* 3 per triangle */
const float *as_mesh_normals(const as_mesh_t *mesh);      /* 3 per vertex */
const float *as_mesh_uvs(const as_mesh_t *mesh);          /* 2 per vertex */
const uint32_t *as_mesh_material_ids(const as_mesh_t *mesh); /* 1 per triangle */

/* ------------------------------------------------------------------------ */
/* Structures                                                               */

/* On-disk enums: sparse values by family, never renumbered. */
typedef enum as_structure_kind {
    AS_STRUCT_BVH = 0x0100,
    AS_STRUCT_KD = 0x0200,
    AS_STRUCT_BIH = 0x0300,
    AS_STRUCT_OCTREE = 0x0400,
    AS_STRUCT_GRID = 0x0500
} as_structure_kind_t;

typedef enum as_layout {
    AS_LAYOUT_DEFAULT = 0,          /* build args: the structure's first layout */
    /* Binary BVH whose 64-byte nodes hold both children's boxes (Aila &
     * Laine 2009), triangles as 3 x float4 in leaf order. */
    AS_LAYOUT_BVH2_CHILD_BOUNDS = 0x0101,
    /* The classic binary BVH: every node stores its own box. */
    AS_LAYOUT_BVH2_OWN_BOUNDS = 0x0102,
    /* The compressed wide BVH (Ylitie, Karras & Laine 2017): 8-wide nodes
     * of 80 bytes with child boxes quantized to 8 bits, collapsed from a
     * binary tree; triangles as in the child-bounds layout. */
    AS_LAYOUT_BVH_CWBVH = 0x0103,
    /* KD tree, 8-byte nodes, traversed with a stack of node and tmax. */
    AS_LAYOUT_KD_STANDARD = 0x0201,
    /* The same tree plus six ropes and a box per leaf, traversed stacklessly. */
    AS_LAYOUT_KD_ROPES = 0x0202,
    AS_LAYOUT_BIH = 0x0301,
    AS_LAYOUT_OCTREE = 0x0401,
    AS_LAYOUT_GRID = 0x0501
} as_layout_t;

typedef enum as_builder {
    AS_BUILDER_DEFAULT = 0,         /* build args: the structure's usual builder */
    AS_BUILDER_BVH_SAH_BINNED = 0x0101,
    AS_BUILDER_BVH_SAH_SWEEP = 0x0102,
    AS_BUILDER_BVH_MIDCUT = 0x0103, /* object median on the longest axis */
    AS_BUILDER_BVH_SBVH = 0x0104,   /* spatial splits (Stich et al. 2009) */
    AS_BUILDER_KD_MIDCUT = 0x0201,  /* spatial median */
    AS_BUILDER_KD_SAH = 0x0202,     /* O(N log N) SAH (Wald & Havran 2006) */
    AS_BUILDER_BIH = 0x0301,        /* Wachter & Keller 2006 */
    AS_BUILDER_OCTREE = 0x0401,
    AS_BUILDER_GRID = 0x0501
} as_builder_t;

/* Names used on command lines and in reports ("bvh", "kd-ropes", "sbvh");
 * NULL or 0 for an unknown value or name. */
const char *as_structure_kind_name(as_structure_kind_t kind);
const char *as_layout_name(as_layout_t layout);
const char *as_builder_name(as_builder_t builder);
as_structure_kind_t as_structure_kind_from_name(const char *name);
as_layout_t as_layout_from_name(const char *name);
/* A builder of the given kind by its short name ("sah", "midcut", "sbvh",
 * "sweep"); 0 when the kind has no such builder. */
as_builder_t as_builder_from_name(as_structure_kind_t kind, const char *name);

typedef bool (*as_progress_fn)(void *user, double fraction);

typedef struct as_build_args {
    size_t size;                 /* sizeof(as_build_args_t) */
    as_structure_kind_t structure;
    as_builder_t builder;
    uint32_t max_leaf_size;      /* leaves hold at most this many triangles
                                    unless the depth cap forces more */
    uint32_t bin_count;          /* SAH bins per axis (binned builder; nodes of
                                    over 1024 triangles use twice as many,
                                    at most 256) */
    float cost_traversal;        /* SAH cost of one node visit */
    float cost_intersection;     /* SAH cost of one triangle test */
    uint32_t thread_count;       /* 0: every core */
    as_progress_fn progress;     /* may be NULL; false cancels the build */
    void *progress_user;
    as_layout_t layout;          /* AS_LAYOUT_DEFAULT or one of the kind's layouts */
    uint32_t max_depth;          /* 0: the structure's default (never deeper
                                    than its traversal stack) */
    float grid_lambda;           /* grid: cells per triangle (default 4) */
    float split_budget;          /* SBVH/KD: references at most this times
                                    the triangle count (default 4) */
    float sbvh_alpha;            /* SBVH: try spatial splits when the child
                                    boxes overlap by more than this fraction
                                    of the root's area (default 1e-5); in
                                    nodes of 1024 references or fewer also
                                    by a tenth of the node's own area, and
                                    never in nodes of 4 or fewer */
} as_build_args_t;

void as_build_args_default(as_build_args_t *args);

typedef struct as_structure as_structure_t;

/* Builds a structure over a mesh. The result does not refer to the mesh. The
 * same mesh and arguments give byte-identical sections whatever the thread
 * count. */
as_structure_t *as_structure_build(const as_mesh_t *mesh, const as_build_args_t *args);

/* What a build will take, known before it runs. */
typedef struct as_memory_estimate {
    uint64_t structure_bytes_max;      /* upper bound of the built structure's bytes (META
                                          and every section, raw): what
                                          as_structure_stats_t.structure_bytes will say */
    uint64_t structure_bytes_typical;  /* what such meshes usually give; an estimate
                                          (for KD, BIH, octree and grid, per-kind
                                          factors measured on the bunny and random
                                          soups), not a bound */
    uint64_t build_peak_bytes;         /* the builder's working memory at its peak, the
                                          result included, the mesh not: an estimate
                                          from the builder's allocations, not a bound */
} as_memory_estimate_t;

/* The memory a build of `mesh` with `args` (NULL: defaults) will need, from
 * the mesh's counts and the arguments alone (for the grid also the scene
 * box), without building, for every kind, builder and layout. How close
 * structure_bytes_max is, from the builders' rules (N: non-degenerate
 * triangles; the TRIS section, 48 bytes per triangle, is exact everywhere):
 *  - BVH: every builder but the SBVH holds N references, at most N - 1
 *    inner nodes (the bunny: 1.4x to 1.7x); the SBVH up to split_budget x N
 *    (5.4x on the bunny at the default budget of 4).
 *  - Grid: the cells are the builder's resolution formula (the build only
 *    lowers it), PRIM at most split_budget x N: 1.07x on the bunny, up to
 *    1.3x on soups, the slack being the budget's unused references.
 *  - BIH: each triangle once, at most N - 1 inner nodes: about 1.3x.
 *  - KD (both builders, both layouts) and octree: references at most
 *    split_budget x N (each subtree keeps to its share), but inner nodes are
 *    bounded only level by level up to the depth cap (the KD cap 8 + 1.3
 *    log2 N unless max_depth says, the octree's 12): each level holds at most
 *    split_budget x N / (fewest references a node splits with) of them, the
 *    SAH KD tree splitting down to one reference and a split may leave one
 *    side empty, so empty leaves are limited only by that cap. On the bunny
 *    3.5x (mid-cut) and 7.6x (SAH), 6.5x and 18x with ropes (48 bytes per
 *    leaf), 5.3x for the octree; up to 24x on flat scenes.
 * build_peak_bytes is an estimate from the builders' allocations. Fails with
 * INVALID_ARGUMENT for a NULL argument or arguments the builder would
 * refuse (split budget, leaf size, grid lambda), UNSUPPORTED for a builder
 * or layout of another kind. */
as_error_t as_structure_estimate(const as_mesh_t *mesh, const as_build_args_t *args, as_memory_estimate_t *out);

typedef struct as_save_args {
    size_t size;
    int compression_level;       /* 0: store raw; 1..22: zstd level */
    bool omit_build_record;      /* leave out the BREC section (build time), so that
                                    two builds of one mesh give byte-identical files */
} as_save_args_t;
void as_save_args_default(as_save_args_t *args);

/* Writes the structure to an .asf file: to a temporary file beside it, then
 * renamed over the target, so a failure never leaves half a file. */
as_error_t as_structure_save(const as_structure_t *s, const char *path,
                             const as_save_args_t *args);

typedef struct as_load_args {
    size_t size;
    bool verify_checksums;       /* default true */
} as_load_args_t;
void as_load_args_default(as_load_args_t *args);

/* Maps an .asf file (uncompressed sections are used in place; compressed ones
 * are decompressed). Checks every offset and size against the file, refuses
 * newer major versions, unknown required sections and structures this build
 * cannot trace, and verifies checksums. */
as_structure_t *as_structure_load(const char *path, const as_load_args_t *args);
/* The same from memory, with the same checks; `name` is used in messages.
 * This is also the way to load from a mapped region (mmap of a file, shared
 * memory): uncompressed sections are read in place, without a copy,
 * wherever they lie on a 64-byte boundary in `data` (all of them when
 * `data` is 64-byte aligned, as a mapping, which starts on a page, is), so
 * the structure keeps pointers into `data`, and the caller must keep those
 * bytes alive and unchanged until as_structure_release. Compressed sections
 * are decompressed into memory the structure owns, and a section that is
 * not 64-byte aligned in `data` is copied there. */
as_structure_t *as_structure_load_memory(const void *data, size_t size, const char *name,
                                         const as_load_args_t *args);

/* Releases the structure. Its large arrays (1 MB and more) that a build
 * made go back to a cache of the process, with those that builds used for
 * their work, so that the next build does not fault in fresh pages: at most
 * 16 blocks and 512 MB as the builds asked for them, the oldest freed first
 * when more come. A block is reused for a request of half its size or more
 * and counted at the request's size, so the cache may hold up to twice that
 * (about 1 GB). Beside it, the temporary arrays that a build frees and asks
 * for again many times (the KD SAH builder's event lists and reference
 * arrays) are kept by power-of-two size class, up to 256 MB of blocks, for
 * the rest of the build and the next builds. */
void as_structure_release(as_structure_t *s);

/* Frees every block of those caches now and returns the bytes they counted
 * (as above: what the builds asked for, the blocks may be up to twice as
 * large; the temporaries at their classes' sizes); 0 when both were empty. Blocks go back with free(), so malloc
 * decides when the system gets them (at once for those it mapped).
 * Thread-safe: a build running meanwhile keeps what it took and gives it
 * back to the cache when it ends. */
size_t as_release_cached_memory(void);

/* A new structure with the same tree in another layout of its kind: the
 * BVH's child-bounds and own-bounds layouts either way, either of them into
 * the compressed wide BVH (collapsed, leaves of up to 3 triangles; there is
 * no way back), a KD tree with or without ropes. Fails with AS_ERROR_UNSUPPORTED for any other pair. The
 * source is validated first. */
as_structure_t *as_structure_convert(const as_structure_t *s, as_layout_t layout);

/* Checks the structure itself: indices in range, each node referenced once,
 * children inside their parent's box, depth within the traversal stack,
 * finite floats. Returns AS_ERROR_INVALID_STRUCTURE with a message naming
 * the node on failure. */
as_error_t as_structure_validate(const as_structure_t *s);

/* What as_structure_validate_recorded did. */
typedef struct as_validation_info {
    bool skipped;                /* the record listed the fingerprint: no walk */
    double fingerprint_ms;       /* hashing the sections (0 without a record) */
    double validate_ms;          /* the walk (0 when skipped) */
    uint8_t fingerprint[16];     /* as as_structure_fingerprint gives it */
} as_validation_info_t;

/* The structure's content as a 128-bit XXH3 fingerprint: META and every
 * section's tag, size and bytes (not the build record), hashed on every
 * core in fixed pieces, so equal bytes give equal fingerprints on any
 * machine and thread count. XXH3 finds accidental changes, not forged ones:
 * see docs/SECURITY.md. */
as_error_t as_structure_fingerprint(const as_structure_t *s, uint8_t fingerprint[16]);

/* Validates the structure once for all later walks in this process. With a
 * `record` (a text file of fingerprints, one per line in hex; missing means
 * empty), a structure whose fingerprint it lists is taken as valid without
 * the walk, and one that passes the walk is added to it (written
 * atomically). Only for records and files from a trusted source: whoever
 * can write either can make the walk be skipped. `record` may be NULL (then
 * this is as_structure_validate, remembered); `info` may be NULL. */
as_error_t as_structure_validate_recorded(const as_structure_t *s, const char *record, as_validation_info_t *info);

#define AS_HISTOGRAM_BINS 65

typedef struct as_structure_stats {
    as_structure_kind_t structure;
    as_layout_t layout;
    uint32_t layout_version;
    as_builder_t builder;
    uint32_t max_leaf_size, bin_count;
    float cost_traversal, cost_intersection;
    uint32_t triangle_count;
    uint64_t node_count;          /* inner nodes */
    uint64_t leaf_count;          /* leaves (grid: cells) holding triangles */
    uint64_t empty_leaf_count;    /* leaves (grid: cells) holding none */
    uint64_t reference_count;     /* triangle references in all leaves */
    double average_leaf_size;     /* references per non-empty leaf */
    uint32_t grid_dims[3];        /* grid: cells per axis; else 0 */
    uint32_t max_depth;           /* root = depth 0 */
    double average_leaf_depth;
    double sah_cost;              /* expected cost per ray, SAH with the costs above */
    uint64_t structure_bytes;     /* raw bytes of every section */
    double build_ms;              /* as recorded by the build (BREC); 0 when not recorded */
    uint32_t build_threads;       /* build threads, as recorded; 0 when not recorded */
    uint32_t build_cores;         /* cores of the building machine, as recorded */
    uint64_t source_hash;
    float bounds_lo[3], bounds_hi[3];
    uint64_t depth_histogram[AS_HISTOGRAM_BINS];      /* leaves per depth (last bin: deeper) */
    uint64_t leaf_size_histogram[AS_HISTOGRAM_BINS];  /* leaves per size (last bin: larger) */
    char writer[32];
    uint32_t writer_version;
} as_structure_stats_t;

/* The figures as-inspect prints: counts, depths, histograms, SAH cost,
 * memory and the build record. Validates the structure first (the walk
 * follows its child indices), so a damaged one gives
 * AS_ERROR_INVALID_STRUCTURE and no figures. */
as_error_t as_structure_get_stats(const as_structure_t *s, as_structure_stats_t *stats);

/* Only what META and the build record say: kind, layout, builder and its
 * parameters, triangle count, bounds, source hash, bytes, the build record
 * and META's counts. No walk, so no validation and no time in proportion to
 * the tree; the walked figures (depths, histograms, SAH cost, leaf counts)
 * stay zero. What a tracer needs before its first launch. */
as_error_t as_structure_get_header_stats(const as_structure_t *s, as_structure_stats_t *stats);

/* Sections of the structure (for inspection). */
typedef struct as_section_info {
    char tag[5];                 /* four characters and a NUL */
    bool required;
    bool compressed;             /* zstd in the file */
    int checksum_status;         /* 1 verified, 0 not checked, -1 mismatch */
    uint64_t offset;             /* in the file; 0 for a built structure */
    uint64_t stored_bytes, raw_bytes, element_count;
    uint32_t stride;
    uint64_t checksum;           /* XXH3-64 of the raw bytes */
    const char *purpose;         /* what the section is for; static string */
} as_section_info_t;

/* How many sections the structure has (0 for NULL): its file's when it was
 * loaded, else META and the built sections. */
uint32_t as_structure_section_count(const as_structure_t *s);
/* Section `index` (0 <= index < as_structure_section_count) in file order;
 * AS_ERROR_INVALID_ARGUMENT when out of range. */
as_error_t as_structure_section_info(const as_structure_t *s, uint32_t index,
                                     as_section_info_t *info);

/* ------------------------------------------------------------------------ */
/* Rays, hits and tracing                                                   */

/* 32 bytes, the record of a ray file. A ray covers t in [tmin, tmax]. */
typedef struct as_ray {
    float org[3];
    float tmin;
    float dir[3];
    float tmax;
} as_ray_t;

#define AS_NO_HIT 0xFFFFFFFFu

/* 16 bytes, the record of a hit file. On a miss t is +infinity and prim is
 * AS_NO_HIT. prim is the triangle's index in the source mesh; the hit point is
 * (1 - u - v) v0 + u v1 + v v2. */
typedef struct as_hit {
    float t;
    uint32_t prim;
    float u, v;
} as_hit_t;

typedef enum as_device {
    AS_DEVICE_AUTO = 0,          /* the GPU when one is usable, else the CPU */
    AS_DEVICE_CPU = 1,
    AS_DEVICE_GPU = 2
} as_device_t;

typedef enum as_schedule {
    AS_SCHEDULE_AUTO = 0,        /* the fastest measured on the H100: one thread per ray
                                    (docs/results/2026-11-22-workloads-sanmiguel-h100.md) */
    AS_SCHEDULE_THREAD_PER_RAY = 1,
    AS_SCHEDULE_PERSISTENT = 2   /* persistent threads fetching a batch of rays per atomic */
} as_schedule_t;

typedef enum as_residency {
    AS_RESIDENCY_AUTO = 0,       /* device memory when the structure fits, else zero-copy */
    AS_RESIDENCY_DEVICE = 1,     /* copy the sections to device memory */
    AS_RESIDENCY_ZERO_COPY = 2   /* kernels read the mapped file in place (registered host memory) */
} as_residency_t;

typedef enum as_upload_method {
    AS_UPLOAD_AUTO = 0,          /* the fastest measured: the pinned pipeline on the H100 */
    AS_UPLOAD_PAGEABLE = 1,      /* cudaMemcpy straight from the mapping */
    AS_UPLOAD_PINNED_PIPELINE = 2, /* eight threads copy the sections into pinned
                                    buffers (two each), uploaded asynchronously
                                    on a stream per thread */
    AS_UPLOAD_REGISTERED = 3     /* cudaHostRegister the mapping, then copy */
} as_upload_method_t;

typedef enum as_intersector {
    AS_INTERSECTOR_WATERTIGHT = 0,        /* Woop et al. 2013 in float, explicitly rounded */
    AS_INTERSECTOR_WATERTIGHT_DOUBLE = 1, /* the default: the same test in double, also exact
                                             where float cancels (huge or tiny triangles for their
                                             distance); decides as the verification reference does */
    AS_INTERSECTOR_MOLLER_TRUMBORE = 2    /* Moller & Trumbore 1997 in float, for comparison:
                                             not watertight (rays slip through shared edges) */
} as_intersector_t;

typedef struct as_trace_args {
    size_t size;
    as_device_t device;
    uint32_t thread_count;       /* CPU: 0 = every core */
    bool any_hit;                /* stop at the first hit (shadow rays) */
    uint32_t timed_runs;         /* GPU: launches to time, median reported; default 5 */
    as_schedule_t schedule;      /* GPU */
    uint32_t batch;              /* GPU persistent threads: rays per atomic (default 32) */
    bool collect_stats;          /* also count steps and triangle tests per ray, in a
                                    separate pass (GPU: a separately compiled kernel)
                                    so the timed pass does not pay for counting */
    as_intersector_t intersector; /* default AS_INTERSECTOR_WATERTIGHT_DOUBLE */
    as_residency_t residency;    /* GPU: where the structure lives (first GPU trace) */
    as_upload_method_t upload;   /* GPU: how sections reach device memory */
    uint64_t device_memory_limit; /* GPU: bytes the structure may take in device
                                    memory (0: the device's free memory); beyond
                                    it AS_RESIDENCY_AUTO reads in place */
    uint32_t *ray_steps;         /* with collect_stats, when not NULL: `count` entries
                                    the counting pass fills with each ray's steps
                                    (nodes visited, leaves included), on either
                                    device; the caller owns the array */
    uint32_t upload_threads;     /* GPU pinned pipeline: copying threads (0: the
                                    measured default) */
    uint32_t upload_chunk_mib;   /* GPU pinned pipeline: MiB per pinned buffer, two
                                    per thread (0: the measured default) */
} as_trace_args_t;
void as_trace_args_default(as_trace_args_t *args);

typedef struct as_trace_timing {
    as_device_t device;          /* where it ran */
    double trace_ms;             /* the trace alone: median of the timed launches
                                    on the GPU (device events), wall clock on the CPU */
    double upload_ms;            /* GPU: structure and rays to the device */
    uint64_t upload_bytes;
    char device_name[128];
    uint32_t timed_runs;         /* launches behind trace_ms */
    double trace_ms_min, trace_ms_max;
    /* With collect_stats: traversal steps (nodes visited, leaves included)
     * and ray/triangle tests per ray. */
    bool have_stats;
    double steps_avg, tests_avg;
    uint32_t steps_max, tests_max;
} as_trace_timing_t;

/* What the first GPU use of a structure cost. */
typedef struct as_upload_info {
    bool zero_copy;              /* kernels read the mapped file in place */
    const char *method;          /* "pageable", "pinned pipeline", "registered", "zero-copy" */
    uint64_t bytes;              /* section bytes the traversal reads */
    double upload_ms;            /* host to device, wall clock */
    double gb_per_s;
    /* A structure loaded from a file is validated before its first upload
     * unless it already was (as_structure_validate_recorded): on the GPU,
     * after the copy and before any kernel reads it, where its layout has
     * a GPU validator and it is in device memory; otherwise on the CPU
     * first. "gpu", "cpu", or "earlier" (already validated, or built in
     * this process). */
    const char *validated;
    double validate_ms;          /* wall clock; 0 for "earlier" */
} as_upload_info_t;

/* Makes the structure resident on the GPU now (the first GPU trace does it
 * otherwise), validating it first as as_upload_info_t says; later traces
 * reuse it until the structure is released. A structure that fails
 * validation is not left on the device (AS_ERROR_INVALID_STRUCTURE). Not
 * thread-safe against concurrent traces of the same structure. */
as_error_t as_structure_upload(const as_structure_t *s, const as_trace_args_t *args, as_upload_info_t *info);

/* Traces `count` rays. `timing` may be NULL. */
as_error_t as_trace(const as_structure_t *s, const as_ray_t *rays, size_t count,
                    as_hit_t *hits, const as_trace_args_t *args, as_trace_timing_t *timing);

/* Verification against a double-precision reference: the watertight test
 * in double over a conservatively traversed BVH of the structure's own
 * triangles. A hit agrees when it is the reference's primitive or a tie (a
 * primitive hit within 1e-6 of the scene diagonal of the reference's t);
 * any-hit results agree when they hit exactly when the reference does, on a
 * triangle the ray really meets. */
typedef struct as_verify_args {
    size_t size;
    size_t sample_count;         /* rays checked, spread over all (default 100,000; 0: all) */
    uint64_t seed;               /* which rays are sampled */
    uint32_t thread_count;       /* 0: every core */
} as_verify_args_t;
void as_verify_args_default(as_verify_args_t *args);

typedef struct as_verify_result {
    uint64_t checked;
    uint64_t wrong_primitive;    /* hit, but neither the reference's triangle nor a tie */
    uint64_t false_misses;       /* the reference hits, the trace missed */
    uint64_t false_hits;         /* the reference misses, the trace hit */
    double max_t_error;          /* largest |t - t_ref| / t_ref over agreeing closest hits
                                    farther than 1e-3 of the scene diagonal */
    double max_t_error_abs;      /* largest |t - t_ref| over all agreeing closest hits,
                                    in units of the scene diagonal */
    double verify_ms;
} as_verify_result_t;

/* Checks `hits` (one per ray, from a trace of `rays` with the same query)
 * against the double-precision reference on args->sample_count rays chosen
 * by args->seed, and counts the disagreements in `result`. `any_hit` says
 * which query made the hits. A disagreement is a result, not an error:
 * the return is AS_OK unless an argument is bad or memory runs out. */
as_error_t as_verify(const as_structure_t *s, const as_ray_t *rays, const as_hit_t *hits, size_t count,
                     bool any_hit, const as_verify_args_t *args, as_verify_result_t *result);

/* True when this build has CUDA and a device is usable. */
bool as_gpu_available(void);

/* Creates the CUDA context now. The first CUDA call of a process pays for
 * it (100 to 300 ms on the H100 host), wherever it falls; a caller that
 * times a load calls this first so the load is timed without it.
 * AS_ERROR_NO_DEVICE without a usable device. */
as_error_t as_gpu_prepare(void);

/* Ray and hit files (formats/SPEC.md). The read functions allocate *out with
 * malloc; the caller frees it. Writers write to a temporary file and rename. */
as_error_t as_rays_read(const char *path, as_ray_t **out, size_t *count);
as_error_t as_rays_write(const char *path, const as_ray_t *rays, size_t count);
as_error_t as_hits_read(const char *path, as_hit_t **out, size_t *count);
as_error_t as_hits_write(const char *path, const as_hit_t *hits, size_t count);
/* The same parsers over memory (used by the fuzzers); `name` is used in messages. */
as_error_t as_rays_parse(const void *data, size_t size, const char *name,
                         as_ray_t **out, size_t *count);
as_error_t as_hits_parse(const void *data, size_t size, const char *name,
                         as_hit_t **out, size_t *count);

/* ------------------------------------------------------------------------ */
/* Closest points                                                           */

typedef struct as_closest_point_args {
    size_t size;                 /* sizeof(as_closest_point_args_t) */
    float max_distance;          /* only triangles at most this far count (inclusive);
                                    default +infinity; must be >= 0 */
    uint32_t thread_count;       /* as_closest_points: 0 = every core */
    bool assume_valid;           /* skip the validation pass: only for a structure
                                    on which as_structure_validate has succeeded
                                    (default false) */
} as_closest_point_args_t;
void as_closest_point_args_default(as_closest_point_args_t *args);

/* The nearest point of the structure's triangles to a query point. prim is
 * the triangle's index in the source mesh, AS_NO_HIT when no triangle lies
 * within max_distance (then distance is +infinity and the rest zero); the
 * point is (1 - u - v) v0 + u v1 + v v2, as for a hit. */
typedef struct as_closest_point_result {
    uint32_t prim;
    float point[3];
    float distance;              /* Euclidean, from the query point */
    float u, v;
} as_closest_point_t;

/* The closest point on a BVH (every layout and builder) to `point`.
 * The answer is the triangle at the smallest distance; among triangles at
 * exactly the same distance, the lowest source index, so the result is the
 * same for every builder, layout and thread count (distances are computed in
 * double from the stored float vertices, after Ericson's closest point on a
 * triangle; a triangle whose corners lie on a line counts as its nearest
 * edge). Zero-area triangles are not in any structure (as_mesh_info_t's
 * degenerate_count says how many a mesh has) and are never the answer;
 * nothing else is skipped. A point with a non-finite coordinate has no
 * closest point (AS_NO_HIT).
 * The structure is validated first (a linear pass over it) unless
 * args->assume_valid is set. Fails with AS_ERROR_UNSUPPORTED for the other
 * structure kinds (KD tree, BIH, octree, grid), INVALID_ARGUMENT for a NULL
 * argument or a negative or NaN max_distance, INVALID_STRUCTURE when
 * validation fails. `args` may be NULL (defaults). */
as_error_t as_closest_point(const as_structure_t *s, const float point[3], const as_closest_point_args_t *args,
                            as_closest_point_t *out);

/* The same for `count` points (3 floats each) into out[0..count), on
 * args->thread_count threads, validating once for the whole batch; each
 * result equals what as_closest_point gives for that point. */
as_error_t as_closest_points(const as_structure_t *s, const float *points, size_t count,
                             const as_closest_point_args_t *args, as_closest_point_t *out);

/* ------------------------------------------------------------------------ */
/* Cameras and images                                                       */

typedef struct as_camera {
    float eye[3], target[3], up[3];
    float fov_y_degrees;         /* vertical field of view */
} as_camera_t;

/* A camera that sees the whole box: looking along -z from in front of it,
 * up +y, 45 degrees, at a distance that fits the bounding sphere. */
void as_camera_default(const float bounds_lo[3], const float bounds_hi[3], as_camera_t *cam);

/* Reads a camera file: text lines "eye X Y Z", "target X Y Z" (both
 * required), "up X Y Z" (default 0 1 0) and "fov DEGREES" (vertical,
 * default 45), in any order; blank lines and lines starting with '#' are
 * skipped. AS_ERROR_PARSE names the file and line of an unknown key or a
 * bad number, and refuses eye = target or an up along the view. */
as_error_t as_camera_read(const char *path, as_camera_t *cam);

/* One ray per pixel through the pixel centres, row-major from the top-left,
 * right-handed (x right, y up, looking down -z in camera space), tmin 0,
 * tmax infinity. `rays` has width * height entries. */
void as_camera_rays(const as_camera_t *cam, uint32_t width, uint32_t height, as_ray_t *rays);

/* The same rays in the order the GPU likes: 16 x 32 pixel tiles along a
 * Morton curve, row-major inside a tile. pixel_of_ray[i] (if not NULL) is
 * the row-major pixel index of ray i. */
void as_camera_rays_tiled(const as_camera_t *cam, uint32_t width, uint32_t height, as_ray_t *rays,
                          uint32_t *pixel_of_ray);

/* ------------------------------------------------------------------------ */
/* Workloads: secondary rays from primary hits                              */

typedef struct as_secondary_args {
    size_t size;
    uint32_t rays_per_hit;       /* AO default 16, diffuse 4 */
    float tmax_fraction;         /* tmax as a fraction of the scene diagonal
                                    (AO default 0.1); 0: unbounded */
    float offset_fraction;       /* origin offset along the geometric normal,
                                    flipped to face the incoming ray, as a
                                    fraction of the diagonal (default 1e-4);
                                    never less (0 included) than 4 float spacings of the
                                    hit point's largest coordinate, which
                                    rounding the origin to float could undo */
    uint64_t seed;
} as_secondary_args_t;
void as_secondary_args_default(as_secondary_args_t *args);

/* Cosine-weighted hemisphere rays from every primary hit (AO: any hit within
 * tmax; diffuse: closest hit, unbounded). *out is malloc'd; (*origin)[i]
 * (if origin is not NULL) is the primary ray that ray i comes from. */
as_error_t as_rays_hemisphere(const as_structure_t *s, const as_ray_t *primary, const as_hit_t *hits,
                              size_t count, const as_secondary_args_t *args, as_ray_t **out,
                              size_t *out_count, uint32_t **origin);

/* Shadow rays from every primary hit towards each light (a point), ending
 * just short of it. */
as_error_t as_rays_shadow(const as_structure_t *s, const as_ray_t *primary, const as_hit_t *hits,
                          size_t count, const float *lights, uint32_t light_count,
                          float offset_fraction, as_ray_t **out, size_t *out_count,
                          uint32_t **origin);

/* A triangle's material for Whitted ray tracing. */
typedef enum as_material_kind {
    AS_MATERIAL_OPAQUE = 0,      /* shadow rays only */
    AS_MATERIAL_MIRROR = 1,      /* and a reflection ray */
    AS_MATERIAL_GLASS = 2        /* and a reflection and a refraction ray */
} as_material_kind_t;

typedef struct as_material {
    uint32_t kind;               /* as_material_kind_t */
    float ior;                   /* glass: index of refraction; 0: as_whitted_args_t.ior */
} as_material_t;

/* The Whitted materials of an OBJ file's triangles, from its material
 * library: `mesh` is the OBJ imported by as_mesh_import (its per-triangle
 * material ids say which `usemtl` was in force), `obj_path` the same file,
 * which is scanned for its `mtllib` and `usemtl` statements. The rule, per
 * material: glass when its dissolve is below 1 (`d` < 1, or `Tr` > 0) or
 * `illum` is 4, 6, 7 or 9, with `Ni` as the index of refraction when given;
 * else a mirror when `illum` is 3 or 5 or every component of `Ks` is at
 * least 0.8; else opaque. Triangles before any `usemtl` are opaque.
 * Only the libraries the OBJ names are read, each relative to the OBJ's
 * directory: an absolute name, a ".." component, or anything but a regular
 * file (a FIFO, a device, a directory) is refused. *out (malloc'd, one per
 * triangle of `mesh`, by index; free() it) and *count are set on success.
 * Fails with FILE_NOT_FOUND or IO for a library that cannot be read, PARSE
 * for a malformed statement, a `usemtl` naming a material no library
 * defines, or an OBJ without `mtllib` (messages name the file and line),
 * INVALID_ARGUMENT when `mesh` does not come from that OBJ (its material
 * ids or triangle count disagree with the file), UNSUPPORTED for a
 * compressed OBJ. */
as_error_t as_materials_read_obj(const char *obj_path, const as_mesh_t *mesh, as_material_t **out,
                                 uint32_t *count);

/* Whitted ray tracing, one bounce at a time: from rays and their hits, the
 * next bounce's reflection and refraction rays and the shadow rays of the
 * hits. With `materials` (from the mesh's material file: see
 * as_materials_read_obj), each triangle's own; without, a fixed, seeded
 * share of the triangles are mirrors and glass (index of refraction `ior`),
 * the rest opaque: opaque hits spawn shadow rays only, mirrors a reflection
 * ray too, glass a refraction and a reflection ray (the reflection alone on
 * total internal reflection). */
typedef struct as_whitted_args {
    size_t size;
    float mirror_fraction;       /* default 0.10 */
    float glass_fraction;        /* default 0.05 */
    float ior;                   /* default 1.5 */
    uint64_t seed;               /* which triangles are mirrors and glass */
    float offset_fraction;       /* as in as_secondary_args_t (default 1e-4) */
    const float *lights;         /* 3 floats per point light */
    uint32_t light_count;
    const as_material_t *materials; /* one per triangle by source index, used instead of
                                    the seeded fractions when not NULL (default NULL);
                                    the caller keeps it alive through the bounces */
    uint32_t material_count;     /* entries in `materials`: the structure's triangle count */
} as_whitted_args_t;
void as_whitted_args_default(as_whitted_args_t *args);

/* The material of a triangle under these arguments: 0 opaque, 1 mirror,
 * 2 glass (as_material_kind_t); with `materials`, that triangle's (opaque
 * past material_count), else the seeded default. */
int as_whitted_material(const as_whitted_args_t *args, uint32_t prim);

/* One Whitted bounce: for every hit of `rays`, a shadow ray to each light
 * (into *shadow) and, on mirrors and glass, the reflection and refraction
 * rays (into *next), each leaving the surface by the offset on its own
 * side. Both arrays are allocated here (free() them) and may be empty;
 * missed rays make none. INVALID_ARGUMENT when `materials` is set and
 * material_count is not the structure's triangle count. */
as_error_t as_rays_whitted_bounce(const as_structure_t *s, const as_ray_t *rays, const as_hit_t *hits,
                                  size_t count, const as_whitted_args_t *args, as_ray_t **next,
                                  size_t *next_count, as_ray_t **shadow, size_t *shadow_count);

/* Four point lights from the scene box, at 90% of its height along y over
 * the quarter points of its x and z extent, so shadows fall inside the
 * scene (as-trace --light overrides them). `lights` holds 12 floats. */
void as_lights_default(const float bounds_lo[3], const float bounds_hi[3], float lights[12]);

/* Shades the hits of as_camera_rays as a grey image lit from the camera (the
 * absolute cosine between the ray and the geometric normal), background dark
 * blue, and writes it as an 8-bit RGB PNG (temporary file, then rename). */
as_error_t as_image_write_png(const as_structure_t *s, const as_ray_t *rays,
                              const as_hit_t *hits, uint32_t width, uint32_t height,
                              const char *path);

/* Writes grey values in [0, 1], row-major, as an 8-bit RGB PNG; a negative
 * value is drawn as the background (dark blue). */
as_error_t as_image_write_png_grey(const char *path, uint32_t width, uint32_t height, const float *values);

/* Writes a heat map of traversal steps per pixel (`steps`: width * height,
 * row-major, as as_trace_args_t.ray_steps gives them once put back in pixel
 * order) as an 8-bit RGB PNG on the viridis ramp: 0 steps dark purple,
 * `scale_max` steps and more yellow. scale_max 0 scales to the image's 99th
 * percentile (at least 1) so a few extreme rays do not flatten the rest.
 * Every pixel is coloured, misses too: a miss costs the steps it took.
 * The scale used goes to *scale_used when it is not NULL. */
as_error_t as_image_write_png_heat(const char *path, uint32_t width, uint32_t height, const uint32_t *steps,
                                   uint32_t scale_max, uint32_t *scale_used);

/* ------------------------------------------------------------------------ */
/* Stiff cases                                                              */

/* The stiff-case suite: meshes and rays where floating point is hardest,
 * each with the outcome a correct tracer gives, generated with fixed seeds
 * so that the same arguments give the same bytes on every machine. The
 * suite's own test (tests/test_stiff.c) takes its cases from here; anyone
 * can test a tracer of their own on them, through these functions or the
 * as-stiff tool (docs/stiff-cases.md). Every ray is a closest-hit query.
 * Values are never renumbered; they run from 1 to AS_STIFF_CASE_COUNT. */
typedef enum as_stiff_case {
    /* A closed lattice cube (6 x 6 quads a face, two triangles each, shared
     * vertices) with its corner at `offset` on every axis, and rays from
     * inside (unbounded) and outside (ending at the centre) aimed exactly at
     * every vertex and at the quarter points of every edge: every ray hits.
     * The Moller-Trumbore test leaks here (some rays miss), which is why the
     * watertight test is the default. */
    AS_STIFF_WATERTIGHT_CUBE = 1,
    /* The same rays on a closed latitude-longitude sphere with pole fans (12
     * rings, 24 segments, radius 4 edges), its box's corner at `offset`. */
    AS_STIFF_WATERTIGHT_SPHERE = 2,
    /* Two triangles sharing a diagonal, rays through points of the diagonal
     * from both sides, slanted: each hits one of the two. */
    AS_STIFF_QUAD_SEAM = 3,
    /* 2,000 random triangles; axis-parallel rays from vertex coordinates (on
     * split planes, box faces, grid walls, octree planes), in groups of four
     * whose other direction components are +0 and -0: the four give equal
     * hits, the first the reference's answer, none a NaN. */
    AS_STIFF_SIGNED_ZERO = 4,
    /* A 1,000 x 1,000 plane (z = 0) of 3,200 triangles; rays reaching it at
     * 1e-1 down to 1e-7 radians (the reference's answer), then rays inside
     * the plane, which meet every triangle edge-on: the documented answer is
     * a miss. */
    AS_STIFF_GRAZING = 5,
    /* 3,000 triangles from 1e-6 to 1e6 in size side by side (log-uniform),
     * half the rays aimed at triangles' centroids: the reference's answer
     * with the double-precision intersector (where the float test cancels,
     * it may disagree; the suite counts how often). */
    AS_STIFF_DYNAMIC_RANGE = 6,
    /* 3,000 triangles: repeated indices, collinear vertices, needles of
     * aspect 1e7 and ordinary ones: zero-area triangles are never hit, the
     * rest is the reference's answer. */
    AS_STIFF_DEGENERATE = 7,
    /* 2,000 triangles all in the plane y = 0.5 (a zero-thickness box), rays
     * from above and below: the reference's answer, hits from both sides. */
    AS_STIFF_FLAT = 8,
    /* `duplicate_count` copies of one triangle, alone or among 500 others,
     * one ray through it: the hit is the lowest copy. A structure over it
     * also keeps its depth within its cap and its nodes linear in the count. */
    AS_STIFF_DUPLICATES = 9,
    /* Axis-aligned quads lying exactly on the box's middle and quarter
     * planes (candidate split planes) on every axis, rays crossing them:
     * every ray hits, the reference's answer. */
    AS_STIFF_PLANAR_ON_SPLIT = 10,
    /* Rays leaving a surface: cosine-weighted hemisphere rays (unbounded)
     * from the hits of 200 x 200 camera rays, offset along the normal by
     * as_rays_hemisphere's default (1e-4 of the scene diagonal, at least 4
     * float spacings of the hit point): none hits the triangle it leaves.
     * On the suite's own mesh (the watertight sphere, at `offset`: convex)
     * every ray misses; on `surface_mesh`, none hits its source. */
    AS_STIFF_SURFACE = 11,
    /* Ordinary rays over 20,000 random triangles, then as many copies with
     * tmin > tmax, a zero direction, or a NaN or Inf in the origin, the
     * direction or tmin: the copies miss (no hit written), and take at most
     * 2.5 times the ordinary rays' time. */
    AS_STIFF_BAD_RAYS = 12
} as_stiff_case_t;

#define AS_STIFF_CASE_COUNT 12

/* The name of a case on command lines ("watertight-cube", "seam",
 * "signed-zero", "bad-rays", ...); NULL for an unknown value. */
const char *as_stiff_case_name(as_stiff_case_t kind);
/* The case of that name; 0 for an unknown name. */
as_stiff_case_t as_stiff_case_from_name(const char *name);

typedef struct as_stiff_args {
    size_t size;                 /* sizeof(as_stiff_args_t) */
    uint64_t seed;               /* 0 (default): the suite's own meshes and rays;
                                    another value gives other random meshes and
                                    rays of the same kind, where the case draws any
                                    (the watertight meshes, the seam, the grazing
                                    plane and the planar quads are fixed; their
                                    rays, but the watertight ones, are drawn) */
    double offset;               /* watertight and surface cases: where the mesh
                                    lies (its box's corner on every axis; the
                                    suite uses 0, 1e6 and 1e7; default 0) */
    double edge;                 /* watertight and surface cases: the lattice edge (the
                                    sphere's radius is 4 of them); 0 (default):
                                    1 at offset 0, 16 at 1e6, 128 at 1e7, else the
                                    smallest power of two of at least 256 float
                                    spacings at the offset, so that the spacing
                                    stays below 1/100 of an edge */
    uint32_t duplicate_count;    /* duplicates: copies of the triangle (default
                                    10,000; the suite also uses 2, 10 and 100) */
    bool duplicates_among_others;/* duplicates: after 500 other triangles
                                    (default false) */
    size_t ray_count;            /* 0 (default): the suite's count; else about this
                                    many rays where the case draws them (seam,
                                    signed zero in groups of 24, grazing in groups of
                                    8, dynamic range, degenerate, flat, planar, and
                                    bad rays, which then gives twice as many) */
    const as_mesh_t *surface_mesh; /* surface: the mesh the rays leave (copied:
                                    positions and indices); NULL (default): the
                                    sphere of AS_STIFF_WATERTIGHT_SPHERE at 0 */
    const as_structure_t *surface_structure; /* surface: a structure over that mesh
                                    that traces the camera rays on the CPU; NULL
                                    (default): a BVH built here. The hits it gives
                                    are where the rays start, so a caller that
                                    tests a structure passes it here to get the rays
                                    its own hits give */
} as_stiff_args_t;
void as_stiff_args_default(as_stiff_args_t *args);

/* What one ray of a case must give. */
typedef enum as_stiff_expect {
    AS_STIFF_EXPECT_HIT = 1,       /* a hit on some triangle */
    AS_STIFF_EXPECT_MISS = 2,      /* no hit: prim AS_NO_HIT, t +infinity */
    AS_STIFF_EXPECT_PRIM = 3,      /* a hit on one of the listed primitives */
    AS_STIFF_EXPECT_NOT_PRIM = 4,  /* a miss, or a hit on none of the listed primitives */
    AS_STIFF_EXPECT_REFERENCE = 5  /* the reference's answer: the double-precision
                                      watertight test over every triangle, agreeing
                                      as as_verify says (the same primitive, or a
                                      tie within 1e-6 of the scene diagonal) */
} as_stiff_expect_t;

#define AS_STIFF_NO_RAY 0xFFFFFFFFu

/* 20 bytes: a ray's correct outcome. A ray meets every condition its
 * outcome states. */
typedef struct as_stiff_outcome {
    uint32_t expect;             /* as_stiff_expect_t */
    uint32_t first, count;       /* PRIM and NOT_PRIM: the primitives are
                                    prims[first .. first + count) of the case */
    uint32_t same_as;            /* AS_STIFF_NO_RAY, or the index of an earlier ray
                                    whose hit this ray's must equal in every byte */
    uint32_t reference;          /* 1: besides `expect`, the hit is the
                                    reference's answer (as for EXPECT_REFERENCE) */
} as_stiff_outcome_t;

/* A generated case. Everything in it is owned by it until
 * as_stiff_case_free; a caller that keeps the mesh sets `mesh` to NULL
 * first (and releases it with as_mesh_release). */
typedef struct as_stiff_case_data {
    as_stiff_case_t kind;
    as_mesh_t *mesh;
    as_ray_t *rays;              /* ray_count rays */
    size_t ray_count;
    as_stiff_outcome_t *outcomes; /* one per ray */
    uint32_t *prims;             /* the primitive lists the outcomes name */
    size_t prim_count;
    as_intersector_t intersector; /* the triangle test the outcomes hold for:
                                    AS_INTERSECTOR_WATERTIGHT_DOUBLE for dynamic
                                    range, AS_INTERSECTOR_WATERTIGHT (and its double
                                    version) for every other case */
    const char *outcome;         /* the correct outcome in words; static string */
} as_stiff_case_data_t;

/* Generates a case: its mesh, its rays and each ray's outcome into *out
 * (cleared first). The same kind and arguments give the same bytes on every
 * machine and thread count, except the surface case given a structure of
 * another kind or builder, whose hits may differ on shared edges. `args`
 * may be NULL (defaults). Fails with INVALID_ARGUMENT for an unknown kind,
 * a NULL `out`, a size field that is no size of as_stiff_args_t, a
 * non-finite offset or edge, a negative edge, a duplicate count
 * of 0 or above 10,000,000, a ray count above 100,000,000, or a surface
 * structure whose triangle count is not the surface mesh's; with
 * INVALID_MESH when the watertight mesh at that offset and edge leaves the
 * float range; OUT_OF_MEMORY. On failure *out holds nothing to free. */
as_error_t as_stiff_case_generate(as_stiff_case_t kind, const as_stiff_args_t *args, as_stiff_case_data_t *out);

/* Frees what a case holds (the mesh too, unless NULL) and clears it; NULL
 * and a cleared case are accepted. */
void as_stiff_case_free(as_stiff_case_data_t *c);

#ifdef __cplusplus
}
#endif

#endif
