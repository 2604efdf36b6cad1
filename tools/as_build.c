/* as-build: mesh file in, .asf structure out. */
#include "tool_common.h"

#include <getopt.h>
#include <stdio.h>
#include <string.h>
#include <time.h>
#include <unistd.h>

static const char *TOOL = "as-build";

static void usage(void)
{
    printf("Usage: %s MESH -o FILE.asf [options]\n"
           "Builds an acceleration structure over a triangle mesh and writes it as .asf.\n"
           "MESH: .obj .ply .off .stl .drc, each optionally compressed as NAME.EXT.zst.\n\n"
           "  -o, --output FILE         the .asf file to write (temporary file, then rename)\n"
           "      --structure KIND      bvh (default), kd, bih, octree, grid\n"
           "      --builder NAME        bvh: sah (binned, default), sweep, midcut, sbvh;\n"
           "                            kd: sah (default), midcut; bih: bih;\n"
           "                            octree: octree; grid: grid\n"
           "      --layout NAME         bvh: bvh2-child-bounds (default), bvh2-own-bounds,\n"
           "                            cwbvh (compressed 8-wide, collapsed from a BVH2\n"
           "                            built with one triangle per leaf);\n"
           "                            kd: kd-standard (default), kd-ropes; bih: bih;\n"
           "                            octree: octree; grid: grid\n"
           "      --max-depth N         depth cap (default: the structure's; never deeper\n"
           "                            than its traversal stack)\n"
           "      --lambda X            grid: cells per triangle (default 4)\n"
           "      --split-budget X      sbvh, kd: at most X times as many references as\n"
           "                            triangles (default 4)\n"
           "      --leaf-size N         largest leaf, triangles (default 4; cwbvh: at most 3)\n"
           "      --bins N              SAH bins per axis, 2..256 (default 32)\n"
           "      --cost-traversal X    SAH cost of a node visit (default 1)\n"
           "      --cost-intersection X SAH cost of a triangle test (default 1)\n"
           "      --threads N           build threads (default: every core)\n"
           "      --compress[=LEVEL]    zstd-compress every section (default level 9)\n"
           "      --no-build-record     leave the build time out of the file, so that two\n"
           "                            builds of one mesh give byte-identical files\n"
           "  -q, --quiet               no summary\n"
           "  -h, --help                this help\n"
           "  -V, --version             the version\n\n"
           "Prints: triangles (in the file, kept, zero-area), nodes, leaves, max depth,\n"
           "SAH cost, size in MB and build time in ms.\n\n" TOOL_EXIT_CODES_HELP,
           TOOL);
}

int main(int argc, char **argv)
{
    enum { OPT_STRUCTURE = 256, OPT_BUILDER, OPT_LEAF, OPT_BINS, OPT_CT, OPT_CI, OPT_THREADS, OPT_COMPRESS, OPT_NO_BUILD_RECORD,
           OPT_LAYOUT, OPT_MAX_DEPTH, OPT_LAMBDA, OPT_BUDGET };
    static const struct option opts[] = {
        {"output", required_argument, 0, 'o'},
        {"structure", required_argument, 0, OPT_STRUCTURE},
        {"builder", required_argument, 0, OPT_BUILDER},
        {"leaf-size", required_argument, 0, OPT_LEAF},
        {"bins", required_argument, 0, OPT_BINS},
        {"cost-traversal", required_argument, 0, OPT_CT},
        {"cost-intersection", required_argument, 0, OPT_CI},
        {"threads", required_argument, 0, OPT_THREADS},
        {"compress", optional_argument, 0, OPT_COMPRESS},
        {"no-build-record", no_argument, 0, OPT_NO_BUILD_RECORD},
        {"layout", required_argument, 0, OPT_LAYOUT},
        {"max-depth", required_argument, 0, OPT_MAX_DEPTH},
        {"lambda", required_argument, 0, OPT_LAMBDA},
        {"split-budget", required_argument, 0, OPT_BUDGET},
        {"quiet", no_argument, 0, 'q'},
        {"help", no_argument, 0, 'h'},
        {"version", no_argument, 0, 'V'},
        {0, 0, 0, 0},
    };
    as_build_args_t args;
    as_build_args_default(&args);
    args.progress = tool_progress;
    as_save_args_t save;
    as_save_args_default(&save);
    const char *out = NULL, *builder_name = NULL;
    int quiet = 0, c;
    unsigned u;
    opterr = 0;
    while ((c = getopt_long(argc, argv, "o:qhV", opts, NULL)) != -1) {
        switch (c) {
        case 'o': out = optarg; break;
        case OPT_STRUCTURE:
            args.structure = as_structure_kind_from_name(optarg);
            if (!args.structure) return tool_usage_error(TOOL, "unknown structure '%s' (known: bvh, kd, bih, octree, grid)", optarg);
            break;
        case OPT_BUILDER: builder_name = optarg; break;
        case OPT_LAYOUT:
            args.layout = as_layout_from_name(optarg);
            if (!args.layout) return tool_usage_error(TOOL, "unknown layout '%s'", optarg);
            break;
        case OPT_MAX_DEPTH:
            if (!tool_parse_u32(optarg, &u) || u < 1) return tool_usage_error(TOOL, "--max-depth needs a positive integer, got '%s'", optarg);
            args.max_depth = u;
            break;
        case OPT_LAMBDA:
            if (!tool_parse_float(optarg, &args.grid_lambda) || args.grid_lambda <= 0) return tool_usage_error(TOOL, "--lambda needs a number > 0, got '%s'", optarg);
            break;
        case OPT_BUDGET:
            if (!tool_parse_float(optarg, &args.split_budget) || args.split_budget < 1) return tool_usage_error(TOOL, "--split-budget needs a number >= 1, got '%s'", optarg);
            break;
        case OPT_LEAF:
            if (!tool_parse_u32(optarg, &u) || u < 1) return tool_usage_error(TOOL, "--leaf-size needs a positive integer, got '%s'", optarg);
            args.max_leaf_size = u;
            break;
        case OPT_BINS:
            if (!tool_parse_u32(optarg, &u) || u < 2 || u > 256) return tool_usage_error(TOOL, "--bins needs an integer in 2..256, got '%s'", optarg);
            args.bin_count = u;
            break;
        case OPT_CT:
            if (!tool_parse_float(optarg, &args.cost_traversal) || args.cost_traversal < 0) return tool_usage_error(TOOL, "--cost-traversal needs a number >= 0, got '%s'", optarg);
            break;
        case OPT_CI:
            if (!tool_parse_float(optarg, &args.cost_intersection) || args.cost_intersection <= 0) return tool_usage_error(TOOL, "--cost-intersection needs a number > 0, got '%s'", optarg);
            break;
        case OPT_THREADS:
            if (!tool_parse_u32(optarg, &u)) return tool_usage_error(TOOL, "--threads needs an integer, got '%s'", optarg);
            args.thread_count = u;
            break;
        case OPT_COMPRESS:
            save.compression_level = 9;
            if (optarg && (!tool_parse_u32(optarg, &u) || u < 1 || u > 22)) return tool_usage_error(TOOL, "--compress level must be 1..22, got '%s'", optarg);
            if (optarg) save.compression_level = (int)u;
            break;
        case OPT_NO_BUILD_RECORD: save.omit_build_record = true; break;
        case 'q': quiet = 1; break;
        case 'h': usage(); return EXIT_OK;
        case 'V': tool_print_version(TOOL); return EXIT_OK;
        default: return tool_usage_error(TOOL, "unknown or incomplete option '%s'", argv[optind - 1]);
        }
    }
    if (optind != argc - 1) return tool_usage_error(TOOL, "expected one mesh file, got %d", argc - optind);
    if (!out) return tool_usage_error(TOOL, "missing -o FILE.asf");
    if (builder_name) {
        args.builder = as_builder_from_name(args.structure, builder_name);
        if (!args.builder)
            return tool_usage_error(TOOL, "unknown builder '%s' for %s", builder_name, as_structure_kind_name(args.structure));
    }
    const char *in = argv[optind];

    as_mesh_t *mesh = as_mesh_import(in);
    if (!mesh) return tool_fail(TOOL);
    as_mesh_info_t mi;
    as_mesh_get_info(mesh, &mi);
    as_structure_t *s = as_structure_build(mesh, &args);
    as_mesh_release(mesh);
    if (!s) return tool_fail(TOOL);
    if (as_structure_save(s, out, &save) != AS_OK) {
        as_structure_release(s);
        return tool_fail(TOOL);
    }
    as_structure_stats_t st;
    if (as_structure_get_stats(s, &st) != AS_OK) {
        as_structure_release(s);
        return tool_fail(TOOL);
    }
    if (!quiet) {
        printf("mesh:         %s\n", in);
        printf("triangles:    %u (faces in file %llu, polygons fanned %u, zero-area %u never hit)\n", mi.triangle_count,
               (unsigned long long)mi.faces_in_file, mi.polygon_faces, mi.degenerate_count);
        printf("structure:    %s, builder %s, layout %s v%u\n", as_structure_kind_name(st.structure),
               as_builder_name(st.builder), as_layout_name(st.layout), st.layout_version);
        printf("parameters:   leaf size %u, bins %u, cost traversal %g, intersection %g\n", st.max_leaf_size,
               st.bin_count, (double)st.cost_traversal, (double)st.cost_intersection);
        printf("nodes:        %llu inner, %llu leaves (%llu empty), %.2f triangles per leaf\n",
               (unsigned long long)st.node_count, (unsigned long long)st.leaf_count,
               (unsigned long long)st.empty_leaf_count, st.average_leaf_size);
        if (st.grid_dims[0])
            printf("grid:         %u x %u x %u cells\n", st.grid_dims[0], st.grid_dims[1], st.grid_dims[2]);
        printf("max depth:    %u (average leaf depth %.2f)\n", st.max_depth, st.average_leaf_depth);
        printf("SAH cost:     %.3f\n", st.sah_cost);
        printf("size:         %.3f MB (%.1f bytes per triangle)\n", (double)st.structure_bytes / 1e6,
               mi.triangle_count ? (double)st.structure_bytes / mi.triangle_count : 0.0);
        printf("build:        %.1f ms\n", st.build_ms);
        printf("written:      %s\n", out);
    }
    as_structure_release(s);
    return EXIT_OK;
}
