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
/* Frees the mesh; only after the simulation is destroyed. */
void ftm_replay_material_free(ftm_replay_material *mat);

#endif
