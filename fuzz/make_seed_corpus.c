/* Writes the seed corpora of the fuzzers: a few valid files of each kind
 * and a few damaged ones, each well under 8 KB. Run once from the
 * repository root; the outputs are committed:
 *   make_seed_corpus fuzz/corpus
 * Seeds of fuzz_asf_reader and fuzz_structure_trace start with the
 * harness's parameter byte. */
#define _POSIX_C_SOURCE 200809L
#include "asf_container.h"
#include "as_internal.h"
#include "fuzz_structure_bytes.h"

#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

static const char *root;

static void die(const char *what)
{
    fprintf(stderr, "make_seed_corpus: %s: %s\n", what, as_get_error_message());
    exit(1);
}

static void put(const char *dir, const char *name, uint8_t param, const void *data, size_t size)
{
    char path[1024];
    snprintf(path, sizeof path, "%s/%s/%s", root, dir, name);
    FILE *f = fopen(path, "wb");
    if (!f) die(path);
    if (strcmp(dir, "asf_reader") == 0 || strcmp(dir, "structure_trace") == 0) fputc(param, f);
    if (size && fwrite(data, 1, size, f) != size) die(path);
    if (fclose(f) != 0) die(path);
}

/* Two triangles under one root: the smallest structure with both leaves. */
static float nodes[16][16];
static float tris[2][12];
static as_meta_t meta;

static void make_structure(asf_section_desc_t desc[3], int level, uint32_t node_count)
{
    memset(nodes, 0, sizeof nodes);
    for (uint32_t n = 0; n < node_count; ++n) {
        const float lo = (float)n, hi = lo + 1.0f;
        const float c[12] = {lo, hi, lo, hi, lo, hi, lo, hi, lo, hi, lo, hi};
        memcpy(nodes[n], c, sizeof c);
        int32_t child[2] = {~0, ~1};
        uint32_t count[2] = {1, 1};
        if (n + 1 < node_count) {
            child[0] = (int32_t)(n + 1);
            count[0] = 0;
        }
        memcpy(&nodes[n][12], child, sizeof child);
        memcpy(&nodes[n][14], count, sizeof count);
    }
    const float t[2][12] = {{0, 0, 0, 0, 1, 0, 0, 0, 0, 1, 0, 0}, {1, 1, 1, 0, 2, 1, 1, 0, 1, 2, 1, 0}};
    memcpy(tris, t, sizeof t);
    const uint32_t second = 1;
    memcpy(&tris[1][3], &second, sizeof second); /* v0.w: source triangle index */

    memset(&meta, 0, sizeof meta);
    strcpy(meta.writer, "libas");
    meta.writer_version = AS_VERSION_NUMBER;
    meta.structure_kind = AS_STRUCT_BVH;
    meta.layout = AS_LAYOUT_BVH2_CHILD_BOUNDS;
    meta.layout_version = 1;
    meta.builder = AS_BUILDER_BVH_SAH_BINNED;
    meta.max_leaf_size = 4;
    meta.bin_count = 16;
    meta.cost_traversal = 1.0f;
    meta.cost_intersection = 1.0f;
    meta.triangle_count = 2;
    meta.node_count = node_count;
    meta.leaf_count = node_count + 1;
    meta.bounds_hi[0] = meta.bounds_hi[1] = meta.bounds_hi[2] = 2.0f;
    desc[0] = (asf_section_desc_t){ASF_TAG_META, ASF_SECTION_REQUIRED, &meta, sizeof meta, 1, sizeof meta, level};
    desc[1] = (asf_section_desc_t){ASF_TAG_BVH2, ASF_SECTION_REQUIRED, nodes, node_count * 64, node_count, 64, level};
    desc[2] = (asf_section_desc_t){ASF_TAG_TRI4, ASF_SECTION_REQUIRED, tris, sizeof tris, 2, 48, level};
}

static uint8_t *container(int level, uint32_t node_count, size_t *size)
{
    asf_section_desc_t desc[3];
    make_structure(desc, level, node_count);
    void *buf;
    if (asf_write_memory(desc, 3, &buf, size) != AS_OK) die("asf_write_memory");
    return buf;
}

static void fix_table(uint8_t *file)
{
    asf_header_t h;
    memcpy(&h, file, sizeof h);
    h.table_checksum = as_hash64(file + h.section_table_offset, (size_t)h.section_count * h.section_entry_size);
    memcpy(file, &h, sizeof h);
}

static asf_section_entry_t *entry(uint8_t *file, int i) { return (asf_section_entry_t *)(file + 64 + 64 * i); }

static void asf_seeds(void)
{
    const char *d = "asf_reader";
    size_t size;
    uint8_t *f = container(0, 1, &size);
    put(d, "valid_raw", 0x01, f, size);
    put(d, "valid_raw_fix_table", 0x03, f, size);
    put(d, "valid_raw_no_known_tags", 0x05, f, size);
    put(d, "valid_raw_misaligned", 0x09, f, size);
    put(d, "truncated", 0x01, f, size - 40);
    put(d, "header_only", 0x01, f, 64);
    f[8] = 2; /* version 2.0 */
    put(d, "newer_major", 0x01, f, size);
    f[8] = 1;
    f[0] = 'X';
    put(d, "bad_magic", 0x01, f, size);
    f[0] = 0x89;
    f[entry(f, 2)->offset + 7] ^= 1;
    put(d, "checksum_mismatch", 0x01, f, size);
    put(d, "checksum_unchecked", 0x00, f, size);
    f[entry(f, 2)->offset + 7] ^= 1;
    entry(f, 2)->tag = ASF_TAG('X', 'T', 'R', 'A');
    entry(f, 2)->flags = 0;
    fix_table(f);
    put(d, "unknown_optional", 0x01, f, size);
    entry(f, 2)->flags = ASF_SECTION_REQUIRED;
    fix_table(f);
    put(d, "unknown_required", 0x01, f, size);
    free(f);

    f = container(19, 16, &size);
    put(d, "valid_zstd", 0x03, f, size);
    asf_section_entry_t *bvh = entry(f, 1);
    if (!(bvh->flags & ASF_SECTION_ZSTD)) die("the BVH2 seed section did not compress");
    f[bvh->offset + bvh->stored_size / 2] ^= 0x5a;
    put(d, "zstd_damaged", 0x03, f, size);
    free(f);

    /* Container 1.1: the CSUM section every file now ends with (entry 3),
     * intact, with a damaged chunk, and with a damaged head. */
    f = container(0, 16, &size);
    asf_section_entry_t *csum = entry(f, 3);
    if (csum->tag != ASF_TAG_CSUM) die("the seed container has no CSUM section");
    put(d, "csum_valid", 0x01, f, size);
    f[entry(f, 1)->offset + 3] ^= 0x20;
    put(d, "csum_chunk_mismatch", 0x01, f, size);
    f[entry(f, 1)->offset + 3] ^= 0x20;
    f[csum->offset] = 40; /* chunk_log2 out of range */
    csum->checksum = as_hash64(f + csum->offset, (size_t)csum->raw_size);
    fix_table(f);
    put(d, "csum_bad_head", 0x01, f, size);
    free(f);

    void *empty;
    if (asf_write_memory(NULL, 0, &empty, &size) != AS_OK) die("asf_write_memory");
    put(d, "no_sections", 0x01, empty, size);
    free(empty);
}

static void ray_seeds(void)
{
    char path[1024];
    as_ray_t rays[4];
    for (int i = 0; i < 4; ++i)
        rays[i] = (as_ray_t){{0.25f * (float)i, 0.5f, 3.0f}, 0.0f, {0.0f, 0.0f, -1.0f}, INFINITY};
    as_hit_t hits[4];
    for (int i = 0; i < 4; ++i) hits[i] = (as_hit_t){3.0f, (uint32_t)i, 0.25f, 0.25f};
    hits[3] = (as_hit_t){INFINITY, AS_NO_HIT, 0.0f, 0.0f};

    snprintf(path, sizeof path, "%s/ray_file/rays_valid", root);
    if (as_rays_write(path, rays, 4) != AS_OK) die(path);
    snprintf(path, sizeof path, "%s/ray_file/rays_empty", root);
    if (as_rays_write(path, NULL, 0) != AS_OK) die(path);
    snprintf(path, sizeof path, "%s/ray_file/hits_valid", root);
    if (as_hits_write(path, hits, 4) != AS_OK) die(path);

    /* Damaged ones, from the bytes of the valid ray file. */
    uint8_t file[32 + 4 * 32];
    as_records_header_t h = {AS_RAYS_MAGIC_BYTES, 1, 0, 32, 4, 0};
    memcpy(file, &h, sizeof h);
    memcpy(file + 32, rays, sizeof rays);
    put("ray_file", "rays_truncated", 0, file, sizeof file - 5);
    h.version_major = 2;
    memcpy(file, &h, sizeof h);
    put("ray_file", "rays_newer_major", 0, file, sizeof file);
    h.version_major = 1;
    h.record_size = 16;
    memcpy(file, &h, sizeof h);
    put("ray_file", "rays_wrong_record_size", 0, file, sizeof file);
    h.record_size = 32;
    h.count = UINT64_MAX / 32;
    memcpy(file, &h, sizeof h);
    put("ray_file", "rays_huge_count", 0, file, sizeof file);
}

/* A tiny scene in the unit cube: a closed cube, a tetrahedron inside it and
 * a tilted quad crossing it, 18 triangles, enough for a few levels in every
 * structure and files of a few KB. */
static as_mesh_t *tiny_mesh(void)
{
    static const float pos[] = {
        0, 0, 0, 1, 0, 0, 1, 1, 0, 0, 1, 0, 0, 0, 1, 1, 0, 1, 1, 1, 1, 0, 1, 1,   /* cube 0..7 */
        0.3f, 0.3f, 0.3f, 0.7f, 0.35f, 0.3f, 0.45f, 0.7f, 0.35f, 0.5f, 0.5f, 0.7f, /* tetrahedron 8..11 */
        0.1f, 0.2f, 0.15f, 0.9f, 0.2f, 0.6f, 0.9f, 0.8f, 0.85f, 0.1f, 0.8f, 0.4f,  /* quad 12..15 */
    };
    static const uint32_t idx[] = {
        0, 2, 1, 0, 3, 2, 4, 5, 6, 4, 6, 7, 0, 1, 5, 0, 5, 4,
        3, 6, 2, 3, 7, 6, 0, 4, 7, 0, 7, 3, 1, 2, 6, 1, 6, 5,
        8, 10, 9, 8, 9, 11, 9, 10, 11, 10, 8, 11,
        12, 13, 14, 12, 14, 15,
    };
    as_mesh_t *m = as_mesh_create(16, pos, (uint32_t)(sizeof idx / sizeof idx[0] / 3), idx);
    if (!m) die("as_mesh_create");
    return m;
}

/* One real file of every structure kind, builder and layout, raw and
 * compressed, with the parameter byte of fuzz_structure_trace: mostly 0x02
 * (the table checksum rewritten, section checksums not verified), so that
 * the fuzzer's mutations reach validation and the traversal. */
static void structure_seeds(void)
{
    static const struct {
        const char *name;
        as_structure_kind_t kind;
        as_builder_t builder;
        as_layout_t layout;
        int level;
        uint8_t param;
    } seeds[] = {
        {"bvh_sah_child_bounds", AS_STRUCT_BVH, AS_BUILDER_BVH_SAH_BINNED, AS_LAYOUT_BVH2_CHILD_BOUNDS, 0, 0x02},
        {"bvh_sah_child_bounds_zstd", AS_STRUCT_BVH, AS_BUILDER_BVH_SAH_BINNED, AS_LAYOUT_BVH2_CHILD_BOUNDS, 19, 0x03},
        {"bvh_sah_own_bounds", AS_STRUCT_BVH, AS_BUILDER_BVH_SAH_BINNED, AS_LAYOUT_BVH2_OWN_BOUNDS, 0, 0x02},
        {"bvh_sweep_child_bounds", AS_STRUCT_BVH, AS_BUILDER_BVH_SAH_SWEEP, AS_LAYOUT_BVH2_CHILD_BOUNDS, 0, 0x06},
        {"bvh_midcut_child_bounds_shifted", AS_STRUCT_BVH, AS_BUILDER_BVH_MIDCUT, AS_LAYOUT_BVH2_CHILD_BOUNDS, 0, 0x0a},
        {"bvh_midcut_own_bounds_zstd", AS_STRUCT_BVH, AS_BUILDER_BVH_MIDCUT, AS_LAYOUT_BVH2_OWN_BOUNDS, 3, 0x02},
        {"bvh_sbvh_child_bounds", AS_STRUCT_BVH, AS_BUILDER_BVH_SBVH, AS_LAYOUT_BVH2_CHILD_BOUNDS, 0, 0x02},
        {"bvh_sbvh_own_bounds", AS_STRUCT_BVH, AS_BUILDER_BVH_SBVH, AS_LAYOUT_BVH2_OWN_BOUNDS, 0, 0x06},
        {"bvh_sah_cwbvh", AS_STRUCT_BVH, AS_BUILDER_BVH_SAH_BINNED, AS_LAYOUT_BVH_CWBVH, 0, 0x02},
        {"bvh_sbvh_cwbvh_zstd", AS_STRUCT_BVH, AS_BUILDER_BVH_SBVH, AS_LAYOUT_BVH_CWBVH, 3, 0x06},
        {"kd_sah_standard", AS_STRUCT_KD, AS_BUILDER_KD_SAH, AS_LAYOUT_KD_STANDARD, 0, 0x02},
        {"kd_sah_ropes", AS_STRUCT_KD, AS_BUILDER_KD_SAH, AS_LAYOUT_KD_ROPES, 0, 0x02},
        {"kd_midcut_standard_zstd", AS_STRUCT_KD, AS_BUILDER_KD_MIDCUT, AS_LAYOUT_KD_STANDARD, 19, 0x03},
        {"kd_midcut_ropes_shifted", AS_STRUCT_KD, AS_BUILDER_KD_MIDCUT, AS_LAYOUT_KD_ROPES, 0, 0x0e},
        {"bih", AS_STRUCT_BIH, AS_BUILDER_BIH, AS_LAYOUT_BIH, 0, 0x02},
        {"bih_zstd_shifted", AS_STRUCT_BIH, AS_BUILDER_BIH, AS_LAYOUT_BIH, 9, 0x0b},
        {"octree", AS_STRUCT_OCTREE, AS_BUILDER_OCTREE, AS_LAYOUT_OCTREE, 0, 0x02},
        {"octree_zstd", AS_STRUCT_OCTREE, AS_BUILDER_OCTREE, AS_LAYOUT_OCTREE, 19, 0x06},
        {"grid", AS_STRUCT_GRID, AS_BUILDER_GRID, AS_LAYOUT_GRID, 0, 0x02},
        {"grid_zstd", AS_STRUCT_GRID, AS_BUILDER_GRID, AS_LAYOUT_GRID, 19, 0x03},
    };
    as_mesh_t *mesh = tiny_mesh();
    for (size_t i = 0; i < sizeof seeds / sizeof seeds[0]; ++i) {
        as_build_args_t args;
        as_build_args_default(&args);
        args.structure = seeds[i].kind;
        args.builder = seeds[i].builder;
        args.layout = seeds[i].layout;
        args.max_leaf_size = 2;
        args.thread_count = 1;
        as_structure_t *s = as_structure_build(mesh, &args);
        if (!s) die(seeds[i].name);
        void *bytes;
        size_t size;
        if (fuzz_structure_bytes(s, seeds[i].level, &bytes, &size) != AS_OK) die(seeds[i].name);
        put("structure_trace", seeds[i].name, seeds[i].param, bytes, size);
        free(bytes);
        as_structure_release(s);
    }
    as_mesh_release(mesh);
}

int main(int argc, char **argv)
{
    if (argc != 2) {
        fprintf(stderr, "usage: make_seed_corpus CORPUS_ROOT (fuzz/corpus)\n");
        return 1;
    }
    root = argv[1];
    asf_seeds();
    ray_seeds();
    structure_seeds();
    return 0;
}
