/* SPDX-License-Identifier: GPL-3.0-or-later */
/* Finding the sessions of a DDS domain: what their servers announce and who
 * is in them, by their statuses (`ftm-client --list`, `ftm-bot --list`, and
 * the participant core's answer to a session name that matches nothing). A
 * transport of every session (ftm_wire_transport_def.any_session) reads the
 * announcements and statuses, which are TRANSIENT_LOCAL: the latest of each
 * writer reaches a new reader at once, so a second suffices. */
#ifndef FTM_SESSION_SESSIONS_H
#define FTM_SESSION_SESSIONS_H

#include "ftm/wire.h"

#include <stdbool.h>
#include <stdint.h>
#include <stdio.h>

#define FTM_SESSIONS_MAX 32

typedef struct ftm_session_seen {
    char name[64];             /* the session's name, in its own case */
    bool announced;            /* a server announces it (else only statuses heard) */
    char scene[FTM_WIRE_NAME_MAX];
    uint32_t server_id;
    uint64_t server_start_ns;  /* wall clock; 0: not announced */
    uint64_t tick;
    uint32_t tick_rate_hz;
    bool paused;
    /* participants heard (statuses, the server's own included), by role */
    int32_t count[FTM_WIRE_ROLE_BOT + 1];
} ftm_session_seen;

typedef struct ftm_sessions_def {
    uint32_t domain;
    const char *dds_config, *dds_security;
    uint32_t participant_id; /* != 0: the transport's own id (it writes nothing) */
    double seconds;          /* how long to listen; 0: 1 s */
    ftm_log_fn log;          /* the transport's messages; NULL: silent */
    void *log_user;
} ftm_sessions_def;

ftm_sessions_def ftm_default_sessions_def(void);

/* Listens for def->seconds and fills out[0..*count) (at most cap), sorted
 * by name. FTM_OK (also when none is heard), or the transport's error. */
int ftm_sessions_find(const ftm_sessions_def *def, ftm_session_seen *out, int32_t cap,
                      int32_t *count, ftm_error *err);

/* One line per session for a terminal: name, scene, server, age, tick,
 * who is there ("sessions on domain 3: none heard in 1 s" when count is 0). */
void ftm_sessions_print(FILE *f, const ftm_sessions_def *def, const ftm_session_seen *s,
                        int32_t count);

/* `PROGRAM --list`: finds the sessions (def) and prints them on stdout;
 * the exit status: 0, or 3 when DDS fails (said on stderr as `program`). */
int ftm_sessions_list_command(const char *program, const ftm_sessions_def *def);

/* The names of the announced sessions, quoted and comma-separated, for a
 * log line or a banner ("" for none). */
void ftm_sessions_names(const ftm_session_seen *s, int32_t count, char *buf, size_t cap);

#endif
