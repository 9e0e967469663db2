/* SPDX-License-Identifier: GPL-3.0-or-later */
/* Mesh generators: the paper's 2D triangular lattice and 3D cubic lattices.
 *
 * Stiffness of a link with unit direction n is
 *     k = stiffness * (axis_scale.x n_x^2 + axis_scale.y n_y^2 + axis_scale.z n_z^2),
 * so axis-aligned links get stiffness * axis_scale.<axis> exactly (anisotropy,
 * paper section 4.1.3) and diagonal links a direction-weighted blend.
 *
 * Input node index of lattice point (ix, iy, iz) is ix + nx * (iy + ny * iz). */
#ifndef FTM_GENERATE_H
#define FTM_GENERATE_H

#include "ftm/mesh.h"

#ifdef __cplusplus
extern "C" {
#endif

/* Faces of a box, for fixing boundaries (bit mask). */
enum {
    FTM_FACE_XMIN = 1 << 0,
    FTM_FACE_XMAX = 1 << 1,
    FTM_FACE_YMIN = 1 << 2,
    FTM_FACE_YMAX = 1 << 3,
    FTM_FACE_ZMIN = 1 << 4,
    FTM_FACE_ZMAX = 1 << 5,
};

typedef struct ftm_material_def {
    double node_mass;    /* mass of every node [kg] */
    double node_damping; /* nodal damping d [N s/m] */
    double stiffness;    /* spring stiffness k [N/m] before axis scaling */
    ftm_vec3 axis_scale; /* per-axis stiffness factors, each > 0, default (1, 1, 1) */
} ftm_material_def;

ftm_material_def ftm_default_material_def(void);

/* A copy of base (built with material `from`) with material `to`: the same
 * nodes, numbering, links, rest lengths, surface and elements; node masses
 * scaled by to.node_mass / from.node_mass, damping by the damping ratio (set
 * to to.node_damping outright when from has none), and each link's
 * stiffness by (to.stiffness a_to) / (from.stiffness a_from), a the axis
 * factor of the link's rest direction. Deterministic: the same (base, from,
 * to) give a bit-identical mesh on every machine. For changing tissue
 * parameters in a running simulation (ftm_sim_set_mesh). FTM_EINVAL with a
 * message on an invalid material, FTM_ENOMEM. */
int ftm_mesh_with_material(const ftm_mesh *base, const ftm_material_def *from,
                           const ftm_material_def *to, ftm_mesh **out, ftm_error *err);

/* Link stiffness per element label (several tissues in one spring body): a
 * copy of base whose link between nodes a and b has base's stiffness times
 * the mean, over the elements (hexahedra, tetrahedra) holding both a and b,
 * of their label's factor: factor[i] for labels[i], 1 for a label not
 * listed (or none). A link no element holds keeps base's stiffness. Each
 * label listed once, >= 1, factor finite and > 0. Deterministic like
 * ftm_mesh_with_material (the elements in their order); FTM_EINVAL,
 * FTM_ENOMEM. */
int ftm_mesh_with_label_stiffness(const ftm_mesh *base, const int32_t *labels,
                                  const double *factor, int32_t count, ftm_mesh **out,
                                  ftm_error *err);

/* 2D triangular lattice in the z = 0 plane, 6 neighbours per interior node
 * (paper Fig. 3). Rows are offset by half a spacing, row pitch spacing*sqrt(3)/2. */
typedef struct ftm_lattice2d_def {
    int32_t nx, ny;           /* nodes per row, rows; >= 2 each */
    double spacing;           /* distance between neighbours [m] */
    ftm_material_def material;
    uint32_t fixed_faces;     /* FTM_FACE_XMIN..YMAX: fix the border nodes on those sides */
} ftm_lattice2d_def;

ftm_lattice2d_def ftm_default_lattice2d_def(void);

typedef enum ftm_stencil {
    FTM_STENCIL_6 = 6,   /* edges */
    FTM_STENCIL_18 = 18, /* edges + face diagonals */
    FTM_STENCIL_26 = 26, /* edges + face diagonals + body diagonals */
} ftm_stencil;

/* Link classes of a cubic lattice, for per-class stiffness. */
typedef enum ftm_link_class {
    FTM_LINK_EDGE = 0,
    FTM_LINK_FACE_DIAGONAL = 1,
    FTM_LINK_BODY_DIAGONAL = 2,
} ftm_link_class;

typedef struct ftm_lattice3d_def {
    int32_t nx, ny, nz;        /* nodes per axis, >= 2 each */
    ftm_vec3 spacing;          /* node spacing per axis [m] */
    ftm_stencil stencil;
    ftm_material_def material;
    double class_scale[3];     /* stiffness factor per ftm_link_class, default 1 */
    uint32_t fixed_faces;      /* FTM_FACE_* mask */
} ftm_lattice3d_def;

ftm_lattice3d_def ftm_default_lattice3d_def(void);

/* Both fill a builder (created by the caller, may already hold other parts).
 * The 3D lattice also adds its (nx-1)(ny-1)(nz-1) cells as hexahedra. */
int ftm_generate_lattice2d(ftm_mesh_builder *builder, const ftm_lattice2d_def *def, ftm_error *err);
int ftm_generate_lattice3d(ftm_mesh_builder *builder, const ftm_lattice3d_def *def, ftm_error *err);

#ifdef __cplusplus
}
#endif
#endif
