/* SPDX-License-Identifier: GPL-3.0-or-later */
/* The client's list of participants (the instructor's "participants:"
 * rows). A trainee that leaves after touching the tissue keeps its row,
 * marked left, so the instructor can still debrief it. */
#ifndef FTM_CLIENT_PARTS_H
#define FTM_CLIENT_PARTS_H

#include "client_session.h"

/* The row of participant id in parts[0 .. *n - 1]. With add, a missing one
 * is appended (zeroed but for its id), taking the place of a departed row
 * when the list is full; NULL when it is full of present participants, or
 * without add when there is none. */
ftm_client_part *ftm_parts_find(ftm_client_part *parts, int32_t *n, uint32_t id, bool add);

/* Participant id has gone: with keep its row stays, marked left, else it
 * is removed (the last row takes its place). */
void ftm_parts_gone(ftm_client_part *parts, int32_t *n, uint32_t id, bool keep);

/* Removes the departed rows, keeping the others in order: on a server
 * restart, whose new session has no figures for them. */
void ftm_parts_forget_departed(ftm_client_part *parts, int32_t *n);

#endif
