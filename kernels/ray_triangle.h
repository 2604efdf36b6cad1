/* Ray setup, the robust slab test and the watertight ray/triangle test,
 * shared by every traversal on CPU and GPU. */
#ifndef AS_RAY_TRIANGLE_H
#define AS_RAY_TRIANGLE_H

#include "as_kernel_common.h"

/* A ray prepared for traversal. */
typedef struct as_ray_pre {
    float ox, oy, oz;
    float dx, dy, dz;
    float ix, iy, iz;       /* 1/d; a zero component (either sign) is +inf */
    float tmin, tmax;
    int kx, ky, kz;         /* kz: the dominant axis of d (Woop et al. 2013) */
    float sx, sy, sz;       /* shear constants */
    int precise;            /* the triangle test runs in double */
    int moller;             /* the Moller-Trumbore test instead (not watertight) */
    double dsx, dsy, dsz;   /* shear constants in double */
} as_ray_pre_t;

/* Flags of as_ray_prepare. */
#define AS_RAY_PRECISE 1    /* watertight test in double: exact where float cancels
                               (huge triangles seen from close by, tiny ones from afar) */
#define AS_RAY_MOLLER_TRUMBORE 2 /* Moller & Trumbore 1997 in float: the classic test,
                                    for comparison; rays can slip through shared edges */

/* The shear constants in double, for the double intersector and the
 * float one's exact distances. */
AS_HD void as_ray_shear_double(const as_ray_pre_t *r, double *dsx, double *dsy, double *dsz)
{
    const float d[3] = {r->dx, r->dy, r->dz};
    *dsx = (double)d[r->kx] / (double)d[r->kz];
    *dsy = (double)d[r->ky] / (double)d[r->kz];
    *dsz = 1.0 / (double)d[r->kz];
}

AS_HD int as_is_finite(float x) { return (as_float_as_uint(x) & 0x7f800000u) != 0x7f800000u; }

/* Prepares a ray; returns 0 for a ray that can hit nothing by definition:
 * NaN or infinite origin or direction, zero direction, tmin > tmax or NaN
 * limits. Such rays report a miss without traversal. */
AS_HD int as_ray_prepare(const float org[3], float tmin, const float dir[3], float tmax, int flags,
                         as_ray_pre_t *r)
{
    if (!as_is_finite(org[0]) || !as_is_finite(org[1]) || !as_is_finite(org[2]) ||
        !as_is_finite(dir[0]) || !as_is_finite(dir[1]) || !as_is_finite(dir[2]))
        return 0;
    if (!(tmin <= tmax)) return 0; /* also false for NaN */
    if (dir[0] == 0.0f && dir[1] == 0.0f && dir[2] == 0.0f) return 0;
    r->ox = org[0]; r->oy = org[1]; r->oz = org[2];
    /* -0 and +0 must behave alike: both become +0, whose inverse is +inf.
     * The slab test below then yields NaN exactly when the origin lies on a
     * slab plane, and fmaxf/fminf drop that NaN, which counts the plane as
     * inside the slab. */
    r->dx = dir[0] == 0.0f ? 0.0f : dir[0];
    r->dy = dir[1] == 0.0f ? 0.0f : dir[1];
    r->dz = dir[2] == 0.0f ? 0.0f : dir[2];
    r->ix = 1.0f / r->dx;
    r->iy = 1.0f / r->dy;
    r->iz = 1.0f / r->dz;
    r->tmin = tmin;
    r->tmax = tmax;
    const float ax = fabsf(r->dx), ay = fabsf(r->dy), az = fabsf(r->dz);
    int kz = ax > ay ? (ax > az ? 0 : 2) : (ay > az ? 1 : 2);
    int kx = kz == 2 ? 0 : kz + 1;
    int ky = kx == 2 ? 0 : kx + 1;
    const float d[3] = {r->dx, r->dy, r->dz};
    if (d[kz] < 0.0f) { const int t = kx; kx = ky; ky = t; } /* keep the winding */
    r->kx = kx; r->ky = ky; r->kz = kz;
    r->sx = d[kx] / d[kz];
    r->sy = d[ky] / d[kz];
    r->sz = 1.0f / d[kz];
    r->precise = flags & AS_RAY_PRECISE;
    r->moller = (flags & AS_RAY_MOLLER_TRUMBORE) != 0;
    as_ray_shear_double(r, &r->dsx, &r->dsy, &r->dsz);
    return 1;
}

/* 1 + 2 gamma(3): scaling the far slab distance by it makes the box test
 * conservative under rounding (Ize 2013, "Robust BVH Ray Traversal"). */
#define AS_BOX_FAR_SCALE 1.00000024f

/* Whether the ray enters the box [lo, hi] within [tmin, tfar_limit]; the
 * entry distance goes to *tnear. */
AS_HD int as_ray_box(const as_ray_pre_t *r, float lox, float hix, float loy, float hiy,
                     float loz, float hiz, float tfar_limit, float *tnear)
{
    const float nx = r->ix >= 0.0f ? lox : hix, fx = r->ix >= 0.0f ? hix : lox;
    const float ny = r->iy >= 0.0f ? loy : hiy, fy = r->iy >= 0.0f ? hiy : loy;
    const float nz = r->iz >= 0.0f ? loz : hiz, fz = r->iz >= 0.0f ? hiz : loz;
    const float t0x = AS_MUL(AS_SUB(nx, r->ox), r->ix), t1x = AS_MUL(AS_SUB(fx, r->ox), r->ix);
    const float t0y = AS_MUL(AS_SUB(ny, r->oy), r->iy), t1y = AS_MUL(AS_SUB(fy, r->oy), r->iy);
    const float t0z = AS_MUL(AS_SUB(nz, r->oz), r->iz), t1z = AS_MUL(AS_SUB(fz, r->oz), r->iz);
    const float tn = AS_MAXF(AS_MAXF(t0x, t0y), AS_MAXF(t0z, r->tmin));
    const float tf = AS_MINF(AS_MINF(t1x, t1y), AS_MINF(t1z, tfar_limit)) * AS_BOX_FAR_SCALE;
    *tnear = tn;
    return tn <= tf;
}

/* Coordinate k (0, 1 or 2) of (x, y, z), by selection: an array indexed by a
 * value known only at run time lives in local memory on the GPU, and every
 * triangle test would store and reload its vertices there. */
AS_HD float as_pick3f(int k, float x, float y, float z) { return k == 0 ? x : (k == 1 ? y : z); }
AS_HD double as_pick3d(int k, double x, double y, double z) { return k == 0 ? x : (k == 1 ? y : z); }

/* What the exact end of the float test reads of a ray. It is passed by
 * value to a function the GPU does not inline; passing the whole prepared
 * ray by address would keep that ray in local memory for the whole trace. */
typedef struct as_ray_exact {
    double dsx, dsy, dsz;
    float ox, oy, oz, tmin, tmax;
    int kx, ky, kz;
} as_ray_exact_t;

AS_HD as_ray_exact_t as_ray_exact_of(const as_ray_pre_t *r)
{
    as_ray_exact_t e;
    e.dsx = r->dsx; e.dsy = r->dsy; e.dsz = r->dsz;
    e.ox = r->ox; e.oy = r->oy; e.oz = r->oz; e.tmin = r->tmin; e.tmax = r->tmax;
    e.kx = r->kx; e.ky = r->ky; e.kz = r->kz;
    return e;
}

/* The sheared edge functions of a triangle in double, and the numerator T
 * and denominator det of its distance t = T / det, without any decision:
 * the float test below decides hit or miss (watertight), and these give the
 * distance and barycentrics of an accepted hit, exact where float cancels
 * (slivers, huge triangles seen from close by). */
AS_HD void as_triangle_sums_double(const as_ray_exact_t *r, as_f4_t a, as_f4_t b, as_f4_t c,
                                   double *T, double *det, double *V, double *W)
{
    const double dsx = r->dsx, dsy = r->dsy, dsz = r->dsz;
    const int kx = r->kx, ky = r->ky, kz = r->kz;
    const double okx = as_pick3d(kx, r->ox, r->oy, r->oz), oky = as_pick3d(ky, r->ox, r->oy, r->oz),
                 okz = as_pick3d(kz, r->ox, r->oy, r->oz);
    const double A_z = AS_DSUB(as_pick3d(kz, a.x, a.y, a.z), okz);
    const double B_z = AS_DSUB(as_pick3d(kz, b.x, b.y, b.z), okz);
    const double C_z = AS_DSUB(as_pick3d(kz, c.x, c.y, c.z), okz);
    const double Ax = AS_DSUB(AS_DSUB(as_pick3d(kx, a.x, a.y, a.z), okx), AS_DMUL(dsx, A_z));
    const double Ay = AS_DSUB(AS_DSUB(as_pick3d(ky, a.x, a.y, a.z), oky), AS_DMUL(dsy, A_z));
    const double Bx = AS_DSUB(AS_DSUB(as_pick3d(kx, b.x, b.y, b.z), okx), AS_DMUL(dsx, B_z));
    const double By = AS_DSUB(AS_DSUB(as_pick3d(ky, b.x, b.y, b.z), oky), AS_DMUL(dsy, B_z));
    const double Cx = AS_DSUB(AS_DSUB(as_pick3d(kx, c.x, c.y, c.z), okx), AS_DMUL(dsx, C_z));
    const double Cy = AS_DSUB(AS_DSUB(as_pick3d(ky, c.x, c.y, c.z), oky), AS_DMUL(dsy, C_z));
    const double U = AS_DSUB(AS_DMUL(Cx, By), AS_DMUL(Cy, Bx));
    *V = AS_DSUB(AS_DMUL(Ax, Cy), AS_DMUL(Ay, Cx));
    *W = AS_DSUB(AS_DMUL(Bx, Ay), AS_DMUL(By, Ax));
    *det = AS_DADD(AS_DADD(U, *V), *W);
    *T = AS_DADD(AS_DADD(AS_DMUL(U, AS_DMUL(dsz, A_z)), AS_DMUL(*V, AS_DMUL(dsz, B_z))),
                 AS_DMUL(*W, AS_DMUL(dsz, C_z)));
}

/* Whether t = T / det can lie in [tmin, tmax] (det != 0), decided without
 * the division: the margins are far wider than the rounding of T x (1 / det)
 * and of the products here, and above tmax wider than half a float step
 * (as_distance_accepted takes a distance that rounds to tmax), so no
 * distance that the exact check after the division accepts is turned away;
 * most candidates behind the closest hit so far are, at the cost of two
 * multiplications. */
AS_HD int as_distance_may_be_in(double T, double det, float tmin, float tmax)
{
    const double Ts = det > 0.0 ? T : -T, ds = det > 0.0 ? det : -det;
    const double lo = AS_DMUL((double)tmin, ds), hi = AS_DMUL((double)tmax, ds);
    if (Ts < AS_DSUB(lo, AS_DADD(fabs(lo) * 0x1p-40, 0x1p-1000))) return 0;
    if (Ts > AS_DADD(hi, AS_DADD(fabs(hi) * 0x1p-23, 0x1p-1000))) return 0; /* false for tmax = inf */
    return 1;
}

/* Whether a distance t computed in double is a hit: inside the ray's own
 * interval [tmin, tmax], exactly, and not beyond the closest hit so far,
 * `tmax_now`, compared as the float that would be stored. That hit is held
 * as a float rounded from its double distance, so a coincident copy of its
 * triangle (the same distance exactly) can lie just above it in double; it
 * must still reach the traversal's tie rule (equal distances go to the
 * lowest source index), or the reported copy would depend on the order in
 * which the traversal meets them. */
AS_HD int as_distance_accepted(double t, float tmin, float tmax, float tmax_now)
{
    return t >= (double)tmin && t <= (double)tmax && (float)t <= tmax_now;
}

/* The exact end of the float test for a triangle the ray crosses: distance
 * and barycentrics in double, one division. Not inlined on the GPU, so that
 * its double registers do not count against the traversal loop; it reloads
 * the triangle (three vertices, 16 bytes each, at `tri`) from the cache
 * rather than receive it. */
AS_NOINLINE_HD int as_triangle_accept_double(as_ray_exact_t r, const as_f4_t *AS_RESTRICT tri,
                                             float tmax_now, float *t_out, float *u_out, float *v_out)
{
    double T, detd, Vd, Wd;
    as_triangle_sums_double(&r, as_load_f4(tri), as_load_f4(tri + 1), as_load_f4(tri + 2), &T, &detd, &Vd, &Wd);
    if (detd == 0.0 || !as_distance_may_be_in(T, detd, r.tmin, tmax_now)) return 0;
    const double inv = 1.0 / detd;
    const double td = T * inv, ud = Vd * inv, vd = Wd * inv;
    if (!as_distance_accepted(td, r.tmin, r.tmax, tmax_now)) return 0;
    *t_out = (float)td; /* rounding is monotonic: still within the float interval */
    *u_out = (float)ud;
    *v_out = (float)vd;
    return 1;
}

/* The same test in double: products of floats are exact in double and the
 * edge functions of a shared edge are still exact negatives, so it stays
 * watertight while the cancellation that float suffers for triangles much
 * larger or smaller than their distance disappears. */
AS_HD int as_ray_triangle_precise(const as_ray_pre_t *r, as_f4_t a, as_f4_t b, as_f4_t c,
                                  float tmax_now, float *t_out, float *u_out, float *v_out)
{
    const int kx = r->kx, ky = r->ky, kz = r->kz;
    const double okx = as_pick3d(kx, r->ox, r->oy, r->oz), oky = as_pick3d(ky, r->ox, r->oy, r->oz),
                 okz = as_pick3d(kz, r->ox, r->oy, r->oz);
    const double A_x = AS_DSUB(as_pick3d(kx, a.x, a.y, a.z), okx), A_y = AS_DSUB(as_pick3d(ky, a.x, a.y, a.z), oky),
                 A_z = AS_DSUB(as_pick3d(kz, a.x, a.y, a.z), okz);
    const double B_x = AS_DSUB(as_pick3d(kx, b.x, b.y, b.z), okx), B_y = AS_DSUB(as_pick3d(ky, b.x, b.y, b.z), oky),
                 B_z = AS_DSUB(as_pick3d(kz, b.x, b.y, b.z), okz);
    const double C_x = AS_DSUB(as_pick3d(kx, c.x, c.y, c.z), okx), C_y = AS_DSUB(as_pick3d(ky, c.x, c.y, c.z), oky),
                 C_z = AS_DSUB(as_pick3d(kz, c.x, c.y, c.z), okz);
    const double Ax = AS_DSUB(A_x, AS_DMUL(r->dsx, A_z)), Ay = AS_DSUB(A_y, AS_DMUL(r->dsy, A_z));
    const double Bx = AS_DSUB(B_x, AS_DMUL(r->dsx, B_z)), By = AS_DSUB(B_y, AS_DMUL(r->dsy, B_z));
    const double Cx = AS_DSUB(C_x, AS_DMUL(r->dsx, C_z)), Cy = AS_DSUB(C_y, AS_DMUL(r->dsy, C_z));
    const double U = AS_DSUB(AS_DMUL(Cx, By), AS_DMUL(Cy, Bx));
    const double V = AS_DSUB(AS_DMUL(Ax, Cy), AS_DMUL(Ay, Cx));
    const double W = AS_DSUB(AS_DMUL(Bx, Ay), AS_DMUL(By, Ax));
    if ((U < 0.0 || V < 0.0 || W < 0.0) && (U > 0.0 || V > 0.0 || W > 0.0)) return 0;
    const double det = AS_DADD(AS_DADD(U, V), W);
    if (det == 0.0) return 0;
    const double T = AS_DADD(AS_DADD(AS_DMUL(U, AS_DMUL(r->dsz, A_z)), AS_DMUL(V, AS_DMUL(r->dsz, B_z))),
                             AS_DMUL(W, AS_DMUL(r->dsz, C_z)));
    const double t = T / det;
    if (!as_distance_accepted(t, r->tmin, r->tmax, tmax_now)) return 0;
    *t_out = (float)t; /* rounding is monotonic: still within the float interval */
    *u_out = (float)(V / det);
    *v_out = (float)(W / det);
    return 1;
}

/* The Moller-Trumbore test (1997), no culling, the way most tracers write
 * it: the edge and distance arithmetic in float, each operation rounded on
 * its own (no fused multiply-add) so that CPU and GPU agree bit for bit. It
 * decides on each triangle alone, so a ray through a shared edge or vertex
 * can miss both triangles, and a parallel ray (det exactly 0) misses. */
AS_HD int as_ray_triangle_moller(const as_ray_pre_t *r, as_f4_t a, as_f4_t b, as_f4_t c,
                                 float tmax_now, float *t_out, float *u_out, float *v_out)
{
    const float e1x = AS_SUB(b.x, a.x), e1y = AS_SUB(b.y, a.y), e1z = AS_SUB(b.z, a.z);
    const float e2x = AS_SUB(c.x, a.x), e2y = AS_SUB(c.y, a.y), e2z = AS_SUB(c.z, a.z);
    const float px = AS_SUB(AS_MUL(r->dy, e2z), AS_MUL(r->dz, e2y));
    const float py = AS_SUB(AS_MUL(r->dz, e2x), AS_MUL(r->dx, e2z));
    const float pz = AS_SUB(AS_MUL(r->dx, e2y), AS_MUL(r->dy, e2x));
    const float det = AS_ADD(AS_ADD(AS_MUL(e1x, px), AS_MUL(e1y, py)), AS_MUL(e1z, pz));
    if (det == 0.0f) return 0;
    const float inv = 1.0f / det;
    const float sx = AS_SUB(r->ox, a.x), sy = AS_SUB(r->oy, a.y), sz = AS_SUB(r->oz, a.z);
    const float u = AS_MUL(AS_ADD(AS_ADD(AS_MUL(sx, px), AS_MUL(sy, py)), AS_MUL(sz, pz)), inv);
    if (!(u >= 0.0f && u <= 1.0f)) return 0;
    const float qx = AS_SUB(AS_MUL(sy, e1z), AS_MUL(sz, e1y));
    const float qy = AS_SUB(AS_MUL(sz, e1x), AS_MUL(sx, e1z));
    const float qz = AS_SUB(AS_MUL(sx, e1y), AS_MUL(sy, e1x));
    const float v = AS_MUL(AS_ADD(AS_ADD(AS_MUL(r->dx, qx), AS_MUL(r->dy, qy)), AS_MUL(r->dz, qz)), inv);
    if (!(v >= 0.0f && AS_ADD(u, v) <= 1.0f)) return 0;
    const float t = AS_MUL(AS_ADD(AS_ADD(AS_MUL(e2x, qx), AS_MUL(e2y, qy)), AS_MUL(e2z, qz)), inv);
    if (!(t >= r->tmin && t <= tmax_now)) return 0;
    *t_out = t;
    *u_out = u;
    *v_out = v;
    return 1;
}

/* Watertight ray/triangle intersection (Woop, Benthin & Wald 2013), no
 * culling, against the triangle whose three vertices (16 bytes each, xyz
 * used) are stored at `tri` and were loaded into a, b, c. Returns 1 and sets
 * *t, *u, *v when the ray hits the triangle with tmin <= t <= tmax_now,
 * where the hit point is (1-u-v) a + u b + v c. Triangles with zero
 * projected area are never hit. */
AS_HD int as_ray_triangle(const as_ray_pre_t *r, const as_f4_t *AS_RESTRICT tri, as_f4_t a, as_f4_t b,
                          as_f4_t c, float tmax_now, float *t_out, float *u_out, float *v_out)
{
    if (r->precise) return as_ray_triangle_precise(r, a, b, c, tmax_now, t_out, u_out, v_out);
    if (r->moller) return as_ray_triangle_moller(r, a, b, c, tmax_now, t_out, u_out, v_out);
    const int kx = r->kx, ky = r->ky, kz = r->kz;
    const float okx = as_pick3f(kx, r->ox, r->oy, r->oz), oky = as_pick3f(ky, r->ox, r->oy, r->oz),
                okz = as_pick3f(kz, r->ox, r->oy, r->oz);
    const float A_x = AS_SUB(as_pick3f(kx, a.x, a.y, a.z), okx), A_y = AS_SUB(as_pick3f(ky, a.x, a.y, a.z), oky),
                A_z = AS_SUB(as_pick3f(kz, a.x, a.y, a.z), okz);
    const float B_x = AS_SUB(as_pick3f(kx, b.x, b.y, b.z), okx), B_y = AS_SUB(as_pick3f(ky, b.x, b.y, b.z), oky),
                B_z = AS_SUB(as_pick3f(kz, b.x, b.y, b.z), okz);
    const float C_x = AS_SUB(as_pick3f(kx, c.x, c.y, c.z), okx), C_y = AS_SUB(as_pick3f(ky, c.x, c.y, c.z), oky),
                C_z = AS_SUB(as_pick3f(kz, c.x, c.y, c.z), okz);
    const float Ax = AS_SUB(A_x, AS_MUL(r->sx, A_z)), Ay = AS_SUB(A_y, AS_MUL(r->sy, A_z));
    const float Bx = AS_SUB(B_x, AS_MUL(r->sx, B_z)), By = AS_SUB(B_y, AS_MUL(r->sy, B_z));
    const float Cx = AS_SUB(C_x, AS_MUL(r->sx, C_z)), Cy = AS_SUB(C_y, AS_MUL(r->sy, C_z));
    float U = AS_SUB(AS_MUL(Cx, By), AS_MUL(Cy, Bx));
    float V = AS_SUB(AS_MUL(Ax, Cy), AS_MUL(Ay, Cx));
    float W = AS_SUB(AS_MUL(Bx, Ay), AS_MUL(By, Ax));
    /* On an edge the float products cancel to exactly zero and their sign is
     * unreliable: redo them in double, where the products are exact. */
    if (U == 0.0f || V == 0.0f || W == 0.0f) {
        U = (float)((double)Cx * (double)By - (double)Cy * (double)Bx);
        V = (float)((double)Ax * (double)Cy - (double)Ay * (double)Cx);
        W = (float)((double)Bx * (double)Ay - (double)By * (double)Ax);
    }
    if ((U < 0.0f || V < 0.0f || W < 0.0f) && (U > 0.0f || V > 0.0f || W > 0.0f)) return 0;
    const float det = AS_ADD(AS_ADD(U, V), W);
    if (det == 0.0f) return 0;
    /* The ray crosses the triangle: its distance comes from double, since
     * T / det in float loses most digits on slivers and on triangles much
     * larger than their distance. (A float distance with an error bound
     * that lets float decide most candidates measured slower on the H100:
     * the bound's registers made the traversal loop spill.) */
    return as_triangle_accept_double(as_ray_exact_of(r), tri, tmax_now, t_out, u_out, v_out);
}
#endif
