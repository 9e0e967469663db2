/* SPDX-License-Identifier: GPL-3.0-or-later */
/* Compares FTM with the CalculiX references kept in tests/calculix/ref
 * (docs/calculix.md). The references are ccx's .dat output of the decks
 * ccx_deck wrote from the same scenes: the displacement U of every node and
 * the reaction RF of the displacement-loaded nodes (set PRESS), printed
 * with 7 significant digits (relative rounding <= 5e-7).
 *
 *   ccx_compare fem SCENE REF.dat [--tol T]
 *       the linear static FEM (ftm_fem, as `ftm fem` solves it) against a
 *       linear reference: displacements and the reaction at PRESS.
 *   ccx_compare csv SCENE REF.dat CSV [--tol T]
 *       the displacements of `ftm fem SCENE --csv CSV` against it.
 *   ccx_compare forces SCENE REF.dat --forces F [--tol T]
 *       FTM's element forces (ftm_sim_internal_forces) at CalculiX's
 *       equilibrium positions: at PRESS they must be CalculiX's reactions,
 *       at every free node zero, or the force load on it (relative to the
 *       total reaction).
 *   ccx_compare sim SCENE REF.dat [--forces F] [--depth D] [--order O]
 *                   [--far-field fixed|elastic] [--settle T] [--max-steps N]
 *                   [--tol-force T] [--tol-u T] [--tol-dent T]
 *       the simulation run as the scene scripts it, then until every node
 *       moves less than T (default 1e-10) times the mesh spacing per step:
 *       its equilibrium against the reference (force at the probe,
 *       displacements of all nodes and of the dent: the top-face nodes within
 *       two cells of the press, relative L2), with the steps and the median
 *       step time (a measurement, not asserted).
 *   ccx_compare dat A.dat B.dat [--tol T]
 *       two .dat files (a stored reference and a fresh ccx run).
 *
 * --json prints the figures as one JSON object. Exit status: 0 within the
 * tolerances, 1 outside them, 2 bad arguments or files, 3 the simulation
 * failed (FTM_EUNSTABLE) or did not settle. */
#include "ftm/fem.h"
#include "ftm/ftm.h"

#include <errno.h>
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <time.h>

/* ---- ccx .dat ---- */

typedef struct ccx_result {
    int32_t nodes;  /* highest node id seen */
    double *u;      /* 3 per node id - 1 (NAN where not printed) */
    int32_t npress; /* RF rows */
    int32_t *press; /* node ids - 1 */
    double *rf;     /* 3 per RF row */
    double total[3];
    bool has_total;
    double time;
} ccx_result;

static void ccx_free(ccx_result *r)
{
    free(r->u);
    free(r->press);
    free(r->rf);
}

/* Keeps the last block of each kind (the end of the step). */
static int ccx_read(const char *path, ccx_result *r)
{
    memset(r, 0, sizeof *r);
    FILE *f = fopen(path, "r");
    if (!f) {
        fprintf(stderr, "ccx_compare: %s: %s\n", path, strerror(errno));
        return 2;
    }
    char line[512];
    enum { NONE, DISP, FORCES, TOTAL } block = NONE;
    int32_t cap = 0, pcap = 0;
    while (fgets(line, sizeof line, f)) {
        double t;
        if (sscanf(line, " displacements (vx,vy,vz) for set %*s and time %lf", &t) == 1) {
            block = DISP;
            r->time = t;
            for (int32_t k = 0; k < 3 * cap; k++)
                r->u[k] = NAN;
            continue;
        }
        if (sscanf(line, " forces (fx,fy,fz) for set %*s and time %lf", &t) == 1) {
            block = FORCES;
            r->npress = 0;
            continue;
        }
        if (sscanf(line, " total force (fx,fy,fz) for set %*s and time %lf", &t) == 1) {
            block = TOTAL;
            continue;
        }
        int id;
        double v[3];
        if (block == DISP && sscanf(line, "%d %lf %lf %lf", &id, &v[0], &v[1], &v[2]) == 4) {
            if (id < 1 || id > 100000000)
                goto bad;
            if (id > cap) {
                int32_t nc = cap ? cap : 1024;
                while (nc < id)
                    nc *= 2;
                double *u = realloc(r->u, 3 * (size_t)nc * sizeof *u);
                if (!u)
                    goto bad;
                for (int32_t k = 3 * cap; k < 3 * nc; k++)
                    u[k] = NAN;
                r->u = u;
                cap = nc;
            }
            memcpy(r->u + 3 * (id - 1), v, sizeof v);
            if (id > r->nodes)
                r->nodes = id;
        } else if (block == FORCES &&
                   sscanf(line, "%d %lf %lf %lf", &id, &v[0], &v[1], &v[2]) == 4) {
            if (r->npress == pcap) {
                pcap = pcap ? 2 * pcap : 64;
                int32_t *p = realloc(r->press, (size_t)pcap * sizeof *p);
                double *g = realloc(r->rf, 3 * (size_t)pcap * sizeof *g);
                if (p)
                    r->press = p;
                if (g)
                    r->rf = g;
                if (!p || !g)
                    goto bad;
            }
            r->press[r->npress] = id - 1;
            memcpy(r->rf + 3 * r->npress, v, sizeof v);
            r->npress++;
        } else if (block == TOTAL && sscanf(line, "%lf %lf %lf", &v[0], &v[1], &v[2]) == 3) {
            memcpy(r->total, v, sizeof v);
            r->has_total = true;
            block = NONE;
        }
    }
    fclose(f);
    if (r->nodes == 0) {
        fprintf(stderr, "ccx_compare: %s: no displacements\n", path);
        ccx_free(r);
        return 2;
    }
    return 0;
bad:
    fclose(f);
    fprintf(stderr, "ccx_compare: %s: bad line or out of memory: %s", path, line);
    ccx_free(r);
    return 2;
}

/* ---- comparisons ---- */

typedef struct figures {
    double u_rel_l2, u_rel_max; /* all nodes */
    double dent_rel_l2;         /* top-face nodes near the press */
    int32_t dent_nodes;
    double force[3], force_ref[3];
    double force_rel;    /* |F - F_ref| / |F_ref| */
    double force_signed; /* (F - F_ref) . F_ref / |F_ref|^2 */
    double max_u_ref;
} figures;

/* Smallest link rest length: the lattice spacing. */
static double spacing(const ftm_mesh *m)
{
    double s = INFINITY;
    for (int32_t l = 0; l < ftm_mesh_link_count(m); l++) {
        int32_t a, b;
        double k, len;
        ftm_mesh_link(m, l, &a, &b, &k, &len);
        s = len < s ? len : s;
    }
    return s;
}

/* u: 3 per mesh index. The dent: nodes at the pressed nodes' height
 * (within 1e-6 of the spacing) within 2 spacings of one of them across. */
static int compare_u(const ftm_mesh *m, const ccx_result *r, const double *u, const int32_t *press,
                     int32_t npress, figures *fg)
{
    const int32_t n = ftm_mesh_node_count(m);
    if (r->nodes != n) {
        fprintf(stderr, "ccx_compare: the reference has %d nodes, the scene %d\n", (int)r->nodes,
                (int)n);
        return 2;
    }
    const double h = spacing(m);
    double num = 0, den = 0, dmax = 0, umax = 0, dn = 0, dd = 0;
    fg->dent_nodes = 0;
    for (int32_t in = 0; in < n; in++) {
        const int32_t v = ftm_mesh_node_of_input(m, in);
        const double *ref = r->u + 3 * in, *uv = u + 3 * (size_t)v;
        if (!isfinite(ref[0])) {
            fprintf(stderr, "ccx_compare: the reference lacks node %d\n", (int)in + 1);
            return 2;
        }
        ftm_vec3 X = ftm_mesh_rest_position(m, v);
        bool dent = false;
        for (int32_t k = 0; k < npress && !dent; k++) {
            ftm_vec3 P = ftm_mesh_rest_position(m, press[k]);
            double dx = X.x - P.x, dy = X.y - P.y;
            dent = fabs(X.z - P.z) <= 1e-6 * h && sqrt(dx * dx + dy * dy) <= 2.0 * h * (1 + 1e-9);
        }
        double e2 = 0, r2 = 0;
        for (int c = 0; c < 3; c++) {
            e2 += (uv[c] - ref[c]) * (uv[c] - ref[c]);
            r2 += ref[c] * ref[c];
        }
        num += e2;
        den += r2;
        dmax = fmax(dmax, sqrt(e2));
        umax = fmax(umax, sqrt(r2));
        if (dent) {
            dn += e2;
            dd += r2;
            fg->dent_nodes++;
        }
    }
    fg->u_rel_l2 = den > 0 ? sqrt(num / den) : sqrt(num);
    fg->u_rel_max = umax > 0 ? dmax / umax : dmax;
    fg->dent_rel_l2 = dd > 0 ? sqrt(dn / dd) : 0;
    fg->max_u_ref = umax;
    return 0;
}

static void compare_force(const double f[3], const double ref[3], figures *fg)
{
    double d2 = 0, r2 = 0, dot = 0;
    for (int c = 0; c < 3; c++) {
        fg->force[c] = f[c];
        fg->force_ref[c] = ref[c];
        d2 += (f[c] - ref[c]) * (f[c] - ref[c]);
        r2 += ref[c] * ref[c];
        dot += (f[c] - ref[c]) * ref[c];
    }
    fg->force_rel = sqrt(d2 / r2);
    fg->force_signed = dot / r2;
}

/* The displacement-loaded nodes of the scene (mesh indices), once each. */
static int32_t scene_press(const ftm_scene *sc, int32_t *out)
{
    int32_t n = 0;
    const ftm_scene_load *l = ftm_scene_loads(sc);
    for (int32_t k = 0; k < ftm_scene_load_count(sc); k++) {
        if (l[k].contact.kind != FTM_CONTACT_DISPLACEMENT)
            continue;
        bool seen = false;
        for (int32_t j = 0; j < n; j++)
            seen = seen || out[j] == l[k].contact.node;
        if (!seen)
            out[n++] = l[k].contact.node;
    }
    return n;
}

/* The reference's reaction at the scene's PRESS nodes: CalculiX's RF is the
 * force the support puts on the body; FTM's reaction is the force on the
 * probe, its negative. */
static int reference_force(const ccx_result *r, double out[3])
{
    if (!r->has_total) {
        fprintf(stderr, "ccx_compare: the reference has no total RF\n");
        return 2;
    }
    for (int c = 0; c < 3; c++)
        out[c] = -r->total[c];
    return 0;
}

/* ---- options ---- */

typedef struct options {
    const char *mode, *scene, *ref, *extra;
    double tol, tol_force, tol_u, tol_dent, settle;
    bool forces_set, json;
    ftm_forces forces;
    int far_field; /* -1: the scene's */
    int32_t depth, max_steps;
    int order;
} options;

static int usage(void)
{
    fprintf(stderr,
            "usage: ccx_compare fem SCENE REF.dat [--tol T]\n"
            "       ccx_compare csv SCENE REF.dat CSV [--tol T]\n"
            "       ccx_compare forces SCENE REF.dat --forces F [--tol T]\n"
            "       ccx_compare sim SCENE REF.dat [--forces F] [--depth D] [--order O]\n"
            "                   [--far-field fixed|elastic] [--tol-dent T]\n"
            "                   [--settle T] [--max-steps N] [--tol-force T] [--tol-u T]\n"
            "       ccx_compare dat A.dat B.dat [--tol T]\n"
            "       (any mode: --json)\n");
    return 2;
}

static bool number(const char *s, double *v)
{
    char *end;
    errno = 0;
    *v = strtod(s, &end);
    return *s && !*end && errno == 0 && isfinite(*v);
}

static int parse(int argc, char **argv, options *o)
{
    memset(o, 0, sizeof *o);
    o->tol = o->tol_force = o->tol_u = o->tol_dent = INFINITY;
    o->settle = 1e-10;
    o->depth = -1;
    o->order = -1;
    o->far_field = -1;
    o->max_steps = 2000000;
    if (argc < 4)
        return usage();
    o->mode = argv[1];
    o->scene = argv[2];
    o->ref = argv[3];
    int i = 4;
    if (strcmp(o->mode, "csv") == 0) {
        if (argc < 5)
            return usage();
        o->extra = argv[i++];
    }
    for (; i < argc; i++) {
        const char *a = argv[i];
        double v;
        if (strcmp(a, "--json") == 0) {
            o->json = true;
            continue;
        }
        if (i + 1 >= argc)
            return usage();
        const char *b = argv[++i];
        if (strcmp(a, "--forces") == 0) {
            static const char *const names[] = {"springs", "linear-fem", "corot-fem",
                                                "neo-hookean"};
            int k = 0;
            while (k < 4 && strcmp(b, names[k]) != 0)
                k++;
            if (k == 4)
                return usage();
            o->forces = (ftm_forces)k;
            o->forces_set = true;
        } else if (strcmp(a, "--far-field") == 0) {
            if (strcmp(b, "fixed") == 0)
                o->far_field = FTM_FAR_FIELD_FIXED;
            else if (strcmp(b, "elastic") == 0)
                o->far_field = FTM_FAR_FIELD_ELASTIC;
            else
                return usage();
        } else if (strcmp(a, "--order") == 0) {
            static const char *const names[] = {"colored", "bfs", "jacobi"};
            static const int values[] = {FTM_ORDER_LAYER_COLORED, FTM_ORDER_BFS,
                                         FTM_ORDER_LAYER_JACOBI};
            o->order = -1;
            for (int k = 0; k < 3; k++)
                if (strcmp(b, names[k]) == 0)
                    o->order = values[k];
            if (o->order < 0)
                return usage();
        } else if (!number(b, &v)) {
            return usage();
        } else if (strcmp(a, "--tol") == 0) {
            o->tol = v;
        } else if (strcmp(a, "--tol-force") == 0) {
            o->tol_force = v;
        } else if (strcmp(a, "--tol-u") == 0) {
            o->tol_u = v;
        } else if (strcmp(a, "--tol-dent") == 0) {
            o->tol_dent = v;
        } else if (strcmp(a, "--settle") == 0 && v > 0) {
            o->settle = v;
        } else if (strcmp(a, "--depth") == 0 && v >= 0 && v <= 1e6 && v == floor(v)) {
            o->depth = (int32_t)v;
        } else if (strcmp(a, "--max-steps") == 0 && v >= 1 && v <= 2e9 && v == floor(v)) {
            o->max_steps = (int32_t)v;
        } else {
            return usage();
        }
    }
    return 0;
}

static bool within(double value, double tol, const char *what)
{
    bool ok = value <= tol; /* NaN fails */
    if (!ok)
        fprintf(stderr, "ccx_compare: %s %.3g exceeds the tolerance %.3g\n", what, value, tol);
    return ok;
}

static void print_force(const figures *fg)
{
    printf("force        FTM %.7g %.7g %.7g N, CalculiX %.7g %.7g %.7g N\n", fg->force[0],
           fg->force[1], fg->force[2], fg->force_ref[0], fg->force_ref[1], fg->force_ref[2]);
    printf("force error  %.3g relative (%+.4g %% along CalculiX's force)\n", fg->force_rel,
           100.0 * fg->force_signed);
}

static void print_u(const figures *fg)
{
    printf("u error      %.3g relative L2, %.3g max (largest |u| %.6g m)\n", fg->u_rel_l2,
           fg->u_rel_max, fg->max_u_ref);
    printf("dent error   %.3g relative L2 over %d top-face nodes within 2 cells\n",
           fg->dent_rel_l2, (int)fg->dent_nodes);
}

static void json_figures(const figures *fg, bool force)
{
    printf("\"u_rel_l2\":%.6g,\"u_rel_max\":%.6g,\"dent_rel_l2\":%.6g,\"dent_nodes\":%d,"
           "\"max_u_ref\":%.9g",
           fg->u_rel_l2, fg->u_rel_max, fg->dent_rel_l2, (int)fg->dent_nodes, fg->max_u_ref);
    if (force)
        printf(",\"force\":[%.9g,%.9g,%.9g],\"force_ref\":[%.9g,%.9g,%.9g],\"force_rel\":%.6g,"
               "\"force_signed\":%.6g",
               fg->force[0], fg->force[1], fg->force[2], fg->force_ref[0], fg->force_ref[1],
               fg->force_ref[2], fg->force_rel, fg->force_signed);
}

/* ---- modes ---- */

/* Per-element materials from the scene's [fem LABEL] sections, as `ftm fem`
 * gives them (the label's section, else [fem]): one per hexahedron (hex)
 * or tetrahedron. *out NULL without sections; false when out of memory. */
static bool element_materials(const ftm_scene *sc, bool hex, ftm_fem_material **out)
{
    const ftm_mesh *m = ftm_scene_mesh(sc);
    int32_t nsec = 0;
    const ftm_label_material *sec = ftm_scene_label_materials(sc, &nsec);
    *out = NULL;
    if (nsec == 0)
        return true;
    const int32_t ne = hex ? ftm_mesh_hexahedron_count(m) : ftm_mesh_tetrahedron_count(m);
    ftm_fem_material *mat = malloc(((size_t)ne + 1) * sizeof *mat);
    if (!mat)
        return false;
    ftm_fem_material base = ftm_default_fem_material();
    ftm_scene_fem_material(sc, &base.young, &base.poisson, NULL);
    for (int32_t e = 0; e < ne; e++) {
        int32_t label = hex ? ftm_mesh_hexahedron_label(m, e) : ftm_mesh_tetrahedron_label(m, e);
        mat[e] = base;
        for (int32_t i = 0; i < nsec; i++)
            if (label > 0 && sec[i].label == label) {
                mat[e].young = sec[i].young;
                mat[e].poisson = sec[i].poisson;
            }
    }
    *out = mat;
    return true;
}

static int mode_fem(const options *o, const ftm_scene *sc, const ccx_result *r)
{
    const ftm_mesh *m = ftm_scene_mesh(sc);
    const int32_t n = ftm_mesh_node_count(m);
    ftm_fem_def d = ftm_default_fem_def();
    ftm_scene_fem_material(sc, &d.material.young, &d.material.poisson, NULL);
    ftm_fem_material *hexm = NULL, *tetm = NULL;
    if (!element_materials(sc, true, &hexm) || !element_materials(sc, false, &tetm)) {
        free(hexm);
        fprintf(stderr, "ccx_compare: out of memory\n");
        return 2;
    }
    d.hex_materials = hexm;
    d.tet_materials = tetm;
    double *f = calloc(3 * (size_t)n, sizeof *f), *pre = calloc(3 * (size_t)n, sizeof *pre);
    double *u = calloc(3 * (size_t)n, sizeof *u), *res = calloc(3 * (size_t)n, sizeof *res);
    bool *con = calloc(3 * (size_t)n, sizeof *con);
    int32_t *press = malloc(((size_t)ftm_scene_load_count(sc) + 1) * sizeof *press);
    if (!f || !pre || !u || !res || !con || !press) {
        fprintf(stderr, "ccx_compare: out of memory\n");
        return 2;
    }
    const ftm_scene_load *l = ftm_scene_loads(sc);
    for (int32_t k = 0; k < ftm_scene_load_count(sc); k++) {
        const ftm_contact *c = &l[k].contact;
        double v[3] = {c->value.x, c->value.y, c->value.z};
        for (int q = 0; q < 3; q++) {
            if (c->kind == FTM_CONTACT_FORCE) {
                f[3 * c->node + q] += v[q];
            } else {
                pre[3 * c->node + q] = v[q];
                con[3 * c->node + q] = true;
            }
        }
    }
    int32_t np = scene_press(sc, press);
    d.constrained = con;
    ftm_fem *fem = NULL;
    ftm_error err;
    int rc = 0;
    if (ftm_fem_create(m, &d, &fem, &err) != FTM_OK ||
        ftm_fem_solve(fem, f, pre, u, &err) != FTM_OK) {
        fprintf(stderr, "ccx_compare: %s\n", err.message);
        rc = 2;
    }
    figures fg;
    memset(&fg, 0, sizeof fg);
    if (!rc)
        rc = compare_u(m, r, u, press, np, &fg);
    bool force = np > 0;
    if (!rc && force) {
        ftm_fem_residual(fem, u, f, res);
        double sum[3] = {0, 0, 0}, ref[3];
        for (int32_t k = 0; k < np; k++)
            for (int q = 0; q < 3; q++)
                sum[q] -= res[3 * press[k] + q]; /* K u at the probe: minus, on the probe */
        rc = reference_force(r, ref);
        if (!rc)
            compare_force(sum, ref, &fg);
    }
    if (!rc) {
        if (o->json) {
            printf("{\"mode\":\"fem\",");
            json_figures(&fg, force);
            printf("}\n");
        } else {
            print_u(&fg);
            if (force)
                print_force(&fg);
        }
        bool ok = within(fg.u_rel_max, o->tol, "displacement error (max)");
        if (force)
            ok = within(fg.force_rel, o->tol, "force error") && ok;
        rc = ok ? 0 : 1;
    }
    ftm_fem_destroy(fem);
    free(hexm);
    free(tetm);
    free(f);
    free(pre);
    free(u);
    free(res);
    free(con);
    free(press);
    return rc;
}

static int mode_csv(const options *o, const ftm_scene *sc, const ccx_result *r)
{
    const ftm_mesh *m = ftm_scene_mesh(sc);
    const int32_t n = ftm_mesh_node_count(m);
    FILE *f = fopen(o->extra, "r");
    if (!f) {
        fprintf(stderr, "ccx_compare: %s: %s\n", o->extra, strerror(errno));
        return 2;
    }
    double *u = malloc(3 * (size_t)n * sizeof *u);
    int32_t *press = malloc(((size_t)ftm_scene_load_count(sc) + 1) * sizeof *press);
    char line[512];
    int32_t rows = 0;
    int rc = u && press && fgets(line, sizeof line, f) ? 0 : 2; /* header */
    while (!rc && fgets(line, sizeof line, f)) {
        int id;
        double x, y, z, v[3];
        if (sscanf(line, "%d,%lf,%lf,%lf,%lf,%lf,%lf", &id, &x, &y, &z, &v[0], &v[1], &v[2]) != 7 ||
            id < 0 || id >= n) {
            fprintf(stderr, "ccx_compare: %s: bad row %s", o->extra, line);
            rc = 2;
            break;
        }
        memcpy(u + 3 * (size_t)ftm_mesh_node_of_input(m, id), v, sizeof v);
        rows++;
    }
    fclose(f);
    if (!rc && rows != n) {
        fprintf(stderr, "ccx_compare: %s: %d rows for %d nodes\n", o->extra, (int)rows, (int)n);
        rc = 2;
    }
    figures fg;
    memset(&fg, 0, sizeof fg);
    if (!rc)
        rc = compare_u(m, r, u, press, scene_press(sc, press), &fg);
    if (!rc) {
        if (o->json) {
            printf("{\"mode\":\"csv\",");
            json_figures(&fg, false);
            printf("}\n");
        } else {
            print_u(&fg);
        }
        rc = within(fg.u_rel_max, o->tol, "displacement error (max)") ? 0 : 1;
    }
    free(u);
    free(press);
    return rc;
}

static void log_to_stderr(void *user, ftm_log_level level, const char *message)
{
    (void)user;
    if (level >= FTM_LOG_WARN)
        fprintf(stderr, "ftm: %s\n", message);
}

/* The scene's simulation with the options' overrides; warnings to stderr
 * when log (low damping, guard events). */
static ftm_sim *make_sim(const options *o, const ftm_scene *sc, bool log, ftm_sim_def *def,
                         ftm_error *err)
{
    ftm_sim_def d = ftm_scene_sim_def(sc);
    if (o->forces_set) {
        d.forces = o->forces;
        if (d.forces != FTM_FORCES_SPRINGS && d.young == 0.0) { /* [fem] but forces = springs */
            ftm_scene_fem_material(sc, &d.young, &d.poisson, &d.density);
            d.label_materials = ftm_scene_label_materials(sc, &d.label_material_count);
        }
    }
    if (o->depth >= 0)
        d.depth = o->depth;
    if (o->order >= 0)
        d.order = (ftm_order)o->order;
    if (o->far_field >= 0)
        d.far_field = (ftm_far_field)o->far_field;
    if (log)
        d.log = log_to_stderr;
    ftm_sim *sim = NULL;
    if (ftm_sim_create(ftm_scene_mesh(sc), &d, &sim, err) != FTM_OK)
        return NULL;
    if (def)
        *def = d;
    return sim;
}

static int mode_forces(const options *o, const ftm_scene *sc, const ccx_result *r)
{
    const ftm_mesh *m = ftm_scene_mesh(sc);
    const int32_t n = ftm_mesh_node_count(m);
    ftm_error err;
    ftm_sim *sim = make_sim(o, sc, false, NULL, &err);
    if (!sim) {
        fprintf(stderr, "ccx_compare: %s\n", err.message);
        return 2;
    }
    if (r->nodes != n || !r->has_total) {
        fprintf(stderr, "ccx_compare: the reference has %d nodes (the scene %d) or no RF\n",
                (int)r->nodes, (int)n);
        ftm_sim_destroy(sim);
        return 2;
    }
    double *x = malloc(3 * (size_t)n * sizeof *x), *f = malloc(3 * (size_t)n * sizeof *f);
    bool *pressed = calloc((size_t)n + 1, 1);
    int rc = x && f && pressed ? 0 : 2;
    for (int32_t in = 0; !rc && in < n; in++) {
        const int32_t v = ftm_mesh_node_of_input(m, in);
        ftm_vec3 X = ftm_mesh_rest_position(m, v);
        x[3 * v] = X.x + r->u[3 * in];
        x[3 * v + 1] = X.y + r->u[3 * in + 1];
        x[3 * v + 2] = X.z + r->u[3 * in + 2];
    }
    if (!rc && (rc = ftm_sim_internal_forces(sim, x, f)) != FTM_OK) {
        fprintf(stderr, "ccx_compare: internal forces: %s\n", ftm_strerror(rc));
        rc = 2;
    }
    double dmax = 0, fmaxv = 0, resid = 0, tot = 0;
    int32_t worst = -1;
    for (int c = 0; c < 3; c++)
        tot += r->total[c] * r->total[c];
    tot = sqrt(tot);
    for (int32_t k = 0; !rc && k < r->npress; k++) {
        const int32_t in = r->press[k], v = ftm_mesh_node_of_input(m, in);
        pressed[v] = true;
        double d2 = 0, f2 = 0;
        for (int c = 0; c < 3; c++) {
            d2 += (f[3 * v + c] - r->rf[3 * k + c]) * (f[3 * v + c] - r->rf[3 * k + c]);
            f2 += r->rf[3 * k + c] * r->rf[3 * k + c];
        }
        dmax = fmax(dmax, sqrt(d2));
        fmaxv = fmax(fmaxv, sqrt(f2));
    }
    /* a node loaded by a force holds it: there the internal force is the
     * load's full value (CalculiX applies it in full at the end of the step) */
    const ftm_scene_load *l = ftm_scene_loads(sc);
    for (int32_t k = 0; !rc && k < ftm_scene_load_count(sc); k++)
        if (l[k].contact.kind == FTM_CONTACT_FORCE) {
            const int32_t v = l[k].contact.node;
            f[3 * v] -= l[k].contact.value.x;
            f[3 * v + 1] -= l[k].contact.value.y;
            f[3 * v + 2] -= l[k].contact.value.z;
        }
    for (int32_t v = 0; !rc && v < n; v++) {
        if (pressed[v] || ftm_mesh_fixed(m, v))
            continue;
        double f2 = f[3 * v] * f[3 * v] + f[3 * v + 1] * f[3 * v + 1] + f[3 * v + 2] * f[3 * v + 2];
        if (sqrt(f2) > resid) {
            resid = sqrt(f2);
            worst = ftm_mesh_input_of_node(m, v);
        }
    }
    if (!rc) {
        double e = dmax / fmaxv, res_rel = resid / tot;
        if (o->json)
            printf("{\"mode\":\"forces\",\"press_rel_max\":%.6g,\"free_residual_rel\":%.6g}\n", e,
                   res_rel);
        else
            printf("forces       at PRESS: %.3g of the largest reaction (max); free nodes: "
                   "residual %.3g of the total reaction (node %d)\n",
                   e, res_rel, (int)worst);
        bool ok = within(e, o->tol, "force error at PRESS");
        ok = within(res_rel, o->tol, "free-node residual") && ok;
        rc = ok ? 0 : 1;
    }
    free(x);
    free(f);
    free(pressed);
    ftm_sim_destroy(sim);
    return rc;
}

static double now(void)
{
    struct timespec ts;
    clock_gettime(CLOCK_MONOTONIC, &ts);
    return (double)ts.tv_sec + 1e-9 * (double)ts.tv_nsec;
}

static int cmp_double(const void *a, const void *b)
{
    double x = *(const double *)a, y = *(const double *)b;
    return (x > y) - (x < y);
}

static double median(double *v, int32_t n)
{
    qsort(v, (size_t)n, sizeof *v, cmp_double);
    return n % 2 ? v[n / 2] : 0.5 * (v[n / 2 - 1] + v[n / 2]);
}

static int mode_sim(const options *o, const ftm_scene *sc, const ccx_result *r)
{
    const ftm_mesh *m = ftm_scene_mesh(sc);
    const int32_t n = ftm_mesh_node_count(m), nl = ftm_scene_load_count(sc);
    ftm_sim_def d;
    ftm_error err;
    ftm_sim *sim = make_sim(o, sc, true, &d, &err);
    if (!sim) {
        fprintf(stderr, "ccx_compare: %s\n", err.message);
        return 2;
    }
    const double h = d.time_step, tol = o->settle * spacing(m);
    double t_end = 0; /* when the script stops changing */
    const ftm_scene_load *l = ftm_scene_loads(sc);
    for (int32_t k = 0; k < nl; k++)
        t_end = fmax(t_end, l[k].ramp == FTM_RAMP_CONSTANT ? l[k].start : l[k].end);
    ftm_contact *c = malloc(((size_t)nl + 1) * sizeof *c);
    int32_t *press = malloc(((size_t)nl + 1) * sizeof *press);
    double *u = malloc(3 * (size_t)n * sizeof *u);
    if (!c || !press || !u) {
        fprintf(stderr, "ccx_compare: out of memory\n");
        return 2;
    }
    int32_t np = scene_press(sc, press), steps = 0, settled_at = -1, ns = 0, scap = 0;
    double *samples = NULL; /* each step's time [us] */
    int rc = 0;
    for (; steps < o->max_steps; steps++) {
        double t = steps * h;
        int32_t nc = ftm_scene_contacts_at(sc, t, c, nl);
        if (ftm_sim_set_contacts(sim, c, nc, &err) != FTM_OK) {
            fprintf(stderr, "ccx_compare: %s\n", err.message);
            rc = 2;
            break;
        }
        double t1 = now();
        int s = ftm_sim_step(sim);
        if (ns == scap) {
            scap = scap ? 2 * scap : 4096;
            double *ss = realloc(samples, (size_t)scap * sizeof *ss);
            if (!ss) {
                fprintf(stderr, "ccx_compare: out of memory\n");
                rc = 2;
                break;
            }
            samples = ss;
        }
        samples[ns++] = 1e6 * (now() - t1);
        if (s != FTM_OK) {
            fprintf(stderr, "ccx_compare: step %d: %s\n", (int)steps, ftm_strerror(s));
            rc = 3;
            break;
        }
        if (t < t_end)
            continue;
        const double *x = ftm_sim_positions(sim), *xp = ftm_sim_previous_positions(sim);
        double mm = 0;
        for (int32_t k = 0; k < 3 * n; k++)
            mm = fmax(mm, fabs(x[k] - xp[k]));
        if (mm < tol) {
            settled_at = steps + 1;
            break;
        }
    }
    if (!rc && settled_at < 0) {
        fprintf(stderr, "ccx_compare: did not settle within %d steps\n", (int)o->max_steps);
        rc = 3;
    }
    figures fg;
    memset(&fg, 0, sizeof fg);
    ftm_sim_stats st;
    ftm_sim_get_stats(sim, &st);
    if (!rc) {
        const double *x = ftm_sim_positions(sim);
        for (int32_t v = 0; v < n; v++) {
            ftm_vec3 X = ftm_mesh_rest_position(m, v);
            u[3 * v] = x[3 * v] - X.x;
            u[3 * v + 1] = x[3 * v + 1] - X.y;
            u[3 * v + 2] = x[3 * v + 2] - X.z;
        }
        rc = compare_u(m, r, u, press, np, &fg);
    }
    bool force = np > 0;
    if (!rc && force) {
        double sum[3] = {0, 0, 0}, ref[3];
        for (int32_t k = 0; k < nl; k++) { /* every group with displacement loads, once */
            int32_t g = l[k].contact.group;
            bool first = l[k].contact.kind == FTM_CONTACT_DISPLACEMENT;
            for (int32_t j = 0; j < k && first; j++)
                first = !(l[j].contact.kind == FTM_CONTACT_DISPLACEMENT && l[j].contact.group == g);
            if (first) {
                ftm_vec3 f = ftm_sim_reaction(sim, g);
                sum[0] += f.x;
                sum[1] += f.y;
                sum[2] += f.z;
            }
        }
        rc = reference_force(r, ref);
        if (!rc)
            compare_force(sum, ref, &fg);
    }
    const char *names[] = {"springs", "linear-fem", "corot-fem", "neo-hookean"};
    double step_us = ns ? median(samples, ns) : 0;
    free(samples);
    if (!rc) {
        if (o->json) {
            printf("{\"mode\":\"sim\",\"scene\":\"%s\",\"forces\":\"%s\",\"far_field\":\"%s\","
                   "\"depth\":%d,"
                   "\"region_nodes\":%d,\"time_step\":%.6g,\"critical_time_step\":%.6g,"
                   "\"steps\":%d,\"step_us\":%.4g,\"guard_events\":%llu,",
                   ftm_scene_name(sc), names[d.forces],
                   d.far_field == FTM_FAR_FIELD_ELASTIC ? "elastic" : "fixed", (int)d.depth,
                   (int)st.region_nodes, h,
                   ftm_sim_critical_time_step(sim), (int)settled_at, step_us,
                   (unsigned long long)st.guard_events);
            json_figures(&fg, force);
            printf("}\n");
        } else {
            printf("scene        %s, forces %s, depth %d (%d nodes in the region), far field %s\n",
                   ftm_scene_name(sc), names[d.forces], (int)d.depth, (int)st.region_nodes,
                   d.far_field == FTM_FAR_FIELD_ELASTIC ? "elastic" : "fixed");
            printf("steps        %d of %.3g s (critical %.3g s) to settle, %.1f us per step "
                   "(median), %llu guard events\n",
                   (int)settled_at, h, ftm_sim_critical_time_step(sim), step_us,
                   (unsigned long long)st.guard_events);
            print_u(&fg);
            if (force)
                print_force(&fg);
        }
        bool ok = within(fg.u_rel_max, o->tol_u, "displacement error (max)");
        ok = within(fg.dent_rel_l2, o->tol_dent, "dent error") && ok;
        if (force)
            ok = within(fg.force_rel, o->tol_force, "force error") && ok;
        rc = ok ? 0 : 1;
    }
    free(c);
    free(press);
    free(u);
    ftm_sim_destroy(sim);
    return rc;
}

static int mode_dat(const options *o)
{
    ccx_result a, b;
    if (ccx_read(o->scene, &a))
        return 2;
    if (ccx_read(o->ref, &b)) {
        ccx_free(&a);
        return 2;
    }
    int rc = 0;
    if (a.nodes != b.nodes || a.npress != b.npress || a.has_total != b.has_total) {
        fprintf(stderr, "ccx_compare: the two results differ in shape\n");
        rc = 1;
    }
    double du = 0, um = 0, df = 0, fm = 0;
    for (int32_t k = 0; !rc && k < 3 * a.nodes; k++) {
        du = fmax(du, fabs(a.u[k] - b.u[k]));
        um = fmax(um, fabs(b.u[k]));
    }
    for (int32_t k = 0; !rc && k < a.npress; k++)
        for (int c = 0; c < 3; c++) {
            df = fmax(df, fabs(a.rf[3 * k + c] - b.rf[3 * k + c]));
            fm = fmax(fm, fabs(b.rf[3 * k + c]));
        }
    if (!rc) {
        double eu = um > 0 ? du / um : du, ef = fm > 0 ? df / fm : df;
        if (o->json)
            printf("{\"mode\":\"dat\",\"u_rel_max\":%.6g,\"rf_rel_max\":%.6g}\n", eu, ef);
        else
            printf("dat          U differs by %.3g, RF by %.3g of the largest\n", eu, ef);
        bool ok = within(eu, o->tol, "displacement difference");
        ok = within(ef, o->tol, "reaction difference") && ok;
        rc = ok ? 0 : 1;
    }
    ccx_free(&a);
    ccx_free(&b);
    return rc;
}

int main(int argc, char **argv)
{
    options o;
    int rc = parse(argc, argv, &o);
    if (rc)
        return rc;
    if (strcmp(o.mode, "dat") == 0)
        return mode_dat(&o);
    bool known = strcmp(o.mode, "fem") == 0 || strcmp(o.mode, "csv") == 0 ||
                 strcmp(o.mode, "forces") == 0 || strcmp(o.mode, "sim") == 0;
    if (!known)
        return usage();
    ftm_error err;
    ftm_scene *sc = NULL;
    if (ftm_scene_load_file(o.scene, &sc, &err) != FTM_OK) {
        fprintf(stderr, "ccx_compare: %s\n", err.message);
        return 2;
    }
    if (!ftm_scene_fem_material(sc, NULL, NULL, NULL)) {
        fprintf(stderr, "ccx_compare: %s: no [fem] section\n", o.scene);
        ftm_scene_destroy(sc);
        return 2;
    }
    ccx_result r;
    if (ccx_read(o.ref, &r)) {
        ftm_scene_destroy(sc);
        return 2;
    }
    if (strcmp(o.mode, "fem") == 0)
        rc = mode_fem(&o, sc, &r);
    else if (strcmp(o.mode, "csv") == 0)
        rc = mode_csv(&o, sc, &r);
    else if (strcmp(o.mode, "forces") == 0)
        rc = o.forces_set ? mode_forces(&o, sc, &r) : usage();
    else
        rc = mode_sim(&o, sc, &r);
    ccx_free(&r);
    ftm_scene_destroy(sc);
    return rc;
}
