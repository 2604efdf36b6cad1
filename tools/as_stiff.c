/* as-stiff: write a case of the stiff-case suite (as_stiff_case_generate)
 * as an OBJ mesh, a ray file and a list of each ray's correct outcome, so
 * that any tracer can be tested on it. */
#include "tool_common.h"

#include <errno.h>
#include <getopt.h>
#include <inttypes.h>
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

static const char *TOOL = "as-stiff";

static void usage(void)
{
    printf("Usage: %s CASE [-o PREFIX] [options]\n"
           "       %s --list\n"
           "Writes a case of the stiff-case suite: PREFIX.obj (the mesh), PREFIX.rays (a ray\n"
           "file, formats/SPEC.md) and PREFIX.expect (each ray's correct outcome, one line\n"
           "per ray: hit, miss, prim P..., not-prim P..., reference; then \"same-as I\" when\n"
           "its hit must equal ray I's, \"+reference\" when it must also be the\n"
           "reference's answer), and prints the case's outcome.\n\n"
           "  -o, --output PREFIX     where to write (default: the case's name)\n"
           "      --list              list the cases\n"
           "      --seed N            another seed: other random meshes and rays (default 0,\n"
           "                          the suite's own)\n"
           "      --offset X          watertight cases: where the mesh lies (default 0)\n"
           "      --edge X            watertight cases: the lattice edge (default: from the offset)\n"
           "      --copies N          duplicates: copies of the triangle (default 10000)\n"
           "      --among-others      duplicates: after 500 other triangles\n"
           "      --ray-count N       about this many rays where the case draws them\n"
           "      --mesh FILE         surface: the mesh the rays leave (default: a sphere)\n"
           "  -h, --help              this help\n"
           "  -V, --version           the version\n\n"
           "Cases: watertight-cube, watertight-sphere, seam, signed-zero, grazing, range,\n"
           "degenerate, flat, duplicates, planar, surface, bad-rays.\n\n" TOOL_EXIT_CODES_HELP,
           TOOL, TOOL);
}

static bool parse_double(const char *s, double *out)
{
    char *end;
    errno = 0;
    const double v = strtod(s, &end);
    if (errno || end == s || *end || !isfinite(v)) return false;
    *out = v;
    return true;
}

static bool parse_u64(const char *s, uint64_t *out)
{
    char *end;
    errno = 0;
    if (*s == '-') return false;
    const unsigned long long v = strtoull(s, &end, 0);
    if (errno || end == s || *end) return false;
    *out = v;
    return true;
}

/* Positions with %.9g, which gives every float back exactly. */
static int write_obj(const char *path, const as_mesh_t *m)
{
    FILE *f = fopen(path, "w");
    if (!f) {
        fprintf(stderr, "%s: error: cannot write %s: %s [IO]\n", TOOL, path, strerror(errno));
        return EXIT_IO;
    }
    as_mesh_info_t info;
    as_mesh_get_info(m, &info);
    const float *p = as_mesh_positions(m);
    const uint32_t *ix = as_mesh_indices(m);
    for (uint32_t v = 0; v < info.vertex_count; ++v)
        fprintf(f, "v %.9g %.9g %.9g\n", (double)p[3 * v], (double)p[3 * v + 1], (double)p[3 * v + 2]);
    for (uint32_t t = 0; t < info.triangle_count; ++t)
        fprintf(f, "f %u %u %u\n", ix[3 * t] + 1, ix[3 * t + 1] + 1, ix[3 * t + 2] + 1);
    if (fclose(f) != 0) {
        fprintf(stderr, "%s: error: cannot write %s [IO]\n", TOOL, path);
        return EXIT_IO;
    }
    return EXIT_OK;
}

static int write_expect(const char *path, const as_stiff_case_data_t *c, size_t counts[6])
{
    static const char *const names[] = {"", "hit", "miss", "prim", "not-prim", "reference"};
    FILE *f = fopen(path, "w");
    if (!f) {
        fprintf(stderr, "%s: error: cannot write %s: %s [IO]\n", TOOL, path, strerror(errno));
        return EXIT_IO;
    }
    for (size_t i = 0; i < c->ray_count; ++i) {
        const as_stiff_outcome_t *o = &c->outcomes[i];
        const uint32_t e = o->expect <= 5 ? o->expect : 0;
        ++counts[e];
        fputs(names[e], f);
        for (uint32_t k = 0; k < o->count; ++k) fprintf(f, " %u", c->prims[o->first + k]);
        if (o->same_as != AS_STIFF_NO_RAY) fprintf(f, " same-as %u", o->same_as);
        if (o->reference) fputs(" +reference", f);
        fputc('\n', f);
    }
    if (fclose(f) != 0) {
        fprintf(stderr, "%s: error: cannot write %s [IO]\n", TOOL, path);
        return EXIT_IO;
    }
    return EXIT_OK;
}

int main(int argc, char **argv)
{
    enum { OPT_LIST = 256, OPT_SEED, OPT_OFFSET, OPT_EDGE, OPT_COPIES, OPT_AMONG, OPT_RAYS, OPT_MESH };
    static const struct option opts[] = {
        {"output", required_argument, 0, 'o'},
        {"list", no_argument, 0, OPT_LIST},
        {"seed", required_argument, 0, OPT_SEED},
        {"offset", required_argument, 0, OPT_OFFSET},
        {"edge", required_argument, 0, OPT_EDGE},
        {"copies", required_argument, 0, OPT_COPIES},
        {"among-others", no_argument, 0, OPT_AMONG},
        {"ray-count", required_argument, 0, OPT_RAYS},
        {"mesh", required_argument, 0, OPT_MESH},
        {"help", no_argument, 0, 'h'},
        {"version", no_argument, 0, 'V'},
        {0, 0, 0, 0},
    };
    as_stiff_args_t args;
    as_stiff_args_default(&args);
    const char *prefix = NULL, *mesh_path = NULL;
    bool list = false;
    uint64_t u64;
    unsigned u;
    int c;
    opterr = 0;
    while ((c = getopt_long(argc, argv, "o:hV", opts, NULL)) != -1) {
        switch (c) {
        case 'o': prefix = optarg; break;
        case OPT_LIST: list = true; break;
        case OPT_SEED:
            if (!parse_u64(optarg, &args.seed)) return tool_usage_error(TOOL, "--seed needs a whole number, got '%s'", optarg);
            break;
        case OPT_OFFSET:
            if (!parse_double(optarg, &args.offset)) return tool_usage_error(TOOL, "--offset needs a finite number, got '%s'", optarg);
            break;
        case OPT_EDGE:
            if (!parse_double(optarg, &args.edge) || args.edge <= 0.0)
                return tool_usage_error(TOOL, "--edge needs a positive number, got '%s'", optarg);
            break;
        case OPT_COPIES:
            if (!tool_parse_u32(optarg, &u) || u == 0) return tool_usage_error(TOOL, "--copies needs a count above 0, got '%s'", optarg);
            args.duplicate_count = u;
            break;
        case OPT_AMONG: args.duplicates_among_others = true; break;
        case OPT_RAYS:
            if (!parse_u64(optarg, &u64) || u64 == 0) return tool_usage_error(TOOL, "--ray-count needs a count above 0, got '%s'", optarg);
            args.ray_count = (size_t)u64;
            break;
        case OPT_MESH: mesh_path = optarg; break;
        case 'h': usage(); return EXIT_OK;
        case 'V': tool_print_version(TOOL); return EXIT_OK;
        default: return tool_usage_error(TOOL, "unknown or incomplete option '%s'", argv[optind - 1]);
        }
    }
    if (list) {
        for (int k = 1; k <= AS_STIFF_CASE_COUNT; ++k) printf("%s\n", as_stiff_case_name((as_stiff_case_t)k));
        return EXIT_OK;
    }
    if (optind != argc - 1) return tool_usage_error(TOOL, "expected one case, got %d", argc - optind);
    const as_stiff_case_t kind = as_stiff_case_from_name(argv[optind]);
    if (!kind) return tool_usage_error(TOOL, "unknown case '%s' (as-stiff --list)", argv[optind]);
    if (!prefix) prefix = argv[optind];
    as_mesh_t *surface = NULL;
    if (mesh_path) {
        surface = as_mesh_import(mesh_path);
        if (!surface) return tool_fail(TOOL);
        args.surface_mesh = surface;
    }
    as_stiff_case_data_t sc;
    if (as_stiff_case_generate(kind, &args, &sc) != AS_OK) {
        as_mesh_release(surface);
        return tool_fail(TOOL);
    }
    as_mesh_release(surface);
    const size_t len = strlen(prefix) + 8;
    char *obj = malloc(len), *rays = malloc(len), *expect = malloc(len);
    int code = obj && rays && expect ? EXIT_OK : EXIT_RUNTIME;
    size_t counts[6] = {0};
    if (code == EXIT_OK) {
        snprintf(obj, len, "%s.obj", prefix);
        snprintf(rays, len, "%s.rays", prefix);
        snprintf(expect, len, "%s.expect", prefix);
        code = write_obj(obj, sc.mesh);
    }
    if (code == EXIT_OK && as_rays_write(rays, sc.rays, sc.ray_count) != AS_OK) code = tool_fail(TOOL);
    if (code == EXIT_OK) code = write_expect(expect, &sc, counts);
    if (code == EXIT_OK) {
        as_mesh_info_t info;
        as_mesh_get_info(sc.mesh, &info);
        printf("case:        %s (seed %" PRIu64 ")\n", as_stiff_case_name(kind), args.seed);
        printf("mesh:        %s: %u vertices, %u triangles (%u zero-area)\n", obj, info.vertex_count,
               info.triangle_count, info.degenerate_count);
        printf("rays:        %s: %zu rays, closest hit\n", rays, sc.ray_count);
        printf("expect:      %s: %zu hit, %zu miss, %zu prim, %zu not-prim, %zu reference\n", expect, counts[1],
               counts[2], counts[3], counts[4], counts[5]);
        printf("intersector: %s\n", sc.intersector == AS_INTERSECTOR_WATERTIGHT_DOUBLE ? "watertight, double" : "watertight");
        printf("outcome:     %s\n", sc.outcome);
    }
    free(obj);
    free(rays);
    free(expect);
    as_stiff_case_free(&sc);
    return code;
}
