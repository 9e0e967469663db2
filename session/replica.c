/* SPDX-License-Identifier: GPL-3.0-or-later */
/* The replica: a copy of the scene that replays the server's tick frames
 * (replica.h, docs/protocol.md "Ticks, heartbeats and replay"). */
#include "replica.h"
#include "digest.h"
#include "keyframe.h"
#include "step.h"

#include "ftm/clock.h"

#include <inttypes.h>
#include <stdarg.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#define RING_CAP 4096            /* frames kept: unapplied ones and recent history */

typedef struct frame {
    uint64_t tick, hash, gap;
    int32_t depth, n, nreact;
    ftm_contact *c;
    ftm_wire_reaction *react;
    bool has_tissue; /* new tissue parameters from this tick on */
    ftm_wire_tissue tissue;
    bool dropped; /* broke the idle rule: not the server's, never applied */
} frame;

struct ftm_replay {
    const ftm_scene *scene;
    ftm_sim *sim;
    ftm_replay_material mat;
    ftm_log_fn log;
    void *log_user;
    uint8_t digest[FTM_REPLAY_DIGEST_SIZE];
    ftm_wire_state state;

    frame *ring;
    int32_t head, count, applied; /* ring[head .. head+applied) are applied */
    bool have_frames;
    uint64_t unbroken_since; /* tick of the first frame of the current gap-free run */
    bool evicted_any;
    uint64_t evicted_max; /* newest tick evicted from the ring */
    uint64_t kf_tick;     /* tick of the last keyframe loaded */
    bool kf_loaded;

    int32_t last_depth; /* depth and contacts of the last applied frame: idle ticks */
    int32_t last_n, last_cap;
    ftm_contact *last_c;

    bool has_pending;
    ftm_wire_keyframe pending;
    bool pending_reported;

    ftm_wire_tick last; /* copy of the last applied frame */
    int32_t last_react_cap, last_contact_cap;

    ftm_replay_stats st;
};

static void rlog(const ftm_replay *r, ftm_log_level level, const char *fmt, ...)
{
    if (!r->log)
        return;
    char buf[512];
    va_list ap;
    va_start(ap, fmt);
    vsnprintf(buf, sizeof buf, fmt, ap);
    va_end(ap);
    r->log(r->log_user, level, buf);
}

static frame *ring_at(ftm_replay *r, int32_t i) { return &r->ring[(r->head + i) % RING_CAP]; }

static void frame_free(frame *f)
{
    free(f->c);
    free(f->react);
    memset(f, 0, sizeof *f);
}

static void ring_pop(ftm_replay *r)
{
    frame *f = ring_at(r, 0);
    if (!r->evicted_any || f->tick > r->evicted_max)
        r->evicted_max = f->tick;
    r->evicted_any = true;
    frame_free(f);
    r->head = (r->head + 1) % RING_CAP;
    r->count--;
    if (r->applied > 0)
        r->applied--;
}

int ftm_replay_create(const ftm_scene *scene, ftm_log_fn log, void *log_user, ftm_replay **out,
                      ftm_error *err)
{
    ftm_replay *r = calloc(1, sizeof *r);
    if (!r)
        goto nomem;
    r->ring = calloc(RING_CAP, sizeof *r->ring);
    if (!r->ring)
        goto nomem;
    r->scene = scene;
    r->mat.scene = scene;
    r->log = log;
    r->log_user = log_user;
    ftm_sim_def def = ftm_replay_sim_def(scene);
    def.log = log;
    def.log_user = log_user;
    int rc = ftm_sim_create(ftm_scene_mesh(scene), &def, &r->sim, err);
    if (rc) {
        free(r->ring);
        free(r);
        return rc;
    }
    if (ftm_replay_scene_digest(scene, r->digest)) {
        ftm_sim_destroy(r->sim);
        goto nomem;
    }
    r->state = FTM_WIRE_STATE_JOINING;
    r->last_depth = def.depth;
    *out = r;
    return FTM_OK;
nomem:
    if (r)
        free(r->ring);
    free(r);
    if (err) {
        err->code = FTM_ENOMEM;
        snprintf(err->message, sizeof err->message, "replay: out of memory");
    }
    return FTM_ENOMEM;
}

void ftm_replay_destroy(ftm_replay *r)
{
    if (!r)
        return;
    while (r->count > 0)
        ring_pop(r);
    free(r->ring);
    free(r->last_c);
    free(r->last.contacts);
    free(r->last.reactions);
    if (r->has_pending)
        ftm_replay_keyframe_free(&r->pending);
    ftm_sim_destroy(r->sim);
    ftm_replay_material_free(&r->mat);
    free(r);
}

int ftm_replay_check_announce(const ftm_replay *r, const ftm_wire_announce *a, ftm_error *err)
{
    /* servers from before the field computed with revision 1 */
    const uint32_t theirs = a->arithmetic ? a->arithmetic : 1, ours = ftm_arithmetic_revision();
    if (theirs != ours) {
        if (err) {
            err->code = FTM_EVERSION;
            snprintf(err->message, sizeof err->message,
                     "the server's physics core is of arithmetic revision %" PRIu32
                     ", this build's of revision %" PRIu32
                     ": its replay would not match the server's; use builds of one FTM version",
                     theirs, ours);
        }
        return FTM_EVERSION;
    }
    const char *why = NULL;
    if (a->digest_len != FTM_REPLAY_DIGEST_SIZE || memcmp(a->digest, r->digest, sizeof r->digest))
        why = "content digest differs";
    else if (a->node_count != ftm_mesh_node_count(ftm_scene_mesh(r->scene)))
        why = "node count differs";
    else if (a->time_step != ftm_replay_sim_def(r->scene).time_step)
        why = "time step differs";
    if (!why)
        return FTM_OK;
    if (err) {
        err->code = FTM_EINVAL;
        snprintf(err->message, sizeof err->message,
                 "announced scene '%s' does not match the local scene '%s': %s", a->scene_id,
                 ftm_scene_name(r->scene), why);
    }
    return FTM_EINVAL;
}

static void enter_resync(ftm_replay *r, const char *why)
{
    if (r->state != FTM_WIRE_STATE_SYNCED)
        return;
    r->state = FTM_WIRE_STATE_RESYNCING;
    r->st.resyncs++;
    rlog(r, FTM_LOG_WARN, "replay: resyncing at tick %" PRIu64 ": %s", ftm_replay_tick(r), why);
}

static int remember_last(ftm_replay *r, const frame *f)
{
    if (f->n > r->last_cap) {
        ftm_contact *c = realloc(r->last_c, (size_t)f->n * sizeof *c);
        ftm_contact *c2 = realloc(r->last.contacts, (size_t)f->n * sizeof *c2);
        if (c)
            r->last_c = c;
        if (c2)
            r->last.contacts = c2;
        if (!c || !c2)
            return FTM_ENOMEM;
        r->last_cap = f->n;
    }
    if (f->nreact > r->last_react_cap) {
        ftm_wire_reaction *q = realloc(r->last.reactions, (size_t)f->nreact * sizeof *q);
        if (!q)
            return FTM_ENOMEM;
        r->last.reactions = q;
        r->last_react_cap = f->nreact;
    }
    if (f->n)
        memcpy(r->last_c, f->c, (size_t)f->n * sizeof *f->c);
    if (f->n)
        memcpy(r->last.contacts, f->c, (size_t)f->n * sizeof *f->c);
    if (f->nreact)
        memcpy(r->last.reactions, f->react, (size_t)f->nreact * sizeof *f->react);
    r->last_n = f->n;
    r->last_depth = f->depth;
    r->last.tick = f->tick;
    r->last.depth = f->depth;
    r->last.contact_count = f->n;
    r->last.reaction_count = f->nreact;
    r->last.state_hash = f->hash;
    return FTM_OK;
}

static int timed_step(ftm_replay *r, int32_t depth, const ftm_contact *c, int32_t n)
{
    int64_t t0 = ftm_clock_mono_ns();
    ftm_error err = {0, ""};
    int rc = ftm_replay_step(r->sim, depth, c, n, &err);
    double dt = (double)(ftm_clock_mono_ns() - t0);
    r->st.replay_ns_total += dt;
    if (dt > r->st.replay_ns_max)
        r->st.replay_ns_max = dt;
    if (rc)
        rlog(r, FTM_LOG_WARN, "replay: tick %" PRIu64 ": %s", ftm_replay_tick(r) + 1, err.message);
    return rc;
}

/* Tissue parameters from a frame or keyframe (NULL: the scene's). */
static int set_tissue(ftm_replay *r, uint64_t tick, const ftm_wire_tissue *t)
{
    ftm_wire_tissue before = ftm_replay_tissue_now(&r->mat);
    ftm_error err = {0, ""};
    int rc = ftm_replay_set_tissue(&r->mat, r->sim, t, &err);
    if (rc) {
        rlog(r, FTM_LOG_ERROR, "replay: tick %" PRIu64 ": tissue parameters not applied: %s",
             tick, err.message);
        return rc;
    }
    ftm_wire_tissue now = ftm_replay_tissue_now(&r->mat);
    if (!ftm_replay_tissue_equal(&before, &now))
        rlog(r, FTM_LOG_INFO,
             "replay: tick %" PRIu64 ": tissue now k %g N/m, d %g N s/m, m %g kg", tick,
             now.stiffness, now.node_damping, now.node_mass);
    return FTM_OK;
}

static int load_keyframe(ftm_replay *r, const ftm_wire_keyframe *k)
{
    ftm_error err = {0, ""};
    int rc = set_tissue(r, k->tick, k->has_tissue ? &k->tissue : NULL);
    if (rc)
        return rc;
    rc = ftm_sim_load_state(r->sim, k->tick, k->depth, k->nodes, k->positions, k->previous,
                            k->count, k->contacts, k->contact_count,
                            k->has_mode ? &k->mode : NULL, &err);
    if (rc) {
        rlog(r, FTM_LOG_ERROR, "replay: keyframe at tick %" PRIu64 " rejected: %s", k->tick,
             err.message);
        return rc;
    }
    uint64_t h = ftm_sim_hash(r->sim);
    if (h != k->state_hash) {
        rlog(r, FTM_LOG_ERROR,
             "replay: keyframe at tick %" PRIu64 " restored with hash %016" PRIx64
             ", keyframe says %016" PRIx64 " (different scene or libftm?)",
             k->tick, h, k->state_hash);
        return FTM_EINVAL;
    }
    /* idle ticks after it step with its contacts, as the server did */
    if (k->contact_count > r->last_cap) {
        ftm_contact *c = realloc(r->last_c, (size_t)k->contact_count * sizeof *c);
        if (c)
            r->last_c = c;
        ftm_contact *c2 = c ? realloc(r->last.contacts, (size_t)k->contact_count * sizeof *c2) : NULL;
        if (c2)
            r->last.contacts = c2;
        if (!c || !c2)
            return FTM_ENOMEM;
        r->last_cap = k->contact_count;
    }
    if (k->contact_count)
        memcpy(r->last_c, k->contacts, (size_t)k->contact_count * sizeof *k->contacts);
    r->last_depth = k->depth;
    r->last_n = k->contact_count;
    r->kf_tick = k->tick;
    r->kf_loaded = true;
    r->st.keyframes_loaded++;
    /* frames after the keyframe are to be applied (again) */
    int32_t i = 0;
    while (i < r->count && ring_at(r, i)->tick <= k->tick)
        i++;
    r->applied = i;
    return FTM_OK;
}

static void drop_pending(ftm_replay *r)
{
    if (r->has_pending)
        ftm_replay_keyframe_free(&r->pending);
    r->has_pending = false;
    r->pending_reported = false;
}

/* A frame that broke the idle rule: never applied, not even after a resync
 * (a keyframe restores the frames after it, which would bring it back). */
static void drop_frame(ftm_replay *r, frame *f, const char *why)
{
    f->dropped = true;
    r->st.rule_breaks++;
    enter_resync(r, why);
}

static int apply_frames(ftm_replay *r)
{
    while (r->state == FTM_WIRE_STATE_SYNCED && r->applied < r->count) {
        frame *f = ring_at(r, r->applied);
        uint64_t cur = ftm_replay_tick(r);
        if (f->dropped) {
            r->applied++;
            continue;
        }
        if (f->gap > 0 && !(r->kf_loaded && f->tick <= r->kf_tick + 1)) {
            r->st.gaps++;
            char why[96];
            snprintf(why, sizeof why, "%" PRIu64 " tick frame(s) lost before tick %" PRIu64,
                     f->gap, f->tick);
            enter_resync(r, why);
            return FTM_OK;
        }
        if (f->tick <= cur) {
            r->st.stale_frames++;
            r->applied++;
            continue;
        }
        /* The server leaves a tick out only when it and the frame before it
         * have no contacts and its step moved nothing (docs/protocol.md).
         * A frame that claims otherwise is not the server's: it is dropped
         * and the replica resyncs, rather than step through up to
         * FTM_WIRE_MAX_TICK_GAP loaded ticks for it. */
        if (f->tick - cur > FTM_WIRE_MAX_TICK_GAP) {
            drop_frame(r, f, "frame too far ahead");
            return FTM_OK;
        }
        if (f->tick - cur > 1 && r->last_n > 0) {
            drop_frame(r, f, "frame skips ticks after a tick with contacts");
            return FTM_OK;
        }
        while (ftm_replay_tick(r) + 1 < f->tick) { /* ticks the server left out: idle */
            uint64_t before = ftm_replay_tick(r);
            timed_step(r, r->last_depth, r->last_c, r->last_n);
            r->st.idle_ticks++;
            if (ftm_replay_tick(r) == before)
                break; /* the step failed; the hash check below catches it */
            ftm_sim_stats st;
            ftm_sim_get_stats(r->sim, &st);
            if (st.updated_nodes > 0) {
                char why[128];
                snprintf(why, sizeof why,
                         "idle tick %" PRIu64 " moved nodes, so the server would have sent it",
                         ftm_replay_tick(r));
                drop_frame(r, f, why);
                return FTM_OK;
            }
        }
        if (f->has_tissue && set_tissue(r, f->tick, &f->tissue)) {
            enter_resync(r, "tissue parameters could not be applied");
            return FTM_OK;
        }
        timed_step(r, f->depth, f->c, f->n);
        r->st.frames_applied++;
        r->applied++;
        int rc = remember_last(r, f);
        if (rc)
            return rc;
        uint64_t h = ftm_sim_hash(r->sim);
        if (h != f->hash || ftm_replay_tick(r) != f->tick) {
            r->st.mismatches++;
            char why[128];
            snprintf(why, sizeof why,
                     "hash mismatch at tick %" PRIu64 ": mine %016" PRIx64 ", server %016" PRIx64,
                     f->tick, h, f->hash);
            enter_resync(r, why);
            return FTM_OK;
        }
        if (r->has_pending && r->pending.tick <= f->tick) {
            if (r->pending.tick == f->tick && r->pending.state_hash != h) {
                rlog(r, FTM_LOG_INFO,
                     "replay: server state changed at tick %" PRIu64 " (reset): keyframe restored",
                     f->tick);
                rc = load_keyframe(r, &r->pending);
                if (rc)
                    enter_resync(r, "keyframe could not be restored");
            }
            drop_pending(r);
        }
    }
    return FTM_OK;
}

/* Not synced: restore the pending keyframe if the frames received since can
 * continue it (no frame after it lost). */
static int try_resync(ftm_replay *r)
{
    if (r->state == FTM_WIRE_STATE_SYNCED || !r->has_pending)
        return FTM_OK;
    uint64_t k = r->pending.tick;
    if (!r->have_frames)
        return FTM_OK; /* wait for frames to show continuity */
    if (r->unbroken_since > k + 1 || (r->evicted_any && r->evicted_max > k)) {
        if (!r->pending_reported) {
            r->st.keyframes_unusable++;
            r->pending_reported = true;
        }
        return FTM_OK; /* frames after it were lost: wait for a newer one */
    }
    int rc = load_keyframe(r, &r->pending);
    drop_pending(r);
    if (rc)
        return FTM_OK;
    rlog(r, FTM_LOG_INFO, "replay: synced from keyframe at tick %" PRIu64, k);
    r->state = FTM_WIRE_STATE_SYNCED;
    return apply_frames(r);
}

int ftm_replay_on_tick(ftm_replay *r, const ftm_wire_received *rx)
{
    const ftm_wire_tick *t = &rx->msg.u.tick;
    r->st.frames_received++;
    if (r->count == RING_CAP)
        ring_pop(r);
    frame *f = ring_at(r, r->count);
    memset(f, 0, sizeof *f);
    f->c = malloc(((size_t)t->contact_count + 1) * sizeof *f->c);
    f->react = malloc(((size_t)t->reaction_count + 1) * sizeof *f->react);
    if (!f->c || !f->react) {
        frame_free(f);
        return FTM_ENOMEM;
    }
    f->tick = t->tick;
    f->hash = t->state_hash;
    f->gap = rx->gap;
    f->depth = t->depth;
    f->n = t->contact_count;
    f->nreact = t->reaction_count;
    f->has_tissue = t->has_tissue;
    f->tissue = t->tissue;
    if (f->n)
        memcpy(f->c, t->contacts, (size_t)f->n * sizeof *f->c);
    if (f->nreact)
        memcpy(f->react, t->reactions, (size_t)f->nreact * sizeof *f->react);
    r->count++;
    if (!r->have_frames || rx->gap > 0)
        r->unbroken_since = t->tick;
    r->have_frames = true;
    if (r->state == FTM_WIRE_STATE_SYNCED)
        return apply_frames(r);
    return try_resync(r);
}

int ftm_replay_on_keyframe(ftm_replay *r, const ftm_wire_keyframe *k)
{
    if (r->state == FTM_WIRE_STATE_SYNCED) {
        uint64_t cur = ftm_replay_tick(r);
        if (k->tick > cur) { /* frames up to it still to come: check it then */
            if (r->has_pending && r->pending.tick > k->tick)
                return FTM_OK;
            drop_pending(r);
            int rc = ftm_replay_keyframe_copy(&r->pending, k);
            r->has_pending = rc == FTM_OK;
            return rc;
        }
        if (k->tick == cur) {
            if (k->state_hash != ftm_sim_hash(r->sim)) {
                rlog(r, FTM_LOG_INFO,
                     "replay: server state changed at tick %" PRIu64 " (reset): keyframe restored",
                     k->tick);
                if (load_keyframe(r, k))
                    enter_resync(r, "keyframe could not be restored");
            }
            return FTM_OK;
        }
        /* behind us: compare with the frame we applied at its tick */
        for (int32_t i = r->applied - 1; i >= 0; i--) {
            frame *f = ring_at(r, i);
            if (f->dropped)
                continue;
            if (f->tick < k->tick)
                break;
            if (f->tick == k->tick) {
                if (f->hash != k->state_hash) {
                    rlog(r, FTM_LOG_INFO,
                         "replay: server state changed at tick %" PRIu64
                         " (reset): keyframe restored, later frames applied again",
                         k->tick);
                    if (load_keyframe(r, k))
                        enter_resync(r, "keyframe could not be restored");
                    else
                        return apply_frames(r);
                }
                break;
            }
        }
        return FTM_OK;
    }
    if (r->has_pending && r->pending.tick >= k->tick)
        return try_resync(r);
    drop_pending(r);
    int rc = ftm_replay_keyframe_copy(&r->pending, k);
    if (rc)
        return rc;
    r->has_pending = true;
    return try_resync(r);
}

ftm_wire_state ftm_replay_state(const ftm_replay *r) { return r->state; }

uint64_t ftm_replay_tick(const ftm_replay *r)
{
    ftm_sim_stats st;
    ftm_sim_get_stats(r->sim, &st);
    return st.step;
}

uint64_t ftm_replay_hash(const ftm_replay *r) { return ftm_sim_hash(r->sim); }

const ftm_wire_tick *ftm_replay_last_frame(const ftm_replay *r) { return &r->last; }

void ftm_replay_get_stats(const ftm_replay *r, ftm_replay_stats *stats) { *stats = r->st; }

double ftm_replay_take_max(ftm_replay *r)
{
    double m = r->st.replay_ns_max;
    r->st.replay_ns_max = 0.0;
    return m;
}

ftm_sim *ftm_replay_sim(ftm_replay *r) { return r->sim; }

ftm_wire_tissue ftm_replay_tissue(const ftm_replay *r) { return ftm_replay_tissue_now(&r->mat); }

int ftm_replay_range(const ftm_replay *r, ftm_tissue_range *out, ftm_error *err)
{
    return ftm_replay_tissue_range(&r->mat, r->sim, NULL, out, err);
}

ftm_wire_tissue ftm_replay_own_tissue(const ftm_replay *r) { return ftm_replay_scene_tissue(r->scene); }
