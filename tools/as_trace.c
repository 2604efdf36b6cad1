/* as-trace: trace the study's workloads through a prebuilt .asf file, on the
 * GPU when there is one, else on every CPU core. */
#define _POSIX_C_SOURCE 200809L
#include "tool_common.h"

#include <getopt.h>
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <time.h>
#include <sys/stat.h>

static const char *TOOL = "as-trace";

static void usage(void)
{
    printf("Usage: %s FILE.asf [options]\n"
           "Traces a workload through a structure file and reports the trace time alone.\n\n"
           "  -d, --device auto|cpu|gpu  where to trace (default: gpu when present, else cpu)\n"
           "  -w, --workload NAME        primary (default), shadow, ao, diffuse, whitted, or\n"
           "                             all; secondary rays start at the primary hits.\n"
           "                             whitted: reflections and refractions up to\n"
           "                             --bounces (10), hard shadows at every hit; 10%% of\n"
           "                             the triangles mirrors, 5%% glass (ior 1.5), seeded,\n"
           "                             unless --materials gives them\n"
           "      --materials MESH.obj   whitted: each triangle's material from the OBJ the\n"
           "                             structure was built from and the .mtl files it\n"
           "                             names (mirror: illum 3/5 or Ks >= 0.8; glass: d < 1\n"
           "                             or illum 4/6/7/9, ior from Ni)\n"
           "      --eye X,Y,Z            camera position\n"
           "      --target X,Y,Z         point the camera looks at\n"
           "      --up X,Y,Z             up vector (default 0,1,0)\n"
           "      --fov DEGREES          vertical field of view (default 45)\n"
           "      --camera FILE          the camera from a file of lines 'eye X Y Z',\n"
           "                             'target X Y Z', 'up X Y Z', 'fov DEGREES' (the\n"
           "                             options above override it)\n"
           "                             Default camera: looking down -z at the centre of\n"
           "                             the scene box from where its bounding sphere fits.\n"
           "  -W, --width N              image width (default 1920)\n"
           "  -H, --height N             image height (default 1080)\n"
           "                             Primary rays go out in 16x32 tiles along a Morton curve.\n"
           "      --light X,Y,Z          a point light for shadow rays (repeatable; default:\n"
           "                             four lights from the scene box)\n"
           "      --shuffle              trace the secondary rays in a random (seeded) order:\n"
           "                             the incoherent case\n"
           "      --ao-rays N            AO rays per primary hit (default 16)\n"
           "      --ao-radius F          AO ray length, fraction of the scene diagonal (0.1)\n"
           "      --diffuse-rays N       diffuse rays per primary hit (default 4)\n"
           "      --ray-limit N          trace only the first N rays of each workload (of the\n"
           "                             file with --rays), for ray-count sweeps; secondary\n"
           "                             rays still start at every primary hit (not with\n"
           "                             whitted)\n"
           "      --bounces N            whitted: reflection and refraction depth, 0..64\n"
           "                             (default 10)\n"
           "      --rays FILE            trace the rays of a ray file instead of a camera\n"
           "      --any-hit              with --rays: stop at the first hit\n"
           "      --hits-out FILE        write the hits (primary or --rays) as a hit file\n"
           "      --dump DIR             write every traced workload's rays and hits as a ray\n"
           "                             file and a hit file, DIR/NAME.rays and DIR/NAME.hits\n"
           "                             (NAME: the workload's name, spaces as '-'), to trace\n"
           "                             the same rays with another tracer or check them\n"
           "  -i, --image FILE.png       write an image: shaded primary hits, or AO when the\n"
           "                             workload is ao\n"
           "      --heat-map FILE.png    write a heat map of the traversal steps of each\n"
           "                             primary ray (viridis: dark purple few, yellow many),\n"
           "                             counted in the untimed statistics pass\n"
           "      --heat-max N           steps drawn yellow in the heat map (default: the\n"
           "                             image's 99th percentile); the scale is printed\n"
           "      --intersector NAME     watertight-double (default: Woop et al. in double,\n"
           "                             decides as the --verify reference does),\n"
           "                             watertight (the same test in float, explicitly\n"
           "                             rounded) or moller-trumbore (the classic float\n"
           "                             test, not watertight: for comparison)\n"
           "      --runs N               GPU: timed launches after a warm-up (default 10)\n"
           "      --schedule NAME        GPU: thread (one per ray, default: measured fastest)\n"
           "                             or persistent (warps fetch --batch rays per atomic)\n"
           "      --batch N              GPU persistent threads: rays per atomic (default 32)\n"
           "      --verify[=N]           check N sampled rays of each workload (default\n"
           "                             100000) against a double-precision reference and\n"
           "                             report wrong primitives, false misses, false hits\n"
           "                             and the largest relative t error\n"
           "      --stats                also count steps and triangle tests per ray, in a\n"
           "                             separate untimed pass (GPU: a counting kernel)\n"
           "      --residency NAME       GPU: auto (default: device memory when the structure\n"
           "                             fits, else in place), device, or zero-copy (kernels\n"
           "                             read the mapped file in place)\n"
           "      --upload NAME          GPU: pipeline (default, measured fastest: eight threads\n"
           "                             copy the sections into pinned buffers uploaded\n"
           "                             asynchronously), pageable (cudaMemcpy from the\n"
           "                             mapping), or registered (cudaHostRegister, then copy)\n"
           "      --upload-threads N     GPU pipeline: copying threads (default 8)\n"
           "      --upload-chunk MIB     GPU pipeline: MiB per pinned buffer, two per thread\n"
           "                             (default 2)\n"
           "      --memory-limit BYTES   GPU: device memory the structure may take (default:\n"
           "                             the free memory)\n"
           "      --rebuild MESH         also rebuild the structure from MESH (the mesh it was\n"
           "                             built from: checked by hash) on the CPU with the\n"
           "                             file's recorded settings and --threads, and print\n"
           "                             that build time beside the load time and the one\n"
           "                             recorded in the file\n"
           "      --threads N            CPU threads (default: every core)\n"
           "  -f, --format text|json     output format (default text)\n"
           "      --no-checksum          do not verify section checksums on load\n"
           "      --validation-record F  skip validation of a file whose fingerprint (XXH3-128\n"
           "                             of its sections) F lists, and add the fingerprint of\n"
           "                             one that passes; only for files and records you trust\n"
           "  -h, --help                 this help\n"
           "  -V, --version              the version\n\n"
           "The structure is validated before a kernel reads it: on the GPU right after its\n"
           "upload, every layout (zero-copy residency: on the CPU first); on the CPU before\n"
           "a CPU trace; once per fingerprint with --validation-record. Times: GPU, the\n"
           "median of the timed launches measured with device events around the kernel\n"
           "alone (rays already on the device); CPU, wall clock of the trace.\n\n" TOOL_EXIT_CODES_HELP,
           TOOL);
}

enum { W_PRIMARY = 1, W_SHADOW = 2, W_AO = 4, W_DIFFUSE = 8, W_WHITTED = 16 };
#define MAX_RESULTS 40

typedef struct run_result {
    char name[32];
    bool any_hit;
    size_t rays;
    size_t workload_rays; /* the workload's rays, of which `rays` were traced */
    size_t hit;
    as_trace_timing_t timing;
    bool verified;
    as_verify_result_t verify;
} run_result;

static size_t verify_samples; /* 0: no verification */
static const char *dump_dir;  /* --dump: where each workload's rays and hits go, or NULL */

/* Writes a workload's rays and hits to DIR/NAME.rays and DIR/NAME.hits,
 * the spaces of NAME as '-'; an exit code. */
static int dump_workload(const char *name, const as_ray_t *rays, const as_hit_t *hits, size_t count)
{
    char path[4096];
    for (int k = 0; k < 2; ++k) {
        const int n = snprintf(path, sizeof path, "%s/%s.%s", dump_dir, name, k ? "hits" : "rays");
        if (n < 0 || (size_t)n >= sizeof path) {
            fprintf(stderr, "%s: error: --dump %s: path too long\n", TOOL, dump_dir);
            return EXIT_IO;
        }
        for (char *c = path + strlen(dump_dir) + 1; *c; ++c)
            if (*c == ' ') *c = '-';
        if ((k ? as_hits_write(path, hits, count) : as_rays_write(path, rays, count)) != AS_OK) return tool_fail(TOOL);
    }
    return EXIT_OK;
}

static double as_now_ms_tool(void)
{
    struct timespec ts;
    clock_gettime(CLOCK_MONOTONIC, &ts);
    return (double)ts.tv_sec * 1e3 + (double)ts.tv_nsec * 1e-6;
}

static int trace_one(const char *name, const as_structure_t *s, const as_ray_t *rays, size_t count, as_hit_t *hits,
                     const as_trace_args_t *base, bool any_hit, run_result *out)
{
    as_trace_args_t args = *base;
    args.any_hit = any_hit;
    snprintf(out->name, sizeof out->name, "%s", name);
    out->any_hit = any_hit;
    out->rays = count;
    out->workload_rays = count;
    if (as_trace(s, rays, count, hits, &args, &out->timing) != AS_OK) return tool_fail(TOOL);
    out->hit = 0;
    for (size_t i = 0; i < count; ++i) out->hit += hits[i].prim != AS_NO_HIT;
    if (dump_dir) {
        const int code = dump_workload(name, rays, hits, count);
        if (code != EXIT_OK) return code;
    }
    out->verified = false;
    if (verify_samples) {
        as_verify_args_t va;
        as_verify_args_default(&va);
        va.sample_count = verify_samples;
        va.thread_count = base->thread_count;
        if (as_verify(s, rays, hits, count, any_hit, &va, &out->verify) != AS_OK) return tool_fail(TOOL);
        out->verified = true;
    }
    return EXIT_OK;
}

/* Fisher-Yates with a fixed seed (splitmix64), keeping each ray's origin
 * index beside it. */
static void shuffle_rays(as_ray_t *rays, uint32_t *from, size_t n)
{
    uint64_t st = 12345;
    for (size_t i = n; i > 1; --i) {
        uint64_t z = (st += 0x9E3779B97F4A7C15ull);
        z = (z ^ (z >> 30)) * 0xBF58476D1CE4E5B9ull;
        z = (z ^ (z >> 27)) * 0x94D049BB133111EBull;
        z ^= z >> 31;
        const size_t j = (size_t)(z % i);
        const as_ray_t r = rays[i - 1];
        rays[i - 1] = rays[j];
        rays[j] = r;
        if (from) {
            const uint32_t f = from[i - 1];
            from[i - 1] = from[j];
            from[j] = f;
        }
    }
}

static double mrays(const run_result *r)
{
    return r->timing.trace_ms > 0 ? (double)r->rays / (r->timing.trace_ms * 1e3) : 0.0;
}

static void print_text(const run_result *r, bool any_hit)
{
    const as_trace_timing_t *t = &r->timing;
    if (strcmp(r->name, "whitted total") == 0) {
        printf("%-16s %10zu rays in all bounces: %.3f ms, %.2f Mrays/s\n", r->name, r->rays, t->trace_ms, mrays(r));
        return;
    }
    printf("%-16s %10zu rays", r->name, r->rays);
    if (r->workload_rays != r->rays) printf(" of %zu", r->workload_rays);
    printf(" (%s), %zu hit: %.3f ms", any_hit ? "any hit" : "closest hit", r->hit, t->trace_ms);
    if (t->device == AS_DEVICE_GPU && t->timed_runs)
        printf(" (median of %u, %.3f..%.3f)", t->timed_runs, t->trace_ms_min, t->trace_ms_max);
    printf(", %.2f Mrays/s\n", mrays(r));
    if (t->have_stats)
        printf("%-16s steps per ray %.2f (max %u), triangle tests per ray %.2f (max %u)\n", "", t->steps_avg,
               t->steps_max, t->tests_avg, t->tests_max);
    if (r->verified)
        printf("%-16s verified %llu rays: %llu wrong primitive, %llu false miss, %llu false hit; max t error %.2e "
               "relative, %.2e of the diagonal (%.0f ms)\n",
               "", (unsigned long long)r->verify.checked, (unsigned long long)r->verify.wrong_primitive,
               (unsigned long long)r->verify.false_misses, (unsigned long long)r->verify.false_hits,
               r->verify.max_t_error, r->verify.max_t_error_abs, r->verify.verify_ms);
}

static void print_json(const run_result *r, bool any_hit, bool last)
{
    const as_trace_timing_t *t = &r->timing;
    printf("    {\"workload\": \"%s\", \"rays\": %zu, \"query\": \"%s\", \"hit\": %zu, \"trace_ms\": %.6f, "
           "\"runs\": %u, \"trace_ms_min\": %.6f, \"trace_ms_max\": %.6f, \"mrays_per_s\": %.3f",
           r->name, r->rays, any_hit ? "any" : "closest", r->hit, t->trace_ms, t->timed_runs, t->trace_ms_min,
           t->trace_ms_max, mrays(r));
    if (r->workload_rays != r->rays) printf(", \"workload_rays\": %zu", r->workload_rays);
    if (t->have_stats)
        printf(", \"steps_avg\": %.4f, \"steps_max\": %u, \"tests_avg\": %.4f, \"tests_max\": %u", t->steps_avg,
               t->steps_max, t->tests_avg, t->tests_max);
    if (r->verified)
        printf(", \"verified\": %llu, \"wrong_primitive\": %llu, \"false_misses\": %llu, \"false_hits\": %llu, "
               "\"mismatch_ppm\": %.3f, \"max_t_error\": %.3e, \"max_t_error_diagonal\": %.3e",
               (unsigned long long)r->verify.checked, (unsigned long long)r->verify.wrong_primitive,
               (unsigned long long)r->verify.false_misses, (unsigned long long)r->verify.false_hits,
               r->verify.checked ? 1e6 * (double)(r->verify.wrong_primitive + r->verify.false_misses + r->verify.false_hits) / (double)r->verify.checked : 0.0,
               r->verify.max_t_error, r->verify.max_t_error_abs);
    printf("}%s\n", last ? "" : ",");
}

/* The mesh of --rebuild or --materials, imported before the traces so that
 * a wrong one is refused before any time is spent: it must be the one the
 * structure was built from. */
static int source_mesh_import(const char *mesh_path, const as_structure_stats_t *file, as_mesh_t **out)
{
    as_mesh_t *mesh = as_mesh_import(mesh_path);
    if (!mesh) return tool_fail(TOOL);
    as_mesh_info_t info;
    as_mesh_get_info(mesh, &info);
    if (info.hash != file->source_hash) {
        as_mesh_release(mesh);
        fprintf(stderr, "%s: error: %s: not the mesh the structure was built from (hash %016llx, the file "
                "records %016llx)\n", TOOL, mesh_path, (unsigned long long)info.hash,
                (unsigned long long)file->source_hash);
        return EXIT_INVALID_INPUT;
    }
    *out = mesh;
    return EXIT_OK;
}

/* Builds the structure `file` describes again from its mesh on this CPU,
 * with the settings the file records, and returns the new build's figures
 * (its build_ms is timed inside the library, as the recorded one was). */
static int rebuild(const as_mesh_t *mesh, const as_structure_stats_t *file, unsigned threads,
                   as_structure_stats_t *out, bool *same)
{
    as_build_args_t b;
    as_build_args_default(&b);
    b.structure = file->structure;
    b.builder = file->builder;
    b.layout = file->layout;
    b.max_leaf_size = file->max_leaf_size;
    b.bin_count = file->bin_count;
    b.cost_traversal = file->cost_traversal;
    b.cost_intersection = file->cost_intersection;
    b.thread_count = threads;
    as_structure_t *s = as_structure_build(mesh, &b);
    if (!s || as_structure_get_stats(s, out) != AS_OK) {
        as_structure_release(s);
        return tool_fail(TOOL);
    }
    as_structure_release(s);
    /* Depth caps, grid density and split budgets are not in the file; the
     * defaults stand in for them, and the counts say whether they matched. */
    *same = out->structure_bytes == file->structure_bytes && out->node_count == file->node_count &&
            out->leaf_count == file->leaf_count && out->reference_count == file->reference_count;
    return EXIT_OK;
}

int main(int argc, char **argv)
{
    enum { OPT_EYE = 256, OPT_TARGET, OPT_UP, OPT_FOV, OPT_CAMERA, OPT_RAYS, OPT_HITS, OPT_ANY, OPT_RUNS, OPT_THREADS,
           OPT_NO_CHECKSUM, OPT_LIGHT, OPT_AO_RAYS, OPT_AO_RADIUS, OPT_DIFFUSE_RAYS, OPT_SCHEDULE, OPT_BATCH,
           OPT_STATS, OPT_VERIFY, OPT_RESIDENCY, OPT_UPLOAD, OPT_MEMLIMIT, OPT_BOUNCES, OPT_SHUFFLE, OPT_INTERSECTOR,
           OPT_HEAT_MAP, OPT_HEAT_MAX, OPT_REBUILD,
           OPT_MATERIALS, OPT_VALIDATION_RECORD, OPT_UPLOAD_THREADS, OPT_UPLOAD_CHUNK, OPT_RAY_LIMIT, OPT_DUMP };
    static const struct option opts[] = {
        {"device", required_argument, 0, 'd'},
        {"workload", required_argument, 0, 'w'},
        {"eye", required_argument, 0, OPT_EYE},
        {"target", required_argument, 0, OPT_TARGET},
        {"up", required_argument, 0, OPT_UP},
        {"camera", required_argument, 0, OPT_CAMERA},
        {"fov", required_argument, 0, OPT_FOV},
        {"width", required_argument, 0, 'W'},
        {"height", required_argument, 0, 'H'},
        {"light", required_argument, 0, OPT_LIGHT},
        {"ao-rays", required_argument, 0, OPT_AO_RAYS},
        {"ao-radius", required_argument, 0, OPT_AO_RADIUS},
        {"diffuse-rays", required_argument, 0, OPT_DIFFUSE_RAYS},
        {"ray-limit", required_argument, 0, OPT_RAY_LIMIT},
        {"dump", required_argument, 0, OPT_DUMP},
        {"rays", required_argument, 0, OPT_RAYS},
        {"hits-out", required_argument, 0, OPT_HITS},
        {"image", required_argument, 0, 'i'},
        {"any-hit", no_argument, 0, OPT_ANY},
        {"runs", required_argument, 0, OPT_RUNS},
        {"schedule", required_argument, 0, OPT_SCHEDULE},
        {"batch", required_argument, 0, OPT_BATCH},
        {"stats", no_argument, 0, OPT_STATS},
        {"verify", optional_argument, 0, OPT_VERIFY},
        {"residency", required_argument, 0, OPT_RESIDENCY},
        {"bounces", required_argument, 0, OPT_BOUNCES},
        {"shuffle", no_argument, 0, OPT_SHUFFLE},
        {"intersector", required_argument, 0, OPT_INTERSECTOR},
        {"upload", required_argument, 0, OPT_UPLOAD},
        {"upload-threads", required_argument, 0, OPT_UPLOAD_THREADS},
        {"upload-chunk", required_argument, 0, OPT_UPLOAD_CHUNK},
        {"memory-limit", required_argument, 0, OPT_MEMLIMIT},
        {"threads", required_argument, 0, OPT_THREADS},
        {"format", required_argument, 0, 'f'},
        {"no-checksum", no_argument, 0, OPT_NO_CHECKSUM},
        {"heat-map", required_argument, 0, OPT_HEAT_MAP},
        {"heat-max", required_argument, 0, OPT_HEAT_MAX},
        {"rebuild", required_argument, 0, OPT_REBUILD},
        {"materials", required_argument, 0, OPT_MATERIALS},
        {"validation-record", required_argument, 0, OPT_VALIDATION_RECORD},
        {"help", no_argument, 0, 'h'},
        {"version", no_argument, 0, 'V'},
        {0, 0, 0, 0},
    };
    as_trace_args_t targs;
    as_trace_args_default(&targs);
    targs.timed_runs = 10;
    as_load_args_t load;
    as_load_args_default(&load);
    float eye[3], target[3], up[3] = {0, 1, 0}, fov = 45.0f, lights[3 * 16], ao_radius = 0.1f;
    unsigned light_count = 0, ao_rays = 16, diffuse_rays = 4, bounces = 10;
    const char *camera_path = NULL;
    int have_eye = 0, have_target = 0, have_fov = 0, have_up = 0, json = 0, workloads = W_PRIMARY, any_hit = 0, shuffle = 0, c;
    unsigned width = 1920, height = 1080, u, heat_max = 0, ray_limit = 0; /* 0: every ray */
    const char *rays_path = NULL, *hits_path = NULL, *image_path = NULL, *heat_path = NULL,
               *rebuild_path = NULL, *materials_path = NULL, *record_path = NULL;
    opterr = 0;
    while ((c = getopt_long(argc, argv, "d:w:W:H:i:f:hV", opts, NULL)) != -1) {
        switch (c) {
        case 'd':
            if (strcmp(optarg, "cpu") == 0) targs.device = AS_DEVICE_CPU;
            else if (strcmp(optarg, "gpu") == 0) targs.device = AS_DEVICE_GPU;
            else if (strcmp(optarg, "auto") == 0) targs.device = AS_DEVICE_AUTO;
            else return tool_usage_error(TOOL, "unknown device '%s' (known: auto, cpu, gpu)", optarg);
            break;
        case 'w':
            if (strcmp(optarg, "primary") == 0) workloads = W_PRIMARY;
            else if (strcmp(optarg, "shadow") == 0) workloads = W_PRIMARY | W_SHADOW;
            else if (strcmp(optarg, "ao") == 0) workloads = W_PRIMARY | W_AO;
            else if (strcmp(optarg, "diffuse") == 0) workloads = W_PRIMARY | W_DIFFUSE;
            else if (strcmp(optarg, "whitted") == 0) workloads = W_PRIMARY | W_WHITTED;
            else if (strcmp(optarg, "all") == 0) workloads = W_PRIMARY | W_SHADOW | W_AO | W_DIFFUSE | W_WHITTED;
            else return tool_usage_error(TOOL, "unknown workload '%s' (known: primary, shadow, ao, diffuse, whitted, all)", optarg);
            break;
        case OPT_EYE: if (!tool_parse_vec3(optarg, eye)) return tool_usage_error(TOOL, "--eye needs X,Y,Z, got '%s'", optarg); have_eye = 1; break;
        case OPT_TARGET: if (!tool_parse_vec3(optarg, target)) return tool_usage_error(TOOL, "--target needs X,Y,Z, got '%s'", optarg); have_target = 1; break;
        case OPT_UP: if (!tool_parse_vec3(optarg, up)) return tool_usage_error(TOOL, "--up needs X,Y,Z, got '%s'", optarg); have_up = 1; break;
        case OPT_CAMERA: camera_path = optarg; break;
        case OPT_FOV:
            if (!tool_parse_float(optarg, &fov) || fov <= 0 || fov >= 180) return tool_usage_error(TOOL, "--fov needs degrees in (0, 180), got '%s'", optarg);
            have_fov = 1;
            break;
        case 'W': if (!tool_parse_u32(optarg, &width) || !width || width > 32768) return tool_usage_error(TOOL, "--width needs 1..32768, got '%s'", optarg); break;
        case 'H': if (!tool_parse_u32(optarg, &height) || !height || height > 32768) return tool_usage_error(TOOL, "--height needs 1..32768, got '%s'", optarg); break;
        case OPT_LIGHT:
            if (light_count == 16) return tool_usage_error(TOOL, "at most 16 lights");
            if (!tool_parse_vec3(optarg, lights + 3 * light_count)) return tool_usage_error(TOOL, "--light needs X,Y,Z, got '%s'", optarg);
            ++light_count;
            break;
        case OPT_AO_RAYS: if (!tool_parse_u32(optarg, &ao_rays) || !ao_rays || ao_rays > 1024) return tool_usage_error(TOOL, "--ao-rays needs 1..1024, got '%s'", optarg); break;
        case OPT_AO_RADIUS: if (!tool_parse_float(optarg, &ao_radius) || ao_radius <= 0) return tool_usage_error(TOOL, "--ao-radius needs a number > 0, got '%s'", optarg); break;
        case OPT_DIFFUSE_RAYS: if (!tool_parse_u32(optarg, &diffuse_rays) || !diffuse_rays || diffuse_rays > 1024) return tool_usage_error(TOOL, "--diffuse-rays needs 1..1024, got '%s'", optarg); break;
        case OPT_DUMP: dump_dir = optarg; break;
        case OPT_RAY_LIMIT: if (!tool_parse_u32(optarg, &ray_limit) || !ray_limit) return tool_usage_error(TOOL, "--ray-limit needs a positive ray count, got '%s'", optarg); break;
        case OPT_RAYS: rays_path = optarg; break;
        case OPT_HITS: hits_path = optarg; break;
        case 'i': image_path = optarg; break;
        case OPT_HEAT_MAP: heat_path = optarg; break;
        case OPT_REBUILD: rebuild_path = optarg; break;
        case OPT_MATERIALS: materials_path = optarg; break;
        case OPT_VALIDATION_RECORD: record_path = optarg; break;
        case OPT_HEAT_MAX: if (!tool_parse_u32(optarg, &heat_max) || !heat_max) return tool_usage_error(TOOL, "--heat-max needs a positive step count, got '%s'", optarg); break;
        case OPT_ANY: any_hit = 1; break;
        case OPT_RUNS: if (!tool_parse_u32(optarg, &u) || !u || u > 1000) return tool_usage_error(TOOL, "--runs needs 1..1000, got '%s'", optarg); targs.timed_runs = u; break;
        case OPT_SCHEDULE:
            if (strcmp(optarg, "persistent") == 0) targs.schedule = AS_SCHEDULE_PERSISTENT;
            else if (strcmp(optarg, "thread") == 0) targs.schedule = AS_SCHEDULE_THREAD_PER_RAY;
            else return tool_usage_error(TOOL, "unknown schedule '%s' (known: persistent, thread)", optarg);
            break;
        case OPT_BATCH: if (!tool_parse_u32(optarg, &u) || u < 1 || u > 4096) return tool_usage_error(TOOL, "--batch needs 1..4096, got '%s'", optarg); targs.batch = u; break;
        case OPT_STATS: targs.collect_stats = true; break;
        case OPT_SHUFFLE: shuffle = 1; break;
        case OPT_INTERSECTOR:
            if (strcmp(optarg, "watertight") == 0) targs.intersector = AS_INTERSECTOR_WATERTIGHT;
            else if (strcmp(optarg, "watertight-double") == 0) targs.intersector = AS_INTERSECTOR_WATERTIGHT_DOUBLE;
            else if (strcmp(optarg, "moller-trumbore") == 0) targs.intersector = AS_INTERSECTOR_MOLLER_TRUMBORE;
            else return tool_usage_error(TOOL, "unknown intersector '%s' (known: watertight, watertight-double, moller-trumbore)", optarg);
            break;
        case OPT_BOUNCES: if (!tool_parse_u32(optarg, &bounces) || bounces > 64) return tool_usage_error(TOOL, "--bounces needs 0..64, got '%s'", optarg); break;
        case OPT_RESIDENCY:
            if (strcmp(optarg, "auto") == 0) targs.residency = AS_RESIDENCY_AUTO;
            else if (strcmp(optarg, "device") == 0) targs.residency = AS_RESIDENCY_DEVICE;
            else if (strcmp(optarg, "zero-copy") == 0) targs.residency = AS_RESIDENCY_ZERO_COPY;
            else return tool_usage_error(TOOL, "unknown residency '%s' (known: auto, device, zero-copy)", optarg);
            break;
        case OPT_UPLOAD:
            if (strcmp(optarg, "pipeline") == 0) targs.upload = AS_UPLOAD_PINNED_PIPELINE;
            else if (strcmp(optarg, "pageable") == 0) targs.upload = AS_UPLOAD_PAGEABLE;
            else if (strcmp(optarg, "registered") == 0) targs.upload = AS_UPLOAD_REGISTERED;
            else return tool_usage_error(TOOL, "unknown upload method '%s' (known: pipeline, pageable, registered)", optarg);
            break;
        case OPT_UPLOAD_THREADS:
            if (!tool_parse_u32(optarg, &targs.upload_threads) || !targs.upload_threads || targs.upload_threads > 64)
                return tool_usage_error(TOOL, "--upload-threads needs 1..64, got '%s'", optarg);
            break;
        case OPT_UPLOAD_CHUNK:
            if (!tool_parse_u32(optarg, &targs.upload_chunk_mib) || !targs.upload_chunk_mib || targs.upload_chunk_mib > 256)
                return tool_usage_error(TOOL, "--upload-chunk needs 1..256 (MiB), got '%s'", optarg);
            break;
        case OPT_MEMLIMIT: {
            char *end;
            const unsigned long long v = strtoull(optarg, &end, 10);
            if (end == optarg || *end || v == 0) return tool_usage_error(TOOL, "--memory-limit needs a byte count, got '%s'", optarg);
            targs.device_memory_limit = v;
            break;
        }
        case OPT_VERIFY:
            verify_samples = 100000;
            if (optarg && (!tool_parse_u32(optarg, &u) || !u)) return tool_usage_error(TOOL, "--verify needs a positive count, got '%s'", optarg);
            if (optarg) verify_samples = u;
            break;
        case OPT_THREADS: if (!tool_parse_u32(optarg, &u)) return tool_usage_error(TOOL, "--threads needs an integer, got '%s'", optarg); targs.thread_count = u; break;
        case 'f':
            if (strcmp(optarg, "json") == 0) json = 1;
            else if (strcmp(optarg, "text") == 0) json = 0;
            else return tool_usage_error(TOOL, "unknown format '%s' (known: text, json)", optarg);
            break;
        case OPT_NO_CHECKSUM: load.verify_checksums = false; break;
        case 'h': usage(); return EXIT_OK;
        case 'V': tool_print_version(TOOL); return EXIT_OK;
        default: return tool_usage_error(TOOL, "unknown or incomplete option '%s'", argv[optind - 1]);
        }
    }
    if (optind != argc - 1) return tool_usage_error(TOOL, "expected one .asf file, got %d", argc - optind);
    if (rays_path && (image_path || heat_path || workloads != W_PRIMARY))
        return tool_usage_error(TOOL, "--rays traces the file's rays: it cannot be used with --image, --heat-map or --workload");
    if (ray_limit && (workloads & W_WHITTED))
        return tool_usage_error(TOOL, "--ray-limit does not apply to whitted, whose bounces each trace the rays of the one before: use -w primary, shadow, ao or diffuse");
    if (materials_path && !(workloads & W_WHITTED))
        return tool_usage_error(TOOL, "--materials gives the whitted workload's materials: use it with -w whitted or all");
    if (have_eye != have_target) return tool_usage_error(TOOL, "--eye and --target go together");
    struct stat dump_st;
    if (dump_dir && (stat(dump_dir, &dump_st) != 0 || !S_ISDIR(dump_st.st_mode))) {
        fprintf(stderr, "%s: error: --dump %s: not a directory\n", TOOL, dump_dir);
        return EXIT_IO;
    }
    const char *path = argv[optind];

    /* The CUDA context is made before the clock starts: the load time is
     * from opening the file to ready to launch, without it. */
    if (targs.device == AS_DEVICE_GPU || (targs.device == AS_DEVICE_AUTO && as_gpu_available())) (void)as_gpu_prepare();
    const double t_open = as_now_ms_tool();
    as_structure_t *s = as_structure_load(path, &load);
    if (!s) return tool_fail(TOOL);
    const double t_loaded = as_now_ms_tool();
    int code = EXIT_OK;
    as_ray_t *rays = NULL, *sec = NULL;
    as_hit_t *hits = NULL, *sec_hits = NULL, *pixels = NULL;
    uint32_t *pixel_of_ray = NULL, *sec_from = NULL, *ray_steps = NULL, *heat = NULL, heat_scale = 0;
    float *ao = NULL;
    as_mesh_t *source_mesh = NULL;
    as_material_t *materials = NULL;
    uint32_t material_count = 0, material_kinds[3] = {0, 0, 0};
    size_t count = 0, nres = 0;
    run_result res[MAX_RESULTS];
    as_camera_t cam;
    as_structure_stats_t st;
    /* Always: a kernel must never read a file that could send it out of
     * bounds, and validation costs one linear pass (or, for a file the
     * record vouches for, one hash of its bytes). */
    as_validation_info_t vinfo;
    memset(&vinfo, 0, sizeof vinfo);
    const bool gpu = targs.device == AS_DEVICE_GPU || (targs.device == AS_DEVICE_AUTO && as_gpu_available());
    /* Bound for the GPU without a record, the upload validates: on the GPU
     * after the copy where the layout can, else on the CPU before it. */
    const bool validate_first = record_path || !gpu;
    if ((validate_first && as_structure_validate_recorded(s, record_path, &vinfo) != AS_OK) ||
        as_structure_get_header_stats(s, &st) != AS_OK) {
        code = tool_fail(TOOL);
        goto done;
    }
    const double t_validated = as_now_ms_tool();
    as_upload_info_t upinfo;
    memset(&upinfo, 0, sizeof upinfo);
    if (gpu && as_structure_upload(s, &targs, &upinfo) != AS_OK) { code = tool_fail(TOOL); goto done; }
    const double t_ready = as_now_ms_tool();
    const double validate_ms = validate_first ? t_validated - t_loaded : upinfo.validate_ms;
    const char *validated_on = validate_first ? (vinfo.skipped ? "skipped" : "cpu") : upinfo.validated;
    if (rebuild_path && (code = source_mesh_import(rebuild_path, &st, &source_mesh))) goto done;
    if (materials_path) {
        /* The .asf keeps no materials: they come from the OBJ (its usemtl
         * per triangle, its .mtl files), checked to be the structure's mesh. */
        as_mesh_t *obj = NULL;
        if ((code = source_mesh_import(materials_path, &st, &obj))) goto done;
        const as_error_t e = as_materials_read_obj(materials_path, obj, &materials, &material_count);
        as_mesh_release(obj);
        if (e != AS_OK) { code = tool_fail(TOOL); goto done; }
        for (uint32_t t = 0; t < material_count; ++t)
            ++material_kinds[materials[t].kind <= AS_MATERIAL_GLASS ? materials[t].kind : AS_MATERIAL_OPAQUE];
    }
    if (rays_path) {
        if (as_rays_read(rays_path, &rays, &count) != AS_OK) { code = tool_fail(TOOL); goto done; }
    } else {
        as_camera_default(st.bounds_lo, st.bounds_hi, &cam);
        if (camera_path && as_camera_read(camera_path, &cam) != AS_OK) { code = tool_fail(TOOL); goto done; }
        if (have_eye) { memcpy(cam.eye, eye, sizeof eye); memcpy(cam.target, target, sizeof target); }
        if (have_up || !camera_path) memcpy(cam.up, up, sizeof up);
        if (have_fov) cam.fov_y_degrees = fov;
        count = (size_t)width * height;
        rays = malloc(sizeof *rays * count);
        pixel_of_ray = malloc(sizeof *pixel_of_ray * count);
        if (!rays || !pixel_of_ray) { fprintf(stderr, "%s: error: out of memory for %zu rays\n", TOOL, count); code = EXIT_RUNTIME; goto done; }
        as_camera_rays_tiled(&cam, width, height, rays, pixel_of_ray);
    }
    hits = malloc(sizeof *hits * (count ? count : 1));
    if (!hits) { fprintf(stderr, "%s: error: out of memory for %zu hits\n", TOOL, count); code = EXIT_RUNTIME; goto done; }
    as_trace_args_t primary_args = targs;
    if (heat_path) {
        ray_steps = malloc(sizeof *ray_steps * (count ? count : 1));
        heat = malloc(sizeof *heat * (count ? count : 1));
        if (!ray_steps || !heat) { fprintf(stderr, "%s: error: out of memory for %zu step counts\n", TOOL, count); code = EXIT_RUNTIME; goto done; }
        primary_args.collect_stats = true;
        primary_args.ray_steps = ray_steps;
    }
    /* With --ray-limit, the first rays of the file are all there is; the
     * camera's rays are traced in full once (one launch, not reported) for
     * the hits the secondary rays, the image and the hit file start from,
     * then the first ray_limit of them are timed. */
    const size_t workload_count = count;
    if (rays_path && ray_limit && ray_limit < count) count = ray_limit;
    const size_t primary_traced = ray_limit && ray_limit < count ? ray_limit : count;
    if (primary_traced < count) {
        as_trace_args_t full = primary_args;
        full.timed_runs = 1;
        as_trace_timing_t full_timing;
        if (as_trace(s, rays, count, hits, &full, &full_timing) != AS_OK) { code = tool_fail(TOOL); goto done; }
        primary_args = targs;
    }
    if ((code = trace_one(rays_path ? "file" : "primary", s, rays, primary_traced, hits, &primary_args,
                          rays_path && any_hit, &res[nres++])))
        goto done;
    res[nres - 1].workload_rays = workload_count;
    if (heat_path) {
        /* The same image code for both devices: only the counts differ in
         * where they were taken. */
        for (size_t i = 0; i < count; ++i) heat[pixel_of_ray[i]] = ray_steps[i];
        if (as_image_write_png_heat(heat_path, width, height, heat, heat_max, &heat_scale) != AS_OK) { code = tool_fail(TOOL); goto done; }
    }

    if (!rays_path && light_count == 0 && (workloads & (W_SHADOW | W_WHITTED))) {
        as_lights_default(st.bounds_lo, st.bounds_hi, lights);
        light_count = 4;
    }
    for (int w = W_SHADOW; w <= W_DIFFUSE; w <<= 1) {
        if (!(workloads & w)) continue;
        size_t n = 0;
        free(sec);
        free(sec_hits);
        free(sec_from);
        sec = NULL; sec_hits = NULL; sec_from = NULL;
        as_error_t e;
        if (w == W_SHADOW) {
            e = as_rays_shadow(s, rays, hits, count, lights, light_count, 1e-4f, &sec, &n, &sec_from);
        } else {
            as_secondary_args_t sa;
            as_secondary_args_default(&sa);
            sa.rays_per_hit = w == W_AO ? ao_rays : diffuse_rays;
            sa.tmax_fraction = w == W_AO ? ao_radius : 0.0f;
            sa.seed = w == W_AO ? 1 : 2;
            e = as_rays_hemisphere(s, rays, hits, count, &sa, &sec, &n, &sec_from);
        }
        if (e != AS_OK) { code = tool_fail(TOOL); goto done; }
        if (shuffle) shuffle_rays(sec, sec_from, n);
        sec_hits = malloc(sizeof *sec_hits * (n ? n : 1));
        if (!sec_hits) { fprintf(stderr, "%s: error: out of memory for %zu hits\n", TOOL, n); code = EXIT_RUNTIME; goto done; }
        const char *name = w == W_SHADOW ? (shuffle ? "shadow random" : "shadow")
                         : w == W_AO ? (shuffle ? "ao random" : "ao") : (shuffle ? "diffuse random" : "diffuse");
        const size_t traced = ray_limit && ray_limit < n ? ray_limit : n;
        if ((code = trace_one(name, s, sec, traced, sec_hits, &targs, w != W_DIFFUSE, &res[nres++]))) goto done;
        res[nres - 1].workload_rays = n;
        if (w == W_AO && image_path) {
            /* Per pixel: the fraction of AO rays that escape. */
            ao = calloc((size_t)width * height, sizeof *ao);
            float *total = calloc((size_t)width * height, sizeof *total);
            if (!ao || !total) { free(total); fprintf(stderr, "%s: error: out of memory\n", TOOL); code = EXIT_RUNTIME; goto done; }
            for (size_t i = 0; i < traced; ++i) {
                const uint32_t p = pixel_of_ray[sec_from[i]];
                total[p] += 1.0f;
                ao[p] += sec_hits[i].prim == AS_NO_HIT ? 1.0f : 0.0f;
            }
            for (size_t p = 0; p < (size_t)width * height; ++p) ao[p] = total[p] > 0 ? ao[p] / total[p] : -1.0f;
            free(total);
        }
    }

    if (workloads & W_WHITTED) {
        /* One bounce at a time: the shadow rays of this bounce's hits, then
         * its reflection and refraction rays, traced for the next. */
        as_whitted_args_t wa;
        as_whitted_args_default(&wa);
        wa.lights = lights;
        wa.light_count = light_count;
        wa.materials = materials;
        wa.material_count = material_count;
        const as_ray_t *cur = rays;
        const as_hit_t *cur_hits = hits;
        size_t cur_n = count;
        as_ray_t *owned_rays = NULL;
        as_hit_t *owned_hits = NULL;
        size_t total_rays = count;
        double total_ms = res[0].timing.trace_ms;
        for (unsigned b = 0; b <= bounces && nres + 2 < MAX_RESULTS; ++b) {
            as_ray_t *nx = NULL, *sh = NULL;
            size_t nn = 0, ns = 0;
            if (as_rays_whitted_bounce(s, cur, cur_hits, cur_n, &wa, &nx, &nn, &sh, &ns) != AS_OK) {
                code = tool_fail(TOOL);
                free(owned_rays); free(owned_hits);
                goto done;
            }
            as_hit_t *sh_hits = malloc(sizeof *sh_hits * (ns ? ns : 1));
            as_hit_t *nx_hits = malloc(sizeof *nx_hits * (nn ? nn : 1));
            char name[32];
            snprintf(name, sizeof name, "whitted %u shadow", b);
            if (!sh_hits || !nx_hits ||
                (code = trace_one(name, s, sh, ns, sh_hits, &targs, true, &res[nres++]))) {
                free(sh); free(nx); free(sh_hits); free(nx_hits); free(owned_rays); free(owned_hits);
                if (!code) code = EXIT_RUNTIME;
                goto done;
            }
            total_rays += ns;
            total_ms += res[nres - 1].timing.trace_ms;
            free(sh);
            free(sh_hits);
            free(owned_rays);
            free(owned_hits);
            owned_rays = nx;
            owned_hits = nx_hits;
            if (nn == 0 || b == bounces) break;
            snprintf(name, sizeof name, "whitted %u", b + 1);
            if ((code = trace_one(name, s, nx, nn, nx_hits, &targs, false, &res[nres++]))) {
                free(owned_rays); free(owned_hits);
                goto done;
            }
            total_rays += nn;
            total_ms += res[nres - 1].timing.trace_ms;
            cur = nx;
            cur_hits = nx_hits;
            cur_n = nn;
        }
        free(owned_rays);
        free(owned_hits);
        if (nres < MAX_RESULTS) {
            run_result *t = &res[nres++];
            memset(t, 0, sizeof *t);
            snprintf(t->name, sizeof t->name, "whitted total");
            t->rays = total_rays;
            t->timing.device = res[0].timing.device;
            t->timing.trace_ms = total_ms;
        }
    }

    /* After the traces, so that the build's threads do not disturb them. */
    as_structure_stats_t rebuilt;
    memset(&rebuilt, 0, sizeof rebuilt);
    bool same_structure = false;
    /* The rebuild is compared with the file's walked counts, which the
     * launch did not need. */
    if (rebuild_path && as_structure_get_stats(s, &st) != AS_OK) { code = tool_fail(TOOL); goto done; }
    if (rebuild_path && (code = rebuild(source_mesh, &st, targs.thread_count, &rebuilt, &same_structure)))
        goto done;

    if (json) {
        printf("{\n  \"file\": ");
        tool_print_json_string(path);
        printf(",\n  \"device\": \"%s\",\n  \"device_name\": ", res[0].timing.device == AS_DEVICE_GPU ? "gpu" : "cpu");
        tool_print_json_string(res[0].timing.device_name);
        printf(",\n");
        printf("  \"open_ms\": %.3f,\n  \"validate_ms\": %.3f,\n  \"validated_on\": \"%s\",\n"
               "  \"upload_method\": \"%s\",\n  \"upload_ms\": %.3f,\n"
               "  \"upload_bytes\": %llu,\n  \"upload_gb_per_s\": %.3f,\n  \"load_ms\": %.3f,\n",
               t_loaded - t_open, validate_ms, validated_on, gpu ? upinfo.method : "none", upinfo.upload_ms,
               (unsigned long long)upinfo.bytes, upinfo.gb_per_s, t_ready - t_open);
        if (record_path) {
            printf("  \"validation_record\": ");
            tool_print_json_string(record_path);
            printf(",\n  \"validation\": \"%s\",\n  \"fingerprint_ms\": %.3f,\n", vinfo.skipped ? "skipped" : "done",
                   vinfo.fingerprint_ms);
        }
        if (heat_path) {
            printf("  \"heat_map\": ");
            tool_print_json_string(heat_path);
            printf(",\n  \"heat_max_steps\": %u,\n  \"heat_scale\": \"%s\",\n", heat_scale, heat_max ? "fixed" : "percentile 99");
        }
        if (st.build_threads)
            printf("  \"rebuild_recorded_ms\": %.3f,\n  \"rebuild_recorded_threads\": %u,\n", st.build_ms, st.build_threads);
        else
            printf("  \"rebuild_recorded_ms\": null,\n  \"rebuild_recorded_threads\": null,\n");
        if (rebuild_path) {
            printf("  \"rebuild_mesh\": ");
            tool_print_json_string(rebuild_path);
            printf(",\n  \"rebuild_measured_ms\": %.3f,\n  \"rebuild_measured_threads\": %u,\n"
                   "  \"rebuild_same_structure\": %s,\n", rebuilt.build_ms, rebuilt.build_threads,
                   same_structure ? "true" : "false");
        } else {
            printf("  \"rebuild_measured_ms\": null,\n");
        }
        if (materials_path) {
            printf("  \"materials\": ");
            tool_print_json_string(materials_path);
            printf(",\n  \"opaque_triangles\": %u,\n  \"mirror_triangles\": %u,\n  \"glass_triangles\": %u,\n",
                   material_kinds[AS_MATERIAL_OPAQUE], material_kinds[AS_MATERIAL_MIRROR], material_kinds[AS_MATERIAL_GLASS]);
        }
        printf("  \"workloads\": [\n");
        for (size_t i = 0; i < nres; ++i) print_json(&res[i], res[i].any_hit, i + 1 == nres);
        printf("  ]\n}\n");
    } else {
        if (!rays_path)
            printf("camera:    eye %g,%g,%g target %g,%g,%g up %g,%g,%g fov %g, %ux%u\n", (double)cam.eye[0],
                   (double)cam.eye[1], (double)cam.eye[2], (double)cam.target[0], (double)cam.target[1],
                   (double)cam.target[2], (double)cam.up[0], (double)cam.up[1], (double)cam.up[2],
                   (double)cam.fov_y_degrees, width, height);
        printf("device:    %s %s\n", res[0].timing.device == AS_DEVICE_GPU ? "gpu" : "cpu", res[0].timing.device_name);
        printf("load:      %.1f ms from open to ready (open and checks %.1f, ", t_ready - t_open, t_loaded - t_open);
        if (!record_path && validate_first)
            printf("validation %.1f", validate_ms);
        else if (!record_path)
            printf("validation %.1f on the %s", validate_ms, strcmp(validated_on, "gpu") == 0 ? "GPU" : "CPU");
        else if (vinfo.skipped)
            printf("validation skipped: fingerprint %.1f, listed in %s", vinfo.fingerprint_ms, record_path);
        else
            printf("validation %.1f, fingerprint %.1f, added to %s", vinfo.validate_ms, vinfo.fingerprint_ms, record_path);
        if (gpu)
            printf(", %s %.1f: %llu bytes at %.2f GB/s", upinfo.method, upinfo.upload_ms, (unsigned long long)upinfo.bytes, upinfo.gb_per_s);
        printf(")\n");
        if (rebuild_path) {
            printf("rebuild:   ");
            if (st.build_threads)
                printf("%.1f ms on %u thread%s as recorded in the file", st.build_ms, st.build_threads,
                       st.build_threads == 1 ? "" : "s");
            else
                printf("not recorded in the file");
            printf("; %.1f ms on %u thread%s measured now from %s (%s)\n", rebuilt.build_ms, rebuilt.build_threads,
                   rebuilt.build_threads == 1 ? "" : "s", rebuild_path, same_structure ? "the same structure" : "a different structure: the file's build "
                   "had settings the file does not record");
        }
        if (materials_path)
            printf("materials: %s: %u mirror, %u glass, %u opaque triangles, from its material files\n", materials_path,
                   material_kinds[AS_MATERIAL_MIRROR], material_kinds[AS_MATERIAL_GLASS], material_kinds[AS_MATERIAL_OPAQUE]);
        for (size_t i = 0; i < nres; ++i) print_text(&res[i], res[i].any_hit);
        printf("Mrays/s:   %.2f (%s)\n", mrays(&res[0]), res[0].name);
    }
    if (hits_path) {
        /* Hits in the order of the rays: the file's, or row-major pixels. */
        const as_hit_t *outh = hits;
        if (pixel_of_ray) {
            pixels = malloc(sizeof *pixels * count);
            if (!pixels) { fprintf(stderr, "%s: error: out of memory\n", TOOL); code = EXIT_RUNTIME; goto done; }
            for (size_t i = 0; i < count; ++i) pixels[pixel_of_ray[i]] = hits[i];
            outh = pixels;
        }
        if (as_hits_write(hits_path, outh, count) != AS_OK) { code = tool_fail(TOOL); goto done; }
        if (!json) printf("hits:      %s\n", hits_path);
    }
    if (image_path) {
        as_error_t e;
        if (ao) {
            e = as_image_write_png_grey(image_path, width, height, ao);
        } else {
            /* Back to row-major order for the image. */
            as_ray_t *prow = malloc(sizeof *prow * count);
            as_hit_t *hrow = malloc(sizeof *hrow * count);
            if (!prow || !hrow) { free(prow); free(hrow); fprintf(stderr, "%s: error: out of memory\n", TOOL); code = EXIT_RUNTIME; goto done; }
            for (size_t i = 0; i < count; ++i) { prow[pixel_of_ray[i]] = rays[i]; hrow[pixel_of_ray[i]] = hits[i]; }
            e = as_image_write_png(s, prow, hrow, width, height, image_path);
            free(prow);
            free(hrow);
        }
        if (e != AS_OK) { code = tool_fail(TOOL); goto done; }
        if (!json) printf("image:     %s\n", image_path);
    }
    if (heat_path && !json)
        printf("heat map:  %s: steps per primary ray, 0 dark purple to %u yellow (%s)\n", heat_path, heat_scale,
               heat_max ? "--heat-max" : "99th percentile");
done:
    free(rays);
    free(hits);
    free(sec);
    free(sec_hits);
    free(sec_from);
    free(pixels);
    free(pixel_of_ray);
    free(ao);
    free(ray_steps);
    free(heat);
    as_mesh_release(source_mesh);
    free(materials);
    as_structure_release(s);
    return code;
}
