/* SPDX-License-Identifier: GPL-3.0-or-later */
#include "report.h"

#include <math.h>
#include <stdarg.h>
#include <stdlib.h>
#include <string.h>

int32_t ftm_report_index(const ftm_report *r, uint32_t id)
{
    for (int32_t i = 0; i < r->count; i++)
        if (r->parts[i].id == id)
            return i;
    return -1;
}

int32_t ftm_report_seen(ftm_report *r, uint32_t id, const char *role, const char *name,
                        uint64_t tick)
{
    int32_t i = ftm_report_index(r, id);
    if (i < 0) {
        if (r->count == FTM_REPORT_MAX_PARTICIPANTS) {
            r->dropped++;
            return -1;
        }
        if (r->count == r->cap) {
            int32_t cap = r->cap ? 2 * r->cap : 16;
            ftm_report_part *p = realloc(r->parts, (size_t)cap * sizeof *p);
            if (!p)
                return -1;
            r->parts = p;
            r->cap = cap;
        }
        i = r->count++;
        memset(&r->parts[i], 0, sizeof r->parts[i]);
        r->parts[i].id = id;
        r->parts[i].first_tick = tick;
    }
    ftm_report_part *p = &r->parts[i];
    snprintf(p->role, sizeof p->role, "%s", role);
    snprintf(p->name, sizeof p->name, "%s", name);
    p->last_tick = tick;
    return i;
}

void ftm_report_contact(ftm_report_probe *p, uint64_t tick, ftm_vec3 force, double push,
                        bool limited, bool unstable)
{
    double f = sqrt(force.x * force.x + force.y * force.y + force.z * force.z);
    if (p->contact_ticks == 0 || f > p->peak_force) {
        p->peak_force = f;
        p->peak_tick = tick;
        p->peak_unstable = unstable;
    }
    if (unstable)
        p->unstable_ticks++;
    p->contact_ticks++;
    p->force_sum += f;
    if (push > p->max_push)
        p->max_push = push;
    if (limited)
        p->limited_ticks++;
}

void ftm_report_event_add(ftm_report *r, uint64_t tick, uint32_t by, const char *what,
                          const char *fmt, ...)
{
    if (r->nevents == FTM_REPORT_MAX_EVENTS) {
        r->events_dropped++;
        return;
    }
    if (r->nevents == r->events_cap) {
        int32_t cap = r->events_cap ? 2 * r->events_cap : 16;
        ftm_report_event *e = realloc(r->events, (size_t)cap * sizeof *e);
        if (!e) {
            r->events_dropped++;
            return;
        }
        r->events = e;
        r->events_cap = cap;
    }
    ftm_report_event *e = &r->events[r->nevents++];
    memset(e, 0, sizeof *e);
    e->tick = tick;
    e->by = by;
    snprintf(e->what, sizeof e->what, "%s", what);
    va_list ap;
    va_start(ap, fmt);
    vsnprintf(e->detail, sizeof e->detail, fmt, ap);
    va_end(ap);
}

/* Length of the well-formed UTF-8 sequence at c (RFC 3629: no overlong
 * forms, no surrogates, at most U+10FFFF), or 0. */
static int utf8_len(const unsigned char *c)
{
    if (c[0] >= 0xc2 && c[0] <= 0xdf)
        return (c[1] & 0xc0) == 0x80 ? 2 : 0;
    if (c[0] >= 0xe0 && c[0] <= 0xef) {
        unsigned lo = c[0] == 0xe0 ? 0xa0 : 0x80, hi = c[0] == 0xed ? 0x9f : 0xbf;
        return c[1] >= lo && c[1] <= hi && (c[2] & 0xc0) == 0x80 ? 3 : 0;
    }
    if (c[0] >= 0xf0 && c[0] <= 0xf4) {
        unsigned lo = c[0] == 0xf0 ? 0x90 : 0x80, hi = c[0] == 0xf4 ? 0x8f : 0xbf;
        return c[1] >= lo && c[1] <= hi && (c[2] & 0xc0) == 0x80 && (c[3] & 0xc0) == 0x80 ? 4
                                                                                           : 0;
    }
    return 0;
}

/* A JSON string (names come from the peers): quotes and backslashes
 * escaped, control characters as \u00XX, well-formed UTF-8 kept (escaping
 * its bytes one by one, as \u00c3\u00a9 for an e-acute, would make a reader
 * decode two Latin-1 characters), any other byte as U+FFFD: the file is
 * valid UTF-8 JSON whatever was sent. */
static void json_str(FILE *f, const char *s)
{
    fputc('"', f);
    for (const unsigned char *c = (const unsigned char *)s; *c; c++) {
        int n;
        if (*c == '"' || *c == '\\')
            fprintf(f, "\\%c", *c);
        else if (*c >= 0x20 && *c < 0x7f)
            fputc(*c, f);
        else if (*c < 0x80)
            fprintf(f, "\\u%04x", *c);
        else if ((n = utf8_len(c)) > 0) {
            fwrite(c, 1, (size_t)n, f);
            c += n - 1;
        } else
            fputs("\\ufffd", f);
    }
    fputc('"', f);
}

/* A JSON number: JSON has no NaN or infinity, so a figure that is not
 * finite (none should be) is null rather than a file no reader accepts. */
static const char *num(char buf[32], double v)
{
    if (!isfinite(v))
        return "null";
    snprintf(buf, 32, "%.17g", v);
    return buf;
}

int ftm_report_write_json(const ftm_report *r, const ftm_report_session *s, FILE *f)
{
    double rate = s->tick_rate_hz > 0 ? s->tick_rate_hz : 1.0;
    fprintf(f, "{\"session\":");
    json_str(f, s->session);
    fprintf(f, ",\"scene\":");
    json_str(f, s->scene);
    fprintf(f, ",\"scene_digest\":\"");
    for (int i = 0; i < s->digest_len; i++)
        fprintf(f, "%02x", s->digest[i]);
    char b[5][32];
    fprintf(f, "\",\"ticks\":%llu,\"tick_rate_hz\":%s,\"seconds\":%s,"
               "\"depth_min\":%d,\"depth_max\":%d,\"unstable_ticks\":%llu,"
               "\"tissue_changes\":%llu,\"participants_not_reported\":%llu,\"participants\":[",
            (unsigned long long)s->ticks, num(b[0], s->tick_rate_hz),
            num(b[1], (double)s->ticks / rate), (int)s->depth_min, (int)s->depth_max,
            (unsigned long long)s->unstable_ticks, (unsigned long long)s->tissue_changes,
            (unsigned long long)r->dropped);
    for (int32_t i = 0; i < r->count; i++) {
        const ftm_report_part *p = &r->parts[i];
        fprintf(f, "%s\n {\"id\":%u,\"role\":", i ? "," : "", p->id);
        json_str(f, p->role);
        fprintf(f, ",\"name\":");
        json_str(f, p->name);
        fprintf(f, ",\"first_tick\":%llu,\"last_tick\":%llu,\"probes\":[",
                (unsigned long long)p->first_tick, (unsigned long long)p->last_tick);
        int n = 0;
        for (int k = 0; k < FTM_REPORT_PROBES; k++) {
            const ftm_report_probe *q = &p->probes[k];
            if (!q->touches && !q->contact_ticks)
                continue;
            fprintf(f,
                    "%s\n  {\"probe\":%d,\"touches\":%u,\"contact_ticks\":%llu,"
                    "\"contact_seconds\":%s,\"peak_force_n\":%s,\"peak_force_tick\":%llu,"
                    "\"mean_force_n\":%s,\"impulse_ns\":%s,\"max_push_m\":%s,"
                    "\"push_limited_ticks\":%llu,\"unstable_ticks\":%llu,"
                    "\"peak_while_unstable\":%s}",
                    n++ ? "," : "", k, q->touches, (unsigned long long)q->contact_ticks,
                    num(b[0], (double)q->contact_ticks / rate), num(b[1], q->peak_force),
                    (unsigned long long)q->peak_tick,
                    num(b[2], q->contact_ticks ? q->force_sum / (double)q->contact_ticks : 0.0),
                    num(b[3], q->force_sum / rate), num(b[4], q->max_push),
                    (unsigned long long)q->limited_ticks, (unsigned long long)q->unstable_ticks,
                    q->peak_unstable ? "true" : "false");
        }
        fprintf(f, "]}");
    }
    fprintf(f, "\n]");
    if (s->recording && s->recording_stopped) {
        const ftm_report_recording *g = s->recording;
        fprintf(f, ",\"recording\":{\"ok\":false,\"stopped_tick\":%llu,\"stopped_seconds\":%s,"
                   "\"error\":",
                (unsigned long long)g->stop_tick, num(b[0], g->stop_seconds));
        json_str(f, g->why ? g->why : "");
        fprintf(f, ",\"kept_bytes\":%llu,\"kept_to_tick\":%llu",
                (unsigned long long)g->kept_bytes, (unsigned long long)g->kept_tick);
        if (g->resumed_file) {
            fprintf(f, ",\"resumed_tick\":%llu,\"resumed_file\":",
                    (unsigned long long)g->resumed_tick);
            json_str(f, g->resumed_file);
        } else if (g->not_resumed && g->not_resumed[0]) {
            fprintf(f, ",\"not_resumed\":");
            json_str(f, g->not_resumed);
        }
        fputc('}', f);
    }
    /* what the instructors changed, for the debriefing's timeline */
    fprintf(f, ",\"events_not_reported\":%llu,\"events\":[",
            (unsigned long long)r->events_dropped);
    for (int32_t i = 0; i < r->nevents; i++) {
        const ftm_report_event *e = &r->events[i];
        fprintf(f, "%s\n {\"tick\":%llu,\"seconds\":%s,\"by\":%u,\"what\":", i ? "," : "",
                (unsigned long long)e->tick, num(b[0], (double)e->tick / rate), e->by);
        json_str(f, e->what);
        fprintf(f, ",\"detail\":");
        json_str(f, e->detail);
        fputc('}', f);
    }
    fprintf(f, "\n]}\n");
    return ferror(f) ? -1 : 0;
}

void ftm_report_free(ftm_report *r)
{
    free(r->parts);
    free(r->events);
    memset(r, 0, sizeof *r);
}
