/* SPDX-License-Identifier: GPL-3.0-or-later */
/* Internal helpers shared by the ftm_fem sources: errors are filled by the
 * core's ftm_error_set (ftm/base.h). */
#ifndef FTM_FEM_INTERNAL_H
#define FTM_FEM_INTERNAL_H

#include "ftm/base.h"

#endif
