/* SPDX-License-Identifier: GPL-3.0-or-later */
/* From the wire to the haptic loop: a probe's ProbeReaction (ftm/wire.h,
 * found with ftm_replay_find_reaction) as an ftm_haptic_sample, with the
 * server's local force model and contact plane when it sent them
 * (docs/haptics.md). Header only, for programs that link both ftm_wire and
 * ftm_haptic (the GL client); ftm_haptic itself stays free of the wire. */
#ifndef FTM_CLIENT_HAPTIC_WIRE_H
#define FTM_CLIENT_HAPTIC_WIRE_H

#include "haptic.h"

#include "ftm/wire.h"

#include <string.h>

/* time: when the force was valid on the haptic clock (the tick's time if
 * the client maps server ticks to its clock, else ftm_haptic_clock() at
 * arrival). r NULL: the probe is not in contact (zero force at hip_now, the
 * current HIP, so that the force model has a point to hold). */
static inline ftm_haptic_sample ftm_haptic_sample_from_reaction(const ftm_wire_reaction *r,
                                                                double time, ftm_vec3 hip_now)
{
    ftm_haptic_sample s;
    memset(&s, 0, sizeof s);
    s.time = time;
    s.hip = hip_now;
    if (!r)
        return s;
    s.force = r->force;
    if (r->has_model) {
        s.hip = r->hip; /* x0: the HIP the server computed the force for */
        s.has_stiffness = true;
        memcpy(s.stiffness, r->stiffness, sizeof s.stiffness);
    }
    if (r->has_plane) {
        s.has_plane = true;
        s.plane_point = r->contact_point;
        s.plane_normal = r->contact_normal;
    }
    return s;
}

#endif
