/* SPDX-License-Identifier: GPL-3.0-or-later */
/* Haptic force rendering and the 1 kHz haptic loop (docs/haptics.md).
 *
 * The server produces a reaction force per probe each tick (paper Eq. 19);
 * it reaches the client late and at most at the tick rate, while a device
 * wants a force every millisecond. Two renderers fill the gap:
 *
 *  - FTM_HAPTIC_EXTRAPOLATE (paper section 3.3.1): the line through the two
 *    most recent reaction forces, evaluated at the current time (at most
 *    max_extrapolation past the newest sample, then held; the newest force
 *    held when the two are closer than min_sample_interval).
 *  - FTM_HAPTIC_FORCE_MODEL: the server sends with each force F0 the HIP x0
 *    it belongs to and the contact stiffness K = dF/dx (3x3); the loop
 *    evaluates F = F0 + K (x - x0) at the current HIP x. Without a stiffness
 *    in the newest sample it holds F0.
 *
 * Both are followed by the same safety stage: a unilateral-contact rule
 * (tissue pushes, it does not pull: with the contact plane of the newest
 * sample, zero force once the HIP is back outside the plane and no
 * component into the tissue; without it, zero when the newest sample's
 * force is zero (no contact) or the force points against it), fade to zero when no sample has arrived for
 * stale_after (linearly over fade_time), magnitude limit max_force,
 * rate-of-change limit max_force_rate, and zero force at once when
 * disconnected or when the device is lost.
 *
 * ftm_force_renderer is the pure part (explicit times, no clock, no
 * threads): tests and the benchmark drive it directly. ftm_haptic runs it in
 * a thread at rate_hz against a device (device.h).
 *
 * Times are seconds on one clock; the loop uses ftm_haptic_clock()
 * (CLOCK_MONOTONIC). Library ftm_haptic: C17 + pthreads, no GL, no DDS. */
#ifndef FTM_CLIENT_HAPTIC_H
#define FTM_CLIENT_HAPTIC_H

#include "device.h"

#include "ftm/base.h"

#ifdef __cplusplus
extern "C" {
#endif

typedef enum ftm_haptic_renderer_kind {
    FTM_HAPTIC_EXTRAPOLATE = 0,
    FTM_HAPTIC_FORCE_MODEL = 1,
} ftm_haptic_renderer_kind;

/* "extrapolate" / "model"; NULL for anything else. */
const char *ftm_haptic_renderer_name(ftm_haptic_renderer_kind kind);
/* Parses those names; FTM_EINVAL otherwise. */
int ftm_haptic_renderer_parse(const char *name, ftm_haptic_renderer_kind *out);

/* One reaction-force sample from the server. */
typedef struct ftm_haptic_sample {
    /* When the force was valid [s, the renderer's clock]: the server tick's
     * time mapped to the local clock if known, else the arrival time. */
    double time;
    ftm_vec3 force;      /* F0 [N], the force on the probe */
    ftm_vec3 hip;        /* x0 [m], the HIP the force was computed for */
    bool has_stiffness;  /* stiffness below is valid */
    double stiffness[9]; /* K = dF/dx0 [N/m], row-major */
    /* The contact's plane, if known (the server sends it): the tissue only
     * pushes while (x - plane_point) . plane_normal < 0, and never along
     * -plane_normal. Without it the newest force's direction stands in. */
    bool has_plane;
    ftm_vec3 plane_point;  /* [m] */
    ftm_vec3 plane_normal; /* outward; normalised on push */
} ftm_haptic_sample;

typedef struct ftm_haptic_def {
    ftm_haptic_renderer_kind renderer; /* default FTM_HAPTIC_FORCE_MODEL */
    double max_force;         /* [N] (default 8, a desktop device's peak) */
    double max_force_rate;    /* [N/s] (default 2000: 0 -> 8 N in 4 ms) */
    double max_extrapolation; /* [s] extrapolator horizon past the newest sample (default 0.1) */
    /* [s] the extrapolator holds the newest force when the two newest
     * samples are closer than this (default 0.5 ms, a 2 kHz server's tick):
     * frames drained back to back, stamped with their arrival, would give
     * a slope of a tick's change over tens of microseconds */
    double min_sample_interval;
    double stale_after;       /* [s] since the newest arrival before fading (default 0.1) */
    double fade_time;         /* [s] fade from full force to zero (default 0.1) */
    double rate_hz;           /* loop rate (default 1000) */
    bool realtime;            /* loop thread: try SCHED_FIFO (default true; falls back silently) */
    int priority;             /* SCHED_FIFO priority (default 80) */
    ftm_log_fn log;           /* loop start/stop messages; may be NULL */
    void *log_user;
} ftm_haptic_def;

ftm_haptic_def ftm_default_haptic_def(void);
/* FTM_EINVAL with a message naming the field if def is unusable. */
int ftm_haptic_def_check(const ftm_haptic_def *def, ftm_error *err);

/* What the safety stage did to the last force (bit set). */
enum {
    FTM_HAPTIC_NO_SAMPLE = 1,     /* no sample yet: zero force */
    FTM_HAPTIC_STALE = 2,         /* fading (or faded out) for lack of samples */
    FTM_HAPTIC_CLAMPED = 4,       /* magnitude limited */
    FTM_HAPTIC_RATE_LIMITED = 8,  /* rate of change limited */
    FTM_HAPTIC_DISCONNECTED = 16, /* disconnected: zero force */
    FTM_HAPTIC_UNILATERAL = 32,   /* the model pulled: that part removed */
    FTM_HAPTIC_DEVICE_LOST = 64,  /* device read failed: zero force */
    FTM_HAPTIC_RELEASED = 128,    /* HIP outside the contact plane, or no contact: zero */
};

/* ---- the renderer (pure; one thread) ---- */

typedef struct ftm_force_renderer {
    /* private: use the functions */
    ftm_haptic_def def;
    ftm_haptic_sample s[2]; /* s[1] newest */
    int count;              /* samples held, 0..2 */
    double arrival;         /* arrival time of s[1] */
    bool connected;
    bool have_prev;
    double prev_time;       /* time of the previous eval */
    ftm_vec3 prev_force;    /* output of the previous eval */
} ftm_force_renderer;

/* def NULL: defaults. Starts connected with no sample (zero force). */
void ftm_force_renderer_init(ftm_force_renderer *r, const ftm_haptic_def *def);
/* A new sample that arrived at time `arrival`. FTM_EINVAL (renderer
 * unchanged) if any value is not finite; a sample older than the newest
 * held is ignored (FTM_OK): samples may arrive out of order. */
int ftm_force_renderer_push(ftm_force_renderer *r, const ftm_haptic_sample *s, double arrival);
/* Disconnect drops the samples and forces zero from the next eval on. */
void ftm_force_renderer_set_connected(ftm_force_renderer *r, bool connected);
void ftm_force_renderer_set_kind(ftm_force_renderer *r, ftm_haptic_renderer_kind kind);
/* The renderer's force before the safety stage (no state change). */
ftm_vec3 ftm_force_renderer_model(const ftm_force_renderer *r, double now, ftm_vec3 hip);
/* The force to display at time now with the HIP at hip, after the safety
 * stage; flags (may be NULL) receives FTM_HAPTIC_* bits. Times of
 * successive calls should not decrease (a decrease counts as dt = 0). */
ftm_vec3 ftm_force_renderer_eval(ftm_force_renderer *r, double now, ftm_vec3 hip, int *flags);

/* Sample times from the server's tick times (tick / tick rate): frames
 * that arrive in a burst keep their ticks' spacing, which arrival times do
 * not (the extrapolator's slope needs it). The offset to the local clock is
 * the least delayed frame's: no sample gets a time after its arrival. The
 * least delay is taken over windows of FTM_HAPTIC_TIMEBASE_WINDOW, so the
 * offset follows a server whose ticks run a little slower than their
 * nominal rate (999.7 per second is common): held at the least delay ever
 * seen, such a drift would make fresh samples look ever older and the
 * extrapolator run ahead by up to max_age. A frame whose mapped time is
 * more than max_age before its arrival (a pause, a restart) re-anchors the
 * offset at it. Zero it (= {0}) to start afresh, e.g. on reconnection. */
#define FTM_HAPTIC_TIMEBASE_WINDOW 0.5 /* [s] */
typedef struct ftm_haptic_timebase {
    bool set;
    double offset;    /* local time - server time [s] */
    double win_min;   /* the least delay (arrival - server time) in this window */
    double win_start; /* when this window began (local) */
} ftm_haptic_timebase;
/* The local time for a sample of the tick at server_time that arrived at
 * arrival (both [s]). */
double ftm_haptic_timebase_map(ftm_haptic_timebase *tb, double server_time, double arrival,
                               double max_age);

/* ---- the haptic loop (a thread) ---- */

typedef struct ftm_haptic ftm_haptic;

/* CLOCK_MONOTONIC in seconds: the loop's clock (use it for sample times). */
double ftm_haptic_clock(void);

/* device is borrowed and must outlive the loop. */
int ftm_haptic_create(const ftm_haptic_def *def, ftm_device *device, ftm_haptic **out,
                      ftm_error *err);
/* Starts the thread (device start, then ticks at absolute deadlines of
 * CLOCK_MONOTONIC). SCHED_FIFO if def.realtime and permitted, else the
 * default policy. FTM_EINVAL if already running. */
int ftm_haptic_start(ftm_haptic *h, ftm_error *err);
/* Stops and joins the thread; the last force written is zero. No-op if not
 * running. */
void ftm_haptic_stop(ftm_haptic *h);
/* Stops if running, then frees. */
void ftm_haptic_destroy(ftm_haptic *h);

/* Any thread (replay thread): a new reaction sample; stamped with the
 * arrival time now. FTM_EINVAL if not finite. Up to 64 samples wait for
 * the next tick; beyond that the oldest are dropped (only the newest two
 * matter to the renderers). */
int ftm_haptic_push(ftm_haptic *h, const ftm_haptic_sample *s);
/* Any thread: connection to the server lost (false) or back (true). */
void ftm_haptic_set_connected(ftm_haptic *h, bool connected);
void ftm_haptic_set_renderer(ftm_haptic *h, ftm_haptic_renderer_kind kind);

typedef struct ftm_haptic_state {
    bool running;
    bool realtime;      /* the thread got SCHED_FIFO */
    uint64_t ticks;     /* loop iterations */
    uint64_t overruns;  /* ticks that started more than one period late */
    uint64_t dropped;   /* samples dropped from a full queue */
    double time;        /* time of the last tick [s] */
    ftm_vec3 hip;       /* HIP read at the last tick [m, scene] */
    ftm_vec3 force;     /* force written at the last tick [N, scene] */
    int flags;          /* FTM_HAPTIC_* of the last tick */
    ftm_haptic_renderer_kind renderer;
} ftm_haptic_state;

/* Any thread (render thread): a consistent snapshot. */
void ftm_haptic_get_state(ftm_haptic *h, ftm_haptic_state *st);

/* HIP positions the loop read, for ProbeInput batches. */
typedef struct ftm_haptic_hip {
    double time;
    ftm_vec3 hip;
} ftm_haptic_hip;
/* Any thread: moves up to max HIP samples, oldest first, that the loop
 * read since the previous call, to out; returns how many. The loop keeps the
 * newest 4096; older ones are lost if nobody takes them. */
int ftm_haptic_take_hips(ftm_haptic *h, ftm_haptic_hip *out, int max);

/* Loop timing since start: achieved rate and the distribution of the
 * period between consecutive ticks (histogram of 1 us bins up to 20 ms). */
typedef struct ftm_haptic_timing {
    uint64_t periods;     /* periods measured */
    double elapsed;       /* first to last tick [s] */
    double rate_hz;       /* periods / elapsed */
    double p50, p99, p999, max; /* period percentiles and maximum [s] */
    double mean;          /* mean period [s] */
} ftm_haptic_timing;
void ftm_haptic_get_timing(ftm_haptic *h, ftm_haptic_timing *t);

#ifdef __cplusplus
}
#endif
#endif
