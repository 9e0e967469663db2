/* Internal knobs of the integrator, for tests. */
#ifndef FTM_SRC_SIM_INTERNAL_H
#define FTM_SRC_SIM_INTERNAL_H

#include "ftm/sim.h"

/* Chooses the kernel of the colored sweep: the widest this CPU supports
 * (the default), or with portable the baseline one. Both give bit-identical
 * results; tests compare them. */
void ftm_sim_select_kernel(ftm_sim *sim, bool portable);

#endif
