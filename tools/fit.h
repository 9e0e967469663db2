/* SPDX-License-Identifier: GPL-3.0-or-later */
/* Parameter identification for `ftm fit` (docs/fit.md, paper section 3.2).
 *
 * Two layers:
 *  - generic optimisers on a cost f: R^n -> R: simulated annealing as in the
 *    paper's Fig. 7 (random neighbour, Metropolis acceptance exp(-df/T) of
 *    Eq. 18, Lundy-Mees cooling T <- T / (1 + beta T), one iteration per
 *    temperature step, a pre-run that sets T0 from the uphill moves it sees)
 *    and Nelder-Mead, both counting cost evaluations; a seeded PRNG
 *    (splitmix64-seeded xoshiro256**) so that every run is reproducible;
 *  - the mass-spring problem: a base mesh whose links are sorted into classes
 *    (edge, face diagonal, body diagonal) by direction, rebuilt with the
 *    parameters (k, d, class scales), run to equilibrium with ftm_sim under
 *    each load case and compared node by node with reference positions (the
 *    FEM solution): the cost of Eq. 17.
 *
 * Nothing here has global state; one ftm_fit_problem per thread. */
#ifndef FTM_TOOLS_FIT_H
#define FTM_TOOLS_FIT_H

#include "ftm/fem.h"
#include "ftm/ftm.h"

#include <stdint.h>

/* ---- PRNG -------------------------------------------------------------- */

typedef struct ftm_fit_rng {
    uint64_t s[4];
} ftm_fit_rng;

void ftm_fit_rng_seed(ftm_fit_rng *rng, uint64_t seed);
uint64_t ftm_fit_rng_next(ftm_fit_rng *rng);
double ftm_fit_rng_uniform(ftm_fit_rng *rng); /* [0, 1), 53 bits */

/* ---- optimisers -------------------------------------------------------- */

enum { FTM_FIT_MAX_DIM = 8 };

/* Cost of x (dim entries). A non-finite return marks x as infeasible (the
 * optimisers treat it as +infinity). */
typedef double (*ftm_fit_cost_fn)(void *user, const double *x);

/* Lundy-Mees cooling step: T / (1 + beta T). */
double ftm_fit_lundy_mees(double t, double beta);
/* The beta that takes T0 to t_final in exactly `steps` Lundy-Mees steps:
 * 1/T_n = 1/T0 + n beta, so beta = (1/t_final - 1/T0) / steps. */
double ftm_fit_lundy_mees_beta(double t0, double t_final, int steps);

typedef struct ftm_fit_trace {
    int iteration; /* 0 = after the pre-run */
    double temperature;
    double current; /* cost of the current point */
    double best;    /* best cost so far */
    const double *x_best;
    int evaluations;
} ftm_fit_trace;

typedef void (*ftm_fit_trace_fn)(void *user, const ftm_fit_trace *t);

typedef struct ftm_fit_anneal_def {
    int dim;
    const double *x0;   /* start */
    const double *lo;   /* box bounds (moves outside are clamped to the box) */
    const double *hi;
    const double *step; /* neighbour half-width per coordinate at T0 */
    uint64_t seed;
    int iterations;     /* temperature steps, one cost evaluation each */
    /* Pre-run: `prerun` random moves of a walk from x0 (every move taken);
     * T0 = -mean(uphill df) / ln(accept_start), T_final = -mean(uphill df) /
     * ln(accept_final). t0 > 0 and t_final > 0 override them; beta > 0
     * overrides the beta derived from T0, T_final and `iterations`. */
    int prerun;
    double accept_start; /* default 0.8 */
    double accept_final; /* default 1e-3 */
    double t0, t_final, beta;
    /* Neighbour half-width scales as step * max(min_step_fraction,
     * sqrt(T / T0)): wide moves while hot, fine ones while cold. 1 keeps the
     * neighbourhood fixed, as in a textbook annealer. */
    double min_step_fraction;
    ftm_fit_trace_fn trace; /* called after the pre-run and every iteration */
    void *trace_user;
} ftm_fit_anneal_def;

ftm_fit_anneal_def ftm_fit_default_anneal_def(void);

typedef struct ftm_fit_result {
    double f;        /* best cost */
    int evaluations; /* all cost evaluations, pre-run included */
    int iterations;
    int accepted;        /* moves accepted */
    int uphill_accepted; /* of which uphill */
    double t0, t_final, beta;
    bool converged; /* Nelder-Mead: tolerance met before max_evaluations */
} ftm_fit_result;

/* Minimises f; x_best (dim) gets the best point seen. FTM_EINVAL on a bad
 * definition, FTM_EINVAL also if f(x0) is not finite. */
int ftm_fit_anneal(const ftm_fit_anneal_def *def, ftm_fit_cost_fn f, void *user, double *x_best,
                   ftm_fit_result *result);

typedef struct ftm_fit_nm_def {
    int dim;
    const double *x0;
    const double *step; /* initial simplex: x0 + step_i e_i */
    const double *lo;   /* optional box (NULL = none): points are clamped */
    const double *hi;
    int max_evaluations;
    double ftol; /* stop when (f_worst - f_best) <= ftol * (|f_best| + ftol_abs) */
    double ftol_abs;
    double xtol; /* ... and the simplex is smaller than xtol in every coordinate */
    ftm_fit_trace_fn trace;
    void *trace_user;
} ftm_fit_nm_def;

ftm_fit_nm_def ftm_fit_default_nm_def(void);

/* Nelder-Mead (standard coefficients 1, 2, 0.5, 0.5). Deterministic. */
int ftm_fit_nelder_mead(const ftm_fit_nm_def *def, ftm_fit_cost_fn f, void *user, double *x_best,
                        ftm_fit_result *result);

/* ---- the mass-spring problem ------------------------------------------- */

typedef struct ftm_fit_problem ftm_fit_problem;

typedef struct ftm_fit_params {
    double k;           /* base spring stiffness [N/m] */
    double d;           /* nodal damping [N s/m] */
    double scale[3];    /* stiffness factor per ftm_link_class (edge = scale[0]) */
} ftm_fit_params;

typedef struct ftm_fit_problem_def {
    /* Base mesh: node positions and fixed flags, the links (their stiffness
     * is replaced; class from the direction: 1, 2 or 3 nonzero components).
     * Must outlive the problem. */
    const ftm_mesh *mesh;
    double node_mass; /* [kg], every node */
    int32_t depth;    /* penetration depth */
    int32_t cases;    /* load cases */
    /* Per case 3 doubles per node (mesh order): external forces; the nodes
     * with a nonzero force become force contacts. */
    const double *const *forces;
    /* Per case 3 doubles per node: reference positions X-hat (rest + FEM
     * displacement). May be NULL to evaluate without a reference (cost 0). */
    const double *const *reference;
    /* Run control. time_step 0: 0.5 * the critical step of each evaluated
     * mesh. fixed_steps > 0: run exactly that many steps (the paper's
     * possible reading, where d matters); otherwise run until the largest
     * per-step motion is below tolerance * mean link length (default 1e-8),
     * at most max_steps (default 200000). */
    double time_step;
    int32_t fixed_steps;
    double tolerance;
    int32_t max_steps;
    /* Several tissues: NULL, or per link (the mesh's order) a factor on its
     * stiffness k * scale[class], e.g. the ratio of its labels' moduli
     * (ftm_mesh_with_label_stiffness), so that one k fits every tissue. */
    const double *link_weight;
} ftm_fit_problem_def;

ftm_fit_problem_def ftm_fit_default_problem_def(void);

typedef struct ftm_fit_case_eval {
    double cost;        /* sum_i |X_i - Xhat_i| [m] */
    double avg_err;     /* mean over all nodes of |X_i - Xhat_i| [m] */
    double max_err;     /* largest |X_i - Xhat_i| [m] */
    double mean_ref_u;  /* mean |Xhat_i - X_i^rest| [m] */
    int32_t steps;      /* steps run */
    bool converged;     /* reached the tolerance (or ran fixed_steps) */
    bool unstable;      /* ftm_sim_step failed */
} ftm_fit_case_eval;

enum { FTM_FIT_MAX_CASES = 16 };

typedef struct ftm_fit_eval {
    double cost; /* sum over cases; INFINITY if a case was unstable */
    int32_t steps;
    bool converged; /* every case */
    ftm_fit_case_eval c[FTM_FIT_MAX_CASES];
} ftm_fit_eval;

int ftm_fit_problem_create(const ftm_fit_problem_def *def, ftm_fit_problem **out, ftm_error *err);
void ftm_fit_problem_destroy(ftm_fit_problem *p);

/* Changes the step cap of later evaluations (>= 1). */
void ftm_fit_problem_set_max_steps(ftm_fit_problem *p, int32_t max_steps);
int32_t ftm_fit_problem_max_steps(const ftm_fit_problem *p);

/* Link counts per class in the base mesh (so callers know which classes exist). */
void ftm_fit_problem_class_counts(const ftm_fit_problem *p, int32_t counts[3]);
double ftm_fit_problem_mean_link_length(const ftm_fit_problem *p);
/* Mean rest length of the links of each class (0 where a class is absent). */
void ftm_fit_problem_class_lengths(const ftm_fit_problem *p, double lengths[3]);

/* Builds the spring mesh for params, runs every load case and compares.
 * positions_out: NULL or per case 3 doubles per node (the equilibria).
 * Returns FTM_OK (a case that went unstable gives cost INFINITY) or an error
 * building the mesh or simulation. */
int ftm_fit_problem_eval(ftm_fit_problem *p, const ftm_fit_params *params, ftm_fit_eval *out,
                         double *const *positions_out, ftm_error *err);

/* FEM reference: rest + u for each load case, one factorisation. u_out
 * (per case, 3 per node) gets the positions. The mesh's fixed nodes are the
 * clamps. */
int ftm_fit_fem_reference(const ftm_mesh *mesh, const ftm_fem_material *material, int32_t cases,
                          const double *const *forces, double *const *positions_out,
                          ftm_error *err);
/* The same with per-element materials (NULL, or one per hexahedron /
 * tetrahedron, as ftm_fem_def's): a body of several tissues. */
int ftm_fit_fem_reference_each(const ftm_mesh *mesh, const ftm_fem_material *material,
                               const ftm_fem_material *hex_materials,
                               const ftm_fem_material *tet_materials, int32_t cases,
                               const double *const *forces, double *const *positions_out,
                               ftm_error *err);

#endif
