/* Shading of primary hits and an 8-bit RGB PNG writer (zlib for IDAT). */
#define _POSIX_C_SOURCE 200809L
#include "structure.h"
#include "bvh2_layout.h"
#include "atomic_file.h"

#include <math.h>
#include <stdlib.h>
#include <string.h>
#include <zlib.h>

static void put_u32be(uint8_t *p, uint32_t v)
{
    p[0] = (uint8_t)(v >> 24); p[1] = (uint8_t)(v >> 16); p[2] = (uint8_t)(v >> 8); p[3] = (uint8_t)v;
}

/* Appends one chunk (length, type, data, CRC over type and data). */
static uint8_t *png_chunk(uint8_t *out, const char type[4], const uint8_t *data, uint32_t len)
{
    put_u32be(out, len);
    memcpy(out + 4, type, 4);
    if (len) memcpy(out + 8, data, len);
    uLong crc = crc32(0L, Z_NULL, 0);
    crc = crc32(crc, out + 4, 4 + len);
    put_u32be(out + 8 + len, (uint32_t)crc);
    return out + 12 + len;
}

/* Encodes rows of 8-bit RGB (each row led by its filter byte, 0) as a PNG
 * and writes it atomically. */
static as_error_t write_png_rows(const char *path, uint32_t width, uint32_t height, const uint8_t *raw)
{
    const size_t row = 1 + 3 * (size_t)width;
    const uLong bound = compressBound((uLong)(row * height));
    uint8_t *z = as_malloc(bound, "compressed image");
    uint8_t *file = as_malloc(bound + 128, "PNG file");
    as_error_t err = AS_OK;
    if (!z || !file) { err = as_get_error(); goto done; }
    uLongf zlen = bound;
    if (compress2(z, &zlen, raw, (uLong)(row * height), 6) != Z_OK) {
        err = as_set_error(AS_ERROR_UNKNOWN, "%s: zlib could not compress the image", path);
        goto done;
    }
    uint8_t *o = file;
    memcpy(o, "\x89PNG\r\n\x1a\n", 8);
    o += 8;
    uint8_t ihdr[13];
    put_u32be(ihdr, width);
    put_u32be(ihdr + 4, height);
    ihdr[8] = 8;  /* bits per channel */
    ihdr[9] = 2;  /* RGB */
    ihdr[10] = ihdr[11] = ihdr[12] = 0;
    o = png_chunk(o, "IHDR", ihdr, 13);
    o = png_chunk(o, "IDAT", z, (uint32_t)zlen);
    o = png_chunk(o, "IEND", NULL, 0);
    const as_file_part_t part = {file, (size_t)(o - file)};
    err = as_atomic_write(path, &part, 1);
done:
    free(z);
    free(file);
    return err;
}

as_error_t as_image_write_png_grey(const char *path, uint32_t width, uint32_t height, const float *values)
{
    if (!path || !values || !width || !height)
        return as_set_error(AS_ERROR_INVALID_ARGUMENT, "as_image_write_png_grey: bad argument");
    const size_t row = 1 + 3 * (size_t)width;
    uint8_t *raw = as_malloc(row * height, "image rows");
    if (!raw) return as_get_error();
    for (uint32_t y = 0; y < height; ++y) {
        uint8_t *p = raw + row * y;
        *p++ = 0;
        for (uint32_t x = 0; x < width; ++x, p += 3) {
            const float v = values[(size_t)y * width + x];
            if (v < 0.0f) { p[0] = 20; p[1] = 24; p[2] = 48; continue; }
            const uint8_t g = (uint8_t)(255.0f * (v > 1.0f ? 1.0f : v) + 0.5f);
            p[0] = p[1] = p[2] = g;
        }
    }
    const as_error_t err = write_png_rows(path, width, height, raw);
    free(raw);
    return err;
}

as_error_t as_image_write_png(const as_structure_t *s, const as_ray_t *rays, const as_hit_t *hits,
                              uint32_t width, uint32_t height, const char *path)
{
    if (!s || !rays || !hits || !path || !width || !height)
        return as_set_error(AS_ERROR_INVALID_ARGUMENT, "as_image_write_png: bad argument");
    const as_tri4_t **where = as_structure_triangles_by_prim(s);
    const uint32_t nsrc = s->meta.triangle_count;
    const size_t row = 1 + 3 * (size_t)width;
    uint8_t *raw = as_malloc(row * height, "image rows");
    as_error_t err = AS_OK;
    if (!where || !raw) { err = as_get_error(); goto done; }
    for (uint32_t y = 0; y < height; ++y) {
        uint8_t *p = raw + row * y;
        *p++ = 0; /* filter: none */
        for (uint32_t x = 0; x < width; ++x, p += 3) {
            const size_t i = (size_t)y * width + x;
            const as_hit_t *h = &hits[i];
            if (h->prim == AS_NO_HIT || h->prim >= nsrc || !where[h->prim]) {
                p[0] = 20; p[1] = 24; p[2] = 48;
                continue;
            }
            const as_tri4_t *t = where[h->prim];
            const float e1[3] = {t->v1.x - t->v0.x, t->v1.y - t->v0.y, t->v1.z - t->v0.z};
            const float e2[3] = {t->v2.x - t->v0.x, t->v2.y - t->v0.y, t->v2.z - t->v0.z};
            float n[3] = {e1[1] * e2[2] - e1[2] * e2[1], e1[2] * e2[0] - e1[0] * e2[2], e1[0] * e2[1] - e1[1] * e2[0]};
            const float nl = sqrtf(n[0] * n[0] + n[1] * n[1] + n[2] * n[2]);
            const float *d = rays[i].dir;
            const float dl = sqrtf(d[0] * d[0] + d[1] * d[1] + d[2] * d[2]);
            float c = nl > 0 && dl > 0 ? fabsf(n[0] * d[0] + n[1] * d[1] + n[2] * d[2]) / (nl * dl) : 0.0f;
            const uint8_t g = (uint8_t)(30.0f + 225.0f * c);
            p[0] = g; p[1] = g; p[2] = g;
        }
    }
    err = write_png_rows(path, width, height, raw);
done:
    free((void *)where);
    free(raw);
    return err;
}

/* Viridis (van der Walt and Smith, matplotlib 2.0) at nine evenly spaced
 * points: perceptually uniform and readable in grey and by colour-blind
 * readers, so equal steps of work look like equal steps of colour. */
static const uint8_t viridis[9][3] = {
    {68, 1, 84},    {72, 40, 120},  {62, 73, 137},  {49, 104, 142}, {38, 130, 142},
    {31, 158, 137}, {53, 183, 121}, {110, 206, 88}, {253, 231, 37},
};

static int cmp_u32(const void *a, const void *b)
{
    const uint32_t x = *(const uint32_t *)a, y = *(const uint32_t *)b;
    return x < y ? -1 : x > y;
}

as_error_t as_image_write_png_heat(const char *path, uint32_t width, uint32_t height, const uint32_t *steps,
                                   uint32_t scale_max, uint32_t *scale_used)
{
    if (!path || !steps || !width || !height)
        return as_set_error(AS_ERROR_INVALID_ARGUMENT, "as_image_write_png_heat: bad argument");
    const size_t n = (size_t)width * height;
    uint32_t scale = scale_max;
    if (!scale) {
        /* The 99th percentile rather than the maximum: a few rays grazing a
         * dense corner would otherwise crush the rest of the image into the
         * bottom of the ramp. */
        uint32_t *sorted = as_malloc(n * sizeof *sorted, "heat map percentile");
        if (!sorted) return as_get_error();
        memcpy(sorted, steps, n * sizeof *sorted);
        qsort(sorted, n, sizeof *sorted, cmp_u32);
        const size_t rank = (size_t)ceil(0.99 * (double)n);
        scale = sorted[rank > 0 ? rank - 1 : 0];
        free(sorted);
        if (!scale) scale = 1;
    }
    const size_t row = 1 + 3 * (size_t)width;
    uint8_t *raw = as_malloc(row * height, "image rows");
    if (!raw) return as_get_error();
    for (uint32_t y = 0; y < height; ++y) {
        uint8_t *p = raw + row * y;
        *p++ = 0;
        for (uint32_t x = 0; x < width; ++x, p += 3) {
            const uint32_t v = steps[(size_t)y * width + x];
            const double f = 8.0 * (v < scale ? (double)v / scale : 1.0);
            const int k = f >= 8.0 ? 7 : (int)f;
            const double w = f - k;
            for (int c = 0; c < 3; ++c)
                p[c] = (uint8_t)((1.0 - w) * viridis[k][c] + w * viridis[k + 1][c] + 0.5);
        }
    }
    const as_error_t err = write_png_rows(path, width, height, raw);
    free(raw);
    if (err == AS_OK && scale_used) *scale_used = scale;
    return err;
}
