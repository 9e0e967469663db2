/* SPDX-License-Identifier: GPL-3.0-or-later */
/* What the server publishes (docs/protocol.md): announcements, its
 * statuses, tick frames (unless idle) and keyframes. Each is encoded here,
 * counted and recorded, and queued for ftm_wire's publishing thread. */
#include "rooms.h"
#include "keyframe.h"
#include "step.h"

#include <stdlib.h>
#include <string.h>

/* Encodes here (to count the bytes) and queues the payload. */
int srv_send(server *s, const ftm_wire_msg *m, uint64_t *bytes)
{
    uint8_t *buf = NULL;
    size_t size = 0;
    ftm_error err = {0, ""};
    int rc = ftm_wire_encode(m, &buf, &size, &err);
    if (rc == FTM_OK && s->pub.wire) /* --offline: encoded and counted only */
        rc = ftm_wire_publish_raw(s->pub.wire, (int)m->kind, buf, size, &err);
    if (buf)
        srv_record_entry(s, false, (int)m->kind, s->o.id, buf, size, false, false);
    free(buf);
    if (rc) {
        s->pub.publish_fail++;
        srv_log(s, "warn", "publishing %s failed: %s", ftm_wire_kind_name((int)m->kind), err.message);
        return rc;
    }
    if (bytes)
        *bytes += size;
    return FTM_OK;
}

void srv_publish_announce(server *s)
{
    ftm_wire_msg m;
    memset(&m, 0, sizeof m);
    m.kind = FTM_WIRE_ANNOUNCE;
    ftm_wire_announce *a = &m.u.announce;
    snprintf(a->scene_id, sizeof a->scene_id, "%s", s->o.scene);
    memcpy(a->digest, s->digest, sizeof s->digest);
    a->digest_len = FTM_REPLAY_DIGEST_SIZE;
    a->tick_rate_hz = (uint32_t)(s->o.rate + 0.5);
    a->time_step = ftm_replay_sim_def(s->scene).time_step;
    a->depth = s->tk.depth;
    a->depth_min = s->per.ctl.def.floor;
    a->depth_max = s->per.ctl.def.max;
    a->tissue = ftm_replay_tissue_now(&s->tk.mat);
    a->node_count = ftm_mesh_node_count(s->mesh);
    a->tick = s->tk.tick;
    a->paused = s->tk.paused;
    a->server_start_ns = s->start_unix_ns;
    /* a resumed lesson's start: its first server's; replicas take the new
     * process as the same session going on */
    a->lesson_start_ns = s->rec.lesson_start_ns ? s->rec.lesson_start_ns : s->start_unix_ns;
    a->arithmetic = ftm_arithmetic_revision();
    srv_send(s, &m, NULL);
}

void srv_publish_status(server *s, ftm_wire_state state)
{
    ftm_wire_msg m;
    memset(&m, 0, sizeof m);
    m.kind = FTM_WIRE_STATUS;
    ftm_wire_status *st = &m.u.status;
    st->participant = s->o.id;
    st->role = FTM_WIRE_ROLE_SERVER;
    st->state = state;
    st->last_applied_tick = s->tk.tick;
    st->state_hash = ftm_sim_hash(s->tk.sim);
    st->replay_ns_per_tick = s->tk.tick ? s->tk.step_ns_total / (double)s->tk.tick : 0.0;
    st->replay_ns_max = s->tk.step_ns_max;
    snprintf(st->name, sizeof st->name, "ftm-server");
    const uint64_t now = srv_now();
    for (int i = 0; i < FTM_WIRE_IGNORED_MAX; i++)
        if (s->parts.ignored[i].last_ns && now - s->parts.ignored[i].last_ns <= STATUS_DEADLINE_NS) {
            st->ignored_participant[st->ignored_count] = s->parts.ignored[i].id;
            st->ignored_origin[st->ignored_count++] = s->parts.ignored[i].origin;
        }
    /* the process heard under each id: what a trainee waits for before it
     * sends probe input or renders force (docs/protocol.md) */
    for (int i = 0; i < MAX_PARTICIPANTS; i++)
        if (s->parts.parts[i].used && s->parts.parts[i].origin) {
            st->holder_participant[st->holder_count] = s->parts.parts[i].id;
            st->holder_origin[st->holder_count++] = s->parts.parts[i].origin;
        }
    srv_send(s, &m, NULL);
}

/* A status now rather than at the next periodic one, for news that decides
 * what a process does (an id taken, an id held); at most 20 extra a second,
 * the periodic status tells the rest within 500 ms. */
void srv_tell_now(server *s)
{
    const uint64_t now = srv_now();
    if (!s->stopping && now - s->pub.told_ns >= 50000000u) {
        s->pub.told_ns = now;
        srv_publish_status(s, FTM_WIRE_STATE_SYNCED);
    }
}

/* The keyframe carries the integrator's mode and the tissue parameters, so a
 * replica restoring it continues bit-identically whatever the guard does. */
bool srv_publish_keyframe(server *s)
{
    ftm_wire_msg m;
    memset(&m, 0, sizeof m);
    m.kind = FTM_WIRE_KEYFRAME;
    ftm_error err = {0, ""};
    if (ftm_replay_make_keyframe(s->tk.sim, &s->tk.mat, &m.u.keyframe, &err)) {
        srv_log(s, "error", "keyframe: %s", err.message);
        return false;
    }
    srv_send(s, &m, &s->pub.bytes_keyframes);
    s->pub.keyframes++;
    ftm_replay_keyframe_free(&m.u.keyframe);
    return true;
}

void srv_publish_frame(server *s, int32_t n, int32_t nreact, bool heartbeat)
{
    ftm_wire_msg m;
    memset(&m, 0, sizeof m);
    m.kind = FTM_WIRE_TICK;
    ftm_wire_tick *t = &m.u.tick;
    t->tick = s->tk.tick;
    t->depth = s->tk.depth;
    t->contact_count = n;
    t->contacts = s->tk.contacts;
    t->reaction_count = nreact;
    t->reactions = s->tk.reactions;
    t->state_hash = ftm_sim_hash(s->tk.sim);
    t->send_time_ns = (uint64_t)ftm_clock_real_ns();
    t->has_tissue = s->pub.tissue_frame;
    t->tissue = ftm_replay_tissue_now(&s->tk.mat);
    if (srv_send(s, &m, &s->pub.bytes_frames) == FTM_OK) {
        s->pub.frames++;
        s->pub.heartbeats += heartbeat;
    }
    s->pub.tissue_frame = false; /* sent or lost: a lost one makes replicas resync */
    s->pub.pub_n = n;
    s->pub.pub_depth = s->tk.depth;
    s->pub.pub_tick = s->tk.tick;
    s->pub.ring_ns[s->pub.ring_n % PUB_RING] = srv_now();
    s->pub.ring_tick[s->pub.ring_n % PUB_RING] = s->tk.tick;
    s->pub.ring_n++;
    s->pub.pub_ns = srv_now();
    s->pub.published_any = true;
}

/* Ticks a participant that has applied `applied` is behind: against the
 * newest frame published at least LAG_GRACE_NS ago (frames still in flight
 * are no lag; without the grace an idle scene's heartbeat sent just before
 * a status arrives would count as a heartbeat interval of lag). */
#define LAG_GRACE_NS 10000000u
int64_t srv_lag_of(const server *s, uint64_t applied)
{
    uint64_t limit = srv_now() - LAG_GRACE_NS, ref = 0;
    uint64_t n = s->pub.ring_n < PUB_RING ? s->pub.ring_n : PUB_RING;
    for (uint64_t k = 1; k <= n; k++) {
        uint64_t i = (s->pub.ring_n - k) % PUB_RING;
        if (s->pub.ring_ns[i] <= limit) {
            ref = s->pub.ring_tick[i];
            break;
        }
    }
    return ref > applied ? (int64_t)(ref - applied) : 0;
}


void srv_publish_tick_frame(server *s)
{
    if (!s->pub.published_any || s->pub.pub_tick != s->tk.tick)
        srv_publish_frame(s, 0, 0, true);
}

/* The most ticks between two frames while the session runs: --heartbeat
 * at the tick rate, rounded, at least 1 (0.1 s at 1 kHz: 100). */
uint64_t srv_heartbeat_ticks(const server *s)
{
    const double n = s->o.heartbeat * s->o.rate + 0.5;
    return n < 1.0 ? 1u : (uint64_t)n;
}

/* Idle ticks (no contacts now or in the last frame sent, no node updated,
 * depth and tissue unchanged) are not sent: replicas step them alone
 * (docs/protocol.md, "Ticks, heartbeats and replay"). */
void srv_publish_tick(server *s, int32_t n, int32_t nreact, bool moved)
{
    srv_publish *pb = &s->pub;
    const uint64_t now = srv_now();
    if (!pb->keyframe_due && now >= pb->next_keyframe_ns)
        pb->keyframe_due = true;
    const bool idle = n == 0 && !moved && pb->pub_n == 0 && pb->pub_depth == s->tk.depth &&
                      pb->published_any && !pb->tissue_frame;
    /* kept in ticks, not by the clock: a receiver can check it from the
     * frames alone (docs/protocol.md, "Ticks, heartbeats and replay") */
    const bool heartbeat = s->tk.tick - pb->pub_tick >= srv_heartbeat_ticks(s);
    if (!idle || heartbeat || pb->keyframe_due || pb->replaying)
        srv_publish_frame(s, n, nreact, idle);
    else
        pb->idle_ticks++;
    if (pb->keyframe_due && srv_publish_keyframe(s)) {
        pb->keyframe_due = false;
        pb->next_keyframe_ns = now + (uint64_t)(s->o.keyframe_every * 1e9);
    }
}
