/* SPDX-License-Identifier: GPL-3.0-or-later */
#include "error.h"

#include <stdarg.h>
#include <stdio.h>

/* Both from the one list in ftm/base.h. */
const char *ftm_strerror(int code)
{
    switch (code) {
#define FTM_ERROR_TEXT_(name, value, text) case name: return text;
        FTM_ERROR_CODES(FTM_ERROR_TEXT_)
#undef FTM_ERROR_TEXT_
    default: return "unknown error";
    }
}

const char *ftm_err_name(int code)
{
    switch (code) {
#define FTM_ERROR_NAME_(name, value, text) case name: return #name;
        FTM_ERROR_CODES(FTM_ERROR_NAME_)
#undef FTM_ERROR_NAME_
    default: return "unknown";
    }
}

int ftm_error_set(ftm_error *err, int code, const char *fmt, ...)
{
    if (err) {
        err->code = code;
        va_list ap;
        va_start(ap, fmt);
        vsnprintf(err->message, sizeof err->message, fmt, ap);
        va_end(ap);
    }
    return code;
}

void ftm_error_clear(ftm_error *err)
{
    if (err) {
        err->code = FTM_OK;
        err->message[0] = '\0';
    }
}

void ftm_logf(ftm_log_fn fn, void *user, ftm_log_level level, const char *fmt, ...)
{
    if (!fn)
        return;
    char buf[512];
    va_list ap;
    va_start(ap, fmt);
    vsnprintf(buf, sizeof buf, fmt, ap);
    va_end(ap);
    fn(user, level, buf);
}
