/* SPDX-License-Identifier: GPL-3.0-or-later */
/* Runs without DDS or the clock (docs/server.md): --offline plays trainees
 * from bot scripts on the tick clock, the reference of the session tests;
 * --inputs and --replay's second pass feed a recording's inputs through the
 * same handlers and tick logic as a live session. */
#include "rooms.h"
#include "script.h"

#include "ftm/options.h"

#include <inttypes.h>
#include <math.h>
#include <stdlib.h>
#include <string.h>

/* Where a recording's inputs are, while they are fed through the server. */
typedef struct feed {
    const char *path, *mode; /* the file, "--replay" or "--inputs" */
    ftm_wire_limits lim;
    uint64_t frames, inputs, end_tick, last_index;
    bool leaving; /* the recorded server's final status seen: it stopped cleanly */
    bool at_damage; /* --upto-damage: stopped before a damaged entry (said so) */
    char why[FTM_ERROR_MESSAGE_MAX + 64]; /* the first problem; "" while none */
} feed;

/* An input entry, handled at the tick it was handled (every tick before it
 * is run: the server runs every tick, idle or not). */
static void feed_input(server *s, feed *f, const ftm_record_entry *e)
{
    if (e->tick < s->tk.tick) {
        snprintf(f->why, sizeof f->why, "input handled at tick %" PRIu64 " after tick %" PRIu64,
                 e->tick, s->tk.tick);
        return;
    }
    while (s->tk.tick < e->tick)
        srv_run_tick(s);
    f->inputs++;
    /* --inputs --record: as the loop records them (server.c), before handling */
    srv_record_entry(s, true, e->kind, e->sender, e->payload, e->size, e->gone, e->lost);
    if (e->lost) {
        participant *p = srv_find_part(s, e->sender, false);
        if (p) {
            srv_lose_probes(s, p);
            p->silent = true;
        }
        return;
    }
    ftm_wire_received rx;
    memset(&rx, 0, sizeof rx);
    rx.sender = e->sender;
    rx.gone = e->gone;
    rx.msg.kind = (ftm_wire_kind)e->kind;
    ftm_error err = {0, ""};
    if (!e->gone && ftm_wire_decode(e->kind, e->payload, e->size, &f->lim, &rx.msg, &err)) {
        snprintf(f->why, sizeof f->why, "%s", err.message);
        return;
    }
    if (e->kind == FTM_WIRE_STATUS)
        srv_on_status(s, &rx);
    else if (e->kind == FTM_WIRE_CONTROL)
        srv_on_control(s, &rx);
    else if (e->kind == FTM_WIRE_PROBE_INPUT)
        srv_on_probe_input(s, &rx);
    ftm_wire_received_free(&rx);
}

/* A recorded tick frame: its depth is this run's for that tick; with
 * --replay this run's frame must have its contacts (bit-exact) and hash. */
static void feed_frame(server *s, feed *f, const ftm_wire_tick *t)
{
    if (t->tick <= s->tk.tick)
        return; /* the frame of a tick sent again before a reset */
    while (s->tk.tick + 1 < t->tick)
        srv_run_tick(s);
    s->tk.depth = t->depth;
    srv_run_tick(s);
    f->frames++;
    if (s->o.inputs)
        return; /* --inputs: the depth only, nothing compared */
    bool same = s->pub.pub_tick == t->tick && s->pub.pub_n == t->contact_count;
    for (int32_t i = 0; same && i < t->contact_count; i++) {
        const ftm_contact *a = &s->tk.contacts[i], *b = &t->contacts[i];
        same = a->node == b->node && a->group == b->group && a->kind == b->kind &&
               memcmp(&a->value, &b->value, sizeof a->value) == 0;
    }
    if (!same)
        snprintf(f->why, sizeof f->why,
                 "tick %" PRIu64 ": the inputs give %d contacts, the frame has %d%s", t->tick,
                 (int)s->pub.pub_n, (int)t->contact_count,
                 s->pub.pub_n == t->contact_count ? " (different nodes or values)" : "");
    else if (ftm_sim_hash(s->tk.sim) != t->state_hash)
        snprintf(f->why, sizeof f->why,
                 "tick %" PRIu64 ": state hash differs: recorded %016" PRIx64
                 ", re-run from the inputs %016" PRIx64,
                 t->tick, t->state_hash, ftm_sim_hash(s->tk.sim));
}

/* One entry of the recording; f->why says what stops the run. */
static void feed_entry(server *s, feed *f, const ftm_record_entry *e)
{
    f->last_index = e->index;
    if (e->tick > f->end_tick && e->tick - f->end_tick > FTM_WIRE_MAX_TICK_GAP) {
        /* every tick between is run: a forged tick would take hours */
        snprintf(f->why, sizeof f->why,
                 "tick %" PRIu64 " is %" PRIu64 " ticks after the entries before it; a "
                 "session records a frame at least every %u ticks",
                 e->tick, e->tick - f->end_tick, FTM_WIRE_MAX_TICK_GAP);
        return;
    }
    if (e->tick > f->end_tick)
        f->end_tick = e->tick;
    if (e->incoming) {
        feed_input(s, f, e);
        return;
    }
    const bool status = e->kind == FTM_WIRE_STATUS && !f->leaving;
    if (!status && !(e->kind == FTM_WIRE_TICK && s->depth_from_frames))
        return;
    ftm_wire_msg m;
    ftm_error err = {0, ""};
    if (ftm_wire_decode(e->kind, e->payload, e->size, &f->lim, &m, &err)) {
        snprintf(f->why, sizeof f->why, "%s", err.message);
        return;
    }
    if (status)
        f->leaving = m.u.status.state == FTM_WIRE_STATE_LEAVING;
    else
        feed_frame(s, f, &m.u.tick);
    ftm_wire_msg_free(&m);
}

/* --inputs: on to where the recorded session ended, and end as a session
 * does: the last tick's frame, LEAVING. */
static void end_inputs(server *s, const feed *f)
{
    while (s->tk.tick < f->end_tick)
        srv_run_tick(s);
    if (s->rec.w) {
        srv_publish_tick_frame(s);
        srv_publish_status(s, FTM_WIRE_STATE_LEAVING);
    }
    if (!f->leaving && !f->at_damage)
        fprintf(stderr,
                "ftm-server --inputs: %s: note: the recording ends at entry %" PRIu64
                " without the server's final status (killed, crashed, or its recording "
                "stopped on a write error?); run to tick %" PRIu64 ", where it was cut\n",
                f->path, f->last_index, f->end_tick);
    srv_log_limits(s);
    printf("inputs %s: %" PRIu64 " inputs through collision and the step; "
           "final tick %" PRIu64 " hash %016" PRIx64 "\n",
           f->path, f->inputs, s->tk.tick, ftm_sim_hash(s->tk.sim));
}

/* --replay, second pass: the recorded inputs (statuses, probe input, session
 * control, gone and lost events) go through the same handlers and tick
 * logic as online — collision, contacts, ftm_replay_step — each at the tick
 * it was handled; every recorded tick frame is then compared with what this
 * run produced: contacts (bit-exact) and state hash. Depths come from the
 * recorded frames (the controller's choices depend on the clock).
 * --inputs: the same without comparing, the frames giving only the depth
 * (unless --depth is given), recording the inputs and this run's frames if
 * --record is given. */
int srv_replay_inputs(server *s)
{
    feed f = {.path = s->o.replay ? s->o.replay : s->o.inputs,
              .mode = s->o.replay ? "--replay" : "--inputs",
              .lim = {0, 0, ftm_mesh_node_count(s->mesh)}};
    ftm_record_header h;
    ftm_record_reader *rd = NULL;
    ftm_error err = {0, ""};
    if (ftm_record_open(f.path, &h, &rd, &err)) {
        fprintf(stderr, "ftm-server %s: %s\n", f.mode, err.message);
        return 1;
    }
    if (srv_open_reactions(s)) {
        ftm_record_close_reader(rd);
        return 3;
    }
    s->pub.replaying = true;
    s->tk.period_ns = 1e9 / s->o.rate;
    int rc = 0;
    ftm_record_entry e;
    while (!f.why[0]) {
        int got = ftm_record_next(rd, &e, &err);
        if (got < 0 && ftm_record_damaged(rd) && s->o.upto_damage) {
            fprintf(stderr, "ftm-server %s: note: %s; %s up to entry %" PRIu64
                    " before it (--upto-damage)\n", f.mode, err.message,
                    s->o.replay ? "replaying" : "running", f.last_index);
            f.at_damage = true;
            break;
        }
        if (got < 0) {
            fprintf(stderr, "ftm-server %s: %s%s\n", f.mode, err.message,
                    ftm_record_damaged(rd) ? " (--upto-damage takes it up to there)" : "");
            rc = 1;
        }
        if (got <= 0)
            break;
        feed_entry(s, &f, &e);
    }
    if (f.why[0]) {
        fprintf(stderr, "ftm-server %s: %s: entry %" PRIu64 " (byte %" PRIu64 "): %s\n", f.mode,
                f.path, e.index, e.offset, f.why);
        rc = 1;
    } else if (rc == 0 && s->o.inputs) {
        end_inputs(s, &f);
    } else if (rc == 0) {
        printf("replay %s from the inputs: %" PRIu64 " inputs through collision and the step, "
               "%" PRIu64 " tick frames with equal contacts and hash\n",
               s->o.replay, f.inputs, f.frames);
    }
    ftm_record_close_reader(rd);
    if (srv_close_reactions(s) && rc == 0)
        rc = 3;
    return rc;
}

/* The --trainee arguments: each a participant slot (in the order given)
 * playing its script. Returns 0, or 2 after saying which is wrong (the
 * scripts read so far are freed). */
static int load_trainees(server *s, ftm_script *sc, double *t0, participant **who)
{
    const int n = s->o.trainees.count;
    for (int i = 0; i < n; i++) {
        const char *arg = s->o.trainees.arg[i];
        long long id = 0;
        const char *colon = strchr(arg, ':');
        char *end = NULL;
        bool ok = colon && ftm_option_int(arg, (size_t)(colon - arg), 1, UINT32_MAX, &id);
        double off = ok ? strtod(colon + 1, &end) : NAN;
        if (!ok || *end != ':' || !isfinite(off) || id == s->o.id ||
            srv_find_part(s, (uint32_t)id, false)) {
            fprintf(stderr, "ftm-server: --trainee '%s': expected ID:T0:FILE, ID in "
                            "1..4294967295, not the server's (--id) nor an earlier trainee's\n",
                    arg);
            for (int j = 0; j < i; j++)
                ftm_script_free(&sc[j]);
            return 2;
        }
        /* (a script that cannot be read says why itself) */
        int bad = ftm_script_load(end + 1, &sc[i]);
        if (!bad && sc[i].npts == 0) {
            fprintf(stderr, "ftm-server: --trainee '%s': %s has no HIP positions for a trainee "
                            "to play\n", arg, end + 1);
            bad = 1;
        }
        if (bad) {
            for (int j = 0; j <= i; j++)
                ftm_script_free(&sc[j]);
            return 2;
        }
        t0[i] = off;
        who[i] = srv_find_part(s, (uint32_t)id, true);
        who[i]->role = FTM_WIRE_ROLE_TRAINEE;
        who[i]->report = ftm_report_seen(&s->rec.report, (uint32_t)id, "trainee", "offline", 0);
        who[i]->state = FTM_WIRE_STATE_SYNCED;
        snprintf(who[i]->name, sizeof who[i]->name, "offline");
    }
    return 0;
}

/* --offline: the session's tick logic without DDS or the clock. Each
 * trainee's probe 0 is at its script's HIP for the tick; then srv_run_tick
 * does what it does online — collision, contacts, ftm_replay_step,
 * reactions, the frame (encoded and counted, not sent). The reference for
 * ftm-bot sessions (tests/net). */
int srv_run_offline(server *s)
{
    ftm_script sc[FTM_SERVER_TRAINEES_MAX];
    double t0[FTM_SERVER_TRAINEES_MAX];
    participant *who[FTM_SERVER_TRAINEES_MAX];
    const int n = s->o.trainees.count;
    int rc = load_trainees(s, sc, t0, who);
    if (rc)
        return rc;
    if (srv_open_reactions(s))
        rc = 3;
    s->tk.period_ns = 1e9 / s->o.rate;
    srv_log(s, "info", "offline: %" PRId64 " ticks at %.0f Hz, %d trainees, depth %d",
            s->o.offline_ticks, s->o.rate, n, (int)s->tk.depth);
    for (int64_t k = 0; k < s->o.offline_ticks && rc == 0; k++) {
        /* tick k + 1 runs at (k + 1) / rate after the start */
        double t = (double)(k + 1) / s->o.rate;
        for (int i = 0; i < n; i++) {
            who[i]->probes[0].hip = ftm_script_at(&sc[i], t0[i] + t);
            who[i]->probes[0].have = true;
        }
        s->tk.base_ns = s->tk.last_tick_ns = 0; /* no clock: no period statistics */
        srv_run_tick(s);
    }
    srv_log(s, "info",
            "offline: %" PRIu64 " ticks, %" PRIu64 " frames (%" PRIu64 " idle ticks not sent), "
            "%.1f bytes/tick; step mean %.1f us",
            s->tk.tick, s->pub.frames, s->pub.idle_ticks,
            s->tk.tick ? (double)s->pub.bytes_frames / (double)s->tk.tick : 0.0,
            s->tk.tick ? s->tk.step_ns_total / (double)s->tk.tick * 1e-3 : 0.0);
    srv_log_limits(s);
    if (rc == 0)
        printf("ftm-server: final tick %" PRIu64 " hash %016" PRIx64 "\n", s->tk.tick,
               ftm_sim_hash(s->tk.sim));
    if (srv_close_reactions(s))
        rc = 3;
    for (int i = 0; i < n; i++)
        ftm_script_free(&sc[i]);
    return rc;
}
