/* Internal: element forces of the integrator (sim_elem.c), the alternative to
 * springs selected by ftm_sim_def.forces. */
#ifndef FTM_SRC_SIM_ELEM_H
#define FTM_SRC_SIM_ELEM_H

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

/* The sweeps and reactions of sim_kernel.c with element forces. */
bool ftm_elem_sweep(ftm_sim *sim, double *max_m2);
bool ftm_elem_sweep_relax(ftm_sim *sim);
void ftm_elem_reactions(ftm_sim *sim);

#endif
