/* SPDX-License-Identifier: GPL-3.0-or-later */
/* ftm/clock.h: the programs' clocks. */
#include "ftm/clock.h"

#include <time.h>

static int64_t ns_of(clockid_t id)
{
    struct timespec ts;
    clock_gettime(id, &ts);
    return (int64_t)ts.tv_sec * FTM_NS_PER_S + ts.tv_nsec;
}

int64_t ftm_clock_mono_ns(void) { return ns_of(CLOCK_MONOTONIC); }

int64_t ftm_clock_real_ns(void) { return ns_of(CLOCK_REALTIME); }
