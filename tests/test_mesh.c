/* SPDX-License-Identifier: GPL-3.0-or-later */
/* Tests of the mesh builder, the node reordering, the lattice generators, the
 * critical time step and the surface extraction, against the contracts in
 * common/include/ftm/mesh.h and generate.h. */
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

/* cmocka 1.1.5's assert_float_equal works in float; this one is double. */
#define ASSERT_NEAR(a, b, tol)                                                            \
    do {                                                                                  \
        double a_ = (a), b_ = (b), t_ = (tol);                                            \
        if (!(fabs(a_ - b_) <= t_))                                                       \
            fail_msg("%s = %.17g, %s = %.17g, |diff| = %.3g > %.3g", #a, a_, #b, b_,      \
                     fabs(a_ - b_), t_);                                                  \
    } while (0)

#define ASSERT_REL(a, b, rel) ASSERT_NEAR((a), (b), (rel) * fabs(b))

/* ------------------------------------------------------------------ helpers */

static ftm_node_def node_at(double x, double y, double z)
{
    ftm_node_def d = ftm_default_node_def();
    d.position = (ftm_vec3){x, y, z};
    return d;
}

static ftm_link_def link_of(int32_t a, int32_t b, double k)
{
    ftm_link_def l = ftm_default_link_def();
    l.a = a;
    l.b = b;
    l.stiffness = k;
    l.rest_length = -1.0;
    return l;
}

static ftm_mesh *build(const ftm_mesh_builder *b, bool reorder)
{
    ftm_mesh_build_def def = ftm_default_mesh_build_def();
    def.reorder = reorder;
    ftm_mesh *m = NULL;
    ftm_error err;
    memset(&err, 0, sizeof err);
    int rc = ftm_mesh_build(b, &def, &m, &err);
    if (rc != FTM_OK)
        fail_msg("ftm_mesh_build failed: %d %s", rc, err.message);
    assert_non_null(m);
    return m;
}

static double dist(ftm_vec3 a, ftm_vec3 b)
{
    double dx = a.x - b.x, dy = a.y - b.y, dz = a.z - b.z;
    return sqrt(dx * dx + dy * dy + dz * dz);
}

/* Finds link (a, b) in a's neighbour list; returns its slot or -1. */
static int32_t find_neighbor(const ftm_mesh *m, int32_t a, int32_t b, double *k, double *len)
{
    const int32_t *nb;
    const double *nk, *nl;
    int32_t n = ftm_mesh_neighbors(m, a, &nb, &nk, &nl);
    for (int32_t j = 0; j < n; j++) {
        if (nb[j] == b) {
            if (k)
                *k = nk[j];
            if (len)
                *len = nl[j];
            return j;
        }
    }
    return -1;
}

/* Structural invariants every mesh must satisfy: neighbour lists symmetric
 * with equal stiffness and rest length, no self loops or duplicates, links
 * consistent with the neighbour lists, degree sum 2 * links, max degree. */
static void check_adjacency(const ftm_mesh *m)
{
    int32_t n = ftm_mesh_node_count(m);
    int64_t degree_sum = 0;
    int32_t max_deg = 0;
    for (int32_t i = 0; i < n; i++) {
        const int32_t *nb;
        const double *nk, *nl;
        int32_t deg = ftm_mesh_neighbors(m, i, &nb, &nk, &nl);
        assert_true(deg >= 0);
        degree_sum += deg;
        if (deg > max_deg)
            max_deg = deg;
        for (int32_t j = 0; j < deg; j++) {
            assert_true(nb[j] >= 0 && nb[j] < n);
            assert_int_not_equal(nb[j], i);
            for (int32_t q = j + 1; q < deg; q++)
                assert_int_not_equal(nb[j], nb[q]);
            double k2 = 0, l2 = 0;
            if (find_neighbor(m, nb[j], i, &k2, &l2) < 0)
                fail_msg("node %d lists %d as neighbour but not the reverse", (int)i, (int)nb[j]);
            /* Same link: bit-identical parameters. */
            assert_true(k2 == nk[j]);
            assert_true(l2 == nl[j]);
            assert_true(nk[j] > 0);
        }
    }
    assert_true(degree_sum == 2 * (int64_t)ftm_mesh_link_count(m));
    assert_int_equal(ftm_mesh_max_degree(m), max_deg);
    for (int32_t e = 0; e < ftm_mesh_link_count(m); e++) {
        int32_t a = -1, b = -1;
        double k = 0, l = 0, k2 = 0, l2 = 0;
        ftm_mesh_link(m, e, &a, &b, &k, &l);
        assert_true(a >= 0 && a < n && b >= 0 && b < n && a != b);
        assert_true(find_neighbor(m, a, b, &k2, &l2) >= 0);
        assert_true(k2 == k);
        assert_true(l2 == l);
    }
}

/* ------------------------------------------------------ builder validation */

static void test_builder_rejects_bad_nodes(void **state)
{
    (void)state;
    ftm_mesh_builder *b = ftm_mesh_builder_create();
    assert_non_null(b);
    assert_int_equal(ftm_mesh_builder_node_count(b), 0);

    ftm_node_def d = node_at(0, 0, 0);
    assert_true(d.mass > 0);
    assert_true(d.damping >= 0);
    assert_false(d.fixed);

    d.mass = 0.0;
    assert_true(ftm_mesh_builder_add_node(b, &d) < 0);
    d.mass = -1.0;
    assert_true(ftm_mesh_builder_add_node(b, &d) < 0);
    d.mass = NAN;
    assert_true(ftm_mesh_builder_add_node(b, &d) < 0);
    d.mass = INFINITY;
    assert_true(ftm_mesh_builder_add_node(b, &d) < 0);
    d.mass = 1.0;
    d.damping = -0.5;
    assert_true(ftm_mesh_builder_add_node(b, &d) < 0);
    d.damping = NAN;
    assert_true(ftm_mesh_builder_add_node(b, &d) < 0);
    d.damping = 0.0;
    d.position.y = NAN;
    assert_true(ftm_mesh_builder_add_node(b, &d) < 0);
    d.position.y = INFINITY;
    assert_true(ftm_mesh_builder_add_node(b, &d) < 0);
    /* Builder unchanged by all of the above. */
    assert_int_equal(ftm_mesh_builder_node_count(b), 0);

    /* Valid nodes get consecutive input indices; zero damping is allowed. */
    d.position.y = 0.0;
    assert_int_equal(ftm_mesh_builder_add_node(b, &d), 0);
    d.position.x = 1.0;
    assert_int_equal(ftm_mesh_builder_add_node(b, &d), 1);
    assert_int_equal(ftm_mesh_builder_node_count(b), 2);
    ftm_mesh_builder_destroy(b);
}

static void test_builder_rejects_bad_links(void **state)
{
    (void)state;
    ftm_mesh_builder *b = ftm_mesh_builder_create();
    for (int i = 0; i < 3; i++) {
        ftm_node_def d = node_at(i, 0, 0);
        assert_int_equal(ftm_mesh_builder_add_node(b, &d), i);
    }
    ftm_link_def l = link_of(0, 3, 1.0); /* node 3 does not exist */
    assert_true(ftm_mesh_builder_add_link(b, &l) < 0);
    l = link_of(-1, 0, 1.0);
    assert_true(ftm_mesh_builder_add_link(b, &l) < 0);
    l = link_of(1, 1, 1.0); /* self link */
    assert_true(ftm_mesh_builder_add_link(b, &l) < 0);
    l = link_of(0, 1, 0.0); /* zero stiffness */
    assert_true(ftm_mesh_builder_add_link(b, &l) < 0);
    l = link_of(0, 1, -2.0);
    assert_true(ftm_mesh_builder_add_link(b, &l) < 0);
    l = link_of(0, 1, NAN);
    assert_true(ftm_mesh_builder_add_link(b, &l) < 0);
    l = link_of(0, 1, INFINITY);
    assert_true(ftm_mesh_builder_add_link(b, &l) < 0);
    l = link_of(0, 1, 1.0);
    l.rest_length = NAN;
    assert_true(ftm_mesh_builder_add_link(b, &l) < 0);

    /* Valid links; the duplicate (either order) is not an error but is kept
     * once, and the first definition wins. (Reading: "kept once" means the
     * call succeeds; only bad input is rejected.) */
    l = link_of(0, 1, 5.0);
    assert_int_equal(ftm_mesh_builder_add_link(b, &l), FTM_OK);
    l = link_of(1, 0, 7.0);
    assert_true(ftm_mesh_builder_add_link(b, &l) >= 0);
    l = link_of(0, 1, 9.0);
    assert_true(ftm_mesh_builder_add_link(b, &l) >= 0);
    l = link_of(1, 2, 3.0);
    l.rest_length = 2.5; /* explicit natural length, not the distance 1 */
    assert_int_equal(ftm_mesh_builder_add_link(b, &l), FTM_OK);

    ftm_mesh *m = build(b, false);
    assert_int_equal(ftm_mesh_node_count(m), 3);
    assert_int_equal(ftm_mesh_link_count(m), 2);
    int32_t n0 = ftm_mesh_node_of_input(m, 0), n1 = ftm_mesh_node_of_input(m, 1),
            n2 = ftm_mesh_node_of_input(m, 2);
    double k = 0, len = 0;
    assert_true(find_neighbor(m, n0, n1, &k, &len) >= 0);
    assert_true(k == 5.0);
    ASSERT_NEAR(len, 1.0, 1e-15); /* rest_length < 0: the rest distance */
    assert_true(find_neighbor(m, n1, n2, &k, &len) >= 0);
    assert_true(k == 3.0);
    assert_true(len == 2.5);
    assert_true(find_neighbor(m, n0, n2, NULL, NULL) < 0);
    check_adjacency(m);
    ftm_mesh_destroy(m);
    ftm_mesh_builder_destroy(b);
}

static void test_builder_rejects_bad_triangles_and_tets(void **state)
{
    (void)state;
    ftm_mesh_builder *b = ftm_mesh_builder_create();
    for (int i = 0; i < 4; i++) {
        ftm_node_def d = node_at(i == 1, i == 2, i == 3);
        assert_int_equal(ftm_mesh_builder_add_node(b, &d), i);
    }
    assert_true(ftm_mesh_builder_add_triangle(b, 0, 0, 1) < 0);
    assert_true(ftm_mesh_builder_add_triangle(b, 0, 1, 1) < 0);
    assert_true(ftm_mesh_builder_add_triangle(b, 2, 1, 2) < 0);
    assert_true(ftm_mesh_builder_add_triangle(b, 0, 1, 4) < 0);
    assert_true(ftm_mesh_builder_add_triangle(b, -1, 1, 2) < 0);
    assert_true(ftm_mesh_builder_add_tetrahedron(b, 0, 1, 2, 2) < 0);
    assert_true(ftm_mesh_builder_add_tetrahedron(b, 3, 1, 2, 3) < 0);
    assert_true(ftm_mesh_builder_add_tetrahedron(b, 0, 1, 2, 4) < 0);
    assert_true(ftm_mesh_builder_add_tetrahedron(b, 0, -5, 2, 3) < 0);
    assert_int_equal(ftm_mesh_builder_add_triangle(b, 0, 1, 2), FTM_OK);

    /* Only the valid triangle made it in; no tetrahedra. */
    ftm_mesh *m = build(b, false);
    assert_int_equal(ftm_mesh_triangle_count(m), 1);
    assert_int_equal(ftm_mesh_tetrahedron_count(m), 0);
    const int32_t *t = ftm_mesh_triangles(m);
    int32_t in[3];
    for (int i = 0; i < 3; i++)
        in[i] = ftm_mesh_input_of_node(m, t[i]);
    /* The same three vertices (a rotation of (0,1,2) or any order). */
    assert_int_equal(in[0] + in[1] + in[2], 3);
    assert_true(in[0] != in[1] && in[1] != in[2] && in[0] != in[2]);
    ftm_mesh_destroy(m);
    ftm_mesh_builder_destroy(b);
}

static void test_build_empty_fails_with_message(void **state)
{
    (void)state;
    ftm_mesh_builder *b = ftm_mesh_builder_create();
    ftm_mesh_build_def def = ftm_default_mesh_build_def();
    assert_true(def.reorder);
    assert_true(def.surface_from_tetrahedra);
    ftm_mesh *sentinel = (ftm_mesh *)(uintptr_t)0x1234;
    ftm_mesh *m = sentinel;
    ftm_error err;
    memset(&err, 0, sizeof err);
    int rc = ftm_mesh_build(b, &def, &m, &err);
    assert_int_equal(rc, FTM_EINVAL);
    assert_int_equal(err.code, FTM_EINVAL);
    assert_true(strlen(err.message) > 0);
    assert_ptr_equal(m, sentinel); /* no output written on error */
    /* err may be NULL. */
    assert_int_equal(ftm_mesh_build(b, &def, &m, NULL), FTM_EINVAL);
    assert_ptr_equal(m, sentinel);
    ftm_mesh_builder_destroy(b);
}

static void test_builder_reusable_after_build(void **state)
{
    (void)state;
    ftm_mesh_builder *b = ftm_mesh_builder_create();
    ftm_node_def d = node_at(0, 0, 0);
    ftm_mesh_builder_add_node(b, &d);
    d.position.x = 2.0;
    ftm_mesh_builder_add_node(b, &d);
    ftm_link_def l = link_of(0, 1, 4.0);
    ftm_mesh_builder_add_link(b, &l);
    ftm_mesh *m1 = build(b, true);
    d.position.x = 3.0;
    assert_int_equal(ftm_mesh_builder_add_node(b, &d), 2);
    l = link_of(1, 2, 4.0);
    assert_int_equal(ftm_mesh_builder_add_link(b, &l), FTM_OK);
    ftm_mesh *m2 = build(b, true);
    /* The first mesh is independent of later builder changes. */
    assert_int_equal(ftm_mesh_node_count(m1), 2);
    assert_int_equal(ftm_mesh_link_count(m1), 1);
    ASSERT_NEAR(ftm_mesh_mean_link_length(m1), 2.0, 1e-15);
    assert_int_equal(ftm_mesh_node_count(m2), 3);
    assert_int_equal(ftm_mesh_link_count(m2), 2);
    ASSERT_NEAR(ftm_mesh_mean_link_length(m2), 1.5, 1e-15);
    ftm_mesh_builder_destroy(b);
    /* ...and of the builder's lifetime. */
    check_adjacency(m1);
    check_adjacency(m2);
    ftm_mesh_destroy(m1);
    ftm_mesh_destroy(m2);
}

/* ------------------------------------------------------------------ reorder */

/* A 2D grid with 4- and diagonal links, nodes added in a scrambled order, so
 * that the Cuthill-McKee renumbering is not the identity. Node attributes
 * (mass, damping, fixed) differ per node so that mix-ups show. */
static ftm_mesh_builder *scrambled_grid(int nx, int ny, int32_t **perm_out)
{
    int n = nx * ny;
    int32_t *perm = malloc(sizeof *perm * (size_t)n); /* grid cell -> input index */
    for (int i = 0; i < n; i++)
        perm[i] = i;
    uint32_t s = 12345u;
    for (int i = n - 1; i > 0; i--) {
        s = s * 1664525u + 1013904223u;
        int j = (int)((s >> 8) % (uint32_t)(i + 1));
        int32_t t = perm[i];
        perm[i] = perm[j];
        perm[j] = t;
    }
    int32_t *cell_of_input = malloc(sizeof *cell_of_input * (size_t)n);
    for (int c = 0; c < n; c++)
        cell_of_input[perm[c]] = c;
    ftm_mesh_builder *b = ftm_mesh_builder_create();
    for (int in = 0; in < n; in++) {
        int c = cell_of_input[in];
        ftm_node_def d = node_at(c % nx, c / nx, 0.25 * (c % 3));
        d.mass = 1.0 + in;
        d.damping = 0.5 * in;
        d.fixed = (in % 7) == 0;
        assert_int_equal(ftm_mesh_builder_add_node(b, &d), in);
    }
    for (int y = 0; y < ny; y++) {
        for (int x = 0; x < nx; x++) {
            int c = x + nx * y;
            ftm_link_def l;
            if (x + 1 < nx) {
                l = link_of(perm[c], perm[c + 1], 10.0 + c);
                assert_int_equal(ftm_mesh_builder_add_link(b, &l), FTM_OK);
            }
            if (y + 1 < ny) {
                l = link_of(perm[c + nx], perm[c], 20.0 + c);
                assert_int_equal(ftm_mesh_builder_add_link(b, &l), FTM_OK);
            }
            if (x + 1 < nx && y + 1 < ny) {
                l = link_of(perm[c], perm[c + nx + 1], 30.0 + c);
                assert_int_equal(ftm_mesh_builder_add_link(b, &l), FTM_OK);
            }
        }
    }
    free(cell_of_input);
    *perm_out = perm;
    return b;
}

static void check_renumbering(const ftm_mesh_builder *b, bool reorder, int nx, int ny,
                              const int32_t *perm)
{
    ftm_mesh *m = build(b, reorder);
    int32_t n = ftm_mesh_node_count(m);
    assert_int_equal(n, nx * ny);
    assert_int_equal(ftm_mesh_link_count(m), (nx - 1) * ny + nx * (ny - 1) + (nx - 1) * (ny - 1));
    char *seen = calloc((size_t)n, 1);
    for (int32_t in = 0; in < n; in++) {
        int32_t node = ftm_mesh_node_of_input(m, in);
        assert_true(node >= 0 && node < n);
        assert_false(seen[node]);
        seen[node] = 1;
        assert_int_equal(ftm_mesh_input_of_node(m, node), in);
        if (!reorder)
            assert_int_equal(node, in);
    }
    for (int32_t node = 0; node < n; node++)
        assert_int_equal(ftm_mesh_node_of_input(m, ftm_mesh_input_of_node(m, node)), node);
    free(seen);

    /* Attributes follow the renumbering. */
    for (int c = 0; c < n; c++) {
        int32_t in = perm[c];
        int32_t node = ftm_mesh_node_of_input(m, in);
        ftm_vec3 p = ftm_mesh_rest_position(m, node);
        assert_true(p.x == (double)(c % nx));
        assert_true(p.y == (double)(c / nx));
        assert_true(p.z == 0.25 * (c % 3));
        assert_true(ftm_mesh_mass(m, node) == 1.0 + in);
        assert_true(ftm_mesh_damping(m, node) == 0.5 * in);
        assert_true(ftm_mesh_fixed(m, node) == ((in % 7) == 0));
    }
    /* Links follow the renumbering, with their parameters. */
    for (int c = 0; c < n; c++) {
        int x = c % nx, y = c / nx;
        int32_t a = ftm_mesh_node_of_input(m, perm[c]);
        double k, len;
        if (x + 1 < nx) {
            int32_t o = ftm_mesh_node_of_input(m, perm[c + 1]);
            assert_true(find_neighbor(m, a, o, &k, &len) >= 0);
            assert_true(k == 10.0 + c);
            ASSERT_NEAR(len, dist(ftm_mesh_rest_position(m, a), ftm_mesh_rest_position(m, o)),
                        1e-15);
        }
        if (y + 1 < ny) {
            int32_t o = ftm_mesh_node_of_input(m, perm[c + nx]);
            assert_true(find_neighbor(m, a, o, &k, &len) >= 0);
            assert_true(k == 20.0 + c);
        }
        if (x + 1 < nx && y + 1 < ny) {
            int32_t o = ftm_mesh_node_of_input(m, perm[c + nx + 1]);
            assert_true(find_neighbor(m, a, o, &k, &len) >= 0);
            assert_true(k == 30.0 + c);
        }
        if (x > 0 && y + 1 < ny) { /* the other diagonal is not a link */
            int32_t o = ftm_mesh_node_of_input(m, perm[c + nx - 1]);
            assert_true(find_neighbor(m, a, o, NULL, NULL) < 0);
        }
    }
    check_adjacency(m);
    ftm_mesh_destroy(m);
}

static void test_reorder_is_a_consistent_permutation(void **state)
{
    (void)state;
    int32_t *perm;
    ftm_mesh_builder *b = scrambled_grid(9, 7, &perm);
    check_renumbering(b, true, 9, 7, perm);
    check_renumbering(b, false, 9, 7, perm);
    free(perm);
    ftm_mesh_builder_destroy(b);
}

/* A path graph added in random order: any Cuthill-McKee (BFS) numbering of a
 * path has bandwidth <= 2 (1 from an end, 2 from an interior start), while
 * the scrambled input order has a large one. */
static void test_reorder_reduces_bandwidth_of_a_path(void **state)
{
    (void)state;
    enum { N = 200 };
    int32_t perm[N];
    for (int i = 0; i < N; i++)
        perm[i] = i;
    uint32_t s = 777u;
    for (int i = N - 1; i > 0; i--) {
        s = s * 1664525u + 1013904223u;
        int j = (int)((s >> 8) % (uint32_t)(i + 1));
        int32_t t = perm[i];
        perm[i] = perm[j];
        perm[j] = t;
    }
    int32_t pos_of_input[N];
    for (int p = 0; p < N; p++)
        pos_of_input[perm[p]] = p;
    ftm_mesh_builder *b = ftm_mesh_builder_create();
    for (int in = 0; in < N; in++) {
        ftm_node_def d = node_at(pos_of_input[in], 0, 0);
        ftm_mesh_builder_add_node(b, &d);
    }
    int input_bandwidth = 0;
    for (int p = 0; p + 1 < N; p++) {
        ftm_link_def l = link_of(perm[p], perm[p + 1], 1.0);
        assert_int_equal(ftm_mesh_builder_add_link(b, &l), FTM_OK);
        int bw = abs(perm[p] - perm[p + 1]);
        if (bw > input_bandwidth)
            input_bandwidth = bw;
    }
    assert_true(input_bandwidth > 10);
    ftm_mesh *m = build(b, true);
    int bandwidth = 0;
    for (int32_t e = 0; e < ftm_mesh_link_count(m); e++) {
        int32_t a, c;
        double k, l;
        ftm_mesh_link(m, e, &a, &c, &k, &l);
        if (abs(a - c) > bandwidth)
            bandwidth = abs(a - c);
    }
    assert_true(bandwidth <= 2);
    ftm_mesh_destroy(m);
    ftm_mesh_builder_destroy(b);
}

/* --------------------------------------------------------------- generators */

static ftm_mesh *make_lattice2d(const ftm_lattice2d_def *def)
{
    ftm_mesh_builder *b = ftm_mesh_builder_create();
    ftm_error err;
    memset(&err, 0, sizeof err);
    int rc = ftm_generate_lattice2d(b, def, &err);
    if (rc != FTM_OK)
        fail_msg("ftm_generate_lattice2d: %d %s", rc, err.message);
    ftm_mesh *m = build(b, true);
    ftm_mesh_builder_destroy(b);
    return m;
}

static ftm_mesh *make_lattice3d(const ftm_lattice3d_def *def)
{
    ftm_mesh_builder *b = ftm_mesh_builder_create();
    ftm_error err;
    memset(&err, 0, sizeof err);
    int rc = ftm_generate_lattice3d(b, def, &err);
    if (rc != FTM_OK)
        fail_msg("ftm_generate_lattice3d: %d %s", rc, err.message);
    ftm_mesh *m = build(b, true);
    ftm_mesh_builder_destroy(b);
    return m;
}

static void test_default_generator_defs(void **state)
{
    (void)state;
    ftm_material_def mat = ftm_default_material_def();
    assert_true(mat.axis_scale.x == 1.0 && mat.axis_scale.y == 1.0 && mat.axis_scale.z == 1.0);
    assert_true(mat.node_mass > 0 && mat.stiffness > 0 && mat.node_damping >= 0);
    ftm_lattice3d_def d3 = ftm_default_lattice3d_def();
    for (int c = 0; c < 3; c++)
        assert_true(d3.class_scale[c] == 1.0);
    assert_true(d3.nx >= 2 && d3.ny >= 2 && d3.nz >= 2);
    assert_true(d3.spacing.x > 0 && d3.spacing.y > 0 && d3.spacing.z > 0);
    ftm_lattice2d_def d2 = ftm_default_lattice2d_def();
    assert_true(d2.nx >= 2 && d2.ny >= 2 && d2.spacing > 0);
}

static void test_lattice2d_topology(void **state)
{
    (void)state;
    ftm_lattice2d_def def = ftm_default_lattice2d_def();
    def.nx = 12;
    def.ny = 9;
    def.spacing = 0.25;
    def.material.node_mass = 0.3;
    def.material.node_damping = 0.7;
    def.material.stiffness = 40.0;
    def.fixed_faces = 0;
    ftm_mesh *m = make_lattice2d(&def);
    assert_int_equal(ftm_mesh_node_count(m), 12 * 9);
    /* Fig. 3 topology: rows of nx-1 links, and 2nx-1 links between two rows. */
    assert_int_equal(ftm_mesh_link_count(m), 9 * 11 + 8 * 23);
    assert_int_equal(ftm_mesh_max_degree(m), 6);
    ASSERT_NEAR(ftm_mesh_mean_link_length(m), 0.25, 1e-14);
    check_adjacency(m);
    for (int iy = 0; iy < def.ny; iy++) {
        for (int ix = 0; ix < def.nx; ix++) {
            int32_t node = ftm_mesh_node_of_input(m, ix + def.nx * iy);
            ftm_vec3 p = ftm_mesh_rest_position(m, node);
            assert_true(p.z == 0.0);
            assert_true(ftm_mesh_mass(m, node) == 0.3);
            assert_true(ftm_mesh_damping(m, node) == 0.7);
            assert_false(ftm_mesh_fixed(m, node));
            const int32_t *nb;
            const double *nk, *nl;
            int32_t deg = ftm_mesh_neighbors(m, node, &nb, &nk, &nl);
            bool interior = ix > 0 && ix < def.nx - 1 && iy > 0 && iy < def.ny - 1;
            if (interior)
                assert_int_equal(deg, 6);
            else
                assert_true(deg >= 2 && deg <= 5);
            for (int32_t j = 0; j < deg; j++) {
                ftm_vec3 q = ftm_mesh_rest_position(m, nb[j]);
                ASSERT_NEAR(dist(p, q), 0.25, 1e-14);
                ASSERT_NEAR(nl[j], 0.25, 1e-14);
                ASSERT_REL(nk[j], 40.0, 1e-12);
                /* Neighbours are in the same row or an adjacent one. */
                int32_t qin = ftm_mesh_input_of_node(m, nb[j]);
                int qy = qin / def.nx;
                assert_true(abs(qy - iy) <= 1);
                if (qy == iy)
                    ASSERT_NEAR(fabs(q.y - p.y), 0.0, 1e-15);
                else
                    ASSERT_NEAR(fabs(q.y - p.y), 0.25 * sqrt(3.0) / 2.0, 1e-14);
            }
        }
    }
    ftm_mesh_destroy(m);
}

static void test_lattice2d_fixed_faces_and_anisotropy(void **state)
{
    (void)state;
    ftm_lattice2d_def def = ftm_default_lattice2d_def();
    def.nx = 7;
    def.ny = 6;
    def.spacing = 1.0;
    def.material.stiffness = 10.0;
    def.material.axis_scale = (ftm_vec3){0.5, 3.0, 1.0};
    def.fixed_faces = FTM_FACE_XMIN | FTM_FACE_YMAX;
    ftm_mesh *m = make_lattice2d(&def);
    for (int iy = 0; iy < def.ny; iy++) {
        for (int ix = 0; ix < def.nx; ix++) {
            int32_t node = ftm_mesh_node_of_input(m, ix + def.nx * iy);
            bool want = ix == 0 || iy == def.ny - 1;
            if (ftm_mesh_fixed(m, node) != want)
                fail_msg("lattice2d node (%d,%d): fixed %d, expected %d", ix, iy,
                         (int)ftm_mesh_fixed(m, node), (int)want);
        }
    }
    /* k = stiffness * (sx nx^2 + sy ny^2 + sz nz^2): horizontal links 10*0.5,
     * links at +-60 degrees 10*(0.5/4 + 3*3/4). */
    for (int32_t e = 0; e < ftm_mesh_link_count(m); e++) {
        int32_t a, b;
        double k, len;
        ftm_mesh_link(m, e, &a, &b, &k, &len);
        ftm_vec3 pa = ftm_mesh_rest_position(m, a), pb = ftm_mesh_rest_position(m, b);
        double d = dist(pa, pb);
        double nx = (pb.x - pa.x) / d, ny = (pb.y - pa.y) / d;
        double want = 10.0 * (0.5 * nx * nx + 3.0 * ny * ny);
        ASSERT_REL(k, want, 1e-12);
        if (pa.y == pb.y)
            ASSERT_REL(k, 5.0, 1e-12);
        else
            ASSERT_REL(k, 10.0 * (0.5 * 0.25 + 3.0 * 0.75), 1e-12);
    }
    ftm_mesh_destroy(m);
}

static int lattice_class(int dx, int dy, int dz)
{
    return (dx != 0) + (dy != 0) + (dz != 0) - 1;
}

static void check_lattice3d(ftm_stencil stencil, int want_interior_degree)
{
    ftm_lattice3d_def def = ftm_default_lattice3d_def();
    def.nx = 5;
    def.ny = 4;
    def.nz = 6;
    def.spacing = (ftm_vec3){1.0, 2.0, 0.5};
    def.stencil = stencil;
    def.material.stiffness = 8.0;
    def.material.node_mass = 0.125;
    def.material.node_damping = 0.0;
    def.fixed_faces = 0;
    ftm_mesh *m = make_lattice3d(&def);
    int nx = def.nx, ny = def.ny, nz = def.nz;
    assert_int_equal(ftm_mesh_node_count(m), nx * ny * nz);
    int links = (nx - 1) * ny * nz + nx * (ny - 1) * nz + nx * ny * (nz - 1);
    if (stencil >= FTM_STENCIL_18)
        links += 2 * ((nx - 1) * (ny - 1) * nz + (nx - 1) * ny * (nz - 1) +
                      nx * (ny - 1) * (nz - 1));
    if (stencil == FTM_STENCIL_26)
        links += 4 * (nx - 1) * (ny - 1) * (nz - 1);
    assert_int_equal(ftm_mesh_link_count(m), links);
    assert_int_equal(ftm_mesh_max_degree(m), want_interior_degree);
    check_adjacency(m);
    for (int iz = 0; iz < nz; iz++) {
        for (int iy = 0; iy < ny; iy++) {
            for (int ix = 0; ix < nx; ix++) {
                int32_t node = ftm_mesh_node_of_input(m, ix + nx * (iy + ny * iz));
                ftm_vec3 p = ftm_mesh_rest_position(m, node);
                assert_true(ftm_mesh_mass(m, node) == 0.125);
                assert_false(ftm_mesh_fixed(m, node));
                const int32_t *nb;
                const double *nk, *nl;
                int32_t deg = ftm_mesh_neighbors(m, node, &nb, &nk, &nl);
                bool interior = ix > 0 && ix < nx - 1 && iy > 0 && iy < ny - 1 && iz > 0 &&
                                iz < nz - 1;
                if (interior)
                    assert_int_equal(deg, want_interior_degree);
                else
                    assert_true(deg < want_interior_degree);
                for (int32_t j = 0; j < deg; j++) {
                    int32_t qin = ftm_mesh_input_of_node(m, nb[j]);
                    int dx = qin % nx - ix, dy = (qin / nx) % ny - iy, dz = qin / (nx * ny) - iz;
                    assert_true(abs(dx) <= 1 && abs(dy) <= 1 && abs(dz) <= 1);
                    int cls = lattice_class(dx, dy, dz);
                    assert_true(cls >= 0 && cls <= (stencil == FTM_STENCIL_6    ? 0
                                                    : stencil == FTM_STENCIL_18 ? 1
                                                                                : 2));
                    double want_len = sqrt(dx * dx * 1.0 + dy * dy * 4.0 + dz * dz * 0.25);
                    ftm_vec3 q = ftm_mesh_rest_position(m, nb[j]);
                    ASSERT_NEAR(q.x - p.x, dx * 1.0, 1e-14);
                    ASSERT_NEAR(q.y - p.y, dy * 2.0, 1e-14);
                    ASSERT_NEAR(q.z - p.z, dz * 0.5, 1e-14);
                    ASSERT_NEAR(nl[j], want_len, 1e-14);
                    ASSERT_REL(nk[j], 8.0, 1e-12);
                }
            }
        }
    }
    ftm_mesh_destroy(m);
}

static void test_lattice3d_stencil6(void **state)
{
    (void)state;
    check_lattice3d(FTM_STENCIL_6, 6);
}

static void test_lattice3d_stencil18(void **state)
{
    (void)state;
    check_lattice3d(FTM_STENCIL_18, 18);
}

static void test_lattice3d_stencil26(void **state)
{
    (void)state;
    check_lattice3d(FTM_STENCIL_26, 26);
}

/* Cubes: link rest lengths are exactly spacing, sqrt2*spacing, sqrt3*spacing. */
static void test_lattice3d_cube_link_lengths(void **state)
{
    (void)state;
    ftm_lattice3d_def def = ftm_default_lattice3d_def();
    def.nx = def.ny = def.nz = 3;
    def.spacing = (ftm_vec3){0.1, 0.1, 0.1};
    def.stencil = FTM_STENCIL_26;
    ftm_mesh *m = make_lattice3d(&def);
    int count[3] = {0, 0, 0};
    for (int32_t e = 0; e < ftm_mesh_link_count(m); e++) {
        int32_t a, b;
        double k, len;
        ftm_mesh_link(m, e, &a, &b, &k, &len);
        double r = len / 0.1;
        if (fabs(r - 1.0) < 1e-12)
            count[0]++;
        else if (fabs(r - sqrt(2.0)) < 1e-12)
            count[1]++;
        else if (fabs(r - sqrt(3.0)) < 1e-12)
            count[2]++;
        else
            fail_msg("link %d has rest length %.17g", (int)e, len);
    }
    assert_int_equal(count[0], 3 * 2 * 9);
    assert_int_equal(count[1], 3 * 2 * 4 * 3);
    assert_int_equal(count[2], 4 * 8);
    /* Interior node of a 3x3x3 cube. */
    int32_t centre = ftm_mesh_node_of_input(m, 1 + 3 * (1 + 3 * 1));
    const int32_t *nb;
    const double *nk, *nl;
    assert_int_equal(ftm_mesh_neighbors(m, centre, &nb, &nk, &nl), 26);
    ftm_mesh_destroy(m);
}

static void test_lattice3d_axis_scale(void **state)
{
    (void)state;
    ftm_lattice3d_def def = ftm_default_lattice3d_def();
    def.nx = 3;
    def.ny = 4;
    def.nz = 3;
    def.spacing = (ftm_vec3){1.0, 1.5, 2.0};
    def.stencil = FTM_STENCIL_26;
    def.material.stiffness = 100.0;
    def.material.axis_scale = (ftm_vec3){0.1, 2.0, 10.0};
    ftm_mesh *m = make_lattice3d(&def);
    int axis_links[3] = {0, 0, 0};
    for (int32_t e = 0; e < ftm_mesh_link_count(m); e++) {
        int32_t a, b;
        double k, len;
        ftm_mesh_link(m, e, &a, &b, &k, &len);
        ftm_vec3 pa = ftm_mesh_rest_position(m, a), pb = ftm_mesh_rest_position(m, b);
        double d = dist(pa, pb);
        double nx = (pb.x - pa.x) / d, ny = (pb.y - pa.y) / d, nz = (pb.z - pa.z) / d;
        double want = 100.0 * (0.1 * nx * nx + 2.0 * ny * ny + 10.0 * nz * nz);
        ASSERT_REL(k, want, 1e-12);
        /* Axis-aligned links: stiffness * axis_scale.<axis> exactly. */
        if (pa.y == pb.y && pa.z == pb.z) {
            assert_true(k == 100.0 * 0.1);
            axis_links[0]++;
        } else if (pa.x == pb.x && pa.z == pb.z) {
            assert_true(k == 100.0 * 2.0);
            axis_links[1]++;
        } else if (pa.x == pb.x && pa.y == pb.y) {
            assert_true(k == 100.0 * 10.0);
            axis_links[2]++;
        }
    }
    assert_int_equal(axis_links[0], 2 * 4 * 3);
    assert_int_equal(axis_links[1], 3 * 3 * 3);
    assert_int_equal(axis_links[2], 3 * 4 * 2);
    ftm_mesh_destroy(m);
}

static void test_lattice3d_class_scale(void **state)
{
    (void)state;
    ftm_lattice3d_def def = ftm_default_lattice3d_def();
    def.nx = def.ny = def.nz = 3;
    def.spacing = (ftm_vec3){1.0, 1.0, 1.0};
    def.stencil = FTM_STENCIL_26;
    def.material.stiffness = 6.0;
    def.class_scale[FTM_LINK_EDGE] = 1.0;
    def.class_scale[FTM_LINK_FACE_DIAGONAL] = 0.5;
    def.class_scale[FTM_LINK_BODY_DIAGONAL] = 0.25;
    ftm_mesh *m = make_lattice3d(&def);
    for (int32_t e = 0; e < ftm_mesh_link_count(m); e++) {
        int32_t a, b;
        double k, len;
        ftm_mesh_link(m, e, &a, &b, &k, &len);
        int32_t ia = ftm_mesh_input_of_node(m, a), ib = ftm_mesh_input_of_node(m, b);
        int cls = lattice_class(ib % 3 - ia % 3, (ib / 3) % 3 - (ia / 3) % 3, ib / 9 - ia / 9);
        ASSERT_REL(k, 6.0 * def.class_scale[cls], 1e-12);
    }
    ftm_mesh_destroy(m);
}

static void test_lattice3d_fixed_faces(void **state)
{
    (void)state;
    static const uint32_t masks[] = {
        0,
        FTM_FACE_XMIN,
        FTM_FACE_ZMIN,
        FTM_FACE_ZMAX,
        FTM_FACE_XMAX | FTM_FACE_YMIN,
        FTM_FACE_YMAX | FTM_FACE_ZMIN | FTM_FACE_XMIN,
        0x3f,
    };
    for (size_t t = 0; t < sizeof masks / sizeof masks[0]; t++) {
        ftm_lattice3d_def def = ftm_default_lattice3d_def();
        def.nx = 4;
        def.ny = 5;
        def.nz = 3;
        def.stencil = FTM_STENCIL_6;
        def.fixed_faces = masks[t];
        ftm_mesh *m = make_lattice3d(&def);
        uint32_t f = masks[t];
        for (int iz = 0; iz < def.nz; iz++)
            for (int iy = 0; iy < def.ny; iy++)
                for (int ix = 0; ix < def.nx; ix++) {
                    bool want = ((f & FTM_FACE_XMIN) && ix == 0) ||
                                ((f & FTM_FACE_XMAX) && ix == def.nx - 1) ||
                                ((f & FTM_FACE_YMIN) && iy == 0) ||
                                ((f & FTM_FACE_YMAX) && iy == def.ny - 1) ||
                                ((f & FTM_FACE_ZMIN) && iz == 0) ||
                                ((f & FTM_FACE_ZMAX) && iz == def.nz - 1);
                    int32_t node = ftm_mesh_node_of_input(m, ix + def.nx * (iy + def.ny * iz));
                    if (ftm_mesh_fixed(m, node) != want)
                        fail_msg("mask 0x%x node (%d,%d,%d): fixed %d expected %d", (unsigned)f,
                                 ix, iy, iz, (int)ftm_mesh_fixed(m, node), (int)want);
                }
        ftm_mesh_destroy(m);
    }
}

static void test_generators_reject_bad_defs(void **state)
{
    (void)state;
    ftm_error err;
    ftm_mesh_builder *b = ftm_mesh_builder_create();

    ftm_lattice2d_def d2 = ftm_default_lattice2d_def();
    d2.nx = 1;
    memset(&err, 0, sizeof err);
    assert_true(ftm_generate_lattice2d(b, &d2, &err) < 0);
    assert_true(strlen(err.message) > 0);
    d2 = ftm_default_lattice2d_def();
    d2.spacing = 0.0;
    assert_true(ftm_generate_lattice2d(b, &d2, &err) < 0);
    d2 = ftm_default_lattice2d_def();
    d2.material.node_mass = -1.0;
    assert_true(ftm_generate_lattice2d(b, &d2, &err) < 0);

    ftm_lattice3d_def d3 = ftm_default_lattice3d_def();
    d3.nz = 1;
    memset(&err, 0, sizeof err);
    assert_true(ftm_generate_lattice3d(b, &d3, &err) < 0);
    assert_true(strlen(err.message) > 0);
    d3 = ftm_default_lattice3d_def();
    d3.stencil = (ftm_stencil)7;
    assert_true(ftm_generate_lattice3d(b, &d3, &err) < 0);
    d3 = ftm_default_lattice3d_def();
    d3.spacing.y = -1.0;
    assert_true(ftm_generate_lattice3d(b, &d3, &err) < 0);
    d3 = ftm_default_lattice3d_def();
    d3.material.stiffness = 0.0;
    assert_true(ftm_generate_lattice3d(b, &d3, &err) < 0);
    d3 = ftm_default_lattice3d_def();
    d3.material.axis_scale.z = -1.0;
    assert_true(ftm_generate_lattice3d(b, &d3, &err) < 0);
    d3 = ftm_default_lattice3d_def();
    d3.class_scale[FTM_LINK_BODY_DIAGONAL] = NAN;
    assert_true(ftm_generate_lattice3d(b, &d3, &err) < 0);

    ftm_mesh_builder_destroy(b);
}

/* ------------------------------------------------------ critical time step */

static void test_critical_time_step_chain(void **state)
{
    (void)state;
    /* 1D chain, equal masses m and springs k. Interior free node: lambda <=
     * 2k(1/m + 1/m) = 4k/m, so h = 2/sqrt(4k/m) = sqrt(m/k). */
    const double mass = 2.0, k = 8.0;
    ftm_mesh_builder *b = ftm_mesh_builder_create();
    for (int i = 0; i < 6; i++) {
        ftm_node_def d = node_at(i * 0.5, 0, 0);
        d.mass = mass;
        assert_int_equal(ftm_mesh_builder_add_node(b, &d), i);
    }
    for (int i = 0; i < 5; i++) {
        ftm_link_def l = link_of(i, i + 1, k);
        ftm_mesh_builder_add_link(b, &l);
    }
    ftm_mesh *m = build(b, true);
    ASSERT_REL(ftm_mesh_critical_time_step(m), sqrt(mass / k), 1e-12);
    ftm_mesh_destroy(m);
    ftm_mesh_builder_destroy(b);
}

static void test_critical_time_step_formula(void **state)
{
    (void)state;
    /* Free chain A(m=1) -k=3- B(m=4) -k=5- C(m=2):
     *   A: 3(1/1 + 1/sqrt(4))              = 4.5
     *   B: 3(1/4 + 1/sqrt(4)) + 5(1/4 + 1/sqrt(8))
     *   C: 5(1/2 + 1/sqrt(8))
     * max is B's row. */
    const double mass[3] = {1.0, 4.0, 2.0};
    ftm_mesh_builder *b = ftm_mesh_builder_create();
    for (int i = 0; i < 3; i++) {
        ftm_node_def d = node_at(i, 0, 0);
        d.mass = mass[i];
        ftm_mesh_builder_add_node(b, &d);
    }
    ftm_link_def l = link_of(0, 1, 3.0);
    ftm_mesh_builder_add_link(b, &l);
    l = link_of(1, 2, 5.0);
    ftm_mesh_builder_add_link(b, &l);
    ftm_mesh *m = build(b, true);
    double la = 3.0 * (1.0 + 1.0 / sqrt(4.0));
    double lb = 3.0 * (0.25 + 1.0 / sqrt(4.0)) + 5.0 * (0.25 + 1.0 / sqrt(8.0));
    double lc = 5.0 * (0.5 + 1.0 / sqrt(8.0));
    double lambda = fmax(la, fmax(lb, lc));
    assert_true(lambda == lb);
    ASSERT_REL(ftm_mesh_critical_time_step(m), 2.0 / sqrt(lambda), 1e-12);
    ftm_mesh_destroy(m);
    ftm_mesh_builder_destroy(b);
}

static void test_critical_time_step_free_nodes_only(void **state)
{
    (void)state;
    /* Star: a fixed hub with 10 links (row sum 20 if it counted) to free
     * leaves of mass 1, k = 1. Each leaf's row is 1*(1 + 1) = 2 if the fixed
     * neighbour's off-diagonal term is included, 1 if not (the contract does
     * not say which; both are accepted); never the hub's 20. */
    ftm_mesh_builder *b = ftm_mesh_builder_create();
    ftm_node_def d = node_at(0, 0, 0);
    d.fixed = true;
    ftm_mesh_builder_add_node(b, &d);
    for (int i = 0; i < 10; i++) {
        double a = 2.0 * 3.14159265358979323846 * i / 10.0;
        d = node_at(cos(a), sin(a), 0);
        d.mass = 1.0;
        ftm_mesh_builder_add_node(b, &d);
        ftm_link_def l = link_of(0, i + 1, 1.0);
        ftm_mesh_builder_add_link(b, &l);
    }
    ftm_mesh *m = build(b, true);
    double h = ftm_mesh_critical_time_step(m);
    if (!(fabs(h - 2.0 / sqrt(2.0)) < 1e-12 || fabs(h - 2.0) < 1e-12))
        fail_msg("critical step of a fixed-hub star: %.17g, expected sqrt(2) or 2", h);
    ftm_mesh_destroy(m);
    ftm_mesh_builder_destroy(b);

    /* No free node with a link: INFINITY. */
    b = ftm_mesh_builder_create();
    d = node_at(0, 0, 0);
    d.fixed = true;
    ftm_mesh_builder_add_node(b, &d);
    d = node_at(1, 0, 0);
    d.fixed = true;
    ftm_mesh_builder_add_node(b, &d);
    d = node_at(5, 0, 0); /* free, but isolated */
    ftm_mesh_builder_add_node(b, &d);
    ftm_link_def l = link_of(0, 1, 1.0);
    ftm_mesh_builder_add_link(b, &l);
    m = build(b, true);
    h = ftm_mesh_critical_time_step(m);
    assert_true(isinf(h) && h > 0);
    ftm_mesh_destroy(m);
    ftm_mesh_builder_destroy(b);
}

static void test_critical_time_step_lattice(void **state)
{
    (void)state;
    /* 2D lattice, equal masses and springs: interior row 6k(2/m). */
    ftm_lattice2d_def def = ftm_default_lattice2d_def();
    def.nx = 6;
    def.ny = 6;
    def.material.node_mass = 0.5;
    def.material.stiffness = 30.0;
    ftm_mesh *m = make_lattice2d(&def);
    ASSERT_REL(ftm_mesh_critical_time_step(m), 2.0 / sqrt(6.0 * 30.0 * 2.0 / 0.5), 1e-12);
    ftm_mesh_destroy(m);
}

/* ----------------------------------------------------- surface from tets */

/* Collects the triangles as sorted input-index triples, sorted. */
static int cmp_tri(const void *a, const void *b)
{
    const int32_t *x = a, *y = b;
    for (int i = 0; i < 3; i++)
        if (x[i] != y[i])
            return x[i] < y[i] ? -1 : 1;
    return 0;
}

static int32_t *sorted_triangles(const ftm_mesh *m)
{
    int32_t n = ftm_mesh_triangle_count(m);
    const int32_t *t = ftm_mesh_triangles(m);
    int32_t *s = malloc(sizeof *s * (size_t)(3 * n + 1));
    for (int32_t i = 0; i < n; i++) {
        int32_t v[3] = {ftm_mesh_input_of_node(m, t[3 * i]), ftm_mesh_input_of_node(m, t[3 * i + 1]),
                        ftm_mesh_input_of_node(m, t[3 * i + 2])};
        for (int p = 0; p < 3; p++)
            for (int q = p + 1; q < 3; q++)
                if (v[q] < v[p]) {
                    int32_t x = v[p];
                    v[p] = v[q];
                    v[q] = x;
                }
        memcpy(&s[3 * i], v, sizeof v);
    }
    qsort(s, (size_t)n, 3 * sizeof(int32_t), cmp_tri);
    return s;
}

static ftm_mesh_builder *tet_builder(int npts)
{
    static const double p[5][3] = {{0, 0, 0}, {1, 0, 0}, {0, 1, 0}, {0, 0, 1}, {1, 1, 1}};
    ftm_mesh_builder *b = ftm_mesh_builder_create();
    for (int i = 0; i < npts; i++) {
        ftm_node_def d = node_at(p[i][0], p[i][1], p[i][2]);
        assert_int_equal(ftm_mesh_builder_add_node(b, &d), i);
    }
    return b;
}

static void test_surface_single_tet(void **state)
{
    (void)state;
    ftm_mesh_builder *b = tet_builder(4);
    assert_int_equal(ftm_mesh_builder_add_tetrahedron(b, 0, 1, 2, 3), FTM_OK);
    ftm_mesh *m = build(b, true);
    assert_int_equal(ftm_mesh_tetrahedron_count(m), 1);
    assert_int_equal(ftm_mesh_triangle_count(m), 4);
    int32_t *s = sorted_triangles(m);
    static const int32_t want[12] = {0, 1, 2, 0, 1, 3, 0, 2, 3, 1, 2, 3};
    assert_memory_equal(s, want, sizeof want);
    free(s);
    /* The stored tetrahedron has the four vertices. */
    const int32_t *t = ftm_mesh_tetrahedra(m);
    int sum = 0;
    for (int i = 0; i < 4; i++)
        sum += ftm_mesh_input_of_node(m, t[i]);
    assert_int_equal(sum, 6);
    ftm_mesh_destroy(m);
    ftm_mesh_builder_destroy(b);
}

static void test_surface_two_tets_sharing_a_face(void **state)
{
    (void)state;
    ftm_mesh_builder *b = tet_builder(5);
    assert_int_equal(ftm_mesh_builder_add_tetrahedron(b, 0, 1, 2, 3), FTM_OK);
    assert_int_equal(ftm_mesh_builder_add_tetrahedron(b, 4, 3, 2, 1), FTM_OK);
    ftm_mesh *m = build(b, true);
    assert_int_equal(ftm_mesh_tetrahedron_count(m), 2);
    assert_int_equal(ftm_mesh_triangle_count(m), 6);
    int32_t *s = sorted_triangles(m);
    /* All faces except the shared one (1,2,3). */
    static const int32_t want[18] = {0, 1, 2, 0, 1, 3, 0, 2, 3, 1, 2, 4, 1, 3, 4, 2, 3, 4};
    assert_memory_equal(s, want, sizeof want);
    free(s);
    ftm_mesh_destroy(m);
    ftm_mesh_builder_destroy(b);
}

static void test_surface_options(void **state)
{
    (void)state;
    /* surface_from_tetrahedra = false: no triangles come from the tets. */
    ftm_mesh_builder *b = tet_builder(4);
    ftm_mesh_builder_add_tetrahedron(b, 0, 1, 2, 3);
    ftm_mesh_build_def def = ftm_default_mesh_build_def();
    def.surface_from_tetrahedra = false;
    ftm_mesh *m = NULL;
    assert_int_equal(ftm_mesh_build(b, &def, &m, NULL), FTM_OK);
    assert_int_equal(ftm_mesh_triangle_count(m), 0);
    assert_int_equal(ftm_mesh_tetrahedron_count(m), 1);
    ftm_mesh_destroy(m);
    /* Triangles given: they are the surface, even with tets present. */
    assert_int_equal(ftm_mesh_builder_add_triangle(b, 0, 1, 2), FTM_OK);
    m = build(b, true);
    assert_int_equal(ftm_mesh_triangle_count(m), 1);
    ftm_mesh_destroy(m);
    ftm_mesh_builder_destroy(b);
}

/* ------------------------------------------------------------ element labels */

static void test_element_labels(void **state)
{
    (void)state;
    ftm_mesh_builder *b = tet_builder(5);
    /* no label set: the mesh carries none, every element reads 0 */
    assert_int_equal(ftm_mesh_builder_add_tetrahedron(b, 0, 1, 2, 3), FTM_OK);
    ftm_mesh *m = build(b, true);
    assert_false(ftm_mesh_has_labels(m));
    assert_null(ftm_mesh_tetrahedron_labels(m));
    assert_int_equal(ftm_mesh_tetrahedron_label(m, 0), 0);
    assert_int_equal(ftm_mesh_tetrahedron_label(m, 1), FTM_ERANGE);
    assert_int_equal(ftm_mesh_tetrahedron_label(m, -1), FTM_ERANGE);
    assert_int_equal(ftm_mesh_hexahedron_label(m, 0), FTM_ERANGE);
    ftm_mesh_destroy(m);

    /* labels set on some elements, also on one added after the first label */
    assert_int_equal(ftm_mesh_builder_tetrahedron_count(b), 1);
    assert_int_equal(ftm_mesh_builder_set_tetrahedron_label(b, 0, 7), FTM_OK);
    assert_int_equal(ftm_mesh_builder_set_tetrahedron_label(b, 1, 7), FTM_ERANGE);
    assert_int_equal(ftm_mesh_builder_set_tetrahedron_label(b, 0, -2), FTM_EINVAL);
    for (int i = 0; i < 200; i++) /* past the label array's first capacity */
        assert_int_equal(ftm_mesh_builder_add_tetrahedron(b, 4, 3, 2, 1), FTM_OK);
    assert_int_equal(ftm_mesh_builder_tetrahedron_count(b), 201);
    assert_int_equal(ftm_mesh_builder_set_tetrahedron_label(b, 200, 2), FTM_OK);
    m = build(b, true);
    assert_true(ftm_mesh_has_labels(m));
    const int32_t *labels = ftm_mesh_tetrahedron_labels(m);
    assert_non_null(labels);
    assert_int_equal(labels[0], 7);
    assert_int_equal(ftm_mesh_tetrahedron_label(m, 0), 7);
    for (int i = 1; i < 200; i++)
        assert_int_equal(ftm_mesh_tetrahedron_label(m, i), 0);
    assert_int_equal(ftm_mesh_tetrahedron_label(m, 200), 2);
    assert_null(ftm_mesh_hexahedron_labels(m));
    ftm_mesh_destroy(m);
    ftm_mesh_builder_destroy(b);

    /* hexahedra: labels follow the builder's element order; a copy with
     * another material keeps them */
    ftm_lattice3d_def d = ftm_default_lattice3d_def();
    d.nx = 3, d.ny = 2, d.nz = 2;
    d.spacing = (ftm_vec3){1, 1, 1};
    b = ftm_mesh_builder_create();
    assert_int_equal(ftm_generate_lattice3d(b, &d, NULL), FTM_OK);
    assert_int_equal(ftm_mesh_builder_hexahedron_count(b), 2);
    assert_int_equal(ftm_mesh_builder_set_hexahedron_label(b, 1, 3), FTM_OK);
    assert_int_equal(ftm_mesh_builder_set_hexahedron_label(b, 2, 3), FTM_ERANGE);
    m = build(b, true);
    assert_int_equal(ftm_mesh_hexahedron_label(m, 0), 0);
    assert_int_equal(ftm_mesh_hexahedron_label(m, 1), 3);
    assert_null(ftm_mesh_tetrahedron_labels(m));
    ftm_material_def to = d.material;
    to.stiffness *= 2;
    ftm_mesh *m2 = NULL;
    assert_int_equal(ftm_mesh_with_material(m, &d.material, &to, &m2, NULL), FTM_OK);
    assert_int_equal(ftm_mesh_hexahedron_label(m2, 1), 3);
    assert_true(ftm_mesh_hexahedron_labels(m2) != ftm_mesh_hexahedron_labels(m));
    ftm_mesh_destroy(m2);
    ftm_mesh_destroy(m);
    ftm_mesh_builder_destroy(b);
}

/* ------------------------------------------------------------ misc queries */

static void test_nearest_node(void **state)
{
    (void)state;
    ftm_lattice3d_def def = ftm_default_lattice3d_def();
    def.nx = 4;
    def.ny = 3;
    def.nz = 5;
    def.spacing = (ftm_vec3){1.0, 1.0, 1.0};
    ftm_mesh *m = make_lattice3d(&def);
    ftm_vec3 origin = ftm_mesh_rest_position(m, ftm_mesh_node_of_input(m, 0));
    for (int iz = 0; iz < def.nz; iz++)
        for (int iy = 0; iy < def.ny; iy++)
            for (int ix = 0; ix < def.nx; ix++) {
                ftm_vec3 p = {origin.x + ix + 0.3, origin.y + iy - 0.2, origin.z + iz + 0.1};
                int32_t want = ftm_mesh_node_of_input(m, ix + def.nx * (iy + def.ny * iz));
                assert_int_equal(ftm_mesh_nearest_node(m, p), want);
            }
    ftm_mesh_destroy(m);
}

/* Boundary conditions set after the nodes exist (scene files fix nodes of
 * loaded meshes this way); bad indices are refused. */
static void test_builder_set_fixed(void **state)
{
    (void)state;
    ftm_mesh_builder *b = ftm_mesh_builder_create();
    ftm_node_def nd = ftm_default_node_def();
    for (int i = 0; i < 3; i++) {
        nd.position = (ftm_vec3){i, 2.0 * i, 0};
        assert_int_equal(ftm_mesh_builder_add_node(b, &nd), i);
    }
    ftm_vec3 p;
    assert_int_equal(ftm_mesh_builder_node_position(b, 2, &p), FTM_OK);
    assert_true(p.x == 2.0 && p.y == 4.0 && p.z == 0.0);
    assert_int_equal(ftm_mesh_builder_node_position(b, 3, &p), FTM_ERANGE);
    assert_int_equal(ftm_mesh_builder_node_position(b, -1, &p), FTM_ERANGE);
    assert_int_equal(ftm_mesh_builder_set_fixed(b, 1, true), FTM_OK);
    assert_int_equal(ftm_mesh_builder_set_fixed(b, 3, true), FTM_ERANGE);
    ftm_mesh *m = NULL;
    assert_int_equal(ftm_mesh_build(b, NULL, &m, NULL), FTM_OK);
    for (int i = 0; i < 3; i++)
        assert_int_equal(ftm_mesh_fixed(m, ftm_mesh_node_of_input(m, i)), i == 1);
    ftm_mesh_destroy(m);
    assert_int_equal(ftm_mesh_builder_set_fixed(b, 1, false), FTM_OK);
    assert_int_equal(ftm_mesh_build(b, NULL, &m, NULL), FTM_OK);
    assert_false(ftm_mesh_fixed(m, ftm_mesh_node_of_input(m, 1)));
    ftm_mesh_destroy(m);
    ftm_mesh_builder_destroy(b);
}

/* The 3D lattice adds its cells as hexahedra: bottom face counter-clockwise
 * seen from +z, then the top face right above it (the FEM reference relies
 * on this order). */
static void test_lattice3d_hexahedra(void **state)
{
    (void)state;
    ftm_mesh_builder *b = ftm_mesh_builder_create();
    ftm_lattice3d_def d = ftm_default_lattice3d_def();
    d.nx = 4;
    d.ny = 3;
    d.nz = 2;
    d.spacing = (ftm_vec3){1.0, 2.0, 3.0};
    assert_int_equal(ftm_generate_lattice3d(b, &d, NULL), FTM_OK);
    ftm_mesh *m = NULL;
    assert_int_equal(ftm_mesh_build(b, NULL, &m, NULL), FTM_OK);
    assert_int_equal(ftm_mesh_hexahedron_count(m), 3 * 2 * 1);
    const int32_t *h = ftm_mesh_hexahedra(m);
    static const double corner[8][3] = {{0, 0, 0}, {1, 0, 0}, {1, 1, 0}, {0, 1, 0},
                                        {0, 0, 1}, {1, 0, 1}, {1, 1, 1}, {0, 1, 1}};
    for (int32_t c = 0; c < ftm_mesh_hexahedron_count(m); c++) {
        ftm_vec3 o = ftm_mesh_rest_position(m, h[8 * c]);
        for (int k = 0; k < 8; k++) {
            ftm_vec3 p = ftm_mesh_rest_position(m, h[8 * c + k]);
            assert_true(p.x == o.x + corner[k][0] * 1.0);
            assert_true(p.y == o.y + corner[k][1] * 2.0);
            assert_true(p.z == o.z + corner[k][2] * 3.0);
        }
    }
    ftm_mesh_destroy(m);
    int32_t bad[8] = {0, 1, 2, 3, 4, 5, 6, 6};
    assert_int_equal(ftm_mesh_builder_add_hexahedron(b, bad), FTM_ERANGE);
    ftm_mesh_builder_destroy(b);
}

int main(void)
{
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(test_builder_rejects_bad_nodes),
        cmocka_unit_test(test_builder_rejects_bad_links),
        cmocka_unit_test(test_builder_rejects_bad_triangles_and_tets),
        cmocka_unit_test(test_build_empty_fails_with_message),
        cmocka_unit_test(test_builder_reusable_after_build),
        cmocka_unit_test(test_reorder_is_a_consistent_permutation),
        cmocka_unit_test(test_reorder_reduces_bandwidth_of_a_path),
        cmocka_unit_test(test_default_generator_defs),
        cmocka_unit_test(test_lattice2d_topology),
        cmocka_unit_test(test_lattice2d_fixed_faces_and_anisotropy),
        cmocka_unit_test(test_lattice3d_stencil6),
        cmocka_unit_test(test_lattice3d_stencil18),
        cmocka_unit_test(test_lattice3d_stencil26),
        cmocka_unit_test(test_lattice3d_cube_link_lengths),
        cmocka_unit_test(test_lattice3d_axis_scale),
        cmocka_unit_test(test_lattice3d_class_scale),
        cmocka_unit_test(test_lattice3d_fixed_faces),
        cmocka_unit_test(test_generators_reject_bad_defs),
        cmocka_unit_test(test_critical_time_step_chain),
        cmocka_unit_test(test_critical_time_step_formula),
        cmocka_unit_test(test_critical_time_step_free_nodes_only),
        cmocka_unit_test(test_critical_time_step_lattice),
        cmocka_unit_test(test_surface_single_tet),
        cmocka_unit_test(test_surface_two_tets_sharing_a_face),
        cmocka_unit_test(test_surface_options),
        cmocka_unit_test(test_element_labels),
        cmocka_unit_test(test_nearest_node),
        cmocka_unit_test(test_builder_set_fixed),
        cmocka_unit_test(test_lattice3d_hexahedra),
    };
    return cmocka_run_group_tests(tests, NULL, NULL);
}
