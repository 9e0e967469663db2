/* SPDX-License-Identifier: GPL-3.0-or-later */
/* Internal: the compressible neo-Hookean solid of CalculiX's *HYPERELASTIC,
 * NEO HOOKE (hyperelastic.c), for the element forces of sim_elem.c. */
#ifndef FTM_SRC_HYPERELASTIC_H
#define FTM_SRC_HYPERELASTIC_H

#include <stdbool.h>

/* j^(-1/3) for a finite j > 0 with + - * / and exact scaling by powers of
 * two: the same bits on every machine (libm's cbrt and pow are not). Within
 * a few ulp of the exact value (test_hyperelastic measures it). */
double ftm_inv_cbrt(double j);

/* The first Piola-Kirchhoff stress P = dW/dF of
 *     W = mu/2 (J^(-2/3) I1 - 3) + kappa/2 (J - 1)^2
 * (C10 = mu/2, D1 = 2/kappa), at F = I + h (h: the displacement gradient,
 * 3x3 row-major). Returns false, with p unset, when J = det F is not > 0
 * (an inverted or degenerate point); *j gets J either way. F = I gives
 * exactly P = 0. */
bool ftm_neo_stress(const double h[9], double mu, double kappa, double p[9], double *j);

/* Nodal forces f_a = sum_q w_q P(F_q) g_qa of one element: a hexahedron
 * (nn = 8 nodes, nq = 8 quadrature points) or a tetrahedron (4, 1). gp
 * holds per point the nn rest gradients g_qa (3 each) and then the weight
 * w_q (rest volume share): nq (3 nn + 1) doubles. u: the nodes'
 * displacements (3 each). fe: 3 per node. Returns false if J <= 0 at a
 * point (fe is then zero); *min_det gets the smallest J of the points
 * computed. */
bool ftm_neo_element_forces(int nn, int nq, const double *gp, const double *u, double mu,
                            double kappa, double *fe, double *min_det);

#endif
