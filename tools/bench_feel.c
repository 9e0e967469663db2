/* SPDX-License-Identifier: GPL-3.0-or-later */
/* `ftm bench feel`: what a trainee feels, per body, force model, far field
 * and penetration depth (docs/feel.md). Each body is pressed by displacing
 * its contact nodes (ramped in, then held) until it is at rest; a row
 * reports the force on the contacts and the dent (the surface within two
 * layers of the contacts) against the body's reference, the median cost of
 * a step, and how long the force takes to settle.
 *
 * References: a small press on the elastin cube, the linear FEM of the same
 * hexahedra with the contacts' displacements prescribed (exact for small
 * strains); a large press (10 % of the cube), the neo-Hookean forces at full
 * depth (the whole body; checked against CalculiX, docs/calculix.md); a
 * shipped training scene, its own model at full depth (what the depth may
 * not change). */
#include "bench.h"
#include "commands.h"
#include "gnuplot.h"

#include "ftm/fem.h"
#include "ftm/ftm.h"

#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#define YOUNG 0.6e6 /* the paper's elastin cube (docs/scenes/elastin-cube.scene) */
#define POISSON 0.45
#define DENSITY 1040.0
#define CUBE_N 10
#define CUBE_SIDE 0.1
#define FIT_K 2615.8 /* springs of the cube, as `ftm fit` identified them (docs/fit.md) */
#define RAMP_STEPS 400
#define SETTLED 1e-3 /* the force is settled within this fraction of its final value */

typedef enum ref_kind { REF_FEM, REF_MODEL_FULL } ref_kind;

typedef struct body {
    char name[24];
    const ftm_mesh *mesh; /* springs, masses, damping of the body */
    ftm_mesh *own_mesh;   /* the cube's (or NULL) */
    ftm_scene *scene;     /* a scene's (or NULL), which owns its mesh */
    ftm_sim_def def;    /* time step, forces and material for element models */
    bool elements;      /* element models apply (volume elements and a [fem] material) */
    ftm_contact *contacts;
    int32_t ncontacts;
    int32_t *dent;      /* surface nodes within two layers of the contacts */
    int32_t ndent;
    int32_t full_depth; /* layers that reach every free node */
    ref_kind ref;
    ftm_forces ref_model; /* REF_MODEL_FULL: whose full-depth run is the reference */
    double ref_force;   /* z force on the contacts */
    double *ref_u;      /* 3 per node */
    bool have_ref;
} body;

typedef struct row {
    const body *b;
    ftm_forces model;
    ftm_far_field far;
    int32_t depth;
    int32_t region, ring;
    double force, force_err, dent_err;
    double step_us, setup_s;
    int32_t steps, settle_steps;
    bool settled, failed;
} row;

typedef struct options {
    bool json, quick, cube, scenes;
    const char *plot;
    int32_t max_steps;
} options;

/* ---- bodies ---- */

static void body_free(body *b)
{
    ftm_mesh_destroy(b->own_mesh);
    ftm_scene_destroy(b->scene);
    free(b->contacts);
    free(b->dent);
    free(b->ref_u);
    memset(b, 0, sizeof *b);
}

/* Surface nodes within two layers of the contacts: the visible dent. */
static int find_dent(body *b, ftm_error *err)
{
    ftm_sim_def d = ftm_default_sim_def();
    d.depth = 2;
    ftm_sim *sim = NULL;
    int rc = ftm_sim_create(b->mesh, &d, &sim, err);
    if (rc)
        return rc;
    if ((rc = ftm_sim_set_contacts(sim, b->contacts, b->ncontacts, err)) != FTM_OK) {
        ftm_sim_destroy(sim);
        return rc;
    }
    const int32_t *order, *start;
    int32_t layers = ftm_sim_layers(sim, &order, &start);
    int32_t n = ftm_mesh_node_count(b->mesh);
    uint8_t *surf = calloc((size_t)n, 1);
    b->dent = malloc(sizeof *b->dent * (size_t)(start[layers] + 1));
    if (!surf || !b->dent) {
        free(surf);
        ftm_sim_destroy(sim);
        return FTM_ENOMEM;
    }
    const int32_t *t = ftm_mesh_triangles(b->mesh);
    for (int32_t k = 0; k < 3 * ftm_mesh_triangle_count(b->mesh); k++)
        surf[t[k]] = 1;
    for (int32_t k = 0; k < start[layers]; k++)
        if (surf[order[k]] && !ftm_mesh_fixed(b->mesh, order[k]))
            b->dent[b->ndent++] = order[k];
    free(surf);
    /* and the depth that reaches every free node */
    ftm_sim_set_depth(sim, 1000000);
    b->full_depth = ftm_sim_layers(sim, NULL, NULL) - 1;
    ftm_sim_destroy(sim);
    return FTM_OK;
}

/* The elastin cube: 10^3 nodes, 0.1 m, hexahedra and 18-neighbour springs,
 * bottom clamped, lumped masses, damping d/2m = 0.11 / h_crit (what the
 * layer-by-layer update needs at half the critical step, docs/core.md); its
 * four central top nodes pressed straight down by `press` metres. */
static int make_cube(body *b, double press, ftm_error *err)
{
    memset(b, 0, sizeof *b);
    snprintf(b->name, sizeof b->name, "cube-%gmm", press * 1e3);
    const double s = CUBE_SIDE / (CUBE_N - 1);
    ftm_mesh_builder *mb = ftm_mesh_builder_create();
    ftm_lattice3d_def ld = ftm_default_lattice3d_def();
    ld.nx = ld.ny = ld.nz = CUBE_N;
    ld.spacing = (ftm_vec3){s, s, s};
    ld.stencil = FTM_STENCIL_18;
    ld.material.node_mass = 1e-3;
    ld.material.node_damping = 0.0;
    ld.material.stiffness = FIT_K;
    ld.fixed_faces = FTM_FACE_ZMIN;
    ftm_mesh *g = NULL;
    int rc = ftm_generate_lattice3d(mb, &ld, err);
    if (!rc)
        rc = ftm_mesh_build(mb, NULL, &g, err);
    ftm_mesh_builder_destroy(mb);
    if (rc)
        return rc;
    int32_t n = ftm_mesh_node_count(g);
    double *mass = malloc(sizeof *mass * (size_t)n);
    if (!mass || (rc = ftm_mesh_lumped_masses(g, DENSITY, mass, err)) != FTM_OK) {
        free(mass);
        ftm_mesh_destroy(g);
        return mass ? rc : FTM_ENOMEM;
    }
    /* the smallest critical step of the models, with these masses */
    ftm_sim_def d = ftm_default_sim_def();
    d.young = YOUNG;
    d.poisson = POISSON;
    d.density = DENSITY;
    d.forces = FTM_FORCES_LINEAR_FEM;
    ftm_sim *probe = NULL;
    double hc = INFINITY;
    if ((rc = ftm_sim_create(g, &d, &probe, err)) == FTM_OK)
        hc = ftm_sim_critical_time_step(probe);
    ftm_sim_destroy(probe);
    /* rebuild with the lumped masses and the damping, in the same order */
    ftm_mesh_builder *rb = ftm_mesh_builder_create();
    for (int32_t i = 0; !rc && i < n; i++) {
        ftm_node_def nd = ftm_default_node_def();
        nd.position = ftm_mesh_rest_position(g, i);
        nd.mass = mass[i];
        nd.fixed = ftm_mesh_fixed(g, i);
        nd.damping = 2.0 * mass[i] * 0.11 / hc;
        if (ftm_mesh_builder_add_node(rb, &nd) < 0)
            rc = FTM_ENOMEM;
    }
    for (int32_t l = 0; !rc && l < ftm_mesh_link_count(g); l++) {
        ftm_link_def lk;
        ftm_mesh_link(g, l, &lk.a, &lk.b, &lk.stiffness, &lk.rest_length);
        rc = ftm_mesh_builder_add_link(rb, &lk);
    }
    for (int32_t e = 0; !rc && e < ftm_mesh_hexahedron_count(g); e++)
        rc = ftm_mesh_builder_add_hexahedron(rb, ftm_mesh_hexahedra(g) + 8 * e);
    const int32_t *tri = ftm_mesh_triangles(g);
    for (int32_t t = 0; !rc && t < ftm_mesh_triangle_count(g); t++)
        rc = ftm_mesh_builder_add_triangle(rb, tri[3 * t], tri[3 * t + 1], tri[3 * t + 2]);
    ftm_mesh_build_def bd = ftm_default_mesh_build_def();
    bd.reorder = false;
    if (!rc)
        rc = ftm_mesh_build(rb, &bd, &b->own_mesh, err);
    b->mesh = b->own_mesh;
    ftm_mesh_builder_destroy(rb);
    free(mass);
    if (rc) {
        ftm_mesh_destroy(g);
        return rc;
    }
    b->def = ftm_default_sim_def();
    b->def.time_step = 0.5 * hc;
    b->def.young = YOUNG;
    b->def.poisson = POISSON;
    b->def.density = 0.0; /* the mesh carries the lumped masses */
    b->elements = true;
    b->contacts = malloc(4 * sizeof *b->contacts);
    if (!b->contacts) {
        ftm_mesh_destroy(g);
        return FTM_ENOMEM;
    }
    for (int j = 4; j <= 5; j++)
        for (int i = 4; i <= 5; i++) {
            int32_t in = i + CUBE_N * (j + CUBE_N * (CUBE_N - 1));
            b->contacts[b->ncontacts++] =
                (ftm_contact){.node = ftm_mesh_node_of_input(g, in), .group = 0,
                              .kind = FTM_CONTACT_DISPLACEMENT, .value = {0, 0, -press}};
        }
    ftm_mesh_destroy(g);
    b->ref = press <= 0.02 * CUBE_SIDE ? REF_FEM : REF_MODEL_FULL;
    b->ref_model = FTM_FORCES_NEO_HOOKEAN;
    return find_dent(b, err);
}

/* A shipped scene, pressed as a probe presses it: the top-face triangle
 * nearest `at`, its three nodes displaced by `press` downwards, in the
 * scene's own model; the reference is that model at full depth. */
static int make_scene(body *b, const char *name, ftm_vec3 at, double press, ftm_error *err)
{
    memset(b, 0, sizeof *b);
    snprintf(b->name, sizeof b->name, "%s", name);
    int rc = ftm_scene_builtin(name, &b->scene, err);
    if (rc)
        return rc;
    const ftm_mesh *m = ftm_scene_mesh(b->scene);
    b->mesh = m;
    b->def = ftm_scene_sim_def(b->scene);
    b->elements = b->def.forces != FTM_FORCES_SPRINGS;
    b->ref = REF_MODEL_FULL;
    b->ref_model = b->def.forces;
    const int32_t *t = ftm_mesh_triangles(m);
    double best = INFINITY;
    int32_t tri = -1;
    for (int32_t i = 0; i < ftm_mesh_triangle_count(m); i++) {
        ftm_vec3 c = {0, 0, 0};
        for (int q = 0; q < 3; q++) {
            ftm_vec3 p = ftm_mesh_rest_position(m, t[3 * i + q]);
            c.x += p.x / 3;
            c.y += p.y / 3;
            c.z += p.z / 3;
        }
        double dd = (c.x - at.x) * (c.x - at.x) + (c.y - at.y) * (c.y - at.y) +
                    (c.z - at.z) * (c.z - at.z);
        if (dd < best) {
            best = dd;
            tri = i;
        }
    }
    b->contacts = malloc(3 * sizeof *b->contacts);
    if (!b->contacts || tri < 0)
        return FTM_ENOMEM;
    for (int q = 0; q < 3; q++)
        b->contacts[b->ncontacts++] =
            (ftm_contact){.node = t[3 * tri + q], .group = 0, .kind = FTM_CONTACT_DISPLACEMENT,
                          .value = {0, 0, -press}};
    return find_dent(b, err);
}

/* The linear FEM with the contacts' displacements prescribed. */
static int fem_reference(body *b, ftm_error *err)
{
    int32_t n = ftm_mesh_node_count(b->mesh);
    bool *con = calloc(3 * (size_t)n, sizeof *con);
    double *pre = calloc(3 * (size_t)n, sizeof *pre), *r = malloc(sizeof *r * 3 * (size_t)n);
    b->ref_u = malloc(sizeof *b->ref_u * 3 * (size_t)n);
    if (!con || !pre || !r || !b->ref_u) {
        free(con);
        free(pre);
        free(r);
        return FTM_ENOMEM;
    }
    for (int32_t k = 0; k < b->ncontacts; k++) {
        int32_t i = b->contacts[k].node;
        con[3 * i] = con[3 * i + 1] = con[3 * i + 2] = true;
        pre[3 * i] = b->contacts[k].value.x;
        pre[3 * i + 1] = b->contacts[k].value.y;
        pre[3 * i + 2] = b->contacts[k].value.z;
    }
    ftm_fem_def fd = ftm_default_fem_def();
    fd.material = (ftm_fem_material){.young = b->def.young, .poisson = b->def.poisson};
    fd.constrained = con;
    ftm_fem *fem = NULL;
    int rc = ftm_fem_create(b->mesh, &fd, &fem, err);
    if (!rc)
        rc = ftm_fem_solve(fem, NULL, pre, b->ref_u, err);
    if (!rc) {
        ftm_fem_residual(fem, b->ref_u, NULL, r);
        b->ref_force = 0;
        for (int32_t k = 0; k < b->ncontacts; k++)
            b->ref_force -= r[3 * b->contacts[k].node + 2];
        b->have_ref = true;
    }
    ftm_fem_destroy(fem);
    free(con);
    free(pre);
    free(r);
    return rc;
}

/* ---- a run ---- */

static double dent_error(const body *b, const double *x)
{
    double num = 0, den = 0;
    for (int32_t k = 0; k < b->ndent; k++) {
        int32_t i = b->dent[k];
        ftm_vec3 X = ftm_mesh_rest_position(b->mesh, i);
        double u[3] = {x[3 * i] - X.x, x[3 * i + 1] - X.y, x[3 * i + 2] - X.z};
        for (int c = 0; c < 3; c++) {
            num += (u[c] - b->ref_u[3 * i + c]) * (u[c] - b->ref_u[3 * i + c]);
            den += b->ref_u[3 * i + c] * b->ref_u[3 * i + c];
        }
    }
    return den > 0 ? sqrt(num / den) : NAN;
}

static void log_quiet(void *user, ftm_log_level level, const char *msg)
{
    (void)user;
    if (level >= FTM_LOG_ERROR)
        fprintf(stderr, "ftm bench feel: %s\n", msg);
}

/* Presses b (ramped over RAMP_STEPS, then held) until it is at rest, in
 * the model, far field and depth of r; fills r, and *x_out with the final
 * positions when asked. */
static int run(const body *b, row *r, const options *o, double **x_out)
{
    ftm_sim_def d = b->def;
    d.forces = r->model;
    d.far_field = r->far;
    d.depth = r->depth;
    d.log = log_quiet;
    ftm_sim *sim = NULL;
    ftm_error err;
    double t0 = ftm_bench_now_us();
    int rc = ftm_sim_create(b->mesh, &d, &sim, &err);
    r->setup_s = (ftm_bench_now_us() - t0) * 1e-6;
    if (rc) {
        fprintf(stderr, "ftm bench feel: %s %s %s depth %d: %s\n", b->name, ftm_forces_name(r->model),
                r->far == FTM_FAR_FIELD_ELASTIC ? "elastic" : "fixed", (int)r->depth,
                err.message);
        r->failed = true;
        return FTM_OK; /* a row that says so */
    }
    const int32_t n = ftm_mesh_node_count(b->mesh);
    const int32_t max_steps = o->max_steps;
    double *force = malloc(sizeof *force * (size_t)max_steps);
    double *times = malloc(sizeof *times * (size_t)max_steps);
    ftm_contact *c = malloc(sizeof *c * (size_t)b->ncontacts);
    if (!force || !times || !c) {
        free(force);
        free(times);
        free(c);
        ftm_sim_destroy(sim);
        return FTM_ENOMEM;
    }
    /* at rest: no node moved more than this in a step */
    const double still = 1e-10 * CUBE_SIDE;
    int32_t s = 0, quiet = 0;
    for (; s < max_steps; s++) {
        double ramp = s < RAMP_STEPS ? (double)(s + 1) / RAMP_STEPS : 1.0;
        for (int32_t k = 0; k < b->ncontacts; k++) {
            c[k] = b->contacts[k];
            c[k].value.x *= ramp;
            c[k].value.y *= ramp;
            c[k].value.z *= ramp;
        }
        if (ftm_sim_set_contacts(sim, c, b->ncontacts, &err) != FTM_OK)
            break;
        double ts = ftm_bench_now_us();
        if (ftm_sim_step(sim) != FTM_OK) {
            r->failed = true;
            break;
        }
        times[s] = ftm_bench_now_us() - ts;
        force[s] = ftm_sim_reaction(sim, 0).z;
        if (s >= RAMP_STEPS) {
            const double *x = ftm_sim_positions(sim), *xp = ftm_sim_previous_positions(sim);
            double mm = 0;
            for (int32_t i = 0; i < 3 * n; i++)
                mm = fmax(mm, fabs(x[i] - xp[i]));
            quiet = mm < still ? quiet + 1 : 0;
            if (quiet >= 20) {
                s++;
                break;
            }
        }
    }
    r->steps = s;
    r->settled = quiet >= 20;
    if (s > RAMP_STEPS) {
        /* the hold's steps: the region's own cost, searched once */
        r->step_us = ftm_bench_median(times + RAMP_STEPS, s - RAMP_STEPS);
        r->force = force[s - 1];
        int32_t last = RAMP_STEPS;
        for (int32_t k = RAMP_STEPS; k < s; k++)
            if (fabs(force[k] - r->force) > SETTLED * fabs(r->force))
                last = k + 1;
        r->settle_steps = last;
    }
    ftm_sim_stats st;
    ftm_sim_get_stats(sim, &st);
    r->region = st.region_nodes;
    r->ring = st.far_nodes;
    if (x_out) {
        *x_out = malloc(sizeof **x_out * 3 * (size_t)n);
        if (*x_out)
            memcpy(*x_out, ftm_sim_positions(sim), sizeof **x_out * 3 * (size_t)n);
    }
    free(force);
    free(times);
    free(c);
    ftm_sim_destroy(sim);
    return FTM_OK;
}

/* The reference of a REF_MODEL_FULL body: its model at full depth. */
static int model_reference(body *b, const options *o)
{
    row r = {.b = b, .model = b->ref_model, .far = FTM_FAR_FIELD_FIXED, .depth = b->full_depth};
    double *x = NULL;
    int rc = run(b, &r, o, &x);
    if (rc || r.failed || !x) {
        free(x);
        return rc ? rc : FTM_EINVAL;
    }
    int32_t n = ftm_mesh_node_count(b->mesh);
    b->ref_u = x;
    for (int32_t i = 0; i < n; i++) {
        ftm_vec3 X = ftm_mesh_rest_position(b->mesh, i);
        b->ref_u[3 * i] -= X.x;
        b->ref_u[3 * i + 1] -= X.y;
        b->ref_u[3 * i + 2] -= X.z;
    }
    b->ref_force = r.force;
    b->have_ref = true;
    return FTM_OK;
}

/* ---- output ---- */

static void print_row(FILE *f, const row *r)
{
    if (r->failed) {
        fprintf(f, "%-11s %-11s %-7s %5d  refused or failed (see above)\n", r->b->name,
                ftm_forces_name(r->model), r->far == FTM_FAR_FIELD_ELASTIC ? "elastic" : "fixed",
                (int)r->depth);
        return;
    }
    fprintf(f, "%-11s %-11s %-7s %5d %6d %5d %9.4f %+8.2f %8.3f %9.1f %7d %9.2f%s\n", r->b->name,
            ftm_forces_name(r->model), r->far == FTM_FAR_FIELD_ELASTIC ? "elastic" : "fixed",
            (int)r->depth, (int)r->region, (int)r->ring, r->force, 100.0 * r->force_err,
            r->dent_err, r->step_us, (int)r->settle_steps, r->settle_steps * r->step_us * 1e-3,
            r->settled ? "" : " (not at rest)");
}

static void print_json(FILE *f, const row *rows, int nrows)
{
    fprintf(f, "{\"rows\": [");
    for (int i = 0; i < nrows; i++) {
        const row *r = &rows[i];
        fprintf(f, "%s{\"body\": \"%s\", \"model\": \"%s\", \"far_field\": \"%s\", \"depth\": %d, "
                   "\"failed\": %s",
                i ? ", " : "", r->b->name, ftm_forces_name(r->model),
                r->far == FTM_FAR_FIELD_ELASTIC ? "elastic" : "fixed", (int)r->depth,
                r->failed ? "true" : "false");
        if (!r->failed) {
            fprintf(f, ", \"region_nodes\": %d, \"far_nodes\": %d, \"force\": ", (int)r->region,
                    (int)r->ring);
            ftm_json_number(f, r->force, 17);
            fputs(", \"reference_force\": ", f);
            ftm_json_number(f, r->b->ref_force, 17);
            fputs(", \"force_error\": ", f);
            ftm_json_number(f, r->force_err, 6);
            fputs(", \"dent_error\": ", f);
            ftm_json_number(f, r->dent_err, 6);
            fputs(", \"step_us\": ", f);
            ftm_json_number(f, r->step_us, 6);
            fputs(", \"setup_s\": ", f);
            ftm_json_number(f, r->setup_s, 6);
            fprintf(f, ", \"steps\": %d, \"settle_steps\": %d, \"settled\": %s", (int)r->steps,
                    (int)r->settle_steps, r->settled ? "true" : "false");
            fputs(", \"settle_ms\": ", f);
            ftm_json_number(f, r->settle_steps * r->step_us * 1e-3, 6);
        }
        fputc('}', f);
    }
    fprintf(f, "]}\n");
}

/* Error against step time, a point per row (colour: model; circle: fixed
 * far field, square: elastic; the number: the depth), a panel per body.
 * Errors below 1e-6 (exact but for round-off) are drawn at 1e-6. */
static int plot(const char *png, const row *rows, int nrows, const body *bodies, int nb)
{
    char dat[1024], gp[1100];
    snprintf(dat, sizeof dat, "%s.dat", png);
    snprintf(gp, sizeof gp, "%s.gp", png);
    FILE *f = fopen(dat, "w");
    if (!f)
        return -1;
    for (int k = 0; k < nb; k++) {
        for (int i = 0; i < nrows; i++)
            if (rows[i].b == &bodies[k] && !rows[i].failed)
                fprintf(f, "%g %g %d %d %d\n", rows[i].step_us,
                        fmax(fabs(rows[i].force_err), 1e-6), (int)rows[i].model,
                        rows[i].far == FTM_FAR_FIELD_ELASTIC, (int)rows[i].depth);
        fprintf(f, "\n\n");
    }
    fclose(f);
    f = fopen(gp, "w");
    if (!f)
        return -1;
    fprintf(f, "set terminal pngcairo size 1300,%d noenhanced font ',11'\nset output ",
            420 * ((nb + 1) / 2) + 40);
    ftm_gnuplot_quote(f, png);
    fprintf(f, "\nset multiplot layout %d,2 title 'ftm bench feel: force error against the "
               "cost of a step (the number: the depth)'\n",
            (nb + 1) / 2);
    fprintf(f, "set logscale xy\nset xlabel 'median step [us]'\nset ylabel '|force error|'\n"
               "set format y '%%.0e'\nset yrange [5e-7:2]\nset grid\n"
               "set key outside bottom center horizontal font ',10'\n");
    static const char *const names[] = {"springs", "linear-fem", "corot-fem", "neo-hookean"};
    for (int k = 0; k < nb; k++) {
        fprintf(f, "set title '%s'\nplot ", bodies[k].name);
        for (int m = 0; m < 4; m++)
            for (int e = 0; e < 2; e++) {
                ftm_gnuplot_quote(f, dat);
                fprintf(f, " index %d using 1:($3==%d && $4==%d ? $2 : 1/0) with points pt %d "
                           "ps 1.6 lc rgb '#%06x' title '%s, %s', ",
                        k, m, e, e ? 5 : 7, m == 0 ? 0x808080 : m == 1 ? 0x1f77b4
                                                 : m == 2 ? 0xff7f0e : 0x2ca02c,
                        names[m], e ? "elastic" : "fixed");
            }
        ftm_gnuplot_quote(f, dat);
        fprintf(f, " index %d using 1:2:(sprintf('%%d', $5)) with labels font ',8' offset "
                   "0.9,0.6 notitle\n", k);
    }
    fprintf(f, "unset multiplot\n");
    fclose(f);
    return ftm_gnuplot_run("ftm bench feel", gp);
}

/* ---- the command ---- */

static void usage(FILE *f)
{
    fprintf(f,
            "usage: ftm bench feel [--quick] [--cube|--scenes] [--max-steps N] [--json] [--plot PNG]\n"
            "\n"
            "What a trainee feels, per body, force model, far field and depth: the force on\n"
            "the pressed nodes and the dent (surface within two layers) against the body's\n"
            "reference, the median step, and the steps until the force stays within 0.1 %%\n"
            "of its final value (docs/feel.md).\n"
            "\n"
            "bodies: the elastin cube pressed 2 mm (reference: linear FEM) and 10 mm (10 %%:\n"
            "neo-Hookean at full depth); the built-in default scene pressed 4 mm by a\n"
            "probe triangle (reference: its springs at full depth)\n"
            "  --quick        the cube at 2 mm only, depths 2 and full, no co-rotational\n"
            "  --cube         the cube only;  --scenes  the scenes only\n"
            "  --max-steps N  at most N steps a run (default 200000)\n"
            "  --json         one JSON object instead of the table\n"
            "  --plot PNG     force error against step time (gnuplot)\n");
}

int ftm_bench_feel(int argc, char **argv)
{
    options o = {.max_steps = 200000, .cube = true, .scenes = true};
    for (int i = 1; i < argc; i++) {
        if (strcmp(argv[i], "--help") == 0 || strcmp(argv[i], "-h") == 0) {
            usage(stdout);
            return 0;
        } else if (strcmp(argv[i], "--quick") == 0) {
            o.quick = true;
            o.scenes = false;
        } else if (strcmp(argv[i], "--json") == 0) {
            o.json = true;
        } else if (strcmp(argv[i], "--cube") == 0) {
            o.scenes = false;
        } else if (strcmp(argv[i], "--scenes") == 0) {
            o.cube = false;
        } else if (strcmp(argv[i], "--plot") == 0 && i + 1 < argc) {
            o.plot = argv[++i];
        } else if (strcmp(argv[i], "--max-steps") == 0 && i + 1 < argc) {
            char *end;
            long v = strtol(argv[++i], &end, 10);
            if (*end || v < 1000 || v > 100000000) {
                fprintf(stderr, "ftm bench feel: --max-steps must be 1000..100000000 (got '%s')\n",
                        argv[i]);
                return 2;
            }
            o.max_steps = (int32_t)v;
        } else {
            fprintf(stderr, "ftm bench feel: unknown option '%s' (or it needs a value)\n", argv[i]);
            usage(stderr);
            return 2;
        }
    }
    body bodies[4];
    int nb = 0;
    ftm_error err;
    int rc = FTM_OK;
    if (o.cube) {
        rc = make_cube(&bodies[nb], 0.002, &err);
        if (!rc && (rc = fem_reference(&bodies[nb], &err)) == FTM_OK)
            nb++;
        if (!rc && !o.quick && (rc = make_cube(&bodies[nb], 0.010, &err)) == FTM_OK)
            nb++;
    }
    if (!rc && o.scenes) {
        rc = make_scene(&bodies[nb], "default", (ftm_vec3){0.035, 0.035, 0.11}, 0.004, &err);
        if (!rc)
            nb++;
    }
    if (rc) {
        fprintf(stderr, "ftm bench feel: %s\n", err.message);
        for (int k = 0; k < nb; k++)
            body_free(&bodies[k]);
        return 1;
    }
    row *rows = calloc(256, sizeof *rows);
    int nrows = 0;
    if (!o.json)
        printf("%-11s %-11s %-7s %5s %6s %5s %9s %8s %8s %9s %7s %9s\n", "body", "model", "far",
               "depth", "region", "ring", "force[N]", "err[%]", "dent", "step[us]", "settle",
               "cost[ms]");
    for (int k = 0; k < nb && rows; k++) {
        body *b = &bodies[k];
        if (!b->have_ref && (rc = model_reference(b, &o)) != FTM_OK) {
            fprintf(stderr, "ftm bench feel: %s: the reference run failed\n", b->name);
            break;
        }
        static const ftm_forces all[] = {FTM_FORCES_SPRINGS, FTM_FORCES_LINEAR_FEM,
                                         FTM_FORCES_COROT_FEM, FTM_FORCES_NEO_HOOKEAN};
        int32_t depths[6], nd = 0;
        if (o.quick) {
            depths[nd++] = 2;
            depths[nd++] = b->full_depth;
        } else {
            for (int32_t dd = 2; dd < b->full_depth; dd += 2)
                depths[nd++] = dd;
            depths[nd++] = b->full_depth;
        }
        for (size_t mi = 0; mi < sizeof all / sizeof all[0]; mi++) {
            ftm_forces model = all[mi];
            if (model != FTM_FORCES_SPRINGS && !b->elements)
                continue;
            if (b->elements && model == FTM_FORCES_SPRINGS && b->ref == REF_MODEL_FULL &&
                b->ref_model != FTM_FORCES_SPRINGS)
                continue; /* springs cannot press 10 % like tissue: see the 2 mm rows */
            if (o.quick && model == FTM_FORCES_COROT_FEM)
                continue;
            for (int fi = 0; fi < 2; fi++)
                for (int32_t di = 0; di < nd; di++) {
                    row *r = &rows[nrows];
                    *r = (row){.b = b, .model = model,
                               .far = fi ? FTM_FAR_FIELD_ELASTIC : FTM_FAR_FIELD_FIXED,
                               .depth = depths[di]};
                    if (fi && depths[di] == b->full_depth)
                        continue; /* the same run as the fixed one */
                    double *x = NULL;
                    if ((rc = run(b, r, &o, &x)) != FTM_OK)
                        break;
                    if (!r->failed && x) {
                        r->force_err = (r->force - b->ref_force) / b->ref_force;
                        r->dent_err = dent_error(b, x);
                    }
                    free(x);
                    if (!o.json) {
                        print_row(stdout, r);
                        fflush(stdout);
                    }
                    nrows++;
                }
        }
    }
    if (o.json && rows)
        print_json(stdout, rows, nrows);
    if (o.plot && rows && plot(o.plot, rows, nrows, bodies, nb) < 0)
        fprintf(stderr, "ftm bench feel: could not write the plot %s\n", o.plot);
    free(rows);
    for (int k = 0; k < nb; k++)
        body_free(&bodies[k]);
    return rc ? 1 : 0;
}
