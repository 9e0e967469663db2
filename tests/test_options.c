/* SPDX-License-Identifier: GPL-3.0-or-later */
/* ftm/options.h: one table drives the parser and --help; refusals name the
 * option; the parser can run many times in one process. */
#include "ftm/options.h"

#include <float.h>
#include <setjmp.h>
#include <stdarg.h>
#include <stddef.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <unistd.h>

#include <cmocka.h>

typedef struct vals {
    const char *scene, *list[4];
    int nlist;
    bool check;
    int32_t depth;
    uint32_t id;
    int64_t ticks;
    double rate, heartbeat, push;
} vals;

static int parse_item(const ftm_option *o, const char *v, void *field, char *why, size_t cap)
{
    vals *x = (vals *)((char *)field - offsetof(vals, list));
    if (x->nlist == 4) {
        snprintf(why, cap, "given more than 4 times");
        return -1;
    }
    x->list[x->nlist++] = v;
    return 0;
}

#define V vals
static const ftm_option table[] = {
    FTM_OPT_SECTION("things:"),
    FTM_OPT_STRING("scene", "NAME", V, scene, "the scene\nsecond line"),
    FTM_OPT_FLAG("check", V, check, "check only"),
    FTM_OPT_INT("depth", "N", V, depth, -1, 1000000, "depth"),
    FTM_OPT_INT("depth-floor", "N", V, depth, 0, 5, "another depth"),
    FTM_OPT_INT("id", "N", V, id, 1, UINT32_MAX, "id"),
    FTM_OPT_INT("ticks", "N", V, ticks, 1, INT64_MAX, "ticks"),
    FTM_OPT_DOUBLE("rate", "HZ", V, rate, 1, 100000, FTM_OPTION_WHOLE, "hertz", "rate"),
    FTM_OPT_DOUBLE("heartbeat", "S", V, heartbeat, 0, 10, FTM_OPTION_ABOVE_LO, "seconds", "hb"),
    FTM_OPT_DOUBLE("push", "M", V, push, 0, DBL_MAX, FTM_OPTION_ABOVE_LO, "metres", "push"),
    FTM_OPT_CUSTOM("item", "X", V, list, parse_item, "repeatable"),
    {0}};
#undef V
static const ftm_option_set set = {"prog", "usage: prog [options]", table, "the end"};

static char captured[4096];

/* Parses the arguments (after "prog") with stderr captured. */
static int run(vals *v, uint64_t *given, int *first, ...)
{
    char *argv[32] = {"prog"};
    int argc = 1;
    va_list ap;
    va_start(ap, first);
    for (char *a; argc < 31 && (a = va_arg(ap, char *));)
        argv[argc++] = a;
    va_end(ap);
    *v = (vals){.depth = -1, .rate = 1000, .heartbeat = 0.1};
    fflush(stderr);
    FILE *tmp = tmpfile();
    assert_non_null(tmp);
    int saved = dup(2);
    dup2(fileno(tmp), 2);
    int rc = ftm_options_parse(&set, argc, argv, v, given, first);
    fflush(stderr);
    dup2(saved, 2);
    close(saved);
    rewind(tmp);
    size_t n = fread(captured, 1, sizeof captured - 1, tmp);
    captured[n] = '\0';
    fclose(tmp);
    return rc;
}

static void assert_said(const char *want)
{
    if (!strstr(captured, want))
        fail_msg("no '%s' in '%s'", want, captured);
}

static void test_values(void **state)
{
    vals v;
    uint64_t given = 0;
    assert_int_equal(run(&v, &given, NULL, "--scene", "a b", "--check", "--depth=7", "--id",
                         "4294967295", "--ticks", "9223372036854775807", "--rate", "500",
                         "--heartbeat=10", "--push", "1e300", "--item", "x", "--item=y", NULL),
                     FTM_OPTIONS_OK);
    assert_string_equal(v.scene, "a b");
    assert_true(v.check);
    assert_int_equal(v.depth, 7);
    assert_true(v.id == UINT32_MAX);
    assert_true(v.ticks == INT64_MAX);
    assert_true(v.rate == 500 && v.heartbeat == 10 && v.push == 1e300);
    assert_int_equal(v.nlist, 2);
    assert_string_equal(v.list[1], "y");
    assert_true(ftm_options_given(&set, given, "scene"));
    assert_true(ftm_options_given(&set, given, "item"));
    assert_false(ftm_options_given(&set, given, "depth-floor"));
    assert_false(ftm_options_given(&set, given, "nosuch"));
    /* negative values in range, and an unambiguous prefix */
    assert_int_equal(run(&v, &given, NULL, "--depth", "-1", "--sc", "s", NULL), FTM_OPTIONS_OK);
    assert_int_equal(v.depth, -1);
    assert_string_equal(v.scene, "s");
    /* an exact name wins over a longer one it prefixes */
    assert_int_equal(run(&v, &given, NULL, "--depth", "3", NULL), FTM_OPTIONS_OK);
    assert_int_equal(v.depth, 3);
}

static void test_refusals(void **state)
{
    vals v;
    assert_int_equal(run(&v, NULL, NULL, "--scene", "--check", NULL), FTM_OPTIONS_BAD);
    assert_said("prog: --scene needs a value (NAME), not the option --check");
    assert_false(v.check);
    assert_int_equal(run(&v, NULL, NULL, "--scene", NULL), FTM_OPTIONS_BAD);
    assert_said("prog: --scene needs a value (NAME)");
    assert_int_equal(run(&v, NULL, NULL, "--scene=--odd", NULL), FTM_OPTIONS_OK);
    assert_string_equal(v.scene, "--odd");
    assert_int_equal(run(&v, NULL, NULL, "--check=yes", NULL), FTM_OPTIONS_BAD);
    assert_said("prog: --check takes no value");
    assert_int_equal(run(&v, NULL, NULL, "--nosuch", "1", NULL), FTM_OPTIONS_BAD);
    assert_said("prog: unknown option --nosuch");
    assert_int_equal(run(&v, NULL, NULL, "--de", "1", NULL), FTM_OPTIONS_BAD);
    assert_said("prog: option --de is ambiguous: --depth, --depth-floor");
    assert_int_equal(run(&v, NULL, NULL, "-x", NULL), FTM_OPTIONS_BAD);
    assert_said("prog: unknown option -x");
    assert_int_equal(run(&v, NULL, NULL, "stray", NULL), FTM_OPTIONS_BAD);
    assert_said("prog: unexpected argument 'stray'");
    /* integers: whole tokens in range, never wrapped */
    assert_int_equal(run(&v, NULL, NULL, "--id", "4294967296", NULL), FTM_OPTIONS_BAD);
    assert_said("prog: --id must be an integer in 1..4294967295 (got '4294967296')");
    assert_int_equal(run(&v, NULL, NULL, "--id", "-1", NULL), FTM_OPTIONS_BAD);
    assert_int_equal(run(&v, NULL, NULL, "--depth", " 5", NULL), FTM_OPTIONS_BAD);
    assert_int_equal(run(&v, NULL, NULL, "--depth", "1e3", NULL), FTM_OPTIONS_BAD);
    assert_int_equal(run(&v, NULL, NULL, "--ticks", "99999999999999999999", NULL), FTM_OPTIONS_BAD);
    /* numbers: finite, in range, whole where asked */
    assert_int_equal(run(&v, NULL, NULL, "--rate", "0.5", NULL), FTM_OPTIONS_BAD);
    assert_said("prog: --rate must be a whole number of hertz in [1, 100000] (got '0.5')");
    assert_int_equal(run(&v, NULL, NULL, "--heartbeat", "0", NULL), FTM_OPTIONS_BAD);
    assert_said("prog: --heartbeat must be a number of seconds in (0, 10] (got '0')");
    assert_int_equal(run(&v, NULL, NULL, "--push", "inf", NULL), FTM_OPTIONS_BAD);
    assert_said("prog: --push must be a number of metres > 0 (got 'inf')");
    assert_int_equal(run(&v, NULL, NULL, "--push", "nan", NULL), FTM_OPTIONS_BAD);
    assert_int_equal(run(&v, NULL, NULL, "--push", "5cm", NULL), FTM_OPTIONS_BAD);
    assert_int_equal(run(&v, NULL, NULL, "--item", "1", "--item", "2", "--item", "3", "--item",
                         "4", "--item", "5", NULL),
                     FTM_OPTIONS_BAD);
    assert_said("prog: --item given more than 4 times");
}

static void test_positional_and_help(void **state)
{
    vals v;
    int first = 0;
    /* arguments that are no options come last, in their order */
    assert_int_equal(run(&v, NULL, &first, "timing", "--scene", "s", "more", NULL), FTM_OPTIONS_OK);
    assert_string_equal(v.scene, "s");
    assert_int_equal(first, 3);
    assert_int_equal(run(&v, NULL, &first, "--check", NULL), FTM_OPTIONS_OK);
    assert_int_equal(first, 2);
    /* --help on stdout, from the table */
    fflush(stdout);
    FILE *tmp = tmpfile();
    assert_non_null(tmp);
    ftm_options_help(&set, tmp);
    rewind(tmp);
    char text[4096];
    size_t n = fread(text, 1, sizeof text - 1, tmp);
    text[n] = '\0';
    fclose(tmp);
    assert_non_null(strstr(text, "usage: prog [options]\nthings:\n  --scene NAME           the scene\n"
                                 "                         second line\n"));
    assert_non_null(strstr(text, "  --check                check only\n"));
    assert_non_null(strstr(text, "  -h, --help             this help\nthe end\n"));
}

int main(void)
{
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(test_values),
        cmocka_unit_test(test_refusals),
        cmocka_unit_test(test_positional_and_help),
    };
    return cmocka_run_group_tests(tests, NULL, NULL);
}
