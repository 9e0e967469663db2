/* SPDX-License-Identifier: GPL-3.0-or-later */
/* Mass-spring meshes: nodes, Voigt links, compact adjacency, surface triangles.
 *
 * A mesh is built once with an ftm_mesh_builder and is immutable afterwards,
 * so several simulations (or threads) may share it read-only.
 *
 * Node order: ftm_mesh_build() may renumber nodes (Cuthill-McKee order) so that a
 * breadth-first region around any node occupies few cache lines. Indices given
 * to the builder are "input indices"; ftm_mesh_node_of_input() and
 * ftm_mesh_input_of_node() translate. Every other call uses mesh indices. */
#ifndef FTM_MESH_H
#define FTM_MESH_H

#include "ftm/base.h"

#ifdef __cplusplus
extern "C" {
#endif

typedef struct ftm_mesh ftm_mesh;
typedef struct ftm_mesh_builder ftm_mesh_builder;

typedef struct ftm_node_def {
    ftm_vec3 position; /* rest position X_i [m] */
    double mass;       /* m_i [kg], > 0 */
    double damping;    /* d_i [N s/m], >= 0 */
    bool fixed;        /* never moves (boundary condition) */
} ftm_node_def;

ftm_node_def ftm_default_node_def(void);

typedef struct ftm_link_def {
    int32_t a, b;       /* input node indices, a != b */
    double stiffness;   /* k_ij [N/m], > 0 */
    double rest_length; /* l_ij [m]; < 0 means "distance between the rest positions" */
} ftm_link_def;

ftm_link_def ftm_default_link_def(void);

typedef struct ftm_mesh_build_def {
    bool reorder;                  /* renumber nodes for locality (default true) */
    bool surface_from_tetrahedra;  /* no triangles given: use the tets' boundary faces (default true) */
} ftm_mesh_build_def;

ftm_mesh_build_def ftm_default_mesh_build_def(void);

/* Builder. Adding functions validate their arguments against what has been
 * added so far and return a negative code (builder unchanged) on bad input.
 * A link added twice (same pair, either order) is kept once: the first wins. */
ftm_mesh_builder *ftm_mesh_builder_create(void);
void ftm_mesh_builder_destroy(ftm_mesh_builder *builder);
/* Returns the new node's input index (>= 0) or a negative code. */
int32_t ftm_mesh_builder_add_node(ftm_mesh_builder *builder, const ftm_node_def *def);
int ftm_mesh_builder_add_link(ftm_mesh_builder *builder, const ftm_link_def *def);
int ftm_mesh_builder_add_triangle(ftm_mesh_builder *builder, int32_t a, int32_t b, int32_t c);
int ftm_mesh_builder_add_tetrahedron(ftm_mesh_builder *builder, int32_t a, int32_t b, int32_t c,
                                     int32_t d);
/* 8-node hexahedron (for the FEM reference; springs are added separately):
 * nodes in the usual order, bottom face a b c d counter-clockwise seen from
 * above, then the top face e f g h above them. */
int ftm_mesh_builder_add_hexahedron(ftm_mesh_builder *builder, const int32_t nodes[8]);
int32_t ftm_mesh_builder_node_count(const ftm_mesh_builder *builder);
int32_t ftm_mesh_builder_tetrahedron_count(const ftm_mesh_builder *builder);
int32_t ftm_mesh_builder_hexahedron_count(const ftm_mesh_builder *builder);
/* Element labels: which tissue an element belongs to (a Gmsh physical
 * group, a label of the segmented scan it was meshed from). Optional: a
 * label is an int32_t >= 1, and an element that was given none has label 0.
 * `tet` / `hex` is the element's index in the order of adding, from 0.
 * FTM_ERANGE (no such element), FTM_EINVAL (label < 0), FTM_ENOMEM. */
int ftm_mesh_builder_set_tetrahedron_label(ftm_mesh_builder *builder, int32_t tet, int32_t label);
int ftm_mesh_builder_set_hexahedron_label(ftm_mesh_builder *builder, int32_t hex, int32_t label);
/* A label's name, for display (a Gmsh physical group's $PhysicalNames
 * entry: "grey matter"): label >= 1; name cut to FTM_MESH_LABEL_NAME_MAX
 * bytes; setting a label's name again replaces it. FTM_EINVAL (label < 1,
 * name NULL or empty), FTM_ERANGE (more than FTM_MESH_MAX_LABEL_NAMES
 * names), FTM_ENOMEM. */
#define FTM_MESH_LABEL_NAME_MAX 40
#define FTM_MESH_MAX_LABEL_NAMES 65536
int ftm_mesh_builder_set_label_name(ftm_mesh_builder *builder, int32_t label, const char *name);
/* Rest position of a node added so far (input index); FTM_ERANGE if none. */
int ftm_mesh_builder_node_position(const ftm_mesh_builder *builder, int32_t node, ftm_vec3 *out);
/* Fixes or frees a node added so far: boundary conditions chosen after a
 * generator or loader has made the nodes. */
int ftm_mesh_builder_set_fixed(ftm_mesh_builder *builder, int32_t node, bool fixed);
/* Whether a node added so far is fixed (false for no such node). */
bool ftm_mesh_builder_node_fixed(const ftm_mesh_builder *builder, int32_t node);
/* Fixes every node of every element labelled `label` (>= 1): a part of the
 * body held in place, the skull around a brain, a bone under a muscle.
 * Returns how many elements carry the label (0: none; nothing changed). */
int32_t ftm_mesh_builder_fix_label(ftm_mesh_builder *builder, int32_t label);
/* Sets mark[i] = 1 (mark: one per node added so far) for every node of
 * every element labelled `label` (>= 1); returns how many elements carry it. */
int32_t ftm_mesh_builder_label_nodes(const ftm_mesh_builder *builder, int32_t label,
                                     uint8_t *mark);
/* Partial constraints (docs/scene-format.md, Boundary conditions): node may
 * not move along `normal` (any length > 0): it slides on the plane through
 * its rest position normal to it. A second call with another direction
 * leaves it a line to slide on; a direction the node's normals span already
 * changes nothing. FTM_ERANGE (no such node), FTM_EINVAL (zero or
 * non-finite normal; a third independent direction: fix the node instead),
 * FTM_ENOMEM. A node also fixed is fixed: the mesh keeps no constraint on it. */
int ftm_mesh_builder_add_slide(ftm_mesh_builder *builder, int32_t node, ftm_vec3 normal);
/* A spring to ground: a force -k (x - X) on the node, X its rest position
 * (an attachment). Springs on one node add up. FTM_ERANGE (no such node),
 * FTM_EINVAL (stiffness not finite and > 0), FTM_ENOMEM. */
int ftm_mesh_builder_add_ground_spring(ftm_mesh_builder *builder, int32_t node,
                                       double stiffness);

/* Builds the mesh; the builder may be reused or destroyed afterwards.
 * Fails (FTM_EINVAL, message in err) on an empty mesh. */
int ftm_mesh_build(const ftm_mesh_builder *builder, const ftm_mesh_build_def *def, ftm_mesh **out,
                   ftm_error *err);
void ftm_mesh_destroy(ftm_mesh *mesh);

int32_t ftm_mesh_node_count(const ftm_mesh *mesh);
int32_t ftm_mesh_link_count(const ftm_mesh *mesh);
int32_t ftm_mesh_triangle_count(const ftm_mesh *mesh);
int32_t ftm_mesh_tetrahedron_count(const ftm_mesh *mesh);
int32_t ftm_mesh_hexahedron_count(const ftm_mesh *mesh);

ftm_vec3 ftm_mesh_rest_position(const ftm_mesh *mesh, int32_t node);
double ftm_mesh_mass(const ftm_mesh *mesh, int32_t node);
double ftm_mesh_damping(const ftm_mesh *mesh, int32_t node);
bool ftm_mesh_fixed(const ftm_mesh *mesh, int32_t node);
/* The unit normals node may not move along (orthonormal), 0..2 of them
 * (copied to normals when not NULL), or FTM_ERANGE. */
int32_t ftm_mesh_slide_normals(const ftm_mesh *mesh, int32_t node, ftm_vec3 normals[2]);
/* Stiffness of node's springs to ground [N/m], 0 if none. */
double ftm_mesh_ground_stiffness(const ftm_mesh *mesh, int32_t node);
bool ftm_mesh_has_slides(const ftm_mesh *mesh);
bool ftm_mesh_has_ground_springs(const ftm_mesh *mesh);

/* Neighbours of a node: count returned, arrays valid for the mesh's lifetime.
 * Each entry j has the neighbour's index, the link's stiffness and rest length. */
int32_t ftm_mesh_neighbors(const ftm_mesh *mesh, int32_t node, const int32_t **neighbors,
                           const double **stiffness, const double **rest_length);

/* Link i's end nodes (mesh indices), stiffness and rest length. */
void ftm_mesh_link(const ftm_mesh *mesh, int32_t link, int32_t *a, int32_t *b, double *stiffness,
                   double *rest_length);

/* Surface triangles as 3 mesh indices each (tri_count * 3 entries). */
const int32_t *ftm_mesh_triangles(const ftm_mesh *mesh);
/* Tetrahedra as 4 mesh indices each (may be empty). */
const int32_t *ftm_mesh_tetrahedra(const ftm_mesh *mesh);
/* Hexahedra as 8 mesh indices each, in the order of the builder (may be empty). */
const int32_t *ftm_mesh_hexahedra(const ftm_mesh *mesh);

/* Element labels, kept in the builder's element order (elements are not
 * renumbered): the label of tetrahedron (hexahedron) i, 0 if it has none, or
 * FTM_ERANGE for no such element. The arrays hold one label per element, or
 * are NULL when the builder labelled no element of that kind. */
int32_t ftm_mesh_tetrahedron_label(const ftm_mesh *mesh, int32_t tet);
int32_t ftm_mesh_hexahedron_label(const ftm_mesh *mesh, int32_t hex);
const int32_t *ftm_mesh_tetrahedron_labels(const ftm_mesh *mesh);
const int32_t *ftm_mesh_hexahedron_labels(const ftm_mesh *mesh);
/* Whether the builder labelled any element. */
bool ftm_mesh_has_labels(const ftm_mesh *mesh);
/* The name the builder gave label (ftm_mesh_builder_set_label_name), NULL
 * for none. */
const char *ftm_mesh_label_name(const ftm_mesh *mesh, int32_t label);

int32_t ftm_mesh_node_of_input(const ftm_mesh *mesh, int32_t input_index);
int32_t ftm_mesh_input_of_node(const ftm_mesh *mesh, int32_t node);

double ftm_mesh_mean_link_length(const ftm_mesh *mesh);
int32_t ftm_mesh_max_degree(const ftm_mesh *mesh);

/* Largest time step h for which the explicit central-difference scheme is
 * guaranteed stable on this mesh, from a Gershgorin bound on the largest
 * eigenvalue of M^-1 K: lambda <= max_i sum_j k_ij (1/m_i + 1/sqrt(m_i m_j)),
 * h_crit = 2 / sqrt(lambda). Conservative: the true limit is at least this.
 * Free nodes only; INFINITY if no free node has a link. */
double ftm_mesh_critical_time_step(const ftm_mesh *mesh);

/* Whether two meshes have the same shape: nodes, rest positions, fixed
 * nodes, partial constraints and springs to ground, adjacency with rest lengths and surface triangles, in the same
 * numbering; only masses, damping and stiffness may differ. */
bool ftm_mesh_same_shape(const ftm_mesh *a, const ftm_mesh *b);

/* Nearest node to a point (linear scan; for scene set-up, not per tick). */
int32_t ftm_mesh_nearest_node(const ftm_mesh *mesh, ftm_vec3 point);

/* ---- linear elastic elements (FEM forces of ftm_sim, and the FEM reference) ----
 * Small strains, isotropic Hooke's law in Voigt order (xx yy zz xy yz zx),
 * engineering shear strains; formulation in docs/fem.md. Matrices row-major,
 * dof 3a+i = element node a, axis i. Hexahedron node order as in
 * ftm_mesh_builder_add_hexahedron. No material validation here. */

/* The 6x6 constitutive matrix D for Young's modulus E and Poisson's ratio nu. */
void ftm_elasticity_matrix(double young, double poisson, double d[36]);
/* 8-node hexahedron, 2x2x2 Gauss: K_e = sum_q B^T D B det J. FTM_EINVAL if
 * det J <= 0 at a Gauss point; *min_det (may be NULL) gets the smallest. */
int ftm_hex8_stiffness(const ftm_vec3 x[8], double young, double poisson, double ke[576],
                       double *min_det);
/* Shape-function gradients dN_a/dx at the element centre (3 per node). */
int ftm_hex8_centre_gradients(const ftm_vec3 x[8], double grad[24]);
/* Shape-function gradients dN_a/dx at the 8 Gauss points of
 * ftm_hex8_stiffness, in its order (24 per point, 3 per node), and det J
 * there (the points' weights are 1). FTM_EINVAL if det J <= 0 at one. */
int ftm_hex8_gauss_gradients(const ftm_vec3 x[8], double grad[192], double det[8]);
/* The inverse Jacobian J^-1 (row-major, J_ij = dx_i/dxi_j; dN_a/dx =
 * J^-T dN_a/dxi) at the 8 Gauss points of ftm_hex8_stiffness in its order,
 * then at the centre (9 each), and det J at the Gauss points. FTM_EINVAL if
 * det J <= 0 at one of the nine. */
int ftm_hex8_inverse_jacobians(const ftm_vec3 x[8], double ji[81], double det[8]);
/* Row-sum lumped masses int rho N_a dV (2x2x2 Gauss). */
int ftm_hex8_lumped_mass(const ftm_vec3 x[8], double density, double mass[8]);
/* 4-node tetrahedron: K_e = V B^T D B, V = |signed volume|. FTM_EINVAL if
 * degenerate (|6V| <= 1e-12 longest edge^3); *signed_volume may be NULL. */
int ftm_tet4_stiffness(const ftm_vec3 x[4], double young, double poisson, double ke[144],
                       double *signed_volume);
/* Constant shape-function gradients dN_a/dx (3 per node). */
int ftm_tet4_gradients(const ftm_vec3 x[4], double grad[12]);
/* Lumped nodal masses of the mesh's hexahedra and tetrahedra at density
 * [kg/m^3]: mass_out[i] (mesh order) = sum over the elements of node i of
 * int rho N_i dV (rho V / 4 for a tetrahedron). Nodes in no element get 0. */
int ftm_mesh_lumped_masses(const ftm_mesh *mesh, double density, double *mass_out,
                           ftm_error *err);
/* The same with each element's own density[e] > 0 (hexahedra, then
 * tetrahedra, as ftm_mesh_hexahedron_label and _tetrahedron_label count
 * them): several tissues in one body. Equal densities give the bits of
 * ftm_mesh_lumped_masses. */
int ftm_mesh_lumped_masses_each(const ftm_mesh *mesh, const double *density, double *mass_out,
                                ftm_error *err);

#ifdef __cplusplus
}
#endif
#endif
