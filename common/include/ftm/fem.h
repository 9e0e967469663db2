/* SPDX-License-Identifier: GPL-3.0-or-later */
/* Linear static finite-element reference (paper section 3.2, Eqs. 11-16).
 *
 * Small-strain, isotropic linear elasticity on the hexahedra and tetrahedra of
 * an ftm_mesh: 8-node trilinear hexahedra integrated with 2x2x2 Gauss points
 * and 4-node constant-strain tetrahedra. The global stiffness K is assembled
 * sparse, the constrained degrees of freedom are eliminated, and the reduced
 * system is factorised once with CHOLMOD (SuiteSparse); every load case then
 * costs one forward/back substitution. Library ftm_fem (links libftm and
 * CHOLMOD; libftm itself does not need SuiteSparse). See docs/fem.md.
 *
 * Degrees of freedom: node i (a mesh index) has dofs 3i, 3i+1, 3i+2 (x, y, z).
 * Every vector below has 3 * ftm_mesh_node_count() entries in that order.
 * Units are whatever the caller uses consistently (SI in FTM: m, N, Pa). */
#ifndef FTM_FEM_H
#define FTM_FEM_H

#include "ftm/mesh.h"

#ifdef __cplusplus
extern "C" {
#endif

typedef struct ftm_fem ftm_fem;

/* Isotropic Hooke material. Valid: young > 0, -1 < poisson < 0.5, both finite. */
typedef struct ftm_fem_material {
    double young;   /* Young's modulus E [Pa] */
    double poisson; /* Poisson's ratio nu */
} ftm_fem_material;

/* E = 1 Pa, nu = 0.3: unit defaults for tests; scenes give real tissue values ([fem]). */
ftm_fem_material ftm_default_fem_material(void);

/* Checks a material; on failure the message names `what` (e.g. "hexahedron 12"). */
int ftm_fem_check_material(const ftm_fem_material *material, const char *what, ftm_error *err);

/* The 6x6 constitutive matrix D (row-major) of NOTES.md section 4: stress
 * (sxx syy szz sxy syz szx) = D (exx eyy ezz gxy gyz gzx), engineering shear
 * strains g = 2 e. No validation. */
void ftm_fem_elasticity_matrix(const ftm_fem_material *material, double d[36]);

/* Element stiffness matrices, row-major, dof 3a+i = node a, axis i.
 *
 * Hexahedron: nodes in the ftm_mesh order (bottom face counter-clockwise seen
 * from +z, then the top face above it), natural coordinates
 * (-1,-1,-1) (1,-1,-1) (1,1,-1) (-1,1,-1) (-1,-1,1) (1,-1,1) (1,1,1) (-1,1,1);
 * K_e = sum over the 2x2x2 Gauss points (+-1/sqrt 3, weight 1) of
 * B^T D B det J. FTM_EINVAL if det J <= 0 at a Gauss point (inverted or
 * degenerate element); *min_det (may be NULL) gets the smallest det J. */
int ftm_fem_hex_stiffness(const ftm_vec3 x[8], const ftm_fem_material *material, double ke[576],
                          double *min_det);
/* Tetrahedron (constant strain): K_e = V B^T D B with V = |signed volume|,
 * so either vertex orientation gives the same matrix. FTM_EINVAL if the
 * tetrahedron is degenerate (|6V| <= 1e-12 * longest edge^3). *signed_volume
 * (may be NULL) gets the signed volume: positive when d lies on the side of
 * the plane (a, b, c) that (b - a) x (c - a) points to. */
int ftm_fem_tet_stiffness(const ftm_vec3 x[4], const ftm_fem_material *material, double ke[144],
                          double *signed_volume);

typedef enum ftm_fem_factorization {
    FTM_FEM_FACTOR_AUTO = 0,       /* CHOLMOD chooses (supernodal for large fill) */
    FTM_FEM_FACTOR_SIMPLICIAL = 1, /* left-looking LL^T, no BLAS: identical on every machine */
    FTM_FEM_FACTOR_SUPERNODAL = 2, /* BLAS-based, faster on big meshes */
} ftm_fem_factorization;

typedef struct ftm_fem_def {
    /* Material of every element without an entry in the arrays below. */
    ftm_fem_material material;
    /* Optional per-element materials: NULL, or one per hexahedron / tetrahedron
     * of the mesh, in the mesh's element order. */
    const ftm_fem_material *hex_materials;
    const ftm_fem_material *tet_materials;
    /* Constrained (Dirichlet) dofs on top of the mesh's fixed nodes, which are
     * always constrained in all three dofs: NULL, or 3 per node, true =
     * constrained. Prescribed values are given to ftm_fem_solve. */
    const bool *constrained;
    ftm_fem_factorization factorization;
    ftm_log_fn log; /* optional; reports the assembly and factor sizes */
    void *log_user;
} ftm_fem_def;

ftm_fem_def ftm_default_fem_def(void);

/* Assembles K over every hexahedron and tetrahedron of the mesh, eliminates
 * the constrained dofs and factorises the reduced stiffness. Errors
 * (message in err, nothing written to *out):
 *   FTM_EINVAL  bad material ("hexahedron 3: poisson must be ..."), a mesh with
 *               no volume elements, an inverted hexahedron (det J <= 0 at a
 *               Gauss point) or tetrahedron (orientation opposite to the rest
 *               of the mesh) or a degenerate one, naming the element index;
 *               a free node that belongs to no element; a stiffness that is
 *               not positive definite ("unconstrained body or mechanism");
 *   FTM_ERANGE  the system is too large for CHOLMOD's int indices;
 *   FTM_ENOMEM  allocation failed.
 * The mesh must outlive the ftm_fem object. */
int ftm_fem_create(const ftm_mesh *mesh, const ftm_fem_def *def, ftm_fem **out, ftm_error *err);
void ftm_fem_destroy(ftm_fem *fem);

/* Solves K u = f for one load case with the factor made by ftm_fem_create.
 * forces: 3 per node (NULL = no forces); the entries at constrained dofs are
 * ignored (they become part of the reactions). prescribed: 3 per node, the
 * displacement of each constrained dof (NULL = all zero); entries at free
 * dofs are ignored. u_out: 3 per node, constrained dofs get their prescribed
 * values. FTM_EINVAL for a non-finite input value. */
int ftm_fem_solve(ftm_fem *fem, const double *forces, const double *prescribed, double *u_out,
                  ftm_error *err);

/* r = K u - f over all dofs (3 per node; forces may be NULL): the reaction
 * forces at the constrained dofs and the residual (about 0) at the free ones. */
void ftm_fem_residual(const ftm_fem *fem, const double *u, const double *forces, double *r_out);

typedef struct ftm_fem_stats {
    int32_t nodes;
    int32_t hexahedra;
    int32_t tetrahedra;
    int64_t dofs;            /* 3 * nodes */
    int64_t constrained;     /* constrained dofs */
    int64_t free_dofs;       /* size of the reduced system */
    int64_t nnz;             /* stored entries of the reduced K (upper triangle) */
    int64_t factor_nnz;      /* entries of the Cholesky factor L */
    bool supernodal;         /* the factorisation CHOLMOD used */
    double rcond;            /* CHOLMOD's rough reciprocal condition estimate (pivot ratio) */
    double assemble_seconds; /* wall time of element matrices + assembly */
    double factor_seconds;   /* symbolic + numeric factorisation */
    double solve_seconds;    /* total over the ftm_fem_solve calls so far */
    int32_t solves;          /* ftm_fem_solve calls so far */
} ftm_fem_stats;

ftm_fem_stats ftm_fem_get_stats(const ftm_fem *fem);
const ftm_mesh *ftm_fem_mesh(const ftm_fem *fem);

/* ---- sparse SPD solver (CHOLMOD) for other implicit models ----
 * Used by the backward-Euler mass-spring model of `ftm bench accuracy`
 * (docs/accuracy.md). The pattern is the upper triangle by columns (CSC):
 * column j holds rows row[col_start[j] .. col_start[j+1]-1], ascending and
 * <= j; it is analysed once (fill-reducing ordering) by ftm_spd_create, and
 * each ftm_spd_factor is a numeric factorisation with values in pattern
 * order. One object per thread. */
typedef struct ftm_spd ftm_spd;

int ftm_spd_create(int32_t n, const int32_t *col_start, const int32_t *row, ftm_spd **out,
                   ftm_error *err);
/* FTM_EINVAL (message) if the matrix is not positive definite. */
int ftm_spd_factor(ftm_spd *spd, const double *values, ftm_error *err);
/* x = A^-1 b with the last successful factorisation (n entries each). */
int ftm_spd_solve(ftm_spd *spd, const double *b, double *x, ftm_error *err);
/* Entries of the last factor L (0 before the first factorisation). */
int64_t ftm_spd_factor_nnz(const ftm_spd *spd);
void ftm_spd_destroy(ftm_spd *spd);

#ifdef __cplusplus
}
#endif
#endif
