/* Internal common layer of libas: errors, memory, clocks, threads. It depends
 * on nothing but libc. */
#ifndef AS_INTERNAL_H
#define AS_INTERNAL_H

#include "as/as.h"

#include <stdarg.h>
#include <stddef.h>
#include <stdint.h>
#include <string.h>

#ifdef __cplusplus
extern "C" {
#endif

#if defined(__GNUC__)
#define AS_PRINTF(f, a) __attribute__((format(printf, f, a)))
#else
#define AS_PRINTF(f, a)
#endif

/* Sets this thread's last error and returns `code`, so that error paths read
 * `return as_set_error(AS_ERROR_CORRUPT, "%s: ...", path);`. */
as_error_t as_set_error(as_error_t code, const char *fmt, ...) AS_PRINTF(2, 3);
as_error_t as_set_errorv(as_error_t code, const char *fmt, va_list ap);

/* Whether this processor runs AVX2 code (asked once): the builders' few
 * AVX2 loops are chosen at run time, the library being built for the
 * x86-64 baseline. 0 elsewhere than x86-64 with GCC or Clang. */
int as_cpu_has_avx2(void);

/* malloc/calloc that set AS_ERROR_OUT_OF_MEMORY (naming `what`) on failure. */
void *as_malloc(size_t bytes, const char *what);
void *as_calloc(size_t count, size_t size, const char *what);

/* Overflow-safe size arithmetic: return false on overflow. */
static inline int as_add_u64(uint64_t a, uint64_t b, uint64_t *out)
{
    if (a > UINT64_MAX - b) return 0;
    *out = a + b;
    return 1;
}
static inline int as_mul_u64(uint64_t a, uint64_t b, uint64_t *out)
{
    if (a != 0 && b > UINT64_MAX / a) return 0;
    *out = a * b;
    return 1;
}

/* Monotonic clock in milliseconds. */
double as_now_ms(void);

/* Piece i of n of [0, total): [*first, *end), the pieces' sizes within one
 * of each other and not depending on which thread asks. */
static inline void as_chunk_range(uint32_t total, unsigned i, unsigned n, uint32_t *first, uint32_t *end)
{
    *first = (uint32_t)((uint64_t)total * i / n);
    *end = (uint32_t)((uint64_t)total * (i + 1) / n);
}

/* Set bits of x. The build targets x86-64 without POPCNT, where
 * __builtin_popcountll is a call into libgcc's table loop (1.5% of a
 * 16-thread binned build's samples, in its partition); these dozen
 * instructions inline are several times faster. */
static inline uint32_t as_popcount64(uint64_t x)
{
#if defined(__POPCNT__)
    return (uint32_t)__builtin_popcountll(x);
#else
    x = x - ((x >> 1) & 0x5555555555555555ull);
    x = (x & 0x3333333333333333ull) + ((x >> 2) & 0x3333333333333333ull);
    x = (x + (x >> 4)) & 0x0f0f0f0f0f0f0f0full;
    return (uint32_t)((x * 0x0101010101010101ull) >> 56);
#endif
}

/* The next float towards -inf / +inf of a float that is not NaN
 * (nextafterf without the library call, which showed in builders'
 * profiles): +inf steps down to FLT_MAX, -inf up to -FLT_MAX. */
static inline float as_float_next_down(float f)
{
    uint32_t u;
    memcpy(&u, &f, 4);
    /* Masks, not branches (the sign is a coin toss where clipping rounds):
     * a negative float steps away from zero, a zero to -denorm_min. */
    const uint32_t step = u - 1 + ((u >> 31) << 1);
    const uint32_t zero = 0u - (uint32_t)((u << 1) == 0), minus_inf = 0u - (uint32_t)(u == 0xff800000u);
    u = (step & ~(zero | minus_inf)) | (0x80000001u & zero) | (u & minus_inf);
    memcpy(&f, &u, 4);
    return f;
}

static inline float as_float_next_up(float f) { return -as_float_next_down(-f); }

/* Number of worker threads for a request (0: online cores). */
unsigned as_thread_count(unsigned requested);

/* Runs fn(user, i) for i in [0, count) on `threads` threads (the caller's
 * among them); items are handed out in order from a shared counter. */
typedef void (*as_parallel_fn)(void *user, size_t index);
void as_parallel_for(unsigned threads, size_t count, as_parallel_fn fn, void *user);

/* XXH3-64 of a byte range. */
uint64_t as_hash64(const void *data, size_t bytes);
uint64_t as_hash64_seeded(const void *data, size_t bytes, uint64_t seed);

#ifdef __cplusplus
}
#endif

#endif
