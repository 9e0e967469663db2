/* SPDX-License-Identifier: GPL-3.0-or-later */
/* A replica fed by a rogue or broken publisher: what reaches ftm_replay (the
 * bots' and the GL client's replay) after the decoder accepted it. Input: a
 * sequence of messages, each a selector byte (bits 0-1: announcement, tick
 * frame, keyframe, tick frame; bit 2: the envelope reported a gap), a 16-bit
 * little-endian length and the payload, for a replica of the built-in
 * default scene. Properties: every message is handled without a crash or a
 * hang, and the replica's state never holds a NaN or infinity. */
#include "fuzz.h"

#include "replica.h"

#include <math.h>
#include <stdlib.h>
#include <string.h>

static ftm_scene *scene;

static void check_finite(ftm_replay *r)
{
    ftm_sim *sim = ftm_replay_sim(r);
    int32_t n = ftm_mesh_node_count(ftm_sim_mesh(sim));
    const double *x = ftm_sim_positions(sim);
    const double *xp = ftm_sim_previous_positions(sim);
    for (int32_t i = 0; i < 3 * n; i++)
        fuzz_check(isfinite(x[i]) && isfinite(xp[i]));
}

int LLVMFuzzerTestOneInput(const uint8_t *data, size_t size)
{
    ftm_error err;
    memset(&err, 0, sizeof err);
    if (!scene && ftm_scene_builtin("default", &scene, &err) != FTM_OK)
        fuzz_fail(__FILE__, __LINE__, err.message);
    ftm_replay *r = NULL;
    fuzz_check(ftm_replay_create(scene, NULL, NULL, &r, &err) == FTM_OK);
    ftm_wire_limits limits;
    memset(&limits, 0, sizeof limits);
    limits.node_count = ftm_mesh_node_count(ftm_scene_mesh(scene));

    uint64_t seq = 0;
    size_t at = 0;
    while (at + 3 <= size) {
        int sel = data[at];
        size_t len = (size_t)data[at + 1] | (size_t)data[at + 2] << 8;
        at += 3;
        if (len > size - at)
            len = size - at;
        static const int kinds[4] = {FTM_WIRE_ANNOUNCE, FTM_WIRE_TICK, FTM_WIRE_KEYFRAME,
                                     FTM_WIRE_TICK};
        int kind = kinds[sel & 3];
        ftm_wire_received rx;
        memset(&rx, 0, sizeof rx);
        int rc = ftm_wire_decode(kind, data + at, len, &limits, &rx.msg, &err);
        at += len;
        if (rc != FTM_OK)
            continue;
        if (kind == FTM_WIRE_ANNOUNCE) {
            rc = ftm_replay_check_announce(r, &rx.msg.u.announce, &err);
            fuzz_check(rc == FTM_OK || (rc < 0 && err.message[0] != '\0'));
        } else if (kind == FTM_WIRE_KEYFRAME) {
            rc = ftm_replay_on_keyframe(r, &rx.msg.u.keyframe);
            fuzz_check(rc <= 0);
        } else {
            rx.sender = 1;
            rx.seq = ++seq;
            rx.gap = (sel & 4) ? 1 : 0;
            rx.payload_size = len;
            rc = ftm_replay_on_tick(r, &rx);
            fuzz_check(rc == FTM_OK || rc == FTM_ENOMEM);
        }
        ftm_wire_msg_free(&rx.msg);
        check_finite(r);
        ftm_wire_state st = ftm_replay_state(r);
        fuzz_check(st >= FTM_WIRE_STATE_JOINING && st <= FTM_WIRE_STATE_LEAVING);
    }
    ftm_replay_destroy(r);
    return 0;
}
