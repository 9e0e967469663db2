/* SPDX-License-Identifier: GPL-3.0-or-later */
/* ftm-bot: a scripted headless participant (docs/bot-script.md).
 *
 * Joins a session as trainee, observer or instructor, replays the server's
 * tick frames with ftm_replay like a real client, drives a probe along a
 * scripted HIP trajectory (trainee) or issues scripted session commands
 * (instructor), publishes its status every 500 ms, and logs reaction forces,
 * latency and hashes; checks the script's expectations on the forces it
 * receives (trainee) and what the server replied to each command
 * (instructor). Exit status: 0 synced at the end; 1 a hash mismatch or gap
 * that did not recover (or never synced); 2 usage; 3 set-up failure; 4
 * otherwise fine, but the script did not hold: an expectation failed or a
 * command was refused or never answered (docs/bot-script.md). */
#include "cli.h"
#include "participant.h"
#include "script.h"
#include "sessions.h"
#include "tissue.h"

#include "ftm/clock.h"
#include "ftm/scene.h"
#include "ftm/wire.h"

#include <ctype.h>
#include <errno.h>
#include <inttypes.h>
#include <math.h>
#include <signal.h>
#include <stdarg.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <time.h>
#include <unistd.h>

#define SEC FTM_NS_PER_S
/* (a larger time would wrap when cast: --duration 1e300 stopped at once) */
#define MAX_SECONDS FTM_OPTION_SECONDS_MAX
/* The shortest --input-period: 10 kHz, ten times a 1 kHz haptic device.
 * Shorter ones only fill the publishing queue ("publishing queue full"). */
#define MIN_INPUT_PERIOD 1e-4

typedef struct options {
    const char *role, *script, *scene, *session, *config, *security, *log_path, *name;
    uint32_t domain, id;
    double duration, resync_timeout, input_period;
    double rejoin; /* after the server leaves, wait this long for it to restart [s] */
    bool list;     /* --list: print the domain's sessions and exit */
} options;

static volatile sig_atomic_t g_stop;
static void on_signal(int sig) { (void)sig; g_stop = 1; }

static int64_t g_t0;        /* the process' start: the log's times, `join` */
static int64_t g_script_t0; /* the script's time 0: g_t0, or with `clock session` the
                             * first moment the bot may act in the session (0: not yet) */
static uint32_t g_id;

/* A script's time [s] as a deadline on the monotonic clock. Scripts bound
 * times only to be finite: one beyond MAX_SECONDS comes after any
 * --duration, so it is never (cast, it would wrap). Before a session clock
 * has started, no script time has come. */
static int64_t script_deadline(double t)
{
    return t < MAX_SECONDS && g_script_t0 ? g_script_t0 + (int64_t)(t * 1e9) : INT64_MAX;
}

/* The script's time at `now` [s]; negative before a session clock starts
 * (no point, command or expectation window is there). */
static double script_time(int64_t now)
{
    return g_script_t0 ? (double)(now - g_script_t0) * 1e-9 : -1.0;
}

static void blog(const char *fmt, ...)
{
    char buf[1024];
    va_list ap;
    va_start(ap, fmt);
    vsnprintf(buf, sizeof buf, fmt, ap);
    va_end(ap);
    fprintf(stderr, "ftm-bot %u [%8.3f] %s\n", g_id, (double)(ftm_clock_mono_ns() - g_t0) * 1e-9, buf);
}

static void log_hook(void *user, ftm_log_level level, const char *message)
{
    (void)user;
    if (level >= FTM_LOG_INFO)
        blog("%s", message);
}

/* ---- options ------------------------------------------------------------------------ */

static int parse_role(const ftm_option *o, const char *v, void *field, char *why, size_t cap)
{
    if (strcmp(v, "trainee") && strcmp(v, "observer") && strcmp(v, "instructor")) {
        snprintf(why, cap, "must be trainee, observer or instructor (got '%s')", v);
        return -1;
    }
    memcpy(field, &v, sizeof v);
    return 0;
}

#define O options
static const ftm_option option_table[] = {
    FTM_OPT_CUSTOM("role", "trainee|observer|instructor", O, role, parse_role,
                   "the participant's role (required)"),
    FTM_OPT_STRING("script", "FILE", O, script, "HIP trajectory / commands (docs/bot-script.md)"),
    FTM_OPT_STRING("scene", "NAME|FILE", O, scene, "local scene (default: the announced scene id)"),
    FTM_OPT_STRING("session", "NAME", O, session, "session name (default: ftm)"),
    FTM_OPT_INT("domain", "N", O, domain, 0, FTM_OPTION_DOMAIN_MAX, "DDS domain id (default 0)"),
    FTM_OPT_STRING("config", "FILE", O, config, "Cyclone DDS configuration"),
    FTM_OPT_STRING("security", "DIR", O, security,
                   "DDS Security: this participant's identity and permissions\n"
                   "(deploy/ftm-security issue DIR NAME --role ROLE)"),
    FTM_OPT_INT("id", "N", O, id, 0, UINT32_MAX, "participant id (default 0: from pid and time)"),
    FTM_OPT_CUSTOM("name", "TEXT", O, name, ftm_option_parse_display_name,
                   "display name, 1..63 bytes, no control characters"),
    FTM_OPT_DOUBLE("duration", "S", O, duration, 0, MAX_SECONDS, FTM_OPTION_ABOVE_LO, "seconds",
                   "stop after S seconds, <= 1e9 (default 10; also when the server\nleaves)"),
    FTM_OPT_DOUBLE("resync-timeout", "S", O, resync_timeout, 0, MAX_SECONDS, FTM_OPTION_ABOVE_LO,
                   "seconds", "fail if not synced for S seconds (default 5)"),
    FTM_OPT_DOUBLE("input-period", "S", O, input_period, MIN_INPUT_PERIOD, MAX_SECONDS, 0,
                   "seconds", "probe input batch period, >= 0.0001 (default 0.001)"),
    FTM_OPT_DOUBLE("rejoin", "S", O, rejoin, 0, 3600, 0, "seconds",
                   "when the server leaves, wait S seconds for it to restart\n"
                   "and rejoin it (default 0: stop)"),
    FTM_OPT_STRING("log", "FILE", O, log_path, "CSV: one line per applied frame"),
    FTM_OPT_FLAG("list", O, list,
                 "list the sessions on the domain (scene, server, age, who is there),\n"
                 "heard for 1.5 s (or --duration S), then exit; no --role needed"),
    {0}};
#undef O

static const ftm_option_set option_set = {
    "ftm-bot", "usage: ftm-bot --role trainee|observer|instructor [options]", option_table,
    "Exit status: 0 synced at the end; 1 not synced; 2 usage or a taken id; 3 set-up;\n"
    "4 the script did not hold (docs/bot-script.md)."};

/* -1 to go on, or the exit status: 0 after --help, 2 refused. */
static int parse(int argc, char **argv, options *o)
{
    *o = (options){.session = "ftm", .duration = 10.0, .resync_timeout = 5.0, .input_period = 0.001};
    uint64_t given = 0;
    int rc = ftm_options_parse(&option_set, argc, argv, o, &given, NULL);
    if (rc == FTM_OPTIONS_HELP)
        return 0;
    if (rc == FTM_OPTIONS_OK && o->list && !ftm_options_given(&option_set, given, "duration"))
        o->duration = 1.5;
    if (rc == FTM_OPTIONS_OK && !o->role && !o->list) {
        fprintf(stderr, "ftm-bot: --role is required (trainee, observer or instructor)\n");
        rc = FTM_OPTIONS_BAD;
    }
    return rc == FTM_OPTIONS_OK ? -1 : 2;
}

/* ---- the bot ---------------------------------------------------------------------------- */

typedef struct bot {
    options o;
    ftm_wire_role role;
    ftm_script sc;
    bool have_script;
    ftm_participant *part; /* the participant's side of the protocol (participant.h) */
    FILE *csv;
    bool push_limited; /* the last frame said the server limited our push */
    uint64_t command_id; /* commands sent */
    /* what became of the commands */
    uint64_t applied, changed, refused, unanswered;
    double lat_sum_us, lat_max_us;
    uint64_t lat_n;
    int64_t unsynced_since;
    /* the last tissue command: a command carries every tissue parameter, so
     * the next one waits until this one is answered and, if applied, in
     * force in the replica (else it would carry the values from before) */
    bool tissue_open, tissue_refused;
    ftm_wire_tissue tissue_sent;
    int64_t tissue_since;
} bot;

/* Server-to-bot latency of a frame [us]: from the server's send time in the
 * frame (when the tick handed it to its publishing thread) if present, else
 * from the DDS source timestamp (when the publishing thread wrote it), to its
 * arrival in this process (ftm_wire's listener); same host clock. */
static double frame_latency_us(const ftm_wire_received *rx)
{
    uint64_t sent = rx->msg.u.tick.send_time_ns;
    return (double)(rx->arrival_ns - (sent ? (int64_t)sent : rx->source_time_ns)) * 1e-3;
}

/* rx_ns: when this thread took the frame (after its arrival); now_s: when
 * it was applied, in script time; f: the reaction on our probe 0 */
static void log_frame(bot *b, ftm_replay *rep, const ftm_wire_received *rx, int64_t rx_ns,
                      double now_s, ftm_vec3 f)
{
    if (!b->csv)
        return;
    const ftm_wire_tick *t = ftm_replay_last_frame(rep);
    double lat_us = frame_latency_us(rx);
    size_t bytes = rx->payload_size; /* as the server sent it */
    ftm_sim_stats st;
    ftm_sim_get_stats(ftm_replay_sim(rep), &st);
    fprintf(b->csv,
            "%.6f,%" PRIu64 ",%016" PRIx64 ",%016" PRIx64 ",%d,%d,%.9g,%.9g,%.9g,%.1f,%d,%.1f,%zu,"
            "%.1f\n",
            now_s, t->tick, t->state_hash, ftm_replay_hash(rep), (int)ftm_replay_state(rep),
            (int)t->contact_count, f.x, f.y, f.z, lat_us, (int)st.updated_nodes,
            (double)(rx->arrival_ns - rx->source_time_ns) * 1e-3, bytes,
            (double)(rx_ns - rx->arrival_ns) * 1e-3);
}

/* A tick frame from the server (hooks.frame): latency, and for a frame
 * applied now the CSV log, the script's expectations and the push limit. */
static void on_frame(void *user, const ftm_wire_received *rx, int64_t taken_ns, bool stepped,
                     bool new_frame)
{
    bot *b = user;
    ftm_replay *rep = ftm_participant_replica(b->part);
    if (!rep)
        return;
    double lat_us = frame_latency_us(rx);
    b->lat_sum_us += lat_us;
    b->lat_n++;
    if (lat_us > b->lat_max_us)
        b->lat_max_us = lat_us;
    if (!new_frame)
        return;
    const ftm_wire_tick *t = ftm_replay_last_frame(rep);
    /* the log and the expectations see the frame at the same time: when it
     * was applied here, the trainee's "now" (after the latency) */
    const double now_s = script_time(ftm_clock_mono_ns());
    ftm_wire_reaction re;
    /* (unconfirmed or taken, a force under our id may be another's) */
    const bool contact = ftm_participant_id_ours(b->part) &&
                         ftm_replay_find_reaction(t, b->o.id, 0, &re);
    const ftm_vec3 f = contact ? re.force : (ftm_vec3){0, 0, 0};
    log_frame(b, rep, rx, taken_ns, now_s, f);
    ftm_script_expect_frame(&b->sc, now_s, t->tick, f, contact);
    bool limited = false;
    for (int32_t i = 0; i < t->reaction_count; i++)
        limited |= t->reactions[i].participant == b->o.id && t->reactions[i].push_limited;
    if (limited && !b->push_limited)
        blog("tick %" PRIu64 ": the server limits our push (HIP beyond --max-penetration)", t->tick);
    b->push_limited = limited;
}

/* What became of a command (hooks.outcome; the core logged it). */
static void on_outcome(void *user, const char *text, int outcome, bool known)
{
    bot *b = user;
    if (!outcome)
        b->unanswered++;
    else if (known) {
        b->applied += outcome == FTM_WIRE_OUTCOME_APPLIED;
        b->changed += outcome == FTM_WIRE_OUTCOME_CHANGED;
        b->refused += outcome == FTM_WIRE_OUTCOME_REFUSED;
    }
    /* the brief of a tissue command names its parameter (ftm_script_command_text) */
    const bool tissue = strncmp(text, "stiffness ", 10) == 0 ||
                        strncmp(text, "damping ", 8) == 0 || strncmp(text, "mass ", 5) == 0;
    if (tissue && outcome != FTM_WIRE_OUTCOME_APPLIED && outcome != FTM_WIRE_OUTCOME_CHANGED)
        b->tissue_refused = true; /* (or unanswered: the replica's values are the base) */
}

static bool is_tissue(const ftm_script_command *c)
{
    return c->e.keyword == FTM_SCRIPT_KW_STIFFNESS || c->e.keyword == FTM_SCRIPT_KW_DAMPING ||
           c->e.keyword == FTM_SCRIPT_KW_MASS;
}

/* Whether the last tissue command is settled: answered, and in force in
 * the replica unless refused (at most 2 s of waiting: then the replica's
 * values are the base whatever they are). */
#define TISSUE_WAIT_NS 2000000000LL
static bool tissue_settled(bot *b, const ftm_wire_tissue *now)
{
    if (!b->tissue_open)
        return true;
    const bool answered = ftm_participant_pending_count(b->part) == 0;
    if ((answered && (b->tissue_refused || ftm_replay_tissue_equal(now, &b->tissue_sent))) ||
        ftm_clock_mono_ns() - b->tissue_since > TISSUE_WAIT_NS)
        b->tissue_open = false;
    return !b->tissue_open;
}

/* why a bot that never synced did not: what it heard of the server (the
 * usual causes across a network, docs/deploy.md "Network") */
static const char *never_synced_why(const bot *b)
{
    const ftm_participant_info *in = ftm_participant_get_info(b->part);
    ftm_replay_stats rs;
    memset(&rs, 0, sizeof rs);
    ftm_replay *rep = ftm_participant_replica(b->part);
    if (rep)
        ftm_replay_get_stats(rep, &rs);
    if (!in->server_id)
        return "no server heard: check that the server runs with the same --session, --domain "
               "and a --config that reaches this host (multicast, or Peers listing both hosts)";
    if (!in->keyframes_heard)
        return rs.frames_received
                   ? "tick frames arrived but no keyframe: keyframes are tens of kB, sent as DDS "
                     "messages of up to the configuration's MaxMessageSize; check that datagrams "
                     "of that size or their IP fragments cross the network (path MTU)"
                   : "the server was heard but neither tick frames nor keyframes arrived";
    return "keyframes arrived but did not load (see above)";
}

static void send_probe(bot *b, double t)
{
    ftm_wire_probe_sample smp = {0, (uint64_t)ftm_clock_mono_ns(), ftm_script_at(&b->sc, t)};
    ftm_participant_send_probe(b->part, &smp, 1);
}

/* The script's commands that are due (script time t). */
static void send_commands(bot *b, double t)
{
    for (int32_t i = 0; i < b->sc.ncmds; i++) {
        ftm_script_command *c = &b->sc.cmds[i];
        if (c->done || t < c->e.t)
            continue;
        /* a tissue command: one parameter changed, the others as the replica runs them now,
         * once our previous change is in force there (commands stay in order) */
        ftm_wire_tissue now = ftm_replay_tissue(ftm_participant_replica(b->part));
        if (is_tissue(c) && !tissue_settled(b, &now))
            break;
        c->done = true;
        ftm_wire_control ctl;
        const char *name = ftm_script_control(c, &now, &ctl);
        char brief[FTM_PENDING_WHAT];
        ftm_script_command_text(c, brief, sizeof brief);
        ftm_error err = {0, ""};
        if (ftm_participant_send_control(b->part, &ctl, brief, &err)) {
            blog("control: %s", err.message);
            continue;
        }
        b->command_id++;
        if (ctl.command == FTM_WIRE_CMD_TISSUE) {
            b->tissue_open = true;
            b->tissue_refused = false;
            b->tissue_sent = ctl.tissue;
            b->tissue_since = ftm_clock_mono_ns();
        }
        if (ctl.command == FTM_WIRE_CMD_TISSUE)
            blog("sent tissue: stiffness %g N/m, damping %g N s/m, mass %g kg (command %" PRIu64
                 ")", ctl.tissue.stiffness, ctl.tissue.node_damping, ctl.tissue.node_mass,
                 ctl.command_id);
        else if (ctl.command == FTM_WIRE_CMD_DEPTH_LIMITS)
            blog("sent depth limits %d..%d (command %" PRIu64 ")", (int)ctl.depth_min,
                 (int)ctl.depth_max, ctl.command_id);
        else
            blog("sent %s (command %" PRIu64 ")", name, ctl.command_id);
    }
}

/* Why the loop should stop now (NULL: go on); *rc_exit 1 for a sync that
 * did not come or come back. */
static const char *stop_reason(bot *b, int64_t now, int64_t joined_ns, int *rc_exit)
{
    const ftm_participant_info *in = ftm_participant_get_info(b->part);
    /* taken: stop, but only a second after joining, so that the session
     * (the server, the process with the id) heard who it was */
    if (in->id_taken && now - joined_ns >= SEC)
        return "participant id taken";
    /* the server has left: take what is still in flight, then stop. A
     * `gone` without LEAVING may be a lease that expired while this process
     * (or the server) was stalled: wait for it to come back for the resync
     * timeout before giving up. */
    int64_t grace = in->server_gone ? (int64_t)(b->o.resync_timeout * 1e9) : SEC / 2;
    if (grace < (int64_t)(b->o.rejoin * 1e9)) /* waiting for a restart */
        grace = (int64_t)(b->o.rejoin * 1e9);
    if (in->server_left && now - in->server_left_ns > grace && now - in->last_frame_ns > SEC / 5)
        return in->server_gone ? "server gone" : "server left";
    if (ftm_participant_state(b->part) == FTM_WIRE_STATE_SYNCED) {
        b->unsynced_since = now;
    } else if (now - b->unsynced_since > (int64_t)(b->o.resync_timeout * 1e9)) {
        blog("not synced for %.1f s (%s): giving up", b->o.resync_timeout,
             in->ever_synced ? "hash mismatch or gap did not recover" : "never synced");
        *rc_exit = 1;
        return "resync timeout";
    }
    return NULL;
}

/* Whether a reader (the server's) is matched with our probe input: with DDS
 * Security each topic's endpoints are matched on their own, and in a
 * sanitizer build on a busy host the probe input's came a second after the
 * status topics' (what a writer sends before is lost). */
static bool input_heard(bot *b)
{
    ftm_wire_stats st;
    return ftm_wire_get_stats(ftm_participant_wire(b->part), FTM_WIRE_PROBE_INPUT, &st, NULL) ==
               FTM_OK &&
           st.matched > 0;
}

/* The session, from joining to the end of the script, --duration, a
 * signal or the server's departure. Returns why it stopped. */
static const char *run(bot *b, int64_t end_ns, int *rc_exit)
{
    ftm_participant_join(b->part);
    const int64_t joined_ns = ftm_clock_mono_ns();
    int64_t next_input = joined_ns;
    b->unsynced_since = joined_ns;
    const bool trainee = b->role == FTM_WIRE_ROLE_TRAINEE;
    while (!g_stop) {
        int64_t now = ftm_clock_mono_ns();
        if (!g_script_t0 && (trainee ? ftm_participant_may_press(b->part) && input_heard(b)
                                     : ftm_participant_get_info(b->part)->ever_synced)) {
            /* `clock session`: the script starts once the bot is in the
             * session (a trainee: synced, heard under its id, its probe
             * input matched by a reader), however long joining took (a
             * secured session on a loaded host) */
            g_script_t0 = now;
            blog("script time 0 (clock session)");
        }
        if (now >= end_ns)
            return "duration reached";
        if (b->sc.leave >= 0 && now >= script_deadline(b->sc.leave))
            return "script leave time";
        /* a trainee waits for frames no longer than until its next input */
        int64_t wait = trainee ? next_input - now : SEC / 1000;
        const int64_t turn_ns = now;
        ftm_participant_turn(b->part, wait < 0 ? 0 : wait > SEC / 1000 ? SEC / 1000 : wait);
        now = ftm_clock_mono_ns();
        /* a turn that took long loaded the session's scene (a mesh from a
         * scan takes a second or more on a busy host): the sync timeout
         * counts from the end of it */
        if (now - turn_ns > SEC / 4 && ftm_participant_state(b->part) != FTM_WIRE_STATE_SYNCED)
            b->unsynced_since += now - turn_ns;
        const double t = script_time(now);
        if (trainee && now >= next_input && ftm_participant_may_press(b->part)) {
            send_probe(b, t);
            next_input += (int64_t)(b->o.input_period * 1e9);
            if (next_input < now)
                next_input = now;
        }
        /* not while the server is away: nobody would hear them. Due ones
         * wait for the server's return (a restarted one: once synced with it) */
        const ftm_participant_info *in = ftm_participant_get_info(b->part);
        if (b->role == FTM_WIRE_ROLE_INSTRUCTOR && in->ever_synced && !in->server_left &&
            !in->need_announce)
            send_commands(b, t);
        const char *why = stop_reason(b, now, joined_ns, rc_exit);
        if (why)
            return why;
        ftm_participant_status_due(b->part, now);
    }
    return "signal";
}

/* After the loop: the replies to the last commands, if the server is still
 * there; then every command never sent or never answered is counted. */
static void wind_down(bot *b)
{
    for (int64_t until = ftm_clock_mono_ns() + FTM_REPLY_TIMEOUT_NS;
         ftm_participant_pending_count(b->part) > 0 && !g_stop &&
         !ftm_participant_get_info(b->part)->server_left && ftm_clock_mono_ns() < until;) {
        ftm_participant_turn(b->part, SEC / 100);
        ftm_participant_status_due(b->part, ftm_clock_mono_ns());
    }
    double t_end = script_time(ftm_clock_mono_ns());
    for (int32_t i = 0; i < b->sc.ncmds && b->role == FTM_WIRE_ROLE_INSTRUCTOR; i++) {
        const ftm_script_command *c = &b->sc.cmds[i];
        if (!c->done && c->e.t <= t_end) { /* due, but held: no server to hear it */
            char what[FTM_PENDING_WHAT];
            ftm_script_command_text(c, what, sizeof what);
            blog("command %s: not sent: no server was there to hear it", what);
            b->unanswered++;
        }
    }
    for (char what[FTM_PENDING_WHAT]; ftm_participant_pending_pop(b->part, what, sizeof what);) {
        blog("command %.95s: no reply from the server before this bot stopped", what);
        b->unanswered++;
    }
}

/* The closing lines and the exit status. */
static int report(bot *b, const char *why, int rc_exit)
{
    ftm_replay *rep = ftm_participant_replica(b->part);
    const ftm_participant_info *in = ftm_participant_get_info(b->part);
    ftm_replay_stats rs;
    memset(&rs, 0, sizeof rs);
    if (rep)
        ftm_replay_get_stats(rep, &rs);
    const ftm_wire_state st = ftm_participant_state(b->part);
    if (st != FTM_WIRE_STATE_SYNCED)
        rc_exit = 1;
    if (in->id_taken)
        rc_exit = 2;
    if (rc_exit == 0 && (b->refused || b->unanswered))
        rc_exit = 4;
    blog("stopping (%s): %s, %" PRIu64 " frames received, %" PRIu64 " applied, %" PRIu64
         " idle ticks, %" PRIu64 " mismatches, %" PRIu64 " gaps, %" PRIu64 " resyncs, %" PRIu64
         " keyframes loaded; latency mean %.0f us max %.0f us; replay %.2f us/tick",
         why, st == FTM_WIRE_STATE_SYNCED ? "synced" : "NOT synced", rs.frames_received,
         rs.frames_applied, rs.idle_ticks, rs.mismatches, rs.gaps, rs.resyncs,
         rs.keyframes_loaded, b->lat_n ? b->lat_sum_us / (double)b->lat_n : 0.0, b->lat_max_us,
         rs.frames_applied ? rs.replay_ns_total / (double)(rs.frames_applied + rs.idle_ticks) * 1e-3
                           : 0.0);
    if (st != FTM_WIRE_STATE_SYNCED && !in->ever_synced)
        blog("never synced: %s", never_synced_why(b));
    if (b->role == FTM_WIRE_ROLE_INSTRUCTOR)
        blog("commands: %" PRIu64 " sent, %" PRIu64 " applied, %" PRIu64 " changed, %" PRIu64
             " refused, %" PRIu64 " unanswered", b->command_id, b->applied, b->changed, b->refused,
             b->unanswered);
    if (in->restarts)
        blog("%u server restart%s rejoined (%u resuming the lesson)", in->restarts,
             in->restarts > 1 ? "s" : "", in->resumes);
    if (b->sc.nexpects > 0) {
        int failed = ftm_script_expect_report(&b->sc, b->o.script,
                                              script_time(ftm_clock_mono_ns()), stderr);
        blog("%d of %d expectations failed", failed, (int)b->sc.nexpects);
        /* a sync failure (1) or a taken id (2) says more: it keeps its code */
        if (failed && rc_exit == 0)
            rc_exit = 4;
    }
    printf("ftm-bot %u: final tick %" PRIu64 " hash %016" PRIx64 " %s\n", b->o.id,
           rep ? ftm_replay_tick(rep) : 0, rep ? ftm_replay_hash(rep) : 0,
           st == FTM_WIRE_STATE_SYNCED ? "synced" : "not-synced");
    fflush(stdout);
    return rc_exit;
}

/* The role and the script, checked together; 0 or the exit status 2. */
static int setup(bot *b)
{
    b->role = strcmp(b->o.role, "trainee") == 0      ? FTM_WIRE_ROLE_TRAINEE
              : strcmp(b->o.role, "observer") == 0   ? FTM_WIRE_ROLE_OBSERVER
                                                     : FTM_WIRE_ROLE_INSTRUCTOR; /* (parse_role) */
    if (b->o.script) {
        if (ftm_script_load(b->o.script, &b->sc))
            return 2;
        b->have_script = true;
    } else {
        b->sc.leave = -1.0;
    }
    if (b->role != FTM_WIRE_ROLE_TRAINEE && b->sc.nexpects > 0) {
        fprintf(stderr, "ftm-bot: %s:%d: 'expect' needs --role trainee (it checks the force on "
                        "the bot's probe)\n", b->o.script, (int)b->sc.expects[0].e.line);
        return 2;
    }
    if (b->role == FTM_WIRE_ROLE_TRAINEE && (!b->have_script || b->sc.npts == 0)) {
        fprintf(stderr, "ftm-bot: a trainee needs a --script with HIP positions\n");
        return 2;
    }
    if (b->o.id == 0)
        b->o.id = (uint32_t)(((uint64_t)getpid() * 2654435761u) ^ (uint64_t)ftm_clock_real_ns()) | 1u;
    g_id = b->o.id;
    return 0;
}

/* The participant core for this bot (0, or the exit status 3). */
static int open_participant(bot *b)
{
    ftm_participant_def pd = {
        .role = b->role, .id = b->o.id, .domain = b->o.domain, .session = b->o.session,
        .name = b->o.name ? b->o.name : b->o.role, .scene = b->o.scene,
        .dds_config = b->o.config, .dds_security = b->o.security, .log = log_hook,
        .hooks = {.frame = on_frame, .outcome = on_outcome}, .hooks_user = b};
    ftm_error err = {0, ""};
    if (ftm_participant_create(&pd, &b->part, &err)) {
        blog("%s", err.message);
        return 3;
    }
    blog("%s joining session '%s' on domain %u", b->o.role, b->o.session, b->o.domain);
    return 0;
}

/* --list: the sessions on the domain, then exit (0; 3 when DDS fails). */
static int list_sessions(const options *o)
{
    ftm_sessions_def d = ftm_default_sessions_def();
    d.domain = o->domain;
    d.dds_config = o->config;
    d.dds_security = o->security;
    d.participant_id = o->id;
    d.seconds = o->duration;
    return ftm_sessions_list_command("ftm-bot", &d);
}

int main(int argc, char **argv)
{
    static bot bb;
    bot *b = &bb;
    g_t0 = ftm_clock_mono_ns();
    g_script_t0 = g_t0;
    int rc = parse(argc, argv, &b->o);
    if (rc >= 0)
        return rc;
    if (b->o.list)
        return list_sessions(&b->o);
    rc = setup(b);
    if (rc) {
        ftm_script_free(&b->sc);
        return rc;
    }
    if (b->o.log_path) {
        b->csv = fopen(b->o.log_path, "w");
        if (!b->csv) {
            fprintf(stderr, "ftm-bot: cannot open %s: %s\n", b->o.log_path, strerror(errno));
            ftm_script_free(&b->sc);
            return 3;
        }
        fprintf(b->csv, "time_s,tick,server_hash,replica_hash,state,contacts,fx,fy,fz,"
                        "latency_us,updated_nodes,dds_latency_us,frame_bytes,pickup_us\n");
    }
    signal(SIGINT, on_signal);
    signal(SIGTERM, on_signal);
    const int64_t end_ns = g_t0 + (int64_t)(b->o.duration * 1e9);
    /* wait for the join time (process time, whatever the clock) */
    const int64_t join_ns = b->sc.join < MAX_SECONDS ? g_t0 + (int64_t)(b->sc.join * 1e9) : INT64_MAX;
    if (b->sc.session_clock)
        g_script_t0 = 0;
    while (!g_stop && ftm_clock_mono_ns() < join_ns && ftm_clock_mono_ns() < end_ns) {
        struct timespec ts = {0, 5000000};
        nanosleep(&ts, NULL);
    }
    rc = open_participant(b);
    if (rc == 0) {
        int rc_exit = 0;
        const char *why = run(b, end_ns, &rc_exit);
        if (g_stop)
            why = "signal";
        wind_down(b);
        ftm_participant_leave(b->part);
        rc = report(b, why, rc_exit);
    }
    ftm_participant_destroy(b->part);
    ftm_script_free(&b->sc);
    if (b->csv)
        fclose(b->csv);
    return rc;
}
