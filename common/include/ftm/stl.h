/* SPDX-License-Identifier: GPL-3.0-or-later */
/* STL surfaces, binary and ASCII: library ftm_stl (common/stl), beside
 * libftm. The facets are read by Assimp (libassimp-dev, C++ behind a C API),
 * which the core does not link: it would bring the C++ runtime and Assimp's
 * own dependencies into every program, and Assimp keeps its last error in one
 * string for the process (ftm_stl holds a lock around each import, so loads
 * from several threads are safe). libftm's ftm_load_mesh refuses .stl and
 * names this library. See docs/meshes.md. */
#ifndef FTM_STL_H
#define FTM_STL_H

#include "ftm/generate.h" /* ftm_material_def */
#include "ftm/mesh.h"

#include <stdbool.h>
#include <stddef.h>
#include <stdint.h>

#ifdef __cplusplus
extern "C" {
#endif

/* STL surface into a builder like an OBJ surface (ftm_load_obj): facet edges
 * become springs; corners at one position are one node. A malformed file
 * leaves the builder as it was. FTM_EINVAL, FTM_EIO, FTM_EPARSE, FTM_ERANGE,
 * FTM_ENOMEM. */
int ftm_load_stl(ftm_mesh_builder *builder, const char *path, const ftm_material_def *material,
                 ftm_error *err);

/* A triangulated surface as a file holds it, for tools that make volumes
 * from it (a mesher). */
typedef struct ftm_surface {
    int32_t vertex_count, triangle_count;
    double *positions;  /* 3 per vertex: the file's coordinates */
    int32_t *triangles; /* 3 vertices per triangle, in the file's facet order */
} ftm_surface;

/* An STL file (binary or ASCII, as its bytes say): corners at one position
 * joined into a vertex, numbered in order of first appearance; a facet with
 * two corners at one point, or all three on a line, is refused naming it
 * (its line in ASCII). With closed = true it must enclose a volume: every
 * edge in exactly two facets, which cross it in opposite directions; the
 * facets are then turned outward if they all faced inward. FTM_EIO,
 * FTM_EPARSE, FTM_ERANGE (over 256 MiB), FTM_ENOMEM. */
int ftm_surface_load(const char *path, bool closed, ftm_surface **out, ftm_error *err);
/* The same from bytes in memory; name is used in error messages. */
int ftm_surface_parse_stl(const void *data, size_t size, const char *name, bool closed,
                          ftm_surface **out, ftm_error *err);
void ftm_surface_destroy(ftm_surface *surface);

#ifdef __cplusplus
}
#endif

#endif
