/* SPDX-License-Identifier: GPL-3.0-or-later */
/* TickFrame (kind 3, server -> all): the contact columns and the probes'
 * reactions are the hooks'. */
#include "codec_internal.h"

#include <math.h>
#include <stdio.h>
#include <string.h>

/* ftm.v1.TickFrame by field number, in the order of the decoder's checks */
#define T ftm_wire_tick
static const wire_field fields[] = {
    {2, WIRE_C(T, tick), WF_U64},
    {3, WIRE_C(T, depth), WF_I32, .rule = WR_DEPTH},
    {9, WIRE_C(T, state_hash), WF_U64},
    {11, WIRE_C(T, tissue), WF_TISSUE, .flags = WF_OPTIONAL, .has_off = offsetof(T, has_tissue)},
    {10, WIRE_C(T, send_time_ns), WF_U64, .flags = WF_OPTIONAL},
};
#undef T

/* ---- checks ------------------------------------------------------------------ */

/* The local force model and the contact plane are each all there or absent. */
static int check_reaction(const vctx *v, size_t i, const Ftm__V1__ProbeReaction *r)
{
    char name[64];
    const char *absent = !r->has_group            ? "group"
                         : !r->has_participant_id ? "participant_id"
                         : !r->has_probe          ? "probe"
                                                  : NULL;
    if (absent) {
        snprintf(name, sizeof name, "reactions[%zu].%s", i, absent);
        return wire_missing(v, name);
    }
    if (r->group > INT32_MAX || r->probe > INT32_MAX)
        return ftm_error_set(v->err, FTM_ERANGE, "%s: reactions[%zu]: group or probe out of range",
                             v->what, i);
    snprintf(name, sizeof name, "reactions[%zu].force", i);
    int rc = wire_check_vec3(v, name, r->force);
    if (rc)
        return rc;
    if (r->n_stiffness != 0 && r->n_stiffness != 9)
        return ftm_error_set(v->err, FTM_EINVAL,
                             "%s: reactions[%zu].stiffness has %zu values (0 or 9)", v->what, i,
                             r->n_stiffness);
    if ((r->n_stiffness == 9) != (r->hip != NULL))
        return ftm_error_set(v->err, FTM_EINVAL,
                             "%s: reactions[%zu]: stiffness and hip must come together", v->what,
                             i);
    for (size_t k = 0; k < r->n_stiffness; k++) {
        if (!isfinite(r->stiffness[k])) {
            snprintf(name, sizeof name, "reactions[%zu].stiffness[%zu]", i, k);
            return wire_check_finite(v, name, r->stiffness[k]);
        }
    }
    snprintf(name, sizeof name, "reactions[%zu].hip", i);
    if (r->hip && (rc = wire_check_vec3(v, name, r->hip)))
        return rc;
    if (!r->contact_point != !r->contact_normal)
        return ftm_error_set(
            v->err, FTM_EINVAL,
            "%s: reactions[%zu]: contact_point and contact_normal must come together", v->what, i);
    snprintf(name, sizeof name, "reactions[%zu].contact_point", i);
    if (r->contact_point && (rc = wire_check_vec3(v, name, r->contact_point)))
        return rc;
    snprintf(name, sizeof name, "reactions[%zu].contact_normal", i);
    if (r->contact_normal && (rc = wire_check_vec3(v, name, r->contact_normal)))
        return rc;
    if (r->contact_normal) {
        const Ftm__V1__Vec3 *nv = r->contact_normal;
        double len = sqrt(nv->x * nv->x + nv->y * nv->y + nv->z * nv->z);
        if (!(fabs(len - 1.0) <= 1e-6))
            return ftm_error_set(v->err, FTM_EINVAL,
                                 "%s: reactions[%zu].contact_normal has length %g (must be 1)",
                                 v->what, i, len);
    }
    return FTM_OK;
}

static int check(const vctx *v, const ProtobufCMessage *pm)
{
    const Ftm__V1__TickFrame *m = (const void *)pm;
    int rc = wire_check_contacts(v, WIRE_CONTACTS_OF(m), v->node_limit);
    if (rc)
        return rc;
    if (m->n_reactions > FTM_WIRE_REACTIONS_MAX)
        return ftm_error_set(v->err, FTM_ERANGE, "%s: %zu reactions (at most %d)", v->what,
                             m->n_reactions, FTM_WIRE_REACTIONS_MAX);
    for (size_t i = 0; i < m->n_reactions; i++)
        if ((rc = check_reaction(v, i, m->reactions[i])))
            return rc;
    return FTM_OK;
}

/* ---- conversions ----------------------------------------------------------------- */

static int from(const ProtobufCMessage *pm, ftm_wire_msg *out, ftm_error *err)
{
    const Ftm__V1__TickFrame *m = (const void *)pm;
    ftm_wire_tick *t = &out->u.tick;
    void *c = NULL, *r = NULL;
    out->storage = wire_alloc_arrays(m->n_contact_node * sizeof *t->contacts,
                                     m->n_reactions * sizeof *t->reactions, 0, &c, &r, NULL);
    if (!out->storage)
        return ftm_error_set(err, FTM_ENOMEM, "%s: out of memory", ftm_wire_kind_name(out->kind));
    t->contacts = c;
    t->reactions = r;
    t->contact_count = (int32_t)m->n_contact_node;
    wire_contacts_from(WIRE_CONTACTS_OF(m), t->contacts);
    t->reaction_count = (int32_t)m->n_reactions;
    for (size_t i = 0; i < m->n_reactions; i++) {
        const Ftm__V1__ProbeReaction *pr = m->reactions[i];
        ftm_wire_reaction *x = &t->reactions[i];
        *x = (ftm_wire_reaction){.group = (int32_t)pr->group,
                                 .participant = pr->participant_id,
                                 .probe = (int32_t)pr->probe,
                                 .force = wire_vec_from(pr->force),
                                 .push_limited = pr->has_push_limited && pr->push_limited};
        if (pr->n_stiffness == 9 && pr->hip) {
            x->has_model = true;
            x->hip = wire_vec_from(pr->hip);
            memcpy(x->stiffness, pr->stiffness, 9 * sizeof(double));
        }
        if (pr->contact_point && pr->contact_normal) {
            x->has_plane = true;
            x->contact_point = wire_vec_from(pr->contact_point);
            x->contact_normal = wire_vec_from(pr->contact_normal);
        }
    }
    return FTM_OK;
}

/* Reaction r into pr, its vectors into vec[0..3] (force, hip, contact
 * point and normal). */
static void reaction_to(const ftm_wire_reaction *r, Ftm__V1__ProbeReaction *pr,
                        Ftm__V1__Vec3 vec[4])
{
    ftm__v1__probe_reaction__init(pr);
    pr->has_group = pr->has_participant_id = pr->has_probe = 1;
    pr->group = (uint32_t)r->group;
    pr->participant_id = r->participant;
    pr->probe = (uint32_t)r->probe;
    wire_vec_to(&vec[0], r->force);
    pr->force = &vec[0];
    if (r->has_model) {
        wire_vec_to(&vec[1], r->hip);
        pr->hip = &vec[1];
        pr->n_stiffness = 9;
        pr->stiffness = (double *)r->stiffness; /* only read while packing */
    }
    pr->has_push_limited = r->push_limited;
    pr->push_limited = r->push_limited;
    if (r->has_plane) {
        wire_vec_to(&vec[2], r->contact_point);
        wire_vec_to(&vec[3], r->contact_normal);
        pr->contact_point = &vec[2];
        pr->contact_normal = &vec[3];
    }
}

static int to(const ftm_wire_msg *msg, scratch *s, ProtobufCMessage *pm, ftm_error *err)
{
    const ftm_wire_tick *t = &msg->u.tick;
    Ftm__V1__TickFrame *m = (void *)pm;
    const char *what = ftm_wire_kind_name(msg->kind);
    if (t->contact_count < 0 || (t->contact_count && !t->contacts))
        return ftm_error_set(err, FTM_EINVAL, "%s: bad contact_count %d or NULL contacts", what,
                             t->contact_count);
    if (t->reaction_count < 0 || t->reaction_count > FTM_WIRE_REACTIONS_MAX ||
        (t->reaction_count && !t->reactions))
        return ftm_error_set(err, FTM_ERANGE, "%s: bad reaction_count %d (0..%d) or NULL reactions",
                             what, t->reaction_count, FTM_WIRE_REACTIONS_MAX);
    const size_t nr = (size_t)t->reaction_count;
    Ftm__V1__ProbeReaction *rs = wire_scratch_alloc(s, nr * sizeof *rs);
    Ftm__V1__ProbeReaction **rptrs = wire_scratch_alloc(s, nr * sizeof *rptrs);
    Ftm__V1__Vec3 *vecs = wire_scratch_alloc(s, 4 * nr * sizeof *vecs);
    if (!rs || !rptrs || !vecs)
        return ftm_error_set(err, FTM_ENOMEM, "%s: out of memory", what);
    int rc = wire_contacts_to(s, what, t->contacts, t->contact_count, WIRE_CONTACTS_SET(m), err);
    if (rc)
        return rc;
    for (size_t i = 0; i < nr; i++) {
        if (t->reactions[i].group < 0 || t->reactions[i].probe < 0)
            return ftm_error_set(err, FTM_ERANGE, "%s: reactions[%zu]: negative group or probe",
                                 what, i);
        reaction_to(&t->reactions[i], &rs[i], &vecs[4 * i]);
        rptrs[i] = &rs[i];
    }
    m->n_reactions = nr;
    m->reactions = rptrs;
    return FTM_OK;
}

const wire_kind_def wire_kind_tick = {
    .kind = FTM_WIRE_TICK,
    .name = "tick frame",
    .topic = "ftm_v1_tick_frame",
    .cap = FTM_WIRE_CAP_TICK,
    .pb = &ftm__v1__tick_frame__descriptor,
    .fields = fields,
    .nfields = sizeof fields / sizeof fields[0],
    .check = check,
    .from = from,
    .to = to,
};
