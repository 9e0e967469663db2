/* SPDX-License-Identifier: GPL-3.0-or-later */
/* One tick, as the server runs it and every replica repeats it: the same
 * simulation definition and the same call sequence on both sides, so that
 * their state hashes agree bit for bit (docs/protocol.md, "Ticks,
 * heartbeats and replay"). */
#ifndef FTM_SESSION_STEP_H
#define FTM_SESSION_STEP_H

#include "ftm/scene.h"
#include "ftm/sim.h"

/* The simulation definition a session runs a scene with (server and every
 * replica): the scene's, without its log callback. Region sleep included:
 * keyframes carry the contacts and the integrator's mode, so a replica
 * restores a sleeping region as it is (docs/protocol.md). */
ftm_sim_def ftm_replay_sim_def(const ftm_scene *scene);

/* One tick, exactly as the server runs it: ftm_sim_set_depth(depth),
 * ftm_sim_set_contacts(contacts), ftm_sim_step(). */
int ftm_replay_step(ftm_sim *sim, int32_t depth, const ftm_contact *contacts, int32_t count,
                    ftm_error *err);

#endif
