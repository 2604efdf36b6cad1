/* as_mesh_import: reads the file, undoes zstd, picks the reader by extension.
 *
 * Every reader works from memory, so NAME.EXT.zst and NAME.EXT take the same
 * path once decompressed. OBJ, PLY and OFF go through OpenMesh's parsers and
 * .drc through Draco (mesh_import_openmesh.cpp, mesh_import_draco.cpp). STL is
 * read here: OpenMesh's STL reader skips facets whose corners coincide, and a
 * ray tracer must keep every facet at its index; the format is simple enough
 * that our own reader is shorter than working around theirs.
 */
#define _POSIX_C_SOURCE 200809L

#include "as_internal.h"
#include "mesh.h"
#include "mesh_import_shims.h"

#include <ctype.h>
#include <errno.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/stat.h>

#include <zstd.h>

static const char known_formats[] = ".obj .ply .off .stl .drc, optionally .zst";

static int ext_is(const char *ext, size_t len, const char *want)
{
    if (len != strlen(want)) return 0;
    for (size_t i = 0; i < len; ++i)
        if (tolower((unsigned char)ext[i]) != want[i]) return 0;
    return 1;
}

static as_error_t read_file(const char *path, unsigned char **out, size_t *size)
{
    *out = NULL;
    *size = 0;
    struct stat st;
    if (stat(path, &st) != 0) {
        if (errno == ENOENT || errno == ENOTDIR)
            return as_set_error(AS_ERROR_FILE_NOT_FOUND, "%s: no such file", path);
        return as_set_error(AS_ERROR_IO, "%s: %s", path, strerror(errno));
    }
    if (S_ISDIR(st.st_mode)) return as_set_error(AS_ERROR_IO, "%s: is a directory", path);
    FILE *f = fopen(path, "rb");
    if (!f) return as_set_error(AS_ERROR_IO, "%s: cannot open: %s", path, strerror(errno));
    size_t cap = st.st_size > 0 ? (size_t)st.st_size : 4096;
    unsigned char *buf = as_malloc(cap + 1, path);
    size_t n = 0;
    if (!buf) {
        fclose(f);
        return AS_ERROR_OUT_OF_MEMORY;
    }
    /* Read to the end rather than trusting st_size (pipes, growing files). */
    for (;;) {
        if (n == cap) {
            unsigned char *bigger = realloc(buf, cap * 2 + 1);
            if (!bigger) {
                free(buf);
                fclose(f);
                return as_set_error(AS_ERROR_OUT_OF_MEMORY, "%s: out of memory", path);
            }
            buf = bigger;
            cap *= 2;
        }
        const size_t got = fread(buf + n, 1, cap - n, f);
        n += got;
        if (got == 0) break;
    }
    const int failed = ferror(f);
    fclose(f);
    if (failed) {
        free(buf);
        return as_set_error(AS_ERROR_IO, "%s: read failed", path);
    }
    buf[n] = '\0';
    *out = buf;
    *size = n;
    return AS_OK;
}

/* Streaming, so frames without a content size (zstd -c from a pipe) work,
 * and concatenated frames too. */
static as_error_t zstd_decompress(const unsigned char *src, size_t src_size, const char *path,
                                  unsigned char **out, size_t *out_size)
{
    *out = NULL;
    *out_size = 0;
    const unsigned long long content = ZSTD_getFrameContentSize(src, src_size);
    size_t cap = src_size * 4 + 4096;
    /* A stated size is only a hint: a damaged or hostile header must not
     * make us allocate gigabytes up front. */
    if (content != ZSTD_CONTENTSIZE_UNKNOWN && content != ZSTD_CONTENTSIZE_ERROR &&
        content < ((size_t)1 << 30))
        cap = (size_t)content + 1;
    ZSTD_DStream *ds = ZSTD_createDStream();
    unsigned char *buf = as_malloc(cap + 1, path);
    if (!ds || !buf) {
        ZSTD_freeDStream(ds);
        free(buf);
        return as_set_error(AS_ERROR_OUT_OF_MEMORY, "%s: out of memory", path);
    }
    ZSTD_inBuffer in = {src, src_size, 0};
    ZSTD_outBuffer ob = {buf, cap, 0};
    size_t last = 1;
    for (;;) {
        if (ob.pos == ob.size) {
            unsigned char *bigger = realloc(buf, cap * 2 + 1);
            if (!bigger) {
                ZSTD_freeDStream(ds);
                free(buf);
                return as_set_error(AS_ERROR_OUT_OF_MEMORY, "%s: out of memory", path);
            }
            buf = bigger;
            cap *= 2;
            ob.dst = buf;
            ob.size = cap;
        }
        last = ZSTD_decompressStream(ds, &ob, &in);
        if (ZSTD_isError(last)) {
            const char *why = ZSTD_getErrorName(last);
            ZSTD_freeDStream(ds);
            free(buf);
            return as_set_error(AS_ERROR_PARSE, "%s: damaged zstd data (%s)", path, why);
        }
        /* All input consumed and room left over: nothing more will come. */
        if (in.pos == in.size && ob.pos < ob.size) break;
    }
    ZSTD_freeDStream(ds);
    if (last != 0 || src_size == 0) {
        free(buf);
        return as_set_error(AS_ERROR_PARSE, "%s: damaged zstd data (truncated frame)", path);
    }
    buf[ob.pos] = '\0';
    *out = buf;
    *out_size = ob.pos;
    return AS_OK;
}

/* ------------------------------------------------------------------------ */
/* STL. Every corner becomes its own vertex: facets share nothing in the
 * format, and merging equal positions would gain memory but nothing a ray
 * tracer needs. */

typedef struct stl_builder {
    float *pos;          /* 3 per corner */
    size_t corners, cap; /* in corners */
    uint32_t *face_end;  /* corner count after each facet */
    size_t faces, face_cap;
} stl_builder_t;

static int stl_push_corner(stl_builder_t *b, const float v[3])
{
    if (b->corners == b->cap) {
        const size_t cap = b->cap ? b->cap * 2 : 3 * 1024;
        float *p = realloc(b->pos, cap * 3 * sizeof(float));
        if (!p) return 0;
        b->pos = p;
        b->cap = cap;
    }
    memcpy(b->pos + b->corners * 3, v, 3 * sizeof(float));
    ++b->corners;
    return 1;
}

static int stl_end_face(stl_builder_t *b)
{
    if (b->faces == b->face_cap) {
        const size_t cap = b->face_cap ? b->face_cap * 2 : 1024;
        uint32_t *p = realloc(b->face_end, cap * sizeof(uint32_t));
        if (!p) return 0;
        b->face_end = p;
        b->face_cap = cap;
    }
    b->face_end[b->faces++] = (uint32_t)b->corners;
    return 1;
}

static float le_float(const unsigned char *p)
{
    const uint32_t u = (uint32_t)p[0] | (uint32_t)p[1] << 8 | (uint32_t)p[2] << 16 |
                       (uint32_t)p[3] << 24;
    float f;
    memcpy(&f, &u, sizeof f);
    return f;
}

static as_error_t stl_read_binary(const unsigned char *data, size_t count, const char *name,
                                  stl_builder_t *b)
{
    for (size_t t = 0; t < count; ++t) {
        /* 12 bytes of facet normal, 3 corners of 12 bytes, 2 attribute bytes. */
        const unsigned char *rec = data + 84 + t * 50 + 12;
        for (int c = 0; c < 3; ++c) {
            const float v[3] = {le_float(rec + c * 12), le_float(rec + c * 12 + 4),
                                le_float(rec + c * 12 + 8)};
            if (!stl_push_corner(b, v)) return as_set_error(AS_ERROR_OUT_OF_MEMORY, "%s: out of memory", name);
        }
        if (!stl_end_face(b)) return as_set_error(AS_ERROR_OUT_OF_MEMORY, "%s: out of memory", name);
    }
    return AS_OK;
}

/* The keywords that matter are "facet", "vertex" and "endfacet"; the rest
 * ("solid", "normal", "outer loop", ...) carry nothing we keep. The buffer
 * ends with a NUL (read_file and zstd_decompress add one). */
static as_error_t stl_read_ascii(const char *text, size_t size, const char *name,
                                 stl_builder_t *b)
{
    const char *p = text, *end = text + size;
    unsigned line = 1;
    int in_facet = 0;
    size_t facet_start = 0;
    while (p < end) {
        while (p < end && isspace((unsigned char)*p)) line += *p++ == '\n';
        const char *word = p;
        while (p < end && !isspace((unsigned char)*p)) ++p;
        const size_t len = (size_t)(p - word);
        if (len == 0) break;
        if (len == 5 && memcmp(word, "facet", 5) == 0) {
            in_facet = 1;
            facet_start = b->corners;
        } else if (len == 6 && memcmp(word, "vertex", 6) == 0) {
            float v[3];
            for (int k = 0; k < 3; ++k) {
                char *after;
                v[k] = strtof(p, &after);
                if (after == p || !in_facet)
                    return as_set_error(AS_ERROR_PARSE, "%s: line %u: cannot parse as STL", name, line);
                p = after;
            }
            if (!stl_push_corner(b, v)) return as_set_error(AS_ERROR_OUT_OF_MEMORY, "%s: out of memory", name);
        } else if (len == 8 && memcmp(word, "endfacet", 8) == 0) {
            if (!in_facet)
                return as_set_error(AS_ERROR_PARSE, "%s: line %u: cannot parse as STL", name, line);
            if (b->corners - facet_start < 3)
                return as_set_error(AS_ERROR_INVALID_MESH,
                                    "%s: face %zu (line %u) has %zu corners (a face needs at least 3)",
                                    name, b->faces, line, b->corners - facet_start);
            if (!stl_end_face(b)) return as_set_error(AS_ERROR_OUT_OF_MEMORY, "%s: out of memory", name);
            in_facet = 0;
        }
    }
    if (in_facet)
        return as_set_error(AS_ERROR_PARSE, "%s: cannot parse as STL (ends inside facet %zu)",
                            name, b->faces);
    return AS_OK;
}

static as_error_t read_stl(const unsigned char *data, size_t size, const char *name,
                           as_mesh_t *mesh)
{
    stl_builder_t b = {0};
    as_error_t err;
    /* Binary when the size matches the triangle count: some exporters start
     * binary headers with "solid" too, so the word alone does not decide. */
    const size_t count = size >= 84 ? (size_t)data[80] | (size_t)data[81] << 8 |
                                          (size_t)data[82] << 16 | (size_t)data[83] << 24
                                    : 0;
    const char *s = (const char *)data;
    while (s < (const char *)data + size && isspace((unsigned char)*s)) ++s;
    const int ascii = (size_t)((const char *)data + size - s) >= 5 && memcmp(s, "solid", 5) == 0;
    if (size >= 84 && (uint64_t)count * 50 + 84 == size)
        err = stl_read_binary(data, count, name, &b);
    else if (ascii)
        err = stl_read_ascii((const char *)data, size, name, &b);
    else
        err = as_set_error(AS_ERROR_PARSE,
                           "%s: cannot parse as STL (neither ASCII nor a binary STL of its size)",
                           name);
    if (err == AS_OK && b.corners > UINT32_MAX)
        err = as_set_error(AS_ERROR_UNSUPPORTED, "%s: too many triangles", name);

    uint64_t triangles = 0;
    uint32_t polygons = 0;
    for (size_t f = 0; err == AS_OK && f < b.faces; ++f) {
        const uint32_t k = b.face_end[f] - (f ? b.face_end[f - 1] : 0);
        triangles += k - 2;
        polygons += k > 3;
    }
    if (err == AS_OK) {
        mesh->indices = as_malloc(triangles * 3 * sizeof(uint32_t) + 1, "STL indices");
        if (!mesh->indices) err = AS_ERROR_OUT_OF_MEMORY;
    }
    if (err != AS_OK) {
        free(b.pos);
        free(b.face_end);
        return err;
    }
    uint32_t *tri = mesh->indices;
    for (size_t f = 0; f < b.faces; ++f) {
        const uint32_t first = f ? b.face_end[f - 1] : 0;
        for (uint32_t c = first + 1; c + 1 < b.face_end[f]; ++c) {
            *tri++ = first;
            *tri++ = c;
            *tri++ = c + 1;
        }
    }
    mesh->positions = b.pos ? b.pos : malloc(1);
    mesh->vertex_count = (uint32_t)b.corners;
    mesh->triangle_count = (uint32_t)triangles;
    mesh->faces_in_file = b.faces;
    mesh->polygon_faces = polygons;
    free(b.face_end);
    return AS_OK;
}

/* ------------------------------------------------------------------------ */

as_mesh_t *as_mesh_import(const char *path)
{
    if (!path) {
        as_set_error(AS_ERROR_INVALID_ARGUMENT, "as_mesh_import: path is NULL");
        return NULL;
    }
    unsigned char *file = NULL;
    size_t file_size = 0;
    if (read_file(path, &file, &file_size) != AS_OK) return NULL;

    /* NAME.EXT or NAME.EXT.zst; the extension is looked for in the last
     * component only. */
    const char *base = strrchr(path, '/');
    base = base ? base + 1 : path;
    const char *dot = strrchr(base, '.');
    const char *ext = dot ? dot + 1 : base + strlen(base);
    size_t ext_len = strlen(ext);
    int compressed = 0;
    if (dot && ext_is(ext, ext_len, "zst")) {
        const char *inner = NULL;
        for (const char *q = base; q < dot; ++q)
            if (*q == '.') inner = q;
        if (inner) {
            compressed = 1;
            ext = inner + 1;
            ext_len = (size_t)(dot - ext);
        }
    }
    enum { FMT_NONE, FMT_OPENMESH, FMT_STL, FMT_DRACO } kind = FMT_NONE;
    const char *om_format = NULL;
    if (dot && ext_is(ext, ext_len, "obj")) kind = FMT_OPENMESH, om_format = "obj";
    else if (dot && ext_is(ext, ext_len, "ply")) kind = FMT_OPENMESH, om_format = "ply";
    else if (dot && ext_is(ext, ext_len, "off")) kind = FMT_OPENMESH, om_format = "off";
    else if (dot && ext_is(ext, ext_len, "stl")) kind = FMT_STL;
    else if (dot && ext_is(ext, ext_len, "drc")) kind = FMT_DRACO;
    if (kind == FMT_NONE) {
        free(file);
        as_set_error(AS_ERROR_UNSUPPORTED, "%s: unknown mesh format '%s%.*s' (known: %s)", path,
                     dot ? "." : "", (int)ext_len, ext, known_formats);
        return NULL;
    }

    unsigned char *data = file;
    size_t size = file_size;
    if (compressed) {
        const as_error_t err = zstd_decompress(file, file_size, path, &data, &size);
        free(file);
        if (err != AS_OK) return NULL;
    }

    as_mesh_t *mesh = as_calloc(1, sizeof *mesh, "mesh");
    as_error_t err = mesh ? AS_OK : AS_ERROR_OUT_OF_MEMORY;
    if (err == AS_OK) {
        switch (kind) {
        case FMT_OPENMESH:
            err = as_mesh_read_openmesh(data, size, om_format, path, compressed ? NULL : path, mesh);
            break;
        case FMT_STL: err = read_stl(data, size, path, mesh); break;
        case FMT_DRACO: err = as_mesh_read_draco(data, size, path, mesh); break;
        case FMT_NONE: break;
        }
    }
    free(data);
    if (err == AS_OK) err = as_mesh_finish(mesh, path);
    if (err != AS_OK) {
        as_mesh_release(mesh);
        return NULL;
    }
    return mesh;
}
