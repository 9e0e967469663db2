/* SPDX-License-Identifier: GPL-3.0-or-later */
/* The pieces several kinds share: checks and conversions of vectors, tissue
 * parameters, depth limits, the integrator's mode, display text and contact
 * columns. The field tables (codec_fields.c) and the kinds' hooks
 * (msg_*.c) call them, so that each rule and each message is written once. */
#include "codec_internal.h"

#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

/* ---- checks ---------------------------------------------------------------- */

int wire_missing(const vctx *v, const char *field)
{
    return ftm_error_set(v->err, FTM_EPARSE, "%s: missing field %s", v->what, field);
}

int wire_check_finite(const vctx *v, const char *field, double x)
{
    if (!isfinite(x))
        return ftm_error_set(v->err, FTM_EINVAL, "%s: %s is not finite (%g)", v->what, field, x);
    return FTM_OK;
}

int wire_check_vec3(const vctx *v, const char *field, const Ftm__V1__Vec3 *p)
{
    char name[96];
    if (!p)
        return wire_missing(v, field);
    if (!p->has_x || !p->has_y || !p->has_z) {
        snprintf(name, sizeof name, "%s.%s", field, !p->has_x ? "x" : !p->has_y ? "y" : "z");
        return wire_missing(v, name);
    }
    const double c[3] = {p->x, p->y, p->z};
    for (int i = 0; i < 3; i++) {
        if (!isfinite(c[i])) {
            snprintf(name, sizeof name, "%s.%c", field, "xyz"[i]);
            return wire_check_finite(v, name, c[i]);
        }
    }
    return FTM_OK;
}

int wire_check_depth(const vctx *v, const char *field, uint32_t depth)
{
    if (depth > WIRE_DEPTH_MAX)
        return ftm_error_set(v->err, FTM_ERANGE, "%s: %s %u out of range (0..%u)", v->what, field,
                             depth, WIRE_DEPTH_MAX);
    return FTM_OK;
}

int wire_check_tissue(const vctx *v, const char *field, const Ftm__V1__TissueParams *t)
{
    char name[96];
    if (!t)
        return wire_missing(v, field);
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
            return wire_missing(v, name);
        int rc = wire_check_finite(v, name, f[i].value);
        if (rc)
            return rc;
        if (f[i].value < 0 || (f[i].value == 0 && !f[i].zero_ok))
            return ftm_error_set(v->err, FTM_EINVAL, "%s: %s must be %s (got %g)", v->what, name,
                                 f[i].zero_ok ? ">= 0" : "> 0", f[i].value);
    }
    snprintf(name, sizeof name, "%s.axis_scale", field);
    int rc = wire_check_vec3(v, name, t->axis_scale);
    if (rc)
        return rc;
    if (!(t->axis_scale->x > 0 && t->axis_scale->y > 0 && t->axis_scale->z > 0))
        return ftm_error_set(v->err, FTM_EINVAL, "%s: %s must be > 0 in every axis", v->what, name);
    return FTM_OK;
}

int wire_check_limits(const vctx *v, const char *field, const Ftm__V1__DepthLimits *d)
{
    char name[96];
    if (!d)
        return wire_missing(v, field);
    if (!d->has_min || !d->has_max) {
        snprintf(name, sizeof name, "%s.%s", field, !d->has_min ? "min" : "max");
        return wire_missing(v, name);
    }
    snprintf(name, sizeof name, "%s.max", field);
    int rc = wire_check_depth(v, name, d->max);
    if (rc)
        return rc;
    if (d->min > d->max)
        return ftm_error_set(v->err, FTM_EINVAL, "%s: %s.min %u above max %u", v->what, field,
                             d->min, d->max);
    return FTM_OK;
}

#define SUBSTEPS_MAX 1024u /* far above any sim's max_substeps; the sim checks its own */

int wire_check_mode(const vctx *v, const Ftm__V1__IntegratorMode *m)
{
    const struct {
        protobuf_c_boolean has;
        const char *name;
    } present[] = {{m->has_substeps, "mode.substeps"},
                   {m->has_steps_at_substeps, "mode.steps_at_substeps"},
                   {m->has_quiet_steps, "mode.quiet_steps"},
                   {m->has_region_sleeping, "mode.region_sleeping"},
                   {m->has_energy_budget, "mode.energy_budget"},
                   {m->has_energy_prev, "mode.energy_prev"}};
    for (size_t i = 0; i < sizeof present / sizeof present[0]; i++)
        if (!present[i].has)
            return wire_missing(v, present[i].name);
    if (m->substeps < 1 || m->substeps > SUBSTEPS_MAX)
        return ftm_error_set(v->err, FTM_ERANGE, "%s: mode.substeps %u out of range (1..%u)",
                             v->what, m->substeps, SUBSTEPS_MAX);
    if (m->steps_at_substeps > INT32_MAX || m->quiet_steps > INT32_MAX)
        return ftm_error_set(v->err, FTM_ERANGE, "%s: mode step counters out of range (%u, %u)",
                             v->what, m->steps_at_substeps, m->quiet_steps);
    int rc;
    if ((rc = wire_check_finite(v, "mode.energy_budget", m->energy_budget)) ||
        (rc = wire_check_finite(v, "mode.energy_prev", m->energy_prev)))
        return rc;
    if (m->energy_prev < 0)
        return ftm_error_set(v->err, FTM_EINVAL, "%s: mode.energy_prev must be >= 0 (got %g)",
                             v->what, m->energy_prev);
    return FTM_OK;
}

/* Text shown on a HUD and written to logs and terminals (a display name, a
 * reason) is WF_PLAIN: no control bytes, so that a peer cannot put escape
 * sequences or line breaks into anyone's terminal. */
int wire_check_text(const vctx *v, const char *field, const char *text, size_t cap, int flags)
{
    if ((flags & WF_NONEMPTY) && (!text || !text[0]))
        return wire_missing(v, field);
    const size_t n = text ? strlen(text) : 0;
    if (n >= cap)
        return ftm_error_set(v->err, FTM_EINVAL, "%s: %s of %zu bytes (at most %zu)", v->what,
                             field, n, cap - 1);
    for (size_t i = 0; (flags & WF_PLAIN) && i < n; i++) {
        const unsigned char c = (unsigned char)text[i];
        if (c < 0x20 || c == 0x7f)
            return ftm_error_set(v->err, FTM_EINVAL,
                                 "%s: %s has control character 0x%02x at byte %zu", v->what, field,
                                 c, i);
    }
    return FTM_OK;
}

int wire_check_contacts(const vctx *v, size_t n, const uint32_t *node, size_t n_group,
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

/* ---- protobuf-c -> plain C --------------------------------------------------- */

ftm_vec3 wire_vec_from(const Ftm__V1__Vec3 *p)
{
    return (ftm_vec3){p->x, p->y, p->z};
}

ftm_wire_tissue wire_tissue_from(const Ftm__V1__TissueParams *t)
{
    return (ftm_wire_tissue){t->node_mass, t->node_damping, t->stiffness,
                             wire_vec_from(t->axis_scale)};
}

ftm_sim_mode wire_mode_from(const Ftm__V1__IntegratorMode *m)
{
    return (ftm_sim_mode){(int32_t)m->substeps,    (int32_t)m->steps_at_substeps,
                          (int32_t)m->quiet_steps, m->region_sleeping != 0,
                          m->energy_budget,        m->energy_prev};
}

void *wire_alloc_arrays(size_t a, size_t b, size_t c, void **pa, void **pb, void **pc)
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

void wire_contacts_from(size_t n, const uint32_t *node, size_t n_group, const uint32_t *group,
                        size_t n_kind, const Ftm__V1__ContactKind *kind, size_t n_value,
                        const double *value, ftm_contact *out)
{
    (void)n_group, (void)n_kind, (void)n_value; /* checked: n, n and 3 n */
    for (size_t i = 0; i < n; i++)
        out[i] = (ftm_contact){.node = (int32_t)node[i],
                               .group = (int32_t)group[i],
                               .kind = kind[i] == FTM__V1__CONTACT_KIND__CONTACT_FORCE
                                           ? FTM_CONTACT_FORCE
                                           : FTM_CONTACT_DISPLACEMENT,
                               .value = {value[3 * i], value[3 * i + 1], value[3 * i + 2]}};
}

/* ---- plain C -> protobuf-c --------------------------------------------------- */

void *wire_scratch_alloc(scratch *s, size_t size)
{
    if (s->nblocks == (int)(sizeof s->blocks / sizeof s->blocks[0]))
        return NULL;
    void *p = calloc(1, size ? size : 1);
    if (p)
        s->blocks[s->nblocks++] = p;
    return p;
}

void wire_scratch_free(scratch *s)
{
    for (int i = 0; i < s->nblocks; i++)
        free(s->blocks[i]);
}

void wire_vec_to(Ftm__V1__Vec3 *p, ftm_vec3 v)
{
    ftm__v1__vec3__init(p);
    p->has_x = p->has_y = p->has_z = 1;
    p->x = v.x;
    p->y = v.y;
    p->z = v.z;
}

Ftm__V1__TissueParams *wire_tissue_to(scratch *s, const ftm_wire_tissue *t)
{
    ftm__v1__tissue_params__init(&s->tissue);
    s->tissue.has_node_mass = s->tissue.has_node_damping = s->tissue.has_stiffness = 1;
    s->tissue.node_mass = t->node_mass;
    s->tissue.node_damping = t->node_damping;
    s->tissue.stiffness = t->stiffness;
    wire_vec_to(&s->axis_scale, t->axis_scale);
    s->tissue.axis_scale = &s->axis_scale;
    return &s->tissue;
}

int wire_limits_to(scratch *s, const char *what, int32_t lo, int32_t hi, ftm_error *err)
{
    if (lo < 0 || hi < 0)
        return ftm_error_set(err, FTM_EINVAL, "%s: negative depth limit (%d..%d)", what, lo, hi);
    ftm__v1__depth_limits__init(&s->limits);
    s->limits.has_min = s->limits.has_max = 1;
    s->limits.min = (uint32_t)lo;
    s->limits.max = (uint32_t)hi;
    return FTM_OK;
}

int wire_mode_to(scratch *s, const char *what, const ftm_sim_mode *md, ftm_error *err)
{
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
    return FTM_OK;
}

int wire_contacts_to(scratch *s, const char *what, const ftm_contact *c, int32_t count,
                     size_t *n_node, uint32_t **node, size_t *n_group, uint32_t **group,
                     size_t *n_kind, Ftm__V1__ContactKind **kind, size_t *n_value, double **value,
                     ftm_error *err)
{
    if (count < 0 || (count && !c))
        return ftm_error_set(err, FTM_EINVAL, "%s: bad contact_count %d or NULL contacts", what,
                             count);
    size_t n = (size_t)count;
    uint32_t *nodes = wire_scratch_alloc(s, 2 * n * sizeof *nodes);
    Ftm__V1__ContactKind *kinds = wire_scratch_alloc(s, n * sizeof *kinds);
    double *values = wire_scratch_alloc(s, 3 * n * sizeof *values);
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
    *n_node = *n_group = *n_kind = n;
    *n_value = 3 * n;
    *node = nodes;
    *group = groups;
    *kind = kinds;
    *value = values;
    return FTM_OK;
}
