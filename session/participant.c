/* SPDX-License-Identifier: GPL-3.0-or-later */
/* The participant core (participant.h): one implementation of the
 * participant's side of the protocol for ftm-bot and ftm-client. */
#include "participant.h"
#include "sessions.h"

#include "ftm/clock.h"

#include <inttypes.h>
#include <pthread.h>
#include <stdarg.h>
#include <stdatomic.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <time.h>

#define SEC FTM_NS_PER_S
#define STATUS_PERIOD_NS (SEC / 2)
#define QUIET_NS SEC /* after joining, statuses say JOINING this long */
#define JOIN_FLUSH_NS (SEC / 10) /* the first JOINING's write, at most */
#define SERVER_STATUS_DEADLINE_NS (2 * SEC) /* the server's (docs/protocol.md) */
/* frames taken per turn, at most this long: a replica that replays slower
 * than the ticks come (a sanitizer build, a loaded host) must still send
 * its status every 500 ms, or the server takes it for lost mid-press */
#define DRAIN_NS (SEC / 100)
#define RETIRED_MAX 8

struct ftm_participant {
    ftm_participant_def def;
    ftm_wire_transport *wire;
    uint64_t origin; /* this process (ftm_wire_transport_origin) */
    ftm_participant_info info;
    ftm_scene *scene;
    /* scenes of servers before a restart: a program may still draw them
     * (scene_loaded); freed with the core */
    ftm_scene *retired[RETIRED_MAX];
    int32_t nretired;
    char failed_scene[FTM_WIRE_NAME_MAX]; /* a name that could not be loaded */
    ftm_replay *rep;
    ftm_id_told told;
    bool held_late_told;
    int64_t joined_ns, last_status_ns;
    int64_t scanned_ns; /* the last look for the domain's sessions (0: none) */
    ftm_wire_state last_told; /* the state of the last status */
    /* commands waiting for their reply: any thread */
    pthread_mutex_t lock;
    ftm_pending pending;
    atomic_uint_fast64_t command_id;
};

static void plog(const ftm_participant *p, ftm_log_level level, const char *fmt, ...)
    __attribute__((format(printf, 3, 4)));
static void plog(const ftm_participant *p, ftm_log_level level, const char *fmt, ...)
{
    if (!p->def.log)
        return;
    char buf[768];
    va_list ap;
    va_start(ap, fmt);
    vsnprintf(buf, sizeof buf, fmt, ap);
    va_end(ap);
    p->def.log(p->def.log_user, level, buf);
}

static void force_off(ftm_participant *p, const char *why)
{
    if (p->def.hooks.force_off)
        p->def.hooks.force_off(p->def.hooks_user, why);
}

/* ---- statuses ------------------------------------------------------------------------- */

static void publish_status(ftm_participant *p, ftm_wire_state state)
{
    ftm_wire_msg m;
    memset(&m, 0, sizeof m);
    m.kind = FTM_WIRE_STATUS;
    ftm_wire_status *st = &m.u.status;
    st->participant = p->def.id;
    st->role = p->def.role;
    st->state = state;
    if (p->rep) {
        ftm_replay_stats rs;
        ftm_replay_get_stats(p->rep, &rs);
        st->last_applied_tick = ftm_replay_tick(p->rep);
        st->state_hash = ftm_replay_hash(p->rep);
        uint64_t n = rs.frames_applied + rs.idle_ticks;
        st->replay_ns_per_tick = n ? rs.replay_ns_total / (double)n : 0.0;
        st->replay_ns_max = ftm_replay_take_max(p->rep);
    }
    snprintf(st->name, sizeof st->name, "%s",
             p->def.name ? p->def.name : ftm_wire_role_name(p->def.role));
    ftm_error err = {0, ""};
    if (ftm_wire_publish(p->wire, &m, &err))
        plog(p, FTM_LOG_WARN, "status: %s", err.message);
    const int64_t now = ftm_clock_mono_ns();
    if (p->last_status_ns && now - p->last_status_ns > SERVER_STATUS_DEADLINE_NS)
        plog(p, FTM_LOG_WARN, "no status sent for %.1f s, past the server's %.0f s deadline: it "
             "has probably declared this participant lost and released its probes",
             (double)(now - p->last_status_ns) * 1e-9, (double)SERVER_STATUS_DEADLINE_NS * 1e-9);
    p->last_status_ns = now;
    p->last_told = state;
}

ftm_wire_state ftm_participant_state(const ftm_participant *p)
{
    return p->rep ? ftm_replay_state(p->rep) : FTM_WIRE_STATE_JOINING;
}

/* A change of the replica's state is told at once, except in the first
 * second after joining: then the status stays the JOINING sent on joining
 * (docs/protocol.md), which is what another process with our id must hear
 * of us first; the periodic status at the end of that second tells the
 * state reached. (A SYNCED told early and then not repeated for a second
 * also looked like a replica falling behind to the server's depth
 * controller.) */
bool ftm_participant_status_due(ftm_participant *p, int64_t now_ns)
{
    const ftm_wire_state st = ftm_participant_state(p);
    if (now_ns - p->joined_ns < QUIET_NS ||
        (st == p->last_told && now_ns - p->last_status_ns < STATUS_PERIOD_NS))
        return false;
    publish_status(p, st);
    return true;
}

/* The replica's state after it took a message: "synced at tick" each time
 * it gets there (after joining and after every resync). */
static void note_state(ftm_participant *p)
{
    const bool synced = p->rep && ftm_replay_state(p->rep) == FTM_WIRE_STATE_SYNCED;
    if (synced && !p->info.synced)
        plog(p, FTM_LOG_INFO, "synced at tick %" PRIu64, ftm_replay_tick(p->rep));
    p->info.synced = synced;
    p->info.ever_synced |= synced;
}

/* ---- the server: trust, gone and back ------------------------------------------------- */

/* Whether rx is from the server process we follow (ftm_replay_from_server:
 * the trust rule); anything else is counted and logged, rate-limited. */
static bool from_server(ftm_participant *p, const ftm_wire_received *rx)
{
    ftm_participant_info *in = &p->info;
    if (ftm_replay_from_server(&in->server_id, &in->server_origin, rx, in->server_left))
        return true;
    if (in->server_id == 0)
        return false; /* no announcement yet: nothing to follow */
    in->foreign++;
    if (in->foreign <= 3 || (in->foreign & (in->foreign - 1)) == 0) /* 1, 2, 3, 4, 8, ... */
        plog(p, FTM_LOG_WARN, "%s from participant %u ignored (%" PRIu64 " so far): not from the "
             "server %u%s", ftm_wire_kind_name((int)rx->msg.kind), rx->sender, in->foreign,
             in->server_id,
             rx->sender == in->server_id ? "'s process: another process uses its id" : "");
    return false;
}

/* The server left: by a `gone` event (lease: its DDS lease expired, which a
 * stall of either side or a cut link also causes) or by its LEAVING status
 * (which still says it left after a lease expiry). */
static void server_left(ftm_participant *p, bool lease, uint64_t tick)
{
    ftm_participant_info *in = &p->info;
    if (in->server_left && !(in->server_gone && !lease))
        return;
    if (lease)
        plog(p, FTM_LOG_WARN, "server %u gone (lease expired or left)", in->server_id);
    else
        plog(p, FTM_LOG_WARN, "server %u leaving at tick %" PRIu64, in->server_id, tick);
    in->server_left = true;
    in->server_gone = lease;
    in->server_left_ns = ftm_clock_mono_ns();
    /* whether it comes back as the same process or a restarted one, its
     * next announcement says (on_announce) */
    if (lease)
        in->need_announce = true;
    force_off(p, "server gone");
}

/* A message from the server's own process (from_server). After a `gone`
 * event it is alive after all: force and probe input come back with the
 * next frame once the replica is synced and the server confirms our id
 * again. */
static void server_heard(ftm_participant *p)
{
    ftm_participant_info *in = &p->info;
    if (!in->server_left || !in->server_gone)
        return;
    plog(p, FTM_LOG_INFO, "server %u is back (its lease had expired): rejoining", in->server_id);
    in->server_left = in->server_gone = false;
    in->last_frame_ns = ftm_clock_mono_ns();
    if (!in->id_held)
        in->held_since_ns = in->last_frame_ns; /* the wait for our id starts again */
}

/* ---- joining ------------------------------------------------------------------------- */

static int make_replica(ftm_participant *p)
{
    ftm_error err = {0, ""};
    if (ftm_replay_create(p->scene, p->def.log, p->def.log_user, &p->rep, &err)) {
        plog(p, FTM_LOG_ERROR, "replay: %s", err.message);
        return err.code;
    }
    /* Keyframes that came before the replica existed are lost, and the one
     * the JOINING sent on joining asked for may be older than the first
     * frame our reader got: ask again, now that the readers are matched
     * (the one more JOINING the first second may carry, docs/protocol.md;
     * waiting for the end of that second instead delayed a late joiner's
     * sync by up to a second) */
    publish_status(p, FTM_WIRE_STATE_JOINING);
    return FTM_OK;
}

/* Another process under the server's id (a service restarted it): its state
 * starts afresh, and so does the replica. The scene is checked afterwards:
 * another one is loaded unless --scene names ours. */
static void rejoin(ftm_participant *p, const ftm_wire_announce *a)
{
    ftm_participant_info *in = &p->info;
    /* a server that resumed the lesson from its recording (ftm-server
     * --resume): the same session going on, from a tick up to about 100 ms
     * before where the crashed one was; the replica resyncs all the same */
    const bool resumed = a->lesson_start_ns && a->lesson_start_ns == in->lesson_start;
    if (resumed)
        plog(p, FTM_LOG_INFO, "server %u resumed the lesson (a new process, going on from tick "
             "%" PRIu64 "; we were at tick %" PRIu64 "): resyncing", in->server_id, a->tick,
             p->rep ? ftm_replay_tick(p->rep) : 0);
    else
        plog(p, FTM_LOG_INFO, "server %u restarted (a new process, announcing tick %" PRIu64
             "; we were at tick %" PRIu64 "): rejoining", in->server_id, a->tick,
             p->rep ? ftm_replay_tick(p->rep) : 0);
    force_off(p, "server restarted");
    const bool same = p->rep && ftm_replay_check_announce(p->rep, a, NULL) == FTM_OK;
    ftm_replay_destroy(p->rep);
    p->rep = NULL;
    in->restarts++;
    in->server_left = in->server_gone = false;
    /* no probe input before it knows us; which process holds our id is the
     * new server's to say */
    in->synced = in->ever_synced = false;
    p->told = (ftm_id_told){0};
    in->id_taken = in->id_held = in->id_late = false;
    p->held_late_told = false;
    in->held_since_ns = 0;
    in->last_frame_ns = ftm_clock_mono_ns();
    in->resumes += resumed;
    if (p->def.hooks.restarted && !resumed)
        p->def.hooks.restarted(p->def.hooks_user);
    if (!same && !p->def.scene && p->nretired < RETIRED_MAX) {
        plog(p, FTM_LOG_INFO, "the restarted server has another scene: '%s'", a->scene_id);
        p->retired[p->nretired++] = p->scene; /* (a program may still draw it) */
        p->scene = NULL;
        p->failed_scene[0] = '\0';
    } else {
        make_replica(p);
    }
}

/* A scene a trainee cannot feel (or that would feel like bone) is said when
 * it loads, not found out by pressing it: the press estimate costs half a
 * simulated second of the contact region, once per scene. */
static void scene_feel(ftm_participant *p)
{
    ftm_press_estimate e;
    ftm_error err = {0, ""};
    p->info.scene_feel = 0;
    p->info.scene_feel_text[0] = '\0';
    if (ftm_scene_press_estimate(p->scene, FTM_PRESS_ESTIMATE_DEPTH, &e, &err)) {
        plog(p, FTM_LOG_INFO, "scene '%s': no press estimate: %s", ftm_scene_name(p->scene),
             err.message);
        return;
    }
    p->info.scene_feel = ftm_press_verdict(&e);
    ftm_press_describe(&e, p->info.scene_feel_text, sizeof p->info.scene_feel_text);
    plog(p, p->info.scene_feel ? FTM_LOG_WARN : FTM_LOG_INFO, "scene '%s': %s",
         ftm_scene_name(p->scene), p->info.scene_feel_text);
}

/* The scene of an announcement, once: a name that failed is not tried
 * again (every announcement would say so). */
static void load_scene(ftm_participant *p, const ftm_wire_announce *a)
{
    const char *name = p->def.scene ? p->def.scene : a->scene_id;
    if (strcmp(p->failed_scene, name) == 0)
        return;
    char path[1024];
    ftm_error err = {0, ""};
    if (ftm_wire_open_scene(name, &p->scene, path, sizeof path, &err)) {
        snprintf(p->failed_scene, sizeof p->failed_scene, "%s", name);
        p->info.scene_failed = true;
        plog(p, FTM_LOG_ERROR, "cannot load scene '%s': %s", name, err.message);
        if (p->def.hooks.scene_refused)
            p->def.hooks.scene_refused(p->def.hooks_user, true, name, &err);
        force_off(p, "no scene");
        return;
    }
    p->info.scene_failed = false;
    if (p->def.feel_check)
        scene_feel(p);
    else
        p->info.scene_feel = 0, p->info.scene_feel_text[0] = '\0';
    if (strcmp(path, name) != 0)
        plog(p, FTM_LOG_INFO, "scene '%s': %s", name, path);
    /* (the announcement's tick is when it was made, not where we sync:
     * "synced at tick" says that) */
    plog(p, FTM_LOG_INFO, "joined session: scene '%s', %u Hz%s; syncing from a keyframe",
         a->scene_id, a->tick_rate_hz, a->paused ? " (paused)" : "");
    if (p->def.hooks.scene_loaded)
        p->def.hooks.scene_loaded(p->def.hooks_user, p->scene, name);
    make_replica(p);
}

static void on_announce(ftm_participant *p, const ftm_wire_announce *a)
{
    ftm_participant_info *in = &p->info;
    if (!in->have_ann || in->ann.paused != a->paused)
        in->last_frame_ns = ftm_clock_mono_ns(); /* frames stop (paused) or start again */
    in->ann = *a;
    in->have_ann = true;
    in->need_announce = false;
    /* a new process under the server's id; also after a scene that did not
     * fit, which a restarted server may fix */
    if (p->scene && a->server_start_ns && in->server_start && a->server_start_ns != in->server_start)
        rejoin(p, a);
    in->lesson_start = a->lesson_start_ns;
    if (p->scene && !p->rep)
        return; /* it did not fit (below): until the server restarts */
    if (!p->scene)
        load_scene(p, a);
    if (!p->rep)
        return;
    in->server_start = a->server_start_ns;
    ftm_error err = {0, ""};
    if (ftm_replay_check_announce(p->rep, a, &err)) {
        plog(p, FTM_LOG_ERROR, "%s", err.message);
        if (p->def.hooks.scene_refused)
            p->def.hooks.scene_refused(p->def.hooks_user, false, a->scene_id, &err);
        /* the scene stays (a program may draw it); the replica goes */
        ftm_replay_destroy(p->rep);
        p->rep = NULL;
        force_off(p, "scene mismatch");
    }
}

/* ---- statuses of the others and of the server ---------------------------------------- */

/* A status of the server: what it says of our id, and whether it left. */
static void server_status(ftm_participant *p, const ftm_wire_status *st)
{
    ftm_participant_info *in = &p->info;
    const uint32_t id = p->def.id;
    const ftm_id_claim c = ftm_replay_id_verdict(&p->told, st, id, p->origin);
    if (c == FTM_ID_TAKEN) {
        plog(p, FTM_LOG_ERROR, "participant id %u is taken: another process in session '%s' uses "
             "it and the server listens to that one; give each participant its own --id", id,
             p->def.session);
        force_off(p, "participant id taken");
    } else if (c == FTM_ID_NEWCOMER) {
        plog(p, FTM_LOG_WARN, "another process joined as participant %u: the server ignores it", id);
    } else if (c == FTM_ID_OURS_AGAIN) {
        /* force comes back once the server also confirms we hold the id */
        plog(p, FTM_LOG_INFO, "participant id %u is ours again: the process that held it left "
             "and the server hears this one", id);
    }
    in->id_taken = p->told.taken;
    const bool held = ftm_replay_id_held(st, id, p->origin);
    if (held && !in->id_held) {
        plog(p, FTM_LOG_INFO, "participant id %u is confirmed: the server hears this process "
             "under it%s", id, p->held_late_told ? " (late)" : "");
    } else if (!held && in->id_held) {
        plog(p, FTM_LOG_WARN, "the server no longer confirms participant id %u as this "
             "process's: no probe input or force until it does", id);
        force_off(p, "participant id not confirmed");
        in->held_since_ns = ftm_clock_mono_ns();
        p->held_late_told = false;
    }
    in->id_held = held;
    if (st->state == FTM_WIRE_STATE_LEAVING) {
        server_left(p, false, st->last_applied_tick);
        return;
    }
    server_heard(p);
    /* a paused server sends no frames: its statuses (every 0.5 s) say it
     * is alive */
    if (in->have_ann && in->ann.paused)
        in->last_frame_ns = ftm_clock_mono_ns();
}

static void on_status(ftm_participant *p, const ftm_wire_received *rx)
{
    ftm_participant_info *in = &p->info;
    bool trusted = false;
    if (rx->gone) {
        /* (origin 0: no longer known; gone only turns things off) */
        if (in->server_id && rx->sender == in->server_id &&
            (!rx->origin || rx->origin == in->server_origin))
            server_left(p, true, 0);
    } else if (rx->sender == p->def.id) {
        return; /* another process with our id: the server says which it hears */
    } else if (rx->msg.u.status.role == FTM_WIRE_ROLE_SERVER && from_server(p, rx)) {
        trusted = true;
        server_status(p, &rx->msg.u.status);
    }
    if (p->def.hooks.status)
        p->def.hooks.status(p->def.hooks_user, rx, trusted);
}

/* ---- frames -------------------------------------------------------------------------- */

static void on_tick(ftm_participant *p, const ftm_wire_received *rx)
{
    server_heard(p);
    const int64_t taken = ftm_clock_real_ns(); /* by this thread, before replaying */
    p->info.last_frame_ns = ftm_clock_mono_ns();
    bool stepped = false, fresh = false;
    if (p->rep) {
        const uint64_t tick = ftm_replay_tick(p->rep), frame = ftm_replay_last_frame(p->rep)->tick;
        if (ftm_replay_on_tick(p->rep, rx))
            plog(p, FTM_LOG_ERROR, "replay: out of memory");
        stepped = ftm_replay_tick(p->rep) != tick;
        fresh = ftm_replay_last_frame(p->rep)->tick != frame;
        note_state(p);
    }
    if (p->def.hooks.frame)
        p->def.hooks.frame(p->def.hooks_user, rx, taken, stepped, fresh);
}

static void on_keyframe(ftm_participant *p, const ftm_wire_keyframe *k)
{
    p->info.keyframes_heard++;
    if (!p->rep)
        return;
    const uint64_t tick = ftm_replay_tick(p->rep);
    if (ftm_replay_on_keyframe(p->rep, k))
        plog(p, FTM_LOG_ERROR, "replay: out of memory");
    note_state(p);
    if (p->def.hooks.keyframe)
        p->def.hooks.keyframe(p->def.hooks_user, ftm_replay_tick(p->rep) != tick);
}

bool ftm_participant_held(const ftm_participant *p)
{
    return p->def.hold && p->rep && ftm_replay_state(p->rep) == FTM_WIRE_STATE_SYNCED &&
           ftm_replay_tick(p->rep) >= p->def.hold_tick;
}

/* ---- commands ------------------------------------------------------------------------ */

static void outcome(ftm_participant *p, const char *text, int what, bool known)
{
    plog(p, what == FTM_WIRE_OUTCOME_APPLIED || what == FTM_WIRE_OUTCOME_CHANGED ? FTM_LOG_INFO
                                                                                 : FTM_LOG_WARN,
         "command %s%s", text, known || !what ? "" : " (no such command waiting)");
    if (p->def.hooks.outcome)
        p->def.hooks.outcome(p->def.hooks_user, text, what, known);
}

static void on_reply(ftm_participant *p, const ftm_wire_control_reply *r)
{
    if (r->issuer != p->def.id || p->told.taken)
        return; /* another instructor's (or for the process holding our id) */
    char text[FTM_OUTCOME_TEXT];
    pthread_mutex_lock(&p->lock);
    const bool known = ftm_pending_reply(&p->pending, r, text, sizeof text);
    pthread_mutex_unlock(&p->lock);
    outcome(p, text, (int)r->outcome, known);
}

static void expire_commands(ftm_participant *p)
{
    char text[FTM_OUTCOME_TEXT];
    for (;;) {
        pthread_mutex_lock(&p->lock);
        const bool late = ftm_pending_expired(&p->pending, ftm_clock_mono_ns(),
                                              FTM_REPLY_TIMEOUT_NS, text, sizeof text);
        pthread_mutex_unlock(&p->lock);
        if (!late)
            return;
        outcome(p, text, 0, true);
    }
}

int ftm_participant_send_control(ftm_participant *p, ftm_wire_control *c, const char *what,
                                 ftm_error *err)
{
    c->issuer = p->def.id;
    c->command_id = (uint64_t)atomic_fetch_add(&p->command_id, 1) + 1;
    ftm_wire_msg m;
    memset(&m, 0, sizeof m);
    m.kind = FTM_WIRE_CONTROL;
    m.u.control = *c;
    /* waiting before it is out: the reply may come before this returns */
    char text[FTM_OUTCOME_TEXT];
    pthread_mutex_lock(&p->lock);
    const bool gave_up = ftm_pending_add(&p->pending, c->command_id, what ? what : "command",
                                         ftm_clock_mono_ns(), text, sizeof text);
    pthread_mutex_unlock(&p->lock);
    if (gave_up)
        outcome(p, text, 0, true);
    int rc = ftm_wire_publish(p->wire, &m, err);
    if (rc) { /* not sent: nothing to wait for */
        pthread_mutex_lock(&p->lock);
        ftm_pending_forget(&p->pending, c->command_id);
        pthread_mutex_unlock(&p->lock);
    }
    return rc;
}

bool ftm_participant_pending_pop(ftm_participant *p, char *what, size_t cap)
{
    pthread_mutex_lock(&p->lock);
    const bool any = p->pending.n > 0;
    if (any) {
        snprintf(what, cap, "%s", p->pending.cmd[0].what);
        ftm_pending_forget(&p->pending, p->pending.cmd[0].id);
    }
    pthread_mutex_unlock(&p->lock);
    return any;
}

int32_t ftm_participant_pending_count(ftm_participant *p)
{
    pthread_mutex_lock(&p->lock);
    const int32_t n = p->pending.n;
    pthread_mutex_unlock(&p->lock);
    return n;
}

/* ---- probe input --------------------------------------------------------------------- */

bool ftm_participant_id_ours(const ftm_participant *p)
{
    return p->info.id_held && !p->told.taken;
}

/* Not before the first sync: the server may not have our first status yet
 * (another topic) and would reject the input of an unknown participant.
 * Only under an id the server confirms ours: it might take our HIP for
 * another process's. Nor while the server is gone: a restarted one would
 * not know us yet. */
bool ftm_participant_may_press(const ftm_participant *p)
{
    return p->def.role == FTM_WIRE_ROLE_TRAINEE && p->info.ever_synced &&
           ftm_participant_id_ours(p) && !p->info.server_left;
}

bool ftm_participant_send_probe(ftm_participant *p, const ftm_wire_probe_sample *samples, int n)
{
    if (n <= 0 || !ftm_participant_may_press(p))
        return false;
    ftm_wire_msg m;
    memset(&m, 0, sizeof m);
    m.kind = FTM_WIRE_PROBE_INPUT;
    m.u.probe_input.participant = p->def.id;
    m.u.probe_input.last_tick_seen = p->rep ? ftm_replay_tick(p->rep) : 0;
    m.u.probe_input.sample_count = n;
    m.u.probe_input.samples = (ftm_wire_probe_sample *)samples;
    ftm_error err = {0, ""};
    if (ftm_wire_publish(p->wire, &m, &err)) {
        plog(p, FTM_LOG_WARN, "probe input: %s", err.message);
        return false;
    }
    return true;
}

/* The wait for the server to confirm our id starts with its first
 * announcement (or its restart, or the confirmation's loss). */
static void id_wait(ftm_participant *p, int64_t now)
{
    ftm_participant_info *in = &p->info;
    if (in->have_ann && !in->held_since_ns)
        in->held_since_ns = now;
    in->id_late = p->def.role == FTM_WIRE_ROLE_TRAINEE && !in->id_held && !p->told.taken &&
                  in->held_since_ns && now - in->held_since_ns > FTM_ID_CONFIRM_WAIT_NS;
    if (in->id_late && !p->held_late_told) {
        p->held_late_told = true;
        plog(p, FTM_LOG_ERROR, "the server %u has not confirmed participant id %u as this "
             "process's for %.0f s (a server older than this participant never does): no probe "
             "input, no force", in->server_id, p->def.id, (double)FTM_ID_CONFIRM_WAIT_NS * 1e-9);
    }
}

/* ---- the loop ------------------------------------------------------------------------ */

/* Up to max messages of a kind, each to its handler. */
static void take(ftm_participant *p, int kind, int max)
{
    for (int i = 0; i < max; i++) {
        ftm_wire_received rx;
        if (ftm_wire_receive(p->wire, kind, &rx, 0, NULL) != FTM_OK)
            return;
        switch (kind) {
        case FTM_WIRE_ANNOUNCE:
            if (from_server(p, &rx))
                on_announce(p, &rx.msg.u.announce);
            break;
        case FTM_WIRE_STATUS: on_status(p, &rx); break;
        case FTM_WIRE_PROBE_INPUT:
            if (p->def.hooks.probe_input)
                p->def.hooks.probe_input(p->def.hooks_user, &rx);
            break;
        case FTM_WIRE_CONTROL_REPLY:
            if (from_server(p, &rx))
                on_reply(p, &rx.msg.u.control_reply);
            break;
        case FTM_WIRE_KEYFRAME:
            if (from_server(p, &rx))
                on_keyframe(p, &rx.msg.u.keyframe);
            break;
        default: break;
        }
        ftm_wire_received_free(&rx);
    }
}

/* No server has announced our session for a while: a mistyped name waits
 * forever, so say which sessions the domain has (blocks for a second, while
 * there is nothing else to do), in the log and in info.sessions_heard. */
#define NO_SESSION_NS 3000000000LL
#define RESCAN_NS 30000000000LL
static void no_session_yet(ftm_participant *p, int64_t now)
{
    if (p->info.have_ann || now - p->joined_ns < NO_SESSION_NS ||
        (p->scanned_ns && now - p->scanned_ns < RESCAN_NS))
        return;
    ftm_sessions_def d = ftm_default_sessions_def();
    d.domain = p->def.domain;
    d.dds_config = p->def.dds_config;
    d.dds_security = p->def.dds_security;
    d.participant_id = p->def.id;
    ftm_session_seen seen[FTM_SESSIONS_MAX];
    int32_t n = 0;
    ftm_error err = {0, ""};
    int rc = ftm_sessions_find(&d, seen, FTM_SESSIONS_MAX, &n, &err);
    p->scanned_ns = ftm_clock_mono_ns();
    if (p->info.have_ann)
        return; /* (it came meanwhile) */
    char names[sizeof p->info.sessions_heard];
    ftm_sessions_names(seen, n, names, sizeof names);
    p->info.sessions_scanned = rc == FTM_OK;
    snprintf(p->info.sessions_heard, sizeof p->info.sessions_heard, "%s", names);
    p->info.nsessions = 0;
    for (int32_t i = 0; rc == FTM_OK && i < n && p->info.nsessions < FTM_PARTICIPANT_PICK; i++)
        if (seen[i].announced)
            p->info.sessions[p->info.nsessions++] = seen[i];
    if (rc)
        plog(p, FTM_LOG_WARN, "no server announces session '%s' on domain %u yet; the domain's "
             "sessions could not be listed: %s", p->def.session, p->def.domain, err.message);
    else
        plog(p, FTM_LOG_WARN,
             "no server announces session '%s' on domain %u after %.0f s; sessions heard there: "
             "%s (names are case-sensitive; --list shows them)",
             p->def.session, p->def.domain, (double)(now - p->joined_ns) * 1e-9,
             n ? names : "none");
}

bool ftm_participant_turn(ftm_participant *p, int64_t wait_ns)
{
    take(p, FTM_WIRE_ANNOUNCE, 1);
    take(p, FTM_WIRE_STATUS, 64);
    if (p->def.watch_probes)
        take(p, FTM_WIRE_PROBE_INPUT, 256);
    if (p->def.role == FTM_WIRE_ROLE_INSTRUCTOR) {
        take(p, FTM_WIRE_CONTROL_REPLY, 64);
        expire_commands(p);
    }
    bool more = false;
    if (ftm_participant_held(p)) {
        struct timespec ts = {0, wait_ns > 0 ? (long)wait_ns : 0};
        nanosleep(&ts, NULL);
    } else {
        take(p, FTM_WIRE_KEYFRAME, 1);
        const int64_t until = ftm_clock_mono_ns() + (wait_ns > 0 ? wait_ns : 0) + DRAIN_NS;
        for (int n = 0; !ftm_participant_held(p); n++) {
            if (n > 0 && ftm_clock_mono_ns() >= until) {
                more = true;
                break;
            }
            ftm_wire_received rx;
            if (ftm_wire_receive(p->wire, FTM_WIRE_TICK, &rx, n == 0 ? wait_ns : 0, NULL) != FTM_OK)
                break;
            if (from_server(p, &rx))
                on_tick(p, &rx);
            ftm_wire_received_free(&rx);
        }
    }
    id_wait(p, ftm_clock_mono_ns());
    no_session_yet(p, ftm_clock_mono_ns());
    return more;
}

/* ---- life ---------------------------------------------------------------------------- */

int ftm_participant_create(const ftm_participant_def *def, ftm_participant **out, ftm_error *err)
{
    ftm_participant *p = calloc(1, sizeof *p);
    if (!p)
        return ftm_error_set(err, FTM_ENOMEM, "participant: out of memory");
    p->def = *def;
    if (!p->def.session)
        p->def.session = "ftm";
    ftm_wire_transport_def wd;
    memset(&wd, 0, sizeof wd);
    wd.config = def->dds_config;
    wd.security = def->dds_security;
    wd.role = def->role;
    wd.domain_id = def->domain;
    wd.session = p->def.session;
    wd.participant_id = def->id;
    wd.publish = FTM_WIRE_KIND_BIT(FTM_WIRE_STATUS);
    if (def->role == FTM_WIRE_ROLE_TRAINEE)
        wd.publish |= FTM_WIRE_KIND_BIT(FTM_WIRE_PROBE_INPUT);
    wd.subscribe = FTM_WIRE_KIND_BIT(FTM_WIRE_ANNOUNCE) | FTM_WIRE_KIND_BIT(FTM_WIRE_TICK) |
                   FTM_WIRE_KIND_BIT(FTM_WIRE_KEYFRAME) | FTM_WIRE_KIND_BIT(FTM_WIRE_STATUS);
    if (def->watch_probes)
        wd.subscribe |= FTM_WIRE_KIND_BIT(FTM_WIRE_PROBE_INPUT);
    if (def->role == FTM_WIRE_ROLE_INSTRUCTOR) {
        wd.publish |= FTM_WIRE_KIND_BIT(FTM_WIRE_CONTROL);
        wd.subscribe |= FTM_WIRE_KIND_BIT(FTM_WIRE_CONTROL_REPLY);
    }
    wd.log = def->log;
    wd.log_user = def->log_user;
    int rc = ftm_wire_transport_create(&wd, &p->wire, err);
    if (rc) {
        free(p);
        return rc;
    }
    p->origin = ftm_wire_transport_origin(p->wire);
    pthread_mutex_init(&p->lock, NULL);
    atomic_init(&p->command_id, 0);
    p->last_told = FTM_WIRE_STATE_JOINING;
    p->joined_ns = p->info.last_frame_ns = ftm_clock_mono_ns();
    *out = p;
    return FTM_OK;
}

void ftm_participant_join(ftm_participant *p)
{
    publish_status(p, FTM_WIRE_STATE_JOINING);
    /* The quiet second counts from when that JOINING is written, which is
     * when DDS stamps it, not from when it was queued: so no receiver sees
     * a status other than JOINING stamped within a second of it
     * (docs/protocol.md).
     * Usually no reader is matched yet and this waits for the write alone;
     * readers matched already are waited for too, at most 0.1 s. */
    ftm_wire_flush(p->wire, JOIN_FLUSH_NS, NULL);
    p->joined_ns = p->info.last_frame_ns = ftm_clock_mono_ns();
}

void ftm_participant_leave(ftm_participant *p)
{
    publish_status(p, FTM_WIRE_STATE_LEAVING);
    ftm_wire_flush(p->wire, SEC, NULL);
}

void ftm_participant_destroy(ftm_participant *p)
{
    if (!p)
        return;
    ftm_wire_transport_destroy(p->wire);
    ftm_replay_destroy(p->rep);
    for (int32_t k = 0; k < p->nretired; k++)
        ftm_scene_destroy(p->retired[k]);
    ftm_scene_destroy(p->scene);
    pthread_mutex_destroy(&p->lock);
    free(p);
}

const ftm_participant_info *ftm_participant_get_info(const ftm_participant *p) { return &p->info; }

ftm_replay *ftm_participant_replica(ftm_participant *p) { return p->rep; }

const ftm_scene *ftm_participant_scene(const ftm_participant *p) { return p->scene; }

ftm_wire_transport *ftm_participant_wire(ftm_participant *p) { return p->wire; }
