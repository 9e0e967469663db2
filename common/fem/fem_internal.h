/* Internal helpers shared by the ftm_fem sources. */
#ifndef FTM_FEM_INTERNAL_H
#define FTM_FEM_INTERNAL_H

#include "ftm/base.h"

/* Formats a message into err (if not NULL) and returns code. */
#if defined(__GNUC__)
__attribute__((format(printf, 3, 4)))
#endif
int ftm_fem_fail(ftm_error *err, int code, const char *fmt, ...);

#endif
