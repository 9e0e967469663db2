/* SPDX-License-Identifier: GPL-3.0-or-later */
/* The scripted device (device.h): a HIP trajectory in the ftm-bot script
 * format, replayed against the haptic clock; records what it is sent. */
#include "device.h"
#include "script_text.h"

#include <math.h>
#include <pthread.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

typedef struct script {
    ftm_script_point *p; /* at least one */
    int32_t n;
    bool started; /* haptic thread only */
    double t0;
    pthread_mutex_t lock; /* guards log */
    ftm_script_device_log log;
} script;

static const ftm_device_ops script_ops;

static int script_read(void *self, double now, ftm_vec3 *hip)
{
    script *s = self;
    if (!s->started) {
        s->t0 = now;
        s->started = true;
    }
    *hip = ftm_script_points_at(s->p, s->n, now - s->t0);
    pthread_mutex_lock(&s->lock);
    s->log.reads++;
    pthread_mutex_unlock(&s->lock);
    return FTM_OK;
}

static void script_write(void *self, double now, ftm_vec3 f)
{
    script *s = self;
    double m = sqrt(f.x * f.x + f.y * f.y + f.z * f.z);
    pthread_mutex_lock(&s->lock);
    s->log.writes++;
    s->log.last_force = f;
    s->log.last_write = now;
    if (m > s->log.max_force)
        s->log.max_force = m;
    pthread_mutex_unlock(&s->lock);
}

static int script_start(void *self, ftm_error *err)
{
    script *s = self;
    s->started = false; /* time 0 = first read of this run */
    return FTM_OK;
}

static void script_destroy(void *self)
{
    script *s = self;
    pthread_mutex_destroy(&s->lock);
    free(s->p);
    free(s);
}

static const ftm_device_ops script_ops = {.name = "script",
                                          .start = script_start,
                                          .read = script_read,
                                          .write = script_write,
                                          .destroy = script_destroy};

static int perr(ftm_error *err, int code, const char *name, int line, const char *msg)
{
    if (err) {
        err->code = code;
        if (line > 0)
            snprintf(err->message, sizeof err->message, "%s:%d: %s", name, line, msg);
        else
            snprintf(err->message, sizeof err->message, "%s: %s", name, msg);
    }
    return code;
}

/* The device of a parsed script; takes its points. The bot's session
 * commands in it are not a device's business. */
static int from_text(ftm_script_text *st, const char *name, const ftm_device_def *def,
                     ftm_device **out, ftm_error *err)
{
    if (st->npts == 0) {
        ftm_script_text_free(st);
        return perr(err, FTM_EPARSE, name, 0, "no trajectory point ('t x y z')");
    }
    script *s = calloc(1, sizeof *s);
    if (!s || pthread_mutex_init(&s->lock, NULL)) {
        free(s);
        ftm_script_text_free(st);
        return perr(err, FTM_ENOMEM, name, 0, "out of memory");
    }
    s->p = st->pts;
    s->n = st->npts;
    st->pts = NULL;
    st->npts = 0;
    int rc = ftm_device_create(&script_ops, s, def, out, err);
    if (rc)
        script_destroy(s);
    return rc;
}

int ftm_script_device_parse(const char *text, size_t length, const char *name,
                            const ftm_device_def *def, ftm_device **out, ftm_error *err)
{
    if (!name)
        name = "script";
    ftm_script_text st;
    int rc = ftm_script_text_parse(text, length, name, &st, err);
    return rc ? rc : from_text(&st, name, def, out, err);
}

int ftm_script_device_open(const char *path, const ftm_device_def *def, ftm_device **out,
                           ftm_error *err)
{
    ftm_script_text st;
    int rc = ftm_script_text_read(path, &st, err);
    return rc ? rc : from_text(&st, path, def, out, err);
}

int ftm_script_device_position(const ftm_device *d, double t, ftm_vec3 *hip)
{
    if (!d || d->ops != &script_ops || !isfinite(t))
        return FTM_EINVAL;
    const script *s = d->self;
    *hip = ftm_script_points_at(s->p, s->n, t);
    return FTM_OK;
}

double ftm_script_device_duration(const ftm_device *d)
{
    if (!d || d->ops != &script_ops)
        return 0;
    const script *s = d->self;
    return s->p[s->n - 1].t;
}

int ftm_script_device_get_log(ftm_device *d, ftm_script_device_log *log)
{
    if (!d || d->ops != &script_ops)
        return FTM_EINVAL;
    script *s = d->self;
    pthread_mutex_lock(&s->lock);
    *log = s->log;
    pthread_mutex_unlock(&s->lock);
    return FTM_OK;
}
