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
#include <stdarg.h>
#include <stdlib.h>
#include <string.h>
#include <unistd.h>

/* Where a recording's inputs are, while they are fed through the server. */
typedef struct feed {
    const char *path, *mode; /* the file, "--replay" or "--inputs" */
    ftm_wire_limits lim;
    uint64_t frames, inputs, end_tick, last_index;
    bool leaving; /* the recorded server's final status seen: it stopped cleanly */
    bool at_damage; /* --upto-damage: stopped before a damaged entry (said so) */
    char why[FTM_ERROR_MESSAGE_MAX + 4200]; /* the first problem; "" while none */
    uint32_t segment;    /* the file of the lesson being read */
    char seg_path[4096]; /* its name */
    bool gap;            /* stopped at a segment begun after a gap */
    uint64_t lesson_start_ns;
    uint64_t cut_at; /* --resume: the last file's unfinished chunk begins here; 0: none */
    /* --resume's fast path: up to the lesson's last keyframe (its file and
     * entry) the server's own state is taken on from the frames without the
     * physics (emulate), the tissue then restored from that keyframe */
    bool fast, emulate, have_key;
    uint32_t key_segment;
    uint64_t key_index, key_tick;
    uint64_t kf_tick;   /* the keyframe before, while emulating */
    bool moved;         /* a frame with contacts since the tissue was last reset */
    uint64_t resets;    /* s->tk.resets when moved was last cleared */
} feed;

/* The longest run of ticks the stability guard keeps more than one substep
 * for, once it raises them: sim.c's FTM_SUBSTEP_RETRY clean steps before it
 * halves them. Keyframes at most this far apart, each with one substep,
 * mean one substep on every tick between (what the report's unstable marks
 * need; the frames do not say). */
#define GUARD_EPISODE_MIN 1024u

/* The fast path cannot go on (feed_lesson then says so and gives status 4). */
static void give_up(feed *f, const char *fmt, ...) __attribute__((format(printf, 2, 3)));
static void give_up(feed *f, const char *fmt, ...)
{
    va_list ap;
    va_start(ap, fmt);
    vsnprintf(f->why, sizeof f->why, fmt, ap);
    va_end(ap);
}

/* Every tick up to `tick` that has no frame of its own (an idle tick, or
 * ticks before an input). */
static void run_to(server *s, feed *f, uint64_t tick)
{
    while (s->tk.tick < tick && !f->why[0]) {
        if (!f->emulate) {
            srv_run_tick(s);
            continue;
        }
        char why[512] = "";
        if (srv_emulate_tick(s, NULL, why, sizeof why))
            give_up(f, "%s", why);
    }
}

/* An input entry, handled at the tick it was handled (every tick before it
 * is run: the server runs every tick, idle or not). */
static void feed_input(server *s, feed *f, const ftm_record_entry *e)
{
    if (e->tick < s->tk.tick) {
        snprintf(f->why, sizeof f->why, "input handled at tick %" PRIu64 " after tick %" PRIu64,
                 e->tick, s->tk.tick);
        return;
    }
    run_to(s, f, e->tick);
    if (f->why[0])
        return;
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
    if (s->tk.resets != f->resets) { /* the instructor's reset: the tissue at rest */
        f->resets = s->tk.resets;
        f->moved = false;
    }
}

/* A keyframe while emulating: each says the guard kept one substep (see
 * GUARD_EPISODE_MIN) and no failed step reset the tissue; the lesson's last
 * is restored, and the physics runs from there. */
static void feed_keyframe(server *s, feed *f, const ftm_wire_keyframe *k, bool last)
{
    run_to(s, f, k->tick);
    if (f->why[0])
        return;
    if (k->tick != s->tk.tick) {
        give_up(f, "keyframe of tick %" PRIu64 " at tick %" PRIu64, k->tick, s->tk.tick);
        return;
    }
    if (k->tick - f->kf_tick > GUARD_EPISODE_MIN) {
        give_up(f, "keyframes at ticks %" PRIu64 " and %" PRIu64 " are more than %u ticks apart: "
                "whether the stability guard substepped between them is not known",
                f->kf_tick, k->tick, GUARD_EPISODE_MIN);
        return;
    }
    if (k->has_mode && k->mode.substeps > 1) {
        give_up(f, "tick %" PRIu64 ": the stability guard had %d substeps (its ticks are marked "
                "unstable in the report; the frames do not say which)", k->tick,
                (int)k->mode.substeps);
        return;
    }
    if (k->count == 0 && f->moved) {
        give_up(f, "tick %" PRIu64 ": the tissue back at rest without the instructor's reset "
                "(a failed step reset it?)", k->tick);
        return;
    }
    f->kf_tick = k->tick;
    if (!last)
        return;
    srv_tick *tk = &s->tk;
    ftm_error err = {0, ""};
    if (ftm_replay_set_tissue(&tk->mat, tk->sim, k->has_tissue ? &k->tissue : NULL, &err) ||
        ftm_sim_load_state(tk->sim, k->tick, k->depth, k->nodes, k->positions, k->previous,
                           k->count, k->contacts, k->contact_count, k->has_mode ? &k->mode : NULL,
                           &err)) {
        give_up(f, "keyframe at tick %" PRIu64 ": %s", k->tick, err.message);
        return;
    }
    if (ftm_sim_hash(tk->sim) != k->state_hash) {
        give_up(f, "keyframe at tick %" PRIu64 " restores to another hash", k->tick);
        return;
    }
    /* the collision grid was left at rest: the keyframe's nodes moved */
    ftm_collide_update(tk->collide, ftm_sim_positions(tk->sim), k->nodes, k->count);
    f->emulate = false;
    f->key_tick = k->tick;
}

/* A recorded tick frame: its depth is this run's for that tick; with
 * --replay this run's frame must have its contacts (bit-exact) and hash. */
static void feed_frame(server *s, feed *f, const ftm_wire_tick *t)
{
    if (t->tick <= s->tk.tick)
        return; /* the frame of a tick sent again before a reset */
    run_to(s, f, t->tick - 1);
    if (f->why[0])
        return;
    s->tk.depth = t->depth;
    if (f->emulate) {
        char why[512] = "";
        if (srv_emulate_tick(s, t, why, sizeof why))
            give_up(f, "%s", why);
        f->frames++;
        f->moved |= t->contact_count > 0;
        return;
    }
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
    if (f->emulate && e->kind == FTM_WIRE_KEYFRAME) {
        ftm_wire_msg m;
        ftm_error err = {0, ""};
        if (ftm_wire_decode(e->kind, e->payload, e->size, &f->lim, &m, &err)) {
            snprintf(f->why, sizeof f->why, "%s", err.message);
            return;
        }
        feed_keyframe(s, f, &m.u.keyframe, e->segment == f->key_segment && e->index == f->key_index);
        ftm_wire_msg_free(&m);
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

/* Feeds the lesson at f->path through the server, entry by entry, up to its
 * end or the first problem (said on stderr). upto: at damage (a checksum
 * that differs, a file cut short), stop there with a note instead: always
 * for --upto-damage; for --resume, only in the lesson's last file. Returns
 * 0 or the exit status 1; 4 where --resume's fast path gave up (said on
 * stderr). */
static int feed_lesson(server *s, feed *f, bool upto)
{
    ftm_record_header h;
    ftm_record_reader *rd = NULL;
    ftm_error err = {0, ""};
    if (ftm_record_open(f->path, &h, &rd, &err)) {
        fprintf(stderr, "ftm-server %s: %s\n", f->mode, err.message);
        return 1;
    }
    f->lesson_start_ns = h.lesson_start_ns;
    int rc = 0;
    ftm_record_entry e;
    memset(&e, 0, sizeof e);
    while (!f->why[0]) {
        int got = ftm_record_next(rd, &e, &err);
        if (got < 0 && ftm_record_damaged(rd) && s->o.resume) {
            /* a crash cuts the last chunk of the last file only: damage
             * anywhere else is not that, and is not resumed over */
            char cut[4096], next[4096];
            uint32_t k = f->segment;
            if (ftm_record_segment_path(f->path, k + 1, cut, sizeof cut) == 0 &&
                strcmp(cut, ftm_record_reader_path(rd)) == 0)
                k++; /* the next file, cut as it was begun */
            upto = ftm_record_damaged_at_end(rd) &&
                   ftm_record_segment_path(f->path, k + 1, next, sizeof next) == 0 &&
                   access(next, F_OK) != 0;
        }
        if (got < 0 && ftm_record_damaged(rd) && upto) {
            fprintf(stderr, "ftm-server %s: note: %s; %s up to entry %" PRIu64
                    " before it%s\n", f->mode, err.message,
                    s->o.replay ? "replaying" : s->o.resume ? "re-running the lesson" : "running",
                    f->last_index, s->o.resume ? " (what the crash cut)" : " (--upto-damage)");
            f->at_damage = true;
            if (s->o.resume && strcmp(ftm_record_reader_path(rd),
                                      f->segment ? f->seg_path : f->path) == 0)
                f->cut_at = ftm_record_damage_offset(rd); /* the next file goes on from there */
            break;
        }
        if (got < 0) {
            fprintf(stderr, "ftm-server %s: %s%s\n", f->mode, err.message,
                    !ftm_record_damaged(rd) ? ""
                    : s->o.resume ? " (not the end of the lesson's last file, where a crash "
                                    "cuts it: not resumed; --replay --upto-damage replays up to "
                                    "it)"
                                            : " (--upto-damage takes it up to there)");
            rc = 1;
        }
        if (got <= 0)
            break;
        if (e.segment != f->segment) {
            f->segment = e.segment;
            snprintf(f->seg_path, sizeof f->seg_path, "%s", ftm_record_reader_path(rd));
            if (ftm_record_reader_header(rd)->after_gap) {
                snprintf(f->why, sizeof f->why, "%s begins after a gap (entries lost on a write "
                         "error): the inputs before it are not all there, so the ones after "
                         "it cannot be re-run", f->seg_path);
                f->gap = true;
                break;
            }
        }
        feed_entry(s, f, &e);
    }
    if (f->why[0] && !f->gap && f->fast) {
        fprintf(stderr, "ftm-server --resume: note: %s: entry %" PRIu64 ": the fast resume "
                "gives up: %s; the whole lesson is re-run instead\n",
                f->segment ? f->seg_path : f->path, e.index, f->why);
        rc = 4;
    } else if (f->why[0] && !f->gap) {
        fprintf(stderr, "ftm-server %s: %s: entry %" PRIu64 " (byte %" PRIu64 "): %s\n", f->mode,
                f->segment ? f->seg_path : f->path, e.index, e.offset, f->why);
        rc = 1;
    }
    ftm_record_close_reader(rd);
    return rc;
}

/* --replay, second pass: the recorded inputs (statuses, probe input, session
 * control, gone and lost events) go through the same handlers and tick
 * logic as online — collision, contacts, ftm_replay_step — each at the tick
 * it was handled; every recorded tick frame is then compared with what this
 * run produced: contacts (bit-exact) and state hash. Depths come from the
 * recorded frames (the controller's choices depend on the clock).
 * --inputs: the same without comparing, the frames giving only the depth
 * (unless --depth is given), recording the inputs and this run's frames if
 * --record is given. A lesson in several files is taken whole; one with a
 * gap (a segment begun after a write error) up to the gap, with a note. */
int srv_replay_inputs(server *s)
{
    feed f = {.path = s->o.replay ? s->o.replay : s->o.inputs,
              .mode = s->o.replay ? "--replay" : "--inputs",
              .lim = {0, 0, ftm_mesh_node_count(s->mesh)}};
    if (srv_open_reactions(s))
        return 3;
    s->pub.replaying = true;
    s->tk.period_ns = 1e9 / s->o.rate;
    int rc = feed_lesson(s, &f, s->o.upto_damage);
    if (f.gap)
        fprintf(stderr, "ftm-server %s: note: %s; %s to tick %" PRIu64 " before it\n", f.mode,
                f.why, s->o.replay ? "the inputs checked up" : "run up", f.end_tick);
    if (rc == 0 && s->o.inputs) {
        end_inputs(s, &f);
    } else if (rc == 0) {
        printf("replay %s from the inputs: %" PRIu64 " inputs through collision and the step, "
               "%" PRIu64 " tick frames with equal contacts and hash\n",
               s->o.replay, f.inputs, f.frames);
    }
    if (srv_close_reactions(s) && rc == 0)
        rc = 3;
    return rc;
}

/* The lesson's last keyframe, where --resume's physics starts (none: the
 * whole lesson is re-run). Read up to the end or the first damage. */
static void find_last_keyframe(feed *f)
{
    ftm_record_header h;
    ftm_record_reader *rd = NULL;
    ftm_error err = {0, ""};
    if (ftm_record_open(f->path, &h, &rd, &err))
        return;
    ftm_record_entry e;
    while (ftm_record_next(rd, &e, &err) > 0)
        if (!e.incoming && e.kind == FTM_WIRE_KEYFRAME) {
            f->have_key = true;
            f->key_segment = e.segment;
            f->key_index = e.index;
        }
    ftm_record_close_reader(rd);
}

/* --resume: the lesson's inputs re-run through this server, as --replay's
 * second pass runs them (every recorded frame's contacts and hash checked),
 * to its last recorded tick: the tissue, the tick counter, the participants
 * and their probes, the tissue parameters, the pause and the report as the
 * crashed server had them there. Not a lesson its server ended (its final
 * LEAVING status), nor one with a gap. Returns 0 (s->rec has the lesson's
 * start and the next file's number), or the exit status 3 after saying why
 * not; 4 when the fast path (up to the last keyframe from the frames, see
 * feed_keyframe) gave up, said on stderr: the caller runs it again with
 * --resume-full. */
int srv_resume_rerun(server *s)
{
    feed f = {.path = s->o.resume, .mode = "--resume",
              .lim = {0, 0, ftm_mesh_node_count(s->mesh)}};
    s->pub.replaying = true;
    s->tk.period_ns = 1e9 / s->o.rate;
    const uint64_t t0 = srv_now();
    if (!s->o.resume_full) {
        find_last_keyframe(&f);
        f.fast = f.emulate = f.have_key;
        f.resets = s->tk.resets;
    }
    int rc = feed_lesson(s, &f, false);
    s->pub.replaying = false;
    if (rc == 4)
        return 4;
    if (rc == 0 && f.gap) {
        fprintf(stderr, "ftm-server --resume: %s: not resumed\n", f.why);
        return 3;
    }
    if (rc)
        return 3;
    if (f.leaving) {
        fprintf(stderr, "ftm-server --resume: %s: the lesson ended cleanly at tick %" PRIu64
                " (its server's final status is in %s): nothing to resume; start a new "
                "lesson (--record, --record-dir)\n",
                f.path, f.end_tick, f.segment ? f.seg_path : f.path);
        return 3;
    }
    if (f.frames == 0) {
        fprintf(stderr, "ftm-server --resume: %s: no tick frame recorded: nothing to resume; "
                "start a new lesson\n", f.path);
        return 3;
    }
    if (f.emulate) {
        fprintf(stderr, "ftm-server --resume: note: %s: the fast resume did not reach the "
                "lesson's last keyframe; the whole lesson is re-run instead\n", f.path);
        return 4;
    }
    while (s->tk.tick < f.end_tick) /* idle ticks after the last entry's frame */
        srv_run_tick(s);
    s->rec.lesson_start_ns = f.lesson_start_ns;
    s->rec.segment = f.segment + 1;
    s->rec.resumed_tick = s->tk.tick;
    s->rec.previous_cut = f.cut_at;
    const double took = (double)(srv_now() - t0) * 1e-9;
    if (f.fast)
        srv_log(s, "info",
                "resumed lesson %s at tick %" PRIu64 " hash %016" PRIx64 " (%u file%s, %" PRIu64
                " inputs and %" PRIu64 " tick frames in %.2f s: ticks 1..%" PRIu64
                " taken from the frames, the tissue from the keyframe of tick %" PRIu64
                ", ticks %" PRIu64 "..%" PRIu64 " stepped and checked)",
                f.path, s->tk.tick, ftm_sim_hash(s->tk.sim), f.segment + 1,
                f.segment ? "s" : "", f.inputs, f.frames, took, f.key_tick, f.key_tick,
                f.key_tick + 1, s->tk.tick);
    else
        srv_log(s, "info",
                "resumed lesson %s at tick %" PRIu64 " hash %016" PRIx64 " (%u file%s, %" PRIu64
                " inputs and %" PRIu64 " tick frames re-run and checked in %.2f s: ticks 1..%"
                PRIu64 " stepped%s)",
                f.path, s->tk.tick, ftm_sim_hash(s->tk.sim), f.segment + 1,
                f.segment ? "s" : "", f.inputs, f.frames, took, s->tk.tick,
                s->o.resume_full ? ", --resume-full" : "");
    /* what follows is this process's: its own counts, its clock */
    srv_publish *pb = &s->pub;
    pb->frames = pb->heartbeats = pb->idle_ticks = pb->keyframes = 0;
    pb->bytes_frames = pb->bytes_keyframes = pb->publish_fail = 0;
    pb->ring_n = 0;
    srv_tick *tk = &s->tk;
    tk->step_ns_total = tk->step_ns_max = tk->step_sum_ns = 0.0;
    tk->step_count = tk->missed_ticks = 0;
    memset(tk->step_bucket, 0, sizeof tk->step_bucket);
    memset(tk->period_hist, 0, sizeof tk->period_hist);
    memset(tk->late_hist, 0, sizeof tk->late_hist);
    memset(tk->work_hist, 0, sizeof tk->work_hist);
    memset(tk->work_contact_hist, 0, sizeof tk->work_contact_hist);
    tk->last_tick_ns = 0;
    s->per.prev_tick = s->tk.tick;
    for (int i = 0; i < 10; i++)
        s->per.rate_tick[i] = s->tk.tick;
    s->depth_from_frames = false;
    s->tk.depth = s->per.ctl.depth; /* the recorded frames' depths were the controller's */
    const uint64_t now = srv_now();
    for (int i = 0; i < MAX_PARTICIPANTS; i++) /* each has the deadline to be heard again */
        if (s->parts.parts[i].used)
            s->parts.parts[i].last_status_ns = now;
    return 0;
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
