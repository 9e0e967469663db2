/* SPDX-License-Identifier: GPL-3.0-or-later */
/* The elastic far field: the ring of nodes just beyond the contact region,
 * placed each step from the body's compliance (farfield.h says what and
 * why; compliance.c computes G). */
#include "farfield.h"

#include "compliance.h"
#include "error.h"
#include "sim_elem.h"

#include <math.h>
#include <stdlib.h>
#include <string.h>

struct ftm_far {
    ftm_compliance *g;
    int32_t n;     /* mesh nodes */
    /* the current K is kscale times the one G was computed for, whose links
     * had the stiffness ref_k (springs) */
    double kscale;
    double *ref_k;

    /* the ring of the current region: nodes, their displacement (3 each) */
    int32_t *ring;
    int32_t nring, ring_cap;
    double *u;
    uint8_t *moves; /* moves[k]: this step places ring node k elsewhere than it is */
    uint32_t *mark; /* mark[i] == gen: i is in the ring */
    uint32_t gen;

    /* contact solve: the displacement contacts' G_dd (3 nd square) as LDL^T */
    bool dd_valid;
    int32_t nd;
    double *dd;
    double *rhs; /* 3 nd */
    size_t dd_cap;
};

void ftm_far_free(ftm_far *f)
{
    if (!f)
        return;
    ftm_compliance_release(f->g);
    free(f->ref_k);
    free(f->ring);
    free(f->u);
    free(f->moves);
    free(f->mark);
    free(f->dd);
    free(f->rhs);
    free(f);
}

int ftm_far_create(ftm_sim *sim, ftm_error *err)
{
    const int32_t n = sim->m->node_count;
    ftm_far *f = calloc(1, sizeof *f);
    if (!f)
        return ftm_error_set(err, FTM_ENOMEM, "far_field = elastic: out of memory");
    f->n = n;
    f->kscale = 1.0;
    f->mark = calloc((size_t)n + 1, sizeof *f->mark);
    const size_t links = (size_t)sim->m->link_count;
    f->ref_k = malloc((links + 1) * sizeof *f->ref_k);
    if (f->ref_k)
        memcpy(f->ref_k, sim->m->link_k, links * sizeof *f->ref_k);
    if (!f->mark || !f->ref_k) {
        ftm_far_free(f);
        return ftm_error_set(err, FTM_ENOMEM, "far_field = elastic: out of memory");
    }
    int rc = ftm_compliance_acquire(sim, sim->m, &f->g, err);
    if (rc) {
        ftm_far_free(f);
        return rc;
    }
    sim->far = f;
    return FTM_OK;
}

/* ---- the ring ---- */

int32_t ftm_far_ring_count(const ftm_far *f) { return f ? f->nring : 0; }
bool ftm_far_ring_moves(const ftm_far *f, int32_t k) { return f->moves[k] != 0; }
const int32_t *ftm_far_ring_nodes(const ftm_far *f) { return f->ring; }
bool ftm_far_in_ring(const ftm_far *f, int32_t node) { return f && f->mark[node] == f->gen; }
void ftm_far_contacts_changed(ftm_far *f)
{
    if (f)
        f->dd_valid = false;
}

static int ring_push(ftm_far *f, int32_t i)
{
    if (f->nring == f->ring_cap) {
        int32_t cap = f->ring_cap ? 2 * f->ring_cap : 256;
        int32_t *r = realloc(f->ring, (size_t)cap * sizeof *r);
        if (!r)
            return FTM_ENOMEM;
        f->ring = r;
        double *u = realloc(f->u, (size_t)cap * 3 * sizeof *u);
        if (!u)
            return FTM_ENOMEM;
        f->u = u;
        uint8_t *mv = realloc(f->moves, (size_t)cap);
        if (!mv)
            return FTM_ENOMEM;
        f->moves = mv;
        f->ring_cap = cap;
    }
    f->ring[f->nring++] = i;
    f->mark[i] = f->gen;
    return FTM_OK;
}

static void next_gen(ftm_far *f)
{
    if (++f->gen == 0) { /* wrapped: clear the stamps once */
        memset(f->mark, 0, (size_t)f->n * sizeof *f->mark);
        f->gen = 1;
    }
}

/* Neighbours of i through the forces: the element rows, or the links. */
static void neighbours(const ftm_sim *sim, int32_t i, const int32_t **nb, int32_t *count)
{
    if (sim->elem) {
        const int32_t *start, *node;
        const double *k;
        ftm_elem_rows(sim->elem, &start, &node, &k);
        *nb = node + start[i];
        *count = start[i + 1] - start[i];
    } else {
        *nb = sim->m->adj_node + sim->m->adj_start[i];
        *count = sim->m->adj_start[i + 1] - sim->m->adj_start[i];
    }
}

int32_t ftm_far_rebuild_ring(ftm_sim *sim, int32_t *cand)
{
    ftm_far *f = sim->far;
    const ftm_layering *ly = &sim->ly;
    /* the old ring, to hand back what leaves it */
    int32_t old = f->nring;
    int32_t *olds = NULL;
    if (old > 0) {
        olds = malloc((size_t)old * sizeof *olds);
        if (!olds)
            return FTM_ENOMEM;
        memcpy(olds, f->ring, (size_t)old * sizeof *olds);
    }
    next_gen(f);
    f->nring = 0;
    int rc = FTM_OK;
    const int32_t region = ly->gen ? ly->count : 0;
    /* every free node outside the region that a region node's forces read */
    for (int32_t k = 0; k < region && !rc; k++) {
        const int32_t *nb;
        int32_t deg;
        neighbours(sim, ly->order[k], &nb, &deg);
        for (int32_t q = 0; q < deg && !rc; q++) {
            int32_t j = nb[q];
            if (!sim->m->fixed[j] && f->mark[j] != f->gen && !ftm_layering_contains(ly, j))
                rc = ring_push(f, j);
        }
    }
    if (rc) {
        free(olds);
        return rc;
    }
    /* ascending: a fixed order for the solve and the hash's neighbours */
    for (int32_t a = 1; a < f->nring; a++) { /* insertion: mostly ordered already */
        int32_t v = f->ring[a], b = a;
        while (b > 0 && f->ring[b - 1] > v) {
            f->ring[b] = f->ring[b - 1];
            b--;
        }
        f->ring[b] = v;
    }
    int32_t added = 0;
    for (int32_t k = 0; k < old; k++) {
        int32_t i = olds[k];
        if (f->mark[i] != f->gen && !ftm_layering_contains(ly, i))
            cand[added++] = i;
    }
    free(olds);
    f->dd_valid = false;
    return added;
}

/* ---- per step ---- */


/* G_dd of the displacement contacts, symmetrised, factorised LDL^T. */
static int factor_dd(ftm_sim *sim)
{
    ftm_far *f = sim->far;
    const int32_t nd = sim->ndisp, w = 3 * nd;
    size_t need = (size_t)w * (size_t)w;
    if (need > f->dd_cap) {
        double *d = realloc(f->dd, (need + 1) * sizeof *d);
        double *r = realloc(f->rhs, ((size_t)w + 1) * sizeof *r);
        if (!d || !r) {
            if (d)
                f->dd = d;
            if (r)
                f->rhs = r;
            return FTM_ENOMEM;
        }
        f->dd = d;
        f->rhs = r;
        f->dd_cap = need;
    }
    const float *const *cols = ftm_compliance_columns(f->g);
    double blk[9], blt[9];
    for (int32_t a = 0; a < nd; a++)
        for (int32_t b = 0; b < nd; b++) {
            ftm_compliance_block(cols, sim->disp[a], sim->disp[b], blk);
            ftm_compliance_block(cols, sim->disp[b], sim->disp[a], blt);
            for (int p = 0; p < 3; p++)
                for (int s = 0; s < 3; s++)
                    f->dd[(size_t)(3 * a + p) * (size_t)w + (size_t)(3 * b + s)] =
                        0.5 * (blk[3 * p + s] + blt[3 * s + p]);
        }
    /* dense LDL^T in place (SPD: a principal block of K^-1) */
    double *A = f->dd;
    for (int32_t r = 0; r < w; r++) {
        double *row = A + (size_t)r * (size_t)w;
        for (int32_t c = 0; c < r; c++) {
            const double *rc = A + (size_t)c * (size_t)w;
            double t = row[c];
            for (int32_t k = 0; k < c; k++)
                t -= row[k] * rc[k];
            row[c] = t;
        }
        double d = row[r];
        for (int32_t c = 0; c < r; c++) {
            double l = row[c] / A[(size_t)c * (size_t)w + (size_t)c];
            d -= row[c] * l;
            row[c] = l;
        }
        row[r] = d > 0.0 ? d : 1.0; /* (cannot happen for distinct free nodes) */
    }
    f->nd = nd;
    f->dd_valid = true;
    return FTM_OK;
}

static void solve_dd(const ftm_far *f, double *x)
{
    const int32_t w = 3 * f->nd;
    const double *A = f->dd;
    for (int32_t r = 0; r < w; r++)
        for (int32_t k = 0; k < r; k++)
            x[r] -= A[(size_t)r * (size_t)w + (size_t)k] * x[k];
    for (int32_t r = 0; r < w; r++)
        x[r] /= A[(size_t)r * (size_t)w + (size_t)r];
    for (int32_t r = w - 1; r >= 0; r--)
        for (int32_t k = 0; k < r; k++)
            x[k] -= A[(size_t)r * (size_t)w + (size_t)k] * x[r];
}

int ftm_far_prepare(ftm_sim *sim)
{
    ftm_far *f = sim->far;
    if (f->nring == 0)
        return FTM_OK;
    for (int32_t c = 0; c < sim->ncontacts; c++) {
        int rc = ftm_compliance_ensure(f->g, sim->contacts[c].node, sim->def.log,
                                       sim->def.log_user);
        if (rc)
            return rc;
    }
    const float *const *cols = ftm_compliance_columns(f->g);
    if (!f->dd_valid) {
        int rc = factor_dd(sim);
        if (rc)
            return rc;
    }
    /* forces on the contacts in the factorised stiffness's units: F / kscale */
    const double inv = 1.0 / f->kscale;
    double blk[9];
    /* rhs = delta_d - G_df F', then y = G_dd^-1 rhs (the displacement
     * contacts' forces in those units) */
    for (int32_t a = 0, r = 0; a < sim->ncontacts; a++) {
        const ftm_contact *ca = &sim->contacts[a];
        if (ca->kind != FTM_CONTACT_DISPLACEMENT)
            continue;
        double *x = f->rhs + 3 * r++;
        x[0] = ca->value.x;
        x[1] = ca->value.y;
        x[2] = ca->value.z;
        for (int32_t b = 0; b < sim->ncontacts; b++) {
            const ftm_contact *cb = &sim->contacts[b];
            if (cb->kind != FTM_CONTACT_FORCE)
                continue;
            ftm_compliance_block(cols, ca->node, cb->node, blk);
            double F[3] = {cb->value.x * inv, cb->value.y * inv, cb->value.z * inv};
            for (int p = 0; p < 3; p++)
                x[p] -= blk[3 * p] * F[0] + blk[3 * p + 1] * F[1] + blk[3 * p + 2] * F[2];
        }
    }
    if (f->nd > 0)
        solve_dd(f, f->rhs);
    for (int32_t k = 0; k < f->nring; k++) {
        const int32_t j = f->ring[k];
        double u[3] = {0.0, 0.0, 0.0};
        for (int32_t c = 0, r = 0; c < sim->ncontacts; c++) {
            const ftm_contact *ct = &sim->contacts[c];
            double F[3];
            if (ct->kind == FTM_CONTACT_DISPLACEMENT) {
                memcpy(F, f->rhs + 3 * r++, sizeof F);
            } else {
                F[0] = ct->value.x * inv;
                F[1] = ct->value.y * inv;
                F[2] = ct->value.z * inv;
            }
            const float *g = cols[ct->node] + 9 * (size_t)j;
            for (int p = 0; p < 3; p++)
                u[p] += (double)g[3 * p] * F[0] + (double)g[3 * p + 1] * F[1] +
                        (double)g[3 * p + 2] * F[2];
        }
        memcpy(f->u + 3 * k, u, sizeof u);
        const double *X = sim->m->rest + 3 * j, *x = sim->x + 3 * j;
        f->moves[k] = X[0] + u[0] != x[0] || X[1] + u[1] != x[1] || X[2] + u[2] != x[2];
    }
    return FTM_OK;
}

void ftm_far_impose(ftm_sim *sim)
{
    const ftm_far *f = sim->far;
    const double *rest = sim->m->rest;
    for (int32_t k = 0; k < f->nring; k++) {
        const int32_t i = f->ring[k];
        double *x = sim->x + 3 * i, *xp = sim->xp + 3 * i;
        for (int d = 0; d < 3; d++) {
            xp[d] = x[d];
            x[d] = rest[3 * i + d] + f->u[3 * k + d];
        }
        if (sim->m->bc && (sim->m->bc[i] & FTM_BC_SLIDES)) /* exactly on its plane */
            ftm_bc_project(sim->m, i, x);
    }
}

void ftm_far_set_scale(ftm_far *f, double scale) { f->kscale = scale; }

int ftm_far_set_mesh(ftm_sim *sim, const ftm_mesh *m, ftm_error *err)
{
    ftm_far *f = sim->far;
    /* every link times one factor against the stiffness G was computed for:
     * G scales by its inverse. The factor comes from the two meshes alone,
     * not from the changes in between, so a replica that starts from the
     * scene's mesh and the new one gets the server's bits. */
    double ratio = 0.0;
    /* (springs to ground keep their stiffness: K is then not a multiple) */
    bool uniform = !sim->elem && m->link_count == sim->m->link_count && !m->ground_k;
    for (int32_t l = 0; uniform && l < m->link_count; l++) {
        double q = m->link_k[l] / f->ref_k[l];
        if (l == 0)
            ratio = q;
        else if (q != ratio)
            uniform = false;
    }
    if (uniform && ratio > 0.0 && isfinite(ratio)) {
        f->kscale = ratio;
        return FTM_OK;
    }
    /* otherwise the compliance of the new stiffness */
    ftm_compliance *g = NULL;
    int rc = ftm_compliance_acquire(sim, m, &g, err);
    if (rc)
        return rc;
    ftm_compliance_release(f->g);
    f->g = g;
    memcpy(f->ref_k, m->link_k, (size_t)m->link_count * sizeof *f->ref_k);
    f->kscale = 1.0;
    f->dd_valid = false;
    return FTM_OK;
}
