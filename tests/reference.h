/* The double-precision brute-force reference every traversal is compared
 * with, the rays the comparisons use, and the comparison rule.
 *
 * "Same hit" (the rule of the foundation): the same primitive, or a tie:
 * another primitive whose hit distance differs from the reference's by at
 * most 1e-6 of the scene's diagonal (shared edges, coincident triangles);
 * t itself within 1e-5 relative. A miss must be a miss. */
#ifndef AS_TEST_REFERENCE_H
#define AS_TEST_REFERENCE_H

#include "as/as.h"
#include "mesh.h"

#include <math.h>
#include <pthread.h>
#include <stdint.h>
#include <stdlib.h>
#include <string.h>
#include <stdio.h>
#include <sys/stat.h>
#include <unistd.h>

typedef struct ref_scene {
    uint32_t tri_count;
    double *v;          /* 9 doubles per triangle */
    uint8_t *skip;      /* zero-area triangles: never hit */
    double diag;
} ref_scene;

typedef struct ref_hit {
    double t;           /* INFINITY on a miss */
    uint32_t prim;
} ref_hit;

static inline int ref_scene_init(ref_scene *s, const as_mesh_t *mesh)
{
    as_mesh_info_t info;
    as_mesh_get_info(mesh, &info);
    const float *p = as_mesh_positions(mesh);
    const uint32_t *ix = as_mesh_indices(mesh);
    s->tri_count = info.triangle_count;
    s->diag = 0.0;
    s->v = malloc(sizeof(double) * 9 * (size_t)s->tri_count);
    s->skip = calloc(s->tri_count ? s->tri_count : 1, 1);
    if (!s->v || !s->skip) return 0;
    for (uint32_t t = 0; t < s->tri_count; ++t) {
        for (int k = 0; k < 3; ++k)
            for (int a = 0; a < 3; ++a) s->v[9 * (size_t)t + 3 * k + a] = p[3 * (size_t)ix[3 * (size_t)t + k] + a];
        /* The library's own definition of zero area: those are never hit. */
        s->skip[t] = (uint8_t)as_mesh_triangle_is_degenerate(mesh, t);
    }
    const double dx = (double)info.bounds_hi[0] - info.bounds_lo[0], dy = (double)info.bounds_hi[1] - info.bounds_lo[1],
                 dz = (double)info.bounds_hi[2] - info.bounds_lo[2];
    s->diag = sqrt(dx * dx + dy * dy + dz * dz);
    return 1;
}

static inline void ref_scene_free(ref_scene *s)
{
    free(s->v);
    free(s->skip);
}

/* Closest hit by brute force: the watertight test of Woop, Benthin & Wald
 * (2013) evaluated in double. Its edge functions of a shared edge are exact
 * negatives of each other in any precision, so the reference itself never
 * leaks through shared edges and vertices (Moller-Trumbore, even in double,
 * does). Edges are inclusive; equal distances go to the lowest index, as in
 * the traversals. */
static inline ref_hit ref_trace(const ref_scene *s, const as_ray_t *ray)
{
    ref_hit best = {INFINITY, AS_NO_HIT};
    const double o[3] = {ray->org[0], ray->org[1], ray->org[2]};
    const double d[3] = {ray->dir[0], ray->dir[1], ray->dir[2]};
    const double tmin = ray->tmin, tmax = ray->tmax;
    if (!(tmin <= tmax) || !isfinite(o[0]) || !isfinite(o[1]) || !isfinite(o[2]) || !isfinite(d[0]) ||
        !isfinite(d[1]) || !isfinite(d[2]) || (d[0] == 0 && d[1] == 0 && d[2] == 0))
        return best;
    const double ax = fabs(d[0]), ay = fabs(d[1]), az = fabs(d[2]);
    const int kz = ax > ay ? (ax > az ? 0 : 2) : (ay > az ? 1 : 2);
    int kx = (kz + 1) % 3, ky = (kx + 1) % 3;
    if (d[kz] < 0) { const int t = kx; kx = ky; ky = t; }
    const double sx = d[kx] / d[kz], sy = d[ky] / d[kz], sz = 1.0 / d[kz];
    for (uint32_t t = 0; t < s->tri_count; ++t) {
        if (s->skip[t]) continue;
        const double *a = s->v + 9 * (size_t)t, *b = a + 3, *c = a + 6;
        const double A[3] = {a[0] - o[0], a[1] - o[1], a[2] - o[2]};
        const double B[3] = {b[0] - o[0], b[1] - o[1], b[2] - o[2]};
        const double C[3] = {c[0] - o[0], c[1] - o[1], c[2] - o[2]};
        const double Ax = A[kx] - sx * A[kz], Ay = A[ky] - sy * A[kz];
        const double Bx = B[kx] - sx * B[kz], By = B[ky] - sy * B[kz];
        const double Cx = C[kx] - sx * C[kz], Cy = C[ky] - sy * C[kz];
        const double U = Cx * By - Cy * Bx, V = Ax * Cy - Ay * Cx, W = Bx * Ay - By * Ax;
        if ((U < 0 || V < 0 || W < 0) && (U > 0 || V > 0 || W > 0)) continue;
        const double det = U + V + W;
        if (det == 0.0) continue;
        const double T = U * sz * A[kz] + V * sz * B[kz] + W * sz * C[kz];
        const double th = T / det;
        if (th < tmin || th > tmax) continue;
        if (th < best.t || (th == best.t && t < best.prim)) {
            best.t = th;
            best.prim = t;
        }
    }
    return best;
}

/* Distance along the ray at which it meets triangle `prim` in double, or
 * INFINITY (used to accept ties). */
static inline double ref_hit_distance(const ref_scene *s, const as_ray_t *ray, uint32_t prim)
{
    if (prim >= s->tri_count) return INFINITY;
    ref_scene one = *s;
    one.v = s->v + 9 * (size_t)prim;
    one.skip = s->skip + prim;
    one.tri_count = 1;
    const ref_hit h = ref_trace(&one, ray);
    return h.t;
}

/* The rule above; returns 1 when `got` agrees with `ref`. A hit on a
 * triangle the double test misses still counts as a tie when it lies within
 * the tolerance of the reference distance: the ray then crosses a shared
 * edge, where float and double may pick different neighbours. */
static inline int ref_agrees(const ref_scene *s, const as_ray_t *ray, const ref_hit *ref, const as_hit_t *got)
{
    const double tol = 1e-6 * s->diag;
    if (ref->prim == AS_NO_HIT) return got->prim == AS_NO_HIT;
    if (got->prim == AS_NO_HIT) return 0;
    if (fabs((double)got->t - ref->t) > 1e-5 * fabs(ref->t) + 1e-30 && fabs((double)got->t - ref->t) > tol) return 0;
    if (got->prim == ref->prim) return 1;
    const double t_other = ref_hit_distance(s, ray, got->prim);
    if (isfinite(t_other)) return fabs(t_other - ref->t) <= tol;
    /* The double test misses got->prim: the float hit is on its edge. */
    return fabs((double)got->t - ref->t) <= tol;
}

typedef struct ref_job {
    const ref_scene *scene;
    const as_ray_t *rays;
    ref_hit *out;
    size_t count;
    size_t next;
    pthread_mutex_t lock;
} ref_job;

static inline void *ref_worker(void *arg)
{
    ref_job *j = arg;
    for (;;) {
        pthread_mutex_lock(&j->lock);
        const size_t begin = j->next;
        j->next += 64;
        pthread_mutex_unlock(&j->lock);
        if (begin >= j->count) return NULL;
        const size_t end = begin + 64 < j->count ? begin + 64 : j->count;
        for (size_t i = begin; i < end; ++i) j->out[i] = ref_trace(j->scene, &j->rays[i]);
    }
}

/* The reference for many rays on every core. */
static inline void ref_trace_all(const ref_scene *s, const as_ray_t *rays, size_t count, ref_hit *out)
{
    ref_job j = {s, rays, out, count, 0, PTHREAD_MUTEX_INITIALIZER};
    long n = sysconf(_SC_NPROCESSORS_ONLN);
    if (n < 1) n = 1;
    if (n > 64) n = 64;
    pthread_t tid[64];
    for (long i = 0; i < n; ++i) pthread_create(&tid[i], NULL, ref_worker, &j);
    for (long i = 0; i < n; ++i) pthread_join(tid[i], NULL);
}

/* The reference for many rays, kept in a cache file under `dir` keyed by a
 * hash of the rays and the scene, so that the variants of one scene share
 * one brute-force pass. The cache is written to a temporary file and renamed;
 * a damaged or foreign cache file is recomputed. */
static inline void ref_trace_all_cached(const ref_scene *s, const as_mesh_t *mesh, const as_ray_t *rays,
                                        size_t count, ref_hit *out, const char *dir)
{
    as_mesh_info_t info;
    as_mesh_get_info(mesh, &info);
    uint64_t key = info.hash ^ (0x9E3779B97F4A7C15ull * (uint64_t)count);
    {
        /* FNV-1a over the ray bytes: cheap and enough for a cache key. */
        const unsigned char *b = (const unsigned char *)rays;
        for (size_t i = 0; i < count * sizeof *rays; ++i) key = (key ^ b[i]) * 0x100000001B3ull;
    }
    char path[1024], tmp[1100];
    snprintf(path, sizeof path, "%s/%016llx.ref", dir, (unsigned long long)key);
    FILE *f = fopen(path, "rb");
    if (f) {
        uint64_t stored_key = 0, stored_count = 0;
        const int ok = fread(&stored_key, 8, 1, f) == 1 && fread(&stored_count, 8, 1, f) == 1 && stored_key == key &&
                       stored_count == count && fread(out, sizeof *out, count, f) == count;
        fclose(f);
        if (ok) return;
    }
    ref_trace_all(s, rays, count, out);
    mkdir(dir, 0777);
    snprintf(tmp, sizeof tmp, "%s.%ld.tmp", path, (long)getpid());
    f = fopen(tmp, "wb");
    if (!f) return;
    const uint64_t n64 = count;
    const int ok = fwrite(&key, 8, 1, f) == 1 && fwrite(&n64, 8, 1, f) == 1 && fwrite(out, sizeof *out, count, f) == count;
    if (fclose(f) == 0 && ok) rename(tmp, path);
    else remove(tmp);
}

/* A small deterministic generator (splitmix64). */
static inline uint64_t ref_rand_u64(uint64_t *state)
{
    uint64_t z = (*state += 0x9E3779B97F4A7C15ull);
    z = (z ^ (z >> 30)) * 0xBF58476D1CE4E5B9ull;
    z = (z ^ (z >> 27)) * 0x94D049BB133111EBull;
    return z ^ (z >> 31);
}

static inline double ref_rand01(uint64_t *state) { return (double)(ref_rand_u64(state) >> 11) * 0x1.0p-53; }

static inline void ref_random_direction(uint64_t *state, float d[3])
{
    const double z = 2.0 * ref_rand01(state) - 1.0, phi = 6.283185307179586 * ref_rand01(state);
    const double r = sqrt(1.0 - z * z);
    d[0] = (float)(r * cos(phi));
    d[1] = (float)(r * sin(phi));
    d[2] = (float)z;
}

/* Half camera rays over the scene (varied eyes around it), half rays from
 * random points inside its box in random directions. */
static inline void ref_make_scene_rays(const as_mesh_t *mesh, size_t count, uint64_t seed, as_ray_t *rays)
{
    as_mesh_info_t info;
    as_mesh_get_info(mesh, &info);
    uint64_t st = seed;
    const size_t ncam = count / 2;
    const uint32_t side = 100;
    size_t done = 0;
    while (done < ncam) {
        as_camera_t cam;
        as_camera_default(info.bounds_lo, info.bounds_hi, &cam);
        /* Eyes on a sphere around the scene, so every side is seen. */
        float dir[3];
        ref_random_direction(&st, dir);
        const float dist = sqrtf((cam.eye[0] - cam.target[0]) * (cam.eye[0] - cam.target[0]) +
                                 (cam.eye[1] - cam.target[1]) * (cam.eye[1] - cam.target[1]) +
                                 (cam.eye[2] - cam.target[2]) * (cam.eye[2] - cam.target[2]));
        for (int k = 0; k < 3; ++k) cam.eye[k] = cam.target[k] + dist * dir[k];
        if (fabsf(dir[1]) > 0.99f) { cam.up[0] = 1; cam.up[1] = 0; cam.up[2] = 0; }
        const size_t n = ncam - done < (size_t)side * side ? ncam - done : (size_t)side * side;
        as_ray_t *tile = malloc(sizeof *tile * side * side);
        as_camera_rays(&cam, side, side, tile);
        memcpy(rays + done, tile, n * sizeof *tile);
        free(tile);
        done += n;
    }
    for (size_t i = ncam; i < count; ++i) {
        as_ray_t *r = &rays[i];
        for (int k = 0; k < 3; ++k)
            r->org[k] = info.bounds_lo[k] + (float)ref_rand01(&st) * (info.bounds_hi[k] - info.bounds_lo[k]);
        ref_random_direction(&st, r->dir);
        r->tmin = 0.0f;
        r->tmax = INFINITY;
    }
}

#endif
