/* Whitted materials from an OBJ file's material libraries (.mtl).
 *
 * The .asf file keeps no materials, so they come from the mesh: the OBJ's
 * `usemtl` statements, which the importer has already turned into one
 * material id per triangle (1, 2, ... in order of each name's first
 * `usemtl`, 0 before any), and the `newmtl` blocks of the libraries its
 * `mtllib` statements name. The names are recovered here by scanning the
 * OBJ with the importer's own rules (a statement's keyword is its first
 * blank-separated word; the name is the rest of the line, trimmed), so id k
 * is the k-th distinct name met.
 *
 * Only what the Whitted rule needs is read from a library (newmtl, Ks,
 * illum, d, Tr, Ni); the rest is skipped. The libraries are opened here,
 * never by a third-party reader, and only beside the OBJ: OpenMesh's own
 * reader opens whatever `mtllib` names (docs/SECURITY.md). */
#define _POSIX_C_SOURCE 200809L
#include "as_internal.h"
#include "mesh.h"

#include <errno.h>
#include <fcntl.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/stat.h>
#include <unistd.h>

/* A library bigger than this is not a material file. */
#define MTL_MAX_BYTES ((size_t)64 << 20)
#define OBJ_MAX_BYTES ((size_t)1 << 34)

typedef struct mtl_entry {
    char *name;
    double ks[3];
    int illum;          /* -1: not given */
    double d;           /* dissolve, 1 opaque */
    double ni;          /* 0: not given */
} mtl_entry;

typedef struct mtl_set {
    mtl_entry *e;
    size_t n, cap;
} mtl_set;

static int is_blank(char c) { return c == ' ' || c == '\t' || c == '\r' || c == '\f' || c == '\v'; }

/* Reads a whole regular file. O_NONBLOCK so that opening a FIFO returns at
 * once instead of waiting for a writer; fstat on the open descriptor, so
 * the checked file is the one read. */
static as_error_t read_regular(const char *path, size_t limit, char **out, size_t *size)
{
    const int fd = open(path, O_RDONLY | O_NONBLOCK | O_CLOEXEC | O_NOCTTY);
    if (fd < 0) {
        if (errno == ENOENT || errno == ENOTDIR) return as_set_error(AS_ERROR_FILE_NOT_FOUND, "%s: no such file", path);
        return as_set_error(AS_ERROR_IO, "%s: cannot open: %s", path, strerror(errno));
    }
    struct stat st;
    if (fstat(fd, &st) != 0) {
        const int e = errno;
        close(fd);
        return as_set_error(AS_ERROR_IO, "%s: %s", path, strerror(e));
    }
    if (!S_ISREG(st.st_mode)) {
        close(fd);
        return as_set_error(AS_ERROR_IO, "%s: not a regular file (%s): refused", path,
                            S_ISDIR(st.st_mode) ? "a directory" : S_ISFIFO(st.st_mode) ? "a FIFO"
                            : S_ISCHR(st.st_mode) || S_ISBLK(st.st_mode) ? "a device" : "a special file");
    }
    if ((uint64_t)st.st_size > limit) {
        close(fd);
        return as_set_error(AS_ERROR_IO, "%s: %lld bytes, more than the %zu a material reader accepts", path,
                            (long long)st.st_size, limit);
    }
    const size_t n = (size_t)st.st_size;
    char *buf = as_malloc(n + 1, path);
    if (!buf) {
        close(fd);
        return as_get_error();
    }
    size_t got = 0;
    while (got < n) {
        const ssize_t r = read(fd, buf + got, n - got);
        if (r < 0 && errno == EINTR) continue;
        if (r <= 0) {
            const int e = r < 0 ? errno : 0;
            close(fd);
            free(buf);
            return as_set_error(AS_ERROR_IO, "%s: read failed%s%s", path, e ? ": " : "", e ? strerror(e) : "");
        }
        got += (size_t)r;
    }
    close(fd);
    buf[n] = '\0';
    *out = buf;
    *size = n;
    return AS_OK;
}

/* One line of a text: [*b, *e) is the line without its newline; returns the
 * start of the next line. */
static size_t next_line(const char *data, size_t size, size_t pos, size_t *b, size_t *e)
{
    const char *nl = memchr(data + pos, '\n', size - pos);
    const size_t end = nl ? (size_t)(nl - data) : size;
    *b = pos;
    *e = end;
    return end + 1;
}

/* The keyword of a line and the trimmed rest after it. */
static void split_statement(const char *data, size_t b, size_t e, size_t *kw, size_t *kw_len, size_t *rest,
                            size_t *rest_end)
{
    size_t p = b;
    while (p < e && is_blank(data[p])) ++p;
    size_t q = p;
    while (q < e && !is_blank(data[q])) ++q;
    *kw = p;
    *kw_len = q - p;
    while (q < e && is_blank(data[q])) ++q;
    size_t r = e;
    while (r > q && is_blank(data[r - 1])) --r;
    *rest = q;
    *rest_end = r;
}

static int keyword_is(const char *data, size_t kw, size_t len, const char *want)
{
    return len == strlen(want) && memcmp(data + kw, want, len) == 0;
}

/* Up to `max` numbers from [p, e); returns how many were read, -1 when a
 * word is not a number. */
static int parse_numbers(const char *data, size_t p, size_t e, double *out, int max)
{
    int n = 0;
    char word[64];
    while (p < e) {
        while (p < e && is_blank(data[p])) ++p;
        if (p >= e) break;
        size_t q = p;
        while (q < e && !is_blank(data[q])) ++q;
        if (n == max || q - p >= sizeof word) return -1;
        memcpy(word, data + p, q - p);
        word[q - p] = '\0';
        char *after;
        out[n] = strtod(word, &after);
        if (after == word || *after) return -1;
        ++n;
        p = q;
    }
    return n;
}

static mtl_entry *find_material(const mtl_set *set, const char *name, size_t len)
{
    for (size_t i = 0; i < set->n; ++i)
        if (strlen(set->e[i].name) == len && memcmp(set->e[i].name, name, len) == 0) return &set->e[i];
    return NULL;
}

static as_error_t parse_mtl(const char *path, const char *data, size_t size, mtl_set *set)
{
    mtl_entry *cur = NULL;
    unsigned line = 0;
    for (size_t pos = 0; pos < size;) {
        size_t b, e, kw, kl, r, re;
        pos = next_line(data, size, pos, &b, &e);
        ++line;
        split_statement(data, b, e, &kw, &kl, &r, &re);
        if (!kl || data[kw] == '#') continue;
        if (keyword_is(data, kw, kl, "newmtl")) {
            if (r == re) return as_set_error(AS_ERROR_PARSE, "%s: line %u: newmtl without a name", path, line);
            /* A name defined twice keeps its first definition, as the first
             * library named wins over later ones. */
            if (find_material(set, data + r, re - r)) { cur = NULL; continue; }
            if (set->n == set->cap) {
                const size_t cap = set->cap ? 2 * set->cap : 16;
                mtl_entry *bigger = realloc(set->e, cap * sizeof *bigger);
                if (!bigger) return as_set_error(AS_ERROR_OUT_OF_MEMORY, "%s: out of memory for materials", path);
                set->e = bigger;
                set->cap = cap;
            }
            cur = &set->e[set->n];
            memset(cur, 0, sizeof *cur);
            cur->name = as_malloc(re - r + 1, "material name");
            if (!cur->name) return as_get_error();
            memcpy(cur->name, data + r, re - r);
            cur->name[re - r] = '\0';
            cur->illum = -1;
            cur->d = 1.0;
            ++set->n;
            continue;
        }
        const int ks = keyword_is(data, kw, kl, "Ks"), illum = keyword_is(data, kw, kl, "illum"),
                  d = keyword_is(data, kw, kl, "d"), tr = keyword_is(data, kw, kl, "Tr"),
                  ni = keyword_is(data, kw, kl, "Ni");
        if (!ks && !illum && !d && !tr && !ni) continue;
        if (!cur && set->n == 0)
            return as_set_error(AS_ERROR_PARSE, "%s: line %u: %.*s before any newmtl", path, line, (int)kl, data + kw);
        if (!cur) continue; /* inside a repeated definition */
        double v[3];
        const int n = parse_numbers(data, r, re, v, 3);
        if (ks) {
            /* "Ks r [g b]": a single value is grey. */
            if (n != 1 && n != 3)
                return as_set_error(AS_ERROR_PARSE, "%s: line %u: Ks needs 1 or 3 numbers", path, line);
            for (int k = 0; k < 3; ++k) cur->ks[k] = v[n == 1 ? 0 : k];
        } else if (n != 1) {
            return as_set_error(AS_ERROR_PARSE, "%s: line %u: %.*s needs one number", path, line, (int)kl, data + kw);
        } else if (illum) {
            if (v[0] < 0 || v[0] > 10 || v[0] != (int)v[0])
                return as_set_error(AS_ERROR_PARSE, "%s: line %u: illum %g is not a model 0..10", path, line, v[0]);
            cur->illum = (int)v[0];
        } else if (d || tr) {
            if (!(v[0] >= 0 && v[0] <= 1))
                return as_set_error(AS_ERROR_PARSE, "%s: line %u: %s %g is outside 0..1", path, line, d ? "d" : "Tr", v[0]);
            cur->d = d ? v[0] : 1.0 - v[0];
        } else {
            if (!(v[0] > 0 && v[0] < 100))
                return as_set_error(AS_ERROR_PARSE, "%s: line %u: Ni %g is not an index of refraction", path, line, v[0]);
            cur->ni = v[0];
        }
    }
    return AS_OK;
}

static as_material_t classify(const mtl_entry *m)
{
    as_material_t out = {AS_MATERIAL_OPAQUE, 0.0f};
    const int il = m->illum;
    if (m->d < 1.0 || il == 4 || il == 6 || il == 7 || il == 9) {
        out.kind = AS_MATERIAL_GLASS;
        out.ior = (float)m->ni;
    } else if (il == 3 || il == 5 || (m->ks[0] >= 0.8 && m->ks[1] >= 0.8 && m->ks[2] >= 0.8)) {
        /* 0.8: exporters write Ks 0.5 for ordinary plastic highlights, which
         * are not mirrors. */
        out.kind = AS_MATERIAL_MIRROR;
    }
    return out;
}

/* Opens one library the OBJ names, relative to the OBJ's directory. */
static as_error_t read_library(const char *obj_path, unsigned line, const char *name, size_t len, mtl_set *set)
{
    if (len && name[0] == '/')
        return as_set_error(AS_ERROR_IO, "%s: line %u: mtllib '%.*s' is an absolute path: only libraries beside the "
                            "OBJ are read", obj_path, line, (int)len, name);
    for (size_t i = 0; i < len;) {
        size_t j = i;
        while (j < len && name[j] != '/') ++j;
        if (j - i == 2 && name[i] == '.' && name[i + 1] == '.')
            return as_set_error(AS_ERROR_IO, "%s: line %u: mtllib '%.*s' leaves the OBJ's directory: only libraries "
                                "beside the OBJ are read", obj_path, line, (int)len, name);
        i = j + 1;
    }
    const char *slash = strrchr(obj_path, '/');
    const size_t dir = slash ? (size_t)(slash - obj_path) + 1 : 0;
    char *path = as_malloc(dir + len + 1, "material library path");
    if (!path) return as_get_error();
    memcpy(path, obj_path, dir);
    memcpy(path + dir, name, len);
    path[dir + len] = '\0';
    char *data = NULL;
    size_t size = 0;
    as_error_t err = read_regular(path, MTL_MAX_BYTES, &data, &size);
    if (err != AS_OK) {
        /* Say which statement asked for it. */
        char msg[512];
        snprintf(msg, sizeof msg, "%s", as_get_error_message());
        err = as_set_error(err, "%s (mtllib on line %u of %s)", msg, line, obj_path);
    } else {
        err = parse_mtl(path, data, size, set);
    }
    free(data);
    free(path);
    return err;
}

as_error_t as_materials_read_obj(const char *obj_path, const as_mesh_t *mesh, as_material_t **out, uint32_t *count)
{
    if (!obj_path || !mesh || !out || !count)
        return as_set_error(AS_ERROR_INVALID_ARGUMENT, "as_materials_read_obj: NULL argument");
    *out = NULL;
    *count = 0;
    const size_t plen = strlen(obj_path);
    if (plen < 4 || strcmp(obj_path + plen - 4, ".obj") != 0)
        return as_set_error(AS_ERROR_UNSUPPORTED, "%s: materials are read from an uncompressed .obj file", obj_path);
    char *data = NULL;
    size_t size = 0;
    as_error_t err = read_regular(obj_path, OBJ_MAX_BYTES, &data, &size);
    if (err != AS_OK) return err;
    mtl_set set = {NULL, 0, 0};
    /* usemtl names by id - 1, and the line of each name's first use. */
    const mtl_entry **used = NULL;
    size_t used_n = 0, used_cap = 0;
    unsigned line = 0, first_usemtl_line = 0;
    int have_lib = 0;
    as_material_t *mats = NULL;
    /* The libraries first: a usemtl may come before the mtllib that
     * defines it. Names are checked in a second pass. */
    for (size_t pos = 0; pos < size && err == AS_OK;) {
        size_t b, e, kw, kl, r, re;
        pos = next_line(data, size, pos, &b, &e);
        ++line;
        split_statement(data, b, e, &kw, &kl, &r, &re);
        if (!keyword_is(data, kw, kl, "mtllib")) continue;
        if (r == re) { err = as_set_error(AS_ERROR_PARSE, "%s: line %u: mtllib without a file name", obj_path, line); break; }
        have_lib = 1;
        for (size_t p = r; p < re && err == AS_OK;) {
            size_t q = p;
            while (q < re && !is_blank(data[q])) ++q;
            err = read_library(obj_path, line, data + p, q - p, &set);
            while (q < re && is_blank(data[q])) ++q;
            p = q;
        }
    }
    line = 0;
    for (size_t pos = 0; pos < size && err == AS_OK;) {
        size_t b, e, kw, kl, r, re;
        pos = next_line(data, size, pos, &b, &e);
        ++line;
        split_statement(data, b, e, &kw, &kl, &r, &re);
        if (!keyword_is(data, kw, kl, "usemtl")) continue;
        if (!first_usemtl_line) first_usemtl_line = line;
        int seen = 0;
        for (size_t i = 0; i < used_n && !seen; ++i)
            seen = strlen(used[i]->name) == re - r && memcmp(used[i]->name, data + r, re - r) == 0;
        if (seen) continue;
        const mtl_entry *m = find_material(&set, data + r, re - r);
        if (!m) {
            err = have_lib ? as_set_error(AS_ERROR_PARSE, "%s: line %u: usemtl '%.*s': no material of that name in the "
                                          "libraries the file names", obj_path, line, (int)(re - r), data + r)
                           : as_set_error(AS_ERROR_PARSE, "%s: line %u: usemtl '%.*s' but the file names no material "
                                          "library (mtllib)", obj_path, line, (int)(re - r), data + r);
            break;
        }
        if (used_n == used_cap) {
            used_cap = used_cap ? 2 * used_cap : 16;
            const mtl_entry **bigger = realloc((void *)used, used_cap * sizeof *bigger);
            if (!bigger) { err = as_set_error(AS_ERROR_OUT_OF_MEMORY, "%s: out of memory", obj_path); break; }
            used = bigger;
        }
        used[used_n++] = m;
    }
    if (err == AS_OK && !have_lib)
        err = as_set_error(AS_ERROR_PARSE, "%s: names no material library (mtllib)", obj_path);
    const uint32_t tris = mesh->triangle_count;
    if (err == AS_OK && !(mats = as_malloc(((size_t)tris + 1) * sizeof *mats, "materials"))) err = as_get_error();
    for (uint32_t t = 0; err == AS_OK && t < tris; ++t) {
        const uint32_t id = mesh->material_ids ? mesh->material_ids[t] : 0;
        if (id > used_n) {
            err = as_set_error(AS_ERROR_INVALID_ARGUMENT, "%s: triangle %u has material %u but the file uses %zu: the "
                               "mesh was not imported from this file", obj_path, t, id, used_n);
            break;
        }
        mats[t] = id ? classify(used[id - 1]) : (as_material_t){AS_MATERIAL_OPAQUE, 0.0f};
    }
    if (err == AS_OK && !mesh->material_ids && used_n)
        err = as_set_error(AS_ERROR_INVALID_ARGUMENT, "%s: line %u: the file uses materials but the mesh has none: the "
                           "mesh was not imported from this file", obj_path, first_usemtl_line);
    for (size_t i = 0; i < set.n; ++i) free(set.e[i].name);
    free(set.e);
    free((void *)used);
    free(data);
    if (err != AS_OK) {
        free(mats);
        return err;
    }
    *out = mats;
    *count = tris;
    return AS_OK;
}
