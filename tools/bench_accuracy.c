/* SPDX-License-Identifier: GPL-3.0-or-later */
/* `ftm bench accuracy`: run time against error (docs/accuracy.md).
 *
 * On two bodies, the paper's elastin cube and a kidney-shaped organ of
 * hexahedra (>= 10k nodes), each method is run from rest under a constant
 * load to its equilibrium, which is compared with the linear static FEM
 * solution (ftm_fem, CHOLMOD):
 *   ft-springs D      force transmittal, springs, penetration depth D
 *   ft-fem D          force transmittal, linear FEM element forces, depth D
 *   ft-corot max      force transmittal, co-rotational element forces, full depth
 *   ft-neo max        force transmittal, neo-Hookean element forces, full depth
 *   explicit-springs  plain explicit central differences, every node at once (Jacobi)
 *   implicit-springs  linearised backward Euler (Baraff-Witkin), CHOLMOD per step
 *   fem-cholmod       the linear FEM itself: one prefactored solve per load
 * Each dynamic method runs twice: once to a tight equilibrium (largest motion
 * per step below 1e-12 of the mean link length) for its final error, then
 * again from rest, timed, until every node is within tol * max|u_FEM| of that
 * equilibrium: the steps and wall time "to equilibrium". Error: the relative
 * L2 error ||u - u_FEM|| / ||u_FEM|| over all nodes.
 *
 * All explicit methods share the nodal masses (lumped from the FEM density),
 * the damping (d_i = 2 zeta m_i, zeta = max(w1, 0.11 / h_crit): the
 * fundamental mode critically damped, w1 from the Rayleigh quotient of the
 * FEM solution under a body force along the load, or the floor the
 * layer-by-layer update needs at h_crit / 2, whichever is larger; on both
 * bodies the floor, so both are overdamped, docs/accuracy.md) and half their
 * critical step. */
#include "bench.h"
#include "bench_bodies.h"
#include "commands.h"

#include "ftm/fem.h"
#include "ftm/ftm.h"

#include <errno.h>
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#define YOUNG FTM_BENCH_YOUNG
#define POISSON FTM_BENCH_POISSON
#define DENSITY FTM_BENCH_DENSITY
#define FIT_K FTM_BENCH_FIT_K
#define FIT_K_PER_ES FTM_BENCH_FIT_K_PER_ES
#define TIGHT 1e-12     /* final equilibrium: motion per step / mean link length */

typedef struct body {
    char name[16];
    ftm_mesh *mesh;     /* lumped masses, damping 2 zeta m, springs of stiffness k */
    int32_t n, free_nodes;
    double *f;          /* external force, 3 per node */
    ftm_contact *contacts;
    int32_t ncontacts;
    double *u_ref;      /* FEM displacement, 3 per node */
    double u_norm, u_max;
    double fem_assemble_s, fem_factor_s, fem_solve_s;
    int64_t fem_dofs, fem_factor_nnz;
    double w1, zeta, k, spacing; /* zeta: d/2m of every node [1/s] */
    int32_t max_depth;  /* layers that reach every free node from the loads */
} body;

typedef struct row {
    const char *mesh;
    char method[24];
    int32_t depth;      /* -1: not a transmittal method */
    int32_t nodes;      /* nodes updated per step */
    double h;           /* time step [s] */
    double step_us;     /* median time of one step */
    int32_t steps;      /* steps to equilibrium within tol */
    double wall_s;      /* measured wall time of those steps (noisy on a shared machine) */
    double time_s;      /* steps x median step: the time to equilibrium reported */
    double setup_s;     /* one-time cost before the first step (factorisation, set-up) */
    double error;       /* relative L2 error of the final equilibrium */
    bool converged;
    uint64_t guard_events; /* transmittal: steps the stability guard rolled back (timed run) */
} row;

typedef struct options {
    double tol;
    int32_t max_steps;
    double be_step;
    bool be_newton; /* implicit-newton on the organ too (always on the cube) */
    bool corot;     /* ft-corot and ft-neo on the organ too (always on the cube) */
    bool json, cube, organ, verbose;
    bool speed, mesh_given; /* --speed: the step of every model side by side (bench_speed.c) */
    int rounds;
    const char *only;
    const char *save;
    int32_t depths[16];
    int ndepths;
} options;

/* ------------------------------------------------------------ bodies */

static void body_free(body *b)
{
    ftm_mesh_destroy(b->mesh);
    free(b->f);
    free(b->contacts);
    free(b->u_ref);
    memset(b, 0, sizeof *b);
}

/* Geometry -> FEM reference, lumped masses, w1, damping -> the final mesh. */
static int body_make(body *bd, const char *name, bool organ, ftm_error *err)
{
    memset(bd, 0, sizeof *bd);
    snprintf(bd->name, sizeof bd->name, "%s", name);
    int32_t loads[FTM_BENCH_MAX_LOADS];
    ftm_vec3 lf[FTM_BENCH_MAX_LOADS];
    int nl = 0;
    ftm_mesh *g = NULL;
    int rc = ftm_bench_body_geometry(organ ? "organ" : "cube", &g, loads, lf, &nl, &bd->spacing,
                                     err);
    if (rc)
        return rc;
    int32_t n = ftm_mesh_node_count(g);
    bd->n = n;
    bd->f = calloc((size_t)n * 3, sizeof *bd->f);
    bd->u_ref = malloc((size_t)n * 3 * sizeof *bd->u_ref);
    bd->contacts = malloc((size_t)nl * sizeof *bd->contacts);
    double *mass = malloc((size_t)n * sizeof *mass);
    if (!bd->f || !bd->u_ref || !bd->contacts || !mass) {
        free(mass);
        ftm_mesh_destroy(g);
        return FTM_ENOMEM;
    }
    for (int q = 0; q < nl; q++) {
        int32_t node = ftm_mesh_node_of_input(g, loads[q]);
        bd->contacts[q] = (ftm_contact){.node = node, .group = 0, .kind = FTM_CONTACT_FORCE,
                                        .value = lf[q]};
        bd->f[3 * node] += lf[q].x;
        bd->f[3 * node + 1] += lf[q].y;
        bd->f[3 * node + 2] += lf[q].z;
    }
    bd->ncontacts = nl;
    /* FEM reference: assemble + factor once, then the load; solve timed as a median */
    ftm_fem_def fd = ftm_default_fem_def();
    fd.material = (ftm_fem_material){.young = YOUNG, .poisson = POISSON};
    ftm_fem *fem = NULL;
    rc = ftm_fem_create(g, &fd, &fem, err);
    double solves[7];
    for (int r = 0; !rc && r < 7; r++) {
        double t0 = ftm_bench_now_us();
        rc = ftm_fem_solve(fem, bd->f, NULL, bd->u_ref, err);
        solves[r] = (ftm_bench_now_us() - t0) * 1e-6;
    }
    if (!rc)
        rc = ftm_mesh_lumped_masses(g, DENSITY, mass, err);
    /* w1 from the Rayleigh quotient of the static shape under a body force
     * m_i a along the load (gravity-like, close to the fundamental mode) */
    double *fg = NULL, *ug = NULL;
    if (!rc) {
        fg = calloc((size_t)n * 3, sizeof *fg);
        ug = malloc((size_t)n * 3 * sizeof *ug);
        if (!fg || !ug)
            rc = FTM_ENOMEM;
    }
    if (!rc) {
        double dir[3] = {0, 0, 0}, dl;
        for (int q = 0; q < nl; q++) {
            dir[0] += lf[q].x;
            dir[1] += lf[q].y;
            dir[2] += lf[q].z;
        }
        dl = sqrt(dir[0] * dir[0] + dir[1] * dir[1] + dir[2] * dir[2]);
        for (int32_t i = 0; i < n; i++)
            for (int c = 0; c < 3; c++)
                fg[3 * i + c] = mass[i] * dir[c] / dl;
        rc = ftm_fem_solve(fem, fg, NULL, ug, err);
    }
    if (!rc) {
        double fu = 0, umu = 0;
        for (int32_t i = 0; i < n; i++)
            for (int c = 0; c < 3; c++) {
                fu += fg[3 * i + c] * ug[3 * i + c];
                umu += mass[i] * ug[3 * i + c] * ug[3 * i + c];
            }
        bd->w1 = sqrt(fu / umu);
    }
    free(fg);
    free(ug);
    if (!rc) {
        ftm_fem_stats st = ftm_fem_get_stats(fem);
        bd->fem_assemble_s = st.assemble_seconds;
        bd->fem_factor_s = st.factor_seconds;
        bd->fem_solve_s = ftm_bench_median(solves, 7);
        bd->fem_dofs = st.free_dofs;
        bd->fem_factor_nnz = st.factor_nnz;
    }
    ftm_fem_destroy(fem);
    if (rc) {
        free(mass);
        ftm_mesh_destroy(g);
        return rc;
    }
    double un = 0, um = 0;
    for (int32_t i = 0; i < n; i++) {
        double u2 = 0;
        for (int c = 0; c < 3; c++) {
            double u = bd->u_ref[3 * i + c];
            u2 += u * u;
        }
        un += u2;
        um = fmax(um, sqrt(u2));
    }
    bd->u_norm = sqrt(un);
    bd->u_max = um;
    bd->k = FIT_K_PER_ES * YOUNG * bd->spacing;

    for (int32_t i = 0; i < n; i++)
        bd->free_nodes += !ftm_mesh_fixed(g, i);
    /* Damping: the fundamental critically damped (d/2m = w1), but at least
     * what the layer-by-layer update needs at half the critical step
     * (d/2m >= 0.055 lambda h = 0.11 / h_crit, docs/core.md "damping is
     * required"), for springs and element forces alike. */
    double floor_zeta = 0;
    rc = ftm_bench_final_mesh(g, mass, bd->k, 0.0, &bd->mesh, err);
    if (!rc)
        rc = ftm_bench_damping_floor(bd->mesh, &floor_zeta, err);
    ftm_mesh_destroy(bd->mesh);
    bd->mesh = NULL;
    bd->zeta = fmax(bd->w1, floor_zeta);
    if (!rc)
        rc = ftm_bench_final_mesh(g, mass, bd->k, bd->zeta, &bd->mesh, err);
    free(mass);
    ftm_mesh_destroy(g);
    if (rc)
        return rc;
    /* the depth that reaches every node */
    ftm_sim *sim = NULL;
    ftm_sim_def d = ftm_default_sim_def();
    d.depth = 1000000;
    rc = ftm_sim_create(bd->mesh, &d, &sim, err);
    if (!rc)
        rc = ftm_sim_set_contacts(sim, bd->contacts, bd->ncontacts, err);
    if (!rc) {
        int32_t layers = ftm_sim_layers(sim, NULL, NULL);
        bd->max_depth = layers - 1;
    }
    ftm_sim_destroy(sim);
    return rc;
}

static double rel_error(const body *bd, const double *x)
{
    double num = 0;
    for (int32_t i = 0; i < bd->n; i++) {
        ftm_vec3 X = ftm_mesh_rest_position(bd->mesh, i);
        double u[3] = {x[3 * i] - X.x, x[3 * i + 1] - X.y, x[3 * i + 2] - X.z};
        for (int c = 0; c < 3; c++)
            num += (u[c] - bd->u_ref[3 * i + c]) * (u[c] - bd->u_ref[3 * i + c]);
    }
    return sqrt(num) / bd->u_norm;
}

/* Largest |a - b| per coordinate over a node list (NULL: all nodes). */
static double max_diff(const double *a, const double *b, const int32_t *nodes, int32_t count)
{
    double m = 0;
    for (int32_t k = 0; k < count; k++) {
        int32_t i = nodes ? nodes[k] : k;
        for (int c = 0; c < 3; c++)
            m = fmax(m, fabs(a[3 * i + c] - b[3 * i + c]));
    }
    return m;
}

/* ------------------------------------------------------------ methods */

static void log_stderr(void *user, ftm_log_level level, const char *msg)
{
    if (*(bool *)user || level >= FTM_LOG_ERROR)
        fprintf(stderr, "  [sim] %s\n", msg);
}

/* Force transmittal at one depth, springs or element forces. */
static int run_ft(const body *bd, ftm_forces forces, int32_t depth, const options *o, row *r)
{
    ftm_error err;
    ftm_sim_def d = ftm_default_sim_def();
    d.forces = forces;
    d.young = YOUNG;
    d.poisson = POISSON;
    d.depth = depth;
    d.log = log_stderr;
    ftm_sim *sim = NULL;
    bool verbose = false;
    d.log_user = &verbose; /* the probe runs at h = 1 ms: its warnings mean nothing */
    int rc = ftm_sim_create(bd->mesh, &d, &sim, &err);
    if (rc) {
        fprintf(stderr, "ftm bench accuracy: %s\n", err.message);
        return rc;
    }
    d.time_step = 0.5 * ftm_sim_critical_time_step(sim);
    d.log_user = (void *)&o->verbose;
    ftm_sim_destroy(sim);
    double ts = ftm_bench_now_us();
    rc = ftm_sim_create(bd->mesh, &d, &sim, &err);
    r->setup_s = (ftm_bench_now_us() - ts) * 1e-6;
    if (!rc)
        rc = ftm_sim_set_contacts(sim, bd->contacts, bd->ncontacts, &err);
    if (rc) {
        fprintf(stderr, "ftm bench accuracy: %s\n", err.message);
        ftm_sim_destroy(sim);
        return rc;
    }
    const int32_t *order, *start;
    int32_t layers = ftm_sim_layers(sim, &order, &start);
    int32_t region = start[layers];
    int32_t *nodes = malloc((size_t)region * sizeof *nodes);
    double *xinf = malloc((size_t)bd->n * 3 * sizeof *xinf);
    double *samples = malloc((size_t)o->max_steps * sizeof *samples);
    if (!nodes || !xinf || !samples) {
        free(nodes);
        free(xinf);
        free(samples);
        ftm_sim_destroy(sim);
        return FTM_ENOMEM;
    }
    memcpy(nodes, order, (size_t)region * sizeof *nodes);
    const double lbar = ftm_mesh_mean_link_length(bd->mesh);
    /* 1: tight equilibrium */
    int32_t s = 0;
    bool conv = false;
    while (!rc && s < o->max_steps && !conv) {
        rc = ftm_sim_run(sim, 10);
        s += 10;
        conv = max_diff(ftm_sim_positions(sim), ftm_sim_previous_positions(sim), nodes, region) <
               TIGHT * lbar;
    }
    memcpy(xinf, ftm_sim_positions(sim), (size_t)bd->n * 3 * sizeof *xinf);
    r->error = rel_error(bd, xinf);
    r->converged = conv && !rc;
    /* 2: timed, from rest, until within tol of that equilibrium */
    ftm_sim_reset(sim);
    rc = rc ? rc : ftm_sim_set_contacts(sim, bd->contacts, bd->ncontacts, &err);
    const double lim = o->tol * bd->u_max;
    int32_t steps = 0;
    double t0 = ftm_bench_now_us();
    bool done = false;
    while (!rc && !done && steps < o->max_steps) {
        double t1 = ftm_bench_now_us();
        rc = ftm_sim_step(sim);
        samples[steps++] = ftm_bench_now_us() - t1;
        if (steps % 10 == 0)
            done = max_diff(ftm_sim_positions(sim), xinf, nodes, region) <= lim;
    }
    r->wall_s = (ftm_bench_now_us() - t0) * 1e-6;
    ftm_sim_stats st;
    ftm_sim_get_stats(sim, &st);
    r->converged = r->converged && done;
    r->guard_events = st.guard_events;
    r->steps = steps;
    r->step_us = steps ? ftm_bench_median(samples, steps) : NAN;
    r->time_s = steps * r->step_us * 1e-6;
    r->nodes = st.updated_nodes;
    r->h = d.time_step;
    r->depth = depth;
    snprintf(r->method, sizeof r->method, "%s",
             forces == FTM_FORCES_SPRINGS     ? "ft-springs"
             : forces == FTM_FORCES_LINEAR_FEM ? "ft-fem"
             : forces == FTM_FORCES_COROT_FEM  ? "ft-corot"
                                               : "ft-neo");
    free(nodes);
    free(xinf);
    free(samples);
    ftm_sim_destroy(sim);
    return rc;
}

/* Spring forces sum_j f_ij on every node (Eq. 6). */
static void spring_forces(const ftm_mesh *m, const double *x, double *f)
{
    int32_t n = ftm_mesh_node_count(m);
    for (int32_t i = 0; i < n; i++) {
        const int32_t *nb;
        const double *k, *len;
        int32_t deg = ftm_mesh_neighbors(m, i, &nb, &k, &len);
        double fx = 0, fy = 0, fz = 0;
        for (int32_t e = 0; e < deg; e++) {
            const double *xi = x + 3 * i, *xj = x + 3 * nb[e];
            double rx = xi[0] - xj[0], ry = xi[1] - xj[1], rz = xi[2] - xj[2];
            double rl = sqrt(rx * rx + ry * ry + rz * rz);
            double t = k[e] * (rl - len[e]) / rl;
            fx += t * rx;
            fy += t * ry;
            fz += t * rz;
        }
        f[3 * i] = fx;
        f[3 * i + 1] = fy;
        f[3 * i + 2] = fz;
    }
}

/* The classic explicit mass-spring model: every free node, central
 * differences, all from the previous state (no layers, no Gauss-Seidel). */
static int run_explicit(const body *bd, const options *o, row *r)
{
    const ftm_mesh *m = bd->mesh;
    const int32_t n = bd->n;
    const double h = 0.5 * ftm_mesh_critical_time_step(m);
    double *x = malloc((size_t)n * 3 * sizeof *x), *xp = malloc((size_t)n * 3 * sizeof *xp),
           *xn = malloc((size_t)n * 3 * sizeof *xn), *f = malloc((size_t)n * 3 * sizeof *f),
           *coef = malloc((size_t)n * 3 * sizeof *coef), *xinf = malloc((size_t)n * 3 * sizeof *xinf),
           *samples = malloc((size_t)o->max_steps * sizeof *samples);
    if (!x || !xp || !xn || !f || !coef || !xinf || !samples) {
        free(x);
        free(xp);
        free(xn);
        free(f);
        free(coef);
        free(xinf);
        free(samples);
        return FTM_ENOMEM;
    }
    for (int32_t i = 0; i < n; i++) {
        double mh = ftm_mesh_mass(m, i) / (h * h), dh = ftm_mesh_damping(m, i) / (2.0 * h);
        double a = 1.0 / (mh + dh);
        coef[3 * i] = a;
        coef[3 * i + 1] = 2.0 * mh * a;
        coef[3 * i + 2] = (mh - dh) * a;
    }
    const double lbar = ftm_mesh_mean_link_length(m), lim = o->tol * bd->u_max;
    int32_t steps = 0;
    bool conv = false, done = false;
    double t0 = 0;
    for (int phase = 0; phase < 2; phase++) {
        for (int32_t i = 0; i < n; i++) {
            ftm_vec3 X = ftm_mesh_rest_position(m, i);
            x[3 * i] = xp[3 * i] = X.x;
            x[3 * i + 1] = xp[3 * i + 1] = X.y;
            x[3 * i + 2] = xp[3 * i + 2] = X.z;
        }
        memcpy(xn, x, (size_t)n * 3 * sizeof *x);
        steps = 0;
        t0 = ftm_bench_now_us();
        while (steps < o->max_steps) {
            double t1 = ftm_bench_now_us();
            spring_forces(m, x, f);
            for (int32_t i = 0; i < n; i++) {
                if (ftm_mesh_fixed(m, i))
                    continue;
                const double *c = coef + 3 * i;
                for (int d = 0; d < 3; d++)
                    xn[3 * i + d] = c[0] * (bd->f[3 * i + d] - f[3 * i + d]) + c[1] * x[3 * i + d] -
                                    c[2] * xp[3 * i + d];
            }
            double *t = xp;
            xp = x;
            x = xn;
            xn = t;
            if (phase == 1)
                samples[steps] = ftm_bench_now_us() - t1;
            steps++;
            if (steps % 10)
                continue;
            if (phase == 0 && (conv = max_diff(x, xp, NULL, n) < TIGHT * lbar))
                break;
            if (phase == 1 && (done = max_diff(x, xinf, NULL, n) <= lim))
                break;
        }
        if (phase == 0) {
            memcpy(xinf, x, (size_t)n * 3 * sizeof *x);
            r->error = rel_error(bd, xinf);
        }
    }
    r->wall_s = (ftm_bench_now_us() - t0) * 1e-6;
    r->steps = steps;
    r->step_us = ftm_bench_median(samples, steps);
    r->time_s = steps * r->step_us * 1e-6;
    r->converged = conv && done;
    r->nodes = bd->free_nodes;
    r->h = h;
    r->depth = -1;
    snprintf(r->method, sizeof r->method, "explicit-springs");
    free(x);
    free(xp);
    free(xn);
    free(f);
    free(coef);
    free(xinf);
    free(samples);
    return FTM_OK;
}

/* Linearised backward Euler (Baraff & Witkin 1998) for the springs:
 *     (M + h D + h^2 K) v' = M v + h (F - f(x)),   x' = x + h v',
 * K the springs' tangent stiffness at x, per link
 *     k [n n^T + max(0, 1 - l/|r|) (I - n n^T)]
 * (the compressive geometric term dropped so that the matrix stays positive
 * definite; it only changes the path, not the equilibrium). The pattern is
 * analysed once, every step refactorises (CHOLMOD) and solves. */
static void link_block(const double *xi, const double *xj, double k, double len, double blk[9])
{
    double r[3] = {xi[0] - xj[0], xi[1] - xj[1], xi[2] - xj[2]};
    double rl = sqrt(r[0] * r[0] + r[1] * r[1] + r[2] * r[2]);
    double g = fmax(0.0, 1.0 - len / rl);
    for (int a = 0; a < 3; a++)
        for (int c = 0; c < 3; c++) {
            double nn = r[a] * r[c] / (rl * rl);
            blk[3 * a + c] = k * (nn + g * ((a == c ? 1.0 : 0.0) - nn));
        }
}

static int run_implicit(const body *bd, const options *o, bool newton, row *r)
{
    const ftm_mesh *m = bd->mesh;
    const int32_t n = bd->n;
    const double h = o->be_step;
    ftm_error err;
    int32_t *fi = malloc((size_t)n * sizeof *fi);
    int32_t nf = 0;
    for (int32_t i = 0; i < n; i++)
        fi[i] = ftm_mesh_fixed(m, i) ? -1 : nf++;
    const int32_t nd = 3 * nf;
    /* pattern: column (i, c): the free neighbours j < i, then i's dofs 0..c */
    int32_t *cs = malloc(((size_t)nd + 1) * sizeof *cs);
    size_t cap = 0;
    for (int32_t i = 0; i < n; i++) {
        if (fi[i] < 0)
            continue;
        const int32_t *nb;
        int32_t deg = ftm_mesh_neighbors(m, i, &nb, NULL, NULL), lower = 0;
        for (int32_t e = 0; e < deg; e++)
            lower += fi[nb[e]] >= 0 && nb[e] < i;
        cap += (size_t)(3 * lower) * 3 + 6;
    }
    int32_t *rows = malloc((cap + 1) * sizeof *rows);
    double *val = malloc((cap + 1) * sizeof *val);
    double *v = calloc((size_t)nd + 1, sizeof *v), *rhs = malloc(((size_t)nd + 1) * sizeof *rhs);
    double *x = malloc((size_t)n * 3 * sizeof *x), *f = malloc((size_t)n * 3 * sizeof *f),
           *xinf = malloc((size_t)n * 3 * sizeof *xinf),
           *samples = malloc((size_t)o->max_steps * sizeof *samples);
    int rc = (!fi || !cs || !rows || !val || !v || !rhs || !x || !f || !xinf || !samples)
                 ? FTM_ENOMEM
                 : FTM_OK;
    size_t q = 0;
    for (int32_t i = 0; !rc && i < n; i++) {
        if (fi[i] < 0)
            continue;
        const int32_t *nb;
        int32_t deg = ftm_mesh_neighbors(m, i, &nb, NULL, NULL);
        for (int c = 0; c < 3; c++) {
            cs[3 * fi[i] + c] = (int32_t)q;
            for (int32_t e = 0; e < deg; e++)
                if (fi[nb[e]] >= 0 && nb[e] < i)
                    for (int a = 0; a < 3; a++)
                        rows[q++] = 3 * fi[nb[e]] + a;
            for (int a = 0; a <= c; a++)
                rows[q++] = 3 * fi[i] + a;
        }
    }
    if (!rc)
        cs[nd] = (int32_t)q;
    ftm_spd *spd = NULL;
    double ts = ftm_bench_now_us();
    if (!rc && (rc = ftm_spd_create(nd, cs, rows, &spd, &err)) != FTM_OK)
        fprintf(stderr, "ftm bench accuracy: %s\n", err.message);
    r->setup_s = (ftm_bench_now_us() - ts) * 1e-6;
    const double lbar = ftm_mesh_mean_link_length(m), lim = o->tol * bd->u_max;
    int32_t steps = 0;
    bool conv = false, done = false;
    double t0 = 0;
    for (int phase = 0; !rc && phase < 2; phase++) {
        for (int32_t i = 0; i < n; i++) {
            ftm_vec3 X = ftm_mesh_rest_position(m, i);
            x[3 * i] = X.x;
            x[3 * i + 1] = X.y;
            x[3 * i + 2] = X.z;
        }
        memset(v, 0, (size_t)nd * sizeof *v);
        steps = 0;
        t0 = ftm_bench_now_us();
        while (!rc && steps < o->max_steps) {
            double t1 = ftm_bench_now_us();
            /* values, column by column in pattern order: every step (Newton)
             * or once, at rest (the constant tangent, reused by both phases) */
            size_t p = 0;
            bool factor = newton || (phase == 0 && steps == 0);
            for (int32_t i = 0; factor && i < n; i++) {
                if (fi[i] < 0)
                    continue;
                const int32_t *nb;
                const double *k, *len;
                int32_t deg = ftm_mesh_neighbors(m, i, &nb, &k, &len);
                double diag[9] = {0}, blk[9];
                for (int32_t e = 0; e < deg; e++) {
                    link_block(x + 3 * i, x + 3 * nb[e], k[e], len[e], blk);
                    for (int t = 0; t < 9; t++)
                        diag[t] += blk[t];
                }
                double mi = ftm_mesh_mass(m, i), di = ftm_mesh_damping(m, i);
                for (int c = 0; c < 3; c++) {
                    for (int32_t e = 0; e < deg; e++)
                        if (fi[nb[e]] >= 0 && nb[e] < i) {
                            link_block(x + 3 * i, x + 3 * nb[e], k[e], len[e], blk);
                            for (int a = 0; a < 3; a++)
                                val[p++] = -h * h * blk[3 * a + c];
                        }
                    for (int a = 0; a <= c; a++)
                        val[p++] = h * h * diag[3 * a + c] + (a == c ? mi + h * di : 0.0);
                }
            }
            rc = factor ? ftm_spd_factor(spd, val, &err) : FTM_OK;
            if (factor && !newton)
                r->setup_s += (ftm_bench_now_us() - t1) * 1e-6;
            if (rc) {
                fprintf(stderr, "ftm bench accuracy: %s\n", err.message);
                break;
            }
            spring_forces(m, x, f);
            for (int32_t i = 0; i < n; i++)
                if (fi[i] >= 0)
                    for (int c = 0; c < 3; c++)
                        rhs[3 * fi[i] + c] = ftm_mesh_mass(m, i) * v[3 * fi[i] + c] +
                                             h * (bd->f[3 * i + c] - f[3 * i + c]);
            rc = ftm_spd_solve(spd, rhs, v, &err);
            double motion = 0;
            for (int32_t i = 0; !rc && i < n; i++)
                if (fi[i] >= 0)
                    for (int c = 0; c < 3; c++) {
                        x[3 * i + c] += h * v[3 * fi[i] + c];
                        motion = fmax(motion, fabs(h * v[3 * fi[i] + c]));
                    }
            if (phase == 1)
                samples[steps] = ftm_bench_now_us() - t1;
            steps++;
            if (phase == 0 && (conv = motion < TIGHT * lbar))
                break;
            if (phase == 1 && (done = max_diff(x, xinf, NULL, n) <= lim))
                break;
        }
        if (phase == 0) {
            memcpy(xinf, x, (size_t)n * 3 * sizeof *x);
            r->error = rel_error(bd, xinf);
        }
    }
    if (!rc) {
        r->wall_s = (ftm_bench_now_us() - t0) * 1e-6;
        r->steps = steps;
        r->step_us = ftm_bench_median(samples, steps);
        r->time_s = steps * r->step_us * 1e-6;
        r->converged = conv && done;
        r->nodes = nf;
        r->h = h;
        r->depth = -1;
        snprintf(r->method, sizeof r->method, newton ? "implicit-newton" : "implicit-springs");
    }
    ftm_spd_destroy(spd);
    free(fi);
    free(cs);
    free(rows);
    free(val);
    free(v);
    free(rhs);
    free(x);
    free(f);
    free(xinf);
    free(samples);
    return rc;
}

/* ------------------------------------------------------------ output */

static void print_row(FILE *out, const row *r)
{
    char depth[16];
    if (r->depth >= 0)
        snprintf(depth, sizeof depth, "%d", (int)r->depth);
    else
        snprintf(depth, sizeof depth, "-");
    fprintf(out, "%-6s %-16s %5s %6d %9.3g %11.2f %8d %9.4f %9.3f %10.3e%s\n", r->mesh,
            r->method, depth, (int)r->nodes, r->h, r->step_us, (int)r->steps, r->time_s,
            r->setup_s, r->error, r->converged ? "" : "  (not converged)");
    if (r->guard_events)
        fprintf(out, "       (the stability guard rolled back %llu steps and substepped)\n",
                (unsigned long long)r->guard_events);
    fflush(out);
}

static void print_json_row(FILE *out, const row *r, bool first)
{
    fprintf(out,
            "%s{\"mesh\":\"%s\",\"method\":\"%s\",\"depth\":%d,\"nodes\":%d,\"h\":%s,"
            "\"step_us\":%s,\"steps\":%d,\"time_s\":%s,\"setup_s\":%s,\"wall_s\":%s,"
            "\"error\":%s,\"converged\":%s,\"guard_events\":%llu}",
            first ? "" : ",", r->mesh, r->method, (int)r->depth, (int)r->nodes,
            FTM_JN("%.6g", r->h), FTM_JN("%.4g", r->step_us), (int)r->steps,
            FTM_JN("%.6g", r->time_s), FTM_JN("%.6g", r->setup_s), FTM_JN("%.6g", r->wall_s),
            FTM_JN("%.6g", r->error), r->converged ? "true" : "false",
            (unsigned long long)r->guard_events);
}

static void print_body(FILE *out, const body *b, const options *o)
{
    fprintf(out,
            "%s: %d nodes (%d free), %d hexahedra, %d springs k = %.1f N/m, spacing %.4g m; "
            "w1 = %.1f rad/s, damping d/2m = %.1f /s; max |u_FEM| = %.4g m; full depth %d\n"
            "  FEM: %lld free dofs, L nnz %lld; assemble %.3f s, factor %.3f s, solve %.4f s\n",
            b->name, (int)b->n, (int)b->free_nodes, (int)ftm_mesh_hexahedron_count(b->mesh),
            (int)ftm_mesh_link_count(b->mesh), b->k, b->spacing, b->w1, b->zeta, b->u_max,
            (int)b->max_depth, (long long)b->fem_dofs, (long long)b->fem_factor_nnz,
            b->fem_assemble_s, b->fem_factor_s, b->fem_solve_s);
    (void)o;
}

static void print_body_json(FILE *out, const body *b, bool first)
{
    fprintf(out,
            "%s{\"name\":\"%s\",\"nodes\":%d,\"free_nodes\":%d,\"hexahedra\":%d,\"springs\":%d,"
            "\"k\":%s,\"spacing\":%s,\"w1\":%s,\"zeta\":%s,\"u_max\":%s,\"max_depth\":%d,"
            "\"fem_dofs\":%lld,\"fem_factor_nnz\":%lld,\"fem_assemble_s\":%s,"
            "\"fem_factor_s\":%s,\"fem_solve_s\":%s}",
            first ? "" : ",", b->name, (int)b->n, (int)b->free_nodes,
            (int)ftm_mesh_hexahedron_count(b->mesh), (int)ftm_mesh_link_count(b->mesh),
            FTM_JN("%.6g", b->k), FTM_JN("%.6g", b->spacing), FTM_JN("%.6g", b->w1),
            FTM_JN("%.6g", b->zeta), FTM_JN("%.6g", b->u_max), (int)b->max_depth,
            (long long)b->fem_dofs, (long long)b->fem_factor_nnz,
            FTM_JN("%.6g", b->fem_assemble_s), FTM_JN("%.6g", b->fem_factor_s),
            FTM_JN("%.6g", b->fem_solve_s));
}

static const char *header =
    "mesh   method           depth  nodes     h [s]   step [us]    steps  time [s] setup [s]  "
    "rel.error\n";

static void usage(FILE *f)
{
    fprintf(f,
            "usage: ftm bench accuracy [--mesh cube|organ|all] [--depths D,D,...] [--tol T]\n"
            "                          [--be-step H] [--newton] [--corot] [--max-steps N]\n"
            "                          [--json] [--save PREFIX] [--verbose]\n"
            "  --mesh       the elastin cube (1000 nodes), the kidney organ (10606), or all (default)\n"
            "  --depths     transmittal depths (default cube 1,2,3,4,6, organ 1,2,4,8,16; the\n"
            "               full depth is always added)\n"
            "  --tol        'at equilibrium': every node within T * max|u_FEM| of the method's\n"
            "               own equilibrium (default 1e-3)\n"
            "  --be-step    backward-Euler time step in s (default 0.01)\n"
            "  --newton     implicit-newton (refactorise every step) on the organ too\n"
            "  --corot      ft-corot and ft-neo on the organ too (slow)\n"
            "  --max-steps  step cap per run (default 2000000)\n"
            "  --json       print {\"meshes\":[...],\"rows\":[{\"mesh\",\"method\",\"depth\",\"nodes\",\"h\",\n"
            "               \"step_us\",\"steps\",\"time_s\",\"setup_s\",\"wall_s\",\"error\",\"converged\"}]}\n"
            "  --save P     also write P.txt (table), P.json and P.dat (gnuplot blocks)\n"
            "  --speed      instead: the step of springs and of linear, co-rotational and\n"
            "               neo-Hookean forces (hexahedra and tetrahedra) at full depth,\n"
            "               alternating in one run, and their ratios to springs (default\n"
            "               --mesh cube); with --json {\"bodies\":[{\"mesh\",...,\"rows\":[{\n"
            "               \"elements\",\"forces\",\"nodes\",\"h\",\"step_us\",\"ratio\"}]}]}\n"
            "  --rounds N   --speed: rounds of 10 steps per model (default 41)\n"
            "  --only 'E F' --speed: springs and only the model of elements E (hexahedra,\n"
            "               tetrahedra) and forces F (for a profiler)\n\n"
            "exit status: 0 success, 1 a run failed, 2 bad arguments or an output that cannot\n"
            "be written\n");
}

static int parse_depths(const char *s, options *o)
{
    o->ndepths = 0;
    while (*s && o->ndepths < 16) {
        char *end;
        long v = strtol(s, &end, 10);
        if (end == s || v < 0 || v > 1000000)
            return -1;
        o->depths[o->ndepths++] = (int32_t)v;
        s = *end == ',' ? end + 1 : end;
        if (*end && *end != ',')
            return -1;
    }
    return o->ndepths ? 0 : -1;
}

static int run_body(body *b, const options *o, row *rows, int *nrows, FILE *progress)
{
    int32_t cube_d[] = {1, 2, 3, 4, 6}, organ_d[] = {1, 2, 4, 8, 16};
    const int32_t *ds = o->ndepths ? o->depths : strcmp(b->name, "cube") == 0 ? cube_d : organ_d;
    int nd = o->ndepths ? o->ndepths : 5;
    int32_t list[18];
    int nl = 0;
    for (int i = 0; i < nd; i++)
        if (ds[i] < b->max_depth)
            list[nl++] = ds[i];
    list[nl++] = b->max_depth;
    for (int pass = 0; pass < 2; pass++)
        for (int i = 0; i < nl; i++) {
            row *r = &rows[(*nrows)];
            memset(r, 0, sizeof *r);
            r->mesh = b->name;
            int rc = run_ft(b, pass ? FTM_FORCES_LINEAR_FEM : FTM_FORCES_SPRINGS, list[i], o, r);
            if (rc)
                return rc;
            (*nrows)++;
            print_row(progress, r);
        }
    row *r = &rows[(*nrows)];
    int rc;
    for (int k = 0; k < 2 && (strcmp(b->name, "cube") == 0 || o->corot); k++) {
        r = &rows[(*nrows)];
        memset(r, 0, sizeof *r);
        r->mesh = b->name;
        ftm_forces f = k ? FTM_FORCES_NEO_HOOKEAN : FTM_FORCES_COROT_FEM;
        if ((rc = run_ft(b, f, b->max_depth, o, r)) != FTM_OK)
            return rc;
        (*nrows)++;
        print_row(progress, r);
    }
    r = &rows[(*nrows)];
    memset(r, 0, sizeof *r);
    r->mesh = b->name;
    if ((rc = run_explicit(b, o, r)) != FTM_OK)
        return rc;
    (*nrows)++;
    print_row(progress, r);
    r = &rows[(*nrows)];
    memset(r, 0, sizeof *r);
    r->mesh = b->name;
    if ((rc = run_implicit(b, o, false, r)) != FTM_OK)
        return rc;
    (*nrows)++;
    print_row(progress, r);
    if (strcmp(b->name, "cube") == 0 || o->be_newton) {
        r = &rows[(*nrows)];
        memset(r, 0, sizeof *r);
        r->mesh = b->name;
        if ((rc = run_implicit(b, o, true, r)) != FTM_OK)
            return rc;
        (*nrows)++;
        print_row(progress, r);
    }
    /* the FEM itself: prefactored, one solve per load */
    r = &rows[(*nrows)];
    memset(r, 0, sizeof *r);
    r->mesh = b->name;
    snprintf(r->method, sizeof r->method, "fem-cholmod");
    r->depth = -1;
    r->nodes = b->free_nodes;
    r->h = NAN;
    r->step_us = b->fem_solve_s * 1e6;
    r->steps = 1;
    r->wall_s = r->time_s = b->fem_solve_s;
    r->setup_s = b->fem_assemble_s + b->fem_factor_s;
    r->error = 0.0;
    r->converged = true;
    (*nrows)++;
    print_row(progress, r);
    return FTM_OK;
}

/* --speed: each selected body (default the cube) through bench_speed.c */
static int run_speed(const options *o)
{
    int status = 0;
    if (o->json)
        printf("{\"bench\":\"speed\",\"bodies\":[");
    for (int which = 0, nb = 0; which < 2 && !status; which++) {
        if ((which == 0 && !o->cube) || (which == 1 && !(o->organ && o->mesh_given)))
            continue;
        ftm_error err;
        body b;
        int rc = body_make(&b, which ? "organ" : "cube", which == 1, &err);
        if (rc) {
            fprintf(stderr, "ftm bench accuracy: %s: %s\n", which ? "organ" : "cube", err.message);
            body_free(&b);
            return 1;
        }
        ftm_speed_def d = {.name = b.name, .mesh = b.mesh, .contacts = b.contacts,
                           .ncontacts = b.ncontacts, .depth = b.max_depth, .young = YOUNG,
                           .poisson = POISSON, .rounds = o->rounds, .steps = 10, .warmup = 200,
                           .only = o->only};
        if (o->json && nb++)
            printf(",");
        if (ftm_bench_speed(&d, stdout, o->json) != FTM_OK)
            status = 1;
        if (!o->json)
            printf("\n");
        body_free(&b);
    }
    if (o->json && !status)
        printf("]}\n");
    return status;
}

int ftm_bench_accuracy(int argc, char **argv)
{
    options o = {.tol = 1e-3, .max_steps = 2000000, .be_step = 0.01, .cube = true, .organ = true,
                 .rounds = 41};
    for (int i = 1; i < argc; i++) {
        const char *a = argv[i];
        static const char *const valued[] = {"--mesh",      "--depths", "--tol",   "--be-step",
                                             "--max-steps", "--save",   "--rounds",  "--only"};
        for (size_t k = 0; k < sizeof valued / sizeof valued[0]; k++) {
            if (strcmp(a, valued[k]) == 0 && i + 1 >= argc) {
                fprintf(stderr, "ftm bench accuracy: %s needs a value\n", a);
                return 2;
            }
        }
        bool more = i + 1 < argc;
        if (strcmp(a, "--json") == 0) {
            o.json = true;
        } else if (strcmp(a, "--verbose") == 0) {
            o.verbose = true;
        } else if (strcmp(a, "--newton") == 0) {
            o.be_newton = true;
        } else if (strcmp(a, "--corot") == 0) {
            o.corot = true;
        } else if (strcmp(a, "--speed") == 0) {
            o.speed = true;
        } else if (strcmp(a, "--only") == 0 && more) {
            o.only = argv[++i];
        } else if (strcmp(a, "--rounds") == 0 && more) {
            if (!ftm_cli_int(argv[++i], 1, 100000, &o.rounds)) {
                fprintf(stderr, "ftm bench accuracy: --rounds must be in 1..100000\n");
                return 2;
            }
        } else if (strcmp(a, "--mesh") == 0 && more) {
            const char *v = argv[++i];
            o.mesh_given = true;
            o.cube = strcmp(v, "cube") == 0 || strcmp(v, "all") == 0;
            o.organ = strcmp(v, "organ") == 0 || strcmp(v, "all") == 0;
            if (!o.cube && !o.organ) {
                fprintf(stderr, "ftm bench accuracy: --mesh must be cube, organ or all\n");
                return 2;
            }
        } else if (strcmp(a, "--depths") == 0 && more) {
            if (parse_depths(argv[++i], &o)) {
                fprintf(stderr, "ftm bench accuracy: --depths wants a list like 1,2,4 (0..1000000)\n");
                return 2;
            }
        } else if (strcmp(a, "--tol") == 0 && more) {
            if (!ftm_cli_double(argv[++i], &o.tol) || !(o.tol > 0 && o.tol < 1)) {
                fprintf(stderr, "ftm bench accuracy: --tol must be in (0, 1)\n");
                return 2;
            }
        } else if (strcmp(a, "--be-step") == 0 && more) {
            if (!ftm_cli_double(argv[++i], &o.be_step) || !(o.be_step > 0 && o.be_step < 100)) {
                fprintf(stderr, "ftm bench accuracy: --be-step must be in (0, 100) s\n");
                return 2;
            }
        } else if (strcmp(a, "--max-steps") == 0 && more) {
            double v;
            if (!ftm_cli_double(argv[++i], &v) || v != floor(v) || v < 10 || v > 100000000) {
                fprintf(stderr, "ftm bench accuracy: --max-steps must be in 10..100000000\n");
                return 2;
            }
            o.max_steps = (int32_t)v;
        } else if (strcmp(a, "--save") == 0 && more) {
            o.save = argv[++i];
        } else if (strcmp(a, "--help") == 0 || strcmp(a, "-h") == 0) {
            usage(stdout);
            return 0;
        } else {
            fprintf(stderr, "ftm bench accuracy: unknown option '%s' (try --help)\n", a);
            usage(stderr);
            return 2;
        }
    }
    if (o.speed)
        return run_speed(&o);
    /* The --save files are opened before the runs, so that a bad path fails
     * at once rather than after them. */
    FILE *outs[3] = {NULL, NULL, NULL};
    char paths[3][4096];
    if (o.save) {
        static const char *const ext[3] = {".txt", ".json", ".dat"};
        for (int k = 0; k < 3; k++) {
            snprintf(paths[k], sizeof paths[k], "%s%s", o.save, ext[k]);
            outs[k] = fopen(paths[k], "w");
            if (!outs[k]) {
                fprintf(stderr, "ftm bench accuracy: %s: cannot write: %s\n", paths[k],
                        strerror(errno));
                for (int j = 0; j < k; j++)
                    fclose(outs[j]);
                return 2;
            }
        }
    }
    body bodies[2];
    int nb = 0;
    row rows[96];
    int nrows = 0;
    FILE *progress = o.json ? stderr : stdout;
    if (!o.json)
        fprintf(progress,
                "Run time against error: each method from rest to its equilibrium under a constant "
                "load,\nagainst the linear static FEM (E = %.3g Pa, nu = %.2f, rho = %.0f kg/m^3).\n"
                "steps, time: until every node is within %.3g * max|u_FEM| of the method's own\n"
                "equilibrium; time = steps x median step (setup: one-time factorisation or set-up).\n"
                "rel.error = ||u - u_FEM|| / ||u_FEM|| of the equilibrium. Springs: uniform k = "
                "%.4g N/m\n(ftm fit elastin-cube) x spacing / (0.1/9 m). Implicit: backward Euler, "
                "h = %g s.\n\n",
                YOUNG, POISSON, DENSITY, o.tol, FIT_K, o.be_step);
    int rc = FTM_OK;
    for (int which = 0; which < 2 && !rc; which++) {
        if ((which == 0 && !o.cube) || (which == 1 && !o.organ))
            continue;
        ftm_error err;
        body *b = &bodies[nb];
        rc = body_make(b, which ? "organ" : "cube", which == 1, &err);
        if (rc) {
            fprintf(stderr, "ftm bench accuracy: %s: %s\n", which ? "organ" : "cube",
                    err.message);
            body_free(b);
            break;
        }
        nb++;
        print_body(progress, b, &o);
        fprintf(progress, "%s", header);
        rc = run_body(b, &o, rows, &nrows, progress);
        fprintf(progress, "\n");
    }
    if (rc) {
        fprintf(stderr, "ftm bench accuracy: failed: %s\n", ftm_strerror(rc));
        for (int i = 0; i < nb; i++)
            body_free(&bodies[i]);
        for (int k = 0; k < 3; k++)
            if (outs[k])
                fclose(outs[k]);
        return 1;
    }
    /* JSON (stdout with --json, and P.json) */
    for (int k = 0; k < 2; k++) {
        FILE *f = k == 0 ? (o.json ? stdout : NULL) : outs[1];
        if (!f)
            continue;
        fprintf(f, "{\"bench\":\"accuracy\",\"tol\":%s,\"young\":%s,\"poisson\":%s,"
                   "\"density\":%s,\"k_fit\":%s,\"be_step\":%s,\"meshes\":[",
                FTM_JN("%.6g", o.tol), FTM_JN("%.6g", YOUNG), FTM_JN("%.6g", POISSON),
                FTM_JN("%.6g", DENSITY), FTM_JN("%.6g", FIT_K), FTM_JN("%.6g", o.be_step));
        for (int i = 0; i < nb; i++)
            print_body_json(f, &bodies[i], i == 0);
        fprintf(f, "],\"rows\":[");
        for (int i = 0; i < nrows; i++)
            print_json_row(f, &rows[i], i == 0);
        fprintf(f, "]}\n");
    }
    if (outs[0]) { /* the table again, whole */
        for (int i = 0; i < nb; i++) {
            print_body(outs[0], &bodies[i], &o);
            fprintf(outs[0], "%s", header);
            for (int j = 0; j < nrows; j++)
                if (strcmp(rows[j].mesh, bodies[i].name) == 0)
                    print_row(outs[0], &rows[j]);
            fprintf(outs[0], "\n");
        }
    }
    if (outs[2]) { /* gnuplot: one block per (mesh, method), then each mesh's Pareto front */
        fprintf(outs[2], "# mesh method depth nodes h step_us steps time_s setup_s error\n");
        int blocks = 0;
        for (int i = 0; i < nrows; i++) {
            const row *r = &rows[i];
            bool new_block = i > 0 && (strcmp(r->mesh, rows[i - 1].mesh) != 0 ||
                                       strcmp(r->method, rows[i - 1].method) != 0);
            if (new_block) {
                fprintf(outs[2], "\n\n");
                blocks++;
            }
            fprintf(outs[2], "%s %s %d %d %.6g %.6g %d %.6g %.6g %.6g\n", r->mesh, r->method,
                    (int)r->depth, (int)r->nodes, r->h, r->step_us, (int)r->steps, r->time_s,
                    r->setup_s, r->error);
        }
        /* Pareto front per mesh: rows no other row beats in both time and error,
         * by increasing time (error 0 drawn at 1e-9 in the plot) */
        for (int bi = 0; bi < nb; bi++) {
            fprintf(outs[2], "\n\n# pareto %s\n", bodies[bi].name);
            int idx[96], ni = 0;
            for (int i = 0; i < nrows; i++) {
                const row *r = &rows[i];
                if (strcmp(r->mesh, bodies[bi].name) != 0 || !r->converged)
                    continue;
                bool dominated = false;
                for (int j = 0; j < nrows && !dominated; j++) {
                    const row *q = &rows[j];
                    dominated = j != i && q->converged && strcmp(q->mesh, r->mesh) == 0 &&
                                q->time_s <= r->time_s && q->error <= r->error &&
                                (q->time_s < r->time_s || q->error < r->error);
                }
                if (!dominated)
                    idx[ni++] = i;
            }
            for (int a2 = 1; a2 < ni; a2++) /* insertion sort by time */
                for (int c = a2; c > 0 && rows[idx[c]].time_s < rows[idx[c - 1]].time_s; c--) {
                    int t = idx[c];
                    idx[c] = idx[c - 1];
                    idx[c - 1] = t;
                }
            for (int c = 0; c < ni; c++) {
                const row *r = &rows[idx[c]];
                fprintf(outs[2], "pareto-%s %s %d %d %.6g %.6g %d %.6g %.6g %.6g\n", r->mesh, r->method,
                        (int)r->depth, (int)r->nodes, r->h, r->step_us, (int)r->steps, r->time_s,
                        r->setup_s, r->error);
            }
        }
    }
    int status = 0;
    for (int k = 0; k < 3; k++)
        if (outs[k] && ftm_close_output(outs[k], "ftm bench accuracy", paths[k]) != 0)
            status = 2;
    for (int i = 0; i < nb; i++)
        body_free(&bodies[i]);
    return status;
}
