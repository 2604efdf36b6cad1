/* Verification of traced hits against a double-precision reference: the
 * watertight test of Woop, Benthin & Wald evaluated in double (its edge
 * functions of a shared edge are exact negatives in any precision, so it
 * never leaks), over a BVH traversed conservatively (boxes widened, no
 * early exit), fast enough for millions of rays on San Miguel. */
#include "structure.h"
#include "bvh2_layout.h"
#include "mesh.h"

#include <math.h>
#include <stdlib.h>
#include <string.h>

typedef struct ref_ctx {
    const as_bvh2_node_t *nodes;
    const as_tri4_t *tris;
} ref_ctx;

/* Closest hit of one triangle in double, edges inclusive; 0 on a miss. */
static int ref_triangle(const double o[3], const double d[3], int kx, int ky, int kz, double sx, double sy, double sz,
                        const as_tri4_t *t, double tmin, double tmax, double *t_out)
{
    const double a[3] = {t->v0.x, t->v0.y, t->v0.z}, b[3] = {t->v1.x, t->v1.y, t->v1.z},
                 c[3] = {t->v2.x, t->v2.y, t->v2.z};
    (void)d;
    const double A[3] = {a[0] - o[0], a[1] - o[1], a[2] - o[2]};
    const double B[3] = {b[0] - o[0], b[1] - o[1], b[2] - o[2]};
    const double C[3] = {c[0] - o[0], c[1] - o[1], c[2] - o[2]};
    const double Ax = A[kx] - sx * A[kz], Ay = A[ky] - sy * A[kz];
    const double Bx = B[kx] - sx * B[kz], By = B[ky] - sy * B[kz];
    const double Cx = C[kx] - sx * C[kz], Cy = C[ky] - sy * C[kz];
    const double U = Cx * By - Cy * Bx, V = Ax * Cy - Ay * Cx, W = Bx * Ay - By * Ax;
    if ((U < 0 || V < 0 || W < 0) && (U > 0 || V > 0 || W > 0)) return 0;
    const double det = U + V + W;
    if (det == 0.0) return 0;
    const double T = U * sz * A[kz] + V * sz * B[kz] + W * sz * C[kz];
    const double th = T / det;
    if (!(th >= tmin && th <= tmax)) return 0;
    *t_out = th;
    return 1;
}

/* Whether the ray may enter the box: the slab test in double on a box
 * widened by a relative and an absolute margin, so rounding can only add
 * boxes, never drop one. */
static int ref_box(const double o[3], const double inv[3], const float lo[3], const float hi[3], double tmin,
                   double tmax)
{
    double tn = tmin, tf = tmax;
    for (int k = 0; k < 3; ++k) {
        const double pad = 1e-6 * (fabs((double)lo[k]) + fabs((double)hi[k])) + 1e-30;
        const double l = (double)lo[k] - pad, h = (double)hi[k] + pad;
        if (isinf(inv[k])) {
            if (o[k] < l || o[k] > h) return 0;
            continue;
        }
        double t0 = (l - o[k]) * inv[k], t1 = (h - o[k]) * inv[k];
        if (t0 > t1) { const double x = t0; t0 = t1; t1 = x; }
        if (t0 > tn) tn = t0;
        if (t1 < tf) tf = t1;
        if (tn > tf) return 0;
    }
    return 1;
}

static void child_box(const as_bvh2_node_t *n, int k, float lo[3], float hi[3])
{
    const as_f4_t xy = k ? n->xy1 : n->xy0;
    lo[0] = xy.x; hi[0] = xy.y; lo[1] = xy.z; hi[1] = xy.w;
    lo[2] = k ? n->z01.z : n->z01.x;
    hi[2] = k ? n->z01.w : n->z01.y;
}

/* Reference closest hit: every box the ray may enter is visited (no
 * ordering tricks), ties go to the lowest source index. */
static void ref_trace(const ref_ctx *c, const as_ray_t *ray, double *t_out, uint32_t *prim_out)
{
    *t_out = INFINITY;
    *prim_out = AS_NO_HIT;
    const double o[3] = {ray->org[0], ray->org[1], ray->org[2]}, d[3] = {ray->dir[0], ray->dir[1], ray->dir[2]};
    const double tmin = ray->tmin, tmax = ray->tmax;
    if (!(tmin <= tmax) || !isfinite(o[0]) || !isfinite(o[1]) || !isfinite(o[2]) || !isfinite(d[0]) ||
        !isfinite(d[1]) || !isfinite(d[2]) || (d[0] == 0 && d[1] == 0 && d[2] == 0))
        return;
    const double inv[3] = {d[0] != 0 ? 1.0 / d[0] : INFINITY, d[1] != 0 ? 1.0 / d[1] : INFINITY,
                           d[2] != 0 ? 1.0 / d[2] : INFINITY};
    const double ax = fabs(d[0]), ay = fabs(d[1]), az = fabs(d[2]);
    const int kz = ax > ay ? (ax > az ? 0 : 2) : (ay > az ? 1 : 2);
    int kx = (kz + 1) % 3, ky = (kx + 1) % 3;
    if (d[kz] < 0) { const int t = kx; kx = ky; ky = t; }
    const double sx = d[kx] / d[kz], sy = d[ky] / d[kz], sz = 1.0 / d[kz];
    int32_t stack[AS_BVH2_MAX_DEPTH + 2];
    int sp = 0;
    stack[sp++] = 0;
    double best = INFINITY;
    uint32_t best_prim = AS_NO_HIT;
    while (sp > 0) {
        const as_bvh2_node_t *n = &c->nodes[stack[--sp]];
        for (int k = 0; k < 2; ++k) {
            float lo[3], hi[3];
            child_box(n, k, lo, hi);
            if (n->child[k] < 0 && n->count[k] == 0) continue;
            if (!ref_box(o, inv, lo, hi, tmin, best < tmax ? best : tmax)) continue;
            if (n->child[k] >= 0) {
                stack[sp++] = n->child[k];
                continue;
            }
            const uint32_t first = (uint32_t)~n->child[k];
            for (uint32_t i = 0; i < n->count[k]; ++i) {
                const as_tri4_t *t = &c->tris[first + i];
                double th;
                if (!ref_triangle(o, d, kx, ky, kz, sx, sy, sz, t, tmin, tmax, &th)) continue;
                const uint32_t prim = as_float_as_uint(t->v0.w);
                if (th < best || (th == best && prim < best_prim)) {
                    best = th;
                    best_prim = prim;
                }
            }
        }
    }
    *t_out = best;
    *prim_out = best_prim;
}

/* The distance at which the ray meets one triangle in double, or INFINITY. */
static double ref_distance(const as_tri4_t *t, const as_ray_t *ray)
{
    const double o[3] = {ray->org[0], ray->org[1], ray->org[2]}, d[3] = {ray->dir[0], ray->dir[1], ray->dir[2]};
    const double ax = fabs(d[0]), ay = fabs(d[1]), az = fabs(d[2]);
    const int kz = ax > ay ? (ax > az ? 0 : 2) : (ay > az ? 1 : 2);
    int kx = (kz + 1) % 3, ky = (kx + 1) % 3;
    if (d[kz] < 0) { const int x = kx; kx = ky; ky = x; }
    double th;
    if (!ref_triangle(o, d, kx, ky, kz, d[kx] / d[kz], d[ky] / d[kz], 1.0 / d[kz], t, ray->tmin, ray->tmax, &th))
        return INFINITY;
    return th;
}

void as_verify_args_default(as_verify_args_t *args)
{
    memset(args, 0, sizeof *args);
    args->size = sizeof *args;
    args->sample_count = 100000;
    args->seed = 1;
}

typedef struct verify_job {
    ref_ctx ctx;
    const as_ray_t *rays;
    const as_hit_t *hits;
    const size_t *sample;
    size_t n;
    int any_hit;
    double tie_tol;
    const as_tri4_t **by_prim;
    uint32_t prim_count;
    as_verify_result_t *partial; /* one per block */
} verify_job;

#define VERIFY_BLOCK 1024

static void verify_block(void *user, size_t block)
{
    const verify_job *j = user;
    as_verify_result_t *r = &j->partial[block];
    memset(r, 0, sizeof *r);
    const size_t begin = block * VERIFY_BLOCK, end = begin + VERIFY_BLOCK < j->n ? begin + VERIFY_BLOCK : j->n;
    for (size_t s = begin; s < end; ++s) {
        const size_t i = j->sample[s];
        const as_ray_t *ray = &j->rays[i];
        const as_hit_t *got = &j->hits[i];
        double t;
        uint32_t prim;
        ref_trace(&j->ctx, ray, &t, &prim);
        r->checked++;
        const int got_hit = got->prim != AS_NO_HIT;
        if (prim == AS_NO_HIT) {
            if (got_hit) r->false_hits++;
            continue;
        }
        if (!got_hit) { r->false_misses++; continue; }
        if (got->prim >= j->prim_count || !j->by_prim[got->prim]) { r->wrong_primitive++; continue; }
        /* Any hit: any triangle really hit within the interval is right. */
        const double t_got = ref_distance(j->by_prim[got->prim], ray);
        if (j->any_hit) {
            if (!isfinite(t_got) && !(got->t >= ray->tmin && got->t <= ray->tmax)) r->wrong_primitive++;
            continue;
        }
        const double err = fabs((double)got->t - t);
        if (got->prim != prim) {
            /* A tie (shared edge, coincident copies) is the same hit; a
             * float hit on an edge the double test misses counts as one
             * when its distance matches. */
            const double other = isfinite(t_got) ? t_got : (double)got->t;
            if (fabs(other - t) > j->tie_tol) { r->wrong_primitive++; continue; }
        }
        /* Near the origin t is dominated by the rounding of the
         * coordinates, not of t: relative errors are taken farther out. */
        if (t > 1e3 * j->tie_tol && err / t > r->max_t_error) r->max_t_error = err / t;
        if (err / (1e6 * j->tie_tol) > r->max_t_error_abs) r->max_t_error_abs = err / (1e6 * j->tie_tol);
    }
}

static uint64_t mix64(uint64_t z)
{
    z = (z ^ (z >> 30)) * 0xBF58476D1CE4E5B9ull;
    z = (z ^ (z >> 27)) * 0x94D049BB133111EBull;
    return z ^ (z >> 31);
}

as_error_t as_verify(const as_structure_t *s, const as_ray_t *rays, const as_hit_t *hits, size_t count, bool any_hit,
                     const as_verify_args_t *user_args, as_verify_result_t *result)
{
    if (!s || (!rays && count) || (!hits && count) || !result)
        return as_set_error(AS_ERROR_INVALID_ARGUMENT, "as_verify: NULL argument");
    as_verify_args_t args;
    as_verify_args_default(&args);
    if (user_args) memcpy(&args, user_args, user_args->size < sizeof args ? user_args->size : sizeof args);
    memset(result, 0, sizeof *result);
    const double t0 = as_now_ms();

    /* The reference BVH is built over the structure's own triangles (not the
     * structure itself), one triangle per source index. */
    const as_tri4_t **by_prim = as_structure_triangles_by_prim(s);
    if (!by_prim) return as_get_error();
    const uint32_t n = s->meta.triangle_count;
    float *pos = as_malloc(sizeof(float) * 9 * (size_t)(n ? n : 1), "verification vertices");
    uint32_t *idx = as_malloc(sizeof(uint32_t) * 3 * (size_t)(n ? n : 1), "verification indices");
    as_mesh_t *mesh = NULL;
    as_structure_t *ref = NULL;
    size_t *sample = NULL;
    as_verify_result_t *partial = NULL;
    as_error_t err = AS_OK;
    if (!pos || !idx) { err = as_get_error(); goto done; }
    for (uint32_t i = 0; i < n; ++i) {
        const as_tri4_t *t = by_prim[i];
        /* A triangle the structure left out has zero area: a point. */
        const float v[9] = {t ? t->v0.x : 0, t ? t->v0.y : 0, t ? t->v0.z : 0, t ? t->v1.x : 0, t ? t->v1.y : 0,
                            t ? t->v1.z : 0, t ? t->v2.x : 0, t ? t->v2.y : 0, t ? t->v2.z : 0};
        memcpy(pos + 9 * (size_t)i, v, sizeof v);
        idx[3 * i] = 3 * i; idx[3 * i + 1] = 3 * i + 1; idx[3 * i + 2] = 3 * i + 2;
    }
    if (n == 0) {
        /* Nothing can be hit: every hit is false. */
        for (size_t i = 0; i < count; ++i) result->false_hits += hits[i].prim != AS_NO_HIT;
        result->checked = count;
        goto done;
    }
    mesh = as_mesh_create(3 * n, pos, n, idx);
    if (!mesh) { err = as_get_error(); goto done; }
    as_build_args_t ba;
    as_build_args_default(&ba);
    ref = as_structure_build(mesh, &ba);
    if (!ref) { err = as_get_error(); goto done; }

    /* A sample of the rays, evenly spread and reproducible. */
    const size_t m = args.sample_count && args.sample_count < count ? args.sample_count : count;
    sample = as_malloc(sizeof *sample * (m ? m : 1), "verification sample");
    if (!sample) { err = as_get_error(); goto done; }
    for (size_t i = 0; i < m; ++i)
        sample[i] = m == count ? i : (size_t)(mix64(args.seed + i) % count);
    const size_t blocks = (m + VERIFY_BLOCK - 1) / VERIFY_BLOCK;
    partial = as_calloc(blocks ? blocks : 1, sizeof *partial, "verification results");
    if (!partial) { err = as_get_error(); goto done; }
    const double dx = (double)s->meta.bounds_hi[0] - s->meta.bounds_lo[0],
                 dy = (double)s->meta.bounds_hi[1] - s->meta.bounds_lo[1],
                 dz = (double)s->meta.bounds_hi[2] - s->meta.bounds_lo[2];
    verify_job job = {{as_structure_find(ref, ASF_TAG_BVH2)->data, as_structure_find(ref, ASF_TAG_TRI4)->data},
                      rays, hits, sample, m, any_hit, 1e-6 * sqrt(dx * dx + dy * dy + dz * dz), by_prim, n, partial};
    as_parallel_for(as_thread_count(args.thread_count), blocks, verify_block, &job);
    for (size_t b = 0; b < blocks; ++b) {
        result->checked += partial[b].checked;
        result->wrong_primitive += partial[b].wrong_primitive;
        result->false_misses += partial[b].false_misses;
        result->false_hits += partial[b].false_hits;
        if (partial[b].max_t_error > result->max_t_error) result->max_t_error = partial[b].max_t_error;
        if (partial[b].max_t_error_abs > result->max_t_error_abs) result->max_t_error_abs = partial[b].max_t_error_abs;
    }
done:
    result->verify_ms = as_now_ms() - t0;
    free((void *)by_prim);
    free(pos);
    free(idx);
    free(sample);
    free(partial);
    as_structure_release(ref);
    as_mesh_release(mesh);
    return err;
}
