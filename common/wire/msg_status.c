/* SPDX-License-Identifier: GPL-3.0-or-later */
/* ParticipantStatus (kind 5, everyone -> all): the replay times' values,
 * the name and the server's lists of ignored and listened-to processes are
 * the hooks'. */
#include "codec_internal.h"

#include <string.h>

/* ftm.v1.ParticipantStatus by field number, in the order of the decoder's checks */
#define T ftm_wire_status
static const wire_field fields[] = {
    {2, WIRE_C(T, participant), WF_U32}, /* participant_id */
    {3, WIRE_C(T, role), WF_ENUM, .rule = WR_ENUM, .lo = FTM_WIRE_ROLE_SERVER,
     .hi = FTM_WIRE_ROLE_BOT},
    {4, WIRE_C(T, state), WF_ENUM, .rule = WR_ENUM, .lo = FTM_WIRE_STATE_JOINING,
     .hi = FTM_WIRE_STATE_LEAVING},
    {5, WIRE_C(T, last_applied_tick), WF_U64},
    {6, WIRE_C(T, state_hash), WF_U64},
    {7, WIRE_C(T, replay_ns_per_tick), WF_F64}, /* values: check */
    {8, WIRE_C(T, replay_ns_max), WF_F64},
    {9, WIRE_C(T, name), WF_TEXT, .flags = WF_PLAIN | WF_HOOK_CHECKED},
};
#undef T

/* A list of (participant, origin) pairs, the server's only. */
static int check_pairs(const vctx *v, const char *field, size_t n_id, size_t n_origin, size_t max,
                       const char *what_they_are, ftm_wire_role role)
{
    if (n_id != n_origin)
        return ftm_error_set(v->err, FTM_EINVAL, "%s: %zu %s_participant but %zu %s_origin",
                             v->what, n_id, field, n_origin, field);
    if (n_id > max)
        return ftm_error_set(v->err, FTM_ERANGE, "%s: %zu %s (at most %zu)", v->what, n_id,
                             what_they_are, max);
    if (n_id && role != FTM_WIRE_ROLE_SERVER)
        return ftm_error_set(v->err, FTM_EINVAL, "%s: %s in a %s's status (a server's only)",
                             v->what, what_they_are, ftm_wire_role_name(role));
    return FTM_OK;
}

static int check(const vctx *v, const ProtobufCMessage *pm)
{
    const Ftm__V1__ParticipantStatus *m = (const void *)pm;
    int rc;
    if ((rc = wire_check_finite(v, "replay_ns_per_tick", m->replay_ns_per_tick)) ||
        (rc = wire_check_finite(v, "replay_ns_max", m->replay_ns_max)))
        return rc;
    if (m->replay_ns_per_tick < 0 || m->replay_ns_max < 0)
        return ftm_error_set(v->err, FTM_EINVAL, "%s: negative replay time", v->what);
    if ((rc = wire_check_text(v, "name", m->name, FTM_WIRE_DISPLAY_MAX, WF_PLAIN)))
        return rc;
    const ftm_wire_role role = (ftm_wire_role)m->role;
    if ((rc = check_pairs(v, "ignored", m->n_ignored_participant, m->n_ignored_origin,
                          FTM_WIRE_IGNORED_MAX, "ignored processes", role)) ||
        (rc = check_pairs(v, "holder", m->n_holder_participant, m->n_holder_origin,
                          FTM_WIRE_HOLDERS_MAX, "holders", role)))
        return rc;
    /* one process per id: a second pair for an id would make "the server
     * hears us" ambiguous */
    for (size_t i = 1; i < m->n_holder_participant; i++)
        for (size_t j = 0; j < i; j++)
            if (m->holder_participant[i] == m->holder_participant[j])
                return ftm_error_set(v->err, FTM_EINVAL, "%s: holder_participant %u listed twice",
                                     v->what, m->holder_participant[i]);
    return FTM_OK;
}

static int from(const ProtobufCMessage *pm, ftm_wire_msg *out, ftm_error *err)
{
    (void)err;
    const Ftm__V1__ParticipantStatus *m = (const void *)pm;
    ftm_wire_status *s = &out->u.status;
    /* the counts are at most FTM_WIRE_IGNORED_MAX and _HOLDERS_MAX: checked */
    s->ignored_count = (int32_t)m->n_ignored_participant;
    for (size_t i = 0; i < m->n_ignored_participant; i++) {
        s->ignored_participant[i] = m->ignored_participant[i];
        s->ignored_origin[i] = m->ignored_origin[i];
    }
    s->holder_count = (int32_t)m->n_holder_participant;
    for (size_t i = 0; i < m->n_holder_participant; i++) {
        s->holder_participant[i] = m->holder_participant[i];
        s->holder_origin[i] = m->holder_origin[i];
    }
    return FTM_OK;
}

/* The caller's count of pairs, as the decoder would take it. */
static int count_to(int32_t count, int32_t max, const char *what_they_are, ftm_wire_role role,
                    const char *what, ftm_error *err)
{
    if (count < 0 || count > max)
        return ftm_error_set(err, FTM_ERANGE, "%s: %d %s (0..%d)", what, (int)count, what_they_are,
                             (int)max);
    if (count && role != FTM_WIRE_ROLE_SERVER)
        return ftm_error_set(err, FTM_EINVAL, "%s: %s in a %s's status (a server's only)", what,
                             what_they_are, ftm_wire_role_name(role));
    return FTM_OK;
}

static int to(const ftm_wire_msg *msg, scratch *s, ProtobufCMessage *pm, ftm_error *err)
{
    (void)s;
    const ftm_wire_status *st = &msg->u.status;
    Ftm__V1__ParticipantStatus *m = (void *)pm;
    const char *what = ftm_wire_kind_name(msg->kind);
    int rc =
        count_to(st->ignored_count, FTM_WIRE_IGNORED_MAX, "ignored processes", st->role, what, err);
    if (rc)
        return rc;
    m->n_ignored_participant = m->n_ignored_origin = (size_t)st->ignored_count;
    m->ignored_participant = (uint32_t *)st->ignored_participant; /* only read while packing */
    m->ignored_origin = (uint64_t *)st->ignored_origin;
    if ((rc = count_to(st->holder_count, FTM_WIRE_HOLDERS_MAX, "holders", st->role, what, err)))
        return rc;
    for (int32_t i = 1; i < st->holder_count; i++)
        for (int32_t j = 0; j < i; j++)
            if (st->holder_participant[i] == st->holder_participant[j])
                return ftm_error_set(err, FTM_EINVAL, "%s: holder_participant %u listed twice",
                                     what, st->holder_participant[i]);
    m->n_holder_participant = m->n_holder_origin = (size_t)st->holder_count;
    m->holder_participant = (uint32_t *)st->holder_participant;
    m->holder_origin = (uint64_t *)st->holder_origin;
    return FTM_OK;
}

const wire_kind_def wire_kind_status = {
    .kind = FTM_WIRE_STATUS,
    .name = "participant status",
    .topic = "ftm_v1_participant_status",
    .cap = FTM_WIRE_CAP_STATUS,
    .pb = &ftm__v1__participant_status__descriptor,
    .fields = fields,
    .nfields = sizeof fields / sizeof fields[0],
    .check = check,
    .from = from,
    .to = to,
};
