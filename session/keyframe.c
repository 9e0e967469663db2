/* SPDX-License-Identifier: GPL-3.0-or-later */
/* Keyframes (keyframe.h). */
#include "keyframe.h"

#include <stdio.h>
#include <stdlib.h>
#include <string.h>

int ftm_replay_make_keyframe(const ftm_sim *sim, const ftm_replay_material *mat,
                             ftm_wire_keyframe *out, ftm_error *err)
{
    const ftm_mesh *m = ftm_sim_mesh(sim);
    int32_t n = ftm_mesh_node_count(m);
    const double *x = ftm_sim_positions(sim), *xp = ftm_sim_previous_positions(sim);
    ftm_sim_stats st;
    ftm_sim_get_stats(sim, &st);
    memset(out, 0, sizeof *out);
    int32_t count = 0;
    for (int pass = 0; pass < 2; pass++) {
        int32_t k = 0;
        for (int32_t i = 0; i < n; i++) {
            ftm_vec3 r = ftm_mesh_rest_position(m, i);
            const double *a = x + 3 * i, *b = xp + 3 * i;
            if (a[0] == r.x && a[1] == r.y && a[2] == r.z && b[0] == r.x && b[1] == r.y &&
                b[2] == r.z)
                continue;
            if (pass == 1) {
                out->nodes[k] = i;
                memcpy(out->positions + 3 * k, a, 3 * sizeof(double));
                memcpy(out->previous + 3 * k, b, 3 * sizeof(double));
            }
            k++;
        }
        if (pass == 0) {
            count = k;
            out->nodes = malloc(((size_t)count + 1) * sizeof *out->nodes);
            out->positions = malloc(((size_t)count + 1) * 3 * sizeof(double));
            out->previous = malloc(((size_t)count + 1) * 3 * sizeof(double));
            if (!out->nodes || !out->positions || !out->previous) {
                ftm_replay_keyframe_free(out);
                if (err) {
                    err->code = FTM_ENOMEM;
                    snprintf(err->message, sizeof err->message, "keyframe: out of memory");
                }
                return FTM_ENOMEM;
            }
        }
    }
    out->tick = st.step;
    out->state_hash = ftm_sim_hash(sim);
    out->has_mode = true;
    ftm_sim_get_mode(sim, &out->mode);
    out->has_tissue = mat && mat->changed;
    if (out->has_tissue)
        out->tissue = mat->current;
    out->node_count = n;
    out->depth = st.depth;
    out->count = count;
    const ftm_contact *c;
    int32_t nc = ftm_sim_contacts(sim, &c);
    out->contacts = malloc(((size_t)nc + 1) * sizeof *out->contacts);
    if (!out->contacts) {
        ftm_replay_keyframe_free(out);
        if (err) {
            err->code = FTM_ENOMEM;
            snprintf(err->message, sizeof err->message, "keyframe: out of memory");
        }
        return FTM_ENOMEM;
    }
    if (nc)
        memcpy(out->contacts, c, (size_t)nc * sizeof *c);
    out->contact_count = nc;
    return FTM_OK;
}

void ftm_replay_keyframe_free(ftm_wire_keyframe *k)
{
    free(k->nodes);
    free(k->positions);
    free(k->previous);
    free(k->contacts);
    memset(k, 0, sizeof *k);
}

int ftm_replay_keyframe_copy(ftm_wire_keyframe *dst, const ftm_wire_keyframe *k)
{
    *dst = *k;
    size_t n = (size_t)k->count;
    dst->nodes = malloc((n + 1) * sizeof *dst->nodes);
    dst->positions = malloc((n + 1) * 3 * sizeof(double));
    dst->previous = malloc((n + 1) * 3 * sizeof(double));
    dst->contacts = malloc(((size_t)k->contact_count + 1) * sizeof *dst->contacts);
    if (!dst->nodes || !dst->positions || !dst->previous || !dst->contacts) {
        ftm_replay_keyframe_free(dst);
        return FTM_ENOMEM;
    }
    if (k->contact_count)
        memcpy(dst->contacts, k->contacts, (size_t)k->contact_count * sizeof *k->contacts);
    if (n) {
        memcpy(dst->nodes, k->nodes, n * sizeof *dst->nodes);
        memcpy(dst->positions, k->positions, n * 3 * sizeof(double));
        memcpy(dst->previous, k->previous, n * 3 * sizeof(double));
    }
    return FTM_OK;
}
