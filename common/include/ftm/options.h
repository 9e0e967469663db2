/* SPDX-License-Identifier: GPL-3.0-or-later */
/* Command-line options from one table. A program lists its options once, as
 * an array of ftm_option: the table drives the parser (libc's getopt_long)
 * and the --help text, so that what a program accepts and what it says it
 * accepts cannot drift apart, and every program refuses a bad value in the
 * same words, naming the option.
 *
 * What getopt_long gives every program (docs/options.md):
 *   --opt VALUE and --opt=VALUE alike; an unambiguous prefix of a long name
 *   (--sess for --session); -h and --help; options in any order, the last
 *   of a repeated one winning (unless its parser collects them).
 * What the table adds: a value that is itself an option (--scene --duration
 * 2) is refused as "--scene needs a value" (a value that starts with "--"
 * is written --scene=--odd); numbers are whole tokens in a stated range,
 * nothing cast or wrapped ("-1" is no 4294967295, "1e300" no duration).
 *
 * Values are stored into a struct of the program's (the table holds each
 * field's offset and size), so one const table serves every call; the
 * parser keeps no state of its own between calls (getopt's is reset).
 * No physics, no I/O beyond printing --help and refusals. */
#ifndef FTM_OPTIONS_H
#define FTM_OPTIONS_H

#include "ftm/base.h"

#include <stddef.h>
#include <stdint.h>
#include <stdio.h>

#ifdef __cplusplus
extern "C" {
#endif

typedef enum ftm_option_type {
    FTM_OPTION_END = 0, /* ends a table ({0}) */
    FTM_OPTION_SECTION, /* a heading in --help (help is its text); no option */
    FTM_OPTION_FLAG,    /* no value: sets a bool */
    FTM_OPTION_STRING,  /* const char *: the argument itself */
    FTM_OPTION_INT,     /* a whole base-10 number in [min, max]; a 4- or 8-byte field */
    FTM_OPTION_DOUBLE,  /* a finite decimal number in [lo, hi] (flags below) */
    FTM_OPTION_CUSTOM,  /* parse() reads it */
} ftm_option_type;

#define FTM_OPTION_ABOVE_LO 1u /* DOUBLE: lo itself is refused, (lo, hi] */
#define FTM_OPTION_WHOLE 2u    /* DOUBLE: a whole number */

typedef struct ftm_option ftm_option;

/* A value's own reader (FTM_OPTION_CUSTOM): reads value into field. On
 * refusal returns -1 with why completing "PROGRAM: --NAME " ("must be WxH,
 * ... (got 'x')"). */
typedef int (*ftm_option_parse_fn)(const ftm_option *opt, const char *value, void *field,
                                   char *why, size_t cap);

struct ftm_option {
    ftm_option_type type;
    const char *name;  /* long name without the dashes */
    const char *arg;   /* the value's name in --help ("N", "FILE"); NULL for a flag */
    size_t offset;     /* of the field in the program's options struct */
    size_t size;       /* of the field */
    long long min, max; /* INT */
    double lo, hi;     /* DOUBLE; hi DBL_MAX: no upper bound */
    const char *unit;  /* DOUBLE, for refusals: "seconds" ("a number of seconds in ...") */
    unsigned flags;
    ftm_option_parse_fn parse; /* CUSTOM */
    const char *help;  /* --help text: lines separated by '\n' */
};

/* Table entries: T is the options struct, F its field. */
#define FTM_OPT_FIELD_(T, F) .offset = offsetof(T, F), .size = sizeof(((T *)0)->F)
#define FTM_OPT_SECTION(TEXT) {.type = FTM_OPTION_SECTION, .help = (TEXT)}
#define FTM_OPT_FLAG(NAME, T, F, HELP) \
    {.type = FTM_OPTION_FLAG, .name = (NAME), FTM_OPT_FIELD_(T, F), .help = (HELP)}
#define FTM_OPT_STRING(NAME, ARG, T, F, HELP) \
    {.type = FTM_OPTION_STRING, .name = (NAME), .arg = (ARG), FTM_OPT_FIELD_(T, F), .help = (HELP)}
#define FTM_OPT_INT(NAME, ARG, T, F, MIN, MAX, HELP)                                            \
    {.type = FTM_OPTION_INT, .name = (NAME), .arg = (ARG), FTM_OPT_FIELD_(T, F), .min = (MIN), \
     .max = (MAX), .help = (HELP)}
#define FTM_OPT_DOUBLE(NAME, ARG, T, F, LO, HI, FLAGS, UNIT, HELP)                             \
    {.type = FTM_OPTION_DOUBLE, .name = (NAME), .arg = (ARG), FTM_OPT_FIELD_(T, F), .lo = (LO), \
     .hi = (HI), .flags = (FLAGS), .unit = (UNIT), .help = (HELP)}
#define FTM_OPT_CUSTOM(NAME, ARG, T, F, FN, HELP)                                              \
    {.type = FTM_OPTION_CUSTOM, .name = (NAME), .arg = (ARG), FTM_OPT_FIELD_(T, F), .parse = (FN), \
     .help = (HELP)}

/* A program's options. */
typedef struct ftm_option_set {
    const char *program;       /* "ftm-server": every message starts with it */
    const char *usage;         /* the first lines of --help ("usage: ftm-server [options]") */
    const ftm_option *options; /* ended by {0}; at most 64 entries */
    const char *epilogue;      /* printed after the options; NULL: none */
} ftm_option_set;

enum {
    FTM_OPTIONS_OK = 0,
    FTM_OPTIONS_HELP = 1, /* --help printed on stdout: exit 0 */
    FTM_OPTIONS_BAD = -1, /* refused, the message printed on stderr: exit 2 */
};

/* Parses argv[1..argc) into the struct at values (its defaults set by the
 * caller). given (NULL: not wanted) receives a bit per table entry that
 * was on the command line (ftm_options_given). Arguments that are no
 * options are refused, unless first_arg is given: it then receives the
 * index in argv of the first of them (getopt_long moves them to the end;
 * argc when there are none). */
int ftm_options_parse(const ftm_option_set *set, int argc, char **argv, void *values,
                      uint64_t *given, int *first_arg);

/* Whether the option named name was given (a bit from ftm_options_parse). */
bool ftm_options_given(const ftm_option_set *set, uint64_t given, const char *name);

/* The --help text: usage, one line or more per option, epilogue. */
void ftm_options_help(const ftm_option_set *set, FILE *f);

/* An integer value v[0..len): a whole base-10 number in lo..hi, nothing
 * cast or wrapped ("-1" is not 4294967295, 4294967376 is not 80). */
bool ftm_option_int(const char *v, size_t len, long long lo, long long hi, long long *out);

/* The longest time an option may give [s], about 31.7 years: in nanoseconds
 * it still fits 64-bit clock arithmetic (a larger double wraps when cast). */
#define FTM_OPTION_SECONDS_MAX 1e9

#ifdef __cplusplus
}
#endif
#endif
