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

/* Runs a press / move / release / relax script and returns the final hash. */
static uint64_t run(const scenario *sc)
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
        assert_int_equal(ftm_generate_lattice3d(b, &d, &err), FTM_OK);
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
    uint64_t h = ftm_sim_hash(sim) ^ (sc->elastic ? pressed : 0);
    ftm_sim_destroy(sim);
    ftm_mesh_destroy(m);
    return h;
}

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
        cmocka_unit_test(test_repeatable),
    };
    return cmocka_run_group_tests(tests, NULL, NULL);
}
