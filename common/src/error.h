/* Internal: filling ftm_error. */
#ifndef FTM_SRC_ERROR_H
#define FTM_SRC_ERROR_H

#include "ftm/base.h"

/* Formats a message into err (if not NULL) and returns code, so that error
 * paths read: return ftm_error_set(err, FTM_EINVAL, "%s: ...", name); */
#if defined(__GNUC__)
__attribute__((format(printf, 3, 4)))
#endif
int ftm_error_set(ftm_error *err, int code, const char *fmt, ...);

/* Clears err to FTM_OK with an empty message. */
void ftm_error_clear(ftm_error *err);

/* Emits a formatted message through a log hook (no-op if fn is NULL). */
#if defined(__GNUC__)
__attribute__((format(printf, 4, 5)))
#endif
void ftm_logf(ftm_log_fn fn, void *user, ftm_log_level level, const char *fmt, ...);

#endif
