/* Workloads of the study: Morton-tiled primary rays, and secondary rays
 * (ambient occlusion, diffuse bounces, hard shadows) generated from primary
 * hits on the host, so that the trace itself can be timed alone. */
#include "structure.h"
#include "bvh2_layout.h"

#include <float.h>
#include <math.h>
#include <stdlib.h>
#include <string.h>

/* ---- primary rays in Morton-ordered tiles -------------------------------- */

#define TILE_W 16
#define TILE_H 32

static uint32_t part1by1(uint32_t x)
{
    x &= 0x0000ffffu;
    x = (x | (x << 8)) & 0x00ff00ffu;
    x = (x | (x << 4)) & 0x0f0f0f0fu;
    x = (x | (x << 2)) & 0x33333333u;
    x = (x | (x << 1)) & 0x55555555u;
    return x;
}

typedef struct tile_key {
    uint32_t morton, tx, ty;
} tile_key;

static int cmp_tile(const void *a, const void *b)
{
    const tile_key *x = a, *y = b;
    return x->morton < y->morton ? -1 : x->morton > y->morton;
}

void as_camera_rays_tiled(const as_camera_t *cam, uint32_t width, uint32_t height, as_ray_t *rays,
                          uint32_t *pixel_of_ray)
{
    as_ray_t *linear = malloc(sizeof *linear * (size_t)width * height);
    const uint32_t tw = (width + TILE_W - 1) / TILE_W, th = (height + TILE_H - 1) / TILE_H;
    tile_key *tiles = malloc(sizeof *tiles * (size_t)tw * th);
    if (!linear || !tiles) {
        /* Without memory for the reordering, row-major rays are still correct. */
        free(linear);
        free(tiles);
        as_camera_rays(cam, width, height, rays);
        if (pixel_of_ray)
            for (size_t i = 0; i < (size_t)width * height; ++i) pixel_of_ray[i] = (uint32_t)i;
        return;
    }
    as_camera_rays(cam, width, height, linear);
    for (uint32_t y = 0; y < th; ++y)
        for (uint32_t x = 0; x < tw; ++x) {
            tile_key *k = &tiles[(size_t)y * tw + x];
            k->morton = part1by1(x) | (part1by1(y) << 1);
            k->tx = x;
            k->ty = y;
        }
    qsort(tiles, (size_t)tw * th, sizeof *tiles, cmp_tile);
    size_t n = 0;
    for (size_t t = 0; t < (size_t)tw * th; ++t)
        for (uint32_t y = tiles[t].ty * TILE_H; y < (tiles[t].ty + 1) * TILE_H && y < height; ++y)
            for (uint32_t x = tiles[t].tx * TILE_W; x < (tiles[t].tx + 1) * TILE_W && x < width; ++x) {
                const size_t p = (size_t)y * width + x;
                rays[n] = linear[p];
                if (pixel_of_ray) pixel_of_ray[n] = (uint32_t)p;
                ++n;
            }
    free(linear);
    free(tiles);
}

/* Hit point from the barycentrics (more precise than org + t dir), and the
 * unit geometric normal facing the incoming ray. */
static int hit_frame(const as_tri4_t *tri, const as_ray_t *ray, const as_hit_t *hit, double p[3], double n[3])
{
    const double a[3] = {tri->v0.x, tri->v0.y, tri->v0.z}, b[3] = {tri->v1.x, tri->v1.y, tri->v1.z},
                 c[3] = {tri->v2.x, tri->v2.y, tri->v2.z};
    const double u = hit->u, v = hit->v, w = 1.0 - u - v;
    const double e1[3] = {b[0] - a[0], b[1] - a[1], b[2] - a[2]}, e2[3] = {c[0] - a[0], c[1] - a[1], c[2] - a[2]};
    n[0] = e1[1] * e2[2] - e1[2] * e2[1];
    n[1] = e1[2] * e2[0] - e1[0] * e2[2];
    n[2] = e1[0] * e2[1] - e1[1] * e2[0];
    const double len = sqrt(n[0] * n[0] + n[1] * n[1] + n[2] * n[2]);
    if (!(len > 0)) return 0;
    const double facing = n[0] * ray->dir[0] + n[1] * ray->dir[1] + n[2] * ray->dir[2];
    const double sgn = facing > 0 ? -1.0 : 1.0;
    for (int k = 0; k < 3; ++k) {
        n[k] *= sgn / len;
        p[k] = w * a[k] + u * b[k] + v * c[k];
    }
    return 1;
}

/* The origin offset off the surface at hit point p: the requested distance,
 * but at least 4 float spacings of p's largest coordinate. Rounding the
 * offset origin to float moves it by up to about 0.87 spacing along the
 * normal, so far from the origin (a scene at 1e6, where the spacing is
 * 1/16) a fraction of the diagonal alone can land the origin back on the
 * surface or behind it, and the ray re-hits its source or not by chance. */
static double surface_offset(const double p[3], double offset)
{
    const double m = fmax(fabs(p[0]), fmax(fabs(p[1]), fabs(p[2])));
    const double least = 4.0 * FLT_EPSILON * m;
    return offset > least ? offset : least;
}

static double scene_diagonal(const as_structure_t *s)
{
    const float *lo = s->meta.bounds_lo, *hi = s->meta.bounds_hi;
    const double dx = (double)hi[0] - lo[0], dy = (double)hi[1] - lo[1], dz = (double)hi[2] - lo[2];
    return sqrt(dx * dx + dy * dy + dz * dz);
}

/* A counter-based generator: the same seed, ray and sample always give the
 * same numbers, whatever the order of generation. */
static double hash01(uint64_t seed, uint64_t a, uint64_t b)
{
    uint64_t z = seed ^ (a * 0x9E3779B97F4A7C15ull) ^ (b * 0xC2B2AE3D27D4EB4Full);
    z = (z ^ (z >> 30)) * 0xBF58476D1CE4E5B9ull;
    z = (z ^ (z >> 27)) * 0x94D049BB133111EBull;
    z ^= z >> 31;
    return (double)(z >> 11) * 0x1.0p-53;
}

void as_secondary_args_default(as_secondary_args_t *args)
{
    memset(args, 0, sizeof *args);
    args->size = sizeof *args;
    args->rays_per_hit = 16;
    args->tmax_fraction = 0.1f;
    args->offset_fraction = 1e-4f;
    args->seed = 1;
}

static size_t count_hits(const as_hit_t *hits, size_t count)
{
    size_t n = 0;
    for (size_t i = 0; i < count; ++i) n += hits[i].prim != AS_NO_HIT;
    return n;
}

as_error_t as_rays_hemisphere(const as_structure_t *s, const as_ray_t *primary, const as_hit_t *hits, size_t count,
                              const as_secondary_args_t *user_args, as_ray_t **out, size_t *out_count,
                              uint32_t **origin)
{
    if (!s || (!primary && count) || (!hits && count) || !out || !out_count)
        return as_set_error(AS_ERROR_INVALID_ARGUMENT, "as_rays_hemisphere: NULL argument");
    as_secondary_args_t args;
    as_secondary_args_default(&args);
    if (user_args) memcpy(&args, user_args, user_args->size < sizeof args ? user_args->size : sizeof args);
    const as_tri4_t **map = as_structure_triangles_by_prim(s);
    if (!map) return as_get_error();
    const size_t cap = count_hits(hits, count) * args.rays_per_hit;
    as_ray_t *rays = as_malloc(sizeof *rays * (cap ? cap : 1), "secondary rays");
    uint32_t *from = origin ? as_malloc(sizeof *from * (cap ? cap : 1), "secondary ray origins") : NULL;
    if (!rays || (origin && !from)) {
        free((void *)map);
        free(rays);
        free(from);
        return as_get_error();
    }
    const double diag = scene_diagonal(s);
    const float tmax = args.tmax_fraction > 0 ? (float)(args.tmax_fraction * diag) : INFINITY;
    const double offset = args.offset_fraction * diag;
    size_t n = 0;
    for (size_t i = 0; i < count; ++i) {
        if (hits[i].prim == AS_NO_HIT || hits[i].prim >= s->meta.triangle_count || !map[hits[i].prim]) continue;
        double p[3], nrm[3];
        if (!hit_frame(map[hits[i].prim], &primary[i], &hits[i], p, nrm)) continue;
        const double off = surface_offset(p, offset);
        /* An orthonormal basis around the normal (Duff et al. 2017). */
        const double sign = nrm[2] >= 0 ? 1.0 : -1.0;
        const double a = -1.0 / (sign + nrm[2]), bb = nrm[0] * nrm[1] * a;
        const double t1[3] = {1.0 + sign * nrm[0] * nrm[0] * a, sign * bb, -sign * nrm[0]};
        const double t2[3] = {bb, sign + nrm[1] * nrm[1] * a, -nrm[1]};
        for (uint32_t k = 0; k < args.rays_per_hit; ++k) {
            /* Cosine-weighted: a uniform disk point lifted to the hemisphere. */
            const double r1 = hash01(args.seed, i, 2 * k), r2 = hash01(args.seed, i, 2 * k + 1);
            const double r = sqrt(r1), phi = 6.283185307179586 * r2;
            const double x = r * cos(phi), y = r * sin(phi), z = sqrt(1.0 - r1 > 0 ? 1.0 - r1 : 0.0);
            as_ray_t *ray = &rays[n];
            for (int d = 0; d < 3; ++d) {
                ray->org[d] = (float)(p[d] + off * nrm[d]);
                ray->dir[d] = (float)(x * t1[d] + y * t2[d] + z * nrm[d]);
            }
            ray->tmin = 0.0f;
            ray->tmax = tmax;
            if (from) from[n] = (uint32_t)i;
            ++n;
        }
    }
    free((void *)map);
    *out = rays;
    *out_count = n;
    if (origin) *origin = from;
    return AS_OK;
}

as_error_t as_rays_shadow(const as_structure_t *s, const as_ray_t *primary, const as_hit_t *hits, size_t count,
                          const float *lights, uint32_t light_count, float offset_fraction, as_ray_t **out,
                          size_t *out_count, uint32_t **origin)
{
    if (!s || (!primary && count) || (!hits && count) || (!lights && light_count) || !out || !out_count)
        return as_set_error(AS_ERROR_INVALID_ARGUMENT, "as_rays_shadow: NULL argument");
    const as_tri4_t **map = as_structure_triangles_by_prim(s);
    if (!map) return as_get_error();
    const size_t cap = count_hits(hits, count) * light_count;
    as_ray_t *rays = as_malloc(sizeof *rays * (cap ? cap : 1), "shadow rays");
    uint32_t *from = origin ? as_malloc(sizeof *from * (cap ? cap : 1), "shadow ray origins") : NULL;
    if (!rays || (origin && !from)) {
        free((void *)map);
        free(rays);
        free(from);
        return as_get_error();
    }
    const double offset = offset_fraction * scene_diagonal(s);
    size_t n = 0;
    for (size_t i = 0; i < count; ++i) {
        if (hits[i].prim == AS_NO_HIT || hits[i].prim >= s->meta.triangle_count || !map[hits[i].prim]) continue;
        double p[3], nrm[3];
        if (!hit_frame(map[hits[i].prim], &primary[i], &hits[i], p, nrm)) continue;
        const double off = surface_offset(p, offset);
        for (uint32_t l = 0; l < light_count; ++l) {
            as_ray_t *ray = &rays[n];
            for (int d = 0; d < 3; ++d) {
                ray->org[d] = (float)(p[d] + off * nrm[d]);
                ray->dir[d] = lights[3 * l + d] - ray->org[d];
            }
            /* The direction spans the whole way: the light is at t = 1. */
            ray->tmin = 0.0f;
            ray->tmax = 1.0f - 1e-4f;
            if (from) from[n] = (uint32_t)i;
            ++n;
        }
    }
    free((void *)map);
    *out = rays;
    *out_count = n;
    if (origin) *origin = from;
    return AS_OK;
}

void as_lights_default(const float lo[3], const float hi[3], float lights[12])
{
    for (int l = 0; l < 4; ++l) {
        const float fx = (l & 1) ? 0.75f : 0.25f, fz = (l & 2) ? 0.75f : 0.25f;
        lights[3 * l + 0] = lo[0] + fx * (hi[0] - lo[0]);
        lights[3 * l + 1] = lo[1] + 0.9f * (hi[1] - lo[1]);
        lights[3 * l + 2] = lo[2] + fz * (hi[2] - lo[2]);
    }
}

/* ---- Whitted ------------------------------------------------------------- */

void as_whitted_args_default(as_whitted_args_t *args)
{
    memset(args, 0, sizeof *args);
    args->size = sizeof *args;
    args->mirror_fraction = 0.10f;
    args->glass_fraction = 0.05f;
    args->ior = 1.5f;
    args->seed = 7;
    args->offset_fraction = 1e-4f;
}

int as_whitted_material(const as_whitted_args_t *args, uint32_t prim)
{
    if (args->materials) return prim < args->material_count ? (int)args->materials[prim].kind : AS_MATERIAL_OPAQUE;
    const double u = hash01(args->seed, prim, 0x57);
    if (u < args->mirror_fraction) return 1;
    if (u < (double)args->mirror_fraction + args->glass_fraction) return 2;
    return 0;
}

static void set_ray(as_ray_t *r, const double o[3], const double d[3])
{
    for (int k = 0; k < 3; ++k) {
        r->org[k] = (float)o[k];
        r->dir[k] = (float)d[k];
    }
    r->tmin = 0.0f;
    r->tmax = INFINITY;
}

as_error_t as_rays_whitted_bounce(const as_structure_t *s, const as_ray_t *rays, const as_hit_t *hits, size_t count,
                                  const as_whitted_args_t *user_args, as_ray_t **next, size_t *next_count,
                                  as_ray_t **shadow, size_t *shadow_count)
{
    if (!s || (!rays && count) || (!hits && count) || !next || !next_count || !shadow || !shadow_count)
        return as_set_error(AS_ERROR_INVALID_ARGUMENT, "as_rays_whitted_bounce: NULL argument");
    as_whitted_args_t args;
    as_whitted_args_default(&args);
    if (user_args) memcpy(&args, user_args, user_args->size < sizeof args ? user_args->size : sizeof args);
    if (args.materials && args.material_count != s->meta.triangle_count)
        return as_set_error(AS_ERROR_INVALID_ARGUMENT,
                            "as_rays_whitted_bounce: %u materials for a structure of %u triangles",
                            args.material_count, s->meta.triangle_count);
    const as_tri4_t **map = as_structure_triangles_by_prim(s);
    if (!map) return as_get_error();
    const size_t hit_count = count_hits(hits, count);
    as_ray_t *nx = as_malloc(sizeof *nx * (2 * hit_count + 1), "Whitted rays");
    as_ray_t *sh = as_malloc(sizeof *sh * (hit_count * args.light_count + 1), "Whitted shadow rays");
    if (!nx || !sh) {
        free((void *)map);
        free(nx);
        free(sh);
        return as_get_error();
    }
    const double offset = args.offset_fraction * scene_diagonal(s);
    size_t nn = 0, ns = 0;
    for (size_t i = 0; i < count; ++i) {
        if (hits[i].prim == AS_NO_HIT || hits[i].prim >= s->meta.triangle_count || !map[hits[i].prim]) continue;
        double p[3], n[3];
        if (!hit_frame(map[hits[i].prim], &rays[i], &hits[i], p, n)) continue;
        const double off = surface_offset(p, offset);
        const double above[3] = {p[0] + off * n[0], p[1] + off * n[1], p[2] + off * n[2]};
        const double below[3] = {p[0] - off * n[0], p[1] - off * n[1], p[2] - off * n[2]};
        /* Hard shadows at every hit. */
        for (uint32_t l = 0; l < args.light_count; ++l) {
            as_ray_t *r = &sh[ns++];
            for (int k = 0; k < 3; ++k) {
                r->org[k] = (float)above[k];
                r->dir[k] = args.lights[3 * l + k] - r->org[k];
            }
            r->tmin = 0.0f;
            r->tmax = 1.0f - 1e-4f;
        }
        const int material = as_whitted_material(&args, hits[i].prim);
        if (material == 0) continue;
        double d[3] = {rays[i].dir[0], rays[i].dir[1], rays[i].dir[2]};
        const double dl = sqrt(d[0] * d[0] + d[1] * d[1] + d[2] * d[2]);
        for (int k = 0; k < 3; ++k) d[k] /= dl;
        const double cosi = -(d[0] * n[0] + d[1] * n[1] + d[2] * n[2]); /* n faces the ray: cosi >= 0 */
        const double refl[3] = {d[0] + 2 * cosi * n[0], d[1] + 2 * cosi * n[1], d[2] + 2 * cosi * n[2]};
        set_ray(&nx[nn++], above, refl);
        if (material == 2) {
            /* Entering or leaving: the geometric normal was flipped towards
             * the ray, so the side is taken from the triangle's winding. */
            const as_tri4_t *t = map[hits[i].prim];
            const double e1[3] = {t->v1.x - t->v0.x, t->v1.y - t->v0.y, t->v1.z - t->v0.z};
            const double e2[3] = {t->v2.x - t->v0.x, t->v2.y - t->v0.y, t->v2.z - t->v0.z};
            const double wn[3] = {e1[1] * e2[2] - e1[2] * e2[1], e1[2] * e2[0] - e1[0] * e2[2],
                                  e1[0] * e2[1] - e1[1] * e2[0]};
            const int entering = wn[0] * d[0] + wn[1] * d[1] + wn[2] * d[2] < 0;
            const double ior = args.materials && args.materials[hits[i].prim].ior > 0
                                   ? args.materials[hits[i].prim].ior : args.ior;
            const double eta = entering ? 1.0 / ior : ior;
            const double k2 = 1.0 - eta * eta * (1.0 - cosi * cosi);
            if (k2 >= 0) {
                const double c = eta * cosi - sqrt(k2);
                const double refr[3] = {eta * d[0] + c * n[0], eta * d[1] + c * n[1], eta * d[2] + c * n[2]};
                set_ray(&nx[nn++], below, refr);
            }
        }
    }
    free((void *)map);
    *next = nx;
    *next_count = nn;
    *shadow = sh;
    *shadow_count = ns;
    return AS_OK;
}
