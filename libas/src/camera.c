/* Pinhole cameras: the default view of a box and one ray per pixel. */
#include "as_internal.h"

#include <math.h>

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
