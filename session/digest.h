/* SPDX-License-Identifier: GPL-3.0-or-later */
/* The scene digest: SHA-256 (OpenSSL's EVP) over what determines a
 * session's dynamics, announced by the server and checked by every
 * replica before it replays a frame (docs/protocol.md, Announcement). */
#ifndef FTM_SESSION_DIGEST_H
#define FTM_SESSION_DIGEST_H

#include "ftm/scene.h"

#include <stddef.h>
#include <stdint.h>

#define FTM_REPLAY_DIGEST_SIZE 32

/* SHA-256 over a canonical encoding of what determines the dynamics: the
 * mesh as built (rest positions, masses, damping, fixed flags, adjacency with
 * stiffness and rest lengths, surface triangles) and the session's sim
 * definition (ftm_replay_sim_def), with element forces their materials
 * (per label too) and the elastic far field where set. Two peers with equal digests replay
 * bit-identically. FTM_OK, or FTM_ENOMEM when OpenSSL cannot make a digest
 * context (out is then all zero: equal to no real digest). */
int ftm_replay_scene_digest(const ftm_scene *scene, uint8_t out[FTM_REPLAY_DIGEST_SIZE]);

/* SHA-256 of arbitrary bytes (FIPS 180-4). FTM_OK or FTM_ENOMEM. */
int ftm_sha256(const void *data, size_t size, uint8_t out[32]);

#endif
