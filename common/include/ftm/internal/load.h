/* SPDX-License-Identifier: GPL-3.0-or-later */
/* Internal to libftm, shared with the lab (the organs of `ftm experiment
 * organs` are made with the OBJ loader's rules for springs): how a loader
 * hands its parsed nodes and elements to a mesh builder. */
#ifndef FTM_INTERNAL_LOAD_H
#define FTM_INTERNAL_LOAD_H

#include "ftm/load.h"

#include <stdbool.h>
#include <stddef.h>
#include <stdint.h>

/* Adds parsed nodes (3 doubles each), triangles and tetrahedra to the
 * builder, with one spring per distinct edge (triangle edges only if
 * tri_edges). */
int ftm_load_commit(ftm_mesh_builder *builder, const char *path, const ftm_material_def *material,
                    const double *pos, size_t node_count, const int32_t *tris, size_t tri_count,
                    bool tri_edges, const int32_t *tets, size_t tet_count, ftm_error *err);

#endif
