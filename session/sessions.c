/* SPDX-License-Identifier: GPL-3.0-or-later */
/* Finding a domain's sessions: see sessions.h. */
#include "sessions.h"

#include <stdlib.h>
#include <string.h>
#include <time.h>

ftm_sessions_def ftm_default_sessions_def(void)
{
    return (ftm_sessions_def){.seconds = 1.0};
}

static int64_t mono_ns(void)
{
    struct timespec ts;
    clock_gettime(CLOCK_MONOTONIC, &ts);
    return (int64_t)ts.tv_sec * 1000000000 + ts.tv_nsec;
}

/* The session's entry, made when new (NULL when out is full). */
static ftm_session_seen *entry(ftm_session_seen *out, int32_t cap, int32_t *n, const char *name)
{
    for (int32_t i = 0; i < *n; i++)
        if (strcmp(out[i].name, name) == 0)
            return &out[i];
    if (*n == cap)
        return NULL;
    ftm_session_seen *s = &out[(*n)++];
    memset(s, 0, sizeof *s);
    snprintf(s->name, sizeof s->name, "%s", name);
    return s;
}

/* Participants per session, each (sender, origin) once, gone ones dropped. */
typedef struct heard {
    char session[64];
    uint32_t sender;
    uint64_t origin;
    ftm_wire_role role;
    uint64_t tick; /* its last applied tick */
    bool gone;
} heard;

static int by_name(const void *a, const void *b)
{
    return strcmp(((const ftm_session_seen *)a)->name, ((const ftm_session_seen *)b)->name);
}

int ftm_sessions_find(const ftm_sessions_def *def, ftm_session_seen *out, int32_t cap,
                      int32_t *count, ftm_error *err)
{
    *count = 0;
    ftm_wire_transport_def td = {
        .config = def->dds_config,
        .security = def->dds_security,
        .role = 0, /* any identity: it writes nothing */
        .domain_id = def->domain,
        .session = "ftm-sessions",
        .any_session = true,
        .participant_id = def->participant_id ? def->participant_id : 0xfffffff0u,
        .subscribe = FTM_WIRE_KIND_BIT(FTM_WIRE_ANNOUNCE) | FTM_WIRE_KIND_BIT(FTM_WIRE_STATUS),
        .log = def->log,
        .log_user = def->log_user,
    };
    ftm_wire_transport *t = NULL;
    int rc = ftm_wire_transport_create(&td, &t, err);
    if (rc)
        return rc;
    enum { HEARD_MAX = 1024 };
    heard *h = calloc(HEARD_MAX, sizeof *h);
    int32_t nh = 0;
    if (!h) {
        ftm_wire_transport_destroy(t);
        return ftm_error_set(err, FTM_ENOMEM, "sessions: out of memory");
    }
    const double secs = def->seconds > 0 ? def->seconds : 1.0;
    const int64_t end = mono_ns() + (int64_t)(secs * 1e9);
    for (int64_t now = mono_ns(); now < end; now = mono_ns()) {
        ftm_wire_received rx;
        /* both kinds, a slice each, until the time is up */
        for (int k = 0; k < 2; k++) {
            int kind = k ? FTM_WIRE_STATUS : FTM_WIRE_ANNOUNCE;
            while (ftm_wire_receive(t, kind, &rx, k ? 20000000 : 0, NULL) == FTM_OK) {
                if (kind == FTM_WIRE_ANNOUNCE) {
                    ftm_session_seen *s = entry(out, cap, count, rx.session);
                    if (s) {
                        const ftm_wire_announce *a = &rx.msg.u.announce;
                        s->announced = true;
                        snprintf(s->scene, sizeof s->scene, "%s", a->scene_id);
                        s->server_id = rx.sender;
                        s->server_start_ns = a->server_start_ns;
                        s->tick = a->tick;
                        s->tick_rate_hz = a->tick_rate_hz;
                        s->paused = a->paused;
                    }
                } else {
                    int32_t i = 0;
                    while (i < nh && !(h[i].sender == rx.sender && h[i].origin == rx.origin &&
                                       strcmp(h[i].session, rx.session) == 0))
                        i++;
                    if (i == nh && nh < HEARD_MAX && !rx.gone) {
                        snprintf(h[nh].session, sizeof h[nh].session, "%s", rx.session);
                        h[nh].sender = rx.sender;
                        h[nh].origin = rx.origin;
                        nh++;
                    }
                    if (i < nh) {
                        h[i].gone = rx.gone || rx.msg.u.status.state == FTM_WIRE_STATE_LEAVING;
                        if (!rx.gone) {
                            h[i].role = rx.msg.u.status.role;
                            h[i].tick = rx.msg.u.status.last_applied_tick;
                        }
                    }
                }
                ftm_wire_received_free(&rx);
            }
        }
    }
    ftm_wire_transport_destroy(t);
    for (int32_t i = 0; i < nh; i++) {
        if (h[i].gone)
            continue;
        ftm_session_seen *s = entry(out, cap, count, h[i].session);
        if (s && h[i].role >= 0 && h[i].role <= FTM_WIRE_ROLE_BOT)
            s->count[h[i].role]++;
        if (s && h[i].role == FTM_WIRE_ROLE_SERVER && h[i].sender == s->server_id &&
            h[i].tick > s->tick)
            s->tick = h[i].tick; /* newer than the announcement's */
    }
    free(h);
    qsort(out, (size_t)*count, sizeof *out, by_name);
    return FTM_OK;
}

void ftm_sessions_print(FILE *f, const ftm_sessions_def *def, const ftm_session_seen *s,
                        int32_t count)
{
    const double secs = def->seconds > 0 ? def->seconds : 1.0;
    if (count == 0) {
        fprintf(f, "sessions on domain %u: none heard in %g s\n", def->domain, secs);
        return;
    }
    fprintf(f, "sessions on domain %u (heard in %g s):\n", def->domain, secs);
    struct timespec now;
    clock_gettime(CLOCK_REALTIME, &now);
    const int64_t wall = (int64_t)now.tv_sec * 1000000000 + now.tv_nsec;
    for (int32_t i = 0; i < count; i++) {
        const ftm_session_seen *e = &s[i];
        char who[160];
        int w = 0;
        for (int r = FTM_WIRE_ROLE_TRAINEE; r <= FTM_WIRE_ROLE_BOT; r++)
            if (e->count[r] && w >= 0 && (size_t)w < sizeof who)
                w += snprintf(who + w, sizeof who - (size_t)w, "%s%d %s%s", w ? ", " : "",
                              (int)e->count[r], ftm_wire_role_name((ftm_wire_role)r),
                              e->count[r] > 1 ? "s" : "");
        if (w == 0)
            snprintf(who, sizeof who, "no participant");
        if (!e->announced) {
            fprintf(f, "  %-20s no server announces it (%s heard)\n", e->name, who);
            continue;
        }
        char age[32] = "?";
        if (e->server_start_ns && (int64_t)e->server_start_ns < wall) {
            double a = (double)(wall - (int64_t)e->server_start_ns) * 1e-9;
            if (a < 120)
                snprintf(age, sizeof age, "%.0f s", a);
            else if (a < 7200)
                snprintf(age, sizeof age, "%.0f min", a / 60);
            else
                snprintf(age, sizeof age, "%.1f h", a / 3600);
        }
        fprintf(f, "  %-20s scene %-12s server %u, up %s, tick %llu at %u Hz%s; %s\n", e->name,
                e->scene, e->server_id, age, (unsigned long long)e->tick, e->tick_rate_hz,
                e->paused ? ", paused" : "", who);
    }
}

void ftm_sessions_names(const ftm_session_seen *s, int32_t count, char *buf, size_t cap)
{
    size_t w = 0;
    if (cap)
        buf[0] = '\0';
    for (int32_t i = 0; i < count && w < cap; i++) {
        if (!s[i].announced)
            continue; /* (ours among them, while we wait) */
        int n = snprintf(buf + w, cap - w, "%s'%s'", w ? ", " : "", s[i].name);
        if (n < 0)
            break;
        w += (size_t)n;
    }
}

int ftm_sessions_list_command(const char *program, const ftm_sessions_def *def)
{
    ftm_session_seen seen[FTM_SESSIONS_MAX];
    int32_t n = 0;
    ftm_error err = {0, ""};
    if (ftm_sessions_find(def, seen, FTM_SESSIONS_MAX, &n, &err)) {
        fprintf(stderr, "%s: --list: %s\n", program, err.message);
        return 3;
    }
    ftm_sessions_print(stdout, def, seen, n);
    return 0;
}
