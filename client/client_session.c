/* The client's session thread; see client_session.h and docs/client.md. */
#include "client_session.h"
#include "parts.h"
#include "report.h"

#include "claims.h"
#include "pending.h"
#include "replica.h"

#include <inttypes.h>
#include <pthread.h>
#include <stdarg.h>
#include <stdatomic.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <time.h>

#define SEC 1000000000LL
#define PUBLISH_EVERY_NS (4 * 1000000LL) /* view updates: 250 Hz is plenty for 60 Hz drawing */
#define HIP_STALE_NS (2 * SEC)            /* a remote HIP not updated for this long is dropped */
#define REJECT_BANNER_NS (5 * SEC)
/* frames replayed per turn of the loop, at most this long: a replica that
 * replays slower than the ticks come must still send its status, its probe
 * input and its view in time (the server takes a participant whose status
 * is 2 s late as lost and releases its probes) */
#define DRAIN_NS (10 * 1000000LL)
#define SERVER_STATUS_DEADLINE_NS (2 * SEC) /* the server's (docs/protocol.md) */

typedef struct remote_hip {
    uint32_t participant;
    int32_t probe;
    ftm_vec3 hip;
    int64_t seen_ns;
} remote_hip;

struct ftm_client_session {
    ftm_client_config cfg;
    ftm_wire_transport *wire;
    pthread_t thread;
    atomic_bool stop;
    atomic_bool want_region;
    atomic_uint_fast64_t command_id;

    /* session thread only */
    ftm_scene *scene;
    ftm_scene *retired[8]; /* scenes of servers before a restart: the render
                              thread may still draw them; freed at stop */
    int32_t nretired;
    ftm_replay *rep;
    char failed_scene[FTM_WIRE_NAME_MAX]; /* announced id we could not load */
    ftm_wire_announce ann;
    bool have_ann;
    uint32_t server_id; /* 0 until the first announcement */
    /* the server's process (ftm_wire_received.origin of its announcement):
     * another process under the server's id is not the server (from_server) */
    uint64_t server_origin;
    uint64_t foreign;   /* messages ignored: not from the server */
    bool server_left;
    /* server_left by a `gone` event (its lease expired: a stall or a cut
     * link on either side), not by its LEAVING status: whatever the same
     * process sends afterwards brings it back (server_heard) */
    bool server_gone;
    uint64_t server_start; /* the announced start of the server process we replay */
    int64_t last_frame_ns, last_status_ns, last_input_ns, last_publish_ns;
    uint64_t newest_rx_tick;
    int64_t last_latency_ns;
    remote_hip hips[FTM_CLIENT_MAX_PROBES];
    int32_t nhips;
    ftm_client_part parts[FTM_CLIENT_MAX_PARTS];
    int32_t nparts;
    ftm_report live;    /* the session report, from the frames received */
    uint64_t live_tick; /* newest frame counted in it */
    uint64_t rejected_seen;
    int64_t reject_until_ns;
    char reject_msg[200];
    bool silent_reported;
    int64_t unlisted_ns; /* last status of a participant the full table could not list */
    /* what the server said of our id (on_status); id_told.taken: it hears
     * another process with our id, not us */
    ftm_id_told id_told;
    /* the newest server status lists this process as the one it hears
     * under our id (ftm_replay_id_held): until then no probe input, no
     * force, no figures of our own. held_since_ns: when the wait began (0:
     * no server yet); held_late_told: the wait's bound was logged */
    bool id_held, held_late_told;
    int64_t held_since_ns;
    bool force_valid;
    bool synced, ever_synced; /* the replica is synced; was once */
    uint64_t contact_ticks, counted_tick;
    bool dirty;
    ftm_wire_state last_state;

    /* shared with the render thread: under lock */
    pthread_mutex_t lock;
    ftm_client_view shared;
    ftm_pending pending; /* commands sent (any thread), waiting for their reply */
};

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

static void slog(ftm_client_session *s, ftm_log_level level, const char *fmt, ...)
{
    if (!s->cfg.log)
        return;
    char buf[768];
    va_list ap;
    va_start(ap, fmt);
    vsnprintf(buf, sizeof buf, fmt, ap);
    va_end(ap);
    s->cfg.log(s->cfg.log_user, level, buf);
}

static void force_off(ftm_client_session *s, const char *why)
{
    if (s->force_valid && s->cfg.role == FTM_WIRE_ROLE_TRAINEE)
        slog(s, FTM_LOG_WARN, "force off: %s", why);
    s->force_valid = false;
    if (s->cfg.on_force)
        s->cfg.on_force(s->cfg.force_user, s->rep ? ftm_replay_tick(s->rep) : 0, 0.0, NULL, false,
                        why);
}

/* Whether rx is from the server process we follow (ftm_replay_from_server:
 * the trust rule); anything else is counted and logged, rate-limited. */
static bool from_server(ftm_client_session *s, const ftm_wire_received *rx)
{
    if (ftm_replay_from_server(&s->server_id, &s->server_origin, rx, s->server_left))
        return true;
    if (s->server_id == 0)
        return false;
    s->foreign++;
    if (s->foreign <= 3 || (s->foreign & (s->foreign - 1)) == 0)
        slog(s, FTM_LOG_WARN, "%s from participant %u ignored (%" PRIu64 " so far): not from the server %u%s",
             ftm_wire_kind_name((int)rx->msg.kind), rx->sender, s->foreign, s->server_id,
             rx->sender == s->server_id ? "'s process: another process uses its id" : "");
    return false;
}

/* ---- messages ----------------------------------------------------------------------- */

static void publish_status(ftm_client_session *s, ftm_wire_state state)
{
    ftm_wire_msg m;
    memset(&m, 0, sizeof m);
    m.kind = FTM_WIRE_STATUS;
    ftm_wire_status *st = &m.u.status;
    st->participant = s->cfg.id;
    st->role = s->cfg.role;
    st->state = state;
    if (s->rep) {
        ftm_replay_stats rs;
        ftm_replay_get_stats(s->rep, &rs);
        st->last_applied_tick = ftm_replay_tick(s->rep);
        st->state_hash = ftm_replay_hash(s->rep);
        uint64_t n = rs.frames_applied + rs.idle_ticks;
        st->replay_ns_per_tick = n ? rs.replay_ns_total / (double)n : 0.0;
        st->replay_ns_max = ftm_replay_take_max(s->rep);
    }
    snprintf(st->name, sizeof st->name, "%s", s->cfg.name ? s->cfg.name : "ftm-client");
    ftm_error err = {0, ""};
    if (ftm_wire_publish(s->wire, &m, &err))
        slog(s, FTM_LOG_WARN, "status: %s", err.message);
    int64_t now = mono_ns();
    if (s->last_status_ns && now - s->last_status_ns > SERVER_STATUS_DEADLINE_NS)
        slog(s, FTM_LOG_WARN, "no status sent for %.1f s, past the server's %.0f s deadline: it has "
             "probably declared this client lost and released its probes",
             (double)(now - s->last_status_ns) * 1e-9, (double)SERVER_STATUS_DEADLINE_NS * 1e-9);
    s->last_status_ns = now;
}

static void drop_scene(ftm_client_session *s)
{
    /* the mesh pointer may be in the render thread's view: keep the scene
     * (scenes are only destroyed at stop); just stop replaying */
    ftm_replay_destroy(s->rep);
    s->rep = NULL;
}

static void on_announce(ftm_client_session *s, const ftm_wire_announce *a)
{
    ftm_error err = {0, ""};
    if (!s->have_ann || s->ann.paused != a->paused)
        s->last_frame_ns = mono_ns(); /* frames stop (paused) or start again from now */
    s->ann = *a;
    s->have_ann = true;
    s->dirty = true;
    /* another process under the server's id (a service restarted it): its
     * state starts afresh, so does the replica; the scene is checked below */
    if (s->rep && a->server_start_ns && s->server_start && a->server_start_ns != s->server_start) {
        slog(s, FTM_LOG_INFO,
             "server %u restarted (a new process, announcing tick %" PRIu64 "; we were at tick %"
             PRIu64 "): rejoining", s->server_id, a->tick, ftm_replay_tick(s->rep));
        force_off(s, "server restarted");
        bool same = ftm_replay_check_announce(s->rep, a, NULL) == FTM_OK;
        ftm_replay_destroy(s->rep);
        s->rep = NULL;
        s->server_left = s->server_gone = s->silent_reported = false;
        s->ever_synced = false; /* no probe input before it knows us (send_probe) */
        /* which process holds our id is the new server's to say */
        s->id_told = (ftm_id_told){0};
        s->id_held = s->held_late_told = false;
        s->held_since_ns = 0;
        s->last_frame_ns = mono_ns();
        s->newest_rx_tick = 0;
        ftm_report_free(&s->live); /* a new session: its ticks start again */
        s->live_tick = 0;
        ftm_parts_forget_departed(s->parts, &s->nparts); /* their figures went with it */
        if (!same && !s->cfg.scene && s->nretired < (int32_t)(sizeof s->retired / sizeof *s->retired)) {
            /* it serves another scene: load that one below, as on joining */
            slog(s, FTM_LOG_INFO, "the restarted server has another scene: '%s'", a->scene_id);
            s->retired[s->nretired++] = s->scene;
            s->scene = NULL;
            s->failed_scene[0] = '\0';
        } else {
            if (ftm_replay_create(s->scene, s->cfg.log, s->cfg.log_user, &s->rep, &err)) {
                slog(s, FTM_LOG_ERROR, "replay: %s", err.message);
                return;
            }
            publish_status(s, FTM_WIRE_STATE_JOINING);
        }
    }
    if (s->scene && !s->rep)
        return; /* rejected before (digest mismatch): the banner stays */
    if (!s->scene) {
        const char *name = s->cfg.scene ? s->cfg.scene : a->scene_id;
        if (strcmp(s->failed_scene, name) == 0)
            return;
        char path[1024];
        if (ftm_wire_open_scene(name, &s->scene, path, sizeof path, &err)) {
            snprintf(s->failed_scene, sizeof s->failed_scene, "%s", name);
            slog(s, FTM_LOG_ERROR, "cannot load scene '%s': %s", name, err.message);
            pthread_mutex_lock(&s->lock);
            snprintf(s->shared.banner, sizeof s->shared.banner, "CANNOT LOAD SCENE '%.60s': %.180s",
                     name, err.message);
            s->shared.banner_error = true;
            s->shared.version++;
            pthread_mutex_unlock(&s->lock);
            force_off(s, "no scene");
            return;
        }
        if (ftm_replay_create(s->scene, s->cfg.log, s->cfg.log_user, &s->rep, &err)) {
            slog(s, FTM_LOG_ERROR, "replay: %s", err.message);
            return;
        }
        if (strcmp(path, name) != 0)
            slog(s, FTM_LOG_INFO, "scene '%s': %s", name, path);
        /* (the announcement's tick is when it was made, not where we sync:
         * "synced at tick" says that) */
        slog(s, FTM_LOG_INFO, "joined session: scene '%s', %u Hz%s; syncing from a keyframe",
             a->scene_id, a->tick_rate_hz, a->paused ? " (paused)" : "");
        const ftm_mesh *m = ftm_scene_mesh(s->scene);
        pthread_mutex_lock(&s->lock);
        s->shared.mesh = m;
        s->shared.volume = ftm_scene_volume(s->scene);
        s->shared.ffd = ftm_scene_ffd(s->scene);
        snprintf(s->shared.scene_name, sizeof s->shared.scene_name, "%s", name);
        pthread_mutex_unlock(&s->lock);
        publish_status(s, FTM_WIRE_STATE_JOINING); /* ask for a fresh keyframe */
    }
    if (ftm_replay_check_announce(s->rep, a, &err)) {
        slog(s, FTM_LOG_ERROR, "%s", err.message);
        pthread_mutex_lock(&s->lock);
        snprintf(s->shared.banner, sizeof s->shared.banner, "%s: %.230s",
                 err.code == FTM_EVERSION ? "VERSION MISMATCH" : "SCENE MISMATCH", err.message);
        s->shared.banner_error = true;
        s->shared.version++;
        pthread_mutex_unlock(&s->lock);
        drop_scene(s);
        force_off(s, "scene mismatch");
    }
    if (s->rep)
        s->server_start = a->server_start_ns;
}

/* Each new frame's reaction forces into the live report: the figures the
 * server's --report will give, seen from here (frames before joining are
 * not seen). */
static void count_reactions(ftm_client_session *s, const ftm_wire_tick *t)
{
    if (t->tick <= s->live_tick)
        return; /* a frame counted already */
    s->live_tick = t->tick;
    for (int32_t i = 0; i < t->reaction_count; i++) {
        const ftm_wire_reaction *re = &t->reactions[i];
        if (re->probe < 0 || re->probe >= FTM_REPORT_PROBES)
            continue;
        int32_t k = ftm_report_index(&s->live, re->participant);
        if (k < 0 && (k = ftm_report_seen(&s->live, re->participant, "trainee", "", t->tick)) < 0)
            continue;
        ftm_report_contact(&s->live.parts[k].probes[re->probe], t->tick, re->force, 0.0,
                           re->push_limited);
    }
}

/* Probe 0 of participant id in the live report (the figures the HUD shows),
 * or NULL before any frame or status from it. */
static const ftm_report_probe *live_probe0(const ftm_client_session *s, uint32_t id)
{
    int32_t k = ftm_report_index(&s->live, id);
    return k >= 0 ? &s->live.parts[k].probes[0] : NULL;
}

static void server_gone(ftm_client_session *s, bool lease, const char *why)
{
    if (s->server_left && !(s->server_gone && !lease))
        return; /* (a LEAVING status after a lease expiry still says it left) */
    s->server_left = true;
    s->server_gone = lease;
    slog(s, FTM_LOG_WARN, "server %u %s", s->server_id, why);
    force_off(s, "server gone");
}

/* A message from the server's own process (from_server). After a `gone`
 * event it is alive after all: a lease expires when either side stalls
 * (SIGSTOP, a loaded machine) or the link is cut for longer than the lease,
 * and the same process is heard again afterwards. Force and probe input
 * come back with the next frame once the replica is synced and the server
 * confirms our id again (after_frames, send_probe). */
static void server_heard(ftm_client_session *s)
{
    if (!s->server_left || !s->server_gone)
        return;
    slog(s, FTM_LOG_INFO, "server %u is back (its lease had expired): rejoining", s->server_id);
    s->server_left = s->server_gone = false;
    s->last_frame_ns = mono_ns();
    if (!s->id_held)
        s->held_since_ns = s->last_frame_ns; /* the wait for our id starts again */
    s->dirty = true;
}

static void on_status(ftm_client_session *s, const ftm_wire_received *rx)
{
    s->dirty = true;
    if (rx->gone) {
        /* one that touched the tissue stays listed, for the debriefing */
        const ftm_report_probe *q = live_probe0(s, rx->sender);
        ftm_parts_gone(s->parts, &s->nparts, rx->sender, q && q->contact_ticks > 0);
        /* (origin 0: no longer known; gone only turns the force off) */
        if (s->server_id != 0 && rx->sender == s->server_id &&
            (!rx->origin || rx->origin == s->server_origin))
            server_gone(s, true, "gone (lease expired or left)");
        return;
    }
    const ftm_wire_status *st = &rx->msg.u.status;
    if (rx->sender == s->cfg.id) /* another process with our id: the server says which it hears */
        return;
    if (st->role == FTM_WIRE_ROLE_SERVER && from_server(s, rx)) {
        const ftm_id_claim c = ftm_replay_id_verdict(&s->id_told, st, s->cfg.id,
                                                     ftm_wire_transport_origin(s->wire));
        if (c == FTM_ID_TAKEN) {
            slog(s, FTM_LOG_ERROR,
                 "participant id %u is taken: another process in session '%s' uses it and the "
                 "server listens to that one; restart with another --id",
                 s->cfg.id, s->cfg.session);
            force_off(s, "participant id taken");
        } else if (c == FTM_ID_NEWCOMER) {
            slog(s, FTM_LOG_WARN, "another process joined as participant %u: the server ignores it",
                 s->cfg.id);
        } else if (c == FTM_ID_OURS_AGAIN) {
            slog(s, FTM_LOG_INFO, "participant id %u is ours again: the process that held it left "
                 "and the server hears this one", s->cfg.id);
            /* the force comes back with the next frame once the server
             * also confirms we hold the id (after_frames) */
        }
        const bool held = ftm_replay_id_held(st, s->cfg.id, ftm_wire_transport_origin(s->wire));
        if (held && !s->id_held) {
            slog(s, FTM_LOG_INFO, "participant id %u is confirmed: the server hears this process "
                 "under it%s", s->cfg.id, s->held_late_told ? " (late)" : "");
        } else if (!held && s->id_held) {
            slog(s, FTM_LOG_WARN, "the server no longer confirms participant id %u as this "
                 "process's: no probe input or force until it does", s->cfg.id);
            force_off(s, "participant id not confirmed");
            s->held_since_ns = mono_ns();
            s->held_late_told = false;
        }
        s->id_held = held;
        if (st->state != FTM_WIRE_STATE_LEAVING)
            server_heard(s);
        if (st->state == FTM_WIRE_STATE_LEAVING) {
            server_gone(s, false, "leaving");
        } else if (s->have_ann && s->ann.paused) {
            /* a paused server sends no frames: its statuses (every 0.5 s)
             * are what says it is alive */
            s->last_frame_ns = mono_ns();
            if (s->silent_reported) {
                slog(s, FTM_LOG_INFO, "the server is back (the session is paused)");
                s->silent_reported = false;
            }
        }
    }
    ftm_client_part *p = ftm_parts_find(s->parts, &s->nparts, rx->sender, true);
    if (!p)
        s->unlisted_ns = mono_ns();
    if (p) {
        p->left = false;
        p->role = st->role;
        p->state = st->state;
        p->tick = st->last_applied_tick;
        snprintf(p->name, sizeof p->name, "%s", st->name);
    }
    ftm_report_seen(&s->live, rx->sender, ftm_wire_role_name(st->role), st->name,
                    st->last_applied_tick);
}

static void on_probe_input(ftm_client_session *s, const ftm_wire_received *rx)
{
    const ftm_wire_probe_input *in = &rx->msg.u.probe_input;
    if (in->sample_count <= 0)
        return;
    const ftm_wire_probe_sample *smp = &in->samples[in->sample_count - 1]; /* newest */
    int32_t k = 0;
    while (k < s->nhips &&
           !(s->hips[k].participant == rx->sender && s->hips[k].probe == smp->probe))
        k++;
    if (k == s->nhips) {
        if (s->nhips == FTM_CLIENT_MAX_PROBES)
            return;
        s->nhips++;
    }
    s->hips[k] = (remote_hip){rx->sender, smp->probe, smp->position, mono_ns()};
    s->dirty = true;
}

/* The server has confirmed that it hears this process under our id, and
 * has not said since that another process holds it. */
static bool id_ours(const ftm_client_session *s) { return s->id_held && !s->id_told.taken; }

static void after_frames(ftm_client_session *s)
{
    const ftm_wire_tick *t = ftm_replay_last_frame(s->rep);
    const ftm_wire_reaction *mine = NULL;
    for (int32_t i = 0; i < t->reaction_count; i++)
        if (t->reactions[i].participant == s->cfg.id && t->reactions[i].probe == 0)
            mine = &t->reactions[i];
    uint64_t tick = ftm_replay_tick(s->rep);
    bool synced = ftm_replay_state(s->rep) == FTM_WIRE_STATE_SYNCED;
    if (synced && !s->synced)
        slog(s, FTM_LOG_INFO, "synced at tick %" PRIu64, tick);
    s->synced = synced;
    s->ever_synced = s->ever_synced || synced;
    /* with our id taken, or not yet confirmed ours, the reaction under it
     * may be another process's: evaluated at our HIP it is no force of ours
     * (up to the clamp) */
    if (ftm_replay_state(s->rep) == FTM_WIRE_STATE_SYNCED && !s->server_left && id_ours(s)) {
        if (!s->force_valid && s->cfg.role == FTM_WIRE_ROLE_TRAINEE)
            slog(s, FTM_LOG_INFO, "force on at tick %" PRIu64, tick);
        s->force_valid = true;
        double rate = s->ann.tick_rate_hz ? (double)s->ann.tick_rate_hz : 1.0; /* (> 0 when valid) */
        if (s->cfg.on_force)
            s->cfg.on_force(s->cfg.force_user, t->tick, (double)t->tick / rate,
                            t->tick == tick ? mine : NULL, true, NULL);
    }
    if (tick != s->counted_tick) {
        if (t->contact_count > 0 && t->tick == tick)
            s->contact_ticks += tick - s->counted_tick;
        else
            s->contact_ticks = 0;
        s->counted_tick = tick;
    }
    s->dirty = true;
}

static void on_tick(ftm_client_session *s, const ftm_wire_received *rx)
{
    server_heard(s);
    s->last_frame_ns = mono_ns();
    if (s->silent_reported) {
        slog(s, FTM_LOG_INFO, "tick frames again from the server");
        s->silent_reported = false;
    }
    const ftm_wire_tick *t = &rx->msg.u.tick;
    if (t->tick > s->newest_rx_tick)
        s->newest_rx_tick = t->tick;
    if (s->rep)
        count_reactions(s, t);
    s->last_latency_ns = real_ns() - rx->source_time_ns;
    if (!s->rep)
        return;
    uint64_t before = ftm_replay_tick(s->rep);
    if (ftm_replay_on_tick(s->rep, rx))
        slog(s, FTM_LOG_ERROR, "replay: out of memory");
    if (ftm_replay_tick(s->rep) != before)
        after_frames(s);
}

static void on_keyframe(ftm_client_session *s, const ftm_wire_keyframe *k)
{
    if (!s->rep)
        return;
    uint64_t before = ftm_replay_tick(s->rep);
    if (ftm_replay_on_keyframe(s->rep, k))
        slog(s, FTM_LOG_ERROR, "replay: out of memory");
    if (ftm_replay_tick(s->rep) != before)
        after_frames(s);
    s->dirty = true;
}

#define HIP_BATCH 64

static void send_probe(ftm_client_session *s)
{
    ftm_wire_probe_sample smp[HIP_BATCH];
    int n = s->cfg.take_hips(s->cfg.hip_user, smp, HIP_BATCH);
    /* (taken all the same, so that none goes out stale later) Not before
     * the first sync: the server may not have our first status yet (sent
     * as the session thread starts) and would reject the input of an
     * unknown participant; there is no force before it anyway. Only with
     * our id confirmed ours: the server might take our HIP for another
     * process's. Nor while the server is gone: a restarted one would not
     * know us yet. */
    if (n <= 0 || !s->ever_synced || !id_ours(s) || s->server_left)
        return;
    ftm_wire_msg m;
    memset(&m, 0, sizeof m);
    m.kind = FTM_WIRE_PROBE_INPUT;
    m.u.probe_input.participant = s->cfg.id;
    m.u.probe_input.last_tick_seen = s->rep ? ftm_replay_tick(s->rep) : 0;
    m.u.probe_input.sample_count = n;
    m.u.probe_input.samples = smp;
    ftm_error err = {0, ""};
    if (ftm_wire_publish(s->wire, &m, &err))
        slog(s, FTM_LOG_WARN, "probe input: %s", err.message);
}

/* ---- watchdog: silent server, malformed frames ----------------------------------------- */

/* Under s->lock: a command's outcome for the view and the log. */
static void outcome_locked(ftm_client_session *s, const char *text, bool bad)
{
    ftm_client_view *v = &s->shared;
    snprintf(v->outcome, sizeof v->outcome, "%s", text);
    v->outcome_bad = bad;
    v->outcome_seq++;
    v->version++;
}

static void on_reply(ftm_client_session *s, const ftm_wire_control_reply *r)
{
    if (r->issuer != s->cfg.id || s->id_told.taken)
        return; /* another instructor's (or the process holding our id) */
    char text[FTM_OUTCOME_TEXT];
    pthread_mutex_lock(&s->lock);
    bool known = ftm_pending_reply(&s->pending, r, text, sizeof text);
    bool bad = r->outcome == FTM_WIRE_OUTCOME_REFUSED;
    outcome_locked(s, text, bad);
    pthread_mutex_unlock(&s->lock);
    slog(s, bad ? FTM_LOG_WARN : FTM_LOG_INFO, "command %s%s", text,
         known ? "" : " (no such command waiting)");
}

static void expire_commands(ftm_client_session *s, int64_t now)
{
    char text[FTM_OUTCOME_TEXT];
    for (;;) {
        pthread_mutex_lock(&s->lock);
        bool late = ftm_pending_expired(&s->pending, now, FTM_REPLY_TIMEOUT_NS, text, sizeof text);
        if (late)
            outcome_locked(s, text, true);
        pthread_mutex_unlock(&s->lock);
        if (!late)
            return;
        slog(s, FTM_LOG_WARN, "command %s", text);
    }
}

static void watchdog(ftm_client_session *s, int64_t now)
{
    ftm_wire_stats ws;
    if (ftm_wire_get_stats(s->wire, FTM_WIRE_TICK, &ws, NULL) == FTM_OK &&
        ws.rejected > s->rejected_seen) {
        slog(s, FTM_LOG_ERROR, "malformed tick frame rejected (%" PRIu64 " so far): %s",
             ws.rejected, ws.last_reject);
        snprintf(s->reject_msg, sizeof s->reject_msg, "MALFORMED TICK FRAME REJECTED: %.160s",
                 ws.last_reject);
        s->rejected_seen = ws.rejected;
        s->reject_until_ns = now + REJECT_BANNER_NS;
        force_off(s, "malformed frame");
        s->dirty = true;
    }
    double silent_s = (double)(now - s->last_frame_ns) * 1e-9;
    if (s->have_ann && !s->server_left && silent_s > s->cfg.server_timeout && !s->silent_reported) {
        s->silent_reported = true;
        if (s->ann.paused)
            slog(s, FTM_LOG_WARN, "no status from the paused server for %.1f s", silent_s);
        else
            slog(s, FTM_LOG_WARN, "no tick frames from the server for %.1f s", silent_s);
        force_off(s, "server silent");
        s->dirty = true;
    }
    if (s->rep && ftm_replay_state(s->rep) != FTM_WIRE_STATE_SYNCED && s->force_valid)
        force_off(s, "replica not synced");
    /* the wait for the server to confirm our id starts with its first
     * announcement (or its restart, or the confirmation's loss) */
    if (s->have_ann && !s->held_since_ns)
        s->held_since_ns = now;
    const bool trainee = s->cfg.role == FTM_WIRE_ROLE_TRAINEE;
    const bool id_late = trainee && !s->id_held && !s->id_told.taken && s->held_since_ns &&
                         now - s->held_since_ns > FTM_ID_CONFIRM_WAIT_NS;
    if (id_late && !s->held_late_told) {
        s->held_late_told = true;
        slog(s, FTM_LOG_ERROR,
             "the server %u has not confirmed participant id %u as this process's for %.0f s (a "
             "server older than this client never does): no probe input, no force",
             s->server_id, s->cfg.id, (double)FTM_ID_CONFIRM_WAIT_NS * 1e-9);
    }

    /* the banner: the most serious condition wins */
    char banner[256] = "";
    bool error = true;
    if (s->have_ann && !s->scene && s->failed_scene[0])
        return; /* the scene banner set in on_announce stays */
    if (s->scene && !s->rep)
        return; /* scene mismatch banner stays */
    if (s->id_told.taken)
        snprintf(banner, sizeof banner,
                 "PARTICIPANT ID %u TAKEN BY ANOTHER PROCESS: THE SERVER IGNORES THIS ONE; "
                 "RESTART WITH ANOTHER --id", s->cfg.id);
    else if (s->server_left)
        snprintf(banner, sizeof banner, "SERVER LEFT THE SESSION: FORCE OFF");
    else if (s->silent_reported)
        snprintf(banner, sizeof banner, "SERVER SILENT FOR %.0f S: FORCE OFF", silent_s);
    else if (now < s->reject_until_ns)
        snprintf(banner, sizeof banner, "%s", s->reject_msg);
    else if (!s->have_ann) {
        snprintf(banner, sizeof banner, "WAITING FOR SESSION '%s'...", s->cfg.session);
        error = false;
    } else if (s->rep && ftm_replay_state(s->rep) != FTM_WIRE_STATE_SYNCED) {
        snprintf(banner, sizeof banner, "%s...",
                 ftm_replay_state(s->rep) == FTM_WIRE_STATE_JOINING ? "JOINING" : "RESYNCING");
        error = false;
    } else if (id_late) {
        snprintf(banner, sizeof banner,
                 "THE SERVER HAS NOT CONFIRMED PARTICIPANT ID %u FOR THIS PROCESS (AN OLDER SERVER "
                 "NEVER DOES): NO FORCE", s->cfg.id);
    } else if (trainee && !s->id_held) {
        snprintf(banner, sizeof banner,
                 "WAITING FOR THE SERVER TO CONFIRM PARTICIPANT ID %u: NO FORCE YET", s->cfg.id);
        error = false;
    } else if (s->ann.paused) {
        /* no frames, so no force samples: the haptic loop fades to zero */
        snprintf(banner, sizeof banner, "SESSION PAUSED%s",
                 s->cfg.role == FTM_WIRE_ROLE_TRAINEE ? ": NO FORCE UNTIL IT RESUMES" : "");
        error = false;
    }
    pthread_mutex_lock(&s->lock);
    bool away = s->server_left || s->silent_reported;
    if (away != s->shared.server_away) {
        s->shared.server_away = away;
        s->shared.version++;
    }
    if (strcmp(banner, s->shared.banner) != 0 || error != s->shared.banner_error) {
        snprintf(s->shared.banner, sizeof s->shared.banner, "%s", banner);
        s->shared.banner_error = error;
        s->shared.version++;
    }
    pthread_mutex_unlock(&s->lock);
}

/* ---- the view -------------------------------------------------------------------------- */

static int grow(void **p, int32_t *cap, int32_t need, size_t elem)
{
    if (need <= *cap)
        return 0;
    int32_t c = need + need / 2 + 16;
    void *q = realloc(*p, (size_t)c * elem);
    if (!q)
        return -1;
    *p = q;
    *cap = c;
    return 0;
}

static ftm_vec3 contact_centroid(const double *x, const ftm_wire_tick *t, int32_t group, bool *any)
{
    ftm_vec3 c = {0, 0, 0};
    int32_t n = 0;
    for (int32_t i = 0; i < t->contact_count; i++)
        if (t->contacts[i].group == group) {
            const double *p = x + 3 * t->contacts[i].node;
            c.x += p[0];
            c.y += p[1];
            c.z += p[2];
            n++;
        }
    *any = n > 0;
    if (n) {
        c.x /= n;
        c.y /= n;
        c.z /= n;
    }
    return c;
}

static void publish_view(ftm_client_session *s, int64_t now, bool caught_up)
{
    ftm_client_view *v = &s->shared;
    const double *x = NULL;
    int32_t n = 0;
    const int32_t *order = NULL, *start = NULL;
    int32_t layers = 0;
    if (s->rep) {
        ftm_sim *sim = ftm_replay_sim(s->rep);
        x = ftm_sim_positions(sim);
        n = ftm_mesh_node_count(ftm_sim_mesh(sim));
        if (atomic_load(&s->want_region))
            layers = ftm_sim_layers(sim, &order, &start);
    }
    pthread_mutex_lock(&s->lock);
    v->version++;
    if (n && grow((void **)&v->pos, &v->pos_cap, 3 * n, sizeof *v->pos) == 0) {
        memcpy(v->pos, x, (size_t)n * 3 * sizeof *x);
        v->node_count = n;
    }
    v->region_count = 0;
    if (layers > 0 && grow((void **)&v->region, &v->region_cap, start[layers], sizeof(int32_t)) == 0) {
        memcpy(v->region, order, (size_t)start[layers] * sizeof(int32_t));
        v->region_count = start[layers];
    }
    v->announced = s->have_ann;
    if (s->have_ann) {
        v->paused = s->ann.paused;
        v->depth_min = s->ann.depth_min;
        v->depth_max = s->ann.depth_max;
        v->rate_hz = s->ann.tick_rate_hz;
        v->tissue = s->ann.tissue;
    }
    v->state = s->rep ? ftm_replay_state(s->rep) : FTM_WIRE_STATE_JOINING;
    if (v->state == FTM_WIRE_STATE_SYNCED)
        v->synced_once = true;
    v->caught_up = caught_up;
    v->contact_ticks = s->contact_ticks;
    v->force_valid = s->force_valid;
    v->nprobes = 0;
    v->own_force = (ftm_vec3){0, 0, 0};
    if (s->rep) {
        const ftm_wire_tick *t = ftm_replay_last_frame(s->rep);
        v->tick = ftm_replay_tick(s->rep);
        v->depth = t->depth;
        int64_t lat = s->last_latency_ns > 0 ? s->last_latency_ns : 0;
        v->latency_ms = (double)lat * 1e-6;
        int64_t behind = s->newest_rx_tick > v->tick ? (int64_t)(s->newest_rx_tick - v->tick) : 0;
        v->lag_ticks = behind + (int64_t)((double)lat * 1e-9 * v->rate_hz + 0.5);
        ftm_replay_stats rs;
        ftm_replay_get_stats(s->rep, &rs);
        v->frames = rs.frames_received;
        v->mismatches = rs.mismatches;
        v->resyncs = rs.resyncs;
        /* probes in contact: from the reactions of the last frame */
        for (int32_t i = 0; i < t->reaction_count && v->nprobes < FTM_CLIENT_MAX_PROBES; i++) {
            const ftm_wire_reaction *r = &t->reactions[i];
            ftm_client_probe *p = &v->probes[v->nprobes++];
            memset(p, 0, sizeof *p);
            p->participant = r->participant;
            p->probe = r->probe;
            p->own = r->participant == s->cfg.id && id_ours(s); /* else another's */
            p->force = r->force;
            p->push_limited = r->push_limited;
            p->contact = contact_centroid(x, t, r->group, &p->in_contact);
            if (p->own && r->probe == 0 && s->force_valid)
                v->own_force = r->force;
        }
    }
    v->rejected = s->rejected_seen;
    /* the others' HIPs, from their probe input */
    for (int32_t k = 0; k < s->nhips; k++) {
        const remote_hip *rh = &s->hips[k];
        if (now - rh->seen_ns > HIP_STALE_NS)
            continue;
        int32_t j = 0;
        while (j < v->nprobes &&
               !(v->probes[j].participant == rh->participant && v->probes[j].probe == rh->probe))
            j++;
        if (j == v->nprobes) {
            if (v->nprobes == FTM_CLIENT_MAX_PROBES)
                continue;
            memset(&v->probes[v->nprobes++], 0, sizeof v->probes[0]);
            v->probes[j].participant = rh->participant;
            v->probes[j].probe = rh->probe;
        }
        v->probes[j].have_hip = true;
        v->probes[j].hip = rh->hip;
    }
    v->nparts = s->nparts;
    memcpy(v->parts, s->parts, (size_t)s->nparts * sizeof s->parts[0]);
    /* heard within the status deadline (statuses come every 0.5 s) */
    v->parts_unlisted = s->unlisted_ns && now - s->unlisted_ns < 2 * SEC;
    const ftm_report_probe *own = id_ours(s) ? live_probe0(s, s->cfg.id) : NULL;
    v->own_contact_ticks = own ? own->contact_ticks : 0;
    v->own_peak_force = own ? own->peak_force : 0.0;
    for (int32_t i = 0; i < v->nparts; i++) {
        const ftm_report_probe *q = live_probe0(s, v->parts[i].id);
        if (q) {
            v->parts[i].contact_ticks = q->contact_ticks;
            v->parts[i].peak_force = q->peak_force;
            v->parts[i].peak_tick = q->peak_tick;
        }
    }
    pthread_mutex_unlock(&s->lock);
    s->last_publish_ns = now;
    s->dirty = false;
}

/* ---- the thread -------------------------------------------------------------------------- */

static bool hold_reached(const ftm_client_session *s)
{
    return s->cfg.hold && s->rep && ftm_replay_state(s->rep) == FTM_WIRE_STATE_SYNCED &&
           ftm_replay_tick(s->rep) >= s->cfg.hold_tick;
}

static void *session_main(void *arg)
{
    ftm_client_session *s = arg;
    int64_t t0 = mono_ns();
    s->last_frame_ns = t0;
    publish_status(s, FTM_WIRE_STATE_JOINING);
    while (!atomic_load(&s->stop)) {
        ftm_wire_received rx;
        if (ftm_wire_receive(s->wire, FTM_WIRE_ANNOUNCE, &rx, 0, NULL) == FTM_OK) {
            if (from_server(s, &rx))
                on_announce(s, &rx.msg.u.announce);
            ftm_wire_received_free(&rx);
        }
        for (int i = 0; i < 64 && ftm_wire_receive(s->wire, FTM_WIRE_STATUS, &rx, 0, NULL) == FTM_OK;
             i++) {
            on_status(s, &rx);
            ftm_wire_received_free(&rx);
        }
        for (int i = 0;
             i < 256 && ftm_wire_receive(s->wire, FTM_WIRE_PROBE_INPUT, &rx, 0, NULL) == FTM_OK;
             i++) {
            on_probe_input(s, &rx);
            ftm_wire_received_free(&rx);
        }
        if (s->cfg.role == FTM_WIRE_ROLE_INSTRUCTOR) {
            for (int i = 0;
                 i < 64 && ftm_wire_receive(s->wire, FTM_WIRE_CONTROL_REPLY, &rx, 0, NULL) == FTM_OK;
                 i++) {
                if (from_server(s, &rx))
                    on_reply(s, &rx.msg.u.control_reply);
                ftm_wire_received_free(&rx);
            }
            expire_commands(s, mono_ns());
        }
        if (!hold_reached(s) &&
            ftm_wire_receive(s->wire, FTM_WIRE_KEYFRAME, &rx, 0, NULL) == FTM_OK) {
            if (from_server(s, &rx))
                on_keyframe(s, &rx.msg.u.keyframe);
            ftm_wire_received_free(&rx);
        }
        bool caught_up = false;
        if (hold_reached(s)) {
            struct timespec ts = {0, 1000000};
            nanosleep(&ts, NULL);
            caught_up = true;
        } else {
            const int64_t until = mono_ns() + DRAIN_NS;
            bool more = false; /* frames left for the next turn */
            for (int n = 0; !hold_reached(s); n++) {
                if (n > 0 && mono_ns() >= until) {
                    more = true;
                    break;
                }
                if (ftm_wire_receive(s->wire, FTM_WIRE_TICK, &rx, n == 0 ? SEC / 1000 : 0, NULL) !=
                    FTM_OK)
                    break;
                if (from_server(s, &rx))
                    on_tick(s, &rx);
                ftm_wire_received_free(&rx);
            }
            caught_up = !more && s->rep && ftm_replay_state(s->rep) == FTM_WIRE_STATE_SYNCED &&
                        ftm_replay_tick(s->rep) >= s->newest_rx_tick;
        }
        int64_t now = mono_ns();
        if (s->cfg.take_hips && now - s->last_input_ns >= SEC / 1000) {
            send_probe(s);
            s->last_input_ns = now;
        }
        ftm_wire_state st = s->rep ? ftm_replay_state(s->rep) : FTM_WIRE_STATE_JOINING;
        /* a change is told at once, but for the first second a joiner's
         * status stays the JOINING it sent (as ftm-bot's): what another
         * process with our id hears first then says we came after it */
        if (s->synced && st != FTM_WIRE_STATE_SYNCED)
            s->synced = false; /* (a resync: "synced at tick" again when it ends) */
        if (now - t0 >= SEC && (st != s->last_state || now - s->last_status_ns >= SEC / 2)) {
            s->last_state = st;
            publish_status(s, st);
            s->dirty = true;
        }
        watchdog(s, now);
        if (s->dirty && (now - s->last_publish_ns >= PUBLISH_EVERY_NS || caught_up))
            publish_view(s, now, caught_up);
        else if (caught_up != s->shared.caught_up)
            publish_view(s, now, caught_up); /* (read without lock: only this thread writes it) */
    }
    force_off(s, "client stopping");
    for (int32_t i = 0; i < s->live.count; i++)
        for (int k = 0; k < FTM_REPORT_PROBES; k++) {
            const ftm_report_probe *q = &s->live.parts[i].probes[k];
            if (q->contact_ticks)
                slog(s, FTM_LOG_INFO,
                     "participant %u probe %d, from the frames received: %.2f s in contact, "
                     "peak %.17g N at tick %" PRIu64, s->live.parts[i].id, k,
                     (double)q->contact_ticks / (s->ann.tick_rate_hz ? s->ann.tick_rate_hz : 1),
                     q->peak_force, q->peak_tick);
        }
    publish_status(s, FTM_WIRE_STATE_LEAVING);
    ftm_wire_flush(s->wire, SEC, NULL);
    return NULL;
}

int ftm_client_session_start(const ftm_client_config *cfg, ftm_client_session **out,
                             ftm_error *err)
{
    ftm_client_session *s = calloc(1, sizeof *s);
    if (!s) {
        if (err) {
            err->code = FTM_ENOMEM;
            snprintf(err->message, sizeof err->message, "client session: out of memory");
        }
        return FTM_ENOMEM;
    }
    s->cfg = *cfg;
    if (!s->cfg.session)
        s->cfg.session = "ftm";
    if (!(s->cfg.server_timeout > 0))
        s->cfg.server_timeout = 3.0;
    s->last_state = FTM_WIRE_STATE_JOINING;
    atomic_init(&s->stop, false);
    atomic_init(&s->want_region, false);
    atomic_init(&s->command_id, 0);
    pthread_mutex_init(&s->lock, NULL);
    s->shared.state = FTM_WIRE_STATE_JOINING;

    ftm_wire_transport_def wd;
    memset(&wd, 0, sizeof wd);
    wd.config = s->cfg.dds_config;
    wd.security = s->cfg.dds_security;
    wd.role = s->cfg.role;
    wd.domain_id = s->cfg.domain;
    wd.session = s->cfg.session;
    wd.participant_id = s->cfg.id;
    wd.publish = FTM_WIRE_KIND_BIT(FTM_WIRE_STATUS);
    if (s->cfg.role == FTM_WIRE_ROLE_TRAINEE)
        wd.publish |= FTM_WIRE_KIND_BIT(FTM_WIRE_PROBE_INPUT);
    /* probe input of the others, to draw their HIPs */
    wd.subscribe = FTM_WIRE_KIND_BIT(FTM_WIRE_ANNOUNCE) | FTM_WIRE_KIND_BIT(FTM_WIRE_TICK) |
                   FTM_WIRE_KIND_BIT(FTM_WIRE_KEYFRAME) | FTM_WIRE_KIND_BIT(FTM_WIRE_STATUS) |
                   FTM_WIRE_KIND_BIT(FTM_WIRE_PROBE_INPUT);
    if (s->cfg.role == FTM_WIRE_ROLE_INSTRUCTOR) {
        wd.publish |= FTM_WIRE_KIND_BIT(FTM_WIRE_CONTROL);
        wd.subscribe |= FTM_WIRE_KIND_BIT(FTM_WIRE_CONTROL_REPLY);
    }
    wd.log = s->cfg.log;
    wd.log_user = s->cfg.log_user;
    int rc = ftm_wire_transport_create(&wd, &s->wire, err);
    if (rc) {
        pthread_mutex_destroy(&s->lock);
        free(s);
        return rc;
    }
    if (pthread_create(&s->thread, NULL, session_main, s) != 0) {
        ftm_wire_transport_destroy(s->wire);
        pthread_mutex_destroy(&s->lock);
        free(s);
        if (err) {
            err->code = FTM_ENOMEM;
            snprintf(err->message, sizeof err->message, "client session: cannot start thread");
        }
        return FTM_ENOMEM;
    }
    *out = s;
    return FTM_OK;
}

void ftm_client_session_stop(ftm_client_session *s)
{
    if (!s)
        return;
    atomic_store(&s->stop, true);
    pthread_join(s->thread, NULL);
    ftm_wire_transport_destroy(s->wire);
    ftm_replay_destroy(s->rep);
    ftm_report_free(&s->live);
    for (int32_t k = 0; k < s->nretired; k++)
        ftm_scene_destroy(s->retired[k]);
    ftm_scene_destroy(s->scene);
    ftm_client_view_free(&s->shared);
    pthread_mutex_destroy(&s->lock);
    free(s);
}

bool ftm_client_session_snapshot(ftm_client_session *s, ftm_client_view *dst)
{
    pthread_mutex_lock(&s->lock);
    const ftm_client_view *v = &s->shared;
    bool changed = dst->version != v->version;
    if (changed) {
        double *pos = dst->pos;
        int32_t pos_cap = dst->pos_cap;
        int32_t *region = dst->region;
        int32_t region_cap = dst->region_cap;
        bool ok = grow((void **)&pos, &pos_cap, 3 * v->node_count, sizeof *pos) == 0 &&
                  grow((void **)&region, &region_cap, v->region_count, sizeof *region) == 0;
        *dst = *v;
        dst->pos = pos;
        dst->pos_cap = pos_cap;
        dst->region = region;
        dst->region_cap = region_cap;
        if (ok) {
            if (v->node_count)
                memcpy(pos, v->pos, (size_t)v->node_count * 3 * sizeof *pos);
            if (v->region_count)
                memcpy(region, v->region, (size_t)v->region_count * sizeof *region);
        } else {
            dst->node_count = 0;
            dst->region_count = 0;
        }
    }
    pthread_mutex_unlock(&s->lock);
    return changed;
}

void ftm_client_view_free(ftm_client_view *v)
{
    free(v->pos);
    free(v->region);
    v->pos = NULL;
    v->region = NULL;
    v->pos_cap = v->region_cap = 0;
}

void ftm_client_session_want_region(ftm_client_session *s, bool on)
{
    atomic_store(&s->want_region, on);
}

int ftm_client_session_control(ftm_client_session *s, ftm_wire_control *c, const char *what,
                               ftm_error *err)
{
    c->issuer = s->cfg.id;
    c->command_id = (uint64_t)atomic_fetch_add(&s->command_id, 1) + 1;
    ftm_wire_msg m;
    memset(&m, 0, sizeof m);
    m.kind = FTM_WIRE_CONTROL;
    m.u.control = *c;
    /* waiting before it is out: the reply may come before this returns */
    char text[FTM_OUTCOME_TEXT];
    pthread_mutex_lock(&s->lock);
    bool gave_up = ftm_pending_add(&s->pending, c->command_id, what ? what : "command", mono_ns(),
                                   text, sizeof text);
    if (gave_up)
        outcome_locked(s, text, true);
    pthread_mutex_unlock(&s->lock);
    if (gave_up)
        slog(s, FTM_LOG_WARN, "command %s", text);
    int rc = ftm_wire_publish(s->wire, &m, err);
    if (rc) { /* not sent: nothing to wait for */
        pthread_mutex_lock(&s->lock);
        ftm_pending_forget(&s->pending, c->command_id);
        pthread_mutex_unlock(&s->lock);
    }
    return rc;
}
