/* The element block kernels (elem_kernel.h): elem_block.inc compiled for
 * 4 portable lanes, 4 lanes of AVX2 and 8 of AVX-512, chosen at run time as
 * the spring kernel is (sim_kernel.c). */
#include "elem_kernel.h"

#include "hyperelastic.h"

#include <math.h>
#include <string.h>

/* the helpers of elem_block.inc pass vectors by value; all are inlined */
#if defined(__GNUC__) && !defined(__clang__)
#pragma GCC diagnostic ignored "-Wpsabi"
#endif

typedef double e4d __attribute__((vector_size(32)));
typedef int64_t e4l __attribute__((vector_size(32)));

#define EW 4
#define EV e4d
#define EL e4l
#define ETARGET
#define ENAME(f) portable_##f
#include "elem_block.inc"
#undef ETARGET
#undef ENAME

#if defined(__x86_64__) || defined(__i386__)
#define ETARGET __attribute__((target("avx2")))
#define ENAME(f) avx2_##f
#include "elem_block.inc"
#undef ETARGET
#undef ENAME
#undef EW
#undef EV
#undef EL

typedef double e8d __attribute__((vector_size(64)));
typedef int64_t e8l __attribute__((vector_size(64)));
#define EW 8
#define EV e8d
#define EL e8l
#define ETARGET __attribute__((target("avx512f")))
#define ENAME(f) avx512_##f
#include "elem_block.inc"
#undef ETARGET
#undef ENAME
#endif
#undef EW
#undef EV
#undef EL

ftm_neo_blocks_fn ftm_neo_blocks_kernel(ftm_elem_kernel which, int *lanes)
{
    *lanes = 4;
#if defined(__x86_64__) || defined(__i386__)
    if (which == FTM_ELEM_KERNEL_BEST && __builtin_cpu_supports("avx512f")) {
        *lanes = 8;
        return avx512_neo_blocks;
    }
    if (which != FTM_ELEM_KERNEL_PORTABLE && __builtin_cpu_supports("avx2"))
        return avx2_neo_blocks;
#else
    (void)which;
#endif
    return portable_neo_blocks;
}
