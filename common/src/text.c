/* SPDX-License-Identifier: GPL-3.0-or-later */
#include "ftm/internal/text.h"

#include "error.h"

#include <errno.h>
#include <stdarg.h>
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/stat.h>

int ftm_text_read_file(const char *path, size_t max_bytes, char **data, size_t *length,
                       ftm_error *err)
{
    FILE *f = fopen(path, "rb");
    if (!f)
        return ftm_error_set(err, FTM_EIO, "%s: cannot open: %s", path, strerror(errno));
    struct stat st;
    if (fstat(fileno(f), &st) == 0 && S_ISDIR(st.st_mode)) { /* fopen opens one for reading */
        fclose(f);
        return ftm_error_set(err, FTM_EIO, "%s: is a directory, not a file", path);
    }
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
                return ftm_error_set(err, FTM_EIO, "%s: read error: %s", path, strerror(errno));
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
    /* Only at the very start: a mark further in stays text for the reader to
     * refuse, since it means files were pasted together. */
    t->pos = length >= 3 && memcmp(data, "\xEF\xBB\xBF", 3) == 0 ? 3 : 0;
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

static bool is_digit(char c)
{
    return c >= '0' && c <= '9';
}

static bool is_word(const char *tok, size_t len, const char *word)
{
    if (len != strlen(word))
        return false;
    for (size_t i = 0; i < len; i++)
        if ((tok[i] >= 'A' && tok[i] <= 'Z' ? tok[i] - 'A' + 'a' : tok[i]) != word[i])
            return false;
    return true;
}

/* Why a token that is not a plain decimal number was refused: strtod would
 * take hexadecimal and the words below, so they get a message of their own. */
static const char *why_not_number(const char *tok, size_t len, const char *otherwise)
{
    size_t i = len > 0 && (tok[0] == '+' || tok[0] == '-');
    const char *t = tok + i;
    size_t n = len - i;
    if (n >= 2 && t[0] == '0' && (t[1] == 'x' || t[1] == 'X'))
        return "hexadecimal numbers are not accepted (numbers are decimal)";
    if (is_word(t, n, "inf") || is_word(t, n, "infinity") || is_word(t, n, "nan") ||
        (n > 4 && is_word(t, 4, "nan(") && t[n - 1] == ')'))
        return "not a finite number (nan and inf are not accepted)";
    return otherwise;
}

/* Length of the decimal number at the start of tok: [+-] digits [. digits]
 * [e [+-] digits], with at least one mantissa digit; 0 if there is none. */
static size_t scan_decimal(const char *tok, size_t len)
{
    size_t i = 0, digits = 0;
    if (i < len && (tok[i] == '+' || tok[i] == '-'))
        i++;
    for (; i < len && is_digit(tok[i]); i++)
        digits++;
    if (i < len && tok[i] == '.')
        for (i++; i < len && is_digit(tok[i]); i++)
            digits++;
    if (digits == 0)
        return 0;
    if (i < len && (tok[i] == 'e' || tok[i] == 'E')) {
        size_t j = i + 1;
        if (j < len && (tok[j] == '+' || tok[j] == '-'))
            j++;
        size_t first = j;
        while (j < len && is_digit(tok[j]))
            j++;
        if (j > first)
            i = j;
    }
    return i;
}

const char *ftm_text_read_double(const char *tok, size_t len, double *out)
{
    if (len == 0 || scan_decimal(tok, len) != len)
        return why_not_number(tok, len, "not a number");
    /* strtod needs a terminated copy; long tokens (many digits, leading
     * zeros) are valid numbers too, so they get one on the heap. */
    char small[64];
    char *buf = len < sizeof small ? small : malloc(len + 1);
    if (!buf)
        return "out of memory";
    memcpy(buf, tok, len);
    buf[len] = '\0';
    char *endp;
    double v = strtod(buf, &endp); /* underflow yields a tiny or zero value: accepted */
    bool whole = endp == buf + len; /* not so only under a locale with another decimal point */
    if (buf != small)
        free(buf);
    if (!whole)
        return "not a number";
    if (!isfinite(v))
        return "out of range for a double";
    *out = v;
    return NULL;
}

const char *ftm_text_read_int(const char *tok, size_t len, int64_t *out)
{
    size_t i = len > 0 && (tok[0] == '+' || tok[0] == '-');
    size_t end = i;
    while (end < len && is_digit(tok[end]))
        end++;
    if (end == i || end != len)
        return why_not_number(tok, len, "not an integer");
    /* Leading zeros carry nothing: dropped, any length fits the buffer. */
    while (i + 1 < len && tok[i] == '0')
        i++;
    if (len - i > 19)
        return "out of range for a 64-bit integer";
    char buf[24];
    buf[0] = tok[0] == '-' ? '-' : '+';
    memcpy(buf + 1, tok + i, len - i);
    buf[1 + len - i] = '\0';
    errno = 0;
    long long v = strtoll(buf, NULL, 10);
    if (errno == ERANGE)
        return "out of range for a 64-bit integer";
    *out = v;
    return NULL;
}

bool ftm_text_parse_double(const char *tok, size_t len, double *out)
{
    return ftm_text_read_double(tok, len, out) == NULL;
}

bool ftm_text_parse_int(const char *tok, size_t len, int64_t *out)
{
    return ftm_text_read_int(tok, len, out) == NULL;
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
