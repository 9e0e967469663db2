/* SPDX-License-Identifier: GPL-3.0-or-later */
/* The wire codec: round trips of every kind, and hostile payloads (truncated,
 * random, wrong wire types, oversized, inflating, wrong version, missing
 * fields, NaN, bad indices) that must be rejected with the right code and a
 * message, without crashing, leaking or exhausting memory. */
#include <setjmp.h>
#include <stdarg.h>
#include <stddef.h>
#include <cmocka.h>

#include "ftm/wire.h"
#include "ftm/v1/ftm.pb-c.h"

#include <float.h>
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

/* ---- helpers ------------------------------------------------------------ */

static uint64_t rng_state = 0x9e3779b97f4a7c15u;
static uint64_t rng(void)
{
    /* xorshift64*: deterministic across runs */
    rng_state ^= rng_state >> 12;
    rng_state ^= rng_state << 25;
    rng_state ^= rng_state >> 27;
    return rng_state * 0x2545f4914f6cdd1du;
}

static bool same_double(double a, double b)
{
    return memcmp(&a, &b, sizeof a) == 0;
}

static bool same_vec(ftm_vec3 a, ftm_vec3 b)
{
    return same_double(a.x, b.x) && same_double(a.y, b.y) && same_double(a.z, b.z);
}

/* Encodes msg and decodes it back into *back (asserting success). */
static void round_trip(const ftm_wire_msg *msg, ftm_wire_msg *back)
{
    ftm_error err = {0, ""};
    uint8_t *buf = NULL;
    size_t size = 0;
    int rc = ftm_wire_encode(msg, &buf, &size, &err);
    if (rc)
        fail_msg("encode: %s", err.message);
    rc = ftm_wire_decode(msg->kind, buf, size, NULL, back, &err);
    if (rc)
        fail_msg("decode: %s", err.message);
    assert_int_equal(back->kind, msg->kind);
    free(buf);
}

static uint8_t *encode_ok(const ftm_wire_msg *msg, size_t *size)
{
    ftm_error err = {0, ""};
    uint8_t *buf = NULL;
    if (ftm_wire_encode(msg, &buf, size, &err))
        fail_msg("encode: %s", err.message);
    return buf;
}

/* Decodes and expects code, with a message containing each needle. */
static void expect_reject(int kind, const void *data, size_t size, const ftm_wire_limits *limits,
                          int code, const char *needle1, const char *needle2)
{
    ftm_error err = {0, ""};
    ftm_wire_msg msg;
    int rc = ftm_wire_decode(kind, data, size, limits, &msg, &err);
    if (rc != code)
        fail_msg("want %d, got %d (%s)", code, rc, err.message);
    assert_int_equal(err.code, code);
    assert_true(strlen(err.message) > 0);
    assert_non_null(strstr(err.message, ftm_wire_kind_name(kind)));
    if (needle1 && !strstr(err.message, needle1))
        fail_msg("message lacks '%s': %s", needle1, err.message);
    if (needle2 && !strstr(err.message, needle2))
        fail_msg("message lacks '%s': %s", needle2, err.message);
    assert_null(msg.storage);
}

static const double odd_values[] = {0.1, -0.0, 4.9406564584124654e-324, DBL_MAX, -1e-300,
                                    1.0 / 3.0, 123456.789, -DBL_MIN};
#define NODD (sizeof odd_values / sizeof odd_values[0])

static ftm_wire_tissue sample_tissue(void)
{
    return (ftm_wire_tissue){1e-3, 0.05, 1.0 / 3.0, {1.0, 0.7, 1.5}};
}

/* A tick frame with n contacts and 2 reactions (arrays static). */
static ftm_contact tick_contacts[64];
static ftm_wire_reaction tick_reactions[2];
static ftm_wire_msg sample_tick(int n, uint64_t tick)
{
    for (int i = 0; i < n; i++) {
        tick_contacts[i] = (ftm_contact){
            .node = 7 * i + 3,
            .group = i % 3,
            .kind = i % 2 ? FTM_CONTACT_DISPLACEMENT : FTM_CONTACT_FORCE,
            .value = {odd_values[i % NODD], odd_values[(i + 1) % NODD], odd_values[(i + 2) % NODD]}};
    }
    tick_reactions[0] = (ftm_wire_reaction){.group = 0, .participant = 17, .probe = 0, .force = {0.5, -0.25, 1e-9}};
    tick_reactions[1] = (ftm_wire_reaction){.group = 2, .participant = 18, .probe = 1, .force = {-0.0, 0, DBL_MAX},
                                            .push_limited = true};
    ftm_wire_msg m;
    memset(&m, 0, sizeof m);
    m.kind = FTM_WIRE_TICK;
    m.u.tick = (ftm_wire_tick){
        .tick = tick, .depth = 10, .contact_count = n, .contacts = tick_contacts,
        .reaction_count = 2, .reactions = tick_reactions, .state_hash = 0xfedcba9876543210u ^ tick,
        .send_time_ns = 0};
    return m;
}

/* ---- round trips ------------------------------------------------------------ */

static void test_round_trip_announce(void **state)
{
    (void)state;
    ftm_wire_msg m, b;
    memset(&m, 0, sizeof m);
    m.kind = FTM_WIRE_ANNOUNCE;
    ftm_wire_announce *a = &m.u.announce;
    snprintf(a->scene_id, sizeof a->scene_id, "liver-probe");
    for (int i = 0; i < 32; i++)
        a->digest[i] = (uint8_t)(i * 37 + 1);
    a->digest_len = 32;
    a->tick_rate_hz = 1000;
    a->time_step = 1e-3;
    a->depth = 10;
    a->depth_min = 2;
    a->depth_max = 40;
    a->tissue = sample_tissue();
    a->node_count = 12345;
    a->tick = UINT64_MAX - 1;
    a->paused = true;
    a->server_start_ns = 1795000000123456789ull;
    a->arithmetic = 4000000000u;
    round_trip(&m, &b);
    const ftm_wire_announce *r = &b.u.announce;
    assert_string_equal(r->scene_id, "liver-probe");
    assert_int_equal(r->digest_len, 32);
    assert_memory_equal(r->digest, a->digest, 32);
    assert_int_equal(r->tick_rate_hz, 1000);
    assert_true(same_double(r->time_step, 1e-3));
    assert_int_equal(r->depth, 10);
    assert_int_equal(r->depth_min, 2);
    assert_int_equal(r->depth_max, 40);
    assert_true(same_double(r->tissue.node_mass, a->tissue.node_mass));
    assert_true(same_double(r->tissue.stiffness, a->tissue.stiffness));
    assert_true(same_vec(r->tissue.axis_scale, a->tissue.axis_scale));
    assert_int_equal(r->node_count, 12345);
    assert_true(r->tick == UINT64_MAX - 1);
    assert_true(r->paused);
    assert_true(r->server_start_ns == 1795000000123456789ull);
    assert_true(r->arithmetic == 4000000000u);
    ftm_wire_msg_free(&b);
    /* optional: a server that does not send them announces 0 */
    a->server_start_ns = 0;
    a->arithmetic = 0;
    round_trip(&m, &b);
    assert_true(b.u.announce.server_start_ns == 0);
    assert_true(b.u.announce.arithmetic == 0);
    ftm_wire_msg_free(&b);
}

static void test_round_trip_probe_input(void **state)
{
    (void)state;
    ftm_wire_probe_sample s[5];
    for (int i = 0; i < 5; i++)
        s[i] = (ftm_wire_probe_sample){i % 2, 1000000000ull * (uint64_t)i + 17,
                                       {odd_values[i], odd_values[i + 1], odd_values[i + 2]}};
    ftm_wire_msg m, b;
    memset(&m, 0, sizeof m);
    m.kind = FTM_WIRE_PROBE_INPUT;
    m.u.probe_input = (ftm_wire_probe_input){0xabcdef01u, 77, 5, s};
    round_trip(&m, &b);
    const ftm_wire_probe_input *r = &b.u.probe_input;
    assert_int_equal(r->participant, 0xabcdef01u);
    assert_int_equal(r->last_tick_seen, 77);
    assert_int_equal(r->sample_count, 5);
    for (int i = 0; i < 5; i++) {
        assert_int_equal(r->samples[i].probe, s[i].probe);
        assert_true(r->samples[i].device_time_ns == s[i].device_time_ns);
        assert_true(same_vec(r->samples[i].position, s[i].position));
    }
    ftm_wire_msg_free(&b);

    /* an empty batch is fine too */
    m.u.probe_input.sample_count = 0;
    m.u.probe_input.samples = NULL;
    round_trip(&m, &b);
    assert_int_equal(b.u.probe_input.sample_count, 0);
    ftm_wire_msg_free(&b);
}

static void test_round_trip_tick(void **state)
{
    (void)state;
    ftm_wire_msg m = sample_tick(40, 123456789), b;
    round_trip(&m, &b);
    const ftm_wire_tick *r = &b.u.tick;
    assert_true(r->tick == 123456789);
    assert_int_equal(r->depth, 10);
    assert_true(r->state_hash == (0xfedcba9876543210u ^ 123456789));
    assert_int_equal(r->contact_count, 40);
    for (int i = 0; i < 40; i++) {
        assert_int_equal(r->contacts[i].node, tick_contacts[i].node);
        assert_int_equal(r->contacts[i].group, tick_contacts[i].group);
        assert_int_equal(r->contacts[i].kind, tick_contacts[i].kind);
        assert_true(same_vec(r->contacts[i].value, tick_contacts[i].value));
    }
    assert_int_equal(r->reaction_count, 2);
    for (int i = 0; i < 2; i++) {
        assert_int_equal(r->reactions[i].group, tick_reactions[i].group);
        assert_int_equal(r->reactions[i].participant, tick_reactions[i].participant);
        assert_int_equal(r->reactions[i].probe, tick_reactions[i].probe);
        assert_true(same_vec(r->reactions[i].force, tick_reactions[i].force));
        assert_int_equal(r->reactions[i].push_limited, tick_reactions[i].push_limited);
    }
    ftm_wire_msg_free(&b);
}

/* Tissue parameters ride on the tick of a change and on keyframes; absent
 * everywhere else. */
static void test_round_trip_tissue(void **state)
{
    (void)state;
    ftm_wire_msg m = sample_tick(3, 77), b;
    round_trip(&m, &b);
    assert_false(b.u.tick.has_tissue);
    ftm_wire_msg_free(&b);
    const ftm_wire_tissue t = {0.0125, 0.0, 1.0 / 3.0, {1.5, 1e-300, 2.0}};
    m.u.tick.has_tissue = true;
    m.u.tick.tissue = t;
    round_trip(&m, &b);
    assert_true(b.u.tick.has_tissue);
    assert_memory_equal(&b.u.tick.tissue, &t, sizeof t);
    ftm_wire_msg_free(&b);

    int32_t nodes[1] = {4};
    double pos[3] = {1, 2, 3};
    ftm_wire_msg k;
    memset(&k, 0, sizeof k);
    k.kind = FTM_WIRE_KEYFRAME;
    k.u.keyframe = (ftm_wire_keyframe){
        .tick = 9, .state_hash = 10, .node_count = 20, .depth = 3, .count = 1, .nodes = nodes,
        .positions = pos, .previous = pos, .has_tissue = true, .tissue = t};
    round_trip(&k, &b);
    assert_true(b.u.keyframe.has_tissue);
    assert_memory_equal(&b.u.keyframe.tissue, &t, sizeof t);
    assert_false(b.u.keyframe.has_mode);
    ftm_wire_msg_free(&b);
    /* with the integrator's mode and the tick's contacts */
    ftm_contact kc[2] = {{3, 1, FTM_CONTACT_DISPLACEMENT, {0.5, -0.25, 1e-300}},
                         {19, 0, FTM_CONTACT_FORCE, {0, 0, -2}}};
    k.u.keyframe.contact_count = 2;
    k.u.keyframe.contacts = kc;
    k.u.keyframe.has_mode = true;
    k.u.keyframe.mode = (ftm_sim_mode){8, 1000, 0, true, 1.0 / 7.0, 0.0};
    round_trip(&k, &b);
    assert_true(b.u.keyframe.has_mode);
    assert_int_equal(b.u.keyframe.mode.substeps, 8);
    assert_int_equal(b.u.keyframe.mode.steps_at_substeps, 1000);
    assert_true(b.u.keyframe.mode.region_sleeping);
    assert_true(b.u.keyframe.mode.energy_budget == 1.0 / 7.0);
    assert_int_equal(b.u.keyframe.contact_count, 2);
    for (int i = 0; i < 2; i++) {
        assert_int_equal(b.u.keyframe.contacts[i].node, kc[i].node);
        assert_int_equal(b.u.keyframe.contacts[i].group, kc[i].group);
        assert_int_equal(b.u.keyframe.contacts[i].kind, kc[i].kind);
        assert_true(same_vec(b.u.keyframe.contacts[i].value, kc[i].value));
    }
    assert_memory_equal(b.u.keyframe.positions, pos, sizeof pos);
    assert_memory_equal(b.u.keyframe.previous, pos, sizeof pos);
    ftm_wire_msg_free(&b);
    /* a contact on a node the mesh does not have: the codec's checks (the
     * encoder runs the decoder's) name it */
    kc[1].node = 20;
    uint8_t *buf = NULL;
    size_t size = 0;
    ftm_error err = {0, ""};
    assert_int_equal(ftm_wire_encode(&k, &buf, &size, &err), FTM_ERANGE);
    assert_non_null(strstr(err.message, "contact 1: node 20 out of range"));
    assert_null(buf);
}

static void test_round_trip_keyframe(void **state)
{
    (void)state;
    enum { N = 500 };
    static int32_t nodes[N];
    static double pos[3 * N], prev[3 * N];
    for (int i = 0; i < N; i++) {
        nodes[i] = 2 * i + 1;
        for (int c = 0; c < 3; c++) {
            pos[3 * i + c] = odd_values[(size_t)(i + c) % NODD] / (i + 1);
            prev[3 * i + c] = nextafter(pos[3 * i + c], 0.0);
        }
    }
    ftm_wire_msg m, b;
    memset(&m, 0, sizeof m);
    m.kind = FTM_WIRE_KEYFRAME;
    m.u.keyframe = (ftm_wire_keyframe){
        .tick = 987654321, .state_hash = 0x0123456789abcdefu, .node_count = 2 * N + 5, .depth = 12,
        .count = N, .nodes = nodes, .positions = pos, .previous = prev};
    round_trip(&m, &b);
    const ftm_wire_keyframe *r = &b.u.keyframe;
    assert_true(r->tick == 987654321);
    assert_true(r->state_hash == 0x0123456789abcdefu);
    assert_int_equal(r->node_count, 2 * N + 5);
    assert_int_equal(r->depth, 12);
    assert_int_equal(r->count, N);
    assert_memory_equal(r->nodes, nodes, sizeof nodes);
    assert_memory_equal(r->positions, pos, sizeof pos);
    assert_memory_equal(r->previous, prev, sizeof prev);
    ftm_wire_msg_free(&b);
}

static void test_round_trip_status(void **state)
{
    (void)state;
    ftm_wire_msg m, b;
    memset(&m, 0, sizeof m);
    m.kind = FTM_WIRE_STATUS;
    ftm_wire_status *s = &m.u.status;
    s->participant = 42;
    s->role = FTM_WIRE_ROLE_TRAINEE;
    s->state = FTM_WIRE_STATE_RESYNCING;
    s->last_applied_tick = 1u << 31;
    s->state_hash = UINT64_MAX;
    s->replay_ns_per_tick = 1234.5;
    s->replay_ns_max = 99999.25;
    snprintf(s->name, sizeof s->name, "trainee A");
    round_trip(&m, &b);
    const ftm_wire_status *r = &b.u.status;
    assert_int_equal(r->participant, 42);
    assert_int_equal(r->role, FTM_WIRE_ROLE_TRAINEE);
    assert_int_equal(r->state, FTM_WIRE_STATE_RESYNCING);
    assert_true(r->last_applied_tick == 1u << 31);
    assert_true(r->state_hash == UINT64_MAX);
    assert_true(same_double(r->replay_ns_per_tick, 1234.5));
    assert_true(same_double(r->replay_ns_max, 99999.25));
    assert_string_equal(r->name, "trainee A");
    assert_int_equal(r->ignored_count, 0);
    assert_int_equal(r->holder_count, 0);
    ftm_wire_msg_free(&b);

    /* a name reaches others' HUDs and terminals: no control characters
     * (the encoder runs the decoder's checks, so both refuse it) */
    uint8_t *buf = NULL;
    size_t size = 0;
    ftm_error err = {0, ""};
    snprintf(s->name, sizeof s->name, "ann\x1b[2J");
    assert_int_equal(ftm_wire_encode(&m, &buf, &size, &err), FTM_EINVAL);
    assert_non_null(strstr(err.message, "name has control character 0x1b at byte 3"));
    assert_null(buf);
    snprintf(s->name, sizeof s->name, "two\nlines");
    assert_int_equal(ftm_wire_encode(&m, &buf, &size, &err), FTM_EINVAL);
    assert_non_null(strstr(err.message, "name has control character 0x0a at byte 3"));
    snprintf(s->name, sizeof s->name, "Jos\xc3\xa9"); /* UTF-8 is fine */
    round_trip(&m, &b);
    assert_string_equal(b.u.status.name, "Jos\xc3\xa9");
    ftm_wire_msg_free(&b);
    snprintf(s->name, sizeof s->name, "trainee A");

    /* the server's status, with the processes it ignores (a full list) */
    s->participant = 1;
    s->role = FTM_WIRE_ROLE_SERVER;
    s->state = FTM_WIRE_STATE_SYNCED;
    s->ignored_count = FTM_WIRE_IGNORED_MAX;
    for (int i = 0; i < FTM_WIRE_IGNORED_MAX; i++) {
        s->ignored_participant[i] = 100 + (uint32_t)i;
        s->ignored_origin[i] = UINT64_MAX - (uint64_t)i * 0x9e3779b97f4a7c15u;
    }
    round_trip(&m, &b);
    assert_int_equal(b.u.status.ignored_count, FTM_WIRE_IGNORED_MAX);
    assert_memory_equal(b.u.status.ignored_participant, s->ignored_participant,
                        sizeof s->ignored_participant);
    assert_memory_equal(b.u.status.ignored_origin, s->ignored_origin, sizeof s->ignored_origin);
    assert_int_equal(b.u.status.holder_count, 0);
    ftm_wire_msg_free(&b);

    /* and with the processes it listens to (a full list) */
    s->holder_count = FTM_WIRE_HOLDERS_MAX;
    for (int i = 0; i < FTM_WIRE_HOLDERS_MAX; i++) {
        s->holder_participant[i] = 7 + 3 * (uint32_t)i;
        s->holder_origin[i] = 1 + (uint64_t)i * 0x9e3779b97f4a7c15u;
    }
    round_trip(&m, &b);
    assert_int_equal(b.u.status.holder_count, FTM_WIRE_HOLDERS_MAX);
    assert_memory_equal(b.u.status.holder_participant, s->holder_participant,
                        sizeof s->holder_participant);
    assert_memory_equal(b.u.status.holder_origin, s->holder_origin, sizeof s->holder_origin);
    assert_int_equal(b.u.status.ignored_count, FTM_WIRE_IGNORED_MAX);
    ftm_wire_msg_free(&b);

    /* only a server's status lists them, and at most FTM_WIRE_IGNORED_MAX */
    s->role = FTM_WIRE_ROLE_TRAINEE;
    assert_int_equal(ftm_wire_encode(&m, &buf, &size, &err), FTM_EINVAL);
    assert_non_null(strstr(err.message, "ignored processes in a trainee's status"));
    s->role = FTM_WIRE_ROLE_SERVER;
    s->ignored_count = FTM_WIRE_IGNORED_MAX + 1;
    assert_int_equal(ftm_wire_encode(&m, &buf, &size, &err), FTM_ERANGE);
    assert_null(buf);
    /* holders: a server's only, at most FTM_WIRE_HOLDERS_MAX, one per id */
    s->ignored_count = 0;
    s->role = FTM_WIRE_ROLE_OBSERVER;
    assert_int_equal(ftm_wire_encode(&m, &buf, &size, &err), FTM_EINVAL);
    assert_non_null(strstr(err.message, "holders in a observer's status"));
    s->role = FTM_WIRE_ROLE_SERVER;
    s->holder_count = FTM_WIRE_HOLDERS_MAX + 1;
    assert_int_equal(ftm_wire_encode(&m, &buf, &size, &err), FTM_ERANGE);
    s->holder_count = 3;
    s->holder_participant[2] = s->holder_participant[0];
    assert_int_equal(ftm_wire_encode(&m, &buf, &size, &err), FTM_EINVAL);
    assert_non_null(strstr(err.message, "holder_participant 7 listed twice"));
    assert_null(buf);
}

static void test_round_trip_control(void **state)
{
    (void)state;
    for (int cmd = FTM_WIRE_CMD_PAUSE; cmd <= FTM_WIRE_CMD_DEPTH_LIMITS; cmd++) {
        ftm_wire_msg m, b;
        memset(&m, 0, sizeof m);
        m.kind = FTM_WIRE_CONTROL;
        m.u.control = (ftm_wire_control){7, 1000 + (uint64_t)cmd, (ftm_wire_command)cmd,
                                         sample_tissue(), 3, 30};
        round_trip(&m, &b);
        const ftm_wire_control *r = &b.u.control;
        assert_int_equal(r->issuer, 7);
        assert_int_equal(r->command_id, 1000 + cmd);
        assert_int_equal(r->command, cmd);
        if (cmd == FTM_WIRE_CMD_TISSUE) {
            assert_true(same_double(r->tissue.node_damping, 0.05));
            assert_true(same_vec(r->tissue.axis_scale, m.u.control.tissue.axis_scale));
        }
        if (cmd == FTM_WIRE_CMD_DEPTH_LIMITS) {
            assert_int_equal(r->depth_min, 3);
            assert_int_equal(r->depth_max, 30);
        }
        ftm_wire_msg_free(&b);
    }
}

static void test_round_trip_control_reply(void **state)
{
    (void)state;
    static const char *reasons[] = {"", "depth now 6",
                                    "the material's critical time step 3.3e-07 s is too short"};
    for (int o = FTM_WIRE_OUTCOME_APPLIED; o <= FTM_WIRE_OUTCOME_REFUSED; o++) {
        ftm_wire_msg m, b;
        memset(&m, 0, sizeof m);
        m.kind = FTM_WIRE_CONTROL_REPLY;
        ftm_wire_control_reply *r = &m.u.control_reply;
        r->issuer = 4000000000u;
        r->command_id = UINT64_MAX - (uint64_t)o;
        r->outcome = (ftm_wire_outcome)o;
        r->tick = 1234;
        snprintf(r->reason, sizeof r->reason, "%s", reasons[o - 1]);
        round_trip(&m, &b);
        const ftm_wire_control_reply *q = &b.u.control_reply;
        assert_int_equal(q->issuer, r->issuer);
        assert_true(q->command_id == r->command_id);
        assert_int_equal(q->outcome, o);
        assert_int_equal(q->tick, 1234);
        assert_string_equal(q->reason, r->reason);
        ftm_wire_msg_free(&b);
    }
    /* the longest reason, multi-byte characters included */
    ftm_wire_msg m, b;
    memset(&m, 0, sizeof m);
    m.kind = FTM_WIRE_CONTROL_REPLY;
    m.u.control_reply = (ftm_wire_control_reply){1, 2, FTM_WIRE_OUTCOME_CHANGED, 3, ""};
    memset(m.u.control_reply.reason, 'x', FTM_WIRE_REASON_MAX - 1);
    memcpy(m.u.control_reply.reason, "h = 1 \xc2\xb5s", 9);
    round_trip(&m, &b);
    assert_string_equal(b.u.control_reply.reason, m.u.control_reply.reason);
    ftm_wire_msg_free(&b);
    assert_string_equal(ftm_wire_kind_name(FTM_WIRE_CONTROL_REPLY), "control reply");
    assert_string_equal(ftm_wire_topic_name(FTM_WIRE_CONTROL_REPLY), "ftm_v1_control_reply");
    assert_string_equal(ftm_wire_outcome_name(FTM_WIRE_OUTCOME_REFUSED), "refused");
}

/* What a decoder of control replies refuses, and the encoder with it. */
static void test_control_reply_rejects(void **state)
{
    (void)state;
    uint8_t buf[512];
    char reason[300];
    Ftm__V1__ControlReply cr = FTM__V1__CONTROL_REPLY__INIT;
    cr.has_version = cr.has_issuer_id = cr.has_command_id = cr.has_outcome = cr.has_tick = 1;
    cr.version = 1;
    cr.issuer_id = 12;
    cr.command_id = 3;
    cr.outcome = FTM__V1__CONTROL_OUTCOME__OUTCOME_REFUSED;
    cr.tick = 99;
    cr.reason = reason;
    snprintf(reason, sizeof reason, "too stiff");
    size_t n = protobuf_c_message_pack(&cr.base, buf);
    ftm_wire_msg ok;
    ftm_error err = {0, ""};
    assert_int_equal(ftm_wire_decode(FTM_WIRE_CONTROL_REPLY, buf, n, NULL, &ok, &err), FTM_OK);
    ftm_wire_msg_free(&ok);
    /* a refusal must say why */
    cr.reason = NULL;
    n = protobuf_c_message_pack(&cr.base, buf);
    expect_reject(FTM_WIRE_CONTROL_REPLY, buf, n, NULL, FTM_EINVAL, "a refused command needs a reason",
                  NULL);
    cr.outcome = FTM__V1__CONTROL_OUTCOME__OUTCOME_CHANGED;
    n = protobuf_c_message_pack(&cr.base, buf);
    expect_reject(FTM_WIRE_CONTROL_REPLY, buf, n, NULL, FTM_EINVAL, "a changed command needs", NULL);
    cr.outcome = FTM__V1__CONTROL_OUTCOME__OUTCOME_APPLIED; /* applied: none needed */
    n = protobuf_c_message_pack(&cr.base, buf);
    assert_int_equal(ftm_wire_decode(FTM_WIRE_CONTROL_REPLY, buf, n, NULL, &ok, &err), FTM_OK);
    assert_string_equal(ok.u.control_reply.reason, "");
    ftm_wire_msg_free(&ok);
    /* one byte too long, and a control character (an escape sequence) */
    cr.reason = reason;
    memset(reason, 'r', FTM_WIRE_REASON_MAX);
    reason[FTM_WIRE_REASON_MAX] = '\0';
    n = protobuf_c_message_pack(&cr.base, buf);
    expect_reject(FTM_WIRE_CONTROL_REPLY, buf, n, NULL, FTM_EINVAL, "reason of 128 bytes",
                  "at most 127");
    snprintf(reason, sizeof reason, "ok\x1b[2Jcleared");
    n = protobuf_c_message_pack(&cr.base, buf);
    expect_reject(FTM_WIRE_CONTROL_REPLY, buf, n, NULL, FTM_EINVAL, "control character 0x1b",
                  "byte 2");
    snprintf(reason, sizeof reason, "two\nlines");
    n = protobuf_c_message_pack(&cr.base, buf);
    expect_reject(FTM_WIRE_CONTROL_REPLY, buf, n, NULL, FTM_EINVAL, "control character 0x0a", NULL);
    snprintf(reason, sizeof reason, "fine");
    /* unknown and unspecified outcomes */
    cr.outcome = (Ftm__V1__ControlOutcome)4;
    n = protobuf_c_message_pack(&cr.base, buf);
    expect_reject(FTM_WIRE_CONTROL_REPLY, buf, n, NULL, FTM_EINVAL, "unknown outcome 4", NULL);
    cr.outcome = FTM__V1__CONTROL_OUTCOME__OUTCOME_UNSPECIFIED;
    n = protobuf_c_message_pack(&cr.base, buf);
    expect_reject(FTM_WIRE_CONTROL_REPLY, buf, n, NULL, FTM_EINVAL, "unknown outcome 0", NULL);
    cr.outcome = FTM__V1__CONTROL_OUTCOME__OUTCOME_APPLIED;
    /* every field required */
    struct {
        protobuf_c_boolean *has;
        const char *name;
    } f[] = {{&cr.has_issuer_id, "issuer_id"}, {&cr.has_command_id, "command_id"},
             {&cr.has_outcome, "outcome"}, {&cr.has_tick, "tick"}};
    for (size_t i = 0; i < sizeof f / sizeof f[0]; i++) {
        *f[i].has = 0;
        n = protobuf_c_message_pack(&cr.base, buf);
        char want[64];
        snprintf(want, sizeof want, "missing field %s", f[i].name);
        expect_reject(FTM_WIRE_CONTROL_REPLY, buf, n, NULL, FTM_EPARSE, want, NULL);
        *f[i].has = 1;
    }
    cr.version = 2;
    n = protobuf_c_message_pack(&cr.base, buf);
    expect_reject(FTM_WIRE_CONTROL_REPLY, buf, n, NULL, FTM_EVERSION, "version 2", NULL);
    cr.version = 1;
    /* the reason as a varint: the structural scan names it */
    static const uint8_t wt[] = {0x08, 0x01, 0x30, 0x05};
    expect_reject(FTM_WIRE_CONTROL_REPLY, wt, sizeof wt, NULL, FTM_EPARSE, "field reason",
                  "expected length-delimited");

    /* the encoder refuses what a decoder would */
    ftm_wire_msg m;
    memset(&m, 0, sizeof m);
    m.kind = FTM_WIRE_CONTROL_REPLY;
    m.u.control_reply = (ftm_wire_control_reply){12, 3, FTM_WIRE_OUTCOME_REFUSED, 99, ""};
    uint8_t *out = NULL;
    size_t size = 0;
    assert_int_equal(ftm_wire_encode(&m, &out, &size, &err), FTM_EINVAL);
    assert_non_null(strstr(err.message, "needs a reason"));
    snprintf(m.u.control_reply.reason, sizeof m.u.control_reply.reason, "bell\a");
    assert_int_equal(ftm_wire_encode(&m, &out, &size, &err), FTM_EINVAL);
    memset(m.u.control_reply.reason, 'x', sizeof m.u.control_reply.reason); /* no NUL */
    assert_int_equal(ftm_wire_encode(&m, &out, &size, &err), FTM_EINVAL);
    assert_non_null(strstr(err.message, "not NUL-terminated"));
    m.u.control_reply.reason[0] = '\0';
    m.u.control_reply.outcome = (ftm_wire_outcome)9;
    assert_int_equal(ftm_wire_encode(&m, &out, &size, &err), FTM_EINVAL);
    assert_null(out);
}

static void test_unknown_fields_ignored(void **state)
{
    (void)state;
    ftm_wire_msg m = sample_tick(3, 5), b;
    size_t size;
    uint8_t *buf = encode_ok(&m, &size);
    /* append field 100 (varint 5) and field 101 (length-delimited "xyz") */
    static const uint8_t extra[] = {0xa0, 0x06, 0x05, 0xaa, 0x06, 0x03, 'x', 'y', 'z'};
    uint8_t *big = malloc(size + sizeof extra);
    memcpy(big, buf, size);
    memcpy(big + size, extra, sizeof extra);
    ftm_error err = {0, ""};
    assert_int_equal(ftm_wire_decode(FTM_WIRE_TICK, big, size + sizeof extra, NULL, &b, &err), FTM_OK);
    assert_int_equal(b.u.tick.contact_count, 3);
    assert_true(b.u.tick.tick == 5);
    ftm_wire_msg_free(&b);
    free(big);
    free(buf);
}

/* ---- rejections on encode ---------------------------------------------------- */

static void test_encode_rejects(void **state)
{
    (void)state;
    ftm_error err = {0, ""};
    uint8_t *buf = NULL;
    size_t size = 0;
    ftm_wire_msg m = sample_tick(4, 1);
    tick_contacts[2].value.y = NAN;
    assert_int_equal(ftm_wire_encode(&m, &buf, &size, &err), FTM_EINVAL);
    assert_non_null(strstr(err.message, "contact 2: value.y is not finite"));
    assert_null(buf);

    m = sample_tick(4, 1);
    tick_contacts[1].node = -4;
    assert_int_equal(ftm_wire_encode(&m, &buf, &size, &err), FTM_ERANGE);
    assert_non_null(strstr(err.message, "contact 1"));

    ftm_wire_msg s;
    memset(&s, 0, sizeof s);
    s.kind = FTM_WIRE_STATUS;
    s.u.status.participant = 1;
    s.u.status.role = (ftm_wire_role)9;
    s.u.status.state = FTM_WIRE_STATE_SYNCED;
    assert_int_equal(ftm_wire_encode(&s, &buf, &size, &err), FTM_EINVAL);
    assert_non_null(strstr(err.message, "unknown role 9"));

    /* a keyframe that does not fit its cap */
    enum { N = 800000 };
    int32_t *nodes = malloc(N * sizeof *nodes);
    double *pos = calloc(3 * N, sizeof *pos);
    for (int i = 0; i < N; i++)
        nodes[i] = i;
    ftm_wire_msg k;
    memset(&k, 0, sizeof k);
    k.kind = FTM_WIRE_KEYFRAME;
    k.u.keyframe = (ftm_wire_keyframe){
        .tick = 1, .state_hash = 2, .node_count = N, .depth = 3, .count = N, .nodes = nodes,
        .positions = pos, .previous = pos};
    assert_int_equal(ftm_wire_encode(&k, &buf, &size, &err), FTM_ETOOBIG);
    assert_non_null(strstr(err.message, "keyframe"));
    free(nodes);
    free(pos);
}

/* ---- hostile payloads ------------------------------------------------------ */

static void test_truncated(void **state)
{
    (void)state;
    ftm_wire_msg m = sample_tick(10, 99);
    size_t size;
    uint8_t *buf = encode_ok(&m, &size);
    for (size_t n = 0; n < size; n++) {
        /* exact-size copies so ASan sees any read past the end */
        uint8_t *part = malloc(n ? n : 1);
        memcpy(part, buf, n);
        ftm_error err = {0, ""};
        ftm_wire_msg out;
        int rc = ftm_wire_decode(FTM_WIRE_TICK, part, n, NULL, &out, &err);
        if (rc >= 0)
            fail_msg("prefix of %zu/%zu bytes accepted", n, size);
        assert_true(rc == FTM_EPARSE || rc == FTM_EINVAL);
        assert_non_null(strstr(err.message, "tick frame"));
        free(part);
    }
    /* a cut inside the packed doubles names the field and the offset */
    ftm_error err = {0, ""};
    ftm_wire_msg out;
    assert_int_equal(ftm_wire_decode(FTM_WIRE_TICK, buf, size / 2, NULL, &out, &err), FTM_EPARSE);
    assert_non_null(strstr(err.message, "malformed at byte"));
    free(buf);
}

static void test_random_bytes(void **state)
{
    (void)state;
    int accepted = 0;
    for (int i = 0; i < 3000; i++) {
        size_t n = (size_t)(rng() % 300);
        uint8_t *b = malloc(n ? n : 1);
        for (size_t j = 0; j < n; j++)
            b[j] = (uint8_t)rng();
        int kind = FTM_WIRE_KIND_MIN + (int)(rng() % FTM_WIRE_KIND_MAX);
        ftm_error err = {0, ""};
        ftm_wire_msg out;
        int rc = ftm_wire_decode(kind, b, n, NULL, &out, &err);
        if (rc == FTM_OK) {
            accepted++;
            ftm_wire_msg_free(&out);
        } else {
            assert_true(rc < 0);
            assert_int_equal(err.code, rc);
            assert_non_null(strstr(err.message, ftm_wire_kind_name(kind)));
        }
        free(b);
    }
    assert_int_equal(accepted, 0); /* random bytes never carry every required field */

    /* mutations of valid messages: flip bytes, decode, never crash */
    ftm_wire_msg m = sample_tick(20, 1);
    size_t size;
    uint8_t *good = encode_ok(&m, &size);
    for (int i = 0; i < 3000; i++) {
        uint8_t *b = malloc(size);
        memcpy(b, good, size);
        int flips = 1 + (int)(rng() % 4);
        for (int f = 0; f < flips; f++)
            b[rng() % size] = (uint8_t)rng();
        ftm_error err = {0, ""};
        ftm_wire_msg out;
        int rc = ftm_wire_decode(FTM_WIRE_TICK, b, size, NULL, &out, &err);
        if (rc == FTM_OK)
            ftm_wire_msg_free(&out);
        else
            assert_true(err.message[0] != '\0');
        free(b);
    }
    free(good);
}

static void test_wrong_wire_type(void **state)
{
    (void)state;
    /* version (varint) sent as length-delimited */
    static const uint8_t a[] = {0x0a, 0x01, 0x01};
    expect_reject(FTM_WIRE_TICK, a, sizeof a, NULL, FTM_EPARSE, "field version",
                  "wire type length-delimited, expected varint");
    /* state_hash (fixed64) sent as a varint, after a valid version */
    static const uint8_t b[] = {0x08, 0x01, 0x48, 0x05};
    expect_reject(FTM_WIRE_TICK, b, sizeof b, NULL, FTM_EPARSE, "byte 2, field state_hash",
                  "expected 64-bit");
    /* a nested one: reactions[].force.x as a 32-bit value */
    static const uint8_t c[] = {0x08, 0x01, 0x42, 0x07, 0x22, 0x05, 0x0d, 0, 0, 0, 0};
    expect_reject(FTM_WIRE_TICK, c, sizeof c, NULL, FTM_EPARSE, "reactions.force.x", "32-bit");
    /* a group (wire type 3) */
    static const uint8_t d[] = {0x08, 0x01, 0x1b};
    expect_reject(FTM_WIRE_STATUS, d, sizeof d, NULL, FTM_EPARSE, "group", NULL);
    /* packed doubles whose length is not a multiple of 8 */
    static const uint8_t e[] = {0x08, 0x01, 0x3a, 0x03, 1, 2, 3};
    expect_reject(FTM_WIRE_KEYFRAME, e, sizeof e, NULL, FTM_EPARSE, "position",
                  "multiple of 8");
    /* a length running past the end */
    static const uint8_t f[] = {0x08, 0x01, 0x12, 0x40, 'a'};
    expect_reject(FTM_WIRE_ANNOUNCE, f, sizeof f, NULL, FTM_EPARSE, "scene_id", "past the end");
}

static void test_oversized(void **state)
{
    (void)state;
    for (int kind = FTM_WIRE_KIND_MIN; kind <= FTM_WIRE_KIND_MAX; kind++) {
        size_t cap = ftm_wire_default_cap(kind);
        uint8_t *b = calloc(cap + 1, 1);
        expect_reject(kind, b, cap + 1, NULL, FTM_ETOOBIG, "exceeds", "cap");
        free(b);
    }
    /* a caller's smaller cap */
    ftm_wire_msg m = sample_tick(10, 1);
    size_t size;
    uint8_t *buf = encode_ok(&m, &size);
    ftm_wire_limits lim = {.max_payload = size - 1};
    expect_reject(FTM_WIRE_TICK, buf, size, &lim, FTM_ETOOBIG, NULL, NULL);
    free(buf);
}

static void test_inflation_budget(void **state)
{
    (void)state;
    /* 1 MiB of empty `reactions` submessages (2 bytes each on the wire,
     * ~50 bytes each unpacked): well-formed, under the 2 MiB tick cap, and
     * would inflate to tens of MB; the budget allocator stops it. */
    size_t n = 1u << 20;
    uint8_t *b = malloc(n);
    for (size_t i = 0; i < n; i += 2) {
        b[i] = 0x42; /* field 8, length-delimited */
        b[i + 1] = 0x00;
    }
    expect_reject(FTM_WIRE_TICK, b, n, NULL, FTM_EBUDGET, "memory budget", NULL);
    /* the same with probe samples, within the probe input cap */
    for (size_t i = 0; i < n; i += 2)
        b[i] = 0x22; /* field 4 */
    expect_reject(FTM_WIRE_PROBE_INPUT, b, FTM_WIRE_CAP_PROBE_INPUT, NULL, FTM_EBUDGET,
                  "memory budget", NULL);
    /* a tight explicit budget rejects an honest message too */
    ftm_wire_msg m = sample_tick(30, 1);
    size_t size;
    uint8_t *buf = encode_ok(&m, &size);
    ftm_wire_limits lim = {.max_memory = 256};
    expect_reject(FTM_WIRE_TICK, buf, size, &lim, FTM_EBUDGET, NULL, NULL);
    free(buf);
    free(b);
}

static void test_version_mismatch(void **state)
{
    (void)state;
    ftm_wire_msg m = sample_tick(2, 1);
    size_t size;
    uint8_t *buf = encode_ok(&m, &size);
    uint8_t *b = malloc(size + 2);
    memcpy(b, buf, size);
    b[size] = 0x08; /* version = 2, the last occurrence wins */
    b[size + 1] = 0x02;
    expect_reject(FTM_WIRE_TICK, b, size + 2, NULL, FTM_EVERSION, "protocol version 2",
                  "version 1");
    free(b);
    free(buf);
    static const uint8_t none[] = {0x10, 0x05}; /* a tick number, no version */
    expect_reject(FTM_WIRE_TICK, none, sizeof none, NULL, FTM_EPARSE, "missing field version",
                  NULL);
}

static void test_missing_and_invalid(void **state)
{
    (void)state;
    /* Built with the generated structs, so that they are well-formed. */
    Ftm__V1__ParticipantStatus st = FTM__V1__PARTICIPANT_STATUS__INIT;
    st.has_version = 1;
    st.version = 1;
    uint8_t buf[256];
    size_t n = protobuf_c_message_pack(&st.base, buf);
    expect_reject(FTM_WIRE_STATUS, buf, n, NULL, FTM_EPARSE, "missing field participant_id", NULL);

    /* ignored processes: pairs that do not pair, too many, or not the server's */
    st.has_participant_id = st.has_role = st.has_state = st.has_last_applied_tick = 1;
    st.has_state_hash = st.has_replay_ns_per_tick = st.has_replay_ns_max = 1;
    st.participant_id = 1;
    st.role = FTM__V1__ROLE__ROLE_SERVER;
    st.state = FTM__V1__PARTICIPANT_STATE__STATE_SYNCED;
    uint32_t ids[FTM_WIRE_IGNORED_MAX + 1] = {0};
    uint64_t origins[FTM_WIRE_IGNORED_MAX + 1] = {0};
    st.ignored_participant = ids;
    st.ignored_origin = origins;
    st.n_ignored_participant = 2;
    st.n_ignored_origin = 1;
    n = protobuf_c_message_pack(&st.base, buf);
    expect_reject(FTM_WIRE_STATUS, buf, n, NULL, FTM_EINVAL,
                  "2 ignored_participant but 1 ignored_origin", NULL);
    st.n_ignored_participant = st.n_ignored_origin = FTM_WIRE_IGNORED_MAX + 1;
    n = protobuf_c_message_pack(&st.base, buf);
    expect_reject(FTM_WIRE_STATUS, buf, n, NULL, FTM_ERANGE, "17 ignored processes (at most 16)",
                  NULL);
    st.n_ignored_participant = st.n_ignored_origin = 1;
    st.role = FTM__V1__ROLE__ROLE_OBSERVER;
    n = protobuf_c_message_pack(&st.base, buf);
    expect_reject(FTM_WIRE_STATUS, buf, n, NULL, FTM_EINVAL,
                  "ignored processes in a observer's status", NULL);
    st.n_ignored_participant = st.n_ignored_origin = 0;

    /* holders: the same rules (at most 64), and each id once */
    st.role = FTM__V1__ROLE__ROLE_SERVER;
    uint32_t hids[FTM_WIRE_HOLDERS_MAX + 1];
    uint64_t horigins[FTM_WIRE_HOLDERS_MAX + 1];
    for (int i = 0; i <= FTM_WIRE_HOLDERS_MAX; i++) {
        hids[i] = 2 + (uint32_t)i;
        horigins[i] = 1000 + (uint64_t)i;
    }
    st.holder_participant = hids;
    st.holder_origin = horigins;
    st.n_holder_participant = 3;
    st.n_holder_origin = 2;
    uint8_t big[2048];
    n = protobuf_c_message_pack(&st.base, big);
    expect_reject(FTM_WIRE_STATUS, big, n, NULL, FTM_EINVAL,
                  "3 holder_participant but 2 holder_origin", NULL);
    st.n_holder_participant = st.n_holder_origin = FTM_WIRE_HOLDERS_MAX + 1;
    assert_true(protobuf_c_message_get_packed_size(&st.base) <= sizeof big);
    n = protobuf_c_message_pack(&st.base, big);
    expect_reject(FTM_WIRE_STATUS, big, n, NULL, FTM_ERANGE, "65 holders (at most 64)", NULL);
    st.n_holder_participant = st.n_holder_origin = 3;
    hids[2] = hids[1];
    n = protobuf_c_message_pack(&st.base, big);
    expect_reject(FTM_WIRE_STATUS, big, n, NULL, FTM_EINVAL, "holder_participant 3 listed twice",
                  NULL);
    hids[2] = 4;
    st.role = FTM__V1__ROLE__ROLE_TRAINEE;
    n = protobuf_c_message_pack(&st.base, big);
    expect_reject(FTM_WIRE_STATUS, big, n, NULL, FTM_EINVAL, "holders in a trainee's status", NULL);
    st = (Ftm__V1__ParticipantStatus)FTM__V1__PARTICIPANT_STATUS__INIT;

    /* a reaction force without z */
    Ftm__V1__TickFrame tf = FTM__V1__TICK_FRAME__INIT;
    tf.has_version = tf.has_tick = tf.has_depth = tf.has_state_hash = 1;
    tf.version = 1;
    Ftm__V1__Vec3 v = FTM__V1__VEC3__INIT;
    v.has_x = v.has_y = 1;
    Ftm__V1__ProbeReaction r = FTM__V1__PROBE_REACTION__INIT;
    r.has_group = r.has_participant_id = r.has_probe = 1;
    r.force = &v;
    Ftm__V1__ProbeReaction *rp = &r;
    tf.n_reactions = 1;
    tf.reactions = &rp;
    n = protobuf_c_message_pack(&tf.base, buf);
    expect_reject(FTM_WIRE_TICK, buf, n, NULL, FTM_EPARSE, "missing field reactions[0].force.z",
                  NULL);
    v.has_z = 1;
    v.y = NAN;
    n = protobuf_c_message_pack(&tf.base, buf);
    expect_reject(FTM_WIRE_TICK, buf, n, NULL, FTM_EINVAL, "reactions[0].force.y is not finite",
                  NULL);
    v.y = 0;

    /* contacts: index out of range, columns that disagree, unknown kind */
    uint32_t node[2] = {5, 912}, group[2] = {0, 1};
    Ftm__V1__ContactKind kinds[2] = {0, 1};
    double val[6] = {0};
    tf.n_contact_node = tf.n_contact_group = tf.n_contact_kind = 2;
    tf.contact_node = node;
    tf.contact_group = group;
    tf.contact_kind = kinds;
    tf.n_contact_value = 6;
    tf.contact_value = val;
    n = protobuf_c_message_pack(&tf.base, buf);
    ftm_wire_limits lim = {.node_count = 400};
    expect_reject(FTM_WIRE_TICK, buf, n, &lim, FTM_ERANGE,
                  "contact 1: node 912 out of range (scene has 400 nodes)", NULL);
    ftm_wire_msg ok;
    ftm_error err = {0, ""};
    assert_int_equal(ftm_wire_decode(FTM_WIRE_TICK, buf, n, NULL, &ok, &err), FTM_OK);
    ftm_wire_msg_free(&ok);
    tf.n_contact_value = 5;
    n = protobuf_c_message_pack(&tf.base, buf);
    expect_reject(FTM_WIRE_TICK, buf, n, NULL, FTM_EINVAL, "contact columns disagree", NULL);
    tf.n_contact_value = 6;
    kinds[0] = (Ftm__V1__ContactKind)7;
    n = protobuf_c_message_pack(&tf.base, buf);
    expect_reject(FTM_WIRE_TICK, buf, n, NULL, FTM_EINVAL, "contact 0: unknown contact kind 7",
                  NULL);

    /* tissue parameters on a tick frame: validated like the instructor's */
    tf.n_contact_node = tf.n_contact_group = tf.n_contact_kind = tf.n_contact_value = 0;
    Ftm__V1__TissueParams tp = FTM__V1__TISSUE_PARAMS__INIT;
    Ftm__V1__Vec3 ax = FTM__V1__VEC3__INIT;
    ax.has_x = ax.has_y = ax.has_z = 1;
    ax.x = ax.y = ax.z = 1.0;
    tp.has_node_mass = tp.has_node_damping = tp.has_stiffness = 1;
    tp.node_mass = 1.0;
    tp.stiffness = -2.0;
    tp.axis_scale = &ax;
    tf.tissue = &tp;
    n = protobuf_c_message_pack(&tf.base, buf);
    expect_reject(FTM_WIRE_TICK, buf, n, NULL, FTM_EINVAL, "tissue.stiffness must be > 0", NULL);
    tp.stiffness = 2.0;
    ax.z = 0.0;
    n = protobuf_c_message_pack(&tf.base, buf);
    expect_reject(FTM_WIRE_TICK, buf, n, NULL, FTM_EINVAL, "tissue.axis_scale must be > 0", NULL);
    tf.tissue = NULL;

    /* keyframe nodes not ascending */
    Ftm__V1__Keyframe kf = FTM__V1__KEYFRAME__INIT;
    kf.has_version = kf.has_tick = kf.has_state_hash = kf.has_node_count = kf.has_depth = 1;
    kf.version = 1;
    kf.node_count = 100;
    uint32_t kn[2] = {9, 9};
    double kp[6] = {0};
    kf.n_node = 2;
    kf.node = kn;
    kf.n_position = kf.n_previous = 6;
    kf.position = kp;
    kf.previous = kp;
    n = protobuf_c_message_pack(&kf.base, buf);
    expect_reject(FTM_WIRE_KEYFRAME, buf, n, NULL, FTM_EINVAL, "entry 1: node 9", "ascend");
    kn[1] = 10;
    /* keyframe mode: zero substeps, a NaN energy */
    Ftm__V1__IntegratorMode im = FTM__V1__INTEGRATOR_MODE__INIT;
    im.has_substeps = im.has_steps_at_substeps = im.has_quiet_steps = 1;
    im.has_region_sleeping = im.has_energy_budget = im.has_energy_prev = 1;
    kf.mode = &im;
    n = protobuf_c_message_pack(&kf.base, buf);
    expect_reject(FTM_WIRE_KEYFRAME, buf, n, NULL, FTM_ERANGE, "mode.substeps 0 out of range",
                  NULL);
    im.substeps = 2;
    im.energy_prev = NAN;
    n = protobuf_c_message_pack(&kf.base, buf);
    expect_reject(FTM_WIRE_KEYFRAME, buf, n, NULL, FTM_EINVAL, "mode.energy_prev is not finite",
                  NULL);
    im.has_energy_prev = 0;
    n = protobuf_c_message_pack(&kf.base, buf);
    expect_reject(FTM_WIRE_KEYFRAME, buf, n, NULL, FTM_EPARSE, "missing field mode.energy_prev",
                  NULL);
    kf.mode = NULL;

    /* control without a command */
    Ftm__V1__SessionControl sc = FTM__V1__SESSION_CONTROL__INIT;
    sc.has_version = sc.has_issuer_id = sc.has_command_id = 1;
    sc.version = 1;
    n = protobuf_c_message_pack(&sc.base, buf);
    expect_reject(FTM_WIRE_CONTROL, buf, n, NULL, FTM_EPARSE, "missing field command", NULL);

    /* empty payload, unknown kind */
    expect_reject(FTM_WIRE_STATUS, buf, 0, NULL, FTM_EPARSE, "empty", NULL);
    assert_int_equal(ftm_wire_decode(99, buf, 1, NULL, &ok, &err), FTM_EINVAL);
    assert_non_null(strstr(err.message, "unknown message kind 99"));
}

int main(void)
{
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(test_round_trip_announce),
        cmocka_unit_test(test_round_trip_probe_input),
        cmocka_unit_test(test_round_trip_tick),
        cmocka_unit_test(test_round_trip_keyframe),
        cmocka_unit_test(test_round_trip_tissue),
        cmocka_unit_test(test_round_trip_status),
        cmocka_unit_test(test_round_trip_control),
        cmocka_unit_test(test_round_trip_control_reply),
        cmocka_unit_test(test_control_reply_rejects),
        cmocka_unit_test(test_unknown_fields_ignored),
        cmocka_unit_test(test_encode_rejects),
        cmocka_unit_test(test_truncated),
        cmocka_unit_test(test_random_bytes),
        cmocka_unit_test(test_wrong_wire_type),
        cmocka_unit_test(test_oversized),
        cmocka_unit_test(test_inflation_budget),
        cmocka_unit_test(test_version_mismatch),
        cmocka_unit_test(test_missing_and_invalid),
    };
    return cmocka_run_group_tests(tests, NULL, NULL);
}
