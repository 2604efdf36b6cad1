/* The uniform grid layout (sections GRDH and GRDC): the structs the builder
 * writes, the file stores, and the CPU and GPU traversals read. */
#ifndef AS_GRID_LAYOUT_H
#define AS_GRID_LAYOUT_H

#include "as_kernel_common.h"

/* 64 bytes, one record, 4-byte aligned; read by both.
 * Cell (x, y, z) covers [lo + i cell, lo + (i + 1) cell] on each axis and
 * is cell number (z dims[1] + y) dims[0] + x. inv_cell = dims / extent, or
 * 0 on an axis of zero extent (a flat scene: dims 1 there, cell 0). */
typedef struct as_grid_header {
    float lo[3];
    float hi[3];
    float cell[3];
    float inv_cell[3];
    uint32_t dims[3];
    uint32_t reserved;       /* zero */
} as_grid_header_t;

#ifndef __CUDACC__
_Static_assert(sizeof(as_grid_header_t) == 64, "as_grid_header_t is 64 bytes");
#else
static_assert(sizeof(as_grid_header_t) == 64, "as_grid_header_t is 64 bytes");
#endif

/* GRDC: uint32 per cell plus one; cell c's triangles are PRIM entries
 * [GRDC[c], GRDC[c + 1]). */

/* At most 2^26 cells (256 MiB of offsets): the builder lowers the
 * resolution beyond. */
#define AS_GRID_MAX_CELLS (1u << 26)
#define AS_GRID_LAYOUT_VERSION 1

#endif
