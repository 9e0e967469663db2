/* SPDX-License-Identifier: GPL-3.0-or-later */
/* One tick of a session (step.h). */
#include "step.h"

#include <stdio.h>

ftm_sim_def ftm_replay_sim_def(const ftm_scene *scene)
{
    ftm_sim_def d = ftm_scene_sim_def(scene);
    d.log = NULL;
    d.log_user = NULL;
    return d;
}

int ftm_replay_step(ftm_sim *sim, int32_t depth, const ftm_contact *contacts, int32_t count,
                    ftm_error *err)
{
    int rc = ftm_sim_set_depth(sim, depth);
    if (rc) {
        if (err) {
            err->code = rc;
            snprintf(err->message, sizeof err->message, "depth %d out of range", (int)depth);
        }
        return rc;
    }
    rc = ftm_sim_set_contacts(sim, contacts, count, err);
    if (rc)
        return rc;
    rc = ftm_sim_step(sim);
    if (rc && err) {
        err->code = rc;
        snprintf(err->message, sizeof err->message, "step failed: %s", ftm_strerror(rc));
    }
    return rc;
}
