/* ftm-server: the authoritative session server (docs/server.md).
 *
 * One libuv loop, one thread for everything but DDS writes (ftm_wire's
 * publishing thread does those): a 1 ms timer runs the ticks that are due by
 * the monotonic clock, after draining received status, probe input and
 * session control without waiting. Each tick: probe HIPs -> contacts (point
 * collision with the deformed surface, collide.h) -> ftm_replay_step (the
 * same call sequence every replica makes) -> tick frame, unless the scene is
 * idle (then a heartbeat frame every 100 ms). */
#define _GNU_SOURCE /* sched_getcpu, pthread_setaffinity_np */
#include "collide.h"
#include "depth_ctl.h"
#include "metrics.h"
#include "record.h"
#include "record_replay.h"
#include "cli.h"
#include "digest.h"
#include "keyframe.h"
#include "report.h"
#include "script.h"
#include "step.h"
#include "tissue.h"
#include "server.h"

#include "ftm/scene.h"
#include "ftm/wire.h"

#include <arpa/inet.h>
#include <errno.h>
#include <fcntl.h>
#include <sys/stat.h>
#include <pthread.h>
#include <sched.h>
#include <signal.h>
#include <inttypes.h>
#include <math.h>
#include <stdarg.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <time.h>
#include <unistd.h>
#include <uv.h>

#define MAX_PARTICIPANTS 64
_Static_assert(MAX_PARTICIPANTS <= FTM_WIRE_HOLDERS_MAX, "every holder fits the server's status");
#define MAX_PROBES 4 /* per trainee; group = slot * MAX_PROBES + probe */
_Static_assert(MAX_PROBES <= FTM_REPORT_PROBES, "the session report counts every probe");
#define MAX_CATCHUP 50 /* ticks run in one timer callback before we call them missed */
/* (a larger time would wrap when cast: a keyframe every tick, a session
 * that stops at once) */
#define MAX_SECONDS FTM_OPTION_SECONDS_MAX
#define MAX_DOMAIN FTM_OPTION_DOMAIN_MAX
#define RT_CPU_START (-1) /* --rt-cpu start: the CPU the server started on */
#define RT_CPU_ANY (-2)   /* --rt-cpu any: not pinned */

typedef struct options {
    const char *scene;
    const char *session;
    const char *config;
    const char *security; /* DDS Security bundle directory (--security) */
    const char *log_path;
    uint32_t domain;
    uint32_t id;
    double rate;
    double keyframe_every;
    double heartbeat;
    double duration;
    int32_t depth; /* -1: the scene's */
    /* --offline N: N ticks without DDS, trainees played from scripts on
     * the tick clock (run_offline) */
    int64_t offline_ticks;
    const char *trainees[8]; /* "ID:OFFSET:SCRIPT" */
    int ntrainees;
    const char *reactions_csv;
    /* adaptive depth, recording, metrics (docs/server.md) */
    int32_t depth_floor;   /* -1: a quarter of the depth, at least 1 */
    int32_t adaptive;      /* 1: adapt the depth to the load; 0 (default): fixed */
    double depth_hold_up;  /* calm time before the depth goes up one step [s] */
    const char *record;    /* --record FILE */
    const char *replay;    /* --replay FILE: replay a recording and exit */
    bool scene_given;      /* --scene was on the command line */
    bool session_given;    /* --session was */
    int32_t metrics_port;  /* 0: off */
    const char *control_log; /* --control-log FILE: CSV per control period */
    int32_t rt_priority;   /* SCHED_FIFO priority of the tick and publishing threads; 0: off */
    int32_t rt_cpu;        /* --rt-cpu: the CPU both run on; RT_CPU_START, RT_CPU_ANY */
    double max_penetration; /* --max-penetration M [m]; 0: not given, the scene's size */
    const char *inputs;     /* --inputs FILE: re-run a recording's inputs (frames ignored) */
    const char *metrics_addr; /* --metrics-addr: the address the metrics listen on */
    const char *record_dir; /* --record-dir DIR: a new recording per run, named by session and time */
    bool check;             /* --check: set everything up, report, exit */
    const char *report;     /* --report FILE: the session report (report.h) as JSON */
} options;

typedef struct probe {
    bool have, have_prev, contact;
    ftm_vec3 hip, prev;
    int32_t tri;
    ftm_vec3 anchor; /* crossing point in rest coordinates */
    ftm_vec3 normal; /* the triangle's rest normal, pointing to where the HIP came from */
    ftm_vec3 push;   /* imposed on the triangle: HIP - anchor, at most the push limit long */
    bool limited;    /* push is HIP - anchor shortened to the limit */
    bool limit_told; /* the log said so during this contact */
} probe;

typedef struct participant {
    bool used, gone;
    uint32_t id;
    ftm_wire_role role;
    ftm_wire_state state;
    char name[FTM_WIRE_DISPLAY_MAX];
    uint64_t last_tick, inputs, rejected;
    uint64_t last_status_ns; /* monotonic time of the last status received */
    bool silent;             /* no status for longer than the deadline */
    uint64_t hash;
    int64_t lag;      /* ticks behind the last published frame, at its last status */
    double replay_ns; /* its replay time per tick, as reported */
    int32_t report;   /* its entry in the session report, -1: none */
    /* the DDS participant of its first status: the id is that process's
     * until it is gone; another process giving the same id is not heard */
    uint64_t origin;
    uint64_t impostor_msgs; /* messages dropped from such a process */
    probe probes[MAX_PROBES];
} participant;

typedef struct server {
    options o;
    FILE *logf;
    uint64_t t_start_ns;
    ftm_scene *scene;
    const ftm_mesh *mesh;
    ftm_sim *sim;
    ftm_replay_material mat; /* tissue parameters in force (instructor) */
    bool tissue_frame;       /* the next frame carries them: they changed */
    ftm_collide *collide;
    ftm_wire_transport *wire;
    uint8_t digest[FTM_REPLAY_DIGEST_SIZE];
    int32_t depth;
    bool paused;
    double max_push;       /* longest push a probe imposes [m]; INFINITY: none */
    uint64_t push_limited; /* probe-ticks whose push was shortened to max_push */
    uint64_t start_unix_ns;    /* wall clock at start: announced, so replicas tell a restart */
    uint64_t rejected_unknown; /* messages from senders with no status yet (log rate) */
    uint64_t own_id_msgs;      /* messages from another process using the server's id */
    /* Participants gone in the last 2 s: their probe input still in flight
     * when their LEAVING status and departure were taken is no stranger's */
    struct {
        uint32_t id;
        uint64_t tick; /* the server's tick when it went (ticks, so that
                        * --inputs decides alike); 0: a free slot */
    } left[8];
    int left_next;
    /* Processes heard with an id another process holds (admit): listed in
     * the server's status while heard, so that each learns it is ignored. */
    struct {
        uint32_t id;
        uint64_t origin;
        uint64_t last_ns; /* monotonic; 0: a free slot */
    } ignored[FTM_WIRE_IGNORED_MAX];
    uint64_t told_ns; /* the last status published at once (tell_now) */
    bool displaced;            /* stopped: another server was serving this session first */
    bool rec_failed;           /* the recording stopped on a write error */
    bool other_server_told;    /* a later server on this session was logged */
    char record_path[1024];    /* --record-dir: this run's recording */
    char scene_path[1024];     /* the file the scene came from (its name for a built-in) */
    ftm_report report;         /* what each participant did (--report, the closing log) */
    int32_t depth_lo, depth_hi; /* depths used by the ticks run */

    uv_loop_t *loop;
    uv_timer_t tick_timer, status_timer, stop_timer;
    uv_signal_t sigint, sigterm;
    bool stopping;

    uint64_t base_ns;    /* wall time of tick `base_tick` */
    uint64_t base_tick;
    uint64_t loop_start_ns, stop_ns;
    uint64_t tick;       /* ticks run (= sim step counter) */
    double period_ns;

    participant parts[MAX_PARTICIPANTS];

    ftm_contact *contacts;
    ftm_wire_reaction *reactions;
    int32_t contact_cap;

    /* what replicas hold: the last published frame's contacts and depth */
    int32_t pub_n, pub_depth;
    uint64_t pub_tick, pub_ns;
    bool published_any;

    bool keyframe_due;
    uint64_t next_keyframe_ns;

    /* statistics */
    uint64_t frames, heartbeats, idle_ticks, keyframes, bytes_frames, bytes_keyframes;
    uint64_t missed_ticks, unstable, publish_fail, tissue_changes;
    double step_ns_total, step_ns_max;
    /* tick period (start to start) and lateness (start - due), 10 us bins */
#define TICK_HIST_BINS 5000
    uint32_t period_hist[TICK_HIST_BINS], late_hist[TICK_HIST_BINS];
    uint64_t last_tick_ns;
    FILE *reactions_csv; /* --reactions (offline, replay): one line per probe reaction */
    /* adaptive depth (depth_ctl.h), metrics, recording: control_period() */
    ftm_depth_ctl ctl;
    uint64_t next_control_ns, floor_log_ns;
    uint64_t prev_tick, prev_missed, prev_rexmit, prev_throttle, prev_sent;
    double prev_step_sum;
    uint64_t rate_tick[10], rate_ns[10]; /* the last second, per control period */
    int rate_i;
    uint64_t step_bucket[FTM_METRICS_STEP_BUCKETS + 1], step_count;
    double step_sum_ns, step_recent_ns;
    ftm_record_writer *rec;
    ftm_metrics *metrics;
    ftm_metrics_snapshot msnap; /* built here, copied to the HTTP thread */
    /* published frames (time, tick), newest last: what a participant can
     * have applied by now (lag_of) */
#define PUB_RING 1024
    uint64_t pub_ring_ns[PUB_RING], pub_ring_tick[PUB_RING];
    uint64_t pub_ring_n;
    FILE *control_csv;
    bool replaying;              /* --replay: publish (encode) every tick for the check */
    bool depth_from_frames;      /* --replay, --inputs without --depth: the recorded depths */
    char replay_scene[FTM_WIRE_NAME_MAX];
    char replay_session[128];
} server;

/* a participant whose status is older than this is lost (its probe released) */
#define STATUS_DEADLINE_NS 2000000000u
#define STATUS_PERIOD_NS 500000000u  /* participants send a status this often */

static uint64_t mono_ns(void)
{
    struct timespec ts;
    clock_gettime(CLOCK_MONOTONIC, &ts);
    return (uint64_t)ts.tv_sec * 1000000000u + (uint64_t)ts.tv_nsec;
}

static uint64_t real_ns(void)
{
    struct timespec ts;
    clock_gettime(CLOCK_REALTIME, &ts);
    return (uint64_t)ts.tv_sec * 1000000000u + (uint64_t)ts.tv_nsec;
}

static void hist_add(uint32_t *h, double ns)
{
    int64_t b = ns > 0 ? (int64_t)(ns / 10000.0) : 0;
    h[b < TICK_HIST_BINS ? b : TICK_HIST_BINS - 1]++;
}

/* The q-quantile [ms] of a 10 us histogram (upper edge of its bin). */
static double hist_quantile(const uint32_t *h, double q)
{
    uint64_t n = 0, acc = 0;
    for (int i = 0; i < TICK_HIST_BINS; i++)
        n += h[i];
    for (int i = 0; i < TICK_HIST_BINS && n; i++)
        if ((acc += h[i]) >= (uint64_t)ceil(q * (double)n))
            return (i + 1) * 0.01;
    return 0.0;
}

static void slog(server *s, const char *level, const char *fmt, ...)
{
    char buf[1024];
    va_list ap;
    va_start(ap, fmt);
    vsnprintf(buf, sizeof buf, fmt, ap);
    va_end(ap);
    double t = (double)(mono_ns() - s->t_start_ns) * 1e-9;
    fprintf(stderr, "ftm-server [%8.3f] %s: %s\n", t, level, buf);
    if (s->logf) {
        fprintf(s->logf, "[%8.3f] %s: %s\n", t, level, buf);
        fflush(s->logf);
    }
}

static void log_hook(void *user, ftm_log_level level, const char *message)
{
    server *s = user; /* every hook is registered with its server */
    static const char *names[] = {"debug", "info", "warn", "error"};
    slog(s, names[level < 4 ? level : 3], "%s", message);
}

/* ---- recording (record.h) ------------------------------------------------------------ */

/* A write error stops the recording, not the session; the exit status says
 * the recording is incomplete (3, as when closing it fails). */
static void record_failed(server *s, const ftm_error *err)
{
    slog(s, "error", "%s; recording stopped", err->message);
    ftm_record_close(s->rec, NULL);
    s->rec = NULL;
    s->rec_failed = true;
}

static void record_entry(server *s, bool incoming, int kind, uint32_t sender, const uint8_t *buf,
                         size_t size, bool gone, bool lost)
{
    if (!s->rec)
        return;
    ftm_record_entry e = {.tick = s->tick, .kind = kind, .sender = sender, .incoming = incoming,
                          .gone = gone, .lost = lost, .time_ns = mono_ns() - s->t_start_ns,
                          .payload = buf, .size = size};
    ftm_error err = {0, ""};
    if (ftm_record_write(s->rec, &e, &err))
        record_failed(s, &err);
}

static void record(server *s, bool incoming, int kind, uint32_t sender, const uint8_t *buf,
                   size_t size, bool gone)
{
    record_entry(s, incoming, kind, sender, buf, size, gone, false);
}

/* ---- publishing ------------------------------------------------------------------ */

/* Encodes here (to count the bytes) and queues the payload. */
static int publish(server *s, const ftm_wire_msg *m, uint64_t *bytes)
{
    uint8_t *buf = NULL;
    size_t size = 0;
    ftm_error err = {0, ""};
    int rc = ftm_wire_encode(m, &buf, &size, &err);
    if (rc == FTM_OK && s->wire) /* --offline: encoded and counted only */
        rc = ftm_wire_publish_raw(s->wire, (int)m->kind, buf, size, &err);
    if (buf)
        record(s, false, (int)m->kind, s->o.id, buf, size, false);
    free(buf);
    if (rc) {
        s->publish_fail++;
        slog(s, "warn", "publishing %s failed: %s", ftm_wire_kind_name((int)m->kind), err.message);
        return rc;
    }
    if (bytes)
        *bytes += size;
    return FTM_OK;
}

static void publish_announce(server *s)
{
    ftm_wire_msg m;
    memset(&m, 0, sizeof m);
    m.kind = FTM_WIRE_ANNOUNCE;
    ftm_wire_announce *a = &m.u.announce;
    snprintf(a->scene_id, sizeof a->scene_id, "%s", s->o.scene);
    memcpy(a->digest, s->digest, sizeof s->digest);
    a->digest_len = FTM_REPLAY_DIGEST_SIZE;
    a->tick_rate_hz = (uint32_t)(s->o.rate + 0.5);
    a->time_step = ftm_replay_sim_def(s->scene).time_step;
    a->depth = s->depth;
    a->depth_min = s->ctl.def.floor;
    a->depth_max = s->ctl.def.max;
    a->tissue = ftm_replay_tissue_now(&s->mat);
    a->node_count = ftm_mesh_node_count(s->mesh);
    a->tick = s->tick;
    a->paused = s->paused;
    a->server_start_ns = s->start_unix_ns;
    a->arithmetic = ftm_arithmetic_revision();
    publish(s, &m, NULL);
}

static void publish_status(server *s, ftm_wire_state state)
{
    ftm_wire_msg m;
    memset(&m, 0, sizeof m);
    m.kind = FTM_WIRE_STATUS;
    ftm_wire_status *st = &m.u.status;
    st->participant = s->o.id;
    st->role = FTM_WIRE_ROLE_SERVER;
    st->state = state;
    st->last_applied_tick = s->tick;
    st->state_hash = ftm_sim_hash(s->sim);
    st->replay_ns_per_tick = s->tick ? s->step_ns_total / (double)s->tick : 0.0;
    st->replay_ns_max = s->step_ns_max;
    snprintf(st->name, sizeof st->name, "ftm-server");
    const uint64_t now = mono_ns();
    for (int i = 0; i < FTM_WIRE_IGNORED_MAX; i++)
        if (s->ignored[i].last_ns && now - s->ignored[i].last_ns <= STATUS_DEADLINE_NS) {
            st->ignored_participant[st->ignored_count] = s->ignored[i].id;
            st->ignored_origin[st->ignored_count++] = s->ignored[i].origin;
        }
    /* the process heard under each id: what a trainee waits for before it
     * sends probe input or renders force (docs/protocol.md) */
    for (int i = 0; i < MAX_PARTICIPANTS; i++)
        if (s->parts[i].used && s->parts[i].origin) {
            st->holder_participant[st->holder_count] = s->parts[i].id;
            st->holder_origin[st->holder_count++] = s->parts[i].origin;
        }
    publish(s, &m, NULL);
}

/* A status now rather than at the next periodic one, for news that decides
 * what a process does (an id taken, an id held); at most 20 extra a second,
 * the periodic status tells the rest within 500 ms. */
static void tell_now(server *s)
{
    const uint64_t now = mono_ns();
    if (!s->stopping && now - s->told_ns >= 50000000u) {
        s->told_ns = now;
        publish_status(s, FTM_WIRE_STATE_SYNCED);
    }
}

/* Notes a process whose messages carry an id another process holds. A new
 * one is told at once (tell_now). */
static void note_ignored(server *s, uint32_t id, uint64_t origin)
{
    const uint64_t now = mono_ns();
    int slot = 0;
    for (int i = 0; i < FTM_WIRE_IGNORED_MAX; i++) {
        if (s->ignored[i].last_ns && s->ignored[i].id == id && s->ignored[i].origin == origin) {
            s->ignored[i].last_ns = now;
            return;
        }
        if (s->ignored[i].last_ns < s->ignored[slot].last_ns) /* a free or the oldest slot */
            slot = i;
    }
    /* all heard within a status period (more than 16 ignored processes):
     * this one waits for a slot rather than push out one just listed, which
     * would then come back, and so on, a status for every message */
    if (s->ignored[slot].last_ns && now - s->ignored[slot].last_ns < STATUS_PERIOD_NS)
        return;
    s->ignored[slot].id = id;
    s->ignored[slot].origin = origin;
    s->ignored[slot].last_ns = now;
    tell_now(s);
}

/* Only with the integrator in its plain mode: keyframes do not carry the
 * guard's substeps (docs/protocol.md). */
/* The keyframe carries the integrator's mode and the tissue parameters, so a
 * replica restoring it continues bit-identically whatever the guard does. */
static bool publish_keyframe(server *s)
{
    ftm_wire_msg m;
    memset(&m, 0, sizeof m);
    m.kind = FTM_WIRE_KEYFRAME;
    ftm_error err = {0, ""};
    if (ftm_replay_make_keyframe(s->sim, &s->mat, &m.u.keyframe, &err)) {
        slog(s, "error", "keyframe: %s", err.message);
        return false;
    }
    publish(s, &m, &s->bytes_keyframes);
    s->keyframes++;
    ftm_replay_keyframe_free(&m.u.keyframe);
    return true;
}

static void publish_frame(server *s, int32_t n, int32_t nreact, bool heartbeat)
{
    ftm_wire_msg m;
    memset(&m, 0, sizeof m);
    m.kind = FTM_WIRE_TICK;
    ftm_wire_tick *t = &m.u.tick;
    t->tick = s->tick;
    t->depth = s->depth;
    t->contact_count = n;
    t->contacts = s->contacts;
    t->reaction_count = nreact;
    t->reactions = s->reactions;
    t->state_hash = ftm_sim_hash(s->sim);
    t->send_time_ns = real_ns();
    t->has_tissue = s->tissue_frame;
    t->tissue = ftm_replay_tissue_now(&s->mat);
    if (publish(s, &m, &s->bytes_frames) == FTM_OK) {
        s->frames++;
        s->heartbeats += heartbeat;
    }
    s->tissue_frame = false; /* sent or lost: a lost one makes replicas resync */
    s->pub_n = n;
    s->pub_depth = s->depth;
    s->pub_tick = s->tick;
    s->pub_ring_ns[s->pub_ring_n % PUB_RING] = mono_ns();
    s->pub_ring_tick[s->pub_ring_n % PUB_RING] = s->tick;
    s->pub_ring_n++;
    s->pub_ns = mono_ns();
    s->published_any = true;
}

/* ---- participants ---------------------------------------------------------------- */

static participant *find_part(server *s, uint32_t id, bool create)
{
    participant *free_slot = NULL;
    for (int i = 0; i < MAX_PARTICIPANTS; i++) {
        if (s->parts[i].used && s->parts[i].id == id)
            return &s->parts[i];
        if (!s->parts[i].used && !free_slot)
            free_slot = &s->parts[i];
    }
    if (!create || !free_slot)
        return NULL;
    memset(free_slot, 0, sizeof *free_slot);
    free_slot->report = -1;
    free_slot->used = true;
    free_slot->id = id;
    return free_slot;
}

static void release_probes(participant *p)
{
    for (int k = 0; k < MAX_PROBES; k++)
        memset(&p->probes[k], 0, sizeof p->probes[k]);
}

/* Ticks a participant that has applied `applied` is behind: against the
 * newest frame published at least LAG_GRACE_NS ago (frames still in flight
 * are no lag; without the grace an idle scene's heartbeat sent just before
 * a status arrives would count as a heartbeat interval of lag). */
#define LAG_GRACE_NS 10000000u
static int64_t lag_of(const server *s, uint64_t applied)
{
    uint64_t limit = mono_ns() - LAG_GRACE_NS, ref = 0;
    uint64_t n = s->pub_ring_n < PUB_RING ? s->pub_ring_n : PUB_RING;
    for (uint64_t k = 1; k <= n; k++) {
        uint64_t i = (s->pub_ring_n - k) % PUB_RING;
        if (s->pub_ring_ns[i] <= limit) {
            ref = s->pub_ring_tick[i];
            break;
        }
    }
    return ref > applied ? (int64_t)(ref - applied) : 0;
}

static void on_status(server *s, ftm_wire_received *rx)
{
    if (rx->gone) {
        participant *p = find_part(s, rx->sender, false);
        if (!p) {
            slog(s, "info", "participant %u gone", rx->sender);
            return;
        }
        if (!p->gone)
            slog(s, "info", "participant %u (%s '%s') gone: %s", p->id,
                 ftm_wire_role_name(p->role), p->name,
                 p->state == FTM_WIRE_STATE_LEAVING ? "left"
                                                   : "lost without leaving (lease expired)");
        release_probes(p);
        p->used = false;
        s->left[s->left_next].id = p->id;
        s->left[s->left_next].tick = s->tick + 1;
        s->left_next = (s->left_next + 1) % (int)(sizeof s->left / sizeof s->left[0]);
        return;
    }
    const ftm_wire_status *st = &rx->msg.u.status;
    if (st->participant != rx->sender) {
        slog(s, "warn", "status from %u names participant %u: ignored", rx->sender,
             st->participant);
        return;
    }
    participant *p = find_part(s, rx->sender, true);
    if (!p) {
        slog(s, "warn", "participant %u: table full (%d), ignored", rx->sender, MAX_PARTICIPANTS);
        return;
    }
    if (!p->origin && rx->origin) {
        /* its id is now this process's (admit). One that was ignored while
         * another held the id is heard from now on: off the list. Either
         * way it is told at once that it holds the id (ftm_replay_id_held) */
        p->origin = rx->origin;
        for (int i = 0; i < FTM_WIRE_IGNORED_MAX; i++)
            if (s->ignored[i].last_ns && s->ignored[i].id == p->id &&
                s->ignored[i].origin == rx->origin) {
                s->ignored[i].last_ns = 0;
                slog(s, "info", "participant %u: the process that held the id is gone; the one "
                     "ignored until now is heard", p->id);
            }
        tell_now(s);
    }
    bool fresh = p->role == 0;
    /* the tick is the participant's own, the last it applied: a joiner has
     * none yet */
    if ((fresh || p->state != st->state || p->role != st->role) &&
        st->state == FTM_WIRE_STATE_JOINING)
        slog(s, "info", "participant %u (%s '%s'): joining at server tick %" PRIu64, rx->sender,
             ftm_wire_role_name(st->role), st->name, s->tick);
    else if (fresh || p->state != st->state || p->role != st->role)
        slog(s, "info", "participant %u (%s '%s'): %s, its last applied tick %" PRIu64,
             rx->sender, ftm_wire_role_name(st->role), st->name, ftm_wire_state_name(st->state),
             st->last_applied_tick);
    if (!fresh && p->role != st->role) {
        release_probes(p);
    }
    if (p->silent)
        slog(s, "info", "participant %u (%s '%s') is back", p->id, ftm_wire_role_name(st->role),
             st->name);
    p->silent = false;
    p->last_status_ns = mono_ns();
    p->role = st->role;
    p->state = st->state;
    p->last_tick = st->last_applied_tick;
    p->hash = st->state_hash;
    /* lag against the frames it could have applied by now */
    p->lag = lag_of(s, st->last_applied_tick);
    p->replay_ns = st->replay_ns_per_tick;
    snprintf(p->name, sizeof p->name, "%s", st->name);
    p->report = ftm_report_seen(&s->report, p->id, ftm_wire_role_name(p->role), p->name, s->tick);
    if (st->state == FTM_WIRE_STATE_JOINING || st->state == FTM_WIRE_STATE_RESYNCING)
        s->keyframe_due = true;
    if (st->state == FTM_WIRE_STATE_LEAVING) {
        release_probes(p);
        /* the id is free: the next process heard with it claims it (another
         * one using it may stay on; its status keeps the DDS instance
         * alive, so no `gone` comes to free the entry) */
        p->origin = 0;
    }
}

static void reject(server *s, participant *p, uint32_t id, const char *what, const char *why)
{
    uint64_t n = p ? ++p->rejected : ++s->rejected_unknown;
    if (n <= 3 || (n & (n - 1)) == 0) /* 1, 2, 3, 4, 8, 16, ... */
        slog(s, "warn", "%s from participant %u rejected (%" PRIu64 " so far): %s", what, id, n,
             why);
}

/* Whether id left the session (its `gone`) within the last 2 s of ticks. */
static bool just_left(const server *s, uint32_t id)
{
    const uint64_t window = (uint64_t)(2.0 * s->o.rate);
    for (size_t i = 0; i < sizeof s->left / sizeof s->left[0]; i++)
        if (s->left[i].tick && s->left[i].id == id && s->tick + 1 - s->left[i].tick <= window)
            return true;
    return false;
}

static void on_probe_input(server *s, ftm_wire_received *rx)
{
    participant *p = find_part(s, rx->sender, false);
    /* input sent just before a trainee's LEAVING status (another topic) may
     * be taken after it, or after its departure: dropped without a warning,
     * which every orderly leave would otherwise log */
    if ((!p || p->role == 0) && just_left(s, rx->sender))
        return;
    if (!p || p->role == 0)
        { reject(s, NULL, rx->sender, "probe input", "unknown participant (no status yet)"); return; }
    if (p->state == FTM_WIRE_STATE_LEAVING)
        return;
    if (p->role != FTM_WIRE_ROLE_TRAINEE)
        { reject(s, p, rx->sender, "probe input", "only trainees may move tissue"); return; }
    if (p->silent)
        { reject(s, p, rx->sender, "probe input", "participant missed its status deadline"); return; }
    const ftm_wire_probe_input *in = &rx->msg.u.probe_input;
    if (in->participant != rx->sender)
        { reject(s, p, rx->sender, "probe input", "participant id differs from the sender"); return; }
    for (int32_t i = 0; i < in->sample_count; i++) {
        const ftm_wire_probe_sample *smp = &in->samples[i];
        if (smp->probe < 0 || smp->probe >= MAX_PROBES) {
            reject(s, p, rx->sender, "probe sample", "probe index out of range 0..3");
            continue;
        }
        probe *pr = &p->probes[smp->probe];
        pr->hip = smp->position; /* samples are oldest first: the newest wins */
        pr->have = true;
    }
    p->inputs++;
    /* a trainee reports the newest frame it applied with every batch: a
     * lag measurement at the input rate, fresher than the status */
    if (in->last_tick_seen > 0)
        p->lag = lag_of(s, in->last_tick_seen);
}

/* Puts the tissue back at rest, keeping the tick counter. With publish_now
 * (between ticks): first the frame of the current tick if it was not sent
 * (replicas must reach it), then the keyframe of the reset state at that tick,
 * which replicas restore because its hash differs from the frame's. */
static void do_reset(server *s, bool publish_now)
{
    if (publish_now && (!s->published_any || s->pub_tick != s->tick))
        publish_frame(s, 0, 0, true); /* an unsent tick was idle: no contacts */
    ftm_error err = {0, ""};
    if (ftm_sim_load_state(s->sim, s->tick, s->depth, NULL, NULL, NULL, 0, NULL, 0, NULL, &err))
        slog(s, "error", "reset: %s", err.message);
    for (int i = 0; i < MAX_PARTICIPANTS; i++)
        for (int k = 0; k < MAX_PROBES; k++)
            s->parts[i].probes[k].contact = false;
    ftm_collide_update(s->collide, ftm_sim_positions(s->sim), NULL, 0);
    s->pub_n = 0; /* replicas restore the keyframe: no contacts */
    s->keyframe_due = true;
    if (publish_now && publish_keyframe(s)) {
        s->keyframe_due = false;
        s->next_keyframe_ns = mono_ns() + (uint64_t)(s->o.keyframe_every * 1e9);
    }
}

/* Tells the issuer what became of its command (docs/protocol.md,
 * ControlReply): published, and recorded, like every outgoing message. The
 * reason is made what the codec accepts: control bytes become spaces, and
 * it is cut to FTM_WIRE_REASON_MAX - 1 bytes at a UTF-8 character boundary. */
static void reply(server *s, uint32_t issuer, uint64_t command_id, ftm_wire_outcome outcome,
                  const char *fmt, ...) __attribute__((format(printf, 5, 6)));
static void reply(server *s, uint32_t issuer, uint64_t command_id, ftm_wire_outcome outcome,
                  const char *fmt, ...)
{
    ftm_wire_msg m;
    memset(&m, 0, sizeof m);
    m.kind = FTM_WIRE_CONTROL_REPLY;
    ftm_wire_control_reply *r = &m.u.control_reply;
    r->issuer = issuer;
    r->command_id = command_id;
    r->outcome = outcome;
    r->tick = s->tick;
    char text[FTM_ERROR_MESSAGE_MAX + 64];
    va_list ap;
    va_start(ap, fmt);
    vsnprintf(text, sizeof text, fmt, ap);
    va_end(ap);
    size_t n = strlen(text);
    if (n >= sizeof r->reason) {
        n = sizeof r->reason - 1;
        while (n > 0 && ((unsigned char)text[n] & 0xc0) == 0x80) /* text[n] continues a character */
            n--;
    }
    for (size_t i = 0; i < n; i++) {
        unsigned char c = (unsigned char)text[i];
        r->reason[i] = c < 0x20 || c == 0x7f ? ' ' : (char)c;
    }
    r->reason[n] = '\0';
    if (!r->reason[0] && outcome != FTM_WIRE_OUTCOME_APPLIED)
        snprintf(r->reason, sizeof r->reason, "no reason given");
    publish(s, &m, NULL);
}

/* A refused command: logged (rate-limited, as every rejection) and told to
 * its issuer. */
static void refuse(server *s, participant *p, const ftm_wire_received *rx, const char *what,
                   const char *why)
{
    reject(s, p, rx->sender, what, why);
    reply(s, rx->sender, rx->msg.u.control.command_id, FTM_WIRE_OUTCOME_REFUSED, "%s", why);
}

/* Appends ", " (unless first) and the formatted text to out[0..cap), *n
 * bytes used; cut at the end of out. */
static void add_change(char *out, size_t cap, size_t *n, const char *fmt, ...)
    __attribute__((format(printf, 4, 5)));
static void add_change(char *out, size_t cap, size_t *n, const char *fmt, ...)
{
    if (*n + 3 > cap)
        return;
    if (*n)
        *n += (size_t)snprintf(out + *n, cap - *n, ", ");
    va_list ap;
    va_start(ap, fmt);
    int w = vsnprintf(out + *n, cap - *n, fmt, ap);
    va_end(ap);
    *n = w < 0 ? *n : *n + (size_t)w < cap ? *n + (size_t)w : cap - 1;
}

/* What a tissue change changes, for the report's timeline: "stiffness 80
 * N/m (was 50), damping ..." for the parameters that differ only. */
static void tissue_change_text(const ftm_wire_tissue *was, const ftm_wire_tissue *now, char *out,
                               size_t cap)
{
    size_t n = 0;
    out[0] = 0;
    if (now->stiffness != was->stiffness)
        add_change(out, cap, &n, "stiffness %g N/m (was %g)", now->stiffness, was->stiffness);
    if (now->node_damping != was->node_damping)
        add_change(out, cap, &n, "damping %g N s/m (was %g)", now->node_damping,
                   was->node_damping);
    if (now->node_mass != was->node_mass)
        add_change(out, cap, &n, "node mass %g kg (was %g)", now->node_mass, was->node_mass);
    if (now->axis_scale.x != was->axis_scale.x || now->axis_scale.y != was->axis_scale.y ||
        now->axis_scale.z != was->axis_scale.z)
        add_change(out, cap, &n, "axis scale %g %g %g", now->axis_scale.x, now->axis_scale.y,
                   now->axis_scale.z);
}

/* Between ticks: the simulation switches material now, so the next tick is
 * stepped with it, and that tick's frame carries the parameters for the
 * replicas to switch at the same tick (docs/protocol.md, "Tissue parameters").
 * If the current tick's frame was not sent (idle), it goes first: replicas
 * must reach this tick under the old material. */
static void set_tissue(server *s, participant *p, const ftm_wire_received *rx)
{
    const uint32_t sender = rx->sender;
    const ftm_wire_tissue *t = &rx->msg.u.control.tissue;
    const uint64_t id = rx->msg.u.control.command_id;
    ftm_wire_tissue before = ftm_replay_tissue_now(&s->mat);
    if (before.node_mass == t->node_mass && before.node_damping == t->node_damping &&
        before.stiffness == t->stiffness && before.axis_scale.x == t->axis_scale.x &&
        before.axis_scale.y == t->axis_scale.y && before.axis_scale.z == t->axis_scale.z) {
        reply(s, sender, id, FTM_WIRE_OUTCOME_APPLIED, "already in force");
        return;
    }
    /* harmless if the change is then refused: a heartbeat */
    if (!s->published_any || s->pub_tick != s->tick)
        publish_frame(s, 0, 0, true); /* an unsent tick was idle: no contacts */
    uint64_t t0 = mono_ns();
    ftm_error err = {0, ""};
    if (ftm_replay_set_tissue(&s->mat, s->sim, t, &err)) {
        /* "sim set mesh: the material's critical time step ... is too short ..." */
        const char *why = strncmp(err.message, "sim set mesh: ", 14) == 0 ? err.message + 14
                                                                          : err.message;
        refuse(s, p, rx, "tissue parameters", why);
        return;
    }
    double ms = (double)(mono_ns() - t0) * 1e-6;
    slog(s, "info",
         "tissue from tick %" PRIu64 " (instructor %u): stiffness %g N/m (was %g), damping %g N s/m "
         "(was %g), node mass %g kg (was %g), axis scale %g %g %g; material built in %.2f ms",
         s->tick + 1, sender, t->stiffness, before.stiffness, t->node_damping, before.node_damping,
         t->node_mass, before.node_mass, t->axis_scale.x, t->axis_scale.y, t->axis_scale.z, ms);
    s->tissue_frame = true;
    s->tissue_changes++;
    char what[128] = ""; /* (the event keeps what fits its detail) */
    tissue_change_text(&before, t, what, sizeof what);
    ftm_report_event_add(&s->report, s->tick, sender, "tissue", "%s", what);
    publish_announce(s);
    reply(s, sender, id, FTM_WIRE_OUTCOME_APPLIED, "%s", "");
}

static void on_control(server *s, ftm_wire_received *rx)
{
    participant *p = find_part(s, rx->sender, false);
    const ftm_wire_control *c = &rx->msg.u.control;
    if (!p || p->role == 0)
        { refuse(s, NULL, rx, "session control", "unknown participant (no status yet)"); return; }
    if (p->role != FTM_WIRE_ROLE_INSTRUCTOR)
        { refuse(s, p, rx, "session control", "only the instructor controls the session"); return; }
    switch (c->command) {
    case FTM_WIRE_CMD_PAUSE:
        if (!s->paused) {
            s->paused = true;
            slog(s, "info", "paused at tick %" PRIu64 " by instructor %u", s->tick, rx->sender);
            ftm_report_event_add(&s->report, s->tick, rx->sender, "pause", "%s", "");
            publish_announce(s);
            reply(s, rx->sender, c->command_id, FTM_WIRE_OUTCOME_APPLIED, "%s", "");
        } else {
            reply(s, rx->sender, c->command_id, FTM_WIRE_OUTCOME_APPLIED, "already paused");
        }
        break;
    case FTM_WIRE_CMD_RESUME:
        if (s->paused) {
            s->paused = false;
            s->base_ns = mono_ns();
            s->base_tick = s->tick;
            slog(s, "info", "resumed at tick %" PRIu64 " by instructor %u", s->tick, rx->sender);
            ftm_report_event_add(&s->report, s->tick, rx->sender, "resume", "%s", "");
            publish_announce(s);
            reply(s, rx->sender, c->command_id, FTM_WIRE_OUTCOME_APPLIED, "%s", "");
        } else {
            reply(s, rx->sender, c->command_id, FTM_WIRE_OUTCOME_APPLIED, "was not paused");
        }
        break;
    case FTM_WIRE_CMD_DEPTH_LIMITS: {
        bool changed = false;
        char why[FTM_DEPTH_REASON_MAX];
        ftm_error err = {0, ""};
        if (ftm_depth_ctl_set_limits(&s->ctl, c->depth_min, c->depth_max, (int64_t)mono_ns(),
                                     &changed, why, sizeof why, &err)) {
            refuse(s, p, rx, "depth limits", err.message);
            break;
        }
        slog(s, "info", "depth limits [%d, %d] from instructor %u at tick %" PRIu64,
             (int)c->depth_min, (int)c->depth_max, rx->sender, s->tick);
        if (changed) {
            slog(s, "info", "depth %s (tick %" PRIu64 ")", why, s->tick);
            s->depth = s->ctl.depth;
        }
        ftm_report_event_add(&s->report, s->tick, rx->sender, "depth limits", "[%d, %d], depth %d",
                             (int)c->depth_min, (int)c->depth_max, (int)s->depth);
        publish_announce(s);
        reply(s, rx->sender, c->command_id, FTM_WIRE_OUTCOME_APPLIED, "depth now %d", (int)s->depth);
        break;
    }
    case FTM_WIRE_CMD_RESET:
        slog(s, "info", "reset at tick %" PRIu64 " by instructor %u", s->tick, rx->sender);
        ftm_report_event_add(&s->report, s->tick, rx->sender, "reset", "%s", "");
        do_reset(s, true);
        reply(s, rx->sender, c->command_id, FTM_WIRE_OUTCOME_APPLIED, "%s", "");
        break;
    case FTM_WIRE_CMD_TISSUE:
        set_tissue(s, p, rx);
        break;
    default:
        refuse(s, p, rx, "session control", "unknown command");
    }
}

static void shutdown_server(server *s, const char *why);

/* Another ftm-server's status on this session: every participant would
 * follow two streams of frames. The one that started later stops (exit 3):
 * at the same rate it has run fewer ticks than the other's status, which is
 * at most a status period old, so the older one never finds itself behind. */
static void other_server(server *s, const ftm_wire_status *st)
{
    if (s->stopping)
        return;
    if (s->tick < st->last_applied_tick) {
        slog(s, "error",
             "session '%s' on domain %u is already served by another ftm-server ('%s', at "
             "tick %" PRIu64 "; this one at %" PRIu64 "): stopping this one",
             s->o.session, s->o.domain, st->name, st->last_applied_tick, s->tick);
        s->displaced = true;
        /* the other server is there, but may not have matched our status
         * writer yet (we heard it within a millisecond of starting): wait
         * for that, so that our LEAVING status tells it someone tried */
        ftm_error err = {0, ""};
        if (ftm_wire_wait_matched(s->wire, FTM_WIRE_STATUS, 1, 1000000000LL, &err))
            slog(s, "warn", "the other server did not match our status in 1 s: %s", err.message);
        shutdown_server(s, "another server serves the session");
    } else if (!s->other_server_told) {
        slog(s, "error",
             "another ftm-server ('%s', at tick %" PRIu64 ") joined session '%s' on domain %u; "
             "it should stop, as it started later: its messages are ignored here",
             st->name, st->last_applied_tick, s->o.session, s->o.domain);
        s->other_server_told = true;
    }
}

/* Whether a message is listened to. An id belongs to the process (DDS
 * participant) of the first status that claimed it until it is gone: a second process with the
 * same id (a copied --id) would otherwise be merged with the first, its
 * probe jumping between them. The server's own id is no participant's, and
 * another server's status stops one of the two (other_server). What is not
 * listened to is not recorded either, so a replay sees what the session did. */
static bool admit(server *s, int kind, const ftm_wire_received *rx)
{
    if (kind == FTM_WIRE_STATUS && !rx->gone &&
        rx->msg.u.status.role == FTM_WIRE_ROLE_SERVER) {
        other_server(s, &rx->msg.u.status);
        return false;
    }
    if (rx->sender == s->o.id) {
        if (rx->gone) /* a server that stopped (other_server) */
            return false;
        if (s->own_id_msgs++ % 1000 == 0)
            slog(s, "error", "%s from participant %u, the server's own id (%" PRIu64 " so far): "
                 "ignored; give each participant its own --id", ftm_wire_kind_name(kind),
                 rx->sender, s->own_id_msgs);
        return false;
    }
    participant *p = find_part(s, rx->sender, false);
    if (!p || !p->origin || !rx->origin || rx->origin == p->origin)
        return true;
    if (!rx->gone)
        note_ignored(s, rx->sender, rx->origin);
    if (p->impostor_msgs++ % 1000 == 0)
        slog(s, "error", "participant %u (%s '%s'): a second process uses this id (%s, %" PRIu64
             " messages so far): ignored; give each participant its own --id",
             p->id, ftm_wire_role_name(p->role), p->name, ftm_wire_kind_name(kind),
             p->impostor_msgs);
    return false;
}

static void drain(server *s)
{
    static const int kinds[3] = {FTM_WIRE_STATUS, FTM_WIRE_CONTROL, FTM_WIRE_PROBE_INPUT};
    for (int k = 0; k < 3; k++)
        for (int n = 0; n < 256; n++) {
            ftm_wire_received rx;
            if (ftm_wire_receive(s->wire, kinds[k], &rx, 0, NULL) != FTM_OK)
                break;
            if (!admit(s, kinds[k], &rx)) {
                ftm_wire_received_free(&rx);
                continue;
            }
            if (s->rec) { /* re-encoded from the decoded message */
                uint8_t *buf = NULL;
                size_t size = 0;
                if (rx.gone || ftm_wire_encode(&rx.msg, &buf, &size, NULL) == FTM_OK)
                    record(s, true, kinds[k], rx.sender, buf, size, rx.gone);
                free(buf);
            }
            if (kinds[k] == FTM_WIRE_STATUS)
                on_status(s, &rx);
            else if (kinds[k] == FTM_WIRE_CONTROL)
                on_control(s, &rx);
            else
                on_probe_input(s, &rx);
            ftm_wire_received_free(&rx);
        }
}

/* ---- one tick ---------------------------------------------------------------------- */

static ftm_vec3 v_sub(ftm_vec3 a, ftm_vec3 b) { return (ftm_vec3){a.x - b.x, a.y - b.y, a.z - b.z}; }
static double v_dot(ftm_vec3 a, ftm_vec3 b) { return a.x * b.x + a.y * b.y + a.z * b.z; }

static int reserve_contacts(server *s, int32_t need)
{
    if (need <= s->contact_cap)
        return 0;
    int32_t cap = s->contact_cap ? 2 * s->contact_cap : 64;
    while (cap < need)
        cap *= 2;
    ftm_contact *c = realloc(s->contacts, (size_t)cap * sizeof *c);
    if (!c)
        return -1;
    s->contacts = c;
    ftm_wire_reaction *r = realloc(s->reactions, (size_t)cap * sizeof *r);
    if (!r)
        return -1;
    s->reactions = r;
    s->contact_cap = cap;
    return 0;
}

/* Outward normal of a surface triangle at rest (not normalised): surface
 * triangles are oriented outward (generators, tetrahedra boundaries; OBJ
 * files must be too). */
static ftm_vec3 rest_normal(server *s, int32_t tr)
{
    const int32_t *v = ftm_mesh_triangles(s->mesh) + 3 * tr;
    ftm_vec3 X0 = ftm_mesh_rest_position(s->mesh, v[0]);
    ftm_vec3 e1 = v_sub(ftm_mesh_rest_position(s->mesh, v[1]), X0);
    ftm_vec3 e2 = v_sub(ftm_mesh_rest_position(s->mesh, v[2]), X0);
    return (ftm_vec3){e1.y * e2.z - e1.z * e2.y, e1.z * e2.x - e1.x * e2.z,
                      e1.x * e2.y - e1.y * e2.x};
}

/* Whether a HIP moving by d crosses the triangle from outside to inside. */
static bool entering(server *s, int32_t tr, ftm_vec3 d) { return v_dot(rest_normal(s, tr), d) < 0.0; }

/* A probe's push: HIP - anchor, shortened along itself to the limit. A HIP
 * far inside the tissue (a device glitch, a forged input) would otherwise
 * impose a displacement no step can follow: the guard would give up and the
 * tissue be reset for every participant. The replicas get the shortened
 * push in the frame, so they need not know the limit. */
static ftm_vec3 probe_push(server *s, const participant *p, int k, probe *pr)
{
    ftm_vec3 pen = v_sub(pr->hip, pr->anchor);
    double len = sqrt(v_dot(pen, pen));
    pr->limited = len > s->max_push;
    if (pr->limited) {
        double f = s->max_push / len; /* 0 if len overflowed: no push rather than NaN */
        pen = (ftm_vec3){pen.x * f, pen.y * f, pen.z * f};
        s->push_limited++;
        if (!pr->limit_told)
            slog(s, "warn",
                 "participant %u probe %d: HIP %.4g m from its contact point; push limited to "
                 "%.4g m (--max-penetration) while it is further",
                 p->id, k, len, s->max_push);
        pr->limit_told = true;
    }
    pr->push = pen;
    return pen;
}

/* Probe HIPs -> displacement contacts on the collided triangles' vertices.
 * Returns the contact count; *nreact the probes in contact. */
static int32_t probe_contacts(server *s, int32_t *nreact)
{
    const double *x = ftm_sim_positions(s->sim);
    const int32_t *tris = ftm_mesh_triangles(s->mesh);
    int32_t n = 0, nr = 0;
    for (int i = 0; i < MAX_PARTICIPANTS; i++) {
        participant *p = &s->parts[i];
        if (!p->used || p->role != FTM_WIRE_ROLE_TRAINEE)
            continue;
        for (int k = 0; k < MAX_PROBES; k++) {
            probe *pr = &p->probes[k];
            if (!pr->have)
                continue;
            if (pr->contact) {
                ftm_vec3 pen = v_sub(pr->hip, pr->anchor);
                if (v_dot(pen, pr->normal) >= 0.0)
                    pr->contact = false; /* back on the side it came from: released */
            } else if (pr->have_prev) {
                double t, w[3];
                int32_t tr = ftm_collide_segment(s->collide, x, pr->prev, pr->hip, &t, w);
                if (tr >= 0 && !entering(s, tr, v_sub(pr->hip, pr->prev)))
                    tr = -1; /* leaving the tissue through the surface: no contact */
                if (tr >= 0) {
                    const int32_t *v = tris + 3 * tr;
                    ftm_vec3 X[3];
                    for (int q = 0; q < 3; q++)
                        X[q] = ftm_mesh_rest_position(s->mesh, v[q]);
                    pr->anchor = (ftm_vec3){w[0] * X[0].x + w[1] * X[1].x + w[2] * X[2].x,
                                            w[0] * X[0].y + w[1] * X[1].y + w[2] * X[2].y,
                                            w[0] * X[0].z + w[1] * X[1].z + w[2] * X[2].z};
                    pr->normal = rest_normal(s, tr);
                    pr->tri = tr;
                    pr->contact = true;
                    pr->limit_told = false;
                    if (p->report >= 0)
                        s->report.parts[p->report].probes[k].touches++;
                    slog(s, "info", "participant %u probe %d: contact on triangle %d", p->id, k,
                         (int)tr);
                }
            }
            pr->prev = pr->hip;
            pr->have_prev = true;
            if (!pr->contact)
                continue;
            if (reserve_contacts(s, n + 3))
                return n;
            int32_t group = i * MAX_PROBES + k;
            ftm_vec3 pen = probe_push(s, p, k, pr);
            const int32_t *v = tris + 3 * pr->tri;
            for (int q = 0; q < 3; q++) {
                bool taken = ftm_mesh_fixed(s->mesh, v[q]);
                for (int32_t j = 0; j < n && !taken; j++)
                    taken = s->contacts[j].node == v[q]; /* an earlier probe has it */
                if (!taken)
                    s->contacts[n++] = (ftm_contact){v[q], group, FTM_CONTACT_DISPLACEMENT, pen};
            }
            s->reactions[nr++] = (ftm_wire_reaction){.group = group, .participant = p->id, .probe = k};
        }
    }
    *nreact = nr;
    return n;
}

/* At the end of a run: what kept the tissue in bounds, if anything did. */
static void log_limits(server *s)
{
    if (s->push_limited || s->unstable)
        slog(s, "info",
             "%" PRIu64 " probe-ticks with the push limited to %.4g m; %" PRIu64
             " unstable ticks (tissue reset)",
             s->push_limited, s->max_push, s->unstable);
}

static void note_step(server *s, double ns)
{
    int b = 0;
    while (b < FTM_METRICS_STEP_BUCKETS && ns * 1e-9 > ftm_metrics_step_bounds[b])
        b++;
    s->step_bucket[b]++;
    s->step_count++;
    s->step_sum_ns += ns;
}

static void run_tick(server *s)
{
    uint64_t tick_t0 = mono_ns(); /* the whole tick, for the depth controller */
    uint64_t begin = mono_ns();
    if (s->last_tick_ns)
        hist_add(s->period_hist, (double)(begin - s->last_tick_ns));
    s->last_tick_ns = begin;
    hist_add(s->late_hist, (double)begin - ((double)s->base_ns +
                                            (double)(s->tick + 1 - s->base_tick) * s->period_ns));
    int32_t nreact = 0;
    int32_t n = probe_contacts(s, &nreact);
    uint64_t t0 = mono_ns();
    ftm_error err = {0, ""};
    int rc = ftm_replay_step(s->sim, s->depth, s->contacts, n, &err);
    double dt = (double)(mono_ns() - t0);
    s->step_ns_total += dt;
    if (dt > s->step_ns_max)
        s->step_ns_max = dt;
    if (rc) {
        /* Deterministic, so every replica fails the same way; start over from
         * rest at the next tick number and send the state as a keyframe. */
        s->unstable++;
        slog(s, "error", "tick %" PRIu64 ": %s; tissue reset to rest", s->tick + 1, err.message);
        s->tick++;
        do_reset(s, false);
        n = nreact = 0;
    } else {
        s->tick++;
    }
    for (int32_t r = 0; r < nreact; r++) {
        ftm_wire_reaction *re = &s->reactions[r];
        re->force = ftm_sim_reaction(s->sim, re->group);
        /* the local force model for the client's haptic loop (docs/haptics.md) */
        const probe *pb = &s->parts[re->group / MAX_PROBES].probes[re->group % MAX_PROBES];
        re->hip = pb->hip;
        /* a limited push does not follow the HIP: no local model, the client
         * holds the force */
        re->push_limited = pb->limited;
        re->has_model = !pb->limited &&
                        ftm_sim_contact_stiffness(s->sim, re->group, re->stiffness) > 0;
        if (re->has_model) {
            ftm_stiffness_make_passive(re->stiffness);
            ftm_stiffness_secant_scale(re->stiffness, re->force, pb->push);
        }
        double nl = sqrt(v_dot(pb->normal, pb->normal));
        re->has_plane = nl > 0.0; /* the release rule of probe_contacts, for the client */
        re->contact_point = pb->anchor;
        if (re->has_plane)
            re->contact_normal = (ftm_vec3){pb->normal.x / nl, pb->normal.y / nl, pb->normal.z / nl};
        const participant *rp = &s->parts[re->group / MAX_PROBES];
        const double push = sqrt(v_dot(pb->push, pb->push));
        if (rp->report >= 0) {
            ftm_report_part *part = &s->report.parts[rp->report];
            ftm_report_contact(&part->probes[re->probe], s->tick, re->force, push, pb->limited);
            part->last_tick = s->tick;
        }
        if (s->reactions_csv) /* --reactions: what the frame carries, and the push */
            fprintf(s->reactions_csv, "%" PRIu64 ",%u,%d,%.17g,%.17g,%.17g,%.17g,%.17g,%d\n",
                    s->tick, re->participant, (int)re->probe, re->force.x, re->force.y,
                    re->force.z, (double)s->tick / s->o.rate, push, pb->limited ? 1 : 0);
    }
    if (s->depth_lo == 0 || s->depth < s->depth_lo)
        s->depth_lo = s->depth;
    if (s->depth > s->depth_hi)
        s->depth_hi = s->depth;
    /* keep the collision grid current: the region's nodes may have moved */
    const int32_t *order = NULL, *start = NULL;
    int32_t layers = ftm_sim_layers(s->sim, &order, &start);
    ftm_collide_update(s->collide, ftm_sim_positions(s->sim), order,
                       layers > 0 && order ? start[layers] : 0);

    ftm_sim_stats st;
    ftm_sim_get_stats(s->sim, &st);
    uint64_t now = mono_ns();
    if (!s->keyframe_due && now >= s->next_keyframe_ns) {
        s->keyframe_due = true;
    }
    bool idle = n == 0 && st.updated_nodes == 0 && s->pub_n == 0 && s->pub_depth == s->depth &&
                s->published_any && !s->tissue_frame;
    bool heartbeat = (double)(now - s->pub_ns) >= s->o.heartbeat * 1e9;
    if (!idle || heartbeat || s->keyframe_due || s->replaying)
        publish_frame(s, n, nreact, idle);
    else
        s->idle_ticks++;
    if (s->keyframe_due && publish_keyframe(s)) {
        s->keyframe_due = false;
        s->next_keyframe_ns = now + (uint64_t)(s->o.keyframe_every * 1e9);
    }
    note_step(s, (double)(mono_ns() - tick_t0));
}

/* ---- adaptive depth and metrics, every 100 ms ------------------------------------------ */

#define CONTROL_PERIOD_NS 100000000u
#define STATUS_OVERDUE_NS 750000000u /* later than this: lagging at least by its age */
#define REXMIT_FLOOR 8192u            /* bytes per control period, see control_period */

/* One control period: the period's measurements -> depth controller
 * (depth_ctl.h), the metrics snapshot. Runs on the loop thread between
 * ticks, so a new depth applies from the next tick and goes out in its frame. */
static void control_period(server *s)
{
    uint64_t now = mono_ns();
    if (now < s->next_control_ns)
        return;
    s->next_control_ns = now + CONTROL_PERIOD_NS;
    ftm_wire_stats ws;
    memset(&ws, 0, sizeof ws);
    ftm_wire_get_stats(s->wire, FTM_WIRE_TICK, &ws, NULL);
    uint64_t ticks = s->tick - s->prev_tick, sent = s->bytes_frames + s->bytes_keyframes;
    double step_ns = ticks ? (s->step_sum_ns - s->prev_step_sum) / (double)ticks : -1.0;
    uint64_t done = ws.published + ws.write_errors;
    ftm_depth_ctl_input in = {
        .now_ns = (int64_t)now,
        .step_ns = step_ns,
        .missed_ticks = s->missed_ticks - s->prev_missed,
        .backlog = s->frames > done ? (int32_t)(s->frames - done) : 0,
        .throttled = ws.throttle_count - s->prev_throttle,
        /* the share of the wire traffic that is repair: every matched reader
         * gets its own copy (unicast), and loses its own datagrams. Against
         * at least REXMIT_FLOOR bytes: a few repairs while little is sent
         * (joins, heartbeats) are no backlog */
        .rexmit_ratio = (double)(ws.rexmit_bytes - s->prev_rexmit) /
                        (double)((sent - s->prev_sent > REXMIT_FLOOR ? sent - s->prev_sent : REXMIT_FLOOR) *
                                 (uint64_t)(ws.matched > 1 ? ws.matched : 1)),
    };
    if (step_ns >= 0)
        s->step_recent_ns = step_ns;
    s->prev_tick = s->tick;
    s->prev_step_sum = s->step_sum_ns;
    s->prev_missed = s->missed_ticks;
    s->prev_throttle = ws.throttle_count;
    s->prev_rexmit = ws.rexmit_bytes;
    s->prev_sent = sent;

    ftm_depth_ctl_part parts[MAX_PARTICIPANTS];
    ftm_metrics_snapshot *m = &s->msnap;
    memset(m, 0, sizeof *m);
    int32_t np = 0;
    for (int i = 0; i < MAX_PARTICIPANTS; i++) {
        participant *p = &s->parts[i];
        if (!p->used || p->silent || p->role == 0 || p->role == FTM_WIRE_ROLE_SERVER)
            continue;
        int64_t lag = p->lag;
        uint64_t age = now - p->last_status_ns;
        if (age > STATUS_OVERDUE_NS) { /* its status is late: it is at least this far behind */
            int64_t late = (int64_t)((double)(age - STATUS_PERIOD_NS) / s->period_ns);
            if (late > lag)
                lag = late;
        }
        /* a joiner has applied nothing yet, a leaver stops: neither is lag */
        const bool replaying = p->state == FTM_WIRE_STATE_SYNCED ||
                               p->state == FTM_WIRE_STATE_RESYNCING;
        if (!replaying)
            lag = 0;
        if (m->nparts < FTM_METRICS_PARTS) {
            ftm_metrics_part *mp = &m->parts[m->nparts++];
            mp->id = p->id;
            snprintf(mp->role, sizeof mp->role, "%s", ftm_wire_role_name(p->role));
            snprintf(mp->state, sizeof mp->state, "%s", ftm_wire_state_name(p->state));
            mp->lag = lag;
            mp->replay_ns = p->replay_ns;
        }
        if (replaying)
            parts[np++] = (ftm_depth_ctl_part){p->id, ftm_wire_role_name(p->role), lag, p->replay_ns};
    }
    in.nparts = np;
    in.parts = parts;
    if (s->o.adaptive && !s->paused) {
        bool changed = false;
        char why[FTM_DEPTH_REASON_MAX];
        int32_t d = ftm_depth_ctl_update(&s->ctl, &in, &changed, why, sizeof why);
        if (changed) {
            slog(s, "info", "depth %s (tick %" PRIu64 ")", why, s->tick);
            s->depth = d;
        } else if (why[0] && d == s->ctl.def.floor && now - s->floor_log_ns >= 1000000000u) {
            slog(s, "info", "depth %d held at the floor: %s (tick %" PRIu64 ")", (int)d, why, s->tick);
            s->floor_log_ns = now;
        }
    }

    s->rate_tick[s->rate_i] = s->tick;
    s->rate_ns[s->rate_i] = now;
    s->rate_i = (s->rate_i + 1) % 10;
    uint64_t t_old = s->rate_ns[s->rate_i], k_old = s->rate_tick[s->rate_i];
    double rate = t_old && now > t_old ? (double)(s->tick - k_old) * 1e9 / (double)(now - t_old) : 0.0;
    if (s->control_csv) {
        const ftm_depth_ctl_part *worst = NULL;
        for (int32_t i = 0; i < np; i++)
            if (!worst || parts[i].lag > worst->lag)
                worst = &parts[i];
        fprintf(s->control_csv, "%.3f,%" PRIu64 ",%d,%.4f,%" PRIu64 ",%lld,%u,%d,%.3f,%.1f\n",
                (double)(now - s->t_start_ns) * 1e-9, s->tick, (int)s->depth,
                step_ns >= 0 ? step_ns * 1e-6 : 0.0, in.missed_ticks,
                worst ? (long long)worst->lag : 0LL, worst ? worst->id : 0u, (int)in.backlog,
                in.rexmit_ratio, rate);
    }
    if (!s->metrics)
        return;
    m->tick_rate_target = s->o.rate;
    m->tick_rate = rate;
    m->ticks = s->tick;
    m->missed_ticks = s->missed_ticks;
    m->idle_ticks = s->idle_ticks;
    m->frames = s->frames;
    m->heartbeats = s->heartbeats;
    m->keyframes = s->keyframes;
    m->bytes_frames = s->bytes_frames;
    m->bytes_keyframes = s->bytes_keyframes;
    m->publish_fail = s->publish_fail;
    m->rexmit_bytes = ws.rexmit_bytes;
    m->throttle_count = ws.throttle_count;
    m->depth = s->depth;
    m->depth_min = s->ctl.def.floor;
    m->depth_max = s->ctl.def.max;
    m->depth_decreases = s->ctl.decreases;
    m->depth_increases = s->ctl.increases;
    m->step_count = s->step_count;
    m->step_sum_s = s->step_sum_ns * 1e-9;
    memcpy(m->step_bucket, s->step_bucket, sizeof m->step_bucket);
    m->step_last_period_s = s->step_recent_ns * 1e-9;
    m->push_limited = s->push_limited;
    m->unstable_ticks = s->unstable;
    for (int i = 0; i < MAX_PARTICIPANTS; i++)
        m->inputs_rejected += s->parts[i].used ? s->parts[i].rejected : 0;
    m->record_bytes = ftm_record_bytes(s->rec);
    ftm_metrics_update(s->metrics, m);
}

/* ---- loop --------------------------------------------------------------------------- */

static void on_tick_timer(uv_timer_t *h)
{
    server *s = h->data;
    if (s->stopping)
        return;
    drain(s);
    control_period(s);
    if (s->paused)
        return;
    uint64_t now = mono_ns();
    uint64_t due = s->base_tick + (uint64_t)((double)(now - s->base_ns) / s->period_ns);
    int32_t ran = 0;
    while (s->tick < due && ran < MAX_CATCHUP) {
        run_tick(s);
        ran++;
    }
    if (s->tick < due) { /* fell behind: skip, do not burst */
        s->missed_ticks += due - s->tick;
        s->base_ns = now;
        s->base_tick = s->tick;
    }
}

/* Statuses come every 500 ms (docs/protocol.md): a participant silent for
 * the status deadline (2 s) is taken as lost, its probes released. DDS also
 * reports a vanished participant (a `gone` status event, on_status), but
 * that was not observed for a SIGKILLed process with Cyclone 0.10.2 here, so
 * the server does not rely on it alone. */

static void on_status_timer(uv_timer_t *h)
{
    server *s = h->data;
    publish_status(s, FTM_WIRE_STATE_SYNCED);
    /* the recording reaches the file at least every 0.5 s (not only per MiB,
     * which an idle session fills in minutes): a server killed or crashed
     * leaves whole entries up to about then */
    ftm_error err = {0, ""};
    if (s->rec && ftm_record_flush(s->rec, &err))
        record_failed(s, &err);
    uint64_t now = mono_ns();
    for (int i = 0; i < MAX_PARTICIPANTS; i++) {
        participant *p = &s->parts[i];
        if (!p->used || p->silent || now - p->last_status_ns <= STATUS_DEADLINE_NS)
            continue;
        p->silent = true;
        slog(s, "warn",
             "participant %u (%s '%s') lost: no status for %.1f s (deadline 2 s); its probes "
             "are released",
             p->id, ftm_wire_role_name(p->role), p->name, (double)(now - p->last_status_ns) * 1e-9);
        release_probes(p);
        p->origin = 0; /* the id is free for the next process heard (on_status) */
        /* a decision by the clock: recorded, so that a replay makes it too */
        record_entry(s, true, FTM_WIRE_STATUS, p->id, NULL, 0, false, true);
    }
}

static void shutdown_server(server *s, const char *why)
{
    if (s->stopping)
        return;
    s->stopping = true;
    s->stop_ns = mono_ns();
    slog(s, "info", "shutting down (%s) at tick %" PRIu64, why, s->tick);
    /* replicas end on the final state: a frame for the last tick */
    if (!s->published_any || s->pub_tick != s->tick) {
        publish_frame(s, 0, 0, true);
    }
    publish_status(s, FTM_WIRE_STATE_LEAVING);
    ftm_error err = {0, ""};
    if (ftm_wire_flush(s->wire, 2000000000LL, &err))
        slog(s, "warn", "flush: %s", err.message);
    uv_timer_stop(&s->tick_timer);
    uv_timer_stop(&s->status_timer);
    uv_timer_stop(&s->stop_timer);
    uv_signal_stop(&s->sigint);
    uv_signal_stop(&s->sigterm);
    uv_close((uv_handle_t *)&s->tick_timer, NULL);
    uv_close((uv_handle_t *)&s->status_timer, NULL);
    uv_close((uv_handle_t *)&s->stop_timer, NULL);
    uv_close((uv_handle_t *)&s->sigint, NULL);
    uv_close((uv_handle_t *)&s->sigterm, NULL);
}

static void on_signal(uv_signal_t *h, int signum)
{
    shutdown_server(h->data, signum == SIGINT ? "SIGINT" : "SIGTERM");
}

static void on_stop_timer(uv_timer_t *h) { shutdown_server(h->data, "duration reached"); }

/* ---- main ----------------------------------------------------------------------------- */

static void usage(FILE *f)
{
    fprintf(f,
            "usage: ftm-server [options]\n"
            "  --scene NAME|FILE      scene to serve (default: default)\n"
            "  --session NAME         session name (default: ftm)\n"
            "  --domain N             DDS domain id (default 0)\n"
            "  --config FILE          Cyclone DDS configuration (default: $CYCLONEDDS_URI)\n"
            "  --security DIR         DDS Security: this server's identity and permissions\n"
            "                         (made by deploy/ftm-security issue DIR NAME --role server)\n"
            "  --rate HZ              tick rate (default 1000)\n"
            "  --keyframe-every S     periodic keyframe interval in seconds (default 1)\n"
            "  --heartbeat S          idle heartbeat interval in seconds, <= 10 (default 0.1)\n"
            "  --depth N              penetration depth (default: the scene's)\n"
            "  --duration S           stop after S seconds (default: until SIGINT/SIGTERM)\n"
            "  --id N                 participant id (default 1)\n"
            "  --log FILE             also write the log to FILE\n"
            "  --adaptive 0|1         adapt the depth to the load (default 0; --depth is the ceiling)\n"
            "  --depth-floor N        lowest adaptive depth (default: depth / 4, at least 1)\n"
            "  --depth-hold-up S      calm time before each depth increase (default 2)\n"
            "  --record FILE          record every input and published message to FILE\n"
            "  --replay FILE          re-simulate a recording, check every hash, exit\n"
            "  --inputs FILE          run a recording's inputs through this server, without DDS\n"
            "                         (its frames ignored; with --record, record the result)\n"
            "  --metrics-port N       Prometheus metrics on http://ADDR:N/metrics (0: off)\n"
            "  --metrics-addr ADDR    address the metrics listen on (default 127.0.0.1)\n"
            "  --record-dir DIR       record each run to a new file DIR/SESSION-<UTC time>.rec,\n"
            "                         with its report (--report) beside it as .json\n"
            "  --report FILE          at the end, what each participant did as JSON (touches,\n"
            "                         contact time, forces, pushes); also with --replay/--inputs\n"
            "  --check                set up as for the session (scene, DDS, files, metrics),\n"
            "                         print what it would be and exit: 0 if it would start\n"
            "  --control-log FILE     CSV every 100 ms: time, tick, depth, step, lag, backlog, rate\n"
            "  --offline N            run N ticks without DDS, trainees from --trainee scripts\n"
            "  --trainee ID:T0:FILE   (offline) trainee ID plays bot script FILE; tick k uses\n"
            "                         the HIP at script time T0 + k / rate (repeatable, <= 8)\n"
            "  --reactions FILE       (offline, replay) CSV per probe in contact per tick:\n"
            "                         tick,participant,probe,fx,fy,fz,time_s,push_m,push_limited\n"
            "  --max-penetration M    longest push a probe imposes on the tissue, in metres\n"
            "                         (default: the scene's size, the longest side of its rest surface's box)\n"
            "  --rt-priority N        SCHED_FIFO priority of the tick thread, the publishing\n"
            "                         thread one above, where permitted (default 10; 0: off)\n"
            "  --rt-cpu start|any|N   with --rt-priority: both threads on the CPU the server\n"
            "                         started on (default), on no CPU in particular, or on CPU N\n");
}

/* The integer option value at v, ending at `stop` ('\0': the end of v),
 * in lo..hi (ftm_option_int). Returns where it ended (at `stop`), NULL if
 * v is no such integer; *out is set only then. */
static const char *int_in(const char *v, char stop, long long lo, long long hi, long long *out)
{
    const char *end = stop ? strchr(v, stop) : v + strlen(v);
    if (!end || !ftm_option_int(v, (size_t)(end - v), lo, hi, out))
        return NULL;
    return end;
}

/* Whether an address (inet_pton's bytes) is one no client can connect to:
 * multicast (IPv4 224.0.0.0/4, IPv6 ff00::/8) or the IPv4 broadcast
 * address, also IPv4-mapped. Binding to them succeeds, so the metrics would
 * say where they listen and never answer. */
static bool unreachable_addr(const unsigned char *a, bool v6)
{
    static const unsigned char mapped[12] = {0, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0xff, 0xff};
    if (v6 && a[0] == 0xff)
        return true;
    if (v6 && memcmp(a, mapped, sizeof mapped) != 0)
        return false;
    const unsigned char *v4 = v6 ? a + 12 : a;
    return (v4[0] >= 224 && v4[0] <= 239) ||
           (v4[0] == 255 && v4[1] == 255 && v4[2] == 255 && v4[3] == 255);
}

static int parse(int argc, char **argv, options *o)
{
    *o = (options){.scene = "default", .session = "ftm", .id = 1, .rate = 1000.0,
                   .keyframe_every = 1.0, .heartbeat = 0.1, .depth = -1, .depth_floor = -1,
                   .depth_hold_up = 2.0, .rt_priority = 10, .rt_cpu = RT_CPU_START, .metrics_addr = "127.0.0.1"};
    for (int i = 1; i < argc; i++) {
        const char *a = argv[i];
        if (strcmp(a, "--help") == 0 || strcmp(a, "-h") == 0) {
            usage(stdout);
            exit(0);
        }
        if (strcmp(a, "--check") == 0) {
            o->check = true;
            continue;
        }
        if (i + 1 >= argc) {
            fprintf(stderr, "ftm-server: %s needs a value (or unknown option)\n", a);
            return -1;
        }
        const char *v = argv[++i];
        char *end = NULL;
        long long n = 0;
        int bad = 0; /* an integer option out of range, already said */
        errno = 0;
        if (strcmp(a, "--scene") == 0) {
            o->scene = v;
            o->scene_given = true;
        } else if (strcmp(a, "--session") == 0) {
            o->session = v;
            o->session_given = true;
        }
        else if (strcmp(a, "--config") == 0)
            o->config = v;
        else if (strcmp(a, "--security") == 0)
            o->security = v;
        else if (strcmp(a, "--log") == 0)
            o->log_path = v;
        else if (strcmp(a, "--domain") == 0) {
            bad = ftm_option_int_arg("ftm-server", a, v, 0, MAX_DOMAIN, &n);
            o->domain = (uint32_t)n;
        } else if (strcmp(a, "--id") == 0) {
            bad = ftm_option_int_arg("ftm-server", a, v, 1, UINT32_MAX, &n);
            o->id = (uint32_t)n;
        } else if (strcmp(a, "--rate") == 0)
            o->rate = strtod(v, &end);
        else if (strcmp(a, "--keyframe-every") == 0)
            o->keyframe_every = strtod(v, &end);
        else if (strcmp(a, "--heartbeat") == 0)
            o->heartbeat = strtod(v, &end);
        else if (strcmp(a, "--duration") == 0)
            o->duration = strtod(v, &end);
        else if (strcmp(a, "--depth") == 0) {
            bad = ftm_option_int_arg("ftm-server", a, v, 0, FTM_DEPTH_CTL_MAX, &n);
            o->depth = (int32_t)n;
        } else if (strcmp(a, "--depth-floor") == 0) {
            bad = ftm_option_int_arg("ftm-server", a, v, 0, FTM_DEPTH_CTL_MAX, &n);
            o->depth_floor = (int32_t)n;
        } else if (strcmp(a, "--depth-hold-up") == 0)
            o->depth_hold_up = strtod(v, &end);
        else if (strcmp(a, "--adaptive") == 0) {
            bad = ftm_option_int_arg("ftm-server", a, v, 0, 1, &n);
            o->adaptive = (int32_t)n;
        } else if (strcmp(a, "--record") == 0)
            o->record = v;
        else if (strcmp(a, "--replay") == 0)
            o->replay = v;
        else if (strcmp(a, "--inputs") == 0)
            o->inputs = v;
        else if (strcmp(a, "--control-log") == 0)
            o->control_log = v;
        else if (strcmp(a, "--metrics-port") == 0) {
            bad = ftm_option_int_arg("ftm-server", a, v, 0, 65535, &n);
            o->metrics_port = (int32_t)n;
        } else if (strcmp(a, "--offline") == 0) {
            bad = ftm_option_int_arg("ftm-server", a, v, 1, INT64_MAX, &n);
            o->offline_ticks = n;
        } else if (strcmp(a, "--metrics-addr") == 0) {
            unsigned char addr[16];
            bool v4 = inet_pton(AF_INET, v, addr) == 1;
            if (!v4 && inet_pton(AF_INET6, v, addr) != 1) {
                fprintf(stderr, "ftm-server: --metrics-addr needs an IPv4 or IPv6 address "
                                "(got '%s')\n", v);
                return -1;
            }
            if (unreachable_addr(addr, !v4)) {
                fprintf(stderr, "ftm-server: --metrics-addr %s is a multicast or broadcast "
                                "address, which no client can connect to: give one of this "
                                "host's addresses (0.0.0.0 or :: for all)\n", v);
                return -1;
            }
            o->metrics_addr = v;
        } else if (strcmp(a, "--record-dir") == 0)
            o->record_dir = v;
        else if (strcmp(a, "--report") == 0)
            o->report = v;
        else if (strcmp(a, "--trainee") == 0) {
            if (o->ntrainees == 8) {
                fprintf(stderr, "ftm-server: at most 8 --trainee options\n");
                return -1;
            }
            o->trainees[o->ntrainees++] = v;
        }
        else if (strcmp(a, "--reactions") == 0)
            o->reactions_csv = v;
        else if (strcmp(a, "--rt-priority") == 0) {
            bad = ftm_option_int_arg("ftm-server", a, v, 0, 98, &n);
            o->rt_priority = (int32_t)n;
        } else if (strcmp(a, "--rt-cpu") == 0) {
            if (strcmp(v, "start") == 0)
                o->rt_cpu = RT_CPU_START;
            else if (strcmp(v, "any") == 0)
                o->rt_cpu = RT_CPU_ANY;
            else if (ftm_option_int(v, strlen(v), 0, CPU_SETSIZE - 1, &n))
                o->rt_cpu = (int32_t)n;
            else {
                fprintf(stderr, "ftm-server: --rt-cpu must be 'start', 'any' or a CPU number in "
                                "0..%d (got '%s')\n", CPU_SETSIZE - 1, v);
                bad = 1;
            }
        } else if (strcmp(a, "--max-penetration") == 0) {
            o->max_penetration = strtod(v, &end);
            if (!*end && !(isfinite(o->max_penetration) && o->max_penetration > 0)) {
                fprintf(stderr, "ftm-server: --max-penetration must be a length > 0 in metres "
                                "(got '%s')\n", v);
                return -1;
            }
        }
        else {
            fprintf(stderr, "ftm-server: unknown option %s\n", a);
            return -1;
        }
        if (bad)
            return -1;
        if (end && (*end || errno)) {
            fprintf(stderr, "ftm-server: %s: bad number '%s'\n", a, v);
            return -1;
        }
    }
    /* the heartbeat bounds the ticks a frame may skip, which replicas check
     * (FTM_WIRE_MAX_TICK_GAP: 10 s at 100 kHz, twice over) */
    /* the rate is announced and recorded in whole hertz: a fraction would
     * replay at another rate, below 0.5 Hz at none */
    if (!(o->rate >= 1 && o->rate <= 100000 && o->rate == floor(o->rate))) {
        fprintf(stderr, "ftm-server: --rate must be a whole number of hertz in 1..100000 (got %g)\n",
                o->rate);
        return -1;
    }
    if (!(o->heartbeat > 0 && o->heartbeat <= 10)) {
        fprintf(stderr, "ftm-server: --heartbeat must be in (0, 10] seconds (got %g)\n",
                o->heartbeat);
        return -1;
    }
    if (!(o->keyframe_every > 0 && o->keyframe_every <= MAX_SECONDS)) {
        fprintf(stderr, "ftm-server: --keyframe-every must be in (0, %g] seconds (got %g)\n",
                MAX_SECONDS, o->keyframe_every);
        return -1;
    }
    if (!(o->duration >= 0 && o->duration <= MAX_SECONDS)) {
        fprintf(stderr, "ftm-server: --duration must be in [0, %g] seconds, 0: until a signal "
                        "(got %g)\n", MAX_SECONDS, o->duration);
        return -1;
    }
    if ((o->depth >= 0 && o->depth_floor > o->depth) ||
        !(o->depth_hold_up >= 0 && o->depth_hold_up <= 3600)) {
        fprintf(stderr, "ftm-server: --depth-floor must be 0..depth, --depth-hold-up 0..3600\n");
        return -1;
    }
    if ((o->replay != NULL) + (o->inputs != NULL) + (o->offline_ticks != 0) > 1 ||
        (o->record && (o->replay || o->offline_ticks))) {
        fprintf(stderr, "ftm-server: --replay, --inputs and --offline exclude each other; "
                        "--record goes with a session or --inputs\n");
        return -1;
    }
    if (o->record_dir && (o->record || o->replay || o->inputs || o->offline_ticks)) {
        fprintf(stderr, "ftm-server: --record-dir goes with a session, without --record\n");
        return -1;
    }
    if (o->check && (o->replay || o->inputs || o->offline_ticks)) {
        fprintf(stderr, "ftm-server: --check checks a session's set-up: not with --replay, "
                        "--inputs or --offline\n");
        return -1;
    }
    /* (--offline itself is at least 1: ftm_option_int_arg) */
    if (o->ntrainees && !o->offline_ticks) {
        fprintf(stderr, "ftm-server: --trainee goes with --offline\n");
        return -1;
    }
    if (o->reactions_csv && !o->offline_ticks && !o->replay && !o->inputs) {
        fprintf(stderr, "ftm-server: --reactions goes with --offline, --replay or --inputs\n");
        return -1;
    }
    return 0;
}

/* The files a run writes, by option (--record-dir's are new files). */
typedef ftm_option_path output;

static int outputs_of(const options *o, output out[5])
{
    const output all[5] = {{"--record", o->record},           {"--log", o->log_path},
                           {"--report", o->report},           {"--control-log", o->control_log},
                           {"--reactions", o->reactions_csv}};
    int n = 0;
    for (int i = 0; i < 5; i++)
        if (all[i].path)
            out[n++] = all[i];
    return n;
}

/* Before anything is opened for writing: an output that is a file the run
 * reads — the recording --replay or --inputs reads, the scene file, the DDS
 * configuration, a --trainee script — (the same file, by device and inode:
 * another name, a link) would be truncated before it is read. Returns 0, or
 * 2 (a bad argument) after saying which. */
static int outputs_apart_from_input(const options *o)
{
    output in[4 + 8];
    int nin = 0;
    if (o->replay || o->inputs)
        in[nin++] = (output){o->replay ? "--replay" : "--inputs", o->replay ? o->replay : o->inputs};
    in[nin++] = (output){"--scene", o->scene}; /* a built-in name is no file: skipped */
    if (o->config)
        in[nin++] = (output){"--config", o->config};
    for (int t = 0; t < o->ntrainees; t++) { /* ID:T0:FILE */
        const char *c = strchr(o->trainees[t], ':');
        if (c && (c = strchr(c + 1, ':')))
            in[nin++] = (output){"--trainee", c + 1};
    }
    output out[5];
    const int nout = outputs_of(o, out);
    int k, i;
    if (!ftm_option_output_is_input(in, nin, out, nout, &k, &i))
        return 0;
    fprintf(stderr, "ftm-server: %s %s is the %s %s %s reads: it would be overwritten; write to "
                    "another file\n", out[i].opt, out[i].path,
            k == 0 && (o->replay || o->inputs) ? "recording" : "file", in[k].opt, in[k].path);
    return 2;
}

/* An output that is an existing directory; NULL if none. fopen fails on it
 * only when the file is written: --report's at the end of the session. */
static const output *output_dir(const output *out, int n)
{
    struct stat st;
    for (int i = 0; i < n; i++)
        if (stat(out[i].path, &st) == 0 && S_ISDIR(st.st_mode))
            return &out[i];
    return NULL;
}

/* --reactions FILE (--offline, --replay, --inputs): one line per probe in
 * contact per tick. Returns 0, or 3 after saying why it cannot be written. */
static int open_reactions(server *s)
{
    if (!s->o.reactions_csv)
        return 0;
    if (!(s->reactions_csv = fopen(s->o.reactions_csv, "w"))) {
        fprintf(stderr, "ftm-server: cannot open %s: %s\n", s->o.reactions_csv, strerror(errno));
        return 3;
    }
    fprintf(s->reactions_csv, "tick,participant,probe,fx,fy,fz,time_s,push_m,push_limited\n");
    return 0;
}

static int close_reactions(server *s)
{
    if (!s->reactions_csv)
        return 0;
    int bad = ferror(s->reactions_csv);
    bad |= fclose(s->reactions_csv) != 0;
    s->reactions_csv = NULL;
    if (bad)
        fprintf(stderr, "ftm-server: --reactions %s: write failed (disk full?)\n",
                s->o.reactions_csv);
    return bad ? 3 : 0;
}

/* --offline: the session's tick logic without DDS or the clock. Each
 * trainee is a participant slot (in the order given) whose probe 0 is at
 * its script's HIP for the tick; then run_tick does what it does online —
 * collision, contacts, ftm_replay_step, reactions, the frame (encoded and
 * counted, not sent). The reference for ftm-bot sessions (tests/net). */
/* --replay, second pass: the recorded inputs (statuses, probe input, session
 * control, gone and lost events) go through the same handlers and tick
 * logic as online — collision, contacts, ftm_replay_step — each at the tick
 * it was handled; every recorded tick frame is then compared with what this
 * run produced: contacts (bit-exact) and state hash. Depths come from the
 * recorded frames (the controller's choices depend on the clock).
 * --inputs: the same without comparing, the frames giving only the depth
 * (unless --depth is given), recording the inputs and this run's frames if
 * --record is given. */
static int replay_inputs(server *s)
{
    const char *path = s->o.replay ? s->o.replay : s->o.inputs;
    const char *mode = s->o.replay ? "--replay" : "--inputs";
    ftm_record_header h;
    ftm_record_reader *rd = NULL;
    ftm_error err = {0, ""};
    if (ftm_record_open(path, &h, &rd, &err)) {
        fprintf(stderr, "ftm-server %s: %s\n", mode, err.message);
        return 1;
    }
    if (open_reactions(s)) {
        ftm_record_close_reader(rd);
        return 3;
    }
    s->replaying = true;
    s->period_ns = 1e9 / s->o.rate;
    ftm_wire_limits lim = {0, 0, ftm_mesh_node_count(s->mesh)};
    uint64_t frames = 0, inputs = 0, end_tick = 0;
    bool leaving = false; /* the recorded server's final status seen: it stopped cleanly */
    uint64_t last_index = 0;
    int rc = 0;
    char why[FTM_ERROR_MESSAGE_MAX + 64] = "";
    ftm_record_entry e;
    for (;;) {
        int got = ftm_record_next(rd, &e, &err);
        if (got < 0) {
            fprintf(stderr, "ftm-server %s: %s\n", mode, err.message);
            rc = 1;
            break;
        }
        if (got == 0)
            break;
        last_index = e.index;
        if (e.tick > end_tick && e.tick - end_tick > FTM_WIRE_MAX_TICK_GAP) {
            /* every tick between is run: a forged tick would take hours */
            snprintf(why, sizeof why,
                     "tick %" PRIu64 " is %" PRIu64 " ticks after the entries before it; a "
                     "session records a frame at least every %u ticks",
                     e.tick, e.tick - end_tick, FTM_WIRE_MAX_TICK_GAP);
            break;
        }
        if (e.tick > end_tick)
            end_tick = e.tick;
        if (e.incoming) {
            if (e.tick < s->tick) {
                snprintf(why, sizeof why, "input handled at tick %" PRIu64 " after tick %" PRIu64,
                         e.tick, s->tick);
                break;
            }
            while (s->tick < e.tick) /* the server runs every tick, idle or not */
                run_tick(s);
            inputs++;
            /* --inputs --record: as drain records them, before handling */
            record_entry(s, true, e.kind, e.sender, e.payload, e.size, e.gone, e.lost);
            if (e.lost) {
                participant *p = find_part(s, e.sender, false);
                if (p) {
                    p->silent = true;
                    release_probes(p);
                }
                continue;
            }
            ftm_wire_received rx;
            memset(&rx, 0, sizeof rx);
            rx.sender = e.sender;
            rx.gone = e.gone;
            rx.msg.kind = (ftm_wire_kind)e.kind;
            if (!e.gone && ftm_wire_decode(e.kind, e.payload, e.size, &lim, &rx.msg, &err)) {
                snprintf(why, sizeof why, "%s", err.message);
                break;
            }
            if (e.kind == FTM_WIRE_STATUS)
                on_status(s, &rx);
            else if (e.kind == FTM_WIRE_CONTROL)
                on_control(s, &rx);
            else if (e.kind == FTM_WIRE_PROBE_INPUT)
                on_probe_input(s, &rx);
            ftm_wire_received_free(&rx);
        } else if (e.kind == FTM_WIRE_STATUS && !leaving) {
            ftm_wire_msg m;
            if (ftm_wire_decode(e.kind, e.payload, e.size, &lim, &m, &err)) {
                snprintf(why, sizeof why, "%s", err.message);
                break;
            }
            leaving = m.u.status.state == FTM_WIRE_STATE_LEAVING;
            ftm_wire_msg_free(&m);
        } else if (e.kind == FTM_WIRE_TICK && s->depth_from_frames) {
            ftm_wire_msg m;
            if (ftm_wire_decode(e.kind, e.payload, e.size, &lim, &m, &err)) {
                snprintf(why, sizeof why, "%s", err.message);
                break;
            }
            const ftm_wire_tick *f = &m.u.tick;
            if (f->tick > s->tick) { /* (<=: the frame of a tick sent again before a reset) */
                while (s->tick + 1 < f->tick)
                    run_tick(s);
                s->depth = f->depth;
                run_tick(s);
                frames++;
                bool same = s->o.inputs || /* --inputs: the depth only, nothing compared */
                            (s->pub_tick == f->tick && s->pub_n == f->contact_count);
                for (int32_t i = 0; same && !s->o.inputs && i < f->contact_count; i++) {
                    const ftm_contact *a = &s->contacts[i], *b = &f->contacts[i];
                    same = a->node == b->node && a->group == b->group && a->kind == b->kind &&
                           memcmp(&a->value, &b->value, sizeof a->value) == 0;
                }
                if (!same)
                    snprintf(why, sizeof why,
                             "tick %" PRIu64 ": the inputs give %d contacts, the frame has %d%s",
                             f->tick, (int)s->pub_n, (int)f->contact_count,
                             s->pub_n == f->contact_count ? " (different nodes or values)" : "");
                else if (!s->o.inputs && ftm_sim_hash(s->sim) != f->state_hash)
                    snprintf(why, sizeof why,
                             "tick %" PRIu64 ": state hash differs: recorded %016" PRIx64
                             ", re-run from the inputs %016" PRIx64,
                             f->tick, f->state_hash, ftm_sim_hash(s->sim));
            }
            ftm_wire_msg_free(&m);
            if (why[0])
                break;
        }
    }
    if (why[0]) {
        fprintf(stderr, "ftm-server %s: %s: entry %" PRIu64 " (byte %" PRIu64 "): %s\n", mode,
                path, e.index, e.offset, why);
        rc = 1;
    } else if (rc == 0 && s->o.inputs) {
        while (s->tick < end_tick) /* on to where the recorded session ended */
            run_tick(s);
        if (s->rec) { /* it ends as a session does: the last tick's frame, LEAVING */
            if (!s->published_any || s->pub_tick != s->tick)
                publish_frame(s, 0, 0, true);
            publish_status(s, FTM_WIRE_STATE_LEAVING);
        }
        if (!leaving)
            fprintf(stderr,
                    "ftm-server --inputs: %s: note: the recording ends at entry %" PRIu64
                    " without the server's final status (killed, crashed, or its recording "
                    "stopped on a write error?); run to tick %" PRIu64 ", where it was cut\n",
                    path, last_index, end_tick);
        log_limits(s);
        printf("inputs %s: %" PRIu64 " inputs through collision and the step; "
               "final tick %" PRIu64 " hash %016" PRIx64 "\n",
               path, inputs, s->tick, ftm_sim_hash(s->sim));
    } else if (rc == 0) {
        printf("replay %s from the inputs: %" PRIu64 " inputs through collision and the step, "
               "%" PRIu64 " tick frames with equal contacts and hash\n",
               s->o.replay, inputs, frames);
    }
    ftm_record_close_reader(rd);
    if (close_reactions(s) && rc == 0)
        rc = 3;
    return rc;
}

static int run_offline(server *s)
{
    ftm_script sc[8];
    double t0[8];
    participant *who[8];
    int n = s->o.ntrainees, rc = 0;
    for (int i = 0; i < n; i++) {
        const char *arg = s->o.trainees[i];
        long long id = 0;
        const char *at = int_in(arg, ':', 1, UINT32_MAX, &id);
        char *end = NULL;
        double off = at ? strtod(at + 1, &end) : NAN;
        if (!at || *end != ':' || !isfinite(off) || id == s->o.id ||
            find_part(s, (uint32_t)id, false)) {
            fprintf(stderr, "ftm-server: --trainee '%s': expected ID:T0:FILE, ID in "
                            "1..4294967295, not the server's (--id) nor an earlier trainee's\n",
                    arg);
            for (int j = 0; j < i; j++)
                ftm_script_free(&sc[j]);
            return 2;
        }
        /* (a script that cannot be read says why itself) */
        int bad = ftm_script_load(end + 1, &sc[i]);
        if (!bad && sc[i].npts == 0) {
            fprintf(stderr, "ftm-server: --trainee '%s': %s has no HIP positions for a trainee "
                            "to play\n", arg, end + 1);
            bad = 1;
        }
        if (bad) {
            for (int j = 0; j <= i; j++)
                ftm_script_free(&sc[j]);
            return 2;
        }
        t0[i] = off;
        who[i] = find_part(s, (uint32_t)id, true);
        who[i]->role = FTM_WIRE_ROLE_TRAINEE;
        who[i]->report = ftm_report_seen(&s->report, (uint32_t)id, "trainee", "offline", 0);
        who[i]->state = FTM_WIRE_STATE_SYNCED;
        snprintf(who[i]->name, sizeof who[i]->name, "offline");
    }
    if (open_reactions(s))
        rc = 3;
    s->period_ns = 1e9 / s->o.rate;
    slog(s, "info", "offline: %" PRId64 " ticks at %.0f Hz, %d trainees, depth %d",
         s->o.offline_ticks, s->o.rate, n, (int)s->depth);
    for (int64_t k = 0; k < s->o.offline_ticks && rc == 0; k++) {
        /* tick k + 1 runs at (k + 1) / rate after the start */
        double t = (double)(k + 1) / s->o.rate;
        for (int i = 0; i < n; i++) {
            who[i]->probes[0].hip = ftm_script_at(&sc[i], t0[i] + t);
            who[i]->probes[0].have = true;
        }
        s->base_ns = s->last_tick_ns = 0; /* no clock: no period statistics */
        run_tick(s);
    }
    slog(s, "info",
         "offline: %" PRIu64 " ticks, %" PRIu64 " frames (%" PRIu64 " idle ticks not sent), "
         "%.1f bytes/tick; step mean %.1f us",
         s->tick, s->frames, s->idle_ticks,
         s->tick ? (double)s->bytes_frames / (double)s->tick : 0.0,
         s->tick ? s->step_ns_total / (double)s->tick * 1e-3 : 0.0);
    log_limits(s);
    if (rc == 0)
        printf("ftm-server: final tick %" PRIu64 " hash %016" PRIx64 "\n", s->tick,
               ftm_sim_hash(s->sim));
    if (close_reactions(s))
        rc = 3;
    for (int i = 0; i < n; i++)
        ftm_script_free(&sc[i]);
    return rc;
}

/* --record-dir: DIR/SESSION-YYYYMMDDTHHMMSSZ.rec, claimed with O_EXCL so that
 * no earlier session's recording is overwritten (a restart within the same
 * second gets -2, -3, ...). */
static int claim_record_path(server *s, ftm_error *err)
{
    char name[128], stamp[32];
    size_t n = 0;
    for (const char *c = s->o.session; *c && n + 1 < 64; c++) /* the session as a file name */
        name[n++] = (*c >= 'a' && *c <= 'z') || (*c >= 'A' && *c <= 'Z') ||
                            (*c >= '0' && *c <= '9') || *c == '-' || *c == '_' || *c == '.'
                        ? *c
                        : '_';
    name[n] = '\0';
    time_t now = (time_t)(real_ns() / 1000000000u);
    struct tm tm;
    gmtime_r(&now, &tm);
    strftime(stamp, sizeof stamp, "%Y%m%dT%H%M%SZ", &tm);
    for (int k = 1; k <= 100; k++) {
        char suffix[8] = "";
        if (k > 1)
            snprintf(suffix, sizeof suffix, "-%d", k);
        int len = snprintf(s->record_path, sizeof s->record_path, "%s/%s-%s%s.rec",
                           s->o.record_dir, name[0] && name[0] != '.' ? name : "session", stamp,
                           suffix);
        if (len < 0 || (size_t)len >= sizeof s->record_path) {
            err->code = FTM_EINVAL;
            snprintf(err->message, sizeof err->message, "--record-dir %.200s: path too long",
                     s->o.record_dir);
            return FTM_EINVAL;
        }
        int fd = open(s->record_path, O_WRONLY | O_CREAT | O_EXCL, 0644);
        if (fd >= 0) {
            close(fd);
            s->o.record = s->record_path;
            return FTM_OK;
        }
        if (errno != EEXIST) {
            err->code = FTM_EIO;
            snprintf(err->message, sizeof err->message, "--record-dir: cannot create %.300s: %s",
                     s->record_path, strerror(errno));
            return FTM_EIO;
        }
    }
    err->code = FTM_EIO;
    snprintf(err->message, sizeof err->message, "--record-dir %.300s: 100 recordings of '%s' "
             "this second already", s->o.record_dir, name);
    return FTM_EIO;
}

static int open_recording(server *s, ftm_error *err)
{
    if (s->o.record_dir && !s->o.record && claim_record_path(s, err))
        return err->code;
    ftm_record_header rh;
    memset(&rh, 0, sizeof rh);
    snprintf(rh.scene_id, sizeof rh.scene_id, "%s", s->o.scene);
    snprintf(rh.session, sizeof rh.session, "%s", s->o.session);
    memcpy(rh.digest, s->digest, FTM_REPLAY_DIGEST_SIZE);
    rh.digest_len = FTM_REPLAY_DIGEST_SIZE;
    rh.tick_rate_hz = (uint32_t)(s->o.rate + 0.5);
    rh.depth_max = s->ctl.def.max;
    rh.depth_min = s->ctl.def.floor;
    rh.node_count = ftm_mesh_node_count(s->mesh);
    rh.max_penetration = isfinite(s->max_push) ? s->max_push : 0.0;
    rh.start_unix_ns = real_ns();
    int rc = ftm_record_create(s->o.record, &rh, &s->rec, err);
    if (rc == FTM_OK)
        slog(s, "info", "recording the session to %s", s->o.record);
    return rc;
}

/* The session report: a closing log line per trainee probe that touched
 * the tissue, and --report FILE. Returns 0, or 3 if the file fails. */
static int finish_report(server *s)
{
    for (int32_t i = 0; i < s->report.count; i++) {
        const ftm_report_part *p = &s->report.parts[i];
        for (int k = 0; k < FTM_REPORT_PROBES; k++) {
            const ftm_report_probe *q = &p->probes[k];
            if (!q->contact_ticks)
                continue;
            slog(s, "info",
                 "participant %u (%s '%s') probe %d: %u touch%s, %.2f s in contact, peak %.3g N "
                 "at tick %" PRIu64 ", mean %.3g N, deepest push %.1f mm%s",
                 p->id, p->role, p->name, k, q->touches, q->touches == 1 ? "" : "es",
                 (double)q->contact_ticks / s->o.rate, q->peak_force, q->peak_tick,
                 q->force_sum / (double)q->contact_ticks, q->max_push * 1e3,
                 q->limited_ticks ? " (push limited)" : "");
        }
    }
    /* --record-dir: each run's report beside its recording, NAME.json */
    const char *path = s->o.report;
    char beside[sizeof s->record_path + 8];
    if (!path && s->record_path[0]) {
        size_t n = strlen(s->record_path);
        snprintf(beside, sizeof beside, "%.*s.json", (int)(n > 4 ? n - 4 : n), s->record_path);
        path = beside;
    }
    if (!path)
        return 0;
    ftm_report_session rs = {s->o.session, s->o.scene, s->digest, FTM_REPLAY_DIGEST_SIZE,
                             s->tick, s->o.rate, s->depth_lo, s->depth_hi, s->unstable,
                             s->tissue_changes};
    /* written whole beside it, then renamed over it: a reader (a course's
     * records, a watcher of the directory) never sees half a report, and a
     * failure (a full disk, a crash) leaves the previous file or none */
    char tmp[4096 + 32];
    int len = snprintf(tmp, sizeof tmp, "%s.tmp-%ld", path, (long)getpid());
    int fd = len > 0 && (size_t)len < sizeof tmp
                 ? open(tmp, O_WRONLY | O_CREAT | O_EXCL | O_CLOEXEC, 0666)
                 : (errno = ENAMETOOLONG, -1);
    if (fd < 0 && errno == EEXIST && unlink(tmp) == 0) /* left by a killed run of this pid */
        fd = open(tmp, O_WRONLY | O_CREAT | O_EXCL | O_CLOEXEC, 0666);
    FILE *f = fd >= 0 ? fdopen(fd, "w") : NULL;
    if (fd >= 0 && !f)
        close(fd);
    int rc = f ? ftm_report_write_json(&s->report, &rs, f) : -1;
    if (f && (fflush(f) != 0 || fsync(fileno(f)) != 0))
        rc = -1;
    if (f && fclose(f) != 0)
        rc = -1;
    if (rc == 0 && rename(tmp, path) != 0)
        rc = -1;
    if (rc) {
        int e = errno;
        if (fd >= 0)
            unlink(tmp);
        slog(s, "error", "report %s: cannot write: %s", path, strerror(e));
        return 3;
    }
    slog(s, "info", "report: %s (%d participants)", path, (int)s->report.count);
    return 0;
}

/* The metrics' address as a URL: http://127.0.0.1:N/metrics, IPv6 in brackets. */
static void metrics_url(const options *o, char *buf, size_t cap)
{
    bool v6 = strchr(o->metrics_addr, ':') != NULL;
    snprintf(buf, cap, "http://%s%s%s:%d/metrics", v6 ? "[" : "", o->metrics_addr, v6 ? "]" : "",
             (int)o->metrics_port);
}

/* Whether a file may be created in the directory of `path` (dir: path is the
 * directory itself); a reason in `why` if not. */
static bool can_create_in(const char *path, bool dir, char *why, size_t cap)
{
    char d[1024];
    snprintf(d, sizeof d, "%s", path);
    if (!dir) {
        char *slash = strrchr(d, '/');
        if (!slash)
            snprintf(d, sizeof d, ".");
        else if (slash == d)
            d[1] = '\0';
        else
            *slash = '\0';
    }
    struct stat st;
    if (stat(d, &st) != 0) {
        snprintf(why, cap, "%s: %s", d, strerror(errno));
        return false;
    }
    if (!S_ISDIR(st.st_mode)) {
        snprintf(why, cap, "%s: not a directory", d);
        return false;
    }
    if (access(d, W_OK | X_OK) != 0) {
        snprintf(why, cap, "%s: %s", d, strerror(errno));
        return false;
    }
    return true;
}

/* --check: everything a session needs was set up (scene, simulation, collision
 * grid, DDS participant); try what remains without starting the session (the
 * metrics' address, where recordings and logs go, real-time scheduling), say
 * what the session would be, and exit: 0 if it would start, 3 if not. For an
 * ExecStartPre= of the service (deploy/) and for whoever writes its options. */
static int check_setup(server *s)
{
    int bad = 0;
    char why[1200];
    printf("scene       %s", s->o.scene);
    if (strcmp(s->scene_path, s->o.scene) != 0)
        printf(" (%s)", s->scene_path);
    printf(": %d nodes\ndigest      ", (int)ftm_mesh_node_count(s->mesh));
    for (int i = 0; i < FTM_REPLAY_DIGEST_SIZE; i++)
        printf("%02x", s->digest[i]);
    printf(" (every participant must load a scene with this digest)\n");
    printf("session     '%s' on DDS domain %u, participant id %u, configuration %s\n",
           s->o.session, s->o.domain, s->o.id,
           s->o.config ? s->o.config : getenv("CYCLONEDDS_URI") ? getenv("CYCLONEDDS_URI")
                                                                : "Cyclone's default");
    if (s->o.security)
        printf("security    DDS Security with the identity in %s (checked)\n", s->o.security);
    /* another server on this session says so within a status period */
    const uint64_t until = mono_ns() + 700000000u;
    for (uint64_t now = mono_ns(); now < until; now = mono_ns()) {
        ftm_wire_received rx;
        if (ftm_wire_receive(s->wire, FTM_WIRE_STATUS, &rx, (int64_t)(until - now), NULL))
            break;
        const bool server_role = !rx.gone && rx.msg.u.status.role == FTM_WIRE_ROLE_SERVER;
        if (server_role) {
            printf("session     FAILS: already served by another ftm-server ('%s', at tick "
                   "%" PRIu64 ")\n", rx.msg.u.status.name, rx.msg.u.status.last_applied_tick);
            bad++;
        }
        ftm_wire_received_free(&rx);
        if (server_role)
            break;
    }
    printf("ticks       %.0f Hz, depth %d, adaptive %s (range %d..%d), keyframe every %g s\n",
           s->o.rate, (int)s->depth, s->o.adaptive ? "on" : "off", (int)s->ctl.def.floor,
           (int)s->ctl.def.max, s->o.keyframe_every);
    if (isfinite(s->max_push))
        printf("push limit  %.4g m\n", s->max_push);
    else
        printf("push limit  none\n");
    struct {
        const char *what, *path;
        bool dir;
    } files[] = {{"recording", s->o.record_dir ? s->o.record_dir : s->o.record, s->o.record_dir != NULL},
                 {"control log", s->o.control_log, false},
                 {"report", s->o.report, false},
                 {"log", s->o.log_path, false}};
    for (size_t i = 0; i < sizeof files / sizeof files[0]; i++) {
        if (!files[i].path)
            continue;
        struct stat st;
        if (!files[i].dir && stat(files[i].path, &st) == 0 && S_ISDIR(st.st_mode)) {
            printf("%-11s FAILS: %s is a directory, not a file\n", files[i].what, files[i].path);
            bad++;
        } else if (can_create_in(files[i].path, files[i].dir, why, sizeof why)) {
            printf("%-11s %s%s\n", files[i].what, files[i].path,
                   files[i].dir ? "/ (a new file per run)" : "");
        } else {
            printf("%-11s FAILS: cannot create files in %s\n", files[i].what, why);
            bad++;
        }
    }
    if (s->o.metrics_port > 0) {
        ftm_error err = {0, ""};
        if (ftm_metrics_start(s->o.metrics_addr, (uint16_t)s->o.metrics_port, &s->metrics, &err)) {
            printf("metrics     FAILS: %s\n", err.message);
            bad++;
        } else {
            char url[128];
            metrics_url(&s->o, url, sizeof url);
            printf("metrics     %s (listened, then closed)\n", url);
            ftm_metrics_stop(s->metrics);
            s->metrics = NULL;
        }
    }
    if (s->o.rt_priority > 0) {
        struct sched_param sp = {.sched_priority = s->o.rt_priority}, was;
        int policy, e = pthread_getschedparam(pthread_self(), &policy, &was);
        if (!e)
            e = pthread_setschedparam(pthread_self(), SCHED_FIFO, &sp);
        if (e) {
            printf("real-time   not permitted (%s): the tick thread would run at default "
                   "scheduling\n", strerror(e));
        } else {
            pthread_setschedparam(pthread_self(), policy, &was);
            printf("real-time   SCHED_FIFO priority %d permitted\n", (int)s->o.rt_priority);
        }
        /* tried, not read off the affinity mask: taskset's mask is where a
         * process starts, not a limit; a cpuset or a CPU that is not there is */
        cpu_set_t given, one;
        if (s->o.rt_cpu >= 0 && !pthread_getaffinity_np(pthread_self(), sizeof given, &given)) {
            CPU_ZERO(&one);
            CPU_SET(s->o.rt_cpu, &one);
            int pe = pthread_setaffinity_np(pthread_self(), sizeof one, &one);
            pthread_setaffinity_np(pthread_self(), sizeof given, &given);
            if (pe)
                printf("real-time   cpu %d not permitted (%s): the tick thread would run on no "
                       "CPU in particular\n", (int)s->o.rt_cpu, strerror(pe));
            else
                printf("real-time   cpu %d permitted\n", (int)s->o.rt_cpu);
        }
    }
    printf("ftm-server --check: %s\n", bad ? "the session would NOT start" : "ok");
    fflush(stdout);
    return bad ? 3 : 0;
}

/* Everything ftm_server_main set up, whichever way it ends (what was never
 * made is NULL). */
static void teardown(server *s)
{
    ftm_wire_transport_destroy(s->wire);
    ftm_collide_destroy(s->collide);
    ftm_sim_destroy(s->sim);
    ftm_replay_material_free(&s->mat);
    ftm_scene_destroy(s->scene);
    ftm_report_free(&s->report);
    free(s->contacts);
    free(s->reactions);
    if (s->logf)
        fclose(s->logf);
}

int ftm_server_main(int argc, char **argv)
{
    static server srv;
    server *s = &srv;
    memset(s, 0, sizeof *s); /* called again by the fuzz target (tests/fuzz) */
    /* over a file size limit (ulimit -f, systemd's LimitFSIZE=) a write must
     * fail with EFBIG, which stops the recording or the report with a logged
     * error, rather than SIGXFSZ killing the session */
    signal(SIGXFSZ, SIG_IGN);
    if (parse(argc, argv, &s->o))
        return 2;
    int apart = outputs_apart_from_input(&s->o);
    if (apart)
        return apart;
    output out[5];
    const output *dir = output_dir(out, outputs_of(&s->o, out));
    if (dir && !s->o.check) { /* (--check says so with the rest) */
        fprintf(stderr, "ftm-server: %s %s is a directory: give a file name\n", dir->opt,
                dir->path);
        return 3;
    }
    if (s->o.replay) { /* first the frames alone, then the inputs (replay_inputs) */
        int rc = ftm_server_replay(s->o.replay, s->o.scene_given ? s->o.scene : NULL);
        if (rc)
            return rc;
    }
    if (s->o.replay || s->o.inputs) { /* the session's settings from the recording */
        const char *path = s->o.replay ? s->o.replay : s->o.inputs;
        ftm_record_header rh;
        ftm_record_reader *rr = NULL;
        ftm_error e0 = {0, ""};
        if (ftm_record_open(path, &rh, &rr, &e0)) {
            fprintf(stderr, "ftm-server %s: %s\n", s->o.replay ? "--replay" : "--inputs",
                    e0.message);
            return 1;
        }
        ftm_record_close_reader(rr);
        if (!s->o.scene_given) {
            snprintf(s->replay_scene, sizeof s->replay_scene, "%s", rh.scene_id);
            s->o.scene = s->replay_scene;
        }
        if (!s->o.session_given && rh.session[0]) { /* the report names it */
            snprintf(s->replay_session, sizeof s->replay_session, "%s", rh.session);
            s->o.session = s->replay_session;
        }
        s->o.rate = rh.tick_rate_hz;
        /* --inputs may try another depth or push limit; --replay must not */
        s->depth_from_frames = s->o.replay || s->o.depth < 0;
        if (s->depth_from_frames)
            s->o.depth = rh.depth_max;
        /* the recording's limit; none in recordings made before there was one */
        if (s->o.replay || !(s->o.max_penetration > 0))
            s->o.max_penetration = rh.max_penetration > 0 ? rh.max_penetration : INFINITY;
        s->o.adaptive = 0;
        s->o.depth_floor = -1;
    }
    s->t_start_ns = mono_ns();
    s->start_unix_ns = real_ns();
    if (s->o.log_path && !(s->logf = fopen(s->o.log_path, "w"))) {
        fprintf(stderr, "ftm-server: cannot open %s: %s\n", s->o.log_path, strerror(errno));
        return 3;
    }
    ftm_error err = {0, ""};
    if (ftm_wire_open_scene(s->o.scene, &s->scene, s->scene_path, sizeof s->scene_path, &err)) {
        slog(s, "error", "%s", err.message);
        return 3;
    }
    if (strcmp(s->scene_path, s->o.scene) != 0)
        slog(s, "info", "scene '%s': %s", s->o.scene, s->scene_path);
    s->mesh = ftm_scene_mesh(s->scene);
    ftm_sim_def def = ftm_replay_sim_def(s->scene);
    def.log = log_hook;
    def.log_user = s;
    s->depth = s->o.depth >= 0 ? s->o.depth : def.depth;
    /* adaptive depth between the floor and the scene's calibrated depth */
    int32_t floor = s->o.depth_floor >= 0 ? s->o.depth_floor : s->depth / 4 > 1 ? s->depth / 4 : 1;
    if (!s->o.adaptive || floor > s->depth)
        floor = s->depth;
    if (s->o.depth_floor > s->depth) {
        slog(s, "error", "--depth-floor %d is above the depth %d", (int)s->o.depth_floor,
             (int)s->depth);
        return 2;
    }
    ftm_depth_ctl_def cdef;
    ftm_depth_ctl_default(&cdef, floor, s->depth, 1e9 / s->o.rate);
    cdef.hold_up_ns = (int64_t)(s->o.depth_hold_up * 1e9);
    if (ftm_depth_ctl_init(&s->ctl, &cdef, &err)) {
        slog(s, "error", "%s", err.message);
        return 2;
    }
    s->mat.scene = s->scene;
    if (ftm_sim_create(s->mesh, &def, &s->sim, &err) ||
        ftm_collide_create(s->mesh, &s->collide, &err)) {
        slog(s, "error", "%s", err.message);
        return 3;
    }
    ftm_replay_scene_digest(s->scene, s->digest);
    ftm_collide_stats cs;
    ftm_collide_get_stats(s->collide, &cs);
    /* the default push limit, the scene's size: a probe pushing the surface
     * further than the whole tissue is deep is passing through it */
    s->max_push = s->o.max_penetration > 0 ? s->o.max_penetration
                  : cs.extent > 0          ? cs.extent
                                           : INFINITY;
    char limit[32] = "none (the recording has none)";
    if (isfinite(s->max_push))
        snprintf(limit, sizeof limit, "%.4g m", s->max_push);
    slog(s, "info",
         "scene '%s': %d nodes, %d surface triangles; collision grid %dx%dx%d cells of %.4g m; "
         "probe push limit %s",
         ftm_scene_name(s->scene), (int)ftm_mesh_node_count(s->mesh), (int)cs.triangles,
         (int)cs.dims[0], (int)cs.dims[1], (int)cs.dims[2], cs.cell_size, limit);

    if (s->o.offline_ticks > 0 || s->o.replay || s->o.inputs) {
        int rc = 0;
        if (s->o.inputs) { /* as a session starts: announcement, the rest state */
            if (s->o.record && open_recording(s, &err)) {
                slog(s, "error", "%s", err.message);
                rc = 3;
            }
            s->period_ns = 1e9 / s->o.rate;
            publish_announce(s);
            publish_keyframe(s);
        }
        if (rc == 0)
            rc = s->o.offline_ticks > 0 ? run_offline(s) : replay_inputs(s);
        if (rc == 0)
            rc = finish_report(s);
        if (rc == 0 && s->rec_failed)
            rc = 3;
        if (s->rec && ftm_record_close(s->rec, &err)) {
            fprintf(stderr, "ftm-server: %s\n", err.message);
            rc = 3;
        }
        s->rec = NULL;
        teardown(s);
        return rc;
    }

    ftm_wire_transport_def wd;
    memset(&wd, 0, sizeof wd);
    wd.config = s->o.config;
    wd.security = s->o.security;
    wd.role = FTM_WIRE_ROLE_SERVER;
    wd.domain_id = s->o.domain;
    wd.session = s->o.session;
    wd.participant_id = s->o.id;
    wd.publish = FTM_WIRE_KIND_BIT(FTM_WIRE_ANNOUNCE) | FTM_WIRE_KIND_BIT(FTM_WIRE_TICK) |
                 FTM_WIRE_KIND_BIT(FTM_WIRE_KEYFRAME) | FTM_WIRE_KIND_BIT(FTM_WIRE_STATUS) |
                 FTM_WIRE_KIND_BIT(FTM_WIRE_CONTROL_REPLY);
    wd.subscribe = FTM_WIRE_KIND_BIT(FTM_WIRE_STATUS) | FTM_WIRE_KIND_BIT(FTM_WIRE_PROBE_INPUT) |
                   FTM_WIRE_KIND_BIT(FTM_WIRE_CONTROL);
    wd.limits.node_count = ftm_mesh_node_count(s->mesh);
    wd.log = log_hook;
    wd.log_user = s;
    /* one above the tick thread: a queued frame goes out at once, not when the
     * tick has finished the rest of its work */
    wd.publisher_priority = s->o.rt_priority > 0 ? s->o.rt_priority + 1 : 0;
    if (ftm_wire_transport_create(&wd, &s->wire, &err)) {
        slog(s, "error", "%s", err.message);
        return 3;
    }
    if (s->o.check) {
        int rc = check_setup(s);
        teardown(s);
        return rc;
    }
    if (s->o.control_log) {
        if (!(s->control_csv = fopen(s->o.control_log, "w"))) {
            slog(s, "error", "cannot create %s: %s", s->o.control_log, strerror(errno));
            return 3;
        }
        fprintf(s->control_csv, "time_s,tick,depth,step_ms,missed,worst_lag,worst_participant,"
                                "backlog,rexmit_ratio,tick_rate_hz\n");
    }
    if (s->o.metrics_port > 0) {
        if (ftm_metrics_start(s->o.metrics_addr, (uint16_t)s->o.metrics_port, &s->metrics, &err)) {
            slog(s, "error", "%s", err.message);
            return 3;
        }
        char url[128];
        metrics_url(&s->o, url, sizeof url);
        slog(s, "info", "metrics on %s", url);
    }
    /* last of what may fail: a start that fails (a metrics port in use)
     * leaves no recording of a session that never ran in --record-dir */
    if ((s->o.record || s->o.record_dir) && open_recording(s, &err)) {
        slog(s, "error", "%s", err.message);
        return 3;
    }
    s->period_ns = 1e9 / s->o.rate;
    publish_announce(s);
    publish_keyframe(s); /* the rest state at tick 0, for joiners */
    publish_status(s, FTM_WIRE_STATE_SYNCED);
    s->next_keyframe_ns = mono_ns() + (uint64_t)(s->o.keyframe_every * 1e9);
    slog(s, "info", "session '%s' on domain %u: %.0f Hz, depth %d, keyframe every %g s", s->o.session,
         s->o.domain, s->o.rate, (int)s->depth, s->o.keyframe_every);
    slog(s, "info", "adaptive depth %s: range [%d, %d], tick budget %.3f ms",
         s->o.adaptive ? "on" : "off", (int)s->ctl.def.floor, (int)s->ctl.def.max,
         s->ctl.def.budget_ns * 1e-6);

    if (s->o.rt_priority > 0) {
        /* the tick loop (this thread) and the frames' hand-off: a tick due
         * or a frame queued runs as soon as a core is free, ahead of
         * ordinary work on the host; they sleep between ticks. Set last, so
         * that threads made before (DDS, metrics) keep default scheduling. */
        struct sched_param sp = {.sched_priority = s->o.rt_priority};
        int e = pthread_setschedparam(pthread_self(), SCHED_FIFO, &sp);
        if (e) {
            slog(s, "info", "real-time scheduling not permitted (%s): default scheduling",
                 strerror(e));
        } else {
            /* both on one CPU: the publishing thread, one level up, takes a
             * queued frame by a context switch, without waking another core.
             * Pinned, neither can move away from a busier real-time thread
             * on that CPU: --rt-cpu any leaves them to the scheduler, --rt-cpu
             * N puts them on a CPU kept for them (isolcpus, a cpuset). */
            const int want = s->o.rt_cpu;
            int cpu = want == RT_CPU_START ? sched_getcpu() : want;
            cpu_set_t was, set;
            CPU_ZERO(&set);
            if (cpu >= 0)
                CPU_SET(cpu, &set);
            char where[96] = ", on no CPU in particular (--rt-cpu any)";
            if (want == RT_CPU_ANY) {
                cpu = -1;
            } else if (cpu < 0 || pthread_getaffinity_np(pthread_self(), sizeof was, &was)) {
                cpu = -1;
                snprintf(where, sizeof where, ", on no CPU in particular (this one unknown)");
            } else if (pthread_setaffinity_np(pthread_self(), sizeof set, &set) ||
                       ftm_wire_pin_publisher(s->wire, cpu, &err)) {
                /* back to the CPUs the server was given (taskset, cgroup) */
                pthread_setaffinity_np(pthread_self(), sizeof was, &was);
                snprintf(where, sizeof where, ", on no CPU in particular (cpu %d not permitted)",
                         cpu);
                cpu = -1;
            }
            if (cpu >= 0)
                snprintf(where, sizeof where, ", both on cpu %d", cpu);
            slog(s, want >= 0 && cpu < 0 ? "warn" : "info",
                 "tick thread SCHED_FIFO priority %d, publishing thread %d%s",
                 (int)s->o.rt_priority, (int)s->o.rt_priority + 1, where);
        }
    }
    s->loop = uv_default_loop();
    uv_timer_init(s->loop, &s->tick_timer);
    uv_timer_init(s->loop, &s->status_timer);
    uv_timer_init(s->loop, &s->stop_timer);
    uv_signal_init(s->loop, &s->sigint);
    uv_signal_init(s->loop, &s->sigterm);
    s->tick_timer.data = s->status_timer.data = s->stop_timer.data = s;
    s->sigint.data = s->sigterm.data = s;
    s->base_ns = mono_ns();
    s->base_tick = 0;
    s->loop_start_ns = s->base_ns;
    uv_timer_start(&s->tick_timer, on_tick_timer, 1, 1);
    uv_timer_start(&s->status_timer, on_status_timer, 500, 500);
    if (s->o.duration > 0)
        uv_timer_start(&s->stop_timer, on_stop_timer, (uint64_t)(s->o.duration * 1000.0), 0);
    uv_signal_start(&s->sigint, on_signal, SIGINT);
    uv_signal_start(&s->sigterm, on_signal, SIGTERM);
    uv_run(s->loop, UV_RUN_DEFAULT);

    double run_s = (double)((s->stop_ns ? s->stop_ns : mono_ns()) - s->loop_start_ns) * 1e-9;
    ftm_wire_stats ws;
    ftm_wire_get_stats(s->wire, FTM_WIRE_TICK, &ws, NULL);
    slog(s, "info",
         "%" PRIu64 " ticks in %.2f s (%.1f ticks/s), %" PRIu64 " missed; %" PRIu64
         " frames (%" PRIu64 " heartbeats, %" PRIu64 " idle ticks not sent), %.1f bytes/frame, "
         "%.1f bytes/tick; %" PRIu64 " keyframes (%" PRIu64 " bytes); step mean %.1f us max "
         "%.1f us; rexmit %" PRIu64 " bytes",
         s->tick, run_s, (double)s->tick / run_s, s->missed_ticks, s->frames, s->heartbeats,
         s->idle_ticks, s->frames ? (double)s->bytes_frames / (double)s->frames : 0.0,
         s->tick ? (double)s->bytes_frames / (double)s->tick : 0.0, s->keyframes,
         s->bytes_keyframes, s->tick ? s->step_ns_total / (double)s->tick * 1e-3 : 0.0,
         s->step_ns_max * 1e-3, ws.rexmit_bytes);
    slog(s, "info",
         "tick period p50 %.2f ms p99 %.2f ms; start after due p50 %.2f ms p99 %.2f ms "
         "(10 us bins)",
         hist_quantile(s->period_hist, 0.5), hist_quantile(s->period_hist, 0.99),
         hist_quantile(s->late_hist, 0.5), hist_quantile(s->late_hist, 0.99));
    printf("ftm-server: final tick %" PRIu64 " hash %016" PRIx64 "\n", s->tick,
           ftm_sim_hash(s->sim));
    fflush(stdout);
    slog(s, "info", "depth %d at the end, range [%d, %d]: %" PRIu64 " decreases, %" PRIu64
         " increases", (int)s->depth, (int)s->ctl.def.floor, (int)s->ctl.def.max,
         s->ctl.decreases, s->ctl.increases);
    log_limits(s);
    int rc = finish_report(s);
    if (s->displaced || s->rec_failed)
        rc = 3;
    if (s->rec) {
        uint64_t bytes = ftm_record_bytes(s->rec);
        if (ftm_record_close(s->rec, &err)) {
            slog(s, "error", "%s", err.message);
            rc = 3;
        } else {
            slog(s, "info", "recording %s: %" PRIu64 " bytes", s->o.record, bytes);
        }
        s->rec = NULL;
    }
    ftm_metrics_stop(s->metrics);
    if (s->control_csv && fclose(s->control_csv) != 0)
        rc = 3;
    teardown(s);
    uv_loop_close(s->loop);
    return rc;
}
