/* SPDX-License-Identifier: GPL-3.0-or-later */
/* ftm-conform: a passive participant written from the contract alone
 * (docs/protocol.md and proto/: the protobuf-c code of proto/ftm.proto, the
 * envelope type idlc makes of proto/ftm_envelope.idl) and Cyclone DDS's C
 * API; it links neither ftm_wire nor the session code nor libftm. It joins
 * a live session, writes nothing, and checks what it receives against the
 * documented rules; each rule is printed with its count and PASS or FAIL,
 * and the exit status is 1 if any failed (2: bad usage or no session).
 *
 *   ftm-conform --domain D --session S --seconds T --rate HZ
 *               [--heartbeat S] [--keyframe-every S] [--status-slack S]
 *               [--from-start] [--participants N]
 *
 * The Cyclone configuration comes from CYCLONEDDS_URI. --heartbeat and
 * --keyframe-every are the server's (defaults 0.1 and 1 s); --from-start:
 * this participant was up before the server, so the first keyframe it gets
 * is the one of tick 0; --participants: the non-server participants that
 * must be seen (their statuses, a LEAVING, their place in the holder list). */
#include "ftm/v1/ftm.pb-c.h"
#include "ftm_envelope.h"

#include <dds/dds.h>
#include <dds/ddsi/ddsi_serdata.h>

#include <inttypes.h>
#include <math.h>
#include <stdarg.h>
#include <stdbool.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <time.h>

#define NKIND 8
#define MAXP 64        /* senders tracked */
#define MAXW 256       /* writers (publication handles) tracked */
#define MAXF 200000    /* frames and keyframes remembered */
#define MAXC 1024      /* commands and replies remembered */
#define SEC 1000000000LL

static const char *const topic_of[NKIND] = {
    NULL, "ftm_v1_scene_announce", "ftm_v1_probe_input", "ftm_v1_tick_frame", "ftm_v1_keyframe",
    "ftm_v1_participant_status", "ftm_v1_session_control", "ftm_v1_control_reply"};
static const ProtobufCMessageDescriptor *const desc_of[NKIND] = {
    NULL,
    &ftm__v1__scene_announce__descriptor,
    &ftm__v1__probe_input__descriptor,
    &ftm__v1__tick_frame__descriptor,
    &ftm__v1__keyframe__descriptor,
    &ftm__v1__participant_status__descriptor,
    &ftm__v1__session_control__descriptor,
    &ftm__v1__control_reply__descriptor};

/* ---- rules: each counts the cases checked and the failures ------------------------------- */

enum {
    R_QOS, R_REPR, R_SESSION, R_KIND, R_VERSION, R_PRESENCE, R_SEQ, R_IDS, R_ORIGIN_STABLE,
    R_TICK_ORDER, R_TICK_ZERO, R_HEARTBEAT, R_PAUSE, R_NODE_RANGE, R_CONTACT_UNIQUE,
    R_KF_START, R_KF_PERIOD, R_KF_FRAME, R_KF_NODES, R_REPLY_FIELDS, R_REPLY_ONE, R_STATUS_PERIOD,
    R_JOINING, R_HOLDER_ORIGIN, R_HOLDER_ALL, R_SERVER_LISTS, R_LEAVING, R_TEXT, R_LATE, R_NRULES
};
static const char *const rule_text[R_NRULES] = {
    [R_QOS] = "each writer's QoS is the topic's row of the table (reliability, durability, history, deadline, liveliness)",
    [R_REPR] = "the envelope is XCDR1: writers offer it; an announcement's bytes are laid out as documented",
    [R_SESSION] = "envelope session is ours (a session of its own on the domain)",
    [R_KIND] = "envelope kind matches its topic",
    [R_VERSION] = "payload decodes and carries version = 1",
    [R_PRESENCE] = "every field the docs require is present (per message)",
    [R_SEQ] = "seq per (sender, kind) is 1, 2, 3, ... without gaps (tick frames, control, replies; others: increasing)",
    [R_IDS] = "sender non-zero; payload ids equal the envelope sender",
    [R_ORIGIN_STABLE] = "one origin (DDS participant) per sender id",
    [R_TICK_ORDER] = "tick frames' ticks strictly increase",
    [R_TICK_ZERO] = "no tick frame of tick 0 (frames start at tick 1)",
    [R_HEARTBEAT] = "consecutive frames at most H = round(heartbeat x rate) ticks apart",
    [R_PAUSE] = "no tick frame beyond the paused tick while paused; frames again after resume",
    [R_NODE_RANGE] = "node indices below the announced node_count; contact columns agree",
    [R_CONTACT_UNIQUE] = "a node appears at most once among a frame's or keyframe's contacts",
    [R_KF_START] = "a keyframe of tick 0 (no nodes, no contacts) at start",
    [R_KF_PERIOD] = "keyframes at least every keyframe-every x rate ticks (+25 %)",
    [R_KF_FRAME] = "keyframe K: frame K sent; same hash and contacts as a set (or a reset at K)",
    [R_KF_NODES] = "keyframe nodes strictly ascending, 3 values per node",
    [R_REPLY_FIELDS] = "control reply: outcome 1..3, reason for CHANGED/REFUSED, <= 127 bytes",
    [R_REPLY_ONE] = "exactly one reply per command heard, to its issuer and command_id",
    [R_STATUS_PERIOD] = "statuses at most 500 ms apart (+ slack; 1 s after the JOINING sent on joining)",
    [R_JOINING] = "a participant's first second: JOINING statuses only, at most two",
    [R_HOLDER_ORIGIN] = "server's holder_origin = origin computed from that participant's GUID",
    [R_HOLDER_ALL] = "every participant is listed among the holders with its origin",
    [R_SERVER_LISTS] = "holder/ignored lists: server only, ids unique, <= 64 / <= 16 pairs",
    [R_LEAVING] = "every participant and the server end with a LEAVING status",
    [R_TEXT] = "names and reasons: within their byte limits, no control characters",
    [R_LATE] = "TRANSIENT_LOCAL: a reader made mid-session gets the newest announcement, keyframe and statuses, written before it existed",
};
static uint64_t checked[R_NRULES], failed[R_NRULES];

static void check(int rule, bool ok, const char *fmt, ...) __attribute__((format(printf, 3, 4)));
static void check(int rule, bool ok, const char *fmt, ...)
{
    checked[rule]++;
    if (ok)
        return;
    if (++failed[rule] <= 5) {
        char buf[512];
        va_list ap;
        va_start(ap, fmt);
        vsnprintf(buf, sizeof buf, fmt, ap);
        va_end(ap);
        fprintf(stderr, "ftm-conform: FAIL %s: %s\n", rule_text[rule], buf);
    }
}

/* ---- the origin, as docs/protocol.md defines it -------------------------------------------- */

static uint64_t origin_of(const dds_guid_t *g)
{
    uint64_t h = 14695981039346656037u; /* FNV-1a 64 offset basis */
    for (int i = 0; i < 16; i++) {
        h ^= g->v[i];
        h *= 1099511628211u; /* FNV prime */
    }
    h ^= h >> 33;
    h *= 0xff51afd7ed558ccdu;
    h ^= h >> 33;
    return h == 0 ? 1 : h;
}

/* ---- state ---------------------------------------------------------------------------------- */

typedef struct {
    dds_instance_handle_t handle;
    uint64_t origin;
    int kind;
} writer_t;

typedef struct {
    uint32_t id;
    uint64_t origin;
    int role;
    uint64_t seq[NKIND];
    bool seen[NKIND];
    int64_t first_status, last_status; /* source time */
    bool joining; /* every status so far a JOINING of the first second */
    int joinings_first_second, statuses_first_second;
    int64_t next_joining; /* the second JOINING, after the first */
    int64_t max_gap;
    bool leaving;
    bool held; /* listed by the server with its origin */
} sender_t;

typedef struct {
    uint64_t tick, hash, digest;
    uint32_t ncontacts, nnodes;
    int64_t t;
} frame_t;

typedef struct {
    uint32_t issuer;
    uint64_t command_id;
    int command;
    int replies;
    uint64_t reply_tick;
} command_t;

static struct {
    uint32_t session_len;
    const char *session;
    double rate, heartbeat, keyframe_every, status_slack;
    bool from_start;
    int participants;
    writer_t writers[MAXW];
    int nwriters;
    sender_t senders[MAXP];
    int nsenders;
    uint32_t server_id;
    uint32_t node_count;
    bool have_announce, paused;
    uint64_t paused_tick;
    int pauses, resumes;
    uint64_t frames_after_resume;
    frame_t *frames, *keyframes;
    int nframes, nkeyframes;
    command_t cmds[MAXC];
    int ncmds;
    struct {
        uint32_t issuer;
        uint64_t command_id, tick;
    } replies[MAXC];
    int nreplies;
    uint64_t received[NKIND], other_session, gone_events, replaced;
    int64_t max_frame_wall_gap, last_frame_arrival;
    uint64_t last_frame_tick;
    bool have_frame, paused_since_frame;
    uint64_t max_tick_gap;
    bool server_leaving;
    int64_t server_leaving_at;
} S;

static int64_t mono_ns(void)
{
    struct timespec ts;
    clock_gettime(CLOCK_MONOTONIC, &ts);
    return (int64_t)ts.tv_sec * SEC + ts.tv_nsec;
}

static sender_t *sender(uint32_t id)
{
    for (int i = 0; i < S.nsenders; i++)
        if (S.senders[i].id == id)
            return &S.senders[i];
    if (S.nsenders == MAXP)
        return NULL;
    sender_t *s = &S.senders[S.nsenders++];
    memset(s, 0, sizeof *s);
    s->id = id;
    return s;
}

/* ---- QoS of a matched writer ----------------------------------------------------------------- */

static void check_qos(int kind, const dds_qos_t *q, uint32_t sender_id)
{
    dds_reliability_kind_t rel;
    dds_duration_t blocking;
    dds_durability_kind_t dur;
    dds_history_kind_t hist;
    int32_t depth;
    dds_liveliness_kind_t live;
    dds_duration_t lease;
    dds_duration_t deadline = DDS_INFINITY;
    bool ok = dds_qget_reliability(q, &rel, &blocking) && dds_qget_durability(q, &dur) &&
              dds_qget_history(q, &hist, &depth) && dds_qget_liveliness(q, &live, &lease);
    if (!ok) {
        check(R_QOS, false, "%s: writer of %u: QoS not readable", topic_of[kind], sender_id);
        return;
    }
    (void)dds_qget_deadline(q, &deadline);
    const bool tl = kind == 1 || kind == 4 || kind == 5;
    const dds_reliability_kind_t want_rel = kind == 2 ? DDS_RELIABILITY_BEST_EFFORT : DDS_RELIABILITY_RELIABLE;
    const int32_t want_depth = kind == 1 || kind == 4 || kind == 5 ? 1 : kind == 3 ? 256 : 64;
    const dds_duration_t want_deadline = kind == 5 ? DDS_SECS(2) : DDS_INFINITY;
    check(R_QOS,
          rel == want_rel && dur == (tl ? DDS_DURABILITY_TRANSIENT_LOCAL : DDS_DURABILITY_VOLATILE) &&
              hist == DDS_HISTORY_KEEP_LAST && depth == want_depth && live == DDS_LIVELINESS_AUTOMATIC &&
              deadline == want_deadline,
          "%s: writer of %u: reliability %d durability %d history %d/%d liveliness %d deadline %" PRId64,
          topic_of[kind], sender_id, (int)rel, (int)dur, (int)hist, (int)depth, (int)live, deadline);
    uint32_t n = 0;
    dds_data_representation_id_t *v = NULL;
    if (dds_qget_data_representation(q, &n, &v)) {
        check(R_REPR, n >= 1 && v[0] == DDS_DATA_REPRESENTATION_XCDR1,
              "%s: writer of %u offers %u representations, the first %d", topic_of[kind], sender_id,
              n, n ? (int)v[0] : -1);
        dds_free(v);
    } else {
        /* absent from the discovery data: XCDR1, the DDS default */
        check(R_REPR, true, "%s", "");
    }
}

/* The origin of a sample's writer (and its QoS, checked once per writer). */
static uint64_t writer_origin(dds_entity_t reader, int kind, dds_instance_handle_t h, uint32_t sender_id)
{
    for (int i = 0; i < S.nwriters; i++)
        if (S.writers[i].handle == h)
            return S.writers[i].origin;
    dds_builtintopic_endpoint_t *ep = dds_get_matched_publication_data(reader, h);
    if (!ep)
        return 0;
    uint64_t o = origin_of(&ep->participant_key);
    check_qos(kind, ep->qos, sender_id);
    dds_builtintopic_free_endpoint(ep);
    if (S.nwriters < MAXW)
        S.writers[S.nwriters++] = (writer_t){h, o, kind};
    return o;
}

/* ---- field checks ---------------------------------------------------------------------------- */

static bool vec3_ok(const Ftm__V1__Vec3 *v)
{
    return v && v->has_x && v->has_y && v->has_z && isfinite(v->x) && isfinite(v->y) && isfinite(v->z);
}

static bool tissue_ok(const Ftm__V1__TissueParams *t)
{
    return t && t->has_node_mass && t->has_node_damping && t->has_stiffness && vec3_ok(t->axis_scale);
}

static bool text_ok(const char *s, size_t max)
{
    if (!s)
        return true; /* absent: empty */
    size_t n = strlen(s);
    for (size_t i = 0; i < n; i++)
        if ((unsigned char)s[i] < 0x20 || s[i] == 0x7f)
            return false;
    return n <= max;
}

/* Contacts as a set: an order-free digest of (node, group, kind, value bits). */
static uint64_t contacts_digest(size_t n, const uint32_t *node, const uint32_t *group,
                                const Ftm__V1__ContactKind *kind, const double *value, bool *unique)
{
    uint64_t sum = 0;
    *unique = true;
    for (size_t i = 0; i < n; i++) {
        for (size_t j = 0; j < i; j++)
            if (node[j] == node[i])
                *unique = false;
        uint64_t h = 1469598103934665603u;
        uint64_t parts[6] = {node[i], group[i], (uint64_t)kind[i], 0, 0, 0};
        memcpy(&parts[3], &value[3 * i], 3 * sizeof(double));
        for (int k = 0; k < 6; k++) {
            h ^= parts[k];
            h *= 1099511628211u;
            h ^= h >> 29;
        }
        sum += h; /* commutative: order does not matter */
    }
    return sum;
}

static bool columns_ok(size_t n, size_t ng, size_t nk, size_t nv, const uint32_t *node)
{
    if (ng != n || nk != n || nv != 3 * n)
        return false;
    for (size_t i = 0; i < n; i++)
        if (S.have_announce && node[i] >= S.node_count)
            return false;
    return true;
}

/* ---- per kind -------------------------------------------------------------------------------- */

static void on_announce(const Ftm__V1__SceneAnnounce *a, uint32_t from)
{
    bool ok = a->scene_id && a->scene_id[0] && strlen(a->scene_id) <= 127 && a->has_content_digest &&
              a->content_digest.len >= 1 && a->content_digest.len <= 64 && a->has_tick_rate_hz &&
              a->tick_rate_hz > 0 && a->has_time_step && a->has_depth && a->depth_limits &&
              a->depth_limits->has_min && a->depth_limits->has_max && tissue_ok(a->tissue) &&
              a->has_node_count && a->has_tick && a->has_paused;
    check(R_PRESENCE, ok, "announce from %u lacks a required field", from);
    if (!ok)
        return;
    S.server_id = from;
    S.node_count = a->node_count;
    if (a->paused && !S.paused) {
        S.pauses++;
        S.paused_since_frame = true;
        S.paused_tick = a->tick;
    } else if (!a->paused && S.paused) {
        S.resumes++;
        check(R_PAUSE, a->tick == S.paused_tick, "resumed at tick %" PRIu64 ", paused at %" PRIu64,
              a->tick, S.paused_tick);
    }
    S.paused = a->paused;
    S.have_announce = true;
}

static void on_probe(const Ftm__V1__ProbeInput *p, uint32_t from)
{
    bool ok = p->has_participant_id && p->has_last_tick_seen && p->n_samples <= 4096;
    for (size_t i = 0; ok && i < p->n_samples; i++)
        ok = p->samples[i]->has_probe && p->samples[i]->has_device_time_ns &&
             vec3_ok(p->samples[i]->position);
    check(R_PRESENCE, ok, "probe input from %u lacks a required field", from);
    check(R_IDS, p->participant_id == from, "probe input participant_id %u from sender %u",
          p->participant_id, from);
}

static void on_tick(const Ftm__V1__TickFrame *f, uint32_t from, int64_t arrival)
{
    bool ok = f->has_tick && f->has_depth && f->has_state_hash;
    for (size_t i = 0; ok && i < f->n_reactions; i++) {
        const Ftm__V1__ProbeReaction *r = f->reactions[i];
        ok = r->has_group && r->has_participant_id && r->has_probe && vec3_ok(r->force) &&
             (r->n_stiffness == 0) == (r->hip == NULL) && (r->n_stiffness == 0 || r->n_stiffness == 9) &&
             (r->contact_point == NULL) == (r->contact_normal == NULL);
    }
    check(R_PRESENCE, ok, "tick frame from %u lacks a required field", from);
    if (!ok)
        return;
    check(R_NODE_RANGE, columns_ok(f->n_contact_node, f->n_contact_group, f->n_contact_kind,
                                   f->n_contact_value, f->contact_node),
          "tick frame %" PRIu64 ": contact columns or node range", f->tick);
    bool unique;
    uint64_t digest = 0;
    if (f->n_contact_group == f->n_contact_node && f->n_contact_kind == f->n_contact_node &&
        f->n_contact_value == 3 * f->n_contact_node) {
        digest = contacts_digest(f->n_contact_node, f->contact_node, f->contact_group,
                                 f->contact_kind, f->contact_value, &unique);
        check(R_CONTACT_UNIQUE, unique, "tick frame %" PRIu64 " lists a node twice", f->tick);
    }
    check(R_TICK_ZERO, f->tick != 0, "a tick frame of tick 0");
    if (S.have_frame) {
        check(R_TICK_ORDER, f->tick > S.last_frame_tick, "frame tick %" PRIu64 " after %" PRIu64,
              f->tick, S.last_frame_tick);
        const uint64_t gap = f->tick - S.last_frame_tick;
        const uint64_t h = (uint64_t)llround(S.heartbeat * S.rate) < 1 ? 1 : (uint64_t)llround(S.heartbeat * S.rate);
        check(R_HEARTBEAT, f->tick > S.last_frame_tick && gap <= h,
              "frames of ticks %" PRIu64 " and %" PRIu64 ": %" PRIu64 " ticks apart (H = %" PRIu64 ")",
              S.last_frame_tick, f->tick, gap, h);
        if (f->tick > S.last_frame_tick && gap > S.max_tick_gap)
            S.max_tick_gap = gap;
        if (!S.paused_since_frame && arrival - S.last_frame_arrival > S.max_frame_wall_gap)
            S.max_frame_wall_gap = arrival - S.last_frame_arrival;
    }
    /* (a frame of the paused tick itself may still be on its way) */
    if (S.paused)
        check(R_PAUSE, f->tick <= S.paused_tick, "frame of tick %" PRIu64 " while paused at %" PRIu64,
              f->tick, S.paused_tick);
    else if (S.resumes)
        S.frames_after_resume++;
    S.have_frame = true;
    S.paused_since_frame = S.paused;
    S.last_frame_tick = f->tick;
    S.last_frame_arrival = arrival;
    if (S.nframes < MAXF)
        S.frames[S.nframes++] = (frame_t){f->tick, f->state_hash, digest, (uint32_t)f->n_contact_node, 0, arrival};
}

static void on_keyframe(const Ftm__V1__Keyframe *k, uint32_t from, int64_t arrival)
{
    bool ok = k->has_tick && k->has_state_hash && k->has_node_count && k->has_depth &&
              (!k->tissue || tissue_ok(k->tissue));
    if (ok && k->mode)
        ok = k->mode->has_substeps && k->mode->has_steps_at_substeps && k->mode->has_quiet_steps &&
             k->mode->has_region_sleeping && k->mode->has_energy_budget && k->mode->has_energy_prev;
    check(R_PRESENCE, ok, "keyframe from %u lacks a required field", from);
    if (!ok)
        return;
    bool asc = k->n_position == 3 * k->n_node && k->n_previous == 3 * k->n_node;
    for (size_t i = 0; asc && i < k->n_node; i++)
        asc = (i == 0 || k->node[i] > k->node[i - 1]) && k->node[i] < k->node_count;
    check(R_KF_NODES, asc, "keyframe %" PRIu64 ": nodes not strictly ascending or columns", k->tick);
    check(R_NODE_RANGE, columns_ok(k->n_contact_node, k->n_contact_group, k->n_contact_kind,
                                   k->n_contact_value, k->contact_node),
          "keyframe %" PRIu64 ": contact columns or node range", k->tick);
    bool unique = true;
    uint64_t digest = 0;
    if (k->n_contact_group == k->n_contact_node && k->n_contact_kind == k->n_contact_node &&
        k->n_contact_value == 3 * k->n_contact_node) {
        digest = contacts_digest(k->n_contact_node, k->contact_node, k->contact_group,
                                 k->contact_kind, k->contact_value, &unique);
        check(R_CONTACT_UNIQUE, unique, "keyframe %" PRIu64 " lists a node twice", k->tick);
    }
    if (S.nkeyframes < MAXF)
        S.keyframes[S.nkeyframes++] = (frame_t){k->tick, k->state_hash, digest,
                                                (uint32_t)k->n_contact_node, (uint32_t)k->n_node, arrival};
}

static void on_status(const Ftm__V1__ParticipantStatus *st, uint32_t from, uint64_t origin,
                      int64_t src_time)
{
    bool ok = st->has_participant_id && st->has_role && st->role >= 1 && st->role <= 5 &&
              st->has_state && st->state >= 1 && st->state <= 4 && st->has_last_applied_tick &&
              st->has_state_hash && st->has_replay_ns_per_tick && st->has_replay_ns_max;
    check(R_PRESENCE, ok, "status from %u lacks a required field", from);
    check(R_IDS, st->participant_id == from, "status participant_id %u from sender %u",
          st->participant_id, from);
    check(R_TEXT, text_ok(st->name, 63), "status name of %u", from);
    if (!ok)
        return;
    const bool server = st->role == FTM__V1__ROLE__ROLE_SERVER;
    bool lists = st->n_holder_participant == st->n_holder_origin &&
                 st->n_ignored_participant == st->n_ignored_origin &&
                 st->n_holder_participant <= 64 && st->n_ignored_participant <= 16 &&
                 (server || (st->n_holder_participant == 0 && st->n_ignored_participant == 0));
    for (size_t i = 0; lists && i < st->n_holder_participant; i++)
        for (size_t j = 0; j < i; j++)
            if (st->holder_participant[j] == st->holder_participant[i])
                lists = false;
    check(R_SERVER_LISTS, lists, "status of %u (role %d): holder/ignored lists", from, (int)st->role);
    sender_t *s = sender(from);
    if (!s)
        return;
    s->role = st->role;
    if (s->first_status) {
        const int64_t gap = src_time - s->last_status;
        /* the JOINING sent on joining may stand alone for a second, and so
         * may the (at most two) JOINING statuses of that second: the next
         * one is due 1 s after the first, not 500 ms after the second */
        int64_t limit = SEC / 2;
        if (s->joining && s->first_status + SEC - s->last_status > limit)
            limit = s->first_status + SEC - s->last_status;
        limit += (int64_t)(S.status_slack * 1e9);
        if (st->state != FTM__V1__PARTICIPANT_STATE__STATE_LEAVING)
            check(R_STATUS_PERIOD, gap <= limit,
                  "statuses of %u %.1f ms apart (limit %.1f ms), the second one %.3f s after its "
                  "first, state %d", from, (double)gap * 1e-6, (double)limit * 1e-6,
                  (double)(src_time - s->first_status) * 1e-9, (int)st->state);
        if (gap > s->max_gap && !s->joining)
            s->max_gap = gap;
        s->joining = s->joining && st->state == FTM__V1__PARTICIPANT_STATE__STATE_JOINING &&
                     src_time - s->first_status < SEC;
    } else {
        s->first_status = src_time;
        s->joining = st->state == FTM__V1__PARTICIPANT_STATE__STATE_JOINING;
    }
    s->last_status = src_time;
    if (st->state == FTM__V1__PARTICIPANT_STATE__STATE_JOINING && src_time != s->first_status &&
        (!s->next_joining || src_time - s->first_status < s->next_joining))
        s->next_joining = src_time - s->first_status;
    if (src_time - s->first_status < SEC) {
        s->statuses_first_second++;
        if (st->state == FTM__V1__PARTICIPANT_STATE__STATE_JOINING)
            s->joinings_first_second++;
    }
    if (st->state == FTM__V1__PARTICIPANT_STATE__STATE_LEAVING) {
        s->leaving = true;
        if (server) {
            S.server_leaving = true;
            S.server_leaving_at = mono_ns();
        }
    }
    if (!server)
        return;
    for (size_t i = 0; i < st->n_holder_participant; i++) {
        const sender_t *h = NULL;
        for (int j = 0; j < S.nsenders; j++)
            if (S.senders[j].id == st->holder_participant[i] && S.senders[j].origin)
                h = &S.senders[j];
        if (!h)
            continue; /* a participant this one has not heard (yet) */
        check(R_HOLDER_ORIGIN, st->holder_origin[i] == h->origin,
              "holder %u: origin %016" PRIx64 " in the server's status, %016" PRIx64 " computed",
              h->id, st->holder_origin[i], h->origin);
        if (st->holder_origin[i] == h->origin)
            ((sender_t *)h)->held = true;
    }
    (void)origin;
}

static void on_control(const Ftm__V1__SessionControl *c, uint32_t from)
{
    bool ok = c->has_issuer_id && c->has_command_id &&
              c->command_case != FTM__V1__SESSION_CONTROL__COMMAND__NOT_SET;
    check(R_PRESENCE, ok, "session control from %u lacks a required field", from);
    check(R_IDS, c->issuer_id == from, "control issuer_id %u from sender %u", c->issuer_id, from);
    if (ok && S.ncmds < MAXC)
        S.cmds[S.ncmds++] = (command_t){from, c->command_id, (int)c->command_case, 0, 0};
}

static void on_reply(const Ftm__V1__ControlReply *r, uint32_t from)
{
    bool ok = r->has_issuer_id && r->has_command_id && r->has_outcome && r->has_tick;
    check(R_PRESENCE, ok, "control reply from %u lacks a required field", from);
    if (!ok)
        return;
    const bool needs_reason = r->outcome == FTM__V1__CONTROL_OUTCOME__OUTCOME_CHANGED ||
                              r->outcome == FTM__V1__CONTROL_OUTCOME__OUTCOME_REFUSED;
    check(R_REPLY_FIELDS,
          r->outcome >= 1 && r->outcome <= 3 && (!needs_reason || (r->reason && r->reason[0])),
          "reply to %u/%" PRIu64 ": outcome %d reason '%s'", r->issuer_id, r->command_id,
          (int)r->outcome, r->reason ? r->reason : "(absent)");
    check(R_TEXT, text_ok(r->reason, 127), "reply reason to %u", r->issuer_id);
    if (S.nreplies < MAXC) {
        S.replies[S.nreplies].issuer = r->issuer_id;
        S.replies[S.nreplies].command_id = r->command_id;
        S.replies[S.nreplies++].tick = r->tick;
    }
}

/* ---- one sample ------------------------------------------------------------------------------ */

static void on_sample(dds_entity_t reader, int kind, const ftm_wire_Envelope *env,
                      const dds_sample_info_t *info, int64_t arrival)
{
    if (!info->valid_data) {
        S.gone_events++;
        return;
    }
    if (strncmp(env->session, S.session, sizeof env->session) != 0) {
        S.other_session++;
        check(R_SESSION, false, "a message of session '%.63s'", env->session);
        return;
    }
    check(R_SESSION, true, "%s", "");
    S.received[kind]++;
    check(R_KIND, env->kind == kind, "kind %d on topic %s", (int)env->kind, topic_of[kind]);
    check(R_IDS, env->sender != 0, "sender 0 on %s", topic_of[kind]);
    const uint64_t origin = writer_origin(reader, kind, info->publication_handle, env->sender);
    sender_t *s = sender(env->sender);
    if (s) {
        if (origin) {
            check(R_ORIGIN_STABLE, !s->origin || s->origin == origin,
                  "sender %u from two DDS participants", env->sender);
            if (!s->origin)
                s->origin = origin;
        }
        if (s->seen[kind]) {
            if (kind == 2 || kind == 1 || kind == 4 || kind == 5) {
                /* best effort (probe input), or KEEP_LAST 1 (announce,
                 * keyframe, status: a newer sample may replace one not yet
                 * repaired): losses allowed at the receiver, order kept */
                check(R_SEQ, env->seq > s->seq[kind], "%s of %u: seq %" PRIu64 " after %" PRIu64,
                      topic_of[kind], env->sender, env->seq, s->seq[kind]);
                if (env->seq > s->seq[kind] + 1)
                    S.replaced += env->seq - s->seq[kind] - 1;
            } else {
                check(R_SEQ, env->seq == s->seq[kind] + 1, "%s of %u: seq %" PRIu64 " after %" PRIu64,
                      topic_of[kind], env->sender, env->seq, s->seq[kind]);
            }
        } else {
            check(R_SEQ, env->seq >= 1, "%s of %u: seq 0", topic_of[kind], env->sender);
        }
        s->seen[kind] = true;
        s->seq[kind] = env->seq;
    }
    ProtobufCMessage *m = protobuf_c_message_unpack(desc_of[kind], NULL, env->payload._length,
                                                    env->payload._buffer);
    if (!m) {
        check(R_VERSION, false, "%s of %u seq %" PRIu64 ": does not decode", topic_of[kind],
              env->sender, env->seq);
        return;
    }
    /* version: field 1 of every top-level message */
    const ProtobufCFieldDescriptor *fd = protobuf_c_message_descriptor_get_field(desc_of[kind], 1);
    const protobuf_c_boolean has_version = *(const protobuf_c_boolean *)((const char *)m + fd->quantifier_offset);
    const uint32_t version = *(const uint32_t *)((const char *)m + fd->offset);
    check(R_VERSION, has_version && version == 1, "%s of %u seq %" PRIu64 ": version %s%u",
          topic_of[kind], env->sender, env->seq, has_version ? "" : "absent ", version);
    switch (kind) {
    case 1: on_announce((const void *)m, env->sender); break;
    case 2: on_probe((const void *)m, env->sender); break;
    case 3: on_tick((const void *)m, env->sender, arrival); break;
    case 4: on_keyframe((const void *)m, env->sender, arrival); break;
    case 5: on_status((const void *)m, env->sender, origin, info->source_timestamp); break;
    case 6: on_control((const void *)m, env->sender); break;
    case 7: on_reply((const void *)m, env->sender); break;
    default: break;
    }
    protobuf_c_message_free_unpacked(m, NULL);
}

/* ---- the end: rules over the whole run ------------------------------------------------------- */

static bool reset_at(uint64_t tick)
{
    for (int r = 0; r < S.nreplies; r++)
        for (int c = 0; c < S.ncmds; c++)
            if (S.cmds[c].issuer == S.replies[r].issuer && S.cmds[c].command_id == S.replies[r].command_id &&
                S.cmds[c].command == FTM__V1__SESSION_CONTROL__COMMAND_RESET && S.replies[r].tick == tick)
                return true;
    return false;
}

static void final_rules(void)
{
    /* keyframes: at start, periodic, consistent with their frames */
    if (S.from_start)
        check(R_KF_START, S.nkeyframes > 0 && S.keyframes[0].tick == 0 && S.keyframes[0].nnodes == 0 &&
                              S.keyframes[0].ncontacts == 0,
              "first keyframe: %s tick %" PRIu64, S.nkeyframes ? "" : "none,",
              S.nkeyframes ? S.keyframes[0].tick : 0);
    const double kf_limit = S.keyframe_every * S.rate * 1.25 + 2;
    for (int i = 1; i < S.nkeyframes; i++)
        check(R_KF_PERIOD, (double)(S.keyframes[i].tick - S.keyframes[i - 1].tick) <= kf_limit,
              "keyframes of ticks %" PRIu64 " and %" PRIu64 " (limit %.0f ticks)",
              S.keyframes[i - 1].tick, S.keyframes[i].tick, kf_limit);
    for (int i = 0; i < S.nkeyframes; i++) {
        const frame_t *k = &S.keyframes[i];
        if (k->tick == 0 || S.nframes == 0 || k->tick < S.frames[0].tick)
            continue; /* before the first frame this one heard */
        const frame_t *f = NULL;
        for (int j = 0; j < S.nframes && !f; j++)
            if (S.frames[j].tick == k->tick)
                f = &S.frames[j];
        if (!f) {
            check(R_KF_FRAME, false, "keyframe of tick %" PRIu64 " without a frame of that tick", k->tick);
            continue;
        }
        const bool same = f->hash == k->hash && f->digest == k->digest && f->ncontacts == k->ncontacts;
        const bool reset = reset_at(k->tick) && k->ncontacts == 0 && k->nnodes == 0;
        check(R_KF_FRAME, same || reset,
              "keyframe %" PRIu64 ": hash %016" PRIx64 " / frame %016" PRIx64 ", %u / %u contacts%s",
              k->tick, k->hash, f->hash, k->ncontacts, f->ncontacts, reset_at(k->tick) ? " (reset)" : "");
    }
    /* replies: one per command, nothing else */
    for (int c = 0; c < S.ncmds; c++) {
        int n = 0;
        for (int r = 0; r < S.nreplies; r++)
            n += S.replies[r].issuer == S.cmds[c].issuer && S.replies[r].command_id == S.cmds[c].command_id;
        check(R_REPLY_ONE, n == 1, "command %u/%" PRIu64 ": %d replies", S.cmds[c].issuer,
              S.cmds[c].command_id, n);
    }
    for (int r = 0; r < S.nreplies; r++) {
        int n = 0;
        for (int c = 0; c < S.ncmds; c++)
            n += S.replies[r].issuer == S.cmds[c].issuer && S.replies[r].command_id == S.cmds[c].command_id;
        check(R_REPLY_ONE, n == 1, "reply to %u/%" PRIu64 " for no command heard", S.replies[r].issuer,
              S.replies[r].command_id);
    }
    if (S.pauses)
        check(R_PAUSE, S.resumes == 0 || S.frames_after_resume > 0, "no frame after the resume");
    int others = 0;
    for (int i = 0; i < S.nsenders; i++) {
        const sender_t *s = &S.senders[i];
        if (!s->first_status)
            continue; /* no status heard (cannot be: everyone sends one) */
        check(R_LEAVING, s->leaving, "participant %u sent no LEAVING", s->id);
        /* (the server's own first status is SYNCED: it joins nobody) */
        if (s->role != FTM__V1__ROLE__ROLE_SERVER)
            check(R_JOINING, s->joinings_first_second <= 2 &&
                                 s->statuses_first_second == s->joinings_first_second,
                  "participant %u: %d statuses in its first second, %d of them JOINING (the "
                  "second JOINING %.1f ms after the first)", s->id, s->statuses_first_second,
                  s->joinings_first_second, (double)s->next_joining * 1e-6);
        if (s->role == FTM__V1__ROLE__ROLE_SERVER)
            continue;
        others++;
        check(R_HOLDER_ALL, s->held, "participant %u (origin %016" PRIx64 ") never listed as a holder",
              s->id, s->origin);
    }
    check(R_HOLDER_ALL, others >= S.participants, "%d participants heard, %d expected", others,
          S.participants);
    check(R_KF_PERIOD, S.nkeyframes >= 2, "%d keyframes", S.nkeyframes);
    check(R_HEARTBEAT, S.nframes >= 2, "%d frames", S.nframes);
}

/* ---- the encapsulation of a sample, as it travels ------------------------------------------- */

static uint32_t get_u32(const unsigned char *b, bool le)
{
    return le ? (uint32_t)b[0] | (uint32_t)b[1] << 8 | (uint32_t)b[2] << 16 | (uint32_t)b[3] << 24
              : (uint32_t)b[3] | (uint32_t)b[2] << 8 | (uint32_t)b[1] << 16 | (uint32_t)b[0] << 24;
}

/* An announcement's bytes as docs/protocol.md lays them out (XCDR1, plain
 * CDR): the encapsulation header, then session, sender, kind, seq (8-aligned)
 * and payload, the payload an ftm.v1.SceneAnnounce. */
static bool layout_ok(const unsigned char *b, size_t n)
{
    if (n < 4 || b[0] != 0 || b[1] > 1)
        return false;
    const bool le = b[1] == 1;
    const unsigned char *d = b + 4; /* alignment counts from here */
    size_t len = n - 4, off = 0;
    if (len < 4)
        return false;
    const uint32_t slen = get_u32(d, le);
    off = 4;
    if (slen < 1 || slen > 64 || off + slen > len || d[off + slen - 1] != 0 ||
        strcmp((const char *)d + off, S.session) != 0)
        return false;
    off += slen;
    off = (off + 3) & ~(size_t)3;
    if (off + 5 > len)
        return false;
    const uint32_t sender = get_u32(d + off, le);
    const unsigned kind = d[off + 4];
    off = (off + 5 + 7) & ~(size_t)7;
    if (off + 12 > len || sender == 0 || kind != 1)
        return false;
    const uint64_t seq = le ? (uint64_t)get_u32(d + off, true) | (uint64_t)get_u32(d + off + 4, true) << 32
                            : (uint64_t)get_u32(d + off + 4, false) | (uint64_t)get_u32(d + off, false) << 32;
    off += 8;
    const uint32_t plen = get_u32(d + off, le);
    off += 4;
    if (seq < 1 || plen > len - off || len - off - plen > 3)
        return false;
    ProtobufCMessage *m = protobuf_c_message_unpack(&ftm__v1__scene_announce__descriptor, NULL, plen, d + off);
    const bool ok = m && ((Ftm__V1__SceneAnnounce *)m)->has_version && ((Ftm__V1__SceneAnnounce *)m)->version == 1;
    if (m)
        protobuf_c_message_free_unpacked(m, NULL);
    return ok;
}

static void check_encapsulation(dds_entity_t raw)
{
    struct ddsi_serdata *sd[4] = {NULL};
    dds_sample_info_t info[4];
    dds_return_t n = dds_takecdr(raw, sd, 4, info, DDS_ANY_STATE);
    for (dds_return_t i = 0; i < n; i++) {
        const size_t size = ddsi_serdata_size(sd[i]);
        if (info[i].valid_data && size >= 4 && size <= 65536) {
            unsigned char buf[65536];
            ddsi_serdata_to_ser(sd[i], 0, size, buf);
            /* RTPS encapsulation identifier: 0x0000 CDR_BE, 0x0001 CDR_LE (XCDR1);
             * 0x0006 / 0x0007 CDR2 (XCDR2) */
            check(R_REPR, layout_ok(buf, size),
                  "an announcement of %zu bytes, encapsulation %02x %02x, not laid out as documented",
                  size, buf[0], buf[1]);
            static bool told;
            if (!told) {
                told = true;
                printf("ftm-conform: announce encapsulation identifier 0x%02x%02x (%s), %zu bytes\n",
                       buf[0], buf[1], buf[0] == 0 && buf[1] <= 1 ? "XCDR1, plain CDR" : "other", size);
            }
        }
        ddsi_serdata_unref(sd[i]);
    }
}

/* ---- the late-join path ----------------------------------------------------------------------- */

/* Two seconds into the session, once every participant's status came
 * (--participants), readers of the three TRANSIENT_LOCAL topics are made
 * anew, as a late joiner makes them. Within a second each must have, from
 * every sender, the newest sample the first readers had then (or a newer
 * one); and samples written before the new readers existed must come, which
 * no VOLATILE reader gets: each participant's status (one of them may have
 * been replaced by a newer one in the moment it took to match). */
static struct {
    dds_entity_t r[NKIND];
    int64_t made;
    dds_time_t made_at; /* the source timestamps' clock */
    bool done;
    uint64_t want_seq[NKIND][MAXP], got_seq[NKIND][MAXP];
    int historical[NKIND];
    uint32_t id[MAXP];
    int n;
} L;

static void late_joiner(dds_entity_t dp, const dds_entity_t *topics)
{
    const int64_t now = mono_ns();
    static int64_t first_seen;
    if (L.done || !S.have_announce || S.nkeyframes == 0)
        return;
    if (!first_seen)
        first_seen = now;
    if (!L.made) {
        int in = 0; /* participants whose status came */
        for (int i = 0; i < S.nsenders; i++)
            in += S.senders[i].first_status && S.senders[i].role != FTM__V1__ROLE__ROLE_SERVER;
        if (now - first_seen < 2 * SEC || in < S.participants || S.paused || S.server_leaving)
            return;
        L.n = S.nsenders;
        for (int i = 0; i < S.nsenders; i++) {
            L.id[i] = S.senders[i].id;
            for (int k = 1; k < NKIND; k++)
                L.want_seq[k][i] = S.senders[i].seen[k] && !S.senders[i].leaving ? S.senders[i].seq[k] : 0;
        }
        L.made_at = dds_time();
        for (int k = 1; k < NKIND; k++) {
            if (k != 1 && k != 4 && k != 5)
                continue;
            dds_qos_t *q = dds_create_qos();
            dds_qset_reliability(q, DDS_RELIABILITY_RELIABLE, DDS_MSECS(100));
            dds_qset_durability(q, DDS_DURABILITY_TRANSIENT_LOCAL);
            dds_qset_history(q, DDS_HISTORY_KEEP_LAST, 64);
            L.r[k] = dds_create_reader(dp, topics[k], q, NULL);
            dds_delete_qos(q);
        }
        L.made = now;
        return;
    }
    for (int k = 1; k < NKIND; k++) {
        if (L.r[k] <= 0)
            continue;
        for (;;) {
            void *samples[16] = {NULL};
            dds_sample_info_t info[16];
            dds_return_t n = dds_take(L.r[k], samples, info, 16, 16);
            if (n <= 0)
                break;
            for (dds_return_t j = 0; j < n; j++) {
                const ftm_wire_Envelope *env = samples[j];
                if (!info[j].valid_data || strncmp(env->session, S.session, sizeof env->session) != 0)
                    continue;
                L.historical[k] += info[j].source_timestamp < L.made_at;
                for (int i = 0; i < L.n; i++)
                    if (L.id[i] == env->sender && env->seq > L.got_seq[k][i])
                        L.got_seq[k][i] = env->seq;
            }
            dds_return_loan(L.r[k], samples, n);
        }
    }
    if (now - L.made < SEC)
        return;
    L.done = true;
    int statuses = 0;
    for (int i = 0; i < L.n; i++)
        for (int k = 1; k < NKIND; k++) {
            if (L.r[k] <= 0 || !L.want_seq[k][i])
                continue;
            statuses += k == 5;
            check(R_LATE, L.got_seq[k][i] >= L.want_seq[k][i],
                  "late reader of %s: from %u seq %" PRIu64 ", the first readers had %" PRIu64 " already",
                  topic_of[k], L.id[i], L.got_seq[k][i], L.want_seq[k][i]);
        }
    check(R_LATE, statuses >= 1 + S.participants && L.historical[5] >= statuses - 1,
          "late reader: statuses of %d senders, %d of them written before it existed", statuses,
          L.historical[5]);
    printf("ftm-conform: late reader: %d announcements, %d keyframes, %d statuses written before it "
           "existed\n", L.historical[1], L.historical[4], L.historical[5]);
    for (int k = 1; k < NKIND; k++)
        if (L.r[k] > 0)
            dds_delete(L.r[k]);
}

/* ---- main ------------------------------------------------------------------------------------ */

static int usage(const char *why)
{
    fprintf(stderr, "ftm-conform: %s\nusage: ftm-conform --domain D --session S --seconds T --rate HZ "
            "[--heartbeat S] [--keyframe-every S] [--status-slack S] [--from-start] "
            "[--participants N]\n", why);
    return 2;
}

int main(int argc, char **argv)
{
    long domain = -1;
    double seconds = 0;
    S.heartbeat = 0.1;
    S.keyframe_every = 1.0;
    S.status_slack = 0.1;
    for (int i = 1; i < argc; i++) {
        const char *a = argv[i], *v = i + 1 < argc ? argv[i + 1] : NULL;
        if (!strcmp(a, "--from-start")) { S.from_start = true; continue; }
        if (!v)
            return usage("an option without its value");
        i++;
        if (!strcmp(a, "--domain")) domain = strtol(v, NULL, 10);
        else if (!strcmp(a, "--session")) S.session = v;
        else if (!strcmp(a, "--seconds")) seconds = strtod(v, NULL);
        else if (!strcmp(a, "--rate")) S.rate = strtod(v, NULL);
        else if (!strcmp(a, "--heartbeat")) S.heartbeat = strtod(v, NULL);
        else if (!strcmp(a, "--keyframe-every")) S.keyframe_every = strtod(v, NULL);
        else if (!strcmp(a, "--status-slack")) S.status_slack = strtod(v, NULL);
        else if (!strcmp(a, "--participants")) S.participants = atoi(v);
        else return usage("unknown option");
    }
    if (domain < 0 || domain > 232 || !S.session || !S.session[0] || strlen(S.session) > 63 ||
        !(seconds > 0 && seconds <= 600) || !(S.rate > 0) || !(S.heartbeat > 0) || !(S.keyframe_every > 0))
        return usage("--domain 0..232, --session (1..63 bytes), --seconds, --rate are needed");
    S.frames = calloc(MAXF, sizeof *S.frames);
    S.keyframes = calloc(MAXF, sizeof *S.keyframes);
    if (!S.frames || !S.keyframes)
        return usage("out of memory");

    dds_entity_t dp = dds_create_participant((dds_domainid_t)domain, NULL, NULL);
    if (dp < 0) {
        fprintf(stderr, "ftm-conform: dds_create_participant: %s\n", dds_strretcode(dp));
        return 2;
    }
    dds_entity_t readers[NKIND] = {0}, topics[NKIND] = {0}, raw = 0;
    dds_entity_t ws = dds_create_waitset(dp);
    for (int k = 1; k < NKIND; k++) {
        dds_entity_t tp = dds_create_topic(dp, &ftm_wire_Envelope_desc, topic_of[k], NULL, NULL);
        topics[k] = tp;
        dds_qos_t *q = dds_create_qos();
        /* a reader's QoS as the table says (no deadline on readers); its own
         * history deep, so that nothing is replaced before it is taken */
        dds_qset_reliability(q, k == 2 ? DDS_RELIABILITY_BEST_EFFORT : DDS_RELIABILITY_RELIABLE, DDS_MSECS(100));
        dds_qset_durability(q, k == 1 || k == 4 || k == 5 ? DDS_DURABILITY_TRANSIENT_LOCAL
                                                          : DDS_DURABILITY_VOLATILE);
        dds_qset_history(q, DDS_HISTORY_KEEP_LAST, 4096);
        dds_qset_liveliness(q, DDS_LIVELINESS_AUTOMATIC, DDS_INFINITY);
        readers[k] = dds_create_reader(dp, tp, q, NULL);
        if (k == 1)
            raw = dds_create_reader(dp, tp, q, NULL); /* for the bytes as they travel */
        dds_delete_qos(q);
        if (tp < 0 || readers[k] < 0 || (k == 1 && raw < 0)) {
            fprintf(stderr, "ftm-conform: cannot create the reader of %s\n", topic_of[k]);
            return 2;
        }
        dds_set_status_mask(readers[k], DDS_DATA_AVAILABLE_STATUS);
        dds_waitset_attach(ws, readers[k], k);
    }
    printf("ftm-conform: listening on domain %ld, session '%s', %.1f s\n", domain, S.session, seconds);
    fflush(stdout);

    const int64_t start = mono_ns(), end = start + (int64_t)(seconds * 1e9);
    while (mono_ns() < end) {
        if (S.server_leaving) {
            /* the server has left: the others follow (ftm-bot stops once
             * its server left); what was in flight has come after 0.5 s */
            bool all = true;
            for (int i = 0; i < S.nsenders; i++)
                all &= S.senders[i].leaving || !S.senders[i].first_status;
            const int64_t since = mono_ns() - S.server_leaving_at;
            if ((all && since > SEC / 2) || since > 5 * SEC)
                break;
        }
        dds_waitset_wait(ws, NULL, 0, DDS_MSECS(10));
        for (int k = 1; k < NKIND; k++) {
            for (;;) {
                void *samples[32] = {NULL};
                dds_sample_info_t info[32];
                dds_return_t n = dds_take(readers[k], samples, info, 32, 32);
                if (n <= 0)
                    break;
                const int64_t arrival = mono_ns();
                for (dds_return_t i = 0; i < n; i++)
                    on_sample(readers[k], k, samples[i], &info[i], arrival);
                dds_return_loan(readers[k], samples, n);
            }
        }
        check_encapsulation(raw);
        late_joiner(dp, topics);
    }
    final_rules();
    dds_delete(dp);

    printf("ftm-conform: received");
    for (int k = 1; k < NKIND; k++)
        printf(" %s %" PRIu64 "%s", topic_of[k] + 7, S.received[k], k + 1 < NKIND ? "," : "\n");
    printf("ftm-conform: %d senders, %d writers, %d frames (largest tick gap %" PRIu64 ", largest gap "
           "between frames while running %.1f ms), %d keyframes, %d commands, %d replies, %d pauses, "
           "%" PRIu64 " messages lost or replaced (best effort, KEEP_LAST 1), %" PRIu64 " gone events\n",
           S.nsenders, S.nwriters, S.nframes, S.max_tick_gap, (double)S.max_frame_wall_gap * 1e-6,
           S.nkeyframes, S.ncmds, S.nreplies, S.pauses, S.replaced, S.gone_events);
    for (int i = 0; i < S.nsenders; i++)
        printf("ftm-conform: participant %u role %d origin %016" PRIx64 ": largest status interval %.1f ms, "
               "%d JOINING in its first second (the second %.1f ms after the first)%s\n",
               S.senders[i].id, S.senders[i].role, S.senders[i].origin, (double)S.senders[i].max_gap * 1e-6,
               S.senders[i].joinings_first_second, (double)S.senders[i].next_joining * 1e-6,
               S.senders[i].held ? ", listed as holder" : "");
    int bad = 0;
    for (int r = 0; r < R_NRULES; r++) {
        const bool ok = failed[r] == 0 && checked[r] > 0;
        if (r == R_KF_START && !S.from_start)
            continue;
        if (r == R_PAUSE && checked[r] == 0) {
            printf("SKIP %-4s %s (no pause)\n", "", rule_text[r]);
            continue;
        }
        bad += !ok;
        printf("%s %" PRIu64 "/%" PRIu64 " %s\n", ok ? "PASS" : "FAIL", checked[r] - failed[r], checked[r],
               rule_text[r]);
    }
    printf("ftm-conform: %s (%d rules failed)\n", bad ? "FAIL" : "PASS", bad);
    free(S.frames);
    free(S.keyframes);
    return bad ? 1 : 0;
}
