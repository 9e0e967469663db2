/* SPDX-License-Identifier: GPL-3.0-or-later */
/* The DDS transport: one Cyclone DDS participant, one topic per message kind
 * (type ftm::wire::Envelope, keyed by session and sender), writers and
 * readers with the QoS of docs/protocol.md, and a publishing thread so that
 * callers never wait in dds_write (which can stall for milliseconds). No
 * globals: every transport is self-contained.
 *
 * Receiving: each reader has a data-available listener, which Cyclone calls
 * in its own receive thread as a sample arrives. It takes the samples, stamps
 * their arrival and queues their bytes; ftm_wire_receive decodes and checks
 * them in the caller's thread. So a message's arrival is seen when it reaches
 * the process, not when the application thread gets round to it, and the
 * receive thread is never held up by decoding. */
#define _GNU_SOURCE /* pthread_setaffinity_np, CPU_SET */
#include "wire_internal.h"

#include "ftm_envelope.h"

#include <dds/dds.h>
#include <dds/ddsc/dds_statistics.h>

#include <errno.h>
#include <limits.h>
#include <pthread.h>
#include <sched.h>
#include <stdarg.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <time.h>

#define KINDS (FTM_WIRE_KIND_MAX + 1)
#define SENDERS_MAX 1024

/* QoS numbers (docs/protocol.md, "Topics and QoS"). */
#define TICK_WRITER_DEPTH 256
#define TICK_READER_DEPTH 1024
#define PROBE_DEPTH 64
#define CONTROL_DEPTH 64
#define STATUS_DEADLINE DDS_SECS(2)
#define MAX_BLOCKING DDS_MSECS(100)
#define DESTROY_DRAIN_NS 2000000000LL

typedef struct queue_item {
    struct queue_item *next;
    int kind;
    uint64_t seq;
    size_t size;
    uint8_t data[];
} queue_item;

/* A sample as taken by the listener, decoded later by ftm_wire_receive. */
typedef struct rx_item {
    struct rx_item *next;
    int64_t arrival_ns;     /* CLOCK_REALTIME in the listener */
    int64_t source_time_ns;
    bool valid;             /* valid_data; else an instance-state change */
    bool alive;             /* instance_state == ALIVE */
    uint32_t sender;
    char session[64]; /* Envelope.session (any_session transports) */
    uint64_t origin; /* the writer's process (writer_of) */
    /* secured: the role and id its writer's partition certifies (0: none) */
    uint32_t cert_id;
    uint8_t cert_role;
    uint8_t kind;
    uint64_t seq;
    size_t size;
    size_t oversize; /* > 0: a payload of this many bytes, over the cap, not copied */
    uint8_t data[];
} rx_item;

/* Per kind, beyond either the oldest go (a gap for the reader): a reader
 * that stops reading, or a peer that floods, costs bounded memory. */
#define RX_QUEUE_MAX 8192
#define RX_QUEUE_BYTES (64u << 20)

typedef struct sender_seq {
    uint32_t sender;
    uint64_t origin; /* two processes that give one sender id count apart */
    uint64_t last;
} sender_seq;

struct ftm_wire_transport;

#define ORIGIN_CACHE 64 /* writers remembered per reader: far more than a session has */

typedef struct kind_io {
    dds_entity_t topic, writer, reader;
    /* receive queue: filled by the reader's listener (Cyclone's thread),
     * emptied by ftm_wire_receive */
    pthread_mutex_t rx_lock;
    pthread_cond_t rx_cond;
    rx_item *rx_head, *rx_tail;
    int32_t rx_count;
    size_t rx_bytes;
    uint64_t rx_dropped, rx_dropped_seen;
    struct ftm_wire_transport *owner;
    int kind;
    struct dds_statistics *wstats;
    uint64_t next_seq; /* under t->lock */
    /* receive side: one thread per kind */
    sender_seq *senders;
    int nsenders, capsenders;
    ftm_wire_stats stats; /* counters under t->lock */
    /* the listener's cache of writer -> DDS participant and, secured, the
     * identity its partition certifies (writer_of) */
    struct writer_info {
        dds_instance_handle_t writer;
        uint64_t origin;
        uint32_t cert_id;
        ftm_wire_role cert_role;
    } origins[ORIGIN_CACHE];
    int next_origin;
} kind_io;

struct ftm_wire_transport {
    dds_entity_t participant;
    /* DDS Security: the permissions file and our writers' partition; ""
     * without. Secured, writers and readers live in a publisher and a
     * subscriber of their own, with the partitions. */
    wire_security sec;
    dds_entity_t publisher, subscriber;
    uint64_t origin; /* ours, as others see it (origin_of_guid) */
    char session[64];
    bool any_session; /* read every session of the domain (def.any_session) */
    uint32_t id;
    ftm_wire_limits limits;
    ftm_log_fn log;
    void *log_user;
    kind_io io[KINDS];

    pthread_mutex_t lock;
    pthread_cond_t wake, drained;
    queue_item *head, *tail;
    int32_t queued, capacity;
    bool busy, stop, thread_started;
    pthread_t thread;
};

static bool valid_kind(int kind)
{
    return kind >= FTM_WIRE_KIND_MIN && kind <= FTM_WIRE_KIND_MAX;
}

static void wire_log(ftm_wire_transport *t, ftm_log_level level, const char *fmt, ...)
    __attribute__((format(printf, 3, 4)));
static void wire_log(ftm_wire_transport *t, ftm_log_level level, const char *fmt, ...)
{
    if (!t->log)
        return;
    char buf[FTM_ERROR_MESSAGE_MAX + 128];
    va_list ap;
    va_start(ap, fmt);
    vsnprintf(buf, sizeof buf, fmt, ap);
    va_end(ap);
    t->log(t->log_user, level, buf);
}

static int64_t now_ns(void)
{
    struct timespec ts;
    clock_gettime(CLOCK_MONOTONIC, &ts);
    return (int64_t)ts.tv_sec * 1000000000 + ts.tv_nsec;
}

static void sleep_ns(int64_t ns)
{
    struct timespec ts = {(time_t)(ns / 1000000000), (long)(ns % 1000000000)};
    while (nanosleep(&ts, &ts) == -1 && errno == EINTR) {
    }
}

static int dds_fail(ftm_error *err, const char *call, dds_return_t rc)
{
    return ftm_error_set(err, FTM_EDDS, "%s failed: %s", call, dds_strretcode(rc));
}

/* ---- QoS ---------------------------------------------------------------- */

static dds_qos_t *kind_qos(int kind, bool writer)
{
    dds_qos_t *q = dds_create_qos();
    /* A participant never receives what it wrote itself. */
    dds_qset_ignorelocal(q, DDS_IGNORELOCAL_PARTICIPANT);
    dds_qset_liveliness(q, DDS_LIVELINESS_AUTOMATIC, DDS_INFINITY);
    switch (kind) {
    case FTM_WIRE_ANNOUNCE:
    case FTM_WIRE_KEYFRAME:
        /* the latest one per (session, sender) is kept by the writer and
         * handed to every reader that joins later */
        dds_qset_reliability(q, DDS_RELIABILITY_RELIABLE, MAX_BLOCKING);
        dds_qset_history(q, DDS_HISTORY_KEEP_LAST, 1);
        dds_qset_durability(q, DDS_DURABILITY_TRANSIENT_LOCAL);
        break;
    case FTM_WIRE_PROBE_INPUT:
        /* superseded by the next batch within a millisecond: no repairs */
        dds_qset_reliability(q, DDS_RELIABILITY_BEST_EFFORT, 0);
        dds_qset_history(q, DDS_HISTORY_KEEP_LAST, PROBE_DEPTH);
        dds_qset_durability(q, DDS_DURABILITY_VOLATILE);
        break;
    case FTM_WIRE_TICK:
        /* every frame is needed; KEEP_LAST so the writer never blocks, a
         * reader that falls behind by more sees a sequence gap and resyncs */
        dds_qset_reliability(q, DDS_RELIABILITY_RELIABLE, MAX_BLOCKING);
        dds_qset_history(q, DDS_HISTORY_KEEP_LAST, writer ? TICK_WRITER_DEPTH : TICK_READER_DEPTH);
        dds_qset_durability(q, DDS_DURABILITY_VOLATILE);
        break;
    case FTM_WIRE_STATUS:
        dds_qset_reliability(q, DDS_RELIABILITY_RELIABLE, MAX_BLOCKING);
        dds_qset_history(q, DDS_HISTORY_KEEP_LAST, 1);
        dds_qset_durability(q, DDS_DURABILITY_TRANSIENT_LOCAL);
        /* Offered by writers only: with a deadline on the reader, Cyclone
         * 0.10.2 never delivers the NOT_ALIVE_NO_WRITERS sample of an
         * instance whose writer's lease expired (a crashed participant's
         * `gone` event; checked on this machine, docs/protocol.md). */
        if (writer)
            dds_qset_deadline(q, STATUS_DEADLINE);
        break;
    case FTM_WIRE_CONTROL:
    case FTM_WIRE_CONTROL_REPLY: /* one per command, like the commands */
    default:
        dds_qset_reliability(q, DDS_RELIABILITY_RELIABLE, MAX_BLOCKING);
        dds_qset_history(q, DDS_HISTORY_KEEP_LAST, CONTROL_DEPTH);
        dds_qset_durability(q, DDS_DURABILITY_VOLATILE);
        break;
    }
    return q;
}

/* ---- publishing thread ---------------------------------------------------- */

static void *publisher_main(void *arg)
{
    ftm_wire_transport *t = arg;
    pthread_mutex_lock(&t->lock);
    for (;;) {
        while (!t->head && !t->stop)
            pthread_cond_wait(&t->wake, &t->lock);
        if (!t->head)
            break; /* stopping and drained */
        queue_item *it = t->head;
        t->head = it->next;
        if (!t->head)
            t->tail = NULL;
        t->queued--;
        t->busy = true;
        pthread_mutex_unlock(&t->lock);

        ftm_wire_Envelope env;
        memset(&env, 0, sizeof env);
        memcpy(env.session, t->session, sizeof env.session);
        env.sender = t->id;
        env.kind = (uint8_t)it->kind;
        env.seq = it->seq;
        env.payload._maximum = (uint32_t)it->size;
        env.payload._length = (uint32_t)it->size;
        env.payload._buffer = it->data;
        env.payload._release = false;
        dds_return_t rc = dds_write(t->io[it->kind].writer, &env);
        if (rc < 0)
            wire_log(t, FTM_LOG_ERROR, "wire: dds_write of %s seq %llu failed: %s",
                     ftm_wire_kind_name(it->kind), (unsigned long long)it->seq,
                     dds_strretcode(rc));

        pthread_mutex_lock(&t->lock);
        if (rc < 0)
            t->io[it->kind].stats.write_errors++;
        else
            t->io[it->kind].stats.published++;
        t->busy = false;
        if (!t->head)
            pthread_cond_broadcast(&t->drained);
        free(it);
    }
    pthread_mutex_unlock(&t->lock);
    return NULL;
}

static int enqueue(ftm_wire_transport *t, int kind, uint8_t *payload, size_t size, ftm_error *err)
{
    queue_item *it = malloc(sizeof *it + size);
    if (!it)
        return ftm_error_set(err, FTM_ENOMEM, "%s: out of memory queueing %zu bytes",
                             ftm_wire_kind_name(kind), size);
    it->next = NULL;
    it->kind = kind;
    it->size = size;
    if (size)
        memcpy(it->data, payload, size);
    pthread_mutex_lock(&t->lock);
    if (t->queued >= t->capacity) {
        t->io[kind].stats.queue_full++;
        pthread_mutex_unlock(&t->lock);
        free(it);
        return ftm_error_set(err, FTM_EAGAIN, "%s: publishing queue full (%d messages); dropped",
                             ftm_wire_kind_name(kind), t->capacity);
    }
    it->seq = ++t->io[kind].next_seq;
    if (t->tail)
        t->tail->next = it;
    else
        t->head = it;
    t->tail = it;
    t->queued++;
    pthread_cond_signal(&t->wake);
    pthread_mutex_unlock(&t->lock);
    return FTM_OK;
}

int ftm_wire_publish(ftm_wire_transport *t, const ftm_wire_msg *msg, ftm_error *err)
{
    if (!t || !msg)
        return ftm_error_set(err, FTM_EINVAL, "ftm_wire_publish: NULL argument");
    if (!valid_kind(msg->kind) || !t->io[msg->kind].writer)
        return ftm_error_set(err, FTM_EINVAL,
                             "ftm_wire_publish: this transport does not publish %s",
                             ftm_wire_kind_name(msg->kind));
    uint8_t *buf = NULL;
    size_t size = 0;
    int rc = ftm_wire_encode(msg, &buf, &size, err);
    if (rc)
        return rc;
    rc = enqueue(t, msg->kind, buf, size, err);
    free(buf);
    return rc;
}

int ftm_wire_publish_raw(ftm_wire_transport *t, int kind, const void *payload, size_t size,
                         ftm_error *err)
{
    if (!t || (!payload && size))
        return ftm_error_set(err, FTM_EINVAL, "ftm_wire_publish_raw: NULL argument");
    if (!valid_kind(kind) || !t->io[kind].writer)
        return ftm_error_set(err, FTM_EINVAL,
                             "ftm_wire_publish_raw: this transport does not publish %s",
                             ftm_wire_kind_name(kind));
    if (size > FTM_WIRE_CAP_KEYFRAME)
        return ftm_error_set(err, FTM_ETOOBIG,
                             "%s: raw payload of %zu bytes exceeds the envelope bound %u",
                             ftm_wire_kind_name(kind), size, (unsigned)FTM_WIRE_CAP_KEYFRAME);
    return enqueue(t, kind, (uint8_t *)payload, size, err);
}

/* Waits until the queue is empty; returns false on timeout. */
static bool wait_drained(ftm_wire_transport *t, int64_t deadline)
{
    pthread_mutex_lock(&t->lock);
    bool ok = true;
    while (t->head || t->busy) {
        int64_t left = deadline - now_ns();
        if (left <= 0) {
            ok = false;
            break;
        }
        struct timespec ts;
        clock_gettime(CLOCK_MONOTONIC, &ts);
        int64_t step = left < 50000000 ? left : 50000000;
        int64_t ns = ts.tv_nsec + step;
        ts.tv_sec += (time_t)(ns / 1000000000);
        ts.tv_nsec = (long)(ns % 1000000000);
        pthread_cond_timedwait(&t->drained, &t->lock, &ts);
    }
    pthread_mutex_unlock(&t->lock);
    return ok;
}

int ftm_wire_flush(ftm_wire_transport *t, int64_t timeout_ns, ftm_error *err)
{
    if (!t)
        return ftm_error_set(err, FTM_EINVAL, "ftm_wire_flush: NULL transport");
    int64_t deadline = now_ns() + timeout_ns;
    if (!wait_drained(t, deadline))
        return ftm_error_set(err, FTM_ETIMEDOUT, "flush: publishing queue not empty after %.3f s",
                             (double)timeout_ns * 1e-9);
    for (int k = FTM_WIRE_KIND_MIN; k <= FTM_WIRE_KIND_MAX; k++) {
        if (!t->io[k].writer || k == FTM_WIRE_PROBE_INPUT)
            continue;
        int64_t left = deadline - now_ns();
        dds_return_t rc = dds_wait_for_acks(t->io[k].writer, left > 0 ? left : 0);
        if (rc == DDS_RETCODE_TIMEOUT)
            return ftm_error_set(err, FTM_ETIMEDOUT,
                                 "flush: %s not acknowledged by every reader in %.3f s",
                                 ftm_wire_kind_name(k), (double)timeout_ns * 1e-9);
        if (rc < 0)
            return dds_fail(err, "dds_wait_for_acks", rc);
    }
    return FTM_OK;
}

/* ---- create / destroy ------------------------------------------------------ */

/* Creates the domain with the configuration (a file, XML text or, if NULL,
 * $CYCLONEDDS_URI) plus the security bundle's fragment. *created: the domain
 * entity if this call made it, else 0 (another transport of this process
 * made it: it is shared). */
static int make_domain(const ftm_wire_transport_def *def, ftm_wire_transport *t,
                       dds_entity_t *created, ftm_error *err)
{
    *created = 0;
    char *sec = NULL;
    if (def->security) {
        int rc = wire_security_config(def->security, def->participant_id, &sec, &t->sec, err);
        if (rc)
            return rc;
    }
    const char *c = def->config;
    char *uri = NULL;
    if (c) {
        while (*c == ' ' || *c == '\t' || *c == '\n' || *c == '\r')
            c++;
        if (*c != '<') {
            FILE *f = fopen(def->config, "r");
            if (!f) {
                free(sec);
                return ftm_error_set(err, FTM_EIO, "Cyclone DDS configuration %s: %s", def->config,
                                     strerror(errno));
            }
            fclose(f);
            if (sec && strchr(def->config, ',')) {
                free(sec);
                return ftm_error_set(err, FTM_EINVAL,
                                     "Cyclone DDS configuration %s: a path with a comma cannot be "
                                     "combined with DDS Security (Cyclone splits at commas)",
                                     def->config);
            }
        }
    } else if (sec) {
        c = getenv("CYCLONEDDS_URI"); /* what the implicit domain would have used */
        if (c && !*c)
            c = NULL;
    }
    if (!c && !sec)
        return FTM_OK; /* implicit domain: $CYCLONEDDS_URI or defaults */
    /* "file://PATH" or the XML text, then ",FRAGMENT": Cyclone reads a
     * comma-separated list of configurations, later ones adding to earlier */
    const bool file = c && *c != '<' && def->config;
    size_t n = (c ? strlen(c) + 8 : 0) + (sec ? strlen(sec) + 1 : 0) + 1;
    uri = malloc(n);
    if (!uri) {
        free(sec);
        return ftm_error_set(err, FTM_ENOMEM, "out of memory");
    }
    snprintf(uri, n, "%s%s%s%s", file ? "file://" : "", c ? c : "", c && sec ? "," : "",
             sec ? sec : "");
    free(sec);
    dds_entity_t dom = dds_create_domain(def->domain_id, uri);
    free(uri);
    if (dom == DDS_RETCODE_PRECONDITION_NOT_MET)
        return FTM_OK; /* this process already has the domain: share it */
    if (dom < 0) {
        const char *cfg = !def->config ? "$CYCLONEDDS_URI" : *c == '<' ? "(XML text)" : def->config;
        return ftm_error_set(err, FTM_EINVAL,
                             "Cyclone DDS rejected the configuration %s%s for domain %u: %s", cfg,
                             def->security ? " with DDS Security" : "", def->domain_id,
                             dds_strretcode(dom));
    }
    *created = dom;
    return FTM_OK;
}

static int64_t real_now_ns(void)
{
    struct timespec ts;
    clock_gettime(CLOCK_REALTIME, &ts);
    return (int64_t)ts.tv_sec * 1000000000 + ts.tv_nsec;
}

/* A process's origin: its DDS participant's GUID, which every process sees
 * alike, folded to 64 bits (FNV-1a, then a final mix); never 0. */
static uint64_t origin_of_guid(const dds_guid_t *g)
{
    uint64_t h = 0xcbf29ce484222325u;
    for (size_t i = 0; i < sizeof g->v; i++)
        h = (h ^ g->v[i]) * 0x100000001b3u;
    h ^= h >> 33;
    h *= 0xff51afd7ed558ccdu;
    h ^= h >> 33;
    return h ? h : 1;
}

/* The origin (origin_of_guid) of the writer of a sample: one process has a
 * writer per kind, so this is what tells two processes that give one
 * sender id apart; and the role and id its partition certifies (DDS
 * Security: the permissions grant each identity its own partition only).
 * Origin 0 if the writer is no longer matched (a sample that reports it
 * gone). Cached: asked once per writer. */
static struct writer_info writer_of(kind_io *io, dds_entity_t reader, dds_instance_handle_t writer)
{
    struct writer_info w = {writer, 0, 0, 0};
    for (int i = 0; i < ORIGIN_CACHE; i++)
        if (io->origins[i].writer == writer && writer != 0)
            return io->origins[i];
    dds_builtintopic_endpoint_t *ep = dds_get_matched_publication_data(reader, writer);
    if (!ep)
        return w;
    w.origin = origin_of_guid(&ep->participant_key);
    uint32_t n = 0;
    char **ps = NULL;
    if (ep->qos && dds_qget_partition(ep->qos, &n, &ps)) {
        /* one partition, which names the identity; anything else certifies none */
        if (n != 1 || !wire_partition_identity(ps[0], &w.cert_role, &w.cert_id))
            w.cert_id = 0;
        for (uint32_t i = 0; i < n; i++)
            dds_free(ps[i]);
        dds_free(ps);
    }
    dds_builtintopic_free_endpoint(ep);
    io->origins[io->next_origin] = w;
    io->next_origin = (io->next_origin + 1) % ORIGIN_CACHE;
    return w;
}

/* Cyclone's receive thread: take what arrived, queue it with its arrival
 * time. Only copies; no decoding and no logging here. */
static void on_data_available(dds_entity_t reader, void *arg)
{
    kind_io *io = arg;
    const ftm_wire_transport *t = io->owner;
    for (;;) {
        void *samples[16] = {NULL};
        dds_sample_info_t info[16];
        dds_return_t n = dds_take(reader, samples, info, 16, 16);
        if (n <= 0)
            return;
        int64_t arrival = real_now_ns();
        for (int32_t i = 0; i < n; i++) {
            const ftm_wire_Envelope *env = samples[i];
            if (!t->any_session && strncmp(env->session, t->session, sizeof env->session) != 0)
                continue; /* another session on the same domain */
            size_t size = info[i].valid_data ? env->payload._length : 0, over = 0;
            /* over the cap: rejected by the reader's thread, never copied */
            if (size > wire_payload_cap(&t->limits, io->kind)) {
                over = size;
                size = 0;
            }
            const struct writer_info w = writer_of(io, reader, info[i].publication_handle);
            rx_item *it = malloc(sizeof *it + size);
            if (!it) {
                pthread_mutex_lock(&io->rx_lock);
                io->rx_dropped++;
                pthread_mutex_unlock(&io->rx_lock);
                continue;
            }
            *it = (rx_item){.arrival_ns = arrival,
                            .source_time_ns = info[i].source_timestamp,
                            .valid = info[i].valid_data,
                            .alive = info[i].instance_state == DDS_IST_ALIVE,
                            .sender = env->sender,
                            .origin = w.origin,
                            .cert_id = w.cert_id,
                            .cert_role = (uint8_t)w.cert_role,
                            .kind = env->kind,
                            .seq = env->seq,
                            .size = size,
                            .oversize = over};
            if (t->any_session)
                snprintf(it->session, sizeof it->session, "%.63s", env->session);
            if (size)
                memcpy(it->data, env->payload._buffer, size);
            pthread_mutex_lock(&io->rx_lock);
            while (io->rx_head &&
                   (io->rx_count >= RX_QUEUE_MAX || io->rx_bytes + size > RX_QUEUE_BYTES)) {
                rx_item *old = io->rx_head; /* nobody reads: keep the newest */
                io->rx_head = old->next;
                if (!io->rx_head)
                    io->rx_tail = NULL;
                io->rx_count--;
                io->rx_bytes -= old->size;
                io->rx_dropped++;
                free(old);
            }
            if (io->rx_tail)
                io->rx_tail->next = it;
            else
                io->rx_head = it;
            io->rx_tail = it;
            io->rx_count++;
            io->rx_bytes += size;
            pthread_cond_signal(&io->rx_cond);
            pthread_mutex_unlock(&io->rx_lock);
        }
        dds_return_loan(reader, samples, n);
    }
}

/* A failed topic, writer or reader: a clear cause when DDS Security's
 * permissions do not grant it. */
static int endpoint_fail(const ftm_wire_transport *t, ftm_error *err, const char *call, int kind,
                         bool write, dds_return_t rc)
{
    if (rc == DDS_RETCODE_NOT_ALLOWED_BY_SECURITY)
        return ftm_error_set(
            err, FTM_EACCESS,
            "not permitted by the DDS Security permissions in %s to %s topic %s (%s) "
            "in partition %s: this program needs an identity issued for its role "
            "and id",
            t->sec.permissions[0] ? t->sec.permissions : "(the configuration)",
            write ? "write" : "read", ftm_wire_topic_name(kind), ftm_wire_kind_name(kind),
            write ? t->sec.partition : FTM_WIRE_PARTITION_PREFIX "*");
    return ftm_error_set(err, FTM_EDDS, "%s for %s failed: %s", call, ftm_wire_topic_name(kind),
                         dds_strretcode(rc));
}

/* Secured: a publisher in our own partition (the identity the permissions
 * grant us) and a subscriber of every FTM partition. */
static int make_partitions(ftm_wire_transport *t, ftm_error *err)
{
    dds_qos_t *q = dds_create_qos();
    dds_qset_partition1(q, t->sec.partition);
    t->publisher = dds_create_publisher(t->participant, q, NULL);
    dds_qset_partition1(q, FTM_WIRE_PARTITION_PREFIX "*");
    t->subscriber = t->publisher < 0 ? 0 : dds_create_subscriber(t->participant, q, NULL);
    dds_delete_qos(q);
    if (t->publisher < 0 || t->subscriber < 0) {
        const dds_return_t r = t->publisher < 0 ? t->publisher : t->subscriber;
        t->publisher = t->subscriber = 0;
        if (r == DDS_RETCODE_NOT_ALLOWED_BY_SECURITY)
            return ftm_error_set(
                err, FTM_EACCESS,
                "not permitted by the DDS Security permissions in %s to use partition "
                "%s (an identity of another role or id)",
                t->sec.permissions, t->sec.partition);
        return dds_fail(err, "dds_create_publisher/subscriber", r);
    }
    return FTM_OK;
}

static int make_endpoints(ftm_wire_transport *t, int k, bool pub, bool sub, ftm_error *err)
{
    kind_io *io = &t->io[k];
    io->topic = dds_create_topic(t->participant, &ftm_wire_Envelope_desc, ftm_wire_topic_name(k),
                                 NULL, NULL);
    if (io->topic < 0)
        return endpoint_fail(t, err, "dds_create_topic", k, pub, io->topic);
    if (pub) {
        dds_qos_t *q = kind_qos(k, true);
        io->writer = dds_create_writer(t->publisher ? t->publisher : t->participant, io->topic, q,
                                       NULL);
        dds_delete_qos(q);
        if (io->writer < 0) {
            int rc = endpoint_fail(t, err, "dds_create_writer", k, true, io->writer);
            io->writer = 0;
            return rc;
        }
        io->wstats = dds_create_statistics(io->writer); /* NULL is fine */
    }
    if (sub) {
        dds_qos_t *q = kind_qos(k, false);
        dds_listener_t *l = dds_create_listener(io);
        if (!l) {
            dds_delete_qos(q);
            return ftm_error_set(err, FTM_ENOMEM, "transport: out of memory for a listener");
        }
        dds_lset_data_available(l, on_data_available);
        io->reader = dds_create_reader(t->subscriber ? t->subscriber : t->participant, io->topic, q,
                                       l);
        dds_delete_listener(l);
        dds_delete_qos(q);
        if (io->reader < 0) {
            int rc = endpoint_fail(t, err, "dds_create_reader", k, false, io->reader);
            io->reader = 0;
            return rc;
        }
    }
    return FTM_OK;
}

static void delete_participant(ftm_wire_transport *t)
{
    for (int k = 0; k < KINDS; k++) {
        if (t->io[k].wstats)
            dds_delete_statistics(t->io[k].wstats);
        t->io[k].wstats = NULL;
    }
    if (t->participant > 0) {
        dds_entity_t dom = dds_get_parent(t->participant);
        dds_delete(t->participant);
        /* The last transport of a domain this library created deletes it. */
        if (dom > 0 && dds_get_children(dom, NULL, 0) == 0)
            dds_delete(dom);
    }
    t->participant = 0;
}

int ftm_wire_transport_create(const ftm_wire_transport_def *def, ftm_wire_transport **out,
                              ftm_error *err)
{
    if (!def || !out)
        return ftm_error_set(err, FTM_EINVAL, "ftm_wire_transport_create: NULL argument");
    if (!def->session || !def->session[0] || strlen(def->session) > 63)
        return ftm_error_set(err, FTM_EINVAL, "transport: session name must have 1..63 bytes");
    if (def->participant_id == 0)
        return ftm_error_set(err, FTM_EINVAL, "transport: participant_id must not be 0");
    if (def->any_session && def->publish)
        return ftm_error_set(err, FTM_EINVAL,
                             "transport: a transport of every session (any_session) publishes "
                             "nothing");
    if ((def->publish | def->subscribe) & ~(uint32_t)FTM_WIRE_ALL_KINDS)
        return ftm_error_set(err, FTM_EINVAL,
                             "transport: publish/subscribe masks name unknown kinds");
    if (def->publisher_priority < 0 || def->publisher_priority > 99)
        return ftm_error_set(err, FTM_EINVAL, "transport: publisher_priority %d out of range 0..99",
                             (int)def->publisher_priority);
    if (def->queue_capacity < 0)
        return ftm_error_set(err, FTM_EINVAL, "transport: negative queue_capacity");

    ftm_wire_transport *t = calloc(1, sizeof *t);
    if (!t)
        return ftm_error_set(err, FTM_ENOMEM, "transport: out of memory");
    snprintf(t->session, sizeof t->session, "%s", def->session);
    t->any_session = def->any_session;
    t->id = def->participant_id;
    t->limits = def->limits;
    t->log = def->log;
    t->log_user = def->log_user;
    t->capacity = def->queue_capacity ? def->queue_capacity : 4096;

    pthread_condattr_t ca;
    pthread_condattr_init(&ca);
    pthread_condattr_setclock(&ca, CLOCK_MONOTONIC);
    pthread_mutex_init(&t->lock, NULL);
    pthread_cond_init(&t->wake, NULL);
    pthread_cond_init(&t->drained, &ca);
    for (int k = 0; k < KINDS; k++) {
        pthread_mutex_init(&t->io[k].rx_lock, NULL);
        pthread_cond_init(&t->io[k].rx_cond, &ca);
        t->io[k].owner = t;
        t->io[k].kind = k;
    }
    pthread_condattr_destroy(&ca);

    dds_entity_t created = 0;
    int rc = make_domain(def, t, &created, err);
    if (rc == FTM_OK) {
        t->participant = dds_create_participant(def->domain_id, NULL, NULL);
        if (t->participant < 0) {
            if (def->security)
                rc = ftm_error_set(
                    err, FTM_EACCESS,
                    "DDS Security refused the identity in %s (dds_create_participant: "
                    "%s); Cyclone DDS gives the reason on standard error or in its "
                    "trace (<Tracing><Verbosity>warning</Verbosity>)",
                    def->security, dds_strretcode(t->participant));
            else
                rc = dds_fail(err, "dds_create_participant", t->participant);
            t->participant = 0;
            if (created > 0)
                dds_delete(created);
        } else {
            dds_guid_t g;
            dds_return_t r = dds_get_guid(t->participant, &g);
            if (r < 0)
                rc = dds_fail(err, "dds_get_guid", r);
            else
                t->origin = origin_of_guid(&g);
        }
    }
    if (rc == FTM_OK && def->security)
        rc = make_partitions(t, err);
    for (int k = FTM_WIRE_KIND_MIN; rc == FTM_OK && k <= FTM_WIRE_KIND_MAX; k++) {
        bool pub = def->publish & FTM_WIRE_KIND_BIT(k), sub = def->subscribe & FTM_WIRE_KIND_BIT(k);
        if (pub || sub)
            rc = make_endpoints(t, k, pub, sub, err);
    }
    /* after the endpoints: an identity whose grants fall short is named by
     * the permission refused; one of a wider role is refused here */
    if (rc == FTM_OK && def->security && def->role && def->role != t->sec.role)
        rc = ftm_error_set(
            err, FTM_EACCESS,
            "DDS Security: the identity in %s was issued for role %s, and this program "
            "runs as %s: the others would reject its statuses; use an identity issued "
            "for %s",
            def->security, ftm_wire_role_name(t->sec.role), ftm_wire_role_name(def->role),
            ftm_wire_role_name(def->role));
    if (rc == FTM_OK) {
        if (pthread_create(&t->thread, NULL, publisher_main, t) != 0) {
            rc = ftm_error_set(err, FTM_ENOMEM, "transport: cannot start the publishing thread");
        } else {
            t->thread_started = true;
            if (def->publisher_priority > 0) {
                struct sched_param sp = {.sched_priority = def->publisher_priority};
                int e = pthread_setschedparam(t->thread, SCHED_FIFO, &sp);
                if (e)
                    wire_log(t, FTM_LOG_INFO,
                             "wire: publishing thread at default scheduling (SCHED_FIFO %d: %s)",
                             (int)def->publisher_priority, strerror(e));
            }
        }
    }
    if (rc != FTM_OK) {
        ftm_wire_transport_destroy(t);
        return rc;
    }
    *out = t;
    return FTM_OK;
}

void ftm_wire_transport_destroy(ftm_wire_transport *t)
{
    if (!t)
        return;
    if (t->thread_started) {
        if (!wait_drained(t, now_ns() + DESTROY_DRAIN_NS))
            wire_log(t, FTM_LOG_WARN, "wire: destroying with %d messages still queued", t->queued);
        pthread_mutex_lock(&t->lock);
        t->stop = true;
        pthread_cond_broadcast(&t->wake);
        pthread_mutex_unlock(&t->lock);
        pthread_join(t->thread, NULL);
    }
    delete_participant(t); /* waits for listeners in progress */
    while (t->head) {
        queue_item *it = t->head;
        t->head = it->next;
        free(it);
    }
    for (int k = 0; k < KINDS; k++) {
        kind_io *io = &t->io[k];
        while (io->rx_head) {
            rx_item *it = io->rx_head;
            io->rx_head = it->next;
            free(it);
        }
        free(io->senders);
        pthread_cond_destroy(&io->rx_cond);
        pthread_mutex_destroy(&io->rx_lock);
    }
    pthread_cond_destroy(&t->wake);
    pthread_cond_destroy(&t->drained);
    pthread_mutex_destroy(&t->lock);
    free(t);
}

/* ---- matching --------------------------------------------------------------- */

static int32_t matched_count(kind_io *io)
{
    if (io->writer) {
        dds_publication_matched_status_t st;
        if (dds_get_publication_matched_status(io->writer, &st) == DDS_RETCODE_OK)
            return (int32_t)st.current_count;
    } else if (io->reader) {
        dds_subscription_matched_status_t st;
        if (dds_get_subscription_matched_status(io->reader, &st) == DDS_RETCODE_OK)
            return (int32_t)st.current_count;
    }
    return 0;
}

int ftm_wire_wait_matched(ftm_wire_transport *t, int kind, int32_t count, int64_t timeout_ns,
                          ftm_error *err)
{
    if (!t || !valid_kind(kind) || (!t->io[kind].writer && !t->io[kind].reader))
        return ftm_error_set(err, FTM_EINVAL,
                             "wait_matched: this transport neither writes nor reads %s",
                             ftm_wire_kind_name(kind));
    int64_t deadline = now_ns() + timeout_ns;
    for (;;) {
        int32_t n = matched_count(&t->io[kind]);
        if (n >= count)
            return FTM_OK;
        if (now_ns() >= deadline)
            return ftm_error_set(err, FTM_ETIMEDOUT, "%s: %d of %d peers matched after %.3f s",
                                 ftm_wire_kind_name(kind), n, count, (double)timeout_ns * 1e-9);
        sleep_ns(5000000);
    }
}

uint64_t ftm_wire_transport_origin(const ftm_wire_transport *t) { return t->origin; }

int ftm_wire_pin_publisher(ftm_wire_transport *t, int cpu, ftm_error *err)
{
    if (!t || !t->thread_started || cpu < 0 || cpu >= CPU_SETSIZE)
        return ftm_error_set(err, FTM_EINVAL, "ftm_wire_pin_publisher: bad transport or cpu %d",
                             cpu);
    cpu_set_t set;
    CPU_ZERO(&set);
    CPU_SET(cpu, &set);
    int e = pthread_setaffinity_np(t->thread, sizeof set, &set);
    if (e)
        return ftm_error_set(err, FTM_EINVAL, "publishing thread on cpu %d: %s", cpu, strerror(e));
    return FTM_OK;
}

/* ---- receive ----------------------------------------------------------------- */

/* The gap before seq from sender; updates the baseline. */
static uint64_t track(kind_io *io, uint32_t sender, uint64_t origin, uint64_t seq)
{
    for (int i = 0; i < io->nsenders; i++) {
        if (io->senders[i].sender == sender && io->senders[i].origin == origin) {
            uint64_t last = io->senders[i].last;
            io->senders[i].last = seq;
            return seq > last ? seq - last - 1 : 0; /* seq <= last: sender restarted */
        }
    }
    if (io->nsenders == io->capsenders) {
        int cap = io->capsenders ? 2 * io->capsenders : 8;
        if (cap > SENDERS_MAX) {
            io->nsenders = 0; /* forget everyone rather than grow without bound */
        } else {
            sender_seq *s = realloc(io->senders, (size_t)cap * sizeof *s);
            if (!s)
                return 0;
            io->senders = s;
            io->capsenders = cap;
        }
    }
    io->senders[io->nsenders++] = (sender_seq){sender, origin, seq};
    return 0;
}

static void reject(ftm_wire_transport *t, int kind, const char *fmt, ...)
    __attribute__((format(printf, 3, 4)));
static void reject(ftm_wire_transport *t, int kind, const char *fmt, ...)
{
    char buf[FTM_ERROR_MESSAGE_MAX];
    va_list ap;
    va_start(ap, fmt);
    vsnprintf(buf, sizeof buf, fmt, ap);
    va_end(ap);
    pthread_mutex_lock(&t->lock);
    t->io[kind].stats.rejected++;
    snprintf(t->io[kind].stats.last_reject, sizeof t->io[kind].stats.last_reject, "%s", buf);
    pthread_mutex_unlock(&t->lock);
    wire_log(t, FTM_LOG_WARN, "wire: rejected %s", buf);
}

/* Secured: the sender id, and the id and role a message names, must be
 * those its writer's partition certifies. NULL if so, else why not. */
static const char *uncertified(const rx_item *it, int kind, const ftm_wire_msg *msg, char *why,
                               size_t cap)
{
    const ftm_wire_role role = (ftm_wire_role)it->cert_role;
    uint32_t named = it->sender;
    bool role_ok = true;
    if (msg) {
        switch (kind) {
        case FTM_WIRE_STATUS:
            named = msg->u.status.participant;
            role_ok = msg->u.status.role == role;
            break;
        case FTM_WIRE_PROBE_INPUT: named = msg->u.probe_input.participant; break;
        case FTM_WIRE_CONTROL: named = msg->u.control.issuer; break;
        default: role_ok = role == FTM_WIRE_ROLE_SERVER; /* only a server writes the others */
        }
    }
    if (!it->cert_id)
        snprintf(why, cap, "its writer has no certified identity (partition)");
    else if (it->sender != it->cert_id || named != it->cert_id)
        snprintf(why, cap, "its writer is certified as %s %u, not participant %u",
                 ftm_wire_role_name(role), it->cert_id, named != it->cert_id ? named : it->sender);
    else if (!role_ok)
        snprintf(why, cap, "its writer is certified as %s %u, not as role %s", ftm_wire_role_name(role),
                 it->cert_id,
                 kind == FTM_WIRE_STATUS ? ftm_wire_role_name(msg->u.status.role) : "server");
    else
        return NULL;
    return why;
}

/* Handles one queued sample: 1 if *out now holds a message, 0 if skipped. */
static int handle_sample(ftm_wire_transport *t, int kind, const rx_item *it, ftm_wire_received *out)
{
    kind_io *io = &t->io[kind];
    const bool secured = t->sec.partition[0] != 0;
    char why[160];
    if (!it->valid) {
        /* a gone status: checked while its writer is known (one that
         * disposes another's instance); a lost writer's is Cyclone's own */
        if (secured && it->origin && uncertified(it, kind, NULL, why, sizeof why)) {
            reject(t, kind, "%s gone from participant %u: %s", ftm_wire_kind_name(kind),
                   it->sender, why);
            return 0;
        }
        if (kind == FTM_WIRE_STATUS && !it->alive) {
            memset(out, 0, sizeof *out);
            out->msg.kind = FTM_WIRE_STATUS;
            out->sender = it->sender;
            out->origin = it->origin;
            memcpy(out->session, it->session, sizeof out->session);
            out->gone = true;
            out->source_time_ns = it->source_time_ns;
            out->arrival_ns = it->arrival_ns;
            return 1;
        }
        return 0;
    }
    const char *what = ftm_wire_kind_name(kind);
    if (it->kind != kind) {
        reject(t, kind, "%s topic: message from participant %u seq %llu says it is a %s (kind %u)",
               what, it->sender, (unsigned long long)it->seq, ftm_wire_kind_name(it->kind),
               it->kind);
        return 0;
    }
    if (it->oversize) {
        const size_t cap = wire_payload_cap(&t->limits, kind);
        reject(t, kind, "message from participant %u seq %llu: %s: payload of %zu bytes exceeds "
               "the %zu-byte cap (%s)",
               it->sender, (unsigned long long)it->seq, what, it->oversize, cap,
               ftm_err_name(FTM_ETOOBIG));
        return 0;
    }
    ftm_error e = {0, ""};
    ftm_wire_msg msg;
    int rc = ftm_wire_decode(kind, it->data, it->size, &t->limits, &msg, &e);
    if (rc) {
        /* the code's name ties the line to the classes of docs/protocol.md */
        reject(t, kind, "message from participant %u seq %llu: %s (%s)", it->sender,
               (unsigned long long)it->seq, e.message, ftm_err_name(rc));
        return 0;
    }
    if (secured && uncertified(it, kind, &msg, why, sizeof why)) {
        reject(t, kind, "%s from participant %u seq %llu: %s", what, it->sender,
               (unsigned long long)it->seq, why);
        ftm_wire_msg_free(&msg);
        return 0;
    }
    memset(out, 0, sizeof *out);
    out->msg = msg;
    out->sender = it->sender;
    out->origin = it->origin;
    memcpy(out->session, it->session, sizeof out->session);
    out->seq = it->seq;
    out->source_time_ns = it->source_time_ns;
    out->arrival_ns = it->arrival_ns;
    out->payload_size = it->size;
    out->gap = track(io, it->sender, it->origin, it->seq);
    pthread_mutex_lock(&t->lock);
    io->stats.received++;
    io->stats.missing += out->gap;
    pthread_mutex_unlock(&t->lock);
    if (out->gap)
        wire_log(t, FTM_LOG_INFO, "wire: %s from participant %u: %llu missing before seq %llu", what,
                 it->sender, (unsigned long long)out->gap, (unsigned long long)it->seq);
    return 1;
}

/* The next queued sample of a kind, waiting until deadline (monotonic). */
static rx_item *next_item(kind_io *io, int64_t deadline, uint64_t *dropped)
{
    pthread_mutex_lock(&io->rx_lock);
    /* rx_cond runs on CLOCK_MONOTONIC, the deadline's clock */
    const struct timespec until = {(time_t)(deadline / 1000000000), (long)(deadline % 1000000000)};
    while (!io->rx_head && now_ns() < deadline)
        pthread_cond_timedwait(&io->rx_cond, &io->rx_lock, &until);
    rx_item *it = io->rx_head;
    if (it) {
        io->rx_head = it->next;
        if (!io->rx_head)
            io->rx_tail = NULL;
        io->rx_count--;
        io->rx_bytes -= it->size;
    }
    *dropped = io->rx_dropped - io->rx_dropped_seen;
    io->rx_dropped_seen = io->rx_dropped;
    pthread_mutex_unlock(&io->rx_lock);
    return it;
}

int ftm_wire_receive(ftm_wire_transport *t, int kind, ftm_wire_received *out, int64_t timeout_ns,
                     ftm_error *err)
{
    if (!t || !out)
        return ftm_error_set(err, FTM_EINVAL, "ftm_wire_receive: NULL argument");
    memset(out, 0, sizeof *out);
    if (!valid_kind(kind) || !t->io[kind].reader)
        return ftm_error_set(err, FTM_EINVAL, "ftm_wire_receive: this transport does not read %s",
                             ftm_wire_kind_name(kind));
    kind_io *io = &t->io[kind];
    int64_t deadline = now_ns() + (timeout_ns > 0 ? timeout_ns : 0);
    for (;;) {
        uint64_t dropped = 0;
        rx_item *it = next_item(io, deadline, &dropped);
        if (dropped)
            wire_log(t, FTM_LOG_WARN,
                     "wire: %llu %s message(s) dropped unread (more than %d or %u MiB waiting, "
                     "or out of memory)",
                     (unsigned long long)dropped, ftm_wire_kind_name(kind), RX_QUEUE_MAX,
                     RX_QUEUE_BYTES >> 20);
        if (!it)
            return ftm_error_set(err, FTM_ETIMEDOUT, "%s: nothing received in %.3f s",
                                 ftm_wire_kind_name(kind), (double)timeout_ns * 1e-9);
        int got = handle_sample(t, kind, it, out);
        free(it);
        if (got)
            return FTM_OK;
        /* skipped one: look at the next without waiting past the deadline */
    }
}

void ftm_wire_received_free(ftm_wire_received *r)
{
    if (r)
        ftm_wire_msg_free(&r->msg);
}

/* ---- statistics -------------------------------------------------------------- */

static uint64_t stat_value(const struct dds_statistics *s, const char *name)
{
    const struct dds_stat_keyvalue *kv = dds_lookup_statistic(s, name);
    if (!kv)
        return 0;
    switch (kv->kind) {
    case DDS_STAT_KIND_UINT32: return kv->u.u32;
    case DDS_STAT_KIND_UINT64: return kv->u.u64;
    default: return kv->u.lengthtime;
    }
}

int ftm_wire_get_stats(ftm_wire_transport *t, int kind, ftm_wire_stats *stats, ftm_error *err)
{
    if (!t || !stats || !valid_kind(kind))
        return ftm_error_set(err, FTM_EINVAL, "ftm_wire_get_stats: bad argument");
    kind_io *io = &t->io[kind];
    pthread_mutex_lock(&t->lock);
    *stats = io->stats;
    pthread_mutex_unlock(&t->lock);
    if (io->wstats && dds_refresh_statistics(io->wstats) == DDS_RETCODE_OK) {
        stats->rexmit_bytes = stat_value(io->wstats, "rexmit_bytes");
        stats->throttle_count = stat_value(io->wstats, "throttle_count");
    }
    if (io->reader && kind == FTM_WIRE_STATUS) {
        dds_requested_deadline_missed_status_t st;
        if (dds_get_requested_deadline_missed_status(io->reader, &st) == DDS_RETCODE_OK)
            stats->deadline_missed = st.total_count;
    }
    stats->matched = matched_count(io);
    return FTM_OK;
}
