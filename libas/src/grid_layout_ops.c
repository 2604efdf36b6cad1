/* The uniform grid layout: its sections, statistics and SAH cost, and the
 * CPU traversal (kernels/grid_traverse.h; the GPU launcher comes later).
 *
 * SAH cost of a grid: the SAH of the grid seen as a one-level tree whose
 * root is the grid box and whose leaves are the cells: C_t for the root,
 * plus for every cell (C_t + C_i refs(cell)) A(cell) / A(root), A being the
 * surface area. It is not the expected number of cells a ray visits (the
 * DDA visits about dims^(1/3) of them per ray, not a fraction by area), but
 * it puts grids beside the trees on the same scale as the study's column. */
#include "spatial_common.h"
#include "grid_traverse.h"

#include <string.h>

double as_grid_sah_cost(const as_structure_t *s, as_structure_stats_t *st)
{
    const as_grid_header_t *g = as_structure_find(s, ASF_TAG_GRDH)->data;
    const as_section_t *cs = as_structure_find(s, ASF_TAG_GRDC);
    const uint32_t *off = cs->data;
    const double ci = s->meta.cost_intersection, ct = s->meta.cost_traversal;
    const double root_area = as_spatial_half_area(g->lo, g->hi);
    const float cell_lo[3] = {0, 0, 0};
    float cell_hi[3];
    for (int k = 0; k < 3; ++k) cell_hi[k] = g->cell[k] > 0 ? g->cell[k] : g->hi[k] - g->lo[k];
    const double rel = root_area > 0 ? as_spatial_half_area(cell_lo, cell_hi) / root_area : 1.0;
    const uint64_t cells = cs->count - 1;
    /* Every cell has the same area, so the sum over cells is C_t x cells +
     * C_i x references, from two counts that are exact: one expression
     * instead of a serial sum over every cell (about 4 ms of each build of
     * bmw-m6's 3 million, whatever the thread count), rounded a few times
     * rather than once per cell. */
    const uint64_t refs = off[cells] - off[0];
    if (st) {
        for (uint64_t c = 0; c < cells; ++c) {
            const uint32_t k = off[c + 1] - off[c];
            if (k == 0) continue;
            st->leaf_count++;
            st->leaf_size_histogram[k < AS_HISTOGRAM_BINS ? k : AS_HISTOGRAM_BINS - 1]++;
        }
        st->depth_histogram[0] = st->leaf_count; /* every cell is at depth 0 */
        memcpy(st->grid_dims, g->dims, sizeof st->grid_dims);
    }
    return ct + (ct * (double)cells + ci * (double)refs) * rel;
}

static void grid_stats(const as_structure_t *s, as_structure_stats_t *st)
{
    st->node_count = 0;
    st->max_depth = 0;
    st->average_leaf_depth = 0.0;
    st->sah_cost = as_grid_sah_cost(s, st);
}

static void grid_trace_cpu(const as_structure_t *s, const as_ray_t *rays, as_hit_t *hits, size_t count, int any_hit,
                           int ray_flags, as_cpu_stats_t *stats)
{
    const as_section_t *hs = as_structure_find(s, ASF_TAG_GRDH), *cs = as_structure_find(s, ASF_TAG_GRDC),
                       *ps = as_structure_find(s, ASF_TAG_PRIM), *ts = as_structure_find(s, ASF_TAG_TRIS);
    AS_TRACE_CPU_LOOP(hs->count == 1 && cs->count > 1,
                      as_grid_trace(hs->data, cs->data, ps->data, ts->data, &pre, any_hit, &h, ctrp));
}

const as_layout_ops_t as_layout_grid = {
    .structure_kind = AS_STRUCT_GRID,
    .layout = AS_LAYOUT_GRID,
    .layout_version = AS_GRID_LAYOUT_VERSION,
    .kind_name = "grid",
    .layout_name = "grid",
    .section_count = 4,
    .sections = {
        {ASF_TAG_GRDH, sizeof(as_grid_header_t), "grid box, dimensions and cell size, read by the traversal"},
        {ASF_TAG_GRDC, sizeof(uint32_t), "per-cell offsets into PRIM (cells + 1), read by the traversal"},
        {ASF_TAG_PRIM, sizeof(uint32_t), "cell triangle lists (source indices into TRIS), read by the traversal"},
        {ASF_TAG_TRIS, sizeof(as_tri4_t), "triangle vertices in source order, read by the traversal"},
    },
    .validate = as_grid_validate,
    .stats = grid_stats,
    .trace_cpu = grid_trace_cpu,
#ifdef AS_HAVE_CUDA
    .trace_gpu = as_layout_trace_gpu,
    .validate_gpu = as_grid_validate_gpu,
#endif
};
