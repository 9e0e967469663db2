/* SPDX-License-Identifier: GPL-3.0-or-later */
/* Internal to libftm, shared with session/'s script parser: reading text
 * files line by line with positions for error messages. Shared by the mesh
 * loaders and the scene parser. */
#ifndef FTM_INTERNAL_TEXT_H
#define FTM_INTERNAL_TEXT_H

#include "ftm/base.h"

#include <stdarg.h>

typedef struct ftm_text {
    const char *name; /* file name for messages */
    const char *data; /* NUL-terminated */
    size_t length;
    size_t pos;
    int32_t line; /* 1-based number of the line last returned */
} ftm_text;

/* Reads a whole file (NUL-terminated copy in *data, free() it). Refuses files
 * with NUL bytes and files over max_bytes; errors name the path. */
int ftm_text_read_file(const char *path, size_t max_bytes, char **data, size_t *length,
                       ftm_error *err);

/* A UTF-8 byte order mark at the very start of data is skipped (editors on
 * Windows write one); anywhere else it is ordinary text, and so an error
 * wherever a reader expects something else. */
void ftm_text_init(ftm_text *t, const char *name, const char *data, size_t length);

/* Next line without its terminator (\n or \r\n); false at end of input.
 * The line is not NUL-terminated: use the returned length. */
bool ftm_text_next_line(ftm_text *t, const char **line, size_t *length);

/* Splits the next whitespace-separated token off [*cur, end); false if none. */
bool ftm_text_token(const char **cur, const char *end, const char **tok, size_t *toklen);

/* An error at a line of a named text: FTM error code `code` with the message
 * "NAME:LINE: reason" (line > 0) or "NAME: reason", the name cut to 200
 * bytes so the reason fits. Returns code. */
#if defined(__GNUC__)
__attribute__((format(printf, 5, 6)))
#endif
int ftm_text_error(ftm_error *err, int code, const char *name, int32_t line, const char *fmt, ...);
int ftm_text_verror(ftm_error *err, int code, const char *name, int32_t line, const char *fmt,
                    va_list ap);

/* Whole-token number parsing, of any length. Doubles are decimal with an
 * optional exponent ("-1.5e-3", ".5", "2."); integers are decimal digits with
 * an optional sign. Returns NULL on success, else why the token is not one,
 * for a message like "bad coordinate '0x1p3': <why>": not a number,
 * hexadecimal, nan or inf, or out of range (for doubles, overflow; an
 * underflow gives a tiny or zero value and is accepted). */
const char *ftm_text_read_double(const char *tok, size_t len, double *out);
const char *ftm_text_read_int(const char *tok, size_t len, int64_t *out);
/* The same, as true on success. */
bool ftm_text_parse_double(const char *tok, size_t len, double *out);
bool ftm_text_parse_int(const char *tok, size_t len, int64_t *out);

#endif
