/* SPDX-License-Identifier: GPL-3.0-or-later */
/* The instructor's session control (docs/server.md, Roles): pause, resume,
 * reset, depth limits and tissue parameters, each answered with a
 * ControlReply to its issuer (docs/protocol.md). */
#include "rooms.h"

#include <inttypes.h>
#include <stdarg.h>
#include <string.h>

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
    r->tick = s->tk.tick;
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
    srv_send(s, &m, NULL);
}

/* A refused command: logged (rate-limited, as every rejection) and told to
 * its issuer. */
static void refuse(server *s, participant *p, const ftm_wire_received *rx, const char *what,
                   const char *why)
{
    srv_reject(s, p, rx->sender, what, why);
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
    ftm_wire_tissue before = ftm_replay_tissue_now(&s->tk.mat);
    if (ftm_replay_tissue_equal(&before, t)) {
        reply(s, sender, id, FTM_WIRE_OUTCOME_APPLIED, "already in force");
        return;
    }
    /* the stable range (session/tissue.h): more substeps than it allows
     * would slow the server and every replica on every tick */
    char why[FTM_WIRE_REASON_MAX];
    ftm_tissue_range range;
    ftm_error cerr = {0, ""};
    int crc = ftm_replay_tissue_check(&s->tk.mat, s->tk.sim, t, &range, why, sizeof why, &cerr);
    if (crc) {
        refuse(s, p, rx, "tissue parameters", crc == FTM_ERANGE ? why : cerr.message);
        return;
    }
    /* harmless if the change is then refused: a heartbeat */
    srv_publish_tick_frame(s);
    uint64_t t0 = srv_now();
    ftm_error err = {0, ""};
    if (ftm_replay_set_tissue(&s->tk.mat, s->tk.sim, t, &err)) {
        /* "sim set mesh: the material's critical time step ... is too short ..." */
        const char *cause = strncmp(err.message, "sim set mesh: ", 14) == 0 ? err.message + 14
                                                                            : err.message;
        refuse(s, p, rx, "tissue parameters", cause);
        return;
    }
    double ms = (double)(srv_now() - t0) * 1e-6;
    srv_log(s, "info",
            "tissue from tick %" PRIu64 " (instructor %u): stiffness %g N/m (was %g), damping %g N s/m "
            "(was %g), node mass %g kg (was %g), axis scale %g %g %g; material built in %.2f ms",
            s->tk.tick + 1, sender, t->stiffness, before.stiffness, t->node_damping, before.node_damping,
            t->node_mass, before.node_mass, t->axis_scale.x, t->axis_scale.y, t->axis_scale.z, ms);
    s->pub.tissue_frame = true;
    s->rec.tissue_changes++;
    char what[128] = ""; /* (the event keeps what fits its detail) */
    tissue_change_text(&before, t, what, sizeof what);
    ftm_report_event_add(&s->rec.report, s->tk.tick, sender, "tissue", "%s", what);
    srv_publish_announce(s);
    if (t->node_damping < range.damping_bound) /* applied, but say so (docs/protocol.md) */
        reply(s, sender, id, FTM_WIRE_OUTCOME_APPLIED,
              "damping below the layer update's bound %.3g N s/m: may slowly gain energy",
              range.damping_bound);
    else
        reply(s, sender, id, FTM_WIRE_OUTCOME_APPLIED, "%s", "");
}

void srv_on_control(server *s, ftm_wire_received *rx)
{
    participant *p = srv_find_part(s, rx->sender, false);
    const ftm_wire_control *c = &rx->msg.u.control;
    if (!p || p->role == 0)
        { refuse(s, NULL, rx, "session control", "unknown participant (no status yet)"); return; }
    if (p->role != FTM_WIRE_ROLE_INSTRUCTOR)
        { refuse(s, p, rx, "session control", "only the instructor controls the session"); return; }
    switch (c->command) {
    case FTM_WIRE_CMD_PAUSE:
        if (!s->tk.paused) {
            s->tk.paused = true;
            srv_log(s, "info", "paused at tick %" PRIu64 " by instructor %u", s->tk.tick, rx->sender);
            ftm_report_event_add(&s->rec.report, s->tk.tick, rx->sender, "pause", "%s", "");
            srv_publish_announce(s);
            reply(s, rx->sender, c->command_id, FTM_WIRE_OUTCOME_APPLIED, "%s", "");
        } else {
            reply(s, rx->sender, c->command_id, FTM_WIRE_OUTCOME_APPLIED, "already paused");
        }
        break;
    case FTM_WIRE_CMD_RESUME:
        if (s->tk.paused) {
            s->tk.paused = false;
            s->tk.base_ns = srv_now();
            s->tk.base_tick = s->tk.tick;
            srv_log(s, "info", "resumed at tick %" PRIu64 " by instructor %u", s->tk.tick, rx->sender);
            ftm_report_event_add(&s->rec.report, s->tk.tick, rx->sender, "resume", "%s", "");
            srv_publish_announce(s);
            reply(s, rx->sender, c->command_id, FTM_WIRE_OUTCOME_APPLIED, "%s", "");
        } else {
            reply(s, rx->sender, c->command_id, FTM_WIRE_OUTCOME_APPLIED, "was not paused");
        }
        break;
    case FTM_WIRE_CMD_DEPTH_LIMITS: {
        bool changed = false;
        char why[FTM_DEPTH_REASON_MAX];
        ftm_error err = {0, ""};
        if (ftm_depth_ctl_set_limits(&s->per.ctl, c->depth_min, c->depth_max, (int64_t)srv_now(),
                                     &changed, why, sizeof why, &err)) {
            refuse(s, p, rx, "depth limits", err.message);
            break;
        }
        srv_log(s, "info", "depth limits [%d, %d] from instructor %u at tick %" PRIu64,
                (int)c->depth_min, (int)c->depth_max, rx->sender, s->tk.tick);
        if (changed) {
            srv_log(s, "info", "depth %s (tick %" PRIu64 ")", why, s->tk.tick);
            s->tk.depth = s->per.ctl.depth;
        }
        ftm_report_event_add(&s->rec.report, s->tk.tick, rx->sender, "depth limits", "[%d, %d], depth %d",
                             (int)c->depth_min, (int)c->depth_max, (int)s->tk.depth);
        srv_publish_announce(s);
        reply(s, rx->sender, c->command_id, FTM_WIRE_OUTCOME_APPLIED, "depth now %d", (int)s->tk.depth);
        break;
    }
    case FTM_WIRE_CMD_RESET:
        srv_log(s, "info", "reset at tick %" PRIu64 " by instructor %u", s->tk.tick, rx->sender);
        ftm_report_event_add(&s->rec.report, s->tk.tick, rx->sender, "reset", "%s", "");
        srv_reset(s, true);
        reply(s, rx->sender, c->command_id, FTM_WIRE_OUTCOME_APPLIED, "%s", "");
        break;
    case FTM_WIRE_CMD_TISSUE:
        set_tissue(s, p, rx);
        break;
    default:
        refuse(s, p, rx, "session control", "unknown command");
    }
}

