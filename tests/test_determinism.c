/* SPDX-License-Identifier: GPL-3.0-or-later */
/* Golden hashes: fixed scenarios whose final ftm_sim_hash is written down
 * here. The same inputs must give the same bits on every machine, compiler
 * version and build type; a change of numerics (even one ulp anywhere) shows
 * up as a failure. If a change of the integrator is intended, update the
 * constants in the same commit and say why, and raise
 * FTM_ARITHMETIC_REVISION (ftm/sim.h) with them: peers of the old revision
 * can no longer replay the new one's sessions, and the revision is how they
 * are told. */
#include "ftm/ftm.h"

#include <inttypes.h>
#include <setjmp.h>
#include <stdarg.h>
#include <stddef.h>
#include <stdio.h>
#include <stdlib.h>

#include <cmocka.h>

typedef struct scenario {
    const char *name;
    ftm_order order;
    bool lattice3d;
    uint64_t expected;
    bool elastic; /* the elastic far field at depth 2 (its ring and solve) */
} scenario;

/* Runs a press / move / release / relax script and returns the final hash.
 * With bc (3D): the bottom not fixed but sliding on z = 0 (one node of it
 * on a tilted plane instead, one on a line), and two top nodes on springs
 * to ground (docs/scene-format.md, Boundary conditions). */
static uint64_t run_bc(const scenario *sc, bool bc)
{
    ftm_mesh_builder *b = ftm_mesh_builder_create();
    ftm_error err;
    int32_t a, c;
    if (sc->lattice3d) {
        ftm_lattice3d_def d = ftm_default_lattice3d_def();
        d.nx = d.ny = d.nz = 10;
        d.spacing = (ftm_vec3){0.01, 0.01, 0.01};
        d.stencil = FTM_STENCIL_18;
        d.material = (ftm_material_def){0.001, 0.3, 50.0, {1.0, 1.0, 2.0}};
        if (bc)
            d.fixed_faces = 0;
        assert_int_equal(ftm_generate_lattice3d(b, &d, &err), FTM_OK);
        for (int32_t i = 0; bc && i < 100; i++)
            assert_int_equal(ftm_mesh_builder_add_slide(b, i, i == 55 ? (ftm_vec3){0.3, -0.2, 1.0}
                                                                      : (ftm_vec3){0, 0, 1}),
                             FTM_OK);
        if (bc) {
            assert_int_equal(ftm_mesh_builder_add_slide(b, 9, (ftm_vec3){0, 1, 0}), FTM_OK);
            assert_int_equal(ftm_mesh_builder_add_ground_spring(b, 900, 30.0), FTM_OK);
            assert_int_equal(ftm_mesh_builder_add_ground_spring(b, 5 + 10 * (4 + 10 * 9), 10.0),
                             FTM_OK);
        }
        a = 4 + 10 * (4 + 10 * 9);
        c = 6 + 10 * (5 + 10 * 9);
    } else {
        ftm_lattice2d_def d = ftm_default_lattice2d_def();
        d.material = (ftm_material_def){1.0, 0.5, 1.0, {1.0, 1.0, 1.0}};
        assert_int_equal(ftm_generate_lattice2d(b, &d, &err), FTM_OK);
        a = 25 + 50 * 25;
        c = 28 + 50 * 24;
    }
    ftm_mesh *m = NULL;
    assert_int_equal(ftm_mesh_build(b, NULL, &m, &err), FTM_OK);
    ftm_mesh_builder_destroy(b);
    ftm_sim_def sd = ftm_default_sim_def();
    sd.order = sc->order;
    sd.time_step = sc->lattice3d ? 1e-3 : 0.1;
    sd.depth = sc->lattice3d ? 6 : 12;
    if (sc->elastic) {
        sd.far_field = FTM_FAR_FIELD_ELASTIC;
        sd.depth = 2;
    }
    ftm_sim *sim = NULL;
    assert_int_equal(ftm_sim_create(m, &sd, &sim, &err), FTM_OK);
    double s = sc->lattice3d ? 0.001 : 0.1;
    ftm_contact press[2] = {
        {.node = ftm_mesh_node_of_input(m, a), .group = 0, .kind = FTM_CONTACT_FORCE,
         .value = {0.0, -0.3 * s, -1.0 * s}},
        {.node = ftm_mesh_node_of_input(m, c), .group = 1, .kind = FTM_CONTACT_DISPLACEMENT,
         .value = {0.2 * s, 0.1 * s, -2.0 * s}},
    };
    /* (the elastic runs relax back to rest exactly: their pressed states
     * are what tells one arithmetic from another) */
    uint64_t pressed = 0;
    assert_int_equal(ftm_sim_set_contacts(sim, press, 2, &err), FTM_OK);
    assert_int_equal(ftm_sim_run(sim, 300), FTM_OK);
    pressed = 31 * pressed + ftm_sim_hash(sim);
    press[0].value.x = 0.5 * s; /* a value change: same layers */
    assert_int_equal(ftm_sim_set_contacts(sim, press, 2, &err), FTM_OK);
    assert_int_equal(ftm_sim_run(sim, 200), FTM_OK);
    pressed = 31 * pressed + ftm_sim_hash(sim);
    assert_int_equal(ftm_sim_set_contacts(sim, press + 1, 1, &err), FTM_OK); /* one released */
    assert_int_equal(ftm_sim_run(sim, 200), FTM_OK);
    pressed = 31 * pressed + ftm_sim_hash(sim);
    assert_int_equal(ftm_sim_set_contacts(sim, NULL, 0, &err), FTM_OK); /* all released */
    assert_int_equal(ftm_sim_run(sim, 300), FTM_OK);
    uint64_t h = ftm_sim_hash(sim) ^ (sc->elastic || bc ? pressed : 0);
    ftm_sim_destroy(sim);
    ftm_mesh_destroy(m);
    return h;
}

static uint64_t run(const scenario *sc) { return run_bc(sc, false); }

static const scenario scenarios[] = {
    {"lattice2d colored", FTM_ORDER_LAYER_COLORED, false, 0x4b86508014e3ad2cULL, false},
    {"lattice2d bfs", FTM_ORDER_BFS, false, 0x82fa75117fefbfaeULL, false},
    {"lattice2d jacobi", FTM_ORDER_LAYER_JACOBI, false, 0xff31735f5f5c721cULL, false},
    {"lattice3d colored", FTM_ORDER_LAYER_COLORED, true, 0xc365fafeb82cbcb8ULL, false},
    {"lattice3d bfs", FTM_ORDER_BFS, true, 0xe0d595223eb48426ULL, false},
    {"lattice3d jacobi", FTM_ORDER_LAYER_JACOBI, true, 0xb816544daa562651ULL, false},
    {"lattice3d colored, elastic far field", FTM_ORDER_LAYER_COLORED, true, 0x4eae6edf591c6470ULL, true},
    {"lattice3d bfs, elastic far field", FTM_ORDER_BFS, true, 0xc530012bdf2e067fULL, true},
};

static void test_golden_hashes(void **state)
{
    (void)state;
    int bad = 0;
    for (size_t i = 0; i < sizeof scenarios / sizeof scenarios[0]; i++) {
        uint64_t h = run(&scenarios[i]);
        if (h != scenarios[i].expected) {
            print_error("%s: hash 0x%016" PRIx64 "ULL, expected 0x%016" PRIx64 "ULL\n",
                        scenarios[i].name, h, scenarios[i].expected);
            bad++;
        }
    }
    assert_int_equal(bad, 0);
}

/* ---- element forces ----
 * A 6 x 6 x 6-node block of 0.05 m (hexahedra of the lattice, or each cell
 * split into 6 tetrahedra), bottom face fixed, E 0.6 MPa, nu 0.45, lumped
 * masses at 1040 kg/m^3: an oblique displacement press on the top centre
 * with a force beside it, a value change, one release, all released. The
 * neo-Hookean forces use only + - * / (their cube root too), so these bits
 * are the same on every CPU; CI runs this test built by GCC and by clang.
 * Both hashes are kept: the one at the end, and the one while the force
 * contact still presses (some runs end with every node back at rest
 * exactly, where the hash is the step counter's alone). */
typedef struct elem_scenario {
    const char *name;
    ftm_forces forces;
    bool tets;
    ftm_order order;
    uint64_t expected; /* at the end (some scenarios end with every node asleep) */
    uint64_t loaded;   /* after the release of one contact, the other still pressing */
} elem_scenario;

#define EN 6
static ftm_mesh *elem_block(bool tets)
{
    ftm_error err;
    ftm_mesh_builder *b = ftm_mesh_builder_create();
    const double s = 0.01;
    if (!tets) {
        ftm_lattice3d_def d = ftm_default_lattice3d_def();
        d.nx = d.ny = d.nz = EN;
        d.spacing = (ftm_vec3){s, s, s};
        d.stencil = FTM_STENCIL_18;
        d.material = (ftm_material_def){0.001, 0.5, 1000.0, {1.0, 1.0, 1.0}};
        d.fixed_faces = FTM_FACE_ZMIN;
        assert_int_equal(ftm_generate_lattice3d(b, &d, &err), FTM_OK);
    } else {
        for (int k = 0; k < EN; k++)
            for (int j = 0; j < EN; j++)
                for (int i = 0; i < EN; i++) {
                    ftm_node_def nd = ftm_default_node_def();
                    nd.position = (ftm_vec3){i * s, j * s, k * s};
                    nd.mass = 0.001;
                    nd.damping = 0.5;
                    nd.fixed = k == 0;
                    assert_true(ftm_mesh_builder_add_node(b, &nd) >= 0);
                }
        /* 6 tetrahedra per cell around its (0,0,0)-(1,1,1) diagonal */
        static const int path[6][3] = {{0, 1, 2}, {0, 2, 1}, {1, 0, 2},
                                       {1, 2, 0}, {2, 0, 1}, {2, 1, 0}};
        for (int k = 0; k + 1 < EN; k++)
            for (int j = 0; j + 1 < EN; j++)
                for (int i = 0; i + 1 < EN; i++)
                    for (int t = 0; t < 6; t++) {
                        int c[3] = {i, j, k}, v[4];
                        v[0] = c[0] + EN * (c[1] + EN * c[2]);
                        for (int st = 0; st < 3; st++) {
                            c[path[t][st]]++;
                            v[st + 1] = c[0] + EN * (c[1] + EN * c[2]);
                        }
                        assert_int_equal(
                            ftm_mesh_builder_add_tetrahedron(b, v[0], v[1], v[2], v[3]), FTM_OK);
                        for (int p = 0; p < 4; p++)
                            for (int q = p + 1; q < 4; q++) {
                                ftm_link_def l = ftm_default_link_def();
                                l.a = v[p];
                                l.b = v[q];
                                l.stiffness = 1000.0;
                                assert_int_equal(ftm_mesh_builder_add_link(b, &l), FTM_OK);
                            }
                    }
    }
    ftm_mesh *m = NULL;
    assert_int_equal(ftm_mesh_build(b, NULL, &m, &err), FTM_OK);
    ftm_mesh_builder_destroy(b);
    return m;
}

static uint64_t run_elem(const elem_scenario *sc, uint64_t *loaded)
{
    ftm_mesh *m = elem_block(sc->tets);
    ftm_error err;
    ftm_sim_def sd = ftm_default_sim_def();
    sd.order = sc->order;
    sd.forces = sc->forces;
    sd.young = 0.6e6;
    sd.poisson = 0.45;
    sd.density = 1040.0;
    sd.time_step = 5e-5;
    sd.depth = 4;
    ftm_sim *sim = NULL;
    assert_int_equal(ftm_sim_create(m, &sd, &sim, &err), FTM_OK);
    const int32_t top = EN * EN * (EN - 1);
    ftm_contact press[2] = {
        {.node = ftm_mesh_node_of_input(m, top + 2 + EN * 2), .group = 0,
         .kind = FTM_CONTACT_DISPLACEMENT, .value = {0.0005, 0.0002, -0.002}},
        {.node = ftm_mesh_node_of_input(m, top + 4 + EN * 3), .group = 1,
         .kind = FTM_CONTACT_FORCE, .value = {0.0, 0.1, -0.5}},
    };
    assert_int_equal(ftm_sim_set_contacts(sim, press, 2, &err), FTM_OK);
    assert_int_equal(ftm_sim_run(sim, 300), FTM_OK);
    press[0].value.z = -0.004; /* a value change: same layers */
    assert_int_equal(ftm_sim_set_contacts(sim, press, 2, &err), FTM_OK);
    assert_int_equal(ftm_sim_run(sim, 200), FTM_OK);
    assert_int_equal(ftm_sim_set_contacts(sim, press + 1, 1, &err), FTM_OK); /* one released */
    assert_int_equal(ftm_sim_run(sim, 200), FTM_OK);
    *loaded = ftm_sim_hash(sim);
    assert_int_equal(ftm_sim_set_contacts(sim, NULL, 0, &err), FTM_OK); /* all released */
    assert_int_equal(ftm_sim_run(sim, 300), FTM_OK);
    uint64_t h = ftm_sim_hash(sim);
    ftm_sim_destroy(sim);
    ftm_mesh_destroy(m);
    return h;
}

static const elem_scenario elem_scenarios[] = {
    {"linear-fem hexahedra", FTM_FORCES_LINEAR_FEM, false, FTM_ORDER_LAYER_COLORED,
     0xd0eed73ebab4029cULL, 0xb9fe48197e7697b1ULL},
    {"linear-fem tetrahedra bfs", FTM_FORCES_LINEAR_FEM, true, FTM_ORDER_BFS,
     0xb610fbe0a202cbb5ULL, 0x0ee2c1177d1551b9ULL},
    /* revision 4 (ftm/sim.h): co-rotational forces per element at the
     * substep's start, in vector lanes (common/src/elem_block.inc), the
     * polar decomposition stopping on its determinant; revision 5: the
     * tetrahedra's fourth gradient and force from the other three, stress
     * from H's upper triangle (the hexahedra's hash did not move); revision
     * 6: the polar decomposition stops after the step from det X <= 1 +
     * 1e-5 (was 1e-8) */
    {"corot-fem hexahedra", FTM_FORCES_COROT_FEM, false, FTM_ORDER_LAYER_COLORED,
     0x173571e653372f6dULL, 0x36f0ca85b951f77eULL},
    {"corot-fem tetrahedra jacobi", FTM_FORCES_COROT_FEM, true, FTM_ORDER_LAYER_JACOBI,
     0x1b6f77c148213d0aULL, 0xcb33d2c8f7772cf4ULL},
    {"neo-hookean hexahedra", FTM_FORCES_NEO_HOOKEAN, false, FTM_ORDER_LAYER_COLORED,
     0x18f5985f9213b241ULL, 0x34e413af608ea098ULL},
    {"neo-hookean tetrahedra bfs", FTM_FORCES_NEO_HOOKEAN, true, FTM_ORDER_BFS,
     0x1b6f77c148213d0aULL, 0x9bb7cdbec582ee28ULL},
};

static void test_elem_golden_hashes(void **state)
{
    (void)state;
    int bad = 0;
    for (size_t i = 0; i < sizeof elem_scenarios / sizeof elem_scenarios[0]; i++) {
        uint64_t loaded, h = run_elem(&elem_scenarios[i], &loaded);
        if (h != elem_scenarios[i].expected || loaded != elem_scenarios[i].loaded) {
            print_error("%s: hashes 0x%016" PRIx64 "ULL, 0x%016" PRIx64 "ULL, expected 0x%016" PRIx64
                        "ULL, 0x%016" PRIx64 "ULL\n",
                        elem_scenarios[i].name, h, loaded, elem_scenarios[i].expected,
                        elem_scenarios[i].loaded);
            bad++;
        }
    }
    assert_int_equal(bad, 0);
}

/* Sliding nodes and springs to ground (the lattice3d scenarios' script on
 * a block resting on the plane z = 0): every kernel updates those nodes
 * with one scalar function, so the hashes are the same everywhere. */
static const scenario bc_scenarios[] = {
    {"bc colored", FTM_ORDER_LAYER_COLORED, true, 0x5b18b8be474381f3ULL, false},
    {"bc bfs", FTM_ORDER_BFS, true, 0x0169b76bc422a344ULL, false},
    {"bc jacobi", FTM_ORDER_LAYER_JACOBI, true, 0x541f9b5fc92e79b0ULL, false},
    {"bc colored, elastic far field", FTM_ORDER_LAYER_COLORED, true, 0x0a397793c44718d9ULL, true},
};

static void test_bc_golden_hashes(void **state)
{
    (void)state;
    int bad = 0;
    for (size_t i = 0; i < sizeof bc_scenarios / sizeof bc_scenarios[0]; i++) {
        uint64_t h = run_bc(&bc_scenarios[i], true);
        if (h != bc_scenarios[i].expected) {
            print_error("%s: hash 0x%016" PRIx64 "ULL, expected 0x%016" PRIx64 "ULL\n",
                        bc_scenarios[i].name, h, bc_scenarios[i].expected);
            bad++;
        }
    }
    assert_int_equal(bad, 0);
}

/* The same run twice in one process, and a run on a rebuilt mesh, agree. */
static void test_repeatable(void **state)
{
    (void)state;
    assert_true(run(&scenarios[0]) == run(&scenarios[0]));
    assert_true(run(&scenarios[3]) == run(&scenarios[3]));
}

int main(void)
{
    setenv("FTM_CACHE_DIR", "", 1); /* the far field computed here, not read from a cache */
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(test_golden_hashes),
        cmocka_unit_test(test_elem_golden_hashes),
        cmocka_unit_test(test_bc_golden_hashes),
        cmocka_unit_test(test_repeatable),
    };
    return cmocka_run_group_tests(tests, NULL, NULL);
}
