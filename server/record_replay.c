/* SPDX-License-Identifier: GPL-3.0-or-later */
/* ftm-server --replay FILE: re-simulates a recorded session from its scene
 * with libftm and checks every recorded tick frame's state hash
 * (docs/server.md, "Session recording").
 *
 * The published tick frames are applied exactly as a replica applies them
 * (ticks the server left out as idle are stepped with the previous frame's
 * depth and contacts); keyframes are checked against the replayed state and
 * restored only where the server reset the tissue (their hash differs from
 * the state at their tick). Inputs are decoded and counted, not re-run: the
 * check is of the physics and the frames, see the docs. */
#include "record.h"
#include "record_replay.h"
#include "digest.h"
#include "step.h"
#include "tissue.h"

#include "ftm/scene.h"
#include "ftm/wire.h"

#include <inttypes.h>
#include <stdarg.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

static uint64_t sim_tick(const ftm_sim *sim)
{
    ftm_sim_stats st;
    ftm_sim_get_stats(sim, &st);
    return st.step;
}

typedef struct rstate {
    const char *path;
    ftm_sim *sim;
    ftm_replay_material mat; /* tissue parameters from the frames */
    uint64_t tissue_changes;
    int32_t node_count;
    int32_t last_depth, last_n;
    ftm_contact *last_c;
    int32_t cap;
    uint64_t frames, idle, keyframes_checked, resets, inputs[FTM_WIRE_KIND_MAX + 1], gone, depth_changes;
    uint64_t replies, refused; /* control replies published, of them refused */
    int32_t depth_min_seen, depth_max_seen;
    uint64_t pending_mismatch; /* tick whose frame mismatched; 0: none */
    uint64_t pending_hash;     /* that frame's hash */
    uint64_t final_status_tick, final_status_hash;
    bool have_final_status;
    uint64_t last_index; /* the last entry read */
    uint32_t segment;    /* the segment of the last entry read */
    bool seg_start;      /* a segment began: its first keyframe takes the replay on */
    bool seg_gap;        /* and entries before it were lost (restore, do not step) */
    uint64_t gaps;
    char seg_path[4096]; /* the file of the last entry read (messages name it) */
} rstate;

static int fail(const char *path, const ftm_record_entry *e, const char *fmt, ...)
    __attribute__((format(printf, 3, 4)));
static int fail(const char *path, const ftm_record_entry *e, const char *fmt, ...)
{
    char buf[FTM_ERROR_MESSAGE_MAX];
    va_list ap;
    va_start(ap, fmt);
    vsnprintf(buf, sizeof buf, fmt, ap);
    va_end(ap);
    if (e)
        fprintf(stderr, "ftm-server --replay: %s: entry %" PRIu64 " (byte %" PRIu64 "): %s\n",
                path, e->index, e->offset, buf);
    else
        fprintf(stderr, "ftm-server --replay: %s: %s\n", path, buf);
    return 1;
}

static int keep_last(rstate *s, const ftm_wire_tick *t)
{
    if (t->contact_count > s->cap) {
        ftm_contact *c = realloc(s->last_c, (size_t)t->contact_count * sizeof *c);
        if (!c)
            return -1;
        s->last_c = c;
        s->cap = t->contact_count;
    }
    if (t->contact_count)
        memcpy(s->last_c, t->contacts, (size_t)t->contact_count * sizeof *s->last_c);
    s->last_n = t->contact_count;
    if (t->depth != s->last_depth)
        s->depth_changes++;
    s->last_depth = t->depth;
    if (t->depth < s->depth_min_seen)
        s->depth_min_seen = t->depth;
    if (t->depth > s->depth_max_seen)
        s->depth_max_seen = t->depth;
    return 0;
}

static int on_frame(rstate *s, const ftm_record_entry *e, const ftm_wire_tick *t)
{
    uint64_t cur = sim_tick(s->sim);
    if (s->pending_mismatch)
        return fail(s->path, e,
                    "tick %" PRIu64 ": state hash differs: recorded %016" PRIx64
                    ", replayed %016" PRIx64,
                    s->pending_mismatch, s->pending_hash, ftm_sim_hash(s->sim));
    if (t->tick <= cur)
        return fail(s->path, e, "tick frame %" PRIu64 " out of order (replayed up to tick %" PRIu64 ")",
                    t->tick, cur);
    if (t->tick - cur > FTM_WIRE_MAX_TICK_GAP) /* not a server's: it would take hours */
        return fail(s->path, e,
                    "tick frame %" PRIu64 " is %" PRIu64 " ticks after tick %" PRIu64
                    "; a server sends a frame at least every %u ticks",
                    t->tick, t->tick - cur, cur, FTM_WIRE_MAX_TICK_GAP);
    ftm_error err = {0, ""};
    while (sim_tick(s->sim) + 1 < t->tick) {
        uint64_t before = sim_tick(s->sim);
        ftm_replay_step(s->sim, s->last_depth, s->last_c, s->last_n, &err);
        s->idle++;
        if (sim_tick(s->sim) == before)
            break; /* the step failed: the hash check says where */
    }
    if (t->has_tissue) {
        if (ftm_replay_set_tissue(&s->mat, s->sim, &t->tissue, &err))
            return fail(s->path, e, "tick %" PRIu64 ": tissue parameters: %s", t->tick,
                        err.message);
        s->tissue_changes++;
    }
    ftm_replay_step(s->sim, t->depth, t->contacts, t->contact_count, &err);
    s->frames++;
    if (keep_last(s, t))
        return fail(s->path, e, "out of memory");
    uint64_t h = ftm_sim_hash(s->sim);
    if (sim_tick(s->sim) != t->tick || h != t->state_hash) {
        /* only a keyframe of this very tick can explain it (the server reset
         * the tissue after a failed step); anything else is a mismatch */
        s->pending_mismatch = t->tick;
        s->pending_hash = t->state_hash;
    }
    return 0;
}

static int on_keyframe(rstate *s, const ftm_record_entry *e, const ftm_wire_keyframe *k)
{
    uint64_t cur = sim_tick(s->sim);
    bool gap = false;
    if (s->seg_start && k->tick > cur && !s->pending_mismatch) {
        /* a segment's first keyframe: a resumed server's (the ticks since
         * the last frame were idle: stepped as a replica steps them, and the
         * keyframe must have that hash), or one after a gap (restored) */
        if (s->seg_gap) {
            gap = true;
        } else {
            ftm_error err = {0, ""};
            while (sim_tick(s->sim) < k->tick) {
                uint64_t before = sim_tick(s->sim);
                ftm_replay_step(s->sim, s->last_depth, s->last_c, s->last_n, &err);
                s->idle++;
                if (sim_tick(s->sim) == before)
                    break;
            }
            cur = sim_tick(s->sim);
        }
    }
    s->seg_start = false;
    /* a tick whose step failed here as it did on the server (which then
     * reset the tissue): the replay stayed on the tick before, and this
     * keyframe of the failed tick is the reset */
    const bool failed_step = s->pending_mismatch == k->tick && cur + 1 == k->tick;
    if (k->tick != cur && !failed_step && !gap)
        return fail(s->path, e, "keyframe at tick %" PRIu64 " but the replay is at tick %" PRIu64,
                    k->tick, cur);
    bool after_mismatch = s->pending_mismatch != 0;
    if (after_mismatch && k->state_hash != s->pending_hash)
        return fail(s->path, e,
                    "tick %" PRIu64 ": state hash differs: recorded %016" PRIx64
                    ", replayed %016" PRIx64,
                    s->pending_mismatch, s->pending_hash, ftm_sim_hash(s->sim));
    s->pending_mismatch = 0;
    if (!gap && !after_mismatch && k->state_hash == ftm_sim_hash(s->sim)) {
        s->keyframes_checked++;
        return 0;
    }
    ftm_error err = {0, ""};
    if (ftm_replay_set_tissue(&s->mat, s->sim, k->has_tissue ? &k->tissue : NULL, &err))
        return fail(s->path, e, "keyframe at tick %" PRIu64 ": tissue parameters: %s", k->tick,
                    err.message);
    if (ftm_sim_load_state(s->sim, k->tick, k->depth, k->nodes, k->positions, k->previous, k->count,
                           k->contacts, k->contact_count, k->has_mode ? &k->mode : NULL, &err))
        return fail(s->path, e, "keyframe at tick %" PRIu64 ": %s", k->tick, err.message);
    if (ftm_sim_hash(s->sim) != k->state_hash)
        return fail(s->path, e, "keyframe at tick %" PRIu64 " restores to another hash", k->tick);
    s->last_depth = k->depth;
    s->last_n = 0;
    if (k->contact_count) { /* the idle ticks after it step with them */
        ftm_wire_tick kt = {.depth = k->depth, .contact_count = k->contact_count,
                            .contacts = k->contacts};
        if (keep_last(s, &kt))
            return fail(s->path, e, "out of memory");
    }
    if (gap)
        s->gaps++;
    else
        s->resets++;
    return 0;
}

int ftm_server_replay(const char *path, const char *scene_name, bool upto_damage)
{
    ftm_record_header h;
    ftm_record_reader *rd = NULL;
    ftm_error err = {0, ""};
    if (ftm_record_open(path, &h, &rd, &err)) {
        fprintf(stderr, "ftm-server --replay: %s\n", err.message);
        return 1;
    }
    int rc = 0;
    ftm_scene *scene = NULL;
    rstate s;
    memset(&s, 0, sizeof s);
    s.path = path;
    if (h.arithmetic != ftm_arithmetic_revision()) {
        rc = fail(path, NULL,
                  "recorded by a physics core of arithmetic revision %" PRIu32
                  ", this build's is revision %" PRIu32
                  ": its state hashes cannot be reproduced here; replay it with the FTM version "
                  "that recorded it",
                  h.arithmetic, ftm_arithmetic_revision());
        goto done;
    }
    const char *name = scene_name ? scene_name : h.scene_id;
    if (ftm_wire_open_scene(name, &scene, NULL, 0, &err)) {
        rc = fail(path, NULL, "scene '%s': %s", name, err.message);
        goto done;
    }
    uint8_t digest[FTM_REPLAY_DIGEST_SIZE];
    ftm_replay_scene_digest(scene, digest);
    if (h.digest_len != FTM_REPLAY_DIGEST_SIZE || memcmp(digest, h.digest, sizeof digest) != 0) {
        rc = fail(path, NULL, "scene '%s' differs from the recorded one (content digest)", name);
        goto done;
    }
    const ftm_mesh *mesh = ftm_scene_mesh(scene);
    if (ftm_mesh_node_count(mesh) != h.node_count) {
        rc = fail(path, NULL, "scene has %d nodes, the recording %d", (int)ftm_mesh_node_count(mesh),
                  (int)h.node_count);
        goto done;
    }
    ftm_sim_def def = ftm_replay_sim_def(scene);
    s.mat.scene = scene;
    if (ftm_sim_create(mesh, &def, &s.sim, &err)) {
        rc = fail(path, NULL, "%s", err.message);
        goto done;
    }
    s.node_count = h.node_count;
    s.last_depth = def.depth;
    s.depth_min_seen = INT32_MAX;
    s.depth_max_seen = INT32_MIN;
    ftm_wire_limits lim = {0, 0, h.node_count};
    bool at_damage = false;
    for (;;) {
        ftm_record_entry e;
        int got = ftm_record_next(rd, &e, &err);
        if (got < 0 && ftm_record_damaged(rd) && upto_damage) { /* the message names the file */
            fprintf(stderr, "ftm-server --replay: note: %s; replaying up to entry %" PRIu64
                    " before it (--upto-damage)\n", err.message, s.last_index);
            at_damage = true;
            break;
        }
        if (got < 0) {
            fprintf(stderr, "ftm-server --replay: %s%s\n", err.message,
                    ftm_record_damaged(rd) ? " (--upto-damage replays up to it)" : "");
            rc = 1;
            goto done;
        }
        if (got == 0)
            break;
        if (e.segment != s.segment) { /* the next file of the lesson */
            snprintf(s.seg_path, sizeof s.seg_path, "%s", ftm_record_reader_path(rd));
            s.path = s.seg_path;
            s.segment = e.segment;
            s.seg_start = true;
            s.seg_gap = ftm_record_reader_header(rd)->after_gap;
        }
        s.last_index = e.index;
        if (e.gone || e.lost) { /* events without a payload */
            s.gone += e.gone;
            continue;
        }
        ftm_wire_msg m;
        if (ftm_wire_decode(e.kind, e.payload, e.size, &lim, &m, &err)) {
            rc = fail(s.path, &e, "%s %s: %s", e.incoming ? "received" : "published",
                      ftm_wire_kind_name(e.kind), err.message);
            goto done;
        }
        if (e.incoming) {
            s.inputs[e.kind]++;
        } else if (e.kind == FTM_WIRE_TICK) {
            rc = on_frame(&s, &e, &m.u.tick);
        } else if (e.kind == FTM_WIRE_KEYFRAME) {
            rc = on_keyframe(&s, &e, &m.u.keyframe);
        } else if (e.kind == FTM_WIRE_CONTROL_REPLY) {
            s.replies++;
            s.refused += m.u.control_reply.outcome == FTM_WIRE_OUTCOME_REFUSED;
        } else if (e.kind == FTM_WIRE_STATUS && m.u.status.state == FTM_WIRE_STATE_LEAVING) {
            s.have_final_status = true;
            s.final_status_tick = m.u.status.last_applied_tick;
            s.final_status_hash = m.u.status.state_hash;
        }
        ftm_wire_msg_free(&m);
        if (rc)
            goto done;
    }
    if (s.pending_mismatch) {
        rc = fail(path, NULL, "tick %" PRIu64 ": state hash differs: recorded %016" PRIx64
                  ", replayed %016" PRIx64, s.pending_mismatch, s.pending_hash, ftm_sim_hash(s.sim));
        goto done;
    }
    uint64_t tick = sim_tick(s.sim), hash = ftm_sim_hash(s.sim);
    if (s.have_final_status && (s.final_status_tick != tick || s.final_status_hash != hash)) {
        rc = fail(path, NULL,
                  "the server's last status says tick %" PRIu64 " hash %016" PRIx64
                  ", the replay ends at tick %" PRIu64 " hash %016" PRIx64,
                  s.final_status_tick, s.final_status_hash, tick, hash);
        goto done;
    }
    if (s.frames == 0) {
        rc = fail(path, NULL, "no tick frames recorded");
        goto done;
    }
    if (!s.have_final_status && !at_damage) /* what is there replayed; say that it is not all */
        fprintf(stderr,
                "ftm-server --replay: %s: note: the recording ends at entry %" PRIu64
                " without the server's final status (killed, crashed, or its recording "
                "stopped on a write error?); replayed to tick %" PRIu64 ", where it was cut\n",
                path, s.last_index, tick);
    printf("replay %s: scene '%s', %" PRIu64 " tick frames and %" PRIu64
           " idle ticks replayed, every hash equal; %" PRIu64 " keyframes checked, %" PRIu64
           " resets; depth %d..%d (%" PRIu64 " changes); %" PRIu64 " tissue changes; inputs: %" PRIu64
           " probe, %" PRIu64 " status, %" PRIu64 " control, %" PRIu64 " gone; %" PRIu64
           " control replies (%" PRIu64 " refused)\n",
           path, h.scene_id, s.frames, s.idle, s.keyframes_checked, s.resets,
           (int)s.depth_min_seen, (int)s.depth_max_seen, s.depth_changes, s.tissue_changes,
           s.inputs[FTM_WIRE_PROBE_INPUT], s.inputs[FTM_WIRE_STATUS], s.inputs[FTM_WIRE_CONTROL],
           s.gone, s.replies, s.refused);
    if (s.segment)
        printf("replay %s: one lesson in %u files (%s, then .1 to .%u), %" PRIu64
               " begun after a gap; %u crash cut%s passed over (a resumed server went on from "
               "there)\n",
               path, s.segment + 1, path, s.segment, s.gaps, ftm_record_cuts_passed(rd),
               ftm_record_cuts_passed(rd) == 1 ? "" : "s");
    printf("ftm-server: final tick %" PRIu64 " hash %016" PRIx64 "\n", tick, hash);
done:
    ftm_sim_destroy(s.sim);
    ftm_replay_material_free(&s.mat);
    free(s.last_c);
    ftm_scene_destroy(scene);
    ftm_record_close_reader(rd);
    return rc;
}
