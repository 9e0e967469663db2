/* SPDX-License-Identifier: GPL-3.0-or-later */
/* Every 100 ms (docs/server.md, Adaptive penetration depth): the period's
 * measurements go to the depth controller (depth_ctl.h), the Prometheus
 * snapshot (metrics.h) and --control-log. Runs on the loop thread between
 * ticks, so a new depth applies from the next tick and goes out in its
 * frame. */
#include "rooms.h"

#include <errno.h>
#include <inttypes.h>
#include <string.h>

#define CONTROL_PERIOD_NS 100000000u
#define STATUS_OVERDUE_NS 750000000u /* later than this: lagging at least by its age */
#define REXMIT_FLOOR 8192u           /* bytes per control period, see measure */

int srv_period_setup(server *s, ftm_error *err)
{
    const int32_t depth = s->tk.depth;
    /* adaptive depth between the floor and the scene's calibrated depth */
    int32_t floor = s->o.depth_floor >= 0 ? s->o.depth_floor : depth / 4 > 1 ? depth / 4 : 1;
    if (!s->o.adaptive || floor > depth)
        floor = depth;
    ftm_depth_ctl_def cdef;
    ftm_depth_ctl_default(&cdef, floor, depth, 1e9 / s->o.rate);
    cdef.hold_up_ns = (int64_t)(s->o.depth_hold_up * 1e9);
    return ftm_depth_ctl_init(&s->per.ctl, &cdef, err);
}

/* The metrics' address as a URL: http://127.0.0.1:N/metrics, IPv6 in brackets. */
void srv_metrics_url(const ftm_server_def *o, char *buf, size_t cap)
{
    bool v6 = strchr(o->metrics_addr, ':') != NULL;
    snprintf(buf, cap, "http://%s%s%s:%d/metrics", v6 ? "[" : "", o->metrics_addr, v6 ? "]" : "",
             (int)o->metrics_port);
}

int srv_period_start(server *s)
{
    srv_period *pe = &s->per;
    if (s->o.control_log) {
        if (!(pe->control_csv = fopen(s->o.control_log, "w"))) {
            srv_log(s, "error", "cannot create %s: %s", s->o.control_log, strerror(errno));
            return 3;
        }
        fprintf(pe->control_csv, "time_s,tick,depth,step_ms,missed,worst_lag,worst_participant,"
                                 "backlog,rexmit_ratio,tick_rate_hz\n");
    }
    if (s->o.metrics_port > 0) {
        ftm_error err = {0, ""};
        if (ftm_metrics_start(s->o.metrics_addr, (uint16_t)s->o.metrics_port, &pe->metrics, &err)) {
            srv_log(s, "error", "%s", err.message);
            return 3;
        }
        char url[128];
        srv_metrics_url(&s->o, url, sizeof url);
        srv_log(s, "info", "metrics on %s", url);
    }
    return 0;
}

int srv_period_stop(server *s)
{
    ftm_metrics_stop(s->per.metrics);
    s->per.metrics = NULL;
    int bad = s->per.control_csv && fclose(s->per.control_csv) != 0;
    s->per.control_csv = NULL;
    return bad ? 3 : 0;
}

/* The transport's and the tick's share of the period's input. */
static void measure(server *s, uint64_t now, const ftm_wire_stats *ws, ftm_depth_ctl_input *in)
{
    srv_period *pe = &s->per;
    uint64_t ticks = s->tk.tick - pe->prev_tick, sent = s->pub.bytes_frames + s->pub.bytes_keyframes;
    double step_ns = ticks ? (s->tk.step_sum_ns - pe->prev_step_sum) / (double)ticks : -1.0;
    uint64_t done = ws->published + ws->write_errors;
    uint64_t sent_now = sent - pe->prev_sent > REXMIT_FLOOR ? sent - pe->prev_sent : REXMIT_FLOOR;
    *in = (ftm_depth_ctl_input){
        .now_ns = (int64_t)now,
        .step_ns = step_ns,
        .missed_ticks = s->tk.missed_ticks - pe->prev_missed,
        .backlog = s->pub.frames > done ? (int32_t)(s->pub.frames - done) : 0,
        .throttled = ws->throttle_count - pe->prev_throttle,
        /* the share of the wire traffic that is repair: every matched reader
         * gets its own copy (unicast), and loses its own datagrams. Against
         * at least REXMIT_FLOOR bytes: a few repairs while little is sent
         * (joins, heartbeats) are no backlog */
        .rexmit_ratio = (double)(ws->rexmit_bytes - pe->prev_rexmit) /
                        (double)(sent_now * (uint64_t)(ws->matched > 1 ? ws->matched : 1)),
    };
    if (step_ns >= 0)
        pe->step_recent_ns = step_ns;
    pe->prev_tick = s->tk.tick;
    pe->prev_step_sum = s->tk.step_sum_ns;
    pe->prev_missed = s->tk.missed_ticks;
    pe->prev_throttle = ws->throttle_count;
    pe->prev_rexmit = ws->rexmit_bytes;
    pe->prev_sent = sent;
}

/* Each replaying participant's lag for the controller (parts, returned
 * count), and every participant's for the metrics snapshot. */
static int32_t lags(server *s, uint64_t now, ftm_depth_ctl_part *parts)
{
    ftm_metrics_snapshot *m = &s->per.snap;
    int32_t np = 0;
    for (int i = 0; i < MAX_PARTICIPANTS; i++) {
        participant *p = &s->parts.parts[i];
        if (!p->used || p->silent || p->role == 0 || p->role == FTM_WIRE_ROLE_SERVER)
            continue;
        int64_t lag = p->lag;
        uint64_t age = now - p->last_status_ns;
        if (age > STATUS_OVERDUE_NS) { /* its status is late: it is at least this far behind */
            int64_t late = (int64_t)((double)(age - STATUS_PERIOD_NS) / s->tk.period_ns);
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
    return np;
}

/* The depth for the next ticks, when it adapts (--adaptive 1). */
static void adapt(server *s, uint64_t now, const ftm_depth_ctl_input *in)
{
    if (!s->o.adaptive || s->tk.paused)
        return;
    bool changed = false;
    char why[FTM_DEPTH_REASON_MAX];
    int32_t d = ftm_depth_ctl_update(&s->per.ctl, in, &changed, why, sizeof why);
    if (changed) {
        srv_log(s, "info", "depth %s (tick %" PRIu64 ")", why, s->tk.tick);
        s->tk.depth = d;
    } else if (why[0] && d == s->per.ctl.def.floor && now - s->per.floor_log_ns >= 1000000000u) {
        srv_log(s, "info", "depth %d held at the floor: %s (tick %" PRIu64 ")", (int)d, why,
                s->tk.tick);
        s->per.floor_log_ns = now;
    }
}

/* The tick rate over the last second [Hz]. */
static double tick_rate(server *s, uint64_t now)
{
    srv_period *pe = &s->per;
    pe->rate_tick[pe->rate_i] = s->tk.tick;
    pe->rate_ns[pe->rate_i] = now;
    pe->rate_i = (pe->rate_i + 1) % 10;
    uint64_t t_old = pe->rate_ns[pe->rate_i], k_old = pe->rate_tick[pe->rate_i];
    return t_old && now > t_old ? (double)(s->tk.tick - k_old) * 1e9 / (double)(now - t_old) : 0.0;
}

static void control_log(server *s, uint64_t now, const ftm_depth_ctl_input *in, double rate)
{
    const ftm_depth_ctl_part *worst = NULL;
    for (int32_t i = 0; i < in->nparts; i++)
        if (!worst || in->parts[i].lag > worst->lag)
            worst = &in->parts[i];
    fprintf(s->per.control_csv, "%.3f,%" PRIu64 ",%d,%.4f,%" PRIu64 ",%lld,%u,%d,%.3f,%.1f\n",
            (double)(now - s->t_start_ns) * 1e-9, s->tk.tick, (int)s->tk.depth,
            in->step_ns >= 0 ? in->step_ns * 1e-6 : 0.0, in->missed_ticks,
            worst ? (long long)worst->lag : 0LL, worst ? worst->id : 0u, (int)in->backlog,
            in->rexmit_ratio, rate);
}

/* The rest of the metrics snapshot, handed to the HTTP thread. */
static void metrics(server *s, const ftm_wire_stats *ws, double rate)
{
    ftm_metrics_snapshot *m = &s->per.snap;
    const ftm_depth_ctl *ctl = &s->per.ctl;
    m->tick_rate_target = s->o.rate;
    m->tick_rate = rate;
    m->ticks = s->tk.tick;
    m->missed_ticks = s->tk.missed_ticks;
    m->idle_ticks = s->pub.idle_ticks;
    m->frames = s->pub.frames;
    m->heartbeats = s->pub.heartbeats;
    m->keyframes = s->pub.keyframes;
    m->bytes_frames = s->pub.bytes_frames;
    m->bytes_keyframes = s->pub.bytes_keyframes;
    m->publish_fail = s->pub.publish_fail;
    m->rexmit_bytes = ws->rexmit_bytes;
    m->throttle_count = ws->throttle_count;
    m->depth = s->tk.depth;
    m->depth_min = ctl->def.floor;
    m->depth_max = ctl->def.max;
    m->depth_decreases = ctl->decreases;
    m->depth_increases = ctl->increases;
    m->step_count = s->tk.step_count;
    m->step_sum_s = s->tk.step_sum_ns * 1e-9;
    memcpy(m->step_bucket, s->tk.step_bucket, sizeof m->step_bucket);
    m->step_last_period_s = s->per.step_recent_ns * 1e-9;
    m->push_limited = s->tk.push_limited;
    m->unstable_ticks = s->tk.unstable;
    for (int i = 0; i < MAX_PARTICIPANTS; i++)
        m->inputs_rejected += s->parts.parts[i].used ? s->parts.parts[i].rejected : 0;
    m->record_bytes = s->rec.w ? ftm_record_bytes(s->rec.w) : s->rec.kept;
    m->record_ok = !s->rec.failed || s->rec.w; /* recording now (again: a new file) */
    m->record_files = s->rec.segments_after_gap;
    m->record_free_bytes = s->rec.free_bytes;
    m->record_errors = s->rec.errors;
    ftm_metrics_update(s->per.metrics, m);
}

void srv_control_period(server *s)
{
    const uint64_t now = srv_now();
    if (now < s->per.next_ns)
        return;
    s->per.next_ns = now + CONTROL_PERIOD_NS;
    ftm_wire_stats ws;
    memset(&ws, 0, sizeof ws);
    ftm_wire_get_stats(s->pub.wire, FTM_WIRE_TICK, &ws, NULL);
    ftm_depth_ctl_input in;
    measure(s, now, &ws, &in);
    ftm_depth_ctl_part parts[MAX_PARTICIPANTS];
    memset(&s->per.snap, 0, sizeof s->per.snap);
    in.nparts = lags(s, now, parts);
    in.parts = parts;
    adapt(s, now, &in);
    const double rate = tick_rate(s, now);
    if (s->per.control_csv)
        control_log(s, now, &in, rate);
    if (s->per.metrics)
        metrics(s, &ws, rate);
}
