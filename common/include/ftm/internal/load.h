/* SPDX-License-Identifier: GPL-3.0-or-later */
/* Internal to libftm, shared with the lab (the organs of `ftm experiment
 * organs` are made with the OBJ loader's rules for springs) and with the
 * STL loader beside the core (ftm_stl, common/stl): how a loader checks its
 * arguments and hands its parsed nodes, elements and their labels to a mesh
 * builder. */
#ifndef FTM_INTERNAL_LOAD_H
#define FTM_INTERNAL_LOAD_H

#include "ftm/load.h"

#include <stdbool.h>
#include <stddef.h>
#include <stdint.h>

/* Checked before any file is read, so a bad material is reported as such. */
int ftm_load_check_args(const ftm_mesh_builder *builder, const char *path,
                        const ftm_material_def *material, ftm_error *err);

/* What a loader parsed, indices 0-based into pos (3 doubles per node).
 * Label arrays may be NULL (no labels); otherwise one per element, 0 = none. */
typedef struct ftm_load_data {
    const double *pos;
    size_t node_count;
    const int32_t *tris; /* 3 per triangle */
    size_t tri_count;
    bool tri_edges;      /* springs on the triangles' edges too */
    const int32_t *tets; /* 4 per tetrahedron */
    const int32_t *tet_labels;
    size_t tet_count;
    const int32_t *hexes; /* 8 per hexahedron, ftm_mesh_builder_add_hexahedron's order */
    const int32_t *hex_labels;
    size_t hex_count;
} ftm_load_data;

/* Adds parsed, validated data to the builder: nodes, one spring per distinct
 * edge (tetrahedron edges, hexahedron edges and face diagonals, triangle
 * edges if tri_edges), triangles, elements and their labels. Hexahedra
 * without triangles get their boundary faces as the surface (two triangles
 * a face, outward). */
int ftm_load_commit(ftm_mesh_builder *builder, const char *path, const ftm_material_def *material,
                    const ftm_load_data *data, ftm_error *err);

#endif
