/* SPDX-License-Identifier: GPL-3.0-or-later */
/* Who is in the session (rooms.h, participants.c): the table of
 * participants from their statuses, their probe input, and whose messages
 * are heard at all: one process per id, one server per session
 * (docs/server.md, Roles). */
#include "rooms.h"

#include <inttypes.h>
#include <stdlib.h>
#include <string.h>

/* Notes a process whose messages carry an id another process holds. A new
 * one is told at once (tell_now). */
static void note_ignored(server *s, uint32_t id, uint64_t origin)
{
    srv_parts *ps = &s->parts;
    const uint64_t now = srv_now();
    int slot = 0;
    for (int i = 0; i < FTM_WIRE_IGNORED_MAX; i++) {
        if (ps->ignored[i].last_ns && ps->ignored[i].id == id && ps->ignored[i].origin == origin) {
            ps->ignored[i].last_ns = now;
            return;
        }
        if (ps->ignored[i].last_ns < ps->ignored[slot].last_ns) /* a free or the oldest slot */
            slot = i;
    }
    /* all heard within a status period (more than 16 ignored processes):
     * this one waits for a slot rather than push out one just listed, which
     * would then come back, and so on, a status for every message */
    if (ps->ignored[slot].last_ns && now - ps->ignored[slot].last_ns < STATUS_PERIOD_NS)
        return;
    ps->ignored[slot].id = id;
    ps->ignored[slot].origin = origin;
    ps->ignored[slot].last_ns = now;
    srv_tell_now(s);
}

participant *srv_find_part(server *s, uint32_t id, bool create)
{
    participant *free_slot = NULL;
    for (int i = 0; i < MAX_PARTICIPANTS; i++) {
        if (s->parts.parts[i].used && s->parts.parts[i].id == id)
            return &s->parts.parts[i];
        if (!s->parts.parts[i].used && !free_slot)
            free_slot = &s->parts.parts[i];
    }
    if (!create || !free_slot)
        return NULL;
    memset(free_slot, 0, sizeof *free_slot);
    free_slot->report = -1;
    free_slot->used = true;
    free_slot->id = id;
    return free_slot;
}

void srv_release_probes(participant *p)
{
    for (int k = 0; k < MAX_PROBES; k++)
        memset(&p->probes[k], 0, sizeof p->probes[k]);
}

/* A trainee lost without leaving (silent past the status deadline, or its
 * lease expired): its probes are released, and kept with its id and
 * process for restore_lost. */
void srv_lose_probes(server *s, participant *p)
{
    srv_parts *ps = &s->parts;
    bool held = false;
    for (int k = 0; k < MAX_PROBES; k++)
        held |= p->probes[k].contact;
    if (held && p->role == FTM_WIRE_ROLE_TRAINEE && p->state != FTM_WIRE_STATE_LEAVING) {
        ps->lost[ps->lost_next].id = p->id;
        ps->lost[ps->lost_next].origin = p->origin;
        ps->lost[ps->lost_next].tick = s->tk.tick + 1;
        memcpy(ps->lost[ps->lost_next].probes, p->probes, sizeof p->probes);
        ps->lost_next = (ps->lost_next + 1) % (int)(sizeof ps->lost / sizeof ps->lost[0]);
    }
    srv_release_probes(p);
}

/* The same process back under its id after its lease expired (within 30 s
 * of ticks, so that --inputs decides alike): its probes as they were, the
 * contacts held; their next samples move them on. */
static void restore_lost(server *s, participant *p, uint64_t origin)
{
    srv_parts *ps = &s->parts;
    const uint64_t window = (uint64_t)(30.0 * s->o.rate);
    for (size_t i = 0; i < sizeof ps->lost / sizeof ps->lost[0]; i++) {
        if (!ps->lost[i].tick || ps->lost[i].id != p->id || ps->lost[i].origin != origin)
            continue;
        const bool recent = s->tk.tick + 1 - ps->lost[i].tick <= window;
        int held = 0;
        for (int k = 0; recent && k < MAX_PROBES; k++) {
            p->probes[k] = ps->lost[i].probes[k];
            p->probes[k].have_prev = false;
            held += p->probes[k].contact;
        }
        if (recent && held)
            srv_log(s, "info",
                    "participant %u: the same process is back %.2f s after its lease expired: "
                    "%d probe contact%s restored",
                    p->id, (double)(s->tk.tick + 1 - ps->lost[i].tick) / s->o.rate, held,
                    held > 1 ? "s" : "");
        ps->lost[i].tick = 0;
    }
}

void srv_on_status(server *s, ftm_wire_received *rx)
{
    if (rx->gone) {
        participant *p = srv_find_part(s, rx->sender, false);
        if (!p) {
            srv_log(s, "info", "participant %u gone", rx->sender);
            return;
        }
        srv_log(s, "info", "participant %u (%s '%s') gone: %s", p->id,
                ftm_wire_role_name(p->role), p->name,
                p->state == FTM_WIRE_STATE_LEAVING ? "left"
                                                  : "lost without leaving (lease expired)");
        srv_parts *ps = &s->parts;
        srv_lose_probes(s, p); /* (nothing left to keep if it went silent first) */
        p->used = false;
        ps->left[ps->left_next].id = p->id;
        ps->left[ps->left_next].tick = s->tk.tick + 1;
        ps->left_next = (ps->left_next + 1) % (int)(sizeof ps->left / sizeof ps->left[0]);
        return;
    }
    const ftm_wire_status *st = &rx->msg.u.status;
    if (st->participant != rx->sender) {
        srv_log(s, "warn", "status from %u names participant %u: ignored", rx->sender,
                st->participant);
        return;
    }
    participant *p = srv_find_part(s, rx->sender, true);
    if (!p) {
        srv_log(s, "warn", "participant %u: table full (%d), ignored", rx->sender, MAX_PARTICIPANTS);
        return;
    }
    if (!p->origin && rx->origin) {
        /* its id is now this process's (admit). One that was ignored while
         * another held the id is heard from now on: off the list. Either
         * way it is told at once that it holds the id (ftm_replay_id_held) */
        p->origin = rx->origin;
        for (int i = 0; i < FTM_WIRE_IGNORED_MAX; i++)
            if (s->parts.ignored[i].last_ns && s->parts.ignored[i].id == p->id &&
                s->parts.ignored[i].origin == rx->origin) {
                s->parts.ignored[i].last_ns = 0;
                srv_log(s, "info", "participant %u: the process that held the id is gone; the one "
                        "ignored until now is heard", p->id);
            }
        srv_tell_now(s);
    }
    bool fresh = p->role == 0;
    /* the tick is the participant's own, the last it applied: a joiner has
     * none yet */
    if ((fresh || p->state != st->state || p->role != st->role) &&
        st->state == FTM_WIRE_STATE_JOINING)
        srv_log(s, "info", "participant %u (%s '%s'): joining at server tick %" PRIu64, rx->sender,
                ftm_wire_role_name(st->role), st->name, s->tk.tick);
    else if (fresh || p->state != st->state || p->role != st->role)
        srv_log(s, "info", "participant %u (%s '%s'): %s, its last applied tick %" PRIu64,
                rx->sender, ftm_wire_role_name(st->role), st->name, ftm_wire_state_name(st->state),
                st->last_applied_tick);
    if (!fresh && p->role != st->role) {
        srv_release_probes(p);
    }
    const bool back = fresh || p->silent; /* after a `gone`, or silent past the deadline */
    if (p->silent)
        srv_log(s, "info", "participant %u (%s '%s') is back", p->id, ftm_wire_role_name(st->role),
                st->name);
    p->silent = false;
    p->last_status_ns = srv_now();
    p->role = st->role;
    p->state = st->state;
    p->last_tick = st->last_applied_tick;
    p->hash = st->state_hash;
    /* lag against the frames it could have applied by now */
    p->lag = srv_lag_of(s, st->last_applied_tick);
    p->replay_ns = st->replay_ns_per_tick;
    snprintf(p->name, sizeof p->name, "%s", st->name);
    p->report = ftm_report_seen(&s->rec.report, p->id, ftm_wire_role_name(p->role), p->name, s->tk.tick);
    if (back && p->role == FTM_WIRE_ROLE_TRAINEE && st->state != FTM_WIRE_STATE_LEAVING)
        restore_lost(s, p, rx->origin);
    if (st->state == FTM_WIRE_STATE_JOINING || st->state == FTM_WIRE_STATE_RESYNCING)
        s->pub.keyframe_due = true;
    if (st->state == FTM_WIRE_STATE_LEAVING) {
        srv_release_probes(p);
        /* the id is free: the next process heard with it claims it (another
         * one using it may stay on; its status keeps the DDS instance
         * alive, so no `gone` comes to free the entry) */
        p->origin = 0;
    }
}

void srv_reject(server *s, participant *p, uint32_t id, const char *what, const char *why)
{
    uint64_t n = p ? ++p->rejected : ++s->parts.rejected_unknown;
    if (n <= 3 || (n & (n - 1)) == 0) /* 1, 2, 3, 4, 8, 16, ... */
        srv_log(s, "warn", "%s from participant %u rejected (%" PRIu64 " so far): %s", what, id, n,
                why);
}

/* Whether id left the session (its `gone`) within the last 2 s of ticks. */
static bool just_left(const server *s, uint32_t id)
{
    const uint64_t window = (uint64_t)(2.0 * s->o.rate);
    const srv_parts *ps = &s->parts;
    for (size_t i = 0; i < sizeof ps->left / sizeof ps->left[0]; i++)
        if (ps->left[i].tick && ps->left[i].id == id && s->tk.tick + 1 - ps->left[i].tick <= window)
            return true;
    return false;
}

void srv_on_probe_input(server *s, ftm_wire_received *rx)
{
    participant *p = srv_find_part(s, rx->sender, false);
    /* input sent just before a trainee's LEAVING status (another topic) may
     * be taken after it, or after its departure: dropped without a warning,
     * which every orderly leave would otherwise log */
    if ((!p || p->role == 0) && just_left(s, rx->sender))
        return;
    if (!p || p->role == 0)
        { srv_reject(s, NULL, rx->sender, "probe input", "unknown participant (no status yet)"); return; }
    if (p->state == FTM_WIRE_STATE_LEAVING)
        return;
    if (p->role != FTM_WIRE_ROLE_TRAINEE)
        { srv_reject(s, p, rx->sender, "probe input", "only trainees may move tissue"); return; }
    if (p->silent)
        { srv_reject(s, p, rx->sender, "probe input", "participant missed its status deadline"); return; }
    const ftm_wire_probe_input *in = &rx->msg.u.probe_input;
    if (in->participant != rx->sender)
        { srv_reject(s, p, rx->sender, "probe input", "participant id differs from the sender"); return; }
    for (int32_t i = 0; i < in->sample_count; i++) {
        const ftm_wire_probe_sample *smp = &in->samples[i];
        if (smp->probe < 0 || smp->probe >= MAX_PROBES) {
            srv_reject(s, p, rx->sender, "probe sample", "probe index out of range 0..3");
            continue;
        }
        probe *pr = &p->probes[smp->probe];
        pr->hip = smp->position; /* samples are oldest first: the newest wins */
        pr->have = true;
    }
    p->inputs++;
    /* a trainee reports the newest frame it applied with every batch: a
     * lag measurement at the input rate, fresher than the status */
    if (in->last_tick_seen > 0)
        p->lag = srv_lag_of(s, in->last_tick_seen);
}

/* Another ftm-server's status on this session: every participant would
 * follow two streams of frames. The one that started later stops (exit 3;
 * displaced):
 * at the same rate it has run fewer ticks than the other's status, which is
 * at most a status period old, so the older one never finds itself behind. */
static void other_server(server *s, const ftm_wire_status *st)
{
    if (s->stopping || s->parts.displaced)
        return;
    if (s->tk.tick < st->last_applied_tick) {
        srv_log(s, "error",
                "session '%s' on domain %u is already served by another ftm-server ('%s', at "
                "tick %" PRIu64 "; this one at %" PRIu64 "): stopping this one",
                s->o.session, s->o.domain, st->name, st->last_applied_tick, s->tk.tick);
        s->parts.displaced = true;
        /* the other server is there, but may not have matched our status
         * writer yet (we heard it within a millisecond of starting): wait
         * for that, so that our LEAVING status tells it someone tried */
        ftm_error err = {0, ""};
        if (ftm_wire_wait_matched(s->pub.wire, FTM_WIRE_STATUS, 1, 1000000000LL, &err))
            srv_log(s, "warn", "the other server did not match our status in 1 s: %s", err.message);
        /* (the loop shuts down when this drain is over) */
    } else if (!s->parts.other_server_told) {
        srv_log(s, "error",
                "another ftm-server ('%s', at tick %" PRIu64 ") joined session '%s' on domain %u; "
                "it should stop, as it started later: its messages are ignored here",
                st->name, st->last_applied_tick, s->o.session, s->o.domain);
        s->parts.other_server_told = true;
    }
}

/* Whether a message is listened to. An id belongs to the process (DDS
 * participant) of the first status that claimed it until it is gone: a second process with the
 * same id (a copied --id) would otherwise be merged with the first, its
 * probe jumping between them. The server's own id is no participant's, and
 * another server's status stops one of the two (other_server). What is not
 * listened to is not recorded either, so a replay sees what the session did. */
bool srv_admit(server *s, int kind, const ftm_wire_received *rx)
{
    if (kind == FTM_WIRE_STATUS && !rx->gone &&
        rx->msg.u.status.role == FTM_WIRE_ROLE_SERVER) {
        other_server(s, &rx->msg.u.status);
        return false;
    }
    if (rx->sender == s->o.id) {
        if (rx->gone) /* a server that stopped (other_server) */
            return false;
        if (s->parts.own_id_msgs++ % 1000 == 0)
            srv_log(s, "error", "%s from participant %u, the server's own id (%" PRIu64 " so far): "
                    "ignored; give each participant its own --id", ftm_wire_kind_name(kind),
                    rx->sender, s->parts.own_id_msgs);
        return false;
    }
    participant *p = srv_find_part(s, rx->sender, false);
    if (!p || !p->origin || !rx->origin || rx->origin == p->origin)
        return true;
    if (!rx->gone)
        note_ignored(s, rx->sender, rx->origin);
    if (p->impostor_msgs++ % 1000 == 0)
        srv_log(s, "error", "participant %u (%s '%s'): a second process uses this id (%s, %" PRIu64
                " messages so far): ignored; give each participant its own --id",
                p->id, ftm_wire_role_name(p->role), p->name, ftm_wire_kind_name(kind),
                p->impostor_msgs);
    return false;
}

/* Statuses come every 500 ms (docs/protocol.md): a participant silent for
 * the status deadline (2 s) is taken as lost, its probes released. DDS also
 * reports a vanished participant (a `gone` status event, srv_on_status), but
 * that was not observed for a SIGKILLed process with Cyclone 0.10.2 here, so
 * the server does not rely on it alone. */
void srv_check_statuses(server *s)
{
    uint64_t now = srv_now();
    for (int i = 0; i < MAX_PARTICIPANTS; i++) {
        participant *p = &s->parts.parts[i];
        if (!p->used || p->silent || now - p->last_status_ns <= STATUS_DEADLINE_NS)
            continue;
        p->silent = true;
        srv_log(s, "warn",
                "participant %u (%s '%s') lost: no status for %.1f s (deadline 2 s); its probes "
                "are released",
                p->id, ftm_wire_role_name(p->role), p->name, (double)(now - p->last_status_ns) * 1e-9);
        srv_lose_probes(s, p);
        p->origin = 0; /* the id is free for the next process heard (on_status) */
        /* a decision by the clock: recorded, so that a replay makes it too */
        srv_record_entry(s, true, FTM_WIRE_STATUS, p->id, NULL, 0, false, true);
    }
}
