/* SPDX-License-Identifier: GPL-3.0-or-later */
/* Names of roles, participant states and reply outcomes, for logs and
 * displays; and the old name of ftm_strerror. (Kinds' names are in their
 * descriptors, kinds.c.) */
#include "wire_internal.h"

const char *ftm_wire_strerror(int code)
{
    return ftm_strerror(code);
}

const char *ftm_wire_role_name(ftm_wire_role role)
{
    switch (role) {
    case FTM_WIRE_ROLE_SERVER: return "server";
    case FTM_WIRE_ROLE_TRAINEE: return "trainee";
    case FTM_WIRE_ROLE_INSTRUCTOR: return "instructor";
    case FTM_WIRE_ROLE_OBSERVER: return "observer";
    case FTM_WIRE_ROLE_BOT: return "bot";
    }
    return "unknown";
}

const char *ftm_wire_state_name(ftm_wire_state state)
{
    switch (state) {
    case FTM_WIRE_STATE_JOINING: return "joining";
    case FTM_WIRE_STATE_SYNCED: return "synced";
    case FTM_WIRE_STATE_RESYNCING: return "resyncing";
    case FTM_WIRE_STATE_LEAVING: return "leaving";
    }
    return "unknown";
}

const char *ftm_wire_outcome_name(ftm_wire_outcome outcome)
{
    switch (outcome) {
    case FTM_WIRE_OUTCOME_APPLIED: return "applied";
    case FTM_WIRE_OUTCOME_CHANGED: return "changed";
    case FTM_WIRE_OUTCOME_REFUSED: return "refused";
    }
    return "unknown";
}
