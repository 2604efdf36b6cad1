/* Loading from a mapped region: as_structure_load_memory over an mmap of a
 * saved file reads the uncompressed sections in place (the structure's
 * section pointers lie inside the caller's mapping), decompresses zstd
 * sections into memory of its own, copies a section that is not 64-byte
 * aligned in the caller's buffer, and in every case traces exactly as
 * as_structure_load of the same file does. */
#include "reference.h"
#include "structure.h"
#include "test_util.h"

#include <fcntl.h>
#include <sys/mman.h>
#include <sys/stat.h>

static as_mesh_t *bunny(void)
{
    as_mesh_t *m = as_mesh_import(AS_SOURCE_DIR "/scenes/bunny.drc");
    if (!m) fprintf(stderr, "  import failed: %s\n", as_get_error_message());
    return m;
}

static int inside(const void *p, const void *base, size_t size)
{
    return (const char *)p >= (const char *)base && (const char *)p < (const char *)base + size;
}

/* The sections the layout's traversal reads, counted by where they are:
 * raw ones must be in the caller's bytes, zstd ones in the structure's. */
static void count_sections(const as_structure_t *s, const void *base, size_t size, int *in_place, int *elsewhere,
                           int *misplaced)
{
    *in_place = *elsewhere = *misplaced = 0;
    for (uint32_t i = 0; i < s->section_count; ++i) {
        if (s->sections[i].bytes == 0) continue;
        const int here = inside(s->sections[i].data, base, size);
        const int compressed = (s->sections[i].flags & ASF_SECTION_ZSTD) != 0;
        if (here) ++*in_place;
        else ++*elsewhere;
        if (here == compressed) ++*misplaced;
    }
}

static as_hit_t *trace(const as_structure_t *s, const as_ray_t *rays, size_t n)
{
    as_trace_args_t ta;
    as_trace_args_default(&ta);
    ta.device = AS_DEVICE_CPU;
    as_hit_t *hits = calloc(n, sizeof *hits);
    if (as_trace(s, rays, n, hits, &ta, NULL) != AS_OK) {
        fprintf(stderr, "  trace failed: %s\n", as_get_error_message());
        free(hits);
        return NULL;
    }
    return hits;
}

/* Saves the structure (raw or zstd), maps the file, loads it both ways and
 * checks where the sections are and that the hits are the same bits. */
static void check_mapped(const char *what, const as_structure_t *built, int compression_level, const as_ray_t *rays,
                         size_t n)
{
    char path[512];
    snprintf(path, sizeof path, "%s/test_load_mapped_%s.asf", AS_BINARY_DIR, what);
    as_save_args_t sa;
    as_save_args_default(&sa);
    sa.compression_level = compression_level;
    CHECK_EQ_INT(as_structure_save(built, path, &sa), AS_OK);
    const int fd = open(path, O_RDONLY);
    CHECK(fd >= 0);
    struct stat st;
    CHECK(fd >= 0 && fstat(fd, &st) == 0);
    const size_t size = (size_t)st.st_size;
    void *map = fd >= 0 ? mmap(NULL, size, PROT_READ, MAP_PRIVATE, fd, 0) : MAP_FAILED;
    CHECK(map != MAP_FAILED);
    if (fd >= 0) close(fd); /* the mapping outlives the descriptor */
    as_structure_t *from_file = as_structure_load(path, NULL);
    as_structure_t *from_map = map != MAP_FAILED ? as_structure_load_memory(map, size, path, NULL) : NULL;
    CHECK(from_file != NULL);
    CHECK(from_map != NULL);
    if (from_file && from_map) {
        int in_place, elsewhere, misplaced;
        count_sections(from_map, map, size, &in_place, &elsewhere, &misplaced);
        fprintf(stderr, "  %s: %d sections read in the mapping, %d in memory of the structure's own\n", what,
                in_place, elsewhere);
        CHECK_EQ_INT(misplaced, 0);
        if (compression_level == 0) CHECK(in_place >= 2 && elsewhere == 0);
        else CHECK(elsewhere >= 1); /* zstd stores incompressible sections raw */
        as_hit_t *a = trace(from_file, rays, n), *b = trace(from_map, rays, n);
        CHECK(a && b && memcmp(a, b, sizeof *a * n) == 0);
        size_t hit = 0;
        for (size_t i = 0; a && i < n; ++i) hit += a[i].prim != AS_NO_HIT;
        CHECK(hit > n / 4); /* the rays do meet the bunny */
        free(a);
        free(b);
    }
    as_structure_release(from_map);
    as_structure_release(from_file);
    if (map != MAP_FAILED) munmap(map, size);
    remove(path);
}

static void mapped_file_is_read_in_place_and_traces_as_loaded(void)
{
    as_mesh_t *m = bunny();
    CHECK(m != NULL);
    if (!m) return;
    const size_t n = 20000;
    as_ray_t *rays = malloc(sizeof *rays * n);
    ref_make_scene_rays(m, n, 42, rays);
    const as_layout_t layouts[] = {AS_LAYOUT_BVH2_CHILD_BOUNDS, AS_LAYOUT_BVH2_OWN_BOUNDS, AS_LAYOUT_KD_ROPES};
    const as_structure_kind_t kinds[] = {AS_STRUCT_BVH, AS_STRUCT_BVH, AS_STRUCT_KD};
    for (int k = 0; k < 3; ++k) {
        as_build_args_t ba;
        as_build_args_default(&ba);
        ba.structure = kinds[k];
        ba.layout = layouts[k];
        as_structure_t *s = as_structure_build(m, &ba);
        CHECK(s != NULL);
        if (!s) continue;
        char what[64];
        snprintf(what, sizeof what, "%s-raw", as_layout_name(layouts[k]));
        check_mapped(what, s, 0, rays, n);
        snprintf(what, sizeof what, "%s-zstd", as_layout_name(layouts[k]));
        check_mapped(what, s, 3, rays, n);
        as_structure_release(s);
    }
    free(rays);
    as_mesh_release(m);
}

/* A buffer that puts the sections off their 64-byte boundary: they are
 * copied, and the structure is still right. */
static void misaligned_buffer_is_copied(void)
{
    as_mesh_t *m = bunny();
    as_structure_t *s = m ? as_structure_build(m, NULL) : NULL;
    CHECK(s != NULL);
    const char *path = AS_BINARY_DIR "/test_load_mapped_misaligned.asf";
    if (s && as_structure_save(s, path, NULL) == AS_OK) {
        unsigned char *data = NULL;
        size_t size = 0;
        CHECK(test_read_file(path, &data, &size));
        unsigned char *shifted = aligned_alloc(64, size + 64);
        memcpy(shifted + 8, data, size);
        as_structure_t *aligned = as_structure_load_memory(data, size, path, NULL);
        as_structure_t *moved = as_structure_load_memory(shifted + 8, size, path, NULL);
        CHECK(aligned != NULL && moved != NULL);
        if (aligned && moved) {
            int in_place, elsewhere, misplaced;
            count_sections(moved, shifted + 8, size, &in_place, &elsewhere, &misplaced);
            CHECK_EQ_INT(in_place, 0);
            CHECK(elsewhere >= 2);
            const size_t n = 5000;
            as_ray_t *rays = malloc(sizeof *rays * n);
            ref_make_scene_rays(m, n, 7, rays);
            as_hit_t *a = trace(aligned, rays, n), *b = trace(moved, rays, n);
            CHECK(a && b && memcmp(a, b, sizeof *a * n) == 0);
            free(a);
            free(b);
            free(rays);
        }
        as_structure_release(aligned);
        as_structure_release(moved);
        free(shifted);
        free(data);
        remove(path);
    }
    as_structure_release(s);
    as_mesh_release(m);
}

int main(void)
{
    RUN_TEST(mapped_file_is_read_in_place_and_traces_as_loaded);
    RUN_TEST(misaligned_buffer_is_copied);
    TEST_EXIT();
}
