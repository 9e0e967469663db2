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
                           "1.5 0.045 0.035 0.12";

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
    assert_int_equal(st.ncmds, 3);
    assert_int_equal(st.cmds[0].keyword, FTM_SCRIPT_KW_STIFFNESS);
    assert_true(st.cmds[0].t == 1.0 && st.cmds[0].value[0] == 80 && st.cmds[0].line == 6);
    assert_int_equal(st.cmds[1].keyword, FTM_SCRIPT_KW_DEPTH);
    assert_true(st.cmds[1].value[0] == 2 && st.cmds[1].value[1] == 8);
    assert_int_equal(st.cmds[2].keyword, FTM_SCRIPT_KW_PAUSE);
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
                              "reset, stiffness, damping, mass, depth)", 0},
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
    free(text);
    assert_int_equal(ftm_script_text_read("/nonexistent/s.bot", &st, &err), FTM_EIO);
    assert_non_null(strstr(err.message, "/nonexistent/s.bot: cannot open"));
}

int main(void)
{
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(test_parse),
        cmocka_unit_test(test_readers_agree),
        cmocka_unit_test(test_refusals),
    };
    return cmocka_run_group_tests(tests, NULL, NULL);
}
