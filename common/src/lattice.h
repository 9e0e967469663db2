/* SPDX-License-Identifier: GPL-3.0-or-later */
/* Internal: what the cubic lattice generators (generate.c, volume_lattice.c)
 * share, so that a volume's control lattice has exactly the links,
 * stiffness, cells and surface faces a lattice3d of the same size would. */
#ifndef FTM_SRC_LATTICE_H
#define FTM_SRC_LATTICE_H

#include "ftm/generate.h"

/* Forward half of the 26-neighbour stencil: each undirected link once. The
 * first 3 are edges, the next 6 face diagonals, the last 4 body diagonals. */
extern const int8_t ftm_lattice_offsets[13][3];

/* How many of ftm_lattice_offsets a stencil uses (3, 9 or 13), 0 if the
 * stencil is not 6, 18 or 26. */
int ftm_lattice_offset_count(ftm_stencil stencil);

/* generate.h's rule: stiffness of a link along (dx, dy, dz), scaled per axis. */
double ftm_lattice_axis_stiffness(const ftm_material_def *m, double dx, double dy, double dz);

/* Whether lattice point (i[0], i[1], i[2]) of a dims[0] x dims[1] x dims[2]
 * lattice lies on one of the FTM_FACE_* faces in mask. */
bool ftm_lattice_on_faces(uint32_t mask, const int32_t i[3], const int32_t dims[3]);

/* The eight corners of a cell in ftm_mesh_builder_add_hexahedron's order, as
 * offsets (0 or 1 per axis) from its minimum corner. */
extern const int8_t ftm_lattice_hex_corners[8][3];

/* Adds the quad id[0..3] (given in the in-plane (u, v) order of a face with
 * normal axis ax, u = ax + 1, v = ax + 2 mod 3) as two triangles that are
 * counter-clockwise seen from outside: from +ax when hi, else from -ax. */
int ftm_lattice_add_quad(ftm_mesh_builder *b, const int32_t id[4], bool hi);

/* Error messages of a builder call that failed, for generator `who`. */
int ftm_lattice_node_failed(int32_t r, const char *who, int32_t index, const ftm_node_def *nd,
                            ftm_error *err);
int ftm_lattice_link_failed(int32_t r, const char *who, double smin, double smax, ftm_error *err);

#endif
