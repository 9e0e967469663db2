/* SPDX-License-Identifier: GPL-3.0-or-later */
/* ControlReply (kind 7, server -> all, read by the issuer): a reason is
 * needed unless the command was applied (the hook). The reason is shown on
 * an instructor's HUD and written to logs and terminals: WF_PLAIN. */
#include "codec_internal.h"

/* ftm.v1.ControlReply by field number, in the order of the decoder's checks */
#define T ftm_wire_control_reply
static const wire_field fields[] = {
    {2, WIRE_C(T, issuer), WF_U32}, /* issuer_id */
    {3, WIRE_C(T, command_id), WF_U64},
    {4, WIRE_C(T, outcome), WF_ENUM, .rule = WR_ENUM, .lo = FTM_WIRE_OUTCOME_APPLIED,
     .hi = FTM_WIRE_OUTCOME_REFUSED},
    {5, WIRE_C(T, tick), WF_U64},
    {6, WIRE_C(T, reason), WF_TEXT, .flags = WF_PLAIN},
};
#undef T

static int check(const vctx *v, const ProtobufCMessage *pm)
{
    const Ftm__V1__ControlReply *m = (const void *)pm;
    if ((!m->reason || !m->reason[0]) && (int)m->outcome != FTM_WIRE_OUTCOME_APPLIED)
        return ftm_error_set(v->err, FTM_EINVAL, "%s: a %s command needs a reason", v->what,
                             ftm_wire_outcome_name((ftm_wire_outcome)m->outcome));
    return FTM_OK;
}

const wire_kind_def wire_kind_control_reply = {
    .kind = FTM_WIRE_CONTROL_REPLY,
    .name = "control reply",
    .topic = "ftm_v1_control_reply",
    .cap = FTM_WIRE_CAP_CONTROL_REPLY,
    .pb = &ftm__v1__control_reply__descriptor,
    .fields = fields,
    .nfields = sizeof fields / sizeof fields[0],
    .check = check,
};
