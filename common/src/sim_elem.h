/* SPDX-License-Identifier: GPL-3.0-or-later */
/* Internal: element forces of the integrator (sim_elem.c), the alternative to
 * springs selected by ftm_sim_def.forces. */
#ifndef FTM_SRC_SIM_ELEM_H
#define FTM_SRC_SIM_ELEM_H

#include "elem_kernel.h"
#include "sim_internal.h"

typedef struct ftm_elem ftm_elem;

/* Validates the FEM fields of sim->def and builds sim->elem from the mesh's
 * elements (stiffness, incidence, masses). Called by ftm_sim_create after the
 * arrays are allocated and before the step coefficients are set. */
int ftm_elem_create(ftm_sim *sim, ftm_error *err);
void ftm_elem_free(ftm_elem *el);
/* Node masses used by the integrator (lumped or the mesh's). */
const double *ftm_elem_masses(const ftm_elem *el);
double ftm_elem_critical_step(const ftm_elem *el);
/* The assembled linear stiffness at rest: node i couples to
 * node[start[i] .. start[i+1]-1] (ascending, i itself among them) with the
 * 3x3 blocks k + 9 * that index, row-major. */
void ftm_elem_rows(const ftm_elem *el, const int32_t **start, const int32_t **node,
                   const double **k);

/* The element kernel (elem_kernel.h): the widest this CPU runs, or another
 * (the same bits; ftm_sim_select_kernel asks for the best or the portable
 * one, tests for each). */
void ftm_elem_select_kernel(ftm_elem *el, ftm_elem_kernel which);

/* ftm_sim_set_mesh with element forces: the new links' stiffness over the
 * ones the elements were made with must be one factor, which then scales E
 * (and the critical step by its inverse square root); the mesh's damping
 * (and masses, without a density) take effect through the caller. */
int ftm_elem_set_mesh(ftm_sim *sim, const ftm_mesh *m, ftm_error *err);
double ftm_elem_scale(const ftm_elem *el);

/* The sweeps and reactions of sim_kernel.c with element forces. */
bool ftm_elem_sweep(ftm_sim *sim, double *max_m2);
bool ftm_elem_sweep_relax(ftm_sim *sim);
void ftm_elem_reactions(ftm_sim *sim);

/* Neo-Hookean: false if an element had J <= 0 at a quadrature point in this
 * substep's sweeps or, after the step's last substep (last), has it in the
 * positions the step leaves (the elements of the scheduled nodes, the
 * displacement contacts and the far field's ring when region_ran, and of
 * the relaxing nodes): their
 * forces, evaluated for that check, are what the next step starts from.
 * Clears the record for the next substep. Other forces: true. */
bool ftm_elem_intact(ftm_sim *sim, bool last, bool region_ran);
/* Positions changed outside the sweeps: node i (put to sleep), or any
 * (rollback, reset, a loaded state). The carried forces are dropped. */
void ftm_elem_node_moved(ftm_sim *sim, int32_t i);
void ftm_elem_forget(ftm_sim *sim);
/* The last inverted element: its index, what (e.g. "hexahedron 5 (input
 * nodes ...)") into what[size], and its smallest J into *det. */
int32_t ftm_elem_inversion(const ftm_sim *sim, char *what, size_t size, double *det);

#endif
