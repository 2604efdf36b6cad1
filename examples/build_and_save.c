/* Builds an acceleration structure and saves it as an .asf file.
 *
 *   build_and_save OUT.asf [MESH]
 *
 * MESH is any file as_mesh_import reads (OBJ, PLY, OFF, STL, Draco .drc,
 * optionally .zst); without one, a scene of three triangles: a 2 x 2 square
 * in z = 0 (triangles 0 and 1) and a small triangle in z = 1 over its centre
 * (triangle 2). The structure is the default one (a BVH with the binned SAH
 * builder, child-bounds layout); load_and_trace and custom_kernel read the
 * file. */
#include <stdio.h>

#include <as/as.h>

static int fail(const char *what)
{
    fprintf(stderr, "build_and_save: %s: %s [%s]\n", what, as_get_error_message(),
            as_error_name(as_get_error()));
    return as_error_exit_code(as_get_error());
}

int main(int argc, char **argv)
{
    if (argc < 2 || argc > 3) {
        fprintf(stderr, "usage: build_and_save OUT.asf [MESH]\n");
        return 1;
    }
    const char *out = argv[1];

    as_mesh_t *mesh;
    if (argc == 3) {
        mesh = as_mesh_import(argv[2]);
    } else {
        const float positions[] = {
            -1.0f, -1.0f, 0.0f,   1.0f, -1.0f, 0.0f,   1.0f, 1.0f, 0.0f,   -1.0f, 1.0f, 0.0f,
            -0.25f, -0.25f, 1.0f, 0.25f, -0.25f, 1.0f, 0.0f, 0.25f, 1.0f,
        };
        const uint32_t indices[] = {0, 1, 2, 0, 2, 3, 4, 5, 6};
        mesh = as_mesh_create(7, positions, 3, indices);
    }
    if (!mesh) return fail("mesh");
    as_mesh_info_t mesh_info;
    as_mesh_get_info(mesh, &mesh_info);
    printf("mesh: %u triangles, %u vertices\n", mesh_info.triangle_count, mesh_info.vertex_count);

    as_build_args_t build;
    as_build_args_default(&build);
    as_structure_t *s = as_structure_build(mesh, &build);
    as_mesh_release(mesh); /* the structure keeps its own copy of the triangles */
    if (!s) return fail("build");

    as_structure_stats_t stats;
    if (as_structure_get_stats(s, &stats) != AS_OK) {
        as_structure_release(s);
        return fail("stats");
    }
    printf("structure: %s, layout %s, builder %s\n", as_structure_kind_name(stats.structure),
           as_layout_name(stats.layout), as_builder_name(stats.builder));
    printf("nodes: %llu, leaves: %llu, max depth: %u, SAH cost: %.2f\n",
           (unsigned long long)stats.node_count, (unsigned long long)stats.leaf_count, stats.max_depth,
           stats.sah_cost);

    /* Raw sections (no zstd) are used in place when the file is mapped, and
     * a user's own kernel can copy them straight from the mapping
     * (custom_kernel.cu). Without the build record (its build time), two runs
     * write the same bytes. */
    as_save_args_t save;
    as_save_args_default(&save);
    save.compression_level = 0;
    save.omit_build_record = true;
    const as_error_t e = as_structure_save(s, out, &save);
    as_structure_release(s);
    if (e != AS_OK) return fail("save");
    printf("saved: %s\n", out);
    return 0;
}
