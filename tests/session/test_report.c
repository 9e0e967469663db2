/* SPDX-License-Identifier: GPL-3.0-or-later */
/* The session report (server/report.h): accumulation, the participant cap,
 * and JSON that stays valid whatever names the peers send. */
#include "report.h"

#include <math.h>
#include <setjmp.h>
#include <stdarg.h>
#include <stddef.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include <cmocka.h>

/* The report as ftm_report_write_json writes it (the caller frees it). */
static char *json_of(const ftm_report *r, const ftm_report_session *s)
{
    char *buf = NULL;
    size_t len = 0;
    FILE *f = open_memstream(&buf, &len);
    assert_non_null(f);
    assert_int_equal(ftm_report_write_json(r, s, f), 0);
    fclose(f);
    return buf;
}

static void test_contact_stats(void **state)
{
    (void)state;
    ftm_report r = {0};
    assert_int_equal(ftm_report_seen(&r, 11, "trainee", "anna", 5), 0);
    ftm_report_probe *q = &r.parts[0].probes[1];
    q->touches++;
    ftm_report_contact(q, 10, (ftm_vec3){3, 4, 0}, 0.002, false, false);  /* 5 N */
    ftm_report_contact(q, 11, (ftm_vec3){0, 0, -6}, 0.004, true, false);  /* 6 N */
    ftm_report_contact(q, 12, (ftm_vec3){6, 0, 0}, 0.001, false, false);  /* 6 N again: first kept */
    assert_int_equal(q->contact_ticks, 3);
    assert_int_equal(q->limited_ticks, 1);
    assert_true(q->peak_force == 6.0);
    assert_int_equal(q->peak_tick, 11);
    assert_true(q->force_sum == 17.0);
    assert_true(q->max_push == 0.004);
    /* seen again: same entry, role and name updated, first tick kept */
    assert_int_equal(ftm_report_seen(&r, 11, "observer", "anna b", 40), 0);
    const ftm_report_part *p = &r.parts[0];
    assert_int_equal(r.count, 1);
    assert_string_equal(p->role, "observer");
    assert_int_equal(p->first_tick, 5);
    assert_int_equal(p->last_tick, 40);
    assert_int_equal(ftm_report_index(&r, 11), 0);
    assert_int_equal(ftm_report_index(&r, 12), -1);
    ftm_report_free(&r);
}

/* A spike of an unstable stretch (the guard substepping) is marked: the peak
 * taken there says so in the JSON, and the substepped ticks are counted. */
static void test_unstable_peak_marked(void **state)
{
    (void)state;
    ftm_report r = {0};
    assert_int_equal(ftm_report_seen(&r, 11, "trainee", "anna", 5), 0);
    ftm_report_probe *q = &r.parts[0].probes[0];
    q->touches = 1;
    ftm_report_contact(q, 10, (ftm_vec3){0, 0, 2}, 0.002, false, false);
    ftm_report_contact(q, 11, (ftm_vec3){0, 0, 65}, 0.002, false, true); /* the spike */
    ftm_report_contact(q, 12, (ftm_vec3){0, 0, 3}, 0.002, false, true);
    assert_int_equal(q->unstable_ticks, 2);
    assert_true(q->peak_unstable);
    ftm_report_session s = {"ward3", "default", NULL, 0, 3000, 1000.0, 8, 8, 0, 1, NULL, false};
    char *buf = json_of(&r, &s);
    if (!strstr(buf, "\"peak_force_n\":65,") || !strstr(buf, "\"unstable_ticks\":2,\"peak_while_unstable\":true}"))
        fail_msg("unstable peak not marked: %s", buf);
    free(buf);
    /* a higher, stable peak later: no longer marked */
    ftm_report_contact(q, 13, (ftm_vec3){0, 0, 70}, 0.002, false, false);
    assert_false(q->peak_unstable);
    ftm_report_free(&r);
}

static void test_cap(void **state)
{
    (void)state;
    ftm_report r = {0};
    for (uint32_t id = 1; id <= FTM_REPORT_MAX_PARTICIPANTS + 10; id++)
        ftm_report_seen(&r, id, "bot", "x", id);
    assert_int_equal(r.count, FTM_REPORT_MAX_PARTICIPANTS);
    assert_int_equal(r.dropped, 10);
    assert_int_equal(ftm_report_seen(&r, 99999, "bot", "x", 1), -1);
    assert_int_equal(ftm_report_seen(&r, 1, "bot", "x", 2), 0); /* a kept one still updates */
    ftm_report_free(&r);
}

static void test_json_escapes_names(void **state)
{
    (void)state;
    ftm_report r = {0};
    int32_t k = ftm_report_seen(&r, 7, "trainee", "a\"b\\c\x01\n\xc3\xa9", 0);
    assert_int_equal(k, 0);
    ftm_report_part *p = &r.parts[k];
    p->probes[0].touches = 1;
    ftm_report_contact(&p->probes[0], 3, (ftm_vec3){0, 0, 2}, 0.001, false, false);
    uint8_t digest[2] = {0xab, 0x01};
    ftm_report_session s = {"ward \"3\"", "default", digest, 2, 1000, 1000.0, 8, 8, 0, 0, NULL, false};
    char *buf = json_of(&r, &s);
    /* UTF-8 kept as it is (not one \u00XX per byte: that decodes as "Ã©") */
    if (!strstr(buf, "\"name\":\"a\\\"b\\\\c\\u0001\\u000a\xc3\xa9\""))
        fail_msg("name not escaped: %s", buf);
    assert_non_null(strstr(buf, "\"session\":\"ward \\\"3\\\"\""));
    assert_non_null(strstr(buf, "\"scene_digest\":\"ab01\""));
    assert_non_null(strstr(buf, "\"seconds\":1,"));
    assert_non_null(strstr(buf, "\"contact_ticks\":1,"));
    assert_non_null(strstr(buf, "\"peak_force_n\":2,\"peak_force_tick\":3,"));
    free(buf);
    ftm_report_free(&r);
}

/* The instructors' changes: in order, with the tick they were handled
 * after and its time, kept up to the bound and counted beyond it. */
static void test_events(void **state)
{
    (void)state;
    ftm_report r = {0};
    ftm_report_event_add(&r, 1447, 15, "tissue", "stiffness %g N/m (was %g)", 80.0, 50.0);
    ftm_report_event_add(&r, 2000, 15, "pause", "%s", "");
    ftm_report_event_add(&r, 2500, 16, "depth limits", "[%d, %d], depth %d", 2, 6, 6);
    assert_int_equal(r.nevents, 3);
    ftm_report_session s = {"ward3", "default", NULL, 0, 3000, 1000.0, 8, 8, 0, 1, NULL, false};
    char *buf = json_of(&r, &s);
    const char *want = "\"events_not_reported\":0,\"events\":[\n"
                       " {\"tick\":1447,\"seconds\":1.4470000000000001,\"by\":15,\"what\":\"tissue\","
                       "\"detail\":\"stiffness 80 N/m (was 50)\"},\n"
                       " {\"tick\":2000,\"seconds\":2,\"by\":15,\"what\":\"pause\",\"detail\":\"\"},\n"
                       " {\"tick\":2500,\"seconds\":2.5,\"by\":16,\"what\":\"depth limits\","
                       "\"detail\":\"[2, 6], depth 6\"}\n]}\n";
    if (!strstr(buf, want))
        fail_msg("events: %s", buf);
    free(buf);
    for (int i = 3; i < FTM_REPORT_MAX_EVENTS + 5; i++)
        ftm_report_event_add(&r, (uint64_t)i, 15, "reset", "%s", "");
    assert_int_equal(r.nevents, FTM_REPORT_MAX_EVENTS);
    assert_int_equal(r.events_dropped, 5);
    buf = json_of(&r, &s);
    assert_non_null(strstr(buf, "\"events_not_reported\":5,"));
    free(buf);
    ftm_report_free(&r);
    assert_null(r.events);
}

/* A session's recording in the report: where (tick, time) and why it
 * stopped on a write error, and what the file kept; no field while it
 * recorded to the end (a replay's report is then the same bytes) or for a
 * run that recorded nothing. */
static void test_recording(void **state)
{
    (void)state;
    ftm_report r = {0};
    ftm_report_recording g = {1503, 1.5, "recording s.rec: write failed: No space left on device",
                              241664, 1490, NULL, 0, NULL};
    ftm_report_session s = {"ward3", "default", NULL, 0, 3000, 1000.0, 8, 8, 0, 0, NULL, false};
    char *buf = json_of(&r, &s);
    assert_null(strstr(buf, "\"recording\""));
    free(buf);
    s.recording = &g;
    buf = json_of(&r, &s);
    if (strstr(buf, "\"recording\"") || !strstr(buf, "\n],\"events_not_reported\":0,"))
        fail_msg("recording ok: %s", buf);
    free(buf);
    s.recording_stopped = true;
    buf = json_of(&r, &s);
    if (!strstr(buf, ",\"recording\":{\"ok\":false,\"stopped_tick\":1503,\"stopped_seconds\":1.5,"
                     "\"error\":\"recording s.rec: write failed: No space left on device\","
                     "\"kept_bytes\":241664,\"kept_to_tick\":1490},"))
        fail_msg("recording stopped: %s", buf);
    free(buf);
    /* why it has not recorded on, then where it did */
    g.not_resumed = "204800 bytes free where it records, it waits for 1048576";
    buf = json_of(&r, &s);
    if (!strstr(buf, "\"kept_to_tick\":1490,\"not_resumed\":\"204800 bytes free where it "
                     "records, it waits for 1048576\"},"))
        fail_msg("recording not resumed: %s", buf);
    free(buf);
    g.resumed_file = "s.rec.1";
    g.resumed_tick = 2200;
    buf = json_of(&r, &s);
    if (!strstr(buf, "\"kept_to_tick\":1490,\"resumed_tick\":2200,\"resumed_file\":\"s.rec.1\"},"))
        fail_msg("recording resumed: %s", buf);
    free(buf);
    ftm_report_free(&r);
}

/* A name that is not UTF-8 (a peer may send any bytes): every ill-formed
 * byte becomes U+FFFD, well-formed sequences are kept, the result is valid
 * UTF-8; a figure that is not finite is null (JSON has no NaN). */
static void test_json_not_utf8(void **state)
{
    (void)state;
    static const struct {
        const char *name, *json;
    } cases[] = {
        {"\xe2\x82\xac \xf0\x9f\x98\x80", "\xe2\x82\xac \xf0\x9f\x98\x80"}, /* euro, emoji */
        {"x\xff\xfey", "x\\ufffd\\ufffdy"},       /* never in UTF-8 */
        {"\x80z", "\\ufffdz"},                      /* a lone continuation byte */
        {"\xc0\xaf", "\\ufffd\\ufffd"},              /* overlong '/' */
        {"\xed\xa0\x80", "\\ufffd\\ufffd\\ufffd"},    /* a surrogate, U+D800 */
        {"\xf4\x90\x80\x80", "\\ufffd\\ufffd\\ufffd\\ufffd"}, /* above U+10FFFF */
        {"ab\xe2\x82", "ab\\ufffd\\ufffd"},          /* cut at the end */
        {"\x7f", "\\u007f"},                        /* DEL is a control character */
    };
    for (size_t i = 0; i < sizeof cases / sizeof cases[0]; i++) {
        ftm_report r = {0};
        int32_t k = ftm_report_seen(&r, 7, "trainee", cases[i].name, 0);
        assert_int_equal(k, 0);
        ftm_report_probe *q = &r.parts[k].probes[0];
        q->touches = 1;
        ftm_report_contact(q, 3, (ftm_vec3){0, 0, 2}, 0.001, false, false);
        if (i == 0)
            q->max_push = NAN;
        ftm_report_session s = {"s", "default", NULL, 0, 10, 1000.0, 8, 8, 0, 0, NULL, false};
        char *buf = json_of(&r, &s);
        char want[128];
        snprintf(want, sizeof want, "\"name\":\"%s\"", cases[i].json);
        if (!strstr(buf, want))
            fail_msg("case %zu: want %s in %s", i, want, buf);
        if (i == 0 && !strstr(buf, "\"max_push_m\":null,"))
            fail_msg("NaN written as a number: %s", buf);
        assert_null(strstr(buf, "nan"));
        free(buf);
        ftm_report_free(&r);
    }
}

int main(void)
{
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(test_contact_stats),
        cmocka_unit_test(test_cap),
        cmocka_unit_test(test_unstable_peak_marked),
        cmocka_unit_test(test_json_escapes_names),
        cmocka_unit_test(test_json_not_utf8),
        cmocka_unit_test(test_events),
        cmocka_unit_test(test_recording),
    };
    return cmocka_run_group_tests(tests, NULL, NULL);
}
