/* as-trace: trace rays through a prebuilt .asf file, on the GPU when there is
 * one, else on every CPU core. */
#include "tool_common.h"

#include <getopt.h>
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

static const char *TOOL = "as-trace";

static void usage(void)
{
    printf("Usage: %s FILE.asf [options]\n"
           "Traces primary camera rays (or rays from a file) through a structure file.\n\n"
           "  -d, --device auto|cpu|gpu  where to trace (default: gpu when present, else cpu)\n"
           "      --eye X,Y,Z            camera position\n"
           "      --target X,Y,Z         point the camera looks at\n"
           "      --up X,Y,Z             up vector (default 0,1,0)\n"
           "      --fov DEGREES          vertical field of view (default 45)\n"
           "                             Default camera: looking down -z at the centre of\n"
           "                             the scene box from where its bounding sphere fits.\n"
           "  -W, --width N              image width (default 1024)\n"
           "  -H, --height N             image height (default 768)\n"
           "      --rays FILE            trace the rays of a ray file instead of a camera\n"
           "      --hits-out FILE        write the hits as a hit file\n"
           "  -i, --image FILE.png       write a shaded image (camera rays only)\n"
           "      --any-hit              stop at the first hit (shadow rays)\n"
           "      --runs N               GPU: timed launches, median reported (default 5)\n"
           "      --threads N            CPU threads (default: every core)\n"
           "      --no-checksum          do not verify section checksums on load\n"

           "  -h, --help                 this help\n"
           "  -V, --version              the version\n\n"
           "Prints the device, the ray count, the trace time (GPU: median of device-event\n"
           "timed launches; CPU: wall clock) and Mrays/s for the trace alone.\n\n" TOOL_EXIT_CODES_HELP,
           TOOL);
}

int main(int argc, char **argv)
{
    enum { OPT_EYE = 256, OPT_TARGET, OPT_UP, OPT_FOV, OPT_RAYS, OPT_HITS, OPT_ANY, OPT_RUNS, OPT_THREADS,
           OPT_NO_CHECKSUM };
    static const struct option opts[] = {
        {"device", required_argument, 0, 'd'},
        {"eye", required_argument, 0, OPT_EYE},
        {"target", required_argument, 0, OPT_TARGET},
        {"up", required_argument, 0, OPT_UP},
        {"fov", required_argument, 0, OPT_FOV},
        {"width", required_argument, 0, 'W'},
        {"height", required_argument, 0, 'H'},
        {"rays", required_argument, 0, OPT_RAYS},
        {"hits-out", required_argument, 0, OPT_HITS},
        {"image", required_argument, 0, 'i'},
        {"any-hit", no_argument, 0, OPT_ANY},
        {"runs", required_argument, 0, OPT_RUNS},
        {"threads", required_argument, 0, OPT_THREADS},
        {"no-checksum", no_argument, 0, OPT_NO_CHECKSUM},
        {"help", no_argument, 0, 'h'},
        {"version", no_argument, 0, 'V'},
        {0, 0, 0, 0},
    };
    as_trace_args_t targs;
    as_trace_args_default(&targs);
    as_load_args_t load;
    as_load_args_default(&load);
    float eye[3], target[3], up[3] = {0, 1, 0}, fov = 45.0f;
    int have_eye = 0, have_target = 0, have_fov = 0, c;
    unsigned width = 1024, height = 768, u;
    const char *rays_path = NULL, *hits_path = NULL, *image_path = NULL;
    opterr = 0;
    while ((c = getopt_long(argc, argv, "d:W:H:i:hV", opts, NULL)) != -1) {
        switch (c) {
        case 'd':
            if (strcmp(optarg, "cpu") == 0) targs.device = AS_DEVICE_CPU;
            else if (strcmp(optarg, "gpu") == 0) targs.device = AS_DEVICE_GPU;
            else if (strcmp(optarg, "auto") == 0) targs.device = AS_DEVICE_AUTO;
            else return tool_usage_error(TOOL, "unknown device '%s' (known: auto, cpu, gpu)", optarg);
            break;
        case OPT_EYE: if (!tool_parse_vec3(optarg, eye)) return tool_usage_error(TOOL, "--eye needs X,Y,Z, got '%s'", optarg); have_eye = 1; break;
        case OPT_TARGET: if (!tool_parse_vec3(optarg, target)) return tool_usage_error(TOOL, "--target needs X,Y,Z, got '%s'", optarg); have_target = 1; break;
        case OPT_UP: if (!tool_parse_vec3(optarg, up)) return tool_usage_error(TOOL, "--up needs X,Y,Z, got '%s'", optarg); break;
        case OPT_FOV:
            if (!tool_parse_float(optarg, &fov) || fov <= 0 || fov >= 180) return tool_usage_error(TOOL, "--fov needs degrees in (0, 180), got '%s'", optarg);
            have_fov = 1;
            break;
        case 'W': if (!tool_parse_u32(optarg, &width) || !width || width > 32768) return tool_usage_error(TOOL, "--width needs 1..32768, got '%s'", optarg); break;
        case 'H': if (!tool_parse_u32(optarg, &height) || !height || height > 32768) return tool_usage_error(TOOL, "--height needs 1..32768, got '%s'", optarg); break;
        case OPT_RAYS: rays_path = optarg; break;
        case OPT_HITS: hits_path = optarg; break;
        case 'i': image_path = optarg; break;
        case OPT_ANY: targs.any_hit = true; break;
        case OPT_RUNS: if (!tool_parse_u32(optarg, &u) || !u) return tool_usage_error(TOOL, "--runs needs a positive integer, got '%s'", optarg); targs.timed_runs = u; break;
        case OPT_THREADS: if (!tool_parse_u32(optarg, &u)) return tool_usage_error(TOOL, "--threads needs an integer, got '%s'", optarg); targs.thread_count = u; break;
        case OPT_NO_CHECKSUM: load.verify_checksums = false; break;
        case 'h': usage(); return EXIT_OK;
        case 'V': tool_print_version(TOOL); return EXIT_OK;
        default: return tool_usage_error(TOOL, "unknown or incomplete option '%s'", argv[optind - 1]);
        }
    }
    if (optind != argc - 1) return tool_usage_error(TOOL, "expected one .asf file, got %d", argc - optind);
    if (rays_path && image_path) return tool_usage_error(TOOL, "--image needs camera rays; it cannot be used with --rays");
    if (have_eye != have_target) return tool_usage_error(TOOL, "--eye and --target go together");
    const char *path = argv[optind];

    as_structure_t *s = as_structure_load(path, &load);
    if (!s) return tool_fail(TOOL);
    int code = EXIT_OK;
    as_ray_t *rays = NULL;
    as_hit_t *hits = NULL;
    size_t count = 0;
    /* Always: a kernel must never read a file that could send it out of
     * bounds, and validation costs one linear pass. */
    if (as_structure_validate(s) != AS_OK) { code = tool_fail(TOOL); goto done; }
    if (rays_path) {
        if (as_rays_read(rays_path, &rays, &count) != AS_OK) { code = tool_fail(TOOL); goto done; }
    } else {
        as_structure_stats_t st;
        if (as_structure_get_stats(s, &st) != AS_OK) { code = tool_fail(TOOL); goto done; }
        as_camera_t cam;
        as_camera_default(st.bounds_lo, st.bounds_hi, &cam);
        if (have_eye) { memcpy(cam.eye, eye, sizeof eye); memcpy(cam.target, target, sizeof target); }
        memcpy(cam.up, up, sizeof up);
        if (have_fov) cam.fov_y_degrees = fov;
        count = (size_t)width * height;
        rays = malloc(sizeof *rays * count);
        if (!rays) { fprintf(stderr, "%s: error: out of memory for %zu rays\n", TOOL, count); code = EXIT_RUNTIME; goto done; }
        as_camera_rays(&cam, width, height, rays);
        printf("camera:      eye %g,%g,%g target %g,%g,%g up %g,%g,%g fov %g, %ux%u\n", (double)cam.eye[0],
               (double)cam.eye[1], (double)cam.eye[2], (double)cam.target[0], (double)cam.target[1],
               (double)cam.target[2], (double)cam.up[0], (double)cam.up[1], (double)cam.up[2],
               (double)cam.fov_y_degrees, width, height);
    }
    hits = malloc(sizeof *hits * (count ? count : 1));
    if (!hits) { fprintf(stderr, "%s: error: out of memory for %zu hits\n", TOOL, count); code = EXIT_RUNTIME; goto done; }
    as_trace_timing_t timing;
    if (as_trace(s, rays, count, hits, &targs, &timing) != AS_OK) { code = tool_fail(TOOL); goto done; }
    size_t nhit = 0;
    for (size_t i = 0; i < count; ++i) nhit += hits[i].prim != AS_NO_HIT;
    printf("device:      %s %s\n", timing.device == AS_DEVICE_GPU ? "gpu" : "cpu", timing.device_name);
    printf("rays:        %zu (%s), %zu hit\n", count, targs.any_hit ? "any hit" : "closest hit", nhit);
    if (timing.device == AS_DEVICE_GPU)
        printf("upload:      %.3f ms for %llu bytes of structure\n", timing.upload_ms,
               (unsigned long long)timing.upload_bytes);
    printf("trace:       %.3f ms (%s)\n", timing.trace_ms,
           timing.device == AS_DEVICE_GPU ? "median of device-event timed launches" : "wall clock");
    printf("Mrays/s:     %.2f\n", timing.trace_ms > 0 ? (double)count / (timing.trace_ms * 1e3) : 0.0);
    if (hits_path) {
        if (as_hits_write(hits_path, hits, count) != AS_OK) { code = tool_fail(TOOL); goto done; }
        printf("hits:        %s\n", hits_path);
    }
    if (image_path) {
        if (as_image_write_png(s, rays, hits, width, height, image_path) != AS_OK) { code = tool_fail(TOOL); goto done; }
        printf("image:       %s\n", image_path);
    }
done:
    free(rays);
    free(hits);
    as_structure_release(s);
    return code;
}
