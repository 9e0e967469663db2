/* SPDX-License-Identifier: GPL-3.0-or-later */
/* The codec's bytes do not change: a fixed set of messages (every kind,
 * every optional field present and absent, every command and outcome) is
 * encoded and compared byte for byte with tests/wire/codec_golden.txt, which
 * the codec wrote before it was rewritten as tables (commit "tests/wire:
 * golden bytes of every message kind"). Each golden payload is also decoded
 * and encoded again, which must give the same bytes: the decoder keeps every
 * field the encoder writes.
 *
 * The file changes only with the protocol (a new field in a message here, a
 * deliberate change of encoding): regenerate it with
 *   build/release/tests/wire/test_wire_golden --write tests/wire/codec_golden.txt
 * and say in the commit why the bytes changed. */
#include <setjmp.h>
#include <stdarg.h>
#include <stddef.h>
#include <cmocka.h>

#include "ftm/wire.h"

#include <float.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

/* ---- the messages ---------------------------------------------------------- */

/* Doubles whose bits a codec could lose: signed zero, subnormals, extremes. */
static const double odd[] = {0.25, -0.0, 5e-324, -DBL_MAX, DBL_MIN, 2.0 / 3.0, -98765.4321, 1e-300};
#define NODD (sizeof odd / sizeof odd[0])

static ftm_vec3 odd_vec(int i)
{
    return (ftm_vec3){odd[(size_t)i % NODD], odd[(size_t)(i + 3) % NODD],
                      odd[(size_t)(i + 5) % NODD]};
}

static const ftm_wire_tissue tissue = {2.5e-3, 0.125, 7.0 / 3.0, {0.5, 1.25, 2.0}};

static ftm_wire_probe_sample samples[5];
static ftm_contact contacts[6];
static int32_t kf_nodes[6];
static double kf_pos[18], kf_prev[18];

static ftm_wire_reaction reactions[3] = {
    {.group = 0, .participant = 21, .probe = 0, .force = {-0.75, 0.5, 3e-9}},
    {.group = 4, .participant = 3000000000u, .probe = 2, .force = {1.0, -2.0, -0.0},
     .has_model = true, .hip = {-0.01, 0.02, 0.05},
     .stiffness = {-120, 1.5, 2, 3, -220, 4, 5, 6.25, -320}, .has_plane = true,
     .contact_point = {0.3, 0.2, 0.1}, .contact_normal = {0.0, 1.0, 0.0}},
    {.group = 1, .participant = 22, .probe = 1, .force = {0, -0.0, -DBL_MAX},
     .push_limited = true, .has_plane = true, .contact_point = {-3, -2, -1},
     .contact_normal = {0.8, 0.0, -0.6}}};

static void fill_arrays(void)
{
    for (int i = 0; i < 5; i++)
        samples[i] = (ftm_wire_probe_sample){(i + 1) % 3, 777000000ull * (uint64_t)i + 5,
                                             odd_vec(i + 1)};
    for (int i = 0; i < 6; i++) {
        contacts[i] = (ftm_contact){.node = 5 * i + 2,
                                    .group = (i + 1) % 4,
                                    .kind = i % 3 ? FTM_CONTACT_FORCE : FTM_CONTACT_DISPLACEMENT,
                                    .value = odd_vec(2 * i)};
        kf_nodes[i] = 4 * i + 3;
        for (int c = 0; c < 3; c++) {
            kf_pos[3 * i + c] = odd[(size_t)(2 * i + c) % NODD] / (i + 2);
            kf_prev[3 * i + c] = kf_pos[3 * i + c] / -3.0;
        }
    }
}

typedef struct golden {
    const char *name;
    ftm_wire_msg msg;
} golden;

#define NGOLDEN 20

#define KIND(k, member) .kind = FTM_WIRE_##k, .u.member

/* Fills g[0..NGOLDEN-1]; the arrays they point to are static. */
static void golden_set(golden *g)
{
    fill_arrays();
    const golden set[NGOLDEN] = {
        {"announce_full",
         {KIND(ANNOUNCE, announce) = {.scene_id = "kidney-needle",
                                      .digest = {0xde, 0xad, 0xbe, 0xef, 0, 1, 2, 0x80, 0xff, 9},
                                      .digest_len = 10, .tick_rate_hz = 500, .time_step = 2e-3,
                                      .depth = 7, .depth_min = 3, .depth_max = 25,
                                      .tissue = tissue, .node_count = 54321,
                                      .tick = UINT64_MAX - 7, .paused = true,
                                      .server_start_ns = 1800000000987654321ull,
                                      .arithmetic = 3}}},
        /* no optional fields, zeros where allowed */
        {"announce_plain",
         {KIND(ANNOUNCE, announce) = {.scene_id = "/srv/scenes/organ.scene", .digest = {0x7f},
                                      .digest_len = 1, .tick_rate_hz = 1, .time_step = 5e-324,
                                      .tissue = {1.0, 0.0, 2.0, {1, 1, 1}}, .node_count = 1}}},
        {"probe_input_5", {KIND(PROBE_INPUT, probe_input) = {0x89abcdefu, 91, 5, samples}}},
        {"probe_input_empty", {KIND(PROBE_INPUT, probe_input) = {13, 0, 0, NULL}}},
        {"tick_full",
         {KIND(TICK, tick) = {.tick = 987654, .depth = 9, .contact_count = 6,
                              .contacts = contacts, .reaction_count = 3, .reactions = reactions,
                              .state_hash = 0x0f1e2d3c4b5a6978u,
                              .send_time_ns = 1800000000123456789ull, .has_tissue = true,
                              .tissue = tissue}}},
        {"tick_idle", {KIND(TICK, tick) = {.tick = 8, .depth = 0, .state_hash = 2}}},
        {"keyframe_full",
         {KIND(KEYFRAME, keyframe) = {.tick = 123456789, .state_hash = 0xfedcba9876543210u,
                                      .node_count = 40, .depth = 11, .count = 6,
                                      .nodes = kf_nodes, .positions = kf_pos,
                                      .previous = kf_prev, .has_tissue = true, .tissue = tissue,
                                      .has_mode = true,
                                      .mode = {4, 250, 7, true, 1.0 / 9.0, 0.5},
                                      .contact_count = 4, .contacts = contacts}}},
        {"keyframe_rest", {KIND(KEYFRAME, keyframe) = {.node_count = 2}}},
        {"status_trainee",
         {KIND(STATUS, status) = {.participant = 77, .role = FTM_WIRE_ROLE_TRAINEE,
                                  .state = FTM_WIRE_STATE_JOINING,
                                  .last_applied_tick = 1ull << 40, .state_hash = 1,
                                  .replay_ns_per_tick = 2345.75, .replay_ns_max = 65432.5,
                                  .name = "Dr. \xc3\x85sa (left hand)"}}},
        {"status_server",
         {KIND(STATUS, status) = {.participant = 2, .role = FTM_WIRE_ROLE_SERVER,
                                  .state = FTM_WIRE_STATE_SYNCED, .last_applied_tick = 12345,
                                  .state_hash = 0x8000000000000002u, .ignored_count = 2,
                                  .ignored_participant = {31, 32},
                                  .ignored_origin = {UINT64_MAX, 0x9e3779b97f4a7c15u},
                                  .holder_count = 3, .holder_participant = {2, 11, 12},
                                  .holder_origin = {5, 0x1234567890abcdefu, UINT64_MAX - 1}}}},
        {"status_bot_leaving",
         {KIND(STATUS, status) = {.participant = 0xffffffffu, .role = FTM_WIRE_ROLE_BOT,
                                  .state = FTM_WIRE_STATE_LEAVING}}},
        {"control_pause",
         {KIND(CONTROL, control) = {.issuer = 9, .command_id = 2001,
                                    .command = FTM_WIRE_CMD_PAUSE}}},
        {"control_resume",
         {KIND(CONTROL, control) = {.issuer = 9, .command_id = 2002,
                                    .command = FTM_WIRE_CMD_RESUME}}},
        {"control_reset",
         {KIND(CONTROL, control) = {.issuer = 9, .command_id = 2003,
                                    .command = FTM_WIRE_CMD_RESET}}},
        {"control_tissue",
         {KIND(CONTROL, control) = {9, 2004, FTM_WIRE_CMD_TISSUE, .tissue = tissue}}},
        {"control_depth_limits",
         {KIND(CONTROL, control) = {9, 2005, FTM_WIRE_CMD_DEPTH_LIMITS, .depth_min = 1,
                                    .depth_max = 64}}},
        {"reply_applied",
         {KIND(CONTROL_REPLY, control_reply) = {.issuer = 3000000001u, .command_id = 41,
                                                .outcome = FTM_WIRE_OUTCOME_APPLIED,
                                                .tick = 99}}},
        {"reply_changed",
         {KIND(CONTROL_REPLY, control_reply) = {3000000001u, 42, FTM_WIRE_OUTCOME_CHANGED, 100,
                                                "depth limited to 25"}}},
        {"reply_refused",
         {KIND(CONTROL_REPLY, control_reply) = {3000000001u, UINT64_MAX,
                                                FTM_WIRE_OUTCOME_REFUSED, 101,
                                                "tissue refused: stiffness must be > 0"}}},
        {"reply_applied_reason",
         {KIND(CONTROL_REPLY, control_reply) = {1, 2, FTM_WIRE_OUTCOME_APPLIED, 0,
                                                "already in force"}}},
    };
    memcpy(g, set, sizeof set);
}

/* ---- the golden file ---------------------------------------------------------- */

static char *to_hex(const uint8_t *b, size_t n)
{
    char *s = malloc(2 * n + 1);
    for (size_t i = 0; i < n; i++)
        snprintf(s + 2 * i, 3, "%02x", b[i]);
    s[2 * n] = '\0';
    return s;
}

static uint8_t *encode(const ftm_wire_msg *m, size_t *size)
{
    ftm_error err = {0, ""};
    uint8_t *buf = NULL;
    if (ftm_wire_encode(m, &buf, size, &err))
        fail_msg("encode: %s", err.message);
    return buf;
}

/* The golden file's line for name: its kind and hex payload (malloc'ed). */
static char *golden_line(const char *name, int *kind)
{
    FILE *f = fopen(FTM_WIRE_GOLDEN, "r");
    if (!f)
        fail_msg("cannot open %s", FTM_WIRE_GOLDEN);
    static char line[1 << 16];
    char *found = NULL;
    while (!found && fgets(line, sizeof line, f)) {
        if (line[0] == '#')
            continue;
        char *sp1 = strchr(line, ' ');
        char *sp2 = sp1 ? strchr(sp1 + 1, ' ') : NULL;
        if (!sp2 || (size_t)(sp1 - line) != strlen(name) || strncmp(line, name, strlen(name)))
            continue;
        *kind = atoi(sp1 + 1);
        line[strcspn(line, "\n")] = '\0';
        found = strdup(sp2 + 1);
    }
    fclose(f);
    if (!found)
        fail_msg("%s has no line for %s", FTM_WIRE_GOLDEN, name);
    return found;
}

static uint8_t *from_hex(const char *hex, size_t *n)
{
    *n = strlen(hex) / 2;
    uint8_t *b = malloc(*n ? *n : 1);
    for (size_t i = 0; i < *n; i++) {
        unsigned v;
        if (sscanf(hex + 2 * i, "%2x", &v) != 1)
            fail_msg("bad hex at %zu", i);
        b[i] = (uint8_t)v;
    }
    return b;
}

static void test_encode_matches_golden(void **state)
{
    (void)state;
    golden g[NGOLDEN];
    golden_set(g);
    for (int i = 0; i < NGOLDEN; i++) {
        size_t size;
        uint8_t *buf = encode(&g[i].msg, &size);
        char *hex = to_hex(buf, size);
        int kind = 0;
        char *want = golden_line(g[i].name, &kind);
        assert_int_equal(kind, g[i].msg.kind);
        if (strcmp(hex, want) != 0)
            fail_msg("%s: encoding differs from the golden bytes\n got  %s\n want %s", g[i].name,
                     hex, want);
        free(want);
        free(hex);
        free(buf);
    }
}

/* Every golden payload decodes and encodes to the same bytes. */
static void test_golden_decodes_back(void **state)
{
    (void)state;
    golden g[NGOLDEN];
    golden_set(g);
    for (int i = 0; i < NGOLDEN; i++) {
        int kind = 0;
        char *hex = golden_line(g[i].name, &kind);
        size_t n;
        uint8_t *bytes = from_hex(hex, &n);
        ftm_wire_msg back;
        ftm_error err = {0, ""};
        if (ftm_wire_decode(kind, bytes, n, NULL, &back, &err))
            fail_msg("%s: decode: %s", g[i].name, err.message);
        size_t size;
        uint8_t *again = encode(&back, &size);
        if (size != n || memcmp(again, bytes, n) != 0)
            fail_msg("%s: decoded and encoded again, the bytes differ", g[i].name);
        free(again);
        ftm_wire_msg_free(&back);
        free(bytes);
        free(hex);
    }
}

/* The file holds no line for a message this test no longer has. */
static void test_golden_file_complete(void **state)
{
    (void)state;
    golden g[NGOLDEN];
    golden_set(g);
    FILE *f = fopen(FTM_WIRE_GOLDEN, "r");
    assert_non_null(f);
    static char line[1 << 16];
    int lines = 0;
    while (fgets(line, sizeof line, f)) {
        if (line[0] == '#')
            continue;
        lines++;
        bool known = false;
        for (int i = 0; i < NGOLDEN; i++)
            known |= strncmp(line, g[i].name, strlen(g[i].name)) == 0 &&
                     line[strlen(g[i].name)] == ' ';
        if (!known)
            fail_msg("a golden line for no message: %.40s", line);
    }
    fclose(f);
    assert_int_equal(lines, NGOLDEN);
}

/* The kinds' names, topics and caps (now read from their descriptors). */
static void test_kind_tables(void **state)
{
    (void)state;
    static const struct {
        const char *name, *topic;
        size_t cap;
    } want[] = {{"unknown kind", NULL, 0},
                {"scene announcement", "ftm_v1_scene_announce", 64 * 1024},
                {"probe input", "ftm_v1_probe_input", 256 * 1024},
                {"tick frame", "ftm_v1_tick_frame", 2 * 1024 * 1024},
                {"keyframe", "ftm_v1_keyframe", 16 * 1024 * 1024},
                {"participant status", "ftm_v1_participant_status", 4 * 1024},
                {"session control", "ftm_v1_session_control", 4 * 1024},
                {"control reply", "ftm_v1_control_reply", 4 * 1024},
                {"unknown kind", NULL, 0}};
    for (int k = 0; k <= FTM_WIRE_KIND_MAX + 1; k++) {
        assert_string_equal(ftm_wire_kind_name(k), want[k].name);
        if (want[k].topic)
            assert_string_equal(ftm_wire_topic_name(k), want[k].topic);
        else
            assert_null(ftm_wire_topic_name(k));
        assert_int_equal(ftm_wire_default_cap(k), want[k].cap);
    }
    assert_string_equal(ftm_wire_kind_name(-1), "unknown kind");
    assert_null(ftm_wire_topic_name(1000));
}

static int write_golden(const char *path)
{
    golden g[NGOLDEN];
    golden_set(g);
    FILE *f = fopen(path, "w");
    if (!f) {
        perror(path);
        return 1;
    }
    fprintf(f, "# name kind payload-hex: tests/wire/test_wire_golden.c says how it is made\n");
    for (int i = 0; i < NGOLDEN; i++) {
        size_t size;
        uint8_t *buf = encode(&g[i].msg, &size);
        char *hex = to_hex(buf, size);
        fprintf(f, "%s %d %s\n", g[i].name, (int)g[i].msg.kind, hex);
        free(hex);
        free(buf);
    }
    return fclose(f) == 0 ? 0 : 1;
}

int main(int argc, char **argv)
{
    if (argc == 3 && strcmp(argv[1], "--write") == 0)
        return write_golden(argv[2]);
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(test_encode_matches_golden),
        cmocka_unit_test(test_golden_decodes_back),
        cmocka_unit_test(test_golden_file_complete),
        cmocka_unit_test(test_kind_tables),
    };
    return cmocka_run_group_tests(tests, NULL, NULL);
}
