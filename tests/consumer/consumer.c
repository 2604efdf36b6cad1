/* A program outside the libas tree, built against an installed libas (CMake
 * find_package or pkg-config): it prints the version it runs with, imports
 * the meshes named on the command line (which needs OpenMesh or Draco, so a
 * static link shows whether those come along), builds a BVH over three
 * triangles and traces four rays whose hits are known. */
#include <math.h>
#include <stdio.h>

#include <as/as.h>

int main(int argc, char **argv)
{
    printf("libas %s (compiled against %s)\n", as_version_string(), AS_VERSION_STRING);
    if (as_version_number() != AS_VERSION_NUMBER) {
        fprintf(stderr, "consumer: running libas %u, compiled against %u\n", as_version_number(),
                AS_VERSION_NUMBER);
        return 1;
    }

    for (int i = 1; i < argc; ++i) {
        as_mesh_t *imported = as_mesh_import(argv[i]);
        if (!imported) {
            fprintf(stderr, "consumer: %s [%s]\n", as_get_error_message(), as_error_name(as_get_error()));
            return 1;
        }
        as_mesh_info_t info;
        as_mesh_get_info(imported, &info);
        printf("mesh %d: %u triangles\n", i, info.triangle_count);
        as_mesh_release(imported);
    }

    /* A 2 x 2 square in z = 0 (triangles 0 and 1, split along its diagonal)
     * and a small triangle in z = 1 over its centre (triangle 2). */
    const float positions[] = {
        -1.0f, -1.0f, 0.0f,   1.0f, -1.0f, 0.0f,   1.0f, 1.0f, 0.0f,   -1.0f, 1.0f, 0.0f,
        -0.25f, -0.25f, 1.0f, 0.25f, -0.25f, 1.0f, 0.0f, 0.25f, 1.0f,
    };
    const uint32_t indices[] = {0, 1, 2, 0, 2, 3, 4, 5, 6};
    as_mesh_t *mesh = as_mesh_create(7, positions, 3, indices);
    as_build_args_t build;
    as_build_args_default(&build);
    as_structure_t *s = mesh ? as_structure_build(mesh, &build) : NULL;
    if (!s) {
        fprintf(stderr, "consumer: %s [%s]\n", as_get_error_message(), as_error_name(as_get_error()));
        as_mesh_release(mesh);
        return 1;
    }
    as_structure_stats_t stats;
    as_structure_get_stats(s, &stats);
    printf("structure: %s, %u triangles\n", as_layout_name(stats.layout), stats.triangle_count);

    /* Straight down from z = 5 onto each triangle, and past the square. */
    const as_ray_t rays[4] = {
        {{0.5f, -0.5f, 5.0f}, 0.0f, {0.0f, 0.0f, -1.0f}, INFINITY},
        {{-0.5f, 0.5f, 5.0f}, 0.0f, {0.0f, 0.0f, -1.0f}, INFINITY},
        {{0.0f, 0.0f, 5.0f}, 0.0f, {0.0f, 0.0f, -1.0f}, INFINITY},
        {{3.0f, 3.0f, 5.0f}, 0.0f, {0.0f, 0.0f, -1.0f}, INFINITY},
    };
    as_hit_t hits[4];
    as_trace_args_t trace;
    as_trace_args_default(&trace);
    trace.device = AS_DEVICE_CPU;
    if (as_trace(s, rays, 4, hits, &trace, NULL) != AS_OK) {
        fprintf(stderr, "consumer: %s\n", as_get_error_message());
        return 1;
    }
    for (int i = 0; i < 4; ++i) {
        if (hits[i].prim == AS_NO_HIT)
            printf("ray %d: miss\n", i);
        else
            printf("ray %d: prim %u t %g u %g v %g\n", i, hits[i].prim, hits[i].t, hits[i].u, hits[i].v);
    }
    as_structure_release(s);
    as_mesh_release(mesh);
    return 0;
}
