/* Fuzzes what stands between an untrusted .asf file and the traversal:
 * as_structure_load_memory, as_structure_validate, then a CPU trace.
 *
 * Asserts, through ASan and UBSan: loading and validation never read outside
 * the file or their own allocations, overflow or leak, and a refusal sets an
 * error with a message; on every file validation accepts, statistics and a
 * CPU trace of a fixed set of rays (axis-parallel, with -0 components, from
 * inside and outside the bounds, grazing a face, clipped by tmin and tmax)
 * finish without a fault, an endless loop (libFuzzer's -timeout) or a hit
 * outside the ray's interval, for closest and any hit. Where the layout
 * converts (BVH child <-> own bounds, KD with <-> without ropes; the wide
 * BVH converts to nothing) the
 * conversion must validate, give identical hits, survive being written and
 * read back, and convert back to a structure with identical hits (the same
 * record, or the same distance on another triangle: a tie, which the order
 * of traversal decides).
 *
 * Which triangle a ray meets first is only defined where every leaf or cell
 * a triangle crosses holds it. Validation proves that for a BVH whose leaf
 * boxes contain their triangles (every builder but SBVH; for the wide BVH,
 * the decoded boxes of the leaf and of every node above it), not for the
 * others, whose leaves and cells need only overlap the triangles they hold
 * (SBVH, KD, BIH, octree, grid): a damaged one may leave part of a triangle
 * in no leaf that holds it, and then the layouts, and closest and any hit,
 * may disagree about that part; safely, which is what is asserted. For them
 * a conversion is traced but not compared, while reading it back and
 * converting it back, which keep the tree and its order, must still give
 * identical hits.
 *
 * The first byte carves the parameters, the rest is the file:
 *   bit 0  verify section checksums (otherwise mutations of the sections
 *          reach validation instead of stopping at the hash);
 *   bit 1  rewrite the table checksum first, so that mutations of the
 *          table reach the entry checks;
 *   bit 2  trace with the double-precision intersector;
 *   bit 3  place the file 8 bytes into its buffer, off the 64-byte
 *          alignment, so that raw sections are copied, not used in place. */
#include "as/as.h"
#include "as_internal.h"
#include "fuzz_structure_bytes.h"

#include <math.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

int LLVMFuzzerTestOneInput(const uint8_t *data, size_t size);

#define RAY_COUNT 24

static void fail(const char *what)
{
    fprintf(stderr, "fuzz_structure_trace: %s (%s)\n", what, as_get_error_message());
    abort();
}

static int finite3(const float v[3]) { return isfinite(v[0]) && isfinite(v[1]) && isfinite(v[2]); }

/* The rays, from the structure's bounds where they are finite (a file may
 * claim any bounds; validation decides whether they bound its triangles),
 * else around the unit cube the seeds are built in. */
static void make_rays(const as_structure_stats_t *st, as_ray_t rays[RAY_COUNT])
{
    float lo[3] = {0.0f, 0.0f, 0.0f}, hi[3] = {1.0f, 1.0f, 1.0f};
    if (finite3(st->bounds_lo) && finite3(st->bounds_hi)) {
        memcpy(lo, st->bounds_lo, sizeof lo);
        memcpy(hi, st->bounds_hi, sizeof hi);
    }
    float c[3], e[3];
    for (int k = 0; k < 3; ++k) {
        c[k] = 0.5f * lo[k] + 0.5f * hi[k];
        e[k] = 0.5f * hi[k] - 0.5f * lo[k];
        if (!isfinite(c[k]) || !isfinite(e[k]) || e[k] < 0.0f) c[k] = 0.0f, e[k] = 1.0f;
        if (e[k] == 0.0f) e[k] = 1.0f;
    }
    const float inf = INFINITY, nz = -0.0f;
    int n = 0;
    /* From the centre along each axis, the other components +0 and -0. */
    for (int k = 0; k < 3; ++k) {
        for (int sign = -1; sign <= 1; sign += 2) {
            as_ray_t r = {{c[0], c[1], c[2]}, 0.0f, {k % 2 ? nz : 0.0f, nz, 0.0f}, inf};
            r.dir[k] = (float)sign;
            rays[n++] = r;
        }
    }
    /* Diagonals from outside a corner, towards the centre and away. */
    rays[n++] = (as_ray_t){{lo[0] - e[0], lo[1] - e[1], lo[2] - e[2]}, 0.0f, {e[0], e[1], e[2]}, inf};
    rays[n++] = (as_ray_t){{hi[0] + e[0], hi[1] + e[1], hi[2] + e[2]}, 0.0f, {-e[0], -e[1], -e[2]}, inf};
    rays[n++] = (as_ray_t){{lo[0] - e[0], lo[1] - e[1], lo[2] - e[2]}, 0.0f, {-1.0f, -1.0f, -1.0f}, inf};
    /* Axis-parallel from outside, in the planes of the box's faces. */
    rays[n++] = (as_ray_t){{lo[0] - e[0], lo[1], c[2]}, 0.0f, {1.0f, 0.0f, nz}, inf};
    rays[n++] = (as_ray_t){{c[0], hi[1], hi[2] + e[2]}, 0.0f, {nz, nz, -1.0f}, inf};
    rays[n++] = (as_ray_t){{hi[0], hi[1] + e[1], hi[2]}, 0.0f, {0.0f, -1.0f, 0.0f}, inf};
    /* Through the centre from outside, every axis. */
    rays[n++] = (as_ray_t){{c[0], c[1], lo[2] - e[2]}, 0.0f, {0.0f, 0.0f, 1.0f}, inf};
    rays[n++] = (as_ray_t){{hi[0] + e[0], c[1], c[2]}, 0.0f, {-1.0f, nz, nz}, inf};
    rays[n++] = (as_ray_t){{c[0], lo[1] - e[1], c[2]}, 0.0f, {nz, 1.0f, 0.0f}, inf};
    /* Nearly axis-parallel: huge reciprocals. */
    rays[n++] = (as_ray_t){{c[0], c[1], c[2]}, 0.0f, {1e-30f, 1.0f, -1e-38f}, inf};
    rays[n++] = (as_ray_t){{lo[0] - e[0], c[1], c[2]}, 0.0f, {1.0f, 1e-20f, -1e-20f}, inf};
    /* An interval: starts past the centre, ends before the far side. */
    rays[n++] = (as_ray_t){{c[0], c[1], lo[2] - e[2]}, 1.5f * e[2], {0.0f, 0.0f, 1.0f}, 2.5f * e[2]};
    /* An empty interval and a zero-length one. */
    rays[n++] = (as_ray_t){{c[0], c[1], c[2]}, 1.0f, {0.0f, 1.0f, 0.0f}, 0.5f};
    rays[n++] = (as_ray_t){{c[0], c[1], c[2]}, 0.0f, {0.0f, 0.0f, 1.0f}, 0.0f};
    /* Oblique rays through the inside, from a face's centre. */
    rays[n++] = (as_ray_t){{c[0], c[1], lo[2]}, 0.0f, {0.3f, -0.2f, 1.0f}, inf};
    rays[n++] = (as_ray_t){{lo[0], c[1], c[2]}, 0.0f, {1.0f, 0.7f, nz}, inf};
    rays[n++] = (as_ray_t){{c[0] + 0.25f * e[0], c[1] - 0.25f * e[1], c[2]}, 0.0f, {-0.5f, 0.25f, 1.0f}, inf};
    (void)n;
}

static void trace(const as_structure_t *s, const as_ray_t *rays, as_hit_t *hits, int any_hit, int precise)
{
    as_trace_args_t args;
    as_trace_args_default(&args);
    args.device = AS_DEVICE_CPU;
    args.thread_count = 1;
    args.any_hit = any_hit;
    args.intersector = precise ? AS_INTERSECTOR_WATERTIGHT_DOUBLE : AS_INTERSECTOR_WATERTIGHT;
    if (as_trace(s, rays, RAY_COUNT, hits, &args, NULL) != AS_OK) fail("CPU trace of a valid structure failed");
    for (int i = 0; i < RAY_COUNT; ++i) {
        if (hits[i].prim == AS_NO_HIT) {
            if (hits[i].t != INFINITY) fail("a miss with a finite t");
            continue;
        }
        if (!(hits[i].t >= rays[i].tmin && hits[i].t <= rays[i].tmax)) fail("a hit outside the ray's interval");
    }
}

static void same_hits(const as_hit_t *a, const as_hit_t *b, int any_hit, const char *what)
{
    for (int i = 0; i < RAY_COUNT; ++i) {
        const int same = any_hit ? (a[i].prim == AS_NO_HIT) == (b[i].prim == AS_NO_HIT)
                                 : memcmp(&a[i], &b[i], sizeof a[i]) == 0 ||
                                       (a[i].prim != AS_NO_HIT && b[i].prim != AS_NO_HIT && a[i].t == b[i].t);
        if (!same) {
            fprintf(stderr, "ray %d: t %a prim %u u %a v %a, against t %a prim %u u %a v %a\n", i, a[i].t,
                    a[i].prim, a[i].u, a[i].v, b[i].t, b[i].prim, b[i].u, b[i].v);
            fail(what);
        }
    }
}

/* Whether validation proves that every triangle lies in each leaf holding it
 * (see the comment at the top). */
static int hits_defined(const as_structure_stats_t *st)
{
    return st->structure == AS_STRUCT_BVH && st->builder != AS_BUILDER_BVH_SBVH;
}

static as_layout_t other_layout(as_layout_t layout)
{
    switch (layout) {
    case AS_LAYOUT_BVH2_CHILD_BOUNDS: return AS_LAYOUT_BVH2_OWN_BOUNDS;
    case AS_LAYOUT_BVH2_OWN_BOUNDS: return AS_LAYOUT_BVH2_CHILD_BOUNDS;
    case AS_LAYOUT_KD_STANDARD: return AS_LAYOUT_KD_ROPES;
    case AS_LAYOUT_KD_ROPES: return AS_LAYOUT_KD_STANDARD;
    default: return AS_LAYOUT_DEFAULT;
    }
}

/* Conversion to the other layout and back, and the converted structure
 * written and read back: every step validates and traces identically. */
static void check_conversion(const as_structure_t *s, const as_structure_stats_t *st, const as_ray_t *rays,
                             const as_hit_t *closest, const as_hit_t *any, int precise)
{
    const as_layout_t layout = st->layout, target = other_layout(layout);
    if (target == AS_LAYOUT_DEFAULT) return;
    const int compare = hits_defined(st);
    as_hit_t converted_hits[RAY_COUNT], hits[RAY_COUNT];
    as_structure_t *converted = as_structure_convert(s, target);
    if (!converted) fail("conversion of a valid structure failed");
    if (as_structure_validate(converted) != AS_OK) fail("a converted structure does not validate");
    trace(converted, rays, hits, 1, precise);
    if (compare) same_hits(any, hits, 1, "the converted structure's any hits differ");
    trace(converted, rays, converted_hits, 0, precise);
    if (compare) same_hits(closest, converted_hits, 0, "the converted structure's closest hits differ");

    /* Written and read back, the same tree: the same hits, SBVH or not. */
    void *bytes = NULL;
    size_t size = 0;
    if (fuzz_structure_bytes(converted, 0, &bytes, &size) != AS_OK) fail("the converted structure cannot be written");
    as_structure_t *reread = as_structure_load_memory(bytes, size, "converted.asf", NULL);
    if (!reread) fail("the converted structure, written, does not load");
    if (as_structure_validate(reread) != AS_OK) fail("the converted structure, read back, does not validate");
    trace(reread, rays, hits, 0, precise);
    same_hits(converted_hits, hits, 0, "the converted structure's closest hits differ after reading it back");
    as_structure_release(reread);
    free(bytes);

    as_structure_t *back = as_structure_convert(converted, layout);
    if (!back) fail("conversion back to the original layout failed");
    if (as_structure_validate(back) != AS_OK) fail("a structure converted back does not validate");
    trace(back, rays, hits, 0, precise);
    same_hits(closest, hits, 0, "the structure converted back gives other closest hits");
    as_structure_release(back);
    as_structure_release(converted);
}

int LLVMFuzzerTestOneInput(const uint8_t *data, size_t size)
{
    if (size < 1) return 0;
    const uint8_t params = data[0];
    ++data;
    --size;

    /* A private copy, since the table checksum may be rewritten. Aligned
     * to 64 bytes, as a mapped file is, raw sections are used in place;
     * shifted, they are copied, and the buffer ends right after the file so
     * that ASan sees a read one past the end. */
    const int shifted = (params & 8) != 0;
    uint8_t *buffer = shifted ? malloc(8 + size) : aligned_alloc(64, (size + 64) / 64 * 64);
    if (!buffer) return 0;
    uint8_t *copy = buffer + (shifted ? 8 : 0);
    if (size) memcpy(copy, data, size);

    if ((params & 2) && size >= sizeof(asf_header_t)) {
        asf_header_t h;
        memcpy(&h, copy, sizeof h);
        uint64_t bytes, end;
        if (h.section_count <= ASF_MAX_SECTIONS && as_mul_u64(h.section_count, h.section_entry_size, &bytes) &&
            as_add_u64(h.section_table_offset, bytes, &end) && end <= size) {
            h.table_checksum = as_hash64(copy + h.section_table_offset, (size_t)bytes);
            memcpy(copy, &h, sizeof h);
        }
    }

    as_load_args_t load;
    as_load_args_default(&load);
    load.verify_checksums = params & 1;
    as_clear_error();
    as_structure_t *s = as_structure_load_memory(copy, size, "fuzz.asf", &load);
    if (!s) {
        if (as_get_error() == AS_OK || as_get_error_message()[0] == '\0') fail("refusal without error");
        free(buffer);
        return 0;
    }
    as_clear_error();
    if (as_structure_validate(s) != AS_OK) {
        if (as_get_error() == AS_OK || as_get_error_message()[0] == '\0') fail("invalid structure without error");
        as_structure_release(s);
        free(buffer);
        return 0;
    }

    as_structure_stats_t st;
    if (as_structure_get_stats(s, &st) != AS_OK) fail("statistics of a valid structure failed");
    as_ray_t rays[RAY_COUNT];
    make_rays(&st, rays);
    const int precise = (params & 4) != 0;
    as_hit_t closest[RAY_COUNT], any[RAY_COUNT];
    trace(s, rays, closest, 0, precise);
    trace(s, rays, any, 1, precise);
    /* Whatever any hit reports, it reports a hit exactly when there is one. */
    if (hits_defined(&st)) same_hits(closest, any, 1, "any hit and closest hit disagree on hit or miss");
    check_conversion(s, &st, rays, closest, any, precise);

    as_structure_release(s);
    free(buffer);
    return 0;
}
