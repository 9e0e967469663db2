/* SPDX-License-Identifier: GPL-3.0-or-later */
/* Adaptive penetration depth (docs/server.md, "Adaptive penetration depth").
 *
 * The depth n decides how many layers around a contact the simulation
 * updates, so it sets the cost of a tick for the server and for every
 * replica. This controller lowers n when someone cannot keep up and raises it
 * back toward the scene's calibrated optimum when everyone can:
 *
 *   overload (any of): server step time > step_high x budget, ticks missed,
 *     a participant's lag > lag_high ticks, a participant's replay time per
 *     tick > replay_high x budget, frames waiting in the publishing queue >
 *     backlog_high, the DDS writer throttled, retransmitted bytes >
 *     rexmit_high x bytes sent to all readers;
 *   calm (all of): every signal below its *low* threshold;
 *   in between: nothing happens (the dead band).
 *
 * Overload lowers n by down_step (not below the floor) at most once per
 * hold_down; n goes up by up_step only after a calm window of hold_up and
 * hold_up since the last change. A calm window has no overload and at most
 * noise_pct percent of its periods in the dead band: on a busy host an
 * occasional period just above a low threshold (a late status, one slow
 * tick) must not hold the depth down for good, while a real overload still
 * ends the window at once. Separate thresholds, the dead band and the
 * asymmetric hold times keep a noisy signal from making n oscillate.
 *
 * Pure logic: no clock, no I/O; the caller passes the time and the
 * measurements of each period and logs the returned reason. */
#ifndef FTM_SERVER_DEPTH_CTL_H
#define FTM_SERVER_DEPTH_CTL_H

#include "ftm/base.h"

#include <stdbool.h>
#include <stddef.h>
#include <stdint.h>

#define FTM_DEPTH_REASON_MAX 160

typedef struct ftm_depth_ctl_def {
    int32_t floor, max;             /* depth range, 0 <= floor <= max */
    double budget_ns;               /* the tick period */
    double step_high, step_low;     /* server step time, fractions of the budget */
    double replay_high, replay_low; /* a participant's replay time per tick, same */
    int32_t lag_high, lag_low;      /* a participant's lag [ticks] */
    int32_t backlog_high;           /* frames queued for DDS; calm below a quarter */
    double rexmit_high;             /* retransmitted / (bytes sent x readers); calm below a quarter */
    int32_t down_step, up_step;     /* depth change per decision, >= 1 */
    int64_t hold_down_ns;           /* minimum time between a change and a decrease */
    int64_t hold_up_ns;             /* calm time (and time since a change) before an increase */
    int32_t noise_pct;              /* dead-band periods a calm window tolerates, 0..50 % */
} ftm_depth_ctl_def;

/* The defaults for a depth range and tick budget: thresholds 0.8/0.5 of the
 * budget, lag 40/10 ticks, backlog 64, rexmit 0.5, steps 2 down / 1 up,
 * hold 0.3 s down / 2 s up, 20 % noise in a calm window. */
void ftm_depth_ctl_default(ftm_depth_ctl_def *def, int32_t floor, int32_t max, double budget_ns);

/* One participant's measurements in a period. */
typedef struct ftm_depth_ctl_part {
    uint32_t id;
    const char *role;     /* for the reason text, e.g. "trainee" */
    int64_t lag;          /* ticks behind the server */
    double replay_ns;     /* its replay time per tick (0: unknown) */
} ftm_depth_ctl_part;

/* The measurements of one period (e.g. 100 ms). */
typedef struct ftm_depth_ctl_input {
    int64_t now_ns;
    double step_ns;          /* mean server tick time in the period; < 0: no tick ran */
    uint64_t missed_ticks;   /* ticks the server skipped in the period */
    int32_t backlog;         /* frames waiting in the publishing queue */
    uint64_t throttled;      /* writer throttle events in the period */
    double rexmit_ratio;     /* retransmitted / sent bytes in the period */
    int32_t nparts;
    const ftm_depth_ctl_part *parts;
} ftm_depth_ctl_input;

typedef struct ftm_depth_ctl {
    ftm_depth_ctl_def def;
    int32_t depth;
    int64_t last_change_ns; /* INT64_MIN: never */
    int64_t calm_since_ns;  /* INT64_MIN: not calm */
    int32_t calm_periods;   /* periods since calm_since_ns ... */
    int32_t noisy_periods;  /* ... and those of them in the dead band */
    uint64_t changes, decreases, increases;
} ftm_depth_ctl;

/* Checks def (FTM_EINVAL naming the bad field) and starts at def->max. */
int ftm_depth_ctl_init(ftm_depth_ctl *ctl, const ftm_depth_ctl_def *def, ftm_error *err);

/* One decision. Returns the depth to use from now on; when it changed,
 * *changed is true and reason says why, e.g.
 * "8 -> 6: participant 12 (observer) lag 45 ticks > 40". On an overload it
 * cannot act on (at the floor, or within hold_down) reason names the
 * overload ("participant 12 (observer) lag 45 ticks > 40") and *changed is
 * false; otherwise reason is empty. */
int32_t ftm_depth_ctl_update(ftm_depth_ctl *ctl, const ftm_depth_ctl_input *in, bool *changed,
                             char *reason, size_t reason_size);

/* New limits (the instructor's DepthLimits): the depth is clamped into them
 * at once (*changed and reason as above). FTM_EINVAL (limits unchanged)
 * unless 0 <= floor <= max <= FTM_DEPTH_CTL_MAX. */
#define FTM_DEPTH_CTL_MAX 1000000
int ftm_depth_ctl_set_limits(ftm_depth_ctl *ctl, int32_t floor, int32_t max, int64_t now_ns,
                             bool *changed, char *reason, size_t reason_size, ftm_error *err);

#endif
