/* SPDX-License-Identifier: GPL-3.0-or-later */
/* Adaptive penetration depth controller (server/depth_ctl.h): overload,
 * recovery, noise around the thresholds, instructor limits. Pure logic: the
 * tests drive it with synthetic measurements every 100 ms. */
#include "depth_ctl.h"

#include <setjmp.h>
#include <stdarg.h>
#include <stddef.h>
#include <stdint.h>
#include <string.h>

#include <cmocka.h>

#define PERIOD_NS 100000000LL /* one decision per 100 ms, as the server */
#define BUDGET_NS 1000000.0   /* 1 kHz */

typedef struct run {
    ftm_depth_ctl ctl;
    int64_t now;
    int32_t min_seen, max_seen;
    int reversals; /* direction changes: down then up or up then down */
    int last_dir;
    int64_t last_change;
    int64_t min_gap_down, min_gap_up; /* shortest time between changes, by direction */
    char last_reason[FTM_DEPTH_REASON_MAX];
} run;

static void start(run *r, int32_t floor, int32_t max)
{
    ftm_depth_ctl_def d;
    ftm_depth_ctl_default(&d, floor, max, BUDGET_NS);
    ftm_error err = {0, ""};
    assert_int_equal(ftm_depth_ctl_init(&r->ctl, &d, &err), FTM_OK);
    assert_int_equal(r->ctl.depth, max);
    r->now = 0;
    r->min_seen = r->max_seen = max;
    r->reversals = r->last_dir = 0;
    r->last_change = INT64_MIN;
    r->min_gap_down = r->min_gap_up = INT64_MAX;
    r->last_reason[0] = '\0';
}

/* One period with the given server step time and participants. */
static int32_t period(run *r, double step_ns, const ftm_depth_ctl_part *parts, int32_t nparts)
{
    r->now += PERIOD_NS;
    ftm_depth_ctl_input in = {r->now, step_ns, 0, 0, 0, 0.0, nparts, parts};
    bool changed = false;
    char reason[FTM_DEPTH_REASON_MAX];
    int32_t before = r->ctl.depth;
    int32_t d = ftm_depth_ctl_update(&r->ctl, &in, &changed, reason, sizeof reason);
    assert_int_equal(d, r->ctl.depth);
    assert_true(d >= r->ctl.def.floor && d <= r->ctl.def.max);
    assert_int_equal(changed, d != before);
    if (changed) {
        assert_true(reason[0] != '\0');
        strcpy(r->last_reason, reason);
        int dir = d > before ? 1 : -1;
        if (r->last_dir && dir != r->last_dir)
            r->reversals++;
        r->last_dir = dir;
        if (r->last_change != INT64_MIN) {
            int64_t gap = r->now - r->last_change;
            if (dir < 0 && gap < r->min_gap_down)
                r->min_gap_down = gap;
            if (dir > 0 && gap < r->min_gap_up)
                r->min_gap_up = gap;
        }
        r->last_change = r->now;
    }
    if (d < r->min_seen)
        r->min_seen = d;
    if (d > r->max_seen)
        r->max_seen = d;
    return d;
}

static void overload_to_floor_and_no_lower(void **state)
{
    (void)state;
    run r;
    start(&r, 2, 10);
    for (int i = 0; i < 100; i++) /* 10 s at 0.9 of the budget */
        period(&r, 0.9 * BUDGET_NS, NULL, 0);
    assert_int_equal(r.ctl.depth, 2);
    assert_int_equal(r.min_seen, 2);
    assert_int_equal(r.ctl.decreases, 4); /* 10 -> 8 -> 6 -> 4 -> 2 */
    {   /* at the floor it still says what it would do something about */
        ftm_depth_ctl_input in = {r.now + PERIOD_NS, 0.9 * BUDGET_NS, 0, 0, 0, 0.0, 0, NULL};
        bool changed = true;
        char reason[FTM_DEPTH_REASON_MAX];
        assert_int_equal(ftm_depth_ctl_update(&r.ctl, &in, &changed, reason, sizeof reason), 2);
        assert_false(changed);
        assert_string_equal(reason, "step 0.900 ms > 0.8 of budget 1 ms");
        in.now_ns += PERIOD_NS;
        in.step_ns = 0.6 * BUDGET_NS; /* dead band: nothing to say */
        ftm_depth_ctl_update(&r.ctl, &in, &changed, reason, sizeof reason);
        assert_string_equal(reason, "");
        r.now = in.now_ns;
    }
    assert_int_equal(r.ctl.increases, 0);
    assert_true(r.min_gap_down >= r.ctl.def.hold_down_ns);
    assert_non_null(strstr(r.last_reason, "step 0.900 ms > 0.8 of budget"));
    /* an odd range: the last step stops at the floor */
    start(&r, 3, 10);
    for (int i = 0; i < 100; i++)
        period(&r, 2.0 * BUDGET_NS, NULL, 0);
    assert_int_equal(r.ctl.depth, 3);
    assert_int_equal(r.ctl.decreases, 4); /* 10, 8, 6, 4, 3 */
}

static void recovery_back_to_max(void **state)
{
    (void)state;
    run r;
    start(&r, 2, 10);
    for (int i = 0; i < 30; i++)
        period(&r, 0.95 * BUDGET_NS, NULL, 0);
    assert_int_equal(r.ctl.depth, 2);
    int64_t calm_start = r.now;
    int64_t reached = -1;
    for (int i = 0; i < 300 && reached < 0; i++)
        if (period(&r, 0.1 * BUDGET_NS, NULL, 0) == 10)
            reached = r.now;
    assert_true(reached > 0);
    assert_int_equal(r.ctl.increases, 8); /* one level at a time */
    assert_true(r.min_gap_up >= r.ctl.def.hold_up_ns);
    /* the first increase waits for hold_up of calm */
    assert_true(reached - calm_start >= 8 * r.ctl.def.hold_up_ns);
    assert_non_null(strstr(r.last_reason, "9 -> 10: calm for"));
    for (int i = 0; i < 100; i++) /* and no higher */
        period(&r, 0.1 * BUDGET_NS, NULL, 0);
    assert_int_equal(r.ctl.depth, 10);
    assert_int_equal(r.max_seen, 10);
    assert_int_equal(r.reversals, 1);
}

/* Deterministic pseudo-random numbers in [0, 1). */
static double rnd(uint64_t *s)
{
    *s = *s * 6364136223846793005ull + 1442695040888963407ull;
    return (double)(*s >> 11) * (1.0 / 9007199254740992.0);
}

static void noise_does_not_oscillate(void **state)
{
    (void)state;
    uint64_t seed = 42;
    run r;
    /* around the upper threshold (0.8): only ever down, then stays */
    start(&r, 2, 10);
    for (int i = 0; i < 600; i++)
        period(&r, (0.75 + 0.1 * rnd(&seed)) * BUDGET_NS, NULL, 0);
    assert_int_equal(r.ctl.increases, 0);
    assert_int_equal(r.reversals, 0);
    assert_int_equal(r.ctl.depth, 2);
    /* around the lower threshold (0.5): the dead band holds, no change */
    start(&r, 2, 10);
    for (int i = 0; i < 600; i++)
        period(&r, (0.45 + 0.1 * rnd(&seed)) * BUDGET_NS, NULL, 0);
    assert_int_equal(r.ctl.changes, 0);
    /* mostly calm with blips into the dead band: it climbs back (blips
     * delay an increase, they do not hold it off), one reversal (down, then
     * up) and no more */
    start(&r, 2, 10);
    for (int i = 0; i < 30; i++)
        period(&r, 0.9 * BUDGET_NS, NULL, 0);
    int64_t changes0 = (int64_t)r.ctl.changes;
    for (int i = 0; i < 600; i++) /* 60 s */
        period(&r, (rnd(&seed) < 0.97 ? 0.3 : 0.6) * BUDGET_NS, NULL, 0);
    assert_int_equal(r.ctl.decreases, 4);
    assert_true((int64_t)r.ctl.changes - changes0 <= 8);
    assert_true(r.reversals <= 1);
    /* a participant's lag jittering around its upper threshold (40 ticks) */
    start(&r, 2, 10);
    ftm_depth_ctl_part p = {3, "trainee", 0, 0.0};
    for (int i = 0; i < 600; i++) {
        p.lag = 35 + (int64_t)(10 * rnd(&seed));
        period(&r, 0.1 * BUDGET_NS, &p, 1);
    }
    assert_int_equal(r.ctl.increases, 0);
    assert_int_equal(r.reversals, 0);
    assert_true(r.ctl.changes <= 4);
}

/* A busy host: every tenth period one signal sits in the dead band (a late
 * status, a slow tick). The calm window tolerates that (noise_pct 20), so
 * the depth still climbs back to the maximum; one period in three in the
 * dead band is no calm, and one overload ends a window at once. */
static void calm_window_tolerates_blips(void **state)
{
    (void)state;
    run r;
    start(&r, 2, 10);
    ftm_depth_ctl_part p = {13, "observer", 0, 0.0};
    for (int i = 0; i < 30; i++)
        period(&r, 0.9 * BUDGET_NS, NULL, 0);
    assert_int_equal(r.ctl.depth, 2);
    for (int i = 0; i < 400 && r.ctl.depth < 10; i++) {
        p.lag = i % 10 == 5 ? 20 : 2; /* 10 <= 20 <= 40: the dead band */
        period(&r, 0.1 * BUDGET_NS, &p, 1);
    }
    assert_int_equal(r.ctl.depth, 10);
    assert_non_null(strstr(r.last_reason, "periods quiet"));
    assert_true(r.min_gap_up >= r.ctl.def.hold_up_ns);

    start(&r, 2, 10);
    for (int i = 0; i < 30; i++)
        period(&r, 0.9 * BUDGET_NS, NULL, 0);
    for (int i = 0; i < 400; i++) {
        p.lag = i % 3 == 1 ? 20 : 2;
        period(&r, 0.1 * BUDGET_NS, &p, 1);
    }
    assert_int_equal(r.ctl.depth, 2);
    assert_int_equal(r.ctl.increases, 0);

    /* quiet periods with one overload every 1.5 s: the 2 s window never fills */
    start(&r, 2, 10);
    for (int i = 0; i < 30; i++)
        period(&r, 0.9 * BUDGET_NS, NULL, 0);
    int32_t low = r.ctl.depth;
    for (int i = 0; i < 400; i++) {
        p.lag = i % 15 == 14 ? 45 : 2;
        period(&r, 0.1 * BUDGET_NS, &p, 1);
    }
    assert_int_equal(low, 2);
    assert_int_equal(r.ctl.increases, 0);
}

static void participant_signals(void **state)
{
    (void)state;
    run r;
    start(&r, 2, 10);
    ftm_depth_ctl_part parts[2] = {{3, "trainee", 2, 50000.0}, {12, "observer", 45, 60000.0}};
    period(&r, 0.1 * BUDGET_NS, parts, 2);
    assert_int_equal(r.ctl.depth, 8);
    assert_string_equal(r.last_reason, "10 -> 8: participant 12 (observer) lag 45 ticks > 40");
    /* within the dead band (10 <= lag <= 40): no change either way */
    parts[1].lag = 20;
    for (int i = 0; i < 100; i++)
        period(&r, 0.1 * BUDGET_NS, parts, 2);
    assert_int_equal(r.ctl.depth, 8);
    /* slow replay of one participant */
    parts[1].lag = 2;
    parts[0].replay_ns = 0.85 * BUDGET_NS;
    period(&r, 0.1 * BUDGET_NS, parts, 2);
    assert_int_equal(r.ctl.depth, 6);
    assert_non_null(strstr(r.last_reason, "participant 3 (trainee) replay 0.850 ms/tick"));
    /* transport: backlog, throttling, retransmits */
    parts[0].replay_ns = 50000.0;
    ftm_depth_ctl_input in = {r.now + 1000000000LL, 0.1 * BUDGET_NS, 0, 100, 0, 0.0, 2, parts};
    bool changed;
    char reason[FTM_DEPTH_REASON_MAX];
    assert_int_equal(ftm_depth_ctl_update(&r.ctl, &in, &changed, reason, sizeof reason), 4);
    assert_non_null(strstr(reason, "100 frames queued"));
    in.now_ns += 1000000000LL;
    in.backlog = 0;
    in.throttled = 3;
    assert_int_equal(ftm_depth_ctl_update(&r.ctl, &in, &changed, reason, sizeof reason), 2);
    assert_non_null(strstr(reason, "throttled 3 times"));
    /* missed ticks come first */
    start(&r, 2, 10);
    ftm_depth_ctl_input in2 = {1, 0.1 * BUDGET_NS, 7, 0, 0, 2.0, 0, NULL};
    ftm_depth_ctl_update(&r.ctl, &in2, &changed, reason, sizeof reason);
    assert_true(changed);
    assert_string_equal(reason, "10 -> 8: 7 ticks missed");
}

static void instructor_limits(void **state)
{
    (void)state;
    run r;
    start(&r, 2, 10);
    bool changed = false;
    char reason[FTM_DEPTH_REASON_MAX];
    ftm_error err = {0, ""};
    assert_int_equal(ftm_depth_ctl_set_limits(&r.ctl, 4, 6, r.now, &changed, reason, sizeof reason, &err),
                     FTM_OK);
    assert_true(changed);
    assert_int_equal(r.ctl.depth, 6);
    assert_string_equal(reason, "10 -> 6: limits now [4, 6]");
    r.min_seen = r.max_seen = 6;
    for (int i = 0; i < 50; i++)
        period(&r, 0.9 * BUDGET_NS, NULL, 0);
    assert_int_equal(r.ctl.depth, 4);
    assert_int_equal(r.min_seen, 4);
    for (int i = 0; i < 300; i++)
        period(&r, 0.1 * BUDGET_NS, NULL, 0);
    assert_int_equal(r.ctl.depth, 6);
    assert_int_equal(r.max_seen, 6);
    /* raising the ceiling does not jump: the depth climbs when calm */
    assert_int_equal(ftm_depth_ctl_set_limits(&r.ctl, 1, 12, r.now, &changed, reason, sizeof reason, &err),
                     FTM_OK);
    assert_false(changed);
    for (int i = 0; i < 300; i++)
        period(&r, 0.1 * BUDGET_NS, NULL, 0);
    assert_int_equal(r.ctl.depth, 12);
    /* a floor above the depth lifts it */
    for (int i = 0; i < 100; i++)
        period(&r, 0.9 * BUDGET_NS, NULL, 0);
    assert_int_equal(r.ctl.depth, 1);
    assert_int_equal(ftm_depth_ctl_set_limits(&r.ctl, 5, 12, r.now, &changed, reason, sizeof reason, &err),
                     FTM_OK);
    assert_int_equal(r.ctl.depth, 5);
    /* bad limits are rejected and change nothing */
    assert_int_equal(ftm_depth_ctl_set_limits(&r.ctl, 7, 3, r.now, &changed, reason, sizeof reason, &err),
                     FTM_EINVAL);
    assert_non_null(strstr(err.message, "min <= max"));
    assert_int_equal(ftm_depth_ctl_set_limits(&r.ctl, -1, 3, r.now, &changed, reason, sizeof reason, &err),
                     FTM_EINVAL);
    assert_int_equal(r.ctl.def.floor, 5);
    assert_int_equal(r.ctl.def.max, 12);
    assert_int_equal(r.ctl.depth, 5);
}

static void bad_definitions(void **state)
{
    (void)state;
    ftm_depth_ctl ctl;
    ftm_depth_ctl_def d;
    ftm_error err = {0, ""};
    ftm_depth_ctl_default(&d, 5, 3, BUDGET_NS);
    assert_int_equal(ftm_depth_ctl_init(&ctl, &d, &err), FTM_EINVAL);
    ftm_depth_ctl_default(&d, 1, 8, BUDGET_NS);
    d.step_low = 0.9; /* above step_high: no dead band */
    assert_int_equal(ftm_depth_ctl_init(&ctl, &d, &err), FTM_EINVAL);
    assert_non_null(strstr(err.message, "step_low < step_high"));
    ftm_depth_ctl_default(&d, 1, 8, 0.0);
    assert_int_equal(ftm_depth_ctl_init(&ctl, &d, &err), FTM_EINVAL);
    ftm_depth_ctl_default(&d, 1, 8, BUDGET_NS);
    d.down_step = 0;
    assert_int_equal(ftm_depth_ctl_init(&ctl, &d, &err), FTM_EINVAL);
    ftm_depth_ctl_default(&d, 1, 8, BUDGET_NS);
    d.noise_pct = 60;
    assert_int_equal(ftm_depth_ctl_init(&ctl, &d, &err), FTM_EINVAL);
    assert_non_null(strstr(err.message, "noise_pct"));
    ftm_depth_ctl_default(&d, 0, 0, BUDGET_NS); /* a fixed depth of 0 is fine */
    assert_int_equal(ftm_depth_ctl_init(&ctl, &d, &err), FTM_OK);
}

int main(void)
{
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(overload_to_floor_and_no_lower),
        cmocka_unit_test(recovery_back_to_max),
        cmocka_unit_test(noise_does_not_oscillate),
        cmocka_unit_test(calm_window_tolerates_blips),
        cmocka_unit_test(participant_signals),
        cmocka_unit_test(instructor_limits),
        cmocka_unit_test(bad_definitions),
    };
    return cmocka_run_group_tests(tests, NULL, NULL);
}
