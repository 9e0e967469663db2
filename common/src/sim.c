/* SPDX-License-Identifier: GPL-3.0-or-later */
/* The force transmittal integrator: contacts, cached layers and update
 * schedule, Gauss-Seidel central differences, relaxation and sleep, the
 * stability guard, reactions and the state hash. */
#include "ftm/sim.h"

#include "error.h"
#include "farfield.h"
#include "sim_elem.h"
#include "sim_internal.h"

#include <math.h>
#include <stdlib.h>
#include <string.h>

#define FTM_SUBSTEP_RETRY 1024 /* steps before the guard tries fewer substeps */

ftm_sim_def ftm_default_sim_def(void)
{
    return (ftm_sim_def){.time_step = 1e-3,
                         .depth = 10,
                         .order = FTM_ORDER_LAYER_COLORED,
                         .sleep_tolerance = 1e-6,
                         .region_sleep_steps = 0,
                         .guard = true,
                         .guard_motion = 0.5,
                         .max_substeps = 64,
                         .cache_layers = true,
                         .planar_kernel = true,
                         .log = NULL,
                         .log_user = NULL};
}

#define FTM_MAX_DEPTH 1000000

static int check_def(const ftm_sim_def *d, ftm_error *err)
{
    if (!(d->time_step >= FTM_MIN_TIME_STEP && d->time_step <= FTM_MAX_TIME_STEP))
        return ftm_error_set(err, FTM_EINVAL, "sim: time_step must be in %g..%g s (got %g)",
                             FTM_MIN_TIME_STEP, FTM_MAX_TIME_STEP, d->time_step);
    if (d->depth < 0 || d->depth > FTM_MAX_DEPTH)
        return ftm_error_set(err, FTM_EINVAL, "sim: depth must be in 0..%d (got %d)",
                             FTM_MAX_DEPTH, (int)d->depth);
    if (d->order != FTM_ORDER_LAYER_COLORED && d->order != FTM_ORDER_BFS &&
        d->order != FTM_ORDER_LAYER_JACOBI)
        return ftm_error_set(err, FTM_EINVAL, "sim: unknown order %d", (int)d->order);
    if (!(d->sleep_tolerance >= 0.0) || !isfinite(d->sleep_tolerance))
        return ftm_error_set(err, FTM_EINVAL, "sim: sleep_tolerance must be >= 0 (got %g)",
                             d->sleep_tolerance);
    if (d->region_sleep_steps < 0)
        return ftm_error_set(err, FTM_EINVAL, "sim: region_sleep_steps must be >= 0 (got %d)",
                             (int)d->region_sleep_steps);
    if (!(d->guard_motion > 0.0) || !isfinite(d->guard_motion))
        return ftm_error_set(err, FTM_EINVAL, "sim: guard_motion must be > 0 (got %g)",
                             d->guard_motion);
    if (d->max_substeps < 1 || d->max_substeps > 1 << 20)
        return ftm_error_set(err, FTM_EINVAL, "sim: max_substeps must be in 1..%d (got %d)",
                             1 << 20, (int)d->max_substeps);
    if (d->far_field != FTM_FAR_FIELD_FIXED && d->far_field != FTM_FAR_FIELD_ELASTIC)
        return ftm_error_set(err, FTM_EINVAL, "sim: unknown far_field %d", (int)d->far_field);
    if (d->label_material_count < 0 || (d->label_material_count > 0 && !d->label_materials))
        return ftm_error_set(err, FTM_EINVAL, "sim: %d label materials at %p",
                             (int)d->label_material_count, (const void *)d->label_materials);
    if (d->label_material_count > 0 && d->forces == FTM_FORCES_SPRINGS)
        return ftm_error_set(err, FTM_EINVAL,
                             "sim: per-label materials are for element forces (springs take "
                             "their stiffness from the mesh's links)");
    return FTM_OK;
}

void ftm_sim_destroy(ftm_sim *sim)
{
    if (!sim)
        return;
    free(sim->x);
    free(sim->xp);
    free(sim->coef);
    free(sim->force);
    free(sim->ke_w);
    free(sim->work_mark);
    free(sim->kind);
    free(sim->contacts);
    free(sim->sources);
    free(sim->disp);
    ftm_layering_free(&sim->ly);
    ftm_schedule_free(&sim->s);
    free(sim->relax);
    free(sim->relax_tmp);
    free(sim->relax_save);
    free(sim->reaction);
    ftm_elem_free(sim->elem);
    ftm_far_free(sim->far);
    free(sim->label_mat);
    free(sim);
}

/* a = 1/(m/h^2 + d/2h), b = 2m/h^2 * a, c = (m/h^2 - d/2h) * a, so that
 * x_new = a (F - sum f) + b x - c x_prev  (Eq. 8 written for positions). */
static void node_coef(const ftm_mesh *m, const double *mass, int32_t i, double h, double *out)
{
    double mh = mass[i] / (h * h), dh = m->damping[i] / (2.0 * h);
    double a = 1.0 / (mh + dh);
    out[0] = a;
    out[1] = 2.0 * mh * a;
    out[2] = (mh - dh) * a;
}

static void set_substep_length(ftm_sim *sim, double h)
{
    sim->h_sub = h;
    for (int32_t i = 0; i < sim->n; i++) {
        node_coef(sim->m, ftm_sim_masses(sim), i, h, sim->coef + FTM_COEF * i);
        sim->ke_w[i] = 0.5 * ftm_sim_masses(sim)[i] / (h * h);
    }
    sim->s.linked = false; /* the schedule's blocks hold copies of the coefficients */
}

/* The layer-by-layer (Gauss-Seidel) update is not time-reversible like plain
 * central differences: a node's update sees its earlier neighbours' new
 * positions, a velocity coupling of order h^3 (k/m) v that feeds energy into
 * smooth modes, so nodal damping must outweigh it. The stability sweep
 * (docs/stability.md) finds the damping needed grows with the time step:
 * d/2m >= 0.11 w_max h/h_crit, i.e. 0.055 lambda h with lambda = w_max^2 the
 * Gershgorin bound. Warns once, naming the worst node. */
static void warn_low_damping(const ftm_sim *sim)
{
    const ftm_mesh *m = sim->m;
    const double h = sim->def.time_step;
    int32_t worst = -1;
    double worst_ratio = INFINITY, need = 0.0;
    for (int32_t i = 0; i < m->node_count; i++) {
        if (m->fixed[i])
            continue;
        double lambda = 0.0;
        for (int32_t e = m->adj_start[i]; e < m->adj_start[i + 1]; e++)
            lambda += m->adj_k[e] *
                      (1.0 / m->mass[i] + 1.0 / sqrt(m->mass[i] * m->mass[m->adj_node[e]]));
        if (lambda <= 0.0)
            continue;
        double required = 0.055 * lambda * h, ratio = m->damping[i] / (2.0 * m->mass[i]) / required;
        if (ratio < worst_ratio) {
            worst_ratio = ratio;
            worst = i;
            need = required;
        }
    }
    if (worst >= 0 && worst_ratio < 1.0)
        ftm_logf(sim->def.log, sim->def.log_user, FTM_LOG_WARN,
                 "nodal damping is low for the layer-by-layer update at this time step (node %d: "
                 "d/2m = %g, needs about %g): the scene may slowly gain energy; raise damping or "
                 "shorten the time step (docs/stability.md)",
                 (int)worst, m->damping[worst] / (2.0 * m->mass[worst]), need);
}

static double energy_floor(const ftm_mesh *m); /* energy guard, below */

int ftm_sim_create(const ftm_mesh *m, const ftm_sim_def *def, ftm_sim **out, ftm_error *err)
{
    if (!m || !out)
        return ftm_error_set(err, FTM_EINVAL, "sim: null argument");
    ftm_sim_def d = def ? *def : ftm_default_sim_def();
    int rc = check_def(&d, err);
    if (rc)
        return rc;
    ftm_sim *sim = calloc(1, sizeof *sim);
    if (!sim)
        return ftm_error_set(err, FTM_ENOMEM, "sim: out of memory");
    sim->m = m;
    sim->def = d;
    sim->n = m->node_count;
    if (d.label_material_count > 0) { /* the caller's array need not outlive the call */
        size_t bytes = (size_t)d.label_material_count * sizeof *sim->label_mat;
        if (!(sim->label_mat = malloc(bytes))) {
            ftm_sim_destroy(sim);
            return ftm_error_set(err, FTM_ENOMEM, "sim: out of memory");
        }
        memcpy(sim->label_mat, d.label_materials, bytes);
        sim->def.label_materials = sim->label_mat;
    } else {
        sim->def.label_materials = NULL;
        sim->def.label_material_count = 0;
    }
    size_t n = (size_t)sim->n;
    sim->x = malloc(n * 3 * sizeof(double));
    sim->xp = malloc(n * 3 * sizeof(double));
    sim->coef = malloc(n * FTM_COEF * sizeof(double));
    sim->force = calloc(n * 3, sizeof(double));
    sim->ke_w = malloc(n * sizeof(double));
    sim->kind = calloc(n, 1);
    sim->relax_tmp = malloc(n * sizeof(int32_t));
    if (!sim->x || !sim->xp || !sim->coef || !sim->force || !sim->ke_w || !sim->kind ||
        !sim->relax_tmp ||
        ftm_layering_init(&sim->ly, sim->n) != FTM_OK) {
        ftm_sim_destroy(sim);
        return ftm_error_set(err, FTM_ENOMEM, "sim: out of memory for %zu nodes", n);
    }
    memcpy(sim->x, m->rest, n * 3 * sizeof(double));
    memcpy(sim->xp, m->rest, n * 3 * sizeof(double));
    for (size_t i = 0; i < n; i++)
        sim->kind[i] = m->fixed[i] ? NODE_FIXED : NODE_FREE;
    ftm_sim_select_kernel(sim, false);
    sim->pad_cheap = ftm_mesh_pad_cheap(m);
    sim->pad_rows = m->pad_node != NULL;
    for (size_t i = 0; i < n; i++) {
        double lim = d.guard_motion * m->min_link[i];
        sim->coef[FTM_COEF * i + FTM_LIM2] = isfinite(lim) ? lim * lim : INFINITY;
    }
    if (d.forces != FTM_FORCES_SPRINGS && (rc = ftm_elem_create(sim, err)) != FTM_OK) {
        ftm_sim_destroy(sim);
        return rc;
    }
    if (d.far_field == FTM_FAR_FIELD_ELASTIC && (rc = ftm_far_create(sim, err)) != FTM_OK) {
        ftm_sim_destroy(sim);
        return rc;
    }
    sim->substeps = 1;
    set_substep_length(sim, d.time_step);
    for (size_t i = 0; i < n; i++) { /* extreme masses against the step: refuse, not NaN later */
        const double *c = sim->coef + FTM_COEF * i;
        if (!m->fixed[i] && !(c[0] > 0.0 && isfinite(c[0]) && isfinite(c[1]) && isfinite(c[2]))) {
            ftm_error_set(err, FTM_EINVAL,
                          "sim: node %zu (mass %g kg, damping %g N s/m) gives non-finite update "
                          "coefficients with time step %g s",
                          i, ftm_sim_masses(sim)[i], m->damping[i], d.time_step);
            ftm_sim_destroy(sim);
            return FTM_EINVAL;
        }
    }
    sim->energy_guard = !sim->elem; /* the element sweeps do not sum spring energy */
    sim->energy_floor = energy_floor(m);
    sim->tol = d.sleep_tolerance * m->mean_link_length;
    sim->layers_dirty = true;
    sim->planar_state = true; /* at rest (ftm_sim_planar also asks the mesh) */
    sim->st.depth = d.depth;
    sim->st.substeps = 1;
    if (!sim->elem)
        warn_low_damping(sim); /* element forces warn in ftm_elem_create */
    double hc = ftm_sim_critical_time_step(sim);
    sim->energy_h_max = hc;
    if (d.time_step > hc) {
        ftm_logf(d.log, d.log_user, FTM_LOG_WARN,
                 "time step %g s exceeds the critical time step %g s of this mesh: the stability "
                 "guard will substep",
                 d.time_step, hc);
        sim->warned_dt = true;
    }
    *out = sim;
    ftm_error_clear(err);
    return FTM_OK;
}

const ftm_mesh *ftm_sim_mesh(const ftm_sim *sim) { return sim->m; }

int ftm_sim_set_mesh(ftm_sim *sim, const ftm_mesh *m, ftm_error *err)
{
    if (!sim || !m)
        return ftm_error_set(err, FTM_EINVAL, "sim set mesh: null argument");
    if (!ftm_mesh_same_shape(sim->m, m))
        return ftm_error_set(err, FTM_EINVAL,
                             "sim set mesh: the new mesh differs in shape (nodes, rest positions, "
                             "fixed nodes, links or surface)");
    if (sim->elem && sim->far && m->ground_k)
        return ftm_error_set(err, FTM_EINVAL,
                             "sim set mesh: a new material with element forces, the elastic far "
                             "field and springs to ground is not supported (the far field's "
                             "stiffness would no longer be a multiple of the one it was made "
                             "for)");
    if (sim->elem) { /* a factor on E from the links, the mesh's damping */
        int rc = ftm_elem_set_mesh(sim, m, err);
        if (rc)
            return rc;
        if (sim->far)
            ftm_far_set_scale(sim->far, ftm_elem_scale(sim->elem));
        sim->m = m;
        set_substep_length(sim, sim->h_sub);
        sim->layers_dirty = true;
        const double h = sim->def.time_step, hc = ftm_sim_critical_time_step(sim);
        if (h > hc)
            ftm_logf(sim->def.log, sim->def.log_user, FTM_LOG_WARN,
                     "time step %g s exceeds the critical time step %g s of the new material: "
                     "the stability guard will substep",
                     h, hc);
        ftm_error_clear(err);
        return FTM_OK;
    }
    const double h = sim->def.time_step, hc = ftm_mesh_critical_time_step(m);
    const int32_t most = sim->def.guard ? sim->def.max_substeps : 1;
    if (h > hc * most)
        return ftm_error_set(err, FTM_EINVAL,
                             "sim set mesh: the material's critical time step %g s is too short "
                             "for time step %g s with at most %d substeps",
                             hc, h, (int)most);
    if (sim->far) {
        int rc = ftm_far_set_mesh(sim, m, err);
        if (rc)
            return rc;
    }
    sim->m = m;
    set_substep_length(sim, sim->h_sub); /* masses and damping are in the coefficients */
    sim->energy_floor = energy_floor(m);
    sim->energy_h_max = hc;
    sim->budget = -1.0; /* the stored spring energy changed: the account restarts */
    sim->layers_dirty = true; /* the schedule holds copies of link stiffness */
    warn_low_damping(sim);
    if (h > hc)
        ftm_logf(sim->def.log, sim->def.log_user, FTM_LOG_WARN,
                 "time step %g s exceeds the critical time step %g s of the new material: the "
                 "stability guard will substep",
                 h, hc);
    ftm_error_clear(err);
    return FTM_OK;
}

/* ---- contacts ---- */

int ftm_sim_relax_reserve(ftm_sim *sim, int32_t need)
{
    if (need <= sim->relax_cap)
        return FTM_OK;
    int32_t cap = sim->relax_cap ? sim->relax_cap : 256;
    while (cap < need)
        cap *= 2;
    int32_t *r = realloc(sim->relax, (size_t)cap * sizeof *r);
    if (!r)
        return FTM_ENOMEM;
    sim->relax = r;
    double *sv = realloc(sim->relax_save, (size_t)cap * 6 * sizeof *sv);
    if (!sv)
        return FTM_ENOMEM;
    sim->relax_save = sv;
    sim->relax_cap = cap;
    return FTM_OK;
}

static int cmp_contact(const void *a, const void *b)
{
    int32_t x = ((const ftm_contact *)a)->node, y = ((const ftm_contact *)b)->node;
    return (x > y) - (x < y);
}

static bool finite3(ftm_vec3 v) { return isfinite(v.x) && isfinite(v.y) && isfinite(v.z); }

/* Every load has z = 0 (a force's or a displacement's), as the planar
 * sweep needs (ftm_sim_planar). */
static bool contacts_in_plane(const ftm_sim *sim)
{
    for (int32_t c = 0; c < sim->ncontacts; c++)
        if (sim->contacts[c].value.z != 0.0)
            return false;
    return true;
}

int ftm_sim_set_contacts(ftm_sim *sim, const ftm_contact *c, int32_t count, ftm_error *err)
{
    if (!sim || count < 0 || (count > 0 && !c))
        return ftm_error_set(err, FTM_EINVAL, "contacts: null argument or negative count");
    if (count > sim->n)
        return ftm_error_set(err, FTM_ERANGE, "contacts: %d contacts for %d nodes", (int)count,
                             (int)sim->n);
    for (int32_t i = 0; i < count; i++) {
        if (c[i].node < 0 || c[i].node >= sim->n)
            return ftm_error_set(err, FTM_ERANGE, "contact %d: node %d out of range 0..%d",
                                 (int)i, (int)c[i].node, (int)sim->n - 1);
        if (sim->m->fixed[c[i].node])
            return ftm_error_set(err, FTM_EINVAL, "contact %d: node %d is fixed", (int)i,
                                 (int)c[i].node);
        if (c[i].kind != FTM_CONTACT_FORCE && c[i].kind != FTM_CONTACT_DISPLACEMENT)
            return ftm_error_set(err, FTM_EINVAL, "contact %d: unknown kind %d", (int)i,
                                 (int)c[i].kind);
        if (!finite3(c[i].value))
            return ftm_error_set(err, FTM_EINVAL, "contact %d: value is not finite", (int)i);
        if (c[i].group < 0 || c[i].group > FTM_MAX_CONTACT_GROUP)
            return ftm_error_set(err, FTM_EINVAL, "contact %d: group %d out of range 0..%d",
                                 (int)i, (int)c[i].group, FTM_MAX_CONTACT_GROUP);
    }
    /* sorted copy, then duplicates */
    ftm_contact *nc = malloc(((size_t)count + 1) * sizeof *nc);
    int32_t *nsrc = malloc(((size_t)count + 1) * sizeof *nsrc);
    int32_t *ndisp = malloc(((size_t)count + 1) * sizeof *ndisp);
    if (!nc || !nsrc || !ndisp) {
        free(nc);
        free(nsrc);
        free(ndisp);
        return ftm_error_set(err, FTM_ENOMEM, "contacts: out of memory");
    }
    if (count)
        memcpy(nc, c, (size_t)count * sizeof *nc);
    qsort(nc, (size_t)count, sizeof *nc, cmp_contact);
    for (int32_t i = 1; i < count; i++)
        if (nc[i].node == nc[i - 1].node) {
            int twice = (int)nc[i].node;
            free(nc);
            free(nsrc);
            free(ndisp);
            return ftm_error_set(err, FTM_EINVAL, "contacts: node %d listed twice", twice);
        }
    int32_t groups = 0, nd = 0;
    for (int32_t i = 0; i < count; i++) {
        nsrc[i] = nc[i].node;
        if (nc[i].group + 1 > groups)
            groups = nc[i].group + 1;
        if (nc[i].kind == FTM_CONTACT_DISPLACEMENT)
            ndisp[nd++] = nc[i].node;
    }
    if (groups > sim->reaction_groups) {
        double *r = realloc(sim->reaction, (size_t)groups * 3 * sizeof *r);
        if (!r) {
            free(nc);
            free(nsrc);
            free(ndisp);
            return ftm_error_set(err, FTM_ENOMEM, "contacts: out of memory");
        }
        memset(r + 3 * sim->reaction_groups, 0,
               (size_t)(groups - sim->reaction_groups) * 3 * sizeof *r);
        sim->reaction = r;
        sim->reaction_groups = groups;
    }

    bool same_nodes = count == sim->ncontacts, same_kinds = same_nodes;
    bool same_values = same_nodes;
    for (int32_t i = 0; same_nodes && i < count; i++) {
        if (nc[i].node != sim->contacts[i].node) {
            same_nodes = same_kinds = same_values = false;
        } else if (nc[i].kind != sim->contacts[i].kind) {
            same_kinds = same_values = false;
        } else if (memcmp(&nc[i].value, &sim->contacts[i].value, sizeof nc[i].value) != 0 ||
                   nc[i].group != sim->contacts[i].group) {
            same_values = false;
        }
    }
    for (int32_t i = 0; i < sim->ncontacts; i++) {
        int32_t v = sim->contacts[i].node;
        sim->kind[v] = NODE_FREE;
        sim->force[3 * v] = sim->force[3 * v + 1] = sim->force[3 * v + 2] = 0.0;
    }
    for (int32_t i = 0; i < count; i++) {
        int32_t v = nc[i].node;
        sim->kind[v] = nc[i].kind == FTM_CONTACT_FORCE ? NODE_FORCE : NODE_DISP;
        if (nc[i].kind == FTM_CONTACT_FORCE) {
            sim->force[3 * v] = nc[i].value.x;
            sim->force[3 * v + 1] = nc[i].value.y;
            sim->force[3 * v + 2] = nc[i].value.z;
        }
    }
    free(sim->contacts);
    free(sim->sources);
    free(sim->disp);
    sim->contacts = nc;
    sim->sources = nsrc;
    sim->disp = ndisp;
    sim->ncontacts = count;
    sim->ndisp = nd;
    if (!contacts_in_plane(sim)) /* a load off the plane: z leaves +0.0 */
        sim->planar_state = false;
    if (!same_nodes)
        sim->layers_dirty = true;
    else if (!same_kinds)
        sim->schedule_dirty = true;
    if (!same_kinds)
        ftm_far_contacts_changed(sim->far);
    if (!same_values) {
        sim->region_sleeping = false;
        sim->quiet_steps = 0;
    }
    ftm_error_clear(err);
    return FTM_OK;
}

int ftm_sim_set_depth(ftm_sim *sim, int32_t depth)
{
    if (!sim || depth < 0 || depth > FTM_MAX_DEPTH)
        return FTM_EINVAL;
    if (depth != sim->def.depth) {
        sim->def.depth = depth;
        sim->st.depth = depth;
        sim->layers_dirty = true;
        sim->region_sleeping = false;
        sim->quiet_steps = 0;
    }
    return FTM_OK;
}

/* ---- schedule ---- */

/* ---- the hot loop ---- */

/* ---- step ---- */

static void impose_displacements(ftm_sim *sim)
{
    for (int32_t c = 0; c < sim->ncontacts; c++) {
        const ftm_contact *ct = &sim->contacts[c];
        if (ct->kind != FTM_CONTACT_DISPLACEMENT)
            continue;
        int32_t i = ct->node;
        const double *X = sim->m->rest + 3 * i;
        double *xi = sim->x + 3 * i, *pi = sim->xp + 3 * i;
        double v[3] = {ct->value.x, ct->value.y, ct->value.z};
        for (int d = 0; d < 3; d++) {
            pi[d] = xi[d];
            xi[d] = X[d] + v[d];
        }
    }
}

/* Saves x and xp of the displacement, relaxing and far-field ring nodes
 * (and, when substepping, of the scheduled nodes too) so a step can be
 * undone. */
static int save_state(ftm_sim *sim, double **full)
{
    const int32_t nring = ftm_far_ring_count(sim->far);
    int32_t aux = sim->ndisp + sim->nrelax + nring;
    int rc = ftm_sim_relax_reserve(sim, aux + 1);
    if (rc)
        return rc;
    double *sv = sim->relax_save;
    for (int32_t r = 0; r < sim->ndisp; r++, sv += 6) {
        memcpy(sv, sim->x + 3 * sim->disp[r], 3 * sizeof(double));
        memcpy(sv + 3, sim->xp + 3 * sim->disp[r], 3 * sizeof(double));
    }
    for (int32_t r = 0; r < sim->nrelax; r++, sv += 6) {
        memcpy(sv, sim->x + 3 * sim->relax[r], 3 * sizeof(double));
        memcpy(sv + 3, sim->xp + 3 * sim->relax[r], 3 * sizeof(double));
    }
    const int32_t *ring = nring ? ftm_far_ring_nodes(sim->far) : NULL;
    for (int32_t r = 0; r < nring; r++, sv += 6) {
        memcpy(sv, sim->x + 3 * ring[r], 3 * sizeof(double));
        memcpy(sv + 3, sim->xp + 3 * ring[r], 3 * sizeof(double));
    }
    *full = NULL;
    if (sim->substeps > 1 && sim->s.count > 0) {
        double *f = malloc((size_t)sim->s.count * 6 * sizeof *f);
        if (!f)
            return FTM_ENOMEM;
        for (int32_t k = 0; k < sim->s.count; k++) {
            memcpy(f + 6 * k, sim->x + 3 * sim->s.node[k], 3 * sizeof(double));
            memcpy(f + 6 * k + 3, sim->xp + 3 * sim->s.node[k], 3 * sizeof(double));
        }
        *full = f;
    }
    return FTM_OK;
}

static void restore_state(ftm_sim *sim, double *full, bool region_ran)
{
    const double *sv = sim->relax_save;
    for (int32_t r = 0; r < sim->ndisp; r++, sv += 6) {
        memcpy(sim->x + 3 * sim->disp[r], sv, 3 * sizeof(double));
        memcpy(sim->xp + 3 * sim->disp[r], sv + 3, 3 * sizeof(double));
    }
    for (int32_t r = 0; r < sim->nrelax; r++, sv += 6) {
        memcpy(sim->x + 3 * sim->relax[r], sv, 3 * sizeof(double));
        memcpy(sim->xp + 3 * sim->relax[r], sv + 3, 3 * sizeof(double));
    }
    const int32_t nring = ftm_far_ring_count(sim->far);
    const int32_t *ring = nring ? ftm_far_ring_nodes(sim->far) : NULL;
    for (int32_t r = 0; r < nring; r++, sv += 6) {
        memcpy(sim->x + 3 * ring[r], sv, 3 * sizeof(double));
        memcpy(sim->xp + 3 * ring[r], sv + 3, 3 * sizeof(double));
    }
    if (!region_ran)
        return;
    if (full) {
        for (int32_t k = 0; k < sim->s.count; k++) {
            memcpy(sim->x + 3 * sim->s.node[k], full + 6 * k, 3 * sizeof(double));
            memcpy(sim->xp + 3 * sim->s.node[k], full + 6 * k + 3, 3 * sizeof(double));
        }
    } else { /* one substep: x_prev holds the old x, save the old x_prev */
        const schedule *s = &sim->s;
        for (int32_t k = 0; k < s->count; k++) {
            int32_t i = s->node[k];
            memcpy(sim->x + 3 * i, sim->xp + 3 * i, 3 * sizeof(double));
        }
        if (sim->def.order != FTM_ORDER_BFS) { /* groups: Jacobi, colored */
            const int32_t w = sim->group_lanes;
            for (int32_t g = 0, b0 = 0; g < s->groups; g++) {
                const int32_t k0 = s->group[g], k1 = s->group[g + 1];
                for (int32_t k = k0; k < k1; k++) {
                    const double *js = ftm_group_save(sim, b0, k0, k);
                    for (int d = 0; d < 3; d++)
                        sim->xp[3 * s->node[k] + d] = js[d * w];
                }
                b0 += ftm_group_blocks(sim, k0, k1);
            }
        } else {
            for (int32_t k = 0; k < s->count; k++)
                memcpy(sim->xp + 3 * s->node[k], s->save + 3 * k, 3 * sizeof(double));
        }
    }
}

/* Changes the number of substeps, keeping velocities: x_prev is moved so that
 * (x - x_prev) / h stays the same for the new substep length. */
static void change_substeps(ftm_sim *sim, int32_t substeps)
{
    double h_new = sim->def.time_step / substeps, ratio = h_new / sim->h_sub;
    for (int32_t i = 0; i < sim->n; i++) {
        double *xi = sim->x + 3 * i, *pi = sim->xp + 3 * i;
        if (xi[0] == pi[0] && xi[1] == pi[1] && xi[2] == pi[2])
            continue;
        for (int d = 0; d < 3; d++)
            pi[d] = xi[d] - (xi[d] - pi[d]) * ratio;
    }
    sim->substeps = substeps;
    sim->steps_at_substeps = 0;
    set_substep_length(sim, h_new);
    sim->st.substeps = substeps;
}

/* ---- energy guard ----
 * The motion check above sees a step that throws a node further than half
 * its shortest link. A slow blow-up (energy growing in smooth modes over
 * hundreds of steps, each step's motion small; docs/stability.md) passes it.
 * This check sees it: the energy E of the updated nodes (kinetic plus
 * elastic, summed by the sweeps at no extra memory traffic) may not exceed
 * what the loads supplied. With W the work the contacts did in the step,
 *     fail if  E > SLACK (B + W) + floor,   then  B <- min(B + W, MEMORY E).
 * Damping only removes energy, so a stable scene stays within B + W; SLACK
 * absorbs the estimate's discretisation error (half-step velocities, a
 * link's two ends seen at different times); MEMORY caps the credit for
 * energy damped away long ago, so the check stays sharp in long runs. A
 * growing mode fails it once its energy reaches a few times the loads' work,
 * long before any motion limit. */
#define FTM_ENERGY_SLACK 4.0
#define FTM_ENERGY_MEMORY 4.0

/* Round-off scale of the energy: a link of mean stiffness stretched by
 * 1e-5 of the mean link length (so a scene at rest never trips the check). */
static double energy_floor(const ftm_mesh *m)
{
    double k = 0.0;
    for (int32_t l = 0; l < m->link_count; l++)
        k += m->link_k[l];
    k = m->link_count ? k / m->link_count : 0.0;
    double len = m->mean_link_length;
    return isfinite(k * len * len) ? 1e-10 * k * len * len : 0.0;
}

static int work_reserve(ftm_sim *sim)
{
    const int32_t need = sim->ncontacts + ftm_far_ring_count(sim->far);
    if (need <= sim->work_cap)
        return FTM_OK;
    double *w = realloc(sim->work_mark, ((size_t)need * 3 + 1) * sizeof *w);
    if (!w)
        return FTM_ENOMEM;
    sim->work_mark = w;
    sim->work_cap = need;
    return FTM_OK;
}

/* Before the step: each force contact's position, each displacement
 * contact's (and far-field ring node's) spring force. */
static void work_begin(ftm_sim *sim)
{
    for (int32_t c = 0; c < sim->ncontacts; c++) {
        int32_t i = sim->contacts[c].node;
        if (sim->contacts[c].kind == FTM_CONTACT_FORCE)
            memcpy(sim->work_mark + 3 * c, sim->x + 3 * i, 3 * sizeof(double));
        else
            ftm_sim_spring_force(sim, i, sim->work_mark + 3 * c);
    }
    /* (a ring node this step does not move does no work) */
    const int32_t nring = ftm_far_ring_count(sim->far);
    for (int32_t r = 0; r < nring; r++)
        if (ftm_far_ring_moves(sim->far, r))
            ftm_sim_spring_force(sim, ftm_far_ring_nodes(sim->far)[r],
                                 sim->work_mark + 3 * (sim->ncontacts + r));
}

/* The work of a held node (displacement contact, ring node) moved from x0
 * to x against its springs' force, which was mark before the step: about
 * f.dx, taken at the end that gives more (the upper bound for stiffening
 * links), so pushing in never looks like free energy. */
static double held_work(const ftm_sim *sim, int32_t i, const double *mark, const double *x0)
{
    const double *x = sim->x + 3 * i;
    double f[3], dx[3] = {x[0] - x0[0], x[1] - x0[1], x[2] - x0[2]};
    ftm_sim_spring_force(sim, i, f);
    double w0 = mark[0] * dx[0] + mark[1] * dx[1] + mark[2] * dx[2];
    double w1 = f[0] * dx[0] + f[1] * dx[1] + f[2] * dx[2];
    return w0 > w1 ? w0 : w1;
}

/* After the step: the work the contacts did. A force contact F moved by dx
 * did F.dx; a displacement contact and a far-field ring node moved by dx
 * did held_work. Relies on save_state having saved the displacement nodes'
 * x first and the ring's after the relaxing nodes'. */
static double work_end(const ftm_sim *sim)
{
    double w = 0.0;
    int32_t r = 0;
    for (int32_t c = 0; c < sim->ncontacts; c++) {
        const ftm_contact *ct = &sim->contacts[c];
        const double *x = sim->x + 3 * ct->node, *mark = sim->work_mark + 3 * c;
        if (ct->kind == FTM_CONTACT_FORCE)
            w += ct->value.x * (x[0] - mark[0]) + ct->value.y * (x[1] - mark[1]) +
                 ct->value.z * (x[2] - mark[2]);
        else
            w += held_work(sim, ct->node, mark, sim->relax_save + 6 * r++);
    }
    const int32_t nring = ftm_far_ring_count(sim->far);
    const double *ring_save = sim->relax_save + 6 * ((size_t)sim->ndisp + (size_t)sim->nrelax);
    for (int32_t k = 0; k < nring; k++)
        if (ftm_far_ring_moves(sim->far, k))
            w += held_work(sim, ftm_far_ring_nodes(sim->far)[k],
                           sim->work_mark + 3 * (sim->ncontacts + k), ring_save + 6 * k);
    return w;
}

/* One attempt at a full step with the current substeps. *inverted: it
 * failed for an inverted element (neo-Hookean forces). */
static bool attempt_step(ftm_sim *sim, bool region_active, double *region_m2, bool *inverted)
{
    *inverted = false;
    bool ok = true;
    schedule *s = &sim->s;
    *region_m2 = 0.0;
    for (int32_t sub = 0; sub < sim->substeps; sub++) {
        sim->energy = 0.0; /* the last substep's counts */
        if (region_active) {
            impose_displacements(sim);
            if (sim->far)
                ftm_far_impose(sim);
            if (sim->elem) {
                ok &= ftm_elem_sweep(sim, region_m2);
            } else if (sim->def.order != FTM_ORDER_BFS) { /* groups: Jacobi, colored */
                sim->st.planar_sweeps += ftm_sim_planar(sim);
                ok &= sim->sweep_groups(sim, region_m2);
                s->uses++;
            } else {
                ok &= ftm_sweep_gs(sim, 0, s->count, region_m2);
            }
            /* the held nodes' share of their links, which no sweep sums: on
             * release it becomes a free node's, and with no free neighbour
             * (depth 0, every neighbour fixed) nothing else accounts for it */
            if (sim->energy_guard) {
                for (int32_t d = 0; d < sim->ndisp; d++)
                    sim->energy += 0.25 * ftm_sim_link_pe(sim, sim->disp[d]);
                const int32_t nring = ftm_far_ring_count(sim->far);
                for (int32_t r = 0; r < nring; r++)
                    sim->energy += 0.25 * ftm_sim_link_pe(sim, ftm_far_ring_nodes(sim->far)[r]);
            }
        }
        ok &= sim->elem ? ftm_elem_sweep_relax(sim) : ftm_sweep_relax(sim);
        if (!sim->def.guard)
            ok = true;
        /* an inverted element has no stress: the step fails, guard or not */
        if (sim->elem && !ftm_elem_intact(sim, sub + 1 == sim->substeps, region_active)) {
            *inverted = true;
            ok = false;
        }
        if (!ok)
            return false;
    }
    return true;
}

/* Relaxing nodes back at rest are set exactly to rest and dropped. */
static void sleep_relaxed(ftm_sim *sim)
{
    int32_t w = 0;
    const double tol = sim->tol;
    for (int32_t r = 0; r < sim->nrelax; r++) {
        int32_t i = sim->relax[r];
        double *xi = sim->x + 3 * i, *pi = sim->xp + 3 * i;
        const double *X = sim->m->rest + 3 * i;
        bool rest = true;
        for (int d = 0; d < 3; d++)
            rest = rest && fabs(xi[d] - X[d]) <= tol && fabs(xi[d] - pi[d]) <= tol;
        if (rest) {
            memcpy(xi, X, 3 * sizeof(double));
            memcpy(pi, X, 3 * sizeof(double));
            ftm_elem_node_moved(sim, i);
        } else {
            sim->relax[w++] = i;
        }
    }
    sim->nrelax = w;
}

/* What a step that fails (even at max_substeps, or for memory) gives back
 * bit for bit: raising the substeps rescales every moving node's x_prev and
 * changes the substep length; the guard also moves the energy account. xp is
 * copied at the first raise. */
typedef struct step_origin {
    int32_t substeps, steps_at_substeps;
    double h_sub, budget;
    double *xp;
} step_origin;

/* The state as when o was taken (x is already restored); frees o's copy. */
static void give_back(ftm_sim *sim, step_origin *o)
{
    if (o->xp) {
        memcpy(sim->xp, o->xp, (size_t)sim->n * 3 * sizeof *o->xp);
        free(o->xp);
        o->xp = NULL;
        sim->substeps = o->substeps;
        sim->st.substeps = o->substeps;
        set_substep_length(sim, o->h_sub);
    }
    sim->steps_at_substeps = o->steps_at_substeps;
    sim->budget = o->budget;
}

int ftm_sim_step(ftm_sim *sim)
{
    const bool region_changed =
        sim->layers_dirty || sim->schedule_dirty || sim->built_depth != sim->def.depth;
    int rc0 = ftm_sim_refresh_region(sim);
    if (rc0)
        return rc0;
    bool region_active = (sim->s.count > 0 || sim->ndisp > 0) && !sim->region_sleeping;
    if (!region_active && sim->nrelax == 0) {
        sim->st.step++;
        sim->st.updated_nodes = 0;
        return FTM_OK;
    }
    if (region_active && sim->far) {
        int rc = ftm_far_prepare(sim);
        if (rc)
            return rc;
    }
    /* energy guard: off with the motion guard, while the region sleeps (its
     * energy is not summed then), and above the critical step, where modes
     * with w h > 2 are stable only by damping and the discrete energy does not
     * balance against the work (the motion check watches those steps); a
     * changed region is credited with what the last one held, since links it
     * now sees whole were half-seen */
    const bool eon = sim->def.guard && sim->energy_guard && sim->h_sub <= sim->energy_h_max;
    const bool echeck = eon && !sim->region_sleeping;
    if (!eon)
        sim->budget = -1.0; /* not kept: the account restarts when the check resumes */
    if (region_changed && sim->budget >= 0.0)
        sim->budget = fmax(sim->budget, FTM_ENERGY_MEMORY * sim->energy_prev);
    if (echeck && work_reserve(sim))
        return FTM_ENOMEM;
    double region_m2 = 0.0;
    step_origin origin = {sim->substeps, sim->steps_at_substeps, sim->h_sub, sim->budget, NULL};
    for (;;) {
        double *full = NULL;
        int rc = save_state(sim, &full);
        if (rc) {
            give_back(sim, &origin);
            return rc;
        }
        if (echeck)
            work_begin(sim);
        bool inverted;
        bool ok = attempt_step(sim, region_active, &region_m2, &inverted), energy_fail = false;
        double work = 0.0;
        if (ok && echeck && sim->budget >= 0.0) {
            work = work_end(sim);
            /* a probe drawing back does negative work; no energy at all
             * never fails (NaN does) */
            energy_fail = !(sim->energy <= FTM_ENERGY_SLACK * fmax(0.0, sim->budget + work) +
                                               sim->energy_floor);
            ok = !energy_fail;
        }
        if (ok) {
            if (echeck) {
                double allowed = sim->budget + work, cap = FTM_ENERGY_MEMORY * sim->energy;
                sim->budget = sim->budget < 0.0 ? cap : fmax(0.0, fmin(allowed, cap));
                sim->energy_prev = sim->energy;
            }
            free(full);
            free(origin.xp);
            break;
        }
        restore_state(sim, full, region_active);
        ftm_elem_forget(sim); /* the attempt's element values are not the restored state's */
        free(full);
        sim->st.guard_events++;
        if (energy_fail) {
            ftm_logf(sim->def.log, sim->def.log_user, FTM_LOG_WARN,
                     "step %llu: energy %g grew beyond what the loads supplied (%g): rolled back",
                     (unsigned long long)sim->st.step, sim->energy, sim->budget + work);
            /* the excess built up over many steps: start the account again from here */
            sim->budget = fmax(sim->budget, sim->energy_prev);
        }
        char what[160] = "";
        double det = 0.0;
        if (inverted)
            ftm_elem_inversion(sim, what, sizeof what, &det);
        if (sim->substeps * 2 > sim->def.max_substeps) {
            sim->st.unstable_steps++;
            if (inverted)
                ftm_logf(sim->def.log, sim->def.log_user, FTM_LOG_ERROR,
                         "step %llu: %s inverted (J = det F = %g at a quadrature "
                         "point) even with %d substeps; state kept as before the step",
                         (unsigned long long)sim->st.step, what, det, (int)sim->substeps);
            else
                ftm_logf(sim->def.log, sim->def.log_user, FTM_LOG_ERROR,
                         "step %llu diverged even with %d substeps; state kept as before the step",
                         (unsigned long long)sim->st.step, (int)sim->substeps);
            give_back(sim, &origin);
            return FTM_EUNSTABLE;
        }
        if (!origin.xp) {
            origin.xp = malloc((size_t)sim->n * 3 * sizeof *origin.xp);
            if (!origin.xp) {
                give_back(sim, &origin);
                return FTM_ENOMEM;
            }
            memcpy(origin.xp, sim->xp, (size_t)sim->n * 3 * sizeof *origin.xp);
        }
        change_substeps(sim, sim->substeps * 2);
        if (inverted)
            ftm_logf(sim->def.log, sim->def.log_user, FTM_LOG_WARN,
                     "step %llu: %s inverted (J = det F = %g at a quadrature point): "
                     "rolled back, now %d substeps per step",
                     (unsigned long long)sim->st.step, what, det, (int)sim->substeps);
        else
            ftm_logf(sim->def.log, sim->def.log_user, FTM_LOG_WARN,
                     "step %llu unstable (a node moved more than %g of its shortest link): "
                     "rolled back, now %d substeps per step",
                     (unsigned long long)sim->st.step, sim->def.guard_motion, (int)sim->substeps);
    }
    sim->st.updated_nodes = (region_active ? sim->s.count : 0) + sim->nrelax;
    sim->st.updated_nodes *= sim->substeps;
    sleep_relaxed(sim);
    if (sim->elem)
        ftm_elem_reactions(sim);
    else
        ftm_sim_compute_reactions(sim);
    if (sim->def.region_sleep_steps > 0 && region_active) {
        if (region_m2 <= sim->tol * sim->tol && sim->nrelax == 0) {
            if (++sim->quiet_steps >= sim->def.region_sleep_steps) {
                sim->region_sleeping = true; /* zero velocity: x_prev = x */
                for (int32_t k = 0; k < sim->s.count; k++) {
                    int32_t i = sim->s.node[k];
                    memcpy(sim->xp + 3 * i, sim->x + 3 * i, 3 * sizeof(double));
                }
                for (int32_t r = 0; r < sim->ndisp; r++)
                    memcpy(sim->xp + 3 * sim->disp[r], sim->x + 3 * sim->disp[r],
                           3 * sizeof(double));
            }
        } else {
            sim->quiet_steps = 0;
        }
    }
    /* fewer substeps again, but not back above the critical step once the
     * guard had to act: there only the motion check watches, and slow growth
     * passes it */
    if (sim->substeps > 1 && ++sim->steps_at_substeps >= FTM_SUBSTEP_RETRY &&
        (!sim->energy_guard || sim->def.time_step / (sim->substeps / 2) <= sim->energy_h_max))
        change_substeps(sim, sim->substeps / 2); /* the guard raises it again if needed */
    sim->st.step++;
    return FTM_OK;
}

int ftm_sim_run(ftm_sim *sim, int32_t count)
{
    for (int32_t i = 0; i < count; i++) {
        int rc = ftm_sim_step(sim);
        if (rc)
            return rc;
    }
    return FTM_OK;
}

/* ---- queries ---- */

const double *ftm_sim_positions(const ftm_sim *sim) { return sim->x; }

ftm_vec3 ftm_sim_position(const ftm_sim *sim, int32_t i)
{
    return (ftm_vec3){sim->x[3 * i], sim->x[3 * i + 1], sim->x[3 * i + 2]};
}

ftm_vec3 ftm_sim_reaction(const ftm_sim *sim, int32_t group)
{
    if (group < 0 || group >= sim->reaction_groups)
        return (ftm_vec3){0, 0, 0};
    const double *r = sim->reaction + 3 * group;
    return (ftm_vec3){r[0], r[1], r[2]};
}

static uint64_t mix64(uint64_t x)
{
    x ^= x >> 30;
    x *= 0xbf58476d1ce4e5b9ULL;
    x ^= x >> 27;
    x *= 0x94d049bb133111ebULL;
    x ^= x >> 31;
    return x;
}

static uint64_t node_hash(const ftm_sim *sim, int32_t i)
{
    uint64_t h = mix64((uint64_t)i + 0x9e3779b97f4a7c15ULL);
    for (int d = 0; d < 3; d++) {
        uint64_t b;
        memcpy(&b, sim->x + 3 * i + d, sizeof b);
        h = mix64(h ^ b);
        memcpy(&b, sim->xp + 3 * i + d, sizeof b);
        h = mix64(h ^ b);
    }
    return h;
}

/* Every node not at rest is in the region, a displacement contact, the
 * far field's ring or the relaxing set; XOR makes the result independent of visiting order. */
uint64_t ftm_sim_hash(const ftm_sim *sim)
{
    uint64_t acc = 0;
    const ftm_layering *ly = &sim->ly;
    int32_t region = ly->gen ? ly->count : 0;
    for (int32_t k = 0; k < region; k++)
        if (!ftm_sim_at_rest(sim, ly->order[k]))
            acc ^= node_hash(sim, ly->order[k]);
    for (int32_t r = 0; r < sim->nrelax; r++)
        if (!ftm_sim_at_rest(sim, sim->relax[r]))
            acc ^= node_hash(sim, sim->relax[r]);
    const int32_t nring = ftm_far_ring_count(sim->far);
    for (int32_t r = 0; r < nring; r++) {
        const int32_t i = ftm_far_ring_nodes(sim->far)[r];
        if (!ftm_sim_at_rest(sim, i))
            acc ^= node_hash(sim, i);
    }
    return mix64(acc ^ mix64(sim->st.step ^ 0x5851f42d4c957f2dULL));
}

void ftm_sim_get_stats(const ftm_sim *sim, ftm_sim_stats *st)
{
    *st = sim->st;
    st->layers = sim->ly.gen ? sim->ly.layers : 0;
    st->region_nodes = sim->ly.gen ? sim->ly.count : 0;
    st->relaxing_nodes = sim->nrelax;
    st->region_sleeping = sim->region_sleeping;
    st->far_nodes = ftm_far_ring_count(sim->far);
}

int32_t ftm_sim_layers(ftm_sim *sim, const int32_t **order, const int32_t **start)
{
    int rc = FTM_OK;
    if (sim->layers_dirty || sim->built_depth != sim->def.depth)
        rc = ftm_sim_rebuild_region(sim);
    else if (sim->schedule_dirty)
        rc = ftm_sim_rebuild_schedule(sim);
    if (rc)
        return rc;
    if (order)
        *order = sim->ly.order;
    if (start)
        *start = sim->ly.start;
    return sim->ly.layers;
}

double ftm_sim_kinetic_energy(const ftm_sim *sim)
{
    double e = 0.0, h = sim->h_sub;
    for (int32_t i = 0; i < sim->n; i++) {
        const double *xi = sim->x + 3 * i, *pi = sim->xp + 3 * i;
        double v2 = 0.0;
        for (int d = 0; d < 3; d++)
            v2 += (xi[d] - pi[d]) * (xi[d] - pi[d]);
        e += 0.5 * sim->m->mass[i] * v2 / (h * h);
    }
    return e;
}

double ftm_sim_potential_energy(const ftm_sim *sim)
{
    const ftm_mesh *m = sim->m;
    double e = 0.0;
    for (int32_t l = 0; l < m->link_count; l++) {
        const double *a = sim->x + 3 * m->link_a[l], *b = sim->x + 3 * m->link_b[l];
        double rx = a[0] - b[0], ry = a[1] - b[1], rz = a[2] - b[2];
        double ext = sqrt(rx * rx + ry * ry + rz * rz) - m->link_len[l];
        e += 0.5 * m->link_k[l] * ext * ext;
    }
    for (int32_t i = 0; m->ground_k && i < m->node_count; i++) { /* springs to ground */
        const double *x = sim->x + 3 * i, *X = m->rest + 3 * i;
        const double ux = x[0] - X[0], uy = x[1] - X[1], uz = x[2] - X[2];
        e += 0.5 * m->ground_k[i] * (ux * ux + uy * uy + uz * uz);
    }
    return e;
}

uint32_t ftm_arithmetic_revision(void)
{
    return FTM_ARITHMETIC_REVISION;
}

void ftm_sim_reset(ftm_sim *sim)
{
    ftm_elem_forget(sim);
    memcpy(sim->x, sim->m->rest, (size_t)sim->n * 3 * sizeof(double));
    memcpy(sim->xp, sim->m->rest, (size_t)sim->n * 3 * sizeof(double));
    ftm_sim_set_contacts(sim, NULL, 0, NULL);
    sim->nrelax = 0;
    sim->layers_dirty = true;
    sim->region_sleeping = false;
    sim->quiet_steps = 0;
    if (sim->substeps != 1)
        change_substeps(sim, 1);
    sim->budget = sim->energy_prev = 0.0; /* all at rest: no energy */
    sim->planar_state = true;
    uint64_t searches = sim->st.searches;
    memset(&sim->st, 0, sizeof sim->st);
    sim->st.searches = searches;
    sim->st.depth = sim->def.depth;
    sim->st.substeps = 1;
}

/* ---- keyframes ---- */

void ftm_sim_get_mode(const ftm_sim *sim, ftm_sim_mode *mode)
{
    mode->substeps = sim->substeps;
    mode->steps_at_substeps = sim->steps_at_substeps;
    mode->quiet_steps = sim->quiet_steps;
    mode->region_sleeping = sim->region_sleeping;
    mode->energy_budget = sim->budget;
    mode->energy_prev = sim->energy_prev;
}

const double *ftm_sim_previous_positions(const ftm_sim *sim) { return sim->xp; }

int32_t ftm_sim_contacts(const ftm_sim *sim, const ftm_contact **contacts)
{
    *contacts = sim->contacts;
    return sim->ncontacts;
}

int ftm_sim_load_state(ftm_sim *sim, uint64_t step, int32_t depth, const int32_t *nodes,
                       const double *x, const double *xp, int32_t count,
                       const ftm_contact *contacts, int32_t ncontacts, const ftm_sim_mode *mode,
                       ftm_error *err)
{
    if (!sim || count < 0 || (count > 0 && (!nodes || !x || !xp)))
        return ftm_error_set(err, FTM_EINVAL, "load state: null argument or negative count");
    if (depth < 0 || depth > FTM_MAX_DEPTH)
        return ftm_error_set(err, FTM_EINVAL, "load state: depth %d out of range 0..%d",
                             (int)depth, FTM_MAX_DEPTH);
    ftm_sim_mode md = {1, 0, 0, false, -1.0, 0.0};
    if (mode)
        md = *mode;
    if (md.substeps < 1 || md.substeps > sim->def.max_substeps || md.steps_at_substeps < 0 ||
        md.quiet_steps < 0 || !isfinite(md.energy_budget) || !(md.energy_prev >= 0.0) ||
        !isfinite(md.energy_prev))
        return ftm_error_set(err, FTM_EINVAL,
                             "load state: mode out of range (substeps %d of at most %d, "
                             "energy account %g and %g)",
                             (int)md.substeps, (int)sim->def.max_substeps, md.energy_budget,
                             md.energy_prev);
    for (int32_t k = 0; k < count; k++) {
        int32_t i = nodes[k];
        if (i < 0 || i >= sim->n)
            return ftm_error_set(err, FTM_ERANGE, "load state: node %d out of range 0..%d",
                                 (int)i, (int)sim->n - 1);
        if (k > 0 && i <= nodes[k - 1])
            return ftm_error_set(err, FTM_EINVAL, "load state: nodes not strictly ascending at %d",
                                 (int)k);
        if (sim->m->fixed[i])
            return ftm_error_set(err, FTM_EINVAL, "load state: node %d is fixed", (int)i);
        for (int d = 0; d < 3; d++)
            if (!isfinite(x[3 * k + d]) || !isfinite(xp[3 * k + d]))
                return ftm_error_set(err, FTM_EINVAL, "load state: node %d: value not finite",
                                     (int)i);
    }
    int rc = ftm_sim_relax_reserve(sim, count + 1);
    if (rc)
        return ftm_error_set(err, rc, "load state: out of memory");
    /* validates the contacts; the first change to the state */
    rc = ftm_sim_set_contacts(sim, contacts, ncontacts, err);
    if (rc)
        return rc;
    size_t n = (size_t)sim->n;
    ftm_elem_forget(sim);
    memcpy(sim->x, sim->m->rest, n * 3 * sizeof(double));
    memcpy(sim->xp, sim->m->rest, n * 3 * sizeof(double));
    for (int32_t k = 0; k < count; k++) {
        memcpy(sim->x + 3 * nodes[k], x + 3 * k, 3 * sizeof(double));
        memcpy(sim->xp + 3 * nodes[k], xp + 3 * k, 3 * sizeof(double));
    }
    sim->def.depth = depth;
    sim->st.depth = depth;
    /* the substep length without rescaling x_prev: it is already in that frame */
    if (md.substeps != sim->substeps) {
        sim->substeps = md.substeps;
        set_substep_length(sim, sim->def.time_step / md.substeps);
    }
    sim->st.substeps = md.substeps;
    /* Region from the contacts, then the relaxing set: every node not at
     * rest outside the region, ascending (the invariant after any step). */
    sim->nrelax = 0;
    sim->layers_dirty = true;
    rc = ftm_sim_rebuild_region(sim);
    if (rc)
        return ftm_error_set(err, rc, "load state: %s", ftm_strerror(rc));
    int32_t nr = 0;
    for (int32_t k = 0; k < count; k++) {
        int32_t i = nodes[k];
        if (!ftm_layering_contains(&sim->ly, i) && !ftm_far_in_ring(sim->far, i) &&
            !ftm_sim_at_rest(sim, i))
            sim->relax[nr++] = i;
    }
    sim->nrelax = nr;
    sim->steps_at_substeps = md.steps_at_substeps;
    sim->quiet_steps = md.quiet_steps;
    sim->region_sleeping = md.region_sleeping;
    if (sim->reaction_groups > 0)
        memset(sim->reaction, 0, (size_t)sim->reaction_groups * 3 * sizeof *sim->reaction);
    sim->st.step = step;
    sim->st.updated_nodes = 0;
    /* planar again if every loaded z is +0.0 (the contacts as now set:
     * the caller's array may have been this simulation's own, freed since) */
    bool planar = contacts_in_plane(sim);
    for (size_t e = 2; e < 3 * (size_t)count && planar; e += 3)
        planar = ftm_is_plus_zero(x[e]) && ftm_is_plus_zero(xp[e]);
    sim->planar_state = planar;
    sim->budget = md.energy_budget < 0.0 ? -1.0 : md.energy_budget;
    sim->energy_prev = md.energy_prev;
    ftm_error_clear(err);
    return FTM_OK;
}
