/* SPDX-License-Identifier: GPL-3.0-or-later */
/* The ftm-bot script format (docs/bot-script.md), parsed in one place for
 * every reader: ftm-bot, ftm-client --commands and ftm-server --offline
 * (script.h), and the scripted haptic device (device.h), so that a file
 * means the same trajectory to all of them. No wire types here: commands
 * come back as keywords with their numbers.
 *
 * Library ftm_script_text: libftm only (its base types, and the text reader
 * its scene and mesh parsers use). */
#ifndef FTM_SESSION_SCRIPT_TEXT_H
#define FTM_SESSION_SCRIPT_TEXT_H

#include "ftm/base.h"

#include <stdbool.h>
#include <stddef.h>
#include <stdint.h>

#define FTM_SCRIPT_COMMANDS_MAX 64 /* timed commands (join and leave not counted) */
#define FTM_SCRIPT_EXPECTS_MAX 64  /* expectations (`expect` lines) */
#define FTM_SCRIPT_LINE_MAX 511    /* bytes of a line, without its newline */
#define FTM_SCRIPT_FILE_MAX ((size_t)64 << 20)

typedef struct ftm_script_point {
    double t;   /* [s], >= 0 */
    ftm_vec3 p; /* HIP [m] */
} ftm_script_point;

typedef enum ftm_script_keyword {
    FTM_SCRIPT_KW_PAUSE = 1,
    FTM_SCRIPT_KW_RESUME,
    FTM_SCRIPT_KW_RESET,
    FTM_SCRIPT_KW_STIFFNESS, /* value[0] > 0 [N/m] */
    FTM_SCRIPT_KW_DAMPING,   /* value[0] >= 0 [N s/m] */
    FTM_SCRIPT_KW_MASS,      /* value[0] > 0 [kg] */
    FTM_SCRIPT_KW_DEPTH,     /* value[0] = min, value[1] = max: whole, 0 <= min <= max <= 1e6 */
} ftm_script_keyword;

typedef struct ftm_script_entry {
    ftm_script_keyword keyword;
    double t; /* [s], >= 0 */
    double value[2];
    int32_t line;
} ftm_script_entry;

/* `expect t0 t1 force|peak MIN MAX` and `expect t0 t1 contact yes|no`:
 * what ftm-bot checks in the frames it applies at times t0..t1
 * (docs/bot-script.md). Not commands: readers that do not check them
 * leave them alone. */
typedef enum ftm_script_expect_kind {
    FTM_SCRIPT_EXPECT_FORCE = 1, /* every frame's |F| in [lo, hi] N */
    FTM_SCRIPT_EXPECT_PEAK,      /* the window's largest |F| in [lo, hi] N */
    FTM_SCRIPT_EXPECT_CONTACT,   /* every frame in contact (contact) or none */
} ftm_script_expect_kind;

typedef struct ftm_script_expect {
    ftm_script_expect_kind kind;
    double t0, t1;  /* [s], 0 <= t0 <= t1 */
    double lo, hi;  /* [N], 0 <= lo <= hi (force, peak) */
    bool contact;   /* (contact) */
    int32_t line;
} ftm_script_expect;

typedef struct ftm_script_text {
    ftm_script_point *pts; /* times strictly increasing; NULL when npts == 0 */
    int32_t npts;
    ftm_script_entry cmds[FTM_SCRIPT_COMMANDS_MAX]; /* in file order */
    int32_t ncmds;
    ftm_script_expect expects[FTM_SCRIPT_EXPECTS_MAX]; /* in file order */
    int32_t nexpects;
    double join;  /* `join t`, default 0 */
    double leave; /* `leave t`, -1: none */
    bool session_clock; /* `clock session`: times but join's count from the
                         * first moment the bot may act in the session */
} ftm_script_text;

/* Parses a script held in memory; name is used in error messages
 * ("trainee.bot:7: expected 't x y z' (4 numbers)"). On error (FTM_EPARSE,
 * FTM_ENOMEM) *out is empty and needs no free. Every number must be a whole
 * token ("0+1" is not two numbers) and finite. */
int ftm_script_text_parse(const char *text, size_t length, const char *name,
                          ftm_script_text *out, ftm_error *err);
/* Reads and parses a file; errors name the path: FTM_EIO if it cannot be
 * read, FTM_ERANGE over FTM_SCRIPT_FILE_MAX bytes, FTM_EPARSE with a NUL byte. */
int ftm_script_text_read(const char *path, ftm_script_text *out, ftm_error *err);
void ftm_script_text_free(ftm_script_text *s);

/* The HIP at time t: linear between points (exactly a point at its time),
 * held before the first and after the last. n >= 1. */
ftm_vec3 ftm_script_points_at(const ftm_script_point *p, int32_t n, double t);

#endif
