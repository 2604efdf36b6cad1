/* as-inspect: what is in an .asf file and what it costs. */
#include "tool_common.h"

#include <getopt.h>
#include <inttypes.h>
#include <stdio.h>
#include <string.h>

static const char *TOOL = "as-inspect";

static void usage(void)
{
    printf("Usage: %s FILE.asf [options]\n"
           "Prints the sections of an .asf file (tag, bytes stored and raw, compression,\n"
           "checksum) and the structure's memory, nodes, leaves, depths, histograms,\n"
           "SAH cost and build parameters.\n\n"
           "  -f, --format text|json  output format (default text)\n"
           "      --validate          also check the structure itself (indices, boxes,\n"
           "                          cycles, depth); exit 3 when it is damaged\n"
           "      --no-checksum       do not verify section checksums\n"
           "  -h, --help              this help\n"
           "  -V, --version           the version\n\n" TOOL_EXIT_CODES_HELP,
           TOOL);
}

static const char *or_unknown(const char *name) { return name ? name : "unknown"; }
#define kind_name(k) or_unknown(as_structure_kind_name(k))
#define builder_name(b) or_unknown(as_builder_name(b))
#define layout_name(l) or_unknown(as_layout_name(l))

static const char *checksum_word(int status)
{
    return status > 0 ? "verified" : status < 0 ? "mismatch" : "not checked";
}

static void print_histogram_json(const char *name, const uint64_t *h)
{
    int last = -1;
    for (int i = 0; i < AS_HISTOGRAM_BINS; ++i)
        if (h[i]) last = i;
    printf("  \"%s\": [", name);
    for (int i = 0; i <= last; ++i) printf("%s%llu", i ? ", " : "", (unsigned long long)h[i]);
    printf("],\n");
}

static void print_histogram_text(const char *title, const uint64_t *h, uint64_t total)
{
    printf("%s\n", title);
    for (int i = 0; i < AS_HISTOGRAM_BINS; ++i) {
        if (!h[i]) continue;
        const int bar = total ? (int)(50.0 * (double)h[i] / (double)total + 0.5) : 0;
        printf("  %3d%s %10llu  ", i, i == AS_HISTOGRAM_BINS - 1 ? "+" : " ", (unsigned long long)h[i]);
        for (int k = 0; k < bar; ++k) putchar('#');
        putchar('\n');
    }
}

int main(int argc, char **argv)
{
    enum { OPT_VALIDATE = 256, OPT_NO_CHECKSUM };
    static const struct option opts[] = {
        {"format", required_argument, 0, 'f'},
        {"validate", no_argument, 0, OPT_VALIDATE},
        {"no-checksum", no_argument, 0, OPT_NO_CHECKSUM},
        {"help", no_argument, 0, 'h'},
        {"version", no_argument, 0, 'V'},
        {0, 0, 0, 0},
    };
    int json = 0, validate = 0, c;
    as_load_args_t load;
    as_load_args_default(&load);
    opterr = 0;
    while ((c = getopt_long(argc, argv, "f:hV", opts, NULL)) != -1) {
        switch (c) {
        case 'f':
            if (strcmp(optarg, "json") == 0) json = 1;
            else if (strcmp(optarg, "text") == 0) json = 0;
            else return tool_usage_error(TOOL, "unknown format '%s' (known: text, json)", optarg);
            break;
        case OPT_VALIDATE: validate = 1; break;
        case OPT_NO_CHECKSUM: load.verify_checksums = false; break;
        case 'h': usage(); return EXIT_OK;
        case 'V': tool_print_version(TOOL); return EXIT_OK;
        default: return tool_usage_error(TOOL, "unknown or incomplete option '%s'", argv[optind - 1]);
        }
    }
    if (optind != argc - 1) return tool_usage_error(TOOL, "expected one .asf file, got %d", argc - optind);
    const char *path = argv[optind];
    as_structure_t *s = as_structure_load(path, &load);
    if (!s) return tool_fail(TOOL);
    if (validate && as_structure_validate(s) != AS_OK) {
        const int code = tool_fail(TOOL);
        as_structure_release(s);
        return code;
    }
    as_structure_stats_t st;
    if (as_structure_get_stats(s, &st) != AS_OK) {
        const int code = tool_fail(TOOL);
        as_structure_release(s);
        return code;
    }
    const uint32_t nsec = as_structure_section_count(s);
    const double bpt = st.triangle_count ? (double)st.structure_bytes / st.triangle_count : 0.0;
    /* In a tree every node but the root is one inner node's child: the
     * width a node fetch serves (2 for a BVH2, up to 8 for the wide BVH). */
    const double fanout = st.node_count ? (double)(st.node_count - 1 + st.leaf_count + st.empty_leaf_count) /
                                              (double)st.node_count
                                        : 0.0;
    if (json) {
        printf("{\n  \"file\": ");
        tool_print_json_string(path);
        printf(",\n  \"sections\": [\n");
        for (uint32_t i = 0; i < nsec; ++i) {
            as_section_info_t si;
            as_structure_section_info(s, i, &si);
            printf("    {\"tag\": \"%s\", \"required\": %s, \"offset\": %llu, \"stored_bytes\": %llu, \"raw_bytes\": %llu, "
                   "\"elements\": %llu, \"stride\": %u, \"compression\": \"%s\", \"checksum\": \"%016llx\", "
                   "\"checksum_status\": \"%s\", \"purpose\": \"%s\"}%s\n",
                   si.tag, si.required ? "true" : "false", (unsigned long long)si.offset,
                   (unsigned long long)si.stored_bytes, (unsigned long long)si.raw_bytes,
                   (unsigned long long)si.element_count, si.stride, si.compressed ? "zstd" : "none",
                   (unsigned long long)si.checksum, checksum_word(si.checksum_status), si.purpose,
                   i + 1 < nsec ? "," : "");
        }
        printf("  ],\n");
        printf("  \"structure\": \"%s\",\n  \"layout\": \"%s\",\n  \"layout_version\": %u,\n", kind_name(st.structure),
               layout_name(st.layout), st.layout_version);
        printf("  \"writer\": ");
        tool_print_json_string(st.writer);
        printf(",\n  \"writer_version\": %u,\n", st.writer_version);
        printf("  \"build\": {\"builder\": \"%s\", \"max_leaf_size\": %u, \"bins\": %u, \"cost_traversal\": %g, "
               "\"cost_intersection\": %g",
               builder_name(st.builder), st.max_leaf_size, st.bin_count, (double)st.cost_traversal,
               (double)st.cost_intersection);
        if (st.build_threads)
            printf(", \"build_ms\": %.3f, \"threads\": %u, \"cores\": %u", st.build_ms, st.build_threads,
                   st.build_cores);
        else
            printf(", \"build_ms\": null");
        printf("},\n");
        printf("  \"source_hash\": \"%016llx\",\n", (unsigned long long)st.source_hash);
        printf("  \"bounds\": [[%g, %g, %g], [%g, %g, %g]],\n", (double)st.bounds_lo[0], (double)st.bounds_lo[1],
               (double)st.bounds_lo[2], (double)st.bounds_hi[0], (double)st.bounds_hi[1], (double)st.bounds_hi[2]);
        printf("  \"triangles\": %u,\n  \"bytes\": %llu,\n  \"megabytes\": %.6f,\n  \"bytes_per_triangle\": %.3f,\n",
               st.triangle_count, (unsigned long long)st.structure_bytes, (double)st.structure_bytes / 1e6, bpt);
        printf("  \"nodes\": %llu,\n  \"children_per_node\": %.4f,\n  \"leaves\": %llu,\n  \"empty_leaves\": %llu,\n"
               "  \"references\": %llu,\n"
               "  \"average_leaf_size\": %.4f,\n  \"max_depth\": %u,\n  \"average_leaf_depth\": %.4f,\n",
               (unsigned long long)st.node_count, fanout, (unsigned long long)st.leaf_count,
               (unsigned long long)st.empty_leaf_count, (unsigned long long)st.reference_count, st.average_leaf_size,
               st.max_depth, st.average_leaf_depth);
        printf("  \"grid_dims\": [%u, %u, %u],\n", st.grid_dims[0], st.grid_dims[1], st.grid_dims[2]);
        printf("  \"sah_cost_ratio\": \"%.2f/1\",\n", (double)(st.cost_traversal / st.cost_intersection));
        printf("  \"sah_cost\": %.6f,\n", st.sah_cost);
        print_histogram_json("depth_histogram", st.depth_histogram);
        print_histogram_json("leaf_size_histogram", st.leaf_size_histogram);
        printf("  \"validated\": %s\n}\n", validate ? "true" : "false");
    } else {
        printf("file:        %s\n", path);
        printf("structure:   %s, layout %s v%u, written by %s %u.%u.%u\n", kind_name(st.structure),
               layout_name(st.layout), st.layout_version, st.writer, st.writer_version / 10000,
               st.writer_version / 100 % 100, st.writer_version % 100);
        printf("sections:\n  %-4s %-8s %12s %12s %12s %6s  %-5s %-11s %s\n", "tag", "flags", "offset", "stored",
               "raw", "stride", "zstd", "checksum", "purpose");
        for (uint32_t i = 0; i < nsec; ++i) {
            as_section_info_t si;
            as_structure_section_info(s, i, &si);
            printf("  %-4s %-8s %12llu %12llu %12llu %6u  %-5s %-11s %s\n", si.tag, si.required ? "required" : "optional",
                   (unsigned long long)si.offset, (unsigned long long)si.stored_bytes,
                   (unsigned long long)si.raw_bytes, si.stride, si.compressed ? "yes" : "no",
                   checksum_word(si.checksum_status), si.purpose);
        }
        printf("triangles:   %u\n", st.triangle_count);
        printf("memory:      %.3f MB, %.1f bytes per triangle\n", (double)st.structure_bytes / 1e6, bpt);
        printf("nodes:       %llu inner, %llu leaves, %.2f children per inner node\n", (unsigned long long)st.node_count,
               (unsigned long long)st.leaf_count, fanout);
        printf("leaves:      %llu empty, %llu references, %.2f per leaf\n", (unsigned long long)st.empty_leaf_count,
               (unsigned long long)st.reference_count, st.average_leaf_size);
        if (st.grid_dims[0])
            printf("grid:        %u x %u x %u cells\n", st.grid_dims[0], st.grid_dims[1], st.grid_dims[2]);
        printf("depth:       max %u, average leaf depth %.2f\n", st.max_depth, st.average_leaf_depth);
        printf("SAH cost:    %.3f (ratio %.2f/1: traversal %g, intersection %g)\n", st.sah_cost,
               (double)(st.cost_traversal / st.cost_intersection), (double)st.cost_traversal,
               (double)st.cost_intersection);
        printf("build:       %s, leaf size %u, bins %u\n", builder_name(st.builder), st.max_leaf_size, st.bin_count);
        if (st.build_threads)
            printf("build time:  %.1f ms on %u threads (%u cores), as recorded in the file\n", st.build_ms,
                   st.build_threads, st.build_cores);
        else
            printf("build time:  not recorded in the file\n");
        printf("source hash: %016llx\n", (unsigned long long)st.source_hash);
        printf("bounds:      (%g, %g, %g) - (%g, %g, %g)\n", (double)st.bounds_lo[0], (double)st.bounds_lo[1],
               (double)st.bounds_lo[2], (double)st.bounds_hi[0], (double)st.bounds_hi[1], (double)st.bounds_hi[2]);
        print_histogram_text("leaves per depth:", st.depth_histogram, st.leaf_count);
        print_histogram_text("leaves per size (triangles):", st.leaf_size_histogram, st.leaf_count);
        if (validate) printf("validation:  passed\n");
    }
    as_structure_release(s);
    return EXIT_OK;
}
