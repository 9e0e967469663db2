/* Benchmarks of `ftm bench` and the timing helpers they share. */
#ifndef FTM_TOOLS_BENCH_H
#define FTM_TOOLS_BENCH_H

#include <stdint.h>
#include <time.h>

int ftm_bench_table3(int argc, char **argv);
int ftm_bench_accuracy(int argc, char **argv); /* only with FTM_HAVE_FEM */
int ftm_bench_feel(int argc, char **argv);     /* only with FTM_HAVE_FEM */
int ftm_bench_peers(int argc, char **argv);    /* against Bullet when FTM_HAVE_BULLET */

static inline double ftm_bench_now_us(void)
{
    struct timespec ts;
    clock_gettime(CLOCK_MONOTONIC, &ts);
    return (double)ts.tv_sec * 1e6 + (double)ts.tv_nsec * 1e-3;
}

/* Median of n samples (sorts them in place). */
double ftm_bench_median(double *v, int n);

#endif
