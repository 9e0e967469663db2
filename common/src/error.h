/* SPDX-License-Identifier: GPL-3.0-or-later */
/* Internal: clearing ftm_error, logging. ftm_error_set is public (ftm/base.h). */
#ifndef FTM_SRC_ERROR_H
#define FTM_SRC_ERROR_H

#include "ftm/base.h"

/* Clears err to FTM_OK with an empty message. */
void ftm_error_clear(ftm_error *err);

/* Emits a formatted message through a log hook (no-op if fn is NULL). */
#if defined(__GNUC__)
__attribute__((format(printf, 4, 5)))
#endif
void ftm_logf(ftm_log_fn fn, void *user, ftm_log_level level, const char *fmt, ...);

#endif
