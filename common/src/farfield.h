/* SPDX-License-Identifier: GPL-3.0-or-later */
/* Internal: the elastic far field (ftm_sim_def.far_field = FTM_FAR_FIELD_ELASTIC).
 *
 * The paper holds every node beyond the penetration depth at rest, so the
 * contact region is clamped at its edge and feels stiffer the shallower it
 * is. Here the nodes just beyond the region (the ring: every free node
 * outside it that shares a link or an element with a region node) are
 * instead placed where the whole body's linear static solution puts them
 * under the current contacts:
 *
 *     u_ring = G_rc f_c,   f_d = G_dd^-1 (delta_d - G_df F),   f_f = F
 *
 * G = K^-1 is the compliance of the whole body (K its stiffness at rest,
 * fixed nodes clamped), c the contact nodes, d the displacement contacts
 * (imposed delta), f the force contacts (force F). The region then solves a
 * Dirichlet problem with the true boundary values, so at equilibrium its
 * displacements and the contact forces are the whole body's, whatever the
 * depth, for linear forces exactly; the cost of a step stays set by the
 * region (ring times contacts). G is the compliance.h object; only
 * + - * / in fixed orders are used, so a replica computes the same bits as
 * its server and needs nothing from it. */
#ifndef FTM_SRC_FARFIELD_H
#define FTM_SRC_FARFIELD_H

#include "sim_internal.h"

typedef struct ftm_far ftm_far;

/* Acquires the body's compliance (compliance.h: computed, shared or read
 * from the cache). Refuses a body that is not held or a precomputation too
 * large, naming the sizes. Called by ftm_sim_create after the element
 * forces. */
int ftm_far_create(ftm_sim *sim, ftm_error *err);
void ftm_far_free(ftm_far *f);

/* The ring of the current layering (after every search): its nodes leave
 * the relaxing set; the old ring's nodes that are neither in the new
 * region nor in the new ring are appended to cand (the caller's candidates
 * for relaxing, room for the old ring's count). Returns the number added,
 * or a negative error. */
int32_t ftm_far_rebuild_ring(ftm_sim *sim, int32_t *cand);
/* Upper bound on what ftm_far_rebuild_ring appends. */
int32_t ftm_far_ring_count(const ftm_far *f);
const int32_t *ftm_far_ring_nodes(const ftm_far *f);
bool ftm_far_in_ring(const ftm_far *f, int32_t node);
/* Whether this step (ftm_far_prepare) moves ring node k (its index in
 * ftm_far_ring_nodes): under unchanged contacts none does. */
bool ftm_far_ring_moves(const ftm_far *f, int32_t k);

/* Marks the contact solve stale (the contact node set or kinds changed). */
void ftm_far_contacts_changed(ftm_far *f);

/* Before a step: the ring's displacements for the current contacts (and the
 * Green's columns of newly loaded nodes). FTM_ENOMEM possible. */
int ftm_far_prepare(ftm_sim *sim);

/* In each substep, before the sweep: the ring nodes placed at X + u
 * (x_prev takes the old x, as for displacement contacts). */
void ftm_far_impose(ftm_sim *sim);

/* A new stiffness of the same shape (ftm_sim_set_mesh): when every link's
 * stiffness is the old one times one factor, the columns are rescaled;
 * otherwise recomputed. */
int ftm_far_set_mesh(ftm_sim *sim, const ftm_mesh *m, ftm_error *err);
/* Element forces: the stiffness is `scale` times the one G was computed
 * for (a factor on E). */
void ftm_far_set_scale(ftm_far *f, double scale);

#endif
