/* SPDX-License-Identifier: GPL-3.0-or-later */
/* Parameter identification (tools/fit.c, docs/fit.md):
 *   - the PRNG is seeded and reproducible;
 *   - Lundy-Mees cooling: T_n = T0 / (1 + n beta T0), and the derived beta
 *     reaches T_final in exactly the requested steps;
 *   - simulated annealing finds the global minimum of a multimodal
 *     2-parameter function, bit-identically for a fixed seed;
 *   - Nelder-Mead minimises Rosenbrock's function;
 *   - the Eq. 17 cost is exactly 0 when the reference is the spring model's
 *     own equilibrium, and positive for other parameters;
 *   - a reduced fit (4x4x4 cube against its FEM reference, one load case, a
 *     few iterations) lowers the cost. */
#include <setjmp.h>
#include <stdarg.h>
#include <stddef.h>
#include <stdint.h>

#include <cmocka.h>

#include "fit.h"

#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#define assert_near(a, b, eps) near_impl((a), (b), (eps), #a, __LINE__)

static void near_impl(double a, double b, double eps, const char *what, int line)
{
    if (!(fabs(a - b) <= eps))
        fail_msg("line %d: %s = %.17g, expected %.17g (+- %g)", line, what, a, b, eps);
}

static void test_rng(void **state)
{
    (void)state;
    ftm_fit_rng a, b, c;
    ftm_fit_rng_seed(&a, 42);
    ftm_fit_rng_seed(&b, 42);
    ftm_fit_rng_seed(&c, 43);
    int differ = 0;
    double sum = 0;
    for (int i = 0; i < 10000; i++) {
        uint64_t x = ftm_fit_rng_next(&a), y = ftm_fit_rng_next(&b), z = ftm_fit_rng_next(&c);
        assert_true(x == y);
        differ += x != z;
        double u = ftm_fit_rng_uniform(&a);
        (void)ftm_fit_rng_uniform(&b);
        assert_true(u >= 0.0 && u < 1.0);
        sum += u;
    }
    assert_true(differ > 9990);
    assert_near(sum / 10000, 0.5, 0.02);
}

static void test_lundy_mees(void **state)
{
    (void)state;
    assert_near(ftm_fit_lundy_mees(1.0, 0.5), 1.0 / 1.5, 1e-15);
    assert_near(ftm_fit_lundy_mees(ftm_fit_lundy_mees(1.0, 0.5), 0.5), 0.5, 1e-15);
    /* closed form: 1/T_n = 1/T0 + n beta */
    double t = 0.7, beta = 0.45;
    for (int i = 0; i < 100; i++)
        t = ftm_fit_lundy_mees(t, beta);
    assert_near(t, 0.7 / (1 + 100 * beta * 0.7), 1e-12);
    /* the paper's ranges: T0 0.1..1, beta 0.4..0.5 */
    assert_near(ftm_fit_lundy_mees(0.1, 0.4), 0.1 / 1.04, 1e-15);
    /* derived beta hits T_final after the requested steps */
    double b = ftm_fit_lundy_mees_beta(2.0, 0.01, 250);
    assert_near(b, (1 / 0.01 - 1 / 2.0) / 250, 1e-15);
    t = 2.0;
    for (int i = 0; i < 250; i++)
        t = ftm_fit_lundy_mees(t, b);
    assert_near(t, 0.01, 1e-12);
    assert_true(ftm_fit_lundy_mees_beta(1.0, 2.0, 10) == 0.0); /* no cooling asked */
}

/* Rastrigin-like, shifted: global minimum 0 at (1.3, -0.7), local minima on
 * the unit grid around it. */
static int calls;
static double multimodal(void *user, const double *x)
{
    (void)user;
    calls++;
    double f = 0;
    static const double c[2] = {1.3, -0.7};
    for (int i = 0; i < 2; i++) {
        double z = x[i] - c[i];
        f += z * z + 2.0 * (1.0 - cos(6.283185307179586 * z));
    }
    return f;
}

static void run_anneal(uint64_t seed, double *x, ftm_fit_result *r)
{
    double x0[2] = {-3.5, 3.2}, lo[2] = {-6, -6}, hi[2] = {6, 6}, step[2] = {2.0, 2.0};
    ftm_fit_anneal_def d = ftm_fit_default_anneal_def();
    d.dim = 2;
    d.x0 = x0;
    d.lo = lo;
    d.hi = hi;
    d.step = step;
    d.seed = seed;
    d.iterations = 3000;
    d.prerun = 50;
    d.min_step_fraction = 0.02;
    assert_int_equal(ftm_fit_anneal(&d, multimodal, NULL, x, r), FTM_OK);
}

static void test_anneal(void **state)
{
    (void)state;
    double x1[2], x2[2], x3[2];
    ftm_fit_result r1, r2, r3;
    calls = 0;
    run_anneal(7, x1, &r1);
    assert_int_equal(calls, r1.evaluations);
    assert_int_equal(r1.evaluations, 1 + 50 + 3000);
    run_anneal(7, x2, &r2);
    /* reproducible: the same seed gives the same bits */
    assert_true(memcmp(x1, x2, sizeof x1) == 0);
    assert_true(r1.f == r2.f && r1.accepted == r2.accepted && r1.t0 == r2.t0);
    run_anneal(99, x3, &r3);
    double fx[3] = {r1.f, r3.f, 0};
    for (int i = 0; i < 2; i++) {
        printf("  seed %s: x = (%.4f, %.4f), f = %.3g, T0 %.3g, beta %.3g, accepted %d (%d uphill)\n",
               i ? "99" : "7", i ? x3[0] : x1[0], i ? x3[1] : x1[1], fx[i], i ? r3.t0 : r1.t0,
               i ? r3.beta : r1.beta, i ? r3.accepted : r1.accepted,
               i ? r3.uphill_accepted : r1.uphill_accepted);
    }
    /* global minimum (the nearest local minima have f ~ 1) */
    assert_near(x1[0], 1.3, 0.05);
    assert_near(x1[1], -0.7, 0.05);
    assert_near(x3[0], 1.3, 0.05);
    assert_near(x3[1], -0.7, 0.05);
    assert_true(r1.f < 0.05 && r3.f < 0.05); /* the next minima have f ~ 1 */
    assert_true(r1.uphill_accepted > 0); /* it did climb out of something */
    assert_true(r1.t0 > r1.t_final && r1.beta > 0);
}

static double rosenbrock(void *user, const double *x)
{
    (void)user;
    double a = 1 - x[0], b = x[1] - x[0] * x[0];
    return a * a + 100 * b * b;
}

static void test_nelder_mead(void **state)
{
    (void)state;
    double x0[2] = {-1.2, 1.0}, step[2] = {0.5, 0.5}, x[2];
    ftm_fit_nm_def d = ftm_fit_default_nm_def();
    d.dim = 2;
    d.x0 = x0;
    d.step = step;
    d.max_evaluations = 1000;
    d.ftol = 1e-12;
    d.ftol_abs = 1e-12;
    d.xtol = 1e-7;
    ftm_fit_result r;
    assert_int_equal(ftm_fit_nelder_mead(&d, rosenbrock, NULL, x, &r), FTM_OK);
    printf("  Rosenbrock: x = (%.8f, %.8f), f = %.3g, %d evaluations, converged %d\n", x[0], x[1],
           r.f, r.evaluations, r.converged);
    assert_true(r.converged);
    assert_near(x[0], 1.0, 1e-4);
    assert_near(x[1], 1.0, 1e-4);
    assert_true(r.evaluations < 1000);
    /* deterministic */
    double y[2];
    ftm_fit_result r2;
    assert_int_equal(ftm_fit_nelder_mead(&d, rosenbrock, NULL, y, &r2), FTM_OK);
    assert_true(memcmp(x, y, sizeof x) == 0 && r.evaluations == r2.evaluations);
    /* a box keeps it inside */
    double lo[2] = {-2, -2}, hi[2] = {0.5, 2};
    d.lo = lo;
    d.hi = hi;
    assert_int_equal(ftm_fit_nelder_mead(&d, rosenbrock, NULL, y, &r2), FTM_OK);
    assert_true(y[0] <= 0.5 && y[0] > 0.45);
}

/* ---- the mass-spring problem on a small cube ----------------------------- */

typedef struct cube {
    ftm_mesh *mesh;
    double *force;
    double *ref;
} cube;

static void make_cube(cube *c, int n, double total_force)
{
    ftm_lattice3d_def ld = ftm_default_lattice3d_def();
    ld.nx = ld.ny = ld.nz = n;
    double a = 0.1 / (n - 1);
    ld.spacing = (ftm_vec3){a, a, a};
    ld.stencil = FTM_STENCIL_18;
    ld.material.node_mass = 1e-3;
    ld.material.stiffness = 1.0;
    ld.fixed_faces = FTM_FACE_ZMIN;
    ftm_mesh_builder *b = ftm_mesh_builder_create();
    ftm_error err;
    assert_int_equal(ftm_generate_lattice3d(b, &ld, &err), FTM_OK);
    assert_int_equal(ftm_mesh_build(b, NULL, &c->mesh, &err), FTM_OK);
    ftm_mesh_builder_destroy(b);
    size_t nd = 3 * (size_t)ftm_mesh_node_count(c->mesh);
    c->force = calloc(nd, sizeof(double));
    c->ref = calloc(nd, sizeof(double));
    assert_non_null(c->force);
    assert_non_null(c->ref);
    /* the central top nodes (n even: four of them) */
    int lo = (n - 1) / 2, hi = n / 2, count = 0;
    for (int iy = lo; iy <= hi; iy++)
        for (int ix = lo; ix <= hi; ix++)
            count++;
    for (int iy = lo; iy <= hi; iy++)
        for (int ix = lo; ix <= hi; ix++) {
            int32_t v = ftm_mesh_node_of_input(c->mesh, ix + n * (iy + n * (n - 1)));
            c->force[3 * (size_t)v + 2] = -total_force / count;
        }
}

static void free_cube(cube *c)
{
    ftm_mesh_destroy(c->mesh);
    free(c->force);
    free(c->ref);
}

static void test_self_reference(void **state)
{
    (void)state;
    cube c;
    make_cube(&c, 4, 5.0);
    const double *forces[1] = {c.force};
    ftm_fit_problem_def pd = ftm_fit_default_problem_def();
    pd.mesh = c.mesh;
    pd.node_mass = 1e-3;
    pd.depth = 10;
    pd.cases = 1;
    pd.forces = forces;
    pd.tolerance = 1e-9;
    ftm_fit_problem *p = NULL;
    ftm_error err;
    assert_int_equal(ftm_fit_problem_create(&pd, &p, &err), FTM_OK);
    int32_t counts[3];
    ftm_fit_problem_class_counts(p, counts);
    assert_true(counts[0] > 0 && counts[1] > 0 && counts[2] == 0);
    ftm_fit_params q = {3000.0, 1.0, {1.0, 1.3, 1.0}};
    ftm_fit_eval ev;
    double *pos[1] = {c.ref};
    assert_int_equal(ftm_fit_problem_eval(p, &q, &ev, pos, &err), FTM_OK);
    assert_true(ev.converged);
    assert_true(ev.cost == 0.0); /* no reference: cost 0 */
    ftm_fit_problem_destroy(p);

    /* the equilibrium itself as the reference */
    const double *refs[1] = {c.ref};
    pd.reference = refs;
    assert_int_equal(ftm_fit_problem_create(&pd, &p, &err), FTM_OK);
    assert_int_equal(ftm_fit_problem_eval(p, &q, &ev, NULL, &err), FTM_OK);
    printf("  self reference: cost %.3g m after %d steps, mean |u| %.3g m\n", ev.cost,
           (int)ev.steps, ev.c[0].mean_ref_u);
    assert_true(ev.cost == 0.0);
    assert_true(ev.c[0].mean_ref_u > 0);
    /* other parameters cost something; stiffer springs move less */
    ftm_fit_params q2 = q;
    q2.k = 3300;
    assert_int_equal(ftm_fit_problem_eval(p, &q2, &ev, NULL, &err), FTM_OK);
    assert_true(ev.cost > 0 && ev.c[0].avg_err < 0.2 * ev.c[0].mean_ref_u);
    q2 = q;
    q2.scale[1] = 1.0;
    assert_int_equal(ftm_fit_problem_eval(p, &q2, &ev, NULL, &err), FTM_OK);
    assert_true(ev.cost > 0);
    /* at equilibrium the damping changes nothing (to the tolerance) */
    q2 = q;
    q2.d = 3.0;
    assert_int_equal(ftm_fit_problem_eval(p, &q2, &ev, NULL, &err), FTM_OK);
    printf("  d 1 -> 3: %d steps, avg difference %.3g of the mean displacement\n", (int)ev.steps,
           ev.c[0].avg_err / ev.c[0].mean_ref_u);
    assert_true(ev.converged && ev.c[0].avg_err < 1e-4 * ev.c[0].mean_ref_u);
    /* bad parameters are refused */
    q2.k = -1;
    assert_int_equal(ftm_fit_problem_eval(p, &q2, &ev, NULL, &err), FTM_EINVAL);
    ftm_fit_problem_destroy(p);
    free_cube(&c);
}

typedef struct reduced {
    ftm_fit_problem *p;
    double k0, mass;
} reduced;

static double reduced_cost(void *user, const double *x)
{
    reduced *r = user;
    ftm_fit_params q = {r->k0 * exp(x[0]), 0, {1.0, exp(x[1]), 1.0}};
    q.d = 0.9 * sqrt(q.k * r->mass);
    ftm_fit_eval ev;
    if (ftm_fit_problem_eval(r->p, &q, &ev, NULL, NULL) != FTM_OK)
        return INFINITY;
    return ev.cost;
}

static void test_reduced_fit(void **state)
{
    (void)state;
    cube c;
    make_cube(&c, 4, 10.0);
    ftm_fem_material mat = {0.6e6, 0.45};
    const double *forces[1] = {c.force};
    double *refs_out[1] = {c.ref};
    ftm_error err;
    assert_int_equal(ftm_fit_fem_reference(c.mesh, &mat, 1, forces, refs_out, &err), FTM_OK);
    const double *refs[1] = {c.ref};
    ftm_fit_problem_def pd = ftm_fit_default_problem_def();
    pd.mesh = c.mesh;
    pd.node_mass = 1040.0 * 1e-3 / 64;
    pd.cases = 1;
    pd.forces = forces;
    pd.reference = refs;
    pd.tolerance = 1e-7;
    reduced r = {NULL, 0.6e6 * 0.1 / 3, pd.node_mass};
    assert_int_equal(ftm_fit_problem_create(&pd, &r.p, &err), FTM_OK);
    double x0[2] = {log(0.25), 0.0}, lo[2] = {-4, -3}, hi[2] = {4, 3}, step[2] = {0.7, 0.7};
    double f0 = reduced_cost(&r, x0);
    ftm_fit_anneal_def d = ftm_fit_default_anneal_def();
    d.dim = 2;
    d.x0 = x0;
    d.lo = lo;
    d.hi = hi;
    d.step = step;
    d.seed = 3;
    d.iterations = 25;
    d.prerun = 5;
    double x[2];
    ftm_fit_result res;
    assert_int_equal(ftm_fit_anneal(&d, reduced_cost, &r, x, &res), FTM_OK);
    printf("  reduced fit (anneal): cost %.4g -> %.4g m in %d evaluations, k %.4g, face scale "
           "%.3g\n",
           f0, res.f, res.evaluations, r.k0 * exp(x[0]), exp(x[1]));
    assert_true(res.f < 0.7 * f0);
    /* reproducible */
    double y[2];
    ftm_fit_result res2;
    assert_int_equal(ftm_fit_anneal(&d, reduced_cost, &r, y, &res2), FTM_OK);
    assert_true(memcmp(x, y, sizeof x) == 0 && res.f == res2.f);
    /* Nelder-Mead from the same start */
    ftm_fit_nm_def nm = ftm_fit_default_nm_def();
    nm.dim = 2;
    nm.x0 = x0;
    nm.step = step;
    nm.lo = lo;
    nm.hi = hi;
    nm.max_evaluations = 30;
    nm.ftol = 1e-4;
    nm.xtol = 1e-2;
    assert_int_equal(ftm_fit_nelder_mead(&nm, reduced_cost, &r, y, &res2), FTM_OK);
    printf("  reduced fit (Nelder-Mead): cost %.4g m in %d evaluations\n", res2.f,
           res2.evaluations);
    assert_true(res2.f < 0.7 * f0);
    ftm_fit_problem_destroy(r.p);
    free_cube(&c);
}

int main(void)
{
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(test_rng),         cmocka_unit_test(test_lundy_mees),
        cmocka_unit_test(test_anneal),      cmocka_unit_test(test_nelder_mead),
        cmocka_unit_test(test_self_reference), cmocka_unit_test(test_reduced_fit),
    };
    return cmocka_run_group_tests(tests, NULL, NULL);
}
