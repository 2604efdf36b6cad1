/* Pinhole cameras: the default view of a box and one ray per pixel. */
#include "as_internal.h"

#include <errno.h>
#include <float.h>
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

static void normalize3(float v[3])
{
    const float l = sqrtf(v[0] * v[0] + v[1] * v[1] + v[2] * v[2]);
    if (l > 0) { v[0] /= l; v[1] /= l; v[2] /= l; }
}

static void cross3(const float a[3], const float b[3], float o[3])
{
    o[0] = a[1] * b[2] - a[2] * b[1];
    o[1] = a[2] * b[0] - a[0] * b[2];
    o[2] = a[0] * b[1] - a[1] * b[0];
}

void as_camera_default(const float lo[3], const float hi[3], as_camera_t *cam)
{
    const float c[3] = {0.5f * (lo[0] + hi[0]), 0.5f * (lo[1] + hi[1]), 0.5f * (lo[2] + hi[2])};
    const float dx = hi[0] - lo[0], dy = hi[1] - lo[1], dz = hi[2] - lo[2];
    const float radius = 0.5f * sqrtf(dx * dx + dy * dy + dz * dz);
    cam->fov_y_degrees = 45.0f;
    /* Far enough that the bounding sphere fits the vertical field of view. */
    const float dist = radius / sinf(0.5f * cam->fov_y_degrees * 3.14159265358979f / 180.0f);
    cam->target[0] = c[0]; cam->target[1] = c[1]; cam->target[2] = c[2];
    cam->eye[0] = c[0]; cam->eye[1] = c[1]; cam->eye[2] = c[2] + (dist > 0 ? dist : 1.0f);
    cam->up[0] = 0; cam->up[1] = 1; cam->up[2] = 0;
}

void as_camera_rays(const as_camera_t *cam, uint32_t width, uint32_t height, as_ray_t *rays)
{
    float f[3] = {cam->target[0] - cam->eye[0], cam->target[1] - cam->eye[1], cam->target[2] - cam->eye[2]};
    normalize3(f);
    float r[3], u[3];
    cross3(f, cam->up, r);
    normalize3(r);
    cross3(r, f, u);
    const float th = tanf(0.5f * cam->fov_y_degrees * 3.14159265358979f / 180.0f);
    const float aspect = (float)width / (float)height;
    for (uint32_t y = 0; y < height; ++y) {
        for (uint32_t x = 0; x < width; ++x) {
            const float px = (2.0f * ((float)x + 0.5f) / (float)width - 1.0f) * th * aspect;
            const float py = (1.0f - 2.0f * ((float)y + 0.5f) / (float)height) * th;
            as_ray_t *ray = &rays[(size_t)y * width + x];
            float d[3] = {f[0] + px * r[0] + py * u[0], f[1] + px * r[1] + py * u[1], f[2] + px * r[2] + py * u[2]};
            normalize3(d);
            ray->org[0] = cam->eye[0]; ray->org[1] = cam->eye[1]; ray->org[2] = cam->eye[2];
            ray->dir[0] = d[0]; ray->dir[1] = d[1]; ray->dir[2] = d[2];
            ray->tmin = 0.0f;
            ray->tmax = INFINITY;
        }
    }
}

/* Reads "KEY numbers" lines; `line` is NUL-terminated, without its newline. */
static int read_numbers(const char *s, float *out, int n)
{
    for (int i = 0; i < n; ++i) {
        char *after;
        const double v = strtod(s, &after);
        if (after == s || !isfinite(v) || fabs(v) > FLT_MAX) return 0;
        out[i] = (float)v;
        s = after;
    }
    while (*s == ' ' || *s == '\t' || *s == '\r') ++s;
    return *s == '\0';
}

as_error_t as_camera_read(const char *path, as_camera_t *cam)
{
    if (!path || !cam) return as_set_error(AS_ERROR_INVALID_ARGUMENT, "as_camera_read: NULL argument");
    FILE *f = fopen(path, "r");
    if (!f)
        return as_set_error(errno == ENOENT ? AS_ERROR_FILE_NOT_FOUND : AS_ERROR_IO, "%s: cannot open: %s", path,
                            strerror(errno));
    as_camera_t c = {{0, 0, 0}, {0, 0, 0}, {0, 1, 0}, 45.0f};
    int have_eye = 0, have_target = 0;
    char line[512];
    unsigned lineno = 0;
    as_error_t err = AS_OK;
    while (err == AS_OK && fgets(line, sizeof line, f)) {
        ++lineno;
        const size_t len = strlen(line);
        if (len == sizeof line - 1 && line[len - 1] != '\n' && !feof(f)) {
            err = as_set_error(AS_ERROR_PARSE, "%s: line %u: longer than %zu characters", path, lineno, sizeof line - 2);
            break;
        }
        line[strcspn(line, "\n")] = '\0';
        char *p = line;
        while (*p == ' ' || *p == '\t') ++p;
        if (*p == '\0' || *p == '#' || *p == '\r') continue;
        char *key = p;
        while (*p && *p != ' ' && *p != '\t') ++p;
        const size_t key_len = (size_t)(p - key);
        float *dst = NULL;
        int n = 3;
        if (key_len == 3 && strncmp(key, "eye", 3) == 0) dst = c.eye, have_eye = 1;
        else if (key_len == 6 && strncmp(key, "target", 6) == 0) dst = c.target, have_target = 1;
        else if (key_len == 2 && strncmp(key, "up", 2) == 0) dst = c.up;
        else if (key_len == 3 && strncmp(key, "fov", 3) == 0) dst = &c.fov_y_degrees, n = 1;
        if (!dst) {
            err = as_set_error(AS_ERROR_PARSE, "%s: line %u: unknown key '%.*s' (known: eye, target, up, fov)", path,
                               lineno, (int)(key_len > 32 ? 32 : key_len), key);
        } else if (!read_numbers(p, dst, n)) {
            err = as_set_error(AS_ERROR_PARSE, "%s: line %u: '%.*s' takes %s", path, lineno, (int)key_len, key,
                               n == 1 ? "one finite number" : "three finite numbers");
        } else if (n == 1 && !(c.fov_y_degrees > 0.0f && c.fov_y_degrees < 180.0f)) {
            err = as_set_error(AS_ERROR_PARSE, "%s: line %u: fov must be in (0, 180) degrees", path, lineno);
        }
    }
    if (err == AS_OK && ferror(f)) err = as_set_error(AS_ERROR_IO, "%s: read error", path);
    fclose(f);
    if (err != AS_OK) return err;
    if (!have_eye || !have_target)
        return as_set_error(AS_ERROR_PARSE, "%s: a camera needs both 'eye' and 'target'", path);
    const float d[3] = {c.target[0] - c.eye[0], c.target[1] - c.eye[1], c.target[2] - c.eye[2]};
    float side[3];
    cross3(d, c.up, side);
    if (d[0] == 0.0f && d[1] == 0.0f && d[2] == 0.0f)
        return as_set_error(AS_ERROR_PARSE, "%s: eye and target are the same point", path);
    if (side[0] == 0.0f && side[1] == 0.0f && side[2] == 0.0f)
        return as_set_error(AS_ERROR_PARSE, "%s: 'up' is zero or parallel to the view direction", path);
    *cam = c;
    return AS_OK;
}
