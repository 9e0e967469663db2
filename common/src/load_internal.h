/* SPDX-License-Identifier: GPL-3.0-or-later */
/* Internal: what the mesh loaders (load_obj.c, load_gmsh.c, load_tetgen.c)
 * share, defined in load.c. Each loader parses into its own arrays and
 * validates everything before ftm_load_commit(), so a malformed file never
 * touches the builder. */
#ifndef FTM_SRC_LOAD_INTERNAL_H
#define FTM_SRC_LOAD_INTERNAL_H

#include "ftm/internal/load.h"

/* Whole file, NUL-terminated, at most 256 MiB. */
int ftm_load_read_file(const char *path, char **data, size_t *length, ftm_error *err);
/* Grows array to hold needed elements (amortised doubling); NULL on failure. */
void *ftm_load_grow(void *array, size_t *capacity, size_t needed, size_t elem_size);
/* ftm_load_check_args, ftm_load_data, ftm_load_commit: ftm/internal/load.h */

/* Shape of an element whose corners are distinct points. */
typedef enum ftm_load_shape {
    FTM_LOAD_SHAPE_OK,
    FTM_LOAD_SHAPE_INVERTED,   /* negative volume: the corners in mirrored order */
    FTM_LOAD_SHAPE_DEGENERATE, /* (nearly) flat, or a hexahedron folded over itself */
} ftm_load_shape;

/* A tetrahedron's shape: positive orientation (the fourth corner on the side
 * of the first three's counter-clockwise normal: Gmsh's and TetGen's
 * convention); degenerate when |6V| <= 1e-12 times its longest edge cubed
 * (the FEM's bound, ftm_tet4_stiffness). */
ftm_load_shape ftm_load_tet_shape(const double *pos, const int32_t v[4]);
/* A hexahedron's shape from its Jacobian determinant at the 8 corners: all
 * positive (beyond the same relative bound) is fine, all negative inverted,
 * anything else degenerate or twisted. */
ftm_load_shape ftm_load_hex_shape(const double *pos, const int32_t v[8]);

/* Finds a tetrahedron listed twice (the same four nodes in any order), which
 * would double its stiffness and hide its faces from the surface. Returns 1
 * with *second the earliest repeat in the input and *first its first copy,
 * 0 if the tetrahedra are distinct, FTM_ENOMEM. Sorted: O(n log n). */
int ftm_load_find_repeated_tet(const int32_t *tets, size_t count, size_t *first, size_t *second);
/* The same for elements of `corners` corners (4 or 8). */
int ftm_load_find_repeated(const int32_t *elements, int corners, size_t count, size_t *first,
                           size_t *second);

#endif
