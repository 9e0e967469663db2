/* SPDX-License-Identifier: GPL-3.0-or-later */
/* Inside ftm-server: one server's state, in rooms. Each room is a file with
 * a state struct of its own; the server struct holds one of each and what
 * they share (the scene, the log, the clock's origin). Nothing is global:
 * every function takes the server it works for, so that one process can
 * run a server after another (the session fuzz target does).
 *
 *   server.c        the lifetime: set-up, the libuv loop and what it drains, the end
 *   server_def.c    options: defaults, the option table, their checks
 *   participants.c  who is in the session: statuses, probe input, ids
 *   commands.c      the instructor's session control and its replies
 *   tick.c          one tick: probes -> contacts, the step, reactions
 *   publish.c       announcements, statuses, tick frames, keyframes
 *   period.c        every 100 ms: adaptive depth, metrics, control log
 *   recording.c     the session recording (a lesson's files) and report
 *   offline.c       runs without DDS: --offline, --inputs, --replay's inputs,
 *                   --resume's re-run
 *   check.c         --check: what a session would be, and whether it starts
 *   log.c           the log
 *
 * Each room calls only rooms below it: server.c; offline.c, check.c;
 * commands.c; participants.c, tick.c, period.c; publish.c; recording.c;
 * log.c. What they share otherwise is state, through the server struct.
 */
#ifndef FTM_SERVER_ROOMS_H
#define FTM_SERVER_ROOMS_H

#include "collide.h"
#include "depth_ctl.h"
#include "digest.h"
#include "metrics.h"
#include "record.h"
#include "report.h"
#include "server.h"
#include "tissue.h"

#include "ftm/clock.h"
#include "ftm/scene.h"
#include "ftm/wire.h"

#include <stdio.h>
#include <uv.h>

#define MAX_PARTICIPANTS 64
_Static_assert(MAX_PARTICIPANTS <= FTM_WIRE_HOLDERS_MAX, "every holder fits the server's status");
#define MAX_PROBES 4 /* per trainee; group = slot * MAX_PROBES + probe */
_Static_assert(MAX_PROBES <= FTM_REPORT_PROBES, "the session report counts every probe");
/* a participant whose status is older than this is lost (its probe released) */
#define STATUS_DEADLINE_NS 2000000000u
#define STATUS_PERIOD_NS 500000000u /* participants send a status this often */

/* The monotonic clock as the server's unsigned nanoseconds. */
static inline uint64_t srv_now(void) { return (uint64_t)ftm_clock_mono_ns(); }

/* ---- participants.c ---- */

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
    bool used;
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

typedef struct srv_parts {
    participant parts[MAX_PARTICIPANTS];
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
    /* Trainees lost without leaving (their lease expired: a stall, a cut
     * network) in the last 30 s of ticks, with their probes: the same
     * process heard again gets its contacts back, so that a probe held in
     * the tissue through the cut presses again (a new sample from inside
     * the tissue crosses no surface, and would press nothing) */
    struct {
        uint32_t id;
        uint64_t origin;
        uint64_t tick; /* when it was lost; 0: a free slot */
        probe probes[MAX_PROBES];
    } lost[8];
    int lost_next;
    /* Processes heard with an id another process holds (admit): listed in
     * the server's status while heard, so that each learns it is ignored. */
    struct {
        uint32_t id;
        uint64_t origin;
        uint64_t last_ns; /* monotonic; 0: a free slot */
    } ignored[FTM_WIRE_IGNORED_MAX];
    bool other_server_told; /* a later server on this session was logged */
    bool displaced;         /* stopped: another server was serving this session first */
} srv_parts;

/* ---- tick.c ---- */

#define TICK_HIST_BINS 5000 /* tick period and lateness, 10 us bins */
#define WORK_HIST_BINS 20000 /* a tick's work, 1 us bins (the last: 20 ms or more) */

typedef struct srv_tick {
    ftm_sim *sim;
    ftm_collide *collide;
    ftm_replay_material mat; /* tissue parameters in force (instructor) */
    int32_t depth;
    bool paused;
    uint64_t tick; /* ticks run (= sim step counter) */
    double period_ns;
    uint64_t base_ns, base_tick; /* tick base_tick was due at base_ns */
    double max_push;       /* longest push a probe imposes [m]; INFINITY: none */
    uint64_t push_limited; /* probe-ticks whose push was shortened to max_push */
    uint64_t unstable, missed_ticks;
    uint64_t resets; /* srv_reset calls: a failed step's or the instructor's */
    ftm_contact *contacts;
    ftm_wire_reaction *reactions;
    int32_t contact_cap;
    int32_t depth_lo, depth_hi; /* depths used by the ticks run */
    /* step time: whole run, recent, per metrics bucket */
    double step_ns_total, step_ns_max, step_sum_ns;
    uint64_t step_bucket[FTM_METRICS_STEP_BUCKETS + 1], step_count;
    uint32_t period_hist[TICK_HIST_BINS], late_hist[TICK_HIST_BINS];
    /* a tick's work (collision, step, frame), in every tick and in the ticks
     * with a probe in contact: what the tick budget must hold */
    uint32_t work_hist[WORK_HIST_BINS], work_contact_hist[WORK_HIST_BINS];
    uint64_t last_tick_ns;
    FILE *reactions_csv; /* --reactions: one line per probe reaction */
} srv_tick;

/* ---- publish.c ---- */

#define PUB_RING 1024

typedef struct srv_publish {
    ftm_wire_transport *wire; /* NULL without DDS: encoded and counted only */
    bool replaying;    /* --replay: a frame for every tick, for the check */
    bool tissue_frame; /* the next frame carries the tissue: it changed */
    /* what replicas hold: the last published frame's contacts and depth */
    int32_t pub_n, pub_depth;
    uint64_t pub_tick, pub_ns;
    bool published_any;
    bool keyframe_due;
    uint64_t next_keyframe_ns;
    uint64_t told_ns; /* the last status published at once (tell_now) */
    /* published frames (time, tick), newest last: what a participant can
     * have applied by now (lag_of) */
    uint64_t ring_ns[PUB_RING], ring_tick[PUB_RING];
    uint64_t ring_n;
    uint64_t frames, heartbeats, idle_ticks, keyframes, bytes_frames, bytes_keyframes;
    uint64_t publish_fail;
} srv_publish;

/* ---- period.c ---- */

typedef struct srv_period {
    ftm_depth_ctl ctl;
    uint64_t next_ns, floor_log_ns;
    uint64_t prev_tick, prev_missed, prev_rexmit, prev_throttle, prev_sent;
    double prev_step_sum, step_recent_ns;
    uint64_t rate_tick[10], rate_ns[10]; /* the last second, per control period */
    int rate_i;
    ftm_metrics *metrics;
    ftm_metrics_snapshot snap; /* built here, copied to the HTTP thread */
    FILE *control_csv;
} srv_period;

/* ---- recording.c ---- */

typedef struct srv_rec {
    ftm_record_writer *w;
    bool failed;            /* the recording stopped on a write error, for good */
    uint64_t errors;        /* write errors (ftm_record_errors_total) */
    uint64_t stop_tick;     /* where it stopped: the session's tick, */
    double stop_s;          /* its time into the session [s], */
    uint64_t kept, kept_tick; /* the bytes the file kept and its last tick, */
    char why[FTM_ERROR_MESSAGE_MAX]; /* and the error */
    char path[1024];        /* --record-dir: this run's recording */
    ftm_report report;      /* what each participant did (--report, the closing log) */
    uint64_t tissue_changes;
    /* the lesson, when it spans several files (FILE, FILE.1, ...) */
    char lesson[1024];        /* its first file (--resume, or this run's after a gap) */
    char seg_path[1100];      /* the file this run records to now */
    uint64_t lesson_start_ns; /* its start: its first server's (announced) */
    uint32_t segment;         /* the number of the file this run records to next */
    uint64_t resumed_tick;    /* --resume: the tick it went on from */
    uint64_t previous_cut;    /* --resume: where a crash cut the lesson's last file; 0 none */
    /* after a write error: a new file once space returns (probed off the
     * tick thread, libuv's thread pool) */
    uv_fs_t statfs_req;
    bool probing;
    bool may_retry;           /* the error was a full disk: space may return */
    uint64_t next_probe_ns, probes, told_ns;
    uint64_t free_bytes;      /* at the last probe */
    uint64_t segments_after_gap;
    uint64_t gap_tick;        /* the last such file: from this tick */
    char gap_file[1100];
    char no_resume_why[256];  /* why recording has not resumed ("" none said) */
} srv_rec;

/* ---- the server ---- */

typedef struct server {
    ftm_server_def o;     /* as given, scene and session resolved */
    FILE *logf;
    uint64_t t_start_ns;
    uint64_t start_unix_ns; /* wall clock at start: announced, so replicas tell a restart */
    ftm_scene *scene;
    const ftm_mesh *mesh;
    uint8_t digest[FTM_REPLAY_DIGEST_SIZE];
    char scene_path[1024]; /* the file the scene came from (its name for a built-in) */
    char replay_scene[FTM_WIRE_NAME_MAX], replay_session[128];
    bool depth_from_frames; /* --replay, --inputs without --depth: the recorded depths */
    uint8_t resume_digest[FTM_REPLAY_DIGEST_SIZE]; /* --resume: the recorded scene's */
    bool log_append;        /* the second set-up after --resume-recent gave up */
    bool resume_if_unended; /* --resume-recent: a lesson that ended is no error, a new one begins */
    srv_parts parts;
    srv_tick tk;
    srv_publish pub;
    srv_period per;
    srv_rec rec;
    /* the loop (server.c) */
    uv_loop_t loop;
    uv_timer_t tick_timer, status_timer, stop_timer;
    uv_signal_t sigint, sigterm;
    bool stopping;
    uint64_t loop_start_ns, stop_ns;
} server;

/* log.c */
void srv_log(server *s, const char *level, const char *fmt, ...) __attribute__((format(printf, 3, 4)));
void srv_log_hook(void *user, ftm_log_level level, const char *message);


/* server_def.c: an output that is an existing directory (opt names it), or NULL */
const char *ftm_server_output_dir(const ftm_server_def *def, const char **opt);

/* participants.c */
participant *srv_find_part(server *s, uint32_t id, bool create);
void srv_release_probes(participant *p);
void srv_lose_probes(server *s, participant *p);
void srv_on_status(server *s, ftm_wire_received *rx);
void srv_on_probe_input(server *s, ftm_wire_received *rx);
void srv_reject(server *s, participant *p, uint32_t id, const char *what, const char *why);
/* whether a message is heard: one process per id, one server per session */
bool srv_admit(server *s, int kind, const ftm_wire_received *rx);
void srv_check_statuses(server *s);

/* commands.c */
void srv_on_control(server *s, ftm_wire_received *rx);

/* tick.c */
int srv_tick_setup(server *s); /* 0, or the exit status */
void srv_tick_free(server *s);
void srv_run_tick(server *s);
int srv_emulate_tick(server *s, const ftm_wire_tick *rec, char *why, size_t why_size);
void srv_reset(server *s, bool publish_now);
void srv_run_due_ticks(server *s);
void srv_log_limits(server *s);
double srv_hist_quantile(const uint32_t *h, double q);
double srv_work_quantile(const uint32_t *h, double q);
uint64_t srv_hist_count(const uint32_t *h, int bins);

/* publish.c */
int srv_send(server *s, const ftm_wire_msg *m, uint64_t *bytes);
void srv_publish_announce(server *s);
void srv_publish_status(server *s, ftm_wire_state state);
void srv_tell_now(server *s);
bool srv_publish_keyframe(server *s);
void srv_publish_frame(server *s, int32_t n, int32_t nreact, bool heartbeat);
/* After a tick: its frame unless it is idle (a heartbeat at least every
 * srv_heartbeat_ticks), and a keyframe when one is due. moved: the step
 * updated nodes. */
void srv_publish_tick(server *s, int32_t n, int32_t nreact, bool moved);
uint64_t srv_heartbeat_ticks(const server *s);
/* The current tick's frame, unless it went out (an unsent tick was idle:
 * no contacts): replicas must reach the tick before what follows. */
void srv_publish_tick_frame(server *s);
int64_t srv_lag_of(const server *s, uint64_t applied);

/* period.c */
/* the depth controller (adaptive or not: its range is announced) */
int srv_period_setup(server *s, ftm_error *err);
/* a session's --control-log and metrics; 0, or 3 after saying why not */
int srv_period_start(server *s);
int srv_period_stop(server *s); /* 0, or 3 if the control log failed */
void srv_metrics_url(const ftm_server_def *o, char *buf, size_t cap);
void srv_control_period(server *s);

/* recording.c */
void srv_record_entry(server *s, bool incoming, int kind, uint32_t sender, const uint8_t *buf,
                      size_t size, bool gone, bool lost);
void srv_record_failed(server *s, const ftm_error *err);
int srv_open_recording(server *s, ftm_error *err);
/* --resume-recent: the newest lesson in --record-dir to resume into s->o.resume, if any */
void srv_pick_recent_lesson(server *s);
/* After a write error, once space has returned: the lesson's next file */
int srv_open_next_file(server *s, ftm_error *err);
int srv_close_recording(server *s);
int srv_finish_report(server *s);
int srv_open_reactions(server *s);
int srv_close_reactions(server *s);

/* offline.c */
int srv_run_offline(server *s);
int srv_replay_inputs(server *s);
int srv_resume_rerun(server *s);

/* check.c */
int srv_check_setup(server *s);

#endif
