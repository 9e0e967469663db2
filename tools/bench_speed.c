/* SPDX-License-Identifier: GPL-3.0-or-later */
/* `ftm bench accuracy --speed`: the step cost of each force model on one
 * body, side by side (docs/benchmarks.md, "Element forces").
 *
 * One simulation per model on the same nodes, masses, damping, load and
 * region (full depth): springs, and linear, co-rotational and neo-Hookean
 * element forces on the body's hexahedra and on the same cells split into
 * six tetrahedra each. Each runs at half its own critical step. After a
 * warm-up that loads them, the simulations take turns, a few steps each per
 * round, every step timed: a load from another process then falls on all of
 * them alike, and the medians over all rounds are comparable within the
 * run. Ratios are to the springs' median. The 10th percentile is given
 * beside it: on a loaded machine the fastest steps are the ones least
 * disturbed. */
#include "bench.h"
#include "commands.h"

#include "ftm/ftm.h"

#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

/* The same nodes, links and fixed set as hex, each hexahedron as the six
 * tetrahedra around its diagonal from corner 0 to corner 6 (node order of
 * ftm_mesh_hexahedra: corners (0,0,0) (1,0,0) (1,1,0) (0,1,0), then z = 1). */
static int tet_twin(const ftm_mesh *hex, ftm_mesh **out, ftm_error *err)
{
    static const int corner[2][2][2] = {{{0, 4}, {3, 7}}, {{1, 5}, {2, 6}}}; /* [x][y][z] */
    static const int path[6][3] = {{0, 1, 2}, {0, 2, 1}, {1, 0, 2},
                                   {1, 2, 0}, {2, 0, 1}, {2, 1, 0}};
    ftm_mesh_builder *b = ftm_mesh_builder_create();
    int rc = b ? FTM_OK : FTM_ENOMEM;
    const int32_t n = ftm_mesh_node_count(hex);
    for (int32_t i = 0; i < n && rc >= 0; i++) {
        ftm_node_def nd = ftm_default_node_def();
        nd.position = ftm_mesh_rest_position(hex, i);
        nd.mass = ftm_mesh_mass(hex, i);
        nd.damping = ftm_mesh_damping(hex, i);
        nd.fixed = ftm_mesh_fixed(hex, i);
        rc = ftm_mesh_builder_add_node(b, &nd);
    }
    for (int32_t l = 0; l < ftm_mesh_link_count(hex) && rc >= 0; l++) {
        ftm_link_def ld;
        ftm_mesh_link(hex, l, &ld.a, &ld.b, &ld.stiffness, &ld.rest_length);
        rc = ftm_mesh_builder_add_link(b, &ld);
    }
    const int32_t *hx = ftm_mesh_hexahedra(hex);
    for (int32_t e = 0; e < ftm_mesh_hexahedron_count(hex) && rc >= 0; e++)
        for (int t = 0; t < 6 && rc >= 0; t++) {
            int c[3] = {0, 0, 0};
            int32_t v[4];
            v[0] = hx[8 * e + corner[0][0][0]];
            for (int st = 0; st < 3; st++) {
                c[path[t][st]] = 1;
                v[st + 1] = hx[8 * e + corner[c[0]][c[1]][c[2]]];
            }
            rc = ftm_mesh_builder_add_tetrahedron(b, v[0], v[1], v[2], v[3]);
        }
    ftm_mesh_build_def bdef = ftm_default_mesh_build_def();
    bdef.reorder = false;
    if (rc >= 0)
        rc = ftm_mesh_build(b, &bdef, out, err);
    else
        ftm_error_set(err, rc, "tetrahedra of the speed benchmark: %s", ftm_strerror(rc));
    ftm_mesh_builder_destroy(b);
    return rc < 0 ? rc : FTM_OK;
}

typedef struct model {
    const char *elements, *forces;
    ftm_forces kind;
    bool tets;
    ftm_sim *sim;
    double *samples;
    int32_t nsamples, updated;
    double h, median, ratio, p10, p10_ratio;
} model;

static int make_sim(const ftm_mesh *m, const ftm_speed_def *d, model *md, ftm_error *err)
{
    ftm_sim_def sd = ftm_default_sim_def();
    sd.forces = md->kind;
    sd.young = d->young;
    sd.poisson = d->poisson;
    sd.depth = d->depth;
    ftm_sim *probe = NULL;
    int rc = ftm_sim_create(m, &sd, &probe, err); /* its critical step */
    if (rc)
        return rc;
    sd.time_step = 0.5 * ftm_sim_critical_time_step(probe);
    ftm_sim_destroy(probe);
    md->h = sd.time_step;
    rc = ftm_sim_create(m, &sd, &md->sim, err);
    if (!rc)
        rc = ftm_sim_set_contacts(md->sim, d->contacts, d->ncontacts, err);
    return rc;
}

int ftm_bench_speed(const ftm_speed_def *d, FILE *out, bool json)
{
    model models[] = {
        {"hexahedra", "springs", FTM_FORCES_SPRINGS, false, .sim = NULL},
        {"hexahedra", "linear-fem", FTM_FORCES_LINEAR_FEM, false, .sim = NULL},
        {"hexahedra", "corot-fem", FTM_FORCES_COROT_FEM, false, .sim = NULL},
        {"hexahedra", "neo-hookean", FTM_FORCES_NEO_HOOKEAN, false, .sim = NULL},
        {"tetrahedra", "linear-fem", FTM_FORCES_LINEAR_FEM, true, .sim = NULL},
        {"tetrahedra", "corot-fem", FTM_FORCES_COROT_FEM, true, .sim = NULL},
        {"tetrahedra", "neo-hookean", FTM_FORCES_NEO_HOOKEAN, true, .sim = NULL},
    };
    int nm = (int)(sizeof models / sizeof models[0]);
    if (d->only) { /* springs and the one model (for a profiler) */
        int keep = 1;
        for (int k = 1; k < nm; k++) {
            char name[64];
            snprintf(name, sizeof name, "%s %s", models[k].elements, models[k].forces);
            if (strcmp(name, d->only) == 0)
                models[keep++] = models[k];
        }
        if (keep == 1) {
            fprintf(stderr, "ftm bench accuracy --speed: no model '%s'\n", d->only);
            return FTM_EINVAL;
        }
        nm = keep;
    }
    ftm_mesh *tets = NULL;
    ftm_error err;
    int rc = tet_twin(d->mesh, &tets, &err);
    const int32_t per_model = d->rounds * d->steps;
    for (int k = 0; !rc && k < nm; k++) {
        models[k].samples = malloc((size_t)per_model * sizeof *models[k].samples);
        if (!models[k].samples)
            rc = FTM_ENOMEM;
        else
            rc = make_sim(models[k].tets ? tets : d->mesh, d, &models[k], &err);
    }
    /* warm-up: every model loaded and moving */
    for (int k = 0; !rc && k < nm; k++)
        rc = ftm_sim_run(models[k].sim, d->warmup);
    for (int r = 0; !rc && r < d->rounds; r++)
        for (int k = 0; !rc && k < nm; k++) {
            model *md = &models[k];
            for (int s = 0; !rc && s < d->steps; s++) {
                double t0 = ftm_bench_now_us();
                rc = ftm_sim_step(md->sim);
                md->samples[md->nsamples++] = ftm_bench_now_us() - t0;
            }
        }
    if (rc) {
        fprintf(stderr, "ftm bench accuracy --speed: %s\n",
                err.code == rc ? err.message : ftm_strerror(rc));
    } else {
        for (int k = 0; k < nm; k++) {
            ftm_sim_stats st;
            ftm_sim_get_stats(models[k].sim, &st);
            models[k].updated = (int32_t)st.updated_nodes;
            models[k].median = ftm_bench_median(models[k].samples, models[k].nsamples);
            models[k].p10 = models[k].samples[models[k].nsamples / 10]; /* (sorted now) */
        }
        for (int k = 0; k < nm; k++) {
            models[k].ratio = models[k].median / models[0].median;
            models[k].p10_ratio = models[k].p10 / models[0].p10;
        }
        if (json) {
            fprintf(out, "{\"mesh\":\"%s\",\"nodes\":%d,\"hexahedra\":%d,"
                         "\"tetrahedra\":%d,\"depth\":%d,\"rounds\":%d,\"steps_per_round\":%d,"
                         "\"warmup\":%d,\"rows\":[",
                    d->name, (int)ftm_mesh_node_count(d->mesh),
                    (int)ftm_mesh_hexahedron_count(d->mesh), (int)ftm_mesh_tetrahedron_count(tets),
                    (int)d->depth, d->rounds, d->steps, d->warmup);
            for (int k = 0; k < nm; k++) {
                const model *md = &models[k];
                fprintf(out, "%s{\"elements\":\"%s\",\"forces\":\"%s\",\"nodes\":%d,\"h\":",
                        k ? "," : "", md->elements, md->forces, (int)md->updated);
                ftm_json_number(out, md->h, 6);
                fprintf(out, ",\"step_us\":");
                ftm_json_number(out, md->median, 6);
                fprintf(out, ",\"ratio\":");
                ftm_json_number(out, md->ratio, 4);
                fprintf(out, ",\"p10_us\":");
                ftm_json_number(out, md->p10, 6);
                fprintf(out, ",\"p10_ratio\":");
                ftm_json_number(out, md->p10_ratio, 4);
                fprintf(out, "}");
            }
            fprintf(out, "]}");
        } else {
            fprintf(out,
                    "%s: %d nodes, %d hexahedra (%d tetrahedra), depth %d; median of %d steps "
                    "per model\n(%d rounds of %d, alternating, after %d warm-up steps)\n",
                    d->name, (int)ftm_mesh_node_count(d->mesh),
                    (int)ftm_mesh_hexahedron_count(d->mesh), (int)ftm_mesh_tetrahedron_count(tets),
                    (int)d->depth, (int)per_model, d->rounds, d->steps, d->warmup);
            fprintf(out, "elements    forces        nodes     h [s]  step [us]  / springs"
                         "   10th pct [us]  / springs\n");
            for (int k = 0; k < nm; k++) {
                const model *md = &models[k];
                fprintf(out, "%-11s %-12s %6d  %8.3g  %9.2f  %9.2f   %13.2f  %9.2f\n",
                        md->elements, md->forces, (int)md->updated, md->h, md->median, md->ratio,
                        md->p10, md->p10_ratio);
            }
        }
    }
    for (int k = 0; k < nm; k++) {
        ftm_sim_destroy(models[k].sim);
        free(models[k].samples);
    }
    ftm_mesh_destroy(tets);
    return rc;
}
