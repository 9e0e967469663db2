/* SPDX-License-Identifier: GPL-3.0-or-later */
/* Subcommands of the `ftm` tool. Each takes the arguments from the
 * subcommand's name on (argv[0] is "sim", "bench", ...) and returns the
 * process exit status: 0 success, 2 bad arguments or input or an output that
 * cannot be written, other codes as
 * documented by the command. */
#ifndef FTM_TOOLS_COMMANDS_H
#define FTM_TOOLS_COMMANDS_H

#include <stdbool.h>
#include <stdio.h>

/* Closes f, a file a command wrote. If a write failed, now or earlier (the
 * stream remembers it), says "WHO: PATH: cannot write: REASON" and returns
 * -1; else 0. */
int ftm_close_output(FILE *f, const char *who, const char *path);

/* A JSON number with that many significant digits, or null for a
 * non-finite value (JSON has no infinity or NaN). */
void ftm_json_number(FILE *f, double v, int digits);
/* The same as text for a printf argument: v printed with fmt (a format of
 * one double, such as "%.6g"), or null for a non-finite value, written into
 * buf (FTM_JSON_NUM bytes) and returned. FTM_JN(fmt, v) gives each use a
 * buffer of its own, which lasts to the end of the enclosing block. */
#define FTM_JSON_NUM 64
const char *ftm_json_num(char *buf, const char *fmt, double v);
#define FTM_JN(fmt, v) ftm_json_num((char[FTM_JSON_NUM]){0}, fmt, v)

/* A JSON string: s in quotes, with quotes, backslashes and control
 * characters escaped (scene names and paths may hold them). */
void ftm_json_string(FILE *f, const char *s);

/* Option values: all of s one finite number (strtod's syntax), or one
 * whole decimal integer in [lo, hi]; false (and *out untouched) if not. */
bool ftm_cli_double(const char *s, double *out);
bool ftm_cli_int(const char *s, long lo, long hi, int *out);

int ftm_cmd_sim(int argc, char **argv);
int ftm_cmd_bench(int argc, char **argv);
int ftm_cmd_fem(int argc, char **argv); /* only with FTM_HAVE_FEM (ftm_fem linked) */
int ftm_cmd_fit(int argc, char **argv); /* only with FTM_HAVE_FEM: parameter identification */
int ftm_cmd_experiment(int argc, char **argv);
/* `ftm experiment volume` (exp_volume.c): argv[0] is "volume"; json when
 * --json came before the name. */
int ftm_experiment_volume(int argc, char **argv, bool json);
/* `ftm experiment organs` (exp_organs.c), the same way. */
int ftm_experiment_organs(int argc, char **argv, bool json);
int ftm_cmd_stability(int argc, char **argv);
/* `ftm mesh` (cmd_mesh.c): runs ftm-mesh from beside ftm, or says why not. */
int ftm_cmd_mesh(int argc, char **argv);

#endif
