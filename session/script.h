/* SPDX-License-Identifier: GPL-3.0-or-later */
/* ftm-bot scripts (docs/bot-script.md): a probe's HIP trajectory over time
 * and timed session commands. Shared by ftm-bot, which plays a script on
 * the wall clock, and ftm-server --offline, which plays it on the tick
 * clock without DDS (the reference the session tests compare against). */
#ifndef FTM_SESSION_SCRIPT_H
#define FTM_SESSION_SCRIPT_H

#include "ftm/wire.h"
#include "script_text.h" /* the format's parser, ftm_script_point */

#include <stdio.h>

/* A timed command as parsed (keyword, time, values) and whether it was sent. */
typedef struct ftm_script_command {
    ftm_script_entry e;
    bool done;
} ftm_script_command;

/* An expectation as parsed and what the frames in its window showed. */
typedef struct ftm_script_check {
    ftm_script_expect e;
    int64_t frames, in_contact; /* frames in the window; those with the probe in contact */
    double min, max, max_t;     /* |F| [N] over them; when the max came [s] */
    bool broken;                /* a frame broke it (force, contact): the first one */
    double bad_t, bad_f;        /* [s], |F| [N] */
    uint64_t bad_tick;
} ftm_script_check;

typedef struct ftm_script {
    ftm_script_point *pts; /* times >= 0, strictly increasing */
    int32_t npts;
    ftm_script_command cmds[FTM_SCRIPT_COMMANDS_MAX];
    int32_t ncmds;
    ftm_script_check expects[FTM_SCRIPT_EXPECTS_MAX];
    int32_t nexpects;
    double join, leave; /* leave < 0: none */
    bool session_clock; /* `clock session` (script_text.h) */
} ftm_script;

/* Reads a script file. On error prints `FILE:LINE: reason` to stderr and
 * returns -1 (nothing to free). */
int ftm_script_load(const char *path, ftm_script *sc);
void ftm_script_free(ftm_script *sc);

/* The SessionControl of a script command; issuer and command_id are left to
 * the sender. A tissue command changes one parameter of now, the tissue in
 * force. Returns the command's name for logs ("pause", "stiffness", ...). */
const char *ftm_script_control(const ftm_script_command *c, const ftm_wire_tissue *now,
                               ftm_wire_control *out);

/* A command for logs and the HUD, with its value: "stiffness 80 N/m",
 * "depth limits 2..6", "pause". */
void ftm_script_command_text(const ftm_script_command *c, char *text, size_t cap);

/* The HIP at time t (ftm_script_points_at). The script must have at least
 * one point. */
ftm_vec3 ftm_script_at(const ftm_script *sc, double t);

/* A frame applied at script time t [s]: its tick, the reaction force on the
 * probe and whether the probe is in contact. Counted by every expectation
 * whose window holds t (t0 <= t <= t1). */
void ftm_script_expect_frame(ftm_script *sc, double t, uint64_t tick, ftm_vec3 force,
                             bool contact);
/* Prints one line per expectation to f: "NAME:LINE: expect ...: ok (...)"
 * or "...: FAILED: why". end: the script time the frames stopped [s]; a
 * window not over by then fails, as does one without frames. Returns how
 * many failed. */
int ftm_script_expect_report(const ftm_script *sc, const char *name, double end, FILE *f);

#endif
