/* SPDX-License-Identifier: GPL-3.0-or-later */
/* Internal: the state of an ftm_sim and the pieces of the integrator that
 * live in separate files: sim.c (API, contacts, the step, queries),
 * sim_schedule.c (layers -> update schedule, the relaxing set) and
 * sim_kernel.c (the hot loop: spring forces and the sweeps). */
#ifndef FTM_SRC_SIM_INTERNAL_H
#define FTM_SRC_SIM_INTERNAL_H

#include "ftm/sim.h"

#include "ftm/internal/layers.h"
#include "mesh_internal.h"

/* Added to a spring's length before dividing by it: exact for any length
 * above ~1e-134, and keeps coincident nodes (r = 0) from producing 0/0. */
#define FTM_LEN_EPS 1e-150

/* sim->coef holds FTM_COEF doubles per node; the guard's limit is the last. */
#define FTM_COEF 4
#define FTM_LIM2 3
/* A block's copy of its nodes' constants (schedule.node_c): a, b, c, lim2
 * and ke_w, a vector of the lane count each. */
#define FTM_NODE_C 5

/* Scheduled nodes are the free and force-loaded ones (kind < NODE_DISP). */
enum { NODE_FREE = 0, NODE_FORCE = 1, NODE_DISP = 2, NODE_FIXED = 3 };

/* GCC vector extensions, for the group kernel's lanes: the same
 * source compiles to AVX-512, AVX or SSE2 with the same IEEE results. */
typedef double v4d __attribute__((vector_size(32)));
typedef int64_t v4l __attribute__((vector_size(32)));
/* Lanes from four addresses. Built as one initialiser: element-by-element
 * assignment makes GCC assemble the vector on the stack, and the wide
 * reload of narrow stores stalls store forwarding. */
#define GATHER4(p, i0, i1, i2, i3) ((v4d){(p)[i0], (p)[i1], (p)[i2], (p)[i3]})
/* Consecutive doubles at any alignment (vectors alias their elements). */
typedef double v4du __attribute__((vector_size(32), aligned(8)));
typedef double v2du __attribute__((vector_size(16), aligned(8)));
#define LOAD4(p) (*(const v4du *)(p))
#define LOAD2(p) (*(const v2du *)(p))

/* The three coordinates of four points stored 3 doubles apiece at p + i0 ..
 * p + i3 as x, y and z vectors: x and y from one 16-byte load per point
 * (fewer instructions than four scalar loads each), z gathered. */
static inline __attribute__((always_inline)) void ftm_load_xy4(const double *p, size_t i0,
                                                               size_t i1, size_t i2, size_t i3,
                                                               v4d *x, v4d *y)
{
    v4d p02 = __builtin_shufflevector(LOAD2(p + i0), LOAD2(p + i2), 0, 1, 2, 3),
        p13 = __builtin_shufflevector(LOAD2(p + i1), LOAD2(p + i3), 0, 1, 2, 3);
    *x = __builtin_shufflevector(p02, p13, 0, 4, 2, 6);
    *y = __builtin_shufflevector(p02, p13, 1, 5, 3, 7);
}

static inline __attribute__((always_inline)) void ftm_load_xyz4(const double *p, size_t i0,
                                                                size_t i1, size_t i2, size_t i3,
                                                                v4d *x, v4d *y, v4d *z)
{
    ftm_load_xy4(p, i0, i1, i2, i3, x, y);
    *z = GATHER4(p + 2, i0, i1, i2, i3);
}

/* A linked schedule's block: up to sim->group_lanes nodes of one group,
 * cut as the group sweep cuts them, updated together over `slots` padded
 * neighbour slots (the largest degree among them), stored slot-major from
 * slot index `link` of the schedule's link arrays, so that the kernel loads
 * each slot's lanes with one vector load. */
typedef struct block {
    int32_t slots, link;
} block;

/* The update order of the contact region, rebuilt when the region changes:
 * the free and force-loaded nodes of the layers, in update order. */
typedef struct schedule {
    int32_t count;  /* scheduled nodes */
    int32_t *node;  /* mesh index */
    /* updated together from the state before them: Jacobi one per layer,
     * colored one per independent set (one per node in the shared-colour set) */
    int32_t groups;
    int32_t *group; /* group g: schedule positions group[g] .. group[g+1]-1 */
    int32_t forced_groups; /* groups 0 .. forced_groups-1 hold layer 0 (the force contacts) */
    int32_t blocks; /* group orders, once linked */
    block *block;
    /* group orders, per slot of a block: 3 * neighbour of each lane (spare
     * lanes repeat the block's last node), stiffness and rest length, as in
     * pad_node / pad_kl */
    int32_t *link_j;
    double *link_kl; /* per slot: k of the lanes, then len */
    /* per block, with the links: the lanes' Eq. 8 coefficients a, b and c,
     * guard limit lim2 and energy weight ke_w (FTM_NODE_C vectors of the lane
     * count), so the kernels load them instead of gathering them per node */
    double *node_c;
    /* rollback: previous positions overwritten in the last step; 3 per
     * schedule position, or in the group orders x, y and z vectors of the
     * lane count per block (ftm_group_save) */
    double *save;
    double *tmp;    /* new positions of a group, x, y and z vectors of 4 or 8 per block */
    int32_t uses;   /* group sweeps since the schedule was built */
    uint32_t version; /* raised with every new schedule (element forces' block lists) */
    int32_t last_uses; /* the previous schedule's, when this one was built */
    bool linked;    /* block, link_j, link_kl and node_c hold the blocks' copies */
    int32_t cap, gcap;
    size_t link_cap;
} schedule;

struct ftm_sim;
typedef bool (*sweep_fn)(struct ftm_sim *sim, double *max_m2);

struct ftm_sim {
    const ftm_mesh *m;
    ftm_sim_def def;
    int32_t n;
    double *x, *xp; /* positions and previous positions, 3 per node */
    /* per node, one 32-byte row: a, b, c of Eq. 8 for the current substep
     * length and the guard's squared motion limit (FTM_LIM2); the vector
     * kernels load a block's rows whole and transpose them */
    double *coef;
    double *force;  /* external force, 3 per node (zero but at force contacts) */
    double *ke_w;   /* energy guard: m / 2 h_sub^2 per node (kinetic energy per squared motion) */
    uint8_t *kind;  /* NODE_* per node */

    ftm_contact *contacts; /* current contacts, sorted by node */
    int32_t ncontacts, contact_cap;
    int32_t *sources;      /* contact node ids (sorted) = layer 0 */
    int32_t *disp;         /* displacement-contact nodes, in contact order */
    int32_t ndisp;

    ftm_layering ly;
    bool layers_dirty;     /* node set or depth changed since the last build */
    bool schedule_dirty;   /* only the contacts' kinds changed */
    int32_t built_depth;
    schedule s;

    int32_t *relax; /* displaced nodes outside the region, ascending */
    int32_t nrelax, relax_cap;
    int32_t *relax_tmp;
    double *relax_save; /* rollback for relaxing and displacement nodes: x, xp */

    int32_t substeps;
    int32_t steps_at_substeps;
    double h_sub;

    int32_t quiet_steps; /* consecutive steps with the region below the sleep tolerance */
    bool region_sleeping;
    /* Every node's z and z_prev is +0.0 and every load has z = 0 (kept
     * since the last reset or load_state; a load with z != 0 clears it):
     * then z stays +0.0, and the group sweep may leave it out. */
    bool planar_state;
    bool warned_dt;

    double *reaction; /* 3 per group */
    int32_t reaction_groups;

    double tol; /* sleep tolerance in metres */
    sweep_fn sweep_groups;
    int group_lanes; /* of sweep_groups: its blocks' width */
    bool pad_cheap;  /* ftm_mesh_pad_cheap: a fresh block runs every padded slot */
    bool pad_rows;   /* the mesh has padded rows; else fresh blocks read the adjacency */
    /* Energy guard (sim.c): the sweeps add each updated node's kinetic energy
     * m |x_new - x|^2 / 2 h^2 and a quarter of its links' k (|r| - l)^2 */
    double energy;       /* of the current substep */
    double energy_prev;  /* at the end of the last step */
    double budget;       /* energy the loads can account for; < 0: unknown */
    double energy_floor; /* below this no check (round-off scale) */
    double energy_h_max; /* checked only with substeps up to the critical step */
    double *work_mark;   /* per contact at the step's start: x (force) or f (displacement) */
    int32_t work_cap;
    bool energy_guard;   /* the sweeps compute spring energy (spring forces) */
    ftm_sim_stats st;
    struct ftm_elem *elem; /* element forces (sim_elem.c); NULL = springs */
    ftm_label_material *label_mat; /* def.label_materials' copy (def points to it) */
    struct ftm_far *far;   /* elastic far field (farfield.c); NULL = fixed */
};

/* The guard's squared motion limit of node i. */
static inline double ftm_sim_lim2(const ftm_sim *sim, int32_t i)
{
    return sim->coef[FTM_COEF * (size_t)i + FTM_LIM2];
}

static inline bool ftm_sim_at_rest(const ftm_sim *sim, int32_t i)
{
    const double *x = sim->x + 3 * i, *xp = sim->xp + 3 * i, *X = sim->m->rest + 3 * i;
    return x[0] == X[0] && x[1] == X[1] && x[2] == X[2] && xp[0] == X[0] && xp[1] == X[1] &&
           xp[2] == X[2];
}

/* Where the group orders save the x_prev of schedule position k for
 * rollback: in its block's x, y and z vectors of sim->group_lanes each
 * (coordinate d at [d * lanes]); b0 is the first block of k's group, k0 the
 * group's first position. */
static inline double *ftm_group_save(const ftm_sim *sim, int32_t b0, int32_t k0, int32_t k)
{
    const int32_t w = sim->group_lanes, off = k - k0;
    return sim->s.save + 3 * (size_t)w * (size_t)(b0 + off / w) + off % w;
}

/* How many blocks the group sweep cuts from the group of schedule positions
 * k0 .. k1-1: sim->group_lanes positions each, the last one possibly fewer.
 * The group after it starts at block b0 + this (see ftm_group_save). */
static inline int32_t ftm_group_blocks(const ftm_sim *sim, int32_t k0, int32_t k1)
{
    const int32_t w = sim->group_lanes;
    return (k1 - k0 + w - 1) / w;
}

/* The group sweep may leave z out: it would compute z = +0.0 for every node
 * and add only exact zeros to the other coordinates' sums (docs/core.md). */
static inline bool ftm_sim_planar(const ftm_sim *sim)
{
    return sim->planar_state && sim->m->planar && sim->def.planar_kernel && !sim->elem;
}

/* The group sweep records the schedule's block-major copy as it goes, for
 * the sweeps after it to load whole: when the schedule is not linked yet
 * and is swept a second time, or with cached layers on its first sweep
 * already — unless the previous schedule was swept just once (contacts
 * that change every step: the stores would be wasted). */
static inline bool ftm_sim_record_links(const ftm_sim *sim)
{
    const schedule *s = &sim->s;
    return !s->linked && (s->uses > 0 || (sim->def.cache_layers && s->last_uses != 1));
}

/* Eq. 8 for node i with a partial constraint or a spring to ground
 * (m->bc[i] != 0): f, the node's internal forces at cur as Eq. 8 subtracts
 * them, gets the ground spring added; the new position is projected onto
 * the node's plane (line). Returns the squared motion; *ground gets the
 * ground spring's energy at cur, k_g |cur - X|^2 / 2. Every order and
 * kernel updates such a node with this one function (sim_groups.inc does it
 * after the vector blocks), so they agree bit for bit. */
static inline double ftm_bc_update(const ftm_sim *sim, int32_t i, const double cur[3], double f[3],
                                   double out[3], double *ground)
{
    const ftm_mesh *m = sim->m;
    const double *c = sim->coef + FTM_COEF * (size_t)i, *F = sim->force + 3 * (size_t)i,
                 *p = sim->xp + 3 * (size_t)i, *X = m->rest + 3 * (size_t)i;
    ftm_bc_ground_force(m, i, cur, f);
    for (int d = 0; d < 3; d++)
        out[d] = c[0] * (F[d] - f[d]) + c[1] * cur[d] - c[2] * p[d];
    ftm_bc_project(m, i, out);
    const double ux = cur[0] - X[0], uy = cur[1] - X[1], uz = cur[2] - X[2];
    *ground = 0.5 * m->ground_k[i] * (ux * ux + uy * uy + uz * uz);
    const double dx = out[0] - cur[0], dy = out[1] - cur[1], dz = out[2] - cur[2];
    return dx * dx + dy * dy + dz * dz;
}

/* sim.c */
int ftm_sim_relax_reserve(ftm_sim *sim, int32_t need);

/* sim_schedule.c */
void ftm_schedule_free(schedule *s);
/* Brings layers and schedule up to date (a search only when needed). */
int ftm_sim_refresh_region(ftm_sim *sim);
int ftm_sim_rebuild_region(ftm_sim *sim);
int ftm_sim_rebuild_schedule(ftm_sim *sim);

/* sim_kernel.c: each sweep returns false if a node moved more than its
 * guard limit or to a non-finite position. */
bool ftm_sweep_gs(ftm_sim *sim, int32_t k0, int32_t k1, double *max_m2);
bool ftm_sweep_relax(ftm_sim *sim);
/* The constrained nodes (m->bc) of the group at schedule positions k0 ..
 * k1-1, whose new positions the group sweep left at tmp (x, y and z vectors
 * of w lanes per block): updated again by ftm_bc_update from the state
 * before the group (the vector blocks leave them out of the guard, the
 * largest motion and the energy). Adds their motion to *mm and their
 * energy to *en; false if one moved more than its guard limit. */
bool ftm_bc_group(ftm_sim *sim, int32_t k0, int32_t k1, double *tmp, int w, double *mm,
                  double *en);
void ftm_sim_compute_reactions(ftm_sim *sim);
void ftm_sim_spring_force(const ftm_sim *sim, int32_t i, double f[3]);
double ftm_sim_link_pe(const ftm_sim *sim, int32_t i);
/* Chooses the group orders' kernel: the widest this CPU supports
 * (the default), or with portable the baseline one. Both give bit-identical
 * results; tests compare them. */
void ftm_sim_select_kernel(ftm_sim *sim, bool portable);

#endif
