#include "error.h"

#include <stdarg.h>
#include <stdio.h>

const char *ftm_strerror(int code)
{
    switch (code) {
    case FTM_OK: return "success";
    case FTM_EINVAL: return "invalid argument";
    case FTM_ENOMEM: return "out of memory";
    case FTM_EIO: return "input/output error";
    case FTM_EPARSE: return "malformed input";
    case FTM_ERANGE: return "index or count out of range";
    case FTM_EUNSTABLE: return "integration diverged";
    case FTM_ENOENT: return "no such scene, generator or command";
    default: return "unknown error";
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
