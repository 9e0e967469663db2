/* SPDX-License-Identifier: GPL-3.0-or-later */
/* ftm sim: runs a scene's scripted load and reports the outcome. */
#include "commands.h"

#include "ftm/ftm.h"

#include <errno.h>
#include <inttypes.h>
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <time.h>

enum { EXIT_USAGE = 2, EXIT_UNSTABLE = 3 };

typedef struct sim_options {
    const char *scene; /* built-in name or file; NULL = "default" */
    int64_t steps;     /* < 0: the scene's */
    int64_t depth;     /* < 0: the scene's */
    int order;         /* < 0: the scene's, else an ftm_order */
    const char *csv;   /* NULL = none, "-" = stdout */
    bool quiet;
    bool json;
    bool press;
} sim_options;

static void usage(FILE *out)
{
    fprintf(out,
            "usage: ftm sim [SCENE] [options]\n"
            "\n"
            "Runs SCENE, a built-in scene name or a scene file (docs/scene-format.md),\n"
            "with its scripted loads and prints a summary. Default scene: \"default\".\n"
            "\n"
            "options:\n"
            "  --steps N      number of time steps (default: the scene's steps)\n"
            "  --depth N      penetration depth (default: the scene's depth)\n"
            "  --order ORDER  update order inside a layer: colored, bfs or jacobi\n"
            "  --csv FILE     write the final node positions as CSV (\"-\": standard output)\n"
            "  --json         print the summary as one JSON object\n"
            "  --press        also estimate what a 7.5 mm press on the top feels like\n"
            "                 (docs/feel.md, \"Can a trainee feel it\")\n"
            "  --quiet        print only the state hash\n"
            "  -h, --help     show this text\n"
            "\n"
            "built-in scenes:");
    for (const char *const *n = ftm_scene_builtin_names(); *n; n++)
        fprintf(out, " %s", *n);
    fprintf(out, "\n\nexit status: 0 success, 1 out of memory or an internal error, 2 bad\n"
                 "arguments or scene, or an output that cannot be written (the summary is still\n"
                 "printed), 3 the integration diverged\n");
}

static bool parse_count(const char *s, int64_t max, int64_t *out)
{
    char *end;
    errno = 0;
    long long v = strtoll(s, &end, 10);
    if (end == s || *end != '\0' || errno == ERANGE || v < 0 || v > max)
        return false;
    *out = v;
    return true;
}

/* Returns 0 to run, 1 if help was printed, EXIT_USAGE on a bad argument. */
static int parse_options(int argc, char **argv, sim_options *o)
{
    *o = (sim_options){NULL, -1, -1, -1, NULL, false, false, false};
    for (int i = 1; i < argc; i++) {
        const char *a = argv[i];
        if (strcmp(a, "-h") == 0 || strcmp(a, "--help") == 0) {
            usage(stdout);
            return 1;
        }
        if (strcmp(a, "--quiet") == 0 || strcmp(a, "-q") == 0) {
            o->quiet = true;
            continue;
        }
        if (strcmp(a, "--json") == 0) {
            o->json = true;
            continue;
        }
        if (strcmp(a, "--press") == 0) {
            o->press = true;
            continue;
        }
        if (a[0] == '-' && a[1] != '\0') {
            /* Options with a value: "--name VALUE" or "--name=VALUE". */
            static const char *const with_value[] = {"--steps", "--depth", "--order", "--csv"};
            const char *value = NULL;
            int which = -1;
            for (int k = 0; k < 4 && which < 0; k++) {
                size_t n = strlen(with_value[k]);
                if (strncmp(a, with_value[k], n) != 0)
                    continue;
                if (a[n] == '=') {
                    which = k;
                    value = a + n + 1;
                } else if (a[n] == '\0') {
                    which = k;
                    if (i + 1 >= argc) {
                        fprintf(stderr, "ftm sim: %s needs a value\n", a);
                        return EXIT_USAGE;
                    }
                    value = argv[++i];
                }
            }
            if (which < 0) {
                fprintf(stderr, "ftm sim: unknown option '%s' (try 'ftm sim --help')\n", a);
                return EXIT_USAGE;
            }
            switch (which) {
            case 0:
                if (!parse_count(value, INT32_MAX, &o->steps)) {
                    fprintf(stderr, "ftm sim: --steps: expected a count 0..%d, got '%s'\n",
                            INT32_MAX, value);
                    return EXIT_USAGE;
                }
                break;
            case 1:
                if (!parse_count(value, 1000000, &o->depth)) {
                    fprintf(stderr, "ftm sim: --depth: expected 0..1000000, got '%s'\n", value);
                    return EXIT_USAGE;
                }
                break;
            case 2:
                if (strcmp(value, "colored") == 0)
                    o->order = FTM_ORDER_LAYER_COLORED;
                else if (strcmp(value, "bfs") == 0)
                    o->order = FTM_ORDER_BFS;
                else if (strcmp(value, "jacobi") == 0)
                    o->order = FTM_ORDER_LAYER_JACOBI;
                else {
                    fprintf(stderr,
                            "ftm sim: --order: expected colored, bfs or jacobi, got '%s'\n",
                            value);
                    return EXIT_USAGE;
                }
                break;
            default:
                if (value[0] == '\0') {
                    fprintf(stderr, "ftm sim: --csv needs a file name\n");
                    return EXIT_USAGE;
                }
                o->csv = value;
                break;
            }
            continue;
        }
        if (o->scene) {
            fprintf(stderr, "ftm sim: unexpected argument '%s' (scene already given: '%s')\n", a,
                    o->scene);
            return EXIT_USAGE;
        }
        o->scene = a;
    }
    return 0;
}

static void log_to_stderr(void *user, ftm_log_level level, const char *message)
{
    (void)user;
    /* (the core's info: the far field's precomputation, its progress and cache) */
    if (level >= FTM_LOG_INFO)
        fprintf(stderr, "ftm: %s: %s\n",
                level >= FTM_LOG_ERROR ? "error" : level >= FTM_LOG_WARN ? "warning" : "info",
                message);
}

static const char *order_name(ftm_order order)
{
    switch (order) {
    case FTM_ORDER_BFS: return "bfs";
    case FTM_ORDER_LAYER_JACOBI: return "jacobi";
    case FTM_ORDER_LAYER_COLORED:
    default: return "colored";
    }
}

static bool same_contacts(const ftm_contact *a, int32_t na, const ftm_contact *b, int32_t nb)
{
    if (na != nb)
        return false;
    /* Field by field: the struct has padding that memcmp would compare. */
    for (int32_t i = 0; i < na; i++) {
        if (a[i].node != b[i].node || a[i].group != b[i].group || a[i].kind != b[i].kind ||
            a[i].value.x != b[i].value.x || a[i].value.y != b[i].value.y ||
            a[i].value.z != b[i].value.z)
            return false;
    }
    return true;
}

static double now_seconds(void)
{
    struct timespec ts;
    clock_gettime(CLOCK_MONOTONIC, &ts);
    return (double)ts.tv_sec + 1e-9 * (double)ts.tv_nsec;
}

static int compare_int32(const void *a, const void *b)
{
    int32_t x = *(const int32_t *)a, y = *(const int32_t *)b;
    return (x > y) - (x < y);
}

/* Groups that have displacement contacts (sorted, unique); returns the count. */
static int32_t displacement_groups(const ftm_scene *scene, int32_t *groups)
{
    const ftm_scene_load *loads = ftm_scene_loads(scene);
    int32_t n = 0;
    for (int32_t i = 0; i < ftm_scene_load_count(scene); i++)
        if (loads[i].contact.kind == FTM_CONTACT_DISPLACEMENT)
            groups[n++] = loads[i].contact.group;
    if (n == 0)
        return 0;
    qsort(groups, (size_t)n, sizeof *groups, compare_int32);
    int32_t u = 1;
    for (int32_t i = 1; i < n; i++)
        if (groups[i] != groups[u - 1])
            groups[u++] = groups[i];
    return u;
}

typedef struct summary {
    const char *scene;
    char model[256]; /* ftm_scene_describe_model */
    char press[256]; /* --press: ftm_press_describe or why there is none; "" without */
    bool have_press;
    ftm_press_estimate pe;
    int32_t nodes, links, triangles;
    double h, h_crit;
    int32_t depth;
    ftm_order order;
    int32_t steps;
    double wall;
    ftm_sim_stats stats;
    double max_disp;
    int32_t max_node; /* input index, -1 if the mesh is empty */
    /* over the run */
    double peak_reaction; /* largest |reaction| of any displacement group */
    int32_t peak_reaction_step, peak_reaction_group;
    int64_t node_updates;   /* sum of per-step node updates: the work done */
    int32_t peak_updates;   /* most node updates in one step */
    int32_t rest_since;     /* first step of the final idle stretch, -1 if never idle */
    uint64_t hash;
} summary;

static void max_displacement(const ftm_sim *sim, const ftm_mesh *mesh, summary *s)
{
    s->max_disp = 0;
    s->max_node = -1;
    for (int32_t i = 0; i < ftm_mesh_node_count(mesh); i++) {
        ftm_vec3 x = ftm_sim_position(sim, i), r = ftm_mesh_rest_position(mesh, i);
        double dx = x.x - r.x, dy = x.y - r.y, dz = x.z - r.z;
        double d = sqrt(dx * dx + dy * dy + dz * dz);
        int32_t input = ftm_mesh_input_of_node(mesh, i);
        /* Ties go to the lowest input index so the report does not depend on node order. */
        if (s->max_node < 0 || d > s->max_disp || (d == s->max_disp && input < s->max_node)) {
            s->max_disp = d;
            s->max_node = input;
        }
    }
}


/* A JSON number that reads back exactly, or null (commands.h). */
static void json_number(FILE *out, double v)
{
    ftm_json_number(out, v, 17);
}

/* Whether a group still had a displacement contact in the last step. */
static bool group_active(const ftm_contact *contacts, int32_t count, int32_t group)
{
    for (int32_t i = 0; i < count; i++)
        if (contacts[i].group == group && contacts[i].kind == FTM_CONTACT_DISPLACEMENT)
            return true;
    return false;
}

static void print_json(FILE *out, const summary *s, const ftm_sim *sim, const int32_t *groups,
                       int32_t group_count, const ftm_contact *last, int32_t last_count)
{
    fputs("{\"scene\": ", out);
    ftm_json_string(out, s->scene);
    fputs(", \"model\": ", out);
    ftm_json_string(out, s->model);
    if (s->have_press)
        fprintf(out, ", \"press\": {\"depth\": %.17g, \"force\": %.17g, \"triangle\": %d}",
                s->pe.depth, s->pe.force, (int)s->pe.triangle);
    fprintf(out, ", \"nodes\": %d, \"links\": %d, \"triangles\": %d", (int)s->nodes,
            (int)s->links, (int)s->triangles);
    fputs(", \"time_step\": ", out);
    json_number(out, s->h);
    fputs(", \"critical_time_step\": ", out);
    json_number(out, s->h_crit);
    fprintf(out, ", \"time_step_above_critical\": %s", s->h > s->h_crit ? "true" : "false");
    fprintf(out, ", \"depth\": %d, \"order\": \"%s\", \"steps\": %d", (int)s->depth,
            order_name(s->order), (int)s->steps);
    fputs(", \"wall_s\": ", out);
    json_number(out, s->wall);
    fputs(", \"steps_per_s\": ", out);
    json_number(out, s->wall > 0 ? s->steps / s->wall : NAN);
    fprintf(out, ", \"region_nodes\": %d, \"layers\": %d, \"relaxing_nodes\": %d, \"far_nodes\": %d",
            (int)s->stats.region_nodes, (int)s->stats.layers, (int)s->stats.relaxing_nodes,
            (int)s->stats.far_nodes);
    fputs(", \"max_displacement\": ", out);
    json_number(out, s->max_disp);
    fprintf(out, ", \"max_displacement_node\": %d, \"reactions\": [", (int)s->max_node);
    for (int32_t i = 0; i < group_count; i++) {
        ftm_vec3 f = ftm_sim_reaction(sim, groups[i]);
        fprintf(out, "%s{\"group\": %d, \"active\": %s, \"force\": [", i ? ", " : "",
                (int)groups[i], group_active(last, last_count, groups[i]) ? "true" : "false");
        json_number(out, f.x);
        fputs(", ", out);
        json_number(out, f.y);
        fputs(", ", out);
        json_number(out, f.z);
        fputs("]}", out);
    }
    fputs("], \"peak_reaction\": ", out);
    json_number(out, s->peak_reaction);
    fprintf(out,
            ", \"node_updates\": %" PRId64 ", \"peak_updates\": %d, \"rest_since_step\": %d",
            s->node_updates, (int)s->peak_updates, (int)s->rest_since);
    fprintf(out,
            ", \"guard_events\": %" PRIu64 ", \"substeps\": %d, \"unstable_steps\": %" PRIu64
            ", \"planar_sweeps\": %" PRIu64 ", \"hash\": \"%016" PRIx64 "\"}\n",
            s->stats.guard_events, (int)s->stats.substeps, s->stats.unstable_steps,
            s->stats.planar_sweeps, s->hash);
}

static void print_human(FILE *out, const summary *s, const ftm_sim *sim, const int32_t *groups,
                        int32_t group_count, const ftm_contact *last, int32_t last_count)
{
    fprintf(out, "scene            %s\n", s->scene);
    fprintf(out, "model            %s\n", s->model);
    if (s->press[0])
        fprintf(out, "press            %s\n", s->press);
    fprintf(out, "mesh             %d nodes, %d links, %d triangles\n", (int)s->nodes,
            (int)s->links, (int)s->triangles);
    fprintf(out, "time step        %.6g s (critical %.6g s)\n", s->h, s->h_crit);
    if (s->h > s->h_crit)
        fprintf(out,
                "WARNING          time step %.6g s exceeds the critical time step %.6g s: "
                "stability is not guaranteed\n",
                s->h, s->h_crit);
    fprintf(out, "depth            %d (order %s)\n", (int)s->depth, order_name(s->order));
    fprintf(out, "steps            %d in %.3f s", (int)s->steps, s->wall);
    if (s->wall > 0)
        fprintf(out, " (%.0f steps/s)", s->steps / s->wall);
    fputc('\n', out);
    fprintf(out, "region           %d nodes in %d layers%s\n", (int)s->stats.region_nodes,
            (int)s->stats.layers, s->stats.region_sleeping ? " (sleeping)" : "");
    fprintf(out, "relaxing nodes   %d\n", (int)s->stats.relaxing_nodes);
    if (s->stats.far_nodes > 0)
        fprintf(out, "far field        %d nodes beyond the region placed elastically\n",
                (int)s->stats.far_nodes);
    if (s->max_node >= 0)
        fprintf(out, "max displacement %.6g m at node %d\n", s->max_disp, (int)s->max_node);
    for (int32_t i = 0; i < group_count; i++) {
        ftm_vec3 f = ftm_sim_reaction(sim, groups[i]);
        fprintf(out, "reaction         group %d: (%.6g, %.6g, %.6g) N%s\n", (int)groups[i], f.x,
                f.y, f.z, group_active(last, last_count, groups[i]) ? "" : " (not in contact)");
    }
    if (s->peak_reaction > 0)
        fprintf(out, "peak reaction    %.6g N (group %d) at t = %.6g s\n", s->peak_reaction,
                (int)s->peak_reaction_group, s->peak_reaction_step * s->h);
    fprintf(out, "work             %" PRId64 " node updates (%.1f per step, peak %d)\n",
            s->node_updates, s->steps ? (double)s->node_updates / s->steps : 0.0,
            (int)s->peak_updates);
    if (s->stats.planar_sweeps)
        fprintf(out, "planar sweeps    %" PRIu64 " (z left out: the scene keeps to z = 0)\n",
                s->stats.planar_sweeps);
    if (s->rest_since >= 0)
        fprintf(out, "at rest          from t = %.6g s (step %d): idle steps update no node\n",
                s->rest_since * s->h, (int)s->rest_since);
    fprintf(out, "guard            %" PRIu64 " events, %d substeps", s->stats.guard_events,
            (int)s->stats.substeps);
    if (s->stats.unstable_steps)
        fprintf(out, ", %" PRIu64 " unstable steps", s->stats.unstable_steps);
    fputc('\n', out);
    fprintf(out, "hash %016" PRIx64 "\n", s->hash);
}

/* Node positions in input order, with "%.17g" so the values round-trip. */
static int write_csv(FILE *f, const ftm_sim *sim, const ftm_mesh *mesh)
{
    fputs("node,x,y,z,ux,uy,uz\n", f);
    for (int32_t i = 0; i < ftm_mesh_node_count(mesh); i++) {
        int32_t node = ftm_mesh_node_of_input(mesh, i);
        ftm_vec3 x = ftm_sim_position(sim, node), r = ftm_mesh_rest_position(mesh, node);
        fprintf(f, "%d,%.17g,%.17g,%.17g,%.17g,%.17g,%.17g\n", (int)i, x.x, x.y, x.z, x.x - r.x,
                x.y - r.y, x.z - r.z);
    }
    return ferror(f) ? -1 : 0;
}

int ftm_cmd_sim(int argc, char **argv)
{
    sim_options o;
    int rc = parse_options(argc, argv, &o);
    if (rc)
        return rc == 1 ? 0 : rc;
    const char *scene_name = o.scene ? o.scene : "default";

    int status = 0;
    ftm_error err;
    err.code = FTM_OK;
    err.message[0] = '\0';
    ftm_scene *scene = NULL;
    ftm_sim *sim = NULL;
    ftm_contact *cur = NULL, *prev = NULL;
    int32_t *groups = NULL;
    FILE *csv = NULL;

    if (ftm_scene_open(scene_name, &scene, &err) != FTM_OK) {
        fprintf(stderr, "ftm sim: %s\n", err.message);
        return EXIT_USAGE;
    }
    /* Open the CSV first so that a bad path fails before a long run. */
    bool csv_stdout = o.csv && strcmp(o.csv, "-") == 0;
    if (o.csv) {
        csv = csv_stdout ? stdout : fopen(o.csv, "w");
        if (!csv) {
            fprintf(stderr, "ftm sim: %s: cannot write: %s\n", o.csv, strerror(errno));
            status = EXIT_USAGE;
            goto done;
        }
    }
    /* With the CSV on standard output the summary goes to standard error. */
    FILE *out = csv_stdout ? stderr : stdout;

    const ftm_mesh *mesh = ftm_scene_mesh(scene);
    ftm_sim_def def = ftm_scene_sim_def(scene);
    if (o.depth >= 0)
        def.depth = (int32_t)o.depth;
    if (o.order >= 0)
        def.order = (ftm_order)o.order;
    def.log = log_to_stderr;
    def.log_user = NULL;
    if (ftm_sim_create(mesh, &def, &sim, &err) != FTM_OK) {
        fprintf(stderr, "ftm sim: %s: %s\n", ftm_scene_name(scene), err.message);
        status = EXIT_USAGE;
        goto done;
    }

    int32_t load_count = ftm_scene_load_count(scene);
    size_t cap = load_count > 0 ? (size_t)load_count : 1;
    cur = malloc(cap * sizeof *cur);
    prev = malloc(cap * sizeof *prev);
    groups = malloc(cap * sizeof *groups);
    if (!cur || !prev || !groups) {
        fprintf(stderr, "ftm sim: out of memory\n");
        status = 1;
        goto done;
    }

    summary s;
    memset(&s, 0, sizeof s);
    s.scene = ftm_scene_name(scene);
    ftm_scene_describe_model(scene, s.model, sizeof s.model);
    if (o.press) {
        ftm_error perr = {0, ""};
        if (ftm_scene_press_estimate(scene, FTM_PRESS_ESTIMATE_DEPTH, &s.pe, &perr) == FTM_OK) {
            s.have_press = true;
            ftm_press_describe(&s.pe, s.press, sizeof s.press);
        } else {
            snprintf(s.press, sizeof s.press, "none: %.200s", perr.message);
        }
    }
    s.nodes = ftm_mesh_node_count(mesh);
    s.links = ftm_mesh_link_count(mesh);
    s.triangles = ftm_mesh_triangle_count(mesh);
    s.h = def.time_step;
    s.h_crit = ftm_sim_critical_time_step(sim); /* of the forces it runs: springs or elements */
    s.depth = def.depth;
    s.order = def.order;
    s.steps = o.steps >= 0 ? (int32_t)o.steps : ftm_scene_steps(scene);
    if ((o.quiet || o.json) && s.h > s.h_crit)
        fprintf(stderr, "ftm: warning: time step %.6g s exceeds the critical time step %.6g s\n",
                s.h, s.h_crit);

    int32_t group_count = displacement_groups(scene, groups);
    s.rest_since = -1;
    int32_t prev_count = 0;
    double t0 = now_seconds();
    for (int32_t step = 0; step < s.steps; step++) {
        double t = (double)step * def.time_step;
        int32_t n = ftm_scene_contacts_at(scene, t, cur, load_count);
        /* Only a changed contact list is passed on: setting contacts is not free. */
        if (!same_contacts(cur, n, prev, prev_count)) {
            if (ftm_sim_set_contacts(sim, cur, n, &err) != FTM_OK) {
                fprintf(stderr, "ftm sim: %s: step %d: %s\n", s.scene, (int)step, err.message);
                status = EXIT_USAGE;
                goto done;
            }
            ftm_contact *swap = prev;
            prev = cur;
            cur = swap;
            prev_count = n;
        }
        rc = ftm_sim_step(sim);
        if (rc == FTM_EUNSTABLE) {
            fprintf(stderr,
                    "ftm sim: %s: step %d (t = %.6g s): the integration diverged (or an "
                    "element inverted) even with %d substeps; use a smaller time_step "
                    "(critical %.6g s) or a gentler load\n",
                    s.scene, (int)step, t, (int)def.max_substeps, s.h_crit);
            status = EXIT_UNSTABLE;
            goto done;
        }
        if (rc != FTM_OK) {
            fprintf(stderr, "ftm sim: %s: step %d: %s\n", s.scene, (int)step, ftm_strerror(rc));
            status = 1;
            goto done;
        }
        ftm_sim_stats st;
        ftm_sim_get_stats(sim, &st);
        s.node_updates += st.updated_nodes;
        if (st.updated_nodes > s.peak_updates)
            s.peak_updates = st.updated_nodes;
        if (st.updated_nodes > 0 || prev_count > 0)
            s.rest_since = -1;
        else if (s.rest_since < 0)
            s.rest_since = step;
        for (int32_t g = 0; g < group_count; g++) {
            ftm_vec3 f = ftm_sim_reaction(sim, groups[g]);
            double mag = sqrt(f.x * f.x + f.y * f.y + f.z * f.z);
            if (mag > s.peak_reaction) {
                s.peak_reaction = mag;
                s.peak_reaction_step = step;
                s.peak_reaction_group = groups[g];
            }
        }
    }
    s.wall = now_seconds() - t0;

    ftm_sim_get_stats(sim, &s.stats);
    max_displacement(sim, mesh, &s);
    s.hash = ftm_sim_hash(sim);

    if (csv) {
        /* write_csv() sees any failed write (the stream remembers it);
         * closing or flushing the rest gives the reason. */
        int e = 0, wrc = write_csv(csv, sim, mesh);
        if (csv_stdout ? fflush(csv) != 0 : fclose(csv) != 0) {
            wrc = -1;
            e = errno;
        }
        if (!csv_stdout)
            csv = NULL;
        if (wrc != 0) {
            /* The run itself succeeded: its summary still follows. */
            fprintf(stderr, "ftm sim: %s: cannot write: %s\n",
                    csv_stdout ? "standard output" : o.csv, e ? strerror(e) : "write error");
            status = EXIT_USAGE;
        }
    }
    if (o.json)
        print_json(out, &s, sim, groups, group_count, prev, prev_count);
    else if (o.quiet)
        fprintf(out, "hash %016" PRIx64 "\n", s.hash);
    else
        print_human(out, &s, sim, groups, group_count, prev, prev_count);

done:
    if (csv && csv != stdout)
        fclose(csv);
    free(groups);
    free(prev);
    free(cur);
    ftm_sim_destroy(sim);
    ftm_scene_destroy(scene);
    return status;
}
