/* SPDX-License-Identifier: GPL-3.0-or-later */
/* SessionControl (kind 6, instructor -> server): the command, a oneof, is
 * the hooks'. */
#include "codec_internal.h"

/* ftm.v1.SessionControl by field number, in the order of the decoder's checks */
#define T ftm_wire_control
static const wire_field fields[] = {
    {2, WIRE_C(T, issuer), WF_U32}, /* issuer_id */
    {3, WIRE_C(T, command_id), WF_U64},
};
#undef T

static int check(const vctx *v, const ProtobufCMessage *pm)
{
    const Ftm__V1__SessionControl *m = (const void *)pm;
    switch (m->command_case) {
    case FTM__V1__SESSION_CONTROL__COMMAND_PAUSE:
    case FTM__V1__SESSION_CONTROL__COMMAND_RESUME:
    case FTM__V1__SESSION_CONTROL__COMMAND_RESET: return FTM_OK;
    case FTM__V1__SESSION_CONTROL__COMMAND_TISSUE: return wire_check_tissue(v, "tissue", m->tissue);
    case FTM__V1__SESSION_CONTROL__COMMAND_DEPTH_LIMITS:
        return wire_check_limits(v, "depth_limits", m->depth_limits);
    default: return wire_missing(v, "command (one of pause, resume, reset, tissue, depth_limits)");
    }
}

static int from(const ProtobufCMessage *pm, ftm_wire_msg *out, ftm_error *err)
{
    (void)err;
    const Ftm__V1__SessionControl *m = (const void *)pm;
    ftm_wire_control *c = &out->u.control;
    switch (m->command_case) {
    case FTM__V1__SESSION_CONTROL__COMMAND_PAUSE: c->command = FTM_WIRE_CMD_PAUSE; break;
    case FTM__V1__SESSION_CONTROL__COMMAND_RESUME: c->command = FTM_WIRE_CMD_RESUME; break;
    case FTM__V1__SESSION_CONTROL__COMMAND_RESET: c->command = FTM_WIRE_CMD_RESET; break;
    case FTM__V1__SESSION_CONTROL__COMMAND_TISSUE:
        c->command = FTM_WIRE_CMD_TISSUE;
        c->tissue = wire_tissue_from(m->tissue);
        break;
    default: /* checked: depth limits */
        c->command = FTM_WIRE_CMD_DEPTH_LIMITS;
        c->depth_min = (int32_t)m->depth_limits->min;
        c->depth_max = (int32_t)m->depth_limits->max;
        break;
    }
    return FTM_OK;
}

static int to(const ftm_wire_msg *msg, scratch *s, ProtobufCMessage *pm, ftm_error *err)
{
    const ftm_wire_control *c = &msg->u.control;
    Ftm__V1__SessionControl *m = (void *)pm;
    const char *what = ftm_wire_kind_name(msg->kind);
    switch (c->command) {
    case FTM_WIRE_CMD_PAUSE:
        ftm__v1__pause__init(&s->pause);
        m->command_case = FTM__V1__SESSION_CONTROL__COMMAND_PAUSE;
        m->pause = &s->pause;
        return FTM_OK;
    case FTM_WIRE_CMD_RESUME:
        ftm__v1__resume__init(&s->resume);
        m->command_case = FTM__V1__SESSION_CONTROL__COMMAND_RESUME;
        m->resume = &s->resume;
        return FTM_OK;
    case FTM_WIRE_CMD_RESET:
        ftm__v1__reset__init(&s->reset);
        m->command_case = FTM__V1__SESSION_CONTROL__COMMAND_RESET;
        m->reset = &s->reset;
        return FTM_OK;
    case FTM_WIRE_CMD_TISSUE:
        m->command_case = FTM__V1__SESSION_CONTROL__COMMAND_TISSUE;
        m->tissue = wire_tissue_to(s, &c->tissue);
        return FTM_OK;
    case FTM_WIRE_CMD_DEPTH_LIMITS: {
        int rc = wire_limits_to(s, what, c->depth_min, c->depth_max, err);
        if (rc)
            return rc;
        m->command_case = FTM__V1__SESSION_CONTROL__COMMAND_DEPTH_LIMITS;
        m->depth_limits = &s->limits;
        return FTM_OK;
    }
    }
    return ftm_error_set(err, FTM_EINVAL, "%s: unknown command %d", what, (int)c->command);
}

const wire_kind_def wire_kind_control = {
    .kind = FTM_WIRE_CONTROL,
    .name = "session control",
    .topic = "ftm_v1_session_control",
    .cap = FTM_WIRE_CAP_CONTROL,
    .pb = &ftm__v1__session_control__descriptor,
    .fields = fields,
    .nfields = sizeof fields / sizeof fields[0],
    .check = check,
    .from = from,
    .to = to,
};
