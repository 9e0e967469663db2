/* SPDX-License-Identifier: GPL-3.0-or-later */
/* SceneAnnounce (kind 1, server -> all): plain fields only. */
#include "codec_internal.h"

/* ftm.v1.SceneAnnounce by field number, in the order of the decoder's checks */
#define T ftm_wire_announce
static const wire_field fields[] = {
    {2, WIRE_C(T, scene_id), WF_TEXT, .flags = WF_NONEMPTY},
    {3, WIRE_C(T, digest), WF_BYTES, .off2 = offsetof(T, digest_len)}, /* content_digest */
    {4, WIRE_C(T, tick_rate_hz), WF_U32, .rule = WR_NONZERO},
    {5, WIRE_C(T, time_step), WF_F64, .rule = WR_POSITIVE},
    {6, WIRE_C(T, depth), WF_I32, .rule = WR_DEPTH},
    {7, WIRE_C(T, depth_min), WF_LIMITS, .off2 = offsetof(T, depth_max)}, /* depth_limits */
    {8, WIRE_C(T, tissue), WF_TISSUE},
    {9, WIRE_C(T, node_count), WF_I32, .rule = WR_NODES},
    {10, WIRE_C(T, tick), WF_U64},
    {11, WIRE_C(T, paused), WF_BOOL},
    {12, WIRE_C(T, server_start_ns), WF_U64, .flags = WF_OPTIONAL},
    {13, WIRE_C(T, arithmetic), WF_U32, .flags = WF_OPTIONAL},
    {14, WIRE_C(T, lesson_start_ns), WF_U64, .flags = WF_OPTIONAL},
};
#undef T

const wire_kind_def wire_kind_announce = {
    .kind = FTM_WIRE_ANNOUNCE,
    .name = "scene announcement",
    .topic = "ftm_v1_scene_announce",
    .cap = FTM_WIRE_CAP_ANNOUNCE,
    .pb = &ftm__v1__scene_announce__descriptor,
    .fields = fields,
    .nfields = sizeof fields / sizeof fields[0],
};
