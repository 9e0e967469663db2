/* SPDX-License-Identifier: GPL-3.0-or-later */
/* FTM base types: vectors, status codes, error reports, logging hook.
 *
 * Every fallible call returns an int: FTM_OK (0) or a negative FTM_E* code.
 * Calls that can fail for a reason worth explaining also take an ftm_error*
 * (may be NULL) that receives a message naming what and where, e.g.
 * "liver.obj:17: face index 912 out of range (file has 400 vertices)".
 * On error no output parameter is written. */
#ifndef FTM_BASE_H
#define FTM_BASE_H

#include <stdbool.h>
#include <stddef.h>
#include <stdint.h>

#ifdef __cplusplus
extern "C" {
#endif

typedef struct ftm_vec3 {
    double x, y, z;
} ftm_vec3;

/* Every status code, once: X(name, value, description). This list makes
 * the enum below, ftm_strerror and ftm_err_name (common/src/error.c); a new
 * code is one line here. The codes from -20 on are the wire layer's
 * (ftm/wire.h, docs/protocol.md); they are in this list so that one
 * function describes any code a program meets. Values never change: they
 * are returned across library versions and logged. */
#define FTM_ERROR_CODES(X)                                                                      \
    X(FTM_OK, 0, "success")                                                                     \
    X(FTM_EINVAL, -1, "invalid argument")                     /* out of range, inconsistent */  \
    X(FTM_ENOMEM, -2, "out of memory")                                                          \
    X(FTM_EIO, -3, "input/output error")                      /* cannot open or read */         \
    X(FTM_EPARSE, -4, "malformed input")                      /* file, text or payload */       \
    X(FTM_ERANGE, -5, "index or count out of range")                                            \
    X(FTM_EUNSTABLE, -6, "integration diverged")              /* beyond recovery */             \
    X(FTM_ENOENT, -7, "no such scene, generator or command")                                    \
    X(FTM_ETOOBIG, -20, "message too large")                  /* over the size cap */           \
    X(FTM_EBUDGET, -21, "decoding memory budget exceeded")                                      \
    X(FTM_EVERSION, -22, "protocol version mismatch")         /* or arithmetic revision */      \
    X(FTM_ETIMEDOUT, -23, "timed out")                        /* nothing came in time */        \
    X(FTM_EDDS, -24, "DDS error")                             /* a DDS call failed */           \
    X(FTM_EAGAIN, -25, "queue full")                          /* message dropped */             \
    X(FTM_EACCESS, -26, "not permitted by DDS Security")

enum {
#define FTM_ERROR_ENUM_(name, value, text) name = value,
    FTM_ERROR_CODES(FTM_ERROR_ENUM_)
#undef FTM_ERROR_ENUM_
};

/* Short description of a status code ("invalid argument"); never NULL. */
const char *ftm_strerror(int code);

/* The code's symbolic name ("FTM_EINVAL"), for logs that an operator
 * matches against the documentation; "unknown" for a value not in the
 * list. Never NULL. */
const char *ftm_err_name(int code);

#define FTM_ERROR_MESSAGE_MAX 512

typedef struct ftm_error {
    int code;                            /* FTM_OK or a negative code */
    char message[FTM_ERROR_MESSAGE_MAX]; /* human-readable, names file/line or parameter */
} ftm_error;

/* Fills err (when not NULL) with code and a printf-formatted message and
 * returns code, so that an error path reads
 *     return ftm_error_set(err, FTM_EINVAL, "%s: node %d out of range", path, i);
 * The one formatter of ftm_error for libftm and the libraries on it. */
#if defined(__GNUC__)
__attribute__((format(printf, 3, 4)))
#endif
int ftm_error_set(ftm_error *err, int code, const char *fmt, ...);

typedef enum ftm_log_level {
    FTM_LOG_DEBUG = 0,
    FTM_LOG_INFO = 1,
    FTM_LOG_WARN = 2,
    FTM_LOG_ERROR = 3,
} ftm_log_level;

/* Optional log sink. The core has no globals, so each object that can log
 * takes one of these in its definition struct; NULL means silent. */
typedef void (*ftm_log_fn)(void *user, ftm_log_level level, const char *message);

#ifdef __cplusplus
}
#endif
#endif
