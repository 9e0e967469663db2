/* SPDX-License-Identifier: GPL-3.0-or-later */
/* The element block kernels (elem_kernel.h): elem_block.inc compiled for
 * 4 portable lanes, 4 lanes of AVX2 and 8 of AVX-512, chosen at run time as
 * the spring kernel is (sim_kernel.c). */
#include "elem_kernel.h"

#include "hyperelastic.h"
#include "sim_internal.h"

#include <math.h>
#include <string.h>

#if defined(__x86_64__) || defined(__i386__)
#include "simd8.h"
#endif

/* the helpers of elem_block.inc pass vectors by value; all are inlined */
#if defined(__clang__)
#pragma clang diagnostic ignored "-Wpsabi"
#elif defined(__GNUC__)
#pragma GCC diagnostic ignored "-Wpsabi"
#endif

typedef double e4d __attribute__((vector_size(32)));
typedef int64_t e4l __attribute__((vector_size(32)));

/* 4 lanes: x, y, z of four points by 16-byte pairs (sim_internal.h) */
#define LOAD_XYZ4(p, o, x, y, z) ftm_load_xyz4(p, o[0], o[1], o[2], o[3], x, y, z)
/* 4 lanes: x, y, z of four nodes' displacements (eb->u) */
#define LOAD_U4(p, o, x, y, z)                                                                   \
    ftm_load_xyz4(p, FTM_EB_U * o[0], FTM_EB_U * o[1], FTM_EB_U * o[2], FTM_EB_U * o[3], x, y, z)
#define SELECT_BITS(m, a, b) ((EV)(((m) & (EL)(a)) | (~(m) & (EL)(b))))

/* Stores EW lanes' forces (x, y, z) as records (x, y, z) (ftm_eb_fe) of a
 * node's records p, the lanes from lane0 */
#define STOREF_LANES(p, lane0, x, y, z)                                                          \
    do {                                                                                         \
        for (int l_ = 0; l_ < EW; l_++) {                                                        \
            double *r_ = (p) + FTM_EB_REC * ((lane0) + l_);                                      \
            r_[0] = (x)[l_];                                                                     \
            r_[1] = (y)[l_];                                                                     \
            r_[2] = (z)[l_];                                                                     \
        }                                                                                        \
    } while (0)

#define EW 4
#define EV e4d
#define EL e4l
#define ETARGET
#define ENAME(f) portable_##f
#define ESELECT SELECT_BITS
#define EANY(m) ((m)[0] | (m)[1] | (m)[2] | (m)[3])
#define ELOADXYZ LOAD_XYZ4
#define ELOADU LOAD_U4
#define ESTOREF STOREF_LANES
#include "elem_block.inc"
#undef ESTOREF
#undef ETARGET
#undef ENAME
#undef ESELECT
#undef EANY

#if defined(__x86_64__) || defined(__i386__)
/* 4 lanes to 4 records (x, y, z): (x0 y0 z0 x1) (y1 z1 x2 y2) (z2 x3 y3 z3) */
static inline __attribute__((target("avx2"), always_inline)) void
avx2_storef(double *p, int lane0, e4d x, e4d y, e4d z)
{
    const __m256d X = (__m256d)x, Y = (__m256d)y, Z = (__m256d)z;
    const __m256d xy = _mm256_unpacklo_pd(X, Y),                             /* x0 y0 x2 y2 */
        yz = _mm256_unpackhi_pd(Y, Z),                                       /* y1 z1 y3 z3 */
        zx1 = _mm256_unpacklo_pd(Z, _mm256_permute4x64_pd(X, 0x55)),         /* z0 x1 z2 x1 */
        zx3 = _mm256_unpacklo_pd(Z, _mm256_permute4x64_pd(X, 0xff));         /* z0 x3 z2 x3 */
    double *r = p + FTM_EB_REC * lane0;
    _mm256_storeu_pd(r, _mm256_permute2f128_pd(xy, zx1, 0x20));     /* x0 y0 z0 x1 */
    _mm256_storeu_pd(r + 4, _mm256_permute2f128_pd(yz, xy, 0x30));  /* y1 z1 x2 y2 */
    _mm256_storeu_pd(r + 8, _mm256_permute2f128_pd(zx3, yz, 0x31)); /* z2 x3 y3 z3 */
}

#define ETARGET __attribute__((target("avx2")))
#define ENAME(f) avx2_##f
#define ESELECT(m, a, b) ((EV)_mm256_blendv_pd((__m256d)(b), (__m256d)(a), (__m256d)(m)))
#define EANY(m) (_mm256_movemask_pd((__m256d)(m)) != 0)
#define ESTOREF avx2_storef
#include "elem_block.inc"
#undef ESTOREF
#undef ETARGET
#undef ENAME
#undef ESELECT
#undef EANY
#undef ELOADXYZ
#undef ELOADU
#undef EW
#undef EV
#undef EL

/* 8 lanes: x, y, z of eight points (simd8.h) */
typedef v8d e8d;
typedef v8l e8l;

/* x, y, z of eight nodes' displacements (eb->u, rows of FTM_EB_U as the
 * coefficient rows: one 256-bit load each and a transpose) */
_Static_assert(FTM_EB_U == FTM_COEF, "load_u8 reads rows as load_coef8 does");
static inline AVX512 void load_u8(const double *p, const size_t o[8], e8d *x, e8d *y, e8d *z)
{
    e8d unused;
    load_coef8(p, o, x, y, z, &unused);
}

/* 8 lanes to 8 records (x, y, z), three stores: x and y interleaved by one
 * permute, z blended in by a masked one */
static inline __attribute__((target("avx512f"), always_inline)) void
avx512_storef(double *p, int lane0, e8d x, e8d y, e8d z)
{
    (void)lane0; /* (0: a block is one vector) */
    const __m512d X = (__m512d)x, Y = (__m512d)y, Z = (__m512d)z;
    /* (_mm512_set_epi64 lists elements 7 .. 0) */
    const __m512d a0 = _mm512_permutex2var_pd(X, _mm512_set_epi64(10, 2, 0, 9, 1, 0, 8, 0), Y),
                  a1 = _mm512_permutex2var_pd(X, _mm512_set_epi64(5, 0, 12, 4, 0, 11, 3, 0), Y),
                  a2 = _mm512_permutex2var_pd(X, _mm512_set_epi64(0, 15, 7, 0, 14, 6, 0, 13), Y);
    _mm512_storeu_pd(p, _mm512_mask_permutexvar_pd(a0, 0x24, _mm512_set_epi64(0, 0, 1, 0, 0, 0, 0, 0),
                                                   Z)); /* x0 y0 z0 x1 y1 z1 x2 y2 */
    _mm512_storeu_pd(p + 8, _mm512_mask_permutexvar_pd(
                                a1, 0x49, _mm512_set_epi64(0, 4, 0, 0, 3, 0, 0, 2),
                                Z)); /* z2 x3 y3 z3 x4 y4 z4 x5 */
    _mm512_storeu_pd(p + 16, _mm512_mask_permutexvar_pd(
                                 a2, 0x92, _mm512_set_epi64(7, 0, 0, 6, 0, 0, 5, 0),
                                 Z)); /* y5 z5 x6 y6 z6 x7 y7 z7 */
}

#define EW 8
#define EV e8d
#define EL e8l
#define ETARGET __attribute__((target("avx512f")))
#define ENAME(f) avx512_##f
#define ESELECT SELECT_BITS /* (a ternary logic instruction) */
#define EANY(m) (_mm512_test_epi64_mask((__m512i)(m), (__m512i)(m)) != 0)
#define ELOADXYZ load_xyz8
#define ELOADU load_u8
#define ESTOREF avx512_storef
#include "elem_block.inc"
#undef ESTOREF
#undef ETARGET
#undef ENAME
#undef ESELECT
#undef EANY
#undef ELOADXYZ
#undef ELOADU
#endif
#undef EW
#undef EV
#undef EL

ftm_blocks_fn ftm_blocks_kernel(ftm_elem_kind kind, ftm_elem_kernel which, int *lanes)
{
    const bool neo = kind == FTM_EK_NEO;
    *lanes = 4;
#if defined(__x86_64__) || defined(__i386__)
    if (which == FTM_ELEM_KERNEL_BEST && __builtin_cpu_supports("avx512f")) {
        *lanes = 8;
        return neo ? avx512_neo_blocks : avx512_corot_blocks;
    }
    if (which != FTM_ELEM_KERNEL_PORTABLE && __builtin_cpu_supports("avx2"))
        return neo ? avx2_neo_blocks : avx2_corot_blocks;
#else
    (void)which;
#endif
    return neo ? portable_neo_blocks : portable_corot_blocks;
}
