/* SPDX-License-Identifier: GPL-3.0-or-later */
/* ftm: the headless FTM tool. Dispatches to subcommands (tools/commands.h). */
#include "commands.h"

#include "ftm/ftm.h"

#include <errno.h>
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

typedef struct command {
    const char *name;
    int (*run)(int argc, char **argv);
    const char *summary;
} command;

static const command commands[] = {
    {"sim", ftm_cmd_sim, "run a scene (built-in or file) and report the result"},
    {"bench", ftm_cmd_bench, "run benchmarks (e.g. the paper's Table 3)"},
    {"experiment", ftm_cmd_experiment, "the paper's experiments: depth, tissue, anisotropy"},
    {"stability", ftm_cmd_stability, "stability sweep: measured boundary vs critical time step"},
    {"mesh", ftm_cmd_mesh, "a tissue mesh (.msh) from a segmented scan or a closed STL surface"},
#ifdef FTM_HAVE_FEM
    {"fem", ftm_cmd_fem, "solve a scene's linear static FEM reference (displacements as CSV)"},
    {"fit", ftm_cmd_fit, "identify spring parameters against the FEM reference (paper Tables 1-2)"},
#endif
};

#define COMMAND_COUNT (sizeof commands / sizeof commands[0])

static void usage(FILE *out)
{
    fprintf(out, "usage: ftm COMMAND [ARGS...]\n"
                 "       ftm help [COMMAND]\n"
                 "       ftm --version\n\n"
                 "commands:\n");
    for (size_t i = 0; i < COMMAND_COUNT; i++)
        fprintf(out, "  %-11s %s\n", commands[i].name, commands[i].summary);
    fprintf(out, "  %-11s %s\n\nbuilt-in scenes:", "help", "show this text or a command's help");
    for (const char *const *n = ftm_scene_builtin_names(); *n; n++)
        fprintf(out, " %s", *n);
    fprintf(out, "\n\nRun 'ftm help COMMAND' for a command's options.\n\n"
                 "exit status: 0 success, 2 bad arguments, input or output (a file or standard\n"
                 "output that cannot be written), other codes as each command's help says\n");
}

static const command *find(const char *name)
{
    for (size_t i = 0; i < COMMAND_COUNT; i++)
        if (strcmp(commands[i].name, name) == 0)
            return &commands[i];
    return NULL;
}

static int run(int argc, char **argv)
{
    if (argc < 2) {
        usage(stderr);
        return 2;
    }
    const char *name = argv[1];
    if (strcmp(name, "--version") == 0 || strcmp(name, "version") == 0) {
        printf("ftm %d.%d.%d\n", FTM_VERSION_MAJOR, FTM_VERSION_MINOR, FTM_VERSION_PATCH);
        return 0;
    }
    if (strcmp(name, "help") == 0 || strcmp(name, "--help") == 0 || strcmp(name, "-h") == 0) {
        if (argc < 3) {
            usage(stdout);
            return 0;
        }
        const command *c = find(argv[2]);
        if (!c) {
            fprintf(stderr, "ftm: unknown command '%s' (try 'ftm help')\n", argv[2]);
            return 2;
        }
        /* A command's help is its own --help. */
        char help[] = "--help";
        char *sub[] = {argv[2], help, NULL};
        return c->run(2, sub);
    }
    const command *c = find(name);
    if (!c) {
        fprintf(stderr, "ftm: unknown command '%s' (try 'ftm help')\n", name);
        return 2;
    }
    return c->run(argc - 1, argv + 1);
}

void ftm_json_number(FILE *f, double v, int digits)
{
    if (isfinite(v))
        fprintf(f, "%.*g", digits, v);
    else
        fputs("null", f);
}

void ftm_json_string(FILE *f, const char *s)
{
    fputc('"', f);
    for (; *s; s++) {
        unsigned char c = (unsigned char)*s;
        if (c == '"' || c == '\\')
            fprintf(f, "\\%c", c);
        else if (c < 0x20)
            fprintf(f, "\\u%04x", c);
        else
            fputc(c, f);
    }
    fputc('"', f);
}

const char *ftm_json_num(char *buf, const char *fmt, double v)
{
    if (isfinite(v))
        snprintf(buf, FTM_JSON_NUM, fmt, v);
    else
        snprintf(buf, FTM_JSON_NUM, "null");
    return buf;
}

int ftm_close_output(FILE *f, const char *who, const char *path)
{
    bool failed = ferror(f) != 0;
    int e = 0;
    if (fclose(f) != 0) {
        failed = true;
        e = errno;
    }
    if (!failed)
        return 0;
    fprintf(stderr, "%s: %s: cannot write: %s\n", who, path, e ? strerror(e) : "write error");
    return -1;
}

int main(int argc, char **argv)
{
    int status = run(argc, argv);
    /* Whatever a command printed must have arrived: on a full disk the
     * report would otherwise end short without a word. A command that failed
     * has said why already (perhaps this very thing). */
    bool failed = ferror(stdout) != 0;
    int e = 0;
    if (fflush(stdout) != 0) {
        failed = true;
        e = errno;
    }
    if (failed && status == 0) {
        fprintf(stderr, "ftm: standard output: cannot write: %s\n",
                e ? strerror(e) : "write error");
        status = 2;
    }
    return status;
}

bool ftm_cli_double(const char *s, double *out)
{
    char *end;
    double v = strtod(s, &end);
    if (end == s || *end != '\0' || !isfinite(v))
        return false;
    *out = v;
    return true;
}

bool ftm_cli_int(const char *s, long lo, long hi, int *out)
{
    char *end;
    errno = 0;
    long v = strtol(s, &end, 10);
    if (end == s || *end != '\0' || errno == ERANGE || v < lo || v > hi)
        return false;
    *out = (int)v;
    return true;
}
