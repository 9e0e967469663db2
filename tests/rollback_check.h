/* SPDX-License-Identifier: GPL-3.0-or-later */
/* Test helper shared by the core's tests (include after cmocka.h and
 * ftm/ftm.h): the exact rollback of steps the stability guard rejects. */
#ifndef FTM_TESTS_ROLLBACK_CHECK_H
#define FTM_TESTS_ROLLBACK_CHECK_H

#include <stdlib.h>
#include <string.h>

/* Steps sim `tries` times. Every step that fails with FTM_EUNSTABLE must
 * leave the positions bit for bit as they were and the state hash too (it
 * covers the previous positions). Returns how many steps failed. */
static inline int rejected_steps_roll_back(ftm_sim *sim, int tries)
{
    const size_t n3 = 3 * (size_t)ftm_mesh_node_count(ftm_sim_mesh(sim));
    double *before = malloc(n3 * sizeof *before);
    assert_non_null(before);
    int failures = 0;
    for (int i = 0; i < tries; i++) {
        memcpy(before, ftm_sim_positions(sim), n3 * sizeof *before);
        const uint64_t h = ftm_sim_hash(sim);
        if (ftm_sim_step(sim) != FTM_EUNSTABLE)
            continue;
        failures++;
        assert_memory_equal(ftm_sim_positions(sim), before, n3 * sizeof *before);
        assert_true(ftm_sim_hash(sim) == h);
    }
    free(before);
    return failures;
}

#endif
