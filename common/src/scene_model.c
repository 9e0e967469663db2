/* SPDX-License-Identifier: GPL-3.0-or-later */
/* What model a scene runs, in words for a log or a summary: the force model,
 * its material, the far field, and, for springs, why (docs/feel.md, "Which
 * model a scene should use"). */
#include "ftm/scene.h"
#include "ftm/sim.h"

#include <stdio.h>

static const char *forces_words(ftm_forces f)
{
    switch (f) {
    case FTM_FORCES_SPRINGS: return "springs";
    case FTM_FORCES_LINEAR_FEM: return "linear FEM element forces";
    case FTM_FORCES_COROT_FEM: return "co-rotational FEM element forces";
    case FTM_FORCES_NEO_HOOKEAN: return "neo-Hookean element forces";
    }
    return "?";
}

const char *ftm_forces_name(ftm_forces forces)
{
    switch (forces) {
    case FTM_FORCES_SPRINGS: return "springs";
    case FTM_FORCES_LINEAR_FEM: return "linear-fem";
    case FTM_FORCES_COROT_FEM: return "corot-fem";
    case FTM_FORCES_NEO_HOOKEAN: return "neo-hookean";
    }
    return "?";
}

int ftm_scene_describe_model(const ftm_scene *scene, char *buf, size_t size)
{
    const ftm_mesh *m = ftm_scene_mesh(scene);
    const ftm_sim_def d = ftm_scene_sim_def(scene);
    const int32_t hex = ftm_mesh_hexahedron_count(m), tet = ftm_mesh_tetrahedron_count(m);
    const char *far = d.far_field == FTM_FAR_FIELD_ELASTIC ? "elastic far field"
                                                           : "fixed far field (the paper's)";
    char elems[64];
    if (hex && tet)
        snprintf(elems, sizeof elems, "%d hexahedra and %d tetrahedra", (int)hex, (int)tet);
    else
        snprintf(elems, sizeof elems, "%d %s", (int)(hex ? hex : tet),
                 hex ? "hexahedra" : "tetrahedra");
    if (d.forces != FTM_FORCES_SPRINGS)
        return snprintf(buf, size, "%s on %s (E %.4g Pa, nu %.3g), %s, depth %d",
                        forces_words(d.forces), elems, d.young, d.poisson, far, (int)d.depth);
    const double k = ftm_scene_material(scene).stiffness;
    if (hex || tet)
        return snprintf(buf, size,
                        "springs (k %.4g N/m), %s, depth %d; the mesh has %s: "
                        "forces = neo-hookean with a [fem] material feels like tissue",
                        k, far, (int)d.depth, elems);
    return snprintf(buf, size,
                    "springs (k %.4g N/m), %s, depth %d: a mesh without volume elements "
                    "takes no element forces and no elastic far field",
                    k, far, (int)d.depth);
}
