/* A PLY file walked as the format defines it, header and body, before
 * OpenMesh's reader sees it.
 *
 * That reader trusts what it reads. Its header parser loops forever on an
 * unreadable number; in the body it reads a face's corner count and pushes
 * that many corners whether or not the stream still has them (a count of
 * 2,000,000,000 from a vertex line one number too long allocates gigabytes);
 * and it reads any list other than a face's vertex indices as one value, in
 * ASCII and binary alike, so every element after such a list is misread. So
 * every header line, every count and every number of the body is checked
 * here, and what the reader would misread is refused with the line or
 * offset that holds it. */
#include "as_internal.h"
#include "mesh_import_shims.h"

#include <errno.h>
#include <float.h>
#include <limits.h>
#include <stdint.h>
#include <stdlib.h>
#include <string.h>

#define PLY_MAX_ELEMENTS 32
#define PLY_MAX_PROPERTIES 64
#define PLY_MAX_WORDS 8

typedef enum { PLY_INT, PLY_UINT, PLY_FLOAT } ply_kind_t;

typedef struct {
    const char *name;
    ply_kind_t kind;
    unsigned size;
} ply_type_t;

/* The scalar types of the format, under both spellings, and only those:
 * OpenMesh's reader takes an unknown type for another one. */
static const ply_type_t ply_types[] = {
    {"char", PLY_INT, 1},    {"uchar", PLY_UINT, 1},   {"short", PLY_INT, 2},
    {"ushort", PLY_UINT, 2}, {"int", PLY_INT, 4},      {"uint", PLY_UINT, 4},
    {"float", PLY_FLOAT, 4}, {"double", PLY_FLOAT, 8}, {"int8", PLY_INT, 1},
    {"uint8", PLY_UINT, 1},  {"int16", PLY_INT, 2},    {"uint16", PLY_UINT, 2},
    {"int32", PLY_INT, 4},   {"uint32", PLY_UINT, 4},  {"float32", PLY_FLOAT, 4},
    {"float64", PLY_FLOAT, 8},
};

typedef struct {
    char name[48];
    const ply_type_t *type;
    const ply_type_t *count_type; /* NULL: not a list */
} ply_property_t;

typedef struct {
    char name[48];
    unsigned long long count;
    int property_count;
    ply_property_t properties[PLY_MAX_PROPERTIES];
} ply_element_t;

typedef struct {
    const char *data;
    size_t size, pos;
    unsigned line;
    const char *name;
    int format; /* 0 ASCII, 1 binary little-endian, 2 binary big-endian */
    int element_count;
    ply_element_t elements[PLY_MAX_ELEMENTS];
} ply_check_t;

typedef struct {
    const char *start;
    size_t len;
} ply_word_t;

static int is_space(char c) { return c == ' ' || c == '\t' || c == '\r' || c == '\f' || c == '\v'; }

static int word_is(ply_word_t w, const char *s)
{
    return w.len == strlen(s) && memcmp(w.start, s, w.len) == 0;
}

static const ply_type_t *find_type(ply_word_t w)
{
    for (size_t i = 0; i < sizeof ply_types / sizeof ply_types[0]; ++i)
        if (word_is(w, ply_types[i].name)) return &ply_types[i];
    return NULL;
}

/* Splits the next header line into words, keeping the first PLY_MAX_WORDS
 * (a comment may hold any number). Returns how many there are, or -1 at the
 * end of the data. */
static int next_header_line(ply_check_t *c, ply_word_t *words)
{
    if (c->pos >= c->size) return -1;
    const char *nl = memchr(c->data + c->pos, '\n', c->size - c->pos);
    const size_t end = nl ? (size_t)(nl - c->data) : c->size;
    int n = 0;
    for (size_t p = c->pos; p < end;) {
        while (p < end && is_space(c->data[p])) ++p;
        size_t q = p;
        while (q < end && !is_space(c->data[q])) ++q;
        if (q > p) {
            if (n < PLY_MAX_WORDS) {
                words[n].start = c->data + p;
                words[n].len = q - p;
            }
            ++n;
        }
        p = q;
    }
    /* Past the newline; a last line without one ends at the end of the
     * data (the binary body's check counts what is left from here). */
    c->pos = nl ? end + 1 : c->size;
    ++c->line;
    return n;
}

/* A whole word as an unsigned decimal count, at most `max`. */
static int parse_count(ply_word_t w, unsigned long long max, unsigned long long *out)
{
    if (w.len == 0 || w.len > 20) return 0;
    unsigned long long v = 0;
    for (size_t i = 0; i < w.len; ++i) {
        const char ch = w.start[i];
        if (ch < '0' || ch > '9') return 0;
        if (v > (ULLONG_MAX - (unsigned)(ch - '0')) / 10) return 0;
        v = v * 10 + (unsigned)(ch - '0');
    }
    if (v > max) return 0;
    *out = v;
    return 1;
}

static as_error_t header_error(const ply_check_t *c, const char *what)
{
    return as_set_error(AS_ERROR_PARSE, "%s: line %u: %s", c->name, c->line, what);
}

static as_error_t read_header(ply_check_t *c)
{
    ply_word_t w[PLY_MAX_WORDS];
    int n = next_header_line(c, w);
    if (n != 1 || !(word_is(w[0], "ply") || word_is(w[0], "PLY")))
        return as_set_error(AS_ERROR_PARSE, "%s: line 1: not a PLY file (no 'ply' line)", c->name);
    int format_seen = 0, vertex_seen = 0, face_seen = 0;
    for (;;) {
        n = next_header_line(c, w);
        if (n < 0) return header_error(c, "the header has no 'end_header' line");
        if (n == 0) return header_error(c, "an empty header line");
        if (word_is(w[0], "comment") || word_is(w[0], "obj_info")) continue;
        if (n > PLY_MAX_WORDS) return header_error(c, "a header line with too many words");
        if (word_is(w[0], "end_header")) {
            if (n != 1) return header_error(c, "words after 'end_header'");
            break;
        }
        if (word_is(w[0], "format")) {
            /* One format line, of a known kind: with two, the reader and
             * this check could read the body differently. */
            if (format_seen) return header_error(c, "a second 'format' line");
            if (n != 3) return header_error(c, "'format' takes a kind and a version");
            if (word_is(w[1], "ascii")) c->format = 0;
            else if (word_is(w[1], "binary_little_endian")) c->format = 1;
            else if (word_is(w[1], "binary_big_endian")) c->format = 2;
            else return header_error(c, "unknown format (ascii, binary_little_endian or binary_big_endian)");
            char version[32];
            char *after;
            if (w[2].len >= sizeof version) return header_error(c, "the version is not a number");
            memcpy(version, w[2].start, w[2].len);
            version[w[2].len] = '\0';
            strtod(version, &after);
            if (after == version || *after != '\0') return header_error(c, "the version is not a number");
            format_seen = 1;
        } else if (word_is(w[0], "element")) {
            unsigned long long count;
            if (n != 3) return header_error(c, "'element' takes a name and a count");
            if (!parse_count(w[2], UINT32_MAX, &count))
                return header_error(c, "the element count is not a number below 2^32");
            if (w[1].len >= sizeof c->elements[0].name) return header_error(c, "an element name too long");
            if (c->element_count == PLY_MAX_ELEMENTS) return header_error(c, "too many elements");
            const int is_vertex = word_is(w[1], "vertex"), is_face = word_is(w[1], "face");
            if ((is_vertex && vertex_seen) || (is_face && face_seen))
                return header_error(c, "a second 'vertex' or 'face' element");
            vertex_seen |= is_vertex;
            face_seen |= is_face;
            ply_element_t *e = &c->elements[c->element_count++];
            memcpy(e->name, w[1].start, w[1].len);
            e->name[w[1].len] = '\0';
            e->count = count;
            e->property_count = 0;
        } else if (word_is(w[0], "property")) {
            if (c->element_count == 0) return header_error(c, "a property before any element");
            ply_element_t *e = &c->elements[c->element_count - 1];
            const int list = n > 1 && word_is(w[1], "list");
            if (n != (list ? 5 : 3))
                return header_error(c, list ? "'property list' takes a count type, a value type and a name"
                                            : "'property' takes a type and a name");
            const ply_type_t *type = find_type(w[list ? 3 : 1]);
            const ply_type_t *count_type = list ? find_type(w[2]) : NULL;
            if (!type || (list && !count_type)) return header_error(c, "unknown property type");
            if (count_type && count_type->kind == PLY_FLOAT)
                return header_error(c, "a list count type must be an integer type");
            const ply_word_t pname = w[n - 1];
            if (list) {
                /* The one list the reader takes: a face's corners. */
                const int corners = strcmp(e->name, "face") == 0 &&
                                    (word_is(pname, "vertex_indices") || word_is(pname, "vertex_index"));
                for (int i = 0; i < e->property_count; ++i)
                    if (e->properties[i].count_type)
                        return header_error(c, "a second list property in an element (only a face's "
                                               "vertex_indices may be a list)");
                if (!corners)
                    return header_error(c, "a list property other than a face's vertex_indices "
                                           "(which is the only list this reader takes)");
            }
            if (pname.len >= sizeof e->properties[0].name) return header_error(c, "a property name too long");
            if (e->property_count == PLY_MAX_PROPERTIES) return header_error(c, "too many properties");
            ply_property_t *p = &e->properties[e->property_count++];
            memcpy(p->name, pname.start, pname.len);
            p->name[pname.len] = '\0';
            p->type = type;
            p->count_type = count_type;
        } else {
            return header_error(c, "unknown header keyword");
        }
    }
    if (!format_seen) return as_set_error(AS_ERROR_PARSE, "%s: the header has no 'format' line", c->name);
    return AS_OK;
}

/* ---- ASCII body ---------------------------------------------------------- */

/* The next blank-separated word of the body, counting lines. */
static int next_token(ply_check_t *c, ply_word_t *w)
{
    while (c->pos < c->size && (is_space(c->data[c->pos]) || c->data[c->pos] == '\n')) {
        if (c->data[c->pos] == '\n') ++c->line;
        ++c->pos;
    }
    if (c->pos >= c->size) return 0;
    const size_t start = c->pos;
    while (c->pos < c->size && !is_space(c->data[c->pos]) && c->data[c->pos] != '\n') ++c->pos;
    w->start = c->data + start;
    w->len = c->pos - start;
    return 1;
}

/* Whether a word is, as a whole, a number of the type, in its range: the
 * reader's operator>> stops inside "2-3" or "0x10" and fails on "nan", on
 * "inf" and on a float above FLT_MAX, after which it would read on with
 * values it never set. */
static int token_fits(ply_word_t w, const ply_type_t *t, long long *int_value)
{
    char buf[64];
    if (w.len == 0 || w.len >= sizeof buf) return 0;
    memcpy(buf, w.start, w.len);
    buf[w.len] = '\0';
    size_t i = (buf[0] == '+' || buf[0] == '-') ? 1 : 0;
    if (t->kind != PLY_FLOAT) {
        if (buf[i] == '\0') return 0;
        for (size_t k = i; buf[k]; ++k)
            if (buf[k] < '0' || buf[k] > '9') return 0;
        errno = 0;
        const long long v = strtoll(buf, NULL, 10);
        if (errno == ERANGE) return 0;
        const unsigned bits = 8 * t->size;
        const long long lo = t->kind == PLY_UINT ? 0 : -(1ll << (bits - 1));
        const long long hi = t->kind == PLY_UINT ? (long long)((1ull << bits) - 1) : (1ll << (bits - 1)) - 1;
        if (v < lo || v > hi) return 0;
        if (int_value) *int_value = v;
        return 1;
    }
    /* digits [. digits] [e [sign] digits], with a digit before or after the point */
    size_t k = i, digits = 0;
    while (buf[k] >= '0' && buf[k] <= '9') ++k, ++digits;
    if (buf[k] == '.') {
        ++k;
        while (buf[k] >= '0' && buf[k] <= '9') ++k, ++digits;
    }
    if (digits == 0) return 0;
    if (buf[k] == 'e' || buf[k] == 'E') {
        ++k;
        if (buf[k] == '+' || buf[k] == '-') ++k;
        if (buf[k] < '0' || buf[k] > '9') return 0;
        while (buf[k] >= '0' && buf[k] <= '9') ++k;
    }
    if (buf[k] != '\0') return 0;
    const double v = strtod(buf, NULL);
    return v >= -FLT_MAX && v <= FLT_MAX;
}

static as_error_t body_ends(const ply_check_t *c, const ply_element_t *e, unsigned long long i)
{
    return as_set_error(AS_ERROR_PARSE, "%s: the data ends in %s %llu of %llu", c->name, e->name, i + 1,
                        e->count);
}

static as_error_t check_ascii_body(ply_check_t *c)
{
    ply_word_t w;
    for (int ei = 0; ei < c->element_count; ++ei) {
        const ply_element_t *e = &c->elements[ei];
        for (unsigned long long i = 0; i < e->count; ++i) {
            for (int pi = 0; pi < e->property_count; ++pi) {
                const ply_property_t *p = &e->properties[pi];
                long long values = 1;
                if (p->count_type) {
                    if (!next_token(c, &w)) return body_ends(c, e, i);
                    if (!token_fits(w, p->count_type, &values) || values < 0)
                        return as_set_error(AS_ERROR_PARSE,
                                            "%s: line %u: '%.*s' is not a %s list count (%s %llu, %s)",
                                            c->name, c->line, (int)(w.len > 32 ? 32 : w.len), w.start,
                                            p->count_type->name, e->name, i, p->name);
                }
                for (long long k = 0; k < values; ++k) {
                    if (!next_token(c, &w)) return body_ends(c, e, i);
                    if (!token_fits(w, p->type, NULL))
                        return as_set_error(AS_ERROR_PARSE,
                                            "%s: line %u: '%.*s' is not a %s (%s %llu, %s)", c->name,
                                            c->line, (int)(w.len > 32 ? 32 : w.len), w.start,
                                            p->type->name, e->name, i, p->name);
                }
            }
        }
    }
    if (next_token(c, &w))
        return as_set_error(AS_ERROR_PARSE, "%s: line %u: data after the last %s", c->name, c->line,
                            c->element_count ? c->elements[c->element_count - 1].name : "header line");
    return AS_OK;
}

/* ---- binary body --------------------------------------------------------- */

static long long read_binary_count(const unsigned char *p, const ply_type_t *t, int big_endian)
{
    uint64_t u = 0;
    for (unsigned b = 0; b < t->size; ++b)
        u |= (uint64_t)p[big_endian ? t->size - 1 - b : b] << (8 * b);
    if (t->kind == PLY_INT && (u >> (8 * t->size - 1)) & 1) return -1; /* negative */
    return (long long)u;
}

static as_error_t check_binary_body(ply_check_t *c)
{
    const unsigned char *data = (const unsigned char *)c->data;
    size_t at = c->pos;
    for (int ei = 0; ei < c->element_count; ++ei) {
        const ply_element_t *e = &c->elements[ei];
        size_t fixed = 0; /* bytes per element without lists */
        int has_list = 0;
        for (int pi = 0; pi < e->property_count; ++pi) {
            if (e->properties[pi].count_type) has_list = 1;
            else fixed += e->properties[pi].type->size;
        }
        if (!has_list) {
            if (fixed && e->count > (c->size - at) / fixed)
                return body_ends(c, e, (c->size - at) / fixed);
            at += fixed * e->count;
            continue;
        }
        for (unsigned long long i = 0; i < e->count; ++i) {
            for (int pi = 0; pi < e->property_count; ++pi) {
                const ply_property_t *p = &e->properties[pi];
                if (!p->count_type) {
                    if (c->size - at < p->type->size) return body_ends(c, e, i);
                    at += p->type->size;
                    continue;
                }
                if (c->size - at < p->count_type->size) return body_ends(c, e, i);
                const long long values = read_binary_count(data + at, p->count_type, c->format == 2);
                if (values < 0)
                    return as_set_error(AS_ERROR_PARSE, "%s: offset %zu: a negative list count (%s %llu, %s)",
                                        c->name, at, e->name, i, p->name);
                at += p->count_type->size;
                if ((unsigned long long)values > (c->size - at) / p->type->size) return body_ends(c, e, i);
                at += (size_t)values * p->type->size;
            }
        }
    }
    if (at != c->size)
        return as_set_error(AS_ERROR_PARSE, "%s: offset %zu: %zu bytes after the last %s", c->name, at,
                            c->size - at,
                            c->element_count ? c->elements[c->element_count - 1].name : "header line");
    return AS_OK;
}

as_error_t as_mesh_check_ply(const void *data, size_t size, const char *name)
{
    ply_check_t *c = calloc(1, sizeof *c);
    if (!c) return as_set_error(AS_ERROR_OUT_OF_MEMORY, "%s: out of memory while reading", name);
    c->data = data;
    c->size = size;
    c->name = name;
    as_error_t err = read_header(c);
    if (err == AS_OK && c->format == 0) {
        ++c->line; /* the body's first line */
        err = check_ascii_body(c);
    } else if (err == AS_OK) {
        err = check_binary_body(c);
    }
    free(c);
    return err;
}
