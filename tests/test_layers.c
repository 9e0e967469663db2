/* SPDX-License-Identifier: GPL-3.0-or-later */
/* Tests of the force transmittal layers (paper section 3.1.2-3.1.6): the
 * depth-synchronised breadth-first search from the contact nodes, its node
 * counts (Eqs. 9 and 10), merging of several sources, the layer cache, and
 * the update order inside a layer. Public API only (sim.h, mesh.h,
 * generate.h). */
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

/* ------------------------------------------------------------------ helpers */

static ftm_mesh *lattice2d(int nx, int ny, uint32_t fixed_faces)
{
    ftm_lattice2d_def def = ftm_default_lattice2d_def();
    def.nx = nx;
    def.ny = ny;
    def.spacing = 1.0;
    def.material.node_mass = 1.0;
    def.material.node_damping = 2.0;
    def.material.stiffness = 10.0;
    def.fixed_faces = fixed_faces;
    ftm_mesh_builder *b = ftm_mesh_builder_create();
    ftm_error err;
    memset(&err, 0, sizeof err);
    if (ftm_generate_lattice2d(b, &def, &err) != FTM_OK)
        fail_msg("lattice2d: %s", err.message);
    ftm_mesh *m = NULL;
    ftm_mesh_build_def bd = ftm_default_mesh_build_def();
    if (ftm_mesh_build(b, &bd, &m, &err) != FTM_OK)
        fail_msg("build: %s", err.message);
    ftm_mesh_builder_destroy(b);
    return m;
}

static ftm_mesh *lattice3d(int nx, int ny, int nz, ftm_stencil stencil, uint32_t fixed_faces)
{
    ftm_lattice3d_def def = ftm_default_lattice3d_def();
    def.nx = nx;
    def.ny = ny;
    def.nz = nz;
    def.spacing = (ftm_vec3){1.0, 1.0, 1.0};
    def.stencil = stencil;
    def.material.node_mass = 1.0;
    def.material.node_damping = 2.0;
    def.material.stiffness = 10.0;
    def.fixed_faces = fixed_faces;
    ftm_mesh_builder *b = ftm_mesh_builder_create();
    ftm_error err;
    memset(&err, 0, sizeof err);
    if (ftm_generate_lattice3d(b, &def, &err) != FTM_OK)
        fail_msg("lattice3d: %s", err.message);
    ftm_mesh *m = NULL;
    ftm_mesh_build_def bd = ftm_default_mesh_build_def();
    if (ftm_mesh_build(b, &bd, &m, &err) != FTM_OK)
        fail_msg("build: %s", err.message);
    ftm_mesh_builder_destroy(b);
    return m;
}

static int32_t node2d(const ftm_mesh *m, int nx, int ix, int iy)
{
    return ftm_mesh_node_of_input(m, ix + nx * iy);
}

static int32_t node3d(const ftm_mesh *m, int nx, int ny, int ix, int iy, int iz)
{
    return ftm_mesh_node_of_input(m, ix + nx * (iy + ny * iz));
}

static ftm_sim *make_sim(const ftm_mesh *m, int32_t depth, ftm_order order)
{
    ftm_sim_def def = ftm_default_sim_def();
    def.depth = depth;
    def.order = order;
    def.time_step = 1e-3;
    ftm_sim *s = NULL;
    ftm_error err;
    memset(&err, 0, sizeof err);
    if (ftm_sim_create(m, &def, &s, &err) != FTM_OK)
        fail_msg("ftm_sim_create: %s", err.message);
    assert_non_null(s);
    return s;
}

static void set_force_contacts(ftm_sim *s, const int32_t *nodes, int count)
{
    ftm_contact c[16];
    assert_true(count <= 16);
    for (int i = 0; i < count; i++) {
        c[i].node = nodes[i];
        c[i].group = 0;
        c[i].kind = FTM_CONTACT_FORCE;
        c[i].value = (ftm_vec3){0.1, -0.05, 0.02};
    }
    ftm_error err;
    memset(&err, 0, sizeof err);
    int rc = ftm_sim_set_contacts(s, c, count, &err);
    if (rc != FTM_OK)
        fail_msg("ftm_sim_set_contacts: %d %s", rc, err.message);
}

/* Graph distance from one source, by a plain BFS over the whole mesh
 * (through fixed nodes too unless skip_fixed). -1: unreachable. */
static void bfs(const ftm_mesh *m, int32_t src, bool skip_fixed, int32_t *dist)
{
    int32_t n = ftm_mesh_node_count(m);
    int32_t *queue = malloc(sizeof *queue * (size_t)n);
    for (int32_t i = 0; i < n; i++)
        dist[i] = -1;
    int32_t head = 0, tail = 0;
    dist[src] = 0;
    queue[tail++] = src;
    while (head < tail) {
        int32_t u = queue[head++];
        if (skip_fixed && u != src && ftm_mesh_fixed(m, u))
            continue;
        const int32_t *nb;
        const double *k, *l;
        int32_t deg = ftm_mesh_neighbors(m, u, &nb, &k, &l);
        for (int32_t j = 0; j < deg; j++) {
            if (dist[nb[j]] < 0) {
                dist[nb[j]] = dist[u] + 1;
                queue[tail++] = nb[j];
            }
        }
    }
    free(queue);
}

/* Reference layer index: min over the sources of the single-source distance. */
static int32_t *reference_layers(const ftm_mesh *m, const int32_t *src, int count, bool skip_fixed)
{
    int32_t n = ftm_mesh_node_count(m);
    int32_t *best = malloc(sizeof *best * (size_t)n);
    int32_t *d = malloc(sizeof *d * (size_t)n);
    for (int32_t i = 0; i < n; i++)
        best[i] = -1;
    for (int s = 0; s < count; s++) {
        bfs(m, src[s], skip_fixed, d);
        for (int32_t i = 0; i < n; i++)
            if (d[i] >= 0 && (best[i] < 0 || d[i] < best[i]))
                best[i] = d[i];
    }
    free(d);
    return best;
}

/* Reads the layers; checks the arrays are well formed and every node appears
 * at most once. Returns layer_of[node] (-1: not in the region), caller frees. */
static int32_t *layer_map(ftm_sim *s, int32_t *layer_count_out)
{
    const ftm_mesh *m = ftm_sim_mesh(s);
    int32_t n = ftm_mesh_node_count(m);
    const int32_t *order = NULL, *start = NULL;
    int32_t lc = ftm_sim_layers(s, &order, &start);
    assert_true(lc >= 0);
    int32_t *layer_of = malloc(sizeof *layer_of * (size_t)n);
    for (int32_t i = 0; i < n; i++)
        layer_of[i] = -1;
    if (lc > 0) {
        assert_non_null(order);
        assert_non_null(start);
        assert_int_equal(start[0], 0);
        for (int32_t l = 0; l < lc; l++) {
            assert_true(start[l + 1] >= start[l]);
            for (int32_t p = start[l]; p < start[l + 1]; p++) {
                int32_t v = order[p];
                assert_true(v >= 0 && v < n);
                if (layer_of[v] >= 0)
                    fail_msg("node %d is in layers %d and %d", (int)v, (int)layer_of[v], (int)l);
                layer_of[v] = l;
            }
        }
    }
    *layer_count_out = lc;
    return layer_of;
}

static int32_t layer_size(ftm_sim *s, int32_t l)
{
    const int32_t *order, *start;
    int32_t lc = ftm_sim_layers(s, &order, &start);
    assert_true(l < lc);
    return start[l + 1] - start[l];
}

static int32_t region_size(ftm_sim *s)
{
    const int32_t *order, *start;
    int32_t lc = ftm_sim_layers(s, &order, &start);
    return lc > 0 ? start[lc] : 0;
}

/* The region is exactly the nodes with reference distance <= depth, each at
 * layer = that distance; layer 0 is exactly the contact set. */
static void check_against_reference(ftm_sim *s, const int32_t *src, int count, int32_t depth)
{
    const ftm_mesh *m = ftm_sim_mesh(s);
    int32_t n = ftm_mesh_node_count(m);
    int32_t *ref = reference_layers(m, src, count, false);
    int32_t lc;
    int32_t *layer_of = layer_map(s, &lc);
    int32_t max_ref = 0;
    for (int32_t i = 0; i < n; i++) {
        int32_t want = (ref[i] >= 0 && ref[i] <= depth) ? ref[i] : -1;
        if (layer_of[i] != want)
            fail_msg("node %d (input %d): layer %d, expected %d", (int)i,
                     (int)ftm_mesh_input_of_node(m, i), (int)layer_of[i], (int)want);
        if (want > max_ref)
            max_ref = want;
    }
    assert_true(lc >= max_ref + 1);
    assert_true(lc <= depth + 1);
    assert_int_equal(layer_size(s, 0), count);
    free(ref);
    free(layer_of);
}

/* ------------------------------------------------------------ Eq. 9 (2D) */

static void test_eq9_triangular_lattice(void **state)
{
    (void)state;
    const int nx = 60, ny = 60;
    ftm_mesh *m = lattice2d(nx, ny, 0);
    int32_t centre = node2d(m, nx, 30, 30);
    for (int32_t n = 1; n <= 20; n++) {
        ftm_sim *s = make_sim(m, n, FTM_ORDER_LAYER_COLORED);
        set_force_contacts(s, &centre, 1);
        const int32_t *order, *start;
        int32_t lc = ftm_sim_layers(s, &order, &start);
        assert_int_equal(lc, n + 1);
        int32_t total = start[lc];
        if (total != 3 * n * n + 3 * n + 1)
            fail_msg("depth %d: %d nodes, Eq. 9 gives %d", (int)n, (int)total,
                     (int)(3 * n * n + 3 * n + 1));
        assert_int_equal(start[1] - start[0], 1);
        assert_int_equal(order[0], centre);
        for (int32_t l = 1; l <= n; l++)
            if (start[l + 1] - start[l] != 6 * l)
                fail_msg("depth %d: layer %d has %d nodes, expected %d", (int)n, (int)l,
                         (int)(start[l + 1] - start[l]), (int)(6 * l));
        if (n == 20 || n == 7)
            check_against_reference(s, &centre, 1, n);
        /* A step leaves the same layers (cached). */
        assert_int_equal(ftm_sim_step(s), FTM_OK);
        ftm_sim_stats st;
        ftm_sim_get_stats(s, &st);
        assert_int_equal(st.layers, n + 1);
        assert_int_equal(st.region_nodes, 3 * n * n + 3 * n + 1);
        assert_int_equal(st.depth, n);
        assert_int_equal(region_size(s), 3 * n * n + 3 * n + 1);
        ftm_sim_destroy(s);
    }
    ftm_mesh_destroy(m);
}

/* Table 3 of the paper on its own 50x50 lattice: 7, 19, 37, 61, 91, 331,
 * 721, 1261 nodes for depths 1, 2, 3, 4, 5, 10, 15, 20. */
static void test_table3_node_counts(void **state)
{
    (void)state;
    static const int32_t depth[] = {1, 2, 3, 4, 5, 10, 15, 20};
    static const int32_t nodes[] = {7, 19, 37, 61, 91, 331, 721, 1261};
    ftm_mesh *m = lattice2d(50, 50, 0);
    int32_t centre = node2d(m, 50, 25, 25);
    ftm_sim *s = make_sim(m, 1, FTM_ORDER_LAYER_COLORED);
    set_force_contacts(s, &centre, 1);
    for (size_t i = 0; i < sizeof depth / sizeof depth[0]; i++) {
        assert_int_equal(ftm_sim_set_depth(s, depth[i]), FTM_OK);
        assert_int_equal(ftm_sim_step(s), FTM_OK);
        ftm_sim_stats st;
        ftm_sim_get_stats(s, &st);
        assert_int_equal(st.depth, depth[i]);
        assert_int_equal(st.region_nodes, nodes[i]);
        assert_int_equal(region_size(s), nodes[i]);
    }
    ftm_sim_destroy(s);
    ftm_mesh_destroy(m);
}

/* ----------------------------------------------------------- Eq. 10 (3D) */

static void test_eq10_cubic_half_space(void **state)
{
    (void)state;
    /* 6-stencil: graph distance is the Manhattan distance. Source at the
     * centre of the top face (12, 12, nz-1); for n <= 12 the region reaches
     * |dx|, |dy| <= 12 (ix, iy in 0..24) and 12 layers down (iz >= 1 with
     * nz = 14), so it never meets another face: the half-space count holds. */
    const int nx = 25, ny = 25, nz = 14;
    ftm_mesh *m = lattice3d(nx, ny, nz, FTM_STENCIL_6, 0);
    int32_t src = node3d(m, nx, ny, 12, 12, nz - 1);
    for (int32_t n = 1; n <= 12; n++) {
        ftm_sim *s = make_sim(m, n, FTM_ORDER_LAYER_COLORED);
        set_force_contacts(s, &src, 1);
        const int32_t *order, *start;
        int32_t lc = ftm_sim_layers(s, &order, &start);
        assert_int_equal(lc, n + 1);
        int32_t want = (n + 1) * (2 * n * n + 4 * n + 3) / 3;
        if (start[lc] != want)
            fail_msg("depth %d: %d nodes, Eq. 10 gives %d", (int)n, (int)start[lc], (int)want);
        /* Layer l of the half space: 1 + 2l(l+1) nodes. */
        for (int32_t l = 0; l <= n; l++)
            assert_int_equal(start[l + 1] - start[l], 1 + 2 * l * (l + 1));
        if (n == 12)
            check_against_reference(s, &src, 1, n);
        ftm_sim_destroy(s);
    }
    ftm_mesh_destroy(m);
}

/* ------------------------------------------------------ several sources */

static void test_two_sources_far_apart(void **state)
{
    (void)state;
    const int nx = 80, ny = 40, depth = 5;
    ftm_mesh *m = lattice2d(nx, ny, 0);
    int32_t src[2] = {node2d(m, nx, 20, 20), node2d(m, nx, 60, 20)};
    ftm_sim *s = make_sim(m, depth, FTM_ORDER_LAYER_COLORED);
    set_force_contacts(s, src, 2);
    const int32_t *order, *start;
    int32_t lc = ftm_sim_layers(s, &order, &start);
    assert_int_equal(lc, depth + 1);
    assert_int_equal(start[lc], 2 * (3 * depth * depth + 3 * depth + 1));
    assert_int_equal(start[1] - start[0], 2);
    for (int32_t l = 1; l <= depth; l++)
        assert_int_equal(start[l + 1] - start[l], 12 * l);
    check_against_reference(s, src, 2, depth);
    ftm_sim_destroy(s);
    ftm_mesh_destroy(m);
}

static void test_two_sources_close_merge(void **state)
{
    (void)state;
    const int nx = 60, ny = 60, depth = 6;
    ftm_mesh *m = lattice2d(nx, ny, 0);
    int32_t src[2] = {node2d(m, nx, 30, 30), node2d(m, nx, 33, 30)};
    ftm_sim *s = make_sim(m, depth, FTM_ORDER_LAYER_COLORED);
    set_force_contacts(s, src, 2);
    check_against_reference(s, src, 2, depth);
    /* The regions overlap: fewer nodes than two separate hexagons. */
    int32_t total = region_size(s);
    assert_true(total < 2 * (3 * depth * depth + 3 * depth + 1));
    assert_true(total > 3 * depth * depth + 3 * depth + 1);
    ftm_sim_destroy(s);
    ftm_mesh_destroy(m);
}

static void test_three_sources_merge(void **state)
{
    (void)state;
    const int nx = 60, ny = 60, depth = 7;
    ftm_mesh *m = lattice2d(nx, ny, 0);
    int32_t src[3] = {node2d(m, nx, 30, 30), node2d(m, nx, 33, 31), node2d(m, nx, 29, 34)};
    ftm_sim *s = make_sim(m, depth, FTM_ORDER_BFS);
    set_force_contacts(s, src, 3);
    check_against_reference(s, src, 3, depth);
    ftm_sim_destroy(s);

    /* Neighbouring sources (a collided triangle's three vertices). */
    int32_t tri[3] = {node2d(m, nx, 20, 20), node2d(m, nx, 21, 20), 0};
    /* The third vertex: a common neighbour of the first two. */
    const int32_t *nb0, *nb1;
    const double *k, *l;
    int32_t d0 = ftm_mesh_neighbors(m, tri[0], &nb0, &k, &l);
    int32_t d1 = ftm_mesh_neighbors(m, tri[1], &nb1, &k, &l);
    tri[2] = -1;
    for (int32_t i = 0; i < d0 && tri[2] < 0; i++)
        for (int32_t j = 0; j < d1; j++)
            if (nb0[i] == nb1[j]) {
                tri[2] = nb0[i];
                break;
            }
    assert_true(tri[2] >= 0);
    s = make_sim(m, depth, FTM_ORDER_LAYER_JACOBI);
    set_force_contacts(s, tri, 3);
    check_against_reference(s, tri, 3, depth);
    ftm_sim_destroy(s);
    ftm_mesh_destroy(m);
}

/* Sources in 3D (26-stencil) and near a corner, where the region is cut by
 * the mesh boundary. */
static void test_sources_3d_and_boundary(void **state)
{
    (void)state;
    const int nx = 10, ny = 9, nz = 8;
    ftm_mesh *m = lattice3d(nx, ny, nz, FTM_STENCIL_26, 0);
    int32_t src[2] = {node3d(m, nx, ny, 1, 1, 7), node3d(m, nx, ny, 8, 2, 7)};
    for (int32_t depth = 0; depth <= 12; depth += 3) {
        ftm_sim *s = make_sim(m, depth, FTM_ORDER_LAYER_COLORED);
        set_force_contacts(s, src, 2);
        check_against_reference(s, src, 2, depth);
        ftm_sim_destroy(s);
    }
    /* A depth far beyond the mesh: the region is the whole (connected) mesh
     * and there are no more than depth + 1 layers. */
    ftm_sim *s = make_sim(m, 1000, FTM_ORDER_LAYER_COLORED);
    set_force_contacts(s, src, 2);
    assert_int_equal(region_size(s), nx * ny * nz);
    check_against_reference(s, src, 2, 1000);
    ftm_sim_destroy(s);
    ftm_mesh_destroy(m);
}

/* ------------------------------------------------------------ depth 0 */

static void test_depth_zero(void **state)
{
    (void)state;
    const int nx = 20, ny = 20;
    ftm_mesh *m = lattice2d(nx, ny, 0);
    int32_t src[3] = {node2d(m, nx, 5, 5), node2d(m, nx, 6, 5), node2d(m, nx, 15, 12)};
    ftm_sim *s = make_sim(m, 0, FTM_ORDER_LAYER_COLORED);
    set_force_contacts(s, src, 3);
    const int32_t *order, *start;
    int32_t lc = ftm_sim_layers(s, &order, &start);
    assert_int_equal(lc, 1);
    assert_int_equal(start[1], 3);
    for (int i = 0; i < 3; i++) {
        bool found = false;
        for (int j = 0; j < 3; j++)
            found = found || order[j] == src[i];
        assert_true(found);
    }
    assert_int_equal(ftm_sim_step(s), FTM_OK);
    ftm_sim_stats st;
    ftm_sim_get_stats(s, &st);
    assert_int_equal(st.layers, 1);
    assert_int_equal(st.region_nodes, 3);
    assert_int_equal(st.depth, 0);

    /* Raising the depth from 0 via set_depth. */
    assert_int_equal(ftm_sim_set_depth(s, 1), FTM_OK);
    assert_int_equal(ftm_sim_step(s), FTM_OK);
    check_against_reference(s, src, 3, 1);
    ftm_sim_destroy(s);
    ftm_mesh_destroy(m);
}

static void test_set_depth_validation(void **state)
{
    (void)state;
    ftm_mesh *m = lattice2d(6, 6, 0);
    ftm_sim *s = make_sim(m, 3, FTM_ORDER_LAYER_COLORED);
    assert_true(ftm_sim_set_depth(s, -1) < 0);
    assert_true(ftm_sim_set_depth(s, 1000001) < 0);
    assert_int_equal(ftm_sim_set_depth(s, 1000000), FTM_OK);
    assert_int_equal(ftm_sim_set_depth(s, 0), FTM_OK);
    assert_int_equal(ftm_sim_step(s), FTM_OK);
    ftm_sim_stats st;
    ftm_sim_get_stats(s, &st);
    assert_int_equal(st.depth, 0);
    /* Creation rejects a negative depth. */
    ftm_sim_def def = ftm_default_sim_def();
    def.depth = -2;
    ftm_sim *bad = NULL;
    ftm_error err;
    memset(&err, 0, sizeof err);
    assert_true(ftm_sim_create(m, &def, &bad, &err) < 0);
    assert_null(bad);
    assert_true(strlen(err.message) > 0);
    ftm_sim_destroy(s);
    ftm_mesh_destroy(m);
}

/* ------------------------------------------------------------ fixed nodes */

/* sim.h does not say whether fixed nodes appear in the layers (they might be
 * kept for traversal) so this asserts only what it promises: every free node
 * within the depth is in the region at its graph distance (in this lattice
 * the fixed bottom row never shortens a path between free nodes: a path
 * along row 0 has a same-length twin along row 1), no node beyond the depth
 * is, and fixed nodes never move. */
static void test_fixed_nodes(void **state)
{
    (void)state;
    const int nx = 20, ny = 20, depth = 5;
    ftm_mesh *m = lattice2d(nx, ny, FTM_FACE_YMIN);
    int32_t src = node2d(m, nx, 10, 2);
    ftm_sim *s = make_sim(m, depth, FTM_ORDER_LAYER_COLORED);
    set_force_contacts(s, &src, 1);
    int32_t n = ftm_mesh_node_count(m);
    int32_t *ref = reference_layers(m, &src, 1, false);
    int32_t *ref_free = reference_layers(m, &src, 1, true);
    int32_t lc;
    int32_t *layer_of = layer_map(s, &lc);
    int fixed_in_region = 0;
    for (int32_t i = 0; i < n; i++) {
        if (ftm_mesh_fixed(m, i)) {
            fixed_in_region += layer_of[i] >= 0;
            if (layer_of[i] >= 0)
                assert_true(ref[i] <= depth);
            continue;
        }
        assert_int_equal(ref[i], ref_free[i]);
        int32_t want = ref[i] <= depth ? ref[i] : -1;
        if (layer_of[i] != want)
            fail_msg("free node %d: layer %d, expected %d", (int)i, (int)layer_of[i], (int)want);
    }
    print_message("fixed nodes listed in the layers: %d\n", fixed_in_region);
    for (int step = 0; step < 50; step++)
        assert_int_equal(ftm_sim_step(s), FTM_OK);
    for (int32_t i = 0; i < n; i++) {
        if (!ftm_mesh_fixed(m, i))
            continue;
        ftm_vec3 x = ftm_sim_position(s, i), X = ftm_mesh_rest_position(m, i);
        assert_true(x.x == X.x && x.y == X.y && x.z == X.z);
    }
    free(ref);
    free(ref_free);
    free(layer_of);
    ftm_sim_destroy(s);
    ftm_mesh_destroy(m);
}

/* ------------------------------------------------------------------ cache */

static uint64_t searches(const ftm_sim *s)
{
    ftm_sim_stats st;
    ftm_sim_get_stats(s, &st);
    return st.searches;
}

static void set_contacts_value(ftm_sim *s, const int32_t *nodes, int count, double fx,
                               ftm_contact_kind kind)
{
    ftm_contact c[8];
    for (int i = 0; i < count; i++) {
        c[i].node = nodes[i];
        c[i].group = i;
        c[i].kind = kind;
        c[i].value = (ftm_vec3){fx, 0.0, 0.0};
    }
    assert_int_equal(ftm_sim_set_contacts(s, c, count, NULL), FTM_OK);
}

static void test_cache(void **state)
{
    (void)state;
    const int nx = 30, ny = 30;
    ftm_mesh *m = lattice2d(nx, ny, 0);
    int32_t a = node2d(m, nx, 10, 10), b = node2d(m, nx, 20, 15);
    ftm_sim *s = make_sim(m, 4, FTM_ORDER_LAYER_COLORED);
    /* The first step may build the (empty) initial region; the contract does
     * not say whether that counts as a search. After it, steps without
     * contact never search. */
    assert_int_equal(ftm_sim_step(s), FTM_OK);
    uint64_t s0 = searches(s);
    assert_true(s0 <= 1);
    for (int i = 0; i < 3; i++)
        assert_int_equal(ftm_sim_step(s), FTM_OK);
    assert_true(searches(s) == s0);

    set_contacts_value(s, &a, 1, 0.1, FTM_CONTACT_FORCE);
    assert_int_equal(ftm_sim_step(s), FTM_OK);
    uint64_t s1 = searches(s);
    assert_true(s1 == s0 + 1);

    /* Only the force value changes: no new search. */
    set_contacts_value(s, &a, 1, 0.2, FTM_CONTACT_FORCE);
    assert_int_equal(ftm_sim_step(s), FTM_OK);
    assert_true(searches(s) == s1);
    /* Further steps: no new search. */
    assert_int_equal(ftm_sim_run(s, 20), FTM_OK);
    assert_true(searches(s) == s1);

    /* Another node: a new search. */
    set_contacts_value(s, &b, 1, 0.1, FTM_CONTACT_FORCE);
    assert_int_equal(ftm_sim_step(s), FTM_OK);
    uint64_t s2 = searches(s);
    assert_true(s2 == s1 + 1);
    int32_t both[2] = {a, b};
    set_contacts_value(s, both, 2, 0.1, FTM_CONTACT_FORCE);
    assert_int_equal(ftm_sim_step(s), FTM_OK);
    uint64_t s3 = searches(s);
    assert_true(s3 == s2 + 1);
    check_against_reference(s, both, 2, 4);

    /* Changing the depth: a new search at the next step. */
    assert_int_equal(ftm_sim_set_depth(s, 6), FTM_OK);
    assert_int_equal(ftm_sim_step(s), FTM_OK);
    uint64_t s4 = searches(s);
    assert_true(s4 == s3 + 1);
    check_against_reference(s, both, 2, 6);
    assert_int_equal(ftm_sim_run(s, 5), FTM_OK);
    assert_true(searches(s) == s4);

    /* Release, then touch again: the layers are searched again. */
    assert_int_equal(ftm_sim_set_contacts(s, NULL, 0, NULL), FTM_OK);
    assert_int_equal(ftm_sim_step(s), FTM_OK);
    ftm_sim_stats st;
    ftm_sim_get_stats(s, &st);
    assert_int_equal(st.region_nodes, 0);
    uint64_t s5 = searches(s);
    set_contacts_value(s, &a, 1, 0.1, FTM_CONTACT_FORCE);
    assert_int_equal(ftm_sim_step(s), FTM_OK);
    assert_true(searches(s) > s5);
    check_against_reference(s, &a, 1, 6);
    ftm_sim_destroy(s);
    ftm_mesh_destroy(m);
}

/* Same node, now as a displacement contact: the node set is unchanged, so
 * no new search ("Layers are recomputed only if the node set changed"). The
 * update schedule may well need rebuilding (a displacement node is not
 * integrated) but that is not a breadth-first search. */
static void test_cache_kind_change_same_node(void **state)
{
    (void)state;
    const int nx = 30, ny = 30;
    ftm_mesh *m = lattice2d(nx, ny, 0);
    int32_t a = node2d(m, nx, 10, 10);
    ftm_sim *s = make_sim(m, 4, FTM_ORDER_LAYER_COLORED);
    set_contacts_value(s, &a, 1, 0.1, FTM_CONTACT_FORCE);
    assert_int_equal(ftm_sim_step(s), FTM_OK);
    uint64_t s1 = searches(s);
    set_contacts_value(s, &a, 1, 0.001, FTM_CONTACT_DISPLACEMENT);
    assert_int_equal(ftm_sim_step(s), FTM_OK);
    if (searches(s) != s1)
        fail_msg("force -> displacement on the same node: searches %llu -> %llu",
                 (unsigned long long)s1, (unsigned long long)searches(s));
    check_against_reference(s, &a, 1, 4);
    ftm_sim_destroy(s);
    ftm_mesh_destroy(m);
}

/* The node *set* decides: the same nodes listed in another order are not a
 * change (reading of "Layers are recomputed only if the node set changed"). */
static void test_cache_same_set_other_order(void **state)
{
    (void)state;
    const int nx = 30, ny = 30;
    ftm_mesh *m = lattice2d(nx, ny, 0);
    int32_t ab[2] = {node2d(m, nx, 10, 10), node2d(m, nx, 20, 15)};
    int32_t ba[2] = {ab[1], ab[0]};
    ftm_sim *s = make_sim(m, 4, FTM_ORDER_LAYER_COLORED);
    set_contacts_value(s, ab, 2, 0.1, FTM_CONTACT_FORCE);
    assert_int_equal(ftm_sim_step(s), FTM_OK);
    uint64_t s1 = searches(s);
    set_contacts_value(s, ba, 2, 0.1, FTM_CONTACT_FORCE);
    assert_int_equal(ftm_sim_step(s), FTM_OK);
    assert_true(searches(s) == s1);
    check_against_reference(s, ba, 2, 4);
    ftm_sim_destroy(s);
    ftm_mesh_destroy(m);
}

/* cache_layers = false: a search every step, with the same layers. */
static void test_cache_disabled(void **state)
{
    (void)state;
    const int nx = 20, ny = 20;
    ftm_mesh *m = lattice2d(nx, ny, 0);
    int32_t a = node2d(m, nx, 10, 10);
    ftm_sim_def def = ftm_default_sim_def();
    def.depth = 3;
    def.cache_layers = false;
    ftm_sim *s = NULL;
    assert_int_equal(ftm_sim_create(m, &def, &s, NULL), FTM_OK);
    set_contacts_value(s, &a, 1, 0.1, FTM_CONTACT_FORCE);
    assert_int_equal(ftm_sim_step(s), FTM_OK);
    uint64_t s1 = searches(s);
    assert_int_equal(ftm_sim_run(s, 10), FTM_OK);
    assert_true(searches(s) == s1 + 10);
    check_against_reference(s, &a, 1, 3);
    ftm_sim_destroy(s);
    ftm_mesh_destroy(m);
}

/* ---------------------------------------------------------- update order */

/* The three orders visit the same layers (as sets). */
static void test_orders_have_same_layer_sets(void **state)
{
    (void)state;
    const int nx = 40, ny = 40, depth = 8;
    ftm_mesh *m = lattice2d(nx, ny, 0);
    int32_t src[2] = {node2d(m, nx, 18, 20), node2d(m, nx, 22, 21)};
    int32_t *maps[3];
    int32_t lcs[3];
    static const ftm_order orders[3] = {FTM_ORDER_LAYER_COLORED, FTM_ORDER_BFS,
                                        FTM_ORDER_LAYER_JACOBI};
    for (int o = 0; o < 3; o++) {
        ftm_sim *s = make_sim(m, depth, orders[o]);
        set_force_contacts(s, src, 2);
        assert_int_equal(ftm_sim_step(s), FTM_OK);
        maps[o] = layer_map(s, &lcs[o]);
        check_against_reference(s, src, 2, depth);
        ftm_sim_destroy(s);
    }
    assert_int_equal(lcs[0], lcs[1]);
    assert_int_equal(lcs[0], lcs[2]);
    assert_memory_equal(maps[0], maps[1], sizeof(int32_t) * (size_t)ftm_mesh_node_count(m));
    assert_memory_equal(maps[0], maps[2], sizeof(int32_t) * (size_t)ftm_mesh_node_count(m));
    for (int o = 0; o < 3; o++)
        free(maps[o]);
    ftm_mesh_destroy(m);
}

/* FTM_ORDER_BFS is a breadth-first traversal order: with a FIFO queue, the
 * nodes of layer l+1 appear in the order of the earliest position (in layer l)
 * of a neighbour that discovers them, so that position never decreases. */
static void check_fifo_order(ftm_sim *s)
{
    const ftm_mesh *m = ftm_sim_mesh(s);
    int32_t n = ftm_mesh_node_count(m);
    const int32_t *order, *start;
    int32_t lc = ftm_sim_layers(s, &order, &start);
    int32_t *pos = malloc(sizeof *pos * (size_t)n);
    int32_t *lay = malloc(sizeof *lay * (size_t)n);
    for (int32_t i = 0; i < n; i++)
        pos[i] = lay[i] = -1;
    for (int32_t l = 0; l < lc; l++)
        for (int32_t p = start[l]; p < start[l + 1]; p++) {
            pos[order[p]] = p;
            lay[order[p]] = l;
        }
    for (int32_t l = 1; l < lc; l++) {
        int32_t prev = -1;
        for (int32_t p = start[l]; p < start[l + 1]; p++) {
            const int32_t *nb;
            const double *k, *len;
            int32_t deg = ftm_mesh_neighbors(m, order[p], &nb, &k, &len);
            int32_t parent = INT32_MAX;
            for (int32_t j = 0; j < deg; j++)
                if (lay[nb[j]] == l - 1 && pos[nb[j]] < parent)
                    parent = pos[nb[j]];
            assert_true(parent != INT32_MAX);
            if (parent < prev)
                fail_msg("BFS order: node at position %d (layer %d) discovered from position "
                         "%d after a node discovered from %d",
                         (int)p, (int)l, (int)parent, (int)prev);
            prev = parent;
        }
    }
    free(pos);
    free(lay);
}

static void test_bfs_order_is_fifo(void **state)
{
    (void)state;
    ftm_mesh *m = lattice2d(40, 40, 0);
    int32_t src[2] = {node2d(m, 40, 15, 20), node2d(m, 40, 23, 22)};
    ftm_sim *s = make_sim(m, 9, FTM_ORDER_BFS);
    set_force_contacts(s, src, 2);
    assert_int_equal(ftm_sim_step(s), FTM_OK);
    check_fifo_order(s);
    ftm_sim_destroy(s);

    ftm_mesh *m3 = lattice3d(9, 9, 9, FTM_STENCIL_26, FTM_FACE_ZMIN);
    int32_t c = node3d(m3, 9, 9, 4, 4, 8);
    s = make_sim(m3, 6, FTM_ORDER_BFS);
    set_force_contacts(s, &c, 1);
    assert_int_equal(ftm_sim_step(s), FTM_OK);
    check_fifo_order(s);
    ftm_sim_destroy(s);
    ftm_mesh_destroy(m3);
    ftm_mesh_destroy(m);
}

/* FTM_ORDER_LAYER_COLORED: each layer is a run of independent sets (no two
 * adjacent nodes in one set). The fewest contiguous independent blocks a
 * layer splits into (greedy cut) is at most the number of sets the
 * implementation used, which a greedy colouring keeps <= max degree + 1. */
static void check_colored(ftm_sim *s)
{
    const ftm_mesh *m = ftm_sim_mesh(s);
    const int32_t *order, *start;
    int32_t lc = ftm_sim_layers(s, &order, &start);
    int32_t limit = ftm_mesh_max_degree(m) + 1;
    for (int32_t l = 0; l < lc; l++) {
        int32_t blocks = 0, block_start = start[l];
        for (int32_t p = start[l]; p < start[l + 1]; p++) {
            bool adjacent = p == start[l];
            const int32_t *nb;
            const double *k, *len;
            int32_t deg = ftm_mesh_neighbors(m, order[p], &nb, &k, &len);
            for (int32_t q = block_start; q < p && !adjacent; q++)
                for (int32_t j = 0; j < deg; j++)
                    if (nb[j] == order[q]) {
                        adjacent = true;
                        break;
                    }
            if (adjacent) {
                blocks++;
                block_start = p;
            }
        }
        if (blocks > limit)
            fail_msg("layer %d (%d nodes) splits into %d independent runs, more than %d",
                     (int)l, (int)(start[l + 1] - start[l]), (int)blocks, (int)limit);
    }
}

static void test_colored_order_groups_independent_sets(void **state)
{
    (void)state;
    ftm_mesh *m = lattice2d(40, 40, 0);
    int32_t src[2] = {node2d(m, 40, 15, 20), node2d(m, 40, 16, 20)};
    ftm_sim *s = make_sim(m, 10, FTM_ORDER_LAYER_COLORED);
    set_force_contacts(s, src, 2);
    assert_int_equal(ftm_sim_step(s), FTM_OK);
    check_colored(s);
    ftm_sim_destroy(s);

    ftm_mesh *m3 = lattice3d(9, 9, 9, FTM_STENCIL_26, 0);
    int32_t c = node3d(m3, 9, 9, 4, 4, 8);
    s = make_sim(m3, 6, FTM_ORDER_LAYER_COLORED);
    set_force_contacts(s, &c, 1);
    assert_int_equal(ftm_sim_step(s), FTM_OK);
    check_colored(s);
    ftm_sim_destroy(s);
    ftm_mesh_destroy(m3);
    ftm_mesh_destroy(m);
}

int main(void)
{
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(test_eq9_triangular_lattice),
        cmocka_unit_test(test_table3_node_counts),
        cmocka_unit_test(test_eq10_cubic_half_space),
        cmocka_unit_test(test_two_sources_far_apart),
        cmocka_unit_test(test_two_sources_close_merge),
        cmocka_unit_test(test_three_sources_merge),
        cmocka_unit_test(test_sources_3d_and_boundary),
        cmocka_unit_test(test_depth_zero),
        cmocka_unit_test(test_set_depth_validation),
        cmocka_unit_test(test_fixed_nodes),
        cmocka_unit_test(test_cache),
        cmocka_unit_test(test_cache_same_set_other_order),
        cmocka_unit_test(test_cache_kind_change_same_node),
        cmocka_unit_test(test_cache_disabled),
        cmocka_unit_test(test_orders_have_same_layer_sets),
        cmocka_unit_test(test_bfs_order_is_fifo),
        cmocka_unit_test(test_colored_order_groups_independent_sets),
    };
    return cmocka_run_group_tests(tests, NULL, NULL);
}
