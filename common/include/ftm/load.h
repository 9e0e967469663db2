/* SPDX-License-Identifier: GPL-3.0-or-later */
/* Mesh loaders. Each reads a file into a builder; nodes get the material's
 * mass and damping, every mesh edge becomes a spring with the material's
 * stiffness (axis scaling as in generate.h) and its rest length.
 *
 * Errors name the file and line: "organ.msh:42: node tag 17 repeated".
 * A loader that fails leaves the builder as it was given (nothing added). */
#ifndef FTM_LOAD_H
#define FTM_LOAD_H

#include "ftm/generate.h"

#ifdef __cplusplus
extern "C" {
#endif

/* Wavefront OBJ surface mesh: "v x y z" and "f a b c ..." lines (polygons are
 * fanned into triangles; "a/b/c" forms and negative indices accepted; other
 * statements ignored). Triangle edges become springs. */
int ftm_load_obj(ftm_mesh_builder *builder, const char *path, const ftm_material_def *material,
                 ftm_error *err);

/* Gmsh MSH 4.1 ASCII volume mesh: $Nodes and $Elements; 4-node tetrahedra
 * (type 4) become tetrahedra and springs on their 6 edges; 3-node triangles
 * (type 2) are kept as surface triangles; other element types are skipped. */
int ftm_load_gmsh(ftm_mesh_builder *builder, const char *path, const ftm_material_def *material,
                  ftm_error *err);

/* TetGen .node/.ele pair: path is the .node file, the .ele file is found by
 * replacing the extension. */
int ftm_load_tetgen(ftm_mesh_builder *builder, const char *node_path,
                    const ftm_material_def *material, ftm_error *err);

/* Chooses by extension: .obj, .msh, .node. An .stl is refused naming
 * ftm_load_stl (ftm/stl.h, library ftm_stl beside libftm). */
int ftm_load_mesh(ftm_mesh_builder *builder, const char *path, const ftm_material_def *material,
                  ftm_error *err);

#ifdef __cplusplus
}
#endif
#endif
