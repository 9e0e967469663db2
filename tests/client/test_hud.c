/* SPDX-License-Identifier: GPL-3.0-or-later */
/* The HUD's text (client/hud.c): what trainees and instructors read,
 * including the debriefing figures (time in contact, peak force). */
#include "hud.h"
#include "parts.h"

#include <setjmp.h>
#include <stdarg.h>
#include <stddef.h>
#include <stdint.h>
#include <stdio.h>
#include <string.h>

#include <cmocka.h>

static char lines[FTM_HUD_LINES][FTM_HUD_WIDTH];

/* The index of the first line containing `text`, or -1. */
static int find(int n, const char *text)
{
    for (int i = 0; i < n; i++)
        if (strstr(lines[i], text))
            return i;
    return -1;
}

static ftm_client_view sample_view(void)
{
    ftm_client_view v;
    memset(&v, 0, sizeof v);
    v.state = FTM_WIRE_STATE_SYNCED;
    snprintf(v.scene_name, sizeof v.scene_name, "default");
    v.tick = 3345;
    v.rate_hz = 500;
    v.nparts = 2;
    v.parts[0] = (ftm_client_part){.id = 11, .role = FTM_WIRE_ROLE_TRAINEE,
                                   .state = FTM_WIRE_STATE_SYNCED, .tick = 3249, .name = "anna",
                                   .contact_ticks = 1575, .peak_force = 1.17298, .peak_tick = 2000};
    v.parts[1] = (ftm_client_part){.id = 13, .role = FTM_WIRE_ROLE_OBSERVER,
                                   .state = FTM_WIRE_STATE_RESYNCING, .tick = 3000, .name = "obs"};
    return v;
}

/* The participant table full and 16 probes in contact: the most a HUD
 * has to fit. */
static void crowd(ftm_client_view *v)
{
    for (uint32_t id = 100; v->nparts < FTM_CLIENT_MAX_PARTS; id++)
        assert_non_null(ftm_parts_find(v->parts, &v->nparts, id, true));
    v->nprobes = 16;
    for (int i = 0; i < v->nprobes; i++)
        v->probes[i] = (ftm_client_probe){.participant = 100 + (uint32_t)i, .in_contact = true};
}

static void test_instructor_sees_debriefing(void **state)
{
    (void)state;
    ftm_client_view v = sample_view();
    ftm_hud_info in = {.role = FTM_WIRE_ROLE_INSTRUCTOR, .id = 21};
    int n = ftm_hud_lines(&v, &in, lines);
    assert_true(n > 0 && n <= FTM_HUD_LINES);
    assert_true(find(n, "instructor 21  synced  scene default") == 0);
    int t = find(n, "  11 trainee synced tick 3249 anna  3.1 s in contact, peak 1.17 N");
    if (t < 0)
        fail_msg("no debriefing line for the trainee; line 6: '%s'", lines[6]);
    assert_true(find(n, "  13 observer resyncing tick 3000 obs") > t);
    assert_int_equal(find(n, "13 observer resyncing tick 3000 obs  "), -1); /* no figures */
    assert_int_equal(find(n, "you:"), -1);
}

static void test_trainee_sees_own_figures(void **state)
{
    (void)state;
    ftm_client_view v = sample_view();
    ftm_hud_info in = {.role = FTM_WIRE_ROLE_TRAINEE, .id = 11};
    int n = ftm_hud_lines(&v, &in, lines);
    assert_int_equal(find(n, "you:"), -1); /* not touched yet: nothing to show */
    v.own_contact_ticks = 250;
    v.own_peak_force = 0.5;
    n = ftm_hud_lines(&v, &in, lines);
    assert_true(find(n, "you: 0.5 s in contact, peak 0.50 N") > 0);
    assert_int_equal(find(n, "participants:"), -1); /* the list is the instructor's */
}

/* A trainee that leaves after touching keeps its row, marked left, with
 * its figures; one that never touched is dropped; a returning one is
 * present again. A full list makes room by reusing a departed row. */
static void test_departed_trainee_kept(void **state)
{
    (void)state;
    ftm_client_view v = sample_view();
    ftm_hud_info in = {.role = FTM_WIRE_ROLE_INSTRUCTOR, .id = 21};
    ftm_parts_gone(v.parts, &v.nparts, 11, true);
    ftm_parts_gone(v.parts, &v.nparts, 13, false);
    assert_int_equal(v.nparts, 1);
    int n = ftm_hud_lines(&v, &in, lines);
    assert_true(find(n, "  11 trainee left tick 3249 anna  3.1 s in contact, peak 1.17 N") > 0);
    assert_int_equal(find(n, "  13 observer"), -1);
    ftm_client_part *p = ftm_parts_find(v.parts, &v.nparts, 11, true);
    assert_true(p == &v.parts[0] && p->contact_ticks == 1575); /* the row it left */
    p->left = false; /* as a status from it does */
    n = ftm_hud_lines(&v, &in, lines);
    assert_true(find(n, "  11 trainee synced tick 3249 anna  3.1 s") > 0);

    ftm_parts_gone(v.parts, &v.nparts, 11, true);
    for (uint32_t id = 100; v.nparts < FTM_CLIENT_MAX_PARTS; id++)
        assert_non_null(ftm_parts_find(v.parts, &v.nparts, id, true));
    p = ftm_parts_find(v.parts, &v.nparts, 500, true); /* full: 11's row is reused */
    assert_true(p == &v.parts[0] && p->id == 500 && p->contact_ticks == 0 && !p->left);
    assert_null(ftm_parts_find(v.parts, &v.nparts, 501, true)); /* full, none departed */
    assert_null(ftm_parts_find(v.parts, &v.nparts, 11, false));
}

/* A server restart starts a session without the departed trainees'
 * figures: their rows go, the present ones stay in order. */
static void test_restart_forgets_departed(void **state)
{
    (void)state;
    ftm_client_view v = sample_view();
    ftm_hud_info in = {.role = FTM_WIRE_ROLE_INSTRUCTOR, .id = 21};
    ftm_parts_gone(v.parts, &v.nparts, 11, true);
    assert_non_null(ftm_parts_find(v.parts, &v.nparts, 14, true));
    ftm_parts_gone(v.parts, &v.nparts, 14, true);
    assert_non_null(ftm_parts_find(v.parts, &v.nparts, 15, true));
    assert_int_equal(v.nparts, 4);
    ftm_parts_forget_departed(v.parts, &v.nparts);
    assert_int_equal(v.nparts, 2);
    assert_true(v.parts[0].id == 13 && v.parts[1].id == 15);
    int n = ftm_hud_lines(&v, &in, lines);
    assert_int_equal(find(n, "  11 trainee"), -1);
    assert_true(find(n, "  13 observer") > 0);
}

/* A list cut short says so: by the HUD's lines, or because more took part
 * than the participant table holds (it was cut silently). */
static void test_cut_list_says_so(void **state)
{
    (void)state;
    ftm_client_view v = sample_view();
    ftm_hud_info in = {.role = FTM_WIRE_ROLE_INSTRUCTOR, .id = 21};
    int n = ftm_hud_lines(&v, &in, lines);
    assert_int_equal(find(n, "  ... "), -1); /* all shown */
    v.parts_unlisted = true;
    n = ftm_hud_lines(&v, &in, lines);
    assert_true(find(n, "  ... more participants than the list holds") > find(n, "  13 observer"));
    v.parts_unlisted = false;
    /* many probes in contact take their lines first */
    crowd(&v);
    n = ftm_hud_lines(&v, &in, lines);
    assert_true(n <= FTM_HUD_LINES);
    int more = find(n, "  ... more not shown");
    assert_true(more > 0);
    assert_true(find(n, "keys:") > more); /* the keys are still shown */
}

/* Participants are listed by role, the server first, then by id, however
 * they joined; a participant that leaves keeps its place. */
static void test_participant_order(void **state)
{
    (void)state;
    ftm_client_view v = sample_view();
    v.nparts = 0;
    const struct {
        uint32_t id;
        ftm_wire_role role;
    } joined[] = {{13, FTM_WIRE_ROLE_OBSERVER}, {12, FTM_WIRE_ROLE_TRAINEE},
                  {21, FTM_WIRE_ROLE_INSTRUCTOR}, {1, FTM_WIRE_ROLE_SERVER},
                  {11, FTM_WIRE_ROLE_TRAINEE}};
    for (size_t i = 0; i < sizeof joined / sizeof *joined; i++) {
        ftm_client_part *p = ftm_parts_find(v.parts, &v.nparts, joined[i].id, true);
        assert_non_null(p);
        p->role = joined[i].role;
        p->state = FTM_WIRE_STATE_SYNCED;
    }
    ftm_hud_info in = {.role = FTM_WIRE_ROLE_INSTRUCTOR, .id = 21};
    const char *want[] = {"  1 server", "  11 trainee", "  12 trainee", "  21 instructor",
                          "  13 observer"};
    int n = ftm_hud_lines(&v, &in, lines), at = find(n, "participants:");
    assert_true(at > 0);
    for (int k = 0; k < 5; k++)
        if (strncmp(lines[at + 1 + k], want[k], strlen(want[k])) != 0)
            fail_msg("participant line %d: '%s', want '%s...'", k, lines[at + 1 + k], want[k]);
    ftm_parts_find(v.parts, &v.nparts, 12, false)->left = true;
    n = ftm_hud_lines(&v, &in, lines);
    assert_true(strncmp(lines[at + 3], "  12 trainee left", 17) == 0);
}

/* What became of a command: the server's reply, under the name the
 * client gave the command, on one or two lines; the full list still fits. */
static void test_command_outcome(void **state)
{
    (void)state;
    ftm_pending p;
    memset(&p, 0, sizeof p);
    char text[FTM_OUTCOME_TEXT];
    assert_false(ftm_pending_add(&p, 1, "stiffness 80 N/m", 1000, text, sizeof text));
    assert_false(ftm_pending_add(&p, 2, "stiffness 5000 N/m", 2000, text, sizeof text));
    assert_false(ftm_pending_add(&p, 3, "pause", 3000, text, sizeof text));
    ftm_wire_control_reply r = {21, 1, FTM_WIRE_OUTCOME_APPLIED, 1234, ""};
    assert_true(ftm_pending_reply(&p, &r, text, sizeof text));
    assert_string_equal(text, "stiffness 80 N/m: applied after tick 1234");
    r = (ftm_wire_control_reply){21, 2, FTM_WIRE_OUTCOME_REFUSED, 1300,
                                 "the material's critical time step 1.4e-05 s is too short for "
                                 "time step 0.001 s with at most 64 substeps"};
    assert_true(ftm_pending_reply(&p, &r, text, sizeof text));
    assert_string_equal(text, "stiffness 5000 N/m: refused: the material's critical time step "
                              "1.4e-05 s is too short for time step 0.001 s with at most 64 substeps");
    /* a second reply to it (a duplicate): named by its id */
    assert_false(ftm_pending_reply(&p, &r, text, sizeof text));
    assert_non_null(strstr(text, "command 2: refused: "));
    r = (ftm_wire_control_reply){21, 9, FTM_WIRE_OUTCOME_CHANGED, 5, "ceiling lowered to 40"};
    assert_false(ftm_pending_reply(&p, &r, text, sizeof text));
    assert_string_equal(text, "command 9: changed after tick 5: ceiling lowered to 40");
    assert_int_equal(p.n, 1);

    /* no reply within the timeout: unanswered, once */
    assert_false(ftm_pending_expired(&p, 3000 + FTM_REPLY_TIMEOUT_NS, FTM_REPLY_TIMEOUT_NS, text,
                                     sizeof text));
    assert_true(ftm_pending_expired(&p, 3001 + FTM_REPLY_TIMEOUT_NS, FTM_REPLY_TIMEOUT_NS, text,
                                    sizeof text));
    assert_non_null(strstr(text, "pause: no reply from the server in 3 s"));
    assert_int_equal(p.n, 0);
    assert_false(ftm_pending_expired(&p, INT64_MAX / 2, FTM_REPLY_TIMEOUT_NS, text, sizeof text));
    /* a full table gives up the oldest, saying so */
    for (int i = 0; i < FTM_PENDING_MAX; i++)
        assert_false(ftm_pending_add(&p, 100 + (uint64_t)i, "reset", i, text, sizeof text));
    assert_true(ftm_pending_add(&p, 999, "resume", 5 * FTM_REPLY_TIMEOUT_NS, text, sizeof text));
    assert_non_null(strstr(text, "reset: no reply"));
    assert_int_equal(p.n, FTM_PENDING_MAX);
    assert_int_equal(p.cmd[0].id, 101);
    ftm_pending_forget(&p, 999);
    assert_int_equal(p.n, FTM_PENDING_MAX - 1);

    /* on the HUD: a short one on one line, a long refusal on two, marked */
    ftm_client_view v = sample_view();
    ftm_hud_info in = {.role = FTM_WIRE_ROLE_INSTRUCTOR, .id = 21};
    int n = ftm_hud_lines(&v, &in, lines);
    assert_int_equal(find(n, "applied"), -1);
    in.command_outcome = "stiffness 80 N/m: applied after tick 1234";
    n = ftm_hud_lines(&v, &in, lines);
    assert_true(find(n, "stiffness 80 N/m: applied after tick 1234") > find(n, "keys:"));
    assert_int_equal(find(n, "!!"), -1);
    in.command_outcome = text;
    in.outcome_bad = true;
    snprintf(text, sizeof text, "stiffness 5000 N/m: refused: the material's critical time step "
                                "1.4e-05 s is too short for time step 0.001 s with at most 64 substeps");
    n = ftm_hud_lines(&v, &in, lines);
    int l = find(n, "!! stiffness 5000 N/m: refused: the material's");
    assert_true(l > 0);
    assert_non_null(strstr(lines[l + 1], "64 substeps"));
    /* with the participant table full, the keys and the outcome still fit */
    crowd(&v);
    n = ftm_hud_lines(&v, &in, lines);
    assert_true(n <= FTM_HUD_LINES);
    assert_true(find(n, "64 substeps") > find(n, "keys:"));
    assert_true(find(n, "map ") == n - 1);
}

/* Keys at a limit, or with nobody to hear them, send nothing and say why. */
/* The instructor sees the stable range, the server's substeps and the lag;
 * substepping is marked. */
static void test_stable_range_shown(void **state)
{
    (void)state;
    ftm_client_view v = sample_view();
    v.tissue = (ftm_wire_tissue){0.001, 0.3, 50, {1, 1, 1}};
    v.range_valid = true;
    v.range = (ftm_tissue_range){.time_step = 1e-3, .h_crit = 1.49e-3, .substeps = 1,
                                 .max_substeps = 2, .stiffness_max = 151.5, .mass_min = 1.13e-4,
                                 .damping_min = 0.099, .damping_bound = 0.198};
    v.substeps = 1;
    v.lag_ticks = 3;
    ftm_hud_info in = {.role = FTM_WIRE_ROLE_INSTRUCTOR, .id = 21};
    int n = ftm_hud_lines(&v, &in, lines);
    int i = find(n, "stable range:");
    assert_true(i >= 0);
    assert_string_equal(lines[i], "stable range: k <= 151.5 N/m  d >= 0.099  m >= 0.000113  "
                                  "(at most 2 substeps)");
    i = find(n, "server substeps");
    assert_true(i >= 0);
    assert_string_equal(lines[i], "server substeps 1 per tick  lag 3 ticks");
    v.substeps = 4;
    n = ftm_hud_lines(&v, &in, lines);
    i = find(n, "server substeps");
    assert_true(i >= 0);
    assert_string_equal(lines[i], "!! server substeps 4 per tick  lag 3 ticks: past the stable step "
                                  "(t: scene tissue)");
    assert_true(find(n, "t scene tissue") >= 0);
    /* a peak taken while the tissue was unstable is marked in the row */
    v.parts[0].peak_unstable = true;
    n = ftm_hud_lines(&v, &in, lines);
    i = find(n, "11 trainee");
    assert_true(i >= 0 && strstr(lines[i], "peak 1.17 N (unstable)") != NULL);
    /* a trainee sees none of it */
    in.role = FTM_WIRE_ROLE_TRAINEE;
    n = ftm_hud_lines(&v, &in, lines);
    assert_true(find(n, "stable range") < 0);
}

/* At 640 px (text scale 2: 51 columns) the instructor's HUD is wrapped,
 * not cut: every row fits, and the words are all there, in order. */
static void test_narrow_window_wraps(void **state)
{
    (void)state;
    ftm_client_view v = sample_view();
    v.tissue = (ftm_wire_tissue){0.001, 0.3, 50, {1, 1, 1}};
    v.range_valid = true;
    v.range = (ftm_tissue_range){.time_step = 1e-3, .h_crit = 1.49e-3, .substeps = 1,
                                 .max_substeps = 2, .stiffness_max = 151.5, .mass_min = 1.13e-4,
                                 .damping_min = 0.099, .damping_bound = 0.198};
    ftm_hud_info in = {.role = FTM_WIRE_ROLE_INSTRUCTOR, .id = 21};
    int n = ftm_hud_lines(&v, &in, lines);
    char before[FTM_HUD_LINES * FTM_HUD_WIDTH] = "", after[FTM_HUD_LINES * FTM_HUD_WIDTH] = "";
    size_t widest = 0;
    for (int i = 0; i < n; i++) {
        strcat(before, lines[i]);
        strcat(before, " ");
        widest = strlen(lines[i]) > widest ? strlen(lines[i]) : widest;
    }
    const int cols = ftm_hud_columns(640, 2);
    assert_int_equal(cols, 51);
    assert_true(widest > (size_t)cols); /* (else there is nothing to wrap) */
    int rows = ftm_hud_wrap(lines, n, cols);
    assert_true(rows > n);
    for (int i = 0; i < rows; i++) {
        assert_true(strlen(lines[i]) <= (size_t)cols);
        strcat(after, lines[i]);
        strcat(after, " ");
    }
    /* the same words in the same order, whatever the spaces */
    char a[sizeof before], b[sizeof after];
    size_t na = 0, nb = 0;
    for (const char *p = before; *p; p++)
        if (*p != ' ')
            a[na++] = *p;
    for (const char *p = after; *p; p++)
        if (*p != ' ')
            b[nb++] = *p;
    a[na] = b[nb] = '\0';
    assert_string_equal(a, b);
    /* a wide window leaves the lines as they are */
    n = ftm_hud_lines(&v, &in, lines);
    assert_int_equal(ftm_hud_wrap(lines, n, ftm_hud_columns(1280, 1)), n);
}

static void test_instructor_keys(void **state)
{
    (void)state;
    ftm_client_view v = sample_view();
    v.depth_min = 2;
    v.depth_max = 3;
    v.tissue = (ftm_wire_tissue){0.001, 0.3, 50, {1, 1, 1}};
    ftm_wire_control c;
    char label[FTM_OUTCOME_TEXT];
    assert_false(ftm_hud_instructor_key(&v, FTM_WIRE_CMD_PAUSE, "pause", &c, label, sizeof label));
    assert_string_equal(label, "pause: not sent: no session joined yet");
    v.announced = true;
    assert_true(ftm_hud_instructor_key(&v, FTM_WIRE_CMD_DEPTH_LIMITS, "depth max -1", &c, label,
                                       sizeof label));
    assert_true(c.command == FTM_WIRE_CMD_DEPTH_LIMITS && c.depth_min == 2 && c.depth_max == 2);
    assert_string_equal(label, "depth max 2");
    v.depth_max = 2; /* at the floor */
    assert_false(ftm_hud_instructor_key(&v, FTM_WIRE_CMD_DEPTH_LIMITS, "depth max -1", &c, label,
                                        sizeof label));
    /* a fixed depth: the key says what would let it move */
    assert_string_equal(label, "depth max -1: not sent: the depth is fixed at 2 (floor = ceiling); "
                               "a server started without --adaptive 1 holds it there");
    assert_true(ftm_hud_instructor_key(&v, FTM_WIRE_CMD_DEPTH_LIMITS, "depth max +1", &c, label,
                                       sizeof label));
    assert_int_equal(c.depth_max, 3);
    assert_non_null(strstr(label, "only on a server started with --adaptive 1"));
    v.depth_max = 1000000;
    assert_false(ftm_hud_instructor_key(&v, FTM_WIRE_CMD_DEPTH_LIMITS, "depth max +1", &c, label,
                                        sizeof label));
    assert_non_null(strstr(label, "not sent: the ceiling is at the largest depth (1000000)"));
    assert_true(ftm_hud_instructor_key(&v, FTM_WIRE_CMD_TISSUE, "stiffer", &c, label, sizeof label));
    assert_true(c.tissue.stiffness == 50 * 1.25 && c.tissue.node_damping == 0.3);
    assert_string_equal(label, "stiffness 62.5 N/m");
    assert_true(ftm_hud_instructor_key(&v, FTM_WIRE_CMD_TISSUE, "softer", &c, label, sizeof label));
    assert_true(c.tissue.stiffness == 50 / 1.25);
    /* the scene's own tissue back (key t): not sent while in force */
    v.scene_tissue = v.tissue;
    assert_false(ftm_hud_instructor_key(&v, FTM_WIRE_CMD_TISSUE, "scene tissue", &c, label,
                                        sizeof label));
    assert_string_equal(label, "scene tissue: not sent: the scene's own tissue is in force");
    v.tissue.stiffness = 122.07;
    v.tissue.node_damping = 0.33;
    assert_true(ftm_hud_instructor_key(&v, FTM_WIRE_CMD_TISSUE, "scene tissue", &c, label,
                                       sizeof label));
    assert_true(c.tissue.stiffness == 50 && c.tissue.node_damping == 0.3);
    assert_string_equal(label, "scene tissue (k 50 N/m, d 0.3 N s/m)");
    assert_true(ftm_hud_instructor_key(&v, FTM_WIRE_CMD_RESET, "reset", &c, label, sizeof label));
    assert_true(c.command == FTM_WIRE_CMD_RESET);
    assert_string_equal(label, "reset");
    v.server_away = true;
    snprintf(v.banner, sizeof v.banner, "SERVER SILENT FOR 4 S: FORCE OFF");
    assert_false(ftm_hud_instructor_key(&v, FTM_WIRE_CMD_TISSUE, "stiffer", &c, label, sizeof label));
    assert_string_equal(label, "stiffer: not sent: the server is away (SERVER SILENT FOR 4 S: FORCE OFF)");
}

/* The help overlay: each role's mouse actions and keys, and only its own. */
static void test_help_per_role(void **state)
{
    (void)state;
    int n = ftm_hud_help(FTM_WIRE_ROLE_TRAINEE, true, false, false, lines);
    assert_true(find(n, "lower / raise the probe") >= 0);
    assert_true(find(n, "the probe back above the tissue") >= 0);
    assert_true(find(n, "reset the tissue") < 0);
    assert_true(find(n, "are the instructor's") >= 0);
    assert_true(find(n, "v  x  n") < 0);
    n = ftm_hud_help(FTM_WIRE_ROLE_INSTRUCTOR, false, true, true, lines);
    assert_true(find(n, "reset the tissue") >= 0);
    assert_true(find(n, "stiffer / softer") >= 0);
    assert_true(find(n, "the probe back above") < 0);
    assert_true(find(n, "left drag          orbit") >= 0);
    assert_true(find(n, "v  x  n") >= 0);
    assert_true(find(n, "the tissues' legend on / off") >= 0); /* a mesh with labels */
    n = ftm_hud_help(FTM_WIRE_ROLE_OBSERVER, false, false, false, lines);
    assert_true(find(n, "reset the tissue") < 0 && find(n, "haptic renderer") < 0);
    assert_true(find(n, "legend") < 0);
}

/* A trainee's probe line (height above the surface, push depth), the word
 * for a key it cannot use, and no "fading" without a force. */
static void test_trainee_probe_and_notice(void **state)
{
    (void)state;
    ftm_client_view v = sample_view();
    ftm_hud_info in = {.role = FTM_WIRE_ROLE_TRAINEE, .id = 11, .haptic = true,
                       .haptic_flags = 2 /* FTM_HAPTIC_STALE */, .renderer = "model",
                       .probe_where = FTM_HUD_PROBE_ABOVE, .probe_mm = 12.34,
                       .command_outcome = "pause: an instructor's key", .outcome_bad = true};
    int n = ftm_hud_lines(&v, &in, lines);
    assert_true(find(n, "probe 12.3 mm above the surface") >= 0);
    assert_true(find(n, "!! pause: an instructor's key") >= 0);
    assert_true(find(n, "fading") < 0);
    in.probe_where = FTM_HUD_PROBE_PRESSING;
    in.probe_mm = 4.5;
    in.force = (ftm_vec3){0, 0, 0.8};
    n = ftm_hud_lines(&v, &in, lines);
    assert_true(find(n, "probe pressing 4.5 mm deep") >= 0);
    assert_true(find(n, "fading") >= 0);
}

/* The waiting screen's picker: the sessions heard, numbered, names in
 * their own case; none once the session is announced. */
static void test_session_picker(void **state)
{
    (void)state;
    ftm_client_view v = sample_view();
    v.announced = false;
    v.nsessions = 2;
    snprintf(v.sessions[0], sizeof v.sessions[0], "Lesson-A");
    snprintf(v.sessions_about[0], sizeof v.sessions_about[0], "scene palpation, 1 trainee");
    snprintf(v.sessions[1], sizeof v.sessions[1], "other");
    snprintf(v.sessions_about[1], sizeof v.sessions_about[1], "scene default");
    ftm_hud_info in = {.role = FTM_WIRE_ROLE_TRAINEE, .id = 11, .session = "lesson-a"};
    int n = ftm_hud_lines(&v, &in, lines);
    assert_true(find(n, "session lesson-a") == 0);
    assert_true(find(n, "a key 1..2 or a click joins one") >= 0);
    assert_true(find(n, "  1  Lesson-A  (scene palpation, 1 trainee)") >= 0);
    assert_true(find(n, "  2  other  (scene default)") >= 0);
    v.announced = true;
    n = ftm_hud_lines(&v, &in, lines);
    assert_true(find(n, "Lesson-A") < 0);
}

int main(void)
{
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(test_cut_list_says_so),
        cmocka_unit_test(test_instructor_sees_debriefing),
        cmocka_unit_test(test_trainee_sees_own_figures),
        cmocka_unit_test(test_departed_trainee_kept),
        cmocka_unit_test(test_restart_forgets_departed),
        cmocka_unit_test(test_participant_order),
        cmocka_unit_test(test_command_outcome),
        cmocka_unit_test(test_instructor_keys),
        cmocka_unit_test(test_stable_range_shown),
        cmocka_unit_test(test_narrow_window_wraps),
        cmocka_unit_test(test_help_per_role),
        cmocka_unit_test(test_session_picker),
        cmocka_unit_test(test_trainee_probe_and_notice),
    };
    return cmocka_run_group_tests(tests, NULL, NULL);
}
