/* SPDX-License-Identifier: GPL-3.0-or-later */
/* The contact stiffness of a probe (ftm_sim_contact_stiffness, sim.h): the
 * derivative of the reaction force (Eq. 19) with respect to the HIP, for the
 * haptic force model the server sends with each reaction (docs/haptics.md).
 *
 * The server's probe displaces the collided triangle's vertices rigidly by
 * the HIP's penetration, so moving the HIP by dx moves every displacement
 * contact of the group by dx. Springs between two of those nodes keep their
 * length; a spring from contact node i to any other node j (free, fixed, or
 * another probe's contact) changes by the tangent stiffness of Eq. 6,
 *   df_ij/dx_i = k_ij [ u u^T + (1 - l_ij/|r_ij|) (I - u u^T) ],  u = r_ij/|r_ij|,
 * and F = -sum f_ij gives K = -sum_{i in group, j not in group} df_ij/dx_i.
 * The rest of the tissue is held where it is: this is the stiffness the
 * probe meets before the tissue around it has moved, the stiffest response
 * of the model (the quasi-static one is softer as the layers follow). */
#include "sim_internal.h"

#include <math.h>
#include <string.h>

/* Whether node j is a displacement contact of group g (contacts are sorted
 * by node). */
static bool in_group(const ftm_sim *sim, int32_t j, int32_t g)
{
    int32_t lo = 0, hi = sim->ncontacts;
    while (lo < hi) {
        int32_t mid = lo + (hi - lo) / 2;
        if (sim->contacts[mid].node < j)
            lo = mid + 1;
        else
            hi = mid;
    }
    return lo < sim->ncontacts && sim->contacts[lo].node == j && sim->contacts[lo].group == g &&
           sim->contacts[lo].kind == FTM_CONTACT_DISPLACEMENT;
}

/* Eigen-decomposition of a symmetric 3x3 matrix by cyclic Jacobi rotations:
 * A = V diag(w) V^T. Deterministic (fixed sweep order and count). */
static void sym_eigen3(const double A[9], double w[3], double V[9])
{
    double a[3][3], v[3][3] = {{1, 0, 0}, {0, 1, 0}, {0, 0, 1}};
    for (int r = 0; r < 3; r++)
        for (int c = 0; c < 3; c++)
            a[r][c] = A[3 * r + c];
    for (int sweep = 0; sweep < 50; sweep++) {
        double off = fabs(a[0][1]) + fabs(a[0][2]) + fabs(a[1][2]);
        if (off == 0.0)
            break;
        for (int p = 0; p < 2; p++) {
            for (int q = p + 1; q < 3; q++) {
                if (a[p][q] == 0.0)
                    continue;
                double theta = (a[q][q] - a[p][p]) / (2.0 * a[p][q]);
                double t = (theta >= 0 ? 1.0 : -1.0) / (fabs(theta) + sqrt(theta * theta + 1.0));
                double c = 1.0 / sqrt(t * t + 1.0), s = t * c;
                for (int k = 0; k < 3; k++) { /* A <- A J */
                    double akp = a[k][p], akq = a[k][q];
                    a[k][p] = c * akp - s * akq;
                    a[k][q] = s * akp + c * akq;
                }
                for (int k = 0; k < 3; k++) { /* A <- J^T A */
                    double apk = a[p][k], aqk = a[q][k];
                    a[p][k] = c * apk - s * aqk;
                    a[q][k] = s * apk + c * aqk;
                }
                for (int k = 0; k < 3; k++) {
                    double vkp = v[k][p], vkq = v[k][q];
                    v[k][p] = c * vkp - s * vkq;
                    v[k][q] = s * vkp + c * vkq;
                }
            }
        }
    }
    for (int k = 0; k < 3; k++)
        w[k] = a[k][k];
    for (int r = 0; r < 3; r++)
        for (int c = 0; c < 3; c++)
            V[3 * r + c] = v[r][c];
}

void ftm_stiffness_make_passive(double K[9])
{
    /* symmetric part, then the negative semi-definite part: eigenvalues of
     * K above zero (a force that grows along the motion) are set to zero */
    double S[9];
    for (int r = 0; r < 3; r++)
        for (int c = 0; c < 3; c++)
            S[3 * r + c] = 0.5 * (K[3 * r + c] + K[3 * c + r]);
    double w[3], V[9];
    sym_eigen3(S, w, V);
    for (int k = 0; k < 3; k++)
        if (!(w[k] < 0.0))
            w[k] = 0.0;
    for (int r = 0; r < 3; r++)
        for (int c = 0; c < 3; c++)
            K[3 * r + c] = V[3 * r + 0] * w[0] * V[3 * c + 0] + V[3 * r + 1] * w[1] * V[3 * c + 1] +
                           V[3 * r + 2] * w[2] * V[3 * c + 2];
}

int32_t ftm_sim_contact_stiffness(const ftm_sim *sim, int32_t group, double K[9])
{
    memset(K, 0, 9 * sizeof *K);
    if (sim->def.forces != FTM_FORCES_SPRINGS)
        return 0; /* element forces: no model (the client holds the force) */
    int32_t used = 0;
    for (int32_t c = 0; c < sim->ncontacts; c++) {
        const ftm_contact *ct = &sim->contacts[c];
        if (ct->group != group || ct->kind != FTM_CONTACT_DISPLACEMENT)
            continue;
        used++;
        int32_t i = ct->node;
        const int32_t *nb;
        const double *ks, *ls;
        int32_t deg = ftm_mesh_neighbors(sim->m, i, &nb, &ks, &ls);
        const double *xi = sim->x + 3 * i;
        for (int32_t e = 0; e < deg; e++) {
            int32_t j = nb[e];
            if (in_group(sim, j, group))
                continue; /* moves with i: length unchanged */
            const double *xj = sim->x + 3 * j;
            double r[3] = {xi[0] - xj[0], xi[1] - xj[1], xi[2] - xj[2]};
            double len = sqrt(r[0] * r[0] + r[1] * r[1] + r[2] * r[2]) + FTM_LEN_EPS;
            double u[3] = {r[0] / len, r[1] / len, r[2] / len};
            double lat = 1.0 - ls[e] / len; /* transverse factor; < 0 when compressed */
            for (int a = 0; a < 3; a++)
                for (int b = 0; b < 3; b++)
                    K[3 * a + b] -= ks[e] * (u[a] * u[b] + lat * ((a == b ? 1.0 : 0.0) - u[a] * u[b]));
        }
        const double kg = ftm_mesh_ground_stiffness(sim->m, i); /* its spring to ground */
        for (int a = 0; a < 3; a++)
            K[4 * a] -= kg;
    }
    return used;
}

double ftm_stiffness_secant_scale(double K[9], ftm_vec3 force, ftm_vec3 pen)
{
    /* alpha = (F . p) / (p^T K p): the stiffness along p that the reaction
     * itself shows (F = K_qs p for a linear tissue pressed from rest),
     * relative to the held tissue's. 1 at the first tick of a contact, less
     * as the layers follow; kept in [0, 1] (never stiffer than held) */
    const double p[3] = {pen.x, pen.y, pen.z};
    double pKp = 0;
    for (int a = 0; a < 3; a++)
        for (int b = 0; b < 3; b++)
            pKp += p[a] * K[3 * a + b] * p[b];
    double fp = force.x * pen.x + force.y * pen.y + force.z * pen.z;
    if (!(pKp < 0.0) || !isfinite(fp))
        return 1.0; /* no penetration or no restoring stiffness along it: keep K */
    double alpha = fp / pKp;
    if (!(alpha > 0.0))
        alpha = 0.0;
    if (alpha > 1.0)
        alpha = 1.0;
    for (int i = 0; i < 9; i++)
        K[i] *= alpha;
    return alpha;
}
