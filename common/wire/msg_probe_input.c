/* SPDX-License-Identifier: GPL-3.0-or-later */
/* ProbeInput (kind 2, trainee -> server): the samples are the hooks'. */
#include "codec_internal.h"

#include <stdio.h>

/* ftm.v1.ProbeInput by field number, in the order of the decoder's checks */
#define T ftm_wire_probe_input
static const wire_field fields[] = {
    {2, WIRE_C(T, participant), WF_U32}, /* participant_id */
    {3, WIRE_C(T, last_tick_seen), WF_U64},
};
#undef T

static int check(const vctx *v, const ProtobufCMessage *pm)
{
    const Ftm__V1__ProbeInput *m = (const void *)pm;
    if (m->n_samples > FTM_WIRE_SAMPLES_MAX)
        return ftm_error_set(v->err, FTM_ERANGE, "%s: %zu samples (at most %d)", v->what,
                             m->n_samples, FTM_WIRE_SAMPLES_MAX);
    for (size_t i = 0; i < m->n_samples; i++) {
        const Ftm__V1__ProbeSample *s = m->samples[i];
        char name[64];
        if (!s->has_probe || !s->has_device_time_ns) {
            snprintf(name, sizeof name, "samples[%zu].%s", i,
                     !s->has_probe ? "probe" : "device_time_ns");
            return wire_missing(v, name);
        }
        if (s->probe > INT32_MAX)
            return ftm_error_set(v->err, FTM_ERANGE, "%s: samples[%zu].probe %u out of range",
                                 v->what, i, s->probe);
        snprintf(name, sizeof name, "samples[%zu].position", i);
        int rc = wire_check_vec3(v, name, s->position);
        if (rc)
            return rc;
    }
    return FTM_OK;
}

static int from(const ProtobufCMessage *pm, ftm_wire_msg *out, ftm_error *err)
{
    const Ftm__V1__ProbeInput *m = (const void *)pm;
    ftm_wire_probe_input *p = &out->u.probe_input;
    void *s = NULL;
    out->storage = wire_alloc_arrays(m->n_samples * sizeof *p->samples, 0, 0, &s, NULL, NULL);
    if (!out->storage)
        return ftm_error_set(err, FTM_ENOMEM, "%s: out of memory", ftm_wire_kind_name(out->kind));
    p->samples = s;
    p->sample_count = (int32_t)m->n_samples;
    for (size_t i = 0; i < m->n_samples; i++)
        p->samples[i] =
            (ftm_wire_probe_sample){(int32_t)m->samples[i]->probe, m->samples[i]->device_time_ns,
                                    wire_vec_from(m->samples[i]->position)};
    return FTM_OK;
}

static int to(const ftm_wire_msg *msg, scratch *s, ProtobufCMessage *pm, ftm_error *err)
{
    const ftm_wire_probe_input *p = &msg->u.probe_input;
    Ftm__V1__ProbeInput *m = (void *)pm;
    const char *what = ftm_wire_kind_name(msg->kind);
    if (p->sample_count < 0 || p->sample_count > FTM_WIRE_SAMPLES_MAX)
        return ftm_error_set(err, FTM_ERANGE, "%s: sample_count %d out of range (0..%d)", what,
                             p->sample_count, FTM_WIRE_SAMPLES_MAX);
    if (p->sample_count && !p->samples)
        return ftm_error_set(err, FTM_EINVAL, "%s: samples is NULL", what);
    const size_t n = (size_t)p->sample_count;
    Ftm__V1__ProbeSample *samples = wire_scratch_alloc(s, n * sizeof *samples);
    Ftm__V1__ProbeSample **ptrs = wire_scratch_alloc(s, n * sizeof *ptrs);
    Ftm__V1__Vec3 *pos = wire_scratch_alloc(s, n * sizeof *pos);
    if (!samples || !ptrs || !pos)
        return ftm_error_set(err, FTM_ENOMEM, "%s: out of memory", what);
    for (size_t i = 0; i < n; i++) {
        const ftm_wire_probe_sample *ps = &p->samples[i];
        if (ps->probe < 0)
            return ftm_error_set(err, FTM_EINVAL, "%s: sample probe is negative (%lld)", what,
                                 (long long)ps->probe);
        ftm__v1__probe_sample__init(&samples[i]);
        samples[i].has_probe = samples[i].has_device_time_ns = 1;
        samples[i].probe = (uint32_t)ps->probe;
        samples[i].device_time_ns = ps->device_time_ns;
        wire_vec_to(&pos[i], ps->position);
        samples[i].position = &pos[i];
        ptrs[i] = &samples[i];
    }
    m->n_samples = n;
    m->samples = ptrs;
    return FTM_OK;
}

const wire_kind_def wire_kind_probe_input = {
    .kind = FTM_WIRE_PROBE_INPUT,
    .name = "probe input",
    .topic = "ftm_v1_probe_input",
    .cap = FTM_WIRE_CAP_PROBE_INPUT,
    .pb = &ftm__v1__probe_input__descriptor,
    .fields = fields,
    .nfields = sizeof fields / sizeof fields[0],
    .check = check,
    .from = from,
    .to = to,
};
