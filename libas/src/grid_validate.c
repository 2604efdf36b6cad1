/* Structural validation of the grid layout: everything the traversal relies
 * on. The header must describe a finite box with 1..AS_GRID_MAX_CELLS cells
 * whose cell size and inverse agree with dims / extent (zero only on a flat
 * axis with one cell), GRDC must hold cells + 1 non-decreasing offsets
 * ending at PRIM's size, and every referenced triangle must lie in the grid
 * box. A DDA over such a grid moves one cell per step toward a wall and
 * stays inside the dims, so it cannot read out of bounds or loop. */
#include "spatial_common.h"
#include "grid_layout.h"
#include "trace_gpu.h"

#include <math.h>
#include <string.h>

as_error_t as_grid_validate(const as_structure_t *s, const char *name)
{
    const as_section_t *hs = as_structure_find(s, ASF_TAG_GRDH), *cs = as_structure_find(s, ASF_TAG_GRDC),
                       *ps = as_structure_find(s, ASF_TAG_PRIM), *ts = as_structure_find(s, ASF_TAG_TRIS);
    if (!hs || !cs || !ps || !ts)
        return as_set_error(AS_ERROR_INVALID_STRUCTURE, "%s: GRDH, GRDC, PRIM or TRIS section missing", name);
    as_error_t err = as_spatial_validate_tris(s, name, ts, ps);
    if (err != AS_OK) return err;
    if (hs->count != 1) return as_set_error(AS_ERROR_INVALID_STRUCTURE, "%s: GRDH holds %llu records, expected 1", name, (unsigned long long)hs->count);
    const as_grid_header_t *g = hs->data;
    if (g->reserved != 0) return as_set_error(AS_ERROR_INVALID_STRUCTURE, "%s: GRDH reserved field is not zero", name);
    uint64_t cells = 1;
    for (int k = 0; k < 3; ++k) {
        if (!isfinite(g->lo[k]) || !isfinite(g->hi[k]) || !(g->lo[k] <= g->hi[k]) || !isfinite(g->cell[k]) ||
            !isfinite(g->inv_cell[k]) || !(g->cell[k] >= 0.0f) || !(g->inv_cell[k] >= 0.0f))
            return as_set_error(AS_ERROR_INVALID_STRUCTURE, "%s: GRDH axis %d: box, cell size or inverse not finite and ordered", name, k);
        if (g->dims[k] == 0 || g->dims[k] > AS_GRID_MAX_CELLS)
            return as_set_error(AS_ERROR_INVALID_STRUCTURE, "%s: GRDH axis %d has %u cells", name, k, g->dims[k]);
        if ((g->cell[k] == 0.0f) != (g->inv_cell[k] == 0.0f) || (g->cell[k] == 0.0f && g->dims[k] != 1))
            return as_set_error(AS_ERROR_INVALID_STRUCTURE, "%s: GRDH axis %d: a zero cell size needs a zero inverse and one cell", name, k);
        if (g->cell[k] > 0.0f) {
            const double ext = (double)g->hi[k] - g->lo[k];
            if (fabs((double)g->cell[k] * g->dims[k] - ext) > 1e-4 * ext ||
                fabs((double)g->inv_cell[k] * ext - g->dims[k]) > 1e-4 * g->dims[k])
                return as_set_error(AS_ERROR_INVALID_STRUCTURE, "%s: GRDH axis %d: cell size and inverse disagree with %u cells over the box", name, k, g->dims[k]);
        }
        cells *= g->dims[k];
    }
    if (cells > AS_GRID_MAX_CELLS)
        return as_set_error(AS_ERROR_INVALID_STRUCTURE, "%s: %llu cells exceed the limit %u", name, (unsigned long long)cells, AS_GRID_MAX_CELLS);
    if (cs->count != cells + 1)
        return as_set_error(AS_ERROR_INVALID_STRUCTURE, "%s: GRDC holds %llu offsets, expected %llu (cells + 1)", name,
                            (unsigned long long)cs->count, (unsigned long long)(cells + 1));
    const uint32_t *off = cs->data;
    if (off[0] != 0 || off[cells] != ps->count)
        return as_set_error(AS_ERROR_INVALID_STRUCTURE, "%s: GRDC runs from %u to %u, expected 0 to %llu (PRIM entries)", name, off[0],
                            off[cells], (unsigned long long)ps->count);
    uint64_t nonempty = 0;
    for (uint64_t c = 0; c < cells; ++c) {
        if (off[c + 1] < off[c])
            return as_set_error(AS_ERROR_INVALID_STRUCTURE, "%s: GRDC offset of cell %llu decreases", name, (unsigned long long)c);
        nonempty += off[c + 1] > off[c];
    }
    const uint32_t *prims = ps->data;
    const as_tri4_t *tris = ts->data;
    for (uint64_t j = 0; j < ps->count; ++j) {
        const as_tri4_t *t = &tris[prims[j]];
        const float *v[3] = {&t->v0.x, &t->v1.x, &t->v2.x};
        for (int a = 0; a < 3; ++a)
            for (int k = 0; k < 3; ++k)
                if (v[a][k] < g->lo[k] || v[a][k] > g->hi[k])
                    return as_set_error(AS_ERROR_INVALID_STRUCTURE, "%s: triangle %u (PRIM entry %llu) lies outside the grid box",
                                        name, prims[j], (unsigned long long)j);
    }
    if (s->meta.leaf_count != nonempty || s->meta.empty_leaf_count != cells - nonempty ||
        s->meta.reference_count != ps->count || s->meta.node_count != 0)
        return as_set_error(AS_ERROR_INVALID_STRUCTURE,
                            "%s: META says %llu non-empty and %llu empty cells, %llu references, %llu nodes; the grid has %llu, %llu, %llu, 0",
                            name, (unsigned long long)s->meta.leaf_count, (unsigned long long)s->meta.empty_leaf_count,
                            (unsigned long long)s->meta.reference_count, (unsigned long long)s->meta.node_count,
                            (unsigned long long)nonempty, (unsigned long long)(cells - nonempty), (unsigned long long)ps->count);
    return AS_OK;
}

#ifdef AS_HAVE_CUDA
as_error_t as_grid_validate_gpu(const as_structure_t *s, const char *name)
{
    return as_spatial_validate_gpu(s, name, ASF_TAG_GRDH, ASF_TAG_GRDC, as_gpu_validate_grid);
}
#endif
