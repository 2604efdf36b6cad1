/* Build benchmark: every structure variant on every scene given, beside
 * Embree 3's builders in the same run, as the reference builder.
 *
 *   bench_build [--runs N] [--paired R] [--threads N] [--out FILE.md] [--commit ID] [--only TEXT] SCENE...
 *
 * For each variant and scene: build time (median of N runs after a first
 * one, monotonic clock), the first build's time, triangles per second, peak
 * build memory (the rise of the resident set during the first build,
 * measured in a child process), structure memory and SAH cost. Embree: one
 * triangle geometry, rtcCommitScene, every core, medium and high (spatial
 * splits) quality, the same builds (a first one in a new device, then the
 * median of N). A process's first build faults in the memory that later
 * ones reuse, the more so the more temporaries a builder has; the first
 * build's column says what a single build in a new process costs.
 *
 * Then the build-time targets, as ratios. On a shared machine a variant's N
 * builds can fall in a slow stretch that its reference's builds miss, so
 * each ratio is also taken in R paired rounds (default 7, after one round
 * not counted): one round builds binned SAH, Embree medium, SBVH, Embree
 * high, KD SAH, BIH and the grid back to back in one process (every other
 * round in reverse order), and the ratio printed is the median of the
 * rounds' ratios, with their range (with BENCH_ROUNDS set in the
 * environment, each round's times go to stderr). The
 * targets are judged on those. A benchmark, not a test: it prints figures
 * and asserts nothing. */
#include "as/as.h"

#include <embree3/rtcore.h>

#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/resource.h>
#include <sys/utsname.h>
#include <sys/wait.h>
#include <time.h>
#include <unistd.h>

typedef struct variant {
    const char *name;        /* the paper's row */
    const char *structure, *builder, *layout;
} variant;

static const variant variants[] = {
    {"BVH (Mid. Cut)", "bvh", "midcut", "bvh2-child-bounds"},
    {"BVH (SAH, binned)", "bvh", "sah", "bvh2-child-bounds"},
    {"BVH (SAH, sweep)", "bvh", "sweep", "bvh2-child-bounds"},
    {"BVH (SBVH)", "bvh", "sbvh", "bvh2-child-bounds"},
    {"KD Standard (Mid. Cut)", "kd", "midcut", "kd-standard"},
    {"KD Standard (SAH)", "kd", "sah", "kd-standard"},
    {"KD Ropes (Mid. Cut)", "kd", "midcut", "kd-ropes"},
    {"KD Ropes (SAH)", "kd", "sah", "kd-ropes"},
    {"BIH", "bih", "bih", "bih"},
    {"Octree", "octree", "octree", "octree"},
    {"Uniform Grid", "grid", "grid", "grid"},
};
#define NVARIANTS (sizeof variants / sizeof variants[0])

static int variant_args(const variant *v, unsigned threads, as_build_args_t *args)
{
    as_build_args_default(args);
    args->structure = as_structure_kind_from_name(v->structure);
    args->builder = as_builder_from_name(args->structure, v->builder);
    args->layout = as_layout_from_name(v->layout);
    args->thread_count = threads;
    return args->structure && args->builder && args->layout;
}

typedef struct result {
    int ok;
    double ms;               /* median of the builds after the first */
    double first_ms;         /* the first build in the process */
    double peak_mb;
    double size_mb;
    double sah;
    char error[160];
} result;

static double now_ms(void)
{
    struct timespec ts;
    clock_gettime(CLOCK_MONOTONIC, &ts);
    return ts.tv_sec * 1e3 + ts.tv_nsec * 1e-6;
}

static int cmp_double(const void *a, const void *b)
{
    const double x = *(const double *)a, y = *(const double *)b;
    return x < y ? -1 : x > y;
}

static double median(double *v, int n)
{
    qsort(v, (size_t)n, sizeof *v, cmp_double);
    return n % 2 ? v[n / 2] : 0.5 * (v[n / 2 - 1] + v[n / 2]);
}

static long rss_kb(void)
{
    FILE *f = fopen("/proc/self/statm", "r");
    long pages = 0, resident = 0;
    if (f) {
        if (fscanf(f, "%ld %ld", &pages, &resident) != 2) resident = 0;
        fclose(f);
    }
    return resident * (sysconf(_SC_PAGESIZE) / 1024);
}

/* Runs the builds of one variant in a child, so that its peak resident set
 * is the build's alone; the result comes back through a pipe. */
static result run_variant(const as_mesh_t *mesh, const variant *v, int runs, unsigned threads)
{
    result r;
    memset(&r, 0, sizeof r);
    as_build_args_t args;
    if (!variant_args(v, threads, &args)) {
        snprintf(r.error, sizeof r.error, "not in this build");
        return r;
    }
    int fd[2];
    if (pipe(fd) != 0) return r;
    const pid_t pid = fork();
    if (pid == 0) {
        close(fd[0]);
        result c;
        memset(&c, 0, sizeof c);
        double times[65];
        const long rss0 = rss_kb();
        for (int i = 0; i <= runs && i < 65; ++i) {
            const double t0 = now_ms();
            as_structure_t *s = as_structure_build(mesh, &args);
            times[i] = now_ms() - t0;
            if (!s) {
                snprintf(c.error, sizeof c.error, "%s", as_get_error_message());
                break;
            }
            if (i == 0) {
                c.first_ms = times[0];
                struct rusage ru;
                getrusage(RUSAGE_SELF, &ru);
                c.peak_mb = (ru.ru_maxrss - rss0) / 1024.0;
                as_structure_stats_t st;
                as_structure_get_stats(s, &st);
                c.size_mb = st.structure_bytes / 1e6;
                c.sah = st.sah_cost;
            }
            as_structure_release(s);
            if (i == runs) {
                c.ok = 1;
                c.ms = median(times + 1, runs);
            }
        }
        if (write(fd[1], &c, sizeof c) != (ssize_t)sizeof c) _exit(1);
        _exit(0);
    }
    close(fd[1]);
    if (read(fd[0], &r, sizeof r) != (ssize_t)sizeof r) snprintf(r.error, sizeof r.error, "builder process died");
    close(fd[0]);
    int status;
    waitpid(pid, &status, 0);
    return r;
}

/* An Embree device; with a fixed thread count, the same as ours. */
static RTCDevice embree_device(unsigned threads)
{
    char config[64] = "";
    if (threads) snprintf(config, sizeof config, "threads=%u", threads);
    return rtcNewDevice(threads ? config : NULL);
}

/* One Embree build of the mesh: the time of rtcCommitScene. */
static double embree_build_once(RTCDevice dev, const as_mesh_t *mesh, enum RTCBuildQuality quality)
{
    as_mesh_info_t info;
    as_mesh_get_info(mesh, &info);
    RTCScene scene = rtcNewScene(dev);
    rtcSetSceneBuildQuality(scene, quality);
    RTCGeometry g = rtcNewGeometry(dev, RTC_GEOMETRY_TYPE_TRIANGLE);
    rtcSetGeometryBuildQuality(g, quality);
    float *vb = rtcSetNewGeometryBuffer(g, RTC_BUFFER_TYPE_VERTEX, 0, RTC_FORMAT_FLOAT3, 3 * sizeof(float),
                                        info.vertex_count);
    unsigned *ib = rtcSetNewGeometryBuffer(g, RTC_BUFFER_TYPE_INDEX, 0, RTC_FORMAT_UINT3, 3 * sizeof(unsigned),
                                           info.triangle_count);
    memcpy(vb, as_mesh_positions(mesh), sizeof(float) * 3 * info.vertex_count);
    memcpy(ib, as_mesh_indices(mesh), sizeof(unsigned) * 3 * info.triangle_count);
    rtcCommitGeometry(g);
    rtcAttachGeometry(scene, g);
    rtcReleaseGeometry(g);
    const double t0 = now_ms();
    rtcCommitScene(scene);
    const double ms = now_ms() - t0;
    rtcReleaseScene(scene);
    return ms;
}

/* A first build in a new device (*first_ms), then the median of `runs`.
 * Embree does not expose its tree's SAH cost. */
static double embree_build(const as_mesh_t *mesh, enum RTCBuildQuality quality, int runs, unsigned threads,
                           double *first_ms)
{
    RTCDevice dev = embree_device(threads);
    double times[64];
    *first_ms = embree_build_once(dev, mesh, quality);
    for (int i = 0; i < runs && i < 64; ++i) times[i] = embree_build_once(dev, mesh, quality);
    rtcReleaseDevice(dev);
    return median(times, runs);
}

/* One build in this process; a negative time when it failed. */
static double build_once(const as_mesh_t *mesh, const as_build_args_t *args)
{
    const double t0 = now_ms();
    as_structure_t *s = as_structure_build(mesh, args);
    const double ms = now_ms() - t0;
    if (!s) return -1.0;
    as_structure_release(s);
    return ms;
}

/* The paired rounds' ratios: binned / Embree medium, SBVH / Embree high,
 * KD SAH / binned, BIH / binned, grid / binned. */
enum { PAIR_BIN_EM, PAIR_SBVH_EH, PAIR_KD_BIN, PAIR_BIH_BIN, PAIR_GRID_BIN, PAIRS };

typedef struct paired {
    int ok;
    double median[PAIRS], lo[PAIRS], hi[PAIRS];
} paired;

static paired run_paired(const as_mesh_t *mesh, int rounds, unsigned threads)
{
    paired p;
    memset(&p, 0, sizeof p);
    /* Indices into variants[] of binned SAH, SBVH, KD SAH, BIH, grid. */
    static const int ours[5] = {1, 3, 5, 8, 10};
    as_build_args_t args[5];
    for (int k = 0; k < 5; ++k)
        if (!variant_args(&variants[ours[k]], threads, &args[k])) return p;
    RTCDevice dev = embree_device(threads);
    double ratio[PAIRS][64];
    /* Round -1 is not counted: this process's first builds of ours (the
     * table's ran in child processes) would take the page faults of memory
     * that later builds reuse. */
    for (int r = -1; r < rounds && r < 64; ++r) {
        /* Seven builds: ours 0..4 and Embree medium (5) and high (6). */
        static const int order[7] = {0, 5, 1, 6, 2, 3, 4};
        double ms[7];
        for (int i = 0; i < 7; ++i) {
            const int b = order[r & 1 ? 6 - i : i];
            ms[b] = b < 5 ? build_once(mesh, &args[b])
                          : embree_build_once(dev, mesh, b == 5 ? RTC_BUILD_QUALITY_MEDIUM : RTC_BUILD_QUALITY_HIGH);
            if (ms[b] < 0.0) {
                rtcReleaseDevice(dev);
                return p;
            }
        }
        if (getenv("BENCH_ROUNDS")) fprintf(stderr, "round %d: bin %.2f em %.2f sbvh %.2f eh %.2f kd %.2f bih %.2f grid %.2f\n", r, ms[0], ms[5], ms[1], ms[6], ms[2], ms[3], ms[4]);
        if (r < 0) continue;
        ratio[PAIR_BIN_EM][r] = ms[0] / ms[5];
        ratio[PAIR_SBVH_EH][r] = ms[1] / ms[6];
        ratio[PAIR_KD_BIN][r] = ms[2] / ms[0];
        ratio[PAIR_BIH_BIN][r] = ms[3] / ms[0];
        ratio[PAIR_GRID_BIN][r] = ms[4] / ms[0];
    }
    rtcReleaseDevice(dev);
    const int n = rounds < 64 ? rounds : 64;
    for (int k = 0; k < PAIRS; ++k) {
        p.median[k] = median(ratio[k], n); /* sorts them */
        p.lo[k] = ratio[k][0];
        p.hi[k] = ratio[k][n - 1];
    }
    p.ok = 1;
    return p;
}

int main(int argc, char **argv)
{
    int runs = 5, rounds = 7;
    unsigned threads = 0;
    const char *out = NULL, *commit = "unknown", *only = NULL;
    int first = 1;
    for (; first < argc && argv[first][0] == '-'; ++first) {
        if (!strcmp(argv[first], "--runs") && first + 1 < argc) runs = atoi(argv[++first]);
        else if (!strcmp(argv[first], "--paired") && first + 1 < argc) rounds = atoi(argv[++first]);
        else if (!strcmp(argv[first], "--threads") && first + 1 < argc) threads = (unsigned)atoi(argv[++first]);
        else if (!strcmp(argv[first], "--out") && first + 1 < argc) out = argv[++first];
        else if (!strcmp(argv[first], "--commit") && first + 1 < argc) commit = argv[++first];
        else if (!strcmp(argv[first], "--only") && first + 1 < argc) only = argv[++first];
        else {
            fprintf(stderr, "usage: %s [--runs N] [--paired R] [--threads N] [--out FILE.md] [--commit ID] [--only TEXT] SCENE...\n", argv[0]);
            return 1;
        }
    }
    if (runs < 1 || runs > 64 || rounds < 0 || rounds > 64 || first >= argc) {
        fprintf(stderr, "usage: %s [--runs N] [--paired R] [--threads N] [--out FILE.md] [--commit ID] [--only TEXT] SCENE...\n", argv[0]);
        return 1;
    }
    FILE *md = out ? fopen(out, "w") : NULL;
    if (out && !md) { perror(out); return 2; }
    struct utsname un;
    uname(&un);
    char cpu[256] = "unknown";
    FILE *ci = fopen("/proc/cpuinfo", "r");
    if (ci) {
        char line[512];
        while (fgets(line, sizeof line, ci))
            if (!strncmp(line, "model name", 10)) {
                const char *c = strchr(line, ':');
                if (c) snprintf(cpu, sizeof cpu, "%s", c + 2);
                cpu[strcspn(cpu, "\n")] = 0;
                break;
            }
        fclose(ci);
    }
    char date[64];
    const time_t now = time(NULL);
    strftime(date, sizeof date, "%Y-%m-%d %H:%M UTC", gmtime(&now));
    const long cores = sysconf(_SC_NPROCESSORS_ONLN);
    char header[1024];
    snprintf(header, sizeof header,
             "date %s; machine %s %s, %s, %ld cores; commit %s; libas %s; Embree %d.%d.%d; median of %d builds after a first, %s threads; "
             "target ratios from %d paired rounds\n",
             date, un.nodename, un.machine, cpu, cores, commit, as_version_string(), RTC_VERSION_MAJOR,
             RTC_VERSION_MINOR, RTC_VERSION_PATCH, runs, threads ? "fixed" : "all", rounds);
    printf("%s", header);
    if (md) fprintf(md, "# Build benchmark\n\n%s\n", header);

    for (int si = first; si < argc; ++si) {
        as_mesh_t *mesh = as_mesh_import(argv[si]);
        if (!mesh) {
            fprintf(stderr, "%s\n", as_get_error_message());
            continue;
        }
        as_mesh_info_t info;
        as_mesh_get_info(mesh, &info);
        const double mtri = info.triangle_count / 1e6;
        printf("\n%s: %u triangles\n", argv[si], info.triangle_count);
        printf("%-24s %10s %10s %10s %10s %10s %10s\n", "variant", "build ms", "first ms", "Mtris/s", "peak MB", "size MB",
               "SAH cost");
        if (md) {
            fprintf(md, "\n## %s (%u triangles)\n\n| variant | build ms | first build ms | M triangles/s | peak build MB | structure MB | SAH cost |\n|---|---:|---:|---:|---:|---:|---:|\n",
                    argv[si], info.triangle_count);
        }
        result res[NVARIANTS];
        for (size_t v = 0; v < NVARIANTS; ++v) {
            if (only && !strstr(variants[v].name, only)) {
                memset(&res[v], 0, sizeof res[v]);
                continue;
            }
            res[v] = run_variant(mesh, &variants[v], runs, threads);
            if (res[v].ok) {
                printf("%-24s %10.1f %10.1f %10.2f %10.1f %10.2f %10.3f\n", variants[v].name, res[v].ms, res[v].first_ms,
                       mtri / (res[v].ms / 1e3), res[v].peak_mb, res[v].size_mb, res[v].sah);
                if (md) fprintf(md, "| %s | %.1f | %.1f | %.2f | %.1f | %.2f | %.3f |\n", variants[v].name, res[v].ms,
                                res[v].first_ms, mtri / (res[v].ms / 1e3), res[v].peak_mb, res[v].size_mb, res[v].sah);
            } else {
                printf("%-24s %s\n", variants[v].name, res[v].error);
                if (md) fprintf(md, "| %s | %s | | | | | |\n", variants[v].name, res[v].error);
            }
            fflush(stdout);
        }
        double em_first, eh_first;
        const double em = embree_build(mesh, RTC_BUILD_QUALITY_MEDIUM, runs, threads, &em_first);
        const double eh = embree_build(mesh, RTC_BUILD_QUALITY_HIGH, runs, threads, &eh_first);
        printf("%-24s %10.1f %10.1f %10.2f\n%-24s %10.1f %10.1f %10.2f\n", "Embree 3 medium", em, em_first,
               mtri / (em / 1e3), "Embree 3 high (spatial)", eh, eh_first, mtri / (eh / 1e3));
        if (md) fprintf(md, "| Embree 3 medium | %.1f | %.1f | %.2f | | | |\n| Embree 3 high (spatial splits) | %.1f | %.1f | %.2f | | | |\n",
                        em, em_first, mtri / (em / 1e3), eh, eh_first, mtri / (eh / 1e3));

        /* The build-time targets, as ratios within this run: the paired rounds'
         * medians, or without rounds those of the table's medians. */
        const result *mid = &res[0], *bin = &res[1], *sweep = &res[2], *sbvh = &res[3], *kdsah = &res[5], *bih = &res[8],
                     *grid = &res[10];
        const int have_all = bin->ok && sbvh->ok && kdsah->ok && bih->ok && grid->ok;
        paired pr;
        memset(&pr, 0, sizeof pr);
        if (rounds > 0 && have_all && !only) pr = run_paired(mesh, rounds, threads);
        if (!pr.ok && have_all) {
            const double table[PAIRS] = {bin->ms / em, sbvh->ms / eh, kdsah->ms / bin->ms, bih->ms / bin->ms, grid->ms / bin->ms};
            for (int k = 0; k < PAIRS; ++k) pr.median[k] = pr.lo[k] = pr.hi[k] = table[k];
        }
        char range[PAIRS][64];
        for (int k = 0; k < PAIRS; ++k) {
            range[k][0] = 0;
            if (pr.ok) snprintf(range[k], sizeof range[k], "; rounds %.2f-%.2f", pr.lo[k], pr.hi[k]);
        }
        const char *how = pr.ok ? "paired median" : "table";
        char lines[6][240];
        int nl = 0;
        /* A target whose variants did not all run (--only, a failed build)
         * is named, not priced. */
#define TARGET(cond_ok, have, name, ...) do { \
            if (have) snprintf(lines[nl], sizeof lines[nl], __VA_ARGS__); \
            else snprintf(lines[nl], sizeof lines[nl], "%s: not all of its variants ran", name); \
            printf("  %-4s %s\n", !(have) ? "n/a" : (cond_ok) ? "met" : "MISS", lines[nl]); \
            if (md) \
                fprintf(md, "%s- %s: %s\n", nl ? "" : "\nTargets:\n\n", \
                        !(have) ? "n/a" : (cond_ok) ? "met" : "missed", lines[nl]); \
            ++nl; \
        } while (0)
        TARGET(pr.median[PAIR_BIN_EM] <= 1.0, have_all, "binned SAH against Embree medium",
               "binned SAH %.0f ms vs Embree medium %.0f ms (table ratio %.2f; %s %.2f%s; target <= 1)", bin->ms, em,
               bin->ms / em, how, pr.median[PAIR_BIN_EM], range[PAIR_BIN_EM]);
        TARGET(bin->sah <= 1.03 * sweep->sah, bin->ok && sweep->ok, "binned SAH cost against the sweep's", "binned SAH cost %.3f vs sweep %.3f (%+.1f%%, target <= +3%%)", bin->sah,
               sweep->sah, 100.0 * (bin->sah / sweep->sah - 1.0));
        TARGET(pr.median[PAIR_SBVH_EH] <= 1.0 && sbvh->sah < bin->sah, have_all, "SBVH against Embree high",
               "SBVH %.0f ms vs Embree high %.0f ms (table ratio %.2f; %s %.2f%s; target <= 1); SAH %.3f vs binned %.3f (target lower)",
               sbvh->ms, eh, sbvh->ms / eh, how, pr.median[PAIR_SBVH_EH], range[PAIR_SBVH_EH], sbvh->sah, bin->sah);
        TARGET(pr.median[PAIR_KD_BIN] <= 5.0, have_all, "KD SAH against binned SAH",
               "KD SAH %.0f ms vs binned SAH %.0f ms (table ratio %.2f; %s %.2f%s; target <= 5)", kdsah->ms, bin->ms,
               kdsah->ms / bin->ms, how, pr.median[PAIR_KD_BIN], range[PAIR_KD_BIN]);
        TARGET(pr.median[PAIR_GRID_BIN] < 1.0 && pr.median[PAIR_BIH_BIN] < 1.0, have_all, "grid and BIH against binned SAH",
               "grid %.0f ms and BIH %.0f ms vs binned SAH %.0f ms (%s ratios %.2f and %.2f; target below 1)", grid->ms,
               bih->ms, bin->ms, how, pr.median[PAIR_GRID_BIN], pr.median[PAIR_BIH_BIN]);
        (void)mid;
#undef TARGET
        as_mesh_release(mesh);
    }
    if (md) fclose(md);
    return 0;
}
