/* SPDX-License-Identifier: GPL-3.0-or-later */
/* ftm fem: the linear static FEM reference for a scene (docs/fem.md). */
#include "commands.h"

#include "ftm/fem.h"
#include "ftm/ftm.h"

#include <errno.h>
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

enum { EXIT_USAGE = 2 };

typedef struct fem_options {
    const char *scene;
    const char *csv; /* NULL = none, "-" = stdout */
    bool json;
    ftm_fem_factorization factor;
} fem_options;

static void usage(FILE *out)
{
    fprintf(out,
            "usage: ftm fem SCENE [options]\n"
            "\n"
            "Solves the linear static FEM reference for SCENE (a scene file or built-in\n"
            "name): the mesh's hexahedra (lattice3d) or tetrahedra (mesh file), the\n"
            "[fem] section's Young's modulus and Poisson's ratio, the fixed nodes as\n"
            "clamps, every force load at its full value and every displacement load as\n"
            "a prescribed displacement. Prints a summary (docs/fem.md).\n"
            "\n"
            "options:\n"
            "  --csv FILE       write node,x,y,z,ux,uy,uz per node in input order\n"
            "                   (\"-\": standard output, the summary goes to standard error)\n"
            "  --json           print the summary as one JSON object\n"
            "  --factor KIND    CHOLMOD factorisation: auto (default), simplicial, supernodal\n"
            "  -h, --help       show this text\n"
            "\n"
            "exit status: 0 success, 2 bad arguments, scene or FEM input, or an output that\n"
            "cannot be written\n");
}

static int parse_options(int argc, char **argv, fem_options *o)
{
    *o = (fem_options){NULL, NULL, false, FTM_FEM_FACTOR_AUTO};
    for (int i = 1; i < argc; i++) {
        const char *a = argv[i];
        if (strcmp(a, "-h") == 0 || strcmp(a, "--help") == 0) {
            usage(stdout);
            return 1;
        }
        if (strcmp(a, "--json") == 0) {
            o->json = true;
            continue;
        }
        const char *value = NULL;
        int which = -1; /* 0 --csv, 1 --factor */
        static const char *const with_value[] = {"--csv", "--factor"};
        for (int k = 0; k < 2 && which < 0; k++) {
            size_t n = strlen(with_value[k]);
            if (strncmp(a, with_value[k], n) != 0)
                continue;
            if (a[n] == '=') {
                which = k;
                value = a + n + 1;
            } else if (a[n] == '\0') {
                which = k;
                if (i + 1 >= argc) {
                    fprintf(stderr, "ftm fem: %s needs a value\n", a);
                    return EXIT_USAGE;
                }
                value = argv[++i];
            }
        }
        if (which == 0) {
            if (value[0] == '\0') {
                fprintf(stderr, "ftm fem: --csv needs a file name\n");
                return EXIT_USAGE;
            }
            o->csv = value;
            continue;
        }
        if (which == 1) {
            if (strcmp(value, "auto") == 0)
                o->factor = FTM_FEM_FACTOR_AUTO;
            else if (strcmp(value, "simplicial") == 0)
                o->factor = FTM_FEM_FACTOR_SIMPLICIAL;
            else if (strcmp(value, "supernodal") == 0)
                o->factor = FTM_FEM_FACTOR_SUPERNODAL;
            else {
                fprintf(stderr,
                        "ftm fem: --factor: expected auto, simplicial or supernodal, got '%s'\n",
                        value);
                return EXIT_USAGE;
            }
            continue;
        }
        if (a[0] == '-' && a[1] != '\0') {
            fprintf(stderr, "ftm fem: unknown option '%s' (try 'ftm fem --help')\n", a);
            return EXIT_USAGE;
        }
        if (o->scene) {
            fprintf(stderr, "ftm fem: unexpected argument '%s' (scene already given: '%s')\n", a,
                    o->scene);
            return EXIT_USAGE;
        }
        o->scene = a;
    }
    if (!o->scene) {
        fprintf(stderr, "ftm fem: missing SCENE (try 'ftm fem --help')\n");
        return EXIT_USAGE;
    }
    return 0;
}


typedef struct result {
    ftm_fem_stats st;
    double young, poisson;
    int32_t force_loads, displacement_loads;
    double total_force[3];
    double reaction[3]; /* sum of the reactions at the constrained dofs, the
                         * sliding nodes' planes and the springs to ground */
    double max_u;
    int32_t max_node; /* input index */
    double max_vec[3];
    const ftm_label_material *labels; /* [fem LABEL] */
    int32_t label_count;
} result;

/* Per-element materials from the scene's [fem LABEL] sections: an element
 * of such a label gets its material, any other the [fem] one. NULL (and
 * nothing to free) without labels; false when out of memory. */
static bool element_materials(const ftm_mesh *mesh, const result *r, bool hex,
                              ftm_fem_material **out)
{
    *out = NULL;
    if (r->label_count == 0)
        return true;
    int32_t n = hex ? ftm_mesh_hexahedron_count(mesh) : ftm_mesh_tetrahedron_count(mesh);
    ftm_fem_material *m = malloc(((size_t)n + 1) * sizeof *m);
    if (!m)
        return false;
    for (int32_t e = 0; e < n; e++) {
        int32_t label = hex ? ftm_mesh_hexahedron_label(mesh, e) : ftm_mesh_tetrahedron_label(mesh, e);
        m[e] = (ftm_fem_material){r->young, r->poisson};
        for (int32_t i = 0; i < r->label_count; i++)
            if (label > 0 && r->labels[i].label == label)
                m[e] = (ftm_fem_material){r->labels[i].young, r->labels[i].poisson};
    }
    *out = m;
    return true;
}

static void print_text(FILE *out, const char *name, const result *r)
{
    const ftm_fem_stats *s = &r->st;
    fprintf(out, "scene        %s\n", name);
    fprintf(out, "mesh         %d nodes, %d hexahedra, %d tetrahedra\n", (int)s->nodes,
            (int)s->hexahedra, (int)s->tetrahedra);
    fprintf(out, "material     E = %g Pa, nu = %g\n", r->young, r->poisson);
    for (int32_t i = 0; i < r->label_count; i++)
        fprintf(out, "label %-6d E = %g Pa, nu = %g\n", (int)r->labels[i].label,
                r->labels[i].young, r->labels[i].poisson);
    fprintf(out, "dofs         %lld (%lld constrained, %lld free)\n", (long long)s->dofs,
            (long long)s->constrained, (long long)s->free_dofs);
    fprintf(out, "matrix       nnz %lld (upper triangle of the reduced K), factor nnz %lld (%s)\n",
            (long long)s->nnz, (long long)s->factor_nnz,
            s->supernodal ? "supernodal" : "simplicial");
    fprintf(out, "time         assemble %.4f s, factor %.4f s, solve %.4f s\n",
            s->assemble_seconds, s->factor_seconds, s->solve_seconds);
    fprintf(out, "loads        %d force (total %g %g %g N), %d displacement\n",
            (int)r->force_loads, r->total_force[0], r->total_force[1], r->total_force[2],
            (int)r->displacement_loads);
    fprintf(out, "reaction     %g %g %g N at the constrained dofs\n", r->reaction[0],
            r->reaction[1], r->reaction[2]);
    if (r->max_node >= 0)
        fprintf(out, "max |u|      %.6g m at node %d (u = %.6g %.6g %.6g)\n", r->max_u,
                (int)r->max_node, r->max_vec[0], r->max_vec[1], r->max_vec[2]);
    else
        fprintf(out, "max |u|      0 m\n");
}

static void print_json(FILE *out, const char *name, const result *r)
{
    const ftm_fem_stats *s = &r->st;
    fprintf(out, "{\"scene\":");
    ftm_json_string(out, name);
    fprintf(out,
            ",\"nodes\":%d,\"hexahedra\":%d,\"tetrahedra\":%d,\"young\":%s,"
            "\"poisson\":%s,\"dofs\":%lld,\"constrained_dofs\":%lld,\"free_dofs\":%lld,"
            "\"nnz\":%lld,\"factor_nnz\":%lld,\"supernodal\":%s,\"assemble_seconds\":%s,"
            "\"factor_seconds\":%s,\"solve_seconds\":%s,\"force_loads\":%d,"
            "\"displacement_loads\":%d,\"total_force\":[%s,%s,%s],"
            "\"reaction\":[%s,%s,%s],\"max_displacement\":%s,"
            "\"max_displacement_node\":%d,\"labels\":[",
            (int)s->nodes, (int)s->hexahedra, (int)s->tetrahedra, FTM_JN("%.17g", r->young),
            FTM_JN("%.17g", r->poisson), (long long)s->dofs, (long long)s->constrained,
            (long long)s->free_dofs, (long long)s->nnz, (long long)s->factor_nnz,
            s->supernodal ? "true" : "false", FTM_JN("%.6f", s->assemble_seconds),
            FTM_JN("%.6f", s->factor_seconds), FTM_JN("%.6f", s->solve_seconds),
            (int)r->force_loads, (int)r->displacement_loads, FTM_JN("%.17g", r->total_force[0]),
            FTM_JN("%.17g", r->total_force[1]), FTM_JN("%.17g", r->total_force[2]),
            FTM_JN("%.17g", r->reaction[0]), FTM_JN("%.17g", r->reaction[1]),
            FTM_JN("%.17g", r->reaction[2]), FTM_JN("%.17g", r->max_u), (int)r->max_node);
    for (int32_t i = 0; i < r->label_count; i++)
        fprintf(out, "%s{\"label\":%d,\"young\":%s,\"poisson\":%s}", i ? "," : "",
                (int)r->labels[i].label, FTM_JN("%.17g", r->labels[i].young),
                FTM_JN("%.17g", r->labels[i].poisson));
    fprintf(out, "]}\n");
}

static int write_csv(FILE *out, const ftm_mesh *mesh, const double *u)
{
    fprintf(out, "node,x,y,z,ux,uy,uz\n");
    int32_t n = ftm_mesh_node_count(mesh);
    for (int32_t in = 0; in < n; in++) {
        int32_t v = ftm_mesh_node_of_input(mesh, in);
        ftm_vec3 x = ftm_mesh_rest_position(mesh, v);
        fprintf(out, "%d,%.17g,%.17g,%.17g,%.17g,%.17g,%.17g\n", (int)in, x.x, x.y, x.z,
                u[3 * (size_t)v], u[3 * (size_t)v + 1], u[3 * (size_t)v + 2]);
    }
    return ferror(out) ? -1 : 0;
}

/* Loads to nodal vectors: forces add up, displacements become constraints. */
static int gather_loads(const ftm_scene *scene, const ftm_mesh *mesh, double *forces,
                        double *prescribed, bool *constrained, bool *has_force, result *r)
{
    const ftm_scene_load *loads = ftm_scene_loads(scene);
    for (int32_t i = 0; i < ftm_scene_load_count(scene); i++) {
        const ftm_contact *c = &loads[i].contact;
        size_t d = 3 * (size_t)c->node;
        double v[3] = {c->value.x, c->value.y, c->value.z};
        int32_t in = ftm_mesh_input_of_node(mesh, c->node);
        if (c->kind == FTM_CONTACT_FORCE) {
            if (constrained[d]) {
                fprintf(stderr, "ftm fem: node %d has both a force and a displacement load\n",
                        (int)in);
                return EXIT_USAGE;
            }
            for (int k = 0; k < 3; k++) {
                forces[d + k] += v[k];
                r->total_force[k] += v[k];
            }
            has_force[c->node] = true;
            r->force_loads++;
        } else {
            if (has_force[c->node]) {
                fprintf(stderr, "ftm fem: node %d has both a force and a displacement load\n",
                        (int)in);
                return EXIT_USAGE;
            }
            if (constrained[d] && (prescribed[d] != v[0] || prescribed[d + 1] != v[1] ||
                                   prescribed[d + 2] != v[2])) {
                fprintf(stderr,
                        "ftm fem: node %d has two displacement loads with different values; a "
                        "static problem takes one\n",
                        (int)in);
                return EXIT_USAGE;
            }
            for (int k = 0; k < 3; k++) {
                prescribed[d + k] = v[k];
                constrained[d + k] = true;
            }
            r->displacement_loads++;
        }
    }
    return 0;
}

int ftm_cmd_fem(int argc, char **argv)
{
    fem_options o;
    int rc = parse_options(argc, argv, &o);
    if (rc != 0)
        return rc == 1 ? 0 : rc;
    ftm_error err;
    memset(&err, 0, sizeof err);
    ftm_scene *scene = NULL;
    if (ftm_scene_open(o.scene, &scene, &err) != FTM_OK) {
        fprintf(stderr, "ftm fem: %s\n", err.message);
        return EXIT_USAGE;
    }
    result r;
    memset(&r, 0, sizeof r);
    r.max_node = -1;
    if (!ftm_scene_fem_material(scene, &r.young, &r.poisson, NULL)) {
        fprintf(stderr,
                "ftm fem: scene '%s' has no [fem] section (young = E in Pa, poisson = nu; see "
                "docs/scene-format.md)\n",
                o.scene);
        ftm_scene_destroy(scene);
        return EXIT_USAGE;
    }
    const ftm_mesh *mesh = ftm_scene_mesh(scene);
    r.labels = ftm_scene_label_materials(scene, &r.label_count);
    int32_t n = ftm_mesh_node_count(mesh);
    size_t nd = 3 * (size_t)n;
    double *forces = calloc(nd, sizeof *forces), *prescribed = calloc(nd, sizeof *prescribed);
    double *u = calloc(nd, sizeof *u), *res = calloc(nd, sizeof *res);
    bool *constrained = calloc(nd, sizeof *constrained), *has_force = calloc((size_t)n, sizeof *has_force);
    ftm_fem *fem = NULL;
    int status = 0;
    if (!forces || !prescribed || !u || !res || !constrained || !has_force) {
        fprintf(stderr, "ftm fem: out of memory\n");
        status = EXIT_USAGE;
    }
    if (status == 0)
        status = gather_loads(scene, mesh, forces, prescribed, constrained, has_force, &r);
    if (status == 0) {
        ftm_fem_def def = ftm_default_fem_def();
        def.material = (ftm_fem_material){r.young, r.poisson};
        def.constrained = constrained;
        def.factorization = o.factor;
        ftm_fem_material *hexm = NULL, *tetm = NULL;
        if (!element_materials(mesh, &r, true, &hexm) ||
            !element_materials(mesh, &r, false, &tetm)) {
            fprintf(stderr, "ftm fem: out of memory\n");
            status = EXIT_USAGE;
        } else {
            def.hex_materials = hexm;
            def.tet_materials = tetm;
            if (ftm_fem_create(mesh, &def, &fem, &err) != FTM_OK ||
                ftm_fem_solve(fem, forces, prescribed, u, &err) != FTM_OK) {
                fprintf(stderr, "ftm fem: %s: %s\n", o.scene, err.message);
                status = EXIT_USAGE;
            }
        }
        free(hexm);
        free(tetm);
    }
    if (status == 0) {
        r.st = ftm_fem_get_stats(fem);
        ftm_fem_residual(fem, u, forces, res);
        for (int32_t v = 0; v < n; v++) {
            const double *uv = u + 3 * (size_t)v;
            double m = sqrt(uv[0] * uv[0] + uv[1] * uv[1] + uv[2] * uv[2]);
            int32_t in = ftm_mesh_input_of_node(mesh, v);
            /* near-ties (symmetric nodes, equal up to rounding) go to the lowest
             * input index, so the report does not depend on the factorisation */
            bool larger = m > r.max_u * (1 + 1e-9);
            bool tie = !larger && m >= r.max_u * (1 - 1e-9) && m > 0 && in < r.max_node;
            if (larger || tie) {
                r.max_u = m;
                r.max_node = in;
                memcpy(r.max_vec, uv, sizeof r.max_vec);
            }
            /* a sliding node's residual is its plane's reaction; a spring to
             * ground pulls with -k_g u (K u holds its k_g u) */
            const bool slides = ftm_mesh_slide_normals(mesh, v, NULL) > 0;
            const double kg = ftm_mesh_ground_stiffness(mesh, v);
            for (int k = 0; k < 3; k++)
                if (ftm_mesh_fixed(mesh, v) || constrained[3 * (size_t)v + k] || slides || kg > 0)
                    r.reaction[k] += res[3 * (size_t)v + k] - kg * uv[k];
        }
        bool csv_stdout = o.csv && strcmp(o.csv, "-") == 0;
        if (o.csv) {
            FILE *f = csv_stdout ? stdout : fopen(o.csv, "w");
            if (!f) {
                fprintf(stderr, "ftm fem: %s: cannot write: %s\n", o.csv, strerror(errno));
                status = EXIT_USAGE;
            } else {
                /* write_csv() sees any failed write (the stream remembers it);
                 * closing or flushing the rest gives the reason. */
                int e = 0, wrc = write_csv(f, mesh, u);
                if (csv_stdout ? fflush(f) != 0 : fclose(f) != 0) {
                    wrc = -1;
                    e = errno;
                }
                if (wrc != 0) {
                    fprintf(stderr, "ftm fem: %s: cannot write: %s\n",
                            csv_stdout ? "standard output" : o.csv,
                            e ? strerror(e) : "write error");
                    status = EXIT_USAGE;
                }
            }
        }
        FILE *out = csv_stdout ? stderr : stdout;
        if (status == 0) {
            if (o.json)
                print_json(out, ftm_scene_name(scene), &r);
            else
                print_text(out, ftm_scene_name(scene), &r);
        }
    }
    ftm_fem_destroy(fem);
    free(forces);
    free(prescribed);
    free(u);
    free(res);
    free(constrained);
    free(has_force);
    ftm_scene_destroy(scene);
    return status;
}
