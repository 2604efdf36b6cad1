/* KD builder, SAH with perfect splits (Wald & Havran 2006, "On building fast
 * kd-trees for ray tracing, and on doing that in O(N log N)").
 *
 * Candidates are the bounds of every reference's clipped box (kd_build.c
 * clips triangles to the node box, so these are the "perfect" planes). Each
 * candidate plane is swept with three event kinds: end, planar, start.
 * A triangle counts below when it starts below the plane, above when it
 * ends above it; triangles lying in the plane are tried on either side and
 * put where the cost is lower (section 4.3 of the paper). The cost is
 * lambda (C_t + C_i (A_L N_L + A_R N_R) / A) with lambda = 0.8 when a side is
 * empty (the empty-space bonus); a node becomes a leaf when no plane costs
 * less than C_i N.
 *
 * This version sorts the events of each node again, with a radix sort that
 * is linear in the node's references, which gives the paper's O(N log N)
 * bound; the paper's sort-once-and-split event lists would save the
 * constant factor of re-sorting and are left for later. */
#include "kd_build.h"

#include <math.h>
#include <stdlib.h>
#include <string.h>

enum { EV_END = 0, EV_PLANAR = 1, EV_START = 2 };

/* A float's bits, ordered as the floats are. */
static uint32_t float_key(float f)
{
    const uint32_t u = as_float_as_uint(f == 0.0f ? 0.0f : f);
    return (u & 0x80000000u) ? ~u : u | 0x80000000u;
}

static float key_float(uint32_t k)
{
    return as_uint_as_float((k & 0x80000000u) ? k & 0x7fffffffu : ~k);
}


/* Sorts event keys (34 significant bits): LSD radix sort, linear in the
 * count, so a node costs O(n) and the build O(N log N); short lists use
 * insertion sort. One read pass makes every digit's histogram, and a digit
 * that all keys share (the high bits of positions inside one node's box
 * mostly are) costs no pass. `tmp` has room for m keys. */
static void radix_sort_digits(uint64_t *ev, uint64_t *tmp, size_t m, int bits, int passes, size_t *count)
{
    const size_t buckets = (size_t)1 << bits, mask = buckets - 1;
    memset(count, 0, sizeof(size_t) * buckets * (size_t)passes);
    for (size_t i = 0; i < m; ++i)
        for (int pass = 0; pass < passes; ++pass) count[(size_t)pass * buckets + ((ev[i] >> (bits * pass)) & mask)]++;
    uint64_t *src = ev, *dst = tmp;
    for (int pass = 0; pass < passes; ++pass) {
        size_t *c = count + (size_t)pass * buckets;
        const int shift = bits * pass;
        if (c[(src[0] >> shift) & mask] == m) continue; /* one bucket: order kept */
        size_t sum = 0;
        for (size_t k = 0; k < buckets; ++k) { const size_t n = c[k]; c[k] = sum; sum += n; }
        for (size_t i = 0; i < m; ++i) dst[c[(src[i] >> shift) & mask]++] = src[i];
        uint64_t *t = src; src = dst; dst = t;
    }
    if (src != ev) memcpy(ev, src, sizeof(uint64_t) * m);
}

static void sort_events(uint64_t *ev, uint64_t *tmp, size_t m)
{
    if (m < 48) {
        for (size_t i = 1; i < m; ++i) {
            const uint64_t k = ev[i];
            size_t j = i;
            for (; j > 0 && ev[j - 1] > k; --j) ev[j] = ev[j - 1];
            ev[j] = k;
        }
        return;
    }
    /* 5 digits of 7 bits for short lists (small histograms to clear), 3 of
     * 12 bits for long ones; both cover the 34 bits of a key. */
    static _Thread_local size_t count[3 << 12];
    if (m < 8192) radix_sort_digits(ev, tmp, m, 7, 5, count);
    else radix_sort_digits(ev, tmp, m, 12, 3, count);
}

static double half_area(const float b[6])
{
    const double dx = (double)b[3] - b[0], dy = (double)b[4] - b[1], dz = (double)b[5] - b[2];
    return dx * dy + dy * dz + dz * dx;
}

static int sah_choose(const kd_ctx *c, kd_ref *refs, uint32_t n, const float box[6], uint32_t depth, kd_split *out)
{
    (void)depth;
    const double ct = c->args->cost_traversal, ci = c->args->cost_intersection;
    const double area = half_area(box);
    if (n <= 1 && ct >= ci) return 0;
    if (!(area > 0.0)) return 0;
    uint64_t *ev = malloc(sizeof(uint64_t) * 4 * (size_t)n);
    if (!ev) return 0;
    uint64_t *tmp = ev + 2 * (size_t)n;
    double best = ci * (double)n;
    int found = 0;
    for (int axis = 0; axis < 3; ++axis) {
        if (!(box[axis + 3] > box[axis])) continue;
        size_t m = 0;
        uint32_t np_total = 0, p_total = 0;
        for (uint32_t i = 0; i < n; ++i) {
            const float lo = refs[i].lo[axis], hi = refs[i].hi[axis];
            if (lo == hi) {
                ev[m++] = ((uint64_t)float_key(lo) << 2) | EV_PLANAR;
                ++p_total;
            } else {
                ev[m++] = ((uint64_t)float_key(lo) << 2) | EV_START;
                ev[m++] = ((uint64_t)float_key(hi) << 2) | EV_END;
                ++np_total;
            }
        }
        sort_events(ev, tmp, m);
        uint32_t s_lt = 0, e_lt = 0, p_lt = 0;
        /* A side's half area is linear in the plane's position: the face
         * across the axis plus the perimeter of that face times the side's
         * length along it. */
        const int a1 = (axis + 1) % 3, a2 = (axis + 2) % 3;
        const double e1 = (double)box[a1 + 3] - box[a1], e2 = (double)box[a2 + 3] - box[a2];
        const double face = e1 * e2 / area, rim = (e1 + e2) / area;
        const double lo = box[axis], hi = box[axis + 3];
        for (size_t i = 0; i < m;) {
            const uint32_t key = (uint32_t)(ev[i] >> 2);
            uint32_t s_eq = 0, e_eq = 0, p_eq = 0;
            size_t j = i;
            for (; j < m && (uint32_t)(ev[j] >> 2) == key; ++j) {
                const int type = (int)(ev[j] & 3);
                s_eq += type == EV_START;
                e_eq += type == EV_END;
                p_eq += type == EV_PLANAR;
            }
            const float pos = key_float(key);
            if (pos > box[axis] && pos < box[axis + 3]) {
                const double al = face + rim * ((double)pos - lo), ar = face + rim * (hi - (double)pos);
                const uint32_t nl0 = s_lt + p_lt, nr0 = (np_total - e_lt - e_eq) + (p_total - p_lt - p_eq);
                for (int side = 1; side >= 0; --side) {
                    const uint32_t nl = nl0 + (side ? p_eq : 0), nr = nr0 + (side ? 0 : p_eq);
                    const double lambda = (nl == 0 || nr == 0) ? 0.8 : 1.0;
                    const double cost = lambda * (ct + ci * (al * nl + ar * nr));
                    if (cost < best) {
                        best = cost;
                        out->axis = axis;
                        out->pos = pos;
                        out->planar_left = side;
                        found = 1;
                    }
                }
            }
            s_lt += s_eq;
            e_lt += e_eq;
            p_lt += p_eq;
            i = j;
        }
    }
    free(ev);
    return found;
}

as_error_t as_kd_build_sah(const as_mesh_t *mesh, const as_build_args_t *args, as_structure_t *s)
{
    return kd_build(mesh, args, AS_BUILDER_KD_SAH, sah_choose, s);
}
