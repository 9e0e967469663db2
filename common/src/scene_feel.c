/* SPDX-License-Identifier: GPL-3.0-or-later */
/* What a press on a scene feels like, before anyone presses it: the scene's
 * own simulation, pressed on the surface triangle at the top of its bounding
 * box the way the server presses a probe's contact triangle (its three
 * vertices displaced together, docs/server.md). A scene whose tissue gives
 * 0.02 N at a 10 mm press is one a trainee cannot feel; the server and the
 * client warn about it when the scene loads. */
#include "ftm/scene.h"

#include "error.h"

#include <math.h>
#include <stdbool.h>
#include <stdio.h>
#include <stdlib.h>

static ftm_vec3 sub(ftm_vec3 a, ftm_vec3 b) { return (ftm_vec3){a.x - b.x, a.y - b.y, a.z - b.z}; }

static ftm_vec3 cross(ftm_vec3 a, ftm_vec3 b)
{
    return (ftm_vec3){a.y * b.z - a.z * b.y, a.z * b.x - a.x * b.z, a.x * b.y - a.y * b.x};
}

/* The upward-facing surface triangle crossed highest by the vertical line
 * through (cx, cy); else the upward-facing one with the highest centroid.
 * -1 when no triangle faces up (a planar mesh, a surface without one). */
static int32_t top_triangle(const ftm_mesh *m, double cx, double cy, ftm_vec3 *point)
{
    const int32_t *tri = ftm_mesh_triangles(m);
    const int32_t n = ftm_mesh_triangle_count(m);
    int32_t best = -1, high = -1;
    double best_z = -INFINITY, high_z = -INFINITY;
    ftm_vec3 high_c = {0, 0, 0};
    for (int32_t t = 0; t < n; t++) {
        const ftm_vec3 a = ftm_mesh_rest_position(m, tri[3 * t]);
        const ftm_vec3 b = ftm_mesh_rest_position(m, tri[3 * t + 1]);
        const ftm_vec3 c = ftm_mesh_rest_position(m, tri[3 * t + 2]);
        const ftm_vec3 nrm = cross(sub(b, a), sub(c, a));
        if (!(nrm.z > 0.0))
            continue;
        const double zc = (a.z + b.z + c.z) / 3.0;
        if (zc > high_z) {
            high_z = zc;
            high = t;
            high_c = (ftm_vec3){(a.x + b.x + c.x) / 3.0, (a.y + b.y + c.y) / 3.0, zc};
        }
        /* barycentric coordinates of (cx, cy) in the triangle's xy projection */
        const double d = (b.x - a.x) * (c.y - a.y) - (c.x - a.x) * (b.y - a.y);
        if (d == 0.0)
            continue;
        const double u = ((cx - a.x) * (c.y - a.y) - (c.x - a.x) * (cy - a.y)) / d;
        const double v = ((b.x - a.x) * (cy - a.y) - (cx - a.x) * (b.y - a.y)) / d;
        if (u < 0.0 || v < 0.0 || u + v > 1.0)
            continue;
        const double z = a.z + u * (b.z - a.z) + v * (c.z - a.z);
        if (z > best_z) {
            best_z = z;
            best = t;
            *point = (ftm_vec3){cx, cy, z};
        }
    }
    if (best < 0 && high >= 0)
        *point = high_c;
    return best >= 0 ? best : high;
}

int ftm_scene_press_estimate(const ftm_scene *scene, double depth, ftm_press_estimate *out,
                             ftm_error *err)
{
    const char *who = "press estimate";
    if (!scene || !out)
        return ftm_error_set(err, FTM_EINVAL, "%s: null argument", who);
    if (!(depth > 0.0 && depth <= 1.0))
        return ftm_error_set(err, FTM_EINVAL, "%s: depth %g m out of range (0, 1]", who, depth);
    const ftm_mesh *m = ftm_scene_mesh(scene);
    const int32_t nn = ftm_mesh_node_count(m);
    if (nn <= 0)
        return ftm_error_set(err, FTM_ENOENT, "%s: the scene has no nodes", who);
    ftm_vec3 lo = ftm_mesh_rest_position(m, 0), hi = lo;
    for (int32_t i = 1; i < nn; i++) {
        const ftm_vec3 p = ftm_mesh_rest_position(m, i);
        lo = (ftm_vec3){fmin(lo.x, p.x), fmin(lo.y, p.y), fmin(lo.z, p.z)};
        hi = (ftm_vec3){fmax(hi.x, p.x), fmax(hi.y, p.y), fmax(hi.z, p.z)};
    }
    /* where and which way: the scene's own press if it scripts one (its
     * first displacement group, up to three nodes, scaled to `depth`), else
     * the top triangle pushed along its inward normal */
    ftm_contact c[3];
    int32_t k = 0, t = -1;
    (void)t;
    ftm_vec3 point = {0, 0, 0}, push = {0, 0, 0};
    const ftm_scene_load *loads = ftm_scene_loads(scene);
    const int32_t nl = ftm_scene_load_count(scene);
    for (int32_t i = 0; i < nl && k < 3; i++) {
        const ftm_contact *lc = &loads[i].contact;
        if (lc->kind != FTM_CONTACT_DISPLACEMENT || (k > 0 && lc->group != c[0].group))
            continue;
        const double len = sqrt(lc->value.x * lc->value.x + lc->value.y * lc->value.y +
                                lc->value.z * lc->value.z);
        if (!(len > 0.0) || ftm_mesh_fixed(m, lc->node))
            continue;
        bool again = false;
        for (int32_t q = 0; q < k; q++)
            again = again || c[q].node == lc->node;
        if (again)
            continue;
        if (k == 0) {
            push = (ftm_vec3){lc->value.x / len * depth, lc->value.y / len * depth,
                              lc->value.z / len * depth};
            point = ftm_mesh_rest_position(m, lc->node);
        }
        c[k++] = (ftm_contact){lc->node, lc->group, FTM_CONTACT_DISPLACEMENT, {0, 0, 0}};
    }
    if (k == 0) {
        t = top_triangle(m, 0.5 * (lo.x + hi.x), 0.5 * (lo.y + hi.y), &point);
        if (t < 0)
            return ftm_error_set(err, FTM_ENOENT,
                                 "%s: scene '%s' scripts no press and has no surface triangle "
                                 "facing up",
                                 who, ftm_scene_name(scene));
        const int32_t *v = ftm_mesh_triangles(m) + 3 * t;
        const ftm_vec3 a = ftm_mesh_rest_position(m, v[0]);
        const ftm_vec3 nrm = cross(sub(ftm_mesh_rest_position(m, v[1]), a),
                                   sub(ftm_mesh_rest_position(m, v[2]), a));
        const double len = sqrt(nrm.x * nrm.x + nrm.y * nrm.y + nrm.z * nrm.z);
        push = (ftm_vec3){-nrm.x / len * depth, -nrm.y / len * depth, -nrm.z / len * depth};
        for (int q = 0; q < 3; q++)
            if (!ftm_mesh_fixed(m, v[q]))
                c[k++] = (ftm_contact){v[q], 0, FTM_CONTACT_DISPLACEMENT, {0, 0, 0}};
        if (k == 0)
            return ftm_error_set(err, FTM_ENOENT, "%s: the top triangle %d is fixed", who, (int)t);
    }

    ftm_sim_def def = ftm_scene_sim_def(scene);
    def.log = NULL;
    def.log_user = NULL;
    const double h = def.time_step;
    if (!(h > 0.0 && h <= 0.25))
        return ftm_error_set(err, FTM_EINVAL, "%s: time step %g s out of range (0, 0.25]", who, h);
    /* ramp over a quarter second, hold another, read the last 50 ms: a
     * trainee's press is that slow, and the mean leaves the ringing out */
    const int32_t ramp = (int32_t)ceil(0.25 / h), hold = ramp, tail = (int32_t)ceil(0.05 / h);
    ftm_sim *sim = NULL;
    int rc = ftm_sim_create(m, &def, &sim, err);
    if (rc)
        return rc;
    double sum[3] = {0, 0, 0};
    int32_t counted = 0;
    for (int32_t s = 1; s <= ramp + hold && rc == FTM_OK; s++) {
        const double f = s < ramp ? (double)s / ramp : 1.0;
        for (int32_t q = 0; q < k; q++)
            c[q].value = (ftm_vec3){push.x * f, push.y * f, push.z * f};
        rc = ftm_sim_set_contacts(sim, c, k, err);
        if (rc == FTM_OK)
            rc = ftm_sim_step(sim);
        if (rc == FTM_OK && s > ramp + hold - tail) {
            const ftm_vec3 r = ftm_sim_reaction(sim, c[0].group);
            sum[0] += r.x;
            sum[1] += r.y;
            sum[2] += r.z;
            counted++;
        }
    }
    ftm_sim_stats st;
    ftm_sim_get_stats(sim, &st);
    ftm_sim_destroy(sim);
    if (rc)
        return ftm_error_set(err, rc, "%s: the press on triangle %d failed: %s", who, (int)t,
                             ftm_strerror(rc));
    const ftm_vec3 r = {sum[0] / counted, sum[1] / counted, sum[2] / counted};
    *out = (ftm_press_estimate){
        .triangle = t,
        .point = point,
        .push = push,
        .depth = depth,
        .force = sqrt(r.x * r.x + r.y * r.y + r.z * r.z),
        .substeps = st.substeps,
    };
    return FTM_OK;
}

int ftm_press_verdict(const ftm_press_estimate *e)
{
    return e->force < FTM_PALPATION_MIN_N / 10.0   ? -1
           : e->force > FTM_PALPATION_MAX_N * 10.0 ? 1
                                                   : 0;
}

int ftm_press_describe(const ftm_press_estimate *e, char *buf, size_t size)
{
    const int v = ftm_press_verdict(e);
    return snprintf(buf, size, "a %.3g mm press %s gives %.3g N%s (palpation: %g-%g N)",
                    e->depth * 1e3, e->triangle < 0 ? "where the scene presses" : "on the top", e->force,
                    v < 0   ? ": far softer than tissue a trainee can feel"
                    : v > 0 ? ": far stiffer than tissue"
                            : "",
                    FTM_PALPATION_MIN_N, FTM_PALPATION_MAX_N);
}
