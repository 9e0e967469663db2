/* SPDX-License-Identifier: GPL-3.0-or-later */
/* The client's session thread; see client_session.h and docs/client.md.
 * The participant's side of the protocol is the participant core's
 * (participant.h), shared with ftm-bot; what is here is the client's own:
 * the view for the render thread, force for the haptic loop, the others'
 * HIPs and the live report, the banner and the watchdog. */
#include "client_session.h"
#include "parts.h"
#include "participant.h"
#include "report.h"

#include "ftm/clock.h"

#include <inttypes.h>
#include <pthread.h>
#include <stdarg.h>
#include <stdatomic.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#define SEC FTM_NS_PER_S
#define PUBLISH_EVERY_NS (4 * 1000000LL) /* view updates: 250 Hz is plenty for 60 Hz drawing */
#define HIP_STALE_NS (2 * SEC)            /* a remote HIP not updated for this long is dropped */
#define REJECT_BANNER_NS (5 * SEC)

typedef struct remote_hip {
    uint32_t participant;
    int32_t probe;
    ftm_vec3 hip;
    int64_t seen_ns;
} remote_hip;

struct ftm_client_session {
    ftm_client_config cfg;
    ftm_participant *part; /* joining, statuses, ids, the server, commands */
    pthread_t thread;
    atomic_bool stop;
    atomic_bool want_region;

    /* session thread only */
    int64_t last_input_ns, last_publish_ns;
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
    bool force_valid;
    uint64_t contact_ticks, counted_tick;
    bool dirty;
    ftm_wire_tissue range_of; /* the tissue shared.range is of */

    /* shared with the render thread: under lock */
    pthread_mutex_t lock;
    ftm_client_view shared;
};

static void slog(ftm_client_session *s, ftm_log_level level, const char *fmt, ...)
    __attribute__((format(printf, 3, 4)));
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

static uint64_t applied_tick(ftm_client_session *s)
{
    ftm_replay *rep = ftm_participant_replica(s->part);
    return rep ? ftm_replay_tick(rep) : 0;
}

/* Force to zero at once (hooks.force_off, and the watchdog's findings). */
static void force_off(void *user, const char *why)
{
    ftm_client_session *s = user;
    if (s->force_valid && s->cfg.role == FTM_WIRE_ROLE_TRAINEE)
        slog(s, FTM_LOG_WARN, "force off: %s", why);
    s->force_valid = false;
    if (s->cfg.on_force)
        s->cfg.on_force(s->cfg.force_user, applied_tick(s), 0.0, NULL, false, why);
}

/* Under s->lock: a banner that stays (the scene cannot be replayed). */
static void banner_locked(ftm_client_session *s, const char *text)
{
    snprintf(s->shared.banner, sizeof s->shared.banner, "%s", text);
    s->shared.banner_error = true;
    s->shared.version++;
}

/* ---- what the participant core tells (participant.h, hooks) --------------------------- */

static void on_scene_loaded(void *user, const ftm_scene *scene, const char *name)
{
    ftm_client_session *s = user;
    pthread_mutex_lock(&s->lock);
    s->shared.mesh = ftm_scene_mesh(scene);
    s->shared.volume = ftm_scene_volume(scene);
    s->shared.ffd = ftm_scene_ffd(scene);
    s->shared.tool = ftm_scene_get_tool(scene);
    s->shared.scene = scene;
    snprintf(s->shared.scene_name, sizeof s->shared.scene_name, "%s", name);
    pthread_mutex_unlock(&s->lock);
}

static void on_scene_refused(void *user, bool loading, const char *name, const ftm_error *err)
{
    ftm_client_session *s = user;
    char text[256];
    if (loading)
        snprintf(text, sizeof text, "CANNOT LOAD SCENE '%.60s': %.180s", name, err->message);
    else
        snprintf(text, sizeof text, "%s: %.230s",
                 err->code == FTM_EVERSION ? "VERSION MISMATCH" : "SCENE MISMATCH", err->message);
    pthread_mutex_lock(&s->lock);
    banner_locked(s, text);
    pthread_mutex_unlock(&s->lock);
}

/* A new server process: its ticks and its figures start again. */
static void on_restarted(void *user)
{
    ftm_client_session *s = user;
    s->silent_reported = false;
    s->newest_rx_tick = 0;
    ftm_report_free(&s->live);
    s->live_tick = 0;
    ftm_parts_forget_departed(s->parts, &s->nparts); /* their figures went with it */
}


/* Each new frame's reaction forces into the live report: the figures the
 * server's --report will give, seen from here (frames before joining are
 * not seen). */
static void count_reactions(ftm_client_session *s, const ftm_wire_tick *t)
{
    if (t->tick <= s->live_tick)
        return; /* a frame counted already */
    s->live_tick = t->tick;
    /* an unstable stretch: the frame does not say whether the server
     * substepped, but the replica steps as it does; its mode when the frame
     * arrives (a few ticks behind; substeps stay up for 1024 steps) */
    ftm_sim_mode mode;
    ftm_sim_get_mode(ftm_replay_sim(ftm_participant_replica(s->part)), &mode);
    const bool unstable = mode.substeps > 1;
    for (int32_t i = 0; i < t->reaction_count; i++) {
        const ftm_wire_reaction *re = &t->reactions[i];
        if (re->probe < 0 || re->probe >= FTM_REPORT_PROBES)
            continue;
        int32_t k = ftm_report_index(&s->live, re->participant);
        if (k < 0 && (k = ftm_report_seen(&s->live, re->participant, "trainee", "", t->tick)) < 0)
            continue;
        ftm_report_contact(&s->live.parts[k].probes[re->probe], t->tick, re->force, 0.0,
                           re->push_limited, unstable);
    }
}


/* Probe 0 of participant id in the live report (the figures the HUD shows),
 * or NULL before any frame or status from it. */
static const ftm_report_probe *live_probe0(const ftm_client_session *s, uint32_t id)
{
    int32_t k = ftm_report_index(&s->live, id);
    return k >= 0 ? &s->live.parts[k].probes[0] : NULL;
}


static void on_status(void *user, const ftm_wire_received *rx, bool from_server)
{
    ftm_client_session *s = user;
    s->dirty = true;
    if (rx->gone) {
        /* one that touched the tissue stays listed, for the debriefing */
        const ftm_report_probe *q = live_probe0(s, rx->sender);
        ftm_parts_gone(s->parts, &s->nparts, rx->sender, q && q->contact_ticks > 0);
        return;
    }
    const ftm_wire_status *st = &rx->msg.u.status;
    const ftm_participant_info *in = ftm_participant_get_info(s->part);
    /* a paused server sends no frames: its statuses say it is alive */
    if (from_server && st->state != FTM_WIRE_STATE_LEAVING && in->have_ann && in->ann.paused &&
        s->silent_reported) {
        slog(s, FTM_LOG_INFO, "the server is back (the session is paused)");
        s->silent_reported = false;
    }
    ftm_client_part *p = ftm_parts_find(s->parts, &s->nparts, rx->sender, true);
    if (!p)
        s->unlisted_ns = ftm_clock_mono_ns();
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


static void on_probe_input(void *user, const ftm_wire_received *rx)
{
    ftm_client_session *s = user;
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
    s->hips[k] = (remote_hip){rx->sender, smp->probe, smp->position, ftm_clock_mono_ns()};
    s->dirty = true;
}


/* After the replica moved: force for the haptic loop, the contact count. */
static void after_frames(ftm_client_session *s)
{
    ftm_replay *rep = ftm_participant_replica(s->part);
    const ftm_participant_info *in = ftm_participant_get_info(s->part);
    const ftm_wire_tick *t = ftm_replay_last_frame(rep);
    const ftm_wire_reaction *mine = NULL;
    for (int32_t i = 0; i < t->reaction_count; i++)
        if (t->reactions[i].participant == s->cfg.id && t->reactions[i].probe == 0)
            mine = &t->reactions[i];
    uint64_t tick = ftm_replay_tick(rep);
    /* with our id taken, or not yet confirmed ours, the reaction under it
     * may be another process's: evaluated at our HIP it is no force of ours
     * (up to the clamp) */
    if (ftm_replay_state(rep) == FTM_WIRE_STATE_SYNCED && !in->server_left &&
        ftm_participant_id_ours(s->part)) {
        if (!s->force_valid && s->cfg.role == FTM_WIRE_ROLE_TRAINEE)
            slog(s, FTM_LOG_INFO, "force on at tick %" PRIu64, tick);
        s->force_valid = true;
        double rate = in->ann.tick_rate_hz ? (double)in->ann.tick_rate_hz : 1.0; /* (> 0 when valid) */
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

static void on_frame(void *user, const ftm_wire_received *rx, int64_t taken_ns, bool stepped,
                     bool new_frame)
{
    ftm_client_session *s = user;
    if (s->silent_reported) {
        slog(s, FTM_LOG_INFO, "tick frames again from the server");
        s->silent_reported = false;
    }
    const ftm_wire_tick *t = &rx->msg.u.tick;
    if (t->tick > s->newest_rx_tick)
        s->newest_rx_tick = t->tick;
    if (ftm_participant_replica(s->part))
        count_reactions(s, t);
    s->last_latency_ns = taken_ns - rx->source_time_ns;
    if (stepped)
        after_frames(s);
}

static void on_keyframe(void *user, bool stepped)
{
    ftm_client_session *s = user;
    if (stepped)
        after_frames(s);
    s->dirty = true;
}

static void send_probe(ftm_client_session *s)
{
    ftm_wire_probe_sample smp[64];
    /* taken all the same, so that none goes out stale later; the core sends
     * them only when the server knows us under an id it confirms ours */
    int n = s->cfg.take_hips(s->cfg.hip_user, smp, 64);
    ftm_participant_send_probe(s->part, smp, n);
}


/* Under s->lock: a command's outcome for the view and the log. */
static void outcome_locked(ftm_client_session *s, const char *text, bool bad)
{
    ftm_client_view *v = &s->shared;
    snprintf(v->outcome, sizeof v->outcome, "%s", text);
    v->outcome_bad = bad;
    v->outcome_seq++;
    v->version++;
}

static void on_outcome(void *user, const char *text, int outcome, bool known)
{
    ftm_client_session *s = user;
    pthread_mutex_lock(&s->lock);
    outcome_locked(s, text, outcome == 0 || outcome == FTM_WIRE_OUTCOME_REFUSED);
    pthread_mutex_unlock(&s->lock);
}


/* ---- watchdog: silent server, malformed frames; the banner ------------------------------ */

/* The banner: the most serious condition wins ("" when all is well). */
static bool banner_text(ftm_client_session *s, int64_t now, char *banner, size_t cap)
{
    const ftm_participant_info *in = ftm_participant_get_info(s->part);
    ftm_replay *rep = ftm_participant_replica(s->part);
    const bool trainee = s->cfg.role == FTM_WIRE_ROLE_TRAINEE;
    const double silent_s = (double)(now - in->last_frame_ns) * 1e-9;
    banner[0] = '\0';
    if (in->id_taken)
        snprintf(banner, cap,
                 "PARTICIPANT ID %u TAKEN BY ANOTHER PROCESS: THE SERVER IGNORES THIS ONE; "
                 "RESTART WITH ANOTHER --id", s->cfg.id);
    else if (in->server_left)
        snprintf(banner, cap, "SERVER LEFT THE SESSION: FORCE OFF");
    else if (s->silent_reported)
        snprintf(banner, cap, "SERVER SILENT FOR %.0f S: FORCE OFF", silent_s);
    else if (now < s->reject_until_ns)
        snprintf(banner, cap, "%s", s->reject_msg);
    else if (!in->have_ann) {
        if (in->sessions_scanned)
            snprintf(banner, cap, "NO SERVER ANNOUNCES SESSION '%s' ON DOMAIN %u. HEARD THERE: %s",
                     s->cfg.session, s->cfg.domain,
                     in->sessions_heard[0] ? in->sessions_heard : "NO SESSION");
        else
            snprintf(banner, cap, "WAITING FOR SESSION '%s'...", s->cfg.session);
        return false;
    } else if (rep && ftm_replay_state(rep) != FTM_WIRE_STATE_SYNCED) {
        snprintf(banner, cap, "%s...",
                 ftm_replay_state(rep) == FTM_WIRE_STATE_JOINING ? "JOINING" : "RESYNCING");
        return false;
    } else if (trainee && in->id_late) {
        snprintf(banner, cap,
                 "THE SERVER HAS NOT CONFIRMED PARTICIPANT ID %u FOR THIS PROCESS (AN OLDER SERVER "
                 "NEVER DOES): NO FORCE", s->cfg.id);
    } else if (trainee && !in->id_held) {
        snprintf(banner, cap,
                 "WAITING FOR THE SERVER TO CONFIRM PARTICIPANT ID %u: NO FORCE YET", s->cfg.id);
        return false;
    } else if (in->ann.paused) {
        /* no frames, so no force samples: the haptic loop fades to zero */
        snprintf(banner, cap, "SESSION PAUSED%s", trainee ? ": NO FORCE UNTIL IT RESUMES" : "");
        return false;
    } else if (in->scene_feel) {
        /* stays while the scene does: an instructor may have picked it on purpose */
        snprintf(banner, cap, "SCENE '%s': %s", ftm_scene_name(ftm_participant_scene(s->part)),
                 in->scene_feel_text);
        return false; /* a warning, not a fault: grey */
    }
    return true;
}

static void watchdog(ftm_client_session *s, int64_t now)
{
    const ftm_participant_info *in = ftm_participant_get_info(s->part);
    ftm_replay *rep = ftm_participant_replica(s->part);
    ftm_wire_stats ws;
    if (ftm_wire_get_stats(ftm_participant_wire(s->part), FTM_WIRE_TICK, &ws, NULL) == FTM_OK &&
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
    double silent_s = (double)(now - in->last_frame_ns) * 1e-9;
    if (in->have_ann && !in->server_left && silent_s > s->cfg.server_timeout &&
        !s->silent_reported) {
        s->silent_reported = true;
        if (in->ann.paused)
            slog(s, FTM_LOG_WARN, "no status from the paused server for %.1f s", silent_s);
        else
            slog(s, FTM_LOG_WARN, "no tick frames from the server for %.1f s", silent_s);
        force_off(s, "server silent");
        s->dirty = true;
    }
    if (rep && ftm_replay_state(rep) != FTM_WIRE_STATE_SYNCED && s->force_valid)
        force_off(s, "replica not synced");
    /* a scene that cannot be replayed: its banner (on_scene_refused) stays */
    if (!ftm_participant_scene(s->part) ? in->scene_failed : !rep)
        return;
    char banner[256];
    bool error = banner_text(s, now, banner, sizeof banner);
    pthread_mutex_lock(&s->lock);
    bool away = in->server_left || s->silent_reported;
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
    ftm_replay *rep = ftm_participant_replica(s->part);
    const ftm_participant_info *in = ftm_participant_get_info(s->part);
    const bool ours = ftm_participant_id_ours(s->part);
    if (rep) {
        ftm_sim *sim = ftm_replay_sim(rep);
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
    v->announced = in->have_ann;
    v->nsessions = 0;
    for (int32_t i = 0; !in->have_ann && i < in->nsessions && i < FTM_CLIENT_PICK; i++) {
        const ftm_session_seen *e = &in->sessions[i];
        char who[48] = "";
        int w = 0;
        for (int r = FTM_WIRE_ROLE_TRAINEE; r <= FTM_WIRE_ROLE_BOT && w >= 0 && w < 40; r++)
            if (e->count[r])
                w += snprintf(who + w, sizeof who - (size_t)w, ", %d %s%s", (int)e->count[r],
                              ftm_wire_role_name((ftm_wire_role)r), e->count[r] > 1 ? "s" : "");
        snprintf(v->sessions[v->nsessions], sizeof v->sessions[0], "%s", e->name);
        snprintf(v->sessions_about[v->nsessions], sizeof v->sessions_about[0], "scene %.40s%s%s",
                 e->scene, e->paused ? ", paused" : "", who);
        v->nsessions++;
    }
    if (in->have_ann) {
        v->paused = in->ann.paused;
        v->depth_min = in->ann.depth_min;
        v->depth_max = in->ann.depth_max;
        v->rate_hz = in->ann.tick_rate_hz;
        v->tissue = in->ann.tissue;
    }
    v->state = ftm_participant_state(s->part);
    if (v->state == FTM_WIRE_STATE_SYNCED)
        v->synced_once = true;
    v->caught_up = caught_up;
    v->contact_ticks = s->contact_ticks;
    v->force_valid = s->force_valid;
    v->nprobes = 0;
    v->own_force = (ftm_vec3){0, 0, 0};
    if (rep) {
        const ftm_wire_tick *t = ftm_replay_last_frame(rep);
        v->tick = ftm_replay_tick(rep);
        v->depth = t->depth;
        /* the range changes with the tissue only: computed once per change */
        ftm_wire_tissue in_force = ftm_replay_tissue(rep);
        if (!v->range_valid || !ftm_replay_tissue_equal(&in_force, &s->range_of)) {
            ftm_error rerr = {0, ""};
            v->range_valid = ftm_replay_range(rep, &v->range, &rerr) == FTM_OK;
            s->range_of = in_force;
        }
        v->scene_tissue = ftm_replay_own_tissue(rep);
        ftm_sim_mode mode;
        ftm_sim_get_mode(ftm_replay_sim(rep), &mode);
        v->substeps = mode.substeps;
        int64_t lat = s->last_latency_ns > 0 ? s->last_latency_ns : 0;
        v->latency_ms = (double)lat * 1e-6;
        int64_t behind = s->newest_rx_tick > v->tick ? (int64_t)(s->newest_rx_tick - v->tick) : 0;
        v->lag_ticks = behind + (int64_t)((double)lat * 1e-9 * v->rate_hz + 0.5);
        ftm_replay_stats rs;
        ftm_replay_get_stats(rep, &rs);
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
            p->own = r->participant == s->cfg.id && ours; /* else another's */
            p->force = r->force;
            p->push_limited = r->push_limited;
            p->contact = contact_centroid(x, t, r->group, &p->in_contact);
            p->has_plane = r->has_plane;
            p->plane_point = r->contact_point;
            p->plane_normal = r->contact_normal;
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
    const ftm_report_probe *own = ours ? live_probe0(s, s->cfg.id) : NULL;
    v->own_contact_ticks = own ? own->contact_ticks : 0;
    v->own_peak_force = own ? own->peak_force : 0.0;
    for (int32_t i = 0; i < v->nparts; i++) {
        const ftm_report_probe *q = live_probe0(s, v->parts[i].id);
        if (q) {
            v->parts[i].contact_ticks = q->contact_ticks;
            v->parts[i].peak_force = q->peak_force;
            v->parts[i].peak_tick = q->peak_tick;
            v->parts[i].peak_unstable = q->peak_unstable;
        }
    }
    pthread_mutex_unlock(&s->lock);
    s->last_publish_ns = now;
    s->dirty = false;
}


/* ---- the thread -------------------------------------------------------------------------- */

static void *session_main(void *arg)
{
    ftm_client_session *s = arg;
    ftm_participant_join(s->part);
    while (!atomic_load(&s->stop)) {
        const bool more = ftm_participant_turn(s->part, SEC / 1000);
        ftm_replay *rep = ftm_participant_replica(s->part);
        const bool caught_up = ftm_participant_held(s->part) ||
                               (!more && rep && ftm_replay_state(rep) == FTM_WIRE_STATE_SYNCED &&
                                ftm_replay_tick(rep) >= s->newest_rx_tick);
        int64_t now = ftm_clock_mono_ns();
        if (s->cfg.take_hips && now - s->last_input_ns >= SEC / 1000) {
            send_probe(s);
            s->last_input_ns = now;
        }
        if (ftm_participant_status_due(s->part, now))
            s->dirty = true;
        watchdog(s, now);
        if (s->dirty && (now - s->last_publish_ns >= PUBLISH_EVERY_NS || caught_up))
            publish_view(s, now, caught_up);
        else if (caught_up != s->shared.caught_up)
            publish_view(s, now, caught_up); /* (read without lock: only this thread writes it) */
    }
    force_off(s, "client stopping");
    const uint32_t rate = ftm_participant_get_info(s->part)->ann.tick_rate_hz;
    for (int32_t i = 0; i < s->live.count; i++)
        for (int k = 0; k < FTM_REPORT_PROBES; k++) {
            const ftm_report_probe *q = &s->live.parts[i].probes[k];
            if (q->contact_ticks)
                slog(s, FTM_LOG_INFO,
                     "participant %u probe %d, from the frames received: %.2f s in contact, "
                     "peak %.17g N at tick %" PRIu64 "%s", s->live.parts[i].id, k,
                     (double)q->contact_ticks / (rate ? rate : 1), q->peak_force, q->peak_tick,
                     q->peak_unstable ? " (while the tissue was unstable: a spike of the "
                                        "simulation)" : "");
        }
    ftm_participant_leave(s->part);
    return NULL;
}

int ftm_client_session_start(const ftm_client_config *cfg, ftm_client_session **out,
                             ftm_error *err)
{
    ftm_client_session *s = calloc(1, sizeof *s);
    if (!s)
        return ftm_error_set(err, FTM_ENOMEM, "client session: out of memory");
    s->cfg = *cfg;
    if (!s->cfg.session)
        s->cfg.session = "ftm";
    if (!(s->cfg.server_timeout > 0))
        s->cfg.server_timeout = 3.0;
    atomic_init(&s->stop, false);
    atomic_init(&s->want_region, false);
    pthread_mutex_init(&s->lock, NULL);
    s->shared.state = FTM_WIRE_STATE_JOINING;
    ftm_participant_def pd = {
        .role = s->cfg.role, .id = s->cfg.id, .domain = s->cfg.domain, .session = s->cfg.session,
        .name = s->cfg.name ? s->cfg.name : "ftm-client", .scene = s->cfg.scene,
        .dds_config = s->cfg.dds_config, .dds_security = s->cfg.dds_security,
        .watch_probes = true, /* the others' HIPs, to draw them */
        .feel_check = true,   /* a scene a hand cannot feel, on the banner */
        .hold = s->cfg.hold, .hold_tick = s->cfg.hold_tick,
        .log = s->cfg.log, .log_user = s->cfg.log_user,
        .hooks = {.force_off = force_off, .scene_loaded = on_scene_loaded,
                  .scene_refused = on_scene_refused, .restarted = on_restarted,
                  .frame = on_frame, .keyframe = on_keyframe, .status = on_status,
                  .probe_input = on_probe_input, .outcome = on_outcome},
        .hooks_user = s};
    int rc = ftm_participant_create(&pd, &s->part, err);
    if (rc) {
        pthread_mutex_destroy(&s->lock);
        free(s);
        return rc;
    }
    if (pthread_create(&s->thread, NULL, session_main, s) != 0) {
        ftm_participant_destroy(s->part);
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
    /* (the scenes go with the core: the render thread draws no more) */
    ftm_participant_destroy(s->part);
    ftm_report_free(&s->live);
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
    return ftm_participant_send_control(s->part, c, what, err);
}
