/* SPDX-License-Identifier: GPL-3.0-or-later */
/* Whose id and whose frames (claims.h). */
#include "claims.h"

ftm_id_claim ftm_replay_id_verdict(ftm_id_told *told, const ftm_wire_status *server_status,
                                   uint32_t own_id, uint64_t own_origin)
{
    const ftm_wire_status *st = server_status;
    if (st->role != FTM_WIRE_ROLE_SERVER)
        return FTM_ID_NOTHING;
    bool us = false, other = false;
    for (int32_t i = 0; i < st->ignored_count; i++) {
        if (st->ignored_participant[i] != own_id)
            continue;
        if (st->ignored_origin[i] == own_origin)
            us = true;
        else
            other = true;
    }
    if (us && !told->taken) {
        told->taken = true;
        return FTM_ID_TAKEN;
    }
    if (!us && told->taken) {
        told->taken = false;
        told->newcomer = false;
        return FTM_ID_OURS_AGAIN;
    }
    if (other && !us && !told->taken && !told->newcomer) {
        told->newcomer = true;
        return FTM_ID_NEWCOMER;
    }
    return FTM_ID_NOTHING;
}

bool ftm_replay_id_held(const ftm_wire_status *server_status, uint32_t own_id,
                        uint64_t own_origin)
{
    const ftm_wire_status *st = server_status;
    if (st->role != FTM_WIRE_ROLE_SERVER)
        return false;
    for (int32_t i = 0; i < st->holder_count; i++)
        if (st->holder_participant[i] == own_id)
            return st->holder_origin[i] == own_origin; /* (each id at most once: the codec) */
    return false;
}

bool ftm_replay_from_server(uint32_t *id, uint64_t *origin, const ftm_wire_received *rx,
                            bool server_left)
{
    if (*id == 0 && rx->msg.kind == FTM_WIRE_ANNOUNCE) {
        *id = rx->sender;
        *origin = rx->origin;
    }
    if (*id == 0 || rx->sender != *id || !rx->origin)
        return false;
    if (rx->origin == *origin)
        return true;
    if (rx->msg.kind == FTM_WIRE_ANNOUNCE && server_left) {
        *origin = rx->origin; /* its successor */
        return true;
    }
    return false;
}
