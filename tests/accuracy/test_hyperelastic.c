/* SPDX-License-Identifier: GPL-3.0-or-later */
/* Neo-Hookean element forces (forces = neo-hookean, docs/calculix.md):
 *   - the cube root of the core against long double cbrtl, in ulps;
 *   - the stress: exactly 0 at rest, dW/dF by finite differences of W,
 *     objective under rotation, Hooke's law at small strain;
 *   - element forces: tangent at rest = the linear K_e; a rigid rotation
 *     has no force and stays put; the critical step is the linear one;
 *   - the integrator: the same bits in every order, the same bits when the
 *     state is reloaded every step (no hidden state), bounded without
 *     damping, an inverted element caught (substeps, else FTM_EUNSTABLE
 *     with the state unchanged and the event logged, never a NaN), and
 *     ftm_sim_internal_forces refusing inverted positions.
 * CalculiX comparisons are in tests/calculix. */
#include <setjmp.h>
#include <stdarg.h>
#include <stddef.h>
#include <stdint.h>

#include <cmocka.h>

#include "ftm/ftm.h"
#include "hyperelastic.h"
#include "../rollback_check.h"

#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#define YOUNG 0.6e6
#define POISSON 0.45
#define DENSITY 1040.0
#define MU (YOUNG / (2.0 * (1.0 + POISSON)))
#define KAPPA (YOUNG / (3.0 * (1.0 - 2.0 * POISSON)))

/* xorshift64*: a fixed sequence in [0, 1) */
static double rnd(uint64_t *s)
{
    *s ^= *s >> 12;
    *s ^= *s << 25;
    *s ^= *s >> 27;
    return (double)((*s * 0x2545f4914f6cdd1dULL) >> 11) * 0x1p-53;
}

/* distance in ulps of a from the long double b, at b's scale */
static double ulps(double a, long double b)
{
    int e;
    frexpl(b, &e);
    long double ulp = ldexpl(1.0L, e - 53);
    return (double)(fabsl((long double)a - b) / ulp);
}

static void test_inv_cbrt(void **state)
{
    (void)state;
    assert_true(ftm_inv_cbrt(1.0) == 1.0);
    assert_true(ftm_inv_cbrt(8.0) == 0.5);
    assert_true(ftm_inv_cbrt(0.125) == 2.0);
    uint64_t s = 42;
    double worst_near = 0, worst_far = 0;
    for (int i = 0; i < 200000; i++) {
        /* near 1 (the fast path and its edges), and 1e-9 .. 1e9 */
        double j = i % 2 ? 0.8 + 0.4 * rnd(&s) : pow(10.0, -9.0 + 18.0 * rnd(&s));
        double u = ulps(ftm_inv_cbrt(j), 1.0L / cbrtl((long double)j));
        if (fabs(j - 1.0) <= 0.125)
            worst_near = fmax(worst_near, u);
        else
            worst_far = fmax(worst_far, u);
    }
    print_message("inv_cbrt: within %.2f ulp near 1, %.2f ulp elsewhere\n", worst_near,
                  worst_far);
    assert_true(worst_near <= 2.0);
    assert_true(worst_far <= 2.0);
}

/* W of the compressible neo-Hookean solid in long double (libm is fine in a
 * test: the core's bits are not at stake here) */
static long double energy(const double f[9])
{
    long double F[9];
    for (int i = 0; i < 9; i++)
        F[i] = f[i];
    long double j = F[0] * (F[4] * F[8] - F[5] * F[7]) - F[1] * (F[3] * F[8] - F[5] * F[6]) +
                    F[2] * (F[3] * F[7] - F[4] * F[6]);
    long double i1 = 0;
    for (int i = 0; i < 9; i++)
        i1 += F[i] * F[i];
    return (long double)MU / 2 * (powl(j, -2.0L / 3) * i1 - 3) +
           (long double)KAPPA / 2 * (j - 1) * (j - 1);
}

static void random_h(uint64_t *s, double scale, double h[9])
{
    for (int i = 0; i < 9; i++)
        h[i] = scale * (2.0 * rnd(s) - 1.0);
}

static void test_stress(void **state)
{
    (void)state;
    double h[9] = {0}, p[9], j;
    assert_true(ftm_neo_stress(h, MU, KAPPA, p, &j));
    for (int i = 0; i < 9; i++)
        assert_true(p[i] == 0.0); /* exactly: F = I is at rest */
    assert_true(j == 1.0);
    uint64_t s = 7;
    double worst = 0;
    for (int t = 0; t < 200; t++) {
        random_h(&s, 0.3, h);
        assert_true(ftm_neo_stress(h, MU, KAPPA, p, &j));
        double f[9];
        for (int i = 0; i < 9; i++)
            f[i] = h[i] + (i % 4 == 0);
        double pmax = 0, err = 0;
        for (int i = 0; i < 9; i++) { /* central difference of W in long double */
            const double d = 1e-6;
            double fp[9], fm[9];
            memcpy(fp, f, sizeof fp);
            memcpy(fm, f, sizeof fm);
            fp[i] += d;
            fm[i] -= d;
            double fd = (double)((energy(fp) - energy(fm)) / (2.0L * d));
            pmax = fmax(pmax, fabs(p[i]));
            err = fmax(err, fabs(fd - p[i]));
        }
        worst = fmax(worst, err / pmax);
    }
    print_message("P against dW/dF by differences: %.2g of the largest entry\n", worst);
    assert_true(worst < 1e-7);
    /* inverted or flat: refused */
    double flat[9] = {0, 0, 0, 0, 0, 0, 0, 0, -1.0};
    assert_false(ftm_neo_stress(flat, MU, KAPPA, p, &j));
    assert_true(j == 0.0);
    double inverted[9] = {0, 0, 0, 0, 0, 0, 0, 0, -1.5};
    assert_false(ftm_neo_stress(inverted, MU, KAPPA, p, &j));
    assert_true(j < 0.0);
    double nan[9] = {NAN, 0, 0, 0, 0, 0, 0, 0, 0};
    assert_false(ftm_neo_stress(nan, MU, KAPPA, p, &j));
}

/* P(R F) = R P(F) for a rotation R; and for a small strain, Hooke's law. */
static void test_stress_objective_and_linear(void **state)
{
    (void)state;
    uint64_t s = 11;
    const double c = cos(0.7), sn = sin(0.7), r[9] = {c, -sn, 0, sn, c, 0, 0, 0, 1};
    for (int t = 0; t < 50; t++) {
        double h[9], p[9], hr[9], pr[9], j, f[9];
        random_h(&s, 0.2, h);
        for (int i = 0; i < 9; i++)
            f[i] = h[i] + (i % 4 == 0);
        for (int a = 0; a < 3; a++) /* hr = R F - I */
            for (int b = 0; b < 3; b++) {
                double v = 0;
                for (int k = 0; k < 3; k++)
                    v += r[3 * a + k] * f[3 * k + b];
                hr[3 * a + b] = v - (a == b);
            }
        assert_true(ftm_neo_stress(h, MU, KAPPA, p, &j));
        assert_true(ftm_neo_stress(hr, MU, KAPPA, pr, &j));
        for (int a = 0; a < 3; a++)
            for (int b = 0; b < 3; b++) {
                double v = 0;
                for (int k = 0; k < 3; k++)
                    v += r[3 * a + k] * p[3 * k + b];
                assert_true(fabs(v - pr[3 * a + b]) < 1e-9 * MU);
            }
    }
    /* small strain: sigma = lambda tr(e) I + 2 mu e, e the symmetric part */
    double h[9], p[9], j;
    random_h(&s, 1e-7, h);
    assert_true(ftm_neo_stress(h, MU, KAPPA, p, &j));
    const double lambda = KAPPA - 2.0 * MU / 3.0, tr = h[0] + h[4] + h[8];
    for (int a = 0; a < 3; a++)
        for (int b = 0; b < 3; b++) {
            double e = 0.5 * (h[3 * a + b] + h[3 * b + a]);
            double sig = lambda * tr * (a == b) + 2.0 * MU * e;
            assert_true(fabs(sig - p[3 * a + b]) < 1e-5 * (KAPPA * 1e-7));
        }
}

/* A general hexahedron (or 6 tetrahedra of a box) as a 1-element mesh. */
static ftm_mesh *single(bool tets)
{
    ftm_error err;
    ftm_mesh_builder *b = ftm_mesh_builder_create();
    static const double X[8][3] = {{0, 0, 0},           {0.012, 0.001, 0},   {0.011, 0.01, 0.001},
                                   {-0.001, 0.011, 0},  {0.001, 0, 0.01},    {0.01, -0.001, 0.011},
                                   {0.012, 0.012, 0.01}, {0, 0.01, 0.012}};
    for (int a = 0; a < 8; a++) {
        ftm_node_def nd = ftm_default_node_def();
        nd.position = (ftm_vec3){X[a][0], X[a][1], X[a][2]};
        nd.mass = 1e-3;
        nd.fixed = a < 3; /* three corners: no rigid motion left */
        assert_true(ftm_mesh_builder_add_node(b, &nd) >= 0);
    }
    for (int a = 0; a < 8; a++)
        for (int c = a + 1; c < 8; c++) {
            ftm_link_def l = ftm_default_link_def();
            l.a = a;
            l.b = c;
            l.stiffness = 1.0;
            assert_int_equal(ftm_mesh_builder_add_link(b, &l), FTM_OK);
        }
    if (!tets) {
        int32_t h[8] = {0, 1, 2, 3, 4, 5, 6, 7};
        assert_int_equal(ftm_mesh_builder_add_hexahedron(b, h), FTM_OK);
    } else { /* around the 0-6 diagonal */
        static const int t[6][4] = {{0, 1, 2, 6}, {0, 5, 1, 6}, {0, 4, 5, 6},
                                    {0, 2, 3, 6}, {0, 3, 7, 6}, {0, 7, 4, 6}};
        for (int e = 0; e < 6; e++)
            assert_int_equal(ftm_mesh_builder_add_tetrahedron(b, t[e][0], t[e][1], t[e][2], t[e][3]),
                             FTM_OK);
    }
    ftm_mesh_build_def bd = ftm_default_mesh_build_def();
    bd.reorder = false;
    ftm_mesh *m = NULL;
    assert_int_equal(ftm_mesh_build(b, &bd, &m, &err), FTM_OK);
    ftm_mesh_builder_destroy(b);
    return m;
}

static ftm_sim_def neo_def(void)
{
    ftm_sim_def d = ftm_default_sim_def();
    d.forces = FTM_FORCES_NEO_HOOKEAN;
    d.young = YOUNG;
    d.poisson = POISSON;
    d.density = DENSITY;
    d.depth = 1000;
    d.time_step = 1e-5;
    return d;
}

/* Forces at a small displacement are K u (the tangent at rest is the linear
 * element stiffness); the critical step is the linear one. */
static void test_tangent_at_rest(void **state)
{
    (void)state;
    for (int tets = 0; tets < 2; tets++) {
        ftm_mesh *m = single(tets);
        ftm_error err;
        ftm_sim_def d = neo_def();
        ftm_sim *neo = NULL, *lin = NULL;
        assert_int_equal(ftm_sim_create(m, &d, &neo, &err), FTM_OK);
        d.forces = FTM_FORCES_LINEAR_FEM;
        assert_int_equal(ftm_sim_create(m, &d, &lin, &err), FTM_OK);
        assert_true(ftm_sim_critical_time_step(neo) == ftm_sim_critical_time_step(lin));
        double x[24], fn[24], fl[24];
        uint64_t s = 3;
        for (int a = 0; a < 8; a++) {
            ftm_vec3 X = ftm_mesh_rest_position(m, a);
            x[3 * a] = X.x + 1e-9 * (rnd(&s) - 0.5);
            x[3 * a + 1] = X.y + 1e-9 * (rnd(&s) - 0.5);
            x[3 * a + 2] = X.z + 1e-9 * (rnd(&s) - 0.5);
        }
        assert_int_equal(ftm_sim_internal_forces(neo, x, fn), FTM_OK);
        assert_int_equal(ftm_sim_internal_forces(lin, x, fl), FTM_OK);
        double dmax = 0, fmx = 0;
        for (int k = 0; k < 24; k++) {
            dmax = fmax(dmax, fabs(fn[k] - fl[k]));
            fmx = fmax(fmx, fabs(fl[k]));
        }
        print_message("%s: neo-Hookean against K u at 1e-7 strain: %.2g\n",
                      tets ? "tetrahedra" : "hexahedron", dmax / fmx);
        assert_true(dmax < 1e-5 * fmx); /* O(strain) plus cancellation */
        /* and exactly zero at rest */
        for (int a = 0; a < 8; a++) {
            ftm_vec3 X = ftm_mesh_rest_position(m, a);
            x[3 * a] = X.x;
            x[3 * a + 1] = X.y;
            x[3 * a + 2] = X.z;
        }
        assert_int_equal(ftm_sim_internal_forces(neo, x, fn), FTM_OK);
        for (int k = 0; k < 24; k++)
            assert_true(fn[k] == 0.0);
        ftm_sim_destroy(neo);
        ftm_sim_destroy(lin);
        ftm_mesh_destroy(m);
    }
}

/* A cube of n^3 nodes (spacing 0.01 m), hexahedra, bottom face fixed. */
static ftm_mesh *block(int n, double damping)
{
    ftm_error err;
    ftm_mesh_builder *b = ftm_mesh_builder_create();
    ftm_lattice3d_def ld = ftm_default_lattice3d_def();
    ld.nx = ld.ny = ld.nz = n;
    ld.spacing = (ftm_vec3){0.01, 0.01, 0.01};
    ld.stencil = FTM_STENCIL_18;
    ld.material.node_mass = 1e-3;
    ld.material.node_damping = damping;
    ld.material.stiffness = 100;
    ld.fixed_faces = FTM_FACE_ZMIN;
    assert_int_equal(ftm_generate_lattice3d(b, &ld, &err), FTM_OK);
    ftm_mesh *m = NULL;
    assert_int_equal(ftm_mesh_build(b, NULL, &m, &err), FTM_OK);
    ftm_mesh_builder_destroy(b);
    return m;
}

/* Every node of a free body rotated rigidly by 60 degrees about z: no
 * neo-Hookean force (the linear forces are large). */
static void test_rigid_rotation(void **state)
{
    (void)state;
    ftm_mesh *m = single(false);
    ftm_error err;
    ftm_sim_def d = neo_def();
    ftm_sim *sim = NULL;
    assert_int_equal(ftm_sim_create(m, &d, &sim, &err), FTM_OK);
    double x[24], f[24];
    const double c = 0.5, s = sqrt(0.75); /* 60 degrees */
    for (int a = 0; a < 8; a++) {
        ftm_vec3 X = ftm_mesh_rest_position(m, a);
        x[3 * a] = c * X.x - s * X.y + 0.003;
        x[3 * a + 1] = s * X.x + c * X.y - 0.002;
        x[3 * a + 2] = X.z + 0.001;
    }
    assert_int_equal(ftm_sim_internal_forces(sim, x, f), FTM_OK);
    const double scale = YOUNG * 0.01 * 0.01; /* E times a face: 60 N */
    for (int k = 0; k < 24; k++)
        assert_true(fabs(f[k]) < 1e-10 * scale);
    ftm_sim_destroy(sim);
    ftm_mesh_destroy(m);
}

/* The same press in the three orders: the same bits (each element is
 * evaluated at the substep's start, whatever the order), and a loaded
 * keyframe every step continues with the same bits (nothing the state
 * does not hold carries over), with either far field (the elastic one
 * places its ring outside the sweeps). */
static void orders_and_keyframes(ftm_far_field far)
{
    ftm_mesh *m = block(5, 0.5);
    static const ftm_order orders[] = {FTM_ORDER_LAYER_COLORED, FTM_ORDER_BFS,
                                       FTM_ORDER_LAYER_JACOBI};
    const int32_t top = ftm_mesh_node_of_input(m, 2 + 5 * (2 + 5 * 4));
    const int32_t side = ftm_mesh_node_of_input(m, 4 + 5 * (1 + 5 * 3));
    uint64_t hash[3];
    for (int o = 0; o < 3; o++) {
        ftm_error err;
        ftm_sim_def d = neo_def();
        d.order = orders[o];
        d.depth = far == FTM_FAR_FIELD_ELASTIC ? 1 : 3;
        d.far_field = far;
        ftm_sim *sim = NULL, *copy = NULL;
        assert_int_equal(ftm_sim_create(m, &d, &sim, &err), FTM_OK);
        assert_int_equal(ftm_sim_create(m, &d, &copy, &err), FTM_OK);
        int32_t n = ftm_mesh_node_count(m);
        int32_t *nodes = malloc(sizeof *nodes * (size_t)n);
        double *x = malloc(sizeof *x * 3 * (size_t)n), *xp = malloc(sizeof *xp * 3 * (size_t)n);
        for (int st = 0; st < 400; st++) {
            /* a ramped oblique press, a force that comes and goes, a release */
            double a = st < 200 ? st / 200.0 : 1.0;
            ftm_contact c[2] = {{.node = top, .group = 0, .kind = FTM_CONTACT_DISPLACEMENT,
                                 .value = {0.001 * a, 0, -0.003 * a}},
                                {.node = side, .group = 1, .kind = FTM_CONTACT_FORCE,
                                 .value = {-0.5, 0, 0}}};
            int nc = st < 300 ? (st % 100 < 50 ? 2 : 1) : 0;
            assert_int_equal(ftm_sim_set_contacts(sim, c, nc, &err), FTM_OK);
            assert_int_equal(ftm_sim_step(sim), FTM_OK);
            if (o == 0) { /* the copy steps alike, then reloads its own state */
                assert_int_equal(ftm_sim_set_contacts(copy, c, nc, &err), FTM_OK);
                assert_int_equal(ftm_sim_step(copy), FTM_OK);
                assert_true(ftm_sim_hash(copy) == ftm_sim_hash(sim));
                /* reload the copy from its own state: drops what it carried */
                const double *cx = ftm_sim_positions(copy), *cxp = ftm_sim_previous_positions(copy);
                int32_t k = 0;
                for (int32_t i = 0; i < n; i++) {
                    ftm_vec3 X = ftm_mesh_rest_position(m, i);
                    const double *p = cx + 3 * i, *q = cxp + 3 * i;
                    if (ftm_mesh_fixed(m, i) ||
                        (p[0] == X.x && p[1] == X.y && p[2] == X.z && q[0] == X.x && q[1] == X.y &&
                         q[2] == X.z))
                        continue;
                    nodes[k] = i;
                    memcpy(x + 3 * k, p, 3 * sizeof *x);
                    memcpy(xp + 3 * k, q, 3 * sizeof *xp);
                    k++;
                }
                const ftm_contact *cc;
                int32_t ncc = ftm_sim_contacts(copy, &cc);
                ftm_contact keep[2];
                memcpy(keep, cc, (size_t)ncc * sizeof *cc);
                ftm_sim_mode mode;
                ftm_sim_get_mode(copy, &mode);
                ftm_sim_stats cs;
                ftm_sim_get_stats(copy, &cs);
                assert_int_equal(ftm_sim_load_state(copy, cs.step, cs.depth, nodes, x, xp, k, keep,
                                                    ncc, &mode, &err),
                                 FTM_OK);
                assert_true(ftm_sim_hash(copy) == ftm_sim_hash(sim));
            }
        }
        hash[o] = ftm_sim_hash(sim);
        free(nodes);
        free(x);
        free(xp);
        ftm_sim_destroy(sim);
        ftm_sim_destroy(copy);
    }
    assert_true(hash[0] == hash[1]);
    assert_true(hash[0] == hash[2]);
    ftm_mesh_destroy(m);
}

static void test_orders_and_keyframes(void **state)
{
    (void)state;
    orders_and_keyframes(FTM_FAR_FIELD_FIXED);
    orders_and_keyframes(FTM_FAR_FIELD_ELASTIC);
}

/* Without damping, at half the critical step, a press and release stays
 * bounded: the forces of the substep's start are plain central differences,
 * with no Gauss-Seidel coupling feeding energy in (docs/calculix.md). */
static void test_undamped_bounded(void **state)
{
    (void)state;
    ftm_mesh *m = block(5, 0.0);
    ftm_error err;
    ftm_sim_def d = neo_def();
    ftm_sim *sim = NULL;
    assert_int_equal(ftm_sim_create(m, &d, &sim, &err), FTM_OK);
    d.time_step = 0.5 * ftm_sim_critical_time_step(sim);
    ftm_sim_destroy(sim);
    assert_int_equal(ftm_sim_create(m, &d, &sim, &err), FTM_OK);
    ftm_contact c = {.node = ftm_mesh_node_of_input(m, 2 + 5 * (2 + 5 * 4)),
                     .kind = FTM_CONTACT_DISPLACEMENT, .value = {0, 0, -0.002}};
    double peak = 0;
    for (int st = 0; st < 6000; st++) {
        double a = st < 100 ? st / 100.0 : 1.0;
        c.value.z = -0.002 * a;
        assert_int_equal(ftm_sim_set_contacts(sim, &c, st < 3000, &err), FTM_OK);
        assert_int_equal(ftm_sim_step(sim), FTM_OK);
        if (st > 3000)
            for (int32_t i = 0; i < ftm_mesh_node_count(m); i++) {
                ftm_vec3 p = ftm_sim_position(sim, i), X = ftm_mesh_rest_position(m, i);
                peak = fmax(peak, fabs(p.z - X.z));
            }
    }
    ftm_sim_stats st;
    ftm_sim_get_stats(sim, &st);
    print_message("undamped after release: peak |u_z| %.3g mm, %llu guard events\n", 1e3 * peak,
                  (unsigned long long)st.guard_events);
    assert_int_equal(st.guard_events, 0);
    assert_true(peak < 0.004); /* free vibration of the 2 mm press, no growth */
    ftm_sim_destroy(sim);
    ftm_mesh_destroy(m);
}

typedef struct log_capture {
    char text[4096];
    int inverted, unstable;
} log_capture;

static void capture(void *user, ftm_log_level level, const char *message)
{
    log_capture *c = user;
    (void)level;
    if (strstr(message, "inverted"))
        c->inverted++;
    if (strstr(message, "even with"))
        c->unstable++;
    size_t n = strlen(c->text);
    snprintf(c->text + n, sizeof c->text - n, "%s\n", message);
}

/* A probe that pushes a node through the element below it at once: the
 * step fails with FTM_EUNSTABLE, the state exactly as before, the inverted
 * element named in the log, with the guard and without. */
static void test_inversion_refused(void **state)
{
    (void)state;
    ftm_mesh *m = block(4, 0.5);
    for (int guard = 0; guard < 2; guard++) {
        ftm_error err;
        log_capture lc = {{0}, 0, 0};
        ftm_sim_def d = neo_def();
        d.guard = guard;
        d.max_substeps = 4;
        d.log = capture;
        d.log_user = &lc;
        ftm_sim *sim = NULL;
        assert_int_equal(ftm_sim_create(m, &d, &sim, &err), FTM_OK);
        ftm_contact c = {.node = ftm_mesh_node_of_input(m, 1 + 4 * (1 + 4 * 3)),
                         .kind = FTM_CONTACT_DISPLACEMENT, .value = {0, 0, -0.005}};
        assert_int_equal(ftm_sim_set_contacts(sim, &c, 1, &err), FTM_OK);
        assert_int_equal(ftm_sim_run(sim, 20), FTM_OK); /* half a cell: fine */
        c.value.z = -0.025; /* two and a half cells below its rest place */
        assert_int_equal(ftm_sim_set_contacts(sim, &c, 1, &err), FTM_OK);
        assert_int_equal(rejected_steps_roll_back(sim, 2), 2);
        ftm_sim_stats st;
        ftm_sim_get_stats(sim, &st);
        assert_int_equal(st.unstable_steps, 2);
        assert_true(lc.inverted >= 2 && lc.unstable == 2);
        if (!strstr(lc.text, "hexahedron") || !strstr(lc.text, "input nodes"))
            fail_msg("the log does not name the element: %s", lc.text);
        const double *x = ftm_sim_positions(sim);
        for (int32_t k = 0; k < 3 * ftm_mesh_node_count(m); k++)
            assert_true(isfinite(x[k]));
        /* back to a reachable press: it goes on */
        c.value.z = -0.006;
        assert_int_equal(ftm_sim_set_contacts(sim, &c, 1, &err), FTM_OK);
        assert_int_equal(ftm_sim_run(sim, 20), FTM_OK);
        ftm_sim_destroy(sim);
    }
    ftm_mesh_destroy(m);
}

/* Far above the critical step with the motion guard off, the body blows up
 * until an element inverts; the inversion is caught and the step redone
 * with substeps, which hold it. */
static void test_inversion_substeps(void **state)
{
    (void)state;
    ftm_mesh *m = block(4, 0.5);
    ftm_error err;
    log_capture lc = {{0}, 0, 0};
    ftm_sim_def d = neo_def();
    ftm_sim *sim = NULL;
    assert_int_equal(ftm_sim_create(m, &d, &sim, &err), FTM_OK);
    d.time_step = 4.0 * ftm_sim_critical_time_step(sim);
    ftm_sim_destroy(sim);
    d.guard = false;
    d.log = capture;
    d.log_user = &lc;
    assert_int_equal(ftm_sim_create(m, &d, &sim, &err), FTM_OK);
    ftm_contact c = {.node = ftm_mesh_node_of_input(m, 1 + 4 * (1 + 4 * 3)),
                     .kind = FTM_CONTACT_FORCE, .value = {0, 0, -2.0}};
    assert_int_equal(ftm_sim_set_contacts(sim, &c, 1, &err), FTM_OK);
    assert_int_equal(ftm_sim_run(sim, 300), FTM_OK);
    ftm_sim_stats st;
    ftm_sim_get_stats(sim, &st);
    print_message("guard off at 4 h_crit: %llu inversions caught, now %d substeps\n",
                  (unsigned long long)st.guard_events, (int)st.substeps);
    assert_true(st.guard_events >= 1 && lc.inverted >= 1);
    assert_true(st.substeps > 1);
    for (int32_t k = 0; k < ftm_mesh_node_count(m); k++)
        assert_true(isfinite(ftm_sim_position(sim, k).z));
    ftm_sim_destroy(sim);
    ftm_mesh_destroy(m);
}

static void test_internal_forces_inverted(void **state)
{
    (void)state;
    ftm_mesh *m = single(false);
    ftm_error err;
    ftm_sim_def d = neo_def();
    ftm_sim *sim = NULL;
    assert_int_equal(ftm_sim_create(m, &d, &sim, &err), FTM_OK);
    double x[24], f[24];
    for (int a = 0; a < 8; a++) {
        ftm_vec3 X = ftm_mesh_rest_position(m, a);
        x[3 * a] = X.x;
        x[3 * a + 1] = X.y;
        x[3 * a + 2] = a >= 4 ? -X.z : X.z; /* the top face below the bottom */
        f[3 * a] = f[3 * a + 1] = f[3 * a + 2] = 12345.0;
    }
    assert_int_equal(ftm_sim_internal_forces(sim, x, f), FTM_EINVAL);
    for (int k = 0; k < 24; k++)
        assert_true(f[k] == 12345.0); /* untouched */
    ftm_sim_destroy(sim);
    ftm_mesh_destroy(m);
}

static void test_scene(void **state)
{
    (void)state;
    const char *text = "[mesh]\ngenerator = lattice3d\nnx = 3\nny = 3\nnz = 3\nspacing = 0.01\n"
                       "fixed_faces = zmin\n[material]\nmass = 0.001\nstiffness = 10\n"
                       "[fem]\nyoung = 0.6e6\npoisson = 0.45\ndensity = 1040\n"
                       "[sim]\nforces = neo-hookean\ntime_step = 1e-5\n";
    ftm_scene *sc = NULL;
    ftm_error err;
    assert_int_equal(ftm_scene_parse(text, strlen(text), "neo.scene", &sc, &err), FTM_OK);
    ftm_sim_def d = ftm_scene_sim_def(sc);
    assert_int_equal(d.forces, FTM_FORCES_NEO_HOOKEAN);
    assert_true(d.young == 0.6e6 && d.poisson == 0.45 && d.density == 1040);
    ftm_sim *sim = NULL;
    assert_int_equal(ftm_sim_create(ftm_scene_mesh(sc), &d, &sim, &err), FTM_OK);
    ftm_sim_destroy(sim);
    ftm_scene_destroy(sc);
    /* on a surface mesh: refused with the reason */
    const char *flat = "[mesh]\ngenerator = lattice2d\nnx = 4\nny = 4\nspacing = 0.01\n"
                       "[material]\nmass = 0.001\nstiffness = 10\n"
                       "[fem]\nyoung = 0.6e6\npoisson = 0.45\n[sim]\nforces = neo-hookean\n";
    assert_int_equal(ftm_scene_parse(flat, strlen(flat), "flat.scene", &sc, &err), FTM_EPARSE);
    if (!strstr(err.message, "hexahedra or tetrahedra"))
        fail_msg("message: %s", err.message);
}

int main(void)
{
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(test_inv_cbrt),
        cmocka_unit_test(test_stress),
        cmocka_unit_test(test_stress_objective_and_linear),
        cmocka_unit_test(test_tangent_at_rest),
        cmocka_unit_test(test_rigid_rotation),
        cmocka_unit_test(test_orders_and_keyframes),
        cmocka_unit_test(test_undamped_bounded),
        cmocka_unit_test(test_inversion_refused),
        cmocka_unit_test(test_inversion_substeps),
        cmocka_unit_test(test_internal_forces_inverted),
        cmocka_unit_test(test_scene),
    };
    return cmocka_run_group_tests(tests, NULL, NULL);
}
