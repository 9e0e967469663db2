/* SPDX-License-Identifier: GPL-3.0-or-later */
/* Element forces in the force transmittal integrator (docs/accuracy.md):
 *   - linear FEM forces at full depth reach the FEM static solution (ftm_fem,
 *     CHOLMOD) to < 1e-3 relative error, on hexahedra and on tetrahedra, in
 *     the colored, bfs and jacobi orders;
 *   - co-rotational forces match the linear ones under a small load;
 *   - a rigidly rotated (and moved) body has zero co-rotational elastic force
 *     and stays put when stepped, where the linear forces are large;
 *   - lumped masses add up to rho V; the run is deterministic; springs are
 *     untouched; bad definitions are refused with a message. */
#include <setjmp.h>
#include <stdarg.h>
#include <stddef.h>
#include <stdint.h>

#include <cmocka.h>

#include "ftm/fem.h"
#include "ftm/ftm.h"
#include "../rollback_check.h"

#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "cube.h"

/* Linear element forces, full depth, against the FEM solution. */
static double run_full_depth(int n, bool tets, ftm_forces forces, ftm_order order, double total,
                             const double *u_ref_in, double **u_out, int *steps_out)
{
    ftm_mesh *m = cube(n, tets, true, 0.0); /* damped_sim sets it */
    int32_t nn = ftm_mesh_node_count(m);
    double *f = malloc(sizeof(double) * 3 * (size_t)nn);
    ftm_contact c[4];
    int nc = top_load(m, n, total, c, f);
    double *u = fem_solution(m, f);
    ftm_mesh *damped = NULL;
    ftm_sim *sim = damped_sim(m, elem_def(forces, order), u, f, &damped);
    ftm_error err;
    assert_int_equal(ftm_sim_set_contacts(sim, c, nc, &err), FTM_OK);
    int steps = settle(sim, SIDE / (n - 1), 1e-11, 200000);
    const double *ref = u_ref_in ? u_ref_in : u;
    double e = rel_error(sim, ref);
    ftm_sim_stats st;
    ftm_sim_get_stats(sim, &st);
    assert_true(st.region_nodes >= ftm_mesh_node_count(m) - n * n); /* every free node */
    assert_int_equal(st.guard_events, 0);
    if (u_out) {
        const double *x = ftm_sim_positions(sim);
        *u_out = malloc(sizeof(double) * 3 * (size_t)nn);
        for (int32_t i = 0; i < nn; i++) {
            ftm_vec3 X = ftm_mesh_rest_position(damped, i);
            (*u_out)[3 * i] = x[3 * i] - X.x;
            (*u_out)[3 * i + 1] = x[3 * i + 1] - X.y;
            (*u_out)[3 * i + 2] = x[3 * i + 2] - X.z;
        }
    }
    if (steps_out)
        *steps_out = steps;
    ftm_sim_destroy(sim);
    ftm_mesh_destroy(damped);
    ftm_mesh_destroy(m);
    free(f);
    free(u);
    return e;
}

static void test_linear_hex_matches_fem(void **state)
{
    (void)state;
    static const ftm_order orders[] = {FTM_ORDER_LAYER_COLORED, FTM_ORDER_BFS,
                                       FTM_ORDER_LAYER_JACOBI};
    static const char *const names[] = {"colored", "bfs", "jacobi"};
    for (int o = 0; o < 3; o++) {
        int steps;
        double e = run_full_depth(6, false, FTM_FORCES_LINEAR_FEM, orders[o], 10.0, NULL, NULL,
                                  &steps);
        printf("linear FEM forces, hexahedra 6^3 nodes, %s order: rel. error %.3g after %d steps\n",
               names[o], e, steps);
        assert_true(e < 1e-3);
    }
}

static void test_linear_tet_matches_fem(void **state)
{
    (void)state;
    int steps;
    double e = run_full_depth(5, true, FTM_FORCES_LINEAR_FEM, FTM_ORDER_LAYER_COLORED, 10.0, NULL,
                              NULL, &steps);
    printf("linear FEM forces, tetrahedra 5^3 nodes: rel. error %.3g after %d steps\n", e, steps);
    assert_true(e < 1e-3);
}

/* Small load: co-rotational equilibrium = linear one (= FEM) to 1e-3. */
static void test_corot_small_load(void **state)
{
    (void)state;
    for (int tets = 0; tets < 2; tets++) {
        int steps;
        double e = run_full_depth(tets ? 5 : 6, tets, FTM_FORCES_COROT_FEM,
                                  FTM_ORDER_LAYER_COLORED, 1.0, NULL, NULL, &steps);
        printf("co-rotational FEM forces, %s, 1 N: rel. difference from linear FEM %.3g (%d "
               "steps)\n",
               tets ? "tetrahedra" : "hexahedra", e, steps);
        assert_true(e < 1e-3);
    }
}

/* rotation by angle about the unit axis (Rodrigues), row-major */
static void rotation(double ax, double ay, double az, double angle, double r[9])
{
    double c = cos(angle), s = sin(angle), t = 1 - c;
    double rr[9] = {t * ax * ax + c,      t * ax * ay - s * az, t * ax * az + s * ay,
                    t * ax * ay + s * az, t * ay * ay + c,      t * ay * az - s * ax,
                    t * ax * az - s * ay, t * ay * az + s * ax, t * az * az + c};
    memcpy(r, rr, sizeof rr);
}

static void test_corot_rotation_invariance(void **state)
{
    (void)state;
    for (int tets = 0; tets < 2; tets++) {
        /* a free body, damped enough for the layer-by-layer update (core.md,
         * "damping is required"): under-damped, round-off would grow */
        ftm_mesh *m = cube(5, tets, false, 10.0);
        int32_t n = ftm_mesh_node_count(m);
        double r[9], q = 1.0 / sqrt(3.0);
        rotation(q, q, q, 2.1, r); /* 120 degrees about (1,1,1) */
        double *x = malloc(sizeof(double) * 3 * (size_t)n), *f = malloc(sizeof(double) * 3 * (size_t)n);
        int32_t *nodes = malloc(sizeof(int32_t) * (size_t)n);
        for (int32_t i = 0; i < n; i++) {
            ftm_vec3 X = ftm_mesh_rest_position(m, i);
            double p[3] = {X.x, X.y, X.z};
            for (int a = 0; a < 3; a++)
                x[3 * i + a] = r[3 * a] * p[0] + r[3 * a + 1] * p[1] + r[3 * a + 2] * p[2] +
                               0.03 * (a + 1);
            nodes[i] = i;
        }
        ftm_error err;
        ftm_sim_def d = elem_def(FTM_FORCES_LINEAR_FEM, FTM_ORDER_LAYER_COLORED);
        ftm_sim *lin = NULL, *cr = NULL;
        assert_int_equal(ftm_sim_create(m, &d, &lin, &err), FTM_OK);
        d.forces = FTM_FORCES_COROT_FEM;
        d.time_step = 0.5 * ftm_sim_critical_time_step(lin);
        assert_int_equal(ftm_sim_create(m, &d, &cr, &err), FTM_OK);
        double fl = 0, fc = 0;
        assert_int_equal(ftm_sim_internal_forces(lin, x, f), FTM_OK);
        for (int32_t k = 0; k < 3 * n; k++)
            fl = fmax(fl, fabs(f[k]));
        assert_int_equal(ftm_sim_internal_forces(cr, x, f), FTM_OK);
        for (int32_t k = 0; k < 3 * n; k++)
            fc = fmax(fc, fabs(f[k]));
        printf("rigid 120 deg rotation, %s: largest nodal force linear %.3g N, co-rotational "
               "%.3g N\n",
               tets ? "tetrahedra" : "hexahedra", fl, fc);
        assert_true(fl > 100.0);     /* the linear forces see a huge fake strain */
        assert_true(fc < 1e-9 * fl); /* the rotated body is unstrained */
        /* stepped from rest in the rotated pose it stays there */
        assert_int_equal(
            ftm_sim_load_state(cr, 0, 5, nodes, x, x, n, NULL, 0, NULL, &err), FTM_OK);
        assert_int_equal(ftm_sim_run(cr, 200), FTM_OK);
        const double *xs = ftm_sim_positions(cr);
        double drift = 0;
        for (int32_t k = 0; k < 3 * n; k++)
            drift = fmax(drift, fabs(xs[k] - x[k]));
        printf("  after 200 steps the rotated body moved %.3g m\n", drift);
        assert_true(drift < 1e-12);
        ftm_sim_destroy(lin);
        ftm_sim_destroy(cr);
        free(x);
        free(f);
        free(nodes);
        ftm_mesh_destroy(m);
    }
}

static void test_lumped_mass_and_rest(void **state)
{
    (void)state;
    for (int tets = 0; tets < 2; tets++) {
        ftm_mesh *m = cube(4, tets, true, 10.0);
        ftm_error err;
        ftm_sim *sim = NULL;
        ftm_sim_def d = elem_def(FTM_FORCES_COROT_FEM, FTM_ORDER_LAYER_COLORED);
        assert_int_equal(ftm_sim_create(m, &d, &sim, &err), FTM_OK);
        d.time_step = 0.5 * ftm_sim_critical_time_step(sim);
        ftm_sim_destroy(sim);
        assert_int_equal(ftm_sim_create(m, &d, &sim, &err), FTM_OK);
        double total = 0;
        for (int32_t i = 0; i < ftm_mesh_node_count(m); i++)
            total += ftm_sim_masses(sim)[i];
        assert_true(fabs(total - DENSITY * SIDE * SIDE * SIDE) < 1e-12 * total);
        /* unloaded at rest: f = 0 exactly, nodes stay to round-off (b X - c X) */
        int32_t any = ftm_mesh_node_of_input(m, 4 * 4 * 4 - 1);
        ftm_contact c = {.node = any, .kind = FTM_CONTACT_FORCE, .value = {0, 0, 0}};
        assert_int_equal(ftm_sim_set_contacts(sim, &c, 1, &err), FTM_OK);
        assert_int_equal(ftm_sim_run(sim, 10), FTM_OK);
        for (int32_t i = 0; i < ftm_mesh_node_count(m); i++) {
            ftm_vec3 p = ftm_sim_position(sim, i), X = ftm_mesh_rest_position(m, i);
            double dev = fabs(p.x - X.x) + fabs(p.y - X.y) + fabs(p.z - X.z);
            if (!(dev < 1e-13))
                fail_msg("node %d moved %g m from rest", (int)i, dev);
        }
        ftm_sim_destroy(sim);
        ftm_mesh_destroy(m);
    }
}

/* Same inputs, same bits; a displacement contact has a reaction. */
static void test_deterministic_and_reaction(void **state)
{
    (void)state;
    ftm_mesh *m = cube(5, false, true, 10.0);
    uint64_t hash[2];
    for (int run = 0; run < 2; run++) {
        ftm_error err;
        ftm_sim *sim = NULL;
        ftm_sim_def d = elem_def(FTM_FORCES_COROT_FEM, FTM_ORDER_LAYER_COLORED);
        d.depth = 3;
        assert_int_equal(ftm_sim_create(m, &d, &sim, &err), FTM_OK);
        ftm_sim_destroy(sim);
        d.time_step = 1e-5;
        assert_int_equal(ftm_sim_create(m, &d, &sim, &err), FTM_OK);
        ftm_contact c = {.node = ftm_mesh_node_of_input(m, 2 + 5 * (2 + 5 * 4)),
                         .kind = FTM_CONTACT_DISPLACEMENT,
                         .value = {0, 0, -1e-3}};
        assert_int_equal(ftm_sim_set_contacts(sim, &c, 1, &err), FTM_OK);
        assert_int_equal(ftm_sim_run(sim, 300), FTM_OK);
        ftm_vec3 rf = ftm_sim_reaction(sim, 0);
        assert_true(rf.z > 0.1); /* the tissue pushes the probe back up */
        hash[run] = ftm_sim_hash(sim);
        ftm_sim_destroy(sim);
    }
    assert_true(hash[0] == hash[1]);
    ftm_mesh_destroy(m);
}

/* A step the guard rejects (far too long, no substeps) leaves the state
 * exactly as it was in every order: the element sweeps keep the previous
 * positions they overwrite where the rollback looks for them. */
static void test_rollback_every_order(void **state)
{
    (void)state;
    ftm_mesh *m = cube(5, false, true, 10.0);
    static const ftm_order orders[] = {FTM_ORDER_LAYER_COLORED, FTM_ORDER_BFS,
                                       FTM_ORDER_LAYER_JACOBI};
    for (int o = 0; o < 3; o++) {
        ftm_error err;
        ftm_sim *sim = NULL;
        ftm_sim_def d = elem_def(FTM_FORCES_LINEAR_FEM, orders[o]);
        d.depth = 3;
        d.time_step = 1e-2;
        d.max_substeps = 1;
        d.log = NULL; /* the time step is far above critical: said once, known */
        assert_int_equal(ftm_sim_create(m, &d, &sim, &err), FTM_OK);
        ftm_contact c = {.node = ftm_mesh_node_of_input(m, 2 + 5 * (2 + 5 * 4)),
                         .kind = FTM_CONTACT_FORCE, .value = {0, 0, -10.0}};
        assert_int_equal(ftm_sim_set_contacts(sim, &c, 1, &err), FTM_OK);
        assert_true(rejected_steps_roll_back(sim, 4) >= 2);
        ftm_sim_destroy(sim);
    }
    ftm_mesh_destroy(m);
}

static void test_bad_definitions(void **state)
{
    (void)state;
    ftm_mesh *m = cube(3, false, true, 1.0);
    ftm_error err;
    ftm_sim *sim = NULL;
    ftm_sim_def d = elem_def(FTM_FORCES_LINEAR_FEM, FTM_ORDER_LAYER_COLORED);
    d.young = 0;
    assert_int_equal(ftm_sim_create(m, &d, &sim, &err), FTM_EINVAL);
    assert_contains(err.message, "Young's modulus");
    d = elem_def(FTM_FORCES_LINEAR_FEM, FTM_ORDER_LAYER_COLORED);
    d.poisson = 0.5;
    assert_int_equal(ftm_sim_create(m, &d, &sim, &err), FTM_EINVAL);
    assert_contains(err.message, "Poisson's ratio");
    d = elem_def((ftm_forces)7, FTM_ORDER_LAYER_COLORED);
    assert_int_equal(ftm_sim_create(m, &d, &sim, &err), FTM_EINVAL);
    assert_contains(err.message, "unknown forces");
    assert_null(sim);
    ftm_mesh_destroy(m);
    /* a 2D lattice has no volume elements */
    ftm_mesh_builder *b = ftm_mesh_builder_create();
    ftm_lattice2d_def ld = ftm_default_lattice2d_def();
    ld.nx = ld.ny = 4;
    assert_int_equal(ftm_generate_lattice2d(b, &ld, &err), FTM_OK);
    assert_int_equal(ftm_mesh_build(b, NULL, &m, &err), FTM_OK);
    ftm_mesh_builder_destroy(b);
    d = elem_def(FTM_FORCES_COROT_FEM, FTM_ORDER_LAYER_COLORED);
    assert_int_equal(ftm_sim_create(m, &d, &sim, &err), FTM_EINVAL);
    assert_contains(err.message, "hexahedra or tetrahedra");
    ftm_mesh_destroy(m);
    /* an inverted hexahedron is named */
    b = ftm_mesh_builder_create();
    for (int k = 0; k < 8; k++) {
        ftm_node_def nd = ftm_default_node_def();
        nd.position = (ftm_vec3){(k == 1 || k == 2 || k == 5 || k == 6) ? 1.0 : 0.0,
                                 (k == 2 || k == 3 || k == 6 || k == 7) ? 1.0 : 0.0,
                                 k >= 4 ? -1.0 : 0.0}; /* top below bottom */
        assert_true(ftm_mesh_builder_add_node(b, &nd) >= 0);
    }
    int32_t v[8] = {0, 1, 2, 3, 4, 5, 6, 7};
    assert_int_equal(ftm_mesh_builder_add_hexahedron(b, v), FTM_OK);
    ftm_link_def l = {0, 1, 1.0, -1.0};
    assert_int_equal(ftm_mesh_builder_add_link(b, &l), FTM_OK);
    assert_int_equal(ftm_mesh_build(b, NULL, &m, &err), FTM_OK);
    ftm_mesh_builder_destroy(b);
    assert_int_equal(ftm_sim_create(m, &d, &sim, &err), FTM_EINVAL);
    assert_contains(err.message, "hexahedron 0");
    assert_contains(err.message, "inverted");
    ftm_mesh_destroy(m);
}

/* The default definition keeps springs: the element fields change nothing. */
static void test_springs_default(void **state)
{
    (void)state;
    ftm_sim_def d = ftm_default_sim_def();
    assert_int_equal(d.forces, FTM_FORCES_SPRINGS);
    ftm_mesh *m = cube(4, false, true, 1.0);
    ftm_error err;
    ftm_sim *sim = NULL;
    assert_int_equal(ftm_sim_create(m, &d, &sim, &err), FTM_OK);
    assert_true(ftm_sim_critical_time_step(sim) == ftm_mesh_critical_time_step(m));
    assert_true(ftm_sim_masses(sim)[0] == ftm_mesh_mass(m, 0));
    ftm_sim_destroy(sim);
    ftm_mesh_destroy(m);
}


/* [sim] forces = ... in a scene: the [fem] material goes into the definition. */
static void test_scene_forces(void **state)
{
    (void)state;
    static const char ok[] = "[mesh]\ngenerator = lattice3d\nnx = 3\nny = 3\nnz = 3\n"
                             "spacing = 0.01\nfixed_faces = zmin\n"
                             "[material]\nmass = 0.001\nstiffness = 10\ndamping = 0.5\n"
                             "[sim]\nforces = corot-fem\n"
                             "[fem]\nyoung = 1e5\npoisson = 0.3\ndensity = 1000\n";
    ftm_scene *sc = NULL;
    ftm_error err;
    assert_int_equal(ftm_scene_parse(ok, sizeof ok - 1, "ok", &sc, &err), FTM_OK);
    ftm_sim_def d = ftm_scene_sim_def(sc);
    assert_int_equal(d.forces, FTM_FORCES_COROT_FEM);
    assert_true(d.young == 1e5 && d.poisson == 0.3 && d.density == 1000);
    ftm_sim *sim = NULL;
    assert_int_equal(ftm_sim_create(ftm_scene_mesh(sc), &d, &sim, &err), FTM_OK);
    assert_true(fabs(ftm_sim_masses(sim)[0] * 8 - 1000 * 1e-6) < 1e-15); /* a corner: 1/8 cell */
    ftm_sim_destroy(sim);
    ftm_scene_destroy(sc);
    static const char no_fem[] = "[mesh]\ngenerator = lattice3d\nnx = 3\nny = 3\nnz = 3\n"
                                 "spacing = 0.01\n[material]\nmass = 0.001\nstiffness = 10\n"
                                 "[sim]\nforces = linear-fem\n";
    assert_int_equal(ftm_scene_parse(no_fem, sizeof no_fem - 1, "no_fem", &sc, &err), FTM_EPARSE);
    assert_contains(err.message, "no_fem:11:");
    assert_contains(err.message, "[fem]");
    static const char flat[] = "[mesh]\ngenerator = lattice2d\nnx = 3\nny = 3\nspacing = 1\n"
                               "[material]\nmass = 1\nstiffness = 1\n[sim]\nforces = linear-fem\n"
                               "[fem]\nyoung = 1\npoisson = 0.3\n";
    assert_int_equal(ftm_scene_parse(flat, sizeof flat - 1, "flat", &sc, &err), FTM_EPARSE);
    assert_contains(err.message, "flat:10:");
    assert_contains(err.message, "hexahedra or tetrahedra");
    static const char bad[] = "[mesh]\ngenerator = lattice3d\nnx = 2\nny = 2\nnz = 2\n"
                              "spacing = 1\n[material]\nmass = 1\nstiffness = 1\n"
                              "[sim]\nforces = fem\n";
    assert_int_equal(ftm_scene_parse(bad, sizeof bad - 1, "bad", &sc, &err), FTM_EPARSE);
    assert_contains(err.message, "springs, linear-fem, corot-fem or neo-hookean");
}

int main(void)
{
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(test_linear_hex_matches_fem),
        cmocka_unit_test(test_linear_tet_matches_fem),
        cmocka_unit_test(test_corot_small_load),
        cmocka_unit_test(test_corot_rotation_invariance),
        cmocka_unit_test(test_lumped_mass_and_rest),
        cmocka_unit_test(test_deterministic_and_reaction),
        cmocka_unit_test(test_rollback_every_order),
        cmocka_unit_test(test_bad_definitions),
        cmocka_unit_test(test_springs_default),
        cmocka_unit_test(test_scene_forces),
    };
    return cmocka_run_group_tests(tests, NULL, NULL);
}
