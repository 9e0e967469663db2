/* SPDX-License-Identifier: GPL-3.0-or-later */
/* The haptic loop thread (haptic.h): device in, renderer, device out, at
 * absolute CLOCK_MONOTONIC deadlines. Exchange with other threads through
 * one mutex held for a few hundred nanoseconds per tick: new samples in,
 * HIP / force / timing out. The loop never blocks on anything else. */
#include "haptic.h"

#include "ftm/clock.h"

#include <errno.h>
#include <math.h>
#include <pthread.h>
#include <sched.h>
#include <stdatomic.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <time.h>

#define QUEUE_SIZE 64
#define HIP_RING 4096
#define HIST_BINS 20000 /* 1 us bins: periods up to 20 ms; longer ones land in the last */

struct ftm_haptic {
    ftm_haptic_def def;
    ftm_device *dev;
    pthread_t thread;
    bool started;        /* thread exists (owner thread only) */
    atomic_bool running; /* the loop keeps going while set */

    pthread_mutex_t lock; /* guards everything below */
    ftm_haptic_sample queue[QUEUE_SIZE];
    double queue_arrival[QUEUE_SIZE];
    int q_head, q_count;
    bool connected;
    bool connected_changed;
    ftm_haptic_renderer_kind kind;
    ftm_haptic_state st;
    ftm_haptic_hip hips[HIP_RING];
    int h_head, h_count;
    uint32_t hist[HIST_BINS];
    uint64_t periods;
    double t_first, t_last, max_period;

    ftm_force_renderer r; /* haptic thread only */
};

double ftm_haptic_clock(void) { return (double)ftm_clock_mono_ns() * 1e-9; }

static void hlog(ftm_haptic *h, ftm_log_level level, const char *fmt, const char *a)
{
    if (!h->def.log)
        return;
    char msg[256];
    snprintf(msg, sizeof msg, fmt, a);
    h->def.log(h->def.log_user, level, msg);
}

int ftm_haptic_create(const ftm_haptic_def *def, ftm_device *device, ftm_haptic **out,
                      ftm_error *err)
{
    ftm_haptic_def d = def ? *def : ftm_default_haptic_def();
    int rc = ftm_haptic_def_check(&d, err);
    if (rc)
        return rc;
    if (!device || !device->ops || !device->ops->read || !device->ops->write) {
        if (err) {
            err->code = FTM_EINVAL;
            snprintf(err->message, sizeof err->message,
                     "haptic loop: no device, or a device without read/write");
        }
        return FTM_EINVAL;
    }
    ftm_haptic *h = calloc(1, sizeof *h);
    if (!h || pthread_mutex_init(&h->lock, NULL)) {
        free(h);
        if (err) {
            err->code = FTM_ENOMEM;
            snprintf(err->message, sizeof err->message, "haptic loop: out of memory");
        }
        return FTM_ENOMEM;
    }
    h->def = d;
    h->dev = device;
    h->connected = true;
    h->kind = d.renderer;
    h->st.renderer = d.renderer;
    atomic_init(&h->running, false);
    *out = h;
    return FTM_OK;
}

static struct timespec ts_add(struct timespec t, long ns)
{
    t.tv_nsec += ns;
    while (t.tv_nsec >= 1000000000L) {
        t.tv_nsec -= 1000000000L;
        t.tv_sec++;
    }
    return t;
}

static double ts_sec(struct timespec t) { return (double)t.tv_sec + 1e-9 * (double)t.tv_nsec; }

static void *loop_main(void *arg)
{
    ftm_haptic *h = arg;
    long period_ns = (long)(1e9 / h->def.rate_hz + 0.5);
    double period = 1e-9 * (double)period_ns;
    struct timespec next;
    clock_gettime(CLOCK_MONOTONIC, &next);
    double prev_wake = -1;
    ftm_haptic_sample batch[QUEUE_SIZE];
    double batch_arrival[QUEUE_SIZE];
    while (atomic_load_explicit(&h->running, memory_order_acquire)) {
        next = ts_add(next, period_ns);
        while (clock_nanosleep(CLOCK_MONOTONIC, TIMER_ABSTIME, &next, NULL) == EINTR) {
        }
        double now = ftm_haptic_clock();

        /* take what other threads left for us */
        pthread_mutex_lock(&h->lock);
        int nb = h->q_count;
        for (int i = 0; i < nb; i++) {
            int k = (h->q_head + i) % QUEUE_SIZE;
            batch[i] = h->queue[k];
            batch_arrival[i] = h->queue_arrival[k];
        }
        h->q_count = 0;
        bool connected = h->connected, changed = h->connected_changed;
        h->connected_changed = false;
        ftm_haptic_renderer_kind kind = h->kind;
        pthread_mutex_unlock(&h->lock);

        if (changed || connected != h->r.connected)
            ftm_force_renderer_set_connected(&h->r, connected);
        ftm_force_renderer_set_kind(&h->r, kind);
        for (int i = 0; i < nb; i++)
            ftm_force_renderer_push(&h->r, &batch[i], batch_arrival[i]); /* checked on push */

        ftm_vec3 hip;
        int flags = 0;
        ftm_vec3 f;
        if (ftm_device_read(h->dev, now, &hip) == FTM_OK) {
            f = ftm_force_renderer_eval(&h->r, now, hip, &flags);
        } else {
            ftm_vec3 lost = {NAN, NAN, NAN};
            f = ftm_force_renderer_eval(&h->r, now, lost, &flags);
            hip = h->st.hip; /* keep the last good one for display */
        }
        ftm_device_write(h->dev, now, f);

        pthread_mutex_lock(&h->lock);
        h->st.ticks++;
        h->st.time = now;
        h->st.hip = hip;
        h->st.force = f;
        h->st.flags = flags;
        h->st.renderer = kind;
        if (!(flags & FTM_HAPTIC_DEVICE_LOST)) {
            int k = (h->h_head + h->h_count) % HIP_RING;
            h->hips[k] = (ftm_haptic_hip){now, hip};
            if (h->h_count < HIP_RING)
                h->h_count++;
            else
                h->h_head = (h->h_head + 1) % HIP_RING;
        }
        if (prev_wake >= 0) {
            double p = now - prev_wake;
            long bin = (long)(p * 1e6);
            if (bin < 0)
                bin = 0;
            if (bin >= HIST_BINS)
                bin = HIST_BINS - 1;
            h->hist[bin]++;
            h->periods++;
            if (p > h->max_period)
                h->max_period = p;
        } else {
            h->t_first = now;
        }
        h->t_last = now;
        pthread_mutex_unlock(&h->lock);
        prev_wake = now;

        /* more than a period late (preempted, suspended): skip the missed
         * deadlines instead of running a burst of catch-up ticks */
        if (now - ts_sec(next) > period) {
            clock_gettime(CLOCK_MONOTONIC, &next);
            pthread_mutex_lock(&h->lock);
            h->st.overruns++;
            pthread_mutex_unlock(&h->lock);
        }
    }
    /* never leave a force on the device */
    ftm_device_write(h->dev, ftm_haptic_clock(), (ftm_vec3){0, 0, 0});
    pthread_mutex_lock(&h->lock);
    h->st.force = (ftm_vec3){0, 0, 0};
    pthread_mutex_unlock(&h->lock);
    return NULL;
}

int ftm_haptic_start(ftm_haptic *h, ftm_error *err)
{
    if (h->started) {
        if (err) {
            err->code = FTM_EINVAL;
            snprintf(err->message, sizeof err->message, "haptic loop: already running");
        }
        return FTM_EINVAL;
    }
    if (h->dev->ops->start) {
        int rc = h->dev->ops->start(h->dev->self, err);
        if (rc)
            return rc;
    }
    ftm_force_renderer_init(&h->r, &h->def);
    pthread_mutex_lock(&h->lock);
    memset(h->hist, 0, sizeof h->hist);
    h->periods = 0;
    h->max_period = 0;
    h->st.ticks = h->st.overruns = 0;
    h->st.running = true;
    h->st.realtime = false;
    pthread_mutex_unlock(&h->lock);
    atomic_store(&h->running, true);

    int rc = -1;
    if (h->def.realtime) {
        pthread_attr_t attr;
        struct sched_param sp = {.sched_priority = h->def.priority};
        if (pthread_attr_init(&attr) == 0) {
            if (pthread_attr_setinheritsched(&attr, PTHREAD_EXPLICIT_SCHED) == 0 &&
                pthread_attr_setschedpolicy(&attr, SCHED_FIFO) == 0 &&
                pthread_attr_setschedparam(&attr, &sp) == 0)
                rc = pthread_create(&h->thread, &attr, loop_main, h);
            pthread_attr_destroy(&attr);
        }
        if (rc == 0) {
            pthread_mutex_lock(&h->lock);
            h->st.realtime = true;
            pthread_mutex_unlock(&h->lock);
        }
    }
    if (rc != 0) /* not permitted (EPERM) or not asked for: default policy */
        rc = pthread_create(&h->thread, NULL, loop_main, h);
    if (rc != 0) {
        atomic_store(&h->running, false);
        pthread_mutex_lock(&h->lock);
        h->st.running = false;
        pthread_mutex_unlock(&h->lock);
        if (h->dev->ops->stop)
            h->dev->ops->stop(h->dev->self);
        if (err) {
            err->code = FTM_ENOMEM;
            snprintf(err->message, sizeof err->message, "haptic loop: cannot start thread: %s",
                     strerror(rc));
        }
        return FTM_ENOMEM;
    }
    h->started = true;
    hlog(h, FTM_LOG_INFO, "haptic loop started (%s)",
         h->st.realtime ? "SCHED_FIFO" : "default scheduling");
    return FTM_OK;
}

void ftm_haptic_stop(ftm_haptic *h)
{
    if (!h->started)
        return;
    atomic_store(&h->running, false);
    pthread_join(h->thread, NULL);
    h->started = false;
    pthread_mutex_lock(&h->lock);
    h->st.running = false;
    pthread_mutex_unlock(&h->lock);
    if (h->dev->ops->stop)
        h->dev->ops->stop(h->dev->self);
    hlog(h, FTM_LOG_INFO, "haptic loop stopped%s", "");
}

void ftm_haptic_destroy(ftm_haptic *h)
{
    if (!h)
        return;
    ftm_haptic_stop(h);
    pthread_mutex_destroy(&h->lock);
    free(h);
}

int ftm_haptic_push(ftm_haptic *h, const ftm_haptic_sample *s)
{
    /* validate here so that the caller learns about bad data */
    ftm_force_renderer probe;
    ftm_force_renderer_init(&probe, &h->def);
    double now = ftm_haptic_clock();
    if (ftm_force_renderer_push(&probe, s, now))
        return FTM_EINVAL;
    pthread_mutex_lock(&h->lock);
    int k;
    if (h->q_count == QUEUE_SIZE) {
        k = h->q_head; /* overwrite the oldest */
        h->q_head = (h->q_head + 1) % QUEUE_SIZE;
        h->st.dropped++;
    } else {
        k = (h->q_head + h->q_count++) % QUEUE_SIZE;
    }
    h->queue[k] = *s;
    h->queue_arrival[k] = now;
    pthread_mutex_unlock(&h->lock);
    return FTM_OK;
}

void ftm_haptic_set_connected(ftm_haptic *h, bool connected)
{
    pthread_mutex_lock(&h->lock);
    if (!connected)
        h->q_count = 0; /* nothing queued before the loss may be rendered */
    h->connected = connected;
    h->connected_changed = true;
    pthread_mutex_unlock(&h->lock);
}

void ftm_haptic_set_renderer(ftm_haptic *h, ftm_haptic_renderer_kind kind)
{
    if (!ftm_haptic_renderer_name(kind))
        return;
    pthread_mutex_lock(&h->lock);
    h->kind = kind;
    pthread_mutex_unlock(&h->lock);
}

void ftm_haptic_get_state(ftm_haptic *h, ftm_haptic_state *st)
{
    pthread_mutex_lock(&h->lock);
    *st = h->st;
    pthread_mutex_unlock(&h->lock);
}

int ftm_haptic_take_hips(ftm_haptic *h, ftm_haptic_hip *out, int max)
{
    pthread_mutex_lock(&h->lock);
    int n = h->h_count < max ? h->h_count : max;
    for (int i = 0; i < n; i++)
        out[i] = h->hips[(h->h_head + i) % HIP_RING];
    h->h_head = (h->h_head + n) % HIP_RING;
    h->h_count -= n;
    pthread_mutex_unlock(&h->lock);
    return n > 0 ? n : 0;
}

static double percentile(const uint32_t *hist, uint64_t total, double q, double max)
{
    if (total == 0)
        return 0;
    uint64_t want = (uint64_t)ceil(q * (double)total), acc = 0;
    if (want == 0)
        want = 1;
    for (int b = 0; b < HIST_BINS; b++) {
        acc += hist[b];
        if (acc >= want)
            return b == HIST_BINS - 1 ? max : (b + 0.5) * 1e-6;
    }
    return max;
}

void ftm_haptic_get_timing(ftm_haptic *h, ftm_haptic_timing *t)
{
    memset(t, 0, sizeof *t);
    pthread_mutex_lock(&h->lock);
    t->periods = h->periods;
    t->elapsed = h->periods ? h->t_last - h->t_first : 0;
    t->rate_hz = t->elapsed > 0 ? (double)h->periods / t->elapsed : 0;
    t->mean = h->periods ? t->elapsed / (double)h->periods : 0;
    t->p50 = percentile(h->hist, h->periods, 0.50, h->max_period);
    t->p99 = percentile(h->hist, h->periods, 0.99, h->max_period);
    t->p999 = percentile(h->hist, h->periods, 0.999, h->max_period);
    t->max = h->max_period;
    pthread_mutex_unlock(&h->lock);
}
