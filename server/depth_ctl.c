/* SPDX-License-Identifier: GPL-3.0-or-later */
/* Adaptive penetration depth: the control law of depth_ctl.h. */
#include "depth_ctl.h"

#include <stdio.h>
#include <string.h>

void ftm_depth_ctl_default(ftm_depth_ctl_def *d, int32_t floor, int32_t max, double budget_ns)
{
    *d = (ftm_depth_ctl_def){
        .floor = floor,
        .max = max,
        .budget_ns = budget_ns,
        .step_high = 0.8,
        .step_low = 0.5,
        .replay_high = 0.8,
        .replay_low = 0.5,
        .lag_high = 40,
        .lag_low = 10,
        .backlog_high = 64,
        .rexmit_high = 0.5,
        .down_step = 2,
        .up_step = 1,
        .hold_down_ns = 300000000,
        .hold_up_ns = 2000000000,
        .noise_pct = 20,
    };
}

static int fail(ftm_error *err, const char *what)
{
    if (err) {
        err->code = FTM_EINVAL;
        snprintf(err->message, sizeof err->message, "depth controller: %s", what);
    }
    return FTM_EINVAL;
}

int ftm_depth_ctl_init(ftm_depth_ctl *ctl, const ftm_depth_ctl_def *d, ftm_error *err)
{
    if (!ctl || !d)
        return fail(err, "NULL argument");
    if (d->floor < 0 || d->floor > d->max || d->max > FTM_DEPTH_CTL_MAX)
        return fail(err, "need 0 <= floor <= max <= 1000000");
    if (!(d->budget_ns > 0))
        return fail(err, "budget_ns must be > 0");
    if (!(d->step_low >= 0 && d->step_low < d->step_high) ||
        !(d->replay_low >= 0 && d->replay_low < d->replay_high))
        return fail(err, "need 0 <= step_low < step_high and 0 <= replay_low < replay_high");
    if (d->lag_low < 0 || d->lag_low >= d->lag_high)
        return fail(err, "need 0 <= lag_low < lag_high");
    if (d->backlog_high < 1 || !(d->rexmit_high > 0))
        return fail(err, "backlog_high and rexmit_high must be > 0");
    if (d->down_step < 1 || d->up_step < 1)
        return fail(err, "down_step and up_step must be >= 1");
    if (d->hold_down_ns < 0 || d->hold_up_ns < 0)
        return fail(err, "hold times must be >= 0");
    if (d->noise_pct < 0 || d->noise_pct > 50)
        return fail(err, "noise_pct must be in 0..50");
    memset(ctl, 0, sizeof *ctl);
    ctl->def = *d;
    ctl->depth = d->max;
    ctl->last_change_ns = INT64_MIN;
    ctl->calm_since_ns = INT64_MIN;
    return FTM_OK;
}

static bool elapsed(int64_t since, int64_t now, int64_t span)
{
    return since == INT64_MIN || now - since >= span;
}

/* The first overload signal, by priority, as text; false if none. */
static bool overload(const ftm_depth_ctl_def *d, const ftm_depth_ctl_input *in, char *why,
                     size_t size)
{
    double budget_ms = d->budget_ns * 1e-6;
    if (in->missed_ticks > 0) {
        snprintf(why, size, "%llu ticks missed", (unsigned long long)in->missed_ticks);
        return true;
    }
    if (in->step_ns > d->step_high * d->budget_ns) {
        snprintf(why, size, "step %.3f ms > %.2g of budget %.3g ms", in->step_ns * 1e-6,
                 d->step_high, budget_ms);
        return true;
    }
    const ftm_depth_ctl_part *worst = NULL;
    for (int32_t i = 0; i < in->nparts; i++)
        if (in->parts[i].lag > d->lag_high && (!worst || in->parts[i].lag > worst->lag))
            worst = &in->parts[i];
    if (worst) {
        snprintf(why, size, "participant %u (%s) lag %lld ticks > %d", worst->id,
                 worst->role ? worst->role : "?", (long long)worst->lag, (int)d->lag_high);
        return true;
    }
    for (int32_t i = 0; i < in->nparts; i++)
        if (in->parts[i].replay_ns > d->replay_high * d->budget_ns) {
            snprintf(why, size, "participant %u (%s) replay %.3f ms/tick > %.2g of budget",
                     in->parts[i].id, in->parts[i].role ? in->parts[i].role : "?",
                     in->parts[i].replay_ns * 1e-6, d->replay_high);
            return true;
        }
    if (in->backlog > d->backlog_high) {
        snprintf(why, size, "%d frames queued for DDS > %d", (int)in->backlog,
                 (int)d->backlog_high);
        return true;
    }
    if (in->throttled > 0) {
        snprintf(why, size, "DDS writer throttled %llu times",
                 (unsigned long long)in->throttled);
        return true;
    }
    if (in->rexmit_ratio > d->rexmit_high) {
        snprintf(why, size, "retransmitted %.2f x the bytes sent > %.2g", in->rexmit_ratio,
                 d->rexmit_high);
        return true;
    }
    return false;
}

static bool calm(const ftm_depth_ctl_def *d, const ftm_depth_ctl_input *in)
{
    if (in->step_ns >= d->step_low * d->budget_ns)
        return false;
    for (int32_t i = 0; i < in->nparts; i++)
        if (in->parts[i].lag >= d->lag_low || in->parts[i].replay_ns >= d->replay_low * d->budget_ns)
            return false;
    return in->backlog * 4 < d->backlog_high && in->throttled == 0 &&
           in->rexmit_ratio * 4.0 < d->rexmit_high;
}

static int32_t change(ftm_depth_ctl *ctl, int32_t to, int64_t now, bool *changed, char *reason,
                      size_t size, const char *why)
{
    snprintf(reason, size, "%d -> %d: %s", (int)ctl->depth, (int)to, why);
    if (to < ctl->depth)
        ctl->decreases++;
    else
        ctl->increases++;
    ctl->changes++;
    ctl->depth = to;
    ctl->last_change_ns = now;
    *changed = true;
    return to;
}

int32_t ftm_depth_ctl_update(ftm_depth_ctl *ctl, const ftm_depth_ctl_input *in, bool *changed,
                             char *reason, size_t reason_size)
{
    const ftm_depth_ctl_def *d = &ctl->def;
    int64_t now = in->now_ns;
    char why[FTM_DEPTH_REASON_MAX];
    *changed = false;
    if (reason_size)
        reason[0] = '\0';
    if (overload(d, in, why, sizeof why)) {
        ctl->calm_since_ns = INT64_MIN;
        snprintf(reason, reason_size, "%s", why); /* also when it cannot act */
        if (ctl->depth > d->floor && elapsed(ctl->last_change_ns, now, d->hold_down_ns)) {
            int32_t to = ctl->depth - d->down_step;
            return change(ctl, to < d->floor ? d->floor : to, now, changed, reason, reason_size,
                          why);
        }
        return ctl->depth;
    }
    bool quiet = calm(d, in);
    if (ctl->calm_since_ns == INT64_MIN) {
        if (!quiet) /* the dead band: neither way */
            return ctl->depth;
        ctl->calm_since_ns = now; /* a window starts with a calm period */
        ctl->calm_periods = ctl->noisy_periods = 0;
    }
    ctl->calm_periods++;
    if (!quiet) {
        ctl->noisy_periods++;
        if ((int64_t)ctl->noisy_periods * 100 > (int64_t)d->noise_pct * ctl->calm_periods)
            ctl->calm_since_ns = INT64_MIN; /* too noisy to call calm */
        return ctl->depth; /* no increase on a noisy period in any case */
    }
    if (ctl->depth < d->max && now - ctl->calm_since_ns >= d->hold_up_ns &&
        elapsed(ctl->last_change_ns, now, d->hold_up_ns)) {
        int64_t worst = 0;
        for (int32_t i = 0; i < in->nparts; i++)
            if (in->parts[i].lag > worst)
                worst = in->parts[i].lag;
        snprintf(why, sizeof why,
                 "calm for %.1f s (%d of %d periods quiet; step %.3f ms < %.3g ms, worst lag %lld ticks)",
                 (double)(now - ctl->calm_since_ns) * 1e-9, (int)(ctl->calm_periods - ctl->noisy_periods),
                 (int)ctl->calm_periods, in->step_ns > 0 ? in->step_ns * 1e-6 : 0.0,
                 d->step_low * d->budget_ns * 1e-6, (long long)worst);
        int32_t to = ctl->depth + d->up_step;
        return change(ctl, to > d->max ? d->max : to, now, changed, reason, reason_size, why);
    }
    return ctl->depth;
}

int ftm_depth_ctl_set_limits(ftm_depth_ctl *ctl, int32_t floor, int32_t max, int64_t now_ns,
                             bool *changed, char *reason, size_t reason_size, ftm_error *err)
{
    *changed = false;
    if (reason_size)
        reason[0] = '\0';
    if (floor < 0 || floor > max || max > FTM_DEPTH_CTL_MAX)
        return fail(err, "depth limits need 0 <= min <= max <= 1000000");
    ctl->def.floor = floor;
    ctl->def.max = max;
    char why[FTM_DEPTH_REASON_MAX];
    snprintf(why, sizeof why, "limits now [%d, %d]", (int)floor, (int)max);
    if (ctl->depth < floor)
        change(ctl, floor, now_ns, changed, reason, reason_size, why);
    else if (ctl->depth > max)
        change(ctl, max, now_ns, changed, reason, reason_size, why);
    return FTM_OK;
}
