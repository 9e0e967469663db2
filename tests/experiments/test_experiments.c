/* SPDX-License-Identifier: GPL-3.0-or-later */
/* Qualitative facts of the paper's experiments (Choi, Sun, Heng 2004, 4.1):
 * optimum penetration depth, tissue responses (Fig. 11), anisotropy (Fig. 12).
 * Quick-sized runs of tools/experiments.c. */
#include <setjmp.h>
#include <stdarg.h>
#include <stddef.h>
#include <stdint.h>
#include <cmocka.h>

#include "experiments.h"

#include <math.h>
#include <stdio.h>
#include <stdlib.h>

static void test_tissue(void **state) __attribute__((unused));
static void test_depth(void **state) __attribute__((unused));
static void test_anisotropy(void **state) __attribute__((unused));

static void test_tissue(void **state)
{
    (void)state;
    ftm_exp_tissue_def def = ftm_exp_default_tissue_def(true);
    ftm_exp_tissue_result r;
    assert_int_equal(ftm_exp_tissue(&def, &r), 0);
    const int D = FTM_EXP_TISSUE_DAMPINGS;
    for (int d = 0; d < D; d++) {
        const ftm_exp_curve *c = &r.creep[d];
        assert_true(c->count > 20);
        /* creep: strain rises monotonically ... */
        for (int i = 1; i < c->count; i++)
            assert_true(c->b[i] >= c->b[i - 1] - 1e-12 * r.creep_static[d]);
        assert_true(r.creep_static[d] > 0.0);
        /* ... to a plateau: the static strain, flat over the last tenth */
        assert_true(fabs(r.creep_final[d] - r.creep_static[d]) < 0.01 * r.creep_static[d]);
        int tail = c->count - c->count / 10;
        assert_true(c->b[c->count - 1] - c->b[tail] < 0.01 * r.creep_static[d]);
        /* the same material, so the same plateau for every damping */
        assert_true(fabs(r.creep_static[d] - r.creep_static[0]) < 1e-6 * r.creep_static[0]);
        /* hysteresis: loading and unloading paths differ */
        assert_true(r.hyst_max_gap[d] > 0.05 * r.creep_static[d]);
        assert_true(r.hyst_area[d] > 0.0);
    }
    for (int d = 1; d < D; d++) {
        /* creep is faster for low damping (lower viscosity) */
        assert_true(def.damping[d] > def.damping[d - 1]);
        assert_true(r.creep_t63[d] > 1.5 * r.creep_t63[d - 1]);
        int early = r.creep[d].count / 20;
        assert_true(r.creep[d].b[early] < r.creep[d - 1].b[early]);
        /* the hysteresis loop widens with damping */
        assert_true(r.hyst_area[d] > 1.1 * r.hyst_area[d - 1]);
        assert_true(r.hyst_max_gap[d] > r.hyst_max_gap[d - 1]);
    }
    /* load-deformation is nonlinear: doubling the force does not double the
     * (equilibrium) strain, and the constant-rate curves bend */
    double ratio = r.static_strain_full / r.static_strain_half;
    assert_true(fabs(ratio - 2.0) > 0.05);
    for (int d = 0; d < D; d++)
        assert_true(fabs(r.rate_slope_end[d] / r.rate_slope_start[d] - 1.0) > 0.05);
    ftm_exp_tissue_free(&r);
}

static void test_depth(void **state)
{
    (void)state;
    ftm_exp_depth_def def = ftm_exp_default_depth_def(true);
    ftm_exp_depth_result *r = malloc(sizeof *r);
    assert_non_null(r);
    for (int mode = 0; mode < 2; mode++) {
        def.observe_time = mode ? 8.0 : 0.0;
        assert_int_equal(ftm_exp_depth(&def, r), 0);
        for (int k = 0; k < r->k_count; k++) {
            int n = r->calibrated[k];
            assert_true(n >= 1 && n <= def.max_depth);
            assert_true(r->change[k][n] < def.threshold);
            assert_true(r->change[k][n - 1] >= def.threshold || n == 1);
            if (k > 0) /* stiffer lattices need at least as deep a penetration */
                assert_true(n >= r->calibrated[k - 1]);
        }
        if (mode == 1) /* at a fixed observation time: strictly deeper, k = 0.5 -> 5 */
            assert_true(r->calibrated[r->k_count - 1] > r->calibrated[0]);
        else /* at equilibrium the linear lattice's shape does not depend on k */
            assert_true(r->calibrated[r->k_count - 1] - r->calibrated[0] <= 1);
    }
    free(r);
}

static void test_anisotropy(void **state)
{
    (void)state;
    ftm_exp_aniso_def def = ftm_exp_default_aniso_def(true);
    ftm_exp_aniso_result r;
    assert_int_equal(ftm_exp_aniso(&def, &r), 0);
    const int V = FTM_EXP_VERTICAL, H = FTM_EXP_HORIZONTAL;
    for (int m = 0; m < FTM_EXP_MODELS; m++)
        for (int l = 0; l < FTM_EXP_LOADS; l++) {
            assert_true(r.peak[m][l] > 0.0 && r.peak[m][l] < def.spacing);
            /* profiles peak at the loaded node and are symmetric about it */
            for (int i = 0; i < r.n; i++) {
                assert_true(r.across[m][l][i] <= r.peak[m][l] + 1e-12);
                assert_true(fabs(r.across[m][l][i] - r.across[m][l][r.n - 1 - i]) <
                            1e-6 * r.peak[m][l]);
            }
        }
    /* isotropic: the same profile whichever way it is loaded */
    for (int i = 0; i < r.n; i++)
        assert_true(fabs(r.across[FTM_EXP_ISO][V][i] - r.across[FTM_EXP_ISO][H][i]) <
                    1e-4 * r.peak[FTM_EXP_ISO][V]);
    /* A (soft horizontally) deforms more horizontally than the control, B less */
    assert_true(r.peak[FTM_EXP_A][H] > 1.5 * r.peak[FTM_EXP_ISO][H]);
    assert_true(r.peak[FTM_EXP_B][H] < r.peak[FTM_EXP_ISO][H] / 1.5);
    /* and each against its own vertical response */
    assert_true(r.peak[FTM_EXP_A][H] > 1.5 * r.peak[FTM_EXP_A][V]);
    assert_true(r.peak[FTM_EXP_B][H] < r.peak[FTM_EXP_B][V] / 1.5);
}

/* Built three times (tests/experiments/CMakeLists.txt), one experiment each. */
#ifndef EXP_TEST
#define EXP_TEST 0
#endif

int main(void)
{
    const struct CMUnitTest tests[] = {
#if EXP_TEST == 0 || EXP_TEST == 1
        cmocka_unit_test(test_depth),
#endif
#if EXP_TEST == 0 || EXP_TEST == 2
        cmocka_unit_test(test_tissue),
#endif
#if EXP_TEST == 0 || EXP_TEST == 3
        cmocka_unit_test(test_anisotropy),
#endif
    };
    return cmocka_run_group_tests(tests, NULL, NULL);
}
