/* SPDX-License-Identifier: GPL-3.0-or-later */
/* The mouse probe (device.h): cursor events from the GL thread move a target
 * HIP; the haptic thread follows it through a first-order low-pass. */
#include "device.h"

#include <math.h>
#include <pthread.h>
#include <stdio.h>
#include <stdlib.h>

typedef struct mouse {
    pthread_mutex_t lock;
    ftm_device_def def;
    ftm_mouse_view view;
    bool have_view;
    bool dragging;
    double px, py;   /* cursor at the last event of the drag */
    ftm_vec3 target; /* scene coordinates */
    double step, tau;
    /* the wheel's direction into the tissue (ftm_mouse_set_push_axis);
     * zero: the viewing direction */
    ftm_vec3 push_axis;
    bool limited;        /* ftm_mouse_set_limits: the boxes below hold */
    ftm_vec3 outer_lo, outer_hi, inner_lo, inner_hi;
    /* haptic thread only */
    bool have_out;
    ftm_vec3 out;
    double out_time;
} mouse;

static const ftm_device_ops mouse_ops;

static mouse *as_mouse(ftm_device *d) { return d && d->ops == &mouse_ops ? d->self : NULL; }

static bool fin(ftm_vec3 v) { return isfinite(v.x) && isfinite(v.y) && isfinite(v.z); }

static int mouse_read(void *self, double now, ftm_vec3 *hip)
{
    mouse *m = self;
    pthread_mutex_lock(&m->lock);
    ftm_vec3 t = m->target;
    pthread_mutex_unlock(&m->lock);
    if (!m->have_out || m->tau <= 0) {
        m->out = t;
    } else {
        double dt = now - m->out_time;
        double a = dt > 0 ? 1.0 - exp(-dt / m->tau) : 0.0;
        m->out = (ftm_vec3){m->out.x + a * (t.x - m->out.x), m->out.y + a * (t.y - m->out.y),
                            m->out.z + a * (t.z - m->out.z)};
    }
    m->have_out = true;
    m->out_time = now;
    /* device coordinates: the wrapper maps them back to the scene */
    double s = m->def.position_scale;
    *hip = (ftm_vec3){(m->out.x - m->def.offset.x) / s, (m->out.y - m->def.offset.y) / s,
                      (m->out.z - m->def.offset.z) / s};
    return FTM_OK;
}

static void mouse_write(void *self, double now, ftm_vec3 force) {} /* a mouse has no motor */

static void mouse_destroy(void *self)
{
    mouse *m = self;
    pthread_mutex_destroy(&m->lock);
    free(m);
}

static const ftm_device_ops mouse_ops = {
    .name = "mouse", .read = mouse_read, .write = mouse_write, .destroy = mouse_destroy};

int ftm_mouse_create(const ftm_device_def *def, ftm_vec3 hip0, double scroll_step,
                     double smoothing, ftm_device **out, ftm_error *err)
{
    if (!fin(hip0) || !isfinite(scroll_step) || !isfinite(smoothing)) {
        if (err) {
            err->code = FTM_EINVAL;
            snprintf(err->message, sizeof err->message,
                     "mouse probe: start HIP, scroll step and smoothing must be finite");
        }
        return FTM_EINVAL;
    }
    mouse *m = calloc(1, sizeof *m);
    if (!m || pthread_mutex_init(&m->lock, NULL)) {
        free(m);
        if (err) {
            err->code = FTM_ENOMEM;
            snprintf(err->message, sizeof err->message, "mouse probe: out of memory");
        }
        return FTM_ENOMEM;
    }
    m->def = def ? *def : ftm_default_device_def();
    m->target = hip0;
    m->step = scroll_step > 0 ? scroll_step : 1e-3;
    m->tau = smoothing < 0 ? 0.015 : smoothing;
    int rc = ftm_device_create(&mouse_ops, m, &m->def, out, err);
    if (rc)
        mouse_destroy(m);
    return rc;
}

/* The target kept in the outer box and out of the inner one (moved to
 * the inner box's nearest face). Under the lock. */
static void limit(mouse *m)
{
    if (!m->limited)
        return;
    double *t = &m->target.x;
    const double *olo = &m->outer_lo.x, *ohi = &m->outer_hi.x;
    const double *ilo = &m->inner_lo.x, *ihi = &m->inner_hi.x;
    bool inside = true;
    for (int k = 0; k < 3; k++) {
        t[k] = fmin(fmax(t[k], olo[k]), ohi[k]);
        inside = inside && t[k] > ilo[k] && t[k] < ihi[k];
    }
    if (!inside)
        return;
    int best = 0;
    double best_d = INFINITY, to = 0;
    for (int k = 0; k < 3; k++) {
        if (t[k] - ilo[k] < best_d)
            best = k, best_d = t[k] - ilo[k], to = ilo[k];
        if (ihi[k] - t[k] < best_d)
            best = k, best_d = ihi[k] - t[k], to = ihi[k];
    }
    t[best] = to;
}

int ftm_mouse_set_limits(ftm_device *d, ftm_vec3 lo, ftm_vec3 hi, double max_depth, double margin)
{
    mouse *m = as_mouse(d);
    if (!m || !fin(lo) || !fin(hi) || !(lo.x <= hi.x && lo.y <= hi.y && lo.z <= hi.z) ||
        !(max_depth >= 0) || !isfinite(max_depth) || !(margin >= 0) || !isfinite(margin))
        return FTM_EINVAL;
    pthread_mutex_lock(&m->lock);
    m->limited = true;
    m->outer_lo = (ftm_vec3){lo.x - margin, lo.y - margin, lo.z - margin};
    m->outer_hi = (ftm_vec3){hi.x + margin, hi.y + margin, hi.z + margin};
    m->inner_lo = (ftm_vec3){lo.x + max_depth, lo.y + max_depth, lo.z + max_depth};
    m->inner_hi = (ftm_vec3){hi.x - max_depth, hi.y - max_depth, hi.z - max_depth};
    limit(m);
    pthread_mutex_unlock(&m->lock);
    return FTM_OK;
}

int ftm_mouse_set_view(ftm_device *d, const ftm_mouse_view *v)
{
    mouse *m = as_mouse(d);
    if (!m || !v || !fin(v->eye) || !fin(v->forward) || !fin(v->right) || !fin(v->up) ||
        !(v->fov_y > 0 && v->fov_y < 3.14159) || !(v->width > 0) || !(v->height > 0) ||
        !isfinite(v->width) || !isfinite(v->height))
        return FTM_EINVAL;
    pthread_mutex_lock(&m->lock);
    m->view = *v;
    m->have_view = true;
    pthread_mutex_unlock(&m->lock);
    return FTM_OK;
}

/* The point under cursor (px, py) at depth `depth` along the viewing
 * direction (a pinhole camera: the ray through the pixel, scaled so that its
 * forward component is depth). */
static ftm_vec3 unproject(const ftm_mouse_view *v, double px, double py, double depth)
{
    double ty = tan(0.5 * v->fov_y), tx = ty * v->width / v->height;
    double nx = 2.0 * px / v->width - 1.0, ny = 1.0 - 2.0 * py / v->height;
    double a = nx * tx * depth, b = ny * ty * depth;
    return (ftm_vec3){v->eye.x + depth * v->forward.x + a * v->right.x + b * v->up.x,
                      v->eye.y + depth * v->forward.y + a * v->right.y + b * v->up.y,
                      v->eye.z + depth * v->forward.z + a * v->right.z + b * v->up.z};
}

int ftm_mouse_button(ftm_device *d, bool down, double px, double py)
{
    mouse *m = as_mouse(d);
    if (!m || !isfinite(px) || !isfinite(py))
        return FTM_EINVAL;
    pthread_mutex_lock(&m->lock);
    m->dragging = down;
    m->px = px;
    m->py = py;
    pthread_mutex_unlock(&m->lock);
    return FTM_OK;
}

int ftm_mouse_motion(ftm_device *d, double px, double py)
{
    mouse *m = as_mouse(d);
    if (!m || !isfinite(px) || !isfinite(py))
        return FTM_EINVAL;
    pthread_mutex_lock(&m->lock);
    if (m->dragging && m->have_view) {
        const ftm_mouse_view *v = &m->view;
        ftm_vec3 e = {m->target.x - v->eye.x, m->target.y - v->eye.y, m->target.z - v->eye.z};
        double depth = e.x * v->forward.x + e.y * v->forward.y + e.z * v->forward.z;
        if (depth > 1e-6) { /* behind the camera the plane makes no sense */
            ftm_vec3 a = unproject(v, m->px, m->py, depth), b = unproject(v, px, py, depth);
            m->target = (ftm_vec3){m->target.x + b.x - a.x, m->target.y + b.y - a.y,
                                   m->target.z + b.z - a.z};
            limit(m);
        }
    }
    m->px = px;
    m->py = py;
    pthread_mutex_unlock(&m->lock);
    return FTM_OK;
}

int ftm_mouse_scroll(ftm_device *d, double dy)
{
    mouse *m = as_mouse(d);
    if (!m || !isfinite(dy))
        return FTM_EINVAL;
    pthread_mutex_lock(&m->lock);
    const ftm_vec3 ax = m->push_axis;
    const bool own_axis = ax.x != 0.0 || ax.y != 0.0 || ax.z != 0.0;
    if (own_axis || m->have_view) {
        const ftm_vec3 u = own_axis ? ax : m->view.forward;
        double s = dy * m->step;
        m->target = (ftm_vec3){m->target.x + s * u.x, m->target.y + s * u.y, m->target.z + s * u.z};
        limit(m);
    }
    pthread_mutex_unlock(&m->lock);
    return FTM_OK;
}

int ftm_mouse_set_push_axis(ftm_device *d, ftm_vec3 axis)
{
    mouse *m = as_mouse(d);
    double n = sqrt(axis.x * axis.x + axis.y * axis.y + axis.z * axis.z);
    if (!m || !fin(axis) || (n > 0.0 && !isfinite(1.0 / n)))
        return FTM_EINVAL;
    pthread_mutex_lock(&m->lock);
    m->push_axis = n > 0.0 ? (ftm_vec3){axis.x / n, axis.y / n, axis.z / n} : (ftm_vec3){0, 0, 0};
    pthread_mutex_unlock(&m->lock);
    return FTM_OK;
}

int ftm_mouse_set_hip(ftm_device *d, ftm_vec3 hip)
{
    mouse *m = as_mouse(d);
    if (!m || !fin(hip))
        return FTM_EINVAL;
    pthread_mutex_lock(&m->lock);
    m->target = hip;
    limit(m);
    pthread_mutex_unlock(&m->lock);
    return FTM_OK;
}

int ftm_mouse_target(ftm_device *d, ftm_vec3 *hip)
{
    mouse *m = as_mouse(d);
    if (!m)
        return FTM_EINVAL;
    pthread_mutex_lock(&m->lock);
    *hip = m->target;
    pthread_mutex_unlock(&m->lock);
    return FTM_OK;
}

int ftm_mouse_out_of_tissue(ftm_device *d, ftm_vec3 point, ftm_vec3 normal, double clearance,
                            double tolerance, ftm_vec3 *moved_to)
{
    mouse *m = as_mouse(d);
    double nn = sqrt(normal.x * normal.x + normal.y * normal.y + normal.z * normal.z);
    if (!m || !fin(point) || !fin(normal) || !(nn > 0.0) || !(clearance >= 0.0) ||
        !isfinite(clearance) || !(tolerance >= 0.0) || !isfinite(tolerance))
        return FTM_EINVAL;
    const ftm_vec3 n = {normal.x / nn, normal.y / nn, normal.z / nn};
    pthread_mutex_lock(&m->lock);
    const ftm_vec3 in = {m->target.x - point.x, m->target.y - point.y, m->target.z - point.z};
    const double depth = -(in.x * n.x + in.y * n.y + in.z * n.z);
    int rc = 0;
    if (depth > tolerance) {
        /* back along the way it went in (the contact point to the HIP), to
         * clearance above the surface; straight out along the normal when
         * that way grazes the surface */
        double len = sqrt(in.x * in.x + in.y * in.y + in.z * in.z);
        ftm_vec3 u = {in.x / len, in.y / len, in.z / len};
        double un = -(u.x * n.x + u.y * n.y + u.z * n.z); /* > 0: into the tissue */
        if (un < 0.25) {
            u = (ftm_vec3){-n.x, -n.y, -n.z};
            un = 1.0;
        }
        const double back = clearance / un;
        m->target = (ftm_vec3){point.x - u.x * back, point.y - u.y * back, point.z - u.z * back};
        limit(m);
        if (moved_to)
            *moved_to = m->target;
        rc = 1;
    }
    pthread_mutex_unlock(&m->lock);
    return rc;
}
