/* SPDX-License-Identifier: GPL-3.0-or-later */
/* Tissue parameters during a session (tissue.h). */
#include "tissue.h"

ftm_wire_tissue ftm_replay_scene_tissue(const ftm_scene *scene)
{
    ftm_material_def m = ftm_scene_material(scene);
    return (ftm_wire_tissue){m.node_mass, m.node_damping, m.stiffness, m.axis_scale};
}

ftm_wire_tissue ftm_replay_tissue_now(const ftm_replay_material *mat)
{
    return mat->changed ? mat->current : ftm_replay_scene_tissue(mat->scene);
}

bool ftm_replay_tissue_equal(const ftm_wire_tissue *a, const ftm_wire_tissue *b)
{
    return a->node_mass == b->node_mass && a->node_damping == b->node_damping &&
           a->stiffness == b->stiffness && a->axis_scale.x == b->axis_scale.x &&
           a->axis_scale.y == b->axis_scale.y && a->axis_scale.z == b->axis_scale.z;
}

int ftm_replay_set_tissue(ftm_replay_material *mat, ftm_sim *sim, const ftm_wire_tissue *t,
                          ftm_error *err)
{
    ftm_wire_tissue base = ftm_replay_scene_tissue(mat->scene), now = ftm_replay_tissue_now(mat);
    if (!t)
        t = &base;
    if (ftm_replay_tissue_equal(t, &now))
        return FTM_OK;
    const ftm_mesh *scene_mesh = ftm_scene_mesh(mat->scene);
    ftm_mesh *m = NULL;
    int rc;
    if (!ftm_replay_tissue_equal(t, &base)) {
        ftm_material_def from = ftm_scene_material(mat->scene);
        ftm_material_def to = {t->node_mass, t->node_damping, t->stiffness, t->axis_scale};
        if ((rc = ftm_mesh_with_material(scene_mesh, &from, &to, &m, err)))
            return rc;
    }
    if ((rc = ftm_sim_set_mesh(sim, m ? m : scene_mesh, err))) {
        ftm_mesh_destroy(m);
        return rc;
    }
    ftm_mesh_destroy(mat->mesh);
    mat->mesh = m;
    mat->changed = m != NULL;
    mat->current = *t;
    return FTM_OK;
}

void ftm_replay_material_free(ftm_replay_material *mat)
{
    ftm_mesh_destroy(mat->mesh);
    mat->mesh = NULL;
    mat->changed = false;
}
