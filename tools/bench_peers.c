/* SPDX-License-Identifier: GPL-3.0-or-later */
/* `ftm bench peers`: FTM against Bullet's soft body (docs/peers.md).
 *
 * The bodies of `ftm bench accuracy` (the elastin cube, the kidney organ;
 * bench_bodies.c): the same nodes, lumped masses, fixed nodes, node pairs
 * and loads in FTM (force transmittal at full depth) and in Bullet's
 * btSoftBody (links solved by its position-based solver at its default
 * iterations, one). Bullet has no spring constant: a link's correction per
 * iteration is kLST times the stretch shared by inverse mass, which at
 * equilibrium acts as a spring of kLST / (h^2 (1/m_a + 1/m_b)). Each link
 * gets kLST = c k h^2 (1/m_a + 1/m_b) (k FTM's spring, h the shared step),
 * and c is tuned until the static displacement of the loaded nodes under
 * the load is FTM's springs' at full depth (a Gauss-Seidel pass of the
 * position solver is not a sum of spring forces, so c is near but not 1);
 * both displacements are reported, with the difference of the whole fields.
 *
 * Then, alternately in this process, round after round: steps of FTM's
 * springs, linear and co-rotational element forces (full depth, each at
 * half its own critical step) and of Bullet's body, its own step and the
 * world's; the median per step of each. */
#include "bench.h"
#include "bench_bodies.h"
#include "commands.h"
#include "gnuplot.h"
#ifdef FTM_HAVE_BULLET
#include "peer_bullet.h"
#endif

#include "ftm/ftm.h"

#include <errno.h>
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#define WHO "ftm bench peers"
#define SETTLE_BLOCK 50       /* steps between two looks at the displacement */
#define SETTLE_MAX 4000000    /* steps at most to a static displacement */
#define FTM_TOL 1e-7          /* static: relative change left (double) */
#define BULLET_TOL 2e-5       /* (float: its positions resolve ~1e-5 of these displacements) */
#define MATCH_TOL 1e-3        /* Bullet's loaded displacement within this of FTM's */
#define MATCH_ITER 12

typedef enum method { M_SPRINGS, M_LINEAR, M_COROT, M_BULLET, M_WORLD, M_COUNT } method;
static const char *const method_names[M_COUNT] = {"ftm-springs", "ftm-linear-fem", "ftm-corot",
                                                  "bullet-body", "bullet-world"};

typedef struct scene {
    char name[16];
    ftm_mesh *mesh;
    ftm_contact contacts[FTM_BENCH_MAX_LOADS];
    int ncontacts;
    double dir[3];       /* the load's direction */
    int32_t n, links, depth;
    double k, zeta, h;   /* springs; d/2m; the springs' half-critical step, shared with Bullet */
    /* results */
    double us[M_COUNT];  /* median step; NAN: not measured */
    double ftm_disp, bullet_disp; /* static displacement of the loaded nodes along the load [m] */
    double field_diff;   /* ||u_bullet - u_ftm|| / ||u_ftm|| over all nodes */
    double scale, klst_lo, klst_hi, kdp;
    int64_t ftm_static_steps, bullet_static_steps;
    int bullet_iterations;
    bool bullet_matched;
} scene;

typedef struct options {
    bool cube, organ, tiny, json;
    int rounds;
    const char *plot, *save;
} options;

/* ------------------------------------------------------------ bodies */

static int scene_make(scene *s, const char *name, ftm_error *err)
{
    memset(s, 0, sizeof *s);
    snprintf(s->name, sizeof s->name, "%s", name);
    int32_t loads[FTM_BENCH_MAX_LOADS];
    ftm_vec3 lf[FTM_BENCH_MAX_LOADS];
    int nl = 0;
    double spacing = 0;
    ftm_mesh *g = NULL;
    int rc = ftm_bench_body_geometry(name, &g, loads, lf, &nl, &spacing, err);
    if (rc)
        return rc;
    s->n = ftm_mesh_node_count(g);
    double *mass = malloc((size_t)s->n * sizeof *mass);
    rc = mass ? ftm_mesh_lumped_masses(g, FTM_BENCH_DENSITY, mass, err) : FTM_ENOMEM;
    if (rc == FTM_ENOMEM)
        snprintf(err->message, sizeof err->message, "out of memory");
    s->k = FTM_BENCH_FIT_K_PER_ES * FTM_BENCH_YOUNG * spacing;
    if (!rc)
        rc = ftm_bench_final_mesh(g, mass, s->k, 0.0, &s->mesh, err);
    if (!rc)
        rc = ftm_bench_damping_floor(s->mesh, &s->zeta, err);
    ftm_mesh_destroy(s->mesh);
    s->mesh = NULL;
    if (!rc)
        rc = ftm_bench_final_mesh(g, mass, s->k, s->zeta, &s->mesh, err);
    if (!rc) {
        double sum[3] = {0, 0, 0};
        for (int q = 0; q < nl; q++) {
            s->contacts[q] = (ftm_contact){.node = ftm_mesh_node_of_input(g, loads[q]), .group = 0,
                                           .kind = FTM_CONTACT_FORCE, .value = lf[q]};
            sum[0] += lf[q].x;
            sum[1] += lf[q].y;
            sum[2] += lf[q].z;
        }
        double len = sqrt(sum[0] * sum[0] + sum[1] * sum[1] + sum[2] * sum[2]);
        for (int c = 0; c < 3; c++)
            s->dir[c] = sum[c] / len;
        s->ncontacts = nl;
        s->links = ftm_mesh_link_count(s->mesh);
    }
    free(mass);
    ftm_mesh_destroy(g);
    return rc;
}

static void scene_free(scene *s)
{
    ftm_mesh_destroy(s->mesh);
    s->mesh = NULL;
}

/* ------------------------------------------------------------ FTM */

/* A simulation of the scene at full depth with these forces, loaded, at
 * half its own critical step (*h). */
static int ftm_make(scene *s, ftm_forces forces, ftm_sim **out, double *h, ftm_error *err)
{
    ftm_sim_def d = ftm_default_sim_def();
    d.forces = forces;
    d.young = FTM_BENCH_YOUNG;
    d.poisson = FTM_BENCH_POISSON;
    d.depth = 1000000;
    ftm_sim *sim = NULL;
    int rc = ftm_sim_create(s->mesh, &d, &sim, err);
    if (!rc)
        rc = ftm_sim_set_contacts(sim, s->contacts, s->ncontacts, err);
    if (!rc) {
        d.depth = ftm_sim_layers(sim, NULL, NULL) - 1; /* the layers reach every node */
        d.time_step = 0.5 * ftm_sim_critical_time_step(sim);
        s->depth = d.depth;
    }
    ftm_sim_destroy(sim);
    sim = NULL;
    if (!rc)
        rc = ftm_sim_create(s->mesh, &d, &sim, err);
    if (!rc)
        rc = ftm_sim_set_contacts(sim, s->contacts, s->ncontacts, err);
    if (rc) {
        ftm_sim_destroy(sim);
        return rc;
    }
    *out = sim;
    *h = d.time_step;
    return FTM_OK;
}

/* The mean displacement of the loaded nodes along the load. */
static double loaded_disp(const scene *s, const double *x)
{
    double sum = 0;
    for (int q = 0; q < s->ncontacts; q++) {
        int32_t i = s->contacts[q].node;
        ftm_vec3 X = ftm_mesh_rest_position(s->mesh, i);
        sum += (x[3 * i] - X.x) * s->dir[0] + (x[3 * i + 1] - X.y) * s->dir[1] +
               (x[3 * i + 2] - X.z) * s->dir[2];
    }
    return sum / s->ncontacts;
}

/* Steps until the loaded displacement d stops: its change over the last
 * block, and what a geometric decay of the changes leaves, both below tol
 * |d|. stepper(ctx, steps) steps and returns d (or NAN on failure). */
static int settle(double (*stepper)(void *, int), void *ctx, double tol, double *d, int64_t *steps)
{
    double d0 = NAN, d1 = NAN, d2 = NAN;
    for (*steps = 0; *steps < SETTLE_MAX;) {
        d0 = d1;
        d1 = d2;
        d2 = stepper(ctx, SETTLE_BLOCK);
        *steps += SETTLE_BLOCK;
        if (!isfinite(d2))
            return FTM_EUNSTABLE;
        double c1 = d2 - d1, c0 = d1 - d0;
        if (!isfinite(c0) || fabs(c1) > tol * fabs(d2))
            continue;
        double r = c0 != 0 ? c1 / c0 : 0;
        double left = r > 0 && r < 1 ? fabs(c1) * r / (1 - r) : r <= 0 ? fabs(c1) : INFINITY;
        if (left <= tol * fabs(d2)) {
            *d = d2;
            return FTM_OK;
        }
    }
    *d = d2;
    return FTM_EUNSTABLE;
}

typedef struct ftm_ctx {
    const scene *s;
    ftm_sim *sim;
    int rc;
} ftm_ctx;

static double ftm_stepper(void *ctx, int steps)
{
    ftm_ctx *c = ctx;
    c->rc = ftm_sim_run(c->sim, steps);
    return c->rc ? NAN : loaded_disp(c->s, ftm_sim_positions(c->sim));
}

/* ------------------------------------------------------------ Bullet */

#ifdef FTM_HAVE_BULLET
typedef struct bullet_ctx {
    const scene *s;
    ftm_peer_bullet *p;
    double *x;
} bullet_ctx;

static double bullet_stepper(void *ctx, int steps)
{
    bullet_ctx *c = ctx;
    for (int i = 0; i < steps; i++)
        ftm_peer_bullet_step(c->p, c->s->h);
    ftm_peer_bullet_positions(c->p, c->x);
    return loaded_disp(c->s, c->x);
}

/* Bullet's body of the scene, its stiffness scaled until its static
 * displacement of the loaded nodes is FTM's (ftm_x: FTM's equilibrium, for
 * the difference of the fields). */
static int bullet_make(scene *s, const double *ftm_x, ftm_peer_bullet **out)
{
    const int32_t n = s->n;
    double *x = malloc((size_t)n * 3 * sizeof *x), *mass = malloc((size_t)n * sizeof *mass);
    int32_t *pairs = malloc((size_t)s->links * 2 * sizeof *pairs);
    double *w = malloc((size_t)s->links * sizeof *w);
    ftm_peer_bullet *p = NULL;
    int rc = x && mass && pairs && w ? FTM_OK : FTM_ENOMEM;
    for (int32_t i = 0; !rc && i < n; i++) {
        ftm_vec3 X = ftm_mesh_rest_position(s->mesh, i);
        x[3 * i] = X.x;
        x[3 * i + 1] = X.y;
        x[3 * i + 2] = X.z;
        mass[i] = ftm_mesh_fixed(s->mesh, i) ? 0.0 : ftm_mesh_mass(s->mesh, i);
    }
    for (int32_t l = 0; !rc && l < s->links; l++) {
        double k, len;
        ftm_mesh_link(s->mesh, l, &pairs[2 * l], &pairs[2 * l + 1], &k, &len);
        double ia = mass[pairs[2 * l]] > 0 ? 1 / mass[pairs[2 * l]] : 0;
        double ib = mass[pairs[2 * l + 1]] > 0 ? 1 / mass[pairs[2 * l + 1]] : 0;
        w[l] = k * s->h * s->h * (ia + ib);
    }
    /* FTM's damping d = 2 zeta m takes exp(-2 zeta h) of the velocity a step */
    s->kdp = 1 - exp(-2 * s->zeta * s->h);
    if (!rc && !(p = ftm_peer_bullet_create(n, x, mass, s->links, pairs, w, s->kdp)))
        rc = FTM_ENOMEM;
    for (int q = 0; !rc && q < s->ncontacts; q++) {
        ftm_vec3 f = s->contacts[q].value;
        ftm_peer_bullet_load(p, s->contacts[q].node, f.x, f.y, f.z);
    }
    s->scale = 1;
    s->bullet_static_steps = 0;
    bullet_ctx c = {.s = s, .p = p, .x = x};
    for (int it = 0; !rc && it < MATCH_ITER; it++) {
        ftm_peer_bullet_set_scale(p, s->scale, &s->klst_lo, &s->klst_hi);
        int64_t steps = 0;
        rc = settle(bullet_stepper, &c, BULLET_TOL, &s->bullet_disp, &steps);
        s->bullet_static_steps += steps;
        if (rc) {
            fprintf(stderr, "%s: %s: Bullet's body did not come to rest in %d steps\n", WHO,
                    s->name, SETTLE_MAX);
            break;
        }
        double ratio = s->bullet_disp / s->ftm_disp;
        if (fabs(ratio - 1) <= MATCH_TOL) {
            s->bullet_matched = true;
            break;
        }
        /* the displacement goes as 1 / c: a new c, and the equilibrium
         * scaled to match as a start */
        double old = s->scale;
        s->scale *= ratio;
        ftm_peer_bullet_positions(p, x);
        for (int32_t i = 0; i < n; i++) {
            ftm_vec3 X = ftm_mesh_rest_position(s->mesh, i);
            x[3 * i] = X.x + (x[3 * i] - X.x) * old / s->scale;
            x[3 * i + 1] = X.y + (x[3 * i + 1] - X.y) * old / s->scale;
            x[3 * i + 2] = X.z + (x[3 * i + 2] - X.z) * old / s->scale;
        }
        ftm_peer_bullet_set_positions(p, x);
    }
    if (!rc) {
        ftm_peer_bullet_positions(p, x);
        double num = 0, den = 0;
        for (int32_t i = 0; i < n; i++) {
            ftm_vec3 X = ftm_mesh_rest_position(s->mesh, i);
            const double r[3] = {X.x, X.y, X.z};
            for (int k = 0; k < 3; k++) {
                double uf = ftm_x[3 * i + k] - r[k], ub = x[3 * i + k] - r[k];
                num += (ub - uf) * (ub - uf);
                den += uf * uf;
            }
        }
        s->field_diff = sqrt(num / den);
        s->bullet_iterations = ftm_peer_bullet_iterations(p);
    }
    free(x);
    free(mass);
    free(pairs);
    free(w);
    if (rc) {
        ftm_peer_bullet_destroy(p);
        return rc;
    }
    *out = p;
    return FTM_OK;
}
#endif

/* ------------------------------------------------------------ timing */

static int run_scene(scene *s, const options *o)
{
    ftm_error err;
    ftm_sim *sim[3] = {NULL, NULL, NULL};
    double h[3] = {0, 0, 0};
    static const ftm_forces forces[3] = {FTM_FORCES_SPRINGS, FTM_FORCES_LINEAR_FEM,
                                         FTM_FORCES_COROT_FEM};
    int rc = FTM_OK;
    for (int m = 0; m < 3 && !rc; m++)
        rc = ftm_make(s, forces[m], &sim[m], &h[m], &err);
    if (rc) {
        fprintf(stderr, "%s: %s: %s\n", WHO, s->name, err.message);
        for (int m = 0; m < 3; m++)
            ftm_sim_destroy(sim[m]);
        return rc;
    }
    s->h = h[M_SPRINGS];
    /* FTM's springs at rest under the load */
    ftm_ctx fc = {.s = s, .sim = sim[M_SPRINGS]};
    rc = settle(ftm_stepper, &fc, FTM_TOL, &s->ftm_disp, &s->ftm_static_steps);
    if (rc)
        fprintf(stderr, "%s: %s: FTM's springs did not come to rest (%s)\n", WHO, s->name,
                ftm_strerror(fc.rc ? fc.rc : rc));
    void *bullet = NULL;
#ifdef FTM_HAVE_BULLET
    if (!rc) {
        ftm_peer_bullet *p = NULL;
        rc = bullet_make(s, ftm_sim_positions(sim[M_SPRINGS]), &p);
        bullet = p;
    }
#endif
    /* the element forces from rest under the load: a few steps first */
    for (int m = 1; m < 3 && !rc; m++)
        rc = ftm_sim_run(sim[m], 20);
    /* rounds of each method in turn, about 20 ms each */
    int count[M_COUNT];
    for (int m = 0; m < M_COUNT; m++) {
        double est = m == M_SPRINGS ? 0.03 * s->n : m == M_LINEAR ? 0.1 * s->n
                     : m == M_COROT ? 0.4 * s->n : 0.15 * s->n; /* us, a guess */
        count[m] = (int)fmin(2000, fmax(10, 20000 / est));
    }
    double *samples[M_COUNT] = {NULL};
    int nsamples[M_COUNT] = {0};
    for (int m = 0; m < M_COUNT && !rc; m++)
        if (!(samples[m] = malloc((size_t)count[m] * o->rounds * sizeof **samples)))
            rc = FTM_ENOMEM;
    for (int r = 0; r < o->rounds && !rc; r++)
        for (int m = 0; m < M_COUNT && !rc; m++) {
            if (m >= M_BULLET && !bullet)
                continue;
            for (int i = 0; i < count[m] && !rc; i++) {
                double t0 = ftm_bench_now_us();
                if (m < M_BULLET)
                    rc = ftm_sim_step(sim[m]);
#ifdef FTM_HAVE_BULLET
                else if (m == M_BULLET)
                    ftm_peer_bullet_step(bullet, s->h);
                else
                    ftm_peer_bullet_step_world(bullet, s->h);
#endif
                samples[m][nsamples[m]++] = ftm_bench_now_us() - t0;
            }
        }
    for (int m = 0; m < M_COUNT; m++) {
        s->us[m] = NAN;
        if (!rc && nsamples[m])
            s->us[m] = ftm_bench_median(samples[m], nsamples[m]);
        free(samples[m]);
    }
    if (rc && rc != FTM_EUNSTABLE)
        fprintf(stderr, "%s: %s: %s\n", WHO, s->name, ftm_strerror(rc));
#ifdef FTM_HAVE_BULLET
    ftm_peer_bullet_destroy(bullet);
#endif
    for (int m = 0; m < 3; m++)
        ftm_sim_destroy(sim[m]);
    return rc;
}

/* ------------------------------------------------------------ output */

static void print_table(FILE *f, const scene *sc, int ns, bool bullet)
{
    fprintf(f, "%-6s %6s %6s %5s %9s | %11s %11s %9s %8s %8s | %9s %9s %9s %9s %9s | %7s %7s\n",
            "scene", "nodes", "links", "depth", "h [us]", "FTM u [mm]", "Bullet u", "diff",
            "field", "kLST c", "springs", "linear", "corot", "B. body", "B. world", "B/spr",
            "B/corot");
    for (int i = 0; i < ns; i++) {
        const scene *s = &sc[i];
        fprintf(f, "%-6s %6d %6d %5d %9.3f | %11.6f ", s->name, (int)s->n, (int)s->links,
                (int)s->depth, s->h * 1e6, s->ftm_disp * 1e3);
        if (bullet)
            fprintf(f, "%11.6f %+8.2e %8.4f %8.4f | ", s->bullet_disp * 1e3,
                    s->bullet_disp / s->ftm_disp - 1, s->field_diff, s->scale);
        else
            fprintf(f, "%11s %9s %8s %8s | ", "-", "-", "-", "-");
        for (int m = 0; m < M_COUNT; m++)
            if (isfinite(s->us[m]))
                fprintf(f, "%9.2f ", s->us[m]);
            else
                fprintf(f, "%9s ", "-");
        if (bullet)
            fprintf(f, "| %6.2fx %6.2fx\n", s->us[M_BULLET] / s->us[M_SPRINGS],
                    s->us[M_BULLET] / s->us[M_COROT]);
        else
            fprintf(f, "| %7s %7s\n", "-", "-");
    }
}

static void json_field(FILE *f, const char *name, double v, int digits)
{
    fprintf(f, ",\"%s\":", name);
    ftm_json_number(f, v, digits);
}

static void print_json(FILE *f, const scene *sc, int ns, const options *o, bool bullet)
{
    fprintf(f, "{\"bench\":\"peers\",\"rounds\":%d,\"bullet\":", o->rounds);
#ifdef FTM_HAVE_BULLET
    fprintf(f, "\"%s\",\"bullet_scalar\":\"%s\"", ftm_peer_bullet_version(),
            ftm_peer_bullet_scalar());
#else
    fprintf(f, "null,\"bullet_scalar\":null");
#endif
    fprintf(f, ",\"scenes\":[");
    for (int i = 0; i < ns; i++) {
        const scene *s = &sc[i];
        double nan = NAN;
        fprintf(f, "%s{\"scene\":\"%s\",\"nodes\":%d,\"links\":%d,\"depth\":%d", i ? "," : "",
                s->name, (int)s->n, (int)s->links, (int)s->depth);
        json_field(f, "h", s->h, 6);
        json_field(f, "k", s->k, 6);
        json_field(f, "zeta", s->zeta, 6);
        json_field(f, "ftm_us", s->us[M_SPRINGS], 5);
        json_field(f, "bullet_us", s->us[M_BULLET], 5);
        json_field(f, "ratio", bullet ? s->us[M_BULLET] / s->us[M_SPRINGS] : nan, 4);
        json_field(f, "ftm_linear_us", s->us[M_LINEAR], 5);
        json_field(f, "ftm_corot_us", s->us[M_COROT], 5);
        json_field(f, "corot_ratio", bullet ? s->us[M_BULLET] / s->us[M_COROT] : nan, 4);
        json_field(f, "bullet_world_us", s->us[M_WORLD], 5);
        json_field(f, "ftm_disp", s->ftm_disp, 8);
        json_field(f, "bullet_disp", bullet ? s->bullet_disp : nan, 8);
        json_field(f, "disp_diff", bullet ? s->bullet_disp / s->ftm_disp - 1 : nan, 4);
        json_field(f, "field_diff", bullet ? s->field_diff : nan, 4);
        json_field(f, "klst_scale", bullet ? s->scale : nan, 6);
        json_field(f, "klst_min", bullet ? s->klst_lo : nan, 6);
        json_field(f, "klst_max", bullet ? s->klst_hi : nan, 6);
        json_field(f, "bullet_kdp", bullet ? s->kdp : nan, 6);
        fprintf(f, ",\"bullet_iterations\":%d,\"ftm_static_steps\":%lld,\"bullet_static_steps\":%lld"
                   ",\"matched\":%s}",
                s->bullet_iterations, (long long)s->ftm_static_steps,
                (long long)s->bullet_static_steps, s->bullet_matched ? "true" : "false");
    }
    fprintf(f, "]}\n");
}

/* Bars of the median step, a group per scene, logarithmic. */
static int plot(const char *png, const scene *sc, int ns)
{
    char dat[1024], gp[1100];
    snprintf(dat, sizeof dat, "%s.dat", png);
    snprintf(gp, sizeof gp, "%s.gp", png);
    FILE *f = fopen(dat, "w");
    if (!f)
        return -1;
    fprintf(f, "# scene");
    for (int m = 0; m < M_COUNT; m++)
        fprintf(f, " %s", method_names[m]);
    fprintf(f, "\n");
    for (int i = 0; i < ns; i++) {
        fprintf(f, "\"%s, %d nodes\"", sc[i].name, (int)sc[i].n);
        for (int m = 0; m < M_COUNT; m++)
            fprintf(f, isfinite(sc[i].us[m]) ? " %.6g" : " NaN", sc[i].us[m]);
        fprintf(f, "\n");
    }
    if (ftm_close_output(f, WHO, dat))
        return -1;
    f = fopen(gp, "w");
    if (!f)
        return -1;
    fprintf(f, "set terminal pngcairo size 1000,520 noenhanced font ',11'\nset output ");
    ftm_gnuplot_quote(f, png);
    fprintf(f, "\nset title 'ftm bench peers: one step, the same body, nodes and links (median)'\n"
               "set style data histograms\nset style histogram clustered gap 1\n"
               "set style fill solid 0.85 border -1\nset boxwidth 0.9\nset logscale y\n"
               "set ylabel 'us per step'\nset grid ytics\nset key top left\nset yrange [1:*]\n");
    static const char *const titles[M_COUNT] = {
        "FTM springs, full depth", "FTM linear FEM forces", "FTM co-rotational FEM forces",
        "Bullet btSoftBody, body step", "Bullet btSoftBody, world step"};
    static const char *const colours[M_COUNT] = {"#1f77b4", "#6baed6", "#9467bd", "#d62728",
                                                 "#ff9896"};
    fprintf(f, "plot ");
    for (int m = 0; m < M_COUNT; m++) {
        fprintf(f, "%s", m ? ", " : "");
        ftm_gnuplot_quote(f, dat);
        fprintf(f, " using %d:xtic(1) title '%s' lc rgb '%s'", m + 2, titles[m], colours[m]);
    }
    /* the figures over the bars: a cluster of M_COUNT bars and a gap of one */
    for (int m = 0; m < M_COUNT; m++) {
        fprintf(f, ", ");
        ftm_gnuplot_quote(f, dat);
        fprintf(f, " using ($0 + %g):%d:(sprintf('%%.3g', $%d)) with labels offset 0,0.7 "
                   "font ',9' notitle", (m - (M_COUNT - 1) / 2.0) / (M_COUNT + 1), m + 2, m + 2);
    }
    fprintf(f, "\n");
    if (ftm_close_output(f, WHO, gp))
        return -1;
    return ftm_gnuplot_run(WHO, gp) < 0 ? -1 : 0;
}

static void print_header(FILE *f, const options *o)
{
#ifdef FTM_HAVE_BULLET
    fprintf(f, "FTM (force transmittal, full depth) against Bullet %s's btSoftBody (%s):\n",
            ftm_peer_bullet_version(), ftm_peer_bullet_scalar());
#else
    fprintf(f, "FTM (force transmittal, full depth); Bullet not built in: its columns empty.\n");
#endif
    fprintf(f, "The same nodes, lumped masses, links and loads. u: static displacement of the\n"
               "loaded nodes along the load (Bullet's kLST = c k h^2 (1/m_a + 1/m_b), c tuned to\n"
               "match; field: ||u_Bullet - u_FTM|| / ||u_FTM||). Median step [us] over %d\n"
               "rounds of every method in turn.\n\n", o->rounds);
}

static void usage(FILE *f)
{
    fprintf(f,
            "usage: ftm bench peers [--scene cube|organ|tiny|all] [--rounds N] [--json]\n"
            "                       [--plot PNG] [--save PREFIX]\n"
            "\n"
            "FTM against Bullet's soft body (btSoftBody) on the bodies of ftm bench accuracy:\n"
            "the same nodes, masses, links and loads; Bullet's link stiffness tuned until its\n"
            "static displacement of the loaded nodes is FTM's springs' at full depth; then the\n"
            "median step of each, run alternately (docs/peers.md).\n"
            "  --scene    cube (the elastin cube, 1000 nodes), organ (the kidney, 10606), tiny\n"
            "             (the cube with 4 x 4 x 4 nodes, for tests), all (default: cube, organ)\n"
            "  --rounds   rounds of every method in turn (default 9)\n"
            "  --json     print {\"scenes\":[{\"scene\",\"ftm_us\",\"bullet_us\",\"ratio\",...}]}\n"
            "  --plot PNG the median steps as bars (gnuplot; PNG.dat and PNG.gp beside it)\n"
            "  --save P   also write the table to P.txt and the JSON to P.json\n"
            "Built without Bullet (Debian: libbullet-dev), it measures FTM's side and says so.\n"
            "exit status: 0 success, 1 a run failed, 2 bad arguments or an output that cannot\n"
            "be written\n");
}

int ftm_bench_peers(int argc, char **argv)
{
    options o = {.rounds = 9};
    const char *which = "all";
    for (int i = 1; i < argc; i++) {
        const char *a = argv[i];
        bool more = i + 1 < argc;
        if (strcmp(a, "--help") == 0 || strcmp(a, "-h") == 0) {
            usage(stdout);
            return 0;
        } else if (strcmp(a, "--json") == 0) {
            o.json = true;
        } else if (strcmp(a, "--scene") == 0 && more) {
            which = argv[++i];
        } else if (strcmp(a, "--rounds") == 0 && more) {
            if (!ftm_cli_int(argv[++i], 1, 999, &o.rounds)) {
                fprintf(stderr, "%s: --rounds must be an integer in 1..999 (got '%s')\n", WHO,
                        argv[i]);
                return 2;
            }
        } else if (strcmp(a, "--plot") == 0 && more) {
            o.plot = argv[++i];
        } else if (strcmp(a, "--save") == 0 && more) {
            o.save = argv[++i];
        } else {
            fprintf(stderr, "%s: unknown option '%s' (or it needs a value)\n", WHO, a);
            usage(stderr);
            return 2;
        }
    }
    o.cube = strcmp(which, "cube") == 0 || strcmp(which, "all") == 0;
    o.organ = strcmp(which, "organ") == 0 || strcmp(which, "all") == 0;
    o.tiny = strcmp(which, "tiny") == 0;
    if (!o.cube && !o.organ && !o.tiny) {
        fprintf(stderr, "%s: --scene must be cube, organ, tiny or all (got '%s')\n", WHO, which);
        return 2;
    }
#ifdef FTM_HAVE_BULLET
    const bool bullet = true;
#else
    const bool bullet = false;
    fprintf(stderr, "%s: built without Bullet (Debian: libbullet-dev, then configure again): "
                    "FTM's side only\n", WHO);
#endif
    /* the --save files first, so that a bad path fails before the runs */
    FILE *outs[2] = {NULL, NULL};
    char paths[2][4096];
    for (int k = 0; k < 2 && o.save; k++) {
        snprintf(paths[k], sizeof paths[k], "%s%s", o.save, k ? ".json" : ".txt");
        if (!(outs[k] = fopen(paths[k], "w"))) {
            fprintf(stderr, "%s: %s: cannot write: %s\n", WHO, paths[k], strerror(errno));
            if (k)
                fclose(outs[0]);
            return 2;
        }
    }
    scene sc[3];
    int ns = 0, rc = FTM_OK;
    const char *names[3] = {o.tiny ? "tiny" : NULL, o.cube ? "cube" : NULL,
                            o.organ ? "organ" : NULL};
    for (int k = 0; k < 3 && !rc; k++) {
        if (!names[k])
            continue;
        ftm_error err;
        scene *s = &sc[ns];
        if ((rc = scene_make(s, names[k], &err)) != FTM_OK) {
            fprintf(stderr, "%s: %s: %s\n", WHO, names[k], err.message);
            scene_free(s);
            break;
        }
        ns++;
        if (!o.json)
            fprintf(stderr, "%s: %s: %d nodes, %d links ...\n", WHO, s->name, (int)s->n,
                    (int)s->links);
        rc = run_scene(s, &o);
    }
    int status = rc ? 1 : 0;
    if (!rc) {
        if (o.json) {
            print_json(stdout, sc, ns, &o, bullet);
        } else {
            print_header(stdout, &o);
            print_table(stdout, sc, ns, bullet);
        }
        for (int k = 0; k < 2 && outs[k]; k++) {
            if (k)
                print_json(outs[k], sc, ns, &o, bullet);
            else {
                print_header(outs[k], &o);
                print_table(outs[k], sc, ns, bullet);
            }
        }
        if (o.plot && plot(o.plot, sc, ns) < 0)
            fprintf(stderr, "%s: could not draw %s\n", WHO, o.plot);
    }
    for (int k = 0; k < 2; k++)
        if (outs[k] && ftm_close_output(outs[k], WHO, paths[k]))
            status = 2;
    for (int k = 0; k < ns; k++)
        scene_free(&sc[k]);
    return status;
}
