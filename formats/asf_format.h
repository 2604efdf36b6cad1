/* The .asf container, version 1.0: on-disk structs, byte for byte as in
 * formats/SPEC.md. Every multi-byte field is little-endian; these structs are
 * read in place on little-endian hosts (the only ones libas supports, checked
 * at build time). Read by the CPU only; the sections they describe are what
 * goes to the GPU. */
#ifndef AS_ASF_FORMAT_H
#define AS_ASF_FORMAT_H

#include <stdint.h>

#define ASF_MAGIC_BYTES "\x89" "ASF\r\n\x1a\n"  /* 8 bytes, PNG-style */
#define ASF_VERSION_MAJOR 1
#define ASF_VERSION_MINOR 1
#define ASF_SECTION_ALIGNMENT 64  /* every section offset is a multiple */
#define ASF_MAX_SECTIONS 1024     /* a limit readers impose */

/* Four-character tags, first character in the lowest byte. */
#define ASF_TAG(a, b, c, d) \
    ((uint32_t)(a) | ((uint32_t)(b) << 8) | ((uint32_t)(c) << 16) | ((uint32_t)(d) << 24))

#define ASF_TAG_META ASF_TAG('M', 'E', 'T', 'A') /* as_meta_t, required */
#define ASF_TAG_BVH2 ASF_TAG('B', 'V', 'H', '2') /* as_bvh2_node_t[], child-bounds layout */
#define ASF_TAG_TRI4 ASF_TAG('T', 'R', 'I', '4') /* as_tri4_t[], triangles in leaf order */
#define ASF_TAG_TRIS ASF_TAG('T', 'R', 'I', 'S') /* as_tri4_t[], one per source triangle, source order */
#define ASF_TAG_PRIM ASF_TAG('P', 'R', 'I', 'M') /* uint32_t[], leaf lists of source indices into TRIS */
#define ASF_TAG_BIHN ASF_TAG('B', 'I', 'H', 'N') /* as_bih_node_t[], BIH nodes */
#define ASF_TAG_OCTH ASF_TAG('O', 'C', 'T', 'H') /* as_octree_header_t, the root cube */
#define ASF_TAG_OCTN ASF_TAG('O', 'C', 'T', 'N') /* as_octree_node_t[], octree nodes */
#define ASF_TAG_GRDH ASF_TAG('G', 'R', 'D', 'H') /* as_grid_header_t, dimensions and box */
#define ASF_TAG_GRDC ASF_TAG('G', 'R', 'D', 'C') /* uint32_t[cells + 1], cell offsets into PRIM */
#define ASF_TAG_BVHO ASF_TAG('B', 'V', 'H', 'O') /* as_bvh2o_node_t[], own-bounds layout */
#define ASF_TAG_CWBV ASF_TAG('C', 'W', 'B', 'V') /* as_cwbvh_node_t[], compressed wide BVH nodes */
#define ASF_TAG_KDN8 ASF_TAG('K', 'D', 'N', '8') /* as_kd_node_t[], KD nodes (8 bytes) */
#define ASF_TAG_KDRP ASF_TAG('K', 'D', 'R', 'P') /* as_kd_ropes_t[], six ropes per KD leaf */
#define ASF_TAG_KDLB ASF_TAG('K', 'D', 'L', 'B') /* as_kd_leaf_box_t[], KD leaf boxes */
#define ASF_TAG_BREC ASF_TAG('B', 'R', 'E', 'C') /* as_build_record_t, optional */
#define ASF_TAG_CSUM ASF_TAG('C', 'S', 'U', 'M') /* chunk checksums of the other sections, optional (1.1) */

/* CSUM: a 16-byte head, then one XXH3-64 per chunk of every other section,
 * in table order (SPEC.md 3.16). */
#define ASF_CSUM_CHUNK_LOG2 20u       /* what writers use: 1 MiB chunks */
#define ASF_CSUM_MIN_CHUNK_LOG2 16u   /* what readers accept */
#define ASF_CSUM_MAX_CHUNK_LOG2 30u
typedef struct asf_csum_head {
    uint32_t chunk_log2;
    uint32_t covered_sections;     /* the sections before CSUM in the table: all others */
    uint64_t hash_count;
} asf_csum_head_t;
_Static_assert(sizeof(asf_csum_head_t) == 16, "CSUM head is 16 bytes");

/* Section flags. */
#define ASF_SECTION_REQUIRED 0x1u   /* a reader that does not know the tag must refuse */
#define ASF_SECTION_ZSTD     0x2u   /* stored as one zstd frame */
#define ASF_SECTION_KNOWN_FLAGS (ASF_SECTION_REQUIRED | ASF_SECTION_ZSTD)

/* File header: 64 bytes at offset 0. */
typedef struct asf_header {
    uint8_t magic[8];              /* ASF_MAGIC_BYTES */
    uint16_t version_major;        /* readers refuse a larger one */
    uint16_t version_minor;        /* readers accept any */
    uint32_t header_size;          /* 64 in 1.0; readers accept >= 64 */
    uint32_t section_count;        /* entries in the table */
    uint32_t section_entry_size;   /* 64 in 1.0; readers accept >= 64 */
    uint64_t section_table_offset; /* multiple of 8, after the header */
    uint64_t file_size;            /* total bytes; must equal the real size */
    uint64_t table_checksum;       /* XXH3-64 of the section table bytes */
    uint8_t reserved[16];          /* must be zero; readers check */
} asf_header_t;

/* Section table entry: 64 bytes. */
typedef struct asf_section_entry {
    uint32_t tag;
    uint32_t flags;                /* ASF_SECTION_*; unknown bits: refuse */
    uint64_t offset;               /* multiple of ASF_SECTION_ALIGNMENT */
    uint64_t stored_size;          /* bytes in the file */
    uint64_t raw_size;             /* bytes after decompression (= stored if raw) */
    uint64_t element_count;        /* raw_size = element_count * stride */
    uint32_t stride;               /* bytes per element, > 0 */
    uint32_t reserved0;            /* must be zero */
    uint64_t checksum;             /* XXH3-64 (seed 0) of the raw bytes */
    uint64_t reserved1;            /* must be zero */
} asf_section_entry_t;

/* The META section: one 256-byte record. */
typedef struct as_meta {
    char writer[32];               /* NUL-terminated, e.g. "libas" */
    uint32_t writer_version;       /* MAJOR*10000 + MINOR*100 + PATCH */
    uint32_t structure_kind;       /* as_structure_kind_t */
    uint32_t layout;               /* as_layout_t */
    uint32_t layout_version;       /* readers refuse a newer one */
    uint32_t builder;              /* as_builder_t */
    uint32_t max_leaf_size;
    uint32_t bin_count;
    float cost_traversal;
    float cost_intersection;
    uint32_t triangle_count;       /* triangles of the source mesh */
    uint64_t source_hash;          /* as_mesh_info_t.hash of the source */
    float bounds_lo[3];            /* scene box */
    float bounds_hi[3];
    uint64_t node_count;           /* inner nodes */
    uint64_t leaf_count;
    uint32_t max_depth;
    uint32_t reserved0;            /* must be zero */
    double sah_cost;
    uint64_t reserved1;            /* must be zero (the build time is in BREC, which is optional) */
    uint64_t empty_leaf_count;     /* leaves (grid: cells) without triangles */
    uint64_t reference_count;      /* triangle references in all leaves */
    uint32_t max_depth_limit;      /* build parameter: depth cap */
    float grid_lambda;             /* build parameter: grid cells per triangle */
    float split_budget;            /* build parameter: SBVH/KD reference budget */
    float sbvh_alpha;              /* build parameter: SBVH overlap threshold */
    uint8_t reserved[80];          /* must be zero */
} as_meta_t;

/* The BREC section: how long the build took, one 32-byte record. Optional:
 * a file without it is as valid, and leaving it out keeps two builds of the
 * same mesh byte-identical. */
typedef struct as_build_record {
    double build_ms;               /* wall time of the build, finite, >= 0 */
    uint32_t thread_count;         /* build threads the builder could use */
    uint32_t core_count;           /* cores of the machine that built it */
    uint64_t reserved[2];          /* must be zero */
} as_build_record_t;

_Static_assert(sizeof(as_build_record_t) == 32, "as_build_record_t is 32 bytes");
_Static_assert(sizeof(asf_header_t) == 64, "asf_header_t is 64 bytes");
_Static_assert(sizeof(asf_section_entry_t) == 64, "asf_section_entry_t is 64 bytes");
_Static_assert(sizeof(as_meta_t) == 256, "as_meta_t is 256 bytes");

/* Ray and hit files: a 32-byte header, then records. */
#define AS_RAYS_MAGIC_BYTES "ASRAYS\0\0"
#define AS_HITS_MAGIC_BYTES "ASHITS\0\0"
#define AS_RECORDS_VERSION_MAJOR 1
#define AS_RECORDS_VERSION_MINOR 0

typedef struct as_records_header {
    uint8_t magic[8];
    uint16_t version_major;
    uint16_t version_minor;
    uint32_t record_size;          /* 32 for rays, 16 for hits */
    uint64_t count;                /* records that follow; file size = 32 + count * record_size */
    uint64_t reserved;             /* must be zero */
} as_records_header_t;

_Static_assert(sizeof(as_records_header_t) == 32, "as_records_header_t is 32 bytes");

#endif
