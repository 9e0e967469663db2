/* SPDX-License-Identifier: GPL-3.0-or-later */
/* Internal: the compliance G = K^-1 of a held body, for the elastic far
 * field (farfield.h). K is the stiffness at rest with the fixed nodes
 * clamped: the springs' tangent, or the assembled linear element stiffness.
 * It is factorised once (profile LDL^T in reverse Cuthill-McKee order) and
 * G's columns of the free surface nodes are solved for; other nodes' columns
 * are added when first asked for. Only + - * / in fixed orders: every
 * machine computes the same bits, so the result is shared
 *   - within a process: one compliance per stiffness, reference-counted
 *     (a server's replicas, a fuzzer's replica per input), and
 *   - across processes: a file per stiffness in $FTM_CACHE_DIR (default
 *     $XDG_CACHE_HOME/ftm or ~/.cache/ftm; set empty: none), named by a hash
 *     of K's profile and the surface nodes and checked by a checksum.
 * Thread-safe: acquire, release and ensure take a process-wide lock. */
#ifndef FTM_SRC_COMPLIANCE_H
#define FTM_SRC_COMPLIANCE_H

#include "sim_internal.h"

typedef struct ftm_compliance ftm_compliance;

/* Precomputation larger than this (factor and columns) is refused. */
#define FTM_COMPLIANCE_MAX_BYTES ((size_t)3 << 30)

/* The compliance of the stiffness sim's forces have on mesh m (the sim's
 * own, or one of the same shape it switches to). Refuses a body that is not
 * held (singular K: the message names the node) or a precomputation over
 * FTM_COMPLIANCE_MAX_BYTES (naming the sizes); logs progress through the
 * sim's log hook when it takes long. */
int ftm_compliance_acquire(const ftm_sim *sim, const ftm_mesh *m, ftm_compliance **out,
                           ftm_error *err);
void ftm_compliance_release(ftm_compliance *c);

/* Makes node's column present (a free node); FTM_ENOMEM possible. */
int ftm_compliance_ensure(ftm_compliance *c, int32_t node, ftm_log_fn log, void *log_user);

/* The 3x3 block G_ab (row-major: response of a to a unit force at b) of a
 * present column b. */
static inline void ftm_compliance_block(const float *const *cols, int32_t a, int32_t b,
                                        double out[9])
{
    const float *g = cols[b] + 9 * (size_t)a;
    for (int e = 0; e < 9; e++)
        out[e] = (double)g[e];
}

/* Tests: the widest solve kernel used from now on in this process (2:
 * AVX-512, 1: AVX2, 0: plain C); each gives the same bits. */
void ftm_compliance_limit_kernel(int widest);

/* The columns (entry b: NULL until present); entries, once set, never change. */
const float *const *ftm_compliance_columns(const ftm_compliance *c);

#endif
