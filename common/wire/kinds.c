/* SPDX-License-Identifier: GPL-3.0-or-later */
/* The message kinds: one descriptor each (msg_<kind>.c), by ftm.v1.Kind.
 * A new kind is a line here once its descriptor exists. */
#include "codec_internal.h"

static const wire_kind_def *const kinds[] = {
    [FTM_WIRE_ANNOUNCE] = &wire_kind_announce,
    [FTM_WIRE_PROBE_INPUT] = &wire_kind_probe_input,
    [FTM_WIRE_TICK] = &wire_kind_tick,
    [FTM_WIRE_KEYFRAME] = &wire_kind_keyframe,
    [FTM_WIRE_STATUS] = &wire_kind_status,
    [FTM_WIRE_CONTROL] = &wire_kind_control,
    [FTM_WIRE_CONTROL_REPLY] = &wire_kind_control_reply,
};
_Static_assert(sizeof kinds / sizeof kinds[0] == FTM_WIRE_KIND_MAX + 1,
               "a descriptor for every kind up to FTM_WIRE_KIND_MAX");

const wire_kind_def *wire_kind(int kind)
{
    return kind >= FTM_WIRE_KIND_MIN && kind <= FTM_WIRE_KIND_MAX ? kinds[kind] : NULL;
}

const char *ftm_wire_kind_name(int kind)
{
    const wire_kind_def *k = wire_kind(kind);
    return k ? k->name : "unknown kind";
}

const char *ftm_wire_topic_name(int kind)
{
    const wire_kind_def *k = wire_kind(kind);
    return k ? k->topic : NULL;
}

size_t ftm_wire_default_cap(int kind)
{
    const wire_kind_def *k = wire_kind(kind);
    return k ? k->cap : 0;
}
