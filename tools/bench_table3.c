/* SPDX-License-Identifier: GPL-3.0-or-later */
/* `ftm bench table3`: the paper's Table 3 timing experiment.
 *
 * 50 x 50 2D triangular lattice (paper Fig. 3), border fixed, a constant force
 * on the centre node, penetration depth 1..20. For each depth: nodes in the
 * region (against Eq. 9), the time of one neighbour search (BFS), of one
 * step with the search repeated every step (as the paper timed it) and of
 * one step with the layers cached, in the default (colored) order and in the
 * jacobi order (whose search needs no colour sets); medians over many steps,
 * beside the paper's figures (Pentium III 800 MHz). Then the intra-layer
 * order variants: step time at the deepest depth and how far their
 * equilibria differ from the paper's plain BFS order.
 *
 * Each figure is measured in ROUNDS rounds that visit every row in turn, and
 * reported as the median of its rounds' medians: a burst of other work on the
 * machine (a shared virtual machine has them) then spoils one round of a few
 * rows instead of a whole row. */
#include "bench.h"
#include "commands.h"

#include "ftm/ftm.h"
#include "ftm/internal/layers.h"

#include <errno.h>
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

static int cmp_double(const void *a, const void *b)
{
    double x = *(const double *)a, y = *(const double *)b;
    return (x > y) - (x < y);
}

double ftm_bench_median(double *v, int n)
{
    qsort(v, (size_t)n, sizeof *v, cmp_double);
    return n % 2 ? v[n / 2] : 0.5 * (v[n / 2 - 1] + v[n / 2]);
}

static const int depths[] = {1, 2, 3, 4, 5, 10, 15, 20};
/* Choi, Sun, Heng (2004), Table 3 */
static const int paper_nodes[] = {7, 19, 37, 61, 91, 331, 721, 1261};
static const double paper_search_ms[] = {0.02, 0.05, 0.12, 0.23, 0.39, 2.59, 10.85, 28.79};
static const double paper_step_ms[] = {0.14, 0.25, 0.42, 0.64, 0.96, 4.17, 13.84, 30.97};
#define NDEPTH ((int)(sizeof depths / sizeof depths[0]))
#define ROUNDS 5

typedef struct bench_setup {
    ftm_mesh *mesh;
    int32_t centre;
    ftm_sim_def def;
    ftm_contact load;
} bench_setup;

static int setup(bench_setup *b)
{
    ftm_error err;
    ftm_mesh_builder *mb = ftm_mesh_builder_create();
    ftm_lattice2d_def ld = ftm_default_lattice2d_def(); /* 50 x 50, spacing 1, border fixed */
    ld.material.node_mass = 1.0;
    ld.material.node_damping = 0.5;
    ld.material.stiffness = 1.0;
    int rc = ftm_generate_lattice2d(mb, &ld, &err);
    if (!rc)
        rc = ftm_mesh_build(mb, NULL, &b->mesh, &err);
    ftm_mesh_builder_destroy(mb);
    if (rc) {
        fprintf(stderr, "ftm bench table3: %s\n", err.message);
        return rc;
    }
    b->centre = ftm_mesh_node_of_input(b->mesh, 25 + 50 * 25);
    b->def = ftm_default_sim_def();
    b->def.time_step = 0.1; /* critical: 2/sqrt(12) = 0.577 */
    b->load = (ftm_contact){.node = b->centre, .group = 0, .kind = FTM_CONTACT_FORCE,
                            .value = {0.0, -0.1, 0.0}};
    return 0;
}

/* A simulation of the setup with depth, order, layer caching and the
 * planar sweep as given, the force on the centre node; NULL if it fails. */
static ftm_sim *loaded_sim(const bench_setup *b, int depth, ftm_order order, bool cache,
                           bool planar)
{
    ftm_sim_def d = b->def;
    d.depth = depth;
    d.order = order;
    d.cache_layers = cache;
    d.planar_kernel = planar;
    ftm_sim *sim;
    if (ftm_sim_create(b->mesh, &d, &sim, NULL))
        return NULL;
    ftm_sim_set_contacts(sim, &b->load, 1, NULL);
    return sim;
}

/* Median time of one step [us] over `steps` steps after a warm-up of as
 * many steps, at most 200 (the load deforms the region first). */
static double time_steps(const bench_setup *b, int depth, ftm_order order, bool cache, int steps,
                         double *samples, bool planar)
{
    ftm_sim *sim = loaded_sim(b, depth, order, cache, planar);
    if (!sim)
        return NAN;
    ftm_sim_run(sim, steps < 200 ? steps : 200);
    for (int i = 0; i < steps; i++) {
        double t0 = ftm_bench_now_us();
        ftm_sim_step(sim);
        samples[i] = ftm_bench_now_us() - t0;
    }
    ftm_sim_destroy(sim);
    return ftm_bench_median(samples, steps);
}

/* Mean time of one step [us] over `steps` steps with the layers cached and
 * the force moving every `every` steps among the centre node and two of
 * its neighbours, as a probe sliding over the tissue moves its contacts:
 * a mean, since the steps after a move cost more than the others. */
static double time_moving(const bench_setup *b, int depth, ftm_order order, int every, int steps)
{
    ftm_sim *sim = loaded_sim(b, depth, order, true, true);
    if (!sim)
        return NAN;
    const int32_t at[3] = {b->centre, ftm_mesh_node_of_input(b->mesh, 26 + 50 * 25),
                           ftm_mesh_node_of_input(b->mesh, 25 + 50 * 26)};
    ftm_contact c = b->load;
    double t0 = 0.0;
    for (int i = -200; i < steps; i++) { /* 200 untimed steps first */
        if (i == 0)
            t0 = ftm_bench_now_us();
        if ((i + 200) % every == 0) {
            c.node = at[((i + 200) / every) % 3];
            ftm_sim_set_contacts(sim, &c, 1, NULL);
        }
        ftm_sim_step(sim);
    }
    const double us = (ftm_bench_now_us() - t0) / steps;
    ftm_sim_destroy(sim);
    return us;
}

/* with_sets: the search the colored order needs (layers split into
 * independent sets); without: the plain one of the bfs and jacobi orders */
static double time_search(const bench_setup *b, int depth, bool with_sets, int reps,
                          double *samples, int32_t *nodes)
{
    ftm_layering ly;
    if (ftm_layering_init(&ly, ftm_mesh_node_count(b->mesh)))
        return NAN;
    for (int i = 0; i < reps; i++) {
        double t0 = ftm_bench_now_us();
        ftm_layering_build(&ly, b->mesh, &b->centre, 1, depth, with_sets);
        samples[i] = ftm_bench_now_us() - t0;
    }
    *nodes = ly.count;
    ftm_layering_free(&ly);
    return ftm_bench_median(samples, reps);
}

/* Runs to equilibrium with one order; returns positions (caller frees). */
static double *equilibrium(const bench_setup *b, int depth, ftm_order order, int steps,
                           double *residual)
{
    ftm_sim *sim = loaded_sim(b, depth, order, true, true);
    if (!sim)
        return NULL;
    ftm_sim_run(sim, steps);
    int32_t n = ftm_mesh_node_count(b->mesh);
    double *x = malloc((size_t)n * 3 * sizeof *x);
    memcpy(x, ftm_sim_positions(sim), (size_t)n * 3 * sizeof *x);
    ftm_sim_step(sim);
    const double *x2 = ftm_sim_positions(sim);
    double r = 0.0;
    for (int32_t i = 0; i < 3 * n; i++)
        r = fmax(r, fabs(x2[i] - x[i]));
    *residual = r;
    ftm_sim_destroy(sim);
    return x;
}

static const char *order_name(ftm_order o)
{
    return o == FTM_ORDER_BFS ? "bfs" : o == FTM_ORDER_LAYER_JACOBI ? "jacobi" : "colored";
}

int ftm_bench_table3(int argc, char **argv)
{
    bool json = false;
    const char *json_file = NULL;
    int steps = 20000, eq_steps = 40000;
    for (int i = 1; i < argc; i++) {
        const char *a = argv[i];
        bool valued = strcmp(a, "--json-file") == 0 || strcmp(a, "--eq-steps") == 0 ||
                      strcmp(a, "--steps") == 0;
        if (valued && i + 1 >= argc) {
            fprintf(stderr, "ftm bench table3: %s needs a value\n", a);
            return 2;
        }
        if (strcmp(a, "--json") == 0)
            json = true;
        else if (strcmp(a, "--json-file") == 0)
            json_file = argv[++i];
        else if (strcmp(a, "--eq-steps") == 0) {
            if (!ftm_cli_int(argv[++i], 1, 10000000, &eq_steps)) {
                fprintf(stderr, "ftm bench table3: --eq-steps must be in 1..10000000\n");
                return 2;
            }
        } else if (strcmp(a, "--steps") == 0) {
            if (!ftm_cli_int(argv[++i], 11, 10000000, &steps)) {
                fprintf(stderr, "ftm bench table3: --steps must be in 11..10000000\n");
                return 2;
            }
        } else if (strcmp(a, "--help") == 0 || strcmp(a, "-h") == 0) {
            printf("usage: ftm bench table3 [--steps N] [--eq-steps N] [--json] "
                   "[--json-file FILE]\n"
                   "  --steps N         timed steps per measurement (default 20000), taken in\n"
                   "                    %d rounds over all rows\n"
                   "  --eq-steps N      steps run to equilibrium for the order comparison\n"
                   "                    (default 40000)\n"
                   "  --json            print {\"rows\":[{\"depth\":..,\"nodes\":..,"
                   "\"search_us\":..,\"step_us\":..},...],\"orders\":[...]}\n"
                   "                    (rows also hold step_cached_us and the jacobi order's\n"
                   "                    jacobi_search_us, jacobi_step_us, jacobi_step_cached_us;\n"
                   "                    full_sweep: the deepest row's steps with the full sweep;\n"
                   "                    moving: mean step there, the force moving every N steps)\n"
                   "  --json-file FILE  print the table and write the same run's JSON to FILE\n\n"
                   "exit status: 0 success, 1 the benchmark could not run, 2 bad arguments or\n"
                   "an output that cannot be written\n",
                   ROUNDS);
            return 0;
        } else {
            fprintf(stderr, "ftm bench table3: unknown option '%s' (try --help)\n", a);
            return 2;
        }
    }
    FILE *jf = NULL;
    if (json_file && !(jf = fopen(json_file, "w"))) {
        fprintf(stderr, "ftm bench table3: %s: cannot write: %s\n", json_file, strerror(errno));
        return 2;
    }
    bench_setup b;
    if (setup(&b)) {
        if (jf)
            fclose(jf);
        return 1;
    }
    const int per = steps / ROUNDS > 0 ? steps / ROUNDS : 1; /* samples per round */
    double *samples = malloc((size_t)per * sizeof *samples);
    /* untimed: brings the core up to speed before the first (shortest) rows */
    time_steps(&b, depths[NDEPTH - 1], FTM_ORDER_LAYER_COLORED, false, per, samples, true);
    /* per round: search, step, cached (colored), the same (jacobi) per row,
     * then the bfs order's step and cached at the deepest depth (the other
     * orders' are the last row's), then the colored and jacobi step and
     * cached there with the full sweep (the lattice lies in z = 0, so the
     * rows run the planar one; a mesh off the plane runs the full one) */
    enum { SEARCH, STEP, CACHED, JSEARCH, JSTEP, JCACHED, FIGS };
    const ftm_order orders[3] = {FTM_ORDER_BFS, FTM_ORDER_LAYER_COLORED, FTM_ORDER_LAYER_JACOBI};
    const int dmax = depths[NDEPTH - 1];
    double fig[NDEPTH][FIGS][ROUNDS], bfs[2][ROUNDS], full[4][ROUNDS];
    enum { NMOVE = 4 };
    static const int every[NMOVE] = {1, 2, 5, 10};
    double moving[NMOVE][2][ROUNDS]; /* colored, jacobi */
    int32_t nodes[NDEPTH];
    for (int k = 0; k < ROUNDS; k++) {
        for (int r = 0; r < NDEPTH; r++) {
            const int d = depths[r];
            fig[r][SEARCH][k] = time_search(&b, d, true, per, samples, &nodes[r]);
            fig[r][STEP][k] =
                time_steps(&b, d, FTM_ORDER_LAYER_COLORED, false, per, samples, true);
            fig[r][CACHED][k] =
                time_steps(&b, d, FTM_ORDER_LAYER_COLORED, true, per, samples, true);
            fig[r][JSEARCH][k] = time_search(&b, d, false, per, samples, &nodes[r]);
            fig[r][JSTEP][k] = time_steps(&b, d, FTM_ORDER_LAYER_JACOBI, false, per, samples, true);
            fig[r][JCACHED][k] =
                time_steps(&b, d, FTM_ORDER_LAYER_JACOBI, true, per, samples, true);
        }
        bfs[0][k] = time_steps(&b, dmax, FTM_ORDER_BFS, false, per, samples, true);
        bfs[1][k] = time_steps(&b, dmax, FTM_ORDER_BFS, true, per, samples, true);
        for (int f = 0; f < 4; f++) { /* colored, then jacobi; fresh, then cached */
            const ftm_order o = f < 2 ? FTM_ORDER_LAYER_COLORED : FTM_ORDER_LAYER_JACOBI;
            full[f][k] = time_steps(&b, dmax, o, f & 1, per, samples, false);
        }
        for (int e = 0; e < NMOVE; e++) {
            moving[e][0][k] = time_moving(&b, dmax, FTM_ORDER_LAYER_COLORED, every[e], per);
            moving[e][1][k] = time_moving(&b, dmax, FTM_ORDER_LAYER_JACOBI, every[e], per);
        }
    }
    double movm[NMOVE][2];
    for (int e = 0; e < NMOVE; e++)
        for (int o = 0; o < 2; o++)
            movm[e][o] = ftm_bench_median(moving[e][o], ROUNDS);
    double fullm[4];
    for (int f = 0; f < 4; f++)
        fullm[f] = ftm_bench_median(full[f], ROUNDS);
    double search[NDEPTH], step[NDEPTH], cached[NDEPTH];
    double jsearch[NDEPTH], jstep[NDEPTH], jcached[NDEPTH];
    for (int r = 0; r < NDEPTH; r++) {
        search[r] = ftm_bench_median(fig[r][SEARCH], ROUNDS);
        step[r] = ftm_bench_median(fig[r][STEP], ROUNDS);
        cached[r] = ftm_bench_median(fig[r][CACHED], ROUNDS);
        jsearch[r] = ftm_bench_median(fig[r][JSEARCH], ROUNDS);
        jstep[r] = ftm_bench_median(fig[r][JSTEP], ROUNDS);
        jcached[r] = ftm_bench_median(fig[r][JCACHED], ROUNDS);
    }
    /* order variants at the deepest depth: equilibria against the bfs order */
    double ostep[3], ocached[3], odiff[3], ores[3];
    double *ref = NULL;
    ostep[0] = ftm_bench_median(bfs[0], ROUNDS);
    ocached[0] = ftm_bench_median(bfs[1], ROUNDS);
    ostep[1] = step[NDEPTH - 1];
    ocached[1] = cached[NDEPTH - 1];
    ostep[2] = jstep[NDEPTH - 1];
    ocached[2] = jcached[NDEPTH - 1];
    for (int o = 0; o < 3; o++) {
        double *x = equilibrium(&b, dmax, orders[o], eq_steps, &ores[o]);
        if (!ref) {
            ref = x;
            odiff[o] = 0.0;
        } else {
            double d = 0.0;
            for (int32_t i = 0; i < 3 * ftm_mesh_node_count(b.mesh); i++)
                d = fmax(d, fabs(x[i] - ref[i]));
            odiff[o] = d; /* spacing is 1: already relative to the spring length */
            free(x);
        }
    }
    free(ref);
    free(samples);

    for (int pass = 0; pass < 2; pass++) {
        /* the JSON to stdout (--json) and/or to the file (--json-file) */
        FILE *out = pass == 0 ? (json ? stdout : NULL) : jf;
        if (!out)
            continue;
        fprintf(out, "{\"bench\":\"table3\",\"steps\":%d,\"rounds\":%d,\"rows\":[", steps,
                ROUNDS);
        for (int r = 0; r < NDEPTH; r++)
            fprintf(out,
                    "%s{\"depth\":%d,\"nodes\":%d,\"paper_nodes\":%d,\"search_us\":%s,"
                    "\"step_us\":%s,\"step_cached_us\":%s,\"paper_search_ms\":%s,"
                    "\"paper_step_ms\":%s,\"node_updates_per_s\":%s,"
                    "\"jacobi_search_us\":%s,\"jacobi_step_us\":%s,"
                    "\"jacobi_step_cached_us\":%s}",
                    r ? "," : "", depths[r], (int)nodes[r], paper_nodes[r],
                    FTM_JN("%.3f", search[r]), FTM_JN("%.3f", step[r]), FTM_JN("%.3f", cached[r]),
                    FTM_JN("%.2f", paper_search_ms[r]), FTM_JN("%.2f", paper_step_ms[r]),
                    FTM_JN("%.4g", nodes[r] / (step[r] * 1e-6)), FTM_JN("%.3f", jsearch[r]),
                    FTM_JN("%.3f", jstep[r]), FTM_JN("%.3f", jcached[r]));
        fprintf(out, "],\"orders\":[");
        for (int o = 0; o < 3; o++)
            fprintf(out,
                    "%s{\"order\":\"%s\",\"depth\":%d,\"step_us\":%s,"
                    "\"step_cached_us\":%s,\"max_diff_vs_bfs\":%s,\"residual\":%s}",
                    o ? "," : "", order_name(orders[o]), dmax, FTM_JN("%.3f", ostep[o]),
                    FTM_JN("%.3f", ocached[o]), FTM_JN("%.3e", odiff[o]), FTM_JN("%.3e", ores[o]));
        fprintf(out,
                "],\"full_sweep\":{\"depth\":%d,\"step_us\":%s,\"step_cached_us\":%s,"
                "\"jacobi_step_us\":%s,\"jacobi_step_cached_us\":%s},\"moving\":[",
                dmax, FTM_JN("%.3f", fullm[0]), FTM_JN("%.3f", fullm[1]), FTM_JN("%.3f", fullm[2]),
                FTM_JN("%.3f", fullm[3]));
        for (int e = 0; e < NMOVE; e++)
            fprintf(out, "%s{\"depth\":%d,\"every\":%d,\"step_us\":%s,\"jacobi_step_us\":%s}",
                    e ? "," : "", dmax, every[e], FTM_JN("%.3f", movm[e][0]),
                    FTM_JN("%.3f", movm[e][1]));
        fprintf(out, "]}\n");
    }
    if (jf && ftm_close_output(jf, "ftm bench table3", json_file) != 0) {
        ftm_mesh_destroy(b.mesh);
        return 2;
    }
    if (!json) {
        printf("Paper Table 3: 50x50 2D lattice, force on the centre node; medians of %d steps\n"
               "in %d rounds over the rows (each figure: the median of its rounds' medians)\n"
               "(step = one time step with a fresh neighbour search, as the paper timed it;\n"
               " cached = the layers reused while the contact is unchanged, FTM's default;\n"
               " colored = the default order, whose search splits layers into independent\n"
               " sets; jacobi = each layer from the state before it, plain search)\n\n",
               steps, ROUNDS);
        printf("%5s %6s %6s | %27s | %27s | %10s %10s %8s %7s\n", "", "", "", "colored (default)",
               "jacobi", "", "", "", "");
        printf("%5s %6s %6s | %8s %8s %9s | %8s %8s %9s | %10s %10s %8s %7s\n", "depth", "nodes",
               "Eq.9", "search", "step", "cached", "search", "step", "cached", "paper srch",
               "paper step", "speedup", "Mupd/s");
        for (int r = 0; r < NDEPTH; r++)
            printf("%5d %6d %6d | %8.3f %8.3f %9.3f | %8.3f %8.3f %9.3f | %8.2fms %8.2fms "
                   "%7.0fx %7.1f\n",
                   depths[r], (int)nodes[r], 3 * depths[r] * depths[r] + 3 * depths[r] + 1,
                   search[r], step[r], cached[r], jsearch[r], jstep[r], jcached[r],
                   paper_search_ms[r], paper_step_ms[r], paper_step_ms[r] * 1e3 / step[r],
                   nodes[r] / step[r]);
        printf("(times in us; speedup: the paper's step over the colored step with its search;\n"
               " Mupd/s: million node updates per second in that step, as node_updates_per_s\n"
               " in the JSON)\n");
        printf("\nIntra-layer order at depth %d (equilibrium after %d steps; spacing = 1):\n\n",
               dmax, eq_steps);
        printf("%8s | %10s %10s | %16s %12s\n", "order", "step us", "cached us",
               "max |x - x_bfs|", "residual");
        for (int o = 0; o < 3; o++)
            printf("%8s | %10.3f %10.3f | %16.3e %12.3e\n", order_name(orders[o]), ostep[o],
                   ocached[o], odiff[o], ores[o]);
        printf("\nThe lattice lies in the plane z = 0 and its load too, so the colored and\n"
               "jacobi sweeps above leave z out (bit-identical; ftm_sim_def.planar_kernel).\n"
               "At depth %d with the full sweep, as a mesh off the plane runs it:\n\n", dmax);
        printf("%8s | %10s %10s\n", "order", "step us", "cached us");
        printf("%8s | %10.3f %10.3f\n%8s | %10.3f %10.3f\n", "colored", fullm[0], fullm[1],
               "jacobi", fullm[2], fullm[3]);
        printf("\nA moving contact at depth %d: the force moves among three neighbouring nodes\n"
               "every N steps, layers cached (mean us per step, as a sliding probe pays):\n\n",
               dmax);
        printf("%8s | %10s %10s\n", "every N", "colored", "jacobi");
        for (int e = 0; e < NMOVE; e++)
            printf("%8d | %10.3f %10.3f\n", every[e], movm[e][0], movm[e][1]);
    }
    ftm_mesh_destroy(b.mesh);
    return 0;
}
