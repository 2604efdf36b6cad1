/* What every traversal header shares: the host/device marker, small vector
 * helpers and the explicitly rounded arithmetic the watertight tests need.
 * Compiles as C11 and under nvcc. */
#ifndef AS_KERNEL_COMMON_H
#define AS_KERNEL_COMMON_H

#include <stdint.h>

#ifdef __CUDACC__
#define AS_HD __host__ __device__ __forceinline__
#define AS_NOINLINE_HD __host__ __device__ __noinline__
#define AS_RESTRICT __restrict__
#else
#include <math.h>
#include <string.h>
#define AS_HD static inline
#define AS_NOINLINE_HD static inline
#define AS_RESTRICT restrict
#endif

/* Each of these is one IEEE operation rounded once. nvcc contracts a*b+c into
 * an FMA by default, which changes the edge functions of the watertight test
 * so that neighbouring triangles no longer agree on shared edges; the _rn
 * intrinsics are never contracted. On the CPU the library is compiled with
 * -ffp-contract=off for the same reason. */
#if defined(__CUDA_ARCH__)
#define AS_MUL(a, b) __fmul_rn((a), (b))
#define AS_ADD(a, b) __fadd_rn((a), (b))
#define AS_SUB(a, b) __fsub_rn((a), (b))
#define AS_MINF(a, b) fminf((a), (b))
#define AS_MAXF(a, b) fmaxf((a), (b))
#define AS_DMUL(a, b) __dmul_rn((a), (b))
#define AS_DADD(a, b) __dadd_rn((a), (b))
#define AS_DSUB(a, b) __dsub_rn((a), (b))
#else
#define AS_MUL(a, b) ((a) * (b))
#define AS_ADD(a, b) ((a) + (b))
#define AS_SUB(a, b) ((a) - (b))
#define AS_MINF(a, b) fminf((a), (b))
#define AS_MAXF(a, b) fmaxf((a), (b))
#define AS_DMUL(a, b) ((a) * (b))
#define AS_DADD(a, b) ((a) + (b))
#define AS_DSUB(a, b) ((a) - (b))
#endif


AS_HD float as_uint_as_float(uint32_t u)
{
#ifdef __CUDA_ARCH__
    return __uint_as_float(u);
#else
    float f;
    memcpy(&f, &u, sizeof f);
    return f;
#endif
}

AS_HD uint32_t as_float_as_uint(float f)
{
#ifdef __CUDA_ARCH__
    return __float_as_uint(f);
#else
    uint32_t u;
    memcpy(&u, &f, sizeof u);
    return u;
#endif
}

AS_HD float as_inf(void) { return as_uint_as_float(0x7f800000u); }

/* A float4 that C and CUDA agree on: 16 bytes, 16-byte aligned, so the GPU
 * reads it with one vector load. */
typedef struct __attribute__((aligned(16))) as_f4 {
    float x, y, z, w;
} as_f4_t;

/* Read-only loads through the texture path on the GPU. */
#ifdef __CUDA_ARCH__
AS_HD as_f4_t as_load_f4(const as_f4_t *p)
{
    const float4 v = __ldg((const float4 *)p);
    as_f4_t r = {v.x, v.y, v.z, v.w};
    return r;
}
#else
AS_HD as_f4_t as_load_f4(const as_f4_t *p) { return *p; }
#endif

#endif
