/* SPDX-License-Identifier: GPL-3.0-or-later */
/* An instructor's commands and the server's replies (ControlReply).
 * ftm-client and ftm-bot remember each SessionControl they sent until the
 * server's reply to it arrives (docs/protocol.md): a command with no reply
 * within FTM_REPLY_TIMEOUT_NS (lost while no server listened, e.g. across a
 * server restart) is reported as unanswered, never forgotten silently. */
#ifndef FTM_SESSION_PENDING_H
#define FTM_SESSION_PENDING_H

#include "ftm/wire.h"

#define FTM_PENDING_MAX 64
#define FTM_PENDING_WHAT 96
#define FTM_REPLY_TIMEOUT_NS (3 * 1000000000LL)
/* room for any outcome text below */
#define FTM_OUTCOME_TEXT (FTM_PENDING_WHAT + FTM_WIRE_REASON_MAX + 64)

typedef struct ftm_pending_cmd {
    uint64_t id;
    int64_t sent_ns;
    char what[FTM_PENDING_WHAT]; /* e.g. "stiffness 80 N/m" */
} ftm_pending_cmd;

typedef struct ftm_pending {
    ftm_pending_cmd cmd[FTM_PENDING_MAX]; /* oldest first */
    int32_t n;
} ftm_pending;

/* Remembers a command just sent. With FTM_PENDING_MAX waiting (a server
 * that never answers), the oldest is given up first: written to text as
 * unanswered, and true returned (else false, text empty). */
bool ftm_pending_add(ftm_pending *p, uint64_t id, const char *what, int64_t now_ns, char *text,
                     size_t cap);

/* Forgets a command (one that could not be sent after all). */
void ftm_pending_forget(ftm_pending *p, uint64_t id);

/* A reply addressed to us: writes what became of the command, "stiffness 80
 * N/m: applied at tick 1234", "...: changed at tick T: REASON", "...:
 * refused: REASON", and forgets the command. A reply to no pending command
 * (a duplicate, or one the timeout gave up) still gets a text, naming the
 * command by its id; returns false then. */
bool ftm_pending_reply(ftm_pending *p, const ftm_wire_control_reply *r, char *text, size_t cap);

/* The oldest command sent more than timeout_ns before now and still without
 * a reply: forgotten, and "WHAT: no reply from the server in 3 s" written to
 * text. false when there is none. */
bool ftm_pending_expired(ftm_pending *p, int64_t now_ns, int64_t timeout_ns, char *text,
                         size_t cap);

#endif
