/* Octree builder: 8-way spatial subdivision of a cube around the scene,
 * level by level (breadth first). A cell is subdivided while it holds more
 * than max_leaf_size triangles and is above the depth limit; each triangle
 * goes to every child whose cell it overlaps (exact triangle/box test,
 * Akenine-Moller 2001, so no false references beyond a few-ulp pad).
 *
 * Termination and budgets:
 *  - depth limit: args->max_depth, else AS_OCTREE_DEFAULT_DEPTH, never more
 *    than AS_OCTREE_MAX_DEPTH (the traversal stack);
 *  - no progress: a cell whose non-empty children, two or more, would each
 *    hold all of its triangles (triangles spanning the cell, copies on a
 *    mid-plane) stays a leaf; one non-empty child is progress (the cell
 *    shrinks around its triangles at no cost in references);
 *  - reference budget: the structure holds at most split_budget x N
 *    references; cells are split in breadth-first order while the budget
 *    allows, the rest stay leaves.
 *
 * Determinism: each level's cells are split in parallel, each into its own
 * buffers; the decisions (no progress, budget) and the node numbering are
 * then made sequentially in breadth-first order, so the output does not
 * depend on the thread count. Children of a node are 8 consecutive nodes. */
#include "spatial_common.h"
#include "octree_layout.h"
#include "octree_traverse.h"

#include <float.h>
#include <math.h>
#include <stdatomic.h>
#include <stdlib.h>
#include <string.h>

/* Plain comparisons: libm's fminf is a call without -ffinite-math-only. */
static inline float min3f(float a, float b, float c) { const float m = a < b ? a : b; return m < c ? m : c; }
static inline float max3f(float a, float b, float c) { const float m = a > b ? a : b; return m > c ? m : c; }

typedef struct oct_cell {
    float lo[3];
    uint32_t depth;
    uint32_t *tris;          /* owned list of source indices, or NULL */
    uint32_t count;
    uint32_t node;           /* node index */
} oct_cell;

typedef struct oct_split_job {
    const as_mesh_t *mesh;
    float size;
    oct_cell *cells;         /* this level's cells */
    uint32_t *candidates;    /* indices into cells */
    uint32_t **child_lists;  /* per candidate: 8 lists, one buffer */
    uint32_t (*child_counts)[8];
    atomic_int failed;
} oct_split_job;

static void split_cell(void *user, size_t index)
{
    oct_split_job *job = user;
    if (atomic_load(&job->failed)) return;
    const oct_cell *c = &job->cells[job->candidates[index]];
    const float half = as_oct_cell_size(job->size, (int)c->depth + 1);
    uint32_t *buf = malloc(sizeof(uint32_t) * 8 * (size_t)c->count);
    if (!buf) { atomic_store(&job->failed, 1); return; }
    job->child_lists[index] = buf;
    const float *p = job->mesh->positions;
    float clo[8][3], chi[8][3], mid[3];
    double pad[8];
    for (int k = 0; k < 3; ++k) mid[k] = c->lo[k] + half;
    for (int ch = 0; ch < 8; ++ch) {
        for (int k = 0; k < 3; ++k) {
            const int bit = (ch >> (2 - k)) & 1;
            clo[ch][k] = bit ? mid[k] : c->lo[k];
            chi[ch][k] = clo[ch][k] + half;
        }
        pad[ch] = as_spatial_pad(clo[ch], chi[ch]);
    }
    uint32_t n[8] = {0, 0, 0, 0, 0, 0, 0, 0};
    for (uint32_t i = 0; i < c->count; ++i) {
        const uint32_t id = c->tris[i];
        const uint32_t *ix = job->mesh->indices + 3 * (size_t)id;
        const float *a = p + 3 * (size_t)ix[0], *b = p + 3 * (size_t)ix[1], *cc = p + 3 * (size_t)ix[2];
        /* Which halves the triangle's box reaches on each axis (the pads
         * are a few ulps: pad[0] bounds them all). */
        int lower[3], upper[3], straddles = 0;
        for (int k = 0; k < 3; ++k) {
            const float lo = min3f(a[k], b[k], cc[k]), hi = max3f(a[k], b[k], cc[k]);
            const double pk = pad[7] > pad[0] ? pad[7] : pad[0];
            lower[k] = (double)lo <= (double)mid[k] + pk;
            upper[k] = (double)hi >= (double)mid[k] - pk;
            straddles |= lower[k] && upper[k];
        }
        for (int ch = 0; ch < 8; ++ch) {
            int ok = 1;
            for (int k = 0; k < 3; ++k) ok &= ((ch >> (2 - k)) & 1) ? upper[k] : lower[k];
            if (!ok) continue;
            /* A box inside one child's half on every axis needs no test:
             * the triangle overlaps the parent, so it overlaps the child. */
            if (straddles && !as_tri_box_overlap(a, b, cc, clo[ch], chi[ch], pad[ch])) continue;
            buf[(size_t)ch * c->count + n[ch]++] = id;
        }
    }
    for (int ch = 0; ch < 8; ++ch) job->child_counts[index][ch] = n[ch];
}

as_error_t as_octree_build(const as_mesh_t *mesh, const as_build_args_t *args, as_structure_t *s)
{
    const double t_start = as_now_ms();
    if (args->max_leaf_size < 1) return as_set_error(AS_ERROR_INVALID_ARGUMENT, "max leaf size must be at least 1");
    if (!(args->cost_traversal >= 0.0f) || !(args->cost_intersection > 0.0f))
        return as_set_error(AS_ERROR_INVALID_ARGUMENT, "SAH costs must be finite, traversal >= 0, intersection > 0");
    if (!(args->split_budget >= 1.0f))
        return as_set_error(AS_ERROR_INVALID_ARGUMENT, "split budget must be at least 1");
    if (args->layout != AS_LAYOUT_OCTREE)
        return as_set_error(AS_ERROR_UNSUPPORTED, "the octree builder writes only the octree layout");
    const unsigned threads = as_thread_count(args->thread_count);
    const uint32_t depth_limit = args->max_depth == 0 ? AS_OCTREE_DEFAULT_DEPTH
                                 : args->max_depth < AS_OCTREE_MAX_DEPTH ? args->max_depth : AS_OCTREE_MAX_DEPTH;

    /* The cube: centred on the box of the non-degenerate triangles, its edge
     * the box's longest extent grown by 1/1024, so no triangle touches a
     * face of the root. */
    uint32_t n = 0;
    float blo[3] = {FLT_MAX, FLT_MAX, FLT_MAX}, bhi[3] = {-FLT_MAX, -FLT_MAX, -FLT_MAX};
    for (uint32_t i = 0; i < mesh->triangle_count; ++i) {
        if (as_mesh_triangle_is_degenerate(mesh, i)) continue;
        ++n;
        for (int v = 0; v < 3; ++v) {
            const float *q = mesh->positions + 3 * (size_t)mesh->indices[3 * (size_t)i + v];
            for (int k = 0; k < 3; ++k) {
                if (q[k] < blo[k]) blo[k] = q[k];
                if (q[k] > bhi[k]) bhi[k] = q[k];
            }
        }
    }
    as_octree_header_t *hdr = as_aligned_alloc(sizeof *hdr, "octree header");
    if (!hdr) return as_get_error();
    memset(hdr, 0, sizeof *hdr);
    if (n == 0) {
        hdr->size = 1.0f;
    } else {
        double ext = 0.0;
        for (int k = 0; k < 3; ++k)
            if ((double)bhi[k] - blo[k] > ext) ext = (double)bhi[k] - blo[k];
        double mag = 0.0;
        for (int k = 0; k < 3; ++k) mag = fmax(mag, fmax(fabs((double)blo[k]), fabs((double)bhi[k])));
        const double size = ext * (1.0 + 1.0 / 1024.0) + mag * 0x1p-18;
        hdr->size = (float)size;
        for (int k = 0; k < 3; ++k) hdr->lo[k] = (float)(0.5 * ((double)blo[k] + bhi[k]) - 0.5 * size);
        /* Rounding may leave the box a hair outside: grow until it is not. */
        for (int k = 0; k < 3; ++k) {
            while (hdr->lo[k] > blo[k]) hdr->lo[k] = nextafterf(hdr->lo[k], -INFINITY);
            while (hdr->lo[k] + hdr->size < bhi[k]) hdr->size = nextafterf(hdr->size, INFINITY);
        }
    }

    /* Breadth-first: `cells` holds every cell made so far, in node order. */
    uint64_t cell_cap = 1024, cell_count = 1;
    oct_cell *cells = malloc(sizeof(oct_cell) * cell_cap);
    as_octree_node_t *nodes = NULL;
    uint32_t *prims = NULL;
    as_tri4_t *tris = NULL;
    as_error_t err = AS_OK;
    if (!cells) { free(hdr); return as_set_error(AS_ERROR_OUT_OF_MEMORY, "out of memory for octree cells"); }
    memcpy(cells[0].lo, hdr->lo, sizeof cells[0].lo);
    cells[0].depth = 0;
    cells[0].count = n;
    cells[0].node = 0;
    cells[0].tris = malloc(sizeof(uint32_t) * (size_t)(n ? n : 1));
    if (!cells[0].tris) { err = as_set_error(AS_ERROR_OUT_OF_MEMORY, "out of memory for octree lists"); goto done; }
    {
        uint32_t k = 0;
        for (uint32_t i = 0; i < mesh->triangle_count; ++i)
            if (!as_mesh_triangle_is_degenerate(mesh, i)) cells[0].tris[k++] = i;
    }
    const double budget = (double)args->split_budget * (double)(n ? n : 1);
    uint64_t refs = n;
    uint64_t level_begin = 0, level_end = 1;
    for (uint32_t depth = 0; depth < depth_limit && level_begin < level_end; ++depth) {
        if (args->progress && !args->progress(args->progress_user, (double)depth / depth_limit)) {
            err = as_set_error(AS_ERROR_CANCELLED, "octree build cancelled by the progress callback");
            goto done;
        }
        uint32_t *cand = malloc(sizeof(uint32_t) * (size_t)(level_end - level_begin));
        uint32_t nc = 0;
        if (!cand) { err = as_set_error(AS_ERROR_OUT_OF_MEMORY, "out of memory for octree candidates"); goto done; }
        for (uint64_t c = level_begin; c < level_end; ++c)
            if (cells[c].count > args->max_leaf_size) cand[nc++] = (uint32_t)c;
        oct_split_job job = {mesh, hdr->size, cells, cand, calloc(nc ? nc : 1, sizeof(uint32_t *)),
                             calloc(nc ? nc : 1, sizeof(uint32_t[8])), 0};
        if (!job.child_lists || !job.child_counts) {
            free(cand); free(job.child_lists); free(job.child_counts);
            err = as_set_error(AS_ERROR_OUT_OF_MEMORY, "out of memory for octree children");
            goto done;
        }
        as_parallel_for(threads, nc, split_cell, &job);
        if (atomic_load(&job.failed)) err = as_set_error(AS_ERROR_OUT_OF_MEMORY, "out of memory splitting octree cells");
        /* Sequential decisions, in breadth-first order. */
        uint64_t next_end = level_end;
        for (uint32_t j = 0; j < nc && err == AS_OK; ++j) {
            oct_cell *c = &cells[cand[j]];
            uint64_t sum = 0;
            int progress = 0, nonempty = 0;
            for (int ch = 0; ch < 8; ++ch) {
                sum += job.child_counts[j][ch];
                nonempty += job.child_counts[j][ch] != 0;
                if (job.child_counts[j][ch] && job.child_counts[j][ch] < c->count) progress = 1;
            }
            /* All triangles in one child: the split adds no reference and
             * shrinks the cell around them (geometry clustered in a corner of
             * a large cube), so it is progress; the depth limit ends it for
             * coincident copies. */
            if (nonempty == 1) progress = 1;
            if (!progress || (double)(refs - c->count + sum) > budget) continue;
            refs = refs - c->count + sum;
            if (next_end + 8 > cell_cap) {
                while (next_end + 8 > cell_cap) cell_cap *= 2;
                oct_cell *grown = realloc(cells, sizeof(oct_cell) * cell_cap);
                if (!grown) { err = as_set_error(AS_ERROR_OUT_OF_MEMORY, "out of memory for octree cells"); break; }
                cells = grown;
                job.cells = cells;
                c = &cells[cand[j]];
            }
            const float half = as_oct_cell_size(hdr->size, (int)c->depth + 1);
            for (int ch = 0; ch < 8; ++ch) {
                oct_cell *d = &cells[next_end + (uint64_t)ch];
                for (int k = 0; k < 3; ++k) d->lo[k] = ((ch >> (2 - k)) & 1) ? c->lo[k] + half : c->lo[k];
                d->depth = c->depth + 1;
                d->count = job.child_counts[j][ch];
                d->tris = NULL;
                d->node = 0;
                if (d->count) {
                    d->tris = malloc(sizeof(uint32_t) * d->count);
                    if (!d->tris) { err = as_set_error(AS_ERROR_OUT_OF_MEMORY, "out of memory for octree lists"); break; }
                    memcpy(d->tris, job.child_lists[j] + (size_t)ch * c->count, sizeof(uint32_t) * d->count);
                }
            }
            /* The parent becomes inner: its list goes; `node` now names the
             * first child's cell. */
            free(c->tris);
            c->tris = NULL;
            c->count = AS_OCTREE_INNER;
            c->node = (uint32_t)next_end;
            next_end += 8;
        }
        for (uint32_t j = 0; j < nc; ++j) free(job.child_lists[j]);
        free(job.child_lists);
        free(job.child_counts);
        free(cand);
        if (err != AS_OK) {
            /* Cells made so far are freed below. */
            cell_count = next_end;
            goto done;
        }
        level_begin = level_end;
        level_end = next_end;
        cell_count = next_end;
    }
    if (args->progress && !args->progress(args->progress_user, 1.0)) {
        err = as_set_error(AS_ERROR_CANCELLED, "octree build cancelled by the progress callback");
        goto done;
    }
    if (cell_count > 0xFFFFFFF0u || refs > 0xFFFFFFF0u) {
        err = as_set_error(AS_ERROR_UNSUPPORTED, "octree too large for 32-bit indices");
        goto done;
    }
    nodes = as_aligned_alloc(sizeof(as_octree_node_t) * cell_count, "octree nodes");
    prims = as_aligned_alloc(sizeof(uint32_t) * (size_t)(refs ? refs : 1), "octree PRIM");
    tris = as_spatial_tris(mesh, as_thread_count(args->thread_count));
    if (!nodes || !prims || !tris) { err = as_get_error(); goto done; }
    uint64_t p = 0, inner = 0, leaves = 0, empty = 0;
    uint32_t max_depth = 0;
    for (uint64_t c = 0; c < cell_count; ++c) {
        if (cells[c].count == AS_OCTREE_INNER) {
            nodes[c].first = cells[c].node;
            nodes[c].count = AS_OCTREE_INNER;
            ++inner;
            continue;
        }
        nodes[c].first = (uint32_t)p;
        nodes[c].count = cells[c].count;
        if (cells[c].count) memcpy(prims + p, cells[c].tris, sizeof(uint32_t) * cells[c].count);
        p += cells[c].count;
        if (cells[c].count) ++leaves; else ++empty;
        if (cells[c].count && cells[c].depth > max_depth) max_depth = cells[c].depth;
    }
    as_spatial_meta(s, mesh, args, AS_STRUCT_OCTREE, AS_LAYOUT_OCTREE, AS_OCTREE_LAYOUT_VERSION, AS_BUILDER_OCTREE);
    s->meta.node_count = inner;
    s->meta.leaf_count = leaves;
    s->meta.empty_leaf_count = empty;
    s->meta.reference_count = p;
    s->meta.max_depth = max_depth;
    s->meta.max_depth_limit = depth_limit;
    s->meta.split_budget = args->split_budget;
    as_structure_add_section(s, ASF_TAG_OCTH, hdr, 1, sizeof *hdr);
    as_structure_add_section(s, ASF_TAG_OCTN, nodes, cell_count, sizeof(as_octree_node_t));
    as_structure_add_section(s, ASF_TAG_PRIM, prims, p, sizeof(uint32_t));
    as_spatial_add_tris(s, tris, mesh->triangle_count);
    hdr = NULL;
    nodes = NULL;
    prims = NULL;
    tris = NULL;
    s->meta.sah_cost = as_octree_sah_cost(s, NULL);
    s->build_ms = as_now_ms() - t_start;
done:
    for (uint64_t c = 0; c < cell_count; ++c)
        if (cells[c].count != AS_OCTREE_INNER) free(cells[c].tris);
    free(cells);
    free(hdr);
    free(nodes);
    free(prims);
    free(tris);
    return err;
}
