/* A CUDA kernel of one's own over an .asf file, without libas's launchers.
 *
 *   custom_kernel FILE.asf [WIDTH HEIGHT]
 *
 * The file must hold a BVH in the child-bounds layout with raw (not zstd)
 * sections, as build_and_save and as-build write it by default. libas loads
 * and validates it and says where the node and triangle sections lie in the
 * file; this program maps the file itself, copies those two sections to the
 * device byte for byte and traces camera rays with the traversal header
 * libas installs (as/device/bvh2_traverse.h), one thread per ray. It then
 * traces the same rays with as_trace on the CPU, which runs the same header,
 * and prints how many hits agree bit for bit.
 *
 * Exit codes: 0 every hit agrees, 1 usage or a difference, 2 to 5 as the
 * libas tools, 77 no CUDA device (what ctest counts as skipped). */
#include <fcntl.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/mman.h>
#include <sys/stat.h>
#include <unistd.h>

#include <cuda_runtime.h>

#include <as/as.h>
#include <as/device/bvh2_traverse.h>

/* One thread per ray: the same steps as libas's own kernel. */
__global__ void trace_kernel(const as_bvh2_node_t *nodes, const as_tri4_t *tris, const as_ray_t *rays,
                             as_hit_rec_t *hits, size_t count)
{
    const size_t i = (size_t)blockIdx.x * blockDim.x + threadIdx.x;
    if (i >= count) return;
    const as_ray_t ray = rays[i];
    as_ray_pre_t pre;
    as_hit_rec_t hit;
    if (as_ray_prepare(ray.org, ray.tmin, ray.dir, ray.tmax, 0, &pre))
        as_bvh2_trace(nodes, tris, &pre, 0, &hit, nullptr);
    else
        as_hit_rec_miss(&hit); /* NaN or zero direction: a miss by definition */
    hits[i] = hit;
}

static int fail_as(const char *what)
{
    fprintf(stderr, "custom_kernel: %s: %s [%s]\n", what, as_get_error_message(), as_error_name(as_get_error()));
    return as_error_exit_code(as_get_error());
}

static bool cuda_ok(cudaError_t e, const char *what)
{
    if (e != cudaSuccess) fprintf(stderr, "custom_kernel: %s: %s\n", what, cudaGetErrorString(e));
    return e == cudaSuccess;
}

/* Where a section lies in the file, by its tag. */
static bool find_section(const as_structure_t *s, const char *tag, as_section_info_t *info)
{
    for (uint32_t i = 0; i < as_structure_section_count(s); ++i)
        if (as_structure_section_info(s, i, info) == AS_OK && strcmp(info->tag, tag) == 0) return true;
    return false;
}

int main(int argc, char **argv)
{
    if (argc != 2 && argc != 4) {
        fprintf(stderr, "usage: custom_kernel FILE.asf [WIDTH HEIGHT]\n");
        return 1;
    }
    const char *path = argv[1];
    const uint32_t width = argc == 4 ? (uint32_t)strtoul(argv[2], NULL, 10) : 512;
    const uint32_t height = argc == 4 ? (uint32_t)strtoul(argv[3], NULL, 10) : 512;
    if (width == 0 || height == 0 || width > 8192 || height > 8192) {
        fprintf(stderr, "custom_kernel: WIDTH and HEIGHT must be 1 to 8192\n");
        return 1;
    }
    int devices = 0;
    if (cudaGetDeviceCount(&devices) != cudaSuccess || devices == 0) {
        fprintf(stderr, "custom_kernel: no CUDA device\n");
        return 77;
    }

    /* Loading checks every offset and checksum; validation checks the tree
     * (indices in range, no cycles, depth within the traversal's stack), so
     * the kernel never follows a damaged index. */
    as_structure_t *s = as_structure_load(path, NULL);
    if (!s) return fail_as("load");
    if (as_structure_validate(s) != AS_OK) return fail_as("validate");
    as_structure_stats_t stats;
    if (as_structure_get_stats(s, &stats) != AS_OK) return fail_as("stats");
    if (stats.layout != AS_LAYOUT_BVH2_CHILD_BOUNDS) {
        fprintf(stderr, "custom_kernel: %s: layout %s, not bvh2-child-bounds (as-convert --layout bvh2-child-bounds)\n",
                path, as_layout_name(stats.layout));
        return 5;
    }
    as_section_info_t node_info, tri_info;
    if (!find_section(s, "BVH2", &node_info) || !find_section(s, "TRI4", &tri_info)) {
        fprintf(stderr, "custom_kernel: %s: no BVH2 or TRI4 section\n", path);
        return 3;
    }
    if (node_info.compressed || tri_info.compressed) {
        fprintf(stderr, "custom_kernel: %s: compressed sections (as-convert --decompress)\n", path);
        return 5;
    }

    /* The file as it is on disk: the sections are the arrays the traversal
     * reads, at 64-byte aligned offsets. */
    const int fd = open(path, O_RDONLY);
    struct stat st;
    if (fd < 0 || fstat(fd, &st) != 0) {
        perror(path);
        return 2;
    }
    void *map = mmap(NULL, (size_t)st.st_size, PROT_READ, MAP_PRIVATE, fd, 0);
    close(fd);
    if (map == MAP_FAILED) {
        perror(path);
        return 2;
    }
    const unsigned char *file = (const unsigned char *)map;

    as_camera_t camera;
    as_camera_default(stats.bounds_lo, stats.bounds_hi, &camera);
    const size_t count = (size_t)width * height;
    as_ray_t *rays = (as_ray_t *)malloc(sizeof *rays * count);
    as_hit_rec_t *gpu_hits = (as_hit_rec_t *)malloc(sizeof *gpu_hits * count);
    as_hit_t *cpu_hits = (as_hit_t *)malloc(sizeof *cpu_hits * count);
    if (!rays || !gpu_hits || !cpu_hits) {
        fprintf(stderr, "custom_kernel: out of memory\n");
        return 4;
    }
    as_camera_rays(&camera, width, height, rays);

    as_bvh2_node_t *d_nodes = NULL;
    as_tri4_t *d_tris = NULL;
    as_ray_t *d_rays = NULL;
    as_hit_rec_t *d_hits = NULL;
    /* cudaMalloc's 256-byte alignment keeps the 16-byte loads of the nodes
     * and triangles aligned. */
    const bool ok =
        cuda_ok(cudaMalloc(&d_nodes, node_info.raw_bytes), "cudaMalloc") &&
        cuda_ok(cudaMalloc(&d_tris, tri_info.raw_bytes ? tri_info.raw_bytes : 1), "cudaMalloc") &&
        cuda_ok(cudaMalloc(&d_rays, sizeof *rays * count), "cudaMalloc") &&
        cuda_ok(cudaMalloc(&d_hits, sizeof *gpu_hits * count), "cudaMalloc") &&
        cuda_ok(cudaMemcpy(d_nodes, file + node_info.offset, node_info.raw_bytes, cudaMemcpyHostToDevice), "copy nodes") &&
        cuda_ok(cudaMemcpy(d_tris, file + tri_info.offset, tri_info.raw_bytes, cudaMemcpyHostToDevice), "copy triangles") &&
        cuda_ok(cudaMemcpy(d_rays, rays, sizeof *rays * count, cudaMemcpyHostToDevice), "copy rays");
    if (!ok) return 4;
    const unsigned block = 128;
    trace_kernel<<<(unsigned)((count + block - 1) / block), block>>>(d_nodes, d_tris, d_rays, d_hits, count);
    if (!cuda_ok(cudaGetLastError(), "launch") || !cuda_ok(cudaDeviceSynchronize(), "kernel") ||
        !cuda_ok(cudaMemcpy(gpu_hits, d_hits, sizeof *gpu_hits * count, cudaMemcpyDeviceToHost), "copy hits"))
        return 4;

    as_trace_args_t trace;
    as_trace_args_default(&trace);
    trace.device = AS_DEVICE_CPU;
    if (as_trace(s, rays, count, cpu_hits, &trace, NULL) != AS_OK) return fail_as("trace");

    /* as_hit_rec_t is the as_hit_t record in the traversal's own header. */
    static_assert(sizeof(as_hit_rec_t) == sizeof(as_hit_t), "one hit record");
    size_t hit_count = 0, differ = 0;
    for (size_t i = 0; i < count; ++i) {
        hit_count += gpu_hits[i].prim != AS_NO_HIT;
        if (memcmp(&gpu_hits[i], &cpu_hits[i], sizeof cpu_hits[i]) != 0 && differ++ < 5)
            fprintf(stderr, "ray %zu: kernel prim %u t %.9g, as_trace prim %u t %.9g\n", i, gpu_hits[i].prim,
                    gpu_hits[i].t, cpu_hits[i].prim, cpu_hits[i].t);
    }
    const size_t agree = count - differ;
    printf("%s: %zu rays, %zu hits; %zu of %zu agree with as_trace on the CPU\n", path, count, hit_count, agree,
           count);

    cudaFree(d_nodes);
    cudaFree(d_tris);
    cudaFree(d_rays);
    cudaFree(d_hits);
    munmap(map, (size_t)st.st_size);
    free(rays);
    free(gpu_hits);
    free(cpu_hits);
    as_structure_release(s);
    return agree == count ? 0 : 1;
}
