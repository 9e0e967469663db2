/* SPDX-License-Identifier: GPL-3.0-or-later */
/* Tests of the force transmittal integrator (sim.h) against closed-form
 * static equilibria, the depth semantics, determinism, the intra-layer
 * order (paper section 3.1.4), anisotropy (paper Fig. 12), release and sleep,
 * imposed displacements with their reaction (Eq. 19), the stability guard
 * and contact validation. Public API only. */
#include <setjmp.h>
#include <stdarg.h>
#include <stddef.h>
#include <stdint.h>

#include <cmocka.h>

#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "ftm/generate.h"
#include "ftm/mesh.h"
#include "ftm/sim.h"

#define ASSERT_NEAR(a, b, tol)                                                            \
    do {                                                                                  \
        double a_ = (a), b_ = (b), t_ = (tol);                                            \
        if (!(fabs(a_ - b_) <= t_))                                                       \
            fail_msg("%s = %.17g, %s = %.17g, |diff| = %.3g > %.3g", #a, a_, #b, b_,      \
                     fabs(a_ - b_), t_);                                                  \
    } while (0)

/* ------------------------------------------------------------------ helpers */

static ftm_mesh *build(ftm_mesh_builder *b)
{
    ftm_mesh *m = NULL;
    ftm_error err;
    memset(&err, 0, sizeof err);
    ftm_mesh_build_def def = ftm_default_mesh_build_def();
    if (ftm_mesh_build(b, &def, &m, &err) != FTM_OK)
        fail_msg("ftm_mesh_build: %s", err.message);
    ftm_mesh_builder_destroy(b);
    return m;
}

/* Straight chain along x: n nodes at i * len, node 0 fixed if fix_first. */
static ftm_mesh *chain(int n, double len, double mass, double damping, double k, bool fix_first)
{
    ftm_mesh_builder *b = ftm_mesh_builder_create();
    for (int i = 0; i < n; i++) {
        ftm_node_def d = ftm_default_node_def();
        d.position = (ftm_vec3){i * len, 0.0, 0.0};
        d.mass = mass;
        d.damping = damping;
        d.fixed = fix_first && i == 0;
        assert_int_equal(ftm_mesh_builder_add_node(b, &d), i);
    }
    for (int i = 0; i + 1 < n; i++) {
        ftm_link_def l = ftm_default_link_def();
        l.a = i;
        l.b = i + 1;
        l.stiffness = k;
        l.rest_length = -1.0;
        assert_int_equal(ftm_mesh_builder_add_link(b, &l), FTM_OK);
    }
    return build(b);
}

static ftm_mesh *lattice2d(int nx, int ny, double mass, double damping, double k,
                           uint32_t fixed_faces)
{
    ftm_lattice2d_def def = ftm_default_lattice2d_def();
    def.nx = nx;
    def.ny = ny;
    def.spacing = 1.0;
    def.material.node_mass = mass;
    def.material.node_damping = damping;
    def.material.stiffness = k;
    def.fixed_faces = fixed_faces;
    ftm_mesh_builder *b = ftm_mesh_builder_create();
    ftm_error err;
    memset(&err, 0, sizeof err);
    if (ftm_generate_lattice2d(b, &def, &err) != FTM_OK)
        fail_msg("lattice2d: %s", err.message);
    return build(b);
}

static ftm_mesh *lattice3d(int n, ftm_stencil stencil, double mass, double damping, double k,
                           ftm_vec3 axis_scale, uint32_t fixed_faces)
{
    ftm_lattice3d_def def = ftm_default_lattice3d_def();
    def.nx = def.ny = def.nz = n;
    def.spacing = (ftm_vec3){1.0, 1.0, 1.0};
    def.stencil = stencil;
    def.material.node_mass = mass;
    def.material.node_damping = damping;
    def.material.stiffness = k;
    def.material.axis_scale = axis_scale;
    def.fixed_faces = fixed_faces;
    ftm_mesh_builder *b = ftm_mesh_builder_create();
    ftm_error err;
    memset(&err, 0, sizeof err);
    if (ftm_generate_lattice3d(b, &def, &err) != FTM_OK)
        fail_msg("lattice3d: %s", err.message);
    return build(b);
}

static int32_t in2d(const ftm_mesh *m, int nx, int ix, int iy)
{
    return ftm_mesh_node_of_input(m, ix + nx * iy);
}

static int32_t in3d(const ftm_mesh *m, int n, int ix, int iy, int iz)
{
    return ftm_mesh_node_of_input(m, ix + n * (iy + n * iz));
}

static ftm_sim *make_sim(const ftm_mesh *m, double h, int32_t depth, ftm_order order)
{
    ftm_sim_def def = ftm_default_sim_def();
    def.time_step = h;
    def.depth = depth;
    def.order = order;
    ftm_sim *s = NULL;
    ftm_error err;
    memset(&err, 0, sizeof err);
    if (ftm_sim_create(m, &def, &s, &err) != FTM_OK)
        fail_msg("ftm_sim_create: %s", err.message);
    return s;
}

static ftm_contact contact(int32_t node, int32_t group, ftm_contact_kind kind, ftm_vec3 v)
{
    ftm_contact c;
    memset(&c, 0, sizeof c);
    c.node = node;
    c.group = group;
    c.kind = kind;
    c.value = v;
    return c;
}

static void set1(ftm_sim *s, int32_t node, ftm_contact_kind kind, ftm_vec3 v)
{
    ftm_contact c = contact(node, 0, kind, v);
    ftm_error err;
    memset(&err, 0, sizeof err);
    if (ftm_sim_set_contacts(s, &c, 1, &err) != FTM_OK)
        fail_msg("ftm_sim_set_contacts: %s", err.message);
}

static double *copy_positions(const ftm_sim *s)
{
    size_t n = (size_t)ftm_mesh_node_count(ftm_sim_mesh(s)) * 3;
    double *p = malloc(n * sizeof *p);
    memcpy(p, ftm_sim_positions(s), n * sizeof *p);
    return p;
}

static double *rest_positions(const ftm_mesh *m)
{
    int32_t n = ftm_mesh_node_count(m);
    double *p = malloc((size_t)n * 3 * sizeof *p);
    for (int32_t i = 0; i < n; i++) {
        ftm_vec3 X = ftm_mesh_rest_position(m, i);
        p[3 * i] = X.x;
        p[3 * i + 1] = X.y;
        p[3 * i + 2] = X.z;
    }
    return p;
}

static double max_abs_diff(const double *a, const double *b, size_t n)
{
    double d = 0.0;
    for (size_t i = 0; i < n; i++)
        d = fmax(d, fabs(a[i] - b[i]));
    return d;
}

static bool all_finite(const ftm_sim *s)
{
    size_t n = (size_t)ftm_mesh_node_count(ftm_sim_mesh(s)) * 3;
    const double *p = ftm_sim_positions(s);
    for (size_t i = 0; i < n; i++)
        if (!isfinite(p[i]))
            return false;
    return true;
}

static double vdist(ftm_vec3 a, ftm_vec3 b)
{
    double dx = a.x - b.x, dy = a.y - b.y, dz = a.z - b.z;
    return sqrt(dx * dx + dy * dy + dz * dz);
}

/* Steps in chunks of 100 until no coordinate moves more than tol over a
 * chunk; fails if that takes more than max_steps. Returns the steps run. */
static int64_t run_to_equilibrium(ftm_sim *s, double tol, int64_t max_steps)
{
    size_t n = (size_t)ftm_mesh_node_count(ftm_sim_mesh(s)) * 3;
    double *before = malloc(n * sizeof *before);
    int64_t steps = 0;
    double moved = INFINITY;
    while (steps < max_steps) {
        memcpy(before, ftm_sim_positions(s), n * sizeof *before);
        int rc = ftm_sim_run(s, 100);
        if (rc != FTM_OK)
            fail_msg("ftm_sim_run failed (%d) after %lld steps", rc, (long long)steps);
        steps += 100;
        moved = max_abs_diff(before, ftm_sim_positions(s), n);
        if (moved < tol)
            break;
    }
    free(before);
    if (!(moved < tol))
        fail_msg("no equilibrium after %lld steps (last chunk moved %.3g, tol %.3g)",
                 (long long)steps, moved, tol);
    return steps;
}

/* ----------------------------------------------------------- definitions */

static void test_default_sim_def(void **state)
{
    (void)state;
    ftm_sim_def d = ftm_default_sim_def();
    assert_true(d.time_step == 1e-3);
    assert_int_equal(d.depth, 10);
    assert_int_equal(d.order, FTM_ORDER_LAYER_COLORED);
    assert_true(d.sleep_tolerance == 1e-6);
    assert_int_equal(d.region_sleep_steps, 0);
    assert_true(d.guard);
    assert_true(d.guard_motion == 0.5);
    assert_int_equal(d.max_substeps, 64);
    assert_true(d.cache_layers);
    assert_null(d.log);
}

static void test_sim_create_validation(void **state)
{
    (void)state;
    ftm_mesh *m = chain(3, 1.0, 1.0, 1.0, 10.0, true);
    static const double bad_h[] = {0.0, -1e-3, NAN, INFINITY, 1e-160, 1e4};
    for (size_t i = 0; i < sizeof bad_h / sizeof bad_h[0]; i++) {
        ftm_sim_def d = ftm_default_sim_def();
        d.time_step = bad_h[i];
        ftm_sim *sentinel = (ftm_sim *)(uintptr_t)0x4321, *s = sentinel;
        ftm_error err;
        memset(&err, 0, sizeof err);
        int rc = ftm_sim_create(m, &d, &s, &err);
        assert_true(rc < 0);
        assert_int_equal(err.code, rc);
        assert_true(strlen(err.message) > 0);
        assert_ptr_equal(s, sentinel);
    }
    ftm_sim_def d = ftm_default_sim_def();
    d.max_substeps = 0;
    ftm_sim *s = NULL;
    assert_true(ftm_sim_create(m, &d, &s, NULL) < 0);
    d = ftm_default_sim_def();
    d.guard_motion = -1.0;
    assert_true(ftm_sim_create(m, &d, &s, NULL) < 0);
    d = ftm_default_sim_def();
    d.sleep_tolerance = NAN;
    assert_true(ftm_sim_create(m, &d, &s, NULL) < 0);
    assert_null(s);
    ftm_mesh_destroy(m);
    /* a mass so large that m / h^2 overflows: refused, naming the node */
    m = chain(3, 1.0, 1e306, 1.0, 10.0, true);
    d = ftm_default_sim_def();
    ftm_error err;
    memset(&err, 0, sizeof err);
    assert_true(ftm_sim_create(m, &d, &s, &err) < 0);
    assert_non_null(strstr(err.message, "non-finite update coefficients"));
    assert_null(s);
    ftm_mesh_destroy(m);
}

static void test_fresh_sim_is_at_rest(void **state)
{
    (void)state;
    ftm_mesh *m = lattice2d(8, 7, 1.0, 1.0, 10.0, FTM_FACE_XMIN);
    ftm_sim *a = make_sim(m, 1e-3, 5, FTM_ORDER_LAYER_COLORED);
    ftm_sim *b = make_sim(m, 1e-3, 5, FTM_ORDER_BFS);
    double *rest = rest_positions(m);
    size_t n3 = (size_t)ftm_mesh_node_count(m) * 3;
    assert_memory_equal(ftm_sim_positions(a), rest, n3 * sizeof(double));
    assert_true(ftm_sim_hash(a) == ftm_sim_hash(b));
    assert_true(ftm_sim_kinetic_energy(a) == 0.0);
    /* "spring potential energy over the nodes not at rest": none here. */
    if (ftm_sim_potential_energy(a) != 0.0)
        fail_msg("fresh sim: potential energy %.17g, expected 0 (no node is displaced)",
                 ftm_sim_potential_energy(a));
    ftm_sim_stats st;
    ftm_sim_get_stats(a, &st);
    assert_true(st.step == 0);
    assert_int_equal(st.region_nodes, 0);
    assert_int_equal(st.relaxing_nodes, 0);
    assert_int_equal(st.substeps, 1);
    assert_int_equal(st.depth, 5);
    assert_ptr_equal(ftm_sim_mesh(a), m);
    /* Steps with no contact: only the step counter changes. */
    assert_int_equal(ftm_sim_run(a, 7), FTM_OK);
    ftm_sim_get_stats(a, &st);
    assert_true(st.step == 7);
    assert_int_equal(st.updated_nodes, 0);
    assert_memory_equal(ftm_sim_positions(a), rest, n3 * sizeof(double));
    assert_true(ftm_sim_hash(a) != ftm_sim_hash(b)); /* the step counter is hashed */
    assert_int_equal(ftm_sim_run(b, 7), FTM_OK);
    assert_true(ftm_sim_hash(a) == ftm_sim_hash(b));
    free(rest);
    ftm_sim_destroy(a);
    ftm_sim_destroy(b);
    ftm_mesh_destroy(m);
}

/* ---------------------------------------------------- static equilibria */

/* One spring, one end fixed at the origin, the other at (0.5, 0, 0), constant
 * force F on it: at equilibrium the spring force balances F, so the node sits
 * at distance 0.5 + |F|/k along F (a pull), or, for a push exactly along the
 * spring (no transverse component ever arises), at 0.5 - |F|/k on the x axis. */
static void check_single_spring(ftm_vec3 force, bool push)
{
    const double len = 0.5, k = 100.0, mass = 1.0, damping = 20.0; /* critical: 2 sqrt(km) */
    ftm_mesh *m = chain(2, len, mass, damping, k, true);
    int32_t fixed = ftm_mesh_node_of_input(m, 0), free_node = ftm_mesh_node_of_input(m, 1);
    ftm_sim *s = make_sim(m, 0.01, 10, FTM_ORDER_LAYER_COLORED);
    set1(s, free_node, FTM_CONTACT_FORCE, force);
    run_to_equilibrium(s, 1e-13, 200000);
    double fn = sqrt(force.x * force.x + force.y * force.y + force.z * force.z);
    double ext = fn / k;
    ftm_vec3 want = {(len + ext) * force.x / fn, (len + ext) * force.y / fn,
                     (len + ext) * force.z / fn};
    if (push)
        want = (ftm_vec3){len - ext, 0.0, 0.0};
    ftm_vec3 got = ftm_sim_position(s, free_node);
    ASSERT_NEAR(got.x, want.x, 1e-9 * ext);
    ASSERT_NEAR(got.y, want.y, 1e-9 * ext);
    ASSERT_NEAR(got.z, want.z, 1e-9 * ext);
    ASSERT_NEAR(fabs(vdist(got, ftm_sim_position(s, fixed)) - len), ext, 1e-9 * ext);
    /* The fixed end never moved. */
    ftm_vec3 p0 = ftm_sim_position(s, fixed);
    assert_true(p0.x == 0.0 && p0.y == 0.0 && p0.z == 0.0);
    /* Energies at rest under load: kinetic ~ 0, spring energy k e^2 / 2. */
    ASSERT_NEAR(ftm_sim_potential_energy(s), 0.5 * k * ext * ext, 1e-8 * 0.5 * k * ext * ext);
    assert_true(ftm_sim_kinetic_energy(s) < 1e-20);
    ftm_sim_destroy(s);
    ftm_mesh_destroy(m);
}

static void test_single_spring_along(void **state)
{
    (void)state;
    check_single_spring((ftm_vec3){3.0, 0.0, 0.0}, false); /* stretch */
    check_single_spring((ftm_vec3){-2.0, 0.0, 0.0}, true); /* compress */
}

static void test_single_spring_along_stays_on_axis(void **state)
{
    (void)state;
    /* A force along the spring never creates a transverse component. */
    ftm_mesh *m = chain(2, 0.5, 1.0, 20.0, 100.0, true);
    int32_t free_node = ftm_mesh_node_of_input(m, 1);
    ftm_sim *s = make_sim(m, 0.01, 10, FTM_ORDER_LAYER_COLORED);
    set1(s, free_node, FTM_CONTACT_FORCE, (ftm_vec3){3.0, 0.0, 0.0});
    for (int i = 0; i < 500; i++) {
        assert_int_equal(ftm_sim_step(s), FTM_OK);
        ftm_vec3 p = ftm_sim_position(s, free_node);
        assert_true(p.y == 0.0 && p.z == 0.0);
    }
    ftm_sim_destroy(s);
    ftm_mesh_destroy(m);
}

static void test_single_spring_oblique(void **state)
{
    (void)state;
    /* Force at an angle: the spring swings round and aligns with it. */
    check_single_spring((ftm_vec3){2.0, 2.0, 1.0}, false);
    check_single_spring((ftm_vec3){0.5, -1.0, 0.0}, false);
}

/* Node C between fixed A (-1,0,0) and B (1,0,0), springs of natural length 1,
 * force F perpendicular: 2 k (s - 1) y / s = F with s = sqrt(1 + y^2). */
static void test_two_springs_perpendicular(void **state)
{
    (void)state;
    const double k = 100.0, f = 10.0;
    ftm_mesh_builder *b = ftm_mesh_builder_create();
    const double xs[3] = {-1.0, 1.0, 0.0};
    for (int i = 0; i < 3; i++) {
        ftm_node_def d = ftm_default_node_def();
        d.position = (ftm_vec3){xs[i], 0.0, 0.0};
        d.mass = 1.0;
        d.damping = 10.0;
        d.fixed = i < 2;
        ftm_mesh_builder_add_node(b, &d);
    }
    for (int i = 0; i < 2; i++) {
        ftm_link_def l = ftm_default_link_def();
        l.a = i;
        l.b = 2;
        l.stiffness = k;
        l.rest_length = -1.0;
        ftm_mesh_builder_add_link(b, &l);
    }
    ftm_mesh *m = build(b);
    int32_t c = ftm_mesh_node_of_input(m, 2);
    ftm_sim *s = make_sim(m, 0.01, 3, FTM_ORDER_LAYER_COLORED);
    set1(s, c, FTM_CONTACT_FORCE, (ftm_vec3){0.0, f, 0.0});
    run_to_equilibrium(s, 1e-13, 400000);
    /* Reference by bisection: g(y) = 2k(s-1)y/s - F is increasing in y. */
    double lo = 0.0, hi = 10.0;
    for (int i = 0; i < 200; i++) {
        double y = 0.5 * (lo + hi), sl = sqrt(1.0 + y * y);
        if (2.0 * k * (sl - 1.0) * y / sl < f)
            lo = y;
        else
            hi = y;
    }
    double y = 0.5 * (lo + hi);
    ftm_vec3 p = ftm_sim_position(s, c);
    ASSERT_NEAR(p.y, y, 1e-9 * y);
    ASSERT_NEAR(p.x, 0.0, 1e-12);
    assert_true(p.z == 0.0);
    ftm_sim_destroy(s);
    ftm_mesh_destroy(m);
}

/* Chain of N nodes, first fixed, force F on the last along the chain: every
 * spring carries F and extends by F/k. */
static void test_chain_extension(void **state)
{
    (void)state;
    enum { N = 10 };
    const double len = 0.2, k = 50.0, f = 1.5;
    ftm_mesh *m = chain(N, len, 0.5, 3.0, k, true);
    int32_t node[N];
    for (int i = 0; i < N; i++)
        node[i] = ftm_mesh_node_of_input(m, i);
    ftm_sim *s = make_sim(m, 0.01, N, FTM_ORDER_LAYER_COLORED);
    set1(s, node[N - 1], FTM_CONTACT_FORCE, (ftm_vec3){f, 0.0, 0.0});
    run_to_equilibrium(s, 1e-13, 400000);
    for (int i = 0; i + 1 < N; i++) {
        double ext = ftm_sim_position(s, node[i + 1]).x - ftm_sim_position(s, node[i]).x - len;
        ASSERT_NEAR(ext, f / k, 1e-9 * f / k);
    }
    ASSERT_NEAR(ftm_sim_position(s, node[N - 1]).x, (N - 1) * (len + f / k), 1e-9 * N * f / k);
    ftm_sim_destroy(s);

    /* Depth 3: layers are nodes 9, 8, 7, 6; node 5 and below never move, so
     * the chain behaves as if node 5 were fixed. */
    s = make_sim(m, 0.01, 3, FTM_ORDER_BFS);
    set1(s, node[N - 1], FTM_CONTACT_FORCE, (ftm_vec3){f, 0.0, 0.0});
    run_to_equilibrium(s, 1e-13, 400000);
    for (int i = 0; i <= N - 5; i++) {
        ftm_vec3 p = ftm_sim_position(s, node[i]);
        assert_true(p.x == i * len && p.y == 0.0 && p.z == 0.0);
    }
    for (int i = N - 5; i + 1 < N; i++) {
        double ext = ftm_sim_position(s, node[i + 1]).x - ftm_sim_position(s, node[i]).x - len;
        ASSERT_NEAR(ext, f / k, 1e-9 * f / k);
    }
    ftm_sim_stats st;
    ftm_sim_get_stats(s, &st);
    assert_int_equal(st.region_nodes, 4);
    assert_int_equal(st.layers, 4);
    ftm_sim_destroy(s);
    ftm_mesh_destroy(m);
}

/* ------------------------------------------------------- depth semantics */

static void test_nodes_beyond_depth_never_move(void **state)
{
    (void)state;
    const int nx = 21, ny = 21, depth = 3;
    ftm_mesh *m = lattice2d(nx, ny, 1.0, 2.0, 20.0, 0);
    int32_t n = ftm_mesh_node_count(m);
    int32_t c = in2d(m, nx, 10, 10);
    ftm_sim *s = make_sim(m, 0.01, depth, FTM_ORDER_LAYER_COLORED);
    set1(s, c, FTM_CONTACT_FORCE, (ftm_vec3){1.0, 0.37, 0.0});
    assert_int_equal(ftm_sim_run(s, 200), FTM_OK);
    const int32_t *order, *start;
    int32_t lc = ftm_sim_layers(s, &order, &start);
    assert_int_equal(lc, depth + 1);
    int32_t *layer = malloc(sizeof *layer * (size_t)n);
    for (int32_t i = 0; i < n; i++)
        layer[i] = -1;
    for (int32_t l = 0; l < lc; l++)
        for (int32_t p = start[l]; p < start[l + 1]; p++)
            layer[order[p]] = l;
    for (int32_t i = 0; i < n; i++) {
        ftm_vec3 x = ftm_sim_position(s, i), X = ftm_mesh_rest_position(m, i);
        bool at_rest = x.x == X.x && x.y == X.y && x.z == X.z;
        if (layer[i] < 0 && !at_rest)
            fail_msg("node %d outside the region moved by %.3g", (int)i, vdist(x, X));
        if (layer[i] >= 0 && at_rest)
            fail_msg("node %d in layer %d did not move", (int)i, (int)layer[i]);
    }
    ftm_sim_stats st;
    ftm_sim_get_stats(s, &st);
    assert_int_equal(st.region_nodes, 37);
    /* Each step updates the free region nodes once (one substep). */
    assert_int_equal(st.substeps, 1);
    assert_int_equal(st.updated_nodes, 37);
    free(layer);
    ftm_sim_destroy(s);
    ftm_mesh_destroy(m);
}

/* ----------------------------------------------------------- determinism */

static void scripted_run(ftm_sim *s, const ftm_mesh *m, int nx, double tweak)
{
    ftm_contact c[3] = {
        contact(in2d(m, nx, 8, 9), 0, FTM_CONTACT_FORCE, (ftm_vec3){0.3, -0.2, 0.1}),
        contact(in2d(m, nx, 10, 9), 1, FTM_CONTACT_DISPLACEMENT, (ftm_vec3){0.0, 0.05, 0.0}),
        contact(in2d(m, nx, 9, 11), 1, FTM_CONTACT_FORCE, (ftm_vec3){-0.1, tweak, 0.0}),
    };
    assert_int_equal(ftm_sim_set_contacts(s, c, 3, NULL), FTM_OK);
    assert_int_equal(ftm_sim_run(s, 150), FTM_OK);
    c[0].value.x = 0.6; /* value change only */
    assert_int_equal(ftm_sim_set_contacts(s, c, 3, NULL), FTM_OK);
    assert_int_equal(ftm_sim_run(s, 100), FTM_OK);
    assert_int_equal(ftm_sim_set_contacts(s, c + 1, 2, NULL), FTM_OK); /* node set change */
    assert_int_equal(ftm_sim_run(s, 100), FTM_OK);
    assert_int_equal(ftm_sim_set_contacts(s, NULL, 0, NULL), FTM_OK); /* release */
    assert_int_equal(ftm_sim_run(s, 50), FTM_OK);
}

static void test_determinism(void **state)
{
    (void)state;
    const int nx = 18, ny = 18;
    ftm_mesh *m1 = lattice2d(nx, ny, 1.0, 1.0, 30.0, FTM_FACE_YMIN);
    ftm_mesh *m2 = lattice2d(nx, ny, 1.0, 1.0, 30.0, FTM_FACE_YMIN);
    size_t n3 = (size_t)ftm_mesh_node_count(m1) * 3;
    static const ftm_order orders[3] = {FTM_ORDER_LAYER_COLORED, FTM_ORDER_BFS,
                                        FTM_ORDER_LAYER_JACOBI};
    for (int o = 0; o < 3; o++) {
        ftm_sim *a = make_sim(m1, 0.01, 6, orders[o]);
        ftm_sim *b = make_sim(m2, 0.01, 6, orders[o]); /* a separately built, equal mesh */
        ftm_sim *c = make_sim(m1, 0.01, 6, orders[o]);
        scripted_run(a, m1, nx, 0.2);
        scripted_run(b, m2, nx, 0.2);
        /* One force 1e-9 relative off. (A single-ulp change can be absorbed
         * by rounding in a * (F - sum f) and never reach the state.) */
        scripted_run(c, m1, nx, 0.2 * (1.0 + 1e-9));
        assert_true(ftm_sim_hash(a) == ftm_sim_hash(b));
        assert_memory_equal(ftm_sim_positions(a), ftm_sim_positions(b), n3 * sizeof(double));
        assert_true(ftm_sim_hash(a) != ftm_sim_hash(c));
        assert_memory_not_equal(ftm_sim_positions(a), ftm_sim_positions(c), n3 * sizeof(double));
        /* The state is not at rest yet (so the hash covers positions). */
        ftm_sim_stats st;
        ftm_sim_get_stats(a, &st);
        assert_true(st.relaxing_nodes > 0);
        uint64_t h = ftm_sim_hash(a);
        assert_int_equal(ftm_sim_step(a), FTM_OK);
        assert_true(ftm_sim_hash(a) != h);
        ftm_sim_destroy(a);
        ftm_sim_destroy(b);
        ftm_sim_destroy(c);
    }
    ftm_mesh_destroy(m1);
    ftm_mesh_destroy(m2);
}

/* ---------------------------------------------- intra-layer order (3.1.4) */

static void compare_orders(const ftm_mesh *m, int32_t load_node, ftm_vec3 force, int32_t depth,
                           double h, double spacing)
{
    static const ftm_order orders[3] = {FTM_ORDER_LAYER_COLORED, FTM_ORDER_BFS,
                                        FTM_ORDER_LAYER_JACOBI};
    size_t n3 = (size_t)ftm_mesh_node_count(m) * 3;
    double *pos[3];
    double *rest = rest_positions(m);
    for (int o = 0; o < 3; o++) {
        ftm_sim *s = make_sim(m, h, depth, orders[o]);
        set1(s, load_node, FTM_CONTACT_FORCE, force);
        run_to_equilibrium(s, 1e-12 * spacing, 400000);
        pos[o] = copy_positions(s);
        ftm_sim_destroy(s);
    }
    double disp = max_abs_diff(pos[0], rest, n3);
    assert_true(disp > 1e-3 * spacing); /* a real deformation */
    for (int o = 1; o < 3; o++) {
        double d = max_abs_diff(pos[0], pos[o], n3);
        print_message("order %d vs colored: max difference %.3g (max displacement %.3g)\n", o, d,
                      disp);
        if (!(d < 1e-6 * spacing))
            fail_msg("order %d vs colored: max position difference %.3g (displacement %.3g)", o,
                     d, disp);
    }
    for (int o = 0; o < 3; o++)
        free(pos[o]);
    free(rest);
}

static void test_intra_layer_order_2d(void **state)
{
    (void)state;
    const int nx = 25, ny = 25;
    ftm_mesh *m = lattice2d(nx, ny, 1.0, 4.0, 10.0, 0);
    compare_orders(m, in2d(m, nx, 12, 12), (ftm_vec3){0.8, 0.5, 0.0}, 6, 0.02, 1.0);
    ftm_mesh_destroy(m);
}

static void test_intra_layer_order_3d(void **state)
{
    (void)state;
    const int n = 7;
    ftm_mesh *m = lattice3d(n, FTM_STENCIL_26, 1.0, 4.0, 10.0, (ftm_vec3){1, 1, 1}, FTM_FACE_ZMIN);
    compare_orders(m, in3d(m, n, 3, 3, n - 1), (ftm_vec3){0.3, 0.2, -1.5}, 6, 0.02, 1.0);
    ftm_mesh_destroy(m);
}

/* --------------------------------------------------- anisotropy (Fig. 12) */

enum { CUBE = 5 };

/* Loaded-node displacement of a CUBE^3 26-stencil lattice; vertical: ZMIN
 * fixed, force -z on the centre of the top face; horizontal: XMIN fixed,
 * force -x on the centre of the XMAX face. Fills disp (all nodes, by input
 * index) if not NULL. */
static double cube_displacement(ftm_vec3 axis_scale, bool horizontal, double *disp)
{
    const double k = 10.0, f = 0.5;
    uint32_t faces = horizontal ? FTM_FACE_XMIN : FTM_FACE_ZMIN;
    /* Damping ratio >= 0.1 in the stiffest mode (omega_max <= 2 / h_crit):
     * enough for the layer-by-layer update, and near-critical for the
     * slowest modes so that the equilibrium is reached quickly. */
    ftm_mesh *m = lattice3d(CUBE, FTM_STENCIL_26, 1.0, 0.0, k, axis_scale, faces);
    double damping = 0.4 / ftm_mesh_critical_time_step(m);
    ftm_mesh_destroy(m);
    m = lattice3d(CUBE, FTM_STENCIL_26, 1.0, damping, k, axis_scale, faces);
    int c = CUBE / 2;
    int32_t load = horizontal ? in3d(m, CUBE, CUBE - 1, c, c) : in3d(m, CUBE, c, c, CUBE - 1);
    ftm_vec3 force = horizontal ? (ftm_vec3){-f, 0, 0} : (ftm_vec3){0, 0, -f};
    double h = 0.5 * ftm_mesh_critical_time_step(m);
    ftm_sim *s = make_sim(m, h, 3 * CUBE, FTM_ORDER_LAYER_COLORED);
    set1(s, load, FTM_CONTACT_FORCE, force);
    run_to_equilibrium(s, 1e-13, 400000);
    double d = vdist(ftm_sim_position(s, load), ftm_mesh_rest_position(m, load));
    if (disp) {
        for (int32_t in = 0; in < CUBE * CUBE * CUBE; in++) {
            int32_t node = ftm_mesh_node_of_input(m, in);
            ftm_vec3 x = ftm_sim_position(s, node), X = ftm_mesh_rest_position(m, node);
            disp[3 * in] = x.x - X.x;
            disp[3 * in + 1] = x.y - X.y;
            disp[3 * in + 2] = x.z - X.z;
        }
    }
    ftm_sim_destroy(s);
    ftm_mesh_destroy(m);
    return d;
}

static void test_anisotropy_isotropic_symmetry(void **state)
{
    (void)state;
    /* Isotropic: the horizontal case is the vertical one rotated (x <-> z),
     * so the displacement fields match node for node. */
    enum { N3 = CUBE * CUBE * CUBE };
    double *dv = malloc(3 * N3 * sizeof *dv), *dh = malloc(3 * N3 * sizeof *dh);
    double v = cube_displacement((ftm_vec3){1, 1, 1}, false, dv);
    double hz = cube_displacement((ftm_vec3){1, 1, 1}, true, dh);
    assert_true(v > 1e-3);
    ASSERT_NEAR(hz, v, 1e-6 * v);
    for (int ix = 0; ix < CUBE; ix++)
        for (int iy = 0; iy < CUBE; iy++)
            for (int iz = 0; iz < CUBE; iz++) {
                int a = ix + CUBE * (iy + CUBE * iz), b = iz + CUBE * (iy + CUBE * ix);
                ASSERT_NEAR(dv[3 * a], dh[3 * b + 2], 1e-6 * v);
                ASSERT_NEAR(dv[3 * a + 1], dh[3 * b + 1], 1e-6 * v);
                ASSERT_NEAR(dv[3 * a + 2], dh[3 * b], 1e-6 * v);
            }
    free(dv);
    free(dh);
}

static void test_anisotropy_soft_and_stiff(void **state)
{
    (void)state;
    double iso_h = cube_displacement((ftm_vec3){1, 1, 1}, true, NULL);
    double soft_h = cube_displacement((ftm_vec3){0.1, 0.1, 1}, true, NULL);   /* A */
    double stiff_h = cube_displacement((ftm_vec3){10, 10, 1}, true, NULL);    /* B */
    double soft_v = cube_displacement((ftm_vec3){0.1, 0.1, 1}, false, NULL);
    double stiff_v = cube_displacement((ftm_vec3){10, 10, 1}, false, NULL);
    print_message("horizontal: soft %.6g iso %.6g stiff %.6g; vertical: soft %.6g stiff %.6g\n",
                  soft_h, iso_h, stiff_h, soft_v, stiff_v);
    /* Horizontal springs 10x softer deform more horizontally, 10x stiffer less. */
    assert_true(soft_h > 1.5 * iso_h);
    assert_true(stiff_h < iso_h / 1.5);
    /* Against the vertical load on the same lattice. */
    assert_true(soft_h > soft_v);
    assert_true(stiff_h < stiff_v);
}

/* ------------------------------------------------ release, relax, sleep */

static void test_release_relax_sleep(void **state)
{
    (void)state;
    const int nx = 15, ny = 15;
    ftm_mesh *m = lattice2d(nx, ny, 1.0, 3.0, 20.0, 0);
    size_t n3 = (size_t)ftm_mesh_node_count(m) * 3;
    double *rest = rest_positions(m);
    ftm_sim *s = make_sim(m, 0.02, 4, FTM_ORDER_LAYER_COLORED);
    set1(s, in2d(m, nx, 7, 7), FTM_CONTACT_FORCE, (ftm_vec3){1.0, -0.6, 0.0});
    assert_int_equal(ftm_sim_run(s, 200), FTM_OK);
    ftm_sim_stats st;
    ftm_sim_get_stats(s, &st);
    assert_int_equal(st.region_nodes, 61);
    assert_int_equal(st.relaxing_nodes, 0);
    assert_true(ftm_sim_potential_energy(s) > 0.0);

    assert_int_equal(ftm_sim_set_contacts(s, NULL, 0, NULL), FTM_OK);
    assert_int_equal(ftm_sim_step(s), FTM_OK);
    ftm_sim_get_stats(s, &st);
    assert_int_equal(st.region_nodes, 0);
    assert_true(st.relaxing_nodes > 0);
    assert_true(st.relaxing_nodes <= 61);
    assert_true(st.updated_nodes > 0);
    int64_t steps = 201;
    while (st.relaxing_nodes > 0 && steps < 100000) {
        assert_int_equal(ftm_sim_step(s), FTM_OK);
        steps++;
        ftm_sim_get_stats(s, &st);
    }
    assert_int_equal(st.relaxing_nodes, 0);
    assert_true(st.step == (uint64_t)steps);
    /* Asleep: exactly at rest. */
    assert_memory_equal(ftm_sim_positions(s), rest, n3 * sizeof(double));
    assert_true(ftm_sim_kinetic_energy(s) == 0.0);
    /* The same hash as a sim that never had a contact, after as many steps. */
    ftm_sim *fresh = make_sim(m, 0.02, 4, FTM_ORDER_LAYER_COLORED);
    assert_int_equal(ftm_sim_run(fresh, (int32_t)steps), FTM_OK);
    assert_true(ftm_sim_hash(s) == ftm_sim_hash(fresh));
    /* Nothing left to do. */
    assert_int_equal(ftm_sim_step(s), FTM_OK);
    ftm_sim_get_stats(s, &st);
    assert_int_equal(st.updated_nodes, 0);
    assert_int_equal(st.relaxing_nodes, 0);
    assert_memory_equal(ftm_sim_positions(s), rest, n3 * sizeof(double));
    assert_int_equal(ftm_sim_step(fresh), FTM_OK);
    assert_true(ftm_sim_hash(s) == ftm_sim_hash(fresh));
    /* Spring energy "over the nodes not at rest": none left. */
    if (ftm_sim_potential_energy(s) != 0.0)
        fail_msg("asleep: potential energy %.17g, expected 0", ftm_sim_potential_energy(s));
    free(rest);
    ftm_sim_destroy(fresh);
    ftm_sim_destroy(s);
    ftm_mesh_destroy(m);
}

/* The contact moves: nodes of the old region that are not in the new one
 * relax back to rest while the new region deforms. */
static void test_moving_contact_relaxes_old_region(void **state)
{
    (void)state;
    const int nx = 30, ny = 12;
    ftm_mesh *m = lattice2d(nx, ny, 1.0, 3.0, 20.0, 0);
    int32_t n = ftm_mesh_node_count(m);
    int32_t a = in2d(m, nx, 6, 6), b = in2d(m, nx, 22, 6);
    ftm_sim *s = make_sim(m, 0.02, 3, FTM_ORDER_LAYER_COLORED);
    set1(s, a, FTM_CONTACT_FORCE, (ftm_vec3){0.0, 1.0, 0.0});
    assert_int_equal(ftm_sim_run(s, 100), FTM_OK);
    set1(s, b, FTM_CONTACT_FORCE, (ftm_vec3){0.0, 1.0, 0.0});
    assert_int_equal(ftm_sim_step(s), FTM_OK);
    ftm_sim_stats st;
    ftm_sim_get_stats(s, &st);
    assert_int_equal(st.region_nodes, 37);
    assert_int_equal(st.relaxing_nodes, 37); /* disjoint regions, all displaced */
    for (int i = 0; i < 20000 && st.relaxing_nodes > 0; i++) {
        assert_int_equal(ftm_sim_step(s), FTM_OK);
        ftm_sim_get_stats(s, &st);
    }
    assert_int_equal(st.relaxing_nodes, 0);
    /* Old region back at rest exactly; the new one deformed. */
    for (int32_t i = 0; i < n; i++) {
        int32_t in = ftm_mesh_input_of_node(m, i);
        int ix = in % nx;
        ftm_vec3 x = ftm_sim_position(s, i), X = ftm_mesh_rest_position(m, i);
        if (ix < 15)
            assert_true(x.x == X.x && x.y == X.y && x.z == X.z);
    }
    assert_true(vdist(ftm_sim_position(s, b), ftm_mesh_rest_position(m, b)) > 1e-3);
    ftm_sim_destroy(s);
    ftm_mesh_destroy(m);
}

static void test_region_sleep(void **state)
{
    (void)state;
    ftm_mesh *m = chain(4, 1.0, 1.0, 10.0, 25.0, true);
    int32_t last = ftm_mesh_node_of_input(m, 3);
    ftm_sim_def def = ftm_default_sim_def();
    def.time_step = 0.01;
    def.region_sleep_steps = 5;
    ftm_sim *s = NULL;
    assert_int_equal(ftm_sim_create(m, &def, &s, NULL), FTM_OK);
    set1(s, last, FTM_CONTACT_FORCE, (ftm_vec3){1.0, 0.0, 0.0});
    ftm_sim_stats st;
    int i;
    for (i = 0; i < 100000; i++) {
        assert_int_equal(ftm_sim_step(s), FTM_OK);
        ftm_sim_get_stats(s, &st);
        if (st.region_sleeping)
            break;
    }
    assert_true(st.region_sleeping);
    /* Near the static answer: node 3 at 3 + 3 F/k (within the sleep
     * tolerance times the per-step convergence factor; loose bound). */
    ASSERT_NEAR(ftm_sim_position(s, last).x, 3.0 + 3.0 / 25.0, 1e-3);
    /* Asleep: the region is not touched any more. */
    double *p = copy_positions(s);
    uint64_t h = ftm_sim_hash(s);
    assert_int_equal(ftm_sim_run(s, 10), FTM_OK);
    ftm_sim_get_stats(s, &st);
    assert_true(st.region_sleeping);
    assert_int_equal(st.updated_nodes, 0);
    assert_memory_equal(ftm_sim_positions(s), p, 12 * sizeof(double));
    assert_true(ftm_sim_hash(s) != h); /* step counter */
    /* A new load value wakes it. */
    set1(s, last, FTM_CONTACT_FORCE, (ftm_vec3){2.0, 0.0, 0.0});
    assert_int_equal(ftm_sim_step(s), FTM_OK);
    ftm_sim_get_stats(s, &st);
    assert_false(st.region_sleeping);
    assert_true(st.updated_nodes > 0);
    assert_true(ftm_sim_position(s, last).x > p[3 * last]);
    free(p);
    ftm_sim_destroy(s);
    ftm_mesh_destroy(m);
}

static void test_reset(void **state)
{
    (void)state;
    const int nx = 10, ny = 10;
    ftm_mesh *m = lattice2d(nx, ny, 1.0, 3.0, 20.0, 0);
    size_t n3 = (size_t)ftm_mesh_node_count(m) * 3;
    double *rest = rest_positions(m);
    ftm_sim *s = make_sim(m, 0.02, 4, FTM_ORDER_LAYER_COLORED);
    set1(s, in2d(m, nx, 5, 5), FTM_CONTACT_FORCE, (ftm_vec3){1.0, 0.0, 0.0});
    assert_int_equal(ftm_sim_run(s, 50), FTM_OK);
    ftm_sim_reset(s);
    assert_memory_equal(ftm_sim_positions(s), rest, n3 * sizeof(double));
    assert_int_equal(ftm_sim_step(s), FTM_OK);
    ftm_sim_stats st;
    ftm_sim_get_stats(s, &st);
    assert_int_equal(st.region_nodes, 0);
    assert_int_equal(st.relaxing_nodes, 0);
    assert_int_equal(st.updated_nodes, 0);
    assert_int_equal(st.depth, 4); /* the definition is kept */
    assert_memory_equal(ftm_sim_positions(s), rest, n3 * sizeof(double));
    free(rest);
    ftm_sim_destroy(s);
    ftm_mesh_destroy(m);
}

/* ------------------------------------------------ imposed displacements */

static void test_displacement_single_spring(void **state)
{
    (void)state;
    const double len = 1.0, k = 40.0;
    ftm_mesh *m = chain(2, len, 1.0, 5.0, k, true);
    int32_t end = ftm_mesh_node_of_input(m, 1);
    ftm_sim *s = make_sim(m, 0.01, 5, FTM_ORDER_LAYER_COLORED);
    ftm_vec3 X = ftm_mesh_rest_position(m, end);

    /* Stretch by u along the spring: F_react = -k u x (Eq. 19). */
    const double u = 0.03;
    ftm_contact c = contact(end, 2, FTM_CONTACT_DISPLACEMENT, (ftm_vec3){u, 0.0, 0.0});
    assert_int_equal(ftm_sim_set_contacts(s, &c, 1, NULL), FTM_OK);
    assert_int_equal(ftm_sim_step(s), FTM_OK);
    ftm_vec3 p = ftm_sim_position(s, end);
    assert_true(p.x == X.x + u && p.y == X.y + 0.0 && p.z == X.z + 0.0);
    ftm_vec3 r = ftm_sim_reaction(s, 2);
    ASSERT_NEAR(r.x, -k * u, 1e-9 * k * u);
    ASSERT_NEAR(r.y, 0.0, 1e-12);
    ASSERT_NEAR(r.z, 0.0, 1e-12);
    /* Groups without displacement contacts have no reaction. */
    ftm_vec3 r0 = ftm_sim_reaction(s, 0), r9 = ftm_sim_reaction(s, 9);
    assert_true(r0.x == 0.0 && r0.y == 0.0 && r0.z == 0.0);
    assert_true(r9.x == 0.0 && r9.y == 0.0 && r9.z == 0.0);

    /* Push in: compression, reaction pushes back out. */
    c.value = (ftm_vec3){-2.0 * u, 0.0, 0.0};
    assert_int_equal(ftm_sim_set_contacts(s, &c, 1, NULL), FTM_OK);
    assert_int_equal(ftm_sim_step(s), FTM_OK);
    assert_true(ftm_sim_position(s, end).x == X.x + -2.0 * u);
    r = ftm_sim_reaction(s, 2);
    ASSERT_NEAR(r.x, 2.0 * k * u, 1e-9 * k * u);

    /* Sideways by v: f = k (|r| - l) r / |r| with r = (l, v, 0). */
    const double v = 0.2;
    c.value = (ftm_vec3){0.0, v, 0.0};
    assert_int_equal(ftm_sim_set_contacts(s, &c, 1, NULL), FTM_OK);
    assert_int_equal(ftm_sim_run(s, 3), FTM_OK);
    p = ftm_sim_position(s, end);
    assert_true(p.x == X.x + 0.0 && p.y == X.y + v);
    double rl = sqrt(len * len + v * v), t = k * (rl - len) / rl;
    r = ftm_sim_reaction(s, 2);
    ASSERT_NEAR(r.x, -t * len, 1e-9 * t);
    ASSERT_NEAR(r.y, -t * v, 1e-9 * t);
    ASSERT_NEAR(r.z, 0.0, 1e-12);
    ftm_sim_destroy(s);
    ftm_mesh_destroy(m);
}

/* Three-node chain, node 0 fixed, node 2 displaced by u: at equilibrium node 1
 * sits half way and the reaction is -k u / 2. A force contact in the same
 * group does not contribute (Eq. 19 sums displacement-contact nodes). */
static void test_displacement_chain_equilibrium(void **state)
{
    (void)state;
    const double k = 30.0, u = 0.1;
    ftm_mesh *m = chain(3, 1.0, 1.0, 6.0, k, true);
    int32_t n1 = ftm_mesh_node_of_input(m, 1), n2 = ftm_mesh_node_of_input(m, 2);
    ftm_sim *s = make_sim(m, 0.01, 5, FTM_ORDER_LAYER_COLORED);
    ftm_contact c = contact(n2, 0, FTM_CONTACT_DISPLACEMENT, (ftm_vec3){u, 0.0, 0.0});
    assert_int_equal(ftm_sim_set_contacts(s, &c, 1, NULL), FTM_OK);
    run_to_equilibrium(s, 1e-13, 400000);
    ASSERT_NEAR(ftm_sim_position(s, n1).x, 1.0 + u / 2, 1e-10);
    assert_true(ftm_sim_position(s, n2).x == 2.0 + u);
    ftm_vec3 r = ftm_sim_reaction(s, 0);
    ASSERT_NEAR(r.x, -k * u / 2, 1e-9 * k * u);
    ASSERT_NEAR(r.y, 0.0, 1e-12);

    /* Now also a force on node 1 in the same group: node 1 moves, the
     * reaction changes through the spring but has no -F term. */
    const double f = 0.6;
    ftm_contact cs[2] = {c, contact(n1, 0, FTM_CONTACT_FORCE, (ftm_vec3){f, 0.0, 0.0})};
    assert_int_equal(ftm_sim_set_contacts(s, cs, 2, NULL), FTM_OK);
    run_to_equilibrium(s, 1e-13, 400000);
    /* Node 1: k (x1 - 1) - k (2 + u - x1 - 1) = f  ->  x1 = 1 + (u + f/k)/2. */
    double x1 = 1.0 + (u + f / k) / 2.0;
    ASSERT_NEAR(ftm_sim_position(s, n1).x, x1, 1e-10);
    r = ftm_sim_reaction(s, 0);
    ASSERT_NEAR(r.x, -k * ((2.0 + u - x1) - 1.0), 1e-9 * k * u);
    ftm_sim_destroy(s);
    ftm_mesh_destroy(m);
}

/* Two probes on one lattice: each group's reaction comes from its own nodes. */
static void test_displacement_groups(void **state)
{
    (void)state;
    const int nx = 20, ny = 10;
    ftm_mesh *m = lattice2d(nx, ny, 1.0, 3.0, 20.0, FTM_FACE_YMIN);
    int32_t a = in2d(m, nx, 5, 8), b = in2d(m, nx, 15, 8);
    ftm_sim *s = make_sim(m, 0.02, 3, FTM_ORDER_LAYER_COLORED);
    ftm_contact cs[2] = {contact(a, 0, FTM_CONTACT_DISPLACEMENT, (ftm_vec3){0, -0.1, 0}),
                         contact(b, 1, FTM_CONTACT_DISPLACEMENT, (ftm_vec3){0, -0.2, 0})};
    assert_int_equal(ftm_sim_set_contacts(s, cs, 2, NULL), FTM_OK);
    run_to_equilibrium(s, 1e-13, 400000);
    ftm_vec3 ra = ftm_sim_reaction(s, 0), rb = ftm_sim_reaction(s, 1);
    /* Pressed down (-y): the lattice pushes back up. */
    assert_true(ra.y > 0.0);
    assert_true(rb.y > ra.y);
    /* Reference from the public neighbour list and positions (Eq. 19). */
    for (int g = 0; g < 2; g++) {
        int32_t node = g == 0 ? a : b;
        const int32_t *nb;
        const double *kk, *ll;
        int32_t deg = ftm_mesh_neighbors(m, node, &nb, &kk, &ll);
        ftm_vec3 xi = ftm_sim_position(s, node), want = {0, 0, 0};
        for (int32_t j = 0; j < deg; j++) {
            ftm_vec3 xj = ftm_sim_position(s, nb[j]);
            ftm_vec3 rr = {xi.x - xj.x, xi.y - xj.y, xi.z - xj.z};
            double len = sqrt(rr.x * rr.x + rr.y * rr.y + rr.z * rr.z);
            double t = kk[j] * (len - ll[j]) / len;
            want.x -= t * rr.x;
            want.y -= t * rr.y;
            want.z -= t * rr.z;
        }
        ftm_vec3 got = ftm_sim_reaction(s, g);
        ASSERT_NEAR(got.x, want.x, 1e-9);
        ASSERT_NEAR(got.y, want.y, 1e-9);
        ASSERT_NEAR(got.z, want.z, 1e-9);
    }
    ftm_sim_destroy(s);
    ftm_mesh_destroy(m);
}

/* ------------------------------------------------------- stability guard */

typedef struct log_count {
    int warn, other;
} log_count;

static void count_log(void *user, ftm_log_level level, const char *message)
{
    log_count *c = user;
    assert_non_null(message);
    if (level >= FTM_LOG_WARN)
        c->warn++;
    else
        c->other++;
}

/* 2D lattice with k = 100, m = 1: critical step 2/sqrt(1200) ~ 0.058 s. The
 * force is small enough that a stable step moves nodes far less than the
 * guard limit; at 8x the critical step the motion explodes within a step.
 * Damping 10 (damping ratio >= 0.17 in every mode): the layer-by-layer
 * (Gauss-Seidel) update of the paper is not energy-conserving and slowly
 * amplifies lightly damped modes at any time step (an undamped chain grows
 * by about 2.5% of omega per unit time), which no number of substeps can
 * cure; this test is about the time step, so it uses enough damping. */
static ftm_mesh *guard_mesh(void)
{
    return lattice2d(11, 11, 1.0, 10.0, 100.0, FTM_FACE_YMIN);
}

static ftm_sim *guard_sim_order(const ftm_mesh *m, double factor, bool guard,
                                int32_t max_substeps, log_count *lc, ftm_order order)
{
    ftm_sim_def def = ftm_default_sim_def();
    def.order = order;
    def.time_step = factor * ftm_mesh_critical_time_step(m);
    def.depth = 20;
    def.guard = guard;
    def.max_substeps = max_substeps;
    def.log = count_log;
    def.log_user = lc;
    ftm_sim *s = NULL;
    assert_int_equal(ftm_sim_create(m, &def, &s, NULL), FTM_OK);
    set1(s, in2d(m, 11, 5, 8), FTM_CONTACT_FORCE, (ftm_vec3){0.0, -0.01, 0.0});
    return s;
}

static ftm_sim *guard_sim(const ftm_mesh *m, double factor, bool guard, int32_t max_substeps,
                          log_count *lc)
{
    return guard_sim_order(m, factor, guard, max_substeps, lc, FTM_ORDER_LAYER_COLORED);
}

static void test_guard_substeps(void **state)
{
    (void)state;
    ftm_mesh *m = guard_mesh();
    log_count lc = {0, 0};
    ftm_sim *s = guard_sim(m, 8.0, true, 64, &lc);
    int ok = 0, unstable = 0;
    ftm_sim_stats st;
    for (int i = 0; i < 300; i++) {
        int rc = ftm_sim_step(s);
        ftm_sim_get_stats(s, &st);
        if (rc == FTM_OK) {
            ok++;
            if (st.guard_events > 0)
                assert_true(st.substeps > 1);
        } else {
            assert_int_equal(rc, FTM_EUNSTABLE);
            unstable++;
        }
        assert_true(st.substeps >= 1 && st.substeps <= 64);
        if (!all_finite(s))
            fail_msg("non-finite position after step %d", i);
    }
    print_message("guard: %d ok, %d unstable, %llu guard events, substeps %d, %d warnings\n", ok,
                  unstable, (unsigned long long)st.guard_events, (int)st.substeps, lc.warn);
    /* h/8 is below the critical step, so the guard can always recover. */
    assert_int_equal(unstable, 0);
    assert_true(st.guard_events > 0);
    assert_true(st.substeps > 1);
    assert_true(lc.warn > 0); /* time step above critical is logged */
    /* The result is the same static equilibrium as with a stable step. */
    size_t n3 = (size_t)ftm_mesh_node_count(m) * 3;
    run_to_equilibrium(s, 1e-14, 100000);
    log_count lc2 = {0, 0};
    ftm_sim *ref = guard_sim(m, 0.5, true, 64, &lc2);
    run_to_equilibrium(ref, 1e-14, 100000);
    ftm_sim_get_stats(ref, &st);
    assert_true(st.guard_events == 0);
    assert_int_equal(lc2.warn, 0);
    double *rest = rest_positions(m);
    double disp = max_abs_diff(ftm_sim_positions(ref), rest, n3);
    assert_true(disp > 1e-5);
    ASSERT_NEAR(max_abs_diff(ftm_sim_positions(s), ftm_sim_positions(ref), n3), 0.0, 1e-6 * disp);
    free(rest);
    ftm_sim_destroy(ref);
    ftm_sim_destroy(s);
    ftm_mesh_destroy(m);
}

static void test_guard_off_blows_up(void **state)
{
    (void)state;
    ftm_mesh *m = guard_mesh();
    log_count lc = {0, 0};
    ftm_sim *s = guard_sim(m, 8.0, false, 64, &lc);
    double *rest = rest_positions(m);
    size_t n3 = (size_t)ftm_mesh_node_count(m) * 3;
    bool blew_up = false;
    for (int i = 0; i < 300 && !blew_up; i++) {
        (void)ftm_sim_step(s);
        /* Stop long before overflow: 1e6 spacings is divergence enough. */
        blew_up = !all_finite(s) || max_abs_diff(ftm_sim_positions(s), rest, n3) > 1e6;
    }
    assert_true(blew_up);
    ftm_sim_stats st;
    ftm_sim_get_stats(s, &st);
    assert_true(st.guard_events == 0);
    free(rest);
    ftm_sim_destroy(s);
    ftm_mesh_destroy(m);
}

/* A step that fails leaves the state exactly as before the call, in every
 * order (each keeps its own rollback copy of the previous positions it
 * overwrote). max_substeps = 1: the guard cannot substep. max_substeps = 8:
 * it raises the substeps three times first, which rescales every moving
 * node's previous position and the substep length; a failure gives those
 * back too (found by tests/fuzz/fuzz_scene: the hash differed). */
static void unstable_step_leaves_state(ftm_order order, int32_t max_substeps)
{
    ftm_mesh *m = guard_mesh();
    log_count lc = {0, 0};
    ftm_sim *s = guard_sim_order(m, 50.0, true, max_substeps, &lc, order);
    size_t n3 = (size_t)ftm_mesh_node_count(m) * 3;
    if (max_substeps > 1) { /* in motion, so that raising the substeps rescales x_prev */
        int32_t n = ftm_mesh_node_count(m), count = 0;
        int32_t *nodes = malloc((size_t)n * sizeof *nodes);
        double *x = malloc(n3 * sizeof *x), *xp = malloc(n3 * sizeof *xp);
        assert_true(nodes && x && xp);
        for (int32_t i = 0; i < n; i++) {
            if (ftm_mesh_fixed(m, i))
                continue;
            ftm_vec3 r = ftm_mesh_rest_position(m, i);
            double *xi = x + 3 * count, *pi = xp + 3 * count;
            xi[0] = pi[0] = r.x;
            xi[1] = r.y;
            pi[1] = r.y + 1e-3 * (double)(i % 7);
            xi[2] = pi[2] = r.z;
            nodes[count++] = i;
        }
        const ftm_contact *c = NULL;
        int32_t nc = ftm_sim_contacts(s, &c);
        ftm_error err = {0, ""};
        if (ftm_sim_load_state(s, 0, 20, nodes, x, xp, count, c, nc, NULL, &err))
            fail_msg("%s", err.message);
        free(nodes);
        free(x);
        free(xp);
    }
    int failures = 0;
    for (int i = 0; i < 20; i++) {
        double *before = copy_positions(s);
        double *prev = malloc(n3 * sizeof *prev);
        assert_non_null(prev);
        memcpy(prev, ftm_sim_previous_positions(s), n3 * sizeof *prev);
        uint64_t h = ftm_sim_hash(s);
        ftm_sim_stats st0, st1;
        ftm_sim_get_stats(s, &st0);
        int rc = ftm_sim_step(s);
        ftm_sim_get_stats(s, &st1);
        assert_true(all_finite(s));
        if (rc == FTM_EUNSTABLE) {
            failures++;
            assert_memory_equal(ftm_sim_positions(s), before, n3 * sizeof(double));
            assert_memory_equal(ftm_sim_previous_positions(s), prev, n3 * sizeof(double));
            assert_true(ftm_sim_hash(s) == h);
            assert_true(st1.unstable_steps == st0.unstable_steps + 1);
            assert_int_equal(st1.substeps, st0.substeps);
        } else {
            assert_int_equal(rc, FTM_OK);
        }
        free(before);
        free(prev);
    }
    assert_true(failures > 0);
    ftm_sim_destroy(s);
    ftm_mesh_destroy(m);
}

static void test_unstable_step_leaves_state(void **state)
{
    (void)state;
    for (int32_t max_substeps = 1; max_substeps <= 8; max_substeps *= 8) {
        unstable_step_leaves_state(FTM_ORDER_LAYER_COLORED, max_substeps);
        unstable_step_leaves_state(FTM_ORDER_BFS, max_substeps);
        unstable_step_leaves_state(FTM_ORDER_LAYER_JACOBI, max_substeps);
    }
}

/* Slow growth (docs/stability.md): light damping below the critical step.
 * The layer-by-layer update feeds energy into smooth modes faster than the
 * damping removes it; no single step moves a node far, so the motion check
 * alone does not fire until the lattice is far from rest. The energy check
 * sees it while the displacement is still a fraction of the spacing, rolls
 * back and substeps; the run then settles at the static solution. */
static ftm_sim *slow_sim(const ftm_mesh *m, bool guard, log_count *lc)
{
    ftm_sim_def def = ftm_default_sim_def();
    def.time_step = 0.6 * ftm_mesh_critical_time_step(m);
    def.depth = 20;
    def.guard = guard;
    def.log = count_log;
    def.log_user = lc;
    ftm_sim *s = NULL;
    assert_int_equal(ftm_sim_create(m, &def, &s, NULL), FTM_OK);
    set1(s, in2d(m, 11, 5, 8), FTM_CONTACT_FORCE, (ftm_vec3){0.6, -2.0, 0.0});
    return s;
}

static void test_guard_energy_slow_growth(void **state)
{
    (void)state;
    ftm_mesh *m = lattice2d(11, 11, 1.0, 4.0, 100.0, FTM_FACE_YMIN);
    double *rest = rest_positions(m);
    size_t n3 = (size_t)ftm_mesh_node_count(m) * 3;
    const int steps = 6000;
    /* guard off: grows past one spacing (the static displacement is ~0.03) */
    log_count lc = {0, 0};
    ftm_sim *s = slow_sim(m, false, &lc);
    int blown_at = -1;
    for (int i = 0; i < steps && blown_at < 0; i++) {
        (void)ftm_sim_step(s);
        if (!all_finite(s) || max_abs_diff(ftm_sim_positions(s), rest, n3) > 1.0)
            blown_at = i;
    }
    assert_true(blown_at > 50); /* slow: many steps */
    ftm_sim_destroy(s);
    /* guard on: caught while small, recovered, never above a third of a spacing */
    s = slow_sim(m, true, &lc);
    double worst = 0.0;
    ftm_sim_stats st;
    for (int i = 0; i < steps; i++) {
        assert_int_equal(ftm_sim_step(s), FTM_OK);
        assert_true(all_finite(s));
        worst = fmax(worst, max_abs_diff(ftm_sim_positions(s), rest, n3));
    }
    ftm_sim_get_stats(s, &st);
    print_message("slow growth: unguarded past 1 spacing at step %d; guarded: %llu events, "
                  "substeps %d, largest displacement %.3g\n",
                  blown_at, (unsigned long long)st.guard_events, (int)st.substeps, worst);
    assert_true(st.guard_events > 0);
    assert_true(worst < 0.33);
    ftm_sim_destroy(s);
    free(rest);
    ftm_mesh_destroy(m);
}

/* No false alarm from the energy check in a stable scene whose loads do work
 * in every direction: a force switched on and off, a probe pressing in and
 * pulling out and sliding to the next node, a release, and a keyframe
 * loaded in the middle (the guard's account restarts there). */
static void test_guard_energy_quiet_when_stable(void **state)
{
    (void)state;
    ftm_mesh *m = guard_mesh();
    log_count lc = {0, 0};
    ftm_sim_def def = ftm_default_sim_def();
    def.time_step = 0.5 * ftm_mesh_critical_time_step(m);
    def.depth = 20;
    def.log = count_log;
    def.log_user = &lc;
    ftm_sim *s = NULL;
    assert_int_equal(ftm_sim_create(m, &def, &s, NULL), FTM_OK);
    for (int phase = 0; phase < 40; phase++) {
        int ix = 3 + phase % 5;
        double depth = 0.3 * sin(0.7 * phase);
        if (phase % 4 == 3)
            set1(s, in2d(m, 11, ix, 7), FTM_CONTACT_FORCE, (ftm_vec3){0.0, 5.0 * depth, 0.0});
        else if (phase % 7 == 6)
            assert_int_equal(ftm_sim_set_contacts(s, NULL, 0, NULL), FTM_OK);
        else
            set1(s, in2d(m, 11, ix, 7), FTM_CONTACT_DISPLACEMENT, (ftm_vec3){0.1, depth, 0.0});
        for (int i = 0; i < 60; i++) {
            assert_int_equal(ftm_sim_step(s), FTM_OK);
            assert_true(all_finite(s));
        }
        if (phase == 20) { /* keyframe round trip into the same sim */
            int32_t n = ftm_mesh_node_count(m), *nodes = malloc((size_t)n * sizeof *nodes);
            double *x = malloc((size_t)n * 3 * sizeof *x), *xp = malloc((size_t)n * 3 * sizeof *xp);
            int32_t count = 0;
            for (int32_t i = 0; i < n; i++) {
                if (ftm_mesh_fixed(m, i))
                    continue;
                nodes[count] = i;
                memcpy(x + 3 * count, ftm_sim_positions(s) + 3 * i, 3 * sizeof *x);
                memcpy(xp + 3 * count, ftm_sim_previous_positions(s) + 3 * i, 3 * sizeof *xp);
                count++;
            }
            ftm_sim_stats st;
            ftm_sim_get_stats(s, &st);
            ftm_sim_mode mode;
            ftm_sim_get_mode(s, &mode);
            ftm_contact ct = {.node = in2d(m, 11, ix, 7), .group = 0,
                              .kind = FTM_CONTACT_DISPLACEMENT, .value = {0.1, depth, 0.0}};
            assert_int_equal(ftm_sim_load_state(s, st.step, def.depth, nodes, x, xp, count, &ct,
                                                phase % 4 == 3 || phase % 7 == 6 ? 0 : 1, &mode,
                                                NULL),
                             FTM_OK);
            free(nodes);
            free(x);
            free(xp);
        }
    }
    ftm_sim_stats st;
    ftm_sim_get_stats(s, &st);
    assert_true(st.guard_events == 0);
    assert_int_equal(lc.warn, 0);
    ftm_sim_destroy(s);
    ftm_mesh_destroy(m);
}

/* No false alarm when a displaced node's links are seen by no free node: a
 * probe pressing the centre of a small lattice whose every other node is
 * fixed, and a probe at depth 0, where the region is the probe's node alone;
 * each pushed in, held, drawn back (negative work) and released. Their
 * links' energy was once outside the account, so the release looked like
 * energy from nothing and the step "diverged" at every substep count. */
static void test_guard_energy_held_node_released(void **state)
{
    (void)state;
    ftm_mesh *walled = lattice3d(3, FTM_STENCIL_6, 0.001, 0.3, 50.0, (ftm_vec3){1, 1, 1}, 0x3F);
    ftm_mesh *open = lattice3d(4, FTM_STENCIL_6, 0.001, 0.3, 50.0, (ftm_vec3){1, 1, 1},
                               FTM_FACE_ZMIN);
    const struct {
        const ftm_mesh *m;
        int32_t node, depth;
    } cases[] = {{walled, in3d(walled, 3, 1, 1, 1), 20}, {open, in3d(open, 4, 1, 2, 3), 0}};
    assert_true(ftm_mesh_fixed(walled, in3d(walled, 3, 0, 1, 1)));
    for (size_t c = 0; c < sizeof cases / sizeof cases[0]; c++) {
        for (int o = 0; o < 3; o++) {
            const ftm_order order[] = {FTM_ORDER_LAYER_COLORED, FTM_ORDER_BFS,
                                       FTM_ORDER_LAYER_JACOBI};
            log_count lc = {0, 0};
            ftm_sim_def def = ftm_default_sim_def();
            def.time_step = 0.5 * ftm_mesh_critical_time_step(cases[c].m);
            def.depth = cases[c].depth;
            def.order = order[o];
            def.log = count_log;
            def.log_user = &lc;
            ftm_sim *s = NULL;
            assert_int_equal(ftm_sim_create(cases[c].m, &def, &s, NULL), FTM_OK);
            for (int i = 0; i < 600; i++) {
                /* in over 100 steps, held 100, out over 100, released */
                double a = i < 100 ? i / 100.0 : i < 200 ? 1.0 : i < 300 ? (300 - i) / 100.0 : 0;
                if (i < 300)
                    set1(s, cases[c].node, FTM_CONTACT_DISPLACEMENT, (ftm_vec3){0, 0, -0.1 * a});
                else if (i == 300)
                    assert_int_equal(ftm_sim_set_contacts(s, NULL, 0, NULL), FTM_OK);
                assert_int_equal(ftm_sim_step(s), FTM_OK);
                assert_true(all_finite(s));
            }
            ftm_sim_stats st;
            ftm_sim_get_stats(s, &st);
            assert_true(st.guard_events == 0);
            assert_int_equal(lc.warn, 0);
            ftm_sim_destroy(s);
        }
    }
    ftm_mesh_destroy(walled);
    ftm_mesh_destroy(open);
}

/* ------------------------------------------------ contact validation */

static void test_set_contacts_validation(void **state)
{
    (void)state;
    const int nx = 12, ny = 12;
    ftm_mesh *m = lattice2d(nx, ny, 1.0, 3.0, 20.0, FTM_FACE_YMIN);
    int32_t n = ftm_mesh_node_count(m);
    int32_t good = in2d(m, nx, 6, 6), other = in2d(m, nx, 3, 9), fixed = in2d(m, nx, 4, 0);
    assert_true(ftm_mesh_fixed(m, fixed));
    ftm_sim *s = make_sim(m, 0.02, 3, FTM_ORDER_LAYER_COLORED);
    ftm_sim *twin = make_sim(m, 0.02, 3, FTM_ORDER_LAYER_COLORED);
    ftm_contact ok = contact(good, 0, FTM_CONTACT_FORCE, (ftm_vec3){0.5, 0.2, 0.0});
    assert_int_equal(ftm_sim_set_contacts(s, &ok, 1, NULL), FTM_OK);
    assert_int_equal(ftm_sim_set_contacts(twin, &ok, 1, NULL), FTM_OK);
    assert_int_equal(ftm_sim_run(s, 20), FTM_OK);
    assert_int_equal(ftm_sim_run(twin, 20), FTM_OK);

    ftm_contact bad[][2] = {
        {contact(-1, 0, FTM_CONTACT_FORCE, (ftm_vec3){1, 0, 0}), ok},
        {contact(n, 0, FTM_CONTACT_FORCE, (ftm_vec3){1, 0, 0}), ok},
        {contact(fixed, 0, FTM_CONTACT_FORCE, (ftm_vec3){1, 0, 0}), ok},
        {contact(other, 0, FTM_CONTACT_FORCE, (ftm_vec3){NAN, 0, 0}), ok},
        {contact(other, 0, FTM_CONTACT_DISPLACEMENT, (ftm_vec3){0, INFINITY, 0}), ok},
        {contact(other, 0, FTM_CONTACT_FORCE, (ftm_vec3){0, 0, -INFINITY}), ok},
        {contact(good, 1, FTM_CONTACT_FORCE, (ftm_vec3){1, 0, 0}), ok}, /* listed twice */
        {contact(other, 0, FTM_CONTACT_FORCE, (ftm_vec3){1, 0, 0}),     /* bad 2nd entry */
         contact(n + 5, 0, FTM_CONTACT_FORCE, (ftm_vec3){1, 0, 0})},
        {contact(other, 0, FTM_CONTACT_FORCE, (ftm_vec3){1, 0, 0}),
         contact(fixed, 0, FTM_CONTACT_DISPLACEMENT, (ftm_vec3){0, 0, 0})},
    };
    for (size_t t = 0; t < sizeof bad / sizeof bad[0]; t++) {
        const int32_t *order, *start;
        int32_t lc0 = ftm_sim_layers(s, &order, &start);
        int32_t region0 = start[lc0];
        int32_t *order0 = malloc(sizeof *order0 * (size_t)region0);
        memcpy(order0, order, sizeof *order0 * (size_t)region0);
        ftm_sim_stats st0, st1;
        ftm_sim_get_stats(s, &st0);
        uint64_t h0 = ftm_sim_hash(s);

        ftm_error err;
        memset(&err, 0, sizeof err);
        int rc = ftm_sim_set_contacts(s, bad[t], 2, &err);
        if (rc >= 0)
            fail_msg("bad contact set %zu accepted", t);
        assert_int_equal(err.code, rc);
        assert_true(strlen(err.message) > 0);
        ftm_sim_get_stats(s, &st1);
        assert_true(st0.step == st1.step && st0.searches == st1.searches);
        assert_int_equal(st0.region_nodes, st1.region_nodes);
        assert_int_equal(st0.layers, st1.layers);
        assert_int_equal(st0.relaxing_nodes, st1.relaxing_nodes);
        assert_int_equal(st0.depth, st1.depth);
        assert_true(ftm_sim_hash(s) == h0);
        int32_t lc1 = ftm_sim_layers(s, &order, &start);
        assert_int_equal(lc1, lc0);
        assert_int_equal(start[lc1], region0);
        assert_memory_equal(order, order0, sizeof *order0 * (size_t)region0);
        free(order0);
        /* The old contact keeps acting exactly as in the twin. */
        assert_int_equal(ftm_sim_run(s, 5), FTM_OK);
        assert_int_equal(ftm_sim_run(twin, 5), FTM_OK);
        assert_true(ftm_sim_hash(s) == ftm_sim_hash(twin));
    }
    /* Negative count, NULL array with a count. */
    assert_true(ftm_sim_set_contacts(s, NULL, 1, NULL) < 0);
    assert_true(ftm_sim_set_contacts(s, &ok, -1, NULL) < 0);
    assert_int_equal(ftm_sim_run(s, 5), FTM_OK);
    assert_int_equal(ftm_sim_run(twin, 5), FTM_OK);
    assert_true(ftm_sim_hash(s) == ftm_sim_hash(twin));
    ftm_sim_destroy(s);
    ftm_sim_destroy(twin);
    ftm_mesh_destroy(m);
}

int main(void)
{
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(test_default_sim_def),
        cmocka_unit_test(test_sim_create_validation),
        cmocka_unit_test(test_fresh_sim_is_at_rest),
        cmocka_unit_test(test_single_spring_along),
        cmocka_unit_test(test_single_spring_along_stays_on_axis),
        cmocka_unit_test(test_single_spring_oblique),
        cmocka_unit_test(test_two_springs_perpendicular),
        cmocka_unit_test(test_chain_extension),
        cmocka_unit_test(test_nodes_beyond_depth_never_move),
        cmocka_unit_test(test_determinism),
        cmocka_unit_test(test_intra_layer_order_2d),
        cmocka_unit_test(test_intra_layer_order_3d),
        cmocka_unit_test(test_anisotropy_isotropic_symmetry),
        cmocka_unit_test(test_anisotropy_soft_and_stiff),
        cmocka_unit_test(test_release_relax_sleep),
        cmocka_unit_test(test_moving_contact_relaxes_old_region),
        cmocka_unit_test(test_region_sleep),
        cmocka_unit_test(test_reset),
        cmocka_unit_test(test_displacement_single_spring),
        cmocka_unit_test(test_displacement_chain_equilibrium),
        cmocka_unit_test(test_displacement_groups),
        cmocka_unit_test(test_guard_substeps),
        cmocka_unit_test(test_guard_off_blows_up),
        cmocka_unit_test(test_guard_energy_slow_growth),
        cmocka_unit_test(test_guard_energy_quiet_when_stable),
        cmocka_unit_test(test_guard_energy_held_node_released),
        cmocka_unit_test(test_unstable_step_leaves_state),
        cmocka_unit_test(test_set_contacts_validation),
    };
    return cmocka_run_group_tests(tests, NULL, NULL);
}
