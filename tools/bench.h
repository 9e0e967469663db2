/* SPDX-License-Identifier: GPL-3.0-or-later */
/* Benchmarks of `ftm bench` and the timing helpers they share. */
#ifndef FTM_TOOLS_BENCH_H
#define FTM_TOOLS_BENCH_H

#include "ftm/ftm.h"

#include <stdbool.h>
#include <stdint.h>
#include <stdio.h>
#include <time.h>

int ftm_bench_table3(int argc, char **argv);
int ftm_bench_accuracy(int argc, char **argv); /* only with FTM_HAVE_FEM */
int ftm_bench_feel(int argc, char **argv);     /* only with FTM_HAVE_FEM */
int ftm_bench_peers(int argc, char **argv);    /* against Bullet when FTM_HAVE_BULLET */

/* `ftm bench accuracy --speed` (bench_speed.c): the step of every force
 * model on one body, alternating in one run. */
typedef struct ftm_speed_def {
    const char *name;
    const ftm_mesh *mesh; /* hexahedra (a tetrahedral twin is made from them) */
    const ftm_contact *contacts;
    int32_t ncontacts, depth;
    double young, poisson;
    int rounds, steps, warmup;
    const char *only; /* NULL, or springs and this model ("tetrahedra neo-hookean", ...) */
} ftm_speed_def;
int ftm_bench_speed(const ftm_speed_def *d, FILE *out, bool json);

static inline double ftm_bench_now_us(void)
{
    struct timespec ts;
    clock_gettime(CLOCK_MONOTONIC, &ts);
    return (double)ts.tv_sec * 1e6 + (double)ts.tv_nsec * 1e-3;
}

/* Median of n samples (sorts them in place). */
double ftm_bench_median(double *v, int n);

#endif
