/* SPDX-License-Identifier: GPL-3.0-or-later */
/* Keyframe (kind 4, server -> late joiners, resync): the node columns and
 * the contacts are the hooks', checked against the keyframe's own mesh. */
#include "codec_internal.h"

#include <math.h>
#include <string.h>

/* ftm.v1.Keyframe by field number, in the order of the decoder's checks */
#define T ftm_wire_keyframe
static const wire_field fields[] = {
    {2, WIRE_C(T, tick), WF_U64},
    {3, WIRE_C(T, state_hash), WF_U64},
    {4, WIRE_C(T, node_count), WF_I32}, /* its range: after the mode (check) */
    {5, WIRE_C(T, depth), WF_I32, .rule = WR_DEPTH},
    {9, WIRE_C(T, tissue), WF_TISSUE, .flags = WF_OPTIONAL, .has_off = offsetof(T, has_tissue)},
    {10, WIRE_C(T, mode), WF_MODE, .flags = WF_OPTIONAL, .has_off = offsetof(T, has_mode)},
};
#undef T

static int check(const vctx *v, const ProtobufCMessage *pm)
{
    const Ftm__V1__Keyframe *m = (const void *)pm;
    if (m->node_count == 0 || m->node_count > INT32_MAX)
        return ftm_error_set(v->err, FTM_ERANGE, "%s: node_count %u out of range (1..%d)", v->what,
                             m->node_count, INT32_MAX);
    int rc = wire_check_contacts(v, WIRE_CONTACTS_OF(m), m->node_count);
    if (rc)
        return rc;
    if (v->scene_nodes && m->node_count != v->scene_nodes)
        return ftm_error_set(v->err, FTM_ERANGE, "%s: for a mesh of %u nodes, scene has %u nodes",
                             v->what, m->node_count, v->scene_nodes);
    const size_t n = m->n_node;
    if (n > m->node_count || m->n_position != 3 * n || m->n_previous != 3 * n)
        return ftm_error_set(v->err, FTM_EINVAL,
                             "%s: node columns disagree: %zu nodes (mesh has %u), %zu positions, "
                             "%zu previous (want 3 per node)",
                             v->what, n, m->node_count, m->n_position, m->n_previous);
    for (size_t i = 0; i < n; i++) {
        if (m->node[i] >= m->node_count)
            return ftm_error_set(v->err, FTM_ERANGE,
                                 "%s: entry %zu: node %u out of range (mesh has %u nodes)", v->what,
                                 i, m->node[i], m->node_count);
        if (i > 0 && m->node[i] <= m->node[i - 1])
            return ftm_error_set(
                v->err, FTM_EINVAL,
                "%s: entry %zu: node %u not above the previous node %u (must ascend)", v->what, i,
                m->node[i], m->node[i - 1]);
    }
    for (size_t i = 0; i < 3 * n; i++) {
        if (!isfinite(m->position[i]) || !isfinite(m->previous[i]))
            return ftm_error_set(v->err, FTM_EINVAL, "%s: entry %zu (node %u): %s.%c is not finite",
                                 v->what, i / 3, m->node[i / 3],
                                 isfinite(m->position[i]) ? "previous" : "position", "xyz"[i % 3]);
    }
    return FTM_OK;
}

static int from(const ProtobufCMessage *pm, ftm_wire_msg *out, ftm_error *err)
{
    const Ftm__V1__Keyframe *m = (const void *)pm;
    ftm_wire_keyframe *k = &out->u.keyframe;
    const size_t n = m->n_node, nc = m->n_contact_node;
    void *pos = NULL, *cts = NULL, *nodes = NULL;
    out->storage = wire_alloc_arrays(6 * n * sizeof(double), nc * sizeof(ftm_contact),
                                     n * sizeof(int32_t), &pos, &cts, &nodes);
    if (!out->storage)
        return ftm_error_set(err, FTM_ENOMEM, "%s: out of memory", ftm_wire_kind_name(out->kind));
    k->positions = pos;
    k->previous = k->positions + 3 * n;
    k->nodes = nodes;
    k->contacts = cts;
    k->contact_count = (int32_t)nc;
    wire_contacts_from(WIRE_CONTACTS_OF(m), k->contacts);
    k->count = (int32_t)n;
    for (size_t i = 0; i < n; i++)
        k->nodes[i] = (int32_t)m->node[i];
    if (n) {
        memcpy(k->positions, m->position, 3 * n * sizeof(double));
        memcpy(k->previous, m->previous, 3 * n * sizeof(double));
    }
    return FTM_OK;
}

static int to(const ftm_wire_msg *msg, scratch *s, ProtobufCMessage *pm, ftm_error *err)
{
    const ftm_wire_keyframe *k = &msg->u.keyframe;
    Ftm__V1__Keyframe *m = (void *)pm;
    const char *what = ftm_wire_kind_name(msg->kind);
    if (k->count < 0 || (k->count && (!k->nodes || !k->positions || !k->previous)))
        return ftm_error_set(err, FTM_EINVAL, "%s: bad count %d or NULL arrays", what, k->count);
    const size_t n = (size_t)k->count;
    uint32_t *nodes = wire_scratch_alloc(s, n * sizeof *nodes);
    if (!nodes)
        return ftm_error_set(err, FTM_ENOMEM, "%s: out of memory", what);
    int rc = wire_contacts_to(s, what, k->contacts, k->contact_count, WIRE_CONTACTS_SET(m), err);
    if (rc)
        return rc;
    for (size_t i = 0; i < n; i++) {
        if (k->nodes[i] < 0)
            return ftm_error_set(err, FTM_ERANGE, "%s: entry %zu: negative node %d", what, i,
                                 k->nodes[i]);
        nodes[i] = (uint32_t)k->nodes[i];
    }
    m->n_node = n;
    m->node = nodes;
    m->n_position = m->n_previous = 3 * n;
    m->position = (double *)k->positions; /* only read while packing */
    m->previous = (double *)k->previous;
    return FTM_OK;
}

const wire_kind_def wire_kind_keyframe = {
    .kind = FTM_WIRE_KEYFRAME,
    .name = "keyframe",
    .topic = "ftm_v1_keyframe",
    .cap = FTM_WIRE_CAP_KEYFRAME,
    .pb = &ftm__v1__keyframe__descriptor,
    .fields = fields,
    .nfields = sizeof fields / sizeof fields[0],
    .check = check,
    .from = from,
    .to = to,
};
