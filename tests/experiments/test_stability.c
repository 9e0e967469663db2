/* SPDX-License-Identifier: GPL-3.0-or-later */
/* The reduced stability sweep (`ftm stability --quick`): every configuration
 * that is unstable with the guard off is, with the guard on, caught by it
 * (recovered or still large but rolled back) or reported as FTM_EUNSTABLE;
 * no NaN is ever observable in the positions; slow growth below the critical
 * step is seen by the energy check; no guard event at a stable step. Plus
 * the physics the sweep must show: the boundary depends only on the dimensionless parameters,
 * zero damping is unstable at any step, heavy damping stabilises. */
#include <setjmp.h>
#include <stdarg.h>
#include <stddef.h>
#include <stdint.h>
#include <cmocka.h>

#include "experiments.h"

#include <math.h>
#include <stdio.h>
#include <string.h>

static ftm_stab_row rows[32];
static int count;

static int setup(void **state)
{
    (void)state;
    ftm_stab_def def = ftm_stab_default_def(true);
    ftm_stab_config configs[32];
    count = ftm_stab_configs(true, configs, 32);
    for (int i = 0; i < count; i++)
        if (ftm_stab_run(&def, &configs[i], &rows[i]) != 0)
            return -1;
    return 0;
}

static const ftm_stab_row *find(const char *name)
{
    for (int i = 0; i < count; i++)
        if (strcmp(rows[i].config.name, name) == 0)
            return &rows[i];
    fail_msg("no configuration '%s'", name);
    return NULL;
}

static void test_guard_catches_everything(void **state)
{
    (void)state;
    assert_true(count >= 8);
    int unstable = 0;
    for (int i = 0; i < count; i++) {
        const ftm_stab_row *r = &rows[i];
        if (!r->unstable_anywhere)
            continue;
        unstable++;
        for (int p = 0; p < 2; p++) {
            const char *o = r->outcome[p];
            if (r->nan_seen[p] || !(strcmp(o, "recovered") == 0 || strcmp(o, "reported") == 0 ||
                                    strcmp(o, "caught") == 0 || strcmp(o, "stable") == 0))
                fail_msg("%s at %g h_crit: outcome %s, NaN %d", r->config.name, r->probe_ratio[p],
                         o, r->nan_seen[p]);
            /* "stable" only at the first unstable ratio (bisection noise) */
            if (p == 1)
                assert_string_not_equal(o, "stable");
            if (strcmp(o, "reported") == 0)
                assert_true(r->reported[p]);
            if (strcmp(o, "recovered") == 0 || strcmp(o, "caught") == 0)
                assert_true(r->guard_events[p] > 0);
        }
    }
    assert_true(unstable >= count / 2);
}

/* Slow growth: the base lattice just above its damping-limited boundary
 * gains energy over hundreds of steps while no step moves a node far; the
 * motion check alone let it grow to several spacings (docs/stability.md).
 * The energy check must see it early: guard events at the first unstable
 * ratio, and the run back within one spacing. */
static void test_guard_sees_slow_growth(void **state)
{
    (void)state;
    const char *slow[] = {"base 2D", "d = 0.5 x threshold", "depth 3"};
    for (size_t i = 0; i < sizeof slow / sizeof slow[0]; i++) {
        const ftm_stab_row *r = find(slow[i]);
        assert_true(r->unstable_anywhere);
        assert_true(r->probe_ratio[0] <= 1.0); /* below h_crit: no warning, slow growth */
        if (r->guard_events[0] == 0 || strcmp(r->outcome[0], "recovered") != 0)
            fail_msg("%s at %g h_crit: %s with %llu guard events", slow[i], r->probe_ratio[0],
                     r->outcome[0], (unsigned long long)r->guard_events[0]);
    }
}

/* No false alarms: at the largest stable step (below the critical step, where
 * the scene gets no warning) the guard stays silent over the guarded runs'
 * longer time, unless that step is itself slowly unstable over that time
 * (stable_long false: a bisection point within its resolution of the boundary). */
static void test_guard_no_false_alarms(void **state)
{
    (void)state;
    int checked = 0;
    for (int i = 0; i < count; i++) {
        const ftm_stab_row *r = &rows[i];
        if (r->stable_ratio <= 0 || r->stable_ratio > 1.0 || !r->stable_long)
            continue;
        checked++;
        if (r->stable_events != 0)
            fail_msg("%s: %llu guard events at the stable step %g h_crit", r->config.name,
                     (unsigned long long)r->stable_events, r->stable_ratio);
    }
    assert_true(checked >= 4);
}

static void test_boundary_physics(void **state)
{
    (void)state;
    const ftm_stab_row *base = find("base 2D");
    /* h_crit is the Gershgorin bound: never above the spectral limit */
    for (int i = 0; i < count; i++)
        assert_true(rows[i].h_spectral >= rows[i].h_crit * (1 - 1e-9));
    /* scaling k and m by the same factor of h_crit changes nothing */
    assert_true(fabs(find("k x10")->measured - base->measured) < 1e-12);
    assert_true(fabs(find("m x0.1")->measured - base->measured) < 1e-12);
    /* no damping: unstable at any step; the core warns */
    const ftm_stab_row *d0 = find("d = 0 x threshold");
    assert_true(d0->measured < 0 && d0->warned);
    assert_false(base->warned);
    /* heavy damping stabilises beyond the undamped critical step */
    assert_true(find("d = 20 x threshold")->measured > 1.0);
    assert_true(find("d = 20 x threshold")->measured > base->measured);
}

int main(void)
{
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(test_guard_catches_everything),
        cmocka_unit_test(test_guard_sees_slow_growth),
        cmocka_unit_test(test_guard_no_false_alarms),
        cmocka_unit_test(test_boundary_physics),
    };
    return cmocka_run_group_tests(tests, setup, NULL);
}
