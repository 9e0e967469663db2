/* SPDX-License-Identifier: GPL-3.0-or-later */
/* ftm-server as a library: its definition (what the command line says,
 * with defaults), the program behind one call, and the argument parser.
 * The session fuzz target (tests/fuzz/fuzz_session.c) runs a server from a
 * definition of its own, many times in one process; main.c stays a line. */
#ifndef FTM_SERVER_H
#define FTM_SERVER_H

#include <stdbool.h>
#include <stdint.h>

#define FTM_SERVER_TRAINEES_MAX 8 /* --trainee scripts of an --offline run */
#define FTM_SERVER_RT_CPU_START (-1) /* --rt-cpu start: the CPU the server started on */
#define FTM_SERVER_RT_CPU_ANY (-2)   /* --rt-cpu any: not pinned */

/* A list of --trainee ID:T0:FILE arguments. */
typedef struct ftm_server_trainees {
    const char *arg[FTM_SERVER_TRAINEES_MAX];
    int count;
} ftm_server_trainees;

/* Everything a run is told (docs/server.md, ftm-server options). Strings
 * are borrowed: they must outlive the run. */
typedef struct ftm_server_def {
    const char *scene;    /* NULL: "default", or the recording's (--replay, --inputs) */
    const char *session;  /* NULL: "ftm", or the recording's */
    const char *config;   /* Cyclone DDS configuration; NULL: $CYCLONEDDS_URI */
    const char *security; /* DDS Security bundle directory; NULL: none */
    const char *log_path;
    uint32_t domain, id;
    double rate;          /* tick rate [Hz], whole */
    double keyframe_every, heartbeat, duration; /* [s]; duration 0: until a signal */
    int32_t depth;        /* -1: the scene's */
    /* adaptive depth (docs/server.md) */
    int32_t adaptive;     /* 1: adapt the depth to the load; 0: fixed */
    int32_t depth_floor;  /* -1: a quarter of the depth, at least 1 */
    double depth_hold_up; /* calm time before the depth goes up one step [s] */
    double max_penetration; /* longest push [m]; 0: the scene's size */
    /* recording, replay and offline runs */
    const char *record, *record_dir, *replay, *inputs, *report;
    int64_t offline_ticks; /* --offline N: N ticks without DDS */
    ftm_server_trainees trainees;
    const char *reactions_csv;
    /* observation */
    int32_t metrics_port; /* 0: off */
    const char *metrics_addr;
    const char *control_log;
    /* scheduling */
    int32_t rt_priority;  /* SCHED_FIFO priority of the tick thread; 0: off */
    int32_t rt_cpu;       /* >= 0, FTM_SERVER_RT_CPU_START or _ANY */
    bool check;           /* --check: set everything up, report, exit */
    bool upto_damage;     /* --upto-damage: replay a damaged recording up to the damage */
    /* resuming a lesson (docs/server.md, Resuming a lesson) */
    const char *resume;   /* --resume FILE: the lesson's first file */
    double resume_recent; /* --resume-recent S (with --record-dir); 0: off */
    bool resume_full;     /* --resume-full: the whole lesson's physics re-run */
} ftm_server_def;

/* The defaults, as --help states them. */
ftm_server_def ftm_default_server_def(void);

/* The command line into *def (from ftm_default_server_def()), every value
 * and their combinations checked, and no output a file the run reads.
 * Returns FTM_OPTIONS_OK (ftm/options.h), FTM_OPTIONS_HELP after printing
 * --help, or FTM_OPTIONS_BAD after saying what is wrong (exit status 2). */
int ftm_server_parse_args(int argc, char **argv, ftm_server_def *def);

/* Runs the server a definition describes and returns its exit status: 0
 * success, 1 a replay or input run that failed its check, 2 bad options, 3
 * a resource or start-up error. Each call is a server of its own: nothing
 * is kept from one call to the next. */
int ftm_server_run(const ftm_server_def *def);

/* ftm_server_parse_args, then ftm_server_run: the program. */
int ftm_server_main(int argc, char **argv);

#endif
