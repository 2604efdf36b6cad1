// Structural validation of the uniform grid layout on the GPU, after the
// upload and before any traversal kernel reads it: the checks of
// as_grid_validate (libas/src/grid_validate.c). The header (one record) is
// read back and checked on the host; the offsets, PRIM entries and
// triangles get one thread each.
#include "grid_layout.h"
#include "validate_gpu_common.cuh"

#include <cmath>

namespace {

enum check : unsigned {
    OFFSET_DECREASES = GV_LAYOUT_CHECKS,
    TRI_OUTSIDE,
};

// gv_scratch counts.
enum { NONEMPTY };

// Offsets never decrease; non-empty cells counted for META.
__global__ void check_cells(const unsigned *off, unsigned long long cells, gv_scratch *s)
{
    const unsigned long long c = gv_thread_index();
    if (c >= cells) return;
    const unsigned a = off[c], b = off[c + 1];
    if (b < a) gv_fail(s, OFFSET_DECREASES, c);
    gv_count(s, NONEMPTY, b > a);
}

// Every referenced triangle inside the grid box; one thread per PRIM entry.
__global__ void check_box(const unsigned *prim, unsigned long long prim_count, const as_tri4_t *tris,
                          unsigned long long tri_count, as_grid_header_t h, gv_scratch *s)
{
    const unsigned long long j = gv_thread_index();
    if (j >= prim_count) return;
    const unsigned t = prim[j];
    if (t >= tri_count) return; // gv_check_prim's failure
    if (!gv_tri_within(tris[t], h.lo, h.hi)) gv_fail(s, TRI_OUTSIDE, j);
}

as_error_t report(const char *name, unsigned long long key, const as_gpu_spatial_expect_t *e, const unsigned *prim)
{
    const unsigned long long index = key >> 8;
    switch ((unsigned)(key & 0xff)) {
    case OFFSET_DECREASES:
        return as_set_error(AS_ERROR_INVALID_STRUCTURE, "%s: GRDC offset of cell %llu decreases", name, index);
    case TRI_OUTSIDE:
        return as_set_error(AS_ERROR_INVALID_STRUCTURE, "%s: triangle %u (PRIM entry %llu) lies outside the grid box",
                            name, gv_prim_at(prim, index), index);
    default:
        return gv_report_shared(name, key, e->tri_count, e->meta.mesh_triangles);
    }
}

// The header checks of as_grid_validate, on the record the kernels read.
as_error_t check_header(const char *name, const as_grid_header_t *g, unsigned long long *cells_out)
{
    if (g->reserved != 0) return as_set_error(AS_ERROR_INVALID_STRUCTURE, "%s: GRDH reserved field is not zero", name);
    unsigned long long cells = 1;
    for (int k = 0; k < 3; ++k) {
        if (!std::isfinite(g->lo[k]) || !std::isfinite(g->hi[k]) || !(g->lo[k] <= g->hi[k]) ||
            !std::isfinite(g->cell[k]) || !std::isfinite(g->inv_cell[k]) || !(g->cell[k] >= 0.0f) ||
            !(g->inv_cell[k] >= 0.0f))
            return as_set_error(AS_ERROR_INVALID_STRUCTURE,
                                "%s: GRDH axis %d: box, cell size or inverse not finite and ordered", name, k);
        if (g->dims[k] == 0 || g->dims[k] > AS_GRID_MAX_CELLS)
            return as_set_error(AS_ERROR_INVALID_STRUCTURE, "%s: GRDH axis %d has %u cells", name, k, g->dims[k]);
        if ((g->cell[k] == 0.0f) != (g->inv_cell[k] == 0.0f) || (g->cell[k] == 0.0f && g->dims[k] != 1))
            return as_set_error(AS_ERROR_INVALID_STRUCTURE,
                                "%s: GRDH axis %d: a zero cell size needs a zero inverse and one cell", name, k);
        if (g->cell[k] > 0.0f) {
            const double ext = (double)g->hi[k] - g->lo[k];
            if (std::fabs((double)g->cell[k] * g->dims[k] - ext) > 1e-4 * ext ||
                std::fabs((double)g->inv_cell[k] * ext - g->dims[k]) > 1e-4 * g->dims[k])
                return as_set_error(AS_ERROR_INVALID_STRUCTURE,
                                    "%s: GRDH axis %d: cell size and inverse disagree with %u cells over the box", name,
                                    k, g->dims[k]);
        }
        cells *= g->dims[k];
    }
    if (cells > AS_GRID_MAX_CELLS)
        return as_set_error(AS_ERROR_INVALID_STRUCTURE, "%s: %llu cells exceed the limit %u", name, cells,
                            AS_GRID_MAX_CELLS);
    *cells_out = cells;
    return AS_OK;
}

} // namespace

extern "C" as_error_t as_gpu_validate_grid(const as_gpu_resident_t *g, const char *name,
                                           const as_gpu_spatial_expect_t *e)
{
    const unsigned long long np = e->prim_count, nt = e->tri_count;
    if (nt != e->meta.mesh_triangles)
        return as_set_error(AS_ERROR_INVALID_STRUCTURE, "%s: TRIS holds %llu triangles but META says the mesh has %u",
                            name, nt, e->meta.mesh_triangles);
    if (e->header_count != 1)
        return as_set_error(AS_ERROR_INVALID_STRUCTURE, "%s: GRDH holds %llu records, expected 1", name,
                            (unsigned long long)e->header_count);
    as_grid_header_t h;
    cudaError_t ce = cudaMemcpy(&h, g->device[0], sizeof h, cudaMemcpyDeviceToHost);
    if (ce != cudaSuccess) return gv_cuda_failed(name, ce);
    unsigned long long cells = 0;
    as_error_t err = check_header(name, &h, &cells);
    if (err != AS_OK) return err;
    if (e->node_count != cells + 1)
        return as_set_error(AS_ERROR_INVALID_STRUCTURE, "%s: GRDC holds %llu offsets, expected %llu (cells + 1)", name,
                            (unsigned long long)e->node_count, cells + 1);
    const unsigned *off = static_cast<const unsigned *>(g->device[1]);
    const unsigned *prim = static_cast<const unsigned *>(g->device[2]);
    const as_tri4_t *tris = static_cast<const as_tri4_t *>(g->device[3]);
    unsigned ends[2] = {0, 0};
    ce = cudaMemcpy(&ends[0], off, sizeof ends[0], cudaMemcpyDeviceToHost);
    if (ce == cudaSuccess) ce = cudaMemcpy(&ends[1], off + cells, sizeof ends[1], cudaMemcpyDeviceToHost);
    if (ce != cudaSuccess) return gv_cuda_failed(name, ce);
    if (ends[0] != 0 || ends[1] != np)
        return as_set_error(AS_ERROR_INVALID_STRUCTURE, "%s: GRDC runs from %u to %u, expected 0 to %llu (PRIM entries)",
                            name, ends[0], ends[1], np);
    gv_memory mem;
    gv_scratch *d_s = gv_new_scratch(mem);
    gv_scratch h_s;
    if (!d_s) return gv_no_memory(name, mem.error());
    if (nt) gv_check_tris<<<gv_blocks(nt), 256>>>(tris, nt, d_s);
    if (np) gv_check_prim<<<gv_blocks(np), 256>>>(prim, np, nt, d_s);
    check_cells<<<gv_blocks(cells), 256>>>(off, cells, d_s);
    if (np) check_box<<<gv_blocks(np), 256>>>(prim, np, tris, nt, h, d_s);
    ce = gv_read(d_s, &h_s);
    if (ce != cudaSuccess) return gv_cuda_failed(name, ce);
    if (h_s.first_failure != GV_NO_FAILURE) return report(name, h_s.first_failure, e, prim);
    const unsigned long long nonempty = h_s.count[NONEMPTY];
    if (e->meta.leaf_count != nonempty || e->meta.empty_leaf_count != cells - nonempty ||
        e->meta.reference_count != np || e->meta.node_count != 0)
        return as_set_error(AS_ERROR_INVALID_STRUCTURE,
                            "%s: META says %llu non-empty and %llu empty cells, %llu references, %llu nodes; the grid "
                            "has %llu, %llu, %llu, 0",
                            name, (unsigned long long)e->meta.leaf_count, (unsigned long long)e->meta.empty_leaf_count,
                            (unsigned long long)e->meta.reference_count, (unsigned long long)e->meta.node_count,
                            nonempty, cells - nonempty, np);
    return AS_OK;
}
