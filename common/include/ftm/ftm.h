/* SPDX-License-Identifier: GPL-3.0-or-later */
/* FTM: force transmittal model core (libftm). Umbrella header. */
#ifndef FTM_FTM_H
#define FTM_FTM_H

#include "ftm/base.h"
#include "ftm/generate.h"
#include "ftm/labels.h"
#include "ftm/load.h"
#include "ftm/mesh.h"
#include "ftm/scene.h"
#include "ftm/sim.h"
#include "ftm/volume.h"

#define FTM_VERSION_MAJOR 0
#define FTM_VERSION_MINOR 1
#define FTM_VERSION_PATCH 0

#endif
