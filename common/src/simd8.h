/* SPDX-License-Identifier: GPL-3.0-or-later */
/* Internal: the 8-lane loads of the AVX-512 kernels (sim_kernel.c,
 * elem_kernel.c): x, y, z of eight points, padded rows' (k, len) pairs and
 * the nodes' coefficient rows as vectors in lane order. Only for x86 builds; a caller
 * runs them only where the processor has AVX-512. */
#ifndef FTM_SRC_SIMD8_H
#define FTM_SRC_SIMD8_H

#if defined(__x86_64__) || defined(__i386__)
#include "sim_internal.h"

#include <immintrin.h>
#include <stddef.h>
#include <stdint.h>

typedef double v8d __attribute__((vector_size(64)));
typedef int64_t v8l __attribute__((vector_size(64)));
#define GATHER8(p, i) ((v8d){(p)[i[0]], (p)[i[1]], (p)[i[2]], (p)[i[3]], (p)[i[4]], (p)[i[5]], \
                             (p)[i[6]], (p)[i[7]]})
#define LO4(v) __builtin_shufflevector((v), (v), 0, 1, 2, 3)
#define HI4(v) __builtin_shufflevector((v), (v), 4, 5, 6, 7)

/* The 8-lane loads are written with intrinsics: built from vector
 * extensions, GCC 12 padded each 4 + 4 concatenation with a register move
 * and a 512-bit shuffle, and the kernel's time follows its loads' vector
 * operations more than its square roots and divisions (docs/benchmarks.md):
 * these loads took it from 16.3 to 15.1-15.6 us cached at depth 20 of
 * Table 3, bit-identical. */
#define AVX512 __attribute__((target("avx512f"), always_inline))

/* the 128-bit pairs at a, b, c and d, in that order */
static inline AVX512 __m512d pairs4(const double *a, const double *b, const double *c,
                                    const double *d)
{
    const __m256d lo =
        _mm256_insertf128_pd(_mm256_castpd128_pd256(_mm_loadu_pd(a)), _mm_loadu_pd(b), 1);
    const __m256d hi =
        _mm256_insertf128_pd(_mm256_castpd128_pd256(_mm_loadu_pd(c)), _mm_loadu_pd(d), 1);
    return _mm512_insertf64x4(_mm512_castpd256_pd512(lo), hi, 1);
}

/* x, y and z of the eight points p + o[0..7]: the (x, y) pairs of the even
 * and the odd points interleave into x, their (y, z) pairs into y and z */
static inline AVX512 void load_xyz8(const double *p, const size_t o[8], v8d *x, v8d *y, v8d *z)
{
    const __m512d xy0 = pairs4(p + o[0], p + o[2], p + o[4], p + o[6]),
                  xy1 = pairs4(p + o[1], p + o[3], p + o[5], p + o[7]),
                  yz0 = pairs4(p + o[0] + 1, p + o[2] + 1, p + o[4] + 1, p + o[6] + 1),
                  yz1 = pairs4(p + o[1] + 1, p + o[3] + 1, p + o[5] + 1, p + o[7] + 1);
    *x = (v8d)_mm512_unpacklo_pd(xy0, xy1);
    *y = (v8d)_mm512_unpacklo_pd(yz0, yz1);
    *z = (v8d)_mm512_unpackhi_pd(yz0, yz1);
}

/* x and y of the eight points p + o[0..7] (a planar sweep's loads) */
static inline AVX512 void load_xy8(const double *p, const size_t o[8], v8d *x, v8d *y)
{
    const __m512d xy0 = pairs4(p + o[0], p + o[2], p + o[4], p + o[6]),
                  xy1 = pairs4(p + o[1], p + o[3], p + o[5], p + o[7]);
    *x = (v8d)_mm512_unpacklo_pd(xy0, xy1);
    *y = (v8d)_mm512_unpackhi_pd(xy0, xy1);
}

/* the (k, len) pairs of eight padded rows at slot sl, as k and len vectors */
static inline AVX512 void load_kl8(const double *const kl[8], int32_t sl, v8d *k, v8d *len)
{
    const size_t e = 2 * (size_t)sl;
    const __m512d p0 = pairs4(kl[0] + e, kl[2] + e, kl[4] + e, kl[6] + e),
                  p1 = pairs4(kl[1] + e, kl[3] + e, kl[5] + e, kl[7] + e);
    *k = (v8d)_mm512_unpacklo_pd(p0, p1);
    *len = (v8d)_mm512_unpackhi_pd(p0, p1);
}

/* the coefficient rows (a, b, c, lim2) of nodes on[0..7] as vectors: the
 * rows of lanes l and l + 4 share a 512-bit register, unpacked into (a, c)
 * and (b, lim2) pairs, which two-source permutes put in lane order */
static inline AVX512 void load_coef8(const double *p, const size_t on[8], v8d *a, v8d *b, v8d *c,
                                     v8d *lim2)
{
    __m512d r[4];
    for (int l = 0; l < 4; l++)
        r[l] = _mm512_insertf64x4(_mm512_castpd256_pd512(_mm256_loadu_pd(p + FTM_COEF * on[l])),
                                  _mm256_loadu_pd(p + FTM_COEF * on[l + 4]), 1);
    const __m512d ac01 = _mm512_unpacklo_pd(r[0], r[1]), bl01 = _mm512_unpackhi_pd(r[0], r[1]),
                  ac23 = _mm512_unpacklo_pd(r[2], r[3]), bl23 = _mm512_unpackhi_pd(r[2], r[3]);
    /* elements 0, 1 of a pair, then 8, 9 (the other source), then 4, 5, 12, 13 */
    const __m512i first = _mm512_set_epi64(13, 12, 5, 4, 9, 8, 1, 0),
                  second = _mm512_set_epi64(15, 14, 7, 6, 11, 10, 3, 2);
    *a = (v8d)_mm512_permutex2var_pd(ac01, first, ac23);
    *c = (v8d)_mm512_permutex2var_pd(ac01, second, ac23);
    *b = (v8d)_mm512_permutex2var_pd(bl01, first, bl23);
    *lim2 = (v8d)_mm512_permutex2var_pd(bl01, second, bl23);
}

#endif
#endif
