/* SPDX-License-Identifier: GPL-3.0-or-later */
/* Internal to libftm, shared with the lab (ftm bench table3 times the bare
 * search): depth-synchronised multi-source breadth-first layering (paper
 * Fig. 5), optionally with each layer split into independent sets (the
 * update schedule of FTM_ORDER_LAYER_COLORED). */
#ifndef FTM_INTERNAL_LAYERS_H
#define FTM_INTERNAL_LAYERS_H

#include "ftm/mesh.h"

#include <stdbool.h>
#include <stdint.h>

/* The mesh colour (ftm_mesh.color) that may hold adjacent nodes: its sets
 * are not independent and must be updated one by one. */
#define FTM_SHARED_COLOR 63

typedef struct ftm_layering {
    /* Per-node scratch, sized to the mesh. visit[i] == gen marks "in the
     * current region", so nothing is cleared between searches. */
    uint32_t *visit;
    uint32_t gen;

    int32_t *queue;    /* region nodes in BFS order (count + 1 entries) */
    int32_t *order;    /* region nodes, layer by layer, in update order (+16 spare) */
    uint8_t *qcol;     /* with AVX-512: the colour of each queue entry (+16 spare) */
    int32_t *start;    /* layer l: order[start[l] .. start[l+1]-1]; layers + 1 entries */
    int32_t start_cap;
    int32_t count;     /* nodes in the region */
    int32_t layers;    /* layers built (<= depth + 1) */

    /* When coloured: set s is order[set_start[s] .. set_start[s+1]-1] with
     * colour set_color[s]; sets of a layer are consecutive, in colour order. */
    int32_t *set_start;
    uint8_t *set_color;
    int32_t sets;
    /* Split the sets the portable way even where AVX-512 could: the two
     * give the same layering (tests compare them). */
    bool scalar_split;
} ftm_layering;

int ftm_layering_init(ftm_layering *ly, int32_t node_count);
void ftm_layering_free(ftm_layering *ly);

/* Builds layers L0..L(depth) from the sources (distinct, in range). Sources
 * form L0 in the given order; every other node reached within depth steps
 * lands in the layer of its smallest distance to any source, in BFS order.
 * With want_sets, each layer is then split by the mesh's greedy colouring into
 * independent sets (no two nodes of one set adjacent, except in the
 * FTM_SHARED_COLOR set); sets in colour order, nodes of a set in BFS order.
 * Deterministic. */
int ftm_layering_build(ftm_layering *ly, const ftm_mesh *mesh, const int32_t *sources,
                       int32_t source_count, int32_t depth, bool want_sets);

/* True if node is in the region of the last build. */
static inline bool ftm_layering_contains(const ftm_layering *ly, int32_t node)
{
    return ly->visit[node] == ly->gen;
}

#endif
