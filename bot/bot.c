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
#include "claims.h"
#include "cli.h"
#include "pending.h"
#include "replica.h"
#include "script.h"

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

#define SEC 1000000000LL
/* (a larger time would wrap when cast: --duration 1e300 stopped at once) */
#define MAX_SECONDS FTM_OPTION_SECONDS_MAX
/* The shortest --input-period: 10 kHz, ten times a 1 kHz haptic device.
 * Shorter ones only fill the publishing queue ("publishing queue full"). */
#define MIN_INPUT_PERIOD 1e-4
#define MAX_DOMAIN FTM_OPTION_DOMAIN_MAX

typedef struct options {
    const char *role, *script, *scene, *session, *config, *security, *log_path, *name;
    uint32_t domain, id;
    double duration, resync_timeout, input_period;
    double rejoin; /* after the server leaves, wait this long for it to restart [s] */
} options;

static volatile sig_atomic_t g_stop;
static void on_signal(int sig) { (void)sig; g_stop = 1; }

static int64_t mono_ns(void)
{
    struct timespec ts;
    clock_gettime(CLOCK_MONOTONIC, &ts);
    return (int64_t)ts.tv_sec * SEC + ts.tv_nsec;
}

static int64_t real_ns(void)
{
    struct timespec ts;
    clock_gettime(CLOCK_REALTIME, &ts);
    return (int64_t)ts.tv_sec * SEC + ts.tv_nsec;
}

static int64_t g_t0;
static uint32_t g_id;

/* A script's time [s] as a deadline on the monotonic clock. Scripts bound
 * times only to be finite: one beyond MAX_SECONDS comes after any
 * --duration, so it is never (cast, it would wrap). */
static int64_t script_deadline(double t)
{
    return t < MAX_SECONDS ? g_t0 + (int64_t)(t * 1e9) : INT64_MAX;
}

static void blog(const char *fmt, ...)
{
    char buf[1024];
    va_list ap;
    va_start(ap, fmt);
    vsnprintf(buf, sizeof buf, fmt, ap);
    va_end(ap);
    fprintf(stderr, "ftm-bot %u [%8.3f] %s\n", g_id, (double)(mono_ns() - g_t0) * 1e-9, buf);
}

static void log_hook(void *user, ftm_log_level level, const char *message)
{
    (void)user;
    if (level >= FTM_LOG_INFO)
        blog("%s", message);
}

/* ---- options ------------------------------------------------------------------------ */

static void usage(FILE *f)
{
    fprintf(f,
            "usage: ftm-bot --role trainee|observer|instructor [options]\n"
            "  --script FILE          HIP trajectory / commands (docs/bot-script.md)\n"
            "  --scene NAME|FILE      local scene (default: the announced scene id)\n"
            "  --session NAME         session name (default: ftm)\n"
            "  --domain N             DDS domain id (default 0)\n"
            "  --config FILE          Cyclone DDS configuration\n"
            "  --security DIR         DDS Security: this participant's identity and permissions\n"
            "                         (deploy/ftm-security issue DIR NAME --role ROLE)\n"
            "  --id N                 participant id (default: from pid and time)\n"
            "  --name TEXT            display name, 1..63 bytes, no control characters\n"
            "  --duration S           stop after S seconds, <= 1e9 (default 10; also when the server\n"
            "                         leaves)\n"
            "  --resync-timeout S     fail if not synced for S seconds (default 5)\n"
            "  --input-period S       probe input batch period, >= 0.0001 (default 0.001)\n"
            "  --rejoin S             when the server leaves, wait S seconds for it to restart\n"
            "                         and rejoin it (default 0: stop)\n"
            "  --log FILE             CSV: one line per applied frame\n");
}

static int parse(int argc, char **argv, options *o)
{
    *o = (options){.session = "ftm", .duration = 10.0, .resync_timeout = 5.0, .input_period = 0.001};
    for (int i = 1; i < argc; i++) {
        const char *a = argv[i];
        if (strcmp(a, "--help") == 0 || strcmp(a, "-h") == 0) {
            usage(stdout);
            exit(0);
        }
        if (i + 1 >= argc) {
            fprintf(stderr, "ftm-bot: %s needs a value (or unknown option)\n", a);
            return -1;
        }
        const char *v = argv[++i];
        char *end = NULL;
        long long n = 0;
        int bad = 0; /* an integer option out of range, already said */
        errno = 0;
        if (strcmp(a, "--role") == 0)
            o->role = v;
        else if (strcmp(a, "--script") == 0)
            o->script = v;
        else if (strcmp(a, "--scene") == 0)
            o->scene = v;
        else if (strcmp(a, "--session") == 0)
            o->session = v;
        else if (strcmp(a, "--config") == 0)
            o->config = v;
        else if (strcmp(a, "--security") == 0)
            o->security = v;
        else if (strcmp(a, "--log") == 0)
            o->log_path = v;
        else if (strcmp(a, "--name") == 0) {
            bad = ftm_option_name_arg("ftm-bot", v);
            o->name = v;
        }
        else if (strcmp(a, "--domain") == 0) {
            bad = ftm_option_int_arg("ftm-bot", a, v, 0, MAX_DOMAIN, &n);
            o->domain = (uint32_t)n;
        } else if (strcmp(a, "--id") == 0) {
            bad = ftm_option_int_arg("ftm-bot", a, v, 0, UINT32_MAX, &n); /* 0: from pid and time */
            o->id = (uint32_t)n;
        } else if (strcmp(a, "--duration") == 0)
            o->duration = strtod(v, &end);
        else if (strcmp(a, "--resync-timeout") == 0)
            o->resync_timeout = strtod(v, &end);
        else if (strcmp(a, "--input-period") == 0)
            o->input_period = strtod(v, &end);
        else if (strcmp(a, "--rejoin") == 0)
            o->rejoin = strtod(v, &end);
        else {
            fprintf(stderr, "ftm-bot: unknown option %s\n", a);
            return -1;
        }
        if (bad)
            return -1;
        if (end && (*end || errno)) {
            fprintf(stderr, "ftm-bot: %s: bad number '%s'\n", a, v);
            return -1;
        }
    }
    if (!o->role) {
        fprintf(stderr, "ftm-bot: --role is required\n");
        return -1;
    }
    if (!(o->duration > 0 && o->duration <= MAX_SECONDS) ||
        !(o->resync_timeout > 0 && o->resync_timeout <= MAX_SECONDS)) {
        fprintf(stderr, "ftm-bot: --duration and --resync-timeout must be in (0, %g] seconds "
                        "(got %g and %g)\n", MAX_SECONDS, o->duration, o->resync_timeout);
        return -1;
    }
    if (!(o->input_period >= MIN_INPUT_PERIOD && o->input_period <= MAX_SECONDS)) {
        fprintf(stderr, "ftm-bot: --input-period must be in [%g, %g] seconds (got %g)\n",
                MIN_INPUT_PERIOD, MAX_SECONDS, o->input_period);
        return -1;
    }
    if (!(o->rejoin >= 0 && o->rejoin <= 3600)) {
        fprintf(stderr, "ftm-bot: --rejoin must be 0..3600 seconds\n");
        return -1;
    }
    return 0;
}

/* ---- the bot ---------------------------------------------------------------------------- */

typedef struct bot {
    options o;
    ftm_wire_role role;
    ftm_script sc;
    bool have_script;
    ftm_wire_transport *wire;
    ftm_scene *scene;
    ftm_replay *rep;
    FILE *csv;
    bool push_limited;  /* the last frame said the server limited our push */
    uint32_t server_id; /* 0 until known; frames from anyone else are ignored */
    /* the server's process (ftm_wire_received.origin of its announcement):
     * another process under the server's id is not the server (from_server) */
    uint64_t server_origin;
    uint64_t foreign;   /* messages ignored: not from the server */
    bool server_left;
    bool server_gone; /* left by a `gone` event (lease expiry), not a LEAVING status */
    uint64_t server_start; /* the announced start of the server process we replay */
    uint32_t restarts;     /* server restarts rejoined */
    /* the server was gone: commands wait for its announcement, which says
     * whether it is the same process (back after its lease expired) or a
     * restarted one (on_announce); its statuses and frames do not tell */
    bool need_announce;
    int64_t server_left_ns;
    int64_t last_frame_ns;
    uint64_t command_id;
    /* commands waiting for the server's reply; what became of them */
    ftm_pending pending;
    uint64_t applied, changed, refused, unanswered;
    double lat_sum_us, lat_max_us;
    uint64_t lat_n;
    bool ever_synced;
    uint64_t keyframes_heard; /* keyframes from the server, loaded or not */
    /* what the server said of our id (on_status); id_told.taken: it hears
     * another process with our id, not us */
    ftm_id_told id_told;
    /* the newest server status lists this process as the one it hears under
     * our id (ftm_replay_id_held): a trainee presses only then, and logs
     * only then a force under our id as its own. held_since_ns: when the
     * wait began (0: no server yet) */
    bool id_held, held_late_told;
    int64_t held_since_ns;
    int64_t unsynced_since;
    /* statuses before this say JOINING (the periodic one at this time tells
     * the state reached): see publish_state */
    int64_t quiet_until_ns;
} bot;

static void publish_status(bot *b, ftm_wire_state state)
{
    ftm_wire_msg m;
    memset(&m, 0, sizeof m);
    m.kind = FTM_WIRE_STATUS;
    ftm_wire_status *st = &m.u.status;
    st->participant = b->o.id;
    st->role = b->role;
    st->state = state;
    if (b->rep) {
        ftm_replay_stats rs;
        ftm_replay_get_stats(b->rep, &rs);
        st->last_applied_tick = ftm_replay_tick(b->rep);
        st->state_hash = ftm_replay_hash(b->rep);
        st->replay_ns_per_tick =
            rs.frames_applied ? rs.replay_ns_total / (double)(rs.frames_applied + rs.idle_ticks) : 0;
        st->replay_ns_max = ftm_replay_take_max(b->rep);
    }
    snprintf(st->name, sizeof st->name, "%s", b->o.name ? b->o.name : b->o.role);
    ftm_error err = {0, ""};
    if (ftm_wire_publish(b->wire, &m, &err))
        blog("status: %s", err.message);
}

static ftm_wire_state cur_state(const bot *b)
{
    return b->rep ? ftm_replay_state(b->rep) : FTM_WIRE_STATE_JOINING;
}

/* A change of the replica's state is told at once, except in the first
 * second after joining: then the status stays the JOINING sent on joining
 * (docs/protocol.md), which is what another process with our id must hear
 * of us first; the periodic status at the end of that second tells the
 * state reached. A SYNCED told early and then not repeated for a second
 * also looked like a replica falling behind to the server's depth
 * controller. */
static void publish_state(bot *b)
{
    if (mono_ns() >= b->quiet_until_ns)
        publish_status(b, cur_state(b));
}

static void on_announce(bot *b, const ftm_wire_announce *a)
{
    ftm_error err = {0, ""};
    /* another process under the server's id: its state starts afresh, so
     * does the replica (same scene: checked below) */
    if (b->rep && a->server_start_ns && b->server_start && a->server_start_ns != b->server_start) {
        blog("server %u restarted (a new process, announcing tick %" PRIu64 "; we were at tick %"
             PRIu64 "): rejoining", b->server_id, a->tick, ftm_replay_tick(b->rep));
        bool same = ftm_replay_check_announce(b->rep, a, NULL) == FTM_OK;
        ftm_replay_destroy(b->rep);
        b->rep = NULL;
        b->restarts++;
        b->server_left = b->server_gone = false;
        /* no probe input until synced with the new server (it would not
         * know us yet); which process holds our id is its to say */
        b->ever_synced = false;
        b->id_told = (ftm_id_told){0};
        b->id_held = b->held_late_told = false;
        b->held_since_ns = 0;
        b->last_frame_ns = mono_ns();
        if (!same && !b->o.scene) {
            /* it serves another scene: load that one below, as on joining */
            blog("the restarted server has another scene: '%s'", a->scene_id);
            ftm_scene_destroy(b->scene);
            b->scene = NULL;
        } else {
            if (ftm_replay_create(b->scene, log_hook, NULL, &b->rep, &err)) {
                blog("replay: %s", err.message);
                return;
            }
            publish_status(b, FTM_WIRE_STATE_JOINING);
        }
    }
    if (!b->scene) {
        const char *name = b->o.scene ? b->o.scene : a->scene_id;
        char path[1024];
        if (ftm_wire_open_scene(name, &b->scene, path, sizeof path, &err)) {
            blog("cannot load scene '%s': %s", name, err.message);
            return;
        }
        if (strcmp(path, name) != 0)
            blog("scene '%s': %s", name, path);
        if (ftm_replay_create(b->scene, log_hook, NULL, &b->rep, &err)) {
            blog("replay: %s", err.message);
            ftm_scene_destroy(b->scene);
            b->scene = NULL;
            return;
        }
        blog("joined session: scene '%s', %u Hz, tick %" PRIu64 "%s", a->scene_id,
             a->tick_rate_hz, a->tick, a->paused ? " (paused)" : "");
        /* keyframes that came before the replica existed are lost: ask again */
        publish_status(b, FTM_WIRE_STATE_JOINING);
    }
    if (ftm_replay_check_announce(b->rep, a, &err)) {
        blog("%s", err.message);
        ftm_replay_destroy(b->rep);
        b->rep = NULL;
        ftm_scene_destroy(b->scene);
        b->scene = NULL;
    }
    if (b->rep)
        b->server_start = a->server_start_ns;
    b->need_announce = false;
}

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
static void log_frame(bot *b, const ftm_wire_received *rx, int64_t rx_ns, double now_s, ftm_vec3 f)
{
    if (!b->csv || !b->rep)
        return;
    const ftm_wire_tick *t = ftm_replay_last_frame(b->rep);
    double lat_us = frame_latency_us(rx);
    size_t bytes = rx->payload_size; /* as the server sent it */
    ftm_sim_stats st;
    ftm_sim_get_stats(ftm_replay_sim(b->rep), &st);
    fprintf(b->csv,
            "%.6f,%" PRIu64 ",%016" PRIx64 ",%016" PRIx64 ",%d,%d,%.9g,%.9g,%.9g,%.1f,%d,%.1f,%zu,"
            "%.1f\n",
            now_s, t->tick, t->state_hash, ftm_replay_hash(b->rep),
            (int)ftm_replay_state(b->rep), (int)t->contact_count, f.x, f.y, f.z, lat_us,
            (int)st.updated_nodes, (double)(rx->arrival_ns - rx->source_time_ns) * 1e-3, bytes,
            (double)(rx_ns - rx->arrival_ns) * 1e-3);
}

/* The server's lease can expire while it is alive (a starved or lossy
 * host): whatever it sends after a `gone` event brings it back. */
static void server_alive(bot *b)
{
    if (b->server_left && b->server_gone) {
        blog("server %u is back (after its lease expired)", b->server_id);
        b->server_left = b->server_gone = false;
    }
}

static void on_tick(bot *b, const ftm_wire_received *rx)
{
    server_alive(b);
    int64_t rx_ns = real_ns(); /* taken by this thread, before replaying */
    b->last_frame_ns = mono_ns();
    if (!b->rep)
        return;
    ftm_wire_state before = ftm_replay_state(b->rep);
    uint64_t applied = ftm_replay_last_frame(b->rep)->tick;
    if (ftm_replay_on_tick(b->rep, rx))
        blog("replay: out of memory");
    double lat_us = frame_latency_us(rx);
    b->lat_sum_us += lat_us;
    b->lat_n++;
    if (lat_us > b->lat_max_us)
        b->lat_max_us = lat_us;
    if (ftm_replay_last_frame(b->rep)->tick != applied) {
        const ftm_wire_tick *t = ftm_replay_last_frame(b->rep);
        /* the log and the expectations see the frame at the same time: when
         * it was applied here, the trainee's "now" (after the latency) */
        const double now_s = (double)(mono_ns() - g_t0) * 1e-9;
        ftm_wire_reaction re;
        /* (unconfirmed or taken, a force under our id may be another's) */
        const bool contact = b->id_held && !b->id_told.taken &&
                             ftm_replay_find_reaction(t, b->o.id, 0, &re);
        const ftm_vec3 f = contact ? re.force : (ftm_vec3){0, 0, 0};
        log_frame(b, rx, rx_ns, now_s, f);
        ftm_script_expect_frame(&b->sc, now_s, t->tick, f, contact);
        bool limited = false;
        for (int32_t i = 0; i < t->reaction_count; i++)
            limited |= t->reactions[i].participant == b->o.id && t->reactions[i].push_limited;
        if (limited && !b->push_limited)
            blog("tick %" PRIu64 ": the server limits our push (HIP beyond --max-penetration)",
                 t->tick);
        b->push_limited = limited;
    }
    if (ftm_replay_state(b->rep) != before)
        publish_state(b);
}

static void on_keyframe(bot *b, const ftm_wire_keyframe *k)
{
    b->keyframes_heard++;
    if (!b->rep)
        return;
    ftm_wire_state before = ftm_replay_state(b->rep);
    if (ftm_replay_on_keyframe(b->rep, k))
        blog("replay: out of memory");
    if (ftm_replay_state(b->rep) != before)
        publish_state(b);
}

/* why a bot that never synced did not: what it heard of the server (the
 * usual causes across a network, docs/deploy.md "Network") */
static const char *never_synced_why(const bot *b)
{
    ftm_replay_stats rs;
    memset(&rs, 0, sizeof rs);
    if (b->rep)
        ftm_replay_get_stats(b->rep, &rs);
    if (!b->server_id)
        return "no server heard: check that the server runs with the same --session, --domain "
               "and a --config that reaches this host (multicast, or Peers listing both hosts)";
    if (!b->keyframes_heard)
        return rs.frames_received
                   ? "tick frames arrived but no keyframe: keyframes are tens of kB, sent as DDS "
                     "messages of up to the configuration's MaxMessageSize; check that datagrams "
                     "of that size or their IP fragments cross the network (path MTU)"
                   : "the server was heard but neither tick frames nor keyframes arrived";
    return "keyframes arrived but did not load (see above)";
}

static void send_probe(bot *b, double t)
{
    ftm_wire_probe_sample smp = {0, (uint64_t)mono_ns(), ftm_script_at(&b->sc, t)};
    ftm_wire_msg m;
    memset(&m, 0, sizeof m);
    m.kind = FTM_WIRE_PROBE_INPUT;
    m.u.probe_input.participant = b->o.id;
    m.u.probe_input.last_tick_seen = b->rep ? ftm_replay_tick(b->rep) : 0;
    m.u.probe_input.sample_count = 1;
    m.u.probe_input.samples = &smp;
    ftm_error err = {0, ""};
    if (ftm_wire_publish(b->wire, &m, &err))
        blog("probe input: %s", err.message);
}

static void unanswered(bot *b, const char *text)
{
    b->unanswered++;
    blog("command %s", text);
}

static void send_commands(bot *b, double t)
{
    for (int32_t i = 0; i < b->sc.ncmds; i++) {
        ftm_script_command *c = &b->sc.cmds[i];
        if (c->done || t < c->e.t)
            continue;
        c->done = true;
        ftm_wire_msg m;
        memset(&m, 0, sizeof m);
        m.kind = FTM_WIRE_CONTROL;
        /* a tissue command: one parameter changed, the others as the replica runs them now */
        ftm_wire_tissue now = ftm_replay_tissue(b->rep);
        const char *name = ftm_script_control(c, &now, &m.u.control);
        m.u.control.issuer = b->o.id;
        m.u.control.command_id = ++b->command_id;
        char what[128];
        const ftm_wire_control *ctl = &m.u.control;
        if (ctl->command == FTM_WIRE_CMD_TISSUE)
            snprintf(what, sizeof what, "tissue: stiffness %g N/m, damping %g N s/m, mass %g kg",
                     ctl->tissue.stiffness, ctl->tissue.node_damping, ctl->tissue.node_mass);
        else if (ctl->command == FTM_WIRE_CMD_DEPTH_LIMITS)
            snprintf(what, sizeof what, "depth limits %d..%d", (int)ctl->depth_min,
                     (int)ctl->depth_max);
        else
            snprintf(what, sizeof what, "%s", name);
        ftm_error err = {0, ""};
        if (ftm_wire_publish(b->wire, &m, &err)) {
            blog("control: %s", err.message);
            continue;
        }
        blog("sent %s (command %" PRIu64 ")", what, ctl->command_id);
        char brief[FTM_PENDING_WHAT], text[FTM_OUTCOME_TEXT];
        ftm_script_command_text(c, brief, sizeof brief);
        if (ftm_pending_add(&b->pending, ctl->command_id, brief, mono_ns(), text, sizeof text))
            unanswered(b, text);
    }
}

static void on_reply(bot *b, const ftm_wire_control_reply *r)
{
    if (r->issuer != b->o.id)
        return; /* another instructor's */
    char text[FTM_OUTCOME_TEXT];
    bool known = ftm_pending_reply(&b->pending, r, text, sizeof text);
    if (known) {
        b->applied += r->outcome == FTM_WIRE_OUTCOME_APPLIED;
        b->changed += r->outcome == FTM_WIRE_OUTCOME_CHANGED;
        b->refused += r->outcome == FTM_WIRE_OUTCOME_REFUSED;
    }
    blog("command %s%s", text, known ? "" : " (no such command waiting)");
}

static void expire_commands(bot *b)
{
    char text[FTM_OUTCOME_TEXT];
    while (ftm_pending_expired(&b->pending, mono_ns(), FTM_REPLY_TIMEOUT_NS, text, sizeof text))
        unanswered(b, text);
}

/* Whether rx is from the server process we follow (ftm_replay_from_server:
 * the trust rule); anything else is counted and logged, rate-limited. */
static bool from_server(bot *b, const ftm_wire_received *rx)
{
    if (ftm_replay_from_server(&b->server_id, &b->server_origin, rx, b->server_left))
        return true;
    if (b->server_id == 0)
        return false; /* no announcement yet: nothing to follow */
    b->foreign++;
    if (b->foreign <= 3 || (b->foreign & (b->foreign - 1)) == 0) /* 1, 2, 3, 4, 8, ... */
        blog("%s from participant %u ignored (%" PRIu64 " so far): not from the server %u%s",
             ftm_wire_kind_name((int)rx->msg.kind), rx->sender, b->foreign, b->server_id,
             rx->sender == b->server_id ? "'s process: another process uses its id" : "");
    return false;
}

static void on_status(bot *b, const ftm_wire_received *rx)
{
    if (rx->gone) {
        /* (origin 0: no longer known; gone only turns things off) */
        if (rx->sender == b->server_id && (!rx->origin || rx->origin == b->server_origin) &&
            !b->server_left) {
            blog("server %u gone", rx->sender);
            b->server_left = b->server_gone = true;
            b->need_announce = true;
            b->server_left_ns = mono_ns();
        }
        return;
    }
    const ftm_wire_status *st = &rx->msg.u.status;
    if (rx->sender == g_id) /* another process with our id: the server says which it hears */
        return;
    if (st->role == FTM_WIRE_ROLE_SERVER && from_server(b, rx)) {
        const ftm_id_claim c =
            ftm_replay_id_verdict(&b->id_told, st, g_id, ftm_wire_transport_origin(b->wire));
        if (c == FTM_ID_TAKEN) {
            blog("participant id %u is taken: another process in session '%s' uses it and the "
                 "server listens to that one; give each participant its own --id",
                 g_id, b->o.session);
        } else if (c == FTM_ID_NEWCOMER) {
            blog("another process joined as participant %u: the server ignores it", g_id);
        } else if (c == FTM_ID_OURS_AGAIN) {
            blog("participant id %u is ours again: the process that held it left", g_id);
        }
        const bool held = ftm_replay_id_held(st, g_id, ftm_wire_transport_origin(b->wire));
        if (held && !b->id_held) {
            blog("participant id %u is confirmed: the server hears this process under it", g_id);
        } else if (!held && b->id_held) {
            blog("the server no longer confirms participant id %u as this process's: no probe "
                 "input until it does", g_id);
            b->held_since_ns = mono_ns();
            b->held_late_told = false;
        }
        b->id_held = held;
        if (st->state != FTM_WIRE_STATE_LEAVING)
            server_alive(b);
        if (st->state == FTM_WIRE_STATE_LEAVING && (!b->server_left || b->server_gone)) {
            blog("server %u leaving at tick %" PRIu64, rx->sender, st->last_applied_tick);
            b->server_left = true;
            b->server_gone = false;
            b->server_left_ns = mono_ns();
        }
    }
}

int main(int argc, char **argv)
{
    static bot bb;
    bot *b = &bb;
    g_t0 = mono_ns();
    if (parse(argc, argv, &b->o)) {
        usage(stderr);
        return 2;
    }
    if (strcmp(b->o.role, "trainee") == 0)
        b->role = FTM_WIRE_ROLE_TRAINEE;
    else if (strcmp(b->o.role, "observer") == 0)
        b->role = FTM_WIRE_ROLE_OBSERVER;
    else if (strcmp(b->o.role, "instructor") == 0)
        b->role = FTM_WIRE_ROLE_INSTRUCTOR;
    else {
        fprintf(stderr, "ftm-bot: --role must be trainee, observer or instructor\n");
        return 2;
    }
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
        ftm_script_free(&b->sc);
        return 2;
    }
    if (b->role == FTM_WIRE_ROLE_TRAINEE && (!b->have_script || b->sc.npts == 0)) {
        fprintf(stderr, "ftm-bot: a trainee needs a --script with HIP positions\n");
        return 2;
    }
    if (b->o.id == 0)
        b->o.id = (uint32_t)(((uint64_t)getpid() * 2654435761u) ^ (uint64_t)real_ns()) | 1u;
    g_id = b->o.id;
    if (b->o.log_path) {
        b->csv = fopen(b->o.log_path, "w");
        if (!b->csv) {
            fprintf(stderr, "ftm-bot: cannot open %s: %s\n", b->o.log_path, strerror(errno));
            return 3;
        }
        fprintf(b->csv, "time_s,tick,server_hash,replica_hash,state,contacts,fx,fy,fz,"
                        "latency_us,updated_nodes,dds_latency_us,frame_bytes,pickup_us\n");
    }
    signal(SIGINT, on_signal);
    signal(SIGTERM, on_signal);
    int64_t end_ns = g_t0 + (int64_t)(b->o.duration * 1e9);

    /* wait for the join time */
    int64_t join_ns = script_deadline(b->sc.join);
    while (!g_stop && mono_ns() < join_ns && mono_ns() < end_ns) {
        struct timespec ts = {0, 5000000};
        nanosleep(&ts, NULL);
    }
    ftm_wire_transport_def wd;
    memset(&wd, 0, sizeof wd);
    wd.config = b->o.config;
    wd.security = b->o.security;
    wd.role = b->role;
    wd.domain_id = b->o.domain;
    wd.session = b->o.session;
    wd.participant_id = b->o.id;
    wd.publish = FTM_WIRE_KIND_BIT(FTM_WIRE_STATUS);
    if (b->role == FTM_WIRE_ROLE_TRAINEE)
        wd.publish |= FTM_WIRE_KIND_BIT(FTM_WIRE_PROBE_INPUT);
    wd.subscribe = FTM_WIRE_KIND_BIT(FTM_WIRE_ANNOUNCE) | FTM_WIRE_KIND_BIT(FTM_WIRE_TICK) |
                   FTM_WIRE_KIND_BIT(FTM_WIRE_KEYFRAME) | FTM_WIRE_KIND_BIT(FTM_WIRE_STATUS);
    if (b->role == FTM_WIRE_ROLE_INSTRUCTOR) {
        wd.publish |= FTM_WIRE_KIND_BIT(FTM_WIRE_CONTROL);
        wd.subscribe |= FTM_WIRE_KIND_BIT(FTM_WIRE_CONTROL_REPLY);
    }
    wd.log = log_hook;
    ftm_error err = {0, ""};
    if (ftm_wire_transport_create(&wd, &b->wire, &err)) {
        blog("%s", err.message);
        return 3;
    }
    blog("%s joining session '%s' on domain %u", b->o.role, b->o.session, b->o.domain);
    publish_status(b, FTM_WIRE_STATE_JOINING);
    /* the first status after JOINING a second on: JOINING is what another
     * process with our id hears of us first (on_status) */
    const int64_t joined_ns = mono_ns();
    int64_t next_status = joined_ns + SEC, next_input = joined_ns;
    b->quiet_until_ns = next_status;
    int64_t leave_ns = b->sc.leave >= 0 ? script_deadline(b->sc.leave) : INT64_MAX;
    b->unsynced_since = mono_ns();
    int rc_exit = 0;
    const char *why = "duration reached";
    while (!g_stop) {
        int64_t now = mono_ns();
        if (now >= end_ns)
            break;
        if (now >= leave_ns) {
            why = "script leave time";
            break;
        }
        /* taken: stop, but only a second after joining, so that the
         * session (the server, the process with the id) heard who it was */
        if (b->id_told.taken && now - joined_ns >= SEC) {
            why = "participant id taken";
            break;
        }
        /* the server has left: take what is still in flight, then stop. A
         * `gone` without LEAVING may be a lease that expired while this
         * process (or the server) was stalled: wait for it to come back for
         * the resync timeout before giving up. */
        int64_t grace = b->server_gone ? (int64_t)(b->o.resync_timeout * 1e9) : SEC / 2;
        if (grace < (int64_t)(b->o.rejoin * 1e9)) /* waiting for a restart */
            grace = (int64_t)(b->o.rejoin * 1e9);
        if (b->server_left && now - b->server_left_ns > grace && now - b->last_frame_ns > SEC / 5) {
            why = b->server_gone ? "server gone" : "server left";
            break;
        }
        ftm_wire_received rx;
        if (ftm_wire_receive(b->wire, FTM_WIRE_ANNOUNCE, &rx, 0, NULL) == FTM_OK) {
            if (from_server(b, &rx))
                on_announce(b, &rx.msg.u.announce);
            ftm_wire_received_free(&rx);
        }
        while (ftm_wire_receive(b->wire, FTM_WIRE_STATUS, &rx, 0, NULL) == FTM_OK) {
            on_status(b, &rx);
            ftm_wire_received_free(&rx);
        }
        if (ftm_wire_receive(b->wire, FTM_WIRE_KEYFRAME, &rx, 0, NULL) == FTM_OK) {
            if (from_server(b, &rx))
                on_keyframe(b, &rx.msg.u.keyframe);
            ftm_wire_received_free(&rx);
        }
        if (b->role == FTM_WIRE_ROLE_INSTRUCTOR) {
            while (ftm_wire_receive(b->wire, FTM_WIRE_CONTROL_REPLY, &rx, 0, NULL) == FTM_OK) {
                if (from_server(b, &rx))
                    on_reply(b, &rx.msg.u.control_reply);
                ftm_wire_received_free(&rx);
            }
            expire_commands(b);
        }
        int64_t wait = b->role == FTM_WIRE_ROLE_TRAINEE ? next_input - mono_ns() : SEC / 1000;
        if (wait < 0)
            wait = 0;
        if (wait > SEC / 1000)
            wait = SEC / 1000;
        /* frames for at most 10 ms a turn: a replica slower than the ticks
         * (a sanitizer build, a loaded host) must still send its status
         * every 500 ms, or the server takes it for lost mid-press */
        const int64_t drain_until = mono_ns() + wait + SEC / 100;
        for (int n = 0; n < 1000; n++) {
            if (ftm_wire_receive(b->wire, FTM_WIRE_TICK, &rx, n == 0 ? wait : 0, NULL) != FTM_OK)
                break;
            if (from_server(b, &rx))
                on_tick(b, &rx);
            ftm_wire_received_free(&rx);
            if (mono_ns() >= drain_until)
                break;
        }
        now = mono_ns();
        double t = (double)(now - g_t0) * 1e-9;
        /* the wait for the server to confirm our id starts with its first
         * announcement (or its restart, or the confirmation's loss) */
        if (!b->held_since_ns && b->server_id)
            b->held_since_ns = now;
        if (b->role == FTM_WIRE_ROLE_TRAINEE && !b->id_held && !b->id_told.taken &&
            !b->held_late_told && b->held_since_ns && now - b->held_since_ns > FTM_ID_CONFIRM_WAIT_NS) {
            b->held_late_told = true;
            blog("the server %u has not confirmed participant id %u as this process's for %.0f s "
                 "(a server older than this bot never does): no probe input",
                 b->server_id, g_id, (double)FTM_ID_CONFIRM_WAIT_NS * 1e-9);
        }
        /* no probe input before the first sync: the server would not know
         * us yet (our JOINING status travels on another topic) and warn;
         * nor before it confirmed that it hears this process under our id */
        if (b->role == FTM_WIRE_ROLE_TRAINEE && now >= next_input && !b->id_told.taken &&
            b->id_held && b->ever_synced && !b->server_left) {
            send_probe(b, t);
            next_input += (int64_t)(b->o.input_period * 1e9);
            if (next_input < now)
                next_input = now;
        }
        /* not while the server is away: nobody would hear them. Due ones
         * wait for the server's return (a restarted one: once synced with it) */
        if (b->role == FTM_WIRE_ROLE_INSTRUCTOR && b->ever_synced && !b->server_left &&
            !b->need_announce)
            send_commands(b, t);
        ftm_wire_state st = cur_state(b);
        if (st == FTM_WIRE_STATE_SYNCED) {
            if (!b->ever_synced)
                blog("synced at tick %" PRIu64, ftm_replay_tick(b->rep));
            b->ever_synced = true;
            b->unsynced_since = now;
        } else if (now - b->unsynced_since > (int64_t)(b->o.resync_timeout * 1e9)) {
            blog("not synced for %.1f s (%s): giving up", b->o.resync_timeout,
                 b->ever_synced ? "hash mismatch or gap did not recover" : "never synced");
            rc_exit = 1;
            why = "resync timeout";
            break;
        }
        if (now >= next_status) {
            publish_status(b, st);
            next_status += SEC / 2;
            if (next_status < now)
                next_status = now + SEC / 2;
        }
    }
    if (g_stop)
        why = "signal";
    /* the replies to the last commands, if the server is still there */
    for (int64_t until = mono_ns() + FTM_REPLY_TIMEOUT_NS;
         b->pending.n > 0 && !g_stop && !b->server_left && mono_ns() < until;) {
        ftm_wire_received rx;
        if (ftm_wire_receive(b->wire, FTM_WIRE_CONTROL_REPLY, &rx, SEC / 100, NULL) == FTM_OK) {
            if (from_server(b, &rx))
                on_reply(b, &rx.msg.u.control_reply);
            ftm_wire_received_free(&rx);
        }
        while (ftm_wire_receive(b->wire, FTM_WIRE_STATUS, &rx, 0, NULL) == FTM_OK) {
            on_status(b, &rx);
            ftm_wire_received_free(&rx);
        }
        if (mono_ns() >= next_status) {
            publish_status(b, cur_state(b));
            next_status = mono_ns() + SEC / 2;
        }
    }
    expire_commands(b);
    double t_end = (double)(mono_ns() - g_t0) * 1e-9;
    for (int32_t i = 0; i < b->sc.ncmds && b->role == FTM_WIRE_ROLE_INSTRUCTOR; i++) {
        const ftm_script_command *c = &b->sc.cmds[i];
        if (!c->done && c->e.t <= t_end) { /* due, but held: no server to hear it */
            char what[FTM_PENDING_WHAT], text[FTM_OUTCOME_TEXT];
            ftm_script_command_text(c, what, sizeof what);
            snprintf(text, sizeof text, "%s: not sent: no server was there to hear it", what);
            unanswered(b, text);
        }
    }
    for (char text[FTM_OUTCOME_TEXT]; b->pending.n > 0;) {
        snprintf(text, sizeof text, "%.95s: no reply from the server before this bot stopped",
                 b->pending.cmd[0].what);
        b->pending.cmd[0] = b->pending.cmd[--b->pending.n]; /* order no longer matters */
        unanswered(b, text);
    }
    publish_status(b, FTM_WIRE_STATE_LEAVING);
    ftm_wire_flush(b->wire, SEC, NULL);
    ftm_replay_stats rs;
    memset(&rs, 0, sizeof rs);
    if (b->rep)
        ftm_replay_get_stats(b->rep, &rs);
    ftm_wire_state st = cur_state(b);
    if (st != FTM_WIRE_STATE_SYNCED)
        rc_exit = 1;
    if (b->id_told.taken)
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
    if (st != FTM_WIRE_STATE_SYNCED && !b->ever_synced)
        blog("never synced: %s", never_synced_why(b));
    if (b->role == FTM_WIRE_ROLE_INSTRUCTOR)
        blog("commands: %" PRIu64 " sent, %" PRIu64 " applied, %" PRIu64 " changed, %" PRIu64
             " refused, %" PRIu64 " unanswered", b->command_id, b->applied, b->changed, b->refused,
             b->unanswered);
    if (b->restarts)
        blog("%u server restart%s rejoined", b->restarts, b->restarts > 1 ? "s" : "");
    if (b->sc.nexpects > 0) {
        int failed = ftm_script_expect_report(&b->sc, b->o.script,
                                              (double)(mono_ns() - g_t0) * 1e-9, stderr);
        blog("%d of %d expectations failed", failed, (int)b->sc.nexpects);
        /* a sync failure (1) or a taken id (2) says more: it keeps its code */
        if (failed && rc_exit == 0)
            rc_exit = 4;
    }
    printf("ftm-bot %u: final tick %" PRIu64 " hash %016" PRIx64 " %s\n", b->o.id,
           b->rep ? ftm_replay_tick(b->rep) : 0, b->rep ? ftm_replay_hash(b->rep) : 0,
           st == FTM_WIRE_STATE_SYNCED ? "synced" : "not-synced");
    fflush(stdout);
    ftm_wire_transport_destroy(b->wire);
    ftm_replay_destroy(b->rep);
    ftm_scene_destroy(b->scene);
    ftm_script_free(&b->sc);
    if (b->csv)
        fclose(b->csv);
    return rc_exit;
}
