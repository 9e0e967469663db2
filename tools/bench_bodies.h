/* SPDX-License-Identifier: GPL-3.0-or-later */
/* The bodies of `ftm bench accuracy` (docs/accuracy.md), shared with
 * `ftm bench peers` (docs/peers.md): the paper's elastin cube and a
 * kidney-shaped organ of hexahedra, their material and fitted springs. */
#ifndef FTM_TOOLS_BENCH_BODIES_H
#define FTM_TOOLS_BENCH_BODIES_H

#include "ftm/ftm.h"

#define FTM_BENCH_YOUNG 0.6e6  /* elastin, docs/scenes/elastin-cube.scene */
#define FTM_BENCH_POISSON 0.45
#define FTM_BENCH_DENSITY 1040.0 /* paper Tables 1-2 */
/* The uniform spring stiffness `ftm fit elastin-cube` identified (docs/fit.md:
 * 2615.8 N/m for the 18-neighbour lattice of spacing 0.1/9 m, E = 0.6 MPa).
 * A lattice's effective modulus is k / spacing, so other spacings (the organ)
 * get k = FTM_BENCH_FIT_K_PER_ES * E * spacing. */
#define FTM_BENCH_FIT_K 2615.8
#define FTM_BENCH_FIT_K_PER_ES (FTM_BENCH_FIT_K / (FTM_BENCH_YOUNG * (0.1 / 9.0)))

/* The loads a body is built with: nodes (input indices) and their forces. */
#define FTM_BENCH_MAX_LOADS 8

/* The elastin cube of docs/scenes/elastin-cube.scene with n x n x n nodes
 * (n even, 4..64; the paper's is 10): 0.1 m, 18-neighbour springs of
 * stiffness 1, bottom clamped, 10 N down on the top face's four central
 * nodes; its hexahedra. */
int ftm_bench_cube_geometry(ftm_mesh_builder *b, int n, int32_t *loads, ftm_vec3 *load_force,
                            int *nloads, double *spacing, ftm_error *err);

/* The kidney-shaped organ (an ellipsoid of 110 x 60 x 50 mm with a hilum
 * notch, clamped at the notch, a 2.5 mm lattice: 10606 nodes), 1 N on the
 * five surface nodes nearest the middle of its convex side. */
int ftm_bench_organ_geometry(ftm_mesh_builder *b, int32_t *loads, ftm_vec3 *load_force,
                             int *nloads, double *spacing, ftm_error *err);

/* A body's geometry built into a mesh: "cube" (the paper's, n = 10),
 * "tiny" (the cube with n = 4) or "organ"; its loads and lattice spacing. */
int ftm_bench_body_geometry(const char *name, ftm_mesh **out, int32_t *loads,
                            ftm_vec3 *load_force, int *nloads, double *spacing, ftm_error *err);

/* The mesh of the runs: g's nodes in g's (already local) order, not
 * renumbered again, so that indices stay valid; node masses, damping
 * 2 zeta m and the springs' stiffness k; g's hexahedra. */
int ftm_bench_final_mesh(const ftm_mesh *g, const double *mass, double k, double zeta,
                         ftm_mesh **out, ftm_error *err);

/* The damping d/2m [1/s] the layer-by-layer update needs at half the
 * critical step (d/2m >= 0.055 lambda h = 0.11 / h_crit, docs/core.md
 * "damping is required"), the smaller critical step of mesh's springs and of
 * its linear element forces (E, nu of the bench), so that every force model
 * runs stably with it. */
int ftm_bench_damping_floor(const ftm_mesh *mesh, double *zeta, ftm_error *err);

#endif
