/* SPDX-License-Identifier: GPL-3.0-or-later */
/* Checks of a material definition, shared by the generators, the loaders
 * and ftm_mesh_with_material, so that every way to make a mesh accepts the
 * same materials. */
#ifndef FTM_SRC_MATERIAL_H
#define FTM_SRC_MATERIAL_H

#include "ftm/generate.h"

/* FTM_EINVAL with "WHO: node mass must be > 0 (got -1)" unless mass and
 * stiffness are finite and > 0, damping finite and >= 0, and each axis
 * scale finite and > 0. */
int ftm_material_check(const ftm_material_def *m, const char *who, ftm_error *err);

#endif
