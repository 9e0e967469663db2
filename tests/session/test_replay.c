/* SPDX-License-Identifier: GPL-3.0-or-later */
/* ftm_sim_load_state and the replay library, in one process (no network):
 * a simulation restored from another's keyframe continues bit-identically;
 * a replica follows frames with idle ticks left out, resyncs on a gap, a
 * mismatch or a frame that breaks the idle rule, and restores a reset
 * keyframe. */
#include <setjmp.h>
#include <stdarg.h>
#include <stddef.h>
#include <cmocka.h>

#include "claims.h"
#include "digest.h"
#include "keyframe.h"
#include "replica.h"
#include "step.h"
#include "tissue.h"

#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <unistd.h>

static ftm_scene *open_scene(void)
{
    ftm_scene *sc = NULL;
    ftm_error err = {0, ""};
    if (ftm_scene_builtin("default", &sc, &err))
        fail_msg("%s", err.message);
    return sc;
}

/* Contacts of "server tick" t (1-based): a 3-node press that moves, grows,
 * changes node set, then a release at tick 220. */
static int32_t contacts_at(const ftm_mesh *m, uint64_t t, ftm_contact c[4])
{
    if (t > 220)
        return 0;
    int32_t top = ftm_mesh_node_of_input(m, 1662); /* (6, 6, 11) */
    int32_t nb = ftm_mesh_node_of_input(m, 1661), nb2 = ftm_mesh_node_of_input(m, 1650);
    double d = -0.004 * (double)(t < 100 ? t : 100) / 100.0;
    int32_t n = 0;
    c[n++] = (ftm_contact){top, 0, FTM_CONTACT_DISPLACEMENT, {0, 0, d}};
    c[n++] = (ftm_contact){t < 150 ? nb : nb2, 0, FTM_CONTACT_DISPLACEMENT, {0.0005, 0, d}};
    if (t > 60)
        c[n++] = (ftm_contact){ftm_mesh_node_of_input(m, 1600), 1, FTM_CONTACT_FORCE,
                               {0, 0, -0.05}};
    return n;
}

static void check_continuation(uint64_t at)
{
    ftm_scene *sc = open_scene();
    const ftm_mesh *m = ftm_scene_mesh(sc);
    ftm_sim_def def = ftm_replay_sim_def(sc);
    ftm_sim *a = NULL, *b = NULL;
    assert_int_equal(ftm_sim_create(m, &def, &a, NULL), FTM_OK);
    assert_int_equal(ftm_sim_create(m, &def, &b, NULL), FTM_OK);
    ftm_contact c[4];
    for (uint64_t t = 1; t <= at; t++) {
        int32_t n = contacts_at(m, t, c);
        assert_int_equal(ftm_replay_step(a, 8, c, n, NULL), FTM_OK);
    }
    /* b has a history of its own first */
    ftm_contact other = {ftm_mesh_node_of_input(m, 1000), 3, FTM_CONTACT_FORCE, {0.1, 0, 0}};
    for (int i = 0; i < 20; i++)
        assert_int_equal(ftm_replay_step(b, 5, &other, 1, NULL), FTM_OK);
    ftm_wire_keyframe k;
    assert_int_equal(ftm_replay_make_keyframe(a, NULL, &k, NULL), FTM_OK);
    assert_true(k.tick == at);
    assert_true(k.count > 0);
    ftm_error err = {0, ""};
    int rc = ftm_sim_load_state(b, k.tick, k.depth, k.nodes, k.positions, k.previous, k.count,
                                NULL, 0, NULL, &err);
    if (rc)
        fail_msg("%s", err.message);
    assert_true(ftm_sim_hash(b) == k.state_hash);
    assert_true(ftm_sim_hash(a) == ftm_sim_hash(b));
    for (uint64_t t = at + 1; t <= 400; t++) {
        int32_t n = contacts_at(m, t, c);
        assert_int_equal(ftm_replay_step(a, 8, c, n, NULL), FTM_OK);
        assert_int_equal(ftm_replay_step(b, 8, c, n, NULL), FTM_OK);
        if (ftm_sim_hash(a) != ftm_sim_hash(b))
            fail_msg("restored at tick %llu: hashes differ at tick %llu", (unsigned long long)at,
                     (unsigned long long)t);
    }
    ftm_sim_stats sa, sb;
    ftm_sim_get_stats(a, &sa);
    ftm_sim_get_stats(b, &sb);
    assert_int_equal(sa.relaxing_nodes, sb.relaxing_nodes);
    ftm_replay_keyframe_free(&k);
    ftm_sim_destroy(a);
    ftm_sim_destroy(b);
    ftm_scene_destroy(sc);
}

static void test_continue_in_contact(void **state)
{
    (void)state;
    check_continuation(80);  /* pressing, contact set growing next */
    check_continuation(149); /* the next tick changes the node set */
    check_continuation(200); /* steady press */
}

static void test_continue_relaxing(void **state)
{
    (void)state;
    check_continuation(221); /* just released */
    check_continuation(260);
}

/* With the contacts and the guard's mode passed too: a time step above the
 * critical one makes the guard substep. */
static void test_continue_substepped(void **state)
{
    (void)state;
    ftm_scene *sc = open_scene();
    const ftm_mesh *m = ftm_scene_mesh(sc);
    ftm_sim_def def = ftm_replay_sim_def(sc);
    def.time_step = 4.0 * ftm_mesh_critical_time_step(m);
    ftm_sim *a = NULL, *b = NULL;
    assert_int_equal(ftm_sim_create(m, &def, &a, NULL), FTM_OK);
    assert_int_equal(ftm_sim_create(m, &def, &b, NULL), FTM_OK);
    ftm_contact c[4];
    int32_t n = 0;
    for (uint64_t t = 1; t <= 120; t++) {
        n = contacts_at(m, t, c);
        assert_int_equal(ftm_replay_step(a, 8, c, n, NULL), FTM_OK);
    }
    ftm_sim_mode mode;
    ftm_sim_get_mode(a, &mode);
    assert_true(mode.substeps > 1);
    ftm_wire_keyframe k;
    assert_int_equal(ftm_replay_make_keyframe(a, NULL, &k, NULL), FTM_OK);
    ftm_error err = {0, ""};
    if (ftm_sim_load_state(b, k.tick, k.depth, k.nodes, k.positions, k.previous, k.count, c, n,
                           &mode, &err))
        fail_msg("%s", err.message);
    assert_true(ftm_sim_hash(a) == ftm_sim_hash(b));
    for (uint64_t t = 121; t <= 1300; t++) { /* past the guard's retry after 1024 steps */
        n = contacts_at(m, t, c);
        assert_int_equal(ftm_replay_step(a, 8, c, n, NULL), FTM_OK);
        assert_int_equal(ftm_replay_step(b, 8, c, n, NULL), FTM_OK);
        if (ftm_sim_hash(a) != ftm_sim_hash(b))
            fail_msg("hashes differ at tick %llu", (unsigned long long)t);
    }
    /* bad input changes nothing */
    uint64_t h = ftm_sim_hash(b);
    int32_t bad_nodes[2] = {5, 3};
    double xs[6] = {0};
    assert_int_equal(ftm_sim_load_state(b, 1, 8, bad_nodes, xs, xs, 2, NULL, 0, NULL, &err),
                     FTM_EINVAL);
    assert_non_null(strstr(err.message, "ascending"));
    ftm_sim_mode bad = {0, 0, 0, false, -1.0, 0.0};
    assert_int_equal(ftm_sim_load_state(b, 1, 8, NULL, NULL, NULL, 0, NULL, 0, &bad, &err),
                     FTM_EINVAL);
    assert_true(ftm_sim_hash(b) == h);
    ftm_replay_keyframe_free(&k);
    ftm_sim_destroy(a);
    ftm_sim_destroy(b);
    ftm_scene_destroy(sc);
}

/* ---- the replica -------------------------------------------------------------------- */

typedef struct fake_server {
    ftm_sim *sim;
    const ftm_mesh *m;
    uint64_t seq;
    int32_t pub_n;
    ftm_contact c[4];
} fake_server;

/* The server's simulation of the scene, as ftm-server makes it. */
static fake_server fake_server_open(const ftm_scene *sc)
{
    fake_server s = {0};
    s.m = ftm_scene_mesh(sc);
    ftm_sim_def def = ftm_replay_sim_def(sc);
    assert_int_equal(ftm_sim_create(s.m, &def, &s.sim, NULL), FTM_OK);
    return s;
}

/* Runs tick t; returns true and fills rx if the server would send a frame
 * (the idle rule of docs/protocol.md). */
static bool server_tick(fake_server *s, uint64_t t, ftm_wire_received *rx, ftm_contact *store)
{
    int32_t n = contacts_at(s->m, t, s->c);
    assert_int_equal(ftm_replay_step(s->sim, 8, s->c, n, NULL), FTM_OK);
    ftm_sim_stats st;
    ftm_sim_get_stats(s->sim, &st);
    bool idle = n == 0 && s->pub_n == 0 && st.updated_nodes == 0 && t % 20 != 0;
    if (idle)
        return false;
    memcpy(store, s->c, sizeof s->c);
    memset(rx, 0, sizeof *rx);
    rx->msg.kind = FTM_WIRE_TICK;
    rx->msg.u.tick = (ftm_wire_tick){
        .tick = t, .depth = 8, .contact_count = n, .contacts = store, .state_hash = ftm_sim_hash(s->sim)};
    rx->sender = 1;
    rx->seq = ++s->seq;
    s->pub_n = n;
    return true;
}

static void test_replica(void **state)
{
    (void)state;
    ftm_scene *sc = open_scene();
    fake_server s = fake_server_open(sc);
    ftm_replay *r = NULL;
    assert_int_equal(ftm_replay_create(sc, NULL, NULL, &r, NULL), FTM_OK);
    assert_int_equal(ftm_replay_state(r), FTM_WIRE_STATE_JOINING);

    ftm_wire_keyframe k0;
    assert_int_equal(ftm_replay_make_keyframe(s.sim, NULL, &k0, NULL), FTM_OK); /* tick 0 */
    ftm_wire_received rx;
    ftm_contact store[4];
    uint64_t lost_at = 150, bad_at = 240, sent = 0;
    bool gap_next = false;
    for (uint64_t t = 1; t <= 4000; t++) {
        if (!server_tick(&s, t, &rx, store))
            continue;
        if (t == 1) { /* first frame, then the keyframe of tick 0 */
            assert_int_equal(ftm_replay_on_tick(r, &rx), FTM_OK);
            assert_int_equal(ftm_replay_on_keyframe(r, &k0), FTM_OK);
            assert_int_equal(ftm_replay_state(r), FTM_WIRE_STATE_SYNCED);
            assert_true(ftm_replay_tick(r) == 1);
            continue;
        }
        if (t == lost_at) { /* lost in the network */
            gap_next = true;
            continue;
        }
        if (gap_next) {
            rx.gap = 1;
            gap_next = false;
        }
        if (t == bad_at)
            rx.msg.u.tick.state_hash ^= 1; /* corrupted: a mismatch */
        assert_int_equal(ftm_replay_on_tick(r, &rx), FTM_OK);
        sent++;
        if (t == lost_at + 1 || t == bad_at) {
            assert_int_equal(ftm_replay_state(r), FTM_WIRE_STATE_RESYNCING);
            /* the server answers with a keyframe of its current tick */
            ftm_wire_keyframe k;
            assert_int_equal(ftm_replay_make_keyframe(s.sim, NULL, &k, NULL), FTM_OK);
            assert_int_equal(ftm_replay_on_keyframe(r, &k), FTM_OK);
            ftm_replay_keyframe_free(&k);
            assert_int_equal(ftm_replay_state(r), FTM_WIRE_STATE_SYNCED);
        }
        assert_int_equal(ftm_replay_state(r), FTM_WIRE_STATE_SYNCED);
        assert_true(ftm_replay_tick(r) == t);
        assert_true(ftm_replay_hash(r) == ftm_sim_hash(s.sim));
    }
    ftm_replay_stats st;
    ftm_replay_get_stats(r, &st);
    assert_true(st.idle_ticks > 1000); /* the scene went idle: most ticks not sent */
    assert_true(st.gaps == 1 && st.mismatches == 1 && st.resyncs == 2);
    assert_true(st.keyframes_loaded == 3);

    /* reset: the server restores rest at its current tick and sends a keyframe */
    uint64_t t = 4000;
    ftm_contact c = {ftm_mesh_node_of_input(s.m, 1662), 0, FTM_CONTACT_DISPLACEMENT, {0, 0, -0.003}};
    for (int i = 0; i < 30; i++) {
        t++;
        assert_int_equal(ftm_replay_step(s.sim, 8, &c, 1, NULL), FTM_OK);
        rx.msg.u.tick = (ftm_wire_tick){
            .tick = t, .depth = 8, .contact_count = 1, .contacts = &c, .state_hash = ftm_sim_hash(s.sim)};
        rx.seq = ++s.seq;
        rx.gap = 0;
        assert_int_equal(ftm_replay_on_tick(r, &rx), FTM_OK);
    }
    assert_true(ftm_replay_hash(r) == ftm_sim_hash(s.sim));
    assert_int_equal(ftm_sim_load_state(s.sim, t, 8, NULL, NULL, NULL, 0, NULL, 0, NULL, NULL),
                     FTM_OK);
    ftm_wire_keyframe kr;
    assert_int_equal(ftm_replay_make_keyframe(s.sim, NULL, &kr, NULL), FTM_OK);
    assert_int_equal(ftm_replay_on_keyframe(r, &kr), FTM_OK);
    assert_int_equal(ftm_replay_state(r), FTM_WIRE_STATE_SYNCED);
    assert_true(ftm_replay_hash(r) == ftm_sim_hash(s.sim));
    ftm_replay_keyframe_free(&kr);

    ftm_replay_keyframe_free(&k0);
    ftm_replay_destroy(r);
    ftm_sim_destroy(s.sim);
    ftm_scene_destroy(sc);
}

/* A tick frame that breaks the idle rule (docs/protocol.md) is not the
 * server's: the replica resyncs at once instead of stepping towards it. A
 * forged tick number used to cost up to 100,000,000 steps. */
static void forge_frame(ftm_replay *r, uint64_t tick, uint64_t seq, uint64_t want_tick)
{
    ftm_wire_received rx;
    memset(&rx, 0, sizeof rx);
    rx.msg.kind = FTM_WIRE_TICK;
    rx.msg.u.tick = (ftm_wire_tick){.tick = tick, .depth = 8};
    rx.sender = 1;
    rx.seq = seq;
    assert_int_equal(ftm_replay_on_tick(r, &rx), FTM_OK);
    assert_int_equal(ftm_replay_state(r), FTM_WIRE_STATE_RESYNCING);
    assert_true(ftm_replay_tick(r) == want_tick);
}

static void test_forged_tick_jumps(void **state)
{
    (void)state;
    ftm_scene *sc = open_scene();
    fake_server s = fake_server_open(sc);
    ftm_replay *r = NULL;
    assert_int_equal(ftm_replay_create(sc, NULL, NULL, &r, NULL), FTM_OK);
    ftm_wire_keyframe k0;
    assert_int_equal(ftm_replay_make_keyframe(s.sim, NULL, &k0, NULL), FTM_OK);
    ftm_wire_received rx;
    ftm_contact store[4];
    int forged = 0;
    for (uint64_t t = 1; t <= 4000; t++) {
        if (!server_tick(&s, t, &rx, store))
            continue;
        assert_int_equal(ftm_replay_on_tick(r, &rx), FTM_OK);
        if (t == 1)
            assert_int_equal(ftm_replay_on_keyframe(r, &k0), FTM_OK);
        assert_int_equal(ftm_replay_state(r), FTM_WIRE_STATE_SYNCED);
        assert_true(ftm_replay_tick(r) == t);
        ftm_sim_stats st;
        ftm_sim_get_stats(ftm_replay_sim(r), &st);
        if (t == 100) { /* in contact: no tick may be left out after this one */
            assert_true(rx.msg.u.tick.contact_count > 0);
            forge_frame(r, t + 1000, ++s.seq, t);
        } else if (t == 230) { /* released, relaxing: an idle tick would move nodes */
            assert_true(rx.msg.u.tick.contact_count == 0 && st.updated_nodes > 0);
            forge_frame(r, t + 1000, ++s.seq, t + 1);
        } else if (t == 4000) { /* at rest: idle ticks are legitimate, but not this many */
            assert_true(st.updated_nodes == 0);
            forge_frame(r, t + 2000001, ++s.seq, t);
        } else {
            continue;
        }
        forged++;
        /* the server answers the resync with a keyframe of its tick */
        ftm_wire_keyframe k;
        assert_int_equal(ftm_replay_make_keyframe(s.sim, NULL, &k, NULL), FTM_OK);
        assert_int_equal(ftm_replay_on_keyframe(r, &k), FTM_OK);
        ftm_replay_keyframe_free(&k);
        assert_int_equal(ftm_replay_state(r), FTM_WIRE_STATE_SYNCED);
        assert_true(ftm_replay_hash(r) == ftm_sim_hash(s.sim));
    }
    assert_int_equal(forged, 3);
    ftm_replay_stats st;
    ftm_replay_get_stats(r, &st);
    assert_true(st.resyncs == 3 && st.rule_breaks == 3 && st.mismatches == 0 && st.gaps == 0);
    ftm_replay_keyframe_free(&k0);
    ftm_replay_destroy(r);
    ftm_sim_destroy(s.sim);
    ftm_scene_destroy(sc);
}

/* ---- tissue parameters (docs/protocol.md, "Tissue parameters") ---------------------- */

/* ftm_mesh_with_material: the same shape, masses and stiffness scaled, and
 * the scene's own material gives back the scene's numbers exactly. */
static void test_material_mesh(void **state)
{
    (void)state;
    ftm_scene *sc = open_scene();
    const ftm_mesh *m = ftm_scene_mesh(sc);
    ftm_material_def from = ftm_scene_material(sc), to = from;
    ftm_mesh *same = NULL, *stiff = NULL, *bad = NULL;
    ftm_error err = {0, ""};
    assert_int_equal(ftm_mesh_with_material(m, &from, &to, &same, &err), FTM_OK);
    to.stiffness *= 2.0;
    to.node_mass *= 4.0;
    to.node_damping *= 0.5;
    assert_int_equal(ftm_mesh_with_material(m, &from, &to, &stiff, &err), FTM_OK);
    assert_true(ftm_mesh_same_shape(m, same) && ftm_mesh_same_shape(m, stiff));
    for (int32_t i = 0; i < ftm_mesh_node_count(m); i++) {
        const int32_t *nb, *nb1, *nb2;
        const double *k, *k1, *k2, *l, *l1, *l2;
        int32_t d = ftm_mesh_neighbors(m, i, &nb, &k, &l);
        assert_int_equal(ftm_mesh_neighbors(same, i, &nb1, &k1, &l1), d);
        assert_int_equal(ftm_mesh_neighbors(stiff, i, &nb2, &k2, &l2), d);
        for (int32_t j = 0; j < d; j++) {
            assert_true(k1[j] == k[j]);
            assert_true(k2[j] == 2.0 * k[j]); /* both powers of two: exact */
        }
        assert_true(ftm_mesh_mass(same, i) == ftm_mesh_mass(m, i));
        assert_true(ftm_mesh_mass(stiff, i) == 4.0 * ftm_mesh_mass(m, i));
        assert_true(ftm_mesh_damping(stiff, i) == 0.5 * ftm_mesh_damping(m, i));
        assert_int_equal(ftm_mesh_input_of_node(stiff, i), ftm_mesh_input_of_node(m, i));
    }
    /* anisotropic: an x-axis link gets the x factor exactly, and every
     * link's two adjacency entries carry the link's own stiffness */
    ftm_material_def ax = from;
    ax.axis_scale.x = 4.0;
    ftm_mesh *aniso = NULL;
    assert_int_equal(ftm_mesh_with_material(m, &from, &ax, &aniso, &err), FTM_OK);
    int32_t along_x = 0;
    for (int32_t l = 0; l < ftm_mesh_link_count(m); l++) {
        int32_t a, b;
        double k0, k1, l0, l1;
        ftm_mesh_link(m, l, &a, &b, &k0, &l0);
        ftm_mesh_link(aniso, l, &a, &b, &k1, &l1);
        ftm_vec3 pa = ftm_mesh_rest_position(m, a), pb = ftm_mesh_rest_position(m, b);
        if (pa.y == pb.y && pa.z == pb.z) {
            assert_true(k1 == 4.0 * k0);
            along_x++;
        }
        for (int end = 0; end < 2; end++) {
            const int32_t *nb;
            const double *k, *len;
            int32_t from_node = end ? b : a, to_node = end ? a : b;
            int32_t d = ftm_mesh_neighbors(aniso, from_node, &nb, &k, &len);
            int32_t j = 0;
            while (j < d && nb[j] != to_node)
                j++;
            assert_true(j < d && k[j] == k1);
        }
    }
    assert_true(along_x > 0);
    ftm_mesh_destroy(aniso);
    to.axis_scale.y = -1.0;
    assert_int_equal(ftm_mesh_with_material(m, &from, &to, &bad, &err), FTM_EINVAL);
    assert_non_null(strstr(err.message, "axis stiffness scale y"));
    assert_null(bad);
    ftm_mesh_destroy(same);
    ftm_mesh_destroy(stiff);
    ftm_scene_destroy(sc);
}

/* Pushes node `top` of a simulation with a constant force until it rests;
 * returns its displacement along z. */
static double settle(ftm_sim *sim, int32_t top, double fz)
{
    ftm_contact c = {top, 0, FTM_CONTACT_FORCE, {0, 0, fz}};
    for (int i = 0; i < 4000; i++)
        assert_int_equal(ftm_replay_step(sim, 8, &c, 1, NULL), FTM_OK);
    return ftm_sim_position(sim, top).z - ftm_mesh_rest_position(ftm_sim_mesh(sim), top).z;
}

/* The physics follows: twice the stiffness, half the static displacement;
 * a change mid-simulation settles where a fresh run with that material does. */
static void tissue_physics(ftm_order order)
{
    ftm_scene *sc = open_scene();
    ftm_sim_def def = ftm_replay_sim_def(sc);
    def.order = order; /* both vector kernels keep copies of link stiffness */
    ftm_sim *a = NULL, *b = NULL;
    assert_int_equal(ftm_sim_create(ftm_scene_mesh(sc), &def, &a, NULL), FTM_OK);
    assert_int_equal(ftm_sim_create(ftm_scene_mesh(sc), &def, &b, NULL), FTM_OK);
    int32_t top = ftm_mesh_node_of_input(ftm_scene_mesh(sc), 1662);
    double ua = settle(a, top, -0.02);
    ftm_replay_material mat = {.scene = sc};
    ftm_wire_tissue t = ftm_replay_scene_tissue(sc);
    t.stiffness *= 2.0;
    ftm_error err = {0, ""};
    assert_int_equal(ftm_replay_set_tissue(&mat, b, &t, &err), FTM_OK);
    assert_true(mat.changed);
    double ub = settle(b, top, -0.02);
    assert_true(ua < 0.0);
    if (!(fabs(ub / ua - 0.5) < 0.01))
        fail_msg("displacement %g (k) vs %g (2k): ratio %g, want 0.5", ua, ub, ub / ua);
    /* a, already loaded, made stiffer now: it comes to b's rest state */
    ftm_replay_material mat_a = {.scene = sc};
    assert_int_equal(ftm_replay_set_tissue(&mat_a, a, &t, &err), FTM_OK);
    double ua2 = settle(a, top, -0.02);
    if (!(fabs(ua2 - ub) <= 1e-9 * fabs(ub)))
        fail_msg("changed mid-run: %.12g, fresh: %.12g", ua2, ub);
    /* back to the scene's own material: the scene's mesh again */
    assert_int_equal(ftm_replay_set_tissue(&mat_a, a, NULL, &err), FTM_OK);
    assert_false(mat_a.changed);
    assert_true(ftm_sim_mesh(a) == ftm_scene_mesh(sc));
    /* refused, nothing changed: far too stiff for the time step, and invalid */
    uint64_t h = ftm_sim_hash(b);
    ftm_wire_tissue hard = t;
    hard.stiffness *= 1e9;
    assert_int_equal(ftm_replay_set_tissue(&mat, b, &hard, &err), FTM_EINVAL);
    assert_non_null(strstr(err.message, "critical time step"));
    ftm_wire_tissue neg = t;
    neg.node_mass = -1.0;
    assert_int_equal(ftm_replay_set_tissue(&mat, b, &neg, &err), FTM_EINVAL);
    assert_non_null(strstr(err.message, "node mass"));
    assert_true(ftm_sim_hash(b) == h);
    assert_true(ftm_replay_tissue_now(&mat).stiffness == t.stiffness);
    ftm_sim_destroy(a);
    ftm_sim_destroy(b);
    ftm_replay_material_free(&mat);
    ftm_replay_material_free(&mat_a);
    ftm_scene_destroy(sc);
}

static void test_tissue_physics(void **state)
{
    (void)state;
    tissue_physics(FTM_ORDER_LAYER_COLORED);
    tissue_physics(FTM_ORDER_LAYER_JACOBI);
}

/* The stable range (session/tissue.h): the default scene's stiffness goes as
 * far as half the layer update's damping bound allows at d = 0.3 N s/m
 * (0.198 N s/m at 50 N/m, so about 151 N/m) and, damped more, as far as two
 * substeps of its 1 ms step (h_crit = 1.49 ms at 50 N/m, so about 444 N/m);
 * the instructor's 50 -> 80 N/m is in range, on springs and on the palpation
 * scene's neo-Hookean elements (a factor 1.6 on E, no damping bound). */
static void range_of(const char *name, double *k_max, double *stiffer_ok)
{
    ftm_scene *sc = NULL;
    ftm_error err = {0, ""};
    if (ftm_scene_builtin(name, &sc, &err))
        fail_msg("%s", err.message);
    ftm_sim *sim = NULL;
    ftm_sim_def def = ftm_replay_sim_def(sc);
    assert_int_equal(ftm_sim_create(ftm_scene_mesh(sc), &def, &sim, &err), FTM_OK);
    ftm_replay_material mat = {.scene = sc};
    ftm_tissue_range r;
    assert_int_equal(ftm_replay_tissue_range(&mat, sim, NULL, &r, &err), FTM_OK);
    assert_int_equal(r.substeps, 1);
    assert_int_equal(r.max_substeps, FTM_TISSUE_MAX_SUBSTEPS);
    *k_max = r.stiffness_max;
    ftm_wire_tissue t = ftm_replay_scene_tissue(sc);
    char why[128];
    /* 50 * 1.6 = 80: in range; switched to, the range is the same */
    t.stiffness *= 1.6;
    t.node_damping = 0.33;
    assert_int_equal(ftm_replay_tissue_check(&mat, sim, &t, &r, why, sizeof why, &err), FTM_OK);
    *stiffer_ok = r.stiffness_max;
    assert_int_equal(ftm_replay_set_tissue(&mat, sim, &t, &err), FTM_OK);
    ftm_tissue_range r2;
    assert_int_equal(ftm_replay_tissue_range(&mat, sim, NULL, &r2, &err), FTM_OK);
    assert_true(fabs(r2.stiffness_max - r.stiffness_max) <= 1e-9 * r.stiffness_max);
    /* just past the range: refused, naming it */
    t.stiffness = r.stiffness_max * 1.01;
    assert_int_equal(ftm_replay_tissue_check(&mat, sim, &t, &r, why, sizeof why, &err), FTM_ERANGE);
    assert_non_null(strstr(why, "past the stable range"));
    assert_true(strlen(why) < 128);
    t.stiffness = r2.stiffness_max * 0.99;
    assert_int_equal(ftm_replay_tissue_check(&mat, sim, &t, &r, why, sizeof why, &err), FTM_OK);
    /* the scene's own tissue is always in range */
    ftm_wire_tissue own = ftm_replay_scene_tissue(sc);
    assert_int_equal(ftm_replay_tissue_check(&mat, sim, &own, NULL, why, sizeof why, &err), FTM_OK);
    ftm_sim_destroy(sim);
    ftm_replay_material_free(&mat);
    ftm_scene_destroy(sc);
}

static void test_tissue_range(void **state)
{
    (void)state;
    double k_max, k_max80;
    range_of("default", &k_max, &k_max80);
    if (!(k_max > 145.0 && k_max < 158.0))
        fail_msg("default scene: stiffness range up to %g N/m, want about 151", k_max);
    range_of("palpation", &k_max, &k_max80);
    if (!(k_max > 80.0))
        fail_msg("palpation: stiffness range up to %g N/m, want above 80", k_max);
    /* the range around 80 N/m with damping 0.33: springs' damping bound
     * (0.11 m lambda h = 0.317 N s/m at 80 N/m, docs/core.md) */
    ftm_scene *sc = open_scene();
    ftm_sim *sim = NULL;
    ftm_sim_def def = ftm_replay_sim_def(sc);
    assert_int_equal(ftm_sim_create(ftm_scene_mesh(sc), &def, &sim, NULL), FTM_OK);
    ftm_replay_material mat = {.scene = sc};
    ftm_wire_tissue t = ftm_replay_scene_tissue(sc);
    t.stiffness = 80.0;
    ftm_tissue_range r;
    ftm_error err = {0, ""};
    assert_int_equal(ftm_replay_tissue_range(&mat, sim, &t, &r, &err), FTM_OK);
    if (!(r.damping_bound > 0.30 && r.damping_bound < 0.33))
        fail_msg("damping bound at 80 N/m: %g N s/m, want about 0.317", r.damping_bound);
    assert_true(r.damping_min == FTM_TISSUE_DAMPING_SHARE * r.damping_bound);
    /* damped well, the substeps bound it: h_crit = 1.49 ms (docs/core.md),
     * k_max = 50 (2 x 1.49 / 1)^2 */
    t.node_damping = 10.0;
    assert_int_equal(ftm_replay_tissue_range(&mat, sim, &t, &r, &err), FTM_OK);
    if (!(r.stiffness_max > 420.0 && r.stiffness_max < 470.0))
        fail_msg("stiffness range at d = 10: up to %g N/m, want about 444", r.stiffness_max);
    t.stiffness = r.stiffness_max * 1.01;
    char why[128];
    assert_int_equal(ftm_replay_tissue_check(&mat, sim, &t, &r, why, sizeof why, &err), FTM_ERANGE);
    assert_int_equal(r.substeps, 4);
    assert_non_null(strstr(why, "needs 4 substeps of 0.001 s, at most 2"));
    t.stiffness = 400.0;
    assert_int_equal(ftm_replay_tissue_check(&mat, sim, &t, &r, why, sizeof why, &err), FTM_OK);
    assert_int_equal(r.substeps, 2);
    /* too little damping at the scene's stiffness: damping named */
    t = ftm_replay_scene_tissue(sc);
    t.node_damping = 0.05;
    assert_int_equal(ftm_replay_tissue_check(&mat, sim, &t, NULL, why, sizeof why, &err), FTM_ERANGE);
    assert_non_null(strstr(why, "damping 0.05 N s/m is below the stable range"));
    t.node_damping = 0.0; /* undamped: below any bound */
    assert_int_equal(ftm_replay_tissue_check(&mat, sim, &t, NULL, why, sizeof why, &err), FTM_ERANGE);
    assert_non_null(strstr(why, "damping 0 N s/m is below the stable range"));
    /* a lighter node: the mass is named when it alone leaves the range */
    assert_int_equal(ftm_replay_tissue_range(&mat, sim, NULL, &r, &err), FTM_OK);
    t = ftm_replay_scene_tissue(sc);
    t.node_mass = r.mass_min * 0.5;
    assert_int_equal(ftm_replay_tissue_check(&mat, sim, &t, NULL, why, sizeof why, &err), FTM_ERANGE);
    assert_non_null(strstr(why, "node mass"));
    ftm_sim_destroy(sim);
    ftm_scene_destroy(sc);
}

/* ftm_sim_set_mesh refuses what it cannot honour, changing nothing. */
static void test_set_mesh_refusals(void **state)
{
    (void)state;
    ftm_scene *sc = open_scene(), *other = NULL;
    assert_int_equal(ftm_scene_builtin("membrane", &other, NULL), FTM_OK);
    ftm_sim_def def = ftm_replay_sim_def(sc);
    ftm_sim *sim = NULL;
    ftm_error err = {0, ""};
    assert_int_equal(ftm_sim_create(ftm_scene_mesh(sc), &def, &sim, NULL), FTM_OK);
    assert_int_equal(ftm_sim_set_mesh(sim, ftm_scene_mesh(other), &err), FTM_EINVAL);
    assert_non_null(strstr(err.message, "differs in shape"));
    assert_true(ftm_sim_mesh(sim) == ftm_scene_mesh(sc));
    ftm_sim_destroy(sim);
    /* element forces: a stiffness change is a factor on E; a change the
     * elements cannot take (links by different factors, masses that the
     * density gives) is refused, changing nothing */
    def.forces = FTM_FORCES_LINEAR_FEM;
    def.young = 3e3;
    def.poisson = 0.45;
    def.density = 1000;
    assert_int_equal(ftm_sim_create(ftm_scene_mesh(sc), &def, &sim, &err), FTM_OK);
    ftm_replay_material mat = {.scene = sc};
    ftm_wire_tissue t = ftm_replay_scene_tissue(sc);
    t.axis_scale.z *= 2.0;
    assert_int_equal(ftm_replay_set_tissue(&mat, sim, &t, &err), FTM_EINVAL);
    assert_non_null(strstr(err.message, "one factor on E"));
    assert_false(mat.changed);
    assert_null(mat.mesh);
    t = ftm_replay_scene_tissue(sc);
    t.node_mass *= 2.0;
    assert_int_equal(ftm_replay_set_tissue(&mat, sim, &t, &err), FTM_EINVAL);
    assert_non_null(strstr(err.message, "density"));
    assert_false(mat.changed);
    t = ftm_replay_scene_tissue(sc);
    t.stiffness *= 2.0;
    assert_int_equal(ftm_replay_set_tissue(&mat, sim, &t, &err), FTM_OK);
    assert_true(mat.changed);
    assert_true(ftm_sim_mesh(sim) == mat.mesh);
    ftm_sim_destroy(sim);
    ftm_replay_material_free(&mat);
    ftm_scene_destroy(sc);
    ftm_scene_destroy(other);
}

/* The server's keyframe of its current state, to a replica. */
static void give_keyframe(ftm_replay *r, const ftm_sim *srv, const ftm_replay_material *mat)
{
    ftm_wire_keyframe k;
    assert_int_equal(ftm_replay_make_keyframe(srv, mat, &k, NULL), FTM_OK);
    assert_int_equal(ftm_replay_on_keyframe(r, &k), FTM_OK);
    ftm_replay_keyframe_free(&k);
}

/* A replica switches at the frame that carries the parameters; one that lost
 * that frame resyncs from a keyframe carrying them; a late joiner starts from
 * such a keyframe. Every hash equals the server's. */
static void test_tissue_replica(void **state)
{
    (void)state;
    ftm_scene *sc = open_scene();
    fake_server s = fake_server_open(sc);
    ftm_replay_material mat = {.scene = sc};
    ftm_replay *r = NULL, *lossy = NULL, *late = NULL;
    assert_int_equal(ftm_replay_create(sc, NULL, NULL, &r, NULL), FTM_OK);
    assert_int_equal(ftm_replay_create(sc, NULL, NULL, &lossy, NULL), FTM_OK);
    assert_int_equal(ftm_replay_create(sc, NULL, NULL, &late, NULL), FTM_OK);
    ftm_wire_keyframe k0;
    assert_int_equal(ftm_replay_make_keyframe(s.sim, NULL, &k0, NULL), FTM_OK);
    ftm_wire_tissue soft = ftm_replay_scene_tissue(sc), stiff = soft;
    soft.stiffness *= 0.5;
    soft.node_damping *= 1.5;
    stiff.stiffness *= 3.0;
    const uint64_t change1 = 80, change2 = 400, join = 600;
    ftm_wire_received rx;
    ftm_contact store[4];
    bool lossy_gap = false;
    uint64_t h200 = 0;
    for (uint64_t t = 1; t <= 1200; t++) {
        if (t == 201)
            h200 = ftm_sim_hash(s.sim);
        const ftm_wire_tissue *nt = t == change1 ? &soft : t == change2 ? &stiff : NULL;
        if (nt) /* between ticks t-1 and t, as the server does on a command */
            assert_int_equal(ftm_replay_set_tissue(&mat, s.sim, nt, NULL), FTM_OK);
        if (!server_tick(&s, t, &rx, store) && !nt)
            continue;
        if (nt) { /* the tick of a change is always sent */
            if (rx.msg.kind != FTM_WIRE_TICK) {
                memset(&rx, 0, sizeof rx);
                rx.msg.kind = FTM_WIRE_TICK;
                rx.msg.u.tick =
                    (ftm_wire_tick){.tick = t, .depth = 8, .state_hash = ftm_sim_hash(s.sim)};
                rx.sender = 1;
                rx.seq = ++s.seq;
            }
            rx.msg.u.tick.has_tissue = true;
            rx.msg.u.tick.tissue = *nt;
        }
        assert_int_equal(ftm_replay_on_tick(r, &rx), FTM_OK);
        if (t == 1) {
            assert_int_equal(ftm_replay_on_keyframe(r, &k0), FTM_OK);
            assert_int_equal(ftm_replay_on_keyframe(lossy, &k0), FTM_OK);
        }
        if (t == change2) { /* lossy never sees this frame */
            lossy_gap = true;
        } else {
            ftm_wire_received rl = rx;
            rl.gap = lossy_gap ? 1 : 0;
            assert_int_equal(ftm_replay_on_tick(lossy, &rl), FTM_OK);
            if (lossy_gap) {
                lossy_gap = false;
                assert_int_equal(ftm_replay_state(lossy), FTM_WIRE_STATE_RESYNCING);
                give_keyframe(lossy, s.sim, &mat);
            }
            assert_int_equal(ftm_replay_state(lossy), FTM_WIRE_STATE_SYNCED);
            assert_true(ftm_replay_hash(lossy) == ftm_sim_hash(s.sim));
        }
        if (t >= join) {
            assert_int_equal(ftm_replay_on_tick(late, &rx), FTM_OK);
            if (t == join) {
                give_keyframe(late, s.sim, &mat);
            }
            assert_int_equal(ftm_replay_state(late), FTM_WIRE_STATE_SYNCED);
            assert_true(ftm_replay_hash(late) == ftm_sim_hash(s.sim));
            assert_true(ftm_replay_tissue(late).stiffness == stiff.stiffness);
        }
        assert_int_equal(ftm_replay_state(r), FTM_WIRE_STATE_SYNCED);
        if (ftm_replay_hash(r) != ftm_sim_hash(s.sim))
            fail_msg("tick %llu: replica hash differs", (unsigned long long)t);
        rx.msg.kind = 0;
    }
    assert_true(ftm_replay_tissue(r).stiffness == stiff.stiffness);
    assert_true(ftm_replay_tissue(lossy).stiffness == stiff.stiffness);
    /* and the frames really differ from a run that ignores the change */
    ftm_sim *plain = NULL;
    ftm_sim_def def = ftm_replay_sim_def(sc);
    assert_int_equal(ftm_sim_create(s.m, &def, &plain, NULL), FTM_OK);
    ftm_contact c[4];
    for (uint64_t t = 1; t <= 200; t++)
        assert_int_equal(ftm_replay_step(plain, 8, c, contacts_at(s.m, t, c), NULL), FTM_OK);
    assert_true(h200 != 0 && ftm_sim_hash(plain) != h200);
    ftm_replay_stats st;
    ftm_replay_get_stats(r, &st);
    assert_true(st.mismatches == 0 && st.resyncs == 0);
    ftm_sim_destroy(plain);
    ftm_replay_keyframe_free(&k0);
    ftm_replay_destroy(r);
    ftm_replay_destroy(lossy);
    ftm_replay_destroy(late);
    ftm_sim_destroy(s.sim);
    ftm_replay_material_free(&mat);
    ftm_scene_destroy(sc);
}

/* ---- region sleep in a session ------------------------------------------------------- */

static const char sleepy_scene[] = "[scene]\nname = sleepy\n[mesh]\ngenerator = lattice3d\n"
                                   "nx = 8\nny = 8\nnz = 8\nspacing = 0.01\nstencil = 18\n"
                                   "fixed_faces = zmin\n[material]\nmass = 0.001\n"
                                   "damping = 0.3\nstiffness = 50\n[sim]\ntime_step = 1e-3\n"
                                   "depth = 6\nregion_sleep_steps = 20\n";

/* A scene whose contact region sleeps under a held load: the region falls
 * asleep on the server and on a replica alike; a replica that joins from a
 * keyframe taken while it sleeps (contacts and mode carried) continues
 * bit-identically through the wake-up, the release and the relaxation. */
static void test_region_sleep_session(void **state)
{
    (void)state;
    ftm_scene *sc = NULL;
    ftm_error err = {0, ""};
    if (ftm_scene_parse(sleepy_scene, sizeof sleepy_scene - 1, "sleepy", &sc, &err))
        fail_msg("%s", err.message);
    const ftm_mesh *m = ftm_scene_mesh(sc);
    ftm_sim_def def = ftm_replay_sim_def(sc);
    assert_int_equal(def.region_sleep_steps, 20);
    ftm_sim *srv = NULL;
    assert_int_equal(ftm_sim_create(m, &def, &srv, NULL), FTM_OK);
    ftm_replay *early = NULL, *late = NULL;
    assert_int_equal(ftm_replay_create(sc, NULL, NULL, &early, NULL), FTM_OK);
    assert_int_equal(ftm_replay_create(sc, NULL, NULL, &late, NULL), FTM_OK);
    ftm_wire_keyframe k0;
    assert_int_equal(ftm_replay_make_keyframe(srv, NULL, &k0, NULL), FTM_OK);
    int32_t top = ftm_mesh_node_of_input(m, 3 + 8 * (3 + 8 * 7));
    int32_t side = ftm_mesh_node_of_input(m, 4 + 8 * (3 + 8 * 7));
    uint64_t seq = 0, slept_at = 0, late_at = 0;
    bool late_joined = false;
    for (uint64_t t = 1; t <= 3000; t++) {
        /* press and hold; a second contact at 1200 wakes the region; release at 1800 */
        ftm_contact c[2] = {{top, 0, FTM_CONTACT_DISPLACEMENT, {0, 0, -0.003}},
                            {side, 0, FTM_CONTACT_DISPLACEMENT, {0, 0, -0.002}}};
        int32_t n = t > 1800 ? 0 : t > 1200 ? 2 : 1;
        assert_int_equal(ftm_replay_step(srv, 6, c, n, NULL), FTM_OK);
        ftm_sim_stats st;
        ftm_sim_get_stats(srv, &st);
        if (st.region_sleeping && !slept_at)
            slept_at = t;
        ftm_wire_received rx;
        memset(&rx, 0, sizeof rx);
        rx.msg.kind = FTM_WIRE_TICK;
        rx.msg.u.tick = (ftm_wire_tick){
            .tick = t, .depth = 6, .contact_count = n, .contacts = c, .state_hash = ftm_sim_hash(srv)};
        rx.sender = 1;
        rx.seq = ++seq;
        assert_int_equal(ftm_replay_on_tick(early, &rx), FTM_OK);
        if (t == 1)
            assert_int_equal(ftm_replay_on_keyframe(early, &k0), FTM_OK);
        /* the late replica joins once the region has slept for a while */
        if (slept_at && t >= slept_at + 100 && !late_joined) {
            assert_true(st.region_sleeping);
            rx.gap = 0;
            assert_int_equal(ftm_replay_on_tick(late, &rx), FTM_OK);
            ftm_wire_keyframe k;
            assert_int_equal(ftm_replay_make_keyframe(srv, NULL, &k, NULL), FTM_OK);
            assert_int_equal(k.contact_count, 1);
            assert_true(k.has_mode && k.mode.region_sleeping);
            assert_int_equal(ftm_replay_on_keyframe(late, &k), FTM_OK);
            ftm_replay_keyframe_free(&k);
            late_joined = true;
            late_at = t;
        } else if (late_joined) {
            assert_int_equal(ftm_replay_on_tick(late, &rx), FTM_OK);
        }
        assert_int_equal(ftm_replay_state(early), FTM_WIRE_STATE_SYNCED);
        if (ftm_replay_hash(early) != ftm_sim_hash(srv))
            fail_msg("tick %llu: the early replica differs", (unsigned long long)t);
        if (late_joined) {
            assert_int_equal(ftm_replay_state(late), FTM_WIRE_STATE_SYNCED);
            if (ftm_replay_hash(late) != ftm_sim_hash(srv))
                fail_msg("tick %llu: the late replica (joined at %llu) differs", (unsigned long long)t,
                         (unsigned long long)late_at);
            ftm_sim_stats ls;
            ftm_sim_get_stats(ftm_replay_sim(late), &ls);
            assert_int_equal(ls.region_sleeping, st.region_sleeping);
        }
    }
    assert_true(slept_at > 0 && slept_at < 1200 && late_joined);
    ftm_replay_keyframe_free(&k0);
    ftm_replay_destroy(early);
    ftm_replay_destroy(late);
    ftm_sim_destroy(srv);
    ftm_scene_destroy(sc);
}

static void test_sha256(void **state)
{
    (void)state;
    uint8_t d[32];
    ftm_sha256("abc", 3, d);
    static const uint8_t want[32] = {0xba, 0x78, 0x16, 0xbf, 0x8f, 0x01, 0xcf, 0xea,
                                     0x41, 0x41, 0x40, 0xde, 0x5d, 0xae, 0x22, 0x23,
                                     0xb0, 0x03, 0x61, 0xa3, 0x96, 0x17, 0x7a, 0x9c,
                                     0xb4, 0x10, 0xff, 0x61, 0xf2, 0x00, 0x15, 0xad};
    assert_memory_equal(d, want, 32);
    const char *two = "abcdbcdecdefdefgefghfghighijhijkijkljklmklmnlmnomnopnopq";
    ftm_sha256(two, strlen(two), d);
    assert_true(d[0] == 0x24 && d[1] == 0x8d && d[31] == 0xc1);
    ftm_scene *a = open_scene(), *b = NULL;
    assert_int_equal(ftm_scene_builtin("membrane", &b, NULL), FTM_OK);
    uint8_t da[32], da2[32], db[32];
    ftm_replay_scene_digest(a, da);
    ftm_replay_scene_digest(a, da2);
    ftm_replay_scene_digest(b, db);
    assert_memory_equal(da, da2, 32);
    assert_memory_not_equal(da, db, 32);
    ftm_scene_destroy(a);
    ftm_scene_destroy(b);
}

/* Sliding nodes and springs to ground are part of the scene: a recording
 * of one does not replay on the scene without them. */
static void test_digest_constraints(void **state)
{
    (void)state;
    static const char *const texts[] = {
        "[mesh]\ngenerator = lattice3d\nnx = 3\nny = 3\nnz = 3\nspacing = 0.01\n"
        "[material]\nmass = 0.001\nstiffness = 50\n",
        "[mesh]\ngenerator = lattice3d\nnx = 3\nny = 3\nnz = 3\nspacing = 0.01\n"
        "ground_springs = 10 : 26\n[material]\nmass = 0.001\nstiffness = 50\n",
        "[mesh]\ngenerator = lattice3d\nnx = 3\nny = 3\nnz = 3\nspacing = 0.01\n"
        "ground_springs = 11 : 26\n[material]\nmass = 0.001\nstiffness = 50\n",
        "[mesh]\ngenerator = lattice3d\nnx = 3\nny = 3\nnz = 3\nspacing = 0.01\n"
        "slide_nodes = x : 26\n[material]\nmass = 0.001\nstiffness = 50\n",
        "[mesh]\ngenerator = lattice3d\nnx = 3\nny = 3\nnz = 3\nspacing = 0.01\n"
        "slide_nodes = y : 26\n[material]\nmass = 0.001\nstiffness = 50\n",
    };
    uint8_t d[5][32];
    for (int i = 0; i < 5; i++) {
        ftm_scene *sc = NULL;
        ftm_error err;
        assert_int_equal(ftm_scene_parse(texts[i], strlen(texts[i]), "c.scene", &sc, &err), FTM_OK);
        ftm_replay_scene_digest(sc, d[i]);
        ftm_scene_destroy(sc);
        for (int j = 0; j < i; j++)
            assert_memory_not_equal(d[i], d[j], 32);
    }
}

/* [fem] mass_scaling changes the masses, so two scenes that differ in it
 * alone have different digests. */
static void test_digest_mass_scaling(void **state)
{
    (void)state;
    static const char *const texts[] = {
        "[mesh]\ngenerator = lattice3d\nnx = 3\nny = 3\nnz = 3\nspacing = 0.01\n"
        "[material]\nmass = 0.001\nstiffness = 50\n[sim]\nforces = linear-fem\n"
        "[fem]\nyoung = 1e4\npoisson = 0.3\ndensity = 1000\n",
        "[mesh]\ngenerator = lattice3d\nnx = 3\nny = 3\nnz = 3\nspacing = 0.01\n"
        "[material]\nmass = 0.001\nstiffness = 50\n[sim]\nforces = linear-fem\n"
        "[fem]\nyoung = 1e4\npoisson = 0.3\ndensity = 1000\nmass_scaling = on\n",
    };
    uint8_t d[2][32];
    for (int i = 0; i < 2; i++) {
        ftm_scene *sc = NULL;
        ftm_error err;
        assert_int_equal(ftm_scene_parse(texts[i], strlen(texts[i]), "m.scene", &sc, &err), FTM_OK);
        ftm_replay_scene_digest(sc, d[i]);
        ftm_scene_destroy(sc);
    }
    assert_memory_not_equal(d[0], d[1], 32);
}

/* An announcement is checked against this build's arithmetic first: a
 * server of another revision (or of none: revision 1, from before the
 * field) is refused with FTM_EVERSION, whatever its scene. */
static void test_announce_arithmetic(void **state)
{
    (void)state;
    ftm_scene *sc = open_scene();
    ftm_replay *r = NULL;
    assert_int_equal(ftm_replay_create(sc, NULL, NULL, &r, NULL), FTM_OK);
    ftm_wire_announce a;
    memset(&a, 0, sizeof a);
    snprintf(a.scene_id, sizeof a.scene_id, "default");
    ftm_replay_scene_digest(sc, a.digest);
    a.digest_len = FTM_REPLAY_DIGEST_SIZE;
    a.node_count = ftm_mesh_node_count(ftm_scene_mesh(sc));
    a.time_step = ftm_replay_sim_def(sc).time_step;
    a.arithmetic = ftm_arithmetic_revision();
    ftm_error err = {0, ""};
    assert_int_equal(ftm_replay_check_announce(r, &a, &err), FTM_OK);
    static const uint32_t other[3] = {0, 1, FTM_ARITHMETIC_REVISION + 1};
    for (int i = 0; i < 3; i++) {
        a.arithmetic = other[i];
        err.message[0] = '\0';
        assert_int_equal(ftm_replay_check_announce(r, &a, &err), FTM_EVERSION);
        assert_int_equal(err.code, FTM_EVERSION);
        char want[96];
        snprintf(want, sizeof want, "arithmetic revision %u, this build's of revision %u",
                 other[i] ? other[i] : 1u, FTM_ARITHMETIC_REVISION);
        assert_non_null(strstr(err.message, want));
    }
    /* the same revision, another scene: the scene's mismatch */
    a.arithmetic = ftm_arithmetic_revision();
    a.node_count++;
    assert_int_equal(ftm_replay_check_announce(r, &a, &err), FTM_EINVAL);
    assert_non_null(strstr(err.message, "node count differs"));
    ftm_replay_destroy(r);
    ftm_scene_destroy(sc);
}

/* Our id is held only when a server's status lists it with our origin
 * among its holders: not from another role, not with another origin, not
 * from a status without the list (a server from before it) and not from
 * one that merely does not list us as ignored. */
static void test_id_held(void **state)
{
    (void)state;
    ftm_wire_status st;
    memset(&st, 0, sizeof st);
    st.participant = 1;
    st.role = FTM_WIRE_ROLE_SERVER;
    assert_false(ftm_replay_id_held(&st, 35, 0xabc)); /* no list at all */
    st.holder_count = 2;
    st.holder_participant[0] = 11;
    st.holder_origin[0] = 0xabc;
    st.holder_participant[1] = 35;
    st.holder_origin[1] = 0xdef;
    assert_false(ftm_replay_id_held(&st, 35, 0xabc)); /* another process holds 35 */
    assert_true(ftm_replay_id_held(&st, 35, 0xdef));
    assert_true(ftm_replay_id_held(&st, 11, 0xabc));
    assert_false(ftm_replay_id_held(&st, 12, 0xabc));
    st.role = FTM_WIRE_ROLE_TRAINEE; /* only the server's word counts */
    assert_false(ftm_replay_id_held(&st, 35, 0xdef));
}


/* Several tissues in one body (scene [fem LABEL] with a density and
 * [material LABEL]): the server's simulation and a replica made from the
 * same scene stay bit-identical under a press, with co-rotational and
 * neo-Hookean forces per label and the elastic far field; an instructor's
 * stiffness change applies to both; the scene digest tells the scene
 * from the one without its [fem LABEL]. */
static const char labelled_msh[] =
    "$MeshFormat\n4.1 0 8\n$EndMeshFormat\n"
    "$Entities\n0 0 0 2\n"
    "1 0 0 0 1 1 1 1 5 0\n2 1 0 0 2 1 1 1 9 0\n$EndEntities\n"
    "$Nodes\n1 12 1 12\n3 1 0 12\n1\n2\n3\n4\n5\n6\n7\n8\n9\n10\n11\n12\n"
    "0 0 0\n0.01 0 0\n0.02 0 0\n0 0.01 0\n0.01 0.01 0\n0.02 0.01 0\n"
    "0 0 0.01\n0.01 0 0.01\n0.02 0 0.01\n0 0.01 0.01\n0.01 0.01 0.01\n0.02 0.01 0.01\n"
    "$EndNodes\n"
    "$Elements\n2 2 1 2\n3 1 5 1\n1 1 2 5 4 7 8 11 10\n3 2 5 1\n2 2 3 6 5 8 9 12 11\n"
    "$EndElements\n";

/* fem_label: with [fem 9] (the same [material 9] either way) */
static ftm_scene *labelled_scene(const char *path, const char *forces, bool fem_label)
{
    char text[1024];
    snprintf(text, sizeof text,
             "[mesh]\nfile = %s\nfixed_box = -0.001 -0.001 -0.001 0.001 0.011 0.011\n"
             "[material]\nmass = 0.0005\nstiffness = 200\ndamping = 0.05\n"
             "[sim]\ntime_step = 1e-4\n%s\n"
             "[fem]\nyoung = 3e3\npoisson = 0.4\ndensity = 1000\n%s",
             path, forces,
             fem_label ? "[material 9]\nstiffness = 800\n"
                         "[fem 9]\nyoung = 1.2e4\npoisson = 0.3\ndensity = 1100\n"
                       : "[material 9]\nstiffness = 800\n");
    ftm_scene *sc = NULL;
    ftm_error err = {0, ""};
    if (ftm_scene_parse(text, strlen(text), "labelled.scene", &sc, &err))
        fail_msg("%s", err.message);
    return sc;
}

static void test_labelled_replica(void **state)
{
    (void)state;
    char dir[] = "/tmp/ftm-test-labelled-XXXXXX", path[64];
    assert_non_null(mkdtemp(dir));
    snprintf(path, sizeof path, "%s/bar.msh", dir);
    FILE *f = fopen(path, "w");
    assert_non_null(f);
    fputs(labelled_msh, f);
    fclose(f);
    setenv("FTM_CACHE_DIR", "", 1); /* the far field's precomputation: no cache file */
    const char *forces[] = {"forces = corot-fem", "forces = neo-hookean",
                            "forces = corot-fem\nfar_field = elastic\ndepth = 1"};
    for (size_t k = 0; k < sizeof forces / sizeof forces[0]; k++) {
        ftm_scene *sc = labelled_scene(path, forces[k], true), *plain =
            labelled_scene(path, forces[k], false);
        uint8_t da[32], db[32];
        ftm_replay_scene_digest(sc, da);
        ftm_replay_scene_digest(plain, db);
        assert_memory_not_equal(da, db, 32);
        ftm_sim_def def = ftm_replay_sim_def(sc);
        assert_int_equal(def.label_material_count, 1);
        const ftm_mesh *m = ftm_scene_mesh(sc);
        ftm_sim *server = NULL;
        ftm_error err = {0, ""};
        if (ftm_sim_create(m, &def, &server, &err))
            fail_msg("%s: %s", forces[k], err.message);
        ftm_replay *r = NULL;
        if (ftm_replay_create(sc, NULL, NULL, &r, &err))
            fail_msg("%s: %s", forces[k], err.message);
        ftm_wire_keyframe k0;
        assert_int_equal(ftm_replay_make_keyframe(server, NULL, &k0, NULL), FTM_OK);
        ftm_replay_material mat = {.scene = sc};
        ftm_contact c[2], store[2];
        int32_t tip[2] = {-1, -1}, nt = 0;
        for (int32_t i = 0; i < ftm_mesh_node_count(m) && nt < 2; i++)
            if (ftm_mesh_rest_position(m, i).x > 0.015 && ftm_mesh_rest_position(m, i).z > 0.005)
                tip[nt++] = i;
        assert_int_equal(nt, 2);
        uint64_t seq = 0;
        for (uint64_t t = 1; t <= 600; t++) {
            const double d = -0.001 * (double)(t < 200 ? t : 200) / 200.0;
            int32_t n = 0;
            if (t <= 400) {
                c[n++] = (ftm_contact){tip[0], 0, FTM_CONTACT_DISPLACEMENT, {0, 0, d}};
                c[n++] = (ftm_contact){tip[1], 0, FTM_CONTACT_DISPLACEMENT, {0, 0, d}};
            }
            if (t == 300) { /* the instructor: stiffness times 1.5, on both */
                ftm_wire_tissue tt = ftm_replay_scene_tissue(sc);
                tt.stiffness *= 1.5;
                if (ftm_replay_set_tissue(&mat, server, &tt, &err))
                    fail_msg("%s: %s", forces[k], err.message);
            }
            assert_int_equal(ftm_replay_step(server, def.depth, c, n, NULL), FTM_OK);
            memcpy(store, c, sizeof c);
            ftm_wire_received rx;
            memset(&rx, 0, sizeof rx);
            rx.msg.kind = FTM_WIRE_TICK;
            rx.msg.u.tick = (ftm_wire_tick){.tick = t, .depth = def.depth, .contact_count = n,
                                            .contacts = store,
                                            .state_hash = ftm_sim_hash(server)};
            if (t == 300) {
                ftm_wire_tissue tt = ftm_replay_scene_tissue(sc);
                tt.stiffness *= 1.5;
                rx.msg.u.tick.tissue = tt;
                rx.msg.u.tick.has_tissue = true;
            }
            rx.sender = 1;
            rx.seq = ++seq;
            assert_int_equal(ftm_replay_on_tick(r, &rx), FTM_OK);
            if (t == 1)
                assert_int_equal(ftm_replay_on_keyframe(r, &k0), FTM_OK);
            assert_int_equal(ftm_replay_state(r), FTM_WIRE_STATE_SYNCED);
            if (ftm_replay_hash(r) != ftm_sim_hash(server))
                fail_msg("%s: the replica left the server at tick %d", forces[k], (int)t);
        }
        ftm_replay_stats st;
        ftm_replay_get_stats(r, &st);
        assert_int_equal(st.mismatches, 0);
        ftm_replay_keyframe_free(&k0);
        ftm_replay_destroy(r);
        ftm_replay_material_free(&mat);
        ftm_sim_destroy(server);
        ftm_scene_destroy(sc);
        ftm_scene_destroy(plain);
    }
    unsetenv("FTM_CACHE_DIR");
    unlink(path);
    rmdir(dir);
}

int main(void)
{
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(test_sha256),
        cmocka_unit_test(test_digest_constraints),
        cmocka_unit_test(test_digest_mass_scaling),
        cmocka_unit_test(test_id_held),
        cmocka_unit_test(test_announce_arithmetic),
        cmocka_unit_test(test_continue_in_contact),
        cmocka_unit_test(test_continue_relaxing),
        cmocka_unit_test(test_continue_substepped),
        cmocka_unit_test(test_replica),
        cmocka_unit_test(test_forged_tick_jumps),
        cmocka_unit_test(test_material_mesh),
        cmocka_unit_test(test_tissue_physics),
        cmocka_unit_test(test_set_mesh_refusals),
        cmocka_unit_test(test_tissue_range),
        cmocka_unit_test(test_tissue_replica),
        cmocka_unit_test(test_region_sleep_session),
        cmocka_unit_test(test_labelled_replica),
    };
    return cmocka_run_group_tests(tests, NULL, NULL);
}
