/* The vector sweeps' kernels (AVX where the CPU has it, the baseline one
 * otherwise; in the colored order link data read from the mesh's padded rows
 * on a schedule's first use, from the schedule's slot-major copy after) must
 * give bit-identical states: compare ftm_sim_hash. Each must also roll a
 * rejected step back exactly. */
#include <setjmp.h>
#include <stdarg.h>
#include <stddef.h>
#include <stdint.h>

#include <cmocka.h>

#include "ftm/ftm.h"
#include "rollback_check.h"
#include "sim_internal.h"

static ftm_sim *make(const ftm_mesh *m, ftm_order order, bool portable, bool cache)
{
    ftm_sim_def d = ftm_default_sim_def();
    d.order = order;
    d.time_step = 0.1;
    d.depth = 12;
    d.cache_layers = cache; /* false: a new schedule, used once, every step */
    ftm_sim *s = NULL;
    assert_int_equal(ftm_sim_create(m, &d, &s, NULL), FTM_OK);
    ftm_sim_select_kernel(s, portable);
    ftm_contact c[2] = {
        {.node = ftm_mesh_node_of_input(m, 20 + 50 * 25), .kind = FTM_CONTACT_FORCE,
         .value = {0.0, -0.3, 0.0}},
        {.node = ftm_mesh_node_of_input(m, 31 + 50 * 22), .group = 1,
         .kind = FTM_CONTACT_DISPLACEMENT, .value = {0.1, 0.2, 0.0}}};
    assert_int_equal(ftm_sim_set_contacts(s, c, 2, NULL), FTM_OK);
    return s;
}

/* The default 2D lattice: 50 x 50 nodes. */
static ftm_mesh *lattice(void)
{
    ftm_mesh_builder *mb = ftm_mesh_builder_create();
    ftm_lattice2d_def ld = ftm_default_lattice2d_def();
    ftm_mesh *m = NULL;
    assert_int_equal(ftm_generate_lattice2d(mb, &ld, NULL), FTM_OK);
    assert_int_equal(ftm_mesh_build(mb, NULL, &m, NULL), FTM_OK);
    ftm_mesh_builder_destroy(mb);
    return m;
}

static void kernels_match(ftm_order order)
{
    ftm_mesh *m = lattice();
    ftm_sim *s[4] = {make(m, order, false, true), make(m, order, true, true),
                     make(m, order, false, false), make(m, order, true, false)};
    for (int i = 0; i < 20; i++) {
        for (int k = 0; k < 4; k++)
            assert_int_equal(ftm_sim_run(s[k], 50), FTM_OK);
        ftm_vec3 r0 = ftm_sim_reaction(s[0], 1);
        for (int k = 1; k < 4; k++) {
            assert_true(ftm_sim_hash(s[k]) == ftm_sim_hash(s[0]));
            ftm_vec3 r = ftm_sim_reaction(s[k], 1);
            assert_memory_equal(&r, &r0, sizeof r);
        }
    }
    for (int k = 0; k < 4; k++)
        ftm_sim_destroy(s[k]);
    ftm_mesh_destroy(m);
}

static void test_portable_kernel_matches(void **state)
{
    (void)state;
    kernels_match(FTM_ORDER_LAYER_COLORED);
}

static void test_portable_jacobi_kernel_matches(void **state)
{
    (void)state;
    kernels_match(FTM_ORDER_LAYER_JACOBI);
}

/* A step the guard rejects (time step 50x critical, no substeps) leaves the
 * state exactly as it was, with the native and the baseline kernel alike:
 * each saves the previous positions it overwrites in its own block layout.
 * The step is retried, so the schedule is used unlinked, then linked. */
static void rollback_restores(ftm_order order, bool portable)
{
    ftm_mesh *m = lattice();
    ftm_sim_def d = ftm_default_sim_def();
    d.order = order;
    d.time_step = 50.0 * ftm_mesh_critical_time_step(m);
    d.max_substeps = 1;
    d.depth = 12;
    ftm_sim *s = NULL;
    assert_int_equal(ftm_sim_create(m, &d, &s, NULL), FTM_OK);
    ftm_sim_select_kernel(s, portable);
    ftm_contact c = {.node = ftm_mesh_node_of_input(m, 20 + 50 * 25),
                     .kind = FTM_CONTACT_FORCE, .value = {0.0, -0.3, 0.0}};
    assert_int_equal(ftm_sim_set_contacts(s, &c, 1, NULL), FTM_OK);
    assert_true(rejected_steps_roll_back(s, 4) >= 2);
    ftm_sim_destroy(s);
    ftm_mesh_destroy(m);
}

static void test_rollback_every_kernel(void **state)
{
    (void)state;
    for (int p = 0; p < 2; p++) {
        rollback_restores(FTM_ORDER_LAYER_COLORED, p);
        rollback_restores(FTM_ORDER_LAYER_JACOBI, p);
    }
}

int main(void)
{
    const struct CMUnitTest tests[] = {cmocka_unit_test(test_portable_kernel_matches),
                                       cmocka_unit_test(test_portable_jacobi_kernel_matches),
                                       cmocka_unit_test(test_rollback_every_kernel)};
    return cmocka_run_group_tests(tests, NULL, NULL);
}
