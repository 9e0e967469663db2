/* SPDX-License-Identifier: GPL-3.0-or-later */
/* The paper's mechanical experiments and the stability sweep (experiments.h). */
#include "experiments.h"

#include "ftm/ftm.h"

#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

/* ---- helpers ------------------------------------------------------------- */

static ftm_mesh *make_lattice2d(int nx, int ny, double spacing, double mass, double damping,
                                double stiffness, uint32_t fixed)
{
    ftm_error err;
    ftm_mesh *mesh = NULL;
    ftm_mesh_builder *mb = ftm_mesh_builder_create();
    if (!mb)
        return NULL;
    ftm_lattice2d_def ld = ftm_default_lattice2d_def();
    ld.nx = nx;
    ld.ny = ny;
    ld.spacing = spacing;
    ld.material.node_mass = mass;
    ld.material.node_damping = damping;
    ld.material.stiffness = stiffness;
    ld.fixed_faces = fixed;
    if (ftm_generate_lattice2d(mb, &ld, &err) == FTM_OK)
        (void)ftm_mesh_build(mb, NULL, &mesh, &err);
    ftm_mesh_builder_destroy(mb);
    return mesh;
}

static ftm_mesh *make_lattice3d(int n, double spacing, double mass, double damping,
                                double stiffness, ftm_vec3 axis_scale, uint32_t fixed)
{
    ftm_error err;
    ftm_mesh *mesh = NULL;
    ftm_mesh_builder *mb = ftm_mesh_builder_create();
    if (!mb)
        return NULL;
    ftm_lattice3d_def ld = ftm_default_lattice3d_def();
    ld.nx = ld.ny = ld.nz = n;
    ld.spacing = (ftm_vec3){spacing, spacing, spacing};
    ld.stencil = FTM_STENCIL_18;
    ld.material.node_mass = mass;
    ld.material.node_damping = damping;
    ld.material.stiffness = stiffness;
    ld.material.axis_scale = axis_scale;
    ld.fixed_faces = fixed;
    if (ftm_generate_lattice3d(mb, &ld, &err) == FTM_OK)
        (void)ftm_mesh_build(mb, NULL, &mesh, &err);
    ftm_mesh_builder_destroy(mb);
    return mesh;
}

static ftm_sim *make_sim(const ftm_mesh *mesh, double h, int depth, bool guard)
{
    ftm_sim_def sd = ftm_default_sim_def();
    sd.time_step = h;
    sd.depth = depth;
    sd.guard = guard;
    ftm_sim *sim = NULL;
    if (ftm_sim_create(mesh, &sd, &sim, NULL) != FTM_OK)
        return NULL;
    return sim;
}

static int set_force(ftm_sim *sim, const int32_t *nodes, int count, ftm_vec3 each)
{
    ftm_contact c[FTM_EXP_MAX_NX];
    if (count > FTM_EXP_MAX_NX)
        return FTM_EINVAL;
    for (int i = 0; i < count; i++)
        c[i] = (ftm_contact){.node = nodes[i], .group = 0, .kind = FTM_CONTACT_FORCE, .value = each};
    return ftm_sim_set_contacts(sim, c, count, NULL);
}

double ftm_exp_max_displacement(const ftm_sim *sim, const ftm_mesh *mesh)
{
    const double *x = ftm_sim_positions(sim);
    double best = 0.0;
    int32_t n = ftm_mesh_node_count(mesh);
    for (int32_t i = 0; i < n; i++) {
        ftm_vec3 r = ftm_mesh_rest_position(mesh, i);
        double dx = x[3 * i] - r.x, dy = x[3 * i + 1] - r.y, dz = x[3 * i + 2] - r.z;
        double d = dx * dx + dy * dy + dz * dz;
        if (!(d <= best))
            best = d; /* NaN propagates */
    }
    return sqrt(best);
}

int ftm_exp_run_to_rest(ftm_sim *sim, const ftm_mesh *mesh, double tol, int every, int max_steps)
{
    int32_t n = ftm_mesh_node_count(mesh);
    double *snap = malloc((size_t)n * 3 * sizeof *snap);
    if (!snap)
        return FTM_ENOMEM;
    int steps = 0, rc = FTM_OK;
    while (steps < max_steps) {
        memcpy(snap, ftm_sim_positions(sim), (size_t)n * 3 * sizeof *snap);
        rc = ftm_sim_run(sim, every);
        steps += every;
        if (rc)
            break;
        const double *x = ftm_sim_positions(sim);
        double moved = 0.0;
        for (int32_t i = 0; i < 3 * n; i++)
            moved = fmax(moved, fabs(x[i] - snap[i]));
        double u = ftm_exp_max_displacement(sim, mesh);
        if (moved <= tol * u)
            break;
    }
    free(snap);
    return rc ? rc : steps;
}

double ftm_exp_shape_change(const ftm_mesh *mesh, const double *prev, const double *cur,
                            double *max_disp)
{
    int32_t nn = ftm_mesh_node_count(mesh);
    double u = 0.0, d = 0.0;
    for (int32_t i = 0; i < nn; i++) {
        ftm_vec3 X = ftm_mesh_rest_position(mesh, i);
        u = fmax(u, hypot(hypot(cur[3 * i] - X.x, cur[3 * i + 1] - X.y), cur[3 * i + 2] - X.z));
        if (prev)
            d = fmax(d, hypot(hypot(cur[3 * i] - prev[3 * i], cur[3 * i + 1] - prev[3 * i + 1]),
                              cur[3 * i + 2] - prev[3 * i + 2]));
    }
    if (max_disp)
        *max_disp = u;
    return u > 0 ? d / u : 0.0;
}

static int32_t node_of(const ftm_mesh *mesh, int input)
{
    return ftm_mesh_node_of_input(mesh, input);
}

/* ---- optimum penetration depth ------------------------------------------ */

ftm_exp_depth_def ftm_exp_default_depth_def(bool quick)
{
    ftm_exp_depth_def d = {
        .nx = quick ? 17 : 41,
        .ny = quick ? 9 : 21,
        .spacing = 1.0,
        .mass = 1.0,
        .damping = 1.0,
        .time_step = 0.1,
        .force = 0.05, /* k = 0.5: largest displacement about 0.25 spacing */
        .threshold = 0.05,
        .max_depth = quick ? 9 : 30,
        .observe_time = 0.0,
        .rest_tol = quick ? 1e-5 : 1e-7,
        .k_count = 3,
        .stiffness = {0.5, 2.0, 5.0},
    };
    return d;
}

/* Runs the depth experiment for one stiffness and depth; fills the end
 * positions (3 per node) and the top-row profile. */
static int depth_run(const ftm_exp_depth_def *def, const ftm_mesh *mesh, int depth, double *pos,
                     double *profile)
{
    ftm_sim *sim = make_sim(mesh, def->time_step, depth, true);
    if (!sim)
        return FTM_EINVAL;
    int32_t load = node_of(mesh, def->nx / 2 + def->nx * (def->ny - 1));
    int rc = set_force(sim, &load, 1, (ftm_vec3){0, -def->force, 0});
    if (!rc) {
        if (def->observe_time > 0) {
            rc = ftm_sim_run(sim, (int32_t)lround(def->observe_time / def->time_step));
        } else {
            int s = ftm_exp_run_to_rest(sim, mesh, def->rest_tol, 100, 400000);
            rc = s < 0 ? s : FTM_OK;
        }
    }
    if (!rc) {
        int32_t n = ftm_mesh_node_count(mesh);
        memcpy(pos, ftm_sim_positions(sim), (size_t)n * 3 * sizeof *pos);
        for (int ix = 0; ix < def->nx; ix++) {
            int32_t i = node_of(mesh, ix + def->nx * (def->ny - 1));
            profile[ix] = pos[3 * i + 1] - ftm_mesh_rest_position(mesh, i).y;
        }
    }
    ftm_sim_destroy(sim);
    return rc;
}

int ftm_exp_depth(const ftm_exp_depth_def *def, ftm_exp_depth_result *r)
{
    if (def->k_count < 1 || def->k_count > FTM_EXP_MAX_K || def->nx > FTM_EXP_MAX_NX ||
        def->max_depth < 1 || def->max_depth >= FTM_EXP_MAX_DEPTH - 1 || def->nx % 2 == 0)
        return FTM_EINVAL;
    memset(r, 0, sizeof *r);
    r->k_count = def->k_count;
    r->nx = def->nx;
    r->depth_count = def->max_depth;
    int rc = FTM_OK;
    for (int k = 0; k < def->k_count && !rc; k++) {
        r->stiffness[k] = def->stiffness[k];
        r->calibrated[k] = -1;
        ftm_mesh *mesh = make_lattice2d(def->nx, def->ny, def->spacing, def->mass, def->damping,
                                        def->stiffness[k], FTM_FACE_YMIN);
        if (!mesh)
            return FTM_EINVAL;
        int32_t nn = ftm_mesh_node_count(mesh);
        if (k == 0) {
            int32_t c = node_of(mesh, def->nx / 2 + def->nx * (def->ny - 1));
            for (int ix = 0; ix < def->nx; ix++)
                r->x[ix] = ftm_mesh_rest_position(mesh, node_of(mesh, ix + def->nx * (def->ny - 1))).x -
                           ftm_mesh_rest_position(mesh, c).x;
        }
        double *prev = malloc((size_t)nn * 3 * sizeof *prev);
        double *cur = malloc((size_t)nn * 3 * sizeof *cur);
        if (!prev || !cur)
            rc = FTM_ENOMEM;
        /* depth n = 1..max_depth; change(n) needs depth n+1 */
        for (int n = 1; n <= def->max_depth + 1 && !rc; n++) {
            double *prof = n <= def->max_depth ? r->profile[k][n] : r->profile[k][0];
            rc = depth_run(def, mesh, n, cur, prof);
            if (rc)
                break;
            double u;
            double change = ftm_exp_shape_change(mesh, n >= 2 ? prev : NULL, cur, &u);
            if (n <= def->max_depth)
                r->max_disp[k][n] = u;
            if (n >= 2) {
                r->change[k][n - 1] = change;
                if (r->calibrated[k] < 0 && r->change[k][n - 1] < def->threshold)
                    r->calibrated[k] = n - 1;
            }
            double *t = prev;
            prev = cur;
            cur = t;
        }
        free(prev);
        free(cur);
        ftm_mesh_destroy(mesh);
    }
    return rc;
}

/* ---- tissue responses ---------------------------------------------------- */

ftm_exp_tissue_def ftm_exp_default_tissue_def(bool quick)
{
    ftm_exp_tissue_def d = {
        .nx = quick ? 7 : 11,
        .ny = quick ? 7 : 11,
        .spacing = 1.0,
        .mass = 1.0,
        .stiffness = 1.0,
        .time_step = 0.1,
        .damping = {1.0, 2.0, 4.0},
        .creep_force = 2.0,
        .creep_time = quick ? 300.0 : 600.0,
        .hyst_force = 2.0,
        .ramp_time = quick ? 100.0 : 200.0,
        .rate = quick ? 0.02 : 0.01,
        .rate_force = 24.0,
        .sample_every = 10,
    };
    return d;
}

typedef struct tissue_setup {
    ftm_mesh *mesh;
    int32_t top[FTM_EXP_MAX_NX];
    int ntop;
    double height;
} tissue_setup;

static int tissue_setup_make(const ftm_exp_tissue_def *def, double damping, tissue_setup *t)
{
    t->mesh = make_lattice2d(def->nx, def->ny, def->spacing, def->mass, damping, def->stiffness,
                             FTM_FACE_YMIN);
    if (!t->mesh)
        return FTM_EINVAL;
    t->ntop = def->nx;
    for (int ix = 0; ix < def->nx; ix++)
        t->top[ix] = node_of(t->mesh, ix + def->nx * (def->ny - 1));
    t->height = ftm_mesh_rest_position(t->mesh, t->top[0]).y -
                ftm_mesh_rest_position(t->mesh, node_of(t->mesh, 0)).y;
    return FTM_OK;
}

static double tissue_strain(const ftm_sim *sim, const tissue_setup *t)
{
    double s = 0.0;
    for (int i = 0; i < t->ntop; i++)
        s += ftm_sim_position(sim, t->top[i]).y - ftm_mesh_rest_position(t->mesh, t->top[i]).y;
    return s / t->ntop / t->height;
}

static int curve_alloc(ftm_exp_curve *c, int cap)
{
    c->count = 0;
    c->a = malloc((size_t)cap * sizeof *c->a);
    c->b = malloc((size_t)cap * sizeof *c->b);
    return c->a && c->b ? FTM_OK : FTM_ENOMEM;
}

static void curve_free(ftm_exp_curve *c)
{
    free(c->a);
    free(c->b);
    c->a = c->b = NULL;
    c->count = 0;
}

/* Runs `steps` steps with total force F(t) = force_at(step) on the top row,
 * sampling every def->sample_every steps into c (a = force or time). */
typedef double (*force_fn)(const void *ctx, int step);

static int tissue_drive(const ftm_exp_tissue_def *def, ftm_sim *sim, const tissue_setup *t,
                        force_fn f, const void *ctx, int steps, bool a_is_time, ftm_exp_curve *c)
{
    double last = NAN;
    for (int s = 0; s <= steps; s++) {
        double F = f(ctx, s);
        if (F != last) {
            int rc = set_force(sim, t->top, t->ntop, (ftm_vec3){0, F / t->ntop, 0});
            if (rc)
                return rc;
            last = F;
        }
        if (s % def->sample_every == 0) {
            c->a[c->count] = a_is_time ? s * def->time_step : F;
            c->b[c->count] = tissue_strain(sim, t);
            c->count++;
        }
        if (s == steps)
            break;
        int rc = ftm_sim_step(sim);
        if (rc)
            return rc;
    }
    return FTM_OK;
}

typedef struct ramp_ctx {
    double peak, h, ramp_time, rate, constant;
} ramp_ctx;

static double force_constant(const void *ctx, int step)
{
    (void)step;
    return ((const ramp_ctx *)ctx)->constant;
}

static double force_updown(const void *ctx, int step)
{
    const ramp_ctx *r = ctx;
    double t = step * r->h;
    return t <= r->ramp_time ? r->peak * t / r->ramp_time
                             : fmax(0.0, r->peak * (2.0 - t / r->ramp_time));
}

static double force_rate(const void *ctx, int step)
{
    const ramp_ctx *r = ctx;
    return r->rate * step * r->h;
}

/* Equilibrium strain under total force F. */
static int tissue_static(const ftm_exp_tissue_def *def, const tissue_setup *t, double F,
                         double *strain)
{
    ftm_sim *sim = make_sim(t->mesh, def->time_step, 1000000, true);
    if (!sim)
        return FTM_EINVAL;
    int rc = set_force(sim, t->top, t->ntop, (ftm_vec3){0, F / t->ntop, 0});
    if (!rc) {
        int s = ftm_exp_run_to_rest(sim, t->mesh, 1e-9, 200, 1000000);
        rc = s < 0 ? s : FTM_OK;
    }
    if (!rc)
        *strain = tissue_strain(sim, t);
    ftm_sim_destroy(sim);
    return rc;
}

static double loop_area(const ftm_exp_curve *c)
{
    /* shoelace over (force, strain), closed back to the first point */
    double a = 0.0;
    for (int i = 0; i < c->count; i++) {
        int j = (i + 1) % c->count;
        a += c->a[i] * c->b[j] - c->a[j] * c->b[i];
    }
    return fabs(0.5 * a);
}

/* Linear interpolation of strain at force F on the monotone part [i0, i1] of c. */
static double strain_at(const ftm_exp_curve *c, int i0, int i1, double F)
{
    int step = i1 >= i0 ? 1 : -1;
    for (int i = i0; i != i1; i += step) {
        double f0 = c->a[i], f1 = c->a[i + step];
        if ((F >= f0 && F <= f1) || (F <= f0 && F >= f1)) {
            if (f1 == f0)
                return c->b[i];
            return c->b[i] + (c->b[i + step] - c->b[i]) * (F - f0) / (f1 - f0);
        }
    }
    return NAN;
}

int ftm_exp_tissue(const ftm_exp_tissue_def *def, ftm_exp_tissue_result *r)
{
    memset(r, 0, sizeof *r);
    if (def->nx > FTM_EXP_MAX_NX || def->sample_every < 1)
        return FTM_EINVAL;
    int rc = FTM_OK;
    for (int di = 0; di < FTM_EXP_TISSUE_DAMPINGS && !rc; di++) {
        tissue_setup t;
        rc = tissue_setup_make(def, def->damping[di], &t);
        if (rc)
            break;
        int creep_steps = (int)lround(def->creep_time / def->time_step);
        int ramp_steps = (int)lround(def->ramp_time / def->time_step);
        int rate_steps = (int)lround(def->rate_force / def->rate / def->time_step);
        rc = curve_alloc(&r->creep[di], creep_steps / def->sample_every + 2);
        if (!rc)
            rc = curve_alloc(&r->hyst[di], 2 * ramp_steps / def->sample_every + 2);
        if (!rc)
            rc = curve_alloc(&r->rate[di], rate_steps / def->sample_every + 2);
        ramp_ctx ctx = {.peak = def->hyst_force, .h = def->time_step, .ramp_time = def->ramp_time,
                        .rate = def->rate, .constant = def->creep_force};
        /* (a) creep */
        ftm_sim *sim = rc ? NULL : make_sim(t.mesh, def->time_step, 1000000, true);
        if (!rc && !sim)
            rc = FTM_EINVAL;
        if (!rc)
            rc = tissue_drive(def, sim, &t, force_constant, &ctx, creep_steps, true, &r->creep[di]);
        if (!rc)
            rc = tissue_static(def, &t, def->creep_force, &r->creep_static[di]);
        if (!rc) {
            ftm_exp_curve *c = &r->creep[di];
            r->creep_final[di] = c->b[c->count - 1];
            r->creep_t63[di] = NAN;
            for (int i = 0; i < c->count; i++)
                if (c->b[i] >= 0.632 * r->creep_static[di]) {
                    r->creep_t63[di] = c->a[i];
                    break;
                }
            for (int i = 1; i < c->count; i++)
                r->creep_max_drop[di] = fmax(r->creep_max_drop[di], c->b[i - 1] - c->b[i]);
        }
        /* (b) hysteresis */
        if (!rc) {
            ftm_sim_reset(sim);
            rc = tissue_drive(def, sim, &t, force_updown, &ctx, 2 * ramp_steps, false, &r->hyst[di]);
        }
        if (!rc) {
            ftm_exp_curve *c = &r->hyst[di];
            r->hyst_area[di] = loop_area(c);
            int peak = c->count / 2;
            for (int i = 0; i < c->count; i++)
                if (c->a[i] > c->a[peak])
                    peak = i;
            for (int q = 1; q < 20; q++) {
                double F = def->hyst_force * q / 20.0;
                double up = strain_at(c, 0, peak, F), down = strain_at(c, c->count - 1, peak, F);
                if (isfinite(up) && isfinite(down))
                    r->hyst_max_gap[di] = fmax(r->hyst_max_gap[di], down - up);
            }
            r->hyst_residual[di] = c->b[c->count - 1];
        }
        /* (c) load-deformation at a constant force rate */
        if (!rc) {
            ftm_sim_reset(sim);
            rc = tissue_drive(def, sim, &t, force_rate, &ctx, rate_steps, false, &r->rate[di]);
        }
        if (!rc) {
            ftm_exp_curve *c = &r->rate[di];
            double F1 = def->rate_force * 0.1, F9 = def->rate_force * 0.9;
            double s1 = strain_at(c, 0, c->count - 1, F1), s9 = strain_at(c, 0, c->count - 1, F9);
            r->rate_slope_start[di] = s1 / F1;
            r->rate_slope_end[di] = (c->b[c->count - 1] - s9) / (c->a[c->count - 1] - F9);
        }
        if (!rc && di == 0) {
            rc = tissue_static(def, &t, def->rate_force * 0.5, &r->static_strain_half);
            if (!rc)
                rc = tissue_static(def, &t, def->rate_force, &r->static_strain_full);
        }
        ftm_sim_destroy(sim);
        ftm_mesh_destroy(t.mesh);
    }
    if (rc)
        ftm_exp_tissue_free(r);
    return rc;
}

void ftm_exp_tissue_free(ftm_exp_tissue_result *r)
{
    for (int i = 0; i < FTM_EXP_TISSUE_DAMPINGS; i++) {
        curve_free(&r->creep[i]);
        curve_free(&r->hyst[i]);
        curve_free(&r->rate[i]);
    }
}

/* ---- anisotropy ---------------------------------------------------------- */

ftm_exp_aniso_def ftm_exp_default_aniso_def(bool quick)
{
    ftm_exp_aniso_def d = {
        .n = quick ? 5 : 11,
        .spacing = 1.0,
        .mass = 1.0,
        /* model B (horizontal springs 10x) gains energy at d = 1 (the guard
         * holds it only by substepping), below the core's warning threshold
         * (d ~ 1.75 here); d = 2 is above it (docs/experiments.md) */
        .damping = 2.0,
        .stiffness = 1.0,
        .ratio = 10.0,
        .force = 0.2,
        .time_step = 0.1,
        .rest_tol = quick ? 1e-5 : 1e-7,
    };
    return d;
}

int ftm_exp_aniso(const ftm_exp_aniso_def *def, ftm_exp_aniso_result *r)
{
    if (def->n < 3 || def->n % 2 == 0 || def->n > FTM_EXP_MAX_NX)
        return FTM_EINVAL;
    memset(r, 0, sizeof *r);
    r->n = def->n;
    r->model_name[FTM_EXP_ISO] = "isotropic";
    r->model_name[FTM_EXP_A] = "A (horizontal 1/10)";
    r->model_name[FTM_EXP_B] = "B (horizontal 10x)";
    const int n = def->n, c = n / 2;
    const double q = def->ratio;
    /* the vertical springs keep `stiffness`; horizontal ones are scaled */
    const ftm_vec3 scale[FTM_EXP_MODELS] = {{1, 1, 1}, {1 / q, 1 / q, 1}, {q, q, 1}};
#define IDX(ix, iy, iz) ((ix) + n * ((iy) + n * (iz)))
    for (int m = 0; m < FTM_EXP_MODELS; m++) {
        for (int l = 0; l < FTM_EXP_LOADS; l++) {
            uint32_t fixed = l == FTM_EXP_VERTICAL ? FTM_FACE_ZMIN : FTM_FACE_XMAX;
            ftm_mesh *mesh = make_lattice3d(n, def->spacing, def->mass, def->damping,
                                            def->stiffness, scale[m], fixed);
            if (!mesh)
                return FTM_EINVAL;
            /* ftm_sim_create warns about a time step above critical; pick h
             * below the (model-dependent) critical step */
            double h = fmin(def->time_step, 0.5 * ftm_mesh_critical_time_step(mesh));
            ftm_sim *sim = make_sim(mesh, h, 1000000, true);
            if (!sim) {
                ftm_mesh_destroy(mesh);
                return FTM_EINVAL;
            }
            int32_t load = node_of(mesh, l == FTM_EXP_VERTICAL ? IDX(c, c, n - 1) : IDX(0, c, c));
            ftm_vec3 f = l == FTM_EXP_VERTICAL ? (ftm_vec3){0, 0, -def->force}
                                               : (ftm_vec3){def->force, 0, 0};
            int rc = set_force(sim, &load, 1, f);
            int steps = rc ? rc : ftm_exp_run_to_rest(sim, mesh, def->rest_tol, 200, 2000000);
            if (steps < 0) {
                ftm_sim_destroy(sim);
                ftm_mesh_destroy(mesh);
                return steps;
            }
            r->steps[m][l] = steps;
            double sum = 0.0;
            for (int i = 0; i < n; i++) {
                /* across: vertical load -> along x on the top face;
                 * horizontal load -> along z on the x-min face (its image
                 * under the rotation taking -z to +x). into: along the load. */
                int32_t a = node_of(mesh, l == FTM_EXP_VERTICAL ? IDX(i, c, n - 1) : IDX(0, c, n - 1 - i));
                int32_t b = node_of(mesh, l == FTM_EXP_VERTICAL ? IDX(c, c, n - 1 - i) : IDX(i, c, c));
                ftm_vec3 pa = ftm_sim_position(sim, a), Xa = ftm_mesh_rest_position(mesh, a);
                ftm_vec3 pb = ftm_sim_position(sim, b), Xb = ftm_mesh_rest_position(mesh, b);
                double ua = l == FTM_EXP_VERTICAL ? Xa.z - pa.z : pa.x - Xa.x;
                double ub = l == FTM_EXP_VERTICAL ? Xb.z - pb.z : pb.x - Xb.x;
                r->across[m][l][i] = ua;
                r->into[m][l][i] = ub;
                sum += ua;
            }
            r->peak[m][l] = r->across[m][l][c];
            r->width[m][l] = r->peak[m][l] > 0 ? sum / r->peak[m][l] : 0.0;
            ftm_sim_destroy(sim);
            ftm_mesh_destroy(mesh);
        }
    }
#undef IDX
    return FTM_OK;
}

/* ---- stability sweep ----------------------------------------------------- */

ftm_stab_def ftm_stab_default_def(bool quick)
{
    ftm_stab_def d = {
        .quick = quick,
        .sim_time_factor = quick ? 300.0 : 1000.0,
        .bisect_iters = quick ? 4 : 8,
        .lo = 0.1,
        .hi = 4.0,
        .guard_length = quick ? 3.0 : 5.0,
    };
    return d;
}

static ftm_stab_config stab_base(const char *name, int n)
{
    ftm_stab_config c;
    memset(&c, 0, sizeof c);
    snprintf(c.name, sizeof c.name, "%s", name);
    c.kind = FTM_STAB_LATTICE2D;
    c.n = n;
    c.mass = 1e-3;
    c.stiffness = 50.0;
    c.damping_factor = 2.0;
    c.depth = 1000000;
    c.short_frac = 0.05;
    c.hub_radius = 3.0;
    return c;
}

int ftm_stab_configs(bool quick, ftm_stab_config *out, int max)
{
    const int n = quick ? 7 : 15;
    ftm_stab_config all[32];
    int count = 0;
#define ADD(expr)                                                                  \
    do {                                                                           \
        ftm_stab_config c_ = stab_base("", n);                                     \
        expr;                                                                      \
        all[count++] = c_;                                                         \
    } while (0)
    ADD(snprintf(c_.name, sizeof c_.name, "base 2D"));
    if (!quick)
        ADD(snprintf(c_.name, sizeof c_.name, "k x0.1"); c_.stiffness = 5.0);
    ADD(snprintf(c_.name, sizeof c_.name, "k x10"); c_.stiffness = 500.0);
    ADD(snprintf(c_.name, sizeof c_.name, "m x0.1"); c_.mass = 1e-4);
    if (!quick)
        ADD(snprintf(c_.name, sizeof c_.name, "m x10"); c_.mass = 1e-2);
    static const double dfac_full[] = {0.0, 0.25, 0.5, 1.0, 4.0, 20.0, 80.0};
    static const double dfac_quick[] = {0.0, 0.5, 20.0};
    const double *dfac = quick ? dfac_quick : dfac_full;
    int ndfac = quick ? 3 : 7;
    for (int i = 0; i < ndfac; i++)
        ADD(snprintf(c_.name, sizeof c_.name, "d = %g x threshold", dfac[i]);
            c_.damping_factor = dfac[i]);
    static const int depth_full[] = {1, 3, 6};
    for (int i = quick ? 1 : 0; i < (quick ? 2 : 3); i++)
        ADD(snprintf(c_.name, sizeof c_.name, "depth %d", depth_full[i]); c_.depth = depth_full[i]);
    ADD(snprintf(c_.name, sizeof c_.name, "3D 18-stencil"); c_.kind = FTM_STAB_LATTICE3D;
        c_.n = quick ? 5 : 8);
    ADD(snprintf(c_.name, sizeof c_.name, "3D; horizontal k x10"); c_.kind = FTM_STAB_LATTICE3D;
        c_.n = quick ? 5 : 8; c_.horiz_scale = 10.0);
    if (!quick)
        ADD(snprintf(c_.name, sizeof c_.name, "3D; horizontal k x10; d x4"); c_.kind = FTM_STAB_LATTICE3D;
            c_.n = 8; c_.horiz_scale = 10.0; c_.damping_factor = 8.0);
    if (!quick)
        ADD(snprintf(c_.name, sizeof c_.name, "short link 0.05; same k"); c_.kind = FTM_STAB_SHORT;
            c_.short_frac = 0.05);
    ADD(snprintf(c_.name, sizeof c_.name, "short link 0.05; k/len"); c_.kind = FTM_STAB_SHORT;
        c_.short_frac = 0.05; c_.short_scale_k = true);
    if (!quick)
        ADD(snprintf(c_.name, sizeof c_.name, "short link 0.01; k/len"); c_.kind = FTM_STAB_SHORT;
            c_.short_frac = 0.01; c_.short_scale_k = true);
    if (!quick)
        ADD(snprintf(c_.name, sizeof c_.name, "hub r=2"); c_.kind = FTM_STAB_HUB; c_.hub_radius = 2.0);
    ADD(snprintf(c_.name, sizeof c_.name, "hub r=3.5"); c_.kind = FTM_STAB_HUB; c_.hub_radius = 3.5);
#undef ADD
    int k = count < max ? count : max;
    memcpy(out, all, (size_t)k * sizeof *out);
    return k;
}

/* Builds the configuration's mesh with nodal damping d; *load gets the node
 * the force is put on (the irregular node where there is one). */
static ftm_mesh *stab_mesh(const ftm_stab_config *c, double d, int32_t *load)
{
    ftm_error err;
    ftm_mesh *mesh = NULL;
    ftm_mesh_builder *mb = ftm_mesh_builder_create();
    if (!mb)
        return NULL;
    int rc;
    int32_t special;
    if (c->kind == FTM_STAB_LATTICE3D) {
        ftm_lattice3d_def ld = ftm_default_lattice3d_def();
        ld.nx = ld.ny = ld.nz = c->n;
        ld.stencil = FTM_STENCIL_18;
        ld.material.node_mass = c->mass;
        ld.material.node_damping = d;
        ld.material.stiffness = c->stiffness;
        ld.fixed_faces = FTM_FACE_ZMIN;
        if (c->horiz_scale > 0)
            ld.material.axis_scale = (ftm_vec3){c->horiz_scale, c->horiz_scale, 1.0};
        rc = ftm_generate_lattice3d(mb, &ld, &err);
        special = c->n / 2 + c->n * (c->n / 2 + c->n * (c->n - 1)); /* top centre */
    } else {
        ftm_lattice2d_def ld = ftm_default_lattice2d_def();
        ld.nx = ld.ny = c->n;
        ld.material.node_mass = c->mass;
        ld.material.node_damping = d;
        ld.material.stiffness = c->stiffness;
        ld.fixed_faces = FTM_FACE_YMIN;
        rc = ftm_generate_lattice2d(mb, &ld, &err);
        special = c->n / 2 + c->n * (c->n / 2); /* centre */
    }
    if (!rc && (c->kind == FTM_STAB_SHORT || c->kind == FTM_STAB_HUB)) {
        ftm_vec3 p;
        rc = ftm_mesh_builder_node_position(mb, special, &p);
        int32_t count = ftm_mesh_builder_node_count(mb);
        if (!rc && c->kind == FTM_STAB_SHORT) {
            /* a new node at short_frac from the centre node, toward its +x
             * neighbour, linked to the centre node and to its neighbours */
            ftm_node_def nd = ftm_default_node_def();
            nd.position = (ftm_vec3){p.x + c->short_frac, p.y, p.z};
            nd.mass = c->mass;
            nd.damping = d;
            int32_t q = ftm_mesh_builder_add_node(mb, &nd);
            rc = q < 0 ? q : FTM_OK;
            for (int32_t j = 0; j < count && !rc; j++) {
                ftm_vec3 o;
                rc = ftm_mesh_builder_node_position(mb, j, &o);
                double dist = hypot(o.x - p.x, o.y - p.y);
                if (rc || !(dist < 1.01))
                    continue;
                ftm_link_def l = ftm_default_link_def();
                l.a = q;
                l.b = j;
                l.stiffness = c->stiffness;
                if (j == special && c->short_scale_k)
                    l.stiffness = c->stiffness / c->short_frac;
                rc = ftm_mesh_builder_add_link(mb, &l);
            }
            special = q;
        } else if (!rc) {
            for (int32_t j = 0; j < count && !rc; j++) {
                ftm_vec3 o;
                rc = ftm_mesh_builder_node_position(mb, j, &o);
                double dist = hypot(o.x - p.x, o.y - p.y);
                if (rc || j == special || !(dist < c->hub_radius + 1e-9))
                    continue;
                ftm_link_def l = ftm_default_link_def();
                l.a = special;
                l.b = j;
                l.stiffness = c->stiffness;
                rc = ftm_mesh_builder_add_link(mb, &l);
            }
        }
    }
    if (!rc)
        rc = ftm_mesh_build(mb, NULL, &mesh, &err);
    ftm_mesh_builder_destroy(mb);
    if (!rc)
        *load = ftm_mesh_node_of_input(mesh, special);
    return rc ? NULL : mesh;
}

/* Largest eigenvalue of M^-1 K (K linearised at rest, free nodes) by power
 * iteration on the symmetric M^-1/2 K M^-1/2; deterministic start vector. */
static double spectral_lambda(const ftm_mesh *mesh)
{
    int32_t n = ftm_mesh_node_count(mesh), links = ftm_mesh_link_count(mesh);
    double *v = calloc((size_t)n * 3, sizeof *v), *w = calloc((size_t)n * 3, sizeof *w);
    double lambda = 0.0;
    if (!v || !w)
        goto done;
    for (int32_t i = 0; i < 3 * n; i++)
        v[i] = ftm_mesh_fixed(mesh, i / 3) ? 0.0 : (((i * 7919) % 13) - 6.0 + 0.1 * (i % 3));
    for (int it = 0; it < 1500; it++) {
        double norm = 0.0;
        for (int32_t i = 0; i < 3 * n; i++)
            norm += v[i] * v[i];
        norm = sqrt(norm);
        if (!(norm > 0))
            break;
        for (int32_t i = 0; i < 3 * n; i++)
            v[i] /= norm;
        memset(w, 0, (size_t)n * 3 * sizeof *w);
        for (int32_t e = 0; e < links; e++) {
            int32_t a, b;
            double k, len;
            ftm_mesh_link(mesh, e, &a, &b, &k, &len);
            ftm_vec3 A = ftm_mesh_rest_position(mesh, a), B = ftm_mesh_rest_position(mesh, b);
            double d[3] = {A.x - B.x, A.y - B.y, A.z - B.z};
            double l = sqrt(d[0] * d[0] + d[1] * d[1] + d[2] * d[2]);
            double sa = 1.0 / sqrt(ftm_mesh_mass(mesh, a)), sb = 1.0 / sqrt(ftm_mesh_mass(mesh, b));
            double proj = 0.0;
            for (int c = 0; c < 3; c++)
                proj += d[c] / l * (v[3 * a + c] * sa - v[3 * b + c] * sb);
            for (int c = 0; c < 3; c++) {
                double f = k * proj * d[c] / l;
                w[3 * a + c] += f * sa;
                w[3 * b + c] -= f * sb;
            }
        }
        for (int32_t i = 0; i < 3 * n; i++)
            if (ftm_mesh_fixed(mesh, i / 3))
                w[i] = 0.0;
        double rq = 0.0;
        for (int32_t i = 0; i < 3 * n; i++)
            rq += v[i] * w[i];
        lambda = rq;
        double *t = v;
        v = w;
        w = t;
    }
done:
    free(v);
    free(w);
    return lambda;
}

typedef struct stab_run {
    bool stable, reported, nan_seen;
    uint64_t guard_events, unstable_steps;
    int max_substeps;
    double max_u, late_u; /* largest displacement: whole run, last quarter */
    /* unguarded runs: the largest energy (kinetic + spring, every 8th step) in
     * the last quarter is above twice that in the first: growth the
     * displacement criterion can miss when it is in short-wave modes */
    bool energy_grew;
} stab_run;

static void count_warn(void *user, ftm_log_level level, const char *message)
{
    if (level == FTM_LOG_WARN && strstr(message, "damping"))
        *(bool *)user = true;
}

/* One run at h = ratio * h_crit for length * (the fixed simulated time).
 * Stable: every position finite, the largest displacement never above one
 * mean spacing (the load gives about 1/50 of it statically) and the largest
 * displacement in the last quarter of the run at most twice that in the first
 * quarter. With the guard off a run stops at the first sign of instability;
 * with it on it runs to the end (or FTM_EUNSTABLE). */
static int stab_once(const ftm_stab_def *def, const ftm_stab_config *c, const ftm_mesh *mesh,
                     int32_t load, double h_crit, double ratio, bool guard, double length,
                     stab_run *out, bool *warned)
{
    memset(out, 0, sizeof *out);
    ftm_sim_def sd = ftm_default_sim_def();
    sd.time_step = ratio * h_crit;
    sd.depth = c->depth;
    sd.guard = guard;
    bool warn = false;
    sd.log = count_warn;
    sd.log_user = &warn;
    ftm_sim *sim = NULL;
    int rc = ftm_sim_create(mesh, &sd, &sim, NULL);
    if (rc)
        return rc;
    if (warned)
        *warned = warn;
    double spacing = ftm_mesh_mean_link_length(mesh);
    double F = 0.02 * c->stiffness * spacing;
    ftm_vec3 dir = c->kind == FTM_STAB_LATTICE3D ? (ftm_vec3){0.3, 0.2, -1.0} : (ftm_vec3){0.3, -1.0, 0};
    ftm_contact ct = {.node = load, .group = 0, .kind = FTM_CONTACT_FORCE,
                      .value = {F * dir.x, F * dir.y, F * dir.z}};
    rc = ftm_sim_set_contacts(sim, &ct, 1, NULL);
    int steps = (int)ceil(length * def->sim_time_factor / ratio);
    double early = 0.0, late = 0.0, e_early = 0.0, e_late = 0.0;
    bool blown = false;
    for (int s = 0; s < steps && !rc; s++) {
        int st = ftm_sim_step(sim);
        if (st == FTM_EUNSTABLE) {
            out->reported = true;
            blown = true;
            break;
        }
        if (st) {
            rc = st;
            break;
        }
        double u = ftm_exp_max_displacement(sim, mesh);
        if (!isfinite(u)) {
            out->nan_seen = true;
            blown = true;
            break;
        }
        out->max_u = fmax(out->max_u, u);
        if (u > spacing) {
            blown = true;
            if (!guard)
                break;
        }
        if (s < steps / 4)
            early = fmax(early, u);
        if (s >= steps - steps / 4)
            late = fmax(late, u);
        if (!guard && s % 8 == 0 && (s < steps / 4 || s >= steps - steps / 4)) {
            double e = ftm_sim_kinetic_energy(sim) + ftm_sim_potential_energy(sim);
            if (s < steps / 4)
                e_early = fmax(e_early, e);
            else
                e_late = fmax(e_late, e);
        }
    }
    out->late_u = late;
    out->energy_grew = !guard && !(e_late <= 2.0 * e_early);
    if (!rc) {
        out->stable = !blown && late <= 2.0 * early;
        ftm_sim_stats st;
        ftm_sim_get_stats(sim, &st);
        out->guard_events = st.guard_events;
        out->unstable_steps = st.unstable_steps;
        out->max_substeps = st.substeps;
        /* a NaN must never be observable in the positions */
        const double *x = ftm_sim_positions(sim);
        for (int32_t i = 0; i < 3 * ftm_mesh_node_count(mesh); i++)
            if (!isfinite(x[i]))
                out->nan_seen = true;
    }
    ftm_sim_destroy(sim);
    return rc;
}

int ftm_stab_run(const ftm_stab_def *def, const ftm_stab_config *c, ftm_stab_row *row)
{
    memset(row, 0, sizeof *row);
    row->config = *c;
    int32_t load = -1;
    ftm_mesh *mesh = stab_mesh(c, 0.0, &load);
    if (!mesh)
        return FTM_EINVAL;
    double hc = ftm_mesh_critical_time_step(mesh);
    double wmax = 2.0 / hc;
    double threshold = 2.0 * c->mass * 0.025 * wmax; /* the sweep's damping unit (the core's
                                                       * warning before 2026-11-25) */
    ftm_mesh_destroy(mesh);
    row->damping = c->damping_factor >= 0 ? c->damping_factor * threshold : c->damping;
    row->damping_ratio = row->damping / threshold;
    mesh = stab_mesh(c, row->damping, &load);
    if (!mesh)
        return FTM_EINVAL;
    row->nodes = ftm_mesh_node_count(mesh);
    row->max_degree = ftm_mesh_max_degree(mesh);
    row->spacing = ftm_mesh_mean_link_length(mesh);
    row->h_crit = hc;
    row->h_spectral = 2.0 / sqrt(spectral_lambda(mesh));
    row->lo = def->lo;
    row->hi = def->hi;
    stab_run r;
    int rc = stab_once(def, c, mesh, load, hc, def->lo, false, 1.0, &r, &row->warned);
    double lo = def->lo, hi = def->hi;
    if (!rc && !r.stable) {
        row->measured = -1.0;
        row->unstable_anywhere = true;
        hi = def->lo;
    } else if (!rc) {
        rc = stab_once(def, c, mesh, load, hc, hi, false, 1.0, &r, NULL);
        if (!rc && r.stable) {
            row->measured = hi;
        } else if (!rc) {
            row->unstable_anywhere = true;
            for (int it = 0; it < def->bisect_iters && !rc; it++) {
                double mid = 0.5 * (lo + hi);
                rc = stab_once(def, c, mesh, load, hc, mid, false, 1.0, &r, NULL);
                if (r.stable)
                    lo = mid;
                else
                    hi = mid;
            }
            row->measured = lo;
        }
    }
    row->lo = lo;
    row->hi = hi;
    /* false alarms: the guard at the largest stable ratio, over the guarded
     * runs' longer time; the same run unguarded says whether that ratio is
     * still stable over the longer time (a ratio within the bisection's
     * resolution of the boundary may grow slowly), by displacement and by
     * energy */
    row->stable_ratio = !rc && row->measured > 0 ? row->measured : 0.0;
    if (row->stable_ratio > 0) {
        rc = stab_once(def, c, mesh, load, hc, row->stable_ratio, false, def->guard_length, &r,
                       NULL);
        row->stable_long = r.stable && !r.energy_grew;
        if (!rc)
            rc = stab_once(def, c, mesh, load, hc, row->stable_ratio, true, def->guard_length, &r,
                           NULL);
        row->stable_events = r.guard_events;
    }
    for (int p = 0; p < 2; p++) {
        row->outcome[p] = "-";
        row->probe_ratio[p] = 0.0;
    }
    if (!rc && row->unstable_anywhere) {
        row->probe_ratio[0] = hi;
        row->probe_ratio[1] = row->measured < 0 ? 1.0 : 2.0 * hi;
        for (int p = 0; p < 2 && !rc; p++) {
            rc = stab_once(def, c, mesh, load, hc, row->probe_ratio[p], true, def->guard_length,
                           &r, NULL);
            row->guard_events[p] = r.guard_events;
            row->unstable_steps[p] = r.unstable_steps;
            row->max_substeps[p] = r.max_substeps;
            row->reported[p] = r.reported;
            row->bounded[p] = r.stable;
            row->nan_seen[p] = r.nan_seen;
            row->max_u[p] = r.max_u;
            row->late_u[p] = r.late_u;
            double spacing = ftm_mesh_mean_link_length(mesh);
            if (r.reported)
                row->outcome[p] = "reported";
            else if (!r.guard_events)
                row->outcome[p] = r.stable ? "stable" : "missed";
            else
                row->outcome[p] = r.late_u <= spacing ? "recovered" : "caught";
        }
    }
    ftm_mesh_destroy(mesh);
    return rc;
}
