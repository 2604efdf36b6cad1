/* The stiff-case generator: the meshes and rays of the stiff-case suite,
 * each ray with its correct outcome (as.h, as_stiff_case_generate).
 *
 * The numbers come from splitmix64 (the generator of tests/reference.h), one
 * stream per mesh or ray set, started at the suite's constant for it xor a
 * mix of the caller's seed; the mix of 0 is 0, so seed 0 is the suite's own
 * cases, byte for byte. Where one statement draws several numbers the draws
 * are made one per statement, in the order the suite's first version drew
 * them (GCC evaluates call arguments right to left, an initializer list left
 * to right), so that order no longer depends on the compiler. */
#include "as_internal.h"
#include "mesh.h"

#include <math.h>
#include <stdlib.h>
#include <string.h>

static uint64_t rand_u64(uint64_t *state)
{
    uint64_t z = (*state += 0x9E3779B97F4A7C15ull);
    z = (z ^ (z >> 30)) * 0xBF58476D1CE4E5B9ull;
    z = (z ^ (z >> 27)) * 0x94D049BB133111EBull;
    return z ^ (z >> 31);
}

static double rand01(uint64_t *state) { return (double)(rand_u64(state) >> 11) * 0x1.0p-53; }

static void random_direction(uint64_t *state, float d[3])
{
    const double z = 2.0 * rand01(state) - 1.0, phi = 6.283185307179586 * rand01(state);
    const double r = sqrt(1.0 - z * z);
    d[0] = (float)(r * cos(phi));
    d[1] = (float)(r * sin(phi));
    d[2] = (float)z;
}

/* splitmix64's finaliser: unrelated streams for neighbouring seeds, and 0
 * for 0. */
static uint64_t seed_mix(uint64_t seed)
{
    uint64_t z = seed;
    z = (z ^ (z >> 30)) * 0xBF58476D1CE4E5B9ull;
    z = (z ^ (z >> 27)) * 0x94D049BB133111EBull;
    return z ^ (z >> 31);
}

/* ---- the case under construction ---------------------------------------- */

typedef struct gen {
    float *p;
    uint32_t *ix;
    uint32_t nv, nt, cap_v, cap_t;
    as_ray_t *rays;
    as_stiff_outcome_t *out;
    size_t nr, cap_r, cap_o;
    uint32_t *prims;
    size_t np, cap_p;
    bool oom;                    /* an allocation failed */
    as_error_t err;              /* a library call failed (its error is set) */
    uint64_t mix;                /* seed_mix(args->seed) */
    const as_stiff_args_t *args;
} gen;

static bool grow(void **ptr, size_t *cap, size_t need, size_t elem, gen *g)
{
    if (need <= *cap) return true;
    size_t n = *cap ? *cap : 1024;
    while (n < need) n *= 2;
    void *q = n <= SIZE_MAX / elem ? realloc(*ptr, n * elem) : NULL;
    if (!q) {
        g->oom = true;
        return false;
    }
    *ptr = q;
    *cap = n;
    return true;
}

static uint32_t vertex(gen *g, double x, double y, double z)
{
    size_t cap = g->cap_v;
    if (g->oom || g->nv == UINT32_MAX || !grow((void **)&g->p, &cap, (size_t)g->nv + 1, 3 * sizeof(float), g)) {
        g->oom = true;
        return 0;
    }
    g->cap_v = (uint32_t)(cap < UINT32_MAX ? cap : UINT32_MAX);
    g->p[3 * (size_t)g->nv] = (float)x;
    g->p[3 * (size_t)g->nv + 1] = (float)y;
    g->p[3 * (size_t)g->nv + 2] = (float)z;
    return g->nv++;
}

static void triangle(gen *g, uint32_t a, uint32_t b, uint32_t c)
{
    size_t cap = g->cap_t;
    if (g->oom || g->nt == UINT32_MAX || !grow((void **)&g->ix, &cap, (size_t)g->nt + 1, 3 * sizeof(uint32_t), g)) {
        g->oom = true;
        return;
    }
    g->cap_t = (uint32_t)(cap < UINT32_MAX ? cap : UINT32_MAX);
    g->ix[3 * (size_t)g->nt] = a;
    g->ix[3 * (size_t)g->nt + 1] = b;
    g->ix[3 * (size_t)g->nt + 2] = c;
    ++g->nt;
}

/* Appends a ray (tmin 0) with its outcome; returns its index. */
static size_t ray(gen *g, double ox, double oy, double oz, double dx, double dy, double dz, float tmax,
                  uint32_t expect, uint32_t reference)
{
    if (g->oom || !grow((void **)&g->rays, &g->cap_r, g->nr + 1, sizeof *g->rays, g)) return 0;
    if (!grow((void **)&g->out, &g->cap_o, g->nr + 1, sizeof *g->out, g)) return 0;
    as_ray_t *r = &g->rays[g->nr];
    r->org[0] = (float)ox;
    r->org[1] = (float)oy;
    r->org[2] = (float)oz;
    r->dir[0] = (float)dx;
    r->dir[1] = (float)dy;
    r->dir[2] = (float)dz;
    r->tmin = 0.0f;
    r->tmax = tmax;
    g->out[g->nr] = (as_stiff_outcome_t){expect, 0, 0, AS_STIFF_NO_RAY, reference};
    return g->nr++;
}

/* Appends a list of primitives; returns where it starts. */
static uint32_t prim_list(gen *g, const uint32_t *prims, size_t n)
{
    if (g->oom || g->np + n > UINT32_MAX || !grow((void **)&g->prims, &g->cap_p, g->np + n, sizeof *g->prims, g))
        return 0;
    memcpy(g->prims + g->np, prims, n * sizeof *prims);
    const uint32_t first = (uint32_t)g->np;
    g->np += n;
    return first;
}

static void outcome_prims(gen *g, size_t ray_index, uint32_t first, uint32_t count)
{
    if (g->oom) return;
    g->out[ray_index].first = first;
    g->out[ray_index].count = count;
}

/* Hands the vertex and index arrays to a new mesh, checked as an imported
 * one; the arrays are the mesh's from here on. */
static as_mesh_t *finish_mesh(gen *g, as_stiff_case_t kind)
{
    if (g->oom) return NULL;
    as_mesh_t *m = as_calloc(1, sizeof *m, "stiff case mesh");
    if (!m) {
        g->err = AS_ERROR_OUT_OF_MEMORY;
        return NULL;
    }
    m->positions = g->p;
    m->indices = g->ix;
    m->vertex_count = g->nv;
    m->triangle_count = g->nt;
    m->faces_in_file = g->nt;
    g->p = NULL;
    g->ix = NULL;
    g->nv = g->nt = g->cap_v = g->cap_t = 0;
    if ((g->err = as_mesh_finish(m, as_stiff_case_name(kind))) != AS_OK) {
        as_mesh_release(m);
        return NULL;
    }
    return m;
}

static size_t ray_count(const gen *g, size_t suite)
{
    return g->args->ray_count ? g->args->ray_count : suite;
}

/* ---- meshes -------------------------------------------------------------- */

/* The lattice cube or the sphere at `offset`; the centre goes to `centre`. */
static void closed_mesh(gen *g, int sphere, double offset, double edge, double centre[3])
{
    if (!sphere) {
        const int n = 6;
        uint32_t id[7 * 7 * 7];
        for (int i = 0; i <= n; ++i)
            for (int j = 0; j <= n; ++j)
                for (int k = 0; k <= n; ++k) {
                    const int on = !i || !j || !k || i == n || j == n || k == n;
                    id[(i * (n + 1) + j) * (n + 1) + k] =
                        on ? vertex(g, offset + i * edge, offset + j * edge, offset + k * edge) : 0;
                }
        for (int f = 0; f < 6; ++f) {
            const int axis = f / 2, fixed = (f % 2) ? n : 0;
            for (int a = 0; a < n; ++a)
                for (int b = 0; b < n; ++b) {
                    uint32_t v[4];
                    const int uv[4][2] = {{a, b}, {a + 1, b}, {a + 1, b + 1}, {a, b + 1}};
                    for (int c = 0; c < 4; ++c) {
                        int q[3];
                        q[axis] = fixed;
                        q[(axis + 1) % 3] = uv[c][0];
                        q[(axis + 2) % 3] = uv[c][1];
                        v[c] = id[(q[0] * (n + 1) + q[1]) * (n + 1) + q[2]];
                    }
                    triangle(g, v[0], v[1], v[2]);
                    triangle(g, v[0], v[2], v[3]);
                }
        }
        for (int k = 0; k < 3; ++k) centre[k] = offset + 0.5 * n * edge;
        return;
    }
    const int rings = 12, segs = 24;
    const double rad = 4.0 * edge;
    for (int k = 0; k < 3; ++k) centre[k] = offset + rad;
    const uint32_t top = vertex(g, centre[0], centre[1], centre[2] + rad);
    const uint32_t bot = vertex(g, centre[0], centre[1], centre[2] - rad);
    const uint32_t first = g->nv;
    for (int r = 1; r < rings; ++r)
        for (int sgm = 0; sgm < segs; ++sgm) {
            /* The suite's own digits of pi, kept so its sphere stays the same. */
            const double th = 3.14159265358979 * r / rings, ph = 6.28318530717959 * sgm / segs;
            vertex(g, centre[0] + rad * sin(th) * cos(ph), centre[1] + rad * sin(th) * sin(ph),
                   centre[2] + rad * cos(th));
        }
#define RV(r, sgm) (first + (uint32_t)(((r) - 1) * segs + ((sgm) % segs)))
    for (int sgm = 0; sgm < segs; ++sgm) {
        triangle(g, top, RV(1, sgm), RV(1, sgm + 1));
        triangle(g, bot, RV(rings - 1, sgm + 1), RV(rings - 1, sgm));
    }
    for (int r = 1; r + 1 < rings; ++r)
        for (int sgm = 0; sgm < segs; ++sgm) {
            triangle(g, RV(r, sgm), RV(r + 1, sgm), RV(r + 1, sgm + 1));
            triangle(g, RV(r, sgm), RV(r + 1, sgm + 1), RV(r, sgm + 1));
        }
#undef RV
}

/* Triangles of log-uniform size between size * scale_lo and size *
 * scale_hi around random points of the unit cube. */
static void random_soup(gen *g, uint64_t seed, uint32_t tris, double size, double scale_lo, double scale_hi)
{
    uint64_t st = seed ^ g->mix;
    for (uint32_t t = 0; t < tris && !g->oom; ++t) {
        const double s = size * exp(log(scale_lo) + rand01(&st) * (log(scale_hi) - log(scale_lo)));
        double c[3];
        for (int k = 0; k < 3; ++k) c[k] = rand01(&st);
        uint32_t v[3];
        for (int k = 0; k < 3; ++k) {
            const double dz = rand01(&st) - 0.5, dy = rand01(&st) - 0.5, dx = rand01(&st) - 0.5;
            v[k] = vertex(g, c[0] + s * dx, c[1] + s * dy, c[2] + s * dz);
        }
        triangle(g, v[0], v[1], v[2]);
    }
}

/* Half camera rays from eyes on a sphere around the mesh, half rays from
 * random points of its box in random directions (tests/reference.h's scene
 * rays). */
static void scene_rays(gen *g, const as_mesh_t *mesh, size_t count, uint64_t seed, uint32_t expect,
                       uint32_t reference)
{
    as_mesh_info_t info;
    as_mesh_get_info(mesh, &info);
    uint64_t st = seed ^ g->mix;
    const size_t ncam = count / 2;
    const uint32_t side = 100;
    as_ray_t *tile = as_malloc(sizeof *tile * side * side, "stiff case camera rays");
    if (!tile) {
        g->oom = true;
        return;
    }
    size_t done = 0;
    while (done < ncam && !g->oom) {
        as_camera_t cam;
        as_camera_default(info.bounds_lo, info.bounds_hi, &cam);
        float dir[3];
        random_direction(&st, dir);
        const float dist = sqrtf((cam.eye[0] - cam.target[0]) * (cam.eye[0] - cam.target[0]) +
                                 (cam.eye[1] - cam.target[1]) * (cam.eye[1] - cam.target[1]) +
                                 (cam.eye[2] - cam.target[2]) * (cam.eye[2] - cam.target[2]));
        for (int k = 0; k < 3; ++k) cam.eye[k] = cam.target[k] + dist * dir[k];
        if (fabsf(dir[1]) > 0.99f) {
            cam.up[0] = 1;
            cam.up[1] = 0;
            cam.up[2] = 0;
        }
        const size_t n = ncam - done < (size_t)side * side ? ncam - done : (size_t)side * side;
        as_camera_rays(&cam, side, side, tile);
        for (size_t i = 0; i < n; ++i) {
            const as_ray_t *r = &tile[i];
            ray(g, r->org[0], r->org[1], r->org[2], r->dir[0], r->dir[1], r->dir[2], r->tmax, expect, reference);
        }
        done += n;
    }
    free(tile);
    for (size_t i = ncam; i < count && !g->oom; ++i) {
        float o[3], d[3];
        for (int k = 0; k < 3; ++k)
            o[k] = info.bounds_lo[k] + (float)rand01(&st) * (info.bounds_hi[k] - info.bounds_lo[k]);
        random_direction(&st, d);
        ray(g, o[0], o[1], o[2], d[0], d[1], d[2], INFINITY, expect, reference);
    }
}

/* ---- the cases ----------------------------------------------------------- */

static double watertight_edge(double offset, double edge)
{
    if (edge > 0.0) return edge;
    if (offset == 0.0) return 1.0;
    if (offset == 1e6) return 16.0;
    if (offset == 1e7) return 128.0;
    const float o = (float)fabs(offset);
    const double spacing = (double)nextafterf(o, INFINITY) - (double)o;
    double e = 1.0;
    while (e < 256.0 * spacing) e *= 2.0;
    return e;
}

static as_mesh_t *watertight(gen *g, as_stiff_case_t kind)
{
    const double offset = g->args->offset, edge = watertight_edge(offset, g->args->edge);
    double centre[3];
    closed_mesh(g, kind == AS_STIFF_WATERTIGHT_SPHERE, offset, edge, centre);
    /* The rays need the stored (float) vertices, which the mesh keeps. */
    as_mesh_t *m = finish_mesh(g, kind);
    if (!m) return NULL;
    const float *p = m->positions;
    const uint32_t *ix = m->indices;
    const float c[3] = {(float)centre[0], (float)centre[1], (float)centre[2]};
    for (uint32_t t = 0; t < m->triangle_count; ++t)
        for (int e = 0; e < 3; ++e)
            for (int w = 0; w < 4; ++w) {
                if (w == 0 && e) continue; /* each vertex once per triangle */
                const float *a = p + 3 * (size_t)ix[3 * (size_t)t + e], *b = p + 3 * (size_t)ix[3 * (size_t)t + (e + 1) % 3];
                float q[3];
                for (int k = 0; k < 3; ++k) q[k] = a[k] + 0.25f * w * (b[k] - a[k]);
                ray(g, c[0], c[1], c[2], q[0] - c[0], q[1] - c[1], q[2] - c[2], INFINITY, AS_STIFF_EXPECT_HIT, 0);
                /* From three times as far out, ending at the centre. */
                ray(g, c[0] + 3.0f * (q[0] - c[0]), c[1] + 3.0f * (q[1] - c[1]), c[2] + 3.0f * (q[2] - c[2]),
                    -3.0f * (q[0] - c[0]), -3.0f * (q[1] - c[1]), -3.0f * (q[2] - c[2]), 1.0f, AS_STIFF_EXPECT_HIT, 0);
            }
    return m;
}

static as_mesh_t *quad_seam(gen *g)
{
    const uint32_t a = vertex(g, 0, 0, 0), b = vertex(g, 1, 0, 0), c = vertex(g, 1, 1, 0), d = vertex(g, 0, 1, 0);
    triangle(g, a, b, c);
    triangle(g, a, c, d);
    const uint32_t both[2] = {0, 1};
    const uint32_t first = prim_list(g, both, 2);
    const size_t n = ray_count(g, 4000);
    uint64_t st = 5 ^ g->mix;
    for (size_t i = 0; i < n && !g->oom; ++i) {
        const float u = (float)rand01(&st); /* a point of the diagonal x = y */
        const double sx = rand01(&st) - 0.5, sy = rand01(&st) - 0.5, sz = (i & 1) ? 1.0 : -1.0;
        outcome_prims(g, ray(g, u + sx, u + sy, sz, -sx, -sy, -sz, INFINITY, AS_STIFF_EXPECT_PRIM, 1), first, 2);
    }
    return finish_mesh(g, AS_STIFF_QUAD_SEAM);
}

static as_mesh_t *signed_zero(gen *g)
{
    random_soup(g, 42, 2000, 0.1, 1, 1);
    as_mesh_t *m = finish_mesh(g, AS_STIFF_SIGNED_ZERO);
    if (!m) return NULL;
    const float *p = m->positions;
    const size_t base = g->args->ray_count ? (g->args->ray_count + 23) / 24 : 1500;
    uint64_t st = 8 ^ g->mix;
    for (size_t i = 0; i < base && !g->oom; ++i) {
        const uint32_t v = (uint32_t)(rand_u64(&st) % m->vertex_count);
        for (int axis = 0; axis < 3; ++axis)
            for (int sign = 0; sign < 2; ++sign) {
                const size_t group = g->nr;
                for (int z = 0; z < 4; ++z) {
                    float o[3], d[3];
                    for (int k = 0; k < 3; ++k) {
                        o[k] = k == axis ? (sign ? 1.5f : -0.5f) : p[3 * (size_t)v + k];
                        d[k] = k == axis ? (sign ? -1.0f : 1.0f)
                                         : ((z >> (k == (axis + 1) % 3)) & 1 ? -0.0f : 0.0f);
                    }
                    const size_t r = ray(g, o[0], o[1], o[2], d[0], d[1], d[2], INFINITY, AS_STIFF_EXPECT_REFERENCE, 0);
                    if (z && !g->oom) g->out[r].same_as = (uint32_t)group;
                }
            }
    }
    return m;
}

static as_mesh_t *grazing(gen *g)
{
    const int n = 40;
    for (int i = 0; i <= n; ++i)
        for (int j = 0; j <= n; ++j) vertex(g, i * 25.0, j * 25.0, 0.0);
    for (int i = 0; i < n; ++i)
        for (int j = 0; j < n; ++j) {
            const uint32_t v00 = (uint32_t)(i * (n + 1) + j), v10 = v00 + (n + 1), v01 = v00 + 1, v11 = v10 + 1;
            triangle(g, v00, v10, v11);
            triangle(g, v00, v11, v01);
        }
    const size_t per = g->args->ray_count ? (g->args->ray_count + 7) / 8 : 1000;
    const double angles[] = {1e-1, 1e-2, 1e-3, 1e-4, 1e-5, 1e-6, 1e-7};
    uint64_t st = 9 ^ g->mix;
    for (int a = 0; a < 7; ++a)
        for (size_t i = 0; i < per && !g->oom; ++i) {
            const double phi = 6.28318530717959 * rand01(&st), x = 100 + 800 * rand01(&st),
                         y = 100 + 800 * rand01(&st);
            const double dx = cos(phi) * cos(angles[a]), dy = sin(phi) * cos(angles[a]), dz = -sin(angles[a]);
            /* From above the plane, reaching it after 50 units. */
            ray(g, x - 50 * dx, y - 50 * dy, -50 * dz, dx, dy, dz, INFINITY, AS_STIFF_EXPECT_REFERENCE, 0);
        }
    for (size_t i = 0; i < per && !g->oom; ++i) {
        const double phi = 6.28318530717959 * rand01(&st);
        const double y = 100 + 800 * rand01(&st), x = 100 + 800 * rand01(&st);
        ray(g, x, y, 0.0, cos(phi), sin(phi), 0.0, INFINITY, AS_STIFF_EXPECT_MISS, 0);
    }
    return finish_mesh(g, AS_STIFF_GRAZING);
}

static as_mesh_t *dynamic_range(gen *g)
{
    random_soup(g, 77, 3000, 1.0, 1e-6, 1e6);
    as_mesh_t *m = finish_mesh(g, AS_STIFF_DYNAMIC_RANGE);
    if (!m) return NULL;
    const float *p = m->positions;
    const size_t n = ray_count(g, 20000);
    uint64_t st = 10 ^ g->mix;
    for (size_t i = 0; i < n && !g->oom; ++i) {
        float d[3];
        random_direction(&st, d);
        if (i & 1) { /* at a triangle's centroid, from one unit away */
            const uint32_t t = (uint32_t)(rand_u64(&st) % m->triangle_count);
            double c[3];
            for (int k = 0; k < 3; ++k) c[k] = (p[9 * (size_t)t + k] + p[9 * (size_t)t + 3 + k] + p[9 * (size_t)t + 6 + k]) / 3.0;
            ray(g, c[0] - d[0], c[1] - d[1], c[2] - d[2], d[0], d[1], d[2], INFINITY, AS_STIFF_EXPECT_REFERENCE, 0);
        } else {
            const double oz = rand01(&st), oy = rand01(&st), ox = rand01(&st);
            ray(g, ox, oy, oz, d[0], d[1], d[2], INFINITY, AS_STIFF_EXPECT_REFERENCE, 0);
        }
    }
    return m;
}

static as_mesh_t *degenerate(gen *g)
{
    uint64_t st = 11 ^ g->mix;
    for (int i = 0; i < 3000 && !g->oom; ++i) {
        double c[3];
        for (int k = 0; k < 3; ++k) c[k] = rand01(&st);
        const uint32_t a = vertex(g, c[0], c[1], c[2]);
        const uint32_t b = vertex(g, c[0] + 0.05, c[1], c[2]);
        switch (i % 4) {
        case 0: triangle(g, a, a, b); break;                                               /* repeated index */
        case 1: triangle(g, a, b, vertex(g, c[0] + 0.1, c[1], c[2])); break;               /* collinear */
        case 2: triangle(g, a, b, vertex(g, c[0], c[1] + 0.05e-7, c[2])); break;           /* needle, aspect 1e7 */
        default: triangle(g, a, b, vertex(g, c[0], c[1] + 0.05, c[2] + 0.01)); break;
        }
    }
    as_mesh_t *m = finish_mesh(g, AS_STIFF_DEGENERATE);
    if (!m) return NULL;
    /* Zero area as the mesh decides it, in float: most needles are among
     * them, their third vertex rounded onto the first two's line. */
    uint32_t *zero = as_malloc(sizeof *zero * m->triangle_count, "stiff case zero-area list");
    if (!zero) {
        g->oom = true;
        return m;
    }
    uint32_t nz = 0;
    for (uint32_t t = 0; t < m->triangle_count; ++t)
        if (as_mesh_triangle_is_degenerate(m, t)) zero[nz++] = t;
    const uint32_t first = prim_list(g, zero, nz);
    free(zero);
    const size_t r0 = g->nr;
    scene_rays(g, m, ray_count(g, 20000), 12, AS_STIFF_EXPECT_NOT_PRIM, 1);
    for (size_t i = r0; i < g->nr; ++i) outcome_prims(g, i, first, nz);
    return m;
}

static as_mesh_t *flat(gen *g)
{
    uint64_t st = 13 ^ g->mix;
    for (int i = 0; i < 2000; ++i) {
        const double x = rand01(&st), z = rand01(&st);
        const uint32_t c = vertex(g, x, 0.5, z + 0.03), b = vertex(g, x + 0.03, 0.5, z), a = vertex(g, x, 0.5, z);
        triangle(g, a, b, c);
    }
    const size_t n = ray_count(g, 10000);
    for (size_t i = 0; i < n && !g->oom; ++i) {
        const double side = (i & 1) ? 1.0 : -1.0; /* odd rays from above */
        const double dz = 0.1 * (rand01(&st) - 0.5), dx = 0.1 * (rand01(&st) - 0.5);
        const double oz = rand01(&st), ox = rand01(&st);
        ray(g, ox, 0.5 + side, oz, dx, -side, dz, INFINITY, AS_STIFF_EXPECT_REFERENCE, 0);
    }
    return finish_mesh(g, AS_STIFF_FLAT);
}

static as_mesh_t *duplicates(gen *g)
{
    uint64_t st = 14 ^ g->mix;
    if (g->args->duplicates_among_others)
        for (int i = 0; i < 500; ++i) {
            const double x = rand01(&st) * 4, y = rand01(&st) * 4, z = 1 + rand01(&st);
            const uint32_t c = vertex(g, x, y + 0.1, z), b = vertex(g, x + 0.1, y, z), a = vertex(g, x, y, z);
            triangle(g, a, b, c);
        }
    const uint32_t first_copy = g->nt;
    const uint32_t a = vertex(g, 0, 0, 0), b = vertex(g, 1, 0, 0), d = vertex(g, 0, 1, 0);
    for (uint32_t k = 0; k < g->args->duplicate_count && !g->oom; ++k) triangle(g, a, b, d);
    const uint32_t first = prim_list(g, &first_copy, 1);
    outcome_prims(g, ray(g, 0.25, 0.25, -1.0, 0, 0, 1, INFINITY, AS_STIFF_EXPECT_PRIM, 0), first, 1);
    return finish_mesh(g, AS_STIFF_DUPLICATES);
}

static as_mesh_t *planar_on_split(gen *g)
{
    /* Two small corner triangles make the box [0, 8]^3, whose middle and
     * quarter planes are 2, 4 and 6. */
    uint32_t c = vertex(g, 0, 0.01, 0), b = vertex(g, 0.01, 0, 0), a = vertex(g, 0, 0, 0);
    triangle(g, a, b, c);
    c = vertex(g, 8, 7.99, 8);
    b = vertex(g, 7.99, 8, 8);
    a = vertex(g, 8, 8, 8);
    triangle(g, a, b, c);
    const double planes[] = {2, 4, 6};
    for (int axis = 0; axis < 3; ++axis)
        for (int pl = 0; pl < 3; ++pl) {
            double q[4][3];
            const double uv[4][2] = {{1, 1}, {7, 1}, {7, 7}, {1, 7}};
            for (int c = 0; c < 4; ++c) {
                q[c][axis] = planes[pl];
                q[c][(axis + 1) % 3] = uv[c][0] + 0.1 * axis;
                q[c][(axis + 2) % 3] = uv[c][1] + 0.1 * pl;
            }
            uint32_t v[4];
            for (int c = 0; c < 4; ++c) v[c] = vertex(g, q[c][0], q[c][1], q[c][2]);
            triangle(g, v[0], v[1], v[2]);
            triangle(g, v[0], v[2], v[3]);
        }
    const size_t n = ray_count(g, 6000);
    uint64_t st = 15 ^ g->mix;
    for (size_t i = 0; i < n && !g->oom; ++i) {
        const int axis = (int)(i % 3);
        double o[3], d[3];
        for (int k = 0; k < 3; ++k) {
            o[k] = 2 + 4 * rand01(&st);
            d[k] = 0.2 * (rand01(&st) - 0.5);
        }
        o[axis] = (i / 3) % 2 ? -1.0 : 9.0;
        d[axis] = (i / 3) % 2 ? 1.0 : -1.0;
        ray(g, o[0], o[1], o[2], d[0], d[1], d[2], INFINITY, AS_STIFF_EXPECT_HIT, 1);
    }
    return finish_mesh(g, AS_STIFF_PLANAR_ON_SPLIT);
}

static as_mesh_t *surface(gen *g)
{
    as_mesh_t *m;
    const as_mesh_t *src = g->args->surface_mesh;
    if (src) {
        as_mesh_info_t info;
        as_mesh_get_info(src, &info);
        m = as_mesh_create(info.vertex_count, as_mesh_positions(src), info.triangle_count, as_mesh_indices(src));
        if (!m) g->err = as_get_error();
    } else {
        double centre[3];
        closed_mesh(g, 1, g->args->offset, watertight_edge(g->args->offset, g->args->edge), centre);
        m = finish_mesh(g, AS_STIFF_SURFACE);
    }
    if (!m) return NULL;
    const as_structure_t *s = g->args->surface_structure;
    as_structure_t *own = NULL;
    if (s) {
        as_structure_stats_t st;
        if ((g->err = as_structure_get_header_stats(s, &st)) != AS_OK) return m;
        if (st.triangle_count != m->triangle_count) {
            g->err = as_set_error(AS_ERROR_INVALID_ARGUMENT,
                         "as_stiff_case_generate: the surface structure has %u triangles, its mesh %u",
                         st.triangle_count, m->triangle_count);
            return m;
        }
    } else {
        s = own = as_structure_build(m, NULL);
        if (!s) {
            g->err = as_get_error();
            return m;
        }
    }
    as_mesh_info_t info;
    as_mesh_get_info(m, &info);
    as_camera_t cam;
    as_camera_default(info.bounds_lo, info.bounds_hi, &cam);
    const uint32_t w = 200, h = 200;
    as_ray_t *prim = as_malloc(sizeof *prim * w * h, "stiff case camera rays");
    as_hit_t *hits = as_malloc(sizeof *hits * w * h, "stiff case camera hits");
    as_ray_t *sec = NULL;
    uint32_t *from = NULL;
    size_t ns = 0;
    as_error_t e = prim && hits ? AS_OK : AS_ERROR_OUT_OF_MEMORY; /* as_malloc set it */
    if (e == AS_OK) {
        as_camera_rays(&cam, w, h, prim);
        as_trace_args_t ta;
        as_trace_args_default(&ta);
        ta.device = AS_DEVICE_CPU;
        e = as_trace(s, prim, (size_t)w * h, hits, &ta, NULL);
    }
    if (e == AS_OK) {
        as_secondary_args_t sa;
        as_secondary_args_default(&sa);
        sa.tmax_fraction = 0.0f; /* unbounded: a re-hit anywhere counts */
        sa.seed ^= g->mix;
        e = as_rays_hemisphere(s, prim, hits, (size_t)w * h, &sa, &sec, &ns, &from);
    }
    for (size_t i = 0; i < ns && e == AS_OK && !g->oom; ++i) {
        const as_ray_t *r = &sec[i];
        const uint32_t first = prim_list(g, &hits[from[i]].prim, 1);
        /* The suite's own sphere is convex: a ray leaving its outside meets
         * nothing. Another mesh: at least not the triangle it leaves. */
        outcome_prims(g, ray(g, r->org[0], r->org[1], r->org[2], r->dir[0], r->dir[1], r->dir[2], r->tmax,
                             src ? AS_STIFF_EXPECT_NOT_PRIM : AS_STIFF_EXPECT_MISS, 0),
                      first, 1);
        if (!g->oom) g->rays[g->nr - 1].tmin = r->tmin;
    }
    if (e != AS_OK) g->err = e;
    free(sec);
    free(from);
    free(prim);
    free(hits);
    as_structure_release(own);
    return m;
}

static as_mesh_t *bad_rays(gen *g)
{
    random_soup(g, 16, 20000, 0.05, 1, 1);
    as_mesh_t *m = finish_mesh(g, AS_STIFF_BAD_RAYS);
    if (!m) return NULL;
    const size_t n = ray_count(g, 200000);
    scene_rays(g, m, n, 17, AS_STIFF_EXPECT_REFERENCE, 0);
    for (size_t i = 0; i < n && !g->oom; ++i) {
        const as_ray_t good = g->rays[i];
        const size_t k = ray(g, 0, 0, 0, 0, 0, 0, 0, AS_STIFF_EXPECT_MISS, 0);
        if (g->oom) break;
        as_ray_t *b = &g->rays[k];
        *b = good;
        switch (i % 7) {
        case 0: b->tmin = 2.0f; b->tmax = 1.0f; break;
        case 1: b->dir[0] = b->dir[1] = b->dir[2] = 0.0f; break;
        case 2: b->org[1] = NAN; break;
        case 3: b->dir[2] = NAN; break;
        case 4: b->org[0] = INFINITY; break;
        case 5: b->dir[1] = -INFINITY; break;
        default: b->tmin = NAN; break;
        }
    }
    return m;
}

/* ---- the public functions ------------------------------------------------ */

static const struct {
    const char *name;
    const char *outcome;
} cases[AS_STIFF_CASE_COUNT + 1] = {
    {NULL, NULL},
    {"watertight-cube", "every ray hits: zero leaks through shared vertices and edges"},
    {"watertight-sphere", "every ray hits: zero leaks through shared vertices and edges"},
    {"seam", "every ray hits one of the two triangles, the reference's answer"},
    {"signed-zero", "the reference's answer; each group of four (+0 and -0) gives equal hits; no NaN"},
    {"grazing", "slanted rays: the reference's answer; rays in the plane miss"},
    {"range", "the reference's answer with the double-precision intersector; no NaN"},
    {"degenerate", "zero-area triangles are never hit; otherwise the reference's answer"},
    {"flat", "the reference's answer; hits from both sides"},
    {"duplicates", "the lowest copy is hit; depth within the cap, nodes linear in the copies"},
    {"planar", "every ray hits, the reference's answer"},
    {"surface", "no ray hits the triangle it leaves"},
    {"bad-rays", "ordinary rays: the reference's answer; the bad copies miss, at most 2.5x the ordinary time"},
};

const char *as_stiff_case_name(as_stiff_case_t kind)
{
    return kind >= 1 && kind <= AS_STIFF_CASE_COUNT ? cases[kind].name : NULL;
}

as_stiff_case_t as_stiff_case_from_name(const char *name)
{
    if (!name) return 0;
    for (int k = 1; k <= AS_STIFF_CASE_COUNT; ++k)
        if (strcmp(cases[k].name, name) == 0) return (as_stiff_case_t)k;
    return 0;
}

void as_stiff_args_default(as_stiff_args_t *args)
{
    memset(args, 0, sizeof *args);
    args->size = sizeof *args;
    args->duplicate_count = 10000;
}

void as_stiff_case_free(as_stiff_case_data_t *c)
{
    if (!c) return;
    as_mesh_release(c->mesh);
    free(c->rays);
    free(c->outcomes);
    free(c->prims);
    memset(c, 0, sizeof *c);
}

as_error_t as_stiff_case_generate(as_stiff_case_t kind, const as_stiff_args_t *user_args, as_stiff_case_data_t *out)
{
    if (!out) return as_set_error(AS_ERROR_INVALID_ARGUMENT, "as_stiff_case_generate: out is NULL");
    memset(out, 0, sizeof *out);
    as_stiff_args_t args;
    as_stiff_args_default(&args);
    if (user_args) {
        if (user_args->size < sizeof(size_t) || user_args->size > sizeof args)
            return as_set_error(AS_ERROR_INVALID_ARGUMENT, "as_stiff_case_generate: args->size %zu is not a size of as_stiff_args_t",
                                user_args->size);
        memcpy(&args, user_args, user_args->size);
    }
    if (!as_stiff_case_name(kind))
        return as_set_error(AS_ERROR_INVALID_ARGUMENT, "as_stiff_case_generate: unknown case %d", (int)kind);
    if (!isfinite(args.offset) || !isfinite(args.edge) || args.edge < 0.0)
        return as_set_error(AS_ERROR_INVALID_ARGUMENT,
                            "as_stiff_case_generate: offset %g and edge %g must be finite, the edge not negative",
                            args.offset, args.edge);
    if (args.duplicate_count == 0 || args.duplicate_count > 10000000)
        return as_set_error(AS_ERROR_INVALID_ARGUMENT,
                            "as_stiff_case_generate: duplicate_count %u is not in 1..10,000,000", args.duplicate_count);
    if (args.ray_count > 100000000)
        return as_set_error(AS_ERROR_INVALID_ARGUMENT, "as_stiff_case_generate: ray_count %zu is above 100,000,000",
                            args.ray_count);
    gen g = {0};
    g.args = &args;
    g.mix = seed_mix(args.seed);
    as_mesh_t *m = NULL;
    switch (kind) {
    case AS_STIFF_WATERTIGHT_CUBE:
    case AS_STIFF_WATERTIGHT_SPHERE: m = watertight(&g, kind); break;
    case AS_STIFF_QUAD_SEAM: m = quad_seam(&g); break;
    case AS_STIFF_SIGNED_ZERO: m = signed_zero(&g); break;
    case AS_STIFF_GRAZING: m = grazing(&g); break;
    case AS_STIFF_DYNAMIC_RANGE: m = dynamic_range(&g); break;
    case AS_STIFF_DEGENERATE: m = degenerate(&g); break;
    case AS_STIFF_FLAT: m = flat(&g); break;
    case AS_STIFF_DUPLICATES: m = duplicates(&g); break;
    case AS_STIFF_PLANAR_ON_SPLIT: m = planar_on_split(&g); break;
    case AS_STIFF_SURFACE: m = surface(&g); break;
    case AS_STIFF_BAD_RAYS: m = bad_rays(&g); break;
    }
    as_error_t e = g.err;
    if (e == AS_OK && (g.oom || !m))
        e = as_set_error(AS_ERROR_OUT_OF_MEMORY, "as_stiff_case_generate: out of memory generating %s",
                         as_stiff_case_name(kind));
    free(g.p);
    free(g.ix);
    if (e != AS_OK) {
        as_mesh_release(m);
        free(g.rays);
        free(g.out);
        free(g.prims);
        return e;
    }
    out->kind = kind;
    out->mesh = m;
    out->rays = g.rays;
    out->ray_count = g.nr;
    out->outcomes = g.out;
    out->prims = g.prims;
    out->prim_count = g.np;
    out->intersector = kind == AS_STIFF_DYNAMIC_RANGE ? AS_INTERSECTOR_WATERTIGHT_DOUBLE : AS_INTERSECTOR_WATERTIGHT;
    out->outcome = cases[kind].outcome;
    return AS_OK;
}
