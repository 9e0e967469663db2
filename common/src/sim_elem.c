/* SPDX-License-Identifier: GPL-3.0-or-later */
/* Element forces in the force transmittal integrator (beyond the paper).
 *
 * Instead of springs, a node's internal force is the sum over its elements of
 * the element force rows: linear, f_e = K_e (x_e - X_e), with the element
 * stiffness of the linear FEM reference (element.c), or co-rotational,
 * f_e = R K_e (R^T x_e - X_e), R the rotation of the element's deformation
 * gradient at its centre (polar decomposition). The update is the same
 * layer-by-layer Gauss-Seidel central difference as with springs, in the
 * same schedule, so at full depth its equilibrium is K u = f exactly: the
 * FEM solution. docs/accuracy.md has the measurements.
 *
 * Linear forces use the assembled rows (node i: sum_j K_ij u_j over the nodes
 * sharing an element with i), which is the same sum in fewer operations.
 * Co-rotational forces go element by element with per-node incidence lists;
 * each element's rotation is computed once per substep, from the positions
 * at its first use in the sweep (fixed order, so deterministic).
 *
 * Neo-Hookean forces (hyperelastic.c) are total Lagrangian:
 * f_a = sum_q w_q P(F_q) grad N_a(X_q), F_q from the rest gradients at the
 * quadrature points of the linear elements (2x2x2 Gauss on hexahedra, one
 * point on tetrahedra), so their tangent at rest is the linear K_e. Each
 * element's nodal forces are computed once per substep, at the element's
 * first use, and summed per node from that cache. No scheduled node of an
 * element has moved before its first use, so every element is evaluated at
 * the positions the substep started from (the displacement contacts
 * already placed): the forces are those of plain central differences, the
 * same in every order. An element with J <= 0 at a quadrature point
 * (inverted) fails the step, with the guard or without: it is undone and
 * substepped, and the positions a step leaves are checked too
 * (ftm_elem_intact). */
#include "sim_elem.h"

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
    size_t *koff;    /* element e: K_e (3 nn)^2 row-major at k + koff[e] */
    double *k;
    double *grad;    /* rest shape gradients at the centre, 3 per element node */
    double *rot;     /* 9 per element: its rotation (row-major) */
    uint32_t *stamp; /* per element: substep generation of rot */
    uint32_t gen;
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
    /* neo-Hookean: quadrature data of element e at gp + goff[e] (per point
     * the rest gradients of its nodes, then the weight; hyperelastic.h), its
     * nodal forces at fe + 3 p (p = start[e] + local node), valid while
     * stamp[e] == gen; the moduli mu and kappa */
    double *gp;
    size_t *goff;
    double *fe;
    double mu, kappa;
    /* the forces of the elements evaluated at the end of the last step (in
     * generation gen) are still those of the current positions: the next
     * sweep reuses them (ftm_elem_intact) */
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
    free(el->grad);
    free(el->rot);
    free(el->stamp);
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
    free(el->fe);
    free(el);
}

/* ---- rotations ---- */

static double det3(const double m[9])
{
    return m[0] * (m[4] * m[8] - m[5] * m[7]) - m[1] * (m[3] * m[8] - m[5] * m[6]) +
           m[2] * (m[3] * m[7] - m[4] * m[6]);
}

/* The rotation of the polar decomposition F = R S by Newton's iteration
 * R <- (R + R^-T) / 2 from R = F: quadratic convergence, only + - * /, so
 * the same bits everywhere. F = I gives exactly I. Returns false for
 * det F <= 0 (an inverted element, which has no proper rotation). */
static bool polar_rotation(const double f[9], double r[9])
{
    double x[9];
    memcpy(x, f, sizeof x);
    for (int it = 0; it < 60; it++) {
        double det = det3(x);
        if (!(det > 0.0) || !isfinite(det))
            return false;
        /* (X^-1)^T = cofactor(X) / det */
        double c[9] = {x[4] * x[8] - x[5] * x[7], x[5] * x[6] - x[3] * x[8],
                       x[3] * x[7] - x[4] * x[6], x[2] * x[7] - x[1] * x[8],
                       x[0] * x[8] - x[2] * x[6], x[1] * x[6] - x[0] * x[7],
                       x[1] * x[5] - x[2] * x[4], x[2] * x[3] - x[0] * x[5],
                       x[0] * x[4] - x[1] * x[3]};
        double diff = 0.0;
        for (int q = 0; q < 9; q++) {
            double y = 0.5 * (x[q] + c[q] / det);
            double dq = fabs(y - x[q]);
            diff = dq > diff ? dq : diff;
            x[q] = y;
        }
        if (diff <= 1e-10) /* the next error is ~diff^2: round-off */
            break;
    }
    memcpy(r, x, sizeof x);
    return true;
}

/* Rotation of element e from positions x: F = I + sum_b u_b grad_b^T. */
static void element_rotation(ftm_elem *el, const ftm_mesh *m, const double *x, int32_t e,
                             double *r)
{
    double f[9] = {1, 0, 0, 0, 1, 0, 0, 0, 1};
    for (int32_t p = el->start[e]; p < el->start[e + 1]; p++) {
        int32_t b = el->node[p];
        const double *g = el->grad + 3 * p;
        for (int i = 0; i < 3; i++) {
            double u = x[3 * b + i] - m->rest[3 * b + i];
            f[3 * i] += u * g[0];
            f[3 * i + 1] += u * g[1];
            f[3 * i + 2] += u * g[2];
        }
    }
    /* inverted: keep the last rotation */
    double nr[9];
    if (polar_rotation(f, nr))
        memcpy(r, nr, sizeof nr);
}

static const double *fresh_rotation(ftm_elem *el, const ftm_mesh *m, const double *x, int32_t e)
{
    double *r = el->rot + 9 * (size_t)e;
    if (el->stamp[e] != el->gen) {
        element_rotation(el, m, x, e, r);
        el->stamp[e] = el->gen;
    }
    return r;
}

static void next_generation(ftm_elem *el)
{
    el->carry = false;
    if (++el->gen == 0) { /* wrapped: no element may look fresh */
        memset(el->stamp, 0, (size_t)el->count * sizeof *el->stamp);
        el->gen = 1;
    }
}

/* Element values of node i's elements are stale (the node moved outside a
 * sweep): evaluated again at their next use. */
static void forget_node(ftm_elem *el, int32_t i)
{
    if (!el->stamp)
        return;
    for (int32_t q = el->inc_start[i]; q < el->inc_start[i + 1]; q++)
        el->stamp[el->inc_elem[q]] = el->gen - 1; /* gen is never 0, so never gen */
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

/* Co-rotational: f = sum over the elements e of i of the rows of node a = i
 * of R K_e (R^T x_e - X_e). rots: NULL = the per-substep cache, else 9 per
 * element precomputed. */
static inline void corot_force(ftm_elem *restrict el, const ftm_mesh *restrict m,
                               const double *restrict x, int32_t i, const double *rots,
                               double f[3])
{
    double fx = 0.0, fy = 0.0, fz = 0.0;
    for (int32_t q = el->inc_start[i]; q < el->inc_start[i + 1]; q++) {
        const int32_t e = el->inc_elem[q], a = el->inc_local[q];
        const double *r = rots ? rots + 9 * (size_t)e : fresh_rotation(el, m, x, e);
        const int32_t s0 = el->start[e], nn = el->start[e + 1] - s0, w = 3 * nn;
        const double *k = el->k + el->koff[e] + (size_t)(3 * a) * (size_t)w;
        double g0 = 0.0, g1 = 0.0, g2 = 0.0;
        for (int32_t b = 0; b < nn; b++) {
            const int32_t j = el->node[s0 + b];
            const double *xj = x + 3 * j, *Xj = m->rest + 3 * j;
            /* y = R^T x_j - X_j */
            double y0 = r[0] * xj[0] + r[3] * xj[1] + r[6] * xj[2] - Xj[0];
            double y1 = r[1] * xj[0] + r[4] * xj[1] + r[7] * xj[2] - Xj[1];
            double y2 = r[2] * xj[0] + r[5] * xj[1] + r[8] * xj[2] - Xj[2];
            const double *k0 = k + 3 * b, *k1 = k0 + w, *k2 = k1 + w;
            g0 += k0[0] * y0 + k0[1] * y1 + k0[2] * y2;
            g1 += k1[0] * y0 + k1[1] * y1 + k1[2] * y2;
            g2 += k2[0] * y0 + k2[1] * y1 + k2[2] * y2;
        }
        fx += r[0] * g0 + r[1] * g1 + r[2] * g2;
        fy += r[3] * g0 + r[4] * g1 + r[5] * g2;
        fz += r[6] * g0 + r[7] * g1 + r[8] * g2;
    }
    f[0] = fx;
    f[1] = fy;
    f[2] = fz;
}

/* The displacements of element e's nodes, 3 each. */
static inline void element_displacements(const ftm_elem *el, const ftm_mesh *m, const double *x,
                                         int32_t e, double *u)
{
    const int32_t s0 = el->start[e], nn = el->start[e + 1] - s0;
    for (int32_t b = 0; b < nn; b++) {
        const int32_t j = el->node[s0 + b];
        for (int d = 0; d < 3; d++)
            u[3 * b + d] = x[3 * j + d] - m->rest[3 * j + d];
    }
}

static inline int quadrature_points(int32_t nn) { return nn == 8 ? 8 : 1; }

static void note_inversion(ftm_elem *el, int32_t e, double det)
{
    if (!el->inverted) {
        el->inv_elem = e;
        el->inv_det = det;
    }
    el->inverted = true;
}

/* Neo-Hookean forces of element e at positions x into fe (3 per node);
 * false (fe zero) if inverted. */
static bool neo_element(const ftm_elem *el, const ftm_mesh *m, const double *x, int32_t e,
                        double *fe, double *min_det)
{
    double u[24];
    const int32_t nn = el->start[e + 1] - el->start[e];
    element_displacements(el, m, x, e, u);
    return ftm_neo_element_forces(nn, quadrature_points(nn), el->gp + el->goff[e], u, el->mu,
                                  el->kappa, fe, min_det);
}

/* Neo-Hookean: f = sum over the elements e of i of their cached force on i,
 * each element evaluated at its first use in the substep. */
static inline void neo_force(ftm_elem *restrict el, const ftm_mesh *restrict m,
                             const double *restrict x, int32_t i, double f[3])
{
    double fx = 0.0, fy = 0.0, fz = 0.0;
    for (int32_t q = el->inc_start[i]; q < el->inc_start[i + 1]; q++) {
        const int32_t e = el->inc_elem[q];
        double *fe = el->fe + 3 * (size_t)el->start[e];
        if (el->stamp[e] != el->gen) {
            double det;
            if (!neo_element(el, m, x, e, fe, &det))
                note_inversion(el, e, det);
            el->stamp[e] = el->gen;
        }
        const double *fa = fe + 3 * el->inc_local[q];
        fx += fa[0];
        fy += fa[1];
        fz += fa[2];
    }
    f[0] = fx;
    f[1] = fy;
    f[2] = fz;
}

static inline void node_force(ftm_elem *el, const ftm_mesh *m, const double *x, int32_t i,
                              double f[3])
{
    if (el->kind == FTM_FORCES_LINEAR_FEM)
        linear_force(el, m, x, i, f);
    else if (el->kind == FTM_FORCES_COROT_FEM)
        corot_force(el, m, x, i, NULL, f);
    else
        neo_force(el, m, x, i, f);
    if (el->scale != 1.0) {
        f[0] *= el->scale;
        f[1] *= el->scale;
        f[2] *= el->scale;
    }
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
static inline bool update_node(ftm_sim *sim, int32_t i, double *save, int stride, double *mm)
{
    double *xi = sim->x + 3 * i, *pi = sim->xp + 3 * i;
    double cur[3] = {xi[0], xi[1], xi[2]}, f[3], nw[3];
    node_force(sim->elem, sim->m, sim->x, i, f);
    double m2 = integrate(sim, i, cur, f, nw);
    *mm = m2 > *mm ? m2 : *mm;
    for (int d = 0; d < 3; d++) {
        if (save)
            save[d * stride] = pi[d];
        pi[d] = cur[d];
        xi[d] = nw[d];
    }
    return m2 <= ftm_sim_lim2(sim, i); /* false for NaN too */
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
    if (sim->def.order == FTM_ORDER_LAYER_COLORED) {
        /* one node at a time in schedule order; save as the kernels do */
        const int32_t w = sim->group_lanes;
        for (int32_t g = 0, b0 = 0; g < s->groups; g++) {
            const int32_t k0 = s->group[g], k1 = s->group[g + 1];
            for (int32_t k = k0; k < k1; k++)
                ok &= update_node(sim, s->node[k], ftm_group_save(sim, b0, k0, k), w, &mm);
            b0 += ftm_group_blocks(sim, k0, k1);
        }
    } else if (sim->def.order == FTM_ORDER_BFS) {
        for (int32_t k = 0; k < s->count; k++)
            ok &= update_node(sim, s->node[k], s->save + 3 * (size_t)k, 1, &mm);
    } else { /* Jacobi: each layer from the state before it; save as the kernels do */
        const int32_t w = sim->group_lanes;
        for (int32_t g = 0, b0 = 0; g < s->groups; g++) {
            for (int32_t k = s->group[g]; k < s->group[g + 1]; k++) {
                int32_t i = s->node[k];
                double f[3];
                node_force(el, sim->m, sim->x, i, f);
                double m2 = integrate(sim, i, sim->x + 3 * i, f, s->tmp + 3 * k);
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
    bool ok = true;
    double mm = 0.0;
    for (int32_t r = 0; r < sim->nrelax; r++)
        ok &= update_node(sim, sim->relax[r], NULL, 1, &mm);
    return ok;
}

/* The end of a step: evaluates the elements of node i not yet evaluated in
 * this generation; false (noted) at the first with J <= 0. */
static bool evaluate_node(ftm_elem *el, const ftm_mesh *m, const double *x, int32_t i)
{
    for (int32_t q = el->inc_start[i]; q < el->inc_start[i + 1]; q++) {
        const int32_t e = el->inc_elem[q];
        if (el->stamp[e] == el->gen)
            continue;
        el->stamp[e] = el->gen;
        double det;
        if (!neo_element(el, m, x, e, el->fe + 3 * (size_t)el->start[e], &det)) {
            note_inversion(el, e, det);
            return false;
        }
    }
    return true;
}

bool ftm_elem_intact(ftm_sim *sim, bool last, bool region_ran)
{
    ftm_elem *el = sim->elem;
    if (el->kind != FTM_FORCES_NEO_HOOKEAN)
        return true;
    bool ok = !el->inverted;
    if (ok && last) {
        /* the positions the step leaves, whose forces the next step starts
         * from: evaluated now (the check) and carried over */
        next_generation(el);
        const ftm_mesh *m = sim->m;
        for (int32_t k = 0; ok && region_ran && k < sim->s.count; k++)
            ok = evaluate_node(el, m, sim->x, sim->s.node[k]);
        for (int32_t k = 0; ok && region_ran && k < sim->ndisp; k++)
            ok = evaluate_node(el, m, sim->x, sim->disp[k]);
        /* (the ring's elements that hold a region node are evaluated above;
         * the others give no scheduled node a force) */
        for (int32_t k = 0; ok && k < sim->nrelax; k++)
            ok = evaluate_node(el, m, sim->x, sim->relax[k]);
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
    for (int32_t c = 0; c < sim->ncontacts; c++) {
        const ftm_contact *ct = &sim->contacts[c];
        if (ct->kind != FTM_CONTACT_DISPLACEMENT)
            continue;
        double f[3];
        node_force(sim->elem, sim->m, sim->x, ct->node, f);
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
    if (el->kind == FTM_FORCES_NEO_HOOKEAN) {
        /* every element from x into a private cache, then the sums per node
         * in the integrator's order; nothing written if one is inverted */
        size_t total = (size_t)el->start[el->count];
        double *fe = malloc((3 * total + 1) * sizeof *fe);
        if (!fe)
            return FTM_ENOMEM;
        for (int32_t e = 0; e < el->count; e++) {
            double det;
            if (!neo_element(el, m, x, e, fe + 3 * (size_t)el->start[e], &det)) {
                free(fe);
                return FTM_EINVAL;
            }
        }
        for (int32_t i = 0; i < m->node_count; i++) {
            double s[3] = {0.0, 0.0, 0.0};
            for (int32_t q = el->inc_start[i]; q < el->inc_start[i + 1]; q++) {
                const int32_t e = el->inc_elem[q];
                const double *fa = fe + 3 * ((size_t)el->start[e] + (size_t)el->inc_local[q]);
                s[0] += fa[0];
                s[1] += fa[1];
                s[2] += fa[2];
            }
            memcpy(f + 3 * i, s, sizeof s);
        }
        free(fe);
        return FTM_OK;
    }
    /* rotations from x into a private copy: the sim's cache stays untouched */
    double *rots = malloc(((size_t)el->count * 9 + 1) * sizeof *rots);
    if (!rots)
        return FTM_ENOMEM;
    memcpy(rots, el->rot, (size_t)el->count * 9 * sizeof *rots);
    for (int32_t e = 0; e < el->count; e++)
        element_rotation((ftm_elem *)el, m, x, e, rots + 9 * (size_t)e);
    for (int32_t i = 0; i < m->node_count; i++)
        corot_force((ftm_elem *)el, m, x, i, rots, f + 3 * i);
    free(rots);
    return FTM_OK;
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

/* Element nodes, stiffness matrices and centre gradients. */
static int build_elements(ftm_elem *el, const ftm_mesh *m, const ftm_sim_def *d, ftm_error *err)
{
    int32_t ne = m->hex_count + m->tet_count;
    size_t nodes = (size_t)m->hex_count * 8 + (size_t)m->tet_count * 4;
    size_t kn = (size_t)m->hex_count * 576 + (size_t)m->tet_count * 144;
    el->count = ne;
    el->start = malloc(((size_t)ne + 1) * sizeof *el->start);
    el->node = malloc((nodes + 1) * sizeof *el->node);
    el->koff = malloc(((size_t)ne + 1) * sizeof *el->koff);
    el->k = malloc((kn + 1) * sizeof *el->k);
    el->grad = malloc((nodes * 3 + 1) * sizeof *el->grad);
    if (!el->start || !el->node || !el->koff || !el->k || !el->grad)
        return ftm_error_set(err, FTM_ENOMEM, "sim: out of memory for %d elements", (int)ne);
    if (el->kind == FTM_FORCES_NEO_HOOKEAN) {
        el->goff = malloc(((size_t)ne + 1) * sizeof *el->goff);
        el->gp = malloc(((size_t)m->hex_count * 200 + (size_t)m->tet_count * 13 + 1) *
                        sizeof *el->gp);
        if (!el->goff || !el->gp)
            return ftm_error_set(err, FTM_ENOMEM, "sim: out of memory for %d elements", (int)ne);
        size_t off = 0;
        for (int32_t e = 0; e <= ne; e++) {
            el->goff[e] = off;
            off += e < m->hex_count ? 200 : 13;
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
        int rc;
        if (hex) {
            double min_det;
            rc = ftm_hex8_stiffness(x, d->young, d->poisson, el->k + ko, &min_det);
            if (!rc)
                rc = ftm_hex8_centre_gradients(x, el->grad + 3 * p);
            if (!rc && el->gp) { /* per Gauss point: 24 gradients, then det J (weight 1) */
                double g[192], det[8];
                double *dst = el->gp + el->goff[e];
                rc = ftm_hex8_gauss_gradients(x, g, det);
                for (int q = 0; !rc && q < 8; q++) {
                    memcpy(dst + 25 * q, g + 24 * q, 24 * sizeof *g);
                    dst[25 * q + 24] = det[q];
                }
            }
            if (rc)
                return ftm_error_set(err, FTM_EINVAL,
                                     "sim: hexahedron %d (input nodes %d %d %d %d %d %d %d %d) is "
                                     "inverted or degenerate: Jacobian determinant %g",
                                     (int)e, IN(0), IN(1), IN(2), IN(3), IN(4), IN(5), IN(6),
                                     IN(7), min_det);
        } else {
            double vol;
            rc = ftm_tet4_stiffness(x, d->young, d->poisson, el->k + ko, &vol);
            if (!rc)
                rc = ftm_tet4_gradients(x, el->grad + 3 * p);
            if (!rc && el->gp) { /* one point: the 12 gradients, then the volume */
                double *dst = el->gp + el->goff[e];
                memcpy(dst, el->grad + 3 * p, 12 * sizeof *dst);
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
        double li = 0.0;
        for (int r = 0; r < 3; r++) {
            double s = 0.0;
            for (int32_t p = el->row_start[i]; p < el->row_start[i + 1]; p++) {
                const double *kb = el->row_k + 9 * (size_t)p + 3 * r;
                double sc = 1.0 / sqrt(el->mass[i] * el->mass[el->row_node[p]]);
                s += (fabs(kb[0]) + fabs(kb[1]) + fabs(kb[2])) * sc;
            }
            li = s > li ? s : li;
        }
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
    /* neo-Hookean forces are evaluated at the substep's start (plain central
     * differences): no Gauss-Seidel coupling to damp (docs/calculix.md:
     * undamped at half the critical step, bounded where linear-fem diverges) */
    if (worst >= 0 && worst_ratio < 1.0 && el->kind != FTM_FORCES_NEO_HOOKEAN)
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
            rc = ftm_mesh_lumped_masses(m, d->density, el->mass, err);
        else
            memcpy(el->mass, m->mass, (size_t)n * sizeof *el->mass);
    }
    for (int32_t i = 0; !rc && i < n; i++)
        if (!m->fixed[i] && el->inc_start[i] == el->inc_start[i + 1])
            rc = ftm_error_set(err, FTM_EINVAL,
                               "sim: node %d (input index %d) belongs to no element and is not "
                               "fixed: element forces cannot hold it",
                               (int)i, (int)m->input_of_node[i]);
    if (!rc && d->forces == FTM_FORCES_COROT_FEM) {
        el->rot = malloc(((size_t)el->count * 9 + 1) * sizeof *el->rot);
        el->stamp = calloc((size_t)el->count + 1, sizeof *el->stamp);
        if (!el->rot || !el->stamp)
            rc = ftm_error_set(err, FTM_ENOMEM, "sim: out of memory");
        else
            for (int32_t e = 0; e < el->count; e++) {
                double *r = el->rot + 9 * (size_t)e;
                memset(r, 0, 9 * sizeof *r);
                r[0] = r[4] = r[8] = 1.0;
            }
    }
    if (!rc && d->forces == FTM_FORCES_NEO_HOOKEAN) {
        el->mu = d->young / (2.0 * (1.0 + d->poisson));
        el->kappa = d->young / (3.0 * (1.0 - 2.0 * d->poisson));
        el->fe = malloc((3 * (size_t)el->start[el->count] + 1) * sizeof *el->fe);
        el->stamp = calloc((size_t)el->count + 1, sizeof *el->stamp);
        if (!el->fe || !el->stamp)
            rc = ftm_error_set(err, FTM_ENOMEM, "sim: out of memory");
    }
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
    bound_and_warn(el, sim); /* neo-Hookean: its tangent at rest is the linear K */
    if (el->kind == FTM_FORCES_NEO_HOOKEAN) { /* the linear matrices have served */
        free(el->k);
        free(el->grad);
        el->k = el->grad = NULL;
        if (d->far_field != FTM_FAR_FIELD_ELASTIC) { /* its compliance needs the rows */
            free(el->row_k);
            el->row_k = NULL;
        }
    }
    sim->elem = el;
    return FTM_OK;
}
