/* SPDX-License-Identifier: GPL-3.0-or-later */
/* Tissue parameters during a session (tissue.h). */
#include "tissue.h"

#include "step.h"

#include <math.h>
#include <stdio.h>

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

/* The critical step of tissue t for sim (which runs mat's tissue now), and
 * for springs t's mesh (*built, owned by the caller; NULL when t is in force
 * or the scene's own). */
static int critical_step(const ftm_replay_material *mat, const ftm_sim *sim,
                         const ftm_wire_tissue *t, double *hc, ftm_mesh **built, ftm_error *err)
{
    *built = NULL;
    const ftm_wire_tissue now = ftm_replay_tissue_now(mat);
    if (ftm_replay_tissue_equal(t, &now)) {
        *hc = ftm_sim_critical_time_step(sim);
        return FTM_OK;
    }
    if (ftm_replay_sim_def(mat->scene).forces != FTM_FORCES_SPRINGS) {
        /* element forces: stiffness is a factor on E, so lambda_max ~ k / m */
        double density = 0.0, f = now.stiffness / t->stiffness;
        ftm_scene_fem_material(mat->scene, NULL, NULL, &density);
        if (!(density > 0.0))
            f *= t->node_mass / now.node_mass;
        if (!(f > 0.0) || !isfinite(f))
            return ftm_error_set(err, FTM_EINVAL, "tissue range: stiffness %g N/m, node mass %g kg",
                                 t->stiffness, t->node_mass);
        *hc = ftm_sim_critical_time_step(sim) * sqrt(f);
        return FTM_OK;
    }
    const ftm_wire_tissue base = ftm_replay_scene_tissue(mat->scene);
    const ftm_mesh *scene_mesh = ftm_scene_mesh(mat->scene);
    if (ftm_replay_tissue_equal(t, &base)) {
        *hc = ftm_mesh_critical_time_step(scene_mesh);
        return FTM_OK;
    }
    ftm_material_def from = ftm_scene_material(mat->scene);
    ftm_material_def to = {t->node_mass, t->node_damping, t->stiffness, t->axis_scale};
    int rc = ftm_mesh_with_material(scene_mesh, &from, &to, built, err);
    if (rc)
        return rc;
    *hc = ftm_mesh_critical_time_step(*built);
    return FTM_OK;
}

/* The damping the layer-by-layer update needs on mesh m at time step h, as
 * the core warns (common/src/sim.c, warn_low_damping: d/2m >= 0.055 lambda_i
 * h per node): the nominal damping (the node damping a material of nominal
 * `damping` gives each node is that times the node's share, d_i / damping;
 * uniform where damping is 0) for its worst node to meet it. */
static double damping_needed(const ftm_mesh *m, double h, double damping)
{
    double need = 0.0;
    for (int32_t i = 0; i < ftm_mesh_node_count(m); i++) {
        if (ftm_mesh_fixed(m, i))
            continue;
        const int32_t *nb;
        const double *k, *len;
        const int32_t deg = ftm_mesh_neighbors(m, i, &nb, &k, &len);
        const double mi = ftm_mesh_mass(m, i);
        double lambda = 0.0;
        for (int32_t e = 0; e < deg; e++)
            lambda += k[e] * (1.0 / mi + 1.0 / sqrt(mi * ftm_mesh_mass(m, nb[e])));
        const double share = damping > 0.0 ? ftm_mesh_damping(m, i) / damping : 1.0;
        if (lambda > 0.0 && share > 0.0) {
            double d = 2.0 * mi * 0.055 * lambda * h / share;
            need = d > need ? d : need;
        }
    }
    return isfinite(need) ? need : 0.0;
}

static int32_t substeps_for(double h, double hc)
{
    int32_t s = 1;
    while (h > hc * s && s < (1 << 20))
        s *= 2;
    return s;
}

/* The substeps allowed: FTM_TISSUE_MAX_SUBSTEPS, or what the scene's own
 * tissue needs if more (its own tissue is always in range). */
static int range_at(const ftm_replay_material *mat, const ftm_sim *sim, const ftm_wire_tissue *t,
                    ftm_tissue_range *out, ftm_error *err)
{
    const ftm_wire_tissue now = ftm_replay_tissue_now(mat);
    ftm_mesh *built = NULL;
    double hc = INFINITY;
    int rc = critical_step(mat, sim, t, &hc, &built, err);
    if (rc)
        return rc;
    const ftm_sim_def def = ftm_replay_sim_def(mat->scene);
    const double h = def.time_step;
    double density = 0.0;
    ftm_scene_fem_material(mat->scene, NULL, NULL, &density);
    out->time_step = h;
    out->h_crit = hc;
    out->substeps = substeps_for(h, hc);
    out->damping_bound = 0.0;
    if (def.forces == FTM_FORCES_SPRINGS) {
        const ftm_mesh *m = built ? built
                                  : ftm_replay_tissue_equal(t, &now) ? ftm_sim_mesh(sim)
                                                                     : ftm_scene_mesh(mat->scene);
        out->damping_bound = damping_needed(m, h, t->node_damping);
    }
    out->masses_fixed = def.forces != FTM_FORCES_SPRINGS && density > 0.0;
    ftm_mesh_destroy(built);
    return FTM_OK;
}

int ftm_replay_tissue_range(const ftm_replay_material *mat, const ftm_sim *sim,
                            const ftm_wire_tissue *t, ftm_tissue_range *out, ftm_error *err)
{
    const ftm_wire_tissue now = ftm_replay_tissue_now(mat), base = ftm_replay_scene_tissue(mat->scene);
    if (!t)
        t = &now;
    ftm_tissue_range own;
    int rc = range_at(mat, sim, &base, &own, err);
    if (!rc)
        rc = range_at(mat, sim, t, out, err);
    if (rc)
        return rc;
    out->max_substeps = own.substeps > FTM_TISSUE_MAX_SUBSTEPS ? own.substeps : FTM_TISSUE_MAX_SUBSTEPS;
    /* lambda_max = 4/h_crit^2 grows as k and falls as m: in range while
     * h <= max_substeps h_crit */
    const double q = isfinite(out->h_crit) ? out->max_substeps * out->h_crit / out->time_step : INFINITY;
    out->stiffness_max = t->stiffness * q * q;
    out->mass_min = out->masses_fixed ? 0.0 : t->node_mass / (q * q);
    /* the damping bound grows as k (lambda m does not change with m) */
    out->damping_min = 0.0;
    if (out->damping_bound > 0.0) {
        double share = FTM_TISSUE_DAMPING_SHARE, own_share = base.node_damping / own.damping_bound;
        share = own.damping_bound > 0.0 && own_share < share ? own_share : share;
        out->damping_min = share * out->damping_bound;
        double k_damp = t->stiffness * t->node_damping / out->damping_min;
        out->stiffness_max = k_damp < out->stiffness_max ? k_damp : out->stiffness_max;
    }
    return FTM_OK;
}

int ftm_replay_tissue_check(const ftm_replay_material *mat, const ftm_sim *sim,
                            const ftm_wire_tissue *t, ftm_tissue_range *out, char *why, size_t cap,
                            ftm_error *err)
{
    ftm_tissue_range r;
    const ftm_wire_tissue base = ftm_replay_scene_tissue(mat->scene), now = ftm_replay_tissue_now(mat);
    int rc = ftm_replay_tissue_range(mat, sim, t, &r, err);
    if (rc)
        return rc;
    if (out)
        *out = r;
    if (cap)
        why[0] = 0;
    const bool damped = !(t->node_damping < r.damping_min);
    if ((r.substeps <= r.max_substeps && damped) || ftm_replay_tissue_equal(t, &base))
        return FTM_OK;
    if (!damped && t->stiffness == now.stiffness)
        snprintf(why, cap,
                 "damping %.4g N s/m is below the stable range [%.3g, ...) N s/m at stiffness %.4g "
                 "N/m, time step %g s",
                 t->node_damping, r.damping_min, t->stiffness, r.time_step);
    else if (!damped)
        snprintf(why, cap,
                 "stiffness %.4g N/m is past the stable range (0, %.4g] N/m at damping %.4g N s/m, "
                 "time step %g s",
                 t->stiffness, r.stiffness_max, t->node_damping, r.time_step);
    else if (t->stiffness != now.stiffness || t->node_mass == now.node_mass)
        snprintf(why, cap,
                 "stiffness %.4g N/m is past the stable range (0, %.4g] N/m: it needs %d substeps "
                 "of %g s, at most %d",
                 t->stiffness, r.stiffness_max, (int)r.substeps, r.time_step, (int)r.max_substeps);
    else
        snprintf(why, cap,
                 "node mass %.4g kg is below the stable range [%.4g, ...) kg: it needs %d substeps "
                 "of %g s, at most %d",
                 t->node_mass, r.mass_min, (int)r.substeps, r.time_step, (int)r.max_substeps);
    return ftm_error_set(err, FTM_ERANGE, "%s", why);
}

void ftm_replay_material_free(ftm_replay_material *mat)
{
    ftm_mesh_destroy(mat->mesh);
    mat->mesh = NULL;
    mat->changed = false;
}
