/* Loads an .asf file and traces camera rays on the CPU.
 *
 *   load_and_trace FILE.asf [WIDTH HEIGHT]
 *
 * The camera is as_camera_default's for the scene box (looking along -z).
 * Prints the hits as a picture, one character per ray: the last digit of the
 * triangle's index in the source mesh, '.' for a miss; then the hit of the
 * ray through the centre of the picture and the number of hits. */
#include <stdio.h>
#include <stdlib.h>

#include <as/as.h>

static int fail(const char *what)
{
    fprintf(stderr, "load_and_trace: %s: %s [%s]\n", what, as_get_error_message(),
            as_error_name(as_get_error()));
    return as_error_exit_code(as_get_error());
}

int main(int argc, char **argv)
{
    if (argc != 2 && argc != 4) {
        fprintf(stderr, "usage: load_and_trace FILE.asf [WIDTH HEIGHT]\n");
        return 1;
    }
    /* Odd sizes have a pixel whose ray goes through the middle of the box. */
    const uint32_t width = argc == 4 ? (uint32_t)strtoul(argv[2], NULL, 10) : 41;
    const uint32_t height = argc == 4 ? (uint32_t)strtoul(argv[3], NULL, 10) : 21;
    if (width == 0 || height == 0 || width > 4096 || height > 4096) {
        fprintf(stderr, "load_and_trace: WIDTH and HEIGHT must be 1 to 4096\n");
        return 1;
    }

    /* NULL arguments: the defaults, which verify every section's checksum. */
    as_structure_t *s = as_structure_load(argv[1], NULL);
    if (!s) return fail("load");
    as_structure_stats_t stats;
    if (as_structure_get_stats(s, &stats) != AS_OK) {
        as_structure_release(s);
        return fail("stats");
    }
    printf("%s: %s (%s), %u triangles\n", argv[1], as_structure_kind_name(stats.structure),
           as_layout_name(stats.layout), stats.triangle_count);

    as_camera_t camera;
    as_camera_default(stats.bounds_lo, stats.bounds_hi, &camera);
    const size_t count = (size_t)width * height;
    as_ray_t *rays = malloc(sizeof *rays * count);
    as_hit_t *hits = malloc(sizeof *hits * count);
    if (!rays || !hits) {
        fprintf(stderr, "load_and_trace: out of memory\n");
        return 4;
    }
    as_camera_rays(&camera, width, height, rays);

    as_trace_args_t trace;
    as_trace_args_default(&trace);
    trace.device = AS_DEVICE_CPU;
    if (as_trace(s, rays, count, hits, &trace, NULL) != AS_OK) {
        free(rays);
        free(hits);
        as_structure_release(s);
        return fail("trace");
    }

    size_t hit_count = 0;
    for (uint32_t y = 0; y < height; ++y) {
        for (uint32_t x = 0; x < width; ++x) {
            const as_hit_t *h = &hits[(size_t)y * width + x];
            hit_count += h->prim != AS_NO_HIT;
            putchar(h->prim == AS_NO_HIT ? '.' : (char)('0' + h->prim % 10));
        }
        putchar('\n');
    }
    const size_t centre = (size_t)(height / 2) * width + width / 2;
    const as_hit_t *h = &hits[centre];
    if (h->prim == AS_NO_HIT)
        printf("centre ray: miss\n");
    else
        printf("centre ray: triangle %u at t = %.6g, u = %.4g, v = %.4g\n", h->prim, h->t, h->u, h->v);
    printf("hits: %zu of %zu rays\n", hit_count, count);

    free(rays);
    free(hits);
    as_structure_release(s);
    return 0;
}
