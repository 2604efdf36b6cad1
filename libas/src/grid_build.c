/* Uniform grid builder. Resolution (Cleary & Wyvill 1988; Wald et al. 2006):
 * cells per axis = extent along the axis x cbrt(lambda N / volume), lambda =
 * args->grid_lambda (cells per triangle), rounded, at least 1 per axis.
 * Axes of (nearly) zero extent (a flat scene) get one cell and are left out
 * of the volume: on k remaining axes the k-th root of lambda N over their
 * k-dimensional measure is used instead. The total is capped at
 * AS_GRID_MAX_CELLS, and the resolution is lowered (x 0.8 per axis, repeated)
 * while the references would exceed split_budget x N.
 *
 * Each triangle goes to every cell its box covers that it overlaps (exact
 * triangle/box test, Akenine-Moller 2001, with a few-ulp pad). Build in
 * parallel passes over units of triangles (blocks, cut finer where their
 * triangles reach many cells: plan_units): find each triangle's cells,
 * keeping the (cell, triangle) pairs of each unit, grouped by range of
 * cells, so the overlap tests run once; count per cell, a range of cells at
 * a time over its pairs in every unit; a prefix sum into GRDC; fill from
 * the pairs the same way, in triangle order, so PRIM is the same whatever
 * the thread count. */
#include "spatial_common.h"
#include "grid_layout.h"

#include <float.h>
#include <math.h>
#include <pthread.h>
#include <stdatomic.h>
#include <stdlib.h>
#include <string.h>

/* Plain comparisons: libm's fminf is a call without -ffinite-math-only. */
static inline float min3f(float a, float b, float c) { const float m = a < b ? a : b; return m < c ? m : c; }
static inline float max3f(float a, float b, float c) { const float m = a > b ? a : b; return m > c ? m : c; }

/* Triangles per block of pass 1: blocks of 2048 left a scene of 31k
 * triangles 16 blocks for its threads (staircase2, 2 threads: 4.2 -> 2.8
 * ms with 512), and a block holding large triangles a long tail (bathroom,
 * 16 threads: 22-27 -> 18-19 ms, run 88). */
#define BLOCK 512

/* The (cell, triangle) pairs pass 1 found in one unit, in triangle order,
 * then grouped by range of cells (range r at [range_at[r], range_at[r + 1]),
 * still in triangle order within each), so that a range's pass reads only
 * its own pairs. */
typedef struct grid_pairs {
    uint32_t *cell, *tri;
    size_t count, cap;
    uint32_t *range_at;
} grid_pairs;

/* A unit of pass 1: triangles [first, end) with all their cells, or one
 * large triangle (end = first + 1) with only its cells whose index along
 * `axis` lies in [lo, hi] (a slab). */
typedef struct grid_unit {
    uint32_t first, end;
    uint32_t lo, hi;   /* hi UINT32_MAX: every cell */
    int axis;
    int reports;       /* counts its triangles in the progress (a slab: the last of its triangle's) */
} grid_unit;

typedef struct grid_job {
    const as_mesh_t *mesh;
    const as_grid_header_t *g;
    const uint8_t *skip;          /* zero-area triangles */
    atomic_uint *counts;          /* per cell: its count, then its cursor (grid_range_pass) */
    uint32_t *prims;              /* pass 2 */
    atomic_uint_fast64_t refs;
    const as_build_args_t *args;
    pthread_mutex_t lock;
    atomic_int cancelled;
    atomic_uint_fast64_t done;
    uint64_t total;
    int pass;
    double pad;                   /* 4 x as_spatial_pad of the grid box */
    double budget;                /* most references allowed */
    atomic_int over;              /* pass 1 found more than the budget */
    atomic_int oom;
    grid_unit *units;             /* pass 1's work, in triangle order */
    size_t unit_count;
    grid_pairs *pairs;            /* one per unit */
    unsigned ranges;              /* a power of two; a cell's range is grid_range_of */
    /* Every wall is finite. Walls past float's range (a scene wider than
     * FLT_MAX) are infinite, the overlap test passes every cell between
     * them, and pass 1 then tests every cell (plane_lines_init). */
    int finite_walls;
} grid_job;

static int pairs_push(grid_pairs *p, uint32_t cell, uint32_t tri)
{
    if (p->count == p->cap) {
        const size_t cap = p->cap ? 2 * p->cap : 4 * BLOCK;
        uint32_t *c = realloc(p->cell, sizeof(uint32_t) * cap);
        if (c) p->cell = c;
        uint32_t *t = c ? realloc(p->tri, sizeof(uint32_t) * cap) : NULL;
        if (!c || !t) return 0;
        p->tri = t;
        p->cap = cap;
    }
    p->cell[p->count] = cell;
    p->tri[p->count] = tri;
    ++p->count;
    return 1;
}

static void report_progress(grid_job *job, uint32_t triangles)
{
    const uint64_t done = atomic_fetch_add(&job->done, triangles) + triangles;
    if (job->args->progress) {
        pthread_mutex_lock(&job->lock);
        if (!atomic_load(&job->cancelled) &&
            !job->args->progress(job->args->progress_user, 0.5 * (double)done / (double)job->total + 0.5 * (job->pass - 1)))
            atomic_store(&job->cancelled, 1);
        pthread_mutex_unlock(&job->lock);
    }
}

/* The box of cell index i on axis k: the same expressions as the traversal. */
static float wall(const as_grid_header_t *g, int k, uint32_t i)
{
    return i >= g->dims[k] ? g->hi[k] : g->lo[k] + (float)i * g->cell[k];
}

static uint32_t clamp_cell(const as_grid_header_t *g, int k, double x)
{
    const double f = (x - g->lo[k]) * g->inv_cell[k];
    if (!(f > 0)) return 0;
    if (f >= g->dims[k]) return g->dims[k] - 1;
    return (uint32_t)f;
}

/* Cells go to the counting and filling passes' ranges in runs of
 * RANGE_RUN_CELLS, dealt out in turn: a range of consecutive cells holds
 * one slab of the scene, and most triangles lie in a few (one range of 46
 * held 47% of bmw-m6's references, one of 57 held 43% of staircase2's), so
 * one thread did most of each pass. A run of 64 counts is four cache lines,
 * so threads on different ranges share none. */
#define RANGE_RUN_CELLS 64

static inline unsigned grid_range_of(const grid_job *job, uint32_t cell)
{
    return (cell / RANGE_RUN_CELLS) & (job->ranges - 1);
}

/* Groups a unit's pairs by range of cells, a stable counting sort. */
static int group_by_range(const grid_job *job, grid_pairs *p)
{
    const unsigned ranges = job->ranges;
    uint32_t *at = calloc((size_t)ranges + 1, sizeof(uint32_t));
    uint32_t *cell = malloc(sizeof(uint32_t) * (p->count ? p->count : 1));
    uint32_t *tri = malloc(sizeof(uint32_t) * (p->count ? p->count : 1));
    if (!at || !cell || !tri) {
        free(at);
        free(cell);
        free(tri);
        return 0;
    }
    for (size_t i = 0; i < p->count; ++i) at[grid_range_of(job, p->cell[i]) + 1]++;
    for (unsigned r = 0; r < ranges; ++r) at[r + 1] += at[r];
    for (size_t i = 0; i < p->count; ++i) {
        const uint32_t k = at[grid_range_of(job, p->cell[i])]++;
        cell[k] = p->cell[i];
        tri[k] = p->tri[i];
    }
    /* The cursors ended where each range ends: shift them back. */
    memmove(at + 1, at, sizeof(uint32_t) * ranges);
    at[0] = 0;
    free(p->cell);
    free(p->tri);
    p->cell = cell;
    p->tri = tri;
    p->cap = p->count;
    p->range_at = at;
    return 1;
}

/* The cells a triangle's plane can reach, line by line. A large slanted
 * triangle's box holds far more cells than the triangle meets (one of
 * bmw-m6's reaches 755,508 of its 2,980,340 cells, a quarter of every
 * test of the build, all in one block on one thread). as_tri_box_overlap
 * rejects a cell whose centre is farther from the plane, along the normal
 * n, than r = sum_k |n_k| (half width_k + pad); along a line of cells in
 * axis s that distance is linear in the centre, so the cells that can pass
 * lie in one interval. It is widened by two cells and by a rounding
 * allowance a million times the test's, so every cell left out fails the
 * test: the cells found, and the bytes, are those of testing every cell. */
#define PLANE_LINES_MIN_CELLS 64

typedef struct plane_lines {
    int s;                 /* the axis along the lines */
    double n[3], na;       /* the normal, n . a */
    double reach;          /* r, at least, for every cell, with the rounding allowance */
} plane_lines;

static int plane_lines_init(const grid_job *job, const float *a, const float *b, const float *c, const uint32_t c0[3],
                            const uint32_t c1[3], plane_lines *pl)
{
    const as_grid_header_t *g = job->g;
    const uint64_t cells = (uint64_t)(c1[0] - c0[0] + 1) * (c1[1] - c0[1] + 1) * (c1[2] - c0[2] + 1);
    if (cells < PLANE_LINES_MIN_CELLS || !job->finite_walls) return 0;
    double e0[3], e1[3];
    for (int k = 0; k < 3; ++k) {
        e0[k] = (double)b[k] - a[k];
        e1[k] = (double)c[k] - b[k];
    }
    pl->n[0] = e0[1] * e1[2] - e0[2] * e1[1];
    pl->n[1] = e0[2] * e1[0] - e0[0] * e1[2];
    pl->n[2] = e0[0] * e1[1] - e0[1] * e1[0];
    pl->s = 0;
    for (int k = 1; k < 3; ++k)
        if (fabs(pl->n[k]) > fabs(pl->n[pl->s])) pl->s = k;
    if (!(fabs(pl->n[pl->s]) > 0) || !isfinite(pl->n[pl->s]) || c1[pl->s] - c0[pl->s] < 4) return 0;
    pl->na = pl->n[0] * a[0] + pl->n[1] * a[1] + pl->n[2] * a[2];
    double reach = 0.0, size = fabs(pl->na);
    for (int k = 0; k < 3; ++k) {
        /* Half a cell (the last one may be wider by its wall's rounding),
         * and the pad that bounds every cell's. */
        reach += fabs(pl->n[k]) * (0.5 * (double)g->cell[k] * 1.001 + job->pad);
        size += fabs(pl->n[k]) * (fabs((double)g->lo[k]) + fabs((double)g->hi[k]) + (double)g->cell[k]);
    }
    pl->reach = reach + 1e-9 * (size + reach);
    return isfinite(pl->reach) && isfinite(pl->na);
}

/* The cells [first, last] of the line at cells (iu, iw) of the other two
 * axes that the plane can reach; 0 when none. first and last come in as
 * the box's and are narrowed. */
static int plane_line(const as_grid_header_t *g, const plane_lines *pl, uint32_t iu, uint32_t iw, uint32_t *first,
                      uint32_t *last)
{
    const int s = pl->s, u = (s + 1) % 3, w = (s + 2) % 3;
    const double cu = 0.5 * ((double)wall(g, u, iu) + (double)wall(g, u, iu + 1));
    const double cw = 0.5 * ((double)wall(g, w, iw) + (double)wall(g, w, iw + 1));
    /* n_s x centre_s must be within reach of this. */
    const double rest = pl->na - pl->n[u] * cu - pl->n[w] * cw;
    double x0 = (rest - pl->reach) / pl->n[s], x1 = (rest + pl->reach) / pl->n[s];
    if (x0 > x1) {
        const double t = x0;
        x0 = x1;
        x1 = t;
    }
    /* Centres to cells, two cells wider. */
    const double f0 = floor((x0 - (double)g->lo[s]) * (double)g->inv_cell[s]) - 2.0;
    const double f1 = floor((x1 - (double)g->lo[s]) * (double)g->inv_cell[s]) + 2.0;
    if (!(f1 >= (double)*first) || !(f0 <= (double)*last)) return 0;
    if (f0 > (double)*first) *first = (uint32_t)f0;
    if (f1 < (double)*last) *last = (uint32_t)f1;
    return 1;
}

/* The cells [c0, c1] that triangle t's box reaches, grown by the pad (which
 * bounds every cell's pad and the rounding of the walls); its vertices in
 * v. Returns whether the box is within one cell. */
static int triangle_cells(const grid_job *job, uint32_t t, const float *v[3], uint32_t c0[3], uint32_t c1[3])
{
    const as_mesh_t *m = job->mesh;
    const uint32_t *ix = m->indices + 3 * (size_t)t;
    for (int j = 0; j < 3; ++j) v[j] = m->positions + 3 * (size_t)ix[j];
    int single = 1;
    for (int k = 0; k < 3; ++k) {
        const float lo = min3f(v[0][k], v[1][k], v[2][k]), hi = max3f(v[0][k], v[1][k], v[2][k]);
        c0[k] = clamp_cell(job->g, k, (double)lo - job->pad);
        c1[k] = clamp_cell(job->g, k, (double)hi + job->pad);
        single &= c0[k] == c1[k];
    }
    return single;
}

/* Pass 1 over a unit: the cells of each triangle, kept as (cell, triangle)
 * pairs. */
static void grid_unit_pass(void *user, size_t unit)
{
    grid_job *job = user;
    if (atomic_load(&job->cancelled)) return;
    /* The unit's pairs are grown in a local copy and stored at the end:
     * neighbouring units' entries share cache lines, and the threads
     * working on them would trade the line at every push. */
    grid_pairs local = job->pairs[unit], *pairs = &local;
    const as_grid_header_t *g = job->g;
    const grid_unit *un = &job->units[unit];
    const uint32_t begin = un->first, end = un->end;
    uint64_t local_refs = 0;
    for (uint32_t t = begin; t < end; ++t) {
        if (job->skip[t]) continue;
        /* Pass 1 stops as soon as the budget is exceeded: the total would
         * exceed it too, whatever the order. Checked at each unit's first
         * triangle too (a slab's is its only one). */
        if (t == begin || (t & 63) == 0) {
            if (atomic_load(&job->over) || (double)(atomic_load(&job->refs) + local_refs) > job->budget) {
                atomic_store(&job->over, 1);
                job->pairs[unit] = local;
                return;
            }
        }
        const float *v[3];
        uint32_t c0[3], c1[3];
        const int single = triangle_cells(job, t, v, c0, c1);
        const float *a = v[0], *b = v[1], *c = v[2];
        /* The cells of the box line by line along axis s, the normal's
         * largest component; a box of many cells tests only the part of
         * each line that the triangle's plane can reach (plane_line). */
        plane_lines pl = {0, {0, 0, 0}, 0, 0};
        const int lines = !single && plane_lines_init(job, a, b, c, c0, c1, &pl);
        if (un->hi != UINT32_MAX) {
            /* A slab of a large triangle: the other slabs are other units. */
            if (un->lo > c0[un->axis]) c0[un->axis] = un->lo;
            if (un->hi < c1[un->axis]) c1[un->axis] = un->hi;
            if (c0[un->axis] > c1[un->axis]) continue;
        }
        const int s = lines ? pl.s : 0, u = (s + 1) % 3, w = (s + 2) % 3;
        uint32_t at[3];
        for (at[w] = c0[w]; at[w] <= c1[w]; ++at[w])
            for (at[u] = c0[u]; at[u] <= c1[u]; ++at[u]) {
                uint32_t first = c0[s], last = c1[s];
                if (lines && !plane_line(g, &pl, at[u], at[w], &first, &last)) continue;
                for (at[s] = first; at[s] <= last; ++at[s]) {
                    const uint32_t x = at[0], y = at[1], z = at[2];
                    const float lo[3] = {wall(g, 0, x), wall(g, 1, y), wall(g, 2, z)};
                    const float hi[3] = {wall(g, 0, x + 1), wall(g, 1, y + 1), wall(g, 2, z + 1)};
                    /* A box within one cell overlaps it: no test. */
                    if (!single && !as_tri_box_overlap(a, b, c, lo, hi, as_spatial_pad(lo, hi))) continue;
                    const size_t cell = ((size_t)z * g->dims[1] + y) * g->dims[0] + x;
                    ++local_refs;
                    if (!pairs_push(pairs, (uint32_t)cell, t)) {
                        atomic_store(&job->oom, 1);
                        job->pairs[unit] = local;
                        return;
                    }
                }
            }
    }
    if (!group_by_range(job, &local)) atomic_store(&job->oom, 1);
    job->pairs[unit] = local;
    atomic_fetch_add(&job->refs, local_refs);
    if (un->reports) report_progress(job, end - begin);
}

/* Pass 1's units. With few threads, blocks of BLOCK triangles. From
 * GRID_SPLIT_MIN_THREADS threads the work is planned first: a block whose
 * triangles' boxes reach more than UNIT_CELLS (or a share of the total,
 * UNIT_SHARE) cells in all is cut into
 * runs of triangles reaching about that many, and a triangle that alone
 * reaches more is cut into slabs along its box's longest axis (in cells).
 * One block of staircase held 14% of its references (a few large
 * triangles), so one thread did that much of the pass while the others
 * had finished. Units follow the triangle order, and a slab's cells are
 * its triangle's, each once: the pairs per cell come out in the order of
 * fixed blocks, and so PRIM. Units of up to 16,384 cells took up to 1.5 ms
 * each on staircase2, where 16 threads spent half the pass waiting for the
 * few that held its large triangles. */
#define UNIT_CELLS 2048
#define GRID_SPLIT_MIN_THREADS 4
#define SLABS_MAX 64
/* Units reach at least total / (UNIT_SHARE x threads) cells: a scene of
 * many large triangles makes at most about that many units beyond its
 * blocks (each unit holds pair buffers, and the counting passes visit
 * every unit for every range). */
#define UNIT_SHARE 32

typedef struct unit_cost_job {
    const grid_job *job;
    uint32_t *cells;        /* per triangle: the cells its box reaches, 0 for a zero-area one */
    uint64_t *block_cells;  /* per block: their sum */
} unit_cost_job;

static void unit_cost_block(void *user, size_t block)
{
    unit_cost_job *u = user;
    const grid_job *job = u->job;
    const uint32_t nt = job->mesh->triangle_count, begin = (uint32_t)(block * BLOCK);
    const uint32_t end = begin + BLOCK < nt ? begin + BLOCK : nt;
    uint64_t sum = 0;
    for (uint32_t t = begin; t < end; ++t) {
        uint64_t n = 0;
        if (!job->skip[t]) {
            const float *v[3];
            uint32_t c0[3], c1[3];
            triangle_cells(job, t, v, c0, c1);
            n = (uint64_t)(c1[0] - c0[0] + 1) * (c1[1] - c0[1] + 1) * (c1[2] - c0[2] + 1);
        }
        u->cells[t] = n > UINT32_MAX ? UINT32_MAX : (uint32_t)n;
        sum += u->cells[t];
    }
    u->block_cells[block] = sum;
}

static int unit_push(grid_job *job, size_t *cap, grid_unit u)
{
    if (job->unit_count == *cap) {
        const size_t c = *cap ? 2 * *cap : 64;
        grid_unit *g = realloc(job->units, sizeof *g * c);
        if (!g) return 0;
        job->units = g;
        *cap = c;
    }
    job->units[job->unit_count++] = u;
    return 1;
}

/* Fills job->units for the current grid; 0 when out of memory. */
static int plan_units(grid_job *job, unsigned threads, size_t blocks)
{
    const uint32_t nt = job->mesh->triangle_count;
    job->unit_count = 0;
    size_t cap = 0;
    free(job->units);
    job->units = NULL;
    uint32_t *cells = NULL;
    uint64_t *block_cells = NULL;
    if (threads >= GRID_SPLIT_MIN_THREADS && blocks > 1) {
        cells = malloc(sizeof(uint32_t) * nt);
        block_cells = malloc(sizeof(uint64_t) * blocks);
        if (cells && block_cells) {
            unit_cost_job uj = {job, cells, block_cells};
            as_parallel_for(threads, blocks, unit_cost_block, &uj);
        } else {
            /* Without the plan, blocks as with few threads. */
            free(cells);
            free(block_cells);
            cells = NULL;
            block_cells = NULL;
        }
    }
    uint64_t unit_cells = UNIT_CELLS;
    if (cells) {
        uint64_t total = 0;
        for (size_t bk = 0; bk < blocks; ++bk) total += block_cells[bk];
        if (total / ((uint64_t)UNIT_SHARE * threads) > unit_cells) unit_cells = total / ((uint64_t)UNIT_SHARE * threads);
    }
    int ok = 1;
    for (size_t bk = 0; bk < blocks && ok; ++bk) {
        const uint32_t begin = (uint32_t)(bk * BLOCK), end = begin + BLOCK < nt ? begin + BLOCK : nt;
        if (!cells || block_cells[bk] <= unit_cells) {
            ok = unit_push(job, &cap, (grid_unit){begin, end, 0, UINT32_MAX, 0, 1});
            continue;
        }
        uint32_t first = begin;
        uint64_t sum = 0;
        for (uint32_t t = begin; t < end && ok; ++t) {
            if (cells[t] > unit_cells) {
                if (t > first) ok = unit_push(job, &cap, (grid_unit){first, t, 0, UINT32_MAX, 0, 1});
                const float *v[3];
                uint32_t c0[3], c1[3];
                triangle_cells(job, t, v, c0, c1);
                int axis = 0;
                for (int k = 1; k < 3; ++k)
                    if (c1[k] - c0[k] > c1[axis] - c0[axis]) axis = k;
                const uint64_t span = (uint64_t)c1[axis] - c0[axis] + 1;
                uint64_t slabs = (cells[t] + unit_cells - 1) / unit_cells;
                if (slabs > span) slabs = span;
                if (slabs > SLABS_MAX) slabs = SLABS_MAX;
                for (uint64_t k = 0; k < slabs && ok; ++k) {
                    const uint32_t lo = c0[axis] + (uint32_t)(span * k / slabs);
                    const uint32_t hi = c0[axis] + (uint32_t)(span * (k + 1) / slabs) - 1;
                    ok = unit_push(job, &cap, (grid_unit){t, t + 1, lo, hi, axis, k + 1 == slabs});
                }
                first = t + 1;
                sum = 0;
                continue;
            }
            if (sum + cells[t] > unit_cells && t > first) {
                ok = unit_push(job, &cap, (grid_unit){first, t, 0, UINT32_MAX, 0, 1});
                first = t;
                sum = 0;
            }
            sum += cells[t];
        }
        if (ok && end > first) ok = unit_push(job, &cap, (grid_unit){first, end, 0, UINT32_MAX, 0, 1});
    }
    free(cells);
    free(block_cells);
    return ok;
}

/* A pass over every unit's pairs of one range of cells, in unit order:
 * each cell belongs to one range, so no two threads touch its count or
 * cursor (atomic adds on neighbouring cells from several threads cost more
 * than the pass), and each range's pairs are read once. Counting adds one
 * per pair to the cell's count; filling puts the pair's triangle at the
 * cell's cursor, so each list comes out in triangle order (the pairs are),
 * which is PRIM's order whatever the thread count. */
typedef struct range_job {
    grid_job *job;
    size_t units;
    int fill;          /* 0: count, 1: fill job->prims */
} range_job;

static void grid_range_pass(void *user, size_t range)
{
    const range_job *f = user;
    grid_job *job = f->job;
    if (atomic_load(&job->cancelled)) return;
    atomic_uint *at = job->counts;
    for (size_t b = 0; b < f->units; ++b) {
        const grid_pairs *pairs = &job->pairs[b];
        if (!pairs->range_at) continue;
        for (size_t i = pairs->range_at[range]; i < pairs->range_at[range + 1]; ++i) {
            const uint32_t cell = pairs->cell[i];
            const uint32_t k = atomic_load_explicit(&at[cell], memory_order_relaxed);
            atomic_store_explicit(&at[cell], k + 1, memory_order_relaxed);
            if (f->fill) job->prims[k] = pairs->tri[i];
        }
    }
    if (!f->fill) return;
    /* The second half of the progress, a range's share of the triangles. */
    const uint64_t nt = job->mesh->triangle_count;
    report_progress(job, (uint32_t)(nt * (range + 1) / job->ranges - nt * range / job->ranges));
}

static void free_pairs(grid_pairs *pairs, size_t units)
{
    if (!pairs) return;
    for (size_t b = 0; b < units; ++b) {
        free(pairs[b].cell);
        free(pairs[b].tri);
        free(pairs[b].range_at);
        pairs[b].cell = pairs[b].tri = pairs[b].range_at = NULL;
        pairs[b].count = pairs[b].cap = 0;
    }
}

/* Below these sizes a pass takes less time than starting the threads for
 * it. At 262,144 triangles and 1,048,576 cells the bunny's bounds pass and
 * prefix sum ran on one thread, 2.2 and 1.4 ms of a 16-thread build of 4 to
 * 7 ms; from 32,768 and 131,072, 0.2 ms each and builds of 2.8 to 3.0 ms
 * (run 124). Since threads watch for work before they sleep (thread_crew.c)
 * a step on them costs about 10 us, and staircase2 (30,927 triangles,
 * 123,708 cells), whose two passes had run on one thread, a tenth of the
 * work and a third of a 16-thread build, takes them on every thread too. */
#define PARALLEL_MIN_TRIANGLES 4096
#define PARALLEL_MIN_CELLS (1u << 14)

#define BOUNDS_CHUNKS 64

typedef struct bounds_job {
    const as_mesh_t *mesh;
    uint8_t *skip;
    float box[BOUNDS_CHUNKS][6];
    uint32_t count[BOUNDS_CHUNKS];
    unsigned chunks;
} bounds_job;

static void grid_bounds_chunk(void *user, size_t ch)
{
    bounds_job *j = user;
    const as_mesh_t *m = j->mesh;
    const uint32_t nt = m->triangle_count;
    uint32_t begin, end;
    as_chunk_range(nt, (unsigned)ch, j->chunks, &begin, &end);
    float lo[3] = {FLT_MAX, FLT_MAX, FLT_MAX}, hi[3] = {-FLT_MAX, -FLT_MAX, -FLT_MAX};
    uint32_t n = 0;
    for (uint32_t i = begin; i < end; ++i) {
        j->skip[i] = (uint8_t)as_mesh_triangle_is_degenerate(m, i);
        if (j->skip[i]) continue;
        ++n;
        for (int v = 0; v < 3; ++v) {
            const float *q = m->positions + 3 * (size_t)m->indices[3 * (size_t)i + v];
            for (int k = 0; k < 3; ++k) {
                if (q[k] < lo[k]) lo[k] = q[k];
                if (q[k] > hi[k]) hi[k] = q[k];
            }
        }
    }
    memcpy(j->box[ch], lo, sizeof lo);
    memcpy(j->box[ch] + 3, hi, sizeof hi);
    j->count[ch] = n;
}

#define PREFIX_CHUNKS 64

typedef struct prefix_job {
    atomic_uint *counts; /* per cell: its count, then its cursor (its offset) */
    uint32_t *offsets;
    uint64_t cells;
    unsigned chunks;
    uint64_t sum[PREFIX_CHUNKS];      /* a chunk's count, then where it starts */
    uint64_t nonempty[PREFIX_CHUNKS];
    int write;
} prefix_job;

static void grid_prefix_chunk(void *user, size_t ch)
{
    prefix_job *j = user;
    const uint64_t c0 = j->cells * ch / j->chunks, c1 = j->cells * (ch + 1) / j->chunks;
    if (!j->write) {
        uint64_t sum = 0, nonempty = 0;
        for (uint64_t c = c0; c < c1; ++c) {
            const uint32_t k = atomic_load_explicit(&j->counts[c], memory_order_relaxed);
            sum += k;
            nonempty += k != 0;
        }
        j->sum[ch] = sum;
        j->nonempty[ch] = nonempty;
        return;
    }
    uint64_t sum = j->sum[ch];
    for (uint64_t c = c0; c < c1; ++c) {
        const uint32_t k = atomic_load_explicit(&j->counts[c], memory_order_relaxed);
        j->offsets[c] = (uint32_t)sum;
        atomic_store_explicit(&j->counts[c], (unsigned)sum, memory_order_relaxed);
        sum += k;
    }
}

/* The cells' counts: a block earlier builds gave back (as_block_take),
 * zeroed in chunks, on every thread from PARALLEL_MIN_CELLS cells. A fresh
 * calloc of millions of cells cost a page fault per 4 KB at every build,
 * most of a build's system time (bmw-m6: 3,000 faults, 50-70 ms of system
 * time for a 120 ms build), and the faults of many threads wait on each
 * other. */
typedef struct zero_job {
    unsigned char *p;
    size_t bytes;
    unsigned chunks;
} zero_job;

static void zero_chunk(void *user, size_t ch)
{
    const zero_job *z = user;
    const size_t b0 = z->bytes * ch / z->chunks, b1 = z->bytes * (ch + 1) / z->chunks;
    memset(z->p + b0, 0, b1 - b0);
}

static atomic_uint *counts_take(uint64_t cells, unsigned threads)
{
    atomic_uint *c = as_block_take(sizeof(atomic_uint) * cells, 1, "grid cell counts");
    if (!c) return NULL;
    zero_job z = {(unsigned char *)c, sizeof(atomic_uint) * cells, cells < PREFIX_CHUNKS ? 1u : PREFIX_CHUNKS};
    as_parallel_for(cells >= PARALLEL_MIN_CELLS ? threads : 1, z.chunks, zero_chunk, &z);
    return c;
}

static void counts_give(atomic_uint *c, uint64_t cells)
{
    as_block_give(c, sizeof(atomic_uint) * cells, 1);
}

/* Cells per axis for a scale factor (cells per unit length). */
static void dims_for(const double ext[3], const int active[3], double s, uint32_t dims[3])
{
    for (int k = 0; k < 3; ++k) {
        double d = active[k] ? floor(ext[k] * s + 0.5) : 1.0;
        if (d < 1) d = 1;
        if (d > AS_GRID_MAX_CELLS) d = AS_GRID_MAX_CELLS;
        dims[k] = (uint32_t)d;
    }
}

as_error_t as_grid_build(const as_mesh_t *mesh, const as_build_args_t *args, as_structure_t *s)
{
    const double t_start = as_now_ms();
    if (!(args->grid_lambda > 0.0f) || !isfinite(args->grid_lambda))
        return as_set_error(AS_ERROR_INVALID_ARGUMENT, "grid lambda must be positive and finite");
    if (!(args->split_budget >= 1.0f))
        return as_set_error(AS_ERROR_INVALID_ARGUMENT, "split budget must be at least 1");
    if (!(args->cost_traversal >= 0.0f) || !(args->cost_intersection > 0.0f))
        return as_set_error(AS_ERROR_INVALID_ARGUMENT, "SAH costs must be finite, traversal >= 0, intersection > 0");
    if (args->layout != AS_LAYOUT_GRID)
        return as_set_error(AS_ERROR_UNSUPPORTED, "the grid builder writes only the grid layout");
    const unsigned threads = as_thread_count(args->thread_count);
    const uint32_t nt = mesh->triangle_count;
    const size_t blocks = (nt + BLOCK - 1) / BLOCK;
    uint8_t *skip = malloc(nt ? nt : 1);
    if (!skip) return as_set_error(AS_ERROR_OUT_OF_MEMORY, "out of memory for the grid build");
    /* The zero-area triangles and the others' bounds, in chunks of blocks on
     * every thread; the chunks' bounds merged in order, so a bound that is
     * zero keeps the sign of its first occurrence, as one pass would. */
    bounds_job bj = {mesh, skip, {{0}}, {0}, blocks < BOUNDS_CHUNKS ? (unsigned)(blocks ? blocks : 1) : BOUNDS_CHUNKS};
    as_parallel_for(nt >= PARALLEL_MIN_TRIANGLES ? threads : 1, bj.chunks, grid_bounds_chunk, &bj);
    uint32_t n = 0;
    float blo[3] = {FLT_MAX, FLT_MAX, FLT_MAX}, bhi[3] = {-FLT_MAX, -FLT_MAX, -FLT_MAX};
    for (unsigned ch = 0; ch < bj.chunks; ++ch) {
        n += bj.count[ch];
        for (int k = 0; k < 3; ++k) {
            if (bj.box[ch][k] < blo[k]) blo[k] = bj.box[ch][k];
            if (bj.box[ch][k + 3] > bhi[k]) bhi[k] = bj.box[ch][k + 3];
        }
    }
    if (n == 0) for (int k = 0; k < 3; ++k) { blo[k] = 0.0f; bhi[k] = 0.0f; }
    as_grid_header_t *g = as_aligned_alloc(sizeof *g, "grid header");
    uint32_t *offsets = NULL, *prims = NULL;
    as_tri4_t *tris = NULL;
    atomic_uint *counts = NULL;
    uint64_t counts_cells = 0;
    as_error_t err = AS_OK;
    grid_job job;
    memset(&job, 0, sizeof job);
    pthread_mutex_init(&job.lock, NULL);
    if (!g) { err = as_get_error(); goto done; }
    memset(g, 0, sizeof *g);
    double ext[3], maxext = 0.0;
    for (int k = 0; k < 3; ++k) {
        g->lo[k] = blo[k];
        g->hi[k] = bhi[k];
        ext[k] = (double)bhi[k] - blo[k];
        if (ext[k] > maxext) maxext = ext[k];
    }
    /* An axis thinner than 1e-6 of the largest extent counts as flat. */
    int active[3], nactive = 0;
    double measure = 1.0;
    for (int k = 0; k < 3; ++k) {
        active[k] = maxext > 0 && ext[k] > 1e-6 * maxext;
        if (active[k]) { ++nactive; measure *= ext[k]; }
    }
    double scale = nactive ? pow((double)args->grid_lambda * (double)(n ? n : 1) / measure, 1.0 / nactive) : 0.0;
    const double budget = (double)args->split_budget * (double)(n ? n : 1);
    job.mesh = mesh;
    job.g = g;
    job.skip = skip;
    job.args = args;
    job.total = 2 * (uint64_t)(nt ? nt : 1);
    job.pad = 4.0 * as_spatial_pad(g->lo, g->hi);
    job.budget = budget < (double)0xFFFFFFF0u ? budget : (double)0xFFFFFFF0u;
    uint64_t cells = 1;
    for (;;) {
        dims_for(ext, active, scale, g->dims);
        cells = (uint64_t)g->dims[0] * g->dims[1] * g->dims[2];
        if (cells > AS_GRID_MAX_CELLS) {
            scale *= pow((double)AS_GRID_MAX_CELLS / (double)cells, 1.0 / (nactive ? nactive : 1)) * 0.999;
            continue;
        }
        for (int k = 0; k < 3; ++k) {
            g->cell[k] = active[k] ? (float)(ext[k] / g->dims[k]) : 0.0f;
            g->inv_cell[k] = active[k] ? (float)(g->dims[k] / ext[k]) : 0.0f;
            if (!active[k]) g->dims[k] = 1;
        }
        counts_give(counts, counts_cells);
        counts = counts_take(cells, threads);
        counts_cells = cells;
        if (!counts) { err = as_set_error(AS_ERROR_OUT_OF_MEMORY, "out of memory for %llu grid cells", (unsigned long long)cells); goto done; }
        job.counts = counts;
        job.finite_walls = 1;
        for (int k = 0; k < 3; ++k) /* walls grow with their index: the last one is the largest */
            job.finite_walls &= isfinite(wall(g, k, g->dims[k] - 1)) && isfinite(g->lo[k]) && isfinite(g->hi[k]);
        /* Ranges for the counting and filling passes: four to eight per
         * thread, no more than there are runs of cells. */
        const uint64_t runs = (cells + RANGE_RUN_CELLS - 1) / RANGE_RUN_CELLS;
        job.ranges = 1;
        while (job.ranges < 4u * threads && 2u * job.ranges <= runs) job.ranges *= 2;
        job.pass = 1;
        atomic_store(&job.over, 0);
        atomic_store(&job.refs, 0);
        atomic_store(&job.done, 0);
        free_pairs(job.pairs, job.unit_count);
        free(job.pairs);
        job.pairs = NULL;
        if (!plan_units(&job, threads, blocks) || !(job.pairs = calloc(job.unit_count ? job.unit_count : 1, sizeof *job.pairs))) {
            err = as_set_error(AS_ERROR_OUT_OF_MEMORY, "out of memory for the grid build");
            goto done;
        }
        as_parallel_for(threads, job.unit_count, grid_unit_pass, &job);
        if (atomic_load(&job.cancelled)) { err = as_set_error(AS_ERROR_CANCELLED, "grid build cancelled by the progress callback"); goto done; }
        if (atomic_load(&job.oom)) { err = as_set_error(AS_ERROR_OUT_OF_MEMORY, "out of memory for the grid build"); goto done; }
        const uint64_t refs = atomic_load(&job.refs);
        if (!atomic_load(&job.over) && (double)refs <= job.budget) {
            const range_job count = {&job, job.unit_count, 0};
            as_parallel_for(threads, job.ranges, grid_range_pass, (void *)&count);
            break;
        }
        if (cells == 1) {
            /* One cell holds every triangle once: within any budget >= 1. */
            err = as_set_error(AS_ERROR_UNSUPPORTED, "grid references exceed 32 bits");
            goto done;
        }
        /* Too many references: coarser. The 0.8 keeps the grid as fine as
         * the budget allows, to within a factor 0.8 per axis. */
        scale *= 0.8;
    }
    offsets = as_aligned_alloc(sizeof(uint32_t) * (cells + 1), "grid cell offsets");
    const uint64_t refs = atomic_load(&job.refs);
    prims = as_aligned_alloc(sizeof(uint32_t) * (refs ? refs : 1), "grid PRIM");
    tris = as_spatial_tris(mesh, as_thread_count(args->thread_count));
    if (!offsets || !prims || !tris) { err = as_get_error(); goto done; }
    /* The prefix sum in chunks of cells: each chunk's sum, then each chunk
     * from where the chunks before it end. */
    prefix_job pj = {counts, offsets, cells, cells < PREFIX_CHUNKS ? (unsigned)cells : PREFIX_CHUNKS, {0}, {0}, 0};
    as_parallel_for(cells >= PARALLEL_MIN_CELLS ? threads : 1, pj.chunks, grid_prefix_chunk, &pj);
    uint64_t sum = 0, nonempty = 0;
    for (unsigned ch = 0; ch < pj.chunks; ++ch) {
        const uint64_t k = pj.sum[ch];
        pj.sum[ch] = sum;
        sum += k;
        nonempty += pj.nonempty[ch];
    }
    pj.write = 1;
    as_parallel_for(cells >= PARALLEL_MIN_CELLS ? threads : 1, pj.chunks, grid_prefix_chunk, &pj);
    offsets[cells] = (uint32_t)sum;
    job.pass = 2;
    job.prims = prims;
    atomic_store(&job.done, 0);
    const range_job fill = {&job, job.unit_count, 1};
    as_parallel_for(threads, job.ranges, grid_range_pass, (void *)&fill);
    free_pairs(job.pairs, job.unit_count);
    if (atomic_load(&job.cancelled)) { err = as_set_error(AS_ERROR_CANCELLED, "grid build cancelled by the progress callback"); goto done; }

    as_spatial_meta(s, mesh, args, AS_STRUCT_GRID, AS_LAYOUT_GRID, AS_GRID_LAYOUT_VERSION, AS_BUILDER_GRID);
    s->meta.node_count = 0;
    s->meta.leaf_count = nonempty;
    s->meta.empty_leaf_count = cells - nonempty;
    s->meta.reference_count = sum;
    s->meta.max_depth = 0;
    s->meta.max_depth_limit = 0;
    s->meta.grid_lambda = args->grid_lambda;
    s->meta.split_budget = args->split_budget;
    as_structure_add_section(s, ASF_TAG_GRDH, g, 1, sizeof *g);
    as_structure_add_kept_section(s, ASF_TAG_GRDC, offsets, cells + 1, sizeof(uint32_t), sizeof(uint32_t) * (cells + 1));
    as_structure_add_kept_section(s, ASF_TAG_PRIM, prims, sum, sizeof(uint32_t), sizeof(uint32_t) * (size_t)(refs ? refs : 1));
    as_spatial_add_tris(s, tris, nt);
    g = NULL;
    offsets = prims = NULL;
    tris = NULL;
    s->meta.sah_cost = as_grid_sah_cost(s, NULL);
    s->build_ms = as_now_ms() - t_start;
done:
    pthread_mutex_destroy(&job.lock);
    free_pairs(job.pairs, job.unit_count);
    free(job.pairs);
    free(job.units);
    free(skip);
    counts_give(counts, counts_cells);
    free(g);
    free(offsets);
    free(prims);
    free(tris);
    return err;
}
