/* SPDX-License-Identifier: GPL-3.0-or-later */
/* From layers to an update schedule: the order in which the region's nodes
 * are updated and its groups (a layer, or an independent set), the blocks'
 * slot-major copies, and the relaxing set kept when the region changes. */
#include "farfield.h"
#include "sim_internal.h"

#include <stdlib.h>
#include <string.h>

static int cmp_i32(const void *a, const void *b)
{
    int32_t x = *(const int32_t *)a, y = *(const int32_t *)b;
    return (x > y) - (x < y);
}

void ftm_schedule_free(schedule *s)
{
    free(s->node);
    free(s->group);
    free(s->block);
    free(s->link_j);
    free(s->link_kl);
    free(s->node_c);
    free(s->save);
    free(s->tmp);
    memset(s, 0, sizeof *s);
}

static int schedule_reserve(schedule *s, int32_t count, int32_t groups, int32_t max_degree,
                            int32_t adjacency)
{
#define GROW(p, n, per)                                                                       \
    do {                                                                                      \
        void *q_ = realloc((p), ((size_t)(n) * (per) + 1) * sizeof *(p));                     \
        if (!q_)                                                                              \
            return FTM_ENOMEM;                                                                \
        (p) = q_;                                                                             \
    } while (0)
    if (count > s->cap) {
        int32_t cap = s->cap ? s->cap : 256;
        while (cap < count)
            cap *= 2;
        GROW(s->node, cap, 1);
        GROW(s->block, cap, 1);
        GROW(s->save, cap, 24); /* blocks <= count, 3 * 8 per block */
        GROW(s->tmp, cap, 12); /* a group's blocks of 8: <= 3 * (count + 7), cap >= 256 */
        GROW(s->node_c, cap, FTM_NODE_C * 8); /* per block, blocks <= count */
        s->cap = cap;
    }
    /* slots of all blocks, up to 8 lanes each: a block runs as many slots as
     * its largest degree, so all of them together no more than the region's
     * degrees, which the adjacency bounds (a hub must not multiply) */
    size_t slots = (size_t)count * (size_t)max_degree;
    if (slots > (size_t)adjacency)
        slots = (size_t)adjacency;
    size_t links = slots * 8;
    if (links > s->link_cap) {
        GROW(s->link_j, links, 1);
        GROW(s->link_kl, links, 2);
        s->link_cap = links;
    }
    if (groups + 1 > s->gcap) {
        int32_t cap = s->gcap ? s->gcap : 64;
        while (cap < groups + 1)
            cap *= 2;
        GROW(s->group, cap, 1);
        s->gcap = cap;
    }
#undef GROW
    return FTM_OK;
}

/* Nodes of the old region (and old relaxing set) that the new region does
 * not cover and that are not at rest become (stay) relaxing, ascending.
 * Called after the search; `old` holds the old region's nodes. */
static int update_relaxing(ftm_sim *sim, int32_t *old, int32_t cand)
{
    const ftm_layering *ly = &sim->ly;
    int32_t nr = 0;
    int32_t *merged = sim->relax;
    for (int32_t k = 0; k < cand; k++) {
        int32_t i = old[k];
        if (!ftm_layering_contains(ly, i) && !ftm_far_in_ring(sim->far, i) && !sim->m->fixed[i] &&
            !ftm_sim_at_rest(sim, i))
            old[nr++] = i;
    }
    int32_t nold = 0;
    for (int32_t k = 0; k < sim->nrelax; k++) {
        int32_t i = sim->relax[k];
        if (!ftm_layering_contains(ly, i) && !ftm_far_in_ring(sim->far, i))
            merged[nold++] = i;
    }
    /* sort the new candidates, then merge with the (sorted) survivors */
    qsort(old, (size_t)nr, sizeof *old, cmp_i32);
    int32_t *out = malloc(((size_t)nold + (size_t)nr + 1) * sizeof *out);
    if (!out)
        return FTM_ENOMEM;
    int32_t a = 0, b = 0, w = 0;
    while (a < nold || b < nr) {
        int32_t v;
        if (b >= nr || (a < nold && merged[a] < old[b]))
            v = merged[a++];
        else if (a >= nold || old[b] < merged[a])
            v = old[b++];
        else {
            v = merged[a++];
            b++;
        }
        out[w++] = v;
    }
    int rc = ftm_sim_relax_reserve(sim, w + 1);
    if (rc) {
        free(out);
        return rc;
    }
    memcpy(sim->relax, out, (size_t)w * sizeof *out);
    sim->nrelax = w;
    free(out);
    return FTM_OK;
}

/* The position in the layering's order from which no node is held: where
 * no fixed node lies within the layers' depth of a source, the region holds
 * none, and beyond layer 0 (the sources, where displaced nodes are) every
 * node is free; else none (INT32_MAX). */
static int32_t free_from(const ftm_sim *sim)
{
    const ftm_layering *ly = &sim->ly;
    const int32_t *hops = sim->m->fixed_hops;
    for (int32_t c = 0; c < sim->ncontacts; c++)
        if (hops[sim->sources[c]] <= sim->built_depth)
            return INT32_MAX;
    return ly->layers > 1 ? ly->start[1] : ly->count;
}

/* The scheduled nodes of order[k0 .. k1 - 1] to out; returns how many.
 * Copied whole from free_from on; else held nodes (displaced, fixed) are
 * filtered out branch-free: each node is written, and kept by advancing. */
static int32_t take_nodes(const ftm_sim *sim, int32_t k0, int32_t k1, int32_t from,
                          int32_t *restrict out)
{
    const int32_t *restrict order = sim->ly.order;
    if (k0 >= from) {
        memcpy(out, order + k0, (size_t)(k1 - k0) * sizeof *out);
        return k1 - k0;
    }
    const uint8_t *restrict kind = sim->kind;
    int32_t n = 0;
    for (int32_t k = k0; k < k1; k++) {
        const int32_t i = order[k];
        out[n] = i;
        n += kind[i] < NODE_DISP;
    }
    return n;
}

/* The schedule: the scheduled nodes (take_nodes) of the ranges
 * bounds[r] .. bounds[r+1]-1 of the layering's order, r = 0 .. ranges-1,
 * one group per range that keeps a node. The plain orders' ranges are the
 * layers; the colored order's are the independent sets (color: each set's
 * colour), so that the group kernel, which reads the state before a group,
 * updates a set exactly as one node after another would: no two nodes of a
 * set are adjacent. The shared-colour set, whose nodes may be adjacent,
 * becomes one group per node. Groups of layer 0 are the forced ones. */
static void schedule_groups(ftm_sim *sim, const int32_t *bounds, int32_t ranges,
                            const uint8_t *color)
{
    const ftm_layering *ly = &sim->ly;
    schedule *s = &sim->s;
    const int32_t from = free_from(sim);
    const int32_t layer1 = ly->layers > 1 ? ly->start[1] : ly->count;
    int32_t *restrict group = s->group;
    int32_t kk = 0, g = 0, forced = 0;
    for (int32_t r = 0; r < ranges; r++) {
        const int32_t first = kk;
        kk += take_nodes(sim, bounds[r], bounds[r + 1], from, s->node + kk);
        if (color && color[r] == FTM_SHARED_COLOR)
            for (int32_t k = first; k < kk; k++)
                group[g++] = k;
        else if (kk > first)
            group[g++] = first;
        if (bounds[r] < layer1)
            forced = g;
    }
    group[g] = kk;
    s->groups = g;
    s->forced_groups = forced;
    s->count = kk;
    s->last_uses = s->uses;
    s->uses = 0;
    s->linked = false;
    s->version++;
}

/* The update schedule from the current layers and contact kinds. */
int ftm_sim_rebuild_schedule(ftm_sim *sim)
{
    const bool colored = sim->def.order == FTM_ORDER_LAYER_COLORED;
    /* colored: a group per set, at most one per node in the shared-colour set */
    int rc = schedule_reserve(&sim->s, sim->ly.count, colored ? sim->ly.sets + sim->ly.count
                                                             : sim->ly.layers,
                              sim->m->max_degree, sim->m->adj_start[sim->m->node_count]);
    if (rc)
        return rc;
    if (colored)
        schedule_groups(sim, sim->ly.set_start, sim->ly.sets, sim->ly.set_color);
    else
        schedule_groups(sim, sim->ly.start, sim->ly.layers, NULL);
    sim->schedule_dirty = false;
    return FTM_OK;
}

/* Rebuilds layers and schedule; moves displaced nodes that left the region
 * into the relaxing set. */
int ftm_sim_rebuild_region(ftm_sim *sim)
{
    ftm_layering *ly = &sim->ly;
    /* Same sources and depth as the last search (a search forced by
     * cache_layers = false): the region is the same, so is the relaxing set. */
    bool same_region = ly->gen && !sim->layers_dirty && sim->built_depth == sim->def.depth;
    int32_t cand = 0;
    if (!same_region) { /* nodes of the old region are candidates for relaxing */
        int32_t old_count = ly->gen ? ly->count : 0;
        int rc = ftm_sim_relax_reserve(sim, sim->nrelax + old_count + 1);
        if (rc)
            return rc;
        memcpy(sim->relax_tmp, ly->order, (size_t)old_count * sizeof *ly->order);
        cand = old_count;
    }
    bool colored = sim->def.order == FTM_ORDER_LAYER_COLORED;
    int rc = ftm_layering_build(ly, sim->m, sim->sources, sim->ncontacts, sim->def.depth, colored);
    if (rc)
        return rc;
    sim->st.searches++;
    sim->built_depth = sim->def.depth;
    if (!same_region && sim->far) { /* the ring follows the region; its leavers may relax */
        int32_t added = ftm_far_rebuild_ring(sim, sim->relax_tmp + cand);
        if (added < 0)
            return added;
        cand += added;
    }
    if (!same_region) {
        rc = update_relaxing(sim, sim->relax_tmp, cand);
        if (rc)
            return rc;
    }
    rc = ftm_sim_rebuild_schedule(sim);
    if (rc)
        return rc;
    sim->layers_dirty = false;
    if (!same_region) {
        sim->region_sleeping = false;
        sim->quiet_steps = 0;
    }
    return FTM_OK;
}

/* Brings layers and schedule up to date: a new search when the contact node
 * set or the depth changed (or on every step without caching), only a new
 * schedule when just the contacts' kinds changed. */
int ftm_sim_refresh_region(ftm_sim *sim)
{
    if (sim->layers_dirty || sim->built_depth != sim->def.depth || !sim->def.cache_layers)
        return ftm_sim_rebuild_region(sim);
    if (sim->schedule_dirty)
        return ftm_sim_rebuild_schedule(sim);
    return FTM_OK;
}
