/* SPDX-License-Identifier: GPL-3.0-or-later */
/* The paper's mechanical experiments (Choi, Sun, Heng 2004, §4.1, Figs. 9-12)
 * and the numerical stability sweep, as library functions that fill result
 * structs: `ftm experiment` and `ftm stability` print and write them, the
 * tests in tests/experiments/ assert on them. See docs/experiments.md and
 * docs/stability.md. Everything is deterministic (no clocks, no randomness). */
#ifndef FTM_TOOLS_EXPERIMENTS_H
#define FTM_TOOLS_EXPERIMENTS_H

#include <stdbool.h>
#include <stdint.h>

struct ftm_sim;
struct ftm_mesh;

/* ---- helpers shared with `ftm experiment volume` (exp_volume.c) ---------- */

/* Largest |x_i - X_i| over the mesh's nodes [m] (NaN if a position is). */
double ftm_exp_max_displacement(const struct ftm_sim *sim, const struct ftm_mesh *mesh);
/* Runs until no node moves more than tol * (largest displacement) over an
 * interval of `every` steps, or max_steps. Returns the steps taken, or a
 * negative code if a step failed. */
int ftm_exp_run_to_rest(struct ftm_sim *sim, const struct ftm_mesh *mesh, double tol, int every,
                        int max_steps);

/* The optimum-depth rule's measure (paper 3.1.3): the largest nodal position
 * change from the shape prev (depth n) to cur (depth n+1, 3 doubles a node),
 * relative to cur's largest displacement from rest (*max_disp, may be NULL;
 * prev NULL: change 0). The optimum depth is the smallest n whose change is
 * below a threshold. */
double ftm_exp_shape_change(const struct ftm_mesh *mesh, const double *prev, const double *cur,
                            double *max_disp);

#define FTM_EXP_MAX_K 8
#define FTM_EXP_MAX_DEPTH 48
#define FTM_EXP_MAX_NX 101

/* ---- Optimum penetration depth (§3.1.3, §4.1.1, Figs. 9-10) -------------
 * 2D triangular lattice, bottom row fixed, a constant downward force on the
 * centre node of the top row. For n = 1, 2, ... the run is repeated from rest
 * at depth n; the shape at the end of the run is compared with the shape at
 * depth n+1:
 *     change(n) = max_i |x_i(n+1) - x_i(n)| / max_i |x_i(n+1) - X_i|,
 * the largest nodal position change caused by one more layer, relative to the
 * largest displacement. The calibrated (optimum) depth is the smallest n with
 * change(n) < threshold. The "end of the run" is either equilibrium
 * (observe_time <= 0) or a fixed observation time after the load is applied
 * (observe_time > 0 seconds, the same for every stiffness). */
typedef struct ftm_exp_depth_def {
    int nx, ny;           /* lattice nodes per row, rows (nx odd) */
    double spacing;       /* [m] */
    double mass, damping; /* per node, the same for every stiffness */
    double time_step;     /* the same for every stiffness */
    double force;         /* downward force on the top centre node [N] */
    double threshold;     /* on change(n) */
    int max_depth;        /* <= FTM_EXP_MAX_DEPTH - 1 */
    double observe_time;  /* <= 0: equilibrium */
    double rest_tol;      /* equilibrium: no node moves more than rest_tol * max displacement in 100 steps */
    int k_count;
    double stiffness[FTM_EXP_MAX_K];
} ftm_exp_depth_def;

typedef struct ftm_exp_depth_result {
    int k_count, nx, depth_count; /* depths 1..depth_count were run */
    double stiffness[FTM_EXP_MAX_K];
    int calibrated[FTM_EXP_MAX_K]; /* optimum depth; -1: not reached by max_depth */
    double change[FTM_EXP_MAX_K][FTM_EXP_MAX_DEPTH]; /* change[k][n], n >= 1 */
    double max_disp[FTM_EXP_MAX_K][FTM_EXP_MAX_DEPTH];  /* largest displacement at depth n [m] */
    /* top-row vertical displacement (negative = down) at depth n, node ix */
    double profile[FTM_EXP_MAX_K][FTM_EXP_MAX_DEPTH][FTM_EXP_MAX_NX];
    double x[FTM_EXP_MAX_NX]; /* rest x of the top-row nodes, relative to the loaded node */
} ftm_exp_depth_result;

ftm_exp_depth_def ftm_exp_default_depth_def(bool quick);
/* result is large (about 3 MB): allocate it. Returns 0 or a negative code. */
int ftm_exp_depth(const ftm_exp_depth_def *def, ftm_exp_depth_result *result);

/* ---- Tissue responses (§4.1.2, Fig. 11) ----------------------------------
 * 2D triangular lattice, bottom row fixed, the top row pulled upward by a
 * total force F split equally over its nodes (uniaxial tension), full depth.
 * Strain = mean upward displacement of the top row / lattice height.
 *  (a) creep: F = creep_force constant from t = 0, strain against time;
 *  (b) hysteresis: F ramped 0 -> hyst_force in ramp_time, then back to 0 in
 *      ramp_time, strain against force; the loop area is the integral of
 *      strain dF around the path (closed back to the start);
 *  (c) load-deformation: F = rate * t up to rate_force, strain against force. */
#define FTM_EXP_TISSUE_DAMPINGS 3

typedef struct ftm_exp_tissue_def {
    int nx, ny;
    double spacing, mass, stiffness, time_step;
    double damping[FTM_EXP_TISSUE_DAMPINGS];
    double creep_force, creep_time;
    double hyst_force, ramp_time;
    double rate, rate_force;
    int sample_every; /* steps between recorded samples */
} ftm_exp_tissue_def;

typedef struct ftm_exp_curve {
    int count;
    double *a; /* time (creep) or force (hysteresis, load-deformation) */
    double *b; /* strain */
} ftm_exp_curve;

typedef struct ftm_exp_tissue_result {
    ftm_exp_curve creep[FTM_EXP_TISSUE_DAMPINGS];
    ftm_exp_curve hyst[FTM_EXP_TISSUE_DAMPINGS]; /* first half loading, second unloading */
    ftm_exp_curve rate[FTM_EXP_TISSUE_DAMPINGS];
    double creep_final[FTM_EXP_TISSUE_DAMPINGS];  /* strain at creep_time */
    double creep_static[FTM_EXP_TISSUE_DAMPINGS]; /* equilibrium strain under creep_force */
    double creep_t63[FTM_EXP_TISSUE_DAMPINGS];    /* time to 63.2% of creep_static */
    double creep_max_drop[FTM_EXP_TISSUE_DAMPINGS]; /* largest decrease between samples */
    double hyst_area[FTM_EXP_TISSUE_DAMPINGS];    /* loop area (strain x N) */
    double hyst_max_gap[FTM_EXP_TISSUE_DAMPINGS]; /* largest unloading - loading strain at equal force */
    double hyst_residual[FTM_EXP_TISSUE_DAMPINGS]; /* strain left when F is back to 0 */
    /* load-deformation: secant compliance (strain / force) over the first and
     * last tenth of the force range, and the static (equilibrium) strain at
     * rate_force */
    double rate_slope_start[FTM_EXP_TISSUE_DAMPINGS], rate_slope_end[FTM_EXP_TISSUE_DAMPINGS];
    double static_strain_half, static_strain_full; /* equilibrium at rate_force/2, rate_force */
} ftm_exp_tissue_result;

ftm_exp_tissue_def ftm_exp_default_tissue_def(bool quick);
int ftm_exp_tissue(const ftm_exp_tissue_def *def, ftm_exp_tissue_result *result);
void ftm_exp_tissue_free(ftm_exp_tissue_result *result);

/* ---- Anisotropy (§4.1.3, Fig. 12) ----------------------------------------
 * n x n x n cubic lattice, 18-neighbour stencil; z is vertical. Models: the
 * isotropic control, A (horizontal x and y springs 1/ratio of the vertical),
 * B (horizontal springs ratio times the vertical), via axis_scale. Two loads,
 * at equilibrium, each with the opposite face fixed: vertical (-z) on the
 * centre of the top face, bottom fixed; horizontal (+x) on the centre of the
 * x-min face, x-max face fixed. Profiles: the displacement along the load
 * (positive into the body) of the nodes on the line through the loaded node
 * across its face (along x for the vertical load, along z for the horizontal
 * one), and along the load direction into the body. */
enum { FTM_EXP_ISO = 0, FTM_EXP_A = 1, FTM_EXP_B = 2, FTM_EXP_MODELS = 3 };
enum { FTM_EXP_VERTICAL = 0, FTM_EXP_HORIZONTAL = 1, FTM_EXP_LOADS = 2 };

typedef struct ftm_exp_aniso_def {
    int n; /* odd */
    double spacing, mass, damping, stiffness, ratio, force, time_step;
    double rest_tol; /* equilibrium: no node moves more than rest_tol * max displacement in 200 steps */
} ftm_exp_aniso_def;

typedef struct ftm_exp_aniso_result {
    int n;
    const char *model_name[FTM_EXP_MODELS];
    /* across[m][l][i]: node i along the line across the loaded face (i = n/2
     * is the loaded node); into[m][l][i]: node i steps into the body */
    double across[FTM_EXP_MODELS][FTM_EXP_LOADS][FTM_EXP_MAX_NX];
    double into[FTM_EXP_MODELS][FTM_EXP_LOADS][FTM_EXP_MAX_NX];
    double peak[FTM_EXP_MODELS][FTM_EXP_LOADS];  /* loaded node's displacement */
    double width[FTM_EXP_MODELS][FTM_EXP_LOADS]; /* sum(across) / peak, in nodes: the dent's width */
    int steps[FTM_EXP_MODELS][FTM_EXP_LOADS];
} ftm_exp_aniso_result;

ftm_exp_aniso_def ftm_exp_default_aniso_def(bool quick);
int ftm_exp_aniso(const ftm_exp_aniso_def *def, ftm_exp_aniso_result *result);

/* ---- Stability sweep (`ftm stability`, docs/stability.md) ---------------- */
typedef enum ftm_stab_mesh_kind {
    FTM_STAB_LATTICE2D = 0, /* triangular lattice, bottom row fixed */
    FTM_STAB_LATTICE3D = 1, /* cubic lattice, 18 neighbours, bottom face fixed */
    FTM_STAB_SHORT = 2,     /* 2D lattice, one node moved to short_frac of a spacing from a neighbour */
    FTM_STAB_HUB = 3,       /* 2D lattice, one node linked to every node within hub_radius */
} ftm_stab_mesh_kind;

typedef struct ftm_stab_config {
    char name[48];
    ftm_stab_mesh_kind kind;
    int n;              /* lattice nodes per side */
    double mass, stiffness;
    double damping_factor; /* d = factor * 2m * 0.025 w_max (the sweep's unit) */
    double damping;        /* if damping_factor < 0: absolute d */
    int depth;
    double short_frac;     /* FTM_STAB_SHORT: distance to the neighbour / spacing */
    bool short_scale_k;    /* FTM_STAB_SHORT: the short link's k scaled by spacing / length */
    double hub_radius;     /* FTM_STAB_HUB: in spacings */
    double horiz_scale;    /* FTM_STAB_LATTICE3D: x and y springs scaled (0: 1) */
} ftm_stab_config;

typedef struct ftm_stab_row {
    ftm_stab_config config;
    int nodes, max_degree;
    double spacing;        /* mean link length [m] */
    double h_crit;         /* ftm_mesh_critical_time_step (Gershgorin) [s] */
    double h_spectral;     /* 2 / sqrt(lambda_max(M^-1 K)) at rest, by power iteration [s] */
    double damping;        /* d used [N s/m] */
    double damping_ratio;  /* d/2m / (0.025 w_max); the core warns below 4.4 h/h_crit */
    bool warned;           /* the core logged its low-damping warning at h = lo */
    /* measured boundary: largest stable h / h_crit, bisection in [lo, hi] */
    double measured;       /* < 0: unstable at the smallest ratio tried; > hi: stable at hi */
    double lo, hi;         /* bracket: stable at lo, unstable at hi (when both exist) */
    bool unstable_anywhere;
    /* guard ON at the unstable ratios probe[0] = hi (first unstable), probe[1] = 2 hi */
    double probe_ratio[2];
    uint64_t guard_events[2], unstable_steps[2];
    int max_substeps[2];
    bool reported[2];      /* ftm_sim_step returned FTM_EUNSTABLE */
    bool bounded[2];       /* the guarded run stayed bounded (the stability criterion) */
    bool nan_seen[2];      /* a non-finite position was ever observed (must be false) */
    double max_u[2], late_u[2]; /* largest displacement: whole run, last quarter [m] */
    /* "reported" (FTM_EUNSTABLE), "recovered" (guard events, bounded at the
     * end), "caught" (guard events, but still above one spacing at the end),
     * "missed" (no guard event, unbounded), "stable" (no event, bounded), "-" */
    const char *outcome[2];
    /* guard ON at the largest stable ratio (measured, or hi when stable
     * everywhere; none when unstable everywhere): guard events there are
     * false alarms */
    double stable_ratio;   /* 0: no stable ratio */
    bool stable_long;      /* unguarded, still stable over the longer time */
    uint64_t stable_events;
} ftm_stab_row;

typedef struct ftm_stab_def {
    bool quick;
    double sim_time_factor; /* simulated time = factor * h_crit */
    int bisect_iters;
    double lo, hi;
    double guard_length; /* guarded runs last this many times the simulated time */
} ftm_stab_def;

ftm_stab_def ftm_stab_default_def(bool quick);
/* The configurations of the sweep; returns the count (<= max). */
int ftm_stab_configs(bool quick, ftm_stab_config *configs, int max);
/* Measures one configuration. Returns 0 or a negative code (mesh/sim error). */
int ftm_stab_run(const ftm_stab_def *def, const ftm_stab_config *config, ftm_stab_row *row);

#endif
