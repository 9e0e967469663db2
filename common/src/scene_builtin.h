/* SPDX-License-Identifier: GPL-3.0-or-later */
/* The built-in scenes (scene_builtin.c), for the scene loader. */
#ifndef FTM_SRC_SCENE_BUILTIN_H
#define FTM_SRC_SCENE_BUILTIN_H

#include <stddef.h>

/* The index of the built-in scene called name, or -1. */
int ftm_scene_builtin_index(const char *name);

/* "default, table3, ..." for messages. */
void ftm_scene_builtin_list(char *buf, size_t size);

#endif
