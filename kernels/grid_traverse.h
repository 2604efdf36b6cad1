/* 3D-DDA traversal of the uniform grid (Amanatides & Woo 1987, "A fast voxel
 * traversal algorithm for ray tracing"), written once for the CPU and the
 * GPU.
 *
 * Setup: the ray is clipped to the grid box with the robust slab test; the
 * entry point gives the first cell, its index clamped into the grid (the
 * rounded entry point may fall a hair outside). Stepping: tMax[k] is the
 * distance to the next cell wall on axis k, recomputed from the wall's
 * coordinate (lo + i cell) at every step instead of accumulated with
 * tDelta, so that no error builds up over long walks; a zero direction
 * component (+0 after as_ray_prepare, whichever sign it had) never steps:
 * its tMax is +inf. A triangle may be referenced by several cells, so a hit
 * is final only when its t is within the current cell's exit distance. */
#ifndef AS_GRID_TRAVERSE_H
#define AS_GRID_TRAVERSE_H

#include "grid_layout.h"
#include "indexed_leaf.h"

/* Distance to the wall a cell is left through on one axis. */
AS_HD float as_grid_wall_t(const as_grid_header_t *g, int k, int32_t cell, int step, float o, float inv)
{
    if (step == 0) return as_inf();
    const int32_t wall = step > 0 ? cell + 1 : cell;
    const float c = wall >= (int32_t)g->dims[k] ? g->hi[k] : AS_ADD(g->lo[k], AS_MUL((float)wall, g->cell[k]));
    return AS_MUL(AS_SUB(c, o), inv);
}

/* Traces one prepared ray through the grid. */
AS_HD void as_grid_trace(const as_grid_header_t *AS_RESTRICT g, const uint32_t *AS_RESTRICT offsets,
                         const uint32_t *AS_RESTRICT prims, const as_tri4_t *AS_RESTRICT tris,
                         const as_ray_pre_t *r, int any_hit, as_hit_rec_t *hit, as_trace_counters_t *ctr)
{
    as_hit_rec_miss(hit);
    float t_enter;
    if (!as_ray_box(r, g->lo[0], g->hi[0], g->lo[1], g->hi[1], g->lo[2], g->hi[2], r->tmax, &t_enter)) return;
    const float org[3] = {r->ox, r->oy, r->oz}, dir[3] = {r->dx, r->dy, r->dz};
    const float inv[3] = {r->ix, r->iy, r->iz};
    /* The far end of the box (NaN terms dropped, as in as_ray_box). */
    float t_exit = r->tmax;
    for (int k = 0; k < 3; ++k) {
        const float far_plane = inv[k] >= 0.0f ? g->hi[k] : g->lo[k];
        t_exit = AS_MINF(t_exit, AS_MUL(AS_SUB(far_plane, org[k]), inv[k]));
    }
    int32_t cell[3], step[3];
    float tmax_axis[3];
    for (int k = 0; k < 3; ++k) {
        const float p = AS_ADD(org[k], AS_MUL(t_enter, dir[k]));
        float f = AS_MUL(AS_SUB(p, g->lo[k]), g->inv_cell[k]);
        int32_t i = f >= 0.0f ? (f < (float)g->dims[k] ? (int32_t)f : (int32_t)g->dims[k] - 1) : 0;
        cell[k] = i;
        step[k] = dir[k] > 0.0f ? 1 : (dir[k] < 0.0f ? -1 : 0);
        tmax_axis[k] = as_grid_wall_t(g, k, i, step[k], org[k], inv[k]);
    }
    const uint32_t dx = g->dims[0], dy = g->dims[1];
    for (;;) {
        const uint32_t c = ((uint32_t)cell[2] * dy + (uint32_t)cell[1]) * dx + (uint32_t)cell[0];
        const float cell_exit = AS_MINF(AS_MINF(tmax_axis[0], tmax_axis[1]), AS_MINF(tmax_axis[2], t_exit));
        if (ctr) ctr->node_visits++;
        const uint32_t first = as_load_u32(offsets + c), end = as_load_u32(offsets + c + 1);
        if (end > first) {
            if (as_indexed_leaf(r, tris, prims, first, end - first, any_hit, hit, ctr)) return;
            if (hit->t <= cell_exit) return;
        }
        /* Next cell: across the nearest wall (ties: x, then y, then z). */
        const int k = tmax_axis[0] <= tmax_axis[1] ? (tmax_axis[0] <= tmax_axis[2] ? 0 : 2)
                                                  : (tmax_axis[1] <= tmax_axis[2] ? 1 : 2);
        if (!(tmax_axis[k] <= t_exit * AS_BOX_FAR_SCALE) || tmax_axis[k] > hit->t) return;
        cell[k] += step[k];
        if (cell[k] < 0 || cell[k] >= (int32_t)g->dims[k]) return;
        tmax_axis[k] = as_grid_wall_t(g, k, cell[k], step[k], org[k], inv[k]);
    }
}

#endif
