/* SPDX-License-Identifier: GPL-3.0-or-later */
/* ftm-bot scripts: the format's parser (ftm_script_text_parse) and its
 * three readers: the bot's loader (ftm_script_load, a path), and the
 * scripted haptic device (ftm_script_device_parse). Properties: a refusal
 * has a message naming the file; an accepted script has times >= 0 that
 * increase and a finite trajectory; every reader accepts the same texts
 * (the device also needs a point) and sees the same trajectory, bit for
 * bit. Before they shared one parser, the bot read "7 0 0+1" as four
 * numbers and the device refused it. Expectations: accepted ones have
 * finite, ordered windows and bounds, the loader keeps them as parsed, and
 * checking frames against them and reporting never fails more than there
 * are. */
#include "fuzz.h"

#include "device.h"
#include "script.h"
#include "script_text.h"

#include <math.h>
#include <stdio.h>
#include <string.h>

int LLVMFuzzerTestOneInput(const uint8_t *data, size_t size)
{
    const char *text = (const char *)data;
    ftm_script_text st;
    ftm_error err;
    memset(&err, 0, sizeof err);
    int rc = ftm_script_text_parse(text, size, "f.bot", &st, &err);
    if (rc != FTM_OK) {
        fuzz_check(rc < 0 && st.pts == NULL && strstr(err.message, "f.bot") != NULL);
    } else {
        for (int32_t i = 0; i < st.npts; i++)
            fuzz_check(st.pts[i].t >= 0 && (i == 0 || st.pts[i].t > st.pts[i - 1].t));
        fuzz_check(st.ncmds >= 0 && st.ncmds <= FTM_SCRIPT_COMMANDS_MAX);
        for (int32_t i = 0; i < st.ncmds; i++)
            fuzz_check(st.cmds[i].t >= 0 && isfinite(st.cmds[i].value[0]) &&
                       isfinite(st.cmds[i].value[1]));
        fuzz_check(st.nexpects >= 0 && st.nexpects <= FTM_SCRIPT_EXPECTS_MAX);
        for (int32_t i = 0; i < st.nexpects; i++) {
            const ftm_script_expect *e = &st.expects[i];
            fuzz_check(e->kind >= FTM_SCRIPT_EXPECT_FORCE && e->kind <= FTM_SCRIPT_EXPECT_CONTACT);
            fuzz_check(e->t0 >= 0 && e->t0 <= e->t1 && isfinite(e->t1) && e->line >= 1);
            fuzz_check(e->lo >= 0 && e->lo <= e->hi && isfinite(e->hi));
        }
    }

    ftm_script sc;
    const char *path = fuzz_write_file("f.bot", data, size);
    int loaded = ftm_script_load(path, &sc) == 0;
    fuzz_check(loaded == (rc == FTM_OK));
    ftm_device *d = NULL;
    int drc = ftm_script_device_parse(text, size, "f.bot", NULL, &d, &err);
    fuzz_check((drc == FTM_OK) == (rc == FTM_OK && st.npts > 0));
    if (drc != FTM_OK)
        fuzz_check(d == NULL && strstr(err.message, "f.bot") != NULL);
    if (loaded) {
        fuzz_check(sc.npts == st.npts && sc.ncmds == st.ncmds);
        fuzz_check(sc.join == st.join && sc.leave == st.leave);
        fuzz_check(sc.nexpects == st.nexpects);
        for (int32_t i = 0; i < sc.nexpects; i++)
            fuzz_check(memcmp(&sc.expects[i].e, &st.expects[i], sizeof st.expects[i]) == 0 &&
                       sc.expects[i].frames == 0);
        /* frames at every window's ends, in contact and not */
        for (int32_t i = 0; i < sc.nexpects; i++) {
            const ftm_script_expect e = sc.expects[i].e;
            ftm_script_expect_frame(&sc, e.t0, (uint64_t)i, (ftm_vec3){0, 0, e.lo}, i % 2 == 0);
            ftm_script_expect_frame(&sc, e.t1, (uint64_t)i, (ftm_vec3){e.hi, 0, 0}, i % 3 == 0);
        }
        static FILE *null;
        if (!null)
            null = fopen("/dev/null", "w");
        if (null) {
            int failed = ftm_script_expect_report(&sc, "f.bot", 1.0, null);
            fuzz_check(failed >= 0 && failed <= sc.nexpects);
        }
    }
    if (d) {
        double dur = ftm_script_device_duration(d);
        fuzz_check(isfinite(dur) && dur >= 0 && dur == st.pts[st.npts - 1].t);
        for (int k = -1; k <= 9; k++) {
            double t = dur * k / 8.0;
            ftm_vec3 a, b = ftm_script_at(&sc, t), c = ftm_script_points_at(st.pts, st.npts, t);
            fuzz_check(ftm_script_device_position(d, t, &a) == FTM_OK);
            fuzz_check(isfinite(a.x) && isfinite(a.y) && isfinite(a.z));
            fuzz_check(memcmp(&a, &b, sizeof a) == 0 && memcmp(&a, &c, sizeof a) == 0);
        }
        ftm_device_destroy(d);
    }
    if (loaded)
        ftm_script_free(&sc);
    if (rc == FTM_OK)
        ftm_script_text_free(&st);
    return 0;
}
