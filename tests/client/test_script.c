/* SPDX-License-Identifier: GPL-3.0-or-later */
/* The bot script format (client/script_text.h, docs/bot-script.md): one
 * parser for ftm-bot, ftm-server --offline and the scripted haptic device.
 * Points, commands, every refusal with its file and line, and the same
 * trajectory through every reader. */
#include <setjmp.h>
#include <stdarg.h>
#include <stddef.h>
#include <cmocka.h>

#include "device.h"
#include "script.h"
#include "script_text.h"

#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <unistd.h>

static const char good[] = "# t x y z\n"
                           "0.0 0.035 0.035 0.12   # above the top face\n"
                           "join 0.5\r\n"
                           "0.5\t0.035 0.035 0.106\n"
                           "\n"
                           "stiffness 1.0 80\n"
                           "depth 1.5 2 8\n"
                           "1.0 0.045 0.035 0.106\n"
                           "pause 2\n"
                           "leave 3\n"
                           "1.5 0.045 0.035 0.12\n"
                           "expect 0.6 1.2 force 0.5 3\n"
                           "expect\t0 0.4 contact no # before the press\n"
                           "expect 0 3 peak 0 1e3\n"
                           "expect 2 2 contact yes";

static void test_parse(void **state)
{
    (void)state;
    ftm_script_text st;
    ftm_error err = {0, ""};
    if (ftm_script_text_parse(good, sizeof good - 1, "g.bot", &st, &err))
        fail_msg("%s", err.message);
    assert_int_equal(st.npts, 4);
    assert_true(st.pts[1].t == 0.5 && st.pts[1].p.z == 0.106 && st.pts[3].p.z == 0.12);
    assert_true(st.join == 0.5 && st.leave == 3.0);
    assert_false(st.session_clock); /* the default: times from the process' start */
    assert_int_equal(st.ncmds, 3);
    assert_int_equal(st.cmds[0].keyword, FTM_SCRIPT_KW_STIFFNESS);
    assert_true(st.cmds[0].t == 1.0 && st.cmds[0].value[0] == 80 && st.cmds[0].line == 6);
    assert_int_equal(st.cmds[1].keyword, FTM_SCRIPT_KW_DEPTH);
    assert_true(st.cmds[1].value[0] == 2 && st.cmds[1].value[1] == 8);
    assert_int_equal(st.cmds[2].keyword, FTM_SCRIPT_KW_PAUSE);
    /* expectations are not commands: in their own list, in file order */
    assert_int_equal(st.nexpects, 4);
    const ftm_script_expect *e = st.expects;
    assert_true(e[0].kind == FTM_SCRIPT_EXPECT_FORCE && e[0].t0 == 0.6 && e[0].t1 == 1.2 &&
                e[0].lo == 0.5 && e[0].hi == 3 && e[0].line == 12);
    assert_true(e[1].kind == FTM_SCRIPT_EXPECT_CONTACT && !e[1].contact && e[1].t1 == 0.4 &&
                e[1].line == 13);
    assert_true(e[2].kind == FTM_SCRIPT_EXPECT_PEAK && e[2].lo == 0 && e[2].hi == 1e3);
    assert_true(e[3].kind == FTM_SCRIPT_EXPECT_CONTACT && e[3].contact && e[3].t0 == e[3].t1);
    /* interpolation: exact at the points, linear between, held outside */
    for (int32_t i = 0; i < st.npts; i++) {
        ftm_vec3 p = ftm_script_points_at(st.pts, st.npts, st.pts[i].t);
        assert_true(p.x == st.pts[i].p.x && p.y == st.pts[i].p.y && p.z == st.pts[i].p.z);
    }
    ftm_vec3 mid = ftm_script_points_at(st.pts, st.npts, 0.75);
    assert_true(mid.x == 0.035 + 0.5 * (0.045 - 0.035) && mid.z == 0.106);
    assert_true(ftm_script_points_at(st.pts, st.npts, -1).z == 0.12);
    assert_true(ftm_script_points_at(st.pts, st.npts, 99).x == 0.045);
    ftm_script_text_free(&st);
    assert_null(st.pts);
    /* `clock session`; the last `clock` line holds */
    static const char cs[] = "clock process\n0 0 0 0.1\nclock session # from the session\n";
    if (ftm_script_text_parse(cs, sizeof cs - 1, "c.bot", &st, &err))
        fail_msg("%s", err.message);
    assert_true(st.session_clock && st.npts == 1);
    ftm_script_text_free(&st);
}

/* The bot's loader and the device read a file to the same trajectory. */
static void test_readers_agree(void **state)
{
    (void)state;
    char path[] = "/tmp/ftm-test-script-XXXXXX";
    int fd = mkstemp(path);
    assert_true(fd >= 0);
    assert_true(write(fd, good, sizeof good - 1) == (ssize_t)(sizeof good - 1));
    close(fd);
    ftm_script sc;
    assert_int_equal(ftm_script_load(path, &sc), 0);
    ftm_device *dev = NULL;
    ftm_error err = {0, ""};
    if (ftm_script_device_open(path, NULL, &dev, &err))
        fail_msg("%s", err.message);
    unlink(path);
    assert_int_equal(sc.npts, 4);
    assert_int_equal(sc.ncmds, 3);
    assert_int_equal(sc.nexpects, 4);
    assert_true(sc.expects[3].e.line == 15 && sc.expects[3].frames == 0);
    ftm_wire_control ctl[3];
    ftm_wire_tissue now = {1, 1, 1, {1, 1, 1}};
    for (int i = 0; i < 3; i++)
        ftm_script_control(&sc.cmds[i], &now, &ctl[i]);
    assert_true(ctl[0].command == FTM_WIRE_CMD_TISSUE && sc.cmds[0].e.keyword == FTM_SCRIPT_KW_STIFFNESS);
    assert_true(ctl[1].command == FTM_WIRE_CMD_DEPTH_LIMITS && ctl[2].command == FTM_WIRE_CMD_PAUSE);
    assert_true(sc.join == 0.5 && sc.leave == 3.0);
    for (int k = -10; k <= 170; k++) {
        double t = k * 0.01;
        ftm_vec3 a = ftm_script_at(&sc, t), b;
        assert_int_equal(ftm_script_device_position(dev, t, &b), FTM_OK);
        assert_memory_equal(&a, &b, sizeof a);
    }
    assert_true(ftm_script_device_duration(dev) == 1.5);
    ftm_device_destroy(dev);
    ftm_script_free(&sc);
}

static void test_refusals(void **state)
{
    (void)state;
    static const struct {
        const char *text, *msg;
        size_t len; /* 0: strlen(text) */
    } bad[] = {
        {"0 0 0\n", "b.bot:1: expected 't x y z' (4 numbers)", 0},
        {"0 0 0 0 5\n", "b.bot:1: expected 't x y z' (4 numbers)", 0},
        /* a number is a whole token: "0+1" is not "0 +1" */
        {"7 0 0+1\n", "b.bot:1: expected 't x y z' (4 numbers)", 0},
        {"0 0 0 1e999\n", "b.bot:1: expected 't x y z' (4 numbers)", 0},
        {"0 0 0 0\n-1 0 0 0\n", "b.bot:2: time -1 is negative (times are seconds from the start)", 0},
        {"1 0 0 0\n1 0 0 0\n", "b.bot:2: time 1 does not increase (previous point at 1)", 0},
        {"0 0 0 0\njump 1\n", "b.bot:2: unknown keyword 'jump' (join, leave, pause, resume, "
                              "reset, stiffness, damping, mass, depth, expect, clock)", 0},
        {"clock\n", "b.bot:1: expected 'clock process|session'", 0},
        {"clock later\n", "b.bot:1: expected 'clock process|session'", 0},
        {"clock session 1\n", "b.bot:1: expected 'clock process|session'", 0},
        {"pause\n", "b.bot:1: expected '<keyword> <time> [values]'", 0},
        {"pause x\n", "b.bot:1: expected '<keyword> <time> [values]'", 0},
        {"join -2\n", "b.bot:1: time -2 is negative (times are seconds from the start)", 0},
        {"pause 1 2\n", "b.bot:1: extra text after 'pause'", 0},
        {"stiffness 1\n", "b.bot:1: 'stiffness' needs 1 finite number(s) after the time", 0},
        {"stiffness 1 0\n", "b.bot:1: stiffness must be > 0", 0},
        {"damping 1 -1\n", "b.bot:1: damping must be >= 0", 0},
        {"depth 1 5 2\n", "b.bot:1: depth limits must be whole numbers 0 <= min <= max <= 1000000", 0},
        {"depth 1 1.5 2\n", "b.bot:1: depth limits must be whole numbers 0 <= min <= max <= 1000000", 0},
        {"0 0 0 0\n0.5 0 0\0 0\n", "b.bot:2: NUL byte (not a text file?)", 19},
        /* expectations: the shape, finite whole numbers, ordered ranges */
#define EXPECT_SHAPE "expected 'expect <t0> <t1> force|peak <min> <max>' or " \
                     "'expect <t0> <t1> contact yes|no'"
        {"expect\n", "b.bot:1: " EXPECT_SHAPE, 0},
        {"expect 1 2\n", "b.bot:1: " EXPECT_SHAPE, 0},
        {"expect 1 2 force 1\n", "b.bot:1: " EXPECT_SHAPE, 0},
        {"expect 1 2 force 1 2 3\n", "b.bot:1: " EXPECT_SHAPE, 0},
        {"expect 1 2 torque 1 2\n", "b.bot:1: " EXPECT_SHAPE, 0},
        {"expect 1 2 Force 1 2\n", "b.bot:1: " EXPECT_SHAPE, 0},
        {"expect 1 2 contact maybe\n", "b.bot:1: " EXPECT_SHAPE, 0},
        {"expect 1 2 contact yes no\n", "b.bot:1: " EXPECT_SHAPE, 0},
        {"expect 1 2 contact\n", "b.bot:1: " EXPECT_SHAPE, 0},
        {"expect 1 2 peak 0+1 2\n", "b.bot:1: " EXPECT_SHAPE, 0},
        {"expect 1 inf force 0 2\n", "b.bot:1: " EXPECT_SHAPE, 0},
        {"expect 1 2 force 0 nan\n", "b.bot:1: " EXPECT_SHAPE, 0},
        {"expect 1 2 force 0 1e999\n", "b.bot:1: " EXPECT_SHAPE, 0},
        {"expect 1 2 force 0 2 # fine\nexpect x 2 force 0 2\n", "b.bot:2: " EXPECT_SHAPE, 0},
        {"expect -1 2 force 0 2\n",
         "b.bot:1: time -1 is negative (times are seconds from the start)", 0},
        {"expect 2 1 contact no\n", "b.bot:1: the window ends before it starts (2 > 1)", 0},
        {"expect 1 2 force 3 2\n", "b.bot:1: force bounds must be 0 <= min <= max [N] (got 3, 2)",
         0},
        {"expect 1 2 peak -1 2\n",
         "b.bot:1: force bounds must be 0 <= min <= max [N] (got -1, 2)", 0},
#undef EXPECT_SHAPE
    };
    for (size_t i = 0; i < sizeof bad / sizeof *bad; i++) {
        ftm_script_text st;
        ftm_error err = {0, ""};
        size_t len = bad[i].len ? bad[i].len : strlen(bad[i].text);
        int rc = ftm_script_text_parse(bad[i].text, len, "b.bot", &st, &err);
        if (rc != FTM_EPARSE)
            fail_msg("'%s': rc %d, expected FTM_EPARSE", bad[i].text, rc);
        assert_null(st.pts);
        assert_string_equal(err.message, bad[i].msg);
    }
    /* a line too long, and more than 64 commands */
    char *text = malloc(4096);
    assert_non_null(text);
    memset(text, ' ', 600);
    memcpy(text + 600, "0 0 0 0\n", 9);
    ftm_script_text st;
    ftm_error err = {0, ""};
    assert_int_equal(ftm_script_text_parse(text, strlen(text), "b.bot", &st, &err), FTM_EPARSE);
    assert_string_equal(err.message, "b.bot:1: line longer than 511 bytes");
    text[0] = '\0';
    for (int i = 0; i <= FTM_SCRIPT_COMMANDS_MAX; i++)
        strcat(text, "pause 1\n");
    assert_int_equal(ftm_script_text_parse(text, strlen(text), "b.bot", &st, &err), FTM_EPARSE);
    assert_string_equal(err.message, "b.bot:65: more than 64 commands");
    /* expectations have a bound of their own, beside the commands' */
    text[0] = '\0';
    for (int i = 0; i < FTM_SCRIPT_COMMANDS_MAX; i++)
        strcat(text, "pause 1\n");
    for (int i = 0; i <= FTM_SCRIPT_EXPECTS_MAX; i++)
        strcat(text, "expect 0 1 contact no\n");
    assert_int_equal(ftm_script_text_parse(text, strlen(text), "b.bot", &st, &err), FTM_EPARSE);
    assert_string_equal(err.message, "b.bot:129: more than 64 expectations");
    free(text);
    assert_int_equal(ftm_script_text_read("/nonexistent/s.bot", &st, &err), FTM_EIO);
    assert_non_null(strstr(err.message, "/nonexistent/s.bot: cannot open"));
}

/* What ftm-bot makes of the frames it applies: windows are inclusive, the
 * first frame that breaks an expectation is named, a window without frames
 * or not seen to its end fails. */
static void test_expect_eval(void **state)
{
    (void)state;
    static const char text[] = "0 0 0 0\n"
                               "expect 1 2 force 0.5 3\n"   /* 2: ok */
                               "expect 1 2 contact yes\n"   /* 3: ok */
                               "expect 0 3 peak 2 4\n"      /* 4: ok */
                               "expect 0 0.5 contact no\n"  /* 5: ok */
                               "expect 2.5 2.6 force 0 1\n" /* 6: no frames */
                               "expect 3.5 10 contact no\n" /* 7: stopped at 4 s */
                               "expect 1 2 peak 0 1\n"      /* 8: peak too high */
                               "expect 1 2 force 0 1\n"     /* 9: 2.5 N at 1.5 s */
                               "expect 1 2 contact no\n";   /* 10: in contact at 1 s */
    char path[] = "/tmp/ftm-test-expect-XXXXXX";
    int fd = mkstemp(path);
    assert_true(fd >= 0);
    assert_true(write(fd, text, sizeof text - 1) == (ssize_t)(sizeof text - 1));
    close(fd);
    ftm_script sc;
    assert_int_equal(ftm_script_load(path, &sc), 0);
    unlink(path);
    assert_int_equal(sc.nexpects, 9);
    static const struct {
        double t, fz;
        bool contact;
    } frames[] = {{0.2, 0, false}, {1.0, 1, true},  {1.5, 2.5, true},
                  {2.0, 3, true},  {2.4, 0, false}, {3.0, 0, false}};
    for (size_t i = 0; i < sizeof frames / sizeof *frames; i++)
        ftm_script_expect_frame(&sc, frames[i].t, (uint64_t)(frames[i].t * 100),
                                (ftm_vec3){0, 0, frames[i].fz}, frames[i].contact);
    FILE *f = tmpfile();
    assert_non_null(f);
    assert_int_equal(ftm_script_expect_report(&sc, "e.bot", 4.0, f), 5);
    char got[2048];
    rewind(f);
    size_t n = fread(got, 1, sizeof got - 1, f);
    got[n] = '\0';
    fclose(f);
    assert_string_equal(
        got,
        "e.bot:2: expect 1 2 force 0.5 3: ok (min 1 max 3 N over 3 frames)\n"
        "e.bot:3: expect 1 2 contact yes: ok (3 frames, all in contact)\n"
        "e.bot:4: expect 0 3 peak 2 4: ok (peak 3 N at t = 2.000 s over 6 frames)\n"
        "e.bot:5: expect 0 0.5 contact no: ok (1 frame, none in contact)\n"
        "e.bot:6: expect 2.5 2.6 force 0 1: FAILED: no frames in the window\n"
        "e.bot:7: expect 3.5 10 contact no: FAILED: the bot stopped at t = 4.000 s, before the "
        "window's end\n"
        "e.bot:8: expect 1 2 peak 0 1: FAILED: peak 3 N at t = 2.000 s over 3 frames\n"
        "e.bot:9: expect 1 2 force 0 1: FAILED: 2.5 N at t = 1.500 s (tick 150); min 1 max 3 N "
        "over 3 frames\n"
        "e.bot:10: expect 1 2 contact no: FAILED: in contact at t = 1.000 s (tick 100); 3 of 3 "
        "frames in contact\n");
    ftm_script_free(&sc);
}

int main(void)
{
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(test_parse),
        cmocka_unit_test(test_readers_agree),
        cmocka_unit_test(test_refusals),
        cmocka_unit_test(test_expect_eval),
    };
    return cmocka_run_group_tests(tests, NULL, NULL);
}
