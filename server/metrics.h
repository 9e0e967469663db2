/* SPDX-License-Identifier: GPL-3.0-or-later */
/* Prometheus metrics of ftm-server over HTTP, on 127.0.0.1 unless told (libmicrohttpd;
 * docs/server.md, "Metrics"). The tick thread hands a snapshot over with
 * ftm_metrics_update (copied under a mutex, every 100 ms); the HTTP thread
 * renders the text format from its own copy, so a slow scraper never
 * touches the tick. */
#ifndef FTM_SERVER_METRICS_H
#define FTM_SERVER_METRICS_H

#include "ftm/base.h"

#include <stdint.h>

#define FTM_METRICS_PARTS 64
/* Upper bounds of the step-time histogram buckets [s] (+Inf is implicit). */
#define FTM_METRICS_STEP_BUCKETS 9
extern const double ftm_metrics_step_bounds[FTM_METRICS_STEP_BUCKETS];

typedef struct ftm_metrics_part {
    uint32_t id;
    char role[16];
    char state[16];
    int64_t lag;       /* ticks behind */
    double replay_ns;  /* its replay time per tick */
} ftm_metrics_part;

typedef struct ftm_metrics_snapshot {
    double tick_rate_target; /* configured [Hz] */
    double tick_rate;        /* measured over the last second [Hz] */
    uint64_t ticks, missed_ticks, idle_ticks;
    uint64_t frames, heartbeats, keyframes;
    uint64_t bytes_frames, bytes_keyframes, publish_fail;
    uint64_t rexmit_bytes, throttle_count;
    int32_t depth, depth_min, depth_max;
    uint64_t depth_decreases, depth_increases;
    uint64_t step_count;           /* ticks timed */
    double step_sum_s;             /* their total time */
    uint64_t step_bucket[FTM_METRICS_STEP_BUCKETS + 1]; /* per bucket (not cumulative); last = +Inf */
    double step_last_period_s;     /* mean step time of the last 100 ms */
    uint64_t inputs_rejected;
    uint64_t push_limited;   /* probe-ticks whose push was shortened to the limit */
    uint64_t unstable_ticks; /* steps the guard could not save: tissue reset */
    uint64_t record_bytes;
    uint64_t slow_closed;    /* metrics connections shut for missing the deadline (filled by
                              * the metrics thread) */
    bool record_ok;          /* 0: the recording asked for has stopped on an error */
    uint64_t record_errors;
    uint64_t record_files;      /* files begun after a write error (space returned) */
    uint64_t record_free_bytes; /* after a full disk: free bytes at the last look; 0: none */
    int32_t nparts;
    ftm_metrics_part parts[FTM_METRICS_PARTS];
} ftm_metrics_snapshot;

typedef struct ftm_metrics ftm_metrics;

/* Serves http://addr:port/metrics from a thread of libmicrohttpd; addr is an
 * IPv4 or IPv6 address (NULL: 127.0.0.1). */
int ftm_metrics_start(const char *addr, uint16_t port, ftm_metrics **out, ftm_error *err);
void ftm_metrics_update(ftm_metrics *m, const ftm_metrics_snapshot *s);
/* The text exposition of s into buf (for tests and the handler); returns the
 * length it needs (like snprintf). */
size_t ftm_metrics_render(const ftm_metrics_snapshot *s, char *buf, size_t size);
void ftm_metrics_stop(ftm_metrics *m); /* NULL is fine */

#endif
