/* Fuzzes the mesh importers through as_mesh_import, the wrapper every tool
 * uses: OBJ, PLY and OFF through OpenMesh's parsers, STL through our own
 * reader, Draco .drc through Draco's decoder, each optionally as NAME.EXT.zst.
 *
 * Asserts, through ASan and UBSan (the Debian builds of OpenMesh and Draco
 * are not instrumented, so faults inside them show only as crashes): no
 * input makes the import read outside its buffers, overflow or leak; a
 * refused file sets an error whose message names it; an accepted mesh has
 * triangles, every index below the vertex count, finite positions, the
 * positions its triangles use inside the bounds its info reports, at least
 * one triangle per face of the file, and attribute arrays as long as it
 * says.
 *
 * The importer picks the format by the file's extension, so the first byte
 * of the input names it and the rest is written to a file of that name:
 *   bits 0-2  0 .obj, 1 .ply, 2 .off, 3 .stl, 4 .drc (5-7 wrap around);
 *   bit 3     NAME.EXT.zst: the rest is zstd-compressed. */
#define _POSIX_C_SOURCE 200809L
#include "as/as.h"

#include <math.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <unistd.h>

int LLVMFuzzerTestOneInput(const uint8_t *data, size_t size);

static char dir[64];
static char paths[10][96];

static void fail(const char *path, const char *what)
{
    fprintf(stderr, "fuzz_mesh_import: %s: %s (%s)\n", path, what, as_get_error_message());
    abort();
}

static void remove_files(void)
{
    for (int i = 0; i < 10; ++i)
        if (paths[i][0]) unlink(paths[i]);
    if (dir[0]) rmdir(dir);
}

/* One private directory per process, with one file name per format. */
static const char *path_for(uint8_t params)
{
    static const char *const ext[5] = {"obj", "ply", "off", "stl", "drc"};
    if (!dir[0]) {
        const char *tmp = getenv("TMPDIR");
        snprintf(dir, sizeof dir, "%s/as_fuzz_mesh.XXXXXX", tmp && *tmp && strlen(tmp) < 32 ? tmp : "/tmp");
        if (!mkdtemp(dir)) {
            perror(dir);
            abort();
        }
        atexit(remove_files);
    }
    const int format = (params & 7) % 5, zst = (params & 8) != 0;
    char *p = paths[format + 5 * zst];
    snprintf(p, sizeof paths[0], "%s/mesh.%s%s", dir, ext[format], zst ? ".zst" : "");
    return p;
}

int LLVMFuzzerTestOneInput(const uint8_t *data, size_t size)
{
    if (size < 1) return 0;
    const char *path = path_for(data[0]);
    FILE *f = fopen(path, "wb");
    if (!f) fail(path, "cannot write the input");
    if (size > 1 && fwrite(data + 1, 1, size - 1, f) != size - 1) fail(path, "cannot write the input");
    if (fclose(f) != 0) fail(path, "cannot write the input");

    as_clear_error();
    as_mesh_t *mesh = as_mesh_import(path);
    if (!mesh) {
        if (as_get_error() == AS_OK) fail(path, "refusal without an error code");
        if (!strstr(as_get_error_message(), path)) fail(path, "the message does not name the file");
        return 0;
    }
    as_mesh_info_t info;
    as_mesh_get_info(mesh, &info);
    if (info.vertex_count == 0 || info.triangle_count == 0) fail(path, "an empty mesh was accepted");
    const float *pos = as_mesh_positions(mesh);
    const uint32_t *idx = as_mesh_indices(mesh);
    if (!pos || !idx) fail(path, "no positions or indices");
    for (uint64_t v = 0; v < info.vertex_count; ++v)
        for (int k = 0; k < 3; ++k)
            if (!isfinite(pos[3 * v + k])) fail(path, "a position that is not finite");
    /* The bounds are those of the vertices the triangles use: a stray
     * vertex may lie outside. */
    for (uint64_t i = 0; i < 3ull * info.triangle_count; ++i) {
        if (idx[i] >= info.vertex_count) fail(path, "an index past the vertices");
        for (int k = 0; k < 3; ++k) {
            const float x = pos[3ull * idx[i] + k];
            if (x < info.bounds_lo[k] || x > info.bounds_hi[k]) fail(path, "a used position outside the bounds");
        }
    }
    /* A face of k corners gives k - 2 >= 1 triangles. */
    if (info.faces_in_file > info.triangle_count) fail(path, "fewer triangles than faces");
    /* The attribute arrays are as long as the mesh says: ASan checks the
     * last element of each. */
    uint32_t last[3] = {0, 0, 0};
    const uint32_t *materials = as_mesh_material_ids(mesh);
    const float *normals = as_mesh_normals(mesh), *uvs = as_mesh_uvs(mesh);
    if (materials) last[0] = materials[info.triangle_count - 1];
    if (normals) memcpy(&last[1], &normals[3ull * info.vertex_count - 1], sizeof last[1]);
    if (uvs) memcpy(&last[2], &uvs[2ull * info.vertex_count - 1], sizeof last[2]);
    volatile uint32_t sink = last[0] ^ last[1] ^ last[2];
    (void)sink;
    as_mesh_release(mesh);
    return 0;
}
