/* SPDX-License-Identifier: GPL-3.0-or-later */
/* Tissue parameters during a session (docs/protocol.md, "Tissue
 * parameters"). The instructor may change the tissue's mass, damping and
 * stiffness. The server and every replica then switch their simulation to a
 * mesh with the new material (ftm_mesh_with_material, always made from the
 * scene's own mesh, so it depends on the parameters alone), at the same
 * tick: the tick frame of that tick carries the parameters, keyframes carry
 * the ones in force. */
#ifndef FTM_SESSION_TISSUE_H
#define FTM_SESSION_TISSUE_H

#include "ftm/scene.h"
#include "ftm/wire.h"

/* The scene's own parameters (its [material]). */
ftm_wire_tissue ftm_replay_scene_tissue(const ftm_scene *scene);

/* Whether two parameter sets are the same, value for value. */
bool ftm_replay_tissue_equal(const ftm_wire_tissue *a, const ftm_wire_tissue *b);

/* The material a simulation of a scene runs with. Zero-initialise, set scene. */
typedef struct ftm_replay_material {
    const ftm_scene *scene;
    bool changed;            /* current differs from the scene's */
    ftm_wire_tissue current; /* valid when changed */
    ftm_mesh *mesh;          /* the mesh of current (owned); NULL: the scene's mesh */
} ftm_replay_material;

/* Switches sim (a simulation of mat->scene's mesh or one made by an earlier
 * call) to tissue t (NULL: the scene's own); takes effect at its next step.
 * No-op when t is already in force. On error (invalid parameters, a material
 * too stiff for the time step, element forces, out of memory) nothing
 * changes and err says why. */
int ftm_replay_set_tissue(ftm_replay_material *mat, ftm_sim *sim, const ftm_wire_tissue *t,
                          ftm_error *err);
/* The parameters in force. */
ftm_wire_tissue ftm_replay_tissue_now(const ftm_replay_material *mat);
/* The stable range (docs/protocol.md, "Tissue parameters"): a change is
 * refused when the stability guard would have to substep it on every tick
 * (each substep is a whole step's work on the server and on every replica):
 * when the scene's time step exceeds the new material's critical step times
 * FTM_TISSUE_MAX_SUBSTEPS, or (springs) when its damping is below
 * FTM_TISSUE_DAMPING_SHARE of the layer-by-layer update's bound
 * (d/2m >= 0.11 w_max h/h_crit, docs/core.md): below that share a pressed
 * lattice needed 2 substeps and more in server_session.sh guard. Between
 * the share and the bound a change is applied with a warning. The scene's
 * own tissue is always in range, and so is what it needs. */
#define FTM_TISSUE_MAX_SUBSTEPS 2
#define FTM_TISSUE_DAMPING_SHARE 0.5

typedef struct ftm_tissue_range {
    double time_step;      /* [s], the scene's */
    double h_crit;         /* critical time step of the material [s] */
    int32_t substeps;      /* the substeps it needs at time_step: 1, 2, 4, ... */
    int32_t max_substeps;  /* in range: FTM_TISSUE_MAX_SUBSTEPS, or the scene's own need */
    bool masses_fixed;     /* element forces whose density gives the masses */
    double stiffness_max;  /* largest stiffness in range at this mass, damping [N/m] */
    double mass_min;       /* smallest node mass in range at this stiffness [kg]; 0: any */
    double damping_min;    /* smallest damping in range at this stiffness [N s/m]; 0: any */
    double damping_bound;  /* the layer update's damping bound [N s/m]; 0: none applies */
} ftm_tissue_range;

/* The range around tissue t (NULL: the one in force) for sim, the simulation
 * mat runs: what a change to t would give. Springs: from t's mesh
 * (ftm_mesh_with_material); element forces: the simulation's critical step
 * scaled by t's stiffness (a factor on E) and, unless the elements' density
 * gives the masses, by its node mass. FTM_OK or what building t's mesh
 * failed with (err). */
int ftm_replay_tissue_range(const ftm_replay_material *mat, const ftm_sim *sim,
                            const ftm_wire_tissue *t, ftm_tissue_range *out, ftm_error *err);
/* Whether t is in range: FTM_OK, or FTM_ERANGE with why (cap bytes, at most
 * 127 used, for a ControlReply) naming the parameter and its range; other
 * errors as ftm_replay_tissue_range. *out (may be NULL) gets t's range. */
int ftm_replay_tissue_check(const ftm_replay_material *mat, const ftm_sim *sim,
                            const ftm_wire_tissue *t, ftm_tissue_range *out, char *why, size_t cap,
                            ftm_error *err);

/* Frees the mesh; only after the simulation is destroyed. */
void ftm_replay_material_free(ftm_replay_material *mat);

#endif
