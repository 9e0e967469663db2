/* SPDX-License-Identifier: GPL-3.0-or-later */
/* The replica: a participant's own copy of the session's scene, replaying
 * the server's tick frames (docs/protocol.md, "Ticks, heartbeats and
 * replay").
 *
 * A replica applies the frames with libftm exactly as the server ran them
 * (ftm_replay_step, step.h), checks the frame's state hash after every
 * tick, finds lost frames from the envelope's sequence gaps, and resyncs
 * from a keyframe when it can no longer be trusted. Used by the
 * participant core (participant.h) of ftm-bot and ftm-client. No threads of
 * its own: one thread per ftm_replay. */
#ifndef FTM_SESSION_REPLICA_H
#define FTM_SESSION_REPLICA_H

#include "ftm/scene.h"
#include "tissue.h"
#include "ftm/wire.h"

#ifdef __cplusplus
extern "C" {
#endif

typedef struct ftm_replay ftm_replay;

typedef struct ftm_replay_stats {
    uint64_t frames_received;  /* tick frames handed to ftm_replay_on_tick */
    uint64_t frames_applied;   /* frames stepped (re-applications included) */
    uint64_t idle_ticks;       /* ticks the server did not send (idle), stepped here */
    uint64_t stale_frames;     /* frames at or before the current tick, ignored */
    uint64_t rule_breaks;      /* frames that broke the idle rule: dropped, resync */
    uint64_t mismatches;       /* hash mismatches */
    uint64_t gaps;             /* frames with a sequence gap */
    uint64_t resyncs;          /* times the replica entered RESYNCING */
    uint64_t keyframes_loaded; /* keyframes restored */
    uint64_t keyframes_unusable; /* keyframes that could not be continued from */
    double replay_ns_total;    /* time spent in ftm_replay_step */
    double replay_ns_max;      /* worst ftm_replay_step since ftm_replay_take_max */
} ftm_replay_stats;

/* The replica of scene (which must outlive it). log may be NULL. */
int ftm_replay_create(const ftm_scene *scene, ftm_log_fn log, void *log_user, ftm_replay **out,
                      ftm_error *err);
void ftm_replay_destroy(ftm_replay *r);

/* Checks an announcement against this build and the local scene: the
 * server core's arithmetic revision (FTM_EVERSION if it is not this
 * build's: hashes could never match), then the scene's digest, node count
 * and time step (FTM_EINVAL). A message names the mismatch. */
int ftm_replay_check_announce(const ftm_replay *r, const ftm_wire_announce *a, ftm_error *err);

/* A received tick frame (r->msg.kind == FTM_WIRE_TICK). Synced: applies it
 * (after stepping any ticks the server left out as idle), checks the hash;
 * a sequence gap or a mismatch switches to RESYNCING. Not synced: keeps it
 * for after the keyframe. Returns FTM_OK or FTM_ENOMEM. */
int ftm_replay_on_tick(ftm_replay *r, const ftm_wire_received *rx);

/* A received keyframe. Not synced: restores it if the frames received since
 * can continue it, and applies those; synced: checks it against the state
 * at its tick and restores it if the server's state differs (reset). */
int ftm_replay_on_keyframe(ftm_replay *r, const ftm_wire_keyframe *k);

ftm_wire_state ftm_replay_state(const ftm_replay *r);
uint64_t ftm_replay_tick(const ftm_replay *r);   /* last applied tick */
uint64_t ftm_replay_hash(const ftm_replay *r);   /* ftm_sim_hash now */
/* Server tick and hash of the last frame applied (hash is what the server
 * said; equal to ftm_replay_hash when synced). */
const ftm_wire_tick *ftm_replay_last_frame(const ftm_replay *r);
void ftm_replay_get_stats(const ftm_replay *r, ftm_replay_stats *stats);
/* Returns replay_ns_max and starts a new maximum (per status period). */
double ftm_replay_take_max(ftm_replay *r);
ftm_sim *ftm_replay_sim(ftm_replay *r);
/* The tissue parameters the replica's simulation runs with now. */
ftm_wire_tissue ftm_replay_tissue(const ftm_replay *r);
/* The stable range around the tissue in force (ftm_replay_tissue_range): what
 * the server would apply, for an instructor's HUD. */
int ftm_replay_range(const ftm_replay *r, ftm_tissue_range *out, ftm_error *err);
/* The scene's own tissue (its [material]). */
ftm_wire_tissue ftm_replay_own_tissue(const ftm_replay *r);

/* The reaction of one probe (participant, probe index) in a tick frame, e.g.
 * ftm_replay_last_frame(r): with the server's local force model when it sent
 * one (out->has_model: F(x) = force + stiffness (x - hip), for
 * FTM_HAPTIC_FORCE_MODEL in haptic.h). false if the frame has no reaction
 * for it (the probe is not in contact: zero force). */
static inline bool ftm_replay_find_reaction(const ftm_wire_tick *t, uint32_t participant,
                                            int32_t probe, ftm_wire_reaction *out)
{
    for (int32_t i = 0; t && i < t->reaction_count; i++) {
        if (t->reactions[i].participant == participant && t->reactions[i].probe == probe) {
            *out = t->reactions[i];
            return true;
        }
    }
    return false;
}

#ifdef __cplusplus
}
#endif
#endif
