/* SPDX-License-Identifier: GPL-3.0-or-later */
/* The haptic loop thread and the devices: start/stop (and restart) cleanly,
 * samples from another thread reach the device, disconnect writes zero, the
 * last force is zero after stop; the scripted device's format and the mouse
 * probe's geometry. Also run under ThreadSanitizer in CI. */
#include <setjmp.h>
#include <stdarg.h>
#include <stddef.h>

#include <cmocka.h>

#include "haptic.h"

#include <math.h>
#include <pthread.h>
#include <string.h>
#include <time.h>

static void sleep_ms(int ms)
{
    struct timespec ts = {ms / 1000, (long)(ms % 1000) * 1000000L};
    nanosleep(&ts, NULL);
}

static double norm(ftm_vec3 a) { return sqrt(a.x * a.x + a.y * a.y + a.z * a.z); }

static const char script_text[] = "# t x y z\n"
                                  "join 0.0\n"
                                  "0.0  0.0 0.0 0.010\n"
                                  "0.5  0.0 0.0 0.000   # pressing\n"
                                  "1.0  0.002 0.0 0.000\n";

typedef struct feeder {
    ftm_haptic *h;
    int count;
} feeder;

/* the replay thread's role: a sample every millisecond */
static void *feed(void *arg)
{
    feeder *f = arg;
    for (int i = 0; i < f->count; i++) {
        ftm_haptic_sample s;
        memset(&s, 0, sizeof s);
        s.time = ftm_haptic_clock();
        s.force = (ftm_vec3){0, 0, 2.0};
        s.hip = (ftm_vec3){0, 0, 0};
        s.has_stiffness = true;
        assert_int_equal(ftm_haptic_push(f->h, &s), FTM_OK);
        sleep_ms(1);
    }
    return NULL;
}

static void test_loop_start_stop(void **state)
{
    ftm_device *dev = NULL;
    ftm_error err = {0, ""};
    assert_int_equal(ftm_script_device_parse(script_text, sizeof script_text - 1, "t.bot", NULL,
                                             &dev, &err),
                     FTM_OK);
    ftm_haptic *h = NULL;
    ftm_haptic_def d = ftm_default_haptic_def();
    assert_int_equal(ftm_haptic_create(&d, dev, &h, &err), FTM_OK);
    for (int run = 0; run < 2; run++) {
        assert_int_equal(ftm_haptic_start(h, &err), FTM_OK);
        assert_int_equal(ftm_haptic_start(h, &err), FTM_EINVAL); /* already running */
        feeder f = {h, 150};
        pthread_t th;
        assert_int_equal(pthread_create(&th, NULL, feed, &f), 0);
        ftm_haptic_state st;
        double peak = 0;
        ftm_haptic_hip hips[256];
        int taken = 0;
        for (int i = 0; i < 30; i++) { /* the render thread's role */
            sleep_ms(5);
            ftm_haptic_get_state(h, &st);
            assert_true(st.running);
            if (norm(st.force) > peak)
                peak = norm(st.force);
            taken += ftm_haptic_take_hips(h, hips, 256);
        }
        pthread_join(th, NULL);
        assert_true(peak > 1.9 && peak <= 2.0 + 1e-12);
        assert_true(taken > 50);
        /* connection lost: zero within a couple of ticks, while running */
        ftm_haptic_set_connected(h, false);
        sleep_ms(20);
        ftm_script_device_log log;
        assert_int_equal(ftm_script_device_get_log(dev, &log), FTM_OK);
        assert_true(norm(log.last_force) == 0.0);
        ftm_haptic_get_state(h, &st);
        assert_true(st.flags & FTM_HAPTIC_DISCONNECTED);
        ftm_haptic_set_connected(h, true);
        ftm_haptic_stop(h);
        ftm_haptic_stop(h); /* idempotent */
        ftm_haptic_get_state(h, &st);
        assert_false(st.running);
        assert_true(st.ticks > 50);
        assert_int_equal(ftm_script_device_get_log(dev, &log), FTM_OK);
        assert_true(norm(log.last_force) == 0.0); /* nothing left on the device */
        assert_true(log.writes >= st.ticks);
        ftm_haptic_timing t;
        ftm_haptic_get_timing(h, &t);
        assert_true(t.periods > 0 && t.rate_hz > 100 && t.p50 > 0 && t.p50 <= t.max);
    }
    /* destroy while running stops first */
    assert_int_equal(ftm_haptic_start(h, &err), FTM_OK);
    sleep_ms(5);
    ftm_haptic_destroy(h);
    ftm_device_destroy(dev);
}

/* A device that fails every read: the loop writes zero. */
static int lost_read(void *self, double now, ftm_vec3 *hip) { return FTM_EIO; }
static void lost_write(void *self, double now, ftm_vec3 f)
{
    ftm_vec3 *last = self;
    *last = f; /* haptic thread only; read after stop (join) */
}
static const ftm_device_ops lost_ops = {.name = "lost", .read = lost_read, .write = lost_write};

static void test_loop_device_lost(void **state)
{
    ftm_vec3 last = {1, 1, 1};
    ftm_device *dev = NULL;
    assert_int_equal(ftm_device_create(&lost_ops, &last, NULL, &dev, NULL), FTM_OK);
    ftm_haptic *h = NULL;
    assert_int_equal(ftm_haptic_create(NULL, dev, &h, NULL), FTM_OK);
    assert_int_equal(ftm_haptic_start(h, NULL), FTM_OK);
    ftm_haptic_sample s;
    memset(&s, 0, sizeof s);
    s.force = (ftm_vec3){0, 0, 3};
    for (int i = 0; i < 10; i++) {
        s.time = ftm_haptic_clock();
        ftm_haptic_push(h, &s);
        sleep_ms(2);
    }
    ftm_haptic_state st;
    ftm_haptic_get_state(h, &st);
    assert_true(st.flags & FTM_HAPTIC_DEVICE_LOST);
    assert_true(norm(st.force) == 0.0);
    s.force.x = NAN;
    assert_int_equal(ftm_haptic_push(h, &s), FTM_EINVAL);
    ftm_haptic_destroy(h);
    assert_true(norm(last) == 0.0);
    ftm_device_destroy(dev);
    /* a device without read is refused */
    static const ftm_device_ops none = {.name = "none"};
    ftm_error err = {0, ""};
    assert_int_equal(ftm_device_create(&none, NULL, NULL, &dev, &err), FTM_EINVAL);
}

static void test_script_device(void **state)
{
    ftm_device *dev = NULL;
    ftm_error err = {0, ""};
    assert_int_equal(ftm_script_device_parse(script_text, sizeof script_text - 1, "t.bot", NULL,
                                             &dev, &err),
                     FTM_OK);
    ftm_vec3 p;
    assert_int_equal(ftm_script_device_position(dev, -1.0, &p), FTM_OK);
    assert_true(p.z == 0.010);
    assert_int_equal(ftm_script_device_position(dev, 0.25, &p), FTM_OK);
    assert_true(fabs(p.z - 0.005) < 1e-15);
    assert_int_equal(ftm_script_device_position(dev, 0.75, &p), FTM_OK);
    assert_true(fabs(p.x - 0.001) < 1e-15 && p.z == 0.0);
    assert_int_equal(ftm_script_device_position(dev, 9.0, &p), FTM_OK);
    assert_true(p.x == 0.002);
    assert_true(ftm_script_device_duration(dev) == 1.0);
    /* the mapping of ftm_device_read: scale and offset */
    ftm_device_destroy(dev);
    ftm_device_def def = ftm_default_device_def();
    def.position_scale = 2.0;
    def.offset = (ftm_vec3){1, 0, 0};
    assert_int_equal(ftm_script_device_parse(script_text, sizeof script_text - 1, "t.bot", &def,
                                             &dev, &err),
                     FTM_OK);
    assert_int_equal(ftm_device_read(dev, 100.0, &p), FTM_OK); /* time 0 */
    assert_true(p.x == 1.0 && p.z == 0.020);
    ftm_device_destroy(dev);

    static const struct {
        const char *text, *msg;
    } bad[] = {
        {"0 0 0\n", "t.bot:1: expected 't x y z' (4 numbers)"},
        {"0 0 0 0\n1 0 0 0 5\n", "t.bot:2: expected 't x y z' (4 numbers)"},
        {"# c\n0 0 0 0\n\n0 1 1 1\n", "t.bot:4: time 0 does not increase (previous point at 0)"},
        {"0 0 x 0\n", "t.bot:1: expected 't x y z' (4 numbers)"},
        {"0 0 0 nan\n", "t.bot:1: expected 't x y z' (4 numbers)"},
        {"# nothing\njoin 1\n", "t.bot: no trajectory point ('t x y z')"},
        {"-0.2 0.35 0 0\n", "t.bot:1: time -0.2 is negative (times are seconds from the start)"},
    };
    for (size_t i = 0; i < sizeof bad / sizeof *bad; i++) {
        dev = NULL;
        assert_int_equal(
            ftm_script_device_parse(bad[i].text, strlen(bad[i].text), "t.bot", NULL, &dev, &err),
            FTM_EPARSE);
        assert_null(dev);
        assert_string_equal(err.message, bad[i].msg);
    }
    assert_int_equal(ftm_script_device_open("/nonexistent/x.bot", NULL, &dev, &err), FTM_EIO);
    assert_non_null(strstr(err.message, "/nonexistent/x.bot"));
}

static void test_mouse_probe(void **state)
{
    ftm_device *dev = NULL;
    ftm_error err = {0, ""};
    ftm_vec3 hip0 = {0, 0, 0};
    assert_int_equal(ftm_mouse_create(NULL, hip0, 0.002, 0.0, &dev, &err), FTM_OK);
    /* camera 0.5 m above, looking down -z; right = +x, up = +y */
    ftm_mouse_view v = {.eye = {0, 0, 0.5},
                        .forward = {0, 0, -1},
                        .right = {1, 0, 0},
                        .up = {0, 1, 0},
                        .fov_y = 2.0 * atan(0.5), /* half-height 0.25 m at depth 0.5 */
                        .width = 800,
                        .height = 400};
    assert_int_equal(ftm_mouse_set_view(dev, &v), FTM_OK);
    ftm_vec3 p;
    /* motion without the button: nothing */
    assert_int_equal(ftm_mouse_motion(dev, 100, 100), FTM_OK);
    assert_int_equal(ftm_mouse_target(dev, &p), FTM_OK);
    assert_true(norm(p) == 0.0);
    /* drag 200 px right, 100 px up: at depth 0.5, 400 px = 0.5 m */
    assert_int_equal(ftm_mouse_button(dev, true, 400, 200), FTM_OK);
    assert_int_equal(ftm_mouse_motion(dev, 600, 100), FTM_OK);
    assert_int_equal(ftm_mouse_button(dev, false, 600, 100), FTM_OK);
    assert_int_equal(ftm_mouse_target(dev, &p), FTM_OK);
    assert_true(fabs(p.x - 0.25) < 1e-12 && fabs(p.y - 0.125) < 1e-12 && fabs(p.z) < 1e-12);
    /* wheel: 3 units into the scene = 6 mm down */
    assert_int_equal(ftm_mouse_scroll(dev, 3.0), FTM_OK);
    assert_int_equal(ftm_mouse_target(dev, &p), FTM_OK);
    assert_true(fabs(p.z + 0.006) < 1e-12);
    assert_int_equal(ftm_device_read(dev, 0.0, &p), FTM_OK); /* no smoothing */
    assert_true(fabs(p.z + 0.006) < 1e-12);
    assert_int_equal(ftm_mouse_set_hip(dev, (ftm_vec3){0, 0, 0.1}), FTM_OK);
    assert_int_equal(ftm_mouse_scroll(dev, NAN), FTM_EINVAL);

    /* travel limits: QA's 200 wheel notches into a 0.11 m organ (top face
     * at z = 0.11) stop 0.02 m deep; a drag stays within the margin */
    ftm_vec3 lo = {-0.055, -0.055, 0}, hi = {0.055, 0.055, 0.11};
    assert_int_equal(ftm_mouse_set_limits(dev, lo, hi, 0.02, 0.11), FTM_OK);
    assert_int_equal(ftm_mouse_set_hip(dev, (ftm_vec3){0.01, 0, 0.15}), FTM_OK);
    for (int k = 0; k < 200; k++)
        assert_int_equal(ftm_mouse_scroll(dev, 1.0), FTM_OK);
    assert_int_equal(ftm_mouse_target(dev, &p), FTM_OK);
    assert_true(fabs(p.z - 0.09) < 1e-12 && fabs(p.x - 0.01) < 1e-12);
    assert_int_equal(ftm_mouse_scroll(dev, -10.0), FTM_OK); /* and back out: 1 cm */
    assert_int_equal(ftm_mouse_target(dev, &p), FTM_OK);
    assert_true(fabs(p.z - 0.11) < 1e-12);
    assert_int_equal(ftm_mouse_button(dev, true, 400, 200), FTM_OK);
    assert_int_equal(ftm_mouse_motion(dev, 800, 200), FTM_OK); /* far right */
    assert_int_equal(ftm_mouse_motion(dev, 800, 200), FTM_OK);
    assert_int_equal(ftm_mouse_target(dev, &p), FTM_OK);
    assert_true(p.x <= 0.165 + 1e-12);
    assert_int_equal(ftm_mouse_set_limits(dev, hi, lo, 0.02, 0.11), FTM_EINVAL);
    assert_int_equal(ftm_mouse_set_limits(dev, lo, hi, -1, 0.11), FTM_EINVAL);
    assert_int_equal(ftm_mouse_button(dev, false, 800, 200), FTM_OK);
    v.fov_y = 0;
    assert_int_equal(ftm_mouse_set_view(dev, &v), FTM_EINVAL);
    ftm_device_destroy(dev);

    /* smoothing: the haptic side follows with a time constant */
    assert_int_equal(ftm_mouse_create(NULL, hip0, 0.0, 0.01, &dev, &err), FTM_OK);
    assert_int_equal(ftm_device_read(dev, 0.0, &p), FTM_OK);
    assert_int_equal(ftm_mouse_set_hip(dev, (ftm_vec3){0.01, 0, 0}), FTM_OK);
    assert_int_equal(ftm_device_read(dev, 0.01, &p), FTM_OK);
    assert_true(fabs(p.x - 0.01 * (1.0 - exp(-1.0))) < 1e-12);
    /* the mouse calls refuse other devices */
    ftm_device *sd = NULL;
    assert_int_equal(ftm_script_device_parse("0 0 0 0", 7, "s", NULL, &sd, &err), FTM_OK);
    assert_int_equal(ftm_mouse_scroll(sd, 1.0), FTM_EINVAL);
    assert_int_equal(ftm_script_device_position(dev, 0.0, &p), FTM_EINVAL);
    ftm_device_destroy(sd);
    ftm_device_destroy(dev);
}

/* The wheel along a push axis (the contact's inward normal): in and back
 * out along one line whatever the view does meanwhile; zero: the view. */
static void test_mouse_push_axis(void **state)
{
    const double h = sqrt(0.5);
    ftm_device *dev = NULL;
    ftm_error err = {0, ""};
    assert_int_equal(ftm_mouse_create(NULL, (ftm_vec3){0, 0, 0}, 0.001, 0.0, &dev, &err), FTM_OK);
    ftm_mouse_view v = {.eye = {0, -0.5, 0.5}, .forward = {0, h, -h},
                        .right = {1, 0, 0}, .up = {0, h, h},
                        .fov_y = 0.7, .width = 800, .height = 400};
    assert_int_equal(ftm_mouse_set_view(dev, &v), FTM_OK);
    /* into a face whose outward normal is (0, 0.6, 0.8) (scaled: normalised) */
    assert_int_equal(ftm_mouse_set_push_axis(dev, (ftm_vec3){0, -3, -4}), FTM_OK);
    ftm_vec3 p;
    for (int k = 0; k < 10; k++)
        assert_int_equal(ftm_mouse_scroll(dev, 1.0), FTM_OK);
    assert_int_equal(ftm_mouse_target(dev, &p), FTM_OK);
    assert_true(fabs(p.x) < 1e-12 && fabs(p.y + 0.006) < 1e-12 && fabs(p.z + 0.008) < 1e-12);
    /* the camera orbits meanwhile: the way out is the same line */
    v.eye = (ftm_vec3){0.5, 0, 0.5};
    v.forward = (ftm_vec3){-h, 0, -h};
    v.right = (ftm_vec3){0, -1, 0};
    v.up = (ftm_vec3){-h, 0, h};
    assert_int_equal(ftm_mouse_set_view(dev, &v), FTM_OK);
    for (int k = 0; k < 10; k++)
        assert_int_equal(ftm_mouse_scroll(dev, -1.0), FTM_OK);
    assert_int_equal(ftm_mouse_target(dev, &p), FTM_OK);
    assert_true(norm(p) < 1e-12);
    /* no axis: the viewing direction again */
    assert_int_equal(ftm_mouse_set_push_axis(dev, (ftm_vec3){0, 0, 0}), FTM_OK);
    assert_int_equal(ftm_mouse_scroll(dev, 2.0), FTM_OK);
    assert_int_equal(ftm_mouse_target(dev, &p), FTM_OK);
    assert_true(fabs(p.x + 0.002 * h) < 1e-12 && fabs(p.z + 0.002 * h) < 1e-12);
    assert_int_equal(ftm_mouse_set_push_axis(dev, (ftm_vec3){NAN, 0, 1}), FTM_EINVAL);
    assert_int_equal(ftm_mouse_set_push_axis(dev, (ftm_vec3){INFINITY, 0, 1}), FTM_EINVAL);
    ftm_device_destroy(dev);
}

int main(void)
{
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(test_loop_start_stop),
        cmocka_unit_test(test_loop_device_lost),
        cmocka_unit_test(test_script_device),
        cmocka_unit_test(test_mouse_probe),
        cmocka_unit_test(test_mouse_push_axis),
    };
    return cmocka_run_group_tests(tests, NULL, NULL);
}
