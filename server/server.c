/* SPDX-License-Identifier: GPL-3.0-or-later */
/* ftm-server: the authoritative session server (docs/server.md).
 *
 * This file keeps the server's lifetime: set-up from its definition, the
 * libuv loop and its end; the rooms it runs are in rooms.h. One
 * thread for everything but DDS writes (ftm_wire's publishing thread does
 * those): a 1 ms timer runs the ticks that are due by the monotonic clock,
 * after draining received status, probe input and session control without
 * waiting. Each tick: probe HIPs -> contacts (point collision with the
 * deformed surface, collide.h) -> ftm_replay_step (the same call sequence
 * every replica makes) -> tick frame, unless the scene is idle (then a
 * heartbeat frame every 100 ms). */
#define _GNU_SOURCE /* sched_getcpu, pthread_setaffinity_np */
#include "record_replay.h"
#include "rooms.h"

#include "ftm/options.h"

#include <errno.h>
#include <inttypes.h>
#include <math.h>
#include <pthread.h>
#include <sched.h>
#include <signal.h>
#include <stdarg.h>
#include <stdlib.h>
#include <string.h>

/* ---- the loop ------------------------------------------------------------------------ */

static void shutdown_loop(server *s, const char *why);

/* What arrived since the last turn, each kind at most 256: statuses,
 * session control, probe input. What is heard (srv_admit) is recorded, then
 * handled, as --inputs and --replay handle it again (offline.c). */
static void drain(server *s)
{
    static const int kinds[3] = {FTM_WIRE_STATUS, FTM_WIRE_CONTROL, FTM_WIRE_PROBE_INPUT};
    for (int k = 0; k < 3; k++)
        for (int n = 0; n < 256; n++) {
            ftm_wire_received rx;
            if (ftm_wire_receive(s->pub.wire, kinds[k], &rx, 0, NULL) != FTM_OK)
                break;
            if (!srv_admit(s, kinds[k], &rx)) {
                ftm_wire_received_free(&rx);
                continue;
            }
            if (s->rec.w) { /* re-encoded from the decoded message */
                uint8_t *buf = NULL;
                size_t size = 0;
                if (rx.gone || ftm_wire_encode(&rx.msg, &buf, &size, NULL) == FTM_OK)
                    srv_record_entry(s, true, kinds[k], rx.sender, buf, size, rx.gone, false);
                free(buf);
            }
            if (kinds[k] == FTM_WIRE_STATUS)
                srv_on_status(s, &rx);
            else if (kinds[k] == FTM_WIRE_CONTROL)
                srv_on_control(s, &rx);
            else
                srv_on_probe_input(s, &rx);
            ftm_wire_received_free(&rx);
        }
}

/* libuv's thread pool has looked at the recording's file system. */
static void on_statfs(uv_fs_t *req)
{
    server *s = req->data;
    srv_rec *r = &s->rec;
    r->probing = false;
    const uv_statfs_t *st = req->result == 0 ? req->ptr : NULL;
    char why[sizeof r->no_resume_why] = "";
    if (!st) {
        snprintf(why, sizeof why, "cannot look at the space on %.180s: %s", r->lesson,
                 uv_strerror((int)req->result));
    } else {
        r->free_bytes = st->f_bavail * st->f_bsize;
        if (r->free_bytes < FTM_RECORD_RESUME_FREE)
            snprintf(why, sizeof why, "%" PRIu64 " bytes free where it records, it waits for %u",
                     r->free_bytes, (unsigned)FTM_RECORD_RESUME_FREE);
    }
    uv_fs_req_cleanup(req);
    if (s->stopping || r->w)
        return;
    if (!why[0]) {
        ftm_error err = {0, ""};
        if (srv_open_next_file(s, &err) == 0) {
            srv_log(s, "info", "recording resumed at tick %" PRIu64 " into %s (space has "
                    "returned: %" PRIu64 " bytes free); ticks %" PRIu64 "..%" PRIu64 " are not "
                    "in the lesson's recording", s->tk.tick, r->seg_path, r->free_bytes,
                    r->kept_tick, s->tk.tick);
            /* the file begins as a session does: what a replay restores */
            srv_publish_announce(s);
            srv_publish_keyframe(s);
            srv_publish_status(s, FTM_WIRE_STATE_SYNCED);
            return;
        }
        snprintf(why, sizeof why, "%.250s", err.message);
    }
    /* said when the reason changes, else once a minute */
    const uint64_t now = srv_now();
    if (strcmp(why, r->no_resume_why) != 0 &&
        (strcspn(why, "0123456789") != strcspn(r->no_resume_why, "0123456789") ||
         strncmp(why, r->no_resume_why, strcspn(why, "0123456789")) != 0 ||
         now - r->told_ns >= 60000000000ull)) {
        srv_log(s, "warn", "recording not resumed yet: %s", why);
        r->told_ns = now;
    }
    snprintf(r->no_resume_why, sizeof r->no_resume_why, "%s", why);
}

/* After a full disk: whether space has returned, once a second, looked at
 * on libuv's thread pool (statfs), off the tick thread. */
static void record_retry(server *s)
{
    srv_rec *r = &s->rec;
    const uint64_t now = srv_now();
    if (!r->failed || !r->may_retry || r->w || r->probing || s->stopping || now < r->next_probe_ns ||
        !s->loop_start_ns)
        return;
    r->next_probe_ns = now + 1000000000u; /* once a second */
    char dir[sizeof r->lesson];
    snprintf(dir, sizeof dir, "%s", r->lesson);
    char *slash = strrchr(dir, '/');
    if (slash)
        slash[slash == dir] = '\0';
    else
        snprintf(dir, sizeof dir, ".");
    r->statfs_req.data = s;
    if (uv_fs_statfs(&s->loop, &r->statfs_req, dir, on_statfs) == 0) {
        r->probing = true;
        r->probes++;
    }
}

static void on_tick_timer(uv_timer_t *h)
{
    server *s = h->data;
    if (s->stopping)
        return;
    drain(s);
    if (s->parts.displaced) {
        shutdown_loop(s, "another server serves the session");
        return;
    }
    srv_control_period(s);
    if (!s->tk.paused)
        srv_run_due_ticks(s);
    /* a chunk of the recording out once it spans 100 ms, also when no entry follows */
    ftm_error err = {0, ""};
    if (s->rec.w && ftm_record_tick(s->rec.w, srv_now() - s->t_start_ns, &err))
        srv_record_failed(s, &err);
}

static void on_status_timer(uv_timer_t *h)
{
    server *s = h->data;
    srv_publish_status(s, FTM_WIRE_STATE_SYNCED);
    /* the recording reaches the file at least every 0.5 s (chunks go out
     * at 100 ms, on the tick timer; this is the backstop): a server
     * killed or crashed leaves whole chunks up to about then */
    ftm_error err = {0, ""};
    if (s->rec.w && ftm_record_flush(s->rec.w, &err))
        srv_record_failed(s, &err);
    record_retry(s); /* after a full disk: space back? (looked at off this thread) */
    srv_check_statuses(s);
}

static void shutdown_loop(server *s, const char *why)
{
    if (s->stopping)
        return;
    s->stopping = true;
    s->stop_ns = srv_now();
    srv_log(s, "info", "shutting down (%s) at tick %" PRIu64, why, s->tk.tick);
    /* replicas end on the final state: a frame for the last tick */
    srv_publish_tick_frame(s);
    srv_publish_status(s, FTM_WIRE_STATE_LEAVING);
    ftm_error err = {0, ""};
    if (ftm_wire_flush(s->pub.wire, 2000000000LL, &err))
        srv_log(s, "warn", "flush: %s", err.message);
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
    shutdown_loop(h->data, signum == SIGINT ? "SIGINT" : "SIGTERM");
}

static void on_stop_timer(uv_timer_t *h) { shutdown_loop(h->data, "duration reached"); }

/* The loop of this server (a loop of its own, not libuv's default one)
 * until SIGINT, SIGTERM, --duration or another server stops it. */
static int run_loop(server *s)
{
    if (uv_loop_init(&s->loop)) {
        srv_log(s, "error", "cannot make an event loop");
        return 3;
    }
    uv_timer_init(&s->loop, &s->tick_timer);
    uv_timer_init(&s->loop, &s->status_timer);
    uv_timer_init(&s->loop, &s->stop_timer);
    uv_signal_init(&s->loop, &s->sigint);
    uv_signal_init(&s->loop, &s->sigterm);
    s->tick_timer.data = s->status_timer.data = s->stop_timer.data = s;
    s->sigint.data = s->sigterm.data = s;
    s->tk.base_ns = srv_now();
    s->tk.base_tick = s->tk.tick; /* 0, or where a resumed lesson goes on */
    s->loop_start_ns = s->tk.base_ns;
    uv_timer_start(&s->tick_timer, on_tick_timer, 1, 1);
    uv_timer_start(&s->status_timer, on_status_timer, 500, 500);
    if (s->o.duration > 0)
        uv_timer_start(&s->stop_timer, on_stop_timer, (uint64_t)(s->o.duration * 1000.0), 0);
    uv_signal_start(&s->sigint, on_signal, SIGINT);
    uv_signal_start(&s->sigterm, on_signal, SIGTERM);
    uv_run(&s->loop, UV_RUN_DEFAULT);
    uv_loop_close(&s->loop);
    return 0;
}

/* ---- set-up ------------------------------------------------------------------------- */

/* --replay, --inputs: the session's settings from the recording. Returns
 * 0, or the exit status 1. */
static int settings_from_recording(server *s)
{
    const char *path = s->o.replay ? s->o.replay : s->o.inputs ? s->o.inputs : s->o.resume;
    const char *mode = s->o.replay ? "--replay" : s->o.inputs ? "--inputs" : "--resume";
    ftm_record_header rh;
    ftm_record_reader *rr = NULL;
    ftm_error err = {0, ""};
    if (ftm_record_open(path, &rh, &rr, &err)) {
        fprintf(stderr, "ftm-server %s: %s\n", mode, err.message);
        return s->o.resume ? 3 : 1;
    }
    ftm_record_close_reader(rr);
    if (s->o.resume) { /* the lesson goes on as it was, but for what a session chooses */
        if (rh.arithmetic != ftm_arithmetic_revision()) {
            fprintf(stderr, "ftm-server --resume: %s: recorded by a physics core of arithmetic "
                    "revision %u, this build's is %u: it cannot go on here\n", path,
                    (unsigned)rh.arithmetic, (unsigned)ftm_arithmetic_revision());
            return 3;
        }
        memcpy(s->resume_digest, rh.digest, sizeof s->resume_digest);
    }
    if (!s->o.scene) {
        snprintf(s->replay_scene, sizeof s->replay_scene, "%s", rh.scene_id);
        s->o.scene = s->replay_scene;
    }
    if (!s->o.session && rh.session[0]) { /* the report names it */
        snprintf(s->replay_session, sizeof s->replay_session, "%s", rh.session);
        s->o.session = s->replay_session;
    }
    s->o.rate = rh.tick_rate_hz;
    if (s->o.resume) {
        s->o.depth = rh.depth_max;
        s->o.max_penetration = rh.max_penetration > 0 ? rh.max_penetration : INFINITY;
        s->depth_from_frames = true; /* while it is re-run */
        return 0;
    }
    /* --inputs may try another depth or push limit; --replay must not */
    s->depth_from_frames = s->o.replay || s->o.depth < 0;
    if (s->depth_from_frames)
        s->o.depth = rh.depth_max;
    /* the recording's limit; none in recordings made before there was one */
    if (s->o.replay || !(s->o.max_penetration > 0))
        s->o.max_penetration = rh.max_penetration > 0 ? rh.max_penetration : INFINITY;
    s->o.adaptive = 0;
    s->o.depth_floor = -1;
    return 0;
}

/* The log file, the scene, the simulation. Returns 0 or the exit status. */
static int setup(server *s)
{
    s->t_start_ns = srv_now();
    s->start_unix_ns = (uint64_t)ftm_clock_real_ns();
    if (s->o.log_path && !(s->logf = fopen(s->o.log_path, s->log_append ? "a" : "w"))) {
        fprintf(stderr, "ftm-server: cannot open %s: %s\n", s->o.log_path, strerror(errno));
        return 3;
    }
    if (s->o.resume_recent > 0 && !s->o.resume && !s->o.check)
        srv_pick_recent_lesson(s);
    if (s->o.replay || s->o.inputs || s->o.resume) {
        int rc = settings_from_recording(s);
        if (rc)
            return rc;
    }
    if (!s->o.scene)
        s->o.scene = "default";
    if (!s->o.session)
        s->o.session = "ftm";
    ftm_error err = {0, ""};
    if (ftm_wire_open_scene(s->o.scene, &s->scene, s->scene_path, sizeof s->scene_path, &err)) {
        srv_log(s, "error", "%s", err.message);
        return 3;
    }
    if (strcmp(s->scene_path, s->o.scene) != 0)
        srv_log(s, "info", "scene '%s': %s", s->o.scene, s->scene_path);
    s->mesh = ftm_scene_mesh(s->scene);
    if (ftm_replay_scene_digest(s->scene, s->digest)) {
        srv_log(s, "error", "scene digest: out of memory");
        return 3;
    }
    if (s->o.resume && memcmp(s->digest, s->resume_digest, sizeof s->digest) != 0) {
        srv_log(s, "error", "--resume %s: scene '%s' differs from the recorded one (content "
                "digest)", s->o.resume, s->o.scene);
        return 3;
    }
    int rc = srv_tick_setup(s);
    if (rc == 0 && srv_period_setup(s, &err)) {
        srv_log(s, "error", "%s", err.message);
        rc = 2;
    }
    return rc;
}

/* --offline, --inputs, --replay's second pass: no DDS, no clock. */
static int run_without_dds(server *s)
{
    int rc = 0;
    if (s->o.inputs) { /* as a session starts: announcement, the rest state */
        ftm_error err = {0, ""};
        if (s->o.record && srv_open_recording(s, &err)) {
            srv_log(s, "error", "%s", err.message);
            rc = 3;
        }
        srv_publish_announce(s);
        srv_publish_keyframe(s);
    }
    if (rc == 0)
        rc = s->o.offline_ticks > 0 ? srv_run_offline(s) : srv_replay_inputs(s);
    if (rc == 0)
        rc = srv_finish_report(s);
    int rc_rec = srv_close_recording(s);
    return rc ? rc : rc_rec;
}

static int open_transport(server *s)
{
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
    wd.log = srv_log_hook;
    wd.log_user = s;
    /* one above the tick thread: a queued frame goes out at once, not when the
     * tick has finished the rest of its work */
    wd.publisher_priority = s->o.rt_priority > 0 ? s->o.rt_priority + 1 : 0;
    ftm_error err = {0, ""};
    if (ftm_wire_transport_create(&wd, &s->pub.wire, &err)) {
        srv_log(s, "error", "%s", err.message);
        return 3;
    }
    return 0;
}

/* The tick loop (this thread) and the frames' hand-off: a tick due or a
 * frame queued runs as soon as a core is free, ahead of ordinary work on the
 * host; they sleep between ticks. Set last, so that threads made before
 * (DDS, metrics) keep default scheduling. Both on one CPU: the publishing
 * thread, one level up, takes a queued frame by a context switch, without
 * waking another core. Pinned, neither can move away from a busier
 * real-time thread on that CPU: --rt-cpu any leaves them to the scheduler,
 * --rt-cpu N puts them on a CPU kept for them (isolcpus, a cpuset). */
static void set_realtime(server *s)
{
    struct sched_param sp = {.sched_priority = s->o.rt_priority};
    int e = pthread_setschedparam(pthread_self(), SCHED_FIFO, &sp);
    if (e) {
        srv_log(s, "info", "real-time scheduling not permitted (%s): default scheduling",
                strerror(e));
        return;
    }
    const int want = s->o.rt_cpu;
    int cpu = want == FTM_SERVER_RT_CPU_START ? sched_getcpu() : want;
    cpu_set_t was, set;
    CPU_ZERO(&set);
    if (cpu >= 0)
        CPU_SET(cpu, &set);
    char where[96] = ", on no CPU in particular (--rt-cpu any)";
    ftm_error err = {0, ""};
    if (want == FTM_SERVER_RT_CPU_ANY) {
        cpu = -1;
    } else if (cpu < 0 || pthread_getaffinity_np(pthread_self(), sizeof was, &was)) {
        cpu = -1;
        snprintf(where, sizeof where, ", on no CPU in particular (this one unknown)");
    } else if (pthread_setaffinity_np(pthread_self(), sizeof set, &set) ||
               ftm_wire_pin_publisher(s->pub.wire, cpu, &err)) {
        /* back to the CPUs the server was given (taskset, cgroup) */
        pthread_setaffinity_np(pthread_self(), sizeof was, &was);
        snprintf(where, sizeof where, ", on no CPU in particular (cpu %d not permitted)", cpu);
        cpu = -1;
    }
    if (cpu >= 0)
        snprintf(where, sizeof where, ", both on cpu %d", cpu);
    srv_log(s, want >= 0 && cpu < 0 ? "warn" : "info",
            "tick thread SCHED_FIFO priority %d, publishing thread %d%s", (int)s->o.rt_priority,
            (int)s->o.rt_priority + 1, where);
}

/* What a session leaves on stdout and in the log when its loop ends. */
static void closing_lines(server *s)
{
    const srv_tick *tk = &s->tk;
    const srv_publish *pb = &s->pub;
    double run_s = (double)((s->stop_ns ? s->stop_ns : srv_now()) - s->loop_start_ns) * 1e-9;
    ftm_wire_stats ws;
    ftm_wire_get_stats(pb->wire, FTM_WIRE_TICK, &ws, NULL);
    srv_log(s, "info",
            "%" PRIu64 " ticks in %.2f s (%.1f ticks/s), %" PRIu64 " missed; %" PRIu64
            " frames (%" PRIu64 " heartbeats, %" PRIu64 " idle ticks not sent), %.1f bytes/frame, "
            "%.1f bytes/tick; %" PRIu64 " keyframes (%" PRIu64 " bytes); step mean %.1f us max "
            "%.1f us; rexmit %" PRIu64 " bytes",
            tk->tick - s->rec.resumed_tick, run_s, (double)(tk->tick - s->rec.resumed_tick) / run_s,
            tk->missed_ticks, pb->frames,
            pb->heartbeats, pb->idle_ticks,
            pb->frames ? (double)pb->bytes_frames / (double)pb->frames : 0.0,
            tk->tick > s->rec.resumed_tick
                ? (double)pb->bytes_frames / (double)(tk->tick - s->rec.resumed_tick)
                : 0.0,
            pb->keyframes,
            pb->bytes_keyframes,
            tk->tick > s->rec.resumed_tick
                ? tk->step_ns_total / (double)(tk->tick - s->rec.resumed_tick) * 1e-3
                : 0.0,
            tk->step_ns_max * 1e-3, ws.rexmit_bytes);
    srv_log(s, "info",
            "tick period p50 %.2f ms p99 %.2f ms; start after due p50 %.2f ms p99 %.2f ms "
            "(10 us bins)",
            srv_hist_quantile(tk->period_hist, 0.5), srv_hist_quantile(tk->period_hist, 0.99),
            srv_hist_quantile(tk->late_hist, 0.5), srv_hist_quantile(tk->late_hist, 0.99));
    srv_log(s, "info",
            "tick work p50 %.0f us p99 %.0f us over %" PRIu64 " ticks; with a probe in contact "
            "p50 %.0f us p99 %.0f us over %" PRIu64 " ticks (1 us bins)",
            srv_work_quantile(tk->work_hist, 0.5), srv_work_quantile(tk->work_hist, 0.99),
            srv_hist_count(tk->work_hist, WORK_HIST_BINS),
            srv_work_quantile(tk->work_contact_hist, 0.5),
            srv_work_quantile(tk->work_contact_hist, 0.99),
            srv_hist_count(tk->work_contact_hist, WORK_HIST_BINS));
    printf("ftm-server: final tick %" PRIu64 " hash %016" PRIx64 "\n", tk->tick,
           ftm_sim_hash(tk->sim));
    fflush(stdout);
    srv_log(s, "info", "depth %d at the end, range [%d, %d]: %" PRIu64 " decreases, %" PRIu64
            " increases; ticks run at depths %d..%d", (int)tk->depth, (int)s->per.ctl.def.floor,
            (int)s->per.ctl.def.max, s->per.ctl.decreases, s->per.ctl.increases,
            (int)tk->depth_lo, (int)tk->depth_hi);
    srv_log_limits(s);
}

/* A session over DDS, from the transport to its end. */
static int run_session(server *s)
{
    int rc = open_transport(s);
    if (rc)
        return rc;
    if (s->o.check)
        return srv_check_setup(s);
    if ((rc = srv_period_start(s)))
        return rc;
    /* last of what may fail: a start that fails (a metrics port in use)
     * leaves no recording of a session that never ran in --record-dir */
    ftm_error err = {0, ""};
    if ((s->o.record || s->o.record_dir || s->o.resume) && srv_open_recording(s, &err)) {
        srv_log(s, "error", "%s", err.message);
        return 3;
    }
    srv_publish_announce(s);
    srv_publish_keyframe(s); /* the rest state at tick 0, for joiners */
    srv_publish_status(s, FTM_WIRE_STATE_SYNCED);
    s->pub.next_keyframe_ns = srv_now() + (uint64_t)(s->o.keyframe_every * 1e9);
    srv_log(s, "info", "session '%s' on domain %u: %.0f Hz, depth %d, keyframe every %g s",
            s->o.session, s->o.domain, s->o.rate, (int)s->tk.depth, s->o.keyframe_every);
    srv_log(s, "info", "adaptive depth %s: range [%d, %d], tick budget %.3f ms",
            s->o.adaptive ? "on" : "off", (int)s->per.ctl.def.floor, (int)s->per.ctl.def.max,
            s->per.ctl.def.budget_ns * 1e-6);
    if (s->o.rt_priority > 0)
        set_realtime(s);
    if ((rc = run_loop(s)))
        return rc;
    closing_lines(s);
    rc = srv_finish_report(s);
    if (s->parts.displaced)
        rc = 3;
    int rc_rec = srv_close_recording(s);
    int rc_per = srv_period_stop(s);
    return rc ? rc : rc_rec ? rc_rec : rc_per;
}

/* Everything a run set up, whichever way it ends (what was never made is
 * NULL). */
static void teardown(server *s)
{
    if (s->rec.w)
        ftm_record_close(s->rec.w, NULL);
    srv_period_stop(s);
    ftm_wire_transport_destroy(s->pub.wire);
    srv_tick_free(s);
    ftm_scene_destroy(s->scene);
    ftm_report_free(&s->rec.report);
    if (s->logf)
        fclose(s->logf);
}

int ftm_server_run(const ftm_server_def *def)
{
    /* over a file size limit (ulimit -f, systemd's LimitFSIZE=) a write must
     * fail with EFBIG, which stops the recording or the report with a logged
     * error, rather than SIGXFSZ killing the session */
    signal(SIGXFSZ, SIG_IGN);
    const char *opt = NULL, *dir = ftm_server_output_dir(def, &opt);
    if (dir && !def->check) { /* (--check says so with the rest) */
        fprintf(stderr, "ftm-server: %s %s is a directory: give a file name\n", opt, dir);
        return 3;
    }
    if (def->replay) { /* first the frames alone, then the inputs (srv_replay_inputs) */
        int rc = ftm_server_replay(def->replay, def->scene, def->upto_damage);
        if (rc)
            return rc;
    }
    server *s = calloc(1, sizeof *s); /* all of this server's state: none is global */
    if (!s) {
        fprintf(stderr, "ftm-server: out of memory\n");
        return 3;
    }
    s->o = *def;
    int rc = setup(s);
    if (rc == 0 && s->o.resume) {
        rc = srv_resume_rerun(s); /* says why not */
        if (rc == 4) { /* the fast path gave up (said why): the whole lesson */
            teardown(s);
            memset(s, 0, sizeof *s);
            s->o = *def;
            s->o.resume_full = true;
            s->log_append = true;
            rc = setup(s);
            if (rc == 0)
                rc = srv_resume_rerun(s);
        }
        if (rc && s->resume_if_unended) { /* --resume-recent: a new lesson instead */
            srv_log(s, "warn", "--resume-recent: %s not resumed: a new lesson", s->o.resume);
            teardown(s);
            memset(s, 0, sizeof *s);
            s->o = *def;
            s->o.resume_recent = 0;
            s->log_append = true; /* (the lines above stay) */
            rc = setup(s);
        }
    }
    if (rc == 0)
        rc = s->o.offline_ticks > 0 || s->o.replay || s->o.inputs ? run_without_dds(s)
                                                                 : run_session(s);
    teardown(s);
    free(s);
    return rc;
}

int ftm_server_main(int argc, char **argv)
{
    ftm_server_def def = ftm_default_server_def();
    int rc = ftm_server_parse_args(argc, argv, &def);
    if (rc != FTM_OPTIONS_OK)
        return rc == FTM_OPTIONS_HELP ? 0 : 2;
    return ftm_server_run(&def);
}
