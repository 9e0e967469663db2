#include "text.h"

#include "error.h"

#include <errno.h>
#include <stdarg.h>
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

int ftm_text_read_file(const char *path, size_t max_bytes, char **data, size_t *length,
                       ftm_error *err)
{
    FILE *f = fopen(path, "rb");
    if (!f)
        return ftm_error_set(err, FTM_EIO, "%s: cannot open: %s", path, strerror(errno));
    size_t cap = 1 << 16, len = 0;
    char *buf = malloc(cap + 1);
    if (!buf) {
        fclose(f);
        return ftm_error_set(err, FTM_ENOMEM, "%s: out of memory", path);
    }
    for (;;) {
        if (len == cap) {
            if (cap >= max_bytes) {
                free(buf);
                fclose(f);
                return ftm_error_set(err, FTM_ERANGE, "%s: file larger than %zu bytes", path,
                                     max_bytes);
            }
            size_t ncap = cap * 2 > max_bytes ? max_bytes : cap * 2;
            char *nb = realloc(buf, ncap + 1);
            if (!nb) {
                free(buf);
                fclose(f);
                return ftm_error_set(err, FTM_ENOMEM, "%s: out of memory", path);
            }
            buf = nb;
            cap = ncap;
        }
        size_t n = fread(buf + len, 1, cap - len, f);
        len += n;
        if (n == 0) {
            if (ferror(f)) {
                free(buf);
                fclose(f);
                return ftm_error_set(err, FTM_EIO, "%s: read error", path);
            }
            break;
        }
    }
    fclose(f);
    if (memchr(buf, '\0', len)) {
        free(buf);
        return ftm_error_set(err, FTM_EPARSE, "%s: binary data (NUL byte) in a text file", path);
    }
    buf[len] = '\0';
    *data = buf;
    *length = len;
    return FTM_OK;
}

void ftm_text_init(ftm_text *t, const char *name, const char *data, size_t length)
{
    t->name = name;
    t->data = data;
    t->length = length;
    t->pos = 0;
    t->line = 0;
}

bool ftm_text_next_line(ftm_text *t, const char **line, size_t *length)
{
    if (t->pos >= t->length)
        return false;
    const char *start = t->data + t->pos;
    const char *nl = memchr(start, '\n', t->length - t->pos);
    size_t n = nl ? (size_t)(nl - start) : t->length - t->pos;
    t->pos += n + (nl ? 1 : 0);
    if (n > 0 && start[n - 1] == '\r')
        n--;
    t->line++;
    *line = start;
    *length = n;
    return true;
}

static bool is_space(char c)
{
    return c == ' ' || c == '\t' || c == '\r' || c == '\v' || c == '\f';
}

bool ftm_text_token(const char **cur, const char *end, const char **tok, size_t *toklen)
{
    const char *p = *cur;
    while (p < end && is_space(*p))
        p++;
    if (p >= end) {
        *cur = p;
        return false;
    }
    const char *s = p;
    while (p < end && !is_space(*p))
        p++;
    *tok = s;
    *toklen = (size_t)(p - s);
    *cur = p;
    return true;
}

bool ftm_text_parse_double(const char *tok, size_t len, double *out)
{
    char buf[64];
    if (len == 0 || len >= sizeof buf)
        return false;
    memcpy(buf, tok, len);
    buf[len] = '\0';
    char *endp;
    double v = strtod(buf, &endp); /* underflow yields a tiny or zero value: accepted */
    if (endp != buf + len || !isfinite(v))
        return false; /* junk, "nan", "inf" or overflow */
    *out = v;
    return true;
}

bool ftm_text_parse_int(const char *tok, size_t len, int64_t *out)
{
    char buf[32];
    if (len == 0 || len >= sizeof buf)
        return false;
    memcpy(buf, tok, len);
    buf[len] = '\0';
    char *endp;
    errno = 0;
    long long v = strtoll(buf, &endp, 10);
    if (endp != buf + len || errno == ERANGE)
        return false;
    *out = v;
    return true;
}

int ftm_text_verror(ftm_error *err, int code, const char *name, int32_t line, const char *fmt,
                    va_list ap)
{
    char msg[FTM_ERROR_MESSAGE_MAX];
    vsnprintf(msg, sizeof msg, fmt, ap);
    if (line > 0)
        return ftm_error_set(err, code, "%.200s:%d: %s", name, (int)line, msg);
    return ftm_error_set(err, code, "%.200s: %s", name, msg);
}

int ftm_text_error(ftm_error *err, int code, const char *name, int32_t line, const char *fmt, ...)
{
    va_list ap;
    va_start(ap, fmt);
    int rc = ftm_text_verror(err, code, name, line, fmt, ap);
    va_end(ap);
    return rc;
}
