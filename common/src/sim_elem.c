/* SPDX-License-Identifier: GPL-3.0-or-later */
/* Element forces in the force transmittal integrator (beyond the paper).
 *
 * Instead of springs, a node's internal force is the sum over its elements of
 * the element force rows: linear, f_e = K_e (x_e - X_e), with the element
 * stiffness of the linear FEM reference (element.c); co-rotational,
 * f_e = R K_e (R^T x_e - X_e), R the rotation of the element's deformation
 * gradient at its centre (polar decomposition); or neo-Hookean
 * (hyperelastic.c), total Lagrangian: f_a = sum_q w_q P(F_q) grad N_a(X_q),
 * F_q from the rest gradients at the quadrature points of the linear
 * elements (2x2x2 Gauss on hexahedra, one point on tetrahedra), so that its
 * tangent at rest is the linear K_e. At full depth the equilibrium is the
 * FEM's. docs/accuracy.md has the measurements.
 *
 * Linear forces use the assembled rows (node i: sum_j K_ij u_j over the nodes
 * sharing an element with i) in the same layer-by-layer Gauss-Seidel update
 * as springs, each node reading its neighbours' newest positions.
 *
 * Co-rotational and neo-Hookean forces are evaluated element by element,
 * once per substep at the positions the substep starts from (the
 * displacement contacts and the far field's ring already placed), a block
 * of elements at a time in vector lanes (elem_kernel.h), and each node sums
 * its elements' forces: the update is plain central differences, the same
 * bits in every order. The forces of the elements evaluated for the
 * end-of-step check (neo-Hookean) are carried into the next step, except
 * those of elements with a node moved outside a sweep. An element with
 * J <= 0 at a quadrature point (neo-Hookean: inverted) fails the step, with
 * the guard or without: it is undone and substepped, and the positions a
 * step leaves are checked too (ftm_elem_intact). */
#include "sim_elem.h"

#include "elem_kernel.h"
#include "error.h"
#include "farfield.h"
#include "hyperelastic.h"

#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

struct ftm_elem {
    ftm_forces kind;
    int32_t count;   /* elements: hexahedra, then tetrahedra */
    int32_t *start;  /* element e: nodes node[start[e] .. start[e+1]-1] */
    int32_t *node;   /* mesh indices */
    size_t *koff;    /* element e: K_e (3 nn)^2 row-major at k + koff[e] (set-up) */
    double *k;
    int32_t *inc_start; /* node i: incidences inc_start[i] .. inc_start[i+1]-1 */
    int32_t *inc_elem;
    int32_t *inc_local; /* the node's index inside the element */
    int32_t *row_start; /* assembled rows: node i couples to row_node[row_start[i]..] */
    int32_t *row_node;
    double *row_k;      /* 9 per entry: the 3x3 block K_ij */
    double *mass;
    double h_crit;
    /* An instructor's stiffness change (ftm_sim_set_mesh): every element
     * model's forces are linear in E (K_e, and mu and kappa of the
     * neo-Hookean form, scale with it), so a factor on E is a factor on the
     * sum of a node's element forces. ref_k: the links the elements were
     * made with, against which a new mesh's links give the factor. */
    double scale;
    double *ref_k;
    /* set-up: element e's data for the blocks (elem_kernel.h) at gp + goff[e] */
    double *gp;
    size_t *goff;
    /* co-rotational and neo-Hookean: the elements in blocks, evaluated a
     * block at a time; inc_fe[q] is where the force record (x, y, z) of
     * incidence q is in eb.fe; node i's blocks are
     * node_blk[node_blk_start[i] ..] */
    ftm_elem_blocks eb;
    ftm_blocks_fn blocks;
    int lanes;
    int32_t *inc_fe;
    int32_t *node_blk_start, *node_blk;
    /* a block's forces are those of the current positions while
     * valid[b] == gen; next_generation starts a new generation, in which
     * every block must be evaluated again */
    uint32_t *valid;
    uint32_t gen;
    int32_t *list;      /* blocks to evaluate */
    uint32_t *bstamp;   /* per block: bgen when listed */
    uint32_t *inv_mark; /* per element: bgen when found inverted */
    uint32_t bgen;
    /* the blocks of the schedule's nodes, for the schedule of that version */
    int32_t *sched_blk, nsched_blk;
    uint32_t sched_version;
    bool sched_known;
    /* the blocks evaluated at the end of the last step (in generation gen)
     * are still those of the current positions: the next sweep reuses them
     * (ftm_elem_intact) */
    bool carry;
    bool inverted;    /* an element had J <= 0 since the last ftm_elem_intact */
    int32_t inv_elem; /* the first such element and its smallest J */
    double inv_det;
};

const double *ftm_elem_masses(const ftm_elem *el) { return el->mass; }
double ftm_elem_critical_step(const ftm_elem *el) { return el->h_crit; }

void ftm_elem_rows(const ftm_elem *el, const int32_t **start, const int32_t **node,
                   const double **k)
{
    *start = el->row_start;
    *node = el->row_node;
    *k = el->row_k;
}

void ftm_elem_free(ftm_elem *el)
{
    if (!el)
        return;
    free(el->start);
    free(el->node);
    free(el->koff);
    free(el->k);
    free(el->inc_start);
    free(el->inc_elem);
    free(el->inc_local);
    free(el->row_start);
    free(el->row_node);
    free(el->row_k);
    free(el->mass);
    free(el->ref_k);
    free(el->gp);
    free(el->goff);
    free(el->eb.lanes);
    free(el->eb.node);
    free(el->eb.gp);
    free(el->eb.rest);
    free(el->eb.mat);
    free(el->eb.elem_of);
    free(el->eb.place_of);
    free(el->eb.u);
    free(el->eb.fe);
    free(el->eb.det);
    free(el->eb.ok);
    free(el->inc_fe);
    free(el->node_blk_start);
    free(el->node_blk);
    free(el->valid);
    free(el->list);
    free(el->bstamp);
    free(el->inv_mark);
    free(el->sched_blk);
    free(el);
}

/* ---- generations ---- */

static void next_generation(ftm_elem *el)
{
    el->carry = false;
    if (!el->valid)
        return;
    if (++el->gen == 0) { /* wrapped: no block may look valid */
        memset(el->valid, 0, (size_t)el->eb.count * sizeof *el->valid);
        el->gen = 1;
    }
}

/* The blocks of node i's elements are stale (the node moved outside a
 * sweep): evaluated again at their next use. */
static void forget_node(ftm_elem *el, int32_t i)
{
    if (!el->valid)
        return;
    for (int32_t q = el->node_blk_start[i]; q < el->node_blk_start[i + 1]; q++)
        el->valid[el->node_blk[q]] = el->gen - 1; /* gen is never 0, so never gen */
}

static uint32_t next_block_generation(ftm_elem *el)
{
    if (++el->bgen == 0) {
        memset(el->bstamp, 0, (size_t)el->eb.count * sizeof *el->bstamp);
        memset(el->inv_mark, 0, (size_t)el->count * sizeof *el->inv_mark);
        el->bgen = 1;
    }
    return el->bgen;
}

/* ---- forces ---- */

/* Linear: f = sum_j K_ij (x_j - X_j) over the assembled row of node i. */
static inline void linear_force(const ftm_elem *restrict el, const ftm_mesh *restrict m,
                                const double *restrict x, int32_t i, double f[3])
{
    const double *rest = m->rest;
    double fx = 0.0, fy = 0.0, fz = 0.0;
    for (int32_t p = el->row_start[i]; p < el->row_start[i + 1]; p++) {
        const int32_t j = el->row_node[p];
        const double *kb = el->row_k + 9 * (size_t)p;
        double ux = x[3 * j] - rest[3 * j], uy = x[3 * j + 1] - rest[3 * j + 1],
               uz = x[3 * j + 2] - rest[3 * j + 2];
        fx += kb[0] * ux + kb[1] * uy + kb[2] * uz;
        fy += kb[3] * ux + kb[4] * uy + kb[5] * uz;
        fz += kb[6] * ux + kb[7] * uy + kb[8] * uz;
    }
    f[0] = fx;
    f[1] = fy;
    f[2] = fz;
}

/* Co-rotational and neo-Hookean: f = sum over the elements of i, in
 * element order, of their force on i in fe (prepared below). */
static inline void element_force(const ftm_elem *restrict el, const double *restrict fe,
                                 int32_t i, double f[3])
{
    /* a record (x, y, z) at a time, x and y as a pair: the same
     * additions, per axis, as one by one */
    typedef double v2 __attribute__((vector_size(16)));
    v2 xy = {0.0, 0.0};
    double fz = 0.0;
    for (int32_t q = el->inc_start[i]; q < el->inc_start[i + 1]; q++) {
        const double *fa = fe + el->inc_fe[q];
        v2 a;
        memcpy(&a, fa, sizeof a);
        xy += a;
        fz += fa[2];
    }
    f[0] = xy[0];
    f[1] = xy[1];
    f[2] = fz;
}

/* element_force of the w nodes node[0 .. w-1] into out (3 each), their
 * sums interleaved: each is one chain of dependent additions, which alone
 * would wait on every add. A record's x, y, z and the next record's x are
 * one vector, one load and one add a record: the fourth lane's sum is not
 * used (ftm_eb_alloc_fe pads the last record). The w run together for as
 * many records as all have, without a branch a record, then each its
 * rest alone. Each node's additions are element_force's, in order. */
static inline __attribute__((always_inline)) void
group_sums(const ftm_elem *restrict el, const double *restrict fe, const int32_t *restrict node,
           const int w, double *restrict out)
{
    typedef double v4 __attribute__((vector_size(32), aligned(8)));
    const int32_t *restrict inc = el->inc_fe;
    int32_t q[8], len[8], n = INT32_MAX;
    v4 acc[8];
    for (int j = 0; j < w; j++) {
        const int32_t i = node[j];
        q[j] = el->inc_start[i];
        len[j] = el->inc_start[i + 1] - q[j];
        n = len[j] < n ? len[j] : n;
        acc[j] = (v4){0.0, 0.0, 0.0, 0.0};
    }
    for (int32_t t = 0; t < n; t++)
        for (int j = 0; j < w; j++)
            acc[j] += *(const v4 *)(fe + inc[q[j] + t]);
    for (int j = 0; j < w; j++)
        for (int32_t t = n; t < len[j]; t++)
            acc[j] += *(const v4 *)(fe + inc[q[j] + t]);
    for (int j = 0; j < w; j++) {
        out[3 * j] = acc[j][0];
        out[3 * j + 1] = acc[j][1];
        out[3 * j + 2] = acc[j][2];
    }
}

static inline __attribute__((always_inline)) void
forces_of_body(const ftm_elem *restrict el, const double *restrict fe,
               const int32_t *restrict node, int32_t count, double *restrict out)
{
    int32_t k = 0;
    for (; k + 8 <= count; k += 8)
        group_sums(el, fe, node + k, 8, out + 3 * (size_t)k);
    for (; k + 4 <= count; k += 4)
        group_sums(el, fe, node + k, 4, out + 3 * (size_t)k);
    for (; k < count; k++)
        element_force(el, fe, node[k], out + 3 * (size_t)k);
}

static void forces_of_base(const ftm_elem *restrict el, const double *restrict fe,
                           const int32_t *restrict node, int32_t count, double *restrict out)
{
    forces_of_body(el, fe, node, count, out);
}

#if defined(__x86_64__) || defined(__i386__)
static __attribute__((target("avx2"))) void
forces_of_avx2(const ftm_elem *restrict el, const double *restrict fe,
               const int32_t *restrict node, int32_t count, double *restrict out)
{
    forces_of_body(el, fe, node, count, out);
}
#endif

/* element_force of count nodes into out (3 each), eight nodes' sums at a
 * time (group_sums), in 256-bit vectors where the processor has them (the
 * same bits per lane). */
static void element_forces_of(const ftm_elem *restrict el, const double *restrict fe,
                              const int32_t *restrict node, int32_t count, double *restrict out)
{
#if defined(__x86_64__) || defined(__i386__)
    if (__builtin_cpu_supports("avx2")) {
        forces_of_avx2(el, fe, node, count, out);
        return;
    }
#endif
    forces_of_base(el, fe, node, count, out);
}

static inline void node_force(const ftm_elem *el, const ftm_mesh *m, const double *x, int32_t i,
                              double f[3])
{
    if (el->kind == FTM_FORCES_LINEAR_FEM)
        linear_force(el, m, x, i, f);
    else
        element_force(el, el->eb.fe, i, f);
    if (el->scale != 1.0) {
        f[0] *= el->scale;
        f[1] *= el->scale;
        f[2] *= el->scale;
    }
}

static void note_inversion(ftm_elem *el, int32_t e, double det)
{
    if (!el->inverted) {
        el->inv_elem = e;
        el->inv_det = det;
    }
    el->inverted = true;
}

/* A node list for prepare(). */
typedef struct node_list {
    const int32_t *node;
    int32_t count;
} node_list;

/* Lists block b for evaluation unless valid or listed already. */
static inline void want_block(ftm_elem *el, int32_t b, uint32_t bg, int32_t *nb)
{
    if (el->valid[b] != el->gen && el->bstamp[b] != bg) {
        el->bstamp[b] = bg;
        el->list[(*nb)++] = b;
    }
}

static int cmp_block(const void *a, const void *b)
{
    const int32_t x = *(const int32_t *)a, y = *(const int32_t *)b;
    return (x > y) - (x < y);
}

/* The blocks of the schedule's nodes, once per schedule, ascending: their
 * data are then read as one forward stream (blocks are independent, so
 * the order changes no bits). */
static void schedule_blocks(ftm_elem *el, const schedule *s)
{
    if (el->sched_known && el->sched_version == s->version)
        return;
    const uint32_t bg = next_block_generation(el);
    int32_t nb = 0;
    for (int32_t k = 0; k < s->count; k++) {
        const int32_t i = s->node[k];
        for (int32_t q = el->node_blk_start[i]; q < el->node_blk_start[i + 1]; q++) {
            const int32_t b = el->node_blk[q];
            if (el->bstamp[b] != bg) {
                el->bstamp[b] = bg;
                el->sched_blk[nb++] = b;
            }
        }
    }
    qsort(el->sched_blk, (size_t)nb, sizeof *el->sched_blk, cmp_block);
    el->nsched_blk = nb;
    el->sched_version = s->version;
    el->sched_known = true;
}

/* Evaluates at x the blocks of the elements of the listed nodes (with
 * sched, first those of the schedule's nodes) that are not valid in this
 * generation; they become valid unless one of their elements is inverted.
 * No node of such an element moves between the start of a sweep and its
 * use, so this is what the scalar code did evaluating each element at its
 * first use. An element in use found inverted is noted, the first in the
 * lists' order (the order of first use), and the result is false. */
static bool prepare(ftm_elem *el, const ftm_sim *sim, bool sched, const node_list *lists,
                    int nlists)
{
    const uint32_t bg = next_block_generation(el);
    const ftm_elem_blocks *eb = &el->eb;
    int32_t nb = 0;
    if (sched) {
        schedule_blocks(el, &sim->s);
        for (int32_t k = 0; k < el->nsched_blk; k++)
            want_block(el, el->sched_blk[k], bg, &nb);
    }
    for (int li = 0; li < nlists; li++)
        for (int32_t k = 0; k < lists[li].count; k++) {
            const int32_t i = lists[li].node[k];
            for (int32_t q = el->node_blk_start[i]; q < el->node_blk_start[i + 1]; q++)
                want_block(el, el->node_blk[q], bg, &nb);
        }
    if (nb == 0)
        return true;
    el->blocks(&el->eb, el->list, nb, sim->x, sim->m->rest);
    if (eb->kind == FTM_EK_COROT) { /* (no element fails) */
        for (int32_t k = 0; k < nb; k++)
            el->valid[el->list[k]] = el->gen;
        return true;
    }
    bool bad = false;
    for (int32_t k = 0; k < nb; k++) {
        const int32_t b = el->list[k], e0 = ftm_eb_first(eb, b);
        bool all = true;
        for (int32_t l = 0; l < eb->lanes[b]; l++)
            if (!eb->ok[FTM_EB * (size_t)b + (size_t)l]) {
                el->inv_mark[ftm_eb_elem(eb, e0 + l)] = bg;
                all = false;
            }
        if (all)
            el->valid[b] = el->gen;
        bad |= !all;
    }
    if (!bad)
        return true;
    /* an inverted element: the first in use, in the order of use */
    const node_list sl = {sim->s.node, sched ? sim->s.count : 0};
    for (int li = -1; li < nlists; li++) {
        const node_list *l = li < 0 ? &sl : &lists[li];
        for (int32_t k = 0; k < l->count; k++) {
            const int32_t i = l->node[k];
            for (int32_t q = el->inc_start[i]; q < el->inc_start[i + 1]; q++) {
                const int32_t e = el->inc_elem[q];
                if (el->inv_mark[e] == bg) {
                    const int32_t b = ftm_eb_block(eb, e);
                    note_inversion(el, e, eb->det[FTM_EB * (size_t)b + (size_t)ftm_eb_lane(eb, e)]);
                    return false;
                }
            }
        }
    }
    return true; /* (inverted elements, none in use) */
}

/* Eq. 8 for node i (as in sim_kernel.c): returns the squared motion. */
static inline double integrate(const ftm_sim *sim, int32_t i, const double cur[3],
                               const double f[3], double out[3])
{
    const double *c = sim->coef + FTM_COEF * i, *F = sim->force + 3 * i, *p = sim->xp + 3 * i;
    for (int d = 0; d < 3; d++)
        out[d] = c[0] * (F[d] - f[d]) + c[1] * cur[d] - c[2] * p[d];
    double dx = out[0] - cur[0], dy = out[1] - cur[1], dz = out[2] - cur[2];
    return dx * dx + dy * dy + dz * dz;
}

/* One Gauss-Seidel update of node i; the overwritten previous position goes
 * to save[0], save[stride], save[2 stride] (the schedule's rollback layout). */
static inline bool update_node(ftm_sim *sim, int32_t i, double *save, int stride, double *mm,
                               const double *pre)
{
    double *xi = sim->x + 3 * i, *pi = sim->xp + 3 * i;
    double cur[3] = {xi[0], xi[1], xi[2]}, f[3], nw[3];
    if (pre) { /* element forces summed beforehand (element_forces_of) */
        const double sc = sim->elem->scale;
        for (int d = 0; d < 3; d++)
            f[d] = sc != 1.0 ? pre[d] * sc : pre[d];
    } else {
        node_force(sim->elem, sim->m, sim->x, i, f);
    }
    double ground;
    double m2 = sim->m->bc && sim->m->bc[i] ? ftm_bc_update(sim, i, cur, f, nw, &ground)
                                            : integrate(sim, i, cur, f, nw);
    *mm = m2 > *mm ? m2 : *mm;
    for (int d = 0; d < 3; d++) {
        if (save)
            save[d * stride] = pi[d];
        pi[d] = cur[d];
        xi[d] = nw[d];
    }
    return m2 <= ftm_sim_lim2(sim, i); /* false for NaN too */
}

/* update_node of every scheduled node in the colored order, its element
 * forces summed beforehand in pre (3 per position): block by block of the
 * group sweep's cut, so that each save slot comes without a division
 * (ftm_group_save's). False if a node moved more than its limit. */
static bool update_summed(ftm_sim *sim, const double *restrict pre, double *mm)
{
    const schedule *s = &sim->s;
    const int32_t w = sim->group_lanes;
    bool ok = true;
    for (int32_t g = 0, b = 0; g < s->groups; g++) {
        const int32_t k1 = s->group[g + 1];
        for (int32_t k = s->group[g]; k < k1; k += w, b++) {
            double *sv = s->save + 3 * (size_t)w * (size_t)b;
            const int32_t lanes = k1 - k < w ? k1 - k : w;
            for (int32_t l = 0; l < lanes; l++)
                ok &= update_node(sim, s->node[k + l], sv + l, w, mm,
                                  pre + 3 * (size_t)(k + l));
        }
    }
    return ok;
}

/* A held node (displacement contact, far-field ring) was just placed, its
 * old position in x_prev: the elements evaluated at the last step's end
 * still hold unless it moved (a probe held still, or a ring under
 * unchanged contacts, keeps them). */
static inline void forget_moved(ftm_elem *el, const ftm_sim *sim, int32_t i)
{
    const double *x = sim->x + 3 * i, *xp = sim->xp + 3 * i;
    if (x[0] != xp[0] || x[1] != xp[1] || x[2] != xp[2])
        forget_node(el, i);
}

bool ftm_elem_sweep(ftm_sim *sim, double *max_m2)
{
    ftm_elem *el = sim->elem;
    schedule *s = &sim->s;
    if (el->carry) { /* the last step's end: all but what was placed since */
        for (int32_t k = 0; k < sim->ndisp; k++)
            forget_moved(el, sim, sim->disp[k]);
        const int32_t nring = ftm_far_ring_count(sim->far); /* ftm_far_impose */
        for (int32_t k = 0; k < nring; k++)
            forget_moved(el, sim, ftm_far_ring_nodes(sim->far)[k]);
    } else {
        next_generation(el);
    }
    el->carry = false;
    bool ok = true;
    double mm = *max_m2;
    /* element forces do not depend on the positions the sweep writes: all
     * the schedule's, summed first */
    double *pre = NULL;
    if (el->kind != FTM_FORCES_LINEAR_FEM) { /* (an inversion is noted and fails the step) */
        prepare(el, sim, true, NULL, 0);
        if (sim->def.order != FTM_ORDER_LAYER_JACOBI) {
            pre = s->tmp;
            element_forces_of(el, el->eb.fe, s->node, s->count, pre);
        }
    }
    if (sim->def.order == FTM_ORDER_LAYER_COLORED && pre) {
        ok &= update_summed(sim, pre, &mm);
    } else if (sim->def.order == FTM_ORDER_LAYER_COLORED) {
        /* one node at a time in schedule order; save as the kernels do */
        const int32_t w = sim->group_lanes;
        for (int32_t g = 0, b0 = 0; g < s->groups; g++) {
            const int32_t k0 = s->group[g], k1 = s->group[g + 1];
            for (int32_t k = k0; k < k1; k++)
                ok &= update_node(sim, s->node[k], ftm_group_save(sim, b0, k0, k), w, &mm,
                                  pre ? pre + 3 * (size_t)k : NULL);
            b0 += ftm_group_blocks(sim, k0, k1);
        }
    } else if (sim->def.order == FTM_ORDER_BFS) {
        for (int32_t k = 0; k < s->count; k++)
            ok &= update_node(sim, s->node[k], s->save + 3 * (size_t)k, 1, &mm,
                              pre ? pre + 3 * (size_t)k : NULL);
    } else { /* Jacobi: each layer from the state before it; save as the kernels do */
        const int32_t w = sim->group_lanes;
        for (int32_t g = 0, b0 = 0; g < s->groups; g++) {
            for (int32_t k = s->group[g]; k < s->group[g + 1]; k++) {
                int32_t i = s->node[k];
                double f[3], ground;
                node_force(el, sim->m, sim->x, i, f);
                double m2 = sim->m->bc && sim->m->bc[i]
                                ? ftm_bc_update(sim, i, sim->x + 3 * i, f, s->tmp + 3 * k, &ground)
                                : integrate(sim, i, sim->x + 3 * i, f, s->tmp + 3 * k);
                ok &= m2 <= ftm_sim_lim2(sim, i);
                mm = m2 > mm ? m2 : mm;
            }
            const int32_t k0 = s->group[g], k1 = s->group[g + 1];
            for (int32_t k = k0; k < k1; k++) {
                int32_t i = s->node[k];
                double *xi = sim->x + 3 * i, *pi = sim->xp + 3 * i,
                       *sv = ftm_group_save(sim, b0, k0, k), *t = s->tmp + 3 * k;
                for (int d = 0; d < 3; d++) {
                    sv[d * w] = pi[d];
                    pi[d] = xi[d];
                    xi[d] = t[d];
                }
            }
            b0 += ftm_group_blocks(sim, k0, k1);
        }
    }
    *max_m2 = mm;
    return ok;
}

bool ftm_elem_sweep_relax(ftm_sim *sim)
{
    if (sim->nrelax == 0)
        return true;
    next_generation(sim->elem);
    if (sim->elem->kind != FTM_FORCES_LINEAR_FEM) {
        const node_list l = {sim->relax, sim->nrelax};
        prepare(sim->elem, sim, false, &l, 1);
    }
    bool ok = true;
    double mm = 0.0;
    for (int32_t r = 0; r < sim->nrelax; r++)
        ok &= update_node(sim, sim->relax[r], NULL, 1, &mm, NULL);
    return ok;
}

bool ftm_elem_intact(ftm_sim *sim, bool last, bool region_ran)
{
    ftm_elem *el = sim->elem;
    if (el->kind != FTM_FORCES_NEO_HOOKEAN)
        return true;
    bool ok = !el->inverted;
    if (ok && last) {
        /* the positions the step leaves, whose forces the next step starts
         * from: evaluated now (the check) and carried over. (The ring's
         * elements that hold a region node are among the region's; the
         * others give no scheduled node a force.) */
        next_generation(el);
        const node_list l[2] = {{sim->disp, region_ran ? sim->ndisp : 0},
                                {sim->relax, sim->nrelax}};
        ok = prepare(el, sim, region_ran, l, 2);
        el->carry = ok;
    }
    el->inverted = false;
    return ok;
}

void ftm_elem_node_moved(ftm_sim *sim, int32_t i)
{
    if (sim->elem)
        forget_node(sim->elem, i);
}

void ftm_elem_forget(ftm_sim *sim)
{
    if (sim->elem)
        sim->elem->carry = false;
}

int32_t ftm_elem_inversion(const ftm_sim *sim, char *what, size_t size, double *det)
{
    const ftm_elem *el = sim->elem;
    const ftm_mesh *m = sim->m;
    const int32_t e = el->inv_elem, s0 = el->start[e], nn = el->start[e + 1] - s0;
    const bool hex = e < m->hex_count;
    int w = snprintf(what, size, "%s %d (input nodes", hex ? "hexahedron" : "tetrahedron",
                     (int)(hex ? e : e - m->hex_count));
    for (int32_t a = 0; a < nn && w >= 0 && (size_t)w < size; a++)
        w += snprintf(what + w, size - (size_t)w, " %d",
                      (int)m->input_of_node[el->node[s0 + a]]);
    if (w >= 0 && (size_t)w < size)
        snprintf(what + w, size - (size_t)w, ")");
    *det = el->inv_det;
    return e;
}

void ftm_elem_reactions(ftm_sim *sim)
{
    if (sim->reaction_groups)
        memset(sim->reaction, 0, (size_t)sim->reaction_groups * 3 * sizeof(double));
    if (!sim->elem->carry) /* neo-Hookean: the step's end already evaluated */
        next_generation(sim->elem);
    if (sim->elem->kind != FTM_FORCES_LINEAR_FEM) {
        const node_list l = {sim->disp, sim->ndisp};
        prepare(sim->elem, sim, false, &l, 1);
    }
    for (int32_t c = 0; c < sim->ncontacts; c++) {
        const ftm_contact *ct = &sim->contacts[c];
        if (ct->kind != FTM_CONTACT_DISPLACEMENT)
            continue;
        double f[3];
        node_force(sim->elem, sim->m, sim->x, ct->node, f);
        if (sim->m->bc) /* a held node on a spring to ground pulls on it too */
            ftm_bc_ground_force(sim->m, ct->node, sim->x + 3 * ct->node, f);
        double *r = sim->reaction + 3 * ct->group;
        r[0] -= f[0];
        r[1] -= f[1];
        r[2] -= f[2];
    }
    sim->elem->inverted = false; /* the step was checked; this is a query */
}

/* ---- public queries ---- */

double ftm_sim_critical_time_step(const ftm_sim *sim)
{
    return sim->elem ? sim->elem->h_crit / sqrt(sim->elem->scale)
                     : ftm_mesh_critical_time_step(sim->m);
}

const double *ftm_sim_masses(const ftm_sim *sim)
{
    return sim->elem ? sim->elem->mass : sim->m->mass;
}

static int element_forces(const ftm_sim *sim, const double *x, double *f)
{
    const ftm_mesh *m = sim->m;
    const ftm_elem *el = sim->elem;
    if (!el) {
        memset(f, 0, (size_t)m->node_count * 3 * sizeof *f);
        for (int32_t l = 0; l < m->link_count; l++) {
            int32_t a = m->link_a[l], b = m->link_b[l];
            const double *xa = x + 3 * a, *xb = x + 3 * b;
            double rx = xa[0] - xb[0], ry = xa[1] - xb[1], rz = xa[2] - xb[2];
            double r = sqrt(rx * rx + ry * ry + rz * rz) + FTM_LEN_EPS;
            double t = m->link_k[l] * (r - m->link_len[l]) / r;
            f[3 * a] += t * rx;
            f[3 * a + 1] += t * ry;
            f[3 * a + 2] += t * rz;
            f[3 * b] -= t * rx;
            f[3 * b + 1] -= t * ry;
            f[3 * b + 2] -= t * rz;
        }
        return FTM_OK;
    }
    if (el->kind == FTM_FORCES_LINEAR_FEM) {
        for (int32_t i = 0; i < m->node_count; i++)
            linear_force(el, m, x, i, f + 3 * i);
        return FTM_OK;
    }
    /* every block from x into private results, then the sums per node in
     * the integrator's order; nothing written if an element is inverted */
    ftm_elem_blocks eb = el->eb;
    const size_t nb = (size_t)eb.count;
    const bool neo = eb.kind == FTM_EK_NEO; /* (co-rotational: ok and det are constants) */
    eb.fe = ftm_eb_alloc_fe(&eb);
    if (neo) {
        eb.det = malloc((FTM_EB * nb + 1) * sizeof *eb.det);
        eb.ok = malloc((FTM_EB * nb + 1) * sizeof *eb.ok);
    }
    eb.u = calloc(FTM_EB_U * (size_t)m->node_count + 1, sizeof *eb.u);
    int32_t *all = malloc((nb + 1) * sizeof *all);
    int rc = eb.fe && eb.det && eb.ok && eb.u && all ? FTM_OK : FTM_ENOMEM;
    if (!rc) {
        for (int32_t b = 0; b < eb.count; b++)
            all[b] = b;
        el->blocks(&eb, all, eb.count, x, m->rest);
        for (size_t b = 0; b < nb && !rc; b++)
            for (int32_t l = 0; l < eb.lanes[b]; l++)
                if (!eb.ok[FTM_EB * b + (size_t)l])
                    rc = FTM_EINVAL;
    }
    for (int32_t i = 0; !rc && i < m->node_count; i++)
        element_force(el, eb.fe, i, f + 3 * i);
    free(eb.fe);
    if (neo) {
        free(eb.det);
        free(eb.ok);
    }
    free(eb.u);
    free(all);
    return rc;
}

int ftm_sim_internal_forces(const ftm_sim *sim, const double *x, double *f)
{
    int rc = element_forces(sim, x, f);
    const ftm_elem *el = sim->elem;
    if (rc == FTM_OK && el && el->scale != 1.0)
        for (size_t k = 0; k < 3 * (size_t)sim->m->node_count; k++)
            f[k] *= el->scale;
    return rc;
}

double ftm_elem_scale(const ftm_elem *el) { return el->scale; }

int ftm_elem_set_mesh(ftm_sim *sim, const ftm_mesh *m, ftm_error *err)
{
    ftm_elem *el = sim->elem;
    double ratio = 0.0;
    for (int32_t l = 0; l < m->link_count; l++) {
        double q = m->link_k[l] / el->ref_k[l];
        if (l == 0)
            ratio = q;
        else if (q != ratio)
            return ftm_error_set(err, FTM_EINVAL,
                                 "sim set mesh: element forces change by one factor on E (every "
                                 "link's stiffness times the same factor); link %d changes by %g, "
                                 "link 0 by %g",
                                 (int)l, q, ratio);
    }
    if (!(ratio > 0.0) || !isfinite(ratio))
        return ftm_error_set(err, FTM_EINVAL, "sim set mesh: stiffness factor %g", ratio);
    if (sim->def.density > 0.0)
        for (int32_t i = 0; i < m->node_count; i++)
            if (m->mass[i] != sim->m->mass[i])
                return ftm_error_set(err, FTM_EINVAL,
                                     "sim set mesh: with element forces the masses come from the "
                                     "density (%g kg/m^3), not from the mesh (node %d: %g kg)",
                                     sim->def.density, (int)i, m->mass[i]);
    const double h = sim->def.time_step, hc = el->h_crit / sqrt(ratio);
    const int32_t most = sim->def.guard ? sim->def.max_substeps : 1;
    if (h > hc * most)
        return ftm_error_set(err, FTM_EINVAL,
                             "sim set mesh: E times %g gives a critical time step of %g s, too "
                             "short for time step %g s with at most %d substeps",
                             ratio, hc, h, (int)most);
    el->scale = ratio;
    if (!(sim->def.density > 0.0)) /* the mesh's masses, not lumped element ones */
        memcpy(el->mass, m->mass, (size_t)m->node_count * sizeof *el->mass);
    return FTM_OK;
}

/* ---- set-up ---- */

static int cmp_i32(const void *a, const void *b)
{
    int32_t x = *(const int32_t *)a, y = *(const int32_t *)b;
    return (x > y) - (x < y);
}

/* Element nodes, stiffness matrices and the data of the blocks
 * (elem_kernel.h) of co-rotational and neo-Hookean forces. */
/* Element e's label (hexahedra first, as el's order), 0 for none. */
static int32_t element_label(const ftm_mesh *m, int32_t e)
{
    if (e < m->hex_count)
        return m->hex_labels ? m->hex_labels[e] : 0;
    return m->tet_labels ? m->tet_labels[e - m->hex_count] : 0;
}

/* Per-label materials: each label once, >= 1, carried by an element, with
 * the constants the def's own need. */
static int check_label_materials(const ftm_mesh *m, const ftm_sim_def *d, ftm_error *err)
{
    const int32_t ne = m->hex_count + m->tet_count;
    for (int32_t i = 0; i < d->label_material_count; i++) {
        const ftm_label_material *lm = &d->label_materials[i];
        if (lm->label < 1)
            return ftm_error_set(err, FTM_EINVAL, "sim: label material %d: label %d (labels are >= 1)",
                                 (int)i, (int)lm->label);
        for (int32_t j = 0; j < i; j++)
            if (d->label_materials[j].label == lm->label)
                return ftm_error_set(err, FTM_EINVAL,
                                     "sim: label %d has two materials (%d and %d)",
                                     (int)lm->label, (int)j, (int)i);
        if (!(lm->young > 0.0) || !isfinite(lm->young))
            return ftm_error_set(err, FTM_EINVAL,
                                 "sim: label %d: Young's modulus must be > 0 (got %g)",
                                 (int)lm->label, lm->young);
        if (!(lm->poisson > -1.0) || !(lm->poisson < 0.5))
            return ftm_error_set(err, FTM_EINVAL,
                                 "sim: label %d: Poisson's ratio must be > -1 and < 0.5 (got %g)",
                                 (int)lm->label, lm->poisson);
        if (!(lm->density >= 0.0) || !isfinite(lm->density))
            return ftm_error_set(err, FTM_EINVAL,
                                 "sim: label %d: density must be >= 0 (got %g)", (int)lm->label,
                                 lm->density);
        if (lm->density > 0.0 && !(d->density > 0.0))
            return ftm_error_set(err, FTM_EINVAL,
                                 "sim: label %d has a density (%g kg/m^3), the body none: the "
                                 "other elements' masses would be the mesh's node masses; give "
                                 "the def a density too",
                                 (int)lm->label, lm->density);
        int32_t e = 0;
        while (e < ne && element_label(m, e) != lm->label)
            e++;
        if (e == ne)
            return ftm_error_set(err, FTM_EINVAL,
                                 "sim: label %d has a material, but no element of the mesh has "
                                 "that label",
                                 (int)lm->label);
    }
    return FTM_OK;
}

/* Element e's density: its label's if it has one, else the def's. */
static double element_density(const ftm_mesh *m, const ftm_sim_def *d, int32_t e)
{
    const int32_t label = element_label(m, e);
    for (int32_t i = 0; label > 0 && i < d->label_material_count; i++)
        if (d->label_materials[i].label == label && d->label_materials[i].density > 0.0)
            return d->label_materials[i].density;
    return d->density;
}

/* Lumped masses of the def's density, or of each element's own where a
 * label has one. */
static int lumped(const ftm_mesh *m, const ftm_sim_def *d, double *mass, ftm_error *err)
{
    bool each = false;
    for (int32_t i = 0; i < d->label_material_count; i++)
        each |= d->label_materials[i].density > 0.0;
    if (!each)
        return ftm_mesh_lumped_masses(m, d->density, mass, err);
    const int32_t ne = m->hex_count + m->tet_count;
    double *rho = malloc(((size_t)ne + 1) * sizeof *rho);
    if (!rho)
        return ftm_error_set(err, FTM_ENOMEM, "sim: out of memory");
    for (int32_t e = 0; e < ne; e++)
        rho[e] = element_density(m, d, e);
    int rc = ftm_mesh_lumped_masses_each(m, rho, mass, err);
    free(rho);
    return rc;
}

/* Element e's elastic constants: its label's, else the def's. */
static void element_material(const ftm_mesh *m, const ftm_sim_def *d, int32_t e, double *young,
                             double *poisson)
{
    *young = d->young;
    *poisson = d->poisson;
    if (d->label_material_count == 0)
        return;
    const int32_t label = element_label(m, e);
    for (int32_t i = 0; label > 0 && i < d->label_material_count; i++)
        if (d->label_materials[i].label == label) {
            *young = d->label_materials[i].young;
            *poisson = d->label_materials[i].poisson;
            return;
        }
}

static int build_elements(ftm_elem *el, const ftm_mesh *m, const ftm_sim_def *d, ftm_error *err)
{
    int32_t ne = m->hex_count + m->tet_count;
    size_t nodes = (size_t)m->hex_count * 8 + (size_t)m->tet_count * 4;
    size_t kn = (size_t)m->hex_count * 576 + (size_t)m->tet_count * 144;
    el->count = ne;
    int lrc = check_label_materials(m, d, err);
    if (lrc)
        return lrc;
    el->start = malloc(((size_t)ne + 1) * sizeof *el->start);
    el->node = malloc((nodes + 1) * sizeof *el->node);
    el->koff = malloc(((size_t)ne + 1) * sizeof *el->koff);
    el->k = malloc((kn + 1) * sizeof *el->k);
    if (!el->start || !el->node || !el->koff || !el->k)
        return ftm_error_set(err, FTM_ENOMEM, "sim: out of memory for %d elements", (int)ne);
    const bool neo = el->kind == FTM_FORCES_NEO_HOOKEAN;
    const size_t hex_gp = neo ? FTM_NEO_HEX_GP : FTM_COROT_HEX_GP;
    if (el->kind != FTM_FORCES_LINEAR_FEM) {
        el->goff = malloc(((size_t)ne + 1) * sizeof *el->goff);
        el->gp = malloc(((size_t)m->hex_count * hex_gp + (size_t)m->tet_count * FTM_TET_GP + 1) *
                        sizeof *el->gp);
        if (!el->goff || !el->gp)
            return ftm_error_set(err, FTM_ENOMEM, "sim: out of memory for %d elements", (int)ne);
        size_t off = 0;
        for (int32_t e = 0; e <= ne; e++) {
            el->goff[e] = off;
            off += e < m->hex_count ? hex_gp : FTM_TET_GP;
        }
    }
    size_t p = 0, ko = 0;
    for (int32_t e = 0; e < ne; e++) {
        bool hex = e < m->hex_count;
        int nn = hex ? 8 : 4;
        const int32_t *src = hex ? m->hexes + 8 * (size_t)e : m->tets + 4 * (size_t)(e - m->hex_count);
/* the node numbers the user's file or builder gave */
#define IN(a) ((int)m->input_of_node[src[a]])
        ftm_vec3 x[8];
        el->start[e] = (int32_t)p;
        el->koff[e] = ko;
        for (int a = 0; a < nn; a++) {
            el->node[p + (size_t)a] = src[a];
            const double *r = m->rest + 3 * (size_t)src[a];
            x[a] = (ftm_vec3){r[0], r[1], r[2]};
        }
        double *dst = el->gp ? el->gp + el->goff[e] : NULL;
        double young, poisson;
        element_material(m, d, e, &young, &poisson);
        int rc;
        if (hex) {
            double min_det;
            rc = ftm_hex8_stiffness(x, young, poisson, el->k + ko, &min_det);
            if (!rc && neo) { /* per Gauss point: 24 gradients, then det J (weight 1) */
                double g[192], det[8];
                rc = ftm_hex8_gauss_gradients(x, g, det);
                for (int q = 0; !rc && q < 8; q++) {
                    memcpy(dst + 25 * q, g + 24 * q, 24 * sizeof *g);
                    dst[25 * q + 24] = det[q];
                }
            } else if (!rc && dst) { /* J^-1 at the Gauss points and the centre, the weights */
                rc = ftm_hex8_inverse_jacobians(x, dst, dst + 81);
            }
            if (rc)
                return ftm_error_set(err, FTM_EINVAL,
                                     "sim: hexahedron %d (input nodes %d %d %d %d %d %d %d %d) is "
                                     "inverted or degenerate: Jacobian determinant %g",
                                     (int)e, IN(0), IN(1), IN(2), IN(3), IN(4), IN(5), IN(6),
                                     IN(7), min_det);
        } else {
            double vol;
            rc = ftm_tet4_stiffness(x, young, poisson, el->k + ko, &vol);
            if (!rc && dst) { /* one point: the 12 gradients, then the volume */
                rc = ftm_tet4_gradients(x, dst);
                dst[12] = fabs(vol);
            }
            if (rc)
                return ftm_error_set(err, FTM_EINVAL,
                                     "sim: tetrahedron %d (input nodes %d %d %d %d) is degenerate",
                                     (int)(e - m->hex_count), IN(0), IN(1), IN(2), IN(3));
        }
        p += (size_t)nn;
        ko += (size_t)(9 * nn * nn);
    }
#undef IN
    el->start[ne] = (int32_t)p;
    el->koff[ne] = ko;
    return FTM_OK;
}

/* Per-node incidence (element, local index) in element order. */
static int build_incidence(ftm_elem *el, int32_t n, ftm_error *err)
{
    size_t total = (size_t)el->start[el->count];
    el->inc_start = calloc((size_t)n + 1, sizeof *el->inc_start);
    el->inc_elem = malloc((total + 1) * sizeof *el->inc_elem);
    el->inc_local = malloc((total + 1) * sizeof *el->inc_local);
    if (!el->inc_start || !el->inc_elem || !el->inc_local)
        return ftm_error_set(err, FTM_ENOMEM, "sim: out of memory for element incidence");
    for (size_t p = 0; p < total; p++)
        el->inc_start[el->node[p] + 1]++;
    for (int32_t i = 0; i < n; i++)
        el->inc_start[i + 1] += el->inc_start[i];
    int32_t *fill = malloc(((size_t)n + 1) * sizeof *fill);
    if (!fill)
        return ftm_error_set(err, FTM_ENOMEM, "sim: out of memory for element incidence");
    memcpy(fill, el->inc_start, (size_t)n * sizeof *fill);
    for (int32_t e = 0; e < el->count; e++)
        for (int32_t p = el->start[e]; p < el->start[e + 1]; p++) {
            int32_t q = fill[el->node[p]]++;
            el->inc_elem[q] = e;
            el->inc_local[q] = p - el->start[e];
        }
    free(fill);
    return FTM_OK;
}

/* Assembled rows: for each node its coupled nodes (sorted) and 3x3 blocks,
 * summed over its elements in incidence order. */
static int build_rows(ftm_elem *el, int32_t n, ftm_error *err)
{
    int32_t *tmp = NULL;
    size_t cap = 0, total = 0;
    el->row_start = malloc(((size_t)n + 1) * sizeof *el->row_start);
    if (!el->row_start)
        return ftm_error_set(err, FTM_ENOMEM, "sim: out of memory for element rows");
    /* pass 1: counts */
    int32_t maxc = 0;
    for (int32_t i = 0; i < n; i++) {
        int32_t c = 0;
        for (int32_t q = el->inc_start[i]; q < el->inc_start[i + 1]; q++)
            c += el->start[el->inc_elem[q] + 1] - el->start[el->inc_elem[q]];
        maxc = c > maxc ? c : maxc;
    }
    tmp = malloc(((size_t)maxc + 1) * sizeof *tmp);
    if (!tmp)
        return ftm_error_set(err, FTM_ENOMEM, "sim: out of memory for element rows");
    for (int pass = 0; pass < 2; pass++) {
        total = 0;
        for (int32_t i = 0; i < n; i++) {
            int32_t c = 0;
            for (int32_t q = el->inc_start[i]; q < el->inc_start[i + 1]; q++) {
                int32_t e = el->inc_elem[q];
                for (int32_t p = el->start[e]; p < el->start[e + 1]; p++)
                    tmp[c++] = el->node[p];
            }
            qsort(tmp, (size_t)c, sizeof *tmp, cmp_i32);
            int32_t u = 0;
            for (int32_t t = 0; t < c; t++)
                if (u == 0 || tmp[t] != tmp[u - 1])
                    tmp[u++] = tmp[t];
            el->row_start[i] = (int32_t)total;
            if (pass == 1) {
                memcpy(el->row_node + total, tmp, (size_t)u * sizeof *tmp);
                for (int32_t q = el->inc_start[i]; q < el->inc_start[i + 1]; q++) {
                    int32_t e = el->inc_elem[q], a = el->inc_local[q];
                    int32_t s0 = el->start[e], nn = el->start[e + 1] - s0, w = 3 * nn;
                    const double *k = el->k + el->koff[e];
                    for (int32_t b = 0; b < nn; b++) {
                        int32_t j = el->node[s0 + b];
                        const int32_t *hit = bsearch(&j, el->row_node + total, (size_t)u,
                                                     sizeof j, cmp_i32);
                        double *blk = el->row_k + 9 * (total + (size_t)(hit - (el->row_node + total)));
                        for (int r = 0; r < 3; r++)
                            for (int c2 = 0; c2 < 3; c2++)
                                blk[3 * r + c2] += k[(size_t)(3 * a + r) * (size_t)w + (size_t)(3 * b + c2)];
                    }
                }
            }
            total += (size_t)u;
        }
        el->row_start[n] = (int32_t)total;
        if (pass == 0) {
            cap = total;
            el->row_node = malloc((cap + 1) * sizeof *el->row_node);
            el->row_k = calloc(cap * 9 + 1, sizeof *el->row_k);
            if (!el->row_node || !el->row_k) {
                free(tmp);
                return ftm_error_set(err, FTM_ENOMEM, "sim: out of memory for element rows");
            }
        }
    }
    free(tmp);
    return FTM_OK;
}

/* An element's place in the Morton order: the key of its centroid, then
 * its number (no two equal). */
typedef struct placed {
    uint64_t key;
    int32_t e;
} placed;

static int cmp_placed(const void *a, const void *b)
{
    const placed *x = a, *y = b;
    if (x->key != y->key)
        return x->key < y->key ? -1 : 1;
    return (x->e > y->e) - (x->e < y->e);
}

/* 21 bits of v spread to every third bit */
static uint64_t spread3(uint64_t v)
{
    v &= 0x1fffff;
    v = (v | v << 32) & 0x1f00000000ffffULL;
    v = (v | v << 16) & 0x1f0000ff0000ffULL;
    v = (v | v << 8) & 0x100f00f00f00f00fULL;
    v = (v | v << 4) & 0x10c30c30c30c30c3ULL;
    v = (v | v << 2) & 0x1249249249249249ULL;
    return v;
}

/* eb->elem_of and place_of: hexahedra and tetrahedra each in the Morton
 * order of their centroids over the mesh's bounding box (elem_kernel.h says
 * why). Integer keys from + - * / of the rest positions: the same places on
 * every machine (and they change no result anyway). Nonzero: out of memory. */
static int place_elements(const ftm_elem *el, const ftm_mesh *m, ftm_elem_blocks *eb)
{
    double lo[3] = {INFINITY, INFINITY, INFINITY}, hi[3] = {-INFINITY, -INFINITY, -INFINITY};
    for (int32_t i = 0; i < m->node_count; i++)
        for (int c = 0; c < 3; c++) {
            lo[c] = fmin(lo[c], m->rest[3 * (size_t)i + (size_t)c]);
            hi[c] = fmax(hi[c], m->rest[3 * (size_t)i + (size_t)c]);
        }
    placed *pl = malloc(((size_t)el->count + 1) * sizeof *pl);
    if (!pl)
        return -1;
    for (int32_t e = 0; e < el->count; e++) {
        const int32_t a0 = el->start[e], nn = el->start[e + 1] - a0;
        uint64_t key = 0;
        for (int c = 0; c < 3; c++) {
            double s = 0.0;
            for (int32_t a = 0; a < nn; a++)
                s += m->rest[3 * (size_t)el->node[a0 + a] + (size_t)c];
            const double span = hi[c] - lo[c];
            double t = span > 0.0 ? (s / nn - lo[c]) / span : 0.0;
            t = t < 0.0 ? 0.0 : t > 1.0 ? 1.0 : t;
            key |= spread3((uint64_t)(t * 2097151.0)) << c;
        }
        pl[e] = (placed){key, e};
    }
    qsort(pl, (size_t)m->hex_count, sizeof *pl, cmp_placed);
    qsort(pl + m->hex_count, (size_t)(el->count - m->hex_count), sizeof *pl, cmp_placed);
    for (int32_t p = 0; p < el->count; p++) {
        eb->elem_of[p] = pl[p].e;
        eb->place_of[pl[p].e] = p;
    }
    free(pl);
    return 0;
}

/* The elements in blocks (elem_kernel.h), lane-minor: their nodes and the
 * data el->gp held per element (freed here); where each incidence's forces
 * are; each node's blocks. */
static int build_blocks(ftm_elem *el, const ftm_mesh *m, const ftm_sim_def *d, ftm_error *err)
{
    ftm_elem_blocks *eb = &el->eb;
    const bool neo = el->kind == FTM_FORCES_NEO_HOOKEAN;
    eb->kind = neo ? FTM_EK_NEO : FTM_EK_COROT;
    eb->hex_gp = neo ? FTM_NEO_HEX_GP : FTM_COROT_HEX_GP;
    eb->hex_count = m->hex_count;
    eb->hex_blocks = (m->hex_count + FTM_EB - 1) / FTM_EB;
    eb->count = eb->hex_blocks + (m->tet_count + FTM_EB - 1) / FTM_EB;
    const size_t nb = (size_t)eb->count, slots = FTM_EB * ftm_eb_node_off(eb, eb->count);
    const size_t ninc = (size_t)el->start[el->count];
    eb->lanes = malloc((nb + 1) * sizeof *eb->lanes);
    eb->node = malloc((slots + 1) * sizeof *eb->node);
    eb->fe = ftm_eb_alloc_fe(eb);
    eb->det = calloc(FTM_EB * nb + 1, sizeof *eb->det);
    eb->ok = calloc(FTM_EB * nb + 1, sizeof *eb->ok);
    eb->gp = calloc(FTM_EB * ftm_eb_gp_off(eb, eb->count) + 1, sizeof *eb->gp);
    eb->rest = calloc(3 * slots + 1, sizeof *eb->rest);
    eb->mat = malloc((FTM_EB_MAT * FTM_EB * nb + 1) * sizeof *eb->mat);
    eb->nodes = m->node_count;
    eb->u = calloc(FTM_EB_U * (size_t)m->node_count + 1, sizeof *eb->u);
    el->inc_fe = malloc((ninc + 1) * sizeof *el->inc_fe);
    el->node_blk_start = malloc(((size_t)m->node_count + 1) * sizeof *el->node_blk_start);
    el->node_blk = malloc((ninc + 1) * sizeof *el->node_blk);
    el->valid = calloc(nb + 1, sizeof *el->valid);
    el->list = malloc((nb + 1) * sizeof *el->list);
    el->bstamp = calloc(nb + 1, sizeof *el->bstamp);
    el->inv_mark = calloc((size_t)el->count + 1, sizeof *el->inv_mark);
    el->sched_blk = malloc((nb + 1) * sizeof *el->sched_blk);
    eb->elem_of = malloc(((size_t)el->count + 1) * sizeof *eb->elem_of);
    eb->place_of = malloc(((size_t)el->count + 1) * sizeof *eb->place_of);
    if (!eb->lanes || !eb->node || !eb->fe || !eb->det || !eb->ok || !eb->gp || !eb->rest || !eb->mat || !eb->u || !el->inc_fe ||
        !eb->elem_of || !eb->place_of ||
        !el->node_blk_start || !el->node_blk || !el->valid || !el->list || !el->bstamp ||
        !el->inv_mark || !el->sched_blk)
        return ftm_error_set(err, FTM_ENOMEM, "sim: out of memory for %d element blocks",
                             (int)nb);
    if (place_elements(el, m, eb)) {
        free(eb->elem_of); /* (out of memory for the sort: places are elements) */
        free(eb->place_of);
        eb->elem_of = eb->place_of = NULL;
    }
    if (!neo) /* (co-rotational elements never fail: set once, not per evaluation) */
        for (size_t k = 0; k < FTM_EB * (size_t)nb; k++) {
            eb->ok[k] = -1;
            eb->det[k] = 1.0;
        }
    for (int32_t b = 0; b < eb->count; b++) {
        const bool hex = ftm_eb_hex(eb, b);
        const int32_t e0 = ftm_eb_first(eb, b), e1 = hex ? eb->hex_count : el->count;
        const int32_t lanes = e1 - e0 < FTM_EB ? e1 - e0 : FTM_EB;
        const int nn = ftm_eb_nodes(eb, b), gn = hex ? eb->hex_gp : FTM_TET_GP;
        eb->lanes[b] = lanes;
        int32_t *node = eb->node + FTM_EB * ftm_eb_node_off(eb, b);
        for (int l = 0; l < FTM_EB; l++) {
            const int32_t e = ftm_eb_elem(eb, e0 + (l < lanes ? l : 0)); /* a spare lane repeats lane 0 */
            for (int a = 0; a < nn; a++) {
                const int32_t i = el->node[el->start[e] + a];
                node[FTM_EB * a + l] = i;
                for (int c = 0; c < 3; c++)
                    eb->rest[FTM_EB * (3 * ftm_eb_node_off(eb, b) + 3 * (size_t)a + (size_t)c) +
                             (size_t)l] = m->rest[3 * (size_t)i + (size_t)c];
            }
            /* the element's own constants (the same expressions for every
             * element, so one material gives every lane the same bits) */
            double young, nu;
            element_material(m, d, e, &young, &nu);
            double *mat = eb->mat + FTM_EB * FTM_EB_MAT * (size_t)b + (size_t)l;
            mat[FTM_EB * FTM_EB_MU] = young / (2.0 * (1.0 + nu));
            mat[FTM_EB * FTM_EB_KAPPA] = young / (3.0 * (1.0 - 2.0 * nu));
            mat[FTM_EB * FTM_EB_LAMBDA] = young * nu / ((1.0 + nu) * (1.0 - 2.0 * nu));
            if (l < lanes) {
                double *gp = eb->gp + FTM_EB * ftm_eb_gp_off(eb, b) + (size_t)l;
                for (int k = 0; k < gn; k++)
                    gp[FTM_EB * k] = el->gp[el->goff[e] + (size_t)k];
                if (!neo && !hex) { /* (w is slot 12: the products the kernel formed) */
                    gp[FTM_EB * FTM_COROT_TET_WL] = gp[FTM_EB * 12] * mat[FTM_EB * FTM_EB_LAMBDA];
                    gp[FTM_EB * FTM_COROT_TET_WM] = gp[FTM_EB * 12] * mat[FTM_EB * FTM_EB_MU];
                }
            }
        }
    }
    /* per node: its incidences' places in eb.fe, and its distinct blocks */
    size_t nbk = 0;
    for (int32_t i = 0; i < m->node_count; i++) {
        el->node_blk_start[i] = (int32_t)nbk;
        for (int32_t q = el->inc_start[i]; q < el->inc_start[i + 1]; q++) {
            const int32_t e = el->inc_elem[q], b = ftm_eb_block(eb, e);
            el->inc_fe[q] =
                (int32_t)ftm_eb_fe(eb, b, el->inc_local[q], ftm_eb_lane(eb, e));
            bool seen = false;
            for (size_t t = (size_t)el->node_blk_start[i]; t < nbk && !seen; t++)
                seen = el->node_blk[t] == b;
            if (!seen)
                el->node_blk[nbk++] = b;
        }
    }
    el->node_blk_start[m->node_count] = (int32_t)nbk;
    free(el->gp);
    free(el->goff);
    el->gp = NULL;
    el->goff = NULL;
    el->blocks = ftm_blocks_kernel(eb->kind, FTM_ELEM_KERNEL_BEST, &el->lanes);
    return FTM_OK;
}

void ftm_elem_select_kernel(ftm_elem *el, ftm_elem_kernel which)
{
    if (el->kind != FTM_FORCES_LINEAR_FEM)
        el->blocks = ftm_blocks_kernel(el->eb.kind, which, &el->lanes);
}

/* Node i's Gershgorin row of M^-1/2 K M^-1/2: the largest over its three
 * rows of sum_j |K_ij| / sqrt(m_i m_j). */
static double gershgorin_row(const ftm_elem *el, const ftm_mesh *m, int32_t i)
{
    double li = 0.0;
    for (int r = 0; r < 3; r++) {
        double s = 0.0;
        for (int32_t p = el->row_start[i]; p < el->row_start[i + 1]; p++) {
            const double *kb = el->row_k + 9 * (size_t)p + 3 * r;
            double sc = 1.0 / sqrt(el->mass[i] * el->mass[el->row_node[p]]);
            s += (fabs(kb[0]) + fabs(kb[1]) + fabs(kb[2])) * sc;
        }
        if (m->ground_k) /* a spring to ground: k_g / m_i on the diagonal */
            s += m->ground_k[i] / el->mass[i];
        li = s > li ? s : li;
    }
    return li;
}

/* Selective mass scaling (ftm_sim_def.mass_scaling): the nodes whose row
 * bounds the critical step below h get mass until every row allows h. A
 * node's row falls at least as 1/sqrt of its mass factor f (its diagonal as
 * 1/f), so a round that multiplies the offending masses by their excess
 * halves the logarithm of the excess or better, and close to the least mass
 * that does it; a last round by the square of what is left settles it. The
 * neighbours' rows only fall with it. In node order, with + - * / and sqrt:
 * the same masses on every machine. */
static void scale_masses(ftm_elem *el, const ftm_sim *sim)
{
    const ftm_mesh *m = sim->m;
    const double h = sim->def.time_step, lim = 4.0 / (h * h) * (1.0 - 1e-9);
    double before = 0.0, after = 0.0;
    int32_t scaled = 0;
    uint8_t *hit = calloc((size_t)m->node_count + 1, 1);
    if (!hit)
        return; /* nothing scaled: the guard substeps, as without it */
    for (int32_t i = 0; i < m->node_count; i++)
        before += m->fixed[i] ? 0.0 : el->mass[i];
    for (int round = 0; round <= 40; round++) {
        bool again = false;
        for (int32_t i = 0; i < m->node_count; i++) {
            if (m->fixed[i])
                continue;
            double li = gershgorin_row(el, m, i);
            if (li > lim) {
                double f = li / lim;
                el->mass[i] *= round < 40 ? f : f * f;
                hit[i] = 1;
                again = true;
            }
        }
        if (!again)
            break;
    }
    for (int32_t i = 0; i < m->node_count; i++) {
        after += m->fixed[i] ? 0.0 : el->mass[i];
        scaled += hit[i];
    }
    free(hit);
    if (scaled > 0)
        ftm_logf(sim->def.log, sim->def.log_user, FTM_LOG_INFO,
                 "mass scaling: %d of %d nodes given mass for a critical step of %g s: "
                 "%.3g %% more mass in all",
                 (int)scaled, (int)m->node_count, h, 100.0 * (after - before) / before);
}

/* Gershgorin bound on the largest eigenvalue of M^-1/2 K M^-1/2 over the
 * free nodes' rows (h_crit = 2 / sqrt(lambda)), and the same low-damping
 * warning as springs (sim.c: d/2m >= 0.055 lambda_i h) where the update is
 * Gauss-Seidel. */
static void bound_and_warn(ftm_elem *el, const ftm_sim *sim)
{
    const ftm_mesh *m = sim->m;
    double lmax = 0.0, worst_ratio = INFINITY, need = 0.0;
    int32_t worst = -1;
    for (int32_t i = 0; i < m->node_count; i++) {
        if (m->fixed[i])
            continue;
        double li = gershgorin_row(el, m, i);
        lmax = li > lmax ? li : lmax;
        double required = 0.055 * li * sim->def.time_step;
        double ratio = m->damping[i] / (2.0 * el->mass[i]) / required;
        if (li > 0.0 && ratio < worst_ratio) {
            worst_ratio = ratio;
            worst = i;
            need = required;
        }
    }
    el->h_crit = lmax > 0.0 ? 2.0 / sqrt(lmax) : INFINITY;
    /* co-rotational and neo-Hookean forces are evaluated at the substep's
     * start (plain central differences): no Gauss-Seidel coupling to damp
     * (docs/calculix.md: undamped at half the critical step, bounded where
     * linear-fem diverges) */
    if (worst >= 0 && worst_ratio < 1.0 && el->kind == FTM_FORCES_LINEAR_FEM)
        ftm_logf(sim->def.log, sim->def.log_user, FTM_LOG_WARN,
                 "nodal damping is low for the layer-by-layer update with element forces at this "
                 "time step (node %d: d/2m = %g, needs about %g): the scene may slowly gain "
                 "energy; raise damping or shorten the time step (docs/stability.md)",
                 (int)worst, m->damping[worst] / (2.0 * el->mass[worst]), need);
}

int ftm_elem_create(ftm_sim *sim, ftm_error *err)
{
    const ftm_sim_def *d = &sim->def;
    const ftm_mesh *m = sim->m;
    if (d->forces != FTM_FORCES_LINEAR_FEM && d->forces != FTM_FORCES_COROT_FEM &&
        d->forces != FTM_FORCES_NEO_HOOKEAN)
        return ftm_error_set(err, FTM_EINVAL, "sim: unknown forces %d", (int)d->forces);
    if (!(d->young > 0.0) || !isfinite(d->young))
        return ftm_error_set(err, FTM_EINVAL,
                             "sim: element forces need Young's modulus > 0 (got %g)", d->young);
    if (!(d->poisson > -1.0) || !(d->poisson < 0.5))
        return ftm_error_set(err, FTM_EINVAL,
                             "sim: element forces need Poisson's ratio > -1 and < 0.5 (got %g)",
                             d->poisson);
    if (!(d->density >= 0.0) || !isfinite(d->density))
        return ftm_error_set(err, FTM_EINVAL, "sim: density must be >= 0 (got %g)", d->density);
    if (m->hex_count + m->tet_count == 0)
        return ftm_error_set(err, FTM_EINVAL,
                             "sim: element forces need hexahedra or tetrahedra, the mesh has none");
    ftm_elem *el = calloc(1, sizeof *el);
    if (!el)
        return ftm_error_set(err, FTM_ENOMEM, "sim: out of memory");
    el->kind = d->forces;
    int32_t n = m->node_count;
    int rc = build_elements(el, m, d, err);
    if (!rc)
        rc = build_incidence(el, n, err);
    if (!rc)
        rc = build_rows(el, n, err);
    if (!rc) {
        el->mass = malloc(((size_t)n + 1) * sizeof *el->mass);
        if (!el->mass)
            rc = ftm_error_set(err, FTM_ENOMEM, "sim: out of memory");
        else if (d->density > 0.0)
            rc = lumped(m, d, el->mass, err);
        else
            memcpy(el->mass, m->mass, (size_t)n * sizeof *el->mass);
    }
    for (int32_t i = 0; !rc && i < n; i++)
        if (!m->fixed[i] && el->inc_start[i] == el->inc_start[i + 1])
            rc = ftm_error_set(err, FTM_EINVAL,
                               "sim: node %d (input index %d) belongs to no element and is not "
                               "fixed: element forces cannot hold it",
                               (int)i, (int)m->input_of_node[i]);
    if (!rc && d->forces != FTM_FORCES_LINEAR_FEM)
        rc = build_blocks(el, m, d, err);
    el->scale = 1.0;
    el->ref_k = malloc(((size_t)m->link_count + 1) * sizeof *el->ref_k);
    if (!rc && !el->ref_k)
        rc = ftm_error_set(err, FTM_ENOMEM, "sim: out of memory");
    if (!rc)
        memcpy(el->ref_k, m->link_k, (size_t)m->link_count * sizeof *el->ref_k);
    if (rc) {
        ftm_elem_free(el);
        return rc;
    }
    el->gen = 1;
    if (d->mass_scaling)
        scale_masses(el, sim);
    bound_and_warn(el, sim); /* the others' tangent at rest is the linear K */
    free(el->k); /* the element matrices have served (the rows hold them) */
    free(el->koff);
    el->k = NULL;
    el->koff = NULL;
    if (el->kind != FTM_FORCES_LINEAR_FEM && d->far_field != FTM_FAR_FIELD_ELASTIC) {
        free(el->row_k); /* (the elastic far field's compliance needs the rows) */
        el->row_k = NULL;
    }
    sim->elem = el;
    return FTM_OK;
}
