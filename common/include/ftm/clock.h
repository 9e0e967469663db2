/* SPDX-License-Identifier: GPL-3.0-or-later */
/* The clocks of the programs around the core, in nanoseconds: one pair for
 * every program instead of a helper in each. The physics never reads a clock
 * (its results depend on its inputs alone); servers, clients and benchmarks
 * time, schedule and stamp with these.
 *
 *   monotonic: intervals, deadlines, rates (never jumps with the wall clock)
 *   realtime:  times another process or host compares (send times, the
 *              start of a server process, file names)
 */
#ifndef FTM_CLOCK_H
#define FTM_CLOCK_H

#include <stdint.h>

#ifdef __cplusplus
extern "C" {
#endif

#define FTM_NS_PER_S 1000000000LL

/* CLOCK_MONOTONIC [ns]. */
int64_t ftm_clock_mono_ns(void);
/* CLOCK_REALTIME [ns since the Unix epoch]. */
int64_t ftm_clock_real_ns(void);

#ifdef __cplusplus
}
#endif
#endif
