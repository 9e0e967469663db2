/* ftm_sim_load_state and the replay library, in one process (no network):
 * a simulation restored from another's keyframe continues bit-identically;
 * a replica follows frames with idle ticks left out, resyncs on a gap or a
 * mismatch, and restores a reset keyframe. */
#include <setjmp.h>
#include <stdarg.h>
#include <stddef.h>
#include <cmocka.h>

#include "replay.h"

#include <stdio.h>
#include <stdlib.h>
#include <string.h>

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
    assert_int_equal(ftm_replay_make_keyframe(a, &k, NULL), FTM_OK);
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
    assert_int_equal(ftm_replay_make_keyframe(a, &k, NULL), FTM_OK);
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
    ftm_sim_mode bad = {0, 0, 0, false};
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
    rx->msg.u.tick = (ftm_wire_tick){t, 8, n, store, 0, NULL, ftm_sim_hash(s->sim), 0};
    rx->sender = 1;
    rx->seq = ++s->seq;
    s->pub_n = n;
    return true;
}

static void test_replica(void **state)
{
    (void)state;
    ftm_scene *sc = open_scene();
    fake_server s = {0};
    s.m = ftm_scene_mesh(sc);
    ftm_sim_def def = ftm_replay_sim_def(sc);
    assert_int_equal(ftm_sim_create(s.m, &def, &s.sim, NULL), FTM_OK);
    ftm_replay *r = NULL;
    assert_int_equal(ftm_replay_create(sc, NULL, NULL, &r, NULL), FTM_OK);
    assert_int_equal(ftm_replay_state(r), FTM_WIRE_STATE_JOINING);

    ftm_wire_keyframe k0;
    assert_int_equal(ftm_replay_make_keyframe(s.sim, &k0, NULL), FTM_OK); /* tick 0 */
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
            assert_int_equal(ftm_replay_make_keyframe(s.sim, &k, NULL), FTM_OK);
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
        rx.msg.u.tick = (ftm_wire_tick){t, 8, 1, &c, 0, NULL, ftm_sim_hash(s.sim), 0};
        rx.seq = ++s.seq;
        rx.gap = 0;
        assert_int_equal(ftm_replay_on_tick(r, &rx), FTM_OK);
    }
    assert_true(ftm_replay_hash(r) == ftm_sim_hash(s.sim));
    assert_int_equal(ftm_sim_load_state(s.sim, t, 8, NULL, NULL, NULL, 0, NULL, 0, NULL, NULL),
                     FTM_OK);
    ftm_wire_keyframe kr;
    assert_int_equal(ftm_replay_make_keyframe(s.sim, &kr, NULL), FTM_OK);
    assert_int_equal(ftm_replay_on_keyframe(r, &kr), FTM_OK);
    assert_int_equal(ftm_replay_state(r), FTM_WIRE_STATE_SYNCED);
    assert_true(ftm_replay_hash(r) == ftm_sim_hash(s.sim));
    ftm_replay_keyframe_free(&kr);

    ftm_replay_keyframe_free(&k0);
    ftm_replay_destroy(r);
    ftm_sim_destroy(s.sim);
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

int main(void)
{
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(test_sha256),
        cmocka_unit_test(test_continue_in_contact),
        cmocka_unit_test(test_continue_relaxing),
        cmocka_unit_test(test_continue_substepped),
        cmocka_unit_test(test_replica),
    };
    return cmocka_run_group_tests(tests, NULL, NULL);
}
