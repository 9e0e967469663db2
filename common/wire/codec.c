/* The protocol codec: ftm_wire_msg <-> protobuf bytes (proto/ftm.proto).
 *
 * Decoding never trusts the input: the size is capped per kind, the bytes are
 * checked structurally first (scan.c, to name the offset and field of a
 * problem), protobuf-c unpacks with an allocator that has a byte budget (its
 * unpack has no limits of its own: 1 MB of empty submessages would become
 * ~49 MB), and the unpacked message is validated field by field before it is
 * copied into the caller's plain C structs. Encoding converts to the
 * protobuf-c structs and runs the same validation, so a sender finds out
 * before its peers do. */
#include "wire_internal.h"

#include "ftm/v1/ftm.pb-c.h"

#include <math.h>
#include <stdalign.h>
#include <stddef.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#define DEPTH_MAX 1000000u /* as ftm_sim_set_depth */

/* ---- budget allocator --------------------------------------------------- */

typedef struct budget {
    ProtobufCAllocator allocator;
    size_t used, limit;
    bool exceeded;
} budget;

#define BUDGET_HEADER (sizeof(max_align_t) > 16 ? sizeof(max_align_t) : 16)

static void *budget_alloc(void *data, size_t size)
{
    budget *b = data;
    if (size > b->limit || size + BUDGET_HEADER > b->limit - b->used) {
        b->exceeded = true;
        return NULL;
    }
    unsigned char *p = malloc(size + BUDGET_HEADER);
    if (!p)
        return NULL;
    memcpy(p, &size, sizeof size);
    b->used += size + BUDGET_HEADER;
    return p + BUDGET_HEADER;
}

static void budget_free(void *data, void *ptr)
{
    if (!ptr)
        return;
    budget *b = data;
    unsigned char *p = (unsigned char *)ptr - BUDGET_HEADER;
    size_t size;
    memcpy(&size, p, sizeof size);
    b->used -= size + BUDGET_HEADER;
    free(p);
}

/* ---- tables ------------------------------------------------------------- */

const ProtobufCMessageDescriptor *wire_descriptor(int kind)
{
    switch (kind) {
    case FTM_WIRE_ANNOUNCE: return &ftm__v1__scene_announce__descriptor;
    case FTM_WIRE_PROBE_INPUT: return &ftm__v1__probe_input__descriptor;
    case FTM_WIRE_TICK: return &ftm__v1__tick_frame__descriptor;
    case FTM_WIRE_KEYFRAME: return &ftm__v1__keyframe__descriptor;
    case FTM_WIRE_STATUS: return &ftm__v1__participant_status__descriptor;
    case FTM_WIRE_CONTROL: return &ftm__v1__session_control__descriptor;
    case FTM_WIRE_CONTROL_REPLY: return &ftm__v1__control_reply__descriptor;
    default: return NULL;
    }
}

size_t ftm_wire_default_cap(int kind)
{
    switch (kind) {
    case FTM_WIRE_ANNOUNCE: return FTM_WIRE_CAP_ANNOUNCE;
    case FTM_WIRE_PROBE_INPUT: return FTM_WIRE_CAP_PROBE_INPUT;
    case FTM_WIRE_TICK: return FTM_WIRE_CAP_TICK;
    case FTM_WIRE_KEYFRAME: return FTM_WIRE_CAP_KEYFRAME;
    case FTM_WIRE_STATUS: return FTM_WIRE_CAP_STATUS;
    case FTM_WIRE_CONTROL: return FTM_WIRE_CAP_CONTROL;
    case FTM_WIRE_CONTROL_REPLY: return FTM_WIRE_CAP_CONTROL_REPLY;
    default: return 0;
    }
}

size_t wire_payload_cap(const ftm_wire_limits *limits, int kind)
{
    return limits && limits->max_payload ? limits->max_payload : ftm_wire_default_cap(kind);
}

/* ---- validation of unpacked (or about to be packed) protobuf-c structs ---- */

typedef struct vctx {
    const char *what; /* kind name */
    ftm_error *err;
    uint32_t node_limit; /* node indices must be below this */
    uint32_t scene_nodes; /* 0: unknown */
} vctx;

static int missing(const vctx *v, const char *field)
{
    return ftm_error_set(v->err, FTM_EPARSE, "%s: missing field %s", v->what, field);
}

static int check_version(const vctx *v, protobuf_c_boolean has, uint32_t version)
{
    if (!has)
        return missing(v, "version");
    if (version != FTM_WIRE_VERSION)
        return ftm_error_set(v->err, FTM_EVERSION,
                             "%s: protocol version %u, this side speaks version %u (ftm.v%u)",
                             v->what, version, FTM_WIRE_VERSION, FTM_WIRE_VERSION);
    return FTM_OK;
}

static int check_finite(const vctx *v, const char *field, double x)
{
    if (!isfinite(x))
        return ftm_error_set(v->err, FTM_EINVAL, "%s: %s is not finite (%g)", v->what, field, x);
    return FTM_OK;
}

static int check_vec3(const vctx *v, const char *field, const Ftm__V1__Vec3 *p)
{
    char name[96];
    if (!p)
        return missing(v, field);
    if (!p->has_x || !p->has_y || !p->has_z) {
        snprintf(name, sizeof name, "%s.%s", field, !p->has_x ? "x" : !p->has_y ? "y" : "z");
        return missing(v, name);
    }
    const double c[3] = {p->x, p->y, p->z};
    for (int i = 0; i < 3; i++) {
        if (!isfinite(c[i])) {
            snprintf(name, sizeof name, "%s.%c", field, "xyz"[i]);
            return check_finite(v, name, c[i]);
        }
    }
    return FTM_OK;
}

static int check_depth(const vctx *v, const char *field, uint32_t depth)
{
    if (depth > DEPTH_MAX)
        return ftm_error_set(v->err, FTM_ERANGE, "%s: %s %u out of range (0..%u)", v->what, field,
                             depth, DEPTH_MAX);
    return FTM_OK;
}

static int check_tissue(const vctx *v, const char *field, const Ftm__V1__TissueParams *t)
{
    char name[96];
    if (!t)
        return missing(v, field);
    struct {
        protobuf_c_boolean has;
        double value;
        const char *name;
        bool zero_ok;
    } f[3] = {{t->has_node_mass, t->node_mass, "node_mass", false},
              {t->has_node_damping, t->node_damping, "node_damping", true},
              {t->has_stiffness, t->stiffness, "stiffness", false}};
    for (int i = 0; i < 3; i++) {
        snprintf(name, sizeof name, "%s.%s", field, f[i].name);
        if (!f[i].has)
            return missing(v, name);
        int rc = check_finite(v, name, f[i].value);
        if (rc)
            return rc;
        if (f[i].value < 0 || (f[i].value == 0 && !f[i].zero_ok))
            return ftm_error_set(v->err, FTM_EINVAL, "%s: %s must be %s (got %g)", v->what, name,
                                 f[i].zero_ok ? ">= 0" : "> 0", f[i].value);
    }
    snprintf(name, sizeof name, "%s.axis_scale", field);
    int rc = check_vec3(v, name, t->axis_scale);
    if (rc)
        return rc;
    if (!(t->axis_scale->x > 0 && t->axis_scale->y > 0 && t->axis_scale->z > 0))
        return ftm_error_set(v->err, FTM_EINVAL, "%s: %s must be > 0 in every axis", v->what, name);
    return FTM_OK;
}

static int check_limits(const vctx *v, const char *field, const Ftm__V1__DepthLimits *d)
{
    char name[96];
    if (!d)
        return missing(v, field);
    if (!d->has_min || !d->has_max) {
        snprintf(name, sizeof name, "%s.%s", field, !d->has_min ? "min" : "max");
        return missing(v, name);
    }
    snprintf(name, sizeof name, "%s.max", field);
    int rc = check_depth(v, name, d->max);
    if (rc)
        return rc;
    if (d->min > d->max)
        return ftm_error_set(v->err, FTM_EINVAL, "%s: %s.min %u above max %u", v->what, field,
                             d->min, d->max);
    return FTM_OK;
}

static int check_announce(const vctx *v, const Ftm__V1__SceneAnnounce *m)
{
    int rc = check_version(v, m->has_version, m->version);
    if (rc)
        return rc;
    if (!m->scene_id || !m->scene_id[0])
        return missing(v, "scene_id");
    if (strlen(m->scene_id) >= FTM_WIRE_NAME_MAX)
        return ftm_error_set(v->err, FTM_EINVAL, "%s: scene_id of %zu bytes (at most %d)", v->what,
                             strlen(m->scene_id), FTM_WIRE_NAME_MAX - 1);
    if (!m->has_content_digest || m->content_digest.len == 0)
        return missing(v, "content_digest");
    if (m->content_digest.len > FTM_WIRE_DIGEST_MAX)
        return ftm_error_set(v->err, FTM_EINVAL, "%s: content_digest of %zu bytes (at most %d)",
                             v->what, m->content_digest.len, FTM_WIRE_DIGEST_MAX);
    if (!m->has_tick_rate_hz)
        return missing(v, "tick_rate_hz");
    if (m->tick_rate_hz == 0)
        return ftm_error_set(v->err, FTM_EINVAL, "%s: tick_rate_hz must be > 0", v->what);
    if (!m->has_time_step)
        return missing(v, "time_step");
    if ((rc = check_finite(v, "time_step", m->time_step)))
        return rc;
    if (!(m->time_step > 0))
        return ftm_error_set(v->err, FTM_EINVAL, "%s: time_step must be > 0 (got %g)", v->what,
                             m->time_step);
    if (!m->has_depth)
        return missing(v, "depth");
    if ((rc = check_depth(v, "depth", m->depth)))
        return rc;
    if ((rc = check_limits(v, "depth_limits", m->depth_limits)))
        return rc;
    if ((rc = check_tissue(v, "tissue", m->tissue)))
        return rc;
    if (!m->has_node_count)
        return missing(v, "node_count");
    if (m->node_count == 0 || m->node_count > INT32_MAX)
        return ftm_error_set(v->err, FTM_ERANGE, "%s: node_count %u out of range (1..%d)", v->what,
                             m->node_count, INT32_MAX);
    if (!m->has_tick)
        return missing(v, "tick");
    if (!m->has_paused)
        return missing(v, "paused");
    return FTM_OK;
}

static int check_probe_input(const vctx *v, const Ftm__V1__ProbeInput *m)
{
    int rc = check_version(v, m->has_version, m->version);
    if (rc)
        return rc;
    if (!m->has_participant_id)
        return missing(v, "participant_id");
    if (!m->has_last_tick_seen)
        return missing(v, "last_tick_seen");
    if (m->n_samples > FTM_WIRE_SAMPLES_MAX)
        return ftm_error_set(v->err, FTM_ERANGE, "%s: %zu samples (at most %d)", v->what,
                             m->n_samples, FTM_WIRE_SAMPLES_MAX);
    for (size_t i = 0; i < m->n_samples; i++) {
        const Ftm__V1__ProbeSample *s = m->samples[i];
        char name[64];
        if (!s->has_probe || !s->has_device_time_ns) {
            snprintf(name, sizeof name, "samples[%zu].%s", i, !s->has_probe ? "probe" : "device_time_ns");
            return missing(v, name);
        }
        if (s->probe > INT32_MAX)
            return ftm_error_set(v->err, FTM_ERANGE, "%s: samples[%zu].probe %u out of range",
                                 v->what, i, s->probe);
        snprintf(name, sizeof name, "samples[%zu].position", i);
        if ((rc = check_vec3(v, name, s->position)))
            return rc;
    }
    return FTM_OK;
}

/* Contact columns (tick frames, keyframes): equal lengths, nodes below
 * limit, known kinds, finite values. */
static int check_contacts(const vctx *v, size_t n, const uint32_t *node, size_t n_group,
                          const uint32_t *group, size_t n_kind, const Ftm__V1__ContactKind *kind,
                          size_t n_value, const double *value, uint32_t limit)
{
    if (n > INT32_MAX || n_group != n || n_kind != n || n_value != 3 * n)
        return ftm_error_set(v->err, FTM_EINVAL,
                             "%s: contact columns disagree: %zu nodes, %zu groups, %zu kinds, "
                             "%zu values (want 3 per node)",
                             v->what, n, n_group, n_kind, n_value);
    for (size_t i = 0; i < n; i++) {
        if (node[i] >= limit) {
            if (v->scene_nodes)
                return ftm_error_set(v->err, FTM_ERANGE,
                                     "%s: contact %zu: node %u out of range (scene has %u nodes)",
                                     v->what, i, node[i], v->scene_nodes);
            return ftm_error_set(v->err, FTM_ERANGE, "%s: contact %zu: node %u out of range",
                                 v->what, i, node[i]);
        }
        if (group[i] > INT32_MAX)
            return ftm_error_set(v->err, FTM_ERANGE, "%s: contact %zu: group %u out of range",
                                 v->what, i, group[i]);
        if ((int)kind[i] != FTM__V1__CONTACT_KIND__CONTACT_FORCE &&
            (int)kind[i] != FTM__V1__CONTACT_KIND__CONTACT_DISPLACEMENT)
            return ftm_error_set(v->err, FTM_EINVAL, "%s: contact %zu: unknown contact kind %d",
                                 v->what, i, (int)kind[i]);
        for (int c = 0; c < 3; c++) {
            double x = value[3 * i + (size_t)c];
            if (!isfinite(x))
                return ftm_error_set(v->err, FTM_EINVAL,
                                     "%s: contact %zu: value.%c is not finite (%g)", v->what, i,
                                     "xyz"[c], x);
        }
    }
    return FTM_OK;
}

static int check_tick(const vctx *v, const Ftm__V1__TickFrame *m)
{
    int rc = check_version(v, m->has_version, m->version);
    if (rc)
        return rc;
    if (!m->has_tick)
        return missing(v, "tick");
    if (!m->has_depth)
        return missing(v, "depth");
    if ((rc = check_depth(v, "depth", m->depth)))
        return rc;
    if (!m->has_state_hash)
        return missing(v, "state_hash");
    if (m->tissue && (rc = check_tissue(v, "tissue", m->tissue)))
        return rc;
    if ((rc = check_contacts(v, m->n_contact_node, m->contact_node, m->n_contact_group,
                             m->contact_group, m->n_contact_kind, m->contact_kind,
                             m->n_contact_value, m->contact_value, v->node_limit)))
        return rc;
    if (m->n_reactions > FTM_WIRE_REACTIONS_MAX)
        return ftm_error_set(v->err, FTM_ERANGE, "%s: %zu reactions (at most %d)", v->what,
                             m->n_reactions, FTM_WIRE_REACTIONS_MAX);
    for (size_t i = 0; i < m->n_reactions; i++) {
        const Ftm__V1__ProbeReaction *r = m->reactions[i];
        char name[64];
        const char *absent = !r->has_group ? "group"
                             : !r->has_participant_id ? "participant_id"
                             : !r->has_probe ? "probe"
                                             : NULL;
        if (absent) {
            snprintf(name, sizeof name, "reactions[%zu].%s", i, absent);
            return missing(v, name);
        }
        if (r->group > INT32_MAX || r->probe > INT32_MAX)
            return ftm_error_set(v->err, FTM_ERANGE,
                                 "%s: reactions[%zu]: group or probe out of range", v->what, i);
        snprintf(name, sizeof name, "reactions[%zu].force", i);
        if ((rc = check_vec3(v, name, r->force)))
            return rc;
        if (r->n_stiffness != 0 && r->n_stiffness != 9)
            return ftm_error_set(v->err, FTM_EINVAL,
                                 "%s: reactions[%zu].stiffness has %zu values (0 or 9)", v->what, i,
                                 r->n_stiffness);
        if ((r->n_stiffness == 9) != (r->hip != NULL))
            return ftm_error_set(v->err, FTM_EINVAL,
                                 "%s: reactions[%zu]: stiffness and hip must come together",
                                 v->what, i);
        for (size_t k = 0; k < r->n_stiffness; k++) {
            if (!isfinite(r->stiffness[k])) {
                snprintf(name, sizeof name, "reactions[%zu].stiffness[%zu]", i, k);
                return check_finite(v, name, r->stiffness[k]);
            }
        }
        snprintf(name, sizeof name, "reactions[%zu].hip", i);
        if (r->hip && (rc = check_vec3(v, name, r->hip)))
            return rc;
        if (!r->contact_point != !r->contact_normal)
            return ftm_error_set(
                v->err, FTM_EINVAL,
                "%s: reactions[%zu]: contact_point and contact_normal must come together", v->what,
                i);
        snprintf(name, sizeof name, "reactions[%zu].contact_point", i);
        if (r->contact_point && (rc = check_vec3(v, name, r->contact_point)))
            return rc;
        snprintf(name, sizeof name, "reactions[%zu].contact_normal", i);
        if (r->contact_normal && (rc = check_vec3(v, name, r->contact_normal)))
            return rc;
        if (r->contact_normal) {
            const Ftm__V1__Vec3 *nv = r->contact_normal;
            double len = sqrt(nv->x * nv->x + nv->y * nv->y + nv->z * nv->z);
            if (!(fabs(len - 1.0) <= 1e-6))
                return ftm_error_set(v->err, FTM_EINVAL,
                                     "%s: reactions[%zu].contact_normal has length %g (must be 1)",
                                     v->what, i, len);
        }
    }
    return FTM_OK;
}

#define SUBSTEPS_MAX 1024u /* far above any sim's max_substeps; the sim checks its own */

static int check_mode(const vctx *v, const Ftm__V1__IntegratorMode *m)
{
    if (!m->has_substeps)
        return missing(v, "mode.substeps");
    if (!m->has_steps_at_substeps)
        return missing(v, "mode.steps_at_substeps");
    if (!m->has_quiet_steps)
        return missing(v, "mode.quiet_steps");
    if (!m->has_region_sleeping)
        return missing(v, "mode.region_sleeping");
    if (!m->has_energy_budget)
        return missing(v, "mode.energy_budget");
    if (!m->has_energy_prev)
        return missing(v, "mode.energy_prev");
    if (m->substeps < 1 || m->substeps > SUBSTEPS_MAX)
        return ftm_error_set(v->err, FTM_ERANGE, "%s: mode.substeps %u out of range (1..%u)",
                             v->what, m->substeps, SUBSTEPS_MAX);
    if (m->steps_at_substeps > INT32_MAX || m->quiet_steps > INT32_MAX)
        return ftm_error_set(v->err, FTM_ERANGE, "%s: mode step counters out of range (%u, %u)",
                             v->what, m->steps_at_substeps, m->quiet_steps);
    int rc;
    if ((rc = check_finite(v, "mode.energy_budget", m->energy_budget)) ||
        (rc = check_finite(v, "mode.energy_prev", m->energy_prev)))
        return rc;
    if (m->energy_prev < 0)
        return ftm_error_set(v->err, FTM_EINVAL, "%s: mode.energy_prev must be >= 0 (got %g)",
                             v->what, m->energy_prev);
    return FTM_OK;
}

static int check_keyframe(const vctx *v, const Ftm__V1__Keyframe *m)
{
    int rc = check_version(v, m->has_version, m->version);
    if (rc)
        return rc;
    if (!m->has_tick)
        return missing(v, "tick");
    if (!m->has_state_hash)
        return missing(v, "state_hash");
    if (!m->has_node_count)
        return missing(v, "node_count");
    if (!m->has_depth)
        return missing(v, "depth");
    if ((rc = check_depth(v, "depth", m->depth)))
        return rc;
    if (m->tissue && (rc = check_tissue(v, "tissue", m->tissue)))
        return rc;
    if (m->mode && (rc = check_mode(v, m->mode)))
        return rc;
    if (m->node_count == 0 || m->node_count > INT32_MAX)
        return ftm_error_set(v->err, FTM_ERANGE, "%s: node_count %u out of range (1..%d)", v->what,
                             m->node_count, INT32_MAX);
    if ((rc = check_contacts(v, m->n_contact_node, m->contact_node, m->n_contact_group,
                             m->contact_group, m->n_contact_kind, m->contact_kind,
                             m->n_contact_value, m->contact_value, m->node_count)))
        return rc;
    if (v->scene_nodes && m->node_count != v->scene_nodes)
        return ftm_error_set(v->err, FTM_ERANGE, "%s: for a mesh of %u nodes, scene has %u nodes",
                             v->what, m->node_count, v->scene_nodes);
    size_t n = m->n_node;
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

/* Text shown on a HUD and written to logs and terminals (a display name, a
 * reason): shorter than cap bytes and no control bytes, so that a peer
 * cannot put escape sequences or line breaks into anyone's terminal. */
static int check_text(const vctx *v, const char *field, const char *text, size_t cap)
{
    const size_t n = text ? strlen(text) : 0;
    if (n >= cap)
        return ftm_error_set(v->err, FTM_EINVAL, "%s: %s of %zu bytes (at most %zu)", v->what,
                             field, n, cap - 1);
    for (size_t i = 0; i < n; i++) {
        const unsigned char c = (unsigned char)text[i];
        if (c < 0x20 || c == 0x7f)
            return ftm_error_set(v->err, FTM_EINVAL,
                                 "%s: %s has control character 0x%02x at byte %zu", v->what, field,
                                 c, i);
    }
    return FTM_OK;
}

static int check_status(const vctx *v, const Ftm__V1__ParticipantStatus *m)
{
    int rc = check_version(v, m->has_version, m->version);
    if (rc)
        return rc;
    if (!m->has_participant_id)
        return missing(v, "participant_id");
    if (!m->has_role)
        return missing(v, "role");
    if ((int)m->role < FTM_WIRE_ROLE_SERVER || (int)m->role > FTM_WIRE_ROLE_BOT)
        return ftm_error_set(v->err, FTM_EINVAL, "%s: unknown role %d", v->what, (int)m->role);
    if (!m->has_state)
        return missing(v, "state");
    if ((int)m->state < FTM_WIRE_STATE_JOINING || (int)m->state > FTM_WIRE_STATE_LEAVING)
        return ftm_error_set(v->err, FTM_EINVAL, "%s: unknown state %d", v->what, (int)m->state);
    if (!m->has_last_applied_tick)
        return missing(v, "last_applied_tick");
    if (!m->has_state_hash)
        return missing(v, "state_hash");
    if (!m->has_replay_ns_per_tick)
        return missing(v, "replay_ns_per_tick");
    if (!m->has_replay_ns_max)
        return missing(v, "replay_ns_max");
    if ((rc = check_finite(v, "replay_ns_per_tick", m->replay_ns_per_tick)) ||
        (rc = check_finite(v, "replay_ns_max", m->replay_ns_max)))
        return rc;
    if (m->replay_ns_per_tick < 0 || m->replay_ns_max < 0)
        return ftm_error_set(v->err, FTM_EINVAL, "%s: negative replay time", v->what);
    if ((rc = check_text(v, "name", m->name, FTM_WIRE_DISPLAY_MAX)))
        return rc;
    if (m->n_ignored_participant != m->n_ignored_origin)
        return ftm_error_set(v->err, FTM_EINVAL,
                             "%s: %zu ignored_participant but %zu ignored_origin", v->what,
                             m->n_ignored_participant, m->n_ignored_origin);
    if (m->n_ignored_participant > FTM_WIRE_IGNORED_MAX)
        return ftm_error_set(v->err, FTM_ERANGE, "%s: %zu ignored processes (at most %d)", v->what,
                             m->n_ignored_participant, FTM_WIRE_IGNORED_MAX);
    if (m->n_ignored_participant && (int)m->role != FTM_WIRE_ROLE_SERVER)
        return ftm_error_set(v->err, FTM_EINVAL,
                             "%s: ignored processes in a %s's status (a server's only)", v->what,
                             ftm_wire_role_name((ftm_wire_role)m->role));
    if (m->n_holder_participant != m->n_holder_origin)
        return ftm_error_set(v->err, FTM_EINVAL, "%s: %zu holder_participant but %zu holder_origin",
                             v->what, m->n_holder_participant, m->n_holder_origin);
    if (m->n_holder_participant > FTM_WIRE_HOLDERS_MAX)
        return ftm_error_set(v->err, FTM_ERANGE, "%s: %zu holders (at most %d)", v->what,
                             m->n_holder_participant, FTM_WIRE_HOLDERS_MAX);
    if (m->n_holder_participant && (int)m->role != FTM_WIRE_ROLE_SERVER)
        return ftm_error_set(v->err, FTM_EINVAL, "%s: holders in a %s's status (a server's only)",
                             v->what, ftm_wire_role_name((ftm_wire_role)m->role));
    /* one process per id: a second pair for an id would make "the server
     * hears us" ambiguous */
    for (size_t i = 1; i < m->n_holder_participant; i++)
        for (size_t j = 0; j < i; j++)
            if (m->holder_participant[i] == m->holder_participant[j])
                return ftm_error_set(v->err, FTM_EINVAL, "%s: holder_participant %u listed twice",
                                     v->what, m->holder_participant[i]);
    return FTM_OK;
}

static int check_control(const vctx *v, const Ftm__V1__SessionControl *m)
{
    int rc = check_version(v, m->has_version, m->version);
    if (rc)
        return rc;
    if (!m->has_issuer_id)
        return missing(v, "issuer_id");
    if (!m->has_command_id)
        return missing(v, "command_id");
    switch (m->command_case) {
    case FTM__V1__SESSION_CONTROL__COMMAND_PAUSE:
    case FTM__V1__SESSION_CONTROL__COMMAND_RESUME:
    case FTM__V1__SESSION_CONTROL__COMMAND_RESET: return FTM_OK;
    case FTM__V1__SESSION_CONTROL__COMMAND_TISSUE: return check_tissue(v, "tissue", m->tissue);
    case FTM__V1__SESSION_CONTROL__COMMAND_DEPTH_LIMITS:
        return check_limits(v, "depth_limits", m->depth_limits);
    default: return missing(v, "command (one of pause, resume, reset, tissue, depth_limits)");
    }
}

/* The reason is shown on an instructor's HUD and written to logs and
 * terminals: bounded, and no control bytes (escape sequences, newlines). */
static int check_control_reply(const vctx *v, const Ftm__V1__ControlReply *m)
{
    int rc = check_version(v, m->has_version, m->version);
    if (rc)
        return rc;
    if (!m->has_issuer_id)
        return missing(v, "issuer_id");
    if (!m->has_command_id)
        return missing(v, "command_id");
    if (!m->has_outcome)
        return missing(v, "outcome");
    if ((int)m->outcome < FTM_WIRE_OUTCOME_APPLIED || (int)m->outcome > FTM_WIRE_OUTCOME_REFUSED)
        return ftm_error_set(v->err, FTM_EINVAL, "%s: unknown outcome %d", v->what,
                             (int)m->outcome);
    if (!m->has_tick)
        return missing(v, "tick");
    if ((rc = check_text(v, "reason", m->reason, FTM_WIRE_REASON_MAX)))
        return rc;
    if ((!m->reason || !m->reason[0]) && (int)m->outcome != FTM_WIRE_OUTCOME_APPLIED)
        return ftm_error_set(v->err, FTM_EINVAL, "%s: a %s command needs a reason", v->what,
                             ftm_wire_outcome_name((ftm_wire_outcome)m->outcome));
    return FTM_OK;
}

static int check_any(const vctx *v, int kind, const ProtobufCMessage *m)
{
    switch (kind) {
    case FTM_WIRE_ANNOUNCE: return check_announce(v, (const Ftm__V1__SceneAnnounce *)m);
    case FTM_WIRE_PROBE_INPUT: return check_probe_input(v, (const Ftm__V1__ProbeInput *)m);
    case FTM_WIRE_TICK: return check_tick(v, (const Ftm__V1__TickFrame *)m);
    case FTM_WIRE_KEYFRAME: return check_keyframe(v, (const Ftm__V1__Keyframe *)m);
    case FTM_WIRE_STATUS: return check_status(v, (const Ftm__V1__ParticipantStatus *)m);
    case FTM_WIRE_CONTROL: return check_control(v, (const Ftm__V1__SessionControl *)m);
    case FTM_WIRE_CONTROL_REPLY: return check_control_reply(v, (const Ftm__V1__ControlReply *)m);
    default: return ftm_error_set(v->err, FTM_EINVAL, "unknown message kind %d", kind);
    }
}

/* ---- protobuf-c -> plain C ---------------------------------------------- */

static ftm_vec3 vec_from(const Ftm__V1__Vec3 *p)
{
    return (ftm_vec3){p->x, p->y, p->z};
}

static ftm_wire_tissue tissue_from(const Ftm__V1__TissueParams *t)
{
    return (ftm_wire_tissue){t->node_mass, t->node_damping, t->stiffness, vec_from(t->axis_scale)};
}

/* One allocation holding up to three arrays, each 16-byte aligned. */
static void *alloc_arrays(size_t a, size_t b, size_t c, void **pa, void **pb, void **pc)
{
    size_t ra = (a + 15) & ~(size_t)15, rb = (b + 15) & ~(size_t)15;
    size_t total = ra + rb + c;
    unsigned char *p = malloc(total ? total : 1);
    if (!p)
        return NULL;
    *pa = p;
    if (pb)
        *pb = p + ra;
    if (pc)
        *pc = p + ra + rb;
    return p;
}

static void contacts_from(const uint32_t *node, const uint32_t *group,
                          const Ftm__V1__ContactKind *kind, const double *value, size_t n,
                          ftm_contact *out)
{
    for (size_t i = 0; i < n; i++)
        out[i] = (ftm_contact){.node = (int32_t)node[i],
                               .group = (int32_t)group[i],
                               .kind = kind[i] == FTM__V1__CONTACT_KIND__CONTACT_FORCE
                                           ? FTM_CONTACT_FORCE
                                           : FTM_CONTACT_DISPLACEMENT,
                               .value = {value[3 * i], value[3 * i + 1], value[3 * i + 2]}};
}

static int convert(int kind, const ProtobufCMessage *pm, ftm_wire_msg *out, ftm_error *err)
{
    memset(out, 0, sizeof *out);
    out->kind = (ftm_wire_kind)kind;
    const char *what = ftm_wire_kind_name(kind);
    switch (kind) {
    case FTM_WIRE_ANNOUNCE: {
        const Ftm__V1__SceneAnnounce *m = (const void *)pm;
        ftm_wire_announce *a = &out->u.announce;
        snprintf(a->scene_id, sizeof a->scene_id, "%s", m->scene_id);
        memcpy(a->digest, m->content_digest.data, m->content_digest.len);
        a->digest_len = (int32_t)m->content_digest.len;
        a->tick_rate_hz = m->tick_rate_hz;
        a->time_step = m->time_step;
        a->depth = (int32_t)m->depth;
        a->depth_min = (int32_t)m->depth_limits->min;
        a->depth_max = (int32_t)m->depth_limits->max;
        a->tissue = tissue_from(m->tissue);
        a->node_count = (int32_t)m->node_count;
        a->tick = m->tick;
        a->paused = m->paused != 0;
        a->server_start_ns = m->has_server_start_ns ? m->server_start_ns : 0;
        a->arithmetic = m->has_arithmetic ? m->arithmetic : 0;
        return FTM_OK;
    }
    case FTM_WIRE_PROBE_INPUT: {
        const Ftm__V1__ProbeInput *m = (const void *)pm;
        ftm_wire_probe_input *p = &out->u.probe_input;
        void *s = NULL;
        if (!(out->storage = alloc_arrays(m->n_samples * sizeof *p->samples, 0, 0, &s, NULL, NULL)))
            return ftm_error_set(err, FTM_ENOMEM, "%s: out of memory", what);
        p->samples = s;
        p->participant = m->participant_id;
        p->last_tick_seen = m->last_tick_seen;
        p->sample_count = (int32_t)m->n_samples;
        for (size_t i = 0; i < m->n_samples; i++)
            p->samples[i] = (ftm_wire_probe_sample){(int32_t)m->samples[i]->probe,
                                                    m->samples[i]->device_time_ns,
                                                    vec_from(m->samples[i]->position)};
        return FTM_OK;
    }
    case FTM_WIRE_TICK: {
        const Ftm__V1__TickFrame *m = (const void *)pm;
        ftm_wire_tick *t = &out->u.tick;
        void *c = NULL, *r = NULL;
        out->storage = alloc_arrays(m->n_contact_node * sizeof *t->contacts,
                                    m->n_reactions * sizeof *t->reactions, 0, &c, &r, NULL);
        if (!out->storage)
            return ftm_error_set(err, FTM_ENOMEM, "%s: out of memory", what);
        t->contacts = c;
        t->reactions = r;
        t->tick = m->tick;
        t->depth = (int32_t)m->depth;
        t->state_hash = m->state_hash;
        t->send_time_ns = m->has_send_time_ns ? m->send_time_ns : 0;
        t->has_tissue = m->tissue != NULL;
        if (m->tissue)
            t->tissue = tissue_from(m->tissue);
        t->contact_count = (int32_t)m->n_contact_node;
        contacts_from(m->contact_node, m->contact_group, m->contact_kind, m->contact_value,
                      m->n_contact_node, t->contacts);
        t->reaction_count = (int32_t)m->n_reactions;
        for (size_t i = 0; i < m->n_reactions; i++) {
            const Ftm__V1__ProbeReaction *pr = m->reactions[i];
            t->reactions[i] = (ftm_wire_reaction){.group = (int32_t)pr->group,
                                                  .participant = pr->participant_id,
                                                  .probe = (int32_t)pr->probe,
                                                  .force = vec_from(pr->force),
                                                  .push_limited = pr->has_push_limited &&
                                                                  pr->push_limited};
            if (pr->n_stiffness == 9 && pr->hip) {
                t->reactions[i].has_model = true;
                t->reactions[i].hip = vec_from(pr->hip);
                memcpy(t->reactions[i].stiffness, pr->stiffness, 9 * sizeof(double));
            }
            if (pr->contact_point && pr->contact_normal) {
                t->reactions[i].has_plane = true;
                t->reactions[i].contact_point = vec_from(pr->contact_point);
                t->reactions[i].contact_normal = vec_from(pr->contact_normal);
            }
        }
        return FTM_OK;
    }
    case FTM_WIRE_KEYFRAME: {
        const Ftm__V1__Keyframe *m = (const void *)pm;
        ftm_wire_keyframe *k = &out->u.keyframe;
        size_t n = m->n_node, nc = m->n_contact_node;
        void *pos = NULL, *cts = NULL, *nodes = NULL;
        out->storage = alloc_arrays(6 * n * sizeof(double), nc * sizeof(ftm_contact),
                                    n * sizeof(int32_t), &pos, &cts, &nodes);
        if (!out->storage)
            return ftm_error_set(err, FTM_ENOMEM, "%s: out of memory", what);
        k->positions = pos;
        k->previous = k->positions + 3 * n;
        k->nodes = nodes;
        k->contacts = cts;
        k->contact_count = (int32_t)nc;
        contacts_from(m->contact_node, m->contact_group, m->contact_kind, m->contact_value, nc,
                      k->contacts);
        k->tick = m->tick;
        k->state_hash = m->state_hash;
        k->node_count = (int32_t)m->node_count;
        k->depth = (int32_t)m->depth;
        k->count = (int32_t)n;
        k->has_tissue = m->tissue != NULL;
        if (m->tissue)
            k->tissue = tissue_from(m->tissue);
        k->has_mode = m->mode != NULL;
        if (m->mode)
            k->mode = (ftm_sim_mode){(int32_t)m->mode->substeps,
                                     (int32_t)m->mode->steps_at_substeps,
                                     (int32_t)m->mode->quiet_steps, m->mode->region_sleeping != 0,
                                     m->mode->energy_budget, m->mode->energy_prev};
        for (size_t i = 0; i < n; i++)
            k->nodes[i] = (int32_t)m->node[i];
        if (n) {
            memcpy(k->positions, m->position, 3 * n * sizeof(double));
            memcpy(k->previous, m->previous, 3 * n * sizeof(double));
        }
        return FTM_OK;
    }
    case FTM_WIRE_STATUS: {
        const Ftm__V1__ParticipantStatus *m = (const void *)pm;
        ftm_wire_status *s = &out->u.status;
        s->participant = m->participant_id;
        s->role = (ftm_wire_role)m->role;
        s->state = (ftm_wire_state)m->state;
        s->last_applied_tick = m->last_applied_tick;
        s->state_hash = m->state_hash;
        s->replay_ns_per_tick = m->replay_ns_per_tick;
        s->replay_ns_max = m->replay_ns_max;
        snprintf(s->name, sizeof s->name, "%s", m->name ? m->name : "");
        s->ignored_count = (int32_t)m->n_ignored_participant; /* <= FTM_WIRE_IGNORED_MAX: checked */
        for (size_t i = 0; i < m->n_ignored_participant; i++) {
            s->ignored_participant[i] = m->ignored_participant[i];
            s->ignored_origin[i] = m->ignored_origin[i];
        }
        s->holder_count = (int32_t)m->n_holder_participant; /* <= FTM_WIRE_HOLDERS_MAX: checked */
        for (size_t i = 0; i < m->n_holder_participant; i++) {
            s->holder_participant[i] = m->holder_participant[i];
            s->holder_origin[i] = m->holder_origin[i];
        }
        return FTM_OK;
    }
    case FTM_WIRE_CONTROL: {
        const Ftm__V1__SessionControl *m = (const void *)pm;
        ftm_wire_control *c = &out->u.control;
        c->issuer = m->issuer_id;
        c->command_id = m->command_id;
        switch (m->command_case) {
        case FTM__V1__SESSION_CONTROL__COMMAND_PAUSE: c->command = FTM_WIRE_CMD_PAUSE; break;
        case FTM__V1__SESSION_CONTROL__COMMAND_RESUME: c->command = FTM_WIRE_CMD_RESUME; break;
        case FTM__V1__SESSION_CONTROL__COMMAND_RESET: c->command = FTM_WIRE_CMD_RESET; break;
        case FTM__V1__SESSION_CONTROL__COMMAND_TISSUE:
            c->command = FTM_WIRE_CMD_TISSUE;
            c->tissue = tissue_from(m->tissue);
            break;
        default:
            c->command = FTM_WIRE_CMD_DEPTH_LIMITS;
            c->depth_min = (int32_t)m->depth_limits->min;
            c->depth_max = (int32_t)m->depth_limits->max;
            break;
        }
        return FTM_OK;
    }
    case FTM_WIRE_CONTROL_REPLY: {
        const Ftm__V1__ControlReply *m = (const void *)pm;
        ftm_wire_control_reply *r = &out->u.control_reply;
        r->issuer = m->issuer_id;
        r->command_id = m->command_id;
        r->outcome = (ftm_wire_outcome)m->outcome;
        r->tick = m->tick;
        snprintf(r->reason, sizeof r->reason, "%s", m->reason ? m->reason : "");
        return FTM_OK;
    }
    default: return ftm_error_set(err, FTM_EINVAL, "unknown message kind %d", kind);
    }
}

void ftm_wire_msg_free(ftm_wire_msg *msg)
{
    if (!msg)
        return;
    free(msg->storage);
    memset(msg, 0, sizeof *msg);
}

int ftm_wire_decode(int kind, const void *data, size_t size, const ftm_wire_limits *limits,
                    ftm_wire_msg *out, ftm_error *err)
{
    if (!out)
        return ftm_error_set(err, FTM_EINVAL, "ftm_wire_decode: out is NULL");
    memset(out, 0, sizeof *out);
    const ProtobufCMessageDescriptor *desc = wire_descriptor(kind);
    if (!desc)
        return ftm_error_set(err, FTM_EINVAL, "unknown message kind %d", kind);
    const char *what = ftm_wire_kind_name(kind);
    if (!data && size)
        return ftm_error_set(err, FTM_EINVAL, "%s: payload is NULL", what);
    size_t cap = wire_payload_cap(limits, kind);
    if (size > cap)
        return ftm_error_set(err, FTM_ETOOBIG, "%s: payload of %zu bytes exceeds the %zu-byte cap",
                             what, size, cap);
    if (size == 0)
        return ftm_error_set(err, FTM_EPARSE, "%s: empty payload", what);
    int rc = wire_scan(desc, data, size, what, err);
    if (rc)
        return rc;

    budget b = {{budget_alloc, budget_free, NULL}, 0, 0, false};
    b.allocator.allocator_data = &b;
    b.limit = limits && limits->max_memory ? limits->max_memory
                                           : (size_t)64 * 1024 + 16 * size;
    ProtobufCMessage *pm = protobuf_c_message_unpack(desc, &b.allocator, size, data);
    if (!pm) {
        if (b.exceeded)
            return ftm_error_set(err, FTM_EBUDGET,
                                 "%s: decoding the %zu-byte payload needs more than its %zu-byte "
                                 "memory budget (e.g. many empty repeated submessages)",
                                 what, size, b.limit);
        return ftm_error_set(err, FTM_EPARSE,
                             "%s: malformed payload of %zu bytes (protobuf-c rejected it)", what,
                             size);
    }
    vctx v = {what, err, (uint32_t)INT32_MAX, 0};
    if (limits && limits->node_count > 0) {
        v.node_limit = (uint32_t)limits->node_count;
        v.scene_nodes = (uint32_t)limits->node_count;
    }
    rc = check_any(&v, kind, pm);
    if (rc == FTM_OK)
        rc = convert(kind, pm, out, err);
    protobuf_c_message_free_unpacked(pm, &b.allocator);
    return rc;
}

/* ---- plain C -> protobuf-c ---------------------------------------------- */

/* Everything an encoding needs besides the top-level struct, freed at once. */
typedef struct scratch {
    Ftm__V1__Vec3 vec[2];
    Ftm__V1__TissueParams tissue;
    Ftm__V1__IntegratorMode mode;
    Ftm__V1__DepthLimits limits;
    Ftm__V1__Pause pause;
    Ftm__V1__Resume resume;
    Ftm__V1__Reset reset;
    void *blocks[8];
    int nblocks;
} scratch;

static void *scratch_alloc(scratch *s, size_t size)
{
    if (s->nblocks == (int)(sizeof s->blocks / sizeof s->blocks[0]))
        return NULL;
    void *p = calloc(1, size ? size : 1);
    if (p)
        s->blocks[s->nblocks++] = p;
    return p;
}

static void scratch_free(scratch *s)
{
    for (int i = 0; i < s->nblocks; i++)
        free(s->blocks[i]);
}

static void vec_to(Ftm__V1__Vec3 *p, ftm_vec3 v)
{
    ftm__v1__vec3__init(p);
    p->has_x = p->has_y = p->has_z = 1;
    p->x = v.x;
    p->y = v.y;
    p->z = v.z;
}

static void tissue_to(scratch *s, const ftm_wire_tissue *t)
{
    ftm__v1__tissue_params__init(&s->tissue);
    s->tissue.has_node_mass = s->tissue.has_node_damping = s->tissue.has_stiffness = 1;
    s->tissue.node_mass = t->node_mass;
    s->tissue.node_damping = t->node_damping;
    s->tissue.stiffness = t->stiffness;
    vec_to(&s->vec[0], t->axis_scale);
    s->tissue.axis_scale = &s->vec[0];
}

/* Contacts as the protocol's columns (tick frames, keyframes). */
static int contacts_to(scratch *s, const char *what, const ftm_contact *c, int32_t count,
                       size_t *n_out, uint32_t **node, uint32_t **group,
                       Ftm__V1__ContactKind **kind, double **value, ftm_error *err)
{
    if (count < 0 || (count && !c))
        return ftm_error_set(err, FTM_EINVAL, "%s: bad contact_count %d or NULL contacts", what,
                             count);
    size_t n = (size_t)count;
    uint32_t *nodes = scratch_alloc(s, 2 * n * sizeof *nodes);
    Ftm__V1__ContactKind *kinds = scratch_alloc(s, n * sizeof *kinds);
    double *values = scratch_alloc(s, 3 * n * sizeof *values);
    if (!nodes || !kinds || !values)
        return ftm_error_set(err, FTM_ENOMEM, "%s: out of memory", what);
    uint32_t *groups = nodes + n;
    for (size_t i = 0; i < n; i++) {
        if (c[i].node < 0 || c[i].group < 0)
            return ftm_error_set(err, FTM_ERANGE, "%s: contact %zu: negative node %d or group %d",
                                 what, i, c[i].node, c[i].group);
        if (c[i].kind != FTM_CONTACT_FORCE && c[i].kind != FTM_CONTACT_DISPLACEMENT)
            return ftm_error_set(err, FTM_EINVAL, "%s: contact %zu: unknown contact kind %d", what,
                                 i, (int)c[i].kind);
        nodes[i] = (uint32_t)c[i].node;
        groups[i] = (uint32_t)c[i].group;
        kinds[i] = c[i].kind == FTM_CONTACT_FORCE ? FTM__V1__CONTACT_KIND__CONTACT_FORCE
                                                  : FTM__V1__CONTACT_KIND__CONTACT_DISPLACEMENT;
        values[3 * i] = c[i].value.x;
        values[3 * i + 1] = c[i].value.y;
        values[3 * i + 2] = c[i].value.z;
    }
    *n_out = n;
    *node = nodes;
    *group = groups;
    *kind = kinds;
    *value = values;
    return FTM_OK;
}

static int limits_to(scratch *s, const char *what, int32_t lo, int32_t hi, ftm_error *err)
{
    if (lo < 0 || hi < 0)
        return ftm_error_set(err, FTM_EINVAL, "%s: negative depth limit (%d..%d)", what, lo, hi);
    ftm__v1__depth_limits__init(&s->limits);
    s->limits.has_min = s->limits.has_max = 1;
    s->limits.min = (uint32_t)lo;
    s->limits.max = (uint32_t)hi;
    return FTM_OK;
}

#define NEG_CHECK(value, field)                                                                    \
    do {                                                                                           \
        if ((value) < 0)                                                                           \
            return ftm_error_set(err, FTM_EINVAL, "%s: %s is negative (%lld)", what, field,        \
                                 (long long)(value));                                              \
    } while (0)

static int build(const ftm_wire_msg *msg, scratch *s, ProtobufCMessage **out, ftm_error *err)
{
    const char *what = ftm_wire_kind_name(msg->kind);
    switch (msg->kind) {
    case FTM_WIRE_ANNOUNCE: {
        const ftm_wire_announce *a = &msg->u.announce;
        Ftm__V1__SceneAnnounce *m = scratch_alloc(s, sizeof *m);
        if (!m)
            return ftm_error_set(err, FTM_ENOMEM, "%s: out of memory", what);
        ftm__v1__scene_announce__init(m);
        NEG_CHECK(a->depth, "depth");
        NEG_CHECK(a->node_count, "node_count");
        if (a->digest_len < 0 || a->digest_len > FTM_WIRE_DIGEST_MAX)
            return ftm_error_set(err, FTM_EINVAL, "%s: digest_len %d out of range (1..%d)", what,
                                 a->digest_len, FTM_WIRE_DIGEST_MAX);
        if (!memchr(a->scene_id, '\0', sizeof a->scene_id))
            return ftm_error_set(err, FTM_EINVAL, "%s: scene_id is not NUL-terminated", what);
        m->has_version = 1;
        m->version = FTM_WIRE_VERSION;
        m->scene_id = (char *)a->scene_id;
        m->has_content_digest = 1;
        m->content_digest.len = (size_t)a->digest_len;
        m->content_digest.data = (uint8_t *)a->digest;
        m->has_tick_rate_hz = 1;
        m->tick_rate_hz = a->tick_rate_hz;
        m->has_time_step = 1;
        m->time_step = a->time_step;
        m->has_depth = 1;
        m->depth = (uint32_t)a->depth;
        int rc = limits_to(s, what, a->depth_min, a->depth_max, err);
        if (rc)
            return rc;
        m->depth_limits = &s->limits;
        tissue_to(s, &a->tissue);
        m->tissue = &s->tissue;
        m->has_node_count = 1;
        m->node_count = (uint32_t)a->node_count;
        m->has_tick = 1;
        m->tick = a->tick;
        m->has_paused = 1;
        m->paused = a->paused;
        m->has_server_start_ns = a->server_start_ns != 0;
        m->server_start_ns = a->server_start_ns;
        m->has_arithmetic = a->arithmetic != 0;
        m->arithmetic = a->arithmetic;
        *out = &m->base;
        return FTM_OK;
    }
    case FTM_WIRE_PROBE_INPUT: {
        const ftm_wire_probe_input *p = &msg->u.probe_input;
        if (p->sample_count < 0 || p->sample_count > FTM_WIRE_SAMPLES_MAX)
            return ftm_error_set(err, FTM_ERANGE, "%s: sample_count %d out of range (0..%d)", what,
                                 p->sample_count, FTM_WIRE_SAMPLES_MAX);
        if (p->sample_count && !p->samples)
            return ftm_error_set(err, FTM_EINVAL, "%s: samples is NULL", what);
        size_t n = (size_t)p->sample_count;
        Ftm__V1__ProbeInput *m = scratch_alloc(s, sizeof *m);
        Ftm__V1__ProbeSample *samples = scratch_alloc(s, n * sizeof *samples);
        Ftm__V1__ProbeSample **ptrs = scratch_alloc(s, n * sizeof *ptrs);
        Ftm__V1__Vec3 *pos = scratch_alloc(s, n * sizeof *pos);
        if (!m || !samples || !ptrs || !pos)
            return ftm_error_set(err, FTM_ENOMEM, "%s: out of memory", what);
        ftm__v1__probe_input__init(m);
        m->has_version = 1;
        m->version = FTM_WIRE_VERSION;
        m->has_participant_id = 1;
        m->participant_id = p->participant;
        m->has_last_tick_seen = 1;
        m->last_tick_seen = p->last_tick_seen;
        for (size_t i = 0; i < n; i++) {
            NEG_CHECK(p->samples[i].probe, "sample probe");
            ftm__v1__probe_sample__init(&samples[i]);
            samples[i].has_probe = samples[i].has_device_time_ns = 1;
            samples[i].probe = (uint32_t)p->samples[i].probe;
            samples[i].device_time_ns = p->samples[i].device_time_ns;
            vec_to(&pos[i], p->samples[i].position);
            samples[i].position = &pos[i];
            ptrs[i] = &samples[i];
        }
        m->n_samples = n;
        m->samples = ptrs;
        *out = &m->base;
        return FTM_OK;
    }
    case FTM_WIRE_TICK: {
        const ftm_wire_tick *t = &msg->u.tick;
        NEG_CHECK(t->depth, "depth");
        if (t->contact_count < 0 || (t->contact_count && !t->contacts))
            return ftm_error_set(err, FTM_EINVAL, "%s: bad contact_count %d or NULL contacts", what,
                                 t->contact_count);
        if (t->reaction_count < 0 || t->reaction_count > FTM_WIRE_REACTIONS_MAX ||
            (t->reaction_count && !t->reactions))
            return ftm_error_set(err, FTM_ERANGE,
                                 "%s: bad reaction_count %d (0..%d) or NULL reactions", what,
                                 t->reaction_count, FTM_WIRE_REACTIONS_MAX);
        size_t nr = (size_t)t->reaction_count;
        Ftm__V1__TickFrame *m = scratch_alloc(s, sizeof *m);
        Ftm__V1__ProbeReaction *rs = scratch_alloc(s, nr * sizeof *rs);
        Ftm__V1__ProbeReaction **rptrs = scratch_alloc(s, nr * sizeof *rptrs);
        /* force, hip, contact point, contact normal */
        Ftm__V1__Vec3 *forces = scratch_alloc(s, 4 * nr * sizeof *forces);
        if (!m || !rs || !rptrs || !forces)
            return ftm_error_set(err, FTM_ENOMEM, "%s: out of memory", what);
        ftm__v1__tick_frame__init(m);
        m->has_version = 1;
        m->version = FTM_WIRE_VERSION;
        m->has_tick = 1;
        m->tick = t->tick;
        m->has_depth = 1;
        m->depth = (uint32_t)t->depth;
        m->has_state_hash = 1;
        m->state_hash = t->state_hash;
        m->has_send_time_ns = t->send_time_ns != 0;
        m->send_time_ns = t->send_time_ns;
        if (t->has_tissue) {
            tissue_to(s, &t->tissue);
            m->tissue = &s->tissue;
        }
        int rc = contacts_to(s, what, t->contacts, t->contact_count, &m->n_contact_node,
                             &m->contact_node, &m->contact_group, &m->contact_kind,
                             &m->contact_value, err);
        if (rc)
            return rc;
        m->n_contact_group = m->n_contact_kind = m->n_contact_node;
        m->n_contact_value = 3 * m->n_contact_node;
        for (size_t i = 0; i < nr; i++) {
            const ftm_wire_reaction *r = &t->reactions[i];
            if (r->group < 0 || r->probe < 0)
                return ftm_error_set(err, FTM_ERANGE, "%s: reactions[%zu]: negative group or probe",
                                     what, i);
            ftm__v1__probe_reaction__init(&rs[i]);
            rs[i].has_group = rs[i].has_participant_id = rs[i].has_probe = 1;
            rs[i].group = (uint32_t)r->group;
            rs[i].participant_id = r->participant;
            rs[i].probe = (uint32_t)r->probe;
            vec_to(&forces[i], r->force);
            rs[i].force = &forces[i];
            if (r->has_model) {
                vec_to(&forces[nr + i], r->hip);
                rs[i].hip = &forces[nr + i];
                rs[i].n_stiffness = 9;
                rs[i].stiffness = (double *)r->stiffness; /* only read while packing */
            }
            rs[i].has_push_limited = r->push_limited;
            rs[i].push_limited = r->push_limited;
            if (r->has_plane) {
                vec_to(&forces[2 * nr + i], r->contact_point);
                vec_to(&forces[3 * nr + i], r->contact_normal);
                rs[i].contact_point = &forces[2 * nr + i];
                rs[i].contact_normal = &forces[3 * nr + i];
            }
            rptrs[i] = &rs[i];
        }
        m->n_reactions = nr;
        m->reactions = rptrs;
        *out = &m->base;
        return FTM_OK;
    }
    case FTM_WIRE_KEYFRAME: {
        const ftm_wire_keyframe *k = &msg->u.keyframe;
        NEG_CHECK(k->depth, "depth");
        NEG_CHECK(k->node_count, "node_count");
        if (k->count < 0 || (k->count && (!k->nodes || !k->positions || !k->previous)))
            return ftm_error_set(err, FTM_EINVAL, "%s: bad count %d or NULL arrays", what,
                                 k->count);
        size_t n = (size_t)k->count;
        Ftm__V1__Keyframe *m = scratch_alloc(s, sizeof *m);
        uint32_t *nodes = scratch_alloc(s, n * sizeof *nodes);
        if (!m || !nodes)
            return ftm_error_set(err, FTM_ENOMEM, "%s: out of memory", what);
        ftm__v1__keyframe__init(m);
        m->has_version = 1;
        m->version = FTM_WIRE_VERSION;
        m->has_tick = 1;
        m->tick = k->tick;
        m->has_state_hash = 1;
        m->state_hash = k->state_hash;
        m->has_node_count = 1;
        m->node_count = (uint32_t)k->node_count;
        m->has_depth = 1;
        m->depth = (uint32_t)k->depth;
        if (k->has_tissue) {
            tissue_to(s, &k->tissue);
            m->tissue = &s->tissue;
        }
        if (k->has_mode) {
            const ftm_sim_mode *md = &k->mode;
            if (md->substeps < 1 || md->steps_at_substeps < 0 || md->quiet_steps < 0)
                return ftm_error_set(err, FTM_ERANGE, "%s: mode out of range (substeps %d)", what,
                                     (int)md->substeps);
            Ftm__V1__IntegratorMode *im = &s->mode;
            ftm__v1__integrator_mode__init(im);
            im->has_substeps = im->has_steps_at_substeps = im->has_quiet_steps = 1;
            im->has_region_sleeping = im->has_energy_budget = im->has_energy_prev = 1;
            im->substeps = (uint32_t)md->substeps;
            im->steps_at_substeps = (uint32_t)md->steps_at_substeps;
            im->quiet_steps = (uint32_t)md->quiet_steps;
            im->region_sleeping = md->region_sleeping;
            im->energy_budget = md->energy_budget;
            im->energy_prev = md->energy_prev;
            m->mode = im;
        }
        int rc = contacts_to(s, what, k->contacts, k->contact_count, &m->n_contact_node,
                             &m->contact_node, &m->contact_group, &m->contact_kind,
                             &m->contact_value, err);
        if (rc)
            return rc;
        m->n_contact_group = m->n_contact_kind = m->n_contact_node;
        m->n_contact_value = 3 * m->n_contact_node;
        for (size_t i = 0; i < n; i++) {
            if (k->nodes[i] < 0)
                return ftm_error_set(err, FTM_ERANGE, "%s: entry %zu: negative node %d", what, i,
                                     k->nodes[i]);
            nodes[i] = (uint32_t)k->nodes[i];
        }
        m->n_node = n;
        m->node = nodes;
        m->n_position = m->n_previous = 3 * n;
        m->position = (double *)k->positions;
        m->previous = (double *)k->previous;
        *out = &m->base;
        return FTM_OK;
    }
    case FTM_WIRE_STATUS: {
        const ftm_wire_status *st = &msg->u.status;
        Ftm__V1__ParticipantStatus *m = scratch_alloc(s, sizeof *m);
        if (!m)
            return ftm_error_set(err, FTM_ENOMEM, "%s: out of memory", what);
        if (!memchr(st->name, '\0', sizeof st->name))
            return ftm_error_set(err, FTM_EINVAL, "%s: name is not NUL-terminated", what);
        ftm__v1__participant_status__init(m);
        m->has_version = 1;
        m->version = FTM_WIRE_VERSION;
        m->has_participant_id = 1;
        m->participant_id = st->participant;
        m->has_role = 1;
        m->role = (Ftm__V1__Role)st->role;
        m->has_state = 1;
        m->state = (Ftm__V1__ParticipantState)st->state;
        m->has_last_applied_tick = 1;
        m->last_applied_tick = st->last_applied_tick;
        m->has_state_hash = 1;
        m->state_hash = st->state_hash;
        m->has_replay_ns_per_tick = 1;
        m->replay_ns_per_tick = st->replay_ns_per_tick;
        m->has_replay_ns_max = 1;
        m->replay_ns_max = st->replay_ns_max;
        m->name = st->name[0] ? (char *)st->name : NULL;
        if (st->ignored_count < 0 || st->ignored_count > FTM_WIRE_IGNORED_MAX)
            return ftm_error_set(err, FTM_ERANGE, "%s: %d ignored processes (0..%d)", what,
                                 (int)st->ignored_count, FTM_WIRE_IGNORED_MAX);
        if (st->ignored_count && st->role != FTM_WIRE_ROLE_SERVER)
            return ftm_error_set(err, FTM_EINVAL,
                                 "%s: ignored processes in a %s's status (a server's only)", what,
                                 ftm_wire_role_name(st->role));
        m->n_ignored_participant = m->n_ignored_origin = (size_t)st->ignored_count;
        m->ignored_participant = (uint32_t *)st->ignored_participant;
        m->ignored_origin = (uint64_t *)st->ignored_origin;
        if (st->holder_count < 0 || st->holder_count > FTM_WIRE_HOLDERS_MAX)
            return ftm_error_set(err, FTM_ERANGE, "%s: %d holders (0..%d)", what,
                                 (int)st->holder_count, FTM_WIRE_HOLDERS_MAX);
        if (st->holder_count && st->role != FTM_WIRE_ROLE_SERVER)
            return ftm_error_set(err, FTM_EINVAL, "%s: holders in a %s's status (a server's only)",
                                 what, ftm_wire_role_name(st->role));
        for (int32_t i = 1; i < st->holder_count; i++)
            for (int32_t j = 0; j < i; j++)
                if (st->holder_participant[i] == st->holder_participant[j])
                    return ftm_error_set(err, FTM_EINVAL, "%s: holder_participant %u listed twice",
                                         what, st->holder_participant[i]);
        m->n_holder_participant = m->n_holder_origin = (size_t)st->holder_count;
        m->holder_participant = (uint32_t *)st->holder_participant;
        m->holder_origin = (uint64_t *)st->holder_origin;
        *out = &m->base;
        return FTM_OK;
    }
    case FTM_WIRE_CONTROL: {
        const ftm_wire_control *c = &msg->u.control;
        Ftm__V1__SessionControl *m = scratch_alloc(s, sizeof *m);
        if (!m)
            return ftm_error_set(err, FTM_ENOMEM, "%s: out of memory", what);
        ftm__v1__session_control__init(m);
        m->has_version = 1;
        m->version = FTM_WIRE_VERSION;
        m->has_issuer_id = 1;
        m->issuer_id = c->issuer;
        m->has_command_id = 1;
        m->command_id = c->command_id;
        switch (c->command) {
        case FTM_WIRE_CMD_PAUSE:
            ftm__v1__pause__init(&s->pause);
            m->command_case = FTM__V1__SESSION_CONTROL__COMMAND_PAUSE;
            m->pause = &s->pause;
            break;
        case FTM_WIRE_CMD_RESUME:
            ftm__v1__resume__init(&s->resume);
            m->command_case = FTM__V1__SESSION_CONTROL__COMMAND_RESUME;
            m->resume = &s->resume;
            break;
        case FTM_WIRE_CMD_RESET:
            ftm__v1__reset__init(&s->reset);
            m->command_case = FTM__V1__SESSION_CONTROL__COMMAND_RESET;
            m->reset = &s->reset;
            break;
        case FTM_WIRE_CMD_TISSUE:
            tissue_to(s, &c->tissue);
            m->command_case = FTM__V1__SESSION_CONTROL__COMMAND_TISSUE;
            m->tissue = &s->tissue;
            break;
        case FTM_WIRE_CMD_DEPTH_LIMITS: {
            int rc = limits_to(s, what, c->depth_min, c->depth_max, err);
            if (rc)
                return rc;
            m->command_case = FTM__V1__SESSION_CONTROL__COMMAND_DEPTH_LIMITS;
            m->depth_limits = &s->limits;
            break;
        }
        default:
            return ftm_error_set(err, FTM_EINVAL, "%s: unknown command %d", what, (int)c->command);
        }
        *out = &m->base;
        return FTM_OK;
    }
    case FTM_WIRE_CONTROL_REPLY: {
        const ftm_wire_control_reply *r = &msg->u.control_reply;
        Ftm__V1__ControlReply *m = scratch_alloc(s, sizeof *m);
        if (!m)
            return ftm_error_set(err, FTM_ENOMEM, "%s: out of memory", what);
        if (!memchr(r->reason, '\0', sizeof r->reason))
            return ftm_error_set(err, FTM_EINVAL, "%s: reason is not NUL-terminated", what);
        ftm__v1__control_reply__init(m);
        m->has_version = 1;
        m->version = FTM_WIRE_VERSION;
        m->has_issuer_id = 1;
        m->issuer_id = r->issuer;
        m->has_command_id = 1;
        m->command_id = r->command_id;
        m->has_outcome = 1;
        m->outcome = (Ftm__V1__ControlOutcome)r->outcome;
        m->has_tick = 1;
        m->tick = r->tick;
        m->reason = r->reason[0] ? (char *)r->reason : NULL;
        *out = &m->base;
        return FTM_OK;
    }
    default: return ftm_error_set(err, FTM_EINVAL, "unknown message kind %d", (int)msg->kind);
    }
}

int ftm_wire_encode(const ftm_wire_msg *msg, uint8_t **out, size_t *size, ftm_error *err)
{
    if (!msg || !out || !size)
        return ftm_error_set(err, FTM_EINVAL, "ftm_wire_encode: NULL argument");
    scratch s;
    memset(&s, 0, sizeof s);
    ProtobufCMessage *pm = NULL;
    int rc = build(msg, &s, &pm, err);
    if (rc == FTM_OK) {
        vctx v = {ftm_wire_kind_name(msg->kind), err, (uint32_t)INT32_MAX, 0};
        if (msg->kind == FTM_WIRE_KEYFRAME)
            v.node_limit = (uint32_t)msg->u.keyframe.node_count;
        rc = check_any(&v, msg->kind, pm);
    }
    if (rc == FTM_OK) {
        size_t n = protobuf_c_message_get_packed_size(pm);
        size_t cap = ftm_wire_default_cap(msg->kind);
        if (n > cap) {
            rc = ftm_error_set(err, FTM_ETOOBIG,
                               "%s: encoding of %zu bytes exceeds the %zu-byte cap",
                               ftm_wire_kind_name(msg->kind), n, cap);
        } else {
            uint8_t *buf = malloc(n ? n : 1);
            if (!buf) {
                rc = ftm_error_set(err, FTM_ENOMEM, "%s: out of memory",
                                   ftm_wire_kind_name(msg->kind));
            } else {
                size_t packed = protobuf_c_message_pack(pm, buf);
                (void)packed;
                *out = buf;
                *size = n;
            }
        }
    }
    scratch_free(&s);
    return rc;
}
