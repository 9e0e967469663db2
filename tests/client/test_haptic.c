/* SPDX-License-Identifier: GPL-3.0-or-later */
/* The force renderers and their safety stage (client/haptic.c), driven with
 * explicit times: exact on linear signals, bounded on steps, fade on stale
 * data, clamp, rate limit, zero on disconnect. */
#include <setjmp.h>
#include <stdarg.h>
#include <stddef.h>

#include <cmocka.h>

#include "haptic.h"

#include <math.h>
#include <string.h>

static ftm_haptic_def loose(ftm_haptic_renderer_kind kind)
{
    ftm_haptic_def d = ftm_default_haptic_def();
    d.renderer = kind;
    d.max_force = 1e9;      /* the renderer alone */
    d.max_force_rate = 1e12;
    d.stale_after = 10.0;
    return d;
}

static ftm_haptic_sample sample(double t, ftm_vec3 f, ftm_vec3 x)
{
    ftm_haptic_sample s;
    memset(&s, 0, sizeof s);
    s.time = t;
    s.force = f;
    s.hip = x;
    return s;
}

static double norm(ftm_vec3 a) { return sqrt(a.x * a.x + a.y * a.y + a.z * a.z); }

static void test_extrapolate_exact_on_linear(void **state)
{
    ftm_haptic_def d = loose(FTM_HAPTIC_EXTRAPOLATE);
    ftm_force_renderer r;
    ftm_force_renderer_init(&r, &d);
    ftm_vec3 a = {0.1, -0.2, 1.0}, b = {0.5, 0.25, -2.0}; /* F(t) = a + b t, stays positive in z */
    ftm_vec3 x = {0, 0, 0};
    ftm_force_renderer_eval(&r, 0.0, x, NULL); /* establish the time base */
    for (int k = 0; k < 40; k++) {
        double tk = 0.010 * k;
        ftm_haptic_sample s = sample(tk, (ftm_vec3){a.x + b.x * tk, a.y + b.y * tk, a.z + b.z * tk}, x);
        assert_int_equal(ftm_force_renderer_push(&r, &s, tk), FTM_OK);
        if (k == 0)
            continue;
        for (int j = 1; j <= 10; j++) { /* 1 kHz ticks until the next sample */
            double t = tk + 0.001 * j;
            ftm_vec3 f = ftm_force_renderer_eval(&r, t, x, NULL);
            assert_true(fabs(f.x - (a.x + b.x * t)) < 1e-12);
            assert_true(fabs(f.y - (a.y + b.y * t)) < 1e-12);
            assert_true(fabs(f.z - (a.z + b.z * t)) < 1e-12);
        }
    }
}

static void test_model_exact_on_linear(void **state)
{
    ftm_haptic_def d = loose(FTM_HAPTIC_FORCE_MODEL);
    ftm_force_renderer r;
    ftm_force_renderer_init(&r, &d);
    /* a linear force field F(x) = c + K x */
    const double K[9] = {-120, 10, 0, 10, -90, 5, 0, 5, -300};
    ftm_vec3 c = {0.3, -0.1, 2.0};
    ftm_vec3 x0 = {0.01, 0.02, -0.003};
    ftm_haptic_sample s = sample(0.0, (ftm_vec3){0, 0, 0}, x0);
    s.force = (ftm_vec3){c.x + K[0] * x0.x + K[1] * x0.y + K[2] * x0.z,
                         c.y + K[3] * x0.x + K[4] * x0.y + K[5] * x0.z,
                         c.z + K[6] * x0.x + K[7] * x0.y + K[8] * x0.z};
    s.has_stiffness = true;
    memcpy(s.stiffness, K, sizeof K);
    assert_int_equal(ftm_force_renderer_push(&r, &s, 0.0), FTM_OK);
    ftm_force_renderer_eval(&r, 0.0, x0, NULL);
    for (int j = 1; j <= 100; j++) {
        ftm_vec3 x = {x0.x + 1e-4 * j * sin(j), x0.y - 5e-5 * j, x0.z + 2e-5 * j * cos(j)};
        ftm_vec3 f = ftm_force_renderer_eval(&r, 0.001 * j, x, NULL);
        ftm_vec3 e = {c.x + K[0] * x.x + K[1] * x.y + K[2] * x.z,
                      c.y + K[3] * x.x + K[4] * x.y + K[5] * x.z,
                      c.z + K[6] * x.x + K[7] * x.y + K[8] * x.z};
        assert_true(norm((ftm_vec3){f.x - e.x, f.y - e.y, f.z - e.z}) < 1e-12);
    }
    /* without a stiffness it holds F0 */
    ftm_haptic_sample h = sample(1.0, (ftm_vec3){0, 0, 1.5}, x0);
    ftm_force_renderer_push(&r, &h, 1.0);
    ftm_vec3 f = ftm_force_renderer_model(&r, 1.01, (ftm_vec3){1, 1, 1});
    assert_true(f.x == 0 && f.y == 0 && f.z == 1.5);
}

/* A step in the samples: the output stays in the force ball, changes at
 * most max_force_rate * dt per tick, and the extrapolation is held at the
 * horizon instead of running away, then fades. */
static void test_bounded_on_step(void **state)
{
    for (int kind = 0; kind < 2; kind++) {
        ftm_haptic_def d = ftm_default_haptic_def();
        d.renderer = (ftm_haptic_renderer_kind)kind;
        ftm_force_renderer r;
        ftm_force_renderer_init(&r, &d);
        ftm_vec3 x = {0, 0, 0};
        ftm_haptic_sample s0 = sample(0.0, (ftm_vec3){0, 0, 0.01}, x);
        ftm_haptic_sample s1 = sample(0.001, (ftm_vec3){0, 0, 5.0}, x); /* 5 kN/s jump */
        s1.has_stiffness = true;
        s1.stiffness[8] = -500; /* and a HIP that moves on */
        ftm_force_renderer_push(&r, &s0, 0.0);
        ftm_force_renderer_push(&r, &s1, 0.001);
        ftm_vec3 prev = ftm_force_renderer_eval(&r, 0.001, x, NULL);
        double peak = 0;
        for (int j = 2; j <= 400; j++) {
            double t = 0.001 * j;
            x.z = -1e-4 * j; /* pushing in: the model's force grows */
            int fl = 0;
            ftm_vec3 f = ftm_force_renderer_eval(&r, t, x, &fl);
            double step = norm((ftm_vec3){f.x - prev.x, f.y - prev.y, f.z - prev.z});
            assert_true(norm(f) <= d.max_force + 1e-12);
            assert_true(step <= d.max_force_rate * 0.001 + 1e-9);
            if (norm(f) > peak)
                peak = norm(f);
            prev = f;
        }
        assert_true(peak > 4.0);                  /* it did render the step */
        assert_true(norm(prev) < 1e-12);          /* and faded out: no sample for 0.4 s */
    }
    /* the extrapolator's horizon: with no clamp, the force at 1 s equals the
     * force at max_extrapolation */
    ftm_haptic_def d = loose(FTM_HAPTIC_EXTRAPOLATE);
    ftm_force_renderer r;
    ftm_force_renderer_init(&r, &d);
    ftm_haptic_sample s0 = sample(0.0, (ftm_vec3){0, 0, 1}, (ftm_vec3){0, 0, 0});
    ftm_haptic_sample s1 = sample(0.001, (ftm_vec3){0, 0, 2}, (ftm_vec3){0, 0, 0});
    ftm_force_renderer_push(&r, &s0, 0);
    ftm_force_renderer_push(&r, &s1, 0.001);
    ftm_vec3 a = ftm_force_renderer_model(&r, 0.001 + d.max_extrapolation, (ftm_vec3){0, 0, 0});
    ftm_vec3 b = ftm_force_renderer_model(&r, 1.0, (ftm_vec3){0, 0, 0});
    assert_true(fabs(a.z - (2.0 + 1000.0 * d.max_extrapolation)) < 1e-9);
    assert_true(a.z == b.z);
}

static void test_fade_on_stale(void **state)
{
    ftm_haptic_def d = ftm_default_haptic_def();
    d.renderer = FTM_HAPTIC_FORCE_MODEL;
    d.max_force_rate = 1e9;
    ftm_force_renderer r;
    ftm_force_renderer_init(&r, &d);
    ftm_vec3 x = {0, 0, 0};
    ftm_haptic_sample s = sample(0.0, (ftm_vec3){0, 2.0, 0}, x);
    ftm_force_renderer_push(&r, &s, 0.0);
    int fl;
    ftm_force_renderer_eval(&r, 0.0, x, &fl);
    ftm_vec3 f = ftm_force_renderer_eval(&r, d.stale_after * 0.99, x, &fl);
    assert_true(fabs(f.y - 2.0) < 1e-12);
    assert_false(fl & FTM_HAPTIC_STALE);
    f = ftm_force_renderer_eval(&r, d.stale_after + 0.5 * d.fade_time, x, &fl);
    assert_true(fabs(f.y - 1.0) < 1e-9);
    assert_true(fl & FTM_HAPTIC_STALE);
    f = ftm_force_renderer_eval(&r, d.stale_after + d.fade_time, x, &fl);
    assert_true(norm(f) == 0.0);
    f = ftm_force_renderer_eval(&r, 10.0, x, &fl);
    assert_true(norm(f) == 0.0);
    /* a fresh sample brings it back (staleness is by arrival, not by the
     * sample's own time: a delayed sample is not stale) */
    ftm_haptic_sample late = sample(5.0, (ftm_vec3){0, 2.0, 0}, x);
    ftm_force_renderer_push(&r, &late, 10.0);
    f = ftm_force_renderer_eval(&r, 10.001, x, &fl);
    assert_true(fabs(f.y - 2.0) < 1e-12);
}

static void test_clamp_at_limit(void **state)
{
    ftm_haptic_def d = ftm_default_haptic_def();
    d.max_force_rate = 1e12;
    ftm_force_renderer r;
    ftm_force_renderer_init(&r, &d);
    ftm_vec3 x = {0, 0, 0};
    ftm_haptic_sample s = sample(0.0, (ftm_vec3){30.0, 40.0, 0}, x); /* 50 N */
    ftm_force_renderer_push(&r, &s, 0.0);
    ftm_force_renderer_eval(&r, 0.0, x, NULL);
    int fl;
    ftm_vec3 f = ftm_force_renderer_eval(&r, 0.001, x, &fl);
    assert_true(fabs(norm(f) - d.max_force) < 1e-12);
    assert_true(fabs(f.x / f.y - 0.75) < 1e-12); /* direction kept */
    assert_true(fl & FTM_HAPTIC_CLAMPED);
    /* an overflowing model gives zero, never inf or NaN */
    ftm_haptic_sample big = sample(1.0, (ftm_vec3){0, 0, 1}, x);
    big.has_stiffness = true;
    big.stiffness[8] = -1e308;
    ftm_force_renderer_push(&r, &big, 1.0);
    f = ftm_force_renderer_eval(&r, 1.001, (ftm_vec3){0, 0, -1e10}, &fl);
    assert_true(isfinite(f.z) && norm(f) <= d.max_force + 1e-12);
}

static void test_rate_limit(void **state)
{
    ftm_haptic_def d = ftm_default_haptic_def(); /* 2000 N/s */
    ftm_force_renderer r;
    ftm_force_renderer_init(&r, &d);
    ftm_vec3 x = {0, 0, 0};
    ftm_force_renderer_eval(&r, 0.0, x, NULL);
    ftm_haptic_sample s = sample(0.0, (ftm_vec3){0, 0, 7.0}, x);
    ftm_force_renderer_push(&r, &s, 0.0);
    int fl;
    for (int j = 1; j <= 3; j++) {
        ftm_vec3 f = ftm_force_renderer_eval(&r, 0.001 * j, x, &fl);
        assert_true(fabs(f.z - 2.0 * j) < 1e-9);
        assert_true(fl & FTM_HAPTIC_RATE_LIMITED);
    }
    ftm_vec3 f = ftm_force_renderer_eval(&r, 0.004, x, &fl);
    assert_true(fabs(f.z - 7.0) < 1e-12);
    assert_false(fl & FTM_HAPTIC_RATE_LIMITED);
    /* time going backwards counts as dt = 0: no change at all */
    ftm_haptic_sample z = sample(0.004, (ftm_vec3){0, 0, 0.5}, x);
    ftm_force_renderer_push(&r, &z, 0.004);
    f = ftm_force_renderer_eval(&r, 0.002, x, &fl);
    assert_true(fabs(f.z - 7.0) < 1e-12);
}

static void test_disconnect_zero(void **state)
{
    for (int kind = 0; kind < 2; kind++) {
        ftm_haptic_def d = ftm_default_haptic_def();
        d.renderer = (ftm_haptic_renderer_kind)kind;
        ftm_force_renderer r;
        ftm_force_renderer_init(&r, &d);
        ftm_vec3 x = {0, 0, 0};
        for (int j = 0; j < 20; j++) {
            ftm_haptic_sample s = sample(0.001 * j, (ftm_vec3){0, 0, 4.0}, x);
            ftm_force_renderer_push(&r, &s, 0.001 * j);
            ftm_force_renderer_eval(&r, 0.001 * j, x, NULL);
        }
        assert_true(fabs(ftm_force_renderer_eval(&r, 0.02, x, NULL).z - 4.0) < 1e-12);
        ftm_force_renderer_set_connected(&r, false);
        int fl;
        ftm_vec3 f = ftm_force_renderer_eval(&r, 0.021, x, &fl);
        assert_true(norm(f) == 0.0); /* at once, not rate-limited */
        assert_true(fl & FTM_HAPTIC_DISCONNECTED);
        ftm_haptic_sample s = sample(0.022, (ftm_vec3){0, 0, 4.0}, x);
        ftm_force_renderer_push(&r, &s, 0.022); /* ignored while disconnected */
        assert_true(norm(ftm_force_renderer_eval(&r, 0.023, x, NULL)) == 0.0);
        ftm_force_renderer_set_connected(&r, true);
        f = ftm_force_renderer_eval(&r, 0.024, x, &fl);
        assert_true(norm(f) == 0.0 && (fl & FTM_HAPTIC_NO_SAMPLE)); /* old samples gone */
        /* a lost device: zero at once too */
        ftm_force_renderer_push(&r, &s, 0.025);
        for (int j = 0; j < 10; j++)
            ftm_force_renderer_eval(&r, 0.025 + 0.001 * j, x, NULL);
        f = ftm_force_renderer_eval(&r, 0.036, (ftm_vec3){NAN, 0, 0}, &fl);
        assert_true(norm(f) == 0.0 && (fl & FTM_HAPTIC_DEVICE_LOST));
    }
}

static void test_unilateral_and_bad_samples(void **state)
{
    ftm_haptic_def d = loose(FTM_HAPTIC_FORCE_MODEL);
    ftm_force_renderer r;
    ftm_force_renderer_init(&r, &d);
    ftm_haptic_sample s = sample(0.0, (ftm_vec3){0, 0, 1.0}, (ftm_vec3){0, 0, -0.002});
    s.has_stiffness = true;
    s.stiffness[8] = -500; /* F = 1 - 500 (z + 0.002): zero at z = 0 */
    ftm_force_renderer_push(&r, &s, 0.0);
    ftm_force_renderer_eval(&r, 0.0, s.hip, NULL);
    int fl;
    ftm_vec3 f = ftm_force_renderer_eval(&r, 0.001, (ftm_vec3){0, 0, 0.001}, &fl);
    assert_true(norm(f) == 0.0 && (fl & FTM_HAPTIC_UNILATERAL)); /* no pull */
    f = ftm_force_renderer_eval(&r, 0.002, (ftm_vec3){0, 0, -0.001}, &fl);
    assert_true(fabs(f.z - 0.5) < 1e-12);

    /* with the contact plane (z = 1 mm, outward +z): zero once the HIP is back
     * outside it, and never a component into the tissue */
    ftm_haptic_sample p = sample(1.0, (ftm_vec3){2.0, 0, 1.0}, (ftm_vec3){0, 0, -0.002});
    p.has_stiffness = true;
    p.stiffness[8] = -500;
    p.has_plane = true;
    p.plane_point = (ftm_vec3){0, 0, 0.001};
    p.plane_normal = (ftm_vec3){0, 0, 3.0}; /* normalised on push */
    assert_int_equal(ftm_force_renderer_push(&r, &p, 1.0), FTM_OK);
    f = ftm_force_renderer_eval(&r, 1.001, (ftm_vec3){0, 0, 0.0005}, &fl);
    assert_true(f.x == 2.0 && f.y == 0.0 && f.z == 0.0); /* -0.25 N inward removed */
    assert_true(fl & FTM_HAPTIC_UNILATERAL);
    f = ftm_force_renderer_eval(&r, 1.002, (ftm_vec3){0, 0, 0.001}, &fl);
    assert_true(norm(f) == 0.0 && (fl & FTM_HAPTIC_RELEASED));
    f = ftm_force_renderer_eval(&r, 1.003, (ftm_vec3){0, 0, -0.001}, &fl);
    assert_true(fabs(f.x - 2.0) < 1e-12 && fabs(f.z - 0.5) < 1e-12);
    ftm_haptic_sample bad = p;
    bad.plane_normal = (ftm_vec3){0, 0, 0};
    assert_int_equal(ftm_force_renderer_push(&r, &bad, 1.004), FTM_EINVAL);
    bad = p;
    bad.plane_point.x = INFINITY;
    assert_int_equal(ftm_force_renderer_push(&r, &bad, 1.004), FTM_EINVAL);

    bad = s;
    bad.force.y = NAN;
    assert_int_equal(ftm_force_renderer_push(&r, &bad, 0.003), FTM_EINVAL);
    bad = s;
    bad.stiffness[4] = INFINITY;
    assert_int_equal(ftm_force_renderer_push(&r, &bad, 0.003), FTM_EINVAL);
    bad = s;
    bad.time = NAN;
    assert_int_equal(ftm_force_renderer_push(&r, &bad, 0.003), FTM_EINVAL);
    /* out of order: older than the newest held, ignored */
    ftm_haptic_sample old = sample(-1.0, (ftm_vec3){0, 0, 7.0}, s.hip);
    assert_int_equal(ftm_force_renderer_push(&r, &old, 1.004), FTM_OK);
    f = ftm_force_renderer_eval(&r, 1.004, (ftm_vec3){0, 0, -0.001}, &fl);
    assert_true(fabs(f.z - 0.5) < 1e-12);

    /* a release in the samples (force to zero, no plane): zero, not the
     * line through the two samples carried on as a pull */
    ftm_force_renderer_init(&r, &d);
    ftm_haptic_sample c0 = sample(2.0, (ftm_vec3){0.3, 0, 1.0}, (ftm_vec3){0, 0, 0});
    ftm_haptic_sample c1 = sample(2.001, (ftm_vec3){0, 0, 0}, (ftm_vec3){0, 0, 0});
    ftm_force_renderer_set_kind(&r, FTM_HAPTIC_EXTRAPOLATE);
    ftm_force_renderer_push(&r, &c0, 2.0);
    ftm_force_renderer_push(&r, &c1, 2.05);
    ftm_force_renderer_eval(&r, 2.05, c0.hip, NULL);
    f = ftm_force_renderer_eval(&r, 2.051, c0.hip, &fl);
    assert_true(norm(f) == 0.0);
    assert_true(norm(ftm_force_renderer_model(&r, 2.051, c0.hip)) > 10.0); /* what it avoided */
}

/* QA's burst: a held press, then two frames drained back to back (100 us
 * apart, arrival-stamped) 0.010 N apart, then no frame for 60 ms. Their
 * slope (100 N/s) carried over the gap reached the 8 N clamp; a pair closer
 * than min_sample_interval is held instead. */
static void test_extrapolate_burst_held(void **state)
{
    ftm_haptic_def d = ftm_default_haptic_def();
    d.renderer = FTM_HAPTIC_EXTRAPOLATE;
    ftm_force_renderer r;
    ftm_force_renderer_init(&r, &d);
    ftm_vec3 x = {0, 0, 0.104};
    double t = 10.0;
    for (int k = 0; k < 200; k++, t += 1e-3) {
        ftm_haptic_sample s = sample(t, (ftm_vec3){0, 0, 1.0}, x);
        assert_int_equal(ftm_force_renderer_push(&r, &s, t), FTM_OK);
        ftm_force_renderer_eval(&r, t + 0.5e-3, x, NULL);
    }
    ftm_haptic_sample a = sample(t, (ftm_vec3){0, 0, 1.0}, x);
    ftm_haptic_sample b = sample(t + 100e-6, (ftm_vec3){0, 0, 1.010}, x);
    ftm_force_renderer_push(&r, &a, a.time);
    ftm_force_renderer_push(&r, &b, b.time);
    for (int k = 1; k <= 200; k++) {
        ftm_vec3 f = ftm_force_renderer_eval(&r, b.time + k * 1e-3, x, NULL);
        assert_true(norm(f) <= 1.010 + 1e-12);
        assert_true(f.z >= 0);
    }
}

/* Frames of a press ramping 2.5 N/s at 500 Hz, 5 ms late, except ticks
 * 100..129: held up by a stall (80 ms without a frame), then drained 60 us
 * apart. Stamped by
 * ftm_haptic_timebase they keep the ticks' spacing: the extrapolator then
 * follows the ramp exactly through the stall and the burst (the server's
 * force 5 ms ago), where arrival stamps gave glitches of tenths of N. */
static void test_timebase_burst(void **state)
{
    ftm_haptic_def d = ftm_default_haptic_def();
    d.renderer = FTM_HAPTIC_EXTRAPOLATE;
    ftm_force_renderer r;
    ftm_force_renderer_init(&r, &d);
    ftm_haptic_timebase tb = {0};
    const double rate = 500.0, lat = 5e-3, local = 100.0; /* local clock = server clock + 100 s */
    ftm_vec3 x = {0, 0, 0.104};
    double arrival[300], prev_mapped = -1;
    for (int k = 0; k < 300; k++)
        arrival[k] = local + k / rate + lat;
    for (int k = 100; k < 130; k++)
        arrival[k] = local + 129 / rate + lat + 0.020 + (k - 100) * 60e-6;
    double now = arrival[0];
    int evals = 0;
    for (int k = 0; k < 300; k++) {
        for (; now < arrival[k]; now += 1e-3, evals++) { /* the 1 kHz loop until this frame */
            ftm_vec3 f = ftm_force_renderer_eval(&r, now, x, NULL);
            double truth = 1.0 + 2.5 * (now - local - lat);
            if (evals > 10) /* (after the first samples and the ramp from zero) */
                assert_true(fabs(f.z - truth) < 1e-9);
        }
        double tk = k / rate;
        double m = ftm_haptic_timebase_map(&tb, tk, arrival[k], d.stale_after);
        assert_true(m <= arrival[k]);
        if (k > 0)
            assert_true(fabs(m - prev_mapped - 1 / rate) < 1e-9); /* the ticks' spacing */
        prev_mapped = m;
        ftm_haptic_sample s = sample(m, (ftm_vec3){0, 0, 1.0 + 2.5 * tk}, x);
        assert_int_equal(ftm_force_renderer_push(&r, &s, arrival[k]), FTM_OK);
    }
    assert_true(evals > 500);
}

/* The offset follows the least delayed frame, and re-anchors after a pause
 * (no ticks for 1 s: its frames would all look 1 s old). */
static void test_timebase_floor_and_pause(void **state)
{
    ftm_haptic_timebase tb = {0};
    assert_true(ftm_haptic_timebase_map(&tb, 1.0, 50.010, 0.1) == 50.010);
    assert_true(fabs(ftm_haptic_timebase_map(&tb, 1.002, 50.030, 0.1) - 50.012) < 1e-12);
    /* a frame less delayed than any before: it sets the floor */
    assert_true(ftm_haptic_timebase_map(&tb, 1.004, 50.012, 0.1) == 50.012);
    assert_true(fabs(ftm_haptic_timebase_map(&tb, 1.006, 50.020, 0.1) - 50.014) < 1e-12);
    /* paused for a second: the next tick is re-anchored at its arrival */
    assert_true(ftm_haptic_timebase_map(&tb, 1.008, 51.016, 0.1) == 51.016);
    assert_true(fabs(ftm_haptic_timebase_map(&tb, 1.010, 51.019, 0.1) - 51.018) < 1e-12);
}

/* A server whose ticks run 0.03 % slow (999.7 a second, as logged), every
 * frame delayed 2 ms: the mapped time of each fresh frame stays within a
 * window's drift of its arrival, instead of falling behind by up to max_age
 * (90 ms after 300 s when the offset only ever moved to a smaller delay,
 * which made the extrapolator run that far ahead). */
static void test_timebase_follows_drift(void **state)
{
    (void)state;
    ftm_haptic_timebase tb = {0};
    double worst = 0;
    for (int k = 0; k < 300000; k++) {
        const double server_time = k * 1e-3, arrival = 100.0 + k / 999.7 + 0.002;
        const double lag = arrival - ftm_haptic_timebase_map(&tb, server_time, arrival, 0.1);
        assert_true(lag >= 0);
        if (lag > worst)
            worst = lag;
    }
    /* 0.03 % of a 0.5 s window, and one more window's worth before it acts */
    assert_true(worst < 0.0005);
}

static void test_def_check(void **state)
{
    ftm_haptic_def d = ftm_default_haptic_def();
    ftm_error err = {0, ""};
    assert_int_equal(ftm_haptic_def_check(&d, &err), FTM_OK);
    d.max_force = -1;
    assert_int_equal(ftm_haptic_def_check(&d, &err), FTM_EINVAL);
    assert_non_null(strstr(err.message, "max_force"));
    d = ftm_default_haptic_def();
    d.min_sample_interval = -1;
    assert_int_equal(ftm_haptic_def_check(&d, &err), FTM_EINVAL);
    assert_non_null(strstr(err.message, "min_sample_interval"));
    d = ftm_default_haptic_def();
    d.rate_hz = 0;
    assert_int_equal(ftm_haptic_def_check(&d, &err), FTM_EINVAL);
    assert_non_null(strstr(err.message, "rate_hz"));
    d = ftm_default_haptic_def();
    d.renderer = (ftm_haptic_renderer_kind)7;
    assert_int_equal(ftm_haptic_def_check(&d, &err), FTM_EINVAL);
    ftm_haptic_renderer_kind k;
    assert_int_equal(ftm_haptic_renderer_parse("extrapolate", &k), FTM_OK);
    assert_int_equal(k, FTM_HAPTIC_EXTRAPOLATE);
    assert_int_equal(ftm_haptic_renderer_parse("model", &k), FTM_OK);
    assert_int_equal(k, FTM_HAPTIC_FORCE_MODEL);
    assert_int_equal(ftm_haptic_renderer_parse("spline", &k), FTM_EINVAL);
}

int main(void)
{
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(test_extrapolate_exact_on_linear),
        cmocka_unit_test(test_model_exact_on_linear),
        cmocka_unit_test(test_bounded_on_step),
        cmocka_unit_test(test_fade_on_stale),
        cmocka_unit_test(test_clamp_at_limit),
        cmocka_unit_test(test_rate_limit),
        cmocka_unit_test(test_disconnect_zero),
        cmocka_unit_test(test_unilateral_and_bad_samples),
        cmocka_unit_test(test_extrapolate_burst_held),
        cmocka_unit_test(test_timebase_burst),
        cmocka_unit_test(test_timebase_floor_and_pause),
        cmocka_unit_test(test_timebase_follows_drift),
        cmocka_unit_test(test_def_check),
    };
    return cmocka_run_group_tests(tests, NULL, NULL);
}
