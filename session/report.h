/* SPDX-License-Identifier: GPL-3.0-or-later */
/* The session report (ftm-server --report FILE, docs/server.md): what each
 * participant did, for the instructor's debriefing. ftm-client keeps the
 * same figures live from the frames it receives, for an instructor's HUD. Trainees' probes count
 * touches, time in contact, the reaction force (peak with its tick, mean,
 * impulse) and how deep they pushed. Everything is counted in ticks from
 * the tick logic alone, never from the clock, so a --replay or --inputs run
 * of a recording reports exactly what the live session did. */
#ifndef FTM_SESSION_REPORT_H
#define FTM_SESSION_REPORT_H

#include "ftm/base.h"

#include <stdbool.h>
#include <stdint.h>
#include <stdio.h>

#define FTM_REPORT_PROBES 4
#define FTM_REPORT_MAX_PARTICIPANTS 1024 /* distinct ids; more are counted, not kept */

typedef struct ftm_report_probe {
    uint32_t touches;         /* contacts begun */
    uint64_t contact_ticks;   /* ticks with a reaction force on this probe */
    uint64_t limited_ticks;   /* of those, ticks with the push limited */
    uint64_t peak_tick;       /* tick of the largest force */
    double peak_force;        /* largest |reaction| [N] */
    double force_sum;         /* sum of |reaction| over contact ticks [N] */
    double max_push;          /* longest push imposed on the tissue [m] */
    /* an unstable stretch: ticks the stability guard substepped (the tissue
     * past its stable step, docs/core.md); a peak taken in one is a spike of
     * the simulation, not of the trainee, and is marked so */
    uint64_t unstable_ticks;
    bool peak_unstable;
} ftm_report_probe;

typedef struct ftm_report_part {
    uint32_t id;
    char role[16];
    char name[64];
    uint64_t first_tick, last_tick; /* first and last tick seen: status or contact */
    ftm_report_probe probes[FTM_REPORT_PROBES];
} ftm_report_part;

#define FTM_REPORT_MAX_EVENTS 4096 /* kept; more are counted */

/* What an instructor changed: handled after tick `tick` (in force from the
 * next), by instructor `by`. */
typedef struct ftm_report_event {
    uint64_t tick;
    uint32_t by;
    char what[16];    /* pause, resume, reset, tissue, depth limits */
    char detail[112]; /* "stiffness 80 N/m (was 50), ..." */
} ftm_report_event;

typedef struct ftm_report {
    ftm_report_part *parts; /* in order of first appearance */
    int32_t count, cap;
    uint64_t dropped; /* statuses from ids beyond FTM_REPORT_MAX_PARTICIPANTS */
    ftm_report_event *events; /* in the order they were handled */
    int32_t nevents, events_cap;
    uint64_t events_dropped; /* beyond FTM_REPORT_MAX_EVENTS, or out of memory */
} ftm_report;

/* Where and why a session's recording stopped on a write error. */
typedef struct ftm_report_recording {
    uint64_t stop_tick;
    double stop_seconds;  /* into the session */
    const char *why;      /* the error */
    uint64_t kept_bytes, kept_tick; /* what the file kept: its size, its last tick */
    /* it recorded on into a new file of the lesson once space returned:
     * resumed_file from resumed_tick; or why it has not (NULL: no word) */
    const char *resumed_file;
    uint64_t resumed_tick;
    const char *not_resumed;
} ftm_report_recording;

/* What the report says of the session as a whole. */
typedef struct ftm_report_session {
    const char *session, *scene;
    const uint8_t *digest;
    int digest_len;
    uint64_t ticks;
    double tick_rate_hz;
    int32_t depth_min, depth_max;
    uint64_t unstable_ticks, tissue_changes;
    /* a session whose recording stopped on a write error (recording_stopped):
     * "recording" in the report, where and why. Nothing otherwise, so that a
     * replay's report is the live one's, byte for byte. */
    const ftm_report_recording *recording;
    bool recording_stopped;
} ftm_report_session;

/* Participant `id` seen at `tick` with this role and name: its entry (made
 * at the first sighting) updated. Returns the entry's index in r->parts
 * (entries move when the array grows: keep indices, not pointers), or -1
 * when FTM_REPORT_MAX_PARTICIPANTS are kept already (counted in dropped)
 * or out of memory. */
int32_t ftm_report_seen(ftm_report *r, uint32_t id, const char *role, const char *name,
                        uint64_t tick);
/* Index of participant id's entry, or -1. */
int32_t ftm_report_index(const ftm_report *r, uint32_t id);
/* A tick of contact on a probe: its reaction force, the length of its push,
 * whether it was limited and whether the tick was substepped (unstable). */
void ftm_report_contact(ftm_report_probe *p, uint64_t tick, ftm_vec3 force, double push,
                        bool limited, bool unstable);
/* An instructor's change (ftm_report_event), detail printf-style. */
void ftm_report_event_add(ftm_report *r, uint64_t tick, uint32_t by, const char *what,
                          const char *fmt, ...) __attribute__((format(printf, 5, 6)));
/* The report as JSON (one object); returns 0 or the stdio error. */
int ftm_report_write_json(const ftm_report *r, const ftm_report_session *s, FILE *f);
void ftm_report_free(ftm_report *r);

#endif
