/* Meshes: as_mesh_create and as_mesh_import over small fixtures in
 * tests/data (every way a file is refused, with its code and message; what
 * is kept and counted), and, with the argument "scenes", over the real scenes
 * of ../shared/scenes, where every face of the file must survive in order. */
#define _POSIX_C_SOURCE 200809L
#include "as/as.h"
#include "as_internal.h"
#include "mesh.h"
#include "test_util.h"

#include <math.h>
#include <stdint.h>
#include <time.h>

#include <zstd.h>

#ifndef AS_SOURCE_DIR
#define AS_SOURCE_DIR "."
#endif

static const char *data_path(const char *file)
{
    static char buf[4][512];
    static int next;
    char *p = buf[next++ % 4];
    snprintf(p, sizeof buf[0], "%s/tests/data/%s", AS_SOURCE_DIR, file);
    return p;
}

/* Imports a fixture that must be refused; checks the code and that the
 * message names the file and says what is wrong. */
static void check_refused(const char *file, as_error_t code, const char *problem)
{
    const char *path = data_path(file);
    as_clear_error();
    as_mesh_t *m = as_mesh_import(path);
    CHECK(m == NULL);
    as_mesh_release(m);
    CHECK_EQ_INT(as_get_error(), code);
    CHECK_STR_CONTAINS(as_get_error_message(), path);
    CHECK_STR_CONTAINS(as_get_error_message(), problem);
}

static as_mesh_t *import_ok(const char *path, as_mesh_info_t *info)
{
    as_clear_error();
    as_mesh_t *m = as_mesh_import(path);
    if (!m) {
        fprintf(stderr, "import of %s failed: %s: %s\n", path, as_error_name(as_get_error()),
                as_get_error_message());
        ++test_failures;
        memset(info, 0, sizeof *info);
        return NULL;
    }
    as_mesh_get_info(m, info);
    return m;
}

static void check_triangle(const as_mesh_t *m, uint32_t t, uint32_t a, uint32_t b, uint32_t c)
{
    const uint32_t *idx = as_mesh_indices(m) + (size_t)t * 3;
    CHECK_EQ_INT(idx[0], a);
    CHECK_EQ_INT(idx[1], b);
    CHECK_EQ_INT(idx[2], c);
}

/* ------------------------------------------------------------------------ */
/* as_mesh_create */

static const float tri_positions[] = {0, 0, 0, 1, 0, 0, 0, 1, 0};

static void create_copies_arrays_and_counts_nothing_degenerate(void)
{
    float pos[9];
    uint32_t idx[3] = {0, 1, 2};
    memcpy(pos, tri_positions, sizeof pos);
    as_mesh_t *m = as_mesh_create(3, pos, 1, idx);
    CHECK(m != NULL);
    if (!m) return;
    pos[0] = 5;
    idx[0] = 2;
    CHECK(as_mesh_positions(m)[0] == 0.0f);
    CHECK_EQ_INT(as_mesh_indices(m)[0], 0);
    as_mesh_info_t info;
    as_mesh_get_info(m, &info);
    CHECK_EQ_INT(info.vertex_count, 3);
    CHECK_EQ_INT(info.triangle_count, 1);
    CHECK_EQ_U64(info.faces_in_file, 1);
    CHECK_EQ_INT(info.polygon_faces, 0);
    CHECK_EQ_INT(info.degenerate_count, 0);
    CHECK(!info.has_normals && !info.has_uvs && !info.has_materials);
    CHECK(as_mesh_normals(m) == NULL && as_mesh_uvs(m) == NULL && as_mesh_material_ids(m) == NULL);
    as_mesh_release(m);
}

static void create_rejects_empty_mesh(void)
{
    as_clear_error();
    CHECK(as_mesh_create(3, tri_positions, 0, NULL) == NULL);
    CHECK_EQ_INT(as_get_error(), AS_ERROR_INVALID_MESH);
    CHECK(strcmp(as_get_error_message(), "as_mesh_create: no triangles") == 0);
}

static void create_rejects_non_finite_coordinate_naming_vertex(void)
{
    const float pos[] = {0, 0, 0, NAN, 0, 1, 0, 1, 0};
    const uint32_t idx[] = {0, 1, 2};
    as_clear_error();
    CHECK(as_mesh_create(3, pos, 1, idx) == NULL);
    CHECK_EQ_INT(as_get_error(), AS_ERROR_INVALID_MESH);
    CHECK_STR_CONTAINS(as_get_error_message(),
                       "as_mesh_create: vertex 1 has a non-finite coordinate (nan, 0, 1)");
    const float inf[] = {0, 0, 0, 1, 0, 0, 0, INFINITY, 0};
    CHECK(as_mesh_create(3, inf, 1, idx) == NULL);
    CHECK_STR_CONTAINS(as_get_error_message(), "vertex 2 has a non-finite coordinate (0, inf, 0)");
}

static void create_rejects_index_out_of_range_naming_triangle(void)
{
    const uint32_t idx[] = {0, 1, 2, 0, 900, 2};
    as_clear_error();
    CHECK(as_mesh_create(3, tri_positions, 2, idx) == NULL);
    CHECK_EQ_INT(as_get_error(), AS_ERROR_INVALID_MESH);
    CHECK(strcmp(as_get_error_message(),
                 "as_mesh_create: triangle 1 refers to vertex 900 but the mesh has 3 vertices") == 0);
}

static void create_rejects_null_arrays(void)
{
    const uint32_t idx[] = {0, 1, 2};
    as_clear_error();
    CHECK(as_mesh_create(3, NULL, 1, idx) == NULL);
    CHECK_EQ_INT(as_get_error(), AS_ERROR_INVALID_ARGUMENT);
    CHECK(as_mesh_create(3, tri_positions, 1, NULL) == NULL);
    CHECK_EQ_INT(as_get_error(), AS_ERROR_INVALID_ARGUMENT);
}

static void release_and_accessors_accept_null(void)
{
    as_mesh_release(NULL);
    CHECK(as_mesh_positions(NULL) == NULL);
    as_mesh_info_t info;
    memset(&info, 0xff, sizeof info);
    as_mesh_get_info(NULL, &info);
    CHECK_EQ_INT(info.triangle_count, 0);
}

static void degenerate_means_exactly_zero_cross_product_or_repeated_index(void)
{
    const float pos[] = {0, 0, 0,  1, 0, 0,  2, 0, 0,      /* collinear */
                         0, 1, 0,  1e-3f, 1e-3f, 0,         /* small but not zero */
                         0, 0, 1};
    const uint32_t idx[] = {0, 1, 2,   /* collinear: zero area */
                            0, 3, 3,   /* repeated index */
                            0, 1, 4,   /* tiny, has a normal */
                            0, 1, 3,   /* proper */
                            5, 5, 5};  /* one point */
    as_mesh_t *m = as_mesh_create(6, pos, 5, idx);
    CHECK(m != NULL);
    if (!m) return;
    CHECK_EQ_INT(as_mesh_triangle_is_degenerate(m, 0), 1);
    CHECK_EQ_INT(as_mesh_triangle_is_degenerate(m, 1), 1);
    CHECK_EQ_INT(as_mesh_triangle_is_degenerate(m, 2), 0);
    CHECK_EQ_INT(as_mesh_triangle_is_degenerate(m, 3), 0);
    CHECK_EQ_INT(as_mesh_triangle_is_degenerate(m, 4), 1);
    as_mesh_info_t info;
    as_mesh_get_info(m, &info);
    CHECK_EQ_INT(info.degenerate_count, 3);
    CHECK_EQ_INT(info.triangle_count, 5);
    as_mesh_release(m);
}

/* Builders count and skip zero-area triangles by ranges of the mesh's bits:
 * a range's count is the number of triangles in it that the per-triangle
 * test calls degenerate, whatever its ends (word boundaries included). */
static void degenerate_range_counts_match_the_triangles(void)
{
    enum { N = 300 };
    float pos[3 * 4] = {0, 0, 0, 1, 0, 0, 0, 1, 0, 2, 0, 0};
    uint32_t idx[3 * N];
    uint32_t x = 12345;
    for (uint32_t i = 0; i < N; ++i) {
        x = x * 1103515245u + 12345u;
        const int zero = (x >> 16) % 3 == 0; /* about a third: collinear 0, 1, 3 */
        idx[3 * i] = 0;
        idx[3 * i + 1] = 1;
        idx[3 * i + 2] = zero ? 3 : 2;
    }
    as_mesh_t *m = as_mesh_create(4, pos, N, idx);
    CHECK(m != NULL);
    if (!m) return;
    const uint32_t ends[] = {0, 1, 2, 63, 64, 65, 127, 128, 129, 200, 255, 256, 299, 300};
    const size_t ne = sizeof ends / sizeof ends[0];
    uint32_t total = 0;
    for (uint32_t i = 0; i < N; ++i) total += (uint32_t)as_mesh_triangle_is_degenerate(m, i);
    as_mesh_info_t info;
    as_mesh_get_info(m, &info);
    CHECK_EQ_INT(info.degenerate_count, total);
    CHECK(total > N / 5 && total < N / 2);
    int wrong = 0;
    for (size_t a = 0; a < ne; ++a)
        for (size_t b = a; b < ne; ++b) {
            uint32_t expect = 0;
            for (uint32_t i = ends[a]; i < ends[b]; ++i) expect += (uint32_t)as_mesh_triangle_is_degenerate(m, i);
            if (as_mesh_degenerate_in_range(m, ends[a], ends[b]) != expect) {
                fprintf(stderr, "     [%u, %u): %u degenerate, range count %u\n", ends[a], ends[b], expect,
                        as_mesh_degenerate_in_range(m, ends[a], ends[b]));
                wrong++;
            }
        }
    CHECK_EQ_INT(wrong, 0);
    as_mesh_release(m);
}

static void hash_chains_positions_then_indices(void)
{
    const uint32_t a[] = {0, 1, 2}, b[] = {0, 2, 1};
    as_mesh_t *ma = as_mesh_create(3, tri_positions, 1, a);
    as_mesh_t *mb = as_mesh_create(3, tri_positions, 1, b);
    CHECK(ma && mb);
    if (ma && mb) {
        as_mesh_info_t ia, ib;
        as_mesh_get_info(ma, &ia);
        as_mesh_get_info(mb, &ib);
        const uint64_t want = as_hash64_seeded(a, sizeof a, as_hash64_seeded(tri_positions, sizeof tri_positions, 0));
        CHECK_EQ_U64(ia.hash, want);
        CHECK(ia.hash != ib.hash);
    }
    as_mesh_release(ma);
    as_mesh_release(mb);
}

static void bounds_cover_referenced_vertices_only(void)
{
    const float pos[] = {0, 0, 0, 1, 0, 0, 0, 2, 0, 100, 100, 100};
    const uint32_t idx[] = {0, 1, 2};
    as_mesh_t *m = as_mesh_create(4, pos, 1, idx);
    CHECK(m != NULL);
    if (!m) return;
    as_mesh_info_t info;
    as_mesh_get_info(m, &info);
    CHECK(info.bounds_lo[0] == 0 && info.bounds_lo[1] == 0 && info.bounds_lo[2] == 0);
    CHECK(info.bounds_hi[0] == 1 && info.bounds_hi[1] == 2 && info.bounds_hi[2] == 0);
    as_mesh_release(m);
}

/* ------------------------------------------------------------------------ */
/* Import: refusals */

static void import_refuses_missing_file_as_file_not_found(void)
{
    const char *path = data_path("no_such_mesh.ply");
    as_clear_error();
    CHECK(as_mesh_import(path) == NULL);
    CHECK_EQ_INT(as_get_error(), AS_ERROR_FILE_NOT_FOUND);
    char want[600];
    snprintf(want, sizeof want, "%s: no such file", path);
    CHECK(strcmp(as_get_error_message(), want) == 0);
}

static void import_refuses_unknown_extension_as_unsupported(void)
{
    check_refused("points.xyz", AS_ERROR_UNSUPPORTED,
                  "unknown mesh format '.xyz' (known: .obj .ply .off .stl .drc, optionally .zst)");
}

static void import_refuses_non_finite_obj_vertex(void)
{
    check_refused("nan.obj", AS_ERROR_INVALID_MESH, "vertex 3 (line 4) has a non-finite coordinate (nan, 0, 1)");
}

static void import_refuses_index_out_of_range(void)
{
    check_refused("index_out_of_range.off", AS_ERROR_INVALID_MESH,
                  "face 1 refers to vertex 900 but the file has 3 vertices");
}

static void import_refuses_face_with_two_corners(void)
{
    check_refused("short_face.off", AS_ERROR_INVALID_MESH, "face 1 has 2 corners");
}

static void import_refuses_file_without_triangles(void)
{
    check_refused("empty.obj", AS_ERROR_INVALID_MESH, "no triangles");
}

static void import_refuses_garbage_ply_header(void)
{
    check_refused("garbage.ply", AS_ERROR_PARSE, "line 3: unknown header keyword");
}

/* OpenMesh's readers would loop for hours or forever on these. */
static void import_refuses_unreadable_header_count_and_glued_corners(void)
{
    check_refused("bad_element_count.ply", AS_ERROR_PARSE, "line 7: 'element' takes a name and a count");
    check_refused("glued_corners.off", AS_ERROR_PARSE,
                  "cannot parse as OFF (line 6: face 0 must be its corner count and exactly that many vertex indices)");
    /* A number left over on a face line would be the next face's count. */
    check_refused("off_face_number_left_over.off", AS_ERROR_PARSE,
                  "cannot parse as OFF (line 7: face 0 must be its corner count and exactly that many vertex indices)");
}

/* OpenMesh's OFF reader takes the counts and the coordinates number by
 * number across lines: a counts line without its edge count, or a vertex
 * line a number short, would shift every number after it, and a corner
 * index read as a corner count had it allocate gigabytes. The line is named
 * instead. */
static void import_refuses_off_lines_shorter_than_the_reader_reads(void)
{
    check_refused("off_counts_line_two_numbers.off", AS_ERROR_PARSE,
                  "cannot parse as OFF (line 2: the counts line must hold three counts: vertices, faces, edges)");
    check_refused("off_vertex_line_short.off", AS_ERROR_PARSE,
                  "cannot parse as OFF (line 4: vertex 1 must begin with 3 numbers)");
    check_refused("off_normal_short.off", AS_ERROR_PARSE,
                  "cannot parse as OFF (line 4: vertex 1 must begin with 6 numbers)");
}

/* An OBJ face corner is its whole word: a NUL byte inside it had ended the
 * number early and the rest was dropped without a word; a number beyond 64
 * bits had saturated. Both are refused where they stand. */
static void import_refuses_obj_corner_that_is_not_a_whole_number(void)
{
    check_refused("obj_corner_with_nul.obj", AS_ERROR_PARSE, "line 4: cannot parse face corner '3?x9'");
    check_refused("obj_corner_overflow.obj", AS_ERROR_PARSE,
                  "line 4: cannot parse face corner '99999999999999999999'");
}

/* A PLY body is read number by number, across lines, as the format says:
 * one number too many on a vertex line makes the next number a face's
 * corner count. OpenMesh's reader would push 200 million corners past the
 * end of the data; the check names the number and what it was read as. */
static void import_refuses_ply_whose_numbers_do_not_add_up(void)
{
    check_refused("ply_vertex_line_too_long.ply", AS_ERROR_PARSE,
                  "line 12: '200000000' is not a uchar list count (face 0, vertex_indices)");
    check_refused("ply_nan_coordinate.ply", AS_ERROR_PARSE, "line 11: 'nan' is not a float (vertex 1, y)");
    check_refused("ply_more_faces_than_counted.ply", AS_ERROR_PARSE, "line 14: data after the last face");
}

/* OpenMesh reads any list but a face's corners as one number and misreads
 * everything after it, so such files are refused rather than half read. */
static void import_refuses_ply_lists_it_cannot_read(void)
{
    check_refused("ply_face_texcoord_list.ply", AS_ERROR_PARSE,
                  "line 9: a second list property in an element");
    check_refused("ply_binary_material_list.ply", AS_ERROR_PARSE,
                  "line 4: a list property other than a face's vertex_indices");
}

static void import_refuses_truncated_binary_ply(void)
{
    check_refused("truncated_binary.ply", AS_ERROR_PARSE, "the data ends in face 3 of 3");
}

/* Draco's decoder sizes its tables from the connectivity's counts before
 * decoding any of it: these 180 bytes claim 606 million faces (14 GB and
 * 37 s of the decoder's before it failed). Refused from the counts. */
static void import_refuses_draco_counts_the_file_cannot_hold(void)
{
    check_refused("draco_claims_too_many_faces.drc", AS_ERROR_PARSE,
                  "its connectivity claims 606366832 faces and 807874604 vertices, more than 180 bytes can hold");
}

/* A binary header whose 'end_header' is the file's last bytes, without a
 * newline: the body is empty, not somewhere past the end of the data. */
static void import_refuses_binary_ply_ending_at_end_header(void)
{
    check_refused("ply_binary_header_without_last_newline.ply", AS_ERROR_PARSE, "the data ends in vertex 1 of 5");
}

static void import_refuses_damaged_zstd_frame(void)
{
    check_refused("damaged.ply.zst", AS_ERROR_PARSE, "damaged zstd data");
}

static void import_refuses_truncated_zstd_frame(void)
{
    check_refused("truncated.ply.zst", AS_ERROR_PARSE, "damaged zstd data (truncated frame)");
}

/* ------------------------------------------------------------------------ */
/* Import: what is kept */

static void obj_quads_become_consecutive_fan_triangles(void)
{
    as_mesh_info_t info;
    as_mesh_t *m = import_ok(data_path("cube.obj"), &info);
    if (!m) return;
    CHECK_EQ_INT(info.vertex_count, 8);
    CHECK_EQ_U64(info.faces_in_file, 6);
    CHECK_EQ_INT(info.triangle_count, 12);
    CHECK_EQ_INT(info.polygon_faces, 6);
    CHECK_EQ_INT(info.degenerate_count, 0);
    CHECK(!info.has_normals && !info.has_uvs && !info.has_materials);
    /* f 1 4 3 2 -> (0 3 2) (0 2 1); f 5 6 7 8 -> (4 5 6) (4 6 7) */
    check_triangle(m, 0, 0, 3, 2);
    check_triangle(m, 1, 0, 2, 1);
    check_triangle(m, 2, 4, 5, 6);
    check_triangle(m, 3, 4, 6, 7);
    CHECK(info.bounds_lo[0] == 0 && info.bounds_hi[2] == 1);
    as_mesh_release(m);
}

static void obj_keeps_faces_with_repeated_corners_normals_uvs_and_materials(void)
{
    as_mesh_info_t info;
    as_mesh_t *m = import_ok(data_path("attributes.obj"), &info);
    if (!m) return;
    CHECK_EQ_INT(info.vertex_count, 5);
    CHECK_EQ_U64(info.faces_in_file, 5);
    CHECK_EQ_INT(info.triangle_count, 8);  /* 1 + 1 + 3 (pentagon) + 1 + 2 */
    CHECK_EQ_INT(info.polygon_faces, 2);
    CHECK_EQ_INT(info.degenerate_count, 2);
    CHECK(info.has_normals && info.has_uvs && info.has_materials);
    check_triangle(m, 2, 0, 1, 2); /* the pentagon's fan */
    check_triangle(m, 3, 0, 2, 4);
    check_triangle(m, 4, 0, 4, 3);
    check_triangle(m, 5, 0, 1, 1); /* f 1 2 2, which OpenMesh alone drops */
    check_triangle(m, 6, 0, 1, 1); /* f -5 -4 -4 -3 */
    check_triangle(m, 7, 0, 1, 2);
    /* Materials number usemtl names in order of first use; 0 is none. */
    const uint32_t want_mat[8] = {1, 2, 2, 2, 2, 1, 1, 1};
    for (int t = 0; t < 8 && as_mesh_material_ids(m); ++t)
        CHECK_EQ_INT(as_mesh_material_ids(m)[t], want_mat[t]);
    if (as_mesh_normals(m)) CHECK(as_mesh_normals(m)[3 * 4 + 2] == 1.0f);
    if (as_mesh_uvs(m)) CHECK(as_mesh_uvs(m)[2 * 4] == 0.5f && as_mesh_uvs(m)[2 * 4 + 1] == 1.0f);
    as_mesh_release(m);
}

/* A COFF file's colours follow the coordinates of a vertex and the corners
 * of a face on the same line: the reader takes them from there, and the
 * checks before it let them be. */
static void coff_colours_after_corners_are_read_past(void)
{
    as_mesh_info_t info;
    as_mesh_t *m = import_ok(data_path("coff_face_colours.off"), &info);
    if (m) {
        CHECK_EQ_U64(info.triangle_count, 1);
        CHECK_EQ_U64(info.vertex_count, 3);
        check_triangle(m, 0, 0, 1, 2);
    }
    as_mesh_release(m);
}

static void off_polygon_is_fanned_and_normals_kept_only_when_present(void)
{
    as_mesh_info_t info;
    as_mesh_t *m = import_ok(data_path("tri.off"), &info);
    if (m) {
        CHECK_EQ_U64(info.faces_in_file, 2);
        CHECK_EQ_INT(info.triangle_count, 3);
        CHECK_EQ_INT(info.polygon_faces, 1);
        check_triangle(m, 1, 0, 1, 3);
        check_triangle(m, 2, 0, 3, 2);
        CHECK(!info.has_normals && !info.has_uvs);
    }
    as_mesh_release(m);
    m = import_ok(data_path("tri_normals.off"), &info);
    if (m) {
        CHECK(info.has_normals);
        CHECK_EQ_INT(info.triangle_count, 1);
        if (as_mesh_normals(m)) CHECK(as_mesh_normals(m)[2] == 1.0f);
    }
    as_mesh_release(m);
}

static void compressed_off_reads_like_uncompressed(void)
{
    as_mesh_info_t plain, packed;
    as_mesh_t *a = import_ok(data_path("tri_normals.off"), &plain);
    as_mesh_t *b = import_ok(data_path("tri_normals.off.zst"), &packed);
    if (a && b) {
        CHECK_EQ_U64(packed.hash, plain.hash);
        CHECK(packed.has_normals);
    }
    as_mesh_release(a);
    as_mesh_release(b);
}

static void extension_is_matched_without_case(void)
{
    as_mesh_info_t info;
    as_mesh_t *m = import_ok(data_path("upper_case.OFF"), &info);
    if (m) CHECK_EQ_INT(info.triangle_count, 3);
    as_mesh_release(m);
}

static void ply_keeps_zero_area_and_repeated_index_faces_in_order(void)
{
    as_mesh_info_t info;
    as_mesh_t *m = import_ok(data_path("degenerate.ply"), &info);
    if (!m) return;
    CHECK_EQ_INT(info.vertex_count, 4);
    CHECK_EQ_U64(info.faces_in_file, 3);
    CHECK_EQ_INT(info.triangle_count, 3);
    CHECK_EQ_INT(info.degenerate_count, 2);
    check_triangle(m, 0, 0, 1, 2);
    check_triangle(m, 1, 0, 1, 3);
    check_triangle(m, 2, 2, 2, 1);
    CHECK_EQ_INT(as_mesh_triangle_is_degenerate(m, 0), 0);
    CHECK_EQ_INT(as_mesh_triangle_is_degenerate(m, 1), 1);
    CHECK_EQ_INT(as_mesh_triangle_is_degenerate(m, 2), 1);
    as_mesh_release(m);
}

static void binary_ply_and_its_zst_without_content_size_agree(void)
{
    as_mesh_info_t plain, packed;
    as_mesh_t *a = import_ok(data_path("quad_binary.ply"), &plain);
    as_mesh_t *b = import_ok(data_path("quad_binary.ply.zst"), &packed);
    if (a && b) {
        CHECK_EQ_U64(plain.faces_in_file, 3);
        CHECK_EQ_INT(plain.triangle_count, 4);
        CHECK_EQ_INT(plain.polygon_faces, 1);
        CHECK_EQ_INT(plain.degenerate_count, 1);
        check_triangle(a, 0, 0, 1, 2);
        check_triangle(a, 1, 0, 2, 3);
        check_triangle(a, 3, 0, 1, 4);
        CHECK_EQ_U64(packed.hash, plain.hash);
        CHECK_EQ_INT(packed.triangle_count, plain.triangle_count);
    }
    as_mesh_release(a);
    as_mesh_release(b);
}

static void stl_keeps_facet_with_coincident_corners(void)
{
    const char *files[] = {"tiny.stl", "tiny_binary.stl"};
    for (int i = 0; i < 2; ++i) {
        as_mesh_info_t info;
        as_mesh_t *m = import_ok(data_path(files[i]), &info);
        if (!m) continue;
        CHECK_EQ_U64(info.faces_in_file, 2);
        CHECK_EQ_INT(info.triangle_count, 2);
        CHECK_EQ_INT(info.vertex_count, 6);
        CHECK_EQ_INT(info.degenerate_count, 1);
        CHECK_EQ_INT(as_mesh_triangle_is_degenerate(m, 1), 1);
        CHECK(as_mesh_positions(m)[3 * 2 + 1] == 1.0f); /* third corner (0 1 0) */
        as_mesh_release(m);
    }
}

/* ------------------------------------------------------------------------ */
/* Real scenes */

static double now_ms(void)
{
    struct timespec ts;
    clock_gettime(CLOCK_MONOTONIC, &ts);
    return ts.tv_sec * 1e3 + ts.tv_nsec / 1e6;
}

static unsigned char *decompress_file(const char *path, size_t *size)
{
    FILE *f = fopen(path, "rb");
    if (!f) return NULL;
    fseek(f, 0, SEEK_END);
    const long n = ftell(f);
    fseek(f, 0, SEEK_SET);
    unsigned char *src = malloc((size_t)n);
    if (!src || fread(src, 1, (size_t)n, f) != (size_t)n) {
        fclose(f);
        free(src);
        return NULL;
    }
    fclose(f);
    const unsigned long long raw = ZSTD_getFrameContentSize(src, (size_t)n);
    unsigned char *out = raw < (1ull << 32) ? malloc(raw) : NULL;
    const size_t got = out ? ZSTD_decompress(out, raw, src, (size_t)n) : 0;
    free(src);
    if (!out || ZSTD_isError(got)) {
        free(out);
        return NULL;
    }
    *size = got;
    return out;
}

/* The scenes' PLY layout (scenes/README.md): float x y z, then
 * "list uchar uint" faces of 3. Compares every position and every triangle
 * with what as_mesh_import returned: same count, same order. */
static void check_same_as_raw_ply(const char *path, const as_mesh_t *m)
{
    size_t size = 0;
    unsigned char *ply = decompress_file(path, &size);
    CHECK(ply != NULL);
    if (!ply) return;
    unsigned nv = 0, nf = 0;
    const char *hdr = (const char *)ply;
    const char *v = strstr(hdr, "element vertex ");
    const char *f = strstr(hdr, "element face ");
    const char *end = strstr(hdr, "end_header\n");
    CHECK(v && f && end);
    if (v && f && end) {
        nv = (unsigned)strtoul(v + 15, NULL, 10);
        nf = (unsigned)strtoul(f + 13, NULL, 10);
        const unsigned char *p = (const unsigned char *)end + 11;
        as_mesh_info_t info;
        as_mesh_get_info(m, &info);
        CHECK_EQ_INT(info.vertex_count, nv);
        CHECK_EQ_INT(info.triangle_count, nf);
        CHECK(memcmp(p, as_mesh_positions(m), (size_t)nv * 12) == 0);
        p += (size_t)nv * 12;
        unsigned mismatches = 0;
        for (unsigned t = 0; t < nf && t < info.triangle_count; ++t, p += 13) {
            uint32_t idx[3];
            memcpy(idx, p + 1, 12);
            mismatches += p[0] != 3 || memcmp(idx, as_mesh_indices(m) + (size_t)t * 3, 12) != 0;
        }
        CHECK_EQ_INT(mismatches, 0);
    }
    free(ply);
}

static void staircase2_keeps_all_faces_zero_area_included_in_file_order(void)
{
    char buf[512];
    const char *path = test_scene_or_exit("staircase2.ply.zst", buf, sizeof buf);
    as_mesh_info_t info;
    as_mesh_t *m = import_ok(path, &info);
    if (!m) return;
    CHECK_EQ_U64(info.faces_in_file, 30927);
    CHECK_EQ_INT(info.triangle_count, 30927);
    CHECK(info.degenerate_count >= 2429);
    CHECK(!info.has_normals && !info.has_uvs && !info.has_materials);
    check_same_as_raw_ply(path, m);
    fprintf(stderr, "     staircase2.ply.zst: %u vertices, %u triangles, %u zero-area\n",
            info.vertex_count, info.triangle_count, info.degenerate_count);
    as_mesh_release(m);
}

static void bunny_ply_and_drc_have_the_same_triangles_and_box(void)
{
    char buf_ply[512], buf_drc[512];
    const char *ply_path = test_scene_or_exit("bunny.ply.zst", buf_ply, sizeof buf_ply);
    const char *drc_path = test_scene_or_exit("bunny.drc", buf_drc, sizeof buf_drc);
    as_mesh_info_t ip, id;
    as_mesh_t *p = import_ok(ply_path, &ip);
    as_mesh_t *d = import_ok(drc_path, &id);
    if (p && d) {
        CHECK_EQ_INT(ip.triangle_count, 69451);
        CHECK_EQ_U64(ip.faces_in_file, 69451);
        check_same_as_raw_ply(ply_path, p);
        CHECK_EQ_INT(id.triangle_count, 69451);
        CHECK_EQ_U64(id.faces_in_file, 69451);
        CHECK(id.has_normals && !id.has_uvs && !id.has_materials);
        CHECK(!ip.has_normals);
        /* Draco quantized positions to 16 bits over the box, so the boxes
         * agree to within one step (0.16 / 2^16 here), not exactly. */
        for (int k = 0; k < 3; ++k) {
            CHECK(fabsf(id.bounds_lo[k] - ip.bounds_lo[k]) < 1e-5f);
            CHECK(fabsf(id.bounds_hi[k] - ip.bounds_hi[k]) < 1e-5f);
        }
        const float *n = as_mesh_normals(d);
        float len = n ? sqrtf(n[0] * n[0] + n[1] * n[1] + n[2] * n[2]) : 0;
        CHECK(fabsf(len - 1.0f) < 1e-2f);
        fprintf(stderr, "     bunny.ply.zst: %u vertices, %u triangles; bunny.drc: %u vertices, %u triangles\n",
                ip.vertex_count, ip.triangle_count, id.vertex_count, id.triangle_count);
    }
    as_mesh_release(p);
    as_mesh_release(d);
}

static void bathroom_drc_decodes_every_face(void)
{
    char buf[512];
    const char *path = test_scene_or_exit("bathroom.drc", buf, sizeof buf);
    as_mesh_info_t info;
    const double t0 = now_ms();
    as_mesh_t *m = import_ok(path, &info);
    const double ms = now_ms() - t0;
    if (!m) return;
    CHECK_EQ_INT(info.triangle_count, 591924);
    CHECK_EQ_U64(info.faces_in_file, 591924);
    CHECK(info.bounds_lo[0] > -2.91f && info.bounds_lo[0] < -2.89f);
    CHECK(info.bounds_hi[1] > 2.78f && info.bounds_hi[1] < 2.80f);
    fprintf(stderr, "     bathroom.drc: %u vertices, %u triangles, %u zero-area, %.0f ms\n",
            info.vertex_count, info.triangle_count, info.degenerate_count, ms);
    as_mesh_release(m);
}

int main(int argc, char **argv)
{
    if (argc > 1 && strcmp(argv[1], "scenes") == 0) {
        RUN_TEST(staircase2_keeps_all_faces_zero_area_included_in_file_order);
        RUN_TEST(bunny_ply_and_drc_have_the_same_triangles_and_box);
        RUN_TEST(bathroom_drc_decodes_every_face);
        TEST_EXIT();
    }
    RUN_TEST(create_copies_arrays_and_counts_nothing_degenerate);
    RUN_TEST(create_rejects_empty_mesh);
    RUN_TEST(create_rejects_non_finite_coordinate_naming_vertex);
    RUN_TEST(create_rejects_index_out_of_range_naming_triangle);
    RUN_TEST(create_rejects_null_arrays);
    RUN_TEST(release_and_accessors_accept_null);
    RUN_TEST(degenerate_means_exactly_zero_cross_product_or_repeated_index);
    RUN_TEST(degenerate_range_counts_match_the_triangles);
    RUN_TEST(hash_chains_positions_then_indices);
    RUN_TEST(bounds_cover_referenced_vertices_only);
    RUN_TEST(import_refuses_missing_file_as_file_not_found);
    RUN_TEST(import_refuses_unknown_extension_as_unsupported);
    RUN_TEST(import_refuses_non_finite_obj_vertex);
    RUN_TEST(import_refuses_index_out_of_range);
    RUN_TEST(import_refuses_face_with_two_corners);
    RUN_TEST(import_refuses_file_without_triangles);
    RUN_TEST(import_refuses_garbage_ply_header);
    RUN_TEST(import_refuses_unreadable_header_count_and_glued_corners);
    RUN_TEST(import_refuses_off_lines_shorter_than_the_reader_reads);
    RUN_TEST(import_refuses_obj_corner_that_is_not_a_whole_number);
    RUN_TEST(import_refuses_truncated_binary_ply);
    RUN_TEST(import_refuses_binary_ply_ending_at_end_header);
    RUN_TEST(import_refuses_draco_counts_the_file_cannot_hold);
    RUN_TEST(import_refuses_ply_whose_numbers_do_not_add_up);
    RUN_TEST(import_refuses_ply_lists_it_cannot_read);
    RUN_TEST(import_refuses_damaged_zstd_frame);
    RUN_TEST(import_refuses_truncated_zstd_frame);
    RUN_TEST(obj_quads_become_consecutive_fan_triangles);
    RUN_TEST(obj_keeps_faces_with_repeated_corners_normals_uvs_and_materials);
    RUN_TEST(off_polygon_is_fanned_and_normals_kept_only_when_present);
    RUN_TEST(coff_colours_after_corners_are_read_past);
    RUN_TEST(compressed_off_reads_like_uncompressed);
    RUN_TEST(extension_is_matched_without_case);
    RUN_TEST(ply_keeps_zero_area_and_repeated_index_faces_in_order);
    RUN_TEST(binary_ply_and_its_zst_without_content_size_agree);
    RUN_TEST(stl_keeps_facet_with_coincident_corners);
    TEST_EXIT();
}
