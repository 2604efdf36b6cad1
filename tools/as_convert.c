/* as-convert: rewrite an .asf file with other section encodings (and, as
 * structures gain layouts, other layouts). */
#include "tool_common.h"

#include <getopt.h>
#include <stdio.h>
#include <string.h>

static const char *TOOL = "as-convert";

static void usage(void)
{
    printf("Usage: %s IN.asf -o OUT.asf [options]\n"
           "Reads a structure file, checks it, and writes it again.\n\n"
           "  -o, --output FILE       the file to write (temporary file, then rename)\n"
           "      --compress[=LEVEL]  zstd-compress every section (default level 9)\n"
           "      --decompress        store every section raw (the default)\n"
           "      --layout NAME       convert to another layout of the same structure:\n"
           "                          bvh2-child-bounds <-> bvh2-own-bounds,\n"
           "                          bvh2-* -> cwbvh (one way: its boxes are quantized),\n"
           "                          kd-standard <-> kd-ropes (adds or removes ropes)\n"
           "  -h, --help              this help\n"
           "  -V, --version           the version\n\n"
           "The structure is validated before it is written; unknown optional sections\n"
           "are not carried over.\n\n" TOOL_EXIT_CODES_HELP,
           TOOL);
}

int main(int argc, char **argv)
{
    enum { OPT_COMPRESS = 256, OPT_DECOMPRESS, OPT_LAYOUT };
    static const struct option opts[] = {
        {"output", required_argument, 0, 'o'},
        {"compress", optional_argument, 0, OPT_COMPRESS},
        {"decompress", no_argument, 0, OPT_DECOMPRESS},
        {"layout", required_argument, 0, OPT_LAYOUT},
        {"help", no_argument, 0, 'h'},
        {"version", no_argument, 0, 'V'},
        {0, 0, 0, 0},
    };
    as_save_args_t save;
    as_save_args_default(&save);
    const char *out = NULL;
    as_layout_t layout = AS_LAYOUT_DEFAULT;
    int c;
    unsigned u;
    opterr = 0;
    while ((c = getopt_long(argc, argv, "o:hV", opts, NULL)) != -1) {
        switch (c) {
        case 'o': out = optarg; break;
        case OPT_COMPRESS:
            save.compression_level = 9;
            if (optarg && (!tool_parse_u32(optarg, &u) || u < 1 || u > 22)) return tool_usage_error(TOOL, "--compress level must be 1..22, got '%s'", optarg);
            if (optarg) save.compression_level = (int)u;
            break;
        case OPT_DECOMPRESS: save.compression_level = 0; break;
        case OPT_LAYOUT:
            layout = as_layout_from_name(optarg);
            if (!layout) return tool_usage_error(TOOL, "unknown layout '%s'", optarg);
            break;
        case 'h': usage(); return EXIT_OK;
        case 'V': tool_print_version(TOOL); return EXIT_OK;
        default: return tool_usage_error(TOOL, "unknown or incomplete option '%s'", argv[optind - 1]);
        }
    }
    if (optind != argc - 1) return tool_usage_error(TOOL, "expected one input file, got %d", argc - optind);
    if (!out) return tool_usage_error(TOOL, "missing -o OUT.asf");
    as_structure_t *s = as_structure_load(argv[optind], NULL);
    if (!s) return tool_fail(TOOL);
    as_structure_stats_t st;
    if (layout != AS_LAYOUT_DEFAULT && as_structure_get_stats(s, &st) == AS_OK && st.layout != layout) {
        as_structure_t *converted = as_structure_convert(s, layout);
        as_structure_release(s);
        if (!converted) return tool_fail(TOOL);
        s = converted;
    }
    if (as_structure_validate(s) != AS_OK || as_structure_save(s, out, &save) != AS_OK) {
        const int code = tool_fail(TOOL);
        as_structure_release(s);
        return code;
    }
    as_structure_release(s);
    return EXIT_OK;
}
