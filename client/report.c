#include "report.h"

#include <math.h>
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
                        bool limited)
{
    double f = sqrt(force.x * force.x + force.y * force.y + force.z * force.z);
    if (p->contact_ticks == 0 || f > p->peak_force) {
        p->peak_force = f;
        p->peak_tick = tick;
    }
    p->contact_ticks++;
    p->force_sum += f;
    if (push > p->max_push)
        p->max_push = push;
    if (limited)
        p->limited_ticks++;
}

/* A JSON string: printable ASCII kept, quotes and backslashes escaped, any
 * other byte (names come from the peers) as \u00XX. */
static void json_str(FILE *f, const char *s)
{
    fputc('"', f);
    for (const unsigned char *c = (const unsigned char *)s; *c; c++) {
        if (*c == '"' || *c == '\\')
            fprintf(f, "\\%c", *c);
        else if (*c >= 0x20 && *c < 0x7f)
            fputc(*c, f);
        else
            fprintf(f, "\\u%04x", *c);
    }
    fputc('"', f);
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
    fprintf(f, "\",\"ticks\":%llu,\"tick_rate_hz\":%.17g,\"seconds\":%.17g,"
               "\"depth_min\":%d,\"depth_max\":%d,\"unstable_ticks\":%llu,"
               "\"tissue_changes\":%llu,\"participants_not_reported\":%llu,\"participants\":[",
            (unsigned long long)s->ticks, s->tick_rate_hz, (double)s->ticks / rate,
            (int)s->depth_min, (int)s->depth_max, (unsigned long long)s->unstable_ticks,
            (unsigned long long)s->tissue_changes, (unsigned long long)r->dropped);
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
                    "\"contact_seconds\":%.17g,\"peak_force_n\":%.17g,\"peak_force_tick\":%llu,"
                    "\"mean_force_n\":%.17g,\"impulse_ns\":%.17g,\"max_push_m\":%.17g,"
                    "\"push_limited_ticks\":%llu}",
                    n++ ? "," : "", k, q->touches, (unsigned long long)q->contact_ticks,
                    (double)q->contact_ticks / rate, q->peak_force,
                    (unsigned long long)q->peak_tick,
                    q->contact_ticks ? q->force_sum / (double)q->contact_ticks : 0.0,
                    q->force_sum / rate, q->max_push, (unsigned long long)q->limited_ticks);
        }
        fprintf(f, "]}");
    }
    fprintf(f, "\n]}\n");
    return ferror(f) ? -1 : 0;
}

void ftm_report_free(ftm_report *r)
{
    free(r->parts);
    memset(r, 0, sizeof *r);
}
