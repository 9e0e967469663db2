/* SPDX-License-Identifier: GPL-3.0-or-later */
/* The force renderers and their safety stage (haptic.h): pure functions of
 * the samples, the time and the HIP, so tests can drive them exactly. */
#include "haptic.h"

#include <math.h>
#include <stdio.h>
#include <string.h>

static ftm_vec3 v_add(ftm_vec3 a, ftm_vec3 b) { return (ftm_vec3){a.x + b.x, a.y + b.y, a.z + b.z}; }
static ftm_vec3 v_sub(ftm_vec3 a, ftm_vec3 b) { return (ftm_vec3){a.x - b.x, a.y - b.y, a.z - b.z}; }
static ftm_vec3 v_scale(ftm_vec3 a, double s) { return (ftm_vec3){a.x * s, a.y * s, a.z * s}; }
static double v_dot(ftm_vec3 a, ftm_vec3 b) { return a.x * b.x + a.y * b.y + a.z * b.z; }
static double v_norm(ftm_vec3 a) { return sqrt(v_dot(a, a)); }
static bool v_finite(ftm_vec3 a) { return isfinite(a.x) && isfinite(a.y) && isfinite(a.z); }

const char *ftm_haptic_renderer_name(ftm_haptic_renderer_kind kind)
{
    switch (kind) {
    case FTM_HAPTIC_EXTRAPOLATE:
        return "extrapolate";
    case FTM_HAPTIC_FORCE_MODEL:
        return "model";
    }
    return NULL;
}

int ftm_haptic_renderer_parse(const char *name, ftm_haptic_renderer_kind *out)
{
    if (name && strcmp(name, "extrapolate") == 0) {
        *out = FTM_HAPTIC_EXTRAPOLATE;
        return FTM_OK;
    }
    if (name && strcmp(name, "model") == 0) {
        *out = FTM_HAPTIC_FORCE_MODEL;
        return FTM_OK;
    }
    return FTM_EINVAL;
}

ftm_haptic_def ftm_default_haptic_def(void)
{
    return (ftm_haptic_def){
        .renderer = FTM_HAPTIC_FORCE_MODEL,
        .max_force = 8.0,
        .max_force_rate = 2000.0,
        .max_extrapolation = 0.1,
        .min_sample_interval = 0.0005,
        .stale_after = 0.1,
        .fade_time = 0.1,
        .rate_hz = 1000.0,
        .realtime = true,
        .priority = 80,
    };
}

static int def_error(ftm_error *err, const char *field, double value, const char *need)
{
    if (err) {
        err->code = FTM_EINVAL;
        snprintf(err->message, sizeof err->message, "haptic definition: %s = %g (must be %s)",
                 field, value, need);
    }
    return FTM_EINVAL;
}

int ftm_haptic_def_check(const ftm_haptic_def *def, ftm_error *err)
{
    if (!ftm_haptic_renderer_name(def->renderer))
        return def_error(err, "renderer", (double)def->renderer, "extrapolate or model");
    if (!(def->max_force > 0) || !isfinite(def->max_force))
        return def_error(err, "max_force", def->max_force, "finite and > 0");
    if (!(def->max_force_rate > 0))
        return def_error(err, "max_force_rate", def->max_force_rate, "> 0");
    if (!(def->max_extrapolation >= 0) || !isfinite(def->max_extrapolation))
        return def_error(err, "max_extrapolation", def->max_extrapolation, "finite and >= 0");
    if (!(def->min_sample_interval >= 0) || !isfinite(def->min_sample_interval))
        return def_error(err, "min_sample_interval", def->min_sample_interval, "finite and >= 0");
    if (!(def->stale_after >= 0) || !isfinite(def->stale_after))
        return def_error(err, "stale_after", def->stale_after, "finite and >= 0");
    if (!(def->fade_time >= 0) || !isfinite(def->fade_time))
        return def_error(err, "fade_time", def->fade_time, "finite and >= 0");
    if (!(def->rate_hz >= 1 && def->rate_hz <= 100000))
        return def_error(err, "rate_hz", def->rate_hz, "in 1..100000");
    if (def->priority < 1 || def->priority > 99)
        return def_error(err, "priority", def->priority, "in 1..99");
    return FTM_OK;
}

void ftm_force_renderer_init(ftm_force_renderer *r, const ftm_haptic_def *def)
{
    memset(r, 0, sizeof *r);
    r->def = def ? *def : ftm_default_haptic_def();
    r->connected = true;
}

int ftm_force_renderer_push(ftm_force_renderer *r, const ftm_haptic_sample *s, double arrival)
{
    if (!isfinite(s->time) || !isfinite(arrival) || !v_finite(s->force) || !v_finite(s->hip))
        return FTM_EINVAL;
    if (s->has_stiffness)
        for (int i = 0; i < 9; i++)
            if (!isfinite(s->stiffness[i]))
                return FTM_EINVAL;
    ftm_haptic_sample c = *s;
    if (c.has_plane) {
        double nl = v_norm(c.plane_normal);
        if (!v_finite(c.plane_point) || !(nl > 0) || !isfinite(nl))
            return FTM_EINVAL;
        c.plane_normal = v_scale(c.plane_normal, 1.0 / nl);
    }
    s = &c;
    if (!r->connected)
        return FTM_OK; /* nothing is rendered while disconnected */
    if (r->count > 0 && s->time < r->s[1].time)
        return FTM_OK; /* older than what we have: out of order */
    if (r->count > 0 && s->time == r->s[1].time) {
        r->s[1] = *s; /* same instant: a correction replaces it */
    } else {
        r->s[0] = r->s[1];
        r->s[1] = *s;
        if (r->count < 2)
            r->count++;
    }
    r->arrival = arrival;
    return FTM_OK;
}

void ftm_force_renderer_set_connected(ftm_force_renderer *r, bool connected)
{
    if (!connected)
        r->count = 0;
    r->connected = connected;
}

void ftm_force_renderer_set_kind(ftm_force_renderer *r, ftm_haptic_renderer_kind kind)
{
    if (ftm_haptic_renderer_name(kind))
        r->def.renderer = kind;
}

ftm_vec3 ftm_force_renderer_model(const ftm_force_renderer *r, double now, ftm_vec3 hip)
{
    if (r->count == 0)
        return (ftm_vec3){0, 0, 0};
    const ftm_haptic_sample *s1 = &r->s[1];
    if (r->def.renderer == FTM_HAPTIC_FORCE_MODEL) {
        if (!s1->has_stiffness)
            return s1->force;
        ftm_vec3 d = v_sub(hip, s1->hip);
        const double *K = s1->stiffness;
        return v_add(s1->force, (ftm_vec3){K[0] * d.x + K[1] * d.y + K[2] * d.z,
                                           K[3] * d.x + K[4] * d.y + K[5] * d.z,
                                           K[6] * d.x + K[7] * d.y + K[8] * d.z});
    }
    /* the line through the two newest samples, at most max_extrapolation
     * past the newest (a sample that stops coming must not run away); two
     * samples closer than min_sample_interval are a burst, not a trend */
    double span = s1->time - r->s[0].time;
    if (r->count < 2 || !(span > 0) || span < r->def.min_sample_interval)
        return s1->force;
    double ahead = now - s1->time;
    if (ahead > r->def.max_extrapolation)
        ahead = r->def.max_extrapolation;
    if (ahead < 0)
        ahead = 0; /* now before the sample's time: no back-extrapolation */
    ftm_vec3 slope = v_scale(v_sub(s1->force, r->s[0].force), 1.0 / span);
    return v_add(s1->force, v_scale(slope, ahead));
}

ftm_vec3 ftm_force_renderer_eval(ftm_force_renderer *r, double now, ftm_vec3 hip, int *flags)
{
    int fl = 0;
    double dt = r->have_prev && now > r->prev_time ? now - r->prev_time : 0.0;
    ftm_vec3 target = {0, 0, 0};
    bool immediate = false; /* zero at once, bypassing the rate limit */
    if (!r->connected) {
        fl |= FTM_HAPTIC_DISCONNECTED;
        immediate = true;
    } else if (!v_finite(hip)) {
        fl |= FTM_HAPTIC_DEVICE_LOST;
        immediate = true;
    } else if (r->count == 0) {
        fl |= FTM_HAPTIC_NO_SAMPLE;
    } else {
        target = ftm_force_renderer_model(r, now, hip);
        /* Unilateral contact: the tissue pushes; a linear model carried past
         * the surface would pull the probe in. */
        const ftm_haptic_sample *s1 = &r->s[1];
        if (s1->has_plane) {
            double fn = v_dot(target, s1->plane_normal);
            if (v_dot(v_sub(hip, s1->plane_point), s1->plane_normal) >= 0.0) {
                if (v_norm(target) > 0.0)
                    fl |= FTM_HAPTIC_RELEASED; /* the server's release rule */
                target = (ftm_vec3){0, 0, 0};
            } else if (fn < 0.0) {
                target = v_sub(target, v_scale(s1->plane_normal, fn));
                fl |= FTM_HAPTIC_UNILATERAL;
            }
        } else if (v_norm(s1->force) == 0.0) {
            /* the server says: no contact (a line from a contact sample to
             * this one would carry the release on as a pull) */
            if (v_norm(target) > 0.0)
                fl |= FTM_HAPTIC_RELEASED;
            target = (ftm_vec3){0, 0, 0};
        } else if (v_dot(target, s1->force) <= 0.0) {
            if (v_norm(target) > 0.0)
                fl |= FTM_HAPTIC_UNILATERAL;
            target = (ftm_vec3){0, 0, 0};
        }
        double age = now - r->arrival;
        if (age > r->def.stale_after) {
            fl |= FTM_HAPTIC_STALE;
            double g = r->def.fade_time > 0 ? 1.0 - (age - r->def.stale_after) / r->def.fade_time
                                            : 0.0;
            target = v_scale(target, g > 0 ? g : 0.0);
        }
    }
    double mag = v_norm(target);
    if (!isfinite(mag)) { /* overflow in the model: no direction to trust, so zero */
        target = (ftm_vec3){0, 0, 0};
        mag = 0;
        fl |= FTM_HAPTIC_CLAMPED;
    } else if (mag > r->def.max_force) {
        target = v_scale(target, r->def.max_force / mag);
        fl |= FTM_HAPTIC_CLAMPED;
    }
    ftm_vec3 out = target;
    if (!immediate && r->have_prev) {
        /* the step from the previous output, limited; a convex step between
         * two points in the force ball stays in it */
        ftm_vec3 step = v_sub(target, r->prev_force);
        double len = v_norm(step), lim = r->def.max_force_rate * dt;
        if (len > lim) {
            out = v_add(r->prev_force, v_scale(step, lim / len));
            fl |= FTM_HAPTIC_RATE_LIMITED;
        }
    } else if (!immediate) {
        /* first output: ramp from zero */
        double lim = 0.0;
        if (mag > lim) {
            out = (ftm_vec3){0, 0, 0};
            fl |= FTM_HAPTIC_RATE_LIMITED;
        }
    }
    r->prev_force = out;
    r->prev_time = now;
    r->have_prev = true;
    if (flags)
        *flags = fl;
    return out;
}

double ftm_haptic_timebase_map(ftm_haptic_timebase *tb, double server_time, double arrival,
                               double max_age)
{
    const double d = arrival - server_time; /* this frame's delay, plus the clocks' offset */
    if (!tb->set || d < tb->offset || d - tb->offset > max_age) {
        tb->offset = d; /* less delayed than any before, or re-anchored */
        tb->set = true;
        tb->win_min = d;
        tb->win_start = arrival;
        return arrival;
    }
    if (d < tb->win_min)
        tb->win_min = d;
    if (arrival - tb->win_start >= FTM_HAPTIC_TIMEBASE_WINDOW) {
        tb->offset = tb->win_min; /* the window's least delay: follows a drift */
        tb->win_min = d;
        tb->win_start = arrival;
    }
    return server_time + tb->offset;
}
