/* SPDX-License-Identifier: GPL-3.0-or-later */
/* The vector sweeps' kernels (AVX where the CPU has it, the baseline one
 * otherwise; in the colored order link data read from the mesh's padded rows
 * on a schedule's first use, from the schedule's slot-major copy after) must
 * give bit-identical states: compare ftm_sim_hash. Each must also roll a
 * rejected step back exactly. */
#include <math.h>
#include <setjmp.h>
#include <stdarg.h>
#include <stddef.h>
#include <stdint.h>
#include <stdlib.h>
#include <string.h>

#include <cmocka.h>

#include "ftm/ftm.h"
#include "rollback_check.h"
#include "sim_internal.h"

static ftm_sim *make(const ftm_mesh *m, ftm_order order, bool portable, bool cache,
                     bool planar)
{
    ftm_sim_def d = ftm_default_sim_def();
    d.planar_kernel = planar;
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

static uint64_t planar_sweeps(const ftm_sim *s)
{
    ftm_sim_stats st;
    ftm_sim_get_stats(s, &st);
    return st.planar_sweeps;
}

/* The mesh in mb, built; mb destroyed. */
static ftm_mesh *built(ftm_mesh_builder *mb)
{
    ftm_mesh *m = NULL;
    assert_int_equal(ftm_mesh_build(mb, NULL, &m, NULL), FTM_OK);
    ftm_mesh_builder_destroy(mb);
    return m;
}

/* The default 2D lattice: 50 x 50 nodes. */
static ftm_mesh *lattice(void)
{
    ftm_mesh_builder *mb = ftm_mesh_builder_create();
    ftm_lattice2d_def ld = ftm_default_lattice2d_def();
    assert_int_equal(ftm_generate_lattice2d(mb, &ld, NULL), FTM_OK);
    return built(mb);
}

/* 50 x 30 nodes, only the bottom row fixed: make()'s regions reach the
 * free top edge, whose nodes have fewer links than the padded rows' slots. */
static ftm_mesh *free_edged(void)
{
    ftm_mesh_builder *mb = ftm_mesh_builder_create();
    ftm_lattice2d_def ld = ftm_default_lattice2d_def();
    ld.ny = 30;
    ld.fixed_faces = FTM_FACE_YMIN;
    assert_int_equal(ftm_generate_lattice2d(mb, &ld, NULL), FTM_OK);
    return built(mb);
}

/* Native and baseline kernel, cached and fresh schedules, each with the
 * planar sweep (the lattice lies in z = 0) and the full one. On the
 * free-edged lattice a fresh schedule runs every padded slot of its nodes'
 * rows (ftm_mesh_pad_cheap) and a cached one only those its nodes use. */
static void kernels_match_on(ftm_mesh *m, ftm_order order)
{
    ftm_sim *s[8];
    for (int k = 0; k < 8; k++)
        s[k] = make(m, order, k & 1, !(k & 2), !(k & 4));
    for (int i = 0; i < 20; i++) {
        for (int k = 0; k < 8; k++)
            assert_int_equal(ftm_sim_run(s[k], 50), FTM_OK);
        ftm_vec3 r0 = ftm_sim_reaction(s[0], 1);
        for (int k = 1; k < 8; k++) {
            assert_true(ftm_sim_hash(s[k]) == ftm_sim_hash(s[0]));
            ftm_vec3 r = ftm_sim_reaction(s[k], 1);
            assert_memory_equal(&r, &r0, sizeof r);
        }
    }
    for (int k = 0; k < 8; k++) {
        assert_int_equal(planar_sweeps(s[k]), k & 4 ? 0 : 1000);
        ftm_sim_destroy(s[k]);
    }
    ftm_mesh_destroy(m);
}

static void kernels_match(ftm_order order)
{
    kernels_match_on(lattice(), order);
    ftm_mesh *m = free_edged();
    assert_true(ftm_mesh_pad_cheap(m));
    kernels_match_on(m, order);
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
static void rollback_restores(ftm_order order, bool portable, bool planar)
{
    ftm_mesh *m = lattice();
    ftm_sim_def d = ftm_default_sim_def();
    d.planar_kernel = planar;
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
    for (int p = 0; p < 4; p++) {
        rollback_restores(FTM_ORDER_LAYER_COLORED, p & 1, p & 2);
        rollback_restores(FTM_ORDER_LAYER_JACOBI, p & 1, p & 2);
    }
}

/* A sim of the lattice m with one force contact on node n. */
static ftm_sim *pushed(const ftm_mesh *m, ftm_order order, int32_t depth, bool cache, int32_t n)
{
    ftm_sim_def d = ftm_default_sim_def();
    d.order = order;
    d.time_step = 0.1;
    d.depth = depth;
    d.cache_layers = cache;
    ftm_sim *s = NULL;
    assert_int_equal(ftm_sim_create(m, &d, &s, NULL), FTM_OK);
    ftm_contact c = {.node = n, .kind = FTM_CONTACT_FORCE, .value = {0.0, -0.3, 0.0}};
    assert_int_equal(ftm_sim_set_contacts(s, &c, 1, NULL), FTM_OK);
    return s;
}

/* The same contact node turned from a force into a displacement and back:
 * only the schedule is rebuilt (same nodes), and it must hold the node at
 * its imposed displacement, then let it move again. */
static void kind_change(ftm_order order, bool cache)
{
    ftm_mesh *m = lattice();
    const int32_t n = ftm_mesh_node_of_input(m, 25 + 50 * 25);
    ftm_sim *s = pushed(m, order, 6, cache, n);
    assert_int_equal(ftm_sim_run(s, 30), FTM_OK);
    ftm_contact c = {.node = n};
    c.kind = FTM_CONTACT_DISPLACEMENT;
    c.value = (ftm_vec3){0.05, 0.1, 0.0};
    assert_int_equal(ftm_sim_set_contacts(s, &c, 1, NULL), FTM_OK);
    const ftm_vec3 x0 = ftm_mesh_rest_position(m, n);
    for (int i = 0; i < 10; i++) {
        assert_int_equal(ftm_sim_run(s, 1), FTM_OK);
        const double *x = ftm_sim_positions(s) + 3 * (size_t)n;
        assert_true(x[0] == x0.x + 0.05 && x[1] == x0.y + 0.1 && x[2] == x0.z);
    }
    c.kind = FTM_CONTACT_FORCE;
    c.value = (ftm_vec3){0.0, -0.3, 0.0};
    assert_int_equal(ftm_sim_set_contacts(s, &c, 1, NULL), FTM_OK);
    assert_int_equal(ftm_sim_run(s, 5), FTM_OK);
    const double *x = ftm_sim_positions(s) + 3 * (size_t)n;
    assert_true(x[0] != x0.x + 0.05 || x[1] != x0.y + 0.1); /* free to move again */
    ftm_sim_destroy(s);
    ftm_mesh_destroy(m);
}

static void test_kind_change_every_order(void **state)
{
    (void)state;
    const ftm_order orders[] = {FTM_ORDER_BFS, FTM_ORDER_LAYER_JACOBI, FTM_ORDER_LAYER_COLORED};
    for (int o = 0; o < 3; o++)
        for (int cache = 0; cache < 2; cache++)
            kind_change(orders[o], cache);
}

/* A force near the lattice's fixed border: regions that reach fixed nodes
 * (depth 6 from a node 3 links in) and regions that do not (depth 2), whose
 * schedules skip the held nodes by filtering and by copying whole layers.
 * Fixed nodes never move; every free node of the region does. */
static void fixed_border(ftm_order order, int32_t depth)
{
    ftm_mesh *m = lattice();
    ftm_sim *s = pushed(m, order, depth, false, ftm_mesh_node_of_input(m, 25 + 50 * 3));
    assert_int_equal(ftm_sim_run(s, 50), FTM_OK);
    const double *x = ftm_sim_positions(s);
    int32_t moved = 0;
    for (int32_t i = 0; i < ftm_mesh_node_count(m); i++) {
        const ftm_vec3 r = ftm_mesh_rest_position(m, i);
        const bool still = x[3 * i] == r.x && x[3 * i + 1] == r.y && x[3 * i + 2] == r.z;
        if (ftm_mesh_fixed(m, i))
            assert_true(still);
        moved += !still;
    }
    /* the region: 3 d (d + 1) + 1 nodes, less the fixed ones when it reaches them */
    if (depth == 2)
        assert_int_equal(moved, 19);
    else
        assert_true(moved > 19 && moved < 3 * depth * (depth + 1) + 1);
    ftm_sim_destroy(s);
    ftm_mesh_destroy(m);
}

static void test_fixed_border_every_order(void **state)
{
    (void)state;
    const ftm_order orders[] = {FTM_ORDER_BFS, FTM_ORDER_LAYER_JACOBI, FTM_ORDER_LAYER_COLORED};
    for (int o = 0; o < 3; o++) {
        fixed_border(orders[o], 2);
        fixed_border(orders[o], 6);
    }
}

/* A sequential sweep over the colored schedule: each node, in schedule
 * order, reads the positions updated before it (ftm_sweep_gs). */
static bool sweep_sequential(ftm_sim *sim, double *max_m2)
{
    return ftm_sweep_gs(sim, 0, sim->s.count, max_m2);
}

/* 70 nodes, each linked to every other: greedy colouring gives the first 63
 * colours 0..62 and the other seven the shared colour, pairwise adjacent. */
static ftm_mesh *clique(void)
{
    ftm_mesh_builder *mb = ftm_mesh_builder_create();
    ftm_node_def nd = ftm_default_node_def();
    nd.mass = 100.0;
    for (int i = 0; i < 70; i++) {
        nd.position = (ftm_vec3){i % 5, (i / 5) % 5, i / 25};
        assert_true(ftm_mesh_builder_add_node(mb, &nd) == i);
    }
    for (int a = 0; a < 70; a++)
        for (int b = a + 1; b < 70; b++) {
            ftm_link_def ld = {.a = a, .b = b, .stiffness = 1.0, .rest_length = -1.0};
            assert_int_equal(ftm_mesh_builder_add_link(mb, &ld), FTM_OK);
        }
    return built(mb);
}

/* The colored order's vector kernel updates an independent set from the
 * state before it, and the shared-colour set one node at a time: both must
 * give exactly what updating the schedule's nodes one after another gives,
 * with and without cached layers. */
static void colored_matches_sequential(const ftm_mesh *m, int32_t node, int32_t depth)
{
    for (int cache = 0; cache < 2; cache++) {
        ftm_sim *s[2] = {pushed(m, FTM_ORDER_LAYER_COLORED, depth, cache, node),
                         pushed(m, FTM_ORDER_LAYER_COLORED, depth, cache, node)};
        s[1]->sweep_groups = sweep_sequential;
        for (int i = 0; i < 8; i++) {
            for (int k = 0; k < 2; k++)
                assert_int_equal(ftm_sim_run(s[k], 25), FTM_OK);
            assert_true(ftm_sim_hash(s[0]) == ftm_sim_hash(s[1]));
        }
        ftm_sim_stats st;
        ftm_sim_get_stats(s[0], &st);
        assert_true(st.guard_events == 0); /* the sums of the energy guard differ */
        assert_false(ftm_sim_at_rest(s[0], node));
        ftm_sim_destroy(s[0]);
        ftm_sim_destroy(s[1]);
    }
}

static void test_colored_matches_sequential(void **state)
{
    (void)state;
    ftm_mesh *m = lattice();
    colored_matches_sequential(m, ftm_mesh_node_of_input(m, 20 + 50 * 25), 12);
    ftm_mesh_destroy(m);
    m = clique();
    int shared = 0;
    for (int32_t i = 0; i < m->node_count; i++)
        shared += m->color[i] == FTM_SHARED_COLOR;
    assert_int_equal(shared, 7);
    colored_matches_sequential(m, ftm_mesh_node_of_input(m, 0), 1);
    ftm_mesh_destroy(m);
}

/* m without its padded rows, as a mesh whose padding would not fit
 * (ftm_mesh_pad_rows_fit) has none: the vector sweep reads the adjacency. */
static ftm_mesh *without_pad_rows(const ftm_mesh *m)
{
    ftm_mesh *c = ftm_mesh_clone(m);
    assert_non_null(c);
    free(c->pad_node);
    free(c->pad_kl);
    c->pad_node = NULL;
    c->pad_kl = NULL;
    return c;
}

/* m with padded rows, as mesh.c lays them out, for a mesh that has none:
 * padding slots link a node to itself with k = -0.0 and len = 0. */
static ftm_mesh *with_pad_rows(const ftm_mesh *m)
{
    ftm_mesh *c = ftm_mesh_clone(m);
    assert_non_null(c);
    const size_t deg = (size_t)c->max_degree, slots = (size_t)c->node_count * deg;
    free(c->pad_node);
    free(c->pad_kl);
    c->pad_node = malloc(slots * sizeof *c->pad_node);
    c->pad_kl = malloc(2 * slots * sizeof *c->pad_kl);
    assert_true(c->pad_node && c->pad_kl);
    for (int32_t i = 0; i < c->node_count; i++)
        for (size_t k = 0; k < deg; k++) {
            const int32_t e = c->adj_start[i] + (int32_t)k;
            const bool in = e < c->adj_start[i + 1];
            c->pad_node[(size_t)i * deg + k] = in ? c->adj_node[e] : i;
            c->pad_kl[2 * ((size_t)i * deg + k)] = in ? c->adj_k[e] : -0.0;
            c->pad_kl[2 * ((size_t)i * deg + k) + 1] = in ? c->adj_len[e] : 0.0;
        }
    return c;
}

/* A hub: node 0 linked to every node of a ring of `ring` (as an OBJ
 * polygon fanned from one corner); every 10th ring node fixed. Ring nodes
 * have 3 links, an odd row whose last link pairs with padding. The ring's
 * node 56 (input 57, where the tests push) sits at the origin: near it the
 * positions are small enough that a force differing in its last place
 * shows in the positions. */
static ftm_mesh *hub(int ring)
{
    const double pi = 3.14159265358979323846, r = 0.2 * ring, a56 = 2.0 * pi * 56 / ring;
    const ftm_vec3 o = {r * cos(a56), r * sin(a56), 0.0};
    ftm_mesh_builder *mb = ftm_mesh_builder_create();
    ftm_node_def nd = ftm_default_node_def();
    nd.damping = 1.0; /* the layer-by-layer update needs some (docs/stability.md) */
    nd.position = (ftm_vec3){-o.x, -o.y, 0};
    assert_true(ftm_mesh_builder_add_node(mb, &nd) == 0);
    for (int i = 0; i < ring; i++) {
        double a = 2.0 * pi * i / ring;
        nd.position = (ftm_vec3){r * cos(a) - o.x, r * sin(a) - o.y, 0.0};
        nd.fixed = i % 10 == 0;
        assert_true(ftm_mesh_builder_add_node(mb, &nd) == i + 1);
    }
    for (int i = 0; i < ring; i++) {
        ftm_link_def spoke = {.a = 0, .b = i + 1, .stiffness = 10.0 / ring, .rest_length = -1.0};
        ftm_link_def rim = {.a = i + 1, .b = (i + 1) % ring + 1, .stiffness = 1.0,
                            .rest_length = -1.0};
        assert_int_equal(ftm_mesh_builder_add_link(mb, &spoke), FTM_OK);
        assert_int_equal(ftm_mesh_builder_add_link(mb, &rim), FTM_OK);
    }
    return built(mb);
}

/* The same sims on a mesh with padded rows (a) and without (b): every
 * kernel, group order, schedule and sweep must give the same bits. */
static void rows_match(const ftm_mesh *a, const ftm_mesh *b, int32_t node, int32_t depth)
{
    assert_true(a->pad_node && !b->pad_node);
    for (int v = 0; v < 16; v++) {
        ftm_sim_def d = ftm_default_sim_def();
        d.order = v & 1 ? FTM_ORDER_LAYER_JACOBI : FTM_ORDER_LAYER_COLORED;
        d.cache_layers = v & 2;
        d.planar_kernel = v & 4;
        d.time_step = 0.1;
        d.depth = depth;
        ftm_sim *s[2];
        const ftm_mesh *m[2] = {a, b};
        ftm_contact c = {.node = node, .kind = FTM_CONTACT_FORCE, .value = {0.02, -0.3, 0.0}};
        for (int k = 0; k < 2; k++) {
            assert_int_equal(ftm_sim_create(m[k], &d, &s[k], NULL), FTM_OK);
            ftm_sim_select_kernel(s[k], v & 8);
            assert_int_equal(ftm_sim_set_contacts(s[k], &c, 1, NULL), FTM_OK);
        }
        assert_true(s[0]->pad_rows && !s[1]->pad_rows);
        for (int i = 0; i < 6; i++) {
            for (int k = 0; k < 2; k++)
                assert_int_equal(ftm_sim_run(s[k], 40), FTM_OK);
            assert_true(ftm_sim_hash(s[0]) == ftm_sim_hash(s[1]));
        }
        assert_false(ftm_sim_at_rest(s[1], node));
        ftm_sim_destroy(s[0]);
        ftm_sim_destroy(s[1]);
    }
}

/* Read from the adjacency (a mesh without padded rows), the vector sweep
 * gives the bits of the padded rows: a lane past its degree gets a padding
 * slot's values. On the lattices (all lanes of a block alike) and on a hub,
 * whose blocks mix its thousand slots with ring lanes of three. */
static void test_compact_rows_match(void **state)
{
    (void)state;
    ftm_mesh *m = lattice(), *c = without_pad_rows(m);
    rows_match(m, c, ftm_mesh_node_of_input(m, 20 + 50 * 25), 12);
    ftm_mesh_destroy(m);
    ftm_mesh_destroy(c);
    m = free_edged();
    c = without_pad_rows(m);
    rows_match(m, c, ftm_mesh_node_of_input(m, 20 + 50 * 25), 12);
    ftm_mesh_destroy(m);
    ftm_mesh_destroy(c);
    c = hub(1000);
    assert_null(c->pad_node); /* 1001 x 1000 slots against 4000 links: not kept */
    m = with_pad_rows(c);
    rows_match(m, c, ftm_mesh_node_of_input(c, 57), 3);
    ftm_mesh_destroy(m);
    ftm_mesh_destroy(c);
}

/* A large hub: padded rows would take 3001 x 3000 slots; the mesh keeps
 * none, and the colored order still updates exactly as one node after
 * another, the jacobi order as the portable kernel does. */
static void test_hub_mesh_without_pad_rows(void **state)
{
    (void)state;
    ftm_mesh *m = hub(3000);
    assert_int_equal(ftm_mesh_max_degree(m), 3000);
    assert_null(m->pad_node);
    assert_null(m->pad_kl);
    const int32_t node = ftm_mesh_node_of_input(m, 57);
    colored_matches_sequential(m, node, 3);
    for (int cache = 0; cache < 2; cache++) {
        ftm_sim *a = pushed(m, FTM_ORDER_LAYER_JACOBI, 3, cache, node),
                *b = pushed(m, FTM_ORDER_LAYER_JACOBI, 3, cache, node);
        ftm_sim_select_kernel(b, true);
        assert_int_equal(ftm_sim_run(a, 200), FTM_OK);
        assert_int_equal(ftm_sim_run(b, 200), FTM_OK);
        assert_true(ftm_sim_hash(a) == ftm_sim_hash(b));
        assert_false(ftm_sim_at_rest(a, node));
        ftm_sim_destroy(a);
        ftm_sim_destroy(b);
    }
    ftm_mesh_destroy(m);
}

/* The colour split of the search's layers: the AVX-512 one (where the CPU
 * has it) and the portable one must give the same layering, on meshes with
 * few colours and with the shared colour, from one and several sources. */
static void splits_match(const ftm_mesh *m, const int32_t *src, int32_t ns, int32_t depth)
{
    ftm_layering a, b;
    assert_int_equal(ftm_layering_init(&a, m->node_count), FTM_OK);
    assert_int_equal(ftm_layering_init(&b, m->node_count), FTM_OK);
    b.scalar_split = true;
    for (int rep = 0; rep < 2; rep++) { /* the second over the first's stamps */
        assert_int_equal(ftm_layering_build(&a, m, src, ns, depth, true), FTM_OK);
        assert_int_equal(ftm_layering_build(&b, m, src, ns, depth, true), FTM_OK);
        assert_int_equal(a.count, b.count);
        assert_int_equal(a.layers, b.layers);
        assert_int_equal(a.sets, b.sets);
        assert_memory_equal(a.order, b.order, (size_t)a.count * sizeof *a.order);
        assert_memory_equal(a.start, b.start, ((size_t)a.layers + 1) * sizeof *a.start);
        assert_memory_equal(a.set_start, b.set_start, ((size_t)a.sets + 1) * sizeof *a.set_start);
        assert_memory_equal(a.set_color, b.set_color, (size_t)a.sets);
    }
    ftm_layering_free(&a);
    ftm_layering_free(&b);
}

static void test_colour_splits_match(void **state)
{
    (void)state;
    ftm_mesh *m = lattice();
    int32_t src[3] = {ftm_mesh_node_of_input(m, 25 + 50 * 25),
                      ftm_mesh_node_of_input(m, 27 + 50 * 25),
                      ftm_mesh_node_of_input(m, 3 + 50 * 40)};
    for (int32_t depth = 0; depth <= 30; depth += 3) {
        splits_match(m, src, 1, depth);
        splits_match(m, src, 3, depth);
    }
    ftm_mesh_destroy(m);

    ftm_mesh_builder *mb = ftm_mesh_builder_create();
    ftm_lattice3d_def ld = ftm_default_lattice3d_def();
    ld.stencil = FTM_STENCIL_26;
    assert_int_equal(ftm_generate_lattice3d(mb, &ld, NULL), FTM_OK);
    m = built(mb);
    src[1] = m->node_count / 3;
    src[0] = m->node_count / 2;
    for (int32_t depth = 0; depth <= 8; depth++)
        splits_match(m, src, 2, depth);
    ftm_mesh_destroy(m);

    m = clique();
    src[0] = 5;
    src[1] = 69;
    splits_match(m, src, 2, 1);
    splits_match(m, src, 1, 2);
    ftm_mesh_destroy(m);
}

/* The state of src loaded into dst: every node not at rest, the contacts,
 * the depth, the step and the mode (what a keyframe carries). */
static void copy_state(ftm_sim *dst, const ftm_sim *src)
{
    const ftm_mesh *m = ftm_sim_mesh(src);
    const int32_t n = ftm_mesh_node_count(m);
    const double *x = ftm_sim_positions(src), *xp = ftm_sim_previous_positions(src);
    int32_t *nodes = malloc((size_t)n * sizeof *nodes);
    double *sx = malloc((size_t)n * 3 * sizeof *sx), *sxp = malloc((size_t)n * 3 * sizeof *sxp);
    assert_true(nodes && sx && sxp);
    int32_t count = 0;
    for (int32_t i = 0; i < n; i++) {
        const ftm_vec3 r = ftm_mesh_rest_position(m, i);
        const double rr[3] = {r.x, r.y, r.z};
        if (memcmp(x + 3 * i, rr, sizeof rr) == 0 && memcmp(xp + 3 * i, rr, sizeof rr) == 0)
            continue;
        memcpy(sx + 3 * count, x + 3 * i, 3 * sizeof *sx);
        memcpy(sxp + 3 * count, xp + 3 * i, 3 * sizeof *sxp);
        nodes[count++] = i;
    }
    const ftm_contact *c;
    const int32_t nc = ftm_sim_contacts(src, &c);
    ftm_sim_stats st;
    ftm_sim_get_stats(src, &st);
    ftm_sim_mode mode;
    ftm_sim_get_mode(src, &mode);
    assert_int_equal(ftm_sim_load_state(dst, st.step, st.depth, nodes, sx, sxp, count, c, nc,
                                        &mode, NULL),
                     FTM_OK);
    free(nodes);
    free(sx);
    free(sxp);
}

/* Steps a (planar sweep allowed) and b (full sweep) together: the same state
 * after every step. Returns how many of a's sweeps were planar. */
static uint64_t step_together(ftm_sim *a, ftm_sim *b, int steps)
{
    const uint64_t p0 = planar_sweeps(a);
    for (int i = 0; i < steps; i++) {
        const int ra = ftm_sim_step(a), rb = ftm_sim_step(b);
        assert_int_equal(ra, rb);
        assert_true(ftm_sim_hash(a) == ftm_sim_hash(b));
    }
    assert_int_equal(planar_sweeps(b), 0);
    return planar_sweeps(a) - p0;
}

/* The planar sweep (a mesh in z = 0, loads in the plane) leaves z out and
 * must give the full sweep's bits: with a force whose z is -0.0, with the
 * guard substepping (time step 3x critical), with both kernels and fresh or
 * cached schedules. A load off the plane switches to the full sweep for
 * good; so does a loaded state off the plane, until a reset or a planar
 * loaded state. */
static void planar_matches(ftm_order order, bool portable, bool cache, double dt_crit)
{
    ftm_mesh *m = lattice();
    ftm_sim *s[2];
    for (int k = 0; k < 2; k++) {
        s[k] = make(m, order, portable, cache, k == 0);
        if (dt_crit > 0) {
            ftm_sim_def d = ftm_default_sim_def();
            d.planar_kernel = k == 0;
            d.order = order;
            d.depth = 12;
            d.cache_layers = cache;
            d.time_step = dt_crit * ftm_mesh_critical_time_step(m);
            ftm_sim_destroy(s[k]);
            assert_int_equal(ftm_sim_create(m, &d, &s[k], NULL), FTM_OK);
            ftm_sim_select_kernel(s[k], portable);
        }
    }
    const int32_t a = ftm_mesh_node_of_input(m, 20 + 50 * 25),
                  b = ftm_mesh_node_of_input(m, 31 + 50 * 22);
    ftm_contact in_plane[2] = {
        {.node = a, .kind = FTM_CONTACT_FORCE, .value = {0.02, -0.3, -0.0}},
        {.node = b, .group = 1, .kind = FTM_CONTACT_DISPLACEMENT, .value = {0.1, 0.2, -0.0}}};
    ftm_contact off_plane = {.node = a, .kind = FTM_CONTACT_FORCE, .value = {0.0, -0.3, 0.05}};
    for (int k = 0; k < 2; k++)
        assert_int_equal(ftm_sim_set_contacts(s[k], in_plane, 2, NULL), FTM_OK);
    assert_true(step_together(s[0], s[1], 60) >= 60);
    if (dt_crit > 0) {
        ftm_sim_stats st;
        ftm_sim_get_stats(s[0], &st);
        assert_true(st.substeps > 1 || st.guard_events > 0);
    }
    /* off the plane: the full sweep from then on, even after the load is
     * back in the plane (z is no longer +0.0) */
    for (int k = 0; k < 2; k++)
        assert_int_equal(ftm_sim_set_contacts(s[k], &off_plane, 1, NULL), FTM_OK);
    assert_int_equal(step_together(s[0], s[1], 30), 0);
    for (int k = 0; k < 2; k++)
        assert_int_equal(ftm_sim_set_contacts(s[k], in_plane, 2, NULL), FTM_OK);
    assert_int_equal(step_together(s[0], s[1], 10), 0);
    /* a reset is back in the plane */
    for (int k = 0; k < 2; k++) {
        ftm_sim_reset(s[k]);
        assert_int_equal(ftm_sim_set_contacts(s[k], in_plane, 2, NULL), FTM_OK);
    }
    assert_true(step_together(s[0], s[1], 20) >= 20);
    /* loaded states: off the plane, then in it */
    ftm_sim *off = make(m, order, portable, cache, false);
    assert_int_equal(ftm_sim_set_contacts(off, &off_plane, 1, NULL), FTM_OK);
    assert_int_equal(ftm_sim_run(off, 10), FTM_OK);
    copy_state(s[0], off);
    copy_state(s[1], off);
    assert_int_equal(step_together(s[0], s[1], 10), 0);
    ftm_sim_reset(off);
    assert_int_equal(ftm_sim_set_contacts(off, in_plane, 2, NULL), FTM_OK);
    assert_int_equal(ftm_sim_run(off, 10), FTM_OK);
    copy_state(s[0], off);
    copy_state(s[1], off);
    assert_true(step_together(s[0], s[1], 10) >= 10);
    /* a simulation's own state loaded back (its contact array is replaced
     * while loading: under ASan a read of the old one fails) */
    copy_state(s[0], s[0]);
    copy_state(s[1], s[1]);
    assert_true(step_together(s[0], s[1], 10) >= 10);
    ftm_sim_destroy(off);
    ftm_sim_destroy(s[0]);
    ftm_sim_destroy(s[1]);
    ftm_mesh_destroy(m);
}

static void test_planar_matches_full(void **state)
{
    (void)state;
    const ftm_order orders[] = {FTM_ORDER_LAYER_JACOBI, FTM_ORDER_LAYER_COLORED};
    for (int o = 0; o < 2; o++)
        for (int v = 0; v < 4; v++)
            planar_matches(orders[o], v & 1, v & 2, 0.0);
    planar_matches(FTM_ORDER_LAYER_COLORED, false, true, 3.0);
    planar_matches(FTM_ORDER_LAYER_JACOBI, true, false, 3.0);
}

/* With cached layers a schedule's block-major copy is recorded by its first
 * sweep, unless the schedule before was swept only once (then by its
 * second); without, schedules live one sweep and it is never made. Either
 * way the state is the same bits. Contacts moved every step, then every
 * second step, then held; compared with fresh schedules step by step. */
static void links_made(ftm_order order, bool portable)
{
    ftm_mesh *m = lattice();
    ftm_sim *a = make(m, order, portable, true, true), *b = make(m, order, portable, false, true);
    const int32_t n0 = ftm_mesh_node_of_input(m, 20 + 50 * 25);
    for (int i = 0; i < 40; i++) {
        const int every = i < 10 ? 1 : i < 30 ? 2 : 1000;
        if (i % every == 0) {
            ftm_contact c = {.node = n0 + (i / every) % 3, .kind = FTM_CONTACT_FORCE,
                             .value = {0.05, -0.3, 0.0}};
            assert_int_equal(ftm_sim_set_contacts(a, &c, 1, NULL), FTM_OK);
            assert_int_equal(ftm_sim_set_contacts(b, &c, 1, NULL), FTM_OK);
        }
        assert_int_equal(ftm_sim_step(a), FTM_OK);
        assert_int_equal(ftm_sim_step(b), FTM_OK);
        assert_true(ftm_sim_hash(a) == ftm_sim_hash(b));
        assert_false(b->s.linked);
        if (i >= 2 && i < 10) /* the schedule before was swept once: not recorded */
            assert_false(a->s.linked);
        else if (i >= 11) /* recorded by the first sweep, or by the second */
            assert_true(a->s.linked);
    }
    ftm_sim_destroy(a);
    ftm_sim_destroy(b);
    ftm_mesh_destroy(m);
}

static void test_links_recorded(void **state)
{
    (void)state;
    for (int p = 0; p < 2; p++) {
        links_made(FTM_ORDER_LAYER_JACOBI, p);
        links_made(FTM_ORDER_LAYER_COLORED, p);
    }
}

/* No planar sweep for a mesh off the plane z = 0 (a cubic lattice). */
static void test_planar_needs_plane(void **state)
{
    (void)state;
    ftm_mesh_builder *mb = ftm_mesh_builder_create();
    ftm_lattice3d_def ld = ftm_default_lattice3d_def();
    assert_int_equal(ftm_generate_lattice3d(mb, &ld, NULL), FTM_OK);
    ftm_mesh *m = built(mb);
    int32_t n = ftm_mesh_node_count(m) / 2;
    while (ftm_mesh_fixed(m, n))
        n++;
    ftm_sim *s = pushed(m, FTM_ORDER_LAYER_COLORED, 4, true, n);
    assert_int_equal(ftm_sim_run(s, 10), FTM_OK);
    assert_int_equal(planar_sweeps(s), 0);
    ftm_sim_destroy(s);
    ftm_mesh_destroy(m);
}

int main(void)
{
    const struct CMUnitTest tests[] = {cmocka_unit_test(test_portable_kernel_matches),
                                       cmocka_unit_test(test_portable_jacobi_kernel_matches),
                                       cmocka_unit_test(test_rollback_every_kernel),
                                       cmocka_unit_test(test_kind_change_every_order),
                                       cmocka_unit_test(test_fixed_border_every_order),
                                       cmocka_unit_test(test_colored_matches_sequential),
                                       cmocka_unit_test(test_colour_splits_match),
                                       cmocka_unit_test(test_planar_matches_full),
                                       cmocka_unit_test(test_planar_needs_plane),
                                       cmocka_unit_test(test_links_recorded),
                                       cmocka_unit_test(test_compact_rows_match),
                                       cmocka_unit_test(test_hub_mesh_without_pad_rows)};
    return cmocka_run_group_tests(tests, NULL, NULL);
}
