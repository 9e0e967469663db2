/* SPDX-License-Identifier: GPL-3.0-or-later */
/* ftm-server's options: the definition's defaults, its option table (the
 * parser and --help, ftm/options.h) and the checks of values together. */
#define _GNU_SOURCE /* CPU_SETSIZE */
#include "cli.h"
#include "depth_ctl.h"
#include "rooms.h"

#include "ftm/options.h"

#include <arpa/inet.h>
#include <float.h>
#include <sched.h>
#include <stdio.h>
#include <string.h>
#include <sys/stat.h>

ftm_server_def ftm_default_server_def(void)
{
    return (ftm_server_def){.id = 1, .rate = 1000.0, .keyframe_every = 1.0, .heartbeat = 0.1,
                            .depth = -1, .depth_floor = -1, .depth_hold_up = 2.0,
                            .rt_priority = 10, .rt_cpu = FTM_SERVER_RT_CPU_START,
                            .metrics_addr = "127.0.0.1"};
}

/* Whether an address (inet_pton's bytes) is one no client can connect to:
 * multicast (IPv4 224.0.0.0/4, IPv6 ff00::/8) or the IPv4 broadcast
 * address, also IPv4-mapped. Binding to them succeeds, so the metrics would
 * say where they listen and never answer. */
static bool unreachable_addr(const unsigned char *a, bool v6)
{
    static const unsigned char mapped[12] = {0, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0xff, 0xff};
    if (v6 && a[0] == 0xff)
        return true;
    if (v6 && memcmp(a, mapped, sizeof mapped) != 0)
        return false;
    const unsigned char *v4 = v6 ? a + 12 : a;
    return (v4[0] >= 224 && v4[0] <= 239) ||
           (v4[0] == 255 && v4[1] == 255 && v4[2] == 255 && v4[3] == 255);
}

static int parse_metrics_addr(const ftm_option *o, const char *v, void *field, char *why,
                              size_t cap)
{
    unsigned char addr[16];
    bool v4 = inet_pton(AF_INET, v, addr) == 1;
    if (!v4 && inet_pton(AF_INET6, v, addr) != 1) {
        snprintf(why, cap, "needs an IPv4 or IPv6 address (got '%s')", v);
        return -1;
    }
    if (unreachable_addr(addr, !v4)) {
        snprintf(why, cap, "%s is a multicast or broadcast address, which no client can connect "
                           "to: give one of this host's addresses (0.0.0.0 or :: for all)", v);
        return -1;
    }
    memcpy(field, &v, sizeof v);
    return 0;
}

static int parse_rt_cpu(const ftm_option *o, const char *v, void *field, char *why, size_t cap)
{
    long long n = 0;
    int32_t cpu;
    if (strcmp(v, "start") == 0)
        cpu = FTM_SERVER_RT_CPU_START;
    else if (strcmp(v, "any") == 0)
        cpu = FTM_SERVER_RT_CPU_ANY;
    else if (ftm_option_int(v, strlen(v), 0, CPU_SETSIZE - 1, &n))
        cpu = (int32_t)n;
    else {
        snprintf(why, cap, "must be 'start', 'any' or a CPU number in 0..%d (got '%s')",
                 CPU_SETSIZE - 1, v);
        return -1;
    }
    memcpy(field, &cpu, sizeof cpu);
    return 0;
}

/* --trainee, repeatable (checked when the run reads the scripts) */
static int parse_trainee(const ftm_option *o, const char *v, void *field, char *why, size_t cap)
{
    ftm_server_trainees *t = field;
    if (t->count == FTM_SERVER_TRAINEES_MAX) {
        snprintf(why, cap, "given more than %d times: at most %d trainees", FTM_SERVER_TRAINEES_MAX,
                 FTM_SERVER_TRAINEES_MAX);
        return -1;
    }
    t->arg[t->count++] = v;
    return 0;
}

#define D ftm_server_def
#define SECONDS FTM_OPTION_SECONDS_MAX
static const ftm_option options[] = {
    FTM_OPT_STRING("scene", "NAME|FILE", D, scene, "scene to serve (default: default)"),
    FTM_OPT_STRING("session", "NAME", D, session, "session name (default: ftm)"),
    FTM_OPT_INT("domain", "N", D, domain, 0, FTM_OPTION_DOMAIN_MAX, "DDS domain id (default 0)"),
    FTM_OPT_STRING("config", "FILE", D, config,
                   "Cyclone DDS configuration (default: $CYCLONEDDS_URI)"),
    FTM_OPT_STRING("security", "DIR", D, security,
                   "DDS Security: this server's identity and permissions\n"
                   "(made by deploy/ftm-security issue DIR NAME --role server)"),
    FTM_OPT_DOUBLE("rate", "HZ", D, rate, 1, 100000, FTM_OPTION_WHOLE, "hertz",
                   "tick rate (default 1000)"),
    FTM_OPT_DOUBLE("keyframe-every", "S", D, keyframe_every, 0, SECONDS, FTM_OPTION_ABOVE_LO,
                   "seconds", "periodic keyframe interval in seconds (default 1)"),
    FTM_OPT_DOUBLE("heartbeat", "S", D, heartbeat, 0, 10, FTM_OPTION_ABOVE_LO, "seconds",
                   "idle heartbeat interval in seconds, <= 10 (default 0.1)"),
    FTM_OPT_INT("depth", "N", D, depth, 0, FTM_DEPTH_CTL_MAX,
                "penetration depth (default: the scene's)"),
    FTM_OPT_DOUBLE("duration", "S", D, duration, 0, SECONDS, 0, "seconds",
                   "stop after S seconds (default: until SIGINT/SIGTERM)"),
    FTM_OPT_INT("id", "N", D, id, 1, UINT32_MAX, "participant id (default 1)"),
    FTM_OPT_STRING("log", "FILE", D, log_path, "also write the log to FILE"),
    FTM_OPT_INT("adaptive", "0|1", D, adaptive, 0, 1,
                "adapt the depth to the load (default 0; --depth is the ceiling)"),
    FTM_OPT_INT("depth-floor", "N", D, depth_floor, 0, FTM_DEPTH_CTL_MAX,
                "lowest adaptive depth (default: depth / 4, at least 1)"),
    FTM_OPT_DOUBLE("depth-hold-up", "S", D, depth_hold_up, 0, 3600, 0, "seconds",
                   "calm time before each depth increase (default 2)"),
    FTM_OPT_STRING("record", "FILE", D, record, "record every input and published message to FILE"),
    FTM_OPT_STRING("replay", "FILE", D, replay, "re-simulate a recording, check every hash, exit"),
    FTM_OPT_STRING("inputs", "FILE", D, inputs,
                   "run a recording's inputs through this server, without DDS\n"
                   "(its frames ignored; with --record, record the result)"),
    FTM_OPT_FLAG("upto-damage", D, upto_damage,
                 "(replay, inputs) take a damaged recording up to its first\n"
                 "damaged entry, with a note, instead of refusing it"),
    FTM_OPT_STRING("resume", "FILE", D, resume,
                   "resume the lesson recorded in FILE (and FILE.1, ...) that its\n"
                   "server did not end: re-run it to its last tick, go on from\n"
                   "there and record on to its next file FILE.N"),
    FTM_OPT_FLAG("resume-full", D, resume_full,
                 "(resume) re-run the whole lesson's physics, not only the ticks\n"
                 "after its last keyframe"),
    FTM_OPT_DOUBLE("resume-recent", "S", D, resume_recent, 0, SECONDS, FTM_OPTION_ABOVE_LO,
                   "seconds",
                   "(record-dir) resume the newest lesson there if its server did\n"
                   "not end it and it was written less than S s ago; else a new one"),
    FTM_OPT_INT("metrics-port", "N", D, metrics_port, 0, 65535,
                "Prometheus metrics on http://ADDR:N/metrics (0: off)"),
    FTM_OPT_CUSTOM("metrics-addr", "ADDR", D, metrics_addr, parse_metrics_addr,
                   "address the metrics listen on (default 127.0.0.1)"),
    FTM_OPT_STRING("record-dir", "DIR", D, record_dir,
                   "record each run to a new file DIR/SESSION-<UTC time>.rec,\n"
                   "with its report (--report) beside it as .json"),
    FTM_OPT_STRING("report", "FILE", D, report,
                   "at the end, what each participant did as JSON (touches,\n"
                   "contact time, forces, pushes); also with --replay/--inputs"),
    FTM_OPT_FLAG("check", D, check,
                 "set up as for the session (scene, DDS, files, metrics),\n"
                 "print what it would be and exit: 0 if it would start"),
    FTM_OPT_STRING("control-log", "FILE", D, control_log,
                   "CSV every 100 ms: time, tick, depth, step, lag, backlog, rate"),
    FTM_OPT_INT("offline", "N", D, offline_ticks, 1, INT64_MAX,
                "run N ticks without DDS, trainees from --trainee scripts"),
    FTM_OPT_CUSTOM("trainee", "ID:T0:FILE", D, trainees, parse_trainee,
                   "(offline) trainee ID plays bot script FILE; tick k uses\n"
                   "the HIP at script time T0 + k / rate (repeatable, <= 8)"),
    FTM_OPT_STRING("reactions", "FILE", D, reactions_csv,
                   "(offline, replay) CSV per probe in contact per tick:\n"
                   "tick,participant,probe,fx,fy,fz,time_s,push_m,push_limited"),
    FTM_OPT_DOUBLE("max-penetration", "M", D, max_penetration, 0, DBL_MAX, FTM_OPTION_ABOVE_LO,
                   "metres",
                   "longest push a probe imposes on the tissue, in metres\n"
                   "(default: the scene's size, the longest side of its rest surface's box)"),
    FTM_OPT_INT("rt-priority", "N", D, rt_priority, 0, 98,
                "SCHED_FIFO priority of the tick thread, the publishing\n"
                "thread one above, where permitted (default 10; 0: off)"),
    FTM_OPT_CUSTOM("rt-cpu", "start|any|N", D, rt_cpu, parse_rt_cpu,
                   "with --rt-priority: both threads on the CPU the server\n"
                   "started on (default), on no CPU in particular, or on CPU N"),
    {0}};
#undef D

static const ftm_option_set option_set = {"ftm-server", "usage: ftm-server [options]", options,
                                          "docs/server.md describes each option."};

/* The values together: what no single option's range can say. */
static int check_combined(const ftm_server_def *o)
{
    const char *why = NULL;
    if (o->depth >= 0 && o->depth_floor > o->depth)
        why = "--depth-floor must be at most --depth";
    else if ((o->replay != NULL) + (o->inputs != NULL) + (o->offline_ticks != 0) > 1 ||
             (o->record && (o->replay || o->offline_ticks)))
        why = "--replay, --inputs and --offline exclude each other; --record goes with a session "
              "or --inputs";
    else if (o->record_dir && (o->record || o->replay || o->inputs || o->offline_ticks))
        why = "--record-dir goes with a session, without --record";
    else if (o->check && (o->replay || o->inputs || o->offline_ticks))
        why = "--check checks a session's set-up: not with --replay, --inputs or --offline";
    else if (o->trainees.count && !o->offline_ticks)
        why = "--trainee goes with --offline";
    else if (o->reactions_csv && !o->offline_ticks && !o->replay && !o->inputs)
        why = "--reactions goes with --offline, --replay or --inputs";
    else if (o->upto_damage && !o->replay && !o->inputs)
        why = "--upto-damage goes with --replay or --inputs";
    else if (o->resume && (o->record || o->record_dir || o->replay || o->inputs ||
                           o->offline_ticks || o->check || o->resume_recent > 0))
        why = "--resume goes with a session, without --record or --record-dir (the lesson is "
              "recorded on to its next file), --replay, --inputs, --offline, --check or "
              "--resume-recent";
    else if (o->resume_full && !o->resume && !(o->resume_recent > 0))
        why = "--resume-full goes with --resume or --resume-recent";
    else if (o->resume_recent > 0 && !o->record_dir)
        why = "--resume-recent goes with --record-dir (the lessons it looks at)";
    if (why)
        fprintf(stderr, "ftm-server: %s\n", why);
    return why ? -1 : 0;
}

/* The files a run writes, by option (--record-dir's are new files). */
static int outputs_of(const ftm_server_def *o, ftm_option_path out[5])
{
    const ftm_option_path all[5] = {
        {"--record", o->record}, {"--log", o->log_path}, {"--report", o->report},
        {"--control-log", o->control_log}, {"--reactions", o->reactions_csv}};
    int n = 0;
    for (int i = 0; i < 5; i++)
        if (all[i].path)
            out[n++] = all[i];
    return n;
}

/* Before anything is opened for writing: an output that is a file the run
 * reads — the recording --replay or --inputs reads, the scene file, the DDS
 * configuration, a --trainee script — (the same file, by device and inode:
 * another name, a link) would be truncated before it is read. */
static int outputs_apart_from_input(const ftm_server_def *o)
{
    ftm_option_path in[4 + FTM_SERVER_TRAINEES_MAX];
    int nin = 0;
    if (o->replay || o->inputs)
        in[nin++] = (ftm_option_path){o->replay ? "--replay" : "--inputs",
                                      o->replay ? o->replay : o->inputs};
    else if (o->resume)
        in[nin++] = (ftm_option_path){"--resume", o->resume};
    if (o->scene) /* a built-in name is no file: skipped */
        in[nin++] = (ftm_option_path){"--scene", o->scene};
    if (o->config)
        in[nin++] = (ftm_option_path){"--config", o->config};
    for (int t = 0; t < o->trainees.count; t++) { /* ID:T0:FILE */
        const char *c = strchr(o->trainees.arg[t], ':');
        if (c && (c = strchr(c + 1, ':')))
            in[nin++] = (ftm_option_path){"--trainee", c + 1};
    }
    ftm_option_path out[5];
    const int nout = outputs_of(o, out);
    int k, i;
    if (!ftm_option_output_is_input(in, nin, out, nout, &k, &i))
        return 0;
    fprintf(stderr, "ftm-server: %s %s is the %s %s %s reads: it would be overwritten; write to "
                    "another file\n", out[i].opt, out[i].path,
            k == 0 && (o->replay || o->inputs || o->resume) ? "recording" : "file", in[k].opt,
            in[k].path);
    return -1;
}

int ftm_server_parse_args(int argc, char **argv, ftm_server_def *def)
{
    int rc = ftm_options_parse(&option_set, argc, argv, def, NULL, NULL);
    if (rc != FTM_OPTIONS_OK)
        return rc;
    if (check_combined(def) || outputs_apart_from_input(def))
        return FTM_OPTIONS_BAD;
    return FTM_OPTIONS_OK;
}

const char *ftm_server_output_dir(const ftm_server_def *def, const char **opt)
{
    ftm_option_path out[5];
    const int n = outputs_of(def, out);
    struct stat st;
    for (int i = 0; i < n; i++)
        if (stat(out[i].path, &st) == 0 && S_ISDIR(st.st_mode)) {
            *opt = out[i].opt;
            return out[i].path;
        }
    return NULL;
}
