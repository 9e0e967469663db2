/* SPDX-License-Identifier: GPL-3.0-or-later */
/* Prometheus text exposition over libmicrohttpd (metrics.h). */
#include "metrics.h"

#include <arpa/inet.h>
#include <errno.h>
#include <microhttpd.h>
#include <netinet/in.h>
#include <pthread.h>
#include <stdarg.h>
#include <stdbool.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/socket.h>
#include <time.h>

const double ftm_metrics_step_bounds[FTM_METRICS_STEP_BUCKETS] = {
    25e-6, 50e-6, 100e-6, 200e-6, 500e-6, 1e-3, 2e-3, 5e-3, 10e-3};

/* Slow clients must not keep a scraper out (a slowloris: connections that
 * trickle their headers, each byte resetting an idle timeout). Three limits:
 * many connections (MHD polls them, no FD_SETSIZE cap); an idle timeout;
 * and a deadline: a connection must complete a request within
 * FTM_METRICS_DEADLINE_S of opening or of its previous answer, or a sweeper
 * shuts its socket down. Holding a slot then costs an attacker a new
 * connection every 2 s: 256 slots need 128 new connections a second. */
#define FTM_METRICS_CONNECTIONS 256
#define FTM_METRICS_IDLE_S 2u
#define FTM_METRICS_DEADLINE_S 2.0

typedef struct conn_slot {
    int fd;        /* -1: free */
    double since;  /* opened, or last answered [s, monotonic] */
    bool shut;     /* the sweeper shut it down; MHD closes it */
} conn_slot;

struct ftm_metrics {
    struct MHD_Daemon *daemon;
    pthread_mutex_t lock;
    ftm_metrics_snapshot snap; /* under lock */
    /* the deadline's sweeper; slots under lock */
    conn_slot slot[FTM_METRICS_CONNECTIONS];
    pthread_t sweeper;
    pthread_cond_t wake;
    bool stopping, sweeping;
    uint64_t deadline_closed; /* connections the sweeper shut down */
};

static double mono_s(void)
{
    struct timespec ts;
    clock_gettime(CLOCK_MONOTONIC, &ts);
    return (double)ts.tv_sec + 1e-9 * (double)ts.tv_nsec;
}

/* MHD_OPTION_NOTIFY_CONNECTION: a slot per open connection, its index in
 * the connection's socket context (+1, so NULL is "none"). MHD calls CLOSED
 * before it closes the socket, so the sweeper never touches a closed fd. */
static void on_connection(void *cls, struct MHD_Connection *c, void **ctx,
                          enum MHD_ConnectionNotificationCode code)
{
    ftm_metrics *m = cls;
    pthread_mutex_lock(&m->lock);
    if (code == MHD_CONNECTION_NOTIFY_STARTED) {
        const union MHD_ConnectionInfo *ci =
            MHD_get_connection_info(c, MHD_CONNECTION_INFO_CONNECTION_FD);
        for (size_t i = 0; ci && i < FTM_METRICS_CONNECTIONS; i++)
            if (m->slot[i].fd < 0) {
                m->slot[i] = (conn_slot){.fd = ci->connect_fd, .since = mono_s()};
                *ctx = (void *)(uintptr_t)(i + 1);
                break;
            }
    } else if (*ctx) {
        m->slot[(uintptr_t)*ctx - 1].fd = -1;
        *ctx = NULL;
    }
    pthread_mutex_unlock(&m->lock);
}

/* A request answered: the deadline starts again (a kept-alive scraper). */
static void answered(ftm_metrics *m, struct MHD_Connection *c)
{
    const union MHD_ConnectionInfo *ci =
        MHD_get_connection_info(c, MHD_CONNECTION_INFO_SOCKET_CONTEXT);
    if (!ci || !ci->socket_context)
        return;
    pthread_mutex_lock(&m->lock);
    m->slot[(uintptr_t)ci->socket_context - 1].since = mono_s();
    pthread_mutex_unlock(&m->lock);
}

static void *sweep(void *arg)
{
    ftm_metrics *m = arg;
    pthread_mutex_lock(&m->lock);
    while (!m->stopping) {
        double now = mono_s();
        for (size_t i = 0; i < FTM_METRICS_CONNECTIONS; i++) {
            conn_slot *sl = &m->slot[i];
            if (sl->fd >= 0 && !sl->shut && now - sl->since > FTM_METRICS_DEADLINE_S) {
                shutdown(sl->fd, SHUT_RDWR); /* MHD sees the end and closes it */
                sl->shut = true;
                m->deadline_closed++;
            }
        }
        struct timespec until;
        clock_gettime(CLOCK_REALTIME, &until);
        until.tv_nsec += 100000000L; /* every 100 ms */
        if (until.tv_nsec >= 1000000000L) {
            until.tv_sec++;
            until.tv_nsec -= 1000000000L;
        }
        pthread_cond_timedwait(&m->wake, &m->lock, &until);
    }
    pthread_mutex_unlock(&m->lock);
    return NULL;
}

typedef struct textbuf {
    char *buf;
    size_t size, len;
} textbuf;

static void put(textbuf *o, const char *fmt, ...) __attribute__((format(printf, 2, 3)));
static void put(textbuf *o, const char *fmt, ...)
{
    va_list ap;
    va_start(ap, fmt);
    size_t room = o->len < o->size ? o->size - o->len : 0;
    int n = vsnprintf(room ? o->buf + o->len : NULL, room, fmt, ap);
    va_end(ap);
    if (n > 0)
        o->len += (size_t)n;
}

static void metric(textbuf *o, const char *name, const char *type, const char *help)
{
    put(o, "# HELP %s %s\n# TYPE %s %s\n", name, help, name, type);
}

size_t ftm_metrics_render(const ftm_metrics_snapshot *s, char *buf, size_t size)
{
    textbuf o = {buf, size, 0};
    if (size)
        buf[0] = '\0';
    metric(&o, "ftm_tick_rate_target_hz", "gauge", "Configured tick rate.");
    put(&o, "ftm_tick_rate_target_hz %.6g\n", s->tick_rate_target);
    metric(&o, "ftm_tick_rate_hz", "gauge", "Ticks run per second, measured over the last second.");
    put(&o, "ftm_tick_rate_hz %.6g\n", s->tick_rate);
    metric(&o, "ftm_ticks_total", "counter", "Ticks run.");
    put(&o, "ftm_ticks_total %llu\n", (unsigned long long)s->ticks);
    metric(&o, "ftm_missed_ticks_total", "counter", "Ticks skipped because the server fell behind.");
    put(&o, "ftm_missed_ticks_total %llu\n", (unsigned long long)s->missed_ticks);
    metric(&o, "ftm_idle_ticks_total", "counter", "Idle ticks not sent.");
    put(&o, "ftm_idle_ticks_total %llu\n", (unsigned long long)s->idle_ticks);
    metric(&o, "ftm_metrics_slow_closed_total", "counter",
           "Metrics connections closed for taking over 2 s to send a request.");
    put(&o, "ftm_metrics_slow_closed_total %llu\n", (unsigned long long)s->slow_closed);
    metric(&o, "ftm_step_seconds", "histogram", "Server time per tick (collision, step, frame).");
    uint64_t cum = 0;
    for (int i = 0; i < FTM_METRICS_STEP_BUCKETS; i++) {
        cum += s->step_bucket[i];
        put(&o, "ftm_step_seconds_bucket{le=\"%g\"} %llu\n", ftm_metrics_step_bounds[i],
            (unsigned long long)cum);
    }
    cum += s->step_bucket[FTM_METRICS_STEP_BUCKETS];
    put(&o, "ftm_step_seconds_bucket{le=\"+Inf\"} %llu\n", (unsigned long long)cum);
    put(&o, "ftm_step_seconds_sum %.9g\n", s->step_sum_s);
    put(&o, "ftm_step_seconds_count %llu\n", (unsigned long long)s->step_count);
    metric(&o, "ftm_step_recent_seconds", "gauge", "Mean server time per tick over the last 100 ms.");
    put(&o, "ftm_step_recent_seconds %.9g\n", s->step_last_period_s);
    metric(&o, "ftm_depth", "gauge", "Penetration depth in use.");
    put(&o, "ftm_depth %d\n", (int)s->depth);
    metric(&o, "ftm_depth_min", "gauge", "Floor of the adaptive depth.");
    put(&o, "ftm_depth_min %d\n", (int)s->depth_min);
    metric(&o, "ftm_depth_max", "gauge", "Ceiling of the adaptive depth (calibrated optimum).");
    put(&o, "ftm_depth_max %d\n", (int)s->depth_max);
    metric(&o, "ftm_depth_changes_total", "counter", "Depth changes by the adaptive controller.");
    put(&o, "ftm_depth_changes_total{direction=\"down\"} %llu\n",
        (unsigned long long)s->depth_decreases);
    put(&o, "ftm_depth_changes_total{direction=\"up\"} %llu\n",
        (unsigned long long)s->depth_increases);
    metric(&o, "ftm_frames_sent_total", "counter", "Tick frames published (heartbeats included).");
    put(&o, "ftm_frames_sent_total %llu\n", (unsigned long long)s->frames);
    metric(&o, "ftm_heartbeats_sent_total", "counter", "Idle heartbeat frames published.");
    put(&o, "ftm_heartbeats_sent_total %llu\n", (unsigned long long)s->heartbeats);
    metric(&o, "ftm_keyframes_sent_total", "counter", "Keyframes published.");
    put(&o, "ftm_keyframes_sent_total %llu\n", (unsigned long long)s->keyframes);
    metric(&o, "ftm_bytes_sent_total", "counter", "Payload bytes published, by message kind.");
    put(&o, "ftm_bytes_sent_total{kind=\"tick_frame\"} %llu\n",
        (unsigned long long)s->bytes_frames);
    put(&o, "ftm_bytes_sent_total{kind=\"keyframe\"} %llu\n",
        (unsigned long long)s->bytes_keyframes);
    metric(&o, "ftm_publish_failures_total", "counter", "Messages that could not be queued.");
    put(&o, "ftm_publish_failures_total %llu\n", (unsigned long long)s->publish_fail);
    metric(&o, "ftm_dds_rexmit_bytes_total", "counter", "Bytes the tick frame writer retransmitted.");
    put(&o, "ftm_dds_rexmit_bytes_total %llu\n", (unsigned long long)s->rexmit_bytes);
    metric(&o, "ftm_dds_throttle_total", "counter", "Times the tick frame writer was throttled.");
    put(&o, "ftm_dds_throttle_total %llu\n", (unsigned long long)s->throttle_count);
    metric(&o, "ftm_inputs_rejected_total", "counter", "Probe input and control messages rejected.");
    put(&o, "ftm_inputs_rejected_total %llu\n", (unsigned long long)s->inputs_rejected);
    metric(&o, "ftm_probe_push_limited_total", "counter",
           "Probe-ticks whose push into the tissue was shortened to the limit.");
    put(&o, "ftm_probe_push_limited_total %llu\n", (unsigned long long)s->push_limited);
    metric(&o, "ftm_unstable_ticks_total", "counter",
           "Steps that stayed unstable at the most substeps: the tissue was reset to rest.");
    put(&o, "ftm_unstable_ticks_total %llu\n", (unsigned long long)s->unstable_ticks);
    metric(&o, "ftm_record_bytes", "gauge",
           "Bytes of the session recording (after a failure: what the file kept).");
    put(&o, "ftm_record_bytes %llu\n", (unsigned long long)s->record_bytes);
    metric(&o, "ftm_record_ok", "gauge",
           "1 unless the recording asked for is stopped on a write error (1 again once it "
           "records on into a new file).");
    put(&o, "ftm_record_ok %d\n", s->record_ok ? 1 : 0);
    metric(&o, "ftm_record_errors_total", "counter", "Write errors of the session recording.");
    put(&o, "ftm_record_errors_total %llu\n", (unsigned long long)s->record_errors);
    metric(&o, "ftm_record_resumed_total", "counter",
           "New files of the lesson begun once space returned after a full disk.");
    put(&o, "ftm_record_resumed_total %llu\n", (unsigned long long)s->record_files);
    metric(&o, "ftm_record_free_bytes", "gauge",
           "After a full disk stopped the recording: free bytes where it records, at the last "
           "look (each second); it records on at 1 MiB.");
    put(&o, "ftm_record_free_bytes %llu\n", (unsigned long long)s->record_free_bytes);
    metric(&o, "ftm_participants", "gauge", "Participants known (not lost).");
    put(&o, "ftm_participants %d\n", (int)s->nparts);
    metric(&o, "ftm_participant_lag_ticks", "gauge", "Ticks a participant is behind the server.");
    for (int32_t i = 0; i < s->nparts && i < FTM_METRICS_PARTS; i++)
        put(&o, "ftm_participant_lag_ticks{participant=\"%u\",role=\"%s\",state=\"%s\"} %lld\n",
            s->parts[i].id, s->parts[i].role, s->parts[i].state, (long long)s->parts[i].lag);
    metric(&o, "ftm_participant_replay_seconds", "gauge",
           "A participant's reported replay time per tick.");
    for (int32_t i = 0; i < s->nparts && i < FTM_METRICS_PARTS; i++)
        put(&o, "ftm_participant_replay_seconds{participant=\"%u\",role=\"%s\"} %.9g\n",
            s->parts[i].id, s->parts[i].role, s->parts[i].replay_ns * 1e-9);
    return o.len;
}

static enum MHD_Result handler(void *cls, struct MHD_Connection *c, const char *url,
                               const char *method, const char *version, const char *upload,
                               size_t *upload_size, void **con_cls)
{
    (void)version;
    (void)upload;
    (void)upload_size;
    (void)con_cls;
    ftm_metrics *m = cls;
    struct MHD_Response *r;
    unsigned status;
    if (strcmp(method, "GET") != 0 || (strcmp(url, "/metrics") != 0 && strcmp(url, "/") != 0)) {
        static const char nf[] = "not found: GET /metrics\n";
        r = MHD_create_response_from_buffer(sizeof nf - 1, (void *)nf, MHD_RESPMEM_PERSISTENT);
        status = MHD_HTTP_NOT_FOUND;
    } else {
        ftm_metrics_snapshot *s = malloc(sizeof *s);
        if (!s)
            return MHD_NO;
        pthread_mutex_lock(&m->lock);
        *s = m->snap;
        s->slow_closed = m->deadline_closed;
        pthread_mutex_unlock(&m->lock);
        size_t need = ftm_metrics_render(s, NULL, 0) + 1;
        char *buf = malloc(need);
        if (!buf) {
            free(s);
            return MHD_NO;
        }
        size_t len = ftm_metrics_render(s, buf, need);
        free(s);
        r = MHD_create_response_from_buffer(len, buf, MHD_RESPMEM_MUST_FREE);
        status = MHD_HTTP_OK;
        if (r)
            MHD_add_response_header(r, "Content-Type", "text/plain; version=0.0.4; charset=utf-8");
    }
    if (!r)
        return MHD_NO;
    answered(m, c);
    enum MHD_Result ret = MHD_queue_response(c, status, r);
    MHD_destroy_response(r);
    return ret;
}

int ftm_metrics_start(const char *addr, uint16_t port, ftm_metrics **out, ftm_error *err)
{
    *out = NULL;
    struct sockaddr_storage ss;
    memset(&ss, 0, sizeof ss);
    struct sockaddr_in *v4 = (struct sockaddr_in *)&ss;
    struct sockaddr_in6 *v6 = (struct sockaddr_in6 *)&ss;
    /* MHD_USE_AUTO: epoll on Linux, so connections past FD_SETSIZE are polled too */
    unsigned flags = MHD_USE_INTERNAL_POLLING_THREAD | MHD_USE_AUTO | MHD_USE_ERROR_LOG;
    if (!addr)
        addr = "127.0.0.1";
    if (inet_pton(AF_INET, addr, &v4->sin_addr) == 1) {
        v4->sin_family = AF_INET;
        v4->sin_port = htons(port);
    } else if (inet_pton(AF_INET6, addr, &v6->sin6_addr) == 1) {
        v6->sin6_family = AF_INET6;
        v6->sin6_port = htons(port);
        flags |= MHD_USE_IPv6;
    } else {
        err->code = FTM_EINVAL;
        snprintf(err->message, sizeof err->message,
                 "metrics: '%.200s' is not an IPv4 or IPv6 address", addr);
        return FTM_EINVAL;
    }
    ftm_metrics *m = calloc(1, sizeof *m);
    if (!m) {
        err->code = FTM_ENOMEM;
        snprintf(err->message, sizeof err->message, "metrics: out of memory");
        return FTM_ENOMEM;
    }
    pthread_mutex_init(&m->lock, NULL);
    pthread_cond_init(&m->wake, NULL);
    for (size_t i = 0; i < FTM_METRICS_CONNECTIONS; i++)
        m->slot[i].fd = -1;
    m->daemon = MHD_start_daemon(
        flags, port, NULL, NULL, handler, m, MHD_OPTION_SOCK_ADDR, (struct sockaddr *)&ss,
        MHD_OPTION_CONNECTION_LIMIT, (unsigned)FTM_METRICS_CONNECTIONS,
        MHD_OPTION_CONNECTION_TIMEOUT, FTM_METRICS_IDLE_S, MHD_OPTION_NOTIFY_CONNECTION,
        on_connection, m, MHD_OPTION_END);
    if (m->daemon && pthread_create(&m->sweeper, NULL, sweep, m) == 0)
        m->sweeping = true;
    if (!m->daemon || !m->sweeping) {
        if (m->daemon)
            MHD_stop_daemon(m->daemon);
        pthread_cond_destroy(&m->wake);
        pthread_mutex_destroy(&m->lock);
        free(m);
        err->code = FTM_EIO;
        snprintf(err->message, sizeof err->message,
                 "metrics: cannot listen on %s%.200s%s:%u (port in use, or no such local address?)",
                 v6->sin6_family == AF_INET6 ? "[" : "", addr,
                 v6->sin6_family == AF_INET6 ? "]" : "", (unsigned)port);
        return FTM_EIO;
    }
    *out = m;
    return FTM_OK;
}

void ftm_metrics_update(ftm_metrics *m, const ftm_metrics_snapshot *s)
{
    if (!m)
        return;
    pthread_mutex_lock(&m->lock);
    m->snap = *s;
    pthread_mutex_unlock(&m->lock);
}

void ftm_metrics_stop(ftm_metrics *m)
{
    if (!m)
        return;
    pthread_mutex_lock(&m->lock);
    m->stopping = true;
    pthread_cond_signal(&m->wake);
    pthread_mutex_unlock(&m->lock);
    pthread_join(m->sweeper, NULL);
    MHD_stop_daemon(m->daemon);
    pthread_cond_destroy(&m->wake);
    pthread_mutex_destroy(&m->lock);
    free(m);
}
