/* SPDX-License-Identifier: GPL-3.0-or-later */
/* ftm-server --replay FILE (record_replay.c). */
#ifndef FTM_SERVER_RECORD_REPLAY_H
#define FTM_SERVER_RECORD_REPLAY_H

#include <stdbool.h>

/* Replays the recording at path on scene_name (NULL: the recorded scene id).
 * Prints a summary and the final tick and hash on stdout; the first problem
 * (tick of a hash mismatch, malformed or truncated entry) on stderr. Returns
 * the exit status: 0 when every hash matched, 1 otherwise. upto_damage: a
 * damaged recording is replayed up to its first damaged entry, with a note. */
int ftm_server_replay(const char *path, const char *scene_name, bool upto_damage);

#endif
