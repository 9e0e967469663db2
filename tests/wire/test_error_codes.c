/* SPDX-License-Identifier: GPL-3.0-or-later */
/* Status codes: one list (FTM_ERROR_CODES in ftm/base.h) makes the enum,
 * ftm_strerror and ftm_err_name, for the core's codes and the wire's alike;
 * ftm_error_set is the one formatter of ftm_error. */
#include <setjmp.h>
#include <stdarg.h>
#include <stddef.h>
#include <cmocka.h>

#include "ftm/wire.h"

#include <string.h>

typedef struct code_row {
    int value;
    const char *name, *text;
} code_row;

static const code_row rows[] = {
#define ROW_(name, value, text) {value, #name, text},
    FTM_ERROR_CODES(ROW_)
#undef ROW_
};
#define NROWS (sizeof rows / sizeof rows[0])

static void test_every_code_named(void **state)
{
    (void)state;
    assert_true(NROWS >= 15);
    for (size_t i = 0; i < NROWS; i++) {
        assert_string_equal(ftm_err_name(rows[i].value), rows[i].name);
        assert_string_equal(ftm_strerror(rows[i].value), rows[i].text);
        assert_string_equal(ftm_wire_strerror(rows[i].value), rows[i].text);
        assert_true(rows[i].value < 0 || (i == 0 && rows[i].value == FTM_OK));
        for (size_t j = 0; j < i; j++) {
            assert_int_not_equal(rows[i].value, rows[j].value);
            assert_string_not_equal(rows[i].text, rows[j].text);
        }
    }
}

/* The values are part of the API (returned, logged): they never move. */
static void test_values_and_names(void **state)
{
    (void)state;
    assert_int_equal(FTM_EINVAL, -1);
    assert_int_equal(FTM_ENOENT, -7);
    assert_int_equal(FTM_ETOOBIG, -20);
    assert_int_equal(FTM_EACCESS, -26);
    assert_string_equal(ftm_err_name(FTM_OK), "FTM_OK");
    assert_string_equal(ftm_err_name(FTM_EPARSE), "FTM_EPARSE");
    assert_string_equal(ftm_err_name(FTM_EBUDGET), "FTM_EBUDGET");
    /* a wire code is known to the core's ftm_strerror too */
    assert_string_equal(ftm_strerror(FTM_ETOOBIG), "message too large");
    assert_string_equal(ftm_strerror(FTM_EUNSTABLE), "integration diverged");
    assert_string_equal(ftm_strerror(-999), "unknown error");
    assert_string_equal(ftm_err_name(-999), "unknown");
    assert_string_equal(ftm_err_name(1), "unknown");
}

static void test_error_set(void **state)
{
    (void)state;
    ftm_error err = {0, ""};
    assert_int_equal(ftm_error_set(&err, FTM_ERANGE, "node %d of %s", 912, "liver.obj"),
                     FTM_ERANGE);
    assert_int_equal(err.code, FTM_ERANGE);
    assert_string_equal(err.message, "node 912 of liver.obj");
    assert_int_equal(ftm_error_set(NULL, FTM_EIO, "no report wanted"), FTM_EIO);
    /* a message longer than the buffer is cut, still terminated */
    char long_text[2 * FTM_ERROR_MESSAGE_MAX];
    memset(long_text, 'x', sizeof long_text - 1);
    long_text[sizeof long_text - 1] = '\0';
    ftm_error_set(&err, FTM_EINVAL, "%s", long_text);
    assert_int_equal(strlen(err.message), FTM_ERROR_MESSAGE_MAX - 1);
}

int main(void)
{
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(test_every_code_named),
        cmocka_unit_test(test_values_and_names),
        cmocka_unit_test(test_error_set),
    };
    return cmocka_run_group_tests(tests, NULL, NULL);
}
