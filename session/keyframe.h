/* SPDX-License-Identifier: GPL-3.0-or-later */
/* Keyframes: a simulation's whole state at a tick, for joiners and for
 * replicas that lost frames (docs/protocol.md, Keyframe). */
#ifndef FTM_SESSION_KEYFRAME_H
#define FTM_SESSION_KEYFRAME_H

#include "tissue.h"

#include "ftm/sim.h"
#include "ftm/wire.h"

/* The keyframe message of a simulation's current state: nodes not at rest,
 * contacts, mode, and the tissue of mat when it differs from the scene's
 * (mat NULL: the scene's). Arrays are malloc'ed into *out (free with
 * ftm_replay_keyframe_free). */
int ftm_replay_make_keyframe(const ftm_sim *sim, const ftm_replay_material *mat,
                             ftm_wire_keyframe *out, ftm_error *err);
/* A deep copy of k into *dst (FTM_ENOMEM: nothing to free). */
int ftm_replay_keyframe_copy(ftm_wire_keyframe *dst, const ftm_wire_keyframe *k);
void ftm_replay_keyframe_free(ftm_wire_keyframe *k);

#endif
