/* Four-float vectors for the builders' inner loops: SSE where the compiler
 * targets it (every x86-64), plain C elsewhere. Both give the same results
 * bit for bit: every operation is a single IEEE operation per lane, and
 * min/max follow the SSE rule (the second operand when either is NaN), so a
 * build is the same on every machine. */
#ifndef AS_SIMD4_H
#define AS_SIMD4_H

#include <stdint.h>

#if defined(__SSE2__)
#include <emmintrin.h>

typedef __m128 v4f;

static inline v4f v4f_load(const float *p) { return _mm_loadu_ps(p); }
/* Loads x, y, z and a zero: the fourth float of a bvh_ref's half is an
 * index, whose bits as a float are often denormal, and arithmetic on
 * denormals is slow on x86. */
static inline v4f v4f_load3(const float *p)
{
    return _mm_and_ps(_mm_loadu_ps(p), _mm_castsi128_ps(_mm_set_epi32(0, -1, -1, -1)));
}
/* x, y, z from three floats that may end an array, and a zero. */
static inline v4f v4f_set3(const float *p) { return _mm_setr_ps(p[0], p[1], p[2], 0.0f); }
static inline void v4f_store(float *p, v4f a) { _mm_storeu_ps(p, a); }
static inline v4f v4f_set1(float x) { return _mm_set1_ps(x); }
static inline v4f v4f_add(v4f a, v4f b) { return _mm_add_ps(a, b); }
static inline v4f v4f_sub(v4f a, v4f b) { return _mm_sub_ps(a, b); }
static inline v4f v4f_mul(v4f a, v4f b) { return _mm_mul_ps(a, b); }
static inline v4f v4f_min(v4f a, v4f b) { return _mm_min_ps(a, b); }
static inline v4f v4f_max(v4f a, v4f b) { return _mm_max_ps(a, b); }
/* Truncates each lane towards zero (lanes must be in int32 range). */
static inline void v4f_to_i32(v4f a, int32_t out[4]) { _mm_storeu_si128((__m128i *)out, _mm_cvttps_epi32(a)); }
/* Bit i set where a[i] < b[i]: a comparison's lanes as an integer, for
 * selecting without branches. */
static inline int v4f_lt_mask(v4f a, v4f b) { return _mm_movemask_ps(_mm_cmplt_ps(a, b)); }
/* Bit i set where a[i] <= b[i] (clear where either is NaN). */
static inline int v4f_le_mask(v4f a, v4f b) { return _mm_movemask_ps(_mm_cmple_ps(a, b)); }
/* Half the surface area of the box lo..hi (x, y, z lanes) in float, 0 when
 * inverted: dx dy + dy dz + dz dx, the products and sums in that order, so
 * it equals the scalar form bit for bit. In registers: the builders' sweeps
 * call it once per candidate plane, and a store and three loads cost more
 * than the arithmetic. */
static inline float v4f_half_area(v4f lo, v4f hi)
{
    const __m128 d = _mm_sub_ps(hi, lo);
    if (_mm_movemask_ps(_mm_cmplt_ps(d, _mm_setzero_ps())) & 7) return 0.0f;
    const __m128 p = _mm_mul_ps(d, _mm_shuffle_ps(d, d, _MM_SHUFFLE(3, 0, 2, 1)));
    const __m128 s = _mm_add_ss(p, _mm_shuffle_ps(p, p, _MM_SHUFFLE(1, 1, 1, 1)));
    return _mm_cvtss_f32(_mm_add_ss(s, _mm_movehl_ps(p, p)));
}
/* The same for a box known to be valid (lo <= hi in every lane), such as a
 * union of triangles' boxes: no test. */
static inline float v4f_half_area_valid(v4f lo, v4f hi)
{
    const __m128 d = _mm_sub_ps(hi, lo);
    const __m128 p = _mm_mul_ps(d, _mm_shuffle_ps(d, d, _MM_SHUFFLE(3, 0, 2, 1)));
    const __m128 s = _mm_add_ss(p, _mm_shuffle_ps(p, p, _MM_SHUFFLE(1, 1, 1, 1)));
    return _mm_cvtss_f32(_mm_add_ss(s, _mm_movehl_ps(p, p)));
}

#else

typedef struct v4f {
    float v[4];
} v4f;

static inline v4f v4f_load(const float *p) { v4f r = {{p[0], p[1], p[2], p[3]}}; return r; }
static inline v4f v4f_load3(const float *p) { v4f r = {{p[0], p[1], p[2], 0.0f}}; return r; }
static inline v4f v4f_set3(const float *p) { v4f r = {{p[0], p[1], p[2], 0.0f}}; return r; }
static inline void v4f_store(float *p, v4f a) { for (int i = 0; i < 4; ++i) p[i] = a.v[i]; }
static inline v4f v4f_set1(float x) { v4f r = {{x, x, x, x}}; return r; }
#define AS_V4F_LANES(expr) \
    v4f r;                 \
    for (int i = 0; i < 4; ++i) r.v[i] = (expr); \
    return r
static inline v4f v4f_add(v4f a, v4f b) { AS_V4F_LANES(a.v[i] + b.v[i]); }
static inline v4f v4f_sub(v4f a, v4f b) { AS_V4F_LANES(a.v[i] - b.v[i]); }
static inline v4f v4f_mul(v4f a, v4f b) { AS_V4F_LANES(a.v[i] * b.v[i]); }
static inline v4f v4f_min(v4f a, v4f b) { AS_V4F_LANES(a.v[i] < b.v[i] ? a.v[i] : b.v[i]); }
static inline v4f v4f_max(v4f a, v4f b) { AS_V4F_LANES(a.v[i] > b.v[i] ? a.v[i] : b.v[i]); }
#undef AS_V4F_LANES
static inline void v4f_to_i32(v4f a, int32_t out[4]) { for (int i = 0; i < 4; ++i) out[i] = (int32_t)a.v[i]; }
static inline int v4f_lt_mask(v4f a, v4f b)
{
    int m = 0;
    for (int i = 0; i < 4; ++i) m |= (a.v[i] < b.v[i]) << i;
    return m;
}
static inline int v4f_le_mask(v4f a, v4f b)
{
    int m = 0;
    for (int i = 0; i < 4; ++i) m |= (a.v[i] <= b.v[i]) << i;
    return m;
}
static inline float v4f_half_area(v4f lo, v4f hi)
{
    const float d0 = hi.v[0] - lo.v[0], d1 = hi.v[1] - lo.v[1], d2 = hi.v[2] - lo.v[2];
    if (d0 < 0.0f || d1 < 0.0f || d2 < 0.0f) return 0.0f;
    return d0 * d1 + d1 * d2 + d2 * d0;
}
static inline float v4f_half_area_valid(v4f lo, v4f hi) { return v4f_half_area(lo, hi); }

#endif

#endif
