/* SPDX-License-Identifier: GPL-3.0-or-later */
/* A body in Bullet's btSoftBody for `ftm bench peers` (docs/peers.md): the
 * same nodes, masses and node pairs as an FTM mesh, links solved by
 * Bullet's position-based solver at its default iterations. C interface
 * over tools/peer_bullet.cpp; only built with Bullet (FTM_HAVE_BULLET). */
#ifndef FTM_TOOLS_PEER_BULLET_H
#define FTM_TOOLS_PEER_BULLET_H

#include <stdbool.h>
#include <stdint.h>

#ifdef __cplusplus
extern "C" {
#endif

typedef struct ftm_peer_bullet ftm_peer_bullet;

/* Bullet's version ("3.24") and its scalar ("float" or "double"). */
const char *ftm_peer_bullet_version(void);
const char *ftm_peer_bullet_scalar(void);

/* n nodes at x (3 each) of masses mass (0: fixed); links pairs (2 each).
 * weight[l] is link l's linear stiffness kLST at scale 1; links of equal
 * weight share a material. damping: Bullet's kDP, the part of the velocity
 * a step takes away. The body sits in a soft-rigid world of its own
 * (no gravity, nothing else in it). NULL: out of memory. */
ftm_peer_bullet *ftm_peer_bullet_create(int32_t n, const double *x, const double *mass,
                                        int32_t nlinks, const int32_t *pairs, const double *weight,
                                        double damping);
void ftm_peer_bullet_destroy(ftm_peer_bullet *p);

/* Every link's kLST = scale * weight (at most 1); returns the smallest and
 * largest kLST in *lo, *hi. */
void ftm_peer_bullet_set_scale(ftm_peer_bullet *p, double scale, double *lo, double *hi);
/* The position solver's iterations (Bullet's default: 1). */
int ftm_peer_bullet_iterations(const ftm_peer_bullet *p);

/* A constant external force on a node, applied before every step. */
void ftm_peer_bullet_load(ftm_peer_bullet *p, int32_t node, double fx, double fy, double fz);

/* One step of h seconds: the soft body's own (predict, solve, integrate),
 * or the world's (stepSimulation: the same plus the world's broadphase,
 * collision pass and bookkeeping). */
void ftm_peer_bullet_step(ftm_peer_bullet *p, double h);
void ftm_peer_bullet_step_world(ftm_peer_bullet *p, double h);

/* Node positions (3 each); setting them also sets the previous position
 * and zero velocity (a start at rest there). */
void ftm_peer_bullet_positions(const ftm_peer_bullet *p, double *x);
void ftm_peer_bullet_set_positions(ftm_peer_bullet *p, const double *x);

#ifdef __cplusplus
}
#endif

#endif
